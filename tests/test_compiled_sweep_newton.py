"""The O(N) implicit-sweep iteration of the generated planar DT-TMM schemes (:mod:`ctmm.compiled_sweep_newton`).

(1) the root of the scheme's equations on the Lagrange models of :mod:`ctmm.reference.planar_lagrange` /
:mod:`ctmm.reference.flexible_lagrange` (global equations, no sweep) is a fixed point of one iterate, which contracts
towards it; (2) the generated step with ``tangent="sweep"`` equals the Python implicit stepper to round-off for every
scheme, straight-line and folded, on a stiff bushing and at large steps (a modal beam: ``tests/test_mapped_tangent.py``);
(3) it is the default from 8 coordinates where it applies; (4) what it does not cover is refused by name; (5)
non-convergence is a ConvergenceError with the result so far.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from ctmm.compiled_parameters import parameter_vector
from ctmm.compiled_scene_schemes import CompiledSceneScheme, simulate_scheme_generated
from ctmm.compiled_sweep_newton import implicit_accelerations, sweep_refusal
from ctmm.errors import ConvergenceError, ModelError
from ctmm.mapped_tangent import MAPPED_MIN_COORDINATES
from ctmm.nonlinear_laws import CubicSpring
from ctmm.planar import NonlinearHinge, Pinned, PlanarModel, RigidBody, simulate_implicit
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.reference.planar_lagrange import PlanarLagrange

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from planar_chain import chain  # noqa: E402

from test_compiled_scene_schemes import DP_START, VARIANTS, _label, double_pendulum, hub_beam  # noqa: E402


@pytest.mark.parametrize("name", ["double_pendulum", "hub_beam"])
def test_the_iteration_has_the_lagrange_root_as_its_fixed_point_and_contracts(name):
    """The root ``a = qddot(q_hat + w a, v_hat + g a)`` of the Lagrange equations (no sweep: Newton with a finite-
    difference Jacobian here) is a fixed point of one iterate, and an iterate from a perturbed ``a`` is closer to it
    by a small factor (``w``, ``g`` of a 1 ms Newmark step)."""
    model = double_pendulum() if name == "double_pendulum" else hub_beam()
    lagrange = PlanarLagrange(model) if name == "double_pendulum" else FlexibleLagrange(model)
    implicit = implicit_accelerations(model, ())
    n, p = model.n_coordinates, parameter_vector(model)
    rng = np.random.default_rng(3)
    w, g, t = 0.25e-6, 0.5e-3, 0.3
    q_hat, v_hat = 0.5 * rng.standard_normal(n), rng.standard_normal(n)

    def residual(a):
        return a - lagrange.accelerations(q_hat + w * a, v_hat + g * a, t)
    root = np.zeros(n)
    for _ in range(8):
        jacobian = np.column_stack([(residual(root + 1e-6 * e) - residual(root - 1e-6 * e)) / 2e-6 for e in np.eye(n)])
        root = root - np.linalg.solve(jacobian, residual(root))
    assert np.max(np.abs(residual(root))) <= 1e-9 * (1.0 + np.max(np.abs(root)))

    def iterate(a):
        return np.asarray(implicit(a, q_hat, v_hat, w, g, np.zeros(0), p, t)).ravel()
    assert np.max(np.abs(iterate(root) - root)) <= 1e-9 * (1.0 + np.max(np.abs(root)))
    start = root + rng.standard_normal(n) * (1.0 + np.abs(root))
    assert np.max(np.abs(iterate(start) - root)) <= 1e-2 * np.max(np.abs(start - root))


@pytest.mark.parametrize("scheme", VARIANTS, ids=_label)
def test_the_sweep_iteration_equals_the_python_implicit_stepper(scheme):
    model = double_pendulum()
    q0, v0 = DP_START
    compiled = CompiledSceneScheme(model, scheme, store_every=3, tangent="sweep")
    generated = simulate_scheme_generated(model, q0, v0, t_final=0.5, dt=0.01, scheme=scheme, store_every=3,
                                          compiled=compiled)
    python = simulate_implicit(model, q0, v0, t_final=0.5, dt=0.01, scheme=scheme, store_every=3)
    assert np.array_equal(generated.t, python.t)
    assert np.max(np.abs(generated.q - python.q)) <= 1e-10
    assert np.max(np.abs(generated.qdot - python.qdot)) <= 1e-10
    assert generated.extra["newton_iterations"] <= 8 * 50           # linear convergence: a few more than Newton


def test_a_folded_chain_takes_the_sweep_by_default_and_equals_the_python_stepper():
    model = chain(24)
    rng = np.random.default_rng(7)
    q0, v0 = 0.3 * rng.standard_normal(24), rng.standard_normal(24)
    compiled = CompiledSceneScheme(model, "generalized_alpha")
    assert compiled.tangent == "sweep" and compiled.period > 0         # the construction this test is for
    generated = simulate_scheme_generated(model, q0, v0, t_final=0.03, dt=1e-3, scheme="generalized_alpha",
                                          compiled=compiled)
    python = simulate_implicit(model, q0, v0, t_final=0.03, dt=1e-3, scheme="generalized_alpha")
    assert np.max(np.abs(generated.q - python.q)) <= 1e-10
    assert np.max(np.abs(generated.qdot - python.qdot)) <= 1e-10


def test_the_default_is_the_sweep_from_8_coordinates_where_it_applies():
    assert CompiledSceneScheme(chain(MAPPED_MIN_COORDINATES - 1), "newmark").tangent == "symbolic"
    assert CompiledSceneScheme(chain(MAPPED_MIN_COORDINATES), "newmark").tangent == "sweep"


def test_models_outside_its_scope_are_refused_by_name():
    cubic = PlanarModel.chain("cubic", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
                                        NonlinearHinge("k", moment_law=CubicSpring(1.0, 2.0)),
                                        RigidBody.uniform_link("b", mass=1.0, length=1.0)])
    assert "nonlinear hinge laws ['k']" in sweep_refusal(cubic)
    assert "feedback loops" in sweep_refusal(double_pendulum(), loops=object())
    with pytest.raises(ModelError, match=r"tangent='sweep' is not for a model with nonlinear hinge laws \['k'\]"):
        CompiledSceneScheme(cubic, "newmark", tangent="sweep")
    with pytest.raises(ModelError, match="tangent must be .*'sweep'.*got 'krylov'"):
        CompiledSceneScheme(double_pendulum(), "newmark", tangent="krylov")


def test_a_step_that_does_not_converge_is_a_convergence_error_with_the_result_so_far():
    """Fast motion, a large step and one Newton iteration allowed (4 sweep iterates): the first step is named with
    its residual and iterate count."""
    model = double_pendulum()
    compiled = CompiledSceneScheme(model, "newmark", tangent="sweep", max_iterations=1)
    with pytest.raises(ConvergenceError, match=r"step 1 \(t = 0.05 s\) did not converge: residual max\|delta qdd\| = "
                                               r"\S+ after 4 sweep iterations \(tolerance 1e-10\)") as info:
        simulate_scheme_generated(model, DP_START[0], 10.0 * DP_START[1], t_final=1.0, dt=0.05, compiled=compiled,
                                  max_iterations=1, stability_check="ignore")
    assert info.value.time == pytest.approx(0.05)
    assert len(info.value.partial_result.t) == 1


def test_a_stiff_bushing_equals_the_python_stepper_with_the_stricter_stop():
    """A 2e5 N/m translational spring (solved implicitly in the pivots) and a free base: linear convergence, so the
    common stopping rule alone left the numpy answer by 3.5e-10 in the rates (1 ms Newmark); the error estimate
    (:data:`ctmm.compiled_sweep_newton.ERROR_FRACTION`) keeps it at round-off."""
    from test_compiled_bushings import Q0, V0, arm

    model = arm(2e5)
    compiled = CompiledSceneScheme(model, "newmark", tangent="sweep")
    generated = simulate_scheme_generated(model, Q0, V0, t_final=0.1, dt=1e-3, compiled=compiled)
    python = simulate_implicit(model, Q0, V0, t_final=0.1, dt=1e-3)
    assert np.max(np.abs(generated.q - python.q)) <= 1e-11
    assert np.max(np.abs(generated.qdot - python.qdot)) <= 1e-10


def test_large_steps_of_a_fast_chain_converge_with_more_iterates_than_newton_needs():
    """A 10-link chain at ~2 rad/s, dt = 20 ms: the linear iteration needs more than 20 iterates on some steps (up
    to ``ITERATIONS_PER_NEWTON max_iterations``); it converges where the Python stepper does, to its answer."""
    model = chain(10)
    rng = np.random.default_rng(1)
    q0, v0 = rng.standard_normal(10), 2.0 * rng.standard_normal(10)
    compiled = CompiledSceneScheme(model, "newmark", tangent="sweep")
    generated = simulate_scheme_generated(model, q0, v0, t_final=1.0, dt=0.02, compiled=compiled,
                                          stability_check="ignore")
    python = simulate_implicit(model, q0, v0, t_final=1.0, dt=0.02, stability_check="ignore")
    assert np.max(np.abs(generated.q - python.q)) <= 1e-10
