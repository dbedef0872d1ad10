"""A subsystem given by global equations, coupled to a spatial transfer system as one body (d = 6).

:class:`SpatialSubsystem` is a body of :class:`ctmm.spatial.SpatialModel`, the spatial counterpart of
:class:`~ctmm.fem.GlobalSubsystem`: its **inboard boundary node** carries the floating frame (origin at
the node, orientation = the node's, given by the inboard joint); its internal coordinates are all other
DOFs, displacements and small rotations in that frame (``"<name>.<node>_ux|uy|uz|rx|ry|rz"``); its
**outboard boundary nodes** are the body's points, where children hang (their frames follow the node's
displacement and rotation).  The physics is in :mod:`ctmm.fem.spatial_terms`, the derivation and the
validation in ``docs/mixed.md`` §7.

The inertia integrals come from :class:`SpatialInertia`: by quadrature of the element shape functions
(:meth:`ctmm.fem.SpatialFiniteElementModel.subsystem`) or, for a user's global ``M``, from lumped masses
(translational DOF triples with equal diagonal masses, rotation DOFs rotary inertias about the model
axes); a consistent ``M`` from elsewhere does not determine the floating-frame couplings and is refused
unless ``inertia_integrals=`` is given.
"""
from __future__ import annotations

import dataclasses
import warnings
from dataclasses import KW_ONLY, dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from ..ops import NUMPY, Ops
from ..protocol import BodyTerms
from .family import SMALL_DEFORMATION, SmallDeformationWarning
from .model_parts import lumped_masses, square_matrix, subsystem_boundary, subsystem_nodes
from .spatial_terms import subsystem_terms

__all__ = ["SpatialInertia", "SpatialSubsystem", "SpatialSubsystemData", "lumped_spatial_inertia"]

_LABELS = ("ux", "uy", "uz", "rx", "ry", "rz")


@dataclass(frozen=True)
class SpatialInertia:
    """Inertia integrals of a spatial subsystem about its inboard node, frame axes, over all DOFs (``n``).

    Attributes
    ----------
    mass : float
        ``m`` [kg].
    first_moment : array (3,)
        ``s0 = int X dm`` [kg m].
    second_moment : array (3, 3)
        ``int X X^T dm`` [kg m^2].
    translation : array (3, n)
        ``S1 = int S dm``.
    coupling : array (3, 3, n)
        ``D_ik = int X_i S_k dm``.
    quadratic : array (3, 3, n, n)
        ``E_ik = int S_i^T S_k dm``.
    rotary : array (3, 3)
        ``J_r``: rotary inertia turning with the frame (sections, point inertias) [kg m^2].
    rotary_coupling : array (3, n)
        ``R_c``: its coupling to the rotation DOFs (``T_rot = 1/2 Omega^T ... Omega``, module docstring of
        :mod:`ctmm.fem.spatial_terms`).
    """

    mass: float
    first_moment: np.ndarray
    second_moment: np.ndarray
    translation: np.ndarray
    coupling: np.ndarray
    quadratic: np.ndarray
    rotary: np.ndarray
    rotary_coupling: np.ndarray


def lumped_spatial_inertia(owner: str, M: np.ndarray, positions: np.ndarray, node_dofs: Mapping[str, tuple],
                           frame_inertia: np.ndarray) -> SpatialInertia:
    """:class:`SpatialInertia` of a lumped (diagonal) ``M``, else :class:`ModelError`.  ``positions``: node
    positions relative to the inboard node (frame) by node name."""
    n = M.shape[0]
    d = lumped_masses(owner, M, "int S_i^T S_k dm", "SpatialFiniteElementModel", "SpatialInertia")
    mass, first, second = 0.0, np.zeros(3), np.zeros((3, 3))
    S1, D, E = np.zeros((3, n)), np.zeros((3, 3, n)), np.zeros((3, 3, n, n))
    J_r, R_c = np.array(frame_inertia, dtype=float), np.zeros((3, n))
    for node, dofs in node_dofs.items():
        t = dofs[:3]
        m = d[t[0]]
        if np.max(np.abs(d[list(t)] - m)) > 1e-12 * max(abs(m), 1e-300):
            raise ModelError(f"{owner}: the x, y and z masses of node {node!r} differ ({d[list(t)].tolist()}); a lumped "
                             "particle has one mass")
        X = positions[node]
        mass += m
        first += m * X
        second += m * np.outer(X, X)
        for k in range(3):
            S1[k, t[k]] = m
            for i in range(3):
                D[i, k, t[k]] += m * X[i]
                E[i, k, t[i], t[k]] = m
        if len(dofs) == 6:
            for k, i in enumerate(dofs[3:]):
                J_r[k, k] += d[i]
                R_c[k, i] = d[i]
    return SpatialInertia(mass, first, second, S1, D, E, J_r, R_c)


def _inertia_tensor(owner: str, value: Any) -> np.ndarray:
    a = validation.finite_array(f"{owner}: frame_inertia", value)
    negative = a.shape == (3,) and bool(np.any(a < 0.0))       # principal values: exact signs
    a = np.diag(a) if a.shape == (3,) else a
    scale = max(np.max(np.abs(a), initial=0.0), 1e-300)
    if negative or a.shape != (3, 3) or np.max(np.abs(a - a.T), initial=0.0) > 1e-12 * scale \
            or np.min(np.linalg.eigvalsh(a)) < -1e-12 * scale:
        raise ModelError(f"{owner}: frame_inertia must be 3 principal values >= 0 or a symmetric positive "
                         f"semi-definite 3 x 3 matrix [kg m^2], got {value!r}")
    return a


@dataclass(frozen=True, eq=False)
class SpatialSubsystem:
    """A subsystem ``M u'' + C u' + K u = f(u, u', t)`` in its floating frame, as a body of a spatial model
    (module docstring).

    Parameters
    ----------
    name : str
        Body name.
    mass_matrix, damping_matrix, stiffness_matrix : array (n, n)
        Symmetric ``M`` (positive definite on the internal DOFs), ``C``, ``K`` over all DOFs, frame axes
        [kg, kg m, kg m^2; N s/m ...; N/m ...].
    nodes : mapping of str to ((x, y, z), dofs)
        Node position [m] and its DOF indices ``(ix, iy, iz)`` or ``(ix, iy, iz, irx, iry, irz)``.
    boundary : sequence of str
        Boundary nodes, the inboard one first (it carries the frame); the others are the body's points.
    nonlinear_force : callable, optional
        ``f(u, u_dot, t) -> (n,)`` [N, N m] over all DOFs (frame DOFs passed as 0, their rows ignored); must
        accept complex arrays (complex-step tangents of ``ctmm.linearize`` and the frequency verbs).
    inertia_integrals : SpatialInertia, optional
        About the inboard node over all DOFs (default: from a lumped ``M``).
    frame_inertia : 3 numbers or (3, 3)
        Extra rotary inertia turning with the frame [kg m^2] (lumped ``M`` only).
    frame_nodes : sequence of str
        Further nodes held in the frame (anchors on the body the subsystem is mounted on).
    potential : callable, optional
        ``V(u) -> float`` [J] of the conservative part of ``nonlinear_force`` (for the energy).
    """

    name: str
    _: KW_ONLY
    mass_matrix: Any
    damping_matrix: Any
    stiffness_matrix: Any
    nodes: Mapping[str, Any]
    boundary: Sequence[str]
    nonlinear_force: Callable | None = None
    inertia_integrals: SpatialInertia | None = None
    frame_inertia: Any = (0.0, 0.0, 0.0)
    frame_nodes: Sequence[str] = ()
    potential: Callable | None = None

    def __post_init__(self) -> None:
        owner = validation.name("element", self.name)
        M = square_matrix(owner, "mass_matrix", self.mass_matrix, None)
        n = M.shape[0]
        C = square_matrix(owner, "damping_matrix", self.damping_matrix, n)
        K = square_matrix(owner, "stiffness_matrix", self.stiffness_matrix, n)
        positions, node_dofs = subsystem_nodes(owner, self.nodes, n, 3, 3)
        boundary, frame_nodes = subsystem_boundary(owner, self.boundary, self.frame_nodes, node_dofs,
                                                   self.nonlinear_force, self.potential)
        if "origin" in node_dofs and boundary[0] != "origin":
            raise ModelError(f"{owner}: the point name 'origin' is the inboard node; name node 'origin' otherwise "
                             f"(it is not the inboard node {boundary[0]!r})")
        frame_inertia = _inertia_tensor(owner, self.frame_inertia)
        origin = positions[boundary[0]].copy()
        relative = {node: p - origin for node, p in positions.items()}
        if self.inertia_integrals is None:
            inertia = lumped_spatial_inertia(owner, M, relative, node_dofs, frame_inertia)
        elif isinstance(self.inertia_integrals, SpatialInertia):
            inertia = _checked(owner, self.inertia_integrals, n)
            if np.any(frame_inertia):
                inertia = dataclasses.replace(inertia, rotary=inertia.rotary + frame_inertia)
        else:
            raise ModelError(f"{owner}: inertia_integrals must be a SpatialInertia, got {self.inertia_integrals!r}")
        keys = [tuple(np.round(relative[b], 12)) for b in boundary]
        if len(set(keys)) != len(keys):
            raise ModelError(f"{owner}: boundary nodes {boundary} must have distinct positions (they are the body's "
                             "points)")
        for attribute, value in (("mass_matrix", M), ("damping_matrix", C), ("stiffness_matrix", K),
                                 ("boundary", boundary), ("frame_inertia", frame_inertia), ("frame_nodes", frame_nodes)):
            object.__setattr__(self, attribute, value)
        object.__setattr__(self, "node_dofs", node_dofs)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "data", SpatialSubsystemData(self, inertia, relative))

    def __hash__(self) -> int:
        return hash(self.name)

    def __repr__(self) -> str:
        return (f"SpatialSubsystem({self.name!r}, {self.data.n} internal DOFs, boundary={self.boundary}, "
                f"mass {self.mass:.6g} kg)")

    # -- body interface of SpatialModel ------------------------------------------------------------
    @property
    def points(self) -> dict[str, np.ndarray]:
        """``"origin"`` (the inboard node) and the boundary nodes in the frame [m]."""
        return {"origin": np.zeros(3), **{node: self.data.position[node].copy() for node in self.boundary}}

    @property
    def mass(self) -> float:
        """Total mass [kg]."""
        return float(self.data.m)

    @property
    def center_of_mass(self) -> np.ndarray:
        """Undeformed centre of mass in the frame [m]."""
        return self.data.s0 / max(self.data.m, 1e-300)

    @property
    def inertia(self) -> np.ndarray:
        """Undeformed inertia about the centre of mass, frame axes [kg m^2]."""
        d, c = self.data, self.center_of_mass
        return d.J0 - d.m * (float(c @ c) * np.eye(3) - np.outer(c, c))

    @property
    def n_eta(self) -> int:
        """Number of internal coordinates."""
        return self.data.n

    @property
    def coordinate_suffixes(self) -> tuple[str, ...]:
        """``"<node>_ux"`` ... ``"<node>_rz"`` of the internal DOFs (after ``"<name>."``)."""
        return self.data.suffixes

    @property
    def coordinate_units(self) -> tuple[str, ...]:
        """``"m"`` for displacements, ``"rad"`` for rotations."""
        return tuple("rad" if s[-2] == "r" else "m" for s in self.data.suffixes)

    @property
    def time_dependent(self) -> bool:
        """True with a ``nonlinear_force`` (Python code: ``compiled=True`` cannot hold it)."""
        return self.nonlinear_force is not None

    @property
    def frequencies(self) -> np.ndarray:
        """Natural frequencies [rad/s] of the subsystem clamped at its inboard (and frame) nodes."""
        from scipy.linalg import eigh

        d = self.data
        return np.sqrt(np.clip(eigh(d.K, d.M, eigvals_only=True), 0.0, None)) if d.n else np.zeros(0)

    def modal_tangent(self, position_weight: float, velocity_weight: float) -> np.ndarray:
        """``b' h^2 K + g' h C`` (n x n) for the implicit schemes' Newton tangent."""
        return position_weight * self.data.K + velocity_weight * self.data.C

    def spatial_terms(self, ops: Ops, **arguments: Any) -> tuple[BodyTerms, dict]:
        """:func:`ctmm.fem.spatial_terms.subsystem_terms` of this body (same keyword arguments)."""
        return subsystem_terms(ops, self.data, **arguments)

    # -- ports ---------------------------------------------------------------------------------------
    def sensor_rows(self) -> list:
        """No extra sensors: the node DOFs are coordinates (sensors ``"<name>.<node>_uy"`` ...)."""
        return []

    def actuator_rows(self) -> list[tuple[str, int, tuple, str]]:
        """Moment actuators ``"<name>.<node>.moment_x|y|z"`` (world axes) at the points (``origin``, boundary nodes)."""
        return [(f"{self.name}.{node}.moment_{a}", 3 + c, tuple(r), "N m") for node, r in self.points.items()
                for c, a in enumerate("xyz")]

    def deformed_point(self, point: Any, eta: np.ndarray, *, rate: bool = False) -> np.ndarray:
        """Frame position ``X + u`` [m] of the node at ``point`` (``rate``: its velocity relative to the frame);
        ``eta`` (n,) or (B, n), real or complex."""
        d = self.data
        key = tuple(np.round(np.asarray(point, dtype=float), 12))
        if key not in d.node_at_position:
            raise ModelError(f"subsystem {self.name!r}: {np.asarray(point).tolist()} m is not a node (sensors read nodes)")
        X, trans, _ = d.point_rows[d.node_at_position[key]]
        eta = np.asarray(eta)
        moved = eta[..., list(trans)] if trans is not None else np.zeros(eta.shape[:-1] + (3,))
        return moved if rate else moved + X

    # -- energy and the small-deformation guard ------------------------------------------------------
    def energy(self, rotation: np.ndarray, origin: np.ndarray, velocity: np.ndarray, omega: np.ndarray,
               eta: np.ndarray, eta_dot: np.ndarray, gravity: np.ndarray) -> np.ndarray:
        """Kinetic ``1/2 V^T M_b V`` (``V = [R^T v ; R^T omega ; u_dot]``), strain ``1/2 u^T K u``, the
        ``potential`` of ``nonlinear_force`` (refused without it) and gravitational energy [J], batch (B,)."""
        d = self.data
        B = eta.shape[0]
        terms, _ = subsystem_terms(NUMPY, d, rotation=np.eye(3)[None], offset=None, omega=None, eta=eta[:, :, None],
                                   eta_dot=np.zeros_like(eta)[:, :, None], t=0.0, gravity=np.zeros(3))
        M_b = np.broadcast_to(terms.M, (B,) + terms.M.shape[-2:])
        Rt = np.swapaxes(rotation, 1, 2)
        V = np.concatenate([Rt @ velocity, Rt @ omega, eta_dot[:, :, None]], axis=1)
        kinetic = 0.5 * (np.swapaxes(V, 1, 2) @ M_b @ V)[:, 0, 0]
        strain = 0.5 * np.einsum("bi,ij,bj->b", eta, d.K, eta)
        s = d.s0[None, :] + eta @ d.S1.T
        height = (d.m * origin[:, :, 0] + (rotation @ s[:, :, None])[:, :, 0]) @ gravity
        total = kinetic + strain - height
        if self.nonlinear_force is not None:
            if self.potential is None:
                raise ModelError(f"the energy of subsystem {self.name!r} needs the potential of its nonlinear_force: "
                                 "pass potential=V(u) [J]")
            for b in range(B):
                u = np.zeros(d.n_all)
                u[d.keep] = eta[b]
                total[b] += float(self.potential(u))
        return total

    def check_deformation(self, model_name: str, t: Any, rows: np.ndarray, method: str,
                          partial: Callable[[], Any] | None = None) -> None:
        """Small deformation in the floating frame (``docs/mixed.md`` §7): warn
        (:class:`~ctmm.fem.SmallDeformationWarning`) when a node moves by more than
        :data:`~ctmm.fem.family.SMALL_DEFORMATION` of the subsystem's size or a node rotation exceeds that
        many radians; raise :class:`SimulationError` (time, this body, ``partial()``) beyond the size itself
        or 1 rad.  ``rows`` (k, n) internal coordinates at times ``t`` (k,)."""
        d = self.data
        rows = np.atleast_2d(rows)
        moved = np.max(np.abs(rows[:, d.translational]), axis=1, initial=0.0)
        turned = np.max(np.abs(rows[:, ~d.translational]), axis=1, initial=0.0)
        bad = np.flatnonzero((moved > d.size) | (turned > 1.0) | ~np.isfinite(moved + turned))
        if len(bad):
            row = int(bad[0])
            time = float(np.atleast_1d(t)[row] if np.ndim(t) else t)
            raise SimulationError(
                f"{model_name}: simulation diverged at t = {time:.6g} s ({method}): subsystem {self.name!r} node "
                f"displacement {moved[row]:.3g} m (size {d.size:.3g} m) or rotation {turned[row]:.3g} rad (limit 1 rad) "
                "far outside the small deformation of its floating frame; the explicit step limit is 2 sqrt 2 / "
                f"omega_max = {2 * np.sqrt(2) / max(float(np.max(self.frequencies, initial=0.0)), 1e-300):.3g} s",
                time=time, element=self.name, partial_result=partial() if partial is not None else None)
        if np.any(d.linear_elastic & ((moved > SMALL_DEFORMATION * d.size) | (turned > SMALL_DEFORMATION))):
            warnings.warn(f"subsystem {self.name!r}: a node moves by more than {SMALL_DEFORMATION:g} of the subsystem's "
                          f"size {d.size:.3g} m or turns by more than {SMALL_DEFORMATION:g} rad: outside the small "
                          "deformation of its floating frame (docs/mixed.md §7)", SmallDeformationWarning, stacklevel=2)


def _checked(owner: str, inertia: SpatialInertia, n: int) -> SpatialInertia:
    shapes = {"first_moment": (3,), "second_moment": (3, 3), "translation": (3, n), "coupling": (3, 3, n),
              "quadratic": (3, 3, n, n), "rotary": (3, 3), "rotary_coupling": (3, n)}
    values = {"mass": validation.nonnegative(f"{owner}: inertia_integrals.mass", inertia.mass)}
    for attribute, shape in shapes.items():
        value = validation.finite_array(f"{owner}: inertia_integrals.{attribute}", getattr(inertia, attribute))
        if value.shape != shape:
            raise ModelError(f"{owner}: inertia_integrals.{attribute} must have shape {shape} ({n} DOFs), got "
                             f"{value.shape}")
        values[attribute] = value
    return SpatialInertia(**values)


class SpatialSubsystemData:
    """Reduced matrices, inertia integrals and point rows of a :class:`SpatialSubsystem` (numpy constants read
    by :func:`ctmm.fem.spatial_terms.subsystem_terms`)."""

    def __init__(self, body: SpatialSubsystem, inertia: SpatialInertia, positions: Mapping[str, np.ndarray]) -> None:
        self.body, self.inertia = body, inertia
        n_all = body.mass_matrix.shape[0]
        held = {i for node in (body.boundary[0],) + body.frame_nodes for i in body.node_dofs[node]}
        keep = np.array([i for i in range(n_all) if i not in held], dtype=int)
        self.keep, self.n_all, self.n = keep, n_all, int(keep.size)
        names = {i: f"{node}_{_LABELS[k]}" for node, dofs in body.node_dofs.items() for k, i in enumerate(dofs)}
        self.suffixes = tuple(names[i] for i in keep)
        sub = np.ix_(keep, keep)
        self.M, self.C, self.K = body.mass_matrix[sub], body.damping_matrix[sub], body.stiffness_matrix[sub]
        if self.n and not np.min(np.linalg.eigvalsh(self.M)) > 1e-12 * np.max(np.abs(self.M), initial=0.0):
            massless = [names[i] for i in keep if body.mass_matrix[i, i] <= 0.0] or "none on the diagonal, but M is singular"
            raise ModelError(f"{body.name}: the mass matrix of the internal DOFs must be positive definite; massless: "
                             f"{massless}; hold such nodes in the frame (frame_nodes) or give them mass")
        self.m, self.s0 = float(inertia.mass), np.asarray(inertia.first_moment, float)
        self.SXX = np.asarray(inertia.second_moment, float)
        self.S1 = inertia.translation[:, keep]
        self.D = inertia.coupling[:, :, keep]
        E = inertia.quadratic[:, :, keep][:, :, :, keep]
        self.E_stack = E.reshape(9 * self.n, self.n)                  # block 3 i + k: E_ik
        self.D_stack = self.D.reshape(9, self.n)                       # row 3 i + k: D_ik
        self.J_rot, self.R_c = np.asarray(inertia.rotary, float), inertia.rotary_coupling[:, keep]
        self.J0 = np.trace(self.SXX) * np.eye(3) - self.SXX + self.J_rot
        local = {i: k for k, i in enumerate(keep)}
        self.position = dict(positions)
        self.point_rows, self.node_at_position = {}, {}
        for node, dofs in body.node_dofs.items():
            trans = tuple(local[i] for i in dofs[:3]) if dofs[0] in local else None
            rot = tuple(local[i] for i in dofs[3:]) if len(dofs) == 6 and dofs[3] in local else None
            self.point_rows[node] = (self.position[node], trans, rot)
            self.node_at_position.setdefault(tuple(np.round(self.position[node], 12)), node)
        self.point_rows["origin"] = self.point_rows[body.boundary[0]]
        for node in body.boundary:                                      # boundary nodes win shared positions
            self.node_at_position[tuple(np.round(self.position[node], 12))] = node
        self.translational = np.array([not s[-2] == "r" for s in self.suffixes], dtype=bool)
        self.linear_elastic = bool(np.any(self.K) or np.any(self.C))
        self.size = max([float(np.linalg.norm(p)) for p in self.position.values()] + [1e-3])
