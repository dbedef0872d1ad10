"""The compiled frequency-context kernel of ``ctmm.compiled_sweep`` (issue 13).

It is a second implementation of the generic sweep's recursion (:func:`ctmm.articulated.articulated_sweep`)
restricted to rigid bodies and one-direction joints, in C; here it must agree with the generic sweep to
round-off on terms that exercise every branch (a branched tree, welds, held drives, joint springs and dampers,
damped bodies, the preload coupling, complex ``s`` off the axis, several load cases, both scalar variants), and
as FRFs of random branched trees (damped and undamped) with the generic sweep and the Lagrange model.  Its
answers as FRFs are also checked against the Lagrange models in ``tests/test_planar_frf_sweep.py`` (rigid
chains, trees and closed loops all take this kernel when a compiler is present).

Its a-posteriori certificate (the backward error of the joint equations, ``RESIDUAL_TOLERANCE``) against chains
whose hinge springs tune every sub-chain next to a resonance: moderate pivots, each accepted by the pivot test,
whose eliminations compound; references: 60-digit solves of the linearised Lagrange model.
"""
from __future__ import annotations

import mpmath
import numpy as np
import pytest

import ctmm
import ctmm.sweep_response as sweep_module
from ctmm.articulated import Tree, articulated_sweep, frequency_kappa
from ctmm.compiled_sweep import CompiledSweep, applies, compiler_present
from ctmm.controlled_linearization import FrequencyAtPoleError
from ctmm.ops import NUMPY
from ctmm.flexible import ModalBeam
from ctmm.planar import ElasticHinge, Pinned, PlanarModel, RigidBody, SmoothHinge, SpringDamperHinge
from ctmm.planar.elements import FixedMounting
from ctmm.planar_linearization import operating_point
from ctmm.planar_transfer_response import SweepResponse
from ctmm.protocol import BodyTerms, JointTerms
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.sweep_response import PIVOT_TOLERANCE, RESIDUAL_TOLERANCE

pytestmark = pytest.mark.skipif(not compiler_present(), reason="no C compiler: the generic sweep answers")

D = 3
PARENT = (-1, 0, 1, 0, 3, 3, 5)
POINT = (None, "a", "a", "b", "a", "b", "a")
HINGE, WELD, HELD = "hinge", "weld", "held"
KIND = (HINGE, HINGE, WELD, HINGE, HELD, HINGE, HINGE)


def terms(seed: int, coupled: bool):
    """Random symmetric positive ``M0``, symmetric ``K0``, ``C0`` and point maps of the tree above."""
    rng = np.random.default_rng(seed)
    bodies = []
    for _ in PARENT:
        a = rng.normal(size=(D, D))
        M0 = a @ a.T + D * np.eye(D)
        k = rng.normal(size=(D, D))
        c = rng.normal(size=(D, D))
        points = {name: (np.eye(D) + 0.3 * rng.normal(size=(D, D)))[None] for name in ("a", "b")}
        forces = {name: (np.eye(D) + 0.3 * rng.normal(size=(D, D)))[None] for name in ("a", "b")}
        bodies.append((M0, 0.1 * (c + c.T), k + k.T, points, forces))
    joints, coupling = [], []
    for j, kind in enumerate(KIND):
        unit = np.zeros((1, D, 1))
        unit[0, 2, 0] = 1.0
        if kind == HINGE:
            joints.append(JointTerms(S=unit, tau=np.zeros((1, 1, 1)), tau_q=np.full((1, 1, 1), -rng.uniform(1, 3)),
                                     tau_v=np.full((1, 1, 1), -rng.uniform(0, 0.4)), axis=2))
        elif kind == HELD:
            joints.append(JointTerms(S=unit, prescribed=np.zeros((1, 1, 1)), axis=2))
        else:
            joints.append(JointTerms(S=np.zeros((1, D, 0))))
        pair = None
        if coupled and kind == HINGE and PARENT[j] >= 0:
            pair = (rng.normal(size=(1, 1, D)), rng.normal(size=(1, D, 1)))
        coupling.append(pair)
    return Tree(PARENT, POINT, D), bodies, joints, coupling


def generic(tree, bodies, joints, coupling, s, load, torque):
    """The generic sweep of ``ctmm.articulated`` on the same terms: ``A_in`` (N, d, B) and the pivots (F, B)."""
    column = s.reshape(-1, 1, 1)
    body_terms = [BodyTerms(column * column * M0 + column * C0 + K0, load[j][None, :, None], Kin,
                            dict.fromkeys(Kin), RF) for j, (M0, C0, K0, Kin, RF) in enumerate(bodies)]
    loaded = [JointTerms(S=jt.S, tau=np.full((1, 1, 1), torque[j]), tau_q=jt.tau_q, tau_v=jt.tau_v, axis=jt.axis)
              if jt.tau is not None else jt for j, jt in enumerate(joints)]
    solution = articulated_sweep(NUMPY, tree, body_terms, loaded, frequency_kappa(NUMPY, loaded, column),
                                 forces=False, coupling=coupling)
    x = np.stack([np.broadcast_to(v, (s.size, D, 1))[:, :, 0].T for v in solution.x])
    pivots = np.array([p[:, 0, 0] for p in solution.pivot if p is not None])
    return x, pivots


TOLERANCES = {"pivot_tolerance": PIVOT_TOLERANCE, "residual_tolerance": RESIDUAL_TOLERANCE}


@pytest.mark.parametrize("coupled", [False, True])
@pytest.mark.parametrize("on_axis", [True, False])
def test_kernel_equals_the_generic_sweep(coupled, on_axis):
    """Damped terms (or s off the axis): the complex variant, against the generic sweep, two load cases."""
    tree, bodies, joints, coupling = terms(3, coupled)
    assert applies(tree, bodies, joints, coupling)
    s = 1j * np.linspace(0.2, 5.0, 9) + (0.0 if on_axis else 0.4)
    rng = np.random.default_rng(7)
    loads, torques = rng.normal(size=(len(PARENT), D, 2)), rng.normal(size=(5, 2))     # two load cases
    kernel = CompiledSweep(tree, bodies, joints, coupling)
    assert kernel.free == [0, 1, 3, 5, 6]
    solution = kernel.solve(s, loads, torques, **TOLERANCES)
    assert solution.x.dtype == complex and solution.x.shape == (len(PARENT), D, 2, s.size)
    for case in range(2):
        torque = dict(zip(kernel.free, torques[:, case]))
        x, pivots = generic(tree, bodies, joints, coupling, s, loads[:, :, case],
                            [torque.get(j, 0.0) for j in range(len(PARENT))])
        assert np.max(np.abs(solution.x[:, :, case] - x)) <= 1e-12 * np.max(np.abs(x))
        assert np.max(np.abs(solution.pivot - pivots)) <= 1e-12 * np.max(np.abs(pivots))
    assert np.all(solution.backward < 1e-13)
    # the pivots of the mass terms alone (kappa = 0, no coupling)
    inertia = [BodyTerms(M0[None], np.zeros((1, D, 1)), Kin, dict.fromkeys(Kin), RF) for M0, _, _, Kin, RF in bodies]
    masses = articulated_sweep(NUMPY, tree, inertia, joints, forces=False)
    expected = np.array([p[0, 0, 0] for p in masses.pivot if p is not None])
    assert np.max(np.abs(kernel.mass_pivot[kernel.free] - expected)) <= 1e-12 * np.max(np.abs(expected))


def test_real_variant_equals_the_generic_sweep():
    """Undamped terms on the imaginary axis with real loads: the real variant (s^2 = -omega^2), 20 load cases
    (two groups of the kernel's load cases)."""
    tree, bodies, joints, coupling = terms(5, True)
    bodies = [(M0, np.zeros_like(C0), K0, Kin, RF) for M0, C0, K0, Kin, RF in bodies]
    joints = [JointTerms(S=j.S, tau=j.tau, tau_q=j.tau_q, axis=j.axis) if j.tau is not None else j for j in joints]
    s = 1j * np.linspace(0.2, 5.0, 7)
    rng = np.random.default_rng(8)
    loads, torques = rng.normal(size=(len(PARENT), D, 20)), rng.normal(size=(5, 20))
    kernel = CompiledSweep(tree, bodies, joints, coupling)
    solution = kernel.solve(s, loads, torques, **TOLERANCES)
    assert solution.x.dtype == float and solution.x.shape == (len(PARENT), D, 20, s.size)
    for case in (0, 19):
        torque = dict(zip(kernel.free, torques[:, case]))
        x, _ = generic(tree, bodies, joints, coupling, s, loads[:, :, case],
                       [torque.get(j, 0.0) for j in range(len(PARENT))])
        assert np.max(np.abs(solution.x[:, :, case] - x)) <= 1e-12 * np.max(np.abs(x))
    assert solution.good.all()


@pytest.mark.parametrize("damped", [False, True])
def test_unit_axes_and_columns_share_one_kernel_bit_for_bit(damped):
    """One kernel text serves joints on a unit axis (a row and column of ``P``) and on a column ``S`` (products with
    ``S``): one library per dimension and scalar type, which reads from the axes whether to run the products.  The
    tree with its hinges and held drives stated on the column ``S = e_z`` (no unit axis) is answered by the same
    library as with ``axis=2``, and bit for bit the same numbers (the products with a unit column are exact)."""
    tree, bodies, joints, coupling = terms(6, True)
    if not damped:                                  # undamped, on the imaginary axis: the real variant
        bodies = [(M0, np.zeros_like(C0), K0, Kin, RF) for M0, C0, K0, Kin, RF in bodies]
        joints = [JointTerms(S=j.S, tau=j.tau, tau_q=j.tau_q, axis=j.axis) if j.tau is not None else j
                  for j in joints]
    columns = [JointTerms(S=j.S, tau=j.tau, tau_q=j.tau_q, tau_v=j.tau_v, prescribed=j.prescribed)
               if j.axis is not None else j for j in joints]
    s = 1j * np.linspace(0.2, 5.0, 11)
    rng = np.random.default_rng(9)
    loads, torques = rng.normal(size=(len(PARENT), D, 3)), rng.normal(size=(5, 3))
    unit, column = CompiledSweep(tree, bodies, joints, coupling), CompiledSweep(tree, bodies, columns, coupling)
    assert list(unit.axis) != list(column.axis) and -2 in list(column.axis)
    assert unit.library(damped)._name == column.library(damped)._name          # one library, compiled once
    first = unit.solve(s, loads, torques, relative=True, **TOLERANCES)
    second = column.solve(s, loads, torques, relative=True, **TOLERANCES)
    assert first.x.dtype == (complex if damped else float)
    for name in ("x", "relative", "pivot", "backward", "good"):
        assert np.array_equal(getattr(first, name), getattr(second, name)), name
    assert np.array_equal(unit.mass_pivot, column.mass_pivot)


def test_kernel_declines_terms_it_does_not_take():
    tree, bodies, joints, coupling = terms(4, False)
    flexible = list(bodies)
    M0, C0, K0, Kin, RF = bodies[2]
    flexible[2] = (np.eye(D + 1), np.zeros((D + 1, D + 1)), np.zeros((D + 1, D + 1)), Kin, RF)
    assert not applies(tree, flexible, joints, coupling)                   # a modal body
    free = list(joints)
    free[0] = JointTerms(S=np.eye(D)[None], tau=np.zeros((1, D, 1)))
    assert not applies(tree, bodies, free, coupling)                       # three free directions
    driven = list(joints)
    driven[4] = JointTerms(S=joints[4].S, prescribed=np.ones((1, 1, 1)), axis=2)
    assert not applies(tree, bodies, driven, coupling)                     # a drive not held at zero


def test_planar_plants_take_the_kernel_where_it_applies():
    arm = PlanarModel.chain("arm", [
        Pinned("base"), RigidBody("a", mass=1.0, inertia=0.1, center_of_mass=(0.5, 0.0), outboard=(1.0, 0.0)),
        SmoothHinge("h"), RigidBody("b", mass=0.5, inertia=0.05, center_of_mass=(0.4, 0.0))], gravity=(0.0, -9.81))
    plant = SweepResponse(arm, operating_point(arm))
    assert plant.compiled is not None
    G, good = plant.response(1j * np.array([0.5, 2.0]), ["b.force_x"], ["b.theta"])
    assert good.all()
    beam = PlanarModel.chain("beam", [Pinned("base"), RigidBody("hub", mass=1.0, inertia=0.1, outboard=(0.1, 0.0)),
                                      FixedMounting("m"), ModalBeam("b", length=1.0, bending_stiffness=10.0,
                                                                    mass_per_length=0.5, n_modes=2)],
                             gravity=(0.0, 0.0))
    assert SweepResponse(beam, operating_point(beam)).compiled is None      # modal bodies: the generic sweep


def test_a_compiler_that_cannot_build_the_kernel_leaves_the_generic_sweep(monkeypatch):
    """A compile error (here: a stand-in for a compiler refusing the kernel's flags) is warned about and the
    generic sweep answers, the same numbers."""
    import ctmm.compiled_sweep as compiled_module
    from ctmm.errors import ModelError

    model = uniform_chain(np.full(4, 20.0))
    point = operating_point(model, (np.zeros(4), np.zeros(4)))
    s = 1j * np.array([0.5, 2.0, 7.0])
    expected, _ = SweepResponse(model, point).response(s, ["l3.moment"], ["l3.theta"])

    def refuse(*arguments):
        raise ModelError("compiling the kernel failed (exit 1)")

    monkeypatch.setattr(compiled_module, "kernel_library", refuse)
    with pytest.warns(RuntimeWarning, match="generic numpy sweep"):
        plant = SweepResponse(model, point)
    assert plant.compiled is None
    G, good = plant.response(s, ["l3.moment"], ["l3.theta"])
    assert good.all() and np.max(np.abs(G - expected)) <= 1e-12 * np.max(np.abs(expected))


# ------------------------------------------------------------------ the a-posteriori certificate (compounding)
def tuned_chain(links: int, fraction: float, omega: float) -> PlanarModel:
    """A chain whose hinge springs put every sub-chain next to a resonance at ``omega``: tip to base, each hinge
    stiffness leaves its pivot ``D_j = fraction |P_aa|`` (the elimination's pivots are read off the sweep only to
    build the model; the references below are the Lagrange model's)."""
    stiffness = np.ones(links)
    zero = (np.zeros(links), np.zeros(links))
    for j in range(links - 1, 0, -1):
        model = uniform_chain(stiffness)
        kernel = SweepResponse(model, operating_point(model, zero)).compiled
        pivot = kernel.solve(np.array([1j * omega]), np.zeros((links, D, 1)), np.zeros((len(kernel.free), 1)),
                             **TOLERANCES).pivot
        inertia = pivot[kernel.free.index(j), 0].real - stiffness[j]
        stiffness[j] = -inertia + fraction * abs(inertia)
    return uniform_chain(stiffness)


def uniform_chain(stiffness: np.ndarray) -> PlanarModel:
    elements = [Pinned("base")]
    for i, k in enumerate(stiffness):
        if i:
            elements.append(ElasticHinge(f"h{i}", stiffness=float(k)))
        elements.append(RigidBody(f"l{i}", mass=1.0, inertia=0.1, center_of_mass=(0.5, 0.0), outboard=(1.0, 0.0)))
    return PlanarModel.chain("tuned", elements, gravity=(0.0, 0.0))


def reference_angle(model: PlanarModel, omega: float) -> float:
    """``theta_tip / moment_tip`` of the linearised Lagrange model by a 60-digit solve of ``K - omega^2 M``."""
    lagrange = PlanarLagrange(model)
    M, _, K = lagrange.linearize(np.zeros(model.n_coordinates))
    row = np.zeros(model.n_coordinates)
    row[lagrange.src[model.n_bodies - 1]] = 1.0
    with mpmath.workdps(60):
        x = mpmath.lu_solve(mpmath.matrix((K - omega * omega * M).tolist()), mpmath.matrix(row.tolist()))
        return float(mpmath.fdot(row.tolist(), x))


def certificate(model: PlanarModel, omega: float):
    """The kernel's answer at ``omega``, its pivots' relative sizes and its backward error."""
    zero = (np.zeros(model.n_coordinates), np.zeros(model.n_coordinates))
    plant = SweepResponse(model, operating_point(model, zero))
    name = f"l{model.n_bodies - 1}"
    G, good = plant.response(np.array([1j * omega]), [f"{name}.moment"], [f"{name}.theta"])
    kernel = plant.compiled
    loads = np.stack([h[0, :, 0] for h in plant.loads(f"{name}.moment")[0]])[:, :, None]
    solution = kernel.solve(np.array([1j * omega]), loads, np.zeros((len(kernel.free), 1)), **TOLERANCES)
    inertia = -omega * omega * kernel.mass_pivot[kernel.free]
    r = np.abs(solution.pivot[:, 0]) / (np.abs(inertia) + np.abs(solution.pivot[:, 0] - inertia))
    return G[0, 0, 0], bool(good[0]), r, float(solution.backward[0])


def test_compounded_eliminations_are_handed_to_the_resolvent():
    """Three links, both inner sub-chains 5e-6 of their terms from resonance: every pivot passes the pivot
    test, yet the sweep's answer is 1e-6 off; the backward error sees it and the resolvent answers."""
    model, omega = tuned_chain(3, 1e-5, 3.0), 3.0
    reference = reference_angle(model, omega)
    answer, good, r, backward = certificate(model, omega)
    assert np.all(r >= PIVOT_TOLERANCE)                     # the pivot test alone would certify it
    assert abs(answer - reference) > 1e-8 * abs(reference)  # and it would be wrong
    assert backward > RESIDUAL_TOLERANCE and not good
    frf = ctmm.frequency_response(model, [2.0, omega], input="l2.moment", output="l2.theta",
                                  operating_point=(np.zeros(3), np.zeros(3)))
    assert frf.info["n_dense_frequencies"] == 1
    assert abs(frf.response[0, 0, 1] - reference) <= 1e-9 * abs(reference)
    assert abs(frf.response[0, 0, 0] - reference_angle(model, 2.0)) <= 1e-9 * abs(reference_angle(model, 2.0))


def test_many_moderate_pivots_compounding_are_not_answered_by_the_sweep():
    """Six links, four inner pivots each 5e-4 of their terms (moderate): the sweep's answer is 1e-3 off a
    60-digit solve; the backward error hands the frequency over and the resolvent refuses it (its scaled
    condition number is 1e14)."""
    model, omega = tuned_chain(6, 1e-3, 3.0), 3.0
    answer, good, r, backward = certificate(model, omega)
    assert np.all(r >= 1e-4)
    assert abs(answer - reference_angle(model, omega)) > 1e-4 * abs(answer)
    assert backward > RESIDUAL_TOLERANCE and not good
    with pytest.raises(FrequencyAtPoleError):
        ctmm.frequency_response(model, [omega], input="l5.moment", output="l5.theta",
                                operating_point=(np.zeros(6), np.zeros(6)))


def test_backward_error_of_a_plain_chain_is_rounding():
    """The 30-link pendulum with hinge springs: backward error at the level of rounding, every frequency answered."""
    model = uniform_chain(np.full(30, 50.0))
    plant = SweepResponse(model, operating_point(model, (np.zeros(30), np.zeros(30))))
    G, good = plant.response(1j * np.logspace(-1, 2, 50), ["l29.moment"], ["l29.theta"])
    loads = np.stack([h[0, :, 0] for h in plant.loads("l29.moment")[0]])[:, :, None]
    solution = plant.compiled.solve(1j * np.logspace(-1, 2, 50), loads, np.zeros((30, 1)), **TOLERANCES)
    assert np.max(solution.backward) < 1e-12


def test_the_generic_sweep_states_the_same_backward_error(monkeypatch):
    """Modal bodies, finite elements, free bases, spatial models and every model without a C compiler take the
    generic sweep: its twin of the certificate (``ctmm.sweep_response.backward_error``) hands the tuned three-link
    chain over as well."""
    model, omega = tuned_chain(3, 1e-5, 3.0), 3.0
    monkeypatch.setattr(sweep_module, "compiler_present", lambda: False)
    plant = SweepResponse(model, operating_point(model, (np.zeros(3), np.zeros(3))))
    assert plant.compiled is None
    _, good = plant.response(np.array([2.0j, 1j * omega]), ["l2.moment"], ["l2.theta"])
    assert good.tolist() == [True, False]
    frf = ctmm.frequency_response(model, [omega], input="l2.moment", output="l2.theta",
                                  operating_point=(np.zeros(3), np.zeros(3)))
    reference = reference_angle(model, omega)
    assert frf.info["n_dense_frequencies"] == 1 and abs(frf.response[0, 0, 0] - reference) <= 1e-9 * abs(reference)


# ------------------------------------------------------------------ random branched trees: generated, numpy, Lagrange
def random_tree(seed: int, damped: bool) -> PlanarModel:
    """A random branched tree of 6-9 rigid bodies on spring(-damper) hinges, each hanging on a random earlier body
    (no gravity: the straight configuration is the equilibrium; the preloaded trees of
    ``tests/test_planar_frf_sweep.py`` carry gravity's coupling)."""
    rng = np.random.default_rng(seed)
    count = int(rng.integers(6, 10))
    elements = [Pinned("base", child="b0")]
    for j in range(count):
        elements.append(RigidBody(f"b{j}", mass=float(rng.uniform(0.3, 2.0)), inertia=float(rng.uniform(0.02, 0.2)),
                                  center_of_mass=tuple(rng.uniform(-0.2, 0.6, 2)),
                                  outboard={f"e{k}": tuple(rng.uniform(-0.8, 0.8, 2)) for k in range(2)}))
        if j:
            parent = f"b{int(rng.integers(0, j))}.e{int(rng.integers(0, 2))}"
            stiffness = float(rng.uniform(1.0, 20.0))
            hinge = SpringDamperHinge(f"h{j}", parent=parent, child=f"b{j}", stiffness=stiffness,
                                      damping=float(rng.uniform(0.05, 0.5))) if damped else \
                ElasticHinge(f"h{j}", parent=parent, child=f"b{j}", stiffness=stiffness)
            elements.append(hinge)
    return PlanarModel(f"random{seed}", elements, gravity=(0.0, 0.0))


@pytest.mark.parametrize("seed, damped", [(11, False), (12, True), (13, True)])
def test_random_trees_generated_equal_the_generic_sweep_and_the_lagrange_model(seed, damped, monkeypatch):
    model = random_tree(seed, damped)
    point = operating_point(model, (np.zeros(model.n_coordinates), np.zeros(model.n_coordinates)))
    omega = np.logspace(-1, 1.5, 40)
    last = f"b{model.n_bodies - 1}"
    inputs, outputs = [f"{last}.moment", "b1.moment"], [f"{last}.theta", "b2.theta"]
    plant = SweepResponse(model, point)
    assert plant.compiled is not None
    G, good = plant.response(1j * omega, inputs, outputs)
    monkeypatch.setattr(sweep_module, "compiler_present", lambda: False)
    generic_plant = SweepResponse(model, point)
    assert generic_plant.compiled is None
    G_generic, good_generic = generic_plant.response(1j * omega, inputs, outputs)
    assert good.all() and np.array_equal(good, good_generic)
    assert np.max(np.abs(G - G_generic)) <= 1e-11 * np.max(np.abs(G_generic))
    lagrange = PlanarLagrange(model)
    M, C, K = lagrange.linearize(point.q)
    angle = np.zeros((model.n_bodies, model.n_coordinates))
    for j in range(model.n_bodies):
        angle[j, lagrange.src[j]] = 1.0
    index = model.body_names.index                  # the model's bodies in topological order
    rows = angle[[index(last), index("b2")]]
    columns = angle[[index(last), index("b1")]].T
    reference = np.array([rows @ np.linalg.solve(-w * w * M + 1j * w * C + K, columns) for w in omega])
    scale = np.max(np.abs(reference), axis=0)
    assert np.max(np.abs(G - reference) / scale) <= 1e-9


def test_the_pivot_certificate_decides_as_the_generic_sweep(monkeypatch):
    """The double pendulum at its outer link's own resonance (``omega^2 = 3 g / (2 L)``: the outer joint's pivot
    closes, a substructure resonance, not a pole), next to it and at a pole: the kernel hands over exactly the
    frequencies the generic sweep hands over, and agrees with it at the others."""
    model = PlanarModel.chain("double", [Pinned("base"), RigidBody.uniform_link("l0", mass=1.0, length=1.0),
                                         SmoothHinge("h1"), RigidBody.uniform_link("l1", mass=1.0, length=1.0)],
                              gravity=(0.0, -9.81))
    point = operating_point(model)
    lagrange = PlanarLagrange(model)
    M, _, K = lagrange.linearize(point.q)
    poles = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    w_sub = np.sqrt(9.81 * 0.5 / (1.0 / 3.0))
    s = 1j * np.array([1.0, w_sub, w_sub * (1 + 1e-9), w_sub * (1 + 1e-3), poles[1], 7.0])
    G, good = SweepResponse(model, point).response(s, ["l1.force_x"], ["l0.theta", "l1.theta"])
    monkeypatch.setattr(sweep_module, "compiler_present", lambda: False)
    G_generic, good_generic = SweepResponse(model, point).response(s, ["l1.force_x"], ["l0.theta", "l1.theta"])
    assert good.tolist() == good_generic.tolist() == [True, False, False, True, False, True]
    assert np.max(np.abs(G[good] - G_generic[good])) <= 1e-12 * np.max(np.abs(G_generic[good]))
