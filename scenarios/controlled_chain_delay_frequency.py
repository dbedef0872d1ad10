"""Seed 001 Fig. 9.36: the loop m6 -> m2 with a time delay, in the frequency domain.

Model (parameters in :mod:`controlled_chain_common`, our choice -- the seed's were lost): the
chain of Fig. 9.27 with ``u(t) = -Ka x6(t - tau)`` on m2, Ka = 5 N/m, tau = 0.05 s.  The
delay enters the actuator's transfer matrix exactly as ``Ka e^{-i w tau}`` (seed eqs. 9.41-9.47,
FORMULAS §5.2): no Pade approximation, no extra states.

* Fig. 9.36: steady-state motion of m2, m4, m6 under ``F6 = 1 N sin(2 t)`` from the TMM phasors
  against the delay differential equations of the global model integrated by the method of
  steps from the steady-state orbit (its history before t = 0 on the orbit as well): they must
  stay on it ("Newton-Euler method" of the figure).
* FRFs of ``X6`` for tau = 0, 0.05, 0.1, 0.2 s and the Nyquist curves of the loop transfer
  function ``L = Ka e^{-i w tau} P_x6,u`` with the delay margin (0.108 s): below it the closed
  loop is stable (no encirclement of -1), at 0.2 s it is not (FRF of an unstable loop is not a
  steady state; it is drawn dotted).

References: ``delay_chain.closed_loop_frequency_response`` (``Ka e^{-i w tau}`` in the dense
dynamic stiffness) and ``delay_chain.method_of_steps`` (DOP853, rtol 1e-11).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ctmm.control import loop_transfer_function, margins
from ctmm.control import encirclements

from . import controlled_chain_common as common

NAME = "controlled_chain_delay_frequency"
DESCRIPTION = ("Seed Fig. 9.36: loop m6 -> m2 with time delay; exact e^(-i w tau) in the TMM against the "
               "global delay equations (steady state by the method of steps), Nyquist and delay margin")

DELAYS = (0.0, common.DELAY, 0.1, 0.2)


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    output_dir = Path(output_dir)
    omega = np.linspace(0.02, 6.0, 600 if quick else 3000)
    t = np.linspace(0.0, 10.0, 201 if quick else 1001)
    frf = {tau: common.frf_comparison("m2", common.KA, tau, omega) for tau in DELAYS}
    steady = common.steady_state_comparison("m2", common.KA, common.DELAY, t)
    undelayed = common.FORCE_AMPLITUDE * common.frf_comparison(
        "m2", common.KA, 0.0, np.array([common.FORCE_FREQUENCY]))["tmm"][:, 0]
    w_nyquist = np.linspace(0.0, 30.0, 3000 if quick else 12000)
    stability, nyquist = {}, {}
    for tau in DELAYS:
        system, _ = common.controlled("m2", common.KA, tau)
        L = loop_transfer_function(system, "control", w_nyquist)
        nyquist[tau] = L
        stability[tau] = encirclements(L) == 0      # damped chain: no open-loop RHP poles
    system, _ = common.controlled("m2", common.KA, 0.0)
    loop_margins = margins(system, "control", np.linspace(0.02, 20.0, 2000 if quick else 8000))
    tmm_time = steady["tmm_time"] + sum(r["tmm_time"] for r in frf.values())
    ref_time = steady["reference_time"] + sum(r["reference_time"] for r in frf.values())

    figures = []
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7.5, 7.5))
    step = max(1, t.size // 50)
    for k, ax in enumerate(axes):
        ax.plot(t[::step], steady["reference"][::step, k], "x", ms=5, label="delay equations (method of steps)")
        ax.plot(t, steady["tmm"][:, k], "--", label=f"TMM, Ka = 5, tau = {common.DELAY:g} s")
        ax.plot(t, np.imag(undelayed[k] * np.exp(1j * common.FORCE_FREQUENCY * t)), ":",
                color="0.5", label="TMM, no delay")
    common.style_axes(axes)
    axes[0].set_title(f"Fig. 9.36: delayed loop m6 -> m2, F6 = {common.FORCE_AMPLITUDE:g} N "
                      f"sin({common.FORCE_FREQUENCY:g} t)")
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    name = f"{NAME}_fig9_36.png"
    fig.savefig(output_dir / name, dpi=110)
    plt.close(fig)
    figures.append(name)

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 5))
    for tau in DELAYS:
        ls = "-" if stability[tau] else ":"
        line = common.plot_magnitude(ax1, frf[tau], "m6", f"tau = {tau:g} s "
                                     f"({'stable' if stability[tau] else 'unstable'})", ls, markers=60,
                                     reference_label="global closed-loop solve" if tau == DELAYS[0] else None)
        L = nyquist[tau]("control.L")
        ax2.plot(L.real, L.imag, ls, color=line.get_color(), label=f"tau = {tau:g} s")
        ax2.plot(L.real, -L.imag, ls, color=line.get_color(), lw=0.5)
    ax1.set_title("X6 per unit force on m6", fontsize=9)
    ax2.plot([-1], [0], "r+", ms=14, mew=2)
    ax2.set_xlim(-3, 1.5)
    ax2.set_ylim(-2.5, 2.5)
    ax2.set_aspect("equal")
    ax2.grid(True, alpha=0.3)
    ax2.set_xlabel("Re L")
    ax2.set_ylabel("Im L")
    ax2.set_title(f"Nyquist of L = Ka e^(-i w tau) P; delay margin {loop_margins.delay_margin:.4f} s")
    ax2.legend(fontsize=8)
    fig.tight_layout()
    name = f"{NAME}_delays.png"
    fig.savefig(output_dir / name, dpi=110)
    plt.close(fig)
    figures.append(name)

    stable_frf_errors = {f"tau={tau:g}": r["error"] for tau, r in frf.items()}
    return {
        "accuracy": common.frf_and_steady_accuracy(
            max(stable_frf_errors.values()),
            "for tau = 0, 0.05, 0.1, 0.2 s (H_ref: dense solve with Ka e^(-i w tau))", steady["error"],
            "the global delay equations with tau = 0.05 s (method of steps, DOP853 rtol 1e-11)"),
        "steady_state_error_m": steady["error"],
        "frf_relative_error": stable_frf_errors,
        "closed_loop_stable": {f"tau={tau:g}": bool(v) for tau, v in stability.items()},
        "delay_margin_s": loop_margins.delay_margin,
        "loop_margins_tau0": loop_margins.as_dict(),
        "steady_state_amplitude_m": np.abs(steady["phasors"]).tolist(),
        "wall_time_s": tmm_time,
        "reference_wall_time_s": ref_time,
        "parameters": common.PARAMETERS,
        "figures": figures,
    }
