"""Generated RK4 of 1-D chains with massless points and prescribed boundary motion (``compiled_chain_condensed``).

Independent references: closed-form / hand-written state equations of small chains (two springs in series, a
Maxwell spring--damper node by the matrix exponential, base excitation by DOP853 at 1e-12); RK4's fourth order
asserted from two steps.  The generated step equals the Python ODE path (``compiled=False``) to round-off.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.integrate import solve_ivp

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import (Damper, Fixed, Free, Mass, PrescribedDisplacement, PrescribedForce, Spring,
                           SpringDamper)
from ctmm.errors import ModelError
from ctmm.signals import Harmonic, Step

pytest.importorskip("casadi")


def _order(errors) -> float:
    return float(np.log2(errors[0] / errors[1]))


def _same(generated, python) -> None:
    """Every stored signal of the generated run equals the Python ODE path's (NaN where that path has NaN)."""
    assert generated.info["method"] == "rk4-generated"
    np.testing.assert_array_equal(generated.time, python.time)
    for mine, theirs in ((generated.states, python.states), (generated.velocity, python.velocity),
                         (generated.acceleration, python.acceleration)):
        assert np.array_equal(np.isnan(mine), np.isnan(theirs))
        scale = max(1.0, float(np.nanmax(np.abs(theirs))))
        assert np.nanmax(np.abs(mine - theirs)) <= 1e-12 * scale


def _both(chain, t_final, dt, **options):
    return (ctmm.simulate(chain, t_final, dt, method="rk4", compiled=True, **options),
            ctmm.simulate(chain, t_final, dt, method="rk4", compiled=False, **options))


def test_two_springs_in_series_condense_to_one():
    """An algebraic massless node: the SDOF with ``k1 k2 / (k1 + k2)``, fourth order, as the Python path."""
    k1, k2, m, x0 = 100.0, 300.0, 2.0, 0.1
    chain = ctmm.Chain("series", [Fixed("w"), Spring("k1", k1), Spring("k2", k2), Mass("m", m), Free("e")])
    omega = np.sqrt(k1 * k2 / (k1 + k2) / m)
    errors = []
    for dt in (0.02, 0.01):
        generated, python = _both(chain, 1.0, dt, x0={"m": x0})
        _same(generated, python)
        errors.append(float(np.max(np.abs(generated["m.x"] - x0 * np.cos(omega * generated.time)))))
        assert np.allclose(generated.states[:, 1, 0], generated["m.x"] * k2 / (k1 + k2), rtol=1e-12, atol=1e-15)
    assert 3.7 <= _order(errors) <= 4.4, errors


def test_a_maxwell_node_is_a_first_order_state_of_the_generated_step():
    """``m x'' = -k q``, ``c (x' - q') = k q`` (hand-written, by the matrix exponential)."""
    k, c, m = 100.0, 5.0, 2.0
    chain = ctmm.Chain("maxwell", [Fixed("w"), Spring("k", k), Damper("c", c), Mass("m", m), Free("e")])
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -k / m], [0.0, 1.0, -k / c]])
    z0 = np.array([0.1, 1.0, 0.0])
    errors, node_errors = [], []
    for dt in (0.02, 0.01):
        generated, python = _both(chain, 0.4, dt, x0={"m": 0.1}, v0={"m": 1.0})
        _same(generated, python)
        exact = np.array([sla.expm(A * t) @ z0 for t in generated.time])
        errors.append(float(np.max(np.abs(generated["m.x"] - exact[:, 0]))))
        node_errors.append(float(np.max(np.abs(generated.states[:, 1, 0] - exact[:, 2]))))
    assert 3.7 <= _order(errors) <= 4.4, errors
    assert 3.7 <= _order(node_errors) <= 4.4, node_errors


def test_a_driven_maxwell_element_without_any_mass():
    """Base ``X = A sin(w t)`` through ``k`` and ``c`` to a wall: ``q' = (k / c) (X - q)``, ``q(0) = 0``, in closed
    form ``q = A / (1 + (w tau)^2) (sin w t - w tau cos w t + w tau exp(-t / tau))``, ``tau = c / k``."""
    k, c, amplitude, w = 40.0, 2.0, 0.01, 7.0
    tau = c / k
    chain = ctmm.Chain("relax", [PrescribedDisplacement("base", Harmonic(amplitude, w)), Spring("k", k),
                                 Damper("c", c), Fixed("wall")])
    errors = []
    for dt in (0.01, 0.005):
        generated, python = _both(chain, 0.5, dt)
        _same(generated, python)
        t = generated.time
        exact = amplitude / (1.0 + (w * tau) ** 2) * (np.sin(w * t) - w * tau * np.cos(w * t)
                                                      + w * tau * np.exp(-t / tau))
        errors.append(float(np.max(np.abs(generated.states[:, 1, 0] - exact))))
    assert 3.7 <= _order(errors) <= 4.4, errors
    assert errors[1] < 1e-6 * amplitude                 # RK4 at dt = tau / 10


def test_base_excitation_and_a_driven_end_wall():
    """``m x'' = -k (x - X) - c (x' - X')`` (base) and ``m x'' = -k x + k2 (X - x)`` (end wall), ``X = A sin(w t)``:
    hand-written ODEs by DOP853 at 1e-12; fourth order; the reaction of a mass riding on the driven end."""
    amplitude, w, k, c, k2, m, mw = 0.02, 9.0, 250.0, 1.2, 100.0, 1.3, 2.0
    X = lambda t: amplitude * np.sin(w * t)                                         # noqa: E731
    V = lambda t: amplitude * w * np.cos(w * t)                                     # noqa: E731
    base = ctmm.Chain("base", [PrescribedDisplacement("base", Harmonic(amplitude, w)), SpringDamper("s", k, c),
                               Mass("m", m), Free("e")])
    end = ctmm.Chain("end", [Fixed("w"), Spring("k", k), Mass("m", m), Spring("k2", k2), Mass("mw", mw),
                             PrescribedDisplacement("end", Harmonic(amplitude, w))])
    rates = {"base": lambda t, z: [z[1], (-k * (z[0] - X(t)) - c * (z[1] - V(t))) / m],
             "end": lambda t, z: [z[1], (-k * z[0] + k2 * (X(t) - z[0])) / m]}
    for chain in (base, end):
        errors = []
        for dt in (0.02, 0.01):
            generated, python = _both(chain, 1.0, dt)
            _same(generated, python)
            exact = solve_ivp(rates[chain.name], (0.0, 1.0), [0.0, 0.0], t_eval=generated.time, rtol=1e-12,
                              atol=1e-14, method="DOP853").y[0]
            errors.append(float(np.max(np.abs(generated["m.x"] - exact))))
        assert 3.7 <= _order(errors) <= 4.4, (chain.name, errors)
    assert np.allclose(generated["mw.x"], X(generated.time), rtol=0.0, atol=1e-15)


def test_a_kelvin_maxwell_chain_with_massless_nodes_and_a_driven_base_as_the_python_path():
    chain = ctmm.Chain("km", [PrescribedDisplacement("base", Harmonic(0.01, 6.0, 0.3)), Spring("k0", 80.0),
                              Damper("c0", 3.0), Mass("m0", 1.0), SpringDamper("s1", 60.0, 0.4), Spring("k2", 90.0),
                              Spring("k3", 45.0), Mass("m1", 0.7, force=Harmonic(1.5, 3.0)), Free("e")])
    generated, python = _both(chain, 0.3, 0.005, x0={"m0": 0.02}, v0={"m1": -0.1})
    _same(generated, python)


def test_constant_supports_away_from_zero_with_a_maxwell_node_at_the_wall():
    chain = ctmm.Chain("held", [PrescribedDisplacement("base", 0.05), Spring("k0", 70.0), Mass("m0", 1.2),
                                Spring("k1", 40.0), Damper("c1", 2.5), Fixed("wall", position=0.3)])
    generated, python = _both(chain, 0.3, 0.005, x0={"m0": 0.1})
    _same(generated, python)
    assert np.all(generated["base.x"] == 0.05)


def test_a_feedback_loop_on_a_base_excited_mass():
    """``m x'' = -k (x - X) - c (x' - X') - g x`` (a loop ``u = -g x`` on the mass): DOP853 at 1e-12, fourth
    order, and the Python loop driver; a sensor across the driven spring is refused by name."""
    amplitude, w, k, c, m, gain = 0.02, 9.0, 250.0, 1.2, 1.3, 80.0
    X = lambda t: amplitude * np.sin(w * t)                                         # noqa: E731
    V = lambda t: amplitude * w * np.cos(w * t)                                     # noqa: E731
    chain = ctmm.Chain("base", [PrescribedDisplacement("base", Harmonic(amplitude, w)), SpringDamper("s", k, c),
                                Mass("m", m), Free("e")])
    looped = ControlledChain(chain, [Feedback("l", "m.x", "m", gain=gain)])
    errors = []
    for dt in (0.02, 0.01):
        generated, python = _both(looped, 1.0, dt)
        assert generated.info["method"] == "rk4-generated"
        for name in ("m.x", "m.v", "s.f", "l.u", "base.x"):
            np.testing.assert_allclose(generated[name], python[name], rtol=0, atol=1e-12)
        exact = solve_ivp(lambda t, z: [z[1], (-k * (z[0] - X(t)) - c * (z[1] - V(t)) - gain * z[0]) / m],
                          (0.0, 1.0), [0.0, 0.0], t_eval=generated.time, rtol=1e-12, atol=1e-14, method="DOP853").y[0]
        errors.append(float(np.max(np.abs(generated["m.x"] - exact))))
    assert 3.7 <= _order(errors) <= 4.4, errors
    across = ControlledChain(chain, [Feedback("l", "s.f", "m", gain=0.1)])
    with pytest.raises(ModelError, match="sensor 's.f' of loop 'l' moves with the prescribed motion"):
        ctmm.simulate(across, 0.1, 0.01, method="rk4", compiled=True)


def test_refusals_name_what_the_generated_rk4_does_not_take():
    massless = ctmm.Chain("q", [Fixed("s"), Spring("k0", 100.0), Mass("m0", 1.0), Spring("k1", 50.0),
                                Spring("k2", 50.0), Mass("m1", 1.0), Free("e")])
    looped = ControlledChain(massless, [Feedback("l", "m1.x", "k2", gain=1.0)])
    with pytest.raises(ModelError, match="'k2' acts on a point without inertia"):
        ctmm.simulate(looped, 0.1, 0.01, method="rk4", compiled=True)
    with pytest.raises(ModelError, match="loops and held actuators .* generated in the RK4"):
        ctmm.simulate(ControlledChain(massless, [Feedback("l", "m1.x", "m0", gain=1.0)]), 0.1, 0.01,
                      method="newmark", compiled=True)
    stepped = ctmm.Chain("s", [PrescribedDisplacement("base", Step(0.1, 0.05)), Spring("k", 10.0), Mass("m", 1.0),
                               Free("e")])
    with pytest.raises(ModelError, match="base: the displacement signal .* no closed-form"):
        ctmm.simulate(stepped, 0.1, 0.01, method="rk4", compiled=True)
    called = ctmm.Chain("u", [PrescribedDisplacement("base", lambda t: 0.01 * t), Spring("k", 10.0), Mass("m", 1.0),
                              Free("e")])
    with pytest.raises(ModelError, match="base: the displacement signal"):
        ctmm.simulate(called, 0.1, 0.01, method="rk4", compiled=True)
    moved = ctmm.Chain("f", [PrescribedForce("F", Harmonic(2.0, 3.0)), Spring("k", 100.0), Mass("m", 2.0),
                             Spring("k2", 50.0), Fixed("e")])
    with pytest.raises(ModelError, match="'force' load .* of 'F' acts on a point without inertia"):
        ctmm.simulate(moved, 0.1, 0.01, method="rk4", compiled=True)
    driven = ctmm.Chain("d", [PrescribedDisplacement("base", Harmonic(0.01, 3.0)), Spring("k", 10.0), Mass("m", 1.0),
                              Free("e")])
    with pytest.raises(ModelError, match="loops and held actuators .* prescribed motion .* generated in the RK4"):
        ctmm.simulate(ControlledChain(driven, [Feedback("l", "m.x", "m", gain=1.0)]), 0.1, 0.01, method="newmark",
                      compiled=True)
