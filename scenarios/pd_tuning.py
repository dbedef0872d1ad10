"""PD tuning of the non-collocated loop m6 -> m2 of the seed chain on a cached plant.

Model: the chain of :mod:`controlled_chain_common` (Figs. 9.27-9.29) with the PD law
``u = -(kp x6 + kd x6')`` on m2, i.e. ``C(s) = kp + kd s`` on the sensed ``x6``.

Design problem: choose ``(kp, kd)`` to minimise the resonance peak ``max_w |X6 / F6|`` of the
disturbance response (force on m6) subject to closed-loop stability (no encirclement of -1 by
the Nyquist curve of ``L = C P``; the damped plant has no unstable poles) and a robustness bound
``min_w |1 + L| >= 0.4`` (sensitivity peak <= 2.5).  ``scipy.optimize.differential_evolution``
(seeded) searches ``kp in [-8, 12] N/m``, ``kd in [-4, 6] N s/m``.

Every objective evaluation uses :class:`ctmm.control.design.PlantCache`: the open-loop plant was
evaluated once with the TMM on the grid; a new ``(kp, kd)`` costs a per-frequency 1x1 solve.  The
JSON reports the time per evaluation, the cost of the same evaluation by re-running the TMM on a
rebuilt :class:`~ctmm.control.ControlledChain` (measured on a sample of parameter sets), the
speed-up, and checks the optimum against the direct TMM (``accuracy``) and in the time domain
(DT-TMM with the embedded, implicit PD, released from ``x6(0) = 0.1 m``).
"""
from __future__ import annotations

import time
from pathlib import Path

import control
import numpy as np
from scipy.optimize import differential_evolution

import ctmm
from ctmm.control import ControlledChain, Feedback, PlantCache, loop_transfer_function, margins
from ctmm.control import encirclements
from ctmm.results import FrequencyResponse
from ctmm.scenario import accuracy

from . import controlled_chain_common as common

NAME = "pd_tuning"
DESCRIPTION = ("PD gains of the loop m6 -> m2 tuned by differential evolution on a PlantCache (closed loops by "
               "per-frequency algebra): time per evaluation and speed-up against re-running the TMM")

BOUNDS = [(-8.0, 12.0), (-4.0, 6.0)]
MIN_DISTANCE = 0.4   # min |1 + L|


def _pd(kp: float, kd: float) -> control.TransferFunction:
    return control.tf([kd, kp], [1.0])


def _objective_terms(frf_x6: np.ndarray, L: FrequencyResponse) -> tuple[float, bool, float]:
    peak = float(np.max(np.abs(frf_x6)))
    stable = encirclements(L) == 0
    distance = float(np.min(np.abs(1.0 + L.response[0, 0])))
    return peak, stable, distance


def _penalised(peak: float, stable: bool, distance: float) -> float:
    if not stable:
        return 1e3 + peak
    return peak + 100.0 * max(0.0, MIN_DISTANCE - distance)


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    output_dir = Path(output_dir)
    omega = np.linspace(0.0, 30.0, 1500 if quick else 4000)
    system = ControlledChain(common.plant(), [Feedback("pd", "m6.x", "m2", gain=_pd(common.KA, 0.0))])
    outputs = ["m2.x", "m4.x", "m6.x"]
    start = time.perf_counter()
    cache = PlantCache(system, omega, inputs="m6.force", outputs=outputs)
    cache_build = time.perf_counter() - start
    s = 1j * omega
    history: list[float] = []

    def objective(p: np.ndarray) -> float:
        response = p[0] + p[1] * s                       # C(i w) as data: no LTI evaluation
        frf = cache.closed_loop(gains={"pd": response})
        L = cache.loop_transfer("pd", gains={"pd": response})
        value = _penalised(*_objective_terms(frf("m6.x"), L))
        history.append(min(value, history[-1]) if history else value)
        return value

    start = time.perf_counter()
    result = differential_evolution(objective, BOUNDS, seed=3, maxiter=8 if quick else 40, popsize=10,
                                    tol=1e-8, polish=True)
    optimise_time = time.perf_counter() - start
    n_evals = len(history)
    per_eval_cache = optimise_time / n_evals
    kp, kd = (float(v) for v in result.x)

    # the same evaluation by the TMM on rebuilt systems, on a sample of parameter sets
    rng = np.random.default_rng(0)
    sample = np.column_stack([rng.uniform(*BOUNDS[0], 6 if quick else 15), rng.uniform(*BOUNDS[1], 6 if quick else 15)])
    start = time.perf_counter()
    direct_terms = []
    for p in sample:
        rebuilt = system.with_loops([system.loop("pd").with_parameters(gain=_pd(*p))])
        frf = ctmm.frequency_response(rebuilt, omega, input="m6.force", output="m6.x")
        L = loop_transfer_function(rebuilt, "pd", omega)
        direct_terms.append(_objective_terms(frf("m6.x"), L))
    per_eval_tmm = (time.perf_counter() - start) / len(sample)
    cached_terms = []
    for p in sample:
        response = p[0] + p[1] * s
        cached_terms.append(_objective_terms(cache.closed_loop(gains={"pd": response})("m6.x"),
                                             cache.loop_transfer("pd", gains={"pd": response})))
    peak_agreement = max(abs(a[0] - b[0]) / a[0] for a, b in zip(direct_terms, cached_terms))
    stability_agreement = all(a[1] == b[1] for a, b in zip(direct_terms, cached_terms))

    # check the optimum with the direct TMM
    tuned = system.with_loops([system.loop("pd").with_parameters(gain=_pd(kp, kd))])
    direct = ctmm.frequency_response(tuned, omega, input="m6.force", output=outputs)
    cached = cache.closed_loop(gains={"pd": _pd(kp, kd)})
    frf_error = float(np.max(np.abs(direct.response - cached.response)) / np.max(np.abs(direct.response)))
    tuned_margins = margins(tuned, "pd", omega[1:])
    baseline = cache.closed_loop(gains={"pd": common.KA})
    open_loop = ctmm.frequency_response(system.plant, omega, input="m6.force", output="m6.x")

    # time domain: embedded PD (real-time, implicit) vs the P loop of the seed and no control
    t_final = 6.0 if quick else 15.0
    runs = {}
    for label, terms in (("tuned PD", [("m6.x", kp), ("m6.v", kd)]), (f"P, Ka = {common.KA:g}", [("m6.x", common.KA)]),
                         ("no control", None)):
        sim_system = (common.plant() if terms is None else
                      ControlledChain(common.plant(), [Feedback("pd", terms, "m2", gain=1.0)]))
        runs[label] = ctmm.simulate(sim_system, t_final, 0.01, x0={"m6": 0.1})

    def settling(res) -> float | None:
        """Last time |x6| exceeds 2 % of its initial 0.1 m (None: not settled within t_final)."""
        above = np.flatnonzero(np.abs(res["m6.x"]) > 0.02 * 0.1)
        if above.size and above[-1] == res.time.size - 1:
            return None
        return float(res.time[above[-1]]) if above.size else 0.0

    def settling_text(res) -> str:
        value = settling(res)
        return f"settles (2 %) at {value:.1f} s" if value is not None else f"not settled by {t_final:g} s"

    # -- figures ------------------------------------------------------------------------
    figures = []
    fig, axes = plt.subplots(2, 2, figsize=(12, 8.5))
    ax = axes[0, 0]
    # Bode magnitudes [dB re 1 m/N] drawn by FrequencyResponse.plot (its labels and units)
    for response, style, label in ((open_loop, ":", "no control"),
                                   (baseline, "--", f"P, Ka = {common.KA:g} N/m (seed)"),
                                   (cached, "-", f"tuned PD kp = {kp:.3g}, kd = {kd:.3g}")):
        response.plot([ax], output="m6.x", phase=False, label=label)
        ax.get_lines()[-1].set_linestyle(style)
    ax.get_lines()[0].set_color("0.5")
    ax.semilogx(omega[::80], 20 * np.log10(np.abs(direct("m6.x")[::80])), "kx", ms=4, label="tuned, direct TMM")
    ax.set_xlim(omega[1], 8)
    ax.set_title("X6 per unit force on m6", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    L = cache.loop_transfer("pd", gains={"pd": _pd(kp, kd)})("pd.L")
    ax.plot(L.real, L.imag, label="L, tuned PD")
    ax.plot(L.real, -L.imag, "--", lw=0.6)
    circle = np.exp(1j * np.linspace(0, 2 * np.pi, 200))
    ax.plot(-1 + MIN_DISTANCE * circle.real, MIN_DISTANCE * circle.imag, "r:", lw=0.8, label="|1 + L| = 0.4")
    ax.plot([-1], [0], "r+", ms=12, mew=2)
    ax.set_xlim(-2.5, 1.5)
    ax.set_ylim(-2, 2)
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_title(f"Nyquist: GM = {tuned_margins.gain_margin:.3g}, PM = {tuned_margins.phase_margin:.3g} deg")
    ax.legend(fontsize=7)
    ax = axes[1, 0]
    ax.semilogy(np.arange(1, n_evals + 1), history[:n_evals], "-")
    ax.set_xlabel("objective evaluation")
    ax.set_ylabel("best penalised peak [m/N]")
    ax.set_title(f"{n_evals} evaluations, {per_eval_cache * 1e3:.2f} ms each "
                 f"({per_eval_tmm / per_eval_cache:.0f}x faster than the TMM)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax = axes[1, 1]
    for label, res in runs.items():
        ax.plot(res.time, res["m6.x"], label=f"{label}: {settling_text(res)}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("x6 [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    name = f"{NAME}.png"
    fig.savefig(output_dir / name, dpi=110)
    plt.close(fig)
    figures.append(name)

    return {
        "accuracy": [accuracy(
            "FRF error of the plant cache vs TMM", frf_error, "relative", 1e-10,
            "max_w |H_cache - H_TMM| / max_w |H_TMM| of X2, X4, X6 per unit force on m6 at the optimum "
            "(PlantCache closed-loop algebra vs the TMM on the rebuilt controlled chain)",
            source="docs/control.md: PlantCache vs embedded closed loop < 1e-10")],
        "sample_check": {"n": int(len(sample)), "max_relative_peak_difference": float(peak_agreement),
                         "same_stability_verdicts": bool(stability_agreement),
                         "n_stable": int(sum(t[1] for t in direct_terms))},
        "optimum": {"kp_N_per_m": kp, "kd_Ns_per_m": kd, "peak_X6_m_per_N": float(np.max(np.abs(cached("m6.x")))),
                    "min_distance_to_minus_1": float(np.min(np.abs(1 + L))),
                    "margins": tuned_margins.as_dict()},
        "baseline_P_Ka5_peak_X6_m_per_N": float(np.max(np.abs(baseline("m6.x")))),
        "uncontrolled_peak_X6_m_per_N": float(np.max(np.abs(open_loop("m6.x")))),
        "settling_time_2pct_s": {label: settling(res) for label, res in runs.items()},
        "settling_definition": "last time |x6| > 2 mm after release from x6(0) = 0.1 m (null: not settled)",
        "evaluations": n_evals,
        "time_per_evaluation_cache_s": per_eval_cache,
        "time_per_evaluation_tmm_s": per_eval_tmm,
        "speedup": per_eval_tmm / per_eval_cache,
        "cache_build_s": cache_build,
        "n_omega": int(omega.size),
        "wall_time_s": optimise_time + cache_build,
        "reference_wall_time_s": per_eval_tmm * n_evals,
        "reference_wall_time_note": ("estimated: time per TMM evaluation (measured on the sample) x number of "
                                     "evaluations of the optimisation"),
        "parameters": common.PARAMETERS,
        "figures": figures,
    }
