"""Stability chart speed and accuracy: 100 x 100 gain x delay chart of a 20-mass chain with delayed PD.

Problem: 20 unit masses in series, springs 400 N/m with dampers 0.5 N s/m, fixed at the start and
free at the end; a delayed PD loop on the tip mass, ``u = -k (20 x + 5 v)(t - tau)``; chart over
the gain factor ``k`` in [0, 4] and the delay ``tau`` in [0, 0.3] s on a 100 x 100 grid.

Measured in one run, on the same machine:

* ``chart``          -- :func:`ctmm.stability_chart.stability_chart` (sequential): D-curves from
                        the affine loop term, exact crossings along the grid rows, one argument-
                        principle count per row interval (best and median of 3 runs, wall and
                        CPU time);
* ``chart_threads``  -- the same with ``executor="threads"``;
* ``direct_counts``  -- ``verify=True``: every grid point also counted directly by the vectorised
                        argument principle (the classification must agree);
* ``per_point_roots`` -- baseline: counting the unstable roots of each grid point separately with
                        :func:`ctmm.roots.count_roots_in_rectangle` on the TMM characteristic
                        function (timed on a few points, extrapolated to the 10 000).

Accuracy, against references that share no TMM code (``ctmm.reference``):

* **boundary**: for 200 points (k(Omega), tau(Omega)) of the D-curves, the root of the
  independently assembled delay equations ``M x'' + C x' + K x = -k(G x + H x')(t - tau)`` is
  polished by Newton's method on ``det(s I - A0 - A1 e^{-s tau})`` from ``s = i Omega``; the
  error is ``max |s_ref - i Omega|`` [rad/s] (0 for an exact boundary);
* **classification**: 40 random grid points, unstable-root counts against Chebyshev collocation
  of the same delay equations (Breda-Maset-Vermiglio, Newton-polished).

Run ``python benchmarks/stability_chart.py``; writes ``benchmarks/results/stability_chart.json``
and ``stability_chart.png``.
"""
from __future__ import annotations

import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import ctmm  # noqa: E402
from ctmm.control import ControlledChain, Feedback  # noqa: E402
from ctmm.elements import Fixed, Free, Mass, SpringDamper  # noqa: E402
from ctmm.reference.chain import GlobalChain, assemble  # noqa: E402
from ctmm.reference.dde import (chebyshev_collocation_roots, newton_refine_root,  # noqa: E402
                                second_order_system)
from ctmm.roots import count_roots_in_rectangle  # noqa: E402
from ctmm.scenario import write_json_atomic  # noqa: E402
from ctmm.stability_chart import stability_chart  # noqa: E402

N_MASSES, STIFFNESS, DAMPING, MASS = 20, 400.0, 0.5, 1.0
KP, KD = 20.0, 5.0
GAINS = np.linspace(0.0, 4.0, 100)
DELAYS = np.linspace(0.0, 0.3, 100)
RESULTS = ROOT / "benchmarks" / "results"


def system() -> ControlledChain:
    elements = [Fixed("wall")]
    for i in range(N_MASSES):
        elements += [SpringDamper(f"k{i}", STIFFNESS, DAMPING), Mass(f"m{i}", MASS)]
    elements.append(Free("end"))
    plant = ctmm.Chain("chain20", elements)
    tip = f"m{N_MASSES - 1}"
    return ControlledChain(plant, [Feedback("pd", [(f"{tip}.x", KP), (f"{tip}.v", KD)], tip, gain=1.0)])


def reference_equations(gain: float, delay: float):
    """First-order delay equations assembled from M, C, K (no transfer matrices)."""
    chain = GlobalChain(np.full(N_MASSES, MASS), np.r_[np.full(N_MASSES, STIFFNESS), 0.0],
                        np.r_[np.full(N_MASSES, DAMPING), 0.0], start="fixed", end="free")
    M, C, K = assemble(chain)
    G, H = np.zeros((N_MASSES, N_MASSES)), np.zeros((N_MASSES, N_MASSES))
    G[-1, -1], H[-1, -1] = gain * KP, gain * KD
    if delay == 0.0:
        return second_order_system(M, C + H, K + G, [])
    return second_order_system(M, C, K, [(G, H, delay)])


def timed(function, repeats: int = 3) -> tuple[object, dict]:
    walls, cpus, result = [], [], None
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        result = function()
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    return result, {"wall_s_best": min(walls), "wall_s_median": statistics.median(walls),
                    "cpu_s_best": min(cpus), "runs": repeats}


def boundary_accuracy(chart, n_points: int = 200) -> dict:
    points = []
    for b in chart.boundaries:
        if b.kind != "oscillatory":
            continue
        ok = np.isfinite(b.x) & np.isfinite(b.y) & (b.y > 0)
        points += list(zip(b.x[ok], b.y[ok], b.omega[ok]))
    rng = np.random.default_rng(1)
    chosen = [points[i] for i in sorted(rng.choice(len(points), min(n_points, len(points)), replace=False))]
    errors, real_parts = [], []
    for gain, delay, omega in chosen:
        A0, delayed = reference_equations(gain, delay)
        s = newton_refine_root(A0, delayed, 1j * omega)
        errors.append(abs(s - 1j * omega))
        real_parts.append(abs(s.real))
    return {"points": len(chosen), "max_abs_root_shift_rad_s": float(max(errors)),
            "max_abs_real_part": float(max(real_parts)),
            "definition": "Newton on the independent delay equations from s = i Omega at D-curve points "
                          "(k(Omega), tau(Omega)); |s_ref - i Omega| is 0 for an exact boundary"}


def classification_check(chart, n_points: int = 40) -> dict:
    rng = np.random.default_rng(2)
    agree, compared, skipped = 0, 0, 0
    for _ in range(n_points):
        iy, ix = int(rng.integers(1, DELAYS.size)), int(rng.integers(GAINS.size))
        count = chart.unstable_roots[iy, ix]
        A0, delayed = reference_equations(GAINS[ix], DELAYS[iy])
        roots = chebyshev_collocation_roots(A0, delayed, 24)[:60]
        roots = roots[np.abs(roots) < 200]
        refined = np.array([newton_refine_root(A0, delayed, z) for z in roots])
        refined = refined[np.abs(refined - roots) < 1e-4 * np.maximum(1, np.abs(roots))]
        if count < 0 or np.min(np.abs(refined.real)) < 1e-6:
            skipped += 1
            continue
        compared += 1
        agree += int(count == int(np.sum(refined.real > 0)))
    return {"compared": compared, "agree": agree, "skipped_on_boundary": skipped,
            "reference": "Chebyshev collocation (24 nodes) of the delay equations from M, C, K, "
                         "Newton-polished"}


def per_point_baseline(sys_: ControlledChain, radius: float, n_points: int = 4) -> dict:
    rng = np.random.default_rng(3)
    times = []
    for _ in range(n_points):
        g, tau = float(rng.choice(GAINS)), float(rng.choice(DELAYS))
        sys_p = sys_.with_loops([Feedback("pd", [("m19.x", g * KP), ("m19.v", g * KD)], "m19",
                                          gain=1.0, delay=tau)])
        t0 = time.perf_counter()
        count_roots_in_rectangle(lambda s: ctmm.characteristic_function(sys_p, s), (0.0, radius),
                                 (-radius, radius))
        times.append(time.perf_counter() - t0)
    per_point = statistics.mean(times)
    return {"seconds_per_point": per_point, "estimated_s_for_chart": per_point * GAINS.size * DELAYS.size,
            "timed_points": n_points}


def main() -> dict:
    import matplotlib

    matplotlib.use("Agg")
    sys_ = system()

    def chart_once(**options):
        return stability_chart(sys_, x=("gain", GAINS, "gain factor k [-]"),
                               y=("delay", DELAYS, "delay tau [s]"), **options)

    chart_once()                                           # warm-up (imports, caches)
    chart, seq = timed(chart_once)
    _, threads = timed(lambda: chart_once(executor="threads"))
    verified, direct = timed(lambda: chart_once(verify=True), repeats=1)
    baseline = per_point_baseline(sys_, chart.im_max)
    boundary = boundary_accuracy(chart)
    classes = classification_check(chart)
    summary = chart.summary()
    result = {
        "problem": {"masses": N_MASSES, "stiffness_N_m": STIFFNESS, "damping_N_s_m": DAMPING,
                    "loop": f"u = -k ({KP} x + {KD} v)(t - tau) on the tip mass",
                    "grid": [int(GAINS.size), int(DELAYS.size)], "gain_range": [0.0, 4.0],
                    "delay_range_s": [0.0, 0.3]},
        "timing": {"chart": seq, "chart_threads": threads, "direct_counts_verify": direct,
                   "per_point_roots_baseline": baseline, "target_s": 2.0,
                   "meets_target": seq["wall_s_best"] <= 2.0},
        "verify_agrees": verified.verified,
        "boundary_accuracy": boundary,
        "classification_vs_collocation": classes,
        "chart": summary,
        "machine": {"python": platform.python_version(), "numpy": np.__version__,
                    "processor": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
                    "load_average_1min": os.getloadavg()[0]},
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    write_json_atomic(RESULTS / "stability_chart.json", result)
    ax = chart.plot()
    ax.set_title(f"20-mass chain, delayed PD at the tip: {GAINS.size}x{DELAYS.size} chart in "
                 f"{seq['wall_s_best']:.2f} s", fontsize=9)
    ax.figure.savefig(RESULTS / "stability_chart.png", dpi=120, bbox_inches="tight")
    return result


if __name__ == "__main__":
    print(json.dumps(main()["timing"], indent=2))
