"""The one rigid sweep over a batch of applied terms, and a kinematic loop's unit loads as that one batch.

A kinematic loop's rate (:meth:`ctmm.planar.closed_loops.KinematicLoopModel.solve_loads`) needs the tree's sweep
without cut loads and with each unit cut load at one state: on a tree without deformable bodies these run as one
call of the traced sweep mapped over the batch (:meth:`ctmm.planar.rigid_sweep.RigidTreeSweep.batch`,
:func:`ctmm.planar.sweep.solve_instant_batch`).  Checked here: every row of a batch is bitwise the single sweep with
that row's terms (and, independently, the numpy evaluation of the sweep to round-off); a singular hinge is named as
by the single sweep; :func:`solve_instant_batch` equals :func:`solve_instant` row by row on rigid, translational-
spring and flexible trees; the batched loop rate equals the per-load route bitwise (rigid four-bar with a cut law,
a driven cut, a two-loop linkage) and is safe in threads.  The loop rates against the global DAE: tests/test_closed_loops.py.
"""
from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from ctmm.errors import SimulationError
from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel
from ctmm.planar.model import REVOLUTE
from ctmm.planar.ports import ActuatorInputs
from ctmm.planar.rigid_sweep import RigidTreeSweep, model_sweep
from ctmm.planar.sweep import body_terms, hinge_torques, solve_instant, solve_instant_batch
from ctmm.scenarios import four_bar
from planar_helpers import random_state, random_tree


@pytest.mark.parametrize("seed", range(3))
def test_batch_rows_are_the_single_sweeps_and_the_numpy_sweep(seed):
    model = random_tree(seed, 6, allow_translation=False)
    q, v, t = random_state(model, seed)
    theta, omega = model.body_angles(q, v, t)
    K, b, E, _ = body_terms(model, theta, omega, t)
    tau = hinge_torques(model, theta, omega, t)
    rng = np.random.default_rng(seed)
    kappa, driven = rng.uniform(0.0, 2.0, model.n_bodies), rng.normal(size=model.n_bodies)
    bs, taus = b + rng.normal(size=(4, model.n_bodies, 3)), tau + rng.normal(size=(4, model.n_bodies))
    sweep = model_sweep(model)
    A, F, alpha = sweep.batch(K, bs, E, kappa, taus, driven)
    assert A.shape == F.shape == (4, model.n_bodies, 3) and alpha.shape == (4, model.n_bodies)
    for k in range(4):
        single = sweep(K, bs[k], E, kappa, taus[k], driven)
        assert all(np.array_equal(x[k], y) for x, y in zip((A, F, alpha), single))
        reference = sweep.numpy_sweep(K, bs[k], E, kappa, taus[k], driven)
        assert all(np.max(np.abs(x[k] - y)) <= 1e-13 * np.max(np.abs(y)) for x, y in zip((A, F), reference))
    complex_rows = sweep.batch(K.astype(complex), bs, E, kappa, taus, driven)        # the numpy evaluation
    for k in range(4):
        single = sweep(K.astype(complex), bs[k], E, kappa, taus[k], driven)
        assert all(np.array_equal(x[k], y) for x, y in zip(complex_rows, single))


def test_batch_names_a_singular_hinge():
    sweep = RigidTreeSweep([-1, 0], [REVOLUTE, REVOLUTE], ["a", "b"])
    K = np.tile(np.diag([1.0, 1.0, 0.5]).reshape(1, 9), (2, 1))
    K[1, 8] = 0.0                                  # body "b": no inertia about its hinge
    for dtype in (float, complex):
        with pytest.raises(SimulationError, match=r"articulated inertia of joint 'b' is singular"):
            sweep.batch(K.astype(dtype), np.zeros((3, 2, 3)), np.zeros((2, 6)), np.zeros(2), np.ones((3, 2)),
                        np.zeros(2))


def _batch_inputs(model: PlanarModel, rng, count: int) -> ActuatorInputs:
    modal = {j: rng.normal(size=(count, len(model.modal_index[j]))) for j in model.beams}
    frame = {j: rng.normal(size=(count, 3)) for j in model.beams}
    return ActuatorInputs(rng.normal(size=(count, model.n_bodies)), rng.normal(size=(count, model.n_bodies, 3)),
                          modal, frame)


@pytest.mark.parametrize("which", ["rigid", "translational springs", "flexible"])
def test_solve_instant_batch_rows_equal_solve_instant(which):
    model = {"rigid": lambda: random_tree(4, 5, allow_translation=False),
             "translational springs": lambda: random_tree(4, 4, allow_driven=False),
             "flexible": lambda: four_bar.flexible_mechanism(80.0, n_modes=3).tree}[which]()
    rng = np.random.default_rng(7)
    q, v = rng.normal(0.0, 0.3, model.n_coordinates), rng.normal(0.0, 0.5, model.n_coordinates)
    inputs = _batch_inputs(model, rng, 3)
    if which == "translational springs":
        assert len(model.bushing_bodies)
    batch = solve_instant_batch(model, q, v, 0.2, inputs)
    for k in range(3):
        row = ActuatorInputs(inputs.hinge_torque[k], inputs.body_force[k],
                             {j: x[k] for j, x in inputs.modal_force.items()},
                             {j: x[k] for j, x in inputs.frame_wrench.items()})
        single = solve_instant(model, q, v, 0.2, row)
        assert np.array_equal(batch.qddot[k], single.qddot)
        assert np.array_equal(batch.body_acceleration[k], single.body_acceleration)
        assert np.array_equal(batch.joint_force[k], single.joint_force)


def _two_loop() -> KinematicLoopModel:
    """A six-bar: the four-bar plus a second loop from the rocker's tip to a ground pivot."""
    link = RigidBody.uniform_link
    tree = PlanarModel("six_bar", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.4, 0.0)), Fixed("g6", position=(0.9, 0.3)),
        link("crank", mass=0.4, length=0.2), SmoothHinge("h1", parent="g", child="crank"),
        link("coupler", mass=1.0, length=0.6), SmoothHinge("h2", parent="crank", child="coupler"),
        link("rocker", mass=0.8, length=0.5), SmoothHinge("h4", parent="g4", child="rocker"),
        link("e", mass=0.3, length=0.5), SmoothHinge("h5", parent="rocker", child="e"),
        link("f", mass=0.3, length=0.5), SmoothHinge("h7", parent="g6", child="f")], gravity=(0.0, -9.81))
    return KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.out"),
                                     CutJoint("h6", parent="f.out", child="e.out")])


def _driven_cut() -> KinematicLoopModel:
    tree = four_bar.mechanism().tree
    return KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.out",
                                              angle=lambda t: 1.9 + 0.1 * math.sin(t),
                                              angle_rate=lambda t: 0.1 * math.cos(t),
                                              angle_acceleration=lambda t: -0.1 * math.sin(t))])


@pytest.mark.parametrize("build", [lambda: four_bar.mechanism(four_bar.SPRING + four_bar.DAMPER), _driven_cut,
                                   _two_loop], ids=["four_bar_law", "driven_cut", "two_loop"])
def test_batched_loop_rate_equals_the_per_load_route(build):
    batched, single = build(), build()
    assert batched._batched
    single._batched = False                         # the route of trees with deformable bodies: one load at a time
    rng = np.random.default_rng(11)
    n = batched.tree.n_coordinates
    for t in (0.0, 0.3):
        q, v = rng.normal(0.0, 0.4, n) + 1.0, rng.normal(0.0, 1.0, n)
        inputs = ActuatorInputs(rng.normal(size=batched.tree.n_bodies), rng.normal(size=(batched.tree.n_bodies, 3)))
        for given in (None, inputs):
            qdd, loads = batched.solve_loads(q, v, t, given)
            qdd_single, loads_single = single.solve_loads(q, v, t, given)
            assert np.array_equal(qdd, qdd_single) and np.array_equal(loads, loads_single)


def test_batched_loop_rate_is_safe_in_threads():
    """The mapped sweep runs through one buffer per thread and batch size: concurrent rates give the serial ones."""
    loop = _two_loop()
    rng = np.random.default_rng(2)
    states = [(rng.normal(0.0, 0.4, 5) + 1.0, rng.normal(0.0, 1.0, 5)) for _ in range(24)]
    serial = [loop.solve_loads(q, v, 0.1)[0] for q, v in states]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(lambda state: loop.solve_loads(*state, 0.1)[0], states))
    assert all(np.array_equal(a, b) for a, b in zip(threaded, serial))
