"""Delay stability of linearised models (issue 12): a planar pendulum chain with delayed PD.

The pendulum chain (``ctmm.planar``: a motor ``ActuatedHinge`` at the ground, damper hinges
between the links) hangs at rest; the delayed PD loop ``u = -(kp motor.angle + kd motor.rate)(t - tau)``
acts on the motor torque.  References, independent of the stability tools and of the TMM:

* the linearised Lagrange equations ``M q'' + C q' + K q = e_0 u`` of
  ``ctmm/reference/planar_lagrange.py``;
* the delay margin from the Walton-Marshall formula of the quasi-polynomial
  ``P(s) + Q(s) e^{-s tau}`` (polynomial determinants by cofactor expansion, crossing frequencies
  as the roots of ``P(s)P(-s) - Q(s)Q(-s)`` in ``s^2``);
* chart cells from the Chebyshev collocation roots of the delay equation
  (``ctmm/reference/dde.py``, Breda-Maset-Vermiglio).
"""
from __future__ import annotations

import math
from typing import Any, NamedTuple

import control
import numpy as np
import numpy.polynomial.polynomial as npoly
import pytest

from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.planar import ActuatedHinge, DamperHinge, Fixed, PlanarModel, RigidBody
from ctmm.planar.elements import FixedMounting
from ctmm.reference.dde import chebyshev_collocation_roots
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.stability import characteristic_roots, delay_margin, gain_margin, stability_chart, unstable_root_count
from ctmm.state_space_characteristic import StateSpaceCharacteristic

KP, KD = 6.0, 2.0          # PD gains [N m/rad], [N m s/rad]


class Loop(NamedTuple):        # the DelayedLoop contract of ctmm.linearize
    name: str
    gain: Any
    delay: float


class Linearised(NamedTuple):  # the LinearizedSystem contract of ctmm.linearize
    state_space: Any
    delays: tuple
    operating_point: Any = None


def pendulum(n_links: int = 2, damping: float = 0.15) -> PlanarModel:
    elements: list = [Fixed("ground"), ActuatedHinge("motor")]
    for i in range(n_links):
        if i:
            elements.append(DamperHinge(f"h{i}", damping=damping))
        elements.append(RigidBody.uniform_link(f"l{i}", mass=1.0 - 0.2 * i, length=0.8 - 0.1 * i))
    return PlanarModel.chain("pendulum", elements)


def reference_mck(model: PlanarModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lagrange ``M, C, K`` about the hanging equilibrium (every link straight down)."""
    q_eq = np.full(model.n_coordinates, -0.5 * math.pi)
    return PlanarLagrange(model).linearize(q_eq)


def reference_state_space(model: PlanarModel, kp: float = KP, kd: float = KD):
    """``x = [q, q']``, input the motor torque, output ``kp q_0 + kd q_0'`` (the loop's y)."""
    M, C, K = reference_mck(model)
    n = M.shape[0]
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ K, -Minv @ C]])
    B = np.concatenate([np.zeros(n), Minv[:, 0]])[:, None]
    Cy = np.zeros((1, 2 * n))
    Cy[0, 0], Cy[0, n] = kp, kd
    return A, B, Cy


def linearised(model: PlanarModel, gain: float, delay: float) -> Linearised:
    A, B, Cy = reference_state_space(model)
    ss = control.ss(A, B, Cy, np.zeros((1, 1)), inputs=["pd_u"], outputs=["pd_y"])
    return Linearised(ss, (Loop("pd", gain, delay),))


# ---------------------------------------------------------------------------------- references
def _poly_det(matrix: list) -> np.ndarray:
    """Determinant of a matrix of polynomials (coefficients, ascending) by cofactor expansion."""
    if len(matrix) == 1:
        return np.asarray(matrix[0][0], float)
    out = np.zeros(1)
    for j, entry in enumerate(matrix[0]):
        minor = [row[:j] + row[j + 1:] for row in matrix[1:]]
        out = npoly.polyadd(out, (-1) ** j * npoly.polymul(entry, _poly_det(minor)))
    return out


def quasi_polynomial(model: PlanarModel, gain: float) -> tuple[np.ndarray, np.ndarray]:
    """``(P, Q)`` with ``Delta(s) = P(s) + Q(s) e^{-s tau}`` (ascending coefficients)."""
    M, C, K = reference_mck(model)
    n = M.shape[0]
    Z = [[[K[i, j], C[i, j], M[i, j]] for j in range(n)] for i in range(n)]
    P = _poly_det(Z)
    Z[0][0] = list(npoly.polyadd(Z[0][0], [gain * KP, gain * KD]))
    return P, npoly.polysub(_poly_det(Z), P)


def walton_marshall_critical_delay(model: PlanarModel, gain: float) -> tuple[float, float]:
    """Smallest delay with a root ``s = i omega`` and its ``omega`` for the rigid pendulum chain."""
    return walton_marshall(*quasi_polynomial(model, gain))


def walton_marshall(P: np.ndarray, Q: np.ndarray) -> tuple[float, float]:
    """Smallest delay with a root ``s = i omega`` of ``P + Q e^{-s tau}``: ``|P(i w)| = |Q(i w)|``."""

    def mirrored(p):                                    # p(-s)
        return p * (-1.0) ** np.arange(p.size)

    R = npoly.polysub(npoly.polymul(P, mirrored(P)), npoly.polymul(Q, mirrored(Q)))
    even = R[::2]                                       # R(s) = sum even[k] (s^2)^k
    z = npoly.polyroots(even)
    z = z[(np.abs(z.imag) < 1e-9 * np.abs(z)) & (z.real < 0)].real
    best = (math.inf, math.nan)
    for omega in np.sqrt(-z):
        for _ in range(3):                              # Newton polish on R(i omega) (real)
            s = 1j * omega
            value = npoly.polyval(s, R).real
            slope = (npoly.polyval(s, npoly.polyder(R)) * 1j).real
            omega -= value / slope
        s = 1j * omega
        tau = np.mod(-np.angle(-npoly.polyval(s, P) / npoly.polyval(s, Q)), 2 * math.pi) / omega
        best = min(best, (float(tau), float(omega)))
    return best


def collocation_counts(model: PlanarModel, gains: np.ndarray, delays: np.ndarray, nodes: int = 40):
    """Unstable roots (Re s > 0) and the rightmost real part per (delay, gain) cell."""
    A, B, Cy = reference_state_space(model)
    counts = np.zeros((delays.size, gains.size), int)
    abscissa = np.zeros((delays.size, gains.size))
    for r, tau in enumerate(delays):
        for c, k in enumerate(gains):
            roots = chebyshev_collocation_roots(A, [(-k * B @ Cy, tau)], nodes)
            roots = roots[np.abs(roots) < 0.5 * nodes / tau]        # converged part of the spectrum
            counts[r, c] = int(np.sum(roots.real > 0))
            abscissa[r, c] = roots.real.max()
    return counts, abscissa


# ---------------------------------------------------------------------------------- tests
@pytest.mark.parametrize("n_links", [2, 3])
def test_delay_margin_of_a_linearised_pendulum_chain_matches_walton_marshall(n_links):
    model = pendulum(n_links)
    tau_ref, omega_ref = walton_marshall_critical_delay(model, 1.0)
    margin = delay_margin(linearised(model, 1.0, 0.02))
    assert abs(margin.critical_delay - tau_ref) <= 1e-6 * tau_ref
    assert abs(margin.critical_frequency - omega_ref) <= 1e-6 * omega_ref
    assert margin.stable and margin.unstable_roots_at_zero_delay == 0
    assert margin.certificate.certified and margin.certificate.source == "bound"
    # the roots cross there: stable just below, a pair in the right half plane just above
    A, B, Cy = reference_state_space(model)
    for tau, expected in ((0.999 * tau_ref, 0), (1.001 * tau_ref, 2)):
        roots = chebyshev_collocation_roots(A, [(-B @ Cy, tau)], 40)
        assert int(np.sum(roots[np.abs(roots) < 20 / tau].real > 0)) == expected


def test_stability_chart_of_a_linearised_pendulum_chain_matches_collocation():
    model = pendulum(2)
    gains = np.linspace(0.15, 2.5, 9)
    delays = np.linspace(0.03, 0.6, 8)
    chart = stability_chart(linearised(model, 1.0, 0.1), x=("gain", gains), y=("delay", delays), verify=True)
    expected, abscissa = collocation_counts(model, gains, delays)
    assert chart.verified and chart.certificate.certified
    assert np.all(np.abs(abscissa) > 1e-4)                      # no cell on a boundary
    assert np.array_equal(chart.unstable_roots, expected)
    assert 0 < chart.stable_fraction < 1                        # both regions are in the chart
    counts = unstable_root_count(linearised(model, 1.0, 0.1), gain=gains[3], delay=delays)
    assert np.array_equal(counts, expected[:, 3])
    threaded = stability_chart(linearised(model, 1.0, 0.1), x=("gain", gains), y=("delay", delays),
                               executor="threads")
    assert np.array_equal(threaded.unstable_roots, expected)


def test_other_delay_free_loops_are_closed_into_the_open_loop():
    # a delay-free rate loop across hinge h1 is an extra damper there: u = -c (q1' - q0')
    base, damped = pendulum(2), pendulum(2, damping=0.15 + 0.4)
    A, B, Cy = reference_state_space(base)
    M, _, _ = reference_mck(base)
    b_h1 = np.concatenate([np.zeros(2), np.linalg.solve(M, [-1.0, 1.0])])
    c_h1 = np.array([0.0, 0.0, -1.0, 1.0])
    ss = control.ss(A, np.column_stack([B[:, 0], b_h1]), np.vstack([Cy, c_h1]), np.zeros((2, 2)),
                    inputs=["pd_u", "extra_u"], outputs=["pd_y", "extra_y"])
    lin = Linearised(ss, (Loop("pd", 1.0, 0.05), Loop("extra", 0.4, 0.0)))
    tau_ref, _ = walton_marshall_critical_delay(damped, 1.0)
    assert abs(delay_margin(lin, "pd").critical_delay - tau_ref) <= 1e-6 * tau_ref
    assert abs(tau_ref - walton_marshall_critical_delay(base, 1.0)[0]) > 1e-3 * tau_ref   # the loop matters


def test_gain_margin_of_a_linearised_pendulum_chain_brackets_the_collocation_switch():
    model = pendulum(2)
    margin = gain_margin(linearised(model, 1.0, 0.1))
    assert margin.stable and 1.0 < margin.upper < math.inf and margin.certificate.certified
    A, B, Cy = reference_state_space(model)
    for factor, expected in ((0.999 * margin.upper, 0), (1.001 * margin.upper, 2)):
        roots = chebyshev_collocation_roots(A, [(-factor * B @ Cy, 0.1)], 40)
        assert int(np.sum(roots[np.abs(roots) < 200.0].real > 0)) == expected


def test_characteristic_roots_of_a_linearised_model_match_collocation():
    model = pendulum(2)
    lin = linearised(model, 1.0, 0.2)
    found = characteristic_roots(lin, re_min=-1.5, im_max=30.0, re_max=2.0)
    A, B, Cy = reference_state_space(model)
    reference = chebyshev_collocation_roots(A, [(-B @ Cy, 0.2)], 60, refine=12)
    reference = reference[(reference.real > -1.5) & (np.abs(reference.imag) <= 30.0)]
    assert len(found.roots) == reference.size
    for root in reference:
        assert np.min(np.abs(np.asarray(found.roots) - root)) < 1e-8 * max(1.0, abs(root))


def test_lti_controller_and_sensor_weights_enter_the_characteristic_exactly():
    # unit mass, y = x + 0.5 v, low-pass controller C(s) = 3/(s + 4): Delta ~ s^2 (s+4) + 3 k (1 + 0.5 s) e^{-s tau}
    ss = control.ss([[0, 1], [0, 0]], [[0], [1]], [[1, 0], [0, 1]], np.zeros((2, 1)),
                    inputs=["m_force"], outputs=["m_x", "m_v"])
    loop_ss = control.ss(ss.A, ss.B, [[1.0, 0.5]], [[0.0]], inputs=["c_u"], outputs=["c_y"])
    model = StateSpaceCharacteristic(Linearised(loop_ss, (Loop("c", control.tf([3.0], [1.0, 4.0]), 0.3),)))
    s = np.array([0.4 + 1.7j, -0.2 + 5.0j])
    d = model.evaluate(s, gain=[1.0, 2.5], delay=[0.3, 0.1])

    def exact(k, tau):
        return s ** 2 * (s + 4) + 3 * k * (1 + 0.5 * s) * np.exp(-s * tau)

    assert np.allclose(d[1] / d[0], exact(2.5, 0.1) / exact(1.0, 0.3), rtol=1e-12, atol=0)
    assert model.gain == 1.0 and model.parameter_names == ("gain", "delay", "c.y")


def test_refusals_name_what_is_wrong():
    model = pendulum(2)
    lin = linearised(model, 1.0, 0.1)
    two = Linearised(lin.state_space, (Loop("pd", 1.0, 0.1), Loop("other", 1.0, 0.2)))
    with pytest.raises(ModelError, match="loop.*'pd'|available: other, pd"):
        delay_margin(two)
    with pytest.raises(ModelError, match=r"\['other'\] also have a delay"):
        delay_margin(two, "pd")
    with pytest.raises(ModelError, match="unknown loop 'nope'"):
        delay_margin(lin, "nope")
    with pytest.raises(ModelError, match="has none"):
        delay_margin(Linearised(lin.state_space, ()))
    with pytest.raises(ModelError, match="unknown input of loop 'x'.*pd_u"):
        delay_margin(Linearised(lin.state_space, (Loop("x", 1.0, 0.1),)))
    with pytest.raises(ModelError, match="PlanarModel with no loop"):
        stability_chart(model, x=("gain", [1.0, 2.0]), y=("delay", [0.1, 0.2]))
    with pytest.raises(ModelError, match="delay must be finite and >= 0"):
        delay_margin(Linearised(lin.state_space, (Loop("pd", 1.0, -0.1),)))


def _controlled_pendulum(n_links: int, delay: float):
    pytest.importorskip("ctmm.linearize", reason="ctmm.linearize (issue 12, LIN) not merged yet")
    from ctmm.control import Feedback, with_feedback

    pd = Feedback("pd", [("motor.angle", KP), ("motor.rate", KD)], "motor.torque", gain=1.0, delay=delay)
    return with_feedback(pendulum(n_links), [pd])


@pytest.mark.parametrize("n_links", [2, 3])
def test_controlled_planar_pendulum_delay_margin_matches_the_lagrange_reference(n_links):
    system = _controlled_pendulum(n_links, 0.02)
    tau_ref, omega_ref = walton_marshall_critical_delay(pendulum(n_links), 1.0)
    margin = delay_margin(system)
    assert abs(margin.critical_delay - tau_ref) <= 1e-6 * tau_ref
    assert abs(margin.critical_frequency - omega_ref) <= 1e-6 * omega_ref
    assert margin.stable and margin.certificate.certified
    # the LinearizedSystem of the controlled model itself: loop left open as "pd_u" / "pd_y"
    import ctmm

    linear = ctmm.linearize(system)
    assert [loop.name for loop in linear.delays] == ["pd"]
    assert abs(delay_margin(linear).critical_delay - tau_ref) <= 1e-6 * tau_ref


def test_controlled_planar_pendulum_charts_match_collocation():
    system = _controlled_pendulum(2, 0.1)
    model = pendulum(2)
    gains = np.linspace(0.15, 2.5, 9)
    delays = np.linspace(0.03, 0.6, 8)
    chart = stability_chart(system, x=("gain", gains), y=("delay", delays))
    expected, _ = collocation_counts(model, gains, delays)
    assert np.array_equal(chart.unstable_roots, expected) and chart.certificate.certified
    # the PD gains as chart axes (sensor weights) at tau = 0.1 s
    kps, kds = np.linspace(0.5, 14.0, 7), np.linspace(0.2, 4.5, 6)
    chart = stability_chart(system, x=("motor.angle", kps), y=("motor.rate", kds))
    A, B, _ = reference_state_space(model)
    n = model.n_coordinates
    for r, kd in enumerate(kds):
        for c, kp in enumerate(kps):
            row = np.zeros((1, 2 * n))
            row[0, 0], row[0, n] = kp, kd
            roots = chebyshev_collocation_roots(A, [(-B @ row, 0.1)], 40)
            roots = roots[np.abs(roots) < 200.0]
            assert abs(roots.real.max()) > 1e-4
            assert chart.unstable_roots[r, c] == int(np.sum(roots.real > 0))
    assert 0 < chart.stable_fraction < 1


def _hub_beam(torque: float = 0.0) -> PlanarModel:
    return PlanarModel.chain("hub_beam", [
        Fixed("ground"), ActuatedHinge("motor", torque=torque),
        RigidBody("hub", mass=2.0, inertia=0.1, outboard=(0.1, 0.0)), FixedMounting("mount"),
        ModalBeam("beam", length=1.0, bending_stiffness=20.0, mass_per_length=0.5, n_modes=2, damping_ratio=0.01)])


def test_controlled_flexible_pendulum_delay_margin_matches_the_flexible_lagrange_reference():
    pytest.importorskip("ctmm.linearize", reason="ctmm.linearize (issue 12, LIN) not merged yet")
    from ctmm.control import Feedback, with_feedback

    model = _hub_beam()
    n = model.n_coordinates
    hub = model.coordinate_index("hub.theta")
    q0 = np.zeros(n)
    q0[hub] = -0.5 * math.pi                                 # hanging straight down, beam undeformed
    free, pushed = FlexibleLagrange(model), FlexibleLagrange(_hub_beam(torque=1.0))
    A = np.zeros((2 * n, 2 * n))                             # x' = A x + b u: central differences
    A[:n, n:] = np.eye(n)
    h = 1e-5
    for j in range(2 * n):
        e = np.zeros(2 * n)
        e[j] = h
        A[n:, j] = (free.accelerations(q0 + e[:n], e[n:]) - free.accelerations(q0 - e[:n], -e[n:])) / (2 * h)
    b = np.concatenate([np.zeros(n), pushed.accelerations(q0, np.zeros(n)) - free.accelerations(q0, np.zeros(n))])
    c = np.zeros(2 * n)
    c[hub], c[n + hub] = KP, KD
    P = np.poly(A)[::-1].real                                # det(sI - A), ascending
    Q = npoly.polysub(np.poly(A - np.outer(b, c))[::-1].real, P)
    tau_ref, omega_ref = walton_marshall(P, Q)
    pd = Feedback("pd", [("motor.angle", KP), ("motor.rate", KD)], "motor.torque", gain=1.0, delay=0.01)
    margin = delay_margin(with_feedback(model, [pd]))
    assert abs(margin.critical_delay - tau_ref) <= 1e-6 * tau_ref
    assert abs(margin.critical_frequency - omega_ref) <= 1e-6 * omega_ref
    assert margin.certificate.certified and omega_ref > 30.0         # a beam mode goes unstable first


def test_controlled_pendulum_with_an_lti_controller_matches_walton_marshall():
    pytest.importorskip("ctmm.linearize", reason="ctmm.linearize (issue 12, LIN) not merged yet")
    from ctmm.control import Feedback, with_feedback

    # u = -C(s) e^{-s tau} (kp angle + kd rate), C(s) = 1 / (0.02 s + 1): P (0.02 s + 1) + Q e^{-s tau}
    lag = control.tf([1.0], [0.02, 1.0])
    pd = Feedback("pd", [("motor.angle", KP), ("motor.rate", KD)], "motor.torque", gain=lag, delay=0.01)
    P, Q = quasi_polynomial(pendulum(2), 1.0)
    tau_ref, omega_ref = walton_marshall(npoly.polymul(P, [1.0, 0.02]), Q)
    margin = delay_margin(with_feedback(pendulum(2), [pd]))
    assert abs(margin.critical_delay - tau_ref) <= 1e-6 * tau_ref
    assert abs(margin.critical_frequency - omega_ref) <= 1e-6 * omega_ref
    assert margin.certificate.certified
