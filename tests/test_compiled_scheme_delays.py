"""Generated DT-TMM schemes with delays between the step samples, Wilson-theta with delays, and loops together with
co-simulated controllers (:mod:`ctmm.compiled_scheme_loops`, :mod:`ctmm.compiled_scheme_cosim`; issue 13).

(1) ``ctmm.simulate(ControlledModel(plant, loops), method=<scheme>, compiled=True)`` with delays that are not whole
multiples of ``dt`` equals the Python DT-TMM path (its delay history: cubic Hermite from the sensed values and their
rates) to round-off for every scheme, and Wilson-theta (equations at ``t_n + 1.4 dt``, between the samples) with a
delay of two steps too; (2) with co-simulated controllers as well (sampled between calls, the loops inside Newton,
Houbolt's restart, the ring's newest rates after a sample) equal to the Python path; (3) independent reference:
a delayed PD with ``tau = 3.75 dt`` and ``7.5 dt`` against the method of steps (DOP853) on the Lagrange equations,
second order for Newmark and Wilson-theta; (4) what still does not compile is refused by name (delays the Python
path refuses; spatial loops: tests/test_compiled_spatial_scheme_loops.py), and a failing controller beside loops keeps the loop signals in its
partial result as the Python path.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import control
import numpy as np
import pytest

import ctmm
from ctmm.compiled_scheme_loops import CompiledSchemeLoops
from ctmm.control import ControlledModel, Feedback
from ctmm.errors import ModelError, SimulationError
from ctmm.schemes import SCHEMES, Newmark, WilsonTheta
from ctmm.signals import Harmonic
from test_compiled_scene_schemes import DP_START, double_pendulum
from test_compiled_cosim import Failing
from test_compiled_scene_schemes_loops import delayed_pd_errors
from test_compiled_scheme_cosim import pid


@pytest.fixture(scope="module")
def plant():
    return double_pendulum()


def _start(model):
    return dict(zip(model.coordinates, DP_START[0])), dict(zip(model.coordinates, DP_START[1]))


def fractional_loops() -> list[Feedback]:
    """A PD 2.5 steps late, a saturating lag 1.7 steps late, a real-time rate loop (dt = 10 ms)."""
    return [Feedback("late", [("a.theta", 6.0), ("a.omega", 1.0)], "o.torque", gain=1.0, delay=0.025),
            Feedback("lag", "h.angle", "h.torque", gain=control.tf([2.0], [1.0, 3.0]), delay=0.017,
                     saturation=(-0.06, 0.06)),
            Feedback("damp", [("b.omega", 0.3)], "h.torque", gain=1.0)]


def controllers():
    """A PID on the base hinge every 3 steps and a rate feedback on the elbow every 2 steps."""
    return [pid("a.theta", "o.torque", 0.03, kp=20.0, ki=5.0, kd=2.0, derivative_filter_time=0.01, reference=0.3),
            pid("b.omega", "h.torque", 0.02, kp=1.5)]


def both_paths(controlled, t_final, options):
    """``(generated, python)`` runs (dt = 10 ms), equal within 1e-10 on every signal of the Python path."""
    generated = ctmm.simulate(controlled, t_final, 0.01, compiled=True, **options)
    python = ctmm.simulate(controlled, t_final, 0.01, **options)
    assert generated.info["method"].startswith("dt-tmm-generated/")
    assert np.array_equal(generated.time, python.time)
    assert set(python.signals()) <= set(generated.signals())
    for name in python.signals():
        assert np.max(np.abs(np.asarray(generated[name]) - np.asarray(python[name]))) <= 1e-10, name
    return generated, python


# ---------------------------------------------------------------- (1) delays between the samples, Wilson-theta
@pytest.mark.parametrize("scheme", sorted(SCHEMES))
def test_delays_between_the_samples_equal_the_python_delay_history(plant, scheme):
    x0, v0 = _start(plant)
    _, python = both_paths(ControlledModel(plant, fractional_loops()), 0.3,
                           dict(method=scheme, x0=x0, v0=v0, references={"late": 0.1}))
    assert 0.0 < np.mean(python["lag.saturated"]) < 1.0


def test_wilson_theta_reads_a_delay_of_whole_steps_between_the_samples(plant):
    """Equations at t_n + 1.4 dt: y(t - 2 dt) lies 0.6 dt before t_n (the ring interpolates)."""
    x0, v0 = _start(plant)
    loops = [Feedback("late", [("a.theta", 6.0), ("a.omega", 1.0)], "o.torque", gain=1.0, delay=0.02)]
    compiled = CompiledSchemeLoops(ControlledModel(plant, loops), "wilson_theta", dt=0.01)
    assert compiled.hermite and compiled.reads[compiled.fraction] == [(-1, pytest.approx(0.4))]
    both_paths(ControlledModel(plant, loops), 0.2, dict(method="wilson_theta", x0=x0, v0=v0))


@dataclass(frozen=True)
class WilsonAfterNewmark(WilsonTheta):
    """Wilson-theta (equations at ``t_n + 1.4 dt``) after two average-acceleration Newmark steps (at ``t_n + dt``):
    a start-up at another evaluation fraction (none of ctmm.schemes.SCHEMES has one)."""

    name: ClassVar[str] = "wilson_after_newmark"
    start_up_steps: ClassVar[int] = 2

    def coefficients(self, history, h):
        if history.steps < self.start_up_steps:
            return Newmark().coefficients(history, h)
        return super().coefficients(history, h)

    def update(self, history, delta, h, coeffs):
        if history.steps < self.start_up_steps:
            return Newmark().update(history, delta, h, coeffs)
        return super().update(history, delta, h, coeffs)


def test_a_start_up_at_another_fraction_reads_the_ring_at_each_steps_own_time(plant):
    """The delay ring read at the start-up's fraction (1) in its two steps and at 1.4 later, as the Python delay
    history is read at each step's own evaluation time: equal to round-off (the PD 2.5 steps late, the lag 1.7)."""
    x0, v0 = _start(plant)
    loops = fractional_loops()[:2]
    compiled = CompiledSchemeLoops(ControlledModel(plant, loops), WilsonAfterNewmark(), dt=0.01)
    assert compiled.fractions == (1.0, 1.4) and compiled.fraction == 1.4
    assert compiled.reads[1.0] == [(-2, pytest.approx(0.5)), (-1, pytest.approx(0.3))]
    assert compiled.reads[1.4] == [(-2, pytest.approx(0.9)), (-1, pytest.approx(0.7))]
    _, python = both_paths(ControlledModel(plant, loops), 0.2, dict(method=WilsonAfterNewmark(), x0=x0, v0=v0,
                                                                    references={"late": 0.1}))
    assert np.ptp(python["late.u"]) > 0.05
    short = ControlledModel(plant, [Feedback("late", "a.theta", "o.torque", gain=2.0, delay=0.012)])
    with pytest.raises(ModelError, match=r"shorter than 1.4 dt .* in some steps"):
        CompiledSchemeLoops(short, WilsonAfterNewmark(), dt=0.01)
    for compiled in (None, False):      # the Python path reads every step's fraction too (not only the first one's)
        with pytest.raises(ModelError, match=r"loop 'late': delay = 0.012 s is shorter than 1.4 dt .* in some steps"):
            ctmm.simulate(short, 0.1, 0.01, method=WilsonAfterNewmark(), compiled=compiled, x0=x0, v0=v0)

# ---------------------------------------------------------------- (2) loops and controllers together
@pytest.mark.parametrize("scheme", ["newmark", "houbolt", "wilson_theta"])
def test_loops_and_cosimulated_controllers_together_equal_the_python_path(plant, scheme):
    x0, v0 = _start(plant)
    options = dict(method=scheme, x0=x0, v0=v0, references={"late": 0.1}, inputs={"b.moment": Harmonic(0.2, 3.0)},
                   store_every=2, outputs=["a.out.x"], controllers=controllers())
    generated, python = both_paths(ControlledModel(plant, fractional_loops()), 0.3, options)
    assert generated.info["intervals"] == 20 and generated.info["controllers"] == python.info["controllers"]
    alone = ctmm.simulate(ControlledModel(plant, fractional_loops()), 0.3, 0.01, compiled=True,
                          **{**options, "controllers": []})
    assert np.max(np.abs(alone["a.theta"] - generated["a.theta"])) > 1e-3        # the controllers act


# ---------------------------------------------------------------- (3) method of steps
@pytest.mark.parametrize("scheme", ["newmark", "wilson_theta"])
def test_a_pd_delayed_between_the_samples_converges_at_second_order_to_the_method_of_steps(plant, scheme):
    """u(t) = -(kp theta_a(t - tau) + kd omega_a(t - tau)) against the method of steps on the Lagrange equations
    (:func:`test_compiled_scene_schemes_loops.method_of_steps`); tau = 3.75 dt and 7.5 dt: errors at T fall 4x."""
    errors = delayed_pd_errors(plant, 6.0, 1.0, 0.0375, 0.3, scheme)
    assert errors[0] < 6e-4 and abs(np.log2(errors[0] / errors[1]) - 2.0) < 0.15, errors


# ---------------------------------------------------------------- (4) refusals
@pytest.mark.parametrize("delay, scheme, match", [
    (0.005, "newmark", "shorter than the step dt"),
    (0.012, "wilson_theta", "shorter than 1.4 dt"),
])
def test_delays_the_python_path_refuses_are_refused_by_name(plant, delay, scheme, match):
    loop = Feedback("late", "a.theta", "o.torque", gain=2.0, delay=delay)
    for compiled in (True, None):
        with pytest.raises(ModelError, match=match):
            ctmm.simulate(ControlledModel(plant, [loop]), 0.1, 0.01, method=scheme, compiled=compiled)


def test_loops_with_controllers_refuse_a_given_compiled_step(plant):
    from ctmm.compiled_scheme_cosim import simulate_cosimulated_scheme_generated

    loops = fractional_loops()
    with pytest.raises(ModelError, match="compiled here"):
        simulate_cosimulated_scheme_generated(plant, *DP_START, t_final=0.1, dt=0.01, scheme="newmark",
                                              controllers=controllers(), loops=loops,
                                              compiled=CompiledSchemeLoops(ControlledModel(plant, loops), dt=0.01))
    with pytest.raises(ModelError, match="needs the step dt"):
        CompiledSchemeLoops(ControlledModel(plant, loops))


def test_a_failing_controller_beside_loops_keeps_the_loop_signals_in_its_partial_result(plant):
    x0, v0 = _start(plant)
    controlled = ControlledModel(plant, fractional_loops())
    failures = []
    for compiled in (True, None):
        with pytest.raises(SimulationError, match="controller broke") as info:
            ctmm.simulate(controlled, 0.1, 0.01, method="newmark", x0=x0, v0=v0, compiled=compiled,
                          references={"late": 0.1}, controllers=[Failing("b.omega", "h.torque")])
        failures.append(info.value.partial_result)
    generated, python = failures
    assert generated.time.tolist() == python.time.tolist() == [0.0, 0.01] and "lag.u" in python.signals()
    for name in python.signals():
        assert np.max(np.abs(np.asarray(generated[name]) - np.asarray(python[name]))) <= 1e-10, name
