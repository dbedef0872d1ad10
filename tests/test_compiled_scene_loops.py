"""Loops closed inside generated kernels (:mod:`ctmm.compiled_loops`, :mod:`ctmm.compiled_control`).

Independent checks:

* the symbolic sensors against the numpy ports (:func:`ctmm.planar.ports.sensor_values`);
* real-time loops and an LTI controller against the Lagrange model integrated by DOP853
  (:class:`ctmm.reference.planar_lagrange.PlanarLagrange`), at fourth order;
* a delayed loop against the method of steps (DOP853 on segments of one delay);
* the numpy path (``ctmm.simulate`` without ``compiled``) of the same controlled model, to round-off.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate

import ctmm
from ctmm.compiled_control import simulate_controlled_generated
from ctmm.compiled_loops import ClosedLoops
from ctmm.compiled_references import SymbolicReference
from ctmm.compiled_planar_sensors import SymbolicKinematics, sensor_expression
from ctmm.control import Feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.errors import ModelError, SimulationError
from ctmm.flexible import ModalBeam
from ctmm.planar import ActuatedHinge, Fixed, FreeBase, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.elements import FixedMounting
from ctmm.planar.ports import PlanarPorts, sensor_values
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.signals import Harmonic, Step

from test_compiled_scene import _state, beam_tree, hub_beam, rigid_tree

casadi = pytest.importorskip("casadi")


@pytest.fixture(autouse=True, scope="module")
def _cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CTMM_CACHE", str(tmp_path_factory.mktemp("kernels")))
        yield


def station_beam() -> PlanarModel:
    """Pinned hub, welded modal beam with two stations, a hinged link at its tip, on a free base."""
    beam = ModalBeam("arm", length=1.2, bending_stiffness=4.0, mass_per_length=0.6, n_modes=3,
                     stations={"s1": 0.3, "s2": 0.9}, outboard={"tip": 1.2}, stiffness_damping=1e-3)
    return PlanarModel("station_beam", [
        FreeBase("f", child="hub"), RigidBody("hub", mass=1.5, inertia=0.08, center_of_mass=(0.02, 0.0),
                                              outboard=(0.15, 0.05)),
        FixedMounting("mount", parent="hub", child="arm", angle=0.2), beam,
        SmoothHinge("h", parent="arm.tip", child="link"), RigidBody.uniform_link("link", mass=0.3, length=0.4)],
        gravity=(0.0, -9.81))


@pytest.mark.parametrize("build", [rigid_tree, hub_beam, beam_tree, station_beam])
def test_symbolic_sensors_equal_the_numpy_ports(build):
    """Every sensor of the model (angles, rates, points, stations, coordinates) as a casadi expression
    equals the numpy port at random states."""
    model = build()
    ports = PlanarPorts(model)
    names = sorted(ports.sensors)
    q, v = casadi.SX.sym("q", model.n_coordinates), casadi.SX.sym("v", model.n_coordinates)
    kinematics = SymbolicKinematics(model, q, v)
    function = casadi.Function("s", [q, v], [casadi.vertcat(*[sensor_expression(ports, n, kinematics)
                                                              for n in names])])
    for seed in range(3):
        q0, v0 = _state(model, seed)
        np.testing.assert_allclose(np.asarray(function(q0, v0)).ravel(), sensor_values(model, names, q0, v0),
                                   rtol=1e-13, atol=1e-13)


def pendulum(hinge) -> PlanarModel:
    return PlanarModel.chain("pendulum", [Fixed("ground"), hinge, RigidBody.uniform_link("rod", mass=1.0,
                                                                                          length=1.0)])


def lagrange_rhs(control):
    """Lagrange pendulum with the hinge torque ``control(t, y)``."""
    torque = [0.0]
    lagrange = PlanarLagrange(pendulum(ActuatedHinge("pivot", torque=lambda t: torque[0])))

    def rhs(t, y):
        torque[0] = control(t, y)
        return np.concatenate([y[1:2], lagrange.accelerations(y[:1], y[1:2], t), y[2:] * 0.0])

    return rhs, lagrange, torque


def dop853(rhs, t_span, y0, **kw):
    solution = scipy.integrate.solve_ivp(rhs, t_span, y0, method="DOP853", rtol=1e-12, atol=1e-12, **kw)
    assert solution.success, solution.message
    return solution


KP, KD, TARGET = 30.0, 4.0, -1.2


def test_real_time_loop_converges_to_lagrange_at_fourth_order():
    """A real-time PD on body angle and rate, closed at every RK4 stage of the generated step."""
    loop = Feedback("pd", [("rod.theta", KP), ("rod.omega", KD)], "pivot.torque", gain=1.0)
    system = ControlledModel(pendulum(SmoothHinge("pivot")), [loop])
    t_final, y0 = 1.5, np.array([-math.pi / 2, 0.0])
    rhs, _, _ = lagrange_rhs(lambda t, y: -(KP * y[0] + KD * y[1] - KP * TARGET))
    errors = []
    for dt in (4e-3, 2e-3):
        result = ctmm.simulate(system, t_final, dt, x0=y0[:1], references={"pd": KP * TARGET}, compiled=True)
        ref = dop853(rhs, (0.0, t_final), y0, t_eval=result.time)
        errors.append(np.max(np.abs(result["rod.theta"] - ref.y[0])))
        u_ref = -(KP * ref.y[0] + KD * ref.y[1] - KP * TARGET)
        assert np.max(np.abs(result["pd.u"] - u_ref)) < 1e-5 * np.max(np.abs(u_ref))
    assert errors[1] < 2e-9, errors
    assert errors[0] / errors[1] > 12.0, errors
    assert result.scheme_name == "rk4-generated" and result.info["loops"] == {"pd": "real-time"}


def test_lti_controller_states_are_integrated_in_the_generated_step():
    """``C(s) = K a / (s + a)`` on the angle error: its state is part of the generated state."""
    control = pytest.importorskip("control")
    K, a = 25.0, 40.0
    loop = Feedback("lag", "rod.theta", "pivot.torque", gain=control.tf([K * a], [1.0, a]))
    system = ControlledModel(pendulum(SmoothHinge("pivot")), [loop])
    result = ctmm.simulate(system, 1.0, 1e-3, x0=[-math.pi / 2], references={"lag": TARGET}, compiled=True)
    cell = [0.0]
    lagrange = PlanarLagrange(pendulum(ActuatedHinge("pivot", torque=lambda t: cell[0])))

    def rhs(t, y):
        cell[0] = -K * y[2]
        return np.array([y[1], lagrange.accelerations(y[:1], y[1:2], t)[0], a * (y[0] - TARGET - y[2])])

    ref = dop853(rhs, (0.0, 1.0), [-math.pi / 2, 0.0, 0.0], t_eval=result.time)
    assert np.max(np.abs(result["rod.theta"] - ref.y[0])) < 1e-8
    assert np.max(np.abs(result["lag.u"] + K * ref.y[2])) < 1e-6


def test_delayed_loop_matches_the_method_of_steps():
    """``u(t) = -K (theta(t - tau) - r) - D omega(t - tau)``, tau = 50 dt, from the ring in the fold
    state, vs DOP853 on segments of one delay; before tau the loop acts on the initial state held."""
    K, D, tau, t_final, dt = 12.0, 1.5, 0.05, 1.0, 1e-3
    loop = Feedback("late", [("rod.theta", K), ("rod.omega", D)], "pivot.torque", gain=1.0, delay=tau)
    system = ControlledModel(pendulum(SmoothHinge("pivot")), [loop])
    y0 = np.array([-math.pi / 2, 0.0])
    result = ctmm.simulate(system, t_final, dt, x0=y0[:1], references={"late": K * TARGET}, compiled=True)
    law = lambda y: -(K * (y[0] - TARGET) + D * y[1])   # noqa: E731
    past = [lambda s: y0]
    rhs, _, _ = lagrange_rhs(lambda t, y: law(past[-1](t - tau)))
    times, thetas, start, y = [], [], 0.0, y0
    while start < t_final - 1e-12:
        end = min(start + tau, t_final)
        solution = dop853(rhs, (start, end), y, dense_output=True)
        grid = result.time[(result.time >= start - 1e-12) & (result.time <= end + 1e-12)]
        times.append(grid)
        thetas.append(solution.sol(grid)[0])
        past.append(lambda s, f=solution.sol, t0=start: f(s) if s >= t0 - 1e-12 else y0)
        start, y = end, solution.y[:, -1]
    reference = np.interp(result.time, np.concatenate(times), np.concatenate(thetas))
    assert np.max(np.abs(result["rod.theta"] - reference)) < 1e-10
    early = result.time < tau - 1e-12
    np.testing.assert_allclose(result["late.u"][early], law(y0), rtol=1e-12)
    assert result.info["loops"] == {"late": "history"}


def controlled_hub_beam() -> tuple[ControlledModel, dict]:
    """Hub-beam sensed through hinge, body, point and modal-coordinate ports: a real-time PD, a real-time
    LTI loop on two actuators, two delayed loops (1 and 7 steps of 2e-3 s; one with an LTI controller),
    symbolic references and inputs."""
    control = pytest.importorskip("control")
    plant = hub_beam()
    loops = [Feedback("pd", [("o.angle", 8.0), ("o.rate", 1.0)], "o.torque", gain=1.0),
             Feedback("end", [("tip.com.y", 3.0), ("tip.com.vx", 0.2)], "tip.force_y", gain=0.5, delay=2e-3),
             Feedback("modal", [("b.q2_dot", 1.0), ("b.com.y", 0.5)], "b.q1.force",
                      gain=control.tf([4.0], [0.05, 1.0]), delay=0.014),
             Feedback("lag", "hub.omega", [("hub.moment", 1.0), ("tip.moment", -0.3)],
                      gain=control.tf([2.0, 1.0], [1.0, 3.0, 2.0]))]
    signals = {"references": {"pd": Harmonic(0.3, 5.0, 0.1), "end": Step(0.05, 0.02)},
               "inputs": {"tip.force_x": 0.2, "b.u1.force": Harmonic(0.1, 20.0, 0.0)}}
    return ControlledModel(plant, loops), signals


def test_controlled_hub_beam_equals_the_numpy_path_to_round_off():
    system, signals = controlled_hub_beam()
    q0, v0 = _state(system.plant, 4)
    kw = dict(x0=q0, v0=v0, outputs=["tip.com.x"], **signals)
    numpy_run = ctmm.simulate(system, 0.2, 2e-3, **kw)
    generated = ctmm.simulate(system, 0.2, 2e-3, compiled=True, **kw)
    assert generated.info["loops"] == {"pd": "real-time", "end": "history", "modal": "history", "lag": "real-time"}
    np.testing.assert_allclose(generated.time, numpy_run.time, rtol=0, atol=1e-15)
    names = list(system.plant.coordinates) + ["tip.com.x"] + [f"{lp.name}.{p}" for lp in system.loops
                                                             for p in ("y", "u")]
    for name in names:
        scale = max(1.0, float(np.max(np.abs(numpy_run[name]))))
        assert np.max(np.abs(generated[name] - numpy_run[name])) < 1e-11 * scale, name
        assert generated.unit(name) == numpy_run.unit(name), name
    # every row and the stored subset agree
    sparse = ctmm.simulate(system, 0.2, 2e-3, compiled=True, store_every=7, **kw)
    index = [k for k in range(len(generated.time)) if k % 7 == 0 or k == len(generated.time) - 1]
    np.testing.assert_array_equal(sparse["tip.com.x"], generated["tip.com.x"][index])


def test_refusals_name_the_feature():
    plant = pendulum(SmoothHinge("pivot"))
    odd = ControlledModel(plant, [Feedback("late", "rod.theta", "pivot.torque", gain=1.0, delay=0.0015)])
    with pytest.raises(ModelError, match="not a whole multiple of dt"):
        ctmm.simulate(odd, 0.1, 1e-3, compiled=True)
    pd = ControlledModel(plant, [Feedback("pd", "rod.theta", "pivot.torque", gain=1.0)])
    with pytest.raises(ModelError, match="references\\['pd'\\] is a Python callable"):
        ctmm.simulate(pd, 0.1, 1e-3, compiled=True, references={"pd": lambda t: 0.1 * t})
    with pytest.raises(ModelError, match="inputs\\['pivot.torque'\\] is a Python callable"):
        ctmm.simulate(pd, 0.1, 1e-3, compiled=True, inputs={"pivot.torque": lambda t: t})
    with pytest.raises(ModelError, match="compiled=True runs the generated RK4"):
        ctmm.simulate(pd, 0.1, 1e-3, compiled=True, method="RK45")
    with pytest.raises(ModelError, match="apply to a ControlledModel"):
        ctmm.compiled_scene.CompiledScene(plant, dt=1e-3)
    scene = ctmm.compiled_scene.CompiledScene(pd, dt=1e-3)
    with pytest.raises(ModelError, match="use run"):
        scene.advance([0.1], [0.0], 1e-3, 3)
    with pytest.raises(ModelError, match="constants of its code"):
        scene.with_model(plant)
    with pytest.raises(ModelError, match="without loops"):
        ctmm.compiled_scene.simulate_batch(scene, scene.parameters[None], [0.1], [0.0], dt=1e-3, n_steps=2)
    with pytest.raises(ModelError, match="ControlledModel"):
        ClosedLoops(plant, ())
    with pytest.raises(ModelError, match="numeric and symbolic forms differ at t = 0.013 s"):
        ctmm.simulate(pd, 0.1, 1e-3, compiled=True,
                      references={"pd": SymbolicReference(lambda t: t, lambda t: casadi.sin(t))})
    with pytest.raises(ModelError, match="unknown inputs: actuator 'pivot.force'"):
        ctmm.simulate(pd, 0.1, 1e-3, compiled=True, inputs={"pivot.force": 1.0})
    with pytest.raises(ModelError, match="scene must be a CompiledScene of this controlled model"):
        simulate_controlled_generated(pd, [0.1], [0.0], t_final=0.01, dt=1e-3, scene=scene, store_every=2)
    reused = simulate_controlled_generated(pd, [0.1], [0.0], t_final=0.01, dt=1e-3, scene=scene)
    fresh = ctmm.simulate(pd, 0.01, 1e-3, x0=[0.1], compiled=True)
    np.testing.assert_array_equal(reused["rod.theta"], fresh["rod.theta"])


def test_diverging_loop_stops_with_the_partial_result():
    """A destabilising real-time loop: SimulationError with the rows before the bound."""
    loop = Feedback("bad", "rod.omega", "pivot.torque", gain=-50.0)
    system = ControlledModel(pendulum(SmoothHinge("pivot")), [loop])
    with pytest.raises(SimulationError) as info:
        ctmm.simulate(system, 2.0, 1e-3, x0=[0.1], compiled=True, divergence_bound=10.0)
    partial = info.value.partial_result
    assert partial is not None and 0 < len(partial.time) < 2001
    assert np.all(np.abs(partial["rod.theta"] - 0.1) <= 10.0)
    assert len(partial["bad.u"]) == len(partial.time)


def test_moment_pairs_on_beam_stations_and_a_symbolic_reference_equal_the_numpy_path():
    """The manipulator scene: PD loop with a cycloidal SymbolicReference and piezo loops acting on the
    moment pairs ``-c`` at ``x1``, ``+c`` at ``x2`` (their frame wrenches cancel: modal forces only)."""
    from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_MOVE, SEED_PZT_GAIN, HubPD, PZTFeedback, manipulator_scene,
                                  seed_manipulator)
    from ctmm.manipulator.compiled import cycloid_reference

    arm = seed_manipulator()
    system = manipulator_scene(arm, pd=HubPD(SEED_KP, SEED_KD), pzt=PZTFeedback(SEED_PZT_GAIN * np.eye(arm.n_patches)))
    references = {"hub_pd": cycloid_reference(SEED_KP, SEED_KD, SEED_MOVE)}
    numpy_run = ctmm.simulate(system, 0.3, 1e-3, references=references, outputs=["arm.tip.w"])
    generated = ctmm.simulate(system, 0.3, 1e-3, references=references, outputs=["arm.tip.w"], compiled=True)
    for name in ["hub.theta", "arm.tip.w"] + [f"{lp.name}.u" for lp in system.loops]:
        scale = float(np.max(np.abs(numpy_run[name])))
        assert scale > 0.0 and np.max(np.abs(generated[name] - numpy_run[name])) < 1e-11 * scale, name
