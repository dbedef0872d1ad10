"""Planar generated kernels folded over the segments of a serial chain (ctmm.compiled_scene_fold, issue 13).

The folded accelerations are checked against the straight-line generated expression (same sweep, other
code: equal to round-off), independently against the Lagrange reference (``reference/planar_lagrange.py``),
and the folded RK4 against the numpy path (``ctmm.planar.integrate.simulate_rk4``).  Every joint kind that
folds (smooth, elastic, damper, spring-damper, actuated hinges with time signals and actuator inputs) is in
one 12-body chain of unequal bodies.  Compiles go to a temporary cache folder.
"""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.errors import ModelError
from ctmm.planar import (ActuatedHinge, DamperHinge, ElasticHinge, Load, Pinned, PlanarModel, RigidBody,
                         SmoothHinge, SpringDamperHinge, ports)
from ctmm.planar.elements import Fixed
from ctmm.planar.integrate import simulate_rk4
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.signals import Harmonic

casadi = pytest.importorskip("casadi")
compiled_scene = pytest.importorskip("ctmm.compiled_scene")
from ctmm.compiled_parameters import parameter_vector, symbolic_numbers  # noqa: E402
from ctmm.compiled_scene_fold import (FOLD_MIN_BODIES, fold_period, folded_acceleration,  # noqa: E402
                                      planar_fold_refusal, symbolic_inputs)
from test_compiled_scene import hub_beam, rigid_tree  # noqa: E402

CompiledScene = compiled_scene.CompiledScene


@pytest.fixture(scope="module")
def kernels(tmp_path_factory):
    """A temporary kernel cache folder."""
    return tmp_path_factory.mktemp("kernels")


def mixed_chain(n: int = 12, f: float = 1.0, loads: bool = False, ground_angle: float = 0.0) -> PlanarModel:
    """Serial chain of ``n`` unequal rigid bodies on every foldable hinge kind (``f`` scales the numbers); with
    a ``ground_angle`` [rad] the first hinge is elastic on a turned ground."""
    elements = [Pinned("base")] if not ground_angle else [Fixed("ground", angle=ground_angle),
                                                            ElasticHinge("base", stiffness=1.5, rest_angle=0.2)]
    for i in range(n):
        if i:
            kind = i % 5
            name = f"h{i}"
            elements.append([SmoothHinge(name), ElasticHinge(name, stiffness=3.0 * f, rest_angle=0.1 * i),
                             DamperHinge(name, damping=0.2 * f),
                             SpringDamperHinge(name, stiffness=2.0 * f, damping=0.1, rest_angle=-0.2),
                             ActuatedHinge(name, torque=Harmonic(0.3 * f, 2.0, 0.1 * i), kp=4.0, kd=0.3 * f,
                                           reference=0.05 * i)][kind])
        length = (0.4 + 0.05 * (i % 3)) * f
        body_loads = (Load(point=(length, 0.0), force_x=0.2),) if loads and i == n // 2 else ()
        elements.append(RigidBody(f"b{i}", mass=(0.5 + 0.1 * (i % 4)) * f, inertia=0.02 + 0.003 * i,
                                  center_of_mass=(0.5 * length, 0.01 * (i % 2)), outboard=(length, 0.02 * (i % 3)),
                                  loads=body_loads))
    return PlanarModel.chain(f"mixed{n}", elements, gravity=(0.3 * f, -9.81 * f))


def _state(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.normal(size=n), rng.normal(size=n)


def _straight_line(model: PlanarModel, actuators) -> casadi.Function:
    return compiled_scene.symbolic_accelerations_with_inputs(model, actuators)


@pytest.fixture(scope="module")
def folded_scene(kernels):
    return CompiledScene(mixed_chain(), fold=True, cache_dir=kernels)


def test_folded_generated_accelerations_equal_straight_line_and_lagrange(folded_scene) -> None:
    model = folded_scene.model
    assert folded_scene.period == 4
    actuators = folded_scene.actuators
    assert actuators, "the chain has actuated hinges (inputs u)"
    q, v = _state(model.n_bodies)
    u = np.linspace(-0.5, 0.7, len(actuators))
    t = 0.37
    folded = folded_scene.accelerations(q, v, dict(zip(actuators, u)), t=t)
    straight = np.asarray(_straight_line(model, actuators)(q, v, u, parameter_vector(model), t)).reshape(-1)
    assert np.max(np.abs(folded - straight)) <= 1e-12 * np.max(np.abs(straight))
    lagrange = PlanarLagrange(model).accelerations(q, v, t)         # independent model, no inputs
    without = folded_scene.accelerations(q, v, t=t)
    assert np.max(np.abs(without - lagrange)) <= 1e-9 * np.max(np.abs(lagrange))
    assert np.max(np.abs(without - folded)) > 1e-3            # the inputs enter


@pytest.mark.parametrize("period, numbers, ground_angle", [(1, "inputs", 0.0), (2, "constants", 0.4),
                                                          (3, "inputs", -0.7), (6, "constants", 0.0)])
def test_every_period_and_number_mode_equals_the_straight_line_expression(period, numbers, ground_angle) -> None:
    model = mixed_chain(ground_angle=ground_angle)
    assert model.ground_angle[0] == ground_angle
    n, n_p = model.n_bodies, parameter_vector(model).size
    actuators = compiled_scene.compiled_actuators(model)
    port = ports.PlanarPorts(model)
    units = [port.inputs({name: 1.0}) for name in actuators]
    u, p, t = casadi.SX.sym("u", len(units)), casadi.SX.sym("p", n_p), casadi.SX.sym("t")
    inputs = symbolic_inputs(model, units, u)
    acceleration = folded_acceleration(model, symbolic_numbers(model, p if numbers == "inputs" else None, t),
                                       inputs, (u, p, t), period)
    q, v = _state(n, seed=period)
    values = np.linspace(0.4, -0.3, len(units))
    folded = np.asarray(acceleration(q, v, values, parameter_vector(model), 1.3)).reshape(-1)
    straight = np.asarray(_straight_line(model, actuators)(q, v, values, parameter_vector(model), 1.3)).reshape(-1)
    assert np.max(np.abs(folded - straight)) <= 1e-12 * np.max(np.abs(straight))


def test_folded_rk4_run_and_other_numbers_equal_the_numpy_path(folded_scene) -> None:
    model = folded_scene.model
    q, v = _state(model.n_bodies, seed=3)
    sim = simulate_rk4(model, q, 0.1 * v, t_final=0.02, dt=1e-3, store_every=5)
    states = folded_scene.run(q, 0.1 * v, 1e-3, 20)
    scale = np.max(np.abs(sim.q[1:]))
    assert np.max(np.abs(states[4::5, :model.n_bodies] - sim.q[1:])) <= 1e-12 * scale
    other = mixed_chain(f=1.3)                  # same structure, other numbers: the same library
    scaled = folded_scene.with_model(other)
    assert np.max(np.abs(scaled.accelerations(q, v, t=0.2) - PlanarLagrange(other).accelerations(q, v, 0.2))) \
        <= 1e-9 * np.max(np.abs(scaled.accelerations(q, v, t=0.2)))


def test_simulate_rk4_generated_takes_fold(kernels) -> None:
    model = mixed_chain()
    q, v = _state(model.n_bodies, seed=4)
    generated = compiled_scene.simulate_rk4_generated(model, q, 0.1 * v, t_final=0.01, dt=1e-3, store_every=10,
                                                      cache_dir=kernels, fold=True)
    numpy_path = simulate_rk4(model, q, 0.1 * v, t_final=0.01, dt=1e-3, store_every=10)
    assert np.max(np.abs(generated.q - numpy_path.q)) <= 1e-12 * np.max(np.abs(numpy_path.q))
    tree = rigid_tree()                                             # fold= reaches CompiledScene
    with pytest.raises(ModelError, match="fold=True needs a serial chain"):
        compiled_scene.simulate_rk4_generated(tree, np.zeros(tree.n_coordinates), np.zeros(tree.n_coordinates),
                                              t_final=0.01, dt=1e-3, cache_dir=kernels, fold=True)


def test_long_chains_fold_by_default(kernels) -> None:
    n = FOLD_MIN_BODIES + 2
    model = PlanarModel.chain("pendulums", [Pinned("base")] + [
        element for i in range(n) for element in ([SmoothHinge(f"h{i}")] if i else [])
        + [RigidBody.uniform_link(f"l{i}", mass=1.0, length=0.5)]], gravity=(0.0, -9.81))
    assert fold_period(model) == max(period for period in (4, 3, 2, 1) if n % period == 0)
    scene = CompiledScene(model, cache_dir=kernels)
    assert scene.period == fold_period(model) > 0
    q, v = _state(n, seed=5)
    lagrange = PlanarLagrange(model).accelerations(q, v)
    assert np.max(np.abs(scene.accelerations(q, v) - lagrange)) <= 1e-9 * np.max(np.abs(lagrange))


@pytest.mark.parametrize("build, match", [
    (rigid_tree, "not a serial chain"),
    (hub_beam, "not a serial chain|modal beams|not a revolute"),
    (lambda: mixed_chain(loads=True), "rigid-body loads"),
    (lambda: mixed_chain(n=1), "at least two segments"),
])
def test_fold_true_on_a_model_that_does_not_fold_is_refused_by_name(build, match) -> None:
    model = build()
    assert planar_fold_refusal(model)
    with pytest.raises(ModelError, match=f"fold=True needs a serial chain.*({match})"):
        CompiledScene(model, fold=True)


def test_fold_must_be_a_boolean_or_none() -> None:
    with pytest.raises(ModelError, match="fold must be True, False or None"):
        CompiledScene(mixed_chain(), fold="yes")
    assert planar_fold_refusal(mixed_chain(), period=5) and planar_fold_refusal(mixed_chain(), period=0)
