"""Spatial cut joints carrying a law and an actuation on their free coordinate (ctmm.spatial.closed_loop_cuts,
docs/closed_loops.md §8.1a): the angle about a revolute cut's axis, the slide along a prismatic cut's guide.

Independent references: the one-coordinate equations of motion of the mechanisms, written here from Newton's law
(a compound pendulum hinged at the ground, ``I_O s'' = m g (x_C cos s - z_C sin s) + u(t) - law(s - rest, s')``; a
body sliding on an inclined guide, ``m s'' = m g . a + u(t) - law(s - rest, s')``), integrated by ``solve_ivp``
(DOP853, 1e-12), and their closed-form small-oscillation frequencies; no code shared with the tree sweep or the cut
mechanism.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.optimize

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.nonlinear_laws import CubicSpring, LinearLaw
from ctmm.spatial import closed_loop_linear as linear
from ctmm.spatial.closed_loop_time import simulate_spatial_loops
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

MASS, INERTIA_Y, COM = 1.2, 0.03, (0.1, 0.0, -0.3)          # [kg], [kg m^2] about the centre of mass, body axes [m]
I_HINGE = INERTIA_Y + MASS * (COM[0] ** 2 + COM[2] ** 2)    # about the hinge axis (world y through the origin)
GUIDE = np.array([0.0, 0.6, 0.8])                            # the prismatic cut's guide direction (world)


def _actuation(t: float) -> float:
    return 0.3 * math.sin(5.0 * t)


def _pendulum(law, rest: float = 0.2, actuation=None) -> SpatialKinematicLoopModel:
    """A body on a free joint held at the ground by a revolute cut about world y at its origin (1 DOF); the cut's
    angle is the rotation about y from the hanging pose (default normals: -z in both frames)."""
    tree = sp.SpatialModel("hinged", [sp.SpatialBody("p", MASS, np.diag([0.02, INERTIA_Y, 0.025]), center_of_mass=COM),
                                      sp.Free(name="free", parent=None, child="p")])
    cut = SpatialCutJoint(name="hinge", parent=None, child="p", kind="revolute", axis=(0, 1, 0), law=law, rest=rest,
                          actuation=actuation)
    return SpatialKinematicLoopModel(tree, [cut])


def _pendulum_reference(law, rest, actuation, s0, rate0, times):
    """``I_O s'' = m g (x_C cos s - z_C sin s) + u(t) - law(s - rest, s')`` (gravity's moment about y)."""
    def rhs(t, y):
        gravity = MASS * 9.81 * (COM[0] * math.cos(y[0]) + COM[2] * math.sin(y[0]))
        load = (actuation(t) if actuation else 0.0) - float(law.force(y[0] - rest, y[1]))
        return [y[1], (gravity + load) / I_HINGE]

    sol = scipy.integrate.solve_ivp(rhs, (times[0], times[-1]), [s0, rate0], method="DOP853", t_eval=times,
                                    rtol=1e-12, atol=1e-13)
    return sol.y[0]


def _start(loop, angle: float = 0.5, rate: float = 2.0):
    return loop.consistent_state({"free.qw": math.cos(angle / 2), "free.qy": math.sin(angle / 2)}, {"free.wy": rate},
                                 keep=["free.wy"])


def test_revolute_cut_law_and_actuation_match_the_pendulum_equation():
    """RK4 2 ms + projection and DOP853 (Baumgarte) over 0.2 s, Newmark 6 / 3 ms over 0.06 s, against the
    reference.  Measured: RK4 1.5e-10 rad, DOP853 1.4e-12 rad, Newmark order 2."""
    law = LinearLaw(2.0, 0.1)
    loop = _pendulum(law, 0.2, _actuation)
    q, v = _start(loop)
    s, rate = loop.cut_coordinates(q, v)
    assert s[0] == pytest.approx(0.5, abs=1e-12) and rate[0] == pytest.approx(2.0, abs=1e-12)
    run = simulate_spatial_loops(loop, q, v, t_final=0.2, dt=2e-3)
    angle = np.array([loop.cut_coordinates(qk, vk)[0][0] for qk, vk in zip(run.q, run.v)])
    reference = _pendulum_reference(law, 0.2, _actuation, 0.5, 2.0, run.t)
    assert np.max(np.abs(angle - reference)) < 1e-8
    smooth = _pendulum_reference(LinearLaw(0.0, 0.0), 0.2, None, 0.5, 2.0, run.t)
    assert np.max(np.abs(smooth - reference)) > 1e-2                          # the law matters
    dop = ctmm.simulate(loop, 0.2, 2e-2, x0=q, v0=v, method="DOP853", rtol=1e-11, atol=1e-12)
    dop_angle = 2.0 * np.arctan2(dop["free.qy"], dop["free.qw"])
    assert np.max(np.abs(dop_angle - reference[::10])) < 1e-8
    errors, end = [], _pendulum_reference(law, 0.2, _actuation, 0.5, 2.0, [0.0, 0.06])[-1]
    for dt in (6e-3, 3e-3):
        newmark = ctmm.simulate(loop, 0.06, dt, x0=q, v0=v, method="newmark")
        errors.append(abs(2.0 * math.atan2(newmark["free.qy"][-1], newmark["free.qw"][-1]) - end))
    assert errors[1] < 1e-4 and 3.0 < errors[0] / errors[1] < 5.0


def test_revolute_cut_spring_frequency_and_energy():
    """About its equilibrium the spring pendulum's frequency is ``sqrt((m g (x_C sin s* - z_C cos s*) + k) / I_O)``;
    undamped (a cubic spring), the energy with the law's potential is conserved."""
    k = 2.0
    loop = _pendulum(LinearLaw(k, 0.0), 0.2)
    q, _ = _start(loop, 0.3, 0.0)
    equilibrium = linear.equilibrium(loop, q)
    balance = lambda s: MASS * 9.81 * (COM[0] * math.cos(s) + COM[2] * math.sin(s)) - k * (s - 0.2)  # noqa: E731
    s_eq = scipy.optimize.brentq(balance, -1.0, 1.0, xtol=1e-14)
    assert loop.cut_coordinates(equilibrium, np.zeros(6))[0][0] == pytest.approx(s_eq, abs=1e-9)
    stiffness = MASS * 9.81 * (COM[0] * math.sin(s_eq) - COM[2] * math.cos(s_eq)) + k
    (omega,) = ctmm.natural_frequencies(loop, operating_point=equilibrium)
    assert omega == pytest.approx(math.sqrt(stiffness / I_HINGE), rel=1e-11)       # measured 5e-13
    cubic = _pendulum(CubicSpring(2.0, 10.0), 0.2)
    q, v = _start(cubic, 0.5, 4.0)
    run = simulate_spatial_loops(cubic, q, v, t_final=0.2, dt=2e-3)
    energy = np.array([sp.energy(cubic.tree, qk, vk) + cubic.cut_potential(qk) for qk, vk in zip(run.q, run.v)])
    spring = np.array([cubic.cut_potential(qk) for qk in run.q])
    assert np.ptp(spring) > 0.1 and np.max(np.abs(energy - energy[0])) < 1e-8 * np.max(np.abs(energy))


def _slider(law, rest: float = 0.0, actuation=None) -> SpatialKinematicLoopModel:
    """A body (centre of mass off its origin) on a free joint, cut to the ground by a prismatic cut along ``GUIDE``
    through the origin: it slides without turning (1 DOF); the cut's coordinate is the slide ``d . GUIDE`` [m]."""
    tree = sp.SpatialModel("slider", [sp.SpatialBody("p", MASS, np.diag([0.02, 0.03, 0.025]),
                                                     center_of_mass=(0.05, 0.02, 0.0)),
                                      sp.Free(name="free", parent=None, child="p")])
    cut = SpatialCutJoint(name="guide", parent=None, child="p", kind="prismatic", axis=tuple(GUIDE), law=law,
                          rest=rest, actuation=actuation)
    return SpatialKinematicLoopModel(tree, [cut])


def test_prismatic_cut_law_and_actuation_match_the_slide_equation():
    """``m s'' = m g . a + u(t) - law(s - rest, s')``: RK4 2 ms over 0.2 s; the undamped frequency ``sqrt(k / m)``."""
    law = LinearLaw(50.0, 0.8)
    loop = _slider(law, -0.1, _actuation)
    q, v = loop.consistent_state({"free.x": 0.0, "free.y": 0.03, "free.z": 0.04}, {"free.vy": 0.3, "free.vz": 0.4},
                                 keep=["free.vy", "free.vz"])
    s, rate = loop.cut_coordinates(q, v)
    assert s[0] == pytest.approx(0.05, abs=1e-12) and rate[0] == pytest.approx(0.5, abs=1e-12)
    run = simulate_spatial_loops(loop, q, v, t_final=0.2, dt=2e-3)
    slide = np.array([loop.cut_coordinates(qk, vk)[0][0] for qk, vk in zip(run.q, run.v)])

    def rhs(t, y):
        return [y[1], (MASS * 9.81 * -GUIDE[2] + _actuation(t) - float(law.force(y[0] + 0.1, y[1]))) / MASS]

    reference = scipy.integrate.solve_ivp(rhs, (0.0, 0.2), [0.05, 0.5], method="DOP853", t_eval=run.t,
                                          rtol=1e-12, atol=1e-13).y[0]
    assert np.max(np.abs(slide - reference)) < 1e-9
    assert np.ptp(reference) > 0.02
    spring = _slider(LinearLaw(50.0, 0.0), -0.1)
    q, _ = spring.consistent_state({"free.y": 0.03, "free.z": 0.04}, {}, keep=[])
    equilibrium = linear.equilibrium(spring, q)
    (omega,) = ctmm.natural_frequencies(spring, operating_point=equilibrium)
    assert omega == pytest.approx(math.sqrt(50.0 / MASS), rel=1e-11)       # measured 3e-13


def test_laws_are_refused_where_a_cut_has_no_coordinate():
    """Universal cuts take neither a law nor an actuation, spherical cuts no actuation (their 3-axis law:
    tests/test_spatial_spherical_cut_law.py)."""
    with pytest.raises(ModelError, match="kind 'spherical' takes neither"):
        SpatialCutJoint(name="c", parent=None, child="p", actuation=1.0)
    with pytest.raises(ModelError, match="kind 'universal' takes neither"):
        SpatialCutJoint(name="c", parent=None, child="p", kind="universal", parent_axis=(1, 0, 0), law=LinearLaw(1.0))
    with pytest.raises(ModelError, match="kind 'universal' takes neither"):
        SpatialCutJoint(name="c", parent=None, child="p", kind="universal", parent_axis=(1, 0, 0), actuation=1.0)
    with pytest.raises(ModelError, match="law must be None or a ctmm.nonlinear_laws.Law"):
        SpatialCutJoint(name="c", parent=None, child="p", kind="revolute", law=3.0)
    with pytest.raises(ModelError, match="rest"):
        SpatialCutJoint(name="c", parent=None, child="p", kind="revolute", rest=math.inf)


def _pendulum_drive():
    return dict(position=lambda t: 0.5 + 0.3 * np.sin(4.0 * t), rate=lambda t: 1.2 * np.cos(4.0 * t),
                acceleration=lambda t: -4.8 * np.sin(4.0 * t))


def test_driven_revolute_cut_follows_its_angle_with_the_drive_moment_of_the_pendulum_equation():
    """The hinge angle prescribed (0 DOF): the moment about the axis is ``I_O s'' - m g (x_C cos s + z_C sin s)``
    (measured 1e-11 N m of 0.8 with RK4 2 ms + projection over 0.1 s, the angle follows to 1e-15 rad); Newmark runs
    it too; the linearisation is refused by name."""
    drive = _pendulum_drive()
    tree = _pendulum(None).tree
    loop = SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="hinge", parent=None, child="p", kind="revolute",
                                                            axis=(0, 1, 0), **drive)])
    q, v = loop.consistent_state({"free.qw": math.cos(0.25), "free.qy": math.sin(0.25)}, {"free.wy": 1.2})
    run = simulate_spatial_loops(loop, q, v, t_final=0.1, dt=2e-3)
    angle = np.array([loop.cut_coordinates(qk, vk)[0][0] for qk, vk in zip(run.q, run.v)])
    assert np.max(np.abs(angle - drive["position"](run.t))) < 1e-10
    s, s_ddot = drive["position"](run.t), drive["acceleration"](run.t)
    expected = I_HINGE * s_ddot - MASS * 9.81 * (COM[0] * np.cos(s) + COM[2] * np.sin(s))
    assert np.max(np.abs(run.cut_moment[:, 0, 1] - expected)) < 1e-9 * np.max(np.abs(expected))
    newmark = ctmm.simulate(loop, 0.02, 2e-3, x0=q, v0=v, method="newmark")
    assert abs(2.0 * math.atan2(newmark["free.qy"][-1], newmark["free.qw"][-1]) - drive["position"](0.02)) < 1e-6
    with pytest.raises(ModelError, match="driven"):
        linear.equilibrium(loop, q)


def test_driven_prismatic_cut_slides_with_the_force_of_the_slide_equation():
    """``s = 0.05 + 0.02 sin 5t`` along the guide: the guide force is ``m s'' - m g . a`` (measured 1e-12 relative)."""
    drive = dict(position=lambda t: 0.05 + 0.02 * np.sin(5.0 * t), rate=lambda t: 0.1 * np.cos(5.0 * t),
                 acceleration=lambda t: -0.5 * np.sin(5.0 * t))
    loop = SpatialKinematicLoopModel(_slider(None).tree, [SpatialCutJoint(
        name="guide", parent=None, child="p", kind="prismatic", axis=tuple(GUIDE), **drive)])
    q, v = loop.consistent_state({"free.y": 0.03, "free.z": 0.04}, {"free.vy": 0.06, "free.vz": 0.08})
    run = simulate_spatial_loops(loop, q, v, t_final=0.1, dt=2e-3)
    slide = np.array([loop.cut_coordinates(qk, vk)[0][0] for qk, vk in zip(run.q, run.v)])
    assert np.max(np.abs(slide - drive["position"](run.t))) < 1e-10
    expected = MASS * drive["acceleration"](run.t) + MASS * 9.81 * GUIDE[2]
    assert np.max(np.abs(run.cut_force[:, 0] @ GUIDE - expected)) < 1e-9 * np.max(np.abs(expected))


def test_bad_spatial_drives_are_refused_by_name():
    with pytest.raises(ModelError, match="position, rate and acceleration all given"):
        SpatialCutJoint(name="c", parent=None, child="p", kind="revolute", position=0.1)
    with pytest.raises(ModelError, match="not the time derivative"):
        SpatialCutJoint(name="c", parent=None, child="p", kind="revolute", position=lambda t: t * t, rate=1.0,
                        acceleration=0.0)
    with pytest.raises(ModelError, match="kind 'spherical'"):
        SpatialCutJoint(name="c", parent=None, child="p", position=0.1, rate=0.0, acceleration=0.0)


# -- cuts between two moving bodies, against the Newton-Euler DAE (ctmm.reference.spatial_loop_dae) -----------------
def _dae_law_loads(dae, y, cut, parent: int, child: int, parent_point, child_point, law, t):
    """The law of a cut between DAE bodies ``parent`` and ``child`` written on the DAE's own state: the coordinate
    (revolute: the angle from ``R_p parent_normal`` to ``R_c normal`` about ``R_c axis``; prismatic: ``d . a`` with
    ``a = R_p parent_axis``), its rate, and the loads ``{body: [force ; moment about the centre of mass]}``."""
    x, _, v, w = dae.split(y)
    R = dae.rotations(y)
    rp, rc = R[parent] @ parent_point, R[child] @ child_point
    d = x[child] + rc - x[parent] - rp
    if cut.kind == "revolute":
        a, n_c, n_p = R[child] @ cut.axis, R[child] @ cut.normal, R[parent] @ cut.parent_normal
        s = math.atan2(np.cross(n_p, n_c) @ a, n_p @ n_c)
        rate = (w[child] - w[parent]) @ a
        f = _actuation(t) - float(law.force(s - cut.rest, rate))
        return {child: np.concatenate([np.zeros(3), f * a]), parent: np.concatenate([np.zeros(3), -f * a])}
    a = R[parent] @ cut.parent_axis
    relative = v[child] + np.cross(w[child], rc) - v[parent] - np.cross(w[parent], rp)
    s, rate = d @ a, relative @ a + d @ np.cross(w[parent], a)
    f = _actuation(t) - float(law.force(s - cut.rest, rate))
    at = x[child] + rc                                   # both at the child point
    return {child: np.concatenate([f * a, np.cross(at - x[child], f * a)]),
            parent: np.concatenate([-f * a, np.cross(at - x[parent], -f * a)])}


def _rod(name, mass, length):
    moments = np.full(3, mass * (length ** 2 + 0.03 ** 2) / 12)
    moments[2] = mass * 0.03 ** 2 / 6
    return sp.SpatialBody(name, mass, np.diag(moments), center_of_mass=(0.0, 0.0, -length / 2),
                          points={"tip": (0.0, 0.0, -length)})


def two_moving(kind: str):
    """``(loop, cut, law, arm, other, q, v)``: a double pendulum whose second hinge (about world x at the arm's tip) is
    a revolute cut, or a sleeve on the swinging arm whose slide is a prismatic cut; each with a spring-damper law and
    an actuation (both sides move); ``q, v`` on the cut with the arm at 0.4 rad, 1.5 rad/s."""
    law = LinearLaw(3.0, 0.05) if kind == "revolute" else LinearLaw(40.0, 0.3)
    arm = _rod("arm", 0.8, 0.6)
    if kind == "revolute":
        other = _rod("link", 0.5, 0.4)
        cut = SpatialCutJoint(name="c", parent="arm", point="tip", child="link", kind="revolute", axis=(1, 0, 0),
                              law=law, rest=0.3, actuation=_actuation)
        keep = {"h1.angle": 0.4, "free.qw": math.cos(0.1), "free.qx": math.sin(0.1)}
    else:
        other = sp.SpatialBody("link", 0.3, np.diag([0.003, 0.002, 0.001]), center_of_mass=(0.02, 0.0, 0.0))
        cut = SpatialCutJoint(name="c", parent="arm", point="origin", child="link", kind="prismatic", axis=(0, 0, 1),
                              normal=(1, 0, 0), parent_normal=(1, 0, 0), law=law, rest=-0.2, actuation=_actuation)
        keep = {"h1.angle": 0.4, "free.z": -0.3}
    tree = sp.SpatialModel("two_moving", [arm, sp.Revolute(name="h1", parent=None, child="arm", axis=(1, 0, 0)),
                                          other, sp.Free(name="free", parent=None, child="link")])
    loop = SpatialKinematicLoopModel(tree, [cut])
    q, v = loop.consistent_state(keep, {"h1.angle_rate": 1.5}, keep=["h1"])
    return loop, cut, law, arm, other, q, v


def two_moving_dae(loop, cut, arm, other):
    """``(dae, points)``: the Newton-Euler DAE of :func:`two_moving`'s mechanism (Baumgarte 10/s; a prismatic cut's
    roll reference its own) and the cut points from the bodies' centres of mass (body axes)."""
    from dataclasses import replace

    from ctmm.scenarios.spatial_four_bar import dae_of

    dae = dae_of(loop, 10.0)
    if cut.kind == "prismatic":                         # the DAE's own roll reference of the prismatic rows
        dae.joints[-1] = replace(dae.joints[-1], child_normal=np.asarray(cut.normal),
                                 parent_normal=np.asarray(cut.parent_normal))
    return dae, (arm.points[cut.point] - arm.center_of_mass, other.points[cut.child_point] - other.center_of_mass)


@pytest.mark.parametrize("kind", ["revolute", "prismatic"])
def test_cut_law_between_two_moving_bodies_matches_the_dae(kind):
    """Revolute: a double pendulum whose second hinge (about world x at the arm's tip) is a cut with a spring-damper
    and an actuation; prismatic: a sleeve on the swinging arm, the slide a cut with a spring-damper and an actuation.
    Both sides move, so the parent's reaction is checked too.  RK4 + projection over 0.2 s (revolute 1 ms: the hinge
    swings 0.86 rad; prismatic 2 ms) against the DAE with the law written on its own state.  Measured: revolute
    7.9e-10 rad, 1.3e-10 m (2 ms: 1.25e-8 rad, RK4's fourth order); prismatic 8.4e-12 rad, 5.8e-11 m."""
    from ctmm.scenarios.spatial_four_bar import poses

    loop, cut, law, arm, other, q, v = two_moving(kind)
    run = simulate_spatial_loops(loop, q, v, t_final=0.2, dt=1e-3 if kind == "revolute" else 2e-3)
    dae, points = two_moving_dae(loop, cut, arm, other)
    loads = lambda t, y: _dae_law_loads(dae, y, cut, 0, 1, *points, law, t)      # noqa: E731
    _, Y = dae.simulate(dae.state(*poses(loop, run.q[0], run.v[0])), run.t, torques=loads)
    angle = position = 0.0
    for k in range(len(run.t)):
        x, R, _, _ = poses(loop, run.q[k], run.v[k])
        angle = max(angle, max(np.abs(a - b).max() for a, b in zip(R, dae.rotations(Y[k]))))
        position = max(position, max(np.abs(a - b).max() for a, b in zip(x, dae.split(Y[k])[0])))
    coordinate = np.array([loop.cut_coordinates(qk, vk)[0][0] for qk, vk in zip(run.q, run.v)])
    assert np.ptp(coordinate) > 0.01
    assert angle < 1e-8 and position < 1e-8


def test_cut_torque_and_force_inputs_of_the_linearisation():
    """``"hinge.torque"`` / ``"guide.force"``: with a spring-damper at the cut, the response of the coordinate to a
    load along it is ``1 / (M (omega_n^2 - omega^2) + i c omega)`` (``M = I_O`` or ``m``, the pendulum's / slider's
    closed forms), read through the tree coordinate that moves with it (the quaternion's ``qy = sin(s / 2)``, the
    position along the guide)."""
    k, c = 2.0, 0.1
    loop = _pendulum(LinearLaw(k, c), 0.2)
    equilibrium = linear.equilibrium(_pendulum(LinearLaw(k, 0.0), 0.2), _start(loop, 0.3, 0.0)[0])
    s_eq = loop.cut_coordinates(equilibrium, np.zeros(6))[0][0]
    stiffness = MASS * 9.81 * (COM[0] * math.sin(s_eq) - COM[2] * math.cos(s_eq)) + k
    omega = np.array([0.0, 1.0, 3.0, 7.0])
    frf = ctmm.frequency_response(loop, omega, input="hinge.torque", output="free.qy", operating_point=equilibrium)
    expected = 0.5 * math.cos(s_eq / 2) / (stiffness - I_HINGE * omega ** 2 + 1j * c * omega)
    np.testing.assert_allclose(frf("free.qy", "hinge.torque"), expected, rtol=1e-6)
    assert frf.units["hinge.torque"] == "N m"
    slider = _slider(LinearLaw(50.0, 0.8), -0.1)
    q, _ = slider.consistent_state({"free.y": 0.03, "free.z": 0.04}, {}, keep=[])
    point = linear.equilibrium(_slider(LinearLaw(50.0, 0.0), -0.1), q)
    frf = ctmm.frequency_response(slider, omega, input="guide.force", output="free.z", operating_point=point)
    np.testing.assert_allclose(frf("free.z", "guide.force"), GUIDE[2] / (50.0 - MASS * omega ** 2 + 0.8j * omega),
                               rtol=1e-6)
    with pytest.raises(ModelError, match="hinge.force"):
        ctmm.linearize(loop, equilibrium, inputs=["hinge.force"])
