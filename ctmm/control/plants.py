"""The plant protocol of the one loop-closing time driver (:mod:`ctmm.control.planar_time`).

A loop or a co-simulated controller sees a model only through its **ports** -- named sensors and
actuators -- and the time driver needs a few dynamics on top.  :class:`Plant` is that small explicit
protocol; :class:`PlanarPlant` (:class:`~ctmm.planar.model.PlanarModel`, ports
:class:`~ctmm.planar.ports.PlanarPorts`), :class:`SpatialPlant`
(:class:`~ctmm.spatial.model.SpatialModel`, ports :class:`~ctmm.spatial.ports.SpatialPorts`) and
:class:`~ctmm.control.chain_plant.ChainPlant` (a lumped 1-D chain on its explicit context, ports
:class:`~ctmm.control.chain_plant.ChainPorts`) are its implementations, and :func:`plant_of` picks one.
A plant with ``signals_need_inputs = True`` gets the actuator values of every stored row in
``signals(..., inputs=...)`` (a chain's accelerations and point forces depend on them).

Ports (``plant.ports``)
    ``sensors``, ``actuators`` (mappings by name), ``check_sensor(name, what)``,
    ``check_actuator(name, what)``, ``sensor_unit(name)``, ``actuator_unit(name)``,
    ``resolve(names)`` (resolved sensors), ``values(resolved, q, v, t)`` (sensor values),
    ``inputs({actuator: value})`` (actuator values arranged for the sweep).
Dynamics (``plant``)
    ``n_positions``, ``n_velocities`` (``q``, ``v`` sizes), ``position_rates(q, v)`` (``q_dot``),
    ``accelerations(q, v, t, inputs)`` (``v_dot`` from the one articulated sweep),
    ``signals(t, q, v, outputs)`` (named histories and units), ``guard(q0, bound, v0)`` (per-step
    check: ``divergence_bound``, distance from the start), ``check_step(q0, v0, dt, policy)`` (RK4 step against the plant's stability limit),
    ``element_names`` (loop names must differ from them), ``schemes`` (whether the implicit
    DT-TMM schemes apply).
"""
from __future__ import annotations

from typing import Any, Callable, Protocol, Sequence

import numpy as np

from ..errors import ModelError
from ..planar.closed_loops import KinematicLoopModel
from ..planar.guards import check_scheme, divergence_guard
from ..planar.integrate import check_state, model_signals
from ..planar.loop_plant import KinematicLoopPlant
from ..planar.model import PlanarModel
from ..planar.ports import PlanarPorts
from ..planar.sweep import accelerations as planar_accelerations
from ..spatial.closed_loop_plant import SpatialLoopPlant
from ..spatial.closed_loops import SpatialKinematicLoopModel
from ..spatial.integrate import divergence_check, spatial_signals
from ..spatial.model import SpatialModel
from ..spatial.ports import SpatialPorts
from ..system import Chain
from .chain_plant import ChainPlant
from .loops import ControlledChain

__all__ = ["Plant", "PlanarPlant", "SpatialPlant", "plant_of", "is_plant_model"]


class Plant(Protocol):
    """What the loop-closing time driver needs of a model (module docstring)."""

    model: Any
    ports: Any
    label: str
    schemes: bool
    n_positions: int
    n_velocities: int
    element_names: tuple[str, ...]

    def position_rates(self, q: np.ndarray, v: np.ndarray) -> np.ndarray: ...

    def accelerations(self, q: np.ndarray, v: np.ndarray, t: float, inputs: Any) -> np.ndarray: ...

    def signals(self, t: np.ndarray, q: np.ndarray, v: np.ndarray, outputs: Sequence[str]) -> tuple[dict, dict]: ...

    def guard(self, q0: np.ndarray, bound: float | None, v0: np.ndarray | None = None
              ) -> Callable[[float, np.ndarray, float | None, str], None]: ...

    def check_step(self, q0: np.ndarray, v0: np.ndarray, dt: float, policy: str) -> None: ...


class PlanarPlant:
    """A :class:`~ctmm.planar.model.PlanarModel` (rigid or with modal beams) as a :class:`Plant`."""

    label = "planar"
    schemes = True

    def __init__(self, model: PlanarModel) -> None:
        self.model = model
        self.ports = PlanarPorts(model)
        self.n_positions = self.n_velocities = model.n_coordinates
        self.element_names = tuple(model.body_names) + tuple(model.joint_names)

    def position_rates(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return v

    def accelerations(self, q: np.ndarray, v: np.ndarray, t: float, inputs: Any) -> np.ndarray:
        return planar_accelerations(self.model, q, v, t, inputs=inputs)

    def signals(self, t: np.ndarray, q: np.ndarray, v: np.ndarray, outputs: Sequence[str]) -> tuple[dict, dict]:
        return model_signals(self.model, t, q, v, outputs)

    def guard(self, q0: np.ndarray, bound: float | None, v0: np.ndarray | None = None
              ) -> Callable[[float, np.ndarray, float | None, str], None]:
        guard = divergence_guard(self.model, q0, bound)
        return lambda t, y, step, method: check_state(self.model, guard, t, y, step, method)

    def check_step(self, q0: np.ndarray, v0: np.ndarray, dt: float, policy: str) -> None:
        check_scheme(self.model, q0, v0, dt, scheme="rk4", policy=policy)


class SpatialPlant:
    """A :class:`~ctmm.spatial.model.SpatialModel` as a :class:`Plant` (its ports carry the dynamics)."""

    label = "spatial"
    schemes = True

    def __init__(self, model: SpatialModel) -> None:
        self.model = model
        self.ports = ports = SpatialPorts(model)
        self.n_positions, self.n_velocities = model.n_positions, model.n_velocities
        self.element_names = ports.element_names
        self.position_rates = ports.position_rates
        self.accelerations = ports.accelerations

    def signals(self, t: np.ndarray, q: np.ndarray, v: np.ndarray, outputs: Sequence[str]) -> tuple[dict, dict]:
        """Every coordinate and velocity, body positions and angular velocities (:func:`spatial_signals`)
        and the sensor ``outputs``."""
        nq, nv = self.n_positions, self.n_velocities
        states = np.concatenate([np.reshape(q, (len(t), nq)), np.reshape(v, (len(t), nv))], axis=1)
        signals, units = spatial_signals(self.model, np.asarray(t), states)
        outputs = list(dict.fromkeys(outputs))
        if outputs:
            sensors = self.ports.resolve(outputs)
            values = np.array([self.ports.values(sensors, states[k, :nq], states[k, nq:], float(t[k]))
                               for k in range(len(t))]).reshape(len(t), len(outputs))
            for k, name in enumerate(outputs):
                signals[name] = values[:, k]
                units[name] = self.ports.sensor_unit(name)
        return signals, units

    def guard(self, q0: np.ndarray, bound: float | None, v0: np.ndarray | None = None
              ) -> Callable[[float, np.ndarray, float | None, str], None]:
        size = self.n_positions + self.n_velocities
        start = np.concatenate([q0, np.zeros(self.n_velocities) if v0 is None else v0])
        check = divergence_check(self.model, start, bound)
        return lambda t, y, step, method: check(t, y[:size], method)

    def check_step(self, q0: np.ndarray, v0: np.ndarray, dt: float, policy: str) -> None:
        """No pre-run limit for spatial models yet (the run's own guards apply)."""


def is_plant_model(model: Any) -> bool:
    """Whether ``model`` is a model the loop-closing driver integrates (planar or spatial)."""
    return isinstance(model, (PlanarModel, SpatialModel))


def plant_of(model: Any) -> Plant:
    """The :class:`Plant` of a planar or spatial model, of a lumped 1-D chain
    (:class:`~ctmm.control.chain_plant.ChainPlant`: ``Chain`` or ``ControlledChain``) or of a kinematic loop
    model (:class:`~ctmm.planar.loop_plant.KinematicLoopPlant`)."""
    if isinstance(model, (Chain, ControlledChain)):
        return ChainPlant(model)
    if isinstance(model, PlanarModel):
        return PlanarPlant(model)
    if isinstance(model, SpatialModel):
        return SpatialPlant(model)
    if isinstance(model, KinematicLoopModel):       # cut joints: ctmm.planar.loop_plant
        return KinematicLoopPlant(model)
    if isinstance(model, SpatialKinematicLoopModel):    # spatial cut joints: ctmm.spatial.closed_loop_plant
        return SpatialLoopPlant(model)
    raise ModelError(f"model must be a ctmm.planar.PlanarModel or a ctmm.spatial.SpatialModel, got {model!r}")
