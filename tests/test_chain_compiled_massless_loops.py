"""Generated RK4 of 1-D chains with massless points AND feedback loops or open-loop inputs.

The generated step integrates the state ``[x_I, v_I, z_r]`` of the Python ODE path (massless nodes condensed,
:mod:`ctmm.compiled_chain_condensed`), and its loops read a massless node from the node's balance as the Python loop
driver does (:meth:`ctmm.control.chain_plant.ChainPorts.point_kinematics`; exact without the actuator values because
actuators touching a massless point are refused, ``tests/test_chain_loops_massless_sensor.py``).

Independent references: hand-written state equations of the condensed chains (DOP853 at rtol 1e-13) with RK4's fourth
order from two steps; the Python loop driver (``compiled=False``) to round-off.

Chains: ``Fixed - k1 - (node) - Damper c | Spring k2 - Mass m - Free`` (the node first-order or algebraic), and the
two-mass chain ``Fixed - k0 - m0 - k1 - (node) - k2 - m1 - Free`` whose node sits at ``(k1 x0 + k2 x1) / (k1 + k2)``.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Damper, Fixed, Free, Mass, PrescribedDisplacement, Spring
from ctmm.errors import ModelError
from ctmm.signals import Harmonic

pytest.importorskip("casadi")
control = pytest.importorskip("control")

K1, K2, C, M, GAIN = 40.0, 25.0, 2.0, 1.5, 30.0
X0, V0 = 0.05, 0.2
NAMES = ("m.x", "m.v", "m.a", "k1.x", "k1.v", "d.f")


def one_mass(second: str) -> ctmm.Chain:
    middle = Damper("d", C) if second == "damper" else Spring("d", K2)
    return ctmm.Chain("q", [Fixed("s"), Spring("k1", K1), middle, Mass("m", M), Free("e")])


def node_balance(second: str, x, v, z):
    """Position [m] and velocity [m/s] of the massless node (``z``: its first-order state, damper)."""
    if second == "damper":
        return z, v - K1 / C * z
    share = K2 / (K1 + K2)
    return share * x, share * v


def _both(system, t_final, dt, names, **options):
    generated = ctmm.simulate(system, t_final, dt, method="rk4", compiled=True, **options)
    python = ctmm.simulate(system, t_final, dt, method="rk4", compiled=False, **options)
    assert generated.info["method"] == "rk4-generated"
    np.testing.assert_array_equal(generated.time, python.time)
    for name in names:
        scale = max(1.0, float(np.max(np.abs(python[name]))))
        np.testing.assert_allclose(generated[name], python[name], rtol=0, atol=1e-12 * scale, err_msg=name)
    return generated


def _order(errors) -> float:
    return float(np.log2(errors[0] / errors[1]))


@pytest.mark.parametrize("second", ["damper", "spring"])
@pytest.mark.parametrize("sensor", ["k1.x", "k1.v"])
def test_a_real_time_loop_on_a_massless_node_is_the_hand_ode(second, sensor):
    """``u = -g y`` with ``y`` the node's position or velocity from its balance: the Python driver to round-off,
    DOP853 of the hand-written condensed ODE, fourth order."""
    system = ControlledChain(one_mass(second), [Feedback("l", sensor, "m", gain=GAIN)])
    derivative = 0 if sensor == "k1.x" else 1

    def rates(t, s):
        z, x, v = s
        position, velocity = node_balance(second, x, v, z)
        u = -GAIN * (position, velocity)[derivative]
        if second == "damper":
            return [velocity, v, (-K1 * z + u) / M]
        return [0.0, v, (-K2 * (x - position) + u) / M]

    errors, sensed = [], []
    for dt in (0.01, 0.005):
        generated = _both(system, 0.6, dt, (*NAMES, "l.y", "l.u"), x0={"m": X0}, v0={"m": V0})
        exact = solve_ivp(rates, (0.0, 0.6), [0.0, X0, V0], method="DOP853", t_eval=generated.time, rtol=1e-13,
                          atol=1e-15).y
        node = node_balance(second, exact[1], exact[2], exact[0])[derivative]
        np.testing.assert_allclose(generated["l.u"], -GAIN * generated["l.y"], rtol=0, atol=1e-14)
        errors.append(float(np.max(np.abs(generated["m.x"] - exact[1]))))
        sensed.append(float(np.max(np.abs(generated["l.y"] - node))))
    assert errors[1] < 1e-6 and sensed[1] < 2e-5, (errors, sensed)
    assert 3.7 <= _order(errors) <= 4.4, errors
    assert 3.7 <= _order(sensed) <= 4.4, sensed


def test_delayed_and_lti_loops_and_inputs_on_a_maxwell_node_as_the_python_driver():
    """A delayed loop on the node's velocity (its rate ``z''`` in the ring), a PI controller on its position and a
    harmonic open-loop force on the mass: the generated step equals the Python driver to round-off."""
    system = ControlledChain(one_mass("damper"), [
        Feedback("late", "k1.v", "m", gain=4.0, delay=0.03),
        Feedback("pi", "k1.x", "m", gain=control.tf([20.0, 60.0], [1.0, 0.0])),
        Feedback("lag", "k1.x", "m", gain=control.tf([15.0], [0.05, 1.0]), delay=0.01)])
    _both(system, 0.8, 0.01, (*NAMES, "late.y", "late.u", "pi.u", "lag.u"), x0={"m": X0}, v0={"m": V0},
          inputs={"m": Harmonic(2.0, 7.0)}, references={"pi": 0.01})


def test_open_loop_input_on_a_chain_with_a_massless_node_is_the_hand_ode():
    """``inputs={"m": F sin(w t)}`` on the Maxwell chain without loops: ``z' = v - k1 z / c``,
    ``m v' = -k1 z + F sin(w t)``."""
    amplitude, w = 2.0, 7.0
    errors = []
    for dt in (0.02, 0.01):
        generated = _both(one_mass("damper"), 0.6, dt, NAMES, x0={"m": X0}, inputs={"m": Harmonic(amplitude, w)})
        exact = solve_ivp(lambda t, s: [s[2] - K1 / C * s[0], s[2], (-K1 * s[0] + amplitude * np.sin(w * t)) / M],
                          (0.0, 0.6), [0.0, X0, 0.0], method="DOP853", t_eval=generated.time, rtol=1e-13,
                          atol=1e-15).y
        np.testing.assert_allclose(generated["k1.x"], exact[0], rtol=0, atol=1e-5)
        errors.append(float(np.max(np.abs(generated["m.x"] - exact[1]))))
    assert 3.7 <= _order(errors) <= 4.4, errors


def test_two_masses_and_a_massless_spring_node_with_a_pi_loop_on_the_node():
    """``Fixed - k0 - m0 - k1 - (node) - k2 - m1 - Free``, a PI loop on the node (at ``(k1 x0 + k2 x1) / (k1 + k2)``)
    driving ``m0``: the hand ODE (the series stiffness ``k1 k2 / (k1 + k2)`` between the masses, the PI state) and
    the Python driver."""
    k0, k1, k2, m0, m1, kp, ki = 120.0, 50.0, 80.0, 1.0, 0.6, 30.0, 40.0
    chain = ctmm.Chain("two", [Fixed("s"), Spring("k0", k0), Mass("m0", m0), Spring("k1", k1), Spring("k2", k2),
                               Mass("m1", m1), Free("e")])
    system = ControlledChain(chain, [Feedback("pi", "k1.x", "m0", gain=control.tf([kp, ki], [1.0, 0.0]))])
    series = k1 * k2 / (k1 + k2)

    def rates(t, s):
        x0, x1, v0, v1, integral = s
        node = (k1 * x0 + k2 * x1) / (k1 + k2)
        u = -(kp * node + ki * integral)
        return [v0, v1, (-k0 * x0 - series * (x0 - x1) + u) / m0, -series * (x1 - x0) / m1, node]

    errors = []
    for dt in (0.02, 0.01):
        generated = _both(system, 1.0, dt, ("m0.x", "m1.x", "m1.v", "k1.x", "pi.y", "pi.u"), x0={"m1": 0.04})
        exact = solve_ivp(rates, (0.0, 1.0), [0.0, 0.04, 0.0, 0.0, 0.0], method="DOP853", t_eval=generated.time,
                          rtol=1e-13, atol=1e-15).y
        node = (k1 * exact[0] + k2 * exact[1]) / (k1 + k2)
        np.testing.assert_allclose(generated["pi.y"], node, rtol=0, atol=1e-5)
        errors.append(float(np.max(np.abs(generated["m0.x"] - exact[0]))))
    assert 3.7 <= _order(errors) <= 4.4, errors


def test_what_is_still_refused_is_named():
    """An actuator touching the massless node; a loop sensing a massless node that moves with a prescribed base."""
    looped = ControlledChain(one_mass("damper"), [Feedback("l", "k1.x", "d", gain=GAIN)])
    with pytest.raises(ModelError, match="'d' acts on a point without inertia"):
        ctmm.simulate(looped, 0.1, 0.01, method="rk4", compiled=True)
    with pytest.raises(ModelError, match="'k1' acts on a point without inertia"):
        ctmm.simulate(one_mass("damper"), 0.1, 0.01, method="rk4", compiled=True, inputs={"k1": 1.0})
    based = ctmm.Chain("b", [PrescribedDisplacement("base", Harmonic(0.01, 5.0)), Spring("k1", K1), Damper("d", C),
                             Mass("m", M), Free("e")])
    with pytest.raises(ModelError, match="sensor 'k1.v' of loop 'l' moves with the prescribed motion"):
        ctmm.simulate(ControlledChain(based, [Feedback("l", "k1.v", "m", gain=1.0)]), 0.1, 0.01, method="rk4",
                      compiled=True)
    # the node's position (the first-order state) and the mass do not move with the base: taken
    _both(ControlledChain(based, [Feedback("l", "k1.x", "m", gain=5.0), Feedback("n", "m.x", "m", gain=3.0)]), 0.2,
          0.01, ("m.x", "k1.x", "k1.v", "l.u", "n.u"))
