"""The manipulator scene's tip station: ``"arm.tip.w"`` is the hub-frame tip deflection.

Checked against the independent assumed-modes model (ctmm/reference/manipulator_lagrange.py):
the closed-loop ``theta_d -> tip`` response (``theta_d`` enters through the hub loop's reference
``r = kp theta_d + kd theta_d_dot``) of the exact beam fields against 150 modes with the static
correction (the continuum), and of the 3-mode scene against the same 3 modes without it.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.manipulator import SEED_KD, SEED_KP, SEED_PZT_GAIN, HubPD, PZTFeedback, seed_manipulator
from ctmm.manipulator.scene import HUB_LOOP, TIP_STATION, manipulator_scene
from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

OMEGA = np.array([2.0, 9.0, 15.7, 40.0, 97.0])
PD_DELAY, PZT_DELAY = 0.004, 0.002


def tip_per_desired_angle(pzt: bool, fields: str | None) -> np.ndarray:
    seed = seed_manipulator()
    law = PZTFeedback.per_patch([SEED_PZT_GAIN] * seed.n_patches, delay=PZT_DELAY) if pzt else None
    scene = manipulator_scene(seed, pd=HubPD(SEED_KP, SEED_KD, delay=PD_DELAY), pzt=law)
    reference, tip = f"{HUB_LOOP}.reference", f"arm.{TIP_STATION}.w"
    response = ctmm.frequency_response(scene, OMEGA, input=reference, output=tip, fields=fields)
    return (SEED_KP + 1j * OMEGA * SEED_KD) * response(tip, reference)


def lagrange_tip(pzt: bool, n_modes: int, static_correction: bool) -> np.ndarray:
    seed = seed_manipulator()
    gains = np.eye(seed.n_patches) * SEED_PZT_GAIN if pzt else None
    model = ManipulatorLagrange.from_manipulator(seed, n_modes)
    return model.frequency_response(OMEGA, kp=SEED_KP, kd=SEED_KD, pd_delay=PD_DELAY, pzt_gains=gains,
                                    pzt_delay=PZT_DELAY, static_correction=static_correction)["theta_d"]["tip"]


@pytest.mark.parametrize("pzt", [False, True])
def test_exact_tip_station_is_the_continuum_hub_frame_tip(pzt):
    np.testing.assert_allclose(tip_per_desired_angle(pzt, "exact"), lagrange_tip(pzt, 150, True), rtol=1e-9)


@pytest.mark.parametrize("pzt", [False, True])
def test_modal_tip_station_is_the_three_mode_hub_frame_tip(pzt):
    np.testing.assert_allclose(tip_per_desired_angle(pzt, None), lagrange_tip(pzt, 3, False), rtol=1e-9)


def test_the_tip_station_sits_at_the_free_end_beside_the_patch_stations():
    seed = seed_manipulator()
    scene = manipulator_scene(seed, pd=None, pzt=None)
    beam = scene.plant.bodies[scene.plant.body_index("arm")]
    assert beam.stations[TIP_STATION] == seed.arm.length
    assert {f"{p.name}_x{end}" for p in seed.patches for end in (1, 2)} <= set(beam.stations)
