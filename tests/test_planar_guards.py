"""Run guards of the planar integrators (rigid, flexible, compiled): stability limits before the run,
divergence, partial results, named user-signal failures, validated state vectors (issue 11).

Stability limits are checked against independent frequencies: the compound pendulum
``sqrt(3 g / (2 L))`` and the linearised Lagrange model (:mod:`ctmm.reference.planar_lagrange`).
"""
from __future__ import annotations

import math
import shutil
import warnings

import numpy as np
import pytest

from ctmm.errors import ModelError, SimulationError
from ctmm.guard import StabilityLimitWarning
from ctmm.planar import (ActuatedHinge, DrivenHinge, Fixed, Load, Pinned, PlanarModel, RigidBody, accelerations,
                         simulate_implicit, simulate_rk4, simulate_scipy, solve_instant)
from ctmm.planar.guards import linearised_omega_max
from ctmm.planar.equilibrium import static_equilibrium
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.schemes import Newmark

from planar_helpers import uniform_chain

G = 9.81


def _pendulum() -> PlanarModel:
    return PlanarModel.chain("pendulum", [Pinned("o"), RigidBody.uniform_link("rod", mass=1.0, length=1.0)])


def test_omega_max_is_the_linearised_frequency():
    # compound pendulum hanging: sqrt(m g L/2 / (m L^2 / 3)) = sqrt(3 g / 2) for L = 1 m
    assert linearised_omega_max(_pendulum(), [-math.pi / 2], [0.0]) == pytest.approx(math.sqrt(1.5 * G), rel=1e-6)
    for n in (6, 30):            # dense Jacobian (n <= 20) and ARPACK (n > 20)
        model = uniform_chain(n)
        q_eq = static_equilibrium(model, np.full(n, -1.5))
        expected = PlanarLagrange(model).natural_frequencies(q_eq)[-1]
        assert linearised_omega_max(model, q_eq, np.zeros(n)) == pytest.approx(expected, rel=1e-4)


def test_rk4_pendulum_at_ten_seconds_is_refused_or_warned_and_stopped():
    """The issue's case: RK4 at dt = 10 s ended at thousands of radians without a word."""
    model = _pendulum()
    # 10 s * sqrt(3 g cos(0.1) / 2) = 38.26 about the initial state
    with pytest.raises(ModelError, match=r"RK4 .* omega_max \* dt = 38\.26 exceeds its limit 2\.828"):
        simulate_rk4(model, [-math.pi / 2 + 0.1], [0.0], t_final=1000.0, dt=10.0, stability_check="error")
    with pytest.warns(StabilityLimitWarning, match="use dt <= 0.7"):
        with pytest.raises(SimulationError, match=r"diverged at t = \d+ s: 'rod.theta'") as info:
            simulate_rk4(model, [-math.pi / 2 + 0.1], [0.0], t_final=1000.0, dt=10.0, divergence_bound=50.0)
    error = info.value
    assert error.element == "rod.theta" and error.time > 0
    partial = error.partial_result
    assert partial.t[-1] < error.time and np.all(np.abs(partial.q - partial.q[0]) <= 50.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        simulate_rk4(model, [-1.0], [0.0], t_final=0.2, dt=0.01)                  # within the limit: silent
        simulate_rk4(model, [-1.0], [0.0], t_final=20.0, dt=10.0, stability_check="ignore")


def test_newmark_parameters_are_checked_before_the_run():
    model = _pendulum()
    with pytest.warns(StabilityLimitWarning, match="not stable at any step size"):
        with pytest.raises(SimulationError):
            simulate_implicit(model, [-1.0], [0.0], t_final=200.0, dt=0.5, scheme=Newmark(beta=0.3, gamma=0.4),
                              divergence_bound=20.0)
    # beta = 0.01, gamma = 1/2: limit omega h <= 1 / sqrt(0.24) = 2.04; omega = 3.836 rad/s about the bottom
    with pytest.raises(ModelError, match=r"omega_max \* dt = 3\.836 exceeds its limit 2\.041"):
        simulate_implicit(model, [-math.pi / 2], [0.0], t_final=1.0, dt=1.0, scheme=Newmark(beta=0.01, gamma=0.5),
                          stability_check="error")
    with pytest.raises(ModelError, match="stability_check must be one of"):
        simulate_rk4(model, [-1.0], [0.0], t_final=1.0, dt=0.1, stability_check="loud")
    with pytest.raises(ModelError, match="store_every must be an integer >= 1, got 0"):
        simulate_implicit(model, [-1.0], [0.0], t_final=1.0, dt=0.1, store_every=0)
    with pytest.raises(ModelError, match="divergence_bound must be a number > 0"):
        simulate_rk4(model, [-1.0], [0.0], t_final=1.0, dt=0.1, divergence_bound=-1.0)


def _failing(after: float, value=float("nan")):
    """0 except on (after, after + 0.15) s (outside DrivenHinge's derivative checks at 0.0137, 0.5, ... s)."""
    def signal(t):
        if after < t < after + 0.15:
            if isinstance(value, Exception):
                raise value
            return value
        return 0.0
    return signal


@pytest.mark.parametrize("make, element, match", [
    (lambda f: [Fixed("g"), ActuatedHinge("motor", torque=f), RigidBody.uniform_link("l", mass=1.0, length=1.0)],
     "motor", "torque of 'motor'"),
    (lambda f: [Pinned("o"), RigidBody("l", mass=1.0, inertia=0.1, center_of_mass=(0.5, 0), outboard=(1.0, 0.0),
                                       loads=(Load(point=(1.0, 0.0), force_y=f),))],
     "load 0 of body 'l'", "force_y of load 0 of body 'l'"),
    (lambda f: [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
                DrivenHinge("drive", angle=lambda t: 0.1 * t, rate=lambda t: 0.1, acceleration=f),
                RigidBody.uniform_link("b", mass=1.0, length=1.0)],
     "drive", "acceleration of 'drive'"),
])
@pytest.mark.parametrize("value, what", [(float("nan"), "non-finite"), (ValueError("boom"), "raised ValueError"),
                                         (np.array([1.0, 2.0]), "returned 2 value")])
def test_failing_user_signals_are_named_with_time_and_partial_result(make, element, match, value, what):
    model = PlanarModel.chain("m", make(_failing(0.3, value)))
    q0, v0 = np.full(model.n_coordinates, -1.0), np.zeros(model.n_coordinates)
    runs = [lambda: simulate_rk4(model, q0, v0, t_final=1.0, dt=0.01),
            lambda: simulate_implicit(model, q0, v0, t_final=1.0, dt=0.01),
            lambda: simulate_scipy(model, q0, v0, t_final=1.0, method="RK45")]
    for run in runs:
        with pytest.raises(SimulationError, match=f"{match}.*{what}|{what}.*{match}") as info:
            run()
        error = info.value
        assert error.element == element and 0.3 < error.time < 0.32
        partial = error.partial_result
        assert partial.t[-1] <= error.time and partial.t[-1] > 0.25 and partial.q.shape == (partial.t.size, 
                                                                                               model.n_coordinates)
        assert np.all(np.isfinite(partial.q)) and np.all(np.isfinite(partial.qdot))


def test_user_signals_returning_one_number_in_any_form_are_accepted():
    """A signal may return its number as a float, an int, a bool, a numpy scalar or a 0-d array, and (after
    t = 0, where the model's check wants a scalar) a one-element array (the guard's contract): the accelerations
    of a two-link chain are those of the Lagrange reference (independent equations)."""
    forms = [lambda v: v, lambda v: np.float32(v), lambda v: np.array(v), lambda v: int(v), lambda v: True]
    q, v = np.array([-1.0, -0.5]), np.array([0.3, -0.2])
    for form in forms:
        model = PlanarModel.chain("m", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
                                        ActuatedHinge("h", torque=lambda t, form=form: form(1.0)),
                                        RigidBody.uniform_link("b", mass=0.5, length=0.8)])
        expected = PlanarLagrange(model).accelerations(q, v, 0.1)
        np.testing.assert_allclose(accelerations(model, q, v, 0.1), expected, rtol=1e-10, atol=1e-12)
    mixed = PlanarModel.chain("m", [Fixed("g"), ActuatedHinge("h1", torque=lambda t: np.array([1.0]) if t else 1.0),
                                    RigidBody.uniform_link("a", mass=1.0, length=1.0),
                                    ActuatedHinge("h2", torque=lambda t: 2.0),
                                    RigidBody.uniform_link("b", mass=0.5, length=0.8)])
    reference, rate, torque = mixed.hinge_laws(0.1)
    assert torque.tolist() == [1.0, 2.0]


def test_scipy_divergence_keeps_the_accepted_steps():
    model = _pendulum()
    with pytest.raises(SimulationError, match="'rod.theta'") as info:
        simulate_scipy(model, [-1.0], [30.0], t_final=5.0, divergence_bound=20.0)   # spins over the top
    partial = info.value.partial_result
    assert partial.t.size > 3 and np.all(np.abs(partial.q + 1.0) <= 20.0)
    # the stored steps are the solution: compare with the Lagrange reference at the last one
    reference = PlanarLagrange(model).simulate([-1.0], [30.0], float(partial.t[-1]))
    assert abs(reference.y[0, -1] - partial.q[-1, 0]) < 1e-6


def test_wrong_state_lengths_are_refused_by_every_state_function():
    model = uniform_chain(2)
    for function in (accelerations, solve_instant):
        with pytest.raises(ModelError, match=r"q must have length 2 .*\(shape \(3,\)\)"):
            function(model, [0.0, 0.0, 0.0], [0.0, 0.0])
        with pytest.raises(ModelError, match=r"qdot must have length 2 .*\(shape \(1,\)\)"):
            function(model, [0.0, 0.0], [0.0])
    with pytest.raises(ModelError, match="q must have length 2"):
        model.points([0.0, 0.0, 1.0], [0.0, 0.0])
    with pytest.raises(ModelError, match="q must be 2 real number"):
        accelerations(model, "ab", [0.0, 0.0])
    with pytest.raises(ModelError, match=r"qdot must be 2 real number\(s\) \(a planar model's states\)"):
        accelerations(model, [0.1, 0.2], np.array([0.0, 1e-20j]))      # not dropped silently
    with warnings.catch_warnings():
        warnings.simplefilter("error")                                  # no ComplexWarning either
        real = accelerations(model, np.array([0.1 + 0j, 0.2]), [0.0, 0.0])
    assert np.array_equal(real, accelerations(model, [0.1, 0.2], [0.0, 0.0]))
    with pytest.raises(ModelError, match=r"qdot must have length 2 .*\(shape \(3,\)\)"):
        model.body_angles(np.zeros(2), np.zeros(3), 0.0)
    from ctmm.flexible import ModalBeam
    from ctmm.flexible.outputs import tip_deflection
    flexible = PlanarModel.chain("f", [Fixed("g"), ModalBeam("arm", length=1.0, bending_stiffness=5.0,
                                                              mass_per_length=0.7, n_modes=2)])
    with pytest.raises(ModelError, match=r"q must have 2 coordinates .*got shape \(4, 3\)"):
        tip_deflection(flexible, np.zeros((4, 3)), "arm")


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_compiled_rk4_truncates_a_diverged_run_at_the_last_good_block():
    pytest.importorskip("casadi")
    from ctmm.compiled_scene import simulate_rk4_generated

    model = _pendulum()
    with pytest.warns(StabilityLimitWarning):
        with pytest.raises(SimulationError, match="'rod.theta'") as info:
            simulate_rk4_generated(model, [-1.4], [0.0], t_final=50.0, dt=1.0, store_every=2, divergence_bound=100.0)
    partial = info.value.partial_result
    assert partial.t[-1] < info.value.time and np.all(np.abs(partial.q + 1.4) <= 100.0)
    assert partial.t.size >= 2
    python = simulate_rk4(model, [-1.4], [0.0], t_final=float(partial.t[-1]), dt=1.0, stability_check="ignore",
                          divergence_bound=math.inf)
    np.testing.assert_allclose(partial.q[-1], python.q[-1], rtol=1e-9)


@pytest.mark.parametrize("hook, what", [
    ("force", "force of 'piezo' on beam 'arm'"),
    ("law", "law of 'piezo' on beam 'arm'"),
    ("distributed", "distributed load q_y of 'arm'"),
])
@pytest.mark.parametrize("value, problem", [(ValueError("boom"), "raised ValueError"), (float("nan"), "returned"),
                                            ("shape", "returned")])
def test_failing_flexible_hooks_are_named(hook, what, value, problem):
    from ctmm.flexible import ModalBeam, ModalForce

    def bad(t, *state):
        if 0.05 < t < 0.2:
            if isinstance(value, Exception):
                raise value
            if value == "shape":
                return np.zeros(5) if hook != "distributed" else np.zeros(2)
            return np.full(3, value) if hook != "distributed" else value
        return np.zeros(3) if hook != "distributed" else 0.0

    kw = {"distributed_load": (0.0, bad)} if hook == "distributed" else \
        {"modal_forces": (ModalForce(label="piezo", **{hook: bad}),)}
    arm = ModalBeam("arm", length=1.0, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3, **kw)
    model = PlanarModel.chain("flex", [Fixed("g"), arm])
    q0, v0 = np.zeros(model.n_coordinates), np.zeros(model.n_coordinates)
    for run in (lambda: simulate_rk4(model, q0, v0, t_final=0.3, dt=0.005),
                lambda: simulate_implicit(model, q0, v0, t_final=0.3, dt=0.01)):
        with pytest.raises(SimulationError, match=f"{what}.*{problem}|{problem}.*{what}") as info:
            run()
        assert info.value.element == "arm" and 0.05 < info.value.time < 0.07
        assert info.value.partial_result.t[-1] == pytest.approx(0.05)
