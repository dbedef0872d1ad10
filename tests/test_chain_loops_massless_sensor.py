"""Loops of a 1-D chain that sense a massless node, on the ODE path and on the DT-TMM path.

On the ODE path the loop driver reads the massless node from its force balance without the actuator
values (:meth:`ctmm.control.chain_plant.ChainPorts.point_kinematics`).  That is exact because an actuator
on an element touching a massless point is refused (:meth:`ChainPorts.check_actuator`), so no actuator
force enters a massless node's balance.  These tests check both halves against hand-written balances and
ODEs (DOP853, rtol 1e-13), independent of the TMM code:

chain ``Fixed - Spring k1 - (massless node) - Damper c | Spring k2 - Mass m - Free``; the node's position
``z`` [m] follows from ``-k1 z + c (v - z') = 0`` (damper: ``z`` is a first-order state) or
``-k1 z + k2 (x - z) = 0`` (spring: ``z`` is algebraic).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Damper, Fixed, Free, Mass, Spring
from ctmm.errors import ModelError

K1, K2, C, M, GAIN = 40.0, 25.0, 2.0, 1.5, 30.0
X0, V0 = 0.05, 0.2


def chain(second: str) -> ctmm.Chain:
    middle = Damper("d", C) if second == "damper" else Spring("d", K2)
    return ctmm.Chain("q", [Fixed("s"), Spring("k1", K1), middle, Mass("m", M), Free("e")])


def node_balance(second: str, x: np.ndarray, v: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position [m] and velocity [m/s] of the massless node from its balance (``z``: its first-order state)."""
    if second == "damper":
        return z, v - K1 / C * z
    share = K2 / (K1 + K2)
    return share * x, share * v


@pytest.mark.parametrize("second", ["damper", "spring"])
@pytest.mark.parametrize("sensor", ["k1.x", "k1.v"])
def test_a_loop_on_a_massless_node_reads_its_balance(second, sensor):
    result = ctmm.simulate(ControlledChain(chain(second), [Feedback("l", sensor, "m", gain=GAIN)]), 0.5, 0.01,
                           method="RK45", x0={"m": X0}, v0={"m": V0}, rtol=1e-11, atol=1e-13)
    derivative = 0 if sensor == "k1.x" else 1
    # the sensed value at every stored state is the node's balance at that state
    sensed = node_balance(second, result["m.x"], result["m.v"], result["k1.x"])[derivative]
    np.testing.assert_allclose(result["l.y"], sensed, rtol=0, atol=1e-14)
    np.testing.assert_allclose(result["k1.v"], node_balance(second, result["m.x"], result["m.v"], result["k1.x"])[1],
                               rtol=0, atol=1e-14)

    def rates(t, s):            # s = [z, x, v]: the node's first-order part (damper) and the mass
        z, x, v = s
        position, velocity = node_balance(second, np.array(x), np.array(v), np.array(z))
        u = -GAIN * (position, velocity)[derivative]
        if second == "damper":
            return [velocity, v, (-K1 * z + u) / M]
        return [0.0, v, (-K2 * (x - position) + u) / M]

    z0 = 0.0 if second == "damper" else K2 / (K1 + K2) * X0
    exact = scipy.integrate.solve_ivp(rates, (0.0, 0.5), [0.0, X0, V0], method="DOP853", t_eval=result.time,
                                      rtol=1e-13, atol=1e-15).y     # (at rtol 1e-12 DOP853 is off by 2e-9 here)
    assert result["k1.x"][0] == pytest.approx(z0, abs=1e-15)
    np.testing.assert_allclose(result["m.x"], exact[1], rtol=0, atol=1e-10)
    np.testing.assert_allclose(result["m.v"], exact[2], rtol=0, atol=1e-10)
    node = node_balance(second, exact[1], exact[2], exact[0])[derivative]
    np.testing.assert_allclose(result["l.y"], node, rtol=0, atol=1e-10)


@pytest.mark.parametrize("actuator", ["k1", "d"])
def test_an_actuator_touching_the_massless_node_is_refused_on_the_ode_path(actuator):
    looped = ControlledChain(chain("damper"), [Feedback("l", "k1.x", actuator, gain=GAIN)])
    with pytest.raises(ModelError, match=f"'{actuator}' acts on a point without inertia"):
        ctmm.simulate(looped, 0.1, 0.01, method="rk4")
    with pytest.raises(ModelError, match=f"'{actuator}' acts on a point without inertia"):
        ctmm.simulate(chain("damper"), 0.1, 0.01, method="rk4", inputs={actuator: lambda t: 1.0})


def test_the_dt_tmm_path_puts_the_actuator_into_the_node_balance():
    """``method="newmark"`` embeds the loop implicitly: an actuator ``u`` across the damper next to the
    node pushes the node by ``-u`` and the mass by ``+u``."""
    gain = 3.0
    result = ctmm.simulate(ControlledChain(chain("damper"), [Feedback("l", "k1.x", "d", gain=gain)]), 0.5, 0.001,
                           method="newmark", x0={"m": X0}, v0={"m": V0})

    def rates(t, s):
        z, x, v = s
        u = -gain * z
        velocity = v + (-K1 * z - u) / C
        return [velocity, v, (-C * (v - velocity) + u) / M]

    exact = scipy.integrate.solve_ivp(rates, (0.0, 0.5), [0.0, X0, V0], method="DOP853", t_eval=result.time,
                                      rtol=1e-12, atol=1e-14).y
    np.testing.assert_allclose(result["l.y"], result["k1.x"], rtol=0, atol=0)
    np.testing.assert_allclose(result["k1.x"], exact[0], rtol=0, atol=5e-7)
    np.testing.assert_allclose(result["m.x"], exact[1], rtol=0, atol=5e-7)


@pytest.mark.parametrize("second", ["damper", "spring"])
def test_the_rate_reuses_the_sensors_condensation_and_is_the_hand_ode(second, monkeypatch):
    """The driver reads the sensors, then the rate at the same ``(t, q, v)``: the rate reuses the sensors'
    condensation of the massless node (no second balance solve) and is the hand ODE with the actuator force."""
    from ctmm.chain_ode import ChainDynamics
    from ctmm.control.chain_plant import ChainPlant

    plant = ChainPlant(chain(second))
    ports = plant.ports
    sensors = ports.resolve([ports.check_sensor("k1.x"), ports.check_sensor("k1.v")])
    inputs = ports.inputs({ports.check_actuator("m"): 0.7})
    z, x, v, t = 0.01, X0, V0, 0.3
    q, rates = np.array([x]), np.array([v, z]) if second == "damper" else np.array([v])
    solves = []
    condense = ChainDynamics.condense
    monkeypatch.setattr(ChainDynamics, "condense", lambda self, *args: solves.append(1) or condense(self, *args))
    sensed = ports.values(sensors, q, rates, t)
    assert len(solves) == 1
    acceleration = plant.accelerations(q, rates, t, inputs)
    assert len(solves) == 1                             # the sensors' condensation reused
    position, velocity = node_balance(second, np.array(x), np.array(v), np.array(z))
    np.testing.assert_allclose(sensed, [position, velocity], rtol=0, atol=1e-15)
    if second == "damper":
        expected = [(-K1 * z + 0.7) / M, velocity]      # the mass, then the node's first-order part z' = z_dot
    else:
        expected = [(-K2 * (x - position) + 0.7) / M]
    np.testing.assert_allclose(acceleration, expected, rtol=1e-14, atol=1e-15)
    plant.accelerations(q + 1e-3, rates, t, inputs)    # another state: its own balance
    assert len(solves) == 2
