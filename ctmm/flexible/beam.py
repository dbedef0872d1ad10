"""Modal planar Euler-Bernoulli beam in a floating frame (seed 003 6.4, seed 000 4.1).

Small deformation, large overall motion.  The floating frame is the root tangent frame
(origin at the inboard end ``I``, x along the undeformed axis, angle ``theta``), see
:mod:`ctmm.flexible.modes`.  A point at abscissa ``x`` is at

``r(x) = r_I + R(theta) rho(x)``,  ``rho(x) = [x + psi(x) . p,  phi(x) . q]``

with transverse modal coordinates ``q`` (``n_modes``) and optional axial ones ``p``
(``n_axial_modes``); ``eta = [q, p]``.  The equations (Newton-Euler of the whole beam about
``I`` and the modal equations by virtual work, derived in ``docs/flexible.md``) read, with the
outboard connection wrenches ``F_e`` (exerted by the beam on what hangs at end ``e``):

``F_I = M_rr A_I + M_re eta'' + h_r + sum_e X_e^T F_e``          (transfer equation 1)
``0   = M_er A_I + M_ee eta'' + h_e + sum_e (Y_e^T + S_e) F_e``  (transfer equation 2:
 modal accelerations)
``A_e = X_e A_I + Y_e eta'' + c_e``                              (kinematics of end ``e``)

``A = [a_x, a_y, alpha]``.  ``S_e`` is the geometric-stiffening term of the axial end force.
The sweep (:mod:`ctmm.flexible.kernel`) eliminates ``eta''`` locally, like a hinge's ``alpha``.

Notation of the numeric kernel (all integrals over ``[0, L]``, ``rhoA`` uniform):
``m = rhoA L``, ``S = rhoA L^2/2``, ``I0 = rhoA L^3/3``, ``b_q = rhoA int phi``,
``c_q = rhoA int x phi``, ``M_q = rhoA int phi phi^T``, ``K_q = EI int phi'' phi''^T``,
sections (Rayleigh, ``rho I``) ``J_r = rho I L``, ``r_q = rho I int phi'``, ``R_q = rho I int phi' phi'^T``,
axial ``b_p, c_p, M_p, K_p = EA int psi' psi'^T``, coupling ``N = rhoA int psi phi^T``,
stiffening ``G1(x) = int_0^x phi' phi'^T``, ``G2 = int (L - x) phi' phi'^T``,
``G3 = int (L^2 - x^2)/2 phi' phi'^T`` (Kane-Ryan-Banerjee ``KG = rhoA G3``).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import KW_ONLY, dataclass
from functools import cached_property
from typing import Callable, ClassVar, Mapping, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError
from ..planar.deformable import DeformableBody
from ..planar.elements import Load
from ..planar.signals import signal_values
from ..signals import Constant, SignalLike, as_signal
from .family import ModalBeamFamily
from .hooks import hook_value
from .modes import ModeSet, check_quadrature, check_root_clamped, gauss_points
from .beam_single import single_terms
from .point_terms import end_terms, point_shortening
from .second_order import SecondOrderInertia, check_second_order
from .stations import check_stations, station_abscissa


@dataclass(frozen=True)
class ModalForce:
    """Extra generalised force on the modal equations of a beam (the actuator / feedback hook).

    ``Q(t, eta, eta_dot) = force(t) - stiffness @ eta - damping @ eta_dot + law(t, eta, eta_dot)``

    with ``eta = [q_1..q_n, p_1..p_m]`` (transverse, then axial).  ``Q`` acts on the modal
    equations only (a self-equilibrated load such as a piezo moment pair exerts no net force or
    moment on the floating frame).  The linear parts are exact in the implicit DT-TMM (they
    enter the modal "kappa" ``beta' h^2 K + gamma' h D``); ``law`` is evaluated at the Newton
    iterate and differentiated by complex step, so it must accept complex arrays (plain
    arithmetic and numpy ufuncs do; ``abs``/``clip`` do not -- use co-simulation for those).

    Parameters
    ----------
    force : callable or None
        ``t -> array (n_eta,)`` [N m per unit modal coordinate, i.e. N].
    stiffness, damping : array (n_eta, n_eta) or None
        Feedback matrices [N/m], [N s/m] (need not be symmetric).
    law : callable or None
        ``(t, eta, eta_dot) -> array (n_eta,)``.
    label : str
        Name used in messages.
    """

    force: Callable | None = None
    stiffness: np.ndarray | None = None
    damping: np.ndarray | None = None
    law: Callable | None = None
    label: str = "modal force"

    def __post_init__(self) -> None:
        for attribute in ("stiffness", "damping"):
            value = getattr(self, attribute)
            if value is not None:
                object.__setattr__(self, attribute,
                                   validation.finite_array(f"{self.label}: {attribute}", value,
                                                           ndim=2))
        for attribute in ("force", "law"):
            value = getattr(self, attribute)
            if value is not None and not callable(value):
                raise ModelError(f"{self.label}: {attribute} must be callable, got {value!r}")


@dataclass(frozen=True)
class ModalBeam(DeformableBody):
    """Planar Euler-Bernoulli beam with modal deformation in its floating (root tangent) frame.

    A body type of :class:`~ctmm.planar.PlanarModel`: its inboard end is the body-frame origin,
    its undeformed axis the body x axis.  Coordinates: ``"name.theta"`` (frame angle, unless the
    beam is welded / driven), ``"name.q1"`` ... (transverse modal coordinates [m]) and
    ``"name.u1"`` ... (axial, if any).  Only what is switched on enters the state.

    Parameters
    ----------
    name : str
        Element name.
    length : float
        ``L`` [m], > 0.
    bending_stiffness : float
        ``EI`` [N m^2], > 0.
    mass_per_length : float
        ``rhoA`` [kg/m], > 0.
    n_modes : int
        Number of transverse modes, >= 1.
    n_axial_modes : int
        Number of axial modes (default 0 = axially rigid).
    axial_stiffness : float, optional
        ``EA`` [N]; required when ``n_axial_modes > 0``.
    geometric_stiffening : bool
        Add the geometric stiffness of the axial force of the overall motion (centrifugal
        stiffening): ``G(N) q`` with ``G_ij = int N phi_i' phi_j'``; default True.
    second_order_inertia : bool
        Move every mass point with the shortening ``-1/2 q^T G1(x) q`` of the bent beam: stiffening
        and its reactions on the frame, energy-conserving (:mod:`ctmm.flexible.second_order`).
        Default False.  Needs ``geometric_stiffening=True`` and no axial modes.
    damping_ratio : float
        Modal viscous damping ratio ``zeta`` of every mode (>= 0; 0 = off).
    stiffness_damping : float
        Kelvin-Voigt coefficient ``mu`` [s]: ``D += mu K`` (>= 0; 0 = off).
    mode_set : ModeSet, optional
        Transverse shapes; default ``ModeSet.clamped_free(n_modes)``.  A set whose boundary is
        not clamped at the root raises :class:`ModelError`.
    outboard : float or mapping of str to float
        Station(s) ``x`` [m] of the outboard end(s); default ``{"out": length}``.
    loads : sequence of Load
        Point loads in global axes; ``Load.point = (x, 0)`` names the station.
    distributed_load : (signal, signal)
        Uniform follower load ``(q_x, q_y)`` [N/m] in the floating frame.
    modal_forces : sequence of ModalForce
        Extra generalised forces on the modal equations (actuators, modal feedback).
    quadrature : int
        Gauss-Legendre points for the modal integrals (default 160), at least
        ``2 max(n_modes, n_axial_modes) + 8`` (fewer integrate the higher shapes wrongly).
    stations : mapping of str to float, optional
        Named stations ``{name: x}`` [m from the root]: ports ``"arm.<name>.w"`` ... (:mod:`ctmm.flexible.stations`).
    rotary_inertia_per_length : float
        Section rotary inertia ``rho I`` [kg m] (Rayleigh beam), >= 0; default 0 (Euler-Bernoulli).  Kinetic energy
        ``1/2 rho I int (omega + phi' . q_dot)^2``: the terms ``J_r``, ``r_q``, ``R_q`` above (``docs/flexible.md``).

    Examples
    --------
    >>> beam = ModalBeam("arm", length=1.0, bending_stiffness=15.0, mass_per_length=0.8,
    ...                  n_modes=3)
    >>> beam.coordinate_suffixes
    ('q1', 'q2', 'q3')
    """

    name: str
    _: KW_ONLY
    length: float
    bending_stiffness: float
    mass_per_length: float
    n_modes: int
    n_axial_modes: int = 0
    axial_stiffness: float | None = None
    geometric_stiffening: bool = True
    second_order_inertia: bool = False
    damping_ratio: float = 0.0
    stiffness_damping: float = 0.0
    mode_set: ModeSet | None = None
    outboard: object = None
    loads: Sequence[Load] = ()
    distributed_load: tuple = (0.0, 0.0)
    modal_forces: Sequence[ModalForce] = ()
    quadrature: int = 160
    stations: Mapping[str, float] | None = None
    rotary_inertia_per_length: float = 0.0
    family: ClassVar[type[ModalBeamFamily]] = ModalBeamFamily

    def __post_init__(self) -> None:
        validation.name("element", self.name)
        n = self.name
        for attribute in ("length", "bending_stiffness", "mass_per_length"):
            object.__setattr__(self, attribute,
                               validation.positive(f"{n}: {attribute}", getattr(self, attribute)))
        object.__setattr__(self, "rotary_inertia_per_length",
                           validation.nonnegative(f"{n}: rotary_inertia_per_length", self.rotary_inertia_per_length))
        for attribute, low in (("n_modes", 1), ("n_axial_modes", 0), ("quadrature", 8)):
            value = getattr(self, attribute)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise ModelError(f"{n}: {attribute} must be an integer >= {low}, got {value!r}")
            object.__setattr__(self, attribute, int(value))
        check_quadrature(n, self.n_modes, self.n_axial_modes, self.quadrature)
        if self.n_axial_modes and self.axial_stiffness is None:
            raise ModelError(f"{n}: axial_stiffness (EA) is required when n_axial_modes > 0")
        if self.axial_stiffness is not None:
            object.__setattr__(self, "axial_stiffness",
                               validation.positive(f"{n}: axial_stiffness", self.axial_stiffness))
        if not isinstance(self.geometric_stiffening, bool):
            raise ModelError(f"{n}: geometric_stiffening must be True or False, got {self.geometric_stiffening!r}")
        check_second_order(self)
        object.__setattr__(self, "damping_ratio", validation.nonnegative(f"{n}: damping_ratio", self.damping_ratio))
        object.__setattr__(self, "stiffness_damping",
                           validation.nonnegative(f"{n}: stiffness_damping", self.stiffness_damping))
        modes = self.mode_set if self.mode_set is not None else ModeSet.clamped_free(self.n_modes)
        if not isinstance(modes, ModeSet):
            raise ModelError(f"{n}: mode_set must be a ModeSet, got {modes!r}")
        if len(modes) != self.n_modes:
            raise ModelError(f"{n}: mode_set has {len(modes)} shapes but n_modes = {self.n_modes}")
        check_root_clamped(modes, n)
        object.__setattr__(self, "mode_set", modes)
        ends = self.outboard if self.outboard is not None else {"out": self.length}
        if isinstance(ends, Mapping):
            checked = {}
            for end_name, x in ends.items():
                validation.name(f"{n}: outboard end", end_name)
                checked[end_name] = station_abscissa(n, f"outboard[{end_name!r}]", x, self.length)
        else:
            checked = {"out": station_abscissa(n, "outboard", ends, self.length)}
        object.__setattr__(self, "outboard", checked)
        object.__setattr__(self, "stations", check_stations(self, self.stations))
        loads = validation.instances(f"{n}: loads", self.loads, Load)
        for load in loads:
            if abs(load.point[1]) > 0.0:
                raise ModelError(f"{n}: a beam load acts on the axis; Load.point must be (x, 0), "
                                 f"got {load.point}")
            station_abscissa(n, "load station", load.point[0], self.length)
        object.__setattr__(self, "loads", loads)
        if not isinstance(self.distributed_load, (list, tuple)) or len(self.distributed_load) != 2:
            raise ModelError(f"{n}: distributed_load must be (q_x, q_y) [N/m], "
                             f"got {self.distributed_load!r}")
        object.__setattr__(self, "distributed_load",
                           tuple(as_signal(f"{n}: distributed_load", v)
                                 for v in self.distributed_load))
        forces = validation.instances(f"{n}: modal_forces", self.modal_forces, ModalForce)
        n_eta = self.n_modes + self.n_axial_modes
        for hook in forces:
            for attribute in ("stiffness", "damping"):
                value = getattr(hook, attribute)
                if value is not None and value.shape != (n_eta, n_eta):
                    raise ModelError(f"{n}: {hook.label}.{attribute} must have shape "
                                     f"({n_eta}, {n_eta}) (modes [q, p]), got {value.shape}")
        object.__setattr__(self, "modal_forces", forces)
        object.__setattr__(self, "data", BeamData(self))   # modal integrals, computed once here

    def __hash__(self) -> int:
        return hash(self.name)

    def __eq__(self, other) -> bool:
        return self is other

    # -- RigidBody-like interface used by PlanarModel ---------------------------------------
    @property
    def mass(self) -> float:
        """Total mass ``rhoA L`` [kg]."""
        return self.mass_per_length * self.length

    @property
    def inertia(self) -> float:
        """Undeformed inertia about the centre ``rhoA L^3 / 12 + rho I L`` [kg m^2] (with the sections' turning)."""
        return self.mass * self.length ** 2 / 12.0 + self.rotary_inertia_per_length * self.length

    @property
    def center_of_mass(self) -> tuple[float, float]:
        return (0.5 * self.length, 0.0)

    @property
    def inboard(self) -> tuple[float, float]:
        return (0.0, 0.0)

    @property
    def ends(self) -> tuple[str, ...]:
        """Names of the outboard ends."""
        return tuple(self.outboard)

    @property
    def end_points(self) -> dict[str, tuple[float, float]]:
        """Undeformed outboard ends in the body frame."""
        return {e: (x, 0.0) for e, x in self.outboard.items()}

    @property
    def n_eta(self) -> int:
        """Number of modal coordinates (transverse + axial)."""
        return self.n_modes + self.n_axial_modes

    @property
    def coordinate_suffixes(self) -> tuple[str, ...]:
        """Names of the modal coordinates (after ``name.``)."""
        return (tuple(f"q{i + 1}" for i in range(self.n_modes))
                + tuple(f"u{k + 1}" for k in range(self.n_axial_modes)))

    # -- shapes ---------------------------------------------------------------------------
    def shapes(self, x, derivative: int = 0) -> np.ndarray:
        """Transverse shapes ``d^k phi / dx^k`` at stations ``x`` [m]: ``(n_modes, len(x))``."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        return self.mode_set.evaluate(x / self.length, derivative) / self.length ** derivative

    def axial_shapes(self, x, derivative: int = 0) -> np.ndarray:
        """Axial shapes ``psi_k`` (or derivatives) at ``x``: ``(n_axial_modes, len(x))``."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        k = np.arange(1, self.n_axial_modes + 1)[:, None]
        a = (2 * k - 1) * math.pi / (2 * self.length)
        y = a * x[None, :]
        base = (np.sin(y), a * np.cos(y), -a * a * np.sin(y))[derivative]
        return math.sqrt(2.0) * base

    def mode_slopes(self, x: float) -> np.ndarray:
        """``phi'(x)`` of all transverse modes [1/m]: e.g. a piezo moment pair between ``x1``
        and ``x2`` with moment ``M`` gives the generalised force ``M (phi'(x2) - phi'(x1))``."""
        return self.shapes([station_abscissa(self.name, "station", x, self.length)], 1)[:, 0]

    def moment_pair(self, x1: float, x2: float, moment: SignalLike, *,
                    label: str = "moment pair") -> ModalForce:
        """Hook for a piezo patch between ``x1 < x2`` inducing the bending moment ``moment(t)``
        [N m] (moments ``-M`` at ``x1``, ``+M`` at ``x2``; FORMULAS 5.3): ``Q_i = M (phi_i'(x2) -
        phi_i'(x1))``.  Use ``dataclasses.replace(beam, modal_forces=(...,))`` to attach it."""
        delta = np.concatenate([self.mode_slopes(x2) - self.mode_slopes(x1),
                                np.zeros(self.n_axial_modes)])
        signal = as_signal(f"{self.name}: {label}", moment)
        return ModalForce(force=lambda t, d=delta, f=signal: f(t) * d, label=label)

    def modal_velocity_feedback(self, x1: float, x2: float, *, coefficient: float,
                                gain: float, mode: int, label: str = "modal feedback"
                                ) -> ModalForce:
        """Hook for piezo modal-velocity feedback ``V = -gain eta_dot_mode`` on a patch between
        ``x1, x2`` with moment coefficient ``c_a`` [N m/V]: ``Q = -c_a gain (phi'(x2) - phi'(x1))
        eta_dot_mode`` -- a (non-symmetric) damping matrix, exact in the implicit DT-TMM."""
        if not (isinstance(mode, (int, np.integer)) and 1 <= mode <= self.n_eta):
            raise ModelError(f"{self.name}: mode must be 1..{self.n_eta}, got {mode!r}")
        delta = np.concatenate([self.mode_slopes(x2) - self.mode_slopes(x1),
                                np.zeros(self.n_axial_modes)])
        damping = np.zeros((self.n_eta, self.n_eta))
        damping[:, mode - 1] = validation.finite("coefficient", coefficient) * \
            validation.finite("gain", gain) * delta
        return ModalForce(damping=damping, label=label)

    def with_modal_forces(self, *forces: ModalForce) -> "ModalBeam":
        """Copy with ``forces`` appended to :attr:`modal_forces`."""
        return dataclasses.replace(self, modal_forces=tuple(self.modal_forces) + tuple(forces))


class BeamData:
    """Modal integrals of a :class:`ModalBeam` (see the module notation)."""
    terms_at_state = single_terms    # terms at one real state, unbatched (the explicit sweep's fast path)

    def __init__(self, beam: ModalBeam) -> None:
        L, EI, rhoA = beam.length, beam.bending_stiffness, beam.mass_per_length
        self.beam = beam
        self.L, self.rhoA = L, rhoA
        self.nq, self.np_ = beam.n_modes, beam.n_axial_modes
        self.n = self.nq + self.np_
        x, w = gauss_points(beam.quadrature, L)
        phi = beam.shapes(x, 0)
        dphi = beam.shapes(x, 1)
        ddphi = beam.shapes(x, 2)
        psi = beam.axial_shapes(x, 0)
        dpsi = beam.axial_shapes(x, 1)
        self.m = rhoA * L
        self.Sx = rhoA * L * L / 2
        self.I0 = rhoA * L ** 3 / 3
        self.b_q = rhoA * phi @ w
        self.c_q = rhoA * phi @ (w * x)
        self.M_q = rhoA * (phi * w) @ phi.T
        if beam.mode_set.name == "clamped-free":
            beta = np.array(beam.mode_set.betas)
            self.K_q = np.diag(EI * beta ** 4 / L ** 3)       # EI int phi''^2 = EI b^4 / L^3
        else:
            self.K_q = EI * (ddphi * w) @ ddphi.T
        self.b_p = rhoA * psi @ w
        self.c_p = rhoA * psi @ (w * x)
        self.M_p = rhoA * (psi * w) @ psi.T
        EA = beam.axial_stiffness or 0.0
        self.K_p = EA * (dpsi * w) @ dpsi.T
        self.N = rhoA * (psi * w) @ phi.T                     # (np, nq)
        rhoI = beam.rotary_inertia_per_length                  # the sections' turning (Rayleigh)
        self.J_r, self.r_q, self.R_q = rhoI * L, rhoI * dphi @ w, rhoI * (dphi * w) @ dphi.T
        self.G2 = (dphi * (w * (L - x))) @ dphi.T
        self.G3 = (dphi * (w * (L * L - x * x) / 2)) @ dphi.T
        self.stiffening = beam.geometric_stiffening
        self.second_order = SecondOrderInertia(beam, x, w, phi, self.G2, self.G3) if beam.second_order_inertia else None
        # damping D = mu K + 2 zeta sqrt(K_ii M_ii)
        K = np.zeros((self.n, self.n))
        Mm = np.zeros((self.n, self.n))
        K[:self.nq, :self.nq] = self.K_q
        K[self.nq:, self.nq:] = self.K_p
        Mm[:self.nq, :self.nq] = self.M_q + self.R_q
        Mm[self.nq:, self.nq:] = self.M_p
        D = beam.stiffness_damping * K + 2 * beam.damping_ratio * np.diag(
            np.sqrt(np.clip(np.diag(K) * np.diag(Mm), 0.0, None)))
        self.K = K
        self.D = D
        self.M_modal = Mm
        self.frequencies = np.sqrt(np.diag(K) / np.diag(Mm))
        # feedback hooks: constant linear parts folded into K, D; time and law parts kept
        self.K_fb = np.zeros((self.n, self.n))
        self.D_fb = np.zeros((self.n, self.n))
        self.forces, self.laws = [], []
        for hook in beam.modal_forces:
            if hook.stiffness is not None:
                self.K_fb += hook.stiffness
            if hook.damping is not None:
                self.D_fb += hook.damping
            if hook.force is not None:
                self.forces.append((hook.label, hook.force))
            if hook.law is not None:
                self.laws.append((hook.label, hook.law))
        self.K_total = self.K + self.K_fb
        self.D_total = self.D + self.D_fb
        # ends and loads: shape values at the stations
        self.end_names = beam.ends
        self.end_x = np.array([beam.outboard[e] for e in beam.ends])
        self.end_phi = beam.shapes(self.end_x, 0).T if len(self.end_x) else np.zeros((0, self.nq))
        self.end_dphi = beam.shapes(self.end_x, 1).T if len(self.end_x) else np.zeros((0, self.nq))
        self.end_psi = (beam.axial_shapes(self.end_x, 0).T if len(self.end_x)
                        else np.zeros((0, self.np_)))
        self.end_G1 = np.array([self._g1(xe) for xe in self.end_x]).reshape(-1, self.nq, self.nq)
        self.load_x = np.array([ld.point[0] for ld in beam.loads])
        self.load_phi = (beam.shapes(self.load_x, 0).T if len(self.load_x)
                         else np.zeros((0, self.nq)))
        self.load_dphi = (beam.shapes(self.load_x, 1).T if len(self.load_x)
                          else np.zeros((0, self.nq)))
        self.load_psi = (beam.axial_shapes(self.load_x, 0).T if len(self.load_x)
                         else np.zeros((0, self.np_)))
        self.load_G1 = np.array([self._g1(xl) for xl in self.load_x]).reshape(-1, self.nq, self.nq)
        self.load_signals = [(ld.force_x, ld.force_y, ld.moment) for ld in beam.loads]
        self.distributed = beam.distributed_load
        self.constant_distributed = all(isinstance(f, Constant) for f in self.distributed)
        self.tip_phi = beam.shapes([L], 0)[:, 0]
        self.tip_psi = beam.axial_shapes([L], 0)[:, 0]
        self.phi_bound = np.max(np.abs(beam.shapes(np.linspace(0, L, 201), 0)), axis=1)
        self._eye = np.eye(3 + self.n)
        _ = self.constant_mass, self.constant_ends, self.functionals   # once: a beam's data never change afterwards

    def _g1(self, x_end: float) -> np.ndarray:
        if x_end <= 0.0:
            return np.zeros((self.nq, self.nq))
        x, w = gauss_points(self.beam.quadrature, x_end)
        dphi = self.beam.shapes(x, 1)
        return (dphi * w) @ dphi.T

    def end_point(self, end: int, eta, eta_dot, shortening: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """End ``end`` in the frame: position [m] and velocity relative to the frame [m/s]; with ``shortening`` and
        ``second_order_inertia`` moved by ``u_e = -1/2 q^T G1(x_e) q`` (:mod:`ctmm.flexible.point_terms`)."""
        q, qd = eta[:self.nq], eta_dot[:self.nq]
        position = np.array([self.end_x[end] + eta[self.nq:] @ self.end_psi[end], q @ self.end_phi[end]])
        velocity = np.array([eta_dot[self.nq:] @ self.end_psi[end], qd @ self.end_phi[end]])
        if shortening and self.second_order is not None:
            position[0] -= 0.5 * q @ self.end_G1[end] @ q
            velocity[0] -= q @ self.end_G1[end] @ qd
        return position, velocity

    # ---------------------------------------------------------------------------------------
    def external(self, t: float):
        """Point loads ``(n_loads, 3)`` and distributed load ``(q_x, q_y)`` at time ``t``."""
        name = self.beam.name
        functions = [f for s in self.load_signals for f in s]
        labels = [f"load {k} of beam {name!r}" for k in range(len(self.load_signals)) for _ in range(3)]
        parts = [part for _ in self.load_signals for part in ("force_x", "force_y", "moment")]
        loads = signal_values(functions, t, labels, parts, quote=False).reshape(-1, 3)
        dist = signal_values(self.distributed, t, [name, name], ["distributed load q_x", "distributed load q_y"])
        return loads, (float(dist[0]), float(dist[1]))

    @cached_property
    def constant_mass(self) -> np.ndarray:
        """Body-frame mass matrix of the undeformed beam (``eta = 0``)."""
        nq, n = self.nq, self.n
        M0 = np.zeros((3 + n, 3 + n))
        M0[0, 0] = M0[1, 1] = self.m
        M0[1, 2] = M0[2, 1] = self.Sx
        M0[2, 2] = self.I0 + self.J_r
        M0[1, 3:3 + nq] = M0[3:3 + nq, 1] = self.b_q
        M0[0, 3 + nq:] = M0[3 + nq:, 0] = self.b_p
        M0[2, 3:3 + nq] = M0[3:3 + nq, 2] = self.c_q + self.r_q
        M0[3:3 + nq, 3:3 + nq] = self.M_q + self.R_q
        M0[3 + nq:, 3 + nq:] = self.M_p
        return M0

    @cached_property
    def constant_ends(self) -> list:
        """Body-frame end kinematics / force maps of the undeformed beam."""
        nq, n = self.nq, self.n
        out = []
        for k in range(len(self.end_x)):
            Kin = np.zeros((3, 3 + n))
            Kin[0, 0] = Kin[1, 1] = Kin[2, 2] = 1.0
            Kin[1, 2] = self.end_x[k]
            Kin[1, 3:3 + nq] = self.end_phi[k]
            Kin[0, 3 + nq:] = self.end_psi[k]
            Kin[2, 3:3 + nq] = self.end_dphi[k]
            out.append(Kin)
        return out

    @cached_property
    def functionals(self):
        """Stacked linear functionals of ``eta`` and ``eta_dot`` (one product per call)."""
        nq, np_ = self.nq, self.np_
        rows, names = [], {}

        def add(name, block):
            block = np.atleast_2d(block)
            names[name] = slice(sum(r.shape[0] for r in rows),
                                sum(r.shape[0] for r in rows) + block.shape[0])
            rows.append(block)

        Zq, Zp = np.zeros((1, nq)), np.zeros((1, np_))
        add("bq", np.hstack([self.b_q[None], Zp]))
        add("bp", np.hstack([Zq, self.b_p[None]]))
        add("cp", np.hstack([Zq, self.c_p[None]]))
        add("Np", np.hstack([np.zeros((nq, nq)), self.N.T]))          # N^T p
        add("Nq", np.hstack([self.N, np.zeros((np_, np_))]))            # N q
        add("Mq", np.hstack([self.M_q, np.zeros((nq, np_))]))
        add("Mp", np.hstack([np.zeros((np_, nq)), self.M_p]))
        add("G2", np.hstack([self.G2, np.zeros((nq, np_))]))
        add("G3", np.hstack([self.G3, np.zeros((nq, np_))]))
        for k in range(len(self.end_x)):
            add(f"e{k}", np.vstack([np.hstack([Zq, self.end_psi[k][None]]),
                                    np.hstack([self.end_phi[k][None], Zp]),
                                    np.hstack([self.end_dphi[k][None], Zp])]))
            add(f"eG{k}", np.hstack([self.end_G1[k], np.zeros((nq, np_))]))
        for k in range(len(self.load_x)):
            add(f"l{k}", np.vstack([np.hstack([Zq, self.load_psi[k][None]]),
                                    np.hstack([self.load_phi[k][None], Zp])]))
            add(f"lG{k}", np.hstack([self.load_G1[k], np.zeros((nq, np_))]))
        return np.vstack(rows).T.copy(), names          # (n, r): eta @ matrix

    def terms(self, theta, omega, eta, eta_dot, t: float, gravity):
        """Body terms of the transfer equations, batched over a leading axis (complex-safe).

        Built in the floating frame (``A_b = [R^T a, alpha]``) and rotated to global axes with
        ``T = diag(R, 1, I_n)``: ``M = T M_b T^T``, ``h = T h_b``, ``Kin = T_3 Kin_b T^T``,
        ``c = T_3 c_b``, ``RF = T RF_b T_3^T``.

        Parameters
        ----------
        theta, omega : array (B,)
            Frame angle and rate.
        eta, eta_dot : array (B, n)
            Modal coordinates ``[q, p]`` and rates.
        t : float
        gravity : (2,)

        Returns
        -------
        M : (B, 3 + n, 3 + n), h : (B, 3 + n)
            ``[F_I ; 0] = M [A_I ; eta''] + h + sum_e RF_e F_e``.
        ends : list of (Kin (B, 3, 3 + n), c (B, 3), RF (B, 3 + n, 3), theta_e (B,), omega_e (B,))
            ``A_e = Kin [A_I ; eta''] + c``.
        """
        nq, n = self.nq, self.n
        N3 = 3 + n
        B = theta.shape[0]
        dtype = np.result_type(theta, omega, eta, eta_dot, float)
        q, p = eta[:, :nq], eta[:, nq:]
        qd, pd = eta_dot[:, :nq], eta_dot[:, nq:]
        c, s = np.cos(theta), np.sin(theta)
        gx, gy = float(gravity[0]), float(gravity[1])
        g1 = c * gx + s * gy                                 # gravity in the frame
        g2 = -s * gx + c * gy
        if self.load_signals or not self.constant_distributed:
            loads, (qx, qy) = self.external(t)
        else:
            loads, qx, qy = (), self.distributed[0].value, self.distributed[1].value
        w2 = omega * omega
        F, sl = self.functionals
        V = eta @ F                                          # (B, r)
        Vd = eta_dot @ F
        bq_q, bp_p = V[:, sl["bq"]][:, 0], V[:, sl["bp"]][:, 0]
        sx = self.Sx + bp_p
        Np, Nq, Mqq, Mpp = V[:, sl["Np"]], V[:, sl["Nq"]], V[:, sl["Mq"]], V[:, sl["Mp"]]
        # -- mass matrix in the frame ---------------------------------------------------------
        M = np.empty((B, N3, N3), dtype=dtype)
        M[:] = self.constant_mass
        M[:, 0, 2] = M[:, 2, 0] = -bq_q
        M[:, 1, 2] = M[:, 2, 1] = sx
        M[:, 2, 2] = self.I0 + self.J_r + 2 * V[:, sl["cp"]][:, 0] + (Mpp * p).sum(1) + (Mqq * q).sum(1)
        M[:, 2, 3:3 + nq] = M[:, 3:3 + nq, 2] = self.c_q + self.r_q + Np
        M[:, 2, 3 + nq:] = M[:, 3 + nq:, 2] = -Nq
        # -- velocity, gravity and load terms in the frame ----------------------------------
        h = np.empty((B, N3), dtype=dtype)
        h[:, 0] = -w2 * sx - 2 * omega * Vd[:, sl["bq"]][:, 0] - self.m * g1 - qx * self.L
        h[:, 1] = -w2 * bq_q + 2 * omega * Vd[:, sl["bp"]][:, 0] - self.m * g2 - qy * self.L
        h[:, 2] = (2 * omega * (Vd[:, sl["cp"]][:, 0] + (Mpp * pd).sum(1) + (Mqq * qd).sum(1))
                   - (sx * g2 - bq_q * g1)
                   - qy * (self.L ** 2 / 2 + bp_p / self.rhoA) + qx * bq_q / self.rhoA)
        hq = (-w2[:, None] * Mqq + 2 * omega[:, None] * Vd[:, sl["Np"]]
              - (g2[:, None] + qy / self.rhoA) * self.b_q)
        hp = (-w2[:, None] * (self.c_p + Mpp) - 2 * omega[:, None] * Vd[:, sl["Nq"]]
              - (g1[:, None] + qx / self.rhoA) * self.b_p)
        if self.stiffening:
            G2q = V[:, sl["G2"]]
            hq = hq + (self.rhoA * g1[:, None] + qx) * G2q + (self.rhoA * w2)[:, None] * V[
                :, sl["G3"]]
            M[:, 3:3 + nq, 0] -= self.rhoA * G2q
        for k in range(len(loads)):
            fx, fy, mz = loads[k]
            f1, f2 = c * fx + s * fy, -s * fx + c * fy       # load in the frame
            lv = V[:, sl[f"l{k}"]]
            rb_x = self.load_x[k] + lv[:, 0]
            if self.second_order is not None:          # the load point moves with the shortening
                rb_x = rb_x + point_shortening(V[:, sl[f"lG{k}"]], q)
            rb_y = lv[:, 1]
            h[:, 0] -= f1
            h[:, 1] -= f2
            h[:, 2] -= rb_x * f2 - rb_y * f1 + mz
            hq = hq - f2[:, None] * self.load_phi[k] - mz * self.load_dphi[k]
            hp = hp - f1[:, None] * self.load_psi[k]
            if self.stiffening:
                hq = hq + f1[:, None] * V[:, sl[f"lG{k}"]]
        h[:, 3:3 + nq] = hq
        h[:, 3 + nq:] = hp
        if self.second_order is not None:
            self.second_order.add_terms(M, h, omega, q, qd, g2 + qy / self.rhoA)
        h[:, 3:] += eta @ self.K_total.T + eta_dot @ self.D_total.T
        for label, f in self.forces:
            h[:, 3:] -= hook_value(self.beam.name, self.n, f"force of {label!r} on beam {self.beam.name!r}", f,
                                   (t,), t)
        for label, law in self.laws:
            what = f"law of {label!r} on beam {self.beam.name!r}"
            h[:, 3:] -= np.stack([hook_value(self.beam.name, self.n, what, law, (t, eta[b], eta_dot[b]), t)
                                  for b in range(B)])
        # -- rotate to global axes ----------------------------------------------------------
        T = np.zeros((B, N3, N3), dtype=dtype)
        T[:] = self._eye
        T[:, 0, 0] = T[:, 1, 1] = c
        T[:, 0, 1] = -s
        T[:, 1, 0] = s
        Tt = np.transpose(T, (0, 2, 1))
        M = T @ M @ Tt
        h = (T @ h[:, :, None])[:, :, 0]
        # -- ends (point_terms.py) -----------------------------------------------------------
        ends = [end_terms(self, k, K0, V, Vd, sl, q, qd, theta, omega, T) for k, K0 in enumerate(self.constant_ends)]
        return M, h, ends


__all__ = ["ModalBeam", "ModalForce", "BeamData"]
