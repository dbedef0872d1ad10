"""Cost of control in ctmm: per-step overhead of the controller paths, and closed-loop FRF cost.

(a) Time domain, one closed loop, one run.  Seed chain of ``scenarios/controlled_chain_common``
(m2 = m4 = m6 = 1 kg, K = 10 N/m, C = 1 N s/m, fixed-free), PD law
``u = -(kp x6 + kd x6')`` on m2 with kp = 5 N/m, kd = 1 N s/m, released from x6(0) = 0.1 m,
Newmark(1/4, 1/2), dt = 1 ms, 2000 steps (``--quick``: 500).  Variants:

* ``plant``            -- no control (``simulate_controlled`` of the bare chain: the baseline);
* ``embedded``         -- :class:`~ctmm.control.Feedback` with sensor terms ``kp m6.x + kd m6.v``,
                          real time: implicit, extended-state DT-TMM step (no lag);
* ``embedded_delayed`` -- the same loop delayed by one step (tau = dt): force from the stored
                          history, no extended state;
* ``python``           -- ``ctmm.controllers.SaturatedPD`` (no limit) as a co-simulated Python
                          object, sample time dt, zero-order hold;
* ``fmu``              -- the FMI 2.0 ``pd_controller`` FMU built from ``controllers/fmu`` with gcc,
                          sample time dt (same law, compiled C through fmpy).

Per-step time = CPU time of this process (``time.process_time``: the machine is shared, wall
time is reported too) of the best of 7 round-robin rounds (after a warm-up run) / steps; overhead = per-step time minus the plant's.
Also: the bare controller call (``step`` 2000 times with fixed inputs) for the Python object and
the FMU, and the deviation of every variant from ``embedded`` (max |x6 - x6_embedded| [m]: the
ZOH of co-simulation is O(dt)); FMU vs Python must be identical.

(b) Closed-loop frequency response on 1000 frequencies (0.01 ... 10 rad/s) of a fixed-free chain of
n masses (1 kg, 10 N/m, 1 N s/m) with the loop ``u = -5 x_tip`` on the first mass; outputs the
first, middle and tip displacement per unit force on the tip; n = 3 (the seed chain), 30, 100.

* ``tmm``             -- :func:`ctmm.frequency_response` of the :class:`~ctmm.control.ControlledChain`;
* ``python_control``  -- the exported open-loop :func:`ctmm.interop.to_state_space` (export time
                         reported separately), closed with ``control.feedback`` (static gain on the
                         loop channel of an augmented plant) and evaluated by
                         ``control.frequency_response`` (no slycot);
* ``plant_cache``     -- :class:`ctmm.control.design.PlantCache` re-evaluation for a new gain after
                         its one-off TMM sweep (build time reported separately).

FRF differences: max |H - H_tmm| / max |H_tmm|.  Times: best CPU time of 3 calls.

Run ``python benchmarks/control_overhead.py [--quick]``; writes
``benchmarks/results/control_overhead.json`` and ``.png``.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import control  # noqa: E402  (imported before any timing)
import fmpy  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

import ctmm  # noqa: E402
from ctmm.control import ControlledChain, Feedback, FMUController, build_fmu, simulate_controlled  # noqa: E402
from ctmm.control.design import PlantCache  # noqa: E402
from ctmm.elements import Fixed, Free, Mass, SpringDamper  # noqa: E402
from ctmm.interop import to_state_space  # noqa: E402
from ctmm.scenario import write_json_atomic  # noqa: E402
from benchmark_support.measure import machine  # noqa: E402

from _controllers_import import load_controllers  # noqa: E402

controllers = load_controllers()

KP, KD, DT = 5.0, 1.0, 1e-3
REPEATS = 3  # frequency-domain repeats
RESULTS = ROOT / "benchmarks" / "results"


def chain(n: int) -> ctmm.Chain:
    elements = [Fixed("ground")]
    for i in range(n):
        elements += [SpringDamper(f"k{i}", 10.0, 1.0), Mass(f"m{i}", 1.0)]
    return ctmm.Chain(f"chain{n}", elements + [Free("tip")])


def best_of(fn, repeats: int = REPEATS):
    """Best CPU time [s] of ``repeats`` calls (process time: robust to other load) and the value."""
    times, value = [], None
    for _ in range(repeats):
        start = time.process_time()
        value = fn()
        times.append(time.process_time() - start)
    return min(times), value


# ------------------------------------------------------------------------------ time domain
def time_domain(t_final: float, fmu_path: Path, repeats: int) -> dict:
    plant = chain(3)  # m0, m1, m2 = the seed's m2, m4, m6
    pd_terms = [("m2.x", KP), ("m2.v", KD)]
    variants = {
        "plant": lambda: simulate_controlled(plant, t_final, DT, x0={"m2": 0.1}),
        "embedded": lambda: simulate_controlled(
            ControlledChain(plant, [Feedback("pd", pd_terms, "m0", gain=1.0)]), t_final, DT, x0={"m2": 0.1}),
        "embedded_delayed": lambda: simulate_controlled(
            ControlledChain(plant, [Feedback("pd", pd_terms, "m0", gain=1.0, delay=DT)]), t_final, DT,
            x0={"m2": 0.1}),
        "python": lambda: simulate_controlled(
            plant, t_final, DT, x0={"m2": 0.1},
            controllers=[controllers.SaturatedPD(("m2.x", "m2.v"), ("m0.force",), kp=KP, kd=KD, sample_time=DT)]),
        "fmu": lambda: simulate_controlled(
            plant, t_final, DT, x0={"m2": 0.1},
            controllers=[FMUController(fmu_path, inputs={"y": "m2.x", "ydot": "m2.v"}, outputs={"u": "m0.force"},
                                       parameters={"kp": KP, "kd": KD, "limit": 0.0, "reference": 0.0},
                                       sample_time=DT)]),
    }
    # one warm-up run each, then REPEATS rounds over all variants (round robin: a load change on
    # the shared machine hits every variant alike); best of the rounds
    runs = {name: fn() for name, fn in variants.items()}
    walls: dict[str, list] = {name: [] for name in variants}
    cpus: dict[str, list] = {name: [] for name in variants}
    for _ in range(repeats):
        for name, fn in variants.items():
            start, cpu = time.perf_counter(), time.process_time()
            fn()
            cpus[name].append(time.process_time() - cpu)
            walls[name].append(time.perf_counter() - start)
    results = {}
    for name, res in runs.items():
        steps = res.time.size - 1
        results[name] = {"cpu_s": min(cpus[name]), "per_step_s": min(cpus[name]) / steps,
                         "wall_s": min(walls[name]), "per_step_wall_s": min(walls[name]) / steps, "steps": steps}
    base = results["plant"]["per_step_s"]
    ref_x = runs["embedded"]["m2.x"]
    for name, entry in results.items():
        entry["overhead_per_step_s"] = entry["per_step_s"] - base
        entry["max_abs_diff_x6_vs_embedded_m"] = float(np.max(np.abs(runs[name]["m2.x"] - ref_x)))
    py_over = results["python"]["overhead_per_step_s"]
    for entry in results.values():
        entry["overhead_ratio_to_python"] = entry["overhead_per_step_s"] / py_over if py_over > 0 else None
        entry["per_step_ratio_to_plant"] = entry["per_step_s"] / base
    fmu_vs_python = max(float(np.max(np.abs(runs["fmu"][f"m{i}.{q}"] - runs["python"][f"m{i}.{q}"])))
                        for i in range(3) for q in ("x", "v"))
    # bare controller calls
    calls = {}
    y = np.array([0.01, -0.2])
    pd = controllers.SaturatedPD(("m2.x", "m2.v"), ("m0.force",), kp=KP, kd=KD, sample_time=DT)
    fmu = FMUController(fmu_path, inputs={"y": "m2.x", "ydot": "m2.v"}, outputs={"u": "m0.force"},
                        parameters={"kp": KP, "kd": KD, "limit": 0.0, "reference": 0.0}, sample_time=DT)
    for name, ctrl in (("python", pd), ("fmu", fmu)):
        def loop(ctrl=ctrl):
            state = ctrl.init(0.0)
            for k in range(2000):
                _, state = ctrl.step(k * DT, y, state)
            closer = getattr(state, "close", None)
            if callable(closer):
                closer()
        wall, _ = best_of(loop)
        calls[name] = {"per_call_s": wall / 2000}
    return {"variants": results, "fmu_vs_python_max_abs_state_diff": fmu_vs_python, "controller_calls": calls,
            "t_final_s": t_final, "dt_s": DT, "kp": KP, "kd": KD}


# -------------------------------------------------------------------------- frequency domain
def frequency_domain(sizes) -> dict:
    omega = np.linspace(0.01, 10.0, 1000)
    out = {}
    for n in sizes:
        plant = chain(n)
        tip, first, mid = f"m{n - 1}", "m0", f"m{n // 2}"
        outputs = [f"{first}.x", f"{mid}.x", f"{tip}.x"]
        system = ControlledChain(plant, [Feedback("loop", f"{tip}.x", first, gain=5.0)])
        t_tmm, frf = best_of(lambda: ctmm.frequency_response(system, omega, input=f"{tip}.force", output=outputs))
        H = frf.response[:, 0]
        t_export, P = best_of(lambda: to_state_space(plant, inputs=[f"{tip}.force", f"{first}.force"],
                                                     outputs=outputs + [f"{tip}.x"]))

        def python_control():
            K = np.zeros((2, 4))
            K[1, 3] = 5.0                                   # u (2nd input) = -5 y (4th output)
            closed = control.feedback(P, control.ss([], [], [], K), sign=-1)
            return control.frequency_response(closed, omega)

        t_pc, response = best_of(python_control)
        H_pc = np.asarray(response.complex)[:3, 0, :]
        t_build, cache = best_of(lambda: PlantCache(system, omega, inputs=f"{tip}.force", outputs=outputs), 1)
        t_cache, cached = best_of(lambda: cache.closed_loop(gains={"loop": 5.0}))
        scale = np.max(np.abs(H))
        out[f"n={n}"] = {
            "n_masses": n, "n_omega": int(omega.size),
            "tmm_s": t_tmm, "python_control_s": t_pc, "export_state_space_s": t_export,
            "plant_cache_build_s": t_build, "plant_cache_evaluation_s": t_cache,
            "ratio_python_control_over_tmm": t_pc / t_tmm,
            "ratio_tmm_over_plant_cache": t_tmm / t_cache,
            "frf_difference_python_control": float(np.max(np.abs(H_pc - H)) / scale),
            "frf_difference_plant_cache": float(np.max(np.abs(cached.response[:, 0] - H)) / scale),
        }
    return out


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    variants = results["time_domain"]["variants"]
    names = list(variants)
    ax1.bar([k.replace("_", "\n") for k in names], [variants[k]["per_step_s"] * 1e6 for k in names],
            color=[f"C{i}" for i in range(len(names))])
    for i, k in enumerate(names):
        ax1.text(i, variants[k]["per_step_s"] * 1e6, f"{variants[k]['per_step_s'] * 1e6:.0f}", ha="center",
                 va="bottom", fontsize=8)
    ax1.set_ylabel("CPU time per step [us]")
    ax1.set_title("DT-TMM closed loop (3 masses, PD), same run")
    ax1.grid(True, axis="y", alpha=0.3)
    freq = results["frequency_domain"]
    sizes = [v["n_masses"] for v in freq.values()]
    x = np.arange(len(sizes))
    for j, (key, label) in enumerate((("tmm_s", "TMM (ControlledChain)"), ("python_control_s", "python-control"),
                                      ("plant_cache_evaluation_s", "PlantCache re-evaluation"))):
        ax2.bar(x + (j - 1) * 0.27, [v[key] for v in freq.values()], width=0.27, label=label)
    ax2.set_yscale("log")
    ax2.set_xticks(x, [f"n = {n}" for n in sizes])
    ax2.set_ylabel("closed-loop FRF, 1000 frequencies, CPU [s]")
    ax2.grid(True, axis="y", which="both", alpha=0.3)
    ax2.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="500 steps, n = 3 and 30 only")
    parser.add_argument("--output", default=str(RESULTS), help="results folder")
    args = parser.parse_args(argv)
    assert shutil.which("gcc"), "gcc is needed to build the FMU"
    fmu_path = build_fmu(controllers.fmu_source("pd_controller"), compiler="gcc")
    started = time.perf_counter()
    results = {
        "benchmark": "control_overhead",
        "description": __doc__.split("\n\n")[0],
        "machine": {**machine(), "fmpy": fmpy.__version__},
        "time_domain": time_domain(0.5 if args.quick else 2.0, fmu_path, 3 if args.quick else 7),
        "frequency_domain": frequency_domain((3, 30) if args.quick else (3, 30, 100)),
        "quick": args.quick,
    }
    results["total_wall_time_s"] = time.perf_counter() - started
    results["machine"]["load_average_after"] = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(out / "control_overhead.json", results)
    plot(results, out / "control_overhead.png")
    td = results["time_domain"]["variants"]
    print("per step [us]: " + ", ".join(f"{k} {v['per_step_s'] * 1e6:.0f}" for k, v in td.items()))
    for key, v in results["frequency_domain"].items():
        print(f"FRF {key}: tmm {v['tmm_s'] * 1e3:.1f} ms, python-control {v['python_control_s'] * 1e3:.1f} ms, "
              f"cache {v['plant_cache_evaluation_s'] * 1e3:.2f} ms, diff {v['frf_difference_python_control']:.1e}")
    return results


if __name__ == "__main__":
    main()
