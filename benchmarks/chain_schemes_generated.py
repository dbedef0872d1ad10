"""1-D chain with a real-time loop: the generated DT-TMM Newmark step vs the Python paths and a global banded Newmark.

Chain, loop, start and reference of ``benchmarks/chain_compiled.py`` (n = 100 and 1000 masses, real-time
non-collocated loop ``u = -500 x_{n-1}`` on ``m_0``, dt = 1e-4 s).  Same run, same machine:

* ``generated_newmark`` -- ``ctmm.simulate(..., method="newmark", compiled=True)`` (:mod:`ctmm.compiled_chain_schemes`:
  the loop implicit in the step), first call (generate + compile or load) timed apart from the run;
* ``generated_rk4``     -- ``ctmm.simulate(..., method="rk4", compiled=True)`` (:mod:`ctmm.compiled_chain`);
* ``python_dttmm``      -- ``ctmm.simulate(..., method="newmark")`` (the Python DT-TMM step, fewer steps);
* ``global_banded_newmark`` -- the benchmark-local textbook global Newmark of ``chain_compiled.py`` (banded
  Cholesky once, the loop by a rank-one update), the O(n) Python baseline;
* ``compiled_banded_newmark`` -- the same global Newmark written in plain C below (:data:`BASELINE_C`, compiled
  at run time by the system ``cc -O2`` as the generated kernels are, loaded by ``ctypes``): the effective
  matrix's tridiagonal LU factors precomputed, the loop by Sherman-Morrison, one pass per sweep direction,
  ``x`` and ``v`` stored every 10th step -- issue 13's baseline ("per step <= 2x a compiled global banded
  Newmark").

The generated kernel's first compile is also taken on CPU time (``first_compile_cpu_s``: this process and the
compiler's, nothing cached; ``unrolled``: straight-line code or the C node loops of
:mod:`ctmm.compiled_chain_kernel`).  Issue 13's ratio ``generated / compiled baseline`` is taken on CPU time (``time.process_time``, the best of
``REPEATS`` runs of ``CPU_STEPS`` steps, the generated kernel called through
:meth:`ctmm.compiled_chain_schemes.CompiledChainScheme.run` so the verb's set-up is not in it): other
processes share the cores.  The load average of the run is recorded.

Per step (``per_step_s``): wall time per step [s] (generated runs store every 10th step); error: max |x - x_ref|
[m] over all masses and stored rows against ``solve_ivp`` (DOP853, rtol 1e-12) on the global closed-loop equations; the
Newmark rows also give their difference to the global banded Newmark (the same scheme: round-off).  Run
``python benchmarks/chain_schemes_generated.py``; writes ``benchmarks/results/chain_schemes_generated.json``.
"""
from __future__ import annotations

import ctypes
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for path in (ROOT, ROOT / "benchmarks"):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

import ctmm  # noqa: E402
from chain_compiled import (DT, GAIN, MASS, banded_newmark, matrices, model, positions,  # noqa: E402
                            reference, start)
from ctmm.compiled_chain_schemes import CompiledChainScheme  # noqa: E402

STEPS = 2000
CPU_STEPS = {100: 20000, 1000: 4000}
REPEATS = 5
EVERY = 10

BASELINE_C = r"""/* Global banded Newmark (beta, gamma) of a lumped chain M a + C v + K x = -g x[s] e_a:
   tridiagonal K, C, diagonal M; the effective matrix M + gamma h C + beta h^2 K factorised once (Thomas LU:
   unit lower factors l, reciprocals d of the upper diagonal, upper band up); the real-time loop by Sherman-Morrison
   (w = S^-1 e_a, denominator precomputed).  Stores x and v after every `every` steps and after the last. */
void newmark(int n, int steps, int every, double h, double beta, double gamma,
             const double *kd, const double *ko, const double *cd, const double *co,
             const double *l, const double *d, const double *up,
             int sensor, int actuator, double gain, const double *w, double denominator,
             double *x, double *v, double *a, double *xp, double *vp, double *z, double *out)
{
    const double bh2 = beta * h * h, gh = gamma * h, p = (0.5 - beta) * h * h, q = (1.0 - gamma) * h;
    int stored = 0;
    for (int step = 1; step <= steps; ++step) {
        for (int i = 0; i < n; ++i) {
            xp[i] = x[i] + h * v[i] + p * a[i];
            vp[i] = v[i] + q * a[i];
        }
        double previous = 0.0;
        for (int i = 0; i < n; ++i) {            /* rhs = -(K xp + C vp), forward substitution fused */
            double r = -(kd[i] * xp[i] + cd[i] * vp[i]);
            if (i > 0) r -= ko[i - 1] * xp[i - 1] + co[i - 1] * vp[i - 1];
            if (i < n - 1) r -= ko[i] * xp[i + 1] + co[i] * vp[i + 1];
            if (i == actuator) r -= gain * xp[sensor];
            previous = r - l[i] * previous;
            z[i] = previous;
        }
        z[n - 1] *= d[n - 1];
        for (int i = n - 2; i >= 0; --i) z[i] = (z[i] - up[i] * z[i + 1]) * d[i];
        const double s = bh2 * gain * z[sensor] / denominator;
        for (int i = 0; i < n; ++i) {
            a[i] = z[i] - s * w[i];
            x[i] = xp[i] + bh2 * a[i];
            v[i] = vp[i] + gh * a[i];
        }
        if (step % every == 0 || step == steps) {
            for (int i = 0; i < n; ++i) { out[stored * 2 * n + i] = x[i]; out[stored * 2 * n + n + i] = v[i]; }
            ++stored;
        }
    }
}
"""


def baseline_library() -> ctypes.CDLL:
    """:data:`BASELINE_C` compiled by the system ``cc`` (``-O2 -shared -fPIC``, the generated kernels' flags)."""
    folder = Path(tempfile.mkdtemp(prefix="ctmm-bench-newmark-"))
    (folder / "baseline.c").write_text(BASELINE_C)
    subprocess.run(["cc", "-O2", "-shared", "-fPIC", "-o", str(folder / "baseline.so"), str(folder / "baseline.c"),
                    "-lm"], check=True)
    library = ctypes.CDLL(str(folder / "baseline.so"))
    library.newmark.restype = None
    return library


def compiled_banded_newmark(library: ctypes.CDLL, n: int, steps: int, beta: float = 0.25,
                            gamma: float = 0.5) -> tuple[np.ndarray, float, float]:
    """Stored positions ``(rows, n)`` [m] (the start, every :data:`EVERY` th step and the last), CPU and wall time
    per step [s] of the C baseline on the chain of ``chain_compiled.model(n)``."""
    K, C = (matrix.toarray() for matrix in matrices(n))
    h = DT
    S = MASS * np.eye(n) + gamma * h * C + beta * h * h * K
    lower, diagonal, upper = np.zeros(n), np.diag(S).copy(), np.diag(S, 1).copy()
    for i in range(1, n):                                       # Thomas: unit lower factors, upper diagonal
        lower[i] = S[i, i - 1] / diagonal[i - 1]
        diagonal[i] -= lower[i] * upper[i - 1]
    sensor, actuator = n - 1, 0
    unit = np.zeros(n)
    unit[actuator] = 1.0
    w = np.linalg.solve(S, unit)
    denominator = 1.0 + beta * h * h * GAIN * w[sensor]
    x, v = start(n), np.zeros(n)
    a = np.linalg.solve(MASS * np.eye(n), -(K @ x + C @ v) - GAIN * x[sensor] * unit)
    rows = -(-steps // EVERY)
    out, work = np.zeros((rows, 2 * n)), np.zeros((3, n))
    x, v, a = (np.ascontiguousarray(value, float) for value in (x, v, a))
    pointer = ctypes.POINTER(ctypes.c_double)

    def p(array: np.ndarray) -> ctypes.Array:
        return array.ctypes.data_as(pointer)

    arrays = [np.ascontiguousarray(value, float) for value in (np.diag(K), np.diag(K, 1), np.diag(C), np.diag(C, 1),
                                                                 lower, 1.0 / diagonal, upper, w)]
    began, wall = time.process_time(), time.perf_counter()
    library.newmark(ctypes.c_int(n), ctypes.c_int(steps), ctypes.c_int(EVERY), ctypes.c_double(h),
                    ctypes.c_double(beta), ctypes.c_double(gamma), *(p(array) for array in arrays[:7]),
                    ctypes.c_int(sensor), ctypes.c_int(actuator), ctypes.c_double(GAIN), p(arrays[7]),
                    ctypes.c_double(denominator), p(x), p(v), p(a), p(work[0]), p(work[1]), p(work[2]), p(out))
    per_step, wall = (time.process_time() - began) / steps, (time.perf_counter() - wall) / steps
    return np.vstack([start(n)[None], out[:, :n]]), per_step, wall


def cpu_per_step(n: int, library: ctypes.CDLL) -> dict:
    """Issue 13's ratio on CPU time: the generated Newmark kernel's ``run`` against the C baseline, the best of
    :data:`REPEATS` runs of ``CPU_STEPS[n]`` steps each, and the largest difference of their stored positions [m]."""
    system, steps = model(n), CPU_STEPS[n]
    x0 = {f"m{i}": float(value) for i, value in enumerate(start(n))}
    before = os.times()
    with tempfile.TemporaryDirectory() as cache:                   # a first compile: nothing cached
        kernel = CompiledChainScheme(system, DT, "newmark", store_every=EVERY, cache_dir=cache)
    after = os.times()
    compile_cpu = sum(after[:4]) - sum(before[:4])                # this process and the compiler's
    first = kernel.start(x0, None)
    generated, baseline = [], []
    for _ in range(REPEATS):
        began = time.process_time()
        states = kernel.run(first, steps)
        generated.append((time.process_time() - began) / steps)
        rows, per_step, _ = compiled_banded_newmark(library, n, steps)
        baseline.append(per_step)
    difference = float(np.max(np.abs(states[:, :n] - rows[1:])))
    return {"first_compile_cpu_s": compile_cpu, "unrolled": kernel.unrolled, "cpu_steps": steps, "repeats": REPEATS, "generated_cpu_per_step_s": min(generated),
            "compiled_baseline_cpu_per_step_s": min(baseline), "ratio_generated_to_compiled_baseline":
            min(generated) / min(baseline), "generated_vs_compiled_baseline_m": difference,
            "load_average": list(os.getloadavg())}


def measure(n: int, library: ctypes.CDLL) -> list[dict]:
    system = model(n)
    x0 = {f"m{i}": float(value) for i, value in enumerate(start(n))}
    banded, banded_per_step = banded_newmark(n, STEPS)
    rows = []

    def row(method: str, steps: int, per_step: float, times: np.ndarray, x: np.ndarray, **extra) -> None:
        error = float(np.max(np.abs(x - reference(n, times))))
        rows.append({"n": n, "method": method, "steps": steps, "per_step_s": per_step, "error_m": error, **extra})
        print(f"n={n:5d} {method:24s} {per_step * 1e6:12.2f} us/step  error {error:.2e} m  {extra}", flush=True)

    for method, label in (("newmark", "generated_newmark"), ("rk4", "generated_rk4")):
        began = time.perf_counter()
        first = ctmm.simulate(system, STEPS * DT, DT, method=method, x0=x0, compiled=True, store_every=EVERY)
        first_call = time.perf_counter() - began
        again = ctmm.simulate(system, STEPS * DT, DT, method=method, x0=x0, compiled=True, store_every=EVERY)
        extra = {"first_call_s": first_call, "compile_time_s": first.info["compile_time_s"]}
        if method == "newmark":
            extra["vs_global_banded_newmark_m"] = float(np.max(np.abs(positions(again, n) - banded[::EVERY])))
            extra.update(cpu_per_step(n, library))
        row(label, STEPS, again.info["wall_time_s"] / STEPS, again.time, positions(again, n), **extra)
    python_steps = 40 if n <= 100 else 10
    began = time.perf_counter()
    result = ctmm.simulate(system, python_steps * DT, DT, method="newmark", x0=x0)
    row("python_dttmm", python_steps, (time.perf_counter() - began) / python_steps, result.time, positions(result, n))
    row("global_banded_newmark", STEPS, banded_per_step, DT * np.arange(STEPS + 1)[::EVERY], banded[::EVERY])
    compiled_rows, _, wall = compiled_banded_newmark(library, n, STEPS)
    row("compiled_banded_newmark", STEPS, wall, DT * np.arange(STEPS + 1)[::EVERY], compiled_rows,
        vs_global_banded_newmark_m=float(np.max(np.abs(compiled_rows - banded[::EVERY]))))
    return rows


def main() -> None:
    library = baseline_library()
    rows = [r for n in (100, 1000) for r in measure(n, library)]
    by = {(r["n"], r["method"]): r for r in rows}
    for n in (100, 1000):
        generated = by[(n, "generated_newmark")]["per_step_s"]
        for other in ("generated_rk4", "python_dttmm", "global_banded_newmark", "compiled_banded_newmark"):
            by[(n, "generated_newmark")][f"speedup_vs_{other}"] = by[(n, other)]["per_step_s"] / generated
    out = {"benchmark": "chain_schemes_generated", "machine": platform.platform(),
           "python": platform.python_version(), "dt_s": DT, "load_average_end": list(os.getloadavg()), "rows": rows}
    path = ROOT / "benchmarks" / "results" / "chain_schemes_generated.json"
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
