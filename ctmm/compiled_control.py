"""RK4 of a controlled planar or spatial model with its loops closed inside generated C (issues 13, 14).

:func:`simulate_controlled_generated` is what ``ctmm.simulate(controlled_model, ..., compiled=True)``
runs on a planar plant: one :class:`~ctmm.compiled_scene.CompiledScene` of the
:class:`~ctmm.control.controlled_model.ControlledModel` (the loops stated by
:class:`~ctmm.compiled_loops.ClosedLoops`), one call per block of stored rows, and the same result
as the numpy path of :func:`ctmm.control.planar_time.simulate_closed_loop` -- coordinates, rates,
``outputs``, ``"<loop>.y"`` and ``"<loop>.u"`` -- equal to it to round-off.
:func:`simulate_spatial_controlled_generated` is the same for a spatial plant
(:class:`~ctmm.compiled_spatial_loops.CompiledControlledSpatial`: the same
:class:`~ctmm.compiled_loops.ClosedLoops` on the spatial plant's symbols).
"""
from __future__ import annotations

import os
import time
from typing import Any, Mapping, Sequence

import numpy as np

from .compiled_scene import CompiledScene
from .compiled_spatial_guard import replay_failure
from .control.controlled_model import ControlledModel
from .control.loop_rows import loop_unit
from .errors import ModelError, SimulationError
from .planar.guards import check_stored, divergence_guard
from .planar.integrate import check_store_every, initial_coordinates, model_signals, step_total
from .results import SimulationResult
from .spatial.integrate import divergence_check
from .spatial.model import SpatialModel
from .signal_results import SignalSystem, signal_result

__all__ = ["add_loop_signals", "first_loop_failure", "loop_state_failure", "simulate_controlled_generated",
           "simulate_spatial_controlled_generated"]


def simulate_controlled_generated(controlled: ControlledModel, q0: Any, qdot0: Any, *, t_final: float, dt: float,
                                  inputs: Mapping[str, Any] | None = None,
                                  references: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                                  store_every: int = 1, divergence_bound: float | None = None,
                                  stability_check: str = "warn", cache_dir: str | os.PathLike | None = None,
                                  scene: CompiledScene | None = None,
                                  ran: tuple[np.ndarray, float] | None = None) -> SimulationResult:
    """Fixed-step RK4 of ``controlled`` with its loops closed in generated C.

    Parameters
    ----------
    controlled : ControlledModel
        Plant and loops (:mod:`ctmm.compiled_loops` lists what compiles).
    q0, qdot0 : array_like
        Initial coordinates [rad, m] and rates.
    t_final, dt : float
        End time and step [s]: ``t_final`` a whole multiple of ``dt``, and each loop delay too.
    inputs : mapping, optional
        ``{actuator: number or ctmm.signals signal}`` open-loop actuator values [SI].
    references : mapping, optional
        ``{loop: number or ctmm.signals signal}`` [sensed unit].
    outputs : sequence of str
        Sensor names stored at every row.
    store_every : int
        Keep every ``store_every``-th step (the last one always).
    divergence_bound, stability_check
        As in :func:`ctmm.control.planar_time.simulate_closed_loop` (the step checked against the
        plant's linearised limit, loops not included; the bound and modal beams' deflection on the stored
        rows after the run).
    cache_dir : path, optional
        Of :func:`ctmm.codegen.shared_library`.
    scene : CompiledScene, optional
        A scene of ``controlled`` built with this step, ``store_every``, inputs and references, to reuse.
    ran : (ndarray, float), optional
        The stored states of this run and its wall time [s], computed already as one member of a batch
        (:mod:`ctmm.batch_loops`; the scene's :meth:`~ctmm.compiled_scene.CompiledScene.run` is not called).

    Returns
    -------
    SimulationResult
        Method label ``"rk4-generated"``; ``info["compile_time_s"]``, ``info["loops"]``.

    Raises
    ------
    ModelError
        What the generated kernel cannot do (named), bad arguments, no compiler.
    SimulationError
        Divergence or non-finite states, with ``partial_result``.
    """
    if not isinstance(controlled, ControlledModel):
        raise ModelError(f"simulate_controlled_generated: controlled must be a ctmm.control.ControlledModel, got "
                         f"{controlled!r}")
    model = controlled.plant
    q, v = initial_coordinates(model, q0, qdot0)
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps
    store_every = check_store_every(store_every)
    if scene is None:
        scene = CompiledScene(controlled, store_every=store_every, cache_dir=cache_dir, dt=h, references=references,
                              signals=inputs)
    elif not isinstance(scene, CompiledScene) or scene.controlled is not controlled or \
            scene.store_every != store_every:
        raise ModelError(f"scene must be a CompiledScene of this controlled model with store_every={store_every!r}, "
                         f"got {scene!r}")
    guard = divergence_guard(model, q, divergence_bound)
    t, full, wall = scene.checked_run(q, v, h, n_steps, stability_check, ran=ran)
    n = model.n_coordinates
    signals_of = scene.loops.signals()
    info = {"dt": h, "method": "rk4-generated", "compile_time_s": scene.compile_time_s, "wall_time_s": wall,
            "loops": {law.name: ("real-time" if law.steps == 0 else "history") for law in scene.loops.laws},
            "n_evaluations": 4 * n_steps}

    def result(rows: int) -> SimulationResult:
        time, block = t[:rows], full[:rows]
        signals, units = model_signals(model, time, block[:, :n], block[:, n:2 * n], outputs)
        extra = add_loop_signals(controlled, scene.loops, signals_of, block, time, signals, units)
        return signal_result(SignalSystem(model, units, list(controlled.loops)), time, signals, "rk4-generated",
                             {**info, **extra})

    replay = scene.replay_step(h)
    rows = first_loop_failure(scene.loops, full)           # the plant's rules on the rows before it first
    check_stored(guard, t[:rows], full[:rows, :n], full[:rows, n:2 * n], result, model=model, step=h,
                 states=full[:rows], replay=replay)

    def plant_rules(times: np.ndarray, pair: np.ndarray) -> None:   # check_state's order: the plant, then the loops
        check_stored(guard, times, pair[:, :n], pair[:, n:2 * n], lambda _: result(rows), model=model, step=h)
    if rows < len(t):
        raise loop_state_failure(scene.loops, t, full, rows, h, replay, plant_rules, result)
    return result(len(t))


def simulate_spatial_controlled_generated(controlled: ControlledModel, q0: np.ndarray, v0: np.ndarray, *,
                                          t_final: float, dt: float, inputs: Mapping[str, Any] | None = None,
                                          references: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                                          store_every: int = 1, divergence_bound: float | None = None,
                                          cache_dir: str | os.PathLike | None = None,
                                          scene: Any = None, ran: tuple[np.ndarray, float] | None = None
                                          ) -> SimulationResult:
    """Fixed-step RK4 of a controlled spatial model with its loops closed in generated C.

    Parameters
    ----------
    controlled : ControlledModel
        A spatial plant and its loops (:mod:`ctmm.compiled_spatial_loops`).
    q0, v0 : ndarray
        Initial coordinates and velocities (checked by the caller).
    t_final, dt : float
        End time and step [s]: ``t_final`` and each loop delay whole multiples of ``dt``.
    inputs, references : mapping, optional
        ``{actuator: value}`` open-loop port inputs [SI], ``{loop: r}`` [sensed unit]: numbers or
        symbolic signals.
    outputs : sequence of str
        Sensor names stored at every row.
    store_every : int
        Keep every ``store_every``-th step (the last one always).
    divergence_bound : float, optional
        Largest allowed distance of a coordinate or velocity from its start (checked on the stored rows).
    cache_dir : path, optional
        Of :func:`ctmm.codegen.shared_library`.
    scene : CompiledControlledSpatial, optional
        A compiled kernel of ``controlled`` with this step, ``store_every``, inputs and references, to reuse.
    ran : (ndarray, float), optional
        The stored states of this run and its wall time [s], computed already as one member of a batch
        (:mod:`ctmm.batch_loops`; the scene's ``run`` is not called).

    Returns
    -------
    SimulationResult
        As :func:`ctmm.control.planar_time.simulate_closed_loop` with ``"rk4"``; method label
        ``"rk4-generated"``, ``info["compile_time_s"]``, ``info["loops"]``.

    Raises
    ------
    ModelError
        What the generated kernel cannot do (named), bad arguments, no compiler.
    SimulationError
        A non-finite or diverging stored state, or a stored state in which a flexible body leaves its bounds: the
        numpy loop driver's guard (:func:`~ctmm.spatial.integrate.divergence_check`, its message, time and
        element) on the stored rows after the run, with ``partial_result``.
    """
    from .compiled_spatial_loops import CompiledControlledSpatial
    from .control.plants import plant_of

    model = controlled.plant
    if not isinstance(model, SpatialModel):
        raise ModelError(f"simulate_spatial_controlled_generated: the plant must be a spatial model, got {model!r}")
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps
    store_every = check_store_every(store_every)
    if scene is None:
        scene = CompiledControlledSpatial(controlled, h, references=references, inputs=inputs,
                                          store_every=store_every, cache_dir=cache_dir)
    elif not isinstance(scene, CompiledControlledSpatial) or scene.controlled is not controlled or \
            scene.store_every != store_every:
        raise ModelError(f"scene must be a CompiledControlledSpatial of this controlled model with store_every="
                         f"{store_every!r}, got {scene!r}")
    if ran is None:
        start = time.perf_counter()
        first, states = scene.run(q0, v0, h, n_steps)
        wall = time.perf_counter() - start
    else:                               # one member of a batch: the initial state as scene.run states it
        first, (states, wall) = scene.loops.initial_state(np.asarray(q0, float), np.asarray(v0, float)), ran
    steps = np.array([k for k in range(1, n_steps + 1) if k % store_every == 0 or k == n_steps])[:len(states)]
    t = np.concatenate([[0.0], steps * h])
    full = np.vstack([first[None], states])
    nq, nv = model.n_positions, model.n_velocities
    plant, signals_of = plant_of(model), scene.loops.signals()
    info = {"dt": h, "method": "rk4-generated", "compile_time_s": scene.compile_time_s, "wall_time_s": wall,
            "loops": {law.name: ("real-time" if law.steps == 0 else "history") for law in scene.loops.laws},
            "n_evaluations": 4 * n_steps}

    def result(rows: int) -> SimulationResult:
        time_rows, block = t[:rows], full[:rows]
        signals, units = plant.signals(time_rows, block[:, :nq], block[:, nq:nq + nv], outputs)
        extra = add_loop_signals(controlled, scene.loops, signals_of, block, time_rows, signals, units)
        return signal_result(SignalSystem(model, units, list(controlled.loops)), time_rows, signals, "rk4-generated",
                             {**info, **extra})

    rows = first_loop_failure(scene.loops, full)           # the plant's rules on the rows before it first
    check = divergence_check(model, full[0, :nq + nv], divergence_bound)
    try:                                # the numpy loop driver's guard (the plant's): bound, finiteness, beams
        check(t[:rows], full[:rows, :nq + nv], "rk4")
    except SimulationError as exc:      # on the stored rows; the steps since the last good one replayed one by one
        k = int(np.searchsorted(t, exc.time))
        replay_failure(model, scene.plain_step, full[0], full[k - 1], np.zeros(len(scene.actuators)),
                       scene.parameters, h, int(round(t[k - 1] / h)), int(round(t[k] / h)), divergence_bound,
                       lambda: result(k), label="rk4", size=nq + nv)
        exc.partial_result = result(k)
        raise
    if rows < len(t):
        held = np.zeros(len(scene.actuators))
        raise loop_state_failure(
            scene.loops, t, full, rows, h,
            lambda state, k: np.asarray(scene.plain_step(state, held, h, scene.parameters, 0.0, float(k))).reshape(-1),
            lambda times, pair: check(times[-1], pair[-1, :nq + nv], "rk4", lambda: result(rows)), result)
    return result(len(t))


def first_loop_failure(loops: Any, states: np.ndarray, first: int | None = None) -> int:
    """The index of the first stored row of ``states`` (rows, a generated state carrying the loop entries of
    :class:`~ctmm.compiled_loops.ClosedLoops` ``loops`` from its entry ``first``, default ``loops.base``: controller
    states law by law, then their other entries and delay ring) whose loop entries are non-finite; the number of
    rows if none."""
    bad = ~np.all(np.isfinite(states[:, loops.base if first is None else first:]), axis=1)
    return int(np.argmax(bad)) if np.any(bad) else len(states)


def loop_state_failure(loops: Any, times: np.ndarray, states: np.ndarray, row: int, dt: float,
                       step: Any, plant_rules: Any, result: Any, first: int | None = None) -> SimulationError:
    """The numpy loop driver's error (:func:`ctmm.control.planar_time.simulate_closed_loop`, the schemes'
    :class:`ctmm.control.implicit_loops` step end) for the stored row ``row`` of ``states`` at ``times`` [s], the
    first with non-finite loop entries (:func:`first_loop_failure`, ``first`` as there): the steps of ``dt`` [s]
    since the stored row before are run again one at a time (``step(state, k)``: the state after step ``k``; ``None``:
    reported at the stored row), each
    checked as the numpy path checks every step -- the plant first (``plant_rules(times, pair)`` on the states
    before and after the step: raises its error), then each loop's controller states, named by loop (the other
    entries alone: the whole loop state); the partial result ``result(row)``."""
    start = loops.base if first is None else first
    state, failed_at = states[row - 1], float(times[row])
    for k in range(int(round(times[row - 1] / dt)), int(round(times[row] / dt))) if step is not None else ():
        previous, state = state, np.asarray(step(state, k), dtype=float).reshape(-1)
        plant_rules(np.array([k * dt, (k + 1) * dt]), np.vstack([previous, state]))
        if not np.all(np.isfinite(state[start:])):
            failed_at = (k + 1) * dt
            break
    else:
        state = states[row]
    offset = start
    for law in loops.laws:
        size = law.A.shape[0]
        if not np.all(np.isfinite(state[offset:offset + size])):
            return SimulationError(f"non-finite controller state of loop {law.name!r} at t = {failed_at:.6g} s",
                                   time=failed_at, element=law.name, partial_result=result(row))
        offset += size
    return SimulationError(f"non-finite controller state or delay history at t = {failed_at:.6g} s", time=failed_at,
                           partial_result=result(row))


def add_loop_signals(controlled: ControlledModel, loops: Any, signals_of: Any, block: np.ndarray, time: np.ndarray,
                      signals: dict, units: dict) -> dict:
    """Add ``"<loop>.y"``, ``"<loop>.u"`` and, for a saturating loop, ``"<loop>.u_demand"`` and
    ``"<loop>.saturated"`` of the stored rows ``block`` at ``time`` [s] (as the numpy path); returns the
    ``info`` entry ``time_saturated_s`` (seconds at a limit, summed over the rows) when there is one."""
    y, u, demand = signals_of(block, time, demand=True)
    saturated_time = {}
    for k, law in enumerate(loops.laws):
        loop = controlled.loop(law.name)
        signals[f"{law.name}.y"], signals[f"{law.name}.u"] = y[:, k], u[:, k]
        units[f"{law.name}.y"] = loop_unit(controlled.ports, loop, "y")
        units[f"{law.name}.u"] = loop_unit(controlled.ports, loop, "u")
        if law.saturation is not None:
            at_limit = (demand[:, k] < law.saturation[0]) | (demand[:, k] > law.saturation[1])
            signals[f"{law.name}.u_demand"], units[f"{law.name}.u_demand"] = demand[:, k], units[f"{law.name}.u"]
            signals[f"{law.name}.saturated"], units[f"{law.name}.saturated"] = at_limit.astype(float), ""
            saturated_time[law.name] = float(np.sum(np.diff(time)[at_limit[:-1]])) if len(time) > 1 else 0.0
    return {"time_saturated_s": saturated_time} if saturated_time else {}
