"""The 1-D chain FRF against a compiled lower bound of its Riccati recursion (issue 13 item 3).

Chain, frequencies, input and outputs of ``benchmarks/foundation_scaling.py`` (a): fixed-free chain of ``n`` masses
(m = 0.1 kg) and spring-dampers (K = 1000 N/m, c = 0.2 N s/m), 1000 log-spaced omega up to 0.95 times the band
edge, unit force on ``m1``, outputs ``m1.x`` (driving point) and ``m<n>.x`` (tip).  Cases, one process, one run:

* ``frequency_response`` -- :func:`ctmm.frequency_response` as a user calls it (the compiled recursion of
  :mod:`ctmm.compiled_chain_frequency` when a C compiler is present: it is here);
* ``compiled_solve`` -- :func:`ctmm.chain_assembly.solve` with ``compiled=True`` (the solve alone: element terms,
  boundaries, the C loop);
* ``numpy_solve`` -- the same with ``compiled=False`` (the numpy recursion batched over omega, the path before);
* ``compiled_bound`` -- the lower bound: the same recursion for THIS chain typed in plain C (``cc -O2``, loaded by
  ``ctypes``, built at run time as ``benchmarks/planar_frf.py`` builds its bound): uniform elements, so one
  compliance ``1 / (k + c s)`` and one impedance ``m s^2`` per frequency, then per mass ``G = 1 - Z S``,
  ``S <- S / G``, ``r = -Z P (+ 1 at m1)``, ``P <- P / G``, the end condition with the same certificate (the end
  unknown finite), the back-substitution through the masses and the two outputs.  Built twice: frequency by
  frequency (``K = 1``) and in blocks of 8 frequencies side by side (``K = 8``, the library kernel's layout); the
  faster is the bound.  No Python work is in it (the arrays are prepared before timing).

* ``banded_loop`` / ``banded_vectorised`` -- the global baselines of ``lumped_chain.global_baselines``:
  ``scipy.linalg.solve_banded`` on the tridiagonal dynamic stiffness per frequency, and the same banded system
  solved for all frequencies at once by a Thomas elimination vectorised over omega (the fastest plain-numpy global
  baseline); timed on banded ``M, C, K`` prepared before timing (the reference assembly goes through dense
  ``n x n`` matrices; its CPU time and memory are reported apart and left out of the ratios, in the baselines'
  favour).  ``frequency_response_over_<baseline>_cpu`` < 1: the compiled path is faster.

Times: best CPU time (``time.process_time``, single-threaded code; the machine is shared, so CPU time is the
figure to compare) and best wall time.  Ratios ``*_vs_bound`` are CPU-time ratios to the faster bound.  Errors:
max relative error against a 30-digit mpmath solve (the Thomas algorithm on the tridiagonal dynamic stiffness,
``lumped_chain.model.high_precision_frf``) at 10 probe frequencies and, per output, the frequency where the
compiled answer and the ``solve_banded`` loop differ most (as ``foundation_scaling`` does), driving point and tip;
``error_<baseline>_over_compiled`` is the baseline's error over the compiled path's.  Memory: peak traced
allocations (``tracemalloc``: numpy arrays count) of one call of each solve.

Controlled chains and the characteristic function (``controlled_rows``, :mod:`ctmm.controlled_chain_frequency`):
the same chain closed by a delayed PD loop on the tip, ``u = -(20 x + 5 v)(t - 0.01 s)`` at ``m<n>`` (``--controlled``
masses, every 10th frequency of the grid: the extended numpy recursion holds ``(B, 4, 4)`` matrices per element):

* ``closed_loop_compiled`` -- :func:`ctmm.controlled_chain_frequency.closed_loop_solve` (plant solves in C, the loop
  closed per frequency), ``closed_loop_numpy`` -- :func:`ctmm.chain_assembly.solve` of the extended chain (numpy);
* ``log_det_compiled`` / ``log_det_numpy`` -- the characteristic log-determinant of the controlled chain at
  ``s = 0.1 + i omega`` (determinant lemma on the compiled plant / the extended numpy recursion), and
  ``plain_log_det_compiled`` / ``plain_log_det_numpy`` of the plant alone (``solve(points=(), want_log_det=True)``
  / :func:`ctmm.assembly.riccati_solve` with ``want_states=False``).

Agreement: largest difference of the outputs relative to the largest output, and of ``exp(log det)`` ratios.

Run ``python benchmarks/chain_frf.py`` (``--sizes 1000`` for one size); writes ``benchmarks/results/chain_frf.json``.
"""
from __future__ import annotations

import argparse
import ctypes
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "benchmarks"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

import ctmm  # noqa: E402
from ctmm.chain_assembly import laplace_variables, solve  # noqa: E402
from ctmm.reference import chain as reference  # noqa: E402  (benchmarks may use the validation models)
from lumped_chain.global_baselines import banded_frequency_loop, thomas_frequency_batch  # noqa: E402
from lumped_chain.model import (DAMPING, MASS, STIFFNESS, ctmm_chain, global_chain, high_precision_frf,  # noqa: E402
                                omega_grid, probe_indices, relative_difference)
from planar_frf import best  # noqa: E402  (best wall and CPU time of repeated calls)

RESULTS = ROOT / "benchmarks" / "results" / "chain_frf.json"

BOUND_C = r"""
#include <math.h>
/* 1 / (br + i bi), Smith's rule without branches (as the library kernel) */
static inline void reciprocal(double br, double bi, double *qr, double *qi)
{
    const int big = fabs(br) >= fabs(bi);
    const double p = big ? br : bi, q = big ? bi : br;
    const double rat = q / p, scl = 1.0 / (p + q * rat);
    *qr = big ? scl : rat * scl;
    *qi = big ? -rat * scl : -scl;
}

/* Fixed-free uniform chain wall-(k, c)-m-(k, c)-m ... m, unit force on mass 1: x at mass 1 and at mass n per omega.
   x known (0) at the wall, force unknown; S = -compliance of the inboard part.  stack: 4 K n doubles. */
void bound(int n, int B, double k, double c, double m, const double *omega, double *x1, double *xn, int *good,
           double *stack)
{
    for (int b0 = 0; b0 < B; b0 += K) {
        double Sr[K], Si[K], Pr[K], Pi[K], cr[K], ci[K], zr[K], S1r[K], S1i[K], P1r[K], P1i[K];
        for (int q = 0; q < K; ++q) {
            const double w = omega[b0 + q];
            reciprocal(k, c * w, cr + q, ci + q);               /* compliance 1 / (k + c s), s = i w */
            zr[q] = m * w * w;                                  /* -Z = -m s^2 = m w^2 (real) */
            Sr[q] = Si[q] = Pr[q] = Pi[q] = 0.0;
        }
        for (int j = 0; j < n; ++j) {
            double *st = stack + 4 * K * j;
            for (int q = 0; q < K; ++q) {
                Sr[q] -= cr[q]; Si[q] -= ci[q];                  /* connector: S <- S - 1 / (k + c s) */
                double gr, gi;                                   /* mass: G = 1 - Z S = 1 + (m w^2) S */
                reciprocal(1.0 + zr[q] * Sr[q], zr[q] * Si[q], &gr, &gi);
                const double tr = Sr[q] * gr - Si[q] * gi, ti = Sr[q] * gi + Si[q] * gr;
                const double rr = zr[q] * Pr[q] + (j == 0 ? 1.0 : 0.0), ri = zr[q] * Pi[q];
                const double pr = Pr[q] * gr - Pi[q] * gi, pi = Pr[q] * gi + Pi[q] * gr;
                st[q] = gr; st[K + q] = gi; st[2 * K + q] = rr; st[3 * K + q] = ri;
                Sr[q] = tr; Si[q] = ti;
                Pr[q] = j == 0 ? pr - tr : pr; Pi[q] = j == 0 ? pi - ti : pi;   /* P <- P / G - S u_e, u_e = -1 */
                if (j == 0) { S1r[q] = Sr[q]; S1i[q] = Si[q]; P1r[q] = Pr[q]; P1i[q] = Pi[q]; }
            }
        }
        double er[K], ei[K];
        for (int q = 0; q < K; ++q) {     /* free end Bm = [0, 1], b = 0: e_N = (b - 0 P) / (0 S + 1) (NaN stays) */
            double hr, hi;
            reciprocal(0.0 * Sr[q] - 0.0 * Si[q] + 1.0, 0.0 * Si[q] + 0.0 * Sr[q], &hr, &hi);
            const double xr = 0.0 - (0.0 * Pr[q] - 0.0 * Pi[q]), xi = 0.0 - (0.0 * Pi[q] + 0.0 * Pr[q]);
            er[q] = xr * hr - xi * hi; ei[q] = xr * hi + xi * hr;
            good[b0 + q] = isfinite(er[q]) && isfinite(ei[q]);
            xn[2 * (b0 + q)] = Sr[q] * er[q] - Si[q] * ei[q] + Pr[q];
            xn[2 * (b0 + q) + 1] = Sr[q] * ei[q] + Si[q] * er[q] + Pi[q];
        }
        for (int j = n - 1; j >= 1; --j) {                       /* back through the masses to mass 1 */
            const double *st = stack + 4 * K * j;
            for (int q = 0; q < K; ++q) {
                const double xr = er[q] - st[2 * K + q], xi = ei[q] - st[3 * K + q];
                er[q] = xr * st[q] - xi * st[K + q]; ei[q] = xr * st[K + q] + xi * st[q];
            }
        }
        for (int q = 0; q < K; ++q) {
            x1[2 * (b0 + q)] = S1r[q] * er[q] - S1i[q] * ei[q] + P1r[q];
            x1[2 * (b0 + q) + 1] = S1r[q] * ei[q] + S1i[q] * er[q] + P1i[q];
        }
    }
}
"""


def bound_library(block: int) -> ctypes.CDLL:
    """:data:`BOUND_C` with ``K = block`` compiled by the system ``cc`` (``-O2 -shared -fPIC``, the library's flags)."""
    folder = Path(tempfile.mkdtemp(prefix="ctmm-bench-chain-frf-"))
    (folder / "bound.c").write_text(f"#define K {block}\n" + BOUND_C)
    subprocess.run(["cc", "-O2", "-shared", "-fPIC", "-o", str(folder / "bound.so"), str(folder / "bound.c"), "-lm"],
                   check=True)
    library = ctypes.CDLL(str(folder / "bound.so"))
    doubles = ctypes.POINTER(ctypes.c_double)
    library.bound.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_double, ctypes.c_double, ctypes.c_double, doubles,
                              doubles, doubles, ctypes.POINTER(ctypes.c_int), doubles]
    return library


def bound_call(library: ctypes.CDLL, block: int, n: int, omega: np.ndarray):
    """``(call, result)``: the bound as a repeatable call on arrays prepared once; ``result()`` gives ``(2, B)``
    displacements per unit force (driving point, tip) and the certified mask."""
    padded = -(-omega.size // block) * block
    w = np.ascontiguousarray(omega[np.minimum(np.arange(padded), omega.size - 1)])
    x1, xn = np.zeros(2 * padded), np.zeros(2 * padded)
    good = np.zeros(padded, dtype=np.intc)
    stack = np.zeros(4 * block * n)
    doubles = ctypes.POINTER(ctypes.c_double)
    arguments = (n, padded, STIFFNESS, DAMPING, MASS, w.ctypes.data_as(doubles), x1.ctypes.data_as(doubles),
                 xn.ctypes.data_as(doubles), good.ctypes.data_as(ctypes.POINTER(ctypes.c_int)),
                 stack.ctypes.data_as(doubles))

    def call() -> None:
        library.bound(*arguments)

    def result() -> tuple[np.ndarray, np.ndarray]:
        H = np.stack([x1.view(complex), xn.view(complex)])[:, :omega.size]
        return H, good[:omega.size].astype(bool)

    return call, result


def peak_bytes(call) -> int:
    """Peak traced allocation [bytes] of one call (numpy arrays are traced)."""
    tracemalloc.start()
    try:
        call()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def relative(value: np.ndarray, reference: np.ndarray) -> float:
    """Max ``|value - reference| / |reference|`` where ``|reference| > 1e-280`` (the tip's response underflows at the
    highest frequencies of n = 10 000: evanescent waves), as ``lumped_chain.model.relative_difference``."""
    return relative_difference(value, reference)["max"]


def run(n: int, bounds: dict[int, ctypes.CDLL]) -> dict:
    system, omega = ctmm_chain(n), omega_grid(n)
    outputs = ["m1.x", f"m{n}.x"]
    s = laplace_variables(omega)
    source = system.input("m1.force")
    amplitudes = {source.position: {source.input: 1.0}}
    points = sorted({system.signal(o).point for o in outputs})
    repeats = 7 if n <= 1000 else 3

    def solved(compiled: bool):
        solution = solve(system, s, amplitudes, points=points, compiled=compiled)
        return np.stack([solution.at(p)[:, 0] for p in points])

    cases = {"frequency_response": lambda: ctmm.frequency_response(system, omega, input="m1.force", output=outputs),
             "compiled_solve": lambda: solved(True), "numpy_solve": lambda: solved(False)}
    row: dict = {"n_masses": n, "n_frequencies": int(omega.size), "load_average": list(os.getloadavg())}
    results = {}
    for name, call in cases.items():
        call()                                                   # warm-up (the library is loaded once)
        row[f"{name}_s"], row[f"{name}_cpu_s"], results[name] = best(call, repeats)
    for block, library in bounds.items():
        call, result = bound_call(library, block, n, omega)
        call()
        row[f"compiled_bound_k{block}_s"], row[f"compiled_bound_k{block}_cpu_s"], _ = best(call, 3 * repeats)
        results[f"bound_k{block}"] = result()
    bound_cpu = min(row[f"compiled_bound_k{block}_cpu_s"] for block in bounds)
    row["compiled_bound_cpu_s"] = bound_cpu
    for name in cases:
        row[f"{name}_vs_bound"] = row[f"{name}_cpu_s"] / bound_cpu
    row["peak_bytes_frequency_response"] = peak_bytes(cases["frequency_response"])
    row["peak_bytes_compiled_solve"] = peak_bytes(lambda: solved(True))
    row["peak_bytes_numpy_solve"] = peak_bytes(lambda: solved(False))
    banded_rows(row, results, n, omega, max(2, repeats // 2))
    frf = results["frequency_response"].response[:, 0]
    # the 10 probe frequencies and, per output, where the compiled answer and the banded loop differ most
    compiled, loop = np.stack([frf[0], frf[1]]), results["banded_loop"]
    worst = [int(np.argmax(np.abs(compiled[k] - loop[k]) / np.maximum(np.abs(loop[k]), 1e-300))) for k in range(2)]
    probe = np.unique(np.concatenate([probe_indices(), worst]))
    row["mpmath_frequencies"] = {"indices": probe.tolist(), "largest_compiled_banded_difference_at": worst}
    exact = high_precision_frf(n, omega[probe])
    answers = {"frequency_response": compiled, "numpy_solve": results["numpy_solve"], "banded_loop": loop,
               "banded_vectorised": results["banded_vectorised"]}
    answers.update({f"bound_k{block}": results[f"bound_k{block}"][0] for block in bounds})
    row["error_vs_mpmath"] = {f"{name}_{label}": relative(H[k, probe], exact[k])
                              for name, H in answers.items() for k, label in enumerate(("driving_point", "tip"))}
    for block in bounds:
        row[f"bound_k{block}_certifies_every_frequency"] = bool(results[f"bound_k{block}"][1].all())
    for name in ("banded_loop", "banded_vectorised"):
        row[f"error_{name}_over_compiled"] = {
            label: row["error_vs_mpmath"][f"{name}_{label}"] / row["error_vs_mpmath"][f"frequency_response_{label}"]
            for label in ("driving_point", "tip")}
    row["compiled_vs_numpy_max_relative"] = relative(results["compiled_solve"], results["numpy_solve"])
    row["compiled_vs_numpy_max_normwise"] = float(np.max(np.abs(results["compiled_solve"] - results["numpy_solve"]))
                                                  / np.max(np.abs(results["numpy_solve"])))
    print(json.dumps(row), flush=True)
    return row


def banded_rows(row: dict, results: dict, n: int, omega: np.ndarray, repeats: int) -> None:
    """The two banded baselines of :mod:`lumped_chain.global_baselines` on the same chain and grid, into ``row``
    and ``results``.

    ``banded_loop`` -- ``scipy.linalg.solve_banded`` per frequency (:func:`~lumped_chain.global_baselines.
    banded_frequency_loop`), ``banded_vectorised`` -- the Thomas elimination vectorised over omega
    (:func:`~lumped_chain.global_baselines.thomas_frequency_batch`).  Both are timed on banded ``M, C, K`` prepared before
    timing (``reference.assemble_banded`` goes through dense ``n x n`` matrices: its time and memory are reported
    apart, ``banded_assembly_*``, and left out of the ratios, which favours the baselines).  Ratios
    ``frequency_response_over_*`` are CPU-time ratios (< 1: the compiled path is faster).
    """
    glob = global_chain(n)
    started = time.process_time()
    tracemalloc.start()
    try:
        Mb, Cb, Kb = reference.assemble_banded(glob)
        row["peak_bytes_banded_assembly"] = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    row["banded_assembly_cpu_s"] = time.process_time() - started
    cases = {"banded_loop": lambda: banded_frequency_loop(Mb, Cb, Kb, omega),
             "banded_vectorised": lambda: thomas_frequency_batch(Mb, Cb, Kb, omega)}
    for name, call in cases.items():
        row[f"{name}_s"], row[f"{name}_cpu_s"], results[name] = best(call, repeats)
        row[f"frequency_response_over_{name}_cpu"] = row["frequency_response_cpu_s"] / row[f"{name}_cpu_s"]
        row[f"peak_bytes_{name}"] = peak_bytes(call)
    row["banded_repeats"] = repeats


def run_controlled(n: int) -> dict:
    """Controlled-chain FRF and log-determinants, compiled against numpy (see the module text)."""
    from ctmm.assembly import riccati_solve
    from ctmm.chain_assembly import assemble
    from ctmm.control import ControlledChain, Feedback
    from ctmm.controlled_chain_frequency import closed_loop_solve, log_determinant

    plant = ctmm_chain(n)
    system = ControlledChain(plant, [Feedback("pd", [(f"m{n}.x", 20.0), (f"m{n}.v", 5.0)], f"m{n}", gain=1.0,
                                              delay=0.01)])
    omega = omega_grid(n)[::10]
    s = laplace_variables(omega)
    source = system.input("m1.force")
    amplitudes = {source.position: {source.input: 1.0}}
    points = sorted({system.signal(o).point for o in ("m1.x", f"m{n}.x")})
    z = 0.1 + s

    def numpy_log_det(chain):
        Us, us, start, end = assemble(chain, z)
        return riccati_solve(Us, us, start, end, want_states=False).log_det

    cases = {"closed_loop_compiled": lambda: closed_loop_solve(system, s, amplitudes, points).states[:, :, 0],
             "closed_loop_numpy": lambda: solve(system, s, amplitudes).states[points][:, :, 0],
             "log_det_compiled": lambda: log_determinant(system, z),
             "log_det_numpy": lambda: numpy_log_det(system),
             "plain_log_det_compiled": lambda: solve(plant, z, points=(), want_log_det=True, certify=False).log_det,
             "plain_log_det_numpy": lambda: numpy_log_det(plant)}
    row: dict = {"n_masses": n, "n_frequencies": int(omega.size), "load_average": list(os.getloadavg()),
                 "kernel": closed_loop_solve(system, s, amplitudes, points).kernel}
    results = {}
    for name, call in cases.items():
        call()
        row[f"{name}_s"], row[f"{name}_cpu_s"], results[name] = best(call, 3)
    for name in ("closed_loop", "log_det", "plain_log_det"):
        row[f"{name}_numpy_over_compiled_cpu"] = row[f"{name}_numpy_cpu_s"] / row[f"{name}_compiled_cpu_s"]
    compiled, numpy = results["closed_loop_compiled"], results["closed_loop_numpy"]
    row["closed_loop_compiled_vs_numpy_normwise"] = float(np.max(np.abs(compiled - numpy)) / np.max(np.abs(numpy)))
    for name in ("log_det", "plain_log_det"):
        row[f"{name}_compiled_vs_numpy_max"] = float(np.max(np.abs(np.expm1(results[f"{name}_compiled"]
                                                                              - results[f"{name}_numpy"]))))
    row["peak_bytes_closed_loop_compiled"] = peak_bytes(cases["closed_loop_compiled"])
    row["peak_bytes_closed_loop_numpy"] = peak_bytes(cases["closed_loop_numpy"])
    print(json.dumps(row), flush=True)
    return row


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=[1000, 10_000])
    parser.add_argument("--controlled", type=int, nargs="*", default=[20, 1000])
    parser.add_argument("--output", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    bounds = {block: bound_library(block) for block in (1, 8)}
    rows = [run(n, bounds) for n in args.sizes]
    controlled_rows = [run_controlled(n) for n in args.controlled]
    result = {"benchmark": "chain_frf", "machine": {"python": platform.python_version(), "numpy": np.__version__,
                                                    "processor": platform.processor() or platform.machine(),
                                                    "load_average": list(os.getloadavg())},
              "frequencies": "lumped_chain.model.omega_grid(n): 1000 log-spaced omega", "rows": rows,
              "controlled_rows": controlled_rows}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
