"""Spatial chain (seed 002 section 7.9.3): four rigid links on spherical and revolute joints falling
under gravity from a tilted, spinning start.

Parameters (ours; the seed's numbers were lost): links of mass 1.0, 0.8, 0.6, 0.5 kg and length
0.6, 0.5, 0.4, 0.4 m (slender, principal inertias m l^2 / 12 about the cross axes and 1e-3 kg m^2
about the link axis), centre of mass mid-link, link axes along -z in the rest pose; joints: ground
spherical, revolute about x, spherical, revolute about (0, 1, 1)/sqrt 2; gravity 9.81 m/s^2 along -z;
start: root tilted 0.5 rad about (1, 1, 0)/sqrt 2, joint angles 0.3 and -0.4 rad, second spherical
tilted 0.3 rad about y, root spin 2 rad/s about z.  Step 1 ms; 2 s (quick: 0.25 s, reference
at half the step instead of a quarter).

ctmm's spatial articulated sweep is integrated by RK4 and by scipy's DOP853; the reference is the
global Newton–Euler model (``ctmm/reference/spatial_tree.py``, its own RK4 at a quarter step).  No
DT-TMM (Newmark) scheme exists for spatial models yet, so none is reported.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

import ctmm.spatial as sp
from ctmm.scene_files import load_scene

from .planar_common import save_figure
from .spatial_common import scenario_runs, scenario_summary

NAME = "spatial_chain"
DESCRIPTION = ("Four links on spherical and revolute joints falling in space: ctmm RK4 and DOP853 "
               "against the global Newton-Euler reference")
MASSES = (1.0, 0.8, 0.6, 0.5)
LENGTHS = (0.6, 0.5, 0.4, 0.4)


def link(name: str, mass: float, length: float) -> sp.SpatialBody:
    """A slender link along -z: centre of mass mid-link, outboard point ``tip``."""
    cross = mass * length ** 2 / 12
    return sp.SpatialBody(name, mass, (cross, cross, 1e-3), (0.0, 0.0, -length / 2), {"tip": (0.0, 0.0, -length)})


def model() -> sp.SpatialModel:
    """The chain, built from its scene file ``scenarios/files/spatial_chain.toml`` (the one source)."""
    return load_scene(Path(__file__).resolve().parent / "files" / "spatial_chain.toml").system


def initial_state() -> tuple[np.ndarray, np.ndarray]:
    """``(q0, v0)`` in ctmm layout (quaternions scalar first)."""
    tilt = 0.5 * np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    q1 = np.r_[np.cos(0.25), np.sin(0.25) * tilt / 0.5]
    q3 = np.r_[np.cos(0.15), 0.0, np.sin(0.15), 0.0]
    q0 = np.r_[q1, 0.3, q3, -0.4]
    v0 = np.r_[0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    return q0, v0


def run(output_dir: Path, quick: bool = False, results: dict | None = None) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    chain = model()
    q0, v0 = initial_state()
    runs = scenario_runs(chain, q0, v0, quick)
    t = runs["reference"].time
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
    for i, axis in enumerate("xyz"):
        axes[0].plot(t, runs["omega_reference"][:, -1, i], color=f"C{i}", label=f"Newton-Euler, {axis}")
        axes[0].plot(t[::25], runs["omega_rk4"][::25, -1, i], "o", ms=3, color=f"C{i}", label=f"ctmm RK4, {axis}")
    axes[0].set(xlabel="t [s]", ylabel="link 4 angular velocity, world axes [rad/s]")
    axes[0].legend(fontsize="x-small", ncol=2)
    for key, label in (("rk4", "ctmm RK4"), ("dop853", "ctmm DOP853 1e-10")):
        error = np.abs(runs[f"omega_{key}"] - runs["omega_reference"]).max(axis=(1, 2))
        axes[1].semilogy(t, error + 1e-17, label=label)
    axes[1].set(xlabel="t [s]", ylabel="max |omega - omega_ref| over links and axes [rad/s]")
    axes[1].legend(fontsize="small")
    walls = [runs["rk4_wall_time_s"], runs["dop853_wall_time_s"], runs["reference_wall_time_s"]]
    axes[2].bar(["ctmm RK4", "ctmm DOP853", f"reference RK4 (h/{runs['refinement']})"], walls)
    axes[2].set(ylabel="wall time [s]")
    save_figure(fig, output_dir, NAME)
    if results is not None:                      # ctmm run --save / --animate
        results.update(rk4=runs["rk4"])
    return scenario_summary(runs, len(MASSES) - 1, "link 4", {"masses_kg": MASSES, "lengths_m": LENGTHS,
                            "dt_s": runs["dt"], "t_final_s": runs["t_final"], "q0": q0, "v0": v0,
                            "gravity_m_s2": 9.81})
