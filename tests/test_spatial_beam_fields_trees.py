"""Trees of exact spatial beams (ctmm.spatial_beam_trees) against the 3-D finite-element reference."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import ctmm
from ctmm.errors import ModelError
from ctmm.reference.fe_beam3d import FEBeam, FEBody, FEBranch, FEChain, FEMarker
from ctmm.spatial_beam_elements import (SpatialClamped, SpatialFree, SpatialPointLoad, SpatialRigidBody,
                                        SpatialSupport)
from ctmm.spatial_beam_fields import SpatialBeamField
from ctmm.spatial_beam_trees import SpatialBeamTree

SECTION = dict(EA=1.4e7, GJ=250.0, EIy=120.0, EIz=480.0, rhoA=0.54, rhoIp=2.2e-5)
SIDEWAYS = Rotation.from_euler("z", 90, degrees=True).as_matrix()     # local x along the chain's y
OTHER_SIDE = Rotation.from_euler("z", -90, degrees=True).as_matrix()
UPWARDS = Rotation.from_euler("y", -90, degrees=True).as_matrix()     # local x along the chain's z
INERTIA = np.array([[2e-3, 1e-4, 0.0], [1e-4, 3e-3, 2e-4], [0.0, 2e-4, 1.5e-3]])


def beam(name, length, rotation=None, loss_factor=0.0):
    s = SECTION
    return SpatialBeamField(name, length, axial_stiffness=s["EA"], torsional_stiffness=s["GJ"],
                            bending_stiffness_y=s["EIy"], bending_stiffness_z=s["EIz"], mass_per_length=s["rhoA"],
                            polar_inertia_per_length=s["rhoIp"], rotation=rotation, loss_factor=loss_factor)


def fe_beam(length, elements, rotation=None, loss_factor=0.0):
    return FEBeam(length, **SECTION, rotation=rotation, elements=elements, loss_factor=loss_factor)


def tree(loss_factor=0.0):
    """Clamped main chain with a sideways branch (beam, body off the axes, beam, free end) and an upward
    branch ending in a spherical pin, both at the same point."""
    eta = loss_factor
    return SpatialBeamTree("tree", [
        SpatialClamped("root"), beam("m1", 0.7, loss_factor=eta), SpatialPointLoad("hub"), SpatialPointLoad("hub2"),
        beam("m2", 0.5, loss_factor=eta), SpatialPointLoad("tip"), SpatialFree("end")], {
        "hub": [beam("br1", 0.6, SIDEWAYS, eta),
                SpatialRigidBody("body", 0.3, INERTIA, center_of_mass=(0.02, 0.03, 0.0), offset=(0.0, 0.05, 0.0)),
                beam("br2", 0.3, SIDEWAYS, eta), SpatialPointLoad("branch_tip"), SpatialFree("branch_end")],
        "hub2": [beam("up", 0.4, UPWARDS, eta), SpatialSupport("up_end", ("ux", "uy", "uz"))]})


def fe_tree(elements, loss_factor=0.0):
    eta = loss_factor
    return FEChain([
        fe_beam(0.7, elements, loss_factor=eta), FEMarker("hub"),
        FEBranch([fe_beam(0.6, elements, SIDEWAYS, eta), FEBody(0.3, INERTIA, (0.02, 0.03, 0.0), (0.0, 0.05, 0.0)),
                  fe_beam(0.3, elements, SIDEWAYS, eta), FEMarker("branch_tip")]),
        FEBranch([fe_beam(0.4, elements, UPWARDS, eta)], end_held=("ux", "uy", "uz")),
        fe_beam(0.5, elements, loss_factor=eta), FEMarker("tip")])


def test_tree_frequencies_are_the_limit_of_the_fe_tree():
    """Branch counts (clamped-attachment J0) + condensed main-chain count: the ten lowest frequencies,
    FE error falling ~16x per halving (h^4; > 5x for modes with an axial / torsional part, h^2 in the
    linear FE elements) to < 4e-6 at 16 elements per beam; the count steps by one across each."""
    omega = tree().natural_frequencies(n_modes=10, rtol=1e-12)
    errors = [np.abs(fe_tree(n).frequencies(10) - omega) / omega for n in (8, 16)]
    ratio = errors[0] / errors[1]
    assert np.all(ratio > 5.0) and np.median(ratio) > 12.0 and errors[1].max() < 4e-6
    counts = tree().eigenvalue_count(np.concatenate([omega * (1 - 1e-8), omega * (1 + 1e-8)]))
    np.testing.assert_array_equal(counts, np.concatenate([np.arange(10), np.arange(1, 11)]))


def test_symmetric_tree_with_coinciding_branch_resonances():
    """Two equal branches at one point on opposite sides: their clamped frequencies (poles of the
    condensed stiffness) coincide; the count-only bisection still finds every frequency (FE, h^4)."""
    symmetric = SpatialBeamTree("symmetric", [
        SpatialClamped("root"), beam("m", 0.6), SpatialPointLoad("a"), SpatialPointLoad("b"),
        SpatialRigidBody("hub", 0.5, (1e-3, 1e-3, 1e-3)), SpatialFree("end")],
        {"a": [beam("left", 0.5, SIDEWAYS), SpatialFree("left_end")],
         "b": [beam("right", 0.5, OTHER_SIDE), SpatialFree("right_end")]})
    omega = symmetric.natural_frequencies(n_modes=12, rtol=1e-12)

    def fe(n):
        return FEChain([fe_beam(0.6, n), FEBranch([fe_beam(0.5, n, SIDEWAYS)]),
                        FEBranch([fe_beam(0.5, n, OTHER_SIDE)]), FEBody(0.5, (1e-3, 1e-3, 1e-3))]).frequencies(12)

    errors = [np.abs(fe(n) - omega) / omega for n in (8, 16)]
    ratio = errors[0] / errors[1]
    assert np.all(ratio > 5.0) and np.median(ratio) > 12.0 and errors[1].max() < 1e-5


def test_tree_frequency_response_reaches_into_the_branches():
    """Loss factor everywhere; FRFs from main-chain loads to main-chain and branch points (incl. the
    rotation of the off-axis body) converge to the FE ones (h^4)."""
    omega = np.array([7.0, 60.0, 300.0, 800.0])
    outputs = ["tip.uz", "branch_tip.ux", "branch_tip.uy", "hub.uy"]
    response = tree(0.02).frequency_response(omega, input=["tip.fy", "hub.mz"], output=outputs).response
    loads = [("tip", "uy"), ("hub", "theta_z")]
    errors = []
    for n in (8, 16):
        fe = fe_tree(n, 0.02)
        error = 0.0
        for i, load in enumerate(loads):
            for o, name in enumerate(outputs):
                point, component = name.split(".")
                h = fe.frf(omega, load, (point, component))
                error = max(error, np.max(np.abs(h - response[o, i]) / np.abs(response[:, i]).max(axis=0)))
        errors.append(error)
    assert errors[1] < errors[0] / 10 and errors[1] < 1e-5
    body = tree(0.02).frequency_response(omega, input="tip.fy", output=["body.theta_z", "br2.uy"]).response
    assert np.all(np.isfinite(body)) and np.all(np.abs(body) > 0)


def test_frequency_response_beside_a_branch_pole_and_refused_on_it():
    """At a natural frequency of a branch with its attachment clamped the condensed stiffness is singular:
    refused there; 2e-7 beside it the response still matches the FE tree (20 elements) to 1e-7."""
    t = tree()
    pole = ctmm.natural_frequencies(t._branches["hub"].clamped, n_modes=2)[1]
    with pytest.raises(ModelError, match="evaluate beside it"):
        t.frequency_response([pole], input="tip.fy", output="tip.uy")
    beside = np.array([pole * (1 + 2e-7)])
    response = t.frequency_response(beside, input="tip.fy", output=["branch_tip.uy", "tip.uy"]).response[:, 0, 0]
    fe = fe_tree(20)
    expected = [fe.frf(beside, ("tip", "uy"), point)[0] for point in (("branch_tip", "uy"), ("tip", "uy"))]
    np.testing.assert_allclose(response, expected, rtol=1e-7)


def test_tree_refusals():
    t = tree()
    with pytest.raises(ModelError, match="must be a ctmm.Chain"):
        ctmm.natural_frequencies(t, n_modes=2)        # the chain verbs do not take trees: the methods do
    with pytest.raises(ModelError, match="mode_shapes"):
        t.mode_shapes(n_modes=2)
    with pytest.raises(ModelError, match="on a branch"):
        t.frequency_response([1.0], input="branch_tip.fx", output="tip.uy")
    with pytest.raises(ModelError, match="not an element of the main chain"):
        SpatialBeamTree("bad", [SpatialClamped("r"), beam("m", 1.0), SpatialFree("e")],
                        {"nowhere": [beam("b", 1.0), SpatialFree("f")]})
    with pytest.raises(ModelError, match="used twice"):
        SpatialBeamTree("bad", [SpatialClamped("r"), beam("m", 1.0), SpatialPointLoad("p"), SpatialFree("e")],
                        {"p": [beam("m", 1.0), SpatialFree("f")]})
    with pytest.raises(ModelError, match="end it with a boundary"):
        SpatialBeamTree("bad", [SpatialClamped("r"), beam("m", 1.0), SpatialPointLoad("p"), SpatialFree("e")],
                        {"p": [beam("b", 1.0)]})
    from ctmm.elements.boundary import Elastic
    with pytest.raises(ModelError, match="must end in SpatialFree"):
        SpatialBeamTree("bad", [SpatialClamped("r"), beam("m", 1.0), SpatialPointLoad("p"), SpatialFree("e")],
                        {"p": [beam("b", 1.0), Elastic("spring", 10.0)]})
