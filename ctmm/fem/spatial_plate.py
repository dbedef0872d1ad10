"""Spatial rectangular plate element: Kirchhoff bending (ACM) with plane-stress membrane action (a flat shell).

A :class:`SpatialPlateElement` joins four nodes of a :class:`~ctmm.fem.SpatialFiniteElementModel` at the
corners of a rectangle, counter-clockwise about its normal; every node has six DOFs (model axes
``u_x, u_y, u_z, r_x, r_y, r_z``), shared with beams.  Local axes: ``x'`` from node 1 to node 2 (length
``a``), ``y'`` from node 1 to node 4 (length ``b``), normal ``z' = x' x y'``; local DOFs per node
``[u, v, w, r_x, r_y, r_z]`` (``r_x = dw/dy'``, ``r_y = -dw/dx'``: right-handed small rotations, as in the
beams).  Three parts (``docs/mixed.md`` §7b):

* **bending** -- the 12-DOF rectangle of Adini, Clough and Melosh (ACM, non-conforming Kirchhoff plate):
  ``w = P(s, t) c`` with ``s = x'/a``, ``t = y'/b`` and the twelve monomials
  ``P = [1, s, t, s^2, s t, t^2, s^3, s^2 t, s t^2, t^3, s^3 t, s t^3]``, ``c`` from the corner values of
  ``(w, r_x, r_y)``; stiffness ``int kappa^T D_b kappa dA`` with ``kappa = (w_xx, w_yy, 2 w_xy)``,
  ``D_b = D [[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu)/2]]``, ``D = E h^3 / (12 (1 - nu^2))``; consistent
  mass ``rho h int w^2 dA`` (the rotary inertia of the section, ``rho h^3/12``, is neglected: classical
  Kirchhoff plate);
* **membrane** -- the bilinear plane-stress quadrilateral of :func:`ctmm.fem.membrane.membrane_matrices`
  on ``(u, v)``, with its consistent mass;
* **drilling rotation** ``r_z`` (about the normal; Kirchhoff theory has no stiffness or inertia for it):
  a penalty ``1/2 sum_corners k_d (r_z - omega)^2`` tying it to the membrane's in-plane rotation
  ``omega = (dv/dx' - du/dy')/2`` at each corner, ``k_d = drilling_stiffness_ratio G h A / 4``
  (``G = E / (2 (1 + nu))``, ``A = a b``), and a lumped inertia ``rho h (A/4) (a^2 + b^2) / 48`` per
  corner (the polar inertia of the corner's quarter of the rectangle about its own centre).  Rigid
  motions stay free of strain energy; the penalty stiffens in-plane bending slightly, less on finer
  meshes; bending of a flat plate does not see it (uncoupled).

All integrals by 4 x 4 Gauss quadrature (exact: the integrands are polynomials of degree <= 6 in each
of ``s, t``).  Convergence of the ACM bending frequencies: ``O(h^2)`` (``docs/mixed.md`` §7b; the element
is non-conforming, so the frequencies are not bounds: they may approach from either side).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from .flat_shell import check_flat_shell
from .membrane import MembraneElement, membrane_matrices

__all__ = ["SpatialPlateElement", "plate_axes", "plate_local_matrices", "plate_shapes", "plate_rotation_block",
           "plate_drilling_inertia", "PLATE_GAUSS_POINTS", "PLATE_GAUSS_WEIGHTS"]

_X, _W = np.polynomial.legendre.leggauss(4)
_S, _WS = 0.5 * (_X + 1.0), 0.5 * _W
PLATE_GAUSS_POINTS = np.array([(s, t) for s in _S for t in _S])
"""Sixteen Gauss points ``(s, t)`` on the unit square (4 x 4, exact to degree 7 in each variable)."""
PLATE_GAUSS_WEIGHTS = np.array([ws * wt for ws in _WS for wt in _WS])
"""Their weights (sum 1)."""
_CORNERS = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@dataclass(frozen=True)
class SpatialPlateElement:
    """Rectangular flat-shell element (ACM bending + membrane) between four nodes (module docstring).

    Parameters
    ----------
    name : str
        Element name.
    nodes : (str, str, str, str)
        Corner nodes of a rectangle, counter-clockwise about the plate's normal ``z'``.
    thickness : float
        ``h`` [m], > 0.
    youngs_modulus : float
        ``E`` [Pa], > 0.
    poisson_ratio : float
        ``nu`` [-], ``0 <= nu < 0.5``.
    density : float
        ``rho`` [kg/m^3], > 0 (the rotations need the plate's inertia).
    drilling_stiffness_ratio : float
        ``k_d / (G h A / 4)`` of the drilling penalty [-], > 0; default 0.1 (``docs/mixed.md`` §7b).

    Examples
    --------
    >>> from ctmm.fem import SpatialFiniteElementModel, SpatialPlateElement
    >>> fe = SpatialFiniteElementModel("panel", {"a": (0, 0, 0), "b": (0.4, 0, 0), "c": (0.4, 0.3, 0),
    ...     "d": (0, 0.3, 0)}, [SpatialPlateElement("p", ("a", "b", "c", "d"), 0.002, 7e10, 0.3, 2700.0)])
    >>> fe.n_dofs, round(fe.floating_inertia("a").mass, 6)           # 4 nodes x 6 DOFs; rho h a b [kg]
    (24, 0.648)
    """

    name: str
    nodes: tuple
    thickness: float
    youngs_modulus: float
    poisson_ratio: float
    density: float
    drilling_stiffness_ratio: float = 0.1

    def __post_init__(self) -> None:
        check_flat_shell(self, 4, "rectangle")

    @property
    def bending_stiffness(self) -> float:
        """``D = E h^3 / (12 (1 - nu^2))`` [N m]."""
        return self.youngs_modulus * self.thickness ** 3 / (12.0 * (1.0 - self.poisson_ratio ** 2))


def plate_axes(corners: np.ndarray, owner: str) -> tuple[float, float, np.ndarray]:
    """Side lengths ``a, b`` [m] and local axes (rows ``x', y', z'`` in model axes) of a rectangle given by its
    corners ``(4, 3)`` [m] in element order, else :class:`ModelError`."""
    p = np.asarray(corners, dtype=float)
    ex, ey = p[1] - p[0], p[3] - p[0]
    a, b = float(np.linalg.norm(ex)), float(np.linalg.norm(ey))
    size = max(a, b)
    if not (a > 1e-9 * size and b > 1e-9 * size) or abs(float(ex @ ey)) > 1e-9 * a * b \
            or np.linalg.norm(p[2] - p[1] - ey) > 1e-9 * size:
        raise ModelError(f"{owner}: the four nodes must be the corners of a rectangle in element order (node 2 - node 1 "
                         f"perpendicular to node 4 - node 1, node 3 = node 2 + node 4 - node 1), got corners "
                         f"{p.tolist()}")
    x, y = ex / a, ey / b
    return a, b, np.vstack([x, y, np.cross(x, y)])


def _monomials(s: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, ...]:
    """``P`` and its derivatives ``P_s, P_t, P_ss, P_tt, P_st`` at ``(s, t)`` (each (..., 12))."""
    o, z = np.ones_like(s), np.zeros_like(s)
    P = np.stack([o, s, t, s * s, s * t, t * t, s ** 3, s * s * t, s * t * t, t ** 3, s ** 3 * t, s * t ** 3], -1)
    Ps = np.stack([z, o, z, 2 * s, t, z, 3 * s * s, 2 * s * t, t * t, z, 3 * s * s * t, t ** 3], -1)
    Pt = np.stack([z, z, o, z, s, 2 * t, z, s * s, 2 * s * t, 3 * t * t, s ** 3, 3 * s * t * t], -1)
    Pss = np.stack([z, z, z, 2 * o, z, z, 6 * s, 2 * t, z, z, 6 * s * t, z], -1)
    Ptt = np.stack([z, z, z, z, z, 2 * o, z, z, 2 * s, 6 * t, z, 6 * s * t], -1)
    Pst = np.stack([z, z, z, z, o, z, z, 2 * s, 2 * t, z, 3 * s * s, 3 * t * t], -1)
    return P, Ps, Pt, Pss, Ptt, Pst


def _bending_coefficients(a: float, b: float) -> np.ndarray:
    """``G`` (12 x 12): ``c = G d`` with ``d = [w, r_x, r_y]`` at the four corners."""
    P, Ps, Pt, _, _, _ = _monomials(_CORNERS[:, 0], _CORNERS[:, 1])
    rows = np.empty((12, 12))
    rows[0::3], rows[1::3], rows[2::3] = P, Pt / b, -Ps / a
    return np.linalg.inv(rows)


_BENDING = [6 * k + j for k in range(4) for j in (2, 3, 4)]     # local (w, r_x, r_y) of the four corners
_MEMBRANE = [6 * k + j for k in range(4) for j in (0, 1)]


def plate_shapes(points: np.ndarray, a: float, b: float) -> np.ndarray:
    """Local displacement interpolation ``[u, v, w](s, t) = S d_local``: ``(P, 3, 24)`` at ``points`` (P, 2)."""
    s, t = np.asarray(points, float)[:, 0], np.asarray(points, float)[:, 1]
    S = np.zeros((len(s), 3, 24))
    bilinear = np.stack([(1 - s) * (1 - t), s * (1 - t), s * t, (1 - s) * t], -1)
    for k in range(4):
        S[:, 0, 6 * k], S[:, 1, 6 * k + 1] = bilinear[:, k], bilinear[:, k]
    S[:, 2, _BENDING] = _monomials(s, t)[0] @ _bending_coefficients(a, b)
    return S


def plate_local_matrices(element: SpatialPlateElement, a: float, b: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Local ``(K, M, j)`` (24 x 24) of a plate element with sides ``a, b`` [m] (module docstring); ``j`` the
    drilling inertia per corner [kg m^2] (already on the diagonal of ``M``)."""
    E, nu, h, rho = element.youngs_modulus, element.poisson_ratio, element.thickness, element.density
    area = a * b
    G = _bending_coefficients(a, b)
    s, t = PLATE_GAUSS_POINTS[:, 0], PLATE_GAUSS_POINTS[:, 1]
    P, _, _, Pss, Ptt, Pst = _monomials(s, t)
    curvature = np.stack([Pss / a ** 2, Ptt / b ** 2, 2 * Pst / (a * b)], 1) @ G       # (P, 3, 12)
    Db = element.bending_stiffness * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1 - nu) / 2]])
    w = PLATE_GAUSS_WEIGHTS * area
    K, M = np.zeros((24, 24)), np.zeros((24, 24))
    bend = np.ix_(_BENDING, _BENDING)
    K[bend] = np.einsum("p,pik,ij,pjl->kl", w, curvature, Db, curvature)
    shape = P @ G
    M[bend] = rho * h * np.einsum("p,pk,pl->kl", w, shape, shape)
    membrane = MembraneElement(element.name, element.nodes, h, E, nu, rho)
    Km, Mm = membrane_matrices(membrane, np.array([[0.0, 0.0], [a, 0.0], [a, b], [0.0, b]]), element.name)
    mem = np.ix_(_MEMBRANE, _MEMBRANE)
    K[mem] += Km
    M[mem] += Mm
    k_d = element.drilling_stiffness_ratio * E / (2 * (1 + nu)) * h * area / 4
    for k, (sk, tk) in enumerate(_CORNERS):                   # omega = (dv/dx - du/dy) / 2 of the bilinear field
        dx = np.array([-(1 - tk), 1 - tk, tk, -tk]) / a
        dy = np.array([-(1 - sk), -sk, sk, 1 - sk]) / b
        row = np.zeros(24)
        row[6 * k + 5] = 1.0
        row[[6 * i + 1 for i in range(4)]] -= 0.5 * dx
        row[[6 * i for i in range(4)]] += 0.5 * dy
        K += k_d * np.outer(row, row)
    j = plate_drilling_inertia(element, a, b)
    for k in range(4):
        M[6 * k + 5, 6 * k + 5] += j
    return K, M, j


def plate_drilling_inertia(element: SpatialPlateElement, a: float, b: float) -> float:
    """Lumped drilling inertia per corner ``rho h (a b / 4) (a^2 + b^2) / 48`` [kg m^2] (module docstring)."""
    return element.density * element.thickness * a * b / 4 * (a * a + b * b) / 48


def plate_rotation_block(axes: np.ndarray) -> np.ndarray:
    """``T`` (24 x 24, local = ``T`` model) of a plate element with local ``axes`` (rows)."""
    T = np.zeros((24, 24))
    for k in range(8):
        T[3 * k:3 * k + 3, 3 * k:3 * k + 3] = axes
    return T
