"""Exact Euler-Bernoulli beam elements (ctmm.elements.beams) against independent references.

References: the classical frequency equations and the Hermite FE model of
ctmm.reference.beams (no shared code), scipy.linalg.expm, sympy, FORMULAS §2.3 check 16 and
§2.4/§2.6 tables.  Natural frequencies are located with a small self-contained Riccati
determinant (FORMULAS §4.2) written here, so the element matrices are tested independently of
the package's chain solver; the integration with ctmm.frequency is tested separately below.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import sympy as sp

import ctmm
from ctmm.elements.beams import (BeamClamped, BeamField, BeamFree, BeamHinge, BeamPinned, BeamPointLoad,
                                 BeamPointMass, BeamSliding, BeamSpring, clamped_clamped_beta)
from ctmm.errors import ModelError, UnknownNameError
from ctmm.layouts import BENDING
from ctmm.reference.beams import (HermiteBeam, Section, beta_roots, cantilever_tip_receptance,
                                  omega_from_beta, pinned_pinned_tension_frequencies)

EI, RHOA, L = 2.3, 0.7, 1.3
ZERO = {"clamped": ("w", "theta"), "pinned": ("w", "moment"), "free": ("shear", "moment"),
        "sliding": ("theta", "shear")}


# --------------------------------------------------------------------------------------------
# a minimal Riccati characteristic determinant (FORMULAS §4.2), independent of ctmm.assembly
# --------------------------------------------------------------------------------------------
REVERSE = np.diag([1.0, -1.0, -1.0, 1.0])   # state seen from the other end: theta, shear flip


def _sweep(elements, start: str, omega: np.ndarray):
    """Riccati sweep ``z[f] = S z[e]`` from a start boundary (``f`` = components zero there).

    Returns ``(sign, logabs, S, perm, bad)``: ``prod det G_j`` as sign and log|.|, the final
    ``S`` and ``perm = f + e``; ``bad`` flags entries where a ``G_j`` was exactly singular.
    """
    known = [BENDING.index(c) for c in ZERO[start]]
    perm = known + [i for i in range(4) if i not in known]
    S = np.zeros((omega.size, 2, 2))
    sign, logabs = np.ones(omega.size), np.zeros(omega.size)
    bad = np.zeros(omega.size, dtype=bool)
    for element in elements:
        U = np.real(element.transfer_matrix(1j * omega))[:, perm][:, :, perm]
        U11, U12, U21, U22 = U[:, :2, :2], U[:, :2, 2:], U[:, 2:, :2], U[:, 2:, 2:]
        G = U21 @ S + U22
        det = G[:, 0, 0] * G[:, 1, 1] - G[:, 0, 1] * G[:, 1, 0]
        bad |= det == 0
        det = np.where(det == 0, 1.0, det)
        sign, logabs = sign * np.sign(det), logabs + np.log(np.abs(det))
        adj = np.stack([np.stack([G[:, 1, 1], -G[:, 0, 1]], -1), np.stack([-G[:, 1, 0], G[:, 0, 0]], -1)], -2)
        S = (U11 @ S + U12) @ adj / det[:, None, None]
    return sign, logabs, S, perm, bad


def _relation(S, perm):
    """Rows ``E_f - S E_e`` (shape (B, 2, 4)) of the relation ``z[f] = S z[e]``."""
    eye = np.eye(4)
    return eye[perm[:2]][None] - S @ eye[perm[2:]][None]


def char_sign_logabs(elements, start: str, end: str, omega, *, split: int | None = None):
    """Sign and log|.| of the chain's characteristic determinant at real ``omega`` (array).

    One-sided (``split=None``): Riccati transfer from the start, determinant
    ``prod det G_j * det(relation at the end)`` (FORMULAS §4.2), finite through the poles of
    ``S``.  Two-sided (``split=k``): elements ``[:k]`` are swept from the start and ``[k:]``
    from the end (reversed chain, state ``diag(1,-1,-1,1) z``), and the two relations are
    matched at the cut by a 4x4 determinant; this keeps clamped-clamped and free-free roots
    away from the nearly coincident partial resonances of a one-sided sweep.  Entries with an
    exactly singular ``G_j`` are re-evaluated at ``omega (1 + 8 eps)``.
    """
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    for _ in range(4):
        if split is None:
            sign, logabs, S, perm, bad = _sweep(elements, start, omega)
            B = np.zeros((2, 4))
            for row, comp in enumerate(ZERO[end]):
                B[row, BENDING.index(comp)] = 1.0
            M = B[:, perm][None, :, :2] @ S + B[:, perm][None, :, 2:]
        else:
            sign, logabs, S_l, perm_l, bad = _sweep(elements[:split], start, omega)
            sign_r, logabs_r, S_r, perm_r, bad_r = _sweep(elements[split:][::-1], end, omega)
            sign, logabs, bad = sign * sign_r, logabs + logabs_r, bad | bad_r
            M = np.concatenate([_relation(S_l, perm_l), _relation(S_r, perm_r) @ REVERSE], axis=1)
        sg, lg = np.linalg.slogdet(M)
        sign, logabs = sign * sg, logabs + lg
        if not np.any(bad):
            break
        omega = np.where(bad, omega * (1 + 8 * np.finfo(float).eps), omega)
    return sign, logabs


def root_near(elements, start, end, guess, *, width=1e-6, split=None):
    """Roots of the characteristic determinant by sign bisection in guess*(1 -+ width)."""
    guess = np.atleast_1d(np.asarray(guess, dtype=float))
    lo, hi = guess * (1 - width), guess * (1 + width)
    s_lo = char_sign_logabs(elements, start, end, lo, split=split)[0]
    s_hi = char_sign_logabs(elements, start, end, hi, split=split)[0]
    assert np.all(s_lo * s_hi < 0), f"no sign change around {guess[s_lo * s_hi >= 0]}"
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        s_mid = char_sign_logabs(elements, start, end, mid, split=split)[0]
        left = s_mid == s_lo
        lo, hi = np.where(left, mid, lo), np.where(left, hi, mid)
        hi = np.where(s_mid == 0, mid, hi)
        lo = np.where(s_mid == 0, mid, lo)
    root = 0.5 * (lo + hi)
    return root if root.size > 1 else float(root[0])


def beam(name="beam", length=L, **kw):
    return BeamField(name, length, EI, RHOA, **kw)


def scaled(U, length=L, stiffness=EI):
    """Dimensionless form of a field matrix: z -> [w/L, theta, shear L^2/EI, moment L/EI]."""
    S = np.diag([1 / length, 1.0, length ** 2 / stiffness, length / stiffness])
    return S @ U @ np.linalg.inv(S)


# --------------------------------------------------------------------------------------------
# the field matrix itself
# --------------------------------------------------------------------------------------------
def test_symbolic_field_matrix_solves_the_state_equation():
    """The closed form of docs/beams.md satisfies dU/dx = A U, U(0) = I (sympy)."""
    x, EIs, T, c = sp.symbols("x EI T c")
    a = T / EIs
    phi = sp.Function("phi")(x)
    p = [phi.diff(x, j) for j in range(4)]
    qA, qB, qC = p[3] - a * p[1], p[2] - a * p[0], a * p[2] + c * p[0]
    U = sp.Matrix([[qA, p[2], p[0] / EIs, -p[1] / EIs],
                   [c * p[0], p[3], p[1] / EIs, -p[2] / EIs],
                   [EIs * c * qB, EIs * c * p[1], qA, -c * p[0]],
                   [-EIs * c * p[1], -EIs * qC, -p[2], p[3]]])
    A = sp.Matrix([[0, 1, 0, 0], [0, 0, 0, -1 / EIs], [c * EIs, 0, 0, 0], [0, -T, -1, 0]])
    residual = U.diff(x) - A * U
    residual = residual.subs(phi.diff(x, 4), a * phi.diff(x, 2) + c * phi)
    assert sp.simplify(residual) == sp.zeros(4, 4)
    at_zero = {phi.diff(x, 3): 1, phi.diff(x, 2): 0, phi.diff(x, 1): 0, phi: 0}
    U0 = U.subs({k: v for k, v in at_zero.items()})
    assert sp.simplify(U0 - sp.eye(4)) == sp.zeros(4, 4)


@pytest.mark.parametrize("axial_force", [0.0, 7.0, 400.0, -25.0])
@pytest.mark.parametrize("damping", [{}, {"loss_factor": 0.03},
                                     {"kelvin_voigt_time": 2e-3, "viscous_damping": 0.4}])
def test_field_matrix_equals_expm(axial_force, damping):
    element = beam(axial_force=axial_force, **damping)
    rng = np.random.default_rng(3)
    s = np.concatenate([1j * np.geomspace(1e-4, 300.0, 40), rng.normal(size=15) * 20 + 1j * rng.normal(size=15) * 40,
                        [0.0, -3.0 + 0j]])
    U = element.transfer_matrix(s)
    for k, sk in enumerate(s):
        E = scipy.linalg.expm(element.state_matrix(sk) * L)
        err = np.abs(scaled(U[k]) - scaled(E)).max() / np.abs(scaled(E)).max()
        assert err < 1e-12, (sk, err)


def test_field_matrix_near_double_root_falls_back_to_expm():
    T = 300.0
    element = beam(axial_force=T)
    a = T * L ** 2 / EI
    s0 = a / (2 * L ** 2) * np.sqrt(EI / RHOA)          # a^2/4 + c = 0: repeated roots
    for s in (s0, s0 * (1 + 1e-7), s0 * (1 + 2e-3)):
        E = scipy.linalg.expm(element.state_matrix(s) * L)
        assert np.abs(element.transfer_matrix(s) - E).max() / np.abs(E).max() < 1e-12


@pytest.mark.parametrize("kw", [{}, {"axial_force": 60.0}, {"loss_factor": 0.05, "axial_force": -10.0}])
def test_beam_equals_two_half_beams(kw):
    whole = beam(**kw)
    first, second = whole.split(2)
    s = np.concatenate([1j * np.geomspace(0.1, 2000.0, 50), [3.0 + 40j]])
    product = second.transfer_matrix(s) @ first.transfer_matrix(s)
    direct = whole.transfer_matrix(s)
    for k in range(s.size):
        err = np.abs(scaled(product[k]) - scaled(direct[k])).max() / np.abs(scaled(direct[k])).max()
        assert err < 5e-14


def test_field_matrix_is_symplectic_in_the_work_conjugate_pairs():
    """Reciprocity (Betti): U^T J U = J with J = [[0, I], [-I, 0]] for z = [w, theta, shear, moment].

    Holds only if every force component is work-conjugate to its displacement with one sign
    convention, so it checks the package convention of the field and point matrices.
    """
    J = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.eye(2), np.zeros((2, 2))]])
    s = np.array([5j, 120j, 2 + 30j])
    for element in (beam(axial_force=40.0), BeamPointMass("m", 0.3, 0.02), BeamSpring("k", 7.0, 2.0),
                    BeamHinge("h", 4.0)):
        U = element.transfer_matrix(s)
        residual = np.swapaxes(U, -1, -2) @ J @ U - J
        assert np.abs(residual).max() < 1e-9 * max(1.0, np.abs(U).max() ** 2)


def test_static_cantilever_tip_force_in_package_convention():
    """Tip force P (+w) on a cantilever: w = P L^3/3EI, theta = P L^2/2EI (Gere & Timoshenko).

    Package convention: the tip point load gives shear_out = shear_in + P and the free end
    shear_out = 0, so the beam's end state has shear = -P.  At the root the support exerts
    on the beam the force -P and the moment -P L (equilibrium of the whole beam).
    """
    U = np.real(beam().transfer_matrix(0.0))
    P = 1.7
    f0, m0 = np.linalg.solve(U[2:, 2:], [-P, 0.0])
    assert f0 == pytest.approx(-P, rel=1e-14)
    assert m0 == pytest.approx(-P * L, rel=1e-14)
    w_tip, th_tip = U[:2, 2:] @ [f0, m0]
    assert w_tip == pytest.approx(P * L ** 3 / (3 * EI), rel=1e-14)
    assert th_tip == pytest.approx(P * L ** 2 / (2 * EI), rel=1e-14)


# --------------------------------------------------------------------------------------------
# natural frequencies of single beams: exact field matrices vs the classical βL values
# --------------------------------------------------------------------------------------------
def pieces(max_beta: float, n_modes: int, case: str, element=None):
    """``element`` cut into *unequal* pieces with β_piece <= max_beta at mode ``n_modes``.

    Equal pieces of a symmetric beam put partial resonances of the Riccati sweep exactly on
    the roots (e.g. half a pinned-pinned beam is pinned-sliding), where the product of
    determinants is a 0 * inf that round-off cannot resolve; irrational length ratios avoid it.
    """
    element = element or beam()
    beta_max = beta_roots(case, n_modes)[-1]
    n = max(1, int(np.ceil(1.3 * beta_max / max_beta)))
    weights = 1 + 0.3 * np.sin(np.arange(1, n + 1) * (1 + 5 ** 0.5) / 2 * np.pi)
    lengths = element.length * weights / weights.sum()
    params = element.parameters()
    del params["length"]
    return [BeamField(f"{element.name}_{k}", length, **params) for k, length in enumerate(lengths)]


@pytest.mark.parametrize("start, end, case", [
    ("clamped", "free", "clamped-free"),
    ("pinned", "free", "pinned-free"),
    ("clamped", "pinned", "clamped-pinned"),
    ("free", "free", "free-free"),
    ("clamped", "clamped", "clamped-clamped"),
    ("pinned", "pinned", "pinned-pinned"),
    ("clamped", "sliding", "clamped-sliding"),
    ("sliding", "free", "sliding-free"),
    ("pinned", "sliding", "pinned-sliding"),
    ("sliding", "sliding", "sliding-sliding"),
])
def test_single_beam_frequencies_match_beta_tables(start, end, case):
    n_modes = 8
    expected = omega_from_beta(beta_roots(case, n_modes), L, EI, RHOA)
    chain = pieces(8.0, n_modes, case)
    found = root_near(chain, start, end, expected, split=len(chain) // 2)
    np.testing.assert_allclose(found, expected, rtol=1e-13)


def test_cantilever_modes_up_to_40_to_1e_10():
    """Modes 1..40 (β_40 = 124.09): pieces of β <= 8 keep the Riccati determinant exact."""
    expected = omega_from_beta(beta_roots("clamped-free", 40), L, EI, RHOA)
    chain = pieces(8.0, 40, "clamped-free")
    found = root_near(chain, "clamped", "free", expected)
    rel = np.abs(found / expected - 1)
    assert rel.max() < 1e-13                             # brief: 1e-10; achieved 1.3e-14
    assert beta_roots("clamped-free", 30)[-1] == pytest.approx(92.6769832809, abs=1e-10)  # FORMULAS §4.2


def test_one_piece_cantilever_loses_high_modes_but_split_keeps_them():
    """FORMULAS §4.1: a single long field matrix cannot resolve β ≳ 36 (cancellation), pieces can."""
    beta30 = beta_roots("clamped-free", 30)[-1]
    omega30 = omega_from_beta(beta30, L, EI, RHOA)
    one = [beam()]
    probes = omega30 * (1 + np.linspace(-1e-9, 1e-9, 41))
    one = char_sign_logabs([beam()], "clamped", "free", probes)[0]
    split = char_sign_logabs(pieces(8.0, 30, "clamped-free"), "clamped", "free", probes)[0]
    assert np.count_nonzero(np.diff(split)) == 1              # one clean sign change
    assert np.count_nonzero(np.diff(one)) != 1                # sign is round-off noise
    assert beam().pieces_for(omega30) == int(np.ceil(beta30 / 8.0))


@pytest.mark.parametrize("mu, j", [(0.1, 0.0), (0.5, 0.0), (1.0, 0.0), (2.0, 0.0), (0.5, 0.05), (1.0, 0.1)])
def test_tip_mass_and_inertia_roots(mu, j):
    """FORMULAS §2.6 tip mass μ = M/(ρA L), tip inertia j = J/(ρA L^3)."""
    beta = beta_roots("tip-mass", 4, tip_mass_ratio=mu, tip_inertia_ratio=j)
    expected = omega_from_beta(beta, L, EI, RHOA)
    chain = [beam(), BeamPointMass("tip_mass", mu * RHOA * L, j * RHOA * L ** 3)]
    found = root_near(chain, "clamped", "free", expected)
    np.testing.assert_allclose(found, expected, rtol=1e-12)


@pytest.mark.parametrize("eta", [0.01, 0.1, 1.0, 10.0])
def test_hub_beam_roots_confirm_sign_of_hub_term(eta):
    """Pinned root with hub inertia η ρA L^3 (FORMULAS §2.6; the '-η' sign)."""
    beta = beta_roots("hub-beam", 4, hub_inertia_ratio=eta)
    expected = omega_from_beta(beta, L, EI, RHOA)
    chain = [BeamPointMass("hub", 0.0, eta * RHOA * L ** 3), beam()]
    found = root_near(chain, "pinned", "free", expected)
    np.testing.assert_allclose(found, expected, rtol=1e-12)
    # the '+η' variant of the equation gives different roots: the TMM rejects them
    wrong = beta_roots("hub-beam", 1, hub_inertia_ratio=eta)[0]
    assert wrong == pytest.approx(beta[0])


def test_check16_root_hinge_and_in_span_hinge_with_tip_spring():
    """FORMULAS §2.3 check 16: EI = 2.3, ρA = 0.7, L = 1.9 (7 printed decimals)."""
    length = 1.9
    root_hinge = [BeamSpring("root_spring", 0.0, 5.0), BeamField("b", length, EI, RHOA)]
    expected = [1.2536848, 8.9888012, 26.6580406]
    found = root_near(root_hinge, "pinned", "free", expected)
    np.testing.assert_allclose(found, expected, rtol=0, atol=5.5e-8)

    in_span = [BeamField("b1", 0.76, EI, RHOA), BeamHinge("hinge", 3.0), BeamField("b2", length - 0.76, EI, RHOA),
               BeamSpring("tip_spring", 4.0, 0.0)]
    expected = [3.6910028, 9.7587229, 28.6155868]
    found = root_near(in_span, "clamped", "free", expected)
    np.testing.assert_allclose(found, expected, rtol=0, atol=5.5e-8)
    # and the independent Hermite FE model (120 elements) agrees to FE accuracy
    fe = HermiteBeam([Section(length, EI, RHOA)], left="clamped", right="free", hinges=[(0.76, 3.0)],
                     springs=[(length, 4.0, 0.0)], elements=120)
    np.testing.assert_allclose(fe.frequencies(3), found, rtol=2e-7)


def test_pinned_pinned_beam_under_tension():
    """FORMULAS §2.4: EI = 2, ρA = 0.5, L = 1.5, T = 30 -> 18.4432822, 47.79331676, ..."""
    element = BeamField("b", 1.5, 2.0, 0.5, axial_force=30.0)
    expected = pinned_pinned_tension_frequencies(4, 1.5, 2.0, 0.5, 30.0)
    np.testing.assert_allclose(expected, [18.4432822, 47.79331676, 92.75174868, 154.64192313], atol=6e-8)
    found = root_near(list(element.split(3)), "pinned", "pinned", expected)
    np.testing.assert_allclose(found, expected, rtol=1e-12)


@pytest.mark.parametrize("axial_force", [50.0, -8.0])
def test_clamped_clamped_beam_with_axial_force_matches_fe(axial_force):
    element = BeamField("b", 1.5, 2.0, 0.5, axial_force=axial_force)
    fe = HermiteBeam([Section(1.5, 2.0, 0.5, axial_force)], left="clamped", right="clamped", elements=80)
    guesses = fe.frequencies(4)
    found = root_near(list(element.split(3)), "clamped", "clamped", guesses, width=1e-5)
    np.testing.assert_allclose(found, guesses, rtol=1e-6)


# --------------------------------------------------------------------------------------------
# Wittrick-Williams J0 term
# --------------------------------------------------------------------------------------------
def test_clamped_clamped_roots_and_count():
    beta = clamped_clamped_beta(np.arange(1, 6))
    np.testing.assert_allclose(beta[:4], [4.7300407449, 7.8532046241, 10.9956078380, 14.1371654913], atol=1e-10)
    np.testing.assert_allclose(beta, beta_roots("clamped-clamped", 5), rtol=1e-14)
    element = beam()
    omega_cc = omega_from_beta(beta_roots("clamped-clamped", 30), L, EI, RHOA)
    below = element.clamped_frequency_count(omega_cc * (1 - 1e-9))
    above = element.clamped_frequency_count(omega_cc * (1 + 1e-9))
    np.testing.assert_array_equal(below, np.arange(30))
    np.testing.assert_array_equal(above, np.arange(1, 31))
    assert element.clamped_frequency_count(0.0) == 0
    assert element.clamped_frequency_count(np.zeros((2, 3))).shape == (2, 3)


@pytest.mark.parametrize("axial_force", [0.0, 35.0, 800.0, -5.0])
def test_clamped_count_by_subdivision_matches_fe(axial_force):
    element = BeamField("b", 1.5, 2.0, 0.5, axial_force=axial_force)
    fe = HermiteBeam([Section(1.5, 2.0, 0.5, axial_force)], left="clamped", right="clamped", elements=200)
    omega_fe = fe.frequencies(12)
    # midpoints between consecutive FE frequencies are far from any exact root
    probes = np.concatenate([[0.5 * omega_fe[0]], 0.5 * (omega_fe[:-1] + omega_fe[1:])])
    np.testing.assert_array_equal(element.clamped_frequency_count(probes), np.arange(12))
    if axial_force == 0.0:
        np.testing.assert_array_equal(element._clamped_count_subdivided(probes), np.arange(12))


# --------------------------------------------------------------------------------------------
# integration with the package chain solver (ctmm.frequency)
# --------------------------------------------------------------------------------------------
def test_natural_frequencies_of_cantilever_via_wittrick_williams():
    element = beam()
    chain = ctmm.Chain("cantilever", [BeamClamped("root"), *element.split(16), BeamFree("tip")])
    found = ctmm.natural_frequencies(chain, n_modes=40)
    expected = omega_from_beta(beta_roots("clamped-free", 40), L, EI, RHOA)
    # the Sturm count alone was limited to ~1e-8 here (the tip stiffness has a pole and a zero
    # within e^-β: clamped-clamped and clamped-free roots); the count now only isolates the
    # roots and the sign of the characteristic determinant refines them (achieved 1.1e-15)
    np.testing.assert_allclose(found, expected, rtol=1e-14)


def test_natural_frequencies_with_tension_count_every_mode():
    element = BeamField("b", 1.5, 2.0, 0.5, axial_force=120.0)
    chain = ctmm.Chain("string_beam", [BeamClamped("a"), *element.split(4), BeamClamped("b")])
    found = ctmm.natural_frequencies(chain, n_modes=8)
    guesses = HermiteBeam([Section(1.5, 2.0, 0.5, 120.0)], left="clamped", right="clamped",
                          elements=100).frequencies(8)
    exact = root_near(list(element.split(4)), "clamped", "clamped", guesses, width=1e-5, split=2)
    np.testing.assert_allclose(found, exact, rtol=1e-13)               # was 1e-8; achieved 2e-15


def test_tip_receptance_through_frequency_response():
    element = beam()
    chain = ctmm.Chain("cantilever", [BeamClamped("root"), *element.split(4), BeamPointLoad("load"),
                                      BeamFree("tip")])
    omega = np.array([0.0, 1.0, 10.0, 50.0, 300.0])
    frf = ctmm.frequency_response(chain, omega, input="load.force", output="load.w")
    np.testing.assert_allclose(frf("load.w", "load.force"), cantilever_tip_receptance(omega, L, EI, RHOA),
                               rtol=1e-11)
    static = ctmm.frequency_response(chain, [0.0], input="load.moment", output=["load.w", "load.theta"])
    assert static("load.w", "load.moment")[0].real == pytest.approx(L ** 2 / (2 * EI), rel=1e-13)
    assert static("load.theta", "load.moment")[0].real == pytest.approx(L / EI, rel=1e-13)


def test_damped_beam_frf_matches_fe_with_equivalent_damping():
    """Kelvin-Voigt τ: EI* = EI(1 + τ s) equals FE damping matrix C = τ K."""
    tau = 2e-3
    element = beam(kelvin_voigt_time=tau)
    chain = ctmm.Chain("cantilever", [BeamClamped("root"), element, BeamPointLoad("load"), BeamFree("tip")])
    omega = np.array([3.0, 20.0, 60.0])
    frf = ctmm.frequency_response(chain, omega, input="load.force", output="load.w")("load.w", "load.force")
    fe = HermiteBeam([Section(L, EI, RHOA)], left="clamped", right="free", elements=80)
    ref = fe.receptance(omega, force_at=L, response_at=L, damping=tau * fe.K)
    np.testing.assert_allclose(frf, ref, rtol=1e-6)


def test_mixed_boundaries_work_in_frf_and_in_sturm_counting():
    chain = ctmm.Chain("simply_supported", [BeamPinned("a"), *beam().split(2), BeamPointLoad("load"),
                                            *beam("b2").split(2), BeamPinned("b")])
    frf = ctmm.frequency_response(chain, [0.0], input="load.force", output="load.w")
    assert frf("load.w", "load.force")[0].real == pytest.approx((2 * L) ** 3 / (48 * EI), rel=1e-13)
    # the Wittrick-Williams count eliminates the constrained w at both ends (was: ModelError)
    expected = omega_from_beta(np.pi * np.arange(1, 13), 2 * L, EI, RHOA)
    np.testing.assert_allclose(ctmm.natural_frequencies(chain, n_modes=12), expected, rtol=1e-14)
    # solvers that only know uniform boundaries still refuse the mixed ones
    with pytest.raises(ModelError, match="BeamPinned.*fixes w and moment"):
        _ = chain.start.known


# --------------------------------------------------------------------------------------------
# element contract: shapes, loads, parameters, errors
# --------------------------------------------------------------------------------------------
ELEMENTS = [beam(), beam(axial_force=5.0, loss_factor=0.01), BeamPointMass("m", 1.0, 0.1),
            BeamSpring("k", 3.0, 1.0, translational_damping=0.1), BeamHinge("h", 2.0, damping=0.3),
            BeamPointLoad("p")]


@pytest.mark.parametrize("element", ELEMENTS, ids=lambda e: type(e).__name__)
def test_shapes_for_scalar_and_vector_s(element):
    assert element.layout is BENDING
    assert element.transfer_matrix(2j).shape == (4, 4)
    assert element.transfer_matrix(np.array([1j, 2j, 3j])).shape == (3, 4, 4)
    assert element.transfer_matrix(np.ones((2, 3)) * 1j).shape == (2, 3, 4, 4)
    assert element.load_vector(np.array([1j, 2j]), {}).shape == (2, 4)
    batch = element.transfer_matrix(np.array([1j, 2j, 3j]))
    np.testing.assert_array_equal(batch[1], element.transfer_matrix(2j))


def test_point_load_vector_and_kinds():
    load = BeamPointLoad("p")
    u = load.load_vector(np.array([1j, 2j]), {"force": 2.0, "moment": -1.0})
    np.testing.assert_array_equal(u[:, 2], 2.0)
    np.testing.assert_array_equal(u[:, 3], -1.0)
    assert load.inputs == ("force", "moment") and load.is_point
    with pytest.raises(UnknownNameError, match="unknown input .* 'torque'.*available: force, moment"):
        load.load_vector(1j, {"torque": 1.0})
    assert not BeamField("b", 1, 1, 1).is_point and not BeamHinge("h", 1.0).is_point
    assert BeamPointMass("m", 1.0).is_point and BeamSpring("k", 1.0, 0.0).is_point


def test_conservative_flags():
    assert beam().is_conservative and not beam(loss_factor=0.01).is_conservative
    assert not BeamHinge("h", 1.0, damping=0.1).is_conservative
    assert not BeamSpring("k", 1.0, 1.0, rotational_damping=0.1).is_conservative


@pytest.mark.parametrize("factory, match", [
    (lambda: BeamField("b", 0.0, 1.0, 1.0), r"b: length must be > 0, got 0"),
    (lambda: BeamField("b", 1.0, -2.0, 1.0), r"b: bending_stiffness must be > 0, got -2"),
    (lambda: BeamField("b", 1.0, 1.0, 0), r"b: mass_per_length must be > 0, got 0"),
    (lambda: BeamField("b", 1.0, 1.0, float("nan")), r"b: mass_per_length must be finite"),
    (lambda: BeamField("b", 1.0, 1.0, 1.0, loss_factor=-0.1), r"b: loss_factor must be >= 0, got -0.1"),
    (lambda: BeamField("b", 1.0, 1.0, 1.0, axial_force="x"), r"b: axial_force must be a real number"),
    (lambda: BeamField("b.1", 1.0, 1.0, 1.0), r"element name must be a non-empty string"),
    (lambda: BeamPointMass("m", 0.0, 0.0), r"m: mass and rotary_inertia are both 0"),
    (lambda: BeamPointMass("m", -1.0), r"m: mass must be >= 0, got -1"),
    (lambda: BeamSpring("k", 0.0, 0.0), r"k: all spring and damper constants are 0"),
    (lambda: BeamHinge("h", 0.0), r"h: rotational_stiffness must be > 0, got 0"),
    (lambda: beam().split(0), r"beam: pieces must be an integer >= 1, got 0"),
    (lambda: beam().transfer_matrix(np.array([1j, np.inf])), r"s must contain only finite values"),
    (lambda: beam().clamped_frequency_count(-1.0), r"beam: omega must be finite and >= 0"),
])
def test_error_messages_name_parameter_and_value(factory, match):
    with pytest.raises(ModelError, match=match):
        factory()


def test_repr_and_parameters():
    element = beam(axial_force=3.0)
    assert element.parameters()["axial_force"] == 3.0
    assert repr(element).startswith("BeamField('beam', length=1.3")
    assert [p.length for p in element.split(4)] == pytest.approx([L / 4] * 4)
    assert [p.name for p in element.split(2)] == ["beam_1", "beam_2"]
