"""Acceptance checks of issue 11 against references built here (red team, variations the team's
tests do not cover).

References (no transfer-matrix code):

* Delay stability: global ``M, C, K`` assembled below; the loop transfer function
  ``L0(s) = C(s) sum_p w_p s^p c^T (s^2 M + s C + K)^{-1} b`` by dense (or tridiagonal) solves;
  the gain crossovers ``|L0(i w)| = 1`` found by sign changes of ``log|L0|`` on a grid that is
  logarithmic *and* clustered around every damped plant pole (``±1000`` half-power widths), then
  Brent-refined; crossing delays ``tau = (arg L0 - pi mod 2 pi + 2 pi j) / w`` and directions
  (a pair enters the right half plane where ``|L0|`` decreases through 1, Cooke and van den
  Driessche 1986); roots at zero delay from the state-space closed loop (controller states
  included).  Gain margins from the phase crossovers ``Im(L0 e^{-i w tau}) = 0``.
* Time: ``ctmm.reference.delay_newmark`` (global closed-loop Newmark) for controlled runs, the
  50-digit global recurrence ``ctmm.reference.chain_stepping`` for stiff chains.
* Planar arms: ``ctmm.reference.planar_lagrange`` (dense ``eigh(K, M)`` of the Lagrange model).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import control
import mpmath
import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import brentq

import ctmm
from ctmm.guard import StabilityLimitWarning
from ctmm.control import ControlledChain, Feedback, simulate_controlled
from ctmm.control.analysis import margins
from ctmm.control.protocol import ControllerStep
from ctmm.elements import Fixed, Free, Mass, Spring, SpringDamper
from ctmm.errors import ModelError
from ctmm.reference.chain import GlobalChain
from ctmm.reference.chain_stepping import step_global
from ctmm.reference.delay_chain import GlobalLoop
from ctmm.reference.delay_newmark import newmark_closed_loop
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.stability import delay_margin, gain_margin, unstable_root_count


# ------------------------------------------------------------------------------ reference
def matrices(masses, stiffness, damping, *, fixed_end: bool):
    """Global M, C, K of wall - k0 - m0 - k1 - ... - m(n-1) [- k_n - wall]."""
    n = len(masses)
    M = np.diag(np.asarray(masses, float))
    K, C = np.zeros((n, n)), np.zeros((n, n))
    pairs = [(None, 0)] + [(i, i + 1) for i in range(n - 1)] + ([(n - 1, None)] if fixed_end else [])
    for (a, b), k, c in zip(pairs, stiffness, damping):
        for matrix, value in ((K, k), (C, c)):
            if a is not None:
                matrix[a, a] += value
            if b is not None:
                matrix[b, b] += value
            if a is not None and b is not None:
                matrix[a, b] -= value
                matrix[b, a] -= value
    return M, C, K


def loop_transfer(M, C, K, b, c_terms, controller):
    """``L0(s)`` vectorised over ``s``: tridiagonal (Thomas) solves of ``D0(s) x = b``.

    The arrays are laid out (mass, frequency) so that every elimination step works on contiguous rows,
    in blocks of frequencies small enough to stay in cache.
    """
    dm, dc, dk = np.diag(M), np.diag(C), np.diag(K)
    oc, ok = np.diag(C, 1), np.diag(K, 1)
    n = len(dm)

    def L0(s):
        s = np.atleast_1d(np.asarray(s, complex))
        if s.size > 2048:                     # blocks of frequencies that stay in cache
            return np.concatenate([L0(block) for block in np.array_split(s, -(-s.size // 2048))])
        if s.size == 1:                       # scalar solve (Brent refinement) in plain complex arithmetic
            return np.array([scalar(complex(s[0]))]) * controller(s)
        d = dm[:, None] * s ** 2 + dc[:, None] * s + dk[:, None]
        off = oc[:, None] * s + ok[:, None]
        r = np.repeat(b.astype(complex)[:, None], s.size, axis=1)
        for i in range(1, n):
            f = off[i - 1] / d[i - 1]
            d[i] -= f * off[i - 1]
            r[i] -= f * r[i - 1]
        x = np.empty_like(r)
        x[-1] = r[-1] / d[-1]
        for i in range(n - 2, -1, -1):
            x[i] = (r[i] - off[i] * x[i + 1]) / d[i]
        return sum(s ** p * (cv @ x) for p, cv in c_terms) * controller(s)

    lists = [v.tolist() for v in (dm, dc, dk, oc, ok, b)]

    def scalar(s: complex) -> complex:
        m, c, k, c1, k1, r = lists
        d = [m[i] * s * s + c[i] * s + k[i] for i in range(n)]
        off = [c1[i] * s + k1[i] for i in range(n - 1)]
        r = [complex(v) for v in r]
        for i in range(1, n):
            f = off[i - 1] / d[i - 1]
            d[i] -= f * off[i - 1]
            r[i] -= f * r[i - 1]
        x = [0j] * n
        x[-1] = r[-1] / d[-1]
        for i in range(n - 2, -1, -1):
            x[i] = (r[i] - off[i] * x[i + 1]) / d[i]
        return sum(s ** p * sum(w * xi for w, xi in zip(cv.tolist(), x)) for p, cv in c_terms)
    return L0


def plant_poles(M, C, K):
    """Roots of ``det(s^2 M + s C + K) = 0``; modal (``eigh``) when the damping is ``C = alpha K``."""
    n = len(M)
    alpha = C[0, 0] / K[0, 0]
    if np.count_nonzero(M - np.diag(np.diag(M))) == 0 and np.allclose(C, alpha * K, rtol=1e-13, atol=0.0):
        w2 = sla.eigh(K, M, eigvals_only=True)                # s^2 + alpha w^2 s + w^2 = 0 per mode
        return np.concatenate([np.roots([1.0, alpha * v, v]) for v in w2]).astype(complex)
    left = np.block([[np.zeros((n, n)), np.eye(n)], [-K, -C]])
    right = np.block([[np.eye(n), np.zeros((n, n))], [np.zeros((n, n)), M]])
    return sla.eigvals(left, right)


def clustered_grid(poles, lowest=1e-4, decades_above=3.0, points=20000, per_pole=400):
    wmax = max(float(np.abs(poles).max()), 1.0)
    grid = [np.logspace(math.log10(lowest), math.log10(wmax) + decades_above, points)]
    offsets = np.logspace(-3, 3, per_pole)
    offsets = np.concatenate([-offsets[::-1], [0.0], offsets])
    for z in poles:
        if z.imag > 0:
            grid.append(z.imag + max(abs(z.real), 1e-12 * abs(z)) * offsets)
    w = np.unique(np.concatenate(grid))
    return w[w > 0]


def crossings(L0, poles, per_pole=400):
    """[(tau0 [s], period [s], direction, frequency [rad/s])] of every gain crossover."""
    w = clustered_grid(poles, per_pole=per_pole)
    with np.errstate(divide="ignore"):
        f = np.log(np.abs(L0(1j * w)))
    assert f[-1] < -1e-3, "loop does not decay: not a retarded loop"
    out = []
    for i in np.nonzero(np.sign(f[:-1]) * np.sign(f[1:]) < 0)[0]:
        wc = brentq(lambda x: float(np.log(abs(L0(1j * x)[0]))), w[i], w[i + 1], xtol=1e-14 * w[i], rtol=1e-15)
        tau0 = np.mod(np.angle(L0(1j * wc)[0]) - math.pi, 2 * math.pi) / wc
        out.append((tau0, 2 * math.pi / wc, 1 if f[i] > f[i + 1] else -1, wc))
    return out


def zero_delay_unstable(M, C, K, b, c_terms, controller_ss):
    """Closed-loop roots in Re s > 0 at zero delay (state space, controller states included)."""
    n = len(M)
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ C]])
    B = np.concatenate([np.zeros(n), Mi @ b])[:, None]
    Cy = np.zeros((1, 2 * n))
    for p, cv in c_terms:
        Cy[0, p * n:(p + 1) * n] += cv
    Ac, Bc, Cc, Dc = (np.atleast_2d(np.asarray(z, float)) for z in controller_ss)
    closed = np.block([[A - B @ Dc @ Cy, -B @ Cc], [Bc @ Cy, Ac]]) if Ac.size else A - B @ Dc @ Cy
    return int(np.sum(np.linalg.eigvals(closed).real > 1e-12))


def count_at(n0, cross, delay):
    total = n0
    for tau0, period, direction, _ in cross:
        taus = tau0 + period * np.arange(int(max(0.0, (delay - tau0) // period)) + 2)
        assert np.all(np.abs(taus - delay) > 1e-7 * max(delay, 1e-9)), "delay too close to a crossing"
        total += 2 * direction * int(np.sum(taus < delay))
    return total


class Case:
    """One chain with one loop, as a ctmm ControlledChain and as reference data."""

    def __init__(self, masses, stiffness, zeta, sensor, actuator, gain, delay, *, fixed_end=False, lti=None):
        n = len(masses)
        damping = [2 * zeta * math.sqrt(k * masses[min(i, n - 1)]) for i, k in enumerate(stiffness)]
        body = [Fixed("wall")]
        for i in range(n):
            body += [SpringDamper(f"k{i}", stiffness[i], damping[i]), Mass(f"m{i}", masses[i])]
        body += [SpringDamper(f"k{n}", stiffness[n], damping[n]), Fixed("far")] if fixed_end else [Free("end")]
        self.M, self.C, self.K = matrices(masses, stiffness, damping, fixed_end=fixed_end)
        self.c_terms = []
        for i, p, weight in sensor:
            cv = np.zeros(n)
            cv[i] = weight
            self.c_terms.append((p, cv))
        self.b = np.zeros(n)
        if actuator[0] == "mass":
            name = f"m{actuator[1]}"
            self.b[actuator[1]] = 1.0
        else:                                    # across connector j: +u outboard, -u inboard
            j = actuator[1]
            name = f"k{j}"
            if j < n:
                self.b[j] += 1.0
            if j >= 1:
                self.b[j - 1] -= 1.0
        terms = [(f"m{i}.{'xva'[p]}", weight) for i, p, weight in sensor]
        self.system = ControlledChain(ctmm.Chain("chain", body),
                                      [Feedback("L", terms, name, gain=gain if lti is None else lti, delay=delay)])
        if lti is None:
            controller, ss, extra = (lambda s: gain + 0 * s), (np.zeros((0, 0)), np.zeros((0, 1)),
                                                                 np.zeros((1, 0)), [[gain]]), ()
        else:
            state = control.ss(lti)
            controller = lambda s: np.asarray(lti(s), complex).reshape(np.shape(s))  # noqa: E731
            ss, extra = (state.A, state.B, state.C, state.D), np.linalg.eigvals(state.A)
        self.delay = delay
        self.L0 = loop_transfer(self.M, self.C, self.K, self.b, self.c_terms, controller)
        self.poles = np.concatenate([plant_poles(self.M, self.C, self.K), np.asarray(extra, complex)])
        self.n0 = zero_delay_unstable(self.M, self.C, self.K, self.b, self.c_terms, ss)
        self.cross = crossings(self.L0, self.poles, per_pole=400 if n <= 60 else 60)

    def critical_delay(self):
        return min((c[0] for c in self.cross), default=math.inf)

    def check(self):
        with warnings.catch_warnings():
            warnings.simplefilter("error")           # a certified default answer must not warn
            dm = delay_margin(self.system)
            counts = unstable_root_count(self.system)
        expected = self.critical_delay()
        assert dm.certificate.certified and counts.certificate.certified
        if math.isinf(expected):
            assert math.isinf(dm.critical_delay)
        else:
            assert dm.critical_delay == pytest.approx(expected, rel=1e-8)
        assert dm.unstable_roots_at_zero_delay == self.n0
        assert counts.tolist() == [count_at(self.n0, self.cross, self.delay)]


M3, K3 = [1.0, 1.3, 0.8], [900.0, 1100.0, 700.0]
LONGEST = 2 * math.pi / 14.0          # about the longest period of the 3-mass chain [s]


# ------------------------------------------------------------------------------ 1. stability
@pytest.mark.parametrize("zeta", [1e-4, 1e-2, 0.3])
@pytest.mark.parametrize("label, sensor, actuator, gain, delay, fixed_end", [
    ("downstream velocity", [(2, 1, 1.0)], ("mass", 0), 3.0, 0.05, False),
    ("upstream displacement", [(0, 0, 1.0)], ("mass", 2), 150.0, 0.05, False),
    ("collocated velocity", [(1, 1, 1.0)], ("mass", 1), 5.0, 0.3, False),
    ("relative velocity", [(2, 1, 1.0), (1, 1, -1.0)], ("mass", 0), 3.0, 0.1, False),
    ("relative displacement across a connector", [(2, 0, 1.0), (1, 0, -1.0)], ("across", 2), 200.0, 0.02, False),
    ("PD", [(2, 0, 100.0), (2, 1, 3.0)], ("mass", 0), 1.0, 0.02, False),
    ("fixed-fixed chain", [(2, 1, 1.0)], ("mass", 0), 3.0, 0.05, True),
    ("100 longest periods", [(2, 1, 1.0)], ("mass", 0), 3.0, 100 * LONGEST, False),
])
def test_delay_margin_and_counts_by_default(label, sensor, actuator, gain, delay, fixed_end, zeta):
    stiffness = K3 + [800.0] if fixed_end else K3
    Case(M3, stiffness, zeta, sensor, actuator, gain, delay, fixed_end=fixed_end).check()


@pytest.mark.parametrize("zeta", [1e-4, 1e-2])
@pytest.mark.parametrize("label, lti, sensor, actuator, delay", [
    ("filtered derivative of x", control.tf([20.0, 0.0], [1 / 200.0, 1.0]), [(2, 0, 1.0)], 0, 0.01),
    ("low-pass on v", control.tf([5.0], [1 / 50.0, 1.0]), [(2, 1, 1.0)], 0, 0.05),
    ("PD with 2nd-order roll-off, collocated", control.tf([6.0, 300.0], [1 / 400.0 ** 2, 1 / 400.0, 1.0]),
     [(1, 0, 1.0)], 1, 0.003),
])
def test_lti_controllers_with_roll_off(label, lti, sensor, actuator, delay, zeta):
    Case(M3, K3, zeta, sensor, ("mass", actuator), None, delay, lti=lti).check()


@pytest.mark.parametrize("n, zeta, delay, sensor, actuator, gain", [
    (50, 1e-3, 0.5, (49, 1), 0, 1.0),
    (50, 1e-3, 0.5, (25, 0), 25, 50.0),
])
def test_long_chain_with_delay(n, zeta, delay, sensor, actuator, gain):
    Case([1.0] * n, [1000.0] * n, zeta, [(sensor[0], sensor[1], 1.0)], ("mass", actuator), gain, delay).check()


@pytest.mark.slow
@pytest.mark.parametrize("n, zeta, delay", [(120, 1e-2, 0.2), (500, 0.05, 0.05)])
def test_very_long_chain_with_delay(n, zeta, delay):
    Case([1.0] * n, [1000.0] * n, zeta, [(n // 2, 0, 1.0)], ("mass", n // 2), 50.0, delay).check()


@pytest.mark.parametrize("zeta, sensor, actuator", [
    (1e-4, [(2, 1, 1.0)], ("mass", 0)),
    (1e-3, [(2, 1, 1.0), (1, 1, -1.0)], ("across", 1)),                 # relative, across k1
])
def test_chart_gain_by_delay_to_100_periods(zeta, sensor, actuator):
    from ctmm.stability_chart import stability_chart
    gains, delays = np.linspace(0.2, 3.0, 8), np.linspace(0.0, 100 * LONGEST, 61)
    chart = stability_chart(Case(M3, K3, zeta, sensor, actuator, 1.0, 0.05).system, x=("gain", gains),
                            y=("delay", delays))
    assert chart.certificate.certified
    for j, gain in enumerate(gains):
        case = Case(M3, K3, zeta, sensor, actuator, float(gain), 0.05)
        expected = [count_at(case.n0, case.cross, float(tau)) for tau in delays]
        assert chart.unstable_roots[:, j].tolist() == expected, gain
    assert np.unique(chart.unstable_roots).size > 5          # a non-trivial chart (counts 0 to 42)


def phase_crossover_factors(case: Case, delay: float):
    w = clustered_grid(case.poles, lowest=1e-3, points=40000)
    L = lambda x: case.L0(1j * x) * np.exp(-1j * x * delay)  # noqa: E731
    im = L(w).imag
    factors = []
    for i in np.nonzero(np.sign(im[:-1]) * np.sign(im[1:]) < 0)[0]:
        wc = brentq(lambda x: L(x)[0].imag, w[i], w[i + 1], xtol=1e-15 * w[i])
        factors.append(-1.0 / L(wc)[0].real)
    return np.array(factors)


@pytest.mark.parametrize("zeta", [1e-4, 1e-2, 0.3])
@pytest.mark.parametrize("delay", [0.0, 0.01, 0.3])
def test_gain_margin_equals_phase_crossovers(zeta, delay):
    case = Case(M3, K3, zeta, [(2, 1, 1.0)], ("mass", 0), 1.0, delay)
    factors = phase_crossover_factors(case, delay)
    result = gain_margin(case.system)
    assert result.certificate.certified
    above, below = factors[factors > 1.0], factors[factors < 1.0]
    upper = above.min() if above.size and above.min() <= 100.0 else math.inf
    lower = below.max() if below.size and below.max() >= -100.0 else -math.inf
    assert result.upper == (upper if math.isinf(upper) else pytest.approx(upper, rel=1e-8))
    assert result.lower == (lower if math.isinf(lower) else pytest.approx(lower, rel=1e-8))


@pytest.mark.parametrize("zeta", [1e-4, 1e-2])
@pytest.mark.parametrize("lti", [None, control.tf([5.0], [1 / 50.0, 1.0])])
def test_margins_from_a_coarse_grid_on_a_lightly_damped_chain(zeta, lti):
    """20 samples over 3 decades: the crossovers near 13-14 and 53 rad/s lie between them."""
    case = Case(M3, K3, zeta, [(2, 1, 1.0)], ("mass", 0), 1.0, 0.0, lti=lti)
    result = margins(case.system, "L", np.logspace(0, 3, 20))
    assert result.delay_margin == pytest.approx(min(tau0 for tau0, _, _, _ in case.cross), rel=1e-9)
    np.testing.assert_allclose(sorted(result.gain_crossovers), sorted(c[3] for c in case.cross), rtol=1e-9)


# ------------------------------------------------------------------------------ 2. controlled runs
def seed_plant():
    return ctmm.Chain("seed", [Fixed("wall"), SpringDamper("K1", 1000.0, 0.5), Mass("m2", 1.0),
                               SpringDamper("K3", 1000.0, 0.5), Mass("m4", 1.0), SpringDamper("K5", 1000.0, 0.5),
                               Mass("m6", 1.0), Free("end")])


SEED_GLOBAL = GlobalChain([1.0] * 3, [1000.0] * 3 + [0.0], [0.5] * 3 + [0.0], start="fixed", end="free")


@pytest.mark.parametrize("sensor, actuator, gain, delay, loop", [
    ("m6.v", "m2", 50.0, 0.003, GlobalLoop(2, "velocity", 0, 50.0, 0.003)),
    ("m6.x", "m2", 300.0, 0.0125, GlobalLoop(2, "displacement", 0, 300.0, 0.0125)),       # tau/dt = 12.5
    ([("m6.v", 1.0), ("m4.v", -1.0)], "K5", 20.0, 0.0047,
     GlobalLoop(2, "velocity", 2, 20.0, 0.0047, relative_to=1, reaction_mass=1)),      # across K5
    ("m4.x", "m4", 500.0, 0.0, GlobalLoop(1, "displacement", 1, 500.0, 0.0)),              # real time
    ("m6.v", "m2", 30.0, 0.0004, GlobalLoop(2, "velocity", 0, 30.0, 0.0004)),              # tau < dt
])
def test_simulate_controlled_chain_equals_global_closed_loop_newmark(sensor, actuator, gain, delay, loop):
    system = ControlledChain(seed_plant(), [Feedback("L", sensor, actuator, gain=gain, delay=delay)])
    run = ctmm.simulate(system, t_final=0.5, dt=1e-3, x0={"m6": 0.01})
    ref = newmark_closed_loop(SEED_GLOBAL, [loop], 0.5, 1e-3, [0.0, 0.0, 0.01], [0.0, 0.0, 0.0])
    scale = np.max(np.abs(ref.displacement))
    for i, name in enumerate(["m2", "m4", "m6"]):
        assert np.max(np.abs(run[f"{name}.x"] - ref.displacement[:, i])) <= 1e-11 * scale
    assert np.max(np.abs(run["L.u"] - ref.control[:, 0])) <= 1e-11 * max(1.0, np.max(np.abs(ref.control)))


@pytest.mark.parametrize("delay", [0.0, 0.0125])
def test_reference_signal_is_delayed_with_the_loop(delay):
    """u = -g (y - r)(t - tau): r enters as the force g r(t - tau) on the actuated mass."""
    r = lambda t: 0.01 * (1.0 - np.cos(5.0 * np.maximum(t, 0.0)))  # noqa: E731
    system = ControlledChain(seed_plant(), [Feedback("L", "m6.x", "m2", gain=300.0, delay=delay)])
    run = simulate_controlled(system, t_final=0.5, dt=1e-3, references={"L": r})
    ref = newmark_closed_loop(SEED_GLOBAL, [GlobalLoop(2, "displacement", 0, 300.0, delay)], 0.5, 1e-3,
                              [0.0] * 3, [0.0] * 3, force_fn=lambda t: np.array([300.0 * float(r(t - delay)), 0, 0]))
    assert np.max(np.abs(ref.displacement[:, 2])) > 1e-3
    assert np.max(np.abs(run["m6.x"] - ref.displacement[:, 2])) <= 1e-12


# ------------------------------------------------------------------------------ 3. hard cases
def stiff(seed: int, n: int, damped: bool):
    rng = np.random.default_rng(seed)
    elements, masses, ks, cs = [Fixed("wall")], [], [], []
    for i in range(n):
        k, c, m = 10 ** rng.uniform(0, 9), (10 ** rng.uniform(-3, 3) if damped else 0.0), 10 ** rng.uniform(-3, 3)
        elements += [SpringDamper(f"k{i}", k, c), Mass(f"m{i}", m)]
        masses.append(m), ks.append(k), cs.append(c)
    k_end = 10 ** rng.uniform(0, 9)
    elements += [Spring("k_end", k_end), Fixed("far")]
    chain = GlobalChain(masses, ks + [k_end], cs + [0.0], start="fixed", end="fixed")
    return ctmm.Chain("stiff", elements), chain, rng.normal(0, 1e-3, n), rng.normal(0, 1e-2, n)


@pytest.mark.parametrize("scheme", ["newmark", "generalized_alpha", "wilson_theta", "houbolt"])
def test_stiff_fixed_fixed_chain_with_initial_velocities(scheme):
    """30 masses, springs 1e0-1e9 N/m, masses 1e-3-1e3 kg, dt = 1e-2 s, both ends fixed, v0 != 0."""
    chain, reference, x0, v0 = stiff(11, 30, damped=True)
    dt, steps = 1e-2, 12
    with mpmath.workdps(40):
        exact = step_global(reference, steps * dt, dt, x0, v0, scheme=scheme, number=mpmath.mpf).displacement
    scale = np.max(np.abs(exact))
    double = np.max(np.abs(step_global(reference, steps * dt, dt, x0, v0, scheme=scheme).displacement - exact))
    names = [f"m{i}" for i in range(30)]
    run = ctmm.simulate(chain, steps * dt, dt, scheme=scheme, x0=dict(zip(names, x0)), v0=dict(zip(names, v0)),
                        stability_check="ignore")
    error = np.max(np.abs(np.column_stack([run[f"{m}.x"] for m in names]) - exact))
    assert error <= 4 * double + steps * np.finfo(float).eps * scale


def _arm(links: int, stiffness: float, gravity):
    from ctmm.planar import ElasticHinge, Fixed as PlanarFixed, PlanarModel, RigidBody
    elements = [PlanarFixed("ground")]
    for i in range(links):                      # 3 kg, 2 m uniform links: J_C = 1 kg m^2
        elements += [ElasticHinge(f"h{i}", stiffness=stiffness),
                     RigidBody(f"l{i}", mass=3.0, inertia=1.0, center_of_mass=(1.0, 0.0), outboard=(2.0, 0.0))]
    return PlanarModel.chain("arm", elements, gravity=gravity)


@pytest.mark.parametrize("links", [3, 4])
def test_equal_round_links_counts_at_their_sub_resonances(links):
    """Every link on its hinge resonates at sqrt(100 / 4) = 5 rad/s (about its hinge, J_O = 4)."""
    model = _arm(links, 100.0, (0.0, 0.0))
    q = np.zeros(links)
    expected = PlanarLagrange(model).natural_frequencies(q)
    np.testing.assert_allclose(ctmm.natural_frequencies(model, n_modes=links, operating_point=(q, np.zeros_like(q))), expected, rtol=1e-12)
    trial = [5.0, 10.0, 2.5, 20.0]
    assert ctmm.eigenvalue_count(model, operating_point=(q, np.zeros_like(q)), omega=trial).tolist() == [int(np.sum(expected < w)) for w in trial]


def test_arm_held_against_gravity_is_refused_not_given_zero_frequencies():
    """About an unstable equilibrium K has a negative eigenvalue (omega^2 = -1.73 / s^2 here); the
    planar natural_frequencies returned 0 rad/s for that mode, like a rigid-body mode."""
    model = _arm(3, 100.0, (-10.0, 0.0))          # links point up, against gravity
    M, _, K = PlanarLagrange(model).linearize(np.zeros(3))
    assert np.sum(sla.eigh(K, M, eigvals_only=True) < 0) == 1
    with pytest.raises(ModelError, match=r"'arm' is statically unstable .* 1 mode\(s\) with negative stiffness"):
        ctmm.natural_frequencies(model, n_modes=3, operating_point=(np.zeros(3),) * 2)
    stable = _arm(3, 100.0, (10.0, 0.0))           # hanging: every eigenvalue positive
    np.testing.assert_allclose(ctmm.natural_frequencies(stable, n_modes=3, operating_point=(np.zeros(3),) * 2),
                               PlanarLagrange(stable).natural_frequencies(np.zeros(3)), rtol=1e-12)


# ------------------------------------------------------------------------------ 4, 5. runs
def test_unstable_delayed_loop_stops_with_every_signal():
    system = ControlledChain(seed_plant(), [Feedback("Ka", "m6.v", "m2", gain=50.0, delay=0.05),
                                            Feedback("Kp", "m4.x", "m4", gain=10.0, delay=0.003)])
    with pytest.raises(ctmm.SimulationError, match=r"diverged at t = .*\['Ka', 'Kp'\] may be unstable") as info:
        ctmm.simulate(system, 200.0, 1e-3, x0={"m6": 0.01})
    partial = info.value.partial_result
    assert info.value.time < 10.0 and info.value.element in ("m2", "m4", "m6")
    assert {"Ka.u", "Ka.y", "Kp.u", "Kp.y", "m6.x"} <= set(partial.signals())
    assert {np.asarray(partial[name]).shape[0] for name in partial.signals()} == {len(partial.time)}
    assert len(partial.time) > 1000


@pytest.mark.slow
def test_delay_history_cost_is_flat_in_run_length(monkeypatch):
    """The delay histories hold a window of O(tau / dt) samples whatever the run length (O(1) memory and look-up
    cost per step): the longest window of every history is the same after 3 000 and 9 000 steps, both past the
    first trim of the 1.2345 s delay's window (2 (1235 + 3) samples), and the number of look-ups per step is the
    same.  Counted, not timed (a wall-clock ratio was asserted before; an O(steps) window would grow 3x here)."""
    from ctmm.control.history import DelayHistory

    counts = {"longest": 0, "calls": 0}
    append, call = DelayHistory.append, DelayHistory.__call__

    def counted_append(self, *args, **kwargs):
        append(self, *args, **kwargs)
        counts["longest"] = max(counts["longest"], self.window_length)

    def counted_call(self, time_s):
        counts["calls"] += 1
        return call(self, time_s)

    monkeypatch.setattr(DelayHistory, "append", counted_append)
    monkeypatch.setattr(DelayHistory, "__call__", counted_call)
    lti = control.tf([5.0], [1 / 50.0, 1.0])
    system = ControlledChain(seed_plant(), [Feedback("Ka", "m6.v", "m2", gain=lti, delay=0.0537),
                                            Feedback("Kb", "m4.x", "m4", gain=5.0, delay=1.2345)])
    longest, calls = [], []
    for steps in (3000, 9000):
        counts.update(longest=0, calls=0)
        simulate_controlled(system, steps * 1e-3, 1e-3, x0={"m6": 0.01})
        longest.append(counts["longest"])
        calls.append(counts["calls"] / steps)
    assert longest[0] == longest[1] <= 2 * (math.ceil(1.2345 / 1e-3) + 3) + 1
    assert longest[0] > math.ceil(1.2345 / 1e-3)                 # the long delay's window was in use
    assert calls[1] == pytest.approx(calls[0], rel=1e-3)


@pytest.mark.parametrize("zeta", [1e-4, 1e-2])
@pytest.mark.parametrize("sensor, actuator, gain", [
    ([(2, 0, 1.0), (2, 1, 2.0)], 0, 5.0), ([(1, 0, 1.0), (1, 1, 2.0)], 1, 5.0), ([(0, 0, 10.0), (0, 1, 10.0)], 0, 1.0)])
def test_free_free_chain_with_a_rigid_body_mode(sensor, actuator, gain, zeta):
    """No wall: the plant has a double pole at s = 0, |L0| -> inf at low frequency."""
    masses, ks = [1.0, 1.3, 0.8], [900.0, 1100.0]
    cs = [2 * zeta * math.sqrt(k) for k in ks]
    body = [Free("a"), Mass("m0", masses[0])]
    for i, (k, c) in enumerate(zip(ks, cs)):
        body += [SpringDamper(f"k{i + 1}", k, c), Mass(f"m{i + 1}", masses[i + 1])]
    system = ControlledChain(ctmm.Chain("free_free", body + [Free("b")]),
                             [Feedback("L", [(f"m{i}.{'xv'[p]}", w) for i, p, w in sensor], f"m{actuator}",
                                       gain=gain, delay=0.1)])
    M, C, K = matrices(masses, [0.0] + ks, [0.0] + cs, fixed_end=False)
    c_terms = []
    for i, p, w in sensor:
        cv = np.zeros(3)
        cv[i] = w
        c_terms.append((p, cv))
    b = np.zeros(3)
    b[actuator] = 1.0
    L0 = loop_transfer(M, C, K, b, c_terms, lambda s: gain + 0 * s)
    cross = crossings(L0, plant_poles(M, C, K))
    n0 = zero_delay_unstable(M, C, K, b, c_terms, (np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[gain]]))
    dm, counts = delay_margin(system), unstable_root_count(system)
    assert dm.certificate.certified and counts.certificate.certified
    assert dm.critical_delay == pytest.approx(min(c[0] for c in cross), rel=1e-8)
    assert counts.tolist() == [count_at(n0, cross, 0.1)]


# ------------------------------------------------------------------------------ 2b. controllers
SEED_A = np.block([[np.zeros((3, 3)), np.eye(3)],
                   [-1000.0 * np.array([[2.0, -1, 0], [-1, 2, -1], [0, -1, 1]]),
                    -0.5 * np.array([[2.0, -1, 0], [-1, 2, -1], [0, -1, 1]])]])     # unit masses
SEED_B = np.eye(6)[:, 3]                                                              # force on m2
SEED_X0 = np.array([0.0, 0.0, 0.01, 0.0, 0.0, 0.0])


def lti_closed_loop_exact(lti, delay: float, t_final: float):
    """Continuous plant + C(s) e^{-s tau} on m6.x -> m2: solve_ivp (method of steps for tau > 0)."""
    from scipy.integrate import solve_ivp
    state = control.ss(lti)
    Ac, Bc, Cc, Dc = (np.asarray(z, float) for z in (state.A, state.B, state.C, state.D))
    segments = []

    def y_delayed(t):
        if t <= 0.0:
            return SEED_X0[2]                       # history: the initial state held
        for segment in segments:
            if segment.t[0] - 1e-12 <= t <= segment.t[-1] + 1e-12:
                return segment.sol(t)[2]
        raise AssertionError(t)

    def rhs(t, w):
        y = y_delayed(t - delay) if delay > 0 else w[2]
        u = -(Cc @ w[6:] + Dc[0] * y)[0]
        return np.concatenate([SEED_A @ w[:6] + SEED_B * u, Ac @ w[6:] + Bc[:, 0] * y])

    w, start = np.concatenate([SEED_X0, np.zeros(Ac.shape[0])]), 0.0
    while start < t_final - 1e-12:
        end = min(start + (delay if delay > 0 else t_final), t_final)
        segments.append(solve_ivp(rhs, (start, end), w, rtol=1e-12, atol=1e-15, dense_output=True))
        w, start = segments[-1].y[:, -1], end
    return lambda t: np.array([next(s.sol(x) for s in segments if s.t[0] - 1e-12 <= x <= s.t[-1] + 1e-12)[:3]
                               for x in t])


@pytest.mark.parametrize("delay", [0.0, 0.0123])
def test_lti_controller_run_converges_at_second_order_to_the_continuous_loop(delay):
    """Tustin + Newmark (both second order, no lag) against the continuous closed loop (0.25 s: about 20 delays
    and 50 time constants of the controller's pole; measured ratios 3.9989 and 3.9990, errors 2.4e-6, 2.5e-6)."""
    lti = control.tf([3.0, 300.0], [1 / 200.0, 1.0])
    exact = lti_closed_loop_exact(lti, delay, 0.25)
    system = ControlledChain(seed_plant(), [Feedback("L", "m6.x", "m2", gain=lti, delay=delay)])
    errors = []
    for dt in (1e-3, 5e-4):
        run = simulate_controlled(system, 0.25, dt, x0={"m6": 0.01})
        x = np.column_stack([run[f"{m}.x"] for m in ("m2", "m4", "m6")])
        errors.append(np.max(np.abs(x - exact(run.time))))
    assert errors[1] < 1e-3 * 0.01 and 3.8 < errors[0] / errors[1] < 4.2, errors   # peak 0.01 m


@dataclass(frozen=True)
class SampledPD:
    """u = -(300 x + 5 v) of m6 on m2, sampled every 10 ms (zero-order hold)."""
    inputs: tuple = ("m6.x", "m6.v")
    outputs: tuple = ("m2.force",)
    sample_time: float = 0.01
    direct_feedthrough: bool = True

    def init(self, t0):
        return 0

    def step(self, t, y, state):
        return ControllerStep(np.array([-(300.0 * y[0] + 5.0 * y[1])]), state + 1)


def sampled_newmark(dt: float, h: float, *, restart: bool) -> np.ndarray:
    """Global average-acceleration Newmark of the seed chain with the held PD force; with
    ``restart`` the acceleration is recomputed after each jump of the held force (a_k^+)."""
    K = -SEED_A[3:, :3]
    C = -SEED_A[3:, 3:]
    x, v = SEED_X0[:3].copy(), SEED_X0[3:].copy()
    f = np.array([-(300.0 * x[2] + 5.0 * v[2]), 0.0, 0.0])
    a = f - C @ v - K @ x
    out, ratio = [x.copy()], int(round(h / dt))
    effective = K + 2 / dt * C + 4 / dt ** 2 * np.eye(3)
    for i in range(int(round(0.5 / dt))):
        if i and i % ratio == 0:
            new = np.array([-(300.0 * x[2] + 5.0 * v[2]), 0.0, 0.0])
            a = a + (new - f) if restart else a
            f = new
        x_new = np.linalg.solve(effective, f + 4 / dt ** 2 * x + 4 / dt * v + a + C @ (2 / dt * x + v))
        v, a = 2 / dt * (x_new - x) - v, 4 / dt ** 2 * (x_new - x) - 4 / dt * v - a
        x = x_new
        out.append(x.copy())
    return np.array(out)


def sampled_exact(h: float) -> np.ndarray:
    """The documented zero-order hold exactly: the plant's matrix exponential over each period."""
    Ad = sla.expm(SEED_A * h)
    Bd = np.linalg.solve(SEED_A, (Ad - np.eye(6)) @ SEED_B)
    z, out = SEED_X0.copy(), [SEED_X0[:3]]
    for _ in range(int(round(0.5 / h))):
        z = Ad @ z + Bd * -(300.0 * z[2] + 5.0 * z[5])
        out.append(z[:3])
    return np.array(out)


def cosimulated(dt: float, scheme: str = "newmark") -> np.ndarray:
    run = simulate_controlled(seed_plant(), 0.5, dt, x0={"m6": 0.01}, controllers=[SampledPD()], scheme=scheme)
    return np.column_stack([run[f"{m}.x"] for m in ("m2", "m4", "m6")])


def test_cosimulated_controller_equals_global_newmark_restarted_at_each_sample():
    """The DT-TMM equals the global scheme whose acceleration restarts at each jump of the held
    output.  Before the fix it equalled the scheme without restart (first order: 6.9e-4 m at
    dt = h/4, 3.2e-4 m at h/8 from the exact hold, for a 0.01 m peak)."""
    x = cosimulated(0.01 / 4)
    assert np.max(np.abs(x - sampled_newmark(0.01 / 4, 0.01, restart=True))) <= 1e-12
    assert np.max(np.abs(x - sampled_newmark(0.01 / 4, 0.01, restart=False))) > 1e-4   # the tests can tell


@pytest.mark.parametrize("scheme", ["newmark", "generalized_alpha", "wilson_theta"])
def test_cosimulated_zero_order_hold_converges_at_second_order(scheme):
    """Against the exact sampled loop (Newmark: 1.3e-4 m at dt = h/4, 3.3e-5 m at h/8; before the
    restart 3.0e-4 and 1.5e-4 m, and Wilson 5.5e-4, 2.7e-4 m: first order)."""
    exact = sampled_exact(0.01)
    errors = [np.max(np.abs(cosimulated(0.01 / m, scheme)[::m] - exact)) for m in (4, 8)]
    assert errors[0] / errors[1] > 3.5 and errors[1] < 1e-4, errors


@pytest.mark.parametrize("scheme", ["newmark", "generalized_alpha"])
def test_planar_implicit_pendulum_at_absurd_step_is_not_silent(scheme):
    from ctmm.planar import Pinned, PlanarModel, RigidBody, simulate_implicit
    from ctmm.schemes import GeneralizedAlpha, Newmark
    model = PlanarModel.chain("pendulum", [Pinned("o"), RigidBody.uniform_link("rod", mass=1.0, length=1.0)])
    # 6 periods per step: Newton may settle on a spurious root each step (the pendulum winds to
    # ~1e5 rad from rest at 0.1 rad, under the default divergence bound) -- warned before the run
    integrator = Newmark() if scheme == "newmark" else GeneralizedAlpha(0.5)
    with pytest.warns(StabilityLimitWarning, match=r"half the period of the slowest motion .* no motion is "
                                                   r"resolved; use dt <= 0\.8\d+ s"):
        simulate_implicit(model, [-math.pi / 2 + 0.1], [0.0], t_final=100.0, dt=10.0, scheme=integrator)
    with pytest.raises(ModelError, match="no motion is resolved"):
        simulate_implicit(model, [-math.pi / 2 + 0.1], [0.0], t_final=100.0, dt=10.0, scheme=integrator,
                          stability_check="error")
    with warnings.catch_warnings():                 # a step that resolves the swing: no warning
        warnings.simplefilter("error")
        run = simulate_implicit(model, [-math.pi / 2 + 0.1], [0.0], t_final=2.0, dt=0.05, scheme=integrator)
    assert np.max(np.abs(run.q[:, 0] + math.pi / 2)) <= 0.1 + 1e-6   # energy cannot grow


@pytest.mark.parametrize("theta", [1.1, 1.2, 1.3])
def test_wilson_theta_limit_against_the_global_recurrence(theta):
    """Below 1 - 2 % of the reported limit the global Wilson recurrence stays bounded, above it grows;
    ctmm warns above the limit and not below."""
    from ctmm.guard import StabilityLimitWarning, wilson_limit
    from ctmm.schemes import WilsonTheta
    limit = wilson_limit(theta)
    reference = GlobalChain([1.0], [100.0, 0.0], start="fixed", end="free")          # omega = 10 rad/s
    chain = ctmm.Chain("sdof", [Fixed("wall"), Spring("k", 100.0), Mass("m", 1.0), Free("tip")])
    for factor, grows in ((0.98, False), (1.02, True)):
        dt = factor * limit / 10.0
        x = step_global(reference, 3000 * dt, dt, [0.01], [0.0], scheme="wilson_theta", theta=theta).displacement
        with np.errstate(all="ignore"):
            assert (not np.all(np.abs(x[-100:]) < 0.02)) == grows, (theta, factor)
        with warnings.catch_warnings():
            warnings.simplefilter("error" if not grows else "ignore")
            if grows:
                with pytest.warns(StabilityLimitWarning):
                    ctmm.simulate(chain, 2 * dt, dt, x0={"m": 0.01}, scheme=WilsonTheta(theta))
            else:
                ctmm.simulate(chain, 2 * dt, dt, x0={"m": 0.01}, scheme=WilsonTheta(theta))


@pytest.mark.parametrize("delay", [0.0, 0.01, 0.2])
def test_uncontrolled_rigid_body_mode_is_reported_on_the_axis_not_counted(delay):
    """Velocity-only feedback on a free-free chain leaves det(K) = 0 and no position term: s = 0 is a
    root for every delay (the closed-loop state matrix below is singular).  The count must not
    pretend it is 0 (stable): it is the documented -1 (a root on Re s = 0), and the loop is not stable."""
    masses, ks, cs = [1.0, 1.3, 0.8], [900.0, 1100.0], [0.06, 0.07]
    body = [Free("a"), Mass("m0", masses[0])]
    for i, (k, c) in enumerate(zip(ks, cs)):
        body += [SpringDamper(f"k{i + 1}", k, c), Mass(f"m{i + 1}", masses[i + 1])]
    system = ControlledChain(ctmm.Chain("free_free", body + [Free("b")]),
                             [Feedback("L", "m2.v", "m0", gain=2.0, delay=delay)])
    M, C, K = matrices(masses, [0.0] + ks, [0.0] + cs, fixed_end=False)
    b, c = np.eye(3)[0], np.eye(3)[2]
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C + 2.0 * np.outer(b, c))]])
    assert np.min(np.abs(np.linalg.eigvals(A))) < 1e-9                     # s = 0 at zero delay too
    counts = unstable_root_count(system)
    assert counts.tolist() == [-1]
    margin = delay_margin(system)
    assert margin.unstable_roots_at_zero_delay == -1 and not margin.stable and margin.margin == 0.0
