"""Generated DT-TMM schemes of planar models (:mod:`ctmm.compiled_scene_schemes`).

(1) the generated step equals the Python implicit stepper (:func:`ctmm.planar.implicit.simulate_implicit`) to
round-off for every scheme; (2) it equals each scheme written here in its global textbook form on the Lagrange
equations of :mod:`ctmm.reference.planar_lagrange` / :mod:`ctmm.reference.flexible_lagrange` (no transfer
matrices, no ctmm scheme code), solved by a finite-difference Newton to round-off, and converges at the
scheme's order against DOP853 of the same Lagrange model; (3) bad input is refused; (4) a step that does not
converge is a ConvergenceError with the result so far.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import ctmm
from ctmm.compiled_scene_schemes import CompiledSceneScheme, simulate_scheme_generated
from ctmm.errors import ConvergenceError, ModelError, SimulationError
from ctmm.flexible import ModalBeam
from ctmm.planar import Load, Pinned, PlanarModel, RigidBody, SpringDamperHinge, simulate_implicit
from ctmm.planar.elements import FixedMounting
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.schemes import SCHEMES, GeneralizedAlpha, Newmark, WilsonTheta
from ctmm.signals import Harmonic

VARIANTS = [*SCHEMES, WilsonTheta(1.0), GeneralizedAlpha(0.3), Newmark(beta=0.3, gamma=0.6)]


def _label(scheme) -> str:
    return scheme if isinstance(scheme, str) else repr(scheme)


def double_pendulum() -> PlanarModel:
    """Spring-damper hinge and a harmonic tip load (the evaluation time of Wilson-theta matters)."""
    return PlanarModel.chain("dp", [
        Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
        SpringDamperHinge("h", stiffness=4.0, damping=0.3, rest_angle=0.2),
        RigidBody.uniform_link("b", mass=0.7, length=0.8,
                               loads=(Load(point=(0.8, 0.0), force_y=Harmonic(2.0, 3.0)),))])


def hub_beam() -> PlanarModel:
    beam = ModalBeam("b", length=1.0, bending_stiffness=1.0, mass_per_length=0.7, n_modes=2)
    return PlanarModel.chain("hub-beam", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", angle=0.3), beam])


DP_START = (np.array([-0.6, -0.2]), np.array([0.5, -0.3]))


def _hub_start(model):
    q0, v0 = np.zeros(model.n_coordinates), np.zeros(model.n_coordinates)
    q0[:2], v0[0] = (0.3, 0.02), 2.0
    return q0, v0


@pytest.fixture(scope="module")
def pendulum():
    return double_pendulum()


@pytest.mark.parametrize("scheme", VARIANTS, ids=_label)
def test_generated_step_equals_the_python_implicit_stepper(pendulum, scheme):
    q0, v0 = DP_START
    generated = simulate_scheme_generated(pendulum, q0, v0, t_final=0.5, dt=0.01, scheme=scheme, store_every=3)
    python = simulate_implicit(pendulum, q0, v0, t_final=0.5, dt=0.01, scheme=scheme, store_every=3)
    assert np.array_equal(generated.t, python.t)
    assert np.max(np.abs(generated.q - python.q)) <= 1e-10
    assert np.max(np.abs(generated.qdot - python.qdot)) <= 1e-10
    assert generated.extra["newton_iterations"] <= 4 * 50          # quadratic Newton: a few per step


@pytest.mark.parametrize("scheme", ["newmark", "houbolt", "wilson_theta"])
def test_generated_step_equals_the_python_stepper_on_a_modal_beam(scheme):
    model = hub_beam()
    q0, v0 = _hub_start(model)
    generated = simulate_scheme_generated(model, q0, v0, t_final=0.1, dt=2e-3, scheme=scheme)
    python = simulate_implicit(model, q0, v0, t_final=0.1, dt=2e-3, scheme=scheme)
    assert np.max(np.abs(generated.q - python.q)) <= 1e-10
    assert np.max(np.abs(generated.qdot - python.qdot)) <= 1e-10


# ---------------------------------------------------------------- (2) independent global schemes
def newton_root(residual, guess):
    """Root of ``residual`` by Newton with a central-difference Jacobian, to round-off."""
    x = np.array(guess, dtype=float)
    for _ in range(50):
        r = residual(x)
        jacobian = np.empty((x.size, x.size))
        for j in range(x.size):
            e = np.zeros(x.size)
            e[j] = 1e-6 * (1.0 + abs(x[j]))
            jacobian[:, j] = (residual(x + e) - residual(x - e)) / (2.0 * e[j])
        dx = np.linalg.solve(jacobian, -r)
        x = x + dx
        if np.max(np.abs(dx)) <= 1e-15 * (1.0 + np.max(np.abs(x))):
            break
    return x


def global_scheme(f, q0, v0, h, n_steps, scheme):
    """The scheme in its textbook global form on ``qddot = f(q, v, t)``; returns ``q, v`` at every step."""
    q, v, a = np.array(q0, float), np.array(v0, float), f(q0, v0, 0.0)
    A = a.copy()                                       # the algorithmic acceleration (generalized-alpha)
    old = [q.copy(), q.copy()]
    qs, vs = [q], [v]
    for step in range(n_steps):
        t1 = (step + 1) * h
        name = scheme if isinstance(scheme, str) else type(scheme).__name__.lower()
        if name in ("newmark", "generalizedalpha", "generalized_alpha") or (name == "houbolt" and step < 2):
            if name == "houbolt":
                beta, gamma, am, af = 0.25, 0.5, 0.0, 0.0
            elif name == "newmark":
                beta, gamma, am, af = (0.25, 0.5, 0.0, 0.0) if isinstance(scheme, str) else (
                    scheme.beta, scheme.gamma, 0.0, 0.0)
            else:                                      # Chung & Hulbert's parameters, Arnold & Bruls' form
                rho = 0.8 if isinstance(scheme, str) else scheme.rho_infinity
                am, af = (2.0 * rho - 1.0) / (rho + 1.0), rho / (rho + 1.0)
                gamma, beta = 0.5 - am + af, 0.25 * (1.0 - am + af) ** 2

            def states(a1, beta=beta, gamma=gamma, am=am, af=af):
                A1 = ((1.0 - af) * a1 + af * a - am * A) / (1.0 - am)
                return (q + h * v + h * h * ((0.5 - beta) * A + beta * A1), v + h * ((1.0 - gamma) * A + gamma * A1),
                        A1)

            a1 = newton_root(lambda x: x - f(*states(x)[:2], t1), a)
            q1, v1, A = states(a1)
        elif name == "forwardeuler" or name == "forward_euler":
            a1 = newton_root(lambda x: x - f(q + h * (v + h * x), v + h * x, t1), a)
            q1, v1 = q + h * (v + h * a1), v + h * a1
            A = a1
        elif name in ("wilsontheta", "wilson_theta"):
            theta = 1.4 if isinstance(scheme, str) else scheme.theta
            tau = theta * h
            a_tau = newton_root(lambda x: x - f(q + tau * v + tau * tau / 6.0 * (2.0 * a + x),
                                            v + 0.5 * tau * (a + x), step * h + tau), a)
            a1 = a + (a_tau - a) / theta
            q1, v1 = q + h * v + h * h / 6.0 * (2.0 * a + a1), v + 0.5 * h * (a + a1)
            A = a1
        else:                                          # Houbolt after its start-up
            def rates(x):
                return ((2.0 * x - 5.0 * q + 4.0 * old[0] - old[1]) / (h * h),
                        (11.0 * x - 18.0 * q + 9.0 * old[0] - 2.0 * old[1]) / (6.0 * h))

            q1 = newton_root(lambda x: rates(x)[0] - f(x, rates(x)[1], t1), q + h * v)
            a1, v1 = rates(q1)
            A = a1
        old = [q, old[0]]
        q, v = q1, v1
        a = a1                                         # Wilson-theta: the interpolated acceleration
        qs.append(q)
        vs.append(v)
    return np.array(qs), np.array(vs)


@pytest.mark.parametrize("scheme", VARIANTS, ids=_label)
def test_generated_step_equals_the_global_scheme_on_the_lagrange_equations(pendulum, scheme):
    q0, v0 = DP_START
    reference = PlanarLagrange(pendulum)
    qs, vs = global_scheme(reference.accelerations, q0, v0, 0.02, 15, scheme)
    generated = simulate_scheme_generated(pendulum, q0, v0, t_final=0.3, dt=0.02, scheme=scheme)
    assert np.max(np.abs(generated.q - qs)) <= 1e-10
    assert np.max(np.abs(generated.qdot - vs)) <= 1e-10


@pytest.mark.parametrize("scheme", ["newmark", "generalized_alpha"])
def test_generated_step_equals_the_global_scheme_on_a_flexible_lagrange_model(scheme):
    model = hub_beam()
    q0, v0 = _hub_start(model)
    qs, vs = global_scheme(FlexibleLagrange(model).accelerations, q0, v0, 2e-3, 10, scheme)
    generated = simulate_scheme_generated(model, q0, v0, t_final=0.02, dt=2e-3, scheme=scheme)
    assert np.max(np.abs(generated.q - qs)) <= 1e-9
    assert np.max(np.abs(generated.qdot - vs)) <= 1e-9


@pytest.mark.parametrize("scheme, order", [("newmark", 2), ("generalized_alpha", 2), ("houbolt", 2),
                                           ("wilson_theta", 2), ("forward_euler", 1)])
def test_generated_schemes_converge_at_their_order(pendulum, scheme, order):
    q0, v0 = DP_START
    T = 0.8
    exact = PlanarLagrange(pendulum).simulate(q0, v0, T, t_eval=[T], rtol=1e-13, atol=1e-13).y[:2, -1]
    errors = [np.max(np.abs(simulate_scheme_generated(pendulum, q0, v0, t_final=T, dt=dt, scheme=scheme).q[-1]
                            - exact)) for dt in (0.02, 0.01, 0.005)]
    ratios = np.array(errors[:-1]) / errors[1:]
    assert np.all(np.abs(np.log2(ratios) - order) < 0.15), (errors, ratios)


# ---------------------------------------------------------------- (3) the verb, bad input
def test_the_verb_runs_the_generated_scheme_with_the_python_paths_numbers(pendulum):
    q0, v0 = DP_START
    x0 = dict(zip(pendulum.coordinates, q0))
    start = dict(zip(pendulum.coordinates, v0))
    generated = ctmm.simulate(pendulum, 0.2, 0.01, method="houbolt", x0=x0, v0=start, compiled=True, store_every=4)
    python = ctmm.simulate(pendulum, 0.2, 0.01, method="houbolt", x0=x0, v0=start, store_every=4)
    assert np.array_equal(generated.time, python.time)
    for name in python.signals():
        assert np.max(np.abs(generated[name] - python[name])) <= 1e-10, name


@pytest.mark.parametrize("options, match", [
    ({"dt": None}, "dt is required"),
    ({"method": "newmark2"}, "newmark2"),
    ({"method": "newmark", "rtol": 1e-6}, "rtol"),
    ({"method": "newmark", "inputs": {"h.torque": lambda t: t}}, "Python callable of time"),
    ({"method": "newmark", "store_every": 0}, "store_every"),
])
def test_bad_options_are_refused(pendulum, options, match):
    arguments = {"dt": 0.01, **options}
    with pytest.raises(ModelError, match=match):
        ctmm.simulate(pendulum, 0.1, arguments.pop("dt"), compiled=True, **arguments)


def test_bad_scheme_and_newton_options_are_refused(pendulum):
    with pytest.raises(ModelError, match="beta"):
        Newmark(beta=-1.0)
    with pytest.raises(ModelError, match="max_iterations"):
        CompiledSceneScheme(pendulum, "newmark", max_iterations=0)
    with pytest.raises(ModelError, match="tolerance"):
        CompiledSceneScheme(pendulum, "newmark", tolerance=-1.0)
    with pytest.raises(ModelError, match="dt is required"):
        simulate_scheme_generated(pendulum, *DP_START, t_final=0.1, dt=None)
    with pytest.raises(ModelError, match="PlanarModel"):
        CompiledSceneScheme("pendulum")


@dataclasses.dataclass(frozen=True)
class _TimeScaled(Newmark):
    """A Newmark variant with a time scale of its own (beta depends on the step): not scalable."""

    def second_order_step(self, history, h):
        return dataclasses.replace(Newmark(beta=0.25 + h, gamma=0.5)).second_order_step(history, h)


def test_a_scheme_with_a_time_scale_of_its_own_is_refused(pendulum):
    with pytest.raises(ModelError, match="time scale"):
        simulate_scheme_generated(pendulum, *DP_START, t_final=0.1, dt=0.01, scheme=_TimeScaled())


# ---------------------------------------------------------------- (4) failures
def test_a_step_that_does_not_converge_is_a_convergence_error_with_the_result_so_far(pendulum):
    with pytest.raises(ConvergenceError, match=r"step 1 \(t = 0.05 s\) did not converge") as info:
        simulate_scheme_generated(pendulum, *DP_START, t_final=0.5, dt=0.05, max_iterations=1)
    assert info.value.time == pytest.approx(0.05)
    partial = info.value.partial_result
    assert partial.t.tolist() == [0.0] and np.array_equal(partial.q[0], DP_START[0])


def test_divergence_bound_stops_the_generated_scheme_with_a_partial_result(pendulum):
    with pytest.raises(SimulationError) as info:
        ctmm.simulate(pendulum, 1.0, 0.01, method="newmark", compiled=True, divergence_bound=0.05,
                      x0=dict(zip(pendulum.coordinates, DP_START[0])), v0=dict(zip(pendulum.coordinates, DP_START[1])))
    partial = info.value.partial_result
    assert 0.0 < partial.time[-1] < 1.0
    assert info.value.time is not None and info.value.time > partial.time[-1]


def test_open_loop_signal_inputs_run_in_the_generated_scheme_without_loops():
    """A hinge torque that is a ctmm.signals function of time, no loop, a DT-TMM scheme: ``compiled=True`` runs it
    in the generated step with loops (none; it refused the signal as "held numbers").  A rod turning freely without
    gravity: ``J theta'' = A sin(w t)``, ``theta = A / (J w^2) (w t - sin(w t))``, ``J = m L^2 / 3``, to the
    scheme's second order; the numpy scheme to round-off."""
    from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
    from ctmm.signals import Harmonic

    rod = PlanarModel.chain("rod", [Fixed("g"), SmoothHinge("pivot"), RigidBody.uniform_link("rod", mass=1.0, length=1.0)],
                            gravity=(0.0, 0.0))
    amplitude, omega, dt = 0.5, 3.0, 1e-3
    inputs = {"pivot.torque": Harmonic(amplitude, omega)}
    generated = ctmm.simulate(rod, t_final=0.5, dt=dt, method="newmark", inputs=inputs, compiled=True)
    numpy_run = ctmm.simulate(rod, t_final=0.5, dt=dt, method="newmark", inputs=inputs, compiled=False)
    t = generated.time
    exact = amplitude / (omega ** 2 / 3.0) * (omega * t - np.sin(omega * t))
    assert np.max(np.abs(generated["rod.theta"] - exact)) <= (omega * dt) ** 2 * np.max(exact)
    assert np.max(np.abs(generated["rod.theta"] - numpy_run["rod.theta"])) <= 1e-14
