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
from ctmm.scenarios.four_bar import DAMPER, SPRING, mechanism, start
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
    with pytest.raises(ModelError, match="compiled"):      # feedback loops with DOP853 (loops with rk4: compiled)
        ctmm.simulate(with_feedback(loop, [Feedback("pd", sensor="crank.theta", actuator="h1.torque", gain=1.0)]),
                      0.01, 1e-3, x0=q0, v0=v0, compiled=True, method="DOP853")
    with pytest.raises(ModelError, match="violates the cut joints"):
        simulate_kinematic_loops_generated(loop, q0 + 0.1, v0, t_final=0.01, dt=1e-3)
    with pytest.raises(ModelError, match="CompiledKinematicLoops of this model"):
        simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.01, dt=1e-3, compiled="a kernel")


# -- spatial cut joints (ctmm.compiled_spatial_kinematic_loops) ---------------------------------------------------
def _spatial_cases():
    from spatial_loop_helpers import hinged_pendulum, hooke_pendulum, rusr

    four_bar = rusr()
    pendulum = hinged_pendulum()
    hooke = hooke_pendulum()
    return {
        "spherical (RUSR four-bar)": (four_bar, four_bar.consistent_state(
            {"h1.angle": 0.1, "h4.angle": 0.1}, {"h1.angle_rate": 3.0}, keep=["h1"])),
        "revolute (free body)": (pendulum, pendulum.consistent_state(
            {"free.qw": np.cos(0.25), "free.qy": np.sin(0.25), "free.x": 0.01}, {"free.wy": 2.0}, keep=["free.wy"])),
        "universal (free body)": (hooke, hooke.consistent_state(
            {"free.qw": np.cos(0.15), "free.qx": np.sin(0.15), "free.x": 0.01},
            {"free.wx": 1.5, "free.wy": -2.0, "free.wz": 0.7})),
    }


SPATIAL = _spatial_cases()


@pytest.mark.parametrize("case", list(SPATIAL))
def test_spatial_generated_run_equals_numpy_and_matches_the_dae(case):
    """Against the numpy RK4 with projection (<= 1e-12) and the global DAE (tests/test_spatial_closed_loops.py's
    bounds: rotations and positions 1e-9, cut loads 1e-7 relative)."""
    from spatial_loop_helpers import dae_of, poses

    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loops

    loop, (q, v) = SPATIAL[case]
    generated = simulate_spatial_kinematic_loops_generated(loop, q, v, t_final=0.06, dt=2e-3)
    numpy_run = simulate_spatial_loops(loop, q, v, t_final=0.06, dt=2e-3)
    assert generated.method == "rk4-generated"
    np.testing.assert_array_equal(generated.t, numpy_run.t)
    assert np.max(np.abs(generated.q - numpy_run.q)) <= 1e-12 and np.max(np.abs(generated.v - numpy_run.v)) <= 1e-12
    for name in ("cut_force", "cut_moment"):
        ours, theirs = getattr(generated, name), getattr(numpy_run, name)
        assert np.max(np.abs(ours - theirs)) <= 1e-12 * max(1.0, np.max(np.abs(theirs))), name
    assert generated.drift.max() < 1e-14 and generated.drift_rate.max() < 1e-13
    dae = dae_of(loop)
    t, Y = dae.simulate(dae.state(*poses(loop, generated.q[0], generated.v[0])), generated.t)
    angle = position = 0.0
    for k in range(len(t)):
        x, R, _, _ = poses(loop, generated.q[k], generated.v[k])
        angle = max(angle, max(np.abs(a - b).max() for a, b in zip(R, dae.rotations(Y[k]))))
        position = max(position, max(np.abs(a - b).max() for a, b in zip(x, dae.split(Y[k])[0])))
    assert angle < 1e-9 and position < 1e-9
    force = dae.accelerations(Y[-1])[1][-loop.n_constraints:][:3]     # the cut's rows are the DAE's last
    assert np.max(np.abs(force - generated.cut_force[-1, 0])) < 1e-7 * np.max(np.abs(force))


def test_spatial_simulate_verb_with_compiled_true():
    loop, (q, v) = SPATIAL["spherical (RUSR four-bar)"]
    generated = ctmm.simulate(loop, 0.02, 2e-3, x0=q, v0=v, compiled=True)
    plain = ctmm.simulate(loop, 0.02, 2e-3, x0=q, v0=v)
    assert generated.info["compiled"] is True and generated["s3.force_z"].shape == (11,)
    for name in ("h1.angle", "s3.force_z", "drift"):
        assert np.max(np.abs(generated[name] - plain[name])) <= 1e-12 * max(1.0, np.max(np.abs(plain[name]))), name
    with pytest.raises(ModelError, match="compiled=True runs the generated RK4.*alone"):   # outputs: the driver's
        ctmm.simulate(loop, 0.02, 2e-3, x0=q, v0=v, compiled=True, method="DOP853")      # run (loop_control)


def test_spatial_refusals_and_failures():
    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated

    loop, (q, v) = SPATIAL["spherical (RUSR four-bar)"]         # driven tree joints: test_compiled_spatial_driven_loops
    with pytest.raises(ModelError, match="violates the cut joints"):
        simulate_spatial_kinematic_loops_generated(loop, q + 0.1, v, t_final=0.01, dt=1e-3)
    with pytest.raises(SimulationError, match="projection onto the cut joints failed") as failure:
        simulate_spatial_kinematic_loops_generated(loop, q, 30 * v, t_final=1.0, dt=0.05)
    partial = failure.value.partial_result
    assert failure.value.element == "s3" and failure.value.time == pytest.approx(partial.t[-1] + 0.05)
    assert partial.q.shape == (len(partial.t), 4) and partial.cut_force.shape == (len(partial.t), 1, 3)


@pytest.mark.parametrize("which", ["slider_crank", "sliding_pendulum"])
def test_spatial_prismatic_cuts(which):
    """Prismatic cuts (the parent loaded at the moving child point): against the numpy RK4 (<= 1e-12) and the DAE with
    its own prismatic rows at the bounds of tests/test_spatial_closed_loops_prismatic.py (1e-10; cut loads 1e-9)."""
    import test_spatial_closed_loops_prismatic as prismatic

    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loops

    loop = getattr(prismatic, which)()
    start = ({"h1.angle": 0.3}, {"h1.angle_rate": 2.0}) if which == "slider_crank" else (
        {"h1.angle": 0.4, "free.z": -0.3}, {"h1.angle_rate": 1.5, "free.vz": 0.2})
    q, v = loop.consistent_state(*start, keep=["h1"])
    generated = simulate_spatial_kinematic_loops_generated(loop, q, v, t_final=0.04, dt=1e-3)
    numpy_run = simulate_spatial_loops(loop, q, v, t_final=0.04, dt=1e-3)
    assert np.max(np.abs(generated.q - numpy_run.q)) <= 1e-12 and np.max(np.abs(generated.v - numpy_run.v)) <= 1e-12
    scale = max(np.abs(numpy_run.cut_force).max(), np.abs(numpy_run.cut_moment).max())
    for name in ("cut_force", "cut_moment"):
        assert np.max(np.abs(getattr(generated, name) - getattr(numpy_run, name))) <= 1e-12 * scale, name
    model = prismatic.dae(loop)
    angle, position, Y = prismatic.errors(loop, generated, model)
    assert angle < 1e-10 and position < 1e-10 and generated.drift.max() < 1e-14
    force, moment = prismatic.cut_load_of_dae(loop, model, Y[-1], model.accelerations(Y[-1])[1])
    scale = max(np.abs(force).max(), np.abs(moment).max())
    assert np.max(np.abs(generated.cut_force[-1, 0] - force)) < 1e-9 * scale
    assert np.max(np.abs(generated.cut_moment[-1, 0] - moment)) < 1e-9 * scale
