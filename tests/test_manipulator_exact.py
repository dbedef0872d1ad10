"""The manipulator scene on station ports (one model for both domains).

The scene's PZT loops sense slope rates at the patch-end stations and act with moment pairs
(ctmm.planar.ports station ports); the Lagrange checks of the closed loops are in
tests/test_manipulator_scene.py.  Here: the loops' structure, and that they are the modal
slope-rate law of the seed (modal-coordinate ports built from the beam's own shape slopes).
"""
from __future__ import annotations

import numpy as np

import ctmm
from ctmm.control import ControlledModel, Feedback
from ctmm.manipulator import SEED_KD, SEED_KP, HubPD, PZTFeedback, seed_manipulator
from ctmm.manipulator.scene import HUB_LOOP, manipulator_scene

G = np.array([[300.0, 20.0, 0.0], [0.0, 150.0, 0.0], [5.0, 0.0, 80.0]])


def test_scene_pzt_loops_act_on_station_ports_as_the_modal_slope_rate_law():
    seed = seed_manipulator()
    pd, pzt = HubPD(SEED_KP, SEED_KD, delay=0.004), PZTFeedback(G, delay=0.003)
    scene = manipulator_scene(seed, pd=pd, pzt=pzt)
    first = seed.patches[0].name
    loop = scene.loops[1]
    assert loop.name == first
    assert {name for name, _ in loop.actuator} == {f"arm.{first}_x1.moment", f"arm.{first}_x2.moment"}
    assert all(name.endswith(".slope_rate") for name, _ in loop.sensor)
    # the same law on modal-coordinate ports: sensing (G Psi) eta_dot, forces c_a Psi
    beam = scene.plant.bodies[scene.plant.body_index("arm")]
    psi = np.array([beam.shapes([p.end], 1)[:, 0] - beam.shapes([p.start], 1)[:, 0] for p in seed.patches])
    sensing, ca = G @ psi, seed.moments_per_volt
    modal = [scene.loops[0]] + [
        Feedback(p.name, sensor=[(f"arm.q{k + 1}_dot", float(sensing[j, k])) for k in range(3)],
                 actuator=[(f"arm.q{k + 1}.force", float(ca[j] * psi[j, k])) for k in range(3)],
                 gain=1.0, delay=pzt.delay) for j, p in enumerate(seed.patches)]
    omega = np.array([3.0, 15.7, 40.0, 97.0, 150.0])
    outputs = ["motor.angle", "arm.out.y"] + [f"{p.name}.u" for p in seed.patches]
    station = ctmm.frequency_response(scene, omega, input=f"{HUB_LOOP}.reference", output=outputs)
    reference = ctmm.frequency_response(ControlledModel(scene.plant, modal), omega, input=f"{HUB_LOOP}.reference",
                                        output=outputs)
    np.testing.assert_allclose(station.response, reference.response, rtol=1e-9, atol=1e-12)
