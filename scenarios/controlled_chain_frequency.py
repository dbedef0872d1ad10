"""Seed 001 Figs. 9.27-9.29: three-mass chain with the loop m6 -> m2, frequency domain.

Model (parameters in :mod:`controlled_chain_common`, our choice -- the seed's were lost):
``ground -[K1,C1]- m2 -[K3,C3]- m4 -[K5,C5]- m6``, sensor on m6, control force
``u = -Ka x6`` on m2, excitation ``F6 sin(Omega t)`` on m6.

* Fig. 9.29: FRFs ``X2, X4, X6`` per unit force on m6 for ``Ka = 0`` and ``Ka = 5.0`` N/m by the
  extended-state TMM (:class:`~ctmm.control.ControlledChain`).  Qualitative behaviour as in the
  book: the loop shifts the resonances (first one 1.41 -> 1.84 rad/s) and reshapes the peaks.
* Fig. 9.28: steady-state motion ``x = Im(X e^{i Omega t})`` under ``F6 = 1 N sin(2 t)`` from
  the TMM phasors, against a time integration of the global closed-loop equations started on the
  steady-state orbit ("multibody system dynamics method"), and the uncontrolled motion.

References: ``delay_chain.closed_loop_frequency_response`` (dense solves of
``-w^2 M + i w C + K + Ka e_m2 e_m6^T``) and ``delay_chain.method_of_steps`` (DOP853, rtol 1e-11).
Also reported: the loop's gain/phase/delay margins (``ctmm.control.analysis.margins``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import controlled_chain_common as common

NAME = "controlled_chain_frequency"
DESCRIPTION = ("Seed Figs. 9.27-9.29: loop m6 -> m2, closed-loop FRFs for Ka = 0 and 5 and steady-state "
               "motion by the extended-state TMM against global closed-loop solves")


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    output_dir = Path(output_dir)
    comparison = common.compare_placement("m2", quick)
    omega, t, frf, steady = comparison["omega"], comparison["t"], comparison["frf"], comparison["steady"]
    tmm_time, ref_time, loop_margins = comparison["tmm_time"], comparison["reference_time"], comparison["margins"]

    # -- figures ------------------------------------------------------------------------
    figures = []
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7.5, 7))
    common.plot_frf_pair(axes, frf, "Fig. 9.29: frequency response, loop m6 -> m2")
    fig.tight_layout()
    name = f"{NAME}_fig9_29.png"
    fig.savefig(output_dir / name, dpi=110)
    plt.close(fig)
    figures.append(name)

    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7.5, 7.5))
    step = max(1, t.size // 50)
    for k, ax in enumerate(axes):
        ax.plot(t, steady[common.KA]["reference"][:, k], "k-", lw=1.0, label="multibody dynamics (global ODE)")
        ax.plot(t[::step], steady[common.KA]["tmm"][::step, k], "D", ms=4, mfc="none", label="TMM, Ka = 5")
        ax.plot(t[::step], steady[0.0]["tmm"][::step, k], "x", ms=5, label="uncontrolled, Ka = 0")
    common.style_axes(axes)
    axes[0].set_title(f"Fig. 9.28: steady state under F6 = {common.FORCE_AMPLITUDE:g} N "
                      f"sin({common.FORCE_FREQUENCY:g} t), loop m6 -> m2")
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    name = f"{NAME}_fig9_28.png"
    fig.savefig(output_dir / name, dpi=110)
    plt.close(fig)
    figures.append(name)

    peaks = {f"Ka={gain:g}": {
        "first_resonance_rad_s": float(omega[np.argmax(np.abs(frf[gain]["tmm"][2]))]),
        "peak_X6_m_per_N": float(np.max(np.abs(frf[gain]["tmm"][2])))} for gain in frf}
    return {
        "accuracy": common.frf_and_steady_accuracy(
            max(r["error"] for r in frf.values()), "over Ka = 0, 5 (H_ref: dense closed-loop solve)",
            max(r["error"] for r in steady.values()), "the global closed-loop ODE (DOP853, rtol 1e-11)"),
        "frf_relative_error": {f"Ka={g:g}": r["error"] for g, r in frf.items()},
        "steady_state_error_m": {f"Ka={g:g}": r["error"] for g, r in steady.items()},
        "wall_time_s": tmm_time,
        "reference_wall_time_s": ref_time,
        "n_omega": int(omega.size),
        "resonances": peaks,
        "loop_margins_Ka5": loop_margins.as_dict(),
        "parameters": common.PARAMETERS,
        "figures": figures,
    }
