"""Co-simulated controllers around the generated DT-TMM schemes of planar and spatial models (issue 13).

``ctmm.simulate(planar_or_spatial_model, t_final, dt, method=<scheme>, compiled=True, controllers=[...])`` runs here:
the
controllers are sampled on the step grid by the one co-simulation master (:class:`~ctmm.control.cosim.CoSimulation`)
and their outputs held, so between two sample instants the plant is a run of the generated scheme step
(:class:`~ctmm.compiled_scene_schemes.CompiledSceneScheme`,
:class:`~ctmm.compiled_spatial_schemes.CompiledSpatialScheme`) with the held outputs as its actuator inputs ``u``: one
call into C per sample interval, continued at the interval's step index (time signals run on; Houbolt's start-up
begins again after every sample, as :meth:`ctmm.schemes.Scheme.restart` on the Python path).
The sampling is the Python path's (:func:`ctmm.control.planar_time.simulate_closed_loop` through
:func:`ctmm.planar.implicit.simulate_implicit` / :func:`ctmm.spatial.implicit.simulate_spatial_implicit` and their
``after_step`` hook): sampled at ``t = 0`` before the start
acceleration (which includes their outputs), then after every step that ends at a sample instant, where the
acceleration of the history is solved again with the new held outputs (``a_n`` and ``qddot_n``, the restart of the
Python stepper; Houbolt then runs its two start-up steps again, which keeps it at order two).  The result equals the Python path's
to its Newton tolerance (``tests/test_compiled_scheme_cosim.py``).

Open-loop actuator ``inputs`` that are numbers are added to the held values (also without controllers: one call
into C).  ``Feedback`` loops and references beside the controllers: the step is the one of
:class:`~ctmm.compiled_scheme_loops.CompiledSchemeLoops` (planar) or
:class:`~ctmm.compiled_spatial_scheme_loops.CompiledSpatialSchemeLoops` (spatial; the controllers' outputs port
actuators of its input) with the loops inside Newton and their delay ring (inputs may then also be symbolic signals,
compiled in), restarted at the stored controller states and ring; equal to the Python path
(``tests/test_compiled_scheme_delays.py``, ``tests/test_compiled_spatial_scheme_loops.py``).  Refused
(:class:`~ctmm.errors.ModelError`, by the verb or here): inputs that are functions of time or signals without loops
(use ``compiled=None``), measurement delays (:class:`~ctmm.control.measurement_delay.DelayedController`), controller
outputs the generated step does not drive (a given ``compiled`` step without them).  Spatial port actuators that
are not one-number inputs of the model (beam station and body-axis forces and moments, joint components) driven by
controllers: the step of :class:`~ctmm.compiled_spatial_scheme_loops.CompiledSpatialSchemeLoops` without loops,
whose input they are.  Planar beam
station forces and moments that controllers drive (or numeric inputs hold) are inputs of the generated step
(``station_inputs`` of :class:`~ctmm.compiled_scene_schemes.CompiledSceneScheme` and
:class:`~ctmm.compiled_scheme_loops.CompiledSchemeLoops`: their modal forces and frame wrench,
:mod:`ctmm.compiled_station_loads`).

Spatial kinematic loop models (:class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel`): the step is the one of
:class:`~ctmm.compiled_spatial_loop_scheme_control.CompiledSpatialLoopSchemeControl` (cut loads solved at the
iterate, projection after every step, the loops beside the controllers inside Newton, open-loop inputs compiled in),
the cut loads stored with each row's held outputs (the values after a sample at a sample instant, as the Python
path stores them), the compliance condition and the projection residual checked at every step (named by the first
cut joint).
"""
from __future__ import annotations

import math
import time as clock
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from . import validation
from .compiled_control import add_loop_signals
from .compiled_parameters import station_loads
from .compiled_cosim import sampled_run, stored_offsets
from .compiled_kinematic_loop_control import applied_loop_inputs
from .compiled_scene_schemes import STATUS, CompiledSceneScheme, not_converged
from .compiled_scheme_loops import CompiledSchemeLoops
from .compiled_spatial_scheme_loops import CompiledSpatialSchemeLoops
from .compiled_spatial_loop_schemes import check_cut_rows
from .compiled_spatial_schemes import CompiledSpatialScheme, warn_conditionally_stable
from .control.controlled_model import ControlledModel
from .control.cosim import CoSimulation
from .control.plants import plant_of
from .errors import ModelError, SimulationError
from .generated_loop import BlockRunner
from .guard import DivergenceGuard
from .loop_integration import CONDITION_LIMIT, PROJECTION_TOLERANCE
from .planar.guards import check_scheme, divergence_guard, with_partial
from .planar.integrate import check_store_every, step_total
from .planar.model import PlanarModel
from .spatial.integrate import beam_deflection_weights
from .spatial.closed_loops import SpatialKinematicLoopModel
from .spatial.model import SpatialModel
from .progress import progress_bar
from .results import SimulationResult
from .schemes import Scheme, as_scheme
from .signals import as_signal
from .signal_results import SignalSystem, signal_result

__all__ = ["cut_rows_pass", "simulate_cosimulated_scheme_generated"]


def simulate_cosimulated_scheme_generated(model: PlanarModel | SpatialModel, q0: np.ndarray, v0: np.ndarray, *,
                                          t_final: float, dt: float, scheme: Scheme | str,
                                          controllers: Sequence[Any] = (), inputs: Mapping[str, Any] | None = None,
                                          outputs: Sequence[str] = (), loops: Sequence[Any] = (),
                                          references: Mapping[str, Any] | None = None,
                                          coupling: str = "hold", store_every: int = 1, progress: bool | None = None,
                                          stability_check: str = "warn", divergence_bound: float | None = None,
                                          compiled: Any = None) -> SimulationResult:
    """A DT-TMM scheme of a planar or spatial model in generated C between the samples of co-simulated controllers.

    Parameters
    ----------
    model : PlanarModel, SpatialModel or SpatialKinematicLoopModel
        Compilable (:func:`ctmm.compiled_parameters.compile_refusal`,
        :func:`ctmm.compiled_spatial.spatial_compile_refusal`,
        :func:`ctmm.compiled_spatial_kinematic_loops.spatial_kinematic_loop_compile_refusal`).
    q0, v0 : ndarray
        Initial coordinates and rates (checked by the caller).
    t_final, dt : float
        End time and step [s]; every sample time a whole multiple of ``dt``.
    scheme : Scheme or str
    controllers : sequence of Controller
        Co-simulated controllers (validated by the caller, :func:`ctmm.control.protocol.check_controllers`) reading
        sensors and writing actuators of the model by name.
    inputs : mapping, optional
        ``{actuator: number}`` held over the run [SI], added to the controllers' outputs on the same actuator (with
        ``loops``: also symbolic :mod:`ctmm.signals`, constants of the code).
    loops, references : optional
        ``Feedback`` loops closed inside the generated Newton step and their references
        (:class:`~ctmm.compiled_scheme_loops.CompiledSchemeLoops`,
        :class:`~ctmm.compiled_spatial_scheme_loops.CompiledSpatialSchemeLoops`: real-time, LTI, delayed), the
        controllers' held outputs added to their actuator values.
    outputs, coupling, store_every, progress
        As in :func:`ctmm.compiled_cosim.simulate_cosimulated_generated` (stored sensors, the co-simulation's
        coupling policy, every ``store_every``-th step kept, a progress bar).
    stability_check : {"warn", "error", "ignore"}
        Planar: the step against the scheme's limit before the run (:func:`ctmm.planar.guards.check_scheme`);
        spatial: a warning for a conditionally stable scheme, as the Python path.
    divergence_bound : float, optional
        As in :func:`ctmm.control.planar_time.simulate_closed_loop` (the plant's guard), every step.
    compiled : CompiledSceneScheme or CompiledSpatialScheme, optional
        A kernel of this model and scheme with ``store_every=1`` (default: compiled here, cached on disk; with
        ``loops``: always compiled here).

    Returns
    -------
    SimulationResult
        As the Python path: coordinates, rates, ``outputs`` and ``"<controller output>@samples"``; method
        ``"dt-tmm-generated/<Scheme>"``, ``info["intervals"]`` (calls into C), ``info["controllers"]``.

    Raises
    ------
    ModelError
        Measurement delays, outputs the generated step does not drive, bad wiring, no compiler.
    ConvergenceError
        A step whose Newton iterations did not converge (step, time, residual), with ``partial_result``.
    SimulationError
        Failing controller code, divergence or a non-finite state, with ``partial_result``.
    """
    scheme = as_scheme(scheme)
    n_steps = step_total(t_final, dt)
    dt = float(t_final) / n_steps
    store_every = check_store_every(store_every)
    planar = isinstance(model, PlanarModel)
    kinematic = isinstance(model, SpatialKinematicLoopModel)      # cut joints: their step with the loops' part
    tree = model.tree if kinematic else model
    plant = plant_of(model)
    ports = plant.ports
    for c in controllers:
        label = f"controller {getattr(c, 'name', None) or type(c).__name__!r}"
        if getattr(c, "measurement_delay", 0.0):
            raise ModelError(f"{label} declares a measurement delay, which the generated DT-TMM schemes do not apply; "
                             "run with compiled=None (the Python stepper reads it late)")
        for name in c.inputs:
            ports.check_sensor(name, f"input of {label}")
        for name in c.outputs:
            ports.check_actuator(name, f"output of {label}")
    kind = CompiledSceneScheme if planar else CompiledSpatialScheme
    held = [name for c in controllers for name in c.outputs]
    joint_inputs = () if planar or kinematic else [name for joint in model.joints for name in joint.inputs
                                                   if joint.velocity_count == 1]
    # spatial port actuators (beam station and body-axis forces and moments) are inputs of the step with loops only
    ported = not planar and not kinematic and compiled is None and any(name not in joint_inputs for name in held)
    # open-loop inputs that are functions of time (ctmm.signals) are stated on the step's time symbol by the step
    # with loops (none here); the plain generated step holds numbers
    timed = any(callable(value) for value in (inputs or {}).values())
    looped = bool(loops) or bool(references) or ported or kinematic or timed
    input_signals = {name: as_signal(f"inputs[{name!r}]", value) for name, value in (inputs or {}).items()} \
        if kinematic else {}
    if looped:                  # loops inside the Newton step, the controllers' held outputs added to theirs
        if compiled is not None:
            raise ModelError("compiled=True with loops and co-simulated controllers together: the step is compiled "
                             f"here, got compiled={compiled!r}; leave compiled out")
        controlled = ControlledModel(model, loops)
        if planar:
            compiled = CompiledSchemeLoops(controlled, scheme, references=references, inputs=inputs, dt=dt,
                                           station_inputs=station_loads(model, held))
        elif kinematic:
            from .compiled_spatial_loop_scheme_control import CompiledSpatialLoopSchemeControl

            compiled = CompiledSpatialLoopSchemeControl(controlled, scheme, references=references, inputs=inputs,
                                                        dt=dt, held=held)
        else:
            compiled = CompiledSpatialSchemeLoops(controlled, scheme, references=references, inputs=inputs, dt=dt,
                                                  held=held)
        signals_of, inputs = compiled.loops.signals(), None
    elif compiled is None:
        stations = station_loads(model, [*held, *dict(inputs or {})]) if planar else ()
        compiled = CompiledSceneScheme(model, scheme, station_inputs=stations) if planar else kind(model, scheme)
    elif not isinstance(compiled, kind) or compiled.model is not model or compiled.scheme != scheme \
            or compiled.store_every != 1:
        raise ModelError(f"compiled must be a {kind.__name__} of this model with scheme={scheme!r} and "
                         f"store_every=1, got {compiled!r}")
    if planar or looped:
        drivable = list(compiled.actuators)
    else:
        drivable = [name for name, width in zip(compiled.rates.actuators, compiled.rates.widths) if width == 1]
    for c in controllers:
        for name in c.outputs:
            if name not in drivable:
                raise ModelError(f"compiled=True: controller output {name!r} is not an input the generated step "
                                 f"drives (it drives {', '.join(drivable) or 'none'}); run with compiled=None")
    constant: dict[str, float] = {}
    for name, value in dict(inputs or {}).items():
        ports.check_actuator(name, "input")
        if name not in drivable:
            raise ModelError(f"compiled=True: input {name!r} is not an input the generated step drives (it drives "
                             f"{', '.join(drivable) or 'none'}); run with compiled=None")
        try:
            number = math.nan if callable(value) or isinstance(value, (str, bool)) else float(value)
        except (TypeError, ValueError):
            number = math.nan
        if not math.isfinite(number):
            raise ModelError(f"inputs[{name!r}] = {value!r}: the generated DT-TMM scheme holds open-loop inputs as "
                             "finite numbers; give a number, or run with compiled=None (functions of time, signals)")
        constant[name] = number

    def vector(held: dict[str, float]) -> np.ndarray:
        """The kernel's input vector ``u`` from the held values by actuator name."""
        if planar:
            return np.array([held.get(name, 0.0) for name in compiled.actuators])
        return compiled.held_inputs(held) if looped else compiled.rates.input_vector(held)

    q0, v0 = np.asarray(q0, float), np.asarray(v0, float)
    if planar:
        closed = (lambda _, q_k, v_k, t_k: compiled.accelerations(q_k, v_k, t_k)) if looped else None
        check_scheme(model, q0, v0, dt, scheme=scheme, policy=stability_check, accelerations=closed)
    else:
        warn_conditionally_stable(tree, scheme)
    sensors = [ports.resolve(list(c.inputs)) for c in controllers]
    nq, nv = plant.n_positions, plant.n_velocities
    guard = plant.guard(q0, divergence_bound, v0)
    screen = _guard_screen(tree, q0, v0, divergence_bound)
    label = f"dt-tmm-generated/{type(scheme).__name__}"
    info: dict = {"dt": dt, "method": label, "compile_time_s": compiled.compile_time_s}
    times: list[float] = []
    rows: list[np.ndarray] = []
    held_rows: list[dict[str, float]] = []      # cut joints: the held outputs of each stored row (its cut loads)
    held_now: dict[str, float] = {}
    intervals = 0
    runner = BlockRunner()                  # the call buffers of this run's intervals, set up once
    start = clock.perf_counter()
    master: CoSimulation | None = None          # None: a controller's init failed (no samples, nothing run)

    def result(count: int) -> SimulationResult:
        t, block = np.array(times[:count]), np.array(rows[:count], dtype=float).reshape(count, compiled.state_size)
        applied = None
        if kinematic:                   # the cut loads with each row's actuator values
            entries = compiled.signal_states(block[:, compiled.status_index + len(STATUS):], t)
            applied = applied_loop_inputs(controlled, compiled.loops, input_signals, t,
                                          signals_of(np.hstack([block[:, :nq + nv], entries]), t)[1],
                                          held_rows[:count])
        signals, units = plant.signals(t, block[:, :nq], block[:, nq:nq + nv], outputs,
                                       **({"inputs": applied} if kinematic else {}))
        for name, samples in (master.outputs(until=t[-1] if count else -math.inf) if master else {}).items():
            signals[name], units[name] = samples, ports.actuator_unit(name.split("@")[0])
        more = {}
        if looped:
            entries = compiled.signal_states(block[:, compiled.status_index + len(STATUS):], t)
            more = add_loop_signals(controlled, compiled.loops, signals_of,
                                    np.hstack([block[:, :nq + nv], entries]), t, signals, units)
            more["loops"] = {law.name: "real-time" if law.steps == 0 else "history" for law in compiled.loops.laws}
        return signal_result(SignalSystem(model, units, list(loops)), t, signals, label, {
            **info, **more, "wall_time_s": clock.perf_counter() - start,
            "controllers": master.describe() if master else [],
            "intervals": intervals, "newton_iterations": int(block[-1, compiled.status_index + 2]) if count else 0})

    try:
        master = CoSimulation(controllers, dt, 0.0, coupling=coupling)
    except SimulationError as exc:          # a controller's init failed: nothing was simulated
        raise with_partial(exc, lambda: result(0)) from exc.__cause__

    def sample(step: int, state: np.ndarray) -> tuple[np.ndarray, bool]:
        """Sample the controllers due at ``step``: the kernel's input vector after it and whether one was sampled
        (the Python stepper then solves the acceleration at that time again)."""
        sampled = master.sample(step, step * dt, lambda i: np.asarray(ports.values(
            sensors[i], state[:nq], state[nq:nq + nv], step * dt), dtype=float))
        held = dict(constant)
        for c, values in zip(master.controllers, master.held):
            for name, value in zip(c.outputs, values):
                held[name] = held.get(name, 0.0) + float(value)     # outputs on one actuator add
        held_now.clear()
        held_now.update(held)
        return vector(held), bool(sampled)

    bar = progress_bar(n_steps, f"ctmm.simulate ({plant.label}, {label})",
                       enabled=validation.flag("progress", progress, optional=True))

    def advance() -> None:
        nonlocal intervals
        held, _ = sample(0, np.concatenate([q0, v0]))
        state = compiled.restarted(compiled.initial_state(*((q0, v0) if planar else (np.concatenate([q0, v0]),))),
                                   held, 0.0)
        times.append(0.0)
        rows.append(state)
        held_rows.append(dict(held_now))
        k = restart = 0                     # restart: the step where the scheme's start-up last began
        while k < n_steps:
            following = min(min(((k // ratio + 1) * ratio for ratio in master.ratios), default=n_steps), n_steps)
            block = compiled.continue_run(state, held, dt, following - k, k, since_start=k - restart, runner=runner)
            intervals += 1
            # rows that converged and pass the screen (the guard's rules on the block) are stored at once; the
            # others and the interval's last row go one by one through the status check and the guard itself
            head = block[:-1]
            suspects = np.flatnonzero((head[:, compiled.status_index] > 0.0) | ~screen(head)
                                      | (kinematic and ~cut_rows_pass(head))).tolist() if len(head) else []
            done = 0
            for j in [*suspects, len(block) - 1]:
                for i in stored_offsets(k, done, j, store_every, n_steps) if j > done else ():
                    times.append(float((k + 1 + i) * dt))
                    rows.append(block[i])
                    held_rows.append(dict(held_now))
                row, step, done = block[j], k + 1 + j, j + 1
                if row[compiled.status_index] > 0.0:
                    raise not_converged(compiled, row, dt, offset=restart)
                guard(step * dt, row[:nq + nv], dt, label)
                if kinematic:               # a singular loop configuration or a projection left off the cuts
                    check_cut_rows(compiled, np.array([step * dt]), row[None], f"spatial kinematic loop "
                                   f"{model.name!r} with controllers ({label})", lambda _: result(len(times)))
                if step == following:       # sampled before the row is stored (also at the end), as the Python path
                    held, sampled = sample(step, row)
                if step % store_every == 0 or step == n_steps:
                    times.append(float(step * dt))
                    rows.append(row)
                    held_rows.append(dict(held_now))
            state, k = block[-1].copy(), following
            bar.update(len(block))
            if sampled and k < n_steps:     # the held outputs may have jumped: the acceleration at t_k with them
                state = compiled.restarted(state, held, k * dt)
                if scheme.restart_on_input_jump:    # a multistep scheme (Houbolt) starts up again (Scheme.restart)
                    restart = k

    return sampled_run(advance, result, times, bar, master)


def cut_rows_pass(block: np.ndarray) -> np.ndarray:
    """Which generated rows of a spatial kinematic loop scheme (rows, state) keep their last two entries
    ``[condition, residual]`` within :data:`~ctmm.loop_integration.CONDITION_LIMIT` and
    :data:`~ctmm.loop_integration.PROJECTION_TOLERANCE`."""
    return (block[:, -2] <= CONDITION_LIMIT) & (block[:, -1] <= PROJECTION_TOLERANCE)


def _guard_screen(model: PlanarModel | SpatialModel, q0: np.ndarray, v0: np.ndarray, bound: float | None
                  ) -> Callable[[np.ndarray], np.ndarray]:
    """``screen(block)``: which stored rows (rows, state) the plant's guard accepts, for a block at once
    (:meth:`~ctmm.guard.DivergenceGuard.passes`): a rigid planar model's coordinates from ``q0`` within the bound and
    finite rates (:func:`ctmm.planar.integrate.check_state`), a spatial model's ``[q ; v]`` from the start within
    ``bound`` (``None``: finite; :func:`ctmm.spatial.integrate.divergence_check`).  Where the guard checks more (a
    deformable family, spatial beams) every row is ``False``: each goes through the guard."""
    nq = len(q0)
    if isinstance(model, PlanarModel):
        if model.deformable_family is not None:
            return lambda block: np.zeros(len(block), dtype=bool)
        coordinates = divergence_guard(model, q0, bound)
        return lambda block: coordinates.passes(block[:, :nq]) & np.all(np.isfinite(block[:, nq:2 * nq]), axis=1)
    if beam_deflection_weights(model):
        return lambda block: np.zeros(len(block), dtype=bool)
    start = np.concatenate([q0, v0])
    state = DivergenceGuard(tuple(model.coordinates) + tuple(model.velocities), start,
                            math.inf if bound is None else float(bound))
    return lambda block: state.passes(block[:, :start.size])
