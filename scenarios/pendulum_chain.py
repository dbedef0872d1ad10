"""Triple pendulum with an elastic hinge: acceleration TMM + RK4 and implicit DT-TMM vs Lagrange.

System (FORMULAS section 3.5, check c07): three rigid links, (m, J_C, r_IO, r_IC) =
(1, .08, [1, 0], [.5, .05]), (.7, .05, [.8, .1], [.4, 0]), (.5, .03, [.6, 0], [.35, -.02]);
g = -9.81 y; ground hinge smooth, hinge 2 spring k = 40 N m/rad with damper c = 0.3 N m s/rad
and rest angle 0.2 rad, hinge 3 smooth; theta(0) = (.3, .9, -.4) rad (absolute), at rest.
Published check values (FORMULAS 3.5): Newmark angle error at T = 1 s vs DOP853 =
1.67e-3, 4.19e-4, 1.05e-4 rad for h = 4, 2, 1 ms.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import ctmm
from ctmm.planar import Pinned, PlanarModel, RigidBody, SmoothHinge, SpringDamperHinge
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.signal_results import coordinate_histories, energy_history

from .planar_common import angle_accuracy, plot_angle_errors, save_figure

NAME = "pendulum_chain"
DESCRIPTION = ("Triple pendulum with an elastic hinge (FORMULAS c07): TMM + RK4 and implicit "
               "DT-TMM (Newmark, Newton) against a tight Lagrange reference; Newmark error ladder "
               "against the published 1.67e-3 / 4.19e-4 / 1.05e-4 rad")
PUBLISHED_NEWMARK = {0.004: 1.67e-3, 0.002: 4.19e-4, 0.001: 1.05e-4}


def model(damping: float = 0.3) -> PlanarModel:
    hinge = SpringDamperHinge("k2", stiffness=40.0, damping=damping, rest_angle=0.2)
    return PlanarModel.chain("c07", [
        Pinned("o"),
        RigidBody("b1", mass=1.0, inertia=0.08, center_of_mass=(0.5, 0.05), outboard=(1.0, 0.0)),
        hinge,
        RigidBody("b2", mass=0.7, inertia=0.05, center_of_mass=(0.4, 0.0), outboard=(0.8, 0.1)),
        SmoothHinge("h3"),
        RigidBody("b3", mass=0.5, inertia=0.03, center_of_mass=(0.35, -0.02), outboard=(0.6, 0.0))])


def run(output_dir: Path, quick: bool = False, results: dict | None = None) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t_final = 0.5 if quick else 3.0
    q0, v0 = np.array([0.3, 0.9, -0.4]), np.zeros(3)
    sys_ = model()
    h = 1e-3
    t_grid = np.linspace(0.0, t_final, int(round(t_final / h)) + 1)
    start = time.perf_counter()
    ref = PlanarLagrange(sys_).simulate(q0, v0, t_final, t_eval=t_grid, rtol=1e-12, atol=1e-12)
    ref_time = time.perf_counter() - start
    q_ref = ref.y[:3].T
    rk4 = ctmm.simulate(sys_, t_final, h, method="rk4", x0=q0, v0=v0)
    newmark = ctmm.simulate(sys_, t_final, h, method="newmark", x0=q0, v0=v0)
    q_rk4, q_nm = coordinate_histories(rk4)[0], coordinate_histories(newmark)[0]
    err_rk4 = np.max(np.abs(q_rk4 - q_ref), axis=1)
    err_nm = np.max(np.abs(q_nm - q_ref), axis=1)
    # Newmark ladder at T = 1 s (published values)
    ref1 = PlanarLagrange(sys_).simulate(q0, v0, 1.0, t_eval=[1.0], rtol=1e-12, atol=1e-12).y[:3, -1]
    ladder = {}
    for dt in list(PUBLISHED_NEWMARK)[: 2 if quick else 3]:
        sim = ctmm.simulate(sys_, 1.0, dt, method="newmark", x0=q0, v0=v0)
        ladder[f"{dt:g}"] = {"error_rad": float(np.max(np.abs(coordinate_histories(sim)[0][-1] - ref1))),
                             "published_rad": PUBLISHED_NEWMARK[dt],
                             "newton_iterations_mean": sim.info["newton_iterations_mean"]}
    # energy of the undamped variant
    undamped = model(damping=0.0)
    e_rk4 = energy_history(ctmm.simulate(undamped, t_final, h, method="rk4", x0=q0, v0=v0))
    e_nm = energy_history(ctmm.simulate(undamped, t_final, h, method="newmark", x0=q0, v0=v0))
    e0 = e_rk4[0]

    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for i, name in enumerate(sys_.coordinates):
        axes[0].plot(ref.t, q_ref[:, i], "k-", lw=2.5, alpha=0.3)
        axes[0].plot(rk4.time, rk4[name], "--", label=f"{name} TMM+RK4")
    axes[0].set(xlabel="t [s]", ylabel="absolute angle [rad]", title="grey: Lagrange DOP853")
    axes[0].legend(fontsize="small")
    plot_angle_errors(axes[1], rk4, err_rk4, newmark, err_nm, "max angle error [rad]", ", h = 1 ms")
    axes[2].plot(rk4.time, e_rk4 - e0, label="RK4 (undamped variant)")
    axes[2].plot(rk4.time, e_nm - e0, label="Newmark (undamped variant)")
    axes[2].set(xlabel="t [s]", ylabel="E(t) - E(0) [J]")
    axes[2].legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    if results is not None:                      # ctmm run --save / --animate
        results.update(rk4=rk4, newmark=newmark)
    return {
        "accuracy": angle_accuracy(rk4.time, err_rk4, "over the links, h = 1 ms, reference DOP853 rtol = atol = 1e-12"),
        "angle_max_error_whole_run_rad": float(err_rk4.max()),
        "newmark_max_error": float(err_nm.max()),
        "newmark_ladder_at_1s": ladder,
        "newton_iterations_mean": newmark.info["newton_iterations_mean"],
        "wall_time_s": rk4.info["wall_time_s"],
        "newmark_wall_time_s": newmark.info["wall_time_s"],
        "reference_wall_time_s": ref_time,
        "energy_drift": {"rk4_J": float(np.max(np.abs(e_rk4 - e0))),
                         "newmark_J": float(np.max(np.abs(e_nm - e0))),
                         "definition": "max |E(t) - E(0)| of the undamped variant (c = 0)"},
    }
