"""The control toolset (loop transfer functions, margins) on planar models with loops.

Independent reference: the linearised pendulum in closed form, L(s) = (kp + kd s) e^{-s tau} /
(J s^2 + m g a), with the gain crossover from brentq on |L(i w)| = 1.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import ctmm
from ctmm.control import ControlledModel, Feedback, loop_transfer_function, margins
from ctmm.errors import ModelError
from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody

G, MASS, LENGTH = 9.81, 1.3, 0.7
KP, KD, TAU = 6.0, 0.8, 0.05
INERTIA = MASS * LENGTH ** 2 / 3.0


def system(delay: float = TAU) -> ControlledModel:
    plant = PlanarModel.chain("pendulum", [Fixed("ground"), ActuatedHinge("motor"),
                                           RigidBody.uniform_link("link", mass=MASS, length=LENGTH)])
    return ControlledModel(plant, [Feedback("pd", sensor=[("motor.angle", KP), ("motor.rate", KD)],
                                            actuator="motor.torque", gain=1.0, delay=delay)])


def exact_loop(w):
    s = 1j * np.asarray(w, float)
    return (KP + KD * s) * np.exp(-s * TAU) / (INERTIA * s ** 2 + MASS * G * LENGTH / 2.0)


def test_loop_transfer_function_of_a_planar_loop_equals_the_closed_form():
    w = np.linspace(0.2, 40.0, 200)
    L = loop_transfer_function(system(), "pd", w)("pd.L")
    np.testing.assert_allclose(L, exact_loop(w), rtol=1e-8)


def test_margins_of_a_planar_loop_equal_the_closed_form():
    result = margins(system(), "pd", np.linspace(0.05, 60.0, 3000))
    w_gc = brentq(lambda w: abs(exact_loop(w)) - 1.0, 1.0, 60.0)
    phase_margin = np.pi + np.angle(exact_loop(w_gc))
    assert result.gain_crossovers == pytest.approx([w_gc], rel=1e-9)
    assert result.delay_margin == pytest.approx(phase_margin / w_gc, rel=1e-8)
    assert any("planar model" in note for note in result.notes)


def test_loop_tools_refuse_unknown_loops_and_plain_models():
    with pytest.raises(ModelError, match="pd"):
        loop_transfer_function(system(), "speed", [1.0])
    with pytest.raises(ModelError):
        loop_transfer_function(system().plant, "pd", [1.0])


def test_margins_of_a_planar_loop_add_the_crossover_a_coarse_grid_misses():
    result = margins(system(), "pd", np.linspace(0.05, 3.0, 50))          # the crossover is near 7.9 rad/s
    w_gc = brentq(lambda w: abs(exact_loop(w)) - 1.0, 1.0, 60.0)
    assert result.gain_crossovers == pytest.approx([w_gc], rel=1e-9)
    assert result.delay_margin == pytest.approx((np.pi + np.angle(exact_loop(w_gc))) / w_gc, rel=1e-8)
    assert any("certified search" in note for note in result.notes)


def test_exact_field_margins_of_the_manipulator_scene_equal_the_continuum_reference():
    """fields="exact": the scene's hub loop on the exact beam fields has the crossovers and delay margins
    of the loop transfer function of the 150-mode Lagrange model with static correction (the former
    ``LinearManipulator`` chain gave the same margins to 1e-15 before it was removed)."""
    from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_PZT_GAIN, HubPD, PZTFeedback, manipulator_scene,
                                  seed_manipulator)
    from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

    arm = seed_manipulator()
    pd, law = HubPD(SEED_KP, SEED_KD), PZTFeedback.per_patch([SEED_PZT_GAIN] * arm.n_patches)
    scene = manipulator_scene(arm, pd=pd, pzt=law, geometric_stiffening=False)
    omega = np.linspace(0.5, 60.0, 300)
    exact = margins(scene, "hub_pd", omega, fields="exact")
    lagrange = ManipulatorLagrange.from_manipulator(arm, 150)

    def reference_loop(w):
        plant = lagrange.frequency_response(np.atleast_1d(w), kp=SEED_KP, kd=SEED_KD, pd_closed=False,
                                            pzt_gains=law.gains)["torque"]["theta"]
        return (SEED_KP + 1j * SEED_KD * np.atleast_1d(w)) * plant

    magnitude = np.abs(reference_loop(omega)) - 1.0
    brackets = np.flatnonzero(np.sign(magnitude[:-1]) != np.sign(magnitude[1:]))
    crossovers = [brentq(lambda w: abs(reference_loop(w)[0]) - 1.0, omega[k], omega[k + 1], xtol=1e-14)
                  for k in brackets]
    assert len(crossovers) >= 1
    np.testing.assert_allclose(exact.gain_crossovers, crossovers, rtol=1e-9)
    expected = [(np.pi + np.angle(reference_loop(w)[0])) % (2 * np.pi) / w for w in crossovers]
    np.testing.assert_allclose(exact.delay_margins, expected, rtol=1e-8)
    assert any("exact beam fields" in note for note in exact.notes)
    # a rigid pendulum hanging in gravity: its exact form (pendulum terms, ctmm/elements/bending_preload.py)
    # is its linearisation
    hanging = loop_transfer_function(system(), "pd", [1.0, 7.0], fields="exact")
    np.testing.assert_allclose(hanging.response, loop_transfer_function(system(), "pd", [1.0, 7.0]).response,
                               rtol=1e-10)


def _loop_from_the_frequency_response(model: ControlledModel, w) -> np.ndarray:
    """``L`` as margins formed it before it linearised once: ctmm.frequency_response (a fresh linearisation)
    of the open plant, summed over the loop's sensor terms in the same order."""
    frf = ctmm.frequency_response(model.plant, np.atleast_1d(w), input="motor.torque",
                                  output=["motor.angle", "motor.rate"])
    P = np.zeros(np.size(w), dtype=complex)
    for sensor, weight in (("motor.angle", KP), ("motor.rate", KD)):
        P = P + 1.0 * weight * frf(sensor, "motor.torque")
    return model.loop("pd").loop_gain(1j * np.atleast_1d(w)) * P


def test_margins_linearise_once_per_call_with_the_numbers_of_fresh_linearisations(monkeypatch):
    """Was: every evaluation of L in the crossover refinement linearised the model again (86 here)."""
    import ctmm.planar_linearization as planar_linearization

    calls = []
    original = planar_linearization.tangent
    monkeypatch.setattr(planar_linearization, "tangent", lambda *a, **k: calls.append(1) or original(*a, **k))
    model, grid = system(), np.linspace(0.05, 60.0, 300)
    result = margins(model, "pd", grid)
    assert len(calls) == 3                  # L, and the certified search's gain crossovers and gain margins
    for w_gc, pm in zip(result.gain_crossovers, result.phase_margins):
        assert pm == (180.0 + np.degrees(np.angle(_loop_from_the_frequency_response(model, w_gc)[0])) + 180.0) \
            % 360.0 - 180.0
    for w_pc, gm in zip(result.phase_crossovers, result.gain_margins):
        assert gm == 1.0 / abs(_loop_from_the_frequency_response(model, w_pc)[0])
    np.testing.assert_array_equal(loop_transfer_function(model, "pd", grid)("pd.L"),
                                  _loop_from_the_frequency_response(model, grid))
    w_gc = brentq(lambda w: abs(exact_loop(w)) - 1.0, 1.0, 60.0)          # independent: the closed form
    assert result.gain_crossovers == pytest.approx([w_gc], rel=1e-9)
    w_pc = brentq(lambda w: exact_loop(w).imag, 20.0, 30.0)
    assert result.phase_crossovers[0] == pytest.approx(w_pc, rel=1e-9)
