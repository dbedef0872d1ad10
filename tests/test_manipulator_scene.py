"""The manipulator as a scene: a general planar model with the PD and PZT laws as Feedback loops.

Independent reference: the Lagrange model of the hub + modal arm (ctmm.reference.manipulator_lagrange)
with the seed's PD torque and slope-rate voltages, at random states.
"""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.control import ControlledModel
from ctmm.errors import ModelError
from ctmm.manipulator import SEED_KD, SEED_KP, SEED_MOVE, HubPD, PZTFeedback, seed_manipulator
from ctmm.manipulator.scene import HUB_LOOP, manipulator_scene, scene_references
from ctmm.planar import solve_instant
from ctmm.planar.ports import PlanarPorts
from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

G = np.diag([300.0, 150.0, 80.0])


def closed_loop_solution(scene: ControlledModel, references, q, v, t):
    """Forward dynamics (accelerations, joint forces) with every loop closed without delay
    (``u = -(y - r)``) through the ports, and the loop outputs ``u``."""
    ports = PlanarPorts(scene.plant)
    sensors = scene.sensors()
    values = dict(zip(sensors, ports.values(ports.resolve(sensors), q, v, t)))
    y = scene.sensed(values)
    u = {name: -(y[name] - (references[name](t) if name in references else 0.0)) for name in y}
    return solve_instant(scene.plant, q, v, t, inputs=ports.inputs(scene.actuation(u))), u


def test_scene_loops_equal_the_lagrange_manipulator():
    seed = seed_manipulator()
    pd, pzt = HubPD(SEED_KP, SEED_KD), PZTFeedback(G)
    scene = manipulator_scene(seed, pd=pd, pzt=pzt)
    assert [loop.name for loop in scene.loops] == [HUB_LOOP] + [p.name for p in seed.patches]
    reference = ManipulatorLagrange.from_manipulator(seed, 3, stiffening=True)
    beam = scene.plant.bodies[scene.plant.body_index("arm")]
    scale = beam.data.tip_phi / reference.phi_tip          # int phi^2 = L  ->  mass-normalised modes
    rng = np.random.default_rng(5)
    for _ in range(4):
        q = np.r_[rng.normal(), 0.02 * rng.normal(size=3)]
        v = np.r_[3 * rng.normal(), 0.3 * rng.normal(size=3)]
        t = float(rng.uniform(0.0, 1.2))
        solution, u = closed_loop_solution(scene, scene_references(pd, SEED_MOVE), q, v, t)
        tmm = solution.qddot
        eta, eta_dot = scale * q[1:], scale * v[1:]
        torque = SEED_KP * (SEED_MOVE.angle(t) - q[0]) + SEED_KD * (SEED_MOVE.rate(t) - v[0])
        voltages = -G @ (reference.Psi @ eta_dot)
        expected = reference.accelerations(v[0], eta, eta_dot, torque, voltages)
        assert np.abs(np.r_[tmm[0], scale * tmm[1:]] - expected).max() <= 1e-12 * np.abs(expected).max()
        np.testing.assert_allclose([u[p.name] for p in seed.patches], voltages, rtol=1e-11, atol=1e-9)
        assert u[HUB_LOOP] == pytest.approx(torque, rel=1e-13)


def test_scene_refuses_what_a_loop_cannot_hold():
    seed = seed_manipulator()
    saturating = manipulator_scene(seed, pd=None, pzt=PZTFeedback(G, on_limit="saturate"))
    assert {lp.saturation for lp in saturating.loops} == {(-seed.voltage_limit, seed.voltage_limit)}
    assert {lp.saturation for lp in manipulator_scene(seed, pd=None, pzt=PZTFeedback(G)).loops} == {None}
    with pytest.raises(ModelError, match="patches"):
        manipulator_scene(seed, pd=None, pzt=PZTFeedback(np.eye(2)))
    with pytest.raises(ModelError, match="HubPD"):
        manipulator_scene(seed, pd=(1.0, 2.0), pzt=None)
    with pytest.raises(ModelError, match="n_modes"):
        manipulator_scene(seed, pd=None, pzt=None, n_modes=0)
    assert manipulator_scene(seed, pd=None, pzt=None).loops == ()
