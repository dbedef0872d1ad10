"""``ctmm.simulate_batch`` of planar and spatial sets runs their RK4 in one C call per block over
all sets (``casadi.Function.map``, ctmm.batch.ParameterKernel.run_mapped): every result equals, to the bit, the
run of its set alone (the per-set path, executor="threads"); a diverging set fails alone, as in the per-set path.
The per-set path itself is checked against models built with the sets' numbers in tests/test_batch.py (whose
spatial sets, run by default, go through the mapped path and are checked there against the numpy path and the
independent reference ``ctmm.reference.spatial_tree``); one planar set here against the independent Lagrange
model with its own RK4."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm import batch as batch_module
from ctmm.control import Feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.errors import ModelError, SimulationError
from ctmm.ode import integrate_rk4, second_order_rate
from ctmm.parameter_sets import with_parameters
from ctmm.reference.planar_lagrange import PlanarLagrange

pytest.importorskip("casadi")

from test_batch import DT, PLANAR_SETS, SPATIAL_SETS, X0, V0, arm, spatial_arm  # noqa: E402

T_FINAL = 0.1
NAMES = ["rod.theta", "fore.theta", "rod.theta_dot", "fore.theta_dot", "fore.out.y"]


def assert_fails_alone(mapped, alone, failed: list, names: list, partial_names: list) -> None:
    """The sets ``failed`` failed on both paths with the same error and partial result; the others equal to the bit."""
    assert sorted(mapped.failures) == sorted(alone.failures) == failed
    for k in failed:
        assert isinstance(mapped.failures[k], SimulationError) and type(mapped.failures[k]) is type(alone.failures[k])
        assert str(mapped.failures[k]) == str(alone.failures[k])
        partial, partial_alone = mapped.failures[k].partial_result, alone.failures[k].partial_result
        assert np.array_equal(partial.time, partial_alone.time)
        for name in partial_names:
            assert np.array_equal(partial[name], partial_alone[name]), (k, name)
    for k in sorted(set(range(len(mapped.results))) - set(failed)):
        for name in names:
            assert np.array_equal(mapped.results[k][name], alone.results[k][name]), (k, name)


def test_mapped_sets_equal_each_set_run_alone_to_the_bit(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    calls = []
    mapped_run = batch_module.ParameterKernel.run_mapped
    monkeypatch.setattr(batch_module.ParameterKernel, "run_mapped",
                        lambda self, sets, start: calls.append(len(sets)) or mapped_run(self, sets, start))
    sets = [values for values, _ in PLANAR_SETS]
    options = dict(x0=X0, v0=V0, outputs=["fore.out.y"], store_every=3)
    mapped = ctmm.simulate_batch(arm(), sets, T_FINAL, DT, **options)
    alone = ctmm.simulate_batch(arm(), sets, T_FINAL, DT, executor="threads", **options)
    assert calls == [len(sets)]                              # the default ran the sets together, threads did not
    assert not mapped.failures and not alone.failures
    for k in range(len(sets)):
        assert mapped.results[k].info["parameters"] == alone.results[k].info["parameters"] == sets[k]
        assert np.array_equal(mapped.results[k].time, alone.results[k].time)
        for name in NAMES:
            assert np.array_equal(mapped.results[k][name], alone.results[k][name]), (k, name)
    model = with_parameters(arm(), sets[1])
    lagrange = PlanarLagrange(model)
    rate = second_order_rate(lambda q, v, t: lagrange.accelerations(q, v, t), 2)
    steps = round(T_FINAL / DT)
    expected = integrate_rk4(rate, np.concatenate([X0, V0]), h=DT, n_steps=steps)
    got = np.r_[mapped.results[1]["rod.theta"][-1], mapped.results[1]["fore.theta"][-1]]
    assert np.max(np.abs(got - expected[:2])) <= 1e-10


def test_a_diverging_set_fails_alone_as_in_the_per_set_path(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    sets = [{"elbow.stiffness": 4.0}, {"elbow.stiffness": 4.0e9}, {"elbow.stiffness": 2.0}]   # the middle one blows up
    options = dict(x0=X0, v0=V0, divergence_bound=50.0, stability_check="ignore")
    mapped = ctmm.simulate_batch(arm(), sets, T_FINAL, DT, **options)
    alone = ctmm.simulate_batch(arm(), sets, T_FINAL, DT, executor="threads", **options)
    assert_fails_alone(mapped, alone, [1], ["fore.theta"], ["rod.theta"])


def count_mapped(monkeypatch) -> list:
    calls: list = []
    mapped_run = batch_module.ParameterKernel.run_mapped
    monkeypatch.setattr(batch_module.ParameterKernel, "run_mapped",
                        lambda self, sets, start: calls.append(len(sets)) or mapped_run(self, sets, start))
    return calls


@pytest.fixture(scope="module")
def spatial_cache(tmp_path_factory):
    """One cache folder for the spatial tests here: the kernel of spatial_arm compiled once."""
    return tmp_path_factory.mktemp("spatial_cache")


SPATIAL_X0, SPATIAL_V0 = np.array([0.3, -0.5, 0.2]), np.array([0.1, 0.4, -0.2])


def test_mapped_spatial_sets_equal_each_set_run_alone_to_the_bit(spatial_cache, monkeypatch) -> None:
    monkeypatch.setenv("CTMM_CACHE", str(spatial_cache))
    calls = count_mapped(monkeypatch)
    sets = [values for values, _ in SPATIAL_SETS] + [{"l0.mass": 0.8, "j2.stiffness": 3.0}]
    options = dict(x0=SPATIAL_X0, v0=SPATIAL_V0, inputs={"j1.torque": 0.3}, store_every=3)
    mapped = ctmm.simulate_batch(spatial_arm(), sets, T_FINAL, DT, **options)
    alone = ctmm.simulate_batch(spatial_arm(), sets, T_FINAL, DT, executor="threads", **options)
    assert calls == [len(sets)]
    assert not mapped.failures and not alone.failures
    model = spatial_arm()
    for k in range(len(sets)):
        assert mapped.results[k].info["parameters"] == alone.results[k].info["parameters"] == sets[k]
        assert np.array_equal(mapped.results[k].time, alone.results[k].time)
        for name in list(model.coordinates) + list(model.velocities):
            assert np.array_equal(mapped.results[k][name], alone.results[k][name]), (k, name)
    assert not np.array_equal(mapped.results[0]["j2.angle"], mapped.results[2]["j2.angle"])  # the sets differ


def test_a_diverging_spatial_set_fails_alone_as_in_the_per_set_path(spatial_cache, monkeypatch) -> None:
    monkeypatch.setenv("CTMM_CACHE", str(spatial_cache))
    sets = [{"j2.stiffness": 4.0}, {"j2.stiffness": 4.0e9}, {"j2.stiffness": 2.0}]      # the middle one blows up
    options = dict(x0=SPATIAL_X0, v0=SPATIAL_V0, divergence_bound=50.0, store_every=3)
    mapped = ctmm.simulate_batch(spatial_arm(), sets, T_FINAL, DT, **options)
    alone = ctmm.simulate_batch(spatial_arm(), sets, T_FINAL, DT, executor="threads", **options)
    assert_fails_alone(mapped, alone, [1], ["j2.angle"], ["j2.angle"])


def test_kernels_with_loops_or_inputs_run_mapped_and_progress_runs_set_by_set(spatial_cache, monkeypatch) -> None:
    """Kernels with loops (or open-loop inputs, planar: a kernel of kind "planar loops" without laws) map too, equal
    to their sets run alone (loops with delays, controllers, references, failures: tests/test_batch_mapped_loops.py);
    progress=True steps set by set."""
    monkeypatch.setenv("CTMM_CACHE", str(spatial_cache))
    calls = count_mapped(monkeypatch)
    controlled = ControlledModel(spatial_arm(), [Feedback("hold", "j1.angle", "j1.torque", gain=2.0)])
    for system, kind, start in ((controlled, "spatial loops", {"x0": SPATIAL_X0}), (arm(), "planar loops", {"x0": X0})):
        kernel = batch_module.ParameterKernel(system, T_FINAL, DT, **({} if kind.startswith("spatial") else
                                                                       {"inputs": {"pivot.torque": 0.1}}))
        assert kernel.kind == kind
        sets = [{"j1.stiffness": 0.9}, {"j1.stiffness": 0.2}] if kind.startswith("spatial") else \
            [{"rod.mass": 1.2}, {"rod.mass": 0.8}]
        runs = kernel.run_mapped(sets, start)
        for values, (result, error) in zip(sets, runs):
            alone = kernel.run(values, **start)
            assert error is None and all(np.array_equal(result[name], alone[name]) for name in alone.time_signals())
    calls.clear()
    ctmm.simulate_batch(spatial_arm(), [{"l0.mass": 1.2}], T_FINAL, DT, x0=SPATIAL_X0, v0=SPATIAL_V0, store_every=3,
                        inputs={"j1.torque": 0.3}, progress=True)
    assert calls == []                                        # progress=True reports set by set
