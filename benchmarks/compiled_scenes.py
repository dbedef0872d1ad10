"""Generated kernels (ctmm.compiled_scene): time, error and compile cost of the compiled paths.

Rows (time and error together, ratios from one run, ``benchmarks/results/compiled_scenes.json``):

1. **Flexible hub-beam** (hub on a constant-torque hinge, modal beam with 3 bending modes and
   geometric stiffening, horizontal plane), ``T_HUB`` s: wall time, real-time factor, first-compile
   time, and the tip-deflection error (``w_tip = phi(L) . q``, max over the run, relative to its peak)
   against the independent Lagrange model (``reference/flexible_lagrange.py``) integrated by
   ``solve_ivp`` DOP853 at rtol 1e-12; the numpy path at the same step for the ratio.
2. **Rigid pendulum chain** N = 5, 20, 100 (unit links, smooth hinges, gravity), 1 s at dt = 1e-3:
   per-step time of the generated path and its RK4 error against a dt/4 run of itself; first-compile
   time in a fresh cache folder (numbers as inputs, the default, and as constants).  Before the
   hand-typed C (``ctmm.planar.compiled``) was removed (issue 13), both ran side by side in one run
   (2026-11-25, 2-core machine, best of 3): generated 1.62 / 4.86 / 24.4 us per step at N = 5 / 20 /
   100, hand-typed 0.93 / 3.88 / 20.0 (ratios 1.75 / 1.26 / 1.22), trajectories equal to 1.3e-15 rad.
   The comparison with Pinocchio and MuJoCo is ``benchmarks/planar_chain.py``.
3. **Manipulator** (seed arm, 3 modes, stiffening, hub PD and PZT loops, cycloidal move, 3 s at
   dt = 1e-3): per-step time of ``CompiledManipulator`` -- since issue 13 the controlled scene through
   the generated kernels (:mod:`ctmm.compiled_loops`) -- and of the same scene with delayed loops (PD
   10 ms, PZT 2 ms) through ``ctmm.simulate(..., compiled=True)``; errors against the numpy path of
   the same model (first 0.2 s).  Before the hand-derived closed form was removed, both ran side by
   side in one run (2026-11-25, 2-core machine, best of 5): closed form 2.99 / 0.48 us per step
   (store every 1 / 5 steps), generated 2.66 / 0.56 (PD), 2.91 / 0.51 vs 2.78 / 0.67 (PD + PZT):
   ratios 0.89-1.33, tip deflections equal to 4e-16 m.
4. **Parameter sweep** (issue 13 item 4): the hub-beam with 10 sets of hub mass, hub inertia and motor
   torque, 0.5 s at dt = 1e-3 each: (a) one compile per set (the numbers as constants of the C: a
   fresh cache folder per set, the behaviour before parameters became inputs), (b) one compile, then
   each set on the same library (``CompiledScene.with_model``), (c) one compile, the 10 sets in one
   ``simulate_batch`` (``casadi.Function.map``).  Whole wall time of each (build, generate, compile,
   run) and the largest difference of (b) and (c) from (a) (round-off).

Run: ``python benchmarks/compiled_scenes.py [--quick]``.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from scipy.integrate import solve_ivp  # noqa: E402

from ctmm.compiled_scene import CompiledScene, parameter_vector, simulate_batch, simulate_rk4_generated  # noqa: E402
from ctmm.flexible import ModalBeam  # noqa: E402
import ctmm  # noqa: E402
from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_MOVE, SEED_PZT_GAIN, HubPD,  # noqa: E402
                              PZTFeedback, manipulator_scene, seed_manipulator)
from ctmm.manipulator.compiled import CompiledManipulator, cycloid_reference  # noqa: E402
from ctmm.manipulator.scene import HUB_LOOP  # noqa: E402
from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody  # noqa: E402
from ctmm.planar.elements import FixedMounting  # noqa: E402
from ctmm.planar.integrate import simulate_rk4  # noqa: E402
from ctmm.reference.flexible_lagrange import FlexibleLagrange  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from planar_chain import chain  # noqa: E402  (the pendulum chain of benchmarks/planar_chain.py)

T_HUB = 2.0
T_CHAIN, H_CHAIN = 1.0, 1e-3
T_MANIPULATOR, H_MANIPULATOR = 3.0, 1e-3


def hub_beam(hub_mass: float = 2.0, hub_inertia: float = 0.05, torque: float = 2.0) -> PlanarModel:
    beam = ModalBeam("beam", length=1.0, bending_stiffness=12.0, mass_per_length=0.8, n_modes=3,
                     geometric_stiffening=True, damping_ratio=0.005)
    return PlanarModel.chain("hub_beam", [
        Fixed("ground"), ActuatedHinge("motor", torque=torque),
        RigidBody("hub", mass=hub_mass, inertia=hub_inertia, center_of_mass=(0.0, 0.0), outboard=(0.1, 0.0)),
        FixedMounting("mount"), beam], gravity=(0.0, 0.0))


def best_of(run, repeats: int = 3):
    """Result and best wall time of the time loop alone (``wall_time_s``; for the generated path the
    scene is built, its C text generated and hashed and the cached library loaded before it: that
    per-call cost is :func:`call_overhead`)."""
    out, best = None, np.inf
    for _ in range(repeats):
        out = run()
        best = min(best, out.wall_time_s)
    return out, best


def call_overhead(run) -> float:
    """Whole-call wall time minus the time loop [s] (build, C generation, hash, load; warm cache)."""
    start = time.perf_counter()
    out = run()
    return time.perf_counter() - start - out.wall_time_s


def first_compile(model: PlanarModel, numbers: str = "inputs") -> float:
    with tempfile.TemporaryDirectory() as folder:
        return CompiledScene(model, cache_dir=folder, numbers=numbers).compile_time_s


def hub_beam_row(quick: bool) -> dict:
    model = hub_beam()
    n = model.n_coordinates
    q0, v0 = np.zeros(n), np.zeros(n)
    lagrange = FlexibleLagrange(model)
    tip = model.beams[model.body_names.index("beam")].data.tip_phi
    modal = [model.coordinates.index(f"beam.q{k}") for k in (1, 2, 3)]
    start = time.perf_counter()
    reference = solve_ivp(lambda t, y: np.concatenate([y[n:], lagrange.accelerations(y[:n], y[n:], t)]),
                          (0.0, T_HUB), np.zeros(2 * n), method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True)
    reference_wall = time.perf_counter() - start
    compile_s = first_compile(model)
    rows = []
    for dt in ((2e-3, 1e-3) if quick else (2e-3, 1e-3, 5e-4)):
        simulation, wall = best_of(lambda: simulate_rk4_generated(model, q0, v0, t_final=T_HUB, dt=dt))
        expected = reference.sol(simulation.t)[:n].T
        w_ref = expected[:, modal] @ tip
        error = float(np.max(np.abs(simulation.q[:, modal] @ tip - w_ref)) / np.max(np.abs(w_ref)))
        overhead = call_overhead(lambda: simulate_rk4_generated(model, q0, v0, t_final=T_HUB, dt=dt))
        row = {"dt": dt, "generated_wall_s": wall, "generated_call_overhead_s": overhead,
               "real_time_factor": T_HUB / wall,
               "per_step_us": wall / round(T_HUB / dt) * 1e6, "tip_error_of_peak": error,
               "tip_peak_m": float(np.max(np.abs(w_ref)))}
        if dt == 2e-3:
            numpy_path = simulate_rk4(model, q0, v0, t_final=T_HUB, dt=dt)
            row["numpy_wall_s"] = numpy_path.wall_time_s
            row["numpy_over_generated"] = numpy_path.wall_time_s / wall
            row["generated_minus_numpy"] = float(np.max(np.abs(simulation.q - numpy_path.q)))
        rows.append(row)
        print(f"hub-beam dt={dt:g}: {wall * 1e3:8.2f} ms  RTF {T_HUB / wall:9.0f}  tip error {error:.2e} of peak")
    return {"first_compile_s": compile_s, "reference_wall_s": reference_wall, "rows": rows}


def chain_rows(quick: bool) -> list:
    rows = []
    steps = round(T_CHAIN / H_CHAIN)
    for n in ((5, 20) if quick else (5, 20, 100)):
        model = chain(n)
        q0, v0 = np.full(n, 0.3), np.zeros(n)
        compile_s = first_compile(model)
        simulate_rk4_generated(model, q0, v0, t_final=T_CHAIN, dt=H_CHAIN)               # load into the cache
        generated, generated_wall = best_of(lambda: simulate_rk4_generated(model, q0, v0, t_final=T_CHAIN,
                                                                           dt=H_CHAIN))
        fine = simulate_rk4_generated(model, q0, v0, t_final=T_CHAIN, dt=H_CHAIN / 4, store_every=4)
        overhead = call_overhead(lambda: simulate_rk4_generated(model, q0, v0, t_final=T_CHAIN, dt=H_CHAIN))
        row = {"n": n, "first_compile_s": compile_s, "generated_call_overhead_s": overhead,
               "first_compile_numbers_as_constants_s": first_compile(model, "constants"),
               "generated_per_step_us": generated_wall / steps * 1e6,
               "rk4_error_generated_rad": float(np.max(np.abs(generated.q[-1] - fine.q[-1])))}
        rows.append(row)
        print(f"chain N={n:4d}: generated {row['generated_per_step_us']:8.2f} us/step, compile {compile_s:.2f} s, "
              f"RK4 error {row['rk4_error_generated_rad']:.1e} rad")
    return rows


def manipulator_row() -> dict:
    """The seed manipulator (PD + PZT loops, cycloidal move): ``CompiledManipulator`` (now the generated
    scene) and the same scene with delayed loops through ``ctmm.simulate(..., compiled=True)``, each
    against the numpy path of the same model over the first 0.2 s."""
    arm = seed_manipulator()
    pd, pzt = HubPD(SEED_KP, SEED_KD), PZTFeedback(SEED_PZT_GAIN * np.eye(arm.n_patches))
    compiled = CompiledManipulator(arm, pd, pzt, SEED_MOVE, block=1, chunks=50)
    compiled.simulate(T_MANIPULATOR, H_MANIPULATOR)
    embedded, embedded_wall = best_of(lambda: compiled.simulate(T_MANIPULATOR, H_MANIPULATOR))
    short = ctmm.simulate(manipulator_scene(arm, pd=pd, pzt=pzt), 0.2, H_MANIPULATOR, outputs=["arm.tip.w"],
                          references={HUB_LOOP: cycloid_reference(SEED_KP, SEED_KD, SEED_MOVE)})
    steps = round(T_MANIPULATOR / H_MANIPULATOR)
    late = manipulator_scene(arm, pd=HubPD(SEED_KP, SEED_KD, delay=0.01), pzt=PZTFeedback(pzt.gains, delay=0.002))
    references = {HUB_LOOP: cycloid_reference(SEED_KP, SEED_KD, SEED_MOVE)}
    def run_delayed():
        return ctmm.simulate(late, T_MANIPULATOR, H_MANIPULATOR, references=references, compiled=True,
                             outputs=["arm.tip.w"])

    start = time.perf_counter()
    run_delayed()
    first_call = time.perf_counter() - start
    delayed = min((run_delayed() for _ in range(3)), key=lambda r: r.info["wall_time_s"])
    numpy_run = ctmm.simulate(late, 0.2, H_MANIPULATOR, references=references, outputs=["arm.tip.w"])
    rows = len(numpy_run.time)
    row = {"embedded_per_step_us": embedded_wall / steps * 1e6,
           "embedded_real_time_factor": T_MANIPULATOR / embedded_wall,
           "embedded_minus_numpy_tip_first_0p2s": float(np.max(np.abs(embedded.tip_deflection[:len(short.time)]
                                                                      - short["arm.tip.w"]))),
           "delayed_first_call_s": first_call,
           "delayed_per_step_us": delayed.info["wall_time_s"] / steps * 1e6,
           "delayed_real_time_factor": T_MANIPULATOR / delayed.info["wall_time_s"],
           "delayed_numpy_per_step_us": numpy_run.info["wall_time_s"] / (rows - 1) * 1e6,
           "delayed_minus_numpy_tip_first_0p2s": float(np.max(np.abs(delayed["arm.tip.w"][:rows]
                                                                     - numpy_run["arm.tip.w"])))}
    row["delayed_numpy_over_generated"] = row["delayed_numpy_per_step_us"] / row["delayed_per_step_us"]
    print(f"manipulator: embedded {row['embedded_per_step_us']:.2f} us/step "
          f"(RTF {row['embedded_real_time_factor']:.0f}); "
          f"delayed loops {row['delayed_per_step_us']:.2f} us/step generated vs {row['delayed_numpy_per_step_us']:.0f} "
          f"us/step numpy, |diff| {row['delayed_minus_numpy_tip_first_0p2s']:.1e} m")
    return row


def parameter_sweep_row(sets: int = 10, t_final: float = 0.5, dt: float = 1e-3) -> dict:
    models = [hub_beam(2.0 + 0.2 * k, 0.05 + 0.01 * k, 2.0 - 0.1 * k) for k in range(sets)]
    n, steps = models[0].n_coordinates, round(t_final / dt)
    zero = np.zeros(n)
    start = time.perf_counter()
    recompiled = []
    for model in models:
        with tempfile.TemporaryDirectory() as folder:
            recompiled.append(CompiledScene(model, cache_dir=folder).run(zero, zero, dt, steps))
    recompile_s = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        scene = CompiledScene(models[0], cache_dir=folder)
        reused = [scene.with_model(model).run(zero, zero, dt, steps) for model in models]
        reuse_s = time.perf_counter() - start
        start = time.perf_counter()
        scene = CompiledScene(models[0], cache_dir=folder, rows=64)      # from the cache: generate, hash, load
        batch = simulate_batch(scene, np.array([parameter_vector(m) for m in models]), zero, zero, dt=dt,
                               n_steps=steps)
        batch_s = time.perf_counter() - start
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        scene = CompiledScene(models[0], cache_dir=folder)
        batch = simulate_batch(scene, np.array([parameter_vector(m) for m in models]), zero, zero, dt=dt,
                               n_steps=steps)
        batch_fresh_s = time.perf_counter() - start
    row = {"sets": sets, "steps": steps, "recompile_each_s": recompile_s, "compile_once_run_each_s": reuse_s,
           "compile_once_batch_s": batch_fresh_s, "batch_from_cache_s": batch_s,
           "recompile_over_compile_once": recompile_s / reuse_s,
           "reuse_minus_recompiled": float(max(np.max(np.abs(a - b)) for a, b in zip(reused, recompiled))),
           "batch_minus_recompiled": float(max(np.max(np.abs(a - b)) for a, b in zip(batch, recompiled)))}
    print(f"parameter sweep ({sets} sets, {steps} steps): recompile each {recompile_s:.2f} s, compile once "
          f"{reuse_s:.2f} s (x{row['recompile_over_compile_once']:.1f}), batch {batch_fresh_s:.2f} s, "
          f"|diff| {row['reuse_minus_recompiled']:.1e} / {row['batch_minus_recompiled']:.1e}")
    return row


def main(quick: bool = False) -> dict:
    results = {"machine": platform.machine(), "python": platform.python_version(), "quick": quick,
               "hub_beam": hub_beam_row(quick), "chain": chain_rows(quick), "manipulator": manipulator_row(),
               "parameter_sweep": parameter_sweep_row()}
    out = ROOT / "benchmarks" / "results" / "compiled_scenes.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    print(f"wrote {out}")
    return results


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    main(parser.parse_args().quick)
