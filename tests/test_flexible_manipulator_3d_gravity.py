"""The 3-D flexible manipulator's arm with gravity on (``scenarios/flexible_manipulator_3d.py``; its full run adds
the ``gravity_on`` panel, PD + PZT over the whole manoeuvre against the reference): the spatial beam's weight
against the independent assumed-modes Lagrange model (``ctmm/reference/spatial_beam_lagrange.py``, its own shapes
and gravity terms) at a bent, moving state.  One mode per bending plane keeps the reference's set-up fast; the
scenario's arm has three."""
from __future__ import annotations

import numpy as np

import ctmm.spatial as sp
from ctmm.reference.spatial_beam_lagrange import HubBeam, SpatialBeamLagrange
from ctmm.scenarios.flexible_manipulator_3d import ARM, BASE, GRAVITY, HUB, PAYLOAD, SHOULDER

SMALL_ARM = {**ARM, "n_modes_y": 1, "n_modes_z": 1}


def _plant(gravity) -> sp.SpatialModel:
    return sp.SpatialModel("arm_with_gravity", [
        sp.SpatialBody("base", BASE["mass"], BASE["inertia"], center_of_mass=BASE["center"],
                       points={"shoulder": SHOULDER}),
        sp.Revolute(name="yaw", parent=None, child="base", axis=(0, 0, 1), actuated=True),
        sp.SpatialBody("hub", HUB["mass"], HUB["inertia"], center_of_mass=HUB["center"], points={"out": HUB["mount"]}),
        sp.Revolute(name="shoulder", parent="base", point="shoulder", child="hub", axis=(0, 1, 0), actuated=True),
        sp.SpatialBeam("arm", **SMALL_ARM),
        sp.Weld(name="mount", parent="hub", child="arm", point="out"),
        sp.SpatialBody("payload", PAYLOAD["mass"], PAYLOAD["inertia"]),
        sp.Weld(name="grip", parent="arm", child="payload", point="tip"),
    ], gravity=gravity)


def test_accelerations_with_gravity_match_the_lagrange_model():
    reference = SpatialBeamLagrange(HubBeam(
        **SMALL_ARM, hub_mass=HUB["mass"], hub_inertia=HUB["inertia"], hub_center=HUB["center"],
        axes=((0, 0, 1), (0, 1, 0)), mount=HUB["mount"], shoulder=SHOULDER, base_mass=BASE["mass"],
        base_inertia=BASE["inertia"], base_center=BASE["center"], tip_mass=PAYLOAD["mass"],
        tip_inertia=PAYLOAD["inertia"], gravity=GRAVITY))
    model = _plant(GRAVITY)
    q = np.array([0.4, -0.3, 2e-3, -1e-3])                       # yaw, shoulder [rad], w_y, w_z modal [m]
    v = np.array([1.0, -0.7, 3e-2, 2e-2])
    expected = reference.accelerations(q, v)
    got = sp.accelerations(model, q, v)
    assert np.max(np.abs(got - expected)) < 1e-12 * np.max(np.abs(expected))
    without = sp.accelerations(_plant((0.0, 0.0, 0.0)), q, v)
    assert np.max(np.abs(without - expected)) > 1e-2 * np.max(np.abs(expected))        # gravity matters here
