"""Natural-frequency counts at trial frequencies that hit substructure resonances exactly.

Each pivot of a Wittrick-Williams / Sylvester count is the dynamic stiffness of a substructure
and vanishes exactly at that substructure's natural frequencies.  The parameters below are
chosen (exact binary fractions) so that the pivot is *exactly* zero at the trial frequency; the
counts and the natural frequencies are checked against references that use no transfer
matrices: the linearised Lagrange model (:mod:`ctmm.reference.planar_lagrange`, dense
``eig(K, M)``), the global spring-mass matrices (:mod:`ctmm.reference.chain`) and the classical
beam frequency equations (:mod:`ctmm.reference.beams`).
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, HealthCheck, given, settings, strategies as st

import ctmm
from ctmm.elements import BeamClamped, BeamField, BeamFree
from ctmm.elements.boundary import Fixed as ChainFixed, Free as ChainFree
from ctmm.elements.lumped import Mass, Spring
from ctmm.planar import ElasticHinge, Fixed, PlanarModel, RigidBody
from ctmm.reference.beams import beta_roots, omega_from_beta
from ctmm.reference.chain import GlobalChain, natural_frequencies as global_frequencies
from ctmm.reference.chain_precise import natural_frequencies_precise
from ctmm.reference.planar_lagrange import PlanarLagrange


def _link(name: str, mass: float, length: float) -> RigidBody:
    """Uniform-ish link with binary-exact parameters: J_O = m L^2 / 2 exactly."""
    return RigidBody(name, mass=mass, inertia=mass * length ** 2 / 4, center_of_mass=(length / 2, 0.0),
                     outboard=(length, 0.0))


def _arm(stiffness: list[float], masses: list[float], lengths: list[float]) -> PlanarModel:
    elements: list[object] = [Fixed("ground")]
    for i, (k, m, length) in enumerate(zip(stiffness, masses, lengths)):
        elements += [ElasticHinge(f"k{i}", stiffness=k), _link(f"l{i}", m, length)]
    return PlanarModel.chain("arm", elements, gravity=(0.0, 0.0))


def test_two_link_arm_first_frequency_at_substructure_resonance():
    """The outer link on its hinge resonates at exactly 10 rad/s (k = 50 N m/rad, J_O = 0.5
    kg m^2), a midpoint of the bisection: the first frequency used to come back as 10.0."""
    model = _arm([500.0, 50.0], [1.0, 1.0], [1.0, 1.0])
    q_eq = np.zeros(2)
    expected = PlanarLagrange(model).natural_frequencies(q_eq)
    assert expected[0] == pytest.approx(8.26665113, rel=1e-8)
    np.testing.assert_allclose(ctmm.natural_frequencies(model, n_modes=2, operating_point=(q_eq, np.zeros_like(q_eq))), expected, rtol=1e-12)
    np.testing.assert_array_equal(ctmm.eigenvalue_count(model, operating_point=(q_eq, np.zeros_like(q_eq)), omega=[10.0, 9.0, 8.0, 30.0]),
                                  [np.sum(expected < w) for w in (10.0, 9.0, 8.0, 30.0)])


def test_tree_mode_exactly_at_the_branch_resonance_is_placed_by_the_determinant_sign():
    """Two equal branches (centre of mass on the hinge, J_C = 0.5 kg m^2, k = 50 N m/rad) on a
    trunk: the antisymmetric mode leaves the trunk at rest, so the whole tree has a natural
    frequency exactly at the branches' own resonance sqrt(k / J_C) = 10 rad/s, where both branch
    pivots vanish.  The count is settled by the sign of det(K - w^2 M) (product of pivots)."""
    from ctmm.planar.elements import ElasticHinge as Spring_

    trunk = RigidBody("trunk", mass=2.0, inertia=0.2, center_of_mass=(0.5, 0.0),
                      outboard={"left": (1.0, 0.0), "right": (1.0, 0.0)})
    branches = [RigidBody(n, mass=1.0, inertia=0.5, center_of_mass=(0.0, 0.0), outboard=(1.0, 0.0)) for n in "lr"]
    model = PlanarModel("tree", [trunk, *branches, Fixed("g"), Spring_("k0", parent="g", child="trunk", stiffness=300.0),
                                 Spring_("k1", parent="trunk.left", child="l", stiffness=50.0),
                                 Spring_("k2", parent="trunk.right", child="r", stiffness=50.0)], gravity=(0.0, 0.0))
    q_eq = np.zeros(3)
    expected = PlanarLagrange(model).natural_frequencies(q_eq)
    assert expected[1] == pytest.approx(10.0, rel=1e-14)
    # strictly below: the mode at exactly 10 is not counted at 10, it is just above
    np.testing.assert_array_equal(ctmm.eigenvalue_count(model, operating_point=(q_eq, np.zeros_like(q_eq)), omega=[10.0 * (1 - 1e-9), 10.0, 10.0 * (1 + 1e-9)]),
                                  [1, 1, 2])
    found = ctmm.natural_frequencies(model, n_modes=3, operating_point=(q_eq, np.zeros_like(q_eq)))
    np.testing.assert_allclose(found, expected, rtol=2e-12)     # 1e-12: the side test's offset


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n_links=st.integers(2, 4), data=st.data())
def test_random_planar_arms_count_exactly_at_substructure_resonances(n_links, data):
    masses = [data.draw(st.sampled_from([0.5, 1.0, 2.0, 4.0])) for _ in range(n_links)]
    lengths = [data.draw(st.sampled_from([0.5, 1.0, 2.0])) for _ in range(n_links)]
    omega = data.draw(st.sampled_from([2.0, 4.0, 5.0, 8.0, 10.0, 12.0, 16.0]))
    stiffness = [data.draw(st.sampled_from([10.0, 50.0, 200.0, 1000.0])) for _ in range(n_links - 1)]
    # outer link pinned on its spring: J_O omega^2 = k exactly (J_O = m L^2 / 2)
    stiffness.append(masses[-1] * lengths[-1] ** 2 / 2 * omega ** 2)
    model = _arm(stiffness, masses, lengths)
    q_eq = np.zeros(n_links)
    expected = PlanarLagrange(model).natural_frequencies(q_eq)
    probes = np.array([omega, omega / 2, 2 * omega])
    if np.min(np.abs(expected[:, None] / probes[None, :] - 1.0)) < 1e-9:
        return                                         # a root of the whole arm sits on a probe
    np.testing.assert_array_equal(ctmm.eigenvalue_count(model, operating_point=(q_eq, np.zeros_like(q_eq)), omega=probes),
                                  [np.sum(expected < w) for w in probes])
    np.testing.assert_allclose(ctmm.natural_frequencies(model, n_modes=n_links, operating_point=(q_eq, np.zeros_like(q_eq))), expected, rtol=1e-10)


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_random_spring_mass_chains_count_exactly_at_substructure_resonances(data):
    n = data.draw(st.integers(3, 7))
    masses = [float(data.draw(st.integers(1, 8))) for _ in range(n)]
    springs = [float(data.draw(st.integers(1, 60))) for _ in range(n)]
    omega = float(data.draw(st.sampled_from([2, 4, 5, 6, 8, 10])))
    at = data.draw(st.integers(1, n - 1))          # connector whose pivot vanishes at omega
    # pivot of connector `at` (0-based): k_at - S with S = -(inboard part clamped at its far end)
    S = -springs[0]
    for j in range(1, at):
        S = S + masses[j - 1] * omega ** 2
        if springs[j] == S:
            return                                   # an earlier pivot already vanishes
        S = springs[j] ** 2 / (springs[j] - S) - springs[j]
    target = S + masses[at - 1] * omega ** 2        # k_at - target = 0 in floating point too
    if not target > 0:
        return
    springs[at] = float(target)
    end = data.draw(st.sampled_from(["free", "fixed"]))
    elements: list[object] = [ChainFixed("wall")]
    for j in range(n):
        elements += [Spring(f"k{j}", springs[j]), Mass(f"m{j}", masses[j])]
    stiffness = springs + [0.0]
    if end == "fixed":
        elements.append(Spring("k_end", 7.0))
        stiffness[-1] = 7.0
    elements.append(ChainFixed("end") if end == "fixed" else ChainFree("end"))
    chain = ctmm.Chain("c", elements)
    # 40-digit reference: double-precision eigh carries eps * lambda_max / lambda on the low modes
    expected = natural_frequencies_precise(GlobalChain(masses, stiffness, start="fixed", end=end))
    if np.min(np.abs(expected / omega - 1.0)) < 1e-9:
        return
    assert ctmm.eigenvalue_count(chain, [omega])[0] == np.sum(expected < omega)
    np.testing.assert_allclose(ctmm.natural_frequencies(chain, n_modes=n), expected, rtol=1e-12)


def test_lumped_chain_from_the_issue_counts_at_its_substructure_resonance():
    """Fixed wall, four 50 N/m springs and 1 kg masses: the first mass between clamped springs
    resonates at exactly 10 rad/s, where the count used to be 1 instead of 2."""
    elements: list[object] = [ChainFixed("wall")]
    for j in range(4):
        elements += [Spring(f"k{j}", 50.0), Mass(f"m{j}", 1.0)]
    chain = ctmm.Chain("c", elements + [ChainFree("tip")])
    expected = global_frequencies(GlobalChain([1.0] * 4, [50.0] * 4 + [0.0], start="fixed", end="free"))
    np.testing.assert_array_equal(ctmm.eigenvalue_count(chain, [9.99, 10.0, 10.01]),
                                  [np.sum(expected < w) for w in (9.99, 10.0, 10.01)])


EI, RHOA, L = 2.3, 0.7, 1.3


@pytest.mark.parametrize("case, length", [("clamped-clamped", L), ("clamped-clamped", L / 2),
                                          ("clamped-pinned", L / 2), ("clamped-sliding", L / 2),
                                          ("clamped-free", L / 2)])
def test_cantilever_in_two_halves_counts_at_substructure_resonances(case, length):
    """A cantilever of two equal exact beam fields, counted at the natural frequencies of its
    substructures (first half clamped at the joint, whole beam clamped at the tip, ...)."""
    chain = ctmm.Chain("cantilever", [BeamClamped("root"), BeamField("a", L / 2, EI, RHOA),
                                      BeamField("b", L / 2, EI, RHOA), BeamFree("tip")])
    probes = omega_from_beta(beta_roots(case, 6), length, EI, RHOA)
    exact = omega_from_beta(beta_roots("clamped-free", 40), L, EI, RHOA)
    # high clamped-pinned roots of L/2 coincide with clamped-free roots of L to ~e^-beta: not a probe
    probes = probes[np.min(np.abs(exact[:, None] / probes[None, :] - 1.0), axis=0) > 1e-9]
    assert probes.size >= 2
    np.testing.assert_array_equal(ctmm.eigenvalue_count(chain, probes),
                                  [np.sum(exact < w) for w in probes])


@settings(max_examples=15, deadline=None)
@given(fraction=st.floats(0.15, 0.85), case=st.sampled_from(["clamped-clamped", "clamped-pinned", "clamped-sliding",
                                                               "clamped-free", "pinned-pinned"]),
       piece=st.sampled_from(["first", "second", "whole"]))
def test_split_cantilevers_count_exactly_at_their_pieces_resonances(fraction, case, piece):
    """A uniform cantilever cut anywhere into two exact fields, probed at natural frequencies of
    its pieces (the inboard part clamped at the cut, each field's own clamped-clamped roots where
    ``J0`` jumps, ...), against the clamped-free frequency equation of the whole beam."""
    first, second = fraction * L, (1 - fraction) * L
    chain = ctmm.Chain("split", [BeamClamped("root"), BeamField("a", first, EI, RHOA),
                                 BeamField("b", second, EI, RHOA), BeamFree("tip")])
    length = {"first": first, "second": second, "whole": L}[piece]
    probes = omega_from_beta(beta_roots(case, 4), length, EI, RHOA)
    exact = omega_from_beta(beta_roots("clamped-free", 60), L, EI, RHOA)
    probes = probes[np.min(np.abs(exact[:, None] / probes[None, :] - 1.0), axis=0) > 1e-9]
    assume(probes.size > 0)           # the whole beam's own clamped-free roots are the answer, not probes
    np.testing.assert_array_equal(ctmm.eigenvalue_count(chain, probes), [np.sum(exact < w) for w in probes])


def test_counts_beside_roots_that_coincide_with_a_substructure_resonance():
    """The 13th, 15th, 17th clamped-free roots of L coincide to round-off with clamped-pinned roots
    of the half beam, where the inner pivot of the two-field cantilever vanishes: probes 1e-12 ...
    1e-8 on either side of them must count the root only from above."""
    chain = ctmm.Chain("cantilever", [BeamClamped("root"), BeamField("a", L / 2, EI, RHOA),
                                      BeamField("b", L / 2, EI, RHOA), BeamFree("tip")])
    exact = omega_from_beta(beta_roots("clamped-free", 30), L, EI, RHOA)
    half = omega_from_beta(beta_roots("clamped-pinned", 10), L / 2, EI, RHOA)
    roots = exact[[12, 14, 16]]
    assert np.all(np.min(np.abs(half[:, None] / roots[None, :] - 1.0), axis=0) < 1e-13)
    offsets = np.array([-1e-8, -1e-10, -1e-12, 1e-12, 1e-10, 1e-8])
    probes = (roots[:, None] * (1.0 + offsets[None, :])).ravel()
    np.testing.assert_array_equal(ctmm.eigenvalue_count(chain, probes), [np.sum(exact < w) for w in probes])
