"""``coordinate_histories`` / ``energy_history``: arrays of a planar ``ctmm.simulate`` result."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.elements import Fixed, Free, Mass, Spring
from ctmm.errors import ModelError
from ctmm.planar import Pinned, PlanarModel, RigidBody
from ctmm.signal_results import coordinate_histories, energy_history


def _pendulum() -> PlanarModel:
    return PlanarModel.chain("p", [Pinned("o"), RigidBody.uniform_link("link", mass=2.0, length=0.5)],
                             gravity=(0.0, -9.81))


def test_histories_follow_the_coordinate_order_and_the_small_angle_solution():
    model = _pendulum()
    result = ctmm.simulate(model, 0.5, 1e-3, method="rk4", x0={"link.theta": -np.pi / 2 + 1e-3})
    q, qdot = coordinate_histories(result)
    assert q.shape == qdot.shape == (501, 1)
    np.testing.assert_array_equal(q[:, 0], result["link.theta"])
    np.testing.assert_array_equal(qdot[:, 0], result["link.theta_dot"])
    # uniform link on a pivot: omega^2 = m g (l/2) / (m l^2 / 3) = 3 g / (2 l), small swing about hanging
    omega = np.sqrt(3 * 9.81 / (2 * 0.5))
    expected = -np.pi / 2 + 1e-3 * np.cos(omega * result.time)
    assert np.max(np.abs(q[:, 0] - expected)) < 1e-8


def test_energy_history_of_the_undamped_pendulum_is_its_analytic_energy():
    model = _pendulum()
    result = ctmm.simulate(model, 0.2, 1e-3, method="rk4", x0={"link.theta": 0.3})
    energy = energy_history(result)
    theta, rate = result["link.theta"], result["link.theta_dot"]
    inertia = 2.0 * 0.5 ** 2 / 3
    analytic = 0.5 * inertia * rate ** 2 + 2.0 * 9.81 * 0.25 * np.sin(theta)   # centre of mass at l/2
    assert np.max(np.abs((energy - energy[0]) - (analytic - analytic[0]))) < 1e-9


def test_a_chain_result_is_refused_by_name():
    chain = ctmm.Chain("c", [Fixed("w"), Spring("k", stiffness=100.0), Mass("m", mass=1.0), Free("e")])
    result = ctmm.simulate(chain, 0.01, 1e-3, x0={"m": 0.01})
    with pytest.raises(ModelError, match="coordinate_histories needs the SimulationResult"):
        coordinate_histories(result)
    with pytest.raises(ModelError, match="energy_history"):
        energy_history(result)
