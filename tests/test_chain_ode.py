"""ODE integrators for plain 1-D chains (``ctmm.simulate(chain, method="rk4" | solve_ivp)``, ``ctmm/chain_ode.py``).

Independent references only: the matrix exponential of the global equations (``reference/chain.py``),
``reference/inerter_chain.py``, and closed-form / hand-written state equations of small chains (two
springs in series, a Maxwell spring--damper node, base excitation).  RK4's order is asserted from two
steps; every ``solve_ivp`` method is held to its tolerance.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

import ctmm
from ctmm.control.loops import ControlledChain, Feedback
from ctmm.elements import (Damper, Fixed, Free, Mass, PrescribedDisplacement, PrescribedForce, Spring,
                           SpringDamper)
from ctmm.errors import ModelError
from ctmm.reference import chain as global_chain
from ctmm.reference import inerter_chain
from ctmm.signals import Harmonic, Step
from _chain_convert import inerter_chains, random_chain, to_global

SOLVE_IVP = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")


def _masses(chain) -> list[str]:
    return [e.name for e in chain.body if isinstance(e, Mass)]


def _assert_fourth_order(errors) -> None:
    order = np.log2(errors[0] / errors[1])
    assert 3.7 <= order <= 4.4, (errors, order)


@pytest.mark.parametrize("start, end", [("fixed", "fixed"), ("free", "elastic")])
def test_rk4_is_fourth_order_against_the_matrix_exponential(start, end):
    rng = np.random.default_rng(7)
    chain = random_chain(rng, 3, start=start, end=end, damped=True, grounded=True)
    reference = to_global(chain)
    names = _masses(chain)
    x0 = rng.normal(scale=0.05, size=len(names))
    t_final, steps = 0.2, (0.008, 0.004)
    times = np.linspace(0.0, t_final, int(round(t_final / steps[0])) + 1)
    exact = global_chain.exact_response(reference, times, x0, np.zeros(len(names)), np.zeros(len(names))).displacement
    finer = global_chain.exact_response(reference, np.linspace(0.0, t_final, int(round(t_final / steps[1])) + 1),
                                        x0, np.zeros(len(names)), np.zeros(len(names))).displacement
    errors = []
    for dt, truth in zip(steps, (exact, finer)):
        result = ctmm.simulate(chain, t_final, dt, method="rk4", x0=dict(zip(names, x0)))
        errors.append(max(float(np.max(np.abs(result[f"{n}.x"] - truth[:, i]))) for i, n in enumerate(names)))
    _assert_fourth_order(errors)
    assert errors[1] < 1e-6


@pytest.mark.parametrize("method", SOLVE_IVP)
def test_every_solve_ivp_method_meets_its_tolerance(method):
    rng = np.random.default_rng(11)
    chain = random_chain(rng, 3, start="fixed", end="free", damped=True)
    reference = to_global(chain)
    names = _masses(chain)
    x0, v0 = rng.normal(scale=0.05, size=(2, len(names)))
    times = np.linspace(0.0, 0.2, 21)
    exact = global_chain.exact_response(reference, times, x0, v0, np.zeros(len(names))).displacement
    result = ctmm.simulate(chain, 0.2, 0.01, method=method, x0=dict(zip(names, x0)), v0=dict(zip(names, v0)),
                           rtol=1e-9, atol=1e-12)
    assert np.allclose(result.time, times, rtol=0.0, atol=1e-12)
    error = max(float(np.max(np.abs(result[f"{n}.x"] - exact[:, i]))) for i, n in enumerate(names))
    assert error <= 2e-6 * float(np.max(np.abs(exact))), error          # rtol 1e-9: global error well inside


def test_same_signals_and_units_as_the_dt_tmm_path():
    chain = ctmm.Chain("sdof", [Fixed("wall"), SpringDamper("k", 400.0, 0.5), Mass("m", 1.5, force=2.0), Free("end")])
    ode = ctmm.simulate(chain, 0.2, 1e-3, method="rk4", x0={"m": 0.01})
    dt_tmm = ctmm.simulate(chain, 0.2, 1e-3, x0={"m": 0.01})
    assert ode.signals() == dt_tmm.signals()
    assert ode.states.shape == dt_tmm.states.shape
    for name in ("m.x", "m.v", "m.a", "k.f", "wall.f"):
        assert np.max(np.abs(ode[name] - dt_tmm[name])) <= 2e-3 * np.max(np.abs(dt_tmm[name])), name


def test_two_springs_in_series_condense_to_one():
    """A node between two springs is algebraic: the chain is the SDOF with ``k1 k2 / (k1 + k2)``."""
    k1, k2, m, x0 = 100.0, 300.0, 2.0, 0.1
    chain = ctmm.Chain("series", [Fixed("w"), Spring("k1", k1), Spring("k2", k2), Mass("m", m), Free("e")])
    omega = np.sqrt(k1 * k2 / (k1 + k2) / m)
    steps = (0.02, 0.01)
    errors = []
    for dt in steps:
        result = ctmm.simulate(chain, 1.0, dt, method="rk4", x0={"m": x0})
        exact = x0 * np.cos(omega * result.time)
        errors.append(float(np.max(np.abs(result["m.x"] - exact))))
        node = result.states[:, 1, 0]                                # the massless point: static split
        assert np.allclose(node, result["m.x"] * k2 / (k1 + k2), rtol=1e-12, atol=1e-15)
        assert np.allclose(result.velocity[:, 1, 0], result["m.v"] * k2 / (k1 + k2), rtol=1e-12, atol=1e-15)
        assert np.all(np.isnan(result.acceleration[:, 1, 0]))         # not a state of the ODE
    _assert_fourth_order(errors)


def test_a_node_between_a_spring_and_a_damper_is_a_first_order_state():
    """Maxwell element: ``m x'' = -k q``, ``c (x' - q') = k q`` (hand-written, by the matrix exponential)."""
    k, c, m = 100.0, 5.0, 2.0
    chain = ctmm.Chain("maxwell", [Fixed("w"), Spring("k", k), Damper("c", c), Mass("m", m), Free("e")])
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -k / m], [0.0, 1.0, -k / c]])
    z0 = np.array([0.1, 1.0, 0.0])
    steps = (0.02, 0.01)
    errors, node_errors = [], []
    for dt in steps:
        result = ctmm.simulate(chain, 0.4, dt, method="rk4", x0={"m": 0.1}, v0={"m": 1.0})
        exact = np.array([sla.expm(A * t) @ z0 for t in result.time])
        errors.append(float(np.max(np.abs(result["m.x"] - exact[:, 0]))))
        node_errors.append(float(np.max(np.abs(result.states[:, 1, 0] - exact[:, 2]))))
    _assert_fourth_order(errors)
    _assert_fourth_order(node_errors)
    for method in ("DOP853",):
        result = ctmm.simulate(chain, 1.0, 0.1, method=method, x0={"m": 0.1}, v0={"m": 1.0}, rtol=1e-9, atol=1e-12)
        exact = np.array([sla.expm(A * t) @ z0 for t in result.time])
        assert np.max(np.abs(result["m.x"] - exact[:, 0])) <= 1e-6, method


@pytest.mark.parametrize("end", ["fixed", "free"])
def test_inerter_chains_against_the_global_equations(end):
    rng = np.random.default_rng(5)
    n = 4
    masses = rng.uniform(0.3, 2.0, n)
    masses[1] = 0.0                                           # held only by the inerters beside it
    k, c, b = rng.uniform(20, 200, n + 1), rng.uniform(0.1, 1.0, n + 1), rng.uniform(0.1, 0.8, n + 1)
    chain, reference = inerter_chains(masses, k, c, b, end)
    x0 = np.array([0.05, 0.0, -0.03, 0.02])
    given = {f"m{j}": x0[j] for j in range(n) if masses[j]}
    times = np.linspace(0.0, 0.5, 26)
    x_ref, _ = inerter_chain.time_response(reference, times, x0, np.zeros(n))
    result = ctmm.simulate(chain, 0.5, 0.02, method="DOP853", x0=given, rtol=1e-11, atol=1e-14)
    for j in range(n):
        signal = result[f"m{j}.x"] if masses[j] else result.states[:, chain.position(f"c{j}"), 0]
        assert np.max(np.abs(signal - x_ref[:, j])) <= 1e-8, j


def test_base_excitation_with_a_harmonic_prescribed_start():
    """``m x'' = -k (x - X) - c (x' - X')``, ``X = A sin(w t)`` (hand-written ODE, DOP853 at 1e-12)."""
    from scipy.integrate import solve_ivp

    k, c, m, amplitude, w = 250.0, 1.2, 1.3, 0.02, 9.0
    chain = ctmm.Chain("base", [PrescribedDisplacement("base", Harmonic(amplitude, w)), SpringDamper("s", k, c),
                                Mass("m", m), Free("e")])

    def rhs(t, z):
        X, V = amplitude * np.sin(w * t), amplitude * w * np.cos(w * t)
        return [z[1], (-k * (z[0] - X) - c * (z[1] - V)) / m]

    times = np.linspace(0.0, 1.0, 51)
    exact = solve_ivp(rhs, (0.0, 1.0), [0.0, 0.0], t_eval=times, rtol=1e-12, atol=1e-14, method="DOP853").y[0]
    result = ctmm.simulate(chain, 1.0, 0.02, method="RK45", rtol=1e-10, atol=1e-13)
    assert np.max(np.abs(result["m.x"] - exact)) <= 1e-8
    assert np.allclose(result["base.x"], amplitude * np.sin(w * times), rtol=0.0, atol=1e-15)


def test_a_force_through_a_spring_on_a_massless_start():
    """The massless start point moves with ``x_m - F/k``; its velocity with ``v_m - F'/k``."""
    k, k2, m = 100.0, 50.0, 2.0
    force = Harmonic(2.0, 3.0)
    chain = ctmm.Chain("pulled", [PrescribedForce("F", force), Spring("k", k), Mass("m", m), Spring("k2", k2),
                                  Fixed("e")])
    from scipy.integrate import solve_ivp

    times = np.linspace(0.0, 1.0, 11)
    exact = solve_ivp(lambda t, z: [z[1], (force(t) - k2 * z[0]) / m], (0.0, 1.0), [0.0, 0.0], t_eval=times,
                      rtol=1e-12, atol=1e-14, method="DOP853").y
    result = ctmm.simulate(chain, 1.0, 0.1, method="DOP853", rtol=1e-11, atol=1e-14)
    assert np.max(np.abs(result["m.x"] - exact[0])) <= 1e-9
    rate = 2.0 * 3.0 * np.cos(3.0 * times)
    sign = np.sign(result.states[3, 0, 0] - result["m.x"][3]) * np.sign(force(0.3))
    values = np.array([force(t) for t in times])
    assert np.allclose(result.states[:, 0, 0], result["m.x"] + sign * values / k, atol=1e-12)
    assert np.allclose(result.velocity[:, 0, 0], result["m.v"] + sign * rate / k, atol=1e-10)


def test_refusals_name_the_reason_and_the_alternative():
    plain = ctmm.Chain("p", [Fixed("w"), Spring("k", 10.0), Mass("m", 1.0), Free("e")])
    controlled = ControlledChain(plain, [Feedback("acc", "m.a", "m", gain=0.1)])
    with pytest.raises(ModelError, match="accelerations are not sensors.*newmark"):
        ctmm.simulate(controlled, 1.0, 0.01, method="rk4")
    stepped = ctmm.Chain("s", [PrescribedDisplacement("base", Step(0.1, 0.5)), Spring("k", 10.0), Mass("m", 1.0),
                               Free("e")])
    with pytest.raises(ModelError, match="no closed-form rate.*DT-TMM"):
        ctmm.simulate(stepped, 1.0, 0.01, method="rk4")
    with pytest.raises(ModelError, match="solver"):
        ctmm.simulate(plain, 1.0, 0.01, method="RK45", solver="plain")
    with pytest.raises(ModelError, match="whole number"):
        ctmm.simulate(plain, 1.0, 0.3, method="rk4")


@pytest.mark.parametrize("option", [{"rtol": 1e-2}, {"atol": 1.0}, {"max_step": 1e-5}])
def test_fixed_step_rk4_refuses_the_adaptive_options_as_planar_models_do(option):
    """rtol, atol and max_step do not act on the fixed-step RK4: refused by name on a chain, with or without
    loops, as on a planar model (a chain's RK4 ignored them silently, the run bit-identical to the default)."""
    plain = ctmm.Chain("p", [Fixed("w"), Spring("k", 10.0), Mass("m", 1.0), Free("e")])
    controlled = ControlledChain(plain, [Feedback("pd", "m.v", "m", gain=0.5)])
    (name, value), = option.items()
    for system in (plain, controlled):
        with pytest.raises(ModelError, match=f"{name}=.* applies to the solve_ivp methods.*not to method='rk4'"):
            ctmm.simulate(system, 0.1, 0.01, method="rk4", x0={"m": 0.01}, **option)
    with pytest.raises(ModelError, match=f"{name}=.* DT-TMM stepper of a chain.*solve_ivp methods take {name}"):
        ctmm.simulate(plain, 0.1, 0.01, method="newmark", **option)
    with pytest.raises(ModelError, match="inputs=.* DT-TMM stepper of a chain.*ODE methods .* take inputs"):
        ctmm.simulate(plain, 0.1, 0.01, method="newmark", inputs={"m": Step(1.0, 0.0)})
    ctmm.simulate(plain, 0.1, 0.01, method="RK45", x0={"m": 0.01}, **option)     # where they apply


def test_a_diverging_run_stops_with_the_partial_result():
    chain = ctmm.Chain("p", [Fixed("w"), Spring("k", 1.0e6), Mass("m", 1.0), Free("e")])
    with pytest.raises(ctmm.SimulationError) as caught:
        ctmm.simulate(chain, 1.0, 0.01, method="rk4", x0={"m": 0.1})   # omega h = 10 > 2 sqrt 2
    partial = caught.value.partial_result
    assert partial is not None and 1 <= len(partial.time) < 101
    assert np.all(np.isfinite(partial["m.x"]))


@pytest.mark.parametrize("scheme", ["newmark", "generalized_alpha"])
def test_dt_tmm_runs_start_massless_nodes_consistently(scheme):
    """A massless node starts at its balance under ``x0`` (springs in series) and with its balance
    velocity (Maxwell node): the scheme's second order is kept from the first step (it was O(h))."""
    k1, k2, m, x0 = 100.0, 300.0, 2.0, 0.1
    series = ctmm.Chain("series", [Fixed("w"), Spring("k1", k1), Spring("k2", k2), Mass("m", m), Free("e")])
    omega = np.sqrt(k1 * k2 / (k1 + k2) / m)
    k, c = 100.0, 5.0
    maxwell = ctmm.Chain("maxwell", [Fixed("w"), Spring("k", k), Damper("c", c), Mass("m", m), Free("e")])
    A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, -k / m], [0.0, 1.0, -k / c]])
    for chain, start, exact in (
            (series, {"x0": {"m": x0}}, lambda t: x0 * np.cos(omega * t)),
            (maxwell, {"x0": {"m": 0.1}, "v0": {"m": 1.0}},
             lambda t: np.array([(sla.expm(A * s) @ [0.1, 1.0, 0.0])[0] for s in t]))):
        errors = []
        for dt in (0.01, 0.005):
            result = ctmm.simulate(chain, 0.5, dt, method=scheme, **start)
            errors.append(float(np.max(np.abs(result["m.x"] - exact(result.time)))))
        order = np.log2(errors[0] / errors[1])
        assert 1.8 <= order <= 2.3, (chain.name, errors, order)
    result = ctmm.simulate(series, 0.1, 0.01, x0={"m": x0})
    assert result.states[0, 1, 0] == pytest.approx(x0 * k2 / (k1 + k2), rel=1e-12)
    result = ctmm.simulate(maxwell, 0.1, 0.01, x0={"m": 0.1}, v0={"m": 1.0})
    assert result.velocity[0, 1, 0] == pytest.approx(1.0, rel=1e-12)


def test_a_mass_on_a_driven_end_moves_with_it_and_loads_its_reaction():
    """Masses directly on prescribed displacements (start and end): they move with the boundary and their
    inertia force enters its reaction (hand-written equations, DOP853 at 1e-12)."""
    from scipy.integrate import solve_ivp

    amplitude, w, k, c, k2, m, m0, mw = 0.01, 5.0, 200.0, 0.8, 100.0, 1.0, 3.0, 2.0
    X = lambda t: amplitude * np.sin(w * t)                                         # noqa: E731
    V = lambda t: amplitude * w * np.cos(w * t)                                     # noqa: E731
    Acc = lambda t: -amplitude * w * w * np.sin(w * t)                              # noqa: E731
    times = np.linspace(0.0, 0.5, 26)
    driven_start = ctmm.Chain("start", [PrescribedDisplacement("base", Harmonic(amplitude, w)), Mass("m0", m0),
                                        SpringDamper("s", k, c), Mass("m", m), Free("e")])
    exact = solve_ivp(lambda t, z: [z[1], (-k * (z[0] - X(t)) - c * (z[1] - V(t))) / m], (0.0, 0.5), [0.0, 0.0],
                      t_eval=times, rtol=1e-12, atol=1e-14, method="DOP853").y
    result = ctmm.simulate(driven_start, 0.5, 0.02, method="DOP853", rtol=1e-11, atol=1e-14)
    assert np.max(np.abs(result["m.x"] - exact[0])) <= 1e-9
    assert np.allclose(result["m0.x"], X(times), atol=1e-15)
    assert np.allclose(result.acceleration[:, 0, 0], Acc(times), atol=1e-12)
    connector = -k * (exact[0] - X(times)) - c * (exact[1] - V(times))
    assert np.max(np.abs(result.states[:, 1, 1] - connector)) <= 1e-7
    assert np.max(np.abs(result.states[:, 0, 1] - (connector + m0 * Acc(times)))) <= 1e-7

    driven_end = ctmm.Chain("end", [Fixed("w"), Spring("k", k), Mass("m", m), Spring("k2", k2), Mass("mw", mw),
                                    PrescribedDisplacement("end", Harmonic(amplitude, w))])
    exact = solve_ivp(lambda t, z: [z[1], (-k * z[0] + k2 * (X(t) - z[0])) / m], (0.0, 0.5), [0.0, 0.0],
                      t_eval=times, rtol=1e-12, atol=1e-14, method="DOP853").y
    result = ctmm.simulate(driven_end, 0.5, 0.02, method="DOP853", rtol=1e-11, atol=1e-14)
    assert np.max(np.abs(result["m.x"] - exact[0])) <= 1e-9
    assert np.allclose(result["mw.x"], X(times), atol=1e-15)
    spring = -k2 * (X(times) - exact[0])                              # force of k2 on its outboard point
    assert np.max(np.abs(result.states[:, 3, 1] - spring)) <= 1e-7
    assert np.max(np.abs(result.states[:, 4, 1] - (spring - mw * Acc(times)))) <= 1e-7
    # a DT-TMM scheme refuses the moving case by name (its support acceleration would not converge) ...
    with pytest.raises(ModelError, match="sits directly on the driven boundary 'end'.*ODE method"):
        ctmm.simulate(driven_end, 0.5, 0.01)
    # ... and runs a mass resting on a Fixed support (refused before), reaction from the mass at rest
    resting = ctmm.Chain("rest", [Fixed("w"), Mass("m0", m0), Spring("k", k), Mass("m", m), Free("e")])
    newmark = ctmm.simulate(resting, 0.5, 0.001, x0={"m": 0.01})
    ode = ctmm.simulate(resting, 0.5, 0.001, method="DOP853", x0={"m": 0.01}, rtol=1e-11, atol=1e-14)
    assert np.all(newmark["m0.x"] == 0.0) and np.all(newmark.acceleration[:, 0, 0] == 0.0)
    assert np.max(np.abs(newmark.states[:, 0, 1] - ode.states[:, 0, 1])) <= 1e-3 * np.max(np.abs(ode.states[:, 0, 1]))


def test_x0_of_a_massless_point_is_an_initial_value_only_where_it_can_be():
    maxwell = ctmm.Chain("maxwell", [Fixed("w"), Spring("k", 100.0), Damper("c", 5.0), Mass("m", 2.0), Free("e")])
    for method in ("rk4", "newmark"):                    # first-order node: its position is an initial value
        result = ctmm.simulate(maxwell, 0.1, 0.01, method=method, x0={"m": 0.1, "k": 0.05})
        assert result.states[0, 1, 0] == 0.05
        assert result.velocity[0, 1, 0] == pytest.approx(-100.0 * 0.05 / 5.0, rel=1e-12)   # c (0 - v) = k q
    pulled = ctmm.Chain("free", [Free("s"), Spring("k", 100.0), Mass("m", 1.0), Spring("k2", 50.0), Fixed("e")])
    with pytest.raises(ModelError, match=r"x0\['s'\] = 0.3: the point of 's' has no mass"):
        ctmm.simulate(pulled, 0.1, 0.01, method="rk4", x0={"s": 0.3})


@pytest.mark.parametrize("method", ["rk4", "newmark"])
def test_a_start_value_given_by_the_free_end_moves_the_mass_it_sits_on(method):
    """x0 / v0 by element name set a point (docs/verbs.md): the Free end behind a mass is that mass's point, so
    {"end": x} starts the mass at x (it was dropped: the run stayed at rest); two names of one point with different
    values are refused.  Reference: m x'' = -k x, x(t) = x0 cos(w t) + v0 / w sin(w t)."""
    k, m = 100.0, 1.0
    chain = ctmm.Chain("a", [Fixed("wall"), Spring("k1", k), Mass("m1", m), Free("end")])
    result = ctmm.simulate(chain, 0.2, 1e-3, method=method, x0={"end": 0.01}, v0={"end": 0.2})
    w = np.sqrt(k / m)
    exact = 0.01 * np.cos(w * result.time) + 0.2 / w * np.sin(w * result.time)
    assert np.max(np.abs(result["m1.x"] - exact)) < 1e-6          # Newmark at dt w = 0.01: 2.9e-7 m; RK4 3e-12
    with pytest.raises(ModelError, match=r"x0\['end'\] = 0.02 and x0\['m1'\] = 0.01 set one point"):
        ctmm.simulate(chain, 0.2, 1e-3, method=method, x0={"m1": 0.01, "end": 0.02})


@pytest.mark.parametrize("t_final, t0", [(0.3, 0.0), (0.35, 0.0), (0.35, 0.1)])
def test_solve_ivp_output_grid_is_k_dt_and_the_end(t_final, t0):
    """dt is the output grid of a solve_ivp run (docs/verbs.md): the times t0 + k dt and t_final itself.  A grid
    time beyond t_final by round-off (3 x 0.1 > 0.3) made scipy raise ValueError ('t_eval not within t_span'); a
    t_final off the grid lost the end of the run.  Reference: x0 cos(w t)."""
    chain = ctmm.Chain("a", [Fixed("wall"), Spring("k1", 100.0), Mass("m1", 1.0), Free("end")])
    result = ctmm.simulate(chain, t_final, 0.1, method="DOP853", x0={"m1": 0.01}, t0=t0, rtol=1e-10, atol=1e-12)
    grid = [t for t in (0.0, 0.1, 0.2, 0.3) if t >= t0 - 1e-12]
    expected = grid + ([t_final] if t_final != grid[-1] else [])
    np.testing.assert_allclose(result.time, expected, rtol=0, atol=1e-15)
    np.testing.assert_allclose(result["m1.x"], 0.01 * np.cos(10.0 * (result.time - t0)), rtol=0, atol=1e-10)
