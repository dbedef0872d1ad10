"""The tangent of kinematic-loop models on the constraint manifold (:func:`ctmm.loop_manifold.accurate_tangent`):
Richardson-extrapolated differences with an error estimate, refused by name where the closed-loop accelerations are
not smooth (issue 16).  The accuracy against independent references is checked where the references are:
``test_flexible_station_cut.py``, ``test_fem_cut_joints.py``, ``test_spatial_closed_loops.py``,
``test_spatial_cut_joint_laws.py``."""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.nonlinear_laws import CallableLaw, LinearLaw
from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel
from ctmm.spatial import closed_loop_linear as linear
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

REST = -1.3


def four_bar(law) -> KinematicLoopModel:
    links = {name: RigidBody.uniform_link(name, mass=mass, length=length)
             for name, mass, length in (("crank", 0.4, 0.2), ("coupler", 0.6, 0.7), ("rocker", 0.8, 0.5))}
    tree = PlanarModel("four_bar_tangent", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.7, 0.0)),
        links["crank"], SmoothHinge("h1", parent="g", child="crank"),
        links["coupler"], SmoothHinge("h2", parent="crank", child="coupler"),
        links["rocker"], SmoothHinge("h4", parent="g4", child="rocker")], gravity=(0.0, -9.81))
    return KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.out", moment_law=law,
                                              rest_angle=REST)])


@pytest.fixture(scope="module")
def spring_equilibrium() -> tuple[KinematicLoopModel, np.ndarray]:
    loop = four_bar(LinearLaw(3.0, 0.0))
    guess, _ = loop.consistent_state([-1.5, 0.5, 1.8], [0.0, 0.0, 0.0], keep=["crank.theta"])
    return loop, loop.equilibrium(guess)


def test_the_tangent_carries_a_small_error_estimate_and_agrees_with_fine_central_differences(spring_equilibrium):
    """A smooth model: the estimate is far below the tolerance, reported as ``jacobian_error``, and the tangent agrees
    with plain central differences to their own ``O(h^2)`` error (step 1e-5: measured 4e-14 of ``max |A|``; step
    1e-3: 4e-7)."""
    loop, q_eq = spring_equilibrium
    A, basis, q0, error = loop.resting_tangent(q_eq)
    assert error < 1e-9
    lin = ctmm.linearize(loop, (q_eq, np.zeros(3)), inputs=["h1.torque"])
    assert lin.operating_point.jacobian_error == error
    central, _, _ = loop.linearize(q_eq, step=1e-5)
    coarse, _, _ = loop.linearize(q_eq, step=1e-3)
    assert np.max(np.abs(A - central)) < 1e-9 * np.max(np.abs(A))
    assert np.max(np.abs(A - coarse)) > 10.0 * np.max(np.abs(A - central))      # the comparison can tell steps apart
    with pytest.raises(ModelError, match="step"):
        loop.linearize(q_eq, step=-1e-5)


def test_a_kink_at_the_equilibrium_is_refused_by_name(spring_equilibrium):
    """The same equilibrium with ``2 |delta - delta_eq|`` added to the cut spring (zero there, so still an equilibrium,
    but the stiffness jumps by 4 N m/rad across it): no tangent exists, and the linear verbs refuse by name instead of
    returning the mean slope."""
    loop, q_eq = spring_equilibrium
    delta_eq = float(loop.relative_angles(q_eq, np.zeros(3))[0][0]) - REST
    kinked = four_bar(CallableLaw(lambda d, v: 3.0 * d + 2.0 * abs(d - delta_eq), name="kinked spring"))
    assert np.max(np.abs(kinked.solve(q_eq, np.zeros(3))[0])) < 1e-9
    with pytest.raises(ModelError, match=r"four_bar_tangent.*tangent on the constraint manifold is not accurate"):
        kinked.natural_frequencies(q_eq)
    with pytest.raises(ModelError, match="not accurate"):
        ctmm.linearize(kinked, (q_eq, np.zeros(3)), inputs=["h1.torque"])


def hinged(law) -> SpatialKinematicLoopModel:
    """A body on a free joint held at the ground by a revolute cut about world y with ``law`` (1 DOF)."""
    tree = sp.SpatialModel("hinged_tangent", [
        sp.SpatialBody("p", 1.2, np.diag([0.02, 0.03, 0.025]), center_of_mass=(0.1, 0.0, -0.3)),
        sp.Free(name="free", parent=None, child="p")])
    return SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="hinge", parent=None, child="p", kind="revolute",
                                                            axis=(0, 1, 0), law=law, rest=0.2)])


def test_spatial_tangent_error_is_the_linearisation_s_and_a_kink_is_refused():
    """The spatial loops share the tangent: its estimate is ``ctmm.linearize``'s ``jacobian_error`` (small), plain
    central differences remain available by ``step``; a kink at the equilibrium (``2 |delta - delta_eq|`` added to
    the cut spring) is refused by name."""
    loop = hinged(LinearLaw(2.0, 0.0))
    q, _ = loop.consistent_state({"free.qw": math.cos(0.15), "free.qy": math.sin(0.15)}, {}, keep=[])
    q_eq = linear.equilibrium(loop, q)
    error = linear.tangent_error(loop, q_eq)
    assert error < 1e-9
    assert ctmm.linearize(loop, q_eq, inputs=["hinge.torque"]).operating_point.jacobian_error == error
    A = linear.tangent(loop, q_eq)[0]
    assert np.max(np.abs(A - linear.tangent(loop, q_eq, step=1e-5)[0])) < 1e-8 * np.max(np.abs(A))
    delta_eq = float(loop.cut_coordinates(q_eq, np.zeros(6))[0][0]) - 0.2
    kinked = hinged(CallableLaw(lambda d, v: 2.0 * d + 2.0 * abs(d - delta_eq), name="kinked spring"))
    with pytest.raises(ModelError, match=r"hinged_tangent.*tangent on the constraint manifold is not accurate"):
        linear.natural_frequencies(kinked, q_eq)
