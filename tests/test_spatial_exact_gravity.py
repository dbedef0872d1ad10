"""Exact spatial fields of chains hanging or standing in gravity (issues 14/15, ``fields="exact"``).

References, none of them transfer matrices: the hanging beam + tip body splits into two bending planes,
each the planar Hermite finite-element model with the consistent geometric stiffness of the linear
tension (ctmm/reference/hanging_beam_fe.py, Richardson over 16 / 32 elements), and axial / torsional
bars with a tip mass / inertia (their frequency equations, solved here); rigid pendulums by their
Lagrange linearisation written here."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.reference.hanging_beam_fe import HangingBeam

# The references here are linear theory about the unstretched beams, as the exact fields; the static stretch
# they neglect is measured and warned in tests/test_spatial_exact_stretch.py.
pytestmark = pytest.mark.filterwarnings("ignore::ctmm.spatial_exact_gravity.StretchWarning")

G = 9.81
ARM = dict(length=1.2, mass_per_length=0.4, bending_stiffness_y=3.0, bending_stiffness_z=5.0,
           torsional_stiffness=2.0, polar_inertia_per_length=0.002, axial_stiffness=4000.0)
MODES = dict(n_modes_y=1, n_modes_z=1, n_torsion_modes=1, n_axial_modes=1)
DOWN = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])      # beam x along world -z, beam y = world y
TIP, TIP_INERTIA = 0.5, np.diag([0.003, 0.002, 0.004])


def hanging_arm(gravity=(0.0, 0.0, -G), rotation=DOWN) -> sp.SpatialModel:
    return sp.SpatialModel("hanging", [
        sp.SpatialBeam("arm", **ARM, **MODES), sp.Weld(name="root", parent=None, child="arm", rotation=rotation),
        sp.SpatialBody("tip", TIP, TIP_INERTIA), sp.Weld(name="grip", parent="arm", child="tip", point="tip")],
        gravity=gravity)


def plane(bending_stiffness, tip_inertia):
    return HangingBeam(ARM["length"], bending_stiffness, ARM["mass_per_length"], G, TIP, tip_inertia)


def bar_frequencies(stiffness, density, tip, count):
    """Fixed bar with a tip mass: ``K k cos(k L) = tip omega^2 sin(k L)``, ``k = omega sqrt(density / K)``."""
    L = ARM["length"]

    def equation(w):
        k = w * np.sqrt(density / stiffness)
        return stiffness * k * np.cos(k * L) - tip * w * w * np.sin(k * L)
    grid = np.linspace(1e-3, 3000.0, 300001)
    values = equation(grid)
    changes = np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:]))[:count]
    return [scipy.optimize.brentq(equation, grid[i], grid[i + 1], xtol=1e-14) for i in changes]


def test_a_hanging_spatial_beam_with_a_tip_body_has_the_frequencies_of_its_planes_and_bars():
    omega = ctmm.natural_frequencies(hanging_arm(), n_modes=6, fields="exact")
    reference = []
    # bending in the beam's x-y plane (w_y, EI = bending_stiffness_y, tip turning about beam z) and x-z plane
    for stiffness, inertia in ((ARM["bending_stiffness_y"], TIP_INERTIA[2, 2]),
                               (ARM["bending_stiffness_z"], TIP_INERTIA[1, 1])):
        coarse, fine = plane(stiffness, inertia).natural_frequencies(16, 4), plane(stiffness, inertia).natural_frequencies(32, 4)
        reference += list(fine + (fine - coarse) / 15.0)
    reference += bar_frequencies(ARM["axial_stiffness"], ARM["mass_per_length"], TIP, 2)
    reference += bar_frequencies(ARM["torsional_stiffness"], ARM["polar_inertia_per_length"], TIP_INERTIA[0, 0], 2)
    np.testing.assert_allclose(omega, np.sort(reference)[:6], rtol=3e-9)            # 3.8e-10 measured
    weightless = ctmm.natural_frequencies(hanging_arm((0.0, 0.0, 0.0)), n_modes=6, fields="exact")
    assert np.all(omega >= weightless * (1 - 1e-12)) and np.all(omega[:2] > weightless[:2] * 1.1)   # stiffening
    assert omega[2] == pytest.approx(weightless[2], rel=1e-12)              # the first torsion mode: no Wagner term


def test_the_tip_receptance_of_the_hanging_spatial_beam_equals_the_finite_element_plane():
    omega = np.array([0.8, 6.0, 25.0])
    frf = ctmm.frequency_response(hanging_arm(), omega, input="tip.force_y", output="tip.origin.y", fields="exact")
    reference = plane(ARM["bending_stiffness_y"], TIP_INERTIA[2, 2])
    coarse, fine = reference.tip_receptance(16, omega), reference.tip_receptance(32, omega)
    expected = fine + (fine - coarse) / 15.0
    np.testing.assert_allclose(frf("tip.origin.y", "tip.force_y"), expected, rtol=1e-8)


def test_a_hanging_or_standing_spatial_double_pendulum_equals_its_lagrange_linearisation():
    m1, c1, l1, m2, c2, k0, k = 1.0, 0.5, 1.0, 0.7, 0.3, 30.0, 20.0
    I1, I2 = np.diag([0.12, 0.1, 0.03]), np.diag([0.06, 0.05, 0.02])
    for g in (G, -G):                          # gravity along +z: hanging from the root; -z: standing on it
        model = sp.SpatialModel("pendulum", [
            sp.SpatialBody("a", m1, I1, center_of_mass=(0.0, 0.0, c1), points={"end": (0.0, 0.0, l1)}),
            sp.Revolute(name="p", parent=None, child="a", axis=(0, 1, 0), stiffness=k0),
            sp.SpatialBody("b", m2, I2, center_of_mass=(0.0, 0.0, c2)),
            sp.Revolute(name="q", parent="a", point="end", child="b", axis=(0, 1, 0), stiffness=k)],
            gravity=(0.0, 0.0, g))
        M = np.array([[I1[1, 1] + m1 * c1 ** 2 + m2 * l1 ** 2, m2 * l1 * c2], [m2 * l1 * c2, I2[1, 1] + m2 * c2 ** 2]])
        K = np.array([[g * (m1 * c1 + m2 * l1) + k0 + k, -k], [-k, g * m2 * c2 + k]])
        reference = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True))
        np.testing.assert_allclose(ctmm.natural_frequencies(model, n_modes=2, fields="exact"), reference, rtol=1e-10)


def test_gravity_the_straight_chain_cannot_carry_is_refused_by_name():
    across = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])         # the beam along world x
    with pytest.raises(ModelError, match=r"beam 'arm' lies along \[1\.0, 0\.0, 0\.0\].*not along gravity"):
        ctmm.natural_frequencies(hanging_arm(rotation=across), n_modes=1, fields="exact")
    leaning = sp.SpatialModel("leaning", [
        sp.SpatialBody("a", 1.0, np.eye(3) * 0.1, center_of_mass=(0.05, 0.0, 0.5)),
        sp.Revolute(name="p", parent=None, child="a", axis=(0, 1, 0), stiffness=30.0)], gravity=(0.0, 0.0, G))
    with pytest.raises(ModelError, match=r"body 'a' has its outboard first moment .* at \[0\.05, 0\.0, 0\.5\] kg m.*vertical"):
        ctmm.natural_frequencies(leaning, n_modes=1, fields="exact")
    floating = sp.SpatialModel("floating", [sp.SpatialBody("a", 1.0, np.eye(3) * 0.1),
                                            sp.Free(name="f", parent=None, child="a")], gravity=(0.0, 0.0, -G))
    with pytest.raises(ModelError, match=r"free or prismatic joints \['f'\]"):
        ctmm.natural_frequencies(floating, n_modes=1, fields="exact")


def test_the_varying_tension_spatial_field_equals_an_ode_integration_and_the_constant_field():
    import scipy.integrate

    from ctmm.spatial_beam_fields import SpatialBeamField, SpatialVaryingTensionField

    parameters = {k: v for k, v in ARM.items() if k != "length"}
    field = SpatialVaryingTensionField("f", 1.1, inboard_tension=20.0, outboard_tension=3.0, rotation=DOWN,
                                       **parameters)
    s = 1j * np.array([2.0, 30.0])
    U = field.transfer_matrix(s)
    for k, sk in enumerate(s):
        solution = scipy.integrate.solve_ivp(lambda x, z, sk=sk: (field.state_matrix_at(sk, x) @ z.reshape(12, 12)).ravel(),
                                             (0.0, 1.1), np.eye(12, dtype=complex).ravel(), method="DOP853",
                                             rtol=1e-13, atol=1e-13)
        reference = solution.y[:, -1].reshape(12, 12)
        assert np.abs(U[k] - reference).max() <= 5e-11 * np.abs(reference).max()
    constant = SpatialVaryingTensionField("c", 1.1, inboard_tension=5.0, outboard_tension=5.0, rotation=DOWN, **parameters)
    exact = SpatialBeamField("e", 1.1, axial_force=5.0, rotation=DOWN, **parameters)
    assert np.abs(constant.transfer_matrix(s) - exact.transfer_matrix(s)).max() <= 1e-13 * np.abs(exact.transfer_matrix(s)).max()
    np.testing.assert_array_equal(constant.clamped_frequency_count([10.0, 100.0, 300.0]),
                                  exact.clamped_frequency_count([10.0, 100.0, 300.0]))
    assert [piece.inboard_tension for piece in field.split(2)] == [20.0, 11.5]
