"""Spherical cut joints with a 3-axis law (a rotary spring-damper on the relative rotation vector) and the cut moment
sensors ``"<cut>.moment_x|y|z"`` (docs/closed_loops.md section 8.1b), against independent references.

The model: a body on a free joint held at the ground by a spherical cut at its origin carrying the law (3 degrees of
freedom).  References: the Newton-Euler DAE of free bodies (ctmm.reference.spatial_loop_dae, the ball rows its own)
with the law's moment computed here from the DAE's rotation matrices -- the rotation vector by scipy's logarithm, the
work-conjugate moment ``-J^-T f`` as central differences of ``f . phi`` over small rotations, the rate ``phi'`` as the
same differences along the angular velocity -- no ctmm.spatial code; the closed-form frequencies ``sqrt(k / lambda_i)``
of the spring's stiffness ``k`` about the rest orientation in zero gravity (``lambda_i`` the eigenvalues of the
inertia about the pivot); energy conservation with the law's potential.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.nonlinear_laws import CubicSpring, LinearLaw, ParallelLaw
from ctmm.spatial import closed_loop_linear as linear
from ctmm.spatial.closed_loop_time import simulate_spatial_loop_scheme, simulate_spatial_loops
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel
from spatial_loop_helpers import dae_of, poses

REST = np.array([0.1, -0.2, 0.05])
MASS, INERTIA, COM = 1.2, np.diag([0.02, 0.03, 0.025]), np.array([0.1, 0.0, -0.3])
SPRING = CubicSpring(2.0, 15.0)
LAW = ParallelLaw(SPRING, LinearLaw(0.0, 0.02))


def _ball(law, gravity=(0.0, 0.0, -9.81)) -> SpatialKinematicLoopModel:
    tree = sp.SpatialModel("ball", [sp.SpatialBody("p", MASS, INERTIA, center_of_mass=tuple(COM)),
                                    sp.Free(name="free", parent=None, child="p")], gravity=gravity)
    return SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="ball", parent=None, child="p", law=law, rest=REST)])


def _start(loop):
    turn = np.sin(0.3)
    return loop.consistent_state({"free.qw": np.cos(0.3), "free.qx": 0.6 * turn, "free.qy": 0.8 * turn},
                                 {"free.wx": 1.0, "free.wz": 2.0})


def _law_moment(law, R: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """The law's moment on the body (world; the parent is the ground), written from its definition."""
    rest = Rotation.from_rotvec(REST)

    def phi_of(rotation: np.ndarray) -> np.ndarray:
        return (Rotation.from_matrix(rotation) * rest.inv()).as_rotvec()

    h = 1e-6
    columns = [(phi_of(Rotation.from_rotvec(h * e).as_matrix() @ R) - phi_of(Rotation.from_rotvec(-h * e).as_matrix()
                                                                            @ R)) / (2 * h) for e in np.eye(3)]
    dphi = np.column_stack(columns)                     # d phi / d theta (world small rotations)
    f = np.array([law.force(p, r) for p, r in zip(phi_of(R), dphi @ omega)])
    return -dphi.T @ f


def _dae_run(loop, law, q, v, times):
    dae = dae_of(loop, 10.0)

    def torques(t, y):
        return {0: _law_moment(law, dae.rotations(y)[0], dae.split(y)[3][0])}

    _, Y = dae.simulate(dae.state(*poses(loop, q, v)), times, torques=torques)
    return dae, Y


def _rotation_error(loop, q, v, dae, Y) -> float:
    return max(float(np.abs(poses(loop, q[k], v[k])[1][0] - dae.rotations(Y[k])[0]).max()) for k in range(len(Y)))


def test_rk4_with_the_nonlinear_law_matches_the_dae():
    """Cubic spring plus a linear damper on each rotation-vector component, gravity: RK4 1 ms + projection over
    0.1 s against the DAE with the law written from its definition (measured 6.1e-10 rad); the law matters (without
    it the motion is 0.1 rad away), the law moment sensor equals the reference moment along the run."""
    loop = _ball(LAW)
    q, v = _start(loop)
    run = simulate_spatial_loops(loop, q, v, t_final=0.1, dt=1e-3, store_every=10)
    dae, Y = _dae_run(loop, LAW, q, v, run.t)
    assert _rotation_error(loop, run.q, run.v, dae, Y) < 5e-9
    free = simulate_spatial_loops(_ball(None), q, v, t_final=0.1, dt=1e-3, store_every=100)
    assert np.abs(free.q[-1] - run.q[-1]).max() > 1e-2
    for k in (0, len(run.t) // 2, -1):
        R, omega = poses(loop, run.q[k], run.v[k])[1][0], poses(loop, run.q[k], run.v[k])[3][0]
        expected = _law_moment(LAW, R, omega)
        scale = np.abs(expected).max()
        assert np.allclose(loop.law_moments(run.q[k], run.v[k])[0], expected, rtol=0, atol=1e-8 * scale)  # 1.5e-10


def _energy(loop, q, v) -> float:
    """Kinetic plus gravitational energy [J] of the body from its pose (centre of mass, rotation, velocities)."""
    (x,), (R,), (velocity,), (omega,) = poses(loop, q, v)
    return float(0.5 * MASS * velocity @ velocity + 0.5 * omega @ R @ INERTIA @ R.T @ omega
                 - MASS * loop.tree.gravity @ x)


def test_energy_with_the_law_potential_is_conserved():
    """Undamped cubic spring: the tree's energy plus the law's potential (the sum over the rotation vector's
    components) is conserved by RK4 to its truncation error, which the exact work-conjugate moment makes possible."""
    loop = _ball(SPRING)
    q, v = _start(loop)
    run = simulate_spatial_loops(loop, q, v, t_final=0.1, dt=1e-3, store_every=25)
    energy = [_energy(loop, qk, vk) + loop.cut_potential(qk) for qk, vk in zip(run.q, run.v)]
    potential = [loop.cut_potential(qk) for qk in run.q]
    assert np.ptp(potential) > 1e-3 * np.abs(energy[0])                  # the spring stores and returns energy
    assert np.ptp(energy) < 1e-9 * max(abs(e) for e in energy)


def test_newmark_with_the_law_converges_to_the_dae_at_second_order():
    loop = _ball(LAW)
    q, v = _start(loop)
    errors = []
    for dt in (4e-3, 2e-3):
        run, info = simulate_spatial_loop_scheme(loop, q, v, t_final=0.032, dt=dt, scheme="newmark")
        dae, Y = _dae_run(loop, LAW, q, v, run.t)
        errors.append(_rotation_error(loop, run.q, run.v, dae, Y))
        assert run.drift.max() < 1e-12
    assert errors[1] < 1e-5 and 3.5 < errors[0] / errors[1] < 4.5


def test_frequencies_and_moment_sensor_in_the_linearisation():
    """Zero gravity: the rest orientation is the equilibrium; its frequencies are sqrt(k / lambda_i(I_O)) (the
    spring's stiffness at zero deflection is K1 = 2 N m/rad); the linearised moment sensor obeys M' = -K1 omega."""
    loop = _ball(SPRING, gravity=(0.0, 0.0, 0.0))
    w, x, y, z = Rotation.from_rotvec(REST).as_quat()[[3, 0, 1, 2]]
    q_eq, _ = loop.consistent_state({"free.qw": w, "free.qx": x, "free.qy": y, "free.qz": z}, {})
    inertia = INERTIA + MASS * (COM @ COM * np.eye(3) - np.outer(COM, COM))
    expected = np.sort(np.sqrt(2.0 / np.linalg.eigvalsh(inertia)))
    assert np.allclose(np.sort(linear.natural_frequencies(loop, q_eq)), expected, rtol=1e-7)
    outputs = [f"ball.moment_{a}" for a in "xyz"] + [f"p.omega_{a}" for a in "xyz"]
    lin = ctmm.linearize(loop, (q_eq, np.zeros(loop.tree.n_velocities)), inputs=["p.moment_x"], outputs=outputs)
    ss = lin.state_space
    C = np.asarray(ss.C)
    assert np.allclose(C[:3] @ np.asarray(ss.A), -2.0 * C[3:], atol=1e-7 * np.abs(C[3:]).max())   # measured 1.5e-9
    assert np.abs(C[:3]).max() > 1.0


def test_moment_sensor_in_a_run_and_refusals():
    loop = _ball(LAW)
    q, v = _start(loop)
    result = ctmm.simulate(loop, 0.01, 1e-3, x0=q, v0=v, outputs=["ball.moment_x", "ball.moment_y", "ball.moment_z"])
    qs = np.array([result[name] for name in loop.tree.coordinates]).T
    vs = np.array([result[name] for name in loop.tree.velocities]).T
    got = np.array([result[f"ball.moment_{a}"] for a in "xyz"]).T
    assert np.allclose(got[-1], loop.law_moments(qs[-1], vs[-1])[0], rtol=1e-12, atol=0)
    assert result.units(["ball.moment_x"]) == {"ball.moment_x": "N m"}
    for method in ("rk4", "newmark"):                                   # every run reports the law's moment
        alone = ctmm.simulate(loop, 0.01, 1e-3, x0=q, v0=v, method=method)
        qn = np.array([alone[name] for name in loop.tree.coordinates]).T
        vn = np.array([alone[name] for name in loop.tree.velocities]).T
        assert np.allclose(alone["ball.moment_y"][-1], loop.law_moments(qn[-1], vn[-1])[0, 1], rtol=1e-12, atol=0)
        assert abs(alone["ball.moment_y"][-1]) > 0.1
    assert "ball.moment_x" not in ctmm.simulate(_ball(None), 0.002, 1e-3, x0=q, v0=v).signals()
    with pytest.raises(ModelError, match="takes neither"):
        SpatialCutJoint(name="c", parent=None, child="p", kind="spherical", actuation=1.0)
    with pytest.raises(ModelError, match="rest"):
        SpatialCutJoint(name="c", parent=None, child="p", law=SPRING, rest=(4.0, 0.0, 0.0))
