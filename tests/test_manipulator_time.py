"""Time domain of the manipulator scene (hub on a torque hinge + modal piezo arm, the PD and PZT laws as
``Feedback`` loops on its ports, run by ``ctmm.simulate``) against the independent Lagrange reference
(ctmm/reference/manipulator_lagrange.py): closed-loop accelerations and end forces, convergence orders,
delays (method of steps), co-simulation (Python, FMU), voltage limits, the compiled path."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import StaticGainController
from ctmm.errors import ModelError, SimulationError
from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_MOVE, SEED_PZT_GAIN, CycloidalMove, HubPD, PZTFeedback,
                              manipulator_plant, manipulator_scene, scene_references, seed_manipulator)
from ctmm.manipulator.compiled import CompiledManipulator
from ctmm.planar.ports import PlanarPorts
from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

from _controllers_import import load_controllers
from test_manipulator_scene import closed_loop_solution

G_SEED = np.eye(3) * SEED_PZT_GAIN
PD = HubPD(SEED_KP, SEED_KD)
TIP = "arm.tip.w"


@pytest.fixture(scope="module")
def seed():
    return seed_manipulator()


@pytest.fixture(scope="module")
def scene(seed):
    return manipulator_scene(seed, pd=PD, pzt=PZTFeedback(G_SEED))


@pytest.fixture(scope="module")
def reference(seed):
    # the modal beam keeps the centrifugal stiffening in the modal equations only
    return ManipulatorLagrange.from_manipulator(seed, 3, stiffening=True)


def _scale(scene, reference):
    """Modal coordinates of the beam (int phi^2 = L) -> mass-normalised ones of the reference."""
    return scene.plant.bodies[scene.plant.body_index("arm")].data.tip_phi / reference.phi_tip


def pzt_controller(manipulator, gains, sample_time=None, limit=None):
    """The PZT law ``V = -G dtheta_dot`` as a co-simulated static gain on the arm's station ports:
    slope rates at the patch ends in, the patch moment pairs ``-/+ c_a V`` out."""
    names = manipulator.patch_names
    P, ca = len(names), manipulator.moments_per_volt
    inputs = [f"arm.{p}_x{end}.slope_rate" for p in names for end in (1, 2)]
    outputs = [f"arm.{p}_x{end}.moment" for p in names for end in (1, 2)]
    C = np.zeros((P, 2 * P))                         # slope-rate difference over each patch
    B = np.zeros((2 * P, P))                         # voltage -> moment pair
    for j in range(P):
        C[j, 2 * j:2 * j + 2] = (-1.0, 1.0)
        B[2 * j:2 * j + 2, j] = (-ca[j], ca[j])
    limits = None if limit is None else np.repeat(ca * limit, 2)
    return StaticGainController(inputs, outputs, B @ (-np.asarray(gains)) @ C, limits=limits,
                                sample_time=sample_time)


def test_closed_loop_accelerations_and_end_forces_equal_lagrange(scene, reference):
    sc = _scale(scene, reference)
    model = scene.plant
    references = scene_references(PD, SEED_MOVE)
    rng = np.random.default_rng(11)
    for _ in range(4):
        q = np.r_[rng.normal(), 0.02 * rng.normal(size=3)]
        v = np.r_[3 * rng.normal(), 0.3 * rng.normal(size=3)]
        t = float(rng.uniform(0.0, 1.2))
        sol, _ = closed_loop_solution(scene, references, q, v, t)
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


def test_compiled_sweep_equals_the_scene(seed, scene):
    compiled = CompiledManipulator(seed, PD, PZTFeedback(G_SEED), SEED_MOVE, block=5, chunks=40)
    references = scene_references(PD, SEED_MOVE)
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = np.r_[rng.normal(), 0.01 * rng.normal(size=3)]
        v = np.r_[2 * rng.normal(), 0.1 * rng.normal(size=3)]
        t = float(rng.uniform(0.0, 1.2))
        a = closed_loop_solution(scene, references, q, v, t)[0].qddot
        assert np.abs(compiled.accelerations(q, v, t) - a).max() <= 1e-13 * np.abs(a).max()
    fast = compiled.simulate(0.2, 0.002)
    slow = ctmm.simulate(scene, 0.2, 0.002, references=references, outputs=[TIP], store_every=5)
    np.testing.assert_allclose(slow.time, fast.t, atol=1e-15)
    assert np.abs(fast.tip_deflection - slow[TIP]).max() < 1e-14


@pytest.mark.parametrize("method, dts, order", [("rk4", (0.01, 0.005), 4.0), ("newmark", (0.01, 0.005), 2.0)])
def test_tip_and_hub_match_the_reference_with_the_right_order(scene, reference, method, dts, order):
    T = 0.4
    ref = reference.simulate(T, reference=SEED_MOVE, kp=SEED_KP, kd=SEED_KD, pzt_gains=G_SEED,
                             t_eval=np.linspace(0.0, T, 41))
    peak = np.abs(ref.tip_deflection).max()
    errors = []
    for dt in dts:
        sim = ctmm.simulate(scene, T, dt, method=method, references=scene_references(PD, SEED_MOVE), outputs=[TIP],
                            store_every=int(round(0.01 / dt)))
        errors.append(np.abs(sim[TIP] - ref.tip_deflection).max() / peak)
        assert np.abs(sim["hub.theta"] - ref.theta).max() < 1e-3 * np.abs(ref.theta).max()
    assert errors[-1] < 1e-3                                   # <= 0.1 % of the peak
    assert abs(np.log2(errors[0] / errors[1]) - order) < 0.3   # measured 4.03 and 2.00


def test_pzt_control_reduces_the_residual_vibration(seed):
    """Seed Fig. 9.43b: the same slew with and without the PZT loops (compiled RK4, 4 s)."""
    runs = {}
    for label, pzt in (("pd", None), ("pd+pzt", PZTFeedback(G_SEED))):
        runs[label] = CompiledManipulator(seed, PD, pzt, SEED_MOVE, block=5, chunks=80).simulate(4.0, 0.002)
    t = runs["pd"].t
    after = t > SEED_MOVE.duration + 0.5
    rms = {k: np.sqrt(np.mean(r.tip_deflection[after] ** 2)) for k, r in runs.items()}
    assert rms["pd+pzt"] < 0.35 * rms["pd"], rms                  # measured 0.24
    assert np.abs(runs["pd+pzt"].voltages).max() < seed.voltage_limit   # 129 V: no saturation needed
    last = t > 3.0                                                 # hub still tracks the target
    assert np.abs(runs["pd+pzt"].theta[last] - SEED_MOVE.final_angle).max() < 1e-3


def test_delayed_loops_match_the_method_of_steps(seed, reference):
    pd = HubPD(SEED_KP, SEED_KD, delay=0.01)
    scene = manipulator_scene(seed, pd=pd, pzt=PZTFeedback(G_SEED, delay=0.002))
    T = 0.3
    ref = reference.simulate(T, reference=SEED_MOVE, kp=SEED_KP, kd=SEED_KD, pd_delay=0.01, pzt_gains=G_SEED,
                             pzt_delay=0.002, t_eval=np.linspace(0.0, T, 31))
    peak = np.abs(ref.tip_deflection).max()
    sim = ctmm.simulate(scene, T, 0.002, references=scene_references(pd, SEED_MOVE), outputs=[TIP], store_every=5)
    assert set(sim.info["loops"].values()) == {"history"}
    assert np.abs(sim[TIP] - ref.tip_deflection).max() < 1e-5 * peak           # measured 8e-9
    voltages = np.column_stack([sim[f"{p}.u"] for p in seed.patch_names])
    assert np.abs(voltages - ref.voltages).max() < 1e-3
    with pytest.raises(ModelError, match="shorter than the step"):
        ctmm.simulate(scene, 0.01, 0.005)


def test_embedded_cosimulated_and_fmu_controllers_agree_as_the_sample_time_shrinks(seed, tmp_path):
    controllers = load_controllers()
    from ctmm.control.fmu import FMUController, build_fmu

    hold = CycloidalMove(0.3, 1.0, start_angle=0.3)           # set point 0.3 rad from rest at 0
    T, dt, start = 0.2, 0.002, {"hub.theta": 0.0}
    embedded = ctmm.simulate(manipulator_scene(seed, pd=PD, pzt=PZTFeedback(G_SEED)), T, dt, x0=start,
                             references=scene_references(PD, hold), outputs=[TIP], store_every=5)
    plant = manipulator_plant(seed)
    peak = np.abs(embedded[TIP]).max()
    errors = []
    for Ts in (0.004, 0.002):           # (8 ms destabilises the PZT loop: ZOH ~ 4 ms delay)
        python = [controllers.SaturatedPD(("hub.theta", "hub.theta_dot"), ("motor.torque",), kp=SEED_KP, kd=SEED_KD,
                                          reference=0.3, sample_time=Ts),
                  pzt_controller(seed, G_SEED, sample_time=Ts)]
        sim = ctmm.simulate(plant, T, dt, x0=start, controllers=python, outputs=[TIP], store_every=5)
        errors.append(np.abs(sim[TIP] - embedded[TIP]).max() / peak)
    assert errors[1] < 0.6 * errors[0] and errors[1] < 0.02      # first order (zero-order hold)
    path = build_fmu(controllers.fmu_source("pd_controller"), tmp_path)
    fmu = FMUController(path, inputs={"y": "hub.theta", "ydot": "hub.theta_dot"}, outputs={"u": "motor.torque"},
                        parameters={"kp": SEED_KP, "kd": SEED_KD, "reference": 0.3, "limit": 0.0}, sample_time=0.002)
    run = ctmm.simulate(plant, T, dt, x0=start, controllers=[fmu, python[1]], outputs=[TIP], store_every=5)
    np.testing.assert_array_equal(run[TIP], sim[TIP])                # same law, bit for bit


def test_the_static_gain_controller_is_the_pzt_law(seed, scene):
    """At one state the co-simulated static gain writes the moments of the embedded PZT loops."""
    ports = PlanarPorts(scene.plant)
    rng = np.random.default_rng(3)
    q, v = np.r_[0.2, 0.01 * rng.normal(size=3)], np.r_[1.0, 0.3 * rng.normal(size=3)]
    controller = pzt_controller(seed, G_SEED, limit=seed.voltage_limit)
    y = ports.values(ports.resolve(list(controller.inputs)), q, v, 0.0)
    moments, clipped = controller.step(0.0, y, controller.init(0.0))
    sensors = scene.sensors()
    sensed = scene.sensed(dict(zip(sensors, ports.values(ports.resolve(sensors), q, v, 0.0))))
    loops = scene.actuation({p: float(np.clip(-sensed[p], -seed.voltage_limit, seed.voltage_limit))
                             for p in seed.patch_names})
    assert loops.get("motor.torque", 0.0) == 0.0                      # only the patch loops were given
    expected = [loops[name] for name in controller.outputs]
    np.testing.assert_allclose(moments, expected, rtol=1e-13, atol=1e-15)
    assert clipped == int(np.abs(sensed["pzt1"]) > seed.voltage_limit)
    with pytest.raises(ModelError, match=r"gains must have shape \(1, 2\)"):
        StaticGainController(["a.x", "a.v"], ["b.force"], [[1.0]])
    with pytest.raises(ModelError, match="limits must be 1 values > 0"):
        StaticGainController(["a.x"], ["b.force"], [[1.0]], limits=[0.0])
    with pytest.raises(ModelError, match="inputs must be a non-empty sequence"):
        StaticGainController(["a.x", "a.x"], ["b.force"], [[1.0, 2.0]])


def test_voltage_limit_policies(seed):
    fast = CycloidalMove(0.6, 0.4)                              # needs ~280 V at t = 0.18 s
    T, dt = 0.25, 0.002

    def run(on_limit):
        scene = manipulator_scene(seed, pd=PD, pzt=PZTFeedback(G_SEED, on_limit=on_limit))
        return ctmm.simulate(scene, T, dt, references=scene_references(PD, fast), outputs=[TIP])

    report = run("report")                                      # unsaturated: the demand is the result
    volts = np.column_stack([report[f"{p}.u"] for p in seed.patch_names])
    over = np.any(np.abs(volts) > seed.voltage_limit, axis=1)
    assert np.abs(volts).max() > 250.0 and over.any()
    sat = run("saturate")
    assert np.abs(sat["pzt1.u"]).max() <= 200.0 + 1e-9 and sat["pzt1.saturated"].any()
    assert np.abs(sat["pzt1.u_demand"]).max() > 200.0           # the unsaturated demand is reported
    assert sat.info["time_saturated_s"]["pzt1"] > 0
    assert np.abs(sat[TIP] - report[TIP]).max() > 0
    with pytest.raises(ModelError, match=r"on_limit='raise' .* CompiledManipulator"):
        manipulator_scene(seed, pd=PD, pzt=PZTFeedback(G_SEED, on_limit="raise"))
    raising = CompiledManipulator(seed, PD, PZTFeedback(G_SEED, on_limit="raise"), fast, chunks=25)
    with pytest.raises(SimulationError, match=r"voltage limit exceeded at t = .* patch 'pzt1' needs .* > 200 V") \
            as info:
        raising.simulate(T, dt)
    first = float(report.time[np.argmax(over)])                  # the scene's first row above the limit
    assert info.value.time == pytest.approx(first, abs=1e-12)
    assert info.value.partial_result.t[-1] < first and np.abs(info.value.partial_result.voltages).max() <= 200.0


def test_bad_controller_wiring_is_reported(seed, scene):
    controllers = load_controllers()
    plant = manipulator_plant(seed)
    wrong = controllers.SaturatedPD(("hub.angle", "hub.theta_dot"), ("motor.force",), kp=1.0, kd=0.1)
    with pytest.raises(ModelError, match=r"hub.angle"):
        ctmm.simulate(plant, 0.01, 0.005, controllers=[wrong])
    late = controllers.SaturatedPD(("hub.theta", "hub.theta_dot"), ("motor.torque",), kp=1.0, kd=0.1,
                                   sample_time=0.0025)
    with pytest.raises(ModelError, match="sample_time 0.0025 must be a whole multiple of dt"):
        ctmm.simulate(plant, 0.01, 0.002, controllers=[late])
    with pytest.raises(ModelError, match="method must be 'rk4'"):
        ctmm.simulate(scene, 0.01, 0.005, method="euler")
    with pytest.raises(ModelError, match="compiled manipulator path needs"):
        CompiledManipulator(seed, HubPD(1.0, 0.1, delay=0.01), None, SEED_MOVE)
