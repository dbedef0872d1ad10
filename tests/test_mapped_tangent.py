"""The Newton tangent of generated DT-TMM schemes by mapped forward derivatives (:mod:`ctmm.mapped_tangent`).

Independent sides: the Python stepper :func:`ctmm.planar.implicit.simulate_implicit` (Newton on the transfer
form, the same root and, with the mass weighting, the same iterates), central differences of the numpy sweep
(:func:`ctmm.planar.accelerations`) for the columns, and the symbolic-Jacobian construction for the
same library built the other way.  The 40-body chain runs the mapped tangent on the folded sweep (code that does
not grow with N); the beams run it on the straight-line sweep.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from ctmm.compiled_parameters import parameter_vector
from ctmm.compiled_scene import symbolic_accelerations_with_inputs
from ctmm.compiled_scene_fold import SCHEME_FOLD_MIN_BODIES
from ctmm.compiled_scene_schemes import CompiledSceneScheme, simulate_scheme_generated
from ctmm.errors import ModelError, SimulationError
from ctmm.flexible import ModalBeam
from ctmm.mapped_tangent import (MAPPED_MIN_COORDINATES, SPATIAL_MAPPED_MIN_VELOCITIES, mapped_columns,
                                 tangent_construction, value_and_jacobian)
from ctmm.planar import (FreeBase, Pinned, PlanarModel, RigidBody, SpringDamperHinge, accelerations,
                         simulate_implicit)
from ctmm.planar.elements import FixedMounting
from ctmm.schemes import Newmark


def chain(n: int) -> PlanarModel:
    """Unequal links on spring-damper hinges (the fold takes each segment's numbers), gravity."""
    elements = [Pinned("base")]
    for i in range(n):
        if i:
            elements.append(SpringDamperHinge(f"h{i}", stiffness=2.0 + 0.1 * i, damping=0.05, rest_angle=0.01 * i))
        elements.append(RigidBody.uniform_link(f"link{i}", mass=1.0 + 0.02 * i, length=0.5 + 0.01 * (i % 3)))
    return PlanarModel.chain(f"chain{n}", elements)


def hub_beam() -> PlanarModel:
    beam = ModalBeam("b", length=1.0, bending_stiffness=1.0, mass_per_length=0.7, n_modes=2)
    return PlanarModel.chain("hub-beam", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", angle=0.3), beam])


def _start(n: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    return 0.3 * rng.standard_normal(n), rng.standard_normal(n)


def test_columns_are_the_derivatives_of_the_numpy_sweep():
    """Column i of ``w dqddot/dq + g dqddot/dv`` against central differences of the numpy accelerations."""
    model = chain(5)
    n = model.n_coordinates
    q, v = _start(n)
    columns = mapped_columns(symbolic_accelerations_with_inputs(model, ()), [0, 1], n)
    w, g = 0.3, 0.7
    mapped = np.array(columns(q, v, np.zeros(0), parameter_vector(model), 0.0, w * np.eye(n), g * np.eye(n)))
    step = 1e-6
    central = np.empty((n, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = step
        central[:, i] = (w * (accelerations(model, q + e, v) - accelerations(model, q - e, v))
                         + g * (accelerations(model, q, v + e) - accelerations(model, q, v - e))) / (2 * step)
    assert np.max(np.abs(mapped - central)) <= 1e-7 * (1.0 + np.max(np.abs(central)))


@pytest.mark.parametrize("symbol", ["SX", "MX"])
def test_value_and_jacobian_are_the_function_and_its_analytic_derivative_along_one_input(symbol):
    """``f(x, y, t) = [sin(x0 x1) + y t, x0^3 exp(x1) y, x1 t^2]``: the value and ``df/dx`` (analytic), the held
    inputs ``y``, ``t`` not differentiated (their derivative would enter through the zero seed only)."""
    import casadi as ca

    kind = getattr(ca, symbol)
    x, y, t = kind.sym("x", 2), kind.sym("y"), kind.sym("t")
    f = ca.Function("f", [x, y, t], [ca.vertcat(ca.sin(x[0] * x[1]) + y * t, x[0] ** 3 * ca.exp(x[1]) * y,
                                                x[1] * t * t)])
    terms = value_and_jacobian(f, 0, "terms")
    x0, x1, y0, t0 = 0.7, -0.4, 1.3, 2.1
    value, jacobian = (np.array(part) for part in terms([x0, x1], y0, t0))
    expected = [np.sin(x0 * x1) + y0 * t0, x0 ** 3 * np.exp(x1) * y0, x1 * t0 * t0]
    assert np.max(np.abs(value.ravel() - expected)) <= 1e-15
    analytic = [[x1 * np.cos(x0 * x1), x0 * np.cos(x0 * x1)],
                [3 * x0 ** 2 * np.exp(x1) * y0, x0 ** 3 * np.exp(x1) * y0], [0.0, t0 * t0]]
    assert np.max(np.abs(jacobian - analytic)) <= 1e-14


def test_a_spatial_ball_pendulum_builds_the_mapped_tangent_and_the_same_run_as_the_symbolic_jacobian():
    """A body on a ball joint (3 velocities, :data:`SPATIAL_MAPPED_MIN_VELOCITIES`): the default generated Newmark
    forms the tangent by directional derivatives along ``a`` (the symbolic Jacobian's C was 1.2x, gcc 1.5x); both
    libraries give the same run (the same Newton iterations) and equal the numpy Lie-group stepper."""
    import ctmm.spatial as sp
    from ctmm.compiled_spatial_schemes import CompiledSpatialScheme, simulate_spatial_scheme_generated
    from ctmm.spatial.implicit import simulate_spatial_implicit

    model = sp.SpatialModel("ball", [sp.SpatialBody("b", 1.0, (0.02, 0.03, 0.015), center_of_mass=(0.1, 0, -0.25)),
                                     sp.Spherical(name="s", parent=None, child="b")], gravity=(0, 0, -9.81))
    assert model.n_velocities == SPATIAL_MAPPED_MIN_VELOCITIES
    v0 = {"s.wx": 1.5, "s.wz": 2.0}
    compiled = {tangent: CompiledSpatialScheme(model, "newmark", tangent=tangent) for tangent in (None, "symbolic")}
    assert compiled[None].tangent == "mapped"
    runs = {tangent: simulate_spatial_scheme_generated(model, 0.05, 1e-3, v0=v0, compiled=library)
            for tangent, library in compiled.items()}
    python = simulate_spatial_implicit(model, 0.05, 1e-3, v0=v0)
    for name in (*model.coordinates, *model.velocities):
        assert np.max(np.abs(runs[None][name] - runs["symbolic"][name])) <= 1e-12, name
        assert np.max(np.abs(runs[None][name] - python[name])) <= 1e-10, name
    assert runs[None].info["newton_iterations"] == runs["symbolic"].info["newton_iterations"]


def test_a_40_body_chain_folded_with_the_mapped_tangent_equals_the_python_stepper():
    model = chain(40)
    q0, v0 = _start(model.n_coordinates)
    compiled = CompiledSceneScheme(model, "newmark", tangent="mapped")
    assert compiled.tangent == "mapped" and compiled.period > 0        # the construction this test is for
    generated = simulate_scheme_generated(model, q0, v0, t_final=0.03, dt=1e-3, compiled=compiled)
    python = simulate_implicit(model, q0, v0, t_final=0.03, dt=1e-3, scheme="newmark")
    assert np.max(np.abs(generated.q - python.q)) <= 1e-10
    assert np.max(np.abs(generated.qdot - python.qdot)) <= 1e-10
    assert generated.extra["newton_iterations"] <= 4 * 30


@pytest.mark.parametrize("tangent", ["mapped", "sweep"])       # sweep: ctmm.compiled_sweep_newton, modal block implicit
@pytest.mark.parametrize("scheme", ["newmark", "houbolt", "wilson_theta"])
def test_the_mapped_tangent_on_a_modal_beam_equals_the_python_stepper(scheme, tangent):
    model = hub_beam()
    q0, v0 = np.zeros(model.n_coordinates), np.zeros(model.n_coordinates)
    q0[:2], v0[0] = (0.3, 0.02), 2.0
    compiled = CompiledSceneScheme(model, scheme, tangent=tangent)
    generated = simulate_scheme_generated(model, q0, v0, t_final=0.1, dt=2e-3, scheme=scheme, compiled=compiled)
    python = simulate_implicit(model, q0, v0, t_final=0.1, dt=2e-3, scheme=scheme)
    assert np.max(np.abs(generated.q - python.q)) <= 1e-10
    assert np.max(np.abs(generated.qdot - python.qdot)) <= 1e-10


def test_the_mapped_tangent_keeps_the_mass_weighted_iterates_on_a_diverging_beam():
    """An unstable Newmark on a pinned beam: the Python stepper converges and diverges at 0.6 s, where Newton on
    the plain residual cycled at 0.45 s; the mapped weighted tangent must stop at the same step, same message."""
    model = PlanarModel.chain("pb", [Pinned("o"), ModalBeam("b", length=1.0, bending_stiffness=1.0,
                                                            mass_per_length=0.7, n_modes=2)])
    scheme = Newmark(beta=0.25, gamma=0.3)
    start = (np.array([0.3, 0.0, 0.0]), np.array([2.0, 0.0, 0.0]))
    compiled = CompiledSceneScheme(model, scheme, tangent="mapped")
    errors = []
    for run, options in ((simulate_implicit, {}), (simulate_scheme_generated, {"compiled": compiled})):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")            # the stability check warns about gamma < 1/2
            with pytest.raises(SimulationError) as info:
                run(model, *start, t_final=1.0, dt=0.025, scheme=scheme, **options)
        errors.append(info.value)
    python, generated = errors
    assert type(python) is type(generated) is SimulationError
    assert python.time == generated.time == pytest.approx(0.6)
    assert str(python) == str(generated)
    assert np.max(np.abs(python.partial_result.q - generated.partial_result.q)) <= 1e-9


def test_the_mapped_tangent_of_a_free_base_model_has_the_plain_residuals_root():
    """No generalised-force basis (free base): the plain residual, its tangent mapped; the same root."""
    model = PlanarModel.chain("free", [FreeBase("base"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
                                       SpringDamperHinge("h", stiffness=3.0, damping=0.1),
                                       RigidBody.uniform_link("b", mass=0.5, length=0.7)], gravity=(0.0, -9.81))
    q0, v0 = np.array([0.0, 0.0, 0.2, -0.4]), np.array([0.1, 0.0, 0.5, -0.3])
    compiled = CompiledSceneScheme(model, "newmark", tangent="mapped")
    generated = simulate_scheme_generated(model, q0, v0, t_final=0.1, dt=1e-2, compiled=compiled)
    python = simulate_implicit(model, q0, v0, t_final=0.1, dt=1e-2, scheme="newmark")
    assert np.max(np.abs(generated.q - python.q)) <= 1e-10


def test_mapped_and_symbolic_libraries_give_the_same_run():
    model = chain(4)
    q0, v0 = _start(4)
    runs = [simulate_scheme_generated(model, q0, v0, t_final=0.05, dt=1e-3, compiled=CompiledSceneScheme(
        model, "newmark", tangent=tangent)) for tangent in ("mapped", "symbolic")]
    assert np.max(np.abs(runs[0].q - runs[1].q)) <= 1e-12
    assert runs[0].extra["newton_iterations"] == runs[1].extra["newton_iterations"]


def test_the_construction_is_chosen_by_size_and_bad_choices_are_refused():
    assert tangent_construction("x", None, MAPPED_MIN_COORDINATES) == "mapped"
    assert tangent_construction("x", None, MAPPED_MIN_COORDINATES, "") == "sweep"       # where it applies
    assert tangent_construction("x", None, MAPPED_MIN_COORDINATES, "modal bodies") == "mapped"
    assert tangent_construction("x", None, MAPPED_MIN_COORDINATES - 1, "") == "symbolic"
    assert tangent_construction("x", None, MAPPED_MIN_COORDINATES - 1) == "symbolic"
    assert tangent_construction("x", None, SPATIAL_MAPPED_MIN_VELOCITIES, minimum=SPATIAL_MAPPED_MIN_VELOCITIES) \
        == "mapped"
    assert tangent_construction("x", None, SPATIAL_MAPPED_MIN_VELOCITIES - 1,
                                minimum=SPATIAL_MAPPED_MIN_VELOCITIES) == "symbolic"
    assert SCHEME_FOLD_MIN_BODIES >= MAPPED_MIN_COORDINATES
    with pytest.raises(ModelError, match="tangent must be 'mapped'.*got 'jacobian'"):
        CompiledSceneScheme(chain(2), "newmark", tangent="jacobian")


def test_the_spherical_cut_law_scheme_uses_the_mapped_tangent_and_equals_numpy():
    """The ball held by a spherical cut with a 3-axis law (``benchmarks/kinematic_loops_generated.py``): its
    generated Newmark forms the tangent by mapped forward derivatives (the law inside the symbolic Jacobian compiled
    in ~17 s) and equals the numpy DT-TMM scheme with projection."""
    import ctmm.spatial as sp
    from ctmm.compiled_spatial_loop_schemes import CompiledSpatialLoopScheme, simulate_spatial_loop_scheme_generated
    from ctmm.nonlinear_laws import CubicSpring, LinearLaw, ParallelLaw
    from ctmm.spatial.closed_loop_time import simulate_spatial_loop_scheme
    from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

    tree = sp.SpatialModel("ball", [sp.SpatialBody("p", 1.2, np.diag([0.02, 0.03, 0.025]),
                                                   center_of_mass=(0.1, 0.0, -0.3)),
                                    sp.Free(name="free", parent=None, child="p")])
    loop = SpatialKinematicLoopModel(tree, [SpatialCutJoint(
        name="ball", parent=None, child="p", law=ParallelLaw(CubicSpring(2.0, 15.0), LinearLaw(0.0, 0.02)),
        rest=(0.1, -0.2, 0.05))])
    turn = np.sin(0.3)
    q0, v0 = loop.consistent_state({"free.qw": np.cos(0.3), "free.qx": 0.6 * turn, "free.qy": 0.8 * turn},
                                   {"free.wx": 1.0, "free.wz": 2.0})
    compiled = CompiledSpatialLoopScheme(loop, "newmark")
    assert compiled.tangent == "mapped"
    generated, _ = simulate_spatial_loop_scheme_generated(loop, q0, v0, t_final=0.02, dt=1e-3, scheme="newmark",
                                                          compiled=compiled)
    plain, _ = simulate_spatial_loop_scheme(loop, q0, v0, t_final=0.02, dt=1e-3, scheme="newmark")
    assert np.max(np.abs(generated.q - plain.q)) <= 1e-12
    assert np.max(np.abs(generated.v - plain.v)) <= 1e-12


def test_loops_inside_the_mapped_step_equal_the_python_dt_tmm_path():
    """8 links with a PD on the base and one on a hinge (the loops' step: the closed-loop rates mapped, the
    weighting's G and d(G s)/dq by mapped forward derivatives) = the Python DT-TMM path with the same loops."""
    import ctmm
    from ctmm.control import ControlledModel, Feedback

    model = chain(8)
    assert tangent_construction("loops", None, model.n_coordinates) == "mapped"
    controlled = ControlledModel(model, [Feedback("pd", [("link0.theta", 8.0), ("link0.omega", 1.5)], "base.torque",
                                                  gain=1.0),
                                         Feedback("elbow", [("h3.angle", 3.0), ("h3.rate", 0.4)], "h3.torque",
                                                  gain=1.0, saturation=(-0.5, 0.5))])
    q0, v0 = _start(model.n_coordinates)
    options = dict(method="newmark", x0=dict(zip(model.coordinates, q0)), v0=dict(zip(model.coordinates, v0)))
    generated = ctmm.simulate(controlled, 0.05, 0.01, compiled=True, **options)
    python = ctmm.simulate(controlled, 0.05, 0.01, **options)
    assert generated.info["method"].startswith("dt-tmm-generated/")
    assert np.ptp(python["pd.u"]) > 0.1
    for name in python.signals():
        assert np.max(np.abs(generated[name] - python[name])) <= 1e-10, name
