"""Planar and spatial models: generated DT-TMM schemes (Newton in C) vs the Python implicit steppers, per step, error.

Models: the pendulum chain of ``benchmarks/planar_chain.py`` at N = 5 (rigid, gravity, start horizontal at rest)
and the hub-beam of ``benchmarks/compiled_scenes.py`` (3 bending modes, geometric stiffening, constant motor
torque).  Same machine, same run, dt = 1 ms:

* ``generated`` -- :func:`ctmm.compiled_scene_schemes.simulate_scheme_generated` (``ctmm.simulate(...,
  method=<scheme>, compiled=True)``) over ``T`` = 1 s, the library already compiled (the first call, generate +
  compile or load, timed apart);
* ``python``    -- :func:`ctmm.planar.implicit.simulate_implicit` over the first :data:`PYTHON_STEPS` steps.

Per scheme: wall time per step of each [s], the speed-up, max |q_generated - q_python| over the Python horizon
(consistency, round-off expected) and the error of the generated run at ``T`` against DOP853 (rtol 1e-12) of
the independent Lagrange model (:mod:`ctmm.reference.planar_lagrange`, :mod:`ctmm.reference.flexible_lagrange`).
Spatial part (:mod:`ctmm.compiled_spatial_schemes`): a double pendulum (revolute link carrying a link on a ball
joint), the same measures against :func:`ctmm.spatial.implicit.simulate_spatial_implicit` and the fine RK4 (dt =
0.1 ms) of the independent Newton-Euler model (:mod:`ctmm.reference.spatial_tree`), error: the largest difference of
the coordinates (quaternion of the ball joint) and velocities at ``T``.
Loops part (:mod:`ctmm.compiled_scheme_loops`, model ``chain_n5_pd_loops``): the N = 5 chain with a real-time PD
loop on every hinge (``u_i = -(20 angle_i + 2 rate_i)``, reference 0.3 rad on the base), the loops inside the
generated Newton step vs the Python DT-TMM path with the same loops (``ctmm.simulate(ControlledModel(chain,
loops), method=<scheme>)``, loops through its ``inputs`` hook), the same measures; error at ``T``: none (no
independent reference here; ``tests/test_compiled_scene_schemes_loops.py`` has the Lagrange one); the same with
every loop delayed by 2 ms (``chain_n5_delayed_pd_loops``, the ring: samples, Wilson-theta between them), by
2.5 ms (``chain_n5_fractional_pd_loops``: cubic Hermite between the samples, the rates stored), and delayed by
2.5 ms with a co-simulated PID (``ctmm.controllers.PID``, 10 ms) on the last hinge beside the loops
(``chain_n5_pd_loops_controller``: one call into C per sample interval, :mod:`ctmm.compiled_scheme_cosim`).
Spatial loops part (:mod:`ctmm.compiled_spatial_scheme_loops`, ``spatial_double_pendulum_pd_loop``): the spatial
double pendulum with a real-time PD on its hinge inside the generated Lie-group Newton step vs the Python DT-TMM path,
error at ``T`` against DOP853 on the reference tree with the same law; ``..._delayed``: the PD 2.5 ms late (Hermite).
Chain sizes part (:func:`chain_size_rows`, ``--chain-sizes``): the first compile and CPU per step of the generated
Newmark on pendulum chains of N = 10, 20, 30, 100 with the Newton tangent by mapped forward derivatives
(:mod:`ctmm.mapped_tangent`, the sweep folded from ``SCHEME_FOLD_MIN_BODIES``) and, up to :data:`SYMBOLIC_MAX_N`, with the symbolic
Jacobian it replaces (the ratios in the same run), and the difference to the Python stepper.
Run ``python benchmarks/compiled_schemes_planar.py`` (``--loops`` / ``--spatial-loops`` / ``--chain-sizes``: that
part alone, merged into the stored rows); writes ``benchmarks/results/compiled_schemes_planar.json``.
"""
from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.integrate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for path in (ROOT, ROOT / "benchmarks"):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

from ctmm.compiled_scene_schemes import CompiledSceneScheme, simulate_scheme_generated  # noqa: E402
from ctmm.errors import ModelError  # noqa: E402
from ctmm.planar import simulate_implicit  # noqa: E402
from ctmm.reference.flexible_lagrange import FlexibleLagrange  # noqa: E402
from ctmm.reference.planar_lagrange import PlanarLagrange  # noqa: E402
from ctmm.reference import spatial_tree as ref  # noqa: E402
import ctmm.spatial as sp  # noqa: E402
from ctmm.compiled_spatial_schemes import CompiledSpatialScheme, simulate_spatial_scheme_generated  # noqa: E402
from ctmm.spatial.implicit import simulate_spatial_implicit  # noqa: E402

DT, T = 1e-3, 1.0
PYTHON_STEPS = 200
SCHEMES = ("newmark", "generalized_alpha", "houbolt", "wilson_theta", "forward_euler")


def models() -> dict:
    """``{name: (model, q0, v0, reference q at T)}``."""
    from compiled_scenes import hub_beam
    from planar_chain import chain

    pendulum = chain(5)
    hub = hub_beam()
    out = {}
    for name, model, lagrange in (("chain_n5", pendulum, PlanarLagrange), ("hub_beam", hub, FlexibleLagrange)):
        q0, v0 = np.zeros(model.n_coordinates), np.zeros(model.n_coordinates)
        exact = lagrange(model).simulate(q0, v0, T, t_eval=[T], rtol=1e-12, atol=1e-12).y[:model.n_coordinates, -1]
        out[name] = (model, q0, v0, exact)
    return out


def generated_run(compiled: CompiledSceneScheme, model, q0, v0, scheme: str):
    """A call of the generated scheme on its compiled library (what the timing measures)."""
    return simulate_scheme_generated(model, q0, v0, t_final=T, dt=DT, scheme=scheme, compiled=compiled,
                                     stability_check="ignore")


def measure(name: str, model, q0, v0, exact) -> list[dict]:
    rows = []
    for scheme in SCHEMES:
        began = time.perf_counter()
        compiled = CompiledSceneScheme(model, scheme)
        first_call = time.perf_counter() - began
        best = min((generated_run(compiled, model, q0, v0, scheme) for _ in range(3)), key=lambda run: run.wall_time_s)
        generated = best.wall_time_s / round(T / DT)
        began = time.perf_counter()
        python = simulate_implicit(model, q0, v0, t_final=PYTHON_STEPS * DT, dt=DT, scheme=scheme,
                                   stability_check="ignore")
        python_step = (time.perf_counter() - began) / PYTHON_STEPS
        row = {"model": name, "scheme": scheme, "dt_s": DT, "t_final_s": T,
               "generated_per_step_s": generated, "python_per_step_s": python_step,
               "speedup": python_step / generated, "first_call_s": first_call,
               "newton_iterations_per_step": best.extra["newton_iterations"] / round(T / DT),
               "generated_vs_python": float(np.max(np.abs(best.q[:PYTHON_STEPS + 1] - python.q))),
               "error_at_t_final": float(np.max(np.abs(best.q[-1] - exact)))}
        rows.append(row)
        print(f"{name:9s} {scheme:18s} generated {generated * 1e6:8.1f} us/step  python {python_step * 1e6:9.1f} "
              f"us/step  x{row['speedup']:6.1f}  |gen - py| {row['generated_vs_python']:.1e}  "
              f"error {row['error_at_t_final']:.2e}", flush=True)
    return rows


def spatial_double_pendulum(pd: tuple[float, float] | None = None):
    """``(model, x0, v0, reference [q ; v] at T)``: ctmm coordinates, the ball's quaternion scalar first; ``pd``:
    the hinge actuated and the reference with ``u = -(kp angle + kd rate)`` on it (DOP853, rtol 1e-12)."""
    inertia_a, inertia_b = (0.02, 0.03, 0.015), (0.01, 0.012, 0.006)
    model = sp.SpatialModel("double", [
        sp.SpatialBody("upper", 1.0, inertia_a, center_of_mass=(0, 0, -0.25), points={"tip": (0, 0, -0.5)}),
        sp.SpatialBody("lower", 0.7, inertia_b, center_of_mass=(0.1, 0, -0.2)),
        sp.Revolute(name="hinge", parent=None, child="upper", axis=(1, 0, 0), actuated=pd is not None),
        sp.Spherical(name="ball", parent="upper", point="tip", child="lower")], gravity=(0, 0, -9.81))
    tree = ref.SpatialTree((
        ref.SpatialBody("upper", -1, "revolute", 1.0, (0, 0, -0.25), np.diag(inertia_a), axes=[(1, 0, 0)]),
        ref.SpatialBody("lower", 0, "spherical", 0.7, (0.1, 0, -0.2), np.diag(inertia_b), joint_position=(0, 0, -0.5))),
        gravity=(0, 0, -9.81))
    x0, v0 = {"hinge.angle": 0.4}, {"hinge.angle_rate": 1.5, "ball.wy": -2.0, "ball.wz": 1.0}
    q0 = np.array([0.4, 0.0, 0.0, 0.0, 1.0])                   # reference order: angle, quaternion scalar last
    if pd is None:
        end = ref.simulate(tree, q0, np.array([1.5, 0.0, -2.0, 1.0]), T, 1e-4)
        q, v = end.q[-1], end.v[-1]
    else:
        def rate(t, y):
            torque = np.array([-(pd[0] * y[0] + pd[1] * y[5]), 0.0, 0.0, 0.0])
            return np.concatenate([ref.configuration_rate(tree, y[:5], y[5:]),
                                   ref.forward_dynamics(tree, y[:5], y[5:], torque, t)])

        end = scipy.integrate.solve_ivp(rate, (0.0, T), np.concatenate([q0, [1.5, 0.0, -2.0, 1.0]]),
                                        method="DOP853", rtol=1e-12, atol=1e-13).y[:, -1]
        q, v = end[:5] / np.r_[1.0, np.full(4, np.linalg.norm(end[1:5]))], end[5:]
    return model, x0, v0, np.concatenate([[q[0], q[4], q[1], q[2], q[3]], v])


def result_row(label: str, scheme: str, best, python, names: list, first_call: float, python_step: float,
               error: float | None) -> dict:
    """The JSON row of a generated run ``best`` (a result over ``T``) against the Python run ``python`` (a result
    over :data:`PYTHON_STEPS`) on the signals ``names``; ``error`` at ``T`` against a reference (or None)."""
    generated = best.info["wall_time_s"] / round(T / DT)
    return {"model": label, "scheme": scheme, "dt_s": DT, "t_final_s": T,
            "generated_per_step_s": generated, "python_per_step_s": python_step,
            "speedup": python_step / generated, "first_call_s": first_call,
            "newton_iterations_per_step": best.info["newton_iterations"] / round(T / DT),
            "generated_vs_python": max(float(np.max(np.abs(best[name][:PYTHON_STEPS + 1] - python[name])))
                                       for name in names),
            "error_at_t_final": error}


def measure_spatial() -> list[dict]:
    model, x0, v0, exact = spatial_double_pendulum()
    names = [*model.coordinates, *model.velocities]
    rows = []
    for scheme in SCHEMES:
        began = time.perf_counter()
        compiled = CompiledSpatialScheme(model, scheme)
        first_call = time.perf_counter() - began
        best = min((simulate_spatial_scheme_generated(model, T, DT, scheme=scheme, x0=x0, v0=v0, compiled=compiled)
                    for _ in range(3)), key=lambda run: run.info["wall_time_s"])
        began = time.perf_counter()
        python = simulate_spatial_implicit(model, PYTHON_STEPS * DT, DT, scheme=scheme, x0=x0, v0=v0)
        python_step = (time.perf_counter() - began) / PYTHON_STEPS
        final = np.array([best[name][-1] for name in names])
        row = result_row("spatial_double_pendulum", scheme, best, python, names, first_call, python_step,
                         float(np.max(np.abs(final - exact))))
        rows.append(row)
        generated = row["generated_per_step_s"]
        print(f"spatial   {scheme:18s} generated {generated * 1e6:8.1f} us/step  python {python_step * 1e6:9.1f} "
              f"us/step  x{row['speedup']:6.1f}  |gen - py| {row['generated_vs_python']:.1e}  "
              f"error {row['error_at_t_final']:.2e}", flush=True)
    return rows


def measure_spatial_loops(delay: float = 0.0) -> list[dict]:
    """A PD on the hinge of the spatial double pendulum (``u = -(20 angle + 2 rate)``, ``delay`` [s]) inside the
    generated Lie-group Newton step (:mod:`ctmm.compiled_spatial_scheme_loops`) vs the Python DT-TMM path with the
    same loop; error at ``T`` against the DOP853 run of the reference tree with the same law (real-time only)."""
    import ctmm
    from ctmm.compiled_spatial_scheme_loops import CompiledSpatialSchemeLoops, simulate_spatial_scheme_loops_generated
    from ctmm.control import ControlledModel, Feedback

    model, x0, v0, exact = spatial_double_pendulum((20.0, 2.0))
    controlled = ControlledModel(model, [Feedback("pd", [("hinge.angle", 20.0), ("hinge.rate", 2.0)], "hinge.torque",
                                                  gain=1.0, delay=delay)])
    label = "spatial_double_pendulum_pd_loop" + ("_delayed" if delay else "")
    names, rows = [*model.coordinates, *model.velocities], []
    for scheme in SCHEMES:
        began = time.perf_counter()
        compiled = CompiledSpatialSchemeLoops(controlled, scheme, dt=DT)
        first_call = time.perf_counter() - began
        best = min((simulate_spatial_scheme_loops_generated(controlled, T, DT, scheme=scheme, x0=x0, v0=v0,
                                                            compiled=compiled) for _ in range(3)),
                   key=lambda run: run.info["wall_time_s"])
        began = time.perf_counter()
        python = ctmm.simulate(controlled, PYTHON_STEPS * DT, DT, method=scheme, x0=x0, v0=v0)
        python_step = (time.perf_counter() - began) / PYTHON_STEPS
        final = np.array([best[name][-1] for name in names])
        row = result_row(label, scheme, best, python, names, first_call, python_step,
                         None if delay else float(np.max(np.abs(final - exact))))
        rows.append(row)
        generated = row["generated_per_step_s"]
        error = "" if delay else f"  error {row['error_at_t_final']:.2e}"
        print(f"{label:9s} {scheme:18s} generated {generated * 1e6:8.1f} us/step  python {python_step * 1e6:9.1f} "
              f"us/step  x{row['speedup']:6.1f}  |gen - py| {row['generated_vs_python']:.1e}{error}", flush=True)
    return rows


def pd_chain(delay: float = 0.0):
    """``(ControlledModel, x0)``: the N = 5 chain with a PD loop on every hinge (``delay`` [s]), started horizontal."""
    from ctmm.control import ControlledModel, Feedback
    from planar_chain import chain

    model = chain(5)
    hinges = ["base", "h1", "h2", "h3", "h4"]
    loops = [Feedback(f"pd_{name}", [(f"{name}.angle", 20.0), (f"{name}.rate", 2.0)], f"{name}.torque", gain=1.0,
                      delay=delay) for name in hinges]
    return ControlledModel(model, loops), dict.fromkeys(model.coordinates, 0.0)


def pid_controllers(with_controller: bool) -> list:
    """A PID on the last hinge sampled every 10 ms (a new one per run: it has state), or none."""
    if not with_controller:
        return []
    sys.path.insert(0, str(ROOT / "tests"))
    from _controllers_import import load_controllers

    return [load_controllers().PID("h4.angle", "h4.torque", sample_time=0.01, kp=5.0, ki=1.0, kd=0.5,
                                   derivative_filter_time=0.005, reference=-0.2)]


def measure_loops(delay: float = 0.0, with_controller: bool = False) -> list[dict]:
    import ctmm
    from ctmm.compiled_scheme_loops import CompiledSchemeLoops, simulate_scheme_loops_generated

    controlled, x0 = pd_chain(delay)
    label = {0.0: "chain_n5_pd_loops", 2 * DT: "chain_n5_delayed_pd_loops"}.get(delay, "chain_n5_fractional_pd_loops")
    label = "chain_n5_pd_loops_controller" if with_controller else label
    q0 = v0 = np.zeros(controlled.plant.n_coordinates)
    references = {"pd_base": 0.3}
    rows = []
    for scheme in SCHEMES:
        began = time.perf_counter()
        if with_controller:                 # ctmm.compiled_scheme_cosim: the kernel is built (or loaded) per run
            def run():
                return ctmm.simulate(controlled, T, DT, method=scheme, x0=x0, references=references, compiled=True,
                                     controllers=pid_controllers(True), stability_check="ignore")
            run()
        else:
            compiled = CompiledSchemeLoops(controlled, scheme, references=references, dt=DT)

            def run():
                return simulate_scheme_loops_generated(controlled, q0, v0, t_final=T, dt=DT, scheme=scheme,
                                                       compiled=compiled, stability_check="ignore")
        first_call = time.perf_counter() - began
        best = min((run() for _ in range(3)), key=lambda result: result.info["wall_time_s"])
        began = time.perf_counter()
        python = ctmm.simulate(controlled, PYTHON_STEPS * DT, DT, method=scheme, x0=x0, references=references,
                               stability_check="ignore", controllers=pid_controllers(with_controller))
        python_step = (time.perf_counter() - began) / PYTHON_STEPS
        row = result_row(label, scheme, best, python, list(controlled.plant.coordinates), first_call,
                         python_step, None)
        rows.append(row)
        generated = row["generated_per_step_s"]
        print(f"{label:9s} {scheme:18s} generated {generated * 1e6:8.1f} us/step  python {python_step * 1e6:9.1f} "
              f"us/step  x{row['speedup']:6.1f}  |gen - py| {row['generated_vs_python']:.1e}", flush=True)
    return rows


def loop_rows() -> list[dict]:
    """The loops part: real-time, delayed 2 ms, delayed 2.5 ms, delayed 2.5 ms with a co-simulated PID."""
    return measure_loops() + measure_loops(2 * DT) + measure_loops(2.5 * DT) + measure_loops(2.5 * DT, True)


CHAIN_SIZES = (10, 20, 30, 100)
"""Pendulum chains (``planar_chain.chain``) of the compile-time part (``--chain-sizes``)."""
SYMBOLIC_MAX_N = 10
"""Largest chain built with the symbolic-Jacobian tangent too (the construction before :mod:`ctmm.mapped_tangent`:
its first compile grows as N^2..N^3: 52 s of CPU at N = 20 at load ~12, 127 s at N = 30 in session 10; at load
14-19 on the 2-core machine gcc passed its 600 s wall-clock limit at N = 20 and 30, recorded as a failed row)."""
CHAIN_STEPS, CHAIN_PYTHON_STEPS = 100, 10


def _cpu() -> float:
    """CPU time [s] of this process and its finished children (the C compiler)."""
    import resource

    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def chain_size_rows(sizes=CHAIN_SIZES, symbolic_max: int = SYMBOLIC_MAX_N) -> list[dict]:
    """Newmark on pendulum chains (start horizontal at rest), per N and tangent construction (``mapped``: the
    default from ``MAPPED_MIN_COORDINATES``, folded sweep from ``SCHEME_FOLD_MIN_BODIES``; ``symbolic``: the old
    one): first compile (CPU incl. gcc, fresh cache), CPU per step over :data:`CHAIN_STEPS` steps, Newton
    iterations per step, ``|q_generated - q_python|`` over the first :data:`CHAIN_PYTHON_STEPS` steps against
    :func:`simulate_implicit` (the transfer form's Newton, independent code; timed after a 2-step warm-up: the rows
    stored before session 12 timed its first steps, which include tracing the rigid sweep once per structure, about
    1 ms per body: 23 ms per step at N = 100, where ``compiled_schemes_default.py`` measures 2.0 ms at N = 80 after
    the warm-up), the load average; per N with both the ratios
    mapped / symbolic."""
    import tempfile

    from planar_chain import chain

    rows = []
    for n in sizes:
        model, q0, v0 = chain(n), np.zeros(n), np.zeros(n)
        simulate_implicit(model, q0, v0, t_final=2 * DT, dt=DT, stability_check="ignore")   # warm-up: sweep traced
        began = time.process_time()
        python = simulate_implicit(model, q0, v0, t_final=CHAIN_PYTHON_STEPS * DT, dt=DT, stability_check="ignore")
        python_step = (time.process_time() - began) / CHAIN_PYTHON_STEPS
        measured = {}
        for tangent in ("mapped", "symbolic") if n <= symbolic_max else ("mapped",):
            began = _cpu()
            try:
                compiled = CompiledSceneScheme(model, "newmark", tangent=tangent, cache_dir=tempfile.mkdtemp())
            except ModelError as error:         # gcc over its time limit (the symbolic Jacobian on a loaded machine)
                rows.append({"model": f"chain_n{n}", "scheme": "newmark", "tangent": tangent,
                             "compile_cpu_s": _cpu() - began, "compile_error": str(error)[:200],
                             "load_average_1min": os.getloadavg()[0]})
                print(f"chain N={n:3d} {tangent:8s} compile failed after {rows[-1]['compile_cpu_s']:.1f} s CPU: "
                      f"{rows[-1]['compile_error']}", flush=True)
                continue
            compile_cpu = _cpu() - began
            began = time.process_time()
            run = simulate_scheme_generated(model, q0, v0, t_final=CHAIN_STEPS * DT, dt=DT, compiled=compiled,
                                            stability_check="ignore")
            step = (time.process_time() - began) / CHAIN_STEPS
            row = {"model": f"chain_n{n}", "scheme": "newmark", "tangent": tangent, "folded": bool(compiled.period),
                   "compile_cpu_s": compile_cpu, "generated_cpu_per_step_s": step,
                   "python_cpu_per_step_s": python_step,
                   "newton_iterations_per_step": run.extra["newton_iterations"] / CHAIN_STEPS,
                   "generated_vs_python": float(np.max(np.abs(run.q[:CHAIN_PYTHON_STEPS + 1] - python.q))),
                   "load_average_1min": os.getloadavg()[0]}
            measured[tangent] = row
            rows.append(row)
            print(f"chain N={n:3d} {tangent:8s} folded={row['folded']!s:5s} compile {compile_cpu:7.2f} s  "
                  f"step {step * 1e6:9.1f} us  python {python_step * 1e6:9.1f} us  |gen - py| "
                  f"{row['generated_vs_python']:.1e}  load {row['load_average_1min']:.1f}", flush=True)
        if len(measured) == 2:
            new, old = measured["mapped"], measured["symbolic"]
            new["compile_ratio_to_symbolic"] = new["compile_cpu_s"] / old["compile_cpu_s"]
            new["step_ratio_to_symbolic"] = new["generated_cpu_per_step_s"] / old["generated_cpu_per_step_s"]
            print(f"chain N={n:3d} mapped / symbolic: compile x{new['compile_ratio_to_symbolic']:.2f}, "
                  f"step x{new['step_ratio_to_symbolic']:.2f}", flush=True)
    return rows


def main() -> None:
    path = ROOT / "benchmarks" / "results" / "compiled_schemes_planar.json"
    if "--chain-sizes" in sys.argv[1:]:         # the compile-time part alone, the other stored rows kept
        kept = json.loads(path.read_text())["rows"] if path.exists() else []
        rows = [row for row in kept if "tangent" not in row] + chain_size_rows()
    elif "--loops" in sys.argv[1:]:               # the loops part alone, the other stored rows kept
        kept = json.loads(path.read_text())["rows"] if path.exists() else []
        rows = [row for row in kept if "pd_loops" not in row["model"]] + loop_rows()
    elif "--spatial-loops" in sys.argv[1:]:     # the spatial loops part alone, the other stored rows kept
        kept = json.loads(path.read_text())["rows"] if path.exists() else []
        rows = [row for row in kept if "pd_loop" not in row["model"] or "spatial" not in row["model"]] + \
            measure_spatial_loops() + measure_spatial_loops(2.5 * DT)
    else:
        rows = [row for name, case in models().items() for row in measure(name, *case)] + measure_spatial() + \
            loop_rows() + measure_spatial_loops() + measure_spatial_loops(2.5 * DT) + chain_size_rows()
    out = {"benchmark": "compiled_schemes_planar", "machine": platform.platform(),
           "python": platform.python_version(), "rows": rows}
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
