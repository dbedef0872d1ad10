"""The hard cases that motivate Riccati transfer (FORMULAS §4.1), kept as regression tests."""
from __future__ import annotations

import numpy as np

import ctmm
from ctmm.elements import Fixed, Free, Mass, Spring, SpringDamper
from ctmm.reference import chain as ref

from _chain_convert import to_global


def uniform_chain(n: int, *, damping: float = 0.0) -> ctmm.Chain:
    els = [Fixed("wall")]
    for i in range(n):
        els += [SpringDamper(f"k{i}", 1000.0, damping) if damping else Spring(f"k{i}", 1000.0),
                Mass(f"m{i}", 0.1, force=100.0 if i == 0 else 0.0)]
    return ctmm.Chain(f"uniform{n}", els + [Free("end")])


def test_dt_tmm_step_riccati_exact_where_plain_product_fails():
    """20 masses, h = 1e-4: (m C / K)^n ~ 1e92.  Riccati = global Newmark to round-off; plain is off."""
    n, h = 20, 1e-4
    chain = uniform_chain(n)
    rng = np.random.default_rng(0)
    u0 = rng.normal(0.0, 1e-3, n)
    x0 = {f"m{i}": u0[i] for i in range(n)}
    glob = ref.newmark_global(to_global(chain), h, h, u0, np.zeros(n),
                              force_fn=lambda t: np.r_[100.0, np.zeros(n - 1)])
    exact = glob.displacement[-1]
    masses = [f"m{i}.x" for i in range(n)]
    riccati = ctmm.simulate(chain, h, h, x0=x0, fast=False, solver="riccati")
    plain = ctmm.simulate(chain, h, h, x0=x0, fast=False, solver="plain", divergence_bound=np.inf)  # shown, not stopped
    fast = ctmm.simulate(chain, h, h, x0=x0)
    err_riccati = max(abs(riccati[m][-1] - e) for m, e in zip(masses, exact))
    err_fast = max(abs(fast[m][-1] - e) for m, e in zip(masses, exact))
    err_plain = max(abs(plain[m][-1] - e) if np.isfinite(plain[m][-1]) else np.inf for m, e in zip(masses, exact))
    assert err_riccati <= 1e-12 * np.max(np.abs(exact)) + 1e-17
    assert err_fast <= 1e-12 * np.max(np.abs(exact)) + 1e-17
    assert err_plain > 1e6 * max(err_riccati, 1e-20)


def test_frf_10000_masses_matches_banded_solve():
    n = 10_000
    chain = uniform_chain(n, damping=0.05)
    omega = np.array([1.0, 50.0, 150.0, 199.0])
    frf = ctmm.frequency_response(chain, omega, input="m0.force", output=["m0.x", "m9999.x", "m5000.x"])
    g = to_global(chain)
    for j, out in enumerate([0, 9999, 5000]):
        exact = ref.frequency_response_banded(g, omega, 0, out)
        assert np.all(np.isfinite(frf.response[j, 0]))
        tiny = np.abs(exact) < 1e-250  # far-end response underflows in both solvers above the band
        np.testing.assert_allclose(frf.response[j, 0][~tiny], exact[~tiny], rtol=1e-8)


def test_plain_product_fails_at_high_frequency_long_chain():
    """Plain products overflow/cancel for a long chain above its band; Riccati stays exact."""
    chain = uniform_chain(400, damping=0.05)
    omega = np.array([300.0])  # above the highest natural frequency 2 sqrt(k/m) = 200 rad/s
    g = to_global(chain)
    exact = ref.frequency_response_banded(g, omega, 0, 3)
    ric = ctmm.frequency_response(chain, omega, input="m0.force", output="m3.x")("m3.x", "m0.force")
    np.testing.assert_allclose(ric, exact, rtol=1e-10)
    try:
        plain = ctmm.frequency_response(chain, omega, input="m0.force", output="m3.x",
                                        solver="plain")("m3.x", "m0.force")
        plain_error = np.abs(plain - exact) / np.abs(exact)
        assert not np.all(plain_error < 1e-6)
    except ctmm.SingularSystemError:
        pass  # the plain end matrix overflowed to a singular/non-finite value: also a failure
