"""Certified delay-stability counts (issue 11): no default may miss a root.

Independent reference (no TMM code): the global matrices of ``ctmm.reference.chain`` and the
exact crossing method for one delay (Walton & Marshall 1987; Cooke & van den Driessche 1986).
With ``D0(s) = s^2 M + s C + K`` and a loop ``u = -g s^p c^T x e^{-s tau}`` on ``b``,

    Delta(s) = P(s) + Q(s) e^{-s tau},   P = det D0,   Q = g (det(D0 + s^p b c^T) - det D0)

(matrix determinant lemma).  Roots cross the imaginary axis only at the positive real zeros
``omega_k`` of the polynomial ``F(omega) = |P(i omega)|^2 - |Q(i omega)|^2``, at the delays
``tau_kj = (arg(-Q/P) mod 2 pi + 2 pi j) / omega_k``, to the right iff ``F'(omega_k) > 0``; the
count at ``tau = 0`` is that of the delay-free eigenvalues (``closed_loop_roots``).  Nothing is
sampled, so the narrow resonance peaks that fooled the old contour height cannot fool it.
The chart and the count at 0.2 s are also checked against Chebyshev collocation
(``ctmm.reference.dde``).
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings, strategies as st

import ctmm
from ctmm.certification import StabilityWarning
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.errors import ModelError
from ctmm.reference.chain import GlobalChain, assemble
from ctmm.reference.dde import chebyshev_collocation_roots, second_order_system
from ctmm.reference.delay_chain import GlobalLoop, closed_loop_roots
from ctmm.stability import delay_margin, gain_margin, stability_chart, unstable_root_count

SEED_CRITICAL_DELAY = 0.140286      # issue 11 (collocation and margins agree)


# ------------------------------------------------------------------------------ models
def chain_pair(masses, stiffness, damping, sensor, actuator, quantity, gain, delay):
    """The same chain as a ctmm ControlledChain and as reference matrices."""
    body = [Fixed("wall")]
    for i, (m, k, c) in enumerate(zip(masses, stiffness, damping)):
        body += [SpringDamper(f"k{i}", k, c), Mass(f"m{i}", m)]
    body.append(Free("end"))
    signal = {"displacement": "x", "velocity": "v"}[quantity]
    system = ControlledChain(ctmm.Chain("chain", body),
                             [Feedback("L", f"m{sensor}.{signal}", f"m{actuator}", gain=gain, delay=delay)])
    reference = GlobalChain(list(masses), list(stiffness) + [0.0], list(damping) + [0.0],
                            start="fixed", end="free")
    loop = GlobalLoop(sensor, quantity, actuator, gain, delay)
    return system, reference, loop


def seed(gain=1.0, delay=0.005):
    return chain_pair([1.0] * 3, [1000.0] * 3, [0.5] * 3, 2, 0, "velocity", gain, delay)


# ------------------------------------------------------------------------------ reference
def _poly_of(M: np.ndarray, C: np.ndarray, K: np.ndarray, scale: float) -> np.ndarray:
    """Coefficients (in z = s/scale) of det(s^2 M + s C + K), from the eigenvalues."""
    n = M.shape[0]
    left = np.block([[np.zeros((n, n)), np.eye(n)], [-K, -C]])
    right = np.block([[np.eye(n), np.zeros((n, n))], [np.zeros((n, n)), M]])
    import scipy.linalg

    eig = scipy.linalg.eigvals(left, right) / scale
    return np.real(np.poly(eig)) * np.linalg.det(M) * scale ** (2 * n)


def crossing_reference(reference: GlobalChain, loop: GlobalLoop):
    """(count at zero delay, [(tau_kj generator: tau0, period, direction), ...])."""
    M, C, K = assemble(reference)
    n = reference.size
    b = np.zeros(n)
    b[loop.actuator_mass] = 1.0
    c = np.zeros(n)
    c[loop.sensor_mass] = 1.0
    scale = math.sqrt(np.max(np.diag(K) / np.diag(M)))
    P = _poly_of(M, C, K, scale)
    outer = np.outer(b, c)
    modified = [M, C, K]
    modified[2 - loop.order] = modified[2 - loop.order] + outer
    Q = loop.gain * np.polysub(_poly_of(*modified, scale), P)   # = g s^p c^T adj(D0) b
    # polynomials in omega (z = i w)
    def in_omega(p):
        degree = len(p) - 1
        return np.array([coef * (1j) ** (degree - i) for i, coef in enumerate(p)])

    Pw, Qw = in_omega(P), in_omega(Q)
    F = np.real(np.polysub(np.polymul(Pw, np.conj(Pw)), np.polymul(Qw, np.conj(Qw))))
    dF = np.polyder(F)
    crossings = []
    for root in np.roots(F):
        if abs(root.imag) > 1e-7 * max(1.0, abs(root)) or root.real <= 0:
            continue
        w = root.real
        for _ in range(5):                                   # polish on the polynomial
            w = w - np.polyval(F, w) / np.polyval(dF, w)
        ratio = -np.polyval(Pw, w) / np.polyval(Qw, w)      # = e^{-i w tau}
        tau0 = np.mod(-np.angle(ratio), 2 * math.pi) / w
        crossings.append((tau0 / scale, 2 * math.pi / (w * scale), int(np.sign(np.polyval(dF, w)))))
    free = GlobalLoop(loop.sensor_mass, loop.quantity, loop.actuator_mass, loop.gain, 0.0)
    roots0 = closed_loop_roots(reference, [free])
    return int(np.sum(roots0.real > 0)), crossings


def reference_count(reference: GlobalChain, loop: GlobalLoop, delay: float, *, guard: float = 0.0):
    """Roots in Re s > 0 at ``delay``; None when a crossing lies within ``guard`` of it."""
    n0, crossings = crossing_reference(reference, loop)
    total = n0
    for tau0, period, direction in crossings:
        j = np.arange(int(max(0, (delay - tau0) // period)) + 2)
        taus = tau0 + period * j
        if np.any(np.abs(taus - delay) <= guard):
            return None
        total += 2 * direction * int(np.sum(taus < delay))
    return total


def collocation_count(reference: GlobalChain, loop: GlobalLoop, nodes: int = 40) -> int:
    M, C, K = assemble(reference)
    n = reference.size
    G = np.zeros((n, n))
    G[loop.actuator_mass, loop.sensor_mass] = loop.gain
    terms = [(G, np.zeros((n, n)), loop.delay)] if loop.order == 0 else [(np.zeros((n, n)), G, loop.delay)]
    A0, delayed = second_order_system(M, C, K, terms)
    roots = chebyshev_collocation_roots(A0, delayed, nodes)
    roots = roots[np.abs(roots) * loop.delay < 0.3 * nodes]       # converged part of the spectrum
    return int(np.sum(roots.real > 1e-9))


# ------------------------------------------------------------------------------ seed chain
def test_seed_reference_critical_delay_is_the_issue_value():
    _, reference, loop = seed()
    _, crossings = crossing_reference(reference, loop)
    first = min(t for t, _, d in crossings)
    assert abs(first - SEED_CRITICAL_DELAY) < 1e-6


def test_seed_chain_delay_margin_with_no_option():
    system, reference, loop = seed()
    dm = delay_margin(system)
    _, crossings = crossing_reference(reference, loop)
    expected = min(t for t, _, _ in crossings)
    assert abs(dm.critical_delay - expected) < 1e-9 * expected
    assert abs(dm.margin - (expected - 0.005)) < 1e-9
    assert dm.certificate.certified and dm.certificate.source == "bound"
    # every crossing below delay_max, with its direction
    listed = sorted((t + j * p, d) for t, p, d in crossings for j in range(100) if t + j * p <= dm.delay_max)
    assert len(listed) == len(dm.crossing_delays)
    assert np.allclose([t for t, _ in listed], dm.crossing_delays, rtol=1e-8)
    assert [d for _, d in listed] == list(dm.crossing_directions)


def test_seed_chain_counts_at_0p2_s(monkeypatch):
    import ctmm.certification as certification
    import ctmm.counting_contour as counting_contour

    searched, search = [], counting_contour.fixed_roots
    monkeypatch.setattr(counting_contour, "fixed_roots", lambda *args: searched.append(args[1]) or search(*args))
    realised, realise = [], certification.plant_realisation
    monkeypatch.setattr(certification, "plant_realisation", lambda model: realised.append(1) or realise(model))
    system, reference, loop = seed(delay=0.2)
    counts = unstable_root_count(system, delay=[0.0, 0.1, 0.2, 0.35])
    expected = [reference_count(reference, GlobalLoop(2, "velocity", 0, 1.0, t), t) for t in (0.0, 0.1, 0.2, 0.35)]
    assert counts.tolist() == expected
    # the open loop's eigenvalue search for roots fixed on the line runs once per contour (it ran twice), and
    # the open loop's realisation and eigenvalues are built once for those roots and the loop bound (twice)
    assert searched == [0.0] and len(realised) == 1
    assert counts[2] == 2 == collocation_count(reference, loop)
    assert counts.certificate.certified


def test_seed_chart_246_cells_82_unstable():
    system, reference, _ = seed()
    gains, delays = np.linspace(0.5, 1.0, 6), np.linspace(0.0, 0.4, 41)
    chart = stability_chart(system, x=("gain", gains), y=("delay", delays))
    assert chart.unstable_roots.size == 246
    assert int(np.sum(chart.unstable_roots > 0)) == 82
    assert chart.certificate.certified
    for i, tau in enumerate(delays):
        for j, g in enumerate(gains):
            expected = reference_count(reference, GlobalLoop(2, "velocity", 0, float(g), float(tau)), float(tau))
            assert chart.unstable_roots[i, j] == expected, (g, tau)


def test_user_im_max_too_small_warns_and_is_not_certified():
    system, _, _ = seed(delay=0.2)
    with pytest.warns(StabilityWarning, match="im_max = 5 rad/s is too small"):
        counts = unstable_root_count(system, im_max=5.0)
    assert not counts.certificate.certified
    with pytest.warns(StabilityWarning):
        dm = delay_margin(system, im_max=5.0)
    assert not dm.certificate.certified and "too small" in " ".join(dm.certificate.notes)


def test_gain_margin_reports_certificate():
    system, reference, loop = seed()
    gm = gain_margin(system)
    assert gm.certificate.certified
    # at the margin factor a root sits on the axis: the reference count changes across it
    below = reference_count(reference, GlobalLoop(2, "velocity", 0, 0.999 * gm.upper, 0.005), 0.005)
    above = reference_count(reference, GlobalLoop(2, "velocity", 0, 1.001 * gm.upper, 0.005), 0.005)
    assert below == 0 and above > 0


# ------------------------------------------------------------------------------ neutral loops
def test_neutral_loop_gets_a_clear_error():
    plant = ctmm.Chain("c", [Fixed("w"), SpringDamper("k", 100.0, 0.1), Mass("m", 1.0), Free("e")])
    system = ControlledChain(plant, [Feedback("acc", "m.a", "m", gain=0.8, delay=0.1)])
    with pytest.raises(ModelError, match=r"loop 'acc' is neutral.*im_max"):
        unstable_root_count(system)
    counts = unstable_root_count(system, im_max=50.0)          # a bounded range: allowed, flagged
    assert not counts.certificate.certified
    assert "neutral" in " ".join(counts.certificate.notes)


def test_small_feedthrough_is_still_certified():
    """|L(inf)| = 0.2 < 1/2: the bound still holds, with its constant part."""
    plant = ctmm.Chain("c", [Fixed("w"), SpringDamper("k", 100.0, 0.1), Mass("m", 1.0), Free("e")])
    system = ControlledChain(plant, [Feedback("acc", "m.a", "m", gain=0.2, delay=0.1)])
    counts = unstable_root_count(system)
    assert counts.certificate.certified
    # x'' (1 + 0.2 e^{-s tau}) + 0.1 x' + 100 x = 0: stable (|0.2| < 1, positive damping)
    assert counts.tolist() == [0]


# ------------------------------------------------------------------------------ random chains
@settings(max_examples=12, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(1, 3), data=st.data())
def test_random_chains_match_the_crossing_reference(n, data):
    masses = [data.draw(st.floats(0.5, 2.0)) for _ in range(n)]
    stiffness = [data.draw(st.floats(50.0, 2000.0)) for _ in range(n)]
    zeta = [10.0 ** -data.draw(st.integers(1, 4)) * data.draw(st.floats(1.0, 3.0)) for _ in range(n)]
    damping = [2 * z * math.sqrt(k * m) for z, k, m in zip(zeta, stiffness, masses)]
    sensor, actuator = data.draw(st.integers(0, n - 1)), data.draw(st.integers(0, n - 1))
    quantity = data.draw(st.sampled_from(["displacement", "velocity"]))
    M, _, K = assemble(GlobalChain(masses, stiffness + [0.0], start="fixed", end="free"))
    omega = np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    longest = 2 * math.pi / omega.min()
    gain = data.draw(st.floats(0.02, 2.0)) * (float(np.max(stiffness)) if quantity == "displacement"
                                              else math.sqrt(float(np.max(stiffness))))
    delay = longest * 10.0 ** data.draw(st.integers(-2, 2)) * data.draw(st.floats(0.3, 1.0))  # to 100 periods
    system, reference, loop = chain_pair(masses, stiffness, damping, sensor, actuator, quantity, gain, delay)
    expected = reference_count(reference, loop, delay, guard=1e-6 * delay)
    assume(expected is not None)
    counts = unstable_root_count(system)
    assert counts.certificate.certified
    assert counts.tolist() == [expected], (masses, stiffness, zeta, sensor, actuator, quantity, gain, delay)


@pytest.mark.parametrize("quantity, gain", [("velocity", 3.0), ("displacement", 150.0)])
def test_lightly_damped_chain_at_100_periods(quantity, gain):
    """Damping ratio 1e-4 on every connector, delay = 100 x the longest period."""
    masses, stiffness = [1.0, 1.3, 0.8], [900.0, 1100.0, 700.0]
    damping = [2e-4 * math.sqrt(k * m) for k, m in zip(stiffness, masses)]
    M, _, K = assemble(GlobalChain(masses, stiffness + [0.0], start="fixed", end="free"))
    longest = 2 * math.pi / np.sqrt(np.linalg.eigvals(np.linalg.solve(M, K)).real.min())
    delay = 100.0 * longest
    system, reference, loop = chain_pair(masses, stiffness, damping, 2, 0, quantity, gain, delay)
    expected = reference_count(reference, loop, delay, guard=1e-6 * delay)
    counts = unstable_root_count(system)
    assert counts.certificate.certified
    assert counts.tolist() == [expected] and expected > 0


# ------------------------------------------------------------------------------ long chains
def long_chain(n, gain=1.0, delay=0.01):
    return chain_pair([1.0] * n, [1000.0] * n, [0.5] * n, n - 1, 0, "velocity", gain, delay)


def test_long_chain_120_masses_default_call():
    system, reference, loop = long_chain(120, delay=0.0)
    counts = unstable_root_count(system, delay=[0.0])
    assert counts.certificate.certified
    roots = closed_loop_roots(reference, [loop])                  # global eigenvalues, no TMM
    assert counts.tolist() == [int(np.sum(roots.real > 0))]


@pytest.mark.slow
def test_long_chain_400_masses_default_call():
    system, reference, loop = long_chain(400, delay=0.0)
    counts = unstable_root_count(system, delay=[0.0])
    assert counts.certificate.certified
    roots = closed_loop_roots(reference, [loop])
    assert counts.tolist() == [int(np.sum(roots.real > 0))]


# ------------------------------------------------------------------------------ library seeds
def test_library_collocation_matches_lambert_w():
    """x' = a x + b x(t - tau): the library's collocation (seeds) against Lambert W roots."""
    from ctmm.delay_collocation import generator_eigenvalues
    from ctmm.reference.dde import lambert_w_roots

    a, b, tau = -0.5, -2.0, 1.0
    exact = lambert_w_roots(a, b, tau, range(-3, 4))
    approx = generator_eigenvalues(np.array([[a]]), [(np.array([[b]]), tau)], 40)
    for root in exact[np.abs(exact) < 8]:
        assert np.min(np.abs(approx - root)) < 1e-8 * max(1.0, abs(root))


# ------------------------------------------------------------------------------ margins on a grid
def test_margins_on_a_coarse_grid_are_completed_by_the_certified_search():
    from ctmm.control.analysis import margins

    system, reference, loop = seed()
    _, crossings = crossing_reference(reference, loop)
    expected = min(t for t, _, _ in crossings) - 0.005
    fine = margins(system, "L", np.logspace(0.5, 2.5, 600))
    for grid in (np.logspace(0.5, 2.5, 40), np.logspace(0.0, 1.0, 40)):   # between / outside
        coarse = margins(system, "L", grid)
        assert abs(coarse.delay_margin - expected) < 1e-9
        assert abs(coarse.gain_margin - fine.gain_margin) < 1e-9
        assert len(coarse.gain_crossovers) == 2 and any("added" in note for note in coarse.notes)
    assert abs(fine.delay_margin - expected) < 1e-9 and fine.certificate.certified


def test_chart_crossing_next_to_an_anti_resonance():
    """20-mass chain of benchmarks/stability_chart.py: at tau = 0.0697 s a pair crosses at
    gain 3.3886 (31.04 rad/s) next to a zero of the loop term; an unrefined row bracket put it at
    3.4067 and misclassified the grid point 3.3939 (2 instead of 4 unstable roots).  The counts 4
    and 12 of the two cells are those of Chebyshev collocation of the delay equations
    (``ctmm.reference.dde``, 40 and 80 nodes agree)."""
    n = 20
    body = [Fixed("wall")]
    for i in range(n):
        body += [SpringDamper(f"k{i}", 400.0, 0.5), Mass(f"m{i}", 1.0)]
    body.append(Free("end"))
    tip = f"m{n - 1}"
    system = ControlledChain(ctmm.Chain("chain20", body),
                             [Feedback("pd", [(f"{tip}.x", 20.0), (f"{tip}.v", 5.0)], tip, gain=1.0, delay=0.1)])
    gains = np.linspace(0.0, 4.0, 100)
    delays = np.array([0.0, 0.3 * 23 / 99, 0.3 * 97 / 99])
    chart = stability_chart(system, x=("gain", gains), y=("delay", delays), verify=True)
    assert chart.verified
    assert chart.unstable_roots[1, 84] == 4 and chart.unstable_roots[2, 74] == 12


def test_roots_and_abscissa_report_their_region():
    from ctmm.stability import characteristic_roots, spectral_abscissa

    system, reference, loop = seed(delay=0.2)
    roots = characteristic_roots(system, re_min=-1.0, im_max=150.0)
    assert roots.certificate.certified and roots.certificate.sigma == -1.0
    assert int(np.sum(roots.expanded().real > 0)) == 2 == reference_count(reference, loop, 0.2)
    with pytest.warns(StabilityWarning, match="too small"):
        abscissa = spectral_abscissa(system, re_min=-1.0, im_max=10.0)   # misses the unstable pair
    assert not abscissa.certificate.certified and not abscissa.roots.certificate.certified


@pytest.mark.parametrize("delay", [0.05, 1.7, 23.0])
def test_two_close_lightly_damped_modes(delay):
    """wall - k - m0 - kc - m1 - k - wall with kc << k: modes at 31.623 and 31.686 rad/s, damping
    ratio 1e-4, both inside one interval of any coarse grid (a 2 pi phase change would look
    like none)."""
    k, kc, c = 1000.0, 2.0, 2e-4 * math.sqrt(1000.0)
    body = [Fixed("w0"), SpringDamper("k0", k, c), Mass("m0", 1.0), SpringDamper("kc", kc, 0.0),
            Mass("m1", 1.0), SpringDamper("k2", k, c), Fixed("w1")]
    system = ControlledChain(ctmm.Chain("pair", body), [Feedback("L", "m1.v", "m0", gain=0.05, delay=delay)])
    reference = GlobalChain([1.0, 1.0], [k, kc, k], [c, 0.0, c], start="fixed", end="fixed")
    loop = GlobalLoop(1, "velocity", 0, 0.05, delay)
    expected = reference_count(reference, loop, delay, guard=1e-6 * delay)
    counts = unstable_root_count(system)
    assert counts.certificate.certified
    assert counts.tolist() == [expected]


def test_small_im_max_without_possible_roots_only_notes():
    """x' = -x/2 - 1.5 x(t - 0.8) (test_stability.scalar): every root beyond |Im s| = 30 has
    Re s < -3.2 (Lambert W branches), and the loop term stays below 1 there: no warning."""
    from ctmm.stability import characteristic_roots
    from test_stability import scalar

    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)
        roots = characteristic_roots(scalar(2.0, 1.0, 3.0, 0.8), re_min=-3.2, im_max=30.0)
    assert not roots.certificate.certified
    assert "below the proven height" in roots.certificate.notes[-1]


def test_open_loop_poles_of_proportionally_damped_chains_equal_the_dense_eigenvalues(monkeypatch):
    """The certificate's open-loop poles: a lumped chain with Rayleigh damping (connector dampers c = beta k) by
    its modes, equal to the dense eigenvalues of its realisation to round-off (matched one to one); the mode
    path is taken (numpy's dense solver is disabled while it runs); other realisations stay dense."""
    from ctmm import certification
    from ctmm.lumped_realisation import chain_state_space

    rng = np.random.default_rng(11)
    cases = []
    for n, beta, end in [(12, 2e-3, "free"), (9, 0.3, "fixed"), (15, 0.0, "free")]:
        body = [Fixed("w")]
        for i in range(n):
            k, m = float(rng.uniform(200.0, 2000.0)), float(rng.uniform(0.3, 3.0))
            body += [SpringDamper(f"k{i}", k, beta * k), Mass(f"m{i}", m)]
        body += [SpringDamper("kn", 500.0, beta * 500.0), Fixed("f")] if end == "fixed" else [Free("e")]
        A = np.asarray(chain_state_space(ctmm.Chain("c", body), inputs=["m0.force"], outputs=["m0.x"]).A, float)
        cases.append((A, np.linalg.eigvals(A)))
    dense_solver = np.linalg.eigvals
    monkeypatch.setattr(np.linalg, "eigvals", lambda a: pytest.fail("the dense solver ran"))
    for A, dense in cases:
        poles = certification.open_loop_poles(A)
        distance = np.abs(poles[:, None] - dense[None, :])
        assert np.max(distance.min(axis=1)) <= 1e-13 * np.abs(dense).max()
        assert sorted(np.argmin(distance, axis=1)) == list(range(dense.size))
    monkeypatch.setattr(np.linalg, "eigvals", dense_solver)
    A = cases[0][0].copy()
    m = A.shape[0] // 2
    A[m + 3, m + 3] *= 1.5                                     # one damper off the proportion: dense
    np.testing.assert_allclose(np.sort_complex(certification.open_loop_poles(A)), np.sort_complex(dense_solver(A)),
                               rtol=0, atol=0)
