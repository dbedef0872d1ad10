"""Houbolt restarts its start-up where a zero-order-held input jumps (``Scheme.restart``, docs/schemes.md).

Independent references: the exact sampled-data solution of one mass with a held P force (matrix exponential per
sample, ``test_compiled_cosim.sampled_p_loop``); the planar Lagrange model restarted at every sample with the held
torque (``ctmm.reference.planar_lagrange``, DOP853); the spatial global Newton-Euler tree
(``ctmm.reference.spatial_tree``, RK4 at 1 ms) with the held elbow torque.  Without the restart Houbolt's error
halves per halving of ``dt`` on all three (first order); with it the error quarters (second order).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm.planar import ActuatedHinge, SmoothHinge
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.schemes import SCHEMES, Houbolt, Newmark

from _controllers_import import load_controllers
from test_compiled_cosim import assert_same, kernel_cache, sampled_p_loop  # noqa: F401 (fixture)
from test_compiled_cosim_chain import MASS, STIFFNESS, one_mass
from test_planar_control_time import Cell, dop853, pendulum
from test_planar_implicit_loops import KD, KP, TARGET, THETA0, law

KP_MASS, TARGET_MASS, SAMPLE, X0_MASS = 30.0, 0.02, 0.02, 0.05


def p_controller():
    return load_controllers().PID("m.x", "m.force", kp=KP_MASS, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                  sample_time=SAMPLE, reference=TARGET_MASS)


def one_mass_errors(compiled: bool | None) -> tuple[list[float], list]:
    """Largest error at the samples over 0.5 s at ``dt = h/8, h/16`` against the exact sampled-data solution."""
    exact = sampled_p_loop(STIFFNESS, MASS, KP_MASS, TARGET_MASS, SAMPLE, X0_MASS, 25)
    errors, runs = [], []
    for per_sample in (8, 16):
        run = ctmm.simulate(one_mass(), 0.5, SAMPLE / per_sample, method="houbolt", x0={"m": X0_MASS},
                            controllers=[p_controller()], compiled=compiled)
        errors.append(float(np.max(np.abs(run["m.x"][::per_sample] - exact))))
        runs.append(run)
    return errors, runs


def test_the_scheme_states_its_restart():
    """Only the multistep scheme declares a start-up; its restart forgets the memory, the others keep theirs."""
    assert Houbolt().start_up_steps == 2 and Houbolt().restart_on_input_jump
    for name, kind in SCHEMES.items():
        if kind is not Houbolt:
            assert kind().start_up_steps == 0 and not kind().restart_on_input_jump, name
    x, histories = np.array([[0.1]]), {}
    for scheme in (Houbolt(), Newmark()):
        history = scheme.start_history(x, 0.0 * x, -x)
        for _ in range(3):
            history = scheme.update(history, np.array([[1e-3]]), 1e-3, scheme.coefficients(history, 1e-3))
        before = Houbolt().coefficients(history, 1e-3)
        scheme.restart(history)
        assert history.steps == (0 if scheme.restart_on_input_jump else 3)
        histories[scheme.name] = history
    restarted = Houbolt().coefficients(histories["houbolt"], 1e-3)   # Newmark's start-up step from the same state
    newmark = Newmark().coefficients(histories["houbolt"], 1e-3)
    assert restarted.C == newmark.C and np.array_equal(restarted.x_pred, newmark.x_pred)
    assert before.C != newmark.C                                     # before the restart: Houbolt's differences


def test_python_chain_with_a_sampled_controller_is_second_order():
    """Measured 9.3e-6 and 2.5e-6 m (3.7x); without the restart 2.0e-4 and 1.0e-4 m (2.0x)."""
    errors, _ = one_mass_errors(None)
    assert 3.5 < errors[0] / errors[1] < 4.3, errors
    assert errors[1] < 4e-6, errors


def test_generated_chain_with_a_sampled_controller_is_second_order_and_equals_the_python_path():
    errors, runs = one_mass_errors(True)
    assert runs[1].scheme_name == "houbolt-generated"
    assert 3.5 < errors[0] / errors[1] < 4.3, errors
    assert errors[1] < 4e-6, errors
    python = ctmm.simulate(one_mass(), 0.5, SAMPLE / 16, method="houbolt", x0={"m": X0_MASS},
                           controllers=[p_controller()])
    assert_same(runs[1], python, ["m.x", "m.v", "m.a", "k.f"])


def test_planar_pendulum_with_a_sampled_pd_is_second_order():
    """SaturatedPD every 10 ms vs the Lagrange pendulum restarted at every sample with the held torque: measured
    3.1e-6 and 8.1e-7 rad (3.8x) at dt = 1.25, 0.625 ms; without the restart 1.1e-3 and 5.7e-4 rad."""
    h, t_final = 0.01, 0.3
    cell = Cell()
    lagrange = PlanarLagrange(pendulum(ActuatedHinge("pivot", torque=cell)))
    n_samples = int(round(t_final / h))
    states, y = [np.array([THETA0, 0.0])], np.array([THETA0, 0.0])
    for k in range(n_samples):
        cell.value = law(states[k])
        y = dop853(lambda t, z: np.concatenate([z[1:], lagrange.accelerations(z[:1], z[1:], t)]),
                   (k * h, (k + 1) * h), y).y[:, -1]
        states.append(y)
    theta = np.array(states)[:, 0]
    errors = []
    for dt in (1.25e-3, 6.25e-4):
        pd = load_controllers().SaturatedPD(("rod.theta", "rod.omega"), ("pivot.torque",), kp=KP, kd=KD,
                                            reference=TARGET, sample_time=h)
        run = ctmm.simulate(pendulum(SmoothHinge("pivot")), t_final, dt, method="houbolt", x0=[THETA0],
                            controllers=[pd])
        rows = np.round(np.arange(n_samples + 1) * h / dt).astype(int)
        errors.append(float(np.max(np.abs(run["rod.theta"][rows] - theta))))
    assert abs(math.log2(errors[0] / errors[1]) - 2.0) < 0.25, errors
    assert errors[1] < 2e-6, errors


@pytest.mark.slow
def test_spatial_arm_with_a_sampled_pd_is_second_order():
    """A saturated elbow PD every 20 ms vs the global Newton-Euler tree (RK4 at 2 ms) with the held torque over
    0.1 s: measured 1.7e-3 and 5.3e-4 (3.2x) at dt = 4, 2 ms; without the restart 2.2e-2 and 1.2e-2 (1.9x).  Slow
    (~1.5 s, most of it the reference on the three-joint arm)."""
    from test_spatial_control_time import V0, X0, Reference, _max_state_error, arm, initial

    kp, kd, h, t_final, fine = 4.0, 0.5, 0.02, 0.1, 0.002
    held = [0.0]
    model = arm()
    reference = Reference(model)
    slot, qslot, every = reference.slot["elbow"], reference.qslot["elbow"], int(round(h / fine))

    def elbow(t, q, v, z):
        tau = reference.generalised(reference.sensors(q, v)[1])
        tau[slot] += held[0]
        return tau, np.zeros(0)

    def on_step(k, t, y):
        if k % every == 0:
            held[0] = float(np.clip(kp * (0.2 - y[qslot]) - kd * y[reference.tree.nq + slot], -1.0, 1.0))

    _, q, v, _ = reference.rk4(*initial(model), np.zeros(0), elbow, t_final, fine, on_step=on_step)
    errors = []
    for dt in (0.004, 0.002):
        pd = load_controllers().SaturatedPD(("elbow.angle1", "elbow.angle1_rate"), ("elbow.torque1",), kp=kp, kd=kd,
                                            reference=0.2, limit=1.0, sample_time=h)
        run = ctmm.simulate(model, t_final, dt, method="houbolt", x0=X0, v0=V0, controllers=[pd])
        stride = int(round(dt / fine))
        errors.append(_max_state_error(model, run, q[::stride], v[::stride]))
    assert 2.8 < errors[0] / errors[1] < 4.6, errors             # pre-asymptotic (3.5 at 2 -> 1 ms over 0.2 s)
    assert errors[1] < 1e-3, errors
