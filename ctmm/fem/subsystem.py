"""A subsystem given by global equations, coupled to a planar transfer system as one body.

:class:`GlobalSubsystem` is a planar body of :class:`~ctmm.planar.PlanarModel` (a
:class:`~ctmm.planar.deformable.DeformableBody`): its **inboard boundary node** carries the floating
frame (origin at the node, angle = the node's rotation, the body coordinate ``"name.theta"``); its
internal coordinates are all other DOFs, displacements in that frame; its **outboard boundary
nodes** are the body's points, where children hang.  A material point at ``X`` (frame, undeformed)
is at ``r = r_I + R(theta) (X + S(X) u)``.  Kane's equations with the speeds ``(v_I, omega, u_dot)``
give, in the frame (``docs/mixed.md`` §3; ``J`` the rotation by +90 degrees)::

    [F_I ; 0] = M_b(u) [a_I ; alpha ; u''] + h_b + sum_e Kin_e^T F_e
    M_b = [[m I,      J s,     S1        ],       s(u) = s0 + S1 u,   I(u) = I0 + 2 Sigma u + u^T M_t u
           [(J s)^T,  I(u),    (Gam+G u)^T],       Gam = int S^T J X dm (+ rotary inertias),
           [S1^T,     Gam+G u, M         ]]       G = int S^T J S dm (skew), M_t = int S^T S dm
    h_b = [-w^2 s + 2 w J S1 u' - m g_b ;
           2 w (Sigma + u^T M_t) u' - (J s) . g_b ;
           -w^2 (Sigma^T + M_t u) + 2 w G u' - S1^T g_b + K u + C u' - f(u, u', t)]
    A_e = Kin_e [a_I ; alpha ; u''] + c_e,   Kin_e = [[I, J rho_e, S_e], [0, 1, P_e]],
    c_e = [-w^2 rho_e + 2 w J rho_e' ; 0],    rho_e = X_e + S_e u

rotated to global axes with ``T = diag(R, 1, I_n)``.  The one articulated sweep eliminates ``u''``
exactly (``W = M^-1 [M_er, h_e]``): the static-and-dynamic condensation of the subsystem onto its
inboard boundary -- the §9.2 mixed method's boundary unknowns solved without iteration.

The inertia integrals come from :class:`FloatingInertia`: by quadrature of the shape functions
(:meth:`ctmm.fem.FiniteElementModel.subsystem`) or, for a user's global ``M``, from lumped masses
(translational DOF pairs with equal diagonal masses and no coupling; rotation DOFs rotary
inertias).  A consistent ``M`` from elsewhere does not determine ``G`` and ``M_t``: pass
``inertia_integrals=`` or use :class:`~ctmm.fem.FiniteElementModel`; anything else is refused.
"""
from __future__ import annotations

import dataclasses
from dataclasses import KW_ONLY, dataclass
from typing import Any, Callable, ClassVar, Mapping, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from ..planar.deformable import DeformableBody
from .family import SubsystemFamily
from .model_parts import lumped_masses, square_matrix, subsystem_boundary, subsystem_nodes

__all__ = ["FloatingInertia", "GlobalSubsystem", "SubsystemData", "lumped_inertia"]

_J = np.array([[0.0, -1.0], [1.0, 0.0]])


@dataclass(frozen=True)
class FloatingInertia:
    """Inertia integrals of a subsystem about its frame origin (all DOFs, module docstring).

    Attributes
    ----------
    mass : float
        ``m`` [kg].
    first_moment : array (2,)
        ``s0 = int X dm`` [kg m].
    polar : float
        ``I0 = int |X|^2 dm`` plus rotary inertias [kg m^2].
    translation : array (2, n)
        ``S1 = int S dm``.
    sigma : array (n,)
        ``int X^T S dm``.
    gamma : array (n,)
        ``int S^T J X dm`` plus the rotary inertia of each rotation DOF.
    gyroscopic : array (n, n)
        ``G = int S^T J S dm`` (skew).
    translational_mass : array (n, n)
        ``M_t = int S^T S dm``.
    """

    mass: float
    first_moment: np.ndarray
    polar: float
    translation: np.ndarray
    sigma: np.ndarray
    gamma: np.ndarray
    gyroscopic: np.ndarray
    translational_mass: np.ndarray


def lumped_inertia(owner: str, M: np.ndarray, positions: np.ndarray, kinds: np.ndarray, pairs: Sequence[tuple],
                   frame_inertia: float = 0.0) -> FloatingInertia:
    """:class:`FloatingInertia` of a lumped mass matrix, else :class:`ModelError`.

    ``positions`` (n, 2): the node position of each DOF (frame, relative to the origin); ``kinds`` (n,)
    0 = x, 1 = y, 2 = rotation; ``pairs``: ``(ix, iy)`` per node.
    """
    n = M.shape[0]
    d = lumped_masses(owner, M, "int S^T J S dm", "FiniteElementModel", "FloatingInertia")
    for ix, iy in pairs:
        if abs(d[ix] - d[iy]) > 1e-12 * max(abs(d[ix]), 1e-300):
            raise ModelError(f"{owner}: the x and y masses of a node differ (M[{ix},{ix}] = {d[ix]!r}, M[{iy},{iy}] = "
                             f"{d[iy]!r}); a lumped particle has one mass")
    translational = kinds < 2
    Mt = np.diag(np.where(translational, d, 0.0))
    S1 = np.zeros((2, n))
    sigma, gamma, G = np.zeros(n), np.zeros(n), np.zeros((n, n))
    first, polar, mass = np.zeros(2), float(frame_inertia), 0.0
    for ix, iy in pairs:
        m, X = d[ix], positions[ix]
        mass += m
        first += m * X
        polar += m * float(X @ X)
        S1[0, ix] = S1[1, iy] = m
        sigma[ix], sigma[iy] = m * X[0], m * X[1]
        gamma[ix], gamma[iy] = -m * X[1], m * X[0]
        G[ix, iy], G[iy, ix] = -m, m
    for i in np.flatnonzero(kinds == 2):
        polar += d[i]
        gamma[i] += d[i]
    return FloatingInertia(mass, first, polar, S1, sigma, gamma, G, Mt)


def _checked_inertia(owner: str, inertia: FloatingInertia, n: int) -> FloatingInertia:
    """``inertia`` with float arrays of the shapes of ``n`` DOFs, else :class:`ModelError`."""
    shapes = {"first_moment": (2,), "translation": (2, n), "sigma": (n,), "gamma": (n,), "gyroscopic": (n, n),
              "translational_mass": (n, n)}
    values = {}
    for attribute, shape in shapes.items():
        value = validation.finite_array(f"{owner}: inertia_integrals.{attribute}", getattr(inertia, attribute))
        if value.shape != shape:
            raise ModelError(f"{owner}: inertia_integrals.{attribute} must have shape {shape} ({n} DOFs), got "
                             f"{value.shape}")
        values[attribute] = value
    return FloatingInertia(validation.nonnegative(f"{owner}: inertia_integrals.mass", inertia.mass),
                           values["first_moment"],
                           validation.nonnegative(f"{owner}: inertia_integrals.polar", inertia.polar),
                           values["translation"], values["sigma"], values["gamma"], values["gyroscopic"],
                           values["translational_mass"])


@dataclass(frozen=True, eq=False)
class GlobalSubsystem(DeformableBody):
    """A subsystem given by global equations ``M u'' + C u' + K u = f(u, u', t)`` in its floating frame,
    as a body of a planar model (module docstring).

    Parameters
    ----------
    name : str
        Body name.
    mass_matrix, damping_matrix, stiffness_matrix : array (n, n)
        Symmetric ``M`` (positive definite on the internal DOFs) [kg, kg m, kg m^2], ``C`` [N s/m ...] and
        ``K`` [N/m ...] over all DOFs, frame axes.
    nodes : mapping of str to ((x, y), dofs)
        Node position in the frame [m] and its DOF indices ``(ix, iy)`` or ``(ix, iy, irz)``.
    boundary : sequence of str
        Boundary nodes: the first is the inboard one (it carries the frame: origin at the node, angle =
        its rotation DOF, or the joint's angle when it has none), the others are the body's points,
        named after their nodes.
    nonlinear_force : callable, optional
        ``f(u, u_dot, t) -> (n,)`` [N, N m]: extra generalised force over all DOFs (inboard DOFs are passed
        as 0; their rows are ignored).  Must accept complex arrays (complex-step tangents of the implicit
        schemes and of ``ctmm.linearize``; plain arithmetic and numpy ufuncs do).
    inertia_integrals : FloatingInertia, optional
        Inertia integrals over all DOFs about the *inboard node* (default: from a lumped ``M``).
    frame_inertia : float
        Extra rotary inertia [kg m^2] turning with the frame (e.g. of particles without rotation DOFs).
    frame_nodes : sequence of str
        Further nodes fixed in the frame (their DOFs are held, e.g. anchor points of springs on the rigid
        body the subsystem is mounted on).
    potential : callable, optional
        ``V(u) -> float`` [J]: the potential of the conservative part of ``nonlinear_force`` (same ``u``), for
        :meth:`ctmm.planar.PlanarModel.energy`; without it the energy of a model whose subsystem has a
        ``nonlinear_force`` is refused (it cannot be integrated here).

    Notes
    -----
    An inboard node without a rotation DOF (a particle) leaves the frame's angle to the joint: a weld
    (:class:`~ctmm.planar.FixedMounting`) to a rigid body, or a hinge when frame-fixed nodes or
    ``frame_inertia`` give the frame its own rotary inertia (else the articulated inertia is singular and
    the run stops with a :class:`~ctmm.errors.SimulationError`).
    """

    name: str
    _: KW_ONLY
    mass_matrix: Any
    damping_matrix: Any
    stiffness_matrix: Any
    nodes: Mapping[str, Any]
    boundary: Sequence[str]
    nonlinear_force: Callable | None = None
    inertia_integrals: FloatingInertia | None = None
    frame_inertia: float = 0.0
    frame_nodes: Sequence[str] = ()
    potential: Callable | None = None
    family: ClassVar[type[SubsystemFamily]] = SubsystemFamily

    def __post_init__(self) -> None:
        owner = validation.name("element", self.name)
        M = square_matrix(owner, "mass", self.mass_matrix, None)
        n = M.shape[0]
        C = square_matrix(owner, "damping", self.damping_matrix, n)
        K = square_matrix(owner, "stiffness", self.stiffness_matrix, n)
        node_position, node_dofs = subsystem_nodes(owner, self.nodes, n, 2, 1)
        boundary, frame_nodes = subsystem_boundary(owner, self.boundary, self.frame_nodes, node_dofs,
                                                   self.nonlinear_force, self.potential)
        inboard = boundary[0]
        positions, kinds, pairs = np.full((n, 2), np.nan), np.full(n, -1), []
        for node, dofs in node_dofs.items():
            for k, i in enumerate(dofs):
                kinds[i], positions[i] = k, node_position[node]
            pairs.append(dofs[:2])
        frame_inertia = validation.nonnegative(f"{owner}: frame_inertia", self.frame_inertia)
        origin = positions[node_dofs[inboard][0]].copy()
        if self.inertia_integrals is None:
            inertia = lumped_inertia(owner, M, positions - origin, kinds, pairs, frame_inertia)
        elif isinstance(self.inertia_integrals, FloatingInertia):
            inertia = _checked_inertia(owner, self.inertia_integrals, n)
            inertia = dataclasses.replace(inertia, polar=inertia.polar + frame_inertia)
        else:
            raise ModelError(f"{owner}: inertia_integrals must be a FloatingInertia, got {self.inertia_integrals!r}")
        for attribute, value in (("mass_matrix", M), ("damping_matrix", C), ("stiffness_matrix", K),
                                 ("boundary", boundary), ("frame_inertia", frame_inertia),
                                 ("frame_nodes", frame_nodes)):
            object.__setattr__(self, attribute, value)
        object.__setattr__(self, "node_dofs", node_dofs)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "data", SubsystemData(self, inertia, positions - origin, kinds))

    def __hash__(self) -> int:
        return hash(self.name)

    # -- the body interface of PlanarModel -------------------------------------------------
    @property
    def mass(self) -> float:
        """Total mass [kg]."""
        return self.data.inertia.mass

    @property
    def center_of_mass(self) -> tuple[float, float]:
        """Undeformed centre of mass in the frame [m] (origin at the inboard node)."""
        d = self.data.inertia
        return tuple(float(v) for v in d.first_moment / max(d.mass, 1e-300))

    @property
    def inertia(self) -> float:
        """Undeformed inertia about the centre of mass [kg m^2]."""
        d = self.data.inertia
        c = np.array(self.center_of_mass)
        return float(d.polar - d.mass * c @ c)

    @property
    def inboard(self) -> tuple[float, float]:
        return (0.0, 0.0)

    @property
    def ends(self) -> tuple[str, ...]:
        """Names of the outboard boundary nodes (the body's points)."""
        return self.boundary[1:]

    @property
    def end_points(self) -> dict[str, tuple[float, float]]:
        """Undeformed outboard boundary nodes in the frame [m]."""
        return {e: tuple(float(v) for v in self.data.node_position(e)) for e in self.ends}

    @property
    def loads(self) -> tuple:
        return ()

    @property
    def coordinate_suffixes(self) -> tuple[str, ...]:
        """Names of the internal coordinates (after ``name.``): ``<node>_ux``, ``<node>_uy``, ``<node>_rz``."""
        return self.data.suffixes

    @property
    def coordinate_units(self) -> tuple[str, ...]:
        """``"m"`` for the nodal displacements ``_ux``, ``_uy``, ``"rad"`` for the rotations ``_rz``."""
        return tuple("rad" if suffix.endswith("_rz") else "m" for suffix in self.coordinate_suffixes)

    @property
    def n_eta(self) -> int:
        return self.data.n


class SubsystemData:
    """The reduced matrices and the body terms of a :class:`GlobalSubsystem` (module docstring)."""

    def __init__(self, body: GlobalSubsystem, inertia: FloatingInertia, positions: np.ndarray, kinds: np.ndarray
                 ) -> None:
        self.body, self.inertia = body, inertia
        n_all = kinds.size
        frame = {i for node in (body.boundary[0],) + body.frame_nodes for i in body.node_dofs[node]}
        keep = np.array([i for i in range(n_all) if i not in frame], dtype=int)
        self.keep, self.n_all, self.n = keep, n_all, keep.size
        self.position = {node: positions[dofs[0]] for node, dofs in body.node_dofs.items()}
        names = {i: f"{node}_{('ux', 'uy', 'rz')[k]}" for node, dofs in body.node_dofs.items()
                 for k, i in enumerate(dofs)}
        self.suffixes = tuple(names[i] for i in keep)
        sub = np.ix_(keep, keep)
        self.M, self.C, self.K = body.mass_matrix[sub], body.damping_matrix[sub], body.stiffness_matrix[sub]
        if self.n and not np.min(np.linalg.eigvalsh(self.M)) > 1e-12 * np.max(np.abs(self.M), initial=0.0):
            massless = [names[i] for i in keep if body.mass_matrix[i, i] <= 0.0] or "none on the diagonal, but M is singular"
            raise ModelError(f"{body.name}: the mass matrix of the internal DOFs must be positive definite (a massless "
                             f"DOF has no acceleration of its own); massless: {massless}; hold such nodes in the frame "
                             "(frame_nodes) or give them mass")
        self.m, self.s0, self.I0 = float(inertia.mass), np.asarray(inertia.first_moment, float), float(inertia.polar)
        self.S1 = inertia.translation[:, keep]
        self.sigma, self.gamma = inertia.sigma[keep], inertia.gamma[keep]
        self.G, self.Mt = inertia.gyroscopic[sub], inertia.translational_mass[sub]
        local = {i: k for k, i in enumerate(keep)}
        self.end_names = body.ends
        self.end_rows, self.end_x, self.end_dphi = [], [], np.zeros((len(self.end_names), self.n))
        for k, e in enumerate(self.end_names):
            dofs = body.node_dofs[e]
            self.end_rows.append((local[dofs[0]], local[dofs[1]], local[dofs[2]] if len(dofs) == 3 else None))
            self.end_x.append(self.position[e])
            if len(dofs) == 3:
                self.end_dphi[k, local[dofs[2]]] = 1.0
        self.laws = [] if body.nonlinear_force is None else [("nonlinear_force", body.nonlinear_force)]
        self.linear_elastic = bool(np.any(self.K) or np.any(self.C))  # K u, C u': linearised about the frame
        self.forces, self.constant_distributed = [], True        # no time loads (read by the code generator)
        self.size = max([float(np.linalg.norm(p)) for p in self.position.values()] + [1e-3])
        self.translational = np.array([kinds[i] < 2 for i in keep], dtype=bool)

    def node_position(self, node: str) -> np.ndarray:
        """Undeformed position of ``node`` in the frame [m]."""
        return self.position[node]

    @property
    def frequencies(self) -> np.ndarray:
        """Natural frequencies [rad/s] of the subsystem clamped at its inboard node (for step limits)."""
        from scipy.linalg import eigh
        try:
            values = eigh(self.K, self.M, eigvals_only=True)
        except np.linalg.LinAlgError:
            return np.array([np.inf])
        return np.sqrt(np.clip(values, 0.0, None))

    # -- kinematics for the model's points and ports ----------------------------------------
    def point_local(self, end: int, eta: np.ndarray, eta_dot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Deformed outboard point ``end`` (index) in the frame and its velocity relative to the frame."""
        ix, iy, _ = self.end_rows[end]
        return (self.end_x[end] + np.array([eta[ix], eta[iy]]), np.array([eta_dot[ix], eta_dot[iy]]))

    def centroid_local(self, eta: np.ndarray, eta_dot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Deformed centre of mass in the frame and its velocity relative to the frame."""
        return (self.s0 + self.S1 @ eta) / self.m, (self.S1 @ eta_dot) / self.m

    def nonlinear_energy(self, eta: np.ndarray) -> float:
        """Potential [J] of ``nonlinear_force`` at the internal coordinates ``eta`` (0 without a force), else
        :class:`ModelError` when the force has no ``potential``."""
        body = self.body
        if body.nonlinear_force is None:
            return 0.0
        if body.potential is None:
            raise ModelError(f"the energy of subsystem {body.name!r} needs the potential of its nonlinear_force: pass "
                             "potential=V(u) [J] (GlobalSubsystem / FiniteElementModel.subsystem)")
        u = np.zeros(self.n_all)
        u[self.keep] = eta
        return float(body.potential(u))

    def generalised_force(self, eta: np.ndarray, eta_dot: np.ndarray, t: float) -> np.ndarray:
        """``f(u, u_dot, t)`` on the internal DOFs, batched ``(B, n)`` (complex allowed)."""
        law = self.body.nonlinear_force
        B = eta.shape[0]
        out = np.zeros((B, self.n), dtype=np.result_type(eta, eta_dot, float))
        for b in range(B):
            u = np.zeros(self.n_all, dtype=out.dtype)
            v = np.zeros(self.n_all, dtype=out.dtype)
            u[self.keep], v[self.keep] = eta[b], eta_dot[b]
            try:
                value = np.asarray(law(u, v, t))
            except Exception as exc:  # noqa: BLE001 - user code: named with the time
                raise SimulationError(f"nonlinear_force of subsystem {self.body.name!r} raised {type(exc).__name__} "
                                      f"at t = {t:.6g} s: {exc}", time=float(t), element=self.body.name) from exc
            if value.shape != (self.n_all,) or not np.all(np.isfinite(value)):
                raise SimulationError(f"nonlinear_force of subsystem {self.body.name!r} returned {value!r} at "
                                      f"t = {t:.6g} s; expected {self.n_all} finite values", time=float(t),
                                      element=self.body.name)
            out[b] = value[self.keep]
        return out

    # -- the body terms --------------------------------------------------------------------------
    def terms(self, theta, omega, eta, eta_dot, t: float, gravity):
        """Body terms in global axes, batched over a leading axis (complex-safe), in the layout of
        :meth:`ctmm.flexible.beam.BeamData.terms`: ``M (B, 3+n, 3+n)``, ``h (B, 3+n)``, per outboard
        point ``(Kin (B, 3, 3+n), c (B, 3), RF (B, 3+n, 3), angle (B,), rate (B,))``."""
        n, N3 = self.n, 3 + self.n
        B = theta.shape[0]
        dtype = np.result_type(theta, omega, eta, eta_dot, float)
        c, s = np.cos(theta), np.sin(theta)
        gx, gy = float(gravity[0]), float(gravity[1])
        g = np.stack([c * gx + s * gy, -s * gx + c * gy], axis=1)           # gravity in the frame (B, 2)
        w, w2 = omega, omega * omega
        sv = self.s0 + eta @ self.S1.T                                       # (B, 2)
        Js = np.stack([-sv[:, 1], sv[:, 0]], axis=1)
        Mtu = eta @ self.Mt                                                  # (B, n) (M_t symmetric)
        Ma = np.empty((B, N3, N3), dtype=dtype)
        Ma[:] = 0.0
        Ma[:, 0, 0] = Ma[:, 1, 1] = self.m
        Ma[:, :2, 2] = Ma[:, 2, :2] = Js
        Ma[:, :2, 3:] = self.S1
        Ma[:, 3:, :2] = self.S1.T
        Ma[:, 2, 2] = self.I0 + 2 * eta @ self.sigma + (Mtu * eta).sum(1)
        gu = self.gamma + eta @ self.G.T
        Ma[:, 2, 3:] = Ma[:, 3:, 2] = gu
        Ma[:, 3:, 3:] = self.M
        S1ud = eta_dot @ self.S1.T                                           # (B, 2)
        h = np.empty((B, N3), dtype=dtype)
        h[:, :2] = -w2[:, None] * sv + 2 * w[:, None] * np.stack([-S1ud[:, 1], S1ud[:, 0]], axis=1) - self.m * g
        h[:, 2] = 2 * w * (eta_dot @ self.sigma + (Mtu * eta_dot).sum(1)) - (Js * g).sum(1)
        h[:, 3:] = (-w2[:, None] * (self.sigma + Mtu) + 2 * w[:, None] * (eta_dot @ self.G.T) - g @ self.S1
                    + eta @ self.K.T + eta_dot @ self.C.T)
        if self.laws:
            h[:, 3:] -= self.generalised_force(eta, eta_dot, t)
        R = np.empty((B, 2, 2), dtype=dtype)                                 # frame -> global, rows 0:2
        R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1] = c, -s, s, c
        Rt = np.transpose(R, (0, 2, 1))
        M = Ma.copy()
        M[:, :2, :] = R @ Ma[:, :2, :]
        M[:, :, :2] = M[:, :, :2] @ Rt
        h[:, :2] = (R @ h[:, :2, None])[:, :, 0]
        ends = []
        for k, (ix, iy, ir) in enumerate(self.end_rows):
            rx, ry = self.end_x[k][0] + eta[:, ix], self.end_x[k][1] + eta[:, iy]
            vx, vy = eta_dot[:, ix], eta_dot[:, iy]
            Kb = np.zeros((B, 3, N3), dtype=dtype)
            Kb[:, 0, 0] = Kb[:, 1, 1] = Kb[:, 2, 2] = 1.0
            Kb[:, 0, 2], Kb[:, 1, 2] = -ry, rx
            Kb[:, 0, 3 + ix] = Kb[:, 1, 3 + iy] = 1.0
            cb = np.zeros((B, 3, 1), dtype=dtype)
            cb[:, 0, 0] = -w2 * rx - 2 * w * vy
            cb[:, 1, 0] = -w2 * ry + 2 * w * vx
            angle, rate = theta, omega
            if ir is not None:
                Kb[:, 2, 3 + ir] = 1.0
                angle, rate = theta + eta[:, ir], omega + eta_dot[:, ir]
            Kin = Kb.copy()                                                  # rows 0:2 and columns 0:2 turn
            Kin[:, :2, :] = R @ Kb[:, :2, :]
            Kin[:, :, :2] = Kin[:, :, :2] @ Rt
            ce = cb[:, :, 0].copy()
            ce[:, :2] = (R @ cb[:, :2])[:, :, 0]
            ends.append((Kin, ce, np.transpose(Kin, (0, 2, 1)), angle, rate))
        return M, h, ends
