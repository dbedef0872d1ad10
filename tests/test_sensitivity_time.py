"""Forward sensitivities of planar RK4 runs (ctmm.sensitivity_time) against a closed form and against
differences of ctmm.simulate on rebuilt models: one central difference (h = 1e-4 |p|,
``tests.test_sensitivity.central_difference``: the numpy runs are these tests' cost; measured errors <= 3.2e-8
relative against the bound 1e-6, Richardson over 1e-3, 5e-4 gave <= 3e-11)."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm import sensitivity as S
from ctmm.errors import ModelError
from ctmm.planar import ElasticHinge, Fixed, PlanarModel, RigidBody


def link(name: str, mass: float, length: float, inertia: float) -> RigidBody:
    return RigidBody(name, mass=mass, inertia=inertia, center_of_mass=(length / 2, 0.0), inboard=(0.0, 0.0),
                     outboard=(length, 0.0))


def test_hinge_oscillator_against_the_closed_form():
    """No gravity: J theta'' = -k theta, J = I + m (L/2)^2, theta = theta0 cos(w t), w = sqrt(k/J)."""
    m, L, inertia, k, theta0 = 1.0, 0.5, 0.02, 3.0, 0.3
    model = PlanarModel.chain("osc", [Fixed("g"), ElasticHinge("hinge", stiffness=k), link("bar", m, L, inertia)],
                              gravity=(0.0, 0.0))
    run = S.simulation_sensitivity(model, ["bar.mass", "bar.inertia", "hinge.stiffness"], t_final=1.0, dt=1e-3,
                                   q0=[theta0], outputs=["bar.theta", "bar.theta_dot"])
    J = inertia + m * L * L / 4
    w = np.sqrt(k / J)
    t = run.time
    assert np.max(np.abs(run.values[0] - theta0 * np.cos(w * t))) < 1e-9
    dtheta_dw = -theta0 * t * np.sin(w * t)
    dw = {"bar.mass": -w / (2 * J) * L * L / 4, "bar.inertia": -w / (2 * J), "hinge.stiffness": w / (2 * k)}
    for i, name in enumerate(run.parameters):
        exact = dtheta_dw * dw[name]
        assert np.max(np.abs(run.derivative[i, 0] - exact)) < 1e-7 * np.max(np.abs(exact)), name
        rate = -theta0 * (np.sin(w * t) + w * t * np.cos(w * t)) * dw[name]
        assert np.max(np.abs(run.derivative[i, 1] - rate)) < 1e-7 * np.max(np.abs(rate)), name


def double_pendulum(upper_mass: float = 1.0, elbow: float = 2.0, lower_inertia: float = 0.0067) -> PlanarModel:
    return PlanarModel.chain("dp", [Fixed("g"), ElasticHinge("motor", stiffness=3.0), link("upper", upper_mass, 0.5, 0.02),
                                    ElasticHinge("elbow", stiffness=elbow), link("lower", 0.5, 0.4, lower_inertia)])


@pytest.mark.parametrize("name, value, builder", [
    ("upper.mass", 1.0, lambda v: double_pendulum(upper_mass=v)),
    ("elbow.stiffness", 2.0, lambda v: double_pendulum(elbow=v)),
    ("lower.inertia", 0.0067, lambda v: double_pendulum(lower_inertia=v))])
def test_double_pendulum_history_against_central_differences(name, value, builder):
    run = S.simulation_sensitivity(double_pendulum(), [name], t_final=0.5, dt=1e-3, q0=[-1.2, -1.0],
                                   outputs=["lower.theta", "upper.theta_dot"])

    def history(v: float) -> np.ndarray:
        sim = ctmm.simulate(builder(v), t_final=0.5, dt=1e-3, method="rk4",
                            x0={"upper.theta": -1.2, "lower.theta": -1.0})
        return np.array([sim["lower.theta"], sim["upper.theta_dot"]])

    h = 1e-4 * abs(value)         # one central difference: measured relative error <= 3.2e-8 (bound 1e-6)
    difference = (history(value + h) - history(value - h)) / (2 * h)
    assert np.max(np.abs(run.values - history(value))) < 1e-12
    assert np.max(np.abs(run.derivative[0] - difference)) < 1e-6 * np.max(np.abs(difference))


def test_start_given_as_ctmm_simulate_takes_it_is_the_start_of_the_run():
    """x0 / v0 by coordinate name, as ctmm.simulate takes them, start a planar run (they were dropped with q0
    given, refused as 'q0 must be an array ..., got None' without it); q0 / qdot0, which a chain or spatial run
    dropped silently (a chain with q0 = [0.3] ran from rest), are refused there by name."""
    model = double_pendulum()
    start, rates = {"upper.theta": -1.2, "lower.theta": -1.0}, {"lower.theta": 0.5}
    run = S.simulation_sensitivity(model, ["upper.mass"], t_final=0.2, dt=1e-3, x0=start, v0=rates,
                                   outputs=["lower.theta", "upper.theta_dot"])
    sim = ctmm.simulate(model, t_final=0.2, dt=1e-3, method="rk4", x0=start, v0=rates)
    assert np.max(np.abs(run.values - np.array([sim["lower.theta"], sim["upper.theta_dot"]]))) < 1e-12
    with pytest.raises(ModelError, match="not both"):
        S.simulation_sensitivity(model, ["upper.mass"], t_final=0.1, dt=0.01, q0=[-1.2, -1.0], x0=start)
    chain = ctmm.Chain("c", [ctmm.elements.Fixed("w"), ctmm.elements.Spring("k", 10.0), ctmm.elements.Mass("m", 1.0),
                             ctmm.elements.Free("e")])
    with pytest.raises(ModelError, match="q0 and qdot0 are the coordinate arrays of a planar model.*got q0="):
        S.simulation_sensitivity(chain, ["m.mass"], t_final=0.1, dt=0.01, q0=[0.3])


def test_refusals():
    model = double_pendulum()
    with pytest.raises(ModelError, match="motor.damping.*is 0"):
        S.simulation_sensitivity(model, ["motor.damping"], t_final=0.1, dt=0.01, q0=[-1.2, -1.0])
    with pytest.raises(ModelError, match="allowed: '<body>.mass'"):
        S.simulation_sensitivity(model, ["upper.length"], t_final=0.1, dt=0.01, q0=[-1.2, -1.0])
    with pytest.raises(ModelError, match="unknown body"):
        S.simulation_sensitivity(model, ["middle.mass"], t_final=0.1, dt=0.01, q0=[-1.2, -1.0])
    with pytest.raises(ModelError, match="unknown output"):
        S.simulation_sensitivity(model, ["upper.mass"], t_final=0.1, dt=0.01, q0=[-1.2, -1.0], outputs=["x"])


def test_chain_history_against_central_differences_of_the_simulation():
    from tests.test_sensitivity import central_difference, relative, seed_chain

    chain = seed_chain()
    names = ["m4.mass", "K3.stiffness", "K1.damping"]
    found = S.simulation_sensitivity(chain, names, t_final=1.0, dt=0.01, x0={"m6": 0.1}, v0={"m2": 0.2},
                                     outputs=["m4.x", "m6.v"])

    def history(c):
        sim = ctmm.simulate(c, 1.0, 0.01, method="rk4", x0={"m6": 0.1}, v0={"m2": 0.2})
        return np.array([sim["m4.x"], sim["m6.v"]])

    assert np.max(np.abs(found.values - history(chain))) < 1e-12
    for i, name in enumerate(names):
        assert relative(found.derivative[i], central_difference(history, chain, name)) < 1e-6, name


def test_chain_history_derivatives_match_the_oscillator_closed_form():
    # m x'' + k x = 0 from x0: x = x0 cos(w t), w = sqrt(k/m); dx/dk = -x0 t sin(w t) / (2 sqrt(k m)),
    # dx/dm = x0 t sin(w t) w / (2 m); RK4 with dt = 1 ms agrees to its O(dt^4) error
    from ctmm.elements import Fixed, Free, Mass, Spring

    m, k, x0 = 2.0, 5.0, 0.1
    chain = ctmm.Chain("sdof", [Fixed("w"), Spring("k", k), Mass("m", m), Free("e")])
    rest = ctmm.simulate(chain, 0.001, 0.001, method="rk4")["m.x"][0]
    found = S.simulation_sensitivity(chain, ["k.stiffness", "m.mass"], t_final=2.0, dt=1e-3, x0={"m": rest + x0},
                                     outputs=["m.x"])
    t, w = found.time, np.sqrt(k / m)
    assert np.max(np.abs(found.values[0] - rest - x0 * np.cos(w * t))) < 1e-9
    expected = [-x0 * t * np.sin(w * t) / (2 * np.sqrt(k * m)), x0 * t * np.sin(w * t) * w / (2 * m)]
    for i in range(2):
        assert np.max(np.abs(found.derivative[i, 0] - expected[i])) < 1e-7 * np.max(np.abs(expected[i]))
    with pytest.raises(ModelError, match="not supported"):
        S.simulation_sensitivity(chain, ["k.stiffness"], t_final=0.1, dt=0.01, outputs=["m.f"])


@pytest.mark.parametrize("delay, lti", [(0.05, False), (0.0, True)])
def test_controlled_chain_history_in_loop_and_element_numbers_against_central_differences(delay, lti):
    # the seed chain's PD loop (delayed; or a first-order LTI controller): gain, sensor weights and the chain's own
    # mass, stiffness and damping numbers
    import control

    from ctmm.control import ControlledChain, Feedback
    from tests.test_sensitivity import central_difference, relative, seed_chain

    gain = control.tf([1.0], [0.1, 1.0]) if lti else 1.0
    system = ControlledChain(seed_chain(), [Feedback("pd", [("m6.x", 5.0), ("m6.v", 1.0)], "m2", gain=gain,
                                                     delay=delay)])
    names = ["pd.m6.x", "pd.m6.v", "pd.gain"] + (["K1.damping"] if lti else ["m4.mass", "K3.stiffness"])
    found = S.simulation_sensitivity(system, names, t_final=2.0, dt=0.01, v0={"m4": 0.5}, x0={"m6": 0.3},
                                     outputs=["m6.x", "m2.v"])

    def history(s):
        run = ctmm.simulate(s, 2.0, 0.01, method="rk4", v0={"m4": 0.5}, x0={"m6": 0.3})
        return np.array([run["m6.x"], run["m2.v"]])

    assert np.max(np.abs(found.values - history(system))) < 1e-12
    for i, name in enumerate(names):
        assert relative(found.derivative[i], central_difference(history, system, name)) < 1e-6, name
    with pytest.raises(ModelError, match="unknown"):
        S.simulation_sensitivity(system, ["m9.mass"], t_final=0.1, dt=0.01)
    if delay:
        with pytest.raises(ModelError, match="whole number of steps"):
            S.simulation_sensitivity(system, ["pd.delay"], t_final=0.1, dt=0.01)


def test_controlled_chain_with_load_signals_against_central_differences():
    # the seed chain's delayed PD loop with a sine force on m4 and a step on m6 (ctmm.signals, stated on the
    # step's time): loop and element numbers against central differences of the numpy RK4 (1e-6, found <= 7.3e-9)
    from ctmm.control import ControlledChain, Feedback
    from ctmm.elements import Fixed, Free, Mass, SpringDamper
    from ctmm.signals import Harmonic, Step
    from tests.test_sensitivity import central_difference, relative

    def chain(force4, force6=Step(0.4, 0.5)):
        return ctmm.Chain("seed", [Fixed("g"), SpringDamper("K1", 10.0, 1.0), Mass("m2", 1.0),
                                   SpringDamper("K3", 10.0, 1.0), Mass("m4", 1.0, force=force4),
                                   SpringDamper("K5", 10.0, 1.0), Mass("m6", 1.0, force=force6), Free("e")])

    def controlled(force4):
        return ControlledChain(chain(force4), [Feedback("pd", [("m6.x", 5.0), ("m6.v", 1.0)], "m2", gain=1.0,
                                                        delay=0.05)])

    system = controlled(Harmonic(0.7, 3.0, 0.2))
    names = ["pd.m6.x", "pd.gain", "m4.mass", "K3.stiffness", "K1.damping"]
    found = S.simulation_sensitivity(system, names, t_final=2.0, dt=0.01, v0={"m4": 0.5}, outputs=["m6.x", "m2.v"])

    def history(s):
        run = ctmm.simulate(s, 2.0, 0.01, method="rk4", v0={"m4": 0.5})
        return np.array([run["m6.x"], run["m2.v"]])

    assert np.max(np.abs(found.values - history(system))) < 1e-12
    for i, name in enumerate(names):
        assert relative(found.derivative[i], central_difference(history, system, name)) < 1e-6, name
    with pytest.raises(ModelError, match="Python callables of time"):
        S.simulation_sensitivity(controlled(lambda t: 0.7 * np.sin(3.0 * t)), ["pd.gain"], t_final=0.1, dt=0.01)


@pytest.mark.parametrize("force", [0.5, "harmonic"])
def test_loaded_chain_history_equals_the_simulation_and_differences(force):
    # a chain with a load (constant or a sine) is not a free response about its rest positions: the explicit form
    # of chain_simulation_sensitivity refuses it and simulation_sensitivity takes it as a ControlledChain without
    # loops (the old code returned the free response, 0.08 m off the simulation)
    from ctmm.elements import Fixed, Free, Mass, SpringDamper
    from ctmm.sensitivity_time import chain_simulation_sensitivity
    from ctmm.signals import Harmonic
    from tests.test_sensitivity import central_difference, relative

    load = Harmonic(0.7, 3.0, 0.2) if force == "harmonic" else force
    chain = ctmm.Chain("c", [Fixed("g"), SpringDamper("K1", 10.0, 1.0), Mass("m2", 1.0, force=load),
                             SpringDamper("K3", 5.0, 0.5), Mass("m4", 2.0), Free("e")])
    names = ["m2.mass", "K1.stiffness", "K3.damping"]
    found = S.simulation_sensitivity(chain, names, t_final=1.0, dt=0.01, v0={"m4": 0.2}, outputs=["m2.x", "m4.v"])

    def history(s):
        run = ctmm.simulate(s, 1.0, 0.01, method="rk4", v0={"m4": 0.2})
        return np.array([run["m2.x"], run["m4.v"]])

    assert np.max(np.abs(found.values - history(chain))) < 1e-12
    for i, name in enumerate(names):
        assert relative(found.derivative[i], central_difference(history, chain, name)) < 1e-6, name
    with pytest.raises(ModelError, match=r"carries loads on \['m2'\]"):
        chain_simulation_sensitivity(chain, names, t_final=1.0, dt=0.01)


def prestressed_chain(force: float = 2.0) -> ctmm.Chain:
    """Two masses between walls 2 m apart, springs with free lengths (1.2 m in all) and a constant force on m4: the
    law forces at the rest positions are not zero (they move with the stiffnesses: the offset term of the outputs'
    derivative)."""
    from ctmm.elements import Fixed, Mass, Spring, SpringDamper

    return ctmm.Chain("pre", [Fixed("g"), Spring("K1", 10.0, free_length=0.5), Mass("m2", 1.0),
                              SpringDamper("K3", 8.0, 0.5, free_length=0.3), Mass("m4", 1.5, force=force),
                              Spring("K5", 12.0, free_length=0.4), Fixed("e", position=2.0)])


@pytest.mark.parametrize("case", ["seed", "prestressed"])
def test_controlled_chain_connector_force_outputs_carry_their_own_number_derivative(case):
    # a connector's law force "K3.f" = k3 (x4 - x2 - L3) + c3 (v4 - v2) depends on K3's numbers directly: its
    # derivative is dF/dx S + dF/dp (the second term was missing: relative errors 1.0 to 1.8 on the old code); against
    # central differences of the numpy RK4 (h = 1e-4 |p|, error O(h^2); bound 1e-6, found <= 1.1e-8)
    from ctmm.control import ControlledChain, Feedback
    from tests.test_sensitivity import central_difference, relative, seed_chain

    if case == "seed":
        system = ControlledChain(seed_chain(), [Feedback("pd", [("m6.x", 5.0), ("m6.v", 1.0)], "m2", gain=1.0)])
        names = ["K3.stiffness", "K3.damping", "K1.stiffness", "m4.mass", "pd.gain"]
        outputs, start = ["K3.f", "K1.in.f", "K5.out.f", "m6.x"], dict(v0={"m4": 0.5}, x0={"m6": 0.3})
    else:
        system = ControlledChain(prestressed_chain(), [Feedback("pd", [("m4.x", 5.0), ("m4.v", 1.0)], "m2",
                                                                      gain=1.0)])
        names = ["K1.stiffness", "K3.stiffness", "K3.damping", "K5.stiffness", "m4.mass"]
        outputs, start = ["K1.f", "K3.f", "K5.f", "m4.x"], dict(v0={"m4": 0.5}, x0={"m2": 0.7})
    found = S.simulation_sensitivity(system, names, t_final=1.0, dt=0.01, outputs=outputs, **start)

    def history(s):
        run = ctmm.simulate(s, 1.0, 0.01, method="rk4", outputs=outputs, **start)
        return np.array([run[name] for name in outputs])

    assert np.max(np.abs(found.values - history(system))) < 1e-12
    for i, name in enumerate(names):
        expected = central_difference(history, system, name)
        for o, output in enumerate(outputs):
            assert relative(found.derivative[i, o], expected[o]) < 1e-6, (name, output)


def test_prestressed_chain_without_loads_is_differentiated_about_its_equilibrium():
    # free lengths that do not fit between the walls: the rest positions are not the equilibrium, so the free
    # response about them (chain_simulation_sensitivity) was a silent wrong answer (values off by 1.2 m from
    # ctmm.simulate); such a chain is now differentiated as a ControlledChain without loops and refused by name by the
    # free-response path; against the simulation (1e-12) and central differences (bound 1e-6, found <= 1.2e-8)
    from ctmm.sensitivity_time import chain_simulation_sensitivity
    from tests.test_sensitivity import central_difference, relative

    chain = prestressed_chain(force=0.0)
    names, outputs = ["K1.stiffness", "K3.stiffness", "K3.damping", "m4.mass"], ["m2.x", "m4.x", "m2.v"]
    start = dict(v0={"m4": 0.5}, x0={"m2": 0.7})
    found = S.simulation_sensitivity(chain, names, t_final=1.0, dt=0.01, outputs=outputs, **start)

    def history(s):
        run = ctmm.simulate(s, 1.0, 0.01, method="rk4", **start)
        return np.array([run[name] for name in outputs])

    assert np.max(np.abs(found.values - history(chain))) < 1e-12
    for i, name in enumerate(names):
        assert relative(found.derivative[i], central_difference(history, chain, name)) < 1e-6, name
    with pytest.raises(ModelError, match="not its equilibrium"):
        chain_simulation_sensitivity(chain, names, t_final=1.0, dt=0.01, **start)
