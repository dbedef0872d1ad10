"""Independent beam references (ctmm.reference.beams) against published numbers and each other.

Sources: FORMULAS §2.3 (check 16), §2.4 (tension), §2.6 (βL tables, tip mass/inertia and
hub-beam roots), §6.1 (Kane-Ryan-Banerjee spin-up); Blevins (1979) Table 8-1 for the
asymptotics βn -> (2n-1)π/2 (clamped-free) and (2n+1)π/2 (clamped-clamped).
"""
from __future__ import annotations

import mpmath
import numpy as np
import pytest

from ctmm.errors import ModelError
from ctmm.reference.beams import (CASES, HermiteBeam, Section, beta_from_omega, beta_roots,
                                  cantilever_tip_receptance, clamped_free_mode, frequency_equation,
                                  kane_spinup, omega_from_beta, pinned_pinned_tension_frequencies,
                                  spinup_angle)


# --------------------------------------------------------------------------------------------
# frequency equations
# --------------------------------------------------------------------------------------------
def _mp_roots(equation, guesses):
    """30-digit roots of the *unscaled* classical equation (mpmath), independent of the code."""
    mpmath.mp.dps = 30
    return np.array([float(mpmath.findroot(equation, g)) for g in guesses])


MP_EQUATIONS = {
    "clamped-free": lambda b: 1 + mpmath.cos(b) * mpmath.cosh(b),
    "pinned-free": lambda b: mpmath.sin(b) * mpmath.cosh(b) - mpmath.cos(b) * mpmath.sinh(b),
    "free-free": lambda b: 1 - mpmath.cos(b) * mpmath.cosh(b),
    "pinned-pinned": mpmath.sin,
    "clamped-sliding": lambda b: mpmath.sin(b) * mpmath.cosh(b) + mpmath.cos(b) * mpmath.sinh(b),
    "pinned-sliding": mpmath.cos,
}
ALIASES = {"clamped-pinned": "pinned-free", "clamped-clamped": "free-free", "sliding-sliding": "pinned-pinned",
           "sliding-free": "clamped-sliding"}


@pytest.mark.parametrize("case", ["clamped-free", "pinned-free", "clamped-pinned", "free-free", "clamped-clamped",
                                  "pinned-pinned", "sliding-sliding", "clamped-sliding", "sliding-free",
                                  "pinned-sliding"])
def test_beta_roots_match_30_digit_roots(case):
    found = beta_roots(case, 12)
    np.testing.assert_allclose(found, _mp_roots(MP_EQUATIONS[ALIASES.get(case, case)], found), rtol=1e-14)


@pytest.mark.parametrize("case, expected, atol", [
    ("clamped-free", [1.8751040687, 4.6940911330, 7.8547574382, 10.9955407349, 14.1371683910], 6e-11),
    # FORMULAS prints 7.0685827500 and 10.2101761242; the 30-digit roots are 7.06858274563 and
    # 10.2101761228 (tan β = tanh β), so the table is good to 5e-9 only
    ("pinned-free", [3.9266023120, 7.0685827500, 10.2101761242, 13.3517687778], 5e-9),
    ("free-free", [4.7300407449, 7.8532046241, 10.9956078380, 14.1371654913], 6e-11),
    ("clamped-clamped", [4.7300407449, 7.8532046241, 10.9956078380, 14.1371654913], 6e-11),
    ("pinned-pinned", np.pi * np.arange(1, 5), 1e-13),
    ("pinned-sliding", np.pi * (np.arange(1, 5) - 0.5), 1e-13),
])
def test_beta_tables(case, expected, atol):
    """FORMULAS §2.6 (10 printed decimals)."""
    np.testing.assert_allclose(beta_roots(case, len(expected)), expected, rtol=0, atol=atol)


def test_tip_mass_and_hub_roots_match_30_digit_roots():
    mu, j, eta = 0.7, 0.03, 0.2
    c, s, ch, sh = mpmath.cos, mpmath.sin, mpmath.cosh, mpmath.sinh
    tip = lambda b: (1 + c(b) * ch(b) + mu * b * (c(b) * sh(b) - s(b) * ch(b))            # noqa: E731
                     - j * b ** 3 * (ch(b) * s(b) + sh(b) * c(b)) + mu * j * b ** 4 * (1 - c(b) * ch(b)))
    found = beta_roots("tip-mass", 6, tip_mass_ratio=mu, tip_inertia_ratio=j)
    np.testing.assert_allclose(found, _mp_roots(tip, found), rtol=1e-14)
    hub = lambda b: (c(b) * sh(b) - s(b) * ch(b)) - eta * b ** 3 * (1 + c(b) * ch(b))       # noqa: E731
    found = beta_roots("hub-beam", 6, hub_inertia_ratio=eta)
    np.testing.assert_allclose(found, _mp_roots(hub, found), rtol=1e-14)


def test_high_roots_approach_asymptotes_and_stay_finite():
    cf = beta_roots("clamped-free", 60)
    np.testing.assert_allclose(cf[10:], (2 * np.arange(11, 61) - 1) * np.pi / 2, rtol=0, atol=1e-9)
    assert cf[29] == pytest.approx(92.6769832809, abs=1e-10)     # FORMULAS §4.2, mode 30
    assert np.all(np.isfinite(frequency_equation("clamped-free", np.linspace(0, 2000, 50))))


def test_clamped_sliding_is_half_of_clamped_clamped_symmetric_modes():
    half = beta_roots("clamped-sliding", 3)
    full = beta_roots("clamped-clamped", 6)
    np.testing.assert_allclose(2 * half, full[0::2], rtol=1e-13)


@pytest.mark.parametrize("mu, j, expected", [
    (0.1, 0.0, [1.72274152, 4.39952282, 7.45105667]),
    (0.5, 0.0, [1.41996443, 4.11113339, 7.19033524]),
    (1.0, 0.0, [1.24791741, 4.03113944, 7.13413224]),
    (2.0, 0.0, [1.07619566, 3.98257329, 7.10265019]),
    (0.5, 0.05, [1.37061484, 2.86387572, 5.14624806]),
    (1.0, 0.1, [1.19566983, 2.50506002, 4.97509844]),
])
def test_tip_mass_roots(mu, j, expected):
    found = beta_roots("tip-mass", 3, tip_mass_ratio=mu, tip_inertia_ratio=j)
    np.testing.assert_allclose(found, expected, rtol=0, atol=6e-9)


@pytest.mark.parametrize("eta, expected", [
    (0.01, [3.64054172, 5.61599608, 8.08408694]),
    (0.1, [2.6389247, 4.79377085, 7.87565294]),
    (1.0, [2.01000332, 4.70379426, 7.85682355]),
    (10.0, [1.89007648, 4.69505831, 7.85496381]),
])
def test_hub_beam_roots(eta, expected):
    found = beta_roots("hub-beam", 3, hub_inertia_ratio=eta)
    np.testing.assert_allclose(found, expected, rtol=0, atol=6e-9)


def test_hub_beam_limits():
    """η -> ∞: clamped-free; η -> 0: pinned-free."""
    np.testing.assert_allclose(beta_roots("hub-beam", 3, hub_inertia_ratio=1e9), beta_roots("clamped-free", 3),
                               rtol=1e-8)
    np.testing.assert_allclose(beta_roots("hub-beam", 3, hub_inertia_ratio=1e-12), beta_roots("pinned-free", 3),
                               rtol=1e-8)


def test_omega_beta_round_trip():
    beta = np.array([1.5, 4.0])
    omega = omega_from_beta(beta, 1.3, 2.3, 0.7)
    np.testing.assert_allclose(beta_from_omega(omega, 1.3, 2.3, 0.7), beta, rtol=1e-15)


def test_errors_list_cases_and_check_counts():
    with pytest.raises(ModelError, match="unknown beam case 'clamped-clamped-free'; available: clamped-free"):
        beta_roots("clamped-clamped-free", 3)
    with pytest.raises(ModelError, match="count must be an integer >= 1, got 0"):
        beta_roots("clamped-free", 0)
    with pytest.raises(ModelError, match="tip_mass_ratio must be finite and >= 0"):
        beta_roots("tip-mass", 2, tip_mass_ratio=-1.0)
    assert set(CASES) >= {"clamped-free", "pinned-free", "free-free", "clamped-clamped", "pinned-pinned",
                          "tip-mass", "hub-beam"}


# --------------------------------------------------------------------------------------------
# mode shapes and the analytic receptance
# --------------------------------------------------------------------------------------------
def test_clamped_free_modes_are_normalised_orthogonal_and_satisfy_boundary_conditions():
    betas = beta_roots("clamped-free", 25)
    x, w = np.polynomial.legendre.leggauss(600)
    xi, w = (x + 1) / 2, w / 2
    phi = np.array([clamped_free_mode(b, xi) for b in betas])
    gram = (phi * w) @ phi.T
    np.testing.assert_allclose(gram, np.eye(25), atol=2e-12)
    for b in betas:
        assert abs(clamped_free_mode(b, 0.0)) < 1e-13 and abs(clamped_free_mode(b, 0.0, 1)) < 1e-12 * b
        assert abs(clamped_free_mode(b, 1.0, 2)) < 1e-12 * b ** 2
        assert abs(clamped_free_mode(b, 1.0, 3)) < 1e-11 * b ** 3
        assert abs(clamped_free_mode(b, 1.0)) == pytest.approx(2.0, rel=1e-12)
    # φ'''' = β^4 φ checked by finite differences of φ''
    b, h = betas[2], 1e-4
    xi0 = np.array([0.3, 0.7])
    fourth = (clamped_free_mode(b, xi0 + h, 2) - 2 * clamped_free_mode(b, xi0, 2) + clamped_free_mode(b, xi0 - h, 2)) / h ** 2
    np.testing.assert_allclose(fourth, b ** 4 * clamped_free_mode(b, xi0), rtol=1e-6)


def test_cantilever_receptance_static_limit_and_modal_sum():
    L, EI, rhoA = 1.3, 2.3, 0.7
    assert cantilever_tip_receptance(0.0, L, EI, rhoA) == pytest.approx(L ** 3 / (3 * EI), rel=1e-15)
    assert cantilever_tip_receptance(1e-6, L, EI, rhoA) == pytest.approx(L ** 3 / (3 * EI), rel=1e-12)
    # modal sum with static correction: α(ω) = α(0) + Σ φ(1)^2/(m) (1/(ωn²-ω²) - 1/ωn²)
    omega = 5.0
    betas = beta_roots("clamped-free", 200)
    wn = omega_from_beta(betas, L, EI, rhoA)
    modal = L ** 3 / (3 * EI) + np.sum(4.0 / (rhoA * L) * (1 / (wn ** 2 - omega ** 2) - 1 / wn ** 2))
    assert cantilever_tip_receptance(omega, L, EI, rhoA) == pytest.approx(modal, rel=1e-12)


# --------------------------------------------------------------------------------------------
# Hermite finite elements
# --------------------------------------------------------------------------------------------
def test_fe_check16_numbers():
    """FORMULAS §2.3 check 16 (FEM with 60 Hermite elements agrees to 2e-7 relative)."""
    section = [Section(1.9, 2.3, 0.7)]
    root = HermiteBeam(section, left="pinned", right="free", springs=[(0.0, 0.0, 5.0)], elements=60)
    np.testing.assert_allclose(root.frequencies(3), [1.2536848, 8.9888012, 26.6580406], rtol=2e-7)
    span = HermiteBeam(section, left="clamped", right="free", hinges=[(0.76, 3.0)], springs=[(1.9, 4.0, 0.0)],
                       elements=60)
    np.testing.assert_allclose(span.frequencies(3), [3.6910028, 9.7587229, 28.6155868], rtol=2e-7)
    assert "theta" + str(int(np.argmin(np.abs(span.nodes - 0.76)))) + "+" in span.dof_names


@pytest.mark.parametrize("left, right, case, n_rigid", [
    ("clamped", "free", "clamped-free", 0), ("pinned", "pinned", "pinned-pinned", 0),
    ("free", "free", "free-free", 2), ("clamped", "clamped", "clamped-clamped", 0),
    ("clamped", "sliding", "clamped-sliding", 0), ("sliding", "free", "sliding-free", 1),
])
def test_fe_converges_to_beta_tables(left, right, case, n_rigid):
    L, EI, rhoA = 1.3, 2.3, 0.7
    fe = HermiteBeam([Section(L, EI, rhoA)], left=left, right=right, elements=60)
    omega = fe.frequencies(n_rigid + 4)
    np.testing.assert_allclose(omega[:n_rigid], 0.0, atol=2e-3)   # eigh round-off: ω^2 ~ 1e-7
    exact = omega_from_beta(beta_roots(case, 4), L, EI, rhoA)
    rel = omega[n_rigid:] / exact - 1
    assert np.all(rel > -1e-8) and np.all(rel < 5e-6)         # conforming FE: from above


def test_fe_tip_mass_hub_tension_and_multi_section():
    L, EI, rhoA = 1.0, 1.0, 1.0
    tip = HermiteBeam([Section(L, EI, rhoA)], point_masses=[(L, 1.0, 0.1)], elements=80)
    np.testing.assert_allclose(tip.frequencies(3), beta_roots("tip-mass", 3, tip_mass_ratio=1.0,
                                                              tip_inertia_ratio=0.1) ** 2, rtol=1e-7)
    hub = HermiteBeam([Section(L, EI, rhoA)], left="pinned", point_masses=[(0.0, 0.0, 0.1)], elements=80)
    omega = hub.frequencies(4)
    assert omega[0] < 2e-3
    np.testing.assert_allclose(omega[1:], beta_roots("hub-beam", 3, hub_inertia_ratio=0.1) ** 2, rtol=1e-7)
    tension = HermiteBeam([Section(1.5, 2.0, 0.5, 30.0)], left="pinned", right="pinned", elements=100)
    np.testing.assert_allclose(tension.frequencies(4), pinned_pinned_tension_frequencies(4, 1.5, 2.0, 0.5, 30.0),
                               rtol=2e-7)
    two = HermiteBeam([Section(0.6, EI, rhoA), Section(0.4, EI, rhoA)], elements=80)
    np.testing.assert_allclose(two.frequencies(3), tip.frequencies(3) * 0 + omega_from_beta(
        beta_roots("clamped-free", 3), L, EI, rhoA), rtol=1e-7)


def test_fe_receptance_matches_analytic_cantilever():
    L, EI, rhoA = 1.3, 2.3, 0.7
    fe = HermiteBeam([Section(L, EI, rhoA)], elements=100)
    omega = np.array([0.0, 2.0, 20.0, 60.0])
    np.testing.assert_allclose(fe.receptance(omega, force_at=L, response_at=L),
                               cantilever_tip_receptance(omega, L, EI, rhoA), rtol=1e-6)
    moment = fe.receptance([0.0], force_at=L, response_at=L, load="theta", response="w")
    assert moment[0].real == pytest.approx(L ** 2 / (2 * EI), rel=1e-8)


def test_fe_errors():
    with pytest.raises(ModelError, match="Section: bending_stiffness must be > 0, got 0"):
        Section(1.0, 0.0, 1.0)
    with pytest.raises(ModelError, match="left must be one of clamped, pinned, free, sliding, got 'hinged'"):
        HermiteBeam([Section(1.0, 1.0, 1.0)], left="hinged")
    with pytest.raises(ModelError, match=r"hinge position must be inside \(0, L\)"):
        HermiteBeam([Section(1.0, 1.0, 1.0)], hinges=[(1.0, 2.0)])
    with pytest.raises(ModelError, match="point mass position must be in"):
        HermiteBeam([Section(1.0, 1.0, 1.0)], point_masses=[(1.5, 1.0, 0.0)])
    with pytest.raises(ModelError, match="w at x = 0.0 is constrained"):
        HermiteBeam([Section(1.0, 1.0, 1.0)]).receptance([1.0], force_at=0.0, response_at=1.0)


# --------------------------------------------------------------------------------------------
# Kane-Ryan-Banerjee spin-up (FORMULAS §6.1)
# --------------------------------------------------------------------------------------------
def test_spinup_angle_law():
    t = np.linspace(0, 20, 2001)
    theta, rate, accel = spinup_angle(t)
    assert theta[0] == 0 and rate[0] == 0 and accel[0] == 0
    i = np.searchsorted(t, 15.0)
    assert rate[i] == pytest.approx(6.0) and theta[i] == pytest.approx(6.0 * 7.5)
    np.testing.assert_allclose(np.gradient(theta, t)[5:-5], rate[5:-5], atol=2e-4)
    np.testing.assert_allclose(np.gradient(rate, t)[5:-5], accel[5:-5], atol=2e-3)
    np.testing.assert_allclose(rate[t > 15], 6.0)


@pytest.fixture(scope="module")
def spinup_runs():
    t_eval = np.linspace(0.0, 20.0, 801)
    return {n: kane_spinup(n_modes=n, t_eval=t_eval) for n in (3, 5)}


def test_spinup_with_geometric_stiffening_stays_bounded(spinup_runs):
    result = spinup_runs[5]
    assert result.first_frequency == pytest.approx(1.8751040687 ** 2 * np.sqrt(1.4e4 / (1.2 * 1e4)), rel=1e-10)
    assert result.first_frequency == pytest.approx(3.80, abs=0.01)
    lag = result.tip_deflection.min()
    assert -0.65 < lag < -0.5                                # "peak lag of roughly half a metre"
    assert 6.0 < result.t[np.argmin(result.tip_deflection)] < 7.5
    assert np.max(np.abs(result.tip_deflection[result.t > 15])) < 0.05   # settles once θ' is constant
    # converged in the number of assumed modes
    np.testing.assert_allclose(spinup_runs[3].tip_deflection, result.tip_deflection, atol=5e-4)
    KG = result.matrices["KG"]
    np.testing.assert_allclose(KG, KG.T, atol=1e-12)
    assert np.all(np.linalg.eigvalsh(KG) > 0)


def test_spinup_without_geometric_stiffening_diverges_after_first_frequency():
    t_eval = np.linspace(0.0, 20.0, 801)
    result = kane_spinup(n_modes=3, geometric_stiffening=False, t_eval=t_eval)
    crossing = result.t[np.argmax(result.hub_rate > result.first_frequency)]
    assert 8.0 < crossing < 9.0
    before = np.abs(result.tip_deflection[result.t < crossing]).max()
    assert before < 5.0                                      # large (softening) but finite
    assert np.abs(result.tip_deflection[-1]) > 1e6 * before
    # exponential growth at rate sqrt(Ω^2 - ω1^2) once θ' = Ω is constant (mode 1 decoupled)
    late = (result.t > 17) & (result.t < 20)
    envelope = np.log(np.abs(result.tip_deflection[late]))
    slope = np.polyfit(result.t[late], envelope, 1)[0]
    assert slope == pytest.approx(np.sqrt(36.0 - result.first_frequency ** 2), rel=1e-2)


def test_spinup_errors():
    with pytest.raises(ModelError, match="n_modes must be an integer >= 1, got 0"):
        kane_spinup(n_modes=0)
    with pytest.raises(ModelError, match="length must be > 0, got -1"):
        kane_spinup(length=-1)
