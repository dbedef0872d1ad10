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
                      beforehand): the per-frequency work;
* ``resolvent``    -- the former path: :func:`ctmm.linearize` (complex-step tangent, 2N x 2N) and the dense
                      ``(s I - A)^-1 B`` with a condition number per frequency
                      (:func:`ctmm.controlled_linearization.delayed_loop_response`);
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
import json
import os
import platform
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "benchmarks"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

import ctmm  # noqa: E402
from ctmm.controlled_linearization import delayed_loop_response  # noqa: E402
from ctmm.planar.equilibrium import hanging_configuration, static_equilibrium  # noqa: E402
from ctmm.planar_linearization import linearize_planar, operating_point  # noqa: E402
from ctmm.planar_transfer_response import SweepResponse  # noqa: E402
from ctmm.reference.planar_lagrange import PlanarLagrange  # noqa: E402
from planar_chain import chain  # noqa: E402

OMEGA = np.logspace(-1, 2, 500)
RESULTS = ROOT / "benchmarks" / "results" / "planar_frf.json"


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


def run(n: int, *, with_resolvent: bool) -> dict:
    model, (force, angle) = chain(n), ports(n)
    repeats = 5 if n <= 100 else 2
    plant = SweepResponse(model, operating_point(model, hanging(n)))
    cases = {"sweep": (lambda: sweep(model, n), repeats),
             "sweep_equilibrium": (lambda: ctmm.frequency_response(model, OMEGA, input=force, output=angle), 2),
             "equilibrium_search": (lambda: static_equilibrium(model, hanging_configuration(model), stable=True),
                                    repeats),
             "sweep_only": (lambda: plant.response(1j * OMEGA, [force], [angle]), repeats),
             "lagrange": (lambda: lagrange(n), 1)}
    if with_resolvent:
        cases["resolvent"] = (lambda: resolvent(n), 1)
    out, results = {"n_links": n, "n_frequencies": int(OMEGA.size)}, {}
    for name, (call, count) in cases.items():
        out[f"{name}_s"], out[f"{name}_cpu_s"], results[name] = best(call, count)
    G, reference = results["sweep"].response[0, 0], results["lagrange"]
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
    rows = [run(n, with_resolvent=n <= 100) for n in sizes]
    result = {"benchmark": "planar_frf", "machine": {"python": platform.python_version(), "numpy": np.__version__,
                                                     "processor": platform.processor() or platform.machine(),
                                                     "load_average": list(os.getloadavg())},
              "frequencies": "np.logspace(-1, 2, 500) rad/s", "rows": rows}
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
