"""Baseline of issue 12 (one core): the numbers the redesign must reproduce.

Two parts, written to ``benchmarks/results/baseline_issue12.json``:

* ``scenarios`` — every scenario of ``scenarios/`` run in quick mode through
  :func:`ctmm.scenario.run_scenario` (outputs in a temporary folder, removed afterwards): each
  accuracy figure (name, value, unit, bound, passed) and the scenario's wall time [s].  Issue 12
  must keep every figure within its bound (``docs/plans/one_core.md`` §5: "scenario numbers in
  the S0 baseline reproduced within their stated bounds").
* ``timings`` — the cheapest configuration of every existing benchmark, built by the benchmark's
  own model function: per-step time (time-stepping), per-sweep time (one call of a forward-dynamics
  sweep or one frequency-response call over the benchmark's frequency grid) or per-chart time.
  Each is the best of :data:`REPEATS` samples after one warm-up call (a sample repeats a short
  call until it lasts :data:`MIN_SAMPLE_S`), as process CPU time and as wall time [s] (the plan's
  rule: Python paths within 10 %, compiled paths unchanged).  The load average is recorded before
  and after each part and after each case.

Each benchmark's cheapest configuration only: ``foundation_work_precision`` at dt = 1 ms (five
schemes); ``foundation_scaling`` at n = 10 (FRF and Newmark, fast and generic path);
``control_overhead`` in its ``--quick`` time-domain form (plant, embedded, delayed, Python
controller) and n = 3 in frequency (TMM, PlantCache); ``delay_history`` at 1000 steps;
``planar_chain`` at N = 5 (sweep, RK4, implicit Newmark, generated RK4); ``flexible`` one sweep at
1, 4 and 16 modes and the implicit step at 1 mode; ``manipulator`` one sweep, RK4 and Newmark at
dt = 10 ms, compiled RK4 at dt = 10 ms; ``stability_chart`` the 100 x 100 chart; ``compiled_scenes``
(issue 13, added after the baseline run: its two cases were measured alone) the generated RK4 of
the hub-beam and of the N = 5 chain; ``spatial_chain`` (issue 14, added later and measured
alone) one forward dynamics of the spatial reference model at N = 5; ``spatial_schemes`` (issue 14,
added later, measured alone) Newmark on the spatial double pendulum at dt = 10 ms; ``chain_compiled``
(issues 12/13, added later, measured alone) the generated RK4 of the 100-mass chain with a real-time loop;
``compiled_schemes_planar`` (issue 13, added later, measured alone) the generated Newmark of the N = 5 chain;
``compiled_schemes_default`` (issue 13, added later, measured alone) the generated and the numpy Newmark step of
the N = 15 and N = 100 chains (the generated step iterating with the implicit sweep since session 13: the N = 15
generated case re-based, the N = 100 cases added); ``chain_default_limits`` (issue 13, added later,
measured alone) the default's chain kind check and a cached generated Newmark call of the 1 002-mass chain.  Left out (too long
for a baseline under ~3 min, or needing a build): larger sizes and step ladders, the external
libraries and references the benchmarks compare with (python-control, pinocchio, MuJoCo, global
and Lagrange models), the FMU controller variant (builds an FMU with gcc), ``flexible``'s chain of
beams and adaptive runs, the verified and threaded charts.

Re-based cases (their stored numbers replaced, measured alone and merged; every other case is the
S0 baseline): on 2026-11-25 (issue 12, retiring ``FlexibleManipulator``) ``manipulator/sweep``,
``manipulator/simulate_rk4`` and ``manipulator/simulate_newmark`` changed what they measure -- the
sweep is the scene plant's ``accelerations()`` with the PD and PZT loops' actuator inputs (was: the
older model with both laws embedded in it), and the two runs are ``ctmm.simulate`` of the
manipulator scene with the laws as ``Feedback`` loops on its ports (was:
``FlexibleManipulator.simulate``); same physics, same step and horizon.  Each re-based case says so
in its ``"rebased"`` entry.  Replaced case: ``planar_chain/rk4_compiled_n5`` (the hand-typed C of
``ctmm.planar.compiled``, removed in issue 13) is dropped; ``planar_chain/rk4_generated_n5`` (the same run
through the generated RK4) was added in its place, measured alone on 2026-11-25 (``timings.added_later``;
``timings.dropped`` keeps the reason).  ``planar_frf/sweep_n20_500_omega`` (issue 13: planar frequency responses
by the one sweep's frequency context), ``spatial_frf/sweep_n30_500_omega`` (issues 13/14: the same for spatial
models), ``kinematic_loops_generated/generated_rk4_projection_four_bar`` and ``..._spatial_four_bar`` (issues 13/16: the
four-bars' RK4 with projection in generated C; ``..._flexible_four_bar`` with a ModalBeam coupler, issue 13 item 1),
``chain_frf/frequency_response_n1000`` (issue 13: the 1-D chain FRF by the compiled Riccati solve) and
``chain_setup_scaling/cached_call_rk4_n1000`` (issue 13: the per-call set-up of a generated chain kernel) were measured
alone when their benchmarks landed (``timings.added_later``); ``chain_default_limits/dense_chain_reason_n1002`` and
``.../cached_call_newmark_n1002`` (issue 13: the default's chain kind check, and a cached generated Newmark call just
above the dense kinds' limit) were added with their benchmark and are to be measured alone the same way;
``kernel_cache/cached_call_planar_pendulum10_newmark`` and ``..._loops_rk4`` (issue 13, session 13: cached planar
scheme and loop calls keyed before building) were measured alone when they landed;
``generated_flags/first_compile_python_four_bar`` (issue 13, session 14: the Python part of a first compile of a
generated kernel) was measured alone when its benchmark landed; ``spatial_scheme_tangent/generated_newmark_free_body``
(issue 13, session 15: the generated spatial Newmark step with the Newton tangent by directional derivatives) was
added with its benchmark and is to be measured alone the same way.
Python time-stepping cases whose
benchmark horizon would make the repeats slow run over a shorter horizon at the benchmark's step
(stated in ``configuration``): the per-step cost does not depend on the horizon.

Run ``python benchmarks/baseline_issue12.py`` to write the baseline (``--only scenarios`` or
``--only timings`` for one part; ``--output`` for another file), and
``python benchmarks/baseline_issue12.py --compare`` after a migration step: it measures again and
lists every scenario figure out of its bound and every timing more than 10 % slower (CPU) than the
baseline (the timing pass is repeated up to :data:`RETRIES` times while a case is too slow, and
each case's best is kept: on the shared machine one pass can be slowed by other work), exiting
with status 1 if there is any.  On a shared machine, read the load averages and
repeat a comparison that fails on timings alone.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "benchmarks"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

import ctmm  # noqa: E402
from ctmm.scenario import available, run_scenario, write_json_atomic  # noqa: E402

REPEATS = 5
MIN_SAMPLE_S = 0.1      # shortest timed sample [s]: short calls are repeated within one sample
TIME_TOLERANCE = 0.10   # docs/plans/one_core.md §5: Python paths within 10 % (best of 5)
RETRIES = 2             # --compare: whole timing passes repeated while a case is too slow (best kept)
RESULTS = ROOT / "benchmarks" / "results" / "baseline_issue12.json"


def machine() -> dict:
    """Platform, versions, core count, load average and the code version."""
    def git(*args: str) -> str:
        try:
            return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
        except (OSError, subprocess.CalledProcessError):
            return "unknown"

    info = {"platform": platform.platform(), "python": platform.python_version(), "numpy": np.__version__,
            "ctmm": ctmm.__version__, "cpu_count": os.cpu_count(),
            "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS"),
            "git_commit": git("rev-parse", "HEAD"), "git_dirty": bool(git("status", "--porcelain", "--", "ctmm")),
            "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    try:
        with open("/proc/cpuinfo") as handle:
            info["cpu_model"] = next((line.split(":", 1)[1].strip() for line in handle
                                      if line.startswith("model name")), "unknown")
    except OSError:
        pass
    return info


def load() -> list[float]:
    """Load average over 1, 5 and 15 min."""
    return [round(value, 2) for value in os.getloadavg()]


# --------------------------------------------------------------------------------------------------
# Scenarios
# --------------------------------------------------------------------------------------------------
def scenarios() -> dict:
    """Accuracy figures and wall time of every scenario, quick mode."""
    out = {"load_average_before": load(), "cases": {}}
    with tempfile.TemporaryDirectory(prefix="ctmm-baseline-") as folder:
        for name in available():
            summary = run_scenario(name, folder, quick=True)
            out["cases"][name] = {
                "passed": summary["passed"], "wall_time_s": summary["total_wall_time_s"],
                "accuracy": [{key: figure[key] for key in ("name", "value", "unit", "bound", "passed")}
                             for figure in summary["accuracy"]]}
            print(f"scenario {name:34s} {summary['total_wall_time_s']:6.2f} s  passed={summary['passed']}",
                  flush=True)
    out["load_average_after"] = load()
    return out


# --------------------------------------------------------------------------------------------------
# Timings
# --------------------------------------------------------------------------------------------------
def best_of(call: Callable[[], object], repeats: int = REPEATS) -> tuple[float, float, int, object]:
    """Best process CPU time [s] and best wall time [s] of one call, and the calls per sample.

    One warm-up call, then ``repeats`` samples; a sample runs ``call`` as often as needed (a power
    of 2) to last at least :data:`MIN_SAMPLE_S`, so that short calls are not timed one by one.
    """
    started = time.perf_counter()
    result = call()
    number = 1
    if time.perf_counter() - started < MIN_SAMPLE_S:
        while True:
            wall = time.perf_counter()
            for _ in range(number):
                call()
            if time.perf_counter() - wall >= MIN_SAMPLE_S:
                break
            number *= 2
    cpus, walls = [], []
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        for _ in range(number):
            result = call()
        cpus.append((time.process_time() - cpu) / number)
        walls.append((time.perf_counter() - wall) / number)
    return min(cpus), min(walls), number, result


class Timings:
    """Collects timing cases: ``benchmark / case`` -> per-unit CPU and wall time [s]."""

    def __init__(self) -> None:
        self.cases: dict[str, dict] = {}

    def add(self, benchmark: str, case: str, call: Callable[[], object], *, per: str, count: int,
            configuration: str, repeats: int = REPEATS) -> object:
        """Time ``call`` and store its time per ``per`` (``count`` of them in one call)."""
        cpu, wall, number, result = best_of(call, repeats)
        key = f"{benchmark}/{case}"
        self.cases[key] = {"benchmark": f"benchmarks/{benchmark}.py", "configuration": configuration,
                           "per": per, "count_per_call": count, "repeats": repeats, "calls_per_sample": number,
                           "cpu_s_per_unit": cpu / count, "wall_s_per_unit": wall / count,
                           "cpu_s_per_call": cpu, "wall_s_per_call": wall, "load_average_after": load()}
        print(f"timing {key:52s} {1e6 * cpu / count:12.1f} us CPU per {per}", flush=True)
        return result


def _work_precision(t: Timings) -> None:
    bench = importlib.import_module("foundation_work_precision")
    system, x0, dt = bench.table_7_1_chain(), bench.initial_positions(), bench.DT_LADDER[0]
    steps = int(round(bench.T_FINAL / dt))
    for scheme in bench.SCHEMES:
        t.add("foundation_work_precision", f"simulate_{scheme}",
              lambda scheme=scheme: ctmm.simulate(system, bench.T_FINAL, dt, method=scheme, x0=x0),
              per="step", count=steps, configuration=f"Table 7.1 chain (5 masses), dt={dt:g} s, {steps} steps")


def _scaling(t: Timings) -> None:
    bench = importlib.import_module("foundation_scaling")
    n = bench.SIZES[0]
    system, omega = bench.ctmm_chain(n), bench.omega_grid(n)
    t.add("foundation_scaling", f"frequency_response_n{n}",
          lambda: ctmm.frequency_response(system, omega, input="m1.force", output=["m1.x", f"m{n}.x"]),
          per="sweep", count=1, configuration=f"fixed-free chain of {n} masses, {omega.size} frequencies")
    x0 = {f"m{j}": float(0.01 * np.sin(np.pi * j / (2 * n))) for j in range(1, n + 1)}
    for fast in (True, False):
        t.add("foundation_scaling", f"simulate_newmark_n{n}_{'fast' if fast else 'generic'}",
              lambda fast=fast: ctmm.simulate(system, bench.N_STEPS * bench.DT, bench.DT, method="newmark", x0=x0,
                                              fast=fast, progress=False),
              per="step", count=bench.N_STEPS,
              configuration=f"chain of {n} masses, Newmark, dt={bench.DT:g} s, fast={fast}")


def _control(t: Timings) -> None:
    bench = importlib.import_module("control_overhead")
    from ctmm.control import ControlledChain, Feedback, simulate_controlled
    from ctmm.control.design import PlantCache

    t_final, dt = 0.5, bench.DT
    steps = int(round(t_final / dt))
    plant = bench.chain(3)
    terms = [("m2.x", bench.KP), ("m2.v", bench.KD)]
    variants = {
        "plant": lambda: simulate_controlled(plant, t_final, dt, x0={"m2": 0.1}),
        "embedded": lambda: simulate_controlled(
            ControlledChain(plant, [Feedback("pd", terms, "m0", gain=1.0)]), t_final, dt, x0={"m2": 0.1}),
        "embedded_delayed": lambda: simulate_controlled(
            ControlledChain(plant, [Feedback("pd", terms, "m0", gain=1.0, delay=dt)]), t_final, dt, x0={"m2": 0.1}),
        "python": lambda: simulate_controlled(
            plant, t_final, dt, x0={"m2": 0.1}, controllers=[bench.controllers.SaturatedPD(
                ("m2.x", "m2.v"), ("m0.force",), kp=bench.KP, kd=bench.KD, sample_time=dt)]),
    }
    for name, call in variants.items():
        t.add("control_overhead", f"time_{name}", call, per="step", count=steps,
              configuration=f"seed chain (3 masses), PD on m0 from m2, Newmark, dt={dt:g} s, {steps} steps (--quick)")
    omega = np.linspace(0.01, 10.0, 1000)
    system = ControlledChain(plant, [Feedback("loop", "m2.x", "m0", gain=5.0)])
    outputs = ["m0.x", "m1.x", "m2.x"]
    t.add("control_overhead", "frequency_tmm_n3",
          lambda: ctmm.frequency_response(system, omega, input="m2.force", output=outputs),
          per="sweep", count=1, configuration="closed-loop FRF, chain of 3 masses, 1000 frequencies")
    cache = PlantCache(system, omega, inputs="m2.force", outputs=outputs)
    t.add("control_overhead", "frequency_plant_cache_n3", lambda: cache.closed_loop(gains={"loop": 5.0}),
          per="sweep", count=1, configuration="PlantCache.closed_loop for a new gain, 3 masses, 1000 frequencies")


def _delay_history(t: Timings) -> None:
    bench = importlib.import_module("delay_history")
    from ctmm.control import simulate_controlled

    system, steps = bench.model(), 1000
    t.add("delay_history", "simulate_1000_steps",
          lambda: simulate_controlled(system, steps * bench.DT, bench.DT, x0={"m6": bench.X_TIP}),
          per="step", count=steps, configuration=f"seed chain, delayed velocity loop, dt={bench.DT:g} s, 1000 steps")


def _planar(t: Timings) -> None:
    bench = importlib.import_module("planar_chain")
    from ctmm.planar import accelerations

    n, horizon = 5, 0.2
    model = bench.chain(n)
    q0, v0 = np.zeros(n), np.zeros(n)
    steps = int(round(horizon / bench.H))
    configuration = f"pendulum chain N={n}, dt={bench.H:g} s, horizon {horizon} s ({steps} steps; benchmark: 1 s)"
    t.add("planar_chain", f"sweep_n{n}", lambda: accelerations(model, q0 + 0.1, v0 + 0.1, 0.0), per="sweep",
          count=1, configuration=f"pendulum chain N={n}, one accelerations() call")
    t.add("planar_chain", f"rk4_n{n}",
          lambda: bench.simulate_rk4(model, q0, v0, t_final=horizon, dt=bench.H, store_every=steps),
          per="step", count=steps, configuration=configuration)
    t.add("planar_chain", f"implicit_newmark_n{n}",
          lambda: bench.simulate_implicit(model, q0, v0, t_final=horizon, dt=bench.H, store_every=steps),
          per="step", count=steps, configuration=configuration)
    steps_c = int(round(bench.T_FINAL / bench.H))
    scene = bench.CompiledScene(model, store_every=steps_c)         # generate, compile or load, outside the timing
    t.add("planar_chain", f"rk4_generated_n{n}",
          lambda: bench.simulate_rk4_generated(model, q0, v0, t_final=bench.T_FINAL, dt=bench.H, store_every=steps_c,
                                               scene=scene),
          per="step", count=steps_c, configuration=f"pendulum chain N={n}, dt={bench.H:g} s, {steps_c} steps, RK4 "
                                                   "generated from the element definitions (simulate_rk4_generated "
                                                   "on a built CompiledScene)")


def _planar_frf(t: Timings) -> None:
    bench = importlib.import_module("planar_frf")
    n = 20
    model = bench.chain(n)
    bench.sweep(model, n)
    t.add("planar_frf", f"sweep_n{n}_500_omega", lambda: bench.sweep(model, n), per="call", count=1,
          configuration=f"pendulum chain N={n} hanging (operating point given), ctmm.frequency_response at "
                        f"{bench.OMEGA.size} omega, one force input, one angle output: the one sweep's frequency "
                        "context batched over omega (ctmm.planar_transfer_response)")


def _spatial_frf(t: Timings) -> None:
    bench = importlib.import_module("spatial_frf")
    n = 30
    model = bench.chain(n)
    bench.sweep(model, n)
    t.add("spatial_frf", f"sweep_n{n}_500_omega", lambda: bench.sweep(model, n), per="call", count=1,
          configuration=f"weightless sprung spatial revolute chain N={n} at rest (operating point given), "
                        f"ctmm.frequency_response at {bench.OMEGA.size} omega, two inputs, two outputs: the one "
                        "sweep's frequency context batched over omega (ctmm.spatial_transfer_response)")


def _flexible(t: Timings) -> None:
    bench = importlib.import_module("flexible")
    from ctmm.planar import accelerations, simulate_implicit

    for modes in (1, 4, 16):
        model = bench.spin_model(modes)
        q = 1e-3 * np.ones(modes)
        t.add("flexible", f"sweep_spin_up_{modes}_modes", lambda model=model, q=q: accelerations(model, q, q, 5.0),
              per="sweep", count=1, configuration=f"Kane spin-up beam, {modes} mode(s), one accelerations() call")
    model = bench.spin_model(1)
    t.add("flexible", "implicit_step_spin_up_1_mode",
          lambda: simulate_implicit(model, np.zeros(1), np.zeros(1), t_final=0.1, dt=0.005), per="step", count=20,
          configuration="Kane spin-up beam, 1 mode, generalized implicit DT-TMM, dt=0.005 s, 20 steps")


def _manipulator(t: Timings) -> None:
    bench = importlib.import_module("manipulator")
    from ctmm.planar import accelerations

    arm, pd, pzt, scene, references = bench.seed_scene()
    q = np.zeros(scene.plant.n_coordinates)
    inputs = bench.loop_inputs(scene, references, q, q, 0.1)
    t.add("manipulator", "sweep", lambda: accelerations(scene.plant, q, q, 0.1, inputs=inputs), per="sweep", count=1,
          configuration="seed manipulator scene (hub + 3-mode arm; PD + PZT loops' actuator inputs), one "
                        "accelerations() call of the plant")
    horizon, dt = 0.5, 0.01
    steps = int(round(horizon / dt))
    for method in ("rk4", "newmark"):
        t.add("manipulator", f"simulate_{method}",
              lambda method=method: ctmm.simulate(scene, horizon, dt, method=method, references=references),
              per="step", count=steps,
              configuration=f"seed manipulator scene through ctmm.simulate, dt={dt:g} s, horizon {horizon} s "
                            f"({steps} steps; benchmark: 3 s)")
    compiled = bench.CompiledManipulator(arm, pd, pzt, bench.SEED_MOVE, block=1, chunks=50)
    steps = int(round(bench.T_WP / dt))
    t.add("manipulator", "simulate_rk4_compiled", lambda: compiled.simulate(bench.T_WP, dt), per="step", count=steps,
          configuration=f"seed manipulator, casadi-compiled RK4, dt={dt:g} s, {bench.T_WP:g} s ({steps} steps)")


def _stability_chart(t: Timings) -> None:
    bench = importlib.import_module("stability_chart")
    system = bench.system()
    t.add("stability_chart", "chart_100x100",
          lambda: bench.stability_chart(system, x=("gain", bench.GAINS, "gain factor k [-]"),
                                        y=("delay", bench.DELAYS, "delay tau [s]")),
          per="chart", count=1, configuration="chain of 20 masses with a PD loop, 100 x 100 (gain, delay) grid")


def _compiled_scenes(t: Timings) -> None:
    bench = importlib.import_module("compiled_scenes")
    cases = (("hub_beam", bench.hub_beam(), 1e-3, 2000), ("chain_n5", bench.chain(5), 1e-3, 1000))
    for label, model, dt, steps in cases:
        scene = bench.CompiledScene(model)
        zero = np.zeros(model.n_coordinates)
        t.add("compiled_scenes", f"generated_rk4_{label}", lambda scene=scene, zero=zero, dt=dt, steps=steps:
              scene.run(zero, zero, dt, steps), per="step", count=steps,
              configuration=f"{label.replace('_', ' ')}, RK4 generated from the element definitions "
                            f"(CompiledScene.run, library loaded), dt={dt:g} s, {steps} steps")


def _spatial_chain(t: Timings) -> None:
    bench = importlib.import_module("spatial_chain")
    tree = bench.reference_tree(5, "ball")
    q0, v0 = bench.initial_state(5, "ball")
    t.add("spatial_chain", "reference_forward_dynamics_ball_n5",
          lambda: bench.reference_model.forward_dynamics(tree, q0, v0 + 0.1), per="evaluation", count=1,
          configuration="5-link ball chain, one forward dynamics of the global reference model "
                        "(ctmm.reference.spatial_tree; the benchmark's only pure-ctmm code until ctmm.spatial lands)")


def _spatial_schemes(t: Timings) -> None:
    bench = importlib.import_module("spatial_schemes")
    model, _, x0, v0 = bench.double_pendulum()
    dt, steps = 0.01, 20
    t.add("spatial_schemes", "newmark_double_pendulum",
          lambda: ctmm.simulate(model, steps * dt, dt, method="newmark", x0=x0, v0=v0, store_every=steps),
          per="step", count=steps,
          configuration=f"spatial double pendulum (revolute + ball joint), Lie-group Newmark, dt={dt:g} s, "
                        f"{steps} steps (benchmark: 0.5 s)")


def _chain_compiled(t: Timings) -> None:
    bench = importlib.import_module("chain_compiled")
    system, n, steps = bench.model(100), 100, 1000
    x0 = {f"m{i}": float(value) for i, value in enumerate(bench.start(n))}
    chain = importlib.import_module("ctmm.compiled_chain").CompiledChain(system, dt=bench.DT, store_every=steps)
    first = np.concatenate(chain.plant.start(x0, None))
    t.add("chain_compiled", "generated_rk4_real_time_loop_n100", lambda: chain.run(first, bench.DT, steps),
          per="step", count=steps,
          configuration=f"chain of 100 masses, real-time loop m99.x -> m0, RK4 generated (CompiledChain.run, library "
                        f"loaded), dt={bench.DT:g} s, {steps} steps")


def _chain_schemes_generated(t: Timings) -> None:
    bench = importlib.import_module("chain_compiled")
    system, n, steps = bench.model(100), 100, 1000
    x0 = {f"m{i}": float(value) for i, value in enumerate(bench.start(n))}
    ctmm.simulate(system, steps * bench.DT, bench.DT, method="newmark", x0=x0, compiled=True, store_every=steps)
    t.add("chain_schemes_generated", "generated_newmark_real_time_loop_n100",
          lambda: ctmm.simulate(system, steps * bench.DT, bench.DT, method="newmark", x0=x0, compiled=True,
                                store_every=steps),
          per="step", count=steps,
          configuration=f"chain of 100 masses, real-time loop m99.x -> m0, DT-TMM Newmark generated "
                        f"(ctmm.simulate compiled=True, library cached), dt={bench.DT:g} s, {steps} steps")


def _chain_ode_speed(t: Timings) -> None:
    bench = importlib.import_module("chain_compiled")
    system, n, steps = bench.model(100), 100, 200
    x0 = {f"m{i}": float(value) for i, value in enumerate(bench.start(n))}
    t.add("chain_ode_speed", "simulate_rk4_loop_n100",
          lambda: ctmm.simulate(system, steps * bench.DT, bench.DT, method="rk4", x0=x0), per="step", count=steps,
          configuration=f"chain of 100 masses, real-time loop m99.x -> m0, Python RK4 on the certified affine "
                        f"rates (ctmm.simulate), dt={bench.DT:g} s, {steps} steps")


def _compiled_cosim(t: Timings) -> None:
    bench = importlib.import_module("compiled_cosim")
    model = bench.pendulum(5)
    dt, steps = 1e-3, 500
    pid = bench.load_controllers().PID("o.angle", "o.torque", kp=20.0, ki=5.0, kd=2.0, derivative_filter_time=0.01,
                                       sample_time=10 * dt, reference=0.3)
    x0 = np.full(5, 0.1)
    ctmm.simulate(model, steps * dt, dt, x0=x0, controllers=[pid], compiled=True)
    t.add("compiled_cosim", "generated_rk4_pid_every_10_steps_n5",
          lambda: ctmm.simulate(model, steps * dt, dt, x0=x0, controllers=[pid], compiled=True), per="step",
          count=steps,
          configuration=f"planar pendulum of 5 links, Python PID sampled every 10 steps, generated RK4 between "
                        f"samples (library cached), dt={dt:g} s, {steps} steps")


def _batch_parameters(t: Timings) -> None:
    bench = importlib.import_module("batch_parameters")
    n, count = 6, 4
    sets = [{f"h{i}.stiffness": 1.0 + 0.5 * k + 0.1 * i for i in range(n)} for k in range(count)]
    base = bench.planar_chain([1.0] * n, [1.0] * n)
    x0 = np.full(n, 0.2)
    ctmm.simulate_batch(base, sets, 0.2, 1e-3, x0=x0)
    t.add("batch_parameters", "simulate_batch_planar_chain_n6_4_sets",
          lambda: ctmm.simulate_batch(base, sets, 0.2, 1e-3, x0=x0), per="set", count=count,
          configuration=f"planar chain of {n} links, {count} stiffness sets on one generated kernel (library cached), "
                        "200 RK4 steps each")


def _compiled_schemes_planar(t: Timings) -> None:
    bench = importlib.import_module("compiled_schemes_planar")
    model = importlib.import_module("planar_chain").chain(5)
    q0 = v0 = np.zeros(5)
    compiled = importlib.import_module("ctmm.compiled_scene_schemes").CompiledSceneScheme(model, "newmark")
    steps = round(bench.T / bench.DT)
    t.add("compiled_schemes_planar", "generated_newmark_chain_n5",
          lambda: bench.generated_run(compiled, model, q0, v0, "newmark"), per="step", count=steps,
          configuration=f"planar pendulum chain N=5, DT-TMM Newmark with Newton in generated C "
                        f"(simulate_scheme_generated, library compiled), dt={bench.DT:g} s, {steps} steps")


def _compiled_schemes_default(t: Timings) -> None:
    bench = importlib.import_module("compiled_schemes_default")
    schemes = importlib.import_module("ctmm.compiled_scene_schemes")
    planar = importlib.import_module("ctmm.planar")
    for n in (15, 100):
        model, steps = bench.planar_model(n), 20
        zero = np.zeros(model.n_coordinates)
        compiled = schemes.CompiledSceneScheme(model, "newmark")          # the implicit-sweep iteration (O(N))
        for case, call in (("generated", lambda model=model, zero=zero, compiled=compiled:
                            schemes.simulate_scheme_generated(model, zero, zero, t_final=steps * bench.DT, dt=bench.DT,
                                                              compiled=compiled, stability_check="ignore")),
                           ("numpy", lambda model=model, zero=zero: planar.simulate_implicit(
                               model, zero, zero, t_final=steps * bench.DT, dt=bench.DT, stability_check="ignore"))):
            how = "library compiled, implicit-sweep iteration" if case == "generated" else "transfer-form Newton"
            t.add("compiled_schemes_default", f"{case}_newmark_chain_n{n}", call, per="step", count=steps,
                  configuration=f"planar pendulum chain N={n}, Newmark, {case} step ({how}), dt={bench.DT:g} s, "
                                f"{steps} steps")


def _kernel_cache(t: Timings) -> None:
    bench = importlib.import_module("kernel_cache")
    run = bench.cases()["spatial_revolute6_rk4"]
    run()                                       # compile once (or find the library in the cache)
    t.add("kernel_cache", "cached_call_spatial_revolute6_rk4", run, per="call", count=1,
          configuration="ctmm.simulate(compiled=True) of a 6-link spatial revolute chain, 1 s at dt = 1 ms, the "
                        "library already in the cache (key taken before the time loop is built)")
    for case, what in (("planar_pendulum10_newmark", "the generated Newmark of a 10-link planar pendulum chain"),
                       ("planar_pendulum10_loops_rk4", "the generated RK4 of a 10-link planar pendulum chain with a "
                                                       "real-time PD and a delayed loop (their numbers inputs p)")):
        run = bench.planar_cases()[case]
        run()                                   # compile once (or find the library in the cache)
        t.add("kernel_cache", f"cached_call_{case}", run, per="call", count=1,
              configuration=f"ctmm.simulate(compiled=True): {what}, 0.1 s at dt = 1 ms, the library already in the "
                            "cache (keyed on the description before anything is built, session 13)")


def _kinematic_loops_generated(t: Timings) -> None:
    bench = importlib.import_module("kinematic_loops_generated")
    loop, q0, v0 = bench.four_bar()
    kernel = bench.CompiledKinematicLoops(loop)
    steps = 1000
    t.add("kinematic_loops_generated", "generated_rk4_projection_four_bar", lambda: kernel.run(q0, v0, bench.DT, steps),
          per="step", count=steps,
          configuration=f"four-bar with the cubic rocker spring and damper closed by a cut joint, RK4 with the cut "
                        f"forces and the projection in the generated step (CompiledKinematicLoops.run, library "
                        f"loaded), dt={bench.DT:g} s, {steps} steps")
    spatial = bench.spatial_four_bar.mechanism()
    q0, v0 = bench.spatial_four_bar.start(spatial)
    spatial_kernel = bench.CompiledSpatialKinematicLoops(spatial)
    t.add("kinematic_loops_generated", "generated_rk4_projection_spatial_four_bar",
          lambda: spatial_kernel.run(q0, v0, bench.DT, steps), per="step", count=steps,
          configuration=f"R-U-S-R four-bar closed by a spherical cut, RK4 with the cut loads and the projection in "
                        f"the generated step (CompiledSpatialKinematicLoops.run, library loaded), dt={bench.DT:g} s, "
                        f"{steps} steps")
    flexible, q0, v0 = bench.flexible_four_bar()
    flexible_kernel = bench.CompiledKinematicLoops(flexible)
    flexible_steps = int(round(bench.T_FLEX / bench.FLEX_STEP))
    t.add("kinematic_loops_generated", "generated_rk4_projection_flexible_four_bar",
          lambda: flexible_kernel.run(q0, v0, bench.FLEX_STEP, flexible_steps), per="step", count=flexible_steps,
          configuration=f"four-bar with a 5-mode ModalBeam coupler (second-order inertia) cut at its end, RK4 with "
                        f"the cut force on the beam's frame and modes and the projection in the generated step "
                        f"(CompiledKinematicLoops.run, library loaded), dt={bench.FLEX_STEP:g} s, {flexible_steps} "
                        "steps")


def _generated_flags(t: Timings) -> None:
    bench = importlib.import_module("kinematic_loops_generated")
    loop, _, _ = bench.four_bar()
    with tempfile.TemporaryDirectory() as base:
        t.add("generated_flags", "first_compile_python_four_bar",
              lambda: bench.CompiledKinematicLoops(loop, cache_dir=tempfile.mkdtemp(dir=base)), per="compile", count=1,
              configuration="the planar four-bar's generated RK4 with projection (CompiledKinematicLoops) built in a "
                            "fresh cache folder: expressions, casadi functions and C text, CPU of this process (the "
                            "compiler's CPU, a child process, is benchmarks/generated_flags.py's compiler_cpu_s)")


def _spatial_scheme_tangent(t: Timings) -> None:
    bench = importlib.import_module("spatial_scheme_tangent")
    model, start = bench.tumbling_top()
    compiled = bench.CompiledSpatialScheme(model, "newmark")
    state, steps = compiled.initial_state(start), 200
    t.add("spatial_scheme_tangent", "generated_newmark_free_body",
          lambda: compiled.run(state, bench.DT, steps), per="step", count=steps,
          configuration=f"a tumbling free body (6 velocities), generated Lie-group Newmark with the default Newton "
                        f"tangent (CompiledSpatialScheme.run, library compiled), dt={bench.DT:g} s, {steps} steps "
                        "(the first compile's C and gcc CPU: benchmarks/spatial_scheme_tangent.py)")


def _chain_frf(t: Timings) -> None:
    bench = importlib.import_module("foundation_scaling")
    n = 1000
    system, omega = bench.ctmm_chain(n), bench.omega_grid(n)
    t.add("chain_frf", f"frequency_response_n{n}",
          lambda: ctmm.frequency_response(system, omega, input="m1.force", output=["m1.x", f"m{n}.x"]),
          per="call", count=1,
          configuration=f"fixed-free chain of {n} masses, {omega.size} frequencies, two outputs: the compiled "
                        "Riccati solve (ctmm.compiled_chain_frequency, library loaded; benchmarks/chain_frf.py)")


def _chain_setup_scaling(t: Timings) -> None:
    bench = importlib.import_module("chain_compiled")
    n, steps = 1000, 10
    system = bench.model(n).plant
    x0 = {f"m{i}": float(value) for i, value in enumerate(bench.start(n))}

    def call() -> object:
        return ctmm.simulate(system, steps * bench.DT, bench.DT, method="rk4", x0=x0, compiled=True,
                             store_every=steps)

    call()                                      # compile once (or find the library in the cache)
    t.add("chain_setup_scaling", f"cached_call_rk4_n{n}", call, per="call", count=1,
          configuration=f"ctmm.simulate(compiled=True) of the plain chain of {n} masses "
                        "(benchmarks/chain_compiled.py), "
                        f"RK4, {steps} steps of dt={bench.DT:g} s, the library already in the cache: the call's set-up "
                        "(affine form read and certified, key, loading) and result")


def _chain_default_limits(t: Timings) -> None:
    bench = importlib.import_module("chain_compiled")
    from ctmm.compiled_default import MAXIMUM_CHAIN_POINTS, dense_chain_reason

    n, steps = MAXIMUM_CHAIN_POINTS // 2 + 1, 10
    system = bench.model(n).plant
    x0 = {f"m{i}": float(value) for i, value in enumerate(bench.start(n))}
    t.add("chain_default_limits", f"dense_chain_reason_n{n}", lambda: dense_chain_reason(system), per="call", count=1,
          configuration=f"the default's kind check (ctmm.compiled_default.dense_chain_reason) of the plain chain of {n} "
                        "masses (benchmarks/chain_compiled.py), the smallest chain above the dense kinds' limit")

    def call() -> object:
        return ctmm.simulate(system, steps * bench.DT, bench.DT, method="newmark", x0=x0, compiled=True)

    call()                                      # compile once (or find the library in the cache)
    t.add("chain_default_limits", f"cached_call_newmark_n{n}", call, per="call", count=1,
          configuration=f"ctmm.simulate(compiled=True) of that chain, Newmark, {steps} steps of dt={bench.DT:g} s, "
                        "the library already in the cache: the generated DT-TMM call's set-up and result "
                        "(benchmarks/chain_default_limits.py measures the cold run end to end)")


TIMING_PARTS = (_work_precision, _scaling, _control, _delay_history, _planar, _flexible, _manipulator,
                _stability_chart, _compiled_scenes, _spatial_chain, _spatial_schemes, _chain_compiled,
                _chain_schemes_generated, _chain_ode_speed, _compiled_cosim, _batch_parameters, _kernel_cache,
                _planar_frf, _compiled_schemes_planar, _compiled_schemes_default, _spatial_frf,
                _kinematic_loops_generated, _chain_frf, _chain_setup_scaling, _chain_default_limits,
                _generated_flags, _spatial_scheme_tangent)


def timings() -> dict:
    """Per-step / per-sweep timings of every benchmark's cheapest configuration."""
    before = load()
    collected = Timings()
    for part in TIMING_PARTS:
        part(collected)
    return {"load_average_before": before, "load_average_after": load(), "repeats": REPEATS,
            "definition": ("best of REPEATS samples after one warm-up call, a sample = calls_per_sample calls "
                           f"lasting >= {MIN_SAMPLE_S} s together; cpu = time.process_time of this process "
                           "(single-threaded code), wall = time.perf_counter; per call = sample / calls_per_sample; "
                           "per unit = per call / count_per_call"),
            "cases": collected.cases}


def _pairs(baseline: dict, new: dict, part: str):
    """``(key, baseline case, new case or None)`` for every case of ``part`` when ``new`` measured it."""
    if part not in new:
        return
    cases = new[part].get("cases", {})
    for key, old in baseline.get(part, {}).get("cases", {}).items():
        yield key, old, cases.get(key)


def compare(baseline: dict, new: dict, *, slower: float = TIME_TOLERANCE) -> list[str]:
    """Differences of a new measurement from the baseline that break the plan's rules.

    A scenario that is missing, fails, or has a figure out of its bound or missing; a timing case
    that is missing or whose CPU time per unit exceeds the baseline's by more than ``slower``
    (relative).  Returns one line per problem (empty: the new code reproduces the baseline).
    """
    problems = []
    for name, old, case in _pairs(baseline, new, "scenarios"):
        if case is None:
            problems.append(f"scenario {name}: missing")
            continue
        figures = {figure["name"]: figure for figure in case["accuracy"]}
        for figure in old["accuracy"]:
            now = figures.get(figure["name"])
            if now is None:
                problems.append(f"scenario {name}: figure {figure['name']!r} missing")
            elif not now["passed"]:
                problems.append(f"scenario {name}: {figure['name']!r} = {now['value']!r} {now['unit']} exceeds its "
                                f"bound {now['bound']!r} (baseline {figure['value']!r})")
    for key, old, case in _pairs(baseline, new, "timings"):
        if case is None:
            problems.append(f"timing {key}: missing")
        elif case["cpu_s_per_unit"] > (1.0 + slower) * old["cpu_s_per_unit"]:
            ratio = case["cpu_s_per_unit"] / old["cpu_s_per_unit"]
            problems.append(f"timing {key}: {1e6 * case['cpu_s_per_unit']:.1f} us CPU per {case['per']} vs baseline "
                            f"{1e6 * old['cpu_s_per_unit']:.1f} us (+{100 * (ratio - 1):.0f} %)")
    return problems


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=("scenarios", "timings"), help="run one part only")
    parser.add_argument("--output", type=Path, default=None,
                        help=f"JSON file to write (default: {RESULTS.relative_to(ROOT)}; with --compare: none)")
    parser.add_argument("--compare", action="store_true",
                        help="measure and list what breaks the baseline's rules instead of replacing it")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    data = {"purpose": ("issue 12 S0 baseline (docs/plans/one_core.md §5): scenario accuracy figures (quick mode) "
                        "and per-step / per-sweep times of the benchmarks' cheapest configurations"),
            "machine": machine()}
    if args.only in (None, "scenarios"):
        data["scenarios"] = scenarios()
    if args.only in (None, "timings"):
        data["timings"] = timings()
        for _ in range(RETRIES if args.compare else 0):   # a slower case may be transient load: measure again
            baseline = json.loads(RESULTS.read_text())
            if not any(line.startswith("timing ") for line in compare(baseline, {"timings": data["timings"]})):
                break
            again = timings()["cases"]
            for key, case in data["timings"]["cases"].items():
                if key in again and again[key]["cpu_s_per_unit"] < case["cpu_s_per_unit"]:
                    data["timings"]["cases"][key] = again[key]
    data["total_wall_time_s"] = time.perf_counter() - started
    output = args.output if args.output is not None or args.compare else RESULTS
    if output is not None:
        write_json_atomic(output, data)
        print(f"wrote {output} in {data['total_wall_time_s']:.0f} s")
    if args.compare:
        problems = compare(json.loads(RESULTS.read_text()), data)
        checked = ["every scenario figure within its bound" if "scenarios" in data else "",
                   f"every timing within {100 * TIME_TOLERANCE:.0f} % (CPU)" if "timings" in data else ""]
        print("\n".join(problems) if problems else "baseline reproduced: " + ", ".join(filter(None, checked)))
        if problems:
            raise SystemExit(1)
    return data


if __name__ == "__main__":
    main()
