"""Generated kernels of planar scenes (ctmm.compiled_scene, issue 13 first slice).

The generated RK4 is checked against the numpy path (``ctmm.planar.integrate.simulate_rk4``, the
TMM sweep in Python: equal to round-off) and, independently, against the Lagrange references
(``reference/planar_lagrange.py``, ``reference/flexible_lagrange.py``): accelerations, and an RK4
run of the Lagrange equations (:func:`ctmm.ode.integrate_rk4`, the same scheme on another model).
Compiles go to a temporary cache folder.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm import elements
from ctmm.errors import ModelError, SimulationError
from ctmm.flexible import ModalBeam
from ctmm.ode import integrate_rk4, second_order_rate
from ctmm.planar import (ActuatedHinge, DamperHinge, ElasticHinge, FreeBase, Load, Pinned, PlanarModel,
                         RigidBody, SmoothHinge, SpringDamperHinge, ports)
from ctmm.planar.body_forms import PlanarScene
from ctmm.planar.elements import FixedMounting
from ctmm.planar.integrate import simulate_rk4
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.signals import Harmonic, SquareWave, Step

casadi = pytest.importorskip("casadi")
compiled_scene = pytest.importorskip("ctmm.compiled_scene")
CompiledScene = compiled_scene.CompiledScene
simulate_rk4_generated = compiled_scene.simulate_rk4_generated


@pytest.fixture(autouse=True, scope="module")
def _cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CTMM_CACHE", str(tmp_path_factory.mktemp("kernels")))
        yield


def _relative(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(b)))


def rigid_tree(f: float = 1.0) -> PlanarModel:
    """Revolute tree with every hinge law, a branch, constant loads, an actuated hinge; ``f`` scales
    every number (same structure)."""
    return PlanarModel("tree", [
        Pinned("o", child="a"),
        RigidBody("a", mass=1.2 * f, inertia=0.05 * f, center_of_mass=(0.3 * f, 0.02), outboard={
            "tip": (0.6 * f, 0.0), "mid": (0.3, 0.1 * f)}),
        ElasticHinge("h1", parent="a.tip", child="b", stiffness=3.0 * f, rest_angle=0.2 * f),
        RigidBody.uniform_link("b", mass=0.7 * f, length=0.5 * f),
        DamperHinge("h2", parent="a.mid", child="c", damping=0.3 * f),
        RigidBody("c", mass=0.4 * f, inertia=0.02 * f, center_of_mass=(0.2, -0.05 * f), outboard=(0.4 * f, 0.0),
                  loads=(Load(point=(0.4 * f, 0.0), force_x=0.5 * f, force_y=-0.3 * f, moment=0.1 * f),)),
        SpringDamperHinge("h3", parent="c", child="d", stiffness=2.0 * f, damping=0.1 * f, rest_angle=-0.3 * f),
        RigidBody.uniform_link("d", mass=0.3 * f, length=0.3 * f),
        ActuatedHinge("h4", parent="b", child="e", torque=0.4 * f, kp=5.0 * f, kd=0.5 * f, reference=0.1 * f),
        RigidBody.uniform_link("e", mass=0.2 * f, length=0.25 * f)], gravity=(0.0, -9.81 * f))


def _beam(name, **kw):
    return ModalBeam(name, length=1.3, bending_stiffness=5.0, mass_per_length=0.7, n_modes=3, **kw)


def hub_beam() -> PlanarModel:
    """Hub + modal beam (3 bending modes, 2 axial, geometric stiffening, damping, constant loads) + tip mass."""
    return PlanarModel.chain("hub_beam", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", angle=0.3),
        _beam("b", n_axial_modes=2, axial_stiffness=300.0, damping_ratio=0.02, stiffness_damping=1e-3,
              distributed_load=(0.4, -0.2), loads=(Load(point=(0.7, 0.0), force_x=0.3, force_y=-0.5, moment=0.2),)),
        FixedMounting("m2"),
        RigidBody("tip", mass=0.2, inertia=0.01, center_of_mass=(0.03, 0.01), outboard=(0.1, 0.0))])


def beam_tree() -> PlanarModel:
    """Pinned beam with two outboard points, a hinged link and a welded second beam."""
    return PlanarModel("beam_tree", [
        Pinned("o", child="b1"), _beam("b1", outboard={"mid": 0.6, "tip": 1.3}),
        ElasticHinge("h", parent="b1.mid", child="l", stiffness=2.0, rest_angle=0.1),
        RigidBody.uniform_link("l", mass=0.4, length=0.7),
        FixedMounting("w", parent="b1.tip", child="b2", angle=-0.4), _beam("b2")])


def floating() -> PlanarModel:
    """Free base (x, y, theta coordinates), beam, smooth hinge, beam without geometric stiffening."""
    return PlanarModel.chain("floating", [FreeBase("f"), _beam("b1"), SmoothHinge("h"),
                                          _beam("b2", geometric_stiffening=False)])


SCENES = {"rigid_tree": rigid_tree, "hub_beam": hub_beam, "beam_tree": beam_tree}


def _state(model, seed):
    rng = np.random.default_rng(seed)
    n = model.n_coordinates
    return 0.1 * rng.normal(size=n), 0.2 * rng.normal(size=n)


@pytest.mark.parametrize("name", sorted(SCENES))
def test_generated_run_equals_the_numpy_path_to_round_off(name):
    model = SCENES[name]()
    q0, v0 = (0.01 * x for x in _state(model, 1))    # near rest: the beam tree is violent from larger states
    generated = simulate_rk4_generated(model, q0, v0, t_final=0.2, dt=2e-3, store_every=3)
    numpy_path = simulate_rk4(model, q0, v0, t_final=0.2, dt=2e-3, store_every=3)
    assert generated.method == "rk4-generated"
    assert np.array_equal(generated.t, numpy_path.t)
    assert _relative(generated.q, numpy_path.q) <= 1e-12
    assert _relative(generated.qdot, numpy_path.qdot) <= 1e-12
    assert np.max(np.abs(generated.q[-1] - q0)) > 1e-3          # it moved


@pytest.mark.parametrize("name", sorted(SCENES) + ["floating"])
def test_generated_accelerations_equal_the_lagrange_models(name):
    model = {**SCENES, "floating": floating}[name]()
    reference = FlexibleLagrange(model) if model.beams else PlanarLagrange(model)
    scene = CompiledScene(model)
    for seed in range(3):
        q, v = _state(model, seed)
        assert _relative(scene.accelerations(q, v), reference.accelerations(q, v, 0.0)) <= 1e-12


def test_generated_hub_beam_run_equals_rk4_of_the_lagrange_model():
    model = hub_beam()
    q0, v0 = _state(model, 2)
    q0 = 0.5 * q0           # at twice this the deflection bound passes the beam's length at 0.028 s: both paths stop
    n = model.n_coordinates
    lagrange = FlexibleLagrange(model)
    expected = integrate_rk4(second_order_rate(lambda q, v, t: lagrange.accelerations(q, v, t), n),
                             np.concatenate([q0, v0]), h=2e-3, n_steps=50)
    generated = simulate_rk4_generated(model, q0, v0, t_final=0.1, dt=2e-3)
    assert _relative(np.concatenate([generated.q[-1], generated.qdot[-1]]), expected) <= 1e-10


def test_blocks_strides_and_remainders_give_the_same_rows():
    model = rigid_tree()
    q0, v0 = _state(model, 3)
    small = CompiledScene(model, store_every=2, rows=4).run(q0, v0, 1e-3, 23)      # 2 blocks, 3 strides, 1 step
    single = CompiledScene(model, store_every=1, rows=1).run(q0, v0, 1e-3, 23)
    assert small.shape == (12, 2 * model.n_coordinates)
    assert np.allclose(small[:11], single[1:22:2], rtol=0, atol=1e-14)
    assert np.allclose(small[-1], single[-1], rtol=0, atol=1e-14)


def test_actuator_inputs_held_over_an_interval_equal_the_numpy_sweep():
    model = rigid_tree()
    scene = CompiledScene(model)
    names = ports.actuator_names(model)
    rng = np.random.default_rng(5)
    values = {name: float(rng.normal()) for name in names}
    q, v = _state(model, 4)
    numeric = ports.actuator_inputs(model, values)
    expected = PlanarScene(model).accelerations(q, v, 0.0, numeric)[0]
    assert _relative(scene.accelerations(q, v, values), expected) <= 1e-12
    assert _relative(scene.accelerations(q, v), expected) > 1e-3                  # the inputs act
    n = model.n_coordinates
    rate = second_order_rate(lambda a, b, t: PlanarScene(model).accelerations(a, b, t, numeric)[0], n)
    reference = integrate_rk4(rate, np.concatenate([q, v]), h=1e-3, n_steps=20)
    q1, v1 = scene.advance(q, v, 1e-3, 20, values)
    assert _relative(np.concatenate([q1, v1]), reference) <= 1e-12


def test_ctmm_simulate_dispatches_compiled_true():
    model = hub_beam()
    x0 = {"hub.theta": 0.2, "b.q1": 0.01}
    generated = ctmm.simulate(model, 0.05, 1e-3, method="rk4", compiled=True, x0=x0, outputs=["b.out.y"])
    numpy_path = ctmm.simulate(model, 0.05, 1e-3, method="rk4", x0=x0, outputs=["b.out.y"])
    assert generated.info["method"] == "rk4-generated" and numpy_path.info["method"] == "rk4"
    for signal in ("hub.theta", "b.q1", "b.out.y"):
        assert _relative(generated[signal], numpy_path[signal]) <= 1e-12


def test_divergence_bound_stops_with_a_partial_result():
    model = rigid_tree()
    q0, v0 = _state(model, 6)
    with pytest.raises(SimulationError) as caught:
        simulate_rk4_generated(model, q0, v0 * 100, t_final=0.5, dt=1e-3, divergence_bound=2.0,
                               stability_check="ignore")
    assert caught.value.partial_result is not None


def signal_tree(amplitude: float = 1.0, wave=SquareWave) -> PlanarModel:
    """A branched tree whose hinge reference, reference rate, torque and rigid-body loads are sines,
    steps and square waves (symbolic signals)."""
    return PlanarModel("signals", [
        Pinned("o", child="a"),
        RigidBody("a", mass=1.2, inertia=0.05, center_of_mass=(0.3, 0.02), outboard={"tip": (0.6, 0.0),
                                                                                    "mid": (0.3, 0.1)}),
        ActuatedHinge("h1", parent="a.tip", child="b", torque=Harmonic(0.4 * amplitude, 3.0, 0.2), kp=5.0, kd=0.5,
                      reference=Harmonic(0.3 * amplitude, 7.0),
                      reference_rate=Harmonic(2.1 * amplitude, 7.0, np.pi / 2)),
        RigidBody.uniform_link("b", mass=0.7, length=0.5),
        SpringDamperHinge("h2", parent="a.mid", child="c", stiffness=2.0, damping=0.1, rest_angle=-0.3),
        RigidBody("c", mass=0.4, inertia=0.02, center_of_mass=(0.2, -0.05), outboard=(0.4, 0.0),
                  loads=(Load(point=(0.4, 0.0), force_x=Step(0.5 * amplitude, 0.05),
                              force_y=wave(0.3 * amplitude, 0.04), moment=Harmonic(0.1, 5.0)),))])


def test_symbolic_time_signals_are_evaluated_in_the_generated_code(tmp_path):
    model = signal_tree()
    scene = CompiledScene(model, store_every=2, rows=4, cache_dir=tmp_path)
    q0, v0 = _state(model, 8)
    generated = simulate_rk4_generated(model, q0, v0, t_final=0.1, dt=2e-3, store_every=2, scene=scene)
    numpy_path = simulate_rk4(model, q0, v0, t_final=0.1, dt=2e-3, store_every=2)
    assert _relative(generated.q, numpy_path.q) <= 1e-12
    assert _relative(generated.qdot, numpy_path.qdot) <= 1e-12
    lagrange = PlanarLagrange(model)
    for t in (0.0, 0.013, 0.03, 0.07):                     # before and after the step, both wave levels
        assert _relative(scene.accelerations(q0, v0, t=t), lagrange.accelerations(q0, v0, t)) <= 1e-12
    assert _relative(scene.accelerations(q0, v0, t=0.07), scene.accelerations(q0, v0, t=0.0)) > 1e-2
    # a run that starts later (co-simulation intervals) takes its times from t0
    q1, v1 = scene.advance(q0, v0, 2e-3, 10, t0=0.03)
    rate = second_order_rate(lambda a, b, t: lagrange.accelerations(a, b, t), model.n_coordinates)
    expected = integrate_rk4(rate, np.concatenate([q0, v0]), h=2e-3, n_steps=10, t0=0.03)
    assert _relative(np.concatenate([q1, v1]), expected) <= 1e-10
    # other amplitudes: same structure, one library; another signal class: another structure
    assert compiled_scene.structure_key(signal_tree(1.7)) == scene.structure
    assert compiled_scene.structure_key(signal_tree(wave=Harmonic)) != scene.structure
    other = scene.with_model(signal_tree(1.7))
    assert _relative(other.accelerations(q0, v0, t=0.07),
                     PlanarLagrange(other.model).accelerations(q0, v0, 0.07)) <= 1e-12
    assert len(_libraries(tmp_path)) == 1
    x0 = {"a.theta": 0.2}
    verb = ctmm.simulate(model, 0.05, 1e-3, method="rk4", compiled=True, x0=x0)
    assert verb.info["method"] == "rk4-generated"
    assert _relative(verb["b.theta"], ctmm.simulate(model, 0.05, 1e-3, method="rk4", x0=x0)["b.theta"]) <= 1e-12


@pytest.mark.parametrize("signal", [Harmonic(0.7, 3.0, 0.4), Step(-1.5, 0.25), SquareWave(2.0, 0.3),
                                    SquareWave(2.0, 0.3, duration=0.5), ctmm.signals.Constant(3.5),
                                    ctmm.signals.Ramp(1.3, -0.4, 0.25), ctmm.signals.Ramp(-2.0)])
def test_symbolic_forms_equal_the_signals(signal):
    t = casadi.SX.sym("t")
    parameters = ctmm.signals.signal_parameters(signal)
    form = casadi.Function("f", [t], [ctmm.signals.symbolic_signal(type(signal), t, parameters)])
    for time in (-0.1, 0.0, 0.1, 0.25, 0.3, 0.44, 0.5, 0.61, 1.7):
        assert float(form(time)) == pytest.approx(signal(time), rel=1e-15, abs=1e-15)
    assert ctmm.signals.signal_parameters(lambda time: time) is None
    with pytest.raises(ModelError, match="no symbolic form"):
        ctmm.signals.symbolic_signal(float, t, ())


@pytest.mark.parametrize("parallelization", ["serial", "thread"])
def test_simulate_batch_maps_parameter_sets_over_one_library(tmp_path, parallelization):
    models = [signal_tree(a) for a in (1.0, 1.6, 0.4)]
    scene = CompiledScene(models[0], store_every=2, rows=4, cache_dir=tmp_path)
    parameters = np.array([compiled_scene.parameter_vector(m) for m in models])
    q0 = np.array([_state(m, 9 + k)[0] for k, m in enumerate(models)])
    v0 = _state(models[0], 9)[1]
    states = compiled_scene.simulate_batch(scene, parameters, q0, v0, dt=2e-3, n_steps=23, t0=0.01,
                                           parallelization=parallelization, threads=2)
    assert states.shape == (3, 12, 2 * models[0].n_coordinates)
    n = models[0].n_coordinates
    for k, model in enumerate(models):
        alone = scene.with_model(model).run(q0[k], v0, 2e-3, 23, t0=0.01)
        assert np.array_equal(states[k], alone)
        lagrange = PlanarLagrange(model)
        rate = second_order_rate(lambda a, b, t: lagrange.accelerations(a, b, t), n)
        expected = integrate_rk4(rate, np.concatenate([q0[k], v0]), h=2e-3, n_steps=23, t0=0.01)
        assert _relative(states[k, -1], expected) <= 1e-10
    assert _relative(states[1], states[0]) > 1e-3
    assert len(_libraries(tmp_path)) == 1
    nonzero = parameters.copy()
    nonzero[:, np.flatnonzero(scene.parameters == 0.0)[0]] = 1.0
    with pytest.raises(ModelError, match="are zero in the scene's model"):
        compiled_scene.simulate_batch(scene, nonzero, q0, v0, dt=1e-3, n_steps=2)
    with pytest.raises(ModelError, match="parameters must be a"):
        compiled_scene.simulate_batch(scene, parameters[:, :-1], q0, v0, dt=1e-3, n_steps=2)
    with pytest.raises(ModelError, match="q0 must be finite"):
        compiled_scene.simulate_batch(scene, parameters, q0[:2], v0, dt=1e-3, n_steps=2)
    with pytest.raises(ModelError, match="parallelization"):
        compiled_scene.simulate_batch(scene, parameters, q0, v0, dt=1e-3, n_steps=2, parallelization="gpu")


def _libraries(folder) -> list:
    return sorted(path.name for path in (folder / "kernels").iterdir())


def test_models_of_one_structure_share_one_library(tmp_path):
    first, second = rigid_tree(), rigid_tree(1.37)
    assert compiled_scene.structure_key(first) == compiled_scene.structure_key(second)
    assert not np.allclose(compiled_scene.parameter_vector(first), compiled_scene.parameter_vector(second))
    scenes = [CompiledScene(model, store_every=3, cache_dir=tmp_path) for model in (first, second)]
    assert len(_libraries(tmp_path)) == 1                       # the second found the first's library
    reused = scenes[0].with_model(second)                        # nothing generated: same functions
    assert reused._step is scenes[0]._step
    for model, scene in [(first, scenes[0]), (second, scenes[1]), (second, reused)]:
        q0, v0 = _state(model, 7)
        generated = simulate_rk4_generated(model, q0, v0, t_final=0.1, dt=2e-3, store_every=3, scene=scene)
        numpy_path = simulate_rk4(model, q0, v0, t_final=0.1, dt=2e-3, store_every=3)
        assert _relative(generated.q, numpy_path.q) <= 1e-12
        assert _relative(generated.qdot, numpy_path.qdot) <= 1e-12
        assert _relative(scene.accelerations(q0, v0), PlanarLagrange(model).accelerations(q0, v0, 0.0)) <= 1e-12
    q0, v0 = _state(first, 7)
    assert _relative(reused.accelerations(q0, v0), scenes[0].accelerations(q0, v0)) > 1e-2   # numbers matter


def test_numbers_as_constants_give_one_library_per_model(tmp_path):
    first, second = rigid_tree(), rigid_tree(1.37)
    scenes = [CompiledScene(model, numbers="constants", cache_dir=tmp_path) for model in (first, second)]
    assert len(_libraries(tmp_path)) == 2
    q0, v0 = _state(first, 7)
    inputs = CompiledScene(second, cache_dir=tmp_path)
    assert _relative(scenes[1].accelerations(q0, v0, t=0.1), inputs.accelerations(q0, v0, t=0.1)) <= 1e-12
    assert _relative(scenes[0].accelerations(q0, v0), PlanarLagrange(first).accelerations(q0, v0, 0.0)) <= 1e-12
    with pytest.raises(ModelError, match="another structure"):
        scenes[0].with_model(second)
    with pytest.raises(ModelError, match="numbers='inputs'"):
        compiled_scene.simulate_batch(scenes[0], scenes[0].parameters[None], q0, v0, dt=1e-3, n_steps=2)
    with pytest.raises(ModelError, match="numbers must be"):
        CompiledScene(first, numbers="symbols")


def test_beam_data_and_structure_changes_give_another_key():
    key = compiled_scene.structure_key
    assert key(hub_beam()) == key(hub_beam())
    other_beam = PlanarModel.chain("hub_beam", [
        Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, center_of_mass=(0.05, 0.02), outboard=(0.2, 0.0)),
        FixedMounting("mount", angle=0.3), ModalBeam("b", length=1.4, bending_stiffness=5.0, mass_per_length=0.7,
                                                     n_modes=3)])
    assert key(other_beam) != key(hub_beam())
    shorter = PlanarModel.chain("c", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0)])
    longer = PlanarModel.chain("c", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0), SmoothHinge("h"),
                                     RigidBody.uniform_link("b", mass=1.0, length=1.0)])
    assert key(shorter) != key(longer)
    tilted = PlanarModel.chain("c", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0)],
                               gravity=(0.5, -9.81))
    assert key(tilted) != key(shorter)            # a zero number is a constant of the code: structure
    with pytest.raises(ModelError, match="another structure"):
        CompiledScene(shorter).with_model(longer)


def test_refusals():
    moving = PlanarModel.chain("moving", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
                                          ActuatedHinge("h", torque=lambda t: np.sin(t)),
                                          RigidBody.uniform_link("b", mass=1.0, length=1.0)])
    with pytest.raises(ModelError, match="time-dependent signals without a symbolic form in 'h'"):
        CompiledScene(moving)
    with pytest.raises(ModelError, match="without a symbolic form"):
        compiled_scene.parameter_vector(moving)
    with pytest.raises(ModelError, match="time-dependent"):
        ctmm.simulate(moving, 0.1, 1e-2, compiled=True)
    swinging_load = PlanarModel.chain("load", [Pinned("o"), _beam("b", loads=(Load(point=(1.0, 0.0),
                                                                                   force_y=lambda t: t),))])
    with pytest.raises(ModelError, match="time-dependent signals without a symbolic form in 'b'"):
        CompiledScene(swinging_load)
    with pytest.raises(ModelError, match="PlanarModel"):
        CompiledScene("not a model")
    model = rigid_tree()
    with pytest.raises(ModelError, match="contradicts compiled=False"):
        ctmm.simulate(model, 0.1, 1e-2, compiled=False, fast=True)
    with pytest.raises(ModelError, match="compiled=True runs the generated RK4"):
        ctmm.simulate(model, 0.1, 1e-2, method="RK45", compiled=True)
    with pytest.raises(ModelError, match="compiled"):
        ctmm.simulate(model, 0.1, 1e-2, compiled="yes")
    with pytest.raises(ModelError, match="unknown actuator"):
        CompiledScene(model).accelerations(np.zeros(model.n_coordinates), np.zeros(model.n_coordinates),
                                           {"nope.torque": 1.0})
    with pytest.raises(ModelError, match="rows"):
        CompiledScene(model, rows=0)
    zero = np.zeros(model.n_coordinates)
    with pytest.raises(ModelError, match="n_steps"):
        CompiledScene(model).advance(zero, zero, 1e-3, 0)
    with pytest.raises(ModelError, match="dt"):
        CompiledScene(model).run(zero, zero, float("nan"), 3)
    with pytest.raises(ModelError, match="CompiledScene of this model"):
        simulate_rk4_generated(model, np.zeros(model.n_coordinates), np.zeros(model.n_coordinates), t_final=0.01,
                               dt=1e-3, store_every=2, scene=CompiledScene(model))
    chain = ctmm.Chain("c", [elements.Fixed("w"), elements.Spring("k", 1.0), elements.Mass("m", 1.0),
                             elements.Free("e")])
    with pytest.raises(ModelError, match="generated RK4 or DT-TMM of a chain.*method='DOP853'"):
        ctmm.simulate(chain, 0.1, 1e-2, method="DOP853", compiled=True)   # rk4 and the DT-TMM schemes only


def test_beam_station_loads_are_inputs_of_generated_kernels_when_named_and_never_dropped():
    """A station force on a beam has a floating-frame part the element protocol does not carry: the numpy element
    terms refuse it by name; a generated scene takes the station loads named in ``station_inputs`` as inputs with their
    frame wrench (ctmm.compiled_station_loads; runs against the numpy path: tests/test_compiled_station_held_inputs.py)
    and refuses the others by name, saying how to take them."""
    from ctmm.compiled_scene import CompiledScene, compiled_actuators
    from ctmm.flexible import ModalBeam
    from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody
    from ctmm.planar.elements import FixedMounting
    from ctmm.planar.body_forms import PlanarScene

    beam = ModalBeam("beam", length=1.0, bending_stiffness=20.0, mass_per_length=0.5, n_modes=2, stations={"mid": 0.5})
    model = PlanarModel.chain("hb", [Fixed("g"), ActuatedHinge("motor"),
                                     RigidBody("hub", mass=2.0, inertia=0.1, outboard=(0.1, 0.0)),
                                     FixedMounting("mount"), beam], gravity=(0.0, 0.0))
    names = compiled_actuators(model)
    assert "motor.torque" in names and "beam.q1.force" in names
    assert not any(name.startswith("beam.mid.") for name in names)
    assert compiled_actuators(model, ["beam.mid.moment"]) == names + ("beam.mid.moment",)
    with pytest.raises(ModelError, match=r"'beam.tip.force' is not a beam station force or moment.*beam.mid.force"):
        compiled_actuators(model, ["beam.tip.force"])
    from ctmm.planar.ports import actuator_inputs

    with pytest.raises(ModelError, match="station forces and moments"):
        PlanarScene(model).accelerations(np.zeros(3), np.zeros(3), inputs=actuator_inputs(model, {"beam.mid.force": 1.0}))
    scene = CompiledScene(model)
    assert scene.actuators == names
    with pytest.raises(ModelError, match=r"'beam.mid.force' is a beam station load .*station_inputs=\['beam.mid.force'\]"):
        scene.advance(np.zeros(3), np.zeros(3), 1e-3, 1, inputs={"beam.mid.force": 1.0})
