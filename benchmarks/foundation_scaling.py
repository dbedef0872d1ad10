"""Cost against chain length: frequency responses and time steps of n = 10 ... 10 000 masses, today's paths.

Chain (:mod:`lumped_chain.model`): fixed-free, wall -- (K || c) -- m -- ... m (free end), K = 1000 N/m, m = 0.1 kg,
c = 0.2 N s/m (stiffness-proportional light damping).  Each path is named in the JSON (``path``, ``kernel``):

(a) :mod:`lumped_chain.frequency_cases` -- 1000 log-spaced omega, unit force on m1, driving point and tip:
    ``ctmm.frequency_response`` (default: the Riccati recursion in C where a C compiler is present), the numpy
    recursion (the path without a compiler), ``solve_banded`` per frequency, the banded system vectorised over
    omega, dense LU per frequency and python-control, with errors against a 30-digit mpmath solve.
(b) :mod:`lumped_chain.stepping_cases` -- Newmark(1/4, 1/2), dt = 1e-4 s, 200 steps: ``ctmm.simulate`` default
    (lumped DT-TMM in numpy), ``fast=False``, ``compiled=True`` (generated C), and global Newmark (dense, banded,
    O(n) banded), with the differences to the banded global Newmark.

CPU time (``time.process_time``) and wall time of the same calls; ratios ``*_cpu`` are CPU-time ratios within the
run; the load average is recorded.  ``benchmarks/chain_frf.py`` times the compiled chain FRF against a plain-C lower
bound of its recursion and reports memory.

Run ``python benchmarks/foundation_scaling.py`` (``--quick`` for n <= 1000); writes
``benchmarks/results/foundation_scaling.json`` and ``.png``.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import control  # noqa: E402  (imported before any timing: its import takes seconds)
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "benchmarks"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

import ctmm  # noqa: E402
from ctmm.reference import chain as reference  # noqa: E402  (benchmarks may use the validation models)
from ctmm.scenario import write_json_atomic  # noqa: E402
from lumped_chain.frequency_cases import fill_skips, frf_case  # noqa: E402
from benchmark_support.measure import code_version, machine, profile_top, slope  # noqa: E402
from lumped_chain.model import ctmm_chain, global_chain, omega_grid  # noqa: E402
from lumped_chain.stepping_cases import DT, N_STEPS, initial_displacements, stepping_case  # noqa: E402

SIZES = (10, 100, 1000, 10_000)
RESULTS = ROOT / "benchmarks" / "results"


def ratios(methods: dict, key: str, baseline: str) -> dict:
    """CPU-time and wall-time ratios of ``key`` over ``baseline`` and both errors against the 30-digit solve."""
    mine, other = methods[key], methods[baseline]
    out = {"cpu_time_ratio": mine["cpu_time_s"] / other["cpu_time_s"] if other.get("cpu_time_s") else None,
           "wall_time_ratio": mine["time_s"] / other["time_s"] if other.get("time_s") else None,
           "baseline_extrapolated": other.get("extrapolated")}
    for label in ("driving_point", "tip"):
        entry = f"rel_error_vs_mpmath_{label}"
        if entry in other:
            out[entry] = {key: mine[entry]["max"], baseline: other[entry]["max"],
                          "baseline_over_ctmm": other[entry]["max"] / mine[entry]["max"]}
    return out


def targets(frf_cases: list[dict]) -> dict:
    """Ratios of ``ctmm.frequency_response`` (default path) to each baseline at every n, and its cost exponent."""
    out: dict = {"ratios": {}}
    for case in frf_cases:
        methods = case["methods"]
        out["ratios"][str(case["n"])] = {
            f"ctmm_over_{baseline}": ratios(methods, "ctmm", baseline)
            for baseline in ("ctmm_numpy", "banded", "banded_vectorised", "dense", "python_control")
            if methods[baseline].get("time_s") is not None}
    by_n = {c["n"]: c for c in frf_cases}
    if 1000 in by_n and by_n[1000]["methods"]["python_control"].get("time_s"):
        pc = ratios(by_n[1000]["methods"], "ctmm", "python_control")
        out["frf_1000_vs_python_control"] = {"target": ">= 20x faster", "speedup_cpu_time": 1.0 / pc["cpu_time_ratio"],
                                             "speedup_wall_time": 1.0 / pc["wall_time_ratio"],
                                             "met": pc["cpu_time_ratio"] <= 1.0 / 20.0,
                                             "python_control_extrapolated": pc["baseline_extrapolated"]}
    ns = [n for n in by_n if n >= 100]
    if len(ns) >= 2:
        exponent = {key: slope(ns, [by_n[n]["methods"][key]["cpu_time_s"] for n in ns])
                    for key in ("ctmm", "ctmm_numpy", "banded", "banded_vectorised")}
        out["frf_cost_linear_in_n"] = {"target": "cost O(n)", "fitted_exponent_cpu_time_n>=100": exponent,
                                       "met": abs(exponent["ctmm"] - 1.0) <= 0.15}
    return out


def warm_up() -> None:
    """One small call of every timed library function (lazy imports, first-call caches)."""
    small = ctmm_chain(3)
    ctmm.frequency_response(small, [1.0, 2.0], input="m1.force", output="m3.x")
    ctmm.simulate(small, 2 * DT, DT, x0={"m1": 0.0})
    ctmm.simulate(small, 2 * DT, DT, x0={"m1": 0.0}, fast=False)
    ctmm.simulate(small, 2 * DT, DT, method="newmark", x0={"m1": 0.0}, compiled=True)
    control.frequency_response(control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]), [1.0])
    reference.frequency_response_banded(global_chain(3), [1.0], 0, 2)


def run(sizes=SIZES, *, quick: bool = False) -> dict:
    """Cases (a) and (b) at every size, the targets, profiles of the default paths and the provenance."""
    version = code_version()  # before any timing: the working tree is shared and may change
    warm_up()
    frf_cases = [frf_case(n) for n in sizes]
    fill_skips(frf_cases)
    step_cases = [stepping_case(n) for n in sizes]
    n_prof = 1000 if 1000 in sizes else sizes[-1]
    system = ctmm_chain(n_prof)
    omega = omega_grid(n_prof)
    x0_map = {f"m{j}": float(x) for j, x in enumerate(initial_displacements(n_prof), start=1)}
    profiles = {
        f"ctmm.frequency_response n={n_prof}": profile_top(
            lambda: ctmm.frequency_response(system, omega, input="m1.force", output=["m1.x", f"m{n_prof}.x"])),
        f"ctmm.simulate default path n={n_prof}, 200 steps": profile_top(
            lambda: ctmm.simulate(system, N_STEPS * DT, DT, x0=x0_map)),
        f"ctmm.simulate generic path n={n_prof}, 10 steps": profile_top(
            lambda: ctmm.simulate(system, 10 * DT, DT, x0=x0_map, fast=False)),
    }
    step_ns = [c["n"] for c in step_cases if c["n"] >= 100]
    step_slopes = {key: slope(step_ns, [c["methods"][key].get("cpu_time_per_step_s") or np.nan
                                        for c in step_cases if c["n"] >= 100])
                   for key in step_cases[0]["methods"]}
    return {
        "benchmark": "foundation_scaling",
        "chain": ("fixed-free wall-(K||c)-m x n, K=1000 N/m, m=0.1 kg, c=0.2 N s/m (stiffness-proportional "
                  "light damping, zeta_j = 1e-4 s * omega_j)"),
        "frequency_response": {
            "definition": ("1000 log-spaced omega in [omega_1/2, 0.95*200] rad/s, unit force on m1, outputs m1.x "
                           "(driving point) and m_n.x (tip) from one solve; time = whole call, best of up to 3 "
                           "while < 1 s spent; "
                           "every method's path named in it"),
            "cases": frf_cases},
        "time_stepping": {
            "definition": (f"Newmark(1/4,1/2), dt={DT} s, {N_STEPS} steps (fewer when the probe estimate exceeds "
                           "the budget: flag reduced_steps), x_i(0)=0.01 sin(pi i/(2n)) m, 100 N on m1; "
                           "time per step = whole call / steps (ctmm: also loop-only); difference to "
                           "reference.newmark_global(banded=True) over all masses and steps"),
            "cases": step_cases,
            "fitted_exponent_time_per_step_vs_n_(n>=100)": step_slopes},
        "targets": targets(frf_cases),
        "profiles_top_own_time": profiles,
        "machine": machine(),
        "code_version": version,
        "quick": quick,
    }


def plot(summary: dict, path: Path) -> None:
    """CPU time of every method against n: (a) 1000-frequency FRF, (b) one Newmark step."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_f, ax_s) = plt.subplots(1, 2, figsize=(12, 4.8))
    cases = summary["frequency_response"]["cases"]
    ns = [c["n"] for c in cases]
    for key, marker in (("ctmm", "o"), ("ctmm_numpy", "x"), ("banded", "s"), ("banded_vectorised", "v"),
                        ("dense", "D"), ("python_control", "^")):
        t = [c["methods"][key].get("cpu_time_s") for c in cases]
        ext = [c["methods"][key].get("extrapolated", False) for c in cases]
        pts = [(n, v) for n, v in zip(ns, t) if v is not None]
        if pts:
            line = ax_f.loglog(*zip(*pts), marker=marker, label=key + (" (open: extrapolated)" if any(ext) else ""))[0]
            for n, v, e in zip(ns, t, ext):
                if v is not None and e:
                    ax_f.loglog([n], [v], marker=marker, mfc="white", color=line.get_color())
    ax_f.set_xlabel("masses n")
    ax_f.set_ylabel("CPU time for 1000 frequencies [s]")
    ax_f.set_title("(a) frequency response")
    scases = summary["time_stepping"]["cases"]
    sns = [c["n"] for c in scases]
    for key, marker in (("ctmm", "o"), ("ctmm_generic", "v"), ("ctmm_compiled", "P"), ("global_banded", "s"),
                        ("global_dense", "D"), ("global_banded_linear", "x")):
        pts = [(n, c["methods"][key].get("cpu_time_per_step_s")) for n, c in zip(sns, scases)]
        pts = [p for p in pts if p[1] is not None]
        if pts:
            ax_s.loglog(*zip(*pts), marker=marker, label=key)
    ax_s.set_xlabel("masses n")
    ax_s.set_ylabel("CPU time per Newmark step [s]")
    ax_s.set_title("(b) time stepping")
    for ax in (ax_f, ax_s):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    load = summary.get("machine", {}).get("load_average_1_5_15min")
    if load:
        fig.suptitle(f"shared 2-core machine, load average {load[0]:.1f} during the run "
                     "(CPU times; wall times in the JSON)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> dict:
    """Command line: run, write the JSON and the PNG into ``--output``, return the summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="n <= 1000 only")
    parser.add_argument("--sizes", type=int, nargs="+", help="chain lengths (default: 10 100 1000 10000)")
    parser.add_argument("--output", type=Path, default=RESULTS, help="output folder")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    sizes = tuple(args.sizes) if args.sizes else SIZES[:3] if args.quick else SIZES
    summary = run(sizes, quick=args.quick or sizes != SIZES)
    summary["total_wall_time_s"] = time.perf_counter() - started
    args.output.mkdir(parents=True, exist_ok=True)
    write_json_atomic(args.output / "foundation_scaling.json", summary)
    plot(summary, args.output / "foundation_scaling.png")
    return summary


if __name__ == "__main__":
    main()
