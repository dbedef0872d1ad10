"""Generated kinematic loops with cut points on deformable bodies (ctmm.compiled_cut_points, issue 13 item 1).

Consistency: the generated step traces the numpy path's own cut-point statements (ctmm.planar.cut_points on casadi
scalars), so the generated RK4 with projection equals the numpy one to round-off over a short run: a ModalBeam's
end (with the foreshortening, with second-order inertia), a ModalBeam's interior station and a ctmm.fem subsystem
node (smooth and with a rotary law across the cut).  Independent references at the numpy path's bounds: the
global Lagrange model of ``ctmm.reference.fem_loop_global`` (no shared code) for the finite-element coupler
(tests/test_fem_cut_joints.py: 2e-7 at 0.25 ms), and energy conservation of the undamped flexible four-bar (the cut
force does no work; tests/test_closed_loops_foreshortening.py).  With feedback loops and inputs: the loop-closing
driver's generated run = its numpy run; a cut body hanging from a foreshortening beam too.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.compiled_cut_points import TracedScalar
from ctmm.compiled_kinematic_loops import CompiledKinematicLoops, simulate_kinematic_loops_generated
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel, simulate_kinematic_loops
from ctmm.scenarios.four_bar import flexible_mechanism, flexible_start
from test_fem_cut_joints import fe_four_bar, reference as fe_reference, start as fe_start


ROUND_OFF_MULTIPLE = 8.0     # the runs' force differences beyond the propagated state difference: at most 1.2 (the
#                              flexible four-bar) and 2.8 (the propped beam) times the round-off of the numpy force


def cut_force_allowance(model: KinematicLoopModel, t: np.ndarray, q: np.ndarray, qdot: np.ndarray,
                        q_difference: np.ndarray, qdot_difference: np.ndarray) -> np.ndarray:
    """The largest difference [N] (rows, 2 n_cuts) of two correct round-off evaluations of the cut forces at the
    stored states ``(t, q, qdot)`` of the numpy run when the other run's states differ by ``q_difference``,
    ``qdot_difference`` (rows, n_coordinates): the state difference carried by the numpy path's force sensitivity
    ``|d lambda / d(q, qdot)|`` (forward differences of :meth:`KinematicLoopModel.solve`, step 1e-6 of
    ``max(1, |x|)``) plus ``ROUND_OFF_MULTIPLE`` times the force's round-off, measured as its largest change under a
    1-ulp change of one coordinate or rate (the cut force is the small balance of large inertial and elastic terms,
    solved through the boundary compliance: its round-off is eps times those terms times the compliance's
    condition, which a 1-ulp change of the state exposes)."""
    allowance = []
    for t_k, q_k, v_k, dq_k, dv_k in zip(t, q, qdot, q_difference, qdot_difference):
        x, n = np.concatenate([q_k, v_k]), len(q_k)

        def force(state: np.ndarray) -> np.ndarray:
            return model.solve(state[:n], state[n:], t_k)[1].reshape(-1)

        base, sensitivity, round_off = force(x), [], 0.0
        for i in range(2 * n):
            step, ulp = x.copy(), x.copy()
            step[i] += 1e-6 * max(1.0, abs(x[i]))
            ulp[i] = np.nextafter(x[i], np.inf)
            sensitivity.append((force(step) - base) / (step[i] - x[i]))
            round_off = np.maximum(round_off, np.abs(force(ulp) - base))
        difference = np.abs(np.concatenate([dq_k, dv_k]))
        allowance.append(np.abs(np.array(sensitivity).T) @ difference + ROUND_OFF_MULTIPLE * round_off)
    return np.array(allowance)


def _agree(generated, numpy_run, rate_bound: float, cut_bound: float | None = None) -> None:
    """Generated = numpy: coordinates to 1e-12 [m, rad], rates to ``rate_bound`` relative, cut forces within
    :func:`cut_force_allowance` (``cut_bound`` relative instead if given)."""
    np.testing.assert_array_equal(generated.t, numpy_run.t)
    assert generated.method == "rk4-generated"
    assert np.max(np.abs(generated.q - numpy_run.q)) <= 1e-12
    assert np.max(np.abs(generated.qdot - numpy_run.qdot)) <= rate_bound * np.max(np.abs(numpy_run.qdot))
    difference = np.abs(generated.cut_force - numpy_run.cut_force).reshape(len(numpy_run.t), -1)
    if cut_bound is None:
        allowance = cut_force_allowance(numpy_run.model, numpy_run.t, numpy_run.q, numpy_run.qdot,
                                        generated.q - numpy_run.q, generated.qdot - numpy_run.qdot)
        assert np.all(difference <= allowance), f"cut forces {np.max(difference / allowance):.3g} times the allowance"
    else:
        assert np.max(difference) <= cut_bound * np.max(np.abs(numpy_run.cut_force))
    assert np.max(generated.drift) < 1e-12


@pytest.mark.parametrize("second_order_inertia", [False, True])
def test_modal_beam_end_equals_the_numpy_rk4(second_order_inertia):
    loop = flexible_mechanism(80.0, n_modes=2, second_order_inertia=second_order_inertia)
    q0, v0 = flexible_start(loop)
    # 20 steps exercise the path (the coupler's first mode swings by 7.6e-4 in them): the allowance's
    # sensitivities cost 21 solves per stored row
    generated = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.02, dt=1e-3)
    numpy_run = simulate_kinematic_loops(loop, q0, v0, t_final=0.02, dt=1e-3)
    _agree(generated, numpy_run, 1e-12)     # the cut force: 1.1e-12 of its peak apart, within cut_force_allowance
    assert np.ptp(generated.coordinate("coupler.q1")) > 1e-4                  # it bends


def _station_loop(stations: dict | None = None) -> tuple[KinematicLoopModel, np.ndarray, np.ndarray]:
    """A propped beam: a ModalBeam on a ground pivot whose interior station ``"mid"`` (0.3 m of 0.6 m) is held by a
    rocker on another ground pivot, a rotary spring across the cut (a triangle: only the bending moves it), released
    straight under gravity (``stations``: the beam's named stations, their force and moment ports)."""
    from ctmm.nonlinear_laws import LinearLaw

    beam = ModalBeam("beam", length=0.6, bending_stiffness=30.0, mass_per_length=1.5, n_modes=2,
                     outboard={"mid": 0.3, "tip": 0.6}, stations=stations)
    tree = PlanarModel("station_loop", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.55, -0.3)),
        beam, SmoothHinge("h1", parent="g", child="beam"),
        RigidBody.uniform_link("rocker", mass=0.5, length=0.4), SmoothHinge("h4", parent="g4", child="rocker")],
        gravity=(0.0, -9.81))
    loop = KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="beam.mid",
                                              moment_law=LinearLaw(2.0, 0.1), rest_angle=-2.0)])
    names = tree.coordinates
    q = [0.0 if n == "beam.theta" else 2.2 if n == "rocker.theta" else 0.0 for n in names]
    q0, v0 = loop.consistent_state(q, np.zeros(len(names)), keep=["beam.q1", "beam.q2"])
    return loop, q0, v0


def test_modal_beam_interior_station_with_a_cut_law_equals_the_numpy_rk4():
    loop, q0, v0 = _station_loop()       # 0.02 s: measured ptp beam.q1 7.5e-4, beam.theta 1.6e-3
    generated = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.02, dt=1e-3)
    numpy_run = simulate_kinematic_loops(loop, q0, v0, t_final=0.02, dt=1e-3)
    _agree(generated, numpy_run, 1e-12)
    assert np.ptp(generated.coordinate("beam.q1")) > 5e-4 and np.ptp(generated.coordinate("beam.theta")) > 1e-3


def test_station_loads_beside_a_cut_on_the_same_beam_equal_the_numpy_rk4():
    """A station force and moment on the propped beam (their frame wrench added to the cut's on the same floating
    frame, ctmm.compiled_station_loads): the generated run = the numpy run (was refused: 'not on the element
    protocol yet')."""
    loop, q0, v0 = _station_loop({"s": 0.45})
    inputs = {"beam.s.force": 0.5, "beam.s.moment": 0.1}
    generated = ctmm.simulate(loop, 0.03, 1e-3, x0=q0, v0=v0, compiled=True, inputs=inputs)
    numpy_run = ctmm.simulate(loop, 0.03, 1e-3, x0=q0, v0=v0, inputs=inputs)
    unloaded = ctmm.simulate(loop, 0.03, 1e-3, x0=q0, v0=v0)
    assert generated.info["compiled"] is True
    for name in (*loop.tree.coordinates, "h3.force_y"):
        scale = max(1.0, float(np.max(np.abs(numpy_run[name]))))
        assert np.max(np.abs(generated[name] - numpy_run[name])) <= 1e-12 * scale, name
    assert np.max(np.abs(unloaded["beam.q1"] - numpy_run["beam.q1"])) > 1e-5          # the station loads matter


@pytest.fixture(scope="module")
def fe_loop():
    loop = fe_four_bar(2)
    return loop, CompiledKinematicLoops(loop)


def test_fem_node_equals_the_numpy_rk4(fe_loop):
    """The coupler's axial mode (accelerations ~1e4 m/s^2 against rates of 3 m/s) scales the round-off of the two
    orders of operation: rates and forces agree to 1e-10 relative (measured 3e-11), coordinates to 1e-12 (5e-13).  The
    forces keep a constant bound: at the numpy run's own states the generated force is offset from the numpy one by
    up to 3.2e-10 N (the accelerations without cut forces 1.6e-11 of their size apart, the compliance G 2e-12), the
    same offset after a 1-ulp change of any coordinate or rate, 1.3e3 times the force's change under it and 270 times
    its change under a 1-ulp change of EI, EA, rho A or the length: not the round-off that cut_force_allowance
    measures (2 to 9 times it for the modal beams).  It has the size of the round-off of the subsystem's
    condensation by its internal mass matrix M (cond 6.6e3): at most 0.57 of eps cond(M) |G^-1| |J| |qddot_0| at
    every stored state (qddot_0 the tree's accelerations without cut forces); a derived bound needs G and qddot_0,
    which the numpy model does not make public."""
    loop, kernel = fe_loop
    q0, v0 = fe_start(loop, 1e-3)
    generated = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.01, dt=5e-4, compiled=kernel)
    numpy_run = simulate_kinematic_loops(loop, q0, v0, t_final=0.01, dt=5e-4)
    _agree(generated, numpy_run, 1e-10, cut_bound=1e-10)
    assert np.ptp(generated.q[:, 2:-1], axis=0).max() > 1e-3                # the nodes move


def test_fem_node_matches_the_global_lagrange_model(fe_loop):
    """At the numpy path's bound (tests/test_fem_cut_joints.py: 2e-7 at 0.25 ms over 10 ms, straight start)."""
    loop, kernel = fe_loop
    q0, v0 = fe_start(loop)
    run = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.01, dt=2.5e-4, compiled=kernel)
    q_ref, _ = fe_reference(2, baumgarte=20.0).simulate(q0, v0, run.t)
    assert np.max(np.abs(run.q - q_ref)) < 2e-7
    assert np.ptp(run.coordinate("coupler.n2_rz")) > 5e-3                     # it bends


def test_fem_node_with_a_cut_law_equals_the_numpy_rk4():
    loop = fe_four_bar(2, law=(3.0, 0.2, 0.1))
    q0, v0 = fe_start(loop, 1e-3)
    generated = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.01, dt=5e-4)
    numpy_run = simulate_kinematic_loops(loop, q0, v0, t_final=0.01, dt=5e-4)
    _agree(generated, numpy_run, 1e-10, cut_bound=1e-10)


def test_the_cut_force_does_no_work_in_the_generated_run():
    """Undamped flexible four-bar (EI = 20 N m^2, no geometric stiffening: the tree's energy is exact), as the numpy
    path's check (tests/test_closed_loops_foreshortening.py)."""
    flexible = flexible_mechanism(20.0, geometric_stiffening=False)
    q0, v0 = flexible_start(flexible)
    run = simulate_kinematic_loops_generated(flexible, q0, v0, t_final=0.05, dt=2.5e-4, store_every=20)
    energy = run.energy()
    assert np.ptp(run.coordinate("coupler.q1")) > 1e-3
    assert np.max(np.abs(energy - energy[0])) < 1e-8 * np.max(np.abs(energy))


def test_simulate_verb_compiles_a_flexible_coupler():
    loop = flexible_mechanism(80.0, n_modes=2)
    q0, v0 = flexible_start(loop)
    generated = ctmm.simulate(loop, 0.02, 1e-3, x0=q0, v0=v0, compiled=True)    # the kernel of the end test
    plain = ctmm.simulate(loop, 0.02, 1e-3, x0=q0, v0=v0)
    assert generated.info["compiled"] is True and generated.info["method"] == "rk4-generated"
    for name in ("crank.theta", "coupler.q1"):
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-12 * max(1.0, np.max(np.abs(plain[name]))), name
    names = loop.tree.coordinates
    q, v = (np.column_stack([plain[n + tail] for n in names]) for tail in ("", "_dot"))
    dq, dv = (np.column_stack([generated[n + tail] - plain[n + tail] for n in names]) for tail in ("", "_dot"))
    difference = np.abs(np.column_stack([generated[n] - plain[n] for n in ("h3.force_x", "h3.force_y")]))
    assert np.all(difference <= cut_force_allowance(loop, plain.time, q, v, dq, dv))


def test_delayed_pd_loop_on_the_flexible_cut_equals_the_numpy_driver():
    """A PD loop on the relative angle across the cut at the beam's end (the end's cross-section angle: frame angle
    plus the end slope) driving the cut torque (a moment pair on the rocker and on the beam's frame and modes), and
    an open-loop crank torque: every stored signal of the generated run = the numpy loop driver's to 1e-12."""
    from ctmm.signals import Harmonic
    from test_compiled_kinematic_loop_control import _equal, _numpy

    loop = flexible_mechanism(80.0, n_modes=2)
    q0, v0 = flexible_start(loop)
    target = float(loop.relative_angles(q0, v0)[0][0]) + 0.2
    pd = Feedback("pd", sensor=[("h3.angle", 6.0), ("h3.rate", 0.6)], actuator="h3.torque", gain=1.0, delay=0.002)
    options = dict(references={"pd": 6.0 * target}, outputs=["h3.angle", "coupler.out.y"],
                   inputs={"h1.torque": Harmonic(0.3, 15.0)})
    system = with_feedback(loop, [pd])
    generated = ctmm.simulate(system, 0.03, 1e-3, x0=q0, v0=v0, compiled=True, **options)
    _equal(generated, _numpy(system, 0.03, 1e-3, x0=q0, v0=v0, **options))
    assert np.ptp(generated["pd.u"]) > 0.1 and np.ptp(generated["coupler.q1"]) > 1e-4


def test_the_traced_scalar_refuses_a_value():
    import casadi as ca

    traced = TracedScalar(ca.SX.sym("x"))
    with pytest.raises(TypeError, match="no float value"):
        float(traced)
    with pytest.raises(TypeError, match="no truth value"):
        bool(traced)
    assert str((np.cos(traced) * 2.0 - 1.0).value) == "((2.*cos(x))-1)"


def test_cut_bodies_hanging_from_a_foreshortening_beam_equal_the_numpy_rk4():
    """A rigid cut body on the tip of a ModalBeam with second-order inertia: the numpy tree moves the tip with the
    beam's foreshortening, and so do the generated kinematics (ctmm.symbolic_beam_points; 3e-6 rad apart and refused
    before them)."""
    beam = ModalBeam("b", length=0.5, bending_stiffness=20.0, mass_per_length=1.0, n_modes=2,
                     second_order_inertia=True)
    tree = PlanarModel("on_beam", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.8, -0.3)),
        beam, SmoothHinge("h1", parent="g", child="b"),
        RigidBody.uniform_link("r", mass=0.5, length=0.4), SmoothHinge("h2", parent="b", child="r"),
        RigidBody.uniform_link("k", mass=0.5, length=0.4), SmoothHinge("h4", parent="g4", child="k")],
        gravity=(0.0, -9.81))
    loop = KinematicLoopModel(tree, [CutJoint("h3", parent="k.out", child="r.out")])
    names = tree.coordinates
    guess = {"b.theta": 0.3, "r.theta": -0.9, "k.theta": 2.0, "b.q1": 0.02, "b.q2": -0.005}
    q0, v0 = loop.consistent_state([guess.get(n, 0.0) for n in names], [3.0 if n == "b.theta" else 0.0 for n in names],
                                   keep=["b.theta", "b.q1", "b.q2"])
    generated = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.02, dt=1e-3)
    numpy_run = simulate_kinematic_loops(loop, q0, v0, t_final=0.02, dt=1e-3)
    _agree(generated, numpy_run, 1e-12)
    assert np.ptp(generated.coordinate("b.q1")) > 1e-3                        # measured 0.056


def test_cut_bodies_hanging_from_a_fem_subsystem_equal_the_numpy_rk4():
    """A rigid cut body hinged at a ctmm.fem subsystem's far node: its inboard end moves with the node in the numpy
    tree and in the generated kinematics (ctmm.symbolic_beam_points; refused before them)."""
    from ctmm.fem import BeamElement, FiniteElementModel

    fe = FiniteElementModel("arm", {f"n{k}": (0.25 * k, 0.0) for k in range(3)},
                            [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", 20.0, 2e3, 1.0) for k in range(2)])
    tree = PlanarModel("on_fem", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.8, -0.3)),
        fe.subsystem("b", boundary=("n0", "n2")), SmoothHinge("h1", parent="g", child="b"),
        RigidBody.uniform_link("r", mass=0.5, length=0.4), SmoothHinge("h2", parent="b.n2", child="r"),
        RigidBody.uniform_link("k", mass=0.5, length=0.4), SmoothHinge("h4", parent="g4", child="k")],
        gravity=(0.0, -9.81))
    loop = KinematicLoopModel(tree, [CutJoint("h3", parent="k.out", child="r.out")])
    names = tree.coordinates
    nodal = [n for n in names if n.startswith("b.n")]
    guess = {"b.theta": 0.3, "r.theta": -0.9, "k.theta": 2.0}
    q0, v0 = loop.consistent_state([guess.get(n, 0.0) for n in names], [3.0 if n == "b.theta" else 0.0 for n in names],
                                   keep=["b.theta", *nodal])
    generated = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.01, dt=5e-4)
    numpy_run = simulate_kinematic_loops(loop, q0, v0, t_final=0.01, dt=5e-4)
    _agree(generated, numpy_run, 1e-10, cut_bound=1e-10)
    assert np.ptp(generated.q[:, [names.index(n) for n in nodal]], axis=0).max() > 1e-3       # the nodes move
