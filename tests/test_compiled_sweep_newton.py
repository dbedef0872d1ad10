"""The O(N) implicit-sweep iteration of the generated planar DT-TMM schemes (:mod:`ctmm.compiled_sweep_newton`).

(1) one iterate is ``(M + g C + w K)^-1 (M qddot(q, v) + (w K + g C) a)`` with ``M``, ``qddot`` from the Lagrange
equations of :mod:`ctmm.reference.planar_lagrange` and ``K``, ``C`` the hinge laws' stiffness and damping written
here (global equations, no sweep); (2) the generated step with ``tangent="sweep"`` equals the Python implicit
stepper to round-off for every scheme, straight-line and folded; (3) it is the default from 8 coordinates where it
applies; (4) what it does not cover is refused by name; (5) non-convergence is a ConvergenceError with the result so
far.
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
from ctmm.planar import Pinned, PlanarModel, RigidBody, simulate_implicit
from ctmm.reference.planar_lagrange import PlanarLagrange

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from planar_chain import chain  # noqa: E402

from test_compiled_scene_schemes import DP_START, VARIANTS, _label, double_pendulum, hub_beam  # noqa: E402


def test_one_iterate_is_the_effective_inertia_solve_of_the_lagrange_equations():
    model = double_pendulum()            # hinge h: k = 4, c = 0.3 on the relative angle q1 - q0; a harmonic load
    lagrange = PlanarLagrange(model)
    implicit = implicit_accelerations(model, ())
    rng = np.random.default_rng(3)
    coupling = np.array([[1.0, -1.0], [-1.0, 1.0]])
    stiffness, damping = 4.0 * coupling, 0.3 * coupling
    for _ in range(3):
        q_hat, v_hat, a = rng.standard_normal(2), rng.standard_normal(2), rng.standard_normal(2)
        w, g, t = 0.3 * rng.random(), 0.5 * rng.random(), rng.random()
        q, v = q_hat + w * a, v_hat + g * a
        mass = lagrange.mass_matrix(q, t)
        tangent = w * stiffness + g * damping
        expected = np.linalg.solve(mass + tangent, mass @ lagrange.accelerations(q, v, t) + tangent @ a)
        got = np.asarray(implicit(q, v, q_hat, v_hat, w, g, np.zeros(0), parameter_vector(model), t)).ravel()
        assert np.max(np.abs(got - expected)) <= 1e-12 * (1.0 + np.max(np.abs(expected)))


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
    beam = hub_beam()
    assert "modal bodies ['b']" in sweep_refusal(beam)
    with pytest.raises(ModelError, match=r"tangent='sweep' is not for a model with modal bodies \['b'\]"):
        CompiledSceneScheme(beam, "newmark", tangent="sweep")
    with pytest.raises(ModelError, match="tangent must be .*'sweep'.*got 'krylov'"):
        CompiledSceneScheme(double_pendulum(), "newmark", tangent="krylov")


def test_a_step_that_does_not_converge_is_a_convergence_error_with_the_result_so_far():
    model = PlanarModel.chain("p", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0)])
    compiled = CompiledSceneScheme(model, "newmark", tangent="sweep", max_iterations=1)
    with pytest.raises(ConvergenceError, match=r"step 1 \(t = 0.01 s\) did not converge: residual") as info:
        simulate_scheme_generated(model, np.array([1.0]), np.array([0.0]), t_final=0.1, dt=0.01,
                                  compiled=compiled)
    assert info.value.time == pytest.approx(0.01)
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
