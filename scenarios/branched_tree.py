"""Branched tree: a pinned trunk carrying two two-link branches (seed 002 section 7.4.2).

The trunk is a rigid body with two outboard ends; each branch is a chain of two links, one
branch joined by smooth hinges, the other by rotary springs.  The acceleration TMM assembles
the branches leaves-to-root in one O(n) sweep.  Reference: Lagrange equations of the same tree
(global mass matrix, DOP853 at 1e-12).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import ctmm
from ctmm.planar import PlanarModel
from ctmm.reference.planar_lagrange import PlanarLagrange, newton_euler_kkt
from ctmm.scene_files import load_scene
from ctmm.signal_results import coordinate_histories, energy_history
from ctmm.planar import solve_instant

from .planar_common import angle_accuracy, plot_angle_errors, save_figure

NAME = "branched_tree"
DESCRIPTION = ("Pinned trunk with two two-link branches (smooth and elastic hinges): TMM + RK4 "
               "and DT-TMM on a tree against the Lagrange tree model")


def model() -> PlanarModel:
    """The tree, built from its scene file ``scenarios/files/branched_tree.toml`` (the one source)."""
    return load_scene(Path(__file__).resolve().parent / "files" / "branched_tree.toml").system


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tree = model()
    n = tree.n_coordinates
    q0 = np.array([0.4, 1.0, 0.2, 0.0, -0.6])
    v0 = np.zeros(n)
    t_final = 1.0 if quick else 3.0
    h = 1e-3
    t_grid = np.linspace(0.0, t_final, int(round(t_final / h)) + 1)
    start = time.perf_counter()
    ref = PlanarLagrange(tree).simulate(q0, v0, t_final, t_eval=t_grid, rtol=1e-12, atol=1e-12)
    ref_time = time.perf_counter() - start
    q_ref = ref.y[:n].T
    rk4 = ctmm.simulate(tree, t_final, h, method="rk4", x0=q0, v0=v0)
    newmark = ctmm.simulate(tree, t_final, h, method="newmark", x0=q0, v0=v0)
    t_rk4, (q_rk4, v_rk4) = rk4.time, coordinate_histories(rk4)
    err_rk4 = np.max(np.abs(q_rk4 - q_ref), axis=1)
    err_nm = np.max(np.abs(coordinate_histories(newmark)[0] - q_ref), axis=1)
    energy_rk4 = energy_history(rk4)
    energy_nm = energy_history(newmark)
    # instantaneous joint forces vs the global Newton-Euler (KKT) solve along the trajectory
    force_err = 0.0
    for k in range(0, len(t_rk4), max(1, len(t_rk4) // 20)):
        tmm = solve_instant(tree, q_rk4[k], v_rk4[k], t_rk4[k])
        kkt = newton_euler_kkt(tree, q_rk4[k], v_rk4[k], t_rk4[k])
        force_err = max(force_err, float(np.max(np.abs(tmm.joint_force - kkt.joint_force))))

    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
    for k in np.linspace(0, len(t_rk4) - 1, 7).astype(int):
        pts = tree.points(q_rk4[k], v_rk4[k], t_rk4[k])
        r = pts["inboard"]
        for j, body in enumerate(tree.body_names):
            theta = pts["theta"][j]
            rot = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
            for end in tree.ends[j].values():
                tip = r[j] + rot @ end
                axes[0].plot([r[j, 0], tip[0]], [r[j, 1], tip[1]], "-", color=f"C{j}",
                             alpha=0.25 + 0.75 * k / len(t_rk4))
    axes[0].set(aspect="equal", title="configurations (darker = later)", xlabel="x [m]",
                ylabel="y [m]")
    plot_angle_errors(axes[1], rk4, err_rk4, newmark, err_nm, "max angle error vs Lagrange [rad]")
    axes[2].plot(t_rk4, energy_rk4 - energy_rk4[0], label="RK4")
    axes[2].plot(newmark.time, energy_nm - energy_nm[0], label="Newmark")
    axes[2].set(xlabel="t [s]", ylabel="E(t) - E(0) [J]")
    axes[2].legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    return {
        "accuracy": angle_accuracy(t_rk4, err_rk4, "over the coordinates, h = 1 ms, Lagrange tree model DOP853 1e-12"),
        "angle_max_error_whole_run_rad": float(err_rk4.max()),
        "newmark_max_error": float(err_nm.max()),
        "newton_iterations_mean": newmark.info["newton_iterations_mean"],
        "joint_force_max_difference_vs_kkt_N": force_err,
        "wall_time_s": rk4.info["wall_time_s"],
        "newmark_wall_time_s": newmark.info["wall_time_s"],
        "reference_wall_time_s": ref_time,
        "energy_drift": {"rk4_J": float(np.max(np.abs(energy_rk4 - energy_rk4[0]))),
                         "newmark_J": float(np.max(np.abs(energy_nm - energy_nm[0]))),
                         "definition": "max |E(t) - E(0)| (undamped tree)"},
    }
