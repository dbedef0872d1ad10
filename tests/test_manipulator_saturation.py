"""Actuator saturation of a Feedback loop (``saturation=(low, high)``): the manipulator's PZT amplifier
limit on the scene, against the independent assumed-modes Lagrange model with the same voltage clip
(ctmm/reference/manipulator_lagrange.py), and its refusal by the linear verbs."""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback, loop_transfer_function, margins
from ctmm.errors import ModelError
from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_PZT_GAIN, CycloidalMove, HubPD, PZTFeedback, manipulator_scene,
                              scene_references, seed_manipulator)
from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

FAST = CycloidalMove(0.6, 0.4)           # demands ~430 V at patch 1 near t = 0.18 s; the limit is 200 V
T_FINAL = 0.25


@pytest.fixture(scope="module")
def seed():
    return seed_manipulator()


@pytest.fixture(scope="module")
def reference(seed):
    gains = np.eye(seed.n_patches) * SEED_PZT_GAIN
    model = ManipulatorLagrange.from_manipulator(seed, 3, stiffening=True)
    return {limit: model.simulate(T_FINAL, reference=FAST, kp=SEED_KP, kd=SEED_KD, pzt_gains=gains,
                                  voltage_limit=limit, t_eval=np.linspace(0.0, T_FINAL, 251))
            for limit in (seed.voltage_limit, None)}


def run(seed, method, dt, on_limit="saturate"):
    pd = HubPD(SEED_KP, SEED_KD)
    scene = manipulator_scene(seed, pd=pd, pzt=PZTFeedback.per_patch([SEED_PZT_GAIN] * seed.n_patches,
                                                                     on_limit=on_limit))
    return ctmm.simulate(scene, T_FINAL, dt, method=method, references=scene_references(pd, FAST),
                         outputs=["arm.tip.w"])


@pytest.mark.parametrize("method, dt, tip_tolerance, volt_tolerance",
                         [("rk4", 0.001, 1e-6, 0.05),          # measured 6e-8, 0.009 V
                          ("newmark", 0.001, 1e-4, 0.5)])      # second order: measured 4e-5, 0.13 V
def test_saturated_pzt_loops_equal_the_clipped_lagrange_model(seed, reference, method, dt, tip_tolerance,
                                                               volt_tolerance):
    result = run(seed, method, dt)
    expected = reference[seed.voltage_limit]
    np.testing.assert_allclose(result.time, np.linspace(0.0, T_FINAL, 251), atol=1e-12)
    peak = np.abs(expected.tip_deflection).max()
    assert np.abs(result["arm.tip.w"] - expected.tip_deflection).max() < tip_tolerance * peak
    volts = np.column_stack([result[f"{p.name}.u"] for p in seed.patches])
    assert np.abs(volts - expected.voltages).max() < volt_tolerance
    assert np.abs(volts).max() == pytest.approx(seed.voltage_limit, abs=1e-12)
    # the unsaturated demand and where the amplifier is at its limit are in the result
    demand = result["pzt1.u_demand"]
    assert demand.max() > 1.9 * seed.voltage_limit
    np.testing.assert_array_equal(result["pzt1.saturated"] == 1.0, np.abs(demand) > seed.voltage_limit)
    at_limit = np.abs(expected.voltages[:, 0]) >= seed.voltage_limit * (1 - 1e-12)
    assert result.info["time_saturated_s"]["pzt1"] == pytest.approx(float(np.sum(np.diff(expected.t)[at_limit[:-1]])),
                                                                    abs=2 * dt)
    assert result.info["time_saturated_s"]["pzt1"] > 0.1 and "hub_pd" not in result.info["time_saturated_s"]
    # the limit matters: the unclipped reference is far from this run
    unclipped = reference[None].tip_deflection
    assert np.abs(unclipped - expected.tip_deflection).max() > 100 * tip_tolerance * peak


def test_an_unsaturated_run_is_unchanged_by_limits_it_never_reaches(seed):
    slow = manipulator_scene(seed, pd=HubPD(SEED_KP, SEED_KD), pzt=PZTFeedback.per_patch([SEED_PZT_GAIN] * 3))
    wide = slow.with_loops([lp if lp.name == "hub_pd" else Feedback(lp.name, lp.sensor, lp.actuator, lp.gain, lp.delay,
                                                                    saturation=(-1e6, 1e6)) for lp in slow.loops])
    plain = ctmm.simulate(slow, 0.05, 0.002, references=scene_references(HubPD(SEED_KP, SEED_KD), FAST))
    limited = ctmm.simulate(wide, 0.05, 0.002, references=scene_references(HubPD(SEED_KP, SEED_KD), FAST))
    np.testing.assert_array_equal(plain["pzt1.u"], limited["pzt1.u"])
    assert limited.info["time_saturated_s"] == {"pzt1": 0.0, "pzt2": 0.0, "pzt3": 0.0}
    assert "time_saturated_s" not in plain.info


def test_saturate_is_branch_free_and_complex_step_safe():
    loop = Feedback("l", "m.x", "m", gain=1.0, saturation=(-2.0, 3.0))
    u = np.array([-5.0, -2.0, 0.5, 3.0, 7.0])
    np.testing.assert_array_equal(loop.saturate(u), [-2.0, -2.0, 0.5, 3.0, 3.0])
    h = 1e-30
    slopes = np.imag(loop.saturate(np.array([-5.0, 0.5, 7.0]) + 1j * h)) / h
    np.testing.assert_array_equal(slopes, [0.0, 1.0, 0.0])
    assert Feedback("l", "m.x", "m", gain=1.0).saturate(1e9) == 1e9
    one_sided = Feedback("l", "m.x", "m", gain=1.0, saturation=(-math.inf, 1.0))
    assert one_sided.saturate(-1e300) == -1e300 and one_sided.saturate(5.0) == 1.0
    assert loop.with_parameters(gain=2.0).saturation == (-2.0, 3.0)
    assert loop.unsaturated().saturation is None and loop.unsaturated().gain == 1.0


@pytest.mark.parametrize("bad", [(1.0, 1.0), (2.0, -2.0), (math.nan, 1.0), (1.0,), "ab", 5.0, (True, 2.0)])
def test_a_bad_saturation_is_refused_naming_the_loop(bad):
    with pytest.raises(ModelError, match=r"loop 'l': saturation must"):
        Feedback("l", "m.x", "m", gain=1.0, saturation=bad)


def test_the_linear_verbs_refuse_a_saturated_loop(seed):
    scene = manipulator_scene(seed, pd=HubPD(SEED_KP, SEED_KD, delay=0.01),
                              pzt=PZTFeedback.per_patch([SEED_PZT_GAIN] * 3, on_limit="saturate"))
    message = r"needs linear loops, but loop 'pzt1' saturates at \(-200.0, 200.0\).*unsaturated\(\)"
    with pytest.raises(ModelError, match="frequency-domain verbs.*" + message):
        ctmm.frequency_response(scene, [1.0], input="motor.torque", output="motor.angle")
    with pytest.raises(ModelError, match="fields='exact'.*" + message):
        ctmm.frequency_response(scene, [1.0], input="motor.torque", output="motor.angle", fields="exact")
    with pytest.raises(ModelError, match="ctmm.linearize " + message):
        ctmm.linearize(scene)
    with pytest.raises(ModelError, match="stability analysis " + message):
        ctmm.stability.delay_margin(scene, "hub_pd")
    with pytest.raises(ModelError, match="loop transfer function " + message):
        loop_transfer_function(scene, "hub_pd", [1.0])
    with pytest.raises(ModelError, match=message):
        margins(scene, "hub_pd", [1.0, 2.0])
    # the small-signal model inside the limits: the loops without their saturation
    linear = scene.with_loops([lp.unsaturated() for lp in scene.loops])
    assert ctmm.frequency_response(linear, [1.0], input="motor.torque", output="motor.angle").response.shape == (1, 1, 1)


def test_a_chain_refuses_a_saturated_loop_where_it_embeds_loops_linearly():
    chain = ctmm.Chain("c", [ctmm.elements.Fixed("wall"), ctmm.elements.Spring("k", 10.0),
                             ctmm.elements.Mass("m", 1.0), ctmm.elements.Free("end")])
    saturated = ControlledChain(chain, [Feedback("pd", "m.x", "m", gain=5.0, saturation=(-1.0, 1.0))])
    with pytest.raises(ModelError, match=r"DT-TMM scheme on a 1-D ControlledChain .*loop 'pd' saturates at "
                                         r"\(-1.0, 1.0\)"):
        ctmm.simulate(saturated, 0.1, 0.01, method="newmark", x0={"m": 0.5})
    with pytest.raises(ModelError, match=r"loop 'pd' saturates at \(-1.0, 1.0\)"):
        ctmm.frequency_response(saturated, [1.0], input="m.force", output="m.x")
    assert ControlledChain(chain, [Feedback("pd", "m.x", "m", gain=5.0)]).loops[0].saturation is None
