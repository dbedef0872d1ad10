"""Exact spatial beam fields and spatial beam chains in the frequency domain (issue 15, items 3 and 5).

References are independent of the transfer-matrix code: ``scipy.linalg.expm`` of the ODE system
matrix, the analytic cantilever frequency equations (:mod:`ctmm.reference.spatial_beam_analytic`),
the 3-D finite-element model (:mod:`ctmm.reference.fe_beam3d`) and, for the planar restriction,
ctmm's planar exact-field form of a ``PlanarModel`` (:mod:`ctmm.exact_fields`).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from scipy.spatial.transform import Rotation

import ctmm
from ctmm.errors import ModelError
from ctmm.reference.fe_beam3d import FEBeam, FEBody, FEChain, FEGround, FEMarker, FESpring
from ctmm.reference.spatial_beam_analytic import cantilever_spectrum
from ctmm.spatial_beam_elements import (SpatialClamped, SpatialFree, SpatialGroundSpring, SpatialHinge, SpatialPinned,
                                        SpatialPointLoad, SpatialRigidBody, SpatialSpring, SpatialSupport)
from ctmm.spatial_beam_fields import SpatialBeamField
from ctmm.system import Chain

SECTION = dict(EA=1.4e7, GJ=250.0, EIy=120.0, EIz=480.0, rhoA=0.54, rhoIp=2.2e-5)


def beam(name, length, *, tension=0.0, loss_factor=0.0, rotation=None):
    s = SECTION
    return SpatialBeamField(name, length, axial_stiffness=s["EA"], torsional_stiffness=s["GJ"],
                            bending_stiffness_y=s["EIy"], bending_stiffness_z=s["EIz"], mass_per_length=s["rhoA"],
                            polar_inertia_per_length=s["rhoIp"], axial_force=tension, loss_factor=loss_factor,
                            rotation=rotation)


def fe_beam(length, elements, *, tension=0.0, loss_factor=0.0, rotation=None):
    return FEBeam(length, **SECTION, tension=tension, loss_factor=loss_factor, rotation=rotation, elements=elements)


TURN = Rotation.from_euler("zyx", [0.2, 0.0, 0.4]).as_matrix()
BODY_INERTIA = np.array([[2e-3, 1e-4, 0.0], [1e-4, 3e-3, 2e-4], [0.0, 2e-4, 1.5e-3]])
BODY = dict(center=(0.03, 0.01, -0.02), offset=(0.05, 0.0, 0.02))
SPRING = [1e5, 2e5, 3e5, 400.0, 500.0, 600.0]
SUPPORT = [0.0, 1e3, 0.0, 0.0, 0.0, 50.0]


def general_chain(loss_factor=0.0, damper=None):
    """Clamped/pinned chain: beam, body with offsets and full inertia, turned beam, 6-DOF spring, beam,
    ground spring (tensioned beams)."""
    return [beam("b1", 0.8, tension=30.0, loss_factor=loss_factor), SpatialPointLoad("mid"),
            SpatialRigidBody("body", 0.4, BODY_INERTIA, center_of_mass=BODY["center"], offset=BODY["offset"]),
            beam("b2", 0.5, tension=30.0, loss_factor=loss_factor, rotation=TURN),
            SpatialSpring("k", SPRING, damping=damper),
            beam("b3", 0.3, tension=30.0, loss_factor=loss_factor), SpatialGroundSpring("g", SUPPORT),
            SpatialPointLoad("tip_load")]


def general_fe(elements, loss_factor=0.0, damper=None, **ends):
    return FEChain([fe_beam(0.8, elements, tension=30.0, loss_factor=loss_factor), FEMarker("mid"),
                    FEBody(0.4, BODY_INERTIA, **BODY),
                    fe_beam(0.5, elements, tension=30.0, loss_factor=loss_factor, rotation=TURN),
                    FESpring(SPRING, damper), fe_beam(0.3, elements, tension=30.0, loss_factor=loss_factor),
                    FEGround(SUPPORT), FEMarker("tip_load")], **ends)


def bare_cantilever_spectrum(length, count):
    """All frequencies [rad/s] of a cantilever without tip body up to the lowest of the four families'
    ``count``-th (so none is missing), ascending: bending ``beta_k^2 / L^2 sqrt(EI / rhoA)``
    (``ctmm.reference.beams``), bar and shaft ``(2n - 1) pi / (2 L) sqrt(K / rho)``."""
    from ctmm.reference.beams import beta_roots

    s, n = SECTION, np.arange(1, count + 1)
    families = [beta_roots("clamped-free", count) ** 2 / length ** 2 * np.sqrt(stiffness / s["rhoA"])
                for stiffness in (s["EIy"], s["EIz"])]
    families += [(2 * n - 1) * np.pi / (2 * length) * np.sqrt(s[k] / s[rho]) for k, rho in (("EA", "rhoA"),
                                                                                          ("GJ", "rhoIp"))]
    merged = np.sort(np.concatenate(families))
    return merged[merged <= min(family.max() for family in families)]


# ----------------------------------------------------------------------------------------------
# the field matrix
@pytest.mark.parametrize("s", [3j, 300j, 0.5 + 40j, 2.0 - 1000j, 25000j])
def test_field_matrix_equals_expm_of_the_system_matrix(s):
    """Closed-form decoupled sub-fields (tension, all dampings, a turned beam) = expm(A L)."""
    field = SpatialBeamField("b", 1.3, axial_stiffness=2e6, torsional_stiffness=300.0, bending_stiffness_y=150.0,
                             bending_stiffness_z=400.0, mass_per_length=2.0, polar_inertia_per_length=0.01,
                             axial_force=120.0, loss_factor=0.02, kelvin_voigt_time=1e-4, viscous_damping=0.3,
                             torsional_damping=0.01, rotation=Rotation.from_euler("zyx", [0.3, -0.5, 1.1]).as_matrix())
    U = field.field_matrix(np.array([s]))[0]
    reference = scipy.linalg.expm(field.state_matrix(s) * field.length)
    scale = np.abs(reference).max(axis=1, keepdims=True) * np.abs(reference).max(axis=0, keepdims=True)
    assert np.max(np.abs(U - reference) / np.sqrt(scale)) < 1e-11


def test_field_matrix_is_symplectic_and_pieces_multiply_to_the_whole():
    """Reciprocity (U^T J U = J in the work-conjugate pairs) and U(L) = U(L/3)^3 (compression too)."""
    field = beam("b", 1.7, tension=-40.0, rotation=TURN)
    s = np.array([77j, 2300j])
    U = field.field_matrix(s).real
    J = np.block([[np.zeros((6, 6)), np.eye(6)], [-np.eye(6), np.zeros((6, 6))]])
    for Uk in U:
        lhs = Uk.T @ J @ Uk
        assert np.max(np.abs(lhs - J) / (np.abs(Uk).T @ np.abs(J) @ np.abs(Uk) + 1.0)) < 1e-12
    piece = field.split(3)[0].field_matrix(s)
    product = piece @ piece @ piece
    np.testing.assert_allclose(product, field.field_matrix(s), rtol=0, atol=1e-10 * np.abs(product).max())


# ----------------------------------------------------------------------------------------------
# natural frequencies against analytic references
def test_cantilever_with_a_tip_body_matches_the_analytic_frequency_equations():
    """Clamped-free beam with an inertial tip body (centre of mass on the axis beyond the tip, principal
    axes along the chain): all 31 frequencies below 2e4 rad/s of the four families to 1e-9."""
    inertia = (4e-4, 2e-3, 3e-3)
    chain = Chain("cantilever", [SpatialClamped("root"), beam("b", 1.2),
                                 SpatialRigidBody("tip_body", 0.35, inertia, center_of_mass=(0.04, 0.0, 0.0)),
                                 SpatialFree("tip")])
    omega = ctmm.natural_frequencies(chain, omega_max=2e4)
    reference = cantilever_spectrum(**SECTION, L=1.2, omega_max=2e4, mass=0.35, offset=0.04, inertia=inertia,
                                    n_grid=2000)
    assert omega.size == reference.size == 31
    np.testing.assert_allclose(omega, reference, rtol=1e-9)


def test_modes_beyond_60_of_a_long_chain_keep_round_off_accuracy():
    """Hard case for a plain transfer-matrix product: a 7 m cantilever of six fields joined at load
    points, 70 modes (bending beta L up to ~130, entries of the whole field ~1e56); the Riccati
    transfer and the Wittrick-Williams count keep every mode at 1e-9 against the analytic roots."""
    lengths = [0.7, 1.3, 0.4, 2.1, 0.9, 1.6]
    elements = [SpatialClamped("root")]
    for i, length in enumerate(lengths):
        elements += [beam(f"b{i}", length), SpatialPointLoad(f"p{i}")]
    chain = Chain("long", elements + [SpatialFree("tip")])
    omega = ctmm.natural_frequencies(chain, n_modes=70)
    reference = bare_cantilever_spectrum(sum(lengths), 79)[:70]
    assert reference.size == 70
    np.testing.assert_allclose(omega, reference, rtol=1e-9)
    whole = beam("whole", sum(lengths))
    assert np.abs(whole.field_matrix(1j * omega[-1:])).max() > 1e50     # a plain product keeps no digit
    with pytest.raises(ModelError, match=r"split the beam: \*whole.split\(\d+\)"):
        whole.transfer_matrix(1j * omega[-1:])            # nor would one Riccati step through it: refused
    counts = ctmm.eigenvalue_count(chain, np.concatenate([omega * (1 - 1e-7), omega * (1 + 1e-7)]))
    np.testing.assert_array_equal(counts, np.concatenate([np.arange(70), np.arange(1, 71)]))


def test_high_frequency_tip_receptances_of_a_split_long_cantilever_are_exact():
    """FRFs up to bending beta L ~ 100 (a 7 m cantilever cut into pieces_for(omega_max) pieces) equal
    the analytic tip receptances of both bending planes (Bishop & Johnson), of the bar and of the shaft:
    ``tan(kL) / (K k)``."""
    from ctmm.reference.beams import cantilever_tip_receptance

    length = 7.0
    whole = beam("b", length)
    omega = np.array([3.0, 41.0, 333.0, 1234.5, 2900.0])
    chain = Chain("long", [SpatialClamped("root"), *whole.split(whole.pieces_for(omega.max())),
                           SpatialPointLoad("t"), SpatialFree("tip")])
    names = ["t.fx", "t.fy", "t.fz", "t.mx"]
    outputs = ["t.ux", "t.uy", "t.uz", "t.theta_x"]
    response = ctmm.frequency_response(chain, omega, input=names, output=outputs).response
    s = SECTION
    k_axial, k_torsion = omega * np.sqrt(s["rhoA"] / s["EA"]), omega * np.sqrt(s["rhoIp"] / s["GJ"])
    expected = [np.tan(k_axial * length) / (s["EA"] * k_axial),
                cantilever_tip_receptance(omega, length, s["EIz"], s["rhoA"]),
                cantilever_tip_receptance(omega, length, s["EIy"], s["rhoA"]),
                np.tan(k_torsion * length) / (s["GJ"] * k_torsion)]
    for i in range(4):
        np.testing.assert_allclose(response[i, i].real, expected[i], rtol=1e-9)
        assert np.max(np.abs(response[i, i].imag)) == 0.0
    off_diagonal = response - np.einsum("ij,ik->ijk", np.eye(4), response[np.arange(4), np.arange(4)])
    assert np.max(np.abs(off_diagonal)) == 0.0           # the four families decouple


# ----------------------------------------------------------------------------------------------
# against the 3-D finite-element beam
@pytest.fixture(scope="module")
def general_frequencies():
    chain = Chain("general", [SpatialClamped("root"), *general_chain(), SpatialFree("tip")])
    return ctmm.natural_frequencies(chain, n_modes=15)


def test_general_chain_frequencies_are_the_limit_of_the_fe_beam_at_h4(general_frequencies):
    """Offsets, a full inertia tensor, a turned beam, 6-DOF springs, tension: the FE frequencies
    converge to the exact ones as h^4 (error / 16 per halving; bending-dominated modes)."""
    errors = []
    for elements in (4, 8, 16):
        fe = general_fe(elements).frequencies(15)
        errors.append(np.abs(fe - general_frequencies) / general_frequencies)
    ratio_1, ratio_2 = errors[0] / errors[1], errors[1] / errors[2]
    assert np.all(errors[0] > errors[1]) and np.all(errors[1] > errors[2])
    assert np.all((ratio_2[1:] > 12.0) & (ratio_2[1:] < 20.0)) and np.all((ratio_1 > 12.0) & (ratio_1 < 20.0))
    assert errors[2].max() < 4e-5


def test_compressed_clamped_pinned_chain_converges_to_the_fe_beam():
    """Compression at half the clamped-pinned buckling load of the weak plane, a point body between two
    fields, a spherical pin at the end: bending modes converge as h^4 (ratio ~16), the torsional /
    axial mode of linear FE elements as h^2 (ratio ~4)."""
    tension = -0.5 * 20.19 * SECTION["EIy"] / 1.5 ** 2
    inertia = (1e-4, 1e-4, 1e-4)
    chain = Chain("compressed", [SpatialClamped("root"), beam("b1", 0.6, tension=tension),
                                 SpatialRigidBody("m", 0.2, inertia), beam("b2", 0.9, tension=tension),
                                 SpatialPinned("pin")])
    omega = ctmm.natural_frequencies(chain, n_modes=10)
    errors = []
    for elements in (8, 16):
        fe = FEChain([fe_beam(0.6, elements, tension=tension), FEBody(0.2, inertia),
                      fe_beam(0.9, elements, tension=tension)], end_held=("ux", "uy", "uz"))
        errors.append(np.abs(fe.frequencies(10) - omega) / omega)
    ratio = errors[0] / errors[1]
    assert np.sum((ratio > 13.0) & (ratio < 17.0)) == 9 and np.sum((ratio > 3.5) & (ratio < 4.5)) == 1
    assert errors[1].max() < 1e-4


def test_count_is_exact_at_the_members_clamped_clamped_frequencies():
    """A cantilever of two equal halves, counted exactly at the halves' clamped-clamped bending, axial
    and torsional frequencies (a zero pivot and a singular field block at once): the analytic count."""
    from ctmm.elements.beams import clamped_clamped_beta

    chain = Chain("halves", [SpatialClamped("root"), beam("h1", 0.6), SpatialPointLoad("joint"), beam("h2", 0.6),
                             SpatialFree("tip")])
    s = SECTION
    trial = np.concatenate([clamped_clamped_beta(np.arange(1, 4)) ** 2 / 0.6 ** 2 * np.sqrt(s["EIy"] / s["rhoA"]),
                            np.arange(1, 3) * np.pi / 0.6 * np.sqrt(s["EA"] / s["rhoA"]),
                            np.arange(1, 3) * np.pi / 0.6 * np.sqrt(s["GJ"] / s["rhoIp"])])
    reference = bare_cantilever_spectrum(1.2, 40)
    assert reference[-1] > trial.max()
    np.testing.assert_array_equal(ctmm.eigenvalue_count(chain, trial), np.searchsorted(reference, trial))


def test_modes_30_to_36_of_a_chain_of_beams_and_bodies_converge_to_the_fe_chain():
    """Six tensioned fields and five bodies (offsets, centres of mass off the axis): modes 29-36 (up to
    3.7e3 rad/s) against the FE chain at 12 and 24 elements per field: the FE error falls 7-16x per
    halving (h^4 for bending, h^2 for the linear axial / torsional elements) to < 1.5e-5."""
    lengths = [0.5, 0.7, 0.4, 0.6, 0.55, 0.45]
    elements, parts = [SpatialClamped("root")], []
    for i, length in enumerate(lengths):
        elements.append(beam(f"b{i}", length, tension=20.0))
        parts.append(("beam", length))
        if i < len(lengths) - 1:
            body = (0.05 + 0.1 * i, np.diag([1e-4, 2e-4, 1.5e-4]), (0.01, 0.005 * (i % 2), -0.004),
                    (0.02, 0.0, 0.01 * (i % 3 == 0)))
            elements.append(SpatialRigidBody(f"m{i}", body[0], body[1], center_of_mass=body[2], offset=body[3]))
            parts.append(("body",) + body)
    omega = ctmm.natural_frequencies(Chain("bodies", elements + [SpatialFree("tip")]), n_modes=36)[28:]
    errors = []
    for n in (12, 24):
        fe = FEChain([fe_beam(p[1], n, tension=20.0) if p[0] == "beam" else FEBody(*p[1:]) for p in parts])
        errors.append(np.abs(fe.frequencies(36)[28:] - omega) / omega)
    ratio = errors[0] / errors[1]
    assert np.all(ratio > 6.0) and np.median(ratio) > 10.0 and errors[1].max() < 1.5e-5


def test_frequency_response_with_pinned_and_mixed_ends_matches_the_fe_beam():
    """Spherical pin at the root, a support holding uy and theta_x at the tip, loss factor and a
    damped spring: FRFs between named points and directions converge to the exact ones (h^4)."""
    damper = [1.0, 1.0, 1.0, 0.01, 0.01, 0.01]
    chain = Chain("forced", [SpatialPinned("root"), *general_chain(0.02, damper),
                             SpatialSupport("tip", ("uy", "theta_x"))])
    omega = np.array([5.0, 50.0, 120.0, 400.0, 900.0])
    response = ctmm.frequency_response(chain, omega, input=["tip_load.fz", "mid.my"],
                                       output=["mid.uy", "tip_load.uz", "tip_load.theta_z"]).response
    loads = [("tip_load", "uz"), ("mid", "theta_y")]
    outputs = [("mid", "uy"), ("tip_load", "uz"), ("tip_load", "theta_z")]
    errors = []
    for elements in (8, 16):
        fe = general_fe(elements, 0.02, damper, start_held=("ux", "uy", "uz"), end_held=("uy", "theta_x"))
        error = 0.0
        for i, load in enumerate(loads):
            for o, out in enumerate(outputs):
                h = fe.frf(omega, load, out)
                error = max(error, np.max(np.abs(h - response[o, i]) / np.abs(response[:, i]).max(axis=0)))
        errors.append(error)
    assert errors[1] < errors[0] / 10 and errors[1] < 2e-4


def test_mode_shapes_match_the_fe_modes(general_frequencies):
    """Shapes at named points and directions (both bending planes, twist) of the first five modes."""
    chain = Chain("general", [SpatialClamped("root"), *general_chain(), SpatialFree("tip")])
    modal = ctmm.mode_shapes(chain, n_modes=5)
    np.testing.assert_allclose(modal.natural_frequencies, general_frequencies[:5], rtol=1e-10)
    points = [("mid", "uy"), ("mid", "uz"), ("mid", "theta_x"), ("tip_load", "uy"), ("tip_load", "uz")]
    index = [next(k for k, name in enumerate(modal.point_names) if name.startswith(f"{p}|")) for p, _ in points]
    shapes = np.array([[modal.shapes[m, index[j], modal.components.index(c)] for j, (_, c) in enumerate(points)]
                       for m in range(5)])
    shapes = shapes / shapes[np.arange(5), np.argmax(np.abs(shapes), axis=1)][:, None]
    reference = general_fe(16).mode_displacements(5, points)
    np.testing.assert_allclose(shapes, reference, atol=2e-4)


# ----------------------------------------------------------------------------------------------
# the planar restriction
def test_planar_restriction_equals_ctmm_planar_exact_fields():
    """A planar chain (beam, elastic hinge, rigid body, elastic hinge, beam) as a PlanarModel through
    fields="exact" and as a spatial chain: every planar frequency is a spatial one (count jumps by
    exactly one across it) and agrees to 1e-10; the spatial chain adds the out-of-plane families."""
    from ctmm.flexible import ModalBeam
    from ctmm.planar import PlanarModel
    from ctmm.planar.elements import ElasticHinge, Fixed, FixedMounting, RigidBody

    planar = PlanarModel.chain("planar", [
        Fixed("g"), FixedMounting("m"), ModalBeam("b", length=0.8, bending_stiffness=480.0, mass_per_length=0.54,
                                                  n_modes=2),
        ElasticHinge("h", stiffness=300.0), RigidBody("body", mass=0.3, inertia=2e-3, center_of_mass=(0.05, 0.0),
                                                      outboard=(0.1, 0.0)),
        ElasticHinge("h2", stiffness=100.0), ModalBeam("b2", length=0.5, bending_stiffness=480.0, mass_per_length=0.54,
                                                       n_modes=2)], gravity=(0.0, 0.0))
    expected = ctmm.natural_frequencies(planar, n_modes=8, fields="exact")
    spatial = Chain("spatial", [SpatialClamped("root"), beam("b", 0.8), SpatialHinge("h", (0, 0, 1), 300.0),
                                SpatialRigidBody("body", 0.3, (1.0, 1.0, 2e-3), center_of_mass=(0.05, 0, 0),
                                                 offset=(0.1, 0, 0)),
                                SpatialHinge("h2", (0, 0, 1), 100.0), beam("b2", 0.5), SpatialFree("tip")])
    omega = ctmm.natural_frequencies(spatial, omega_max=1.01 * expected[-1])
    matched = np.array([omega[np.argmin(np.abs(omega - w))] for w in expected])
    np.testing.assert_allclose(matched, expected, rtol=1e-10)
    assert omega.size > expected.size
    below = ctmm.eigenvalue_count(spatial, expected * (1 - 1e-8))
    above = ctmm.eigenvalue_count(spatial, expected * (1 + 1e-8))
    np.testing.assert_array_equal(above - below, np.ones(expected.size, dtype=int))


# ----------------------------------------------------------------------------------------------
# refusals
def test_bad_input_and_unsupported_requests_are_refused():
    with pytest.raises(ModelError, match="bending_stiffness_y"):
        SpatialBeamField("b", 1.0, axial_stiffness=1.0, torsional_stiffness=1.0, bending_stiffness_y=-1.0,
                         bending_stiffness_z=1.0, mass_per_length=1.0, polar_inertia_per_length=1.0)
    with pytest.raises(ModelError, match="rotation"):
        beam("b", 1.0, rotation=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ModelError, match="positive definite"):
        SpatialSpring("k", [1.0, 1.0, 1.0, 1.0, 1.0, 0.0])
    with pytest.raises(ModelError, match="held"):
        SpatialSupport("s", ("ux", "spin"))
    with pytest.raises(ModelError, match="free hinge"):
        SpatialHinge("h", (0, 0, 1), 0.0)
    with pytest.raises(ModelError, match="inertia"):
        SpatialRigidBody("r", 1.0, [[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    damped = Chain("damped", [SpatialClamped("root"), beam("b", 1.0, loss_factor=0.01), SpatialFree("tip")])
    with pytest.raises(ModelError, match="conservative|undamped"):
        ctmm.natural_frequencies(damped, n_modes=1)
    with pytest.raises(ModelError, match="no time-domain form"):
        beam("b", 1.0).discretize(None)


@pytest.mark.parametrize("tilt", [1e-17, 1e-9, 0.3, 1.0, 2.5])
def test_a_tilted_cantilever_has_no_rigid_mode_and_its_analytic_frequencies(tilt):
    """A clamped-free field turned by any rotation has the frequencies of the straight one (the analytic
    cantilever spectrum), none at 0 rad/s: the static rigid-mode count of ctmm.natural equilibrates the
    rows and columns of its omega = 0 matrix (it once counted three rigid modes for a turned field)."""
    rotation = Rotation.from_rotvec(tilt * np.array([0.2, 1.0, 0.7])).as_matrix()
    chain = Chain("tilted", [SpatialClamped("g"), beam("b", 1.0, rotation=rotation), SpatialFree("f")])
    omega = ctmm.natural_frequencies(chain, n_modes=8)
    np.testing.assert_allclose(omega, bare_cantilever_spectrum(1.0, 8)[:8], rtol=1e-9)
