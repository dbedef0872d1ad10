"""Named sensors and actuators of a planar kinematic loop model: the tree's ports plus the cut joints'.

A :class:`~ctmm.planar.closed_loops.KinematicLoopModel` exposes every port of its spanning tree
(:mod:`ctmm.planar.ports`) and, for every cut joint ``<cut>`` (:mod:`ctmm.planar.cut_joints`),

Sensors
    * ``"<cut>.angle"``, ``"<cut>.rate"`` -- the relative angle across the cut
      ``dtheta = theta_child - theta_parent`` [rad] and its rate [rad/s]
      (:meth:`KinematicLoopModel.relative_angles`; at a ``ModalBeam`` end the elastic end slope included, at a
      ``ctmm.fem`` subsystem node its rotation ``r_z``);
    * ``"<cut>.moment"`` -- the moment of the cut's own law and torque signal on its child side
      ``torque(t) - moment_law(dtheta - rest_angle, dtheta_dot)`` [N m] (:meth:`CutJoint.moment`), for an undriven
      cut with a ``moment_law`` or a ``torque`` (actuator inputs on ``"<cut>.torque"`` are not part of it; a driven
      cut's moment is a reaction, solved with the accelerations, and not a sensor);
    * ``"<cut>.force_x"``, ``"<cut>.force_y"`` -- the cut force on the child point, global axes [N], solved with the
      accelerations **under the actuator values of that instant** (:meth:`KinematicLoopModel.solve`): the one kind of
      sensor that depends on the inputs (:attr:`KinematicLoopPorts.input_dependent`); :meth:`KinematicLoopPorts.values`
      refuses it by name unless given the actuator inputs, so a path that reads sensors from the state alone cannot
      return it without them.

Actuators
    * ``"<cut>.torque"`` -- a torque [N m] across an undriven cut: ``+u`` on the child side, ``-u`` on the parent
      (:meth:`KinematicLoopModel.torque_inputs`), added to the cut's own law and torque (not at a ``ctmm.fem``
      subsystem node without a rotation DOF: a particle takes no moment).

These are the one list of the cut joints' port names: :func:`ctmm.simulate` (inputs, outputs, loops,
controllers), :func:`ctmm.linearize`, :func:`ctmm.frequency_response` and the margins of a kinematic loop model
resolve names through :class:`KinematicLoopPorts`.  A loop on a cut force with no delay is algebraic (the force
responds to the loop's own actuator at once): the linearisation and the generated RK4 (``compiled=True``) close it
exactly, the numpy time driver refuses it by name (``docs/closed_loops.md`` §3c).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any
from dataclasses import dataclass

import numpy as np

from .. import validation
from ..errors import ModelError
from ..named_ports import NOT_GIVEN, merged_values, split_actuator_values
from .closed_loops import KinematicLoopModel
from .ports import ActuatorInputs, PlanarPorts

__all__ = ["KinematicLoopPorts", "loop_sensor_signals", "tree_outputs"]


@dataclass(frozen=True)
class _CutSensor:
    """A sensor of cut joint number ``index``: ``part`` is ``"angle"``, ``"rate"``, ``"moment"``, ``"force_x"`` or
    ``"force_y"``."""

    name: str
    index: int
    part: str
    unit: str

    @property
    def is_rate(self) -> bool:
        return self.part == "rate"


@dataclass(frozen=True)
class _CutActuator:
    """The torque input of cut joint ``cut``."""

    name: str
    cut: str
    unit: str = "N m"


class KinematicLoopPorts(PlanarPorts):
    """The sensors and actuators of a kinematic loop model (module docstring), resolved once.

    Parameters
    ----------
    model : KinematicLoopModel

    Attributes
    ----------
    model : PlanarModel
        The spanning tree (whose ports these extend).
    loop_model : KinematicLoopModel
    input_dependent : frozenset of str
        The sensors whose values depend on the actuator inputs (the cut forces).
    """

    def __init__(self, model: KinematicLoopModel) -> None:
        if not isinstance(model, KinematicLoopModel):
            raise ModelError(f"model must be a ctmm.planar.closed_loops.KinematicLoopModel, got {model!r}")
        super().__init__(model.tree)
        self.loop_model = model
        sensors, actuators = dict(self.sensors), dict(self.actuators)
        added: dict[str, object] = {}
        for k, cut in enumerate(model.cuts):
            added[f"{cut.name}.angle"] = _CutSensor(f"{cut.name}.angle", k, "angle", "rad")
            added[f"{cut.name}.rate"] = _CutSensor(f"{cut.name}.rate", k, "rate", "rad/s")
            if cut.has_moment:
                added[f"{cut.name}.moment"] = _CutSensor(f"{cut.name}.moment", k, "moment", "N m")
            for axis in "xy":
                added[f"{cut.name}.force_{axis}"] = _CutSensor(f"{cut.name}.force_{axis}", k, f"force_{axis}", "N")
            if not cut.driven and model.cut_points.takes_moment[k]:     # a particle node takes no moment
                added[f"{cut.name}.torque"] = _CutActuator(f"{cut.name}.torque", cut.name)
        clash = sorted(name for name, entry in added.items()
                       if name in (actuators if isinstance(entry, _CutActuator) else sensors))
        if clash:
            raise ModelError(f"kinematic loop {model.name!r}: the cut joints' ports {clash} are also ports of the tree "
                             "(a cut joint named like a tree hinge or body); rename the cut joint")
        for name, entry in added.items():
            (actuators if isinstance(entry, _CutActuator) else sensors)[name] = entry
        self.sensors, self.actuators = sensors, actuators
        self.input_dependent = frozenset(name for name, entry in added.items()
                                         if isinstance(entry, _CutSensor) and entry.part.startswith("force_"))
        self._unit_inputs = {entry.cut: model.torque_inputs(entry.cut) for entry in added.values()
                             if isinstance(entry, _CutActuator)}

    def check_sensor(self, name: str, what: str = "sensor") -> str:
        """``name`` if it is a sensor, else an error listing the sensors (a driven cut's moment: why not)."""
        if isinstance(name, str) and name.endswith(".moment") and name not in self.sensors:
            cut = next((c for c in self.loop_model.cuts if c.name == name[:-len(".moment")]), None)
            if cut is not None:
                raise ModelError(f"{what} {name!r}: " + (
                    "a driven cut's moment is the drive's reaction, solved with the accelerations (a loop on it "
                    "would be algebraic); it is a stored signal of ctmm.simulate" if cut.driven else
                    f"cut joint {cut.name!r} has no moment_law or torque (a smooth cut has no moment)")
                    + f"; sensors of the cut: {cut.name}.angle, {cut.name}.rate")
        return super().check_sensor(name, what)

    def check_actuator(self, name: str, what: str = "actuator") -> str:
        """``name`` if it is an actuator, else an error listing the actuators (a driven cut's torque: why not)."""
        if isinstance(name, str) and name.endswith(".torque") and name not in self.actuators:
            cut = next((c for c in self.loop_model.cuts if c.name == name[:-len(".torque")]), None)
            if cut is not None:
                raise ModelError(f"{what} {name!r}: cut joint {cut.name!r} is driven (its relative angle is "
                                 "prescribed); only undriven cut joints take a torque input")
        return super().check_actuator(name, what)

    def values(self, sensors: list, q: np.ndarray, qdot: np.ndarray, t: float, inputs: Any = NOT_GIVEN) -> np.ndarray:
        """Values of resolved ``sensors`` (no validation of the state: for inner loops); the cut forces solved with the
        actuator ``inputs`` (an :class:`ActuatorInputs` or ``None``: none), refused by name when ``inputs`` is not
        given."""
        def cut_values(chosen: list) -> list[float]:
            angle, rate = self.loop_model.relative_angles(q, qdot, t)
            cuts = self.loop_model.cuts
            forces = None
            if any(s.part.startswith("force_") for s in chosen):
                if inputs is NOT_GIVEN:
                    named = [s.name for s in chosen if s.part.startswith("force_")]
                    raise ModelError(f"sensors {named}: a cut force depends on the actuator values of the instant, "
                                     "and this path reads its sensors from the state alone; read it in the loop "
                                     "driver (ctmm.simulate with compiled=None) or ctmm.linearize")
                forces = np.asarray(self.loop_model.solve(q, qdot, t, inputs)[1], dtype=float).reshape(-1, 2)
            return [angle[s.index] if s.part == "angle" else rate[s.index] if s.part == "rate"
                    else forces[s.index, 0 if s.part == "force_x" else 1] if s.part.startswith("force_")
                    else cuts[s.index].moment(angle[s.index], rate[s.index], t) for s in chosen]

        return merged_values(sensors, _CutSensor, lambda chosen: PlanarPorts.values(self, chosen, q, qdot, t),
                             cut_values)

    def inputs(self, values: Mapping[str, float]) -> ActuatorInputs:
        """Arrange actuator ``values`` (``{actuator name: value}``, SI units) for the tree's sweeps: the tree's
        actuators and the cut torques (each ``u`` times the cut's unit moment pair); entries on one actuator add."""
        tree, cut = split_actuator_values(values, self.actuators, _CutActuator)
        inputs = super().inputs(tree)
        if not cut:
            return inputs
        body = np.array(inputs.body_force, dtype=float)
        modal = {j: np.array(row, dtype=float) for j, row in inputs.modal_force.items()}
        frame = {j: np.array(row, dtype=float) for j, row in inputs.frame_wrench.items()}
        for name, value in cut:
            value = validation.finite(f"actuator {name!r}", value)
            unit = self._unit_inputs[self.actuators[name].cut]
            body += value * unit.body_force
            for target, source in ((modal, unit.modal_force), (frame, unit.frame_wrench)):
                for j, row in source.items():
                    target[j] = target.get(j, np.zeros(len(row))) + value * np.asarray(row, dtype=float)
        return ActuatorInputs(inputs.hinge_torque, body, modal, frame)


def loop_sensor_signals(ports: KinematicLoopPorts, t: np.ndarray, q: np.ndarray, qdot: np.ndarray,
                        outputs: Sequence[str]) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """The cut-joint sensors among ``outputs`` at the stored rows ``(t, q, qdot)`` (each row a state of the tree),
    with their units; the tree's sensors are left to :func:`ctmm.planar.integrate.model_signals`."""
    names = [name for name in outputs if isinstance(ports.sensors.get(name), _CutSensor)
             and name not in ports.input_dependent]      # the cut forces: stored with every result, solved with inputs
    if not names:
        return {}, {}
    sensors = ports.resolve(names)
    rows = np.array([ports.values(sensors, q[k], qdot[k], float(t[k])) for k in range(len(t))]).reshape(len(t), -1)
    return ({name: rows[:, i] for i, name in enumerate(names)}, {name: ports.sensors[name].unit for name in names})


def tree_outputs(ports: KinematicLoopPorts, outputs: Sequence[str]) -> list[str]:
    """The names among ``outputs`` that are sensors of the spanning tree (not of the cut joints)."""
    return [name for name in outputs if not isinstance(ports.sensors.get(name), _CutSensor)]
