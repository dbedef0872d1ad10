"""The linearised controlled manipulator in the frequency domain: the scene (``manipulator_scene``)
through the verbs on its exact beam fields (``fields="exact"``), against the linearised Lagrange
reference (issue 6, C; issue 12 item 4: the former ``LinearManipulator`` chain gave the same
numbers, compared before it was removed)."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import loop_transfer_function, margins
from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_PZT_GAIN, HubPD, PZTFeedback, manipulator_scene,
                              seed_manipulator)
from ctmm.manipulator.scene import HUB_LOOP, TIP_STATION
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


def scene_response(seed, pd, pzt, omega, input):  # noqa: A002 - the reference's name for it
    """Closed-loop responses of the scene's exact fields per unit ``input``: ``"theta_d"`` (desired
    hub angle, through the hub loop's reference ``r = kp theta_d + kd theta_d_dot``), ``"torque"``
    (extra motor torque) or ``"<patch>.voltage"`` (the patch's moment pair times ``c_a``)."""
    w = np.asarray(omega, dtype=float)
    scene = manipulator_scene(seed, pd=pd, pzt=pzt)
    patches = seed.patches
    if input == "theta_d":
        terms = [(f"{HUB_LOOP}.reference", pd.kp + 1j * w * pd.kd)]
    elif input == "torque":
        terms = [("motor.torque", 1.0)]
    else:
        k = [f"{p.name}.voltage" for p in patches].index(input)
        ca = seed.moments_per_volt[k]
        terms = [(f"arm.{patches[k].name}_x1.moment", -ca), (f"arm.{patches[k].name}_x2.moment", ca)]
    outputs = ["motor.angle", f"arm.{TIP_STATION}.w", f"{HUB_LOOP}.u"]
    outputs += [f"arm.{p.name}_x{end}.slope" for p in patches for end in (1, 2)]
    if pzt is not None:
        outputs += [f"{p.name}.u" for p in patches]
    frf = ctmm.frequency_response(scene, w, input=[name for name, _ in terms], output=outputs, fields="exact")

    def value(signal):
        return sum(weight * frf(signal, name) for name, weight in terms)

    volts = (np.array([value(f"{p.name}.u") for p in patches]) if pzt is not None
             else np.zeros((len(patches), w.size), dtype=complex))
    for k, patch in enumerate(patches):            # an injected voltage adds to the loop's output
        if input == f"{patch.name}.voltage":
            volts[k] += 1.0
    return {"theta": value("motor.angle"), "tip": value(f"arm.{TIP_STATION}.w"), "torque": value(f"{HUB_LOOP}.u"),
            "voltages": volts,
            "slopes": np.array([value(f"arm.{p.name}_x2.slope") - value(f"arm.{p.name}_x1.slope") for p in patches])}


@pytest.mark.parametrize("pd_delay, pzt_delay", [(0.0, 0.0), (0.01, 0.003)])
def test_closed_loop_frf_equals_the_lagrange_reference(seed, reference, pd_delay, pzt_delay):
    G = np.diag([SEED_PZT_GAIN, 0.6 * SEED_PZT_GAIN, 0.3 * SEED_PZT_GAIN])
    G[0, 2] = 100.0                                   # a cross-coupled sensor term as well
    pd, pzt = HubPD(SEED_KP, SEED_KD, pd_delay), PZTFeedback(G, delay=pzt_delay)
    ref = reference.frequency_response(OMEGA, kp=SEED_KP, kd=SEED_KD, pd_delay=pd_delay, pzt_gains=G,
                                       pzt_delay=pzt_delay)
    for inp, key in (("theta_d", "theta_d"), ("torque", "torque"), ("pzt2.voltage", "voltage_2")):
        tmm = scene_response(seed, pd, pzt, OMEGA, inp)
        assert _rel(tmm["tip"], ref[key]["tip"]).max() < 1e-8, inp
        assert _rel(tmm["theta"], ref[key]["theta"]).max() < 1e-8, inp
        assert np.abs(tmm["voltages"] - ref[key]["voltages"]).max() < 1e-8 * np.abs(ref[key]["voltages"]).max()
        assert np.abs(tmm["slopes"] - ref[key]["slopes"]).max() < 1e-8 * np.abs(ref[key]["slopes"]).max()


def test_pd_only_frf_and_modal_truncation_error(seed, reference):
    """Without static correction the N-mode reference converges like 1/N (moment-pair ports), so
    the continuum TMM is the better yardstick; the error is quantified here."""
    tmm = scene_response(seed, HubPD(SEED_KP, SEED_KD), None, OMEGA, "theta_d")
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
    scene = manipulator_scene(seed, pd=HubPD(SEED_KP, SEED_KD, 0.005), pzt=PZTFeedback(G, delay=0.002))
    kwargs = dict(kp=SEED_KP, kd=SEED_KD, pd_delay=0.005, pzt_gains=G, pzt_delay=0.002)
    L_pd = loop_transfer_function(scene, HUB_LOOP, OMEGA, fields="exact")(f"{HUB_LOOP}.L")
    open_pd = reference.frequency_response(OMEGA, pd_closed=False, **kwargs)["torque"]["theta"]
    assert _rel(L_pd, (SEED_KP + SEED_KD * 1j * OMEGA) * np.exp(-0.005j * OMEGA) * open_pd).max() < 1e-8
    L_p1 = loop_transfer_function(scene, "pzt1", OMEGA, fields="exact")("pzt1.L")
    open_p1 = reference.frequency_response(OMEGA, pzt_closed=[False, True, True], **kwargs)
    assert _rel(L_p1, np.exp(-0.002j * OMEGA) * open_p1["voltage_1"]["pzt_sensed"][0]).max() < 1e-8


def test_pzt_feedback_flattens_the_first_flexible_resonance(seed):
    w = np.linspace(10.0, 25.0, 301)
    pd = HubPD(SEED_KP, SEED_KD)
    with_pzt = scene_response(seed, pd, PZTFeedback.per_patch([SEED_PZT_GAIN] * 3), w, "theta_d")["tip"]
    without = scene_response(seed, pd, None, w, "theta_d")["tip"]
    ratio = np.abs(with_pzt).max() / np.abs(without).max()
    assert ratio < 0.35, ratio              # measured 0.266 on this grid


def test_margins_of_the_hub_and_of_a_patch(seed, monkeypatch):
    import ctmm.exact_fields as exact_fields

    built, build = [], exact_fields.exact_form
    monkeypatch.setattr(exact_fields, "exact_form", lambda *args, **kwargs: built.append(1) or build(*args, **kwargs))
    scene = manipulator_scene(seed, pd=HubPD(SEED_KP, SEED_KD), pzt=PZTFeedback.per_patch([SEED_PZT_GAIN] * 3))
    hub = margins(scene, HUB_LOOP, np.logspace(-1, 3, 300), fields="exact")
    assert 40.0 < hub.phase_margin < 90.0 and np.isfinite(hub.delay_margin)
    # one exact form answers the grid and every crossover refinement (it was rebuilt at each of ~80 evaluations)
    assert len(built) == 1
    patch = margins(scene, "pzt1", np.logspace(0, 3.3, 300), fields="exact")
    # collocated slope-rate feedback: phase of L in (-90, 90) deg -> no phase crossover below 2 kHz
    assert patch.gain_margin == np.inf or patch.gain_margin > 1.0
    assert patch.delay_margin > 1e-3


def test_an_exact_response_answers_every_call_as_a_fresh_one(seed):
    """The exact form built at the first call is not changed by a solve: later calls (other frequencies,
    as in the margins' refinement) equal a fresh form's answer exactly."""
    from ctmm.exact_fields import ExactResponse

    scene = manipulator_scene(seed, pd=HubPD(SEED_KP, SEED_KD), pzt=PZTFeedback.per_patch([SEED_PZT_GAIN] * 3))
    ports = (["hub_pd.reference", "pzt1.reference"], ["arm.tip.w", "hub_pd.u"])
    reused = ExactResponse(scene, *ports)
    first = reused(OMEGA[::-2])
    later = reused(OMEGA)
    fresh = ExactResponse(scene, *ports)(OMEGA)
    assert np.array_equal(later, fresh) and np.array_equal(first, fresh[..., ::-2])
