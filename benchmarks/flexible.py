"""Speed against error for the modal beam: spin-up and single link; cost against modes.

Writes ``benchmarks/results/flexible.json`` and ``flexible.png``:

* work-precision of the Kane-Ryan-Banerjee spin-up (4 modes, 0-20 s; error = max |tip - KG
  assumed-modes reference|) and of the motor-driven single link (3 modes, 0-2 s; error = max
  |tip - independent Euler-Lagrange|) for acceleration TMM + RK4 (dt ladder), TMM +
  solve_ivp DOP853 (rtol ladder) and the implicit DT-TMM (Newmark and generalized-alpha,
  Newton; dt ladder);
* cost of one acceleration sweep and of one implicit step against the number of modes;
* real-time factors (simulated time / wall time).

Run: ``python benchmarks/flexible.py [--quick]``.  Pure Python on a shared 2-core machine: the
load average is recorded; compare within a row.
"""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ctmm.flexible import ModalBeam  # noqa: E402
from ctmm.flexible.outputs import spinup_law, tip_deflection  # noqa: E402
from ctmm.planar import (DrivenHinge, Fixed, PlanarModel, accelerations, simulate_implicit,  # noqa: E402
                         simulate_rk4, simulate_scipy)
from ctmm.reference.beams import kane_spinup  # noqa: E402
from ctmm.reference.flexible_lagrange import FlexibleLagrange  # noqa: E402
from ctmm.schemes import GeneralizedAlpha, Newmark  # noqa: E402


def spin_model(n_modes: int) -> PlanarModel:
    a, r, c = spinup_law(6.0, 15.0)
    return PlanarModel.chain("spin", [Fixed("g"), DrivenHinge("motor", angle=a, rate=r,
                                                              acceleration=c),
                                      ModalBeam("beam", length=10.0, bending_stiffness=1.4e4,
                                                mass_per_length=1.2, n_modes=n_modes)],
                             gravity=(0.0, 0.0))


def link_model() -> PlanarModel:
    from ctmm.scenarios.single_link import model
    return model()


def _runs(model, beam, t_final, grid, y_ref, plan):
    z = np.zeros(model.n_coordinates)
    out = []
    for label, kind, value in plan:
        if kind == "rk4":
            sim = simulate_rk4(model, z, z, t_final=t_final, dt=value)
        elif kind == "dop853":
            sim = simulate_scipy(model, z, z, t_final=t_final, method="DOP853", rtol=value,
                                 atol=value * 1e-3, t_eval=grid)
        else:
            scheme = Newmark() if kind == "newmark" else GeneralizedAlpha(0.9)
            sim = simulate_implicit(model, z, z, t_final=t_final, dt=value, scheme=scheme)
        y = np.interp(grid, sim.t, tip_deflection(model, sim.q, beam))
        err = float(np.max(np.abs(y - y_ref)))
        out.append({"method": label, "parameter": value, "error_m": err,
                    "wall_time_s": sim.wall_time_s, "evaluations": int(sim.n_evaluations),
                    "real_time_factor": t_final / sim.wall_time_s})
        print(f"  {label:>24s} {value:8.1e}: error {err:.2e} m, {sim.wall_time_s:.2f} s",
              flush=True)
    return out


def cost_vs_modes(counts) -> list:
    """Best-of-7 timings (robust to machine load) of one sweep and one implicit step."""
    import timeit
    cost = []
    for n in counts:
        mm = spin_model(n)
        q = 1e-3 * np.ones(n)
        sweep = min(timeit.repeat(lambda: accelerations(mm, q, q, 5.0), number=20, repeat=7)) / 20
        steps = []
        for _ in range(3):
            sim = simulate_implicit(mm, np.zeros(n), np.zeros(n), t_final=0.1, dt=0.005)
            steps.append(sim.wall_time_s / 20)
        cost.append({"n_modes": n, "sweep_s": sweep, "implicit_step_s": min(steps),
                     "newton_iterations_mean": float(sim.iterations.mean())})
        print(f"  modes {n:2d}: sweep {1e6 * sweep:.0f} us, implicit step "
              f"{1e3 * min(steps):.2f} ms", flush=True)
    return cost


def cost_vs_bodies(counts) -> list:
    """Best-of-5 time of one sweep for chains of k modal beams (3 modes each) joined by
    elastic hinges: the modal accelerations are eliminated locally, so the cost is O(k)."""
    import timeit
    from ctmm.planar import ElasticHinge, Pinned
    out = []
    for k in counts:
        elements = [Pinned("o")]
        for i in range(k):
            if i:
                elements.append(ElasticHinge(f"h{i}", stiffness=50.0))
            elements.append(ModalBeam(f"b{i}", length=0.5, bending_stiffness=5.0,
                                      mass_per_length=0.7, n_modes=3))
        mm = PlanarModel.chain("beams", elements)
        q = 1e-2 * np.ones(mm.n_coordinates)
        t = min(timeit.repeat(lambda: accelerations(mm, q, q, 0.0), number=5, repeat=5)) / 5
        out.append({"n_beams": k, "n_coordinates": mm.n_coordinates, "sweep_s": t,
                    "per_beam_s": t / k})
        print(f"  {k:3d} beams: sweep {1e3 * t:.2f} ms ({1e6 * t / k:.0f} us per beam)",
              flush=True)
    return out


def main(quick: bool = False) -> dict:
    load = os.getloadavg()
    results = {"machine_load_average_start": load}
    # --- spin-up ------------------------------------------------------------------------------
    T = 20.0
    m = spin_model(4)
    grid = np.linspace(0.0, T, 401)
    ref = kane_spinup(n_modes=4, t_final=T, t_eval=grid)
    plan = [("TMM + RK4", "rk4", 0.02), ("TMM + RK4", "rk4", 0.01),
            ("TMM + DOP853", "dop853", 1e-6), ("DT-TMM Newmark", "newmark", 0.02),
            ("DT-TMM Newmark", "newmark", 0.01), ("DT-TMM gen-alpha 0.9", "genalpha", 0.01)]
    if not quick:
        plan += [("TMM + RK4", "rk4", 0.005), ("TMM + DOP853", "dop853", 1e-9),
                 ("DT-TMM Newmark", "newmark", 0.005)]
    print("spin-up", flush=True)
    results["spin_up"] = _runs(m, "beam", T, grid, ref.tip_deflection, plan)
    # --- single link --------------------------------------------------------------------------
    T = 2.0
    m = link_model()
    grid = np.linspace(0.0, T, 501)
    z = np.zeros(m.n_coordinates)
    start = time.perf_counter()
    sol = FlexibleLagrange(m).simulate(z, z, T, t_eval=grid, rtol=1e-11, atol=1e-13)
    ref_time = time.perf_counter() - start
    y_ref = tip_deflection(m, sol.y[:m.n_coordinates].T, "link")
    plan = [("TMM + RK4", "rk4", 2e-3), ("TMM + RK4", "rk4", 1e-3),
            ("TMM + DOP853", "dop853", 1e-7), ("DT-TMM Newmark", "newmark", 4e-3),
            ("DT-TMM Newmark", "newmark", 2e-3), ("DT-TMM Newmark", "newmark", 1e-3)]
    if not quick:
        plan += [("TMM + DOP853", "dop853", 1e-10), ("DT-TMM gen-alpha 0.9", "genalpha", 1e-3)]
    print("single link", flush=True)
    results["single_link"] = _runs(m, "link", T, grid, y_ref, plan)
    results["single_link_reference_wall_time_s"] = ref_time
    # --- cost against modes -------------------------------------------------------------------
    cost = cost_vs_modes((1, 2, 4, 8, 16) if not quick else (1, 4, 16))
    results["cost_vs_modes"] = cost
    results["cost_vs_bodies"] = cost_vs_bodies((1, 4, 16) if quick else (1, 4, 16, 64))
    results["machine_load_average_end"] = os.getloadavg()
    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "flexible.json").write_text(json.dumps(results, indent=2) + "\n")
    _plot(results, out / "flexible.png")
    return results


def _plot(results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(22, 4.8))
    for ax, key, title in ((axes[0], "spin_up", "spin-up (4 modes, 20 s)"),
                           (axes[1], "single_link", "single link (3 modes, 2 s)")):
        methods = sorted({r["method"] for r in results[key]})
        for method in methods:
            rows = sorted((r for r in results[key] if r["method"] == method),
                          key=lambda r: r["wall_time_s"])
            ax.loglog([r["wall_time_s"] for r in rows], [r["error_m"] for r in rows], "o-",
                      label=method)
        ax.set(xlabel="wall time [s]", ylabel="max tip error [m]", title=title)
        ax.legend(fontsize="small")
    c = results["cost_vs_modes"]
    axes[2].loglog([r["n_modes"] for r in c], [1e3 * r["sweep_s"] for r in c], "o-",
                   label="one acceleration sweep")
    axes[2].loglog([r["n_modes"] for r in c], [1e3 * r["implicit_step_s"] for r in c], "s-",
                   label="one implicit step (Newton)")
    axes[2].set(xlabel="number of modes", ylabel="[ms]", title="cost against modes")
    axes[2].legend(fontsize="small")
    b = results.get("cost_vs_bodies", [])
    if b:
        k = np.array([r["n_beams"] for r in b])
        axes[3].loglog(k, [1e3 * r["sweep_s"] for r in b], "o-", label="one sweep")
        axes[3].loglog(k, 1e3 * b[-1]["sweep_s"] * k / k[-1], "k:", label="O(n)")
        axes[3].set(xlabel="beams in the chain (3 modes each)", ylabel="[ms]",
                    title="modal accelerations eliminated locally: O(n)")
        axes[3].legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    if "--cost-only" in sys.argv:             # re-measure the cost table into the existing JSON
        path = ROOT / "benchmarks" / "results" / "flexible.json"
        data = json.loads(path.read_text())
        data["cost_vs_modes"] = cost_vs_modes((1, 2, 4, 8, 16))
        data["cost_vs_bodies"] = cost_vs_bodies((1, 4, 16, 64))
        data["cost_load_average"] = os.getloadavg()
        path.write_text(json.dumps(data, indent=2) + "\n")
        _plot(data, path.with_suffix(".png"))
    else:
        main(quick="--quick" in sys.argv)
