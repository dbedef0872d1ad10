"""Seed 001 controlled chain with a delayed loop: K_a x tau stability chart.

Model: the chain of Figs. 9.27/9.36 (parameters of :mod:`controlled_chain_common`) with the
non-collocated loop ``u(t) = -K_a x6(t - tau)`` on m2.  The chart over ``K_a`` and ``tau`` comes
from the transfer-matrix characteristic function (the loop enters it as an affine term; exact
``e^{-s tau}``).  Independent references, assembled from M, C, K by ``ctmm.reference`` (no
transfer matrices):

* the stable/unstable classification against Chebyshev collocation of the delay equations
  ``M x'' + C x' + K x = -K_a e_2 e_6^T x(t - tau)`` (``reference.dde.second_order_system``) on a
  sub-grid;
* the D-curve points against the global dynamic stiffness
  ``s^2 M + s C + K + K_a e^{-s tau} e_2 e_6^T``, which must be singular at ``s = i Omega``
  (smallest over largest singular value);
* the delay margin of ``K_a = 5`` against python-control's margins of the loop transfer function
  (:func:`ctmm.control.analysis.margins`), and simulations on both sides of the boundary.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ctmm.control import margins
from ctmm.reference.chain import assemble
from ctmm.reference.dde import second_order_system
from ctmm.reference.delay_chain import GlobalLoop, closed_loop_dynamic_stiffness
from ctmm.stability import crosscheck_by_simulation, delay_margin, gain_margin, stability_chart
from ctmm.scenario import accuracy

from . import controlled_chain_common as common
from .delay_common import DCURVE_BOUND_SOURCE, boundary_points, compare_classification

NAME = "delay_chain_chart"
DESCRIPTION = ("Seed chain, loop m6 -> m2 with delay: K_a x tau stability chart from the TMM against "
               "collocation of the globally assembled delay equations, delay margin, simulation")


def first_order(gain: float, tau: float):
    M, C, K = assemble(common.global_chain())
    G = np.zeros((3, 3))
    G[0, 2] = gain                                       # force on m2 from the position of m6
    if tau == 0.0:
        return second_order_system(M, C, K + G, [])
    return second_order_system(M, C, K, [(G, np.zeros((3, 3)), tau)])


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = 40 if quick else 120
    gains, taus = np.linspace(-15.0, 40.0, n), np.linspace(0.0, 1.0, n)
    system, _ = common.controlled("m2", common.KA, common.DELAY)
    started = time.perf_counter()
    chart = stability_chart(system, x=("gain", gains, "K_a [N/m]"), y=("delay", taus, "tau [s]"))
    wall = time.perf_counter() - started

    ref_started = time.perf_counter()
    classes = compare_classification(chart, first_order, stride=4 if quick else 8)
    x, t, w = boundary_points(chart)
    step = max(1, x.size // (60 if quick else 300))
    ratios = []
    for g, tau, omega in zip(x[::step], t[::step], w[::step]):
        D = closed_loop_dynamic_stiffness(common.global_chain(), [GlobalLoop(2, "displacement", 0, g, tau)],
                                          1j * omega)
        sv = np.linalg.svd(D, compute_uv=False)
        ratios.append(sv[-1] / sv[0])
    boundary_error = float(max(ratios))
    xs, _, _ = boundary_points(chart, "static")
    static_gain = -float(np.linalg.det(assemble(common.global_chain())[2]) /
                         np.linalg.det(np.delete(np.delete(assemble(common.global_chain())[2], 0, 0), 2, 1)))
    ref_wall = time.perf_counter() - ref_started

    margin = delay_margin(system)
    omega = np.linspace(0.01, 10.0, 4000)
    reference_margin = margins(system.with_loops([system.loops[0].with_parameters(delay=0.0)]), "control", omega)
    margin_error = abs(margin.critical_delay - reference_margin.delay_margin)
    gm = gain_margin(system)
    t_final, dt = (20.0, 0.02) if quick else (60.0, 0.01)
    tau_c = margin.critical_delay
    check = crosscheck_by_simulation(system, [{"delay": 0.7 * tau_c}, {"delay": 1.4 * tau_c}],
                                     t_final=t_final, dt=dt)

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    chart.plot(ax=axes[0])
    axes[0].plot([common.KA] * 2, [0.7 * tau_c, 1.4 * tau_c], "o", color="tab:red", ms=4,
                 label="simulated points")
    axes[0].legend(fontsize=8, loc="upper right")
    axes[0].set_title(f"(a) seed chain, u = -K_a x6(t - tau) on m2; delay margin at K_a = 5: "
                      f"{tau_c:.4f} s", fontsize=9)
    for label, (p, rate, alpha) in zip(("stable side", "unstable side"),
                                       zip(check.points, check.rate, check.abscissa)):
        axes[1].bar(label + "\nroots", alpha, color="tab:blue", alpha=0.6)
        axes[1].bar(label + "\nsimulation", rate, color="tab:orange", alpha=0.6)
    axes[1].axhline(0.0, color="k", lw=0.6)
    axes[1].set_ylabel("growth rate [1/s]")
    axes[1].set_title("(b) spectral abscissa vs envelope growth of the DT-TMM simulation", fontsize=9)
    fig.tight_layout()
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / f"{NAME}.png", dpi=100)
    plt.close(fig)
    static_error = float(np.max(np.abs(xs - static_gain))) if xs.size else 0.0
    return {
        "accuracy": [
            accuracy("D-curve error vs global delay model", max(boundary_error, static_error / abs(static_gain)),
                     "relative", 1e-9,
                     "max of sigma_min/sigma_max of the global dynamic stiffness s^2 M + s C + K + "
                     "K_a e^{-s tau} e_2 e_6^T at the TMM D-curve points (s = i Omega) and the relative error of "
                     "the static boundary K_a = -det K / minor",
                     source=DCURVE_BOUND_SOURCE),
            accuracy("delay margin error vs python-control", margin_error, "s", 1e-9,
                     "|delay margin - python-control margins on the exact L|",
                     source=DCURVE_BOUND_SOURCE)],
        "boundary_singularity": boundary_error,
        "static_boundary": {"tmm": xs[:1].tolist(), "reference": static_gain},
        "classification_vs_collocation": classes,
        "delay_margin": margin.as_dict(),
        "delay_margin_python_control": reference_margin.delay_margin,
        "gain_margin": gm.as_dict(),
        "simulation_check": check.as_dict(),
        "chart": chart.summary(),
        "parameters": common.PARAMETERS,
        "wall_time_s": wall,
        "reference_wall_time_s": ref_wall,
        "figures": [f"{NAME}.png"],
    }
