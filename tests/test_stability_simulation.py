"""Stability predictions against time simulations (DT-TMM with the delayed loop from its history).

On both sides of a stability boundary the envelope of the simulated response must decay or grow
as the characteristic roots say, at a rate equal to the spectral abscissa.
"""
from __future__ import annotations

import math

import numpy as np

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Free, Mass
from ctmm.stability import crosscheck_by_simulation, delay_margin, envelope_rate
from test_stability import seed_chain


def test_envelope_rate_of_known_signals():
    t = np.linspace(0, 20, 4001)
    assert abs(envelope_rate(t, np.exp(-0.3 * t) * np.cos(5 * t + 0.2)) + 0.3) < 1e-3
    assert abs(envelope_rate(t, np.exp(0.1 * t)) - 0.1) < 1e-12


def test_pd_mass_on_both_sides_of_the_critical_delay():
    plant = ctmm.Chain("mass", [Free("a"), Mass("m", 1.0), Free("b")])
    system = ControlledChain(plant, [Feedback("pd", [("m.x", 1.0), ("m.v", 1.0)], "m", gain=1.0)])
    critical = delay_margin(system).critical_delay
    check = crosscheck_by_simulation(system, [{"delay": 0.85 * critical}, {"delay": 1.1 * critical}],
                                     t_final=40.0, dt=0.02)
    assert check.agree and list(check.predicted_stable) == [True, False]
    np.testing.assert_allclose(check.rate, check.abscissa, atol=2e-3)


def test_seed_chain_stability_switches():
    """K_a = -60: stable, unstable past the first switch (tau = 0.031 s), stable again (0.26-0.73 s)."""
    system = seed_chain(gain=-60.0, delay=0.0)
    margin = delay_margin(system, delay_max=0.8)
    assert margin.crossing_directions[:3] == (1, -1, 1)
    assert abs(margin.stable_intervals[1][0] - 0.264) < 1e-3
    check = crosscheck_by_simulation(system, [{"delay": 0.02}, {"delay": 0.05}, {"delay": 0.3}],
                                     t_final=20.0, dt=0.01)
    assert check.agree and list(check.predicted_stable) == [True, False, True]
    # rates where one pair dominates clearly (at tau = 0.3 s two pairs decay at similar rates)
    assert np.all(np.abs(check.rate[:2] - check.abscissa[:2]) < 0.05 * np.abs(check.abscissa[:2]))
    assert math.isfinite(check.rate[1]) and check.rate[1] > 0.1
