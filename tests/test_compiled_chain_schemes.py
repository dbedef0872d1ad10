"""Generated DT-TMM schemes of plain 1-D chains (``ctmm.simulate(chain, method=<scheme>, compiled=True)``,
``ctmm/compiled_chain_schemes.py``).

Equal to the Python DT-TMM path to round-off (positions and velocities), and checked independently: a
textbook Newmark on the global ``M, C, K`` of ``reference/chain.py`` written here (same answer to round-off),
and every scheme's convergence order against the matrix exponential of the global equations.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.compiled_chain_scheme_runs import simulate_chain_scheme_generated
from ctmm.compiled_chain_schemes import CompiledChainScheme, SchemeMaps
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, PrescribedForce, Spring, SpringDamper
from ctmm.errors import ModelError
from ctmm.reference import chain as global_chain
from ctmm.reference.delay_chain import GlobalLoop, method_of_steps
from ctmm.schemes import Newmark, WilsonTheta
from ctmm.signals import Harmonic
from _chain_convert import inerter_chains, random_chain, to_global

pytest.importorskip("casadi")
SCHEMES = ("newmark", "generalized_alpha", "wilson_theta", "houbolt", "forward_euler")
ORDERS = {"newmark": 2, "generalized_alpha": 2, "wilson_theta": 2, "houbolt": 2, "forward_euler": 1}


def _chain():
    rng = np.random.default_rng(7)
    chain = random_chain(rng, 5, start="fixed", end="elastic", damped=True, grounded=True)
    names = [e.name for e in chain.body if isinstance(e, Mass)]
    return chain, names, dict(zip(names, rng.normal(scale=0.05, size=len(names))))


def _positions(result, names) -> np.ndarray:
    return np.column_stack([result[f"{n}.x"] for n in names])


@pytest.mark.parametrize("scheme", SCHEMES)
def test_each_generated_scheme_is_the_python_dttmm_step(scheme):
    chain, names, x0 = _chain()
    generated = ctmm.simulate(chain, 0.3, 1e-3, method=scheme, x0=x0, compiled=True)
    python = ctmm.simulate(chain, 0.3, 1e-3, method=scheme, x0=x0)
    scale = max(abs(v) for v in x0.values())
    assert np.max(np.abs(_positions(generated, names) - _positions(python, names))) < 1e-12 * scale
    velocity = np.column_stack([python[f"{n}.v"] for n in names])
    assert np.max(np.abs(np.column_stack([generated[f"{n}.v"] for n in names]) - velocity)) < \
        1e-11 * np.max(np.abs(velocity))
    assert generated.info["method"] == f"{scheme}-generated"


def test_a_loaded_chain_weights_its_loads_as_the_scheme_does():
    load = Harmonic(3.0, 40.0, 0.3)
    chain = ctmm.Chain("loaded", [Fixed("s"), SpringDamper("k0", 2e3, 1.0), Mass("m0", 1.0, force=load),
                                  SpringDamper("k1", 1e3, 0.5), Mass("m1", 0.5), Free("e")])
    for scheme in (WilsonTheta(1.4), "generalized_alpha"):          # w = theta (extrapolated), w = 1 - alpha_f
        generated = ctmm.simulate(chain, 0.2, 2e-3, method=scheme, compiled=True)
        python = ctmm.simulate(chain, 0.2, 2e-3, method=scheme)
        assert np.max(np.abs(_positions(generated, ["m0", "m1"]) - _positions(python, ["m0", "m1"]))) < 1e-15


@pytest.mark.parametrize("unrolled", [True, False])
def test_generated_newmark_is_a_global_textbook_newmark(unrolled):
    chain, names, x0 = _chain()
    M, C, K = global_chain.assemble(to_global(chain))
    h, beta, gamma, steps = 1e-3, 0.3, 0.6, 200
    x = np.array([x0[n] for n in names])
    v = np.zeros_like(x)
    a = np.linalg.solve(M, -K @ x - C @ v)
    effective = M + gamma * h * C + beta * h * h * K
    rows = [x.copy()]
    for _ in range(steps):
        x_pred = x + h * v + (0.5 - beta) * h * h * a
        v_pred = v + (1.0 - gamma) * h * a
        a = np.linalg.solve(effective, -K @ x_pred - C @ v_pred)
        x, v = x_pred + beta * h * h * a, v_pred + gamma * h * a
        rows.append(x.copy())
    kernel = CompiledChainScheme(chain, h, Newmark(beta, gamma), unrolled=unrolled)    # straight-line code or loops
    assert kernel.unrolled is unrolled
    generated = simulate_chain_scheme_generated(chain, steps * h, h, Newmark(beta, gamma), x0=x0, compiled=kernel)
    assert np.max(np.abs(_positions(generated, names) - np.array(rows))) < 1e-13 * np.max(np.abs(rows))


@pytest.mark.parametrize("scheme", SCHEMES)
def test_each_generated_scheme_converges_at_its_order_to_the_matrix_exponential(scheme):
    chain, names, x0 = _chain()
    reference = to_global(chain)
    start = np.array([x0[n] for n in names])
    errors = []
    for dt in (2e-3, 1e-3):
        result = ctmm.simulate(chain, 0.2, dt, method=scheme, x0=x0, compiled=True)
        exact = global_chain.exact_response(reference, result.time, start, np.zeros(len(names)),
                                            np.zeros(len(names))).displacement
        errors.append(float(np.max(np.abs(_positions(result, names) - exact))))
    order = np.log2(errors[0] / errors[1])
    assert abs(order - ORDERS[scheme]) < 0.3, (errors, order)


def test_an_inerter_chain_solves_its_coupled_step():
    masses = np.array([1.0, 2.0, 0.5])
    chain, _ = inerter_chains(masses, np.array([100.0, 200.0, 150.0, 80.0]), np.array([0.5, 0.2, 0.1, 0.3]),
                              np.array([0.0, 0.7, 0.0, 0.4]), end="fixed")
    x0 = {"m0": 0.01, "m2": -0.02}
    generated = ctmm.simulate(chain, 0.1, 1e-3, method="newmark", x0=x0, compiled=True)
    python = ctmm.simulate(chain, 0.1, 1e-3, method="newmark", x0=x0)
    names = ["m0", "m1", "m2"]
    assert np.max(np.abs(_positions(generated, names) - _positions(python, names))) < 1e-14


def test_scheme_maps_read_houbolt_start_up_and_refuse_nothing_linear():
    later, first = SchemeMaps(ctmm.schemes.Houbolt(), 1e-3, 2), SchemeMaps(ctmm.schemes.Houbolt(), 1e-3, 0)
    assert not np.array_equal(later.update, first.update)
    assert np.array_equal(first.update, SchemeMaps(Newmark(), 1e-3, 0).update)


def _controlled():
    chain, names, x0 = _chain()
    loops = [Feedback("rt", [(f"{names[-1]}.x", 1.0), (f"{names[-1]}.v", 0.05)], names[0], gain=80.0),
             Feedback("late", f"{names[2]}.v", names[1], gain=3.0, delay=0.004)]
    return ControlledChain(chain, loops), names, x0


@pytest.mark.parametrize("scheme", SCHEMES)
def test_realtime_and_delayed_loops_close_as_the_python_dttmm_step(scheme):
    system, names, x0 = _controlled()
    references = {"rt": Harmonic(0.01, 20.0)}
    generated = ctmm.simulate(system, 0.2, 1e-3, method=scheme, x0=x0, compiled=True, references=references)
    if scheme == "houbolt":                          # the loop form too: start-up branch, Woodbury, rings
        kernel = CompiledChainScheme(system, 1e-3, scheme, references=references, unrolled=False)
        assert kernel.unrolled is False
        generated = simulate_chain_scheme_generated(system, 0.2, 1e-3, scheme, x0=x0, references=references,
                                                    compiled=kernel)
    python = ctmm.simulate(system, 0.2, 1e-3, method=scheme, x0=x0, references=references)
    assert np.max(np.abs(_positions(generated, names) - _positions(python, names))) < 1e-12 * 0.05
    for name in ("rt.u", "late.u", "rt.y", "late.y"):
        assert np.max(np.abs(generated[name] - python[name])) < 1e-11 * np.max(np.abs(python[name])), name
    assert generated.info["loops"] == {"rt": "real-time", "late": "history"}


def test_generated_loops_converge_at_the_scheme_order_to_the_method_of_steps():
    chain, names, x0 = _chain()
    reference = to_global(chain)
    index = {name: k for k, name in enumerate(names)}
    loops = [Feedback("rt", f"{names[-1]}.x", names[0], gain=80.0),
             Feedback("late", f"{names[2]}.x", names[1], gain=30.0, delay=0.02)]
    system = ControlledChain(chain, loops)
    global_loops = [GlobalLoop(index[names[-1]], "displacement", index[names[0]], 80.0, 0.0),
                    GlobalLoop(index[names[2]], "displacement", index[names[1]], 30.0, 0.02)]
    start = np.array([x0[n] for n in names])
    exact = method_of_steps(reference, global_loops, 0.2, start, np.zeros(len(names)), rtol=1e-12, atol=1e-14)
    errors = []
    for dt in (2e-3, 1e-3):
        result = ctmm.simulate(system, 0.2, dt, method="newmark", x0=x0, compiled=True)
        errors.append(float(np.max(np.abs(_positions(result, names) - exact.evaluate(result.time).displacement))))
    order = np.log2(errors[0] / errors[1])
    assert abs(order - 2.0) < 0.3, (errors, order)


@pytest.mark.parametrize("scheme", ["newmark", "wilson_theta"])
def test_lti_controllers_advance_as_the_python_dttmm_step(scheme):
    control = pytest.importorskip("control")
    system, names, x0 = _controlled()
    loops = [Feedback("lag", [(f"{names[-1]}.x", 1.0), (f"{names[-1]}.v", 0.05)], names[0],
                      gain=control.tf([40.0, 200.0], [0.02, 1.0])),
             Feedback("late", f"{names[2]}.v", names[1], gain=control.tf([3.0], [0.01, 1.0]), delay=0.004)]
    system = system.with_loops(loops)
    references = {"lag": Harmonic(0.01, 20.0), "late": 0.02}
    generated = ctmm.simulate(system, 0.2, 1e-3, method=scheme, x0=x0, compiled=True, references=references)
    python = ctmm.simulate(system, 0.2, 1e-3, method=scheme, x0=x0, references=references)
    assert np.max(np.abs(_positions(generated, names) - _positions(python, names))) < 1e-12 * 0.05
    for name in ("lag.u", "late.u"):
        assert np.max(np.abs(generated[name] - python[name])) < 1e-11 * np.max(np.abs(python[name])), name


def test_what_the_generated_step_refuses():
    system, names, _ = _controlled()
    with pytest.raises(ModelError, match="unrolled must be True, False or None"):
        CompiledChainScheme(system, 1e-3, "newmark", unrolled="yes")
    with pytest.raises(ModelError, match="whole multiple"):
        ctmm.simulate(system, 0.012, 3e-3, method="newmark", compiled=True)
    saturated = system.with_loops([Feedback("s", f"{names[-1]}.x", names[0], gain=5.0, saturation=(-1.0, 1.0))])
    with pytest.raises(ModelError, match="saturates"):
        ctmm.simulate(saturated, 0.01, 1e-3, method="newmark", compiled=True)
    massless = ctmm.Chain("springs", [Fixed("s"), Spring("k0", 10.0), Spring("k1", 10.0), Mass("m", 1.0), Free("e")])
    with pytest.raises(ModelError, match="without inertia .* generated in the RK4"):       # (without loops:
        ctmm.simulate(ControlledChain(massless, [Feedback("l", "m.x", "m", gain=1.0)]), 0.01, 1e-3,
                      method="newmark", compiled=True)                # test_compiled_chain_scheme_nodes)
    with pytest.raises(ModelError, match="gamma"):                   # no stable step: refused before the run
        ctmm.simulate(system.plant, 0.01, 1e-3, method=Newmark(0.25, 0.4), compiled=True)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_a_harmonic_end_force_is_weighted_as_the_python_step_weights_it(scheme):
    chain = ctmm.Chain("end", [Fixed("s"), SpringDamper("k0", 2e3, 1.0), Mass("m0", 1.0, force=Harmonic(1.0, 25.0)),
                               SpringDamper("k1", 1e3, 0.5), Mass("m1", 0.5),
                               PrescribedForce("e", Harmonic(3.0, 40.0, 0.3))])
    generated = ctmm.simulate(chain, 0.2, 2e-3, method=scheme, compiled=True)
    python = ctmm.simulate(chain, 0.2, 2e-3, method=scheme)
    motion = _positions(python, ["m0", "m1"])
    assert generated.info["method"] == f"{scheme}-generated"
    assert np.max(np.abs(_positions(generated, ["m0", "m1"]) - motion)) < 1e-12 * np.max(np.abs(motion))


@pytest.mark.parametrize("scheme", ["generalized_alpha", "wilson_theta"])
def test_a_controlled_chain_weights_its_end_force_as_the_python_step(scheme):
    chain = ctmm.Chain("cend", [Fixed("s"), SpringDamper("k0", 2e3, 1.0), Mass("m0", 1.0),
                                SpringDamper("k1", 1e3, 0.5), Mass("m1", 0.5),
                                PrescribedForce("e", Harmonic(3.0, 40.0, 0.3))])
    system = ControlledChain(chain, [Feedback("rt", [("m1.x", 1.0), ("m1.v", 0.05)], "m0", gain=80.0)])
    generated = ctmm.simulate(system, 0.2, 2e-3, method=scheme, compiled=True)
    python = ctmm.simulate(system, 0.2, 2e-3, method=scheme)
    motion = _positions(python, ["m0", "m1"])
    assert generated.info["method"] == f"{scheme}-generated"
    assert np.max(np.abs(_positions(generated, ["m0", "m1"]) - motion)) < 1e-12 * np.max(np.abs(motion))
