"""Runs of the generated DT-TMM step of 1-D lumped chains (issue 13): ``ctmm.simulate(chain, method=<scheme>,
compiled=True)``.

:func:`simulate_scheme_verb` refuses by name the verb's options that do not apply (:func:`check_scheme_options`)
and calls :func:`simulate_chain_scheme_generated`, which compiles (or reuses) the step of
:class:`ctmm.compiled_chain_schemes.CompiledChainScheme`, runs it from the chain's start, checks the stored rows with
the chain's guard (a :class:`~ctmm.errors.SimulationError` carries the rows before the failure) and reads them as a
result with :func:`scheme_result` (also the result of co-simulated runs, :mod:`ctmm.compiled_cosim`): point signals
of the equation of motion at the stored states, and each loop's ``y`` and ``u``.
"""
from __future__ import annotations

import os
import time as _time
from typing import Any, Mapping, Sequence

import numpy as np

from .chain_ode import chain_result
from .compiled_chain import whole_steps
from .compiled_chain_scheme_nodes import node_guard, node_result
from .compiled_chain_schemes import CompiledChainScheme
from .control.loop_rows import loop_unit
from .errors import ModelError, SimulationError
from .guard import unstable_loops_hint
from .results import SimulationResult
from .schemes import as_scheme
from .signal_results import SignalSystem, signal_result
from .step_limit import check_scheme_step

__all__ = ["check_scheme_options", "scheme_result", "simulate_chain_scheme_generated", "simulate_scheme_verb"]


def simulate_chain_scheme_generated(system: Any, t_final: float, dt: float, scheme: Any = "newmark", *,
                                    x0: Mapping[str, float] | None = None, v0: Mapping[str, float] | None = None,
                                    references: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                                    store_every: int = 1, divergence_bound: float | None = None,
                                    cache_dir: str | os.PathLike | None = None,
                                    compiled: CompiledChainScheme | None = None) -> SimulationResult:
    """A DT-TMM scheme on a chain (with its loops) in generated C.

    Parameters
    ----------
    system : Chain or ControlledChain
    t_final, dt : float
        End time and step [s] (``t_final`` and each loop delay whole multiples of ``dt``).
    scheme : Scheme or str
    x0, v0 : mapping, optional
        Initial positions [m] / velocities [m/s] by element name.
    references : mapping, optional
        ``{loop: number or signal}`` [sensed unit].
    outputs : sequence of str
        Extra signal names (every chain signal is stored).
    store_every : int
        Keep every ``store_every``-th step (the last one always).
    divergence_bound : float, optional
        As in :func:`ctmm.chain_ode.simulate_chain_ode` (checked on the stored rows).
    cache_dir : path, optional
    compiled : CompiledChainScheme, optional
        A compiled kernel of this system, step, scheme, references and ``store_every`` to reuse.

    Returns
    -------
    SimulationResult
        The point signals of :func:`ctmm.chain_ode.simulate_chain_ode` (with loops: named signals and
        ``"<loop>.y"``, ``"<loop>.u"``); ``info["method"]`` is ``"<scheme>-generated"``, with
        ``info["compile_time_s"]`` [s].

    Raises
    ------
    ModelError
        Bad arguments, no compiler, or what the generated step cannot do (named).
    SimulationError
        A diverging or non-finite state (``partial_result``: the rows before it).
    """
    t_final, dt, n_steps = whole_steps(t_final, dt)
    if compiled is None:
        compiled = CompiledChainScheme(system, dt, scheme, store_every=store_every, references=references,
                                       cache_dir=cache_dir)
    elif not isinstance(compiled, CompiledChainScheme) or compiled.dt != dt or compiled.store_every != store_every \
            or compiled.scheme != as_scheme(scheme):
        raise ModelError(f"compiled must be a CompiledChainScheme of this chain with dt={dt!r}, scheme={scheme!r} and "
                         f"store_every={store_every!r}, got {compiled!r}")
    for name in outputs:
        system.signal(name)
    check_scheme_step(compiled.plant.chain, compiled.scheme, dt, None)     # the scheme's step limit, as in Python
    first = compiled.start(x0, v0)
    started = _time.perf_counter()
    states = compiled.run(first, n_steps)
    wall = _time.perf_counter() - started
    every, m = compiled.store_every, compiled.m
    steps = np.array([k for k in range(1, n_steps + 1) if k % every == 0 or k == n_steps])[:len(states)]
    times = np.concatenate([[0.0], steps * dt])
    states = np.vstack([first[None], states])
    label = f"{compiled.scheme.name}-generated"
    info = {"dt": dt, "method": label, "path": "generated-dttmm", "compile_time_s": compiled.compile_time_s,
            "wall_time_s": wall, "n_steps": n_steps}
    if compiled.nodes is not None:
        guard, passes = node_guard(compiled.dynamics, compiled.nodes, states, divergence_bound)
    else:
        hint = unstable_loops_hint([lp.loop.name for lp in compiled.loops]) if compiled.loops else ""
        plant_check = compiled.plant.guard(states[0, :m], divergence_bound, hint=hint)    # the numpy path's message
        guard = lambda t, k: plant_check(t, states[k, :2 * m], dt, label)                   # noqa: E731
        passes = compiled.plant.guard_screen(states[0, :m], divergence_bound, hint=hint)(times, states[:, :2 * m])
    for k in np.flatnonzero(~passes).tolist():          # the rows the screen refuses: the guard names the first
        try:
            guard(float(times[k]), k)
        except SimulationError as exc:
            exc.partial_result = scheme_result(compiled, times[:k], states[:k], outputs, info)
            raise
    return scheme_result(compiled, times, states, outputs, info)


def scheme_result(compiled: CompiledChainScheme, times: np.ndarray, states: np.ndarray, outputs: Sequence[str],
                  info: dict, held: Sequence[Mapping[str, float]] | None = None) -> SimulationResult:
    """The stored rows as a result: point signals from the states (accelerations and forces of the equation of
    motion with the loops' forces and the ``held`` inputs ``{actuator: value}`` [N] of each row), and each loop's
    ``y`` and ``u``."""
    m, label = compiled.m, info["method"]
    if compiled.nodes is not None:
        steps = np.rint(np.asarray(times, float) / compiled.dt).astype(int)
        return node_result(compiled.dynamics, compiled.nodes, times, steps, states, compiled.dt, compiled.consistent,
                           label, info)
    if not compiled.loops and held is None:
        return chain_result(compiled.dynamics, list(times), list(states[:, :2 * m]), label, dict(info))
    forces = np.array([compiled.loop_forces(float(t), row) for t, row in zip(times, states)])
    forces = forces.reshape(len(times), len(compiled.loops))
    inputs = [compiled.actuator_inputs(row, None if held is None else held[k]) for k, row in enumerate(forces)]
    plant, system = compiled.plant, compiled.system
    signals, units = plant.signals(times, states[:, :m], states[:, m:2 * m], outputs, inputs=inputs)
    for j, lp in enumerate(compiled.loops):
        name = lp.loop.name
        signals[f"{name}.y"] = states[:, :2 * m] @ lp.row + lp.offset
        signals[f"{name}.u"] = forces[:, j]
        units[f"{name}.y"], units[f"{name}.u"] = loop_unit(plant.ports, lp.loop, "y"), loop_unit(plant.ports, lp.loop,
                                                                                                  "u")
    info = {**info, "loops": {lp.loop.name: ("real-time" if lp.steps == 0 else "history") for lp in compiled.loops}}
    return signal_result(SignalSystem(system, units, list(getattr(system, "loops", ()))), times, signals, label, info)


def simulate_scheme_verb(system: Any, t_final: float, dt: float | None, scheme: Any, x0: Any, v0: Any,
                         store_every: int, divergence_bound: float | None, others: Mapping[str, tuple], *,
                         t0: float, inputs: Any, outputs: Any, references: Mapping[str, Any]) -> SimulationResult:
    """``ctmm.simulate(chain, method=<scheme>, compiled=True)``: the options that do not apply are refused by
    name (``others``: ``{name: (value, default)}`` of the verb), then :func:`simulate_chain_scheme_generated`."""
    check_scheme_options(dt, {**others, "t0": (t0, 0.0), "inputs": (inputs or None, None)})
    return simulate_chain_scheme_generated(system, t_final, dt, scheme, x0=x0, v0=v0, references=references or None,
                                           outputs=tuple(outputs), store_every=store_every,
                                           divergence_bound=divergence_bound)


def check_scheme_options(dt: float | None, options: Mapping[str, tuple]) -> None:
    """Refuse, by name, the options ``{name: (value, default)}`` of :func:`ctmm.simulate` that do not apply to the
    generated DT-TMM step of a chain (any value but the default), and a missing ``dt``."""
    for name, (value, default) in options.items():
        if value is not default and value != default:
            other = "an ODE method ('rk4' or a solve_ivp one)" if name == "inputs" else "compiled=False"
            raise ModelError(f"{name}={value!r} does not apply to the generated DT-TMM step of a chain (leave {name} "
                             f"at {default!r}, or use {other})")
    if dt is None:
        raise ModelError("dt is required to simulate a chain (the DT-TMM step [s], > 0), got None")
