"""The DT-TMM start of a chain evaluates a time-varying boundary force at ``t0``, not at 0.

A free mass ``m`` pushed by ``PrescribedForce(A t)`` from rest at ``t0 = 1.5 s``: closed form
``a = A t / m``, ``v = A (t^2 - t0^2) / (2 m)``, ``x = A / (2 m) ((t^3 - t0^3) / 3 - t0^2 (t - t0))``.
Newmark's average acceleration integrates a linear acceleration exactly in ``v`` and leaves
``dt^2 (t - t0) A / (12 m)`` in ``x`` (its position update's quadrature error); a start force taken
at ``t = 0`` instead gives ``a(t0) = 0`` and a velocity offset ``dt A t0 / (2 m)`` for the whole run.
With an inerter ``b`` between two masses the start accelerations solve
``[[m1 + b, -b], [-b, m2 + b]] a = [A t0, 0]`` (the coupled start).  A delayed loop of a controlled
chain reads the held start before ``t0``, with the boundary force at ``t0``.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Inerter, Mass, PrescribedForce, Spring

SLOPE, MASS, T0, DT, SPAN = 6.0, 2.0, 1.5, 1e-3, 0.2      # N/s, kg, s, s, s


@pytest.mark.parametrize("fast", [True, False])
def test_a_ramp_force_starts_at_t0(fast):
    chain = ctmm.Chain("c", [PrescribedForce("p", lambda t: SLOPE * t), Mass("m", MASS), Free("end")])
    result = ctmm.simulate(chain, T0 + SPAN, DT, t0=T0, method="newmark", fast=fast)
    t = result.time
    assert t[0] == T0
    assert np.ravel(result["m.a"])[0] == pytest.approx(SLOPE * T0 / MASS, abs=1e-12)
    assert np.ravel(result["p.f"])[0] == pytest.approx(SLOPE * T0, abs=1e-12)
    np.testing.assert_allclose(np.ravel(result["m.a"]), SLOPE * t / MASS, rtol=0.0, atol=1e-11)
    np.testing.assert_allclose(np.ravel(result["m.v"]), SLOPE * (t ** 2 - T0 ** 2) / (2 * MASS), rtol=0.0, atol=1e-12)
    x = SLOPE / (2 * MASS) * ((t ** 3 - T0 ** 3) / 3 - T0 ** 2 * (t - T0))
    quadrature = DT ** 2 * (t - T0) * SLOPE / (12 * MASS)      # Newmark's position error, exact here
    np.testing.assert_allclose(np.ravel(result["m.x"]) - x, quadrature, rtol=0.0, atol=1e-12)


def test_the_coupled_start_with_an_inerter_takes_the_force_at_t0():
    m1, m2, b = 1.0, 3.0, 0.5
    chain = ctmm.Chain("c", [PrescribedForce("p", lambda t: SLOPE * t), Mass("m1", m1), Inerter("b", b),
                             Mass("m2", m2), Free("end")])
    result = ctmm.simulate(chain, T0 + 10 * DT, DT, t0=T0, method="newmark")
    expected = np.linalg.solve([[m1 + b, -b], [-b, m2 + b]], [SLOPE * T0, 0.0])
    start = [np.ravel(result["m1.a"])[0], np.ravel(result["m2.a"])[0]]
    np.testing.assert_allclose(start, expected, rtol=1e-12, atol=0.0)


def test_a_delayed_loop_reads_the_boundary_force_of_the_held_start_at_t0():
    """Before ``t0`` the history is the start state held: a loop sensing the force at the loaded end reads
    ``F(t0)`` there, so ``u(t) = -g A max(t - tau, t0)`` (the end force is the applied ``A t`` exactly)."""
    gain, delay = 0.5, 0.05
    chain = ctmm.Chain("c", [PrescribedForce("p", lambda t: SLOPE * t), Mass("m", MASS), Spring("k", 50.0),
                             Fixed("wall")])
    system = ControlledChain(chain, [Feedback("l", "p.f", "m", gain=gain, delay=delay)])
    result = ctmm.simulate(system, T0 + 0.1, DT, t0=T0, method="newmark")
    t = result.time
    np.testing.assert_allclose(np.ravel(result["l.y"]), SLOPE * t, rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(np.ravel(result["l.u"]), -gain * SLOPE * np.maximum(t - delay, T0), rtol=1e-12,
                               atol=0.0)
