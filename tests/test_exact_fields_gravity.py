"""Exact fields of straight planar chains hanging or standing in gravity (issue 14).

References, none of them transfer matrices: an ODE integration of the varying-tension field
(scipy DOP853), a Hermite finite-element model with the consistent geometric stiffness of the
linear tension (ctmm/reference/hanging_beam_fe.py, Richardson-extrapolated over two meshes), the
heavy hanging string (zeros of J0), and a Lagrange linearisation of a rigid double pendulum
written here.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
from scipy.special import jn_zeros

import ctmm
from ctmm.elements.beams import BeamField
from ctmm.elements.bending_preload import GeometricMoment, VaryingTensionBeamField
from ctmm.errors import ModelError
from ctmm.reference.hanging_beam_fe import HangingBeam

G = 9.81
L, EI, RHOA, TIP, TIP_J = 1.2, 3.0, 0.4, 0.5, 0.002


def beam_with_tip(gravity, *, bending_stiffness=EI, root_stiffness=None):
    from ctmm.flexible import ModalBeam
    from ctmm.planar import ElasticHinge, Fixed, PlanarModel, RigidBody
    from ctmm.planar.elements import FixedMounting

    root = FixedMounting("root") if root_stiffness is None else ElasticHinge("root", stiffness=root_stiffness)
    beam = ModalBeam("b", length=L, bending_stiffness=bending_stiffness, mass_per_length=RHOA, n_modes=2)
    return PlanarModel.chain("hanging", [Fixed("g"), root, beam, FixedMounting("weld"),
                                         RigidBody("tip", mass=TIP, inertia=TIP_J)],
                              gravity=gravity if isinstance(gravity, tuple) else (gravity, 0.0))


def fe_extrapolated(values16, values32):
    """Richardson (h^4) value of two meshes and the FE model's convergence bound."""
    return values32 + (values32 - values16) / 15.0, np.abs(values32 - values16) / 15.0


def test_varying_tension_field_equals_the_constant_field_and_an_ode_integration():
    s = 1j * np.array([0.5, 40.0, 200.0])
    constant = VaryingTensionBeamField("c", 1.3, 15.0, 0.8, inboard_tension=7.0, outboard_tension=7.0)
    exact = BeamField("e", 1.3, 15.0, 0.8, axial_force=7.0).transfer_matrix(s)
    np.testing.assert_allclose(constant.transfer_matrix(s), exact, rtol=0, atol=1e-12 * np.abs(exact).max())
    field = VaryingTensionBeamField("v", 1.3, 15.0, 0.8, inboard_tension=30.0, outboard_tension=-5.0)
    U = field.transfer_matrix(s)
    J = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.eye(2), np.zeros((2, 2))]])
    for k, sk in enumerate(s):
        def rhs(x, z, sk=sk):
            A = np.array([[0, 1, 0, 0], [0, 0, 0, -1 / 15.0], [-0.8 * sk * sk, 0, 0, 0],
                          [0, -(30.0 - 35.0 * x / 1.3), -1, 0]])
            return (A @ z.reshape(4, 4)).ravel()
        solution = scipy.integrate.solve_ivp(rhs, (0.0, 1.3), np.eye(4, dtype=complex).ravel(), method="DOP853",
                                             rtol=1e-13, atol=1e-13)
        reference = solution.y[:, -1].reshape(4, 4)
        np.testing.assert_allclose(U[k], reference, rtol=0, atol=5e-11 * np.abs(reference).max())
        real = U[k].real
        assert np.abs(real.T @ J @ real - J).max() < 1e-12 * np.abs(real).max() ** 2       # reciprocal
    with pytest.raises(ModelError, match="split the field"):
        VaryingTensionBeamField("long", 10.0, 1.0, 1.0, inboard_tension=100.0,
                                outboard_tension=0.0).transfer_matrix(1j * 1e4)
    with pytest.raises(ModelError, match="stiffness"):
        GeometricMoment("g", float("nan"))


def test_hanging_and_standing_beam_with_tip_mass_equal_the_finite_element_model():
    hanging = ctmm.natural_frequencies(beam_with_tip(G), n_modes=4, fields="exact")
    reference = HangingBeam(L, EI, RHOA, G, TIP, TIP_J)
    value, bound = fe_extrapolated(reference.natural_frequencies(16, 4), reference.natural_frequencies(32, 4))
    assert np.all(np.abs(hanging - value) <= 0.1 * bound + 3e-9 * value)
    # standing on a root spring (compression), stable
    standing = ctmm.natural_frequencies(beam_with_tip(-G, bending_stiffness=30.0, root_stiffness=40.0), n_modes=4,
                                        fields="exact", operating_point={"q": np.zeros(3)})
    reference = HangingBeam(L, 30.0, RHOA, -G, TIP, TIP_J, root="pinned", root_stiffness=40.0)
    value, bound = fe_extrapolated(reference.natural_frequencies(16, 4), reference.natural_frequencies(32, 4))
    assert np.all(np.abs(standing - value) <= 0.1 * bound + 3e-9 * value)
    # the trend: tension stiffens, compression softens (every mode)
    weightless = ctmm.natural_frequencies(beam_with_tip(0.0), n_modes=4, fields="exact")
    assert np.all(hanging > weightless * (1 + 1e-4))
    upright = ctmm.natural_frequencies(beam_with_tip(0.0, bending_stiffness=30.0, root_stiffness=40.0), n_modes=4,
                                      fields="exact")
    assert np.all(standing < upright * (1 - 1e-5))
    with pytest.raises(ModelError, match="statically unstable"):        # the slender beam buckles standing
        ctmm.natural_frequencies(beam_with_tip(-G), n_modes=1, fields="exact", operating_point={"q": np.zeros(2)})


def test_hanging_beam_tip_receptance_equals_the_finite_element_model():
    omega = np.array([0.7, 3.0, 20.0, 60.0])
    exact = ctmm.frequency_response(beam_with_tip(G), omega, input="tip.force_y", output="tip.com.y",
                                    fields="exact")("tip.com.y", "tip.force_y")
    reference = HangingBeam(L, EI, RHOA, G, TIP, TIP_J)
    value, bound = fe_extrapolated(reference.tip_receptance(16, omega), reference.tip_receptance(32, omega))
    assert np.all(np.abs(exact - value) <= 0.1 * bound + 1e-8 * np.abs(value))


def test_a_standing_field_answers_every_input_in_one_sweep_as_one_solve_each():
    """The varying-tension field (standing: compression) and the root spring in the one sweep for all inputs
    (``chain_assembly.solve_load_cases``, the exact-field open loop): equal to one ``solve`` per input bit for bit."""
    from ctmm.chain_assembly import solve, solve_load_cases
    from ctmm.exact_fields import exact_form

    chain = exact_form(beam_with_tip(-G, bending_stiffness=30.0, root_stiffness=40.0), {"q": np.zeros(3)}).chain
    assert any(isinstance(element, VaryingTensionBeamField) for element in chain.body)
    s = 1j * np.array([0.7, 20.0, 300.0, 5000.0])
    cases = [{entry.position: {entry.input: 1.0}} for entry in map(chain.input, chain.input_names())]
    assert np.array_equal(solve_load_cases(chain, s, cases), np.stack([solve(chain, s, case).states for case in cases]))


def test_the_count_of_the_hanging_beam_is_certified_between_the_reference_frequencies():
    from ctmm.exact_fields import exact_form

    chain = exact_form(beam_with_tip(G)).chain
    reference = HangingBeam(L, EI, RHOA, G, TIP, TIP_J).natural_frequencies(32, 4)
    between = np.r_[0.5 * reference[0], 0.5 * (reference[:-1] + reference[1:])]
    np.testing.assert_array_equal(ctmm.eigenvalue_count(chain, between), [0, 1, 2, 3])


def test_a_heavy_hanging_beam_tends_to_the_hanging_string():
    from ctmm.flexible import ModalBeam
    from ctmm.planar import Fixed, PlanarModel, SmoothHinge

    length, rho = 1.0, 0.5
    string = jn_zeros(0, 2) / 2 * np.sqrt(G / length)         # omega_n = (j_0n / 2) sqrt(g / L)
    errors = []
    for ratio in (3e-2, 1e-2):                                 # sqrt(EI / (rhoA g L^3))
        beam = ModalBeam("b", length=length, bending_stiffness=ratio ** 2 * rho * G * length ** 3,
                         mass_per_length=rho, n_modes=1)
        model = PlanarModel.chain("chain", [Fixed("g"), SmoothHinge("top"), beam], gravity=(G, 0.0))
        errors.append(ctmm.natural_frequencies(model, n_modes=2, fields="exact") / string - 1)
    assert np.all(errors[1] > 0) and np.all(errors[1] < errors[0] / 5)      # stiffer than the string, converging
    assert errors[1][0] < 1e-4 and errors[1][1] < 6e-3


def test_a_hanging_or_standing_rigid_double_pendulum_equals_its_lagrange_linearisation():
    from ctmm.planar import ElasticHinge, Fixed, PlanarModel, RigidBody

    m1, J1, c1, l1, m2, J2, c2, k, k0 = 1.0, 0.1, 0.5, 1.0, 0.7, 0.05, 0.3, 20.0, 30.0
    straight = {"q": np.zeros(2)}            # standing: the default equilibrium search starts hanging
    for g in (G, -G):
        model = PlanarModel.chain("pendulum", [
            Fixed("g"), ElasticHinge("p", stiffness=k0),
            RigidBody("a", mass=m1, inertia=J1, center_of_mass=(c1, 0.0), outboard=(l1, 0.0)),
            ElasticHinge("q", stiffness=k), RigidBody("b", mass=m2, inertia=J2, center_of_mass=(c2, 0.0))],
            gravity=(g, 0.0))
        # absolute angles phi1, phi2: y_c1 = c1 phi1, y_c2 = l1 phi1 + c2 phi2; the axial drop is quadratic
        M = np.array([[J1 + m1 * c1 ** 2 + m2 * l1 ** 2, m2 * l1 * c2], [m2 * l1 * c2, J2 + m2 * c2 ** 2]])
        K = np.array([[g * (m1 * c1 + m2 * l1) + k0 + k, -k], [-k, g * m2 * c2 + k]])
        reference = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True))
        exact = ctmm.natural_frequencies(model, n_modes=2, fields="exact", operating_point=straight)
        np.testing.assert_allclose(exact, reference, rtol=1e-10)
        response = ctmm.frequency_response(model, [1.5], input="q.torque", output="b.theta", fields="exact",
                                           operating_point=straight)
        phasor = np.linalg.solve(K - 1.5 ** 2 * M, np.array([-1.0, 1.0]))[1]
        np.testing.assert_allclose(response("b.theta", "q.torque")[0], phasor, rtol=1e-10)


def test_gravity_across_the_chain_is_refused_by_name():
    with pytest.raises(ModelError, match=r"component 0\.5 m/s\^2 transverse.*hanging or standing"):
        ctmm.natural_frequencies(beam_with_tip((G, 0.5)), n_modes=1, fields="exact")
    from ctmm.flexible import ModalBeam
    from ctmm.planar import Fixed, PlanarModel
    from ctmm.planar.elements import FixedMounting

    extensible = ModalBeam("b", length=L, bending_stiffness=EI, mass_per_length=RHOA, n_modes=1, n_axial_modes=1,
                           axial_stiffness=4000.0)
    stretched = PlanarModel.chain("stretched", [Fixed("g"), FixedMounting("c"), extensible], gravity=(G, 0.0))
    with pytest.raises(ModelError, match="stretches under gravity"):
        ctmm.natural_frequencies(stretched, n_modes=1, fields="exact")
