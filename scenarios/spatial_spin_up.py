"""Spatial spin-up with out-of-plane gravity: the Kane-Ryan-Banerjee beam on a vertical spin axis.

The KRB beam of the planar ``spin_up`` (FORMULAS 6.1: L = 10 m, EI = 1.4e4 N m^2 in both planes,
rhoA = 1.2 kg/m, hub radius 0) is horizontal along ``x`` and spun about the vertical ``z`` axis by
the prescribed KRB law (Omega_s = 6 rad/s reached at T_s = 15 s, 0-20 s) with gravity -9.81 m/s^2
along ``z``, out of the plane of rotation.  It starts at rest in its static sag (the modal
coordinates of ``K eta = f_gravity``, computed from the reference's equations; tip sag 1.05 m).
The in-plane deflection ``w_y`` is driven by the spin-up, the out-of-plane ``w_z`` by gravity
and the stiffening that the spin adds.  Model: driven ``Revolute`` (about z) -> ``SpatialBeam``
(3 modes per plane), acceleration TMM + RK4, h = 10 ms (``h omega_3 = 0.67``).

With geometric stiffening (the consistent first-order model, Kane, Ryan, Banerjee 1987) both
deflections stay bounded; without it the in-plane deflection diverges once the spin passes the
first bending frequency ``omega_1 = 3.80 rad/s`` (the centrifugal softening has no stiffening to
balance it).  The spatial beam's deflection guard stops that run with a ``SimulationError`` once the
deflection bound exceeds the beam's length; its partial history is plotted.  The contrast is asserted: the run
stops, or its in-plane tip deflection exceeds 10 times the stiffened one.  The out-of-plane direction has no centrifugal softening (the spin axis is along it).

Reference: the independent assumed-modes Lagrange model (``ctmm/reference/spatial_beam_lagrange.py``,
the same modes and consistent geometric stiffness, no TMM code) with the hub angle prescribed
(``driven_rk4``, RK4 at h / 2), for both runs; the stiffened run is compared over the whole time,
the unstiffened one up to the time ctmm stops it.

Quick mode (the test): T_s = 3 s, 0-4.5 s, h = 25 ms (``h omega_3 = 1.7``), so that the
unstiffened run passes ``omega_1`` and diverges within the run.  The unstiffened run is compared
with its reference while the reference's in-plane tip deflection is below the beam length.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import ctmm
import ctmm.spatial as sp
from ctmm.errors import SimulationError
from ctmm.flexible.outputs import spinup_law
from ctmm.reference.beams import beta_roots, clamped_free_mode
from ctmm.reference.spatial_beam_lagrange import HubBeam, SpatialBeamLagrange
from ctmm.scenario import accuracy
from ctmm.spatial.ports import sensor_values

from .planar_common import save_figure

NAME = "spatial_spin_up"
DESCRIPTION = ("Spatial KRB spin-up with out-of-plane gravity: SpatialBeam TMM + RK4 with / without geometric "
               "stiffening vs the assumed-modes Lagrange model; in-plane and out-of-plane tip deflection")
BEAM = dict(length=10.0, mass_per_length=1.2, bending_stiffness_y=1.4e4, bending_stiffness_z=1.4e4,
            n_modes_y=3, n_modes_z=3)
GRAVITY = (0.0, 0.0, -9.81)
FULL = dict(final_rate=6.0, ramp_time=15.0, t_final=20.0, dt=1e-2)
QUICK = dict(final_rate=6.0, ramp_time=3.0, t_final=4.5, dt=2.5e-2)
BOUND = 0.1                 # [% of peak]
DIVERGENCE_RATIO = 10.0


def model(stiffening: bool, case: dict) -> sp.SpatialModel:
    angle, rate, acceleration = spinup_law(case["final_rate"], case["ramp_time"])
    beam = sp.SpatialBeam("beam", geometric_stiffening=stiffening, **BEAM)
    return sp.SpatialModel(NAME, [beam, sp.Revolute(name="motor", parent=None, child="beam", axis=(0.0, 0.0, 1.0),
                                                    position=angle, rate=rate, acceleration=acceleration)],
                           gravity=GRAVITY)


def reference(stiffening: bool) -> SpatialBeamLagrange:
    return SpatialBeamLagrange(HubBeam(geometric_stiffening=stiffening, gravity=GRAVITY, **BEAM))


def static_sag(lagrange: SpatialBeamLagrange) -> np.ndarray:
    """Modal coordinates of the static sag at rest: ``K eta = f`` from the reference's equations."""
    n = lagrange.n_eta
    eta = np.zeros(n)
    for _ in range(3):                         # linear in eta: one Newton step; two more for round-off
        q = np.concatenate([[0.0], eta])
        residual = lagrange.mass_and_bias(q, np.zeros(n + 1))[1][1:]
        eta = eta + np.linalg.solve(lagrange.K, residual)
    return eta


def reference_tip(eta: np.ndarray) -> np.ndarray:
    """``[w_y, w_z]`` at the tip from the reference's modal coordinates, shapes written here."""
    tips = np.array([clamped_free_mode(b, np.array([1.0]), 0)[0] for b in beta_roots("clamped-free", 3)])
    return np.c_[eta[:, :3] @ tips, eta[:, 3:6] @ tips]


def run_case(stiffening: bool, case: dict, eta0: np.ndarray) -> dict:
    m = model(stiffening, case)
    v0 = np.zeros(m.n_velocities)
    started = time.perf_counter()
    try:
        result, stopped, message = ctmm.simulate(m, case["t_final"], case["dt"], method="rk4", x0=eta0, v0=v0), None, ""
    except SimulationError as error:
        result, stopped, message = error.partial_result, float(error.partial_result.time[-1]), str(error)
    wall = time.perf_counter() - started
    t = np.asarray(result.time)
    q = np.array([result[name] for name in m.coordinates]).T
    v = np.array([result[name] for name in m.velocities]).T
    tip = np.array([sensor_values(m, ["beam.tip.w_y", "beam.tip.w_z"], qk, vk) for qk, vk in zip(q, v)])
    angle, rate, acceleration = spinup_law(case["final_rate"], case["ramp_time"])
    started = time.perf_counter()
    steps = len(t) - 1
    states = reference(stiffening).driven_rk4(lambda s: (angle(s), rate(s), acceleration(s)), eta0,
                                              np.zeros_like(eta0), case["dt"] / 2, 2 * steps)[::2]
    reference_time = time.perf_counter() - started
    return {"t": t, "tip": tip, "tip_ref": reference_tip(states[:, :eta0.size]), "stopped": stopped,
            "message": message, "wall": wall, "reference_wall": reference_time}


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    case = QUICK if quick else FULL
    eta0 = static_sag(reference(True))
    on, off = run_case(True, case, eta0), run_case(False, case, eta0)
    figures, errors = [], {}
    for k, label in ((0, "in-plane"), (1, "out-of-plane")):
        error = float(np.max(np.abs(on["tip"][:, k] - on["tip_ref"][:, k])))
        peak = float(np.max(np.abs(on["tip_ref"][:, k])))
        errors[label] = (error, peak)
        figures.append(accuracy(
            f"{label} tip deflection error vs Lagrange (stiffened)", 100.0 * error / peak, "% of peak", BOUND,
            f"max over t of |{label} tip deflection: SpatialBeam TMM + RK4 (h = {case['dt'] * 1e3:g} ms) - "
            "independent assumed-modes Lagrange with the consistent geometric stiffness (RK4, h / 2)| / "
            "max_t |reference| x 100",
            source="the 0.1 % of the peak tip error target of docs/manipulator.md"))
    valid = np.abs(off["tip_ref"][:, 0]) < BEAM["length"]     # the unstiffened runs until |w_y| reaches L
    off_error = float(np.max(np.abs(off["tip"][valid, 0] - off["tip_ref"][valid, 0])))
    off_valid = float(off["t"][valid][-1])
    on_peak = float(np.max(np.abs(on["tip"][:, 0])))
    off_peak = float(np.max(np.abs(off["tip"][:, 0])))
    diverged = off["stopped"] is not None or off_peak > DIVERGENCE_RATIO * on_peak
    fig, axes = plt.subplots(1, 3, figsize=(16, 4))
    angle, rate, _ = spinup_law(case["final_rate"], case["ramp_time"])
    axes[0].plot(on["t"], [rate(s) for s in on["t"]])
    axes[0].axhline(3.80, color="grey", lw=0.8, ls=":", label="omega_1 = 3.80 rad/s")
    axes[0].set(xlabel="t [s]", ylabel="spin rate [rad/s]", title="prescribed KRB spin-up")
    axes[0].legend(fontsize="small")
    for k, axis, title in ((0, axes[1], "in-plane tip deflection w_y"), (1, axes[2], "out-of-plane tip deflection w_z")):
        axis.plot(on["t"], on["tip"][:, k], label="stiffened, TMM + RK4")
        axis.plot(on["t"], on["tip_ref"][:, k], "k--", lw=1, label="stiffened, Lagrange")
        axis.plot(off["t"], off["tip"][:, k], "r", lw=1, label="no stiffening (stopped)" if off["stopped"] else
                  "no stiffening")
        axis.plot(off["t"], off["tip_ref"][:, k], "r:", lw=1, label="no stiffening, Lagrange")
        bound = 2.5 * max(np.max(np.abs(on["tip"][:, k])), 0.1)
        axis.set(xlabel="t [s]", ylabel="[m]", title=title, ylim=(-bound, bound))
        axis.legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    return {
        "accuracy": figures,
        "in_plane_tip_max_error_m": errors["in-plane"][0],
        "out_of_plane_tip_max_error_m": errors["out-of-plane"][0],
        "peak_in_plane_tip_m": on_peak,
        "peak_out_of_plane_tip_m": float(np.max(np.abs(on["tip"][:, 1]))),
        "static_sag_tip_m": float(reference_tip(eta0[None])[0, 1]),
        "unstiffened_stopped_at_s": off["stopped"],
        "unstiffened_message": off["message"][:300],
        "unstiffened_peak_in_plane_tip_m": off_peak,
        "unstiffened_tip_max_error_m": off_error,
        "unstiffened_compared_until_s": off_valid,
        "unstiffened_diverged": bool(diverged),
        "wall_time_s": on["wall"],
        "unstiffened_wall_time_s": off["wall"],
        "reference_wall_time_s": on["reference_wall"],
        "real_time_factor": case["t_final"] / on["wall"],
        "parameters": {"beam": BEAM, "gravity": GRAVITY, **case},
        "figures": [f"{NAME}.png"],
    }
