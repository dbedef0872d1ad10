"""Wagner term of torsion under tension and the section's rotary inertia in bending (Rayleigh beam) in the
exact spatial beam fields (issue 15).

References, none of them transfer matrices: the closed form of a uniform bar in torsion under constant
tension, ``omega_n = (2n - 1) pi / (2L) sqrt((GJ + T I_p / A) / rho I_p)`` (clamped-free); a finite-element
torsion bar written here (linear elements, the stiffness ``GJ + T(x) I_p / A`` of the linear tension of a
hanging beam integrated exactly, consistent mass, tip inertia; ``h^2`` convergence, Richardson); the closed
form of the simply supported Rayleigh beam under tension, ``EI k^4 + T k^2 = omega^2 (rho A + rho I k^2)``,
``k = n pi / L``; a Hermite finite-element Rayleigh cantilever written here (consistent rotary inertia
matrix); and the planar hanging-beam FE (``ctmm.reference.hanging_beam_fe``) for the count with preload.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
from scipy.spatial.transform import Rotation

import ctmm
from ctmm.elements.base import Element
from ctmm.errors import ModelError
from ctmm.reference.hanging_beam_fe import HangingBeam
from ctmm.spatial_beam_elements import SpatialClamped, SpatialFree, SpatialPointLoad, SpatialRigidBody, SpatialSupport
from ctmm.spatial_beam_fields import SPATIAL_BEAM, SpatialBeamField, SpatialVaryingTensionField
from ctmm.system import Chain

G = 9.81
SECTION = dict(axial_stiffness=1.4e6, torsional_stiffness=0.05, bending_stiffness_y=120.0, bending_stiffness_z=480.0,
               mass_per_length=2.0, polar_inertia_per_length=0.01)          # I_p / A = 0.005 m^2: a thin open section
RADIUS2 = SECTION["polar_inertia_per_length"] / SECTION["mass_per_length"]


def torsion_closed_form(length, stiffness, count):
    return np.array([(2 * n - 1) * np.pi / (2 * length) * np.sqrt(stiffness / SECTION["polar_inertia_per_length"])
                     for n in range(1, count + 1)])


def nearest(found, wanted):
    """Relative distance of every wanted frequency to the nearest one found."""
    return np.array([np.min(np.abs(found - w)) / w for w in wanted])


@pytest.mark.parametrize("tension", [40.0, -6.0])
def test_a_cantilever_twists_with_the_wagner_stiffness_gj_plus_t_ip_over_a(tension):
    L = 1.2
    beam = SpatialBeamField("b", L, axial_force=tension, wagner_term=True, **SECTION)
    chain = Chain("c", [SpatialClamped("root"), beam, SpatialFree("tip")])
    omega = ctmm.natural_frequencies(chain, omega_max=60.0)
    stiffness = SECTION["torsional_stiffness"] + tension * RADIUS2
    wanted = torsion_closed_form(L, stiffness, 4)
    assert np.max(nearest(omega, wanted)) < 1e-12                             # 2e-16 measured
    plain = Chain("c", [SpatialClamped("root"), SpatialBeamField("b", L, axial_force=tension, **SECTION),
                        SpatialFree("tip")])
    without = torsion_closed_form(L, SECTION["torsional_stiffness"], 4)
    assert np.max(nearest(ctmm.natural_frequencies(plain, omega_max=60.0), without)) < 1e-12
    between = 0.5 * (without[0] + wanted[0])                                  # the first twist moved past it
    difference = ctmm.eigenvalue_count(chain, [between])[0] - ctmm.eigenvalue_count(plain, [between])[0]
    assert difference == (-1 if tension > 0 else 1)
    # the count steps by one across each torsion frequency (no bending or axial root nearby)
    counts = ctmm.eigenvalue_count(chain, np.concatenate([wanted * (1 - 1e-9), wanted * (1 + 1e-9)]))
    np.testing.assert_array_equal(counts[4:] - counts[:4], 1)


def test_the_field_with_wagner_term_and_rotary_inertia_is_the_exponential_of_its_system_matrix():
    """``U = expm(A L)`` of ``state_matrix`` (a turned, damped beam; the closed-form torsion bar and the planes
    placed in the right rows), and symplectic undamped."""
    turn = Rotation.from_euler("zyx", [0.3, -0.2, 0.5]).as_matrix()
    beam = SpatialBeamField("b", 0.9, axial_force=25.0, wagner_term=True, loss_factor=0.02, kelvin_voigt_time=1e-4,
                            viscous_damping=0.3, torsional_damping=0.01, rotation=turn, **dict(RAYLEIGH, torsional_stiffness=3.0))
    for s in (3j, 2 + 40j, 200j, -150j):
        U, E = beam.field_matrix(np.array([s]))[0], scipy.linalg.expm(beam.state_matrix(s) * 0.9)
        assert np.abs(U - E).max() <= 1e-13 * np.abs(E).max()                # 1.3e-15 measured
    undamped = SpatialBeamField("u", 0.9, axial_force=25.0, wagner_term=True, rotation=turn, **RAYLEIGH)
    U = undamped.field_matrix(np.array([50j])).real[0]
    J = np.block([[np.zeros((6, 6)), np.eye(6)], [-np.eye(6), np.zeros((6, 6))]])
    assert np.abs(U.T @ J @ U - J).max() <= 1e-12 * np.abs(U).max() ** 2


def test_compression_beyond_the_torsional_buckling_load_is_refused_by_name():
    buckling = SECTION["torsional_stiffness"] / RADIUS2                      # T = -GJ A / I_p = -10 N
    with pytest.raises(ModelError, match=r"'?b'?: the compression 12 N with wagner_term .*\(torsional buckling\)"):
        SpatialBeamField("b", 1.0, axial_force=-1.2 * buckling, wagner_term=True, **SECTION)
    SpatialBeamField("b", 1.0, axial_force=-1.2 * buckling, **SECTION)      # Saint-Venant torsion alone: accepted
    with pytest.raises(ModelError, match=r"b: the compression .* wagner_term"):
        SpatialVaryingTensionField("b", 1.0, inboard_tension=5.0, outboard_tension=-1.2 * buckling, wagner_term=True,
                                   **SECTION)
    with pytest.raises(ModelError, match="wagner_term must be True or False"):
        SpatialBeamField("b", 1.0, wagner_term=1, **SECTION)
    with pytest.raises(ModelError, match="rotary_inertia_per_length_y"):
        SpatialBeamField("b", 1.0, rotary_inertia_per_length_y=-1e-3, **SECTION)


def torsion_fe(length, tip_mass, tip_inertia, elements, torsional_stiffness=SECTION["torsional_stiffness"]):
    """Hanging torsion bar: linear elements, ``K(x) = GJ + T(x) I_p / A`` with ``T(x) = g (M + rhoA (L - x))``
    (linear, so the element integral ``int K / h^2`` is exactly ``K(x_mid) / h``), consistent mass, the
    tip body's axial inertia on the last node, root clamped."""
    h, rho = length / elements, SECTION["polar_inertia_per_length"]
    K, M = np.zeros((elements + 1,) * 2), np.zeros((elements + 1,) * 2)
    for e in range(elements):
        middle = (e + 0.5) * h
        tension = G * (tip_mass + SECTION["mass_per_length"] * (length - middle))
        k = (torsional_stiffness + tension * RADIUS2) / h
        K[e:e + 2, e:e + 2] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
        M[e:e + 2, e:e + 2] += rho * h / 6 * np.array([[2.0, 1.0], [1.0, 2.0]])
    M[-1, -1] += tip_inertia
    return np.sqrt(scipy.linalg.eigh(K[1:, 1:], M[1:, 1:], eigvals_only=True))


def test_a_hanging_beam_twists_with_the_wagner_stiffness_of_its_varying_tension():
    L, tip_mass, tip_inertia = 1.2, 0.5, (4e-3, 2e-3, 3e-3)
    inboard, outboard = G * (tip_mass + SECTION["mass_per_length"] * L), G * tip_mass
    field = SpatialVaryingTensionField("arm", L, inboard_tension=inboard, outboard_tension=outboard, wagner_term=True,
                                       **SECTION)
    chain = Chain("hanging", [SpatialClamped("root"), field, SpatialRigidBody("tip", tip_mass, tip_inertia),
                              SpatialFree("end")])
    omega = ctmm.natural_frequencies(chain, omega_max=40.0)
    coarse, fine = torsion_fe(L, tip_mass, tip_inertia[0], 200)[:3], torsion_fe(L, tip_mass, tip_inertia[0], 400)[:3]
    reference = fine + (fine - coarse) / 3.0                                  # h^2: Richardson
    assert np.max(nearest(omega, reference)) < 1e-8                           # 1.3e-10 measured
    plain = SpatialVaryingTensionField("arm", L, inboard_tension=inboard, outboard_tension=outboard, **SECTION)
    plain_omega = ctmm.natural_frequencies(Chain("hanging", [SpatialClamped("root"), plain,
                                                             SpatialRigidBody("tip", tip_mass, tip_inertia),
                                                             SpatialFree("end")]), omega_max=5.0)
    assert nearest(plain_omega, reference[:1])[0] > 0.3                      # without the term: 40 % off
    # the Magnus torsion bar (theta_x, mx) against an ODE integration of its A(x, s), a damped s and a
    # Kelvin-Voigt field (GJ (1 + tau s) + T(x) I_p / A) included
    field = SpatialVaryingTensionField("arm", L, inboard_tension=inboard, outboard_tension=outboard, wagner_term=True,
                                       kelvin_voigt_time=0.02, **SECTION)
    s = np.array([25.0j, 3.0 + 12.0j])
    U = field.transfer_matrix(s)[:, [[3], [9]], [3, 9]]
    for k, sk in enumerate(s):
        def rate(x, z, sk=sk):
            return (field.state_matrix_at(sk, x)[np.ix_([3, 9], [3, 9])] @ z.reshape(2, 2)).ravel()
        solution = scipy.integrate.solve_ivp(rate, (0.0, L), np.eye(2, dtype=complex).ravel(), method="DOP853",
                                             rtol=1e-13, atol=1e-13)
        reference_U = solution.y[:, -1].reshape(2, 2)
        assert np.abs(U[k] - reference_U).max() <= 5e-11 * np.abs(reference_U).max()


RAYLEIGH = dict(SECTION, torsional_stiffness=250.0, polar_inertia_per_length=0.02,
                rotary_inertia_per_length_y=0.006, rotary_inertia_per_length_z=0.014)


def simply_supported(length, stiffness, rotary, tension, omega_max):
    k = np.arange(1, 400) * np.pi / length
    omega = np.sqrt((stiffness * k ** 4 + tension * k * k) / (RAYLEIGH["mass_per_length"] + rotary * k * k))
    return omega[omega < omega_max]


def test_a_simply_supported_rayleigh_beam_has_the_closed_form_frequencies_up_to_mode_sixty():
    L, T, top = 1.5, 300.0, 5500.0
    beam = SpatialBeamField("b", L, axial_force=T, **RAYLEIGH)
    chain = Chain("ss", [SpatialSupport("a", ("ux", "uy", "uz", "theta_x")), beam, SpatialSupport("b_end", ("uy", "uz"))])
    reference = np.concatenate([simply_supported(L, RAYLEIGH["bending_stiffness_y"], RAYLEIGH["rotary_inertia_per_length_y"],
                                                 T, top),
                                simply_supported(L, RAYLEIGH["bending_stiffness_z"], RAYLEIGH["rotary_inertia_per_length_z"],
                                                 T, top)])
    bars = [(2 * n - 1) * np.pi / (2 * L) * np.sqrt(stiffness / density) for n in range(1, 60)
            for stiffness, density in ((RAYLEIGH["axial_stiffness"], RAYLEIGH["mass_per_length"]),
                                       (RAYLEIGH["torsional_stiffness"], RAYLEIGH["polar_inertia_per_length"]))]
    reference = np.sort(np.concatenate([reference, [b for b in bars if b < top]]))
    assert len(reference) >= 60                      # 20 + 15 bending modes of the two planes, axial and twist
    between = np.concatenate([[0.5 * reference[0]], 0.5 * (reference[1:] + reference[:-1]), [top]])
    np.testing.assert_array_equal(ctmm.eigenvalue_count(chain, between), np.arange(len(between)))
    omega = ctmm.natural_frequencies(chain, omega_max=top)
    np.testing.assert_allclose(omega, reference, rtol=1e-12)                 # 5e-15 measured
    euler_bernoulli = np.sqrt(RAYLEIGH["bending_stiffness_y"] * (20 * np.pi / L) ** 4 / RAYLEIGH["mass_per_length"])
    assert euler_bernoulli > 1.5 * simply_supported(L, RAYLEIGH["bending_stiffness_y"],
                                                    RAYLEIGH["rotary_inertia_per_length_y"], 0.0, np.inf)[19]


def rayleigh_cantilever_fe(length, stiffness, rotary, tension, elements, count, omega=None):
    """Hermite cubic elements: bending, consistent mass, the consistent rotary inertia ``rho I / (30 h) [..]`` and
    geometric stiffness ``T / (30 h) [..]`` (the same matrix of the slopes), clamped root, free tip."""
    h, rho = length / elements, RAYLEIGH["mass_per_length"]
    k = stiffness / h ** 3 * np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                                       [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
    m = rho * h / 420 * np.array([[156, 22 * h, 54, -13 * h], [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                                  [54, 13 * h, 156, -22 * h], [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
    slopes = np.array([[36, 3 * h, -36, 3 * h], [3 * h, 4 * h * h, -3 * h, -h * h],
                       [-36, -3 * h, 36, -3 * h], [3 * h, -h * h, -3 * h, 4 * h * h]]) / (30 * h)
    n = 2 * (elements + 1)
    K, M = np.zeros((n, n)), np.zeros((n, n))
    for e in range(elements):
        dofs = slice(2 * e, 2 * e + 4)
        K[dofs, dofs] += k + tension * slopes
        M[dofs, dofs] += m + rotary * slopes
    if omega is not None:                                                     # tip receptance [m/N]
        force = np.zeros(n - 2)
        force[-2] = 1.0
        return np.array([np.linalg.solve(K[2:, 2:] - w * w * M[2:, 2:], force)[-2] for w in omega])
    return np.sqrt(scipy.linalg.eigh(K[2:, 2:], M[2:, 2:], eigvals_only=True)[:count])


def test_a_rayleigh_cantilever_under_tension_equals_the_finite_element_beam():
    L, T = 1.1, 150.0
    beam = SpatialBeamField("b", L, axial_force=T, **RAYLEIGH)
    omega = ctmm.natural_frequencies(Chain("c", [SpatialClamped("root"), beam, SpatialFree("tip")]), omega_max=900.0)
    for stiffness, rotary in ((RAYLEIGH["bending_stiffness_y"], RAYLEIGH["rotary_inertia_per_length_y"]),
                              (RAYLEIGH["bending_stiffness_z"], RAYLEIGH["rotary_inertia_per_length_z"])):
        coarse = rayleigh_cantilever_fe(L, stiffness, rotary, T, 40, 4)
        fine = rayleigh_cantilever_fe(L, stiffness, rotary, T, 80, 4)
        reference = fine + (fine - coarse) / 15.0                             # h^4: Richardson
        reference = reference[reference < 900.0]
        assert len(reference) >= 3
        assert np.max(nearest(omega, reference)) < 1e-8                       # 1e-10 measured
        euler = rayleigh_cantilever_fe(L, stiffness, 0.0, T, 80, 4)[:len(reference)]
        assert np.min(nearest(omega, euler)) > 1e-3                          # rotary inertia lowers them
    # tip receptance of the x-y plane (uy per fy; EI_z, rho I_z) between and above its resonances
    chain = Chain("c", [SpatialClamped("root"), *beam.split(beam.pieces_for(800.0)), SpatialPointLoad("tip_load"),
                        SpatialFree("tip")])
    w = np.array([30.0, 250.0, 800.0])
    frf = ctmm.frequency_response(chain, w, input="tip_load.fy", output="tip_load.uy")
    coarse, fine = (rayleigh_cantilever_fe(L, RAYLEIGH["bending_stiffness_z"], RAYLEIGH["rotary_inertia_per_length_z"], T,
                                           n, 0, omega=w) for n in (40, 80))
    np.testing.assert_allclose(frf("tip_load.uy", "tip_load.fy"), fine + (fine - coarse) / 15.0, rtol=1e-7)


def test_the_count_of_a_hanging_spatial_beam_equals_the_finite_element_count_at_several_omega():
    """Counting with preload: the exact chain of a beam hanging in gravity with a tip body (varying tension in both
    bending planes, the Wagner term in torsion) counts exactly the modes of the independent references below
    each omega: the two planes' FE (``ctmm.reference.hanging_beam_fe``), the axial bar's and the FE torsion bar's."""
    L, tip_mass, tip_inertia = 1.2, 0.5, (4e-3, 2e-3, 3e-3)
    inboard, outboard = G * (tip_mass + SECTION["mass_per_length"] * L), G * tip_mass
    section = dict(SECTION, torsional_stiffness=0.5)
    chain = Chain("hanging", [SpatialClamped("root"),
                              SpatialVaryingTensionField("arm", L, inboard_tension=inboard, outboard_tension=outboard,
                                                         wagner_term=True, **section),
                              SpatialRigidBody("tip", tip_mass, tip_inertia), SpatialFree("end")])
    top = 300.0
    reference = []
    for stiffness, inertia in ((SECTION["bending_stiffness_z"], tip_inertia[2]),
                               (SECTION["bending_stiffness_y"], tip_inertia[1])):
        plane = HangingBeam(L, stiffness, SECTION["mass_per_length"], G, tip_mass, inertia)
        coarse, fine = plane.natural_frequencies(16, 12), plane.natural_frequencies(32, 12)
        reference += list(fine + (fine - coarse) / 15.0)
    torsion = torsion_fe(L, tip_mass, tip_inertia[0], 800, section["torsional_stiffness"])
    reference += list(torsion[torsion < top])
    axial_k = np.sqrt(SECTION["mass_per_length"] / SECTION["axial_stiffness"])      # tip mass: K k cos kL = M w^2 sin kL
    grid = np.linspace(1.0, top, 20001)
    values = SECTION["axial_stiffness"] * axial_k * np.cos(axial_k * grid * L) - tip_mass * grid * np.sin(axial_k * grid * L)
    reference += list(grid[:-1][np.sign(values[:-1]) != np.sign(values[1:])])
    reference = np.sort(reference)
    reference = reference[reference < top]
    assert len(reference) >= 15
    gaps = np.flatnonzero(np.diff(reference) > 2e-3 * reference[1:])          # omegas well between two modes
    omega = 0.5 * (reference[gaps] + reference[gaps + 1])
    np.testing.assert_array_equal(ctmm.eigenvalue_count(chain, omega), gaps + 1)


class ArmOffThePreload(Element):
    """A static force ``f0`` on an arm ``r`` of a rigid body turned by ``theta``: ``(theta x r) x f0`` in world-axes
    rotations, ``m_out = m_in - (r f0^T - (r . f0) I) theta`` -- not symmetric unless ``r`` is along ``f0``."""

    layout = SPATIAL_BEAM
    is_point = True

    def __init__(self, name, arm, force):
        super().__init__(name)
        self.matrix = np.outer(arm, force) - np.dot(arm, force) * np.eye(3)

    def parameters(self):
        return {}

    def transfer_matrix(self, s):
        s = np.asarray(s, dtype=complex)
        U = np.broadcast_to(np.eye(12, dtype=complex), s.shape + (12, 12)).copy()
        U[..., 9:12, 3:6] = -self.matrix
        return U


def test_a_preload_moment_off_the_arm_line_is_refused_by_the_count_and_along_it_is_counted():
    beam = SpatialBeamField("b", 1.0, axial_force=20.0, **dict(SECTION, torsional_stiffness=0.5))
    body = SpatialRigidBody("tip", 0.5, (4e-3, 2e-3, 3e-3))
    along = Chain("along", [SpatialClamped("root"), beam, body, ArmOffThePreload("arm", (0.3, 0, 0), (4.9, 0, 0)),
                            SpatialFree("end")])
    assert ctmm.eigenvalue_count(along, [50.0])[0] > 0                       # symmetric: counted
    off = Chain("off", [SpatialClamped("root"), beam, body, ArmOffThePreload("arm", (0.3, 0.1, 0), (4.9, 0, 0)),
                        SpatialFree("end")])
    with pytest.raises(ModelError, match=r"reciprocal \(symplectic\).*'arm'"):
        ctmm.eigenvalue_count(off, [50.0])
    with pytest.raises(ModelError, match=r"reciprocal \(symplectic\).*'arm'"):
        ctmm.natural_frequencies(off, n_modes=3)


DOWN = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])      # beam x along world -z


def hanging_model(twist_modes, wagner_term=True):
    import ctmm.spatial as sp

    return sp.SpatialModel("hanging", [
        sp.SpatialBeam("arm", length=1.2, mass_per_length=SECTION["mass_per_length"],
                       bending_stiffness_y=SECTION["bending_stiffness_y"], bending_stiffness_z=SECTION["bending_stiffness_z"],
                       torsional_stiffness=SECTION["torsional_stiffness"],
                       polar_inertia_per_length=SECTION["polar_inertia_per_length"], n_modes_y=1, n_modes_z=1,
                       n_torsion_modes=twist_modes, static_shapes=True, wagner_term=wagner_term),
        sp.Weld(name="root", parent=None, child="arm", rotation=DOWN),
        sp.SpatialBody("tip", 0.5, np.diag([4e-3, 2e-3, 3e-3])),
        sp.Weld(name="grip", parent="arm", child="tip", point="tip")], gravity=(0.0, 0.0, -G))


def test_the_modal_beam_hanging_with_the_wagner_term_converges_from_above_to_the_exact_field_and_the_fe():
    """The modal beam's twist stiffened by its gravity tension (global linearisation about the hanging equilibrium)
    and its exact-field form (``fields="exact"`` passes the term on) against the FE torsion bar."""
    from ctmm.compiled_spatial_beam_numbers import beam_numbers

    coarse, fine = torsion_fe(1.2, 0.5, 4e-3, 200)[:2], torsion_fe(1.2, 0.5, 4e-3, 400)[:2]
    reference = fine + (fine - coarse) / 3.0
    exact = ctmm.natural_frequencies(hanging_model(2), omega_max=15.0, fields="exact")
    assert np.max(nearest(exact, reference)) < 1e-8                          # 4e-11 measured
    errors = []
    for modes in (1, 2, 4):
        omega = ctmm.natural_frequencies(hanging_model(modes), n_modes=3)
        twist = np.array([omega[np.argmin(np.abs(omega - r))] for r in reference])
        errors.append(twist / reference - 1)
    errors = np.array(errors)
    assert np.all(errors > 0) and np.all(np.diff(errors, axis=0) < 0)        # from above, monotonically
    assert np.max(errors[-1]) < 5e-4                                          # 1.5e-5, 2.2e-4 measured
    plain = ctmm.natural_frequencies(hanging_model(2, wagner_term=False), n_modes=1)
    assert plain[0] < 0.7 * reference[0]                                      # the term: 2.22 -> 3.72 rad/s
    numbers = [attribute for attribute, _, _ in beam_numbers(hanging_model(2).bodies[0])]
    assert "mass_per_length" not in numbers and "polar_inertia_per_length" not in numbers   # not linear in them
    assert "mass_per_length" in [a for a, _, _ in beam_numbers(hanging_model(2, wagner_term=False).bodies[0])]
    import ctmm.spatial as sp
    with pytest.raises(ModelError, match="wagner_term=True needs geometric_stiffening=True"):
        sp.SpatialBeam("arm", length=1.0, mass_per_length=1.0, bending_stiffness_y=1.0, bending_stiffness_z=1.0,
                       geometric_stiffening=False, wagner_term=True)
