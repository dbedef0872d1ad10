"""A 3-D flexible manipulator under control (issues 14/15): yaw + shoulder PD joint control and piezo
modal-velocity feedback on a flexible forearm that bends in two planes.

Scene (our parameters; the spatial counterpart of the planar ``flexible_manipulator``, seed 001 Fig. 9.43):

* ``yaw`` -- a revolute about world ``z`` carrying the rigid ``base`` (5 kg, the first link; 2 kg m^2 about the
  yaw axis, the gear motor's reflected rotor inertia included, as the planar scenario's 2 kg m^2 hub);
* ``shoulder`` -- a revolute about the base's ``y`` axis at ``(0, 0, 0.3)`` m carrying the ``hub`` (1 kg,
  2 kg m^2 about the shoulder axis, likewise);
* ``arm`` -- a :class:`~ctmm.spatial.SpatialBeam` welded at the hub's ``out`` point (1 m, rhoA = 0.5 kg/m,
  EI_y = 30 N m^2 for the deflection ``w_y`` (bending in the yaw plane), EI_z = 60 N m^2 for ``w_z``, 3 modes
  per plane, Kelvin-Voigt 0.2 ms) with a 0.2 kg ``payload`` welded at its tip;
* two PZT patch pairs (bimorphs) between the stations ``p1`` (5 mm) and ``p2`` (105 mm), one bending each
  plane (``c_a = 5e-3 N m/V``): the moments ``-c_a V`` at ``p1`` and ``+c_a V`` at ``p2`` about the beam's **body**
  ``z`` (``pzt_z``) and ``y`` (``pzt_y``) axes -- the ``moment_body`` ports, turning with the forearm
  (:func:`ctmm.spatial.beam_ports.patch_actuator`);
* loops (:class:`ctmm.control.Feedback`): ``yaw_pd`` and ``shoulder_pd`` -- ``tau = kp (theta_d - theta) +
  kd (theta_d_dot - theta_dot)`` (sensor ``kp angle + kd rate``, reference ``kp theta_d + kd theta_d_dot``;
  the seed's ``kp = 200 N m/rad``, ``kd = 30 N m s/rad``);
  ``pzt_z``, ``pzt_y`` -- the modal-velocity law of seed eq. (9.65) in each plane, ``V = -Ka (theta_dot(x2) -
  theta_dot(x1))`` on the collocated section rotations ``theta_z = w_y'``, ``theta_y = -w_z'``
  (:func:`ctmm.spatial.beam_ports.patch_sensor`), ``Ka = 2000 V s/rad``;
* manoeuvre: yaw 0 -> 60 deg and shoulder 0 -> -30 deg (the forearm lifts), cycloidal in 1 s.  Gravity is off
  (a space arm, or joints with gravity compensation): the linearisation is about the start pose.  The full run adds
  a panel with gravity on (``GRAVITY``, -9.81 m/s^2 along world z, no compensation: the PD joints hold the arm with
  a steady error and the forearm bends under its own and the payload's weight), PD + PZT against the reference
  with the same gravity (``gravity_on`` in the JSON; the numbers of the gravity-free runs are unchanged).

Outputs, through the verbs on the one controlled model:

* time domain (``ctmm.simulate``, RK4, dt = 2 ms, its generated RK4 where a C compiler is present (the numpy
  RK4 to round-off, ``spatial_common.generated_rk4``); full run also the implicit DT-TMM, Newmark + Newton, on PD + PZT): PD only, PD + PZT, and a delayed variant (yaw PD 10 ms late) -- joint angles, tip deflections ``w_y``, ``w_z`` in the forearm's frame, PZT voltages; the first two
  against the independent assumed-modes Lagrange model (``ctmm/reference/spatial_beam_lagrange.py``: its
  own shapes and the piezo moments' generalised forces by virtual power, closed loop written there,
  ``solve_ivp`` DOP853, rtol 1e-10; its mass integrals on ``REFERENCE_POINTS`` Gauss points, converged);
* the closed-loop roots of the forearm's bending modes (``ctmm.linearize``) with and without PZT: the patch
  loops raise their damping ratios (e.g. 3.8 % -> 12.6 % for the first); the tip deflection right after the
  move is mostly the quasi-static bending of the joint PD's own slow modes, which the patches do not damp;
* frequency domain: the closed-loop FRFs ``yaw reference -> tip w_y`` and ``shoulder reference -> tip w_z``
  with and without PZT
  (``ctmm.frequency_response`` of the controlled linearisation) against the reference's linearisation
  closed by hand;
* delay margin of the yaw PD (``ctmm.stability.delay_margin``, the other loops closed without delay) and
  its check: the smallest singular value of the reference's ``i w I - A_0 - A_1 e^{-i w tau}`` at the
  reported crossing (0 at an exact root); the stability chart of the yaw PD over its gain scale and delay
  (``ctmm.stability_chart``), which must agree with the margin at gain 1.
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

import ctmm
import ctmm.spatial as sp
import ctmm.stability
from ctmm.stability_chart import stability_chart
from ctmm.control import Feedback, with_feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.manipulator import CycloidalMove
from ctmm.manipulator.compiled import cycloid_reference
from ctmm.reference.spatial_beam_lagrange import HubBeam, SpatialBeamLagrange
from ctmm.scenario import accuracy
from ctmm.spatial.beam_ports import patch_actuator, patch_sensor

from .planar_common import save_figure
from .spatial_common import generated_rk4

NAME = "flexible_manipulator_3d"
DESCRIPTION = ("3-D two-link arm (yaw + shoulder) with a flexible forearm bending in two planes: PD joint control "
               "and body-axis PZT modal-velocity feedback, delay margin; TMM vs assumed-modes Lagrange")

DT = 0.002
ARM = dict(length=1.0, mass_per_length=0.5, bending_stiffness_y=30.0, bending_stiffness_z=60.0, n_modes_y=3,
           n_modes_z=3, stiffness_damping=2e-4)
STATIONS = {"p1": 0.005, "p2": 0.105}
BASE = dict(mass=5.0, inertia=np.diag([1.0, 1.0, 2.0]), center=(0.0, 0.0, 0.15))
SHOULDER = (0.0, 0.0, 0.3)
HUB = dict(mass=1.0, inertia=np.diag([1.0, 2.0, 1.0]), center=(0.02, 0.0, 0.0), mount=(0.05, 0.0, 0.0))
PAYLOAD = dict(mass=0.2, inertia=np.diag([1e-4, 1e-4, 1e-4]))
GAINS = {"yaw_pd": (200.0, 30.0), "shoulder_pd": (200.0, 30.0)}      # kp [N m/rad], kd [N m s/rad]
MOVES = {"yaw_pd": CycloidalMove(math.radians(60.0), 1.0), "shoulder_pd": CycloidalMove(math.radians(-30.0), 1.0)}
C_A = 5e-3                  # N m/V (a bimorph patch pair, both faces of the section)
KA = 2000.0                 # V s/rad
VOLTAGE_LIMIT = 200.0       # V (reported, not enforced)
DELAY = 0.01                # s, the yaw PD of the delayed variant
BOUND_TIME = 0.1            # % of peak
BOUND_LINEAR = 1e-8
GRAVITY = (0.0, 0.0, -9.81)  # m/s^2, the full run's gravity panel (world z up)
REFERENCE_POINTS = 16       # Gauss mass points of the reference's beam integrals: converged (its accelerations
                            # agree with 64 points' to ~1e-14 relative, tests/test_flexible_manipulator_3d.py)
NO_GRAVITY = (0.0, 0.0, 0.0)


def plant(gravity: tuple[float, float, float] = NO_GRAVITY) -> sp.SpatialModel:
    """The open-loop arm (no laws of its own: the joints are actuated); ``gravity`` [m/s^2] in world axes."""
    return sp.SpatialModel(NAME, [
        sp.SpatialBody("base", BASE["mass"], BASE["inertia"], center_of_mass=BASE["center"],
                       points={"shoulder": SHOULDER}),
        sp.Revolute(name="yaw", parent=None, child="base", axis=(0, 0, 1), actuated=True),
        sp.SpatialBody("hub", HUB["mass"], HUB["inertia"], center_of_mass=HUB["center"], points={"out": HUB["mount"]}),
        sp.Revolute(name="shoulder", parent="base", point="shoulder", child="hub", axis=(0, 1, 0), actuated=True),
        sp.SpatialBeam("arm", **ARM, stations=STATIONS),
        sp.Weld(name="mount", parent="hub", child="arm", point="out"),
        sp.SpatialBody("payload", PAYLOAD["mass"], PAYLOAD["inertia"]),
        sp.Weld(name="grip", parent="arm", child="payload", point="tip"),
    ], gravity=gravity)


def controlled(pzt: bool, delay: float = 0.0, gravity: tuple[float, float, float] = NO_GRAVITY) -> ControlledModel:
    """The arm with its joint PD loops (the yaw one ``delay`` s late) and, if ``pzt``, the two patch loops."""
    model = plant(gravity)
    beam = model.bodies[2]
    loops = [Feedback(name, [(f"{joint}.angle", kp), (f"{joint}.rate", kd)], f"{joint}.torque", gain=1.0,
                      delay=delay if name == "yaw_pd" else 0.0)
             for (name, (kp, kd)), joint in zip(GAINS.items(), ("yaw", "shoulder"))]
    if pzt:
        loops += [Feedback(f"pzt_{axis}", patch_sensor(beam, "p1", "p2", axis=axis, gain=KA),
                           patch_actuator(beam, "p1", "p2", axis=axis, coefficient=C_A), gain=1.0)
                  for axis in ("z", "y")]
    return with_feedback(model, loops)


def references() -> dict:
    """``{loop: r(t)}``, ``r = kp theta_d + kd theta_d_dot`` of each joint's cycloidal move, as numbers and on
    casadi symbols (:class:`~ctmm.compiled_references.SymbolicReference`: the generated RK4 takes them too)."""
    return {name: cycloid_reference(kp, kd, MOVES[name]) for name, (kp, kd) in GAINS.items()}


# -- the independent reference ---------------------------------------------------------------------------
def lagrange(gravity: tuple[float, float, float] = NO_GRAVITY) -> SpatialBeamLagrange:
    """The assumed-modes Lagrange model of the same arm; actuators: the patch moments (body axes)."""
    x1, x2 = STATIONS["p1"], STATIONS["p2"]
    return SpatialBeamLagrange(HubBeam(
        **ARM, hub_mass=HUB["mass"], hub_inertia=HUB["inertia"], hub_center=HUB["center"],
        axes=((0, 0, 1), (0, 1, 0)), mount=HUB["mount"], shoulder=SHOULDER, base_mass=BASE["mass"],
        base_inertia=BASE["inertia"], base_center=BASE["center"], tip_mass=PAYLOAD["mass"],
        tip_inertia=PAYLOAD["inertia"], gravity=gravity, points=REFERENCE_POINTS,
        actuators=((x1, "moment", 2), (x2, "moment", 2), (x1, "moment", 1), (x2, "moment", 1))))


def _patch_rows(reference: SpatialBeamLagrange) -> dict[str, np.ndarray]:
    """``theta_a(x2) - theta_a(x1)`` per unit ``q`` (reference shapes) of each patch loop."""
    x1, x2 = STATIONS["p1"], STATIONS["p2"]
    return {f"pzt_{a}": reference.section_rows(x2)[row] - reference.section_rows(x1)[row]
            for a, row in (("z", 2), ("y", 1))}


def _reference_run(reference: SpatialBeamLagrange, pzt: bool, t_eval: np.ndarray, rtol: float) -> dict:
    """The closed loop on the reference (no delay), ``solve_ivp`` DOP853."""
    n = reference.n
    rows = _patch_rows(reference)

    def voltages(u: np.ndarray) -> np.ndarray:
        return np.array([-KA * rows[name] @ u for name in ("pzt_z", "pzt_y")]) if pzt else np.zeros(2)

    def rhs(t: float, state: np.ndarray) -> np.ndarray:
        q, u = state[:n], state[n:]
        tau = np.zeros(n)
        for k, (name, (kp, kd)) in enumerate(GAINS.items()):
            move = MOVES[name]
            tau[k] = kp * (move.angle(t) - q[k]) + kd * (move.rate(t) - u[k])
        V = voltages(u)
        act = C_A * np.array([-V[0], V[0], -V[1], V[1]])
        return np.concatenate([u, reference.accelerations(q, u, tau, act)])

    solution = solve_ivp(rhs, (0.0, float(t_eval[-1])), np.zeros(2 * n), method="DOP853", t_eval=t_eval,
                         rtol=rtol, atol=1e-12)
    states = solution.y.T
    tip = reference.deflection_rows(ARM["length"])
    return {"angles": states[:, :2], "tip": states[:, :n] @ tip[1:].T,
            "voltages": np.array([voltages(u) for u in states[:, n:]])}


def _reference_closed(reference: SpatialBeamLagrange, pzt: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A_0, A_yaw, B_yaw)``: the reference's linearisation about the start with the shoulder PD and the
    patch loops closed (``A_0``), the yaw PD's part (``A_yaw``: ``x' = A_0 x + A_yaw x(t - tau) + B_yaw r``)."""
    n = reference.n
    A, B_force, B_act = reference.linearize(np.zeros(n))
    closed, yaw = A.copy(), np.zeros_like(A)
    for k, (name, (kp, kd)) in enumerate(GAINS.items()):
        target = yaw if name == "yaw_pd" else closed
        target[:, k] -= B_force[:, k] * kp
        target[:, n + k] -= B_force[:, k] * kd
    if pzt:
        for first, name in ((0, "pzt_z"), (2, "pzt_y")):
            closed[:, n:] -= KA * C_A * np.outer(B_act[:, first + 1] - B_act[:, first], _patch_rows(reference)[name])
    return closed, yaw, B_force[:, 0]


# -- runs ------------------------------------------------------------------------------------------------
def _simulate(pzt: bool, delay: float, t_final: float, store_every: int, method: str = "rk4",
              gravity: tuple[float, float, float] = NO_GRAVITY) -> dict:
    system = controlled(pzt, delay, gravity)
    compiled = method == "rk4" and generated_rk4()
    result = ctmm.simulate(system, t_final, DT, method=method, references=references(), store_every=store_every,
                           compiled=compiled)
    weights = [np.asarray(system.ports.sensors[f"arm.tip.{w}"].weights) for w in ("w_y", "w_z")]
    eta = np.column_stack([result[f"arm.{s}"] for s in system.plant.bodies[2].coordinate_suffixes])
    voltages = np.column_stack([result[f"pzt_{a}.u"] for a in ("z", "y")]) if pzt else np.zeros((eta.shape[0], 2))
    return {"t": np.asarray(result.time), "angles": np.column_stack([result["yaw.angle"], result["shoulder.angle"]]),
            "tip": eta @ np.column_stack(weights), "voltages": voltages, "wall": float(result.info["wall_time_s"]),
            "result": result, "method": str(result.info["method"])}


def _flexible_modes(system: ControlledModel, above: float = 15.0) -> list[tuple[float, float]]:
    """``(|s| [rad/s], damping ratio)`` of the closed-loop roots above ``above`` rad/s (the forearm's bending
    modes; below are the joint PD modes), from ``ctmm.linearize``."""
    roots = np.linalg.eigvals(ctmm.linearize(system).state_space.A)
    roots = roots[(roots.imag > 0) & (np.abs(roots) > above)]
    roots = roots[np.argsort(np.abs(roots))]
    return [(float(abs(r)), float(-r.real / abs(r))) for r in roots]


def _gravity_panel(t_final: float, compare) -> dict:
    """PD + PZT with gravity on (no compensation) against the reference with the same gravity: errors (as the
    gravity-free runs), the joints' final errors and the forearm's final tip deflections (its static sag)."""
    sim = _simulate(True, 0.0, t_final, store_every=5, gravity=GRAVITY)
    ref = _reference_run(lagrange(GRAVITY), True, sim["t"], 1e-10)
    return {"gravity_m_s2": list(GRAVITY), "errors": compare(sim, ref), "wall_time_s": sim["wall"],
            "joint_final_error_rad": [float(sim["angles"][-1, k] - MOVES[name].angle(t_final))
                                      for k, name in enumerate(GAINS)],
            "final_tip_deflection_m": [float(v) for v in sim["tip"][-1]],
            "reference_final_tip_deflection_m": [float(v) for v in ref["tip"][-1]]}


def _after_move(t: np.ndarray) -> np.ndarray:
    return t >= 1.0 + 0.25 - 1e-9


def run(output_dir: Path, quick: bool = False, results: dict | None = None) -> dict:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    output_dir = Path(output_dir)
    t_final = 1.5 if quick else 4.0
    reference = lagrange()
    labels = {"PD only": False, "PD + PZT": True}
    sims, refs, errors, ref_wall = {}, {}, {}, 0.0
    def compare(sim: dict, ref: dict) -> dict:
        peak = float(np.abs(ref["tip"]).max())
        return {"tip_error_percent_of_peak": float(np.abs(sim["tip"] - ref["tip"]).max() / peak * 100),
                "joint_angle_error_rad": float(np.abs(sim["angles"] - ref["angles"]).max()),
                "voltage_error_V": float(np.abs(sim["voltages"] - ref["voltages"]).max())}

    for label, pzt in labels.items():
        sims[label] = _simulate(pzt, 0.0, t_final, store_every=5)
        started = time.perf_counter()
        refs[label] = _reference_run(reference, pzt, sims[label]["t"], 1e-9 if quick else 1e-10)
        ref_wall += time.perf_counter() - started
        errors[label] = compare(sims[label], refs[label])
    extra = {}
    if not quick:                  # the implicit DT-TMM (Newmark + Newton) of the book on the PD + PZT loops
        newmark = _simulate(True, 0.0, t_final, store_every=5, method="newmark")
        errors["PD + PZT, DT-TMM Newmark"] = compare(newmark, refs["PD + PZT"])
        extra["dt_tmm_newmark"] = {"wall_time_s": newmark["wall"], "real_time_factor": t_final / newmark["wall"],
                                   "mean_newton_iterations": newmark["result"].info.get("newton_iterations_mean")}
        extra["gravity_on"] = _gravity_panel(t_final, compare)
    delayed = _simulate(True, DELAY, t_final, store_every=5)
    after = _after_move(sims["PD + PZT"]["t"])
    rms = {label: [float(np.sqrt(np.mean(s["tip"][after, k] ** 2))) for k in range(2)]
           for label, s in {**sims, "PD 10 ms late + PZT": delayed}.items()}

    # -- frequency domain and the delay margin --------------------------------------------------------------
    omega = np.linspace(1.0, 80.0, 60 if quick else 300)
    n = reference.n
    tip_rows = reference.deflection_rows(ARM["length"])[1:, :]
    pairs = (("yaw_pd.reference", "arm.tip.w_y", 0, 0), ("shoulder_pd.reference", "arm.tip.w_z", 1, 1))
    frf, frf_ref, frf_error = {}, {}, 0.0
    started = time.perf_counter()
    for label, pzt in labels.items():
        response = ctmm.frequency_response(controlled(pzt), omega, input=[p[0] for p in pairs],
                                           output=[p[1] for p in pairs])
        frf[label] = np.array([response(output, inp) for inp, output, _, _ in pairs])
    frf_wall = time.perf_counter() - started
    for label, pzt in labels.items():
        closed, yaw, _ = _reference_closed(reference, pzt)
        drives = reference.linearize(np.zeros(n))[1]                  # joint torque k = reference of loop k
        frf_ref[label] = np.array([[tip_rows[row] @ np.linalg.solve(1j * w * np.eye(2 * n) - closed - yaw,
                                                                    drives[:, joint])[:n] for w in omega]
                                   for _, _, joint, row in pairs])
        scale = np.abs(frf_ref[label]).max(axis=1, keepdims=True)
        if not np.all(scale > 0):
            raise RuntimeError("the reference frequency response is zero: nothing to compare")
        frf_error = max(frf_error, float(np.max(np.abs(frf[label] - frf_ref[label]) / scale)))
    damping = {label: _flexible_modes(controlled(pzt)) for label, pzt in labels.items()}
    margin = ctmm.stability.delay_margin(controlled(True, DELAY), "yaw_pd")
    grid = 8 if quick else 24
    chart = stability_chart(controlled(True, DELAY), ("gain", np.linspace(0.25, 2.0, grid), "yaw PD gain scale"),
                            ("delay", np.linspace(0.0, 0.15, grid), "yaw PD delay [s]"), loop="yaw_pd")
    unit_gain = int(np.argmin(np.abs(chart.x - 1.0)))
    column = np.asarray(chart.unstable_roots)[:, unit_gain]
    chart_agrees = bool(np.all(column[chart.y < margin.critical_delay - 1e-9] == 0)
                        and np.all(column[chart.y > margin.critical_delay + 1e-9] > 0))
    closed, yaw, _ = _reference_closed(reference, True)
    w_c, tau_c = margin.critical_frequency, margin.critical_delay
    characteristic = 1j * w_c * np.eye(2 * n) - closed - yaw * np.exp(-1j * w_c * tau_c)
    singular = np.linalg.svd(characteristic, compute_uv=False)
    margin_residual = float(singular[-1] / singular[0])

    # -- figures --------------------------------------------------------------------------------------------
    figures = []
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True)
    t = sims["PD + PZT"]["t"]
    step = max(1, t.size // 50)
    for k, (name, color) in enumerate((("yaw_pd", "C0"), ("shoulder_pd", "C2"))):
        joint = name.split("_")[0]
        axes[0, 0].plot(t, np.degrees([MOVES[name].angle(s) for s in t]), "--", color=color, lw=1.0,
                        label=f"{joint} desired")
        axes[0, 0].plot(t, np.degrees(sims["PD + PZT"]["angles"][:, k]), color=color, lw=1.0,
                        label=f"{joint} (TMM, PD + PZT)")
        axes[0, 0].plot(t[::step], np.degrees(refs["PD + PZT"]["angles"][::step, k]), "x", ms=4, color="C3")
    for k, ax, title in ((0, axes[0, 1], "tip deflection w_y (yaw plane)"), (1, axes[1, 0], "tip deflection w_z")):
        for label, color in (("PD only", "C1"), ("PD + PZT", "C0")):
            ax.plot(t, 1e3 * sims[label]["tip"][:, k], color=color, lw=1.0, label=f"TMM, {label}")
            ax.plot(t[::step], 1e3 * refs[label]["tip"][::step, k], "x", ms=4, color="C3")
        ax.plot(delayed["t"], 1e3 * delayed["tip"][:, k], ":", color="C4", lw=1.0, label="TMM, yaw PD 10 ms late + PZT")
        ax.set_ylabel("[mm]")
        ax.set_title(title, fontsize=10)
    for k, (axis, color) in enumerate((("z", "C0"), ("y", "C2"))):
        axes[1, 1].plot(t, sims["PD + PZT"]["voltages"][:, k], color=color, lw=1.0, label=f"V pzt_{axis} (TMM)")
        axes[1, 1].plot(t[::step], refs["PD + PZT"]["voltages"][::step, k], "x", ms=4, color="C3")
    axes[0, 0].set_ylabel("joint angle [deg]")
    axes[1, 1].set_ylabel("[V]")
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
        ax.legend(fontsize="x-small", loc="best")
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    fig.suptitle("3-D flexible manipulator: PD joints + body-axis PZT (x: assumed-modes Lagrange)", fontsize=11)
    save_figure(fig, output_dir, NAME)
    figures.append(f"{NAME}.png")

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for k, ax in enumerate(axes):
        for label, color in (("PD only", "C1"), ("PD + PZT", "C0")):
            ax.semilogy(omega, np.abs(frf[label][k]), color=color, label=f"TMM, {label}")
            ax.semilogy(omega[::5], np.abs(frf_ref[label][k][::5]), "x", color="C3", ms=4)
        ax.set(xlabel="omega [rad/s]", ylabel="[m per N m]", title=f"{pairs[k][0]} -> {pairs[k][1]}")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize="small")
    save_figure(fig, output_dir, f"{NAME}_frf")
    figures.append(f"{NAME}_frf.png")

    fig, ax = plt.subplots(figsize=(6.5, 4.8))
    chart.plot(ax)
    ax.plot([1.0], [tau_c], "r*", ms=10, label=f"delay margin {tau_c * 1e3:.1f} ms (gain 1)")
    ax.plot([1.0], [DELAY], "ko", ms=5, label=f"the delayed variant ({DELAY * 1e3:g} ms)")
    ax.legend(fontsize="small")
    ax.set_title("yaw PD: stability chart over gain scale and delay (other loops real-time)", fontsize=10)
    save_figure(fig, output_dir, f"{NAME}_chart")
    figures.append(f"{NAME}_chart.png")

    if results is not None:                      # ctmm run --save / --animate
        results.update({label.replace(" ", "").replace("+", "_"): s["result"] for label, s in sims.items()})
    time_error = max(e["tip_error_percent_of_peak"] for e in errors.values())
    wall = sum(s["wall"] for s in sims.values())
    return {
        "accuracy": [
            accuracy("tip deflection error vs Lagrange", time_error, "% of peak", BOUND_TIME,
                     "max_t |(w_y, w_z)_tip,TMM - (w_y, w_z)_tip,Lagrange| / max_t |reference| x 100, PD only and "
                     "PD + PZT (ctmm.simulate RK4, dt = 2 ms, generated where a C compiler is present; full run also the DT-TMM Newmark on PD + PZT); "
                     "reference DOP853 rtol 1e-10 (1e-9 quick)",
                     source="docs/manipulator.md: tip error << 0.1 % of the peak (the planar scenario's bound)"),
            accuracy("closed-loop FRF vs reference linearisation", frf_error, "1", BOUND_LINEAR,
                     "max_omega |H_TMM - H_ref| / max_omega |H_ref| of yaw reference -> tip w_y and shoulder "
                     "reference -> tip w_z, with and without PZT (H_ref: the Lagrange linearisation with the loops "
                     "closed by hand)",
                     source="the linearisations agree to round-off (tests/test_spatial_beam_body_actuators.py)"),
            accuracy("delay margin: reference characteristic at the crossing", margin_residual, "1", BOUND_LINEAR,
                     "sigma_min / sigma_max of the reference's i w I - A_0 - A_yaw e^{-i w tau} at the crossing "
                     "(w_c, tau_c) that ctmm.stability.delay_margin reports for the yaw PD",
                     source="an exact root: 0 to round-off (the spatial_elastic_hinge_control scenario's bound)")],
        "errors": errors,
        "wall_time_s": wall,
        "rk4_method": sims["PD + PZT"]["method"],
        "real_time_factor": float(2 * t_final / wall),
        "reference_wall_time_s": ref_wall,
        "frf_wall_time_s": frf_wall,
        "t_final_s": t_final,
        "dt_s": DT,
        "peak_tip_deflection_m": {label: [float(v) for v in np.abs(s["tip"]).max(axis=0)] for label, s in sims.items()},
        "rms_tip_after_move_m": rms,
        "rms_reduction_by_pzt": [1.0 - rms["PD + PZT"][k] / rms["PD only"][k] for k in range(2)],
        "flexible_mode_damping": damping,
        "peak_voltage_V": float(np.abs(sims["PD + PZT"]["voltages"]).max()),
        "voltage_limit_V": VOLTAGE_LIMIT,
        "joint_final_error_rad": [float(abs(sims["PD + PZT"]["angles"][-1, k] - MOVES[name].angle(t_final)))
                                  for k, name in enumerate(GAINS)],
        "delay_margin": {"loop": "yaw_pd", "delay_s": DELAY, "critical_delay_s": tau_c,
                         "critical_frequency_rad_s": w_c, "margin_s": margin.margin, "stable": margin.stable,
                         "reference_residual": margin_residual},
        "stability_chart": {"gain_scale": [float(chart.x[0]), float(chart.x[-1]), grid],
                            "delay_s": [float(chart.y[0]), float(chart.y[-1]), grid],
                            "stable_fraction": float(chart.stable_fraction), "wall_time_s": float(chart.wall_time_s),
                            "agrees_with_delay_margin_at_gain_1": chart_agrees},
        "delayed_wall_time_s": delayed["wall"],
        **extra,
        "parameters": {"arm": {k: v for k, v in ARM.items()}, "stations_m": STATIONS, "shoulder_m": SHOULDER,
                       "base_kg": BASE["mass"], "hub_kg": HUB["mass"], "payload_kg": PAYLOAD["mass"],
                       "gains": GAINS, "c_a_N_m_per_V": C_A, "Ka_V_s_per_rad": KA,
                       "moves_deg": {"yaw": 60.0, "shoulder": -30.0, "duration_s": 1.0}, "gravity": "off"},
        "figures": figures,
    }
