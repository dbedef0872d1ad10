"""Planar generated kernels keyed on the model's description before anything is built (issue 13;
ctmm.compiled_scene_key, ctmm.model_description.describe(numbers=False)).

A cached call builds no symbols (the symbolic builders are replaced by functions that raise); the cache
folder's files (counted by the operating system) show hits and misses; every scene's accelerations are
checked against the independent Lagrange model of its own model.
"""
from __future__ import annotations

import numpy as np
import pytest

from ctmm import compiled_parameters, compiled_scene_key
from ctmm.control import Feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.planar import ElasticHinge, Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.reference.planar_lagrange import PlanarLagrange

casadi = pytest.importorskip("casadi")
compiled_scene = pytest.importorskip("ctmm.compiled_scene")
CompiledScene = compiled_scene.CompiledScene


def pendulum(mass: float = 1.0, length: float = 0.8, stiffness: float = 2.0, angle: float = 0.2,
             rest: float = 0.1) -> PlanarModel:
    """Two links on an elastic and a smooth hinge; ``angle``: the ground's angle (a constant of the code)."""
    return PlanarModel.chain("pendulum", [
        Fixed("ground", angle=angle), ElasticHinge("base", stiffness=1.5, rest_angle=0.2),
        RigidBody.uniform_link("a", mass=mass, length=length),
        ElasticHinge("h", stiffness=stiffness, rest_angle=rest),
        RigidBody("b", mass=0.5 * mass, inertia=0.02, center_of_mass=(0.2, 0.01), outboard=(0.4, 0.0))],
        gravity=(0.0, -9.81))


def libraries(folder) -> list[str]:
    return sorted(path.name for path in (folder / "kernels").iterdir() if not path.name.startswith("."))


def forbid_building(monkeypatch) -> None:
    def refuse(*_args, **_kwargs):
        raise AssertionError("symbols were built although the library is cached")

    monkeypatch.setattr(compiled_scene, "symbolic_numbers", refuse)


def assert_lagrange(scene: CompiledScene, model: PlanarModel) -> None:
    rng = np.random.default_rng(5)
    q, v = rng.uniform(-1.0, 1.0, model.n_coordinates), rng.uniform(-1.0, 1.0, model.n_coordinates)
    expected = PlanarLagrange(model).accelerations(q, v, 0.0)
    assert np.max(np.abs(scene.accelerations(q, v) - expected)) <= 1e-10 * np.max(np.abs(expected))


def test_other_parameters_hit_without_building_and_other_constants_miss(tmp_path, monkeypatch) -> None:
    first = CompiledScene(pendulum(), cache_dir=tmp_path, rows=2)
    assert len(libraries(tmp_path)) == 1
    assert_lagrange(first, first.model)
    with monkeypatch.context() as patch:
        forbid_building(patch)
        for other in (pendulum(mass=1.7, length=1.1, stiffness=5.0), pendulum(mass=0.3)):   # entries of p
            scene = CompiledScene(other, cache_dir=tmp_path, rows=2)
            assert len(libraries(tmp_path)) == 1
            assert_lagrange(scene, other)
        with pytest.raises(AssertionError, match="symbols were built"):       # a constant of the code: built
            CompiledScene(pendulum(angle=0.4), cache_dir=tmp_path, rows=2)
    turned = CompiledScene(pendulum(angle=0.4), cache_dir=tmp_path, rows=2)
    assert len(libraries(tmp_path)) == 2
    assert_lagrange(turned, turned.model)
    zero = CompiledScene(pendulum(rest=0.0), cache_dir=tmp_path, rows=2)      # a zero is a constant too
    assert len(libraries(tmp_path)) == 3
    assert_lagrange(zero, zero.model)
    assert first.symbolic_step is not None and scene.symbolic_step is not None    # built on demand (FMU export)


def test_numbers_as_constants_miss_on_any_number_and_hit_on_the_same_model(tmp_path, monkeypatch) -> None:
    CompiledScene(pendulum(), cache_dir=tmp_path, rows=2, numbers="constants")
    with monkeypatch.context() as patch:
        forbid_building(patch)
        CompiledScene(pendulum(), cache_dir=tmp_path, rows=2, numbers="constants")
    assert len(libraries(tmp_path)) == 1
    other = CompiledScene(pendulum(mass=1.7), cache_dir=tmp_path, rows=2, numbers="constants")
    assert len(libraries(tmp_path)) == 2
    assert_lagrange(other, other.model)


def test_a_hit_that_does_not_compute_the_model_is_rebuilt(tmp_path, monkeypatch) -> None:
    """A structure key that missed a constant (simulated: every model one key) would find the library of
    another ground angle; the certification against the numpy sweep rejects it and the scene is built."""
    monkeypatch.setattr(compiled_scene_key, "structure_key", lambda model: "one key for every model")
    CompiledScene(pendulum(), cache_dir=tmp_path, rows=2)
    turned = pendulum(angle=0.4)
    scene = CompiledScene(turned, cache_dir=tmp_path, rows=2)
    assert len(libraries(tmp_path)) == 2
    assert_lagrange(scene, turned)


def test_loops_with_constant_numbers_key_on_the_description(tmp_path, monkeypatch) -> None:
    def system(gain: float) -> ControlledModel:
        plant = PlanarModel.chain("arm", [Fixed("ground"), SmoothHinge("pivot"),
                                          RigidBody.uniform_link("rod", mass=1.0, length=0.8)])
        return ControlledModel(plant, [Feedback("hold", "rod.theta", "pivot.torque", gain=gain)])

    first = CompiledScene(system(4.0), cache_dir=tmp_path, rows=2, numbers="constants", dt=1e-3)
    with monkeypatch.context() as patch:
        patch.setattr(compiled_parameters, "symbolic_loop_numbers", lambda *a, **k: (_ for _ in ()).throw(
            AssertionError("symbols were built although the library is cached")))
        forbid_building(patch)
        again = CompiledScene(system(4.0), cache_dir=tmp_path, rows=2, numbers="constants", dt=1e-3)
    assert len(libraries(tmp_path)) == 1
    CompiledScene(system(6.0), cache_dir=tmp_path, rows=2, numbers="constants", dt=1e-3)
    assert len(libraries(tmp_path)) == 2
    state = np.array([0.3, -0.2])
    assert np.array_equal(again.closed_loop_rates(state), first.closed_loop_rates(state))


def test_a_description_without_numbers_keeps_the_zero_pattern_and_the_rest() -> None:
    from ctmm.model_description import describe

    assert describe((1.5, np.array([0.0, 2.0]), "a"), numbers=False) == \
        describe((-3.0, np.array([0.0, 7.0]), "a"), numbers=False)
    assert describe((1.5, np.array([0.0, 2.0])), numbers=False) != describe((0.0, np.array([0.0, 2.0])), numbers=False)
    assert describe((1.5, np.array([0.0, 2.0])), numbers=False) != describe((1.5, np.array([1.0, 2.0])), numbers=False)
    assert describe((1.5, "a"), numbers=False) != describe((1.5, "b"), numbers=False)
    assert describe((1, 1.5), numbers=False) != describe((2, 1.5), numbers=False)      # integers are kept
    assert describe(1.5) != describe(2.5)                                               # the default keeps numbers
