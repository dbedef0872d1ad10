"""Generated spatial kinematic loops with cuts at deformable points (ctmm.compiled_spatial_cut_points).

A cut pinning or hinging a SpatialBeam's tip or station, or a ctmm.fem spatial subsystem node, runs in the generated
RK4 with projection: the point is placed by the numpy path's own ``ctmm.spatial.cut_points.side_point`` traced on
casadi scalars, the cut force goes through the body's own load path, so the generated run equals the numpy one to
round-off; revolute and universal cuts there read the cross-section's axes by the traced ``side_frame``.
Independent reference at the numpy path's bound: the beam's Lagrange multiplier model
(``ctmm.reference.spatial_beam_lagrange``, tests/test_spatial_cut_points.py: 1e-7 at 2 ms over 20 ms), pinned and
hinged.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from test_spatial_cut_points import (BEAM, PinnedBeamReference, _reference_run, assembled, beam_loop, beam_state,
                                     hinged_tip)


def _agree(loop, generated, plain, rate_bound: float) -> None:
    """Coordinates to 1e-12 of their scale (at least 1), rates to ``rate_bound`` of the largest rate."""
    assert generated.info["compiled"] is True
    np.testing.assert_array_equal(generated.time, plain.time)
    for name in loop.tree.coordinates:
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-12 * max(1.0, np.max(np.abs(plain[name]))), name
    largest = max(np.max(np.abs(plain[name])) for name in loop.tree.velocities)
    for name in loop.tree.velocities:
        assert np.max(np.abs(generated[name] - plain[name])) <= rate_bound * largest, name
    assert np.max(generated["drift"]) < 1e-12


@pytest.mark.parametrize("station, x", [("tip", BEAM["length"]), ("p", 0.7)])
def test_pinned_beam_point_equals_the_numpy_rk4(station, x):
    q0, u0 = beam_state(4)
    u0, p0 = assembled(PinnedBeamReference(True, x), q0, u0)
    loop = beam_loop(True, station, p0)
    generated = ctmm.simulate(loop, 0.02, 1e-3, x0=q0, v0=u0, compiled=True)
    _agree(loop, generated, ctmm.simulate(loop, 0.02, 1e-3, x0=q0, v0=u0), 1e-14)
    assert np.ptp(generated["b.qy2"]) > 1e-3                                    # it bends


def test_pinned_beam_tip_matches_the_lagrange_multiplier_model():
    """At the numpy path's bound (1e-7 at 2 ms against the reference's RK4 at 0.5 ms, with geometric stiffening)."""
    q0, u0 = beam_state(4)
    reference = PinnedBeamReference(True, BEAM["length"])
    u0, p0 = assembled(reference, q0, u0)
    loop = beam_loop(True, "tip", p0)
    exact = _reference_run(reference, q0, u0, 0.02, 40)
    run = ctmm.simulate(loop, 0.02, 2e-3, x0=q0, v0=u0, compiled=True)
    final = np.array([run[name][-1] for name in loop.tree.coordinates])
    assert np.abs(final - exact[:7]).max() < 1e-7


@pytest.mark.parametrize("kind", ["revolute", "universal"])
def test_hinged_beam_tip_equals_the_numpy_rk4(kind):
    """The alignment rows read the tip's cross-section axes (side_frame traced)."""
    q0, u0 = beam_state(4)
    reference, options = hinged_tip(q0, kind)
    u0, p0 = assembled(reference, q0, u0)
    loop = beam_loop(True, "tip", p0, **options)
    generated = ctmm.simulate(loop, 0.02, 1e-3, x0=q0, v0=u0, compiled=True)
    _agree(loop, generated, ctmm.simulate(loop, 0.02, 1e-3, x0=q0, v0=u0), 1e-14)
    assert np.ptp(generated["b.twist1"]) > 1e-4


def test_hinged_beam_tip_matches_the_lagrange_multiplier_model():
    """At the numpy path's bound (tests/test_spatial_cut_points.py: 1e-7 at 2 ms over 20 ms)."""
    q0, u0 = beam_state(4)
    reference, options = hinged_tip(q0)
    u0, p0 = assembled(reference, q0, u0)
    loop = beam_loop(True, "tip", p0, **options)
    exact = _reference_run(reference, q0, u0, 0.02, 40)
    run = ctmm.simulate(loop, 0.02, 2e-3, x0=q0, v0=u0, compiled=True)
    final = np.array([run[name][-1] for name in loop.tree.coordinates])
    assert np.abs(final - exact[:7]).max() < 1e-7


def test_pd_loop_on_the_pinned_beam_equals_the_numpy_driver():
    """The loop-closing driver's generated run (ctmm.compiled_kinematic_loop_control on the same closed-loop rates):
    a delayed PD on the hub's yaw driving a moment on the hub and a harmonic force on the beam's station, with the
    beam tip pinned, = the numpy driver to 1e-12 for every stored signal."""
    from ctmm.control import Feedback, with_feedback
    from ctmm.signals import Harmonic
    from test_compiled_kinematic_loop_control import _equal, _numpy

    q0, u0 = beam_state(4)
    u0, p0 = assembled(PinnedBeamReference(True, BEAM["length"]), q0, u0)
    loop = beam_loop(True, "tip", p0)
    pd = Feedback("pd", sensor=[("yaw.angle", 4.0), ("yaw.rate", 0.4)], actuator="hub.moment_z", gain=1.0,
                  delay=2e-3)
    options = dict(x0=q0, v0=u0, references={"pd": 4.0 * (q0[0] + 0.1)}, outputs=["yaw.angle"],
                   inputs={"b.p.force_z": Harmonic(0.5, 40.0)})
    generated = ctmm.simulate(with_feedback(loop, [pd]), 0.02, 1e-3, compiled=True, **options)
    _equal(generated, _numpy(with_feedback(loop, [pd]), 0.02, 1e-3, **options))
    assert np.ptp(generated["pd.u"]) > 0.05


def test_hinged_subsystem_node_equals_the_numpy_rk4():
    """A revolute cut at the L-frame's node n3 (the node's position and its rotation DOFs turning its axes), as
    tests/test_spatial_cut_points.py states it: = the numpy RK4; the frame's top frequencies (~3e3 rad/s) scale the
    round-off of the two orders of operations: rates to 1e-11 of the largest."""
    from ctmm.spatial import SpatialCutJoint, SpatialKinematicLoopModel
    from test_spatial_cut_points import hinged_node

    model, ref, q, rng, p0, a = hinged_node()
    loop = SpatialKinematicLoopModel(model, [SpatialCutJoint(name="hinge", parent=None, point=tuple(p0), child="frame",
                                                             child_point="n3", kind="revolute", axis=(1, 0, 0),
                                                             parent_axis=tuple(a))])
    J = np.column_stack([loop.constraints(q, np.eye(ref.n)[k])[1] for k in range(ref.n)])
    N = np.linalg.svd(J)[2][5:].T
    v0 = N @ (N.T @ rng.normal(size=ref.n))
    generated = ctmm.simulate(loop, 0.0025, 2.5e-4, x0=q, v0=v0, compiled=True)
    _agree(loop, generated, ctmm.simulate(loop, 0.0025, 2.5e-4, x0=q, v0=v0), 1e-11)
