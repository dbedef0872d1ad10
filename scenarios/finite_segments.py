"""Finite-segment beam (seed 001 section 9.4, Figs. 9.19-9.25): convergence and cost.

Cantilever L = 1 m, EI = 2 N m^2, rhoA = 0.5 kg/m cut into N rigid segments joined by torsional
springs EI/l (root 2EI/l, FORMULAS 3.7).  (1) First three natural frequencies (linear planar
sweep, ``ctmm.natural_frequencies``) against the exact clamped-free
beta L values for N = 5..80, with the 2EI/l and the EI/l root spring: orders 2 and 1.  The
verb ``ctmm.natural_frequencies`` counts them by Wittrick-Williams on the articulated sweep
(converged to round-off; a dense eigensolver would lose ~3e-5 on the lowest mode at N = 80 and
spoil the observed order).
(2) Time domain: tip response to a suddenly applied tip force (0.05 N, 2 s) of the segment
chains against the modal beam (6 clamped-free modes), both by the implicit DT-TMM (Newmark,
h = 1 ms: the short segments' highest frequencies, ~(2N)^2 omega_1 / 3.5, would force tiny
explicit steps).
(3) Cost of one O(n) acceleration sweep and of a 0.2 s RK4 run against N (Fig. 9.25: linear).
"""
from __future__ import annotations

import math
import timeit
from pathlib import Path

import numpy as np

import ctmm
from ctmm.flexible import ModalBeam
from ctmm.flexible.outputs import tip_deflection
from ctmm.flexible.segments import finite_segment_beam
from ctmm.planar import Fixed, Load, PlanarModel, RigidBody, accelerations
from ctmm.reference.beams import beta_roots
from ctmm.scenario import accuracy
from ctmm.signal_results import coordinate_histories

NAME = "finite_segments"
DESCRIPTION = ("Finite-segment beam: frequency convergence O(1/N^2) with the 2EI/l root spring "
               "(O(1/N) with EI/l), tip response vs the modal beam, cost linear in N")
BEAM = dict(length=1.0, bending_stiffness=2.0, mass_per_length=0.5)
FORCE = 0.05


def segment_model(n: int, factor: float = 2.0, load: bool = False) -> PlanarModel:
    parts = finite_segment_beam("s", n_segments=n, root_spring_factor=factor, **BEAM)
    if load:
        last = parts[-1]
        parts[-1] = RigidBody(last.name, mass=last.mass, inertia=last.inertia,
                              center_of_mass=last.center_of_mass, outboard=last.outboard["out"],
                              loads=(Load(point=last.outboard["out"], force_y=FORCE),))
    return PlanarModel.chain("fs", [Fixed("ground")] + parts, gravity=(0.0, 0.0))


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    exact = beta_roots("clamped-free", 3) ** 2 * math.sqrt(BEAM["bending_stiffness"]
                                                          / BEAM["mass_per_length"])
    counts = (5, 10, 20) if quick else (5, 10, 20, 40, 80)
    errors = {2.0: [], 1.0: []}
    for factor in errors:
        for n in counts:
            w = ctmm.natural_frequencies(segment_model(n, factor), n_modes=3)
            errors[factor].append(w / exact - 1)
    e2, e1 = np.array(errors[2.0]), np.array(errors[1.0])
    order2 = np.log2(e2[-2] / e2[-1])
    order1 = np.log2(e1[-2] / e1[-1])
    # time domain: tip force on the cantilever
    t_final = 0.3 if quick else 2.0
    beam = ModalBeam("beam", n_modes=6, loads=(Load(point=(1.0, 0.0), force_y=FORCE),), **BEAM)
    modal = PlanarModel.chain("modal", [Fixed("ground"), beam], gravity=(0.0, 0.0))
    msim = ctmm.simulate(modal, t_final, 1e-3, method="newmark", store_every=10)
    y_modal = tip_deflection(modal, coordinate_histories(msim)[0], "beam")
    tip_err, tips = {}, {}
    l_counts = (5, 10) if quick else (5, 10, 20, 40)
    for n in l_counts:
        fs = segment_model(n, load=True)
        sim = ctmm.simulate(fs, t_final, 1e-3, method="newmark", store_every=10)
        l = BEAM["length"] / n
        y = np.sum(l * np.sin(coordinate_histories(sim)[0]), axis=1)
        tips[n] = y
        tip_err[n] = float(np.max(np.abs(y - y_modal)))
    # cost against N
    cost = {}
    for n in (10, 40, 160) if quick else (10, 40, 160, 640):
        fs = segment_model(n)
        q = 0.01 * np.ones(n)
        number = 3 if quick else 10
        cost[n] = min(timeit.repeat(lambda: accelerations(fs, q, q), number=number,
                                    repeat=5)) / number     # best of 5: robust to load
    ns = np.array(sorted(cost))
    slope = float(np.polyfit(np.log(ns), np.log([cost[k] for k in ns]), 1)[0])
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.5))
    for k in range(3):
        axes[0].loglog(counts, np.abs(e2[:, k]), "o-", label=f"mode {k + 1}, root 2EI/l")
        axes[0].loglog(counts, np.abs(e1[:, k]), "x--", label=f"mode {k + 1}, root EI/l")
    axes[0].set(xlabel="segments N", ylabel="|relative frequency error|",
                title=f"orders {order2.mean():.2f} (2EI/l), {order1.mean():.2f} (EI/l)")
    axes[0].legend(fontsize="x-small")
    axes[1].plot(msim.time, 1e3 * y_modal, "k-", lw=2.5, alpha=0.4, label="modal beam (6 modes)")
    for n, y in tips.items():
        axes[1].plot(msim.time, 1e3 * y, "--", lw=1, label=f"N = {n}")
    axes[1].set(xlabel="t [s]", ylabel="tip deflection [mm]", title="suddenly applied tip force")
    axes[1].legend(fontsize="small")
    axes[2].loglog(ns, [1e3 * cost[k] for k in ns], "s-")
    axes[2].set(xlabel="segments N", ylabel="one sweep [ms]",
                title=f"cost ~ N^{slope:.2f} (cf. Fig. 9.25)")
    fig.tight_layout()
    Path(output_dir).mkdir(parents=True, exist_ok=True)
    fig.savefig(Path(output_dir) / f"{NAME}.png", dpi=100)
    plt.close(fig)
    return {
        "accuracy": [accuracy(
            "convergence order deviation", float(np.max(np.abs(order2 - 2.0))), "(dimensionless)", 0.05,
            f"max |p - 2| of the observed orders p of the relative errors of the first 3 frequencies "
            f"(2EI/l root spring, N = {', '.join(map(str, counts))}) against the exact clamped-free beta L values",
            source="docs/flexible.md: frequency order 2.00 (2EI/l); test bound 0.05")],
        "frequency_max_relative_error_finest": float(np.max(np.abs(e2[-1]))),
        "frequency_errors_2EI_l": {str(n): e2[i].tolist() for i, n in enumerate(counts)},
        "frequency_errors_EI_l": {str(n): e1[i].tolist() for i, n in enumerate(counts)},
        "observed_order_2EI_l": order2.tolist(),
        "observed_order_EI_l": order1.tolist(),
        "tip_response_max_difference_m": {str(k): v for k, v in tip_err.items()},
        "sweep_cost_s": {str(k): v for k, v in cost.items()},
        "cost_exponent": slope,
        "wall_time_s": msim.info["wall_time_s"],
        "reference_wall_time_s": 0.0,
        "figures": [f"{NAME}.png"],
    }
