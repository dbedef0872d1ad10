"""A ctmm.fem subsystem closing a kinematic loop: a four-bar whose coupler is a finite-element beam cut at its tip.

The coupler ``FiniteElementModel(...).subsystem("coupler", boundary=("n0", "n<ne>"))`` hangs from the crank at its
root node and is joined to the rocker by a cut joint at its tip node (``docs/closed_loops.md`` §4c): the cut force
enters the subsystem as a nodal load at that node, the cut's rows read that node's motion.  Independent reference:
``ctmm.reference.fem_loop_global`` -- the two branches as global Lagrange models (``mixed_global.GlobalChain``: own
Hermite interpolation, Gauss-point masses, strain-energy stiffness) closed by a Lagrange multiplier, sharing no code
with ``ctmm.fem``, the planar model, the sweep or the cut joints.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import null_space

import ctmm
from ctmm.errors import ModelError
from ctmm.fem import BeamElement, FiniteElementModel, NodeSpring, PointMass
from ctmm.nonlinear_laws import LinearLaw
from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.equilibrium import hanging_configuration
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel, simulate_kinematic_loops
from ctmm.reference.fem_loop_global import GlobalLoop
from ctmm.reference.mixed_global import BeamSegment, GlobalChain, RigidSegment

EI, EA, RHO_A, LENGTH = 20.0, 2e3, 1.0 / 0.6, 0.6        # [N m^2], [N], [kg/m], [m]: the coupler (1 kg)


def fe_four_bar(elements: int, *, rayleigh=(0.0, 0.0), law=None, baumgarte: float = 20.0) -> KinematicLoopModel:
    nodes = {f"n{k}": (k * LENGTH / elements, 0.0) for k in range(elements + 1)}
    fe = FiniteElementModel("coupler", nodes, [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", EI, EA, RHO_A)
                                               for k in range(elements)], rayleigh=rayleigh)
    tree = PlanarModel("fe_four_bar", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.7, 0.0)),
        RigidBody.uniform_link("crank", mass=0.4, length=0.2), SmoothHinge("h1", parent="g", child="crank"),
        fe.subsystem("coupler", boundary=("n0", f"n{elements}")), SmoothHinge("h2", parent="crank", child="coupler"),
        RigidBody.uniform_link("rocker", mass=0.8, length=0.5), SmoothHinge("h4", parent="g4", child="rocker")],
        gravity=(0.0, -9.81))
    cut = CutJoint("h3", parent="rocker.out", child=f"coupler.n{elements}",
                   **({} if law is None else {"moment_law": LinearLaw(law[0], law[1]), "rest_angle": law[2]}))
    return KinematicLoopModel(tree, [cut], baumgarte=baumgarte)


def reference(elements: int, *, rayleigh=(0.0, 0.0), law=None, baumgarte: float = 0.0) -> GlobalLoop:
    crank = GlobalChain([RigidSegment(0.2, 0.4, 0.4 * 0.2 ** 2 / 12, 0.1),
                         BeamSegment(LENGTH, elements, EI, EA, RHO_A, rayleigh=rayleigh)])
    rocker = GlobalChain([RigidSegment(0.5, 0.8, 0.8 * 0.5 ** 2 / 12, 0.25)])
    return GlobalLoop([(crank, (0.0, 0.0)), (rocker, (0.7, 0.0))], [(1, 0)], baumgarte=baumgarte, cut_laws=[law])


def start(loop: KinematicLoopModel, deformation: float = 0.0):
    """Crank at 90 deg with 3 rad/s; the coupler's nodes displaced by ``deformation`` times a fixed pattern (held);
    the coupler and rocker angles assembled."""
    names = loop.tree.coordinates
    nodal = [n for n in names if n.startswith("coupler.n")]
    pattern = deformation * np.sin(np.arange(1, len(nodal) + 1))
    q = [math.pi / 2 if n == "crank.theta" else 0.5 if n == "coupler.theta" else 1.8 if n == "rocker.theta"
         else float(pattern[nodal.index(n)]) for n in names]
    v = [3.0 if n == "crank.theta" else 0.5 * float(pattern[nodal.index(n)]) * 40 if n in nodal else 0.0
         for n in names]
    return loop.consistent_state(q, v, keep=["crank.theta", *nodal])


def equilibrium(loop: KinematicLoopModel, ref: GlobalLoop) -> tuple[np.ndarray, np.ndarray]:
    """The hanging equilibrium by the global model's Newton from the tree's hanging configuration (nodes held)."""
    hanging = np.asarray(hanging_configuration(loop.tree), float)
    nodal = [n for n in loop.tree.coordinates if n.startswith("coupler.n")]
    return ref.equilibrium(loop.consistent_state(hanging, np.zeros(len(hanging)), keep=nodal)[0])


def test_coordinates_are_the_reference_s():
    loop = fe_four_bar(2)
    assert loop.tree.coordinates == ("crank.theta", "coupler.theta", "coupler.n1_ux", "coupler.n1_uy",
                                     "coupler.n1_rz", "coupler.n2_ux", "coupler.n2_uy", "coupler.n2_rz",
                                     "rocker.theta")
    assert reference(2).n == loop.tree.n_coordinates


@pytest.mark.parametrize("rayleigh, law", [((0.0, 0.0), None), ((0.5, 2e-4), (3.0, 0.05, -1.2))])
def test_accelerations_and_cut_force_match_the_global_model(rayleigh, law):
    """Bent, moving state (nodal displacements up to 9 mm, rates up to 0.36 m/s): accelerations and the cut force
    on the tip node, with Rayleigh damping and a spring-damper at the cut (it acts on the tip node's rotation)."""
    loop, ref = fe_four_bar(3, rayleigh=rayleigh, law=law), reference(3, rayleigh=rayleigh, law=law)
    q, v = start(loop, 0.01)
    assert np.max(np.abs(q[2:-1])) > 5e-3
    qdd, force = loop.solve(q, v)
    qdd_ref, force_ref = ref.solve(q, v)
    assert np.max(np.abs(qdd - qdd_ref)) < 1e-10 * np.max(np.abs(qdd_ref))
    assert np.max(np.abs(force - force_ref)) < 1e-10 * np.max(np.abs(force_ref))
    if law is not None:
        assert abs(loop.relative_angles(q, v)[0][0] - ref.relative_angles(q)[0]) < 1e-14
        assert abs(loop.relative_angles(q, v)[1][0] - ref.relative_angles(v)[0]) < 1e-14


def test_rk4_history_matches_the_global_model_step_for_step():
    """The same ODE (Baumgarte 20/s on both, no projection), the same RK4 step, from a bent, moving state: equal to
    round-off."""
    loop, ref = fe_four_bar(2), reference(2, baumgarte=20.0)
    q0, v0 = start(loop, 0.005)
    run = simulate_kinematic_loops(loop, q0, v0, t_final=0.01, dt=5e-4, projection=False)
    q_ref, v_ref = ref.rk4(q0, v0, 0.01, 5e-4)
    assert np.ptp(run.q[:, 2:-1], axis=0).max() > 1e-3                  # the coupler's nodes move
    assert np.max(np.abs(run.q - q_ref)) < 1e-11
    assert np.max(np.abs(run.qdot - v_ref)) < 1e-9


def test_verbs_run_it_at_fourth_order_against_a_tight_dae_solution():
    """``ctmm.simulate`` (RK4 + projection, undamped) from a straight start: on the constraints, the global model's
    energy conserved, and converging at fourth order to DOP853 of the global model (1e-12) -- measured 1.1e-6,
    7.8e-8 (0.5, 0.25 ms; the coupler's axial mode at 2100 rad/s sets the error); ``compiled=True``:
    tests/test_compiled_kinematic_loops_flexible.py."""
    loop, ref = fe_four_bar(2), reference(2, baumgarte=20.0)
    q0, v0 = start(loop)
    errors = []
    for dt in (5e-4, 2.5e-4):
        run = ctmm.simulate(loop, 0.01, dt, x0=q0, v0=v0)
        q = np.column_stack([run[name] for name in loop.tree.coordinates])
        q_ref, _ = ref.simulate(q0, v0, np.asarray(run.time))
        errors.append(np.max(np.abs(q - q_ref)))
    assert np.max(run["drift"]) < 1e-14 and np.ptp(run["coupler.n2_rz"]) > 5e-3   # it bends
    v = np.column_stack([run[name + "_dot"] for name in loop.tree.coordinates])
    energy = np.array([ref.energy(a, b) for a, b in zip(q, v)])
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * np.max(np.abs(energy))
    assert errors[1] < 2e-7 and errors[0] / errors[1] > 10.0


def test_newmark_dt_tmm_run_tracks_the_global_model():
    """The DT-TMM Newmark scheme (the cut forces re-solved at every Newton iterate, ``docs/closed_loops.md`` §3c)
    against DOP853 of the global model, 1 ms over 0.01 s: crank and rocker 2.1e-6 rad, nodes 1.3e-4 (the axial
    mode at 2100 rad/s is far beyond 1 / dt: its phase error dominates)."""
    loop, ref = fe_four_bar(2), reference(2, baumgarte=20.0)
    q0, v0 = start(loop)
    run = ctmm.simulate(loop, 0.01, 1e-3, x0=q0, v0=v0, method="newmark")
    q = np.column_stack([run[name] for name in loop.tree.coordinates])
    q_ref, _ = ref.simulate(q0, v0, np.asarray(run.time))
    assert np.max(np.abs(q[:, [0, -1]] - q_ref[:, [0, -1]])) < 4e-6
    assert np.max(np.abs(q - q_ref)) < 3e-4


def test_natural_frequencies_match_the_constrained_global_model():
    """About the hanging equilibrium (found by the global model's Newton on ``(q, lambda)``; the library checks it is
    one, else refuses): the library's manifold tangent vs ``eig(N^T K N, N^T M N)`` of the global model's Lagrangian
    (with the static cut force's curvature term, by complex step): measured 3.2e-11 (the Richardson tangent of
    :func:`ctmm.loop_manifold.accurate_tangent`)."""
    loop, ref = fe_four_bar(2), reference(2)
    q_eq, lam = equilibrium(loop, ref)
    assert np.max(np.abs(loop.solve(q_eq, np.zeros_like(q_eq))[0])) < 1e-8
    assert np.max(np.abs(loop.solve(q_eq, np.zeros_like(q_eq))[1] - lam)) < 1e-8
    omega = ctmm.natural_frequencies(loop, operating_point=(q_eq, np.zeros_like(q_eq)))
    omega_ref = ref.natural_frequencies(q_eq, lam)
    assert len(omega) == len(omega_ref) == loop.tree.n_coordinates - 2
    assert np.max(np.abs(omega - omega_ref) / omega_ref) < 3e-10


def test_cut_torque_response_matches_the_constrained_global_model():
    """A torque across the cut (on the tip node's rotation and on the rocker) -> the node's deflection and the cut
    angle, about the hanging equilibrium: ``ctmm.linearize`` vs ``C N (N^T (K - w^2 M) N)^-1 N^T b`` of the global
    model (``b`` the torque's generalised force, ``K`` the Lagrangian's stiffness): measured 2.1e-10 at 3 rad/s."""
    loop, ref = fe_four_bar(2), reference(2)
    q_eq, lam = equilibrium(loop, ref)
    rest = np.zeros_like(q_eq)
    lin = ctmm.linearize(loop, (q_eq, rest), inputs=["h3.torque"], outputs=["coupler.n2_uy", "h3.angle"])
    A, B, C, D = (np.asarray(m) for m in (lin.state_space.A, lin.state_space.B, lin.state_space.C, lin.state_space.D))
    M, _ = ref.mass_and_forces(q_eq, rest)
    N = null_space(ref.constraints(q_eq, rest)[1])
    K = ref.stiffness(q_eq, lam)
    torque = ref.angle_row(0) - ref.angle_row(1)                 # child (the coupler's tip) minus parent (rocker)
    C_ref = np.vstack([np.eye(len(q_eq))[6], torque])
    for w in (3.0, 50.0, 200.0):
        H = C @ np.linalg.solve(1j * w * np.eye(A.shape[0]) - A, B) + D
        H_ref = C_ref @ N @ np.linalg.solve(N.T @ (K - w * w * M) @ N, N.T @ torque)
        assert np.max(np.abs(H[:, 0] - H_ref)) < 2e-9 * np.max(np.abs(H_ref))


def test_a_cut_at_a_node_that_is_not_a_boundary_node_is_refused_by_name():
    loop = fe_four_bar(2)
    with pytest.raises(ModelError, match=r"outboard boundary nodes.*n2"):
        KinematicLoopModel(loop.tree, [CutJoint("h3", parent="rocker.out", child="coupler.n1")])


def _particle_tip_four_bar(**cut_options) -> KinematicLoopModel:
    """The coupler: a beam element n0-n1 and a particle n2 on a spring from n1 (no rotation DOF at n2), cut at n2."""
    nodes = {"n0": (0.0, 0.0), "n1": (0.45, 0.0), "n2": (0.6, 0.0)}
    fe = FiniteElementModel("coupler", nodes, [BeamElement("e0", "n0", "n1", EI, EA, RHO_A),
                                               NodeSpring("s", "n1", "n2", stiffness=4e3), PointMass("p", "n2", 0.2)])
    tree = PlanarModel("particle_four_bar", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.7, 0.0)),
        RigidBody.uniform_link("crank", mass=0.4, length=0.2), SmoothHinge("h1", parent="g", child="crank"),
        fe.subsystem("coupler", boundary=("n0", "n2")), SmoothHinge("h2", parent="crank", child="coupler"),
        RigidBody.uniform_link("rocker", mass=0.8, length=0.5), SmoothHinge("h4", parent="g4", child="rocker")],
        gravity=(0.0, -9.81))
    return KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.n2", **cut_options)])


def test_a_particle_node_closes_the_loop_without_taking_a_moment():
    """A cut at a subsystem node without a rotation DOF: the smooth cut runs and its nodal load does no work (the
    undamped linkage's energy, RK4 + projection); a moment law, torque or drive there, and the ``"h3.torque"``
    actuator, are refused by name."""
    loop = _particle_tip_four_bar()
    assert "coupler.n2_rz" not in loop.tree.coordinates
    q0, v0 = start(loop)
    run = simulate_kinematic_loops(loop, q0, v0, t_final=0.005, dt=2.5e-4)
    energy = run.energy()
    assert np.ptp(run.coordinate("coupler.n2_ux")) > 1e-5 and np.max(run.drift) < 1e-14
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * np.max(np.abs(energy))
    with pytest.raises(ModelError, match=r"h3.*coupler.n2.*without a rotation DOF"):
        _particle_tip_four_bar(moment_law=LinearLaw(1.0, 0.0))
    with pytest.raises(ModelError, match="h3.torque"):
        ctmm.linearize(loop, (q0, np.zeros_like(q0)), inputs=["h3.torque"], allow_nonequilibrium=True)
