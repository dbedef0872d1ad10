"""Stability charts: D-curves against closed forms, classification against independent delay equations.

References: the delayed PD oscillator's closed-form D-curves (FORMULAS 6.2) and characteristic
function, Hayes' region of x' = a x + b x(t - tau), and, for the seed chain, the determinant of
s^2 M + s C + K + G e^{-s tau} and Chebyshev collocation of the same equations -- all assembled
from M, C, K by ``ctmm.reference`` without transfer matrices.
"""
from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor

import matplotlib
import numpy as np
import pytest

from ctmm.control import Feedback
from ctmm.errors import ModelError, UnknownNameError
from ctmm.reference.dde import (delayed_pd_oscillator_characteristic_function,
                                delayed_pd_oscillator_dcurves, hayes_is_stable)
from ctmm.stability_chart import stability_chart
from test_stability import collocation_roots, oscillator, scalar, seed_chain, seed_matrices

matplotlib.use("Agg")


def finite_points(boundary):
    ok = np.isfinite(boundary.x) & np.isfinite(boundary.y)
    return boundary.x[ok], boundary.y[ok], boundary.omega[ok]


# ------------------------------------------------------------------------------ D-curves
def test_pd_oscillator_dcurves_equal_closed_form():
    omega_n, zeta, tau = 1.0, 0.1, 0.5
    chart = stability_chart(oscillator(omega_n, zeta, delay=tau), x=("m.x", np.linspace(-2, 4, 41)),
                            y=("m.v", np.linspace(-1, 3, 41)), verify=True)
    kinds = sorted(b.kind for b in chart.boundaries)
    assert kinds == ["oscillatory", "static"]
    n_points = 0
    for b in chart.boundaries:
        kp, kd, omega = finite_points(b)
        if b.kind == "static":
            np.testing.assert_allclose(kp, -omega_n ** 2, rtol=1e-12)      # the line k_p = -omega_n^2
            continue
        exact = delayed_pd_oscillator_dcurves(omega_n, zeta, tau, omega)
        assert np.max(np.abs(kp - exact.proportional_gain) / np.maximum(1, np.abs(kp))) <= 1e-8
        assert np.max(np.abs(kd - exact.derivative_gain) / np.maximum(1, np.abs(kd))) <= 1e-8
        n_points += kp.size
    assert n_points > 50
    assert chart.verified
    # stable inside the D-curve lobe right of the static line (Stepan's chart): kp = 0.5, kd = 1
    assert chart.stable[np.argmin(abs(chart.y - 1.0)), np.argmin(abs(chart.x - 0.5))]
    assert not chart.stable[np.argmin(abs(chart.y - 1.0)), np.argmin(abs(chart.x + 1.5))]


def test_pd_oscillator_delay_chart_points_are_roots():
    """kp x tau chart (kd fixed): every D-curve point makes the independent Delta vanish at i Omega."""
    omega_n, zeta, kd = 1.0, 0.05, 0.4
    chart = stability_chart(oscillator(omega_n, zeta, kd=kd), x=("m.x", np.linspace(-1.5, 3, 46)),
                            y=("delay", np.linspace(0, 6, 61)), verify=True)
    assert chart.verified
    worst = 0.0
    for b in chart.boundaries:
        kp, tau, omega = finite_points(b)
        for p, t, w in zip(kp, tau, omega):
            delta = delayed_pd_oscillator_characteristic_function(omega_n, zeta, t, p, kd)
            s = 1j * w
            scale = abs(s * s) + 2 * zeta * omega_n * abs(s) + omega_n ** 2 + abs(p) + kd * abs(s)
            worst = max(worst, abs(delta(np.array([s]))[0]) / scale)
    assert worst <= 1e-10


def test_scalar_chart_equals_hayes_region():
    c, k = 1.0, 0.5
    gains = np.linspace(-3.0, 4.0, 36)
    taus = np.linspace(0.0, 3.0, 31)
    chart = stability_chart(scalar(c, k), x=("gain", gains), y=("delay", taus))
    a = -k / c
    for iy, tau in enumerate(taus[1:], start=1):
        for ix, g in enumerate(gains):
            if chart.unstable_roots[iy, ix] >= 0:
                assert (chart.unstable_roots[iy, ix] == 0) == hayes_is_stable(a, -g / c, tau), (g, tau)
    # D-curve points solve i Omega = a + b e^{-i Omega tau}, b = -g/c
    for b in chart.boundaries:
        g, tau, omega = finite_points(b)
        residual = 1j * omega - a + (g / c) * np.exp(-1j * omega * tau)
        assert np.max(np.abs(residual) / (abs(a) + np.abs(g) / c + omega)) <= 1e-10


# ------------------------------------------------------------------------------ the seed chain
@pytest.fixture(scope="module")
def seed_chart():
    gains = np.linspace(-40.0, 80.0, 25)
    taus = np.linspace(0.0, 0.4, 21)
    return stability_chart(seed_chain(), x=("gain", gains, "K_a [N/m]"), y=("delay", taus, "tau [s]"),
                           verify=True)


def test_seed_chain_chart_equals_collocation(seed_chart):
    """Stable set of the TMM chart = stable set of the delay equations assembled from M, C, K."""
    M, C, K = seed_matrices()
    chart = seed_chart
    assert chart.verified
    compared = 0
    for iy in range(1, chart.y.size, 2):                  # every other point of the chart
        for ix in range(0, chart.x.size, 2):
            tau, gain = chart.y[iy], chart.x[ix]
            if chart.unstable_roots[iy, ix] < 0:
                continue
            G = np.zeros((3, 3))
            G[0, 2] = gain
            roots = collocation_roots(M, C, K, G, np.zeros((3, 3)), tau, nodes=24, keep=12)
            rightmost = roots.real.max()
            if abs(rightmost) < 1e-6:
                continue
            assert chart.unstable_roots[iy, ix] == int(np.sum(roots.real > 0)), (gain, tau)
            compared += 1
    assert compared > 100


def test_seed_chain_boundaries_solve_the_global_equations(seed_chart):
    from ctmm.reference.delay_chain import GlobalLoop, closed_loop_dynamic_stiffness
    from ctmm.reference.chain import GlobalChain

    chain = GlobalChain([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0],
                        start="fixed", end="free")
    worst, n = 0.0, 0
    for b in seed_chart.boundaries:
        gains, taus, omegas = finite_points(b)
        for g, t, w in zip(gains[::3], taus[::3], omegas[::3]):
            D = closed_loop_dynamic_stiffness(chain, [GlobalLoop(2, "displacement", 0, g, t)], 1j * w)
            sv = np.linalg.svd(D, compute_uv=False)
            worst = max(worst, sv[-1] / sv[0])
            n += 1
    assert n > 20 and worst <= 1e-9


def test_chart_summary_and_plot(seed_chart, tmp_path):
    summary = seed_chart.summary()
    json.dumps(summary)
    assert summary["x"]["name"] == "gain" and 0 < summary["stable_fraction"] < 1
    ax = seed_chart.plot()
    assert ax.get_xlabel() == "K_a [N/m]"
    ax.figure.savefig(tmp_path / "chart.png")
    with pytest.raises(ModelError, match="no spectral abscissa"):
        seed_chart.plot(abscissa=True)


def test_abscissa_levels_bracket_the_rightmost_root():
    levels = np.linspace(-1.0, 1.0, 21)
    gains, taus = np.array([5.0, 40.0, 70.0]), np.array([0.05, 0.2])
    chart = stability_chart(seed_chain(), x=("gain", gains), y=("delay", taus), abscissa_levels=levels)
    M, C, K = seed_matrices()
    for iy, tau in enumerate(taus):
        for ix, gain in enumerate(gains):
            G = np.zeros((3, 3))
            G[0, 2] = gain
            alpha = collocation_roots(M, C, K, G, np.zeros((3, 3)), tau, nodes=24).real.max()
            assert abs(chart.abscissa[iy, ix] - np.clip(alpha, -1.0, 1.0)) <= 0.05 + 1e-9
    chart.plot(abscissa=True)


# ------------------------------------------------------------------------------ sweeps
def test_executors_and_functions_give_the_same_chart(seed_chart):
    gains, taus = seed_chart.x[::3], seed_chart.y[::2]
    reference = stability_chart(seed_chain(), x=("gain", gains), y=("delay", taus))
    with ThreadPoolExecutor(max_workers=2) as pool:
        threaded = stability_chart(seed_chain(), x=("gain", gains), y=("delay", taus), executor=pool)
    processes = stability_chart(seed_chain(), x=("gain", gains), y=("delay", taus), executor="processes")
    assert np.array_equal(threaded.unstable_roots, reference.unstable_roots)
    assert np.array_equal(processes.unstable_roots, reference.unstable_roots)
    system = seed_chain()

    def make(gain, delay):
        return system.with_loops([Feedback("ka", "m2.x", "m0", gain=gain, delay=delay)])

    from_function = stability_chart(make, x=("K_a", gains), y=("tau", taus))
    assert from_function.method.startswith("points (batched")
    assert np.array_equal(from_function.unstable_roots, reference.unstable_roots)


def test_dask_distributed_executor():
    distributed = pytest.importorskip("distributed")
    gains, taus = np.linspace(-40.0, 80.0, 9), np.linspace(0.0, 0.4, 7)
    reference = stability_chart(seed_chain(), x=("gain", gains), y=("delay", taus))
    with distributed.LocalCluster(n_workers=2, processes=False, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        chart = stability_chart(seed_chain(), x=("gain", gains), y=("delay", taus),
                                executor=client.get_executor())
    assert np.array_equal(chart.unstable_roots, reference.unstable_roots)


def test_general_function_without_shared_structure():
    """Systems that differ in more than one loop's parameters are counted one by one."""
    base = seed_chain()

    def make(stiffness_scale, delay):
        import ctmm
        from ctmm.control import ControlledChain
        from ctmm.elements import Fixed, Free, Mass, SpringDamper

        plant = ctmm.Chain("seed", [Fixed("wall"), SpringDamper("k1", 100.0 * stiffness_scale, 0.5),
                                    Mass("m0", 1.0), SpringDamper("k3", 80.0, 0.3), Mass("m1", 1.5),
                                    SpringDamper("k5", 120.0, 0.4), Mass("m2", 2.0), Free("end")])
        return ControlledChain(plant, [Feedback("ka", "m2.x", "m0", gain=40.0, delay=delay)])

    chart = stability_chart(make, x=("scale", [0.5, 1.0]), y=("tau", [0.05, 0.3]))
    assert chart.method.startswith("points (one count")
    expected = stability_chart(base, x=("gain", [40.0, 41.0]), y=("delay", [0.05, 0.3])).unstable_roots[:, 0]
    assert np.array_equal(chart.unstable_roots[:, 1], expected)


# ------------------------------------------------------------------------------ bad input
def test_bad_grids_and_names():
    system = seed_chain()
    taus = np.linspace(0, 0.3, 5)
    with pytest.raises(ModelError, match="grid 'gain' must be finite, got nan at index 2"):
        stability_chart(system, x=("gain", [1.0, 2.0, np.nan]), y=("delay", taus))
    with pytest.raises(ModelError, match="delays must be >= 0"):
        stability_chart(system, x=("gain", [1.0, 2.0]), y=("delay", [-0.1, 0.2]))
    with pytest.raises(UnknownNameError, match="unknown loop 'motor'; available: ka"):
        stability_chart(system, x=("gain", [1.0, 2.0]), y=("delay", taus), loop="motor")
    with pytest.raises(UnknownNameError, match="parameter of loop 'ka' 'kd'; available: delay, gain, m2.x"):
        stability_chart(system, x=("gain", [1.0, 2.0]), y=("kd", taus))
    with pytest.raises(ModelError, match="different parameters"):
        stability_chart(system, x=("gain", [1.0, 2.0]), y=("gain", [1.0, 3.0]))
    with pytest.raises(ModelError, match="at least 2 values"):
        stability_chart(system, x=("gain", [1.0]), y=("delay", taus))
    with pytest.raises(ModelError, match="executor must be"):
        stability_chart(system, x=("gain", [1.0, 2.0]), y=("delay", taus), executor="gpu")


def test_no_loop_or_no_delay():
    with pytest.raises(ModelError, match="plain Chain with no loop"):
        stability_chart(seed_chain().plant, x=("gain", [1.0, 2.0]), y=("delay", [0.0, 0.1]))
    chart = stability_chart(seed_chain(delay=0.0), x=("gain", np.linspace(-40, 80, 13)),
                            y=("m2.x", np.linspace(0.5, 2.0, 4)))
    assert any("no delay" in note for note in chart.notes)
    # without delay the loop K_a * w is stable in a gain interval that contains the open loop
    assert chart.stable[:, np.argmin(abs(chart.x))].all()
