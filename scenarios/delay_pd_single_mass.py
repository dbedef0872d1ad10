"""Delayed PD control of a single mass: the classical stability charts (Stepan 1989).

Model: a free mass m = 1 kg with ``u(t) = -(kp x + kd v)(t - tau)`` -- the TMM chain
``[Free, Mass, Free]`` closed by one ``Feedback`` with sensor weights ``kp`` ("m.x") and ``kd``
("m.v").  Characteristic function ``m s^2 + (kp + kd s) e^{-s tau}``; on ``s = i Omega``

    kp(Omega) = m Omega^2 cos(Omega tau),   kd(Omega) = m Omega sin(Omega tau),

plus the static line ``kp = 0`` (G. Stepan, *Retarded Dynamical Systems*, 1989; Insperger &
Stepan, *Semi-Discretization for Time-Delay Systems*, 2011, ch. 1: the stable region is the
curved triangle bounded by ``kp = 0`` and the first D-curve branch ``0 < Omega tau < pi/2``; a
delayed P controller (``kd = 0``) never stabilises the mass).

Charts: (a) ``kp x kd`` at ``tau = 1 s``; (b) ``kp x tau`` at ``kd = 0.5 N s/m``.
References: the closed-form D-curves above, the characteristic equation at every D-curve point
of chart (b), and Chebyshev collocation of ``x'' = -(kp x + kd x')(t - tau)`` on a sub-grid; two
points across the boundary of chart (b) are simulated (DT-TMM with the delayed loop).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Free, Mass
from ctmm.stability import crosscheck_by_simulation, delay_margin, stability_chart
from ctmm.scenario import accuracy

from .delay_common import DCURVE_BOUND_SOURCE, boundary_points, compare_classification, pd_first_order

NAME = "delay_pd_single_mass"
DESCRIPTION = ("Delayed PD on a single mass: kp x kd and kp x tau stability charts from the TMM against "
               "Stepan's closed-form D-curves, collocation and simulation")
MASS, TAU, KD = 1.0, 1.0, 0.5


def system(kp: float = 0.2, kd: float = KD, tau: float = TAU) -> ControlledChain:
    plant = ctmm.Chain("single_mass", [Free("left"), Mass("m", MASS), Free("right")])
    return ControlledChain(plant, [Feedback("pd", [("m.x", kp), ("m.v", kd)], "m", gain=1.0, delay=tau)])


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = 40 if quick else 100
    kp, kd, taus = np.linspace(-0.25, 1.25, n), np.linspace(-0.25, 1.75, n), np.linspace(0.0, 3.0, n)
    started = time.perf_counter()
    chart_a = stability_chart(system(), x=("m.x", kp, "k_p [N/m]"), y=("m.v", kd, "k_d [N s/m]"))
    chart_b = stability_chart(system(), x=("m.x", kp, "k_p [N/m]"), y=("delay", taus, "tau [s]"))
    wall = time.perf_counter() - started

    # references: closed-form D-curves (a), characteristic equation at D-curve points (b)
    ref_started = time.perf_counter()
    x, y, w = boundary_points(chart_a)
    exact_kp, exact_kd = MASS * w ** 2 * np.cos(w * TAU), MASS * w * np.sin(w * TAU)
    error_a = float(max(np.max(np.abs(x - exact_kp) / np.maximum(1, np.abs(exact_kp))),
                        np.max(np.abs(y - exact_kd) / np.maximum(1, np.abs(exact_kd)))))
    xs, _, _ = boundary_points(chart_a, "static")
    error_static = float(np.max(np.abs(xs))) if xs.size else 0.0
    x, t, w = boundary_points(chart_b)
    s = 1j * w
    residual = np.abs(MASS * s ** 2 + (x + KD * s) * np.exp(-s * t)) / (MASS * w ** 2 + np.abs(x) + KD * w)
    error_b = float(residual.max())
    stride = 8 if quick else 10
    classes_a = compare_classification(chart_a, lambda p, d: pd_first_order(MASS, 0.0, 0.0, p, d, TAU),
                                       stride=stride)
    classes_b = compare_classification(chart_b, lambda p, tau: pd_first_order(MASS, 0.0, 0.0, p, KD, tau),
                                       stride=stride)
    ref_wall = time.perf_counter() - ref_started

    # Stepan: the delayed P controller (kd = 0) never stabilises; the margin of kp = 0.2, kd = 0.5
    row_kd0 = chart_a.unstable_roots[np.argmin(np.abs(kd)), :]
    margin = delay_margin(system(kp=0.2, kd=KD, tau=0.0))
    t_final, dt = (30.0, 0.02) if quick else (60.0, 0.01)
    check = crosscheck_by_simulation(system(kp=0.2), [{"delay": 0.9 * margin.critical_delay},
                                                      {"delay": 1.1 * margin.critical_delay}],
                                     t_final=t_final, dt=dt)

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
    chart_a.plot(ax=axes[0])
    axes[0].set_title(f"(a) tau = {TAU} s: D-curves kp = m W^2 cos(W tau), kd = m W sin(W tau)", fontsize=9)
    chart_b.plot(ax=axes[1])
    axes[1].plot([0.2, 0.2], [0.9 * margin.critical_delay, 1.1 * margin.critical_delay], "o",
                 color="tab:red", ms=4, label="simulated points")
    axes[1].legend(fontsize=8, loc="upper right")
    axes[1].set_title(f"(b) kd = {KD} N s/m; delay margin of kp = 0.2: {margin.critical_delay:.4f} s",
                      fontsize=9)
    fig.tight_layout()
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / f"{NAME}.png", dpi=100)
    plt.close(fig)
    return {
        "accuracy": [accuracy(
            "D-curve error vs closed form", max(error_a, error_b, error_static), "relative", 1e-9,
            "max of (a) relative deviation of the TMM D-curve points from kp = m W^2 cos(W tau), "
            "kd = m W sin(W tau) and of the static line from kp = 0, (b) |m s^2 + (kp + kd s) e^{-s tau}| / "
            "(m W^2 + |kp| + kd W) at the D-curve points s = i W", source=DCURVE_BOUND_SOURCE)],
        "dcurve_error_kp_kd": error_a, "dcurve_residual_kp_tau": error_b,
        "classification_vs_collocation": {"kp_kd": classes_a, "kp_tau": classes_b},
        "delayed_P_never_stable": bool(np.all(row_kd0 != 0)),
        "delay_margin_kp0.2_kd0.5": margin.as_dict(),
        "simulation_check": check.as_dict(),
        "charts": {"kp_kd": chart_a.summary(), "kp_tau": chart_b.summary()},
        "parameters": {"mass_kg": MASS, "tau_chart_a_s": TAU, "kd_chart_b_Ns_per_m": KD, "grid": n},
        "wall_time_s": wall,
        "reference_wall_time_s": ref_wall,
        "figures": [f"{NAME}.png"],
    }
