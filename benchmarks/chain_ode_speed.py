"""Python ODE path of 1-D chains: one sweep per rate (before) vs the certified affine rates (after).

Chain and loop of ``benchmarks/chain_compiled.py`` (``Fixed - [k, c] - m_0 - ... - m_{n-1} - Free``,
m = 1 kg, k = 1e4 N/m, c = 1 N s/m, real-time loop ``u = -500 x_{n-1}`` on ``m_0``), dt = 1e-4 s,
n = 100 and 1000.  Same run, same machine:

* ``rk4_sweep_rate``  -- fixed-step RK4 (:func:`ctmm.ode.rk4_step`) on ``ChainDynamics(chain, affine=False).rate``:
  one articulated sweep of the element terms per rate evaluation, the path before (plain chain);
* ``rk4_affine_rate`` -- the same loop on ``ChainDynamics(chain).rate`` (:mod:`ctmm.chain_affine`: one sparse
  mat-vec per rate; the setup -- probes and certification -- reported apart as ``setup_s``);
* ``simulate_rk4_plain`` / ``simulate_rk4_loop`` -- the whole verb ``ctmm.simulate(..., method="rk4")`` on the
  plain chain / on the controlled chain (the loop driver), everything included (setup, stored signals), per step.

Error: max |x - x_ref| [m] over all masses and stored rows, ``x_ref`` from ``solve_ivp`` (DOP853, rtol 1e-12)
on the global state equations (sparse), with or without the loop.  Run ``python benchmarks/chain_ode_speed.py``;
writes ``benchmarks/results/chain_ode_speed.json``.
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
import scipy.sparse as sp  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for path in (ROOT, ROOT / "benchmarks"):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

import ctmm  # noqa: E402
from chain_compiled import DT, GAIN, MASS, matrices, model, start  # noqa: E402
from ctmm.chain_ode import ChainDynamics  # noqa: E402
from ctmm.ode import rk4_step  # noqa: E402


def reference(n: int, times: np.ndarray, loop: bool) -> np.ndarray:
    K, C = matrices(n)
    if loop:
        K = K + sp.csr_matrix(([GAIN], ([0], [n - 1])), shape=(n, n))

    def rate(t: float, y: np.ndarray) -> np.ndarray:
        return np.concatenate([y[n:], -(K @ y[:n]) / MASS - (C @ y[n:]) / MASS])

    solution = solve_ivp(rate, (0.0, float(times[-1])), np.concatenate([start(n), np.zeros(n)]), method="DOP853",
                         t_eval=times, rtol=1e-12, atol=1e-15)
    return solution.y[:n].T


def stepped(chain, n: int, steps: int, affine: bool) -> tuple[np.ndarray, float, float]:
    """RK4 rows of the positions, seconds per step and setup seconds on one rate path."""
    began = time.perf_counter()
    dynamics = ChainDynamics(chain, affine=affine)
    y = np.concatenate([start(n), np.zeros(n)])
    dynamics.rate(0.0, y)                        # the affine form is read and certified on first use
    setup = time.perf_counter() - began
    rows = [y[:n].copy()]
    began = time.perf_counter()
    for k in range(steps):
        y = rk4_step(dynamics.rate, k * DT, y, DT)
        rows.append(y[:n].copy())
    return np.array(rows), (time.perf_counter() - began) / steps, setup


def measure(n: int) -> list[dict]:
    controlled = model(n)
    plain = controlled.plant
    x0 = {f"m{i}": float(value) for i, value in enumerate(start(n))}
    rows = []

    def row(method: str, steps: int, per_step: float, times: np.ndarray, x: np.ndarray, loop: bool, **extra) -> None:
        error = float(np.max(np.abs(x - reference(n, times, loop))))
        rows.append({"n": n, "method": method, "steps": steps, "per_step_s": per_step, "error_m": error, **extra})
        print(f"n={n:5d} {method:20s} {per_step * 1e6:12.1f} us/step  error {error:.2e} m  {extra}", flush=True)

    before_steps, after_steps = (20, 2000) if n <= 100 else (4, 400)
    for affine, steps, label in ((False, before_steps, "rk4_sweep_rate"), (True, after_steps, "rk4_affine_rate")):
        x, per_step, setup = stepped(plain, n, steps, affine)
        row(label, steps, per_step, DT * np.arange(steps + 1), x, False, setup_s=setup)
    for system, label, loop in ((plain, "simulate_rk4_plain", False), (controlled, "simulate_rk4_loop", True)):
        began = time.perf_counter()
        result = ctmm.simulate(system, after_steps * DT, DT, method="rk4", x0=x0)
        per_step = (time.perf_counter() - began) / after_steps
        row(label, after_steps, per_step, result.time, np.column_stack([result[f"m{i}.x"] for i in range(n)]), loop)
    return rows


def main() -> None:
    rows = [r for n in (100, 1000) for r in measure(n)]
    by = {(r["n"], r["method"]): r for r in rows}
    for n in (100, 1000):
        by[(n, "rk4_affine_rate")]["speedup_vs_sweep_rate"] = \
            by[(n, "rk4_sweep_rate")]["per_step_s"] / by[(n, "rk4_affine_rate")]["per_step_s"]
    out = {"benchmark": "chain_ode_speed", "machine": platform.platform(), "python": platform.python_version(),
           "dt_s": DT, "rows": rows}
    path = ROOT / "benchmarks" / "results" / "chain_ode_speed.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
