"""A planar model's sensors on casadi symbols (issue 13): the ports of :mod:`ctmm.planar.ports` as expressions of
the state ``(q, qdot)`` (and the time, when a driven hinge moves), for loops closed inside generated kernels.

:class:`SymbolicKinematics` gives the body angles, rates and point motions of a
:class:`~ctmm.planar.model.PlanarModel` on symbols ``q, v`` (modal beams' deformed ends, centroids and stations
included; driven motions on a time symbol, :func:`ctmm.compiled_parameters.symbolic_drives`);
:func:`sensor_expression` reads one named sensor -- coordinates and their rates, body angles and rates, hinge angles and rates, positions and velocities of named points,
beam station deflections, slopes and their rates -- from it; :class:`PlanarSymbols` is the planar plant on symbols
that :class:`ctmm.compiled_loops.ClosedLoops` closes its loops on.  No port reads an acceleration, so no loop
built on them is algebraic.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

from .compiled_parameters import moving_drives, symbolic_drives
from .errors import ModelError
from .planar.model import BUSHING, FREE, PlanarModel
from .planar.ports import PlanarPorts
from .symbolic_beam_points import DeformedPoints

__all__ = ["PlanarSymbols", "SymbolicKinematics", "sensor_expression"]

_POINT_AXES = {"x": (0, 0), "y": (0, 1), "vx": (1, 0), "vy": (1, 1)}
_STATION_PARTS = {"w": (0, False), "slope": (1, False), "w_dot": (0, True), "slope_rate": (1, True)}


def _dot(row: Any, column: Any, index: Sequence[int]) -> Any:
    """``sum_k row[k] column[index[k]]`` on symbols (zero weights left out)."""
    return sum((float(w) * column[int(k)] for w, k in zip(row, index) if w != 0.0), 0.0)


class SymbolicKinematics:
    """Angles, rates and point motions of a planar model on casadi symbols ``q, v`` (the numbers of
    :meth:`~ctmm.planar.model.PlanarModel.points`; driven motions at the time symbol ``t``, their numbers
    constants of the code, :func:`~ctmm.compiled_parameters.symbolic_drives`).

    Parameters
    ----------
    model : PlanarModel
    q, v : casadi SX
        Coordinate and rate symbols (``n_coordinates`` each).
    t : casadi SX, optional
        Time symbol [s]; needed when a driven hinge moves (:func:`~ctmm.compiled_parameters.moving_drives`).
    driven : mapping int -> (angle, rate, acceleration), optional
        The driven hinges' motion by body (expressions, e.g. :attr:`SceneNumbers.driven
        <ctmm.planar.family_terms.SceneNumbers>` of the generated sweep, numbers as inputs); default
        :func:`~ctmm.compiled_parameters.symbolic_drives` at ``t``.
    """

    def __init__(self, model: PlanarModel, q: Any, v: Any, t: Any = None, driven: Mapping[int, tuple] | None = None
                 ) -> None:
        import casadi as ca

        self.model, self.q, self.v = model, q, v
        self.deformed = DeformedPoints(model, q, v)
        if driven is None and t is None and moving_drives(model):
            raise ModelError(f"the sensors of model {model.name!r} move with its driven hinges "
                             f"{[model.joint_names[j] for j, _ in moving_drives(model)]}: they need the time symbol")
        driven = {i: motion[:2] for i, motion in (symbolic_drives(model, t) if driven is None else driven).items()}
        nb = model.n_bodies
        self.theta: list = [None] * nb
        self.omega: list = [None] * nb
        self.end_angle: list = [None] * nb         # angle and rate of the parent end body i hangs on
        for i in range(nb):
            p = int(model.parent[i])
            if p >= 0:
                th, om = self.theta[p], self.omega[p]
                if p in model.beams:
                    slope = model.end_slope(i)
                    index = model.modal_index[p][:len(slope)]
                    th, om = th + _dot(slope, q, index), om + _dot(slope, v, index)
            else:
                th, om = float(model.ground_angle[i]), 0.0
            self.end_angle[i] = (th, om)
            if model.theta_index[i] >= 0:
                k = int(model.theta_index[i])
                self.theta[i], self.omega[i] = q[k], v[k]
            else:
                angle, rate = driven[i]
                self.theta[i], self.omega[i] = th + angle, om + rate
        self.cos = [ca.cos(th) for th in self.theta]
        self.sin = [ca.sin(th) for th in self.theta]
        self._inboard: dict[int, tuple] = {}

    def rotate(self, i: int, x: Any, y: Any) -> tuple:
        return self.cos[i] * x - self.sin[i] * y, self.sin[i] * x + self.cos[i] * y

    def beam_local(self, j: int, end: int) -> tuple:
        """Deformed end ``end`` of beam ``j`` in its frame: position and velocity (2-tuples; the numpy definition,
        foreshortening and ``ctmm.fem`` nodes included, :mod:`ctmm.symbolic_beam_points`)."""
        return self.deformed.end(j, end)

    def inboard(self, i: int) -> tuple:
        """Position and velocity of body ``i``'s inboard end (2-tuples), global axes."""
        if i in self._inboard:
            return self._inboard[i]
        m, q, v = self.model, self.q, self.v
        p = int(m.parent[i])
        if p >= 0:
            (rp, vp), omega = self.inboard(p), self.omega[p]
            if p in m.beams:
                e, ed = self.beam_local(p, int(m.parent_end_index[i]))
            else:
                e, ed = tuple(float(x) for x in m.end_vector[i]), (0.0, 0.0)
            rx, ry = self.rotate(p, *e)
            dx, dy = self.rotate(p, *ed)
            out = ((rp[0] + rx, rp[1] + ry), (vp[0] - omega * ry + dx, vp[1] + omega * rx + dy))
        elif m.joint_kind[i] == FREE:
            ix, iy = (int(k) for k in m.xy_index[i])
            out = ((q[ix], q[iy]), (v[ix], v[iy]))
        else:
            out = (tuple(float(x) for x in m.ground_position[i]), (0.0, 0.0))
        if m.joint_kind[i] == BUSHING:      # plus the translational spring's offset (as PlanarModel.points)
            out = tuple((a + x[int(m.xy_index[i][0])], b + x[int(m.xy_index[i][1])]) for (a, b), x in zip(out, (q, v)))
        self._inboard[i] = out
        return out

    def point(self, i: int, name: str) -> tuple:
        """Position and velocity of point ``name`` (``"inboard"``, ``"com"`` or an end) of body ``i``."""
        m = self.model
        (r, v), omega = self.inboard(i), self.omega[i]
        if name == "inboard":
            return r, v
        if name == "com" and i in m.beams:         # the deformed centroid
            local, rate = self.deformed.centroid(i)
        elif name == "com":
            local, rate = tuple(float(x) for x in m.com[i]), (0.0, 0.0)
        elif i in m.beams:
            local, rate = self.beam_local(i, list(m.ends[i]).index(name))
        else:
            local, rate = tuple(float(x) for x in m.ends[i][name]), (0.0, 0.0)
        x, y = self.rotate(i, *local)
        dx, dy = self.rotate(i, *rate)
        return (r[0] + x, r[1] + y), (v[0] - omega * y + dx, v[1] + omega * x + dy)


def sensor_expression(ports: PlanarPorts, name: str, kinematics: SymbolicKinematics) -> Any:
    """The value of sensor ``name`` of :mod:`ctmm.planar.ports` as a casadi expression of the
    symbols of ``kinematics``."""
    sensor = ports.resolve([name])[0]
    m, q, v = kinematics.model, kinematics.q, kinematics.v
    if sensor.kind == "coordinate":
        return (v if sensor.part == "dot" else q)[sensor.index]
    if sensor.kind == "body_angle":
        return (kinematics.omega if sensor.part == "omega" else kinematics.theta)[sensor.index]
    if sensor.kind == "hinge":
        th, om = kinematics.end_angle[sensor.index]
        if sensor.part == "rate":
            return kinematics.omega[sensor.index] - om
        return kinematics.theta[sensor.index] - th
    if sensor.kind == "station":
        derivative, rate = _STATION_PARTS[sensor.part]
        beam = m.beams[sensor.index]
        row = beam.shapes([beam.stations[sensor.point]], derivative)[:, 0]
        return _dot(row, v if rate else q, m.modal_index[sensor.index][:row.size])
    which, axis = _POINT_AXES[sensor.part]
    return kinematics.point(sensor.index, sensor.point)[which][axis]


class PlanarSymbols:
    """A planar plant on symbols for :class:`~ctmm.compiled_loops.ClosedLoops`: ``q`` and ``v = qdot`` of
    ``n_coordinates`` each, sensors by :func:`sensor_expression`.  With a moving driven hinge
    (:attr:`time_sensors`) the sensors are functions of the state and the time symbol as well, which the loops
    state at every stage time (the generated RK4) and the paths that read them at the state only refuse."""

    def __init__(self, model: PlanarModel, ports: PlanarPorts) -> None:
        self.model, self.ports = model, ports
        self.n_positions = self.n_velocities = model.n_coordinates
        self.time_sensors = bool(moving_drives(model))
        self._kinematics: tuple[Any, Any, Any, SymbolicKinematics] | None = None

    def position_rates(self, q: Any, v: Any) -> Any:
        return v

    def sensor(self, name: str, q: Any, v: Any, t: Any = None) -> Any:
        """Sensor ``name`` as an expression of the symbols ``q``, ``v`` (and the time ``t`` [s] with a moving
        driven hinge)."""
        if self._kinematics is None or any(a is not b for a, b in zip(self._kinematics[:3], (q, v, t))):
            self._kinematics = (q, v, t, SymbolicKinematics(self.model, q, v, t))
        return sensor_expression(self.ports, name, self._kinematics[3])
