"""A particle-spring net (seed 001 Example 9.1's kind) welded to a rigid pendulum: a lumped
GlobalSubsystem with exact nonlinear springs (its nonlinear_force, frame coordinates) against the global
model of :mod:`ctmm.reference.mixed_global` (exact springs from global positions)."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.errors import SimulationError
from ctmm.fem import GlobalSubsystem
from ctmm.planar import PlanarModel, Pinned, RigidBody, SmoothHinge
from ctmm.planar.elements import FixedMounting
from ctmm.planar.sweep import accelerations
from ctmm.reference.mixed_global import GlobalChain, ParticleNet, RigidSegment

PARTICLES = np.array([[0.3, 0.2], [0.6, 0.0], [0.3, -0.2], [0.9, 0.1]])     # link axes, from its tip [m]
MASSES = np.array([0.2, 0.3, 0.25, 0.15])
ANCHORS = {"a_up": (0.0, 0.25), "a_down": (0.0, -0.25)}                      # on the link
SPRINGS = [("a_up", 0, 400.0), ("a_down", 2, 400.0), ("hub", 1, 300.0), (0, 1, 250.0), (1, 2, 250.0),
           (0, 2, 200.0), (1, 3, 350.0), (0, 3, 150.0)]
DAMPING = 0.4


def net_subsystem() -> GlobalSubsystem:
    """User matrices: lumped masses, K = 0; the springs as an exact law in frame coordinates."""
    nodes = {"hub": ((0.0, 0.0), (0, 1))}
    nodes.update({name: (xy, (2 + 2 * k, 3 + 2 * k)) for k, (name, xy) in enumerate(ANCHORS.items())})
    first = 2 + 2 * len(ANCHORS)
    nodes.update({f"p{k}": (tuple(PARTICLES[k]), (first + 2 * k, first + 2 * k + 1)) for k in range(len(MASSES))})
    n = first + 2 * len(MASSES)
    M = np.zeros((n, n))
    M[first:, first:] = np.diag(np.repeat(MASSES, 2))
    position = {name: np.asarray(xy, float) for name, (xy, _) in nodes.items()}
    dofs = {name: list(d) for name, (_, d) in nodes.items()}
    ends = [(a if isinstance(a, str) else f"p{a}", f"p{b}", k) for a, b, k in SPRINGS]

    # the springs as arrays, one row per spring: ends' rest positions and DOFs, stiffness, rest length
    start = np.array([position[a] for a, _, _ in ends])
    end = np.array([position[b] for _, b, _ in ends])
    start_dofs, end_dofs = np.array([dofs[a] for a, _, _ in ends]), np.array([dofs[b] for _, b, _ in ends])
    stiffness = np.array([k for _, _, k in ends])
    rest = np.linalg.norm(end - start, axis=1)

    def springs(u, u_dot, t):
        d = end + u[end_dofs] - start - u[start_dofs]                   # (springs, 2), complex-safe
        length = np.sqrt((d * d).sum(1))
        e = d / length[:, None]
        stretch_rate = (e * (u_dot[end_dofs] - u_dot[start_dofs])).sum(1)
        force = -(stiffness * (length - rest) + DAMPING * stretch_rate)[:, None] * e
        f = np.zeros_like(u)
        np.add.at(f, end_dofs, force)
        np.subtract.at(f, start_dofs, force)
        return f

    def potential(u):
        total = 0.0
        for a, b, k in ends:
            d = position[b] + u[dofs[b]] - position[a] - u[dofs[a]]
            total += 0.5 * k * (np.sqrt(d @ d) - np.linalg.norm(position[b] - position[a])) ** 2
        return total

    return GlobalSubsystem("net", mass_matrix=M, damping_matrix=np.zeros((n, n)), stiffness_matrix=np.zeros((n, n)),
                           nodes=nodes, boundary=("hub",), frame_nodes=tuple(ANCHORS), nonlinear_force=springs,
                           potential=potential)


def build():
    link = RigidBody.uniform_link("link", mass=1.0, length=1.0)
    upper = RigidBody.uniform_link("upper", mass=0.7, length=0.6)
    model = PlanarModel.chain("net_pendulum", [Pinned("base"), upper, SmoothHinge("h"), link,
                                               FixedMounting("mount"), net_subsystem()])
    springs = tuple((ANCHORS[a] if a in ANCHORS else (0.0, 0.0), b, k) if isinstance(a, str) else (a, b, k)
                    for a, b, k in SPRINGS)
    reference = GlobalChain([RigidSegment(0.6, 0.7, 0.7 * 0.36 / 12, 0.3), RigidSegment(1.0, 1.0, 1.0 / 12, 0.5),
                             ParticleNet(tuple(map(tuple, PARTICLES)), tuple(MASSES), springs, DAMPING)])
    return model, reference


def test_the_net_coordinates_are_the_particle_displacements():
    model, reference = build()
    assert model.coordinates == ("upper.theta", "link.theta") + tuple(
        f"net.p{k}_{axis}" for k in range(4) for axis in ("ux", "uy"))
    assert reference.n == model.n_coordinates


def test_accelerations_equal_the_global_model_at_large_deformation():
    model, reference = build()
    rng = np.random.default_rng(11)
    for scale in (0.01, 0.15):                                   # 0.15 m: half the spacing, springs far from linear
        q = rng.normal(size=model.n_coordinates)
        v = rng.normal(size=model.n_coordinates)
        q[2:] *= scale
        a = accelerations(model, q, v, 0.0)
        a_ref = reference.accelerations(q, v)
        assert np.max(np.abs(a - a_ref)) <= 1e-11 * np.max(np.abs(a_ref))
        assert model.energy(q, v) == pytest.approx(reference.energy(q, v), rel=1e-12)   # with the springs' potential


def test_swing_equals_the_global_model_in_time_with_rk4_and_newmark():
    model, reference = build()
    q0 = np.zeros(model.n_coordinates)
    q0[:2] = -0.4, 0.3
    q0[model.coordinates.index("net.p3_uy")] = 0.05
    dt, t_final = 1e-3, 0.3
    result = ctmm.simulate(model, t_final, dt, method="rk4", x0=q0)
    q = np.column_stack([result.extra[c] for c in model.coordinates])
    _, q_ref, _ = reference.rk4(q0, np.zeros_like(q0), t_final, dt)
    assert np.max(np.abs(q - q_ref)) < 1e-9
    newmark = ctmm.simulate(model, t_final, dt, method="newmark", x0=q0)
    q_nm = np.column_stack([newmark[c] for c in model.coordinates])
    assert np.max(np.abs(q_nm - q_ref)) < 5e-5                 # 1.8e-5 (0.5 ms: 4.6e-6, O(h^2))


def test_a_net_on_a_revolute_hinge_without_frame_inertia_is_refused_at_run_time():
    link = RigidBody.uniform_link("link", mass=1.0, length=1.0)
    model = PlanarModel.chain("loose", [Pinned("base"), link, SmoothHinge("free"), net_subsystem()])
    with pytest.raises(SimulationError):
        ctmm.simulate(model, 0.01, 1e-3, method="rk4")
