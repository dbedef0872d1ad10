"""Generated kernels of spatial models (``ctmm.simulate(spatial, ..., compiled=True)``, issues 13/14):
the same result as the numpy path to round-off on random trees with every joint kind, free and elastic
bases, loads and inputs; an RK4 of Pinocchio's ABA written here as the independent peer; refusals."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError, SimulationError
from ctmm.signals import Harmonic

pytest.importorskip("casadi")
import test_spatial_pinocchio as pinocchio_tests  # noqa: E402  (its random trees; needs pinocchio)

FAST_COMPILE = ("-O0", "-shared", "-fPIC")        # the same numbers, a fraction of the compile time
KINDS = pinocchio_tests.KINDS


def random_tree(seed: int, n: int, base: str) -> sp.SpatialModel:
    """The random tree of ``test_spatial_pinocchio`` (body 0 on ``base`` to the ground, each other body on
    a random earlier body's random point, joint kinds cycling through every kind, laws, actuators, random
    gravity) with constant loads in world and body axes."""
    rng = np.random.default_rng(seed)
    tree = pinocchio_tests.random_tree(rng, n, base, loads=False)
    loads = [sp.Load("push", f"b{n - 1}", "p1", force=rng.normal(size=3), moment=rng.normal(size=3)),
             sp.Load("twist", "b0", "p2", force=rng.normal(size=3), moment=rng.normal(size=3), axes="body")]
    return sp.SpatialModel("tree", list(tree.bodies) + list(tree.joints) + loads, gravity=tree.gravity)


def start(seed: int, model: sp.SpatialModel) -> tuple[np.ndarray, np.ndarray, dict]:
    rng = np.random.default_rng(seed + 100)
    q = model.neutral() + 0.3 * rng.normal(size=model.n_positions)
    inputs = {name: (rng.normal(size=k) if k > 1 else float(rng.normal()))
              for j in model.joints for name, k in ((n, j.velocity_count) for n in j.inputs)}
    return q, 0.5 * rng.normal(size=model.n_velocities), inputs


@pytest.mark.parametrize("seed, base, store_every", [(1, "free", 1), (2, "elastic6", 3)])
def test_random_trees_equal_the_numpy_path(seed: int, base: str, store_every: int, tmp_path) -> None:
    """Every stored signal (coordinates, velocities, body positions, angular velocities) of 8 bodies
    with every joint kind equals the numpy RK4 to 1e-11 relative; rows (store_every with a remainder,
    more steps than one block) and times identical."""
    model = random_tree(seed, 8, base)
    q0, v0, inputs = start(seed, model)
    assert {joint.kind for joint in model.joints} >= set(KINDS)
    arguments = dict(x0=q0, v0=v0, inputs=inputs, store_every=store_every)
    numpy_run = ctmm.simulate(model, 0.071, 1e-3, **arguments)
    from ctmm.compiled_spatial import CompiledSpatialScene, simulate_spatial_generated

    scene = CompiledSpatialScene(model, store_every=store_every, rows=8, cache_dir=tmp_path, flags=FAST_COMPILE)
    generated = simulate_spatial_generated(model, 0.071, 1e-3, scene=scene, **arguments)
    assert generated.scheme_name == "rk4-generated" and generated.info["compile_time_s"] > 0
    np.testing.assert_array_equal(generated.time, numpy_run.time)
    names = list(model.coordinates) + list(model.velocities) + [f"b{j}.{s}_{a}" for j in range(8)
                                                                for s in ("position", "omega") for a in "xyz"]
    for name in names:
        scale = max(1.0, float(np.max(np.abs(numpy_run[name]))))
        assert np.max(np.abs(generated[name] - numpy_run[name])) < 1e-11 * scale, name
    # the motion is not trivial: every coordinate moved
    moved = [np.ptp(numpy_run[name]) for name in model.coordinates]
    assert min(moved) > 1e-6


def test_verb_dispatch_and_accelerations(tmp_path) -> None:
    """``ctmm.simulate(..., compiled=True)`` takes the generated path; the compiled accelerations equal
    the numpy sweep at a random state (non-unit quaternions included)."""
    model = random_tree(4, 5, "free")
    q0, v0, inputs = start(4, model)
    result = ctmm.simulate(model, 0.01, 1e-3, x0=q0, v0=v0, inputs=inputs, compiled=True)
    assert result.scheme_name == "rk4-generated"
    from ctmm.compiled_spatial import CompiledSpatialScene

    scene = CompiledSpatialScene(model, cache_dir=tmp_path, flags=FAST_COMPILE)
    q = q0 * 1.7
    np.testing.assert_allclose(scene.accelerations(q, v0, inputs), sp.accelerations(model, q, v0, 0.0, inputs),
                               rtol=1e-11, atol=1e-11)


def test_ball_chain_matches_pinocchio_rk4(tmp_path) -> None:
    """An independent peer: Pinocchio ABA with an RK4 written here (quaternions as 4-vectors, rates
    ``1/2 q (x) (0, omega)``, not normalised) on a 6-link ball-and-revolute chain; final state equal to
    1e-9 after 0.2 s (both are the same RK4 of the same ODE)."""
    pin = pytest.importorskip("pinocchio")
    n, inertia, com = 6, np.diag([0.01, 0.08, 0.08]), np.array([0.5, 0.0, 0.0])
    elements = []
    model = pin.Model()
    model.gravity.linear = np.array([0.0, 0.0, -9.81])
    parent = 0
    for i in range(n):
        ball = i % 2 == 0
        elements.append(sp.SpatialBody(f"l{i}", 1.0, inertia, com, {"end": (1.0, 0.0, 0.0)}))
        common = dict(name=f"j{i}", parent=None if i == 0 else f"l{i - 1}", child=f"l{i}",
                      point=(0.0, 0.0, 0.0) if i == 0 else "end")
        elements.append(sp.Spherical(**common) if ball else sp.Revolute(axis=(0, 0, 1), **common))
        placement = pin.SE3(np.eye(3), np.array([1.0 if i else 0.0, 0.0, 0.0]))
        parent = model.addJoint(parent, pin.JointModelSpherical() if ball else pin.JointModelRZ(), placement,
                                f"j{i}")
        model.appendBodyToJoint(parent, pin.Inertia(1.0, com, inertia), pin.SE3.Identity())
    ours = sp.SpatialModel("chain", elements, gravity=(0, 0, -9.81))
    data = model.createData()
    half = 0.15
    q0 = np.concatenate([[np.cos(half), 0.0, np.sin(half), 0.0] if i % 2 == 0 else [0.3] for i in range(n)])
    v0 = np.linspace(-1.0, 1.0, ours.n_velocities)
    dt, steps = 2e-3, 100
    from ctmm.compiled_spatial import CompiledSpatialScene, simulate_spatial_generated

    scene = CompiledSpatialScene(ours, store_every=steps, cache_dir=tmp_path, flags=FAST_COMPILE)
    result = simulate_spatial_generated(ours, dt * steps, dt, x0=q0, v0=v0, store_every=steps, scene=scene)

    def to_pin(q):      # scalar-first (ours) -> scalar-last (Pinocchio)
        return np.concatenate([q[k:k + 4][[1, 2, 3, 0]] if joint.kind == "spherical" else q[k:k + 1]
                               for joint, k in zip(ours.joints, position_offsets[:-1])])

    position_offsets = np.cumsum([0] + [j.coordinate_count for j in ours.joints])
    velocity_offsets = np.cumsum([0] + [j.velocity_count for j in ours.joints])

    def rates(y):
        q, v = y[:ours.n_positions], y[ours.n_positions:]
        qdot, unit = [], []
        for i, j in enumerate(ours.joints):
            qi, vi = q[position_offsets[i]:position_offsets[i + 1]], v[velocity_offsets[i]:velocity_offsets[i + 1]]
            if j.kind == "spherical":
                w, x, yy, z = qi
                p, r, s = vi
                qdot.append(0.5 * np.array([-x * p - yy * r - z * s, w * p + yy * s - z * r, w * r + z * p - x * s,
                                            w * s + x * r - yy * p]))
                unit.append(qi / np.linalg.norm(qi))
            else:
                qdot.append(vi)
                unit.append(qi)
        return np.concatenate(qdot + [pin.aba(model, data, to_pin(np.concatenate(unit)), v, np.zeros(len(v)))])

    y = np.concatenate([q0, v0])
    for _ in range(steps):
        k1 = rates(y)
        k2 = rates(y + dt / 2 * k1)
        k3 = rates(y + dt / 2 * k2)
        k4 = rates(y + dt * k3)
        y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    final = np.array([result[name][-1] for name in ours.coordinates + ours.velocities])
    assert np.ptp(result[ours.coordinates[0]]) > 1e-3                     # the chain moved
    np.testing.assert_allclose(final, y, rtol=0, atol=1e-9)


def test_refusals_name_what_cannot_compile() -> None:
    def model(load_force=(1.0, 0.0, 0.0), driven=None):
        elements = [sp.SpatialBody("a", 1.0, (0.1, 0.1, 0.1), points={"tip": (0, 0, 1)}),
                    sp.SpatialBody("b", 1.0, (0.1, 0.1, 0.1)),
                    sp.Spherical(name="ball", parent=None, child="a", actuated=True),
                    sp.Load("push", "a", "tip", force=load_force)]
        if driven is None:
            elements.append(sp.Revolute(name="hinge", parent="a", point="tip", child="b", axis=(1, 0, 0)))
        else:
            elements.append(sp.Revolute(name="hinge", parent="a", point="tip", child="b", axis=(1, 0, 0),
                                        position=driven[0], rate=driven[1], acceleration=driven[2]))
        return sp.SpatialModel("m", elements)

    # ctmm.signals compile (tests/test_compiled_spatial_signals.py); user callables do not
    with pytest.raises(ModelError, match="load 'push'"):
        ctmm.simulate(model(load_force=(lambda t: 1.0, 0.0, 0.0)), 0.01, 1e-3, compiled=True)
    with pytest.raises(ModelError, match="driven joint 'hinge'"):
        ctmm.simulate(model(driven=(Harmonic(0.1, 1.0, 0.0), Harmonic(0.1, 1.0, np.pi / 2),
                                    lambda t: -0.1 * np.sin(t))), 0.01, 1e-3, compiled=True)
    with pytest.raises(ModelError, match="'ball.torque' is a function of time"):
        ctmm.simulate(model(), 0.01, 1e-3, compiled=True, inputs={"ball.torque": lambda t: np.zeros(3)})
    with pytest.raises(ModelError, match="generated RK4.*DOP853"):
        ctmm.simulate(model(), 0.01, 1e-3, method="DOP853", compiled=True)
    with pytest.raises(ModelError, match="rtol=1e-06 does not apply to the generated DT-TMM scheme 'newmark'"):
        ctmm.simulate(model(), 0.01, 1e-3, method="newmark", compiled=True, rtol=1e-6)
    with pytest.raises(ModelError, match="unknown spatial input 'nope'"):
        ctmm.simulate(model(), 0.01, 1e-3, compiled=True, inputs={"nope": 1.0})
    # constant driven motion compiles and equals the numpy path
    fixed = model(driven=(0.2, 0.0, 0.0))
    a = ctmm.simulate(fixed, 0.02, 1e-3, compiled=True, v0={"ball.wx": 1.0})
    b = ctmm.simulate(fixed, 0.02, 1e-3, v0={"ball.wx": 1.0})
    np.testing.assert_allclose(a["b.omega_y"], b["b.omega_y"], rtol=0, atol=1e-13)


def test_divergence_raises_with_the_partial_result() -> None:
    """A state beyond the bound: SimulationError at the same stored time as the numpy path, with the
    result up to the last good row."""
    model = random_tree(5, 3, "free")
    q0, v0, _ = start(5, model)
    free = ctmm.simulate(model, 0.5, 1e-3, x0=q0, v0=v0, compiled=True)  # only picks the bound (the same kernel)
    largest = max(float(np.max(np.abs(free[name] - free[name][0]))) for name in model.coordinates + model.velocities)
    bound = 0.5 * largest                                  # a distance from the start passed during the run
    caught = []
    for compiled in (None, True):
        with pytest.raises(SimulationError) as info:
            ctmm.simulate(model, 0.5, 1e-3, x0=q0, v0=v0, compiled=compiled, divergence_bound=bound)
        caught.append(info.value)
    assert caught[0].time == pytest.approx(caught[1].time)
    assert len(caught[1].partial_result.time) == len(caught[0].partial_result.time)
    assert caught[1].partial_result.time[-1] < caught[1].time


def folded_chain(n: int, mixed: bool = False) -> sp.SpatialModel:
    """A serial chain of ``n`` links: revolute joints about alternating axes (period 2), or (``mixed``)
    a period of three -- a sprung and damped revolute with a turned joint frame, a prismatic and a
    universal joint -- on links with an off-axis centre of mass."""
    inertia = np.diag([0.02, 0.09, 0.08])
    com = (0.5, 0.03, -0.02) if mixed else (0.5, 0.0, 0.0)
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    elements = []
    for i in range(n):
        elements.append(sp.SpatialBody(f"l{i}", 1.0 + 0.2 * mixed, inertia, com, {"end": (1.0, 0.0, 0.1 * mixed)}))
        common = dict(name=f"j{i}", parent=None if i == 0 else f"l{i - 1}", child=f"l{i}",
                      point=(0.1, 0.0, 0.0) if i == 0 else "end")
        if not mixed:
            elements.append(sp.Revolute(axis=(0, 1, 0) if i % 2 == 0 else (0, 0, 1), **common))
        elif i % 3 == 0:
            elements.append(sp.Revolute(axis=(0, 1, 1), rotation=turn, stiffness=3.0, damping=0.4, reference=0.1,
                                        **common))
        elif i % 3 == 1:
            elements.append(sp.Prismatic(axis=(1, 0, 0), stiffness=20.0, damping=0.5, **common))
        else:
            elements.append(sp.Universal(axis1=(1, 0, 0), axis2=(0, 0, 1), **common))
    return sp.SpatialModel(f"chain{n}", elements, gravity=(0.3, -0.2, -9.81))


def ball_chain(n: int) -> sp.SpatialModel:
    """A chain of ``n`` links (``n`` even) of period two: a sprung and damped ball-and-socket joint (full
    stiffness and damping matrices, turned joint frame) then a revolute joint, on links with an off-axis
    centre of mass and a full inertia."""
    inertia = np.array([[0.02, 0.001, 0.0], [0.001, 0.09, 0.002], [0.0, 0.002, 0.08]])
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    stiffness = np.array([[3.0, 0.2, 0.0], [0.2, 2.0, 0.1], [0.0, 0.1, 1.0]])
    elements = []
    for i in range(n):
        elements.append(sp.SpatialBody(f"l{i}", 1.2, inertia, (0.5, 0.03, -0.02), {"end": (1.0, 0.0, 0.1)}))
        common = dict(name=f"j{i}", parent=None if i == 0 else f"l{i - 1}", child=f"l{i}",
                      point=(0.1, 0.0, 0.0) if i == 0 else "end")
        elements.append(sp.Spherical(stiffness=stiffness, damping=0.3 * np.eye(3), rotation=turn, **common)
                        if i % 2 == 0 else sp.Revolute(axis=(0, 1, 1), stiffness=2.0, damping=0.1, **common))
    return sp.SpatialModel(f"ball_chain{n}", elements, gravity=(0.3, -0.2, -9.81))


def test_fold_with_ball_joints_equals_the_numpy_sweep() -> None:
    """The fold takes ball-and-socket joints: the folded accelerations of a period-2 chain of sprung ball and
    revolute joints equal the numpy sweep to 1e-12 relative, and the folded quaternion rates the model's
    ``position_rates``, at a random state with quaternions of non-unit norm (casadi's virtual machine)."""
    from ctmm.compiled_spatial import SpatialRates, chain_period

    model = ball_chain(8)
    assert chain_period(model) == 2
    rates = SpatialRates(model, fold=True)
    rng = np.random.default_rng(4)
    q, v = model.neutral() + 0.3 * rng.normal(size=model.n_positions), rng.normal(size=model.n_velocities)
    expected = sp.accelerations(model, q, v, 0.0, {})
    rate = np.asarray(rates.rate(np.r_[q, v], np.zeros(0), np.zeros(0), 0.0)).reshape(-1)
    assert np.max(np.abs(rate[model.n_positions:] - expected)) < 1e-12 * np.max(np.abs(expected))
    q_dot = model.position_rates(q[None], v[None])[0]
    assert np.max(np.abs(rate[:model.n_positions] - q_dot)) < 1e-14 * np.max(np.abs(q_dot))
    assert np.ptp(np.linalg.norm(q[:4]) - 1.0) == 0.0 and abs(np.linalg.norm(q[:4]) - 1.0) > 1e-3


def test_folded_ball_chain_runs_as_the_numpy_path(tmp_path) -> None:
    """A ball chain of 10 links (20 velocities: folded by default) compiled and run for 30 ms: every
    coordinate and velocity equal the numpy RK4 to 1e-11 relative."""
    from ctmm.compiled_spatial import CompiledSpatialScene, simulate_spatial_generated

    model = ball_chain(10)
    rng = np.random.default_rng(6)
    q0, v0 = model.neutral() + 0.1 * rng.normal(size=model.n_positions), rng.normal(size=model.n_velocities)
    scene = CompiledSpatialScene(model, store_every=3, rows=4, cache_dir=tmp_path, flags=FAST_COMPILE)
    assert scene.rates.period == 2
    generated = simulate_spatial_generated(model, 0.03, 1e-3, x0=q0, v0=v0, store_every=3, scene=scene)
    numpy_run = ctmm.simulate(model, 0.03, 1e-3, x0=q0, v0=v0, store_every=3)
    for name in list(model.coordinates) + list(model.velocities):
        scale = max(1.0, float(np.max(np.abs(numpy_run[name]))))
        assert np.max(np.abs(generated[name] - numpy_run[name])) < 1e-11 * scale, name
    assert min(np.ptp(numpy_run[name]) for name in model.velocities) > 1e-4


def test_fold_equals_the_numpy_sweep_with_every_foldable_joint() -> None:
    """The folded rates (three folds over segments, one articulated sweep per segment) of a period-3 chain
    of sprung revolute (turned joint frame), prismatic and universal joints equal the numpy sweep to
    1e-12 relative at a random state (casadi's virtual machine, nothing compiled)."""
    from ctmm.compiled_spatial import SpatialRates, chain_period

    model = folded_chain(12, mixed=True)
    assert chain_period(model) == 3
    rates = SpatialRates(model, fold=True)
    rng = np.random.default_rng(3)
    q, v = 0.4 * rng.normal(size=model.n_positions), rng.normal(size=model.n_velocities)
    expected = sp.accelerations(model, q, v, 0.0, {})
    folded = np.asarray(rates.velocity_rate(q, v, np.zeros(0), np.zeros(0), 0.0)).reshape(-1)
    assert np.max(np.abs(folded - expected)) < 1e-12 * np.max(np.abs(expected))


def test_folded_chain_of_60_runs_as_the_numpy_path_in_code_of_one_segment(tmp_path) -> None:
    """A 60-link chain compiled through the fold: every coordinate and velocity of a 40 ms RK4 run equal
    the numpy path to 1e-11 relative; the generated C of the rates grows by less than 10 kB from 60 to
    120 links (a handful of call sites and the reversing permutation), less than the straight-line C
    grows from 5 to 10 links, and stays under 150 kB."""
    from ctmm.codegen import casadi_source
    from ctmm.compiled_spatial import CompiledSpatialScene, SpatialRates, simulate_spatial_generated

    model = folded_chain(60)
    q0 = np.array([0.0 if i % 2 == 0 else 0.2 for i in range(60)])
    v0 = 0.3 * np.random.default_rng(5).normal(size=60)
    numpy_run = ctmm.simulate(model, 0.04, 1e-3, x0=q0, v0=v0, store_every=4)
    scene = CompiledSpatialScene(model, store_every=4, rows=8, cache_dir=tmp_path, flags=FAST_COMPILE, fold=True)
    assert scene.rates.period == 2
    generated = simulate_spatial_generated(model, 0.04, 1e-3, x0=q0, v0=v0, store_every=4, scene=scene)
    for name in list(model.coordinates) + list(model.velocities):
        scale = max(1.0, float(np.max(np.abs(numpy_run[name]))))
        assert np.max(np.abs(generated[name] - numpy_run[name])) < 1e-11 * scale, name
    assert min(np.ptp(numpy_run[name]) for name in model.coordinates) > 1e-6

    def size(n: int, fold: bool) -> int:
        return len(casadi_source([SpatialRates(folded_chain(n), fold=fold).velocity_rate], "size"))

    fold_60, fold_120 = size(60, True), size(120, True)
    straight_growth = size(10, False) - size(5, False)
    assert fold_60 < 150_000 and fold_120 - fold_60 < 10_000 < straight_growth, (fold_60, fold_120, straight_growth)


def test_fold_rule_and_refusals() -> None:
    """Foldable models of FOLD_MIN_VELOCITIES or more velocities take the fold by default, smaller ones the
    straight-line code; trees, loads, inputs and unequal segments are not foldable (period 0) and
    ``fold=True`` on them is refused by name."""
    from ctmm.compiled_spatial import FOLD_MIN_VELOCITIES, SpatialRates, chain_period

    assert FOLD_MIN_VELOCITIES % 2 == 0
    assert SpatialRates(folded_chain(FOLD_MIN_VELOCITIES)).period == 2
    assert SpatialRates(folded_chain(FOLD_MIN_VELOCITIES - 2)).period == 0
    assert chain_period(folded_chain(10)) == 2
    assert [(m.n_velocities, SpatialRates(m).period) for m in (ball_chain(8), ball_chain(10))] == [(16, 0), (20, 2)]
    tree = random_tree(4, 5, "free")
    assert chain_period(tree) == 0
    chain = folded_chain(6)
    loaded = sp.SpatialModel("loaded", list(chain.bodies) + list(chain.joints)
                             + [sp.Load("push", "l5", "end", force=(1.0, 0.0, 0.0))], gravity=chain.gravity)
    assert chain_period(loaded) == 0
    odd = sp.SpatialModel("odd", list(chain.bodies[:5]) + [sp.SpatialBody("l5", 2.0, np.eye(3) * 0.1, points={
        "end": (1.0, 0.0, 0.0)})] + list(chain.joints), gravity=chain.gravity)
    assert chain_period(odd) == 0
    with pytest.raises(ModelError, match="fold=True.*'odd'"):
        SpatialRates(odd, fold=True)


def test_blocks_equal_their_strides_for_every_rows() -> None:
    """Blocks built by doubling (two calls of the next smaller block and, for odd sizes, one stride) return
    the states of ``size`` strides one after the other, for powers of two, odd sizes and ``rows`` with no
    halving: a forced oscillator ``y'' = -y + t`` with a stride of 3 steps from step 5."""
    import casadi as ca

    from ctmm.generated_loop import rk4_step_function, time_loop_functions

    y, u, p, t = ca.MX.sym("y", 2), ca.MX.sym("u", 0), ca.MX.sym("p", 0), ca.MX.sym("t")
    step = rk4_step_function(ca.Function("rate", [y, u, p, t], [ca.vertcat(y[1], -y[0] + t)]))
    for rows in (3, 8, 13):
        stride, sizes, blocks = time_loop_functions(step, 3, rows)
        assert sizes == [rows >> j for j in range(rows.bit_length()) if rows >> j > 1]
        for size, block in zip(sizes, blocks):
            states, x = [], np.array([1.0, 0.0])
            for j in range(size):
                x = np.asarray(stride(x, [], 0.01, [], 0.2, 5.0 + 3 * j)).reshape(-1)
                states.append(x)
            np.testing.assert_allclose(np.asarray(block([1.0, 0.0], [], 0.01, [], 0.2, 5.0)), np.array(states).T,
                                       rtol=0, atol=1e-14)
