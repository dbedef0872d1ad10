"""``ctmm.simulate_batch`` of planar and spatial sets *with loops* steps all sets together, one C call per block
(``ctmm.batch_loops``: each set's controller states and delay ring in its state, its loop gains, controller
realisation and reference fields in its parameter column): every result equals, to the bit, the run of its set
alone (the per-set path, ``executor="threads"``), and one set equals the numpy loop driver of a system built by
hand with its numbers (``ctmm.simulate`` without ``compiled``, its own history interpolation and controller
integration) to round-off; a diverging set fails alone, with the same error and partial result as alone.
Co-simulated controllers are refused by the mapped run (they run set by set)."""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest

import ctmm
from ctmm import batch as batch_module
from ctmm.control import Feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.errors import ModelError
from ctmm.signals import Harmonic

pytest.importorskip("casadi")
control = pytest.importorskip("control")

from test_batch import DT, X0, V0, arm, assert_round_off, spatial_arm  # noqa: E402
from test_batch_mapped import assert_fails_alone, count_mapped  # noqa: E402

T_FINAL = 0.06
LAG = control.tf([2.0], [1.0, 5.0])                     # an LTI controller: one state per set


def planar_system(pd_gain: float = 4.0, late_gain: float = -3.2, rod_mass: float = 1.0) -> ControlledModel:
    """The arm with a real-time PD on the shoulder, a loop delayed 3 steps and an LTI lag on the elbow."""
    return ControlledModel(arm(rod_mass=rod_mass), [
        Feedback("pd", [("rod.theta", 1.0), ("rod.omega", 0.3)], "pivot.torque", gain=pd_gain),
        Feedback("late", "elbow.angle", "elbow.torque", gain=late_gain, delay=3 * DT),
        Feedback("lag", "fore.omega", "elbow.torque", gain=LAG)])


PLANAR_SETS = [{"pd.gain": 4.0, "late.gain": -3.2, "rod.mass": 1.0, "pd.reference.amplitude": 0.1},
               {"pd.gain": 9.0, "late.gain": 0.5, "rod.mass": 1.6, "pd.reference.amplitude": 0.3},
               {"pd.gain": 6.0, "late.gain": -1.0, "rod.mass": 0.7, "pd.reference.amplitude": -0.2}]
PLANAR_OPTIONS = dict(x0=X0, v0=V0, references={"pd": Harmonic(0.1, 7.0, 0.2)}, outputs=["fore.out.y"],
                      store_every=2)
PLANAR_NAMES = ["rod.theta", "fore.theta", "rod.theta_dot", "fore.out.y", "pd.y", "pd.u", "late.y", "late.u",
                "lag.u"]


def spatial_system(gain: float = 2.0, push: float = 1.0, mass: float = 0.5) -> ControlledModel:
    """The spatial arm with a joint-torque loop and a body force at a point delayed 2 steps."""
    return ControlledModel(spatial_arm(masses=(1.0, 0.7, mass)), [
        Feedback("hold", "j1.angle", "j1.torque", gain=gain),
        Feedback("push", "l2.end.vz", "l2.end.force_z", gain=push, delay=2 * DT)])


SPATIAL_SETS = [{"hold.gain": 5.0, "push.gain": 0.8, "l2.mass": 0.5},
                {"hold.gain": 1.5, "push.gain": 2.0, "l2.mass": 0.9},
                {"hold.gain": 3.0, "push.gain": -1.0, "l2.mass": 0.6}]
SPATIAL_OPTIONS = dict(x0=np.array([0.3, -0.5, 0.2]), v0=np.zeros(3), outputs=["l2.end.z"],
                       references={"hold": 0.05}, store_every=2)
SPATIAL_DIVERGING_GAIN = -30.0          # positive feedback on j1: beyond the bound 3 after some rows
SPATIAL_NAMES = ["j0.angle", "j1.angle", "j2.angle_rate", "hold.u", "push.y", "push.u", "l2.end.z"]


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    """One cache folder for this module: each kernel compiled once."""
    return tmp_path_factory.mktemp("mapped_loops_cache")


def assert_same_bits(mapped, alone, count: int, names: list) -> None:
    assert not mapped.failures and not alone.failures
    for k in range(count):
        assert mapped.results[k].info["parameters"] == alone.results[k].info["parameters"]
        assert np.array_equal(mapped.results[k].time, alone.results[k].time)
        for name in names:
            assert np.array_equal(mapped.results[k][name], alone.results[k][name]), (k, name)


def test_planar_sets_with_loops_step_together_equal_each_set_alone_and_the_numpy_driver(cache, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(cache))
    calls = count_mapped(monkeypatch)
    mapped = ctmm.simulate_batch(planar_system(), PLANAR_SETS, T_FINAL, DT, **PLANAR_OPTIONS)
    alone = ctmm.simulate_batch(planar_system(), PLANAR_SETS, T_FINAL, DT, executor="threads", **PLANAR_OPTIONS)
    assert calls == [len(PLANAR_SETS)]                       # the default ran the sets together, threads did not
    assert_same_bits(mapped, alone, len(PLANAR_SETS), PLANAR_NAMES)
    assert np.max(np.abs(mapped.stacked("late.u")[0] - mapped.stacked("late.u")[1])) > 1e-3    # the sets differ
    values = PLANAR_SETS[1]
    built = planar_system(values["pd.gain"], values["late.gain"], values["rod.mass"])
    options = {**PLANAR_OPTIONS, "references": {"pd": Harmonic(values["pd.reference.amplitude"], 7.0, 0.2)}}
    numpy_run = ctmm.simulate(built, T_FINAL, DT, method="rk4", **options)
    for name in PLANAR_NAMES:
        assert_round_off(mapped.results[1][name], numpy_run[name], name)


def test_a_diverging_planar_set_with_loops_fails_alone_as_in_the_per_set_path(cache, monkeypatch):
    """Positive feedback: beyond the divergence bound after some rows (set 1), overflowing within two steps (set 3:
    its rows turn non-finite in the mapped run, beside the others; the default bound of the planar guard)."""
    monkeypatch.setenv("CTMM_CACHE", str(cache))
    sets = [PLANAR_SETS[0], {**PLANAR_SETS[1], "pd.gain": -200.0}, PLANAR_SETS[2], {"pd.gain": -4.0e7}]
    for bound, failed in ((2.0, [1, 3]), (None, [3])):
        options = {**PLANAR_OPTIONS, "divergence_bound": bound, "stability_check": "ignore"}
        mapped = ctmm.simulate_batch(planar_system(), sets, T_FINAL, DT, **options)
        alone = ctmm.simulate_batch(planar_system(), sets, T_FINAL, DT, executor="threads", **options)
        assert_fails_alone(mapped, alone, failed, PLANAR_NAMES, ["rod.theta", "pd.u", "late.y", "lag.u"])
        if bound is not None:
            assert len(mapped.failures[1].partial_result.time) > 5       # some rows before the bound
    assert "beyond the bound 1e+06" in str(mapped.failures[3])
    assert len(mapped.results[1].time) == 16                 # without the bound, set 1 ran to the end beside set 3


def test_spatial_sets_with_loops_step_together_equal_each_set_alone_and_the_numpy_driver(cache, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(cache))
    calls = count_mapped(monkeypatch)
    mapped = ctmm.simulate_batch(spatial_system(), SPATIAL_SETS, T_FINAL, DT, **SPATIAL_OPTIONS)
    alone = ctmm.simulate_batch(spatial_system(), SPATIAL_SETS, T_FINAL, DT, executor="threads", **SPATIAL_OPTIONS)
    assert calls == [len(SPATIAL_SETS)]
    assert_same_bits(mapped, alone, len(SPATIAL_SETS), SPATIAL_NAMES)
    assert np.max(np.abs(mapped.stacked("hold.u")[0] - mapped.stacked("hold.u")[1])) > 1e-3
    values = SPATIAL_SETS[2]
    numpy_run = ctmm.simulate(spatial_system(values["hold.gain"], values["push.gain"], values["l2.mass"]), T_FINAL,
                              DT, method="rk4", **SPATIAL_OPTIONS)
    for name in SPATIAL_NAMES:
        assert_round_off(mapped.results[2][name], numpy_run[name], name)


def test_a_diverging_spatial_set_with_loops_fails_alone_as_in_the_per_set_path(cache, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(cache))
    sets = [SPATIAL_SETS[0], {**SPATIAL_SETS[1], "hold.gain": SPATIAL_DIVERGING_GAIN}, SPATIAL_SETS[2],
            {"hold.gain": -4.0e7}]
    mapped = ctmm.simulate_batch(spatial_system(), sets, T_FINAL, DT, divergence_bound=3.0, **SPATIAL_OPTIONS)
    alone = ctmm.simulate_batch(spatial_system(), sets, T_FINAL, DT, divergence_bound=3.0, executor="threads",
                                **SPATIAL_OPTIONS)
    assert_fails_alone(mapped, alone, [1, 3], SPATIAL_NAMES, ["j1.angle", "hold.u", "push.y"])
    assert len(mapped.failures[1].partial_result.time) > 5                 # some rows before the bound


def test_sets_on_threads_build_their_expressions_one_at_a_time(cache, monkeypatch):
    """casadi releases the GIL while it builds expressions, and the kernel's shared sensors cache their kinematics
    per symbol: sets run on threads used to build their loop laws side by side and, now and then, one set's sensor
    function held another set's symbols (it failed, "variables [v_0] are free"; 2 of 80 batches of 12 sets).  Each
    set's expressions are now built under the kernel's lock: never two at once (a set lingering in its build makes an
    overlap certain on the old code), and every set still equals its mapped run to the bit."""
    monkeypatch.setenv("CTMM_CACHE", str(cache))
    building, most = [0], [0]
    count = threading.Lock()
    loop_run = batch_module.ParameterKernel.loop_run

    def lingering_loop_run(self, *args, **kwargs):
        with count:
            building[0] += 1
            most[0] = max(most[0], building[0])
        try:
            time.sleep(0.02)                        # a slow build: other threads would enter meanwhile
            return loop_run(self, *args, **kwargs)
        finally:
            with count:
                building[0] -= 1

    monkeypatch.setattr(batch_module.ParameterKernel, "loop_run", lingering_loop_run)
    sets = PLANAR_SETS * 3
    alone = ctmm.simulate_batch(planar_system(), sets, T_FINAL, DT, executor="threads", **PLANAR_OPTIONS)
    assert most[0] == 1
    mapped = ctmm.simulate_batch(planar_system(), sets, T_FINAL, DT, **PLANAR_OPTIONS)
    assert_same_bits(mapped, alone, len(sets), PLANAR_NAMES)


def test_a_set_with_a_bad_number_fails_alone_and_controllers_refuse_the_mapped_run(cache, monkeypatch):
    """A set whose numbers break its model (a negative mass) is reported by index, the others run together; a kernel
    with co-simulated controllers refuses run_mapped by name (its controllers are called per set)."""
    monkeypatch.setenv("CTMM_CACHE", str(cache))
    kernel = batch_module.ParameterKernel(planar_system(), T_FINAL, DT, references=PLANAR_OPTIONS["references"],
                                          outputs=PLANAR_OPTIONS["outputs"], store_every=2)
    start = {"x0": X0, "v0": V0}
    runs = kernel.run_mapped([PLANAR_SETS[0], {"rod.mass": -1.0}, PLANAR_SETS[2]], start)
    assert runs[0][1] is None and runs[2][1] is None and isinstance(runs[1][1], ModelError)
    assert "rod" in str(runs[1][1]) and runs[1][0] is None
    assert np.array_equal(runs[2][0]["late.u"], kernel.run(PLANAR_SETS[2], **start)["late.u"])

    class Hold:
        inputs, outputs, sample_time, direct_feedthrough = ("rod.theta",), ("pivot.torque",), 4 * DT, False

        def init(self, t0, inputs):
            return {"pivot.torque": 0.0}

        def step(self, t, inputs):
            return {"pivot.torque": -inputs["rod.theta"]}

    cosimulated = batch_module.ParameterKernel(arm(), T_FINAL, DT, controllers=[Hold()])
    with pytest.raises(ModelError, match=r"run_mapped runs .* co-simulated controllers \(1\)"):
        cosimulated.run_mapped([{}], {})
