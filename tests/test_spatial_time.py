"""Spatial models in time (issue 14): ``ctmm.simulate`` with RK4 and ``solve_ivp`` against closed-form
physics (energy, Euler's equations, angular momentum, a pendulum ODE solved by scipy) and against
Pinocchio's ABA integrated by an RK4 written here."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError, SimulationError


def states(model: sp.SpatialModel, result) -> tuple[np.ndarray, np.ndarray]:
    q = np.array([result[name] for name in model.coordinates]).T
    v = np.array([result[name] for name in model.velocities]).T
    return q, v


def rotation(quaternion: np.ndarray) -> np.ndarray:
    w, x, y, z = quaternion / np.linalg.norm(quaternion)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def pendulum_tree() -> sp.SpatialModel:
    """A conservative branched tree: spherical, universal and revolute joints under gravity."""
    def body(name):
        return sp.SpatialBody(name, 1.0, (0.02, 0.03, 0.04), (0.0, 0.0, -0.5),
                              {"tip": (0.0, 0.0, -1.0), "side": (0.2, 0.0, -0.5)})
    return sp.SpatialModel("tree", [
        body("a"), body("b"), body("c"),
        sp.Spherical(name="ja", parent=None, child="a"),
        sp.Universal(name="jb", parent="a", point="tip", child="b", axis1=(1, 0, 0), axis2=(0, 1, 0)),
        sp.Revolute(name="jc", parent="a", point="side", child="c", axis=(0, 1, 1))])


PENDULUM_X0 = np.array([np.cos(0.4), np.sin(0.4), 0.1, 0.0, 0.3, -0.2, 0.5])
PENDULUM_V0 = np.array([0.5, -1.0, 2.0, 1.0, 0.0, -1.5])


@pytest.fixture(scope="module")
def pendulum_runs():
    model = pendulum_tree()
    runs = {dt: ctmm.simulate(model, 1.0, dt, x0=PENDULUM_X0, v0=PENDULUM_V0) for dt in (0.02, 0.01, 0.005)}
    return model, runs


def test_energy_drift_bounded_and_shrinks_at_order_four(pendulum_runs) -> None:
    """Energy of a conservative tree: drift over 1 s below 1e-5 J at dt = 5 ms, and shrinking ~16x per halving."""
    model, runs = pendulum_runs
    drift = {}
    for dt, result in runs.items():
        energy = sp.energy(model, *states(model, result))
        drift[dt] = np.abs(energy - energy[0]).max()
    assert drift[0.005] < 1e-5
    assert drift[0.02] / drift[0.01] > 10 and drift[0.01] / drift[0.005] > 10, drift


def test_rk4_converges_at_order_four(pendulum_runs) -> None:
    model, runs = pendulum_runs
    reference = ctmm.simulate(model, 1.0, 0.02, method="DOP853", x0=PENDULUM_X0, v0=PENDULUM_V0, rtol=1e-12,
                              atol=1e-12)
    errors = []
    for dt in (0.02, 0.01, 0.005):
        q, _ = states(model, runs[dt])
        q_ref, _ = states(model, reference)
        errors.append(np.abs(q[-1] - q_ref[-1]).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 3.7) and np.all(orders < 4.4), (errors, orders)


def test_torque_free_asymmetric_body_obeys_euler_equations() -> None:
    """Free body, no gravity: v_dot equals Euler's equations in body axes to round-off; the angular momentum
    in world axes is conserved by the run (intermediate-axis tumbling)."""
    inertia = np.diag([1.0, 2.0, 2.8])
    model = sp.SpatialModel("tumbler", [sp.SpatialBody("b", 3.0, inertia), sp.Free(name="f", parent=None, child="b")],
                            gravity=(0, 0, 0))
    q0 = np.r_[0.1, -0.2, 0.3, np.cos(0.3), 0.0, np.sin(0.3), 0.0]
    v0 = np.r_[0.4, 0.0, -0.1, 0.3, 3.0, -0.3]
    acc = sp.accelerations(model, q0, v0)
    omega = v0[3:]
    np.testing.assert_allclose(acc[3:], np.linalg.solve(inertia, -np.cross(omega, inertia @ omega)), atol=1e-14)
    np.testing.assert_allclose(acc[:3], -np.cross(omega, v0[:3]), atol=1e-14)   # child-axes velocity of a free mass
    result = ctmm.simulate(model, 2.0, 0.004, x0=q0, v0=v0)
    q, v = states(model, result)
    momentum = np.array([rotation(qk[3:]) @ (inertia @ vk[3:]) for qk, vk in zip(q, v)])
    assert np.abs(momentum - momentum[0]).max() < 1e-8 * np.linalg.norm(momentum[0])
    assert np.ptp(v[:, 4]) > 1.0                                     # it really tumbles


def test_spherical_pendulum_swings_through_euler_angle_lock() -> None:
    """A spherical pendulum swinging over the top in the x-z plane turns its body x axis onto the world z axis
    (ZYX Euler angles lock at pitch +-90 deg): the quaternion run equals the scalar pendulum ODE solved by scipy."""
    mass, length, inertia_y = 2.0, 0.8, 0.05
    model = sp.SpatialModel("ball", [sp.SpatialBody("b", mass, (0.05, inertia_y, 0.04), (0.0, 0.0, -length)),
                                     sp.Spherical(name="s", parent=None, child="b")])
    pivot = inertia_y + mass * length ** 2
    rate0 = 1.05 * np.sqrt(4 * mass * 9.81 * length / pivot)           # enough to go over the top
    result = ctmm.simulate(model, 2.0, 0.002, v0=[0.0, rate0, 0.0])
    q, _ = states(model, result)

    def pendulum(t, y):
        return [y[1], -mass * 9.81 * length * np.sin(y[0]) / pivot]
    exact = solve_ivp(pendulum, (0, 2.0), [0.0, rate0], t_eval=result.time, rtol=1e-12, atol=1e-12)
    angle = 2 * np.unwrap(np.arctan2(q[:, 2], q[:, 0]) * 2) / 2              # rotation about y
    np.testing.assert_allclose(angle, exact.y[0], atol=1e-8)
    body_x_up = np.array([rotation(qk)[2, 0] for qk in q])
    assert body_x_up.min() < -0.9999 and body_x_up.max() > 0.9999      # within 0.9 deg of both lock poses (1 ms grid)


def test_spherical_pendulum_in_3d_conserves_energy_and_vertical_momentum() -> None:
    model = sp.SpatialModel("ball", [sp.SpatialBody("b", 2.0, (0.05, 0.06, 0.04), (0.0, 0.0, -0.8)),
                                     sp.Spherical(name="s", parent=None, child="b")])
    q0 = np.r_[np.cos(0.7), np.sin(0.7) * np.array([0.6, 0.8, 0.0])]
    result = ctmm.simulate(model, 2.0, 0.002, x0=q0, v0=[1.0, 6.0, 2.0])
    q, v = states(model, result)
    energy = sp.energy(model, q, v)
    lz = np.array([(rotation(qk) @ (np.diag([0.05, 0.06, 0.04]) @ vk))[2]
                   + 2.0 * np.cross(rotation(qk) @ [0, 0, -0.8], np.cross(rotation(qk) @ vk,
                                                                         rotation(qk) @ [0, 0, -0.8]))[2]
                   for qk, vk in zip(q, v)])
    assert np.abs(energy - energy[0]).max() < 1e-6 * abs(energy[0])
    assert np.abs(lz - lz[0]).max() < 1e-6 * max(1.0, abs(lz[0]))


def test_random_tree_run_equals_pinocchio_aba_with_rk4() -> None:
    """A random 5-body tree (free base, joint laws, inputs, a time-varying load): ctmm.simulate's RK4 run
    equals an RK4 written here on Pinocchio's ABA (same ODE, no normalisation in either) to 1e-9."""
    from test_spatial_pinocchio import PinTree, random_inputs, random_state, random_tree

    rng = np.random.default_rng(5)
    model = random_tree(rng, 5, kinds=("spherical", "universal", "prismatic", "revolute"))
    reference = PinTree(model)
    q0, v0 = random_state(rng, model)
    v0 *= 0.3
    inputs = random_inputs(rng, model)
    dt, n = 0.002, 100

    def rates(t, x):
        q, v = x[:model.n_positions], x[model.n_positions:]
        qdot = []
        for joint, layout in zip(model.joints, model.layout):
            qj, vj = q[layout.position], v[layout.velocity]
            if joint.kind == "spherical":
                qdot.append(0.5 * np.r_[-qj[1:] @ vj, qj[0] * vj + np.cross(qj[1:], vj)])
            elif joint.kind in ("free", "elastic6"):
                quat = qj[3:]
                qdot.append(np.r_[rotation(quat) @ vj[:3], 0.5 * np.r_[-quat[1:] @ vj[3:],
                                                                       quat[0] * vj[3:] + np.cross(quat[1:], vj[3:])]])
            else:
                qdot.append(vj)
        return np.r_[np.concatenate(qdot), reference.solve(q, v, inputs, t)[0]]

    x = np.r_[q0, v0]
    for step in range(n):
        t = step * dt
        k1 = rates(t, x)
        k2 = rates(t + dt / 2, x + dt / 2 * k1)
        k3 = rates(t + dt / 2, x + dt / 2 * k2)
        k4 = rates(t + dt, x + dt * k3)
        x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    result = ctmm.simulate(model, n * dt, dt, x0=q0, v0=v0, inputs=inputs)
    q, v = states(model, result)
    ours = np.r_[q[-1], v[-1]]
    assert np.abs(ours - x).max() < 1e-9 * max(1.0, np.abs(x).max())
    assert np.abs(x - np.r_[q0, v0]).max() > 0.01                          # it moved


def test_simulate_arguments_are_checked() -> None:
    model = pendulum_tree()
    with pytest.raises(ModelError, match="method for a spatial model"):
        ctmm.simulate(model, 1.0, 0.01, method="verlet")
    with pytest.raises(ModelError, match="unknown spatial input|ja.torque|no such"):
        ctmm.simulate(model, 1.0, 0.01, inputs={"ja.torque": 1.0})
    with pytest.raises(ModelError, match="whole multiple"):
        ctmm.simulate(model, 1.0, 0.3)
    with pytest.raises(ModelError, match="fast=True is not available for spatial models"):
        ctmm.simulate(model, 1.0, 0.01, fast=True)
    with pytest.raises(ModelError, match="x0 must be"):
        ctmm.simulate(model, 1.0, 0.01, x0=[1.0, 0.0])


def test_divergence_is_a_simulation_error_with_partial_result() -> None:
    model = pendulum_tree()
    with pytest.raises(SimulationError) as error:
        ctmm.simulate(model, 1.0, 0.01, x0=PENDULUM_X0, v0=PENDULUM_V0, divergence_bound=2.5)
    assert error.value.time is not None and error.value.partial_result is not None
    assert len(error.value.partial_result.time) >= 1


def test_joint_springs_are_conservative_with_their_stated_potentials() -> None:
    """Revolute and universal springs with rest angles and an isotropic spherical spring (potential
    2 k (1 - w^2) of the law tau = -k 2 w (x, y, z)) under gravity: energy drift shrinks ~16x per halving."""
    def body(name):
        return sp.SpatialBody(name, 0.7, (0.01, 0.012, 0.008), (0.05, 0.0, -0.2), {"tip": (0.0, 0.1, -0.4)})
    model = sp.SpatialModel("springs", [
        body("a"), body("b"), body("c"),
        sp.Spherical(name="s", parent=None, child="a", stiffness=3.0),
        sp.Revolute(name="r", parent="a", point="tip", child="b", axis=(1, 1, 0), stiffness=2.0, reference=0.3),
        sp.Universal(name="u", parent="b", point="tip", child="c", stiffness=(1.0, 0.5), reference=(0.1, -0.2))])
    x0 = np.r_[np.cos(0.6), np.sin(0.6) * np.array([0.0, 0.6, 0.8]), 0.2, 0.4, -0.3]
    v0 = np.r_[1.0, -2.0, 0.5, 3.0, -1.0, 2.0]
    drift = []
    for dt in (0.004, 0.002):
        result = ctmm.simulate(model, 0.4, dt, x0=x0, v0=v0)
        energy = sp.energy(model, *states(model, result))
        drift.append(np.abs(energy - energy[0]).max())
    assert drift[1] < 1e-6 * abs(energy[0]) + 1e-9 and drift[0] / drift[1] > 10, drift


def test_welded_model_has_static_reactions() -> None:
    """Everything welded: no coordinate; each weld carries the weight of what hangs on it."""
    model = sp.SpatialModel("rack", [
        sp.SpatialBody("a", 2.0, (0.1, 0.1, 0.1), (0.0, 0.0, -0.5), {"tip": (0.0, 0.0, -1.0)}),
        sp.SpatialBody("b", 3.0, (0.1, 0.1, 0.1), (0.3, 0.0, 0.0)),
        sp.Weld(name="w0", parent=None, child="a"), sp.Weld(name="w1", parent="a", point="tip", child="b")])
    assert model.n_positions == 0 and model.n_velocities == 0
    wrench = sp.reactions(model, np.zeros(0), np.zeros(0))
    np.testing.assert_allclose(wrench[1], [0, 0, 3 * 9.81, 0, -3 * 9.81 * 0.3, 0], atol=1e-12)
    np.testing.assert_allclose(wrench[0], [0, 0, 5 * 9.81, 0, -3 * 9.81 * 0.3, 0], atol=1e-12)
    with pytest.raises(ModelError, match="nothing to integrate"):
        ctmm.simulate(model, 1.0, 0.01)


def test_solve_ivp_output_grid_is_k_dt_and_the_end() -> None:
    """dt is the output grid of a solve_ivp run: t = k dt, and t_final where dt does not divide it (the grid was
    stretched to t_final / round(t_final / dt) steps, 1.005 ms for dt = 1 ms)."""
    arm = sp.SpatialModel("arm", [sp.SpatialBody("l", 1.0, (0.01, 0.1, 0.1), center_of_mass=(0.5, 0, 0)),
                                  sp.Revolute(name="j", parent=None, child="l", axis=(0, 0, 1))],
                          gravity=(0, -9.81, 0))
    result = ctmm.simulate(arm, 0.1005, 1e-3, method="DOP853", x0={"j.angle": -1.0})
    expected = np.append(1e-3 * np.arange(101), 0.1005)
    np.testing.assert_allclose(result.time, expected, rtol=0, atol=1e-15)
