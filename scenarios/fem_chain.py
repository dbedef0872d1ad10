"""Chain of rigid bodies with a finite-element beam (seed 001 §9.3, Figs. 9.10-9.18): mixed MSTMM.

The seed's chain MRFS (Fig. 9.10) hangs a finite-element beam ("beam 1", Fig. 9.11) between rigid
bodies; its parameters were lost, so this scenario chooses its own (all SI):

* ground pivot at the origin, gravity ``(0, -9.81)``; bodies 1, 2, 3 before the beam and 4, 5 after it,
  uniform links of length 0.5 m and masses 1.0, 0.8, 0.6, 0.5, 0.4 kg, smooth hinges;
* beam 1: length 1.2 m, 4 Euler-Bernoulli elements (nodes 0-4, node 0 at the connected point with
  body 3, node 4 carries body 4), ``EI = 20 N m^2``, ``EA = 5e3 N``, ``rhoA = 0.8 kg/m``, Rayleigh
  ``C = 2e-4 K``; hinges at both beam ends;
* released at rest with every body and the beam frame at ``theta = -pi/2 + 0.6 rad`` (hanging, swung
  out by 0.6 rad); the tip of the beam then bends by up to 41 mm (3.4 % of its length, 0.065 rad):
  small deformation in the floating frame, as the model assumes (released horizontally, the whip of
  bodies 4 and 5 bends this beam by more than half its length, far outside that model).

The beam is a :class:`ctmm.fem.GlobalSubsystem` (floating frame at node 0, its internal DOFs eliminated
exactly by the one articulated sweep -- the §9.2 boundary unknowns without iteration,
``docs/mixed.md``).  Outputs as the seed's figures: transverse displacement (global ``y``) of the
connected point (Fig. 9.12), transverse displacements of nodes 1-3 in the beam frame (Figs. 9.13-9.15),
azimuths of bodies 3 and 5 (Figs. 9.16-9.17), interaction force between body 3 and beam 1 (Fig. 9.18).

Independent reference: :mod:`ctmm.reference.mixed_global` (one global Lagrange model of the whole
chain, its own FE matrices), integrated with the same RK4 step (the coupling is then checked to
round-off) and with DOP853 (rtol 1e-11) for the integration error of the TMM runs (RK4 and the
implicit DT-TMM Newmark).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import ctmm
from ctmm.flexible import solve_flexible
from ctmm.planar import PlanarModel
from ctmm.reference.mixed_global import BeamSegment, GlobalChain, RigidSegment
from ctmm.scenario import accuracy
from ctmm.scene_files import load_scene

from .mixed_common import coordinates_accuracy, histories, same_step
from .planar_common import save_figure

NAME = "fem_chain"
DESCRIPTION = ("Chain of rigid bodies with a finite-element beam (seed 001 §9.3, Figs. 9.10-9.18): mixed MSTMM "
               "(FE subsystem on the one sweep) + RK4 / Newmark vs a global Lagrange model")

MASSES = (1.0, 0.8, 0.6, 0.5, 0.4)
LINK = 0.5
BEAM = dict(length=1.2, elements=4, bending_stiffness=20.0, axial_stiffness=5.0e3, mass_per_length=0.8)
RAYLEIGH = (0.0, 2.0e-4)
STEP = 2.5e-4
INITIAL_ANGLE = -np.pi / 2 + 0.6
BOUND_SAME_INTEGRATOR = 1e-8
BOUND_FORCE = 1e-8


def model() -> PlanarModel:
    """The mixed model (module docstring), built from its scene file ``scenarios/files/fem_chain.toml``
    (the one source of the TMM model; :func:`reference` builds the global model from the constants above)."""
    return load_scene(Path(__file__).resolve().parent / "files" / "fem_chain.toml").system


def reference() -> GlobalChain:
    """The independent global model of the same chain."""
    rigid = [RigidSegment(LINK, m, m * LINK ** 2 / 12, LINK / 2) for m in MASSES]
    b = BEAM
    beam = BeamSegment(b["length"], b["elements"], b["bending_stiffness"], b["axial_stiffness"],
                       b["mass_per_length"], rayleigh=RAYLEIGH)
    return GlobalChain(rigid[:3] + [beam] + rigid[3:])


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t_final = 0.05 if quick else 1.5
    mixed, ref = model(), reference()
    names = mixed.coordinates
    q0 = np.zeros(mixed.n_coordinates)
    q0[[names.index(c) for c in names if c.endswith(".theta")]] = INITIAL_ANGLE
    rk4 = ctmm.simulate(mixed, t_final, STEP, method="rk4", x0=q0, outputs=("body3.out.y",))
    newmark = ctmm.simulate(mixed, t_final, STEP, method="newmark", x0=q0)
    q, v = histories(rk4, names)
    q_nm, _ = histories(newmark, names)
    start = time.perf_counter()
    _, q_ref, v_ref = ref.rk4(q0, np.zeros_like(q0), t_final, STEP)
    reference_rk4_time = time.perf_counter() - start
    start = time.perf_counter()
    q_tight, _ = ref.solve(q0, np.zeros_like(q0), rk4.time, rtol=1e-11, atol=1e-12)
    reference_tight_time = time.perf_counter() - start
    error_same = float(np.max(np.abs(q - q_ref)))
    beam_index = mixed.body_names.index("beam1")
    samples = np.arange(0, rk4.time.size, max(1, rk4.time.size // 200))
    force = np.array([solve_flexible(mixed, q[k], v[k], rk4.time[k]).joint_force[beam_index, :2] for k in samples])
    force_ref = np.array([ref.interaction_force(q_ref[k], v_ref[k], 3, rk4.time[k]) for k in samples])
    error_force = float(np.max(np.abs(force - force_ref)) / np.max(np.abs(force_ref)))
    connected_ref = np.array([ref.hinge_positions(q_ref[k])[3, 1] for k in range(q_ref.shape[0])])
    error_connected = float(np.max(np.abs(rk4["body3.out.y"] - connected_ref)))
    angles = [names.index(c) for c in names if c.endswith(".theta")]
    error_rk4_tight = float(np.max(np.abs(q[:, angles] - q_tight[:, angles])))
    error_newmark_tight = float(np.max(np.abs(q_nm[:, angles] - q_tight[:, angles])))

    fig, axes = plt.subplots(2, 3, figsize=(15, 7.5))
    t = rk4.time
    axes[0, 0].plot(t, rk4["body3.out.y"], label="mixed MSTMM + RK4")
    axes[0, 0].plot(t[::40], connected_ref[::40], "kx", label="global Lagrange")
    axes[0, 0].set(xlabel="t [s]", ylabel="y [m]", title="connected point (Fig. 9.12)")
    for k in (1, 2, 3):
        i = names.index(f"beam1.n{k}_uy")
        axes[0, 1].plot(t, q[:, i] * 1e3, label=f"node {k}")
        axes[0, 1].plot(t[::40], q_ref[::40, i] * 1e3, "kx")
    axes[0, 1].set(xlabel="t [s]", ylabel="transverse displacement [mm]", title="beam nodes 1-3, frame axes "
                   "(Figs. 9.13-9.15)")
    for body in ("body3", "body5"):
        i = names.index(f"{body}.theta")
        axes[0, 2].plot(t, q[:, i], label=f"{body} TMM")
        axes[0, 2].plot(t[::40], q_ref[::40, i], "kx")
    axes[0, 2].set(xlabel="t [s]", ylabel="azimuth [rad]", title="bodies 3 and 5 (Figs. 9.16-9.17)")
    axes[1, 0].plot(t[samples], force[:, 1], label="q_y mixed")
    axes[1, 0].plot(t[samples][::4], force_ref[::4, 1], "kx", label="q_y global")
    axes[1, 0].plot(t[samples], force[:, 0], label="q_x mixed")
    axes[1, 0].set(xlabel="t [s]", ylabel="force [N]", title="interaction body 3 -> beam 1 (Fig. 9.18)")
    axes[1, 1].semilogy(t, np.max(np.abs(q - q_ref), axis=1) + 1e-17, label="RK4 vs global RK4 (same step)")
    axes[1, 1].semilogy(t, np.max(np.abs(q[:, angles] - q_tight[:, angles]), axis=1) + 1e-17,
                        label="RK4 vs global DOP853")
    axes[1, 1].semilogy(t, np.max(np.abs(q_nm[:, angles] - q_tight[:, angles]), axis=1) + 1e-17,
                        label="Newmark DT-TMM vs global DOP853")
    axes[1, 1].set(xlabel="t [s]", ylabel="max coordinate error", title=f"h = {STEP * 1e3:g} ms")
    for k in np.linspace(0, q.shape[0] - 1, 7).astype(int):
        pts = ref.hinge_positions(q[k])
        axes[1, 2].plot(pts[:, 0], pts[:, 1], "o-", ms=3)
    axes[1, 2].set(xlabel="x [m]", ylabel="y [m]", title="hinges at 7 instants", aspect="equal")
    for ax in axes.flat[:5]:
        ax.legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    same = same_step(STEP)
    return {
        "accuracy": [
            coordinates_accuracy(error_same, BOUND_SAME_INTEGRATOR, "angles, FE node displacements", STEP,
                                 "issue 16 / task H5: mixed model vs global reference to 1e-8 with the same integrator"),
            accuracy("interaction force vs global model", error_force, "relative", BOUND_FORCE,
                     f"max |F_TMM - F_global| / max |F_global| of the force of body 3 on beam 1 (global x, y), {same}; "
                     "F_global = momentum rate of the beam and bodies 4, 5 minus their weight",
                     source="issue 16: interaction force of seed 001 Fig. 9.18; same bound as the coordinates"),
        ],
        "connected_point_error_m": error_connected,
        "largest_tip_deflection_m": float(np.max(np.abs(q[:, names.index(f"beam1.n{BEAM['elements']}_uy")]))),
        "rk4_angle_error_vs_dop853_rad": error_rk4_tight,
        "newmark_angle_error_vs_dop853_rad": error_newmark_tight,
        "newton_iterations_mean": newmark.info.get("newton_iterations_mean"),
        "wall_time_s": rk4.info["wall_time_s"],
        "newmark_wall_time_s": newmark.info["wall_time_s"],
        "reference_rk4_wall_time_s": reference_rk4_time,
        "reference_dop853_wall_time_s": reference_tight_time,
        "parameters": {"masses_kg": MASSES, "link_length_m": LINK, "beam": BEAM, "rayleigh": RAYLEIGH,
                       "step_s": STEP, "t_final_s": t_final,
                       "initial_angles_rad": INITIAL_ANGLE},
    }
