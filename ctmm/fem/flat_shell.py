"""Parts shared by the flat-shell elements of any shape (thick quadrilateral, bending triangle).

A flat-shell element joins ``n`` nodes (3 or 4) of a :class:`~ctmm.fem.SpatialFiniteElementModel` lying in
one plane, counter-clockwise about the element normal; every node has the six model DOFs
``u_x, u_y, u_z, r_x, r_y, r_z``.  Local axes: ``x'`` from node 1 to node 2, normal ``z'`` by the right-hand
rule of the node order, ``y' = z' x x'``; local DOFs per node ``[u, v, w, r_x, r_y, r_z]`` (``r_x, r_y``
right-handed small rotations about ``x', y'``: the section slopes are ``psi_x = r_y`` and ``psi_y = -r_x``;
in the thin limit ``r_x = dw/dy'``, ``r_y = -dw/dx'`` as in the beams and the rectangular plate).

This module holds what does not depend on the bending theory: the local axes and the planarity check,
the parameter checks, the drilling penalty (``r_z`` has no stiffness or inertia in plate theory: tied to the
membrane's in-plane rotation ``omega = (dv/dx' - du/dy')/2`` at every corner by ``k_d = ratio G h A / n``,
with a lumped corner inertia ``J_c / n^2``, ``J_c`` the polar inertia of the element about its centroid --
for a rectangle this is the rule of :mod:`ctmm.fem.spatial_plate`), and the transformation of local
matrices and mass points to model axes (:class:`FlatShellParts`, consumed by
:mod:`ctmm.fem.spatial_assembly`).  Derivations: ``docs/mixed.md`` §7d.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import validation
from ..errors import ModelError

__all__ = ["FlatShellParts", "PlateMaterial", "flat_shell_axes", "check_flat_shell", "drilling_stiffness",
           "shell_parts_in_model_axes"]


@dataclass(frozen=True)
class FlatShellParts:
    """Matrices and mass points of one flat-shell element in model axes (``6 n`` DOFs, node by node).

    Attributes
    ----------
    stiffness, mass : array (6n, 6n)
        ``K`` [N/m, N, N m] and ``M`` [kg, kg m, kg m^2] (translational, rotary and drilling inertia).
    point_masses : array (P,)
        Masses of the quadrature points [kg] (``rho h`` times the area weight).
    points : array (P, 3)
        Their undeformed positions relative to the element's first node, model axes [m].
    shapes : array (P, 3, 6n)
        Displacement of each point from the element DOFs (model axes).
    rotary : array (3, 3)
        Rotary inertia of the element's sections and drilling corners, model axes [kg m^2].
    rotary_coupling : array (3, 6n)
        ``int J(X) R(X) dA`` with ``R`` the section rotation from the DOFs (``R_c`` of
        :class:`~ctmm.fem.SpatialInertia`).
    """

    stiffness: np.ndarray
    mass: np.ndarray
    point_masses: np.ndarray
    points: np.ndarray
    shapes: np.ndarray
    rotary: np.ndarray
    rotary_coupling: np.ndarray


class PlateMaterial:
    """Mixin of the flat-shell element records: the plate's bending stiffness from its fields ``thickness``,
    ``youngs_modulus`` and ``poisson_ratio``."""

    @property
    def bending_stiffness(self) -> float:
        """``D = E h^3 / (12 (1 - nu^2))`` [N m]."""
        return self.youngs_modulus * self.thickness ** 3 / (12.0 * (1.0 - self.poisson_ratio ** 2))


def check_flat_shell(element: Any, count: int, shape: str, extra: tuple[str, ...] = ()) -> None:
    """Check and normalise (in place, frozen dataclass) the parameters of a flat-shell ``element`` with ``count``
    nodes, else :class:`ModelError` naming parameter, value and what is allowed."""
    n = validation.name("element", element.name)
    nodes = tuple(element.nodes) if isinstance(element.nodes, (tuple, list)) else ()
    if len(nodes) != count or not all(isinstance(k, str) and k for k in nodes) or len(set(nodes)) != count:
        raise ModelError(f"{n}: nodes must be {count} distinct node names (corners of a {shape}, counter-clockwise "
                         f"about its normal), got {element.nodes!r}")
    object.__setattr__(element, "nodes", nodes)
    for attribute in ("thickness", "youngs_modulus", "density", "drilling_stiffness_ratio") + extra:
        object.__setattr__(element, attribute, validation.positive(f"{n}: {attribute}", getattr(element, attribute)))
    nu = validation.nonnegative(f"{n}: poisson_ratio", element.poisson_ratio)
    if not nu < 0.5:
        raise ModelError(f"{n}: poisson_ratio must be in [0, 0.5), got {element.poisson_ratio!r}")
    object.__setattr__(element, "poisson_ratio", nu)


def flat_shell_axes(corners: np.ndarray, owner: str) -> tuple[np.ndarray, np.ndarray]:
    """Local axes (rows ``x', y', z'`` in model axes) and local corner coordinates ``(n, 2)`` [m] of a flat
    element with corners ``(n, 3)`` [m] in element order, else :class:`ModelError` (coincident nodes, zero area,
    corners not in one plane)."""
    p = np.asarray(corners, dtype=float)
    size = max(float(np.max(np.linalg.norm(p - p[0], axis=1))), 1e-300)
    normal = np.cross(p[2] - p[0], p[-1] - p[1]) if len(p) == 4 else np.cross(p[1] - p[0], p[2] - p[0])
    edge = p[1] - p[0]
    if np.linalg.norm(normal) <= 1e-9 * size ** 2 or np.linalg.norm(edge) <= 1e-9 * size:
        raise ModelError(f"{owner}: the {len(p)} nodes span no area (coincident or collinear corners {p.tolist()}); "
                         "give the corners of a non-degenerate polygon, counter-clockwise about its normal")
    z = normal / np.linalg.norm(normal)
    off = np.abs((p - p[0]) @ z)
    if np.max(off) > 1e-9 * size:
        raise ModelError(f"{owner}: the corners are not in one plane (a corner {np.max(off):.3g} m off the plane "
                         f"of the others, corners {p.tolist()}); flat elements only")
    x = edge - (edge @ z) * z
    x /= np.linalg.norm(x)
    axes = np.vstack([x, np.cross(z, x), z])
    return axes, (p - p[0]) @ axes[:2].T


def drilling_stiffness(element: Any, area: float, gradients: list[np.ndarray]) -> np.ndarray:
    """Drilling penalty ``sum_k k_d (r_z,k - omega_k)^2 / 2`` (local, ``6 n`` DOFs), ``k_d = ratio G h A / n``;
    ``gradients[k]`` (2, n): ``dN/d(x', y')`` of the membrane shape functions at corner ``k``."""
    n = len(gradients)
    nu = element.poisson_ratio
    k_d = element.drilling_stiffness_ratio * element.youngs_modulus / (2 * (1 + nu)) * element.thickness * area / n
    K = np.zeros((6 * n, 6 * n))
    for k, (dx, dy) in enumerate(gradients):
        row = np.zeros(6 * n)
        row[6 * k + 5] = 1.0
        row[1::6] -= 0.5 * dx
        row[0::6] += 0.5 * dy
        K += k_d * np.outer(row, row)
    return K


def shell_parts_in_model_axes(axes: np.ndarray, K: np.ndarray, M: np.ndarray, point_masses: np.ndarray,
                              local_points: np.ndarray, shapes: np.ndarray, rotary_per_area: np.ndarray,
                              rotary_weights: np.ndarray, rotations: np.ndarray, drilling_inertia: float
                              ) -> FlatShellParts:
    """:class:`FlatShellParts` from local ``K, M`` (drilling inertia not yet on ``M``), mass points (local
    positions ``(P, 2)``, shapes ``(P, 3, 6n)``), the section rotary inertia per area ``(3,)`` (local axes)
    with its quadrature (area weights ``(Q,)``, rotation interpolation ``(Q, 3, 6n)``) and the lumped drilling
    inertia per corner [kg m^2]."""
    n = K.shape[0] // 6
    M = M.copy()
    M[5::6, 5::6] += drilling_inertia * np.eye(n)
    T = np.kron(np.eye(2 * n), axes)                                  # local = T model
    J_local = np.einsum("q,i,qik->ik", rotary_weights, rotary_per_area, rotations)     # (3, 6n)
    drill = np.zeros((3, 6 * n))
    drill[2, 5::6] = drilling_inertia
    tensor = axes.T @ np.diag(rotary_per_area) @ axes * float(np.sum(rotary_weights))
    rotary = tensor + n * drilling_inertia * np.outer(axes[2], axes[2])
    return FlatShellParts(stiffness=T.T @ K @ T, mass=T.T @ M @ T, point_masses=np.asarray(point_masses, float),
                          points=np.asarray(local_points, float) @ axes[:2],
                          shapes=np.einsum("ji,pjk,kl->pil", axes, shapes, T), rotary=rotary,
                          rotary_coupling=axes.T @ (J_local + drill) @ T)
