"""Time-history sensitivities of spatial models whose loads and driven joints carry ctmm.signals (issue 13).

A pendulum on a revolute joint forced by a sinusoidal moment (linear regime) against the closed-form forced
response from rest (its parameter derivatives by complex step of the closed form, and the steady amplitude's
mass derivative by hand); a chain with a driven joint and a step / sine load, alone and with a PD loop,
against central differences of two ``ctmm.simulate`` runs (the numpy RK4); the
refusals that remain (user callables, loop sensors moving with a driven joint, the frequency domain).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm import sensitivity as S
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.signals import Harmonic
from tests.test_compiled_spatial_signals import driven_chain
from tests.test_sensitivity import central_difference

pytest.importorskip("casadi")

MASS, ARM, INERTIA_XX, STIFFNESS, DAMPING, MOMENT, OMEGA, GRAVITY = 2.0, 0.5, 0.05, 3.0, 2.0, 1e-3, 3.0, 9.81
PENDULUM_NAMES = ["bob.mass", "bob.inertia.xx", "hinge.stiffness", "hinge.damping"]


def forced_pendulum() -> sp.SpatialModel:
    """A body hanging ``ARM`` below a revolute joint about x (spring, damper) under ``MOMENT sin(OMEGA t)``."""
    return sp.SpatialModel("pendulum", [
        sp.SpatialBody("bob", MASS, np.diag([INERTIA_XX, 0.06, 0.02]), center_of_mass=(0.0, 0.0, -ARM)),
        sp.Revolute(name="hinge", parent=None, child="bob", axis=(1, 0, 0), stiffness=STIFFNESS, damping=DAMPING),
        sp.Load("drive", "bob", moment=(Harmonic(MOMENT, OMEGA), 0.0, 0.0))], gravity=(0.0, 0.0, -GRAVITY))


def forced_response(t: np.ndarray, mass, inertia_xx, stiffness, damping):
    """``theta(t)`` of ``I theta'' + c theta' + (k + m g d) theta = M sin(w t)`` from rest, ``I = I_xx + m d^2``:
    the steady response ``a cos + b sin`` plus the damped free motion that starts it at rest (real formulas, so
    complex steps in the numbers give their derivatives)."""
    inertia, spring = inertia_xx + mass * ARM ** 2, stiffness + mass * GRAVITY * ARM
    detuning = spring - inertia * OMEGA ** 2
    delta = detuning ** 2 + (damping * OMEGA) ** 2
    a, b = -MOMENT * damping * OMEGA / delta, MOMENT * detuning / delta
    sigma = -damping / (2 * inertia)
    omega_d = np.sqrt(spring / inertia - sigma ** 2)
    first = -a
    second = -(sigma * first + b * OMEGA) / omega_d
    return (a * np.cos(OMEGA * t) + b * np.sin(OMEGA * t)
            + np.exp(sigma * t) * (first * np.cos(omega_d * t) + second * np.sin(omega_d * t)))


def test_forced_pendulum_history_and_amplitude_match_the_closed_form():
    # amplitude ~1e-4 rad: the linearisation error (sin q - q) is ~q^2/6 ~ 2e-9 relative, the RK4 error at 5 ms
    # (omega_n = 4.8 rad/s) ~1e-9; measured differences <= 1.2e-8, bound 1e-7.  After 20 s the free motion and its
    # derivatives are below 1e-14 of the steady ones (measured: 3e-15), so the last period is the steady response
    # (amplitude and dA/dm measured to 3.4e-9 and 3.0e-9)
    T, dt = 20.0, 5e-3
    found = S.simulation_sensitivity(forced_pendulum(), PENDULUM_NAMES, t_final=T, dt=dt, outputs=["hinge.angle"])
    base = [MASS, INERTIA_XX, STIFFNESS, DAMPING]
    expected = forced_response(found.time, *base)
    peak = np.max(np.abs(expected))
    assert np.max(np.abs(found.values[0] - expected)) < 1e-7 * peak
    for i, name in enumerate(PENDULUM_NAMES):
        shifted = [complex(x) for x in base]
        shifted[i] += 1e-30j
        slope = forced_response(found.time, *shifted).imag / 1e-30
        assert np.max(np.abs(found.derivative[i, 0] - slope)) < 1e-7 * np.max(np.abs(slope)), name
    # the steady amplitude A = M / |k + m g d - I w^2 + i c w| and dA/dm from the fitted last period
    last = found.time >= T - 2 * np.pi / OMEGA
    basis = np.column_stack([np.sin(OMEGA * found.time[last]), np.cos(OMEGA * found.time[last])])
    (s, c), (ds, dc) = (np.linalg.lstsq(basis, row[last], rcond=None)[0]
                        for row in (found.values[0], found.derivative[0, 0]))
    amplitude, amplitude_slope = np.hypot(s, c), (s * ds + c * dc) / np.hypot(s, c)
    inertia, spring = INERTIA_XX + MASS * ARM ** 2, STIFFNESS + MASS * GRAVITY * ARM
    detuning = spring - inertia * OMEGA ** 2
    delta = detuning ** 2 + (DAMPING * OMEGA) ** 2
    exact = MOMENT / np.sqrt(delta)
    exact_slope = -exact * detuning * (GRAVITY * ARM - ARM ** 2 * OMEGA ** 2) / delta
    assert abs(amplitude - exact) < 1e-7 * exact
    assert abs(amplitude_slope - exact_slope) < 1e-7 * abs(exact_slope)


@pytest.mark.parametrize("loop", [False, True])
def test_driven_joint_and_load_signals_match_differences_of_the_simulation(loop):
    # driven_chain: a revolute, a revolute driven by 0.4 sin(2 t + 0.3) in the middle, a ball joint, a step and
    # a sine force at the tip; outputs include a point and a rate outboard of the driven joint (they move with
    # its signal).  One central difference per number (h = 1e-4 |p|): truncation ~1e-8, round-off ~1e-12 relative;
    # measured relative error <= 2.9e-9, bound 1e-7 (b.mass; Richardson over 1e-3, 5e-4 gave <= 3.2e-11).
    # 40 RK4 steps of 5 ms (the derivative of the same discrete run is compared; the step load at 10 ms and the
    # driven joint's sine are inside the run)
    model = driven_chain()
    names = ["b.mass", "c.inertia.xx", "gravity.z"]
    if loop:
        model = with_feedback(model, [Feedback("pd", [("ja.angle", 8.0), ("ja.angle_rate", 0.5)], "ja.torque",
                                               gain=1.0)])
        names = ["a.mass", "pd.gain", "pd.ja.angle"]
    v0 = {"ja.angle_rate": 0.5, "jc.wx": 0.3}
    outputs = ["ja.angle", "jc.wx", "c.tip.z", "b.omega_y", "c.rotation_x"]          # a rotation vector too
    T, dt = 0.2, 5e-3
    found = S.simulation_sensitivity(model, names, t_final=T, dt=dt, v0=v0, outputs=outputs)

    def history(system):
        run = ctmm.simulate(system, T, dt, v0=v0, outputs=outputs, method="rk4")
        return np.array([run[name] for name in outputs])

    assert np.max(np.abs(found.values - history(model))) < 1e-12
    assert np.ptp(found.values[outputs.index("b.omega_y")]) > 0.1          # the driven joint moved body b
    for i, name in enumerate(names):
        expected = central_difference(history, model, name)
        assert np.max(np.abs(found.derivative[i] - expected)) < 1e-7 * np.max(np.abs(expected)), name


def test_what_stays_refused_with_time_signals():
    with pytest.raises(ModelError, match=r"without a symbolic form in load 'push' \(force\[0\] is a UserFunction"):
        S.simulation_sensitivity(driven_chain(force=(lambda t: t, 0.0, 0.0)), ["a.mass"], t_final=0.01, dt=1e-3)
    sensing = with_feedback(driven_chain(), [Feedback("pd", [("c.tip.x", 8.0)], "ja.torque", gain=1.0)])
    with pytest.raises(ModelError, match=r"sensor 'c.tip.x' moves with the time signals of the driven joints 'jb'"):
        S.simulation_sensitivity(sensing, ["pd.gain"], t_final=0.01, dt=1e-3)
    with pytest.raises(ModelError, match=r"frequency-domain sensitivities linearise about one equilibrium"):
        S.frequency_response_sensitivity(driven_chain(), ["a.mass"], [1.0], input="ja.torque", output="ja.angle")
