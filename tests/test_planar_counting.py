"""Wittrick-Williams counting on the one sweep's frequency context (:mod:`ctmm.planar_counting`).

Flexible (modal-beam) and rigid planar models: natural frequencies and counts against the
independent :mod:`ctmm.reference.flexible_lagrange` model (its global mass matrix and its exactly
linear elastic forces at rest without gravity, generalised eigenproblem solved in 40 digits with
mpmath; with gravity its differentiated accelerations), a clamped modal beam against the
Euler-Bernoulli roots, and counts at trial frequencies that are natural frequencies of substructures
(a beam clamped at its joint, a beam on its hinge).
"""
from __future__ import annotations

import mpmath
import numpy as np
import pytest

import ctmm
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.planar import ElasticHinge, Fixed, FreeBase, Pinned, PlanarModel, RigidBody, SpringDamperHinge
from ctmm.planar.elements import FixedMounting
from ctmm.planar.equilibrium import hanging_configuration, static_equilibrium
from ctmm.planar_counting import FrequencyCounter, eigenvalue_count, natural_frequencies
from ctmm.planar_linearization import jacobian
from ctmm.reference.beams import beta_roots, omega_from_beta
from ctmm.reference.flexible_lagrange import FlexibleLagrange


def _beam(name: str, **options) -> ModalBeam:
    options = {"length": 1.2, "bending_stiffness": 8.0, "mass_per_length": 0.9, "n_modes": 3} | options
    return ModalBeam(name, **options)


def _hub_beam(gravity=(0.0, 0.0)) -> PlanarModel:
    return PlanarModel.chain("hub_beam", [
        Fixed("g"), ElasticHinge("k", stiffness=40.0),
        RigidBody("hub", mass=2.0, inertia=0.15, center_of_mass=(0.1, 0.02), outboard=(0.25, 0.0)),
        FixedMounting("m", angle=0.2), _beam("b"),
        ElasticHinge("e", stiffness=3.0), RigidBody.uniform_link("tip", mass=0.3, length=0.4)], gravity=gravity)


def _two_beam_tree() -> PlanarModel:
    return PlanarModel("two_beams", [
        Fixed("g"), ElasticHinge("k", parent="g", child="b1", stiffness=25.0),
        _beam("b1", outboard={"mid": 0.5, "tip": 1.2}),
        ElasticHinge("h", parent="b1.mid", child="l", stiffness=2.0),
        RigidBody.uniform_link("l", mass=0.4, length=0.7),
        FixedMounting("w", parent="b1.tip", child="b2", angle=-0.4), _beam("b2", n_modes=2, length=0.8)],
        gravity=(0.0, 0.0))


def _equilibrium(model: PlanarModel) -> np.ndarray:
    return static_equilibrium(model, np.zeros(model.n_coordinates))


def _floating() -> PlanarModel:
    return PlanarModel.chain("floating", [FreeBase("f"), _beam("b1"), ElasticHinge("h", stiffness=2.0),
                                          _beam("b2", n_modes=2)], gravity=(0.0, 0.0))


def _reference_matrices(model: PlanarModel) -> tuple[np.ndarray, np.ndarray]:
    """``M, K`` of the FlexibleLagrange model at rest without gravity or loads: its mass matrix at the
    equilibrium and its generalised forces, which are then exactly linear in q (elastic modal forces
    and hinge springs), so ``K`` columns are exact differences."""
    reference = FlexibleLagrange(model)
    n = model.n_coordinates
    q0, zero = _equilibrium(model), np.zeros(model.n_coordinates)
    M, b0, *_ = reference._system(q0, zero, 0.0)
    K = np.array([-(reference._system(q0 + e, zero, 0.0)[1] - b0) for e in np.eye(n)]).T
    assert np.max(np.abs(K - K.T)) <= 1e-12 * np.max(np.abs(K))
    return M, K


def _reference_frequencies(model: PlanarModel) -> np.ndarray:
    """Natural frequencies of :func:`_reference_matrices`: ``eig(K, M)`` in 40 digits."""
    M, K = _reference_matrices(model)
    with mpmath.workdps(40):
        L = mpmath.cholesky(mpmath.matrix(0.5 * (M + M.T)))
        Li = L ** -1
        A = Li * mpmath.matrix(0.5 * (K + K.T)) * Li.T
        values = mpmath.eigsy(0.5 * (A + A.T), eigvals_only=True)
        omega = np.array(sorted(float(mpmath.sqrt(max(v, 0))) for v in values))
    return np.where(omega < 1e-6 * omega[-1], 0.0, omega)      # rigid-body modes of a floating base


@pytest.mark.parametrize("make", [_hub_beam, _two_beam_tree, _floating], ids=["hub_beam", "two_beam_tree", "floating"])
def test_flexible_frequencies_and_counts_equal_the_flexible_lagrange_model(make):
    model = make()
    q0 = _equilibrium(model)
    expected = _reference_frequencies(model)
    # two independent modal integrations (different quadratures and assembly) of the clamped-free
    # shapes, whose cosh - cos cancellation loses ~e^(beta L) eps: 2e-11 on the highest kept mode
    # (the dense eig of M^-1 K the verb used before loses ~eps omega_max^2 / omega^2 on the low modes)
    got = natural_frequencies(model, q0, n_modes=model.n_coordinates)
    np.testing.assert_allclose(got, expected, rtol=2e-11)
    np.testing.assert_allclose(ctmm.natural_frequencies(model, n_modes=model.n_coordinates), expected, rtol=2e-11)
    elastic = expected[expected > 0]
    trials = np.concatenate([elastic * (1 - 1e-9), elastic * (1 + 1e-9), [0.5 * elastic[0], 2 * elastic[-1], 0.0]])
    want = [int(np.sum(expected < w)) for w in trials]
    np.testing.assert_array_equal(eigenvalue_count(model, q0, trials), want)
    np.testing.assert_array_equal(ctmm.eigenvalue_count(model, trials), want)
    M, K = _reference_matrices(model)
    modes = ctmm.mode_shapes(model, n_modes=model.n_coordinates)
    np.testing.assert_allclose(modes.natural_frequencies, expected, rtol=2e-11)
    for w, shape in zip(modes.natural_frequencies, modes.shapes[:, :, 0]):
        assert np.linalg.norm(K @ shape - w * w * (M @ shape)) <= 1e-8 * np.linalg.norm(K) * np.linalg.norm(shape)
    n_rigid = int(np.sum(expected == 0.0))
    below = ctmm.natural_frequencies(model, omega_max=float(np.sqrt(elastic[1] * elastic[2])))
    np.testing.assert_allclose(below, expected[:n_rigid + 2], rtol=2e-11)


def test_hanging_hub_beam_with_preload_equals_the_differentiated_flexible_lagrange_model():
    """Gravity: geometric stiffness of the static preload in the beams and hinges."""
    model = _hub_beam(gravity=(0.0, -9.81))
    q0 = static_equilibrium(model, hanging_configuration(model))
    n = model.n_coordinates
    Jq, _ = jacobian(lambda q: FlexibleLagrange(model).accelerations(q, np.zeros(n)), q0)
    expected = np.sort(np.sqrt(np.linalg.eigvals(-Jq).real))
    np.testing.assert_allclose(natural_frequencies(model, q0, n_modes=n), expected, rtol=1e-7)


def test_clamped_modal_beam_equals_the_euler_bernoulli_roots_below_the_kept_modes():
    """Clamped-free shapes are the exact eigenfunctions: the kept modes are the Euler-Bernoulli
    frequencies (up to quadrature), and the count never sees a frequency beyond the kept ones."""
    length, EI, rhoA = 1.5, 12.0, 0.8
    model = PlanarModel.chain("cantilever", [Fixed("g"), FixedMounting("m"),
                                             _beam("c", length=length, bending_stiffness=EI,
                                                   mass_per_length=rhoA, n_modes=4)], gravity=(0.0, 0.0))
    exact = omega_from_beta(beta_roots("clamped-free", 5), length, EI, rhoA)
    q0 = np.zeros(model.n_coordinates)
    np.testing.assert_allclose(natural_frequencies(model, q0, n_modes=4), exact[:4], rtol=1e-9)
    assert int(eigenvalue_count(model, q0, [exact[4] * 10])[0]) == 4
    with pytest.raises(ModelError, match="fewer than 5 natural frequencies|has 4 natural frequencies"):
        natural_frequencies(model, q0, n_modes=5)


def test_counts_exactly_at_substructure_resonances():
    """Trial frequencies at which a pivot vanishes: the natural frequencies of the beam clamped at its
    mounting (modal block C of the beam) and of beam + tip on the hinge (hinge pivot of the hub)."""
    model = _hub_beam()
    q0 = _equilibrium(model)
    expected = _reference_frequencies(model)
    clamped = PlanarModel.chain("clamped", [Fixed("g"), FixedMounting("m"), _beam("b"),
                                            ElasticHinge("e", stiffness=3.0),
                                            RigidBody.uniform_link("tip", mass=0.3, length=0.4)], gravity=(0.0, 0.0))
    resonances = natural_frequencies(clamped, _equilibrium(clamped), n_modes=clamped.n_coordinates)
    tip = PlanarModel.chain("tip", [Fixed("g"), ElasticHinge("e", stiffness=3.0),
                                    RigidBody.uniform_link("tip", mass=0.3, length=0.4)], gravity=(0.0, 0.0))
    resonances = np.concatenate([resonances, natural_frequencies(tip, [0.0], n_modes=1)])
    counter = FrequencyCounter(model, q0)
    _, margin = counter.raw(resonances)
    assert np.all(~(margin > 1e-10))          # each of them spoils a pivot: the certified path decides
    np.testing.assert_array_equal(counter.count(resonances), [int(np.sum(expected < w)) for w in resonances])


def test_rigid_tree_counts_equal_the_old_numbers_and_refusals():
    model = PlanarModel.chain("pendulum", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=2.0)])
    q0 = np.array([-np.pi / 2])
    assert natural_frequencies(model, q0, n_modes=1)[0] == pytest.approx(np.sqrt(3 * 9.81 / 4), rel=1e-14)
    damped = PlanarModel.chain("damped", [Fixed("g"), FixedMounting("m"), _beam("b", damping_ratio=0.01)],
                               gravity=(0.0, 0.0))
    with pytest.raises(ModelError, match="needs an undamped system.*'b'.*velocity-dependent"):
        eigenvalue_count(damped, np.zeros(damped.n_coordinates), [1.0])
    with pytest.raises(ModelError, match="not an equilibrium"):
        eigenvalue_count(model, [0.0], [1.0])
    with pytest.raises(ModelError, match="statically unstable"):
        natural_frequencies(model, [np.pi / 2], n_modes=1)
    with pytest.raises(ModelError, match="omega must be >= 0"):
        eigenvalue_count(model, q0, [-1.0])
    hinge = PlanarModel.chain("damped_hinge", [Fixed("g"), SpringDamperHinge("k", stiffness=5.0, damping=0.1),
                                               RigidBody.uniform_link("a", mass=1.0, length=2.0)])
    with pytest.raises(ModelError, match="eigenvalue_count needs an undamped system, but 'k' has damping=0.1"):
        ctmm.eigenvalue_count(hinge, [1.0])
    assert ctmm.eigenvalue_count(model, [2.0, 3.0]).tolist() == [0, 1]
