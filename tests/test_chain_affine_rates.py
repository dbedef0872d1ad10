"""The affine explicit rates of lumped chains (``ctmm/chain_affine.py``) and the row-batched point forces
(``ctmm/chain_point_rows.py``) behind the fast ODE path of chains.

Independent references: the global ``M, C, K`` of ``reference/chain.py`` and ``reference/inerter_chain.py``
(assembled from the element parameters only), and closed-form boundary forces.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.chain_affine import linear_rates
from ctmm.chain_ode import ChainDynamics
from ctmm.elements import Fixed, Free, Mass, PrescribedForce, SpringDamper
from ctmm.elements.nonlinear_connector import NonlinearSpring
from ctmm.reference import chain as global_chain
from ctmm.reference import inerter_chain
from ctmm.nonlinear_laws import CubicSpring
from ctmm.signals import Harmonic
from _chain_convert import inerter_chains, random_chain, to_global


@pytest.mark.parametrize("start, end", [("fixed", "fixed"), ("free", "elastic"), ("elastic", "free")])
def test_banded_rates_are_the_global_matrices(start, end):
    rng = np.random.default_rng(3)
    chain = random_chain(rng, 6, start=start, end=end, damped=True, grounded=True)
    M, C, K = global_chain.assemble(to_global(chain))
    form = ChainDynamics(chain).linear
    assert form is not None
    stiffness = form.stiffness.toarray()
    m = M.shape[0]
    scale = np.max(np.abs(K)) / np.min(np.diag(M))
    assert np.max(np.abs(stiffness[:, :m] + np.linalg.solve(M, K))) <= 1e-12 * scale
    assert np.max(np.abs(stiffness[:, m:] + np.linalg.solve(M, C))) <= 1e-12 * scale


def test_inerter_chain_reads_the_coupled_rates_column_by_column():
    masses = np.array([1.0, 2.0, 0.5])
    chain, reference = inerter_chains(masses, np.array([100.0, 200.0, 150.0, 80.0]), np.array([0.5, 0.2, 0.1, 0.3]),
                                      np.array([0.0, 0.7, 0.0, 0.4]), end="fixed")
    M, C, K = inerter_chain.assemble(reference)
    form = ChainDynamics(chain).linear
    assert form is not None and isinstance(form.stiffness, np.ndarray)      # dense: M couples every node
    assert np.allclose(form.stiffness[:, :3], -np.linalg.solve(M, K), rtol=0, atol=1e-10 * np.max(np.abs(K)))
    assert np.allclose(form.stiffness[:, 3:], -np.linalg.solve(M, C), rtol=0, atol=1e-10 * np.max(np.abs(K)))


def test_a_nonlinear_connector_keeps_the_sweep():
    chain = ctmm.Chain("nl", [Fixed("s"), NonlinearSpring("k", CubicSpring(100.0, 5.0e3)), Mass("m", 1.0),
                              Free("e")])
    dynamics = ChainDynamics(chain)
    assert linear_rates(dynamics) is None and dynamics.linear is None
    y = np.array([0.3, 0.1])
    assert np.allclose(dynamics.rate(0.0, y), dynamics.swept_rate(0.0, y))


def test_loads_and_actuator_inputs_are_columns_of_the_inverse_mass():
    load = Harmonic(2.0, 5.0)
    chain = ctmm.Chain("driven", [Fixed("s"), SpringDamper("k0", 100.0, 0.2), Mass("m0", 2.0, force=load),
                                  SpringDamper("k1", 50.0, 0.1), Mass("m1", 0.5), Free("e")])
    form = ChainDynamics(chain).linear
    x, v, t = np.array([0.01, -0.02]), np.array([0.1, 0.0]), 0.37
    extra = {4: {"force": 3.0}}                       # a force on m1
    K = np.array([[150.0, -50.0], [-50.0, 50.0]])
    C = np.array([[0.3, -0.1], [-0.1, 0.1]])
    f = np.array([load(t), 3.0])
    expected = (f - K @ x - C @ v) / np.array([2.0, 0.5])
    assert np.allclose(form.accelerations(t, x, v, extra), expected, rtol=1e-13, atol=1e-13)


def test_a_time_varying_end_force_is_the_point_force_at_every_row():
    force = Harmonic(4.0, 7.0)
    chain = ctmm.Chain("pulled", [Fixed("s"), SpringDamper("k", 400.0, 1.0), Mass("m", 1.0), PrescribedForce("e", force)])
    result = ctmm.simulate(chain, 0.5, 1e-3, method="rk4")
    # the end's point force is the applied force at each stored time (sign of the end boundary, as the DT-TMM path)
    newmark = ctmm.simulate(chain, 0.5, 1e-3, method="newmark")
    assert np.allclose(result["e.f"], newmark["e.f"], rtol=0, atol=1e-12)
    assert np.allclose(result["e.f"], -4.0 * np.sin(7.0 * result.time), rtol=0, atol=1e-12)   # the end's sign


def test_fast_rk4_meets_the_matrix_exponential_at_many_masses():
    rng = np.random.default_rng(5)
    chain = random_chain(rng, 40, start="fixed", end="free", damped=True)
    reference = to_global(chain)
    names = [e.name for e in chain.body if isinstance(e, Mass)]
    x0 = rng.normal(scale=0.01, size=len(names))
    times = np.linspace(0.0, 0.05, 51)
    exact = global_chain.exact_response(reference, times, x0, np.zeros(len(names)), np.zeros(len(names))).displacement
    result = ctmm.simulate(chain, 0.05, 1e-3, method="rk4", x0=dict(zip(names, x0)))
    error = max(float(np.max(np.abs(result[f"{n}.x"] - exact[:, i]))) for i, n in enumerate(names))
    assert error < 1e-3 * np.max(np.abs(x0))


def test_stored_accelerations_and_forces_of_a_controlled_run_obey_the_global_equations():
    from ctmm.control import ControlledChain, Feedback

    load = Harmonic(2.0, 5.0)
    chain = ctmm.Chain("driven", [Fixed("s"), SpringDamper("k0", 100.0, 0.2), Mass("m0", 2.0, force=load),
                                  SpringDamper("k1", 50.0, 0.1), Mass("m1", 0.5), Free("e")])
    system = ControlledChain(chain, [Feedback("pd", [("m0.x", 30.0), ("m0.v", 2.0)], "m1", gain=1.0)])
    result = ctmm.simulate(system, 0.3, 1e-3, method="rk4", x0={"m0": 0.05})
    x = np.column_stack([result["m0.x"], result["m1.x"]])
    v = np.column_stack([result["m0.v"], result["m1.v"]])
    K = np.array([[150.0, -50.0], [-50.0, 50.0]])
    C = np.array([[0.3, -0.1], [-0.1, 0.1]])
    f = np.column_stack([2.0 * np.sin(5.0 * result.time), result["pd.u"]])
    expected = (f - x @ K.T - v @ C.T) / np.array([2.0, 0.5])
    assert np.allclose(np.column_stack([result["m0.a"], result["m1.a"]]), expected, rtol=1e-12, atol=1e-12)
    # the spring-damper k1 carries -k dx - c dv at both of its points
    assert np.allclose(result["k1.f"], -50.0 * (x[:, 1] - x[:, 0]) - 0.1 * (v[:, 1] - v[:, 0]), rtol=1e-12,
                       atol=1e-12)


@pytest.mark.parametrize("method", ["rk4", "RK45"])
@pytest.mark.parametrize("t0", [0.0, 5.0])
def test_a_load_function_is_called_only_inside_the_run(method, t0):
    """The affine rates are certified at the run's start: a user's load defined on the run's interval alone
    (a table, an interpolant that raises outside its data) is never called outside ``[t0, t_final]``.  They
    were certified at random times in [0, 3) s, which failed a 0.1 s run with "raised ... at t = 0.54 s"."""
    calls: list[float] = []

    def force(t: float) -> float:
        if t == 0.0 and not calls:         # the construction's probe f(0.0) (ctmm.signals.as_signal)
            calls.append(float("nan"))
            return 1.0
        calls.append(float(t))
        if not t0 - 1e-9 <= t <= t0 + 0.1 + 1e-9:     # the run's interval (with the steps' round-off)
            raise ValueError(f"outside the data: t = {t}")
        return 1.0

    chain = ctmm.Chain("c", [Fixed("g"), SpringDamper("k", 100.0, 0.0), Mass("m", 1.0, force=force), Free("f")])
    run = ctmm.simulate(chain, t0 + 0.1, 1e-3, method=method, t0=t0, compiled=False)
    assert min(calls[1:]) >= t0 - 1e-9 and max(calls[1:]) <= t0 + 0.1 + 1e-9
    exact = (1.0 - np.cos(10.0 * (run.time - t0))) / 100.0      # m x'' + k x = 1 from rest: (1 - cos w t) / k
    assert np.max(np.abs(run["m.x"] - exact)) < 1e-7
