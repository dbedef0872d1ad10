"""Seed 001 Figs. 9.39-9.41 and 9.46: DT-TMM of the controlled chain, real-time and delayed.

Model (parameters in :mod:`controlled_chain_common`, our choice -- the seed's were lost): the
chain ``ground -[K1,C1]- m2 -[K3,C3]- m4 -[K5,C5]- m6`` released from ``x6(0) = 0.1 m`` (all
other displacements and all velocities zero), Newmark (beta = 1/4, gamma = 1/2), dt = 0.01 s.

* Fig. 9.39: motion with control (``u = -Ka x6`` on m2, Ka = 5 N/m, real time) and without.
* Fig. 9.40: the real-time loop m6 -> m2 by the DT-TMM (extended state, implicit: no lag)
  against the "Newton-Euler method" (the global closed-loop ODE, DOP853, rtol 1e-12).
* Fig. 9.41: the same with the loop acting across ``K3,C3`` (+u on m4, -u on m2).
* Fig. 9.46: the delayed loop ``u = -Ka x6(t - tau)`` on m2, tau = 0.05 s = 5 dt: the control
  force is known from the stored history and enters as an external force (seed §9.6.2),
  against the delay equations integrated by the method of steps.

Two references per case: the exact solution (``delay_chain.method_of_steps``; the DT-TMM
error is Newmark's O(dt^2)) and the global Newmark with the same loop rule
(``ctmm.reference.delay_newmark``; agreement to round-off).  For the delayed case the order is
measured on dt = 0.02, 0.01, 0.005 s.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import ctmm
from ctmm.reference.delay_chain import method_of_steps
from ctmm.reference.delay_newmark import newmark_closed_loop
from ctmm.scenario import accuracy

from . import controlled_chain_common as common

NAME = "controlled_chain_time"
DESCRIPTION = ("Seed Figs. 9.39-9.41, 9.46: DT-TMM with and without control, real-time (implicit) and "
               "delayed (history) loops against the exact closed-loop equations and a global Newmark")

X0 = np.array([0.0, 0.0, 0.1])
DT = 0.01


def _case(placement: str, gain: float, delay: float, t_final: float, dt: float = DT) -> dict:
    system, loops = common.controlled(placement, gain, delay)
    if gain == 0.0:  # uncontrolled: the bare plant (plain DT-TMM, no loop rows)
        system, loops = system.plant, []
    start = time.perf_counter()
    result = ctmm.simulate(system, t_final, dt, x0={"m6": float(X0[2])})
    tmm_time = time.perf_counter() - start
    x = np.column_stack([result[f"{m}.x"] for m in common.MASSES])
    chain = common.global_chain()
    start = time.perf_counter()
    exact = method_of_steps(chain, loops, t_final, X0, np.zeros(3), rtol=1e-12, atol=1e-14)
    x_exact = exact.evaluate(result.time).displacement
    ref_time = time.perf_counter() - start
    newmark = newmark_closed_loop(chain, loops, t_final, dt, X0, np.zeros(3))
    return {"time": result.time, "x": x, "exact": x_exact,
            "error_exact": float(np.max(np.abs(x - x_exact))),
            "error_newmark": float(np.max(np.abs(x - newmark.displacement))),
            "tmm_time": tmm_time, "reference_time": ref_time, "steps": int(result.time.size - 1),
            "path": result.info.get("loops") or result.info.get("path", "")}


def _plot(plt, path: Path, title: str, curves: list) -> None:
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7.5, 7.5))
    for k, ax in enumerate(axes):
        for t, x, style, label in curves:
            step = max(1, t.size // 80) if style not in ("-", "--", ":") else 1
            ax.plot(t[::step], x[::step, k], style, ms=4, mfc="none", lw=1.0, label=label)
    common.style_axes(axes)
    axes[0].set_title(title)
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    output_dir = Path(output_dir)
    t_final = 4.0 if quick else 15.0
    cases = {
        "uncontrolled": _case("m2", 0.0, 0.0, t_final),
        "real_time_m2": _case("m2", common.KA, 0.0, t_final),
        "real_time_across_K3": _case("K3", common.KA, 0.0, t_final),
        "delayed_m2": _case("m2", common.KA, common.DELAY, t_final),
    }
    ladder = (0.02, 0.01, 0.005)
    ladder_errors = [] if quick else [_case("m2", common.KA, common.DELAY, 4.0, dt)["error_exact"] for dt in ladder]
    order = float(np.polyfit(np.log(ladder), np.log(ladder_errors), 1)[0]) if ladder_errors else None

    figures = []
    c0, c1 = cases["uncontrolled"], cases["real_time_m2"]
    name = f"{NAME}_fig9_39.png"
    _plot(plt, output_dir / name, "Fig. 9.39: DT-TMM with (Ka = 5) and without (Ka = 0) control",
          [(c1["time"], c1["x"], "-", "ka = 5.0"), (c0["time"], c0["x"], "x", "ka = 0.0")])
    figures.append(name)
    for key, fig_id, title in (
            ("real_time_m2", "9_40", "Fig. 9.40: real-time loop m6 -> m2"),
            ("real_time_across_K3", "9_41", "Fig. 9.41: real-time loop m6 -> across K3,C3"),
            ("delayed_m2", "9_46", f"Fig. 9.46: delayed loop m6 -> m2, tau = {common.DELAY:g} s")):
        c = cases[key]
        name = f"{NAME}_fig{fig_id}.png"
        _plot(plt, output_dir / name, title,
              [(c["time"], c["exact"], "-", "Newton-Euler (global closed-loop equations, exact)"),
               (c["time"], c["x"], "x", f"DT-TMM controlled, dt = {DT:g} s")])
        figures.append(name)

    return {
        "accuracy": [
            accuracy("error vs global Newmark", max(c["error_newmark"] for c in cases.values()), "m", 1e-13,
                     "max over the four runs of max_t |x_DT-TMM - x_Newmark| (m2, m4, m6) against the global "
                     "Newmark with the same loop rule (ctmm.reference.delay_newmark): round-off",
                     source="docs/control.md: DT-TMM vs reference.delay_newmark < 1e-13 m"),
            accuracy("error vs exact solution", max(c["error_exact"] for c in cases.values()), "m", 1e-3,
                     "max over the four runs of max_t |x_DT-TMM - x_exact| (m2, m4, m6) against the closed-loop "
                     "equations solved by the method of steps (DOP853, rtol 1e-12); Newmark dt = 0.01 s, so this "
                     "is the O(dt^2) discretisation error",
                     source="1 % of the 0.1 m initial displacement")],
        "error_vs_exact_m": {k: c["error_exact"] for k, c in cases.items()},
        "error_vs_global_newmark_m": {k: c["error_newmark"] for k, c in cases.items()},
        "delayed_convergence": {"dt_s": list(ladder), "error_m": ladder_errors, "observed_order": order,
                                "t_final_s": 4.0} if ladder_errors else "skipped in quick mode",
        "loop_treatment": {k: c["path"] for k, c in cases.items()},
        "wall_time_s": sum(c["tmm_time"] for c in cases.values()),
        "reference_wall_time_s": sum(c["reference_time"] for c in cases.values()),
        "tmm_time_per_step_s": {k: c["tmm_time"] / c["steps"] for k, c in cases.items()},
        "initial_condition": "x6(0) = 0.1 m, all other displacements and all velocities 0",
        "dt_s": DT,
        "t_final_s": t_final,
        "parameters": common.PARAMETERS,
        "figures": figures,
    }
