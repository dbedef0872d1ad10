"""Generated DT-TMM schemes of 1-D chains with massless points and prescribed boundary motion
(``ctmm.simulate(chain, method=<scheme>, compiled=True)``, ``ctmm/compiled_chain_scheme_nodes.py``).

Independent references: a textbook Newmark on the global equations ``M a + C v + K x = f`` written here (``M``
singular at the massless nodes; the prescribed support a degree of freedom whose position is imposed at every
step), the same answer to round-off; the exact response of the condensed ODE (DOP853 at 1e-13), second order.
Every scheme equals the Python DT-TMM path to round-off (positions and velocities at every point).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Damper, Fixed, Free, Mass, PrescribedDisplacement, Spring, SpringDamper
from ctmm.errors import ModelError
from ctmm.schemes import Newmark
from ctmm.signals import Harmonic, Step

pytest.importorskip("casadi")
SCHEMES = ("newmark", "generalized_alpha", "wilson_theta", "houbolt", "forward_euler")


def chains() -> dict:
    return {
        "maxwell": ctmm.Chain("mx", [Fixed("s"), Spring("k1", 40.0), Damper("d", 2.0), Mass("m", 1.5), Free("e")]),
        "series": ctmm.Chain("se", [Fixed("s"), Spring("k0", 120.0), Mass("m0", 1.0), Spring("k1", 50.0),
                                    Spring("k2", 80.0), Mass("m1", 0.6), Free("e")]),
        "base": ctmm.Chain("ba", [PrescribedDisplacement("base", Harmonic(0.02, 9.0)), SpringDamper("s", 250.0, 1.2),
                                  Mass("m", 1.3), Free("e")]),
        "km": ctmm.Chain("km", [PrescribedDisplacement("base", Harmonic(0.01, 6.0, 0.3)), Spring("k0", 80.0),
                                Damper("c0", 3.0), Mass("m0", 1.0), SpringDamper("s1", 60.0, 0.4), Spring("k2", 90.0),
                                Spring("k3", 45.0), Mass("m1", 0.7, force=Harmonic(1.5, 3.0)), Free("e")]),
        "wall": ctmm.Chain("wa", [Fixed("s", position=0.01), Spring("k0", 70.0), Mass("m0", 1.2), Spring("k1", 40.0),
                                  Damper("c1", 2.5), PrescribedDisplacement("wall", Step(0.05, 0.02))]),
    }


def _same(generated, python, store_every: int = 1, tolerance: float = 1e-12) -> None:
    """Positions and velocities at every point equal the Python DT-TMM path's (``tolerance`` of the motion; Houbolt's
    three-level history 1e-11); the stored times too."""
    np.testing.assert_array_equal(generated.time, python.time[::store_every] if store_every == 1 else generated.time)
    rows = np.searchsorted(python.time, generated.time - 1e-12)
    x, v = python.states[rows, :, 0], python.velocity[rows]
    assert np.array_equal(np.isnan(generated.velocity), np.isnan(v))
    tolerance = max(tolerance, 1e-11 if "houbolt" in generated.info["method"] else tolerance)
    assert np.max(np.abs(generated.states[:, :, 0] - x)) <= tolerance * np.max(np.abs(x))
    assert np.nanmax(np.abs(generated.velocity - v)) <= tolerance * np.nanmax(np.abs(v))


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("name", ["maxwell", "series", "km", "wall"])
def test_each_generated_scheme_is_the_python_dttmm_step(name, scheme):
    chain = chains()[name]
    first = next(e.name for e in chain.body if isinstance(e, Mass))
    start = {"x0": {first: 0.03}, "v0": {first: 0.2}}
    generated = ctmm.simulate(chain, 0.3, 1e-3, method=scheme, compiled=True, **start)
    python = ctmm.simulate(chain, 0.3, 1e-3, method=scheme, **start)
    assert generated.info["method"] == f"{scheme}-generated"
    # the wall's step of 0.02 m in one step rings the trapezoidal (Newmark) velocity of the wall and of the damper
    # node next to it at +-2 dX / h = 40 m/s for ever (undamped): the round-off it carries grows to ~2e-12 of the motion
    _same(generated, python, tolerance=5e-12 if name == "wall" else 1e-12)
    if scheme == "newmark":          # Newmark meets the equation of motion at t_{n+1}: the masses' accelerations too
        masses = [e.name for e in chain.body if isinstance(e, Mass)]
        for mass in masses:
            scale = max(1.0, float(np.max(np.abs(python[f"{mass}.a"]))))
            assert np.max(np.abs(generated[f"{mass}.a"] - python[f"{mass}.a"])) <= 1e-11 * scale, mass


def test_stored_every_third_step_the_algebraic_node_velocity_from_the_kept_positions():
    """The velocity of an algebraic massless node is a backward difference of its positions; the generated state
    keeps ``x_{n-1}``, ``x_{n-2}``, so the stored rows carry it whatever ``store_every`` is."""
    chain = chains()["series"]
    generated = ctmm.simulate(chain, 0.3, 1e-3, method="newmark", compiled=True, x0={"m1": 0.03}, store_every=3)
    python = ctmm.simulate(chain, 0.3, 1e-3, method="newmark", x0={"m1": 0.03})
    assert len(generated.time) == 101
    _same(generated, python, store_every=3)


def test_generated_newmark_is_a_textbook_global_newmark_with_a_massless_node_and_a_moving_base():
    """``base -k0- z -c0- m0 -s1(k1, c1)- y -k2- m1 - Free`` with ``base = X(t)``: textbook Newmark on the global
    ``M (singular at z, y), C, K`` with the base a degree of freedom imposed at every step."""
    k0, c0, m0, k1, c1, k2, m1 = 80.0, 3.0, 1.0, 60.0, 0.4, 90.0, 0.7
    amplitude, omega = 0.01, 6.0
    chain = ctmm.Chain("g", [PrescribedDisplacement("base", Harmonic(amplitude, omega)), Spring("k0", k0),
                             Damper("c0", c0), Mass("m0", m0), SpringDamper("s1", k1, c1), Spring("k2", k2),
                             Mass("m1", m1), Free("e")])
    # DOFs [X, z, m0, y, m1]: K and C of the connectors, M of the masses
    K, C = np.zeros((5, 5)), np.zeros((5, 5))
    for (i, j), k, c in (((0, 1), k0, 0.0), ((1, 2), 0.0, c0), ((2, 3), k1, c1), ((3, 4), k2, 0.0)):
        for matrix, value in ((K, k), (C, c)):
            matrix[np.ix_([i, j], [i, j])] += value * np.array([[1.0, -1.0], [-1.0, 1.0]])
    M = np.diag([0.0, 0.0, m0, 0.0, m1])
    free = [1, 2, 3, 4]
    h, beta, gamma, steps = 1e-3, 0.3, 0.6, 300
    X = lambda t: amplitude * np.sin(omega * t)                      # noqa: E731
    x, v, a = np.zeros(5), np.zeros(5), np.zeros(5)
    x[4] = 0.02
    x[3] = k1 * x[2] / (k1 + k2) + k2 * x[4] / (k1 + k2)             # the spring node on its balance
    v[0] = amplitude * omega                                         # the base's start velocity (the Python start)
    a[[2, 4]] = np.linalg.solve(M[np.ix_([2, 4], [2, 4])], -(K @ x + C @ v)[[2, 4]])
    rows = [x.copy()]
    F = np.ix_(free, free)
    effective = M[F] + gamma * h * C[F] + beta * h * h * K[F]
    for n in range(steps):
        x_pred, v_pred = x + h * v + (0.5 - beta) * h * h * a, v + (1.0 - gamma) * h * a
        a_new = np.zeros(5)
        a_new[0] = (X((n + 1) * h) - x_pred[0]) / (beta * h * h)      # the base imposed at t_{n+1}
        x_base, v_base = x_pred + beta * h * h * a_new, v_pred + gamma * h * a_new
        a_new[free] = np.linalg.solve(effective, -(K @ x_base + C @ v_base)[free])
        x, v, a = x_pred + beta * h * h * a_new, v_pred + gamma * h * a_new, a_new
        rows.append(x.copy())
    rows = np.array(rows)
    generated = ctmm.simulate(chain, steps * h, h, method=Newmark(beta, gamma), compiled=True, x0={"m1": 0.02})
    for column, name in ((0, "base.x"), (1, "k0.x"), (2, "m0.x"), (3, "s1.x"), (4, "m1.x")):
        assert np.max(np.abs(generated[name] - rows[:, column])) < 1e-13 * np.max(np.abs(rows)), name


def test_newmark_converges_at_second_order_to_the_condensed_ode():
    """``base = X(t) -k- z -c- m -Free``: ``c (z' - X') = ... `` hand-written: ``k (z - X) = c (v - z')`` is the
    node's balance, ``m v' = -c (v - z')``; DOP853 at 1e-13; the trapezoidal Newmark (beta 1/4, gamma 1/2) at
    second order."""
    k, c, m, amplitude, omega = 40.0, 2.0, 1.5, 0.02, 5.0
    X = lambda t: amplitude * np.sin(omega * t)                      # noqa: E731
    chain = ctmm.Chain("o", [PrescribedDisplacement("base", Harmonic(amplitude, omega)), Spring("k", k),
                             Damper("c", c), Mass("m", m), Free("e")])

    def rates(t, s):
        z, x, v = s
        z_rate = v - k * (z - X(t)) / c
        return [z_rate, v, -c * (v - z_rate) / m]

    errors = []
    for dt in (4e-3, 2e-3):
        generated = ctmm.simulate(chain, 0.8, dt, method="newmark", compiled=True, x0={"m": 0.03})
        exact = solve_ivp(rates, (0.0, 0.8), [0.0, 0.03, 0.0], method="DOP853", t_eval=generated.time, rtol=1e-13,
                          atol=1e-15).y
        errors.append(float(np.max(np.abs(generated["m.x"] - exact[1]))))
    order = np.log2(errors[0] / errors[1])
    assert errors[1] < 1e-5 and abs(order - 2.0) < 0.3, (errors, order)


def test_what_the_generated_dttmm_step_still_refuses_is_named():
    maxwell = chains()["maxwell"]
    with pytest.raises(ModelError, match="loops and held actuators .* generated in the RK4"):
        ctmm.simulate(ControlledChain(maxwell, [Feedback("l", "k1.x", "m", gain=1.0)]), 0.01, 1e-3, method="newmark",
                      compiled=True)
    called = ctmm.Chain("u", [PrescribedDisplacement("base", lambda t: 0.01 * t), Spring("k", 10.0), Mass("m", 1.0),
                              Free("e")])
    with pytest.raises(ModelError, match="base: the displacement signal .* Python callable"):
        ctmm.simulate(called, 0.01, 1e-3, method="newmark", compiled=True)
