"""Cut joints carrying a moment law and an actuator torque (ctmm.planar.cut_joints, docs/closed_loops.md §2a).

The law acts on the relative angle across the cut ``dtheta = theta_child - theta_parent`` (at a ``ModalBeam`` end:
the frame angle plus the elastic end slope); the moment ``tau = torque(t) - law(dtheta - rest, dtheta')`` acts on the
child side and ``-tau`` on the parent side.  Independent reference: the global DAE of ``ctmm.reference.planar_dae``
(every joint a revolute constraint with multipliers, the law written there as a plain function on its own absolute
angles, the torque as its motor), no code shared with the sweep or the cut mechanism; the frequency checks use
the DAE's stiffness, damping and torque gain measured on its own constraints.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.optimize

import ctmm
from ctmm.errors import ModelError
from ctmm.nonlinear_laws import CubicSpring, LinearLaw
from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel, simulate_kinematic_loops
from ctmm.planar.implicit_kinematic_loops import simulate_loop_scheme
from ctmm.scenarios.four_bar import BODIES, GROUND, LENGTHS, MASSES, flexible_mechanism, flexible_reference
from ctmm.scenarios.four_bar import flexible_start
from ctmm.scenarios.four_bar import reference as four_bar_dae
from ctmm.schemes import as_scheme

REST = -1.3                      # rest relative angle coupler - rocker at the cut [rad]
SPRING_DAMPER = LinearLaw(3.0, 0.05)


def _torque(t: float) -> float:
    return 0.3 * math.sin(7.0 * t)


def _loop(law, torque=None) -> KinematicLoopModel:
    links = {name: RigidBody.uniform_link(name, mass=MASSES[name], length=LENGTHS[name]) for name in BODIES}
    tree = PlanarModel("four_bar_cut_law", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(GROUND, 0.0)),
        links["crank"], SmoothHinge("h1", parent="g", child="crank"),
        links["coupler"], SmoothHinge("h2", parent="crank", child="coupler"),
        links["rocker"], SmoothHinge("h4", parent="g4", child="rocker")], gravity=(0.0, -9.81))
    cut = CutJoint("h3", parent="rocker.out", child="coupler.out", moment_law=law, rest_angle=REST, torque=torque)
    return KinematicLoopModel(tree, [cut])


def _dae(law, torque=None, crank_torque: float = 0.0):
    """The same linkage as the global DAE: the law on its cut revolute (coupler relative to rocker), the torque as a
    motor from the rocker on the coupler, an optional constant crank torque from the ground."""
    dae = four_bar_dae(None)
    cut = dae.joints[-1]                                   # rocker.out - coupler.out
    cut.moment, cut.rest = (lambda d, v: float(law.force(d, v))), REST
    if torque is not None:
        dae.add_motor("rocker", "coupler", lambda t, angle, rate: torque(t))
    if crank_torque:
        dae.add_motor(None, "crank", lambda t, angle, rate: crank_torque)
    return dae


def _start(loop):
    return loop.consistent_state([math.pi / 2, 0.5, 1.8], [3.0, 0.0, 0.0], keep=["crank.theta"])


def test_spring_damper_and_torque_at_the_cut_match_the_dae_with_every_method():
    """RK4 1 ms (projection) and DOP853 over 0.2 s, Newmark 2 / 1 ms over 0.06 s (the order needs the step sizes in
    the asymptotic range, not the long run) against the DAE.  Measured: RK4 3.0e-10 rad, cut force 5.8e-9 N of
    7.9 N; DOP853 1.9e-12 rad; Newmark 1.6e-6 / 3.9e-7 rad (ratio 4.004, order 2)."""
    loop = _loop(SPRING_DAMPER, _torque)
    q0, v0 = _start(loop)
    rk4 = ctmm.simulate(loop, 0.2, 1e-3, x0=q0, v0=v0)
    dae = _dae(SPRING_DAMPER, _torque)
    reference = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.2, t_eval=rk4.time)
    assert max(np.max(np.abs(rk4[f"{n}.theta"] - reference.angle(n))) for n in BODIES) < 3e-9
    force = reference.forces[:, 3, :]                   # the DAE's cut multiplier: the force on the coupler
    for axis, column in (("x", 0), ("y", 1)):
        assert np.max(np.abs(rk4[f"h3.force_{axis}"] - force[:, column])) < 1e-8 * np.max(np.abs(force))
    smooth = ctmm.simulate(_loop(None), 0.2, 1e-3, x0=q0, v0=v0)
    assert np.max(np.abs(smooth["crank.theta"] - rk4["crank.theta"])) > 1e-2     # the law matters here
    dop = ctmm.simulate(loop, 0.2, 1e-2, x0=q0, v0=v0, method="DOP853", rtol=1e-11, atol=1e-12)
    assert np.max(np.abs(dop["crank.theta"] - reference.angle("crank")[::10])) < 1e-9
    assert reference.t[60] == pytest.approx(0.06, abs=1e-12)
    errors = [abs(ctmm.simulate(loop, 0.06, dt, x0=q0, v0=v0, method="newmark")["crank.theta"][-1]
                  - reference.angle("crank")[60]) for dt in (2e-3, 1e-3)]          # the DAE at t = 0.06 s
    assert errors[1] < 1e-4 and 3.5 < errors[0] / errors[1] < 4.5


def test_relative_angle_and_moment_convention():
    loop = _loop(SPRING_DAMPER, _torque)
    q0, v0 = _start(loop)
    angle, rate = loop.relative_angles(q0, v0)
    assert angle[0] == pytest.approx(q0[1] - q0[2], abs=1e-15) and rate[0] == pytest.approx(v0[1] - v0[2], abs=1e-15)
    expected = _torque(0.1) - SPRING_DAMPER.force(angle[0] - REST, rate[0])
    assert loop.cut_moments(q0, v0, 0.1)[0] == pytest.approx(expected, rel=1e-14)


def test_undamped_cut_spring_conserves_energy_with_its_potential():
    """A cubic spring at the cut: the tree's energy plus the spring's potential is conserved (RK4 0.5 ms with
    projection, 0.15 s; measured 4.8e-13 relative) while the spring's potential itself changes by far more."""
    loop = _loop(CubicSpring(3.0, 20.0))
    q0, v0 = _start(loop)
    run = simulate_kinematic_loops(loop, q0, v0, t_final=0.15, dt=5e-4)
    energy = run.energy()
    spring = np.array([loop.cut_potential(q) for q in run.q])
    assert np.ptp(spring) > 0.1                                    # measured 0.28
    assert np.max(np.abs(energy - energy[0])) < 1e-8 * np.max(np.abs(energy))
    dae = _dae(CubicSpring(3.0, 20.0))
    q_dae, v_dae = dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0)))
    potential = [None, None, None, lambda d: float(CubicSpring(3.0, 20.0).potential(d))]
    assert energy[0] == pytest.approx(dae.energy(q_dae, v_dae, potential), rel=1e-12)


def test_stored_cut_forces_are_the_solve_at_each_row_without_solving_it_twice():
    """The cut forces of an RK4 run (every 2nd step stored) are ``KinematicLoopModel.solve`` at each stored row,
    exactly; the rows the next step's first stage already solved are not solved again (only the last row is)."""
    loop = _loop(SPRING_DAMPER, torque=_torque)
    q0, v0 = _start(loop)
    calls = []
    solve = loop.solve
    loop.solve = lambda q, v, t=0.0, inputs=None: (calls.append(t), solve(q, v, t, inputs))[1]
    run = simulate_kinematic_loops(loop, q0, v0, t_final=0.02, dt=1e-3, store_every=2)
    assert len(run.t) == 11 and len(calls) == 4 * 20 + 1 and calls[-1] == run.t[-1]
    for t, q, v, force in zip(run.t, run.q, run.qdot, run.cut_force):
        np.testing.assert_array_equal(force, solve(q, v, t)[1])


def test_dae_rows_carry_the_drift_and_forces_of_one_solve_per_row():
    """The DAE reference's stored drift (the joints' ``Phi``, not the drive row), joint forces and drive moment are
    ``constraints`` and ``solve`` at each row exactly, from one evaluation of the constraints per stored row (the
    integration's own count does not depend on the output grid)."""
    drive = _drive()
    dae = four_bar_dae(None)
    dae.add_drive("rocker", "coupler", drive["angle"], drive["angle_rate"], drive["angle_acceleration"])
    loop = KinematicLoopModel(_loop(None).tree, [CutJoint("h3", parent="rocker.out", child="coupler.out", **drive)])
    q0, v0 = loop.consistent_state([math.pi / 2, 0.5, 1.8], [0.0, 0.0, 0.0])
    state = dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0)))
    constraints, calls = dae.constraints, []
    dae.constraints = lambda q, v: (calls.append(1), constraints(q, v))[1]
    counts, runs = [], []
    for rows in (3, 21):
        calls.clear()
        runs.append(dae.simulate(state, 0.02, t_eval=np.linspace(0.0, 0.02, rows)))
        counts.append(len(calls))
    assert counts[1] - counts[0] == 21 - 3
    run = runs[1]
    for k, (t, q, v) in enumerate(zip(run.t, run.q, run.v)):
        assert run.drift[k] == np.max(np.abs(constraints(q, v)[0]))
        multipliers = dae.solve(q, v, 10.0, t)[1]
        np.testing.assert_array_equal(run.forces[k].ravel(), multipliers[:-1])
        np.testing.assert_array_equal(run.drive_moments[k], multipliers[-1:])
    assert np.max(run.drift) > 0.0 and np.ptp(run.drive_moments) > 0.0


def _dae_manifold_state(dae, crank: float, crank_rate: float, guess):
    """DAE state with the crank at ``crank`` [rad] and ``crank_rate`` [rad/s], the others from the DAE's own
    loop constraint (positions by a root solve, rates by its linear velocity constraint)."""
    def residual(angles):
        q, v = dae.assemble(dict(zip(BODIES, [crank, *angles])), dict.fromkeys(BODIES, 0.0))
        return dae.constraints(q, v)[0][-2:]

    angles = scipy.optimize.fsolve(residual, guess, xtol=1e-13)
    assert np.max(np.abs(residual(angles))) < 1e-12
    unit = []
    for k in range(3):
        q, v = dae.assemble(dict(zip(BODIES, [crank, *angles])), dict(zip(BODIES, np.eye(3)[k])))
        unit.append(dae.constraints(q, v)[1][-2:])
    rates = np.linalg.solve(np.column_stack(unit[1:]), -crank_rate * unit[0])
    return dae.assemble(dict(zip(BODIES, [crank, *angles])), dict(zip(BODIES, [crank_rate, *rates]))), angles


def test_frequency_verbs_with_a_cut_spring_damper_match_the_dae():
    """About the static equilibrium with the spring at the cut: the undamped frequency, and with the damper the
    crank's response to a crank torque ``g / (k - omega^2 + i c omega)`` and to a torque across the cut (the input
    ``"h3.torque"``) ``g_cut / (...)``, the DAE's ``k``, ``c``, ``g``, ``g_cut`` measured on its own constraints
    (measured: frequency 3.6e-11, responses 1.3e-9, set by the DAE's central differences at step 1e-5)."""
    spring = LinearLaw(3.0, 0.0)
    loop = _loop(spring)
    guess, _ = loop.consistent_state([-1.5, 0.5, 1.8], [0.0, 0.0, 0.0], keep=["crank.theta"])
    q_eq = loop.equilibrium(guess)
    point = (q_eq, np.zeros(3))
    h = 1e-5
    for law in (spring, SPRING_DAMPER):
        dae, torque = _dae(law), _dae(law, crank_torque=1.0)
        state, angles = _dae_manifold_state(dae, q_eq[0], 0.0, q_eq[1:])
        assert np.max(np.abs(dae.solve(*state)[0])) < 1e-9                 # the loop's equilibrium is the DAE's
        plus, minus = (_dae_manifold_state(dae, q_eq[0] + s, 0.0, angles)[0] for s in (h, -h))
        k = -(dae.solve(*plus)[0][2] - dae.solve(*minus)[0][2]) / (2 * h)
        fast, slow = (_dae_manifold_state(dae, q_eq[0], s, angles)[0] for s in (h, -h))
        c = -(dae.solve(*fast)[0][2] - dae.solve(*slow)[0][2]) / (2 * h)
        g = torque.solve(*state)[0][2] - dae.solve(*state)[0][2]
        if law is spring:
            assert abs(c) < 1e-6
            (omega_n,) = ctmm.natural_frequencies(_loop(law), operating_point=point)
            assert omega_n ** 2 == pytest.approx(k, rel=5e-10)                    # measured 3.6e-11
            continue
        assert c > 1e-3
        cut_torque = _dae(law, lambda t: 1.0)                                # 1 N m across the cut
        g_cut = cut_torque.solve(*state)[0][2] - dae.solve(*state)[0][2]
        omega = np.array([0.0, 0.5, 1.0, 2.0]) * math.sqrt(k)
        frf = ctmm.frequency_response(_loop(law), omega, input=["h1.torque", "h3.torque"], output="crank.theta",
                                      operating_point=point)
        np.testing.assert_allclose(frf("crank.theta", "h1.torque"), g / (k - omega ** 2 + 1j * c * omega), rtol=1e-8)
        np.testing.assert_allclose(frf("crank.theta", "h3.torque"), g_cut / (k - omega ** 2 + 1j * c * omega),
                                   rtol=1e-8)                                  # measured 1.3e-9 (the DAE's k, c)
        assert abs(g_cut) > 0.1 * abs(g) and frf.units["h3.torque"] == "N m"
        with pytest.raises(ModelError, match="damp"):
            ctmm.natural_frequencies(_loop(law), operating_point=point)


def test_cut_spring_at_a_modal_beam_end():
    """The flexible coupler (EI = 20 N m^2, 3 modes) with a torsional spring at its tip's cut: the moment acts on the
    beam frame and, through the end slope, on the modal coordinates.  Undamped, without geometric stiffening, the
    energy with the spring's potential is conserved to RK4's error (0.03 s, 0.25 / 0.125 ms: measured 1.1e-8 /
    3.7e-10 relative, falling at fourth order: no work of the law is lost); the spring's effect on the crank
    angle matches the finite-segment DAE's (the law on the last segment's angle) to 3 % of the effect (measured
    1.4 %; the first-order beam's own gap, docs/closed_loops.md §4b, bounds it)."""
    law = LinearLaw(4.0, 0.0)
    plain = flexible_mechanism(20.0, geometric_stiffening=False)
    cut = plain.cuts[0]
    loop = KinematicLoopModel(plain.tree, [CutJoint(cut.name, cut.parent, cut.child, moment_law=law, rest_angle=REST)])
    q0, v0 = flexible_start(loop)
    index = loop.tree.coordinate_index
    bent = np.array(q0)
    bent[index("coupler.q1")] = 0.01
    slope = loop.tree.beams[loop.tree.body_names.index("coupler")].data.end_dphi[0][0] * 0.01
    assert (loop.relative_angles(bent, v0)[0] - loop.relative_angles(q0, v0)[0])[0] == pytest.approx(slope, rel=1e-12)
    drifts = []
    for dt in (2.5e-4, 1.25e-4):                         # the energy error is RK4's: it falls at fourth order
        run = simulate_kinematic_loops(loop, q0, v0, t_final=0.03, dt=dt)
        energy = run.energy()
        drifts.append(np.max(np.abs(energy - energy[0])) / np.max(np.abs(energy)))
    assert drifts[1] < 1e-9 and drifts[0] / drifts[1] > 10.0
    smooth = simulate_kinematic_loops(plain, q0, v0, t_final=0.03, dt=2.5e-4)
    effect = run.coordinate("crank.theta")[::2] - smooth.coordinate("crank.theta")
    segments = 8

    def dae_crank(with_law: bool) -> np.ndarray:
        dae = flexible_reference(20.0, segments)
        if with_law:
            dae.joints[-1].moment, dae.joints[-1].rest = (lambda d, v: float(law.force(d, v))), REST
        angles = {"crank": q0[0], "rocker": q0[-1], **{f"s{i}": q0[1] for i in range(segments)}}
        rates = {"crank": v0[0], "rocker": v0[-1], **{f"s{i}": v0[1] for i in range(segments)}}
        # rtol 1e-8: the effect moves by 3e-14 rad from rtol 1e-10's, a 1e-9 part of the 3 % bound
        return dae.simulate(dae.assemble(angles, rates), 0.03, t_eval=smooth.t, rtol=1e-8, atol=1e-10).angle("crank")

    dae_effect = dae_crank(True) - dae_crank(False)
    assert np.max(np.abs(effect)) > 1e-3
    assert np.max(np.abs(effect - dae_effect)) < 0.03 * np.max(np.abs(dae_effect))


def test_bad_laws_are_refused_by_name():
    with pytest.raises(ModelError, match="moment_law must be a ctmm.nonlinear_laws.Law"):
        CutJoint("h3", parent="rocker.out", child="coupler.out", moment_law=lambda d, v: d)
    with pytest.raises(ModelError, match="rest_angle"):
        CutJoint("h3", parent="rocker.out", child="coupler.out", rest_angle=float("nan"))
    with pytest.raises(ModelError, match="torque"):
        CutJoint("h3", parent="rocker.out", child="coupler.out", torque="fast")


def _drive() -> dict:
    return dict(angle=lambda t: REST + 0.4 * math.sin(3.0 * t), angle_rate=lambda t: 1.2 * math.cos(3.0 * t),
                angle_acceleration=lambda t: -3.6 * math.sin(3.0 * t))


def test_driven_cut_angle_matches_the_dae_with_every_method():
    """The four-bar's relative angle at the cut prescribed (0 DOF left): motion, cut force and drive moment against
    the DAE with its own drive row (``PlanarDAE.add_drive``), 0.15 s (Newmark 0.06 s).  Measured: RK4 1 ms 1.2e-13
    rad, force 4.2e-13 N, moment 1.1e-12 N m (of 2.2 N m); Newmark 2 / 1 ms 8.3e-8 / 2.1e-8 rad (ratio 4.0002)."""
    drive = _drive()
    loop = KinematicLoopModel(_loop(None).tree, [CutJoint("h3", parent="rocker.out", child="coupler.out", **drive)])
    q0, v0 = loop.consistent_state([math.pi / 2, 0.5, 1.8], [0.0, 0.0, 0.0])     # the drive fixes the angles
    assert loop.relative_angles(q0, v0)[0][0] == pytest.approx(REST, abs=1e-12)
    run = ctmm.simulate(loop, 0.15, 1e-3, x0=q0, v0=v0)
    dae = four_bar_dae(None)
    dae.add_drive("rocker", "coupler", drive["angle"], drive["angle_rate"], drive["angle_acceleration"])
    reference = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.15, t_eval=run.time)
    assert max(np.max(np.abs(run[f"{n}.theta"] - reference.angle(n))) for n in BODIES) < 1e-10
    assert np.max(np.abs(run["h3.force_y"] - reference.forces[:, 3, 1])) < 1e-9 * np.max(np.abs(reference.forces))
    moment = reference.drive_moments[:, 0]
    assert np.max(np.abs(run["h3.moment"] - moment)) < 1e-9 * np.max(np.abs(moment)) and np.ptp(moment) > 0.5
    assert run.units(["h3.moment"]) == {"h3.moment": "N m"} and np.max(run["drift"]) < 1e-12
    dop = ctmm.simulate(loop, 0.15, 1e-2, x0=q0, v0=v0, method="DOP853", rtol=1e-11, atol=1e-12)
    assert np.max(np.abs(dop["crank.theta"] - reference.angle("crank")[::10])) < 1e-10
    # Newmark projects onto the cuts after every step: with no degree of freedom left that is the assembled
    # configuration at the drive's angle (measured 7e-16 rad); with Baumgarte alone it converges at order two
    # (the order needs the step sizes in the asymptotic range, not the long run: 0.06 s, the DAE's index 60)
    assert reference.t[60] == pytest.approx(0.06, abs=1e-12)
    projected = ctmm.simulate(loop, 0.06, 2e-3, x0=q0, v0=v0, method="newmark")
    assert abs(projected["crank.theta"][-1] - reference.angle("crank")[60]) < 1e-12
    errors = [abs(simulate_loop_scheme(loop, q0, v0, t_final=0.06, dt=dt, scheme=as_scheme("newmark"),
                                       projection=False)[0].coordinate("crank.theta")[-1] - reference.angle("crank")[60])
              for dt in (2e-3, 1e-3)]
    assert errors[1] < 1e-5 and 3.5 < errors[0] / errors[1] < 4.5
    with pytest.raises(ModelError, match="driven"):
        ctmm.linearize(loop, (q0, np.zeros(3)))
    with pytest.raises(ModelError, match="driven"):
        loop.equilibrium(q0)


def test_driven_cut_at_a_modal_beam_end_follows_the_drive():
    """The flexible coupler's tip driven relative to the rocker (the end angle includes the elastic slope): without
    projection and Baumgarte the drive row drifts only by RK4's truncation (its acceleration includes the slope's,
    ``phi'(x_e) . w''``); measured 4e-16 rad over 0.03 s (RK4 0.5 ms: a missing slope term would drift by the
    slope's own motion, whatever the step) while the slope itself moves by 4.5e-3 rad."""
    drive = _drive()
    plain = flexible_mechanism(20.0, geometric_stiffening=False)
    cut = plain.cuts[0]
    loop = KinematicLoopModel(plain.tree, [CutJoint(cut.name, cut.parent, cut.child, **drive)], baumgarte=0.0)
    names = loop.tree.coordinates
    modal = [name for name in names if name.startswith("coupler.q")]
    q0, v0 = loop.consistent_state([1.3 if n == "crank.theta" else 0.5 if n == "coupler.theta" else
                                    1.8 if n == "rocker.theta" else 0.0 for n in names], np.zeros(len(names)),
                                   keep=modal)
    run = simulate_kinematic_loops(loop, q0, v0, t_final=0.03, dt=5e-4, projection=False)
    drift = [abs(loop.constraints(q, v, t)[0][2]) for t, q, v in zip(run.t, run.q, run.qdot)]
    index = [loop.tree.coordinate_index(name) for name in modal]
    slope = loop.tree.beams[loop.tree.body_names.index("coupler")].data.end_dphi[0] @ run.q[:, index].T
    assert np.ptp(slope) > 1e-3 and max(drift) < 1e-8


def test_bad_drives_are_refused_by_name():
    with pytest.raises(ModelError, match="angle_rate and angle_acceleration must be a signal"):
        CutJoint("h3", parent="rocker.out", child="coupler.out", angle=lambda t: t * t, angle_rate=1.0)
    with pytest.raises(ModelError, match="takes no moment_law or torque"):
        CutJoint("h3", parent="rocker.out", child="coupler.out", angle=0.1, torque=1.0)


def test_feedback_loop_on_a_linkage_with_a_cut_spring_matches_the_dae():
    """A PD loop on the crank torque (``u = -(8 theta + 0.8 theta' - 9.6)``, through ``ctmm.control.with_feedback``)
    with the spring-damper and torque at the cut: the loop driver carries the law (RK4 1 ms, 0.1 s against the DAE
    with the PD as a crank motor; measured 7.3e-11 rad)."""
    from ctmm.control import Feedback, with_feedback

    loop = _loop(SPRING_DAMPER, _torque)
    q0, v0 = _start(loop)
    pd = Feedback("pd", sensor=[("h1.angle", 8.0), ("h1.rate", 0.8)], actuator="h1.torque", gain=1.0)
    run = ctmm.simulate(with_feedback(loop, [pd]), 0.1, 1e-3, x0=q0, v0=v0, references={"pd": 9.6})
    dae = _dae(SPRING_DAMPER, _torque)
    dae.add_motor(None, "crank", lambda t, angle, rate: -(8.0 * angle + 0.8 * rate - 9.6))
    reference = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.1, t_eval=run.time)
    assert max(np.max(np.abs(run[f"{n}.theta"] - reference.angle(n))) for n in BODIES) < 1e-8
    angle, rate = loop.relative_angles(q0, v0)
    assert run["h3.moment"][0] == pytest.approx(-SPRING_DAMPER.force(angle[0] - REST, rate[0]), rel=1e-12)


def test_scene_file_cut_joint_with_a_law(tmp_path):
    """A scene file's cut table carries the law, its rest angle and a drive as value tables / numbers."""
    from pathlib import Path

    from ctmm.scene_files import load_scene

    text = (Path(__file__).parent.parent / "scenarios" / "files" / "four_bar.toml").read_text()
    plain = 'cuts = [{ type = "CutJoint", name = "h3", parent = "rocker.out", child = "coupler.out" }]'
    assert plain in text
    law = plain[:-3] + ', rest_angle = -1.3, moment_law = { type = "LinearLaw", stiffness = 3.0, damping = 0.05 } }]'
    (tmp_path / "law.toml").write_text(text.replace(plain, law))
    (cut,) = load_scene(tmp_path / "law.toml").system.cuts
    assert (cut.moment_law.stiffness, cut.moment_law.damping, cut.rest_angle, cut.driven) == (3.0, 0.05, -1.3, False)
