"""Named sensors and actuators of a spatial model: the signals loops and controllers connect to.

A :class:`~ctmm.spatial.model.SpatialModel` exposes

Sensors (measured signals)
    * joint coordinates and rates: ``"<joint>.angle"`` [rad] / ``"<joint>.rate"`` [rad/s] of a
      revolute joint, ``"<joint>.position"`` [m] / ``"<joint>.rate"`` [m/s] of a prismatic one,
      ``"<joint>.q1"``, ``"<joint>.q2"`` [rad] and ``"<joint>.q1_rate"``, ``"<joint>.q2_rate"``
      [rad/s] of a universal one; and every entry of ``q`` and ``v`` under its own name
      (``model.coordinates``, ``model.velocities``: quaternion components [1], free-joint
      positions [m], spherical / free angular velocities ``"<joint>.wx|wy|wz"`` [rad/s] and
      linear velocities ``"<joint>.vx|vy|vz"`` [m/s], child axes);
    * ``"<body>.omega_x|y|z"`` -- angular velocity about the world axes [rad/s];
      ``"<body>.omega_body_x|y|z"`` -- the same vector in the body's axes [rad/s];
    * ``"<body>.angle_x|y|z"`` -- the book's x-y-z angles of the body (seed 002 §7.3.4): the body
      rotation ``R = Rx(angle_x) Ry(angle_y) Rz(angle_z)`` (turn about x, then the new y, then the
      new z) [rad].  Limits: ``angle_y`` in ``[-pi/2, pi/2]``, ``angle_x``, ``angle_z`` in
      ``(-pi, pi]`` (they jump by ``2 pi`` when they cross ``pi``); at ``|angle_y| = pi/2`` (gimbal
      lock) only ``angle_x + angle_z`` (or the difference) is defined and the angles are ill
      conditioned near it (the sensor is exact, but a loop on it sees an amplified noise).  For
      small rotations they equal the rotation vector to first order (the book's linearisation);
    * ``"<body>.rotation_x|y|z"`` -- the rotation vector ``phi = angle * axis`` of the body
      (``R = exp([phi]x)``, ``|phi| <= pi``; at ``|phi| = pi`` it flips to ``-phi``) [rad];
    * ``"<body>.<point>.x|y|z"`` [m] and ``".vx|vy|vz"`` [m/s] -- world position and velocity of
      a body point: ``origin``, ``com`` (centre of mass) and every named point of the body (of a beam:
      the deformed points; of a :class:`ctmm.fem.SpatialSubsystem`: also ``"<body>.<node>.x|y|z"`` of every node,
      deformed);
    * beams (:class:`~ctmm.spatial.beam.SpatialBeam`): the station sensors of :mod:`ctmm.spatial.beam_ports`.

Actuators (inputs, added to what the model's own laws and loads apply)
    * joint inputs of actuated joints (``actuated=True``; their model inputs
      ``model.inputs``): ``"<joint>.torque"`` [N m] (revolute), ``"<joint>.force"`` [N]
      (prismatic), ``"<joint>.torque1|torque2"`` [N m] (universal, per coordinate),
      ``"<joint>.torque_x|y|z"`` [N m] (spherical, child axes), ``"<joint>.force_x|y|z"`` [N] and
      ``"<joint>.torque_x|y|z"`` [N m] (free and elastic6: the wrench input, child axes);
    * ``"<body>.force_x|y|z"`` [N] -- force at the centre of mass, world axes;
      ``"<body>.moment_x|y|z"`` [N m] -- moment on the body, world axes;
      ``"<body>.<point>.force_x|y|z"`` [N] -- force at a named point (or ``origin``), world axes;
    * the same in the **body's axes** (components along the body axes, turning with the body: a thruster, a
      reaction wheel's torque): ``"<body>.force_body_x|y|z"`` [N] (at the centre of mass),
      ``"<body>.moment_body_x|y|z"`` [N m] and, on rigid bodies, ``"<body>.<point>.force_body_x|y|z"`` [N]
      (of a beam or a :class:`ctmm.fem.SpatialSubsystem`: the axes of its floating frame);
      beams also ``"<beam>.<point>.moment_x|y|z"`` [N m] (world axes) at their points, and
      ``"<beam>.<point>.force_body_x|y|z"`` [N], ``".moment_body_x|y|z"`` [N m] in the beam's floating frame
      (turning with it: a piezo pair, :func:`ctmm.spatial.beam_ports.patch_actuator`).

Sensors are kinematic: a position-like sensor depends on ``q`` (and ``t`` through driven
joints) only, a rate sensor is linear in ``v``.  :func:`sensor_jacobians` gives the Jacobians in
the **tangent coordinates** of ``v`` (a perturbation ``delta`` moves ``q`` along ``G(q) delta``),
exact to round-off: by complex step through the complex-step-safe sensor maps of
:mod:`ctmm.spatial.sensor_maps` (the one statement of every sensor, also behind :meth:`SpatialPorts.values`).

Accelerations are not sensors (they would close an algebraic loop through the sweep: the
actuator values would depend on the accelerations they cause); measure positions, angles or
rates.  Driven joints have no sensors (their motion is the signal you gave) and no inputs.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from .. import validation
from ..errors import ModelError, UnknownNameError
from ..named_ports import NamedPorts
from . import sensor_maps as maps
from .beam_ports import beam_actuator_rows, beam_sensor_rows
from .body_forms import SpatialScene
from .dynamics import scene_solution, solve_scene
from .model import SpatialModel
from .sensor_maps import rotation_vector, xyz_angles

__all__ = ["SpatialPorts", "SpatialInputs", "sensor_values", "sensor_jacobians", "xyz_angles", "rotation_vector"]

_AXES = "xyz"
_RATE_PARTS = ("rate", "q1_rate", "q2_rate", "omega", "omega_body", "v", "velocity")


@dataclass(frozen=True)
class _Sensor:
    """One resolved sensor: what it reads (``kind``, ``index``, ``component``) and its unit."""

    name: str
    kind: str            # "q", "v" (state entries), "omega", "omega_body", "angles", "rotation", "point", "point_v"
    index: int           # state index, or body index
    component: int = 0   # axis 0, 1, 2
    point: tuple = ()    # body-axes point of kind "point" / "point_v"
    unit: str = ""
    weights: tuple = ()  # kinds "modal" / "modal_v": y = weights . eta (or eta_dot) of the body's beam

    @property
    def is_rate(self) -> bool:
        return self.kind in ("v", "omega", "omega_body", "point_v", "modal_v")


@dataclass(frozen=True)
class _Actuator:
    name: str
    kind: str            # "joint" or "body"
    target: str | int    # model input name, or body index
    component: int       # entry of the joint input; body: 0..2 force, 3..5 moment
    point: tuple         # body-axes point of a force (body actuators)
    unit: str
    axes: str = "world"  # body actuators: components in world axes, or "body" (the body's / floating frame's)


@dataclass(frozen=True)
class SpatialInputs:
    """Actuator values of one instant, arranged for the sweep.

    Attributes
    ----------
    joint : dict of str to ndarray
        Joint inputs by model input name (``"<joint>.torque"``: (k,) [N m, N]).
    wrenches : dict of int to list
        Extra loads by body index: ``(point (3,) body axes [m], numpy batched column (1, 6, 1) [f ; m] world
        axes [N, N m])``, or ``(point, column, "body")`` with ``[f ; m]`` in the body's axes (of a beam: its
        floating frame; the ``force_body`` / ``moment_body`` actuators).
    checked : bool
        ``True`` when the wrenches were built by ctmm (:meth:`SpatialPorts.inputs`, the loop drivers) in the form
        the sweep reads, so :meth:`SpatialPorts.accelerations` skips their check in inner loops; a hand-built
        ``SpatialInputs`` keeps the default ``False`` and its wrenches are checked (a bad entry is a
        :class:`ModelError` naming it).
    """

    joint: Mapping[str, np.ndarray] = field(default_factory=dict)
    wrenches: Mapping[int, list] = field(default_factory=dict)
    checked: bool = field(default=False, kw_only=True)     # by keyword: a subclass adds fields after it


def _joint_sensor_names(joint) -> list[tuple[str, str, int, str]]:
    """``(suffix, "q" | "v", offset in the joint's block, unit)`` of a lawful joint's own sensors."""
    if joint.kind == "revolute":
        return [("angle", "q", 0, "rad"), ("rate", "v", 0, "rad/s")]
    if joint.kind == "prismatic":
        return [("position", "q", 0, "m"), ("rate", "v", 0, "m/s")]
    if joint.kind == "universal":
        return [("q1", "q", 0, "rad"), ("q2", "q", 1, "rad"), ("q1_rate", "v", 0, "rad/s"),
                ("q2_rate", "v", 1, "rad/s")]
    return []


def _joint_actuator_names(joint) -> list[tuple[str, int, str]]:
    """``(name, component of the model input, unit)`` of an actuated joint."""
    if not joint.inputs:
        return []
    base = joint.name
    if joint.kind == "revolute":
        return [(f"{base}.torque", 0, "N m")]
    if joint.kind == "prismatic":
        return [(f"{base}.force", 0, "N")]
    if joint.kind == "universal":
        return [(f"{base}.torque1", 0, "N m"), (f"{base}.torque2", 1, "N m")]
    if joint.kind == "spherical":
        return [(f"{base}.torque_{a}", k, "N m") for k, a in enumerate(_AXES)]
    return [(f"{base}.force_{a}", k, "N") for k, a in enumerate(_AXES)] + \
        [(f"{base}.torque_{a}", 3 + k, "N m") for k, a in enumerate(_AXES)]


def _state_unit(name: str, rate: bool) -> str:
    part = name.rsplit(".", 1)[-1]
    if rate:
        return "m/s" if part in ("vx", "vy", "vz", "position_rate") else "rad/s"
    if part in ("x", "y", "z", "position"):
        return "m"
    return "1" if part in ("qw", "qx", "qy", "qz") else "rad"


def _build(model: SpatialModel) -> tuple[dict, dict]:
    sensors: dict[str, _Sensor] = {}
    actuators: dict[str, _Actuator] = {}
    for joint, layout in zip(model.joints, model.layout):
        if joint.driven:
            continue
        for suffix, which, offset, unit in _joint_sensor_names(joint):
            start = (layout.position if which == "q" else layout.velocity).start
            sensors[f"{joint.name}.{suffix}"] = _Sensor(f"{joint.name}.{suffix}", which, start + offset, unit=unit)
        for name, component, unit in _joint_actuator_names(joint):
            actuators[name] = _Actuator(name, "joint", joint.inputs[0], component, (), unit)
    for body, layout in zip(model.bodies, model.modal):      # beams' modal coordinates and rates
        if layout is not None:
            for k, (suffix, unit) in enumerate(zip(body.coordinate_suffixes, body.coordinate_units)):
                name = f"{body.name}.{suffix}"
                sensors[name] = _Sensor(name, "q", layout.position.start + k, unit=unit)
                sensors[f"{name}_rate"] = _Sensor(f"{name}_rate", "v", layout.velocity.start + k, unit=f"{unit}/s")
    for k, name in enumerate(model.coordinates):
        sensors.setdefault(name, _Sensor(name, "q", k, unit=_state_unit(name, False)))
    for k, name in enumerate(model.velocities):
        sensors.setdefault(name, _Sensor(name, "v", k, unit=_state_unit(name, True)))
    for j, body in enumerate(model.bodies):
        for c, a in enumerate(_AXES):
            for kind, label, unit in (("omega", "omega", "rad/s"), ("omega_body", "omega_body", "rad/s"),
                                      ("angles", "angle", "rad"), ("rotation", "rotation", "rad")):
                sensors[f"{body.name}.{label}_{a}"] = _Sensor(f"{body.name}.{label}_{a}", kind, j, c, unit=unit)
        points = {p: tuple(r) for p, r in body.points.items()}
        if model.modal[j] is None:
            points["com"] = tuple(body.center_of_mass)
        else:                                                # a beam: station sensors, point moments
            for name, rate, weights, unit in beam_sensor_rows(body):
                sensors[name] = _Sensor(name, "modal_v" if rate else "modal", j, unit=unit, weights=tuple(weights))
            for name, component, point, unit, axes in beam_actuator_rows(body):
                actuators[name] = _Actuator(name, "body", j, component, point, unit, axes)
        for point, r in points.items():
            for c, a in enumerate(_AXES):
                sensors[f"{body.name}.{point}.{a}"] = _Sensor(f"{body.name}.{point}.{a}", "point", j, c, r, "m")
                sensors[f"{body.name}.{point}.v{a}"] = _Sensor(f"{body.name}.{point}.v{a}", "point_v", j, c, r,
                                                               "m/s")
            if point != "com":
                for c, a in enumerate(_AXES):
                    label = f"{body.name}.{point}.force_{a}"
                    actuators[label] = _Actuator(label, "body", j, c, r, "N")
                    if model.modal[j] is None:                 # a beam's body-axes point forces: beam_actuator_rows
                        label = f"{body.name}.{point}.force_body_{a}"
                        actuators[label] = _Actuator(label, "body", j, c, r, "N", "body")
        for node, (r, _, _) in getattr(getattr(body, "data", None), "point_rows", {}).items():   # every FE node
            for c, a in enumerate(_AXES):
                label = f"{body.name}.{node}.{a}"
                sensors.setdefault(label, _Sensor(label, "point", j, c, tuple(r), "m"))
        for c, a in enumerate(_AXES):
            actuators[f"{body.name}.force_{a}"] = _Actuator(f"{body.name}.force_{a}", "body", j, c,
                                                            tuple(body.center_of_mass), "N")
            actuators[f"{body.name}.moment_{a}"] = _Actuator(f"{body.name}.moment_{a}", "body", j, 3 + c,
                                                             (0.0, 0.0, 0.0), "N m")
            actuators[f"{body.name}.force_body_{a}"] = _Actuator(f"{body.name}.force_body_{a}", "body", j, c,
                                                                 tuple(body.center_of_mass), "N", "body")
            actuators[f"{body.name}.moment_body_{a}"] = _Actuator(f"{body.name}.moment_body_{a}", "body", j, 3 + c,
                                                                  (0.0, 0.0, 0.0), "N m", "body")
    return sensors, actuators



class SpatialPorts(NamedPorts):
    """The sensors and actuators of one spatial model, resolved once (hold one in a time loop).

    Parameters
    ----------
    model : SpatialModel
    """

    def __init__(self, model: SpatialModel) -> None:
        if not isinstance(model, SpatialModel):
            raise ModelError(f"model must be a ctmm.spatial.SpatialModel, got {model!r}")
        self.model = model
        self.scene = SpatialScene(model)
        self.sensors, self.actuators = _build(model)

    # -- sizes and dynamics -------------------------------------------------------------------
    @property
    def n_positions(self) -> int:
        """Entries of ``q``."""
        return self.model.n_positions

    @property
    def n_velocities(self) -> int:
        """Entries of ``v``."""
        return self.model.n_velocities

    @property
    def element_names(self) -> tuple[str, ...]:
        """Names of the model's bodies and joints (loop names must differ from them)."""
        return tuple(b.name for b in self.model.bodies) + tuple(j.name for j in self.model.joints)

    def position_rates(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``q_dot = G(q) v`` (1-D)."""
        return self.model.position_rates(q[None], v[None])[0]

    def accelerations(self, q: np.ndarray, v: np.ndarray, t: float, inputs: SpatialInputs | None) -> np.ndarray:
        """``v_dot`` (1-D) with the actuator ``inputs`` (:meth:`inputs`) applied."""
        if inputs is None:
            rates = solve_scene(self.scene, q, v, t).velocity_rates
        elif not inputs.checked:                            # a hand-built SpatialInputs: its wrenches checked
            rates = solve_scene(self.scene, q, v, t, inputs.joint, inputs.wrenches).velocity_rates
        else:
            rates = scene_solution(self.scene, q, v, validation.finite("t", t), inputs.joint,
                                   inputs.wrenches).velocity_rates      # the wrenches built by inputs()
        return rates[0] if np.ndim(q) == 1 else rates

    # -- names ----------------------------------------------------------------------------------
    def check_sensor(self, name: str, what: str = "sensor") -> str:
        """``name`` if it is a sensor, else an error listing the sensors."""
        if not isinstance(name, str) or name not in self.sensors:
            last = name.rsplit(".", 1)[-1] if isinstance(name, str) and "." in name else ""
            if last in ("a", "ax", "ay", "az", "alpha") or last.startswith(("alpha_", "acceleration")):
                raise ModelError(f"{what} {name!r}: accelerations are not sensors of spatial models (they would "
                                 "close an algebraic loop through the sweep: the actuator values would depend on "
                                 "the accelerations they cause); measure positions, angles or rates")
            if isinstance(name, str) and name.split(".", 1)[0] in {j.name for j in self.model.joints if j.driven}:
                raise ModelError(f"{what} {name!r}: joint {name.split('.', 1)[0]!r} is driven (its motion is the "
                                 "signal you prescribed); it has no sensors")
            raise UnknownNameError(f"unknown {what} {name!r} of spatial model {self.model.name!r}; available: "
                                   f"{', '.join(sorted(self.sensors)) or '(none)'}")
        return name

    def check_actuator(self, name: str, what: str = "actuator") -> str:
        """``name`` if it is an actuator, else an error listing the actuators."""
        if not isinstance(name, str) or name not in self.actuators:
            joints = {j.name: j for j in self.model.joints}
            head = name.split(".", 1)[0] if isinstance(name, str) else None
            if head in joints:
                joint = joints[head]
                reason = ("is driven (its motion is prescribed)" if joint.driven else
                          "is welded (it has no free direction)" if joint.kind == "weld" else
                          "has no actuator of that name" if joint.inputs else
                          "is not actuated: declare it with actuated=True to give it an input")
                raise ModelError(f"{what} {name!r}: joint {head!r} {reason}; the actuators of {head!r} are "
                                 f"{[a for a in self.actuators if a.startswith(head + '.')]}")
            raise UnknownNameError(f"unknown {what} {name!r} of spatial model {self.model.name!r}; available: "
                                   f"{', '.join(sorted(self.actuators)) or '(none)'}")
        return name

    def values(self, sensors: list, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """Values of resolved ``sensors`` at ``(q, v, t)`` (no validation of the state: for inner loops;
        the maps of :func:`ctmm.spatial.sensor_maps.sensor_values`)."""
        return maps.sensor_values(self.model, self.scene, sensors, np.asarray(q, float)[None],
                                  np.asarray(v, float)[None], t)[0]

    def inputs(self, values: Mapping[str, float]) -> SpatialInputs:
        """Arrange actuator ``values`` (``{actuator name: value}``, SI units) for the sweep; several
        entries on one actuator add up."""
        if not isinstance(values, Mapping):
            raise ModelError(f"values must be a mapping of actuator name to value, got {values!r}")
        joint: dict[str, np.ndarray] = {}
        body: dict[tuple[int, tuple, str], np.ndarray] = {}
        for name, value in values.items():
            actuator = self.actuators[self.check_actuator(name)]
            value = validation.finite(f"actuator {name!r}", value)
            if actuator.kind == "joint":
                size = next(j.velocity_count for j in self.model.joints if actuator.target in j.inputs)
                joint.setdefault(actuator.target, np.zeros(size))[actuator.component] += value
            else:
                key = (actuator.target, actuator.point, actuator.axes)
                body.setdefault(key, np.zeros(6))[actuator.component] += value
        wrenches: dict[int, list] = {}
        for (j, point, axes), wrench in body.items():
            entry = (np.asarray(point, float), wrench.reshape(1, 6, 1))
            wrenches.setdefault(j, []).append(entry if axes == "world" else entry + (axes,))
        return SpatialInputs(joint, wrenches, checked=True)


def _state(model: SpatialModel, q, v, t) -> tuple[np.ndarray, np.ndarray, float]:
    given = {"q": q, "v": v}
    q, v = validation.finite_array("q", q, ndim=1), validation.finite_array("v", v, ndim=1)
    for label, array, names in (("q", q, model.coordinates), ("v", v, model.velocities)):
        if array.shape != (len(names),):
            raise ModelError(f"{label} must have {len(names)} entries {names}, got {given[label]!r}")
    try:
        q, v = model.check_state(q, v)
    except ModelError as exc:
        raise ModelError(f"q = {given['q']!r}: {exc}") from None
    if q.shape[0] != 1:
        raise ModelError(f"q and v must be one state ({model.n_positions},), ({model.n_velocities},), got a batch "
                         f"of {q.shape[0]}")
    return q[0], v[0], validation.finite("t", t)


def sensor_values(model: SpatialModel, names: Sequence[str], q, v, t: float = 0.0) -> np.ndarray:
    """Values of the sensors ``names`` at the state ``(q, v)`` and time ``t``.

    Parameters
    ----------
    model : SpatialModel
    names : sequence of str
        Sensor names (``SpatialPorts(model).sensors``).
    q : array_like, shape (n_positions,)
        Coordinates (quaternions need not be unit).
    v : array_like, shape (n_velocities,)
        Velocities.
    t : float
        Time [s] (driven joints).

    Returns
    -------
    ndarray, shape (len(names),)
        In the sensors' units (:meth:`SpatialPorts.sensor_unit`).
    """
    ports = SpatialPorts(model)
    sensors = ports.resolve(names)
    q, v, t = _state(model, q, v, t)
    return ports.values(sensors, q, v, t)


def sensor_jacobians(model: SpatialModel, names: Sequence[str], q, v, t: float = 0.0, *, step: float = 1e-3
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians of the sensors ``names`` in tangent coordinates at ``(q, v, t)``, exact to round-off.

    ``dy_dx[:, k]`` is the derivative of ``y`` when ``q`` moves along ``G(q) e_k`` (the motion of unit
    velocity ``k``: for quaternion joints the rotation about a child axis) at fixed ``v``; ``dy_dv`` the
    derivative in ``v``.  Both by complex step (step ``1e-30``) through the complex-step-safe sensor maps
    (:mod:`ctmm.spatial.sensor_maps`): ``2 n_velocities`` states in one batched evaluation.

    Parameters
    ----------
    model, names, q, v, t
        As in :func:`sensor_values`.
    step : float
        Checked (``> 0``) and otherwise unused: kept from the finite-difference version (the complex step
        has no step to choose).

    Returns
    -------
    dy_dx, dy_dv : ndarray, shape (len(names), n_velocities)

    Raises
    ------
    ModelError
        Bad arguments; an x-y-z angle sensor at gimbal lock or a rotation vector of length ``pi`` (no
        derivative there).
    """
    ports = SpatialPorts(model)
    sensors = ports.resolve(names)
    validation.positive("step", step)
    q, v, t = _state(model, q, v, t)
    nv = model.n_velocities
    if nv == 0 or not sensors:
        return np.zeros((len(sensors), nv)), np.zeros((len(sensors), nv))
    h = 1e-30
    unit = np.eye(nv)
    directions = model.position_rates(np.repeat(q[None], nv, axis=0), unit)      # G(q) e_k
    q_batch = np.concatenate([q[None] + 1j * h * directions, np.repeat(q[None], nv, axis=0)])
    v_batch = np.concatenate([np.repeat(v[None], nv, axis=0), v[None] + 1j * h * unit])
    values = maps.sensor_values(model, ports.scene, sensors, q_batch, v_batch, t,
                                differentiable="sensor_jacobians").imag / h
    return values[:nv].T.copy(), values[nv:].T.copy()
