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
