"""Manipulator parameters and control laws: derived constants and bad input (issue 6, A)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.errors import ModelError
from ctmm.manipulator import (PZT_5A, PZT_5H, Arm, CycloidalMove, Hub, HubPD,
                              Manipulator, PZTFeedback, PZTPatch, manipulator_scene, moment_per_volt, seed_manipulator)


def test_arm_section_properties_of_the_seed_arm():
    arm = Arm()                                     # 1 m x 40 mm x 3 mm aluminium
    assert arm.bending_stiffness == pytest.approx(70e9 * 0.04 * 0.003 ** 3 / 12, rel=1e-15)
    assert arm.bending_stiffness == pytest.approx(6.3, rel=1e-12)
    assert arm.mass_per_length == pytest.approx(0.324, rel=1e-12)
    # clamped-free omega_1 = 1.8751^2 sqrt(EI / (rho A L^4))
    assert arm.clamped_free_frequency(1) == pytest.approx(1.8751040687 ** 2 * math.sqrt(6.3 / 0.324), rel=1e-12)


def test_moment_per_volt_formula_and_sign():
    # c_a = -E_p d31 b (t_b + t_a)/2 (Bailey-Hubbard pin-force moment, bonding neglected)
    ca = moment_per_volt(PZT_5H, patch_thickness=5e-4, patch_width=0.04, arm_thickness=3e-3)
    assert ca == pytest.approx(60.6e9 * 2.74e-10 * 0.04 * 3.5e-3 / 2, rel=1e-14)
    assert ca > 0                                    # d31 < 0: positive voltage -> positive curvature
    assert moment_per_volt(PZT_5A, patch_thickness=5e-4, patch_width=0.04, arm_thickness=3e-3) < ca
    patch = PZTPatch("p", 0.1, 0.2, width=0.02)
    assert patch.moment_per_volt(Arm()) == pytest.approx(ca / 2, rel=1e-14)


def test_seed_manipulator_is_consistent():
    m = seed_manipulator()
    assert m.patch_names == ("pzt1", "pzt2", "pzt3")
    assert m.patch_ends.shape == (3, 2)
    assert np.all(m.moments_per_volt > 0)
    r, L = m.hub.radius, m.arm.length
    assert m.rigid_inertia == pytest.approx(m.hub.inertia + m.arm.mass_per_length * ((r + L) ** 3 - r ** 3) / 3)


def test_patches_are_sorted_and_may_touch():
    m = Manipulator(patches=(PZTPatch("b", 0.5, 0.6), PZTPatch("a", 0.4, 0.5)))
    assert m.patch_names == ("a", "b")


@pytest.mark.parametrize("patches, message", [
    ((PZTPatch("p", 0.9, 1.1),), r"'p' \[0.9, 1.1\] m lies outside the arm \[0, 1\] m"),
    ((PZTPatch("p", -0.05, 0.1),), "lies outside the arm"),
    ((PZTPatch("p", 0.1, 0.3), PZTPatch("q", 0.2, 0.4)), r"patches 'p' \[0.1, 0.3\] and 'q' \[0.2, 0.4\] overlap"),
    ((PZTPatch("p", 0.1, 0.2), PZTPatch("p", 0.3, 0.4)), "patch names must be unique"),
    ((PZTPatch("p", 0.1, 0.2, width=0.05),), "wider"),
])
def test_bad_patches_are_reported(patches, message):
    with pytest.raises(ModelError, match=message):
        Manipulator(patches=patches)


def test_all_problems_are_reported_together():
    with pytest.raises(ModelError) as info:
        Manipulator(patches=(PZTPatch("p", 0.1, 0.3), PZTPatch("q", 0.2, 1.4)), voltage_limit=-1.0)
    text = str(info.value)
    assert "overlap" in text and "outside the arm" in text and "voltage_limit must be > 0" in text


def test_bad_parameters_name_the_parameter():
    with pytest.raises(ModelError, match="arm: thickness must be > 0"):
        Arm(thickness=0.0)
    with pytest.raises(ModelError, match="hub: inertia must be > 0"):
        Hub(inertia=-1.0)
    with pytest.raises(ModelError, match="end .* must be > start"):
        PZTPatch("p", 0.3, 0.2)
    with pytest.raises(ModelError, match="d31 must be non-zero"):
        type(PZT_5A)("x", d31=0.0, youngs_modulus=1e9)


@pytest.mark.parametrize("kp, kd, delay, message", [
    (0.0, 1.0, 0.0, "kp must be > 0"),
    (-5.0, 1.0, 0.0, "kp must be > 0"),
    (5.0, -1.0, 0.0, "kd must be >= 0"),
    (5.0, 1.0, -0.01, "delay must be >= 0"),
])
def test_pd_gains_are_checked(kp, kd, delay, message):
    with pytest.raises(ModelError, match=message):
        HubPD(kp, kd, delay)


def test_pzt_gains_are_checked():
    with pytest.raises(ModelError, match=r"per-patch gains must be >= 0 .* Ka_2 = -3.0"):
        PZTFeedback.per_patch([1.0, -3.0])
    with pytest.raises(ModelError, match="square"):
        PZTFeedback(np.ones((2, 3)))
    with pytest.raises(ModelError, match="on_limit must be one of"):
        PZTFeedback.per_patch([1.0], on_limit="ignore")
    with pytest.raises(ModelError, match="cannot be estimated from 2 patch sensors"):
        PZTFeedback.modal(np.ones((2, 3)), np.ones((2, 3)))
    with pytest.raises(ModelError, match="for 2 patches, the manipulator has 3"):
        manipulator_scene(seed_manipulator(), pd=HubPD(1.0, 0.1), pzt=PZTFeedback.per_patch([1.0, 1.0]))


def test_modal_gains_round_trip():
    rng = np.random.default_rng(3)
    Psi = rng.normal(size=(3, 3))
    Ka = rng.normal(size=(3, 3))
    law = PZTFeedback.modal(Ka, Psi)
    np.testing.assert_allclose(law.modal_gains(Psi), Ka, atol=1e-12)
    seed = PZTFeedback.per_patch([1.0, 2.0, 3.0])
    np.testing.assert_allclose(seed.modal_gains(Psi), np.diag([1.0, 2.0, 3.0]) @ Psi)
    np.testing.assert_allclose(seed.voltages([0.1, 0.2, 0.3]), [-0.1, -0.4, -0.9])


def test_cycloidal_move_derivatives():
    move = CycloidalMove(final_angle=1.2, duration=0.8, start_angle=0.2, start_time=0.1)
    t = np.linspace(0.0, 1.2, 241)
    h = 1e-6
    np.testing.assert_allclose((move.angle(t + h) - move.angle(t - h)) / (2 * h), move.rate(t), atol=1e-7)
    # (the jerk jumps at the ends of the move: O(h) difference error there)
    np.testing.assert_allclose((move.rate(t + h) - move.rate(t - h)) / (2 * h), move.acceleration(t), atol=1e-4)
    assert move.angle(0.0) == 0.2 and move.angle(5.0) == pytest.approx(1.2)
    assert move.rate(0.5) == pytest.approx(float(move.rate(np.array([0.5]))[0]))
    assert move.breakpoints == (0.1, pytest.approx(0.9))
