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


def _jacobian(p: np.ndarray, d: np.ndarray, owner: str) -> tuple[float, np.ndarray]:
    jac = d @ p
    det = float(np.linalg.det(jac))
    if not det > 1e-9 * float(np.sum(p * p)):
        raise ModelError(f"{owner}: the quadrilateral is degenerate or not convex (det J = {det:.3g} m^2 at a corner "
                         f"or Gauss point, local corners {p.tolist()}); give four corners of a convex quadrilateral, "
                         "counter-clockwise about its normal")
    return det, jac


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
    for r, s in _CORNERS:                                     # det J > 0 at the corners: convex, counter-clockwise
        _jacobian(p, bilinear_shape(r, s)[1], label)
    E, nu, h, rho = element.youngs_modulus, element.poisson_ratio, element.thickness, element.density
    Db = element.bending_stiffness * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1 - nu) / 2]])
    shear = element.shear_correction * E / (2 * (1 + nu)) * h
    tying_r = _covariant_shear(p, 0.0, 1.0)[0], _covariant_shear(p, 0.0, -1.0)[0]          # A, C
    tying_s = _covariant_shear(p, 1.0, 0.0)[1], _covariant_shear(p, -1.0, 0.0)[1]          # D, B
    K = np.zeros((24, 24))
    for r, wr in zip(*_G2):
        for s, ws in zip(*_G2):
            n, d = bilinear_shape(r, s)
            det, jac = _jacobian(p, d, label)
            dxy = np.linalg.solve(jac, d)                     # dN/d(x', y')
            Bb = np.zeros((3, 24))
            Bb[0, 4::6] = dxy[0]                              # psi_x,x
            Bb[1, 3::6] = -dxy[1]                             # psi_y,y
            Bb[2, 4::6], Bb[2, 3::6] = dxy[1], -dxy[0]         # psi_x,y + psi_y,x
            g = np.vstack([(1 + s) / 2 * tying_r[0] + (1 - s) / 2 * tying_r[1],
                           (1 + r) / 2 * tying_s[0] + (1 - r) / 2 * tying_s[1]])
            Bs = np.linalg.solve(jac, g)                      # (gamma_xz, gamma_yz)
            K += wr * ws * det * (Bb.T @ Db @ Bb + shear * Bs.T @ Bs)
    Km, _ = membrane_matrices(MembraneElement(element.name, element.nodes, h, E, nu, rho), p, label)
    membrane = [6 * k + j for k in range(4) for j in (0, 1)]
    K[np.ix_(membrane, membrane)] += Km
    gradients = []
    for r, s in _CORNERS:
        _, d = bilinear_shape(r, s)
        gradients.append(np.linalg.solve(d @ p, d))
    points, weights, shapes, rotations = [], [], [], []
    for r, wr in zip(*_G3):
        for s, ws in zip(*_G3):
            n, d = bilinear_shape(r, s)
            det, _ = _jacobian(p, d, label)
            S, R = np.zeros((3, 24)), np.zeros((3, 24))
            for j in range(3):
                S[j, j::6] = n
            R[0, 3::6], R[1, 4::6] = n, n                      # section rotations (r_x, r_y), local
            points.append(n @ p)
            weights.append(wr * ws * det)
            shapes.append(S)
            rotations.append(R)
    weights, shapes, rotations, points = np.array(weights), np.array(shapes), np.array(rotations), np.array(points)
    section = rho * h ** 3 / 12 * np.array([1.0, 1.0, 0.0])   # per area, about x', y', z' [kg]
    M = rho * h * np.einsum("p,pik,pil->kl", weights, shapes, shapes) \
        + np.einsum("p,i,pik,pil->kl", weights, section, rotations, rotations)
    area = float(weights.sum())
    centroid = weights @ points / area
    polar = rho * h * float(weights @ np.sum((points - centroid) ** 2, axis=1))
    K += drilling_stiffness(element, area, gradients)
    return shell_parts_in_model_axes(axes, K, M, rho * h * weights, points, shapes, section, weights, rotations,
                                     polar / 16)
