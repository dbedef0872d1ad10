"""Delay stability of the hub PD on the flexible arm: chart Kd x tau (issue 7, flexible case).

The manipulator scene of ``scenarios/flexible_manipulator.py`` (seed 001 Fig. 9.42: hub of
inertia J_h on a pivot, aluminium arm; ``ctmm.manipulator.manipulator_plant``) on its exact
Euler-Bernoulli fields (``ctmm.exact_fields.exact_form``: the plant about its rest pose as a bending
chain, with its port map; PZT loops open) with a
delayed PD hub torque ``tau_m(t) = -(kp theta + kd theta_dot)(t - tau)``, ``kp`` fixed at the seed
value.  The chart over (kd, tau) comes from the TMM characteristic function with the exact factor
``e^{-s tau}`` (D-subdivision + root counting, ``ctmm.stability_chart``); the delay margin at the
seed gains from ``ctmm.stability.delay_margin``.

Independent reference: the assumed-modes Lagrange model of the same hub + arm
(``ctmm.reference.manipulator_lagrange``, clamped-free modes, no TMM code), its delay equations
solved for the rightmost roots by Chebyshev collocation of the infinitesimal generator
(``ctmm.reference.dde``), and the critical delay found by bisection on the spectral abscissa.
It converges to the TMM value with the number of modes (3 modes: 4e-9 s, 10 modes: 4e-12 s).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ctmm.scenario import accuracy

NAME = "delay_hub_beam_chart"
DESCRIPTION = ("Hub PD on the flexible arm with delay: stability chart kd x tau from the TMM with exact "
               "delays; delay margin vs collocation of the assumed-modes Lagrange delay equations")


def _reference_critical_delay(manipulator, kp: float, kd: float, n_modes: int, n_nodes: int,
                              iterations: int) -> float:
    from ctmm.reference.dde import chebyshev_collocation_roots, second_order_system
    from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

    lin = ManipulatorLagrange.from_manipulator(manipulator, n_modes).linearize()
    torque = np.outer(lin["B_torque"], lin["B_torque"])

    def abscissa(tau: float) -> float:
        A0, delayed = second_order_system(lin["M"], lin["D"], lin["K"], [(kp * torque, kd * torque, tau)])
        roots = chebyshev_collocation_roots(A0, delayed, n_nodes)
        return float(roots[np.abs(roots) < 2000.0].real.max())   # spurious large-modulus roots dropped

    low, high = 1e-4, 0.2
    if not (abscissa(low) < 0.0 < abscissa(high)):
        raise RuntimeError("reference bracket for the critical delay failed")
    for _ in range(iterations):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if abscissa(mid) < 0.0 else (low, mid)
    return 0.5 * (low + high)


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib.pyplot as plt

    from ctmm.control import ControlledChain, Feedback
    from ctmm.exact_fields import exact_form
    from ctmm.manipulator import manipulator_plant
    from ctmm.manipulator.parameters import SEED_KD, SEED_KP, seed_manipulator
    from ctmm.stability import delay_margin, stability_chart

    manipulator = seed_manipulator()
    form = exact_form(manipulator_plant(manipulator))     # the scene's plant on its exact beam fields
    (angle, unit_angle), = form.sensor("motor.angle")
    (rate, unit_rate), = form.sensor("motor.rate")
    if unit_rate != 1.0:                                   # the chart's x is the weight of this term: kd itself
        raise RuntimeError(f"the hinge rate maps to {unit_rate!r} x {rate!r}, expected a unit weight")
    pd = Feedback("pd", [(angle, SEED_KP * unit_angle), (rate, SEED_KD)], form.actuator("motor.torque"),
                  gain=1.0, delay=0.01)
    system = ControlledChain(form.chain, [pd])
    n = 16 if quick else 60
    start = time.perf_counter()
    margin = delay_margin(system, "pd")
    chart = stability_chart(system, x=(rate, np.linspace(1.0, 80.0, n), "kd [N m s/rad]"),
                            y=("delay", np.linspace(0.0, 0.08, n), "delay [s]"), loop="pd", im_max=400.0)
    wall = time.perf_counter() - start
    start = time.perf_counter()
    reference = _reference_critical_delay(manipulator, SEED_KP, SEED_KD, n_modes=3 if quick else 10,
                                          n_nodes=30 if quick else 40, iterations=22 if quick else 34)
    reference_wall = time.perf_counter() - start
    error = abs(margin.critical_delay - reference)
    ax = chart.plot()
    ax.plot([SEED_KD], [margin.critical_delay], "r*", ms=12, label=f"seed kd: delay margin {margin.critical_delay:.5f} s")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"Hub PD on the flexible arm (kp = {SEED_KP:g} N m/rad): stable region shaded")
    png = Path(output_dir) / "delay_hub_beam_chart.png"
    ax.figure.savefig(png, dpi=120)
    plt.close(ax.figure)
    return {"accuracy": [accuracy(
                "critical delay error vs Lagrange delay equations", error, "s", 1e-7 if quick else 1e-9,
                "|critical delay (TMM, exact e^{-s tau}) - critical delay (collocation of the assumed-modes "
                "Lagrange delay equations, bisection)|; the reference converges with its number of modes "
                "(3 quick, 10 full)",
                source="reference convergence in this module's docstring (3 modes: 4e-9 s, 10 modes: 4e-12 s)")],
            "wall_time_s": wall, "reference_wall_time_s": reference_wall,
            "critical_delay_tmm_s": margin.critical_delay, "critical_delay_reference_s": reference,
            "reference_modes": 3 if quick else 10, "kp": SEED_KP, "kd": SEED_KD,
            "stable_fraction_of_chart": float(np.mean(chart.stable)), "chart_points": n * n,
            "figures": [png.name]}
