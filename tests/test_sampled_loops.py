"""Sampled (zero-order-hold) controllers converge to the exact sampled-data loop at the scheme's order.

Reference: the exact discretisation of ``m x'' + c x' + k x = u_j`` over each hold interval by the
matrix exponential of the augmented system (no TMM code), with ``u_j = -(kp x_j + kd v_j)`` taken
from the exact state at the sample instant.  The DT-TMM restarts the acceleration at every sample
instant where the held force jumps (``ctmm.control.simulate``), so a sampled loop converges at
second order in ``dt`` for the second-order schemes (it was first order: every switch acted dt/2 late).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

import ctmm
from ctmm.elements import Fixed, Free, Mass, SpringDamper

from _controllers_import import load_controllers

controllers = load_controllers()
K, C, M = 40.0, 0.3, 2.0
KP, KD, H = 25.0, 2.0, 0.02


def plant() -> ctmm.Chain:
    return ctmm.Chain("sdof", [Fixed("w"), SpringDamper("k", K, C), Mass("m", M), Free("e")])


def exact_sampled(x0: float, n: int) -> np.ndarray:
    """Positions at the sample instants of the exact ZOH loop."""
    a = np.array([[0.0, 1.0], [-K / M, -C / M]])
    b = np.array([[0.0], [1.0 / M]])
    step = scipy.linalg.expm(np.block([[a, b], [np.zeros((1, 3))]]) * H)
    z, xs = np.array([x0, 0.0]), [x0]
    for _ in range(n):
        u = -(KP * z[0] + KD * z[1])
        z = step[:2, :2] @ z + step[:2, 2] * u
        xs.append(z[0])
    return np.array(xs)


@pytest.mark.parametrize("scheme", ["newmark", "generalized_alpha"])
def test_sampled_pd_converges_at_second_order_to_the_exact_sampled_loop(scheme):
    exact = exact_sampled(0.05, 50)
    errors = []
    for dt in (H / 2, H / 4, H / 8):
        pd = controllers.SaturatedPD(("m.x", "m.v"), ("m.force",), kp=KP, kd=KD, sample_time=H)
        run = ctmm.simulate(plant(), 50 * H, dt, x0={"m": 0.05}, controllers=[pd], scheme=scheme)
        errors.append(np.max(np.abs(run["m.x"][::round(H / dt)] - exact)))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.8), (errors, orders)
    assert errors[-1] < 1e-4 * 0.05


def test_a_held_force_that_does_not_change_leaves_the_run_unchanged():
    """The restart only acts where the held force jumps: a controller with a constant output gives the
    same run as the same force applied by a plain chain load."""
    class Constant:
        inputs: tuple = ()
        outputs = ("m.force",)
        sample_time = H
        direct_feedthrough = False

        def init(self, t0):
            return None

        def step(self, t, y, state):
            return np.array([3.0]), state

    with_controller = ctmm.simulate(plant(), 0.4, H / 4, controllers=[Constant()])
    loaded = ctmm.Chain("sdof", [Fixed("w"), SpringDamper("k", K, C), Mass("m", M, force=3.0), Free("e")])
    direct = ctmm.simulate(loaded, 0.4, H / 4)
    np.testing.assert_allclose(with_controller["m.x"], direct["m.x"], rtol=0, atol=1e-15)
