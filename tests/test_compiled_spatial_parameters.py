"""A spatial model's numbers as parameters of its generated kernels (issues 13/14: one library per structure).

Independent check: the numpy articulated sweep (``ctmm.spatial.accelerations``) and the numpy RK4
(``ctmm.simulate`` without ``compiled``) of a model *built with the changed numbers*, to round-off,
while the generated functions were built from the first model; the cache folder's files (counted by
the operating system) show that the changed model found the first one's library; the FMU is run by
fmpy with the changed numbers set through FMI.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError

pytest.importorskip("casadi")

from test_spatial_compiled import FAST_COMPILE, ball_chain, folded_chain, random_tree, start  # noqa: E402

from ctmm.compiled_spatial import CompiledSpatialScene, SpatialRates, simulate_spatial_generated  # noqa: E402
from ctmm.compiled_spatial_parameters import spatial_parameter_layout, spatial_parameter_vector  # noqa: E402


def renumbered(model: sp.SpatialModel, seed: int) -> sp.SpatialModel:
    """The model with other masses, inertias, 1-/2-DOF joint laws and gravity (same zeros and geometry)."""
    rng = np.random.default_rng(seed)
    bodies = [dataclasses.replace(body, mass=body.mass * rng.uniform(0.5, 2.0),
                                  inertia=np.asarray(body.inertia) * rng.uniform(0.5, 2.0)) for body in model.bodies]
    joints = []
    for joint in model.joints:
        if joint.kind in ("revolute", "prismatic", "universal") and not joint.driven:
            n = joint.velocity_count
            joint = dataclasses.replace(joint, stiffness=np.asarray(joint.stiffness) * rng.uniform(0.5, 2.0, n),
                                        damping=np.asarray(joint.damping) * rng.uniform(0.5, 2.0, n),
                                        reference=np.asarray(joint.reference) + rng.uniform(-0.3, 0.3, n))
        joints.append(joint)
    gravity = np.asarray(model.gravity) * rng.uniform(0.5, 1.5, 3)
    return sp.SpatialModel(model.name, bodies + joints + list(model.loads), gravity=gravity)


def relative(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - b)) / max(1.0, np.max(np.abs(b))))


@pytest.mark.parametrize("build, period", [(lambda: random_tree(5, 7, "free"), 0),
                                           (lambda: folded_chain(12, mixed=True), 3), (lambda: ball_chain(6), 2)])
def test_rates_built_once_take_the_numbers_of_another_model(build, period) -> None:
    """Straight-line (every joint kind, loads, inputs) and folded (per-segment parameter columns; a chain with
    ball joints too): the rates built from one model with the numbers of another equal the numpy sweep of
    the other."""
    model = build()
    rates = SpatialRates(model, fold=bool(period), numbers="inputs")
    assert rates.period == period
    q, v, inputs = start(5, model)
    for seed in (1, 2):
        other = renumbered(model, seed)
        assert [e.name for e in spatial_parameter_layout(other)] == [e.name for e in rates.layout]
        expected = sp.accelerations(other, q, v, 0.0, inputs)
        got = rates.velocity_rate(q, v, rates.input_vector(inputs), spatial_parameter_vector(other), 0.0)
        assert relative(np.asarray(got).reshape(-1), expected) < 1e-12, seed
        assert relative(expected, sp.accelerations(model, q, v, 0.0, inputs)) > 1e-3     # the numbers matter
    names = [e.name for e in rates.layout]
    assert "b0.mass" in names or "l0.mass" in names
    assert any(name.startswith("gravity.") for name in names)


def test_one_library_serves_models_of_one_structure(tmp_path) -> None:
    """Without loads (whose part of a body's terms keeps that body's numbers in the code) a changed
    model finds the first one's library and runs as its numpy RK4."""
    import test_spatial_pinocchio as pinocchio_tests

    base = pinocchio_tests.random_tree(np.random.default_rng(6), 5, "free", loads=False)
    # both built the same way (dataclasses.replace normalises a joint axis again, to round-off)
    model, other = renumbered(base, 1), renumbered(base, 3)
    q0, v0, inputs = start(6, model)
    scene = CompiledSpatialScene(model, cache_dir=tmp_path, flags=FAST_COMPILE, numbers="inputs")
    built = sorted(path.name for path in (tmp_path / "kernels").iterdir())
    again = CompiledSpatialScene(other, cache_dir=tmp_path, flags=FAST_COMPILE, numbers="inputs")
    assert sorted(path.name for path in (tmp_path / "kernels").iterdir()) == built and len(built) == 1
    generated = simulate_spatial_generated(other, 0.03, 1e-3, x0=q0, v0=v0, inputs=inputs, scene=again)
    numpy_run = ctmm.simulate(other, 0.03, 1e-3, x0=q0, v0=v0, inputs=inputs, method="rk4")
    for name in list(model.coordinates) + list(model.velocities):
        assert relative(generated[name], numpy_run[name]) < 1e-11, name
    assert relative(scene.accelerations(q0, v0, inputs), sp.accelerations(model, q0, v0, 0.0, inputs)) < 1e-12
    with pytest.raises(ModelError, match="numbers must be 'constants'.*'inputs'.*got 'symbols'"):
        SpatialRates(model, numbers="symbols")


def test_spatial_fmu_parameters_set_through_fmi_equal_ctmm_simulate(tmp_path) -> None:
    fmpy = pytest.importorskip("fmpy")
    model = folded_chain(3, mixed=True)
    q0, v0 = model.neutral() + 0.2, np.linspace(-0.5, 0.5, model.n_velocities)
    path = ctmm.export_fmu(model, tmp_path / "chain.fmu", step=1e-3, q0=q0, qdot0=v0)
    description = fmpy.read_model_description(str(path))
    parameters = [v.name for v in description.modelVariables if v.causality == "parameter"]
    layout = spatial_parameter_layout(model)
    assert [e.name for e in layout] == [name for name in parameters if not name.endswith("_start")]
    other = renumbered(model, 4)
    changed = {e.name: e.value for e in spatial_parameter_layout(other)}
    out = fmpy.simulate_fmu(str(path), stop_time=0.05, output_interval=0.01, start_values=changed)
    native = ctmm.simulate(other, 0.05, 1e-3, x0=q0, v0=v0, method="rk4")
    rows = np.searchsorted(native.time, out["time"] - 1e-12)
    for name in list(model.coordinates) + list(model.velocities):
        assert relative(out[name], native[name][rows]) < 1e-12, name
    with pytest.raises(ModelError, match="parameters.*'l0.color'"):
        ctmm.export_fmu(model, tmp_path / "chain.fmu", step=1e-3, parameters=["l0.color"])
