"""Feedback loops and open-loop inputs on planar kinematic loop models with compiled=True
(ctmm.compiled_kinematic_loop_control, issues 13 x 16).

The generated run states the numpy loop driver's run on symbols (the loops by ctmm.compiled_loops.ClosedLoops, the
closed-loop accelerations with the actuator values applied, the projection onto the cut joints after every RK4 step),
so every stored signal equals the driver's projected run (``ctmm.simulate``'s default) to round-off (<= 1e-12
relative); without the projection on both sides (``projection=False``) too.  Independent reference: the global DAE
of ctmm.reference.planar_dae with a motor between the rocker and the coupler carrying the same PD law, read ``delay`` seconds late by the method of
steps (tests/test_cut_joint_control.py's model and bounds).
"""
from __future__ import annotations

import math
from functools import partial

import control
import numpy as np
import pytest
from test_cut_joint_control import BODIES, KD, KP, OFFSET, _pd, _relative

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.control.static_gain import StaticGainController
from ctmm.errors import ModelError, SimulationError
from ctmm.nonlinear_laws import LinearLaw
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel
from ctmm.scenarios.four_bar import mechanism, reference, start
from ctmm.signals import Harmonic


def _numpy(system, t_final: float, dt: float, *, x0, v0, projection: bool = True, **options):
    """The numpy loop driver's run (``projection=False``: the drift held by Baumgarte alone)."""
    from ctmm.control.planar_time import simulate_closed_loop

    model = getattr(system, "plant", system)
    return simulate_closed_loop(model, x0, v0, t_final, dt, loops=tuple(getattr(system, "loops", ())),
                                projection=projection, **options)


def _equal(generated, plain) -> None:
    assert generated.info["method"] == "rk4-generated"
    np.testing.assert_array_equal(generated.time, plain.time)
    assert sorted(generated.time_signals()) == sorted(plain.time_signals())
    for name in plain.time_signals():
        scale = max(1.0, float(np.max(np.abs(plain[name]))))
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-12 * scale, name


@pytest.mark.parametrize("delay", [0.0, 0.01], ids=["real-time", "delayed"])
def test_pd_loop_on_the_cut_equals_the_numpy_driver_and_matches_the_dae(delay):
    """Measured: generated = numpy to 3e-14 N (cut force); vs the DAE at the numpy path's bound 1e-9 rad.  0.1 s
    (ten delays): the loop already moves the coupler by 4.7e-3 rad from the free run (bound 1e-3)."""
    loop = mechanism()
    q0, v0 = start(loop)
    target = float(loop.relative_angles(q0, v0)[0][0]) + OFFSET
    options = dict(x0=q0, v0=v0, references={"pd": KP * target}, outputs=["h3.angle", "h3.rate", "coupler.out.x"])
    generated = ctmm.simulate(with_feedback(loop, [_pd(delay)]), 0.1, 1e-3, compiled=True, **options)
    _equal(generated, _numpy(with_feedback(loop, [_pd(delay)]), 0.1, 1e-3, **options))
    assert generated.info["loops"] == {"pd": "history" if delay else "real-time"}
    assert generated.info["projection"] and generated.info["max_drift_after_projection"] < 1e-12
    dae = reference()
    dae.add_motor("rocker", "coupler", lambda t, angle, rate: -(KP * angle + KD * rate - KP * target), delay=delay)
    dae_run = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.1, t_eval=generated.time)
    assert max(np.max(np.abs(generated[f"{n}.theta"] - dae_run.angle(n))) for n in BODIES) < 1e-9
    assert np.max(np.abs(generated["h3.angle"] - _relative(dae_run))) < 1e-9
    free = ctmm.simulate(loop, 0.1, 1e-3, x0=q0, v0=v0)
    assert np.max(np.abs(free["coupler.theta"] - generated["coupler.theta"])) > 1e-3       # the loop acts


def test_open_loop_inputs_and_an_lti_controller_on_a_linkage_with_a_cut_law():
    """A harmonic cut torque input against the DAE's motor (1e-9 rad); with a PI controller on the crank rate, a
    saturated loop and a cut spring-damper with a torque as well: = the numpy driver to round-off."""
    loop = mechanism()
    q0, v0 = start(loop)
    generated = ctmm.simulate(loop, 0.1, 1e-3, x0=q0, v0=v0, inputs={"h3.torque": Harmonic(0.8, 20.0)},
                              outputs=["h3.angle"], compiled=True)
    _equal(generated, _numpy(loop, 0.1, 1e-3, x0=q0, v0=v0, inputs={"h3.torque": Harmonic(0.8, 20.0)},
                                 outputs=["h3.angle"]))
    dae = reference()
    dae.add_motor("rocker", "coupler", lambda t, angle, rate: 0.8 * math.sin(20.0 * t))
    dae_run = dae.simulate(dae.assemble(dict(zip(BODIES, q0)), dict(zip(BODIES, v0))), 0.1, t_eval=generated.time)
    assert np.max(np.abs(generated["h3.angle"] - _relative(dae_run))) < 1e-9
    cut = loop.cuts[0]
    lawful = KinematicLoopModel(loop.tree, [CutJoint(cut.name, cut.parent, cut.child, moment_law=LinearLaw(
        3.0, 0.05), rest_angle=-1.3, torque=Harmonic(0.3, 7.0))])
    q0, v0 = start(lawful)
    loops = [Feedback("pi", sensor="h1.rate", actuator="h1.torque", gain=control.tf([2.0, 5.0], [1.0, 0.0])),
             Feedback("hold", sensor="h3.angle", actuator="h3.torque", gain=4.0, saturation=(-0.5, 0.5))]
    options = dict(x0=q0, v0=v0, inputs={"h1.torque": Harmonic(2.0, 10.0)}, references={"hold": -1.3 * 4.0},
                   store_every=4)
    generated = ctmm.simulate(with_feedback(lawful, loops), 0.1, 1e-3, compiled=True, **options)
    _equal(generated, _numpy(with_feedback(lawful, loops), 0.1, 1e-3, **options))
    assert np.ptp(generated["pi.u"]) > 0.1 and np.max(generated["hold.saturated"]) == 1.0


def test_refusals_and_failures_are_named():
    loop = mechanism()
    q0, v0 = start(loop)
    timed = KinematicLoopModel(loop.tree, [CutJoint("h3", "rocker.out", "coupler.out", moment_law=LinearLaw(
        3.0), torque=Harmonic(0.3, 7.0))])
    on_moment = Feedback("m", sensor="h3.moment", actuator="h1.torque", gain=1.0)
    with pytest.raises(ModelError, match="sensor 'h3.moment'.*time-varying torque.*compiled=None"):
        ctmm.simulate(with_feedback(timed, [on_moment]), 0.01, 1e-3, x0=q0, v0=v0, compiled=True)
    with pytest.raises(ModelError, match="whole multiple"):
        ctmm.simulate(with_feedback(loop, [_pd(0.0105)]), 0.02, 1e-3, x0=q0, v0=v0, compiled=True)
    with pytest.raises(ModelError, match="compiled=True is not available"):      # with a solve_ivp method
        ctmm.simulate(loop, 0.01, 1e-3, x0=q0, v0=v0, compiled=True, method="DOP853", controllers=[
            StaticGainController(["h3.angle"], ["h3.torque"], [[-KP]], sample_time=1e-3)])
    with pytest.raises(ModelError, match="inputs\\['h1.torque'\\]"):
        ctmm.simulate(loop, 0.01, 1e-3, x0=q0, v0=v0, compiled=True, inputs={"h1.torque": lambda t: t})
    twice = KinematicLoopModel(loop.tree, [*loop.cuts, CutJoint("h3b", parent="rocker.out", child="coupler.out")])
    with pytest.raises(SimulationError, match="with loops \\(generated RK4\\): the cut joints' boundary compliance is "
                       "singular") as failure:
        ctmm.simulate(with_feedback(twice, [_pd(0.0)]), 0.01, 1e-3, x0=q0, v0=v0, compiled=True,
                      stability_check="ignore")
    assert failure.value.time == 0.0 and failure.value.element == "h3"


def test_co_simulated_controllers_between_calls_into_the_kernel():
    """A static-gain PD on the cut sampled every 2 ms (zero-order hold), alone and beside a delayed PD loop on the crank
    with an open-loop input: one call into C per sample interval, every stored signal = the numpy driver (the cut
    forces with the held torque of each row)."""
    loop = mechanism()
    q0, v0 = start(loop)
    pd = Feedback("hold", sensor=[("h1.angle", 8.0), ("h1.rate", 0.8)], actuator="h1.torque", gain=1.0, delay=0.01)
    for system, options in [(loop, {"outputs": ["h3.angle"]}),
                            (with_feedback(loop, [pd]), {"references": {"hold": 9.6},
                                                         "inputs": {"crank.moment": Harmonic(0.2, 5.0)}})]:
        runs = [run(system, 0.1, 1e-3, x0=q0, v0=v0, controllers=[StaticGainController(
            ["h3.angle", "h3.rate"], ["h3.torque"], [[-KP, -KD]], sample_time=2e-3)], **options)
            for run in (partial(ctmm.simulate, compiled=True), _numpy)]
        _equal(runs[0], runs[1])
        assert runs[0].info["intervals"] == 50 and np.ptp(runs[0]["h3.torque@samples"][:, 1]) > 0.1



# -- spatial kinematic loops (the same kernel on the spatial closed-loop rates) ----------------------------------------
@pytest.mark.parametrize("delay", [0.0, 0.01], ids=["real-time", "delayed"])
def test_spatial_pd_loop_on_a_revolute_cut_equals_the_numpy_driver_and_newtons_law(delay):
    """The pendulum held by a revolute cut with a PD on the cut angle (tests/test_cut_joint_control.py's model and its
    Newton's-law reference by the method of steps, bound 1e-9 rad; measured 2.3e-11): = the numpy driver to 1e-12."""
    from test_cut_joint_control import S_KD, S_KP, S_TARGET, _spatial_pendulum, _spatial_reference, _spatial_state

    loop = _spatial_pendulum()
    q0, v0 = _spatial_state(loop, 0.5, 2.0)
    pd = Feedback("pd", sensor=[("hinge.angle", S_KP), ("hinge.rate", S_KD)], actuator="hinge.torque", gain=1.0,
                  delay=delay)
    options = dict(x0=q0, v0=v0, references={"pd": S_KP * S_TARGET}, outputs=["hinge.angle", "hinge.rate"])
    generated = ctmm.simulate(with_feedback(loop, [pd]), 0.1, 2e-3, compiled=True, **options)
    _equal(generated, _numpy(with_feedback(loop, [pd]), 0.1, 2e-3, **options))
    assert np.max(np.abs(generated["hinge.angle"] - _spatial_reference(0.5, 2.0, generated.time, delay))) < 1e-9


def test_spatial_port_inputs_and_co_simulated_controllers():
    """A harmonic cut torque (a port input: the driver's run) and a sampled static-gain PD on the cut: = the numpy
    driver to round-off, the cut loads with each row's held torque."""
    from test_cut_joint_control import S_KD, S_KP, _spatial_pendulum, _spatial_state

    loop = _spatial_pendulum()
    q0, v0 = _spatial_state(loop, 0.5, 2.0)
    for options in ({"inputs": {"hinge.torque": Harmonic(0.5, 10.0)}},
                    {"controllers": [StaticGainController(["hinge.angle", "hinge.rate"], ["hinge.torque"],
                                                          [[-S_KP, -S_KD]], sample_time=4e-3)]}):
        runs = [run(loop, 0.1, 2e-3, x0=q0, v0=v0, outputs=["hinge.angle"], **options)
                for run in (partial(ctmm.simulate, compiled=True), _numpy)]
        _equal(runs[0], runs[1])


def test_spatial_cut_law_sensor_in_a_generated_loop_equals_the_numpy_driver():
    """A loop on a revolute cut's ``"c.law_moment"`` (``-law(s - rest, s')`` on the cut coordinates' symbols) driving the
    cut's torque, on the double pendulum of tests/test_spatial_cut_joint_laws.py (its law kept, a harmonic actuation):
    = the numpy driver to round-off."""
    from dataclasses import replace

    from ctmm.spatial.closed_loops import SpatialKinematicLoopModel
    from test_spatial_cut_joint_laws import two_moving

    loop, cut, *_, q0, v0 = two_moving("revolute")
    loop = SpatialKinematicLoopModel(loop.tree, [replace(cut, actuation=Harmonic(0.3, 5.0))])
    follow = Feedback("f", sensor="c.law_moment", actuator="c.torque", gain=0.5)
    options = dict(x0=q0, v0=v0, outputs=["c.law_moment"])
    generated = ctmm.simulate(with_feedback(loop, [follow]), 0.02, 2e-3, compiled=True, **options)
    _equal(generated, _numpy(with_feedback(loop, [follow]), 0.02, 2e-3, **options))
    assert np.max(np.abs(generated["f.y"] - generated["c.law_moment"])) < 1e-12 and np.ptp(generated["f.y"]) > 0.01


def test_without_projection_the_generated_run_equals_the_baumgarte_numpy_driver():
    """``projection=False`` on both sides (the drift held by Baumgarte alone): equal to round-off, and apart from the
    projected run by the drift the projection removes (measured ~2e-9 rad over 1 s; here > 0 and < 1e-6 rad)."""
    from ctmm.compiled_kinematic_loop_control import simulate_controlled_kinematic_loops_generated

    loop = mechanism()
    q0, v0 = start(loop)
    options = dict(references={"pd": 0.0}, outputs=["h3.angle"])
    plain = simulate_controlled_kinematic_loops_generated(with_feedback(loop, [_pd(0.01)]), q0, v0, t_final=0.1,
                                                          dt=1e-3, projection=False, **options)
    _equal(plain, _numpy(with_feedback(loop, [_pd(0.01)]), 0.1, 1e-3, x0=q0, v0=v0, projection=False, **options))
    assert plain.info["projection"] is False and "max_drift_after_projection" not in plain.info
    projected = ctmm.simulate(with_feedback(loop, [_pd(0.01)]), 0.1, 1e-3, x0=q0, v0=v0, compiled=True, **options)
    assert 0.0 < np.max(np.abs(projected["h3.angle"] - plain["h3.angle"])) < 1e-6
