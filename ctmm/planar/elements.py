"""Planar multi-rigid-body elements: rigid bodies, hinges and boundaries (descriptions only).

All elements are immutable descriptions validated at construction; every invalid parameter
raises :class:`~ctmm.errors.ModelError` naming the parameter and the value.  The package
sign convention (:mod:`ctmm.layouts`) holds: the force / moment stored at a connection point
is the one **exerted by the inboard part on the outboard part**, in global axes.

Body frame
----------
Each :class:`RigidBody` has its own body-fixed frame, rotated by the body angle ``theta``
[rad] from the global frame.  The inboard end, the outboard ends, the centre of mass and the
load points are given as body-frame coordinates [m]; the body frame origin is arbitrary.

Hinge laws (moment on the outboard body, ``dtheta = theta_child - theta_parent``)
-----------------------------------------------------------------------------------
``tau = u(t) - k (dtheta - r(t)) - c (dtheta_dot - r_dot(t))``

* :class:`SmoothHinge` (revolute): ``k = c = u = 0``
* :class:`ElasticHinge`: rotary spring ``k`` with rest angle ``r``
* :class:`DamperHinge`: rotary damper ``c``
* :class:`SpringDamperHinge`: spring ``k`` parallel to damper ``c``
* :class:`ActuatedHinge`: torque input ``u(t)`` plus an optional collocated PD law with gains
  ``kp, kd`` about a reference angle ``r(t)`` (e.g. a motor)
* :class:`DrivenHinge`: prescribed relative angle ``r(t)`` (0 DOF); the torque is an output.
"""
from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass, field
from typing import Mapping, Sequence

from .. import validation
from ..errors import ModelError
from ..signals import Constant, SignalLike, TimeFunction, as_signal

Vector2 = tuple[float, float]


def _required(label: str, value) -> None:
    if isinstance(value, float) and math.isnan(value):
        raise ModelError(f"{label} is required (a finite number), got {value!r}")


def _translational(hinge) -> None:
    for attribute in ("translational_stiffness", "translational_damping"):
        object.__setattr__(hinge, attribute, validation.nonnegative(
            f"{hinge.name}: {attribute}", getattr(hinge, attribute)))


def _rotary_spring(hinge) -> None:
    """Check a spring hinge's ``stiffness`` (required, > 0), ``rest_angle`` and translational terms."""
    _translational(hinge)
    _required(f"{hinge.name}: stiffness", hinge.stiffness)
    object.__setattr__(hinge, "stiffness", validation.positive(f"{hinge.name}: stiffness", hinge.stiffness))
    object.__setattr__(hinge, "rest_angle", validation.finite(f"{hinge.name}: rest_angle", hinge.rest_angle))


def translational_law(hinge) -> tuple[float, float]:
    """``(k_t, c_t)`` of a hinge's translational spring / damper (0, 0 when rigid)."""
    return (float(getattr(hinge, "translational_stiffness", 0.0)),
            float(getattr(hinge, "translational_damping", 0.0)))


def _point(name: str, value) -> Vector2:
    x, y = validation.vector(name, value, 2, unit="m")
    return (float(x), float(y))


@dataclass(frozen=True)
class Load:
    """External load on a rigid body, in global axes.

    Parameters
    ----------
    point : (float, float)
        Application point in the body frame [m].
    force_x, force_y : float or callable
        Force components [N] in global axes, constants or functions of time ``t`` [s].
    moment : float or callable
        Moment [N m] about the global z axis.
    """

    point: Vector2 = (0.0, 0.0)
    force_x: SignalLike = 0.0
    force_y: SignalLike = 0.0
    moment: SignalLike = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "point", _point("load point", self.point))
        for attribute in ("force_x", "force_y", "moment"):
            object.__setattr__(self, attribute, as_signal(f"load {attribute}",
                                                          getattr(self, attribute)))


@dataclass(frozen=True)
class RigidBody:
    """Planar rigid body with one inboard end and any number of outboard ends.

    Parameters
    ----------
    name : str
        Unique element name.
    mass : float
        Mass [kg], > 0.
    inertia : float
        Moment of inertia about the centre of mass [kg m^2], > 0.
    center_of_mass : (float, float)
        Centre of mass in the body frame [m].
    inboard : (float, float)
        Inboard end (the point attached to the parent hinge) in the body frame [m].
    outboard : (float, float) or mapping of str to (float, float)
        Outboard end(s) in the body frame [m].  A single point is named ``"out"``; a mapping
        names several ends (a tree body, seed 002 section 7.4.2); ``{}`` for none.
    loads : sequence of Load
        External forces / moments in global axes at body points.

    Examples
    --------
    >>> link = RigidBody("link", mass=1.0, inertia=1 / 12, center_of_mass=(0.5, 0.0),
    ...                  outboard=(1.0, 0.0))
    >>> link.ends
    ('out',)
    """

    name: str
    _: KW_ONLY
    mass: float
    inertia: float
    center_of_mass: Vector2 = (0.0, 0.0)
    inboard: Vector2 = (0.0, 0.0)
    outboard: object = field(default_factory=dict)
    loads: Sequence[Load] = ()

    def __post_init__(self) -> None:
        validation.name("element", self.name)
        object.__setattr__(self, "mass", validation.positive(f"{self.name}: mass", self.mass))
        object.__setattr__(self, "inertia",
                           validation.positive(f"{self.name}: inertia", self.inertia))
        object.__setattr__(self, "center_of_mass",
                           _point(f"{self.name}: center_of_mass", self.center_of_mass))
        object.__setattr__(self, "inboard", _point(f"{self.name}: inboard", self.inboard))
        ends = self.outboard
        if isinstance(ends, Mapping):
            checked = {}
            for end_name, point in ends.items():
                validation.name(f"{self.name}: outboard end", end_name)
                checked[end_name] = _point(f"{self.name}: outboard[{end_name!r}]", point)
        else:
            checked = {"out": _point(f"{self.name}: outboard", ends)}
        object.__setattr__(self, "outboard", dict(checked))
        object.__setattr__(self, "loads", validation.instances(f"{self.name}: loads", self.loads, Load))

    @property
    def ends(self) -> tuple[str, ...]:
        """Names of the outboard ends."""
        return tuple(self.outboard)

    def __hash__(self) -> int:
        return hash(self.name)

    @classmethod
    def uniform_link(cls, name: str, *, mass: float, length: float,
                     loads: Sequence[Load] = ()) -> "RigidBody":
        """Slender uniform link along the body x axis: inboard at 0, outboard at ``length``.

        ``inertia = mass * length**2 / 12`` about the centre ``(length/2, 0)``.
        """
        length = validation.positive(f"{name}: length", length)
        mass = validation.positive(f"{name}: mass", mass)
        inertia = mass * length * length / 12.0
        if not 0.0 < inertia < math.inf:
            raise ModelError(f"{name}: inertia mass * length**2 / 12 must be finite and > 0, got {inertia!r} "
                             f"(mass={mass!r}, length={length!r})")
        return cls(name, mass=mass, inertia=inertia,
                   center_of_mass=(0.5 * length, 0.0), inboard=(0.0, 0.0),
                   outboard=(length, 0.0), loads=loads)


# ------------------------------------------------------------------------------------------
# hinges
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Hinge:
    """Common part of all hinges: the name and the connection (parent end, child body).

    ``parent`` is ``"body"`` (its only outboard end), ``"body.end"`` or the name of a
    :class:`Fixed` ground element; ``child`` is the body name.  Inside
    :meth:`PlanarModel.chain` both are filled in from the element order.
    """

    name: str
    _: KW_ONLY
    parent: str | None = None
    child: str | None = None

    def __post_init__(self) -> None:
        validation.name("element", self.name)
        for attribute in ("parent", "child"):
            value = getattr(self, attribute)
            if value is not None and (not isinstance(value, str) or not value):
                raise ModelError(f"{self.name}: {attribute} must be a name, got {value!r}")

    def connected(self, parent: str, child: str) -> "Hinge":
        """Copy with the connection filled in (used by the chain builder)."""
        import dataclasses
        return dataclasses.replace(self, parent=parent, child=child)

    # hinge law coefficients ---------------------------------------------------------------
    def law(self) -> tuple[float, float, TimeFunction, TimeFunction | None, TimeFunction]:
        """``(k, c, r, r_dot, u)`` of ``tau = u - k (dtheta - r) - c (dtheta_dot - r_dot)``."""
        return 0.0, 0.0, Constant(0.0), Constant(0.0), Constant(0.0)


@dataclass(frozen=True)
class SmoothHinge(Hinge):
    """Smooth revolute hinge: relative rotation free, moment ``tau = 0``."""


@dataclass(frozen=True, kw_only=True)
class ElasticHinge(Hinge):
    """Rotary spring hinge: ``tau = -stiffness (dtheta - rest_angle)``.

    Parameters
    ----------
    stiffness : float
        Rotary stiffness [N m/rad], > 0.
    rest_angle : float
        Relative angle at which the spring is relaxed [rad].
    translational_stiffness, translational_damping : float
        Optional isotropic translational spring [N/m] and damper [N s/m] between the parent
        end and the child's inboard end (>= 0).  When either is > 0 the hinge lets the
        child's inboard end move by ``d`` (coordinates ``"child.dx"``, ``"child.dy"``,
        global axes) with the force ``f = -k_t d - c_t d_dot`` on the child (3 DOF).
    """

    stiffness: float = math.nan
    rest_angle: float = 0.0
    translational_stiffness: float = 0.0
    translational_damping: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        _rotary_spring(self)

    def law(self):
        return self.stiffness, 0.0, Constant(self.rest_angle), Constant(0.0), Constant(0.0)


@dataclass(frozen=True, kw_only=True)
class DamperHinge(Hinge):
    """Rotary viscous damper hinge: ``tau = -damping dtheta_dot``.

    Parameters
    ----------
    damping : float
        Rotary damping [N m s/rad], > 0.
    """

    damping: float = math.nan

    def __post_init__(self) -> None:
        super().__post_init__()
        _required(f"{self.name}: damping", self.damping)
        object.__setattr__(self, "damping",
                           validation.positive(f"{self.name}: damping", self.damping))

    def law(self):
        return 0.0, self.damping, Constant(0.0), Constant(0.0), Constant(0.0)


@dataclass(frozen=True, kw_only=True)
class SpringDamperHinge(Hinge):
    """Rotary spring parallel to a damper: ``tau = -k (dtheta - rest_angle) - c dtheta_dot``.

    Parameters
    ----------
    stiffness : float
        Rotary stiffness [N m/rad], > 0.
    damping : float
        Rotary damping [N m s/rad], >= 0.
    rest_angle : float
        Relaxed relative angle [rad].
    translational_stiffness, translational_damping : float
        Optional isotropic translational spring / damper, as in :class:`ElasticHinge`.
    """

    stiffness: float = math.nan
    damping: float = math.nan
    rest_angle: float = 0.0
    translational_stiffness: float = 0.0
    translational_damping: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        _rotary_spring(self)
        _required(f"{self.name}: damping", self.damping)
        object.__setattr__(self, "damping",
                           validation.nonnegative(f"{self.name}: damping", self.damping))

    def law(self):
        return (self.stiffness, self.damping, Constant(self.rest_angle), Constant(0.0),
                Constant(0.0))


@dataclass(frozen=True, kw_only=True)
class ActuatedHinge(Hinge):
    """Hinge with a torque input and an optional collocated PD law (a motor).

    ``tau = torque(t) - kp (dtheta - reference(t)) - kd (dtheta_dot - reference_rate(t))``

    Parameters
    ----------
    torque : float or callable
        Feed-forward / open-loop torque input [N m].
    kp : float
        Proportional gain [N m/rad], >= 0.
    kd : float
        Derivative gain [N m s/rad], >= 0.
    reference : float or callable
        Reference relative angle ``theta_d(t)`` [rad].
    reference_rate : float or callable, optional
        Its time derivative [rad/s]; required when ``kd > 0`` and ``reference`` varies in
        time (no numerical differentiation is done silently).
    """

    torque: SignalLike = 0.0
    kp: float = 0.0
    kd: float = 0.0
    reference: SignalLike = 0.0
    reference_rate: SignalLike | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "torque", as_signal(f"{self.name}: torque", self.torque))
        object.__setattr__(self, "kp", validation.nonnegative(f"{self.name}: kp", self.kp))
        object.__setattr__(self, "kd", validation.nonnegative(f"{self.name}: kd", self.kd))
        varying = callable(self.reference) and not isinstance(self.reference, Constant)
        object.__setattr__(self, "reference",
                           as_signal(f"{self.name}: reference", self.reference))
        if self.reference_rate is None:
            if varying and self.kd > 0.0:
                raise ModelError(f"{self.name}: reference_rate is required when kd > 0 and the "
                                 f"reference varies in time (got reference={self.reference!r})")
            object.__setattr__(self, "reference_rate", Constant(0.0))
        else:
            object.__setattr__(self, "reference_rate",
                               as_signal(f"{self.name}: reference_rate", self.reference_rate))

    def law(self):
        return self.kp, self.kd, self.reference, self.reference_rate, self.torque


@dataclass(frozen=True, kw_only=True)
class DrivenHinge(Hinge):
    """Hinge with a prescribed relative angle ``angle(t)`` (0 DOF; the torque is an output).

    Parameters
    ----------
    angle, rate, acceleration : float or callable
        ``theta_d(t)`` [rad], its first [rad/s] and second [rad/s^2] time derivatives.  The
        three are checked for consistency by finite differences at a few times.
    """

    angle: SignalLike = 0.0
    rate: SignalLike = 0.0
    acceleration: SignalLike = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        for attribute in ("angle", "rate", "acceleration"):
            object.__setattr__(self, attribute,
                               as_signal(f"{self.name}: {attribute}", getattr(self, attribute)))
        self._check_derivatives()

    def _check_derivatives(self) -> None:
        step = 1e-4
        for t in (0.0137, 0.5, 1.31, 3.7):
            for low, high, label in ((self.angle, self.rate, "rate"),
                                     (self.rate, self.acceleration, "acceleration")):
                try:
                    numeric = (float(low(t + step)) - float(low(t - step))) / (2 * step)
                    given = float(high(t))
                except Exception as exc:  # noqa: BLE001 - user code, named with what it did
                    raise ModelError(f"{self.name}: checking the prescribed motion at t = {t} s, a signal "
                                     f"raised {type(exc).__name__}: {exc}") from exc
                if abs(numeric - given) > 1e-4 * max(1.0, abs(given), abs(numeric)):
                    raise ModelError(
                        f"{self.name}: {label}({t}) = {given!r} is not the time derivative of the "
                        f"previous signal (finite difference gives {numeric!r})")


@dataclass(frozen=True, kw_only=True)
class FixedMounting(DrivenHinge):
    """Rigid connection of a body to its parent's end (seed 000 section 4.3, "fixed mounting").

    The child's angle is the parent end's angle plus the constant mounting ``angle`` [rad]; for
    a flexible parent (:class:`~ctmm.flexible.ModalBeam`) the end angle includes the elastic
    slope at the end station, so the outboard body follows the slope at the inboard tip
    (rigid -> flexible, flexible -> flexible and flexible -> rigid mountings alike).  0 DOF; the
    transmitted moment is an output.
    """

    angle: float = 0.0

    def __post_init__(self) -> None:
        angle = self.angle.value if isinstance(self.angle, Constant) else self.angle
        object.__setattr__(self, "angle", validation.finite(f"{self.name}: angle", angle))
        super().__post_init__()


@dataclass(frozen=True, kw_only=True)
class NonlinearHinge(Hinge):
    """Hinge with a nonlinear rotary spring / damper law and, optionally, a nonlinear radial spring
    (seed 002 section 7.6.1; :mod:`ctmm.nonlinear_laws`: cubic ``K1 theta + K2 theta^3``, clearance /
    stop, power-law damper, user callables, and their sums).

    Moment on the child ``tau = -moment_law(dtheta - rest_angle, dtheta_dot)``.  With a ``radial_law``
    the child's inboard end may move by ``d`` from the parent end (coordinates ``"child.dx"``,
    ``"child.dy"``, global axes, as the translational springs of :class:`ElasticHinge`) and the force
    on the child is ``f = -radial_law(|d|) d / |d|`` (a radial spring: a pin in a hole with a clearance
    is ``ClearanceSpring(k, clearance=gap)``).  Time integration uses the laws themselves (the implicit
    DT-TMM Newton their tangents); the frequency verbs linearise them about the operating point.

    Parameters
    ----------
    moment_law : ctmm.nonlinear_laws.Law, optional
        Restoring moment ``f(delta, rate)`` [N m] of the relative angle [rad] and rate [rad/s]
        (None: no moment, a smooth hinge).
    radial_law : ctmm.nonlinear_laws.Law, optional
        Restoring force [N] of the radial offset ``|d|`` [m]; a spring (no rate dependence).
    rest_angle : float
        Relative angle at which ``delta = 0`` [rad].
    """

    moment_law: object = None
    radial_law: object = None
    rest_angle: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        from ..nonlinear_laws import Law
        for label in ("moment_law", "radial_law"):
            value = getattr(self, label)
            if value is not None and not isinstance(value, Law):
                raise ModelError(f"{self.name}: {label} must be a ctmm.nonlinear_laws.Law (CubicSpring, "
                                 f"ClearanceSpring, PowerDamper, CallableLaw, LinearLaw or their sum) or None, got "
                                 f"{value!r}")
        if self.moment_law is None and self.radial_law is None:
            raise ModelError(f"{self.name}: give a moment_law, a radial_law or both (got neither)")
        if self.radial_law is not None and self.radial_law.velocity_dependent:
            hint = (" (a CallableLaw counts as rate-dependent when its casadi force contains the rate, or when its "
                    "derivatives are given)") if "CallableLaw" in repr(self.radial_law) else ""
            raise ModelError(f"{self.name}: radial_law must be a spring (no rate dependence), got "
                             f"{self.radial_law!r}{hint}")
        object.__setattr__(self, "rest_angle", validation.finite(f"{self.name}: rest_angle", self.rest_angle))

    def moment(self, dtheta, dtheta_dot):
        """Hinge moment on the child ``-moment_law(dtheta - rest_angle, dtheta_dot)`` [N m] (0 without one)."""
        if self.moment_law is None:
            return 0.0 * dtheta
        return -self.moment_law.force(dtheta - self.rest_angle, dtheta_dot)


# ------------------------------------------------------------------------------------------
# boundaries
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Fixed:
    """Ground point (fixed boundary) at ``position`` [m] with frame angle ``angle`` [rad].

    Hinges name it as their ``parent``.  In a chain, a body that follows ``Fixed`` directly
    is welded to the ground.
    """

    name: str
    _: KW_ONLY
    position: Vector2 = (0.0, 0.0)
    angle: float = 0.0

    def __post_init__(self) -> None:
        validation.name("element", self.name)
        object.__setattr__(self, "position", _point(f"{self.name}: position", self.position))
        object.__setattr__(self, "angle", validation.finite(f"{self.name}: angle", self.angle))


@dataclass(frozen=True)
class Pinned:
    """Ground point with a smooth revolute hinge to ``child`` (pinned boundary)."""

    name: str
    _: KW_ONLY
    position: Vector2 = (0.0, 0.0)
    child: str | None = None

    def __post_init__(self) -> None:
        validation.name("element", self.name)
        object.__setattr__(self, "position", _point(f"{self.name}: position", self.position))


@dataclass(frozen=True)
class FreeBase:
    """Free (floating) base: ``child`` moves freely in the plane (3 DOF, zero force)."""

    name: str
    _: KW_ONLY
    child: str | None = None

    def __post_init__(self) -> None:
        validation.name("element", self.name)


@dataclass(frozen=True)
class Free:
    """Free end (zero force and moment); unconnected outboard ends are free anyway."""

    name: str

    def __post_init__(self) -> None:
        validation.name("element", self.name)


HINGE_TYPES = (SmoothHinge, ElasticHinge, DamperHinge, SpringDamperHinge, ActuatedHinge,
               DrivenHinge, FixedMounting, NonlinearHinge)
"""All hinge classes."""


def law_arrays(hinge: Hinge) -> tuple[float, float]:
    """Stiffness and damping of a hinge law (``0, 0`` for driven hinges)."""
    if isinstance(hinge, DrivenHinge):
        return 0.0, 0.0
    k, c, _, _, _ = hinge.law()
    return k, c


__all__ = ["Load", "RigidBody", "SmoothHinge", "ElasticHinge", "DamperHinge",
           "SpringDamperHinge", "ActuatedHinge", "DrivenHinge", "FixedMounting", "NonlinearHinge", "Fixed", "Pinned",
           "FreeBase", "Free", "HINGE_TYPES"]
