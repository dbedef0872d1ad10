"""3-D robot arm with PD joint control tracking a point-to-point move, with and without a measurement
delay (issue 14): ctmm's Python RK4, generated RK4 (``compiled=True``) and Newmark DT-TMM against the
global Newton-Euler reference with the control law written here.

Arm (parameters ours): base 4 kg (inertia diag(0.03, 0.03, 0.02) kg m^2, centre of mass 0.1 m up) on
a revolute **yaw** joint about the world z axis; upper arm 2 kg, 0.4 m along its x axis (centre of
mass mid-link, inertia (0.002, 0.03, 0.03)) on a revolute **shoulder** pitch about y at the top of the
base (0.2 m); forearm 1.5 kg, 0.35 m (inertia (0.0015, 0.016, 0.016)) on a revolute **elbow** pitch
about y; hand with payload 1.5 kg (centre of mass 0.08 m out, inertia (0.003, 0.004, 0.004), tool
point ``tcp`` 0.12 m out) on a **spherical wrist**.  Gravity 9.81 m/s^2 along -z.  Every joint is
actuated.

Control (``Feedback`` loops, gains ours): each of yaw, shoulder and elbow a PD ``u = -(kp (q - q_d) +
kd (q_dot - q_d_dot))(t - tau)`` with kp = 150, 300, 300 N m/rad, kd = 20, 10, 10 N m s/rad, tracking a
quintic point-to-point move from (0, -0.3, 0.6) to (1.2, 0.2, 1.0) rad in 1 s (the reference
``kp q_d + kd q_d_dot`` of each loop, a :class:`~ctmm.compiled_references.SymbolicReference` so that the
generated code follows it); the wrist held straight by three real-time PDs on its quaternion,
``u_i = -(40 q_i + w_i)`` (``2 q_vec`` is the rotation vector to first order).  No gravity
compensation: the shoulder and elbow settle with a static error ``torque / kp``.  Runs (a) real-time
joint PDs and (b) the joint PDs on measurements ``tau = 6 ms`` late (at 20 ms the
loops lose stability: the elbow derivative gain times the delay is of the order of the forearm's
inertia).  RK4 and Newmark at 1 ms over 1.5 s
(quick: 0.06 s at 2 ms).

Reference: the arm written directly as a ``ctmm/reference/spatial_tree`` tree (no ctmm code), the same
laws evaluated on its states, integrated by scipy's DOP853 (rtol 1e-11) -- for (b) by the method of
steps (intervals of one delay, the delayed state from the previous interval's dense output, the initial
state held before 0).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import scipy.integrate

import ctmm
import ctmm.spatial as sp
from ctmm.compiled_references import SymbolicReference
from ctmm.control import Feedback, with_feedback
from ctmm.reference import spatial_tree as ref
from ctmm.reference.spatial_kinematics import kinematics
from ctmm.scenario import accuracy
from ctmm.scene_files import load_scene

from .planar_common import save_figure

NAME = "spatial_robot_arm"
DESCRIPTION = ("3-D arm (yaw, shoulder, elbow, spherical wrist + payload) with PD joint control on a point-to-point "
               "move, real-time and 6 ms late: Python RK4, generated RK4 and Newmark against Newton-Euler")
JOINTS = ("yaw", "shoulder", "elbow")
KP = (150.0, 300.0, 300.0)                   # N m/rad
KD = (20.0, 10.0, 10.0)                      # N m s/rad
WRIST_KP, WRIST_KD = 40.0, 1.0               # N m per unit of q_vec, N m s/rad
START, GOAL, MOVE_TIME = (0.0, -0.3, 0.6), (1.2, 0.2, 1.0), 1.0      # rad, rad, s
DELAY = 0.006                                # s
GRAVITY = (0.0, 0.0, -9.81)
BODIES = {  # name: mass [kg], inertia diagonal [kg m^2], centre of mass [m], outboard point [m]
    "base": (4.0, (0.03, 0.03, 0.02), (0.0, 0.0, 0.1), (0.0, 0.0, 0.2)),
    "upper": (2.0, (0.002, 0.03, 0.03), (0.2, 0.0, 0.0), (0.4, 0.0, 0.0)),
    "fore": (1.5, (0.0015, 0.016, 0.016), (0.175, 0.0, 0.0), (0.35, 0.0, 0.0)),
    "hand": (1.5, (0.003, 0.004, 0.004), (0.08, 0.0, 0.0), (0.12, 0.0, 0.0)),
}
AXES = ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (0.0, 1.0, 0.0))
TRACKING_BOUND = 1e-6    # [rad] RK4 at the scenario step against the converged reference
COMPILED_BOUND = 1e-10   # [rad] generated against Python RK4: one discretisation, round-off only
NEWMARK_BOUND = 1e-4     # [rad] a second-order scheme at 1-2 ms on 10-40 rad/s loops (ours)


def model() -> sp.SpatialModel:
    """The arm (no loops), built from the scene file ``scenarios/files/spatial_robot_arm.toml`` (the one source of the
    plant; :func:`reference_tree` builds the reference from the constants above)."""
    return load_scene(Path(__file__).resolve().parent / "files" / "spatial_robot_arm.toml").plant


def desired(k: int, t: float, *, ops=np) -> tuple:
    """Quintic move of joint ``k``: angle [rad] and rate [rad/s] at ``t`` [s] (``ops``: numpy or casadi)."""
    if ops is np:
        s = np.clip(t / MOVE_TIME, 0.0, 1.0)
    else:
        s = ops.fmin(ops.fmax(t / MOVE_TIME, 0.0), 1.0)
    step = GOAL[k] - START[k]
    return START[k] + step * s ** 3 * (10 - 15 * s + 6 * s * s), step / MOVE_TIME * 30 * s * s * (1 - s) ** 2


def references() -> dict:
    """``{loop: kp q_d + kd q_d_dot}`` as signals with a numeric and a symbolic form."""
    import casadi

    def signal(k: int) -> SymbolicReference:
        def numeric(t: float) -> float:
            angle, rate = desired(k, t)
            return KP[k] * float(angle) + KD[k] * float(rate)

        def symbolic(t):
            angle, rate = desired(k, t, ops=casadi)
            return KP[k] * angle + KD[k] * rate
        return SymbolicReference(numeric, symbolic)
    return {f"{joint}_pd": signal(k) for k, joint in enumerate(JOINTS)}


def loops(delay: float) -> list[Feedback]:
    joint_loops = [Feedback(f"{joint}_pd", [(f"{joint}.angle", KP[k]), (f"{joint}.rate", KD[k])], f"{joint}.torque",
                            gain=1.0, delay=delay) for k, joint in enumerate(JOINTS)]
    wrist = [Feedback(f"wrist_{a}", [(f"wrist.q{a}", WRIST_KP), (f"wrist.w{a}", WRIST_KD)], f"wrist.torque_{a}",
                      gain=1.0) for a in "xyz"]
    return joint_loops + wrist


def initial_state() -> tuple[np.ndarray, np.ndarray]:
    """``(q0, v0)``: the start pose at rest, wrist straight (quaternion scalar first)."""
    return np.r_[START, 1.0, 0.0, 0.0, 0.0], np.zeros(6)


# ---------------------------------------------------------------- reference (global Newton-Euler)

def reference_tree() -> ref.SpatialTree:
    """The arm written directly in the reference's description (no ctmm model code)."""
    out, names = [], list(BODIES)
    for k, name in enumerate(names):
        mass, inertia, com, _ = BODIES[name]
        position = np.zeros(3) if k == 0 else np.asarray(BODIES[names[k - 1]][3], float)
        kind, axes = ("revolute", np.array([AXES[k]])) if k < 3 else ("spherical", np.zeros((0, 3)))
        out.append(ref.SpatialBody(name, k - 1, kind, mass, np.asarray(com, float), np.diag(inertia), axes=axes,
                                   joint_position=position, joint_rotation=np.eye(3)))
    return ref.SpatialTree(tuple(out), gravity=np.asarray(GRAVITY))


def reference_torque(t: float, y: np.ndarray, measured: np.ndarray, delay: float) -> np.ndarray:
    """Generalised forces ``(yaw, shoulder, elbow, wrist x, y, z)`` of the loops: joint PDs on ``measured``
    (the state at ``t - delay``) against the move at ``t - delay``, wrist PDs on ``y`` (reference layout
    ``q = (yaw, shoulder, elbow, qx, qy, qz, qw)``, ``v`` (6,))."""
    tau = np.zeros(6)
    for k in range(3):
        angle, rate = desired(k, t - delay)
        tau[k] = -(KP[k] * (measured[k] - angle) + KD[k] * (measured[7 + k] - rate))
    tau[3:] = -(WRIST_KP * y[3:6] + WRIST_KD * y[10:13])
    return tau


def reference_run(tree: ref.SpatialTree, q0: np.ndarray, t_final: float, times: np.ndarray, delay: float
                  ) -> np.ndarray:
    """States (times, 13) in the reference layout: DOP853, by the method of steps when ``delay > 0``."""
    y0 = np.r_[q0[:3], q0[4:7], q0[3], np.zeros(6)]
    history = [lambda s: y0]

    def rhs(t, y):
        measured = history[-1](t - delay) if delay > 0 else y
        q, v = y[:7], y[7:]
        return np.r_[ref.configuration_rate(tree, q, v),
                     ref.forward_dynamics(tree, q, v, reference_torque(t, y, measured, delay), t)]

    span = delay if delay > 0 else t_final
    bounds = np.append(np.arange(0.0, t_final - 1e-9 * t_final, span), t_final)
    y = y0
    for start, end in zip(bounds[:-1], bounds[1:]):      # one interval of one delay at a time
        solution = scipy.integrate.solve_ivp(rhs, (start, end), y, method="DOP853", rtol=1e-11, atol=1e-12,
                                             dense_output=True)
        history.append(lambda s, f=solution.sol, t0=start, before=history[-1]: f(s) if s >= t0 - 1e-12 else before(s))
        y = solution.y[:, -1]
    return np.array([history[-1](t) for t in times])


def reference_tcp(tree: ref.SpatialTree, states: np.ndarray) -> np.ndarray:
    tcp = np.asarray(BODIES["hand"][3], float)
    return np.array([(lambda k: k.origin[3] + k.rotation[3] @ tcp)(kinematics(tree, y[:7], y[7:])) for y in states])


# ---------------------------------------------------------------- runs

def _joint_error(result, reference_states: np.ndarray) -> float:
    return float(max(np.abs(result[f"{joint}.angle"] - reference_states[:, k]).max() for k, joint in enumerate(JOINTS)))


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t_final, dt = (0.06, 2e-3) if quick else (1.5, 1e-3)
    arm = model()
    q0, v0 = initial_state()
    x0, rates0 = dict(zip(arm.coordinates, q0)), dict(zip(arm.velocities, v0))
    outputs = ["hand.tcp.x", "hand.tcp.y", "hand.tcp.z"]
    tree = reference_tree()
    cases, figures, walls, data = {"real-time": 0.0, "delayed": DELAY}, [], {}, {}
    for case, delay in cases.items():
        controlled = with_feedback(arm, loops(delay))
        common = dict(x0=x0, v0=rates0, references=references(), outputs=outputs)
        runs = {"RK4": ctmm.simulate(controlled, t_final, dt, **common),
                "generated RK4": ctmm.simulate(controlled, t_final, dt, compiled=True, **common),
                "Newmark": ctmm.simulate(controlled, t_final, dt, method="newmark", **common)}
        start = time.perf_counter()
        reference = reference_run(tree, q0, t_final, runs["RK4"].time, delay)
        walls[case] = {key: float(r.info["wall_time_s"]) for key, r in runs.items()}
        walls[case]["generated RK4 compile"] = float(runs["generated RK4"].info["compile_time_s"])
        walls[case]["reference DOP853"] = time.perf_counter() - start
        errors = {key: _joint_error(r, reference) for key, r in runs.items()}
        compiled_gap = float(max(np.abs(runs["generated RK4"][name] - runs["RK4"][name]).max()
                                 for name in list(arm.coordinates) + list(arm.velocities)))
        where = f"{case} joint PDs" + (f" ({delay * 1e3:.0f} ms late)" if delay else "")
        figures += [
            accuracy(f"joint angle error, {where}, ctmm RK4 vs Newton-Euler", errors["RK4"], "rad", TRACKING_BOUND,
                     "max over t and yaw, shoulder, elbow of |q_ctmm - q_ref|; reference: "
                     "ctmm/reference/spatial_tree.py with the laws written in the scenario, DOP853 rtol 1e-11"
                     + (", method of steps" if delay else ""), source="ours: the spatial scenarios' RK4 target 1e-6"),
            accuracy(f"generated RK4 vs Python RK4, {where}", compiled_gap, "rad, rad/s", COMPILED_BOUND,
                     "max over t of every coordinate and velocity of |generated - Python|",
                     source="ours: one discretisation of one ODE (tests/test_spatial_compiled_loops.py, 1e-10)"),
            accuracy(f"joint angle error, {where}, ctmm Newmark vs Newton-Euler", errors["Newmark"], "rad",
                     NEWMARK_BOUND, "as the RK4 figure, Newmark (average acceleration, Lie-group form) at the same "
                     "step", source="ours: second order, (omega dt)^2 / 12 x 0.1 rad ~ 1e-5 at 2 ms on 40 rad/s"),
        ]
        tcp_ref = reference_tcp(tree, reference)
        data[case] = {"runs": runs, "reference": reference, "tcp_reference": tcp_ref, "errors": errors}
    t = data["real-time"]["runs"]["RK4"].time
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.3))
    for k, joint in enumerate(JOINTS):
        axes[0].plot(t, desired(k, t)[0], "k:", lw=1)
        for case, style in (("real-time", "-"), ("delayed", "--")):
            axes[0].plot(t, data[case]["runs"]["RK4"][f"{joint}.angle"], style, color=f"C{k}",
                         label=f"{joint}, {case}")
        axes[0].plot(t[::max(1, len(t) // 30)], data["real-time"]["reference"][::max(1, len(t) // 30), k], "o", ms=3,
                     color=f"C{k}")
    axes[0].set(xlabel="t [s]", ylabel="joint angle [rad] (dotted: move, o: Newton-Euler)")
    axes[0].legend(fontsize="x-small", ncol=2)
    for case, style in (("real-time", "-"), ("delayed", "--")):
        runs = data[case]["runs"]
        for key, color in (("RK4", "C0"), ("generated RK4", "C1"), ("Newmark", "C2")):
            error = np.max(np.abs(np.column_stack([runs[key][f"{j}.angle"] for j in JOINTS])
                                  - data[case]["reference"][:, :3]), axis=1)
            axes[1].semilogy(t, error + 1e-17, style, color=color, label=f"{key}, {case}")
    axes[1].set(xlabel="t [s]", ylabel="max joint angle error vs Newton-Euler [rad]")
    axes[1].legend(fontsize="x-small")
    labels = [f"{key}\n{case}" for case in cases for key in walls[case]]
    axes[2].bar(range(len(labels)), [walls[case][key] for case in cases for key in walls[case]])
    axes[2].set_xticks(range(len(labels)), labels, rotation=70, fontsize="x-small")
    axes[2].set(ylabel="wall time [s]", yscale="log")
    save_figure(fig, output_dir, NAME)
    tcp = data["real-time"]["runs"]["RK4"]
    return {
        "accuracy": figures,
        "joint_errors_rad": {case: data[case]["errors"] for case in cases},
        "tcp_error_m": {case: float(np.abs(np.column_stack([data[case]["runs"]["RK4"][n] for n in outputs])
                                           - data[case]["tcp_reference"]).max()) for case in cases},
        "tcp_travel_m": float(np.linalg.norm(np.ptp(np.column_stack([tcp[n] for n in outputs]), axis=0))),
        "final_tracking_error_rad": {case: [float(data[case]["runs"]["RK4"][f"{j}.angle"][-1] - desired(k, t_final)[0])
                                            for k, j in enumerate(JOINTS)] for case in cases},
        "wall_time_s": float(sum(sum(v for key, v in walls[case].items() if "reference" not in key) for case in cases)),
        "wall_times_s": walls,
        "reference_wall_time_s": float(sum(walls[case]["reference DOP853"] for case in cases)),
        "parameters": {"bodies": {name: {"mass_kg": m, "inertia_kg_m2": i, "center_of_mass_m": c, "point_m": p}
                                  for name, (m, i, c, p) in BODIES.items()},
                       "axes": AXES, "kp_N_m_rad": KP, "kd_N_m_s_rad": KD, "wrist_kp": WRIST_KP,
                       "wrist_kd_N_m_s_rad": WRIST_KD, "start_rad": START, "goal_rad": GOAL,
                       "move_time_s": MOVE_TIME, "delay_s": DELAY, "gravity_m_s2": GRAVITY, "dt_s": dt,
                       "t_final_s": t_final},
    }
