"""Contract of the 1-D lumped families on the element protocol (issue 12, plan S4A; ``ctmm/lumped_forms.py``).

* frequency context: for random chains of every lumped family and boundary, the states at every
  connection point and the characteristic function equal today's chain transfer solution (the scalar
  Riccati fast path ``chain_assembly.solve``, the assembled ``U(s)`` path and
  ``frequency.characteristic_function``), and the displacements equal the independent global
  equations (``reference/inerter_chain.py``);
* explicit context: accelerations equal ``M^-1 (f - C v - K x)`` of the global references
  (``reference/chain.py``, ``reference/inerter_chain.py``); a massless node is refused;
* the terms run on casadi symbols and give the numpy numbers.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.assembly import SOLVERS
from ctmm.chain_assembly import assemble, solve
from ctmm.elements import (BeamClamped, BeamField, BeamFree, Damper, Elastic, Fixed, Free, GroundedSpring, Inerter,
                           Mass, PrescribedDisplacement, PrescribedForce, Spring, SpringDamper)
from ctmm.errors import ModelError
from ctmm.frequency import characteristic_function
from ctmm.lumped_forms import explicit_accelerations, frequency_states, implicit_corrections, lumped_tree
from ctmm.ops import CASADI, NUMPY
from ctmm.protocol import Motion
from ctmm.reference import chain as global_chain
from ctmm.reference import inerter_chain
from _chain_convert import inerter_chains, random_chain, to_global

S = 0.05 + 1j * np.array([0.0, 0.7, 3.1, 9.0, 22.0])      # off the axis: no resonance is hit exactly


def _connector(rng, name):
    kind = rng.integers(4)
    k, c, b = float(rng.uniform(20, 300)), float(rng.uniform(0.1, 3.0)), float(rng.uniform(0.05, 1.0))
    length = float(rng.uniform(-0.5, 0.5))
    return [Spring(name, k, free_length=length), Damper(name, c), SpringDamper(name, k, c, free_length=length),
            Inerter(name, b, stiffness=k * rng.integers(2), damping=c * rng.integers(2))][kind]


def _boundary(rng, name, kinds):
    kind = kinds[rng.integers(len(kinds))]
    return {"fixed": lambda: Fixed(name, position=float(rng.uniform(-1, 1))),
            "free": lambda: Free(name),
            "elastic": lambda: Elastic(name, float(rng.uniform(20, 200)), damping=float(rng.uniform(0, 1)),
                                       anchor=float(rng.uniform(-1, 1))),
            "base": lambda: PrescribedDisplacement(name, 0.0),
            "force": lambda: PrescribedForce(name, 0.0)}[kind]()


def _random_lumped_chain(seed: int) -> ctmm.Chain:
    """Every lumped family, massless nodes (connectors in series), point elements on a fixed end."""
    rng = np.random.default_rng(seed)
    elements = [_boundary(rng, "start", ("fixed", "free", "elastic", "base", "force"))]
    for i in range(int(rng.integers(3, 7))):
        if rng.uniform() < 0.85:
            elements.append(_connector(rng, f"k{i}"))
        if rng.uniform() < 0.8:
            elements.append(Mass(f"m{i}", float(rng.uniform(0.2, 3.0))))
        if rng.uniform() < 0.3:
            elements.append(GroundedSpring(f"g{i}", float(rng.uniform(10, 100)), damping=float(rng.uniform(0, 1))))
    if not any(isinstance(e, (Spring, Damper, SpringDamper, Inerter)) for e in elements):
        elements.append(_connector(rng, "k_last"))
    if not any(e.is_point for e in elements[1:]):
        elements.append(Mass("m_last", 1.0))
    elements.append(_boundary(rng, "end", ("fixed", "free", "elastic", "base", "force")))
    return ctmm.Chain(f"lumped_{seed}", elements)


def _relative(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(b)))


@pytest.mark.parametrize("seed", range(24))
def test_frequency_context_equals_the_chain_transfer_solution_for_every_family(seed):
    chain = _random_lumped_chain(seed)
    tree = lumped_tree(chain)
    for position, element in enumerate(chain.elements):
        for name in element.inputs:
            amplitudes = {position: {name: 0.7 - 0.2j}}
            derived = frequency_states(tree, S, amplitudes).states
            fast = solve(chain, S, amplitudes).states                       # scalar Riccati fast path
            Us, us, start, end = assemble(chain, S, amplitudes)               # element matrices U(s)
            generic = SOLVERS["riccati"](Us, us, start, end).states
            scale = np.max(np.abs(fast), axis=(0, 2))                        # per frequency
            assert np.max(np.abs(derived - fast) / scale[None, :, None]) <= 1e-12, (element.name, name)
            assert np.max(np.abs(derived - generic) / scale[None, :, None]) <= 1e-12, (element.name, name)
    s = np.concatenate([S, [1.0 + 0j]])
    characteristic = frequency_states(tree, s).characteristic
    expected = characteristic_function(chain, S)                            # normalised at s = 1
    assert _relative(characteristic[:-1] / characteristic[-1], expected) <= 1e-12


@pytest.mark.parametrize("seed", range(6))
def test_frequency_context_equals_the_global_equations_with_inerters(seed):
    rng = np.random.default_rng(100 + seed)
    n = 4
    masses = rng.uniform(0.3, 2.0, n)
    k, c, b = rng.uniform(20, 200, n + 1), rng.uniform(0.1, 1.0, n + 1), rng.uniform(0.1, 0.8, n + 1)
    b[rng.integers(n + 1)] = 0.0
    chain, reference = inerter_chains(masses, k, c, b, ("fixed", "free")[seed % 2])
    tree = lumped_tree(chain)
    omega = np.array([0.5, 4.0, 11.0])
    force = rng.normal(size=n)
    amplitudes = {chain.position(f"m{i}"): {"force": force[i]} for i in range(n)}
    states = frequency_states(tree, 1j * omega, amplitudes).states
    derived = np.array([states[chain.position(f"m{i}"), :, 0] for i in range(n)]).T
    assert _relative(derived, inerter_chain.frequency_response(reference, omega, force)) <= 1e-12


def _node_of(tree, chain, name) -> int:
    return tree.node[tree.positions.index(chain.position(name))]


@pytest.mark.parametrize("start, end", [("fixed", "fixed"), ("fixed", "free"), ("free", "fixed"),
                                        ("elastic", "free"), ("free", "elastic")])
@pytest.mark.parametrize("seed", range(3))
def test_explicit_context_equals_the_global_equations(start, end, seed):
    rng = np.random.default_rng(seed)
    chain = random_chain(rng, 4, start=start, end=end, damped=True, grounded=True)
    reference = to_global(chain)
    tree = lumped_tree(chain)
    x, v, f = rng.normal(size=(3, 3, reference.size))
    expected = global_chain.accelerations(reference, x, v, f)
    masses = [e.name for e in chain.body if isinstance(e, Mass)]
    nodes = [_node_of(tree, chain, name) for name in masses]
    xn, vn = np.zeros((3, tree.n_nodes)), np.zeros((3, tree.n_nodes))
    xn[:, nodes], vn[:, nodes] = x, v
    inputs = {chain.position(name): {"force": f[:, i].reshape(-1, 1, 1)} for i, name in enumerate(masses)}
    accelerations = explicit_accelerations(tree, xn, vn, 0.0, inputs)[:, nodes]
    assert _relative(accelerations, expected) <= 1e-12


@pytest.mark.parametrize("seed", range(4))
def test_explicit_context_with_inerters_and_inertance_only_nodes(seed):
    rng = np.random.default_rng(200 + seed)
    n = 4
    masses = rng.uniform(0.3, 2.0, n)
    masses[1] = 0.0                                       # held only by the inerters beside it
    k, c, b = rng.uniform(20, 200, n + 1), rng.uniform(0.1, 1.0, n + 1), rng.uniform(0.1, 0.8, n + 1)
    reference = inerter_chain.InerterChain(masses, k, c, b, start="fixed", end="fixed")
    elements = [Fixed("start")]
    for j in range(n + 1):
        elements.append(Inerter(f"c{j}", b[j], stiffness=k[j], damping=c[j]))
        if j < n and masses[j]:
            elements.append(Mass(f"m{j}", masses[j]))
    chain = ctmm.Chain("inerters", elements + [Fixed("end")])
    tree = lumped_tree(chain)
    x, v, f = rng.normal(size=(3, n))
    f[1] = 0.0
    nodes = [tree.node[tree.positions.index(chain.position(f"m{j}"))] if masses[j] else
             tree.node[tree.point_body[chain.position(f"c{j}")]] for j in range(n)]
    xn, vn = np.zeros(tree.n_nodes), np.zeros(tree.n_nodes)
    xn[nodes], vn[nodes] = x, v
    inputs = {chain.position(f"m{j}"): {"force": f[j]} for j in range(n) if masses[j]}
    accelerations = explicit_accelerations(tree, xn, vn, 0.0, inputs)[0, nodes]
    assert _relative(accelerations, inerter_chain.initial_acceleration(reference, x, v, f)) <= 1e-12


@pytest.mark.parametrize("seed", range(6))
def test_implicit_context_solves_the_global_step_equations(seed):
    """One implicit sweep = ``(C M + A C_d + cx K) delta = f - M D - C_d B - K dx`` of the global matrices
    (``reference/inerter_chain.py``), with inerters and a massless node between two springs."""
    rng = np.random.default_rng(300 + seed)
    n = 5
    masses = rng.uniform(0.3, 2.0, n)
    masses[2] = 0.0
    k, c, b = rng.uniform(20, 200, n + 1), rng.uniform(0.1, 1.0, n + 1), rng.uniform(0.1, 0.8, n + 1)
    b[2] = b[3] = 0.0                                     # node 2: a massless point between two springs
    chain, reference = inerter_chains(masses, k, c, b, ("fixed", "free")[seed % 2])
    tree = lumped_tree(chain)
    nodes = [tree.node[tree.positions.index(chain.position(f"m{j}"))] if masses[j] else
             tree.node[tree.point_body[chain.position(f"c{j}")]] for j in range(n)]
    cx, A, C = 0.25, 2.0e3, 4.0e6                          # Newmark at dt = 1 ms (x = delta + ..., scaled)
    dx, B, D, f = rng.normal(size=(4, n))
    f[2] = 0.0
    values = [np.zeros(tree.n_nodes) for _ in range(3)]
    for value, given in zip(values, (dx, B, D)):
        value[nodes] = given
    inputs = {chain.position(f"m{j}"): {"force": f[j]} for j in range(n) if masses[j]}
    delta = implicit_corrections(tree, cx, A, C, *values, 0.0, inputs)[0, nodes]
    M, Cd, K = inerter_chain.assemble(reference)
    expected = np.linalg.solve(C * M + A * Cd + cx * K, f - M @ D - Cd @ B - K @ dx)
    assert _relative(delta, expected) <= 1e-12


def test_explicit_context_refuses_a_massless_node_between_springs():
    chain = ctmm.Chain("series", [Fixed("w"), Spring("k1", 10.0), Spring("k2", 20.0), Mass("m", 1.0), Free("e")])
    tree = lumped_tree(chain)
    with pytest.raises(ModelError, match="no mass and no inertance"):
        explicit_accelerations(tree, np.zeros(tree.n_nodes), np.zeros(tree.n_nodes))
    # the frequency context solves it: two springs in series
    states = frequency_states(tree, [0.0], {3: {"force": 1.0}}).states
    assert abs(states[3, 0, 0] - (1 / 10.0 + 1 / 20.0)) <= 1e-15


def test_non_lumped_chains_are_refused_by_name():
    beam = ctmm.Chain("beam", [BeamClamped("c"), BeamField("b", 1.0, 1.0, 1.0),
                               BeamFree("f")])
    with pytest.raises(ModelError, match="only lumped 1-D elements"):
        lumped_tree(beam)
    with pytest.raises(ModelError, match="can move"):
        lumped_tree(ctmm.Chain("held", [Fixed("a"), Mass("m", 1.0), Fixed("b")]))


def test_terms_on_casadi_symbols_equal_numpy():
    casadi = pytest.importorskip("casadi")
    x, v, F = casadi.SX.sym("x"), casadi.SX.sym("v"), casadi.SX.sym("F")
    values = (0.3, -1.2, 2.5)
    point = GroundedSpring("g", 40.0, damping=0.7)
    body = point.terms(CASADI, Motion((x,), (v,)), u={"force": F})
    reference = point.terms(NUMPY, Motion((np.full((1, 1, 1), 0.3),), (np.full((1, 1, 1), -1.2),)),
                            u={"force": 2.5})
    h = casadi.Function("h", [x, v, F], [body.h])(*values)
    assert abs(float(h) - float(reference.h[0, 0, 0])) <= 1e-15
    for element in (SpringDamper("k", 50.0, 0.4, free_length=0.2), Inerter("b", 0.3, stiffness=9.0),
                    Elastic("e", 30.0, damping=0.5, anchor=0.1)):
        joint = element.terms(CASADI, x, v, 0.0, {"force": F}) if not isinstance(element, Elastic) else \
            element.terms(CASADI, x, v, 0.0, side="end")
        expected = element.terms(NUMPY, np.full((1, 1, 1), 0.3), np.full((1, 1, 1), -1.2), 0.0, {"force": 2.5}) \
            if not isinstance(element, Elastic) else element.terms(NUMPY, np.full((1, 1, 1), 0.3),
                                                                   np.full((1, 1, 1), -1.2), 0.0, side="end")
        tau = casadi.Function("tau", [x, v, F], [joint.tau])(*values)
        assert abs(float(tau) - float(expected.tau[0, 0, 0])) <= 1e-13


@pytest.mark.parametrize("seed", [0, 1, 2, 4, 6, 7, 8, 9, 12, 13])     # 3: refused in time (mass on a driven end)
def test_fast_time_kernel_equals_the_step_derived_from_the_terms(seed):
    """The vectorised kernel (``timestep._LumpedKernel``, scalar Riccati) against the generic DT-TMM
    step, whose element matrices are derived from the terms (``elements/axial.py``)."""
    chain = _random_lumped_chain(seed)
    x0, value = {}, 0.01            # one value per node: masses joined without a connector share a point
    for element in chain.body:
        if isinstance(element, Mass):
            x0[element.name] = value
        elif not element.is_point:  # a connector: the masses after it sit on the next node
            value += 0.01
    for scheme in ("newmark", "generalized_alpha", "houbolt"):
        fast = ctmm.simulate(chain, 0.03, 1e-3, scheme=scheme, x0=x0, fast=True)
        generic = ctmm.simulate(chain, 0.03, 1e-3, scheme=scheme, x0=x0, fast=False)
        scale = np.max(np.abs(fast.states[:, :, 0])) + 1.0
        assert np.max(np.abs(fast.states[:, :, 0] - generic.states[:, :, 0])) <= 1e-13 * scale
        assert np.max(np.abs(fast.states[:, :, 1] - generic.states[:, :, 1])) <= \
            1e-10 * (np.max(np.abs(fast.states[:, :, 1])) + 1.0)


@pytest.mark.parametrize("fast", [True, False])
def test_springs_in_series_move_their_massless_node(fast):
    """Regression: the fast kernel kept a massless node between two connectors at its start position
    (one predicted force per point; error 2e-3 of a 1e-2 amplitude).  Closed form: k_eq = k1 k2 / (k1 + k2)."""
    chain = ctmm.Chain("series", [Fixed("w"), Spring("k1", 100.0), Spring("k2", 60.0), Mass("m", 2.0), Free("e")])
    result = ctmm.simulate(chain, 0.2, 1e-4, x0={"m": 0.01}, fast=fast)
    exact = 0.01 * np.cos(np.sqrt(37.5 / 2.0) * result.time)
    # the node starts at 0, not at its equilibrium 0.00375: the first acceleration is off, an O(h) error
    assert np.max(np.abs(result["m.x"] - exact)) <= 2e-6
    node = result.states[-1, 1, 0]                                 # the point between the springs
    assert node == pytest.approx(60.0 / 160.0 * result["m.x"][-1], rel=1e-9)


def test_every_form_is_derived_from_the_terms():
    """U(s), u(s), the DT-TMM matrices and the lumped coefficients follow the stated law."""
    from ctmm.elements.base import Linearisation

    inerter = Inerter("b", 0.4, stiffness=30.0, damping=0.2, free_length=0.1)
    s = np.array([0.3j, 2.0 + 1j])
    assert np.allclose(inerter.connector_stiffness(s), 0.4 * s * s + 0.2 * s + 30.0, rtol=1e-15, atol=0)
    assert inerter.lumped_coefficients() == type(inerter.lumped_coefficients())(True, 0.4, 0.2, 30.0, 0.1)
    lin_in, lin_out = Linearisation(0.5, 0.1, 20.0, 0.3, 400.0, -0.2), Linearisation(0.5, -0.4, 20.0, 0.7, 400.0, 0.9)
    U, u = inerter.discretize(None).step_matrices(0.0, lin_in, lin_out, 1.5)
    k_eff = 30.0 * 0.5 + 0.2 * 20.0 + 0.4 * 400.0
    assert U[0, 1] == pytest.approx(-1 / k_eff, rel=1e-15)
    assert u[0] == pytest.approx((30.0 * 0.1 - 30.0 * (-0.5) - 0.2 * 0.4 - 0.4 * 1.1 + 1.5) / k_eff, rel=1e-14)
    point = GroundedSpring("g", 40.0, damping=0.7)
    assert np.allclose(point.transfer_matrix(s)[:, 1, 0], -(0.7 * s + 40.0), rtol=1e-15, atol=0)
    assert np.allclose(Mass("m", 2.0).load_vector(s, {"force": 3.0})[:, 1], 3.0)


def test_a_law_that_is_not_affine_is_refused():
    class Cubic(Spring):
        def terms(self, ops, q_rel, v_rel, t=0.0, u=None):
            joint = super().terms(ops, q_rel, v_rel, t, u)
            return type(joint)(S=joint.S, tau=joint.tau - q_rel * q_rel * q_rel, tau_q=joint.tau_q, tau_v=joint.tau_v)

    with pytest.raises(ModelError, match="not affine"):
        Cubic("cubic", 10.0).transfer_matrix(np.array([1j]))


def test_the_affine_form_is_read_off_the_terms_in_every_direction():
    """Each direction of the probe (x, v, the input) is checked on its own: terms that are affine in all but
    one are refused, a mass that moves with the motion and terms that do not take a batch are refused by name;
    affine terms give their stated numbers exactly."""
    from ctmm.elements.lumped import PointElement

    class Stiffening(GroundedSpring):                           # h not affine in x
        def terms(self, ops, motion, eta=None, eta_dot=None, t=0.0, u=None):
            body = super().terms(ops, motion, eta, eta_dot, t, u)
            return type(body)(M=body.M, h=body.h + motion.pose[0] ** 2, Kin=body.Kin, c=body.c, RF=body.RF)

    class Quadratic(Damper):                                   # tau not affine in v (stated tangent kept)
        def terms(self, ops, q_rel, v_rel, t=0.0, u=None):
            joint = super().terms(ops, q_rel, v_rel, t, u)
            return type(joint)(S=joint.S, tau=joint.tau - v_rel * v_rel, tau_q=joint.tau_q, tau_v=joint.tau_v)

    class SquaredInput(Spring):                                # tau not affine in the input force
        def terms(self, ops, q_rel, v_rel, t=0.0, u=None):
            joint = super().terms(ops, q_rel, v_rel, t, u)
            force = (u or {}).get("force", 0.0)
            return type(joint)(S=joint.S, tau=joint.tau + force * force, tau_q=joint.tau_q, tau_v=joint.tau_v)

    class Moving(Mass):                                        # M depends on the velocity
        def terms(self, ops, motion, eta=None, eta_dot=None, t=0.0, u=None):
            body = super().terms(ops, motion, eta, eta_dot, t, u)
            return type(body)(M=body.M + 0 * motion.twist[0].real + (motion.twist[0] != 0), h=body.h, Kin=body.Kin,
                              c=body.c, RF=body.RF)

    class Unbatched(Mass):                                     # h of a fixed batch of 3
        def terms(self, ops, motion, eta=None, eta_dot=None, t=0.0, u=None):
            body = super().terms(ops, motion, eta, eta_dot, t, u)
            return type(body)(M=body.M, h=np.zeros((3, 1, 1)) + body.h[:1], Kin=body.Kin, c=body.c, RF=body.RF)

    for make, message in [(lambda: Stiffening("g", 5.0), "not affine"), (lambda: Quadratic("d", 2.0), "not affine"),
                          (lambda: SquaredInput("s", 3.0), "not affine"),
                          (lambda: Moving("m", 1.0), "mass term depends on the motion"),
                          (lambda: Unbatched("m", 1.0), "must broadcast against the batch axis")]:
        with pytest.raises(ModelError, match=message):
            make()
    co = PointElement("p", mass=0.3, damping=0.7, stiffness=11.0, force=2.0).axial_coefficients()
    assert (co.inertia, co.damping, co.stiffness, co.rest, dict(co.inputs)) == (0.3, 0.7, 11.0, 0.0, {"force": -1.0})
    co = Inerter("i", 0.4, stiffness=30.0, damping=0.2, free_length=0.1).axial_coefficients()
    assert (co.inertia, co.damping, co.stiffness, dict(co.inputs)) == (0.4, 0.2, 30.0, {"force": 1.0})
    assert co.rest == pytest.approx(30.0 * 0.1, rel=1e-15)


def test_elements_with_the_same_terms_and_data_share_one_probe_and_no_other():
    """The probe is shared by elements whose terms and data agree to the bit; a subclass with its own terms, or
    data one ulp apart, is probed on its own; every element owns its coefficients (and stays picklable)."""
    import pickle

    class Stiffer(Spring):                                     # its own law on the same data
        def terms(self, ops, q_rel, v_rel, t=0.0, u=None):
            joint = super().terms(ops, q_rel, v_rel, t, u)
            return type(joint)(S=joint.S, tau=2.0 * joint.tau, tau_q=2.0 * joint.tau_q, tau_v=joint.tau_v)

    springs = [Spring("a", 7.0, free_length=0.25), Stiffer("b", 7.0, free_length=0.25),
               Spring("c", 7.0, free_length=0.25), Spring("d", np.nextafter(7.0, 8.0), free_length=0.25)]
    stiffness = [spring.axial_coefficients().stiffness for spring in springs]
    assert stiffness == [7.0, 14.0, 7.0, np.nextafter(7.0, 8.0)]
    assert [spring.axial_coefficients().rest for spring in springs[:3]] == [1.75, 3.5, 1.75]
    masses = [Mass("m", 2.0), Mass("n", 2.0), GroundedSpring("g", 2.0)]
    assert [(co.inertia, co.stiffness) for co in (m.axial_coefficients() for m in masses)] == \
        [(2.0, 0.0), (2.0, 0.0), (0.0, 2.0)]
    masses[0].axial_coefficients().inputs["force"] = 99.0      # one element's mapping is its own
    assert masses[1].axial_coefficients().inputs == {"force": -1.0}
    copy = pickle.loads(pickle.dumps(springs[2]))
    assert copy.axial_coefficients() == springs[2].axial_coefficients()


def test_a_chain_build_probes_each_kind_once_and_keeps_no_memo_after_it(monkeypatch):
    """Elements of the library's own laws are probed by the chain that holds them, once per key and build (a
    uniform chain of 40 masses and 40 spring-dampers: one probe each); the next build probes again (no memo
    outlives a build); an element outside a chain is probed on every call and never written to; coefficients are
    each element's own."""
    import ctmm.elements.axial as axial

    calls = []
    for name in ("body_coefficients", "joint_coefficients"):
        original = getattr(axial, name)
        monkeypatch.setattr(axial, name, lambda element, original=original, name=name: calls.append(name) or
                            original(element))

    def uniform(tag):
        return [e for i in range(40) for e in (SpringDamper(f"{tag}k{i}", 100.0, 0.5), Mass(f"{tag}m{i}", 2.0))]

    for tag in "ab":
        body = uniform(tag)
        assert calls == []                                       # built, not probed
        chain = ctmm.Chain(tag, [Fixed("g")] + body + [Free("e")])
        assert sorted(calls) == ["body_coefficients", "joint_coefficients"], calls
        calls.clear()
    assert [(e.axial_coefficients().inertia, e.axial_coefficients().damping, e.axial_coefficients().stiffness)
            for e in chain.body[:2]] == [(0.0, 0.5, 100.0), (2.0, 0.0, 0.0)]
    chain.body[1].axial_coefficients().inputs["force"] = 99.0  # one element's mapping is its own
    assert chain.body[3].axial_coefficients().inputs == {"force": -1.0}
    lone = Mass("lone", 2.0)
    built = dict(vars(lone))
    assert lone.lumped_coefficients() == chain.body[3].lumped_coefficients() and calls == ["body_coefficients"]
    assert lone.lumped_coefficients() == chain.body[3].lumped_coefficients() and len(calls) == 2
    assert vars(lone) == built
