"""A prescribed boundary force is weighted as the DT-TMM scheme weights its loads (``ctmm/timestep.py``).

``(1 - w) F(t_n) + w F(t_n + h)``, as the elements' loads are: the balance's time ``t_{n+1-alpha_f}`` for
generalized-alpha, Wilson-theta's linear extrapolation to ``t_n + theta h``.  Checked independently: a
harmonic force on the free end of a damped oscillator is the same system as that force on its mass (same
answer to round-off), and every scheme converges at its order to the closed-form response (matrix
exponential of the oscillator driven by the harmonic).  Before, the end force was taken at the unknown's
time ``t_n + h`` under generalized-alpha (first order, 2.4e-2 vs 1.4e-3 at h = 4 ms) and at ``t_n + theta h``
under Wilson-theta (not the scheme's extrapolated load).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

import ctmm
from ctmm.elements import Fixed, Free, Mass, PrescribedForce, SpringDamper
from ctmm.signals import Harmonic

MASS, STIFFNESS, DAMPING = 1.0, 400.0, 4.0            # [kg], [N/m], [N s/m]; natural frequency 20 rad/s
AMPLITUDE, OMEGA, PHASE = 3.0, 13.0, 0.3              # [N], [rad/s], [rad]
SCHEMES = ("newmark", "generalized_alpha", "wilson_theta", "houbolt")


def _end_loaded() -> ctmm.Chain:
    return ctmm.Chain("end", [Fixed("s"), SpringDamper("k", STIFFNESS, DAMPING), Mass("m", MASS),
                              PrescribedForce("f", Harmonic(AMPLITUDE, OMEGA, PHASE))])


def _mass_loaded() -> ctmm.Chain:
    return ctmm.Chain("mass", [Fixed("s"), SpringDamper("k", STIFFNESS, DAMPING),
                               Mass("m", MASS, force=Harmonic(AMPLITUDE, OMEGA, PHASE)), Free("f")])


def _exact(times: np.ndarray) -> np.ndarray:
    """Displacement [m] from rest of ``m x'' + c x' + k x = F sin(omega t + phase)``: the state
    ``(x, v, sin, cos)`` of the oscillator and its forcing is linear, so ``exp(A t)`` is exact."""
    A = np.array([[0.0, 1.0, 0.0, 0.0], [-STIFFNESS / MASS, -DAMPING / MASS, AMPLITUDE / MASS, 0.0],
                  [0.0, 0.0, 0.0, OMEGA], [0.0, 0.0, -OMEGA, 0.0]])
    start = np.array([0.0, 0.0, np.sin(PHASE), np.cos(PHASE)])
    return np.array([(expm(A * t) @ start)[0] for t in times])


@pytest.mark.parametrize("scheme", SCHEMES)
def test_an_end_force_is_the_same_force_on_the_mass(scheme):
    end = ctmm.simulate(_end_loaded(), 0.5, 2e-3, method=scheme)
    mass = ctmm.simulate(_mass_loaded(), 0.5, 2e-3, method=scheme)
    assert np.max(np.abs(end["m.x"] - mass["m.x"])) < 1e-12 * np.max(np.abs(mass["m.x"]))


@pytest.mark.parametrize("scheme", SCHEMES)
def test_an_end_force_keeps_the_scheme_second_order(scheme):
    errors = []
    for dt in (4e-3, 2e-3):
        result = ctmm.simulate(_end_loaded(), 2.0, dt, method=scheme)
        exact = _exact(result.time)
        errors.append(np.max(np.abs(result["m.x"] - exact)) / np.max(np.abs(exact)))
    assert errors[1] < 2e-3                             # (omega_n h)^2 = 1.6e-3 at h = 2 ms
    assert np.log2(errors[0] / errors[1]) > 1.9
