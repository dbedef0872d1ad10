"""Cut joints with moment laws, torques and drives in the generated RK4 of kinematic loops (issues 13 x 16).

The generated step states the cut's moment (``tau = torque(t) - law(dtheta - rest, dtheta')`` as a moment pair, or a
driven cut's row ``dtheta = angle(t)`` with its moment an unknown) on symbols, as
:meth:`KinematicLoopModel.solve` does in numpy: the two agree to round-off (<= 1e-12).  Independent reference: the
global DAE of :mod:`ctmm.reference.planar_dae` with the law on its own cut revolute, the torque as its motor and the
drive as its own row (``tests/test_cut_joint_laws.py``'s models and bounds).  Signals must have a symbolic form and
laws must be casadi-expressible; other ones are refused by name.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from test_cut_joint_laws import BODIES, REST, SPRING_DAMPER, _dae, _loop, _start

import ctmm
from ctmm.compiled_kinematic_loops import simulate_kinematic_loops_generated
from ctmm.errors import ModelError
from ctmm.nonlinear_laws import CallableLaw, CubicSpring, LinearLaw
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel, simulate_kinematic_loops
from ctmm.scenarios.four_bar import reference as four_bar_dae
from ctmm.signals import Harmonic

TORQUE = Harmonic(0.3, 7.0)                                  # 0.3 sin(7 t) [N m]
DRIVE = {"angle": Harmonic(REST, 3.0, math.pi / 2),          # REST cos(3 t) [rad] and its derivatives
         "angle_rate": Harmonic(3.0 * REST, 3.0, math.pi),
         "angle_acceleration": Harmonic(-9.0 * REST, 3.0, math.pi / 2)}


def _same(generated, numpy_run) -> None:
    np.testing.assert_array_equal(generated.t, numpy_run.t)
    assert np.max(np.abs(generated.q - numpy_run.q)) <= 1e-12
    assert np.max(np.abs(generated.qdot - numpy_run.qdot)) <= 1e-12 * np.max(np.abs(numpy_run.qdot))
    assert np.max(np.abs(generated.cut_force - numpy_run.cut_force)) <= 1e-12 * np.max(np.abs(numpy_run.cut_force))


@pytest.mark.parametrize("law", [SPRING_DAMPER, CubicSpring(3.0, 20.0)], ids=["linear", "cubic"])
def test_cut_law_and_torque_equal_the_numpy_path_and_match_the_dae(law):
    """Measured: generated = numpy to 4e-16 rad/s; vs the DAE 3e-10 rad (the numpy path's bound 3e-9)."""
    loop = _loop(law, TORQUE)
    q0, v0 = _start(loop)
    generated = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.2, dt=1e-3)
    _same(generated, simulate_kinematic_loops(loop, q0, v0, t_final=0.2, dt=1e-3))
    dae = _dae(law, TORQUE)
    reference = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.2, t_eval=generated.t)
    assert max(np.max(np.abs(generated.coordinate(f"{n}.theta") - reference.angle(n))) for n in BODIES) < 3e-9
    force = reference.forces[:, 3, :]
    assert np.max(np.abs(generated.cut_force[:, 0] - force)) < 1e-8 * np.max(np.abs(force))
    smooth = simulate_kinematic_loops_generated(_loop(None), q0, v0, t_final=0.2, dt=1e-3)
    assert np.max(np.abs(smooth.q - generated.q)) > 1e-2                     # the law and torque matter


def test_driven_cut_equals_the_numpy_path_and_matches_the_dae():
    """The relative angle at the cut prescribed (0 DOF): motion, cut force and drive moment (``"h3.moment"`` of the
    verb) against the DAE with its own drive row; measured 1e-13 rad as the numpy path."""
    loop = KinematicLoopModel(_loop(None).tree, [CutJoint("h3", parent="rocker.out", child="coupler.out", **DRIVE)])
    q0, v0 = loop.consistent_state([math.pi / 2, 0.5, 1.8], [0.0, 0.0, 0.0])
    generated = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.15, dt=1e-3)
    _same(generated, simulate_kinematic_loops(loop, q0, v0, t_final=0.15, dt=1e-3))
    assert np.max(generated.drift) < 1e-12 and np.ptp(generated.coordinate("crank.theta")) > 0.1
    run = ctmm.simulate(loop, 0.15, 1e-3, x0=q0, v0=v0, compiled=True)
    assert run.info["compiled"] is True
    dae = four_bar_dae(None)
    dae.add_drive("rocker", "coupler", DRIVE["angle"], DRIVE["angle_rate"], DRIVE["angle_acceleration"])
    reference = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.15, t_eval=run.time)
    assert max(np.max(np.abs(run[f"{n}.theta"] - reference.angle(n))) for n in BODIES) < 1e-10
    assert np.max(np.abs(run["h3.force_y"] - reference.forces[:, 3, 1])) < 1e-9 * np.max(np.abs(reference.forces))
    moment = reference.drive_moments[:, 0]
    assert np.max(np.abs(run["h3.moment"] - moment)) < 1e-9 * np.max(np.abs(moment)) and np.ptp(moment) > 0.1


def test_signals_and_laws_without_a_symbolic_form_are_refused_by_name():
    user_law = CallableLaw(lambda d, r: 3.0 * d, stiffness=lambda d, r: 3.0, damping=lambda d, r: 0.0)
    driven = KinematicLoopModel(_loop(None).tree, [CutJoint("h3", parent="rocker.out", child="coupler.out",
                                                            **dict(DRIVE, angle=lambda t: REST * math.cos(3.0 * t)))])
    cases = [(_loop(None, lambda t: 0.3 * math.sin(7.0 * t)), "its torque .* has no symbolic form"),
             (_loop(user_law), "its moment_law .* is not expressible with casadi"),
             (driven, "its angle .* has no symbolic form")]
    for loop, message in cases:
        q0, v0 = (loop.consistent_state([math.pi / 2, 0.5, 1.8], [0.0, 0.0, 0.0]) if loop is driven else
                  _start(loop))
        with pytest.raises(ModelError, match="cut joint 'h3': " + message + ".*compiled=None"):
            ctmm.simulate(loop, 0.01, 1e-3, x0=q0, v0=v0, compiled=True)
    traced = CallableLaw(lambda d, r: 3.0 * d + 0.05 * r)        # casadi-compatible: traced, not refused
    loop = _loop(traced, TORQUE)
    q0, v0 = _start(loop)
    _same(simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.02, dt=1e-3),
          simulate_kinematic_loops(loop, q0, v0, t_final=0.02, dt=1e-3))


# -- spatial revolute and prismatic cuts (ctmm.compiled_spatial_kinematic_loops) ----------------------------------
def _spatial_same(generated, numpy_run) -> None:
    np.testing.assert_array_equal(generated.t, numpy_run.t)
    assert np.max(np.abs(generated.q - numpy_run.q)) <= 1e-12 and np.max(np.abs(generated.v - numpy_run.v)) <= 1e-12
    scale = max(1.0, np.abs(numpy_run.cut_force).max(), np.abs(numpy_run.cut_moment).max())
    for name in ("cut_force", "cut_moment"):
        assert np.max(np.abs(getattr(generated, name) - getattr(numpy_run, name))) <= 1e-12 * scale, name


def _spatial_runs(loop, q, v, t_final, dt):
    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loops

    generated = simulate_spatial_kinematic_loops_generated(loop, q, v, t_final=t_final, dt=dt)
    assert generated.method == "rk4-generated" and generated.drift.max() < 1e-12
    _spatial_same(generated, simulate_spatial_loops(loop, q, v, t_final=t_final, dt=dt))
    return generated


def test_spatial_revolute_cut_law_and_actuation_match_the_pendulum_equation():
    """``I_O s'' = m g (x_C cos s - z_C sin s) + u(t) - law(s - rest, s')`` (tests/test_spatial_cut_joint_laws.py's
    reference and bound); measured generated = numpy to 1e-13 N, 8e-16 rad/s."""
    from test_spatial_cut_joint_laws import _pendulum, _pendulum_reference
    from test_spatial_cut_joint_laws import _start as pendulum_start

    law = LinearLaw(2.0, 0.1)
    loop = _pendulum(law, 0.2, Harmonic(0.3, 5.0))
    q, v = pendulum_start(loop)
    run = _spatial_runs(loop, q, v, 0.2, 2e-3)
    angle = np.array([loop.cut_coordinates(qk, vk)[0][0] for qk, vk in zip(run.q, run.v)])
    reference = _pendulum_reference(law, 0.2, Harmonic(0.3, 5.0), 0.5, 2.0, run.t)
    assert np.max(np.abs(angle - reference)) < 1e-8
    assert np.max(np.abs(_pendulum_reference(LinearLaw(0.0, 0.0), 0.2, None, 0.5, 2.0, run.t) - reference)) > 1e-2


def test_spatial_prismatic_cut_law_between_two_moving_bodies_matches_the_dae():
    """A sleeve on a swinging arm, the slide a prismatic cut with a spring-damper and an actuation (both sides move:
    the parent's reaction at the child point counts); against the spatial Newton-Euler DAE with the law written on
    its own state (tests/test_spatial_cut_joint_laws.py's model and bound 1e-8)."""
    from dataclasses import replace

    from test_spatial_cut_joint_laws import _dae_law_loads, _rod

    import ctmm.spatial as sp
    from ctmm.scenarios.spatial_four_bar import dae_of, poses
    from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

    law = LinearLaw(40.0, 0.3)
    arm = _rod("arm", 0.8, 0.6)
    other = sp.SpatialBody("link", 0.3, np.diag([0.003, 0.002, 0.001]), center_of_mass=(0.02, 0.0, 0.0))
    cut = SpatialCutJoint(name="c", parent="arm", point="origin", child="link", kind="prismatic", axis=(0, 0, 1),
                          normal=(1, 0, 0), parent_normal=(1, 0, 0), law=law, rest=-0.2, actuation=Harmonic(0.3, 5.0))
    tree = sp.SpatialModel("two_moving", [arm, sp.Revolute(name="h1", parent=None, child="arm", axis=(1, 0, 0)),
                                          other, sp.Free(name="free", parent=None, child="link")])
    loop = SpatialKinematicLoopModel(tree, [cut])
    q, v = loop.consistent_state({"h1.angle": 0.4, "free.z": -0.3}, {"h1.angle_rate": 1.5}, keep=["h1"])
    run = _spatial_runs(loop, q, v, 0.2, 2e-3)
    dae = dae_of(loop, 10.0)
    dae.joints[-1] = replace(dae.joints[-1], child_normal=np.asarray(cut.normal),
                             parent_normal=np.asarray(cut.parent_normal))
    points = (arm.points[cut.point] - arm.center_of_mass, other.points[cut.child_point] - other.center_of_mass)
    _, Y = dae.simulate(dae.state(*poses(loop, run.q[0], run.v[0])), run.t,
                        torques=lambda t, y: _dae_law_loads(dae, y, cut, 0, 1, *points, law, t))
    angle = position = 0.0
    for k in range(len(run.t)):
        x, R, _, _ = poses(loop, run.q[k], run.v[k])
        angle = max(angle, max(np.abs(a - b).max() for a, b in zip(R, dae.rotations(Y[k]))))
        position = max(position, max(np.abs(a - b).max() for a, b in zip(x, dae.split(Y[k])[0])))
    assert angle < 1e-8 and position < 1e-8
    slide = np.array([loop.cut_coordinates(qk, vk)[0][0] for qk, vk in zip(run.q, run.v)])
    assert np.ptp(slide) > 0.01


@pytest.mark.parametrize("kind", ["revolute", "prismatic"])
def test_spatial_driven_cuts_carry_the_load_of_the_one_coordinate_equation(kind):
    """Revolute: the pendulum's hinge angle ``0.5 cos 4t`` prescribed, the drive moment ``I_O s'' - m g (x_C cos s +
    z_C sin s)``; prismatic: the slide ``0.05 cos 5t`` along the guide, the guide force ``m s'' + m g a_z``
    (tests/test_spatial_cut_joint_laws.py's references and bounds)."""
    from test_spatial_cut_joint_laws import COM, GUIDE, I_HINGE, MASS, _pendulum, _slider

    from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

    if kind == "revolute":
        amplitude, omega = 0.5, 4.0
        tree, extra = _pendulum(None).tree, {"axis": (0, 1, 0)}
        start = ({"free.qw": math.cos(0.25), "free.qy": math.sin(0.25)}, {})
    else:
        amplitude, omega = 0.05, 5.0
        tree, extra = _slider(None).tree, {"axis": tuple(GUIDE)}
        start = ({"free.y": 0.03, "free.z": 0.04}, {})
    drive = {"position": Harmonic(amplitude, omega, math.pi / 2), "rate": Harmonic(amplitude * omega, omega, math.pi),
             "acceleration": Harmonic(-amplitude * omega ** 2, omega, math.pi / 2)}
    name = "hinge" if kind == "revolute" else "guide"
    loop = SpatialKinematicLoopModel(tree, [SpatialCutJoint(name=name, parent=None, child="p", kind=kind, **extra,
                                                            **drive)])
    q, v = loop.consistent_state(*start)
    run = _spatial_runs(loop, q, v, 0.1, 2e-3)
    s = np.array([loop.cut_coordinates(qk, vk)[0][0] for qk, vk in zip(run.q, run.v)])
    assert np.max(np.abs(s - amplitude * np.cos(omega * run.t))) < 1e-10
    s_ddot = -amplitude * omega ** 2 * np.cos(omega * run.t)
    if kind == "revolute":
        expected = I_HINGE * s_ddot - MASS * 9.81 * (COM[0] * np.cos(s) + COM[2] * np.sin(s))
        load = run.cut_moment[:, 0, 1]
    else:
        expected, load = MASS * s_ddot + MASS * 9.81 * GUIDE[2], run.cut_force[:, 0] @ GUIDE
    assert np.max(np.abs(load - expected)) < 1e-9 * np.max(np.abs(expected)) and np.ptp(s) > 0.05 * amplitude


def test_spatial_signals_and_laws_without_a_symbolic_form_are_refused_by_name():
    from test_spatial_cut_joint_laws import _pendulum
    from test_spatial_cut_joint_laws import _start as pendulum_start

    user_law = CallableLaw(lambda d, r: 3.0 * d, stiffness=lambda d, r: 3.0, damping=lambda d, r: 0.0)
    for loop, message in [(_pendulum(LinearLaw(2.0), 0.2, lambda t: 0.3 * math.sin(5.0 * t)), "its actuation"),
                          (_pendulum(user_law), "its law .* is not expressible with casadi")]:
        q, v = pendulum_start(loop)
        with pytest.raises(ModelError, match="cut joint 'hinge': " + message + ".*compiled=None"):
            ctmm.simulate(loop, 0.01, 1e-3, x0=q, v0=v, compiled=True)
