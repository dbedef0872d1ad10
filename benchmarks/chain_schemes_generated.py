"""1-D chain with a real-time loop: the generated DT-TMM Newmark step vs the Python paths and a global banded Newmark.

Chain, loop, start and reference of ``benchmarks/chain_compiled.py`` (n = 100 and 1000 masses, real-time
non-collocated loop ``u = -500 x_{n-1}`` on ``m_0``, dt = 1e-4 s).  Same run, same machine:

* ``generated_newmark`` -- ``ctmm.simulate(..., method="newmark", compiled=True)`` (:mod:`ctmm.compiled_chain_schemes`:
  the loop implicit in the step), first call (generate + compile or load) timed apart from the run;
* ``generated_rk4``     -- ``ctmm.simulate(..., method="rk4", compiled=True)`` (:mod:`ctmm.compiled_chain`);
* ``python_dttmm``      -- ``ctmm.simulate(..., method="newmark")`` (the Python DT-TMM step, fewer steps);
* ``global_banded_newmark`` -- the benchmark-local textbook global Newmark of ``chain_compiled.py`` (banded
  Cholesky once, the loop by a rank-one update), the O(n) Python baseline.

Per step: wall time per step [s] (generated runs store every 10th step); error: max |x - x_ref| [m] over all
masses and stored rows against ``solve_ivp`` (DOP853, rtol 1e-12) on the global closed-loop equations; the
Newmark rows also give their difference to the global banded Newmark (the same scheme: round-off).  Run
``python benchmarks/chain_schemes_generated.py``; writes ``benchmarks/results/chain_schemes_generated.json``.
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

import ctmm  # noqa: E402
from chain_compiled import DT, banded_newmark, model, positions, reference, start  # noqa: E402

STEPS = 2000


def measure(n: int) -> list[dict]:
    system = model(n)
    x0 = {f"m{i}": float(value) for i, value in enumerate(start(n))}
    banded, banded_per_step = banded_newmark(n, STEPS)
    rows = []

    def row(method: str, steps: int, per_step: float, times: np.ndarray, x: np.ndarray, **extra) -> None:
        error = float(np.max(np.abs(x - reference(n, times))))
        rows.append({"n": n, "method": method, "steps": steps, "per_step_s": per_step, "error_m": error, **extra})
        print(f"n={n:5d} {method:22s} {per_step * 1e6:12.1f} us/step  error {error:.2e} m  {extra}", flush=True)

    for method, label in (("newmark", "generated_newmark"), ("rk4", "generated_rk4")):
        began = time.perf_counter()
        first = ctmm.simulate(system, STEPS * DT, DT, method=method, x0=x0, compiled=True, store_every=10)
        first_call = time.perf_counter() - began
        again = ctmm.simulate(system, STEPS * DT, DT, method=method, x0=x0, compiled=True, store_every=10)
        extra = {"first_call_s": first_call, "compile_time_s": first.info["compile_time_s"]}
        if method == "newmark":
            extra["vs_global_banded_newmark_m"] = float(np.max(np.abs(positions(again, n) - banded[::10])))
        row(label, STEPS, again.info["wall_time_s"] / STEPS, again.time, positions(again, n), **extra)
    python_steps = 40 if n <= 100 else 10
    began = time.perf_counter()
    result = ctmm.simulate(system, python_steps * DT, DT, method="newmark", x0=x0)
    row("python_dttmm", python_steps, (time.perf_counter() - began) / python_steps, result.time, positions(result, n))
    row("global_banded_newmark", STEPS, banded_per_step, DT * np.arange(STEPS + 1)[::10], banded[::10])
    return rows


def main() -> None:
    rows = [r for n in (100, 1000) for r in measure(n)]
    by = {(r["n"], r["method"]): r for r in rows}
    for n in (100, 1000):
        generated = by[(n, "generated_newmark")]["per_step_s"]
        for other in ("generated_rk4", "python_dttmm", "global_banded_newmark"):
            by[(n, "generated_newmark")][f"speedup_vs_{other}"] = by[(n, other)]["per_step_s"] / generated
    out = {"benchmark": "chain_schemes_generated", "machine": platform.platform(),
           "python": platform.python_version(), "dt_s": DT, "rows": rows}
    path = ROOT / "benchmarks" / "results" / "chain_schemes_generated.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
