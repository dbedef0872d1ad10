"""The independent assumed-modes Lagrange reference of the manipulator (issue 6, B).

Checked against things it does not compute itself: the classical clamped-free beta table
(FORMULAS §2.6), quadrature of its own closed forms, energy conservation, the static
flexibility of a cantilever (unit-load method), and the Newton-Euler balance of the hub.
"""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.manipulator import CycloidalMove, seed_manipulator
from ctmm.reference.manipulator_lagrange import ClampedFreeModes, ManipulatorLagrange, clamped_free_beta


@pytest.fixture(scope="module")
def seed():
    return seed_manipulator()


def test_beta_table():
    # FORMULAS §2.6: 1.8751040687, 4.6940911330, 7.8547574382, 10.9955407349, 14.1371683910
    np.testing.assert_allclose(clamped_free_beta(5), [1.8751040687, 4.6940911330, 7.8547574382,
                                                       10.9955407349, 14.1371683910], rtol=1e-10)
    b = clamped_free_beta(200)
    np.testing.assert_allclose(b[50:], (2 * np.arange(51, 201) - 1) * np.pi / 2, rtol=1e-15)


def test_modes_are_orthonormal_up_to_high_order(seed):
    ref = ManipulatorLagrange.from_manipulator(seed, 60)
    modes = ref.modes
    M = ref.quadrature(lambda x: ref.rhoA * np.einsum("xi,xj->xij", modes.evaluate(x), modes.evaluate(x)))
    K = ref.quadrature(lambda x: ref.EI * np.einsum("xi,xj->xij", modes.evaluate(x, 2), modes.evaluate(x, 2)))
    assert np.abs(M - np.eye(60)).max() < 1e-12
    assert np.abs(K / np.outer(ref.omega, ref.omega) - np.eye(60)).max() < 1e-12
    # free end: phi''(L) = phi'''(L) = 0; clamp: phi(0) = phi'(0) = 0; |phi(L)| sqrt(rho A L) = 2
    for d in (0, 1):
        assert np.abs(modes.evaluate(0.0, d)).max() < 1e-9 * np.abs(modes.evaluate(ref.L / 3, d)).max()
    for d in (2, 3):
        assert np.abs(modes.evaluate(ref.L, d)).max() < 1e-9 * np.abs(modes.evaluate(ref.L / 3, d)).max()
    np.testing.assert_allclose(np.abs(ref.phi_tip) * np.sqrt(ref.rhoA * ref.L), 2.0, rtol=1e-12)


def test_closed_form_modal_integrals_equal_quadrature(seed):
    ref = ManipulatorLagrange.from_manipulator(seed, 12, stiffening=True)
    ev = ref.modes.evaluate
    a = ref.quadrature(lambda x: ref.rhoA * (ref.r + x)[:, None] * ev(x))
    np.testing.assert_allclose(ref.a, a, rtol=1e-12, atol=1e-15)
    m = ref.quadrature(lambda x: ref.rhoA * ev(x))
    np.testing.assert_allclose(ref.modal_mass_moments(), m, rtol=1e-12, atol=1e-15)
    # K_G of Kane-Ryan-Banerjee for r = 0: rho A int (L^2 - x^2)/2 phi' phi'
    ref0 = ManipulatorLagrange(4, hub_inertia=1.0, hub_radius=0.0, length=2.0, bending_stiffness=3.0,
                               mass_per_length=0.5, stiffening=True)
    KG = ref0.quadrature(lambda x: 0.5 * (4.0 - x ** 2)[:, None, None] * 0.5
                         * np.einsum("xi,xj->xij", ref0.modes.evaluate(x, 1), ref0.modes.evaluate(x, 1)))
    np.testing.assert_allclose(ref0.KG, KG, rtol=1e-12)


def test_static_port_flexibility_is_the_limit_of_the_modal_sum(seed):
    """Unit-load method (EI u'' = moment distribution) vs sum_k b b^T / omega_k^2: residual O(1/N)."""
    ref = ManipulatorLagrange.from_manipulator(seed, 400)
    F = ref._static_ports()
    b = ref._port_modal()
    # classical checks: tip force P -> u(L) = P L^3 / (3 EI); pair M on [x1, x2] -> u(L) = M (x2 - x1)(L - mid)/EI
    L, EI = ref.L, ref.EI
    assert F[-1, -1] == pytest.approx(L ** 3 / (3 * EI), rel=1e-14)
    x1, x2 = ref.patch_ends[0]
    assert F[1, -1] == pytest.approx((x2 - x1) * (L - (x1 + x2) / 2) / EI, rel=1e-14)
    errors = []
    for n in (50, 100, 200, 400):
        S = (b[:, :n] / ref.omega[:n] ** 2) @ b[:, :n].T
        errors.append(np.abs(S - F).max() / np.abs(F).max())
    assert errors[-1] < 2e-3
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(rates > 0.9)      # first order in 1/N for moment pairs (slope jumps)


@pytest.mark.parametrize("stiffening", [False, True])
def test_energy_is_conserved_without_damping_and_control(seed, stiffening):
    ref = ManipulatorLagrange(3, hub_inertia=0.3, hub_radius=0.05, length=1.0, bending_stiffness=6.3,
                              mass_per_length=0.324, stiffening=stiffening, consistent_inertia=True)
    eta0 = np.array([0.02, -0.005, 0.002])
    sim = ref.simulate(0.4, theta_dot0=8.0, eta0=eta0, eta_dot0=[0.1, 0.0, 0.1],
                       t_eval=np.linspace(0, 0.4, 21), rtol=1e-12, atol=1e-14)
    energies = []
    for k in range(sim.t.size):
        M = ref.mass_matrix(sim.eta[k])
        v = np.concatenate([[sim.theta_dot[k]], sim.eta_dot[k]])
        energies.append(0.5 * v @ M @ v + 0.5 * sim.eta[k] @ ref.K @ sim.eta[k])
    energies = np.array(energies)
    assert np.abs(energies - energies[0]).max() < 1e-10 * energies[0]


def test_clamp_load_balances_the_hub(seed):
    """Hub Euler: J_h theta_ddot = tau - (M_c + r f_Y) (the arm's load on the hub, moved to the pivot)."""
    ref = ManipulatorLagrange.from_manipulator(seed, 3)
    rng = np.random.default_rng(7)
    for _ in range(5):
        w, eta, eta_dot = rng.normal(), 0.01 * rng.normal(size=3), rng.normal(size=3) * 0.1
        tau, V = rng.normal() * 5, rng.normal(size=3) * 100
        acc = ref.accelerations(w, eta, eta_dot, tau, V)
        f = ref.clamp_load(w, eta, eta_dot, acc)
        assert ref.Jh * acc[0] == pytest.approx(tau - (f[2] + ref.r * f[1]), rel=1e-12, abs=1e-12)


def test_linearisation_equals_the_modal_frequency_response(seed):
    ref = ManipulatorLagrange.from_manipulator(seed, 5)
    lin = ref.linearize()
    G = np.diag([300.0, 200.0, 100.0])
    w = np.array([0.7, 12.0, 60.0, 250.0])
    s = 1j * w
    kp, kd = 20.0, 4.0
    out = ref.frequency_response(w, kp=kp, kd=kd, pzt_gains=G, static_correction=False)["theta_d"]
    for k, sk in enumerate(s):
        D = lin["D"] + lin["B_voltage"] @ G @ lin["C_slopes"]
        D[0, 0] += kd
        K = lin["K"].copy()
        K[0, 0] += kp
        q = np.linalg.solve(sk ** 2 * lin["M"] + sk * D + K, lin["B_torque"] * (kp + kd * sk))
        assert q[0] == pytest.approx(out["theta"][k], rel=1e-11)
        assert lin["C_tip"] @ q == pytest.approx(out["tip"][k], rel=1e-10)


def test_small_delay_converges_to_the_undelayed_loop(seed):
    ref = ManipulatorLagrange.from_manipulator(seed, 2)
    move = CycloidalMove(0.3, 0.5)
    G = np.eye(3) * 500.0
    kwargs = dict(reference=move, kp=50.0, kd=15.0, pzt_gains=G, t_eval=np.linspace(0, 0.4, 41),
                  rtol=1e-9, atol=1e-11)
    base = ref.simulate(0.4, **kwargs)
    errs = [np.abs(ref.simulate(0.4, pd_delay=tau, pzt_delay=tau / 2, **kwargs).tip_deflection
                   - base.tip_deflection).max() for tau in (0.004, 0.002)]
    assert errs[1] < 0.6 * errs[0]            # O(tau)
    assert errs[1] < 0.05 * np.abs(base.tip_deflection).max()
