"""The bridge from a spatial model of modal beams to the exact spatial beam fields (issue 15,
``fields="exact"``, ctmm/spatial_exact_fields.py): analytic cantilever frequencies and static
compliance (independent of both forms), the modal beam converging to the exact frequencies from
above as its modes increase (clamped beam with an inertial tip body; hub-beam on a revolute
joint), rigid directions, and refusals by name."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import ctmm
import ctmm.spatial as sp
from ctmm import spatial_exact_fields
from ctmm.errors import ModelError
from ctmm.reference.beams import beta_roots

ARM = dict(length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0,
           torsional_stiffness=3.0, polar_inertia_per_length=0.002, axial_stiffness=400.0)
TILT = Rotation.from_euler("zy", [30, 20], degrees=True).as_matrix()


def beam(n: int, static: bool = False, **changes) -> sp.SpatialBeam:
    parameters = dict(ARM, n_modes_y=n, n_modes_z=n, n_torsion_modes=n, n_axial_modes=n, static_shapes=static)
    parameters.update(changes)
    return sp.SpatialBeam("arm", **parameters)


def cantilever(arm: sp.SpatialBeam, tip: bool = True, rotation=None) -> sp.SpatialModel:
    elements = [arm, sp.Weld(name="root", parent=None, child="arm", rotation=rotation)]
    if tip:
        elements += [sp.SpatialBody("payload", 0.3, (0.004, 0.005, 0.006), center_of_mass=(0.05, 0.01, 0.0)),
                     sp.Weld(name="grip", parent="arm", child="payload", point="tip")]
    return sp.SpatialModel("cantilever", elements, gravity=(0.0, 0.0, 0.0))


def hub_beam(arm: sp.SpatialBeam) -> sp.SpatialModel:
    return sp.SpatialModel("hub_beam", [
        sp.SpatialBody("hub", 2.0, (0.1, 0.12, 0.15), points={"out": (0.2, 0.0, 0.0)}),
        sp.Revolute(name="hinge", parent=None, child="hub", axis=(0.0, 0.0, 1.0), actuated=True),
        arm, sp.Weld(name="mount", parent="hub", child="arm", point="out"),
        sp.SpatialBody("payload", 0.3, (0.004, 0.005, 0.006), center_of_mass=(0.05, 0.01, 0.0)),
        sp.Weld(name="grip", parent="arm", child="payload", point="tip")], gravity=(0.0, 0.0, 0.0))


def test_exact_cantilever_frequencies_are_the_analytic_ones_in_every_direction():
    """Clamped-free, no tip body, tilted: bending beta_k^2 sqrt(EI / rhoA L^4) with the modal beam's
    EI_y for w_y and EI_z for w_z, torsion and axial (2k - 1) pi / 2L sqrt(stiffness / inertia)."""
    L, rhoA = ARM["length"], ARM["mass_per_length"]
    expected = []
    for stiffness in (ARM["bending_stiffness_y"], ARM["bending_stiffness_z"]):
        expected += list(beta_roots("clamped-free", 3) ** 2 * math.sqrt(stiffness / (rhoA * L ** 4)))
    for stiffness, inertia in ((ARM["torsional_stiffness"], ARM["polar_inertia_per_length"]),
                               (ARM["axial_stiffness"], rhoA)):
        expected += [(2 * k - 1) * math.pi / (2 * L) * math.sqrt(stiffness / inertia) for k in (1, 2, 3)]
    expected = np.sort([w for w in expected if w < 167.0])          # 11 frequencies, the last torsional
    omega = ctmm.natural_frequencies(cantilever(beam(1), tip=False, rotation=TILT), omega_max=167.0, fields="exact")
    np.testing.assert_allclose(omega, expected, rtol=1e-9)


def test_exact_static_compliance_in_world_axes_and_beam_axes():
    """omega = 0: the tip compliance R diag(L / EA, L^3 / 3 EI_y, L^3 / 3 EI_z) R^T (world axes) and its
    rows in the beam's axes (w_y, w_z, axial sensors)."""
    L = ARM["length"]
    model = cantilever(beam(2, stations={"mid": 0.5}), tip=False, rotation=TILT)
    forces = ["arm.tip.force_x", "arm.tip.force_y", "arm.tip.force_z"]
    frf = ctmm.frequency_response(model, [0.0], input=forces, fields="exact",
                                  output=["arm.tip.x", "arm.tip.y", "arm.tip.z", "arm.tip.axial", "arm.tip.w_y",
                                          "arm.tip.w_z"])
    local = np.diag([L / ARM["axial_stiffness"], L ** 3 / (3 * ARM["bending_stiffness_y"]),
                     L ** 3 / (3 * ARM["bending_stiffness_z"])])
    response = frf.response[:, :, 0]
    np.testing.assert_allclose(response[:3].real, TILT @ local @ TILT.T, atol=1e-14)
    np.testing.assert_allclose(response[3:].real, local @ TILT.T, atol=1e-14)
    assert np.max(np.abs(response.imag)) == 0.0


@pytest.mark.parametrize("make, counts, checked", [
    (lambda n: cantilever(beam(n, static=True)), (2, 4, 6), 6),
    (lambda n: hub_beam(beam(n, static=True)), (1, 2, 4), 5),
])
def test_modal_beam_frequencies_converge_to_the_exact_ones_from_above(make, counts, checked):
    """Clamped-free beam with an inertial tip body, and the hub-beam on a free revolute joint (one rigid
    mode, 0 rad/s in both forms): with static shapes the modal beam's lowest frequencies approach the
    exact ones from above (Rayleigh-Ritz) and monotonically as the modes increase."""
    exact = ctmm.natural_frequencies(make(1), n_modes=checked, fields="exact")
    errors = []
    for n in counts:
        modal = ctmm.natural_frequencies(make(n), n_modes=checked)
        assert np.all(modal >= exact * (1 - 1e-10)), (n, modal, exact)
        errors.append(np.abs(modal - exact)[exact > 0] / exact[exact > 0])
    errors = np.array(errors)
    assert np.all(errors[1:] <= errors[:-1] * 1.0001 + 1e-10), errors     # 1e-10: round-off floor
    assert errors[-1].max() < 3e-5 and errors[0].max() > 10 * errors[-1].max(), errors
    if exact[0] == 0.0:
        assert ctmm.natural_frequencies(make(counts[-1]), n_modes=1)[0] == pytest.approx(0.0, abs=1e-6)


def test_free_end_modes_converge_too_without_static_shapes():
    """Plain clamped-free modes: the tip body's frequencies converge (slowly, O(1/n)) from above."""
    exact = ctmm.natural_frequencies(cantilever(beam(1)), n_modes=2, fields="exact")
    errors = [ctmm.natural_frequencies(cantilever(beam(n)), n_modes=2) / exact - 1 for n in (2, 4, 8)]
    assert np.all(np.diff(np.array(errors), axis=0) < 0) and np.all(np.array(errors) > 0)


def test_rigid_directions_are_rigid_and_a_frequency_that_depends_on_them_is_refused(monkeypatch):
    """A bending-only beam (no twist or axial modes, no section inertia) is rigid there: its exact form
    gives the modal beam's limit; asking for frequencies of the rigid directions is refused by name."""
    bending_only = dict(n_torsion_modes=0, n_axial_modes=0, polar_inertia_per_length=0.0)
    exact = ctmm.natural_frequencies(cantilever(beam(1, **bending_only)), n_modes=4, fields="exact")
    modal = ctmm.natural_frequencies(cantilever(beam(6, static=True, **bending_only)), n_modes=4)
    np.testing.assert_allclose(modal, exact, rtol=1e-6)
    assert np.all(modal >= exact * (1 - 1e-10))
    axial_only = sp.SpatialBeam("arm", length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0,
                                bending_stiffness_z=9.0, n_modes_y=0, n_modes_z=0, n_axial_modes=1,
                                axial_stiffness=400.0)
    first = ctmm.natural_frequencies(cantilever(axial_only, tip=False), n_modes=1, fields="exact")
    assert first[0] == pytest.approx(math.pi / 2.2 * math.sqrt(400.0 / 0.9), rel=1e-9)
    four = ctmm.natural_frequencies(cantilever(axial_only, tip=False), n_modes=4, fields="exact")
    np.testing.assert_allclose(four, first[0] * np.array([1, 3, 5, 7]), rtol=1e-9)   # the rigid planes stay out
    monkeypatch.setattr(spatial_exact_fields, "RIGID_FACTOR", 1e2)       # rigid bending now near 100 rad/s
    with pytest.raises(ModelError, match="arm.bending_y"):
        ctmm.natural_frequencies(cantilever(axial_only, tip=False), n_modes=4, fields="exact")


def test_hinge_torque_and_angle_ports_of_the_hub_beam():
    """The hub-beam's base torque -> hub angle at low frequency: a free rotor, -1 / (J_total omega^2),
    J_total the whole model's inertia about the axis (hub, beam, tip body: computed here directly)."""
    model = hub_beam(beam(2))
    omega = np.array([1e-3])
    frf = ctmm.frequency_response(model, omega, input="hinge.torque", output=["hinge.angle", "hub.omega_z"],
                                  fields="exact")
    L, rhoA, r = ARM["length"], ARM["mass_per_length"], 0.2
    beam_inertia = rhoA * ((r + L) ** 3 - r ** 3) / 3 + ARM["polar_inertia_per_length"] * 0.0
    tip = 0.3 * ((r + L + 0.05) ** 2 + 0.01 ** 2) + 0.006
    inertia = 0.15 + beam_inertia + tip
    assert frf.response[0, 0, 0].real == pytest.approx(-1 / (inertia * omega[0] ** 2), rel=1e-5)
    assert frf.response[1, 0, 0] == pytest.approx(1j * omega[0] * frf.response[0, 0, 0], rel=1e-12)


@pytest.mark.parametrize("change, words", [
    (lambda els: sp.SpatialModel("m", els, gravity=(0, 0, -9.81)), "gravity"),
    (lambda els: sp.SpatialModel("m", els[:3] + [sp.Prismatic(name="grip", parent="arm", child="payload",
                                                              point="tip", stiffness=5.0)],
                                 gravity=(0, 0, 0)), "prismatic"),
    (lambda els: sp.SpatialModel("m", [sp.SpatialBeam("arm", **dict(ARM, damping_ratio=0.01)), els[1]],
                                 gravity=(0, 0, 0)), "damping_ratio"),
    (lambda els: sp.SpatialModel("m", [sp.SpatialBeam("arm", **dict(ARM, stations={"s": 0.5})), els[1], els[2],
                                       sp.Weld(name="grip", parent="arm", child="payload", point="s")],
                                 gravity=(0, 0, 0)), "mid-span"),
])
def test_unconvertible_models_are_refused_by_name(change, words):
    elements = [sp.SpatialBeam("arm", **ARM), sp.Weld(name="root", parent=None, child="arm"),
                sp.SpatialBody("payload", 0.3, (0.004, 0.005, 0.006)),
                sp.Weld(name="grip", parent="arm", child="payload", point="tip")]
    with pytest.raises(ModelError, match=words):
        ctmm.natural_frequencies(change(elements), n_modes=2, fields="exact")


def test_ports_without_a_counterpart_are_refused():
    model = cantilever(beam(2))
    with pytest.raises(ModelError, match="arm.qy1"):
        ctmm.frequency_response(model, [1.0], input="arm.tip.force_y", output="arm.qy1", fields="exact")
    with pytest.raises(ModelError, match="fields"):
        ctmm.natural_frequencies(model, n_modes=2, fields="finite")


def test_a_beam_turned_obliquely_to_the_base_axis_has_one_rigid_mode_and_the_converged_modal_frequencies():
    """A coning beam on a hub revolute (a field turned obliquely to the chain axes): one rigid mode (the hub)
    and the flexible frequencies that the modal beam approaches from above (6 modes per direction)."""
    def model(n):
        return sp.SpatialModel("coning", [
            sp.SpatialBody("hub", 2.0, (0.1, 0.12, 0.15), points={"out": (0.2, 0.0, 0.0)}),
            sp.Revolute(name="hinge", parent=None, child="hub", axis=(0.0, 0.0, 1.0)),
            beam(n), sp.Weld(name="mount", parent="hub", child="arm", point="out",
                             rotation=Rotation.from_euler("y", 20, degrees=True).as_matrix())], gravity=(0.0, 0.0, 0.0))
    exact = ctmm.natural_frequencies(model(1), n_modes=5, fields="exact")
    modal = ctmm.natural_frequencies(model(6), n_modes=5)
    assert exact[0] == 0.0 and np.all(exact[1:] > 1.0)
    assert np.all(modal[1:] >= exact[1:] * (1 - 1e-9))
    np.testing.assert_allclose(modal[1:], exact[1:], rtol=1e-5)


def test_a_feedback_loop_is_closed_on_the_exact_fields_and_matches_the_converged_modal_beam():
    """A delayed PD on the hub (two loops, hinge.angle and hinge.rate -> hinge.torque, 10 ms): the
    closed-loop response reference -> hub angle and -> loop force on the exact fields equals the
    modal beam's (static shapes, 4 modes per direction) below the first flexible resonance."""
    from ctmm.control import Feedback, with_feedback

    loop = [Feedback("p", "hinge.angle", "hinge.torque", gain=20.0, delay=0.01),
            Feedback("d", "hinge.rate", "hinge.torque", gain=3.0, delay=0.01)]
    omega = np.array([0.5, 2.0, 4.0])
    outputs = ["hinge.angle", "p.u", "arm.tip.w_y"]
    exact = ctmm.frequency_response(with_feedback(hub_beam(beam(1)), loop), omega, input="p.reference",
                                    output=outputs, fields="exact").response
    modal = ctmm.frequency_response(with_feedback(hub_beam(beam(4, static=True)), loop), omega,
                                    input="p.reference", output=outputs[:2]).response
    np.testing.assert_allclose(exact[:2], modal, rtol=1e-6)            # measured 5e-8
    assert np.all(np.abs(exact[2]) > 1e-3)              # the beam bends (m per rad of reference)
    assert np.abs(exact[0, 0, 0]) > 0.5                 # the loop tracks at low frequency
