"""The numpy fast paths of the spatial body terms (filled arrays, stacked beam loads) against the one ops statement
of the same terms evaluated on casadi numbers (``CASADI`` ops on ``DM`` values: the generic path, no fill), for a
batch of three states: a rigid body with an offset, an angular velocity, two points and two loads, and the 3-D
flexible manipulator's forearm (stiffened modal beam) with its patch moments in body axes, a child point and its
frame."""
from __future__ import annotations

import casadi
import numpy as np

from ctmm.ops import CASADI, NUMPY
from ctmm.spatial.beam_terms import spatial_beam_terms
from ctmm.spatial.body_forms import rigid_body_terms

RNG = np.random.default_rng(7)


def _rotations(count: int) -> np.ndarray:
    """Proper rotations from QR factors of random matrices."""
    out = []
    for _ in range(count):
        Q, R = np.linalg.qr(RNG.normal(size=(3, 3)))
        Q = Q @ np.diag(np.sign(np.diag(R)))
        out.append(Q if np.linalg.det(Q) > 0 else -Q)
    return np.array(out)


def _close(numpy_value: np.ndarray, casadi_value, sample: int, what: str) -> None:
    expected = np.array(casadi.DM(casadi_value))
    got = np.asarray(numpy_value)
    got = got[sample] if got.shape[0] > 1 else got[0]
    scale = max(1.0, float(np.abs(expected).max()))
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-13 * scale, err_msg=what)


def _compare(terms_numpy, terms_casadi, sample: int) -> None:
    _close(terms_numpy.M, terms_casadi.M, sample, "M")
    _close(terms_numpy.h, terms_casadi.h, sample, "h")
    for field in ("Kin", "c", "RF"):
        numpy_maps, casadi_maps = getattr(terms_numpy, field), getattr(terms_casadi, field)
        assert set(numpy_maps) == set(casadi_maps)
        for name in numpy_maps:
            _close(numpy_maps[name], casadi_maps[name], sample, f"{field}[{name}]")


def test_rigid_body_terms_numpy_path_equals_the_ops_statement():
    batch = 3
    rotation, offset, omega = _rotations(batch), RNG.normal(size=(batch, 3, 1)), RNG.normal(size=(batch, 3, 1))
    wrenches = [RNG.normal(size=(batch, 6, 1)), RNG.normal(size=(1, 6, 1))]
    numbers = dict(mass=2.5, inertia=np.array([[1.0, 0.1, 0.0], [0.1, 2.0, 0.2], [0.0, 0.2, 3.0]]),
                   center_of_mass=np.array([0.1, -0.2, 0.3]), gravity=np.array([0.0, 0.0, -9.81]),
                   points={"a": np.array([1.0, 0.0, 0.0]), "b": np.array([0.0, 0.5, -0.2])})
    load_points = [np.array([0.5, 0.0, 0.0]), np.array([0.0, 0.0, 0.4])]
    terms = rigid_body_terms(NUMPY, rotation=rotation, offset=offset, omega=omega,
                             loads=list(zip(load_points, wrenches)), **numbers)
    assert terms.M.shape == (batch, 6, 6) and terms.h.shape == (batch, 6, 1)
    for k in range(batch):
        reference = rigid_body_terms(CASADI, rotation=casadi.DM(rotation[k]), offset=casadi.DM(offset[k]),
                                     omega=casadi.DM(omega[k]), **numbers,
                                     loads=[(p, casadi.DM(w[min(k, w.shape[0] - 1)]))
                                            for p, w in zip(load_points, wrenches)])
        _compare(terms, reference, k)
    at_rest = rigid_body_terms(NUMPY, rotation=rotation[:1], offset=None, omega=None, **numbers)
    reference = rigid_body_terms(CASADI, rotation=casadi.DM(rotation[0]), offset=None, omega=None, **numbers)
    _compare(at_rest, reference, 0)


def test_modal_beam_numpy_path_with_stacked_loads_equals_the_ops_statement():
    from scenarios import flexible_manipulator_3d as scene

    beam = scene.plant().bodies[2]
    n, batch = beam.data.n, 3
    assert beam.data.stiffening and beam.data.second_order is None
    rotation, omega = _rotations(batch), RNG.normal(size=(batch, 3, 1))
    eta, eta_dot = RNG.normal(size=(batch, n, 1)) * 0.02, RNG.normal(size=(batch, n, 1))
    stations = [np.array([x, 0.0, 0.0]) for x in (scene.STATIONS["p1"], scene.STATIONS["p2"], 0.6)]
    wrenches = [RNG.normal(size=(batch, 6, 1)) for _ in stations]
    common = dict(beam=beam, t=0.0, gravity=np.array([0.0, 0.0, -9.81]), points={"tip": beam.points["tip"]},
                  frames=("tip",))
    terms, frames = spatial_beam_terms(NUMPY, rotation=rotation, offset=None, omega=omega, eta=eta, eta_dot=eta_dot,
                                       loads=list(zip(stations, wrenches)), **common)
    for k in range(batch):
        reference, reference_frames = spatial_beam_terms(
            CASADI, rotation=casadi.DM(rotation[k]), offset=None, omega=casadi.DM(omega[k]), eta=casadi.DM(eta[k]),
            eta_dot=casadi.DM(eta_dot[k]), loads=[(p, casadi.DM(w[k])) for p, w in zip(stations, wrenches)],
            **common)
        _compare(terms, reference, k)
        for field in ("arm", "velocity", "rotation", "omega"):
            _close(getattr(frames["tip"], field), getattr(reference_frames["tip"], field), k, f"tip {field}")


def _joints():
    """Spherical (with and without its law), free and elastic joints, one actuated, with a 6 x 6 law."""
    import ctmm.spatial as sp

    law6 = np.diag([2.0e4, 1.5e4, 1.0e4, 40.0, 55.0, 30.0])
    law6[3, 4] = law6[4, 3] = 3.0
    common = dict(parent=None, child="b")
    return [sp.Spherical(name="ball", **common), sp.Spherical(name="sprung", stiffness=[2.0, 3.0, 4.0], damping=0.1,
                                                              actuated=True, **common),
            sp.Free(name="free", **common), sp.Free(name="pushed", actuated=True, **common),
            sp.Elastic6(name="hinge", stiffness=law6, damping=np.diag([5.0, 5.0, 5.0, 0.2, 0.3, 0.1]), **common),
            sp.Elastic6(name="driven", stiffness=law6, actuated=True, **common)]


def test_joint_motion_numpy_path_equals_the_ops_statement():
    """The filled numpy path of spherical, free and elastic joints (law, input, prescribed acceleration; a batch of
    three states, its quaternions not unit; real and complex-step values) against the casadi statement per state."""
    from ctmm.spatial.joint_kinematics import joint_motion

    batch = 3
    for joint in _joints():
        nq, nv = joint.coordinate_count, joint.velocity_count
        for dtype in (float, complex):
            q = RNG.normal(size=(batch, nq)) * 0.4 + np.r_[np.zeros(nq - 4), 1.0, 0.0, 0.0, 0.0]
            v = RNG.normal(size=(batch, nv)).astype(dtype)
            if dtype is complex:
                q = q + 1e-20j * RNG.normal(size=q.shape)
            u = RNG.normal(size=(batch, nv, 1)) if joint.inputs else None
            for acceleration in (None, RNG.normal(size=(batch, nv))):
                rows = [q[:, k].reshape(-1, 1, 1) for k in range(nq)]
                rates = [v[:, k].reshape(-1, 1, 1) for k in range(nv)]
                prescribed = None if acceleration is None else [acceleration[:, k].reshape(-1, 1, 1) for k in range(nv)]
                motion = joint_motion(NUMPY, joint, rows, rates, u, prescribed)
                for k in range(batch):
                    reference = joint_motion(CASADI, joint, [casadi.DM(q[k, i].real) for i in range(nq)],
                                             [casadi.DM(v[k, i].real) for i in range(nv)],
                                             None if u is None else casadi.DM(u[k]),
                                             None if acceleration is None else [casadi.DM(a) for a in acceleration[k]])
                    for field in ("rotation", "translation", "S", "bias", "linear", "angular", "tau", "tau_q", "tau_v",
                                  "prescribed"):
                        got, expected = getattr(motion, field), getattr(reference, field)
                        assert (got is None) == (expected is None), (joint.name, field)
                        if got is not None:
                            _close(np.real(got), expected, k, f"{joint.name} {field}")
                            if field in ("rotation", "S", "angular"):          # complex steps kept
                                assert np.result_type(got) == np.result_type(dtype), (joint.name, field)


def test_batch_shape_is_numpys_broadcast_of_the_leads():
    """:func:`ctmm.ops.batch_shape` (the fills' allocation) against ``np.broadcast_shapes`` of the leading shapes,
    and its refusal of leads that do not broadcast."""
    import pytest

    from ctmm.ops import batch_shape

    cases = [[(1, 3, 3), (4, 3, 1)], [(4, 3, 3), (4, 6, 1)], [(1, 3, 3), (1, 2, 2)], [(4, 3, 3), (1, 3, 3), (4, 1, 1)],
             [(3, 3), (2, 3, 3)], [(2, 5, 3, 3), (5, 3, 1)], [(3, 3), (3, 1)]]
    for shapes in cases:
        arrays = [np.zeros(shape) for shape in shapes]
        assert batch_shape(*arrays) == np.broadcast_shapes(*(shape[:-2] for shape in shapes)), shapes
    with pytest.raises(ValueError):
        batch_shape(np.zeros((2, 3, 3)), np.zeros((3, 3, 3)))


def _mixed_tree():
    """Seven rigid bodies on mixed joints: a family at rest (a prismatic base: no angular velocity, its axes
    unbatched), turning bodies with and without a translation, different outboard points, three bodies with one
    load each (one in body axes), two with two and one without points."""
    import ctmm.spatial as sp

    def body(name, mass, points):
        return sp.SpatialBody(name, mass, (0.03 * mass, 0.02 * mass, 0.01 * mass), (0.1 * mass, -0.05, -0.2), points)

    elements = [body("base", 4.0, {"l": (0.2, 0.0, 0.1), "r": (-0.2, 0.1, 0.0), "top": (0.0, 0.0, 0.3)}),
                body("a", 1.0, {"tip": (0.0, 0.0, -0.5)}), body("b", 0.8, {"tip": (0.1, 0.0, -0.4)}),
                body("c", 1.2, {"tip": (0.0, 0.2, -0.5), "side": (0.1, 0.1, 0.0)}), body("d", 0.5, {"tip": (0, 0, -0.3)}),
                body("e", 0.7, {}), body("f", 0.3, {}),
                sp.Prismatic(name="slide", parent=None, child="base", axis=(1.0, 0.0, 0.0), stiffness=3.0),
                sp.Revolute(name="j1", parent="base", child="a", point="l", axis=(0.0, 1.0, 0.0), actuated=True),
                sp.Spherical(name="j2", parent="a", child="b", point="tip"),
                sp.Universal(name="j3", parent="base", child="c", point="r"),
                sp.Prismatic(name="j4", parent="c", child="d", point="tip", axis=(0.0, 0.0, 1.0), damping=0.2),
                sp.Free(name="j5", parent="c", child="e", point="side"),
                sp.Revolute(name="j6", parent="base", child="f", point="top", axis=(1.0, 0.0, 0.0)),
                sp.Load(name="push", body="a", point="tip", force=(1.0, -2.0, 0.5), moment=(0.1, 0.0, 0.3)),
                sp.Load(name="twist", body="d", point="tip", force=(0.0, 1.5, 0.0), moment=(0.2, -0.1, 0.0),
                        axes="body"),
                sp.Load(name="drag", body="b", point="tip", force=(-0.5, 0.0, 1.0)),
                sp.Load(name="turn", body="b", moment=(0.0, 0.4, -0.2), axes="body")]
    return sp.SpatialModel("mixed_tree", elements, gravity=(0.3, -0.2, -9.81))


def test_scene_terms_of_rigid_families_equal_the_ops_statement_per_body():
    """``SpatialScene.terms`` on numpy evaluates the rigid bodies of a family (equal numbers of loads) and the revolute
    and the prismatic joints (with and without law or input) each in one call over the members stacked on a leading
    axis; every body's terms (``M, h, Kin, c, RF``), joint terms and state equal the ops statement evaluated per body
    on casadi numbers (the generic path: one body at a time, no stacking), for a batch
    of three states and for one state, with extra wrenches (world and body axes) on three bodies."""
    from ctmm.spatial.body_forms import SpatialScene
    from ctmm.spatial.joint_kinematics import AxisJointFamily, joint_motion

    model = _mixed_tree()
    scene = SpatialScene(model)
    nq, nv = model.n_positions, model.n_velocities
    for batch in (3, 1):
        q = RNG.normal(size=(batch, nq)) * 0.4
        for joint, layout in zip(model.joints, model.layout):
            if joint.kind in ("spherical", "free"):
                q[:, layout.position.stop - 4:layout.position.stop] += [1.0, 0.0, 0.0, 0.0]
        v = RNG.normal(size=(batch, nv))
        torque = RNG.normal(size=(batch, 1, 1))
        extra = {1: [(np.array([0.0, 0.1, -0.3]), RNG.normal(size=(batch, 6, 1)))],
                 5: [(np.array([0.1, 0.0, 0.2]), RNG.normal(size=(batch, 6, 1)))],
                 6: [(np.array([0.0, 0.3, 0.0]), RNG.normal(size=(1, 6, 1)), "body")]}
        bodies, joints, states = scene.terms(NUMPY, q, v, 0.4, {"j1.torque": torque}, extra)
        assert len({id(terms.M.base) for terms in bodies if terms.M.base is not None}) < len(bodies)  # stacked
        for kind in ("revolute", "prismatic"):                              # the joint families on their own
            members = [j for j, joint in enumerate(model.joints) if joint.kind == kind]
            family = AxisJointFamily([model.joints[j] for j in members],
                                     [model.layout[j].position.start for j in members],
                                     [model.layout[j].velocity.start for j in members])
            for j, motion in zip(members, family.motions(q, v, {"j1.torque": torque})):
                joint, layout = model.joints[j], model.layout[j]
                for k in range(batch):
                    u = casadi.DM(torque[k]) if joint.inputs else None
                    reference = joint_motion(CASADI, joint, [casadi.DM(q[k, layout.position.start])],
                                             [casadi.DM(v[k, layout.velocity.start])], u)
                    for field in ("rotation", "translation", "S", "bias", "linear", "angular", "tau", "tau_q", "tau_v"):
                        got, expected = getattr(motion, field), getattr(reference, field)
                        assert (got is None) == (expected is None), (joint.name, field)
                        if got is not None:
                            _close(got, expected, k, f"{joint.name} {field}")
        for k in range(batch):
            reference_bodies, reference_joints, reference_states = scene.terms(
                CASADI, casadi.DM(q[k]), casadi.DM(v[k]), 0.4, {"j1.torque": casadi.DM(torque[k])},
                {j: [(entry[0], casadi.DM(entry[1][min(k, entry[1].shape[0] - 1)]), *entry[2:]) for entry in entries]
                 for j, entries in extra.items()})
            for terms, reference in zip(bodies, reference_bodies):
                _compare(terms, reference, k)
            for terms, reference in zip(joints, reference_joints):
                for field in ("S", "c", "tau", "tau_q", "tau_v"):
                    assert (getattr(terms, field) is None) == (getattr(reference, field) is None), field
                    if getattr(reference, field) is not None:
                        _close(getattr(terms, field), getattr(reference, field), k, field)
            for state, reference in zip(states, reference_states):
                for field in ("rotation", "origin", "velocity", "omega", "inboard"):
                    _close(getattr(state, field), getattr(reference, field), k, field)
