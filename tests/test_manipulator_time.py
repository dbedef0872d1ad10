"""Time domain: hub PD (ActuatedHinge) + modal piezo arm (ModalBeam + ModalForce hook) against the
independent Lagrange reference; convergence orders; delays; co-simulation (Python, FMU);
voltage limits; the compiled path (issue 6, D/F)."""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.errors import ModelError, SimulationError
from ctmm.flexible import solve_flexible
from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_MOVE, SEED_PZT_GAIN, CycloidalMove, FlexibleManipulator,
                              HubPD, PZTFeedback, seed_manipulator)
from ctmm.manipulator.compiled import CompiledManipulator
from ctmm.manipulator.controllers import SlopeRateFeedback
from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

from _controllers_import import load_controllers

G_SEED = np.eye(3) * SEED_PZT_GAIN


@pytest.fixture(scope="module")
def seed():
    return seed_manipulator()


@pytest.fixture(scope="module")
def system(seed):
    return FlexibleManipulator(seed, HubPD(SEED_KP, SEED_KD), PZTFeedback(G_SEED), SEED_MOVE)


@pytest.fixture(scope="module")
def reference(seed):
    # the modal beam keeps the centrifugal stiffening in the modal equations only
    return ManipulatorLagrange.from_manipulator(seed, 3, stiffening=True)


def _scale(system, reference):
    """Modal coordinates of the beam (int phi^2 = L) -> mass-normalised ones of the reference."""
    return system.tip_shape / reference.phi_tip


def test_closed_loop_accelerations_and_end_forces_equal_lagrange(seed, system, reference):
    model = system.model()
    sc = _scale(system, reference)
    rng = np.random.default_rng(11)
    for _ in range(4):
        q = np.r_[rng.normal(), 0.02 * rng.normal(size=3)]
        v = np.r_[3 * rng.normal(), 0.3 * rng.normal(size=3)]
        t = float(rng.uniform(0.0, 1.2))
        sol = solve_flexible(model, q, v, t)
        eta, eta_dot = sc * q[1:], sc * v[1:]
        tau = SEED_KP * (SEED_MOVE.angle(t) - q[0]) + SEED_KD * (SEED_MOVE.rate(t) - v[0])
        acc = reference.accelerations(v[0], eta, eta_dot, tau, -G_SEED @ (reference.Psi @ eta_dot))
        tmm = np.r_[sol.qddot[0], sc * sol.qddot[1:]]
        assert np.abs(tmm - acc).max() <= 1e-12 * np.abs(acc).max()
        f = reference.clamp_load(v[0], eta, eta_dot, acc)          # hub-frame axes
        c, s = np.cos(q[0]), np.sin(q[0])
        clamp = np.r_[c * f[0] - s * f[1], s * f[0] + c * f[1], f[2]]
        scale = np.abs(clamp).max()
        np.testing.assert_allclose(sol.joint_force[model.body_index("arm")], clamp, atol=1e-11 * scale)
        np.testing.assert_allclose(sol.joint_force[model.body_index("hub")], np.r_[clamp[:2], tau],
                                   atol=1e-11 * scale)


def test_embedded_pzt_law_is_the_modal_damping_of_the_seed_law(seed, system, reference):
    # D_pzt = Psi^T diag(c_a) G Psi in the beam's coordinates equals c_a Psi_ref^T G Psi_ref rescaled
    sc = _scale(system, reference)
    D_ref = reference.Psi.T @ (reference.ca[:, None] * G_SEED) @ reference.Psi
    np.testing.assert_allclose(system.pzt_damping, sc[:, None] * D_ref * sc[None, :], rtol=1e-12)
    assert np.all(np.linalg.eigvalsh(system.pzt_damping) > -1e-12)   # dissipative


def test_compiled_sweep_equals_the_python_sweep(system):
    compiled = CompiledManipulator(system.manipulator, system.pd, system.pzt, system.reference, block=5, chunks=40)
    model = system.model()
    from ctmm.planar import accelerations

    rng = np.random.default_rng(5)
    for _ in range(3):
        q = np.r_[rng.normal(), 0.01 * rng.normal(size=3)]
        v = np.r_[2 * rng.normal(), 0.1 * rng.normal(size=3)]
        t = float(rng.uniform(0.0, 1.2))
        a = accelerations(model, q, v, t)
        assert np.abs(compiled.accelerations(q, v, t) - a).max() <= 1e-13 * np.abs(a).max()
    fast = compiled.simulate(0.2, 0.002)
    slow = system.simulate(0.2, 0.002, store_every=5)
    assert np.abs(fast.tip_deflection - slow.tip_deflection).max() < 1e-14


@pytest.mark.parametrize("method, dts, order", [("rk4", (0.01, 0.005), 4.0), ("newmark", (0.01, 0.005), 2.0)])
def test_tip_and_hub_match_the_reference_with_the_right_order(system, reference, method, dts, order):
    T = 0.4
    ref = reference.simulate(T, reference=SEED_MOVE, kp=SEED_KP, kd=SEED_KD, pzt_gains=G_SEED,
                             t_eval=np.linspace(0.0, T, 41))
    peak = np.abs(ref.tip_deflection).max()
    errors = []
    for dt in dts:
        sim = system.simulate(T, dt, method=method, store_every=int(round(0.01 / dt)))
        errors.append(np.abs(sim.tip_deflection - ref.tip_deflection).max() / peak)
        assert np.abs(sim.theta - ref.theta).max() < 1e-3 * np.abs(ref.theta).max()
    assert errors[-1] < 1e-3                                   # <= 0.1 % of the peak
    assert abs(np.log2(errors[0] / errors[1]) - order) < 0.3   # measured 4.03 and 2.00


def test_pzt_control_reduces_the_residual_vibration(seed):
    """Seed Fig. 9.43b: the same slew with and without the PZT loops (compiled RK4, 4 s)."""
    pd = HubPD(SEED_KP, SEED_KD)
    runs = {}
    for label, pzt in (("pd", None), ("pd+pzt", PZTFeedback(G_SEED))):
        system = FlexibleManipulator(seed, pd, pzt, SEED_MOVE)
        runs[label] = CompiledManipulator(seed, pd, pzt, SEED_MOVE, block=5, chunks=80).simulate(4.0, 0.002)
    t = runs["pd"].t
    after = t > SEED_MOVE.duration + 0.5
    rms = {k: np.sqrt(np.mean(r.tip_deflection[after] ** 2)) for k, r in runs.items()}
    assert rms["pd+pzt"] < 0.35 * rms["pd"], rms                  # measured 0.24
    assert np.abs(runs["pd+pzt"].voltages).max() < seed.voltage_limit   # 129 V: no saturation needed
    last = t > 3.0                                                 # hub still tracks the target
    assert np.abs(runs["pd+pzt"].theta[last] - SEED_MOVE.final_angle).max() < 1e-3


def test_delayed_loops_match_the_method_of_steps(seed, reference):
    system = FlexibleManipulator(seed, HubPD(SEED_KP, SEED_KD, delay=0.01), PZTFeedback(G_SEED, delay=0.002),
                                 SEED_MOVE)
    T = 0.3
    ref = reference.simulate(T, reference=SEED_MOVE, kp=SEED_KP, kd=SEED_KD, pd_delay=0.01, pzt_gains=G_SEED,
                             pzt_delay=0.002, t_eval=np.linspace(0.0, T, 31))
    peak = np.abs(ref.tip_deflection).max()
    sim = system.simulate(T, 0.002, store_every=5)
    assert np.abs(sim.tip_deflection - ref.tip_deflection).max() < 1e-5 * peak     # measured 8e-9
    assert np.abs(sim.voltages - ref.voltages).max() < 1e-3
    with pytest.raises(ModelError, match="shorter than the step"):
        system.simulate(0.01, 0.005)


def test_embedded_cosimulated_and_fmu_controllers_agree_as_the_sample_time_shrinks(seed, tmp_path):
    controllers = load_controllers()
    from ctmm.control.fmu import FMUController, build_fmu

    hold = CycloidalMove(0.3, 1.0, start_angle=0.3)           # set point 0.3 rad from rest at 0
    system = FlexibleManipulator(seed, HubPD(SEED_KP, SEED_KD), PZTFeedback(G_SEED), hold)
    T, dt = 0.2, 0.002
    embedded = system.simulate(T, dt, theta0=0.0, store_every=5)
    peak = np.abs(embedded.tip_deflection).max()
    errors = []
    for Ts in (0.004, 0.002):           # (8 ms destabilises the PZT loop: ZOH ~ 4 ms delay)
        python = [controllers.SaturatedPD(("hub.theta", "hub.theta_dot"), ("motor.torque",), kp=SEED_KP, kd=SEED_KD,
                                          reference=0.3, sample_time=Ts),
                  SlopeRateFeedback(seed.patch_names, G_SEED, sample_time=Ts)]
        sim = system.simulate(T, dt, theta0=0.0, controllers=python, store_every=5)
        errors.append(np.abs(sim.tip_deflection - embedded.tip_deflection).max() / peak)
    assert errors[1] < 0.6 * errors[0] and errors[1] < 0.02      # first order (zero-order hold)
    path = build_fmu(controllers.fmu_source("pd_controller"), tmp_path)
    fmus = [FMUController(path, inputs={"y": "hub.theta", "ydot": "hub.theta_dot"}, outputs={"u": "motor.torque"},
                          parameters={"kp": SEED_KP, "kd": SEED_KD, "reference": 0.3, "limit": 0.0}, sample_time=0.002)]
    for p in seed.patch_names:                                 # V = -Ka slope_rate with kp = 0
        fmus.append(FMUController(path, inputs={"y": f"{p}.slope", "ydot": f"{p}.slope_rate"},
                                  outputs={"u": f"{p}.voltage"},
                                  parameters={"kp": 0.0, "kd": SEED_PZT_GAIN, "limit": 0.0}, sample_time=0.002))
    fmu = system.simulate(T, dt, theta0=0.0, controllers=fmus, store_every=5)
    np.testing.assert_array_equal(fmu.tip_deflection, sim.tip_deflection)   # same law, bit for bit


def test_voltage_limit_policies(seed):
    fast = CycloidalMove(0.6, 0.4)                              # needs ~280 V at t = 0.18 s
    T, dt = 0.25, 0.002
    law = PZTFeedback(G_SEED)
    sim = FlexibleManipulator(seed, HubPD(SEED_KP, SEED_KD), law, fast).simulate(T, dt)
    assert sim.limit_exceeded and sim.peak_voltage > 250.0 and sim.time_over_limit > 0
    saturate = FlexibleManipulator(seed, HubPD(SEED_KP, SEED_KD), PZTFeedback(G_SEED, on_limit="saturate"), fast)
    sat = saturate.simulate(T, dt)
    assert np.abs(sat.voltages).max() <= 200.0 + 1e-9 and sat.saturated.any()
    assert sat.peak_voltage > 200.0                              # the unsaturated demand is reported
    assert np.abs(sat.tip_deflection - sim.tip_deflection).max() > 0
    raising = FlexibleManipulator(seed, HubPD(SEED_KP, SEED_KD), PZTFeedback(G_SEED, on_limit="raise"), fast)
    with pytest.raises(SimulationError, match=r"voltage limit exceeded at t = .* patch 'pzt1' needs .* limit 200 V"):
        raising.simulate(T, dt)


def test_bad_controller_wiring_is_reported(seed, system):
    controllers = load_controllers()
    wrong = controllers.SaturatedPD(("hub.angle", "hub.theta_dot"), ("motor.force",), kp=1.0, kd=0.1)
    with pytest.raises(ModelError, match=r"unknown input of controller 0 'hub.angle'; available: .*hub.theta"):
        system.simulate(0.01, 0.005, controllers=[wrong])
    late = controllers.SaturatedPD(("hub.theta", "hub.theta_dot"), ("motor.torque",), kp=1.0, kd=0.1,
                                   sample_time=0.0025)
    with pytest.raises(ModelError, match="sample_time 0.0025 must be a whole multiple of dt"):
        system.simulate(0.01, 0.002, controllers=[late])
    with pytest.raises(ModelError, match="method must be one of"):
        system.simulate(0.01, 0.005, method="euler")
    with pytest.raises(ModelError, match="compiled manipulator path needs"):
        CompiledManipulator(seed, HubPD(1.0, 0.1, delay=0.01), None, SEED_MOVE)
