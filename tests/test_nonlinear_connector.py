"""Nonlinear 1-D connectors (ctmm.elements.nonlinear_connector.NonlinearSpring) in chains.

Independent reference: the chain's global equations of motion written here (Newton's law per mass, the laws
as plain functions of the elongations), integrated by DOP853 at 1e-12; a massless point between a nonlinear
and a linear spring is condensed here by a scalar root search.  No TMM, sweep or chain code is shared.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.optimize

import ctmm
from ctmm.elements import Fixed, Free, Mass, Spring
from ctmm.elements.nonlinear_connector import NonlinearSpring
from ctmm.errors import ModelError
from ctmm.nonlinear_laws import CubicSpring, PowerDamper

M1, M2 = 1.0, 0.5                                  # [kg]
K1, K3 = 100.0, 5e4                                # wall spring: f = K1 d + K3 d^3  [N/m, N/m^3]
L1, L3, C2 = 50.0, 2e4, 0.5                        # coupling spring + power damper 0.5 |v|^1.5 sign(v)
FREE = 0.3                                         # coupling spring free length [m]


def _wall(d):
    return K1 * d + K3 * d ** 3


def _coupling(d, rate):
    return L1 * d + L3 * d ** 3 + C2 * np.sign(rate) * np.abs(rate) ** 1.5


def duffing_chain(operating_deflection=None) -> ctmm.Chain:
    return ctmm.Chain("duffing", [
        Fixed("wall"), NonlinearSpring("k1", CubicSpring(K1, K3), operating_deflection=operating_deflection),
        Mass("m1", M1),
        NonlinearSpring("k2", CubicSpring(L1, L3) + PowerDamper(C2, 1.5, regularization_rate=1e-9),
                        free_length=FREE, operating_deflection=operating_deflection),
        Mass("m2", M2), Free("end")])


def reference(x0, t):
    def rhs(_, y):
        x1, x2, v1, v2 = y
        f2 = _coupling(x2 - x1 - FREE, v2 - v1)
        return [v1, v2, (-_wall(x1) + f2) / M1, -f2 / M2]

    sol = scipy.integrate.solve_ivp(rhs, (0.0, t[-1]), [*x0, 0.0, 0.0], method="DOP853", t_eval=t, rtol=1e-12,
                                    atol=1e-14)
    return sol.y


def test_duffing_chain_matches_the_global_ode_on_every_path():
    x0 = (0.05, 0.05 + FREE + 0.06)
    chain = duffing_chain()
    runs = {}
    for method, dt in (("newmark", 1e-3), ("newmark", 5e-4), ("rk4", 1e-3), ("DOP853", 1e-3)):
        options = {"rtol": 1e-11, "atol": 1e-13} if method == "DOP853" else {}
        runs[method, dt] = ctmm.simulate(chain, 0.25, dt, method=method, x0={"m1": x0[0], "m2": x0[1]}, **options)
    y = reference(x0, runs["newmark", 1e-3].time)
    errors = {key: np.max(np.abs(run["m2.x"] - (y[1] if key[1] == 1e-3 else
                                                reference(x0, run.time)[1]))) for key, run in runs.items()}
    assert np.ptp(y[1]) > 0.1                                             # a large, nonlinear motion
    assert errors["rk4", 1e-3] < 1e-9 and errors["DOP853", 1e-3] < 1e-11
    assert errors["newmark", 5e-4] < 1e-6 and 3.5 < errors["newmark", 1e-3] / errors["newmark", 5e-4] < 4.5
    newmark = runs["newmark", 5e-4]
    assert 2 <= newmark.info["newton_iterations_max"] <= 4                 # Newton with the exact tangent
    np.testing.assert_allclose(newmark["k1.f"][0], -_wall(x0[0]), rtol=1e-12)   # the law at t0
    assert np.max(np.abs(runs["rk4", 1e-3]["k1.f"] + _wall(y[0]))) < 1e-7 * np.max(np.abs(_wall(y[0])))


def test_massless_point_between_a_nonlinear_and_a_linear_spring():
    """The DT-TMM step condenses the massless point exactly (Newton on the whole step); the ODE methods,
    which read the massless tangents once, refuse the chain by name."""
    chain = ctmm.Chain("series", [Fixed("wall"), NonlinearSpring("k1", CubicSpring(K1, K3)), Spring("k0", 300.0),
                                  Mass("m1", M1), Free("end")])
    def point(x1):                       # the massless point: K1 y + K3 y^3 = 300 (x1 - y)
        return scipy.optimize.brentq(lambda yq: _wall(yq) - 300.0 * (x1 - yq), -1.0, 1.0, xtol=1e-15)

    start = {"k1": point(0.08), "m1": 0.08}             # the massless point (after k1) at its balance
    runs = [ctmm.simulate(chain, 0.15, dt, x0=start) for dt in (5e-4, 2.5e-4)]
    errors = []
    for run in runs:
        sol = scipy.integrate.solve_ivp(lambda _, s: [s[1], -300.0 * (s[0] - point(s[0])) / M1], (0.0, 0.15),
                                        [0.08, 0.0], method="DOP853", t_eval=run.time, rtol=1e-12, atol=1e-14)
        errors.append(np.max(np.abs(run["m1.x"] - sol.y[0])))
    assert np.ptp(runs[1]["m1.x"]) > 0.05 and errors[1] < 2e-6 * 0.08 and 3.5 < errors[0] / errors[1] < 4.5
    with pytest.raises(ModelError, match="nonlinear connectors"):
        ctmm.simulate(chain, 0.1, 1e-3, x0={"m1": 0.08}, method="rk4")
    with pytest.raises(ModelError, match="nonlinear connectors.*DT-TMM scheme with compiled=False"):
        ctmm.simulate(chain, 0.1, 1e-3, x0={"m1": 0.08}, method="newmark", compiled=True)   # said "use a DT-TMM scheme"


def test_massless_point_left_out_of_x0_starts_at_its_balance_and_small_steps_converge():
    """The massless point between the nonlinear and a linear spring, left out of x0, starts at its force balance
    (it started at its rest length 0: initial acceleration -300 x1 / M1 instead of the balance's, a start error
    the scheme carried on); and Newton converges at small steps (its rate test amplified round-off by 1 / h:
    "did not converge" at dt = 1e-5)."""
    chain = ctmm.Chain("series", [Fixed("wall"), NonlinearSpring("k1", CubicSpring(K1, K3)), Spring("k0", 300.0),
                                  Mass("m1", M1), Free("end")])
    def point(x1):                       # the massless point: K1 y + K3 y^3 = 300 (x1 - y)
        return scipy.optimize.brentq(lambda yq: _wall(yq) - 300.0 * (x1 - yq), -1.0, 1.0, xtol=1e-15)

    for dt, t_final, bound in ((5e-4, 0.15, 1e-5), (1e-5, 0.005, 1e-10)):
        run = ctmm.simulate(chain, t_final, dt, x0={"m1": 0.08})
        np.testing.assert_allclose(run["k1.x"][0], point(0.08), rtol=1e-12)
        np.testing.assert_allclose(run["m1.a"][0], -300.0 * (0.08 - point(0.08)) / M1, rtol=1e-10)
        sol = scipy.integrate.solve_ivp(lambda _, s: [s[1], -300.0 * (s[0] - point(s[0])) / M1], (0.0, t_final),
                                        [0.08, 0.0], method="DOP853", t_eval=run.time, rtol=1e-12, atol=1e-14)
        assert np.max(np.abs(run["m1.x"] - sol.y[0])) < bound * 0.08
        assert run.info["newton_iterations_max"] <= 4                    # Newton with the exact tangent
    with pytest.raises(ModelError, match=r"x0\['k1'\].*force balance"):
        ctmm.simulate(chain, 0.01, 1e-3, x0={"m1": 0.08, "k1": 0.0})


def test_frequency_forms_are_the_tangent_at_the_operating_point_or_refused():
    with pytest.raises(ModelError, match="operating_deflection"):
        ctmm.natural_frequencies(duffing_chain(), n_modes=2)
    with pytest.raises(ModelError, match="operating_deflection"):
        ctmm.frequency_response(duffing_chain(), [1.0], input="m2.force", output="m2.x")
    with pytest.raises(ModelError, match="NonlinearSpring"):
        ctmm.linearize(duffing_chain(0.0))
    for deflection in (0.0, 0.02):
        k1, k2 = K1 + 3 * K3 * deflection ** 2, L1 + 3 * L3 * deflection ** 2     # tangents at the point
        stiffness = np.array([[k1 + k2, -k2], [-k2, k2]])
        expected = np.sqrt(np.linalg.eigvalsh(np.diag([1 / M1 ** 0.5, 1 / M2 ** 0.5]) @ stiffness
                                              @ np.diag([1 / M1 ** 0.5, 1 / M2 ** 0.5])))
        np.testing.assert_allclose(ctmm.natural_frequencies(duffing_chain(deflection), n_modes=2), expected,
                                   rtol=1e-9)
        omega = np.array([0.0, 3.0])
        frf = ctmm.frequency_response(duffing_chain(deflection), omega, input="m2.force", output="m1.x")
        direct = [np.linalg.solve(stiffness - w ** 2 * np.diag([M1, M2]), [0.0, 1.0])[0] for w in omega]
        np.testing.assert_allclose(frf("m1.x", "m2.force").real, direct, rtol=1e-9)


def test_bad_input_is_refused_by_name():
    with pytest.raises(ModelError, match="law must be"):
        NonlinearSpring("k", 3.0)
    with pytest.raises(ModelError, match="free_length"):
        NonlinearSpring("k", CubicSpring(1.0, 1.0), free_length=float("nan"))
