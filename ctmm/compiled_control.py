"""RK4 of a controlled planar model with its loops closed inside generated C (issue 13).

:func:`simulate_controlled_generated` is what ``ctmm.simulate(controlled_model, ..., compiled=True)``
runs: one :class:`~ctmm.compiled_scene.CompiledScene` of the
:class:`~ctmm.control.controlled_model.ControlledModel` (the loops stated by
:class:`~ctmm.compiled_loops.ClosedLoops`), one call per block of stored rows, and the same result
as the numpy path of :func:`ctmm.control.planar_time.simulate_closed_loop` -- coordinates, rates,
``outputs``, ``"<loop>.y"`` and ``"<loop>.u"`` -- equal to it to round-off.
"""
from __future__ import annotations

import os
from typing import Any, Mapping, Sequence

import numpy as np

from .compiled_scene import CompiledScene
from .control.controlled_model import ControlledModel
from .control.planar_time import loop_unit
from .errors import ModelError, SimulationError
from .planar.guards import check_stored, divergence_guard
from .planar.integrate import check_store_every, initial_coordinates, model_signals, step_total
from .results import SimulationResult
from .signal_results import SignalSystem, signal_result

__all__ = ["simulate_controlled_generated"]


def simulate_controlled_generated(controlled: ControlledModel, q0: Any, qdot0: Any, *, t_final: float, dt: float,
                                  inputs: Mapping[str, Any] | None = None,
                                  references: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                                  store_every: int = 1, divergence_bound: float | None = None,
                                  stability_check: str = "warn", cache_dir: str | os.PathLike | None = None,
                                  scene: CompiledScene | None = None) -> SimulationResult:
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
        plant's linearised limit, loops not included; the bound on the stored rows after the run).
    cache_dir : path, optional
        Of :func:`ctmm.codegen.shared_library`.
    scene : CompiledScene, optional
        A scene of ``controlled`` built with this step, ``store_every``, inputs and references, to reuse.

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
    t, full, wall = scene.checked_run(q, v, h, n_steps, stability_check)
    n = model.n_coordinates
    signals_of = scene.loops.signals()
    info = {"dt": h, "method": "rk4-generated", "compile_time_s": scene.compile_time_s, "wall_time_s": wall,
            "loops": {law.name: ("real-time" if law.steps == 0 else "history") for law in scene.loops.laws},
            "n_evaluations": 4 * n_steps}

    def result(rows: int) -> SimulationResult:
        time, block = t[:rows], full[:rows]
        signals, units = model_signals(model, time, block[:, :n], block[:, n:2 * n], outputs)
        y, u = signals_of(block, time)
        for k, law in enumerate(scene.loops.laws):
            loop = controlled.loop(law.name)
            signals[f"{law.name}.y"], signals[f"{law.name}.u"] = y[:, k], u[:, k]
            units[f"{law.name}.y"] = loop_unit(controlled.ports, loop, "y")
            units[f"{law.name}.u"] = loop_unit(controlled.ports, loop, "u")
        return signal_result(SignalSystem(model, units, list(controlled.loops)), time, signals, "rk4-generated", info)

    check_stored(guard, t, full[:, :n], full[:, n:2 * n], result)
    controller = full[:, 2 * n:]
    if not np.all(np.isfinite(controller)):
        k = int(np.flatnonzero(~np.all(np.isfinite(controller), axis=1))[0])
        raise SimulationError(f"non-finite controller state or delay history at t = {t[k]:.6g} s", time=float(t[k]),
                              partial_result=result(k))
    return result(len(t))
