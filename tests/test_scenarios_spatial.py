"""The spatial scenarios (issue 14 item 4) in their quick form: accuracy bounds against the global
Newton–Euler reference, and motion large enough for the comparison to mean something."""
from __future__ import annotations

import json

import numpy as np
import pytest


def expected_rk4_method() -> str:
    """``result.info["method"]`` of the spatial scenarios' RK4 runs: generated where a C compiler is present."""
    from ctmm.scenarios.spatial_common import generated_rk4

    return "rk4-generated" if generated_rk4() else "rk4"


@pytest.mark.parametrize("name", ["spatial_chain", "branch_system"])
def test_spatial_scenario_quick_meets_its_bounds(name, quick_scenario):
    summary, tmp_path = quick_scenario(name)
    data = json.loads((tmp_path / f"{name}.json").read_text())
    assert data["passed"] and len(data["accuracy"]) == 2
    for figure in data["accuracy"]:
        assert figure["unit"] == "rad/s" and figure["value"] <= figure["bound"] == 1e-6, figure
    assert summary["omega_range_rad_s"] > 1.0                 # the bodies really turn (rad/s)
    assert summary["velocity_max_error_rk4"] < 1e-6
    assert data["wall_time_s"] > 0 and data["reference_wall_time_s"] > 0
    assert np.isclose(data["parameters"]["dt_s"], 1e-3)
    assert summary["rk4_method"] == expected_rk4_method()     # the generated RK4 where a compiler is present


def test_reference_conversion_puts_quaternion_scalar_last():
    from ctmm.scenarios.spatial_chain import initial_state, model
    from ctmm.scenarios.spatial_common import to_reference

    q0, _ = initial_state()
    converted = to_reference(model(), q0)[0]
    np.testing.assert_array_equal(converted[:4], np.r_[q0[1:4], q0[0]])
    np.testing.assert_array_equal(converted[4], q0[4])


def test_elastic_hinge_control_quick_meets_its_bounds(quick_scenario):
    """theta_z of the uncontrolled and PD runs against the reference (1e-6 rad), the delay margin a
    crossing of the reference's characteristic determinant (1e-8), the PD really acting."""
    name = "spatial_elastic_hinge_control"
    summary, tmp_path = quick_scenario(name)
    data = json.loads((tmp_path / f"{name}.json").read_text())
    assert data["passed"] and len(data["accuracy"]) == 3
    for figure in data["accuracy"]:
        assert figure["value"] <= figure["bound"], figure
    assert [f["unit"] for f in data["accuracy"]] == ["rad", "rad", "1"]
    assert [f["bound"] for f in data["accuracy"]] == [1e-6, 1e-6, 1e-8]
    ranges = summary["theta_z_range_rad"]
    assert ranges["uncontrolled"] > 0.3                              # the body really twists (rad)
    assert ranges["PD"] < 0.9 * ranges["uncontrolled"]               # and the loop damps it
    assert 0.0 < summary["delay_s"] < summary["delay_margin_s"] < 1.0
    assert data["wall_time_s"] > 0 and data["reference_wall_time_s"] > 0
    assert summary["rk4_method"] == expected_rk4_method()


def test_robot_arm_quick_meets_its_bounds(quick_scenario):
    """PD joint control of a 3-D arm, real-time and delayed: Python RK4 against the Newton-Euler reference
    (1e-6 rad), generated RK4 equal to it (1e-10), Newmark within 1e-4 rad; the arm really moves."""
    summary, tmp_path = quick_scenario("spatial_robot_arm")
    data = json.loads((tmp_path / "spatial_robot_arm.json").read_text())
    figures = data["accuracy"]
    assert data["passed"] and all(f["value"] <= f["bound"] for f in figures), figures
    assert [f["bound"] for f in figures] == [1e-6, 1e-10, 1e-4] * 2
    assert summary["tcp_travel_m"] > 1e-3                            # the tool point moves (m)
    errors = summary["joint_errors_rad"]
    assert errors["real-time"]["Newmark"] > errors["real-time"]["RK4"]     # order 2 against order 4
    assert data["wall_time_s"] > 0 and data["reference_wall_time_s"] > 0


@pytest.mark.parametrize("name", ["spatial_hub_beam", "spatial_hub_beam_tip_body"])
def test_spatial_hub_beam_quick_meets_its_bounds(name, quick_scenario):
    """Hub rate, longitudinal (axial mode) and transverse tip deformation of the SpatialBeam run against
    the independent assumed-modes Lagrange model with the axial mode (0.1 % of peak), the beam really
    bending in the plane of rotation and stretching, nothing out of that plane."""
    summary, tmp_path = quick_scenario(name)
    data = json.loads((tmp_path / f"{name}.json").read_text())
    assert data["passed"] and [f["unit"] for f in data["accuracy"]] == ["% of peak"] * 3
    for figure in data["accuracy"]:
        assert figure["value"] <= figure["bound"] == 0.1, figure
    assert summary["peak_transverse_tip_m"] > 5e-3               # the beam really bends (m)
    assert summary["peak_longitudinal_tip_m"] > 1e-10            # and really stretches (m)
    assert summary["peak_out_of_plane_tip_m"] == 0.0             # planar motion stays planar
    assert summary["longitudinal_tip_max_error_m"] < 1e-3 * summary["peak_longitudinal_tip_m"]
    assert data["wall_time_s"] > 0 and data["reference_wall_time_s"] > 0


@pytest.mark.parametrize("tip_mass", [None, 0.2])
def test_spatial_hub_beam_reference_mass_integrals_are_converged(tip_mass):
    """The hub-beam scenarios' Lagrange reference integrates the beam on REFERENCE_POINTS Gauss points: its
    accelerations (any hub angle, rates, torques; with and without the tip body) equal those on 64 points to
    round-off (12 points: 7e-11 and 1e-9 relative, 20 points: 1e-13)."""
    import dataclasses

    from ctmm.reference.spatial_beam_lagrange import SpatialBeamLagrange
    from ctmm.scenarios import spatial_hub_beam

    reference = spatial_hub_beam.reference(tip_mass)
    assert reference.p.points == spatial_hub_beam.REFERENCE_POINTS < 64
    fine = SpatialBeamLagrange(dataclasses.replace(reference.p, points=64))
    rng = np.random.default_rng(0)
    scale = np.r_[1.0, [0.05] * (reference.n - 1)]                  # hub angle [rad], modal coordinates [m]
    for _ in range(4):
        q, u, tau = rng.normal(size=reference.n) * scale, rng.normal(size=reference.n) * 3.0 * scale, \
            rng.normal(size=reference.n) * 5.0
        expected = fine.accelerations(q, u, tau)
        np.testing.assert_allclose(reference.accelerations(q, u, tau), expected, rtol=0,
                                   atol=1e-12 * np.abs(expected).max())


def test_spatial_spin_up_quick_is_bounded_with_stiffening_and_diverges_without(quick_scenario):
    """In-plane and out-of-plane tip deflection of the stiffened spin-up under out-of-plane gravity
    against the independent Lagrange model (0.1 % of peak); without stiffening the in-plane
    deflection diverges once the spin passes omega_1 (the contrast, asserted)."""
    name = "spatial_spin_up"
    summary, tmp_path = quick_scenario(name)
    data = json.loads((tmp_path / f"{name}.json").read_text())
    assert data["passed"] and len(data["accuracy"]) == 2
    for figure in data["accuracy"]:
        assert figure["value"] <= figure["bound"] == 0.1, figure
    assert summary["peak_in_plane_tip_m"] > 0.5                       # the spin-up bends the beam (m)
    assert summary["static_sag_tip_m"] < -1.0                          # gravity acts out of plane (m)
    assert summary["peak_out_of_plane_tip_m"] < 1.5 * abs(summary["static_sag_tip_m"])   # bounded
    assert summary["unstiffened_diverged"]
    assert summary["unstiffened_stopped_at_s"] is not None               # the beam's deflection guard stopped it
    assert summary["unstiffened_peak_in_plane_tip_m"] > 1.5 * summary["peak_in_plane_tip_m"]
    assert summary["unstiffened_tip_max_error_m"] < 1e-3 * 10.0        # same divergence in the reference
