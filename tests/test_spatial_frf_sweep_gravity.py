"""Spatial frequency responses by the one sweep about preloaded equilibria (gravity, static loads): the joint
coupling of ctmm.articulated (the geometric stiffness of the static joint wrench as the joint's directions turn
with the parent, and the shifted reference point of a sliding joint) and the rotation columns of the body terms.

Independent references: the global Newton-Euler linearisation ``M, C, K`` of ``ctmm/reference/spatial_tree.py``
(its ``K`` by complex step of its own generalised forces through its retraction, gravity and world point loads
included) and the assumed-modes Lagrange model ``ctmm/reference/spatial_beam_lagrange.py`` (hub + beam + tip) in
gravity.  Second path: the dense resolvent of ``ctmm.linearize`` (also with loops closed per frequency, with and
without delay).  Tolerance 1e-9 of each (output, input) pair's
largest entry, away from poles.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.controlled_linearization import FrequencyAtPoleError
from ctmm.errors import ModelError
from ctmm.reference import spatial_tree as ref
from ctmm.reference.spatial_beam_lagrange import SpatialBeamLagrange
from ctmm.spatial_linearization import operating_point, tangent_names
from spatial_linear_helpers import elastic_hinge_body, random_spring_tree, reference_configuration, reference_tree
from test_spatial_frf_sweep import DENSE, OMEGA, SWEEP, assert_close, dense, hub_beam, joint_torques

GRAVITY = (0.3, -1.0, -9.81)


def reference_response(tree, q_reference, omega, forcing):
    mass, damping, stiffness = ref.linearize(tree, q_reference)
    return np.stack([np.linalg.solve(stiffness + 1j * w * damping - w * w * mass, forcing) for w in omega], axis=-1)


@pytest.mark.parametrize("seed, base, n", [(11, "universal", 5), (5, "revolute", 7), (3, "universal", 7)])
def test_gravity_loaded_trees_equal_the_newton_euler_reference(seed, base, n):
    """Revolute, universal, prismatic (children: the shifted point), unsprung spherical and weld joints under
    gravity, every spring deflected at the equilibrium."""
    model = random_spring_tree(np.random.default_rng(seed), n, base)
    point = operating_point(model)
    inputs, forcing = joint_torques(model)
    outputs = list(tangent_names(model))
    frf = ctmm.frequency_response(model, OMEGA, input=inputs, output=outputs)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    expected = reference_response(reference_tree(model), reference_configuration(model, point.q), OMEGA, forcing)
    assert_close(frf.response, expected, 1e-9)
    if seed == 11:
        assert_close(frf.response, dense(model, (), OMEGA, inputs, outputs, point), 1e-9)


def test_static_loads_equal_the_reference_and_the_dense_path():
    """A world-axes force and moment at a body point (the reference's PointLoad) and a body-axes load (it turns
    with its body: the dense path) on top of gravity."""
    model = random_spring_tree(np.random.default_rng(5), 7, "revolute")
    push = sp.Load("push", "b4", point="p2", force=(1.5, -2.0, 0.7), moment=(0.3, 0.2, -0.4))
    loaded = sp.SpatialModel("loaded", list(model.bodies) + list(model.joints) + [push], gravity=model.gravity)
    point = operating_point(loaded)
    inputs, forcing = joint_torques(loaded)
    outputs = list(tangent_names(loaded))
    frf = ctmm.frequency_response(loaded, OMEGA, input=inputs, output=outputs)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    index = [body.name for body in loaded.bodies].index("b4")              # bodies in topological order
    tree = dataclasses.replace(reference_tree(loaded), loads=(ref.PointLoad(index, loaded.bodies[index].points["p2"],
                                                                            push.values(0.0)[:3],
                                                                            push.values(0.0)[3:]),))
    assert_close(frf.response, reference_response(tree, reference_configuration(loaded, point.q), OMEGA, forcing),
                 1e-9)
    turning = sp.Load("turning", "b2", point="p0", force=(0.0, 3.0, -1.0), moment=(0.5, 0.0, 0.2), axes="body")
    body_axes = sp.SpatialModel("body_axes", list(model.bodies) + list(model.joints) + [turning],
                                gravity=model.gravity)
    point = operating_point(body_axes)
    inputs = ["j1.torque", "b3.p1.force_body_y", "b5.moment_z"]
    outputs = ["j1.angle", "j2.angle2", "b6.origin.vy"] + outputs[-2:]
    frf = ctmm.frequency_response(body_axes, OMEGA, input=inputs, output=outputs)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    assert_close(frf.response, dense(body_axes, (), OMEGA, inputs, outputs, point), 1e-9)


def test_hub_beam_in_gravity_equals_the_lagrange_model():
    model, reference = hub_beam(((0, 0, 1),))
    loaded = sp.SpatialModel("hub_beam_g", list(model.bodies) + list(model.joints), gravity=GRAVITY)
    reference = SpatialBeamLagrange(dataclasses.replace(reference.p, gravity=GRAVITY))
    point = operating_point(loaded)
    assert np.max(np.abs(point.q)) > 1e-3                      # gravity deflects the hub and the beam
    n = loaded.n_velocities
    A, B, _ = reference.linearize(point.q)
    frf = ctmm.frequency_response(loaded, OMEGA, input="hubj.torque", output=list(tangent_names(loaded)))
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    expected = np.stack([np.linalg.solve(1j * w * np.eye(2 * n) - A, B[:, :1])[:n] for w in OMEGA], axis=-1)
    assert_close(frf.response, expected, 1e-9)


def test_a_pole_in_gravity_is_handed_back_and_elastic_hinges_take_the_dense_path():
    undamped = random_spring_tree(np.random.default_rng(11), 4, "universal", damped=False)
    first = ctmm.natural_frequencies(undamped, n_modes=4)
    first = first[first > 1e-6][2]      # (the first two: the ball joint's pendulum, weakly coupled to j1)
    # next to an undamped pole of the loaded tree: the base pivot closes, the resolvent gets it and refuses it
    with pytest.raises(FrequencyAtPoleError, match="singular at omega"):
        ctmm.frequency_response(undamped, [0.5 * first, first * (1.0 + 1e-12)], input="j1.torque", output="j1.angle")
    frf = ctmm.frequency_response(undamped, [0.5 * first, first * (1.0 + 1e-5)], input="j1.torque", output="j1.angle")
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    with pytest.raises(ModelError, match="singular at omega = 0.0"):      # the free yaw of a ball joint
        ctmm.frequency_response(undamped, [0.0, 1.0], input="j1.torque", output="j1.angle")
    hinge = elastic_hinge_body()
    names = list(tangent_names(hinge))
    frf = ctmm.frequency_response(hinge, OMEGA[:2], input=list(sp.ports.SpatialPorts(hinge).actuators)[:1],
                                  output=names[:1])
    assert frf.info["method"] == DENSE


def test_the_joint_coupling_is_the_same_on_casadi():
    """The coupled sweep of a loaded tree (universal, revolute, prismatic child: ``G`` and ``H`` both present) at
    one real ``s^2 = -omega^2``, written once in ctmm.ops: casadi constants give the numpy numbers."""
    import casadi

    from ctmm.articulated import articulated_sweep, frequency_kappa
    from ctmm.ops import CASADI, NUMPY
    from ctmm.protocol import BodyTerms
    from ctmm.spatial_transfer_response import SpatialSweepResponse

    model = random_spring_tree(np.random.default_rng(5), 7, "revolute")
    plant = SpatialSweepResponse(model, operating_point(model))
    assert plant.coupling is not None and any(c is not None and c[1] is not None for c in plant.coupling)
    loads, joints = plant.loads("j1.torque")
    squared = -1.7 ** 2
    bodies = [BodyTerms((squared * M0 + K0)[None], h, Kin, dict.fromkeys(Kin), RF)
              for (M0, _, K0, Kin, RF), h in zip(plant.bodies, loads)]
    kappa = frequency_kappa(NUMPY, joints, 0.0)
    expected = articulated_sweep(NUMPY, plant.tree, bodies, joints, kappa, forces=False, coupling=plant.coupling)

    def symbolic(value):
        if isinstance(value, dict):
            return {key: symbolic(entry) for key, entry in value.items()}
        if isinstance(value, tuple):
            return tuple(symbolic(entry) for entry in value)
        if isinstance(value, np.ndarray):
            return casadi.SX(np.asarray(value[0] if value.ndim == 3 else value, dtype=float))
        return value

    def converted(items):
        return [dataclasses.replace(item, **{f.name: symbolic(getattr(item, f.name)) for f in dataclasses.fields(item)
                                             if f.name != "axis"}) for item in items]

    got = articulated_sweep(CASADI, plant.tree, converted(bodies), converted(joints), [symbolic(k) for k in kappa],
                            forces=False, coupling=[symbolic(c) for c in plant.coupling])
    for x_numpy, x_casadi in zip(expected.x, got.x):
        value = np.array(casadi.evalf(x_casadi))
        assert np.max(np.abs(value - x_numpy[0])) <= 1e-12 * (1.0 + np.max(np.abs(x_numpy)))


@pytest.mark.parametrize("delay", [0.04, 0.0])
def test_loops_closed_per_frequency_about_a_loaded_tree_equal_the_dense_path(delay):
    from ctmm.control import Feedback, with_feedback

    model = random_spring_tree(np.random.default_rng(11), 5, "universal")
    loop = Feedback("pd", sensor=[("j1.angle", 6.0), ("j1.rate", 0.5)], actuator="j1.torque", gain=1.0, delay=delay)
    inputs, outputs = ["j0.torque1", "pd.reference"], ["j2.angle1", "pd.u"]
    frf = ctmm.frequency_response(with_feedback(model, [loop]), OMEGA, input=inputs, output=outputs)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    assert_close(frf.response, dense(model, [loop], OMEGA, inputs, outputs, operating_point(model)), 1e-9)
