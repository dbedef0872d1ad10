"""Gate tests of the element protocol and the one articulated sweep (issue 12, plan §5 S2).

Every context is checked against an INDEPENDENT model: explicit accelerations against the Lagrange
references (``reference/planar_lagrange.py``, ``reference/flexible_lagrange.py``), the frequency
context's characteristic function and FRF against ``PlanarLagrange.linearize`` ``M, C, K``; casadi
evaluation against numpy; the sweep of rigid trees (``planar/rigid_sweep.py RigidTreeSweep``, traced on casadi
and on numpy) equal to the sweep of the scene's own terms with arbitrary joint tangents ``kappa`` (the implicit
context);
and ``flexible/kernel.py FlexibleSystem.sweep`` (a call of the one sweep on its own terms) equal to
the sweep of the scene's tree.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.articulated import Tree, articulated_sweep
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.ops import CASADI, NUMPY
from ctmm.planar.elements import FixedMounting
from ctmm.planar import (ElasticHinge, Fixed, FreeBase, Load, Pinned, PlanarModel, RigidBody,
                         SmoothHinge, accelerations, ports)
from ctmm.planar.body_forms import PlanarScene
from ctmm.planar.equilibrium import hanging_configuration, static_equilibrium
from ctmm.planar.rigid_sweep import RigidTreeSweep, model_sweep
from ctmm.planar.sweep import body_terms, hinge_torques
from ctmm.protocol import BodyTerms
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.reference.planar_lagrange import PlanarLagrange
from planar_helpers import random_state, random_tree


def _relative(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(b)))


@pytest.mark.parametrize("seed", range(8))
def test_explicit_context_equals_the_planar_lagrange_model_on_random_trees(seed):
    model = random_tree(seed, 6, allow_translation=False)
    q, v, t = random_state(model, seed)
    reference = PlanarLagrange(model).accelerations(q, v, t)
    assert _relative(PlanarScene(model).accelerations(q, v, t)[0], reference) <= 1e-12


def test_explicit_context_is_batched_and_takes_actuator_inputs():
    model = random_tree(3, 5, allow_translation=False)
    scene = PlanarScene(model)
    rng = np.random.default_rng(7)
    states = [random_state(model, k) for k in range(4)]
    q = np.array([s[0] for s in states])
    v = np.array([s[1] for s in states])
    batched = scene.accelerations(q, v, 0.4)
    reference = PlanarLagrange(model)
    for k in range(4):
        assert _relative(batched[k], reference.accelerations(q[k], v[k], 0.4)) <= 1e-12
    names = ports.actuator_names(model)
    values = {name: float(rng.normal()) for name in names}
    inputs = ports.actuator_inputs(model, values)
    expected = accelerations(model, q[0], v[0], 0.4, inputs=inputs)
    assert _relative(scene.accelerations(q[0], v[0], 0.4, inputs)[0], expected) <= 1e-12
    assert _relative(expected, scene.accelerations(q[0], v[0], 0.4)[0]) > 1e-3     # the inputs act


@pytest.mark.parametrize("seed", range(12))
def test_translational_spring_hinges_on_the_protocol_equal_lagrange_and_the_old_kernel(seed):
    """BUSHING (S = I3, f = -k_t d - c_t d_dot along the global offset): random trees with
    translational-spring hinges, against the independent Lagrange model and the Python-float kernel."""
    model = random_tree(seed, 6, allow_translation=True)
    q, v, t = random_state(model, seed)
    scene = PlanarScene(model)
    reference = PlanarLagrange(model)
    free = scene.accelerations(q, v, t)[0]
    assert _relative(free, reference.accelerations(q, v, t)) <= 1e-12
    assert _relative(accelerations(model, q, v, t), free) <= 1e-15          # ctmm.planar.accelerations routes here
    # hinge torques and body moments act through the Lagrange mass matrix: qdd(u) - qdd(0) = M^-1 Q(u)
    rng = np.random.default_rng(seed)
    values, Q = {}, np.zeros(model.n_coordinates)
    for j, name in enumerate(model.joint_names):
        if model.joint_kind[j] in (0, 3) and f"{name}.torque" in ports.actuator_names(model):
            u = values[f"{name}.torque"] = float(rng.normal())
            Q[model.theta_index[j]] += u
            p = model.parent[j]
            while p >= 0 and model.theta_index[p] < 0:    # a driven parent turns with its own parent
                p = model.parent[p]
            if p >= 0:
                Q[model.theta_index[p]] -= u
    for j, name in enumerate(model.body_names):
        if model.theta_index[j] >= 0:
            u = values[f"{name}.moment"] = float(rng.normal())
            Q[model.theta_index[j]] += u
    forced = scene.accelerations(q, v, t, ports.actuator_inputs(model, values))[0]
    assert _relative(forced - free, np.linalg.solve(reference.mass_matrix(q, t), Q)) <= 1e-10


def test_translational_spring_hinge_frequency_context_equals_the_lagrange_linearisation():
    import ctmm

    model = PlanarModel.chain("bushed", [Pinned("o"), RigidBody.uniform_link("l1", mass=1.0, length=1.0),
                                         ElasticHinge("h", stiffness=4.0, rest_angle=0.4, translational_stiffness=300.0,
                                                      translational_damping=0.7),
                                         RigidBody.uniform_link("l2", mass=0.5, length=0.8)])
    assert model.joint_kind.tolist()[1] == 3                    # the hinge is a BUSHING
    q0 = ctmm.linearize(model, inputs=[], outputs=[]).operating_point.q
    M, C, K = PlanarLagrange(model).linearize(q0)
    s = np.array([0.3 + 1.7j, -0.2 + 0.5j, 2.0j, 0.7])
    Z = s[:, None, None] ** 2 * M + s[:, None, None] * C + K
    assert np.max(np.abs(q0[1:3])) > 1e-3                       # the spring is preloaded
    characteristic = PlanarScene(model).frequency(q0, s).characteristic[:, 0, 0]
    assert _relative(characteristic, np.linalg.det(Z)) <= 1e-12


def test_translational_spring_hinges_are_linearised_by_complex_step(monkeypatch):
    """ctmm.linearize of a model with a translational-spring hinge takes the complex step through the
    one sweep (Richardson differences only along the one cross-check direction, not per coordinate)
    and equals the Lagrange linearisation ``A = [[0, I], [-M^-1 K, -M^-1 C]]``."""
    import ctmm
    from ctmm import planar_linearization

    sizes = []
    differences = planar_linearization.jacobian

    def recorded(function, x, **options):
        sizes.append(np.size(x))
        return differences(function, x, **options)

    monkeypatch.setattr(planar_linearization, "jacobian", recorded)
    model = PlanarModel.chain("bushed", [Pinned("o"), RigidBody.uniform_link("l1", mass=1.0, length=1.0),
                                         ElasticHinge("h", stiffness=4.0, rest_angle=0.4, translational_stiffness=300.0,
                                                      translational_damping=0.7),
                                         RigidBody.uniform_link("l2", mass=0.5, length=0.8)])
    lin = ctmm.linearize(model, inputs=[], outputs=[])
    assert sizes == [1]                                         # the cross-check direction only
    q0 = lin.operating_point.q
    M, C, K = PlanarLagrange(model).linearize(q0)
    n = model.n_coordinates
    expected = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    assert _relative(np.asarray(lin.state_space.A), expected) <= 1e-10
    assert lin.operating_point.jacobian_error <= 1e-8


def test_translational_spring_hinges_are_counted_by_the_one_sweep():
    """Now on the protocol, models with translational springs take the Wittrick-Williams count (3 x 3
    joint pivots) in ctmm.natural_frequencies / eigenvalue_count: equal to the Lagrange eigenvalues."""
    import ctmm
    from ctmm.planar_counting import FrequencyCounter

    model = PlanarModel.chain("bushed", [Pinned("o"), RigidBody.uniform_link("l1", mass=1.0, length=1.0),
                                         ElasticHinge("h", stiffness=4.0, rest_angle=0.4, translational_stiffness=300.0),
                                         RigidBody.uniform_link("l2", mass=0.5, length=0.8)])
    q0 = ctmm.linearize(model, inputs=[], outputs=[]).operating_point.q
    expected = PlanarLagrange(model).natural_frequencies(q0)
    np.testing.assert_allclose(FrequencyCounter(model, q0, 0.0).frequencies(n_modes=4), expected, rtol=1e-10)
    np.testing.assert_allclose(ctmm.natural_frequencies(model, n_modes=4), expected, rtol=1e-10)
    omega = np.concatenate([0.999 * expected, 1.001 * expected])
    np.testing.assert_array_equal(ctmm.eigenvalue_count(model, omega),
                                  np.sum(expected[None, :] < omega[:, None], axis=1))


def _beam(name, **kw):
    return ModalBeam(name, length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3, **kw)


FLEXIBLE = {
    "hub_beam_tip": lambda: PlanarModel.chain("m2", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", angle=0.3),
        _beam("b", n_axial_modes=2, axial_stiffness=300.0, damping_ratio=0.02, stiffness_damping=1e-3,
              distributed_load=(0.4, -0.2),
              loads=(Load(point=(0.7, 0.0), force_x=0.3, force_y=lambda t: math.sin(t), moment=0.2),)),
        FixedMounting("m2"),
        RigidBody("tip", mass=0.2, inertia=0.01, center_of_mass=(0.03, 0.01), outboard=(0.1, 0.0))]),
    "floating": lambda: PlanarModel.chain("m4", [FreeBase("f"), _beam("b1"), SmoothHinge("h"),
                                                 _beam("b2", geometric_stiffening=False)]),
    "tree": lambda: PlanarModel("m5", [
        Pinned("o", child="b1"), _beam("b1", outboard={"mid": 0.6, "tip": 1.3}),
        ElasticHinge("h", parent="b1.mid", child="l", stiffness=2.0, rest_angle=0.1),
        RigidBody.uniform_link("l", mass=0.4, length=0.7),
        FixedMounting("w", parent="b1.tip", child="b2", angle=-0.4), _beam("b2")]),
}


@pytest.mark.parametrize("name", sorted(FLEXIBLE))
def test_explicit_context_equals_the_flexible_lagrange_model(name):
    model = FLEXIBLE[name]()
    rng = np.random.default_rng(len(name))
    q, v, t = 0.3 * rng.normal(size=model.n_coordinates), rng.normal(size=model.n_coordinates), 0.7
    reference = FlexibleLagrange(model).accelerations(q, v, t)
    assert _relative(PlanarScene(model).accelerations(q, v, t)[0], reference) <= 1e-12


def _equilibrium_models():
    out = []
    for seed in (0, 3, 5, 6, 8):
        model = random_tree(seed, 5, allow_translation=False, allow_driven=False, base="pinned")
        out.append((model, static_equilibrium(model, hanging_configuration(model))))
    return out


def test_frequency_context_characteristic_and_response_equal_the_lagrange_linearisation():
    s = np.array([0.3 + 1.7j, -0.2 + 0.5j, 2.0j, 0.7])
    for model, q0 in _equilibrium_models():
        M, C, K = PlanarLagrange(model).linearize(q0)
        Z = s[:, None, None] ** 2 * M + s[:, None, None] * C + K
        scene = PlanarScene(model)
        assert _relative(scene.frequency(q0, s).characteristic[:, 0, 0], np.linalg.det(Z)) <= 1e-12
        # response to a unit torque across the hinge of the last body (parent on child)
        j = model.n_bodies - 1
        force = np.zeros(model.n_coordinates)
        force[model.theta_index[j]] += 1.0
        force[model.theta_index[model.parent[j]]] -= 1.0
        expected = np.linalg.solve(Z, np.broadcast_to(force, (s.size, force.size))[:, :, None])[:, :, 0]
        response = scene.coordinate_accelerations(scene.frequency(q0, s, torque={j: 1.0}))
        assert _relative(response, expected) <= 1e-12


def test_frequency_context_refuses_a_point_that_is_not_an_equilibrium():
    model, q0 = _equilibrium_models()[0]
    with pytest.raises(ModelError, match="not an equilibrium"):
        PlanarScene(model).frequency(q0 + 0.1, [1j])


def test_casadi_evaluation_equals_numpy():
    casadi = pytest.importorskip("casadi")
    model = random_tree(4, 5, allow_translation=False)
    scene = PlanarScene(model)
    n = model.n_coordinates
    q_sym, v_sym = casadi.SX.sym("q", n), casadi.SX.sym("v", n)
    t = 0.3
    bodies, joints = scene.terms(CASADI, q_sym, v_sym, t)
    solution = articulated_sweep(CASADI, scene.tree, bodies, joints)
    function = casadi.Function("x", [q_sym, v_sym], [casadi.vertcat(*solution.x)])
    numeric = articulated_sweep(NUMPY, scene.tree, *scene.terms(NUMPY, *(np.asarray(a)[None, :, None] for a in
                                                                        random_state(model, 4)[:2]), t))
    q, v, _ = random_state(model, 4)
    assert _relative(np.asarray(function(q, v)).ravel(), np.concatenate([x[0, :, 0] for x in numeric.x])) <= 1e-13


def _kernel_inputs(model, q, v, t):
    theta, omega = model.body_angles(q, v, t)
    K, b, E, _ = body_terms(model, theta, omega, t)
    return K, b, E, hinge_torques(model, theta, omega, t)


@pytest.mark.parametrize("seed", range(4))
def test_rigid_tree_sweep_traced_and_numpy_equal_the_scene_sweep_with_joint_tangents(seed):
    """The implicit context: arbitrary kappa and the rigid sweep's own (K, b, E) as BodyTerms, assembled here from
    the scene's joints; the traced (casadi) and the numpy evaluation of RigidTreeSweep both give its numbers."""
    model = random_tree(seed, 6, allow_translation=False)
    q, v, t = random_state(model, seed)
    K, b, E, tau = _kernel_inputs(model, q, v, t)
    rng = np.random.default_rng(seed)
    kappa = rng.uniform(0.5, 5.0, model.n_bodies)
    alpha_driven = [0.0] * model.n_bodies
    for i, _, _, acceleration in model.driven(t):
        alpha_driven[i] = acceleration
    sweep = RigidTreeSweep(model.parent, model.joint_kind, model.joint_names)
    A, F, alpha = sweep(K, b, E, kappa, tau, alpha_driven)
    A_np, F_np, alpha_np = sweep.numpy_sweep(K, b, E, kappa, tau, np.array(alpha_driven))
    assert _relative(A_np, A) <= 1e-13 and _relative(F_np, F) <= 1e-13
    assert np.max(np.abs(alpha_np - alpha)) <= 1e-13 * np.max(np.abs(alpha))
    scene = PlanarScene(model)
    _, joints = scene.terms(NUMPY, q[None, :, None], v[None, :, None], t)
    bodies = []
    for j in range(model.n_bodies):
        Kin, c, RF = {}, {}, {}
        for child in np.flatnonzero(model.parent == j):
            kx, ky, lx, ly, cx, cy = E[child]
            point = scene.tree.point[child]
            Kin[point] = np.array([[[1.0, 0.0, kx], [0.0, 1.0, ky], [0.0, 0.0, 1.0]]])
            RF[point] = np.array([[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [lx, ly, 1.0]]])
            c[point] = np.array([[[cx], [cy], [0.0]]])
        bodies.append(BodyTerms(K[j].reshape(1, 3, 3), b[j].reshape(1, 3, 1), Kin, c, RF))
    kap = [None if joint.free != 1 else np.full((1, 1, 1), kappa[j]) for j, joint in enumerate(joints)]
    joints = [joint if joint.tau is None or joint.free != 1 else
              type(joint)(S=joint.S, tau=np.full((1, 1, 1), tau[j])) for j, joint in enumerate(joints)]
    result = articulated_sweep(NUMPY, scene.tree, bodies, joints, kap)
    assert _relative([x[0, :, 0] for x in result.x], A) <= 1e-12
    assert _relative([f[0, :, 0] for f in result.force], F) <= 1e-12
    rel = [0.0 if r is None else r[0, -1, 0] for r in result.relative]
    free = model.joint_kind != 2
    assert _relative(np.array(rel)[free], np.array(alpha)[free]) <= 1e-12


@pytest.mark.parametrize("seed", range(3))
def test_unit_axis_hint_gives_the_numbers_of_the_products_with_S(seed):
    """Revolute and driven joints carry ``axis = 2``; the sweep without the hint (products with ``S``)
    gives the same accelerations, forces, pivots and characteristic, explicit and with tangents."""
    from dataclasses import replace

    model = random_tree(seed, 6, allow_translation=False)
    q, v, t = random_state(model, seed)
    scene = PlanarScene(model)
    bodies, joints = scene.terms(NUMPY, q[None, :, None], v[None, :, None], t)
    assert any(joint.axis == 2 for joint in joints)
    plain = [replace(joint, axis=None) for joint in joints]
    rng = np.random.default_rng(seed)
    kappa = [np.full((1, 1, 1), rng.uniform(0.5, 5.0)) if joint.free == 1 and joint.tau is not None else None
             for joint in joints]
    for kap in (None, kappa):
        hinted = articulated_sweep(NUMPY, scene.tree, bodies, joints, kap, characteristic=True)
        products = articulated_sweep(NUMPY, scene.tree, bodies, plain, kap, characteristic=True)
        for a, b in [(hinted.x, products.x), (hinted.force, products.force),
                     ([p for p in hinted.pivot if p is not None], [p for p in products.pivot if p is not None])]:
            assert _relative(np.concatenate([np.ravel(e) for e in a]), np.concatenate([np.ravel(e) for e in b])) <= 1e-13
        assert _relative(hinted.characteristic, products.characteristic) <= 1e-13


def test_unit_axis_hint_needs_one_column():
    from ctmm.protocol import JointTerms

    with pytest.raises(ModelError, match="axis = 2"):
        JointTerms(S=np.eye(3), axis=2)
    with pytest.raises(ModelError, match="axis = 3"):
        JointTerms(S=np.ones((3, 1)), axis=3)


@pytest.mark.parametrize("name", sorted(FLEXIBLE))
def test_flexible_system_sweep_is_the_one_sweep_of_the_scene_with_joint_tangents(name):
    model = FLEXIBLE[name]()
    system = model.flexible_system
    rng = np.random.default_rng(3)
    q, v, t = 0.3 * rng.normal(size=model.n_coordinates), rng.normal(size=model.n_coordinates), 0.4
    terms, (theta, omega, _, _, _) = system.all_terms(q, v, t)
    tau = system.hinge_torques(q, v, theta, omega, t)
    kappa = rng.uniform(0.5, 5.0, model.n_bodies)
    x, F, _, alpha = system.sweep(terms, kappa.tolist(), tau.tolist(), system.driven_alpha(t))
    scene = PlanarScene(model)
    bodies, joints = scene.terms(NUMPY, q[None, :, None], v[None, :, None], t)
    for j, (M, h, ends) in enumerate(terms):     # the kernel's own terms (same numbers by construction)
        points = list(bodies[j].Kin)
        bodies[j] = BodyTerms(M[None], h[None, :, None], {p: e[0][None] for p, e in zip(points, ends)},
                              {p: e[1][None, :, None] for p, e in zip(points, ends)},
                              {p: e[2][None] for p, e in zip(points, ends)})
    kap = [np.full((1, 1, 1), kappa[j]) if joint.free == 1 and joint.tau is not None else None
           for j, joint in enumerate(joints)]
    result = articulated_sweep(NUMPY, scene.tree, bodies, joints, kap)
    assert _relative(np.concatenate([xj[0, :, 0] for xj in result.x]), np.concatenate(x)) <= 1e-12
    assert _relative([f[0, :, 0] for f in result.force], F) <= 1e-12


def test_bad_trees_and_unsupported_joints_are_refused():
    with pytest.raises(ModelError, match="topological order"):
        Tree((-1, 2, 0), (None, "out", "out"))
    with pytest.raises(ModelError, match="one entry per body"):
        Tree((-1, 0), (None,))
    pendulum = PlanarModel.chain("p", [Pinned("o"), RigidBody.uniform_link("l", mass=1.0, length=1.0)])
    with pytest.raises(ModelError, match=r"\(B, 1\)"):
        PlanarScene(pendulum).accelerations(np.zeros(5), np.zeros(5))


# ------------------------------------------------------------------ first caller: ctmm.linearize of planar models
def _first_order(M, C, K):
    n = M.shape[0]
    return np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])


def test_linearize_takes_its_state_matrix_from_the_one_sweep_exactly():
    import ctmm
    from ctmm.planar_linearization import jacobian

    for model, q0 in _equilibrium_models()[:3]:
        lin = ctmm.linearize(model, operating_point=(q0, np.zeros_like(q0)), inputs=[], outputs=[],
                             allow_nonequilibrium=True)      # random loads vary in time: the tangent at t = 0
        A = np.asarray(lin.state_space.A)
        M, C, K = PlanarLagrange(model).linearize(q0)
        assert _relative(A, _first_order(M, C, K)) <= 1e-13          # the difference path met 1e-9
        assert 0.0 < lin.operating_point.jacobian_error <= 1e-9
        # cross-check: the Richardson difference path of today's kernel, within its own error estimate
        n = model.n_coordinates
        Jq, error = jacobian(lambda q: accelerations(model, q, np.zeros(n)), q0)
        assert np.all(np.abs(A[n:, :n] - Jq) <= error + 1e-12 * np.max(np.abs(Jq)))


def test_linearize_falls_back_to_differences_when_the_complex_step_disagrees(monkeypatch):
    import ctmm
    import ctmm.planar_linearization as planar_linearization

    model, q0 = _equilibrium_models()[1]
    n = model.n_coordinates
    monkeypatch.setattr(planar_linearization, "_complex_step_jacobians",
                        lambda *args, **kwargs: (np.zeros((n, n)), np.zeros((n, n))))   # a non-analytic term
    lin = ctmm.linearize(model, operating_point=(q0, np.zeros(n)), inputs=[], outputs=[], allow_nonequilibrium=True)
    M, C, K = PlanarLagrange(model).linearize(q0)
    assert _relative(np.asarray(lin.state_space.A), _first_order(M, C, K)) <= 1e-9
    assert lin.operating_point.jacobian_error > 1e-14               # Richardson's estimate, not the cross-check


def test_linearize_of_a_model_off_the_protocol_uses_differences():
    import ctmm

    model = PlanarModel.chain("bushed", [Pinned("o"), RigidBody.uniform_link("l1", mass=1.0, length=1.0),
                                         ElasticHinge("h", stiffness=4.0, translational_stiffness=300.0),
                                         RigidBody.uniform_link("l2", mass=0.5, length=0.8)])
    lin = ctmm.linearize(model, inputs=[], outputs=[])
    q0 = lin.operating_point.q
    M, C, K = PlanarLagrange(model).linearize(q0)
    assert _relative(np.asarray(lin.state_space.A), _first_order(M, C, K)) <= 1e-8
    assert 0.0 < lin.operating_point.jacobian_error <= 1e-8


def test_frequency_context_with_modal_elimination_equals_the_flexible_lagrange_linearisation():
    """Delta(s) = prod det D_j prod det C_j = det(s^2 M + s C + K) = det(M) det(s I - A): the ratio to
    det(s I - A) of the differentiated FlexibleLagrange model is the constant det M."""
    from ctmm.planar import SpringDamperHinge
    from ctmm.planar_linearization import jacobian

    model = PlanarModel.chain("hub_beam_link", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", angle=0.3),
        _beam("b", n_axial_modes=1, axial_stiffness=300.0, damping_ratio=0.02),
        SpringDamperHinge("e", stiffness=3.0, damping=0.2), RigidBody.uniform_link("l", mass=0.3, length=0.5)])
    q0 = static_equilibrium(model, hanging_configuration(model))
    n = model.n_coordinates
    reference = FlexibleLagrange(model)
    Jq, _ = jacobian(lambda q: reference.accelerations(q, np.zeros(n)), q0)
    Jv, _ = jacobian(lambda v: reference.accelerations(q0, v), np.zeros(n))
    A = np.block([[np.zeros((n, n)), np.eye(n)], [Jq, Jv]])
    s = np.array([0.3 + 1.7j, -0.2 + 0.5j, 2.0j, 0.7, 5.0 + 3.0j])
    ratio = PlanarScene(model).frequency(q0, s).characteristic[:, 0, 0] / np.linalg.det(
        s[:, None, None] * np.eye(2 * n) - A)
    assert np.max(np.abs(ratio - ratio[0])) <= 1e-9 * abs(ratio[0])


@pytest.mark.parametrize("seed", range(3))
def test_implicit_tangent_sweep_on_the_one_sweep_equals_the_rigid_tree_sweep(seed):
    """The planar Newton step's tangent relations swept by articulated_sweep (the path of models with
    translational springs) give the numbers of RigidTreeSweep (traced) on rigid revolute trees."""
    from ctmm.planar.implicit import _NewtonStep
    from ctmm.planar.sweep import solve_instant

    model = random_tree(seed, 6, allow_translation=False)
    q, v, t = random_state(model, seed)
    h = 0.01
    step = _NewtonStep(model, 0.25 * h * h, 0.5 * h)
    start = solve_instant(model, q, v, t)
    tangent = step.linearise(q, v, t, start.body_acceleration, start.joint_force, start.qddot)
    A, F, _ = step.solve(tangent)
    A_one, F_one, translation = step.tangent_sweep(tangent["K"], tangent["b"], tangent["E"], tangent["tau_tilde"],
                                                   tangent["alpha_d"], None)
    assert translation == {}
    assert _relative(A_one, A) <= 1e-12 and _relative(F_one, F) <= 1e-12


def test_rigid_tree_sweep_refuses_bad_structure_and_names_a_singular_hinge():
    """Joint kinds off the rigid sweep are refused up front (ModelError naming the joint); a zero articulated
    inertia gives non-finite accelerations, reported as a SimulationError naming the joint."""
    from ctmm.errors import SimulationError
    from ctmm.planar.model import BUSHING, FREE, REVOLUTE

    with pytest.raises(ModelError, match=r"joint 'b' has kind 3; allowed: revolute"):
        RigidTreeSweep([-1, 0], [REVOLUTE, BUSHING], ["a", "b"])
    with pytest.raises(ModelError, match=r"joint 'hinge 1' has kind 2"):
        RigidTreeSweep([-1, 0], [REVOLUTE, FREE])
    sweep = RigidTreeSweep([-1, 0], [REVOLUTE, REVOLUTE], ["a", "b"])
    K = np.tile(np.diag([1.0, 1.0, 0.5]).reshape(1, 9), (2, 1))
    K[1, 8] = 0.0                                  # body "b": no inertia about its hinge
    args = (K, np.zeros((2, 3)), np.zeros((2, 6)), np.zeros(2), np.ones(2), np.zeros(2))
    for evaluate in (sweep, lambda *a: sweep(*(np.asarray(x, complex) for x in a))):
        with pytest.raises(SimulationError, match=r"articulated inertia of joint 'b' is singular"):
            evaluate(*args)


def test_model_sweep_is_one_per_structure():
    """The traced sweep is built once per tree structure (a memo of the structure, not of the model object)."""
    first = random_tree(0, 5, allow_translation=False)
    again = random_tree(0, 5, allow_translation=False)
    assert first is not again and model_sweep(first) is model_sweep(again)


def test_rigid_tree_sweep_is_safe_in_threads():
    """The traced sweep runs through one buffer per thread: concurrent calls on one model give the serial numbers."""
    from concurrent.futures import ThreadPoolExecutor

    model = random_tree(1, 7, allow_translation=False)
    states = [random_state(model, seed)[:2] for seed in range(40)]
    serial = [accelerations(model, q, v) for q, v in states]
    with ThreadPoolExecutor(4) as pool:
        for _ in range(3):
            threaded = list(pool.map(lambda state: accelerations(model, *state), states))
            assert all(np.array_equal(a, b) for a, b in zip(threaded, serial))
