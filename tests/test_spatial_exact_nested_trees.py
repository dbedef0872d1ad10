"""Branches of branches in the exact spatial trees (issue 15): a branch carrying its own branch is
condensed recursively; checked against the global finite-element tree of ctmm/reference/fe_beam3d.py
(nested ``FEBranch``; 16 and 32 elements per beam, Richardson-extrapolated)."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.reference.fe_beam3d import COMPONENTS, FEBeam, FEBody, FEBranch, FEChain, FEMarker, FESpring

ARM = dict(length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0,
           torsional_stiffness=3.0, polar_inertia_per_length=0.002, axial_stiffness=400.0)
SIDE = dict(length=0.4, mass_per_length=0.5, bending_stiffness_y=3.0, bending_stiffness_z=4.0,
            torsional_stiffness=2.0, polar_inertia_per_length=0.001, axial_stiffness=300.0)
MODES = dict(n_modes_y=1, n_modes_z=1, n_torsion_modes=1, n_axial_modes=1)
SIX = np.diag([500.0, 600.0, 700.0, 5.0, 6.0, 7.0])
SIDEWAYS = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])      # beam x along world y
RING = np.diag([0.002, 0.003, 0.0025])
BOB = np.diag([0.001, 0.002, 0.0015])
PAYLOAD = np.diag([0.004, 0.005, 0.006])


def nested_tree() -> sp.SpatialModel:
    """A clamped arm with a payload; at mid-span a ring on an elastic6 joint (a branch) carrying a bob on a
    second elastic6 joint (the branch goes on) and a beam welded sideways (a branch of the branch)."""
    return sp.SpatialModel("nested", [
        sp.SpatialBeam("arm", **ARM, **MODES, stations={"mid": 0.5}), sp.Weld(name="root", parent=None, child="arm"),
        sp.SpatialBody("payload", 0.3, PAYLOAD), sp.Weld(name="grip", parent="arm", child="payload", point="tip"),
        sp.SpatialBody("ring", 0.4, RING, points={"hook": (0.0, 0.0, -0.1), "side": (0.0, 0.1, 0.0)}),
        sp.Elastic6(name="clip", parent="arm", point="mid", child="ring", stiffness=2 * SIX),
        sp.SpatialBody("bob", 0.2, BOB, center_of_mass=(0.0, 0.02, -0.03)),
        sp.Elastic6(name="hang", parent="ring", point="hook", child="bob", stiffness=SIX),
        sp.SpatialBeam("side", **SIDE, **MODES),
        sp.Weld(name="tee", parent="ring", point="side", child="side", rotation=SIDEWAYS)], gravity=(0, 0, 0))


def _fe_beam(length, parameters, elements, rotation=None) -> FEBeam:
    return FEBeam(length=length, EA=parameters["axial_stiffness"], GJ=parameters["torsional_stiffness"],
                  EIy=parameters["bending_stiffness_z"], EIz=parameters["bending_stiffness_y"],
                  rhoA=parameters["mass_per_length"], rhoIp=parameters["polar_inertia_per_length"], rotation=rotation,
                  elements=elements)


def fe_tree(n: int) -> FEChain:
    side = FEBranch([FEBody(0.0, np.zeros((3, 3)), offset=(0.0, 0.1, 0.0)), _fe_beam(0.4, SIDE, n, SIDEWAYS),
                     FEMarker("side_tip")])
    ring = FEBranch([FESpring(2 * SIX), FEBody(0.4, RING), side, FEBody(0.0, np.zeros((3, 3)), offset=(0.0, 0.0, -0.1)),
                     FESpring(SIX), FEMarker("bob"), FEBody(0.2, BOB, center=(0.0, 0.02, -0.03))])
    return FEChain([_fe_beam(0.5, ARM, n), ring, _fe_beam(0.6, ARM, n), FEMarker("tip"), FEBody(0.3, PAYLOAD)],
                   start_held=COMPONENTS)


def test_a_branch_of_a_branch_has_the_natural_frequencies_of_the_finite_element_tree():
    omega = ctmm.natural_frequencies(nested_tree(), n_modes=6, fields="exact")
    coarse, fine = fe_tree(16).frequencies(6), fe_tree(32).frequencies(6)
    reference = (4.0 * fine - coarse) / 3.0            # the linear axial / torsional elements converge like h^2
    bound = np.abs(fine - coarse) / 3.0
    assert np.all(np.abs(omega - reference) <= 0.05 * bound + 1e-8 * reference)   # 3e-9 measured


def test_the_response_of_a_branch_of_a_branch_equals_the_finite_element_tree():
    omega = np.array([3.0, 17.0, 45.0])
    frf = ctmm.frequency_response(nested_tree(), omega, input="arm.tip.force_z",
                                  output=["side.tip.z", "side.tip.x", "bob.origin.z", "arm.tip.z"], fields="exact")
    trees = [fe_tree(16), fe_tree(32)]
    for name, output in (("side.tip.z", ("side_tip", "uz")), ("side.tip.x", ("side_tip", "ux")),
                         ("bob.origin.z", ("bob", "uz")), ("arm.tip.z", ("tip", "uz"))):
        coarse, fine = (tree.frf(omega, ("tip", "uz"), output) for tree in trees)
        reference = (4.0 * fine - coarse) / 3.0
        got = frf(name, "arm.tip.force_z")
        assert np.abs(got - reference).max() <= 1e-7 * np.abs(reference).max(), name   # 1.5e-8 measured


def test_inputs_on_a_branch_of_a_branch_are_refused_by_name():
    with pytest.raises(ModelError, match="side.tip.force_z.*branch"):
        ctmm.frequency_response(nested_tree(), [1.0], input="side.tip.force_z", output="arm.tip.z", fields="exact")


def test_a_tree_refuses_a_sub_branch_point_that_is_not_on_its_branch():
    from ctmm.spatial_beam_elements import SpatialClamped, SpatialFree, SpatialPointLoad
    from ctmm.spatial_beam_fields import SpatialBeamField
    from ctmm.spatial_beam_trees import SpatialBeamTree

    def beam(name):
        return SpatialBeamField(name, 0.5, axial_stiffness=300.0, torsional_stiffness=2.0, bending_stiffness_y=3.0,
                                bending_stiffness_z=4.0, mass_per_length=0.5, polar_inertia_per_length=0.001)

    branch = [beam("b"), SpatialPointLoad("b_mid"), beam("b2"), SpatialFree("b_end")]
    with pytest.raises(ModelError, match="branch point 'nowhere' is not one of its elements"):
        SpatialBeamTree("t", [SpatialClamped("r"), beam("m"), SpatialPointLoad("p"), SpatialFree("e")],
                        {"p": (branch, {"nowhere": [beam("c"), SpatialFree("c_end")]})})
    tree = SpatialBeamTree("t", [SpatialClamped("r"), beam("m"), SpatialPointLoad("p"), SpatialFree("e")],
                           {"p": (branch, {"b_mid": [beam("c"), SpatialFree("c_end")]})})
    assert tree.eigenvalue_count([1e-3])[0] == 0
