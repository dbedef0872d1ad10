"""The modal spatial beam (issue 15): an Euler-Bernoulli beam in a floating frame, as a body of a
:class:`~ctmm.spatial.model.SpatialModel`.

Small deformation, large overall motion.  The floating frame is the root tangent frame (the body
frame: origin at the inboard end, ``x`` along the undeformed axis, ``y`` and ``z`` the principal axes of
the cross-section); the deformation is modal (:mod:`ctmm.spatial.beam_modes`): bending in both planes
(``EI_y`` for the deflection ``w_y`` along ``y``, ``EI_z`` for ``w_z``), twist and axial extension.  The
physics (Newton-Euler about the inboard point plus virtual work on the modes) is in
:mod:`ctmm.spatial.beam_terms`; the derivation is in ``docs/spatial_modal_beam.md``.

A beam hangs on any spatial joint (its inboard point is its root), carries children and loads at its
**points** (named stations ``{name: x}`` on the axis, plus ``"origin"`` at ``x = 0`` and ``"tip"`` at
``x = L``), whose frames follow the deformation (position ``rho(x)``, rotation ``theta(x)``).  A child
welded at a point is a fixed mounting (rigid -> flexible or flexible -> flexible).
"""
from __future__ import annotations

import dataclasses
from dataclasses import KW_ONLY, dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError
from ..flexible.beam import ModalForce
from ..flexible.modes import check_quadrature
from ..flexible.second_order import check_second_order
from ..signals import Constant, SignalLike, as_signal
from .beam_modes import SpatialBeamData

__all__ = ["SpatialBeam", "ModalForce"]

_RESERVED = ("origin", "tip", "com")


@dataclass(frozen=True, eq=False)
class SpatialBeam:
    """Modal spatial Euler-Bernoulli beam (floating root tangent frame).

    Coordinates (after the joint coordinates of the model, :class:`~ctmm.spatial.model.SpatialModel`):
    ``"<name>.qy1"`` ... (deflection along body ``y`` [m]), ``"<name>.qz1"`` ... (along ``z``),
    ``"<name>.twist1"`` ... (twist [rad]), ``"<name>.u1"`` ... (axial [m]); velocities ``"..._rate"``.

    Parameters
    ----------
    name : str
    length : float
        ``L`` [m], > 0.
    mass_per_length : float
        ``rhoA`` [kg/m], > 0.
    bending_stiffness_y, bending_stiffness_z : float
        ``EI`` of the deflection along body ``y`` (bending in the ``x-y`` plane, moment about ``z``) and
        along ``z`` [N m^2], > 0.
    n_modes_y, n_modes_z : int
        Bending modes per plane (>= 0).
    n_torsion_modes : int
        Twist modes (default 0: torsionally rigid); needs ``torsional_stiffness`` and
        ``polar_inertia_per_length``.
    torsional_stiffness : float, optional
        ``GJ`` [N m^2].
    polar_inertia_per_length : float
        ``rho I_p`` [kg m] (cross-section rotary inertia about the axis; 0 allowed without twist modes).
    rotary_inertia_per_length_y, rotary_inertia_per_length_z : float
        Section rotary inertia in bending (Rayleigh) [kg m], >= 0, paired like the stiffnesses:
        ``rotary_inertia_per_length_y`` is the section's ``rho I`` about body ``z``, turning with the
        deflection ``w_y`` (slope ``w_y'``), ``rotary_inertia_per_length_z`` about body ``y``, turning with
        ``w_z``.  Default 0 (Euler-Bernoulli: the section's turning carries no kinetic energy); for a
        homogeneous section their sum is ``polar_inertia_per_length``.  The kinetic energy ``1/2 int (omega +
        Lambda eta_dot)^T J_s (omega + Lambda eta_dot)`` of the sections (``J_s = diag(rho I_p, rho I about y,
        rho I about z)``, ``Lambda`` the modal section rotation) gives the modal rotary-inertia matrix ``int
        rho I w' w'^T`` and its coupling to the frame (:mod:`ctmm.spatial.beam_modes`); the second-order
        coupling of the turned section with the frame's spin (a spinning shaft's gyroscopic ``2 Omega rho I_p``
        and spin-softening terms) is not modelled, as for the twist.  Generated kernels with
        ``numbers="inputs"`` refuse a beam with it.
    n_axial_modes : int
        Axial modes (default 0: axially rigid); needs ``axial_stiffness``.
    axial_stiffness : float, optional
        ``EA`` [N].
    geometric_stiffening : bool
        Geometric stiffness of the axial force of the overall motion in both bending planes (centrifugal
        stiffening, gravity, root acceleration, end and station loads); default True.
    second_order_inertia : bool
        Move every mass point with the shortening ``-1/2 eta^T G1(x) eta`` of the bent axis: the geometric
        stiffness and its reactions on the frame, energy-conserving (:mod:`ctmm.spatial.beam_second_order`).
        Default False.  Needs ``geometric_stiffening=True`` and no axial modes.
    wagner_term : bool
        Twist stiffened by the same axial force (Wagner): ``G(N)`` gains ``int N (I_p / A) chi' chi'^T`` on the twist
        block, ``I_p / A = polar_inertia_per_length / mass_per_length`` (homogeneous, doubly symmetric section;
        derivation in :mod:`ctmm.spatial_beam_torsion`).  Default False.  Needs ``geometric_stiffening=True``; not
        with ``second_order_inertia`` (whose shortening is the bent axis's alone).  The beam's mass and polar
        inertia are then not parameters of generated kernels (the term is not linear in them).
    damping_ratio : float
        Modal damping ratio ``zeta`` of every mode (>= 0).
    stiffness_damping : float
        Kelvin-Voigt coefficient ``mu`` [s]: ``D += mu K`` (>= 0).
    stations : mapping of str to float, optional
        Named points ``{name: x}`` [m from the root] (children, loads, ports).
    distributed_load : 3 signals
        Uniform follower load ``(q_x, q_y, q_z)`` [N/m] in the floating frame.
    modal_forces : sequence of ModalForce
        Generalised forces on the modal equations (actuators, modal feedback): ``force(t)``,
        ``stiffness``, ``damping`` (``law`` is refused: give a linear hook or use the control ports).
    static_shapes : bool
        Add to the modes of every direction that has some the static tip-load shapes (bending: tip force
        and tip moment deflections; twist and axial: the linear shape) -- coordinates ``"qy_force"``,
        ``"qy_moment"``, ``"qz_force"``, ``"qz_moment"``, ``"twist_static"``, ``"u_static"``.  The free-end
        modes alone cannot bend or strain the tip, so a tip body's frequencies converge as ``1/n``; with
        these shapes a few modes reach 1e-8 (``docs/spatial_modal_beam.md``).  Each is made orthogonal to the
        modes and to the previous one and scaled to ``int shape^2 = L`` (the raw shapes lie nearly in the modes'
        span: their modal mass would be ill-conditioned); their stiffness couples them to the modes, so
        ``damping_ratio`` must be 0 (use ``stiffness_damping``).  Default False.
    quadrature : int
        Gauss-Legendre points of the modal integrals (>= 2 max(mode counts) + 8; default 160).

    Examples
    --------
    >>> beam = SpatialBeam("arm", length=1.0, mass_per_length=0.8, bending_stiffness_y=15.0,
    ...                    bending_stiffness_z=30.0, n_modes_y=2, n_modes_z=2)
    >>> beam.coordinate_suffixes
    ('qy1', 'qy2', 'qz1', 'qz2')
    """

    name: str
    _: KW_ONLY
    length: float
    mass_per_length: float
    bending_stiffness_y: float
    bending_stiffness_z: float
    n_modes_y: int = 1
    n_modes_z: int = 1
    n_torsion_modes: int = 0
    torsional_stiffness: float | None = None
    polar_inertia_per_length: float = 0.0
    rotary_inertia_per_length_y: float = 0.0
    rotary_inertia_per_length_z: float = 0.0
    n_axial_modes: int = 0
    axial_stiffness: float | None = None
    geometric_stiffening: bool = True
    second_order_inertia: bool = False
    wagner_term: bool = False
    damping_ratio: float = 0.0
    stiffness_damping: float = 0.0
    static_shapes: bool = False
    stations: Mapping[str, float] | None = None
    distributed_load: Sequence[SignalLike] = (0.0, 0.0, 0.0)
    modal_forces: Sequence[ModalForce] = ()
    quadrature: int = 160

    def __post_init__(self) -> None:
        n = validation.name("body", self.name)
        for attribute in ("length", "mass_per_length", "bending_stiffness_y", "bending_stiffness_z"):
            object.__setattr__(self, attribute, validation.positive(f"{n}: {attribute}", getattr(self, attribute)))
        for attribute, low in (("n_modes_y", 0), ("n_modes_z", 0), ("n_torsion_modes", 0), ("n_axial_modes", 0),
                               ("quadrature", 8)):
            value = getattr(self, attribute)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise ModelError(f"{n}: {attribute} must be an integer >= {low}, got {value!r}")
            object.__setattr__(self, attribute, int(value))
        if self.n_eta == 0:
            raise ModelError(f"{n}: a spatial beam needs at least one mode (n_modes_y, n_modes_z, n_torsion_modes or "
                             "n_axial_modes >= 1); a rigid beam is a SpatialBody")
        check_quadrature(n, max(self.n_modes_y, self.n_modes_z), max(self.n_torsion_modes, self.n_axial_modes),
                         self.quadrature)
        for count, attribute in (("n_torsion_modes", "torsional_stiffness"), ("n_axial_modes", "axial_stiffness")):
            value = getattr(self, attribute)
            if getattr(self, count) and value is None:
                raise ModelError(f"{n}: {attribute} is required when {count} > 0, got None")
            if value is not None:
                object.__setattr__(self, attribute, validation.positive(f"{n}: {attribute}", value))
        object.__setattr__(self, "polar_inertia_per_length",
                           validation.nonnegative(f"{n}: polar_inertia_per_length", self.polar_inertia_per_length))
        for attribute in ("rotary_inertia_per_length_y", "rotary_inertia_per_length_z"):
            object.__setattr__(self, attribute, validation.nonnegative(f"{n}: {attribute}", getattr(self, attribute)))
        if self.n_torsion_modes and self.polar_inertia_per_length == 0.0:
            raise ModelError(f"{n}: polar_inertia_per_length (rho I_p [kg m]) must be > 0 with twist modes "
                             f"(n_torsion_modes = {self.n_torsion_modes}), got 0.0")
        validation.flag(f"{n}: geometric_stiffening", self.geometric_stiffening)
        validation.flag(f"{n}: static_shapes", self.static_shapes)
        check_second_order(self)
        validation.flag(f"{n}: wagner_term", self.wagner_term)
        if self.wagner_term and (not self.geometric_stiffening or self.second_order_inertia):
            raise ModelError(f"{n}: wagner_term=True needs geometric_stiffening=True and second_order_inertia=False "
                             f"(the axial force it stiffens the twist with), got geometric_stiffening = "
                             f"{self.geometric_stiffening}, second_order_inertia = {self.second_order_inertia}")
        for attribute in ("damping_ratio", "stiffness_damping"):
            object.__setattr__(self, attribute, validation.nonnegative(f"{n}: {attribute}", getattr(self, attribute)))
        if self.static_shapes and self.damping_ratio:
            raise ModelError(f"{n}: damping_ratio = {self.damping_ratio!r} needs orthogonal modes, but static_shapes=True "
                             "adds shapes that are not; use stiffness_damping (D = mu K) instead")
        stations = {} if self.stations is None else self.stations
        if not isinstance(stations, Mapping):
            raise ModelError(f"{n}: stations must be a mapping {{name: x [m]}}, got {self.stations!r}")
        checked = {}
        for key, value in stations.items():
            validation.name(f"{n}: station", key)
            if key in _RESERVED or key in self.coordinate_suffixes:
                raise ModelError(f"{n}: station name {key!r} is taken ({', '.join(_RESERVED)} and the modal coordinate "
                                 "names are reserved)")
            x = validation.finite(f"{n}: stations[{key!r}]", value)
            if x < -1e-12 * self.length or x > self.length * (1 + 1e-12):
                raise ModelError(f"{n}: stations[{key!r}] = {value!r} m must lie on the beam, 0 <= x <= {self.length} m")
            checked[key] = min(max(x, 0.0), self.length)
        object.__setattr__(self, "stations", checked)
        load = tuple(self.distributed_load) if isinstance(self.distributed_load, (list, tuple)) else None
        if load is None or len(load) != 3:
            raise ModelError(f"{n}: distributed_load must be 3 signals (q_x, q_y, q_z) [N/m], got "
                             f"{self.distributed_load!r}")
        object.__setattr__(self, "distributed_load",
                           tuple(as_signal(f"{n}: distributed_load[{i}]", v) for i, v in enumerate(load)))
        hooks = validation.instances(f"{n}: modal_forces", self.modal_forces, ModalForce)
        for hook in hooks:
            if hook.law is not None:
                raise ModelError(f"{n}: {hook.label}: a spatial beam takes ModalForce force, stiffness and damping; "
                                 "law is not supported (use a linear hook or the control ports)")
            for attribute in ("stiffness", "damping"):
                value = getattr(hook, attribute)
                if value is not None and value.shape != (self.n_eta, self.n_eta):
                    raise ModelError(f"{n}: {hook.label}.{attribute} must have shape ({self.n_eta}, {self.n_eta}) "
                                     f"(modes {self.coordinate_suffixes}), got {value.shape}")
        object.__setattr__(self, "modal_forces", hooks)
        object.__setattr__(self, "data", SpatialBeamData(self))

    # -- body interface of SpatialModel ---------------------------------------------------------
    @property
    def points(self) -> dict[str, np.ndarray]:
        """Undeformed points in body axes [m]: ``"origin"``, ``"tip"`` and the stations."""
        out = {"origin": np.zeros(3), "tip": np.array([self.length, 0.0, 0.0])}
        out.update({key: np.array([x, 0.0, 0.0]) for key, x in self.stations.items()})
        return out

    @property
    def mass(self) -> float:
        """``rhoA L`` [kg]."""
        return self.mass_per_length * self.length

    @property
    def center_of_mass(self) -> np.ndarray:
        """Undeformed centre of mass ``(L/2, 0, 0)`` [m]."""
        return np.array([0.5 * self.length, 0.0, 0.0])

    @property
    def inertia(self) -> np.ndarray:
        """Undeformed inertia about the centre of mass, body axes [kg m^2] (with the sections' rotary inertias;
        about body ``y`` the one turning with ``w_z``, about ``z`` the one turning with ``w_y``)."""
        transverse = self.mass * self.length ** 2 / 12.0
        return np.diag([self.polar_inertia_per_length * self.length,
                        transverse + self.rotary_inertia_per_length_z * self.length,
                        transverse + self.rotary_inertia_per_length_y * self.length])

    @property
    def direction_counts(self) -> dict[str, int]:
        """Modal coordinates per direction ``{"y", "z", "t" (twist), "a" (axial): count}`` (modes plus static
        shapes)."""
        extra = {"y": 2, "z": 2, "t": 1, "a": 1} if self.static_shapes else {"y": 0, "z": 0, "t": 0, "a": 0}
        counts = {"y": self.n_modes_y, "z": self.n_modes_z, "t": self.n_torsion_modes, "a": self.n_axial_modes}
        return {key: count + extra[key] if count else 0 for key, count in counts.items()}

    @property
    def n_eta(self) -> int:
        """Number of modal coordinates."""
        return sum(self.direction_counts.values())

    @property
    def coordinate_suffixes(self) -> tuple[str, ...]:
        """Names of the modal coordinates (after ``"<name>."``), in the order of ``eta``."""
        names = []
        for prefix, count, static in (("qy", self.n_modes_y, ("qy_force", "qy_moment")),
                                      ("qz", self.n_modes_z, ("qz_force", "qz_moment")),
                                      ("twist", self.n_torsion_modes, ("twist_static",)),
                                      ("u", self.n_axial_modes, ("u_static",))):
            names += [f"{prefix}{i + 1}" for i in range(count)]
            if count and self.static_shapes:
                names += list(static)
        return tuple(names)

    @property
    def time_dependent(self) -> bool:
        """True when modal force hooks or a non-constant distributed load make the terms depend on time
        (generated code cannot follow them: ``compiled=True`` refuses such a beam)."""
        return bool(self.data.forces) or not all(isinstance(f, Constant) for f in self.distributed_load)

    @property
    def coordinate_units(self) -> tuple[str, ...]:
        """Units of the modal coordinates (``"m"``; ``"rad"`` for twist), in the order of ``eta``."""
        return tuple("rad" if suffix.startswith("twist") else "m" for suffix in self.coordinate_suffixes)

    @property
    def frequencies(self) -> np.ndarray:
        """Uncoupled modal frequencies ``sqrt(K_ii / M_ii)`` of the clamped root [rad/s]."""
        return self.data.frequencies.copy()

    def modal_tangent(self, position_weight: float, velocity_weight: float) -> np.ndarray:
        """``b' h^2 K + g' h D`` (n x n): the modal stiffness and damping (with the linear hooks) in the
        implicit DT-TMM's Newton tangent, ``position_weight = b' h^2`` [s^2], ``velocity_weight = g' h`` [s]."""
        return position_weight * self.data.K_total + velocity_weight * self.data.D_total

    def moment_pair(self, x1: float, x2: float, moment: SignalLike, *, axis: str = "z",
                    label: str = "moment pair") -> ModalForce:
        """Hook for a piezo patch between stations ``x1 < x2`` [m] inducing the bending moment ``moment(t)``
        [N m] about body ``axis`` (``"z"``: bending in the ``x-y`` plane, ``"y"``: in the ``x-z`` plane):
        ``-M`` at ``x1``, ``+M`` at ``x2``; generalised force ``M (theta(x2) - theta(x1))`` of that axis (linear:
        the exact virtual work of the pair, with its second-order couplings, is the body-axes ports'
        :func:`ctmm.spatial.beam_ports.patch_actuator`, also usable in :class:`ctmm.control.Feedback`)."""
        delta = self._rotation_difference(x1, x2, axis)
        signal = as_signal(f"{self.name}: {label}", moment)
        return ModalForce(force=lambda t, d=delta, f=signal: f(t) * d, label=label)

    def modal_velocity_feedback(self, x1: float, x2: float, *, coefficient: float, gain: float, mode: int,
                                axis: str = "z", label: str = "modal feedback") -> ModalForce:
        """Piezo modal-velocity feedback ``V = -gain eta_dot[mode - 1]`` on a patch ``x1 .. x2`` about ``axis``
        with moment coefficient ``coefficient`` [N m/V]: a damping matrix on the modal equations."""
        if isinstance(mode, bool) or not isinstance(mode, (int, np.integer)) or not 1 <= mode <= self.n_eta:
            raise ModelError(f"{self.name}: mode must be 1..{self.n_eta}, got {mode!r}")
        delta = self._rotation_difference(x1, x2, axis)
        damping = np.zeros((self.n_eta, self.n_eta))
        damping[:, mode - 1] = validation.finite("coefficient", coefficient) * validation.finite("gain", gain) * delta
        return ModalForce(damping=damping, label=label)

    def with_modal_forces(self, *forces: ModalForce) -> "SpatialBeam":
        """Copy with ``forces`` appended to :attr:`modal_forces`."""
        return dataclasses.replace(self, modal_forces=tuple(self.modal_forces) + tuple(forces))

    def _rotation_difference(self, x1: float, x2: float, axis: str) -> np.ndarray:
        row = {"x": 0, "y": 1, "z": 2}.get(axis)
        if row is None:
            raise ModelError(f"{self.name}: axis must be 'x' (twist), 'y' or 'z', got {axis!r}")
        first, second = (validation.finite(f"{self.name}: {label}", x) for label, x in (("x1", x1), ("x2", x2)))
        if not 0.0 <= first < second <= self.length:
            raise ModelError(f"{self.name}: a patch needs 0 <= x1 < x2 <= {self.length} m, got x1={x1!r}, x2={x2!r}")
        return self.data.station(second)[1][row] - self.data.station(first)[1][row]

    def __hash__(self) -> int:
        return hash(self.name)
