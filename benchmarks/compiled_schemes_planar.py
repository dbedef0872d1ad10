"""Planar models: the generated DT-TMM schemes (Newton in C) vs the Python implicit stepper, per step and error.

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


def main() -> None:
    rows = [row for name, case in models().items() for row in measure(name, *case)]
    out = {"benchmark": "compiled_schemes_planar", "machine": platform.platform(),
           "python": platform.python_version(), "rows": rows}
    path = ROOT / "benchmarks" / "results" / "compiled_schemes_planar.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
