"""Triangular flat-shell element: discrete Kirchhoff (DKT) bending with a constant-strain membrane.

A :class:`SpatialTrianglePlateElement` joins three nodes of a :class:`~ctmm.fem.SpatialFiniteElementModel`
(any non-degenerate triangle, counter-clockwise about its normal), so irregular plates mesh; six model DOFs
per node, local axes and DOFs as :mod:`ctmm.fem.flat_shell` (bending DOFs ``w, r_x, r_y`` per corner;
section slopes ``psi_x = r_y``, ``psi_y = -r_x``).  Derivation (``docs/mixed.md`` §7d; Batoz, Bathe and Ho
1980, built here from its definition rather than from the published closed forms):

* **bending (DKT)** -- the slopes ``psi`` are quadratic over the triangle (six-node shape functions
  ``L_i (2 L_i - 1)`` at the corners, ``4 L_i L_j`` at the edge midpoints, ``L_i`` area coordinates).  At the
  corners ``psi`` are the nodal values (Kirchhoff there); at the midpoint of an edge ``i -> j`` (length ``l``,
  tangent ``t``, normal ``n``) Kirchhoff holds in the tangential direction for the Hermite cubic ``w`` of the
  edge, ``psi_t = 3 (w_i - w_j) / (2 l) - (psi_t,i + psi_t,j) / 4``, and the normal slope is the mean
  ``psi_n = (psi_n,i + psi_n,j) / 2``.  Curvatures ``kappa = (psi_x,x, psi_y,y, psi_x,y + psi_y,x)``
  are linear; ``K_b = int B^T D_b B dA`` by the three-edge-midpoint rule (exact for its quadratic integrand),
  ``D_b`` as the rectangular plate.  Constant curvature states are exact (patch test);
* **mass** -- the DKT has no interior ``w``; the consistent mass uses the reduced Hermite cubic on the same
  nine DOFs (``w, grad w = (-r_y, r_x)`` at the corners, the centroid value
  ``w_c = sum_i [w_i + grad w_i . (c - x_i) / 2] / 3``, which reproduces quadratics): its edge traces are the
  Hermite cubics of the DKT edges.  ``rho h int (u^2 + v^2 + w^2) dA`` by a 4 x 4 collapsed Gauss rule
  (exact to degree 7); the rotary inertia of the sections is neglected (Kirchhoff plate);
* **membrane** -- the constant-strain triangle (linear ``u, v``), plane stress;
* **drilling** ``r_z`` -- penalty and lumped inertia of :mod:`ctmm.fem.flat_shell`.

Convergence: frequencies at ``O(h^2)`` in the mesh size (``tests/test_fem_plate_triangle.py``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .flat_shell import (FlatShellParts, PlateMaterial, check_flat_shell, drilling_stiffness, flat_shell_axes,
                         shell_parts_in_model_axes)

__all__ = ["SpatialTrianglePlateElement", "triangle_plate_parts", "dkt_curvature"]

_U, _WU = np.polynomial.legendre.leggauss(4)
_U, _WU = 0.5 * (_U + 1.0), 0.5 * _WU
_EDGES = ((0, 1), (1, 2), (2, 0))
_BENDING = [6 * k + j for k in range(3) for j in (2, 3, 4)]


@dataclass(frozen=True)
class SpatialTrianglePlateElement(PlateMaterial):
    """Triangular flat-shell element (DKT bending + constant-strain membrane) between three nodes.

    Parameters
    ----------
    name : str
        Element name.
    nodes : (str, str, str)
        Corners of a non-degenerate triangle, counter-clockwise about the plate's normal ``z'``.
    thickness : float
        ``h`` [m], > 0.
    youngs_modulus : float
        ``E`` [Pa], > 0.
    poisson_ratio : float
        ``nu`` [-], ``0 <= nu < 0.5``.
    density : float
        ``rho`` [kg/m^3], > 0.
    drilling_stiffness_ratio : float
        ``k_d / (G h A / 3)`` of the drilling penalty [-], > 0; default 0.1.

    Examples
    --------
    >>> from ctmm.fem import SpatialFiniteElementModel, SpatialTrianglePlateElement
    >>> fe = SpatialFiniteElementModel("gusset", {"a": (0, 0, 0), "b": (0.4, 0, 0), "c": (0.1, 0.3, 0)},
    ...     [SpatialTrianglePlateElement("t", ("a", "b", "c"), 0.002, 7e10, 0.3, 2700.0)])
    >>> fe.n_dofs, round(fe.floating_inertia("a").mass, 6)           # rho h A, A = 0.06 m^2 [kg]
    (18, 0.324)
    """

    name: str
    nodes: tuple
    thickness: float
    youngs_modulus: float
    poisson_ratio: float
    density: float
    drilling_stiffness_ratio: float = 0.1

    def __post_init__(self) -> None:
        check_flat_shell(self, 3, "triangle")


def _area_gradients(p: np.ndarray) -> tuple[float, np.ndarray]:
    """Area ``A`` [m^2] and ``d L_i / d(x, y)`` (2, 3) of the triangle ``p`` (3, 2)."""
    area = 0.5 * float((p[1, 0] - p[0, 0]) * (p[2, 1] - p[0, 1]) - (p[2, 0] - p[0, 0]) * (p[1, 1] - p[0, 1]))
    b = np.array([p[(i + 1) % 3, 1] - p[(i + 2) % 3, 1] for i in range(3)])
    c = np.array([p[(i + 2) % 3, 0] - p[(i + 1) % 3, 0] for i in range(3)])
    return area, np.vstack([b, c]) / (2 * area)


def _slope_nodes(p: np.ndarray) -> np.ndarray:
    """``(6, 2, 9)``: the slopes ``psi`` at the corners and edge midpoints from ``[w, r_x, r_y]`` of the corners."""
    T = np.zeros((6, 2, 9))
    for i in range(3):
        T[i, 0, 3 * i + 2], T[i, 1, 3 * i + 1] = 1.0, -1.0            # psi_x = r_y, psi_y = -r_x
    for k, (i, j) in enumerate(_EDGES):
        edge = p[j] - p[i]
        length = float(np.linalg.norm(edge))
        t = edge / length
        n = np.array([t[1], -t[0]])
        psi_t = -0.25 * (t @ T[i] + t @ T[j])
        psi_t[3 * i] += 1.5 / length
        psi_t[3 * j] -= 1.5 / length
        psi_n = 0.5 * (n @ T[i] + n @ T[j])
        T[3 + k] = np.outer(t, psi_t) + np.outer(n, psi_n)
    return T


def dkt_curvature(p: np.ndarray, L: np.ndarray) -> np.ndarray:
    """Curvatures ``(psi_x,x, psi_y,y, psi_x,y + psi_y,x)`` (3, 9) of the DKT triangle with local corners
    ``p`` (3, 2) [m] at the area coordinates ``L`` (3,), from ``[w, r_x, r_y]`` of the corners."""
    return _curvature(_slope_nodes(p), _area_gradients(p)[1], L)


def _curvature(T: np.ndarray, dL: np.ndarray, L: np.ndarray) -> np.ndarray:
    """:func:`dkt_curvature` from the slope map ``T`` (6, 2, 9) and ``dL`` (2, 3)."""
    dN = np.zeros((2, 6))
    for i in range(3):
        dN[:, i] = (4 * L[i] - 1) * dL[:, i]
    for k, (i, j) in enumerate(_EDGES):
        dN[:, 3 + k] = 4 * (L[j] * dL[:, i] + L[i] * dL[:, j])
    gx, gy = np.einsum("a,aj->j", dN[0], T[:, 0]), np.einsum("a,aj->j", dN[1], T[:, 1])
    return np.vstack([gx, gy, np.einsum("a,aj->j", dN[1], T[:, 0]) + np.einsum("a,aj->j", dN[0], T[:, 1])])


def _cubic_monomials(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ten cubic monomials ``1, x, y, x^2, x y, y^2, x^3, x^2 y, x y^2, y^3`` and their ``x`` and ``y``
    derivatives at ``(x, y)`` (each (..., 10))."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    o, z = np.ones_like(x), np.zeros_like(x)
    m = np.stack([o, x, y, x * x, x * y, y * y, x ** 3, x * x * y, x * y * y, y ** 3], -1)
    mx = np.stack([z, o, z, 2 * x, y, z, 3 * x * x, 2 * x * y, y * y, z], -1)
    my = np.stack([z, z, o, z, x, 2 * y, z, x * x, 2 * x * y, 3 * y * y], -1)
    return m, mx, my


def _cubic_w(p: np.ndarray) -> tuple[np.ndarray, float]:
    """Coefficients ``(10, 9)`` of the reduced Hermite cubic ``w`` in the monomials of ``(x, y) / scale``, and
    ``scale`` [m] (module docstring)."""
    scale = float(np.max(np.abs(p))) or 1.0
    rows, rhs = np.zeros((10, 10)), np.zeros((10, 9))
    centroid = p.mean(axis=0)
    for i in range(3):
        m, mx, my = _cubic_monomials(*(p[i] / scale))
        mx, my = mx / scale, my / scale
        rows[3 * i], rows[3 * i + 1], rows[3 * i + 2] = m, mx, my
        rhs[3 * i, 3 * i], rhs[3 * i + 1, 3 * i + 2], rhs[3 * i + 2, 3 * i + 1] = 1.0, -1.0, 1.0
        d = centroid - p[i]                                          # w_c - sum(w_i + grad w_i . d_i / 2)/3 = 0
        rows[9] -= (m + 0.5 * (d[0] * mx + d[1] * my)) / 3
    rows[9] += _cubic_monomials(*(centroid / scale))[0]
    return np.linalg.solve(rows, rhs), scale


def triangle_plate_parts(element: SpatialTrianglePlateElement, corners: np.ndarray, owner: str) -> FlatShellParts:
    """:class:`~ctmm.fem.flat_shell.FlatShellParts` of a triangular plate with corners ``(3, 3)`` [m] (model
    axes, element order); ``owner`` names it in error messages (module docstring)."""
    label = f"{owner}: {element.name}"
    axes, p = flat_shell_axes(corners, label)
    E, nu, h, rho = element.youngs_modulus, element.poisson_ratio, element.thickness, element.density
    area, dL = _area_gradients(p)
    Db = element.bending_stiffness * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1 - nu) / 2]])
    K = np.zeros((18, 18))
    bend = np.ix_(_BENDING, _BENDING)
    T = _slope_nodes(p)
    for i, j in _EDGES:                                              # edge midpoints, weights A/3
        L = np.zeros(3)
        L[i] = L[j] = 0.5
        B = _curvature(T, dL, L)
        K[bend] += area / 3 * B.T @ Db @ B
    Bm = np.zeros((3, 18))                                           # constant-strain membrane
    Bm[0, 0::6], Bm[1, 1::6] = dL[0], dL[1]
    Bm[2, 0::6], Bm[2, 1::6] = dL[1], dL[0]
    K += h * area * E / (1 - nu * nu) * Bm.T @ np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1 - nu) / 2]]) @ Bm
    K += drilling_stiffness(element, area, [dL] * 3)
    coefficients, scale = _cubic_w(p)
    u, v = np.repeat(_U, len(_U)), np.tile(_U, len(_U))             # collapsed square -> triangle
    L = np.stack([1 - u, u * (1 - v), u * v], -1)                    # (16, 3) area coordinates
    weights = np.repeat(_WU, len(_U)) * np.tile(_WU, len(_U)) * u * 2 * area
    points = L @ p
    x, y = points[:, 0] / scale, points[:, 1] / scale
    shapes = np.zeros((len(u), 3, 18))
    shapes[:, 0, 0::6], shapes[:, 1, 1::6] = L, L
    shapes[:, 2, _BENDING] = _cubic_monomials(x, y)[0] @ coefficients
    M = rho * h * np.einsum("p,pik,pil->kl", weights, shapes, shapes)
    centroid = p.mean(axis=0)
    polar = rho * h * float(weights @ np.sum((points - centroid) ** 2, axis=1))
    return shell_parts_in_model_axes(axes, K, M, rho * h * weights, points, shapes, np.zeros(3), weights,
                                     np.zeros((len(weights), 3, 18)), polar / 9)
