"""Four-bar linkage closed by a cut joint, with a nonlinear rocker spring (issue 16, items 2 and 3).

Own parameters (the seeds give none): a Grashof crank-rocker with ground pivots ``(0, 0)`` and
``(0.7, 0)`` m; uniform slender links crank 0.2 m / 0.4 kg, coupler 0.6 m / 1.0 kg, rocker 0.5 m /
0.8 kg; gravity -9.81 m/s^2 along y.  The rocker pivot carries a hardening cubic spring
``M = K1 d + K2 d^3`` (K1 = 2 N m/rad, K2 = 15 N m/rad^3, seed 002 Fig. 7.12 form) about the rest
angle 1.9 rad, parallel to a quadratic damper ``0.02 d' |d'|`` N m.  The crank starts at 90 deg with
3 rad/s, the coupler and rocker assembled (:meth:`KinematicLoopModel.consistent_state`) and free.

The tree is crank -> coupler from the ground and the rocker from the second ground pivot; the cut
joint ``h3`` joins the coupler's outboard end to the rocker's (the coupler is a body with two input
ends).  ctmm: the TMM sweep with the cut force as boundary unknowns
(:mod:`ctmm.planar.closed_loops`), RK4 at 1 ms with projection, and DOP853 with Baumgarte only.
Reference: the global DAE (:mod:`ctmm.reference.planar_dae`, absolute coordinates and Lagrange
multipliers, DOP853 at 1e-11).  Energy check: the same linkage without the damper.  Extra panel: a PD
crank-angle loop (``ctmm.control.with_feedback`` on the kinematic loop model; kp = 8 N m/rad, kd = 0.8 N m s/rad,
set point 1.2 rad), real-time and with a 10 ms delay, against the DAE with the same law as a crank motor.
Flexible variant (issue 16 item 4): the smooth linkage with the coupler a ``ModalBeam`` (EI = 80 N m^2, 5 modes,
second-order inertia; RK4 0.25 ms with projection; 0.12 s, quick 0.06 s) against the finite-segment DAE
(:func:`flexible_reference`) at 8 and 16 segments (quick 4 and 8) extrapolated in ``1/N^2``; its crank-angle error as
a share of the flexible effect (rigid vs DAE).
"""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

import ctmm
from ctmm.control import ControlledModel, Feedback, with_feedback
from ctmm.nonlinear_laws import CubicSpring, Law, PowerDamper
from ctmm.planar import Fixed, NonlinearHinge, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.closed_loops import KinematicLoopModel, CutJoint, simulate_kinematic_loops
from ctmm.reference.planar_dae import PlanarDAE
from ctmm.scenario import accuracy

from .planar_common import save_figure

NAME = "four_bar"
DESCRIPTION = ("Four-bar linkage closed by a cut joint (boundary unknowns), nonlinear rocker spring and "
               "damper; angles, cut force, drift and energy vs the global DAE reference")
CRANK, COUPLER, ROCKER, GROUND = 0.2, 0.6, 0.5, 0.7            # [m]
MASSES = {"crank": 0.4, "coupler": 1.0, "rocker": 0.8}          # [kg]
LENGTHS = {"crank": CRANK, "coupler": COUPLER, "rocker": ROCKER}
REST = 1.9                                                       # rocker spring rest angle [rad]
SPRING = CubicSpring(2.0, 15.0)
DAMPER = PowerDamper(0.02, 2.0)
BODIES = ("crank", "coupler", "rocker")
PD_GAINS = (8.0, 0.8)            # crank-angle PD loop: kp [N m/rad], kd [N m s/rad]
PD_TARGET = 1.2                  # its set point [rad]
PD_DELAY = 0.01                  # the delayed variant's loop delay [s]
FLEX_EI = 80.0                   # flexible variant: the coupler's bending stiffness [N m^2]
FLEX_MODES = 5                   # its clamped-free modes (with second-order inertia, docs/closed_loops.md §4b)
FLEX_STEP = 2.5e-4               # its RK4 step [s] (1 ms and 0.5 ms fail the projection: the stiff bent modes)


def mechanism(rocker_law: Law | None = None) -> KinematicLoopModel:
    """The linkage as a tree plus the cut joint ``h3``; ``rocker_law`` on the rocker pivot (None: smooth)."""
    rocker_hinge = (SmoothHinge("h4", parent="g4", child="rocker") if rocker_law is None else
                    NonlinearHinge("h4", parent="g4", child="rocker", moment_law=rocker_law, rest_angle=REST))
    links = {name: RigidBody.uniform_link(name, mass=MASSES[name], length=LENGTHS[name]) for name in BODIES}
    tree = PlanarModel("four_bar", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(GROUND, 0.0)),
        links["crank"], SmoothHinge("h1", parent="g", child="crank"),
        links["coupler"], SmoothHinge("h2", parent="crank", child="coupler"),
        links["rocker"], rocker_hinge], gravity=(0.0, -9.81))
    return KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.out")])


def reference(rocker_law: Law | None = None) -> PlanarDAE:
    """The same linkage as a global DAE (the law handed over as a plain function)."""
    dae = PlanarDAE(gravity=(0.0, -9.81))
    for name in BODIES:
        m, length = MASSES[name], LENGTHS[name]
        dae.add_body(name, mass=m, inertia=m * length ** 2 / 12,
                     points={"in": (-length / 2, 0.0), "out": (length / 2, 0.0)})
    dae.add_revolute(None, (0.0, 0.0), "crank", "in")
    dae.add_revolute("crank", "out", "coupler", "in")
    dae.add_revolute(None, (GROUND, 0.0), "rocker", "in",
                     moment=None if rocker_law is None else (lambda d, v: float(rocker_law.force(d, v))), rest=REST)
    dae.add_revolute("rocker", "out", "coupler", "out")
    return dae


def flexible_mechanism(bending_stiffness: float, *, n_modes: int = 3, geometric_stiffening: bool = True,
                       second_order_inertia: bool = False) -> KinematicLoopModel:
    """The smooth linkage with the coupler a ``ModalBeam`` (``EI`` [N m^2], 1 kg over 0.6 m, ``n_modes``
    clamped-free modes in its root-tangent frame, axially rigid), cut at its outboard end ``"out"``;
    ``second_order_inertia`` moves the beam's mass points with their foreshortening (``docs/closed_loops.md`` §4b)."""
    from ctmm.flexible import ModalBeam

    coupler = ModalBeam("coupler", length=COUPLER, bending_stiffness=bending_stiffness,
                        mass_per_length=MASSES["coupler"] / COUPLER, n_modes=n_modes,
                        geometric_stiffening=geometric_stiffening, second_order_inertia=second_order_inertia)
    tree = PlanarModel("four_bar_flexible", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(GROUND, 0.0)),
        RigidBody.uniform_link("crank", mass=MASSES["crank"], length=CRANK), SmoothHinge("h1", parent="g", child="crank"),
        coupler, SmoothHinge("h2", parent="crank", child="coupler"),
        RigidBody.uniform_link("rocker", mass=MASSES["rocker"], length=ROCKER),
        SmoothHinge("h4", parent="g4", child="rocker")], gravity=(0.0, -9.81))
    return KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.out")])


def flexible_start(loop: KinematicLoopModel) -> tuple[np.ndarray, np.ndarray]:
    """Crank at 90 deg with 3 rad/s, the coupler straight (modal coordinates and rates 0), the rest assembled."""
    names = loop.tree.coordinates
    modal = [name for name in names if name.startswith("coupler.q")]
    q = [math.pi / 2 if n == "crank.theta" else 0.5 if n == "coupler.theta" else 1.8 if n == "rocker.theta" else 0.0
         for n in names]
    v = [3.0 if n == "crank.theta" else 0.0 for n in names]
    return loop.consistent_state(q, v, keep=["crank.theta", *modal])


def flexible_reference(bending_stiffness: float, n_segments: int) -> PlanarDAE:
    """The flexible linkage as a global DAE: the coupler ``n_segments`` rigid segments (mass and inertia of their
    share of the uniform bar) joined by revolute joints with rotational springs ``EI / h`` (finite segments)."""
    dae = PlanarDAE(gravity=(0.0, -9.81))
    for name in ("crank", "rocker"):
        m, length = MASSES[name], LENGTHS[name]
        dae.add_body(name, mass=m, inertia=m * length ** 2 / 12,
                     points={"in": (-length / 2, 0.0), "out": (length / 2, 0.0)})
    h, m = COUPLER / n_segments, MASSES["coupler"] / n_segments
    for i in range(n_segments):
        dae.add_body(f"s{i}", mass=m, inertia=m * h * h / 12, points={"in": (-h / 2, 0.0), "out": (h / 2, 0.0)})
    dae.add_revolute(None, (0.0, 0.0), "crank", "in")
    dae.add_revolute("crank", "out", "s0", "in")
    for i in range(1, n_segments):
        dae.add_revolute(f"s{i - 1}", "out", f"s{i}", "in", moment=lambda d, v: bending_stiffness / h * d)
    dae.add_revolute(None, (GROUND, 0.0), "rocker", "in")
    dae.add_revolute("rocker", "out", f"s{n_segments - 1}", "out")
    return dae


def pd_loop(loop: KinematicLoopModel, delay: float) -> ControlledModel:
    """``loop`` with the PD crank-angle loop ``u = -(KP theta + KD theta' - r)`` on the crank hinge torque
    (``theta``, ``theta'`` read ``delay`` seconds late; ``r = KP * PD_TARGET``: the reference of :func:`run`)."""
    return with_feedback(loop, [Feedback("pd", sensor=[("h1.angle", PD_GAINS[0]), ("h1.rate", PD_GAINS[1])],
                                         actuator="h1.torque", gain=1.0, delay=delay)])


def pd_reference(rocker_law: Law | None, delay: float) -> PlanarDAE:
    """:func:`reference` with the same PD law as a motor on the crank (the DAE's method of steps for the delay)."""
    kp, kd = PD_GAINS
    dae = reference(rocker_law)
    dae.add_motor(None, "crank", lambda t, angle, rate: -(kp * angle + kd * rate - kp * PD_TARGET), delay=delay)
    return dae


def start(loop: KinematicLoopModel) -> tuple[np.ndarray, np.ndarray]:
    """Crank at 90 deg with 3 rad/s; coupler and rocker assembled."""
    return loop.consistent_state([math.pi / 2, 0.5, 1.8], [3.0, 0.0, 0.0], keep=["crank.theta"])


def flexible_variant(t_final: float, segments: tuple[int, int]) -> dict:
    """The flexible-coupler linkage (``FLEX_EI``, ``FLEX_MODES`` modes, second-order inertia; RK4 ``FLEX_STEP``
    with projection) against the finite-segment DAE at the coarse and fine segment counts ``segments`` and their
    Richardson extrapolation in ``1/N^2`` (the converged reference), plus the rigid linkage (the flexible effect).

    Returns the time [s], crank angles [rad] (ctmm, rigid, each DAE, extrapolated), ``coupler.q1`` [m], the
    cut-joint drift [m] and the wall times [s]."""
    loop = flexible_mechanism(FLEX_EI, n_modes=FLEX_MODES, second_order_inertia=True)
    q0, v0 = flexible_start(loop)
    flexible = simulate_kinematic_loops(loop, q0, v0, t_final=t_final, dt=FLEX_STEP)
    rigid_loop = mechanism()
    rigid_q0, rigid_v0 = start(rigid_loop)
    rigid = simulate_kinematic_loops(rigid_loop, rigid_q0, rigid_v0, t_final=t_final, dt=FLEX_STEP)
    crank_dae, began = {}, time.perf_counter()
    for n in segments:
        dae = flexible_reference(FLEX_EI, n)
        state = dae.assemble({"crank": q0[0], "rocker": q0[-1], **{f"s{i}": q0[1] for i in range(n)}},
                             {"crank": v0[0], "rocker": v0[-1], **{f"s{i}": v0[1] for i in range(n)}})
        crank_dae[n] = dae.simulate(state, t_final, t_eval=flexible.t, rtol=1e-8, atol=1e-12).angle("crank")
    coarse, fine = segments
    ratio = (fine / coarse) ** 2
    extrapolated = crank_dae[fine] + (crank_dae[fine] - crank_dae[coarse]) / (ratio - 1.0)
    return {"t": flexible.t, "crank": flexible.coordinate("crank.theta"), "rigid": rigid.coordinate("crank.theta"),
            "dae": crank_dae, "extrapolated": extrapolated, "q1": flexible.coordinate("coupler.q1"),
            "drift": flexible.drift, "wall_time_s": flexible.wall_time_s,
            "reference_wall_time_s": time.perf_counter() - began}


def _angle_error(simulation, solution) -> np.ndarray:
    return np.max([np.abs(simulation.coordinate(f"{n}.theta") - solution.angle(n)) for n in BODIES], axis=0)


def run(output_dir: Path, quick: bool = False) -> dict:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t_final, h = (0.25 if quick else 2.0), 1e-3
    law = SPRING + DAMPER
    loop = mechanism(law)
    q0, v0 = start(loop)
    rk4 = simulate_kinematic_loops(loop, q0, v0, t_final=t_final, dt=h)
    dop = simulate_kinematic_loops(loop, q0, v0, t_final=t_final, method="DOP853", rtol=1e-11, atol=1e-12)
    dae = reference(law)
    state = dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0)))
    began = time.perf_counter()
    ref = dae.simulate(state, t_final, t_eval=rk4.t)
    reference_wall = time.perf_counter() - began
    ref_dop = dae.simulate(state, t_final, t_eval=dop.t)
    error_rk4, error_dop = _angle_error(rk4, ref), _angle_error(dop, ref_dop)
    force_scale = float(np.max(np.abs(ref.forces[:, 3])))
    force_error = float(np.max(np.abs(rk4.cut_force[:, 0] - ref.forces[:, 3]))) / force_scale
    # energy: the undamped linkage (spring only)
    undamped = mechanism(SPRING)
    conservative = simulate_kinematic_loops(undamped, q0, v0, t_final=t_final, dt=h)
    energy = conservative.energy()
    energy_drift = float(np.max(np.abs(energy - energy[0])) / np.max(np.abs(energy)))

    # the PD crank-angle loop (ctmm.control.with_feedback on the kinematic loop model), real-time and delayed
    controlled, controlled_error, controlled_wall = {}, {}, {}
    for delay in (0.0, PD_DELAY):
        began = time.perf_counter()
        controlled[delay] = ctmm.simulate(pd_loop(loop, delay), t_final, h, x0=q0, v0=v0,
                                          references={"pd": PD_GAINS[0] * PD_TARGET})
        controlled_wall[delay] = time.perf_counter() - began
        dae_pd = pd_reference(law, delay)
        ref_pd = dae_pd.simulate(state, t_final, t_eval=controlled[delay].time)
        controlled_error[delay] = float(max(np.max(np.abs(controlled[delay][f"{n}.theta"] - ref_pd.angle(n)))
                                            for n in BODIES))

    # the flexible coupler (a 5-mode ModalBeam with second-order inertia) vs the finite-segment DAE, extrapolated
    segments = (4, 8) if quick else (8, 16)
    flex = flexible_variant(0.06 if quick else 0.12, segments)     # 16 segments: ~25 s for 0.12 s
    effect = float(np.max(np.abs(flex["rigid"] - flex["extrapolated"])))       # what the flexibility changes
    flex_error = float(np.max(np.abs(flex["crank"] - flex["extrapolated"]))) / effect
    flex_reference_change = float(np.max(np.abs(flex["dae"][segments[1]] - flex["extrapolated"]))) / effect
    coarse_change = np.max(np.abs(flex["dae"][segments[1]] - flex["dae"][segments[0]]))

    fig, axes = plt.subplots(4, 2, figsize=(12, 16))
    for n in BODIES:
        axes[0, 0].plot(rk4.t, rk4.coordinate(f"{n}.theta"), label=f"{n} (ctmm)")
        axes[0, 0].plot(ref.t, ref.angle(n), "k--", lw=0.8)
    axes[0, 0].set(xlabel="t [s]", ylabel="absolute angle [rad]", title="angles (dashed: global DAE)")
    axes[0, 0].legend(fontsize="small")
    axes[0, 1].plot(rk4.t, rk4.cut_force[:, 0, 0], label="f_x (ctmm)")
    axes[0, 1].plot(rk4.t, rk4.cut_force[:, 0, 1], label="f_y (ctmm)")
    axes[0, 1].plot(ref.t, ref.forces[:, 3, 0], "k--", lw=0.8, label="global DAE")
    axes[0, 1].plot(ref.t, ref.forces[:, 3, 1], "k--", lw=0.8)
    axes[0, 1].set(xlabel="t [s]", ylabel="cut-joint force on the coupler [N]")
    axes[0, 1].legend(fontsize="small")
    axes[1, 0].semilogy(rk4.t, error_rk4 + 1e-17, label="RK4 1 ms + projection")
    axes[1, 0].semilogy(dop.t, error_dop + 1e-17, label="DOP853 1e-11 + Baumgarte")
    axes[1, 0].set(xlabel="t [s]", ylabel="max angle error vs DAE [rad]")
    axes[1, 0].legend(fontsize="small")
    axes[1, 1].semilogy(rk4.t, rk4.drift + 1e-17, label="RK4 + projection")
    axes[1, 1].semilogy(dop.t, dop.drift + 1e-17, label="DOP853 + Baumgarte (alpha = 20/s)")
    axes[1, 1].semilogy(conservative.t, np.abs(energy - energy[0]) + 1e-17, label="energy error, undamped [J]")
    axes[1, 1].set(xlabel="t [s]", ylabel="constraint drift |Phi| [m]")
    axes[1, 1].legend(fontsize="small")
    for delay, style in ((0.0, "-"), (PD_DELAY, "--")):
        run_pd = controlled[delay]
        label = "real-time" if delay == 0.0 else f"delay {delay * 1e3:g} ms"
        axes[2, 0].plot(run_pd.time, run_pd["crank.theta"], style, label=f"crank, PD {label}")
        axes[2, 1].plot(run_pd.time, run_pd["pd.u"], style, label=f"torque, PD {label}")
    axes[2, 0].plot(rk4.t, rk4.coordinate("crank.theta"), "k:", lw=0.8, label="crank, free")
    axes[2, 0].axhline(PD_TARGET, color="grey", lw=0.5)
    axes[2, 0].set(xlabel="t [s]", ylabel="crank angle [rad]",
                   title=f"PD crank loop (kp, kd = {PD_GAINS}), set point {PD_TARGET} rad")
    axes[2, 0].legend(fontsize="small")
    axes[2, 1].set(xlabel="t [s]", ylabel="crank torque [N m]",
                   title=f"max angle error vs DAE: {controlled_error[0.0]:.1e} / {controlled_error[PD_DELAY]:.1e} rad")
    axes[2, 1].legend(fontsize="small")
    axes[3, 0].plot(flex["t"], flex["rigid"] - flex["rigid"], "k:", lw=0.8, label="rigid coupler")
    axes[3, 0].plot(flex["t"], flex["crank"] - flex["rigid"], label=f"modal coupler ({FLEX_MODES} modes, ctmm)")
    for n in segments:
        axes[3, 0].plot(flex["t"], flex["dae"][n] - flex["rigid"], "--", lw=0.8, label=f"DAE, {n} segments")
    axes[3, 0].plot(flex["t"], flex["extrapolated"] - flex["rigid"], "k-.", lw=0.8, label="DAE, extrapolated")
    axes[3, 0].set(xlabel="t [s]", ylabel="crank angle - rigid linkage's [rad]",
                   title=f"flexible coupler EI = {FLEX_EI:g} N m^2: error {100 * flex_error:.2f} % of the effect")
    axes[3, 0].legend(fontsize="small")
    axes[3, 1].plot(flex["t"], flex["q1"], label="coupler.q1 (ctmm)")
    axes[3, 1].set(xlabel="t [s]", ylabel="first modal coordinate [m]", title="coupler bending")
    axes[3, 1].legend(fontsize="small")
    save_figure(fig, output_dir, NAME)
    source = "docs/closed_loops.md: four-bar targets"
    return {
        "accuracy": [
            accuracy("angle error vs global DAE", float(np.max(error_rk4)), "rad", 1e-6,
                     "max over the run and the three links of |theta_ctmm (RK4 1 ms, projection) - theta_DAE|",
                     source=source),
            accuracy("cut force error vs global DAE", force_error, "relative", 1e-4,
                     "max |lambda_ctmm - lambda_DAE| / max |lambda_DAE| of the cut joint h3 (RK4 run)", source=source),
            accuracy("constraint drift", float(max(np.max(rk4.drift), np.max(dop.drift))), "m", 1e-9,
                     "max |Phi| of the cut joint, RK4 with projection and DOP853 with Baumgarte", source=source),
            accuracy("energy drift, undamped", energy_drift, "relative", 1e-6,
                     "max |E - E0| / max |E| of the linkage without the damper (RK4 1 ms, projection)",
                     source=source),
            accuracy("PD crank loop angle error vs DAE, real-time", controlled_error[0.0], "rad", 1e-8,
                     "max |theta_ctmm - theta_DAE| of the with_feedback run (RK4 1 ms, Baumgarte) vs the DAE with "
                     "the same PD law as a crank motor", source=source),
            accuracy("PD crank loop angle error vs DAE, delayed", controlled_error[PD_DELAY], "rad", 1e-8,
                     f"as above with the loop delay {PD_DELAY} s (ctmm: delay history; DAE: method of steps)",
                     source=source),
            accuracy("flexible coupler crank-angle error vs extrapolated DAE", flex_error, "share of the effect", 0.02,
                     f"max |theta_crank,ctmm - theta_crank,DAE| / max |theta_crank,rigid - theta_crank,DAE|: coupler "
                     f"EI = {FLEX_EI:g} N m^2, {FLEX_MODES} modes, second-order inertia, RK4 {FLEX_STEP:g} s with "
                     f"projection; DAE: {segments[0]} and {segments[1]} rigid segments extrapolated in 1/N^2. Bound: "
                     "the truncation to 5 modes (the independent same-truncation Lagrange model: 0.55 % at 0.06 s, "
                     "docs/closed_loops.md §4b)", source=source),
            accuracy("flexible coupler DAE reference change, fine to extrapolated", flex_reference_change,
                     "share of the effect", 0.005,
                     "max |theta_crank,DAE(fine) - theta_crank,DAE(extrapolated)| / the flexible effect: the "
                     "reference's own discretisation error estimate, a quarter of the error bound above so that "
                     "the reference resolves it", source=source),
            accuracy("flexible coupler constraint drift", float(np.max(flex["drift"])), "m", 1e-9,
                     "max |Phi| of the cut joint at the modal beam's end (RK4 with projection)", source=source)],
        "angle_max_error_dop853_rad": float(np.max(error_dop)),
        "max_cut_force_N": force_scale,
        "crank_turns": float(np.ptp(rk4.coordinate("crank.theta")) / (2 * np.pi)),
        "wall_time_s": rk4.wall_time_s,
        "dop853_wall_time_s": dop.wall_time_s,
        "reference_wall_time_s": reference_wall,
        "energy_drift": energy_drift,
        "evaluations_rk4": rk4.n_evaluations,
        "pd_loop_wall_time_s": controlled_wall,
        "flexible_effect_rad": effect,
        "flexible_dae_segments": list(segments),
        "flexible_dae_change_coarse_to_fine_rad": float(coarse_change),
        "flexible_wall_time_s": flex["wall_time_s"],
        "flexible_reference_wall_time_s": flex["reference_wall_time_s"],
        "pd_loop_final_crank_rad": {delay: float(run_pd["crank.theta"][-1]) for delay, run_pd in controlled.items()},
    }
