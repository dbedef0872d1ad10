"""Generated DT-TMM schemes of spatial kinematic loop models with feedback loops
(ctmm.compiled_spatial_loop_scheme_control, issue 13): ``ctmm.simulate(with_feedback(loop_model, loops), ...,
method=<scheme>, compiled=True)``.

Checks: equal to the numpy loop driver with the same scheme (ctmm.control.implicit_loops: the tree's scheme with the
cut loads at every iterate, projected after every step) to round-off -- real-time, LTI, whole-step and
between-sample delayed loops, references, open-loop port inputs and outputs, several schemes; a PD crank on the
R-U-S-R four-bar against the Newton-Euler DAE with the same control law (ctmm.reference.spatial_loop_dae, no
ctmm.spatial code) at order two; co-simulated controllers between calls into the step (ctmm.compiled_scheme_cosim) =
the numpy driver and, a sampled P law, the DAE with its zero-order hold at order two; refusals by name.
"""
from __future__ import annotations

import control
import numpy as np
import pytest
from test_compiled_spatial_loop_schemes import _dae_rotation_error

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.control.planar_time import simulate_closed_loop
from ctmm.errors import ModelError
from ctmm.scenarios.spatial_four_bar import DOWN, mechanism, start
from ctmm.signals import Harmonic

KP, KD, TARGET = 20.0, 2.0, 0.3          # crank PD [N m/rad, N m s/rad], set point [rad]


def _pd(delay: float = 0.0, gain=1.0) -> Feedback:
    """``u = -(KP angle + KD rate) + KP TARGET`` on the crank (the reference ``KP TARGET``)."""
    return Feedback("pd", [("h1.angle", KP), ("h1.angle_rate", KD)], "h1.torque", gain=gain, delay=delay)


def _equal(generated, plain) -> None:
    """Every signal of the numpy driver's result, to 1e-12 of its scale."""
    assert generated.info["method"].startswith("dt-tmm-generated/") and generated.info["compiled"] is True
    np.testing.assert_array_equal(generated.time, plain.time)
    assert sorted(generated.time_signals()) == sorted(plain.time_signals())
    for name in plain.time_signals():
        scale = max(1.0, float(np.max(np.abs(plain[name]))))
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-12 * scale, name


def _numpy(system, t_final: float, dt: float, **options):
    return simulate_closed_loop(system.plant, options.pop("x0"), options.pop("v0"), t_final, dt,
                                loops=tuple(system.loops), **options)


@pytest.fixture(scope="module")
def four_bar():
    loop = mechanism()
    return (loop, *start(loop))


def test_pd_crank_equals_the_numpy_driver_and_converges_to_the_dae(four_bar):
    """A real-time PD on the crank towards 0.3 rad, Newmark at 4 / 2 ms over 0.04 s: every signal = the numpy
    driver's to 1e-12 (at 4 ms); the bodies' rotations against the DAE with the same law (crank angle about world x from its
    rotation, rate from its angular velocity) at order two (1 ms: 2.9e-6 rad, ratio 4.00; the law with the wrong sign
    is 0.75 rad away); drift at round-off after every step."""
    loop, q, v = four_bar
    system = with_feedback(loop, [_pd()])
    options = dict(x0=q, v0=v, method="newmark", references={"pd": KP * TARGET}, outputs=["h4.angle"])

    def law(t, y, dae):
        R = dae.rotations(y)[0] @ DOWN.T                  # R_x(angle)
        angle, rate = np.arctan2(R[2, 1], R[1, 1]), dae.split(y)[3][0][0]
        return {0: np.array([-KP * (angle - TARGET) - KD * rate, 0.0, 0.0])}

    from spatial_loop_helpers import dae_of

    dae = dae_of(loop, 10.0)
    errors = []
    for dt in (4e-3, 2e-3):
        generated = ctmm.simulate(system, 0.04, dt, compiled=True, **options)
        if dt == 4e-3:                                   # the numpy driver at one step: the same path at both
            _equal(generated, _numpy(system, 0.04, dt, **options))
        assert generated.info["loops"] == {"pd": "real-time"} and generated["drift"].max() <= 1e-12
        run = type("Run", (), {"t": generated.time, "q": np.array([generated[n] for n in loop.tree.coordinates]).T,
                               "v": np.array([generated[n] for n in loop.tree.velocities]).T})
        errors.append(_dae_rotation_error(loop, run, lambda t, y: law(t, y, dae)))
    assert generated["h1.angle"][-1] > q[0] + 0.05                   # the loop drives the crank
    assert errors[1] < 2e-5 and 3.3 < errors[0] / errors[1] < 4.7    # measured 4.7e-5 / 1.2e-5 rad, ratio 4.02


@pytest.mark.parametrize("case", ["whole-step delay", "between-sample delay", "lag controller", "port input",
                                  "generalized_alpha", "houbolt"])
def test_loop_kinds_and_schemes_equal_the_numpy_driver(four_bar, case):
    """Delays of two steps and of 1.5 steps (cubic Hermite between ring samples), an LTI lag ``C(s) = 2 / (s + 3)``
    with its state, a harmonic open-loop moment on the rocker (a port actuator, a symbolic signal) with the PD, and other
    schemes: every signal = the numpy driver's to 1e-12."""
    loop, q, v = four_bar
    loops, method, inputs = [_pd()], "newmark", {}
    if case == "whole-step delay":
        loops = [_pd(8e-3)]
    elif case == "between-sample delay":
        loops = [_pd(6e-3)]
    elif case == "lag controller":
        loops = [_pd(gain=control.tf([2.0], [1.0, 3.0]))]
    elif case == "port input":
        inputs = {"rocker.moment_y": Harmonic(0.5, 60.0)}
    else:
        method = case
    system = with_feedback(loop, loops)
    options = dict(x0=q, v0=v, method=method, references={"pd": KP * TARGET}, inputs=inputs)
    _equal(ctmm.simulate(system, 0.04, 4e-3, compiled=True, **options), _numpy(system, 0.04, 4e-3, **options))


def test_refusals_are_named(four_bar):
    """``progress`` with the loops in the step and a solve_ivp method with ``compiled=True`` are refused by name; a
    loop model without loops but with outputs runs here (= numpy)."""
    loop, q, v = four_bar
    system = with_feedback(loop, [_pd()])
    with pytest.raises(ModelError, match="compiled=True .* not the RK4 with joint inputs alone"):
        ctmm.simulate(loop, 0.04, 4e-3, x0=q, v0=v, method="DOP853", compiled=True)
    with pytest.raises(ModelError, match="progress=True is not available with compiled=True and a DT-TMM scheme"):
        ctmm.simulate(system, 0.04, 4e-3, x0=q, v0=v, method="newmark", compiled=True, progress=True)
    alone = ctmm.simulate(loop, 0.04, 4e-3, x0=q, v0=v, method="newmark", compiled=True, outputs=["h4.angle"])
    plain = ctmm.simulate(loop, 0.04, 4e-3, x0=q, v0=v, method="newmark", outputs=["h4.angle"])
    _equal(alone, plain)


def _zero_order_hold_dae_error(loop, run, sample_time: float, law) -> float:
    """Largest rotation difference [rad] of ``run`` against the Newton-Euler DAE driven by a sampled crank torque
    ``law(angle)`` [N m] held between samples (each interval integrated on its own with its held moment about world
    x; the crank angle read from the crank's rotation)."""
    from spatial_loop_helpers import dae_of, poses

    dae = dae_of(loop, 10.0)
    y = dae.state(*poses(loop, run.q[0], run.v[0]))
    every = int(round(sample_time / (run.t[1] - run.t[0])))
    error = 0.0
    for k in range(0, len(run.t) - 1, every):
        R = dae.rotations(y)[0] @ DOWN.T
        torque = {0: np.array([law(np.arctan2(R[2, 1], R[1, 1])), 0.0, 0.0])}
        _, Y = dae.simulate(y, run.t[k:k + every + 1], torques=torque)
        for j in range(1, every + 1):
            error = max(error, max(np.abs(a - b).max() for a, b in zip(poses(loop, run.q[k + j], run.v[k + j])[1],
                                                                         dae.rotations(Y[j]))))
        y = Y[-1]
    return error


def test_cosimulated_pid_equals_the_numpy_driver_and_converges_to_the_dae(four_bar):
    """A sampled P controller (``ctmm.controllers.PID``, kp = 20 N m/rad towards 0.3 rad every 8 ms) on the crank,
    Newmark at 4 / 2 ms: every signal = the numpy loop driver's to its Newton tolerance (1e-10, as the other
    co-simulated schemes; measured 6e-14; at 4 ms); against the DAE with the same zero-order-hold law at
    order two."""
    from ctmm.controllers import PID

    loop, q, v = four_bar
    pid = PID("h1.angle", "h1.torque", kp=KP, ki=0.0, kd=0.0, derivative_filter_time=0.0, sample_time=8e-3,
              reference=TARGET)
    options = dict(x0=q, v0=v, method="newmark", controllers=[pid], outputs=["h4.angle"])
    errors = []
    for dt in (4e-3, 2e-3):
        generated = ctmm.simulate(loop, 0.04, dt, compiled=True, **options)
        assert generated.info["method"] == "dt-tmm-generated/Newmark" and generated.info["intervals"] == 5
        if dt == 4e-3:                                   # the numpy driver at one step: the same path at both
            plain = ctmm.simulate(loop, 0.04, dt, **options)
            assert sorted(generated.time_signals()) == sorted(plain.time_signals())
            for name in plain.time_signals():
                scale = max(1.0, float(np.max(np.abs(plain[name]))))
                assert np.max(np.abs(generated[name] - plain[name])) <= 1e-10 * scale, name
        run = type("Run", (), {"t": generated.time, "q": np.array([generated[n] for n in loop.tree.coordinates]).T,
                               "v": np.array([generated[n] for n in loop.tree.velocities]).T})
        errors.append(_zero_order_hold_dae_error(loop, run, 8e-3, lambda angle: KP * (TARGET - angle)))
    assert generated["h1.angle"][-1] > q[0] + 0.05                   # the controller drives the crank
    assert errors[1] < 2e-5 and 3.3 < errors[0] / errors[1] < 4.7    # measured 3.3e-5 / 8.2e-6 rad, ratio 4.0


def test_cosimulated_controller_beside_loops_and_inputs_equals_the_numpy_driver(four_bar):
    """A sampled P controller beside a delayed PD loop and a harmonic moment on the rocker, Houbolt (started up
    again after every sample, as the Python path): every signal = the numpy driver's to 1e-10."""
    from ctmm.controllers import PID

    loop, q, v = four_bar
    pid = PID("h1.angle", "h1.torque", kp=5.0, ki=2.0, kd=0.0, derivative_filter_time=0.0, sample_time=8e-3)
    options = dict(x0=q, v0=v, method="houbolt", controllers=[pid], references={"pd": KP * TARGET},
                   inputs={"rocker.moment_y": Harmonic(0.5, 60.0)})
    system = with_feedback(loop, [_pd(8e-3)])
    generated = ctmm.simulate(system, 0.04, 4e-3, compiled=True, **options)
    plain = ctmm.simulate(system, 0.04, 4e-3, **options)
    assert sorted(generated.time_signals()) == sorted(plain.time_signals())
    for name in plain.time_signals():
        scale = max(1.0, float(np.max(np.abs(plain[name]))))
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-10 * scale, name
