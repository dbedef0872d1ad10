"""Seed 001 §9.4: the finite-segment cantilever on a rotary base through the TMM against the independent Kane
assumed-modes model (ctmm.reference.rotary_base_kane); the Kane model itself against a closed form."""
from __future__ import annotations

import json

import numpy as np
import pytest

from ctmm.reference.rotary_base_kane import RotaryBaseBeam


def test_kane_reference_steady_centrifugal_stretch_equals_the_rotating_rod_solution():
    """At constant omega with no bending, the stretch solves EA u'' + rhoA omega^2 (r_h + x + u) = 0, u(0) = u'(L) = 0:
    u = r_h cos kx + (1 + r_h k sin kL) sin kx / (k cos kL) - (r_h + x), k^2 = rhoA omega^2 / EA."""
    L, EA, rhoA, r_h, omega = 1.0, 50.0, 0.5, 0.1, 4.0
    beam = RotaryBaseBeam(length=L, bending_stiffness=2.0, axial_stiffness=EA, mass_per_length=rhoA, hub_radius=r_h,
                          hub_inertia=0.0, rate=lambda t: omega, acceleration=lambda t: 0.0, bending_modes=1,
                          axial_modes=6)
    # static: z'' = 0 with z' = 0 is linear in the stretch coordinates
    n = beam.n
    base = beam.accelerations(np.zeros(n), np.zeros(n), 0.0)
    tangent = np.column_stack([beam.accelerations(np.eye(n)[i], np.zeros(n), 0.0) - base for i in range(n)])
    z = np.linalg.solve(tangent, -base)
    k = np.sqrt(rhoA * omega ** 2 / EA)
    exact = r_h * np.cos(k * L) + (1 + r_h * k * np.sin(k * L)) * np.sin(k * L) / (k * np.cos(k * L)) - (r_h + L)
    assert z[:6] @ beam.phi_tip == pytest.approx(exact, rel=2e-3)        # 6 rod modes: tip slope error O(1/n^3)
    assert np.allclose(z[6:], 0.0)


def test_rotary_base_segments_quick_converges_to_kane(quick_scenario):
    summary, tmp_path = quick_scenario("rotary_base_segments")
    json.dumps(summary)
    assert (tmp_path / "rotary_base_segments.png").stat().st_size > 1000
    (figure,) = summary["accuracy"]
    assert figure["passed"]                                           # N = 10: 1.7e-2 relative
    for key, orders in summary["observed_orders"].items():
        assert orders[0] > 1.8, key                                   # 1/N^2 (observed 2.12-2.15)
    assert summary["max_difference"]["10"]["angular_velocity"] < 1e-12   # prescribed
    assert summary["peak_transverse_tip_m"] < -0.02 and summary["peak_longitudinal_tip_m"] < -3e-4
