"""Reported signals of massless chain nodes on the DT-TMM path, against hand solutions.

Chain ``Fixed - s1 - m - s2 - n (load F) - s3 - Free``: ``s3`` carries no force, so the massless node
``n`` sits at ``x_m + F / k2`` and the mass obeys ``m x'' + k1 x = F``; with ``F = A sin(W t)`` and
``x(0) = x0, v(0) = 0`` the hand solution is closed form. A spring-damper node (first order) is checked
against ``solve_ivp`` of its three-state ODE.
"""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ctmm
from ctmm.elements.boundary import Fixed, Free
from ctmm.elements.lumped import Damper, Mass, PointElement, Spring
from ctmm.signals import Harmonic, Step
from ctmm.system import Chain
from ctmm.timestep import simulate as dt_tmm_simulate

K1, MASS, K2, K3, A, W, X0 = 100.0, 1.0, 50.0, 80.0, 2.0, 20.0, 0.01
SCHEMES = {"newmark": (2, 2e-3), "generalized_alpha": (2, 2e-3), "wilson_theta": (2, 2e-3),
           "houbolt": (2, 2e-3), "forward_euler": (1, 2e-4)}
NODE_VELOCITY_ORDER = {**{name: order for name, (order, _) in SCHEMES.items()}, "wilson_theta": 1}
"""Order of the reported velocity of a spring-spring node: the scheme's, except Wilson-theta, whose node
positions at ``t_n`` (interpolated from the ``theta`` level) carry an O(h^2) error alternating from step
to step, so their difference quotient is first order (docs/schemes.md)."""


def pulled_chain(force) -> Chain:
    return Chain("pulled", [Fixed("w"), Spring("s1", K1), Mass("m", MASS), Spring("s2", K2),
                            PointElement("n", force=force), Spring("s3", K3), Free("e")])


def hand_node_velocity(t: np.ndarray) -> np.ndarray:
    """``v_n = v_m + F' / k2`` with ``m x'' + k1 x = A sin(W t)``, ``x(0) = X0``, ``v(0) = 0``."""
    w = math.sqrt(K1 / MASS)
    forced = A / MASS / (w ** 2 - W ** 2)
    v_mass = -X0 * w * np.sin(w * t) + forced * W * (np.cos(W * t) - np.cos(w * t))
    return v_mass + A * W * np.cos(W * t) / K2


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_spring_spring_node_velocity_at_scheme_order(scheme):
    order, dt = SCHEMES[scheme]
    errors = []
    for h in (dt, dt / 2):
        result = ctmm.simulate(pulled_chain(Harmonic(A, W)), 0.2, h, method=scheme, x0={"m": X0})
        errors.append(np.max(np.abs(result["n.v"] - hand_node_velocity(result.time))))
        assert np.all(np.isnan(result["n.a"]))   # not a state: NaN by design, as on the ODE path
    assert errors[1] < 0.02 * A * W / K2
    assert errors[0] / errors[1] > 0.8 * 2 ** NODE_VELOCITY_ORDER[scheme]


@pytest.mark.parametrize("scheme", ["newmark", "houbolt"])
def test_no_ringing_after_a_load_jump(scheme):
    """A step of the node's load moves the node at once; afterwards its velocity is the mass's again
    (the trapezoidal update used to alternate between 0 and twice the true value for ever)."""
    dt, jump = 1e-3, 0.05
    result = ctmm.simulate(pulled_chain(Step(A, jump)), 0.2, dt, method=scheme, x0={"m": X0})
    after = result.time > jump + 2.5 * dt
    error = np.abs(result["n.v"] - result["m.v"])[after]
    assert np.max(error) < 1e-3 * np.max(np.abs(result["m.v"]))


def test_controlled_force_on_the_node():
    """A loop force (force hook, no closed-form rate) on the node: right velocity after the start step."""
    dt = 1e-3
    chain = pulled_chain(0.0)
    position = [e.name for e in chain.elements].index("n")
    hook = lambda t_n, h, w, history: {position: A * math.sin(W * (t_n + w * h))}  # noqa: E731
    errors = []
    for h in (dt, dt / 2):
        result = dt_tmm_simulate(chain, 0.2, h, scheme="newmark", x0={"m": X0}, force_hook=hook)
        assert math.isnan(result["n.v"][0])      # off the balance's rate at t0: unknown, not 0
        errors.append(np.max(np.abs(result["n.v"] - hand_node_velocity(result.time))[2:]))
    assert errors[1] < 0.02 * A * W / K2
    assert errors[0] / errors[1] > 3.2


@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_spring_damper_node_velocity(scheme):
    """``Fixed - s1 - m - s2 - node - d3 - Fixed``: the node is a first-order state ``c v = k2 (x_m - x)``."""
    order, dt = SCHEMES[scheme]
    damping = 3.0
    chain = Chain("damped", [Fixed("w"), Spring("s1", K1), Mass("m", MASS), Spring("s2", K2),
                             Damper("d3", damping), Fixed("e")])

    def rates(t, y):
        x, v, q = y
        return [v, (-K1 * x - K2 * (x - q)) / MASS, K2 * (x - q) / damping]

    errors = []
    for h in (dt, dt / 2):
        result = ctmm.simulate(chain, 0.2, h, method=scheme, x0={"m": X0})
        node = result.states[:, 3, 0]
        reference = solve_ivp(rates, (0.0, 0.2 + 1e-9), [X0, 0.0, node[0]], t_eval=result.time,
                              rtol=1e-12, atol=1e-15).y
        errors.append(np.max(np.abs(result.velocity[:, 3, 0] - K2 * (reference[0] - reference[2]) / damping)))
    assert errors[0] / errors[1] > 0.8 * 2 ** order


@pytest.mark.parametrize("nonlinear", [False, True])
def test_massless_point_starts_at_its_balance_with_a_prescribed_start_away_from_zero(nonlinear):
    """A prescribed start at 0.05 m at t0 (a constant: the chain of a fixed support there): the massless point
    between the two springs starts at its balance with the support where it is, (100 * 0.05 + 300 * 0.08) / 400,
    and the mass at -k_series (0.08 - 0.05) / m.  The DT-TMM start balanced it with the support at 0 (0.06 m,
    -6 m/s^2 instead of -2.25) and then put the support at 0.05; the nonlinear-connector start left the support
    at 0 for the first step."""
    from ctmm.elements import PrescribedDisplacement
    from ctmm.elements.nonlinear_connector import NonlinearSpring
    from ctmm.nonlinear_laws import LinearLaw
    first = NonlinearSpring("k1", LinearLaw(100.0)) if nonlinear else Spring("k1", 100.0)
    run = ctmm.simulate(Chain("base", [PrescribedDisplacement("b", 0.05), first, Spring("k0", 300.0), Mass("m1", 1.0),
                                       Free("end")]), 0.5, 1e-3, x0={"m1": 0.08}, method="newmark")
    assert run["b.x"][0] == 0.05
    assert run["k1.x"][0] == pytest.approx((100.0 * 0.05 + 300.0 * 0.08) / 400.0, rel=1e-12)
    assert run["m1.a"][0] == pytest.approx(-75.0 * 0.03, rel=1e-12)
    omega = math.sqrt(75.0)                                   # the series springs on the mass, about 0.05 m
    exact = 0.05 + 0.03 * np.cos(omega * np.asarray(run.time))
    phase = omega * 0.5 * (omega * 1e-3) ** 2 / 12.0               # the trapezoidal rule's phase error at 0.5 s
    assert np.max(np.abs(run["m1.x"] - exact)) < 1.1 * 0.03 * phase
