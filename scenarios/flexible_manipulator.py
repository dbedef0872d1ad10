"""Seed 001 Fig. 9.43: controlled flexible manipulator (PD hub + segmented-PZT modal-velocity feedback).

Scene (``ctmm.manipulator.seed_manipulator``; parameters our choice, the book's were lost):
1 m x 40 mm x 3 mm aluminium arm on a 2 kg m^2 hub (radius 50 mm), three PZT-5H patches
(20-120, 300-400, 550-650 mm, c_a = 1.16e-3 N m/V, +-200 V), PD kp = 200 N m/rad,
kd = 30 N m s/rad, PZT law eq. (9.65) with Ka_i = 1000 V s/rad, 60 deg cycloidal slew in 1 s,
3 clamped-free modes (as in the seed).

* (a) desired vs actual hub angle, (b) hub-frame tip deflection with and without PZT control,
  (c) voltage on PZT 1 -- TMM time domain through the verbs: the scene
  (:func:`ctmm.manipulator.manipulator_scene`: hub ``ActuatedHinge`` + ``ModalBeam``, the PD and
  the PZT laws as ``Feedback`` loops) simulated by ``ctmm.simulate(..., method="rk4", dt = 2 ms,
  references=scene_references(pd, move))``, against the independent assumed-modes Lagrange model
  (``solve_ivp`` DOP853, rtol 1e-11).
* full run only: the implicit DT-TMM (Newmark + Newton) of the book and a delayed variant (PD
  10 ms, PZT 2 ms, through the verb) against the method of steps.
* frequency domain, through the verbs on the same scene with exact beam fields
  (``fields="exact"``: the arm as exact Euler-Bernoulli fields between its stations, the loops
  closed on them with exact delays): closed-loop FRF ``theta_d -> tip`` with and without PZT
  against the reference (150 modes + static correction); loop margins at the hub and at PZT 1
  (full run) by ``ctmm.control.margins(scene, loop, omega, fields="exact")``.

  The FRF per unit desired angle.  The hub loop senses ``y = kp theta + kd theta_dot`` and its
  reference is ``r = kp theta_d + kd theta_d_dot`` (:func:`~ctmm.manipulator.scene_references`),
  so ``theta_d`` enters the closed loop only through ``r``: with ``theta_d = e^{i w t}``,
  ``r = (kp + kd i w) e^{i w t}``, and by linearity

      tip / theta_d = (kp + i w kd) * H(i w),   H = "arm.tip.w" per unit "hub_pd.reference",

  ``H`` from ``ctmm.frequency_response(scene, omega, input="hub_pd.reference",
  output="arm.tip.w", fields="exact")``.  ``"arm.tip.w"`` is the station port at the arm's free
  end: the deflection in the arm's root-tangent (hub) frame, ``u(L) = w(L) - (r_h + L) theta``
  for the inertial transverse displacement ``w`` -- the reference's hub-frame tip.

The compiled RK4 timing uses :class:`~ctmm.manipulator.compiled.CompiledManipulator` (the controlled
scene through the generated kernels, its loops closed inside the generated step, the path of
``ctmm.simulate(..., compiled=True)``); it is reported as a timing and checked against the verb's run.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from dataclasses import dataclass

import ctmm
from ctmm.flexible.outputs import tip_deflection
from ctmm.control import margins
from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_MOVE, SEED_PZT_GAIN, HubPD, PZTFeedback,
                              manipulator_scene, scene_references, seed_manipulator)
from ctmm.manipulator.compiled import CompiledManipulator
from ctmm.manipulator.scene import HUB_LOOP, TIP_STATION
from ctmm.reference.manipulator_lagrange import ManipulatorLagrange
from ctmm.scenario import accuracy
from ctmm.signal_results import coordinate_histories

NAME = "flexible_manipulator"
DESCRIPTION = ("Seed Fig. 9.43: PD hub + segmented-PZT modal-velocity feedback on a flexible arm; TMM time "
               "domain (modal beam, compiled RK4 / DT-TMM Newmark) and continuum FRF vs assumed-modes Lagrange")

DT = 0.002


def _settling_time(t: np.ndarray, tip: np.ndarray, fraction: float) -> float:
    """Last time ``|tip|`` exceeds ``fraction`` of its peak (``inf`` if still at the end)."""
    above = np.nonzero(np.abs(tip) > fraction * np.abs(tip).max())[0]
    if not above.size:
        return 0.0
    k = above[-1]
    return float("inf") if k >= t.size - 1 else float(t[k + 1])


@dataclass(frozen=True)
class _Run:
    """The histories the figures compare, read from a :class:`~ctmm.results.SimulationResult`."""

    t: np.ndarray
    theta: np.ndarray
    desired: np.ndarray
    tip_deflection: np.ndarray
    voltages: np.ndarray
    wall_time_s: float
    info: dict
    result: object = None          # the SimulationResult (ctmm run --save / --animate)

    @property
    def peak_voltage(self) -> float:
        return float(np.abs(self.voltages).max()) if self.voltages.size else 0.0


def _simulate_scene(arm, pd: HubPD, law, t_final: float, store_every: int, method: str = "rk4") -> _Run:
    """``ctmm.simulate`` of the manipulator scene (``method``, ``DT``) tracking ``SEED_MOVE``."""
    scene = manipulator_scene(arm, pd=pd, pzt=law)
    result = ctmm.simulate(scene, t_final, DT, method=method, store_every=store_every,
                           references=scene_references(pd, SEED_MOVE))
    q = coordinate_histories(result)[0]
    patches = [patch.name for patch in arm.patches] if law is not None else []
    voltages = np.column_stack([result[f"{name}.u"] for name in patches]) if patches else np.zeros((len(q), 0))
    return _Run(result.time, result["hub.theta"], np.array([SEED_MOVE.angle(t) for t in result.time]),
                tip_deflection(scene.plant, q, "arm"), voltages, result.info["wall_time_s"], result.info, result)


def _tip_per_desired_angle(scene, pd: HubPD, omega: np.ndarray) -> np.ndarray:
    """Closed-loop ``tip / theta_d`` [m/rad] of the scene's exact beam fields over ``omega``
    [rad/s]: ``(kp + i omega kd)`` times the response of ``"arm.tip.w"`` to the hub loop's
    reference (module docstring)."""
    reference = f"{HUB_LOOP}.reference"
    tip = f"arm.{TIP_STATION}.w"
    response = ctmm.frequency_response(scene, omega, input=reference, output=tip, fields="exact")
    return (pd.kp + 1j * omega * pd.kd) * response(tip, reference)


def _after_move(t: np.ndarray) -> np.ndarray:
    """Stored times [s] from 0.5 s after the end of the move on (that time included, to 1e-9 s:
    independent of round-off in the time grid)."""
    return t >= SEED_MOVE.duration + 0.5 - 1e-9


def _error(sim, ref) -> dict:
    peak = float(np.abs(ref.tip_deflection).max())
    return {"tip_error_percent_of_peak": float(np.abs(sim.tip_deflection - ref.tip_deflection).max() / peak * 100),
            "hub_angle_error_rad": float(np.abs(sim.theta - ref.theta).max()),
            "voltage_error_V": float(np.abs(sim.voltages - ref.voltages).max()) if sim.voltages.size else 0.0}


def run(output_dir: Path, quick: bool = False, results: dict | None = None) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    output_dir = Path(output_dir)
    t_final = 2.5 if quick else 5.0
    arm = seed_manipulator()
    pd = HubPD(SEED_KP, SEED_KD)
    gains = np.eye(arm.n_patches) * SEED_PZT_GAIN
    laws = {"PD only": None, "PD + PZT": PZTFeedback.per_patch([SEED_PZT_GAIN] * arm.n_patches)}
    reference_model = ManipulatorLagrange.from_manipulator(arm, 3, stiffening=True)

    # -- time domain: the scene through ctmm.simulate vs the Lagrange reference ---------------
    sims, refs, errors, wall, ref_wall = {}, {}, {}, 0.0, 0.0
    for label, law in laws.items():
        sims[label] = _simulate_scene(arm, pd, law, t_final, store_every=5)
        wall += sims[label].wall_time_s
        started = time.perf_counter()
        refs[label] = reference_model.simulate(t_final, reference=SEED_MOVE, kp=SEED_KP, kd=SEED_KD,
                                               pzt_gains=None if law is None else gains, t_eval=sims[label].t,
                                               rtol=1e-10 if quick else 1e-11)
        ref_wall += time.perf_counter() - started
        errors[label] = _error(sims[label], refs[label])
    t = sims["PD + PZT"].t
    after = _after_move(t)
    rms = {k: float(np.sqrt(np.mean(s.tip_deflection[after] ** 2))) for k, s in sims.items()}
    settling = {k: {f"{int(f * 100)}%": _settling_time(s.t, s.tip_deflection, f) for f in (0.05, 0.02)}
                for k, s in sims.items()}
    controlled = sims["PD + PZT"]

    # compiled RK4 of the same scene (the generated kernels with the loops inside the step): timing, agreement
    compiled = CompiledManipulator(arm, pd, laws["PD + PZT"], SEED_MOVE, block=5, chunks=100).simulate(t_final, DT)
    extra = {"compiled_rk4": {
        "wall_time_s": compiled.wall_time_s, "real_time_factor": compiled.real_time_factor,
        "tip_difference_vs_verb_m": float(np.abs(compiled.tip_deflection - controlled.tip_deflection).max()),
        "note": ("CompiledManipulator (the controlled scene through the generated kernels, loops closed inside "
                 "the generated RK4 step)")}}
    if not quick:
        newmark = _simulate_scene(arm, pd, laws["PD + PZT"], t_final, store_every=5, method="newmark")
        extra["dt_tmm_newmark"] = {**_error(newmark, refs["PD + PZT"]), "wall_time_s": newmark.wall_time_s,
                                   "real_time_factor": t_final / newmark.wall_time_s,
                                   "mean_newton_iterations": newmark.info.get("newton_iterations_mean")}
        dsim = _simulate_scene(arm, HubPD(SEED_KP, SEED_KD, delay=0.01), PZTFeedback(gains, delay=0.002),
                               t_final, store_every=5)
        dref = reference_model.simulate(t_final, reference=SEED_MOVE, kp=SEED_KP, kd=SEED_KD, pd_delay=0.01,
                                        pzt_gains=gains, pzt_delay=0.002, t_eval=dsim.t)
        extra["delayed_pd10ms_pzt2ms"] = {**_error(dsim, dref), "wall_time_s": dsim.wall_time_s,
                                          "peak_voltage_V": dsim.peak_voltage,
                                          "rms_tip_after_move_m": float(np.sqrt(np.mean(
                                              dsim.tip_deflection[_after_move(dsim.t)] ** 2)))}

    # -- frequency domain ----------------------------------------------------------------------
    omega = np.linspace(2.0, 40.0, 120 if quick else 400)
    started = time.perf_counter()
    scenes = {label: manipulator_scene(arm, pd=pd, pzt=law) for label, law in laws.items()}
    frf = {label: _tip_per_desired_angle(scene, pd, omega) for label, scene in scenes.items()}
    frf_wall = time.perf_counter() - started
    continuum = ManipulatorLagrange.from_manipulator(arm, 150)
    frf_ref = {label: continuum.frequency_response(omega, kp=SEED_KP, kd=SEED_KD,
                                                   pzt_gains=None if law is None else gains)["theta_d"]["tip"]
               for label, law in laws.items()}
    frf_error = max(float(np.max(np.abs(frf[k] - frf_ref[k]) / np.abs(frf_ref[k]))) for k in frf)
    if not quick:                      # margins refine every crossover on the exact L (slow-ish)
        controlled_scene = scenes["PD + PZT"]
        extra["margins_hub_pd"] = margins(controlled_scene, HUB_LOOP, np.logspace(-1, 3, 600),
                                          fields="exact").as_dict()
        extra["margins_pzt1"] = margins(controlled_scene, arm.patches[0].name, np.logspace(0, 3.5, 600),
                                        fields="exact").as_dict()

    # -- figures -------------------------------------------------------------------------------
    figures = []
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7.5, 8.5))
    step = max(1, t.size // 60)
    axes[0].plot(t, np.degrees(controlled.desired), "k--", lw=1.2, label="desired")
    axes[0].plot(t, np.degrees(controlled.theta), "C0-", lw=1.0, label="actual (TMM, PD + PZT)")
    axes[0].plot(t[::step], np.degrees(refs["PD + PZT"].theta[::step]), "x", ms=4, color="C3",
                 label="Lagrange reference")
    for label, color in (("PD only", "C1"), ("PD + PZT", "C0")):
        axes[1].plot(t, 1e3 * sims[label].tip_deflection, color=color, lw=1.0, label=f"TMM, {label}")
        axes[1].plot(t[::step], 1e3 * refs[label].tip_deflection[::step], "x", ms=4, color="C3")
    axes[2].plot(t, controlled.voltages[:, 0], "C0-", lw=1.0, label="TMM")
    axes[2].plot(t[::step], refs["PD + PZT"].voltages[::step, 0], "x", ms=4, color="C3", label="Lagrange")
    axes[0].set_ylabel("hub angle [deg]")
    axes[1].set_ylabel("tip deflection [mm]")
    axes[2].set_ylabel("V on PZT 1 [V]")
    axes[2].set_xlabel("t [s]")
    axes[0].set_title("Fig. 9.43: (a) hub angle, (b) tip deflection, (c) voltage on PZT 1")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small", loc="best")
    fig.tight_layout()
    name = f"{NAME}_fig9_43.png"
    fig.savefig(output_dir / name, dpi=110)
    plt.close(fig)
    figures.append(name)

    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for label, color in (("PD only", "C1"), ("PD + PZT", "C0")):
        ax.semilogy(omega, np.abs(frf[label]), color=color, label=f"TMM continuum, {label}")
        ax.semilogy(omega[::6], np.abs(frf_ref[label][::6]), "x", color="C3", ms=4)
    ax.set_xlabel("omega [rad/s]")
    ax.set_ylabel("|tip / theta_d| [m/rad]")
    ax.set_title("closed-loop FRF theta_d -> tip (x: Lagrange, 150 modes + static correction)", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize="small")
    fig.tight_layout()
    name = f"{NAME}_frf.png"
    fig.savefig(output_dir / name, dpi=110)
    plt.close(fig)
    figures.append(name)

    max_error = max(e["tip_error_percent_of_peak"] for e in errors.values())
    if "dt_tmm_newmark" in extra:
        max_error = max(max_error, extra["dt_tmm_newmark"]["tip_error_percent_of_peak"])
    simulated = sum(s.t[-1] for s in sims.values())
    if results is not None:                      # ctmm run --save / --animate
        results.update({label.replace(" ", ""): s.result for label, s in sims.items()})
    return {
        "accuracy": [accuracy(
            "tip deflection error vs Lagrange", float(max_error), "% of peak", 0.1,
            "max_t |u_tip,TMM - u_tip,Lagrange| / max_t |u_tip,Lagrange| x 100, over the PD-only and PD+PZT "
            "runs (ctmm.simulate RK4, dt = 2 ms; full run also the DT-TMM Newmark); reference: assumed modes (3), "
            "Lagrange, DOP853 rtol 1e-11 (1e-10 quick)",
            source="docs/manipulator.md: real-time target, tip error << 0.1 % of the peak")],
        "errors": errors,
        "wall_time_s": wall,
        "real_time_factor": float(simulated / wall),
        "reference_wall_time_s": ref_wall,
        "t_final_s": t_final,
        "dt_s": DT,
        "peak_tip_deflection_m": {k: float(np.abs(s.tip_deflection).max()) for k, s in sims.items()},
        "rms_tip_after_move_m": rms,
        "rms_reduction_by_pzt": 1.0 - rms["PD + PZT"] / rms["PD only"],
        "settling_time_s": settling,
        "peak_voltage_V": controlled.peak_voltage,
        "voltage_limit_V": arm.voltage_limit,
        "voltage_limit_exceeded": bool(controlled.peak_voltage > arm.voltage_limit),
        "hub_tracking_error_max_rad": float(np.abs(controlled.theta - controlled.desired).max()),
        "hub_final_error_rad": float(abs(controlled.theta[-1] - controlled.desired[-1])),
        "frf_relative_error": frf_error,
        "frf_wall_time_s": frf_wall,
        "frf_peak_m_per_rad": {k: float(np.abs(v).max()) for k, v in frf.items()},
        **extra,
        "parameters": {"arm": "1 m x 40 mm x 3 mm Al, EI = 6.3 N m^2, rho A = 0.324 kg/m, tau_d = 0.2 ms",
                       "hub": "J_h = 2 kg m^2, r_h = 0.05 m", "patches": "PZT-5H 0.5 mm at 20-120, 300-400, 550-650 mm",
                       "c_a_N_m_per_V": float(arm.moments_per_volt[0]), "kp": SEED_KP, "kd": SEED_KD,
                       "Ka": SEED_PZT_GAIN, "move": "0 -> 60 deg cycloidal in 1 s", "modes": 3},
        "figures": figures,
    }
