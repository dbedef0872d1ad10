"""Spatial finite elements: 12-DOF Euler-Bernoulli (optionally Timoshenko) beam, point mass with inertia, node
spring-damper.

Every element lives between named nodes of a :class:`~ctmm.fem.spatial_assembly.SpatialFiniteElementModel`.
A node has the displacements ``(u_x, u_y, u_z)`` [m] in the model's axes and, when a beam touches it,
the small rotations ``(r_x, r_y, r_z)`` [rad] (``docs/mixed.md`` §7).

**Beam** (Euler-Bernoulli, no shear deformation, no warping): local axes ``x'`` from node ``a`` to
node ``b`` (length ``L``), ``y'`` the component of ``orientation`` perpendicular to ``x'``, ``z' = x' x y'``;
local DOFs per node ``[u, v, w, r_x, r_y, r_z]`` (``r_z = v'``, ``r_y = -w'``); axial displacement and
twist linear, deflections Hermite cubic (``xi = x / L``)::

    u   = (1 - xi) u_a + xi u_b,                 phi = (1 - xi) r_xa + xi r_xb
    v   = H1 v_a + L H2 r_za + H3 v_b + L H4 r_zb
    w   = H1 w_a - L H2 r_ya + H3 w_b - L H4 r_yb,
    H1 = 1 - 3 xi^2 + 2 xi^3,  H2 = xi - 2 xi^2 + xi^3,  H3 = 3 xi^2 - 2 xi^3,  H4 = -xi^2 + xi^3

Stiffness ``int (EA u'^2 + EI_y v''^2 + EI_z w''^2 + GJ phi'^2) dx``, translational consistent mass
``rhoA int (u^2 + v^2 + w^2) dx``, torsional mass ``rho I_p int phi^2 dx`` (the section's rotary inertia
about its axis; the bending rotary inertia of a slender section is neglected unless given, below),
geometric stiffness of a constant axial force ``N`` (tension > 0) ``N int (v'^2 + w'^2) dx`` -- all by five-point Gauss
quadrature, exact for these polynomials (degree <= 6).  ``bending_stiffness_y`` is the ``EI`` of the
deflection along ``y'`` (bending in the ``x'-y'`` plane), as for :class:`ctmm.spatial.SpatialBeam`.

**Timoshenko option**: ``shear_stiffness_y`` / ``_z`` (``kappa G A`` of the deflection along ``y'`` / ``z'``)
make that bending plane shear-deformable, ``bending_rotary_inertia_y`` / ``_z`` (``rho I`` of its sections)
add their rotary inertia; the plane's interpolation is then the one of :mod:`ctmm.fem.timoshenko` (``r_z``,
``-r_y`` the section rotations instead of the slopes ``v'``, ``w'``), with the strain energy
``int (EI theta'^2 + kappa G A (v' - theta)^2) dx`` and kinetic ``rho I int theta_dot^2 dx``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import validation
from ..errors import ModelError
from .model_parts import TwoNodeSpring, node_name
from .timoshenko import bending_shapes, shear_parameter

__all__ = ["SpatialBeamElement", "SpatialPointMass", "SpatialNodeSpring", "spatial_beam_axes", "spatial_beam_shapes",
           "spatial_beam_local_matrices", "spatial_shear_parameters", "section_rotary_inertia", "node_rotation_block",
           "GAUSS_POINTS", "GAUSS_WEIGHTS"]

_X, _W = np.polynomial.legendre.leggauss(5)
GAUSS_POINTS, GAUSS_WEIGHTS = 0.5 * (_X + 1.0), 0.5 * _W
"""Five Gauss-Legendre points on ``[0, 1]`` and their weights (exact to degree 9)."""


@dataclass(frozen=True)
class SpatialBeamElement:
    """Spatial Euler-Bernoulli beam element between two nodes (module docstring).

    Parameters
    ----------
    name : str
    start, end : str
        Node names.
    axial_stiffness : float
        ``EA`` [N], > 0.
    torsional_stiffness : float
        ``GJ`` [N m^2], > 0.
    bending_stiffness_y, bending_stiffness_z : float
        ``EI`` of the deflection along local ``y'`` and along ``z'`` [N m^2], > 0.
    mass_per_length : float
        ``rhoA`` [kg/m], >= 0.
    polar_inertia_per_length : float
        ``rho I_p`` [kg m], >= 0 (rotary inertia of the section about the axis).
    axial_force : float
        Constant axial force ``N`` [N] (tension > 0) of the geometric stiffness; default 0.
    orientation : 3 numbers, optional
        A direction not along the element whose perpendicular component is local ``y'`` (model axes);
        default: ``z x x'`` (``x'`` along ``x`` gives ``y' = y``), or ``y`` for an element along ``z``.
    shear_stiffness_y, shear_stiffness_z : float or None
        ``kappa G A`` [N], > 0, of the deflection along ``y'`` / ``z'`` (Timoshenko); default None (rigid in
        shear, Euler-Bernoulli).
    bending_rotary_inertia_y, bending_rotary_inertia_z : float
        ``rho I`` [kg m], >= 0, of the sections of the bending along ``y'`` (rotation about ``z'``) / along
        ``z'`` (rotation about ``y'``); default 0.
    """

    name: str
    start: str
    end: str
    axial_stiffness: float
    torsional_stiffness: float
    bending_stiffness_y: float
    bending_stiffness_z: float
    mass_per_length: float
    polar_inertia_per_length: float = 0.0
    axial_force: float = 0.0
    orientation: Any = None
    shear_stiffness_y: float | None = None
    shear_stiffness_z: float | None = None
    bending_rotary_inertia_y: float = 0.0
    bending_rotary_inertia_z: float = 0.0

    def __post_init__(self) -> None:
        n = validation.name("element", self.name)
        node_name(n, "start", self.start)
        node_name(n, "end", self.end)
        if self.start == self.end:
            raise ModelError(f"{n}: start and end must be different nodes, got {self.start!r} twice")
        for attribute in ("axial_stiffness", "torsional_stiffness", "bending_stiffness_y", "bending_stiffness_z"):
            object.__setattr__(self, attribute, validation.positive(f"{n}: {attribute}", getattr(self, attribute)))
        for attribute in ("mass_per_length", "polar_inertia_per_length", "bending_rotary_inertia_y",
                          "bending_rotary_inertia_z"):
            object.__setattr__(self, attribute, validation.nonnegative(f"{n}: {attribute}", getattr(self, attribute)))
        for attribute in ("shear_stiffness_y", "shear_stiffness_z"):
            if getattr(self, attribute) is not None:
                object.__setattr__(self, attribute, validation.positive(
                    f"{n}: {attribute} (kappa G A [N], or None for no shear deformation)", getattr(self, attribute)))
        object.__setattr__(self, "axial_force", validation.finite(f"{n}: axial_force", self.axial_force))
        if self.orientation is not None:
            object.__setattr__(self, "orientation", validation.unit_vector(f"{n}: orientation (x, y, z)",
                                                                           self.orientation))


@dataclass(frozen=True)
class SpatialPointMass:
    """A mass and a rotary inertia at a node.

    Parameters
    ----------
    name, node : str
    mass : float
        [kg], >= 0.
    inertia : 3 numbers or (3, 3)
        Inertia about the node in the model's axes [kg m^2] (principal values or a symmetric positive
        semi-definite matrix); default 0.  On a node without rotation DOFs it turns with the subsystem's
        floating frame; with them it turns with the node (small rotations, ``docs/mixed.md`` §7).
    """

    name: str
    node: str
    mass: float
    inertia: Any = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        n = validation.name("element", self.name)
        node_name(n, "node", self.node)
        object.__setattr__(self, "mass", validation.nonnegative(f"{n}: mass", self.mass))
        inertia = validation.finite_array(f"{n}: inertia", self.inertia)
        inertia = np.diag(inertia) if inertia.shape == (3,) else inertia
        if inertia.shape != (3, 3) or np.max(np.abs(inertia - inertia.T)) > 1e-12 * max(np.max(np.abs(inertia)), 1e-300) \
                or np.min(np.linalg.eigvalsh(inertia)) < -1e-12 * max(np.max(np.abs(inertia)), 1e-300):
            raise ModelError(f"{n}: inertia must be 3 principal values >= 0 or a symmetric positive semi-definite "
                             f"3 x 3 matrix [kg m^2], got {self.inertia!r}")
        object.__setattr__(self, "inertia", 0.5 * (inertia + inertia.T))


@dataclass(frozen=True)
class SpatialNodeSpring(TwoNodeSpring):
    """Linear spring and viscous damper between two nodes along the line of their undeformed positions,
    optionally an isotropic rotational spring-damper between their rotations (small displacements).

    Parameters
    ----------
    name, start, end : str
    stiffness, damping : float
        Axial [N/m], [N s/m], >= 0 (needs distinct node positions).
    rotational_stiffness, rotational_damping : float
        [N m/rad], [N m s/rad], >= 0, on ``r_end - r_start`` (both nodes need rotation DOFs).
    """


def spatial_beam_axes(start: np.ndarray, end: np.ndarray, orientation: np.ndarray | None, owner: str
                      ) -> tuple[float, np.ndarray]:
    """Length [m] and the local axes (rows ``x', y', z'`` in model axes, 3 x 3: local = ``A`` global)."""
    d = np.asarray(end, float) - np.asarray(start, float)
    length = float(np.linalg.norm(d))
    if not length > 0.0:
        raise ModelError(f"{owner}: its nodes coincide (length 0); a beam needs two distinct node positions")
    e1 = d / length
    if orientation is None:
        hint = np.cross([0.0, 0.0, 1.0], e1) if abs(e1[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
    else:
        hint = np.asarray(orientation, float)
    y = hint - (hint @ e1) * e1
    if not np.linalg.norm(y) > 1e-8 * max(np.linalg.norm(hint), 1e-300):
        raise ModelError(f"{owner}: orientation {np.asarray(orientation).tolist()} is along the element; give a "
                         "direction with a component perpendicular to it")
    y = y / np.linalg.norm(y)
    return length, np.vstack([e1, y, np.cross(e1, y)])


def spatial_shear_parameters(element: SpatialBeamElement, length: float) -> tuple[float, float]:
    """``phi = 12 EI / (kappa G A L^2)`` of the bending along ``y'`` and along ``z'`` (0 without shear)."""
    return (shear_parameter(element.name, element.bending_stiffness_y, element.shear_stiffness_y, length),
            shear_parameter(element.name, element.bending_stiffness_z, element.shear_stiffness_z, length))


def spatial_beam_shapes(xi: np.ndarray, length: float, shear: tuple[float, float] = (0.0, 0.0)
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Local interpolation at ``xi`` (P,) with the shear parameters ``shear`` of the two bending planes:
    ``N`` (P, 4, 12) of ``[u, v, w, phi]``, the first derivatives ``dN/dx`` (P, 4, 12) [1/m], the curvatures
    (derivatives of the section rotations ``r_z``, ``-r_y`` in the rows of ``v``, ``w``; ``d2N/dx2`` without
    shear) (P, 4, 12) [1/m^2] and the section rotations ``[phi, r_y, r_z]`` (P, 3, 12)."""
    xi = np.asarray(xi, dtype=float)
    L = length
    N, D1, D2 = (np.zeros(xi.shape + (4, 12)) for _ in range(3))
    R = np.zeros(xi.shape + (3, 12))
    for row, (a, b) in ((0, (0, 6)), (3, (3, 9))):                     # axial u, twist phi: linear
        N[..., row, a], N[..., row, b] = 1 - xi, xi
        D1[..., row, a], D1[..., row, b] = -1 / L, 1 / L
    R[..., 0, :] = N[..., 3, :]
    for row, columns, sign, rotation in ((1, (1, 5, 7, 11), 1.0, 2), (2, (2, 4, 8, 10), -1.0, 1)):
        v, slope, theta, curvature = bending_shapes(xi, L, shear[row - 1])
        for k, column in enumerate(columns):
            s = sign if k in (1, 3) else 1.0
            N[..., row, column], D1[..., row, column], D2[..., row, column] = s * v[..., k], s * slope[..., k], \
                s * curvature[..., k]
            R[..., rotation, column] = sign * s * theta[..., k]        # r_z = theta_v, r_y = -theta_w
    return N, D1, D2, R


def spatial_beam_local_matrices(element: SpatialBeamElement, length: float) -> tuple[np.ndarray, np.ndarray,
                                                                                     np.ndarray, np.ndarray]:
    """Local ``(K, M_translational, M_rotary, K_G)`` (12 x 12) of a beam element (module docstring); ``M_rotary``
    holds the torsional and (Timoshenko option) the bending rotary inertia of the sections."""
    N, D1, D2, R = spatial_beam_shapes(GAUSS_POINTS, length, spatial_shear_parameters(element, length))
    w = GAUSS_WEIGHTS * length
    strain = np.stack([D1[:, 0], D2[:, 1], D2[:, 2], D1[:, 3]], axis=1)           # (P, 4, 12)
    moduli = np.array([element.axial_stiffness, element.bending_stiffness_y, element.bending_stiffness_z,
                       element.torsional_stiffness])
    K = np.einsum("p,pik,i,pil->kl", w, strain, moduli, strain)
    for shear_stiffness, gamma in ((element.shear_stiffness_y, D1[:, 1] - R[:, 2]),
                                   (element.shear_stiffness_z, D1[:, 2] + R[:, 1])):
        if shear_stiffness is not None:
            K += shear_stiffness * np.einsum("p,pk,pl->kl", w, gamma, gamma)
    M_t = element.mass_per_length * np.einsum("p,pik,pil->kl", w, N[:, :3], N[:, :3])
    M_r = np.einsum("p,pik,i,pil->kl", w, R, section_rotary_inertia(element), R)
    G = element.axial_force * np.einsum("p,pik,pil->kl", w, D1[:, 1:3], D1[:, 1:3])
    return K, M_t, M_r, G


def section_rotary_inertia(element: SpatialBeamElement) -> np.ndarray:
    """Rotary inertia per length of the sections about local ``x', y', z'`` [kg m]:
    ``(rho I_p, bending_rotary_inertia_z, bending_rotary_inertia_y)``."""
    return np.array([element.polar_inertia_per_length, element.bending_rotary_inertia_z,
                     element.bending_rotary_inertia_y])


def node_rotation_block(axes: np.ndarray) -> np.ndarray:
    """``T`` (12 x 12, local = ``T`` model) of an element with local ``axes`` (rows)."""
    T = np.zeros((12, 12))
    for k in range(4):
        T[3 * k:3 * k + 3, 3 * k:3 * k + 3] = axes
    return T

