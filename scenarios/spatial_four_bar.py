"""Spatial four-bar R-U-S-R closed by a spherical cut joint (issue 16 item 2, spatial part).

Own parameters: slender box links (0.03 m square section) crank 0.2 m / 0.4 kg hanging on a revolute about world x at
the origin, coupler 0.55 m / 1.0 kg on a universal joint (axes z, then y, of the crank's axes) at the crank's tip,
rocker 0.4 m / 0.8 kg hanging on a revolute about world y at (0.5, 0.2, 0) m; gravity 9.81 m/s^2 along -z.  The
spherical cut ``s3`` joins the coupler's tip to the rocker's (one degree of freedom; the hinge axes are skew, the
motion is genuinely spatial).  Start: crank at 0.1 rad with 3 rad/s, the rest assembled
(:meth:`SpatialKinematicLoopModel.consistent_state`).  2 s (quick: 0.05 s).

ctmm: the spatial articulated sweep with the cut force as boundary unknowns (:mod:`ctmm.spatial.closed_loops`), RK4
at 1 ms with projection and DOP853 (1e-11) with Baumgarte only.  Reference: a Newton-Euler DAE in absolute
coordinates with every joint as constraint rows (:mod:`ctmm.reference.spatial_loop_dae`, DOP853 at 1e-12), and its
small-oscillation frequency about the hanging equilibrium by Lagrange on the constraint manifold.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import ctmm
import ctmm.spatial as sp
from ctmm.ops import NUMPY
from ctmm.reference.spatial_loop_dae import DaeBody, DaeJoint, SpatialLoopDAE
from ctmm.scenario import accuracy
from ctmm.spatial.body_forms import SpatialScene
from ctmm.spatial.closed_loop_linear import equilibrium, natural_frequencies
from ctmm.spatial.closed_loop_time import simulate_spatial_loops
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

from .planar_common import save_figure

NAME = "spatial_four_bar"
DESCRIPTION = ("Spatial four-bar R-U-S-R closed by a spherical cut joint (boundary unknowns): motion, cut force, drift, "
               "energy and frequency vs a Newton-Euler DAE")
WIDTH = 0.03                                                    # link section [m]
START = ({"h1.angle": 0.1, "h4.angle": 0.1}, {"h1.angle_rate": 3.0})    # crank angle [rad] and rate [rad/s]
DOWN = np.diag([1.0, -1.0, -1.0])                              # joint frames that hang the links along -z


def rod(name: str, mass: float, length: float, direction: int = 0, width: float = WIDTH) -> sp.SpatialBody:
    """A slender box of ``length`` along body axis ``direction`` from the origin (centre of mass at mid-length,
    point ``"tip"`` at the end)."""
    moments = np.full(3, mass * (length ** 2 + width ** 2) / 12.0)
    moments[direction] = mass * 2 * width ** 2 / 12.0
    tip = np.eye(3)[direction] * length
    return sp.SpatialBody(name, mass, np.diag(moments), center_of_mass=tip / 2, points={"tip": tip})


def mechanism(baumgarte: float = 20.0) -> SpatialKinematicLoopModel:
    """The R-U-S-R linkage: the tree (crank, coupler; rocker) and the spherical cut ``s3``."""
    tree = sp.SpatialModel("spatial_four_bar", [
        rod("crank", 0.4, 0.2, direction=2),
        sp.Revolute(name="h1", parent=None, child="crank", axis=(1, 0, 0), rotation=DOWN, actuated=True),
        rod("coupler", 1.0, 0.55),
        sp.Universal(name="u2", parent="crank", point="tip", child="coupler", axis1=(0, 0, 1), axis2=(0, 1, 0)),
        rod("rocker", 0.8, 0.4, direction=2),
        sp.Revolute(name="h4", parent=None, point=(0.5, 0.2, 0.0), child="rocker", axis=(0, 1, 0), rotation=DOWN)])
    return SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="s3", parent="rocker", point="tip",
                                                            child="coupler", child_point="tip")], baumgarte=baumgarte)


def start(loop: SpatialKinematicLoopModel) -> tuple[np.ndarray, np.ndarray]:
    """The assembled start ``(q0, v0)``: the crank's angle and rate held."""
    return loop.consistent_state(*START, keep=["h1"])


def dae_of(loop: SpatialKinematicLoopModel, baumgarte: float = 10.0) -> SpatialLoopDAE:
    """The DAE of a loop model of rigid bodies on revolute, universal, spherical and free joints: every tree joint
    and cut joint (spherical, revolute, universal, prismatic with its roll reference ``normal`` / ``parent_normal``)
    as constraint rows, points from the centres of mass (data only: no ctmm.spatial code runs)."""
    tree = loop.tree
    names = [b.name for b in tree.bodies]

    def local(body: str | None, point) -> tuple[int, np.ndarray]:
        if body is None:
            return -1, np.asarray(point, float)
        b = tree.bodies[names.index(body)]
        return names.index(body), (b.points[point] if isinstance(point, str) else np.asarray(point, float)) \
            - b.center_of_mass

    joints = []
    for joint in tree.joints:
        parent, p_point = local(joint.parent, joint.point)
        child, c_point = local(joint.child, "origin")
        R_J = np.eye(3) if joint.rotation is None else np.asarray(joint.rotation)
        if joint.kind == "revolute":
            joints.append(DaeJoint(joint.name, "revolute", parent, p_point, child, c_point,
                                   parent_axis=R_J @ joint.axis, child_axis=joint.axis))
        elif joint.kind == "universal":
            joints.append(DaeJoint(joint.name, "universal", parent, p_point, child, c_point,
                                   parent_axis=R_J @ joint.axis1, child_axis=joint.axis2))
        elif joint.kind == "spherical":
            joints.append(DaeJoint(joint.name, "ball", parent, p_point, child, c_point))
        elif joint.kind != "free":                       # a free joint: no rows
            raise ValueError(f"dae_of: joint kind {joint.kind!r} is not converted")
    for cut in loop.cuts:
        parent, p_point = local(cut.parent, cut.point)
        child, c_point = local(cut.child, cut.child_point)
        joints.append(DaeJoint(cut.name, {"spherical": "ball"}.get(cut.kind, cut.kind), parent, p_point, child,
                               c_point, parent_axis=cut.parent_axis, child_axis=cut.axis,
                               parent_normal=cut.parent_normal, child_normal=cut.normal))   # None unless prismatic
    return SpatialLoopDAE([DaeBody(b.name, b.mass, b.inertia) for b in tree.bodies], joints, gravity=tree.gravity,
                          baumgarte=baumgarte)


def poses(loop: SpatialKinematicLoopModel, q, v) -> tuple[list, list, list, list]:
    """Centre-of-mass positions [m], rotation matrices, centre-of-mass velocities [m/s] and angular velocities
    [rad/s] (world) of the tree's bodies at ``(q, v)`` (the DAE's start; its own rows check it)."""
    states = SpatialScene(loop.tree).terms(NUMPY, np.asarray(q, float)[None], np.asarray(v, float)[None])[2]
    x, R, vc, w = [], [], [], []
    for body, s in zip(loop.tree.bodies, states):
        rotation = np.asarray(s.rotation)[0]
        arm = rotation @ body.center_of_mass
        omega = np.asarray(s.omega).reshape(-1, 3)[0]
        x.append(np.asarray(s.origin).reshape(-1, 3)[0] + arm)
        R.append(rotation)
        vc.append(np.asarray(s.velocity).reshape(-1, 3)[0] + np.cross(omega, arm))
        w.append(omega)
    return x, R, vc, w


def _errors(loop, run, dae, Y) -> tuple[np.ndarray, np.ndarray]:
    """Per stored time: the largest rotation-matrix entry difference [rad] and centre-of-mass difference [m]."""
    angle, position = [], []
    for k in range(len(run.t)):
        x, R, _, _ = poses(loop, run.q[k], run.v[k])
        angle.append(max(np.abs(a - b).max() for a, b in zip(R, dae.rotations(Y[k]))))
        position.append(max(np.abs(a - b).max() for a, b in zip(x, dae.split(Y[k])[0])))
    return np.array(angle), np.array(position)


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    loop = mechanism()
    q0, v0 = start(loop)
    t_final, dt = (0.05 if quick else 2.0), 1e-3
    rk4 = simulate_spatial_loops(loop, q0, v0, t_final=t_final, dt=dt)
    dop = simulate_spatial_loops(loop, q0, v0, t_final=t_final, dt=0.01, method="DOP853", rtol=1e-11, atol=1e-12)
    dae = dae_of(loop)
    y0 = dae.state(*poses(loop, q0, v0))
    started = time.perf_counter()
    _, Y = dae.simulate(y0, rk4.t)
    reference_wall = time.perf_counter() - started
    _, Y_dop = dae.simulate(y0, dop.t)
    angle_rk4, position_rk4 = _errors(loop, rk4, dae, Y)
    angle_dop, _ = _errors(loop, dop, dae, Y_dop)
    every = max(1, len(rk4.t) // 40)
    forces_dae = np.array([dae.accelerations(Y[k])[1][-3:] for k in range(0, len(rk4.t), every)])
    force_scale = float(np.max(np.abs(forces_dae)))
    force_error = float(np.max(np.abs(rk4.cut_force[::every, 0] - forces_dae))) / force_scale
    energy = np.asarray(sp.energy(loop.tree, rk4.q, rk4.v))
    energy_drift = float(np.max(np.abs(energy - energy[0])) / np.max(np.abs(energy)))
    q_eq = equilibrium(loop, q0)
    omega = float(natural_frequencies(loop, q_eq)[0])
    omega_dae = float(dae.natural_frequencies(dae.state(*poses(loop, q_eq, np.zeros_like(v0))))[0])
    frequency_error = abs(omega / omega_dae - 1.0)

    fig, axes = plt.subplots(2, 2, figsize=(12, 8))
    for name in ("h1.angle", "h4.angle", "u2.angle1", "u2.angle2"):
        k = loop.tree.coordinates.index(name)
        axes[0, 0].plot(rk4.t, rk4.q[:, k], label=name)
    axes[0, 0].set(xlabel="t [s]", ylabel="tree coordinate [rad]", title="R-U-S-R motion (ctmm RK4 1 ms)")
    axes[0, 0].legend(fontsize="small")
    axes[0, 1].semilogy(rk4.t, angle_rk4 + 1e-17, label="RK4 1 ms + projection")
    axes[0, 1].semilogy(dop.t, angle_dop + 1e-17, label="DOP853 1e-11, Baumgarte")
    axes[0, 1].set(xlabel="t [s]", ylabel="max |R_ctmm - R_DAE| over bodies [rad]", title="error vs Newton-Euler DAE")
    axes[0, 1].legend(fontsize="small")
    for i, label in enumerate("xyz"):
        axes[1, 0].plot(rk4.t, rk4.cut_force[:, 0, i], color=f"C{i}", label=f"ctmm, {label}")
        axes[1, 0].plot(rk4.t[::every], forces_dae[:, i], "o", ms=3, color=f"C{i}", label=f"DAE, {label}")
    axes[1, 0].set(xlabel="t [s]", ylabel="cut force on the coupler [N]", title="boundary unknowns")
    axes[1, 0].legend(fontsize="x-small", ncol=2)
    axes[1, 1].semilogy(rk4.t, rk4.drift + 1e-17, label="RK4 + projection")
    axes[1, 1].semilogy(dop.t, dop.drift + 1e-17, label="DOP853, Baumgarte")
    axes[1, 1].set(xlabel="t [s]", ylabel="drift max |Phi| [m]", title=f"omega = {omega:.6f} rad/s (DAE {omega_dae:.6f})")
    axes[1, 1].legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    source = "docs/closed_loops.md §8 (task: < 1e-8 rad with RK4 at a small step)"
    return {
        "accuracy": [
            accuracy("body rotation error vs Newton-Euler DAE", float(angle_rk4.max()), "rad", 1e-8,
                     "max over the run and the bodies of the largest entry of R_ctmm - R_DAE (RK4 1 ms, projection)",
                     source=source),
            accuracy("centre-of-mass error vs DAE", float(position_rk4.max()), "m", 1e-8,
                     "max over the run and the bodies of |x_ctmm - x_DAE| (RK4 1 ms)", source=source),
            accuracy("cut force error vs DAE", force_error, "relative", 1e-6,
                     "max |f_ctmm - mu_DAE| / max |mu_DAE| of the cut s3, 40 samples", source=source),
            accuracy("constraint drift", float(max(rk4.drift.max(), dop.drift.max())), "m", 1e-9,
                     "max |Phi| of the cut, RK4 with projection and DOP853 with Baumgarte", source=source),
            accuracy("energy drift", energy_drift, "relative", 1e-6,
                     "max |E - E0| / max |E| of the tree's energy (cut forces do no work), RK4 1 ms", source=source),
            accuracy("natural frequency vs DAE", frequency_error, "relative", 1e-6,
                     "|omega_ctmm / omega_DAE - 1| about the hanging equilibrium (DAE: Lagrange on its manifold)",
                     source=source)],
        "angle_max_error_dop853_rad": float(angle_dop.max()),
        "natural_frequency_rad_s": omega, "natural_frequency_dae_rad_s": omega_dae,
        "max_cut_force_N": force_scale,
        "wall_time_s": rk4.wall_time_s, "dop853_wall_time_s": dop.wall_time_s,
        "reference_wall_time_s": reference_wall,
        "evaluations_rk4": rk4.n_evaluations, "evaluations_dop853": dop.n_evaluations,
        "t_final_s": t_final, "dt_s": dt, "q0": q0.tolist(), "v0": v0.tolist(),
        "parameters": {"masses_kg": {"crank": 0.4, "coupler": 1.0, "rocker": 0.8},
                       "lengths_m": {"crank": 0.2, "coupler": 0.55, "rocker": 0.4}, "section_m": WIDTH,
                       "rocker_pivot_m": [0.5, 0.2, 0.0], "gravity_m_s2": 9.81, "baumgarte_1_s": loop.baumgarte},
    }
