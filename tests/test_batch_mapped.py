"""``ctmm.simulate_batch`` of planar sets without loops runs their RK4 in one C call per block over all sets
(``casadi.Function.map``, ctmm.batch.ParameterKernel.run_mapped): every result equals, to the bit, the run of
its set alone (the per-set path, executor="threads"); a diverging set fails alone, as in the per-set path.
The per-set path itself is checked against models built with the sets' numbers in tests/test_batch.py; one
set here against the independent Lagrange model with its own RK4."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm import batch as batch_module
from ctmm.errors import SimulationError
from ctmm.ode import integrate_rk4, second_order_rate
from ctmm.parameter_sets import with_parameters
from ctmm.reference.planar_lagrange import PlanarLagrange

pytest.importorskip("casadi")

from test_batch import DT, PLANAR_SETS, X0, V0, arm  # noqa: E402

T_FINAL = 0.1
NAMES = ["rod.theta", "fore.theta", "rod.theta_dot", "fore.theta_dot", "fore.out.y"]


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
    assert sorted(mapped.failures) == sorted(alone.failures) == [1]
    assert isinstance(mapped.failures[1], SimulationError) and type(mapped.failures[1]) is type(alone.failures[1])
    assert str(mapped.failures[1]) == str(alone.failures[1])
    partial, partial_alone = mapped.failures[1].partial_result, alone.failures[1].partial_result
    assert np.array_equal(partial["rod.theta"], partial_alone["rod.theta"])
    for k in (0, 2):
        assert np.array_equal(mapped.results[k]["fore.theta"], alone.results[k]["fore.theta"])
