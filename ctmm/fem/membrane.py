"""Planar membrane (plane-stress) quadrilateral: the in-plane "equivalent flexible plate" of seed 001 §9.2.

A :class:`MembraneElement` joins four named nodes (counter-clockwise) of a
:class:`~ctmm.fem.assembly.FiniteElementModel`; each node has the in-plane displacements ``(u_x, u_y)``
[m].  The element is the isoparametric bilinear quadrilateral (Q4)::

    N_a(xi, eta) = (1 + xi_a xi)(1 + eta_a eta) / 4,   (xi_a, eta_a) = (-1,-1), (1,-1), (1,1), (-1,1)
    u(xi, eta) = sum_a N_a u_a,   x(xi, eta) = sum_a N_a x_a

with plane-stress elasticity ``D = E / (1 - nu^2) [[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu)/2]]`` and
thickness ``t``: stiffness ``K = t int B^T D B dA`` (2 x 2 Gauss, the usual full integration),
consistent mass ``M = rho t int N^T N dA`` (3 x 3 Gauss: exact for any straight-sided quadrilateral,
whose integrand ``N^T N det J`` is of degree 3 in each of ``xi, eta``).  A plate that moves in its own
plane carries loads by membrane action only: this element is the planar projection of a plate (its
out-of-plane bending is not a planar motion).  Convergence: frequencies at ``O(h^2)`` (``docs/mixed.md``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import validation
from ..errors import ModelError

__all__ = ["MembraneElement", "membrane_matrices", "membrane_shape_points", "bilinear_shape"]

_CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
_G2 = np.polynomial.legendre.leggauss(2)
_G3 = np.polynomial.legendre.leggauss(3)


@dataclass(frozen=True)
class MembraneElement:
    """Plane-stress bilinear quadrilateral between four nodes (counter-clockwise).

    Parameters
    ----------
    name : str
    nodes : (str, str, str, str)
        Corner nodes, counter-clockwise.
    thickness : float
        ``t`` [m], > 0.
    youngs_modulus : float
        ``E`` [Pa], > 0.
    poisson_ratio : float
        ``nu`` [-], ``0 <= nu < 0.5``.
    density : float
        ``rho`` [kg/m^3], >= 0.

    Examples
    --------
    >>> from ctmm.fem import FiniteElementModel, MembraneElement
    >>> fe = FiniteElementModel("sheet", {"a": (0, 0), "b": (1, 0), "c": (1, 1), "d": (0, 1)},
    ...     [MembraneElement("q", ("a", "b", "c", "d"), 0.002, 7e10, 0.3, 2700.0)])
    >>> round(float(fe.mass.sum()) / 2, 6)                         # rho t A per direction [kg]
    5.4
    """

    name: str
    nodes: tuple
    thickness: float
    youngs_modulus: float
    poisson_ratio: float
    density: float

    def __post_init__(self) -> None:
        validation.name("element", self.name)
        nodes = tuple(self.nodes) if isinstance(self.nodes, (tuple, list)) else ()
        if len(nodes) != 4 or not all(isinstance(n, str) and n for n in nodes) or len(set(nodes)) != 4:
            raise ModelError(f"{self.name}: nodes must be four distinct node names (counter-clockwise), "
                             f"got {self.nodes!r}")
        object.__setattr__(self, "nodes", nodes)
        for attribute in ("thickness", "youngs_modulus"):
            object.__setattr__(self, attribute, validation.positive(f"{self.name}: {attribute}",
                                                                    getattr(self, attribute)))
        object.__setattr__(self, "density", validation.nonnegative(f"{self.name}: density", self.density))
        nu = validation.nonnegative(f"{self.name}: poisson_ratio", self.poisson_ratio)
        if not nu < 0.5:
            raise ModelError(f"{self.name}: poisson_ratio must be in [0, 0.5), got {self.poisson_ratio!r}")
        object.__setattr__(self, "poisson_ratio", nu)


def bilinear_shape(xi: float, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """``N`` (4,) and ``dN/d(xi, eta)`` (2, 4) of the bilinear quadrilateral."""
    n = 0.25 * (1 + _CORNERS[:, 0] * xi) * (1 + _CORNERS[:, 1] * eta)
    d = 0.25 * np.array([_CORNERS[:, 0] * (1 + _CORNERS[:, 1] * eta), _CORNERS[:, 1] * (1 + _CORNERS[:, 0] * xi)])
    return n, d


def _jacobian(corners: np.ndarray, d: np.ndarray, owner: str) -> tuple[float, np.ndarray]:
    jac = d @ corners                                              # (2, 2): d(x, y)/d(xi, eta)
    det = float(np.linalg.det(jac))
    if not det > 0.0:
        raise ModelError(f"{owner}: the quadrilateral is degenerate, clockwise or not convex (det J = {det:.3g} "
                         "at a Gauss point); give its four nodes counter-clockwise around a convex quadrilateral")
    return det, jac


def membrane_matrices(element: MembraneElement, corners: np.ndarray, owner: str = "") -> tuple[np.ndarray, np.ndarray]:
    """``(K, M)`` (8 x 8) of a membrane element, DOFs ``[u_x1, u_y1, ..., u_x4, u_y4]`` (model axes).

    Parameters
    ----------
    element : MembraneElement
    corners : (4, 2) array
        Node positions [m], in the element's node order.
    owner : str
        Name used in error messages.
    """
    corners = np.asarray(corners, float)
    E, nu, t = element.youngs_modulus, element.poisson_ratio, element.thickness
    D = E / (1 - nu * nu) * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1 - nu) / 2]])
    K, M = np.zeros((8, 8)), np.zeros((8, 8))
    label = f"{owner}: {element.name}" if owner else element.name
    for xi, wx in zip(*_G2):
        for eta, wy in zip(*_G2):
            _, d = bilinear_shape(xi, eta)
            det, jac = _jacobian(corners, d, label)
            dxy = np.linalg.solve(jac, d)                         # (2, 4): dN/d(x, y)
            B = np.zeros((3, 8))
            B[0, 0::2], B[1, 1::2] = dxy[0], dxy[1]
            B[2, 0::2], B[2, 1::2] = dxy[1], dxy[0]
            K += t * wx * wy * det * B.T @ D @ B
    for point, weight, shape in zip(*membrane_shape_points(corners, label)):
        M += element.density * t * weight * shape.T @ shape
    return K, M


def membrane_shape_points(corners: np.ndarray, owner: str = "") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss points (3 x 3) of a quadrilateral: positions ``(9, 2)`` [m], area weights ``(9,)`` [m^2] and
    displacement interpolation ``(9, 2, 8)`` (``u(point) = S d`` with ``d = [u_x1, u_y1, ..., u_y4]``)."""
    corners = np.asarray(corners, float)
    points, weights, shapes = [], [], []
    for xi, wx in zip(*_G3):
        for eta, wy in zip(*_G3):
            n, d = bilinear_shape(xi, eta)
            det, _ = _jacobian(corners, d, owner)
            S = np.zeros((2, 8))
            S[0, 0::2], S[1, 1::2] = n, n
            points.append(n @ corners)
            weights.append(wx * wy * det)
            shapes.append(S)
    return np.array(points), np.array(weights), np.array(shapes)
