"""Linearised controlled manipulator (exact beam fields + embedded PD/PZT loops) vs the
linearised Lagrange reference (issue 6, C)."""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.elements.beams import BeamPointMass
from ctmm.errors import ModelError
from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_PZT_GAIN, HubPD, LinearManipulator, PZTFeedback,
                              RigidHub, seed_manipulator)
from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

OMEGA = np.array([0.3, 2.0, 5.0, 11.0, 16.0, 25.0, 60.0, 100.0, 180.0, 300.0])


@pytest.fixture(scope="module")
def seed():
    return seed_manipulator()


@pytest.fixture(scope="module")
def reference(seed):
    # 150 modes + static correction of the rest: converged to ~1e-12 below 300 rad/s
    return ManipulatorLagrange.from_manipulator(seed, 150)


def _rel(a, b):
    return np.abs(a - b) / np.abs(b)


def test_rigid_hub_matrix_satisfies_newton_euler():
    hub = RigidHub("hub", inertia=0.7, radius=0.2, mass=1.3)
    s = np.array([0.3j, 2.0 + 5j])
    rng = np.random.default_rng(1)
    z_in = rng.normal(size=(2, 4)) + 1j * rng.normal(size=(2, 4))
    tau = 0.4 - 0.1j
    z_out = np.einsum("wij,wj->wi", hub.transfer_matrix(s), z_in) + hub.load_vector(s, {"torque": tau})
    w, th, f, m = z_in.T
    wo, tho, fo, mo = z_out.T
    np.testing.assert_allclose(wo, w + 0.2 * th)
    np.testing.assert_allclose(tho, th)
    np.testing.assert_allclose(hub.mass * s ** 2 * w, f - fo)                        # Newton
    np.testing.assert_allclose(hub.inertia * s ** 2 * th, m - mo - 0.2 * fo + tau)   # Euler about the pivot
    # r = 0: the point inertia of the beam library
    np.testing.assert_allclose(RigidHub("h", 0.7).transfer_matrix(s), BeamPointMass("p", 0.0, 0.7).transfer_matrix(s))
    with pytest.raises(ModelError, match="inertia must be > 0"):
        RigidHub("h", 0.0)


@pytest.mark.parametrize("pd_delay, pzt_delay", [(0.0, 0.0), (0.01, 0.003)])
def test_closed_loop_frf_equals_the_lagrange_reference(seed, reference, pd_delay, pzt_delay):
    G = np.diag([SEED_PZT_GAIN, 0.6 * SEED_PZT_GAIN, 0.3 * SEED_PZT_GAIN])
    G[0, 2] = 100.0                                   # a cross-coupled sensor term as well
    model = LinearManipulator(seed, HubPD(SEED_KP, SEED_KD, pd_delay), PZTFeedback(G, delay=pzt_delay))
    ref = reference.frequency_response(OMEGA, kp=SEED_KP, kd=SEED_KD, pd_delay=pd_delay, pzt_gains=G,
                                       pzt_delay=pzt_delay)
    for inp, key in (("theta_d", "theta_d"), ("torque", "torque"), ("pzt2.voltage", "voltage_2")):
        tmm = model.response(OMEGA, input=inp)
        assert _rel(tmm["tip"], ref[key]["tip"]).max() < 1e-8, inp
        assert _rel(tmm["theta"], ref[key]["theta"]).max() < 1e-8, inp
        assert np.abs(tmm["voltages"] - ref[key]["voltages"]).max() < 1e-8 * np.abs(ref[key]["voltages"]).max()
        assert np.abs(tmm["slopes"] - ref[key]["slopes"]).max() < 1e-8 * np.abs(ref[key]["slopes"]).max()


def test_pd_only_frf_and_modal_truncation_error(seed, reference):
    """Without static correction the N-mode reference converges like 1/N (moment-pair ports), so
    the continuum TMM is the better yardstick; the error is quantified here."""
    model = LinearManipulator(seed, HubPD(SEED_KP, SEED_KD))
    tmm = model.response(OMEGA)
    ref = reference.frequency_response(OMEGA, kp=SEED_KP, kd=SEED_KD)["theta_d"]
    assert _rel(tmm["tip"], ref["tip"]).max() < 1e-8
    errors = []
    for n in (3, 10, 30):
        trunc = ManipulatorLagrange.from_manipulator(seed, n).frequency_response(
            OMEGA[:5], kp=SEED_KP, kd=SEED_KD, static_correction=False)["theta_d"]
        errors.append(_rel(trunc["tip"], tmm["tip"][:5]).max())
    assert errors[0] < 2e-2                 # the 3-mode time-domain model below 16 rad/s
    assert errors[2] < errors[1] < errors[0]


def test_loop_transfer_functions_equal_the_reference(seed, reference):
    G = np.eye(3) * SEED_PZT_GAIN
    model = LinearManipulator(seed, HubPD(SEED_KP, SEED_KD, 0.005), PZTFeedback(G, delay=0.002))
    kwargs = dict(kp=SEED_KP, kd=SEED_KD, pd_delay=0.005, pzt_gains=G, pzt_delay=0.002)
    L_pd = model.loop_transfer("pd", OMEGA)("pd.L")
    open_pd = reference.frequency_response(OMEGA, pd_closed=False, **kwargs)["torque"]["theta"]
    assert _rel(L_pd, (SEED_KP + SEED_KD * 1j * OMEGA) * np.exp(-0.005j * OMEGA) * open_pd).max() < 1e-8
    L_p1 = model.loop_transfer("pzt1", OMEGA)("pzt1.L")
    open_p1 = reference.frequency_response(OMEGA, pzt_closed=[False, True, True], **kwargs)
    assert _rel(L_p1, np.exp(-0.002j * OMEGA) * open_p1["voltage_1"]["pzt_sensed"][0]).max() < 1e-8


def test_pzt_feedback_flattens_the_first_flexible_resonance(seed):
    w = np.linspace(10.0, 25.0, 301)
    pd = HubPD(SEED_KP, SEED_KD)
    with_pzt = LinearManipulator(seed, pd, PZTFeedback.per_patch([SEED_PZT_GAIN] * 3)).response(w)["tip"]
    without = LinearManipulator(seed, pd).response(w)["tip"]
    ratio = np.abs(with_pzt).max() / np.abs(without).max()
    assert ratio < 0.35, ratio              # measured 0.266 on this grid


def test_margins_of_the_hub_and_of_a_patch(seed):
    model = LinearManipulator(seed, HubPD(SEED_KP, SEED_KD), PZTFeedback.per_patch([SEED_PZT_GAIN] * 3))
    hub = model.margins("pd", np.logspace(-1, 3, 300))
    assert 40.0 < hub.phase_margin < 90.0 and np.isfinite(hub.delay_margin)
    patch = model.margins("pzt1", np.logspace(0, 3.3, 300))
    # collocated slope-rate feedback: phase of L in (-90, 90) deg -> no phase crossover below 2 kHz
    assert patch.gain_margin == np.inf or patch.gain_margin > 1.0
    assert patch.delay_margin > 1e-3


def test_unknown_input_lists_the_inputs(seed):
    model = LinearManipulator(seed, HubPD(1.0, 0.1))
    with pytest.raises(ModelError, match=r"unknown manipulator input 'pzt9.voltage'; available: .*pzt1.voltage"):
        model.response([1.0], input="pzt9.voltage")
