"""The independent spatial reference model (ctmm.reference.spatial_tree) against Pinocchio and
against closed forms.

Tolerances: Pinocchio comparisons 1e-12 relative to the largest entry (measured: <= 4e-15 on
~10-body trees with every joint kind); closed forms as stated per test.
"""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.errors import ModelError
from ctmm.reference.spatial_kinematics import kinematics, orientations
from ctmm.reference.spatial_tree import (
    PointLoad, SpatialBody, SpatialTree, bias_forces, configuration_rate, energy,
    forward_dynamics, inverse_dynamics, joint_law_forces, joint_reactions, linearize,
    mass_matrix, natural_frequencies, retract, simulate)

KINDS = ("revolute", "prismatic", "universal", "spherical", "free", "elastic6", "weld")
ROUND_OFF = 1e-12


def _unit(rng, size=3):
    x = rng.normal(size=size)
    return x / np.linalg.norm(x)


def _rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q @ np.diag(np.sign(np.diag(r)))
    return q if np.linalg.det(q) > 0 else -q


def _inertia(rng):
    a = rng.normal(size=(3, 3))
    return a @ a.T + 0.2 * np.eye(3)


def random_tree(rng, kinds, springs=False, loads=False):
    """Random tree with the given joint kinds (body i gets kinds[i]); free joints only at the
    ground.  Depth-first order (the parent is body i-1 or one of its ancestors), as Pinocchio's
    CRBA needs (its subtree velocity indices must be contiguous)."""
    bodies, path = [], [-1]
    for i, kind in enumerate(kinds):
        parent = -1 if (i == 0 or kind == "free") else int(rng.choice(path))
        path = path[: path.index(parent) + 1] + [i]
        axes = [_unit(rng) for _ in range({"revolute": 1, "prismatic": 1,
                                            "universal": 2}.get(kind, 0))]
        nv = {"revolute": 1, "prismatic": 1, "universal": 2, "spherical": 3, "free": 6,
              "elastic6": 6, "weld": 0}[kind]
        stiffness = damping = None
        if springs and kind not in ("free", "weld"):
            stiffness, damping = rng.uniform(1, 5, nv), rng.uniform(0.1, 0.5, nv)
        bodies.append(SpatialBody(f"b{i}", parent, kind, rng.uniform(0.5, 2.0),
                                  rng.normal(scale=0.3, size=3), _inertia(rng), axes=axes,
                                  joint_position=rng.normal(scale=0.5, size=3),
                                  joint_rotation=_rotation(rng), stiffness=stiffness,
                                  damping=damping))
    applied = ()
    if loads:
        applied = (PointLoad(len(kinds) - 1, rng.normal(size=3), rng.normal(size=3),
                             rng.normal(size=3)),)
    return SpatialTree(tuple(bodies), gravity=(0.3, -0.5, -9.81), loads=applied)


def random_state(rng, tree):
    q = retract(tree, tree.neutral_configuration(), rng.normal(size=tree.nv))
    return q, rng.normal(size=tree.nv), rng.normal(size=tree.nv)


def pinocchio_model(tree):
    """The same tree built in Pinocchio (weld bodies merged into their parent's joint)."""
    pin = pytest.importorskip("pinocchio")
    model = pin.Model()
    model.gravity.linear = np.array(tree.gravity)
    frame_of = []            # per body: (pinocchio joint id, placement of the body in it)
    for body in tree.bodies:
        joint_id, base = (0, pin.SE3.Identity()) if body.parent < 0 else frame_of[body.parent]
        placement = base * pin.SE3(body.joint_rotation, body.joint_position)
        inertia = pin.Inertia(body.mass, body.com, body.inertia)
        if body.joint == "weld":
            model.appendBodyToJoint(joint_id, inertia, placement)
            frame_of.append((joint_id, placement))
            continue
        joint = {"revolute": lambda: pin.JointModelRevoluteUnaligned(body.axes[0]),
                 "prismatic": lambda: pin.JointModelPrismaticUnaligned(body.axes[0]),
                 "universal": lambda: pin.JointModelUniversal(body.axes[0], body.axes[1]),
                 "spherical": pin.JointModelSpherical,
                 "free": pin.JointModelFreeFlyer,
                 "elastic6": pin.JointModelFreeFlyer}[body.joint]()
        new_id = model.addJoint(joint_id, joint, placement, body.name)
        model.appendBodyToJoint(new_id, inertia, pin.SE3.Identity())
        frame_of.append((new_id, pin.SE3.Identity()))
    return pin, model, model.createData(), frame_of


def _close(a, b):
    scale = max(1.0, float(np.max(np.abs(b))))
    assert np.max(np.abs(np.asarray(a) - np.asarray(b))) <= ROUND_OFF * scale


@pytest.mark.parametrize("seed", range(4))
def test_every_joint_kind_matches_pinocchio(seed):
    rng = np.random.default_rng(seed)
    kinds = ["free"] + list(rng.permutation([k for k in KINDS if k != "free"])) \
        + list(rng.choice(KINDS[:6], size=3))
    tree = random_tree(rng, [k if k != "free" or i == 0 else "elastic6"
                             for i, k in enumerate(kinds)])
    pin, model, data, _ = pinocchio_model(tree)
    assert model.nq == tree.nq and model.nv == tree.nv
    q, v, tau = random_state(rng, tree)
    crba = pin.crba(model, data, q)
    crba = np.triu(crba) + np.triu(crba, 1).T
    _close(mass_matrix(tree, q), crba)
    _close(bias_forces(tree, q, v), pin.rnea(model, data, q, v, np.zeros(tree.nv)))
    _close(forward_dynamics(tree, q, v, tau), pin.aba(model, data, q, v, tau))
    _close(inverse_dynamics(tree, q, v, tau), pin.rnea(model, data, q, v, tau))


@pytest.mark.parametrize("seed", range(2))
def test_orientations_match_pinocchio_and_are_the_kinematics_values_to_the_bit(seed):
    """The cheap route (rotations and angular velocities only) against Pinocchio's forward kinematics, and
    bitwise the values of the full kinematics (real and complex-step inputs) on every joint kind."""
    rng = np.random.default_rng(10 + seed)
    kinds = ["free"] + list(rng.permutation([k for k in KINDS if k != "free"])) + ["universal", "revolute"]
    tree = random_tree(rng, [k if k != "free" or i == 0 else "elastic6" for i, k in enumerate(kinds)])
    pin, model, data, frame_of = pinocchio_model(tree)
    q, v, _ = random_state(rng, tree)
    pin.forwardKinematics(model, data, q, v)
    fast = orientations(tree, q, v)
    for i, (joint_id, placement) in enumerate(frame_of):
        world = data.oMi[joint_id].rotation
        _close(fast.rotation[i], world @ placement.rotation)
        _close(fast.omega[i], world @ data.v[joint_id].angular)
    for q_case, v_case in ((q, v), (q + 1e-20j * rng.normal(size=q.shape), v),
                           (q, v + 1e-20j * rng.normal(size=v.shape))):
        full, fast = kinematics(tree, q_case, v_case), orientations(tree, q_case, v_case)
        assert fast.rotation.dtype == full.rotation.dtype
        assert fast.rotation.tobytes() == full.rotation.tobytes() and fast.omega.tobytes() == full.omega.tobytes()


@pytest.mark.parametrize("seed", range(3))
def test_joint_reactions_match_pinocchio_rnea_forces(seed):
    rng = np.random.default_rng(10 + seed)
    tree = random_tree(rng, ["free", "spherical", "revolute", "universal", "weld",
                             "prismatic", "elastic6", "revolute"])
    pin, model, data, frame_of = pinocchio_model(tree)
    q, v, tau = random_state(rng, tree)
    vdot = forward_dynamics(tree, q, v, tau)
    pin.rnea(model, data, q, v, vdot)
    ours = joint_reactions(tree, q, v, vdot)
    for i, body in enumerate(tree.bodies):
        if body.joint != "weld":
            _close(ours[i], np.concatenate([data.f[frame_of[i][0]].linear,
                                            data.f[frame_of[i][0]].angular]))
    # across a free joint only the actuation is transmitted: (force, moment) in body axes
    _close(ours[0], tau[:6])


def test_springs_dampers_and_loads_are_generalised_forces_of_pinocchio_model():
    """With springs and a point load, forward dynamics = Pinocchio ABA with the law's forces
    and the load's generalised force (J^T F from Pinocchio's frame Jacobian) as torques."""
    rng = np.random.default_rng(21)
    tree = random_tree(rng, ["elastic6", "spherical", "universal", "revolute", "prismatic"],
                       springs=True, loads=True)
    pin, model, data, frame_of = pinocchio_model(tree)
    q, v, tau = random_state(rng, tree)
    load = tree.loads[0]
    joint_id, placement = frame_of[load.body]
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    jacobian = pin.getJointJacobian(model, data, joint_id, pin.LOCAL_WORLD_ALIGNED)
    point = data.oMi[joint_id].act(placement.act(load.point))
    lever = point - data.oMi[joint_id].translation
    force, moment = load.at(0.0)
    q_load = jacobian[:3].T @ force + jacobian[3:].T @ (moment + np.cross(lever, force))
    expected = pin.aba(model, data, q, v, tau + joint_law_forces(tree, q, v) + q_load)
    _close(forward_dynamics(tree, q, v, tau), expected)


def test_configuration_rate_is_pinocchio_integrate_derivative():
    rng = np.random.default_rng(3)
    tree = random_tree(rng, ["free", "spherical", "universal", "elastic6", "prismatic"])
    pin, model, *_ = pinocchio_model(tree)
    q, v, _ = random_state(rng, tree)
    eps = 1e-6
    numeric = (pin.integrate(model, q, eps * v) - pin.integrate(model, q, -eps * v)) / (2 * eps)
    assert np.max(np.abs(configuration_rate(tree, q, v) - numeric)) < 1e-9


def _conservative_tree():
    rng = np.random.default_rng(5)
    bodies = [SpatialBody("base", -1, "free", 2.0, (0.1, 0, 0), _inertia(rng)),
              SpatialBody("ball", 0, "spherical", 1.0, (0, 0, -0.4), _inertia(rng),
                          joint_position=(0.2, 0.1, 0), stiffness=3.0),
              SpatialBody("arm", 1, "revolute", 0.7, (0.3, 0, 0), _inertia(rng),
                          axes=[(0, 1, 0)], joint_position=(0, 0, -0.5), stiffness=2.0),
              SpatialBody("pod", 1, "elastic6", 0.5, (0, 0.1, 0), _inertia(rng),
                          joint_position=(0, 0.3, 0),
                          stiffness=np.diag([40, 50, 60, 4, 4, 4]))]
    tree = SpatialTree(tuple(bodies), gravity=(0, 0, -9.81))
    q = retract(tree, tree.neutral_configuration(), rng.normal(scale=0.3, size=tree.nv))
    return tree, q, rng.normal(size=tree.nv)


def test_rk4_conserves_energy_at_order_four():
    tree, q0, v0 = _conservative_tree()
    e0 = sum(energy(tree, q0, v0))
    drift = []
    for dt in (0.01, 0.005):
        run = simulate(tree, q0, v0, 0.4, dt, store_every=1000)
        drift.append(abs(sum(energy(tree, run.q[-1], run.v[-1])) - e0))
    order = np.log2(drift[0] / drift[1])
    assert drift[1] < 1e-5 * abs(e0) + 1e-6
    assert 3.5 < order < 5.5, (drift, order)


def test_physical_pendulum_small_angle_frequency():
    mass, arm, inertia_x = 1.5, 0.4, 0.02
    tree = SpatialTree((SpatialBody("p", -1, "revolute", mass, (0, 0, -arm),
                                    np.diag([inertia_x, 0.03, 0.01]), axes=[(1, 0, 0)]),),
                       gravity=(0, 0, -9.81))
    expected = np.sqrt(mass * 9.81 * arm / (inertia_x + mass * arm ** 2))
    assert abs(natural_frequencies(tree, [0.0])[0] - expected) < 1e-12 * expected
    # and in time: a 1e-3 rad swing returns after one period (RK4, h = T/400)
    period = 2 * np.pi / expected
    run = simulate(tree, [1e-3], [0.0], period, period / 400, store_every=400)
    assert abs(run.q[-1, 0] - 1e-3) < 1e-3 * 1e-5


def test_torque_free_axisymmetric_body_precesses_at_the_euler_rate():
    i1, i3, spin, tilt = 0.5, 0.8, 3.0, 0.7
    tree = SpatialTree((SpatialBody("top", -1, "free", 2.0, (0, 0, 0),
                                    np.diag([i1, i1, i3])),), gravity=(0, 0, 0))
    v0 = np.array([0, 0, 0, tilt, 0, spin])
    t_final = 1.0            # RK4 at h = 4 ms: measured errors 3e-11 (omega), 2e-10 rad (axis)
    run = simulate(tree, tree.neutral_configuration(), v0, t_final, 4e-3, store_every=1000)
    rate = (i3 - i1) / i1 * spin          # body-frame precession of omega about the axis
    expected = tilt * np.array([np.cos(rate * t_final), np.sin(rate * t_final)])
    assert np.max(np.abs(run.v[-1, 3:5] - expected)) < 1e-9
    assert abs(run.v[-1, 5] - spin) < 1e-12
    # in space: the symmetry axis turns about the fixed angular momentum at |L| / I1
    momentum = np.array([i1 * tilt, 0, i3 * spin])
    from ctmm.reference.spatial_kinematics import quaternion_matrix
    axis = quaternion_matrix(run.q[-1, 3:7])[:, 2]
    unit = momentum / np.linalg.norm(momentum)
    start = np.array([0, 0, 1.0]) - unit[2] * unit
    now = axis - (axis @ unit) * unit
    angle = np.arctan2(np.cross(start, now) @ unit, start @ now)
    space_rate = np.linalg.norm(momentum) / i1
    assert abs(np.angle(np.exp(1j * (angle - space_rate * t_final)))) < 1e-9


def test_spring_mass_on_elastic6_frequencies_are_sqrt_eig_of_hand_matrices():
    rng = np.random.default_rng(8)
    mass, com, inertia = 1.3, np.array([0.1, -0.2, 0.15]), _inertia(rng)
    a = rng.normal(size=(6, 6))
    stiffness = a @ a.T * 50 + 10 * np.eye(6)
    damping = np.diag(rng.uniform(0.1, 1, 6))
    tree = SpatialTree((SpatialBody("m", -1, "elastic6", mass, com, inertia,
                                    joint_rotation=_rotation(rng), joint_position=(1, 2, 3),
                                    stiffness=stiffness, damping=damping),),
                       gravity=(0, 0, 0))
    c = np.array([[0, -com[2], com[1]], [com[2], 0, -com[0]], [-com[1], com[0], 0]])
    hand_mass = np.block([[mass * np.eye(3), -mass * c],
                          [mass * c, inertia - mass * c @ c]])
    m_lin, c_lin, k_lin = linearize(tree, tree.neutral_configuration())
    assert np.max(np.abs(m_lin - hand_mass)) < 1e-13
    assert np.max(np.abs(k_lin - stiffness)) < 1e-10 * np.max(stiffness)
    assert np.max(np.abs(c_lin - damping)) < 1e-13
    import scipy.linalg
    expected = np.sqrt(np.sort(scipy.linalg.eigh(stiffness, hand_mass, eigvals_only=True)))
    assert np.max(np.abs(natural_frequencies(tree, tree.neutral_configuration()) - expected)) \
        < 1e-10 * expected[-1]


def test_linearize_gravity_tree_is_symmetric_and_matches_finite_differences():
    """Hanging tree (ball and revolute joints, springs): the complex-step K is symmetric (a
    potential's Hessian) and equals central differences of the forward dynamics' residual."""
    rng = np.random.default_rng(12)
    bodies = (SpatialBody("a", -1, "spherical", 1.0, (0, 0, -0.5), _inertia(rng)),
              SpatialBody("b", 0, "universal", 0.8, (0, 0, -0.3), _inertia(rng),
                          axes=[(1, 0, 0), (0, 1, 0)], joint_position=(0, 0, -1)),
              SpatialBody("c", 1, "revolute", 0.6, (0, 0, -0.2), _inertia(rng),
                          axes=[(0, 0, 1)], joint_position=(0, 0, -0.6), stiffness=5.0))
    tree = SpatialTree(bodies)
    q0 = tree.neutral_configuration()
    _, _, k = linearize(tree, q0)
    assert np.max(np.abs(k - k.T)) < 1e-12 * np.max(np.abs(k))
    eps = 1e-6
    for j in range(tree.nv):
        step = np.zeros(tree.nv)
        step[j] = eps
        numeric = (bias_forces(tree, retract(tree, q0, step), np.zeros(tree.nv))
                   - bias_forces(tree, retract(tree, q0, -step), np.zeros(tree.nv))) / (2 * eps)
        assert np.max(np.abs(numeric - k[:, j])) < 1e-7 * np.max(np.abs(k))


def test_bad_input_is_refused_with_the_parameter_named():
    with pytest.raises(ModelError, match="joint='hinge'"):
        SpatialBody("x", -1, "hinge", 1.0, (0, 0, 0), np.eye(3))
    with pytest.raises(ModelError, match="mass=0"):
        SpatialBody("x", -1, "spherical", 0.0, (0, 0, 0), np.eye(3))
    with pytest.raises(ModelError, match="inertia"):
        SpatialBody("x", -1, "spherical", 1.0, (0, 0, 0), -np.eye(3))
    with pytest.raises(ModelError, match="unit axes"):
        SpatialBody("x", -1, "revolute", 1.0, (0, 0, 0), np.eye(3))
    with pytest.raises(ModelError, match="elastic6"):
        SpatialBody("x", -1, "free", 1.0, (0, 0, 0), np.eye(3), stiffness=1.0)
    body = SpatialBody("x", 1, "spherical", 1.0, (0, 0, 0), np.eye(3))
    with pytest.raises(ModelError, match="parent=1"):
        SpatialTree((body,))
    hanging = SpatialTree((SpatialBody("p", -1, "revolute", 1.0, (0, 0, -1), np.eye(3),
                                       axes=[(1, 0, 0)]),))
    with pytest.raises(ModelError, match="not an equilibrium"):
        linearize(hanging, [0.5])
