"""Co-simulated controllers around generated kernels (``compiled=True`` with ``controllers``, ctmm.compiled_cosim).

Rows (time and error together, ratios from one run, ``benchmarks/results/compiled_cosim.json``); each row is
the per-step wall time of the numpy path and of the generated path with the same controllers, their ratio,
and the error:

1. **Linear torsion plant** (one body on an elastic hinge, no gravity) with a sampled P controller
   (``ctmm.controllers.PID``, h = 20 ms), dt = h / 4, ``T`` s: error of both paths against the exact
   sampled-data solution (``scipy.linalg.expm`` of the plant with the held input) [rad].
2. **Planar pendulum chain** N = 5 and 20 (unit links, smooth hinges, gravity), dt = 1 ms, a PID on the
   first hinge sampled every 10 steps and every step (the worst case: one call into C per step): largest
   difference generated - numpy over the coordinates [rad].
3. **Spatial arm** (``tests/test_spatial_control_time.arm``: yaw, 2-axis elbow, ball wrist) with two of
   its real-time loops in the step and a PID on the yaw joint every 10 steps, dt = 2 ms, 0.4 s (the arm
   tumbles later): the same difference.
4. **1-D chains** (``method="rk4"``, :mod:`ctmm.compiled_chain`): one mass on a spring with a sampled P controller
   on its force (h = 20 ms, dt = h / 4, ``T`` s): error of both paths against the exact sampled-data solution
   (``scipy.linalg.expm``) [m]; and N = 50 masses (spring-dampers, wall to free end) with a PID on the last mass
   every 10 steps and a real-time loop inside the step, dt = 1 ms: the largest difference generated - numpy over
   the positions [m].
5. **1-D chains on a DT-TMM scheme** (``method="newmark"`` / ``"houbolt"``, :mod:`ctmm.compiled_chain_schemes` with
   the controllers' held outputs as its input, ``--only schemes``): the one-mass P loop of 4. (T = 10 s) with both
   paths' error against the exact sampled-data solution and their difference; N = 5 and 50 masses, a real-time loop
   in the step and a PID every 10 steps, 2 s at 1 ms: their difference [m].
6. **Short intervals** (``--only intervals``, :func:`interval_rows`, ``benchmarks/results/compiled_cosim_intervals.json``):
   the planar pendulum N = 5 (RK4 and Newmark) and the one-mass chain with a PID every 1, 10 and 100 steps of 1 ms,
   CPU time: the overhead per sample beyond the generated run without controllers, and the whole-run ratio.

The first compile is excluded (a warm-up run fills the kernel cache); each timed ``ctmm.simulate`` call still
builds its kernel from the cache (expressions, C text and its hash, loading the library), which weighs on
short runs (the spatial row: 200 steps); best of :data:`REPEATS`.

Measured (2026-11-25, 2-core machine shared with other work, one run): torsion 367 / 51 us per step (7.2x),
both 5.8e-7 rad from the exact ZOH solution (the RK4 error at dt = 5 ms); pendulum N = 5: 214 / 21 us (10x)
every 10 steps, 290 / 126 us (2.3x) every step; N = 20: 409 / 59 us (6.9x), 326 / 112 us (2.9x); spatial arm
5.2 ms / 430 us (12x); every difference generated - numpy <= 9e-15.  Chains (the same day): one mass 126 / 38 us
per step (3.3x), both 1.75e-8 m from the exact ZOH solution (T = 10 s, dt = 5 ms); N = 50 masses 247 / 73 us (3.4x),
difference 0 (the chain's guard is checked at every step in Python on both paths, and the stored forces are
formed in Python on both).
  DT-TMM schemes (5., the same day, one run): one mass Newmark 261 / 128 us per step (2.0x), both
2.800e-4 m from the exact ZOH solution (Newmark's error at dt = 5 ms), difference 2e-16 m; Houbolt 272 / 118 us
(2.3x), both 1.85e-2 m from it (Houbolt's backward differences span the jumps of the held force), difference 0;
N = 5 masses Newmark 2.41 ms / 116 us (21x), N = 50: 14.9 ms / 186 us (80x), differences <= 5e-16 m.  The generated
side is a Python loop per sample interval (the chain's guard at every step, the sample, one call into C).
  Short intervals (6., 2026-11-25, load 5-7, CPU, best of 5, four runs before / three after the rows of an
interval were handled as a block, alternating): overhead per sample, every step / 10 / 100 steps: planar RK4
29-32 / 39-51 / 75-95 us -> 20-22 / 47-50 / 60-73 us; Newmark 80-94 / 127-181 / 629-658 -> 81-89 / 110-132 / 125-169
us; chain 24-26 / 74-84 / 392-479 -> 24-25 / 51-67 / 181-210 us (docs/control.md, "Short sample intervals").

Run: ``python benchmarks/compiled_cosim.py [--quick] [--only schemes | intervals]``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

import ctmm  # noqa: E402
from ctmm.control import with_feedback  # noqa: E402
from ctmm.planar import ElasticHinge, Fixed, PlanarModel, Pinned, RigidBody, SmoothHinge  # noqa: E402

from _controllers_import import load_controllers  # noqa: E402
from test_compiled_cosim import sampled_p_loop  # noqa: E402

REPEATS = 3
INTERVAL_REPEATS = 5     # the short-interval rows (6.): CPU time, best of five
STIFFNESS, INERTIA = 40.0, 0.5


def best(run, repeats: int = REPEATS):
    """``(result, best wall time [s])`` of ``run()`` after one warm-up call."""
    result = run()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return result, min(times)


def row(name: str, steps: int, numpy_run, compiled_run, error) -> dict:
    python, t_python = best(numpy_run)
    generated, t_generated = best(compiled_run)
    out = {"case": name, "steps": steps, "numpy_us_per_step": 1e6 * t_python / steps,
           "compiled_us_per_step": 1e6 * t_generated / steps, "speedup": t_python / t_generated,
           **error(python, generated)}
    print(json.dumps(out))
    return out


def torsion_case(t_final: float) -> dict:
    kp, r, h, theta0 = 12.0, 0.2, 0.02, 0.1
    dt = h / 4
    model = PlanarModel.chain("torsion", [Fixed("g"), ElasticHinge("h", stiffness=STIFFNESS),
                                          RigidBody("b", mass=1.0, inertia=INERTIA, center_of_mass=(0.0, 0.0))],
                              gravity=(0.0, 0.0))
    pid = load_controllers().PID("h.angle", "h.torque", kp=kp, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                 sample_time=h, reference=r)
    exact = sampled_p_loop(STIFFNESS, INERTIA, kp, r, h, theta0, round(t_final / h))

    def error(python, generated) -> dict:
        return {"numpy_error_rad": float(np.max(np.abs(python["b.theta"][::4] - exact))),
                "compiled_error_rad": float(np.max(np.abs(generated["b.theta"][::4] - exact)))}

    def run(compiled):
        return lambda: ctmm.simulate(model, t_final, dt, x0=[theta0], controllers=[pid], compiled=compiled)

    return row("torsion P controller, h = 4 dt", round(t_final / dt), run(None), run(True), error)


def pendulum(n: int) -> PlanarModel:
    elements = [Pinned("o"), RigidBody.uniform_link("l0", mass=1.0, length=1.0)]
    for i in range(1, n):
        elements += [SmoothHinge(f"h{i}"), RigidBody.uniform_link(f"l{i}", mass=1.0, length=1.0)]
    return PlanarModel.chain(f"pendulum{n}", elements)


def difference(coordinates):
    def error(python, generated) -> dict:
        return {"largest_difference": float(max(np.max(np.abs(generated[c] - python[c])) for c in coordinates))}
    return error


def pendulum_case(n: int, every: int, t_final: float) -> dict:
    dt = 1e-3
    model = pendulum(n)
    pid = load_controllers().PID("o.angle", "o.torque", kp=20.0, ki=5.0, kd=2.0, derivative_filter_time=0.01,
                                 sample_time=every * dt, reference=0.3)
    x0 = np.full(n, 0.1)

    def run(compiled):
        return lambda: ctmm.simulate(model, t_final, dt, x0=x0, controllers=[pid], compiled=compiled,
                                     stability_check="ignore")

    return row(f"pendulum N = {n}, PID every {every} steps", round(t_final / dt), run(None), run(True),
               difference(model.coordinates))


def spatial_case(t_final: float) -> dict:
    from test_spatial_control_time import LOOPS, V0, X0, arm

    dt = 2e-3
    model = arm()
    pid = load_controllers().PID("yaw.angle", "yaw.torque", kp=4.0, ki=2.0, kd=0.3, derivative_filter_time=0.02,
                                 sample_time=10 * dt, reference=0.1)
    controlled = with_feedback(model, LOOPS[1:])

    def run(compiled):
        return lambda: ctmm.simulate(controlled, t_final, dt, x0=X0, v0=V0, controllers=[pid], compiled=compiled)

    return row("spatial arm, 2 loops + PID every 10 steps", round(t_final / dt), run(None), run(True),
               difference(list(model.coordinates) + list(model.velocities)))


def chain_zoh_case(t_final: float, method: str = "rk4") -> dict:
    from ctmm.elements import Fixed as Wall, Free, Mass, Spring

    kp, r, h, x0, stiffness, mass = 30.0, 0.02, 0.02, 0.05, 50.0, 2.0
    dt = h / 4
    chain = ctmm.Chain("one", [Wall("w"), Spring("k", stiffness), Mass("m", mass), Free("e")])
    pid = load_controllers().PID("m.x", "m.force", kp=kp, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                 sample_time=h, reference=r)
    exact = sampled_p_loop(stiffness, mass, kp, r, h, x0, round(t_final / h))

    def error(python, generated) -> dict:
        return {"numpy_error_m": float(np.max(np.abs(python["m.x"][::4] - exact))),
                "compiled_error_m": float(np.max(np.abs(generated["m.x"][::4] - exact))),
                "largest_difference": float(np.max(np.abs(generated["m.x"] - python["m.x"])))}

    def run(compiled):
        return lambda: ctmm.simulate(chain, t_final, dt, method=method, x0={"m": x0}, controllers=[pid],
                                     compiled=compiled)

    return row(f"chain, one mass, P controller, h = 4 dt, {method}", round(t_final / dt), run(None), run(True),
               error)


def chain_case(n: int, t_final: float, method: str = "rk4") -> dict:
    from ctmm.control import ControlledChain, Feedback
    from ctmm.elements import Fixed as Wall, Free, Mass, SpringDamper

    dt = 1e-3
    elements = [Wall("w")]
    for i in range(n):
        elements += [SpringDamper(f"k{i}", 1e3, 0.5), Mass(f"m{i}", 1.0)]
    chain = ctmm.Chain(f"chain{n}", elements + [Free("e")])
    system = ControlledChain(chain, [Feedback("damp", "m0.v", "m0", gain=5.0)])
    last = f"m{n - 1}"
    pid = load_controllers().PID(f"{last}.x", f"{last}.force", kp=200.0, ki=50.0, kd=20.0,
                                 derivative_filter_time=0.01, sample_time=10 * dt, reference=0.05)

    def run(compiled):
        return lambda: ctmm.simulate(system, t_final, dt, method=method, x0={"m0": 0.01}, controllers=[pid],
                                     compiled=compiled)

    return row(f"chain N = {n} masses, loop + PID every 10 steps, {method}", round(t_final / dt), run(None),
               run(True), difference([f"m{i}.x" for i in range(n)]))


def cpu_best(run, repeats: int = REPEATS) -> float:
    """Best CPU time [s] (``time.process_time``: the machine is shared) of ``run()`` after one warm-up call."""
    run()
    times = []
    for _ in range(repeats):
        start = time.process_time()
        run()
        times.append(time.process_time() - start)
    return min(times)


def interval_rows(kind: str, lengths: tuple[float, float]) -> list[dict]:
    """Per-sample cost of short co-simulation intervals (6.): a PID sampled every 1, 10 and 100 steps (one call into
    C per interval), CPU time of ``ctmm.simulate(..., compiled=True)`` at two run lengths against the same generated
    run without controllers; the per-sample overhead is the slope ``((co_2 - co_1) - (pure_2 - pure_1)) /
    (samples_2 - samples_1)`` (the fixed cost of loading the kernel from the cache drops out), the whole-run ratio
    ``co_2 / pure_2`` keeps it."""
    dt = 1e-3
    if kind in ("planar", "planar newmark"):
        model, x0 = pendulum(5), np.full(5, 0.1)
        sensor, actuator, extra = "o.angle", "o.torque", {"x0": x0, "stability_check": "ignore"}
        label = "planar pendulum N = 5"
        if kind == "planar newmark":        # the generated DT-TMM step (compiled_scheme_cosim)
            extra["method"], label = "newmark", label + ", Newmark"
    else:
        from ctmm.elements import Fixed as Wall, Free, Mass, Spring

        model = ctmm.Chain("one", [Wall("w"), Spring("k", 50.0), Mass("m", 2.0), Free("e")])
        sensor, actuator, extra, label = "m.x", "m.force", {"method": "rk4", "x0": {"m": 0.05}}, "chain, one mass"
    out = []
    pure_runs: dict = {}
    for every in (1, 10, 100):
        if every == 100:                # five times longer runs: enough samples for the slope
            lengths = (5 * lengths[0], 5 * lengths[1])
        if lengths not in pure_runs:
            pure_runs[lengths] = [cpu_best(lambda: ctmm.simulate(model, t_final, dt, compiled=True, **extra),
                                           INTERVAL_REPEATS) for t_final in lengths]
        pure = pure_runs[lengths]
        pid = load_controllers().PID(sensor, actuator, kp=20.0, ki=5.0, kd=2.0, derivative_filter_time=0.01,
                                     sample_time=every * dt, reference=0.03)
        cosim = [cpu_best(lambda: ctmm.simulate(model, t_final, dt, controllers=[pid], compiled=True, **extra),
                          INTERVAL_REPEATS) for t_final in lengths]
        samples = [round(t_final / dt) / every for t_final in lengths]
        steps = round(lengths[1] / dt)
        entry = {"case": f"{label}, PID every {every} steps (CPU)", "steps": steps,
                 "overhead_us_per_sample": 1e6 * ((cosim[1] - cosim[0]) - (pure[1] - pure[0])) / (samples[1] - samples[0]),
                 "cosim_us_per_step": 1e6 * cosim[1] / steps, "pure_generated_us_per_step": 1e6 * pure[1] / steps,
                 "whole_run_ratio": cosim[1] / pure[1], "fixed_ms": 1e3 * (cosim[0] - (cosim[1] - cosim[0])
                                                                           * lengths[0] / (lengths[1] - lengths[0]))}
        print(json.dumps(entry))
        out.append(entry)
    return out


def main(quick: bool, only: str | None = None) -> None:
    scale = 0.2 if quick else 1.0
    if only == "schemes":           # the DT-TMM rows only (5.)
        rows = [chain_zoh_case(10.0 * scale, method) for method in ("newmark", "houbolt")]
        rows += [chain_case(n, 2.0 * scale, "newmark") for n in (5, 50)]
        out = ROOT / "benchmarks" / "results" / "compiled_cosim_schemes.json"
        out.parent.mkdir(exist_ok=True)
        out.write_text(json.dumps({"quick": quick, "rows": rows}, indent=2))
        print(f"wrote {out}")
        return
    if only == "intervals":         # the per-sample cost of short intervals only (6.)
        lengths = (0.05, 0.5) if quick else (0.2, 2.0)
        rows = [row for kind in ("planar", "planar newmark", "chain") for row in interval_rows(kind, lengths)]
        out = ROOT / "benchmarks" / "results" / "compiled_cosim_intervals.json"
        out.parent.mkdir(exist_ok=True)
        out.write_text(json.dumps({"quick": quick, "load": os.getloadavg(), "rows": rows}, indent=2))
        print(f"wrote {out}")
        return
    scale = 0.2 if quick else 1.0
    rows = [torsion_case(10.0 * scale)]
    for n in (5, 20):
        for every in (10, 1):
            rows.append(pendulum_case(n, every, 2.0 * scale))
    rows.append(spatial_case(0.4 * scale))
    rows += [chain_zoh_case(10.0 * scale), chain_case(50, 2.0 * scale)]
    out = ROOT / "benchmarks" / "results" / "compiled_cosim.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps({"quick": quick, "rows": rows}, indent=2))
    print(f"wrote {out}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short runs (a smoke test)")
    parser.add_argument("--only", choices=("schemes", "intervals"),
                        help="only the DT-TMM scheme rows (5.) or the short-interval rows (6.)")
    arguments = parser.parse_args()
    main(arguments.quick, arguments.only)
