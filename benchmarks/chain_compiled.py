"""1-D chain with a real-time feedback loop: generated RK4 vs the Python paths vs a global banded Newmark.

Chain ``Fixed - [k, c] - m_0 - [k, c] - ... - m_{n-1} - Free`` (m = 1 kg, k = 1e4 N/m, c = 1 N s/m),
a non-collocated real-time loop ``u = -g x_{n-1}`` on ``m_0`` (g = 500 N/m), initial displacement
``x_i(0) = 0.01 sin(pi (i + 1) / (2 n))`` m, dt = 1e-4 s, n = 100 and 1000.  Same run, same machine:

* ``generated_rk4``  -- ``ctmm.simulate(..., method="rk4", compiled=True)`` (:mod:`ctmm.compiled_chain`),
  first call (generate + compile, or load from the cache) timed apart from the run;
* ``python_rk4``     -- ``ctmm.simulate(..., method="rk4")`` (the one loop driver on the chain's plant);
* ``python_dttmm``   -- ``ctmm.simulate(..., method="newmark")`` (the DT-TMM step with the loop embedded,
  :mod:`ctmm.control.simulate`);
* ``global_banded_newmark`` -- a benchmark-local textbook global Newmark (1/4, 1/2): the loop implicit in the
  step (rank-one Sherman-Morrison update of a banded Cholesky factorised once), tridiagonal mat-vecs:
  the O(n) Python global baseline.

Per step: wall time per step [s] (the generated run stores every 10th step); error: max |x - x_ref| [m]
over all masses and the run's stored rows,
``x_ref`` from ``solve_ivp`` (DOP853, rtol 1e-12) on the global closed-loop state equations (sparse).  The
Python paths run fewer steps (``steps`` in the row).  Run ``python benchmarks/chain_compiled.py``; writes
``benchmarks/results/chain_compiled.json``.
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
import scipy.linalg as sla  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import ctmm  # noqa: E402
from ctmm.control import ControlledChain, Feedback  # noqa: E402
from ctmm.elements import Fixed, Free, Mass, SpringDamper  # noqa: E402

MASS, STIFFNESS, DAMPING, GAIN, DT = 1.0, 1.0e4, 1.0, 500.0, 1.0e-4


def model(n: int) -> ControlledChain:
    elements = [Fixed("start")]
    for i in range(n):
        elements += [SpringDamper(f"k{i}", STIFFNESS, DAMPING), Mass(f"m{i}", MASS)]
    plant = ctmm.Chain(f"chain{n}", elements + [Free("end")])
    return ControlledChain(plant, [Feedback("tip", f"m{n - 1}.x", "m0", gain=GAIN)])


def start(n: int) -> np.ndarray:
    return 0.01 * np.sin(np.pi * (np.arange(n) + 1) / (2 * n))


def matrices(n: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Global ``K`` and ``C`` (fixed start, free end), tridiagonal."""
    main = np.full(n, 2.0)
    main[-1] = 1.0
    band = sp.diags([main, -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1], format="csr")
    return STIFFNESS * band, DAMPING * band


def reference(n: int, times: np.ndarray) -> np.ndarray:
    K, C = matrices(n)
    loop = sp.csr_matrix(([GAIN], ([0], [n - 1])), shape=(n, n))
    stiffness = (K + loop) / MASS
    damping = C / MASS

    def rate(t: float, y: np.ndarray) -> np.ndarray:
        return np.concatenate([y[n:], -(stiffness @ y[:n]) - damping @ y[n:]])

    solution = solve_ivp(rate, (0.0, float(times[-1])), np.concatenate([start(n), np.zeros(n)]), method="DOP853",
                         t_eval=times, rtol=1e-12, atol=1e-15)
    return solution.y[:n].T


def banded_newmark(n: int, steps: int, beta: float = 0.25, gamma: float = 0.5) -> tuple[np.ndarray, float]:
    K, C = matrices(n)
    h = DT
    effective = (sp.identity(n) * MASS + gamma * h * C + beta * h * h * K).todia()
    upper = np.zeros((2, n))
    upper[1] = effective.diagonal(0)
    upper[0, 1:] = effective.diagonal(1)
    factor = sla.cholesky_banded(upper)
    b, c = np.zeros(n), np.zeros(n)
    b[0], c[n - 1] = 1.0, 1.0
    w = sla.cho_solve_banded((factor, False), b)
    scale = beta * h * h * GAIN
    denominator = 1.0 + scale * (c @ w)
    x, v = start(n), np.zeros(n)
    a = -(K @ x + C @ v + GAIN * x[n - 1] * b) / MASS
    rows = [x.copy()]
    began = time.perf_counter()
    for _ in range(steps):
        x_pred = x + h * v + (0.5 - beta) * h * h * a
        v_pred = v + (1.0 - gamma) * h * a
        z = sla.cho_solve_banded((factor, False), -(C @ v_pred) - K @ x_pred - GAIN * x_pred[n - 1] * b)
        a = z - (scale * z[n - 1] / denominator) * w
        x, v = x_pred + beta * h * h * a, v_pred + gamma * h * a
        rows.append(x.copy())
    return np.array(rows), (time.perf_counter() - began) / steps


def positions(result, n: int) -> np.ndarray:
    return np.column_stack([result[f"m{i}.x"] for i in range(n)])


def measure(n: int) -> list[dict]:
    system = model(n)
    x0 = {f"m{i}": float(value) for i, value in enumerate(start(n))}
    rows = []

    def row(method: str, steps: int, per_step: float, times: np.ndarray, x: np.ndarray, **extra) -> None:
        error = float(np.max(np.abs(x - reference(n, times))))
        rows.append({"n": n, "method": method, "steps": steps, "per_step_s": per_step, "error_m": error, **extra})
        print(f"n={n:5d} {method:22s} {per_step * 1e6:12.1f} us/step  error {error:.2e} m  {extra}", flush=True)

    steps = 2000
    began = time.perf_counter()
    generated = ctmm.simulate(system, steps * DT, DT, method="rk4", x0=x0, compiled=True, store_every=10)
    first = time.perf_counter() - began
    again = ctmm.simulate(system, steps * DT, DT, method="rk4", x0=x0, compiled=True, store_every=10)
    row("generated_rk4", steps, again.info["wall_time_s"] / steps, again.time, positions(again, n),
        first_call_s=first, compile_time_s=generated.info["compile_time_s"])
    python_steps = 40 if n <= 100 else 10
    for method, label in (("rk4", "python_rk4"), ("newmark", "python_dttmm")):
        began = time.perf_counter()
        result = ctmm.simulate(system, python_steps * DT, DT, method=method, x0=x0)
        row(label, python_steps, (time.perf_counter() - began) / python_steps, result.time, positions(result, n))
    x, per_step = banded_newmark(n, steps)
    row("global_banded_newmark", steps, per_step, DT * np.arange(steps + 1)[::10], x[::10])
    return rows


def main() -> None:
    rows = [r for n in (100, 1000) for r in measure(n)]
    by = {(r["n"], r["method"]): r for r in rows}
    for n in (100, 1000):
        generated = by[(n, "generated_rk4")]["per_step_s"]
        for other in ("python_rk4", "python_dttmm", "global_banded_newmark"):
            by[(n, "generated_rk4")][f"speedup_vs_{other}"] = by[(n, other)]["per_step_s"] / generated
    out = {"benchmark": "chain_compiled", "machine": platform.platform(), "python": platform.python_version(),
           "dt_s": DT, "rows": rows}
    path = ROOT / "benchmarks" / "results" / "chain_compiled.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
