"""Delayed PD oscillator (FORMULAS 6.2): D-curves, rightmost roots, delay margin, spectral abscissa.

Model: a unit mass on a spring-damper (``omega_n = 1 rad/s``, ``zeta = 0.1``) with
``u(t) = -(kp x + kd x')(t - tau)``, i.e. ``x'' + 2 zeta omega_n x' + omega_n^2 x = -kp x(t - tau)
- kd x'(t - tau)`` -- the TMM chain ``[Fixed, SpringDamper, Mass, Free]`` with one Feedback.

* chart ``kp x kd`` at ``tau = 0.5 s`` (and its spectral abscissa map) against the closed-form
  D-curves ``kp(Omega) = (Omega^2 - omega_n^2) cos(Omega tau) + 2 zeta omega_n Omega sin(Omega
  tau)``, ``kd(Omega) = [(Omega^2 - omega_n^2) sin(Omega tau) - 2 zeta omega_n Omega cos(Omega
  tau)] / Omega`` and the static line ``kp = -omega_n^2`` (``ctmm.reference.dde``);
* chart ``kp x tau`` at ``kd = 0.4``: every D-curve point must solve the characteristic equation;
* rightmost roots at three points against Chebyshev collocation (Breda-Maset-Vermiglio) with
  Newton refinement;
* delay margin of ``kp = 0.5, kd = 0.4`` against its closed form: ``|L0(i Omega)| = 1`` is the
  quadratic ``W^2 + (4 zeta^2 omega_n^2 - 2 omega_n^2 - kd^2) W + omega_n^4 - kp^2 = 0`` in
  ``W = Omega^2``, then ``tau = (-arg(-1/L0)) mod 2 pi / Omega``.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.reference.dde import delayed_pd_oscillator_characteristic_function, delayed_pd_oscillator_dcurves
from ctmm.stability import characteristic_roots, delay_margin, stability_chart
from ctmm.scenario import accuracy

from .delay_common import (DCURVE_BOUND_SOURCE, boundary_points, collocation_roots,
                           compare_classification, pd_first_order)

NAME = "delay_oscillator"
DESCRIPTION = ("Delayed PD oscillator (FORMULAS 6.2): TMM D-curves and charts against the closed forms, "
               "rightmost roots against collocation, exact delay margin, spectral abscissa map")
OMEGA_N, ZETA, TAU, KD = 1.0, 0.1, 0.5, 0.4


def system(kp: float = 0.5, kd: float = KD, tau: float = TAU) -> ControlledChain:
    plant = ctmm.Chain("oscillator", [Fixed("wall"), SpringDamper("k", OMEGA_N ** 2, 2 * ZETA * OMEGA_N),
                                      Mass("m", 1.0), Free("end")])
    return ControlledChain(plant, [Feedback("pd", [("m.x", kp), ("m.v", kd)], "m", gain=1.0, delay=tau)])


def analytic_delay_margin(kp: float, kd: float) -> tuple[float, float]:
    """Smallest crossing delay and its frequency of the oscillator, in closed form."""
    b = 4 * ZETA ** 2 * OMEGA_N ** 2 - 2 * OMEGA_N ** 2 - kd ** 2
    c = OMEGA_N ** 4 - kp ** 2
    best = (math.inf, math.nan)
    for W in np.roots([1.0, b, c]):
        if abs(W.imag) > 1e-12 or W.real <= 0:
            continue
        omega = math.sqrt(W.real)
        s = 1j * omega
        L0 = (kp + kd * s) / (s * s + 2 * ZETA * OMEGA_N * s + OMEGA_N ** 2)
        tau = (-np.angle(-1.0 / L0)) % (2 * math.pi) / omega
        best = min(best, (tau, omega))
    return best


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = 40 if quick else 100
    kp, kd, taus = np.linspace(-2.0, 4.0, n), np.linspace(-1.0, 3.0, n), np.linspace(0.0, 6.0, n)
    levels = np.linspace(-0.8, 0.4, 13 if quick else 25)
    started = time.perf_counter()
    chart_a = stability_chart(system(), x=("m.x", kp, "k_p [1/s^2]"), y=("m.v", kd, "k_d [1/s]"))
    chart_b = stability_chart(system(), x=("m.x", kp, "k_p [1/s^2]"), y=("delay", taus, "tau [s]"))
    wall = time.perf_counter() - started
    m = 20 if quick else 40
    chart_c = stability_chart(system(), x=("m.x", np.linspace(-2.0, 4.0, m), "k_p [1/s^2]"),
                              y=("m.v", np.linspace(-1.0, 3.0, m), "k_d [1/s]"), abscissa_levels=levels)

    ref_started = time.perf_counter()
    x, y, w = boundary_points(chart_a)
    exact = delayed_pd_oscillator_dcurves(OMEGA_N, ZETA, TAU, w)
    error_a = float(max(np.max(np.abs(x - exact.proportional_gain) / np.maximum(1, np.abs(x))),
                        np.max(np.abs(y - exact.derivative_gain) / np.maximum(1, np.abs(y)))))
    xs, _, _ = boundary_points(chart_a, "static")
    error_static = float(np.max(np.abs(xs + OMEGA_N ** 2))) if xs.size else 0.0
    x, t, w = boundary_points(chart_b)
    residual = [abs(delayed_pd_oscillator_characteristic_function(OMEGA_N, ZETA, ti, xi, KD)(np.array([1j * wi]))[0])
                / (wi ** 2 + 2 * ZETA * OMEGA_N * wi + OMEGA_N ** 2 + abs(xi) + KD * wi)
                for xi, ti, wi in zip(x, t, w)]
    error_b = float(max(residual))
    stride = 8 if quick else 10
    classes = compare_classification(chart_a, lambda p, d: pd_first_order(1.0, OMEGA_N ** 2, 2 * ZETA * OMEGA_N,
                                                                         p, d, TAU), stride=stride)
    root_errors = {}
    for p, d in ((0.5, 0.4), (2.0, 0.3), (-0.5, 1.5)):
        reference = collocation_roots(*pd_first_order(1.0, OMEGA_N ** 2, 2 * ZETA * OMEGA_N, p, d, TAU), nodes=40)
        reference = reference[(reference.real > -2.0) & (np.abs(reference.imag) < 30)]
        found = characteristic_roots(system(p, d), re_min=-2.0, im_max=30.0)
        root_errors[f"kp={p},kd={d}"] = float(max(np.min(np.abs(found.roots - z)) for z in reference))
    exact_tau, exact_omega = analytic_delay_margin(0.5, KD)
    ref_wall = time.perf_counter() - ref_started
    margin = delay_margin(system(0.5, KD, 0.0))
    margin_error = abs(margin.critical_delay - exact_tau)

    fig, axes = plt.subplots(1, 3, figsize=(17, 4.6))
    chart_a.plot(ax=axes[0])
    axes[0].set_title(f"(a) tau = {TAU} s, omega_n = {OMEGA_N}, zeta = {ZETA}", fontsize=9)
    chart_b.plot(ax=axes[1])
    axes[1].axhline(margin.critical_delay, color="tab:red", lw=0.8, ls=":")
    axes[1].set_title(f"(b) k_d = {KD}; delay margin of k_p = 0.5: {margin.critical_delay:.5f} s", fontsize=9)
    chart_c.plot(ax=axes[2], abscissa=True)
    axes[2].set_title("(c) spectral abscissa (level counts)", fontsize=9)
    fig.tight_layout()
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / f"{NAME}.png", dpi=100)
    plt.close(fig)
    return {
        "accuracy": [
            accuracy("D-curve error vs closed form", max(error_a, error_static, error_b), "relative", 1e-9,
                     "max of the relative deviation of the TMM D-curve points of the kp x kd chart from the closed "
                     "form (FORMULAS 6.2), of the static line from -omega_n^2, and the scaled |Delta(i W)| of the "
                     "independent characteristic function at the kp x tau D-curve points",
                     source=DCURVE_BOUND_SOURCE),
            accuracy("rightmost-root error vs collocation", max(root_errors.values()), "1/s", 1e-8,
                     "|root_TMM - root_collocation| of the rightmost roots at three points (roots of magnitude ~1)",
                     source="docs/stability.md: roots vs collocation <= 1e-8 relative"),
            accuracy("delay margin error vs closed form", margin_error, "s", 1e-9,
                     "|delay margin - closed form|",
                     source=DCURVE_BOUND_SOURCE)],
        "dcurve_error_kp_kd": error_a, "static_line_error": error_static, "dcurve_residual_kp_tau": error_b,
        "rightmost_root_errors": root_errors, "delay_margin": margin.as_dict(),
        "delay_margin_closed_form": {"tau_s": exact_tau, "omega_rad_s": exact_omega, "error_s": margin_error},
        "classification_vs_collocation": classes,
        "charts": {"kp_kd": chart_a.summary(), "kp_tau": chart_b.summary(),
                   "abscissa_map": chart_c.summary()},
        "parameters": {"omega_n_rad_s": OMEGA_N, "zeta": ZETA, "tau_s": TAU, "kd_chart_b": KD, "grid": n},
        "wall_time_s": wall,
        "reference_wall_time_s": ref_wall,
        "figures": [f"{NAME}.png"],
    }
