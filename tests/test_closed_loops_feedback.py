"""Feedback loops on a closed kinematic loop model: ``ctmm.control.with_feedback(loop_model, loops)``.

A four-bar linkage (scenario ``four_bar``) with a PD crank-angle loop on the crank hinge torque, real-time and
delayed, through every verb: ``ctmm.simulate`` (RK4, ``solve_ivp``, a DT-TMM scheme) and the linear verbs
(``ctmm.linearize``, ``ctmm.frequency_response``, ``margins``, ``delay_margin``, ``stability_chart``).

Independent references: the global DAE of :mod:`ctmm.reference.planar_dae` with a motor on the crank (the same
PD law read ``delay`` seconds late, the method of steps), which shares no code with the tree sweep, the cut-joint
mechanism or the loop driver; and the closed forms of the one-degree-of-freedom tangent
``theta'' = -k theta + b u`` whose ``k`` and ``b`` are measured on the DAE's own constraints:
closed-loop poles ``s^2 + b kd s + k + b kp = 0``, the delay crossing of ``s^2 + k + b (kp + kd s) e^{-s tau}``
and the response ``b / (s^2 + k + b (kp + kd s) e^{-s tau})``.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.optimize

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.control.analysis import margins
from ctmm.errors import ModelError
from ctmm.scenarios.four_bar import BODIES, mechanism, reference, start
from ctmm.stability import delay_margin
from ctmm.stability_chart import stability_chart

KP, KD = 8.0, 0.8               # PD on the crank angle [N m/rad], [N m s/rad]
TARGET = 1.2                    # crank angle set point [rad]: reference r = KP * TARGET on y = KP theta + KD theta'


def _pd(delay: float, kp: float = KP) -> Feedback:
    return Feedback("pd", sensor=[("h1.angle", kp), ("h1.rate", KD)], actuator="h1.torque", gain=1.0, delay=delay)


@pytest.mark.parametrize("delay", [0.0, 0.01], ids=["real-time", "delayed"])
def test_pd_crank_loop_in_time_matches_the_dae_with_a_motor(delay):
    loop = mechanism()
    q0, v0 = start(loop)
    controlled = with_feedback(loop, [_pd(delay)])
    dae = reference()
    dae.add_motor(None, "crank", lambda t, angle, rate: -(KP * angle + KD * rate - KP * TARGET), delay=delay)
    state = dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0)))
    run = ctmm.simulate(controlled, 0.2, 1e-3, x0=q0, v0=v0, references={"pd": KP * TARGET})
    dae_run = dae.simulate(state, 0.2, t_eval=run.time)
    error = max(np.max(np.abs(run[f"{n}.theta"] - dae_run.angle(n))) for n in BODIES)
    assert error < 1e-9                       # RK4 at 1 ms (measured 9.7e-11 / 8.3e-11 rad)
    force = dae_run.forces[:, 3]
    assert np.max(np.abs(run["h3.force_x"] - force[:, 0])) < 1e-8 * np.max(np.abs(force))
    torque = -(KP * dae_run.angle("crank") + KD * dae_run.rate("crank") - KP * TARGET) if delay == 0.0 else None
    if torque is not None:
        assert np.max(np.abs(run["pd.u"] - torque)) < 1e-7
    assert np.max(run["drift"]) < 1e-10 and run.units(["drift", "h3.force_y"]) == {"drift": "m", "h3.force_y": "N"}
    assert np.ptp(run["crank.theta"]) > 0.2 and run.info["loops"]["pd"] == ("real-time" if delay == 0 else "history")


def test_pd_crank_loop_on_a_dt_tmm_scheme_and_solve_ivp():
    loop = mechanism()
    q0, v0 = start(loop)
    controlled = with_feedback(loop, [_pd(0.01)])
    dae = reference()
    dae.add_motor(None, "crank", lambda t, angle, rate: -(KP * angle + KD * rate - KP * TARGET), delay=0.01)
    state = dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0)))
    errors = []
    for dt in (2e-3, 1e-3):
        run = ctmm.simulate(controlled, 0.1, dt, x0=q0, v0=v0, method="newmark", references={"pd": KP * TARGET})
        dae_run = dae.simulate(state, 0.1, t_eval=run.time)
        errors.append(np.max(np.abs(run["crank.theta"] - dae_run.angle("crank"))))
        assert np.max(run["drift"]) < 1e-5 and np.all(np.isfinite(run["h3.force_x"]))
    assert errors[1] < 1e-5 and 3.0 < errors[0] / errors[1] < 5.0        # second order (measured 4.0)
    dop = ctmm.simulate(controlled, 0.1, 1e-2, x0=q0, v0=v0, method="DOP853", rtol=1e-11, atol=1e-12,
                        inputs={"pd.reference": KP * TARGET})
    dae_run = dae.simulate(state, 0.1, t_eval=dop.time)
    assert np.max(np.abs(dop["crank.theta"] - dae_run.angle("crank"))) < 1e-6   # cubic Hermite delay history


def test_open_loop_torque_input_on_the_kinematic_loop_model():
    loop = mechanism()
    q0, v0 = start(loop)
    run = ctmm.simulate(loop, 0.1, 1e-3, x0=q0, v0=v0, inputs={"h1.torque": lambda t: 0.5 * math.sin(10.0 * t)})
    dae = reference()
    dae.add_motor(None, "crank", lambda t, angle, rate: 0.5 * math.sin(10.0 * t))
    dae_run = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.1, t_eval=run.time)
    assert max(np.max(np.abs(run[f"{n}.theta"] - dae_run.angle(n))) for n in BODIES) < 1e-9
    free = ctmm.simulate(loop, 0.1, 1e-3, x0=q0, v0=v0)
    assert np.max(np.abs(free["crank.theta"] - run["crank.theta"])) > 1e-4          # the torque acts


def test_sampled_controller_converges_to_the_continuous_loop_of_the_dae():
    """A co-simulated static-gain PD sampled every step (zero-order hold) approaches the continuous PD of the DAE at
    first order in the sample time (measured crank errors at 0.1 s: 6.7e-3, 3.3e-3 rad)."""
    from ctmm.control.static_gain import StaticGainController

    loop = mechanism()
    q0, v0 = start(loop)
    dae = reference()
    dae.add_motor(None, "crank", lambda t, angle, rate: -(KP * angle + KD * rate))
    crank = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.1, t_eval=[0.0, 0.1]).angle(
        "crank")[-1]
    errors = []
    for dt in (1e-3, 5e-4):
        controller = StaticGainController(["h1.angle", "h1.rate"], ["h1.torque"], [[-KP, -KD]], sample_time=dt)
        run = ctmm.simulate(loop, 0.1, dt, x0=q0, v0=v0, controllers=[controller])
        errors.append(abs(run["crank.theta"][-1] - crank))
        assert np.max(run["drift"]) < 1e-9
    assert errors[0] < 1e-2 and errors[0] / errors[1] == pytest.approx(2.0, rel=0.05)


def _assembled(dae, crank: float, guess):
    """DAE state at rest with the crank at ``crank`` [rad]; coupler and rocker from the DAE's loop constraint."""
    def residual(angles):
        q, v = dae.assemble(dict(zip(BODIES, [crank, *angles])), dict.fromkeys(BODIES, 0.0))
        return dae.constraints(q, v)[0][-2:]

    angles = scipy.optimize.fsolve(residual, guess, xtol=1e-13)
    assert np.max(np.abs(residual(angles))) < 1e-13
    return dae.assemble(dict(zip(BODIES, [crank, *angles])), dict.fromkeys(BODIES, 0.0))


@pytest.fixture(scope="module")
def tangent():
    """``(k, b)``: the DAE's crank stiffness ``-d crank''/d crank`` [1/s^2] and torque gain ``d crank''/d tau``
    [1/(kg m^2)] at the four-bar's hanging equilibrium (the default operating point of the linear verbs, checked
    to be the DAE's equilibrium), on the DAE's own constraints."""
    q_eq = ctmm.linearize(mechanism(), inputs=["h1.torque"]).operating_point.q
    dae, driven = reference(), reference()
    driven.add_motor(None, "crank", lambda t, angle, rate: 1.0)
    state = _assembled(dae, q_eq[0], q_eq[1:])
    assert np.max(np.abs(dae.solve(*state)[0])) < 1e-9 and np.max(np.abs(state[0][2::3] - q_eq)) < 1e-12
    h = 1e-5
    plus, minus = _assembled(dae, q_eq[0] + h, q_eq[1:]), _assembled(dae, q_eq[0] - h, q_eq[1:])
    k = -(dae.solve(*plus)[0][2] - dae.solve(*minus)[0][2]) / (2 * h)
    b = driven.solve(*state)[0][2] - dae.solve(*state)[0][2]
    return k, b


@pytest.fixture(scope="module")
def cut_force_tangent():
    """``(slope, gain)``: the DAE's cut-joint force on the coupler per crank angle on the constraints at rest
    [N/rad] and per crank torque [N/(N m)], at the same equilibrium (joint 3 of the DAE is the cut h3)."""
    q_eq = ctmm.linearize(mechanism(), inputs=["h1.torque"]).operating_point.q
    dae, driven = reference(), reference()
    driven.add_motor(None, "crank", lambda t, angle, rate: 1.0)
    state = _assembled(dae, q_eq[0], q_eq[1:])
    h = 1e-5
    plus, minus = _assembled(dae, q_eq[0] + h, q_eq[1:]), _assembled(dae, q_eq[0] - h, q_eq[1:])
    slope = (dae.solve(*plus)[1][6:8] - dae.solve(*minus)[1][6:8]) / (2 * h)
    gain = driven.solve(*state)[1][6:8] - dae.solve(*state)[1][6:8]
    return slope, gain


def _critical_delay(k: float, b: float, kp: float, kd: float) -> tuple[float, float]:
    """Smallest delay [s] and frequency [rad/s] at which s^2 + k + b (kp + kd s) e^{-s tau} has a root i omega."""
    quadratic = np.roots([1.0, -(2 * k + b * b * kd * kd), k * k - b * b * kp * kp])
    omega = math.sqrt(max(r.real for r in quadratic))
    phase = -np.angle(-(k - omega ** 2) / (b * (kp + 1j * kd * omega)))
    return (phase % (2 * math.pi)) / omega, omega


def test_linear_verbs_of_the_controlled_loop_match_the_closed_forms(tangent):
    k, b = tangent
    loop = mechanism()
    real_time = with_feedback(loop, [_pd(0.0)])
    lin = ctmm.linearize(real_time, inputs=["pd.reference"], outputs=["crank.theta", "pd.u"])
    poles = np.sort_complex(np.linalg.eigvals(lin.state_space.A))
    np.testing.assert_allclose(poles, np.sort_complex(np.roots([1.0, b * KD, k + b * KP])), rtol=1e-7)
    assert lin.delays == ()
    delayed = with_feedback(loop, [_pd(0.02)])
    omega = np.array([0.0, 5.0, 20.0])
    s = 1j * omega
    frf = ctmm.frequency_response(delayed, omega, input="h1.torque", output=["crank.theta", "pd.u"])
    crank = b / (s * s + k + b * (KP + KD * s) * np.exp(-0.02 * s))
    np.testing.assert_allclose(frf("crank.theta", "h1.torque"), crank, rtol=1e-7)
    np.testing.assert_allclose(frf("pd.u", "h1.torque"), -(KP + KD * s) * np.exp(-0.02 * s) * crank, rtol=1e-7)
    assert frf.units["pd.u"] == "N m"
    tau, omega_c = _critical_delay(k, b, KP, KD)
    margin = delay_margin(delayed)
    assert margin.stable and margin.critical_delay == pytest.approx(tau, rel=1e-6)
    assert margin.critical_frequency == pytest.approx(omega_c, rel=1e-6)
    found = margins(delayed, "pd", np.linspace(0.5, 60.0, 600))
    assert found.delay_margin == pytest.approx(tau - 0.02, rel=1e-5)


def test_cut_force_outputs_of_the_controlled_loop_match_the_closed_forms(tangent, cut_force_tangent):
    """The cut force feeds through from the actuators: ``F = slope theta + gain u_total`` with the closed-loop crank
    angle and the total crank torque (the input plus the loop's force)."""
    k, b = tangent
    slope, gain = cut_force_tangent
    omega = np.array([0.0, 5.0, 20.0])
    s = 1j * omega
    real_time = with_feedback(mechanism(), [_pd(0.0)])
    frf = ctmm.frequency_response(real_time, omega, input=["pd.reference", "h1.torque"],
                                  output=["h3.force_x", "h3.force_y", "crank.theta"])
    crank = b / (s * s + k + b * (KP + KD * s))             # per unit reference and per unit torque alike
    torque = {"pd.reference": 1.0 - (KP + KD * s) * crank, "h1.torque": 1.0 - (KP + KD * s) * crank}
    for name in torque:
        np.testing.assert_allclose(frf("crank.theta", name), crank, rtol=1e-7)
        for axis, column in (("x", 0), ("y", 1)):
            expected = slope[column] * crank + gain[column] * torque[name]
            np.testing.assert_allclose(frf(f"h3.force_{axis}", name), expected, rtol=1e-6,
                                       atol=1e-6 * np.max(np.abs(expected)))
    delayed = with_feedback(mechanism(), [_pd(0.02)])
    frf = ctmm.frequency_response(delayed, omega, input="h1.torque", output="h3.force_y")
    loop_term = (KP + KD * s) * np.exp(-0.02 * s)
    crank = b / (s * s + k + b * loop_term)
    expected = slope[1] * crank + gain[1] * (1.0 - loop_term * crank)
    np.testing.assert_allclose(frf("h3.force_y", "h1.torque"), expected, rtol=1e-6, atol=1e-6 * np.max(np.abs(expected)))
    lin = ctmm.linearize(delayed, inputs=["h1.torque"], outputs=["h3.force_y", "crank.theta"])
    assert lin.state_space.output_labels == ["h3_force_y", "crank_theta", "pd_y"] and len(lin.delays) == 1


def test_stability_chart_of_the_controlled_loop_matches_the_closed_form(tangent):
    k, b = tangent
    gains, delays = np.array([4.0, 12.0]), np.array([0.02, 0.08, 0.2])
    chart = stability_chart(with_feedback(mechanism(), [_pd(0.05)]), x=("h1.angle", gains),
                                 y=("delay", delays))
    expected = np.array([[d < _critical_delay(k, b, kp, KD)[0] for kp in gains] for d in delays])
    assert expected.any() and not expected.all()
    np.testing.assert_array_equal(chart.stable, expected)


def test_refusals_of_the_controlled_loop_model():
    loop = mechanism()
    q0, v0 = start(loop)
    controlled = with_feedback(loop, [_pd(0.0)])
    with pytest.raises(ModelError, match="natural_frequencies"):
        ctmm.natural_frequencies(controlled)
    with pytest.raises(ModelError, match="compiled"):      # with "rk4" it runs: compiled_kinematic_loop_control
        ctmm.simulate(controlled, 0.01, 1e-3, x0=q0, v0=v0, compiled=True, method="newmark")
    with pytest.raises(ModelError, match="cut joints"):
        ctmm.simulate(controlled, 0.01, 1e-3, x0=q0 + 0.1, v0=v0)
    with pytest.raises(ModelError, match="algebraic"):      # cut-force loops: tests/test_cut_force_sensors.py
        ctmm.simulate(with_feedback(loop, [Feedback("pd", sensor="h3.force_x", actuator="h1.torque", gain=1.0)]),
                      0.01, 1e-3, x0=q0, v0=v0)
