"""Named sensors and actuators of a planar model: the signals loops and controllers connect to.

A :class:`~ctmm.planar.model.PlanarModel` (rigid or with modal beams) exposes

Sensors (measured signals, all in global axes)
    * ``"<body>.theta"``, ``"<body>.omega"`` -- absolute angle [rad] and rate [rad/s] of a body;
    * ``"<body>.<point>.x|y|vx|vy"`` -- position [m] and velocity [m/s] of a point of a body:
      ``inboard``, ``com`` (centre of mass, deformed for beams) or one of the body's outboard
      ends (``out`` for a link, the deformed end of a beam);
    * ``"<hinge>.angle"``, ``"<hinge>.rate"`` -- relative angle [rad] and rate [rad/s] of a
      hinge (child minus the parent end, elastic slope of a flexible parent included);
    * every generalised coordinate (``"arm.q1"``, ``"base.x"``) and its rate
      ``"<coordinate>_dot"``;
    * at every named station of a modal beam (:mod:`ctmm.flexible.stations`), in the beam's
      floating frame: ``"<beam>.<station>.w"`` (transverse deflection [m]), ``".slope"``
      (elastic slope [rad]), ``".w_dot"`` [m/s], ``".slope_rate"`` [rad/s].

Actuators (inputs, added to what the model's own laws apply)
    * ``"<hinge>.torque"`` -- torque [N m] exerted by the parent on the child across a
      revolute hinge (every hinge that is not driven or welded; the reaction acts on the
      parent);
    * ``"<body>.force_x"``, ``"<body>.force_y"`` [N], ``"<body>.moment"`` [N m] -- force at
      the centre of mass in global axes and moment, on a rigid body;
    * ``"<beam>.<coordinate suffix>.force"`` -- generalised force on one modal equation of a
      beam [N per unit modal coordinate]; a piezo moment pair ``M`` between ``x1`` and ``x2``
      is the weighted set ``M (phi_i'(x2) - phi_i'(x1))`` over the transverse modes (see
      :meth:`ctmm.flexible.ModalBeam.mode_slopes`);
    * ``"<beam>.<station>.force"`` -- transverse force [N] (beam frame, turning with the beam)
      and ``"<beam>.<station>.moment"`` [N m] at a named station: physical loads, on the modal
      equations ``phi_k(x) F``, ``phi_k'(x) M`` and on the floating frame ``F`` and ``x F + M``
      (a station force needs an axially rigid first-order beam, ``n_axial_modes = 0`` and no
      ``second_order_inertia``).

A kinematic loop model (:class:`~ctmm.planar.closed_loops.KinematicLoopModel`) has its tree's ports plus its cut
joints' (``"<cut>.angle"``, ``"<cut>.rate"``, ``"<cut>.moment"``; ``"<cut>.torque"``): :mod:`ctmm.planar.loop_ports`.

Sensors are kinematic: a position-like sensor (angle, position, coordinate) depends on ``q``
only and its rate counterpart is linear in ``qdot``, ``y_rate = J(q) qdot (+ dy/dt of driven
motions)``.  :func:`sensor_jacobians` uses this: ``dy/dq`` of a position-like sensor and
``dy/dqdot`` of a rate sensor are the rate map evaluated on unit rates (exact, no step size);
only ``dy/dq`` of a rate sensor (zero at rest) is a fourth-order central difference.

Accelerations are not sensors here (they would close an algebraic loop through the sweep).
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from .. import validation
from ..errors import ModelError, UnknownNameError
from ..named_ports import NamedPorts
from .model import BUSHING, DRIVEN, REVOLUTE, PlanarModel

__all__ = [
    "ActuatorInputs",
    "PlanarPorts",
    "actuator_inputs",
    "actuator_names",
    "actuator_unit",
    "sensor_jacobians",
    "sensor_names",
    "sensor_unit",
    "sensor_values",
]

_POINT_PARTS = {"x": (0, 0, "m"), "y": (0, 1, "m"), "vx": (1, 0, "m/s"), "vy": (1, 1, "m/s")}
_RATE_OF = {"x": "vx", "y": "vy", "theta": "omega", "angle": "rate", "w": "w_dot", "slope": "slope_rate"}
_STATION_PARTS = {"w": ("m", 0, False), "slope": ("rad", 1, False), "w_dot": ("m/s", 0, True),
                  "slope_rate": ("rad/s", 1, True)}      # unit, shape derivative, rate


@dataclass(frozen=True)
class _Sensor:
    """One resolved sensor: what it reads and whether it is a rate (linear in ``qdot``)."""

    name: str
    kind: str            # "coordinate", "body_angle", "hinge", "point", "station"
    index: int           # coordinate index, body index or joint index
    part: str            # "theta"/"omega", "angle"/"rate", "x"/"y"/"vx"/"vy", "" / "dot"
    point: str = ""      # point name for kind == "point", station name for kind == "station"
    unit: str = ""

    @property
    def is_rate(self) -> bool:
        return self.part in ("omega", "rate", "vx", "vy", "dot", "w_dot", "slope_rate")


@dataclass(frozen=True)
class _Actuator:
    name: str
    kind: str            # "hinge", "body", "modal", "station"
    index: int           # joint index, body index
    component: int       # 0, 1, 2 (fx, fy, moment) for bodies; modal row for beams; 1, 2 (force,
                         # moment) for stations
    unit: str
    station: str = ""


def _unknown(what: str, name: object, model: PlanarModel, known: Mapping) -> UnknownNameError:
    return UnknownNameError(f"unknown {what} {name!r} of model {model.name!r}; available: "
                            f"{', '.join(sorted(known)) or '(none)'}")


def _body_points(model: PlanarModel, i: int) -> tuple[str, ...]:
    return ("inboard", "com") + tuple(model.ends[i])


def _body_entries(model: PlanarModel, i: int, sensors: dict, actuators: dict) -> None:
    """Add the sensors and actuators of body ``i`` (every name starts with the body's name and a dot)."""
    body = model.body_names[i]
    sensors[f"{body}.theta"] = _Sensor(f"{body}.theta", "body_angle", i, "theta", unit="rad")
    sensors[f"{body}.omega"] = _Sensor(f"{body}.omega", "body_angle", i, "omega", unit="rad/s")
    for point in _body_points(model, i):
        for part, (_, _, unit) in _POINT_PARTS.items():
            label = f"{body}.{point}.{part}"
            sensors[label] = _Sensor(label, "point", i, part, point, unit)
    if i not in model.beams:
        for k, part in enumerate(("force_x", "force_y", "moment")):
            label = f"{body}.{part}"
            actuators[label] = _Actuator(label, "body", i, k, "N m" if k == 2 else "N")
        return
    for k, suffix in enumerate(model.beams[i].coordinate_suffixes):
        label = f"{body}.{suffix}.force"
        actuators[label] = _Actuator(label, "modal", i, k, "N")
    for station in getattr(model.beams[i], "stations", None) or {}:
        for part, (unit, _, _) in _STATION_PARTS.items():
            label = f"{body}.{station}.{part}"
            sensors[label] = _Sensor(label, "station", i, part, station, unit)
        for k, part in ((1, "force"), (2, "moment")):
            if k == 1 and (model.beams[i].n_axial_modes or getattr(model.beams[i], "second_order_inertia", 0)):
                continue        # the moment arm x + psi(x) . p (+ u(x)) would depend on the state
            label = f"{body}.{station}.{part}"
            actuators[label] = _Actuator(label, "station", i, k, "N" if k == 1 else "N m", station)


def _joint_entries(model: PlanarModel, j: int, sensors: dict, actuators: dict) -> None:
    """Add the sensors and actuators of hinge ``j`` (names ``"<hinge>.angle|rate|torque"``)."""
    hinge, kind = model.joint_names[j], model.joint_kind[j]
    if kind in (REVOLUTE, BUSHING, DRIVEN):
        sensors[f"{hinge}.angle"] = _Sensor(f"{hinge}.angle", "hinge", j, "angle", unit="rad")
        sensors[f"{hinge}.rate"] = _Sensor(f"{hinge}.rate", "hinge", j, "rate", unit="rad/s")
    if kind in (REVOLUTE, BUSHING):
        actuators[f"{hinge}.torque"] = _Actuator(f"{hinge}.torque", "hinge", j, 0, "N m")


def _coordinate_entries(model: PlanarModel, k: int, sensors: dict) -> None:
    """Add the sensors of coordinate ``k``: itself (unless an earlier entry has its name) and ``"<coordinate>_dot"``."""
    coordinate = model.coordinates[k]
    unit = "m" if coordinate.rsplit(".", 1)[-1] in ("x", "y", "dx", "dy") else (
        "rad" if coordinate.endswith(".theta") else "1")
    owner, _, suffix = coordinate.rpartition(".")
    body = model.beams.get(model.body_index(owner))     # internal coordinates: the body's own units (modal: m)
    if body is not None and suffix in body.coordinate_suffixes:
        unit = body.coordinate_units[body.coordinate_suffixes.index(suffix)]
    rate_unit = f"{unit}/s"
    sensors.setdefault(coordinate, _Sensor(coordinate, "coordinate", k, "", unit=unit))
    sensors[f"{coordinate}_dot"] = _Sensor(f"{coordinate}_dot", "coordinate", k, "dot", unit=rate_unit)


def _build(model: PlanarModel, bodies: Iterable[int] | None = None, joints: Iterable[int] | None = None,
           coordinates: Iterable[int] | None = None) -> tuple[dict, dict]:
    """The sensor and actuator tables of the given bodies, hinges and coordinates (default all), in this order:
    bodies, hinges, coordinates, each ascending (a later entry of one name replaces an earlier one, except a
    coordinate's own sensor)."""
    sensors: dict[str, _Sensor] = {}
    actuators: dict[str, _Actuator] = {}
    for i in range(model.n_bodies) if bodies is None else bodies:
        _body_entries(model, i, sensors, actuators)
    for j in range(len(model.joint_names)) if joints is None else joints:
        _joint_entries(model, j, sensors, actuators)
    for k in range(len(model.coordinates)) if coordinates is None else coordinates:
        _coordinate_entries(model, k, sensors)
    return sensors, actuators


class _Owners:
    """Which bodies, hinges and coordinates of a model can own a port name, and their entries resolved on demand
    (one per :class:`PlanarPorts`; the model is immutable)."""

    def __init__(self, model: PlanarModel) -> None:
        self.model = model
        self.body = {name: i for i, name in enumerate(model.body_names)}
        self.joint = {name: j for j, name in enumerate(model.joint_names)}
        self.coordinate = {name: k for k, name in enumerate(model.coordinates)}
        self.resolved: dict[str, tuple] = {}          # name -> (sensor or None, actuator or None)
        self.whole: tuple[dict, dict] | None = None

    def entries(self, name: str) -> tuple:
        """``(sensor, actuator)`` named ``name`` (``None`` where there is none), as the whole tables have them."""
        if name in self.resolved:
            return self.resolved[name]
        if self.whole is not None:
            found = (self.whole[0].get(name), self.whole[1].get(name))
        else:
            # every entry of a body or hinge starts with its name and a dot; a coordinate owns itself and "_dot"
            prefixes = [name[:p] for p, letter in enumerate(name) if letter == "."]
            bodies = sorted(self.body[p] for p in prefixes if p in self.body)
            joints = sorted(self.joint[p] for p in prefixes if p in self.joint)
            coordinates = sorted(self.coordinate[c] for c in (name, name[:-4] if name.endswith("_dot") else None)
                                 if c in self.coordinate)
            sensors, actuators = _build(self.model, bodies, joints, coordinates)
            found = (sensors.get(name), actuators.get(name))
        self.resolved[name] = found
        return found

    def tables(self) -> tuple[dict, dict]:
        """The whole sensor and actuator tables (built at the first call)."""
        if self.whole is None:
            self.whole = _build(self.model)
        return self.whole


class _PortTable(Mapping):
    """Read-only mapping of port name to resolved sensor or actuator of one model, resolved name by name on
    demand: a look-up builds only the entries of the bodies, hinges and coordinates that can own that name;
    iterating (or ``len``) builds the whole table once.  Equal, entry for entry and in order, to the whole table.

    Parameters
    ----------
    owners : _Owners
        The model's owners (shared by its sensor and actuator tables).
    actuators : bool
        The actuator table (else the sensor table).
    """

    def __init__(self, owners: _Owners, actuators: bool) -> None:
        self._owners, self._column = owners, int(actuators)

    def __getitem__(self, name: object) -> object:
        entry = self._owners.entries(name)[self._column] if isinstance(name, str) else None
        if entry is None:
            raise KeyError(name)
        return entry

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and self._owners.entries(name)[self._column] is not None

    def __iter__(self) -> Iterator[str]:
        return iter(self._owners.tables()[self._column])

    def __len__(self) -> int:
        return len(self._owners.tables()[self._column])

    def __repr__(self) -> str:
        return f"_PortTable({dict(self)!r})"


class PlanarPorts(NamedPorts):
    """The sensors and actuators of one model, each name resolved once, when first asked (hold one in a time loop).

    ``sensors`` and ``actuators`` are read-only mappings of name to resolved entry: a look-up builds only the
    entries of the body, hinge or coordinate whose name the port name starts with (a model of N bodies has about
    20 N names, most never asked); iterating them (``sensor_names``, an error listing the names) builds the
    whole table once.

    Parameters
    ----------
    model : PlanarModel
    """

    def __init__(self, model: PlanarModel) -> None:
        if not isinstance(model, PlanarModel):
            raise ModelError(f"model must be a ctmm.planar.PlanarModel, got {model!r}")
        self.model = model
        owners = _Owners(model)             # entries resolved by name on demand (O(N) names, most never asked)
        self.sensors: Mapping[str, _Sensor] = _PortTable(owners, actuators=False)
        self.actuators: Mapping[str, _Actuator] = _PortTable(owners, actuators=True)
        # mode-shape rows of beam stations, computed on first use (the model is immutable); they were
        # recomputed on every evaluation, most of a station-loop step
        self._station_rows: dict = {}
        self._resolved_actuators: dict[str, _Actuator] = {}     # actuator name -> its checked entry (inputs)

    def check_sensor(self, name: str, what: str = "sensor") -> str:
        """``name`` if it is a sensor, else an error listing the sensors."""
        if not isinstance(name, str) or name not in self.sensors:
            if isinstance(name, str) and name.endswith((".a", ".alpha", ".ax", ".ay")):
                raise ModelError(f"{what} {name!r}: accelerations are not sensors of planar models "
                                 "(they would close an algebraic loop through the sweep); measure "
                                 "positions, angles or rates")
            raise _unknown(what, name, self.model, self.sensors)
        return name

    def check_actuator(self, name: str, what: str = "actuator") -> str:
        """``name`` if it is an actuator, else an error listing the actuators."""
        if not isinstance(name, str) or name not in self.actuators:
            if isinstance(name, str) and name.endswith(".torque") and \
                    name[:-len(".torque")] in self.model.joint_names:
                raise ModelError(f"{what} {name!r}: hinge {name[:-7]!r} is driven or welded (its "
                                 "motion is prescribed); only free revolute hinges take a torque input")
            station = self.actuators.get(name[:-len(".force")] + ".moment") if isinstance(name, str) \
                and name.endswith(".force") else None
            if station is not None and station.kind == "station":
                raise ModelError(f"{what} {name!r}: a station force needs an axially rigid first-order beam "
                                 "(n_axial_modes = 0, second_order_inertia = False: its moment arm would move with "
                                 "the axial modes or the shortening); station moments and Load are available")
            raise _unknown(what, name, self.model, self.actuators)
        return name

    def values(self, sensors: list, q: np.ndarray, qdot: np.ndarray, t: float) -> np.ndarray:
        """Values of resolved ``sensors`` (no validation of the state: for inner loops)."""
        return _evaluate(self.model, sensors, q, qdot, t, self._station_rows)

    def inputs(self, values: Mapping[str, float]) -> ActuatorInputs:
        """Arrange actuator ``values`` (``{actuator name: value}``, SI units) for the sweeps;
        several entries on one actuator add up."""
        if not isinstance(values, Mapping):
            raise ModelError(f"values must be a mapping of actuator name to value, got {values!r}")
        model = self.model
        nb = model.n_bodies
        torque = np.zeros(nb)
        force = np.zeros((nb, 3))
        modal: dict[int, np.ndarray] = {}
        frame: dict[int, np.ndarray] = {}
        resolved = self._resolved_actuators
        for name, value in values.items():
            actuator = resolved.get(name)
            if actuator is None:        # checked and resolved once per name (every stage of a time loop asks)
                actuator = resolved[name] = self.actuators[self.check_actuator(name)]
            if not (type(value) is float and math.isfinite(value)):
                value = validation.finite(f"actuator {name!r}", value)
            if actuator.kind == "hinge":
                torque[actuator.index] += value
            elif actuator.kind == "body":
                force[actuator.index, actuator.component] += value
            else:
                row = modal.setdefault(actuator.index, np.zeros(len(model.modal_index[actuator.index])))
                if actuator.kind == "modal":
                    row[actuator.component] += value
                else:
                    _station_load(model.beams[actuator.index], actuator, value, row,
                                  frame.setdefault(actuator.index, np.zeros(3)), self._station_rows)
        return ActuatorInputs(torque, force, modal, frame)


def _station_load(beam, actuator: _Actuator, value: float, modal_row: np.ndarray, frame_row: np.ndarray,
                  shape_rows: dict | None = None) -> None:
    """Add the loads of ``value`` on station actuator ``actuator`` (in place): modal
    ``phi_k(x) F`` or ``phi_k'(x) M`` and frame ``(0, F, x F)`` or ``(0, 0, M)``; ``shape_rows``
    keeps the mode-shape rows of the stations between calls (keyed by beam body, station and
    derivative, as the sensors' rows)."""
    x = beam.stations[actuator.station]
    nq = beam.n_modes
    derivative = 0 if actuator.component == 1 else 1
    key = (actuator.index, actuator.station, derivative)
    rows = {} if shape_rows is None else shape_rows
    if key not in rows:
        rows[key] = beam.shapes([x], derivative)[:, 0]
    modal_row[:nq] += value * rows[key][:nq]
    if actuator.component == 1:
        frame_row[1] += value
        frame_row[2] += x * value
    else:
        frame_row[2] += value


def sensor_names(model: PlanarModel) -> tuple[str, ...]:
    """Every sensor signal of ``model`` (see the module docstring for the naming)."""
    return tuple(PlanarPorts(model).sensors)


def actuator_names(model: PlanarModel) -> tuple[str, ...]:
    """Every actuator input of ``model`` (see the module docstring for the naming)."""
    return tuple(PlanarPorts(model).actuators)


def sensor_unit(model: PlanarModel, name: str) -> str:
    """SI unit of sensor ``name`` of ``model``."""
    return PlanarPorts(model).sensor_unit(name)


def actuator_unit(model: PlanarModel, name: str) -> str:
    """SI unit of actuator ``name`` of ``model``."""
    return PlanarPorts(model).actuator_unit(name)


# ------------------------------------------------------------------------------------------
# sensor evaluation
# ------------------------------------------------------------------------------------------
def _point_kinematics(model: PlanarModel, q, qdot, t: float) -> dict:
    """Positions and velocities of every named point: ``{(body, point): (r, v)}``."""
    pts = model.points(q, qdot, t)
    theta = pts["theta"]
    omega = pts["omega"]
    out = {}
    for i, body in enumerate(model.body_names):
        r_in, v_in = pts["inboard"][i], pts["inboard_velocity"][i]
        out[(i, "inboard")] = (r_in, v_in)
        out[(i, "com")] = (pts["com"][i], pts["com_velocity"][i])
        c, s = np.cos(theta[i]), np.sin(theta[i])
        rotation = np.array([[c, -s], [s, c]])
        for k, end in enumerate(model.ends[i]):
            if i in model.beams:
                local, local_rate = model.beam_point_local(i, k, q, qdot, shortening=True)
            else:
                local, local_rate = np.asarray(model.ends[i][end], float), np.zeros(2)
            r = rotation @ local
            out[(i, end)] = (r_in + r, v_in + omega[i] * np.array([-r[1], r[0]])
                             + rotation @ local_rate)
    return out, theta, omega


def _evaluate(model: PlanarModel, sensors: Sequence[_Sensor], q, qdot, t: float,
              station_rows: dict | None = None) -> np.ndarray:
    need_points = any(s.kind == "point" for s in sensors)
    need_angles = any(s.kind in ("body_angle", "hinge") for s in sensors)
    points = theta = omega = None
    if need_points:
        points, theta, omega = _point_kinematics(model, q, qdot, t)
    elif need_angles:
        theta, omega = model.body_angles(q, qdot, t)
    relative = None
    values = np.empty(len(sensors))
    station_rows = {} if station_rows is None else station_rows     # (beam, station, derivative) -> shape row
    for n, sensor in enumerate(sensors):
        if sensor.kind == "coordinate":
            values[n] = (qdot if sensor.part == "dot" else q)[sensor.index]
        elif sensor.kind == "body_angle":
            values[n] = (omega if sensor.part == "omega" else theta)[sensor.index]
        elif sensor.kind == "hinge":
            if relative is None:
                relative = model.relative_angles(theta, omega, q, qdot)
            values[n] = relative[1 if sensor.part == "rate" else 0][sensor.index]
        elif sensor.kind == "station":
            _, derivative, rate = _STATION_PARTS[sensor.part]
            key = (sensor.index, sensor.point, derivative)
            if key not in station_rows:
                beam = model.beams[sensor.index]
                station_rows[key] = beam.shapes([beam.stations[sensor.point]], derivative)[:, 0]
            row = station_rows[key]
            index = model.modal_index[sensor.index][:row.size]
            values[n] = row @ (qdot if rate else q)[index]
        else:
            derivative, axis, _ = _POINT_PARTS[sensor.part]
            values[n] = points[(sensor.index, sensor.point)][derivative][axis]
    return values


def sensor_values(model: PlanarModel, names: Sequence[str], q, qdot, t: float = 0.0) -> np.ndarray:
    """Values of the sensors ``names`` at the state ``(q, qdot)`` and time ``t``.

    Parameters
    ----------
    model : PlanarModel
    names : sequence of str
        Sensor names (:func:`sensor_names`).
    q, qdot : array_like, shape (n_coordinates,)
        Coordinates [rad, m] and rates.
    t : float
        Time [s] (driven hinges).

    Returns
    -------
    ndarray, shape (len(names),)
        In the sensors' units (:func:`sensor_unit`).
    """
    sensors = PlanarPorts(model).resolve(names)          # checks the model type first
    q, qdot = model.state(q, qdot)
    return _evaluate(model, sensors, q, qdot, validation.finite("t", t))


def _rate_twin(sensor: _Sensor) -> _Sensor:
    """The rate sensor whose map ``J(q) qdot`` is the position sensor's Jacobian."""
    if sensor.is_rate:
        return sensor
    part = "dot" if sensor.kind == "coordinate" else _RATE_OF[sensor.part]
    return _Sensor(sensor.name + "'", sensor.kind, sensor.index, part, sensor.point, sensor.unit)


def sensor_jacobians(model: PlanarModel, names: Sequence[str], q, qdot, t: float = 0.0,
                     *, step: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians ``dy/dq`` and ``dy/dqdot`` of the sensors ``names`` at ``(q, qdot, t)``.

    Exact (rate maps on unit rates) except ``dy/dq`` of rate sensors, a fourth-order central
    difference with relative step ``step`` (zero at rest, where linearisations are usually taken).

    Returns
    -------
    dy_dq, dy_dqdot : ndarray, shape (len(names), n_coordinates)
    """
    sensors = PlanarPorts(model).resolve(names)          # checks the model type first
    step = validation.positive("step", step)
    q, qdot = model.state(q, qdot)
    t = validation.finite("t", t)
    n = model.n_coordinates
    twins = [_rate_twin(s) for s in sensors]
    # the rate maps are affine in qdot: J e_k = y(q, e_k) - y(q, 0)
    base = _evaluate(model, twins, q, np.zeros(n), t)
    jacobian = np.empty((len(sensors), n))
    for k in range(n):
        unit = np.zeros(n)
        unit[k] = 1.0
        jacobian[:, k] = _evaluate(model, twins, q, unit, t) - base
    dy_dq = np.zeros((len(sensors), n))
    dy_dqdot = np.zeros((len(sensors), n))
    rates = np.array([s.is_rate for s in sensors], dtype=bool)
    dy_dq[~rates] = jacobian[~rates]
    dy_dqdot[rates] = jacobian[rates]
    if rates.any() and np.any(qdot != 0.0):
        rate_sensors = [s for s in sensors if s.is_rate]
        for k in range(n):
            h = step * max(1.0, abs(q[k]))
            shifted = []
            for offset in (-2.0, -1.0, 1.0, 2.0):
                qk = q.copy()
                qk[k] += offset * h
                shifted.append(_evaluate(model, rate_sensors, qk, qdot, t))
            dy_dq[rates, k] = (shifted[0] - 8.0 * shifted[1] + 8.0 * shifted[2] - shifted[3]) / (12.0 * h)
    return dy_dq, dy_dqdot


# ------------------------------------------------------------------------------------------
# actuator inputs
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ActuatorInputs:
    """Actuator values of one instant, arranged for the sweeps.

    Attributes
    ----------
    hinge_torque : ndarray, shape (n_bodies,)
        Extra torque across each body's inboard hinge [N m] (parent on child).
    body_force : ndarray, shape (n_bodies, 3)
        Extra force at the centre of mass (global ``fx, fy`` [N]) and moment [N m] on each body.
    modal_force : dict of int to ndarray
        Extra generalised forces on the modal equations of beams, by body index.
    frame_wrench : dict of int to ndarray
        Extra wrench on the floating frame of beams, by body index: ``(f_x, f_y, moment about
        the root)`` [N, N, N m] in the beam's frame (it turns with the beam): the frame part of
        the station loads.
    """

    hinge_torque: np.ndarray
    body_force: np.ndarray
    modal_force: Mapping[int, np.ndarray] = field(default_factory=dict)
    frame_wrench: Mapping[int, np.ndarray] = field(default_factory=dict)

    def has_wrench(self) -> bool:
        """Whether these inputs load the bodies (body forces, beam frame wrenches), not the hinges and modes only:
        without, :meth:`inboard_wrench` is zero and the sweeps skip it."""
        force = self.body_force
        return bool(self.frame_wrench) or force.dtype.kind not in "fc" or bool(force.any())

    def inboard_wrench(self, model: PlanarModel, theta: np.ndarray) -> np.ndarray:
        """``(fx, fy, moment about the inboard point)`` of the body forces, shape (n_bodies, 3),
        with the bodies at absolute angles ``theta`` [rad]; inputs with a leading batch axis on every array (a
        batch of inputs at one state, :func:`ctmm.planar.sweep.solve_instant_batch`): (n_batch, n_bodies, 3)."""
        c, s = np.cos(theta), np.sin(theta)
        rcx = c * model.com[:, 0] - s * model.com[:, 1]
        rcy = s * model.com[:, 0] + c * model.com[:, 1]
        f = self.body_force
        wrench = np.array(f, dtype=np.result_type(f, theta))
        wrench[..., 2] = rcx * f[..., 1] - rcy * f[..., 0] + f[..., 2]
        if self.frame_wrench:
            for j, frame in self.frame_wrench.items():
                frame = np.asarray(frame)
                f1, f2, moment = frame if frame.ndim == 1 else np.moveaxis(frame, -1, 0)   # one state: its entries
                wrench[..., j, 0] += c[j] * f1 - s[j] * f2
                wrench[..., j, 1] += s[j] * f1 + c[j] * f2
                wrench[..., j, 2] += moment
        return wrench


def actuator_inputs(model: PlanarModel, values: Mapping[str, float]) -> ActuatorInputs:
    """Arrange actuator ``values`` (``{actuator name: value}``, SI units) of ``model`` for the
    sweeps (:meth:`PlanarPorts.inputs`)."""
    return PlanarPorts(model).inputs(values)
