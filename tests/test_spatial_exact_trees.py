"""Trees in the exact-field bridge (issue 15, ``fields="exact"``): a spatial model whose bodies carry
several children becomes a :class:`ctmm.spatial_beam_trees.SpatialBeamTree` (the main path: the base and
every body's first child; the other children: branches condensed onto it), checked against the
finite-element tree of ctmm/reference/fe_beam3d.py (``FEBranch``; 16 and 32 elements per beam,
Richardson-extrapolated for the linear axial and torsional elements)."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.reference.fe_beam3d import COMPONENTS, FEBeam, FEBody, FEBranch, FEChain, FEGround, FEMarker, FESpring

ARM = dict(length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0,
           torsional_stiffness=3.0, polar_inertia_per_length=0.002, axial_stiffness=400.0)
SIDE = dict(length=0.6, mass_per_length=0.5, bending_stiffness_y=3.0, bending_stiffness_z=4.0,
            torsional_stiffness=2.0, polar_inertia_per_length=0.001, axial_stiffness=300.0)
MODES = dict(n_modes_y=1, n_modes_z=1, n_torsion_modes=1, n_axial_modes=1)
TIP_INERTIA = np.array([[0.004, 0.0005, 0.0], [0.0005, 0.005, 0.0], [0.0, 0.0, 0.006]])
TIP_CENTER = (0.05, 0.01, -0.02)
SIX = np.diag([500.0, 600.0, 700.0, 5.0, 6.0, 7.0])
SIDEWAYS = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])      # beam x along world y


def _fe_beam(length, parameters, elements, rotation=None) -> FEBeam:
    return FEBeam(length=length, EA=parameters["axial_stiffness"], GJ=parameters["torsional_stiffness"],
                  EIy=parameters["bending_stiffness_z"], EIz=parameters["bending_stiffness_y"],
                  rhoA=parameters["mass_per_length"], rhoIp=parameters["polar_inertia_per_length"], rotation=rotation,
                  elements=elements)


def test_bodies_on_a_mid_span_station_and_on_a_body_point_equal_the_finite_element_tree():
    elements = [sp.SpatialBeam("arm", **ARM, **MODES, stations={"mid": 0.5}),
                sp.Weld(name="root", parent=None, child="arm"),
                sp.SpatialBody("payload", 0.3, TIP_INERTIA, center_of_mass=TIP_CENTER,
                               points={"hook": (0.05, 0.0, -0.1)}),
                sp.Weld(name="grip", parent="arm", child="payload", point="tip"),
                sp.SpatialBody("bob", 0.2, (0.001, 0.002, 0.0015), center_of_mass=(0.0, 0.02, -0.03)),
                sp.Elastic6(name="hang", parent="payload", point="hook", child="bob", stiffness=SIX),
                sp.SpatialBody("ring", 0.4, (0.002, 0.003, 0.0025)),
                sp.Elastic6(name="clip", parent="arm", point="mid", child="ring", stiffness=2 * SIX)]
    omega = ctmm.natural_frequencies(sp.SpatialModel("tree", elements, gravity=(0, 0, 0)), n_modes=8,
                                     fields="exact")

    def fe(n):
        parts = [_fe_beam(0.5, ARM, n), FEBranch([FESpring(2 * SIX), FEBody(0.4, np.diag([0.002, 0.003, 0.0025]))]),
                 _fe_beam(0.6, ARM, n), FEBody(0.3, TIP_INERTIA, center=TIP_CENTER),
                 FEBody(0.0, np.zeros((3, 3)), offset=(0.05, 0.0, -0.1)), FESpring(SIX),
                 FEBody(0.2, np.diag([0.001, 0.002, 0.0015]), center=(0.0, 0.02, -0.03))]
        return FEChain(parts, start_held=COMPONENTS).frequencies(8)

    reference = (4.0 * fe(32) - fe(16)) / 3.0
    np.testing.assert_allclose(omega, reference, rtol=1e-7)                    # 2.3e-8 measured


def hub_tree() -> sp.SpatialModel:
    """A hub on a revolute spring with a beam at one point and a second beam welded sideways at another."""
    return sp.SpatialModel("hub_tree", [
        sp.SpatialBody("hub", 2.0, (0.1, 0.12, 0.15), points={"out": (0.2, 0.0, 0.0), "side": (0.0, 0.15, 0.05)}),
        sp.Revolute(name="hinge", parent=None, child="hub", axis=(0, 0, 1), stiffness=50.0, actuated=True),
        sp.SpatialBeam("arm", **ARM, **MODES), sp.Weld(name="mount", parent="hub", child="arm", point="out"),
        sp.SpatialBeam("side", **SIDE, **MODES),
        sp.Weld(name="tee", parent="hub", child="side", point="side", rotation=SIDEWAYS)], gravity=(0, 0, 0))


def test_the_frequency_response_of_a_tree_reads_the_branches_and_closes_loops():
    omega = np.array([2.0, 15.0, 40.0])
    outputs = ["side.tip.w_z", "side.tip.z", "arm.tip.z", "hinge.angle"]
    frf = ctmm.frequency_response(hub_tree(), omega, input=["hinge.torque", "arm.tip.force_body_z"], output=outputs,
                                  fields="exact")

    def fe(n):
        branch = FEBranch([FEBody(0.0, np.zeros((3, 3)), offset=(0.0, 0.15, 0.05)), FEMarker("side_root"),
                           _fe_beam(0.6, SIDE, n, SIDEWAYS), FEMarker("side_tip")])
        return FEChain([FEGround(np.diag([0, 0, 0, 0, 0, 50.0])), FEMarker("root"), branch,
                        FEBody(2.0, np.diag([0.1, 0.12, 0.15]), offset=(0.2, 0.0, 0.0)), _fe_beam(1.1, ARM, n),
                        FEMarker("tip")], start_held=("ux", "uy", "uz", "theta_x", "theta_y"))

    chains = [fe(16), fe(32)]

    def reference(load, output):
        coarse, fine = (chain.frf(omega, load, output) for chain in chains)
        return (4.0 * fine - coarse) / 3.0

    for i, load in enumerate([("root", "theta_z"), ("tip", "uz")]):
        side_z = reference(load, ("side_tip", "uz"))
        # w_z of the side beam: relative to its root frame (beam z = world z, beam x = world y)
        relative = side_z - reference(load, ("side_root", "uz")) + 0.6 * reference(load, ("side_root", "theta_x"))
        cases = (("side.tip.w_z", relative), ("side.tip.z", side_z), ("arm.tip.z", reference(load, ("tip", "uz"))),
                 ("hinge.angle", reference(load, ("root", "theta_z"))))
        # a response the reference decouples exactly (the hinge under an out-of-plane tip force: 0) is met to
        # round-off of the load's largest response (1e-16 found), not to 1e-6 of zero
        scale = max(np.abs(expected).max() for _, expected in cases)
        for name, expected in cases:
            got = frf(name, frf.inputs[i])
            assert np.abs(got - expected).max() <= 1e-6 * np.abs(expected).max() + 1e-12 * scale, (name, frf.inputs[i])
    closed = ctmm.frequency_response(
        with_feedback(hub_tree(), [Feedback("pd", [("hinge.angle", 30.0), ("hinge.rate", 2.0)], "hinge.torque", gain=1.0)]),
        omega, input="pd.reference", output="side.tip.z", fields="exact")
    open_angle, open_side = frf("hinge.angle", "hinge.torque"), frf("side.tip.z", "hinge.torque")
    controller = 30.0 + 2.0j * omega                                  # u = -C (y - r): y / r = G C / (1 + G C)
    expected = open_side * controller / (1.0 + controller * open_angle)
    assert np.abs(closed("side.tip.z", "pd.reference") - expected).max() <= 1e-10 * np.abs(expected).max()


def test_tree_refusals_name_the_part():
    model = hub_tree()
    with pytest.raises(ModelError, match="side.tip.force_z.*branch"):
        ctmm.frequency_response(model, [1.0], input="side.tip.force_z", output="arm.tip.z", fields="exact")
    # branches of branches: tests/test_spatial_exact_nested_trees.py
