"""Planar finite elements: Euler-Bernoulli (optionally Timoshenko) beam, point mass, spring-damper between nodes.

Every element lives between named nodes of a :class:`~ctmm.fem.assembly.FiniteElementModel`.  A node
has the displacement degrees of freedom ``(u_x, u_y)`` [m] in the model's axes and, when a beam
touches it, a rotation ``r_z`` [rad].

**Beam** (``docs/mixed.md`` §2): local axis ``x'`` from node ``a`` to node ``b`` (length ``L``, angle
``beta``), local DOFs ``[u_a, v_a, r_a, u_b, v_b, r_b]``; axial displacement linear, transverse Hermite
cubic::

    u(xi) = (1 - xi) u_a + xi u_b
    v(xi) = H1 v_a + L H2 r_a + H3 v_b + L H4 r_b,   H1 = 1 - 3 xi^2 + 2 xi^3, H2 = xi - 2 xi^2 + xi^3,
                                                     H3 = 3 xi^2 - 2 xi^3,     H4 = -xi^2 + xi^3

Stiffness ``EA/L`` (axial) and ``EI/L^3 [[12, 6L, -12, 6L], ...]``, consistent mass
``rhoA L/6 [[2, 1], [1, 2]]`` and ``rhoA L/420 [[156, 22L, 54, -13L], ...]``, geometric stiffness of a
constant axial force ``N`` (tension > 0) ``N/(30 L) [[36, 3L, -36, 3L], ...]`` (Przemieniecki,
"Theory of Matrix Structural Analysis", 1968, ch. 5 and 11).  With ``shear_stiffness`` (``kappa G A``) or
``rotary_inertia_per_length`` (``rho I``) the bending part is the Timoshenko element of
:mod:`ctmm.fem.timoshenko` (the rotation DOF is then the section rotation, not the slope).  Global = ``T^T k T`` with
``T = diag(r, r)``, ``r = [[c, s, 0], [-s, c, 0], [0, 0, 1]]``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import validation
from ..errors import ModelError
from .model_parts import TwoNodeSpring, node_name
from .timoshenko import bending_matrices, bending_shapes

__all__ = ["BeamElement", "PointMass", "NodeSpring", "beam_local_matrices", "beam_shape_functions",
           "beam_section_rotation"]


@dataclass(frozen=True)
class BeamElement:
    """Planar Euler-Bernoulli beam element between two nodes (module docstring).

    Parameters
    ----------
    name : str
        Element name.
    start, end : str
        Node names.
    bending_stiffness : float
        ``EI`` [N m^2], > 0.
    axial_stiffness : float
        ``EA`` [N], > 0.
    mass_per_length : float
        ``rhoA`` [kg/m], > 0 (a massless beam would leave its rotation DOFs without inertia).
    axial_force : float
        Constant axial force ``N`` [N] (tension > 0) of the geometric stiffness; default 0 (off).
    shear_stiffness : float or None
        ``kappa G A`` [N], > 0 (shear coefficient ``kappa`` times shear modulus times area): Timoshenko shear
        deformation; default None (Euler-Bernoulli, rigid in shear).
    rotary_inertia_per_length : float
        ``rho I`` [kg m], >= 0: rotary inertia of the sections in bending; default 0.
    """

    name: str
    start: str
    end: str
    bending_stiffness: float
    axial_stiffness: float
    mass_per_length: float
    axial_force: float = 0.0
    shear_stiffness: float | None = None
    rotary_inertia_per_length: float = 0.0

    def __post_init__(self) -> None:
        validation.name("element", self.name)
        n = self.name
        node_name(n, "start", self.start)
        node_name(n, "end", self.end)
        if self.start == self.end:
            raise ModelError(f"{n}: start and end must be different nodes, got {self.start!r} twice")
        object.__setattr__(self, "bending_stiffness", validation.positive(f"{n}: bending_stiffness",
                                                                          self.bending_stiffness))
        object.__setattr__(self, "axial_stiffness", validation.positive(f"{n}: axial_stiffness",
                                                                        self.axial_stiffness))
        object.__setattr__(self, "mass_per_length", validation.positive(f"{n}: mass_per_length",
                                                                           self.mass_per_length))
        object.__setattr__(self, "axial_force", validation.finite(f"{n}: axial_force", self.axial_force))
        if self.shear_stiffness is not None:
            object.__setattr__(self, "shear_stiffness", validation.positive(
                f"{n}: shear_stiffness (kappa G A [N], or None for no shear deformation)", self.shear_stiffness))
        object.__setattr__(self, "rotary_inertia_per_length", validation.nonnegative(
            f"{n}: rotary_inertia_per_length", self.rotary_inertia_per_length))


@dataclass(frozen=True)
class PointMass:
    """A mass (and rotary inertia) at a node.

    Parameters
    ----------
    name : str
    node : str
    mass : float
        [kg], > 0.
    inertia : float
        Rotary inertia about the node [kg m^2], >= 0.  On a node without a rotation DOF it turns with
        the subsystem's floating frame.
    """

    name: str
    node: str
    mass: float
    inertia: float = 0.0

    def __post_init__(self) -> None:
        validation.name("element", self.name)
        node_name(self.name, "node", self.node)
        object.__setattr__(self, "mass", validation.positive(f"{self.name}: mass", self.mass))
        object.__setattr__(self, "inertia", validation.nonnegative(f"{self.name}: inertia", self.inertia))


@dataclass(frozen=True)
class NodeSpring(TwoNodeSpring):
    """Linear spring and viscous damper between two nodes, along the line joining their undeformed
    positions (small displacements), optionally a rotational spring-damper between their rotations.

    Parameters
    ----------
    name : str
    start, end : str
        Node names (distinct positions when ``stiffness`` or ``damping`` is set).
    stiffness, damping : float
        Axial [N/m], [N s/m], >= 0.
    rotational_stiffness, rotational_damping : float
        [N m/rad], [N m s/rad], >= 0; both nodes need rotation DOFs (a beam at each).
    """


def beam_local_matrices(length: float, bending_stiffness: float, axial_stiffness: float, mass_per_length: float,
                        axial_force: float = 0.0, *, shear_stiffness: float | None = None,
                        rotary_inertia_per_length: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local ``(K, M, K_G)`` (6 x 6) of a beam element, DOFs ``[u_a, v_a, r_a, u_b, v_b, r_b]``.

    Parameters
    ----------
    length : float
        [m], > 0.
    bending_stiffness, axial_stiffness, mass_per_length, axial_force : float
        ``EI`` [N m^2] > 0, ``EA`` [N] > 0, ``rhoA`` [kg/m] >= 0, ``N`` [N] finite.
    shear_stiffness : float or None
        ``kappa G A`` [N] > 0 (Timoshenko, :mod:`ctmm.fem.timoshenko`); None: Euler-Bernoulli.
    rotary_inertia_per_length : float
        ``rho I`` [kg m] >= 0.
    """
    L = validation.positive("beam_local_matrices: length", length)
    EI = validation.positive("beam_local_matrices: bending_stiffness", bending_stiffness)
    EA = validation.positive("beam_local_matrices: axial_stiffness", axial_stiffness)
    rA = validation.nonnegative("beam_local_matrices: mass_per_length", mass_per_length)
    axial_force = validation.finite("beam_local_matrices: axial_force", axial_force)
    K = np.zeros((6, 6))
    M = np.zeros((6, 6))
    G = np.zeros((6, 6))
    ax, tr = [0, 3], [1, 2, 4, 5]
    K[np.ix_(ax, ax)] = EA / L * np.array([[1.0, -1.0], [-1.0, 1.0]])
    K[np.ix_(tr, tr)] = EI / L ** 3 * np.array([[12, 6 * L, -12, 6 * L], [6 * L, 4 * L * L, -6 * L, 2 * L * L],
                                                [-12, -6 * L, 12, -6 * L], [6 * L, 2 * L * L, -6 * L, 4 * L * L]])
    M[np.ix_(ax, ax)] = rA * L / 6 * np.array([[2.0, 1.0], [1.0, 2.0]])
    M[np.ix_(tr, tr)] = rA * L / 420 * np.array([[156, 22 * L, 54, -13 * L], [22 * L, 4 * L * L, 13 * L, -3 * L * L],
                                                 [54, 13 * L, 156, -22 * L], [-13 * L, -3 * L * L, -22 * L, 4 * L * L]])
    G[np.ix_(tr, tr)] = axial_force / (30 * L) * np.array([[36, 3 * L, -36, 3 * L], [3 * L, 4 * L * L, -3 * L, -L * L],
                                                          [-36, -3 * L, 36, -3 * L], [3 * L, -L * L, -3 * L, 4 * L * L]])
    rI = validation.nonnegative("beam_local_matrices: rotary_inertia_per_length", rotary_inertia_per_length)
    if shear_stiffness is not None or rI:
        K[np.ix_(tr, tr)], M[np.ix_(tr, tr)], G[np.ix_(tr, tr)] = bending_matrices(
            L, EI, shear_stiffness, rA, rI, axial_force, "beam_local_matrices")
    return K, M, G


def beam_shape_functions(xi: np.ndarray, length: float, shear: float = 0.0) -> np.ndarray:
    """Local displacement interpolation ``[u, v](xi) = N(xi) d_local``: ``(len(xi), 2, 6)``; ``shear`` the
    parameter ``phi = 12 EI / (kappa G A L^2)`` of a Timoshenko element (:mod:`ctmm.fem.timoshenko`)."""
    xi = np.asarray(xi, dtype=float)
    N = np.zeros(xi.shape + (2, 6))
    N[..., 0, 0] = 1 - xi
    N[..., 0, 3] = xi
    N[..., 1, [1, 2, 4, 5]] = bending_shapes(xi, length, shear)[0]
    return N


def beam_section_rotation(xi: np.ndarray, length: float, shear: float = 0.0) -> np.ndarray:
    """Local section-rotation interpolation ``theta(xi) = B(xi) d_local``: ``(len(xi), 6)``."""
    B = np.zeros(np.shape(xi) + (6,))
    B[..., [1, 2, 4, 5]] = bending_shapes(xi, length, shear)[2]
    return B


def beam_rotation(start: np.ndarray, end: np.ndarray, owner: str) -> tuple[float, np.ndarray]:
    """Length [m] and ``T`` (6 x 6, local = ``T`` global) of a beam between two node positions."""
    d = np.asarray(end, float) - np.asarray(start, float)
    length = math.hypot(d[0], d[1])
    if not length > 0.0:
        raise ModelError(f"{owner}: its nodes coincide (length 0); a beam needs two distinct node positions")
    c, s = d / length
    r = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    T = np.zeros((6, 6))
    T[:3, :3] = T[3:, 3:] = r
    return length, T
