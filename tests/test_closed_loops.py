"""Closed kinematic loops by cut joints with boundary unknowns (ctmm.planar.closed_loops).

Independent reference: the global DAE of :mod:`ctmm.reference.planar_dae` (absolute coordinates,
Lagrange multipliers, Baumgarte, DOP853 at 1e-11), which shares no code with the TMM sweep or the
cut-joint mechanism.  Checked: angles and cut forces of a four-bar linkage (rigid coupler, a nonlinear
rocker spring), a body with two input ends (a plate hung from two links, seed 002 section 7.4.2.1),
energy conservation of the undamped loop, the drift report, and the refusals.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.errors import ModelError, SimulationError
from ctmm.loop_integration import compliance_condition
from ctmm.nonlinear_laws import CubicSpring
from ctmm.planar import Fixed, NonlinearHinge, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.closed_loops import KinematicLoopModel, CutJoint, simulate_kinematic_loops
from ctmm.reference.planar_dae import PlanarDAE
from ctmm.scenarios.four_bar import DAMPER, SPRING, mechanism as four_bar, reference as four_bar_dae
from ctmm.scenarios.four_bar import start as four_bar_start


def start(loop):
    """Crank at 90 deg with 3 rad/s, coupler and rocker assembled (the four_bar scenario's start)."""
    q0, v0 = four_bar_start(loop)
    assert v0[0] == 3.0 and q0[0] == pytest.approx(math.pi / 2)     # crank held, the others assembled
    return q0, v0


def compare(loop, dae, names, q0, v0, t_final, **kwargs):
    simulation = simulate_kinematic_loops(loop, q0, v0, t_final=t_final, **kwargs)
    state = dae.assemble(dict(zip(names, q0)), dict(zip(names, v0)))
    assert np.max(np.abs(dae.constraints(*state)[0])) < 1e-12         # the same assembled configuration
    reference = dae.simulate(state, t_final, t_eval=simulation.t)
    angle_error = max(np.max(np.abs(simulation.coordinate(f"{n}.theta") - reference.angle(n))) for n in names)
    return simulation, reference, angle_error


@pytest.mark.parametrize("law", [None, SPRING + DAMPER], ids=["smooth", "cubic spring + damper"])
def test_four_bar_matches_the_global_dae(law):
    loop = four_bar(law)
    q0, v0 = start(loop)
    simulation, reference, error = compare(loop, four_bar_dae(law), ["crank", "coupler", "rocker"], q0, v0, 0.4,
                                           dt=1e-3)
    assert error < 2e-7
    force_error = np.max(np.abs(simulation.cut_force[:, 0] - reference.forces[:, 3]))
    assert force_error < 1e-4 * np.max(np.abs(reference.forces[:, 3]))
    assert np.max(simulation.drift) < 1e-12 and np.max(simulation.drift_rate) < 1e-12     # projected
    assert np.ptp(simulation.coordinate("crank.theta")) > 0.8                          # it moves


def test_undamped_loop_conserves_energy_with_baumgarte_only():
    loop = four_bar(SPRING)
    q0, v0 = start(loop)
    simulation = simulate_kinematic_loops(loop, q0, v0, t_final=1.0, method="DOP853", rtol=1e-11, atol=1e-12)
    energy = simulation.energy()
    assert np.max(np.abs(energy - energy[0])) < 1e-7 * np.max(np.abs(energy))
    assert np.max(simulation.drift) < 1e-9


def test_drift_is_reported_and_controlled():
    q0, v0 = start(four_bar())
    free = KinematicLoopModel(four_bar().tree, four_bar().cuts, baumgarte=0.0)
    loose = simulate_kinematic_loops(free, q0, v0, t_final=1.0, dt=5e-3, projection=False)
    held = simulate_kinematic_loops(four_bar(), q0, v0, t_final=1.0, dt=5e-3, projection=False)
    projected = simulate_kinematic_loops(four_bar(), q0, v0, t_final=1.0, dt=5e-3)
    assert loose.drift[-1] > 1e-7                                    # truncation error drifts unchecked
    assert held.drift[-1] < 0.1 * loose.drift[-1]                    # Baumgarte keeps it bounded
    assert np.max(projected.drift) < 1e-12


def test_body_with_two_input_ends():
    """A triangular plate hangs from two links (seed 002 section 7.4.2.1): its inboard end on link a, its
    second input end 'b_end' cut-jointed to link b's tip."""
    plate = RigidBody("plate", mass=2.0, inertia=0.05, center_of_mass=(0.25, -0.12), inboard=(0.0, 0.0),
                      outboard={"b_end": (0.5, 0.0)})
    tree = PlanarModel("swing", [
        Fixed("ga", position=(0.0, 0.0)), Fixed("gb", position=(0.6, 0.0)),
        RigidBody.uniform_link("a", mass=0.3, length=0.8), SmoothHinge("ha", parent="ga", child="a"),
        plate, NonlinearHinge("hp", parent="a", child="plate", moment_law=CubicSpring(1.0, 5.0), rest_angle=1.2),
        RigidBody.uniform_link("b", mass=0.3, length=0.7), SmoothHinge("hb", parent="gb", child="b")],
        gravity=(0.0, -9.81))
    loop = KinematicLoopModel(tree, [CutJoint("hb_plate", parent="b.out", child="plate.b_end")])
    q0, v0 = loop.consistent_state([-1.2, 0.1, -1.6], [1.0, 0.0, 0.0], keep=["a.theta"])
    dae = PlanarDAE(gravity=(0.0, -9.81))
    dae.add_body("a", mass=0.3, inertia=0.3 * 0.64 / 12, points={"in": (-0.4, 0.0), "out": (0.4, 0.0)})
    dae.add_body("plate", mass=2.0, inertia=0.05, points={"in": (-0.25, 0.12), "b_end": (0.25, 0.12)})
    dae.add_body("b", mass=0.3, inertia=0.3 * 0.49 / 12, points={"in": (-0.35, 0.0), "out": (0.35, 0.0)})
    dae.add_revolute(None, (0.0, 0.0), "a", "in")
    dae.add_revolute("a", "out", "plate", "in", moment=lambda d, v: 1.0 * d + 5.0 * d ** 3, rest=1.2)
    dae.add_revolute(None, (0.6, 0.0), "b", "in")
    dae.add_revolute("b", "out", "plate", "b_end")
    _, _, error = compare(loop, dae, ["a", "plate", "b"], q0, v0, 0.5, dt=1e-3)
    assert error < 1e-6


def test_refusals_name_the_problem():
    tree = four_bar().tree
    with pytest.raises(ModelError, match="no end 'tip'"):
        KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.tip", child="coupler.out")])
    with pytest.raises(ModelError, match="names no body"):
        KinematicLoopModel(tree, [CutJoint("h3", parent="wheel.out", child="coupler.out")])
    with pytest.raises(ModelError, match="violates the cut joints"):
        simulate_kinematic_loops(four_bar(), [math.pi / 2, 0.5, 1.8], [0.0, 0.0, 0.0], t_final=0.1, dt=1e-3)
    with pytest.raises(ModelError, match="baumgarte"):
        KinematicLoopModel(tree, four_bar().cuts, baumgarte=-1.0)


def test_cut_names_and_sides_are_refused_at_construction_as_the_spatial_cuts():
    """Two cuts of one name kept only the second's signals (``"h3.force_x"`` the other cut's force, the first's lost)
    and a cut named like a tree hinge was refused only when the ports were built; a cut between two points of one
    rigid body (its rows constant, the compliance zero) ran into "a singular configuration of the loop".  Now each is
    refused by name when the model is built, as ``SpatialKinematicLoopModel`` and ``SpatialCutJoint`` do."""
    tree = PlanarModel("six_bar", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.4, 0.0)), Fixed("g6", position=(0.9, 0.3)),
        RigidBody.uniform_link("crank", mass=0.4, length=0.2), SmoothHinge("h1", parent="g", child="crank"),
        RigidBody.uniform_link("coupler", mass=1.0, length=0.6), SmoothHinge("h2", parent="crank", child="coupler"),
        RigidBody.uniform_link("rocker", mass=0.8, length=0.5), SmoothHinge("h4", parent="g4", child="rocker"),
        RigidBody.uniform_link("e", mass=0.3, length=0.5), SmoothHinge("h5", parent="rocker", child="e"),
        RigidBody.uniform_link("f", mass=0.3, length=0.5), SmoothHinge("h7", parent="g6", child="f")])
    first = CutJoint("h3", parent="rocker.out", child="coupler.out")
    for name in ("h3", "h1", "g6", "rocker"):
        with pytest.raises(ModelError, match=f"duplicate name '{name}' .*differ from each other and from the tree"):
            KinematicLoopModel(tree, [first, CutJoint(name, parent="f.out", child="e.out")])
    with pytest.raises(ModelError, match="'coupler.out' and child 'coupler.out' are points of the same rigid body"):
        KinematicLoopModel(tree, [CutJoint("h3", parent="coupler.out", child="coupler.out")])
    plate = PlanarModel("plate", [Fixed("g", position=(0.0, 0.0)), SmoothHinge("h", parent="g", child="p"),
                                  RigidBody("p", mass=1.0, inertia=0.1, outboard={"a": (0.3, 0.0), "b": (0.0, 0.3)})])
    with pytest.raises(ModelError, match="'p.a' and child 'p.b' are points of the same rigid body 'p'"):
        KinematicLoopModel(plate, [CutJoint("c", parent="p.a", child="p.b")])
    KinematicLoopModel(tree, [first, CutJoint("h6", parent="f.out", child="e.out")])     # distinct: accepted


def test_the_condition_guard_is_numpys_frobenius_condition_and_refuses_a_folded_linkage():
    """The guard's number (:func:`ctmm.loop_integration.compliance_condition`, computed without numpy's generic
    checks) is ``numpy.linalg.cond(G, "fro")`` to the bit, also for singular and non-finite ``G``; the four-bar folded
    flat (crank, coupler and rocker at one angle: the coupler and rocker aligned) is refused by name."""
    rng = np.random.default_rng(3)
    matrices = [rng.standard_normal((m, m)) * 10.0 ** rng.uniform(-6, 6, (m, m)) for m in (1, 2, 3, 4, 6)
                for _ in range(40)]
    matrices += [np.zeros((2, 2)), np.array([[1.0, 2.0], [2.0, 4.0]]), np.array([[np.nan, 0.0], [0.0, 1.0]]),
                 np.array([[np.inf, 1.0], [1.0, 1.0]]), np.array([[1e-320, 0.0], [0.0, 1.0]])]
    for G in matrices:
        expected = float(np.linalg.cond(G, "fro"))
        assert compliance_condition(G) == expected or (math.isnan(expected) and math.isnan(compliance_condition(G)))
    assert compliance_condition(np.zeros((2, 2))) == math.inf
    with pytest.raises(SimulationError, match="boundary compliance is singular"):
        four_bar().solve([0.3, 0.3, 0.3], [0.2, 0.2, 0.2], 0.01)



def test_linearisation_on_the_constraint_manifold_matches_the_dae():
    """Equilibrium and natural frequency of the four-bar with the rocker spring (gravity on): the equilibrium
    is one of the global DAE (its accelerations vanish there) and the frequency is the DAE's small-oscillation
    period (1e-4 rad free vibration about it, zero crossings)."""
    loop = four_bar(SPRING)
    guess, _ = loop.consistent_state([-1.5, 0.5, 1.8], [0.0, 0.0, 0.0], keep=["crank.theta"])
    q_eq = loop.equilibrium(guess)
    dae = four_bar_dae(SPRING)
    names = ["crank", "coupler", "rocker"]
    state = dae.assemble(dict(zip(names, q_eq)), dict(zip(names, [0.0, 0.0, 0.0])))
    assert np.max(np.abs(dae.solve(*state)[0])) < 1e-9
    (omega,) = loop.natural_frequencies(q_eq)
    A, basis, _ = loop.linearize(q_eq)
    q1, v1 = loop.consistent_state(q_eq + basis[:, 0] * 1e-4, np.zeros(3), keep=["crank.theta"])
    period = 2 * math.pi / omega
    t = np.linspace(0.0, 3 * period, 3001)
    x = dae.simulate(dae.assemble(dict(zip(names, q1)), dict(zip(names, v1))), 3 * period, t_eval=t).angle("crank")
    x = x - q_eq[0]
    up = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    crossings = t[up] - x[up] * (t[up + 1] - t[up]) / (x[up + 1] - x[up])
    assert np.mean(np.diff(crossings)) == pytest.approx(period, rel=1e-6)
    upright = loop.equilibrium(loop.consistent_state([1.5, 0.5, 1.8], [0.0, 0.0, 0.0], keep=["crank.theta"])[0])
    with pytest.raises(ModelError, match="not a stable equilibrium"):
        loop.natural_frequencies(upright)
    with pytest.raises(ModelError, match="not an equilibrium"):
        loop.natural_frequencies(guess)




def test_the_dae_constraint_rows_are_consistent_with_their_positions():
    """The reference DAE's ``Phi_q``, ``Phi'`` and ``gamma`` (all joints at once) against central differences of
    its own ``Phi``: ``Phi_q = dPhi/dq``, ``Phi' = Phi_q v`` and ``gamma = -d(Phi_q v)/dq . v`` (ground joints and
    a ten-body chain included; measured 3e-10 / 2e-16 / 1.4e-10 of O(1) values at step 1e-6)."""
    from ctmm.scenarios.four_bar import flexible_reference

    rng = np.random.default_rng(13)
    h = 1e-6
    for dae in (four_bar_dae(SPRING), flexible_reference(20.0, 8)):
        n = 3 * len(dae.bodies)
        q, v = rng.normal(size=n), rng.normal(size=n)
        phi, phi_dot, jac, gamma = dae.constraints(q, v)
        columns = [(dae.constraints(q + h * e, v)[0] - dae.constraints(q - h * e, v)[0]) / (2 * h) for e in np.eye(n)]
        np.testing.assert_allclose(jac, np.column_stack(columns), atol=1e-8)
        np.testing.assert_allclose(phi_dot, jac @ v, atol=1e-13)
        along = (dae.constraints(q + h * v, v)[1] - dae.constraints(q - h * v, v)[1]) / (2 * h)
        np.testing.assert_allclose(gamma, -along, atol=1e-7 * max(1.0, np.max(np.abs(gamma))))
        assert np.max(np.abs(phi)) > 0.1 and np.max(np.abs(gamma)) > 0.1          # off the manifold, moving


def test_the_dae_constraint_rows_follow_joints_added_after_an_evaluation():
    """The joints' index layout is built once per set of joints: a joint added after a first evaluation (closing
    an open chain into a loop) adds its two rows, ``Phi`` of the new joint being ``P_a - P_b`` by hand."""
    dae = PlanarDAE()
    for name in ("a", "b"):
        dae.add_body(name, mass=1.0, inertia=0.1, points={"in": (-0.5, 0.0), "out": (0.5, 0.0)})
    dae.add_revolute(None, (0.0, 0.0), "a", "in")
    dae.add_revolute("a", "out", "b", "in")
    q, v = np.array([0.5, 0.1, 0.3, 1.2, 0.4, -0.2]), np.zeros(6)
    assert dae.constraints(q, v)[2].shape == (4, 6)
    dae.add_revolute(None, (1.5, 0.0), "b", "out")
    phi, _, jac, _ = dae.constraints(q, v)
    tip = q[3:5] + 0.5 * np.array([math.cos(q[5]), math.sin(q[5])])
    assert jac.shape == (6, 6) and np.allclose(phi[4:], np.array([1.5, 0.0]) - tip, rtol=0.0, atol=1e-15)


@pytest.mark.parametrize("flexible", [False, True], ids=["rigid", "modal_coupler"])
def test_one_evaluation_of_the_terms_for_several_inputs_equals_separate_sweeps(flexible):
    """``solve_instant_inputs`` (the tree's body terms and hinge laws once, one sweep per inputs: the cut-load
    responses of :meth:`KinematicLoopModel.solve_loads`) returns, for each inputs, exactly what
    ``solve_instant`` returns on its own -- on a rigid tree and on one with a modal beam (cut forces on its frame
    and modal coordinates)."""
    from ctmm.planar.sweep import solve_instant, solve_instant_inputs
    from ctmm.scenarios.four_bar import flexible_mechanism, flexible_start

    loop = flexible_mechanism(80.0, n_modes=3) if flexible else four_bar(SPRING + DAMPER)
    q0, v0 = flexible_start(loop) if flexible else start(loop)
    q, v = np.array(q0) + 0.01, np.array(v0) - 0.2                  # off the start, coordinates and rates
    inputs = [None, loop.cut_inputs(q, v, 0.1), loop.torque_inputs("h3") if not flexible else
              loop.cut_inputs(q, v, 0.1, loop.cut_inputs(q0, v0, 0.0))]
    together = solve_instant_inputs(loop.tree, q, v, 0.1, inputs)
    assert len(together) == 3
    for one, each in zip(together, inputs):
        alone = solve_instant(loop.tree, q, v, 0.1, each)
        for field in ("qddot", "body_acceleration", "joint_force", "hinge_acceleration"):
            assert np.array_equal(getattr(one, field), getattr(alone, field)), field
        assert one.modal_acceleration.keys() == alone.modal_acceleration.keys()
        assert all(np.array_equal(one.modal_acceleration[k], alone.modal_acceleration[k])
                   for k in one.modal_acceleration)
    assert not np.array_equal(together[0].qddot, together[1].qddot)     # the inputs act


def test_consistent_state_holds_one_coordinate_given_by_name_as_the_spatial_model():
    """``keep="crank.theta"`` was read character by character ("unknown coordinate 'c'") where the spatial model
    takes one name; now the crank is held: its angle and rate as given, the cut joints closed."""
    loop = four_bar()
    q, v = loop.consistent_state([1.4, 0.5, 1.8], [2.0, 0.0, 0.0], keep="crank.theta")
    assert (q[0], v[0]) == (1.4, 2.0)
    phi, rate = loop.constraints(q, v)
    assert np.max(np.abs(phi)) < 1e-12 and np.max(np.abs(rate)) < 1e-12
