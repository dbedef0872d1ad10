"""Delay stability with roots on the imaginary axis that the loop cannot move (marginal systems).

Finding checked (issue: "no silent wrong answer"): on the undamped arm of docs/spatial.md §9 with a
delayed yaw loop, delay_margin reported "6 unstable roots at zero delay" with an uncertified
height of 6e27 rad/s and stability_chart "unstable": the link's pendulum modes and spin are
neither driven nor sensed by the yaw loop, so they stay on the imaginary axis for every gain and
delay.  Contract (as issue 11's "-1: a root on the imaginary axis"): every count of the counting
tools (delay_margin, stability_chart, root counts) is -1 and their certificate notes name those
roots as marginal; characteristic_roots lists them on the axis and notes them too.  Reference: the closed form of an undamped oscillator ``s^2 + w0^2 + (kp + kd s) e^{-s tau}``
(crossing where ``(w0^2 - W^2)^2 = kp^2 + kd^2 W^2``, ``e^{-i W tau} = (W^2 - w0^2)/(kp + i kd W)``),
with a second oscillator ``s^2 + 9`` (or ``s^2 + 0.2 s + 9``) beside it, not coupled to the loop.
"""
from __future__ import annotations

import math

import control
import numpy as np
import pytest

from ctmm.linearize import DelayedLoop, LinearizedSystem
from ctmm.stability import characteristic_roots, delay_margin
from ctmm.stability_chart import stability_chart

W0, KP, KD, DELAY = 2.0, 1.0, 0.5, 0.1


def _system(other_damping: float | None, delay: float = DELAY) -> LinearizedSystem:
    """Oscillator ``x'' + W0^2 x = u``, ``u = -(KP x + KD x')(t - delay)``; optionally a second
    oscillator ``z'' + c z' + 9 z = 0`` beside it that the loop neither drives nor senses."""
    A = np.array([[0.0, 1.0], [-W0 ** 2, 0.0]])
    B = np.array([[0.0], [1.0]])
    C = np.array([[KP, KD]])
    if other_damping is not None:
        A = np.block([[A, np.zeros((2, 2))], [np.zeros((2, 2)), np.array([[0.0, 1.0], [-9.0, -other_damping]])]])
        B = np.vstack([B, np.zeros((2, 1))])
        C = np.hstack([C, np.zeros((1, 2))])
    plant = control.ss(A, B, C, 0.0, inputs=["pd_u"], outputs=["pd_y"], name="oscillator")
    return LinearizedSystem(plant, (DelayedLoop("pd", 1.0, delay),), None)


def _closed_form() -> tuple[float, float]:
    """First crossing: frequency W [rad/s] and delay [s] of the characteristic quasi-polynomial."""
    squares = np.roots([1.0, -(2 * W0 ** 2 + KD ** 2), W0 ** 4 - KP ** 2])
    crossings = []
    for w in np.sqrt(squares[squares.real > 0].real):
        rotation = (w ** 2 - W0 ** 2) / (KP + 1j * KD * w)                  # = e^{-i W tau}, |.| = 1
        assert abs(abs(rotation) - 1) < 1e-12
        crossings.append((np.mod(-np.angle(rotation), 2 * math.pi) / w, w))
    tau, w = min(crossings)
    return float(w), float(tau)


@pytest.mark.parametrize("other_damping", [None, 0.2])
def test_delay_margin_of_the_undamped_oscillator_is_the_closed_form(other_damping):
    omega, tau = _closed_form()
    margin = delay_margin(_system(other_damping))
    assert margin.critical_delay == pytest.approx(tau, rel=1e-10)
    assert margin.critical_frequency == pytest.approx(omega, rel=1e-10)
    assert margin.stable and margin.unstable_roots_at_zero_delay == 0
    assert margin.margin == pytest.approx(tau - DELAY, rel=1e-9)
    roots = characteristic_roots(_system(other_damping, delay=tau), re_min=-0.5, im_max=10.0)
    near = np.argmin(np.abs(roots.roots - 1j * omega))
    assert abs(roots.roots[near] - 1j * omega) <= max(roots.error_estimates[near], 1e-9)


def _named(notes, marginal: str = "±3j") -> bool:
    return any(f"s = {marginal}" in note and "at best marginally stable" in note for note in notes)


def test_roots_the_loop_cannot_move_are_reported_marginal_by_every_tool():
    system = _system(0.0)
    margin = delay_margin(system)
    assert margin.unstable_roots_at_zero_delay == -1 and not margin.stable and margin.margin == 0.0
    assert margin.stable_intervals == () and _named(margin.certificate.notes)
    omega, tau = _closed_form()                   # the loop's own crossings are still exact
    assert margin.critical_delay == pytest.approx(tau, rel=1e-10)
    chart = stability_chart(system, ("delay", np.linspace(0.0, 0.5, 3)), ("gain", np.array([0.5, 1.0])))
    assert np.all(chart.unstable_roots == -1) and _named(chart.notes)
    roots = characteristic_roots(system, re_min=-0.5, im_max=10.0)
    fixed = np.abs(np.abs(roots.roots) - 3.0) < 1e-4
    assert fixed.sum() == 2 and np.allclose(roots.roots[fixed].imag, [-3.0, 3.0], atol=1e-4)
    assert np.all(np.abs(roots.roots[fixed].real) <= np.maximum(roots.error_estimates[fixed], 1e-9))
    assert _named(roots.certificate.notes)
    loop_roots = characteristic_roots(_system(None), re_min=-0.5, im_max=10.0).roots
    np.testing.assert_allclose(np.sort_complex(roots.roots[~fixed]), np.sort_complex(loop_roots), atol=1e-8)


def test_undamped_arm_of_the_spatial_guide_is_reported_marginal_naming_its_pendulum_modes_and_spin():
    """docs/spatial.md §9: the link hangs from a frictionless ball joint on the yaw axis, so the yaw
    loop neither drives nor senses it: compound-pendulum swings ``w^2 = m g d / (I + m d^2)`` about
    the link's y and z axes (inertias 0.01, 0.002 kg m^2, d = 0.25 m, m = 1 kg) and a free spin."""
    import re

    import ctmm.spatial as sp
    from ctmm.control import Feedback, with_feedback

    arm = sp.SpatialModel("arm", [
        sp.SpatialBody("base", 2.0, (0.02, 0.02, 0.01), center_of_mass=(0, 0, 0.1), points={"top": (0, 0, 0.2)}),
        sp.SpatialBody("link", 1.0, (0.01, 0.01, 0.002), center_of_mass=(0.25, 0, 0), points={"tip": (0.5, 0, 0)}),
        sp.Revolute(name="yaw", parent=None, child="base", axis=(0, 0, 1), actuated=True),
        sp.Spherical(name="ball", parent="base", point="top", child="link"),
    ], gravity=(0, 0, -9.81))
    pd = Feedback("pd", [("base.rotation_z", 3.0), ("base.omega_z", 0.4)], "yaw.torque", gain=1.0, delay=0.05)
    margin = delay_margin(with_feedback(arm, [pd]))
    assert margin.unstable_roots_at_zero_delay == -1 and not margin.stable
    note = next(n for n in margin.certificate.notes if "at best marginally stable" in n)
    listed = re.search(r"s = (.*?); the system", note).group(1)
    swings = sorted(float(w) for w in re.findall(r"±([0-9.]+)j", listed))
    exact = sorted(math.sqrt(1.0 * 9.81 * 0.25 / (inertia + 0.25 ** 2)) for inertia in (0.01, 0.002))
    np.testing.assert_allclose(swings, exact, rtol=1e-5)
    assert "0" in listed.split(", ")                          # the free spin of the link
