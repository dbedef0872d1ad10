"""Planar frequency responses: the one sweep's frequency context against the dense resolvent (issue 13).

Problem: the pendulum chain of ``benchmarks/planar_chain.py`` (N uniform links, 1 m, 1 kg, smooth hinges,
pinned, g = 9.81 m/s^2) hanging at rest; ``ctmm.frequency_response(chain, np.logspace(-1, 2, 500),
input="link<N-1>.force_x", output="link<N-1>.theta")`` [rad/N] (issue 13 target: N = 100, 500 omega,
<= 10 ms).

Methods (one run, one machine):

* ``sweep``        -- :func:`ctmm.frequency_response` with the hanging operating point given (its check
                      included): the one articulated sweep on the linearised terms, batched over the 500
                      frequencies (:mod:`ctmm.planar_transfer_response`), O(N) per frequency;
* ``sweep_equilibrium`` -- the same call without ``operating_point`` (the static equilibrium is searched
                      first, :func:`ctmm.planar.equilibrium.static_equilibrium`);
* ``equilibrium_search`` -- that search alone (``stable=True`` from the hanging guess, which already is the
                      equilibrium: its residual, then the stiffness of the stability check);
* ``sweep_only``   -- :meth:`~ctmm.planar_transfer_response.SweepResponse.response` alone (terms linearised
                      beforehand): the per-frequency work, by the compiled kernel of :mod:`ctmm.compiled_sweep`
                      (the default with a C compiler); ``kernel_only`` its C call alone;
* ``sweep_only_generic`` -- the same without a compiler: the generic numpy sweep
                      (:func:`ctmm.articulated.articulated_sweep`);
* ``first_compile`` -- wall time and the compiler's CPU time of building each kernel variant into an empty
                      cache folder (:func:`ctmm.codegen.shared_library`; the real variant on the first call, the
                      complex one on the first damped or delayed call; then cached on disk);
* ``resolvent``    -- the former path: :func:`ctmm.linearize` (complex-step tangent, 2N x 2N) and the dense
                      ``(s I - A)^-1 B`` with a condition number per frequency
                      (:func:`ctmm.controlled_linearization.delayed_loop_response`);
* ``compiled_bound`` -- the compiled lower bound of ``sweep_only``: the same articulated 3 x 3 recursion on the same
                      linearised terms (one hinge pivot per body, its certificate against the mass pivots, the
                      outward pass, the joint residuals' backward error), frequency by frequency in plain C
                      (``cc -O2``, loaded by ``ctypes``, built at run time as ``benchmarks/chain_schemes_generated.py``
                      builds its baseline); ``sweep_only_vs_bound`` is the ratio of CPU times;
* ``lagrange``     -- the reference: ``PlanarLagrange.linearize`` (analytic ``M, K`` about the hanging chain,
                      gravity's geometric stiffness included), ``e^T (K - omega^2 M)^-1 J_C^T e_x`` by a dense
                      solve per frequency (no transfer matrices).

Times: best wall time ``*_s`` and best CPU time ``*_cpu_s`` of this process (single-threaded code; on a shared
machine the CPU time is the figure to compare).  Errors: largest ``|G - G_lagrange| / |G_lagrange|`` over the frequencies (elementwise relative) and the same
against the resolvent path.  Run ``python benchmarks/planar_frf.py`` (``--quick``: N = 5, 20; ``--sizes``);
writes ``benchmarks/results/planar_frf.json``.
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
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "benchmarks"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

import ctmm  # noqa: E402
from ctmm.codegen import shared_library  # noqa: E402
from ctmm.compiled_sweep import COMPLEX_FLAGS, REAL_FLAGS, kernel_source  # noqa: E402
from ctmm.controlled_linearization import delayed_loop_response  # noqa: E402
from ctmm.planar.equilibrium import hanging_configuration, static_equilibrium  # noqa: E402
from ctmm.planar_linearization import linearize_planar, operating_point  # noqa: E402
from ctmm.planar_transfer_response import SweepResponse  # noqa: E402
from ctmm.reference.planar_lagrange import PlanarLagrange  # noqa: E402
from ctmm.sweep_response import PIVOT_TOLERANCE, RESIDUAL_TOLERANCE  # noqa: E402
from planar_chain import chain  # noqa: E402

OMEGA = np.logspace(-1, 2, 500)
RESULTS = ROOT / "benchmarks" / "results" / "planar_frf.json"


BOUND_C = r"""
#include <math.h>
/* The articulated sweep of a rigid tree with hinges on axis 2 (free[j] = 1) or welds, undamped, one load case,
   real s^2; bodies in topological order; Kin, RF: the parent's point maps of body j (row-major 3 x 3); both
   certificates of ctmm.sweep_response (pivots against the mass pivots, the joint residuals' backward error). */
void sweep(int n, int B, const int *parent, const int *free_, const double *M0, const double *K0,
           const double *Kin, const double *RF, const double *load, const double *kappa, const double *mass_pivot,
           double tol, double residual_tol, const double *squared, double *theta, int *good, double *acc,
           double *bias, double *w, double *r, double *x, double *rel, double *wrench, double *size)
{
    for (int b = 0; b < B; ++b) {
        const double sq = squared[b];
        int ok = 1;
        for (int i = 0; i < 9 * n; ++i) acc[i] = 0.0;
        for (int i = 0; i < 3 * n; ++i) bias[i] = 0.0;
        for (int j = n - 1; j >= 0; --j) {
            double P[9], p[3], T[9];
            for (int i = 0; i < 9; ++i) P[i] = sq * M0[9 * j + i] + K0[9 * j + i] + acc[9 * j + i];
            for (int i = 0; i < 3; ++i) p[i] = load[3 * j + i] + bias[3 * j + i];
            if (free_[j]) {
                const double D = P[8] + kappa[j], inertia = sq * mass_pivot[j];
                if (!(fabs(D) >= tol * (fabs(inertia) + fabs(D - inertia)))) ok = 0;
                const double col[3] = {P[2], P[5], P[8]};
                for (int k = 0; k < 3; ++k) w[3 * j + k] = P[6 + k] / D;
                r[j] = -p[2] / D;
                for (int i = 0; i < 3; ++i) {
                    for (int k = 0; k < 3; ++k) P[3 * i + k] -= col[i] * w[3 * j + k];
                    p[i] += col[i] * r[j];
                }
            }
            const int q = parent[j];
            if (q < 0) continue;
            const double *F = RF + 9 * j, *K = Kin + 9 * j;
            for (int i = 0; i < 3; ++i)
                for (int k = 0; k < 3; ++k)
                    T[3 * i + k] = F[3 * i] * P[k] + F[3 * i + 1] * P[3 + k] + F[3 * i + 2] * P[6 + k];
            for (int i = 0; i < 3; ++i) {
                for (int k = 0; k < 3; ++k)
                    acc[9 * q + 3 * i + k] += T[3 * i] * K[k] + T[3 * i + 1] * K[3 + k] + T[3 * i + 2] * K[6 + k];
                bias[3 * q + i] += F[3 * i] * p[0] + F[3 * i + 1] * p[1] + F[3 * i + 2] * p[2];
            }
        }
        for (int j = 0; j < n; ++j) {
            double *A = x + 3 * j;
            const int q = parent[j];
            if (q < 0) {
                A[0] = A[1] = A[2] = 0.0;
            } else {
                const double *K = Kin + 9 * j, *X = x + 3 * q;
                for (int i = 0; i < 3; ++i) A[i] = K[3 * i] * X[0] + K[3 * i + 1] * X[1] + K[3 * i + 2] * X[2];
            }
            rel[j] = 0.0;
            if (free_[j]) {
                rel[j] = r[j] - (w[3 * j] * A[0] + w[3 * j + 1] * A[1] + w[3 * j + 2] * A[2]);
                A[2] += rel[j];
            }
            theta[b * n + j] = A[2];
            if (!isfinite(A[2])) ok = 0;
        }
        /* the a-posteriori certificate: joint residuals of F_j = Z_j x_j + h_j + sum RF_c F_c, tip to base */
        for (int i = 0; i < 3 * n; ++i) wrench[i] = size[i] = 0.0;
        for (int j = n - 1; j >= 0; --j) {
            double F[3], S[3];
            const double *A = x + 3 * j;
            for (int i = 0; i < 3; ++i) {
                F[i] = load[3 * j + i] + wrench[3 * j + i];
                S[i] = fabs(load[3 * j + i]) + size[3 * j + i];
                for (int k = 0; k < 3; ++k) {
                    F[i] += (sq * M0[9 * j + 3 * i + k] + K0[9 * j + 3 * i + k]) * A[k];
                    S[i] += (fabs(sq * M0[9 * j + 3 * i + k]) + fabs(K0[9 * j + 3 * i + k])) * fabs(A[k]);
                }
            }
            if (free_[j]) {
                const double law = kappa[j] * rel[j];
                const double scale = S[2] + fabs(law);
                if (!(fabs(F[2] + law) <= residual_tol * scale)) ok = 0;
            }
            const int q = parent[j];
            if (q < 0) continue;
            const double *R = RF + 9 * j;
            for (int i = 0; i < 3; ++i) {
                wrench[3 * q + i] += R[3 * i] * F[0] + R[3 * i + 1] * F[1] + R[3 * i + 2] * F[2];
                size[3 * q + i] += fabs(R[3 * i]) * S[0] + fabs(R[3 * i + 1]) * S[1] + fabs(R[3 * i + 2]) * S[2];
            }
        }
        good[b] = ok;
    }
}
"""


def bound_library() -> ctypes.CDLL:
    """:data:`BOUND_C` compiled by the system ``cc`` (``-O2 -shared -fPIC``, the generated kernels' flags)."""
    folder = Path(tempfile.mkdtemp(prefix="ctmm-bench-frf-"))
    (folder / "bound.c").write_text(BOUND_C)
    subprocess.run(["cc", "-O2", "-shared", "-fPIC", "-o", str(folder / "bound.so"), str(folder / "bound.c"),
                    "-lm"], check=True)
    return ctypes.CDLL(str(folder / "bound.so"))


def compiled_bound(library: ctypes.CDLL, plant: SweepResponse, force: str, angle: str, omega: np.ndarray = OMEGA):
    """``(call, G)``: the C sweep of ``plant``'s terms as a repeatable call and its ``G`` (B,) of ``force`` to
    ``angle`` with the certified mask (the plant's kernel must have answered once: its mass pivots)."""
    kernel, n = plant.compiled, len(plant.bodies)
    parent = np.array(kernel.tree.parent, dtype=np.intc)
    free = np.array(kernel.axis >= 0, dtype=np.intc)
    assert all(a in (-1, 2) for a in kernel.axis) and kernel.undamped
    M0, K0 = kernel.M0.reshape(n, 9), kernel.K0.reshape(n, 9)
    Kin, RF = kernel.Kin.reshape(n, 9), kernel.RF.reshape(n, 9)
    load = np.ascontiguousarray(np.array([h[0, :, 0] for h in plant.loads(force)[0]]))
    kappa, mass = -kernel.stiffness.real, kernel.mass_pivot.copy()
    squared = -omega * omega
    theta, good = np.zeros((omega.size, n)), np.zeros(omega.size, dtype=np.intc)
    work = [np.zeros(9 * n), np.zeros(3 * n), np.zeros(3 * n), np.zeros(n), np.zeros(3 * n), np.zeros(n),
            np.zeros(3 * n), np.zeros(3 * n)]
    pointer = ctypes.POINTER(ctypes.c_double)

    def p(array: np.ndarray):
        return array.ctypes.data_as(ctypes.POINTER(ctypes.c_int) if array.dtype == np.intc else pointer)

    arguments = (ctypes.c_int(n), ctypes.c_int(omega.size), p(parent), p(free), p(M0), p(K0), p(Kin), p(RF), p(load),
                 p(kappa), p(mass), ctypes.c_double(PIVOT_TOLERANCE), ctypes.c_double(RESIDUAL_TOLERANCE), p(squared),
                 p(theta), p(good), *(p(a) for a in work))

    def call() -> None:
        library.sweep(*arguments)

    call()
    row = plant.rows([angle])[0, :plant.model.n_coordinates]
    index = np.asarray(plant.model.theta_index)
    amplitudes = np.zeros((omega.size, plant.model.n_coordinates))
    amplitudes[:, index[index >= 0]] = theta[:, index >= 0]
    return call, amplitudes @ row, good.astype(bool)


def generic_plant(model, n: int) -> SweepResponse:
    """The plant as it is without a C compiler (the generic numpy sweep)."""
    import ctmm.sweep_response as sweep_module

    present = sweep_module.compiler_present
    sweep_module.compiler_present = lambda: False
    try:
        plant = SweepResponse(model, operating_point(model, hanging(n)))
    finally:
        sweep_module.compiler_present = present
    assert plant.compiled is None
    return plant


def first_compile() -> dict:
    """Wall time and the compiler's CPU time [s] of building each kernel variant (d = 3) into an empty cache
    folder (the real one on the first call, the complex one on the first damped or delayed call)."""
    out = {}
    for label, complex_scalar, flags in (("real", False, REAL_FLAGS), ("complex", True, COMPLEX_FLAGS)):
        folder = tempfile.mkdtemp(prefix="ctmm-bench-frf-cache-")
        started, before = time.perf_counter(), os.times()
        shared_library(kernel_source(3, complex_scalar), "first_compile", flags=flags, cache_dir=folder)
        after = os.times()
        out[f"first_compile_{label}_s"] = time.perf_counter() - started
        out[f"first_compile_{label}_cpu_s"] = (after.children_user - before.children_user
                                               + after.children_system - before.children_system)
    return out


def ports(n: int) -> tuple[str, str]:
    return f"link{n - 1}.force_x", f"link{n - 1}.theta"


def hanging(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The hanging chain: every link straight down (absolute angles -pi/2), at rest."""
    return np.full(n, -np.pi / 2), np.zeros(n)


def best(call, repeats: int) -> tuple[float, float, object]:
    """Best wall time and best CPU time [s] of ``repeats`` calls (CPU: this process; the code is single-threaded,
    and on a loaded machine the wall time waits for the cores) and the last result."""
    walls, cpus, result = [], [], None
    for _ in range(repeats):
        started, cpu = time.perf_counter(), time.process_time()
        result = call()
        walls.append(time.perf_counter() - started)
        cpus.append(time.process_time() - cpu)
    return min(walls), min(cpus), result


def sweep(model, n: int, omega: np.ndarray = OMEGA):
    force, angle = ports(n)
    return ctmm.frequency_response(model, omega, input=force, output=angle, operating_point=hanging(n))


def lagrange(n: int, omega: np.ndarray = OMEGA) -> np.ndarray:
    model = chain(n)
    reference = PlanarLagrange(model)
    q0 = hanging(n)[0]
    M, _, K = reference.linearize(q0)
    kin = reference.kinematics(q0, np.zeros(n), 0.0)
    column = kin["j_c"][n - 1][0]                       # force_x at the last link's centre of mass
    row = np.zeros(n)
    row[reference.src[n - 1]] = 1.0                     # its absolute angle
    return np.array([row @ np.linalg.solve(K - w * w * M, column) for w in omega])


def resolvent(n: int, omega: np.ndarray = OMEGA) -> np.ndarray:
    model, (force, angle) = chain(n), ports(n)
    return delayed_loop_response(lambda a, b: linearize_planar(model, (), hanging(n), inputs=a, outputs=b), (),
                                 1j * omega, [force], [angle], model.name)[0][0, 0]


def relative(value: np.ndarray, reference: np.ndarray) -> float:
    return float(np.max(np.abs(value - reference) / np.abs(reference)))


def run(n: int, *, with_resolvent: bool, library: ctypes.CDLL | None = None) -> dict:
    model, (force, angle) = chain(n), ports(n)
    repeats = 5 if n <= 100 else 2
    plant = SweepResponse(model, operating_point(model, hanging(n)))
    generic = generic_plant(model, n)
    h = np.stack([column[0, :, 0] for column in plant.loads(force)[0]])[:, :, None]
    torque = np.zeros((len(plant.compiled.free), 1))
    cases = {"sweep": (lambda: sweep(model, n), repeats),
             "sweep_equilibrium": (lambda: ctmm.frequency_response(model, OMEGA, input=force, output=angle), 2),
             "equilibrium_search": (lambda: static_equilibrium(model, hanging_configuration(model), stable=True),
                                    repeats),
             "sweep_only": (lambda: plant.response(1j * OMEGA, [force], [angle]), repeats),
             "kernel_only": (lambda: plant.compiled.solve(1j * OMEGA, h, torque, pivot_tolerance=PIVOT_TOLERANCE,
                                                          residual_tolerance=RESIDUAL_TOLERANCE), repeats),
             "sweep_only_generic": (lambda: generic.response(1j * OMEGA, [force], [angle]), repeats),
             "lagrange": (lambda: lagrange(n), 1)}
    if with_resolvent:
        cases["resolvent"] = (lambda: resolvent(n), 1)
    out, results = {"n_links": n, "n_frequencies": int(OMEGA.size)}, {}
    for name, (call, count) in cases.items():
        out[f"{name}_s"], out[f"{name}_cpu_s"], results[name] = best(call, count)
    G, reference = results["sweep"].response[0, 0], results["lagrange"]
    if library is not None:
        call, bound, certified = compiled_bound(library, plant, force, angle)
        out["compiled_bound_s"], out["compiled_bound_cpu_s"], _ = best(call, 3 * repeats)
        out["sweep_only_vs_bound"] = out["sweep_only_cpu_s"] / out["compiled_bound_cpu_s"]
        out["kernel_only_vs_bound"] = out["kernel_only_cpu_s"] / out["compiled_bound_cpu_s"]
        out["generic_vs_bound"] = out["sweep_only_generic_cpu_s"] / out["compiled_bound_cpu_s"]
        out["error_bound_vs_sweep"] = relative(bound, G)
        out["bound_certifies_the_same"] = bool(np.array_equal(certified, results["sweep_only"][1]))
    out["error_generic_vs_compiled"] = relative(results["sweep_only_generic"][0][:, 0, 0],
                                                results["sweep_only"][0][:, 0, 0])
    out["generic_certifies_the_same"] = bool(np.array_equal(results["sweep_only_generic"][1],
                                                             results["sweep_only"][1]))
    out.update({"error_sweep_vs_lagrange": relative(G, reference),
                "dense_frequencies_in_sweep": results["sweep"].info["n_dense_frequencies"],
                "method": results["sweep"].info["method"]})
    if with_resolvent:
        out.update({"error_resolvent_vs_lagrange": relative(results["resolvent"], reference),
                    "error_sweep_vs_resolvent": relative(G, results["resolvent"])})
    print(json.dumps(out), flush=True)
    return out


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="N = 5, 20 only")
    parser.add_argument("--sizes", type=int, nargs="+", default=None)
    parser.add_argument("--output", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    sizes = args.sizes or ([5, 20] if args.quick else [5, 20, 100])
    resolvent(3, OMEGA[:2])                             # warm-up: the first linearisation imports and builds caches
    library = bound_library()
    compile_time = first_compile()
    print(json.dumps(compile_time), flush=True)
    rows = [run(n, with_resolvent=n <= 100, library=library) for n in sizes]
    return write_result("planar_frf", rows, args.output, compile_time)


def write_result(name: str, rows: list, output: Path, extra: dict | None = None) -> dict:
    """The benchmark's JSON (machine, load average, the frequency grid, ``extra`` entries, ``rows``) written to
    ``output``."""
    result = {"benchmark": name, "machine": {"python": platform.python_version(), "numpy": np.__version__,
                                             "processor": platform.processor() or platform.machine(),
                                             "load_average": list(os.getloadavg())},
              "frequencies": "np.logspace(-1, 2, 500) rad/s", **(extra or {}), "rows": rows}
    output.parent.mkdir(parents=True, exist_ok=True)
    output.write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
