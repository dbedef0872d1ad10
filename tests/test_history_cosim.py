"""The one delay history (``ctmm.control.history``) and the one co-simulation master
(``ctmm.control.cosim``) against analytic signals and hand-counted sample times (issue 12, S1b)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.control.cosim import CoSimulation, check_wiring, sample_ratio
from ctmm.control.history import DelayHistory
from ctmm.control.protocol import ControllerStep
from ctmm.errors import ModelError, SimulationError


def cubic(t):
    return 0.3 - 1.2 * t + 2.5 * t ** 2 - 4.0 * t ** 3


def cubic_rate(t):
    return -1.2 + 5.0 * t - 12.0 * t ** 2


def test_hermite_is_exact_on_a_cubic_with_uneven_steps():
    times = np.cumsum([0.0, 0.1, 0.05, 0.2, 0.07, 0.13, 0.1])
    history = DelayHistory(0.0, cubic(0.0), cubic_rate(0.0), delay=1.0, step=0.05)
    for t in times[1:]:
        history.append(float(t), cubic(t), cubic_rate(t))
    queries = np.linspace(0.0, times[-1], 97)
    values = np.array([history(float(t)) for t in queries])
    np.testing.assert_allclose(values, cubic(queries), rtol=0, atol=1e-14)


def test_hermite_without_derivative_is_linear_between_samples():
    history = DelayHistory(0.0, cubic(0.0), None, delay=1.0, step=0.1)
    history.append(0.1, cubic(0.1), None)
    assert history(0.05) == pytest.approx(0.5 * (cubic(0.0) + cubic(0.1)), abs=1e-15)
    assert abs(history(0.05) - cubic(0.05)) > 1e-4          # not the cubic: the chord


def test_lagrange_is_exact_on_cubics_for_vector_signals():
    dt = 0.01
    grid = dt * np.arange(12)
    signal = lambda t: np.array([cubic(t), 2.0 * cubic(t) - t])        # noqa: E731
    history = DelayHistory(0.0, signal(0.0), delay=0.05, step=dt, interpolation="lagrange")
    for t in grid[1:]:
        history.append(float(t), signal(t))
    for t in np.linspace(0.0, grid[-1], 53):
        np.testing.assert_allclose(history(float(t)), signal(t), rtol=0, atol=1e-13)


def test_before_the_start_the_held_state_and_at_the_start_the_start_value():
    history = DelayHistory(1.0, 5.0, 0.0, before=7.0, delay=0.5, step=0.1)
    assert history(0.2) == 7.0 and history(1.0) == 5.0
    vector = DelayHistory(0.0, np.array([1.0, 2.0]), delay=0.1, step=0.1, interpolation="lagrange")
    np.testing.assert_array_equal(vector(-0.3), [1.0, 2.0])


def test_window_is_order_delay_over_step_and_lookups_stay_exact():
    dt, tau = 1e-3, 0.05
    for interpolation in ("hermite", "lagrange"):
        history = DelayHistory(0.0, cubic(0.0), cubic_rate(0.0), delay=tau, step=dt, interpolation=interpolation)
        lengths = []
        for n in range(1, 4001):
            t = n * dt
            history.append(t, cubic(t), cubic_rate(t))
            lengths.append(history.window_length)
            if n % 500 == 0:     # the delayed value still reads the right samples after trimming
                s = t + dt - tau - 0.3 * dt
                assert history(s) == pytest.approx(cubic(s), rel=1e-12)
        bound = 2 * (math.ceil(tau / dt) + 4)
        assert max(lengths) <= bound and max(lengths[2000:]) == max(lengths[:2000])   # no growth with the run



def test_hermite_keeps_what_the_delay_reads_when_steps_are_shorter_than_the_window_step():
    """A solve_ivp method may take steps far shorter than the step the window is counted in (``tau * 1e-5`` on the
    loop driver): the window must still reach ``t - tau`` (it was trimmed by count and a lookup fell before it,
    "internal error"), and stay bounded."""
    tau, step, short = 0.05, 1e-3, 1e-5          # 5000 samples per delay against a window of 2 * 53
    history = DelayHistory(0.0, cubic(0.0), cubic_rate(0.0), delay=tau, step=step)
    lengths = []
    for n in range(1, 30001):
        t = n * short
        history.append(t, cubic(t), cubic_rate(t))
        lengths.append(history.window_length)
        if t > tau and n % 997 == 0:
            s = t - tau + 0.3 * short
            assert history(s) == pytest.approx(cubic(s), rel=1e-12)
    assert max(lengths) <= 2 * (tau / short + 3)    # bounded by the samples of one delay, not the run


def test_lookups_beyond_the_last_sample_or_before_the_window_are_refused():
    history = DelayHistory(0.0, 0.0, 0.0, delay=0.002, step=1e-3)
    for n in range(1, 50):
        history.append(n * 1e-3, float(n), 1.0)
    with pytest.raises(SimulationError, match="beyond the last step"):
        history(0.0495)
    with pytest.raises(SimulationError, match="before its window"):
        history(0.001)
    grid = DelayHistory(0.0, np.zeros(2), delay=1e-3, step=1e-3, interpolation="lagrange")
    grid.append(1e-3, np.ones(2))
    with pytest.raises(SimulationError, match="beyond the stored history"):
        grid(1.5e-3)
    with pytest.raises(SimulationError, match="off the step grid"):
        grid.append(2.5e-3, np.ones(2))


def test_array_samples_are_copied_and_bad_parameters_refused():
    buffer = np.array([1.0, 2.0])
    history = DelayHistory(0.0, np.zeros(2), delay=0.1, step=0.1, interpolation="lagrange")
    history.append(0.1, buffer)
    buffer[:] = 99.0
    np.testing.assert_array_equal(history(0.1), [1.0, 2.0])
    with pytest.raises(ModelError, match="interpolation must be one of"):
        DelayHistory(0.0, 0.0, interpolation="spline")
    with pytest.raises(ModelError, match="delay must be a finite number >= 0"):
        DelayHistory(0.0, 0.0, delay=-1.0)
    with pytest.raises(ModelError, match="step"):
        DelayHistory(0.0, 0.0, step=0.0)


class Recorder:
    """``u = y`` sampled every ``sample_time``; remembers its calls and whether it was closed."""

    def __init__(self, inputs=("x",), sample_time=None, direct_feedthrough=False, fail=None, outputs=("u",)):
        self.inputs, self.outputs = tuple(inputs), tuple(outputs)
        self.sample_time, self.direct_feedthrough, self.fail = sample_time, direct_feedthrough, fail
        self.calls, self.closed = [], None

    def init(self, t0):
        if self.fail == "init":
            raise RuntimeError("no licence")
        return 0

    def step(self, t, y, state):
        self.calls.append(t)
        if self.fail == "nan":
            return ControllerStep(np.array([math.nan]), state)
        if self.fail == "shape":
            return np.array([1.0])
        return ControllerStep(np.array([y[0]]), state + 1)

    def close(self, state):
        self.closed = state


def test_zero_order_hold_samples_every_ratio_steps_once_and_records_them():
    dt = 0.01
    fast, slow = Recorder(), Recorder(sample_time=0.03, outputs=("w",))     # one controller per actuator
    master = CoSimulation([fast, slow], dt, 0.0)
    measured, held = [], []
    for n in range(10):
        t = n * dt
        for _ in range(2):         # a step may ask twice (initial call and first step): one sample
            master.sample(n, t, lambda i: measured.append((i, t)) or np.array([t]))
        held.append(master.held[1][0])
    assert fast.calls == pytest.approx([n * dt for n in range(10)])
    assert slow.calls == pytest.approx([0.0, 0.03, 0.06, 0.09])
    assert len(measured) == 14                          # inputs read only when due
    np.testing.assert_allclose(held, [0.0] * 3 + [0.03] * 3 + [0.06] * 3 + [0.09], atol=1e-15)
    samples = master.outputs(until=0.065)["w@samples"]
    np.testing.assert_allclose(samples, [[0.0, 0.0], [0.03, 0.03], [0.06, 0.06]], atol=1e-15)
    assert master.describe()[1]["sample_time"] == pytest.approx(0.03)
    master.close()
    assert fast.closed == 10 and slow.closed == 4


def test_sample_times_must_be_whole_multiples_of_the_step():
    assert sample_ratio(None, 0.01) == 1 and sample_ratio(0.05, 0.01) == 5
    with pytest.raises(ModelError, match=r"sample_time 0.025 must be a whole multiple of dt = 0.01"):
        CoSimulation([Recorder(sample_time=0.025)], 0.01, 0.0)
    with pytest.raises(ModelError, match="whole multiple"):
        sample_ratio(0.004, 0.01)


def test_direct_feedthrough_from_an_instantaneous_signal_is_an_algebraic_loop():
    instantaneous = {"m2.a"}
    with pytest.raises(ModelError, match=r"algebraic loop.*\['m2.a'\].*coupling='previous'"):
        CoSimulation([Recorder(("m2.a",), direct_feedthrough=True)], 0.01, 0.0, instantaneous=instantaneous)
    CoSimulation([Recorder(("m2.a",), direct_feedthrough=True)], 0.01, 0.0, instantaneous=instantaneous,
                 coupling="previous")
    CoSimulation([Recorder(("m2.a",))], 0.01, 0.0, instantaneous=instantaneous)      # no feedthrough: no loop
    CoSimulation([Recorder(("m2.x",), direct_feedthrough=True)], 0.01, 0.0, instantaneous=instantaneous)
    with pytest.raises(ModelError, match="coupling must be"):
        CoSimulation([], 0.01, 0.0, coupling="next")


@pytest.mark.parametrize("fail, match", [("nan", r"'c' returned a non-finite value \[nan\] at t = 0.02 s"),
                                         ("shape", r"'c' returned array\(\[1.\]\) at t = 0.02 s; expected "
                                                   r"\(outputs, state\)")])
def test_failing_controllers_are_named_with_the_time(fail, match):
    ok, bad = Recorder(outputs=("w",)), Recorder(fail=fail)
    master = CoSimulation([ok, bad], 0.01, 0.0, labels=["controller 'ok'", "controller 'c'"])
    bad.fail = None
    master.sample(0, 0.0, lambda i: np.zeros(1))
    bad.fail = fail
    with pytest.raises(SimulationError, match=match) as info:
        master.sample(2, 0.02, lambda i: np.zeros(1))
    assert info.value.time == pytest.approx(0.02) and info.value.element == "controller 'c'"


def test_a_failing_init_is_named_and_closes_the_controllers_already_started():
    first = Recorder(outputs=("w",))
    with pytest.raises(SimulationError, match=r"controller 'Recorder' \(outputs \['u'\]\) raised RuntimeError "
                                              r"at t = 0.5 s: no licence"):
        CoSimulation([first, Recorder(fail="init")], 0.01, 0.5)
    assert first.closed == 0



def test_wiring_is_checked_by_name_and_held_outputs_are_read_by_actuator_name():
    signals, actuators = ("hub.theta", "p1.slope"), ("motor.torque", "p1.voltage", "p2.voltage")
    a = Recorder(("hub.theta",), outputs=("p2.voltage",))
    b = Recorder(("p1.slope",), sample_time=0.02, outputs=("motor.torque",))
    assert check_wiring([a, b], signals, actuators, 0.01) == {"p2.voltage", "motor.torque"}
    bad = [Recorder(("hub.angle",), outputs=("p2.voltage",)),
           Recorder(("hub.theta",), sample_time=0.015, outputs=("p2.voltage", "motor.force"))]
    with pytest.raises(ModelError) as info:
        check_wiring(bad, signals, actuators, 0.01, what="test controllers")
    lines = str(info.value).splitlines()
    assert lines[0] == "test controllers are invalid:" and len(lines) == 5       # every problem, one per line
    assert "unknown input of controller 0 'hub.angle'; available: hub.theta, p1.slope" in lines[1]
    assert "'p2.voltage' is written by controllers 0 and 1" in lines[2]
    assert "unknown output of controller 1 'motor.force'; available: motor.torque, p1.voltage" in lines[3]
    assert "controller 1: sample_time 0.015 must be a whole multiple of dt = 0.01" in lines[4]
    master = CoSimulation([a, b], 0.01, 0.0)
    np.testing.assert_array_equal(master.held_values(actuators), [0.0, 0.0, 0.0])
    master.sample(0, 0.0, lambda i: np.array([1.5 + i]))          # a sees 1.5, b sees 2.5
    master.sample(1, 0.01, lambda i: np.array([-4.0]))             # only a is due
    np.testing.assert_array_equal(master.held_values(actuators), [2.5, 0.0, -4.0])      # unwritten: 0


def test_the_manipulator_holds_and_records_its_controller_samples():
    """A sampled controller on the manipulator scene: its samples recorded under ``"<output>@samples"``
    and each held over two steps (zero-order hold) -- the run equals one where the held values are an
    open-loop input, piecewise constant on the sample intervals."""
    import ctmm
    from ctmm.control import StaticGainController
    from ctmm.manipulator import SEED_MOVE, SEED_PZT_GAIN, HubPD, manipulator_scene, scene_references, seed_manipulator

    seed = seed_manipulator()
    pd = HubPD(10.0, 1.0)
    scene = manipulator_scene(seed, pd=pd, pzt=None)
    patch = seed.patch_names[0]
    ca = seed.moments_per_volt[0]
    sensors = [f"arm.{patch}_x1.slope_rate", f"arm.{patch}_x2.slope_rate"]
    controller = StaticGainController(sensors, [f"arm.{patch}_x2.moment"], [[ca * SEED_PZT_GAIN, -ca * SEED_PZT_GAIN]],
                                      sample_time=0.004)
    references = scene_references(pd, SEED_MOVE)
    sim = ctmm.simulate(scene, 0.012, 0.002, controllers=[controller], references=references)
    samples = sim[f"arm.{patch}_x2.moment@samples"]
    np.testing.assert_allclose(samples[:, 0], [0.0, 0.004, 0.008, 0.012], atol=1e-15)
    assert np.abs(samples[1:, 1]).max() > 0

    # replay: three runs of one sample interval each, the held value a constant input
    names = scene.plant.coordinates
    x0, v0, rows = None, None, []
    for k in range(3):
        shifted = {"hub_pd": (lambda t, s=0.004 * k: references["hub_pd"](t + s))}
        part = ctmm.simulate(scene, 0.004, 0.002, x0=x0, v0=v0, references=shifted,
                             inputs={f"arm.{patch}_x2.moment": float(samples[k, 1])})
        x0 = [float(part[name][-1]) for name in names]
        v0 = [float(part[f"{name}_dot"][-1]) for name in names]
        rows.append(part["arm.q1"][1:])
    replay = np.concatenate([[0.0], *rows])
    np.testing.assert_allclose(replay, sim["arm.q1"], rtol=0, atol=1e-12 * np.abs(sim["arm.q1"]).max())
