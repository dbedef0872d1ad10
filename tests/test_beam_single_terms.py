"""The unbatched fast path of the planar modal beam's body terms (:func:`ctmm.flexible.beam_single.single_terms`,
used by the explicit sweep) against the batched routine :meth:`ctmm.flexible.beam.BeamData.terms` (the generic
statements that also run on complex numbers and casadi symbols), at a batch of three random states, each compared
with the fast path at that state to 1e-13 relative: beams with and without geometric stiffening, axial modes,
damping, a time-varying point load and distributed load, modal forces (force, stiffness, damping, law), two ends,
the Rayleigh sections' turning and the second-order inertia."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.flexible import ModalBeam
from ctmm.flexible.beam import ModalForce
from ctmm.flexible.beam_single import single_terms
from ctmm.planar import Load, Pinned, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.elements import FixedMounting

RNG = np.random.default_rng(11)
GRAVITY = (0.7, -9.81)


def _law(t, eta, eta_dot):
    return 0.3 * eta * eta_dot + 0.1 * math.sin(t)


def _beams() -> dict:
    load = Load(point=(0.7, 0.0), force_x=lambda t: 0.3 + t, force_y=lambda t: math.sin(3 * t), moment=0.2)
    common = dict(length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3)
    hooks = (ModalForce(force=lambda t: np.array([0.1, -0.2, 0.05 * t, 0.3]), stiffness=0.2 * np.eye(4),
                        damping=0.05 * np.ones((4, 4)), law=_law, label="patch"),)
    return {
        "axial_loads_hooks": ModalBeam("b1", **common, n_axial_modes=1, axial_stiffness=300.0, damping_ratio=0.02,
                                       stiffness_damping=1e-3, distributed_load=(0.4, lambda t: -0.2 * t),
                                       loads=(load,), modal_forces=hooks, outboard={"mid": 0.6, "tip": 1.3}),
        "no_stiffening": ModalBeam("b2", **common, n_axial_modes=2, axial_stiffness=100.0,
                                   geometric_stiffening=False, loads=(load,)),
        "rayleigh": ModalBeam("b3", **common, rotary_inertia_per_length=0.01, distributed_load=(0.1, -0.3)),
        "second_order": ModalBeam("b4", **common, second_order_inertia=True, loads=(load,),
                                  outboard={"mid": 0.5, "tip": 1.3}),
    }


def _close(got: np.ndarray, expected: np.ndarray, what: str) -> None:
    scale = max(1.0, float(np.abs(expected).max()))
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-13 * scale, err_msg=what)


@pytest.mark.parametrize("kind", list(_beams()))
def test_single_state_terms_equal_the_batched_terms(kind):
    data = _beams()[kind].data
    B, n = 3, data.n
    theta, omega = RNG.uniform(-3, 3, B), RNG.uniform(-4, 4, B)
    eta, eta_dot = 0.05 * RNG.normal(size=(B, n)), 0.5 * RNG.normal(size=(B, n))
    t = 0.37
    M, h, ends = data.terms(theta, omega, eta, eta_dot, t, GRAVITY)
    assert len(ends) == len(data.end_names)
    for b in range(B):
        Ms, hs, ends_s = single_terms(data, float(theta[b]), float(omega[b]), eta[b].copy(), eta_dot[b].copy(), t,
                                      GRAVITY)
        _close(Ms, M[b], f"{kind}: M, state {b}")
        _close(hs, h[b], f"{kind}: h, state {b}")
        assert len(ends_s) == len(ends)
        for e, (batched, single) in enumerate(zip(ends, ends_s)):
            for field, got, expected in zip(("Kin", "c", "RF", "theta_e", "omega_e"), single, batched):
                _close(np.asarray(got), expected[b], f"{kind}: end {e} {field}, state {b}")
        # and the batched routine at this one state (B = 1), the explicit sweep's old call
        M1, h1, _ = data.terms(theta[b:b + 1], omega[b:b + 1], eta[b:b + 1], eta_dot[b:b + 1], t, GRAVITY)
        _close(Ms, M1[0], f"{kind}: M at B = 1, state {b}")
        _close(hs, h1[0], f"{kind}: h at B = 1, state {b}")


def test_the_explicit_sweep_terms_equal_the_batched_body_terms():
    """FlexibleSystem.all_terms (fast path for beams) against body_terms at B = 1 (the batched routine) on a tree with
    two beams and a link."""
    common = dict(length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3)
    model = PlanarModel("tree", [Pinned("o", child="b1"), ModalBeam("b1", **common, outboard={"mid": 0.6, "tip": 1.3}),
                                 SmoothHinge("h", parent="b1.mid", child="l"),
                                 RigidBody.uniform_link("l", mass=0.4, length=0.7),
                                 FixedMounting("w", parent="b1.tip", child="b2", angle=-0.4),
                                 ModalBeam("b2", **common, n_axial_modes=1, axial_stiffness=80.0)])
    system = model.flexible_system
    assert set(system.at_state) == set(system.beam_data)
    q, v = 0.1 * RNG.normal(size=model.n_coordinates), RNG.normal(size=model.n_coordinates)
    terms, (theta, omega, eta, eta_dot, loads) = system.all_terms(q, v, 0.2)
    for j, (M, h, ends) in enumerate(terms):
        M1, h1, ends1 = system.body_terms(j, theta[j:j + 1], omega[j:j + 1], eta[j][None], eta_dot[j][None], 0.2,
                                          loads)
        _close(M, M1[0], f"body {j}: M")
        _close(h, h1[0], f"body {j}: h")
        for (K, c, R), batched in zip(ends, ends1):
            for got, expected in zip((K, c, R), batched):
                _close(got, expected[0], f"body {j}: end terms")


def test_the_sweep_reads_the_ends_that_carry_a_child_and_they_are_the_full_terms():
    """``all_terms(carrying=True)`` (the explicit sweep's call) gives of each body the terms of the ends that carry a
    child, equal bit for bit to the full terms, and ``None`` for the others (a beam's free tip, a link's tip)."""
    common = dict(length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3)
    model = PlanarModel("tree", [Pinned("o", child="b1"), ModalBeam("b1", **common, outboard={"mid": 0.6, "tip": 1.3}),
                                 SmoothHinge("h", parent="b1.mid", child="l"),
                                 RigidBody("l", mass=0.4, inertia=0.02, outboard={"end": (0.7, 0.0)}),
                                 FixedMounting("w", parent="b1.tip", child="b2", angle=-0.4), ModalBeam("b2", **common)])
    system = model.flexible_system
    q, v = 0.1 * RNG.normal(size=model.n_coordinates), RNG.normal(size=model.n_coordinates)
    full, _ = system.all_terms(q, v, 0.2)
    carried, _ = system.all_terms(q, v, 0.2, carrying=True)
    assert [[e is not None for e in ends] for _, _, ends in carried] == [[True, True], [False], [False]]
    for (M, h, ends), (Mc, hc, ends_c) in zip(full, carried):
        np.testing.assert_array_equal(Mc, M)
        np.testing.assert_array_equal(hc, h)
        for end, end_c in zip(ends, ends_c):
            for got, expected in zip(end_c or (), end):
                np.testing.assert_array_equal(got, expected)


def test_the_rigid_bodies_of_the_explicit_sweep_are_their_batched_terms_bit_for_bit():
    """``all_terms`` gives a flexible tree's rigid bodies by the one statement on Python floats
    (``FlexibleSystem.rigid_terms_at_state``): every number equal to ``rigid_terms`` at ``B = 1`` (numpy ops), bit for
    bit, with a time-varying load, a constant one and two carrying ends, and with ``carrying=True``."""
    common = dict(length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=2)
    loads = (Load(point=(0.3, 0.1), force_x=lambda t: 0.3 + t, force_y=lambda t: math.sin(3 * t), moment=0.2),
             Load(point=(-0.1, 0.2), force_y=-1.5))
    model = PlanarModel("tree", [
        Pinned("o", child="hub"),
        RigidBody("hub", mass=1.7, inertia=0.05, center_of_mass=(0.04, -0.02), loads=loads,
                  outboard={"a": (0.2, 0.05), "b": (-0.1, 0.3), "free": (0.0, -0.4)}),
        FixedMounting("m", parent="hub.a", child="b1", angle=0.3), ModalBeam("b1", **common),
        SmoothHinge("h", parent="hub.b", child="l"), RigidBody.uniform_link("l", mass=0.4, length=0.7)],
        gravity=GRAVITY)
    system = model.flexible_system
    q, v, t = 0.3 * RNG.normal(size=model.n_coordinates), RNG.normal(size=model.n_coordinates), 0.37
    for carrying in (False, True):
        terms, (theta, omega, _, _, loads_t) = system.all_terms(q, v, t, carrying=carrying)
        for j in system.rigid:
            M, h, ends = system.rigid_terms(j, theta[j:j + 1], omega[j:j + 1], t, loads_t)
            np.testing.assert_array_equal(terms[j][0], M[0])
            np.testing.assert_array_equal(terms[j][1], h[0])
            wanted = system.carrying[j] if carrying else range(len(ends))
            assert [e is not None for e in terms[j][2]] == [e in wanted for e in range(len(ends))]
            for got, (Kin, c, RF, _, _) in zip(terms[j][2], ends):
                for value, expected in zip(got or (), (Kin[0], c[0], RF[0])):
                    np.testing.assert_array_equal(value, expected)
    assert np.any(terms[0][1] != 0.0) and len(model.load_body) == 2
