"""The library verbs on closed kinematic loops (ctmm.planar.loop_verbs): ctmm.simulate (RK4, solve_ivp, the
DT-TMM schemes), ctmm.linearize, ctmm.natural_frequencies, ctmm.eigenvalue_count, ctmm.frequency_response.

Independent reference: the global DAE of :mod:`ctmm.reference.planar_dae` (absolute coordinates, Lagrange
multipliers), which shares no code with the tree sweep or the cut-joint mechanism; the four-bar's assembled
configurations for the frequency checks are solved here on the DAE's own constraints.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.optimize

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.reference.planar_dae import PlanarDAE
from ctmm.scenarios.four_bar import GROUND, LENGTHS, MASSES, REST, SPRING, mechanism as four_bar
from ctmm.scenarios.four_bar import reference as four_bar_dae
from ctmm.scenarios.four_bar import start

NAMES = ["crank", "coupler", "rocker"]


def _dae_history(loop, q0, v0, t):
    dae = four_bar_dae(SPRING)
    return dae.simulate(dae.assemble(dict(zip(NAMES, q0)), dict(zip(NAMES, v0))), t[-1], t_eval=t)


def test_simulate_honours_the_cut_joint_with_every_method():
    loop = four_bar(SPRING)
    q0, v0 = start(loop)
    x0 = dict(zip(loop.tree.coordinates, q0))                      # by coordinate name
    rk4 = ctmm.simulate(loop, 0.2, 1e-3, x0=x0, v0=v0, outputs=["coupler.out.x"])
    reference = _dae_history(loop, q0, v0, rk4.time)
    error = max(np.max(np.abs(rk4[f"{n}.theta"] - reference.angle(n))) for n in NAMES)
    assert error < 1e-9
    force = rk4["h3.force_y"]
    assert np.max(np.abs(force - reference.forces[:, 3, 1])) < 1e-7 * np.max(np.abs(reference.forces[:, 3, 1]))
    assert rk4.units(["h3.force_x", "drift", "drift_rate"]) == {"h3.force_x": "N", "drift": "m", "drift_rate": "m/s"}
    assert np.max(rk4["drift"]) < 1e-12 and rk4.info["projection"] is True
    dop = ctmm.simulate(loop, 0.2, 1e-2, x0=q0, v0=v0, method="DOP853", rtol=1e-11, atol=1e-12)
    assert len(dop.time) == 21 and np.max(np.abs(dop["rocker.theta"] - reference.angle("rocker")[::10])) < 1e-8
    # the DT-TMM scheme: second order against the DAE, projected onto the cut after every step, drift reported;
    # over 0.06 s (the DAE's index 60): the order needs the steps in the asymptotic range, not the long run
    # (measured 2.2e-6 / 5.5e-7 rad, ratio 4.005)
    assert reference.t[60] == pytest.approx(0.06, abs=1e-12)
    errors = []
    for dt in (2e-3, 1e-3):
        run = ctmm.simulate(loop, 0.06, dt, x0=q0, v0=v0, method="newmark")
        errors.append(np.max(np.abs(run["crank.theta"][-1] - reference.angle("crank")[60])))
        assert run.info["newton_iterations_max"] <= 6 and np.max(run["drift"]) < 1e-10
        assert np.max(run["drift"]) == pytest.approx(run.info["max_drift_m"])
    assert errors[1] < 1e-4 and 3.0 < errors[0] / errors[1] < 5.0



def test_solve_ivp_output_grid_is_k_dt_and_the_end():
    """dt is the output grid of a solve_ivp run: k dt and t_final where dt does not divide it (the grid was
    stretched to t_final / round(t_final / dt) steps); the states there are the DAE's."""
    loop = four_bar(SPRING)
    q0, v0 = start(loop)
    run = ctmm.simulate(loop, 0.105, 1e-2, x0=q0, v0=v0, method="DOP853", rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(run.time, np.append(1e-2 * np.arange(11), 0.105), rtol=0, atol=1e-15)
    reference = _dae_history(loop, q0, v0, run.time)
    assert np.max(np.abs(run["rocker.theta"] - reference.angle("rocker"))) < 1e-8


def _dae(crank_torque: float) -> PlanarDAE:
    """The four-bar with the rocker spring as a global DAE, a constant torque [N m] on the crank from the ground."""
    dae = PlanarDAE(gravity=(0.0, -9.81))
    for name in NAMES:
        m, length = MASSES[name], LENGTHS[name]
        dae.add_body(name, mass=m, inertia=m * length ** 2 / 12,
                     points={"in": (-length / 2, 0.0), "out": (length / 2, 0.0)})
    dae.add_revolute(None, (0.0, 0.0), "crank", "in", moment=lambda d, v: -crank_torque)
    dae.add_revolute("crank", "out", "coupler", "in")
    dae.add_revolute(None, (GROUND, 0.0), "rocker", "in", moment=lambda d, v: float(SPRING.force(d, v)), rest=REST)
    dae.add_revolute("rocker", "out", "coupler", "out")
    return dae


def _assembled(dae, crank: float, guess):
    """DAE state at rest with the crank at ``crank`` [rad], coupler and rocker from the DAE's loop constraint."""
    def residual(angles):
        q, v = dae.assemble(dict(zip(NAMES, [crank, *angles])), dict.fromkeys(NAMES, 0.0))
        return dae.constraints(q, v)[0][-2:]

    angles = scipy.optimize.fsolve(residual, guess, xtol=1e-12)
    assert np.max(np.abs(residual(angles))) < 1e-13
    return dae.assemble(dict(zip(NAMES, [crank, *angles])), dict.fromkeys(NAMES, 0.0)), angles


def test_frequency_verbs_match_the_dae_about_the_equilibrium():
    loop = four_bar(SPRING)
    guess, _ = loop.consistent_state([-1.5, 0.5, 1.8], [0.0, 0.0, 0.0], keep=["crank.theta"])
    q_eq = loop.equilibrium(guess)
    point = (q_eq, np.zeros(3))
    # reference: a 1-DOF tangent from the DAE -- stiffness k = -d crank''/d crank on the constraints at rest,
    # torque gain g = d crank''/d tau of a torque tau on the crank from the ground, cut force sensitivities
    dae, torque = _dae(0.0), _dae(1.0)
    state, _ = _assembled(dae, q_eq[0], q_eq[1:])
    h = 1e-5
    plus, _ = _assembled(dae, q_eq[0] + h, q_eq[1:])
    minus, _ = _assembled(dae, q_eq[0] - h, q_eq[1:])
    k = -(dae.solve(*plus)[0][2] - dae.solve(*minus)[0][2]) / (2 * h)
    force_slope = (dae.solve(*plus)[1][6:8] - dae.solve(*minus)[1][6:8]) / (2 * h)
    g = torque.solve(*state)[0][2] - dae.solve(*state)[0][2]
    force_gain = torque.solve(*state)[1][6:8] - dae.solve(*state)[1][6:8]
    assert abs(dae.solve(*state)[0][2]) < 1e-9                          # the loop's equilibrium is the DAE's

    (omega_n,) = ctmm.natural_frequencies(loop, operating_point=point)
    assert omega_n ** 2 == pytest.approx(k, rel=1e-8)
    assert list(ctmm.eigenvalue_count(loop, [0.5 * omega_n, 2.0 * omega_n], operating_point=point)) == [0, 1]
    omega = np.array([0.0, 0.5 * omega_n, 3.0 * omega_n])
    frf = ctmm.frequency_response(loop, omega, input="h1.torque", output=["crank.theta", "h3.force_x", "h3.force_y"],
                                  operating_point=point)
    crank = g / (k - omega ** 2)
    np.testing.assert_allclose(frf("crank.theta", "h1.torque").real, crank, rtol=1e-8)
    for axis, column in (("x", 0), ("y", 1)):
        expected = force_slope[column] * crank + force_gain[column]
        np.testing.assert_allclose(frf(f"h3.force_{axis}", "h1.torque").real, expected, rtol=1e-8,
                                   atol=1e-8 * np.max(np.abs(expected)))
    assert frf.units["h3.force_x"] == "N" and frf.units["h1.torque"] == "N m"
    lin = ctmm.linearize(loop, point, inputs=["h1.torque"], outputs=["crank.theta", "h3.force_y"])
    assert lin.state_space.nstates == 2 and lin.operating_point.equilibrium and lin.delays == ()
    assert lin.operating_point.jacobian_error < 1e-6


def test_the_verbs_refuse_what_they_cannot_honour():
    loop = four_bar()
    q0, v0 = start(loop)
    with pytest.raises(ModelError, match="consistent_state"):
        ctmm.simulate(loop, 0.1, 1e-3)                                   # zero angles: not assembled
    with pytest.raises(ModelError, match="fast"):      # inputs and feedback: tests/test_closed_loops_feedback.py
        ctmm.simulate(loop, 0.1, 1e-3, x0=q0, v0=v0, inputs={"h1.torque": 1.0}, fast=True)
    with pytest.raises(ModelError, match="divergence_bound"):
        ctmm.simulate(loop, 0.1, 1e-3, x0=q0, v0=v0, divergence_bound=10.0)
    with pytest.raises(ModelError, match="natural_frequencies"):
        ctmm.natural_frequencies(with_feedback(loop, [Feedback("pd", sensor="h1.angle", actuator="h1.torque",
                                                               gain=1.0)]))
    with pytest.raises(ModelError, match="mode_shapes answers the open kinematic loop model"):
        ctmm.mode_shapes(with_feedback(loop, [Feedback("pd", sensor="h1.angle", actuator="h1.torque", gain=1.0)]),
                         n_modes=1)                        # the modes: tests/test_loop_mode_shapes.py
    with pytest.raises(ModelError, match="rates must be zero"):
        ctmm.linearize(loop, (q0, v0))
    with pytest.raises(ModelError, match="not an equilibrium"):
        ctmm.linearize(loop, (q0, np.zeros(3)))


def test_a_frequency_at_a_pole_is_refused_naming_the_model():
    """Was: the refusal named a function repr (``<function frequency_response_loops.<locals>.solve ...>``)."""
    from ctmm.controlled_linearization import FrequencyAtPoleError

    loop = four_bar(SPRING)
    guess, _ = loop.consistent_state([-1.5, 0.5, 1.8], [0.0, 0.0, 0.0], keep=["crank.theta"])
    point = (loop.equilibrium(guess), np.zeros(3))
    (omega_n,) = ctmm.natural_frequencies(loop, operating_point=point)
    with pytest.raises(FrequencyAtPoleError, match=rf"of '{loop.name}' is singular at omega = ") as caught:
        ctmm.frequency_response(loop, [omega_n], input="h1.torque", output="crank.theta", operating_point=point)
    assert "function" not in str(caught.value)


@pytest.mark.parametrize("t_final, dt", [(0.0105, 1e-3), (0.01, 3e-3), (0.01, 1.0)])
def test_rk4_refuses_an_end_time_that_is_not_a_whole_number_of_steps_as_every_fixed_step_path(t_final, dt):
    """The open loop model's RK4 (numpy and generated, planar and spatial) rounded ``t_final / dt`` and silently
    ended at 0.010 s for 0.0105 s, at 0.009 s for 0.01 s in steps of 3 ms, and stepped on to 1 s for 0.01 s in
    steps of 1 s, where the tree, the DT-TMM schemes and the loop driver refuse it; now the same refusal."""
    from spatial_loop_helpers import rusr
    planar = four_bar(SPRING)
    q0, v0 = start(planar)
    spatial = rusr()
    q, v = spatial.consistent_state({"h1.angle": 0.1, "h4.angle": 0.1}, {"h1.angle_rate": 3.0}, keep=["h1"])
    for loop, x0, rates in [(planar, q0, v0), (spatial, q, v)]:
        for compiled in (None, True):
            with pytest.raises(ModelError, match=f"t_final = {t_final!r} must be a whole multiple of dt = {dt!r}"):
                ctmm.simulate(loop, t_final, dt, x0=x0, v0=rates, compiled=compiled)
        with pytest.raises(ModelError, match="whole multiple"):                 # the rule the schemes keep
            ctmm.simulate(loop, t_final, dt, x0=x0, v0=rates, method="newmark")
    run = ctmm.simulate(planar, 0.0105, 1e-3, x0=q0, v0=v0, method="DOP853")   # dt: the output grid, not a step
    assert run.time[-1] == pytest.approx(0.0105, abs=1e-15)
