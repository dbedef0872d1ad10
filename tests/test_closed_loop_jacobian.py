"""The constraint Jacobian ``J = dPhi/dq`` of planar kinematic loop models (``KinematicLoopModel.jacobian``).

``J`` is built in one pass from the tree's rate maps (``CutPoints.rate_maps``).  Independent references, at
coordinates off the constraint manifold and at a time where every prescribed rate is nonzero:

* a central difference of the positions ``Phi(q)`` alone (no rate code at all);
* the former construction, written here: ``Phi'`` is affine in ``qdot``, so column ``k`` is
  ``Phi'(q, e_k) - Phi'(q, 0)`` (the tree's velocity recursion, :meth:`PlanarModel.points`);
* ``Phi'(q, qdot) = J qdot + Phi'(q, 0)`` for a random ``qdot``.

The models cover every kind of side and tree joint the rate maps follow: ground, rigid-body points, a modal beam's
end with foreshortening (second-order inertia: the children on the beam end too) or axial modes, a driven hinge
on a beam end (its slope), a hinge with translational springs, a free base, a ``ctmm.fem`` subsystem node, and a
driven cut (its angle row).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.flexible import ModalBeam
from ctmm.planar import DrivenHinge, ElasticHinge, Fixed, FreeBase, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel
from test_fem_cut_joints import fe_four_bar

T = 0.3                                                     # [s]: every prescribed rate nonzero here


def _drive(phase: float) -> dict:
    return dict(angle=lambda t: phase + 0.4 * math.sin(3.0 * t), rate=lambda t: 1.2 * math.cos(3.0 * t),
                acceleration=lambda t: -3.6 * math.sin(3.0 * t))


def _cut_drive() -> dict:
    return dict(angle=lambda t: 1.9 + 0.4 * math.sin(3.0 * t), angle_rate=lambda t: 1.2 * math.cos(3.0 * t),
                angle_acceleration=lambda t: -3.6 * math.sin(3.0 * t))


def _flexible(second_order: bool) -> KinematicLoopModel:
    """A crank, a modal coupler (2 bending modes; with second-order inertia, else 1 axial mode; two outboard
    stations) with a rigid tab driven on its middle station, a rocker: cut between the rocker tip and the coupler's
    end (driven angle across it), and a second cut from the tab's tip to the ground."""
    axial = {} if second_order else {"n_axial_modes": 1, "axial_stiffness": 2e3}
    coupler = ModalBeam("coupler", length=0.6, bending_stiffness=40.0, mass_per_length=1.0 / 0.6, n_modes=2,
                        second_order_inertia=second_order, outboard={"mid": 0.3, "out": 0.6}, **axial)
    tree = PlanarModel("jacobian_flexible", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.7, 0.0)), Fixed("g5", position=(0.3, 0.4)),
        RigidBody.uniform_link("crank", mass=0.4, length=0.2), SmoothHinge("h1", parent="g", child="crank"),
        coupler, SmoothHinge("h2", parent="crank", child="coupler"),
        RigidBody.uniform_link("tab", mass=0.1, length=0.15),
        DrivenHinge("hd", parent="coupler.mid", child="tab", **_drive(0.8)),
        RigidBody.uniform_link("rocker", mass=0.8, length=0.5), SmoothHinge("h4", parent="g4", child="rocker")],
        gravity=(0.0, -9.81))
    return KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.out", **_cut_drive()),
                                     CutJoint("h5", parent="g5", child="tab.out")])


def _rigid() -> KinematicLoopModel:
    """A free-floating link, a link on a hinge with translational springs, a driven link on it: cuts close the
    floating link to the ground and the driven link to the floating one."""
    tree = PlanarModel("jacobian_rigid", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g2", position=(0.5, 0.1)),
        FreeBase("base", child="float"), RigidBody.uniform_link("float", mass=0.5, length=0.4),
        RigidBody.uniform_link("a", mass=0.3, length=0.3),
        ElasticHinge("ha", parent="g", child="a", stiffness=2.0, translational_stiffness=300.0),
        RigidBody.uniform_link("b", mass=0.2, length=0.25), DrivenHinge("hb", parent="a", child="b", **_drive(0.5))],
        gravity=(0.0, -9.81))
    return KinematicLoopModel(tree, [CutJoint("c1", parent="g2", child="float.out"),
                                     CutJoint("c2", parent="float.out", child="b.out")])


def _finite_element() -> KinematicLoopModel:
    """The four-bar of ``test_fem_cut_joints`` with its coupler a two-element ``ctmm.fem`` subsystem, cut at its
    outboard boundary node (its rotation: a driven angle across the cut)."""
    tree = fe_four_bar(2).tree
    return KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.n2", **_cut_drive())])


def _column_differences(loop: KinematicLoopModel, q: np.ndarray, t: float) -> np.ndarray:
    """The former construction: ``Phi'(q, e_k) - Phi'(q, 0)`` column by column."""
    n = loop.tree.n_coordinates
    offset = loop.constraints(q, np.zeros(n), t)[1]
    return np.column_stack([loop.constraints(q, unit, t)[1] - offset for unit in np.eye(n)])


def _central_difference(loop: KinematicLoopModel, q: np.ndarray, t: float, h: float = 1e-6) -> np.ndarray:
    """``dPhi/dq`` by central differences of the positions ``Phi(q)`` alone."""
    zero = np.zeros(loop.tree.n_coordinates)
    return np.column_stack([(loop.constraints(q + h * e, zero, t)[0] - loop.constraints(q - h * e, zero, t)[0])
                            / (2 * h) for e in np.eye(len(q))])


@pytest.mark.parametrize("build", [lambda: _flexible(True), lambda: _flexible(False), _rigid, _finite_element],
                         ids=["modal_beam_second_order", "modal_beam_axial", "rigid", "fem"])
def test_jacobian_matches_the_positions_and_the_rates(build):
    loop = build()
    rng = np.random.default_rng(14)
    n = loop.tree.n_coordinates
    q, qdot = rng.uniform(-0.6, 0.6, n) + 0.3, rng.normal(size=n)
    J = loop.jacobian(q, T)
    rows = sum(3 if cut.driven else 2 for cut in loop.cuts)
    assert J.shape == (rows, n)
    scale = float(np.max(np.abs(J)))
    # the former column-by-column construction: the same to round-off (measured <= 1.2e-16 of max |J|)
    np.testing.assert_allclose(J, _column_differences(loop, q, T), rtol=0.0, atol=1e-14 * scale)
    # positions alone (central difference, truncation ~h^2, round-off ~1e-16 / h): measured <= 1e-10 of max |J|;
    # the former construction without the offset of a driven tree hinge was 17 % off here (rigid)
    np.testing.assert_allclose(J, _central_difference(loop, q, T), rtol=0.0, atol=1e-8 * scale)
    # Phi' is affine in qdot with this J (the offset: the prescribed rates, nonzero here)
    offset = loop.constraints(q, np.zeros(n), T)[1]
    assert np.max(np.abs(offset)) > 0.1
    np.testing.assert_allclose(loop.constraints(q, qdot, T)[1], J @ qdot + offset, rtol=0.0, atol=1e-13 * scale)
