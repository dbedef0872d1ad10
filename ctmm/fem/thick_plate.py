"""Thick (Mindlin-Reissner) flat-shell quadrilateral: MITC4 bending and shear with plane-stress membrane action.

A :class:`SpatialThickPlateElement` joins four nodes of a :class:`~ctmm.fem.SpatialFiniteElementModel` at the
corners of a convex plane quadrilateral (any shape), counter-clockwise about its normal; six model DOFs per
node, local axes and DOFs as :mod:`ctmm.fem.flat_shell` (``psi_x = r_y``, ``psi_y = -r_x`` the section
slopes).  Derivation (``docs/mixed.md`` §7d):

* **interpolation** -- isoparametric bilinear, natural coordinates ``(r, s)`` in ``[-1, 1]^2``, corners
  ``(-1,-1), (1,-1), (1,1), (-1,1)``: ``N_a = (1 + r_a r)(1 + s_a s)/4`` for ``x', y'``, ``u, v, w`` and
  ``r_x, r_y`` independently (Mindlin: the sections rotate independently of ``grad w``);
* **bending** -- ``kappa = (psi_x,x, psi_y,y, psi_x,y + psi_y,x)``, ``K_b = int B_b^T D_b B_b dA`` with
  ``D_b = D [[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu)/2]]``, ``D = E h^3 / (12 (1 - nu^2))``, 2 x 2 Gauss
  (exact for a parallelogram);
* **transverse shear (MITC4, Bathe and Dvorkin 1985)** -- the covariant shear strains
  ``g_r = w,r + psi . x,r`` and ``g_s = w,s + psi . x,s`` are sampled at the edge midpoints (tying points
  ``A = (0, 1)``, ``C = (0, -1)`` for ``g_r``; ``D = (1, 0)``, ``B = (-1, 0)`` for ``g_s``) and interpolated
  ``g_r = (1 + s)/2 g_r(A) + (1 - s)/2 g_r(C)``, ``g_s = (1 + r)/2 g_s(D) + (1 - r)/2 g_s(B)``; Cartesian
  ``gamma = J^-1 (g_r, g_s)`` (``J = d(x', y')/d(r, s)``, rows ``r, s``);
  ``K_s = k G h int gamma^T gamma dA`` (``G = E / (2 (1 + nu))``, shear correction ``k``, default 5/6), 2 x 2
  Gauss.  Along an edge the assumed ``g`` is constant and equals the exact mean of ``w,t + psi_t``, so a
  Kirchhoff mode (``gamma = 0``) is representable: no shear locking in the thin limit, and no spurious
  zero-energy modes (the element passes the patch tests of Bathe and Dvorkin);
* **mass** -- consistent, ``rho h int (u^2 + v^2 + w^2) dA + rho h^3/12 int (psi_x^2 + psi_y^2) dA`` (rotary
  inertia of the sections included, as in Mindlin's theory), 3 x 3 Gauss (exact for any straight-sided
  quadrilateral);
* **membrane** -- the plane-stress stiffness of :func:`ctmm.fem.membrane.membrane_matrices` on ``(u, v)``;
* **drilling** ``r_z`` -- penalty and lumped inertia of :mod:`ctmm.fem.flat_shell`.

Convergence: frequencies at ``O(h^2)`` in the mesh size, from both sides (``tests/test_fem_plate_thick.py``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from .flat_shell import (FlatShellParts, PlateMaterial, check_flat_shell, drilling_stiffness, flat_shell_axes,
                         shell_parts_in_model_axes)
from .membrane import MembraneElement, bilinear_shape, membrane_matrices

__all__ = ["SpatialThickPlateElement", "thick_plate_parts"]

_CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])     # (r, s) of the nodes
_G2 = np.polynomial.legendre.leggauss(2)
_G3 = np.polynomial.legendre.leggauss(3)


@dataclass(frozen=True)
class SpatialThickPlateElement(PlateMaterial):
    """Mindlin-Reissner flat-shell quadrilateral (MITC4 + membrane) between four nodes (module docstring).

    Parameters
    ----------
    name : str
        Element name.
    nodes : (str, str, str, str)
        Corners of a convex plane quadrilateral, counter-clockwise about the plate's normal ``z'``.
    thickness : float
        ``h`` [m], > 0.
    youngs_modulus : float
        ``E`` [Pa], > 0.
    poisson_ratio : float
        ``nu`` [-], ``0 <= nu < 0.5``.
    density : float
        ``rho`` [kg/m^3], > 0.
    shear_correction : float
        ``k`` of the transverse shear stiffness ``k G h`` [-], > 0; default 5/6 (Reissner).
    drilling_stiffness_ratio : float
        ``k_d / (G h A / 4)`` of the drilling penalty [-], > 0; default 0.1.

    Examples
    --------
    >>> from ctmm.fem import SpatialFiniteElementModel, SpatialThickPlateElement
    >>> fe = SpatialFiniteElementModel("slab", {"a": (0, 0, 0), "b": (0.4, 0, 0), "c": (0.5, 0.3, 0),
    ...     "d": (0, 0.3, 0)}, [SpatialThickPlateElement("p", ("a", "b", "c", "d"), 0.05, 7e10, 0.3, 2700.0)])
    >>> fe.n_dofs, round(fe.floating_inertia("a").mass, 6)           # rho h A, A = 0.135 m^2 [kg]
    (24, 18.225)
    """

    name: str
    nodes: tuple
    thickness: float
    youngs_modulus: float
    poisson_ratio: float
    density: float
    shear_correction: float = 5.0 / 6.0
    drilling_stiffness_ratio: float = 0.1

    def __post_init__(self) -> None:
        check_flat_shell(self, 4, "convex quadrilateral", ("shear_correction",))


def _grid(rule: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points ``r, s`` and weights of the tensor-product Gauss rule ``rule`` on ``[-1, 1]^2``."""
    points, weights = rule
    return np.repeat(points, len(points)), np.tile(points, len(points)), np.outer(weights, weights).ravel()


def _shapes(r: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~ctmm.fem.membrane.bilinear_shape` at many points: ``N`` (P, 4) and ``dN/d(r, s)`` (P, 2, 4)."""
    values = [bilinear_shape(a, b) for a, b in zip(r, s)]
    return np.array([v[0] for v in values]), np.array([v[1] for v in values])


_STIFFNESS_POINTS = _grid(_G2), _shapes(*_grid(_G2)[:2])
"""``(r, s, weights)`` and ``(N, dN/d(r, s))`` at the 2 x 2 Gauss points."""
_MASS_POINTS = _grid(_G3), _shapes(*_grid(_G3)[:2])
"""The same at the 3 x 3 Gauss points."""
_CORNER_GRADIENTS = _shapes(_CORNERS[:, 0], _CORNERS[:, 1])[1]
"""``dN/d(r, s)`` (4, 2, 4) at the corners."""


def _determinants(jac: np.ndarray, p: np.ndarray, owner: str) -> np.ndarray:
    """``det J`` (P,) of the Jacobians ``jac`` (P, 2, 2), else :class:`ModelError` (not positive: degenerate,
    crossed or non-convex quadrilateral)."""
    det = np.linalg.det(jac)
    if not np.all(det > 1e-9 * float(np.sum(p * p))):
        raise ModelError(f"{owner}: the quadrilateral is degenerate or not convex (det J = {float(np.min(det)):.3g} "
                         f"m^2 at a corner or Gauss point, local corners {p.tolist()}); give four corners of a convex "
                         "quadrilateral, counter-clockwise about its normal")
    return det


def _covariant_shear(p: np.ndarray, r: float, s: float) -> np.ndarray:
    """Rows ``g_r, g_s`` (2, 24) of the covariant shear strains at ``(r, s)`` (displacement-based)."""
    n, d = bilinear_shape(r, s)
    jac = d @ p                                               # rows x,r and x,s
    G = np.zeros((2, 24))
    for i in range(2):
        G[i, 2::6] = d[i]                                     # w,r or w,s
        G[i, 4::6] = n * jac[i, 0]                            # psi_x x,i  (psi_x = r_y)
        G[i, 3::6] = -n * jac[i, 1]                           # psi_y y,i  (psi_y = -r_x)
    return G


def thick_plate_parts(element: SpatialThickPlateElement, corners: np.ndarray, owner: str) -> FlatShellParts:
    """:class:`~ctmm.fem.flat_shell.FlatShellParts` of a thick plate with corners ``(4, 3)`` [m] (model axes,
    element order); ``owner`` names it in error messages (module docstring)."""
    label = f"{owner}: {element.name}"
    axes, p = flat_shell_axes(corners, label)
    _determinants(_CORNER_GRADIENTS @ p, p, label)           # > 0 at the corners: convex
    E, nu, h, rho = element.youngs_modulus, element.poisson_ratio, element.thickness, element.density
    Db = element.bending_stiffness * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1 - nu) / 2]])
    shear = element.shear_correction * E / (2 * (1 + nu)) * h
    tying_r = _covariant_shear(p, 0.0, 1.0)[0], _covariant_shear(p, 0.0, -1.0)[0]          # A, C
    tying_s = _covariant_shear(p, 1.0, 0.0)[1], _covariant_shear(p, -1.0, 0.0)[1]          # D, B
    (r, s, w), (n, d) = _STIFFNESS_POINTS                    # (4, 4), (4, 2, 4) at the 2 x 2 points
    jac = d @ p                                               # (4, 2, 2)
    det = _determinants(jac, p, label)
    dxy = np.linalg.solve(jac, d)                             # dN/d(x', y')
    Bb = np.zeros((len(r), 3, 24))
    Bb[:, 0, 4::6] = dxy[:, 0]                                # psi_x,x
    Bb[:, 1, 3::6] = -dxy[:, 1]                               # psi_y,y
    Bb[:, 2, 4::6], Bb[:, 2, 3::6] = dxy[:, 1], -dxy[:, 0]    # psi_x,y + psi_y,x
    g = np.stack([np.outer((1 + s) / 2, tying_r[0]) + np.outer((1 - s) / 2, tying_r[1]),
                  np.outer((1 + r) / 2, tying_s[0]) + np.outer((1 - r) / 2, tying_s[1])], 1)
    Bs = np.linalg.solve(jac, g)                              # (gamma_xz, gamma_yz)
    wd = (w * det)[:, None, None]
    K = np.einsum("pik,pil->kl", Bb, wd * (Db @ Bb)) + shear * np.einsum("pik,pil->kl", Bs, wd * Bs)
    Km, _ = membrane_matrices(MembraneElement(element.name, element.nodes, h, E, nu, rho), p, label)
    membrane = [6 * k + j for k in range(4) for j in (0, 1)]
    K[np.ix_(membrane, membrane)] += Km
    d = _CORNER_GRADIENTS
    gradients = list(np.linalg.solve(d @ p, d))
    (r, s, w), (n, d) = _MASS_POINTS
    weights, points = w * _determinants(d @ p, p, label), n @ p
    shapes, rotations = np.zeros((len(r), 3, 24)), np.zeros((len(r), 3, 24))
    for j in range(3):
        shapes[:, j, j::6] = n
    rotations[:, 0, 3::6], rotations[:, 1, 4::6] = n, n       # section rotations (r_x, r_y), local
    section = rho * h ** 3 / 12 * np.array([1.0, 1.0, 0.0])   # per area, about x', y', z' [kg]
    M = rho * h * np.einsum("pik,pil->kl", shapes, weights[:, None, None] * shapes) \
        + np.einsum("pik,pil->kl", rotations, (weights[:, None] * section)[:, :, None] * rotations)
    area = float(weights.sum())
    centroid = weights @ points / area
    polar = rho * h * float(weights @ np.sum((points - centroid) ** 2, axis=1))
    K += drilling_stiffness(element, area, gradients)
    return shell_parts_in_model_axes(axes, K, M, rho * h * weights, points, shapes, section, weights, rotations,
                                     polar / 16)
