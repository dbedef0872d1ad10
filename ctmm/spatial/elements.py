"""Spatial multibody elements: rigid bodies, joints and loads (descriptions only, issue 14).

All elements are immutable descriptions validated at construction; an invalid parameter raises
:class:`~ctmm.errors.ModelError` naming the parameter, the value and what is allowed.  Physics
(the terms of the one articulated sweep) is in :mod:`ctmm.spatial.body_forms`; conventions and
derivations in ``docs/spatial.md``.

Frames
------
Every :class:`SpatialBody` has a body-fixed frame whose **origin is its inboard point** (where its
joint attaches it to its parent).  Centre of mass, inertia and named points are given in body
axes [m, kg m^2].  A joint connects a point of the parent (or of the ground) to the child's origin;
its **joint frame** is the parent's axes turned by the fixed rotation ``rotation`` (3 x 3, default
identity).  Joint axes are given in the joint frame.

Joint coordinates ``q`` and velocities ``v`` (velocities in the **child frame**, as in Pinocchio)
------------------------------------------------------------------------------------------
* :class:`Revolute` / :class:`Prismatic`: angle [rad] / displacement [m] along ``axis``; ``v = q_dot``;
* :class:`Universal`: two angles, child rotation ``R = Rot(axis1, q1) Rot(axis2, q2)``; ``v = q_dot``;
* :class:`Spherical`: unit quaternion ``(w, x, y, z)`` (scalar first); ``v`` = relative angular
  velocity in child axes [rad/s];
* :class:`Free` and :class:`Elastic6`: position of the child origin in the joint frame [m] and a
  quaternion; ``v = [v_o ; omega]`` in child axes (``v_o`` the velocity of the child origin);
* :class:`Weld`: none.

Joint laws (generalised force along ``v`` on the child, dual to ``v``)
--------------------------------------------------------------------
1- and 2-DOF joints: ``tau = u(t) - k (q - q_ref) - c v - law(q - q_ref, v)`` (``law`` an optional nonlinear
law of :mod:`ctmm.nonlinear_laws`, applied per coordinate; ``u`` the actuator input
``"<joint>.torque"`` / ``"<joint>.force"`` when ``actuated``); driven variants prescribe
``q(t), q_dot(t), q_ddot(t)`` (no coordinate; the generalised force is an output).  Spherical
(optional rotary spring / damper, "non-zero output torque"): ``tau = u - k s - c omega`` with
``s = 2 w (x, y, z)`` (``sin(angle) * axis``: exact potential ``2 k (1 - w^2)`` for a scalar ``k``,
the rotation vector to second order).  Elastic6: ``tau = u - K [R_rel^T p ; s] - C v``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError
from ..signals import SignalLike, as_signal

__all__ = ["SpatialBody", "Revolute", "Prismatic", "Universal", "Spherical", "Free", "Elastic6", "Weld",
           "Load", "JOINT_TYPES"]


def parent_point(label: str, parent: str | None, point: Any) -> Any:
    """A connection's point on its parent: the name of a point of the parent body (default ``"origin"``), or at the
    ground (``parent=None``) a location [m] in world axes (default the world origin).

    Parameters
    ----------
    label : str
        The connection, for messages (e.g. ``"hinge"``, ``"cut joint 'c'"``).
    parent : str or None
        The parent body's name, ``None`` for the ground.
    point : str, array_like or None
        As given.

    Returns
    -------
    str or ndarray (3,)
        The point's name, or the ground location.

    Raises
    ------
    ModelError
        A non-name on a body, or a ground location that is not 3 finite numbers.
    """
    if parent is not None:
        name = "origin" if point is None else point
        if not isinstance(name, str):
            raise ModelError(f"{label}: point must be the name of a point of the parent body {parent!r}, got {point!r}")
        return name
    return validation.vector(f"{label}: point (ground location)", (0.0, 0.0, 0.0) if point is None else point, unit="m")


def _rotation(label: str, value: Any) -> np.ndarray:
    if value is None:
        return np.eye(3)
    matrix = validation.finite_array(label, value)
    if matrix.shape != (3, 3):
        raise ModelError(f"{label} must be a 3 x 3 rotation matrix, got shape {matrix.shape}: {value!r:.80}")
    if not np.allclose(matrix.T @ matrix, np.eye(3), atol=1e-9) or np.linalg.det(matrix) < 0:
        raise ModelError(f"{label} must be a proper rotation matrix (R^T R = I, det R = +1 to 1e-9), got "
                         f"{value!r:.200}")
    return matrix


def _per_coordinate(label: str, value: Any, count: int, *, nonnegative: bool = False) -> np.ndarray:
    array = validation.finite_array(label, value)
    if array.ndim == 0:
        array = np.full(count, float(array))
    if array.shape != (count,):
        raise ModelError(f"{label} must be one number or {count} numbers (one per coordinate), got {value!r}")
    if nonnegative and np.any(array < 0):
        raise ModelError(f"{label} must be >= 0, got {value!r}")
    return array


def _matrix_law(label: str, value: Any, size: int) -> np.ndarray:
    array = validation.finite_array(label, value)
    if array.ndim <= 1 and np.any(array < 0.0):             # a number or a diagonal: exact signs, no round-off
        raise ModelError(f"{label} must be >= 0 (a number or a diagonal), got {value!r:.80}")
    if array.ndim == 0:
        array = float(array) * np.eye(size)
    elif array.shape == (size,):
        array = np.diag(array)
    if array.shape != (size, size):
        raise ModelError(f"{label} must be a number, {size} numbers (diagonal) or a {size} x {size} matrix, got "
                         f"shape {array.shape}: {value!r:.80}")
    if not np.allclose(array, array.T, atol=1e-12 * max(1.0, np.abs(array).max())):
        raise ModelError(f"{label} must be symmetric, got {array.tolist()}")
    if np.linalg.eigvalsh(array).min() < -1e-12 * max(1.0, np.abs(array).max()):
        raise ModelError(f"{label} must be positive semi-definite, got eigenvalues "
                         f"{np.linalg.eigvalsh(array).tolist()} of {value!r:.200}")
    return array


def _signals(label: str, value: Any, count: int) -> tuple:
    if value is None:
        return None
    several = isinstance(value, (list, tuple)) or (isinstance(value, np.ndarray) and value.ndim > 0)
    items = list(value) if several else [value]          # a 0-d array is one number
    if len(items) != count:
        raise ModelError(f"{label} must be {count} signal(s) (numbers or f(t)), one per coordinate, got {value!r}")
    return tuple(as_signal(f"{label}[{i}]", item) for i, item in enumerate(items))


@dataclass(frozen=True)
class SpatialBody:
    """Rigid body in space.

    Parameters
    ----------
    name : str
    mass : float
        Mass [kg], > 0.
    inertia : (3, 3) array
        Inertia tensor about the centre of mass in body axes [kg m^2]: symmetric positive definite,
        principal moments satisfying the triangle inequalities.
    center_of_mass : (3,) array
        Centre of mass in body axes, from the inboard point (the body origin) [m].
    points : mapping of str to (3,) array
        Named connection / load / sensor points in body axes [m] (``"origin"`` is always there).
    """

    name: str
    mass: float
    inertia: Any
    center_of_mass: Any = (0.0, 0.0, 0.0)
    points: Any = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", validation.name("body", self.name))
        object.__setattr__(self, "mass", validation.positive(f"{self.name}: mass", self.mass))
        inertia = validation.finite_array(f"{self.name}: inertia", self.inertia)
        if inertia.shape == (3,):
            inertia = np.diag(inertia)
        if inertia.shape != (3, 3):
            raise ModelError(f"{self.name}: inertia must be a 3 x 3 matrix (or 3 principal moments) [kg m^2], "
                             f"got shape {inertia.shape}: {self.inertia!r:.80}")
        scale = max(1e-300, float(np.abs(inertia).max()))
        if not np.allclose(inertia, inertia.T, atol=1e-12 * scale):
            raise ModelError(f"{self.name}: inertia must be symmetric, got {inertia.tolist()}")
        moments = np.linalg.eigvalsh(inertia)
        if moments.min() <= 0:
            raise ModelError(f"{self.name}: inertia must be positive definite [kg m^2], got principal moments "
                             f"{moments.tolist()}")
        a, b, c = moments
        if c > a + b + 1e-12 * scale:
            raise ModelError(f"{self.name}: inertia principal moments {moments.tolist()} violate the triangle "
                             "inequality (largest <= sum of the other two) of a physical body")
        object.__setattr__(self, "inertia", inertia)
        object.__setattr__(self, "center_of_mass", validation.vector(f"{self.name}: center_of_mass",
                                                                     self.center_of_mass, unit="m"))
        if not hasattr(self.points, "items"):
            raise ModelError(f"{self.name}: points must be a mapping of point name to (3,) body coordinates, "
                             f"got {self.points!r}")
        points = {"origin": np.zeros(3)}
        for key, value in self.points.items():
            validation.name(f"{self.name}: points key {key!r}:", key)
            points[key] = validation.vector(f"{self.name}: points[{key!r}]", value, unit="m")
            if key == "origin" and np.any(points[key]):
                raise ModelError(f"{self.name}: points['origin'] is the body origin (its inboard point) and must "
                                 f"be (0, 0, 0), got {list(value)}; name the point differently")
        object.__setattr__(self, "points", points)


@dataclass(frozen=True, kw_only=True)
class _Joint:
    """Common fields of the joints: ``parent`` body name (``None``: ground), its ``point`` (a point
    name of the parent; at the ground a (3,) location [m], default the origin), ``child`` body name
    and the joint frame ``rotation`` relative to the parent's axes."""

    name: str
    parent: str | None
    child: str
    point: Any = None
    rotation: Any = None

    coordinate_count = 0
    velocity_count = 0
    kind = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", validation.name("joint", self.name))
        if self.parent is not None:
            validation.name(f"{self.name}: parent", self.parent)
        object.__setattr__(self, "point", parent_point(self.name, self.parent, self.point))
        validation.name(f"{self.name}: child", self.child)
        object.__setattr__(self, "rotation", _rotation(f"{self.name}: rotation", self.rotation))

    @property
    def inputs(self) -> tuple[str, ...]:
        """Actuator input names (``"<joint>.torque"`` or ``"<joint>.force"``)."""
        return ()

    @property
    def driven(self) -> bool:
        """True for a joint with prescribed motion (no coordinate)."""
        return False


@dataclass(frozen=True, kw_only=True)
class _Lawful(_Joint):
    """A 1- or 2-DOF joint with ``tau = u - stiffness (q - reference) - damping v - law(q - reference, v)``
    (per coordinate; ``law`` an optional :mod:`ctmm.nonlinear_laws` law, restoring force [N] or moment
    [N m]), or driven by ``position, rate, acceleration`` signals (one each per coordinate)."""

    stiffness: Any = 0.0
    damping: Any = 0.0
    reference: Any = 0.0
    law: Any = None
    actuated: bool = False
    position: Any = None
    rate: Any = None
    acceleration: Any = None

    input_kind = "torque"

    def __post_init__(self) -> None:
        super().__post_init__()
        n = self.velocity_count
        object.__setattr__(self, "stiffness", _per_coordinate(f"{self.name}: stiffness", self.stiffness, n,
                                                              nonnegative=True))
        object.__setattr__(self, "damping", _per_coordinate(f"{self.name}: damping", self.damping, n,
                                                            nonnegative=True))
        object.__setattr__(self, "reference", _per_coordinate(f"{self.name}: reference", self.reference, n))
        validation.flag(f"{self.name}: actuated", self.actuated)
        if self.law is not None:
            from ..nonlinear_laws import Law
            if not isinstance(self.law, Law):
                raise ModelError(f"{self.name}: law must be None or a ctmm.nonlinear_laws.Law (CubicSpring, "
                                 f"ClearanceSpring, PowerDamper, CallableLaw, ...), got {self.law!r}")
        given = [self.position is not None, self.rate is not None, self.acceleration is not None]
        if any(given) and not all(given):
            raise ModelError(f"{self.name}: a driven joint needs position, rate and acceleration (signals), got "
                             f"position={self.position!r}, rate={self.rate!r}, acceleration={self.acceleration!r}")
        if all(given):
            if self.actuated or np.any(self.stiffness) or np.any(self.damping) or self.law is not None:
                raise ModelError(f"{self.name}: a driven joint has no law; leave stiffness, damping at 0, law at None "
                                 "and actuated at False")
            for attribute in ("position", "rate", "acceleration"):
                object.__setattr__(self, attribute, _signals(f"{self.name}: {attribute}", getattr(self, attribute), n))
            _check_derivatives(self)

    @property
    def inputs(self) -> tuple[str, ...]:
        """``("<joint>.torque",)`` (prismatic ``".force"``) when actuated."""
        return (f"{self.name}.{self.input_kind}",) if self.actuated else ()

    @property
    def driven(self) -> bool:
        """True when ``position, rate, acceleration`` are given."""
        return self.position is not None


def _check_derivatives(joint: _Lawful) -> None:
    step = 1e-4
    for t in (0.0137, 0.5, 1.31, 3.7):
        for low, high, label in ((joint.position, joint.rate, "rate"), (joint.rate, joint.acceleration,
                                                                          "acceleration")):
            for i, (f, g) in enumerate(zip(low, high)):
                numeric = (float(f(t + step)) - float(f(t - step))) / (2 * step)
                given = float(g(t))
                if abs(numeric - given) > 1e-4 * max(1.0, abs(given), abs(numeric)):
                    raise ModelError(f"{joint.name}: {label}[{i}]({t}) = {given!r} is not the time derivative of "
                                     f"the previous signal (finite difference gives {numeric!r})")


@dataclass(frozen=True, kw_only=True)
class Revolute(_Lawful):
    """Revolute joint about ``axis`` (joint frame, normalised); coordinate: angle [rad]."""

    axis: Any = (0.0, 0.0, 1.0)
    coordinate_count = 1
    velocity_count = 1
    kind = "revolute"

    def __post_init__(self) -> None:
        object.__setattr__(self, "axis", validation.unit_vector(f"{getattr(self, 'name', '?')}: axis", self.axis))
        super().__post_init__()


@dataclass(frozen=True, kw_only=True)
class Prismatic(_Lawful):
    """Prismatic joint along ``axis`` (joint frame, normalised); coordinate: displacement [m]."""

    axis: Any = (1.0, 0.0, 0.0)
    coordinate_count = 1
    velocity_count = 1
    kind = "prismatic"
    input_kind = "force"

    def __post_init__(self) -> None:
        object.__setattr__(self, "axis", validation.unit_vector(f"{getattr(self, 'name', '?')}: axis", self.axis))
        super().__post_init__()


@dataclass(frozen=True, kw_only=True)
class Universal(_Lawful):
    """Universal (Cardan) joint: ``R = Rot(axis1, q1) Rot(axis2, q2)``; axes not parallel."""

    axis1: Any = (1.0, 0.0, 0.0)
    axis2: Any = (0.0, 1.0, 0.0)
    coordinate_count = 2
    velocity_count = 2
    kind = "universal"

    def __post_init__(self) -> None:
        label = getattr(self, "name", "?")
        object.__setattr__(self, "axis1", validation.unit_vector(f"{label}: axis1", self.axis1))
        object.__setattr__(self, "axis2", validation.unit_vector(f"{label}: axis2", self.axis2))
        if np.linalg.norm(np.cross(self.axis1, self.axis2)) < 1e-6:
            raise ModelError(f"{label}: axis1 {self.axis1.tolist()} and axis2 {self.axis2.tolist()} must not be "
                             "parallel")
        super().__post_init__()


@dataclass(frozen=True, kw_only=True)
class Spherical(_Joint):
    """Smooth ball-and-socket joint (quaternion coordinates), optionally with a rotary spring / damper
    (``stiffness``, ``damping``: number, 3 numbers or 3 x 3 [N m/rad], [N m s/rad]) and a torque input
    (3 components in child axes) when ``actuated``."""

    stiffness: Any = 0.0
    damping: Any = 0.0
    actuated: bool = False
    coordinate_count = 4
    velocity_count = 3
    kind = "spherical"

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "stiffness", _matrix_law(f"{self.name}: stiffness", self.stiffness, 3))
        object.__setattr__(self, "damping", _matrix_law(f"{self.name}: damping", self.damping, 3))
        validation.flag(f"{self.name}: actuated", self.actuated)

    @property
    def inputs(self) -> tuple[str, ...]:
        """``("<joint>.torque",)`` (3 components, child axes) when actuated."""
        return (f"{self.name}.torque",) if self.actuated else ()


@dataclass(frozen=True, kw_only=True)
class Free(_Joint):
    """Six-DOF free joint (floating base when ``parent`` is ``None``): position + quaternion, twist in
    child axes; ``actuated`` adds a wrench input ``"<joint>.wrench"`` (6, child axes, force first)."""

    actuated: bool = False
    coordinate_count = 7
    velocity_count = 6
    kind = "free"

    def __post_init__(self) -> None:
        super().__post_init__()
        validation.flag(f"{self.name}: actuated", self.actuated)

    @property
    def inputs(self) -> tuple[str, ...]:
        """``("<joint>.wrench",)`` (force and moment, child axes) when actuated."""
        return (f"{self.name}.wrench",) if self.actuated else ()


@dataclass(frozen=True, kw_only=True)
class Elastic6(Free):
    """Six-DOF elastic / damper hinge (elastic boundary at the ground): a :class:`Free` joint with the
    linear law ``tau = u - stiffness [R_rel^T p ; 2 w (x, y, z)] - damping v`` (6 x 6, translation first
    [N/m, N, N m/m, N m/rad]; symmetric positive semi-definite)."""

    stiffness: Any = 0.0
    damping: Any = 0.0
    kind = "elastic6"

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "stiffness", _matrix_law(f"{self.name}: stiffness", self.stiffness, 6))
        object.__setattr__(self, "damping", _matrix_law(f"{self.name}: damping", self.damping, 6))


@dataclass(frozen=True, kw_only=True)
class Weld(_Joint):
    """Rigid connection (fixed boundary at the ground); no coordinate; its wrench is an output."""

    kind = "weld"


JOINT_TYPES = (Revolute, Prismatic, Universal, Spherical, Free, Elastic6, Weld)
"""Joint element classes of :class:`~ctmm.spatial.model.SpatialModel`."""


@dataclass(frozen=True)
class Load:
    """External force and moment on a body at one of its points.

    Parameters
    ----------
    name : str
    body : str
        Body name.
    point : str
        Application point (a point name of the body; default its origin).
    force, moment : 3 numbers or callables of time
        Force [N] and moment [N m] components.
    axes : {"world", "body"}
        Axes of the components.
    """

    name: str
    body: str
    point: str = "origin"
    force: Sequence[SignalLike] = (0.0, 0.0, 0.0)
    moment: Sequence[SignalLike] = (0.0, 0.0, 0.0)
    axes: str = "world"

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", validation.name("load", self.name))
        validation.name(f"{self.name}: body", self.body)
        if not isinstance(self.point, str) or not self.point:
            raise ModelError(f"{self.name}: point must be a point name of body {self.body!r}, got {self.point!r}")
        object.__setattr__(self, "axes", validation.option(f"{self.name}: axes", self.axes, ("world", "body")))
        for label in ("force", "moment"):
            if getattr(self, label) is None:
                raise ModelError(f"{self.name}: {label} must be 3 signals (numbers or f(t)); for none give "
                                 f"(0, 0, 0), got None")
            object.__setattr__(self, label, _signals(f"{self.name}: {label}", getattr(self, label), 3))

    def values(self, t: float) -> np.ndarray:
        """``[force ; moment]`` (6,) at time ``t`` [N, N m]."""
        return np.array([float(f(t)) for f in self.force + self.moment])
