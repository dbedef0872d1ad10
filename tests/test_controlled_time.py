"""Controlled chains in the time domain: DT-TMM with real-time, delayed and co-simulated control.

References (independent of the TMM code):

* ``ctmm.reference.delay_newmark.newmark_closed_loop`` -- textbook Newmark on ``M, C, K`` with
  the loop forces of the rule documented in ``ctmm/control/simulate.py`` (same scheme, same
  history rule): the DT-TMM must equal it to round-off;
* ``ctmm.reference.delay_chain.method_of_steps`` -- the exact delay differential equation
  (DOP853, rtol 1e-12): the DT-TMM must converge to it at order 2;
* the embedded (implicit) PD against the co-simulated PD object as the sample time goes to zero
  (zero-order hold: first order), and FMU against Python controllers (same law, same answer).
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import ctmm
from ctmm.control import ControlledChain, Feedback, FMUController, build_fmu, simulate_controlled
from ctmm.errors import ModelError, SimulationError
from ctmm.reference.delay_chain import GlobalLoop, method_of_steps
from ctmm.reference.delay_newmark import newmark_closed_loop

from _controllers_import import load_controllers
from test_controlled_frequency import build

controllers = load_controllers()

X0 = [-0.05, 0.0, 0.1]
V0 = [0.0, 0.3, 0.0]


def seed_setup(loops):
    """Seed Fig. 9.37 chain: ground -[K1,C1]- m0 -[K3,C3]- m1 -[K5,C5]- m2 (free end)."""
    return build([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0], [0.0] * 3,
                 start="fixed", end="free", loops=loops)


def initial(values):
    return {f"m{i}": v for i, v in enumerate(values) if v != 0.0}


def dttmm(setup, t_final, dt, x0=X0, v0=V0, **kwargs):
    result = simulate_controlled(setup.system, t_final, dt, x0=initial(x0), v0=initial(v0), **kwargs)
    return result, np.column_stack([result[f"m{i}.x"] for i in range(setup.chain.size)])


def slope(errors, steps) -> float:
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


# --------------------------------------------------------------- DT-TMM = global Newmark
H = 0.01
ROUNDOFF_CASES = {
    "downstream real-time": [(2, "displacement", 0, 5.0, 0.0, None, False)],
    "downstream tau < h": [(2, "displacement", 0, 5.0, 0.004, None, False)],
    "downstream delayed 5h": [(2, "displacement", 0, 5.0, 0.05, None, False)],
    "downstream delayed 5.3h": [(2, "displacement", 0, 5.0, 0.053, None, False)],
    "upstream velocity real-time": [(0, "velocity", 2, 3.0, 0.0, None, False)],
    "upstream velocity delayed 4h": [(0, "velocity", 2, 3.0, 0.04, None, False)],
    "collocated velocity tau < h": [(1, "velocity", 1, 2.0, 0.007, None, False)],
    "across relative velocity": [(1, "velocity", 1, 3.0, 0.0, 0, True)],
    "three loops mixed": [(2, "displacement", 0, 5.0, 0.03, None, False),
                          (1, "velocity", 1, 3.0, 0.0, 0, True),
                          (0, "displacement", 2, -20.0, 0.0, None, False)],
}


@pytest.mark.parametrize("case", list(ROUNDOFF_CASES))
def test_dttmm_equals_global_newmark_with_loops(case):
    setup = seed_setup(ROUNDOFF_CASES[case])
    result, x = dttmm(setup, 1.0, H)
    ref = newmark_closed_loop(setup.chain, setup.global_loops, 1.0, H, X0, V0)
    assert np.max(np.abs(x - ref.displacement)) < 1e-13
    for k, loop in enumerate(setup.loops):
        np.testing.assert_allclose(result[f"{loop.name}.y"], ref.sensed[:, k], rtol=0, atol=1e-13)
        np.testing.assert_allclose(result[f"{loop.name}.u"], ref.control[:, k], rtol=0, atol=1e-11)


@pytest.mark.parametrize("case", ["downstream real-time", "downstream delayed 5h"])
def test_reported_initial_control_force(case):
    setup = seed_setup(ROUNDOFF_CASES[case])
    result, _ = dttmm(setup, 1.0, H)
    ref = newmark_closed_loop(setup.chain, setup.global_loops, 1.0, H, X0, V0)
    assert result["loop0.u"][0] == pytest.approx(ref.control[0, 0], abs=1e-12)     # -Ka x6(0) = -0.5 N


@settings(max_examples=12, deadline=None, derandomize=True)
@given(st.integers(0, 2**31 - 1))
def test_dttmm_equals_global_newmark_random_loops(seed):
    rng = np.random.default_rng(seed)
    loops = []
    for _ in range(int(rng.integers(1, 4))):
        quantity = str(rng.choice(["displacement", "velocity"]))
        sensor, actuator = int(rng.integers(3)), int(rng.integers(3))
        across = bool(actuator >= 1 and rng.random() < 0.3)
        # delays: 0, inside the step, whole steps or any multiple of the step
        delay = float(rng.choice([0.0, 0.003, 0.02, 0.05]))
        if rng.random() < 0.5:
            delay = float(rng.uniform(0.0, 0.1))
        gain = float(rng.uniform(-1, 1) * (20.0 if quantity == "displacement" else 1.0))
        loops.append((sensor, quantity, actuator, gain, delay, None, across))
    setup = seed_setup(loops)
    _, x = dttmm(setup, 0.5, H)
    ref = newmark_closed_loop(setup.chain, setup.global_loops, 0.5, H, X0, V0)
    assert np.max(np.abs(x - ref.displacement)) < 1e-12


def test_delayed_velocity_loop_non_integer_delay_equals_global_newmark():
    setup = seed_setup([(2, "velocity", 0, 3.0, 0.053, None, False)])
    _, x = dttmm(setup, 1.0, H)
    ref = newmark_closed_loop(setup.chain, setup.global_loops, 1.0, H, X0, V0)
    assert np.max(np.abs(x - ref.displacement)) < 1e-12


@pytest.mark.parametrize("delay", [0.0, 0.05])
def test_acceleration_loop_equals_global_newmark(delay):
    setup = seed_setup([(0, "acceleration", 2, 0.3, delay, None, False)])
    _, x = dttmm(setup, 1.0, H)
    ref = newmark_closed_loop(setup.chain, setup.global_loops, 1.0, H, X0, V0)
    assert np.max(np.abs(x - ref.displacement)) < 1e-12


# ------------------------------------------------------------ convergence to the exact DDE
def convergence(loops, steps, t_final=0.6):
    setup = seed_setup(loops)
    exact = method_of_steps(setup.chain, setup.global_loops, t_final, X0, V0, rtol=1e-12, atol=1e-14)
    errors, ref_errors = [], []
    for dt in steps:
        result, x = dttmm(setup, t_final, dt)
        truth = exact.evaluate(result.time).displacement
        errors.append(np.max(np.abs(x - truth)))
        ref = newmark_closed_loop(setup.chain, setup.global_loops, t_final, dt, X0, V0)
        ref_errors.append(np.max(np.abs(ref.displacement - truth)))
    return np.array(errors), np.array(ref_errors)


@pytest.mark.parametrize("name, loops", [
    ("real-time", [(2, "displacement", 0, 5.0, 0.0, None, False), (1, "velocity", 1, 3.0, 0.0, 0, True)]),
    ("delayed", [(2, "displacement", 0, 5.0, 0.05, None, False), (0, "velocity", 2, 2.0, 0.033, None, False)]),
])
def test_dttmm_converges_to_method_of_steps_at_order_two(name, loops):
    steps = np.array([0.02, 0.01, 0.005])
    errors, ref_errors = convergence(loops, steps)
    assert 1.9 < slope(errors, steps) < 2.1, errors
    assert errors[-1] < 2e-4
    assert 1.9 < slope(ref_errors, steps) < 2.1, ref_errors


def test_realtime_acceleration_loop_converges_at_order_two():
    steps = np.array([0.02, 0.01, 0.005])
    errors, ref_errors = convergence([(0, "acceleration", 2, 0.3, 0.0, None, False)], steps)
    assert 1.9 < slope(ref_errors, steps) < 2.1
    assert 1.9 < slope(errors, steps) < 2.1, errors


# --------------------------------------------------- embedded PD vs co-simulated PD
def test_embedded_pd_equals_cosimulated_pd_as_sample_time_vanishes():
    kp, kd = 40.0, 4.0
    base = seed_setup([])
    embedded = ControlledChain(base.plant, [Feedback("pd", [("m2.x", kp), ("m2.v", kd)], "m0", gain=1.0)])
    steps = np.array([0.004, 0.002, 0.001])
    differences = []
    for h in steps:
        a = simulate_controlled(embedded, 0.3, h, x0=initial(X0), v0=initial(V0))
        pd = controllers.SaturatedPD(("m2.x", "m2.v"), ("m0.force",), kp=kp, kd=kd, sample_time=h)
        b = simulate_controlled(base.plant, 0.3, h, x0=initial(X0), v0=initial(V0), controllers=[pd])
        differences.append(max(np.max(np.abs(a[f"m{i}.x"] - b[f"m{i}.x"])) for i in range(3)))
    assert 0.85 < slope(differences, steps) < 1.15, differences


# ---------------------------------------------------------------- FMU vs Python object
@pytest.fixture(scope="session")
def pd_fmu(tmp_path_factory):
    assert shutil.which("gcc"), "gcc is required to build the test FMU"
    return build_fmu(controllers.fmu_source("pd_controller"), tmp_path_factory.mktemp("fmu_time"),
                     compiler="gcc")


def test_fmu_and_python_controllers_give_the_same_closed_loop(pd_fmu):
    plant = seed_setup([]).plant
    h, kp, kd, limit, reference = 2e-3, 60.0, 5.0, 4.0, 0.02
    fmu = FMUController(pd_fmu, inputs={"y": "m2.x", "ydot": "m2.v"}, outputs={"u": "m0.force"},
                        parameters={"kp": kp, "kd": kd, "limit": limit, "reference": reference},
                        sample_time=2 * h)
    python = controllers.SaturatedPD(("m2.x", "m2.v"), ("m0.force",), kp=kp, kd=kd, limit=limit,
                                     reference=reference, sample_time=2 * h)
    a = simulate_controlled(plant, 1.0, h, x0=initial(X0), controllers=[fmu])
    b = simulate_controlled(plant, 1.0, h, x0=initial(X0), controllers=[python])
    samples = a.extra["m0.force@samples"]
    assert np.all(np.diff(samples[:, 0]) > 0)              # one sample per sample time
    assert np.any(np.abs(samples[:, 1]) == limit)          # the saturation is exercised
    np.testing.assert_array_equal(samples, b.extra["m0.force@samples"])
    np.testing.assert_array_equal(a.states, b.states)


# ------------------------------------------------------------------- failures and errors
@pytest.mark.parametrize("loop, t_final", [
    ((2, "displacement", 2, -6.5e4, 0.0, None, False), 5.0),     # real-time positive feedback
    ((2, "displacement", 2, -2.0e5, 0.02, None, False), 50.0),   # delayed positive feedback
], ids=["real-time", "delayed"])
def test_diverging_closed_loop_stops_with_simulation_error(loop, t_final):
    """Stopped at the divergence bound (not at overflow), naming the loop; the partial result has
    every signal, cut at the last good step, and equals the global closed-loop Newmark there."""
    setup = seed_setup([loop])
    with pytest.raises(SimulationError, match=r"diverged.*\['loop0'\].*unstable_root_count.*delay_margin") as info:
        simulate_controlled(setup.system, t_final, 0.01, x0=initial(X0), v0=initial(V0))
    error = info.value
    assert error.time is not None and 0.0 < error.time < t_final
    assert error.element in {e.name for e in setup.plant.elements}
    partial = error.partial_result
    assert partial is not None and partial.time[-1] == pytest.approx(error.time - 0.01)
    rows = len(partial.time)
    for name in ("m2.x", "loop0.y", "loop0.u"):
        assert len(partial[name]) == rows and np.all(np.isfinite(partial[name]))
    bound = 1e6 * max(1.0, max(abs(v) for v in X0))
    assert 1e-3 * bound < np.max(np.abs(partial["m2.x"])) <= bound      # stopped at the bound, not at 1e308
    ref = newmark_closed_loop(setup.chain, setup.global_loops, partial.time[-1], 0.01, X0, V0)
    scale = np.max(np.abs(ref.displacement), axis=0)
    x = np.column_stack([partial[f"m{i}.x"] for i in range(3)])
    assert np.max(np.abs(x - ref.displacement) / scale) < 1e-9
    np.testing.assert_allclose(partial["loop0.u"], ref.control[:, 0], rtol=1e-9, atol=0)


def test_divergence_bound_option():
    setup = seed_setup([(2, "displacement", 2, -6.5e4, 0.0, None, False)])
    with pytest.raises(SimulationError, match="beyond the bound 10") as info:
        ctmm.simulate(setup.system, 5.0, 0.01, x0=initial(X0), divergence_bound=10.0)
    assert np.max(np.abs(info.value.partial_result["m2.x"])) <= 10.0
    with pytest.raises(ModelError, match="divergence_bound must be"):
        ctmm.simulate(setup.system, 5.0, 0.01, divergence_bound=0.0)


def test_algebraic_loop_is_detected():
    plant = seed_setup([]).plant
    pd = controllers.SaturatedPD(("m2.a", "m2.v"), ("m0.force",), kp=1.0, kd=0.1, sample_time=0.01)
    with pytest.raises(ModelError, match=r"algebraic loop.*m2\.a"):
        simulate_controlled(plant, 0.1, 0.01, controllers=[pd])
    # accepted explicitly with a one-sample lag
    result = simulate_controlled(plant, 0.1, 0.01, x0=initial(X0), controllers=[pd], coupling="previous")
    assert np.all(np.isfinite(result["m2.x"]))


def test_sample_time_must_be_a_multiple_of_the_step():
    plant = seed_setup([]).plant
    pd = controllers.SaturatedPD(("m2.x", "m2.v"), ("m0.force",), kp=1.0, kd=0.1, sample_time=0.015)
    with pytest.raises(ModelError, match="whole multiple"):
        simulate_controlled(plant, 0.1, 0.01, controllers=[pd])
