"""The stored rows of the loop-closing driver (:func:`ctmm.control.planar_time.simulate_closed_loop`) and their result.

:class:`LoopRows` keeps the times, states ``[q, v, controller states]`` and every loop's ``(y, e, u)`` of the
stored steps (and, for plants whose stored signals depend on the actuators, the actuator values);
:func:`rows_result` turns them into a :class:`~ctmm.results.SimulationResult` -- also the partial result of a failed
run -- with each loop's ``"<loop>.y"`` and ``"<loop>.u"`` in the units of :func:`ctmm.signal_units.loop_unit`, a
saturating loop's unclipped demand and time at its limits, and the co-simulated controllers' samples.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from ..results import SimulationResult
from ..signal_results import SignalSystem, signal_result
from ..signal_units import loop_unit

# loop_unit (the one rule of a loop signal's unit) lives in ctmm.signal_units; re-exported here for the compiled
# runs and the FMU export, which import it from this module
__all__ = ["LoopRows", "loop_unit", "rows_result"]


class LoopRows:
    """Stored rows of a run of the loop-closing driver: times, states ``[q, v, controller states]`` and every loop's
    ``(y, e, u)`` (a partial result on failure).

    Parameters
    ----------
    system : object
        The closed loop of :mod:`ctmm.control.planar_time` (its ``plant``, ``ports``, ``loops``, ``loop_values``
        and ``actuator_values``).
    """

    def __init__(self, system: Any) -> None:
        self.system = system
        self.t: list[float] = []
        self.y: list[np.ndarray] = []
        self.loops: list[list[tuple[float, float, float]]] = []
        self.inputs: list[Any] | None = [] if getattr(system.plant, "signals_need_inputs", False) else None

    def add(self, t: float, y: np.ndarray) -> None:
        """Store the state ``y`` at ``t`` [s] with the loops' signals there."""
        self.t.append(float(t))
        self.y.append(np.array(y, dtype=float))
        values = self.system.loop_values(t, y, record=True) if self.system.loops else []
        self.loops.append(values)
        if self.inputs is not None:     # a plant whose stored signals depend on the actuators (chains)
            actuators = self.system.actuator_values(t, y, values)
            self.inputs.append(self.system.ports.inputs(actuators) if actuators else None)


def rows_result(rows: LoopRows, outputs: Sequence[str], method: str, info: dict) -> SimulationResult:
    """The stored rows as a result: the plant's signals and ``outputs``, each loop's ``"<loop>.y"``, ``"<loop>.u"``
    (with saturation ``"<loop>.u_demand"``, ``"<loop>.saturated"`` and ``info["time_saturated_s"]``), the
    controllers' ``"<output>@samples"``; ``info`` adds ``"loops"`` and ``"n_evaluations"``."""
    system = rows.system
    model, n = system.model, system.n
    t = np.array(rows.t)
    y = np.array(rows.y).reshape(len(t), system.size)
    extra = {} if rows.inputs is None else {"inputs": rows.inputs}
    signals, units = system.plant.signals(t, y[:, :n], y[:, n:system.base], outputs, **extra)
    saturated_time = {}
    for k, lp in enumerate(system.loops):
        values = np.array([row[k] for row in rows.loops]).reshape(len(t), 3)
        signals[f"{lp.name}.y"], signals[f"{lp.name}.u"] = values[:, 0], values[:, 2]
        units[f"{lp.name}.y"] = loop_unit(system.ports, lp.loop, "y")
        units[f"{lp.name}.u"] = loop_unit(system.ports, lp.loop, "u")
        if lp.loop.saturation is not None:
            demand, at_limit = _saturation_signals(lp, y[:, lp.states], values[:, 1])
            signals[f"{lp.name}.u_demand"], units[f"{lp.name}.u_demand"] = demand, units[f"{lp.name}.u"]
            signals[f"{lp.name}.saturated"], units[f"{lp.name}.saturated"] = at_limit.astype(float), ""
            saturated_time[lp.name] = float(np.sum(np.diff(t)[at_limit[:-1]])) if len(t) > 1 else 0.0
    if saturated_time:
        info = {**info, "time_saturated_s": saturated_time}
    if system.master is not None:
        last = t[-1] if len(t) else -math.inf
        for name, samples in system.master.outputs(until=last).items():
            signals[name] = samples
            units[name] = system.ports.actuator_unit(name.split("@")[0])
        info = {**info, "controllers": system.master.describe()}
    info = {**info, "loops": {lp.name: ("real-time" if lp.delay == 0.0 else "history") for lp in system.loops},
            "n_evaluations": system.evaluations}
    return signal_result(SignalSystem(model, units, [lp.loop for lp in system.loops]), t, signals, method, info)



def empty_result(plant: Any, model: Any, loops: Sequence[Any], outputs: Sequence[str], method: str,
                 info: dict) -> SimulationResult:
    """The result of a run that stored no row (a controller's ``init`` failed): the signals :func:`rows_result`
    gives -- the plant's, ``outputs``, each of the Feedback ``loops``' ``"<loop>.y"``, ``"<loop>.u"`` (with
    saturation ``.u_demand``, ``.saturated``) -- each with no value."""
    signals, units = plant.signals(np.zeros(0), np.zeros((0, plant.n_positions)), np.zeros((0, plant.n_velocities)),
                                   outputs)
    for loop in loops:
        for part in ("y", "u") + (("u_demand", "saturated") if loop.saturation is not None else ()):
            signals[f"{loop.name}.{part}"] = np.zeros(0)
            units[f"{loop.name}.{part}"] = "" if part == "saturated" else \
                loop_unit(plant.ports, loop, "u" if part == "u_demand" else part)
    return signal_result(SignalSystem(model, units, list(loops)), np.zeros(0), signals, method, info)


def _saturation_signals(lp: Any, z: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The unsaturated demand ``-C z - D e`` of a saturating loop on the stored rows [actuator unit]
    and where it is beyond the limits (the applied ``"<loop>.u"`` is at a limit there)."""
    demand = -(z @ lp.C[0]) - lp.D * e if z.shape[1] else -lp.D * e
    low, high = lp.loop.saturation
    return demand, (demand < low) | (demand > high)
