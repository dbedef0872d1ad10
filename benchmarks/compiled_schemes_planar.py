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
Run ``python benchmarks/compiled_schemes_planar.py``; writes ``benchmarks/results/compiled_schemes_planar.json``.
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

ROOT = Path(__file__).resolve().parents[1]
for path in (ROOT, ROOT / "benchmarks"):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

from ctmm.compiled_scene_schemes import CompiledSceneScheme, simulate_scheme_generated  # noqa: E402
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


def spatial_double_pendulum():
    """``(model, x0, v0, reference [q ; v] at T)``: ctmm coordinates, the ball's quaternion scalar first."""
    inertia_a, inertia_b = (0.02, 0.03, 0.015), (0.01, 0.012, 0.006)
    model = sp.SpatialModel("double", [
        sp.SpatialBody("upper", 1.0, inertia_a, center_of_mass=(0, 0, -0.25), points={"tip": (0, 0, -0.5)}),
        sp.SpatialBody("lower", 0.7, inertia_b, center_of_mass=(0.1, 0, -0.2)),
        sp.Revolute(name="hinge", parent=None, child="upper", axis=(1, 0, 0)),
        sp.Spherical(name="ball", parent="upper", point="tip", child="lower")], gravity=(0, 0, -9.81))
    tree = ref.SpatialTree((
        ref.SpatialBody("upper", -1, "revolute", 1.0, (0, 0, -0.25), np.diag(inertia_a), axes=[(1, 0, 0)]),
        ref.SpatialBody("lower", 0, "spherical", 0.7, (0.1, 0, -0.2), np.diag(inertia_b), joint_position=(0, 0, -0.5))),
        gravity=(0, 0, -9.81))
    x0, v0 = {"hinge.angle": 0.4}, {"hinge.angle_rate": 1.5, "ball.wy": -2.0, "ball.wz": 1.0}
    q0 = np.array([0.4, 0.0, 0.0, 0.0, 1.0])                   # reference order: angle, quaternion scalar last
    end = ref.simulate(tree, q0, np.array([1.5, 0.0, -2.0, 1.0]), T, 1e-4)
    q, v = end.q[-1], end.v[-1]
    return model, x0, v0, np.concatenate([[q[0], q[4], q[1], q[2], q[3]], v])


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
        generated = best.info["wall_time_s"] / round(T / DT)
        began = time.perf_counter()
        python = simulate_spatial_implicit(model, PYTHON_STEPS * DT, DT, scheme=scheme, x0=x0, v0=v0)
        python_step = (time.perf_counter() - began) / PYTHON_STEPS
        final = np.array([best[name][-1] for name in names])
        row = {"model": "spatial_double_pendulum", "scheme": scheme, "dt_s": DT, "t_final_s": T,
               "generated_per_step_s": generated, "python_per_step_s": python_step,
               "speedup": python_step / generated, "first_call_s": first_call,
               "newton_iterations_per_step": best.info["newton_iterations"] / round(T / DT),
               "generated_vs_python": max(float(np.max(np.abs(best[name][:PYTHON_STEPS + 1] - python[name])))
                                          for name in names),
               "error_at_t_final": float(np.max(np.abs(final - exact)))}
        rows.append(row)
        print(f"spatial   {scheme:18s} generated {generated * 1e6:8.1f} us/step  python {python_step * 1e6:9.1f} "
              f"us/step  x{row['speedup']:6.1f}  |gen - py| {row['generated_vs_python']:.1e}  "
              f"error {row['error_at_t_final']:.2e}", flush=True)
    return rows


def main() -> None:
    rows = [row for name, case in models().items() for row in measure(name, *case)] + measure_spatial()
    out = {"benchmark": "compiled_schemes_planar", "machine": platform.platform(),
           "python": platform.python_version(), "rows": rows}
    path = ROOT / "benchmarks" / "results" / "compiled_schemes_planar.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
