"""Beams in time: the DT-TMM with the Hermite time form of BeamField against analytic references.

References (independent of the transfer-matrix code): the exact modal superposition of the
clamped-free beam (analytic modes and frequencies of :mod:`ctmm.reference.beams`, 60 modes), the
same exact modes integrated by a scalar average-acceleration Newmark recursion (isolates the
mesh error), the static Euler-Bernoulli formulas and the pinned-pinned frequency
``(pi/L)^2 sqrt(EI/rho A)``.  The frequency-domain comparison uses the exact field matrix.

Error of the step load (a discontinuous load): the modal amplitudes fall like ``omega_k^-2`` and
the step's phase error of mode ``k`` is ``(omega_k dt)^2 omega_k t / 12`` until it saturates, so
the largest error comes from the modes near ``omega dt ~ 1`` and converges like ``dt`` (not
``dt^2``) in the maximum norm; a single smooth mode (pinned-pinned release) shows the second order.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import scipy.linalg

import ctmm
from ctmm.elements import (BeamClamped, BeamField, BeamFree, BeamHinge, BeamPinned, BeamPointLoad, BeamPointMass,
                           BeamSpring)
from ctmm.elements.beam_time import (FREQUENCY_TOLERANCE, BeamMeshWarning, BeamSegment, hermite_matrices,
                                     time_element_count)
from ctmm.errors import ModelError
from ctmm.schemes import GeneralizedAlpha
from ctmm.reference.beams import beta_roots, clamped_free_mode, omega_from_beta, pinned_pinned_tension_frequencies
from ctmm.signals import Harmonic

EI, RHO_A, L, F = 15.0, 0.8, 1.0, 2.0
STATIC_TIP = F * L ** 3 / (3 * EI)
BETAS = beta_roots("clamped-free", 60)
OMEGAS = omega_from_beta(BETAS, L, EI, RHO_A)
TIP_SHAPES = np.array([clamped_free_mode(b, 1.0) for b in BETAS])       # phi_k(1), int phi^2 = 1
Q_STATIC = F * TIP_SHAPES / (RHO_A * L * OMEGAS ** 2)                  # modal coordinates of the static tip load


def exact_tip_step(t: np.ndarray) -> np.ndarray:
    """Tip deflection [m] of the clamped-free beam under a tip force F applied at t = 0 (exact modes)."""
    return (TIP_SHAPES * Q_STATIC) @ (1.0 - np.cos(np.outer(OMEGAS, t)))


def newmark_modal_tip_step(t: np.ndarray, dt: float) -> np.ndarray:
    """The same, each exact mode integrated by average-acceleration Newmark with step ``dt`` [s]."""
    q, v, a = np.zeros_like(OMEGAS), np.zeros_like(OMEGAS), OMEGAS ** 2 * Q_STATIC
    tip = np.zeros(len(t))
    for i in range(1, len(t)):
        predicted = q + dt * v + dt * dt / 4 * a
        a_new = OMEGAS ** 2 * (Q_STATIC - predicted) / (1 + OMEGAS ** 2 * dt * dt / 4)
        v, q, a = v + dt / 2 * (a + a_new), predicted + dt * dt / 4 * a_new, a_new
        tip[i] = TIP_SHAPES @ q
    return tip


def cantilever(time_elements=None, *, load=F, **damping) -> ctmm.Chain:
    return ctmm.Chain("cantilever", [BeamClamped("root"),
                                     BeamField("beam", L, EI, RHO_A, time_elements=time_elements, **damping),
                                     BeamPointLoad("load", force=load), BeamFree("tip")])


def max_error(result, reference) -> float:
    return float(np.max(np.abs(result["tip.w"] - reference))) / STATIC_TIP


def test_tip_step_load_matches_modal_superposition_and_converges_in_dt():
    errors = [max_error(r, exact_tip_step(r.time)) for r in
              (ctmm.simulate(cantilever(), 0.3, dt) for dt in (2e-3, 1e-3, 5e-4))]
    assert errors[1] < 3e-3                       # measured 2.1e-3 of the static tip deflection
    assert errors[0] / errors[1] > 2.0 and errors[1] / errors[2] > 2.0, errors   # order >= 1 (measured 2.5, 2.6)


@pytest.mark.parametrize("scheme, bound", [("newmark", 3e-3), ("generalized_alpha", 3e-3), ("wilson_theta", 5e-3),
                                           ("houbolt", 8e-3), ("forward_euler", 5e-2)])
def test_every_scheme_steps_the_beam(scheme, bound):
    # measured at dt = 1e-3 over 0.3 s: 2.1e-3, 2.3e-3, 3.5e-3, 6.3e-3 (second order), 4.0e-2 (first order)
    result = ctmm.simulate(cantilever(), 0.3, 1e-3, scheme=scheme)
    assert max_error(result, exact_tip_step(result.time)) < bound


def test_mesh_convergence_against_the_exact_modes_integrated_alike():
    dt = 1e-3
    errors = []
    for count in (2, 4, 8):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result = ctmm.simulate(cantilever(count), 0.3, dt)
        assert any(issubclass(w.category, BeamMeshWarning) for w in caught) == (count < time_element_count(
            cantilever().element("beam"), dt))
        errors.append(max_error(result, newmark_modal_tip_step(result.time, dt)))
    assert errors[0] / errors[1] > 2.5 and errors[1] / errors[2] > 2.5, errors   # measured 3.1, 4.1
    assert errors[2] < 2e-3                                                      # measured 8.8e-4


def test_release_from_the_static_deflection_matches_modal_superposition():
    P = F            # the static shape under a tip force P: w = P x^2 (3L - x) / (6 EI)
    shape = lambda x: (P * x * x * (3 * L - x) / (6 * EI), P * x * (2 * L - x) / (2 * EI))  # noqa: E731
    result = ctmm.simulate(cantilever(load=0.0), 0.3, 1e-3, x0={"beam": shape})
    exact = (TIP_SHAPES * Q_STATIC) @ np.cos(np.outer(OMEGAS, result.time))
    assert result["tip.w"][0] == pytest.approx(STATIC_TIP, rel=1e-12)
    assert max_error(result, exact) < 3e-3


@pytest.mark.parametrize("scheme", ["forward_euler", "houbolt", GeneralizedAlpha(rho_infinity=0.0)])
def test_static_limit_is_the_analytic_cantilever(scheme):
    # a dissipative scheme at a step far beyond every period settles on the static solution
    result = ctmm.simulate(cantilever(), 200.0, 10.0, scheme=scheme)
    assert result["tip.w"][-1] == pytest.approx(STATIC_TIP, rel=1e-6)
    assert result["tip.theta"][-1] == pytest.approx(F * L ** 2 / (2 * EI), rel=1e-6)
    assert result["root.shear"][-1] == pytest.approx(-F, rel=1e-6)          # support holds the load
    assert result["root.moment"][-1] == pytest.approx(-F * L, rel=1e-6)


def test_static_spring_between_fields():
    k = 40.0                                      # tip on a spring: w = F / (k + 3 EI / L^3)
    chain = ctmm.Chain("propped", [BeamClamped("root"), BeamField("a", L / 2, EI, RHO_A), BeamPointMass("m", 0.1),
                                   BeamField("b", L / 2, EI, RHO_A), BeamSpring("k", k, 0.0),
                                   BeamPointLoad("load", force=F), BeamFree("tip")])
    result = ctmm.simulate(chain, 200.0, 10.0, scheme="forward_euler")
    assert result["tip.w"][-1] == pytest.approx(F / (k + 3 * EI / L ** 3), rel=1e-6)


def pinned_release(dt: float, time_elements: int | None = None, tension: float = 0.0) -> float:
    """Relative error of the free-vibration period of a pinned-pinned beam (tension [N]) released in mode 1."""
    amplitude = 1e-2

    def shape(x):
        return amplitude * math.sin(math.pi * x / L), amplitude * math.pi / L * math.cos(math.pi * x / L)

    halves = [BeamField(name, L / 2, EI, RHO_A, axial_force=tension, time_elements=time_elements) for name in "ab"]
    chain = ctmm.Chain("pinned", [BeamPinned("left"), halves[0], BeamPointLoad("mid"), halves[1], BeamPinned("right")])
    omega = pinned_pinned_tension_frequencies(1, L, EI, RHO_A, tension)[0]
    periods = 2
    t_final = dt * math.ceil(periods * 2 * math.pi / omega / dt + 5)
    result = ctmm.simulate(chain, t_final, dt, x0={"a": shape, "b": lambda x: shape(x + L / 2)})
    w, t = result["mid.w"], result.time
    assert w[0] == pytest.approx(amplitude, rel=1e-12)
    down = np.flatnonzero((w[:-1] > 0) & (w[1:] <= 0))       # downward zero crossings, linear interpolation
    crossings = t[down] + dt * w[down] / (w[down] - w[down + 1])
    period = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    return period * omega / (2 * math.pi) - 1


def test_pinned_pinned_period_and_second_order():
    omega = (math.pi / L) ** 2 * math.sqrt(EI / RHO_A)
    # default mesh: step (omega dt)^2/12 = 1.5e-4 and mesh (lambda h)^4/1440 errors, both below FREQUENCY_TOLERANCE
    assert 0 < pinned_release(1e-3) < 2e-3
    # fine mesh (mesh error 1e-6): Newmark's period elongation (omega dt)^2 / 12, second order
    coarse, fine = pinned_release(2e-3, 8), pinned_release(1e-3, 8)
    assert fine == pytest.approx((omega * 1e-3) ** 2 / 12, rel=0.05)
    assert coarse / fine == pytest.approx(4.0, rel=0.05)


def test_pinned_pinned_under_tension():
    tension = 50.0                               # omega_1 = (pi/L)^2 sqrt(EI/rho A) sqrt(1 + T L^2 / (EI pi^2))
    omega = pinned_pinned_tension_frequencies(1, L, EI, RHO_A, tension)[0]
    assert pinned_release(1e-3, 8, tension) == pytest.approx((omega * 1e-3) ** 2 / 12, rel=0.05)


def steady_amplitude_error(dt: float, omega: float, t_final: float = 1.5) -> float:
    """Relative error of the steady tip response (phasor fitted over the last two periods) vs the exact FRF."""
    elements = [BeamClamped("root"), BeamField("beam", L, EI, RHO_A, viscous_damping=20.0, kelvin_voigt_time=1e-3),
                BeamPointMass("m", 0.1), BeamPointLoad("load", force=Harmonic(F, omega)), BeamFree("tip")]
    chain = ctmm.Chain("harmonic", elements)
    exact = ctmm.frequency_response(chain, [omega], input="load.force", output="tip.w")("tip.w", "load.force")[0]
    result = ctmm.simulate(chain, t_final, dt)
    last = result.time >= t_final - 2 * (2 * math.pi / omega)    # transients decayed to ~2e-4 of the response
    t = result.time[last]
    (s, c), *_ = np.linalg.lstsq(np.column_stack([np.sin(omega * t), np.cos(omega * t)]), result["tip.w"][last],
                                 rcond=None)
    return abs(complex(s, c) / (F * exact) - 1)


def test_steady_harmonic_response_matches_the_exact_frequency_response():
    # 40 rad/s: between modes 1 and 2, inside the band 0.11/dt = 55 rad/s that the step (and the mesh) resolve
    coarse, fine = steady_amplitude_error(2e-3, 40.0), steady_amplitude_error(1e-3, 40.0)
    assert coarse < 2e-3 and fine < 6e-4             # measured 1.1e-3, 2.8e-4: second order
    assert coarse / fine > 3.0


@pytest.mark.parametrize("dt", [1e-3, 1e-4])
def test_default_mesh_resolves_every_mode_the_step_resolves(dt):
    field = BeamField("beam", L, EI, RHO_A)
    count = time_element_count(field, dt)
    K_e, KT_e, M_e = hermite_matrices(L / count, EI, RHO_A)
    K, M = np.zeros((2 * count + 2,) * 2), np.zeros((2 * count + 2,) * 2)
    for k in range(count):                        # assemble, then clamp node 0
        dofs = slice(2 * k, 2 * k + 4)
        K[dofs, dofs] += K_e + KT_e
        M[dofs, dofs] += M_e
    mesh = np.sqrt(scipy.linalg.eigh(K[2:, 2:], M[2:, 2:], eigvals_only=True))
    band = math.sqrt(12 * FREQUENCY_TOLERANCE) / dt
    in_band = OMEGAS[OMEGAS <= band]
    assert len(in_band) >= 2
    assert np.all(np.abs(mesh[:len(in_band)] / in_band - 1) <= FREQUENCY_TOLERANCE)


def test_segment_frequency_matrix_converges_to_the_exact_field():
    s = 1j * np.array([5.0, 20.0])
    errors = []
    for h in (0.5, 0.25, 0.125):
        exact = BeamField("b", h, EI, RHO_A).transfer_matrix(s)
        segment = BeamSegment("h", BeamField("b", 1.0, EI, RHO_A), h)
        errors.append(np.abs(segment.transfer_matrix(s) - exact).max() / np.abs(exact).max())
    assert errors[0] / errors[1] > 12 and errors[1] / errors[2] > 12, errors     # h^4 (16 per halving)


def test_refusals():
    with pytest.raises(ModelError, match="loss_factor"):
        ctmm.simulate(cantilever(loss_factor=0.02), 0.01, 1e-3)
    hinged = ctmm.Chain("h", [BeamClamped("root"), BeamField("a", L, EI, RHO_A), BeamHinge("hinge", 10.0),
                              BeamField("b", L, EI, RHO_A), BeamFree("tip")])
    with pytest.raises(ModelError, match="BeamHinge"):
        ctmm.simulate(hinged, 0.01, 1e-3)
    with pytest.raises(ModelError, match="callable shape"):
        ctmm.simulate(cantilever(), 0.01, 1e-3, x0={"beam": 0.1})
    with pytest.raises(ModelError, match="support"):
        ctmm.simulate(cantilever(), 0.01, 1e-3, x0={"root": 0.1})
    with pytest.raises(ModelError, match="pair"):
        ctmm.simulate(cantilever(), 0.01, 1e-3, x0={"load": (1.0, 2.0, 3.0)})
    with pytest.raises(ModelError, match="already given"):
        ctmm.simulate(cantilever(), 0.01, 1e-3, x0={"beam": lambda x: (x, 1.0), "load": 0.5})
    with pytest.raises(ModelError, match="time_elements"):
        BeamField("b", L, EI, RHO_A, time_elements=0)


def test_initial_values_at_points_and_velocities():
    # a tip mass given a velocity, the beam at rest: momentum M v0 at t0, the tip deflection starts at 0
    chain = ctmm.Chain("c", [BeamClamped("root"), BeamField("beam", L, EI, RHO_A), BeamPointMass("m", 0.5),
                             BeamFree("tip")])
    result = ctmm.simulate(chain, 2e-3, 1e-3, x0={"m": 0.0}, v0={"m": (0.1, 0.0)})
    assert result["m.w_dot"][0] == 0.1 and result["tip.w_dot"][0] == 0.1 and result["beam.w_dot"][0] == 0.1
    assert result["m.w"][0] == 0.0 and result["m.w"][1] == pytest.approx(0.1e-3, rel=0.05)
    with pytest.raises(ModelError, match="force hooks, feedback loops"):   # (a ControlledChain takes this path too)
        ctmm.simulate(cantilever(), 0.01, 1e-3, force_hook=lambda t_n, dt, w, history: {2: 1.0})
