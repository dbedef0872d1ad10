"""Spatial kinematic loops (ctmm.spatial.closed_loops): cut joints with the cut loads as boundary unknowns,
checked against an independent Newton-Euler DAE in absolute coordinates (ctmm.reference.spatial_loop_dae) and
closed-form pendulum frequencies (docs/closed_loops.md section 6)."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError, SimulationError
from ctmm.spatial import closed_loop_linear as linear
from ctmm.spatial.closed_loop_time import simulate_spatial_loops
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel
from ctmm.scenarios.spatial_four_bar import DOWN
from spatial_loop_helpers import dae_of, hinged_pendulum, hooke_pendulum, poses, rod, rusr, triangle, triangle_guess


def _dae_errors(loop, run, baumgarte: float = 10.0):
    """Largest differences of the bodies' rotation matrices [rad] and centre-of-mass positions [m] against the DAE
    started from the same state, and the DAE's multipliers at the last time."""
    dae = dae_of(loop, baumgarte)
    y0 = dae.state(*poses(loop, run.q[0], run.v[0]))
    t, Y = dae.simulate(y0, run.t)
    angle = position = 0.0
    for k in range(len(t)):
        x, R, _, _ = poses(loop, run.q[k], run.v[k])
        angle = max(angle, max(np.abs(a - b).max() for a, b in zip(R, dae.rotations(Y[k]))))
        position = max(position, max(np.abs(a - b).max() for a, b in zip(x, dae.split(Y[k])[0])))
    return angle, position, dae.accelerations(Y[-1])[1]


@pytest.fixture(scope="module")
def four_bar():
    loop = rusr()
    q, v = loop.consistent_state({"h1.angle": 0.1, "h4.angle": 0.1}, {"h1.angle_rate": 3.0}, keep=["h1"])
    return loop, q, v


@pytest.fixture(scope="module")
def four_bar_equilibrium(four_bar):
    loop, q, _ = four_bar
    return linear.equilibrium(loop, q)


def test_consistent_state_holds_the_kept_motion_and_closes_the_cut(four_bar):
    loop, q, v = four_bar
    phi, rate = loop.constraints(q, v)
    assert np.max(np.abs(phi)) < 1e-12 and np.max(np.abs(rate)) < 1e-12
    assert q[0] == 0.1 and v[0] == 3.0
    assert loop.jacobian(q).shape == (3, 4) and np.linalg.matrix_rank(loop.jacobian(q)) == 3
    # the DAE's own rows vanish on the mapped state: the tree kinematics and the cut rows agree independently
    dae = dae_of(loop)
    y0 = dae.state(*poses(loop, q, v))
    phi_dae, J_dae, _ = dae.rows(y0)
    assert np.max(np.abs(phi_dae)) < 1e-12 and np.max(np.abs(J_dae @ dae.velocities(y0))) < 1e-12


def test_rusr_four_bar_rk4_matches_the_dae(four_bar):
    loop, q, v = four_bar
    run = simulate_spatial_loops(loop, q, v, t_final=0.06, dt=2e-3)
    angle, position, mu = _dae_errors(loop, run)
    assert angle < 1e-9 and position < 1e-9                      # measured 5e-11, 1e-11
    assert np.max(np.abs(mu[-3:] - run.cut_force[-1, 0])) < 1e-7 * np.max(np.abs(mu[-3:]))
    assert run.drift.max() < 1e-14 and run.drift_rate.max() < 1e-14       # projection after every step
    assert run.cut_force.shape == (len(run.t), 1, 3) and not np.any(run.cut_moment)


def test_rusr_four_bar_rk4_converges_at_fourth_order(four_bar):
    loop, q, v = four_bar
    errors = [_dae_errors(loop, simulate_spatial_loops(loop, q, v, t_final=0.064, dt=dt))[0] for dt in (8e-3, 4e-3)]
    assert 10.0 < errors[0] / errors[1] < 24.0                   # 2^4 = 16


def test_solve_ivp_with_baumgarte_matches_the_dae(four_bar):
    loop, q, v = four_bar
    run = simulate_spatial_loops(loop, q, v, t_final=0.1, dt=0.02, method="DOP853", rtol=1e-11, atol=1e-12)
    angle, position, _ = _dae_errors(loop, run)
    assert angle < 1e-9 and position < 1e-9 and run.drift.max() < 1e-10


def test_newmark_runs_the_tree_with_the_cut_loads_as_inputs_at_second_order(four_bar):
    """A DT-TMM scheme: the tree's implicit stepper with the cut loads re-solved at every iterate (input_map), projected
    onto the cut after every step, against the DAE (measured 6.6e-6 / 1.7e-6 rad at 4 / 2 ms over 0.016 s, ratio 4.00
    (over 0.032 s: 1.34e-5 / 3.36e-6), drift 7e-15 m; Baumgarte alone: tests/test_loop_scheme_projection.py)."""
    loop, q, v = four_bar
    errors, drifts = [], []
    for dt in (4e-3, 2e-3):
        result = ctmm.simulate(loop, 0.016, dt, x0=q, v0=v, method="newmark")
        qs = np.array([result[name] for name in loop.tree.coordinates]).T
        vs = np.array([result[name] for name in loop.tree.velocities]).T
        dae = dae_of(loop)
        _, Y = dae.simulate(dae.state(*poses(loop, q, v)), result.time)
        errors.append(max(max(np.abs(a - b).max() for a, b in zip(poses(loop, qs[k], vs[k])[1], dae.rotations(Y[k])))
                          for k in range(len(result.time))))
        drifts.append(result["drift"].max())
        assert result["drift"][-1] == np.max(np.abs(loop.constraints(qs[-1], vs[-1])[0]))
    assert 3.0 < errors[0] / errors[1] < 5.0 and errors[1] < 2e-5            # order 2
    assert max(drifts) < 1e-12                                                 # projected after every step


def test_driven_crank_moves_the_loop_through_its_assembled_configurations():
    """The four-bar with the crank driven at 3 rad/s (no degree of freedom left): every stored configuration is the
    loop assembled at the crank's prescribed angle (a position solve, no dynamics), and the rates satisfy the cut
    with the driven rate included."""
    bodies = {b.name: b for b in rusr().tree.bodies}
    tree = sp.SpatialModel("driven", [
        bodies["crank"], sp.Revolute(name="h1", parent=None, child="crank", axis=(1, 0, 0), rotation=DOWN,
                                     position=lambda t: 0.1 + 3.0 * t, rate=lambda t: 3.0, acceleration=lambda t: 0.0),
        bodies["coupler"], sp.Universal(name="u2", parent="crank", point="tip", child="coupler", axis1=(0, 0, 1),
                                        axis2=(0, 1, 0)),
        bodies["rocker"], sp.Revolute(name="h4", parent=None, point=(0.5, 0.2, 0.0), child="rocker", axis=(0, 1, 0),
                                      rotation=DOWN)])
    loop = SpatialKinematicLoopModel(tree, rusr().cuts)
    q, v = loop.consistent_state({"h4.angle": -0.05, "u2.angle1": -0.32, "u2.angle2": -0.41}, None)
    assert np.max(np.abs(loop.constraints(q, v)[1])) < 1e-12           # J v = -(the driven rate's term)
    run = simulate_spatial_loops(loop, q, v, t_final=0.05, dt=1e-3)
    assert run.drift.max() < 1e-13 and run.drift_rate.max() < 1e-12
    for k in (25, 50):
        reference = SpatialKinematicLoopModel(rusr().tree, rusr().cuts)
        q_ref, _ = reference.consistent_state({"h1.angle": 0.1 + 3.0 * run.t[k], **dict(zip(
            ("h4.angle", "u2.angle1", "u2.angle2"), run.q[k]))}, None, keep=["h1"])
        assert np.max(np.abs(q_ref[1:] - run.q[k])) < 1e-10
    with pytest.raises(ModelError, match="driven joints"):
        linear.natural_frequencies(loop, q)


def test_drift_is_reported_and_controlled(four_bar):
    loop, q, v = four_bar
    free = SpatialKinematicLoopModel(loop.tree, loop.cuts, baumgarte=0.0)
    loose = simulate_spatial_loops(free, q, v, t_final=0.1, dt=5e-3, projection=False)
    held = simulate_spatial_loops(free, q, v, t_final=0.1, dt=5e-3)
    assert loose.drift[-1] > 1e-10 and held.drift.max() < 1e-14       # measured 3e-9 without projection
    phi, _ = free.constraints(loose.q[-1], loose.v[-1])
    assert loose.drift[-1] == np.max(np.abs(phi))


def test_rusr_natural_frequency_matches_the_dae_on_its_manifold(four_bar, four_bar_equilibrium):
    loop, _, _ = four_bar
    omega = linear.natural_frequencies(loop, four_bar_equilibrium)
    dae = dae_of(loop)
    y = dae.state(*poses(loop, four_bar_equilibrium, np.zeros(4)))
    assert np.max(np.abs(dae.accelerations(y)[0])) < 1e-8         # an equilibrium of the DAE too
    reference = dae.natural_frequencies(y)
    assert omega.shape == (1,) and abs(omega[0] / reference[0] - 1.0) < 1e-10    # measured 1.4e-11 (8.442 rad/s)


def test_revolute_cut_pendulum_frequency_and_motion():
    loop = hinged_pendulum()
    half = 0.25
    q, v = loop.consistent_state({"free.qw": np.cos(half), "free.qy": np.sin(half), "free.x": 0.01},
                                 {"free.wy": 2.0}, keep=["free.wy"])
    run = simulate_spatial_loops(loop, q, v, t_final=0.06, dt=2e-3)
    angle, position, mu = _dae_errors(loop, run)
    assert angle < 1e-9 and position < 1e-9
    assert np.max(np.abs(mu[:3] - run.cut_force[-1, 0])) < 1e-7 * np.max(np.abs(mu[:3]))
    equilibrium = linear.equilibrium(loop, q)
    mass, arm = 1.2, np.hypot(0.1, 0.3)
    exact = np.sqrt(mass * 9.81 * arm / (0.03 + mass * arm ** 2))        # compound pendulum about the hinge
    assert abs(linear.natural_frequencies(loop, equilibrium)[0] / exact - 1.0) < 1e-11  # measured 1.0e-12


def test_revolute_cut_moment_is_perpendicular_to_the_hinge():
    loop = hinged_pendulum()
    q, v = loop.consistent_state({"free.qw": np.cos(0.3), "free.qy": np.sin(0.3)}, {"free.wy": 1.0, "free.wx": 0.4},
                                 keep=["free.wy"])
    _, lam = loop.solve(q, v)
    (force, moment), = loop.cut_loads(q, lam)
    assert lam.shape == (5,) and abs(moment[1]) < 1e-12 * max(1.0, np.abs(moment).max())


def test_universal_cut_pendulum_matches_the_dae_and_the_closed_form_frequencies():
    """A universal (Hooke) cut, 4 rows: the motion and the cut loads (force and the moment multiplier along
    ``u x b``) against the DAE with its own universal rows; about the hanging equilibrium the two compound-pendulum
    frequencies ``m g L / (I_xx + m L^2)`` and ``m g L / (I_yy + m L^2)`` (the cross axes are the principal axes
    there), and the spin about the vertical held."""
    loop = hooke_pendulum()
    q, v = loop.consistent_state({"free.qw": np.cos(0.15), "free.qx": np.sin(0.15), "free.x": 0.01},
                                 {"free.wx": 1.5, "free.wy": -2.0, "free.wz": 0.7})
    assert loop.jacobian(q).shape == (4, 6) and np.linalg.matrix_rank(loop.jacobian(q)) == 4
    run = simulate_spatial_loops(loop, q, v, t_final=0.06, dt=2e-3)
    angle, position, mu = _dae_errors(loop, run)
    assert angle < 1e-9 and position < 1e-9 and run.drift.max() < 1e-14
    _, lam = loop.solve(run.q[-1], run.v[-1], run.t[-1])
    assert lam.shape == (4,) and np.max(np.abs(mu - lam)) < 1e-7 * np.max(np.abs(mu))
    assert np.any(run.cut_moment[-1, 0])
    assert ctmm.simulate(loop, 0.004, 2e-3, x0=q, v0=v)["hooke.moment_x"].shape == (3,)
    equilibrium = linear.equilibrium(loop, q)
    mass, arm = 1.2, 0.3
    exact = np.sqrt(mass * 9.81 * arm / (np.array([0.02, 0.03]) + mass * arm ** 2))
    assert np.max(np.abs(linear.natural_frequencies(loop, equilibrium) / np.sort(exact) - 1.0)) < 1e-11  # 7e-16
    with pytest.raises(ModelError, match="parent_axis"):
        SpatialCutJoint(name="u", parent=None, child="p", kind="universal", axis=(0, 1, 0))


def test_closed_triangle_of_bodies_matches_the_dae():
    loop = triangle()
    q, v = loop.consistent_state(triangle_guess(), {"ja.wx": 1.0, "jb.wz": 0.5, "jc.wy": -0.3})
    run = simulate_spatial_loops(loop, q, v, t_final=0.06, dt=2e-3)
    angle, position, mu = _dae_errors(loop, run)
    assert angle < 1e-9 and position < 1e-9 and run.drift.max() < 1e-14
    assert np.max(np.abs(mu[-3:] - run.cut_force[-1, 0])) < 1e-7 * np.max(np.abs(mu[-3:]))


def test_simulate_verb_returns_named_signals(four_bar):
    loop, q, v = four_bar
    result = ctmm.simulate(loop, 0.02, 2e-3, x0=q, v0=v)
    assert result["s3.force_z"].shape == (11,) and result["drift"].max() < 1e-14
    assert result.info["max_drift"] < 1e-14 and "h1.angle" in result.extra
    assert abs(result["h1.angle"][-1] - simulate_spatial_loops(loop, q, v, t_final=0.02, dt=2e-3).q[-1, 0]) < 1e-14
    with pytest.raises(ModelError, match="odd"):
        ctmm.simulate(loop, 0.02, 2e-3, x0=q, v0=v, method="odd")
    with pytest.raises(ModelError, match="compiled"):           # compiled=True: RK4 only (tests/test_compiled_kinematic_loops.py)
        ctmm.simulate(loop, 0.02, 2e-3, x0=q, v0=v, method="DOP853", compiled=True)
    with pytest.raises(ModelError, match="violates the cut joints"):
        ctmm.simulate(loop, 0.02, 2e-3, x0=loop.tree.neutral(), v0=v)


def test_simulate_with_a_joint_torque_matches_the_dae(four_bar):
    """``inputs`` of ctmm.simulate act on the tree before the cut force is solved: a constant crank torque (about
    world x, the hinge axis), against the DAE with the torque on the crank."""
    loop, q, v = four_bar
    result = ctmm.simulate(loop, 0.04, 2e-3, x0=q, v0=v, inputs={"h1.torque": 0.3})
    qs = np.array([result[name] for name in loop.tree.coordinates]).T
    vs = np.array([result[name] for name in loop.tree.velocities]).T
    dae = dae_of(loop)
    _, Y = dae.simulate(dae.state(*poses(loop, q, v)), result.time, torques={0: np.array([0.3, 0.0, 0.0])})
    _, R, _, _ = poses(loop, qs[-1], vs[-1])
    assert max(np.abs(a - b).max() for a, b in zip(R, dae.rotations(Y[-1]))) < 1e-9
    free = ctmm.simulate(loop, 0.04, 2e-3, x0=q, v0=v)
    assert abs(free["h1.angle"][-1] - result["h1.angle"][-1]) > 1e-5            # the torque moved the crank


def test_feedback_loop_on_the_crank_matches_the_dae_with_the_law_as_a_motor(four_bar):
    """``with_feedback(loop_model, [PD])``: the loop-closing driver on the closed-loop accelerations (cut force solved
    with the loop torque applied), against the DAE with ``u = -(8 theta + 0.8 theta' - 1.6)`` on the crank."""
    from ctmm.control import Feedback, with_feedback

    loop, q, v = four_bar
    pd = Feedback("pd", sensor=[("h1.angle", 8.0), ("h1.rate", 0.8)], actuator="h1.torque", gain=1.0)
    controlled = with_feedback(loop, [pd])
    result = ctmm.simulate(controlled, 0.04, 2e-3, x0=q, v0=v, references={"pd": 1.6}, outputs=["h4.angle"])
    down = np.diag([1.0, -1.0, -1.0])

    def law(t, y):
        crank = down.T @ dae.rotations(y)[0]                       # Rot_x(theta)
        theta, rate = np.arctan2(crank[2, 1], crank[1, 1]), dae.split(y)[3][0][0]
        return {0: np.array([-(8.0 * theta + 0.8 * rate - 1.6), 0.0, 0.0])}

    dae = dae_of(loop)
    _, Y = dae.simulate(dae.state(*poses(loop, q, v)), result.time, torques=law)
    qs = np.array([result[name] for name in loop.tree.coordinates]).T
    vs = np.array([result[name] for name in loop.tree.velocities]).T
    _, R, _, _ = poses(loop, qs[-1], vs[-1])
    assert max(np.abs(a - b).max() for a, b in zip(R, dae.rotations(Y[-1]))) < 1e-9
    u = -(8.0 * result["h1.angle"] + 0.8 * result["h1.angle_rate"] - 1.6)
    assert np.max(np.abs(result["pd.u"] - u)) < 1e-12 and result["drift"].max() < 1e-8
    force = dae.accelerations(Y[-1], law(0.0, Y[-1]))[1][-1]       # with the loop torque of the row (measured 3.5e-8)
    assert abs(result["s3.force_z"][-1] - force) < 1e-7 * abs(force)
    with pytest.raises(ModelError, match="not available"):
        ctmm.natural_frequencies(controlled, operating_point=q)
    # the DT-TMM schemes run it too: tests/test_loop_scheme_projection.py


def test_closed_loop_poles_of_a_crank_pd_match_the_dae(four_bar, four_bar_equilibrium):
    """``ctmm.linearize`` of the controlled spatial loop model (real-time PD on the crank) against
    ``M s^2 + kd s + K + kp = 0`` with the crank's generalised mass ``M`` and stiffness ``K`` from the DAE (Lagrange on
    its manifold, the crank angle as the coordinate)."""
    from ctmm.control import Feedback, with_feedback

    loop, _, _ = four_bar
    kp, kd = 8.0, 0.8
    pd = Feedback("pd", sensor=[("h1.angle", kp), ("h1.rate", kd)], actuator="h1.torque", gain=1.0)
    lin = ctmm.linearize(with_feedback(loop, [pd]), four_bar_equilibrium, inputs=["pd.reference"],
                         outputs=["h1.angle", "pd.u"])
    poles = np.sort_complex(np.linalg.eigvals(np.asarray(lin.state_space.A)))
    dae = dae_of(loop)
    N, K, Mr = dae.small_oscillations(dae.state(*poses(loop, four_bar_equilibrium, np.zeros(4))))
    crank_rate = N[3, 0]                                          # crank omega_x (= h1 rate) per unit z'
    mass, stiffness = Mr[0, 0] / crank_rate ** 2, K[0, 0] / crank_rate ** 2
    expected = np.sort_complex(np.roots([mass, kd, stiffness + kp]))
    assert np.max(np.abs(poles - expected)) < 1e-6 * np.max(np.abs(expected))
    static = (np.asarray(lin.state_space.D) - np.asarray(lin.state_space.C) @ np.linalg.solve(
        np.asarray(lin.state_space.A), np.asarray(lin.state_space.B)))[0, 0]
    assert abs(static - 1.0 / (stiffness + kp)) < 1e-6 / (stiffness + kp)     # theta per unit reference


def test_cut_force_output_of_the_controlled_loop_matches_the_dae(four_bar, four_bar_equilibrium):
    """Cut-force outputs with a real-time crank PD: ``F = slope theta + gain u_total`` with the closed-loop crank angle
    ``theta = u / (M s^2 + K + kp + kd s)`` and the total crank torque ``u_total = 1 - (kp + kd s) theta`` per unit
    reference or torque; ``M``, ``K``, the slope (cut force per crank angle at rest on the manifold) and the gain (per
    unit crank torque) from the DAE."""
    from ctmm.control import Feedback, with_feedback

    loop, _, _ = four_bar
    kp, kd = 8.0, 0.8
    pd = Feedback("pd", sensor=[("h1.angle", kp), ("h1.rate", kd)], actuator="h1.torque", gain=1.0)
    omega = np.array([0.0, 5.0, 20.0])
    frf = ctmm.frequency_response(with_feedback(loop, [pd]), omega, input=["pd.reference", "h1.torque"],
                                  output=["s3.force_z", "h1.angle"], operating_point=four_bar_equilibrium)
    dae = dae_of(loop)
    y = dae.state(*poses(loop, four_bar_equilibrium, np.zeros(4)))
    N, K, Mr = dae.small_oscillations(y)
    crank = N[3, 0]                                                # crank angle per unit z
    h = 1e-4
    slope = (dae.accelerations(dae.manifold_configuration(y, [h]))[1][-1]
             - dae.accelerations(dae.manifold_configuration(y, [-h]))[1][-1]) / (2 * h * crank)
    gain = dae.accelerations(y, torques={0: np.array([1.0, 0.0, 0.0])})[1][-1] - dae.accelerations(y)[1][-1]
    s = 1j * omega
    theta = 1.0 / (Mr[0, 0] / crank ** 2 * s * s + K[0, 0] / crank ** 2 + kp + kd * s)
    expected = slope * theta + gain * (1.0 - (kp + kd * s) * theta)
    for name in ("pd.reference", "h1.torque"):
        np.testing.assert_allclose(frf("h1.angle", name), theta, rtol=1e-6)
        np.testing.assert_allclose(frf("s3.force_z", name), expected, rtol=1e-6,        # measured 1.4e-8
                                   atol=1e-6 * np.max(np.abs(expected)))


def test_delay_margin_of_the_linearised_controlled_loop_matches_the_closed_form(four_bar, four_bar_equilibrium):
    """``ctmm.stability.delay_margin`` of ``ctmm.linearize`` of a delayed crank PD on the spatial loop model, against
    ``M s^2 + K + (kp + kd s) e^{-s tau} = 0`` with ``M``, ``K`` of the crank from the DAE on its manifold: the
    crossover ``|K - M w^2| = |kp + i kd w|`` and the delay from its phase."""
    import scipy.optimize
    from ctmm.control import Feedback, with_feedback

    loop, _, _ = four_bar
    kp, kd = 8.0, 0.8
    pd = Feedback("pd", sensor=[("h1.angle", kp), ("h1.rate", kd)], actuator="h1.torque", gain=1.0, delay=0.01)
    controlled = with_feedback(loop, [pd])
    margin = ctmm.stability.delay_margin(ctmm.linearize(controlled, four_bar_equilibrium))
    dae = dae_of(loop)
    N, K, Mr = dae.small_oscillations(dae.state(*poses(loop, four_bar_equilibrium, np.zeros(4))))
    mass, stiffness = Mr[0, 0] / N[3, 0] ** 2, K[0, 0] / N[3, 0] ** 2
    crossing = scipy.optimize.brentq(lambda w: (stiffness - mass * w * w) ** 2 - kp ** 2 - (kd * w) ** 2,
                                     np.sqrt(stiffness / mass), 1e3)
    phase = np.angle((mass * crossing ** 2 - stiffness) / (kp + 1j * kd * crossing))
    delay = (-phase) % (2 * np.pi) / crossing
    assert abs(margin.critical_frequency / crossing - 1.0) < 1e-8 and abs(margin.critical_delay / delay - 1.0) < 1e-8
    omega = np.array([2.0, 20.0])                      # the delayed loop closed exactly in the frequency response
    frf = ctmm.frequency_response(controlled, omega, input="h1.torque", output="h1.angle",
                                  operating_point=four_bar_equilibrium)
    s = 1j * omega
    expected = 1.0 / (mass * s ** 2 + stiffness + (kp + kd * s) * np.exp(-s * 0.01))
    assert np.max(np.abs(frf.response[0, 0] - expected) / np.abs(expected)) < 1e-6


def test_frequency_verbs(four_bar, four_bar_equilibrium):
    loop, _, _ = four_bar
    omega = ctmm.natural_frequencies(loop, operating_point=four_bar_equilibrium)
    assert np.allclose(omega, linear.natural_frequencies(loop, four_bar_equilibrium), rtol=0, atol=0)
    assert ctmm.eigenvalue_count(loop, [1.0, 10.0], operating_point=four_bar_equilibrium).tolist() == [0, 1]
    lin = ctmm.linearize(loop, four_bar_equilibrium, inputs=["h1.torque"], outputs=["h1.angle", "s3.force_z"])
    A = np.asarray(lin.state_space.A)
    assert np.allclose(np.sort(np.abs(np.linalg.eigvals(A).imag)), [omega[0], omega[0]], rtol=1e-10)
    frf = ctmm.frequency_response(loop, [0.0, 3.0], input="h1.torque", output="h1.angle",
                                  operating_point=four_bar_equilibrium)
    assert frf.response.shape == (1, 1, 2)
    A, B = np.asarray(lin.state_space.A), np.asarray(lin.state_space.B)
    C, D = np.asarray(lin.state_space.C), np.asarray(lin.state_space.D)
    at_3 = (C @ np.linalg.solve(3j * np.eye(2) - A, B) + D)[0, 0]
    assert abs(frf.response[0, 0, 1] - at_3) < 1e-12 * abs(at_3)
    with pytest.raises(ModelError, match="pole"):
        ctmm.frequency_response(loop, [omega[0]], input="h1.torque", output="h1.angle",
                                operating_point=four_bar_equilibrium)
    with pytest.raises(ModelError, match="operating_point"):
        ctmm.natural_frequencies(loop)


def test_torque_input_matches_the_dae(four_bar, four_bar_equilibrium):
    """B of ctmm.linearize: at rest the crank's angular acceleration per unit crank torque, against the DAE with the
    torque on the crank (about world x, the hinge axis)."""
    loop, _, _ = four_bar
    lin = ctmm.linearize(loop, four_bar_equilibrium, inputs=["h1.torque"], outputs=["h1.angle", "s3.force_z"])
    basis = linear.tangent(loop, four_bar_equilibrium)[1]
    crank = (basis @ np.asarray(lin.state_space.B)[1:, 0])[0]
    dae = dae_of(loop)
    y = dae.state(*poses(loop, four_bar_equilibrium, np.zeros(4)))
    rest, mu0 = dae.accelerations(y)
    pushed, mu1 = dae.accelerations(y, torques={0: np.array([1.0, 0.0, 0.0])})
    assert abs(crank - (pushed - rest)[3]) < 1e-9 * abs(crank)
    assert abs(np.asarray(lin.state_space.D)[1, 0] - (mu1 - mu0)[-1]) < 1e-8 * max(1.0, abs((mu1 - mu0)[-1]))


def test_refusals(four_bar):
    loop, q, v = four_bar
    with pytest.raises(ModelError, match="kind"):
        SpatialCutJoint(name="c", parent=None, child="crank", kind="sliding")
    with pytest.raises(ModelError, match="two different bodies"):
        SpatialCutJoint(name="c", parent="crank", child="crank", child_point="tip")
    with pytest.raises(ModelError, match="nope"):
        SpatialKinematicLoopModel(loop.tree, [SpatialCutJoint(name="c", parent="nope", child="crank")])
    with pytest.raises(ModelError, match="point of crank"):
        SpatialKinematicLoopModel(loop.tree, [SpatialCutJoint(name="c", parent=None, child="crank",
                                                              child_point="elbow")])
    with pytest.raises(ModelError, match="duplicate"):
        SpatialKinematicLoopModel(loop.tree, [SpatialCutJoint(name="h1", parent=None, child="crank")])
    with pytest.raises(ModelError, match="not an equilibrium"):
        linear.natural_frequencies(loop, q)
    with pytest.raises(ModelError, match="allow_nonequilibrium"):
        ctmm.linearize(loop, q, allow_nonequilibrium=True)


def test_redundant_cut_of_a_planar_loop_is_refused_with_time_and_joint():
    """A planar four-bar (parallel hinge axes) closed by a revolute cut: 5 rows, only 2 independent."""
    down = np.diag([1.0, -1.0, -1.0])
    tree = sp.SpatialModel("planar", [
        rod("crank", 0.4, 0.2, direction=2), sp.Revolute(name="h1", parent=None, child="crank", axis=(1, 0, 0),
                                                         rotation=down),
        rod("coupler", 1.0, 0.5, direction=1), sp.Revolute(name="h2", parent="crank", point="tip", child="coupler",
                                                           axis=(1, 0, 0)),
        rod("rocker", 0.8, 0.2, direction=2), sp.Revolute(name="h4", parent=None, point=(0, 0.5, 0),
                                                          child="rocker", axis=(1, 0, 0), rotation=down)])
    loop = SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="h3", parent="rocker", point="tip", child="coupler",
                                                            child_point="tip", kind="revolute", axis=(1, 0, 0))])
    q = {"h1.angle": 0.1, "h2.angle": np.pi, "h4.angle": 0.0}
    q, v = loop.consistent_state(q, None, keep=["h1"])
    with pytest.raises(SimulationError, match="singular") as caught:
        loop.solve(q, v, 0.25)
    assert caught.value.time == 0.25 and caught.value.element == "h3"
