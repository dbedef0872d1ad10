"""Elastic-hinge body with a PD loop on its yaw (seed 001 Figs. 9.44-9.45): a rigid cuboid on a 6-DOF
elastic hinge to the ground, moving in space from an initial twist and tilt; theta_z (the body's
``angle_z``) without control, with a real-time PD ``Feedback`` and with the same PD delayed.

Parameters (ours; the seed's numbers were lost): body 4 kg, principal inertias (0.05, 0.08, 0.06)
kg m^2, centre of mass 0.25 m above the hinge; hinge translational stiffness 2e4 N/m (isotropic),
rotary stiffness [[40, 3, 0], [3, 55, 1], [0, 1, 30]] N m/rad, dampers 5 N s/m (translation) and
(0.2, 0.3, 0.1) N m s/rad; gravity 9.81 m/s^2 along -z; start: rotation 0.2 rad about z after 0.1 rad
about x (``R = Rx(0.1) Rz(0.2)``), yaw rate 1 rad/s.  Loop ``body.moment_z = -(kp angle_z + kd
omega_z)(t - tau)``, kp = 10 N m/rad, kd = 0.5 N m s/rad; the delayed run at half the delay margin
(rounded to whole steps: 20 ms).  RK4 at 1 ms over 3 s (quick: 0.5 s), on the generated RK4 where a C
compiler is present (the numpy RK4 to round-off, ``spatial_common.generated_rk4``).

Accuracy figures:

* theta_z of runs (a) and (b) against the global Newton-Euler reference (``ctmm/reference/spatial_tree``,
  its RK4 at a quarter step, quick: half).  The reference integrates its own equations of motion; the
  hinge law and the PD law are written in this module in the reference's coordinates: the hinge law as
  ctmm states it (``tau = -K [R^T d ; 2 w (x, y, z)] - C v``, docs/spatial.md §1 -- the reference's own
  elastic6 law uses the rotation vector and agrees only to first order), the loop's sensors from the
  reference kinematics (x-y-z angle from the rotation matrix, world angular velocity) and its world
  moment as the generalised force ``R^T m`` on the hinge's angular velocity (child axes).
* the delay margin of ``ctmm.stability.delay_margin`` on the linearised plant (loop left open) against
  the reference's characteristic determinant ``det(M s^2 + C s + K + b (kp + kd s) e^{-s tau} e^T)``
  (``M, C, K`` from ``spatial_tree.linearize``): the smallest singular value of that matrix at
  ``s = i omega_c``, ``tau = tau_c``, relative to its largest.
"""
from __future__ import annotations

import time
from pathlib import Path

import control
import numpy as np

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback, with_feedback
from ctmm.linearize import DelayedLoop, LinearizedSystem
from ctmm.reference import spatial_tree as ref
from ctmm.reference.spatial_kinematics import orientations, quaternion_matrix
from ctmm.scenario import accuracy
from ctmm.scene_files import load_scene
from ctmm.stability import delay_margin

from .planar_common import save_figure
from .spatial_common import generated_rk4

NAME = "spatial_elastic_hinge_control"
DESCRIPTION = ("Rigid body on a 6-DOF elastic hinge: theta_z without control, with a real-time and a delayed "
               "PD on a body moment; against the global Newton-Euler reference and its characteristic determinant")
KP, KD = 10.0, 0.5                       # N m/rad, N m s/rad
MASS, INERTIA, COM = 4.0, (0.05, 0.08, 0.06), (0.0, 0.0, 0.25)
ROTARY = np.array([[40.0, 3.0, 0.0], [3.0, 55.0, 1.0], [0.0, 1.0, 30.0]])
TRANSLATIONAL = 2.0e4
DAMPING = (5.0, 5.0, 5.0, 0.2, 0.3, 0.1)
GRAVITY = (0.0, 0.0, -9.81)
THETA_BOUND = 1e-6      # [rad]
MARGIN_BOUND = 1e-8     # [1]


def stiffness() -> np.ndarray:
    return np.block([[TRANSLATIONAL * np.eye(3), np.zeros((3, 3))], [np.zeros((3, 3)), ROTARY]])


def model() -> sp.SpatialModel:
    """The body on its hinge (no loop), built from the scene file ``scenarios/files/spatial_elastic_hinge_control.toml``
    (the one source of the plant; :func:`reference_tree` builds the reference from the constants above)."""
    return load_scene(Path(__file__).resolve().parent / "files" / "spatial_elastic_hinge_control.toml").plant


def initial_state() -> tuple[np.ndarray, np.ndarray]:
    """``(q0, v0)`` in ctmm layout ``(x, y, z, qw, qx, qy, qz)``, ``(vx, vy, vz, wx, wy, wz)``."""
    qx = np.array([np.cos(0.05), np.sin(0.05), 0.0, 0.0])
    qz = np.array([np.cos(0.1), 0.0, 0.0, np.sin(0.1)])
    w1, v1 = qx[0], qx[1:]
    w2, v2 = qz[0], qz[1:]
    quat = np.r_[w1 * w2 - v1 @ v2, w1 * v2 + w2 * v1 + np.cross(v1, v2)]       # qx * qz
    return np.r_[0.0, 0.0, 0.0, quat], np.r_[0.0, 0.0, 0.0, 0.0, 0.0, 1.0]


def loop(delay: float = 0.0) -> Feedback:
    return Feedback("yaw_pd", [("body.angle_z", KP), ("body.omega_z", KD)], "body.moment_z", gain=1.0,
                    delay=delay)


# ---------------------------------------------------------------- reference (global Newton-Euler)

def reference_tree(with_law: bool) -> ref.SpatialTree:
    """The body on an elastic6 joint; ``with_law``: the reference's own (rotation-vector) law."""
    law = dict(stiffness=stiffness(), damping=np.diag(DAMPING)) if with_law else {}
    body = ref.SpatialBody("body", -1, "elastic6", MASS, np.asarray(COM), np.diag(INERTIA), axes=np.zeros((0, 3)),
                           joint_position=np.zeros(3), joint_rotation=np.eye(3), **law)
    return ref.SpatialTree((body,), gravity=np.asarray(GRAVITY))


def to_reference(q: np.ndarray) -> np.ndarray:
    return np.r_[q[:3], q[4:7], q[3]]


def reference_theta_z(tree: ref.SpatialTree, q: np.ndarray) -> float:
    """x-y-z angle ``a_z`` of ``R = Rx Ry Rz``: ``R[0,1] = -cos a_y sin a_z``, ``R[0,0] = cos a_y cos a_z``."""
    return theta_z(orientations(tree, q, np.zeros(tree.nv)).rotation[0])


def theta_z(rotation: np.ndarray) -> float:
    """x-y-z angle ``a_z`` [rad] of a rotation matrix ``R = Rx Ry Rz`` (:func:`reference_theta_z`)."""
    return float(np.arctan2(-rotation[0, 1], rotation[0, 0]))


def reference_law(tree: ref.SpatialTree, controlled: bool):
    """Generalised forces of the hinge law (ctmm's statement) and, if ``controlled``, the PD moment."""
    k, c = stiffness(), np.diag(DAMPING)

    def torque(t, q, v):
        quat = q[3:7]                                   # (x, y, z, w)
        rotation = quaternion_matrix(quat)
        tau = -k @ np.r_[rotation.T @ q[:3], 2.0 * quat[3] * quat[:3]] - c @ v
        if controlled:
            kin = orientations(tree, q, v)                    # rotations and angular velocities only
            moment = np.array([0.0, 0.0, -(KP * theta_z(kin.rotation[0]) + KD * kin.omega[0][2])])
            tau[3:] += kin.rotation[0].T @ moment
        return tau
    return torque


def reference_matrices(q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return ref.linearize(reference_tree(True), to_reference(q0))


def relative_singularity(q0: np.ndarray, s: complex, delay: float) -> float:
    mass, damping, stiff = reference_matrices(q0)
    z = mass * s * s + damping * s + stiff
    z = z.astype(complex)
    z[5, 5] += (KP + KD * s) * np.exp(-s * delay)           # world moment z on the rotation about z at rest
    sv = np.linalg.svd(z, compute_uv=False)
    return float(sv[-1] / sv[0])


# ---------------------------------------------------------------- ctmm

def open_loop_system(plant: sp.SpatialModel, delay: float) -> LinearizedSystem:
    """The linearised plant with the PD closed through a delay left open (``u = -y(t - delay)``).

    The spatial linearisation takes joint inputs and tangent coordinates: the hinge's moment about its
    child z axis and ``hinge.rz``, ``hinge.wz``.  At the equilibrium (``R = I``: the centre of mass is
    above the hinge, gravity loads the hinge in translation only) these are ``body.moment_z``,
    ``body.angle_z`` and ``body.omega_z`` to first order."""
    lin = ctmm.linearize(plant, inputs=["hinge.wrench_mz"], outputs=["hinge.rz", "hinge.wz"])
    ss = lin.state_space
    opened = control.ss(ss.A, ss.B, np.array([[KP, KD]]) @ ss.C, 0.0, inputs=["pd_u"], outputs=["pd_y"],
                        states=list(ss.state_labels), name="hinge")
    return LinearizedSystem(opened, (DelayedLoop("pd", 1.0, delay),), lin.operating_point)


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t_final, dt, refinement = (0.5, 1e-3, 2) if quick else (3.0, 1e-3, 4)
    plant = model()
    q0, v0 = initial_state()
    x0 = dict(zip(plant.coordinates, q0))
    v0d = dict(zip(plant.velocities, v0))
    outputs = ["body.angle_z"]
    start = time.perf_counter()
    margin = delay_margin(open_loop_system(plant, 0.0))
    margin_time = time.perf_counter() - start
    delay = dt * max(1, round(0.5 * margin.critical_delay / dt))     # half the margin in whole steps (generated ring)
    compiled = generated_rk4()                  # the generated RK4 where a compiler is present (numpy to round-off)
    runs = {"uncontrolled": ctmm.simulate(plant, t_final, dt, x0=x0, v0=v0d, outputs=outputs, compiled=compiled),
            "PD": ctmm.simulate(with_feedback(plant, [loop()]), t_final, dt, x0=x0, v0=v0d, outputs=outputs,
                                compiled=compiled),
            "delayed PD": ctmm.simulate(with_feedback(plant, [loop(delay)]), t_final, dt, x0=x0, v0=v0d,
                                        outputs=outputs, compiled=compiled)}
    tree = reference_tree(False)
    reference, reference_time, figures = {}, 0.0, []
    for key, controlled in (("uncontrolled", False), ("PD", True)):
        start = time.perf_counter()
        trajectory = ref.simulate(tree, to_reference(q0), v0, t_final, dt / refinement,
                                  torque=reference_law(tree, controlled), store_every=refinement)
        reference_time += time.perf_counter() - start
        reference[key] = np.array([reference_theta_z(tree, qk) for qk in trajectory.q])
        error = float(np.abs(runs[key]["body.angle_z"] - reference[key]).max())
        figures.append(accuracy(f"theta_z error, {key}, ctmm RK4 vs Newton-Euler", error, "rad", THETA_BOUND,
                                f"max over t of |theta_z ctmm - theta_z ref| (x-y-z angle of the body, "
                                f"R = Rx Ry Rz); reference: ctmm/reference/spatial_tree.py RK4 at step / "
                                f"{refinement}, hinge and PD laws written in the scenario",
                                source="ours: the spatial scenarios' RK4 target 1e-6 (docs/scenarios.md)"))
    singular = relative_singularity(open_loop_system(plant, 0.0).operating_point.q, 1j * margin.critical_frequency,
                                    margin.critical_delay)
    figures.append(accuracy("delay margin: reference characteristic determinant at the crossing", singular, "1",
                            MARGIN_BOUND, "smallest / largest singular value of the reference's M s^2 + C s + K + "
                            "b (kp + kd s) e^{-s tau} e^T at s = i omega_c, tau = tau_c of "
                            "ctmm.stability.delay_margin (0 at an exact crossing)",
                            source="ours: tests/test_spatial_linear_stability.py (1e-8)"))
    t = runs["PD"].time
    fig, ax = plt.subplots(figsize=(8, 4.2))
    for key, style in (("uncontrolled", "C0"), ("PD", "C1"), ("delayed PD", "C2")):
        label = key if key != "delayed PD" else f"PD delayed {delay * 1e3:.1f} ms (half the margin, whole steps)"
        ax.plot(t, runs[key]["body.angle_z"], color=style, label=f"ctmm, {label}")
    for key, style in (("uncontrolled", "C0"), ("PD", "C1")):
        ax.plot(t[::20], reference[key][::20], "o", ms=3, color=style, label=f"Newton-Euler, {key}")
    ax.set(xlabel="t [s]", ylabel="theta_z [rad]",
           title=f"elastic-hinge body: delay margin {margin.critical_delay * 1e3:.2f} ms "
                 f"at {margin.critical_frequency:.1f} rad/s")
    ax.legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    return {
        "accuracy": figures,
        "delay_margin_s": float(margin.critical_delay),
        "crossing_frequency_rad_s": float(margin.critical_frequency),
        "delay_s": float(delay),
        "theta_z_range_rad": {key: float(np.ptp(r["body.angle_z"])) for key, r in runs.items()},
        "theta_z_final_abs_rad": {key: float(abs(r["body.angle_z"][-1])) for key, r in runs.items()},
        "wall_time_s": float(sum(r.info["wall_time_s"] for r in runs.values())),
        "run_wall_times_s": {key: float(r.info["wall_time_s"]) for key, r in runs.items()},
        "rk4_method": str(runs["PD"].info["method"]),
        "delay_margin_wall_time_s": margin_time,
        "reference_wall_time_s": reference_time,
        "parameters": {"mass_kg": MASS, "inertia_kg_m2": INERTIA, "center_of_mass_m": COM,
                       "translational_stiffness_N_m": TRANSLATIONAL, "rotary_stiffness_N_m_rad": ROTARY,
                       "damping": DAMPING, "gravity_m_s2": GRAVITY, "kp_N_m_rad": KP, "kd_N_m_s_rad": KD,
                       "dt_s": dt, "t_final_s": t_final, "reference_refinement": refinement, "q0": q0, "v0": v0},
    }
