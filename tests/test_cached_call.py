"""A cached compiled call builds no expression (issue 13: the cost of a cached ``compiled=True`` call).

Generated kernels keyed on the model's description before anything is built (:mod:`ctmm.compiled_scene_key`,
:func:`ctmm.model_description.describe`): a call whose library is cached replaces the symbolic builders by functions
that raise and still runs; the cache folder's entries (counted on disk) show hits and misses (a changed structure,
option or constant of the code misses, a changed number that is an input of the code hits); every run is checked
against an independent stepper of its own model (the Python implicit DT-TMM stepper
:func:`ctmm.planar.implicit.simulate_implicit`, which shares no generated code), so a wrong hit cannot pass.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm import compiled_scene_key
from ctmm.control import Feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.planar import ElasticHinge, Fixed, PlanarModel, RigidBody, SmoothHinge, simulate_implicit
from ctmm.schemes import Newmark
from ctmm.signals import Harmonic
from test_planar_description_key import forbid_building as forbid_scene_building, libraries

casadi = pytest.importorskip("casadi")
compiled_scene = pytest.importorskip("ctmm.compiled_scene")
compiled_scene_schemes = pytest.importorskip("ctmm.compiled_scene_schemes")
simulate_scheme_generated = compiled_scene_schemes.simulate_scheme_generated

START = (np.array([0.3, -0.2]), np.array([0.5, -0.4]))
T_FINAL, DT = 0.1, 0.01


def pendulum(mass: float = 1.0, stiffness: float = 2.0, angle: float = 0.2, rest: float = 0.1) -> PlanarModel:
    """Two links on elastic hinges; ``angle``: the ground's angle (a constant of the code), the rest of the numbers
    are entries of ``p``."""
    return PlanarModel.chain("pendulum", [
        Fixed("ground", angle=angle), ElasticHinge("base", stiffness=1.5, rest_angle=0.2),
        RigidBody.uniform_link("a", mass=mass, length=0.8),
        ElasticHinge("h", stiffness=stiffness, rest_angle=rest),
        RigidBody("b", mass=0.5 * mass, inertia=0.02, center_of_mass=(0.2, 0.01), outboard=(0.4, 0.0))],
        gravity=(0.0, -9.81))


def forbid_building(monkeypatch) -> None:
    """The planar scheme's symbolic builders raise (a cached call must not reach them)."""
    def refuse(*_args, **_kwargs):
        raise AssertionError("symbols were built although the library is cached")

    for name in ("symbolic_accelerations_with_inputs", "folded_accelerations_with_inputs"):
        monkeypatch.setattr(compiled_scene_schemes, name, refuse)


def run(model: PlanarModel, folder, scheme="newmark", **options):
    return simulate_scheme_generated(model, *START, t_final=T_FINAL, dt=DT, scheme=scheme, cache_dir=folder, **options)


def assert_python_stepper(generated, model: PlanarModel, scheme="newmark", **options) -> None:
    """The generated run equals the Python implicit stepper of ``model`` (independent of the library) to 1e-10."""
    python = simulate_implicit(model, *START, t_final=T_FINAL, dt=DT, scheme=scheme, **options)
    assert np.array_equal(generated.t, python.t)
    assert np.max(np.abs(generated.q - python.q)) <= 1e-10
    assert np.max(np.abs(generated.qdot - python.qdot)) <= 1e-10


def test_a_cached_planar_scheme_call_builds_nothing_and_gives_the_same_numbers(tmp_path, monkeypatch) -> None:
    first = run(pendulum(), tmp_path)
    assert len(libraries(tmp_path)) == 1
    assert_python_stepper(first, pendulum())
    with monkeypatch.context() as patch:
        forbid_building(patch)
        again = run(pendulum(), tmp_path)
        assert np.array_equal(again.q, first.q) and np.array_equal(again.qdot, first.qdot)
        for other in (pendulum(mass=1.7, stiffness=5.0), pendulum(rest=0.3)):    # entries of p: the same library
            assert_python_stepper(run(other, tmp_path), other)
    assert len(libraries(tmp_path)) == 1


def test_a_changed_constant_or_option_of_a_planar_scheme_misses(tmp_path, monkeypatch) -> None:
    run(pendulum(), tmp_path)
    changes = [(pendulum(angle=0.4), "newmark", {}),             # a constant of the code
               (pendulum(rest=0.0), "newmark", {}),              # a zero is a constant too
               (pendulum(), Newmark(beta=0.3, gamma=0.6), {}),   # the scheme's coefficients
               (pendulum(), "newmark", {"tolerance": 1e-9}),     # a Newton option
               (pendulum(), "houbolt", {})]                      # another scheme
    for count, (model, scheme, options) in enumerate(changes, start=2):
        with monkeypatch.context() as patch, pytest.raises(AssertionError, match="symbols were built"):
            forbid_building(patch)
            run(model, tmp_path, scheme, **options)
        generated = run(model, tmp_path, scheme, **options)
        assert len(libraries(tmp_path)) == count
        assert_python_stepper(generated, model, scheme, **options)


def test_a_planar_scheme_hit_that_does_not_compute_the_model_is_rebuilt(tmp_path, monkeypatch) -> None:
    """A structure key that missed a constant (simulated: one key for every model) would find the library of another
    ground angle; the certification against the numpy sweep rejects it and the step is built."""
    monkeypatch.setattr(compiled_scene_key, "structure_key", lambda model: "one key for every model")
    run(pendulum(), tmp_path)
    turned = pendulum(angle=0.4)
    generated = run(turned, tmp_path)
    assert len(libraries(tmp_path)) == 2
    assert_python_stepper(generated, turned)


# -- planar scenes with loops (numbers as inputs: the loops' gains, realisations and references are entries of p) --

def arm(gain: float, fore_length: float = 0.6, delay_steps: int = 3, weight: float = 0.3) -> ControlledModel:
    """Double pendulum: a real-time PD on the shoulder, a delayed loop on the height of the forearm's end (its code
    keeps the forearm's length) and an LTI lag."""
    control = pytest.importorskip("control")
    plant = PlanarModel.chain("arm", [Fixed("ground"), SmoothHinge("pivot"),
                                      RigidBody.uniform_link("rod", mass=1.0, length=0.8), SmoothHinge("elbow"),
                                      RigidBody.uniform_link("fore", mass=0.5, length=fore_length)])
    loops = [Feedback("pd", [("rod.theta", 1.0), ("rod.omega", weight)], "pivot.torque", gain=gain),
             Feedback("late", "fore.out.y", "elbow.torque", gain=2.0, delay=delay_steps * LOOP_DT),
             Feedback("lag", "fore.omega", "elbow.torque", gain=control.tf([1.5 * 30.0], [1.0, 30.0]))]
    return ControlledModel(plant, loops)


LOOP_DT, LOOP_T = 2e-3, 0.06
ARM_START = {"x0": np.array([0.5, -0.2]), "v0": np.array([0.0, 0.4])}
LOOP_SIGNALS = ["rod.theta", "fore.theta", "pd.u", "late.u", "lag.u"]


def loop_run(system: ControlledModel, reference: float = 0.2, compiled: bool | None = True):
    return ctmm.simulate(system, LOOP_T, LOOP_DT, compiled=compiled, references={"pd": Harmonic(reference, 7.0, 0.2),
                                                                                 "late": 0.05}, **ARM_START)


def assert_numpy_loop_path(generated, system: ControlledModel, reference: float = 0.2) -> None:
    """Every loop signal equals the numpy loop driver (:mod:`ctmm.control.planar_time`) of ``system`` to round-off."""
    numpy_path = loop_run(system, reference, compiled=False)
    for name in LOOP_SIGNALS:
        scale = max(1.0, float(np.max(np.abs(numpy_path[name]))))
        assert np.max(np.abs(generated[name] - numpy_path[name])) < 1e-12 * scale, name


def test_a_cached_call_with_loops_builds_nothing_for_other_gains_and_references(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    first = loop_run(arm(6.0))
    assert_numpy_loop_path(first, arm(6.0))
    with monkeypatch.context() as patch:
        forbid_scene_building(patch)
        again = loop_run(arm(6.0))
        assert all(np.array_equal(again[name], first[name]) for name in LOOP_SIGNALS)
        other = loop_run(arm(11.0), reference=-0.4)                  # a gain and a reference: entries of p
        assert_numpy_loop_path(other, arm(11.0), reference=-0.4)
    assert len(libraries(tmp_path)) == 1
    assert np.max(np.abs(other["rod.theta"] - first["rod.theta"])) > 1e-3      # the numbers matter


@pytest.mark.parametrize("changed", [{"delay_steps": 4}, {"weight": 0.5}], ids=["delay", "sensor weight"])
def test_a_changed_loop_constant_misses(tmp_path, monkeypatch, changed) -> None:
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    loop_run(arm(6.0))
    with monkeypatch.context() as patch, pytest.raises(AssertionError, match="symbols were built"):
        forbid_scene_building(patch)
        loop_run(arm(6.0, **changed))
    generated = loop_run(arm(6.0, **changed))
    assert len(libraries(tmp_path)) == 2
    assert_numpy_loop_path(generated, arm(6.0, **changed))


def test_a_hit_whose_loop_sensors_keep_another_geometry_is_rebuilt(tmp_path, monkeypatch) -> None:
    """The forearm's length is an entry of p for the sweep but a constant of the sensor ``fore.out.y``: the library of
    one length is found by the description of another, the sweep's certification passes, the sensors' fails and
    the step is built (without that check the run would use the old length: shown by disabling it)."""
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    loop_run(arm(6.0))
    longer = arm(6.0, fore_length=0.9)
    generated = loop_run(longer)
    assert len(libraries(tmp_path)) == 2
    assert_numpy_loop_path(generated, longer)
    with monkeypatch.context() as patch:
        patch.setattr(compiled_scene, "certified_sensors", lambda *_: True)
        patch.setenv("CTMM_CACHE", str(tmp_path / "unchecked"))
        loop_run(arm(6.0))
        wrong = loop_run(longer)
    assert np.max(np.abs(wrong["late.u"] - generated["late.u"])) > 1e-3


def beam_system(gain: float) -> ControlledModel:
    """Hub + modal beam (clamped-free shapes) + tip mass with a real-time PD and a delayed loop on the tip."""
    from test_compiled_scene import hub_beam

    return ControlledModel(hub_beam(), [
        Feedback("pd", [("o.angle", 8.0), ("o.rate", 1.0)], "o.torque", gain=gain),
        Feedback("end", [("tip.com.y", 3.0), ("tip.com.vx", 0.2)], "tip.force_y", gain=0.5, delay=2 * LOOP_DT)])


def test_a_modal_beam_is_described_and_its_cached_call_with_loops_builds_nothing(tmp_path, monkeypatch) -> None:
    """The beam's clamped-free shapes are objects of numbers (a lambda could not be described: the scene was keyed
    on its built functions); a cached call with another gain builds nothing and equals the numpy loop driver."""
    from ctmm.model_description import describe
    from test_compiled_scene import _state

    assert describe(beam_system(1.0).plant, numbers=False) is not None
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    q0, v0 = _state(beam_system(1.0).plant, 4)
    names = [*beam_system(1.0).plant.coordinates, "pd.u", "end.u"]
    ctmm.simulate(beam_system(1.0), 0.02, LOOP_DT, x0=q0, v0=v0, compiled=True)
    with monkeypatch.context() as patch:
        forbid_scene_building(patch)
        generated = ctmm.simulate(beam_system(2.5), 0.02, LOOP_DT, x0=q0, v0=v0, compiled=True)
    assert len(libraries(tmp_path)) == 1
    numpy_path = ctmm.simulate(beam_system(2.5), 0.02, LOOP_DT, x0=q0, v0=v0, compiled=False)
    for name in names:
        scale = max(1.0, float(np.max(np.abs(numpy_path[name]))))
        assert np.max(np.abs(generated[name] - numpy_path[name])) < 1e-11 * scale, name
