"""The hard cases that motivate Riccati transfer (FORMULAS §4.1), kept as regression tests."""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla

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


def uniform_dynamic_stiffness_band(n: int, omega: float, *, mass: float = 0.1, stiffness: float = 1000.0,
                                   damping: float = 0.0) -> np.ndarray:
    """``K - omega^2 M + i omega C`` [N/m] of wall - k - m - ... - k - m - free in ``solve_banded((1, 1))`` form,
    written from the global equations (connector impedance ``z = k + i omega c`` on both sides of every mass
    but the last)."""
    z = stiffness + 1j * omega * damping
    band = np.zeros((3, n), dtype=complex)
    band[0, 1:] = band[2, :-1] = -z
    band[1, :] = 2.0 * z - omega ** 2 * mass
    band[1, -1] = z - omega ** 2 * mass
    return band


def test_frf_10000_masses_matches_banded_solve():
    """Reference: one banded global solve per frequency (O(n), no dense n x n assembly) for all three outputs."""
    n = 10_000
    chain = uniform_chain(n, damping=0.05)
    omega = np.array([1.0, 50.0, 150.0, 199.0])
    outputs = [0, 9999, 5000]
    frf = ctmm.frequency_response(chain, omega, input="m0.force", output=[f"m{i}.x" for i in outputs])
    unit = np.zeros(n, dtype=complex)
    unit[0] = 1.0
    displacement = np.array([sla.solve_banded((1, 1), uniform_dynamic_stiffness_band(n, w, damping=0.05), unit)
                             for w in omega])
    for j, out in enumerate(outputs):
        exact = displacement[:, out]
        assert np.all(np.isfinite(frf.response[j, 0]))
        tiny = np.abs(exact) < 1e-250  # far-end response underflows in both solvers above the band
        np.testing.assert_allclose(frf.response[j, 0][~tiny], exact[~tiny], rtol=1e-8)


def test_uniform_band_is_the_assembled_global_band():
    """The band written from the global equations above equals the reference assembly of the same chain."""
    chain = uniform_chain(7, damping=0.05)
    Mb, Cb, Kb = ref.assemble_banded(to_global(chain))
    for w in (0.0, 3.0, 250.0):
        expected = Kb - w ** 2 * Mb + 1j * w * Cb
        expected[0, 0] = expected[2, -1] = 0.0                 # unused corners of the banded layout
        np.testing.assert_allclose(uniform_dynamic_stiffness_band(7, w, damping=0.05), expected, rtol=1e-15,
                                   atol=0.0)


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
