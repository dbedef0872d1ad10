"""DT-TMM time stepping against exact (matrix-exponential) and global Newmark solutions."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.elements import Damper, Elastic, Fixed, Free, Mass, PrescribedDisplacement, Spring, SpringDamper
from ctmm.reference import chain as ref
from ctmm.schemes import ForwardEuler, GeneralizedAlpha, Houbolt, Newmark, WilsonTheta

from _chain_convert import random_chain, to_global


def table71_chain(force=100.0) -> ctmm.Chain:
    els = [Fixed("wall")]
    for i in range(5):
        els += [Spring(f"k{i + 1}", 1000.0, free_length=0.1), Mass(f"m{i + 1}", 0.1, force=force if i == 0 else 0.0)]
    return ctmm.Chain("table7_1", els + [Free("end")])


def exact_table71(t):
    """Reading A: absolute x_i(0) = 0.1 i (springs unstretched), 100 N on mass 1 from t = 0."""
    g = to_global(table71_chain())
    hist = ref.exact_response(g, np.atleast_1d(t), np.zeros(5), np.zeros(5), np.array([100.0, 0, 0, 0, 0]))
    return hist.displacement + 0.1 * np.arange(1, 6)


def final_error(scheme, dt, t_end=0.5):
    res = ctmm.simulate(table71_chain(), t_end, dt, scheme=scheme)
    x = np.array([res[f"m{i}.x"][-1] for i in range(1, 6)])
    return np.max(np.abs(x - exact_table71(t_end)[-1]))


@pytest.mark.parametrize("scheme, order", [
    (Newmark(), 2), (GeneralizedAlpha(0.8), 2), (GeneralizedAlpha(0.0), 2), (WilsonTheta(1.4), 2),
    (Houbolt(), 2), (ForwardEuler(), 1), (Newmark(beta=0.3, gamma=0.6), 1)])
def test_convergence_order(scheme, order):
    """Error at t = 0.5 s vs the exact solution on a dt ladder: observed slope = scheme order."""
    dts = [4e-4, 2e-4, 1e-4] if order == 2 else [8e-5, 4e-5, 2e-5]
    errors = [final_error(scheme, dt, t_end=0.5 if order == 2 else 0.1) for dt in dts]
    slopes = np.diff(np.log(errors)) / np.diff(np.log(dts))
    assert np.all(np.abs(slopes - order) < 0.15), (errors, slopes)


def test_newmark_equals_global_newmark_to_round_off():
    """Average-acceleration DT-TMM is algebraically global Newmark (FORMULAS §3.2)."""
    chain = random_chain(np.random.default_rng(1), 10, start="fixed", end="elastic", damped=True, grounded=True)
    g = to_global(chain)
    rng = np.random.default_rng(2)
    x0 = rng.normal(0, 0.01, 10)
    masses = [e.name for e in chain.body if isinstance(e, Mass)]
    res = ctmm.simulate(chain, 0.2, 1e-3, x0=dict(zip(masses, x0)))
    glob = ref.newmark_global(g, 0.2, 1e-3, x0, np.zeros(10))
    tmm = np.column_stack([res[f"{m}.x"] for m in masses])
    assert np.max(np.abs(tmm - glob.displacement)) < 1e-13


def test_fast_and_generic_paths_agree():
    chain = random_chain(np.random.default_rng(3), 8, start="elastic", end="fixed", damped=True)
    masses = [e.name for e in chain.body if isinstance(e, Mass)]
    x0 = {m: 0.01 * (i + 1) for i, m in enumerate(masses)}
    for scheme in ("newmark", "houbolt", "wilson_theta", "generalized_alpha", "forward_euler"):
        a = ctmm.simulate(chain, 0.05, 1e-3, scheme=scheme, x0=x0, fast=True)
        b = ctmm.simulate(chain, 0.05, 1e-3, scheme=scheme, x0=x0, fast=False)
        np.testing.assert_allclose(a.states[:, :, 0], b.states[:, :, 0], atol=1e-13)
        np.testing.assert_allclose(a.velocity, b.velocity, atol=1e-10)


def test_newmark_conserves_energy_over_1e5_steps():
    """Undamped average-acceleration Newmark conserves 1/2 v'Mv + 1/2 u'Ku up to round-off.

    In exact arithmetic the discrete energy is invariant; in floating point each step adds
    O(eps) relative error, so after N steps the drift is bounded by N eps (= 2.2e-11 for
    N = 1e5), which is asserted.  The chain is written in displacement coordinates (free
    lengths 0) so that no absolute-position representation error enters.  Before the
    predictor / incremental-force form of the DT-TMM step (ctmm/schemes.py,
    ctmm/timestep.py) the drift was 2e-9, i.e. 100 N eps: that form lost eps |x| / h per step.
    """
    els = [Fixed("wall")]
    for i in range(5):
        els += [Spring(f"k{i + 1}", 1000.0), Mass(f"m{i + 1}", 0.1)]
    chain = ctmm.Chain("energy", els + [Free("end")])
    x0 = {f"m{i}": 0.01 * (-1) ** i * i for i in range(1, 6)}
    n_steps, dt = 100_000, 1e-4
    res = ctmm.simulate(chain, n_steps * dt, dt, x0=x0)
    M, _, K = ref.assemble(to_global(chain))
    u = np.column_stack([res[f"m{i}.x"] for i in range(1, 6)])
    v = np.column_stack([res[f"m{i}.v"] for i in range(1, 6)])
    energy = 0.5 * np.einsum("ti,ij,tj->t", v, M, v) + 0.5 * np.einsum("ti,ij,tj->t", u, K, u)
    assert len(res.time) == n_steps + 1
    drift = np.max(np.abs(energy - energy[0])) / energy[0]
    assert drift < n_steps * np.finfo(float).eps, drift


def test_harmonic_force_and_damper_against_solve_ivp():
    from ctmm.signals import Harmonic

    els = [Fixed("w"), SpringDamper("k1", 400.0, 0.8), Mass("m1", 1.0, force=Harmonic(5.0, 7.0)),
           Damper("c2", 1.5), Mass("m2", 0.5), Spring("k3", 300.0), Free("e")]
    chain = ctmm.Chain("mixed", els)
    res = ctmm.simulate(chain, 1.0, 5e-4)
    M = np.diag([1.0, 0.5])
    C = np.array([[0.8 + 1.5, -1.5], [-1.5, 1.5]])
    K = np.array([[400.0, 0], [0, 0.0]])
    from scipy.integrate import solve_ivp

    def rhs(t, y):
        f = np.array([5.0 * np.sin(7.0 * t), 0.0])
        return np.concatenate([y[2:], np.linalg.solve(M, f - C @ y[2:] - K @ y[:2])])

    sol = solve_ivp(rhs, (0, 1.0), np.zeros(4), rtol=1e-12, atol=1e-14, t_eval=res.time, method="DOP853")
    assert np.max(np.abs(res["m1.x"] - sol.y[0])) < 2e-5
    assert np.max(np.abs(res["m2.x"] - sol.y[1])) < 2e-5


def test_prescribed_base_motion():
    from ctmm.signals import Harmonic

    chain = ctmm.Chain("base", [PrescribedDisplacement("base", Harmonic(0.01, 3.0)), Spring("k", 900.0),
                                Mass("m", 1.0), Free("e")])
    res = ctmm.simulate(chain, 2.0, 1e-3)
    t = res.time
    w, wn = 3.0, 30.0
    # x'' + wn^2 x = wn^2 X sin(w t), x(0) = x'(0) = 0
    exact = 0.01 * wn ** 2 / (wn ** 2 - w ** 2) * (np.sin(w * t) - w / wn * np.sin(wn * t))
    assert np.max(np.abs(res["m.x"] - exact)) < 1e-5


def test_result_object(tmp_path):
    res = ctmm.simulate(table71_chain(), 0.01, 1e-3)
    assert res["m1.x"].shape == (11,)
    assert np.allclose(res["m1.v"][0], 0.0)
    np.testing.assert_allclose(res["m1.a"][0], 100.0 / 0.1)  # initial acceleration from F/m
    assert "k3.f" in res.signals()
    fig = res.plot("m1.x", "m5.x")
    fig.savefig(tmp_path / "t.png")
    with pytest.raises(ctmm.UnknownNameError, match="available"):
        res["nope.x"]


def test_non_finite_step_stops_with_time_and_element():
    def bad_force(t):
        return np.nan if t > 0.0045 else 0.0

    chain = ctmm.Chain("bad", [Fixed("w"), Spring("k", 10.0), Mass("m", 1.0, force=bad_force), Free("e")])
    with pytest.raises(ctmm.SimulationError, match=r"'m: force' returned a non-finite value \[nan\] at t = 0.005") \
            as info:
        ctmm.simulate(chain, 0.01, 1e-3)
    assert info.value.time == pytest.approx(0.005)
    assert "'m: force'" in info.value.element          # the user function is named, not a neighbour
    assert len(info.value.partial_result.time) == 5
