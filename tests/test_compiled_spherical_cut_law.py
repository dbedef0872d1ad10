"""Spherical cut joints with a 3-axis law in the generated kinematic-loop steps (issue 13; docs/closed_loops.md §8.1b):
the law's moment on symbols (ctmm.compiled_spherical_cut_law) in the generated RK4 with projection
(ctmm.compiled_spatial_kinematic_loops) and in the generated loop driver with the ``"<cut>.moment_x|y|z"`` sensors
(ctmm.compiled_kinematic_loop_control).

Checks: the symbolic moment against the numpy definition at random rotations; the generated runs against the numpy
paths to round-off; the generated RK4 against the Newton-Euler DAE of tests/test_spatial_spherical_cut_law.py (its law
moment written from the definition with scipy, no ctmm.spatial code) at that file's bound; a run turned beyond the
law's 3 rad stopped by name.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_compiled_kinematic_loop_control import _equal, _numpy
from test_spatial_spherical_cut_law import COM, INERTIA, LAW, MASS, REST, _ball, _dae_run, _rotation_error, _start

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback, with_feedback
from ctmm.control.static_gain import StaticGainController
from ctmm.errors import SimulationError
from ctmm.nonlinear_laws import CubicSpring, LinearLaw, ParallelLaw
from ctmm.spatial.closed_loop_cuts import SpatialCutJoint, spherical_law_moment
from ctmm.spatial.closed_loops import SpatialKinematicLoopModel


def test_symbolic_law_moment_equals_the_numpy_definition():
    """Random parent and child orientations at relative rotations from 1e-9 to 2.95 rad from the rest (both sides of
    the series switches), with and without a parent body: = spatial_law_moment to 1e-13 relative (the logarithm
    through the unit quaternion on both sides); NaN beyond 3 rad, where the numpy path raises."""
    import casadi as ca

    from ctmm.compiled_spherical_cut_law import symbolic_spherical_law_moment

    cut = SpatialCutJoint(name="c", parent="a", child="b", law=LAW, rest=REST)
    Rp, Rc, wp, wc = (ca.SX.sym("Rp", 3, 3), ca.SX.sym("Rc", 3, 3), ca.SX.sym("wp", 3), ca.SX.sym("wc", 3))
    with_parent = ca.Function("m", [Rp, Rc, wp, wc], [symbolic_spherical_law_moment(cut, Rp, Rc, wp, wc)])
    at_ground = ca.Function("m", [Rc, wc], [symbolic_spherical_law_moment(cut, None, Rc, ca.DM.zeros(3), wc)])
    rng = np.random.default_rng(7)
    rest = Rotation.from_rotvec(REST).as_matrix()
    for angle in (1e-9, 3e-5, 1e-3, 0.5, 1.7, 2.95):
        for _ in range(3):
            axis = rng.normal(size=3)
            relative = Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).as_matrix()
            parent = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
            omega_p, omega_c = rng.normal(size=3), rng.normal(size=3)
            child = parent @ relative @ rest
            expected = spherical_law_moment(cut, parent, child, omega_p, omega_c, 0.0)
            got = np.asarray(with_parent(parent, child, omega_p, omega_c)).ravel()
            assert np.abs(got - expected).max() <= 1e-13 * max(1.0, np.abs(expected).max()), angle
            expected = spherical_law_moment(cut, None, relative @ rest, np.zeros(3), omega_c, 0.0)
            got = np.asarray(at_ground(relative @ rest, omega_c)).ravel()
            assert np.abs(got - expected).max() <= 1e-13 * max(1.0, np.abs(expected).max()), angle
    beyond = Rotation.from_rotvec([0.0, 3.05, 0.0]).as_matrix() @ rest
    assert np.all(np.isnan(np.asarray(at_ground(beyond, np.zeros(3)))))
    with pytest.raises(SimulationError, match="beyond the 3 rad"):
        spherical_law_moment(cut, None, beyond, np.zeros(3), np.zeros(3), 0.0)


def test_symbolic_rotation_vector_equals_numpy_up_to_pi():
    """The one logarithm on symbols (the law's and the ``"<body>.rotation_x|y|z"`` sensors') against
    ctmm.spatial.sensor_maps.rotation_vector: random axes at angles from 1e-9 rad to pi - 1e-9 (every branch of the
    quaternion's largest component, the series), exactly pi about each axis (the sign numpy chooses) to 1e-13; its
    forward derivative along ``R' = [w]x R`` (the delay ring's rates) against numpy's complex step to 1e-9."""
    import casadi as ca

    from ctmm.compiled_spherical_cut_law import symbolic_rotation_vector
    from ctmm.spatial.sensor_maps import rotation_vector

    R, w = ca.SX.sym("R", 3, 3), ca.SX.sym("w", 3)
    phi = symbolic_rotation_vector(R)
    skew = ca.vertcat(ca.horzcat(0, -w[2], w[1]), ca.horzcat(w[2], 0, -w[0]), ca.horzcat(-w[1], w[0], 0))
    log = ca.Function("log", [R, w], [phi, ca.jtimes(phi, ca.vec(R), ca.vec(ca.mtimes(skew, R)))])
    rng = np.random.default_rng(3)
    rotations = [np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])]
    for angle in (1e-9, 1e-4, 3e-4, 0.5, 2.0, 3.0, np.pi - 1e-6, np.pi - 1e-9):
        for _ in range(4):
            axis = rng.normal(size=3)
            rotations.append(Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).as_matrix())
    branches = set()
    for matrix in rotations:
        omega = rng.normal(size=3)
        got, rate = (np.asarray(x).ravel() for x in log(matrix, omega))
        expected = rotation_vector(matrix)
        assert np.abs(got - expected).max() <= 1e-13, (matrix, got, expected)
        if np.linalg.norm(expected) < np.pi - 1e-3:              # the flip at pi has no derivative
            bent = matrix + 1e-30j * np.cross(omega[None, :], matrix.T).T      # (I + i h [w]x) R
            numeric = np.imag(rotation_vector(bent)) / 1e-30
            assert np.abs(rate - numeric).max() <= 1e-9 * max(1.0, np.abs(numeric).max()), matrix
        branches.add(int(np.argmax([np.trace(matrix), *np.diag(matrix)])))
    assert branches == {0, 1, 2, 3}


def test_generated_rk4_equals_numpy_and_matches_the_dae():
    """The ball held by a spherical cut with a cubic spring and a damper, gravity: the generated RK4 with projection =
    the numpy RK4 with projection to 1e-12 (states, cut forces and the law's moment), both 5e-9 rad from the DAE (the
    numpy path's bound, tests/test_spatial_spherical_cut_law.py); ctmm.simulate(..., compiled=True) too."""
    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loops

    loop = _ball(LAW)
    q, v = _start(loop)
    generated = simulate_spatial_kinematic_loops_generated(loop, q, v, t_final=0.1, dt=1e-3)   # the kernel of
    numpy_run = simulate_spatial_loops(loop, q, v, t_final=0.1, dt=1e-3)                     # ctmm.simulate below
    np.testing.assert_array_equal(generated.t, numpy_run.t)
    assert np.max(np.abs(generated.q - numpy_run.q)) <= 1e-12 and np.max(np.abs(generated.v - numpy_run.v)) <= 1e-12
    for name in ("cut_force", "cut_moment"):
        ours, theirs = getattr(generated, name), getattr(numpy_run, name)
        assert np.max(np.abs(ours - theirs)) <= 1e-12 * max(1.0, np.max(np.abs(theirs))), name
    assert np.abs(generated.cut_moment).max() > 0.1                       # the law's moment is stored
    dae, Y = _dae_run(loop, LAW, q, v, generated.t)
    assert _rotation_error(loop, generated.q, generated.v, dae, Y) < 5e-9
    assert _rotation_error(loop, numpy_run.q, numpy_run.v, dae, Y) < 5e-9
    outputs = ["ball.moment_x", "ball.moment_y", "ball.moment_z", "ball.force_z"]
    compiled = ctmm.simulate(loop, 0.01, 1e-3, x0=q, v0=v, compiled=True)
    plain = ctmm.simulate(loop, 0.01, 1e-3, x0=q, v0=v)
    assert compiled.info["compiled"] is True
    for name in outputs:
        assert np.max(np.abs(compiled[name] - plain[name])) <= 1e-12 * max(1.0, np.max(np.abs(plain[name]))), name


def _actuated(law=LAW) -> SpatialKinematicLoopModel:
    tree = sp.SpatialModel("ball", [sp.SpatialBody("p", MASS, INERTIA, center_of_mass=tuple(COM)),
                                    sp.Free(name="free", parent=None, child="p", actuated=True)])
    return SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="ball", parent=None, child="p", law=law, rest=REST)])


def test_loops_on_the_law_moment_sensors_equal_the_numpy_driver():
    """A loop per axis feeding the law's moment ``"ball.moment_x|y|z"`` back as a body torque (x and y three steps
    late from the loops' ring, z real-time; one kernel): = the numpy loop driver (projected) to 1e-12, and the loops
    act."""
    loop = _actuated()
    q0, v0 = _start(loop)
    loops = [Feedback(f"m{a}", sensor=f"ball.moment_{a}", actuator=f"free.torque_{a}", gain=-0.8,
                      delay=0.0 if a == "z" else 3e-3) for a in "xyz"]
    options = dict(x0=q0, v0=v0, outputs=["ball.moment_x", "ball.moment_y", "ball.moment_z"])
    generated = ctmm.simulate(with_feedback(loop, loops), 0.05, 1e-3, compiled=True, **options)
    _equal(generated, _numpy(with_feedback(loop, loops), 0.05, 1e-3, **options))
    assert generated.info["loops"] == {"mx": "history", "my": "history", "mz": "real-time"}
    assert np.max(np.abs(generated["mz.u"] - 0.8 * generated["ball.moment_z"])) < 1e-12   # u = -gain y
    free = ctmm.simulate(loop, 0.05, 1e-3, x0=q0, v0=v0)
    assert np.max(np.abs(free["ball.moment_x"] - generated["ball.moment_x"])) > 1e-3


def test_a_turn_beyond_the_law_limit_stops_the_generated_runs_by_name():
    """A weak spring spun about the cut's z axis: the relative rotation passes 3 rad near t = 0.3 s; the numpy RK4
    raises there (at a stage inside the step), the generated RK4, the generated loop driver and the co-simulated
    run at the end of that step, with the cut named and the partial result."""
    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loops

    loop = _actuated(LinearLaw(0.01, 0.0))
    w, x, y, z = Rotation.from_rotvec(REST).as_quat()[[3, 0, 1, 2]]
    q0, v0 = loop.consistent_state({"free.qw": w, "free.qx": x, "free.qy": y, "free.qz": z}, {"free.wz": 10.0})
    with pytest.raises(SimulationError, match="beyond the 3 rad") as numpy_error:
        simulate_spatial_loops(loop, q0, v0, t_final=0.5, dt=5e-3)
    with pytest.raises(SimulationError, match="cut joint 'ball' is turned 2.9.* rad") as error:
        simulate_spatial_kinematic_loops_generated(loop, q0, v0, t_final=0.5, dt=5e-3)
    assert error.value.element == "ball" and abs(error.value.time - numpy_error.value.time) <= 5e-3 * (1 + 1e-9)
    assert len(error.value.partial_result.t) > 10
    held = Feedback("h", sensor="ball.moment_z", actuator="free.torque_z", gain=0.0)
    with pytest.raises(SimulationError, match="cut joint 'ball' is turned 2.9.* rad") as error:
        ctmm.simulate(with_feedback(loop, [held]), 0.5, 5e-3, x0=q0, v0=v0, compiled=True)
    assert error.value.element == "ball"
    sampled = StaticGainController(["ball.moment_z"], ["free.torque_x"], [[0.0]], sample_time=1e-2)
    with pytest.raises(SimulationError, match="cut joint 'ball' is turned 2.9.* rad") as error:
        ctmm.simulate(loop, 0.5, 5e-3, x0=q0, v0=v0, controllers=[sampled], compiled=True)
    assert error.value.element == "ball" and error.value.partial_result is not None


def test_co_simulated_controller_on_the_law_moment_sensors_equals_the_numpy_driver():
    """A sampled static gain on ``"ball.moment_x|y"`` driving a body torque (4 ms samples): = the numpy driver."""
    loop = _actuated()
    q0, v0 = _start(loop)
    sampled = StaticGainController(["ball.moment_x", "ball.moment_y"], ["free.torque_x"], [[-0.5, 0.3]],
                                   sample_time=4e-3)
    options = dict(x0=q0, v0=v0, outputs=["ball.moment_x"], controllers=[sampled])
    _equal(ctmm.simulate(loop, 0.04, 1e-3, compiled=True, **options), _numpy(loop, 0.04, 1e-3, **options))


def _body_law_moments(law, rest: np.ndarray, Rp: np.ndarray, Rc: np.ndarray, wp: np.ndarray, wc: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The law's moments on the parent and the child (world) written from the definition: ``phi = log(R_p^T R_c
    R_rest^T)`` by scipy, its derivatives along small world rotations of each body by central differences, the
    moments ``-(d phi / d theta)^T f`` and ``phi' = sum (d phi / d theta) omega`` -- no ctmm.spatial code."""
    rest_rotation = Rotation.from_rotvec(rest).as_matrix()

    def phi_of(parent: np.ndarray, child: np.ndarray) -> np.ndarray:
        return Rotation.from_matrix(parent.T @ child @ rest_rotation.T).as_rotvec()

    h = 1e-6
    turns = [(Rotation.from_rotvec(h * e).as_matrix(), Rotation.from_rotvec(-h * e).as_matrix()) for e in np.eye(3)]
    d_child = np.column_stack([(phi_of(Rp, plus @ Rc) - phi_of(Rp, minus @ Rc)) / (2 * h) for plus, minus in turns])
    d_parent = np.column_stack([(phi_of(plus @ Rp, Rc) - phi_of(minus @ Rp, Rc)) / (2 * h) for plus, minus in turns])
    f = np.array([law.force(p, r) for p, r in zip(phi_of(Rp, Rc), d_child @ wc + d_parent @ wp)])
    return -d_parent.T @ f, -d_child.T @ f


def test_a_law_between_two_moving_bodies_equals_numpy_and_matches_the_dae():
    """The closed triangle of rods (tests/spatial_loop_helpers.py: three ball joints in a ring, its spherical cut
    between rods a and c) with a weak law on the cut (a tenth of LAW; the rods' spins about their axes are light, so
    the law makes fast modes), its rest 0.15 rad from the start: the generated RK4 = the numpy RK4 to 1e-12; both
    against the Newton-Euler DAE with the law's moments on both rods written from the definition (_body_law_moments)
    at the triangle's bound, 1e-9 rad (tests/test_spatial_closed_loops.py), at dt = 0.5 ms over 0.03 s (the RK4 error
    over 0.06 s: 7.9e-8 / 4.9e-9 rad at 2 / 1 ms, order 4; with LAW itself 8.8e-6 / 4.6e-7 / 2.6e-8 at 2 / 1 / 0.5 ms)."""
    from dataclasses import replace

    from spatial_loop_helpers import dae_of, poses, triangle, triangle_guess

    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loops

    ring = triangle()
    q, v = ring.consistent_state(triangle_guess(), {"ja.wx": 1.0, "jb.wz": 0.5, "jc.wy": -0.3})
    (a, _, c), start = poses(ring, q, v)[1], poses(ring, q, v)
    rest = Rotation.from_matrix(a.T @ c).as_rotvec() + np.array([0.1, -0.1, 0.05])
    law = ParallelLaw(CubicSpring(0.2, 1.5), LinearLaw(0.0, 0.002))
    loop = SpatialKinematicLoopModel(ring.tree, [replace(ring.cuts[0], law=law, rest=rest)])
    generated = simulate_spatial_kinematic_loops_generated(loop, q, v, t_final=0.03, dt=5e-4, store_every=4)
    numpy_run = simulate_spatial_loops(loop, q, v, t_final=0.03, dt=5e-4, store_every=4)
    assert np.max(np.abs(generated.q - numpy_run.q)) <= 1e-12 and np.max(np.abs(generated.v - numpy_run.v)) <= 1e-12
    dae = dae_of(loop, 10.0)

    def torques(t, y):
        R, (_, _, _, omega) = dae.rotations(y), dae.split(y)
        parent, child = _body_law_moments(law, rest, R[0], R[2], omega[0], omega[2])
        return {0: parent, 2: child}

    _, Y = dae.simulate(dae.state(*start), generated.t, torques=torques)
    for run in (generated, numpy_run):
        error = max(np.abs(R - S).max() for k in range(len(Y))
                    for R, S in zip(poses(loop, run.q[k], run.v[k])[1], dae.rotations(Y[k])))
        assert error < 1e-9
    assert np.abs(loop.law_moments(q, v)).max() > 0.01                         # the law acts (0.02 N m)


def test_a_spherical_law_casadi_cannot_express_is_refused_by_name():
    """A CallableLaw with its own derivatives (plain Python, not traced) on a spherical cut: compiled=True refuses the
    model by name before building (the numpy path runs it)."""
    from ctmm.errors import ModelError
    from ctmm.nonlinear_laws import CallableLaw

    law = CallableLaw(lambda d, r: 2.0 * float(d) + 0.02 * float(r), stiffness=lambda d, r: 2.0,
                      damping=lambda d, r: 0.02, name="python spring")
    loop = _ball(law)
    q, v = _start(loop)
    with pytest.raises(ModelError, match="cut joint 'ball'.*python spring.*not expressible with casadi"):
        ctmm.simulate(loop, 0.002, 1e-3, x0=q, v0=v, compiled=True)
    assert ctmm.simulate(loop, 0.002, 1e-3, x0=q, v0=v)["ball.moment_x"].shape == (3,)
