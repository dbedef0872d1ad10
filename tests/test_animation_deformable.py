"""Animation of finite-element subsystems: the drawn polyline of a spatial ctmm.fem.SpatialSubsystem and of a planar
ctmm.fem subsystem runs through the deformed nodes (node displacements in the floating frame), checked against
the chain kinematics written out here from the scenarios' numbers (rotations by hand, node positions from the
scene data, displacements read from the stored coordinates)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import ctmm
from ctmm.animation import animate, drawing_outputs, mechanism_frames
from ctmm.animation_spatial import with_pose_signals
from ctmm.scene_files import load_scene

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def rotation(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return {"y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]), "z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def test_spatial_subsystem_is_drawn_through_its_deformed_nodes(tmp_path):
    from scenarios import spatial_fem_chain as scenario

    model = scenario.model()
    x0 = {**scenario.INITIAL, "beam1.n3_uy": 0.012, "beam1.n2_uz": -0.01, "beam1.n1_ux": 0.001}
    options = dict(method="rk4", x0=x0, v0=scenario.INITIAL_RATE)
    stored = ctmm.simulate(model, 0.01, scenario.STEP, outputs=drawing_outputs(model), **options)
    added = with_pose_signals(ctmm.simulate(model, 0.01, scenario.STEP, **options))
    for row in (0, 12):
        value = {name: float(stored[name][row]) for name in model.coordinates}
        yaw, pitch = rotation("z", value["yaw.angle"]), rotation("y", value["pitch.angle"])
        frame = yaw @ pitch @ rotation("z", value["connection.angle"])
        origin = yaw @ np.array([0.0, 0.0, 0.3]) + yaw @ pitch @ np.array([0.3, 0.0, 0.0])
        expected = [origin + frame @ (np.array([k / 3, 0.0, 0.0]) + (np.zeros(3) if k == 0 else np.array(
            [value[f"beam1.n{k}_u{axis}"] for axis in "xyz"]))) for k in range(4)]
        for result in (stored, added):
            drawn = mechanism_frames(result, [row])[0]
            np.testing.assert_allclose(drawn.bodies["beam1"], np.array(expected), rtol=0, atol=1e-12)
        undeformed = [origin + frame @ np.array([k / 3, 0.0, 0.0]) for k in range(4)]
        assert np.max(np.abs(np.array(expected) - undeformed)) > 0.005         # the deformation is visible
    assert animate(stored, tmp_path / "fem.gif", frames=3).stat().st_size > 1000


@pytest.mark.parametrize("exaggeration", [1.0, 4.0])
def test_planar_subsystem_is_drawn_through_its_deformed_nodes(exaggeration):
    scene = load_scene(ROOT / "scenarios" / "files" / "fem_chain.toml")
    model = scene.system
    x0 = {**scene.arguments["x0"], "beam1.n2_uy": 0.01, "beam1.n4_ux": -0.002}
    result = ctmm.simulate(model, 0.01, 5e-4, method="rk4", x0=x0)
    row = 15
    theta = {name: float(result[f"{name}.theta"][row]) for name in ("body1", "body2", "body3", "beam1")}

    def turn(angle):
        return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])

    origin = sum(turn(theta[f"body{i}"]) @ np.array([0.5, 0.0]) for i in (1, 2, 3))
    displacement = [np.zeros(2)] + [np.array([float(result[f"beam1.n{k}_u{axis}"][row]) for axis in "xy"])
                                    for k in range(1, 5)]
    expected = np.array([origin + turn(theta["beam1"]) @ (np.array([0.3 * k, 0.0]) + exaggeration * displacement[k])
                         for k in range(5)])
    drawn = mechanism_frames(result, [row], exaggeration=exaggeration)[0]
    np.testing.assert_allclose(drawn.bodies["beam1"], expected, rtol=0, atol=1e-12)
    assert max(np.max(np.abs(u)) for u in displacement) > 1e-3                  # it deformed
    if exaggeration == 1.0:                                                     # the next body hangs at the tip
        np.testing.assert_allclose(drawn.bodies["body4"][0], expected[-1], rtol=0, atol=1e-12)
