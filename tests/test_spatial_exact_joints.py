"""Roots and joints of the exact-field bridge other than welds and revolutes (issue 15, ``fields="exact"``,
ctmm/spatial_exact_joints.py):

* beams on spherical (pinned), universal, prismatic (sliding) and free ground joints: every frequency below
  a bound equals the analytic Euler-Bernoulli, torsion and rod frequencies of their end conditions (roots
  of the frequency equations in ctmm/reference/beams.py), the rigid-body modes counted; pinned-pinned on
  the fields directly (two supports need a closed loop, which spatial models do not have);
* elastic roots (a spherical joint with a full 3 x 3 spring, an elastic6 joint) and an elastic6 joint
  between a beam and a body against the converged finite-element reference (ctmm/reference/fe_beam3d.py,
  Richardson-extrapolated in the mesh);
* universal (oblique axes) and spherical springs between rigid bodies against the 2- and 3-DOF
  eigenproblems written by hand;
* the ports of a spherical root (torque, rates) against the finite-element frequency response;
* refusals by name.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import block_diag, eigh
from scipy.spatial.transform import Rotation

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.reference.beams import beta_roots
from ctmm.reference.fe_beam3d import FEBeam, FEBody, FEChain, FEGround, FEMarker, FESpring
from ctmm.spatial_beam_elements import SpatialPinned
from ctmm.spatial_beam_fields import SpatialBeamField

ARM = dict(length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0,
           torsional_stiffness=3.0, polar_inertia_per_length=0.002, axial_stiffness=400.0)
L, RHO_A = ARM["length"], ARM["mass_per_length"]
MODES = dict(n_modes_y=1, n_modes_z=1, n_torsion_modes=1, n_axial_modes=1)
TURN = Rotation.from_euler("zyx", [25, -15, 40], degrees=True).as_matrix()


def arm(**changes) -> sp.SpatialBeam:
    return sp.SpatialBeam("arm", **dict(ARM, **MODES, **changes))


def bending(case: str, stiffness: float, count: int = 4) -> list:
    return list(beta_roots(case, count) ** 2 * math.sqrt(stiffness / (RHO_A * L ** 4)))


def rod(ends: str, stiffness: float, inertia: float, count: int = 4) -> list:
    """Axial or torsional frequencies: ``(2k - 1) pi / 2L c`` (held-free), ``k pi / L c`` (free-free)."""
    c = math.sqrt(stiffness / inertia)
    return [((2 * k - 1) / 2 if ends == "held-free" else k) * math.pi / L * c for k in range(1, count + 1)]


TORSION, AXIAL = (ARM["torsional_stiffness"], ARM["polar_inertia_per_length"]), (ARM["axial_stiffness"], RHO_A)
#: ground joint -> (rigid modes, analytic frequencies: x-y plane (EI of w_y), x-z plane, torsion, axial)
GROUND = {
    "spherical": (lambda: sp.Spherical(name="root", parent=None, child="arm"), 3,
                  bending("pinned-free", 6.0) + bending("pinned-free", 9.0) + rod("free-free", *TORSION)
                  + rod("held-free", *AXIAL)),
    "universal": (lambda: sp.Universal(name="root", parent=None, child="arm", axis1=(0, 1, 0), axis2=(0, 0, 1)), 2,
                  bending("pinned-free", 6.0) + bending("pinned-free", 9.0) + rod("held-free", *TORSION)
                  + rod("held-free", *AXIAL)),
    "prismatic": (lambda: sp.Prismatic(name="root", parent=None, child="arm", axis=(0, 1, 0)), 1,
                  bending("sliding-free", 6.0) + bending("clamped-free", 9.0) + rod("held-free", *TORSION)
                  + rod("held-free", *AXIAL)),
    "free": (lambda: sp.Free(name="root", parent=None, child="arm"), 6,
             bending("free-free", 6.0) + bending("free-free", 9.0) + rod("free-free", *TORSION)
             + rod("free-free", *AXIAL)),
}


@pytest.mark.parametrize("kind", list(GROUND))
def test_beams_on_ground_joints_have_the_analytic_frequencies_of_their_end_conditions(kind):
    joint, rigid, analytic = GROUND[kind]
    model = sp.SpatialModel("m", [arm(), joint()], gravity=(0.0, 0.0, 0.0))
    omega = ctmm.natural_frequencies(model, omega_max=167.0, fields="exact")
    expected = np.sort([w for w in analytic if w < 167.0])
    assert np.count_nonzero(omega == 0.0) == rigid
    np.testing.assert_allclose(omega[rigid:], expected, rtol=1e-9)
    assert len(expected) >= 7


def test_a_pinned_pinned_field_chain_has_the_analytic_frequencies():
    """Two-point supports need a closed loop in a spatial model (not expressible there): the fields between
    two spherical pins directly -- pinned-pinned bending, free-free torsion (one rigid spin), held-held axial."""
    field = SpatialBeamField("beam", L, bending_stiffness_z=6.0, bending_stiffness_y=9.0, mass_per_length=RHO_A,
                             axial_stiffness=ARM["axial_stiffness"], torsional_stiffness=ARM["torsional_stiffness"],
                             polar_inertia_per_length=ARM["polar_inertia_per_length"])
    omega = ctmm.natural_frequencies(ctmm.Chain("pp", [SpatialPinned("a"), field, SpatialPinned("b")]),
                                     omega_max=167.0)
    analytic = bending("pinned-pinned", 6.0) + bending("pinned-pinned", 9.0) + rod("free-free", *TORSION) \
        + rod("free-free", *AXIAL)                                    # held-held axial: k pi / L c as well
    expected = np.sort([w for w in analytic if w < 167.0])
    assert np.count_nonzero(omega == 0.0) == 1
    np.testing.assert_allclose(omega[1:], expected, rtol=1e-9)


def _fe_frequencies(parts, start_held, count: int) -> np.ndarray:
    """The finite-element reference at 32 and 64 elements per beam, Richardson-extrapolated for the linear
    axial and torsional elements (``O(h^2)``; the cubic bending elements are converged at both meshes)."""
    meshes = []
    for n in (32, 64):
        chain = FEChain([FEBeam(**{**p.__dict__, "elements": n}) if isinstance(p, FEBeam) else p for p in parts],
                        start_held=start_held)
        meshes.append(chain.frequencies(count))
    return (4.0 * meshes[1] - meshes[0]) / 3.0


def _fe_beam(rotation=None, elements: int = 64) -> FEBeam:
    return FEBeam(length=L, EA=ARM["axial_stiffness"], GJ=ARM["torsional_stiffness"], EIy=ARM["bending_stiffness_z"],
                  EIz=ARM["bending_stiffness_y"], rhoA=RHO_A, rhoIp=ARM["polar_inertia_per_length"], rotation=rotation,
                  elements=elements)


TIP_INERTIA = np.array([[0.004, 0.0005, 0.0], [0.0005, 0.005, 0.0], [0.0, 0.0, 0.006]])
TIP_CENTER = np.array([0.05, 0.01, -0.02])


def _tip(elements, rotation):
    body = sp.SpatialBody("payload", 0.3, TIP_INERTIA, center_of_mass=TIP_CENTER)
    fe = FEBody(0.3, rotation @ TIP_INERTIA @ rotation.T, center=rotation @ TIP_CENTER)
    return elements + [body, sp.Weld(name="grip", parent="arm", child="payload", point="tip")], fe


@pytest.mark.parametrize("kind", ["spherical", "elastic6"])
def test_elastic_roots_equal_the_converged_finite_element_reference(kind):
    rotary = np.array([[40.0, 5.0, -3.0], [5.0, 30.0, 2.0], [-3.0, 2.0, 25.0]])
    if kind == "spherical":
        joint = sp.Spherical(name="root", parent=None, child="arm", rotation=TURN, stiffness=rotary)
        law, held = block_diag(np.zeros((3, 3)), TURN @ rotary @ TURN.T), ("ux", "uy", "uz")
    else:
        six = block_diag(np.diag([3e3, 2e3, 4e3]), rotary)
        six[0, 4] = six[4, 0] = 50.0                                  # a coupled translation-rotation term
        joint = sp.Elastic6(name="root", parent=None, child="arm", rotation=TURN, stiffness=six)
        T = block_diag(TURN, TURN)
        law, held = T @ six @ T.T, ()
    elements, tip = _tip([arm(), joint], TURN)
    omega = ctmm.natural_frequencies(sp.SpatialModel("m", elements, gravity=(0.0, 0.0, 0.0)), n_modes=10,
                                     fields="exact")
    reference = _fe_frequencies([FEGround(law), _fe_beam(TURN), tip], held, 10)
    assert omega[0] > 1.0                                             # no rigid mode: the springs hold it
    np.testing.assert_allclose(omega, reference, rtol=5e-7)                  # 1.2e-7 measured


def test_an_elastic6_joint_between_a_beam_and_a_body_equals_the_finite_element_reference():
    six = np.diag([2e3, 1.5e3, 1e3, 30.0, 20.0, 15.0])
    elements = [arm(), sp.Weld(name="root", parent=None, child="arm", rotation=TURN),
                sp.SpatialBody("payload", 0.3, TIP_INERTIA, center_of_mass=TIP_CENTER),
                sp.Elastic6(name="grip", parent="arm", child="payload", point="tip", stiffness=six)]
    omega = ctmm.natural_frequencies(sp.SpatialModel("m", elements, gravity=(0.0, 0.0, 0.0)), n_modes=10,
                                     fields="exact")
    T = block_diag(TURN, TURN)
    parts = [_fe_beam(TURN), FESpring(T @ six @ T.T), FEBody(0.3, TURN @ TIP_INERTIA @ TURN.T,
                                                              center=TURN @ TIP_CENTER)]
    np.testing.assert_allclose(omega, _fe_frequencies(parts, ("ux", "uy", "uz", "theta_x", "theta_y", "theta_z"),
                                                      10), rtol=5e-7)   # 1.4e-7 measured


def _two_bodies(joint):
    inertia = np.array([[0.02, 0.003, -0.001], [0.003, 0.03, 0.002], [-0.001, 0.002, 0.025]])
    center = np.array([0.12, -0.04, 0.05])
    elements = [sp.SpatialBody("base", 1.0, (0.1, 0.1, 0.1), points={"p": (0.3, 0.1, 0.0)}),
                sp.Weld(name="ground", parent=None, child="base", rotation=TURN),
                sp.SpatialBody("head", 0.8, inertia, center_of_mass=center), joint]
    about_joint = inertia + 0.8 * (center @ center * np.eye(3) - np.outer(center, center))   # head axes
    return sp.SpatialModel("pair", elements, gravity=(0.0, 0.0, 0.0)), about_joint


def test_a_universal_spring_with_oblique_axes_between_bodies_is_the_two_degree_of_freedom_pendulum():
    a1, a2 = np.array([1.0, 0.0, 0.0]), np.array([0.6, 0.8, 0.0])     # 53 degrees apart
    joint = sp.Universal(name="u", parent="base", point="p", child="head", rotation=TURN, axis1=a1, axis2=a2,
                         stiffness=(4.0, 2.5))
    model, inertia = _two_bodies(joint)
    A = np.column_stack([a1, a2])                                      # rotation per unit q (joint = head axes)
    expected = np.sqrt(eigh(np.diag([4.0, 2.5]), A.T @ inertia @ A, eigvals_only=True))
    omega = ctmm.natural_frequencies(model, n_modes=2, fields="exact")
    np.testing.assert_allclose(omega, expected, rtol=1e-10)


def test_the_ports_of_a_universal_joint_between_bodies_are_its_coordinates_and_torques():
    a1, a2 = np.array([1.0, 0.0, 0.0]), np.array([0.6, 0.8, 0.0])
    joint = sp.Universal(name="u", parent="base", point="p", child="head", rotation=TURN, axis1=a1, axis2=a2,
                         stiffness=(4.0, 2.5), damping=(0.1, 0.05), actuated=True)
    model, inertia = _two_bodies(joint)
    A = np.column_stack([a1, a2])
    omega = np.array([0.5, 3.0, 9.0])
    frf = ctmm.frequency_response(model, omega, input=["u.torque1", "u.torque2"], output=["u.q1", "u.q2_rate"],
                                  fields="exact")
    for k, w in enumerate(omega):                    # (K + i w C - w^2 A^T I A) q = tau
        dynamic = np.diag([4.0, 2.5]) + 1j * w * np.diag([0.1, 0.05]) - w * w * (A.T @ inertia @ A)
        expected = np.linalg.inv(dynamic)
        np.testing.assert_allclose(frf.response[0, :, k], expected[0], rtol=1e-10)
        np.testing.assert_allclose(frf.response[1, :, k], 1j * w * expected[1], rtol=1e-10)


def test_the_ports_of_a_prismatic_root_are_its_position_and_force():
    joint = sp.Prismatic(name="slide", parent=None, child="arm", axis=(0, 1, 0), stiffness=80.0, actuated=True)
    model = sp.SpatialModel("m", [arm(), joint], gravity=(0.0, 0.0, 0.0))
    omega = np.array([2.0, 11.0, 35.0])
    frf = ctmm.frequency_response(model, omega, input="slide.force", output=["slide.position", "arm.tip.y"],
                                  fields="exact")
    chains = [FEChain([FEGround(np.diag([0, 80.0, 0, 0, 0, 0])), FEMarker("root"), _fe_beam(elements=n),
                       FEMarker("tip")], start_held=("ux", "uz", "theta_x", "theta_y", "theta_z")) for n in (32, 64)]
    for output, name in ((("root", "uy"), "slide.position"), (("tip", "uy"), "arm.tip.y")):
        coarse, fine = (chain.frf(omega, ("root", "uy"), output) for chain in chains)
        expected = (4.0 * fine - coarse) / 3.0
        np.testing.assert_allclose(frf(name, "slide.force"), expected, rtol=1e-6)


def test_a_spherical_spring_between_bodies_is_the_three_degree_of_freedom_pendulum():
    rotary = np.array([[4.0, 0.5, 0.0], [0.5, 3.0, 0.2], [0.0, 0.2, 2.0]])
    joint = sp.Spherical(name="s", parent="base", point="p", child="head", stiffness=rotary)
    model, inertia = _two_bodies(joint)
    expected = np.sqrt(eigh(rotary, inertia, eigvals_only=True))
    omega = ctmm.natural_frequencies(model, n_modes=3, fields="exact")
    np.testing.assert_allclose(omega, expected, rtol=1e-10)


def test_the_ports_of_a_spherical_root_equal_the_finite_element_response():
    elements, tip = _tip([arm(), sp.Spherical(name="root", parent=None, child="arm", stiffness=(20.0, 30.0, 40.0),
                                              actuated=True)], np.eye(3))
    model = sp.SpatialModel("m", elements, gravity=(0.0, 0.0, 0.0))
    omega = np.array([3.0, 17.0, 60.0])
    frf = ctmm.frequency_response(model, omega, input=["root.torque_y", "payload.force_body_z"],
                                  output=["arm.tip.z", "root.wy", "arm.tip.w_z"], fields="exact")
    chains = [FEChain([FEGround(np.diag([0, 0, 0, 20.0, 30.0, 40.0])), FEMarker("root"), _fe_beam(elements=n),
                       FEMarker("tip"), tip], start_held=("ux", "uy", "uz")) for n in (32, 64)]

    def fe(w, output):                                   # Richardson in the mesh, as in _fe_frequencies
        coarse, fine = (chain.frf(w, ("root", "theta_y"), output)[0] for chain in chains)
        return (4.0 * fine - coarse) / 3.0

    for k, w in enumerate(omega):
        tip_z, root_y = fe(w, ("tip", "uz")), fe(w, ("root", "theta_y"))
        got = frf.response[:, 0, k]
        assert abs(got[0] - tip_z) <= 1e-6 * abs(tip_z)
        assert abs(got[1] - 1j * w * root_y) <= 1e-6 * abs(w * root_y)
        relative = tip_z + L * root_y                                     # w_z: relative to the root frame
        assert abs(got[2] - relative) <= 1e-6 * abs(relative)
    assert np.all(np.abs(frf.response[:, 1, :]) > 0.0)


@pytest.mark.parametrize("joint, words", [
    (sp.Universal(name="u", parent="base", point="p", child="head", stiffness=(4.0, 0.0)), "free in a direction"),
    (sp.Spherical(name="s", parent="base", point="p", child="head", stiffness=(4.0, 3.0, 2.0),
                  damping=[[1.0, 0.3, 0.0], [0.3, 1.0, 0.0], [0.0, 0.0, 1.0]]), "principal axes"),
    (sp.Elastic6(name="e", parent="base", point="p", child="head", stiffness=(1, 1, 1, 1, 1, 0)), "positive definite"),
    (sp.Free(name="f", parent="base", point="p", child="head"), "free joint"),
])
def test_joints_between_bodies_without_a_transfer_matrix_are_refused_by_name(joint, words):
    model, _ = _two_bodies(joint)
    with pytest.raises(ModelError, match=words):
        ctmm.natural_frequencies(model, n_modes=2, fields="exact")
