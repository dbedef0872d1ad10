"""Seed 001 Figs. 9.30-9.31: the loop m6 -> an actuator across the spring-damper K3,C3.

Model (parameters in :mod:`controlled_chain_common`, our choice -- the seed's were lost):
``ground -[K1,C1]- m2 -[K3,C3]- m4 -[K5,C5]- m6``, sensor on m6, control force ``u = -Ka x6``
acting *across* ``K3,C3`` (``+u`` on m4, ``-u`` on m2), i.e. in parallel with the connector: its
transfer matrix gets ``x_out = x_in + (u - f)/(K3 + i w C3)``.

* Fig. 9.31: steady-state motion of m2, m4, m6 under ``F6 = 1 N sin(2 t)`` from the TMM phasors
  ("TMM for linear controlled multibody system") against the global closed-loop equations
  integrated from the steady-state orbit ("multibody system dynamics method"), Ka = 5 N/m.
* FRFs ``X2, X4, X6`` per unit force on m6 for Ka = 0 and 5 N/m (as Fig. 9.29, for this loop).

References: ``delay_chain.closed_loop_frequency_response`` with ``b = e_m4 - e_m2`` and
``delay_chain.method_of_steps`` (DOP853, rtol 1e-11).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import controlled_chain_common as common

NAME = "controlled_chain_across"
DESCRIPTION = ("Seed Figs. 9.30-9.31: loop m6 -> actuator across K3,C3; steady state and FRFs by the "
               "extended-state TMM against global closed-loop solves")


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    output_dir = Path(output_dir)
    comparison = common.compare_placement("K3", quick)
    t, frf, steady = comparison["t"], comparison["frf"], comparison["steady"]
    tmm_time, ref_time, loop_margins = comparison["tmm_time"], comparison["reference_time"], comparison["margins"]

    figures = []
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7.5, 7.5))
    step = max(1, t.size // 50)
    for k, ax in enumerate(axes):
        ax.plot(t[::step], steady[common.KA]["reference"][::step, k], "x", ms=5,
                label="multibody system dynamics (global ODE)")
        ax.plot(t, steady[common.KA]["tmm"][:, k], "--", label="TMM for linear controlled MBS, Ka = 5")
        ax.plot(t, steady[0.0]["tmm"][:, k], ":", color="0.5", label="uncontrolled, Ka = 0")
    common.style_axes(axes)
    axes[0].set_title(f"Fig. 9.31: loop m6 -> across K3,C3, F6 = {common.FORCE_AMPLITUDE:g} N "
                      f"sin({common.FORCE_FREQUENCY:g} t)")
    axes[-1].set_xlabel("t [s]")
    fig.tight_layout()
    name = f"{NAME}_fig9_31.png"
    fig.savefig(output_dir / name, dpi=110)
    plt.close(fig)
    figures.append(name)

    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7.5, 7))
    common.plot_frf_pair(axes, frf, "loop m6 -> across K3,C3")
    fig.tight_layout()
    name = f"{NAME}_frf.png"
    fig.savefig(output_dir / name, dpi=110)
    plt.close(fig)
    figures.append(name)

    return {
        "accuracy": common.frf_and_steady_accuracy(
            max(r["error"] for r in frf.values()),
            "over Ka = 0, 5 (H_ref: dense closed-loop solve, actuator b = e_m4 - e_m2)",
            max(r["error"] for r in steady.values()), "the global closed-loop ODE (DOP853, rtol 1e-11)"),
        "frf_relative_error": {f"Ka={g:g}": r["error"] for g, r in frf.items()},
        "steady_state_error_m": {f"Ka={g:g}": r["error"] for g, r in steady.items()},
        "steady_state_amplitude_m": {f"Ka={g:g}": np.abs(r["phasors"]).tolist() for g, r in steady.items()},
        "wall_time_s": tmm_time,
        "reference_wall_time_s": ref_time,
        "loop_margins_Ka5": loop_margins.as_dict(),
        "parameters": common.PARAMETERS,
        "figures": figures,
    }
