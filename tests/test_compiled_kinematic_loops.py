"""The generated RK4 with projection of planar kinematic loop models (ctmm.compiled_kinematic_loops, issues 13/16).

Consistency: the generated step states the numpy path's mechanism (KinematicLoopModel.solve and .project) on
symbols, so the two agree to round-off (<= 1e-12).  Independent reference: the global DAE of
:mod:`ctmm.reference.planar_dae` (absolute coordinates, Lagrange multipliers, DOP853 at 1e-11), at the bounds the
numpy path is tested at (tests/test_closed_loops.py).  Also: the verb ``ctmm.simulate(..., compiled=True)``, the
Baumgarte rate in the kernel, failures with time, cut joint and partial result, and the refusals.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.compiled_kinematic_loops import CompiledKinematicLoops, simulate_kinematic_loops_generated
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError, SimulationError
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel, simulate_kinematic_loops
from ctmm.scenarios.four_bar import DAMPER, SPRING, flexible_mechanism, flexible_start, mechanism, start
from ctmm.scenarios.four_bar import reference as four_bar_dae

LAWS = {"smooth": None, "cubic spring + damper": SPRING + DAMPER}


@pytest.fixture(scope="module", params=list(LAWS))
def compiled(request):
    loop = mechanism(LAWS[request.param])
    return loop, CompiledKinematicLoops(loop), request.param


def test_generated_run_equals_the_numpy_rk4_with_projection(compiled):
    loop, kernel, _ = compiled
    q0, v0 = start(loop)
    generated = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.1, dt=1e-3, compiled=kernel)
    numpy_run = simulate_kinematic_loops(loop, q0, v0, t_final=0.1, dt=1e-3)
    assert generated.method == "rk4-generated" and generated.t.shape == numpy_run.t.shape == (101,)
    np.testing.assert_array_equal(generated.t, numpy_run.t)
    assert np.max(np.abs(generated.q - numpy_run.q)) <= 1e-12
    assert np.max(np.abs(generated.qdot - numpy_run.qdot)) <= 1e-12 * np.max(np.abs(numpy_run.qdot))
    assert np.max(np.abs(generated.cut_force - numpy_run.cut_force)) <= 1e-12 * np.max(np.abs(numpy_run.cut_force))
    assert np.max(generated.drift) < 1e-12 and np.max(generated.drift_rate) < 1e-12
    assert np.ptp(generated.coordinate("crank.theta")) > 0.2                            # it moves


def test_generated_run_matches_the_global_dae(compiled):
    loop, kernel, law = compiled
    q0, v0 = start(loop)
    simulation = simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.4, dt=1e-3, compiled=kernel)
    dae = four_bar_dae(LAWS[law])
    names = ["crank", "coupler", "rocker"]
    state = dae.assemble(dict(zip(names, q0)), dict(zip(names, v0)))
    reference = dae.simulate(state, 0.4, t_eval=simulation.t)
    error = max(np.max(np.abs(simulation.coordinate(f"{n}.theta") - reference.angle(n))) for n in names)
    assert error < 2e-7                                                  # the numpy path's bound
    force_error = np.max(np.abs(simulation.cut_force[:, 0] - reference.forces[:, 3]))
    assert force_error < 1e-4 * np.max(np.abs(reference.forces[:, 3]))
    assert np.ptp(simulation.coordinate("crank.theta")) > 0.8


def test_simulate_verb_with_compiled_true():
    loop = mechanism(SPRING)
    q0, v0 = start(loop)
    generated = ctmm.simulate(loop, 0.05, 1e-3, x0=q0, v0=v0, compiled=True, outputs=["coupler.out.x"],
                              store_every=5)
    plain = ctmm.simulate(loop, 0.05, 1e-3, x0=q0, v0=v0, outputs=["coupler.out.x"], store_every=5)
    assert generated.info["compiled"] is True and generated.info["method"] == "rk4-generated"
    np.testing.assert_array_equal(generated.time, plain.time)
    for name in ("crank.theta", "rocker.theta_dot", "coupler.out.x", "h3.force_y"):
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-12 * max(1.0, np.max(np.abs(plain[name]))), name
    assert np.max(generated["drift"]) < 1e-12 and generated.units(["drift"]) == {"drift": "m"}


def test_the_baumgarte_rate_is_part_of_the_kernel():
    loop = mechanism()
    q0, v0 = start(loop)
    free = KinematicLoopModel(loop.tree, loop.cuts, baumgarte=0.0)
    runs = {}
    for model in (loop, free):
        generated = simulate_kinematic_loops_generated(model, q0, v0, t_final=0.02, dt=2e-3)
        numpy_run = simulate_kinematic_loops(model, q0, v0, t_final=0.02, dt=2e-3)
        assert np.max(np.abs(generated.q - numpy_run.q)) <= 1e-12
        runs[model.baumgarte] = generated.qdot[-1]
    assert np.max(np.abs(runs[0.0] - runs[20.0])) > 1e-12              # another kernel, not the cached one


def test_failures_name_time_cut_joint_and_keep_the_partial_result():
    loop = mechanism()
    q0, v0 = start(loop)
    with pytest.raises(SimulationError, match="projection onto the cut joints failed") as failure:
        simulate_kinematic_loops_generated(loop, q0, 10 * v0, t_final=2.0, dt=0.05)
    assert failure.value.element == "h3" and failure.value.time == pytest.approx(0.5)
    partial = failure.value.partial_result
    assert partial.t[-1] == pytest.approx(0.45) and partial.q.shape == (10, 3) and partial.cut_force.shape == (10, 1, 2)
    twice = KinematicLoopModel(loop.tree, [*loop.cuts, CutJoint("h3b", parent="rocker.out", child="coupler.out")])
    with pytest.raises(SimulationError, match="singular") as failure:
        simulate_kinematic_loops_generated(twice, q0, v0, t_final=0.01, dt=1e-3)
    assert failure.value.time == 0.0 and len(failure.value.partial_result.t) == 0
    with pytest.raises(SimulationError, match="singular"):           # the numpy path refuses it too
        simulate_kinematic_loops(twice, q0, v0, t_final=0.01, dt=1e-3)


def test_refusals():
    loop = mechanism()
    q0, v0 = start(loop)
    with pytest.raises(ModelError, match="compiled=True runs the generated RK4.*DOP853"):
        ctmm.simulate(loop, 0.01, 1e-3, x0=q0, v0=v0, method="DOP853", compiled=True)
    with pytest.raises(ModelError, match="compiled"):
        ctmm.simulate(loop, 0.01, 1e-3, x0=q0, v0=v0, compiled="yes")
    with pytest.raises(ModelError, match="compiled"):                  # feedback loops: still refused by name
        ctmm.simulate(with_feedback(loop, [Feedback("pd", sensor="crank.theta", actuator="h1.torque", gain=1.0)]),
                      0.01, 1e-3, x0=q0, v0=v0, compiled=True)
    flexible = flexible_mechanism(50.0, n_modes=1)
    with pytest.raises(ModelError, match="'h3'.*deformable body 'coupler'"):
        ctmm.simulate(flexible, 0.01, 1e-3, x0=flexible_start(flexible)[0], v0=flexible_start(flexible)[1],
                      compiled=True)
    with pytest.raises(ModelError, match="violates the cut joints"):
        simulate_kinematic_loops_generated(loop, q0 + 0.1, v0, t_final=0.01, dt=1e-3)
    with pytest.raises(ModelError, match="CompiledKinematicLoops of this model"):
        simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.01, dt=1e-3, compiled="a kernel")
