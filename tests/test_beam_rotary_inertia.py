"""Section rotary inertia (Rayleigh term ``rho I``) in the modal beams: planar ``ModalBeam(rotary_inertia_per_length)``
and ``SpatialBeam(rotary_inertia_per_length_y|z)``, and the spatial exact-field converter passing it on.

Independent references, none of them transfer matrices or ctmm.flexible / ctmm.spatial code:

* the clamped-free Rayleigh beam's frequency equation, written here: ``EI w'''' + rho I omega^2 w'' - rhoA omega^2 w =
  0``, ``w = C1 cosh(a x) + C2 sinh(a x) + C3 cos(b x) + C4 sin(b x)``, clamped ``w = w' = 0``, free ``w'' = 0`` and
  ``EI w''' + rho I omega^2 w' = 0`` (the natural end condition of the rotary inertia's energy);
* a Hermite finite-element Rayleigh cantilever with a tip body, written here (consistent mass and rotary inertia
  ``rho I / (30 h) [...]``, 32 / 64 elements, Richardson);
* the assumed-modes Lagrange models :mod:`ctmm.reference.flexible_lagrange` (planar, mass points with their section
  turning) and :mod:`ctmm.reference.spatial_beam_lagrange` (casadi AD of the energy with the sections' turning).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.flexible.kernel import solve_flexible
from ctmm.planar import Fixed, Pinned, PlanarModel, RigidBody
from ctmm.planar.elements import FixedMounting
from ctmm.reference.beams import beta_roots
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.reference.spatial_beam_lagrange import HubBeam, SpatialBeamLagrange
from ctmm.spatial.dynamics import accelerations, energy

L, EI, RHO_A, RHO_I = 1.0, 2.0, 0.5, 0.002
EI_Z, RHO_I_Z = 3.0, 0.003


def rayleigh_cantilever(length, stiffness, density, rotary, count):
    """The ``count`` lowest clamped-free Rayleigh frequencies [rad/s] (module docstring)."""
    def determinant(omega):
        k = rotary * omega ** 2
        root = math.sqrt(k * k + 4 * stiffness * density * omega ** 2)
        a, b = math.sqrt((root - k) / (2 * stiffness)), math.sqrt((root + k) / (2 * stiffness))
        ch, sh, c, s = (math.cosh(a * length), math.sinh(a * length), math.cos(b * length), math.sin(b * length))
        rows = np.array([[1.0, 0.0, 1.0, 0.0], [0.0, a, 0.0, b],
                         [a * a * ch, a * a * sh, -b * b * c, -b * b * s],
                         [(stiffness * a ** 3 + k * a) * sh, (stiffness * a ** 3 + k * a) * ch,
                          (stiffness * b ** 3 - k * b) * s, -(stiffness * b ** 3 - k * b) * c]])
        return np.linalg.det(rows) / math.cosh(a * length)
    top = 4 * (count + 1) ** 2 * math.pi ** 2 * math.sqrt(stiffness / density) / length ** 2
    grid = np.linspace(1e-6, top, 20001)
    values = np.array([determinant(w) for w in grid])
    found = np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:]))[:count]
    return np.array([scipy.optimize.brentq(determinant, grid[i], grid[i + 1], xtol=1e-14, rtol=1e-15) for i in found])


def rayleigh_fe(length, stiffness, density, rotary, tip_mass, tip_inertia, elements, count):
    """Hermite cubic cantilever: bending, consistent mass and rotary inertia, a tip body (mass and rotary inertia at
    the tip node); the ``count`` lowest frequencies [rad/s]."""
    h = length / elements
    k = stiffness / h ** 3 * np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                                        [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
    m = density * h / 420 * np.array([[156, 22 * h, 54, -13 * h], [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                                      [54, 13 * h, 156, -22 * h], [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
    r = rotary / (30 * h) * np.array([[36, 3 * h, -36, 3 * h], [3 * h, 4 * h * h, -3 * h, -h * h],
                                      [-36, -3 * h, 36, -3 * h], [3 * h, -h * h, -3 * h, 4 * h * h]])
    n = 2 * (elements + 1)
    K, M = np.zeros((n, n)), np.zeros((n, n))
    for e in range(elements):
        dofs = slice(2 * e, 2 * e + 4)
        K[dofs, dofs] += k
        M[dofs, dofs] += m + r
    M[-2, -2] += tip_mass
    M[-1, -1] += tip_inertia
    values = scipy.linalg.eigh(K[2:, 2:], M[2:, 2:], eigvals_only=True, subset_by_index=[0, count - 1])
    return np.sqrt(values)


def planar_cantilever(modes, rotary=RHO_I):
    return PlanarModel.chain("c", [Fixed("g"), ModalBeam("b", length=L, bending_stiffness=EI, mass_per_length=RHO_A,
                                                         n_modes=modes, rotary_inertia_per_length=rotary)],
                             gravity=(0.0, 0.0))


def spatial_cantilever(modes, tip=None, static_shapes=False, gravity=(0.0, 0.0, 0.0), rotation=None):
    beam = sp.SpatialBeam("b", length=L, mass_per_length=RHO_A, bending_stiffness_y=EI, bending_stiffness_z=EI_Z,
                          n_modes_y=modes, n_modes_z=modes, rotary_inertia_per_length_y=RHO_I,
                          rotary_inertia_per_length_z=RHO_I_Z, static_shapes=static_shapes)
    parts = [beam, sp.Weld(name="w", parent=None, child="b", rotation=rotation)]
    if tip is not None:
        parts += [sp.SpatialBody("tip", tip[0], np.diag([0.003, tip[1], tip[2]])),
                  sp.Weld(name="grip", parent="b", point="tip", child="tip")]
    return sp.SpatialModel("s", parts, gravity=gravity)


def test_the_modal_beams_converge_from_above_to_the_rayleigh_frequency_equation():
    """Clamped-free: the Euler-Bernoulli modes do not meet the free end's ``EI w''' + rho I omega^2 w' = 0``, so the
    Ritz frequencies converge from above like a tip load's (``~n^-3``; measured 1.4e-7, 1.9e-8, 2.4e-9 at 4, 8, 16
    modes for the first).  Planar and spatial (one plane each) alike; the exact spatial field with the same data
    equals the equation to 1e-10 in both planes."""
    exact = rayleigh_cantilever(L, EI, RHO_A, RHO_I, 4)
    euler = beta_roots("clamped-free", 4) ** 2 * math.sqrt(EI / RHO_A / L ** 4)
    assert np.all(exact < euler * (1 - 5e-3))                       # the rotary inertia matters (9e-3 .. 0.2)
    gaps = []
    for modes in (4, 8):
        planar = ctmm.natural_frequencies(planar_cantilever(modes), n_modes=4)
        gaps.append(planar / exact - 1)
        spatial = ctmm.natural_frequencies(spatial_cantilever(modes), n_modes=8)
        np.testing.assert_allclose(spatial[::2][:2], planar[:2], rtol=1e-10)   # the weak plane's lowest two
    assert np.all(gaps[0] > 0) and np.all(gaps[1] > 0)                           # from above
    assert np.all(gaps[1] < 0.2 * gaps[0])                                       # measured ratios 0.14 .. 0.11
    assert gaps[1][0] < 3e-8 and gaps[1][3] < 1e-3
    both = np.sort(np.concatenate([exact, rayleigh_cantilever(L, EI_Z, RHO_A, RHO_I_Z, 4)]))
    fields = ctmm.natural_frequencies(spatial_cantilever(2), n_modes=8, fields="exact")
    np.testing.assert_allclose(fields, both, rtol=1e-10)


def test_a_rayleigh_cantilever_with_a_tip_body_equals_the_finite_element_beam():
    """Tip body (mass and rotary inertia at the tip): the exact field of the modal beam's data equals the Hermite FE
    Rayleigh beam (32 / 64 elements, Richardson) to 1e-9, and the modal beam with static shapes (4 modes per plane)
    lies above it (measured 1.5e-10, 3.6e-10, 4.2e-7, 1.2e-6 at the four lowest)."""
    tip = (0.3, 0.002, 0.004)        # mass [kg], inertia about body y (w_z plane), about z (w_y plane) [kg m^2]
    reference = []
    for stiffness, rotary, inertia in ((EI, RHO_I, tip[2]), (EI_Z, RHO_I_Z, tip[1])):
        coarse, fine = (rayleigh_fe(L, stiffness, RHO_A, rotary, tip[0], inertia, n, 4) for n in (32, 64))
        reference += list(fine + (fine - coarse) / 15.0)
    reference = np.sort(reference)[:6]
    fields = ctmm.natural_frequencies(spatial_cantilever(2, tip), n_modes=6, fields="exact")
    np.testing.assert_allclose(fields, reference, rtol=1e-9)
    modal = ctmm.natural_frequencies(spatial_cantilever(4, tip, static_shapes=True), n_modes=6)
    gap = modal / fields - 1
    assert np.all(gap > -1e-12) and np.all(gap[:2] < 1e-9) and np.all(gap[:4] < 3e-6), gap


# bent, spinning, vibrating: planar [hub angle, q1..q3] and spatial [hub angles, q_y, q_z, twist] with rates
PLANAR_Q, PLANAR_V = np.array([0.4, 0.05, -0.02, 0.01]), np.array([5.0, 0.8, -0.5, 0.3])


def planar_hub_beam(rotary):
    beam = ModalBeam("b", length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3, quadrature=16,
                     rotary_inertia_per_length=rotary)
    return PlanarModel("arm", [
        Pinned("o", child="hub"),
        RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", parent="hub", child="b", angle=0.3), beam,
        FixedMounting("weld", parent="b.out", child="tip"),
        RigidBody("tip", mass=0.4, inertia=0.01, center_of_mass=(0.03, 0.01), outboard=(0.1, 0.0))],
        gravity=(0.5, -9.81))


def test_the_planar_beam_with_rotary_inertia_equals_the_lagrange_model():
    """Hub spinning at 5 rad/s, bent beam, tip body, gravity, stiffening: accelerations and joint forces equal the
    assumed-modes Lagrange model with the sections' turning to 1e-10 of their size, the energy of a pinned beam to
    1e-12; without the term the accelerations differ by more than 1e-3."""
    model, reference = planar_hub_beam(0.01), FlexibleLagrange(planar_hub_beam(0.01))
    expected = reference.accelerations(PLANAR_Q, PLANAR_V)
    solution = solve_flexible(model, PLANAR_Q, PLANAR_V, 0.0)
    assert np.max(np.abs(solution.qddot - expected)) < 1e-10 * np.max(np.abs(expected))
    forces = reference.joint_forces(PLANAR_Q, PLANAR_V)
    assert np.max(np.abs(solution.joint_force - forces)) < 1e-10 * np.max(np.abs(forces))
    pinned = PlanarModel.chain("p", [Pinned("o"), ModalBeam("b", length=1.3, bending_stiffness=5.0, mass_per_length=0.7,
                                                            n_modes=3, quadrature=16, rotary_inertia_per_length=0.01)])
    assert pinned.energy(PLANAR_Q, PLANAR_V) == pytest.approx(FlexibleLagrange(pinned).energy(PLANAR_Q, PLANAR_V),
                                                              rel=1e-12)      # (the reference's energy: no welds)
    plain = solve_flexible(planar_hub_beam(0.0), PLANAR_Q, PLANAR_V, 0.0).qddot
    assert np.max(np.abs(plain - expected)) > 1e-3 * np.max(np.abs(expected))


HUB_INERTIA = np.array([[0.12, 0.01, 0], [0.01, 0.1, 0.02], [0, 0.02, 0.15]])
TIP_INERTIA = np.array([[0.004, 0.0005, 0], [0.0005, 0.005, 0.0003], [0, 0.0003, 0.006]])


def rotation(axis, angle):
    a = np.asarray(axis, float)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


MOUNT = rotation((0, 1, 0), 0.2) @ rotation((1, 0, 0), 0.3)
SPATIAL_BEAM = dict(length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0, n_modes_y=2,
                    n_modes_z=2, n_torsion_modes=1, torsional_stiffness=3.0, polar_inertia_per_length=0.002)
AXES = ((0, 0, 1), (0, 1, 0))
SPATIAL_Q = np.r_[0.4, -0.3, 0.05, -0.02, 0.06, 0.01, 0.02]
SPATIAL_U = np.r_[5.0, -3.0, 0.8, -0.5, 1.1, 0.4, -0.6]


def spatial_hub_beam(rotary_y, rotary_z, second_order=False):
    beam = dict(SPATIAL_BEAM, rotary_inertia_per_length_y=rotary_y, rotary_inertia_per_length_z=rotary_z)
    model = sp.SpatialModel("s", [
        sp.SpatialBody("hub", mass=2.0, inertia=HUB_INERTIA, center_of_mass=(0.03, 0.01, 0.02),
                       points={"out": (0.2, 0, 0.05)}),
        sp.Universal(name="hubj", parent=None, child="hub", axis1=AXES[0], axis2=AXES[1]),
        sp.SpatialBeam("b", **beam, second_order_inertia=second_order, quadrature=12),
        sp.Weld(name="mount", parent="hub", child="b", point="out", rotation=MOUNT),
        sp.SpatialBody("tip", mass=0.3, inertia=TIP_INERTIA, center_of_mass=(0.03, 0.02, -0.01)),
        sp.Weld(name="m2", parent="b", child="tip", point="tip")], gravity=(0.5, 0.2, -9.81))
    lagrange = SpatialBeamLagrange(HubBeam(
        **beam, hub_mass=2.0, hub_inertia=HUB_INERTIA, hub_center=(0.03, 0.01, 0.02), axes=AXES, mount=(0.2, 0.0, 0.05),
        mount_rotation=MOUNT, tip_mass=0.3, tip_inertia=TIP_INERTIA, tip_center=(0.03, 0.02, -0.01),
        gravity=(0.5, 0.2, -9.81), points=12, second_order_inertia=second_order))
    return model, lagrange


def test_the_spatial_beam_with_rotary_inertia_equals_the_lagrange_model(second_order=False):
    """Universal hub turning about two axes (3-D frame motion), both bending planes and twist, a tip body: the
    accelerations equal the Lagrange model with the sections' turning (same order as the twist's) to 1e-10 of
    their size and the energy to 1e-12 -- the gyroscopic moment ``omega x (b_r eta_dot)`` included; without the term
    they differ by more than 1e-3."""
    model, lagrange = spatial_hub_beam(0.01, 0.02, second_order)
    expected = lagrange.accelerations(SPATIAL_Q, SPATIAL_U)
    got = accelerations(model, SPATIAL_Q, SPATIAL_U)
    assert np.abs(got - expected).max() <= 1e-10 * np.abs(expected).max()
    assert energy(model, SPATIAL_Q, SPATIAL_U) == pytest.approx(lagrange.energy(SPATIAL_Q, SPATIAL_U), rel=1e-12)
    plain, _ = spatial_hub_beam(0.0, 0.0, second_order)
    assert np.abs(accelerations(plain, SPATIAL_Q, SPATIAL_U) - expected).max() > 1e-3 * np.abs(expected).max()


def test_rotary_inertia_without_a_field_counterpart_or_negative_is_refused_by_name():
    with pytest.raises(ModelError, match="rotary_inertia_per_length must be >= 0"):
        ModalBeam("b", length=1.0, bending_stiffness=1.0, mass_per_length=1.0, n_modes=2, rotary_inertia_per_length=-1)
    with pytest.raises(ModelError, match="rotary_inertia_per_length_z must be >= 0"):
        sp.SpatialBeam("b", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=1.0,
                       rotary_inertia_per_length_z=-1e-3)
    with pytest.raises(ModelError, match="beam 'b' has section rotary inertia 0.002 kg m .*Euler-Bernoulli"):
        ctmm.natural_frequencies(planar_cantilever(2), n_modes=2, fields="exact")
    down = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    hanging = spatial_cantilever(2, gravity=(0.0, 0.0, -9.81), rotation=down)
    with pytest.raises(ModelError, match="beam 'b' has section rotary inertia .* in gravity"):
        ctmm.natural_frequencies(hanging, n_modes=2, fields="exact")


def test_generated_kernels_take_the_term_as_constants_and_refuse_it_as_parameters():
    """``compiled=True`` (numbers constants of the code) equals the numpy sweep to 1e-12; ``numbers="inputs"`` would
    scale the sections' terms with the beam's mass: refused by name."""
    pytest.importorskip("casadi")
    from ctmm.compiled_spatial import SpatialRates
    from ctmm.compiled_spatial_parameters import spatial_parameter_vector

    beam = sp.SpatialBeam("b", length=1.0, mass_per_length=0.5, bending_stiffness_y=2.0, bending_stiffness_z=3.0,
                          n_modes_y=1, n_modes_z=1, rotary_inertia_per_length_y=0.02, rotary_inertia_per_length_z=0.03)
    model = sp.SpatialModel("m", [beam, sp.Universal(name="w", parent=None, child="b", axis1=(0, 0, 1),
                                                     axis2=(0, 1, 0))], gravity=(0.0, 0.0, -9.81))
    q, v = np.array([0.3, 0.2, 0.01, -0.02]), np.array([2.0, -1.0, 0.5, 0.3])
    rates = SpatialRates(model)
    got = np.asarray(rates.velocity_rate(q, v, rates.input_vector({}), [], 0.0)).reshape(-1)
    expected = accelerations(model, q, v)
    assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max()
    rates = SpatialRates(model, numbers="inputs")
    with pytest.raises(ModelError, match="b: numbers='inputs' .* section rotary inertia"):
        rates.velocity_rate(q, v, rates.input_vector({}), spatial_parameter_vector(model), 0.0)
