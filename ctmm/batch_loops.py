"""Parameter sets with loops stepped together on one generated kernel (issue 13 item 4): the mapped loop
driver of :meth:`ctmm.batch.ParameterKernel.run_mapped`.

A planar or spatial kernel with feedback loops (real-time, LTI controllers, delayed), ``references``, open-loop
or port inputs or spatial ``outputs`` carries everything that differs between parameter sets either in its
state or in its parameter column (:class:`~ctmm.compiled_loops.ClosedLoops` with ``numbers="inputs"``):

* the state ``[q, v, z, ring]``: coordinates, velocities, the controller states ``z`` and the delay ring of
  each delayed loop (its samples of the loop signal and their rates);
* the column ``p``: the plant's numbers, then each loop's gain, controller realisation and reference fields.

So the sets step together: each set is prepared on the shared kernel as a :class:`LoopRun` (its controlled
model, the scene with its loop laws and numbers, its whole initial state;
:meth:`ctmm.batch.ParameterKernel.loop_run`), and :func:`run_members` runs the generated RK4 of all of them in
one C call per block (``casadi.Function.map``, serial: each member runs the same compiled function as a run
alone, so the same numbers to the bit).  Each set is then checked and stored from its own rows as alone
(:func:`~ctmm.compiled_control.simulate_controlled_generated`,
:func:`~ctmm.compiled_control.simulate_spatial_controlled_generated` with ``ran``: loop signals
``"<loop>.y|u"`` from the set's own laws, ``outputs``, step check, divergence bound): a diverging set's rows turn
non-finite without touching the others' and it fails alone, with its partial result.

Every set states its loops on symbols again (its gains, references and controllers are its own); the loop
sensors, functions of the state and the geometry only, are stated once per kernel (:class:`SharedSensors`) where
no number of a set enters them: planar plants (geometry and beam data are structure) and spatial plants without
modal beams (a beam's station shapes are computed from its data; those sets state their sensors per set).

Co-simulated controllers (Python objects or FMUs) are called between sample intervals of each set: their sets
run one by one (:meth:`ctmm.batch.ParameterKernel.run`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .control.controlled_model import ControlledModel
from .errors import ModelError

__all__ = ["LoopRun", "SharedSensors", "run_members"]


@dataclass(frozen=True)
class LoopRun:
    """One parameter set's run with loops, prepared on the shared kernel (nothing run yet).

    Attributes
    ----------
    controlled : ControlledModel
        The set's plant (with its numbers) and loops (with its gains).
    scene : CompiledScene or CompiledControlledSpatial
        The shared compiled functions with the set's loop laws (``scene.loops``) and parameter column
        (``scene.parameters``: the plant's numbers, then the loops').
    q0, v0 : ndarray
        Initial coordinates [m, rad; spatial: quaternion entries] and velocities [m/s, rad/s], checked.
    first : ndarray
        The whole initial state ``[q, v, z = 0, ring]`` (the history before ``t = 0`` the initial state held).
    """

    controlled: ControlledModel
    scene: Any
    q0: np.ndarray
    v0: np.ndarray
    first: np.ndarray


class SharedSensors:
    """A plant on symbols for :class:`~ctmm.compiled_loops.ClosedLoops` (``symbols=``) whose sensors are each
    stated once and then called on the symbols of every later set (a ``casadi.Function`` of ``(q, v)``: the same
    expression, no kinematics built again).

    Parameters
    ----------
    symbols : PlanarSymbols or SpatialSymbols
        The kernel's plant on symbols (:class:`~ctmm.compiled_planar_sensors.PlanarSymbols`,
        :class:`~ctmm.compiled_spatial_loops.SpatialSymbols`); only for plants whose sensors hold no parameter.

    Attributes
    ----------
    functions : dict of str to casadi.Function
        ``sensor(q, v)`` by sensor name, filled at first use.
    """

    def __init__(self, symbols: Any) -> None:
        self.symbols, self.ports = symbols, symbols.ports
        self.n_positions, self.n_velocities = symbols.n_positions, symbols.n_velocities
        self.parameter_count = getattr(symbols, "parameter_count", 0)
        self.time_sensors = bool(getattr(symbols, "time_sensors", False))     # sensors moving with driven joints
        self.functions: dict[str, Any] = {}

    def position_rates(self, q: Any, v: Any) -> Any:
        """``q_dot`` on symbols (the plant's own rule)."""
        return self.symbols.position_rates(q, v)

    def sensor(self, name: str, q: Any, v: Any, t: Any = None) -> Any:
        """Sensor ``name`` on the symbols ``q``, ``v`` (and the time ``t`` [s] when the sensors move with driven
        joints, :attr:`time_sensors`): the expression stated once, called on them."""
        import casadi as ca

        function = self.functions.get(name)
        if function is None:
            q_first, v_first = ca.SX.sym("q", self.n_positions), ca.SX.sym("v", self.n_velocities)
            if self.time_sensors:
                t_first = ca.SX.sym("t")
                function = ca.Function("sensor", [q_first, v_first, t_first],
                                       [self.symbols.sensor(name, q_first, v_first, t_first)])
            else:
                function = ca.Function("sensor", [q_first, v_first], [self.symbols.sensor(name, q_first, v_first)])
            self.functions[name] = function
        return function(q, v, t) if self.time_sensors else function(q, v)


def run_members(scene: Any, runs: Sequence[LoopRun], dt: float, n_steps: int) -> tuple[np.ndarray, float]:
    """The stored states of every prepared set's run, one C call per block for all of them.

    Parameters
    ----------
    scene : CompiledScene or CompiledControlledSpatial
        The shared kernel (numbers as inputs) the ``runs`` were prepared on.
    runs : sequence of LoopRun
        The sets, each with its whole initial state and parameter column.
    dt : float
        Step [s].
    n_steps : int
        RK4 steps from ``t = 0``.

    Returns
    -------
    states : ndarray (sets, rows, state size)
        Stored states of each set after each ``store_every`` steps and after the last (the initial state
        excluded; rows after a set's first non-finite one are non-finite).
    wall : float
        Wall time of the mapped run per set [s].

    Raises
    ------
    ModelError
        No sets, or a set whose state or parameter column does not fit the kernel (named by index).
    """
    if not runs:
        raise ModelError("run_members: runs must hold at least one prepared set (LoopRun), got none")
    size, count = runs[0].first.size, scene.parameters.size
    for index, run in enumerate(runs):
        if run.first.size != size or run.scene.parameters.size != count:
            raise ModelError(f"run_members: set {index} has a state of {run.first.size} and "
                             f"{run.scene.parameters.size} parameters; the kernel takes {size} and {count} (prepare "
                             "every set on this kernel)")
    states = np.stack([np.asarray(run.first, float) for run in runs], axis=1)
    parameters = np.stack([np.asarray(run.scene.parameters, float) for run in runs], axis=1)
    clock = time.perf_counter()
    rows = scene.run_members(states, parameters, dt, n_steps)
    return rows, (time.perf_counter() - clock) / len(runs)
