"""The inerter (``ctmm.elements.Inerter``) in every chain verb, against independent references.

References: closed forms (one and two degrees of freedom), the global ``M, C, K`` model of
:mod:`ctmm.reference.inerter_chain` (the inerter in the mass matrix; ``eigh``, dense solves,
``solve_ivp``), and the delay-equation roots of :mod:`ctmm.reference.dde` (Chebyshev collocation
of the same global matrices).  The element law is rederived with sympy.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import ctmm
from ctmm import interop, stability
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Inerter, LumpedCoefficients, Mass, Spring
from ctmm.elements.base import Linearisation
from ctmm.guard import StabilityLimitWarning
from ctmm.reference import dde
from ctmm.reference import inerter_chain as ref
from ctmm.schemes import Newmark

MASSES = (1.0, 0.5, 0.8)
K1, K12, K3 = 97.0, 40.0, 60.0     # k1 = 100 would put m1's clamped resonance on the chart's grid (see the report)
B12, B23 = 0.3, 0.2


def chain(damping: float = 0.0, force: float = 0.0, k23: float = 0.0) -> ctmm.Chain:
    """Wall - k1 - m1 - (b12 | k12 | c) - m2 - (b23 | k23; pure inerter by default) - m3 - k3 - wall."""
    return ctmm.Chain("inerters", [
        Fixed("g"), Spring("k1", K1), Mass("m1", MASSES[0], force=force),
        Inerter("b12", B12, stiffness=K12, damping=damping), Mass("m2", MASSES[1]),
        Inerter("b23", B23, stiffness=k23), Mass("m3", MASSES[2]), Spring("k3", K3), Fixed("wall")])


def reference(damping: float = 0.0, k23: float = 0.0) -> ref.InerterChain:
    return ref.InerterChain(MASSES, [K1, K12, k23, K3], damping=[0.0, damping, 0.0, 0.0],
                            inertance=[0.0, B12, B23, 0.0], start="fixed", end="fixed")


# ------------------------------------------------------------------------------ element contract
def test_element_law_rederived_with_sympy():
    """U and u follow from f_out = f_in and f = -(b s^2 + c s + k)(x_out - x_in) + F (Smith 2002)."""
    sp = pytest.importorskip("sympy")
    s, b, c, k, F, x_in, f_in, x_out, f_out = sp.symbols("s b c k F x_in f_in x_out f_out")
    solved = sp.solve([sp.Eq(f_out, f_in), sp.Eq(f_out, -(b * s**2 + c * s + k) * (x_out - x_in) + F)],
                      [x_out, f_out], dict=True)[0]
    values = {b: 0.3, c: 0.7, k: 40.0}
    element = Inerter("b", 0.3, stiffness=40.0, damping=0.7)
    for s_value in (0.5 + 3.0j, 2.0j, -1.0 + 0.1j):
        U = element.transfer_matrix(np.array(s_value))
        u = element.load_vector(np.array(s_value), {"force": 1.0})
        subs = {**values, s: s_value, F: 0}
        expected_U = [[complex(sp.diff(solved[out], var).subs(subs)) for var in (x_in, f_in)] for out in (x_out, f_out)]
        expected_u = [complex(solved[out].subs({**subs, F: 1.0, x_in: 0, f_in: 0})) for out in (x_out, f_out)]
        np.testing.assert_allclose(U, expected_U, rtol=1e-14)
        np.testing.assert_allclose(u, expected_u, rtol=1e-14)
    assert element.transfer_matrix(np.array([1j, 2j, 3j])).shape == (3, 2, 2)
    assert element.lumped_coefficients() == LumpedCoefficients(True, 0.3, 0.7, 40.0, 0.0)


def test_step_matrices_match_the_law_at_the_step():
    """delta_out from f = -k (x_out - x_in - l) - c dv - b da + F with x = cx d + dx, v = A d + B, a = C d + D."""
    element = Inerter("b", 0.3, stiffness=40.0, damping=0.7, free_length=0.1)
    inboard = Linearisation(0.9, 0.02, 3.0, 0.4, 50.0, -1.0)
    outboard = Linearisation(0.9, 0.15, 3.0, -0.3, 50.0, 2.0)
    U, u = element.discretize(Newmark()).step_matrices(0.0, inboard, outboard, force=1.5)
    delta_in, f = 0.004, -2.0
    delta_out = U[0, 0] * delta_in + U[0, 1] * f + u[0]
    x = lambda lin, d: lin.cx * d + lin.dx  # noqa: E731
    v = lambda lin, d: lin.A * d + lin.B  # noqa: E731
    a = lambda lin, d: lin.C * d + lin.D  # noqa: E731
    law = (-40.0 * (x(outboard, delta_out) - x(inboard, delta_in) - 0.1)
           - 0.7 * (v(outboard, delta_out) - v(inboard, delta_in))
           - 0.3 * (a(outboard, delta_out) - a(inboard, delta_in)) + 1.5)
    assert law == pytest.approx(f, rel=1e-13)
    assert U[1, 1] * f + U[1, 0] * delta_in + u[1] == f


@pytest.mark.parametrize("kwargs, match", [
    ({"inertance": 0.0}, r"b: inertance must be > 0, got 0\.0"),
    ({"inertance": 1.0, "stiffness": -1.0}, r"b: stiffness must be >= 0, got -1\.0"),
    ({"inertance": 1.0, "damping": float("nan")}, r"b: damping"),
    ({"inertance": 1.0, "free_length": float("inf")}, r"b: free_length"),
])
def test_invalid_parameters_are_refused_by_name(kwargs, match):
    with pytest.raises(ctmm.ModelError, match=match):
        Inerter("b", **kwargs)


# ------------------------------------------------------------------------------ natural frequencies
def test_apparent_mass_one_degree_of_freedom():
    """Wall - inerter b with spring k - mass m - free: omega = sqrt(k / (m + b)) (the inerter adds mass)."""
    system = ctmm.Chain("one", [Fixed("g"), Inerter("b", 1.5, stiffness=90.0), Mass("m", 2.5), Free("e")])
    assert ctmm.natural_frequencies(system, n_modes=1)[0] == pytest.approx(np.sqrt(90.0 / 4.0), rel=1e-13)


def test_two_degrees_of_freedom_closed_form():
    """Wall - k1 - m1 - (b, k2) - m2 - free: det(K - w^2 M) = 0 is a quadratic in w^2,
    M = [[m1 + b, -b], [-b, m2 + b]], K = [[k1 + k2, -k2], [-k2, k2]]."""
    m1, m2, k1, k2, b = 1.0, 0.5, 100.0, 30.0, 0.2
    system = ctmm.Chain("two", [Fixed("g"), Spring("k1", k1), Mass("m1", m1), Inerter("b", b, stiffness=k2),
                                Mass("m2", m2), Free("e")])
    a2 = (m1 + b) * (m2 + b) - b * b
    a1 = -((k1 + k2) * (m2 + b) + k2 * (m1 + b) - 2 * k2 * b)
    a0 = (k1 + k2) * k2 - k2 * k2
    w2 = np.sort(np.roots([a2, a1, a0]).real)
    np.testing.assert_allclose(ctmm.natural_frequencies(system, n_modes=2), np.sqrt(w2), rtol=1e-13)


def test_counts_and_frequencies_against_global_eigh():
    """Sturm count with connector stiffness k - b w^2 (negative above sqrt(k/b), -b w^2 for a pure
    inerter) equals the count of eigh(K, M); also exactly at the connector zero w = sqrt(k12/b12)."""
    system, expected = chain(), ref.natural_frequencies(reference())
    np.testing.assert_allclose(ctmm.natural_frequencies(system, n_modes=3), expected, rtol=1e-12)
    omega = np.concatenate([np.linspace(0.0, 1.2 * expected[-1], 61), [np.sqrt(K12 / B12)],
                            expected * (1 - 1e-9), expected * (1 + 1e-9)])
    np.testing.assert_array_equal(ctmm.eigenvalue_count(system, omega), ref.count_below(reference(), omega))


def test_mode_shapes_against_global_eigenvectors():
    system = chain()
    modes = ctmm.mode_shapes(system, n_modes=3)
    M, _, K = ref.assemble(reference())
    import scipy.linalg as sla

    _, vectors = sla.eigh(K, M)
    points = [system.signal(f"m{i}.x").point for i in (1, 2, 3)]
    for k in range(3):
        shape = modes.shapes[k, points, 0]
        vector = vectors[:, k] * (shape[np.argmax(np.abs(shape))] / vectors[np.argmax(np.abs(shape)), k])
        np.testing.assert_allclose(shape, vector, atol=1e-10)


def test_modal_superposition_refuses_a_chain_with_inerters():
    """ctmm.modal weighs mode shapes with the point masses only: with inertance the shapes are not
    orthogonal in that weighting, and the verb refuses instead of superposing them."""
    from ctmm.modal import modal_response

    with pytest.raises(ctmm.ModelError, match="not mass-orthogonal"):
        modal_response(chain(k23=5.0), np.linspace(0.0, 0.1, 5), x0={"m2": 0.01})


# ------------------------------------------------------------------------------ frequency response
def test_frequency_response_and_internal_force_against_global_solve():
    """Inputs on a mass and across the inerter; outputs displacement, acceleration and the inerter's
    force ``-(b s^2 + c s + k)(x2 - x1) + F`` from the global dynamic stiffness."""
    system, rc = chain(damping=0.7), reference(damping=0.7)
    omega = np.array([0.5, 3.0, 7.0, np.sqrt(K12 / B12) * 1.01, 25.0])
    response = ctmm.frequency_response(system, omega, input=["m1.force", "b12.force"],
                                       output=["m3.x", "m2.a", "b12.f"])
    for column, force in enumerate(([1.0, 0.0, 0.0], [-1.0, 1.0, 0.0])):
        X = ref.frequency_response(rc, omega, force)
        s = 1j * omega
        across = 1.0 if column == 1 else 0.0
        inerter_force = -(B12 * s**2 + 0.7 * s + K12) * (X[:, 1] - X[:, 0]) + across
        np.testing.assert_allclose(response.response[0, column], X[:, 2], rtol=1e-11)
        np.testing.assert_allclose(response.response[1, column], s**2 * X[:, 1], rtol=1e-11)
        np.testing.assert_allclose(response.response[2, column], inerter_force, rtol=1e-10, atol=1e-13)


def test_at_the_connector_zero_the_answer_is_right_or_refused():
    """At w = sqrt(k/b) the inerter-spring transmits no force and its matrix has 1/(k - b w^2): within
    round-off of that zero the response is still the global one; exactly at it (k = 32, b = 2, w = 4)
    the element matrix is infinite, like a damper's at w = 0, and the solve refuses."""
    omega = np.sqrt(K12 / B12)
    response = ctmm.frequency_response(chain(), [omega], input="m1.force", output=["m1.x", "m3.x"])
    expected = ref.frequency_response(reference(), [omega], [1.0, 0.0, 0.0])[0, [0, 2]]
    np.testing.assert_allclose(response.response[:, 0, 0], expected, rtol=1e-9, atol=1e-16)
    exact = ctmm.Chain("exact", [Fixed("g"), Spring("k1", 100.0), Mass("m1", 1.0), Inerter("b", 2.0, stiffness=32.0),
                                 Mass("m2", 0.5), Free("e")])
    with pytest.raises(ctmm.SingularSystemError), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        ctmm.frequency_response(exact, [4.0], input="m1.force", output="m2.x")


def test_state_space_export_and_linearize_against_global_matrices():
    system, rc = chain(damping=0.7), reference(damping=0.7)
    ss = interop.to_state_space(system, inputs=["m1.force", "b12.force"], outputs=["m3.x", "b12.f", "m2.a"])
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(ss.A)),
                               np.sort_complex(np.linalg.eigvals(ref.state_matrix(rc))), rtol=1e-11)
    omega = np.array([1.0, 6.0, 20.0])
    for column, force in enumerate(([1.0, 0.0, 0.0], [-1.0, 1.0, 0.0])):
        X = ref.frequency_response(rc, omega, force)
        s = 1j * omega
        expected = [X[:, 2], -(B12 * s**2 + 0.7 * s + K12) * (X[:, 1] - X[:, 0]) + column, s**2 * X[:, 1]]
        got = np.array([ss(sk) for sk in s])[:, :, column]
        np.testing.assert_allclose(got.T, expected, rtol=1e-10, atol=1e-13)
    linearized = ctmm.linearize(system)
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(linearized.state_space.A)),
                               np.sort_complex(np.linalg.eigvals(ref.state_matrix(rc))), rtol=1e-11)


# ------------------------------------------------------------------------------ time domain
def _errors(scheme: str, dt: float, fast: bool) -> tuple[float, ctmm.results.SimulationResult]:
    t_final = 0.4
    result = ctmm.simulate(chain(damping=0.7, force=2.0), t_final, dt, scheme=scheme, x0={"m2": 0.01},
                           v0={"m3": -0.2}, fast=fast)
    x, _ = ref.time_response(reference(damping=0.7), result.time, [0.0, 0.01, 0.0], [0.0, 0.0, -0.2],
                             lambda t, x, v: np.array([2.0, 0.0, 0.0]))
    got = np.stack([result[f"m{i}.x"] for i in (1, 2, 3)], axis=1)
    return float(np.max(np.abs(got - x))), result


@pytest.mark.parametrize("scheme, order", [("newmark", 2), ("generalized_alpha", 2), ("wilson_theta", 2),
                                           ("houbolt", 2), ("forward_euler", 1)])
def test_every_scheme_converges_to_the_global_solution(scheme, order):
    """Both DT-TMM paths (vectorised lumped and generic step_matrices) converge at the scheme's order."""
    coarse, result = _errors(scheme, 2e-3, fast=True)
    fine, _ = _errors(scheme, 1e-3, fast=True)
    generic, result_generic = _errors(scheme, 1e-3, fast=False)
    assert result.info["path"] == "lumped-fast" and result_generic.info["path"] == "generic-riccati"
    assert coarse / fine > 0.8 * 2**order
    assert fine < (1e-5 if order == 2 else 2e-3)
    assert generic == pytest.approx(fine, rel=1e-6)


def test_initial_acceleration_and_force_from_the_coupled_equations():
    """At t0 the inerter couples the accelerations: a0 = M^-1 (F - K x0) with M holding b."""
    result = ctmm.simulate(chain(force=2.0), 0.01, 1e-3, x0={"m2": 0.01})
    a0 = ref.initial_acceleration(reference(), [0.0, 0.01, 0.0], [0.0, 0.0, 0.0], [2.0, 0.0, 0.0])
    np.testing.assert_allclose([result[f"m{i}.a"][0] for i in (1, 2, 3)], a0, rtol=1e-13)
    expected_force = -K12 * 0.01 - B12 * (a0[1] - a0[0])
    assert result["b12.f"][0] == pytest.approx(expected_force, rel=1e-13)


def test_conditionally_stable_scheme_is_not_certified_with_inerters():
    with pytest.warns(StabilityLimitWarning, match="inerters"):
        ctmm.simulate(chain(), 0.01, 1e-3, scheme=Newmark(beta=0.1, gamma=0.5), x0={"m2": 0.01})


# ------------------------------------------------------------------------------ control and stability
LOOP = np.outer([-1.0, 1.0, 0.0], [0.0, 0.0, 1.0])   # force e2 - e1 across b12 from x3 (or v3)


def _controlled(gain: float, delay: float, sensor: str = "m3.x", k23: float = 0.0) -> ControlledChain:
    """m3's displacement (velocity) fed back as a force across the inerter b12: u = -g y(t - tau)."""
    return ControlledChain(chain(damping=0.7, k23=k23), [Feedback("loop", sensor, "b12", gain=gain, delay=delay)])


def _reference_roots(gain: float, delay: float, velocity: bool = False, k23: float = 0.0,
                     box: tuple[float, float] = (-3.0, 25.0)) -> np.ndarray:
    """Roots of det(s^2 M + s C + K + g s^p e^(-s tau) LOOP) in ``Re s > box[0], |Im s| < box[1]``:
    Chebyshev collocation candidates, each polished by Newton and kept only with a tiny residual."""
    M, C, K = ref.assemble(reference(damping=0.7, k23=k23))
    zero = np.zeros((3, 3))
    A0, delayed = dde.second_order_system(M, C, K, [(zero, gain * LOOP, delay) if velocity
                                                    else (gain * LOOP, zero, delay)])
    candidates = dde.chebyshev_collocation_roots(A0, delayed, 120)
    roots = set()
    for candidate in candidates[(candidates.real > box[0] - 1) & (np.abs(candidates.imag) < box[1] + 5)]:
        root = dde.newton_refine_root(A0, delayed, candidate)
        s = root
        factor = gain * (s if velocity else 1.0) * np.exp(-s * delay)
        residual = abs(np.linalg.det(s * s * M + s * C + K + factor * LOOP)) / abs(np.linalg.det(s * s * M + s * C + K))
        if residual < 1e-10 and root.real > box[0] and abs(root.imag) < box[1]:
            roots.add(complex(round(root.real, 9), round(root.imag, 9)))
    return np.sort_complex(np.array(sorted(roots, key=lambda z: (z.real, z.imag))))


def test_delayed_loop_across_the_inerter_characteristic_roots():
    """Rightmost roots of the delayed loop (pure inerter b23 in the plant) equal the global ones."""
    roots = stability.characteristic_roots(_controlled(40.0, 0.05), re_min=-3.0, im_max=25.0)
    np.testing.assert_allclose(np.sort_complex(roots.roots), _reference_roots(40.0, 0.05), rtol=1e-9)


def test_unstable_root_count_and_delay_margin_against_global_characteristic():
    """Velocity feedback across b12 (b23 with a spring): stable without delay, destabilised at the margin."""
    system = _controlled(5.0, 0.0, sensor="m3.v", k23=5.0)
    assert int(stability.unstable_root_count(system, delay=0.3)[0]) == int(
        np.sum(_reference_roots(5.0, 0.3, velocity=True, k23=5.0, box=(0.0, 60.0)).real > 0))
    margin = stability.delay_margin(system)
    assert margin.unstable_roots_at_zero_delay == 0 and margin.stable
    M, C, K = ref.assemble(reference(damping=0.7, k23=5.0))
    s = 1j * margin.critical_frequency
    open_loop = s * s * M + s * C + K
    closed = open_loop + 5.0 * s * np.exp(-s * margin.critical_delay) * LOOP
    assert abs(np.linalg.det(closed)) < 1e-9 * abs(np.linalg.det(open_loop))
    below = _reference_roots(5.0, 0.999 * margin.critical_delay, velocity=True, k23=5.0, box=(-1.0, 60.0))
    assert below.size and np.all(below.real < 0)


def test_stability_chart_against_global_root_counts():
    """D-subdivision chart over (gain, delay) of the velocity loop across b12: the number of unstable
    roots at every grid point equals the count of the global delay equation's roots."""
    gains, delays = np.array([2.0, 5.0, 8.0]), np.array([0.05, 0.2, 0.35])
    chart = stability.stability_chart(_controlled(5.0, 0.0, sensor="m3.v", k23=5.0), ("gain", gains),
                                      ("delay", delays))
    expected = [[int(np.sum(_reference_roots(g, d, velocity=True, k23=5.0, box=(0.0, 80.0)).real > 0))
                 for g in gains] for d in delays]
    np.testing.assert_array_equal(chart.unstable_roots, expected)
    assert 0 < np.sum(chart.stable) < chart.stable.size


def test_closed_loop_frequency_response_with_the_exact_delay():
    """Delayed displacement loop across b12: the TMM response equals the global closed-loop solve
    (s^2 M + s C + K + g e^(-s tau) LOOP) X = F."""
    gain, delay = 40.0, 0.05
    omega = np.array([0.7, 4.0, 9.0, 17.0])
    response = ctmm.frequency_response(_controlled(gain, delay), omega, input="m1.force", output=["m3.x", "b12.f"])
    M, C, K = ref.assemble(reference(damping=0.7))
    for k, w in enumerate(omega):
        s = 1j * w
        X = np.linalg.solve(s * s * M + s * C + K + gain * np.exp(-s * delay) * LOOP, [1.0, 0.0, 0.0])
        u = -gain * np.exp(-s * delay) * X[2]
        inerter_force = -(B12 * s * s + 0.7 * s + K12) * (X[1] - X[0]) + u
        np.testing.assert_allclose(response.response[:, 0, k], [X[2], inerter_force], rtol=1e-10)


def test_unstable_root_count_with_a_pure_inerter_in_the_plant():
    """The pure inerter's b s^2 makes the sweep fail at s = 0 on the counting line (NaN, formerly a
    count of -1); the circle mean of ctmm.entire_values gives the finite value there."""
    system = _controlled(40.0, 0.05)
    counts = stability.unstable_root_count(system)
    expected = int(np.sum(_reference_roots(40.0, 0.05).real > 0))
    assert expected == 2 and int(counts[0]) == expected and counts.certificate.certified


def test_undelayed_loop_across_the_inerter_in_time():
    """Closed loop u = -g x3 across b12, simulated by ctmm.simulate, against solve_ivp."""
    gain = 25.0
    result = ctmm.simulate(_controlled(gain, 0.0), 0.4, 1e-3, x0={"m2": 0.01})
    x, _ = ref.time_response(reference(damping=0.7), result.time, [0.0, 0.01, 0.0], [0.0, 0.0, 0.0],
                             lambda t, x, v: -gain * LOOP @ x)
    got = np.stack([result[f"m{i}.x"] for i in (1, 2, 3)], axis=1)
    assert np.max(np.abs(got - x)) < 1e-5
    np.testing.assert_allclose(result["loop.u"], -gain * result["m3.x"], rtol=1e-12, atol=1e-15)


def test_sampled_controller_across_the_inerter_converges_at_second_order():
    """A zero-order-hold PD force across b12 from m3: at each sample the held force jumps and the
    accelerations restart by M^-1 dF (the inerter couples m1 and m2).  Reference: exact ZOH
    discretisation of the global first-order system by the matrix exponential."""
    import scipy.linalg

    from _controllers_import import load_controllers

    controllers = load_controllers()
    kp, kd, hold, n = 30.0, 1.5, 0.02, 30
    rc = reference(damping=0.7)
    M, _, _ = ref.assemble(rc)
    a = ref.state_matrix(rc)
    b = np.concatenate([np.zeros(3), np.linalg.solve(M, [-1.0, 1.0, 0.0])])[:, None]
    step = scipy.linalg.expm(np.block([[a, b], [np.zeros((1, 7))]]) * hold)
    z, exact = np.array([0.0, 0.01, 0.0, 0.0, 0.0, 0.0]), [0.01]
    for _ in range(n):
        z = step[:6, :6] @ z + step[:6, 6] * (-(kp * z[2] + kd * z[5]))
        exact.append(z[1])
    errors = []
    for dt in (hold / 2, hold / 4, hold / 8):
        pd = controllers.SaturatedPD(("m3.x", "m3.v"), ("b12.force",), kp=kp, kd=kd, sample_time=hold)
        run = ctmm.simulate(chain(damping=0.7), n * hold, dt, x0={"m2": 0.01}, controllers=[pd])
        errors.append(np.max(np.abs(run["m2.x"][::round(hold / dt)] - np.array(exact))))
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 1.8), (errors, orders)
