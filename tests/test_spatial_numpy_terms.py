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
