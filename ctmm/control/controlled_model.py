"""Feedback loops on planar models (rigid and flexible) and spatial models: :class:`ControlledModel`.

The loops are the same :class:`~ctmm.control.loops.Feedback` objects as on 1-D chains,

    u(t) = -C [ y(t - tau) - r(t - tau) ],    y = sum_i c_i * sensor_i,

with sensors and actuators named by the model's ports (:mod:`ctmm.planar.ports`: hinge angles
and rates, body angles, point positions and velocities, generalised coordinates; hinge
torques, body forces and moments, modal forces; :mod:`ctmm.spatial.ports`: joint coordinates and
rates, angular velocities about world or body axes, x-y-z angles, rotation vectors, point
positions and velocities; joint torques and forces, body forces and moments).  A controlled model is a description: the
verbs close its loops -- :func:`ctmm.simulate` in time (real-time loops at the current state,
delayed loops from the history), :func:`ctmm.linearize` about an operating point (real-time
loops inside ``A``, delayed loops beside it) and the stability tools on that linearisation.

:func:`with_feedback` is the one constructor for every plant: a :class:`~ctmm.system.Chain`
gets a :class:`~ctmm.control.loops.ControlledChain` (loops embedded in its transfer
matrices), a :class:`~ctmm.planar.model.PlanarModel` or a :class:`~ctmm.spatial.model.SpatialModel`
a :class:`ControlledModel`.  Spatial controlled models are simulated (``"rk4"`` and the
``solve_ivp`` methods); their linearisation is issue 14's next step.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from .. import validation
from ..errors import ModelError, unknown_name
from ..planar.closed_loops import KinematicLoopModel
from ..spatial.closed_loops import SpatialKinematicLoopModel
from ..planar.model import PlanarModel
from ..spatial.model import SpatialModel
from ..system import Chain
from .loops import ControlledChain, Feedback
from .plants import is_plant_model, plant_of

__all__ = ["ControlledModel", "with_feedback"]


class ControlledModel:
    """A planar model (rigid or with modal beams) or a spatial model with embedded feedback loops.

    Parameters
    ----------
    plant : PlanarModel, KinematicLoopModel or SpatialModel
        The open-loop model (a kinematic loop model: the ports of its spanning tree).
    loops : sequence of Feedback
        A list (any iterable but a string or a mapping; a single Feedback is one loop) of
        loops whose sensor terms name sensors of ``plant`` and whose actuator terms name its
        actuators (:mod:`ctmm.planar.ports`, :mod:`ctmm.spatial.ports`).  ``gain`` is a float or a
        SISO continuous-time python-control system; a PD law on an angle is the weighted sensor
        ``[("motor.angle", kp), ("motor.rate", kd)]`` with ``gain=1`` (no improper ``C(s)``).

    Examples
    --------
    >>> from ctmm.planar import ActuatedHinge, PlanarModel, Pinned, RigidBody
    >>> from ctmm.control import Feedback, with_feedback
    >>> arm = PlanarModel.chain("arm", [Pinned("motor"), RigidBody.uniform_link("link", mass=1.0, length=0.5)])
    >>> pd = Feedback("pd", sensor=[("motor.angle", 20.0), ("motor.rate", 2.0)], actuator="motor.torque",
    ...               gain=1.0, delay=0.01)
    >>> with_feedback(arm, [pd]).signal_names()[-2:]
    ['pd.y', 'pd.u']
    """

    def __init__(self, plant: PlanarModel | SpatialModel, loops: Sequence[Feedback]) -> None:
        if not (is_plant_model(plant) or isinstance(plant, (KinematicLoopModel, SpatialKinematicLoopModel))):
            raise ModelError(f"plant must be a ctmm.planar.PlanarModel, a KinematicLoopModel, a "
                             f"ctmm.spatial.SpatialModel or a SpatialKinematicLoopModel (use with_feedback for any "
                             f"plant), got {plant!r}")
        if isinstance(loops, Feedback):
            loops = [loops]                         # one loop, as ControlledChain accepts it
        if isinstance(loops, (str, bytes, Mapping)) or not isinstance(loops, Iterable):
            raise ModelError(f"loops must be a list of ctmm.control.Feedback loops, got {loops!r}")
        loops = tuple(loops)
        described = plant_of(plant)
        ports = described.ports
        names: set[str] = set()
        for index, loop in enumerate(loops):
            if not isinstance(loop, Feedback):
                raise ModelError(f"loops[{index}] must be a ctmm.control.Feedback loop, got {loop!r}")
            if loop.name in names:
                raise ModelError(f"duplicate loop name {loop.name!r}")
            if loop.name in described.element_names:
                raise ModelError(f"loop name {loop.name!r} is also an element of {plant.name!r}; "
                                 "signal names would be ambiguous")
            names.add(loop.name)
            for sensor, _ in loop.terms:
                ports.check_sensor(sensor, f"loop {loop.name!r}: sensor")
            for actuator, _ in loop.actuator_terms:
                ports.check_actuator(actuator, f"loop {loop.name!r}: actuator")
        self._plant = plant
        self._loops = tuple(loops)
        self._ports = ports

    # -- description ---------------------------------------------------------------------
    @property
    def plant(self) -> PlanarModel | SpatialModel:
        """The open-loop model."""
        return self._plant

    @property
    def loops(self) -> tuple[Feedback, ...]:
        """The loops, in the order given."""
        return self._loops

    @property
    def name(self) -> str:
        """The plant's name."""
        return self._plant.name

    @property
    def ports(self) -> Any:
        """The plant's sensors and actuators (:class:`~ctmm.planar.ports.PlanarPorts` or
        :class:`~ctmm.spatial.ports.SpatialPorts`)."""
        return self._ports

    def loop(self, name: str) -> Feedback:
        """The loop called ``name``."""
        for loop in self._loops:
            if loop.name == name:
                return loop
        raise unknown_name("loop", name, [loop.name for loop in self._loops])

    def with_loops(self, loops: Sequence[Feedback]) -> ControlledModel:
        """The same plant with other loops."""
        return ControlledModel(self._plant, loops)

    def signal_names(self) -> list[str]:
        """Plant sensors, then ``"<loop>.y"`` and ``"<loop>.u"`` of every loop."""
        return list(self._ports.sensors) + [f"{loop.name}.{part}" for loop in self._loops
                                            for part in ("y", "u")]

    def input_names(self) -> list[str]:
        """Plant actuators, then ``"<loop>.reference"`` of every loop."""
        return list(self._ports.actuators) + [f"{loop.name}.reference" for loop in self._loops]

    # -- evaluation helpers for the verbs ------------------------------------------------
    def sensed(self, values: Mapping[str, float]) -> dict[str, float]:
        """``{loop: y}`` from sensor values ``{sensor: value}`` (``y = sum c_i sensor_i``); every
        sensor of :meth:`sensors` must be given, as a finite number in its unit."""
        if not isinstance(values, Mapping):
            raise ModelError(f"values must be a mapping {{sensor name: value}}, got {values!r:.80}")
        missing = [sensor for sensor in self.sensors() if sensor not in values]
        if missing:
            raise ModelError(f"values must give every sensor the loops read: missing {missing} in {values!r:.80}")
        checked = {sensor: validation.finite(f"values[{sensor!r}]", values[sensor]) for sensor in self.sensors()}
        return {loop.name: sum(weight * checked[sensor] for sensor, weight in loop.terms) for loop in self._loops}

    def actuation(self, forces: Mapping[str, float]) -> dict[str, float]:
        """``{actuator: value}`` from loop outputs ``{loop: u}`` (weighted actuator terms added; a
        loop not given contributes 0)."""
        if not isinstance(forces, Mapping):
            raise ModelError(f"forces must be a mapping {{loop name: u}}, got {forces!r:.80}")
        for name in forces:
            if name not in {loop.name for loop in self._loops}:
                raise unknown_name("loop of forces", name, [loop.name for loop in self._loops])
        out: dict[str, float] = {}
        for loop in self._loops:
            u = validation.finite(f"forces[{loop.name!r}]", forces.get(loop.name, 0.0))
            for actuator, weight in loop.actuator_terms:
                out[actuator] = out.get(actuator, 0.0) + weight * u
        return out

    def sensors(self) -> list[str]:
        """Every sensor some loop reads (each once, in loop order)."""
        seen: dict[str, None] = {}
        for loop in self._loops:
            for sensor, _ in loop.terms:
                seen.setdefault(sensor, None)
        return list(seen)

    def __repr__(self) -> str:
        return f"ControlledModel({self._plant!r}, loops={[loop.name for loop in self._loops]})"


def with_feedback(plant: Any, loops: Sequence[Feedback]) -> ControlledChain | ControlledModel:
    """``plant`` with the feedback ``loops`` closed, for any plant.

    Parameters
    ----------
    plant : Chain, PlanarModel, KinematicLoopModel or SpatialModel
        A 1-D chain (loops embedded in its transfer matrices: :class:`ControlledChain`), a
        planar model, rigid or with modal beams, a planar model with cut joints or a spatial model
        (:class:`ControlledModel`).
    loops : sequence of Feedback

    Returns
    -------
    ControlledChain or ControlledModel
    """
    if isinstance(plant, Chain):
        return ControlledChain(plant, loops)
    if is_plant_model(plant) or isinstance(plant, (KinematicLoopModel, SpatialKinematicLoopModel)):  # closed_loops.md
        return ControlledModel(plant, loops)
    if isinstance(plant, (ControlledChain, ControlledModel)):
        raise ModelError(f"plant {plant!r} already has loops; use plant.with_loops(...) to "
                         "replace them or build from the open-loop plant")
    raise ModelError(f"plant must be a ctmm.Chain, a ctmm.planar.PlanarModel or a ctmm.spatial.SpatialModel, got "
                     f"{plant!r}")
