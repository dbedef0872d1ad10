"""Generated spatial kernels with time signals on loads and driven joints (issue 13): the generated
accelerations (and the loop sweep with a hinge torque) against Pinocchio; the generated RK4, DT-TMM schemes,
feedback loops in both, kinematic loops with loaded trees and exported FMUs against the numpy paths; user
callables and loop sensors that move with a driven joint refused by name."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.compiled_spatial import spatial_compile_refusal
from ctmm.errors import ModelError
from ctmm.signals import Harmonic, Ramp, Step

pytest.importorskip("casadi")

# the driven angle 0.4 sin(2 t + 0.3), its rate and acceleration
ANGLE, RATE, ACCELERATION = Harmonic(0.4, 2.0, 0.3), Harmonic(0.8, 2.0, 0.3 + np.pi / 2), Harmonic(-1.6, 2.0, 0.3)


def body(name: str) -> sp.SpatialBody:
    return sp.SpatialBody(name, 1.0, (0.1, 0.2, 0.25), (0.0, 0.0, -0.5), {"tip": (0.0, 0.0, -1.0)})


def driven_chain(position=ANGLE, force=(Step(0.5, 0.01), 0.0, Harmonic(0.3, 5.0)), rate=RATE,
                 acceleration=ACCELERATION) -> sp.SpatialModel:
    """A revolute, a revolute driven by sines in the middle, a ball joint; a load (a step and a sine) at the tip."""
    return sp.SpatialModel("driven", [
        body("a"), body("b"), body("c"),
        sp.Revolute(name="ja", parent=None, child="a", axis=(1, 0, 0), actuated=True),
        sp.Revolute(name="jb", parent="a", point="tip", child="b", axis=(0, 1, 1), position=position, rate=rate,
                    acceleration=acceleration),
        sp.Spherical(name="jc", parent="b", point="tip", child="c", actuated=True),
        sp.Load("push", "c", "tip", force=force)])


def test_driven_joint_on_the_time_symbol_equals_pinocchio() -> None:
    """The generated accelerations at two times equal Pinocchio's with the driven acceleration moved to the
    right-hand side (the load set to zero: Pinocchio's ABA takes none here)."""
    pin = pytest.importorskip("pinocchio")
    from ctmm.compiled_spatial import CompiledSpatialScene

    model = driven_chain(force=(0.0, 0.0, 0.0))
    assert spatial_compile_refusal(model, time_signals=True) == ""
    scene = CompiledSpatialScene(model)
    q, v = np.array([0.3, 0.9, 0.1, -0.3, 0.2]), np.array([0.5, 0.2, -0.4, 0.3])
    for t in (0.0, 0.7):
        expected = pinocchio_accelerations(pin, model, q, v, t, 0.0)
        np.testing.assert_allclose(scene.accelerations(q, v, t=t), expected, rtol=0,
                                   atol=1e-10 * max(1.0, np.abs(expected).max()))


def pinocchio_accelerations(pin, model: sp.SpatialModel, q: np.ndarray, v: np.ndarray, t: float, torque: float
                            ) -> np.ndarray:
    """Pinocchio's accelerations of the free coordinates of ``driven_chain`` at ``(q, v, t)`` with ``torque`` [N m]
    on the inboard hinge: the driven acceleration moved to the right-hand side (no load)."""
    from spatial_pinocchio_helpers import pinocchio_driven_chain

    pm, _ = pinocchio_driven_chain(pin, model)
    data = pm.createData()
    quat = q[1:] / np.linalg.norm(q[1:])
    qp, vp = np.r_[q[0], ANGLE(t), quat[1:], quat[0]], np.r_[v[0], RATE(t), v[1:]]
    M = pin.crba(pm, data, qp)
    M = np.triu(M) + np.triu(M, 1).T
    bias = pin.nle(pm, data, qp, vp)
    free = [0, 2, 3, 4]
    return np.linalg.solve(M[np.ix_(free, free)], np.r_[torque, 0.0, 0.0, 0.0] - bias[free]
                           - M[free, 1] * ACCELERATION(t))


def test_generated_rk4_with_time_signals_equals_the_numpy_rk4() -> None:
    model = driven_chain()
    v0 = {"ja.angle_rate": 0.5, "jc.wx": 0.3}
    generated = ctmm.simulate(model, 0.1, 1e-3, compiled=True, v0=v0)
    reference = ctmm.simulate(model, 0.1, 1e-3, method="rk4", v0=v0)
    assert generated.info["method"] == "rk4-generated"
    for name in model.coordinates + model.velocities:
        np.testing.assert_allclose(generated[name], reference[name], rtol=0, atol=1e-12)
    assert np.ptp(generated["jc.wx"]) > 1e-2                                   # the load and the drive acted


def test_user_callables_are_refused_by_name() -> None:
    with pytest.raises(ModelError, match=r"without a symbolic form in driven joint 'jb' \(position\[0\] is a UserFunction\)"):
        ctmm.simulate(driven_chain(position=lambda t: 0.4 * np.sin(2 * t + 0.3)), 0.01, 1e-3, compiled=True)
    with pytest.raises(ModelError, match=r"without a symbolic form in load 'push' \(force\[0\]"):
        ctmm.simulate(driven_chain(force=(lambda t: t, 0.0, 0.0)), 0.01, 1e-3, compiled=True)
    # the paths that state the terms at one time keep refusing any signal that is not a constant
    assert "signals that are not constants in driven joint 'jb' (position[0] is a Harmonic), load 'push' (force[0] " \
        "is a Step)" in spatial_compile_refusal(driven_chain())


def test_time_signals_with_the_numbers_as_inputs() -> None:
    """``numbers="inputs"`` (one library per structure): the loads' part kept from the terms on the time symbol."""
    from ctmm.compiled_spatial import CompiledSpatialScene

    model = driven_chain()
    scene = CompiledSpatialScene(model, numbers="inputs")
    q, v = np.array([0.3, 0.9, 0.1, -0.3, 0.2]), np.array([0.5, 0.2, -0.4, 0.3])
    for t in (0.0, 0.7):
        expected = sp.accelerations(model, q, v, t)
        np.testing.assert_allclose(scene.accelerations(q, v, t=t), expected, rtol=0,
                                   atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("method", ["newmark", "houbolt"])
def test_generated_dt_tmm_scheme_with_time_signals_equals_the_numpy_scheme(method) -> None:
    """The generated Lie-group step (Newton in C) states the signals at its time symbol, as the numpy scheme."""
    model = driven_chain()
    v0 = {"ja.angle_rate": 0.5, "jc.wx": 0.3}
    generated = ctmm.simulate(model, 0.1, 1e-3, method=method, compiled=True, v0=v0)
    reference = ctmm.simulate(model, 0.1, 1e-3, method=method, v0=v0)
    assert generated.scheme_name == f"dt-tmm-generated/{method}"
    for name in model.coordinates + model.velocities:
        np.testing.assert_allclose(generated[name], reference[name], rtol=0, atol=1e-11)
    assert np.ptp(generated["jc.wx"]) > 1e-2


# ---------------------------------------------------------------- feedback loops with time signals
def signal_loops() -> list:
    """A real-time PD on the inboard hinge, a PD delayed two steps (dt = 10 ms) on a point of the inboard body and a
    rate loop on the ball joint: their sensors do not move with the driven joint."""
    from ctmm.control import Feedback

    return [Feedback("pd", [("ja.angle", 6.0), ("ja.rate", 0.8)], "ja.torque", gain=1.0, saturation=(-2.0, 2.0)),
            Feedback("late", [("a.tip.y", 3.0), ("a.tip.vy", 0.4)], "ja.torque", gain=1.0, delay=0.02),
            Feedback("ball", "jc.wx", "jc.torque_x", gain=0.3)]


def test_loop_acceleration_on_the_time_symbol_equals_pinocchio() -> None:
    """The closed-loop sweep of the generated loops (a torque on the inboard hinge as the input ``u``) at two
    times equals Pinocchio's with the driven acceleration moved to the right-hand side."""
    pin = pytest.importorskip("pinocchio")
    from ctmm.compiled_spatial_loops import loop_acceleration
    from ctmm.spatial.ports import SpatialPorts

    model = driven_chain(force=(0.0, 0.0, 0.0))
    acceleration = loop_acceleration(model, SpatialPorts(model), ["ja.torque"])
    q, v, torque = np.array([0.3, 0.9, 0.1, -0.3, 0.2]), np.array([0.5, 0.2, -0.4, 0.3]), 0.7
    for t in (0.0, 0.7):
        expected = pinocchio_accelerations(pin, model, q, v, t, torque)
        got = np.asarray(acceleration(q, v, [torque], np.zeros(0), t)).reshape(-1)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-10 * max(1.0, np.abs(expected).max()))


@pytest.mark.parametrize("method", ["rk4", "newmark", "houbolt"])
def test_generated_loops_with_time_signals_equal_the_python_path(method) -> None:
    """Loops closed in the generated RK4 / DT-TMM step of the driven, loaded chain: every state and loop signal
    equal to the Python path's (the same discretisation) to round-off."""
    from ctmm.control import with_feedback

    model = driven_chain()
    controlled = with_feedback(model, signal_loops())
    arguments = dict(method=method, v0={"ja.angle_rate": 0.5, "jc.wx": 0.3}, references={"pd": Step(0.2, 0.05)})
    generated = ctmm.simulate(controlled, 0.1, 0.01, compiled=True, **arguments)
    python = ctmm.simulate(controlled, 0.1, 0.01, **arguments)
    assert generated.info["method"] == ("rk4-generated" if method == "rk4" else f"dt-tmm-generated/{method}")
    np.testing.assert_array_equal(generated.time, python.time)
    names = list(model.coordinates + model.velocities) + [f"{loop}.{part}" for loop in ("pd", "late", "ball")
                                                     for part in ("y", "u")]
    for name in names:
        scale = max(1.0, float(np.max(np.abs(python[name]))))
        assert np.max(np.abs(generated[name] - python[name])) < 1e-11 * scale, name
    assert np.ptp(python["jc.wx"]) > 1e-2 and np.ptp(python["late.u"]) > 1e-3       # the load and loops acted


def test_rk4_loops_on_sensors_that_move_with_the_drive_equal_numpy() -> None:
    """Sensors outboard of the driven joint (a real-time loop on the tip's height, a loop delayed two steps on the
    ball's angular velocity about world z): the generated RK4 states them at the state and the time symbol, the
    delayed loop's sampled rate with ``dy/dt``; every loop signal and coordinate = the numpy RK4 to round-off.  The
    old kernel refused both sensors."""
    from ctmm.control import Feedback, with_feedback

    outboard = [Feedback("tip", "c.tip.z", "ja.torque", gain=1.0),
                Feedback("late", "c.omega_z", "jc.torque_x", gain=0.2, delay=0.002)]
    arguments = dict(v0={"ja.angle_rate": 0.5, "jc.wx": 0.3}, references={"tip": Ramp(0.3, -1.5)})
    controlled = with_feedback(driven_chain(), outboard)
    generated = ctmm.simulate(controlled, 0.1, 1e-3, method="rk4", compiled=True, **arguments)
    python = ctmm.simulate(controlled, 0.1, 1e-3, method="rk4", **arguments)
    assert generated.info["method"] == "rk4-generated"
    assert np.ptp(python["late.y"]) > 5e-4 and np.ptp(python["tip.u"]) > 1e-2
    for name in python.signals():
        scale = max(1.0, float(np.max(np.abs(python[name]))))
        assert np.max(np.abs(generated[name] - python[name])) <= 1e-12 * scale, name


@pytest.mark.parametrize("method", ["rk4", "newmark"])
def test_loops_on_sensors_that_move_with_the_drive_or_user_callables_are_refused_by_name(method) -> None:
    """The generated DT-TMM scheme loops state their sensors at the state only: a sensor that moves with the drive is
    refused by name (the RK4 takes it, above); user callables by both."""
    from ctmm.control import Feedback, with_feedback

    if method == "newmark":
        outboard = [Feedback("tip", "c.tip.z", "ja.torque", gain=1.0)]
        with pytest.raises(ModelError, match=r"sensor 'c.tip.z' moves with the time signals of the driven joints "
                                             r"'jb'"):
            ctmm.simulate(with_feedback(driven_chain(), outboard), 0.02, 0.01, method=method, compiled=True)
    with pytest.raises(ModelError, match=r"without a symbolic form in load 'push' \(force\[0\] is a UserFunction\)"):
        ctmm.simulate(with_feedback(driven_chain(force=(lambda t: t, 0.0, 0.0)), signal_loops()), 0.02, 0.01,
                      method=method, compiled=True)
    # with constant drives the same sensor is stated on symbols (it no longer moves with time)
    import casadi as ca

    from ctmm.compiled_spatial_loops import SpatialSymbols
    from ctmm.spatial.ports import SpatialPorts

    steady = driven_chain(position=0.4, rate=0.0, acceleration=0.0)
    symbols = SpatialSymbols(steady, SpatialPorts(steady))
    assert isinstance(symbols.sensor("c.tip.z", ca.SX.sym("q", 5), ca.SX.sym("v", 4)), ca.SX)


# ---------------------------------------------------------------- kinematic loops with load signals
def loaded_hinge():
    """A body on a free joint held at the ground by a revolute cut about world y (a compound pendulum), pushed at
    its tip by a step and a sine, and its consistent start."""
    from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

    tree = sp.SpatialModel("hinged", [
        sp.SpatialBody("p", 1.2, np.diag([0.02, 0.03, 0.025]), (0.1, 0.0, -0.3), {"tip": (0.2, 0.0, -0.6)}),
        sp.Free(name="free", parent=None, child="p"),
        sp.Load("push", "p", "tip", force=(Harmonic(3.0, 20.0), Step(1.0, 0.011), Step(-2.0, 0.005)))])
    loop = SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="hinge", parent=None, child="p", kind="revolute",
                                                            axis=(0, 1, 0))], baumgarte=20.0)
    return loop, loop.consistent_state({"free.qw": np.cos(0.25), "free.qy": np.sin(0.25), "free.x": 0.01},
                                       {"free.wy": 2.0}, keep=["free.wy"])


def test_kinematic_loops_with_load_signals_equal_the_numpy_runs() -> None:
    """The generated RK4 with projection and the generated Newmark step of a cut-joint model whose tree carries a
    load with time signals: equal to the numpy runs to round-off (states and cut loads)."""
    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
    from ctmm.compiled_spatial_loop_schemes import simulate_spatial_loop_scheme_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loop_scheme, simulate_spatial_loops
    from ctmm.spatial.closed_loops import SpatialKinematicLoopModel

    loop, (q, v) = loaded_hinge()
    runs = [(simulate_spatial_kinematic_loops_generated(loop, q, v, t_final=0.02, dt=1e-3),
             simulate_spatial_loops(loop, q, v, t_final=0.02, dt=1e-3))]
    runs.append(tuple(run[0] for run in (
        simulate_spatial_loop_scheme_generated(loop, q, v, t_final=0.02, dt=1e-3, scheme="newmark"),
        simulate_spatial_loop_scheme(loop, q, v, t_final=0.02, dt=1e-3, scheme="newmark"))))
    bare = SpatialKinematicLoopModel(sp.SpatialModel("bare", list(loop.tree.bodies) + list(loop.tree.joints)),
                                     loop.cuts, baumgarte=20.0)
    unloaded = simulate_spatial_loops(bare, q, v, t_final=0.02, dt=1e-3)
    for generated, numpy_run in runs:
        np.testing.assert_array_equal(generated.t, numpy_run.t)
        assert np.max(np.abs(generated.q - numpy_run.q)) <= 1e-12 and np.max(np.abs(generated.v - numpy_run.v)) <= 1e-12
        scale = max(1.0, np.max(np.abs(numpy_run.cut_force)))
        assert np.max(np.abs(generated.cut_force - numpy_run.cut_force)) <= 1e-12 * scale
        assert np.max(np.abs(generated.v - unloaded.v)) > 1e-3               # the load acted


def test_kinematic_loops_refuse_load_callables_by_name() -> None:
    from ctmm.compiled_spatial_kinematic_loops import spatial_kinematic_loop_compile_refusal
    from ctmm.spatial.closed_loops import SpatialKinematicLoopModel

    loop, _ = loaded_hinge()
    tree = sp.SpatialModel("hinged", list(loop.tree.bodies) + list(loop.tree.joints) + [
        sp.Load("user", "p", "tip", force=(lambda t: t, 0.0, 0.0))])
    reason = spatial_kinematic_loop_compile_refusal(SpatialKinematicLoopModel(tree, loop.cuts))
    assert "without a symbolic form in load 'user' (force[0] is a UserFunction)" in reason
    assert spatial_kinematic_loop_compile_refusal(loop) == ""


# ---------------------------------------------------------------- exported FMUs with time signals
def test_an_exported_fmu_follows_the_time_signals_as_the_numpy_rk4(tmp_path, monkeypatch) -> None:
    """The FMU of the driven, loaded chain (its RK4 step at the FMU's time; outputs outboard of the driven joint at
    that time): coordinates, velocities and body positions equal to the numpy RK4 to round-off."""
    import shutil

    fmpy = pytest.importorskip("fmpy")
    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path / "cache"))
    model = driven_chain()
    v0 = {"ja.angle_rate": 0.5, "jc.wx": 0.3}
    outputs = ["ja.angle", "jc.qx", "jc.wx", "c.position_x", "c.position_y", "b.omega_z"]
    path = ctmm.export_fmu(model, tmp_path / "driven.fmu", step=1e-3, inputs=[], outputs=outputs, qdot0=v0)
    out = fmpy.simulate_fmu(str(path), stop_time=0.05, output_interval=0.01)
    reference = ctmm.simulate(model, 0.05, 1e-3, method="rk4", v0=v0, store_every=10)
    np.testing.assert_allclose(out["time"], reference.time, rtol=0, atol=1e-12)
    for name in outputs:
        np.testing.assert_allclose(out[name], reference[name], rtol=0, atol=1e-12, err_msg=name)
    assert np.ptp(out["c.position_x"]) > 1e-2                  # the drive moved it


def test_a_feedback_loop_on_a_kinematic_loop_model_with_load_signals_equals_the_numpy_driver() -> None:
    """A PD on the revolute cut of the pushed pendulum, closed in the generated RK4 (the loop driver's kernel,
    :mod:`ctmm.compiled_kinematic_loop_control`): every state and loop signal equal to the numpy driver's."""
    from ctmm.control import Feedback, with_feedback

    loop, (q, v) = loaded_hinge()
    pd = Feedback("pd", sensor=[("hinge.angle", 4.0), ("hinge.rate", 0.5)], actuator="hinge.torque", gain=1.0)
    options = dict(x0=q, v0=v, outputs=["hinge.angle"])
    generated = ctmm.simulate(with_feedback(loop, [pd]), 0.02, 1e-3, compiled=True, **options)
    python = ctmm.simulate(with_feedback(loop, [pd]), 0.02, 1e-3, **options)
    np.testing.assert_array_equal(generated.time, python.time)
    for name in list(loop.tree.coordinates) + list(loop.tree.velocities) + ["hinge.angle", "pd.u"]:
        scale = max(1.0, float(np.max(np.abs(python[name]))))
        assert np.max(np.abs(generated[name] - python[name])) <= 1e-12 * scale, name
    assert np.ptp(python["pd.u"]) > 1e-3


@pytest.mark.parametrize("method", ["rk4", "newmark"])
def test_open_loop_signal_inputs_run_generated_without_loops(method) -> None:
    """A joint torque that is a ctmm.signals function of time and no loop: ``compiled=True`` runs it in generated
    code (the step with loops, none here, states it on the time symbol; it refused it as "held numbers").  A yaw
    joint about gravity's axis: ``J theta'' = A sin(w t)``, ``theta = A / (J w^2) (w t - sin(w t))`` with
    ``J = I_zz + m d^2``; the numpy run to round-off.  A Python callable stays refused by name."""
    model = sp.SpatialModel("yaw", [
        sp.SpatialBody("link", 1.0, (0.01, 0.02, 0.02), center_of_mass=(0.3, 0.0, 0.0), points={"tip": (0.6, 0, 0)}),
        sp.Revolute(name="yaw", parent=None, child="link", axis=(0, 0, 1), actuated=True)], gravity=(0, 0, -9.81))
    amplitude, omega, dt = 0.5, 3.0, 1e-3
    inputs = {"yaw.torque": Harmonic(amplitude, omega)}
    generated = ctmm.simulate(model, t_final=0.5, dt=dt, method=method, inputs=inputs, compiled=True)
    numpy_run = ctmm.simulate(model, t_final=0.5, dt=dt, method=method, inputs=inputs, compiled=False)
    t, inertia = generated.time, 0.02 + 1.0 * 0.3 ** 2
    exact = amplitude / (inertia * omega ** 2) * (omega * t - np.sin(omega * t))
    # RK4: to round-off of the quadrature of a sine (1e-11); Newmark, second order: (omega dt)^2 of the angle
    bound = 1e-11 if method == "rk4" else (omega * dt) ** 2
    assert np.max(np.abs(generated["yaw.angle"] - exact)) <= bound * np.max(exact)
    assert np.max(np.abs(generated["yaw.angle"] - numpy_run["yaw.angle"])) <= 1e-14
    with pytest.raises(ModelError, match="Python callable of time"):
        ctmm.simulate(model, t_final=0.1, dt=dt, method=method, inputs={"yaw.torque": lambda t: t}, compiled=True)
