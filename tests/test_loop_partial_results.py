"""``ctmm.simulate`` returns one kind of result, also on failure, for kinematic loop models alone: the
``partial_result`` of a failed run is a :class:`ctmm.results.SimulationResult` with the signals of a whole run (cut
loads and drift included), equal to them at the rows before the failure -- planar and spatial, DT-TMM scheme
(``divergence_bound`` tripped) and RK4 (a step too large for the projection), numpy and generated (the generated
spatial scheme and both RK4s; the planar scheme is not generated alone).  The driver paths (loops, controllers) were
already of this kind (``ctmm.control.planar_time``).

Expected values: the whole run's signals from a run that does not fail (same state, a short end or a loose bound).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.errors import SimulationError
from ctmm.results import SimulationResult
from ctmm.scenarios import four_bar, spatial_four_bar


def _model(kind: str, spring: bool = True):
    if kind == "planar":
        loop = four_bar.mechanism(four_bar.SPRING) if spring else four_bar.mechanism()
        return (loop, *four_bar.start(loop))
    loop = spatial_four_bar.mechanism()
    return (loop, *spatial_four_bar.start(loop))


def _same_rows(partial, whole) -> None:
    assert isinstance(partial, SimulationResult) and partial.info["failed"] is True
    assert sorted(partial.time_signals()) == sorted(whole.time_signals())
    assert any(name.endswith(".force_x") for name in partial.time_signals()) and "drift" in partial.time_signals()
    n = len(partial.time)
    assert n >= 1
    np.testing.assert_array_equal(partial.time, whole.time[:n])
    for name in whole.time_signals():
        scale = max(1.0, float(np.max(np.abs(whole[name][:n]))))
        assert np.max(np.abs(partial[name] - whole[name][:n])) <= 1e-12 * scale, name


@pytest.mark.parametrize("kind, compiled", [("planar", None), ("spatial", None), ("spatial", True)])
def test_a_scheme_stopped_by_divergence_bound_keeps_a_whole_runs_signals(kind, compiled):
    """Newmark at 4 ms, ``divergence_bound=0.05``: stopped; the partial result has every signal of the run with a
    bound it stays within (cut loads, drift), equal at the stored rows before the stop (the run with the wide bound
    goes two steps past the stop: measured stops at 0.016 s planar, 0.004 s spatial, of 0.2 s)."""
    loop, q, v = _model(kind)
    options = dict(x0=q, v0=v, method="newmark", compiled=compiled)
    with pytest.raises(SimulationError, match="divergence_bound") as failure:
        ctmm.simulate(loop, 0.2, 4e-3, divergence_bound=0.05, **options)
    partial = failure.value.partial_result
    past = (round(float(partial.time[-1]) / 4e-3) + 2) * 4e-3
    assert past < 0.2
    whole = ctmm.simulate(loop, past, 4e-3, divergence_bound=100.0, **options)
    assert len(whole.time) > len(partial.time)
    _same_rows(partial, whole)


@pytest.mark.parametrize("kind, scale", [("planar", 10.0), ("spatial", 30.0)])
@pytest.mark.parametrize("compiled", [None, True])
def test_an_rk4_step_too_large_for_the_projection_keeps_a_whole_runs_signals(kind, scale, compiled):
    """RK4 at 50 ms with a fast start: the projection fails (planar at 0.5 s, spatial at the first step); the partial
    result has every signal of a whole run of the same start: the run to the last good time, or (stopped at the first
    step) one short step that the projection holds."""
    loop, q, v = _model(kind, spring=False)
    options = dict(x0=q, v0=scale * np.asarray(v), compiled=compiled)
    with pytest.raises(SimulationError, match="projection onto the cut joints failed") as failure:
        ctmm.simulate(loop, 1.0, 0.05, **options)
    partial = failure.value.partial_result
    last = float(partial.time[-1]) if isinstance(partial, SimulationResult) else 0.0
    whole = ctmm.simulate(loop, last, 0.05, **options) if last > 0.0 else ctmm.simulate(loop, 1e-4, 1e-4, **options)
    _same_rows(partial, whole)
