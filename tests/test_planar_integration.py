"""Time integration of planar models: RK4 / solve_ivp on the TMM ODE, implicit DT-TMM orders,
Newton convergence, energy behaviour, convergence errors."""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.errors import ConvergenceError, ModelError
from ctmm.planar.implicit import _NewtonStep, simulate_implicit
from ctmm.planar.integrate import simulate_rk4, simulate_scipy
from ctmm.planar import solve_instant
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.schemes import GeneralizedAlpha, Newmark

from planar_helpers import random_state, random_tree, uniform_chain

T = 1.0


@pytest.fixture(scope="module")
def case():
    """4-link chain with smooth, driven and actuated hinges, loads; tight Lagrange reference."""
    model = random_tree(5, 4, chain=True, base="pinned", allow_translation=False)
    q0, qdot0, _ = random_state(model, 5)
    qdot0 = 0.3 * qdot0
    ref = PlanarLagrange(model).simulate(q0, qdot0, T, t_eval=[T], rtol=1e-13, atol=1e-13)
    return model, q0, qdot0, ref.y[: model.n_coordinates, -1]


def _slope(dts, errors):
    return float(np.polyfit(np.log(dts), np.log(errors), 1)[0])


def test_rk4_fourth_order(case):
    model, q0, qdot0, q_ref = case
    dts = [0.02, 0.01, 0.005]
    errors = [np.max(np.abs(simulate_rk4(model, q0, qdot0, t_final=T, dt=dt).q[-1] - q_ref))
              for dt in dts]
    assert 3.8 <= _slope(dts, errors) <= 4.2, errors
    assert errors[-1] < 1e-8


@pytest.mark.parametrize("scheme", [Newmark(), GeneralizedAlpha(0.8)], ids=["newmark", "galpha"])
def test_implicit_second_order_and_newton_iterations(case, scheme):
    model, q0, qdot0, q_ref = case
    dts = [0.02, 0.01, 0.005]
    errors, iterations = [], []
    for dt in dts:
        sim = simulate_implicit(model, q0, qdot0, t_final=T, dt=dt, scheme=scheme)
        errors.append(np.max(np.abs(sim.q[-1] - q_ref)))
        iterations.append(sim.iterations.mean())
    assert 1.95 <= _slope(dts, errors) <= 2.05, errors
    assert max(iterations) <= 3.5


def test_newton_converges_quadratically():
    model = uniform_chain(5)
    q = np.linspace(0.1, 1.0, 5)
    v = np.linspace(-1.0, 2.0, 5)
    h = 0.01
    step = _NewtonStep(model, 0.25 * h * h, 0.5 * h)
    sol = solve_instant(model, q, v)
    A, F, x = sol.body_acceleration, sol.joint_force, sol.qddot
    q_hat, v_hat = q + h * v + 0.25 * h * h * x, v + 0.5 * h * x
    residuals = []
    for _ in range(4):
        A, F, x_new = step.sweep(q_hat + step.bh2 * x, v_hat + step.gh * x, h, A, F, x)
        residuals.append(np.max(np.abs(x_new - x)))
        x = x_new
    r = residuals
    assert r[1] < 1e-3 * r[0] and r[2] <= max(10 * r[1] ** 2 / r[0], 1e-12), r


def test_scipy_methods_drive_the_tmm(case):
    model, q0, qdot0, q_ref = case
    dop = simulate_scipy(model, q0, qdot0, t_final=T, method="DOP853", rtol=1e-11, atol=1e-11)
    assert np.max(np.abs(dop.q[-1] - q_ref)) < 1e-8
    rk45 = simulate_scipy(model, q0, qdot0, t_final=T, method="RK45", rtol=1e-8, atol=1e-9)
    assert np.max(np.abs(rk45.q[-1] - q_ref)) < 1e-5
    radau = simulate_scipy(model, q0, qdot0, t_final=T, method="Radau", rtol=1e-8, atol=1e-9)
    assert np.max(np.abs(radau.q[-1] - q_ref)) < 1e-5


def test_energy_conservation_as_promised():
    """Undamped chain with springs: RK4 drift O(h^4); Newmark bounded O(h^2), no drift;
    generalized-alpha (rho < 1) may only lose energy."""
    from ctmm.planar import ElasticHinge, Pinned, PlanarModel, RigidBody, SmoothHinge
    model = PlanarModel.chain("springy", [
        Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
        ElasticHinge("k1", stiffness=20.0, rest_angle=0.3),
        RigidBody.uniform_link("b", mass=0.7, length=0.8), SmoothHinge("h2"),
        RigidBody("c", mass=0.5, inertia=0.03, center_of_mass=(0.3, 0.05), outboard=(0.6, 0.0))])
    q0, v0 = np.array([0.0, 0.4, -0.3]), np.zeros(3)
    e0 = model.energy(q0, v0)
    scale = 20.0  # J, potential energy range of the motion
    rk4 = simulate_rk4(model, q0, v0, t_final=1.0, dt=0.005)
    assert np.max(np.abs(rk4.energy() - e0)) < 1e-6 * scale
    nm = simulate_implicit(model, q0, v0, t_final=1.0, dt=0.005)
    drift = nm.energy() - e0
    assert np.max(np.abs(drift)) < 5e-3 * scale
    nm2 = simulate_implicit(model, q0, v0, t_final=1.0, dt=0.0025)
    assert np.max(np.abs(nm2.energy() - e0)) < 0.3 * np.max(np.abs(drift))
    ga = simulate_implicit(model, q0, v0, t_final=1.0, dt=0.005, scheme=GeneralizedAlpha(0.6))
    assert ga.energy()[-1] <= e0 + 1e-9


def test_convergence_error_names_step_time_residual_iterations(case):
    model, q0, qdot0, _ = case
    with pytest.raises(ConvergenceError, match=r"step 1 \(t = 0.1 s\).*residual.*after 1 Newton"):
        simulate_implicit(model, q0, qdot0, t_final=0.2, dt=0.1, max_iterations=1)


def test_integrator_argument_errors(case):
    model, q0, qdot0, _ = case
    with pytest.raises(ModelError, match="q0 and qdot0 must have shape"):
        simulate_rk4(model, q0[:1], qdot0, t_final=1.0, dt=0.1)
    with pytest.raises(ModelError, match="whole multiple"):
        simulate_rk4(model, q0, qdot0, t_final=1.0, dt=0.3)
    with pytest.raises(ModelError, match="method must be one of"):
        simulate_scipy(model, q0, qdot0, t_final=1.0, method="Euler")


def test_generated_rk4_of_a_branched_tree_equals_rk4_of_the_lagrange_model():
    """The compiled RK4 (``ctmm.simulate(..., compiled=True)``, generated from the element definitions) on a
    branched revolute tree with a tilted ground, spring-damper and actuated hinges: accelerations equal to
    the independent Lagrange model, and its run equal to the same RK4 on the Lagrange equations (round-off)."""
    pytest.importorskip("casadi")
    from ctmm.compiled_scene import CompiledScene, simulate_rk4_generated
    from ctmm.ode import integrate_rk4, second_order_rate
    from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody, SpringDamperHinge
    fork = RigidBody("fork", mass=1.2, inertia=0.1, center_of_mass=(0.4, 0.1),
                     outboard={"l": (1.0, 0.3), "r": (0.8, -0.4)})
    model = PlanarModel("t", [fork, RigidBody.uniform_link("a", mass=0.5, length=0.7),
                              RigidBody.uniform_link("b", mass=0.4, length=0.5),
                              Fixed("g", angle=0.3),
                              SpringDamperHinge("k0", parent="g", child="fork", stiffness=8.0,
                                                damping=0.2, rest_angle=0.1),
                              ActuatedHinge("m", parent="fork.l", child="a", torque=0.5, kp=3.0,
                                            kd=0.1, reference=0.2),
                              SpringDamperHinge("k2", parent="fork.r", child="b", stiffness=2.0,
                                                damping=0.05)])
    lagrange = PlanarLagrange(model)
    q, v = np.array([0.2, 1.0, -0.7]), np.array([0.5, -1.0, 2.0])
    expected = lagrange.accelerations(q, v, 0.0)
    assert np.max(np.abs(CompiledScene(model).accelerations(q, v) - expected)) <= 1e-12 * np.max(np.abs(expected))
    generated = simulate_rk4_generated(model, q, v, t_final=0.5, dt=1e-3, store_every=10)
    rate = second_order_rate(lambda x, y, t: lagrange.accelerations(x, y, t), 3)
    rows = []
    integrate_rk4(rate, np.concatenate([q, v]), h=1e-3, n_steps=500,
                  after_step=lambda k, t, y: rows.append(y.copy()) if k % 10 == 0 else None)
    rows = np.array(rows)
    assert np.allclose(generated.t[1:], np.arange(1, 51) * 1e-2, rtol=0, atol=1e-14)
    assert np.max(np.abs(generated.q[1:] - rows[:, :3])) < 1e-12
    assert np.max(np.abs(generated.qdot[1:] - rows[:, 3:])) < 1e-12
    assert np.max(np.abs(generated.q[-1] - q)) > 0.1                 # it moved


@pytest.mark.parametrize("seed,base", [(11, "free"), (12, "fixed"), (13, "pinned")])
def test_implicit_on_random_trees_is_second_order(seed, base):
    """Trees with floating / welded / pinned bases, driven and actuated hinges and loads."""
    model = random_tree(seed, 4, base=base, allow_translation=False)
    q0, qdot0, _ = random_state(model, seed)
    qdot0 = 0.3 * qdot0
    ref = PlanarLagrange(model).simulate(q0, qdot0, 0.5, t_eval=[0.5])
    q_ref = ref.y[: model.n_coordinates, -1]
    errors = []
    for dt in (0.01, 0.005):
        sim = simulate_implicit(model, q0, qdot0, t_final=0.5, dt=dt)
        errors.append(np.max(np.abs(sim.q[-1] - q_ref)))
        assert sim.iterations.max() <= 4
    assert 1.9 <= np.log2(errors[0] / errors[1]) <= 2.1


def test_translational_spring_hinge_orders_and_energy():
    """Elbow with rotary and isotropic translational springs (3-DOF hinge)."""
    from ctmm.planar import ElasticHinge, Pinned, PlanarModel, RigidBody, SpringDamperHinge
    def arm(damping):
        elbow = (SpringDamperHinge("elbow", stiffness=8.0, damping=0.05, rest_angle=0.3,
                                   translational_stiffness=200.0, translational_damping=0.5)
                 if damping else
                 ElasticHinge("elbow", stiffness=8.0, rest_angle=0.3,
                              translational_stiffness=200.0))
        return PlanarModel.chain("arm", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0,
                                                                             length=1.0),
                                         elbow, RigidBody.uniform_link("b", mass=0.6, length=0.7)])
    model = arm(True)
    assert model.coordinates == ("a.theta", "b.dx", "b.dy", "b.theta")
    q0, v0 = np.array([0.2, 0.01, -0.02, 0.6]), np.zeros(4)
    T_ = 0.5
    q_ref = PlanarLagrange(model).simulate(q0, v0, T_, t_eval=[T_]).y[:4, -1]
    dts = [0.004, 0.002, 0.001]
    implicit = [np.max(np.abs(simulate_implicit(model, q0, v0, t_final=T_, dt=dt).q[-1] - q_ref))
                for dt in dts]
    assert 1.9 <= _slope(dts, implicit) <= 2.1, implicit
    rk4 = [np.max(np.abs(simulate_rk4(model, q0, v0, t_final=T_, dt=dt).q[-1] - q_ref))
           for dt in dts[:2]]
    assert 3.7 <= np.log2(rk4[0] / rk4[1]) <= 4.3, rk4
    undamped = arm(False)
    sim = simulate_rk4(undamped, q0, v0, t_final=T_, dt=0.002)
    energy = sim.energy()
    assert np.max(np.abs(energy - energy[0])) < 1e-7 * 20.0
