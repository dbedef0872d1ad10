"""The flexible bodies' guard inside the generated RK4 of spatial models (ctmm.compiled_spatial_guard): a
SpatialBeam driven past its deflection bound and a ctmm.fem.SpatialSubsystem driven past its small deformation
(too large a step) stop on the generated path at the same time, with the same element and the same partial result
as on the numpy RK4 (which checks after every step), also when the failing step is not a stored one; the
generated run itself stops (NaN from the failing step on) instead of integrating the diverged model to the end.
"""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

import ctmm
from ctmm.compiled_spatial import CompiledSpatialScene
from ctmm.errors import SimulationError
from ctmm.spatial.integrate import initial_state

from test_spatial_beam_guard import spinner

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SPIN = dict(x0={"arm.qy1": 0.01}, v0={"hub.angle_rate": 8.0})


def failure(model, t_final, dt, store_every, compiled, start):
    with pytest.raises(SimulationError) as caught:
        ctmm.simulate(model, t_final, dt, method="rk4", store_every=store_every, compiled=compiled, **start)
    return caught.value


def fem_chain():
    from scenarios import spatial_fem_chain as scenario

    return scenario.model(), dict(x0=scenario.INITIAL, v0=scenario.INITIAL_RATE)


@pytest.mark.parametrize("store_every", [1, 7])
@pytest.mark.parametrize("case", ["beam", "fem"])
def test_both_paths_stop_at_the_same_step_and_element(case, store_every):
    # the beam spins above its first critical speed without stiffening; the FE beam runs at 6x its step limit
    model, start, t_final, dt, element = ((spinner(False), SPIN, 2.0, 0.01, "arm") if case == "beam" else
                                          (*fem_chain(), 0.3, 3e-3, "beam1"))
    numpy_error = failure(model, t_final, dt, store_every, False, start)
    generated = failure(model, t_final, dt, store_every, True, start)
    assert generated.element == numpy_error.element == element
    assert generated.time == numpy_error.time and 0.0 < generated.time < t_final
    assert str(generated) == str(numpy_error).replace("(rk4)", "(rk4-generated)")
    failed_step = int(round(generated.time / dt))
    assert failed_step % store_every or store_every == 1           # with 7: the failing step is not a stored one
    ours, theirs = generated.partial_result, numpy_error.partial_result
    assert np.array_equal(ours.time, theirs.time) and ours.time[-1] < generated.time
    for name in model.coordinates:
        np.testing.assert_allclose(ours[name], theirs[name], rtol=1e-9, atol=1e-12, err_msg=name)


def test_the_generated_run_stops_after_the_failing_step(tmp_path):
    """The guard acts inside the generated loop: the step after which the deflection bound exceeds the length
    (t = 0.19 s, found above on the numpy path) returns NaN, the loop stops after its block of 4 steps."""
    model = spinner(False)
    scene = CompiledSpatialScene(model, rows=4, cache_dir=tmp_path)
    states = scene.run(initial_state(model, SPIN["x0"], SPIN["v0"]), 0.01, 200)
    assert len(states) == 20                                   # blocks of 4 rows: steps 17-20 hold the failure
    assert np.all(np.isfinite(states[:18])) and np.all(np.isnan(states[18:]))
    stable = spinner(True)
    assert np.all(np.isfinite(CompiledSpatialScene(stable, rows=4, cache_dir=tmp_path).run(
        initial_state(stable, SPIN["x0"], SPIN["v0"]), 0.01, 200)))


def test_numbers_as_inputs_refuse_finite_element_bodies_by_name():
    """One library per structure takes the numbers of rigid bodies and modal beams (tests/test_batch_beams.py): a
    model with a finite-element subsystem is refused by name (not a casadi dimension mismatch), on the plain and
    the controlled kernels."""
    from ctmm.compiled_spatial import SpatialRates
    from ctmm.compiled_spatial_loops import CompiledControlledSpatial
    from ctmm.control import Feedback, with_feedback
    from ctmm.errors import ModelError

    assert SpatialRates(spinner(True), numbers="inputs").layout          # a beam's numbers are inputs
    model, start = fem_chain()
    with pytest.raises(ModelError, match="finite-element bodies 'beam1'"):
        ctmm.simulate(model, 0.05, 0.01, method="rk4", compiled=True, parameters={"gravity.z": -9.0}, **start)
    with pytest.raises(ModelError, match="finite-element bodies 'beam1'"):
        SpatialRates(model, numbers="inputs")
    controlled = with_feedback(model, [Feedback("rate", "yaw.angle_rate", "body3.force_y", gain=-1.0)])
    with pytest.raises(ModelError, match="finite-element bodies 'beam1'"):
        CompiledControlledSpatial(controlled, 0.01, numbers="inputs")


def test_a_controlled_spinner_stops_at_the_time_of_the_numpy_loop_driver():
    """With a feedback loop (zero gain) the generated kernel with loops checks the beam too (on the stored rows,
    store_every=1: the time, element and partial result of the numpy loop driver) instead of running on."""
    from ctmm.control import Feedback, with_feedback

    controlled = with_feedback(spinner(False), [Feedback("rate", "hub.angle_rate", "arm.force_y", gain=0.0)])
    errors = [failure(controlled, 2.0, 0.01, 1, compiled, SPIN) for compiled in (False, True)]
    assert errors[0].element == errors[1].element == "arm"
    assert errors[0].time == errors[1].time and 0.0 < errors[1].time < 2.0
    assert np.array_equal(errors[0].partial_result.time, errors[1].partial_result.time)
