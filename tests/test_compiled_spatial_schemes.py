"""Generated DT-TMM schemes of spatial models (:mod:`ctmm.compiled_spatial_schemes`).

(1) equal to the Python Lie-group stepper (:func:`ctmm.spatial.implicit.simulate_spatial_implicit`) to its Newton
tolerance; (2) equal to the Lie-group Newmark / generalized-alpha written here in global form on the independent
Newton-Euler model of :mod:`ctmm.reference.spatial_tree` (its forward dynamics and its own retraction, no ctmm
sweep or scheme code), solved by a finite-difference Newton, and second order against the reference's fine RK4;
(3) bad input refused; (4) a step that does not converge is a ConvergenceError with the result so far.
"""
from __future__ import annotations

import numpy as np
import pytest
from test_compiled_scene_schemes import global_scheme, newton_root
from test_spatial_beam import hub_beam as spatial_hub_beam
from test_spatial_schemes import T_FINAL, asymmetric_top, double_pendulum, final_state, pose_error, \
    reference_final, to_reference

import ctmm
from ctmm.compiled_spatial_schemes import CompiledSpatialScheme, simulate_spatial_scheme_generated
from ctmm.errors import ConvergenceError, ModelError
from ctmm.reference import spatial_tree as ref
from ctmm.schemes import GeneralizedAlpha, Newmark, WilsonTheta
from ctmm.spatial.implicit import simulate_spatial_implicit
from ctmm.spatial.integrate import initial_state

SCHEMES = ["newmark", "generalized_alpha", "wilson_theta", "houbolt", "forward_euler", WilsonTheta(1.0)]
"""Every scheme and a conditionally stable variant (the parameter variants of the maps: the planar tests)."""


def _label(scheme) -> str:
    return scheme if isinstance(scheme, str) else repr(scheme)


def _difference(model, a, b) -> float:
    return max(float(np.max(np.abs(a[name] - b[name]))) for name in (*model.coordinates, *model.velocities))


@pytest.mark.filterwarnings("ignore::ctmm.guard.StabilityLimitWarning")     # Wilson-theta 1.0: both paths say so
@pytest.mark.parametrize("scheme", SCHEMES, ids=_label)
def test_generated_step_equals_the_python_lie_group_stepper(scheme):
    model, _, x0, v0 = double_pendulum()
    generated = simulate_spatial_scheme_generated(model, 0.2, 0.01, scheme=scheme, x0=x0, v0=v0, store_every=2)
    python = simulate_spatial_implicit(model, 0.2, 0.01, scheme=scheme, x0=x0, v0=v0, store_every=2)
    assert np.array_equal(generated.time, python.time)
    assert _difference(model, generated, python) <= 1e-10
    assert generated.info["newton_iterations"] <= 4 * 20          # exact tangent: quadratic


def test_generated_houbolt_equals_the_python_stepper_on_a_tumbling_free_body():
    """SE(3): the chart differences of earlier configurations (group logarithm) and the chart-rate brackets."""
    model, _, x0, v0 = asymmetric_top()
    generated = ctmm.simulate(model, 0.2, 0.01, method="houbolt", x0=x0, v0=v0, compiled=True)
    python = ctmm.simulate(model, 0.2, 0.01, method="houbolt", x0=x0, v0=v0)
    assert generated.scheme_name == "dt-tmm-generated/houbolt"
    assert _difference(model, generated, python) <= 1e-10


# ---------------------------------------------------------------- (2) independent global Lie-group schemes
def lie_group_alpha(tree, q0, v0, h, n_steps, rho=None):
    """Arnold & Bruls' generalized-alpha (Newmark for ``rho=None``) on ``q (+) delta`` of the reference's own
    retraction and forward dynamics: ``delta = h v + h^2 ((1/2 - beta) A + beta A1)``, ``v1 = v + h ((1 - gamma) A +
    gamma A1)``, ``(1 - am) A1 + am A = (1 - af) a1 + af a``, ``a1 = f(q (+) delta, v1)``."""
    if rho is None:
        am = af = 0.0
        beta, gamma = 0.25, 0.5
    else:
        am, af = (2.0 * rho - 1.0) / (rho + 1.0), rho / (rho + 1.0)
        gamma, beta = 0.5 - am + af, 0.25 * (1.0 - am + af) ** 2
    q, v = np.array(q0, float), np.array(v0, float)
    a = ref.forward_dynamics(tree, q, v)
    A = a.copy()
    for _ in range(n_steps):
        def states(a1):
            A1 = ((1.0 - af) * a1 + af * a - am * A) / (1.0 - am)
            delta = h * v + h * h * ((0.5 - beta) * A + beta * A1)
            return ref.normalized(tree, ref.retract(tree, q, delta)), v + h * ((1.0 - gamma) * A + gamma * A1), A1

        a1 = newton_root(lambda x: x - ref.forward_dynamics(tree, *states(x)[:2]), a)
        q, v, A = states(a1)
        a = a1
    return q, v


@pytest.mark.parametrize("scheme, rho", [("newmark", None), (GeneralizedAlpha(0.6), 0.6)], ids=["newmark", "alpha"])
def test_generated_step_equals_the_global_lie_group_scheme_on_the_newton_euler_model(scheme, rho):
    model, tree, x0, v0 = double_pendulum()
    start = initial_state(model, x0, v0)
    q_ref, v_ref = lie_group_alpha(tree, to_reference(model, tree, start[:model.n_positions]),
                                   start[model.n_positions:], 0.02, 10, rho)
    compiled = CompiledSpatialScheme(model, scheme)
    assert compiled.tangent == "mapped"     # 4 velocities: directional derivatives (0.66x the C of the Jacobian)
    generated = simulate_spatial_scheme_generated(model, 0.2, 0.02, scheme=scheme, x0=x0, v0=v0, compiled=compiled)
    q, v = final_state(model, generated)
    assert pose_error(tree, to_reference(model, tree, q), v, q_ref, v_ref) <= 1e-10


def test_a_spatial_beam_equals_the_python_stepper_and_the_global_scheme_on_its_lagrange_model():
    """A hub on a revolute spring-damper joint carrying a stiffened SpatialBeam with a tip body (bending, torsion,
    axial modes): the coordinates are a vector space, so the global Newmark of the planar tests applies to the
    independent assumed-modes model of ``ctmm/reference/spatial_beam_lagrange.py``."""
    model, reference = spatial_hub_beam(((0, 0, 1),), True)
    q0, v0 = np.zeros(model.n_positions), np.zeros(model.n_velocities)
    q0[0], v0[0] = 0.2, 3.0
    generated = simulate_spatial_scheme_generated(model, 0.02, 2e-3, x0=q0, v0=v0)
    python = simulate_spatial_implicit(model, 0.02, 2e-3, x0=q0, v0=v0)
    assert _difference(model, generated, python) <= 1e-10
    qs, vs = global_scheme(lambda q, v, t: reference.accelerations(q, v), q0, v0, 2e-3, 10, "newmark")
    assert np.max(np.abs(np.array([generated[name] for name in model.coordinates]).T - qs)) <= 1e-10
    assert np.max(np.abs(np.array([generated[name] for name in model.velocities]).T - vs)) <= 1e-10
    assert np.max(np.abs(qs[-1, 1:])) > 1e-4                        # the beam did deform


@pytest.mark.parametrize("scheme", ["newmark", "generalized_alpha", "houbolt"])
def test_generated_schemes_are_second_order_against_the_reference(scheme):
    model, tree, x0, v0 = double_pendulum()
    q_ref, v_ref = reference_final("double", double_pendulum)
    errors = []
    for dt in (0.02, 0.01):
        q, v = final_state(model, simulate_spatial_scheme_generated(model, T_FINAL, dt, scheme=scheme, x0=x0, v0=v0))
        errors.append(pose_error(tree, to_reference(model, tree, q), v, q_ref, v_ref))
    low = 1.75 if scheme == "houbolt" else 1.9          # Houbolt's measured order here: 1.82 (test_spatial_schemes)
    assert low < np.log2(errors[0] / errors[1]) < 2.1, errors


# ---------------------------------------------------------------- (3) bad input, (4) failures
def test_bad_input_is_refused():
    model, _, x0, v0 = double_pendulum()
    with pytest.raises(ModelError, match="dt is required"):
        ctmm.simulate(model, 0.1, None, method="newmark", compiled=True)
    with pytest.raises(ModelError, match="rtol=1e-06 does not apply"):
        ctmm.simulate(model, 0.1, 0.01, method="newmark", compiled=True, rtol=1e-6)
    with pytest.raises(ModelError, match="progress=True does not apply.*with loops"):     # (outputs: the loop path)
        ctmm.simulate(model, 0.1, 0.01, method="newmark", compiled=True, outputs=["hinge.angle"], progress=True)
    with pytest.raises(ModelError, match="beta"):
        ctmm.simulate(model, 0.1, 0.01, method=Newmark(beta=0.0), compiled=True)
    with pytest.raises(ModelError, match="max_iterations"):
        CompiledSpatialScheme(model, max_iterations=0)
    with pytest.raises(ModelError, match="SpatialModel"):
        CompiledSpatialScheme("model")


def test_a_step_that_does_not_converge_is_a_convergence_error_with_the_result_so_far():
    model, _, x0, v0 = double_pendulum()
    with pytest.raises(ConvergenceError, match=r"step 1 \(newmark\) at t = 0.05 s did not converge") as info:
        simulate_spatial_scheme_generated(model, 0.5, 0.05, x0=x0, v0=v0, max_iterations=1)
    assert info.value.time == pytest.approx(0.05)
    assert info.value.partial_result.time.tolist() == [0.0]
