"""Delay stability from the TMM characteristic function: affine loop structure, roots, counts, margins.

Independent references (no TMM code): closed forms of ``ctmm.reference.dde`` (Lambert W roots
and Hayes' stability region of x' = a x + b x(t - tau), the delayed PD oscillator's D-curves)
and Chebyshev collocation of the delay equations assembled from M, C, K.
"""
from __future__ import annotations

import math

import control
import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, GroundedSpring, Mass, SpringDamper
from ctmm.errors import ModelError, UnknownNameError
from ctmm.reference.dde import (chebyshev_collocation_roots, delayed_pd_oscillator_characteristic_function,
                                hayes_critical_b, hayes_critical_delay, hayes_is_stable, lambert_w_roots,
                                newton_refine_root)
from ctmm.stability import (LoopCharacteristic, characteristic_roots, delay_margin, gain_margin,
                            spectral_abscissa, spectral_seeds, unstable_root_count)


# ------------------------------------------------------------------------------ systems
def scalar(c=2.0, k=1.0, gain=3.0, delay=0.8) -> ControlledChain:
    """Massless point with a grounded spring-damper: c x' + k x = -g x(t - tau).

    That is x' = a x + b x(t - tau) with a = -k/c, b = -g/c (Hayes' equation for a = 0)."""
    plant = ctmm.Chain("scalar", [Free("a"), GroundedSpring("p", k, damping=c), Free("b")])
    return ControlledChain(plant, [Feedback("u", "p.x", "p", gain=gain, delay=delay)])


def oscillator(omega_n=1.0, zeta=0.1, kp=0.5, kd=0.3, delay=0.5) -> ControlledChain:
    """Unit mass on a spring-damper with a delayed PD loop (FORMULAS 6.2)."""
    plant = ctmm.Chain("oscillator", [Fixed("wall"), SpringDamper("k", omega_n ** 2, 2 * zeta * omega_n),
                                      Mass("m", 1.0), Free("end")])
    return ControlledChain(plant, [Feedback("pd", [("m.x", kp), ("m.v", kd)], "m", gain=1.0, delay=delay)])


def seed_chain(gain=5.0, delay=0.1) -> ControlledChain:
    """Seed Fig. 9.27: sensor on the last mass, actuator on the first (non-collocated)."""
    plant = ctmm.Chain("seed", [Fixed("wall"), SpringDamper("k1", 100.0, 0.5), Mass("m0", 1.0),
                                SpringDamper("k3", 80.0, 0.3), Mass("m1", 1.5),
                                SpringDamper("k5", 120.0, 0.4), Mass("m2", 2.0), Free("end")])
    return ControlledChain(plant, [Feedback("ka", "m2.x", "m0", gain=gain, delay=delay)])


def seed_matrices():
    from ctmm.reference.chain import GlobalChain, assemble

    chain = GlobalChain([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0],
                        start="fixed", end="free")
    return assemble(chain)


def collocation_roots(M, C, K, G, H, delay, nodes=40, keep=8):
    """Rightmost roots of M x'' + C x' + K x = -G x(t-tau) - H x'(t-tau), refined by Newton."""
    from ctmm.reference.dde import second_order_system

    A0, delayed = second_order_system(M, C, K, [(G, H, delay)])
    roots = chebyshev_collocation_roots(A0, delayed, nodes)[:keep]
    refined = np.array([newton_refine_root(A0, delayed, z) for z in roots])
    converged = np.abs(refined - roots) < 1e-4 * np.maximum(1.0, np.abs(roots))   # not spurious
    return refined[converged]


# ------------------------------------------------------------------------------ eq. (1)
@pytest.mark.parametrize("make", [scalar, oscillator, seed_chain])
def test_loop_enters_affinely(make):
    """Delta(s; k, tau, w) = D Delta_0 + k e^{-s tau} sum w_j T_j equals direct TMM evaluations
    (ratios between parameter sets, so that the positive per-s scaling cancels)."""
    system = make()
    model = LoopCharacteristic(system)
    rng = np.random.default_rng(7)
    s = rng.normal(size=12) * 3 + 1j * rng.normal(size=12) * 10
    sets = [dict(gain=rng.normal() * 5, delay=rng.random(), weights=rng.normal(size=model.weights.size))
            for _ in range(4)]
    modelled = np.array([model.evaluate(s, gain=p["gain"], delay=p["delay"], weights=p["weights"])[0]
                         for p in sets])
    direct = []
    for p in sets:
        sys_p = system.with_loops([Feedback(model.loop.name, list(zip(model.term_names, p["weights"])),
                                            model.loop.actuator, gain=p["gain"], delay=p["delay"])])
        direct.append(ctmm.characteristic_function(sys_p, s, normalize=False))
    direct = np.array(direct)
    np.testing.assert_allclose(modelled[1:] / modelled[0], direct[1:] / direct[0], rtol=1e-10)


def test_other_loops_stay_closed():
    """With a second (delayed velocity) loop closed, eq. (1) in the first loop still holds."""
    base = seed_chain()
    system = base.with_loops([base.loops[0], Feedback("damp", "m1.v", "m1", gain=3.0, delay=0.02)])
    model = LoopCharacteristic(system, "ka")
    s = np.array([0.3 + 2j, -0.1 + 7j, 1.0 + 0.5j, 0.0])
    modelled = model.evaluate(s, gain=[2.0, 7.0], delay=[0.1, 0.25])
    direct = [ctmm.characteristic_function(
        system.with_loops([Feedback("ka", "m2.x", "m0", gain=g, delay=tau), system.loops[1]]), s,
        normalize=False) for g, tau in ((2.0, 0.1), (7.0, 0.25))]
    np.testing.assert_allclose(modelled[1] / modelled[0], direct[1] / direct[0], rtol=1e-12)


def test_lti_controller_gain_is_a_factor():
    """For C(s) = (2 + s)/(1 + 0.1 s), 'gain' k scales C: Delta(k) matches the loop k*C."""
    plant = oscillator().plant
    controller = control.tf([1.0, 2.0], [0.1, 1.0])
    system = ControlledChain(plant, [Feedback("c", "m.x", "m", gain=controller, delay=0.3)])
    model = LoopCharacteristic(system)
    s = np.array([0.3 + 2j, -0.2 + 0.5j, 1.0 + 7j])
    ratio = model.evaluate(s, gain=[2.5])[0] / model.evaluate(s, gain=[1.0])[0]
    scaled = system.with_loops([Feedback("c", "m.x", "m", gain=2.5 * controller, delay=0.3)])
    direct = ctmm.characteristic_function(scaled, s, normalize=False) / \
        ctmm.characteristic_function(system, s, normalize=False)
    np.testing.assert_allclose(ratio, direct, rtol=1e-10)


# ------------------------------------------------------------------------------ roots
def test_rightmost_roots_equal_lambert_w():
    c, k, g, tau = 2.0, 1.0, 3.0, 0.8
    roots = characteristic_roots(scalar(c, k, g, tau), re_min=-3.2, im_max=30.0)
    assert roots.reliable
    exact = lambert_w_roots(-k / c, -g / c, tau, [0, -1, 1, -2, 2])
    for z in exact:
        assert np.min(np.abs(roots.roots - z)) <= 1e-10 * max(1.0, abs(z))
    # the principal branch is the rightmost pair (Shinozaki & Mori 2006)
    assert abs(spectral_abscissa(scalar(c, k, g, tau), re_min=-3.2, im_max=30.0).value - exact[0].real) < 1e-10


def test_hayes_equation_rightmost_pair():
    """lambda = -e^{-lambda}: rightmost roots -0.3181 +- 1.3372i (DESIGN §6)."""
    roots = characteristic_roots(scalar(c=1.0, k=1e-300, gain=1.0, delay=1.0), re_min=-2.0, im_max=10.0)
    z = roots.roots[np.argmax(roots.roots.imag >= 0)]
    assert abs(z - complex(lambert_w_roots(0.0, -1.0, 1.0, 0))) < 1e-10
    assert abs(z - (-0.318131505 + 1.337235701j)) < 1e-9


def test_chain_roots_equal_collocation():
    """Seed chain, delayed non-collocated loop: TMM roots = collocation of M x'' + ... = -G x(t-tau)."""
    gain, tau = 25.0, 0.12
    M, C, K = seed_matrices()
    G = np.zeros((3, 3))
    G[0, 2] = gain
    reference = collocation_roots(M, C, K, G, np.zeros((3, 3)), tau, nodes=48)
    found = characteristic_roots(seed_chain(gain, tau), re_min=reference[:6].real.min() - 0.5, im_max=30.0)
    assert found.reliable
    for z in reference[:6]:
        assert np.min(np.abs(found.roots - z)) <= 1e-8 * max(1.0, abs(z))


def test_spectral_seeds_save_work_not_accuracy():
    """Seeds from collocation of the state-space realisation: same roots, fewer evaluations."""
    system = seed_chain(25.0, 0.12)
    plain = characteristic_roots(system, re_min=-1.5, im_max=30.0)
    seeded = characteristic_roots(system, re_min=-1.5, im_max=30.0, seeds="spectral")
    assert seeded.count == plain.count and seeded.reliable
    np.testing.assert_allclose(seeded.roots, plain.roots, atol=1e-12)
    assert seeded.n_evaluations < plain.n_evaluations
    lti = ControlledChain(oscillator().plant, [Feedback("c", "m.x", "m", gain=control.tf([1.0], [0.1, 1.0]))])
    assert spectral_seeds(lti).size == 0                   # no realisation used for LTI loops
    with pytest.raises(ModelError, match="seeds must be"):
        characteristic_roots(system, re_min=-1.0, im_max=10.0, seeds="eig")


def test_oscillator_roots_equal_collocation():
    omega_n, zeta, kp, kd, tau = 2.0, 0.05, 1.5, 0.8, 0.4
    A0 = [[0.0, 1.0], [-omega_n ** 2, -2 * zeta * omega_n]]
    A1 = [[0.0, 0.0], [-kp, -kd]]
    reference = chebyshev_collocation_roots(A0, [(A1, tau)], 40)
    reference = np.array([newton_refine_root(A0, [(A1, tau)], z) for z in reference[:12]])
    reference = reference[(reference.real > -3.0) & (np.abs(reference.imag) < 40.0)]
    found = characteristic_roots(oscillator(omega_n, zeta, kp, kd, tau), re_min=-3.0, im_max=40.0)
    assert found.count == reference.size
    for z in reference:
        assert np.min(np.abs(found.roots - z)) <= 1e-9 * max(1.0, abs(z))
    delta = delayed_pd_oscillator_characteristic_function(omega_n, zeta, tau, kp, kd)
    assert np.all(np.abs(delta(found.roots)) < 1e-9 * (1 + np.abs(found.roots) ** 2))


# ------------------------------------------------------------------------------ counts
def test_unstable_root_count_equals_hayes_region():
    """Counts of x' = a x + b x(t - tau) on a random (a, b) sample match Hayes' conditions."""
    rng = np.random.default_rng(3)
    tau = 1.0
    c = 1.0
    for _ in range(3):
        k = rng.uniform(0.05, 1.5)                    # a = -k/c in (-1.5, -0.05)
        gains = rng.uniform(-4.0, 4.0, size=40)       # b = -g/c
        counts = unstable_root_count(scalar(c, k, 1.0, tau), gain=gains, delay=tau)
        expected = np.array([hayes_is_stable(-k / c, -g / c, tau) for g in gains])
        assert np.array_equal(counts == 0, expected)


def test_counts_of_a_free_mass_equal_collocation():
    """The open chain is singular at s = 0 (free mass): there the closed chains are swept, with
    the same phase convention as the open path."""
    plant = ctmm.Chain("mass", [Free("a"), Mass("m", 1.0), Free("b")])
    system = ControlledChain(plant, [Feedback("pd", [("m.x", 0.2), ("m.v", 0.5)], "m", gain=1.0)])
    kp = np.array([-0.2, 0.1, 0.3, 0.6, 1.0, 0.25])
    kd = np.array([0.5, 0.2, 0.9, 0.4, 1.5, 0.6])
    taus = np.array([1.0, 0.5, 1.0, 2.0, 0.3, 1.4])
    counts = unstable_root_count(system, weights=np.column_stack([kp, kd]), delay=taus)
    for count, p, d, tau in zip(counts, kp, kd, taus):
        A0, A1 = [[0.0, 1.0], [0.0, 0.0]], [[0.0, 0.0], [-p, -d]]
        roots = chebyshev_collocation_roots(A0, [(A1, tau)], 40)
        roots = roots[np.abs(roots) < 10]
        assert count == int(np.sum(roots.real > 0)), (p, d, tau)


def test_counts_equal_collocation_for_the_seed_chain():
    M, C, K = seed_matrices()
    system = seed_chain()
    gains = np.array([-30.0, -5.0, 5.0, 20.0, 45.0, 80.0])
    taus = np.array([0.02, 0.15, 0.4])
    G, T = np.meshgrid(gains, taus)
    counts = unstable_root_count(system, gain=G.ravel(), delay=T.ravel())
    for count, g, tau in zip(counts, G.ravel(), T.ravel()):
        Gm = np.zeros((3, 3))
        Gm[0, 2] = g
        roots = collocation_roots(M, C, K, Gm, np.zeros((3, 3)), tau, nodes=40, keep=40)
        assert count == int(np.sum(roots.real > 0)), (g, tau)


# ------------------------------------------------------------------------------ margins
def test_delay_margin_equals_hayes_critical_delay():
    c, k, g = 2.0, 1.0, 3.0
    result = delay_margin(scalar(c, k, g, 0.5))
    exact = hayes_critical_delay(-k / c, -g / c)
    assert abs(result.critical_delay - exact) <= 1e-12 * exact
    assert abs(result.critical_frequency - math.sqrt((g / c) ** 2 - (k / c) ** 2)) < 1e-12
    assert result.stable and abs(result.margin - (exact - 0.5)) < 1e-12
    assert result.crossing_directions[0] == 1            # roots move right with the delay
    assert result.stable_intervals[0] == (0.0, result.critical_delay)


@pytest.mark.parametrize("delay_max_factor", [0.5, 0.05])
def test_delay_margin_below_delay_max_keeps_the_critical_delay(delay_max_factor):
    """delay_max only limits the crossings listed: the critical delay and the margin stay Hayes' closed form
    (before: both inf, i.e. 'stable for every delay', when delay_max was below the first crossing)."""
    c, k, g = 2.0, 1.0, 3.0
    exact = hayes_critical_delay(-k / c, -g / c)
    result = delay_margin(scalar(c, k, g, 0.1), delay_max=delay_max_factor * exact)
    assert abs(result.critical_delay - exact) <= 1e-12 * exact
    assert abs(result.critical_frequency - math.sqrt((g / c) ** 2 - (k / c) ** 2)) < 1e-12
    assert result.stable and abs(result.margin - (exact - 0.1)) < 1e-12
    assert result.crossing_delays == () and result.delay_max == delay_max_factor * exact


def test_delay_margin_pd_on_mass_and_stability_switches():
    """m s^2 + (kp + kd s) e^{-s tau}: Omega^4 = kp^2 + kd^2 Omega^2, tau_c = arctan(kd Omega/kp)/Omega."""
    plant = ctmm.Chain("mass", [Free("a"), Mass("m", 1.0), Free("b")])
    kp, kd = 2.0, 0.7
    system = ControlledChain(plant, [Feedback("pd", [("m.x", kp), ("m.v", kd)], "m", gain=1.0)])
    result = delay_margin(system)
    omega = math.sqrt((kd ** 2 + math.sqrt(kd ** 4 + 4 * kp ** 2)) / 2)
    assert abs(result.critical_frequency - omega) < 1e-12
    assert abs(result.critical_delay - math.atan(kd * omega / kp) / omega) < 1e-12
    # delay-independent stability: a spring dominates the delayed gain (|L0| < 1 everywhere)
    independent = delay_margin(oscillator(omega_n=2.0, zeta=0.2, kp=0.5, kd=0.0, delay=0.3))
    assert independent.critical_delay == math.inf and independent.stable


def test_gain_margin_equals_hayes_critical_gain():
    c, k, tau = 2.0, 1.0, 0.8
    result = gain_margin(scalar(c, k, 1.0, tau))
    assert abs(result.upper - (-c * hayes_critical_b(-k / c, tau))) < 1e-11
    assert abs(result.lower - (-k)) < 1e-12 and result.lower_frequency == 0.0
    assert result.stable and result.stable_intervals == ((result.lower, result.upper),)


# ------------------------------------------------------------------------------ bad input
def test_unknown_loop_lists_loops():
    with pytest.raises(UnknownNameError, match="unknown loop 'nope'.*available: ka"):
        delay_margin(seed_chain(), "nope")


def test_plain_chain_explains_the_delay_free_answer():
    with pytest.raises(ModelError, match="plain Chain with no loop.*delay-free answer: stable"):
        delay_margin(seed_chain().plant)
    free_mass = ctmm.Chain("mass", [Free("a"), Mass("m", 1.0), Free("b")])
    with pytest.raises(ModelError, match="delay-free answer: not asymptotically stable: a root lies on "
                                         "the imaginary axis near s = 0"):
        gain_margin(free_mass)
    # ... and the delay-free answer it points to
    assert spectral_abscissa(seed_chain().plant, re_min=-1.0, im_max=30.0).stable


def test_bad_parameters():
    with pytest.raises(ModelError, match="delays must be >= 0"):
        unstable_root_count(scalar(), delay=[0.1, -0.2])
    with pytest.raises(ModelError, match="finite"):
        unstable_root_count(scalar(), gain=[1.0, np.nan])
    with pytest.raises(ModelError, match="common length"):
        unstable_root_count(scalar(), gain=[1.0, 2.0], delay=[0.1, 0.2, 0.3])
    with pytest.raises(ModelError, match="gain 0"):
        gain_margin(scalar(gain=0.0))


def test_docstring_examples_run():
    import doctest

    import ctmm.stability
    import ctmm.stability_chart
    import ctmm.sweeps

    for module in (ctmm.stability, ctmm.stability_chart, ctmm.sweeps):
        result = doctest.testmod(module, optionflags=doctest.ELLIPSIS)
        assert result.failed == 0, module.__name__
    from ctmm.stability import stability_chart as exported
    assert exported is ctmm.stability_chart.stability_chart
