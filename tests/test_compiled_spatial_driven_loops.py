"""Spatial kinematic loops whose tree has driven joints, in generated C (issue 13).

The generated RK4 with projection (:mod:`ctmm.compiled_spatial_kinematic_loops`) and the generated DT-TMM steps
(:mod:`ctmm.compiled_spatial_loop_schemes`) state the driven joints' signals on the time symbol; ``Phi''`` takes the
prescribed motion's rate and acceleration along the driven coordinates.  Checked against the numpy runs (equal to
round-off) and, independently, against the closed-form kinematics of a spatial slider-crank whose crank is driven at a
prescribed angle (the slide and its rate) and Lagrange's equation of the pendulum it carries.  User callables on the
drive are refused by name.  The loop driver's generated run (feedback loops on the driven tree) reads its sensors at
the state and the time: equal to the numpy driver to round-off, a delayed loop's sampled sensor rate with ``dy/dt``.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from ctmm.signals import Harmonic, Ramp
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

# crank radius, coupler length, the guide's offsets from the crank's axis [m]; the crank angle A sin(W t + PHASE)
RADIUS, LENGTH, OFFSET_Y, OFFSET_Z = 0.1, 0.3, 0.05, 0.08
AMPLITUDE, FREQUENCY, PHASE = 0.8, 3.0, 0.3


def _rod(name: str, mass: float, length: float, direction: int = 0, sign: float = 1.0) -> sp.SpatialBody:
    """A slender rod of ``length`` [m] along body axis ``direction`` (``sign``: which way), point ``"tip"`` at its
    end."""
    moments = np.full(3, mass * (length ** 2 + 0.02 ** 2) / 12.0)
    moments[direction] = mass * 2 * 0.02 ** 2 / 12.0
    tip = np.eye(3)[direction] * length * sign
    return sp.SpatialBody(name, mass, np.diag(moments), center_of_mass=tip / 2, points={"tip": tip})


def slider_crank(position=None, bob_actuated: bool = False, rate=None, acceleration=None) -> SpatialKinematicLoopModel:
    """A spatial R-U-S-P slider-crank: the crank (``h1`` about world z, driven), the coupler on a universal joint at
    the crank's tip, the slider on a prismatic guide along world x offset by ``(OFFSET_Y, OFFSET_Z)`` from the
    crank's axis, a spherical cut closing the coupler's tip on the slider; a pendulum ``bob`` hinged on the slider
    (the loop's one degree of freedom, under gravity)."""
    position = Harmonic(AMPLITUDE, FREQUENCY, PHASE) if position is None else position
    rate = Harmonic(AMPLITUDE * FREQUENCY, FREQUENCY, PHASE + np.pi / 2) if rate is None else rate
    acceleration = Harmonic(-AMPLITUDE * FREQUENCY ** 2, FREQUENCY, PHASE) if acceleration is None else acceleration
    crank = sp.Revolute(name="h1", parent=None, child="crank", axis=(0, 0, 1), position=position, rate=rate,
                        acceleration=acceleration)
    tree = sp.SpatialModel("slider_crank", [
        _rod("crank", 0.3, RADIUS), crank,
        _rod("coupler", 0.5, LENGTH),
        sp.Universal(name="u2", parent="crank", point="tip", child="coupler", axis1=(0, 0, 1), axis2=(0, 1, 0)),
        sp.SpatialBody("slider", 1.0, np.diag([1e-3, 1e-3, 1e-3]), points={"pin": np.zeros(3)}),
        sp.Prismatic(name="p3", parent=None, point=(0.0, OFFSET_Y, OFFSET_Z), child="slider", axis=(1, 0, 0)),
        _rod("bob", 0.2, 0.15, direction=2, sign=-1.0),
        sp.Revolute(name="h5", parent="slider", point="pin", child="bob", axis=(0, 1, 0), actuated=bob_actuated)],
        gravity=(0, 0, -9.81))
    cut = SpatialCutJoint(name="s4", parent="slider", point="pin", child="coupler", child_point="tip")
    return SpatialKinematicLoopModel(tree, [cut], baumgarte=20.0)


def start(loop: SpatialKinematicLoopModel) -> tuple[np.ndarray, np.ndarray]:
    """The assembled start at t = 0: the pendulum at 0.3 rad and at rest."""
    return loop.consistent_state({"p3.position": 0.3, "u2.angle1": -0.2, "u2.angle2": -0.2, "h5.angle": 0.3}, None,
                                 keep=["h5"])


def closed_form_slide(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The slide ``x`` [m] and its rate [m/s] of the slider-crank at times ``t`` [s]: the coupler's length between
    the crank's tip ``(r cos th, r sin th, 0)`` and the pin ``(x, e_y, e_z)``,
    ``x = r cos th + sqrt(l^2 - (e_y - r sin th)^2 - e_z^2)``."""
    angle = AMPLITUDE * np.sin(FREQUENCY * t + PHASE)
    rate = AMPLITUDE * FREQUENCY * np.cos(FREQUENCY * t + PHASE)
    root = np.sqrt(LENGTH ** 2 - (OFFSET_Y - RADIUS * np.sin(angle)) ** 2 - OFFSET_Z ** 2)
    slide = RADIUS * np.cos(angle) + root
    slide_rate = (-RADIUS * np.sin(angle) + (OFFSET_Y - RADIUS * np.sin(angle)) * RADIUS * np.cos(angle) / root) * rate
    return slide, slide_rate


def pendulum_on_the_slide(t: np.ndarray, angle: float) -> np.ndarray:
    """The bob's angle [rad] at times ``t`` [s] from ``angle`` at rest at t = 0 (Lagrange, its pivot moving along x
    by the closed-form slide): ``(I_c + m c^2) th'' = m c (x'' cos th - g sin th)``, ``x''`` by the complex step of the
    closed-form rate; DOP853 at 1e-12."""
    from scipy.integrate import solve_ivp

    mass, half, gravity = 0.2, 0.075, 9.81
    inertia = mass * (0.15 ** 2 + 0.02 ** 2) / 12.0 + mass * half ** 2

    def rate(time: float, y: np.ndarray) -> list:
        slide_acceleration = closed_form_slide(time + 1e-20j)[1].imag / 1e-20
        return [y[1], mass * half * (slide_acceleration * np.cos(y[0]) - gravity * np.sin(y[0])) / inertia]

    return solve_ivp(rate, (0.0, t[-1]), [angle, 0.0], t_eval=t, method="DOP853", rtol=1e-12, atol=1e-12).y[0]


def _equal(generated, numpy_run, rows: int | None = None) -> None:
    """States to 1e-12, cut forces to 1e-12 relative, the same times (``rows``: the generated run's first rows, the
    whole numpy run)."""
    rows = len(generated.t) if rows is None else rows
    assert len(numpy_run.t) == rows
    np.testing.assert_array_equal(generated.t[:rows], numpy_run.t)
    assert np.max(np.abs(generated.q[:rows] - numpy_run.q)) <= 1e-12
    assert np.max(np.abs(generated.v[:rows] - numpy_run.v)) <= 1e-12
    scale = max(1.0, np.max(np.abs(numpy_run.cut_force)))
    assert np.max(np.abs(generated.cut_force[:rows] - numpy_run.cut_force)) <= 1e-12 * scale


def test_driven_slider_crank_rk4_equals_numpy_and_the_closed_form_kinematics():
    """The generated RK4 with projection = the numpy RK4 to round-off (its first 40 steps: the same step every
    time, the numpy run 0.08 s); the slide and its rate = the closed form
    (bound 1e-12; the projection holds the cut to 1e-14); the pendulum on the slider = Lagrange's pendulum on a pivot
    moving by the closed-form slide (bound 1e-8 rad at dt = 2 ms, and falling at fourth order with dt)."""
    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loops

    loop = slider_crank()
    q, v = start(loop)
    generated = simulate_spatial_kinematic_loops_generated(loop, q, v, t_final=0.3, dt=2e-3)
    _equal(generated, simulate_spatial_loops(loop, q, v, t_final=0.08, dt=2e-3), rows=41)
    slide, slide_rate = closed_form_slide(generated.t)
    assert np.max(np.abs(generated.q[:, 0] - slide)) < 1e-12
    assert np.max(np.abs(generated.v[:, 0] - slide_rate)) < 1e-12
    assert np.ptp(slide) > 0.01 and np.ptp(generated.q[:, 3]) > 0.01          # the slider and the pendulum moved
    assert generated.drift.max() < 1e-12 and generated.drift_rate.max() < 1e-12
    error = np.max(np.abs(generated.q[:, 3] - pendulum_on_the_slide(generated.t, 0.3)))
    finer = simulate_spatial_kinematic_loops_generated(loop, q, v, t_final=0.3, dt=1e-3)
    finer_error = np.max(np.abs(finer.q[:, 3] - pendulum_on_the_slide(finer.t, 0.3)))
    assert error < 1e-8 and error / finer_error > 12.0          # RK4's fourth order (measured 3.3e-9, 2.0e-10 rad)


@pytest.mark.parametrize("scheme", ["newmark", "generalized_alpha"])
def test_driven_slider_crank_schemes_equal_numpy(scheme):
    """The generated DT-TMM step with projection = the numpy scheme to round-off, the slide = the closed form."""
    from ctmm.compiled_spatial_loop_schemes import simulate_spatial_loop_scheme_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loop_scheme

    loop = slider_crank()
    q, v = start(loop)
    generated, info = simulate_spatial_loop_scheme_generated(loop, q, v, t_final=0.04, dt=2e-3, scheme=scheme)
    _equal(generated, simulate_spatial_loop_scheme(loop, q, v, t_final=0.04, dt=2e-3, scheme=scheme)[0])
    assert np.max(np.abs(generated.q[:, 0] - closed_form_slide(generated.t)[0])) < 1e-12
    assert info["max_drift_after_projection"] < 1e-12


def test_simulate_verb_with_compiled_true_takes_the_driven_tree():
    """``ctmm.simulate(..., compiled=True)``: every named signal = the numpy run's to round-off."""
    loop = slider_crank()
    q, v = start(loop)
    generated = ctmm.simulate(loop, 0.04, 2e-3, x0=q, v0=v, compiled=True)
    plain = ctmm.simulate(loop, 0.04, 2e-3, x0=q, v0=v)
    assert generated.info["compiled"] is True
    for name in plain.signals():
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-12 * max(1.0, np.max(np.abs(plain[name]))), name


def test_held_crank_of_the_four_bar_equals_numpy():
    """The R-U-S-R four-bar with its crank held at a constant angle by a driven joint (no signal in time): the
    generated RK4 = the numpy RK4 (the crank's position enters the cut only through the drive)."""
    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
    from ctmm.scenarios.spatial_four_bar import DOWN, mechanism
    from ctmm.spatial.closed_loop_time import simulate_spatial_loops

    loop = mechanism()
    joints = {joint.name: joint for joint in loop.tree.joints}
    held = sp.Revolute(name="h1", parent=None, child="crank", axis=(1, 0, 0), rotation=DOWN, position=0.1, rate=0.0,
                       acceleration=0.0)
    driven = SpatialKinematicLoopModel(sp.SpatialModel("driven", [*loop.tree.bodies, held, joints["u2"],
                                                                   joints["h4"]]), loop.cuts)
    q, v = driven.consistent_state({"h4.angle": 0.1, "u2.angle1": -0.32, "u2.angle2": -0.41}, None)
    _equal(simulate_spatial_kinematic_loops_generated(driven, q, v, t_final=0.02, dt=1e-3),
           simulate_spatial_loops(driven, q, v, t_final=0.02, dt=1e-3))


def test_user_callable_drives_are_refused_by_name():
    """A drive given as a Python callable has no symbolic form: refused, naming the joint."""
    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated

    user = slider_crank(position=lambda t: AMPLITUDE * np.sin(FREQUENCY * t + PHASE))
    q, v = start(user)
    with pytest.raises(ModelError, match=r"driven joint 'h1' \(position\[0\] is a UserFunction\)"):
        simulate_spatial_kinematic_loops_generated(user, q, v, t_final=0.01, dt=1e-3)
    with pytest.raises(ModelError, match=r"driven joint 'h1' \(position\[0\] is a UserFunction\)"):
        ctmm.simulate(user, 0.01, 1e-3, x0=q, v0=v, method="newmark", compiled=True)
    loop = slider_crank(position=lambda t: AMPLITUDE * np.sin(FREQUENCY * t + PHASE), bob_actuated=True)
    damper = Feedback("damper", sensor="h5.angle_rate", actuator="h5.torque", gain=-0.1)
    with pytest.raises(ModelError, match=r"driven joint 'h1' \(position\[0\] is a UserFunction\)"):
        ctmm.simulate(with_feedback(loop, [damper]), 0.01, 1e-3, x0=q, v0=v, compiled=True)


@pytest.mark.parametrize("drive", ["harmonic", "ramp"])
def test_loops_on_the_driven_slider_crank_generated_equal_the_numpy_driver(drive):
    """A PD on the pendulum (its reference a ramp), a loop delayed two steps on the coupler's angular velocity and
    one on the crank's tip (both move with the drive: sensors of the state and the time): every signal of the
    generated run = the numpy loop driver's to round-off.  Without ``dy/dt`` in the delayed loop's sampled rate the
    runs differ by 3e-8 rad (measured); the old kernel refused the driven tree."""
    position = None if drive == "harmonic" else Ramp(FREQUENCY, 0.2)
    extra = {} if drive == "harmonic" else {"rate": FREQUENCY, "acceleration": 0.0}
    loop = slider_crank(position=position, bob_actuated=True, **extra)
    q, v = start(loop)
    loops = [Feedback("p", sensor="h5.angle", actuator="h5.torque", gain=0.5),
             Feedback("d", sensor="h5.angle_rate", actuator="h5.torque", gain=0.02),
             Feedback("late", sensor="coupler.omega_z", actuator="h5.torque", gain=0.003, delay=4e-3),
             Feedback("tip", sensor="crank.tip.y", actuator="h5.torque", gain=0.2)]
    options = dict(x0=q, v0=v, references={"p": Ramp(0.5)})
    generated = ctmm.simulate(with_feedback(loop, loops), 0.1, 2e-3, compiled=True, **options)
    plain = ctmm.simulate(with_feedback(loop, loops), 0.1, 2e-3, compiled=False, **options)
    assert generated.info["method"] == "rk4-generated" and plain.info["method"] == "rk4"
    assert np.ptp(plain["h5.angle"]) > 0.1 and np.ptp(plain["late.y"]) > 0.1 and np.ptp(plain["tip.u"]) > 1e-3
    for name in plain.signals():
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-12 * max(1.0, np.max(np.abs(plain[name]))), name


def test_a_co_simulated_controller_on_the_driven_slider_crank_equals_the_numpy_driver():
    """A static-gain controller sampled every 2 ms on the pendulum (zero-order hold) beside a loop on the crank's tip
    (it moves with the drive): one call into C per sample interval, every stored signal = the numpy driver's (the old
    kernel refused the driven tree)."""
    from ctmm.control.planar_time import simulate_closed_loop
    from ctmm.control.static_gain import StaticGainController

    loop = slider_crank(bob_actuated=True)
    q, v = start(loop)
    tip = [Feedback("tip", sensor="crank.tip.y", actuator="h5.torque", gain=0.2)]
    controller = StaticGainController(["h5.angle", "h5.angle_rate"], ["h5.torque"], [[-0.5, -0.02]], sample_time=2e-3)
    generated = ctmm.simulate(with_feedback(loop, tip), 0.06, 1e-3, x0=q, v0=v, compiled=True,
                              controllers=[controller])
    plain = simulate_closed_loop(loop, q, v, 0.06, 1e-3, loops=tuple(tip), controllers=[controller])
    assert generated.info["intervals"] == 30
    assert np.ptp(plain["h5.torque@samples"][:, 1]) > 1e-3
    for name in plain.signals():
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-12 * max(1.0, np.max(np.abs(plain[name]))), name
