"""Named sensors and actuators of a spatial kinematic loop model: the tree's ports plus the cut joints'.

A :class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel` exposes every port of its spanning tree
(:mod:`ctmm.spatial.ports`) and, for every revolute or prismatic cut joint ``<cut>``
(:mod:`ctmm.spatial.closed_loop_cuts`), its coordinate ``s`` (the angle about a revolute cut's axis from
``parent_normal`` to ``normal``, the slide of a prismatic cut's child point along the guide;
:meth:`SpatialKinematicLoopModel.cut_coordinates`):

Sensors
    * revolute: ``"<cut>.angle"`` [rad], ``"<cut>.rate"`` [rad/s];
    * prismatic: ``"<cut>.position"`` [m], ``"<cut>.rate"`` [m/s] (the names of the tree's joints);
    * revolute with a ``law``: ``"<cut>.law_moment"`` [N m] -- the law's moment on the child about the cut's axis,
      ``-law(s - rest, s')`` (the cut's ``"<cut>.moment_x|y|z"`` outputs are the constraint's moment, without it);
    * prismatic with a ``law``: ``"<cut>.law_force"`` [N] -- the law's force on the child along the guide, the same;
    * spherical with a ``law``: ``"<cut>.moment_x"``, ``"<cut>.moment_y"``, ``"<cut>.moment_z"`` [N m] -- the law's
      moment on the child, world axes (:meth:`SpatialKinematicLoopModel.law_moments`, a function of the state).

A law sensor holds the law alone: the cut's ``actuation(t)`` and a port input ``"<cut>.torque"`` / ``"<cut>.force"``
(both known signals) are not in it, so the cut's whole load on the child along ``a`` is
``law_moment + actuation(t) + u`` plus the constraint's (``docs/closed_loops.md`` §8.6).

Actuators (undriven cuts; the names of :attr:`SpatialKinematicLoopModel.actuation_names`)
    * revolute: ``"<cut>.torque"`` [N m] -- a moment ``u`` about the cut's axis;
    * prismatic: ``"<cut>.force"`` [N] -- a force ``u`` along the slide.

Each is added to the cut's own ``actuation`` (:class:`~ctmm.spatial.closed_loop_cuts.CutActuatedInputs`): ``u a`` on
the child with ``a`` the world direction of the cut's coordinate at the current state, the opposite on the parent,
the load of :meth:`SpatialKinematicLoopModel.actuation_inputs` (the linearisation's input).  Spherical and universal cuts have no coordinate and
no actuators (a spherical cut with a law its moment sensors).

Every cut's force on the child ``"<cut>.force_x"``, ``"<cut>.force_y"``, ``"<cut>.force_z"`` [N] (world axes) is a
sensor too, solved with the accelerations **under the actuator values of that instant**: the sensors that respond
to the actuators at once (:attr:`SpatialLoopPorts.input_dependent`), refused by name by :meth:`SpatialLoopPorts.values`
unless it is given the actuator inputs (the planar rule, :mod:`ctmm.planar.loop_ports`; ``docs/closed_loops.md`` §3c).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import validation
from ..errors import ModelError
from ..named_ports import NOT_GIVEN, merged_values, split_actuator_values
from .closed_loop_cuts import LAW_KINDS, CutActuatedInputs
from .closed_loops import SpatialKinematicLoopModel
from .ports import SpatialInputs, SpatialPorts

__all__ = ["SpatialLoopPorts"]


@dataclass(frozen=True)
class _CutSensor:
    name: str
    index: int           # cut index
    rate: bool
    unit: str
    component: int = -1  # 0, 1, 2: a spherical cut's law moment along world x, y, z; -1: the coordinate or its rate
    law: bool = False    # a revolute / prismatic cut's law load along its coordinate
    force: int = -1      # 0, 1, 2: the cut force on the child along world x, y, z


@dataclass(frozen=True)
class _CutActuator:
    name: str
    cut: str
    unit: str


class SpatialLoopPorts(SpatialPorts):
    """The sensors and actuators of a spatial kinematic loop model (module docstring), resolved once.

    Parameters
    ----------
    model : SpatialKinematicLoopModel

    Attributes
    ----------
    model : SpatialModel
        The spanning tree (whose ports these extend).
    loop_model : SpatialKinematicLoopModel
    """

    def __init__(self, model: SpatialKinematicLoopModel) -> None:
        if not isinstance(model, SpatialKinematicLoopModel):
            raise ModelError(f"model must be a ctmm.spatial.closed_loops.SpatialKinematicLoopModel, got {model!r}")
        super().__init__(model.tree)
        self.loop_model = model
        sensors, actuators = dict(self.sensors), dict(self.actuators)
        added_sensors, added_actuators = {}, {}
        for k, cut in enumerate(model.cuts):
            added_sensors.update({f"{cut.name}.force_{axis}": _CutSensor(f"{cut.name}.force_{axis}", k, False, "N",
                                                                         force=j) for j, axis in enumerate("xyz")})
            if cut.kind == "spherical" and cut.law is not None:
                added_sensors.update({f"{cut.name}.moment_{axis}": _CutSensor(f"{cut.name}.moment_{axis}", k, False,
                                                                              "N m", j) for j, axis in enumerate("xyz")})
            if cut.kind not in LAW_KINDS:
                continue
            revolute = cut.kind == "revolute"
            position = "angle" if revolute else "position"
            added_sensors[f"{cut.name}.{position}"] = _CutSensor(f"{cut.name}.{position}", k, False,
                                                                 "rad" if revolute else "m")
            added_sensors[f"{cut.name}.rate"] = _CutSensor(f"{cut.name}.rate", k, True, "rad/s" if revolute else "m/s")
            if cut.law is not None:
                law = f"{cut.name}.law_{'moment' if revolute else 'force'}"
                added_sensors[law] = _CutSensor(law, k, False, "N m" if revolute else "N", law=True)
            label = f"{cut.name}.{'torque' if revolute else 'force'}"
            if label not in model.actuation_names:
                continue                                    # a driven cut
            added_actuators[label] = _CutActuator(label, cut.name, "N m" if revolute else "N")
        clash = sorted([n for n in added_sensors if n in sensors] + [n for n in added_actuators if n in actuators])
        if clash:
            raise ModelError(f"spatial kinematic loop {model.name!r}: the cut joints' ports {clash} are also ports of "
                             "the tree (a cut joint named like a tree joint or body); rename the cut joint")
        sensors.update(added_sensors)
        actuators.update(added_actuators)
        self.sensors, self.actuators = sensors, actuators
        self.input_dependent = frozenset(name for name, entry in added_sensors.items() if entry.force >= 0)

    def check_actuator(self, name: str, what: str = "actuator") -> str:
        """``name`` if it is an actuator, else an error listing the actuators (a driven cut's load: why not)."""
        if isinstance(name, str) and name not in self.actuators:
            cut = next((c for c in self.loop_model.cuts if c.name == name.rpartition(".")[0]), None)
            if cut is not None:
                reason = ("is driven (its coordinate is prescribed)" if cut.kind in LAW_KINDS else
                          f"is {cut.kind} (no coordinate to load; only revolute and prismatic cuts take a load)")
                raise ModelError(f"{what} {name!r}: cut joint {cut.name!r} {reason}; cut actuators: "
                                 f"{[a for a in self.actuators if isinstance(self.actuators[a], _CutActuator)]}")
        return super().check_actuator(name, what)

    def values(self, sensors: list, q: np.ndarray, v: np.ndarray, t: float, inputs: Any = NOT_GIVEN) -> np.ndarray:
        """Values of resolved ``sensors`` at ``(q, v, t)`` (no validation of the state: for inner loops); the cut
        forces solved with the actuator ``inputs`` (``None``: none), refused by name when ``inputs`` is not given."""
        cuts = self.loop_model.cuts

        def cut_values(chosen: list) -> list[float]:
            coordinate, rate = self.loop_model.cut_coordinates(q, v, t)
            moments = self.loop_model.law_moments(q, v, t) if any(s.component >= 0 for s in chosen) else None
            forces = None
            if any(s.force >= 0 for s in chosen):
                if inputs is NOT_GIVEN:
                    raise ModelError(f"sensors {[s.name for s in chosen if s.force >= 0]}: a cut force depends on "
                                     "the actuator values of the instant, and this path reads its sensors from the "
                                     "state alone; read it in the loop driver (ctmm.simulate, compiled=None) or "
                                     "ctmm.linearize")
                loads = self.loop_model.cut_loads(q, self.loop_model.solve(q, v, t, inputs)[1], t)
                forces = np.array([force for force, _ in loads], dtype=float).reshape(-1, 3)

            def value(s: _CutSensor) -> float:
                if s.force >= 0:
                    return forces[s.index, s.force]
                if s.component >= 0:
                    return moments[s.index, s.component]
                if s.law:
                    cut = cuts[s.index]
                    return -float(cut.law.force(coordinate[s.index] - cut.rest, rate[s.index]))
                return (rate if s.rate else coordinate)[s.index]
            return [value(s) for s in chosen]

        return merged_values(sensors, _CutSensor, lambda chosen: SpatialPorts.values(self, chosen, q, v, t),
                             cut_values)

    def inputs(self, values: Mapping[str, float]) -> SpatialInputs:
        """Arrange actuator ``values`` (``{actuator name: value}``, SI units) for the sweep: the tree's actuators and
        the cut loads (:class:`~ctmm.spatial.closed_loop_cuts.CutActuatedInputs`); entries on one actuator add up."""
        tree, cut = split_actuator_values(values, self.actuators, _CutActuator)
        inputs = super().inputs(tree)
        if not cut:
            return inputs
        loads: dict[str, float] = {}
        for name, value in cut:
            target = self.actuators[name].cut
            loads[target] = loads.get(target, 0.0) + validation.finite(f"actuator {name!r}", value)
        return CutActuatedInputs(inputs.joint, inputs.wrenches, checked=inputs.checked, cut_actuation=loads)
