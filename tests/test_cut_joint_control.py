"""Cut-joint torques and relative angles as actuators and sensors of the control toolset (planar kinematic loops).

The four-bar linkage (scenario ``four_bar``: cut ``h3`` between the rocker's and the coupler's outboard ends) with a
PD loop on the cut's relative angle ``"h3.angle"`` / ``"h3.rate"`` driving the cut torque ``"h3.torque"`` (a motor at
the cut joint), real-time and delayed, through ``ctmm.simulate`` (loops, open-loop inputs, a co-simulated controller)
and the linear verbs.

Independent references: the global DAE of :mod:`ctmm.reference.planar_dae` with a motor between the rocker and the
coupler (the same PD law read ``delay`` seconds late, the method of steps), which shares no code with the tree
sweep, the cut-joint mechanism, the ports or the loop driver; and the closed forms of the one-degree-of-freedom
tangent ``crank'' = -k crank + b u``, ``dtheta = c crank`` whose ``k``, ``b`` and ``c`` are measured on the DAE's own
constraints: closed-loop poles ``s^2 + b c kd s + k + b c kp = 0`` and the response
``b / (s^2 + k + b c (kp + kd s) e^{-s tau})`` of the crank to a torque at the cut.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.optimize

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel
from ctmm.planar.loop_ports import KinematicLoopPorts
from ctmm.scenarios.four_bar import BODIES, mechanism, reference, start

KP, KD = 6.0, 0.6               # PD on the cut's relative angle [N m/rad], [N m s/rad]
OFFSET = 0.2                    # set point: the initial relative angle plus this [rad]


def _pd(delay: float) -> Feedback:
    return Feedback("pd", sensor=[("h3.angle", KP), ("h3.rate", KD)], actuator="h3.torque", gain=1.0, delay=delay)


def _relative(run_or_dae) -> np.ndarray:
    return run_or_dae.angle("coupler") - run_or_dae.angle("rocker")


@pytest.fixture(scope="module")
def free_four_bar():
    """The four-bar without the loop over the loop tests' 0.1 s at 1 ms (both delays compare with it)."""
    loop = mechanism()
    q0, v0 = start(loop)
    return ctmm.simulate(loop, 0.1, 1e-3, x0=q0, v0=v0)


@pytest.mark.parametrize("delay", [0.0, 0.01], ids=["real-time", "delayed"])
def test_pd_loop_on_the_cut_joint_matches_the_dae_with_a_motor_at_the_cut(delay, free_four_bar):
    # 0.1 s (ten delays): the loop moves the coupler 4.7e-3 rad from the free run (bound 1e-3)
    loop = mechanism()
    q0, v0 = start(loop)
    target = float(loop.relative_angles(q0, v0)[0][0]) + OFFSET
    dae = reference()
    dae.add_motor("rocker", "coupler", lambda t, angle, rate: -(KP * angle + KD * rate - KP * target), delay=delay)
    state = dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0)))
    run = ctmm.simulate(with_feedback(loop, [_pd(delay)]), 0.1, 1e-3, x0=q0, v0=v0,
                        references={"pd": KP * target}, outputs=["h3.angle", "h3.rate"])
    dae_run = dae.simulate(state, 0.1, t_eval=run.time)
    error = max(np.max(np.abs(run[f"{n}.theta"] - dae_run.angle(n))) for n in BODIES)
    assert error < 1e-9                       # RK4 at 1 ms, the bound of the crank-hinge loop tests
    assert np.max(np.abs(run["h3.angle"] - _relative(dae_run))) < 1e-9
    relative_rate = dae_run.rate("coupler") - dae_run.rate("rocker")
    assert np.max(np.abs(run["h3.rate"] - relative_rate)) < 1e-8
    if delay == 0.0:
        torque = -(KP * _relative(dae_run) + KD * relative_rate - KP * target)
        assert np.max(np.abs(run["pd.u"] - torque)) < 1e-7
    assert run.units(["h3.angle", "h3.rate", "pd.u"]) == {"h3.angle": "rad", "h3.rate": "rad/s", "pd.u": "N m"}
    assert np.max(run["drift"]) < 1e-10
    assert np.max(np.abs(free_four_bar["coupler.theta"] - run["coupler.theta"])) > 1e-3       # the loop acts


def test_delayed_cut_loop_on_a_dt_tmm_scheme_converges_to_the_dae_at_second_order():
    """Newmark (the tree's implicit stepper, cut forces and the cut torque applied at every Newton iterate)."""
    loop = mechanism()
    q0, v0 = start(loop)
    target = float(loop.relative_angles(q0, v0)[0][0]) + OFFSET
    dae = reference()
    dae.add_motor("rocker", "coupler", lambda t, angle, rate: -(KP * angle + KD * rate - KP * target), delay=0.01)
    state = dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0)))
    errors = []
    for dt in (2e-3, 1e-3):
        run = ctmm.simulate(with_feedback(loop, [_pd(0.01)]), 0.05, dt, x0=q0, v0=v0, method="newmark",
                            references={"pd": KP * target}, outputs=["h3.angle"])
        errors.append(np.max(np.abs(run["h3.angle"] - _relative(dae.simulate(state, 0.05, t_eval=run.time)))))
    assert errors[1] < 1e-6 and 3.0 < errors[0] / errors[1] < 5.0


def test_open_loop_cut_torque_input_and_cut_sensor_outputs():
    loop = mechanism()
    q0, v0 = start(loop)
    run = ctmm.simulate(loop, 0.1, 1e-3, x0=q0, v0=v0, inputs={"h3.torque": lambda t: 0.8 * math.sin(20.0 * t)},
                        outputs=["h3.angle"])
    dae = reference()
    dae.add_motor("rocker", "coupler", lambda t, angle, rate: 0.8 * math.sin(20.0 * t))
    dae_run = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.1, t_eval=run.time)
    assert max(np.max(np.abs(run[f"{n}.theta"] - dae_run.angle(n))) for n in BODIES) < 1e-9
    assert np.max(np.abs(run["h3.angle"] - _relative(dae_run))) < 1e-9
    bare = ctmm.simulate(loop, 0.1, 1e-3, x0=q0, v0=v0, outputs=["h3.angle", "h3.rate"])    # the model's own runner
    free = reference().simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.1, t_eval=bare.time)
    assert np.max(np.abs(bare["h3.angle"] - _relative(free))) < 1e-9
    assert np.max(np.abs(bare["h3.angle"] - run["h3.angle"])) > 1e-4                 # the torque acts


def test_sampled_controller_on_the_cut_converges_to_the_continuous_loop_of_the_dae():
    """A co-simulated static-gain PD on the cut angle and rate, sampled every step (zero-order hold), approaches
    the continuous PD of the DAE's cut motor at first order in the sample time."""
    from ctmm.control.static_gain import StaticGainController

    loop = mechanism()
    q0, v0 = start(loop)
    dae = reference()
    dae.add_motor("rocker", "coupler", lambda t, angle, rate: -(KP * angle + KD * rate))
    angle = _relative(dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.1,
                                   t_eval=[0.0, 0.1]))[-1]
    errors = []
    for dt in (1e-3, 5e-4):
        controller = StaticGainController(["h3.angle", "h3.rate"], ["h3.torque"], [[-KP, -KD]], sample_time=dt)
        run = ctmm.simulate(loop, 0.1, dt, x0=q0, v0=v0, controllers=[controller], outputs=["h3.angle"])
        errors.append(abs(run["h3.angle"][-1] - angle))
    assert errors[0] < 1e-2 and errors[0] / errors[1] == pytest.approx(2.0, rel=0.05)


def _assembled(dae, crank: float, guess):
    """DAE state at rest with the crank at ``crank`` [rad]; coupler and rocker from the DAE's loop constraint."""
    def residual(angles):
        q, v = dae.assemble(dict(zip(BODIES, [crank, *angles])), dict.fromkeys(BODIES, 0.0))
        return dae.constraints(q, v)[0][-2:]

    angles = scipy.optimize.fsolve(residual, guess, xtol=1e-13)
    assert np.max(np.abs(residual(angles))) < 1e-13
    return dae.assemble(dict(zip(BODIES, [crank, *angles])), dict.fromkeys(BODIES, 0.0))


@pytest.fixture(scope="module")
def tangent():
    """``(k, b, c)`` at the four-bar's hanging equilibrium (the default operating point of the linear verbs,
    checked to be the DAE's), on the DAE's own constraints: the crank stiffness ``-d crank''/d crank`` [1/s^2], the
    crank's acceleration per torque at the cut ``d crank''/d u`` [1/(kg m^2)] and the cut's relative angle per
    crank angle ``c = d dtheta / d crank`` [1]."""
    q_eq = ctmm.linearize(mechanism(), inputs=["h3.torque"]).operating_point.q
    dae, driven = reference(), reference()
    driven.add_motor("rocker", "coupler", lambda t, angle, rate: 1.0)
    state = _assembled(dae, q_eq[0], q_eq[1:])
    assert np.max(np.abs(dae.solve(*state)[0])) < 1e-9 and np.max(np.abs(state[0][2::3] - q_eq)) < 1e-12
    h = 1e-5
    plus, minus = _assembled(dae, q_eq[0] + h, q_eq[1:]), _assembled(dae, q_eq[0] - h, q_eq[1:])
    k = -(dae.solve(*plus)[0][2] - dae.solve(*minus)[0][2]) / (2 * h)
    b = driven.solve(*state)[0][2] - dae.solve(*state)[0][2]
    c = ((plus[0][5] - plus[0][8]) - (minus[0][5] - minus[0][8])) / (2 * h)
    return k, b, c


def test_linearised_cut_loop_matches_the_dae_tangent(tangent):
    k, b, c = tangent
    loop = mechanism()
    lin = ctmm.linearize(with_feedback(loop, [_pd(0.0)]), inputs=["h3.torque"], outputs=["crank.theta", "h3.angle"])
    poles = np.sort_complex(np.linalg.eigvals(np.asarray(lin.state_space.A, dtype=float)))
    np.testing.assert_allclose(poles, np.sort_complex(np.roots([1.0, b * c * KD, k + b * c * KP])), rtol=1e-8)
    omega = np.array([0.5, 3.0, 9.0, 25.0])
    s = 1j * omega
    for delay in (0.0, 0.02):
        frf = ctmm.frequency_response(with_feedback(loop, [_pd(delay)]), omega, input="h3.torque",
                                      output=["crank.theta", "h3.angle", "pd.u"])
        crank = b / (s ** 2 + k + b * c * (KP + KD * s) * np.exp(-delay * s))
        np.testing.assert_allclose(frf("crank.theta", "h3.torque"), crank, rtol=1e-8)
        np.testing.assert_allclose(frf("h3.angle", "h3.torque"), c * crank, rtol=1e-8)
        np.testing.assert_allclose(frf("pd.u", "h3.torque"), -c * (KP + KD * s) * np.exp(-delay * s) * crank,
                                   rtol=1e-8)
        assert frf.units["h3.torque"] == "N m" and frf.units["h3.angle"] == "rad"
    open_loop = ctmm.frequency_response(loop, omega, input="h3.torque", output="h3.angle")
    np.testing.assert_allclose(open_loop("h3.angle", "h3.torque"), c * b / (s ** 2 + k), rtol=1e-8)


def test_margins_of_the_delayed_cut_loop_match_the_dae_tangent(tangent):
    from ctmm.stability import delay_margin

    k, b, c = tangent
    gain_p, gain_d = b * c * KP, b * c * KD          # s^2 + k + (gain_p + gain_d s) e^{-s tau}
    quadratic = np.roots([1.0, -(2 * k + gain_d ** 2), k * k - gain_p ** 2])
    omega = math.sqrt(max(r.real for r in quadratic))
    tau = (-np.angle(-(k - omega ** 2) / (gain_p + 1j * gain_d * omega)) % (2 * math.pi)) / omega
    margin = delay_margin(with_feedback(mechanism(), [_pd(0.01)]))
    assert margin.stable and margin.critical_delay == pytest.approx(tau, rel=1e-6)


def test_cut_port_names_are_listed_and_bad_names_refused():
    loop = mechanism()
    ports = KinematicLoopPorts(loop)
    assert {"h3.angle", "h3.rate"} <= set(ports.sensors) and "h3.torque" in ports.actuators
    assert "h3.moment" not in ports.sensors            # a smooth cut has no moment
    assert ports.sensor_unit("h3.rate") == "rad/s" and ports.actuator_unit("h3.torque") == "N m"
    q0, v0 = start(loop)
    with pytest.raises(ModelError, match=r"h3\.torq.*h3\.torque"):
        ctmm.simulate(loop, 0.01, 1e-3, x0=q0, v0=v0, inputs={"h3.torq": 1.0})
    with pytest.raises(ModelError, match=r"h3\.angel.*h3\.angle"):
        ctmm.simulate(with_feedback(loop, [Feedback("f", sensor="h3.angel", actuator="h3.torque", gain=1.0)]), 0.01, 1e-3,
                      x0=q0, v0=v0)
    with pytest.raises(ModelError, match=r"h3\.moment.*no moment_law or torque.*h3\.angle"):
        ctmm.linearize(loop, inputs=["h3.torque"], outputs=["h3.moment"])
    driven = KinematicLoopModel(loop.tree, [CutJoint("h3", parent="rocker.out", child="coupler.out",
                                                     angle=lambda t: 0.1 * t, angle_rate=0.1)])
    with pytest.raises(ModelError, match=r"h3\.torque.*driven"):
        KinematicLoopPorts(driven).check_actuator("h3.torque")
    with pytest.raises(ModelError, match=r"h3\.moment.*driven"):
        KinematicLoopPorts(driven).check_sensor("h3.moment")


def test_cut_moment_sensor_reads_the_law():
    from ctmm.nonlinear_laws import LinearLaw

    tree = mechanism().tree
    sprung = KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.out",
                                                moment_law=LinearLaw(3.0, 0.2), rest_angle=-1.3)])
    q0, v0 = start(sprung)
    ports = KinematicLoopPorts(sprung)
    angle, rate = sprung.relative_angles(q0, v0)
    value = ports.values(ports.resolve(["h3.moment"]), q0, v0, 0.0)[0]
    assert value == pytest.approx(-(3.0 * (angle[0] + 1.3) + 0.2 * rate[0]), rel=1e-14)
    run = ctmm.simulate(sprung, 0.01, 1e-3, x0=q0, v0=v0, inputs={"h3.torque": 0.3}, outputs=["h3.angle"])
    assert run.units(["h3.moment"]) == {"h3.moment": "N m"}


# ------------------------------------------------------------------------------------------------------------------
# spatial: a revolute cut
# ------------------------------------------------------------------------------------------------------------------
S_MASS, S_INERTIA_Y, S_COM = 1.2, 0.03, (0.1, 0.0, -0.3)    # [kg], [kg m^2] about the centre of mass, body axes [m]
S_HINGE = S_INERTIA_Y + S_MASS * (S_COM[0] ** 2 + S_COM[2] ** 2)     # about the hinge axis [kg m^2]
S_KP, S_KD, S_TARGET = 3.0, 0.3, 0.9                        # PD on the cut angle [N m/rad], [N m s/rad]; set point [rad]


def _spatial_pendulum(**cut):
    """A body on a free joint held at the ground by a revolute cut about world y at its origin (6 - 5 = 1 DOF)."""
    import ctmm.spatial as sp
    from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

    tree = sp.SpatialModel("hinged", [sp.SpatialBody("p", S_MASS, np.diag([0.02, S_INERTIA_Y, 0.025]),
                                                     center_of_mass=S_COM),
                                      sp.Free(name="free", parent=None, child="p")])
    return SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="hinge", parent=None, child="p", kind="revolute",
                                                            axis=(0, 1, 0), **cut)])


def _spatial_state(loop, angle: float, rate: float):
    return loop.consistent_state({"free.qw": math.cos(angle / 2), "free.qy": math.sin(angle / 2)}, {"free.wy": rate},
                                 keep=["free.wy"])


def _gravity_moment(s: float) -> float:
    """Gravity's moment about the hinge [N m] at the cut angle ``s`` [rad] (Newton's law of the compound pendulum)."""
    return S_MASS * 9.81 * (S_COM[0] * math.cos(s) + S_COM[2] * math.sin(s))


def _spatial_reference(s0: float, rate0: float, times: np.ndarray, delay: float) -> np.ndarray:
    """``I_O s'' = gravity(s) + u``, ``u = -(kp s + kd s' - kp target)`` read ``delay`` s late (before 0: the initial
    state), by the method of steps (DOP853, 1e-12), written here from Newton's law."""
    def law(s: float, rate: float) -> float:
        return -(S_KP * s + S_KD * rate - S_KP * S_TARGET)

    if delay == 0.0:
        sol = scipy.integrate.solve_ivp(lambda t, y: [y[1], (_gravity_moment(y[0]) + law(*y)) / S_HINGE],
                                        (0.0, times[-1]), [s0, rate0], method="DOP853", t_eval=times, rtol=1e-12,
                                        atol=1e-13)
        return sol.y[0]
    segments = []

    def past(t: float) -> np.ndarray:
        if t <= 0.0:
            return np.array([s0, rate0])
        return next(seg for start, seg in segments if start <= t <= start + delay + 1e-15)(t)

    start, y = 0.0, [s0, rate0]
    while start < times[-1]:
        end = min(start + delay, times[-1])
        sol = scipy.integrate.solve_ivp(lambda t, y: [y[1], (_gravity_moment(y[0]) + law(*past(t - delay)))
                                                      / S_HINGE], (start, end), y, method="DOP853",
                                        dense_output=True, rtol=1e-12, atol=1e-13)
        segments.append((start, sol.sol))
        start, y = end, sol.y[:, -1]
    return np.array([past(t)[0] for t in times])


@pytest.mark.parametrize("delay", [0.0, 0.01], ids=["real-time", "delayed"])
def test_spatial_pd_loop_on_a_revolute_cut_matches_newtons_law(delay):
    loop = _spatial_pendulum()
    q0, v0 = _spatial_state(loop, 0.5, 2.0)
    pd = Feedback("pd", sensor=[("hinge.angle", S_KP), ("hinge.rate", S_KD)], actuator="hinge.torque", gain=1.0,
                  delay=delay)
    run = ctmm.simulate(with_feedback(loop, [pd]), 0.1, 2e-3, x0=q0, v0=v0, references={"pd": S_KP * S_TARGET},
                        outputs=["hinge.angle", "hinge.rate"])
    expected = _spatial_reference(0.5, 2.0, run.time, delay)
    assert np.max(np.abs(run["hinge.angle"] - expected)) < 1e-9      # RK4 at 2 ms (measured 2.3e-11 rad)
    assert run.units(["hinge.angle", "hinge.rate"]) == {"hinge.angle": "rad", "hinge.rate": "rad/s"}
    free = _spatial_reference(0.5, 2.0, run.time, 0.0) if delay else None
    if free is not None:
        assert np.max(np.abs(free - expected)) > 1e-5               # the delay shows


def _spatial_dae(cut):
    """The pendulum as :mod:`ctmm.reference.spatial_loop_dae` (the body free in space, the revolute to the ground as
    five constraint rows), the cut angle and rate read off the DAE's rotation (``(s, s', a)``, ``a`` the world hinge
    axis) and the DAE state of the start (0.5 rad, 2 rad/s)."""
    from ctmm.reference.spatial_loop_dae import DaeBody, DaeJoint, SpatialLoopDAE

    com = np.asarray(S_COM, float)
    dae = SpatialLoopDAE([DaeBody("p", S_MASS, np.diag([0.02, S_INERTIA_Y, 0.025]))],
                         [DaeJoint("hinge", "revolute", -1, np.zeros(3), 0, -com, parent_axis=np.array([0.0, 1.0, 0.0]),
                                   child_axis=np.array([0.0, 1.0, 0.0]))], gravity=(0.0, 0.0, -9.81))

    def angle_and_rate(y: np.ndarray) -> tuple[float, float, np.ndarray]:
        R = dae.rotations(y)[0]
        a, n_c = R @ cut.axis, R @ cut.normal
        return (math.atan2(np.cross(cut.parent_normal, n_c) @ a, cut.parent_normal @ n_c),
                float(dae.split(y)[3][0] @ a), a)

    c, s_ = math.cos(0.5), math.sin(0.5)
    R0 = np.array([[c, 0.0, s_], [0.0, 1.0, 0.0], [-s_, 0.0, c]])          # 0.5 rad about y
    w0 = np.array([0.0, 2.0, 0.0])
    y0 = dae.state([R0 @ com], [R0], [np.cross(w0, R0 @ com)], [w0])
    assert angle_and_rate(y0)[:2] == pytest.approx((0.5, 2.0), abs=1e-14)
    return dae, angle_and_rate, y0


def _pd_torque(s: float, rate: float) -> float:
    return -(S_KP * s + S_KD * rate - S_KP * S_TARGET)


def test_spatial_real_time_cut_loop_matches_the_newton_euler_dae():
    """The same loop against :mod:`ctmm.reference.spatial_loop_dae`: the PD torque ``u a`` with the angle between the
    cut's normals read off the DAE's rotation."""
    loop = _spatial_pendulum()
    q0, v0 = _spatial_state(loop, 0.5, 2.0)
    pd = Feedback("pd", sensor=[("hinge.angle", S_KP), ("hinge.rate", S_KD)], actuator="hinge.torque", gain=1.0)
    run = ctmm.simulate(with_feedback(loop, [pd]), 0.1, 2e-3, x0=q0, v0=v0, references={"pd": S_KP * S_TARGET},
                        outputs=["hinge.angle"])
    dae, angle_and_rate, y0 = _spatial_dae(loop.cuts[0])

    def torques(t: float, y: np.ndarray) -> dict:
        s, rate, a = angle_and_rate(y)
        return {0: _pd_torque(s, rate) * a}

    _, Y = dae.simulate(y0, run.time, torques=torques)
    expected = np.array([angle_and_rate(y)[0] for y in Y])
    assert np.max(np.abs(run["hinge.angle"] - expected)) < 1e-9      # RK4 at 2 ms
    assert np.ptp(expected) > 0.05


def test_spatial_delayed_cut_loop_matches_the_newton_euler_dae_by_the_method_of_steps():
    """The PD loop read 10 ms late against the spatial DAE with the delay: the method of steps on the DAE (DOP853 at
    1e-12 on segments one delay long, the torque ``u(s, s')`` of the state ``delay`` earlier from the previous
    segment's dense output, the start's state before t = 0) -- the delayed loop checked against the spatial
    Newton-Euler equations, not only against the one-coordinate pendulum (measured 2.3e-11 rad at RK4 2 ms)."""
    delay = 0.01
    loop = _spatial_pendulum()
    q0, v0 = _spatial_state(loop, 0.5, 2.0)
    pd = Feedback("pd", sensor=[("hinge.angle", S_KP), ("hinge.rate", S_KD)], actuator="hinge.torque", gain=1.0,
                  delay=delay)
    run = ctmm.simulate(with_feedback(loop, [pd]), 0.1, 2e-3, x0=q0, v0=v0, references={"pd": S_KP * S_TARGET},
                        outputs=["hinge.angle"])
    dae, angle_and_rate, y0 = _spatial_dae(loop.cuts[0])
    segments: list = []

    def past(t: float) -> np.ndarray:
        if t <= 0.0:
            return y0
        return next(dense for begin, dense in segments if begin <= t <= begin + delay + 1e-15)(t)

    def torques(t: float, y: np.ndarray) -> dict:
        s, rate, _ = angle_and_rate(past(t - delay))
        return {0: _pd_torque(s, rate) * angle_and_rate(y)[2]}       # about the hinge axis now

    begin, y = 0.0, y0
    while begin < run.time[-1] - 1e-12:
        end = min(begin + delay, run.time[-1])
        sol = scipy.integrate.solve_ivp(lambda t, state: dae.rate(t, state, torques), (begin, end), y,
                                        method="DOP853", dense_output=True, rtol=1e-12, atol=1e-13)
        segments.append((begin, sol.sol))
        begin, y = end, sol.y[:, -1]
    expected = np.array([angle_and_rate(past(t))[0] for t in run.time])
    assert np.max(np.abs(run["hinge.angle"] - expected)) < 1e-9
    real_time = _spatial_reference(0.5, 2.0, run.time, 0.0)
    assert np.max(np.abs(real_time - expected)) > 1e-5               # the delay shows


def test_spatial_open_loop_cut_torque_input():
    loop = _spatial_pendulum()
    q0, v0 = _spatial_state(loop, 0.5, 2.0)
    run = ctmm.simulate(loop, 0.1, 2e-3, x0=q0, v0=v0, inputs={"hinge.torque": lambda t: 0.8 * math.sin(20.0 * t)},
                        outputs=["hinge.angle"])
    sol = scipy.integrate.solve_ivp(lambda t, y: [y[1], (_gravity_moment(y[0]) + 0.8 * math.sin(20.0 * t)) / S_HINGE],
                                    (0.0, 0.1), [0.5, 2.0], method="DOP853", t_eval=run.time, rtol=1e-12, atol=1e-13)
    assert np.max(np.abs(run["hinge.angle"] - sol.y[0])) < 1e-9


def test_spatial_linearised_cut_loop_matches_the_closed_form():
    """About the hanging equilibrium ``tan s* = x_C / -z_C``: ``I_O s'' = -k s + u``, ``k = m g (x_C sin s* - z_C cos
    s*)``; the loop closes ``1 / (I_O s^2 + k + (kp + kd s) e^{-s tau})``."""
    from ctmm.spatial.closed_loop_linear import equilibrium

    loop = _spatial_pendulum()
    rest = math.atan2(S_COM[0], -S_COM[2])
    q_eq = equilibrium(loop, _spatial_state(loop, rest + 0.01, 0.0)[0])
    k = S_MASS * 9.81 * (S_COM[0] * math.sin(rest) - S_COM[2] * math.cos(rest))
    omega = np.array([0.5, 3.0, 9.0, 25.0])
    s = 1j * omega
    for delay in (0.0, 0.02):
        pd = Feedback("pd", sensor=[("hinge.angle", S_KP), ("hinge.rate", S_KD)], actuator="hinge.torque", gain=1.0,
                      delay=delay)
        frf = ctmm.frequency_response(with_feedback(loop, [pd]), omega, input="hinge.torque",
                                      output=["hinge.angle", "pd.u"], operating_point=q_eq)
        angle = 1.0 / (S_HINGE * s ** 2 + k + (S_KP + S_KD * s) * np.exp(-delay * s))
        np.testing.assert_allclose(frf("hinge.angle", "hinge.torque"), angle, rtol=1e-8)
        np.testing.assert_allclose(frf("pd.u", "hinge.torque"), -(S_KP + S_KD * s) * np.exp(-delay * s) * angle,
                                   rtol=1e-8)
    pd = Feedback("pd", sensor=[("hinge.angle", S_KP), ("hinge.rate", S_KD)], actuator="hinge.torque", gain=1.0)
    lin = ctmm.linearize(with_feedback(loop, [pd]), q_eq, inputs=["hinge.torque"], outputs=["hinge.angle"])
    poles = np.sort_complex(np.linalg.eigvals(np.asarray(lin.state_space.A, dtype=float)))
    np.testing.assert_allclose(poles, np.sort_complex(np.roots([S_HINGE, S_KD, k + S_KP])), rtol=1e-8)


def test_spatial_cut_ports_refused_by_name():
    from ctmm.spatial.closed_loop_ports import SpatialLoopPorts

    loop = _spatial_pendulum()
    ports = SpatialLoopPorts(loop)
    assert {"hinge.angle", "hinge.rate"} <= set(ports.sensors) and ports.actuator_unit("hinge.torque") == "N m"
    q0, v0 = _spatial_state(loop, 0.5, 2.0)
    with pytest.raises(ModelError, match=r"hinge\.force.*hinge\.torque"):
        ctmm.simulate(loop, 0.01, 1e-3, x0=q0, v0=v0, inputs={"hinge.force": 1.0})
    driven = _spatial_pendulum(position=lambda t: 0.5 + 0.1 * t, rate=0.1, acceleration=0.0)
    with pytest.raises(ModelError, match=r"hinge\.torque.*driven"):
        SpatialLoopPorts(driven).check_actuator("hinge.torque")


def test_spatial_cut_force_port_between_two_moving_bodies_equals_the_cuts_own_actuation():
    """A prismatic cut whose guide moves (a sleeve on a swinging rod): the port ``"<cut>.force"`` (held in the
    bodies' own axes, the parent's share at its own point) loads the mechanism as the cut's ``actuation`` (world
    direction at the current state, validated against Newton's law in tests/test_spatial_cut_joint_laws.py) does, to
    the drift (both runs in the loop driver)."""
    from dataclasses import replace

    from ctmm.spatial.closed_loops import SpatialKinematicLoopModel
    from test_spatial_closed_loops_prismatic import sliding_pendulum

    def force(t: float) -> float:
        return 1.5 * math.sin(15.0 * t)

    loop = sliding_pendulum()
    q, v = loop.consistent_state({"h1.angle": 0.4, "free.z": -0.3}, {"h1.angle_rate": 1.5, "free.vz": 0.2},
                                 keep=["h1"])
    actuated = SpatialKinematicLoopModel(loop.tree, [replace(loop.cuts[0], actuation=force)], baumgarte=20.0)
    port = ctmm.simulate(loop, 0.05, 2e-3, x0=q, v0=v, inputs={"sleeve_on_arm.force": force},
                         outputs=["sleeve_on_arm.position", "h1.angle"])
    own = ctmm.simulate(actuated, 0.05, 2e-3, x0=q, v0=v, outputs=["sleeve_on_arm.position", "h1.angle"])
    free = ctmm.simulate(loop, 0.05, 2e-3, x0=q, v0=v, outputs=["sleeve_on_arm.position", "h1.angle"])
    for name in ("sleeve_on_arm.position", "h1.angle"):
        assert np.max(np.abs(port[name] - own[name])) < 1e-9
        assert np.max(np.abs(free[name] - own[name])) > 1e-5                # the force acts
    assert port.units(["sleeve_on_arm.position"]) == {"sleeve_on_arm.position": "m"}


def test_spatial_sampled_controller_on_the_cut_converges_to_the_continuous_loop():
    """A co-simulated static-gain PD on ``"hinge.angle"``, ``"hinge.rate"`` driving ``"hinge.torque"``, sampled every
    step (zero-order hold), approaches the continuous PD of Newton's law at first order in the sample time."""
    from ctmm.control.static_gain import StaticGainController

    loop = _spatial_pendulum()
    q0, v0 = _spatial_state(loop, 0.5, 2.0)
    sol = scipy.integrate.solve_ivp(lambda t, y: [y[1], (_gravity_moment(y[0]) - S_KP * y[0] - S_KD * y[1]) / S_HINGE],
                                    (0.0, 0.1), [0.5, 2.0], method="DOP853", rtol=1e-12, atol=1e-13)
    expected = sol.y[0, -1]                         # the continuous PD (no set point) by Newton's law
    errors = []
    for dt in (2e-3, 1e-3):
        controller = StaticGainController(["hinge.angle", "hinge.rate"], ["hinge.torque"], [[-S_KP, -S_KD]],
                                          sample_time=dt)
        run = ctmm.simulate(loop, 0.1, dt, x0=q0, v0=v0, controllers=[controller], outputs=["hinge.angle"])
        errors.append(abs(run["hinge.angle"][-1] - expected))
    assert errors[0] < 1e-2 and errors[0] / errors[1] == pytest.approx(2.0, rel=0.1)


def test_planar_cut_torque_port_at_a_beam_end_equals_the_cuts_own_torque():
    """The flexible coupler (a ModalBeam cut at its end): the port ``"h3.torque"`` loads the frame and, through the end
    slope, the modal coordinates as the cut's own ``torque`` signal does (one load path: a check of the wiring; the
    cut torque itself is checked against the DAE in tests/test_cut_joint_laws.py)."""
    from ctmm.scenarios.four_bar import flexible_mechanism, flexible_start

    def torque(t: float) -> float:
        return 0.6 * math.sin(25.0 * t)

    loop = flexible_mechanism(20.0, n_modes=2)
    q0, v0 = flexible_start(loop)
    own = KinematicLoopModel(loop.tree, [CutJoint("h3", parent="rocker.out", child="coupler.out", torque=torque)])
    port = ctmm.simulate(loop, 0.03, 1e-3, x0=q0, v0=v0, inputs={"h3.torque": torque}, outputs=["h3.angle"])
    reference_run = ctmm.simulate(own, 0.03, 1e-3, x0=q0, v0=v0, inputs={"h1.torque": 0.0}, outputs=["h3.angle"])
    free = ctmm.simulate(loop, 0.03, 1e-3, x0=q0, v0=v0, inputs={"h1.torque": 0.0}, outputs=["h3.angle"])
    assert np.max(np.abs(port["h3.angle"] - reference_run["h3.angle"])) < 1e-12
    assert np.max(np.abs(port["coupler.q1"] - reference_run["coupler.q1"])) < 1e-12
    assert np.max(np.abs(free["h3.angle"] - port["h3.angle"])) > 1e-5                 # the torque acts
