"""Branch system (seed 001 Figs. 9.32–9.35): a pinned trunk carrying two branches, six rigid bodies on
spherical, universal and revolute joints moving in space; the angular velocity of element 5 about
x, y and z (world axes), ctmm against the Newton–Euler model.

Parameters (ours; the seed's numbers were lost): element 1 (trunk, 2.0 kg, 0.8 m) on a ground
spherical joint; element 2 (1.0 kg, 0.5 m) on a universal joint (x then y) at the trunk's left end
(0.3, 0, -0.8) m; element 3 (0.8 kg, 0.4 m) on a revolute joint about y at element 2's tip;
element 4 (1.2 kg, 0.6 m) on a spherical joint at the trunk's right end (-0.3, 0, -0.8) m;
element 5 (0.7 kg, 0.5 m) on a revolute joint about (1, 1, 0)/sqrt 2 at element 4's tip; element 6
(0.5 kg, 0.4 m) on a revolute joint about x at element 5's tip.  Links are slender along -z (cross
inertias m l^2 / 12, axial 1e-3 kg m^2, centre of mass mid-link); gravity 9.81 m/s^2 along -z.
Start: trunk tilted 0.4 rad about x and spinning 1.5 rad/s about z, universal angles (0.5, -0.3) rad,
revolute angles 0.6, -0.8, 0.4 rad, element 4 tilted 0.5 rad about y.  Step 1 ms; 0.5 s (quick: 0.25 s,
reference at half the step instead of a quarter).  The run stops at 0.5 s because at about 0.53 s the
slender outer elements whip (element 5 reaches 45 rad/s about z by 1.9 s): over 2 s, RK4 at 1 ms departs
from the reference by up to 1.5e-4 rad/s and DOP853 by 5e-7 rad/s (of the order of the reference's own
RK4 error at 0.25 ms), both above the 1e-6 rad/s bound for RK4, which is not widened.

ctmm's spatial articulated sweep (one O(n) sweep over the tree) is integrated by RK4 and by scipy's
DOP853; the reference is the global Newton–Euler model (``ctmm/reference/spatial_tree.py``, its own
RK4 at a finer step).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

import ctmm.spatial as sp
from ctmm.scene_files import load_scene

from .planar_common import save_figure
from .spatial_common import scenario_runs, scenario_summary

NAME = "branch_system"
DESCRIPTION = ("Six-body branched tree in space: angular velocity of element 5 about x, y, z, ctmm RK4 "
               "and DOP853 against the global Newton-Euler reference")
FULL_DURATION_S = 0.5   # [s]: after ~0.53 s the tree whips (see the module docstring)
BODIES = (("e1", 2.0, 0.8), ("e2", 1.0, 0.5), ("e3", 0.8, 0.4), ("e4", 1.2, 0.6), ("e5", 0.7, 0.5), ("e6", 0.5, 0.4))


def model() -> sp.SpatialModel:
    """The tree, built from its scene file ``scenarios/files/branch_system.toml`` (the one source)."""
    return load_scene(Path(__file__).resolve().parent / "files" / "branch_system.toml").system


def initial_state() -> tuple[np.ndarray, np.ndarray]:
    """``(q0, v0)`` in ctmm layout (quaternions scalar first)."""
    q0 = np.r_[np.cos(0.2), np.sin(0.2), 0.0, 0.0, 0.5, -0.3, 0.6, np.cos(0.25), 0.0, np.sin(0.25), 0.0, -0.8, 0.4]
    v0 = np.zeros(11)
    v0[2] = 1.5
    return q0, v0


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    tree = model()
    q0, v0 = initial_state()
    runs = scenario_runs(tree, q0, v0, quick, t_final_full=FULL_DURATION_S)
    element = tree.body_index("e5")
    t = runs["reference"].time
    fig, axes = plt.subplots(1, 4, figsize=(17, 4.2))
    for i, axis in enumerate("xyz"):
        axes[i].plot(t, runs["omega_reference"][:, element, i], "k-", label="Newton-Euler")
        axes[i].plot(t[::25], runs["omega_rk4"][::25, element, i], "o", ms=3, label="ctmm RK4")
        axes[i].set(xlabel="t [s]", ylabel=f"element 5 angular velocity about {axis} [rad/s]")
        axes[i].legend(fontsize="small")
    for key, label in (("rk4", "ctmm RK4"), ("dop853", "ctmm DOP853 1e-10")):
        error = np.abs(runs[f"omega_{key}"][:, element] - runs["omega_reference"][:, element]).max(axis=1)
        axes[3].semilogy(t, error + 1e-17, label=label)
    axes[3].set(xlabel="t [s]", ylabel="element 5: max |omega - omega_ref| [rad/s]")
    axes[3].legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    return scenario_summary(runs, element, "element 5", {"bodies_name_kg_m": BODIES,
                            "dt_s": runs["dt"], "t_final_s": runs["t_final"],
                            "q0": q0, "v0": v0, "gravity_m_s2": 9.81})
