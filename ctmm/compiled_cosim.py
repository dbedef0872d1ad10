"""Co-simulated controllers (Python objects, FMUs) around generated kernels: ``compiled=True`` with ``controllers``.

:func:`simulate_cosimulated_generated` is what ``ctmm.simulate(model, ..., compiled=True, controllers=[...])`` runs
on a planar or spatial model, plain or controlled (its :class:`~ctmm.control.loops.Feedback` loops closed inside
the generated step), and on a lumped 1-D chain, plain or a :class:`~ctmm.control.loops.ControlledChain` (the
generated RK4 of :mod:`ctmm.compiled_chain`).  The controllers are sampled on the step grid and their outputs held
(zero-order hold), so between two sample instants the plant is a run of the generated RK4 with the held outputs as
its actuator inputs ``u``: one call into C per sample interval (:meth:`ctmm.compiled_scene.CompiledScene.continue_run`,
:meth:`ctmm.compiled_spatial_loops.CompiledControlledSpatial.continue_run`,
:meth:`ctmm.compiled_chain.CompiledChain.continue_run`, continued at the interval's step
index so that delayed loops' rings and time signals run on), and at each sample instant the one co-simulation
master :class:`~ctmm.control.cosim.CoSimulation` calls the controllers in Python exactly as the numpy path
(:func:`ctmm.control.planar_time.simulate_closed_loop`) does: the same sample instants, coupling policy,
failure messages and ``"<output>@samples"`` records.  The result equals the numpy path's to round-off
(``tests/test_compiled_cosim.py``).  A plant whose stored signals need each row's actuator values (a planar
kinematic loop model's cut forces, ``signals_need_inputs``) gets them from the scene's ``applied_inputs``
(:class:`ctmm.compiled_kinematic_loop_control.CompiledKinematicLoopControl`).

With a DT-TMM scheme on a chain (``method="newmark"``, ... ``compiled=True``), :func:`simulate_cosimulated_scheme`
does the same around the generated scheme step (:mod:`ctmm.compiled_chain_schemes`, the held outputs its input
``u``) with the Python DT-TMM path's sampling (:func:`ctmm.control.simulate.simulate_controlled`: sampled at
``t = 0`` before the start acceleration, the history's acceleration restarted by ``M^-1 dF`` where a held output
jumps).  The generated schemes of planar and spatial models take co-simulated controllers in
:mod:`ctmm.compiled_scheme_cosim`.

A :class:`~ctmm.control.measurement_delay.DelayedController` reads its inputs ``delay`` seconds late from the
states of the run; the delay must be a whole multiple of ``dt`` here (the numpy path interpolates its delay
history between steps; on the grid both read the stored step).  Before ``t = 0`` the initial state is held.
Controller outputs must drive actuators of the generated kernel (planar: beam station forces and moments that
controllers drive are inputs of the scene, ``station_inputs`` of :class:`~ctmm.compiled_scene.CompiledScene`).
A chain's divergence guard is its own (point positions from rest, :class:`~ctmm.control.chain_plant.ChainPlant`), checked at
every step as on the numpy path; so are a planar model's modal beams and a spatial model's beams (each row through the
plant's guard: the numpy path's rules and messages), and a kinematic loop model's bound is its tree's coordinates.
"""
from __future__ import annotations

import math
import operator
import time as clock
from collections import deque
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from . import validation
from .compiled_chain import chain_loop_signals
from .compiled_control import add_loop_signals
from .compiled_parameters import station_loads
from .control.chain_plant import ChainPlant
from .control.controlled_model import ControlledModel
from .control.cosim import CoSimulation, check_wiring
from .control.loop_rows import empty_result
from .control.loops import ControlledChain
from .control.plants import plant_of
from .errors import ModelError, SimulationError
from .generated_loop import BlockRunner
from .planar.guards import divergence_guard, with_partial
from .planar.integrate import check_store_every, step_total
from .planar.model import PlanarModel
from .progress import progress_bar
from .results import SimulationResult
from .signal_results import SignalSystem, signal_result
from .spatial.integrate import beam_deflection_weights
from .spatial.model import SpatialModel

__all__ = ["sampled_run", "simulate_cosimulated_generated", "simulate_cosimulated_scheme", "stored_offsets"]


def _scene(controlled: Any, dt: float, controllers: Sequence[Any], inputs: Mapping[str, Any],
           references: Mapping[str, Any]) -> Any:
    """The generated kernel of ``controlled`` (a ControlledModel or a ControlledChain; every step stored) whose
    actuator inputs include every controller output."""
    held = {name: 0.0 for c in controllers for name in c.outputs if name not in inputs}
    if isinstance(controlled, ControlledChain):
        from .compiled_chain import CompiledChain

        return CompiledChain(controlled, dt=dt, store_every=1, references=references, inputs={**inputs, **held})
    if isinstance(controlled.plant, SpatialModel):
        from .compiled_spatial_loops import CompiledControlledSpatial

        return CompiledControlledSpatial(controlled, dt, references=references, inputs={**inputs, **held},
                                         store_every=1)
    from .compiled_scene import CompiledScene

    outputs = [name for c in controllers for name in c.outputs]         # beam station loads among them: inputs too
    return CompiledScene(controlled, store_every=1, dt=dt, references=references, signals=inputs,
                         station_inputs=station_loads(controlled.plant, outputs))


def _delay_steps(controller: Any, dt: float) -> int:
    """A controller's measurement delay in steps (0 without one); a delay off the step grid is refused."""
    delay = validation.nonnegative("controller measurement_delay", getattr(controller, "measurement_delay", 0.0))
    steps = int(round(delay / dt))
    if abs(steps * dt - delay) > 1e-9 * max(delay, dt):
        raise ModelError(f"controller with outputs {list(controller.outputs)}: measurement_delay = {delay!r} s is "
                         f"not a whole multiple of dt = {dt!r} s, which compiled=True needs (it reads the stored "
                         "step); choose such a delay or dt, or run with compiled=False")
    return steps


def simulate_cosimulated_generated(model: Any, loops: Sequence[Any], q0: np.ndarray, v0: np.ndarray, *,
                                   t_final: float, dt: float, controllers: Sequence[Any],
                                   inputs: Mapping[str, Any] | None = None,
                                   references: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                                   coupling: str = "hold", store_every: int = 1, progress: bool | None = None,
                                   stability_check: str = "warn", divergence_bound: float | None = None,
                                   scene: Any = None) -> SimulationResult:
    """Fixed-step RK4 in generated C between the samples of co-simulated controllers (module docstring).

    Parameters
    ----------
    model : PlanarModel, SpatialModel, Chain or ControlledChain
        The plant (compilable: :func:`ctmm.compiled_scene.compile_refusal`,
        :func:`ctmm.compiled_spatial.spatial_compile_refusal`, :class:`ctmm.compiled_chain.CompiledChain`); a
        ControlledChain carries its loops.
    loops : sequence of Feedback
        Loops closed inside the generated step (may be empty; a chain's: ``model.loops``).
    q0, v0 : ndarray
        Initial coordinates and velocities (checked by the caller; planar: ``v = qdot``; a chain: positions [m]
        and velocities [m/s] of its masses, :meth:`ctmm.control.chain_plant.ChainPlant.start`).
    t_final, dt : float
        End time and step [s]: ``t_final``, every sample time and every delay whole multiples of ``dt``.
    controllers : sequence of Controller
        Co-simulated controllers (validated by the caller, :func:`ctmm.control.protocol.check_controllers`).
    inputs, references : mapping, optional
        ``{actuator: value}`` [SI] and ``{loop: r}`` [sensed unit]: numbers or symbolic signals.
    outputs : sequence of str
        Sensor names stored at every row.
    coupling : {"hold", "previous"}
        As in :class:`~ctmm.control.cosim.CoSimulation`.
    store_every : int
        Keep every ``store_every``-th step (the last one always).
    progress : bool, optional
        Progress bar over the steps (long runs on a terminal by default).
    stability_check : {"warn", "error", "ignore"}
        The step against the plant's linearised RK4 limit before the run (as the numpy path).
    divergence_bound : float, optional
        As in :func:`ctmm.control.planar_time.simulate_closed_loop`, checked at every step: planar, the coordinates
        from ``q0`` (default ``1e6 max(1, .)``); spatial, ``q`` and ``v`` from the start (default none); a chain,
        its guard (point positions from rest).
    scene : compiled scene, optional
        The kernel to run (every step stored, the controllers' outputs among its actuators): a parameter
        set's scene on a shared kernel (:meth:`ctmm.batch.ParameterKernel.run`); by default compiled here.

    Returns
    -------
    SimulationResult
        As the numpy path: coordinates, rates, ``outputs``, ``"<loop>.y"``, ``"<loop>.u"`` and
        ``"<controller output>@samples"``; method label ``"rk4-generated"``, ``info["compile_time_s"]``,
        ``info["controllers"]``, ``info["intervals"]`` (calls into C).

    Raises
    ------
    ModelError
        What the generated kernel cannot do (named), bad wiring, an algebraic loop, no compiler.
    SimulationError
        Failing controller code, divergence or non-finite states, with ``partial_result``.
    """
    plant = plant_of(model)
    ports = plant.ports
    n_steps = step_total(t_final, dt)
    store_every = check_store_every(store_every)
    inputs, references = dict(inputs or {}), dict(references or {})
    for c in controllers:
        label = f"controller {getattr(c, 'name', None) or type(c).__name__!r}"
        for name in c.inputs:
            ports.check_sensor(name, f"input of {label}")
        for name in c.outputs:
            ports.check_actuator(name, f"output of {label}")
    check_wiring(controllers, None, None, dt)      # the one rule (before compiling): one controller per actuator
    delays = [_delay_steps(c, dt) for c in controllers]
    chain = isinstance(plant, ChainPlant)
    rows_need_inputs = not chain and getattr(plant, "signals_need_inputs", False)   # cut forces: scene.applied_inputs
    if chain and tuple(loops) != tuple(getattr(model, "loops", ())):
        raise ModelError("simulate_cosimulated_generated: a chain's loops are those of its ControlledChain; give "
                         "loops=model.loops")
    controlled = (model if isinstance(model, ControlledChain) else ControlledChain(model, ())) if chain \
        else ControlledModel(model, loops)
    scene = _scene(controlled, dt, controllers, inputs, references) if scene is None else scene
    for c in controllers:
        for name in c.outputs:
            if name not in scene.actuators:
                raise ModelError(f"compiled=True: controller output {name!r} is not an input of the generated "
                                 f"kernel (it drives {', '.join(scene.actuators) or 'none'}); run with compiled=False")
    plant.check_step(q0, v0, dt, stability_check)
    sensors = [ports.resolve(list(c.inputs)) for c in controllers]
    index = {name: k for k, name in enumerate(scene.actuators)}
    nq, nv = plant.n_positions, plant.n_velocities
    first = scene.loops.initial_state(np.asarray(q0, float), np.asarray(v0, float))
    guard = plant.guard(q0, divergence_bound, v0)
    screen = None if chain else _guard_screen(plant, q0, first, divergence_bound)    # None: each row to the guard
    if screen is not None:
        watched, reference, bound = screen
        reference_list = reference.tolist()
    label = "rk4-generated" if chain else "rk4"     # the numpy path's label in the plant's own messages
    history: deque = deque(maxlen=max(delays, default=0) + 1)     # (step, state) of the delayed reads
    history.append((0, first))
    times: list[float] = []                                       # the stored rows, from t = 0 once sampled
    rows: list[np.ndarray] = []
    held_rows: list[dict[str, float]] = []                         # a chain's held controller outputs per row
    info = {"dt": dt, "method": "rk4-generated", "compile_time_s": scene.compile_time_s,
            "loops": {law.name: ("real-time" if law.steps == 0 else "history") for law in scene.loops.laws}}
    done = [0]                                                    # steps run

    try:
        master = CoSimulation(controllers, dt, 0.0, coupling=coupling, measurement_delays=True)
    except SimulationError as exc:          # a controller's init failed: nothing was simulated
        raise with_partial(exc, lambda: empty_result(plant, model, loops, outputs, "rk4-generated", info)) \
            from exc.__cause__
    start = clock.perf_counter()

    def result(count: int) -> SimulationResult:
        t, block = np.array(times[:count]), np.array(rows[:count], dtype=float).reshape(count, first.size)
        if chain:
            signals, units, extra = chain_loop_signals(model, scene, t, block, outputs, held_rows[:count])
        else:
            signals, units = plant.signals(t, block[:, :nq], block[:, nq:nq + nv], outputs, **(
                {"inputs": scene.applied_inputs(t, block, held_rows[:count])} if rows_need_inputs else {}))
            extra = add_loop_signals(controlled, scene.loops, scene.loops.signals(), block, t, signals, units) \
                if scene.loops.laws else {}
        for name, samples in master.outputs(until=t[-1] if count else -math.inf).items():
            signals[name], units[name] = samples, ports.actuator_unit(name.split("@")[0])
        return signal_result(SignalSystem(model, units, list(loops)), t, signals, "rk4-generated", {
            **info, **extra, "wall_time_s": clock.perf_counter() - start, "n_evaluations": 4 * done[0],
            "controllers": master.describe(), "intervals": intervals})

    def sample(step: int, state: np.ndarray) -> None:
        t = step * dt

        def measure(i: int) -> np.ndarray:
            if delays[i]:
                then = step - delays[i]
                past = first if then <= 0 else next(y for k, y in history if k == then)
                when = max(then, 0) * dt
                return np.asarray(ports.values(sensors[i], past[:nq], past[nq:nq + nv], when), dtype=float)
            return np.asarray(ports.values(sensors[i], state[:nq], state[nq:nq + nv], t), dtype=float)

        master.sample(step, t, measure)

    def held_now() -> dict[str, float]:
        return {name: float(value) for c, outputs_held in zip(master.controllers, master.held)
                for name, value in zip(c.outputs, outputs_held)}

    def first_bad(block: np.ndarray, k: int) -> int | None:
        if screen is None:          # a chain (positions from rest), modal beams, spatial beams: the guard, every step
            finite = np.all(np.isfinite(block), axis=1).tolist()
            for j, row in enumerate(block):
                if not finite[j]:
                    return j
                try:
                    guard((k + 1 + j) * dt, row, dt, label)
                except SimulationError:
                    return j
            return None
        # the usual case first: a NaN or infinity anywhere makes a sum non-finite (an overflow of finite numbers
        # too: then the exact test below decides), so the distances compared with the bound are of finite numbers
        if len(block) == 1:                         # one row (an interval of one step): Python numbers are cheaper
            row = block[0].tolist()
            if math.isfinite(sum(row)) and max(map(abs, map(operator.sub, row[:watched], reference_list)),
                                               default=0.0) <= bound:
                return None
        with np.errstate(invalid="ignore", over="ignore"):
            if math.isfinite(block.sum()) and np.abs(block[:, :watched] - reference).max(initial=0.0) <= bound:
                return None
            bad = ~np.all(np.isfinite(block), axis=1) | (np.max(np.abs(block[:, :watched] - reference), axis=1,
                                                                initial=0.0) > bound)
        return int(np.argmax(bad)) if np.any(bad) else None

    def fail(step: int, row: np.ndarray) -> None:
        t = float(step * dt)
        guard(t, row, dt, label)                    # the plant's own message where it applies
        what = "non-finite" if not np.all(np.isfinite(row)) else f"beyond divergence_bound = {divergence_bound}"
        raise SimulationError(f"{getattr(model, 'name', 'model')}: the state (with controller states and delay "
                              f"ring) became {what} at t = {t:.6g} s (rk4-generated)", time=t,
                              element=getattr(model, "name", None))

    intervals = 0
    runner = BlockRunner()                          # the call buffers of this run's intervals, set up once
    bar = progress_bar(n_steps, f"ctmm.simulate ({plant.label}, rk4-generated)", enabled=progress)

    delays_on, per_row_inputs = any(delays), chain or rows_need_inputs

    def advance() -> None:
        nonlocal intervals
        sample(0, first)                # a controller failing here leaves no row, as on the numpy path
        times.append(0.0)
        rows.append(first)
        if per_row_inputs:
            held_rows.append(held_now())
        state, k = first, 0
        while k < n_steps:
            following = _next_sample(master, k, n_steps)
            block = scene.continue_run(state, _held_inputs(master, index), dt, following - k, k, runner=runner)
            intervals += 1
            bad = first_bad(block, k)
            good = len(block) if bad is None else bad       # the rows before the first bad one
            if delays_on:
                history.extend(zip(range(k + 1, k + 1 + good), block[:good]))
            sampled = bad is None and k + len(block) == following     # the interval's last row is a sample
            before = good - 1 if sampled else good                  # the rows stored with the interval's held outputs
            stored = stored_offsets(k, 0, before, store_every, n_steps) if before else []
            if stored:
                times.extend(float((k + 1 + j) * dt) for j in stored)
                rows.extend(block[stored])
                if per_row_inputs:
                    held_rows.extend([held_now()] * len(stored))
            done[0] = k + before
            if bad is not None:
                fail(k + 1 + bad, block[bad])
            if sampled:
                step, row = following, block[-1]
                sample(step, row)
                if step % store_every == 0 or step == n_steps:
                    times.append(float(step * dt))
                    rows.append(row)
                    if per_row_inputs:
                        held_rows.append(held_now())
            done[0] = k + len(block)
            state, k = block[-1], following
            bar.update(len(block))

    return sampled_run(advance, result, times, bar, master)


def _guard_screen(plant: Any, q0: np.ndarray, first: np.ndarray, bound: float | None
                 ) -> tuple[int, np.ndarray, float] | None:
    """The run guard of a planar or spatial plant (:meth:`~ctmm.control.plants.Plant.guard`, the numpy path's) as
    one test of a block of stored rows: ``(watched, reference, bound)``, a row passes when every entry is finite
    and its first ``watched`` entries are within ``bound`` of ``reference`` (planar: the coordinates from ``q0``,
    default ``1e6 max(1, |q0|)``, :func:`ctmm.planar.guards.divergence_guard`; spatial: ``[q ; v]`` from the
    initial state ``first``, default finiteness only, :func:`ctmm.spatial.integrate.divergence_check`; a kinematic
    loop model's: its tree's).  ``None`` where the guard checks more than that (a planar deformable family's
    deflection, spatial beams' deflection): then each row goes through the guard itself, as on the numpy path."""
    tree = getattr(plant.model, "tree", plant.model)
    if isinstance(tree, PlanarModel):
        if tree.deformable_family is not None:
            return None
        coordinates = divergence_guard(tree, np.asarray(q0, float), bound)
        return plant.n_positions, np.asarray(coordinates.reference, float), coordinates.bound
    if beam_deflection_weights(tree):
        return None
    size = plant.n_positions + plant.n_velocities
    return size, np.asarray(first[:size], float), math.inf if bound is None else float(bound)


def simulate_cosimulated_scheme(system: Any, t_final: float, dt: float | None, scheme: Any, *,
                                controllers: Sequence[Any], x0: Mapping[str, float] | None = None,
                                v0: Mapping[str, float] | None = None,
                                references: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                                coupling: str = "hold", store_every: int = 1, progress: bool | None = None,
                                stability_check: str | None = None, divergence_bound: float | None = None,
                                compiled: Any = None) -> SimulationResult:
    """A DT-TMM scheme on a chain in generated C between the samples of co-simulated controllers:
    ``ctmm.simulate(chain, method=<scheme>, compiled=True, controllers=[...])``.

    The controllers' outputs are the held input ``u`` of the generated step
    (:class:`~ctmm.compiled_chain_schemes.CompiledChainScheme` with ``actuators``): one call into C per sample
    interval, continued at the interval's step index (delayed loops' rings and load signals run on; Houbolt's
    start-up only where a held output jumps).  At each sample instant the master :class:`~ctmm.control.cosim.CoSimulation` calls the controllers exactly
    as the Python DT-TMM path (:func:`ctmm.control.simulate.simulate_controlled`) does: sampled at ``t = 0`` before
    the start acceleration (which includes their outputs), then at the end of each interval from the stored
    positions and velocities, and where a held output jumps the acceleration of the history restarts by
    ``M^-1 dF`` and a multistep scheme's start-up runs again (the Python path's restart of a lumped chain,
    :meth:`ctmm.schemes.Scheme.restart`), so the result equals the Python path's to round-off
    (``tests/test_compiled_cosim_schemes.py``).

    Parameters
    ----------
    system : Chain or ControlledChain
    t_final, dt : float
        End time and step [s] (whole multiples of ``dt``, as every sample time and loop delay).
    scheme : Scheme or str
    controllers : sequence of Controller
        Co-simulated controllers (checked by the caller, :func:`ctmm.control.protocol.check_controllers`) reading
        positions or velocities of points and writing the first input of body elements [N].  Accelerations and
        forces as controller inputs, and measurement delays, are refused (:class:`ModelError`).
    x0, v0 : mapping, optional
        Initial positions [m] / velocities [m/s] by element name.
    references : mapping, optional
        ``{loop: number or ctmm.signals signal}`` [sensed unit].
    outputs : sequence of str
        Extra signal names (every chain signal is stored).
    coupling : {"hold", "previous"}
        As in :class:`~ctmm.control.cosim.CoSimulation`.
    store_every : int
        Keep every ``store_every``-th step (the last one always).
    progress : bool, optional
        Progress bar over the steps.
    stability_check : {"warn", "error", "ignore"}, optional
        ``dt`` against the scheme's step limit of the plant (:func:`ctmm.step_limit.check_scheme_step`).
    divergence_bound : float, optional
        Largest distance [m] of a point from rest (the chain's guard, checked at every step).
    compiled : CompiledChainScheme, optional
        A kernel of this system, ``dt``, scheme and references whose ``actuators`` are the controllers' outputs
        (every step stored); by default compiled here (cached on disk).

    Returns
    -------
    SimulationResult
        The point signals (accelerations and forces of the equation of motion with the held outputs of the step
        that ended at the row), ``"<loop>.y"``, ``"<loop>.u"``, ``"<output>@samples"``; method
        ``"<scheme>-generated"``, ``info["intervals"]`` (calls into C), ``info["controllers"]``.

    Raises
    ------
    ModelError
        What the generated step or the co-simulation cannot do (named), bad wiring, no compiler.
    SimulationError
        Failing controller code, divergence or a non-finite state, with ``partial_result``.
    """
    from .compiled_chain import whole_steps
    from .compiled_chain_scheme_runs import scheme_result
    from .compiled_chain_schemes import CompiledChainScheme
    from .schemes import as_scheme
    from .step_limit import check_scheme_step

    if dt is None:
        raise ModelError("dt is required to simulate a chain (the DT-TMM step [s], > 0), got None")
    t_final, dt, n_steps = whole_steps(t_final, dt)
    store_every = check_store_every(store_every)
    policy = None if stability_check is None else validation.option("stability_check", stability_check,
                                                                    ("warn", "error", "ignore"))
    plant = ChainPlant(system)
    chain, ports = plant.chain, plant.ports
    for name in outputs:
        system.signal(name)
    sensors, driven = [], []
    for c in controllers:
        label = f"controller {getattr(c, 'name', None) or type(c).__name__!r}"
        if getattr(c, "measurement_delay", 0.0):
            raise ModelError(f"{label} declares a measurement delay, which the DT-TMM schemes of a chain do not "
                             "apply (it would be dropped); close a delayed measurement as a Feedback loop with "
                             "delay=..., or use method='rk4'")
        for name in c.inputs:
            signal = chain.signal(name)
            if signal.derivative >= 2 or signal.component != 0:
                raise ModelError(f"input {name!r} of {label}: co-simulated controllers of the generated DT-TMM step "
                                 "read positions and velocities of points (accelerations and forces come from the "
                                 "Python step's solution); measure a position or velocity, or run with "
                                 "compiled=False")
            ports.check_sensor(name, f"input of {label}")
        sensors.append(ports.resolve(list(c.inputs)))
        for name in c.outputs:
            chain.input(name)                       # the names of the Python DT-TMM path: '<element>.<input>'
            actuator = ports.actuators[ports.check_actuator(name, f"output of {label}")]
            element = chain.elements[actuator.position]
            if actuator.input != element.inputs[0]:
                raise ModelError(f"output {name!r} of {label} is not the first input of {element.name!r}, which "
                                 "co-simulated controllers cannot drive in time on a DT-TMM scheme; drivable: "
                                 + ", ".join(f"{e.name}.{e.inputs[0]}" for e in chain.body if e.inputs))
            driven.append(name)
    check_wiring(controllers, None, None, dt)      # the one rule (before compiling): one controller per actuator
    if compiled is None:
        compiled = CompiledChainScheme(system, dt, scheme, store_every=1, references=references, actuators=driven)
    elif not isinstance(compiled, CompiledChainScheme) or compiled.dt != dt or compiled.store_every != 1 or \
            compiled.scheme != as_scheme(scheme) or not set(driven) <= set(compiled.actuators):
        raise ModelError(f"compiled must be a CompiledChainScheme of this chain with dt={dt!r}, scheme={scheme!r}, "
                         f"store_every=1 and the actuators {driven}, got {compiled!r}")
    check_scheme_step(chain, compiled.scheme, dt, policy)
    m, label = compiled.m, f"{compiled.scheme.name}-generated"
    index = {name: k for k, name in enumerate(compiled.actuators)}
    lumped = chain.layout.size == 2 and all(e.lumped_coefficients() is not None for e in chain.body)
    q0, w0 = plant.start(x0, v0)
    info = {"dt": dt, "method": label, "path": "generated-dttmm", "compile_time_s": compiled.compile_time_s,
            "n_steps": n_steps}
    times: list[float] = []
    rows: list[np.ndarray] = []
    held_rows: list[dict[str, float]] = []          # the held outputs of the step that ended at each row
    intervals = 0
    runner = BlockRunner()                          # the call buffers of this run's intervals, set up once
    started = clock.perf_counter()

    def result(count: int) -> SimulationResult:
        t = np.array(times[:count])
        block = np.array(rows[:count]).reshape(count, compiled.state_size)
        out = scheme_result(compiled, t, block, outputs, {
            **info, "wall_time_s": clock.perf_counter() - started, "intervals": intervals,
            "controllers": master.describe()}, held_rows[:count])
        for name, samples in master.outputs(until=t[-1] if count else -math.inf).items():
            out.extra[name] = samples
        return out

    try:
        master = CoSimulation(controllers, dt, 0.0, coupling=coupling)
    except SimulationError as exc:                  # a controller's init failed: nothing was simulated
        raise with_partial(exc, lambda: scheme_result(compiled, np.zeros(0), np.zeros((0, compiled.state_size)),
                                                      outputs, info, [])) from exc.__cause__

    def sample(step: int, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Sample the controllers due at ``step``; the held vector of :attr:`compiled.actuators` after it."""
        master.sample(step, step * dt, lambda i: np.asarray(ports.values(sensors[i], q, v, step * dt), dtype=float))
        return _held_inputs(master, index)

    guard = plant.guard(q0, divergence_bound)
    bar = progress_bar(n_steps, f"ctmm.simulate ({plant.label}, {label})",
                       enabled=validation.flag("progress", progress, optional=True))

    def advance() -> None:
        nonlocal intervals
        held = sample(0, q0, w0)
        state = compiled.start(x0, v0, dict(zip(compiled.actuators, held)))
        times.append(0.0)
        rows.append(state)
        held_rows.append(dict(zip(compiled.actuators, held)))
        k = 0
        while k < n_steps:
            following = _next_sample(master, k, n_steps)
            block = compiled.continue_run(state, held, following - k, k, runner=runner)
            intervals += 1
            applied = dict(zip(compiled.actuators, held))
            for j, row in enumerate(block):
                step = k + 1 + j
                guard(step * dt, row[:2 * m], dt, label)
                if step % store_every == 0 or step == n_steps:
                    times.append(float(step * dt))
                    rows.append(row)
                    held_rows.append(applied)
            state, k = block[-1].copy(), following
            bar.update(len(block))
            if k < n_steps:
                now = sample(k, state[:m], state[m:2 * m])
                if lumped and np.any(now != held):      # the history's acceleration restarts: a_n + M^-1 dF
                    state[2 * m:3 * m] += compiled.held_columns @ (now - held)
                    if compiled.scheme.restart_on_input_jump:   # and a multistep scheme's start-up (Houbolt)
                        state[compiled.start_up_index] = 0.0
                held = now

    return sampled_run(advance, result, times, bar, master)


def stored_offsets(start: int, first: int, stop: int, store_every: int, n_steps: int) -> list[int]:
    """The offsets ``j`` in ``[first, stop)`` of the rows of an interval from step ``start`` (row ``j`` ends step
    ``start + 1 + j``) that a run keeps: every ``store_every``-th step and the last one, ``n_steps``."""
    offsets = list(range(first + (-(start + 1 + first) % store_every), stop, store_every))
    if first <= n_steps - start - 1 < stop and (not offsets or offsets[-1] != n_steps - start - 1):
        offsets.append(n_steps - start - 1)
    return offsets


def sampled_run(advance: Callable[[], None], result: Callable[[int], SimulationResult], times: list, bar: Any,
                 master: CoSimulation) -> SimulationResult:
    """Run the sample intervals (``advance``) and return ``result`` of the stored rows; a
    :class:`~ctmm.errors.SimulationError` carries the partial result of the rows stored so far, and the progress
    ``bar`` and the controllers of ``master`` are closed whatever happens."""
    try:
        advance()
    except SimulationError as exc:
        raise with_partial(exc, lambda: result(len(times))) from exc.__cause__
    finally:
        bar.close()
        master.close()
    return result(len(times))


def _next_sample(master: CoSimulation, step: int, n_steps: int) -> int:
    """The first step after ``step`` at which a controller of ``master`` is due (at most ``n_steps``): where the
    generated interval that starts at ``step`` ends."""
    return min(min((step // ratio + 1) * ratio for ratio in master.ratios), n_steps)


def _held_inputs(master: CoSimulation, index: Mapping[str, int]) -> np.ndarray:
    """The kernel's actuator inputs from the controllers' held outputs: ``index`` maps an actuator name to its
    input position (each actuator is written by one controller: :func:`~ctmm.control.cosim.check_wiring`)."""
    held = np.zeros(len(index))
    for c, values in zip(master.controllers, master.held):
        for name, value in zip(c.outputs, values):
            held[index[name]] = float(value)
    return held
