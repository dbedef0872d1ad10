"""Work-precision of the DT-TMM integrators on the Table 7.1 chain (seed 002 §7.2).

Problem (FORMULAS §3.3, reading A): wall -- K -- m1 -- K -- m2 -- ... -- K -- m5 (free end),
K = 1000 N/m, free length l = 0.1 m, m = 0.1 kg, a constant F = 100 N on m1 from t = 0, absolute
initial positions x_i(0) = 0.1 i m (every spring at its free length), zero velocity.

Error = max over the five masses of |x_i(0.5 s) - x_i,exact(0.5 s)| [m] in absolute coordinates,
with the exact solution from :func:`ctmm.reference.chain.exact_response` (matrix exponential of
the global first-order system, displacements from the unstretched configuration) plus the
unstretched positions :func:`ctmm.reference.chain.unstretched_positions`.

Methods, each on the same dt ladder and in the same run:

* ``ctmm.simulate`` with every scheme of :mod:`ctmm.schemes` (forward_euler, newmark,
  wilson_theta, houbolt, generalized_alpha), Riccati solver, lumped fast path (the default);
* the global-equation Newmark baseline :func:`ctmm.reference.chain.newmark_global`
  (average acceleration, dense LU factorised once).

Wall time = the whole call (set-up + all steps), best of repeated calls for short runs.
Observed order = least-squares slope of log(error) against log(dt) over the ladder, plus the
slopes between neighbouring steps.

Run ``python benchmarks/foundation_work_precision.py`` (``--quick`` for a 4-step ladder); writes
``benchmarks/results/foundation_work_precision.json`` and ``.png``.
"""
from __future__ import annotations

import argparse
import os
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
from ctmm.elements.boundary import Fixed, Free  # noqa: E402
from ctmm.elements.lumped import Mass, Spring  # noqa: E402
from ctmm.reference import chain as reference  # noqa: E402
from ctmm.scenario import write_json_atomic  # noqa: E402
from benchmark_support.measure import code_version, machine, timed  # noqa: E402

STIFFNESS, FREE_LENGTH, MASS, FORCE, N_MASSES = 1000.0, 0.1, 0.1, 100.0, 5
T_FINAL = 0.5
DT_LADDER = (1e-3, 5e-4, 2.5e-4, 1e-4, 5e-5, 2.5e-5, 1.25e-5)
SCHEMES = ("forward_euler", "newmark", "wilson_theta", "houbolt", "generalized_alpha")
REPEAT_UNTIL_S = 1.0     # repeat a call until this much time is spent (best time is kept) ...
MAX_REPEATS = 5          # ... but at most this often
RESULTS = ROOT / "benchmarks" / "results"


def table_7_1_chain() -> ctmm.Chain:
    """The Table 7.1 chain as a ctmm model (absolute coordinates, free lengths 0.1 m)."""
    elements = [Fixed("wall")]
    for i in range(1, N_MASSES + 1):
        elements.append(Spring(f"k{i}", STIFFNESS, free_length=FREE_LENGTH))
        elements.append(Mass(f"m{i}", MASS, force=FORCE if i == 1 else 0.0))
    elements.append(Free("end"))
    return ctmm.Chain("table_7_1", elements)


def table_7_1_reference() -> reference.GlobalChain:
    """The same chain for the global-equation reference (displacements from unstretched)."""
    lengths = np.full(N_MASSES + 1, FREE_LENGTH)
    lengths[-1] = 0.0  # no connector at the free end
    stiffness = np.full(N_MASSES + 1, STIFFNESS)
    stiffness[-1] = 0.0
    return reference.GlobalChain(np.full(N_MASSES, MASS), stiffness, free_length=lengths,
                                 start="fixed", end="free")


def initial_positions() -> dict[str, float]:
    return {f"m{i}": FREE_LENGTH * i for i in range(1, N_MASSES + 1)}


def force_vector() -> np.ndarray:
    f = np.zeros(N_MASSES)
    f[0] = FORCE
    return f


def exact_positions(glob: reference.GlobalChain) -> np.ndarray:
    """Exact absolute positions [m] of the masses at T_FINAL (reading A: x(0) = X0, v(0) = 0)."""
    x0 = np.asarray([initial_positions()[f"m{i}"] for i in range(1, N_MASSES + 1)])
    rest = reference.unstretched_positions(glob)
    exact = reference.exact_response(glob, [T_FINAL], x0 - rest, np.zeros(N_MASSES), force_vector())
    return rest + exact.displacement[-1]


def observed_orders(dts, errors) -> dict:
    dts, errors = np.asarray(dts, float), np.asarray(errors, float)
    ok = errors > 0
    slope = float(np.polyfit(np.log(dts[ok]), np.log(errors[ok]), 1)[0]) if ok.sum() >= 2 else float("nan")
    local = np.log(errors[:-1] / errors[1:]) / np.log(dts[:-1] / dts[1:])
    return {"least_squares": slope, "between_neighbours": local.tolist()}


def run(ladder=DT_LADDER) -> dict:
    version = code_version()  # before any timing: the working tree is shared and may change
    system = table_7_1_chain()
    glob = table_7_1_reference()
    x_exact = exact_positions(glob)
    x0 = initial_positions()
    names = [f"m{i}.x" for i in range(1, N_MASSES + 1)]
    methods: dict[str, dict] = {}
    for scheme in SCHEMES:
        rows = []
        for dt in ladder:
            sim, wall, cpu, runs = timed(lambda: ctmm.simulate(system, T_FINAL, dt, method=scheme, x0=x0),
                                       repeat_until=REPEAT_UNTIL_S, max_repeats=MAX_REPEATS)
            x_end = np.array([sim[n][-1] for n in names])
            rows.append({"dt": dt, "error_m": float(np.max(np.abs(x_end - x_exact))), "wall_time_s": wall,
                         "cpu_time_s": cpu, "n_steps": sim.info["n_steps"], "runs": runs, "path": sim.info["path"]})
            print(f"{scheme:18s} dt={dt:.3e}  error={rows[-1]['error_m']:.3e} m  wall={wall:.3e} s", flush=True)
        methods[scheme] = {"label": f"ctmm DT-TMM {scheme}", "runs": rows}
    rest = reference.unstretched_positions(glob)
    x0_rel = np.array([x0[f"m{i}"] for i in range(1, N_MASSES + 1)]) - rest
    force = force_vector()
    rows = []
    for dt in ladder:
        hist, wall, cpu, runs = timed(lambda: reference.newmark_global(glob, T_FINAL, dt, x0_rel, np.zeros(N_MASSES),
                                                                  lambda t: force),
                                      repeat_until=REPEAT_UNTIL_S, max_repeats=MAX_REPEATS)
        x_end = rest + hist.displacement[-1]
        rows.append({"dt": dt, "error_m": float(np.max(np.abs(x_end - x_exact))), "wall_time_s": wall,
                     "cpu_time_s": cpu, "n_steps": int(round(T_FINAL / dt)), "runs": runs})
        print(f"{'global newmark':18s} dt={dt:.3e}  error={rows[-1]['error_m']:.3e} m  wall={wall:.3e} s", flush=True)
    methods["global_newmark"] = {"label": "global Newmark (reference.newmark_global, dense LU)", "runs": rows}
    offsets = offset_roundoff(glob)
    for entry in methods.values():
        entry["observed_order"] = observed_orders([r["dt"] for r in entry["runs"]],
                                                  [r["error_m"] for r in entry["runs"]])
    # same algorithm, two implementations: DT-TMM Newmark vs global Newmark at equal dt
    agreement = [abs(a["error_m"] - b["error_m"]) for a, b in
                 zip(methods["newmark"]["runs"], methods["global_newmark"]["runs"])]
    ratios = [b["wall_time_s"] / a["wall_time_s"] for a, b in
              zip(methods["newmark"]["runs"], methods["global_newmark"]["runs"])]
    return {
        "benchmark": "foundation_work_precision",
        "problem": ("Table 7.1 chain (seed 002 §7.2; FORMULAS §3.3 reading A): wall-K-m x5, K=1000 N/m, "
                    "l=0.1 m, m=0.1 kg, F=100 N constant on m1, x_i(0)=0.1 i m absolute, v(0)=0"),
        "error_definition": ("max over the 5 masses of |x_i(0.5 s) - exact| [m], absolute coordinates; exact = "
                             "reference.chain.exact_response (expm) + unstretched_positions"),
        "wall_time_definition": ("whole call (set-up + all steps), best of up to 5 calls while < 1 s spent; "
                                 "cpu_time_s = best process CPU time of the same calls (single-threaded code, "
                                 "shared machine: see machine.load_average)"),
        "t_final_s": T_FINAL,
        "exact_positions_m": x_exact.tolist(),
        "dt_ladder_s": list(ladder),
        "methods": methods,
        "newmark_dttmm_vs_global": {
            "error_difference_m": agreement,
            "wall_time_ratio_global_over_dttmm": ratios,
            "note": "same algorithm (average-acceleration Newmark) in two implementations; the errors must agree "
                    "to round-off",
        },
        "absolute_coordinate_roundoff": offsets,
        "machine": machine(),
        "code_version": version,
    }


def offset_roundoff(glob: reference.GlobalChain, dt: float = 2.5e-5, offsets=(0.0, 1.0, 100.0)) -> dict:
    """Round-off of the displacement-form DT-TMM against the coordinate origin.

    The same chain is shifted by ``offset`` [m] (wall at ``offset``); the exact motion relative to
    the wall does not change, and the global Newmark (displacements from the unstretched state)
    does not see the offset.  The DT-TMM forms ``a = C x + D`` with ``C = 1/(beta dt^2)`` from
    absolute positions, so it loses about log10(C |x| / |a|) digits in the acceleration history.
    """
    rest = reference.unstretched_positions(glob)
    force = force_vector()
    glob_hist = reference.newmark_global(glob, T_FINAL, dt, np.zeros(N_MASSES), np.zeros(N_MASSES), lambda t: force)
    rows = []
    for offset in offsets:
        elements = [Fixed("wall", position=offset)]
        for i in range(1, N_MASSES + 1):
            elements.append(Spring(f"k{i}", STIFFNESS, free_length=FREE_LENGTH))
            elements.append(Mass(f"m{i}", MASS, force=FORCE if i == 1 else 0.0))
        elements.append(Free("end"))
        system = ctmm.Chain("table_7_1_shifted", elements)
        sim = ctmm.simulate(system, T_FINAL, dt, x0={f"m{i}": offset + FREE_LENGTH * i for i in range(1, N_MASSES + 1)})
        x = np.array([sim[f"m{i}.x"] for i in range(1, N_MASSES + 1)]).T - offset - rest
        rows.append({"wall_position_m": offset,
                     "max_difference_to_global_newmark_m": float(np.max(np.abs(x - glob_hist.displacement)))})
        diff = rows[-1]["max_difference_to_global_newmark_m"]
        print(f"offset {offset:6.1f} m: DT-TMM vs global Newmark {diff:.2e} m", flush=True)
    return {"dt": dt, "n_steps": int(round(T_FINAL / dt)), "rows": rows,
            "note": "same scheme (Newmark 1/4, 1/2) in two implementations; the difference is round-off only"}


def plot(summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_w, ax_h) = plt.subplots(1, 2, figsize=(12, 5.6))
    order = [k for k in (*SCHEMES, "global_newmark") if k in summary["methods"]]
    markers = dict(zip(order, "osD^vx"))
    for key in order:
        entry = summary["methods"][key]
        dt = [r["dt"] for r in entry["runs"]]
        err = [r["error_m"] for r in entry["runs"]]
        wall = [r["wall_time_s"] for r in entry["runs"]]
        style = "--" if key == "global_newmark" else "-"
        lab = f"{entry['label']} (order {entry['observed_order']['least_squares']:.2f})"
        ax_w.loglog(wall, err, style, marker=markers[key], label=lab)
        ax_h.loglog(dt, err, style, marker=markers[key])
    ax_w.set_xlabel("wall time [s]")
    ax_w.set_ylabel("max position error at t = 0.5 s [m]")
    ax_w.set_title("Table 7.1 chain: error vs wall time")
    ax_h.set_xlabel("dt [s]")
    ax_h.set_title("error vs step size")
    for ax in (ax_w, ax_h):
        ax.grid(True, which="both", alpha=0.3)
    fig.legend(*ax_w.get_legend_handles_labels(), loc="lower center", ncol=3, fontsize=8)
    load = summary.get("machine", {}).get("load_average_1_5_15min")
    if load:
        fig.suptitle(f"shared 2-core machine, load average {load[0]:.1f} during the run "
                     "(CPU times in the JSON)", fontsize=8)
    fig.tight_layout(rect=(0, 0.12, 1, 0.97))
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="4-step ladder (1e-3 .. 1e-4) for a smoke run")
    parser.add_argument("--output", type=Path, default=RESULTS, help="output folder")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    summary = run(DT_LADDER[:4] if args.quick else DT_LADDER)
    summary["quick"] = args.quick
    summary["total_wall_time_s"] = time.perf_counter() - started
    args.output.mkdir(parents=True, exist_ok=True)
    write_json_atomic(args.output / "foundation_work_precision.json", summary)
    plot(summary, args.output / "foundation_work_precision.png")
    return summary


if __name__ == "__main__":
    main()
