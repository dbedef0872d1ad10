"""The 3-D flexible manipulator scenario (issues 14/15) in its quick form: the tip deflections of the PD and
PD + PZT runs against the independent Lagrange model (0.1 % of the peak), the controlled FRFs against the
reference linearisation closed by hand (1e-8), the delay margin an exact root of the reference's
characteristic (1e-8) and the stability chart agreeing with it; the forearm really bends in both planes and the body-axis patches really damp it."""
from __future__ import annotations

import dataclasses
import json

import numpy as np


def test_flexible_manipulator_3d_quick_meets_its_bounds(quick_scenario):
    name = "flexible_manipulator_3d"
    summary, tmp_path = quick_scenario(name)
    data = json.loads((tmp_path / f"{name}.json").read_text())
    figures = data["accuracy"]
    assert data["passed"] and [f["bound"] for f in figures] == [0.1, 1e-8, 1e-8], figures
    assert all(f["value"] <= f["bound"] for f in figures), figures
    peaks = summary["peak_tip_deflection_m"]["PD only"]
    assert peaks[0] > 1e-2 and peaks[1] > 1e-3                       # both bending planes (m)
    assert summary["errors"]["PD + PZT"]["voltage_error_V"] < 1e-3 * summary["peak_voltage_V"]
    assert 10.0 < summary["peak_voltage_V"] < summary["voltage_limit_V"]
    without, with_pzt = (summary["flexible_mode_damping"][k] for k in ("PD only", "PD + PZT"))
    for (_, zeta_off), (_, zeta_on) in zip(without[:2], with_pzt[:2]):   # the first bending pair
        assert zeta_on > 2.0 * zeta_off
    margin = summary["delay_margin"]
    assert margin["stable"] and margin["delay_s"] < margin["critical_delay_s"] < 1.0
    assert summary["stability_chart"]["agrees_with_delay_margin_at_gain_1"]
    assert 0.0 < summary["stability_chart"]["stable_fraction"] < 1.0
    assert all(e < 0.05 * 0.5 for e in summary["joint_final_error_rad"])   # within 5 % of the moves (>= 30 deg)
    assert data["wall_time_s"] > 0 and data["reference_wall_time_s"] > 0
    from ctmm.scenarios.spatial_common import generated_rk4

    assert summary["rk4_method"] == ("rk4-generated" if generated_rk4() else "rk4")   # generated with a compiler


def test_reference_mass_integrals_are_converged():
    """The scenario's Lagrange reference integrates the beam on REFERENCE_POINTS Gauss points: its accelerations
    (any pose, rates, joint torques and patch moments; gravity on) equal those on 64 points to round-off."""
    from ctmm.reference.spatial_beam_lagrange import SpatialBeamLagrange
    from ctmm.scenarios import flexible_manipulator_3d as scene

    reference = scene.lagrange(scene.GRAVITY)
    assert reference.p.points == scene.REFERENCE_POINTS < 64
    fine = SpatialBeamLagrange(dataclasses.replace(reference.p, points=64))
    rng = np.random.default_rng(0)
    scale = np.r_[1.0, 1.0, [0.05] * (reference.n - 2)]             # joint angles [rad], modal coordinates [m]
    for _ in range(4):
        q, u = rng.normal(size=reference.n) * scale, rng.normal(size=reference.n) * 3.0 * scale
        tau, act = rng.normal(size=reference.n) * 50.0, rng.normal(size=4)
        expected = fine.accelerations(q, u, tau, act)
        np.testing.assert_allclose(reference.accelerations(q, u, tau, act), expected, rtol=0,
                                   atol=1e-12 * np.abs(expected).max())       # 12 points: 2e-10, 16: 2e-15
