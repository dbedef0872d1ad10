"""Acceleration-based planar TMM: instantaneous accelerations and hinge forces vs global models."""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.planar import solve_instant, accelerations
from ctmm.reference.planar_lagrange import PlanarLagrange, newton_euler_kkt

from planar_helpers import random_state, random_tree, uniform_chain


def _rel(a, b):
    a, b = np.asarray(a), np.asarray(b)
    if b.size == 0:
        return 0.0 if a.size == 0 else np.inf
    return float(np.max(np.abs(a - b)) / max(1.0, np.max(np.abs(b))))


@pytest.mark.parametrize("seed", range(40))
def test_random_trees_match_kkt_and_lagrange(seed):
    """All hinge types (incl. translational springs), loads, driven hinges, pinned / free /
    fixed bases, random states."""
    model = random_tree(seed, 1 + seed % 8, chain=(seed % 3 == 0))
    q, qdot, t = random_state(model, seed)
    tmm = solve_instant(model, q, qdot, t)
    kkt = newton_euler_kkt(model, q, qdot, t)
    lagrange = PlanarLagrange(model).accelerations(q, qdot, t)
    assert _rel(tmm.qddot, kkt.qddot) <= 1e-11
    assert _rel(tmm.qddot, lagrange) <= 1e-11
    assert _rel(tmm.joint_force, kkt.joint_force) <= 1e-11


def test_single_rod_analytic():
    """Horizontal uniform rod pinned at one end: theta_ddot = -3 g / (2 L), pin force m g / 4."""
    model = uniform_chain(1, length=2.0, mass=3.0)
    sol = solve_instant(model, [0.0], [0.0])
    assert sol.qddot[0] == pytest.approx(-3 * 9.81 / 4.0, rel=1e-14)
    assert sol.joint_force[0, 1] == pytest.approx(3.0 * 9.81 / 4.0, rel=1e-14)


def test_riccati_sweep_accurate_for_1000_links():
    """N = 1000 chain at a random state: TMM equals the sparse global Newton-Euler solve."""
    model = uniform_chain(1000)
    rng = np.random.default_rng(7)
    q = np.cumsum(rng.normal(0.0, 0.2, 1000))
    qdot = rng.normal(0.0, 1.0, 1000)
    tmm = solve_instant(model, q, qdot)
    kkt = newton_euler_kkt(model, q, qdot)
    assert _rel(tmm.qddot, kkt.qddot) <= 1e-10
    assert _rel(tmm.joint_force, kkt.joint_force) <= 1e-11


def test_fast_lagrange_path_equals_general_path():
    model = uniform_chain(6)
    lag = PlanarLagrange(model)
    rng = np.random.default_rng(3)
    q, qdot = rng.normal(size=6), rng.normal(size=6)
    kin = lag.kinematics(q, qdot, 0.0)
    M, rhs = lag._generalised(q, qdot, 0.0, kin)
    assert _rel(lag.accelerations(q, qdot), np.linalg.solve(M, rhs)) <= 1e-12
    assert _rel(accelerations(model, q, qdot), np.linalg.solve(M, rhs)) <= 1e-12


@pytest.mark.parametrize("seed", range(12))
def test_coordinate_accelerations_put_each_body_angle_at_its_coordinate_name(seed):
    """``coordinate_accelerations`` (the revolute chains' shortcut and the general mapping) on random body
    accelerations: each body's ``alpha`` at the coordinate ``<body>.theta``, a free base's ``a_x, a_y`` at
    ``<body>.x, <body>.y``, a translational-spring hinge's given translations at ``<body>.dx, <body>.dy`` (the expected
    vector built from the coordinate names); a batch of states for models without those hinges.  The seeds give
    chains with and without translational springs, trees and free bases."""
    from ctmm.planar.sweep import coordinate_accelerations

    model = random_tree(seed, 1 + seed % 6, chain=(seed % 2 == 0))
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(4, model.n_bodies, 3))
    translation = {int(j): tuple(rng.normal(size=2)) for j in model.bushing_bodies}
    expected = np.full((4, model.n_coordinates), np.nan)
    for j, body in enumerate(model.body_names):
        for suffix, value in (("theta", A[:, j, 2]), ("x", A[:, j, 0]), ("y", A[:, j, 1]),
                              ("dx", translation.get(j, (np.nan,))[0]), ("dy", translation.get(j, (0, np.nan))[1])):
            if f"{body}.{suffix}" in model.coordinates:
                expected[:, model.coordinate_index(f"{body}.{suffix}")] = value
    assert not np.isnan(expected).any()
    np.testing.assert_array_equal(coordinate_accelerations(model, A[1], translation or None), expected[1])
    if not translation:
        np.testing.assert_array_equal(coordinate_accelerations(model, A), expected)
        assert coordinate_accelerations(model, A[1]).flags.c_contiguous
