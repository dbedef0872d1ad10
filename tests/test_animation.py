"""Animation of planar and spatial runs: the drawn geometry against independent kinematics, GIF files
with the asked number of frames, and clear refusals."""
from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pytest

import ctmm
from ctmm.animation import drawing_outputs, frame_rows, mechanism_frames
from ctmm.animation_spatial import with_pose_signals
from ctmm.errors import ModelError
from ctmm.scene_files import load_scene

FILES = Path(__file__).resolve().parents[1] / "scenarios" / "files"


def _run(name, t_final=0.05, **options):
    scene = load_scene(FILES / f"{name}.toml")
    return scene, ctmm.simulate(scene.system, t_final, 1e-3, method="rk4", x0=scene.arguments["x0"],
                                v0=scene.arguments["v0"], **options)


def test_planar_frames_follow_the_absolute_link_angles():
    """The pendulum's coordinates are absolute link angles: its drawn points are sums of rotated link vectors
    (written out here from the scenario's numbers, not from the model)."""
    _, result = _run("pendulum_chain")
    frame = mechanism_frames(result, [40])[0]
    theta = [result[f"b{i}.theta"][40] for i in (1, 2, 3)]
    links = [np.array([1.0, 0.0]), np.array([0.8, 0.1]), np.array([0.6, 0.0])]      # outboard - inboard [m]
    position = np.zeros(2)
    for i, (angle, link) in enumerate(zip(theta, links)):
        rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        assert np.allclose(frame.bodies[f"b{i + 1}"][0], position, atol=1e-13)
        assert np.allclose(frame.joints[i], position, atol=1e-13)
        position = position + rotation @ link
        assert np.allclose(frame.bodies[f"b{i + 1}"][-1], position, atol=1e-13)
    assert frame.time == pytest.approx(0.04)


def test_spatial_frames_equal_the_newton_euler_reference_kinematics():
    spatial_common = importlib.import_module("ctmm.scenarios.spatial_common")
    from ctmm.reference.spatial_kinematics import kinematics

    scene, result = _run("spatial_chain", outputs=drawing_outputs(load_scene(FILES / "spatial_chain.toml").system))
    model = scene.system
    tree = spatial_common.reference_tree(model)
    row = 30
    q = np.array([result[name][row] for name in model.coordinates])
    v = np.array([result[name][row] for name in model.velocities])
    reference = kinematics(tree, spatial_common.to_reference(model, q)[0], v)
    frame = mechanism_frames(result, [row])[0]
    for i, body in enumerate(model.bodies):
        tip = reference.origin[i] + reference.rotation[i] @ np.array([0.0, 0.0, -(0.6, 0.5, 0.4, 0.4)[i]])
        assert np.allclose(frame.bodies[body.name][0], reference.origin[i], atol=1e-12)
        assert np.allclose(frame.bodies[body.name][1], tip, atol=1e-12)
    added = mechanism_frames(with_pose_signals(_run("spatial_chain")[1]), [row])[0]     # same run, signals added after
    for name in frame.bodies:
        assert np.allclose(added.bodies[name], frame.bodies[name], atol=1e-13)


def test_beam_frames_draw_the_deformation_to_the_tip():
    """A modal beam is drawn through its stations; its last station is the deformed tip of the model."""
    manipulator = importlib.import_module("ctmm.manipulator")
    arm = manipulator.seed_manipulator()
    pd = manipulator.HubPD(manipulator.SEED_KP, manipulator.SEED_KD)
    scene = manipulator.manipulator_scene(arm, pd=pd, pzt=None)
    result = ctmm.simulate(scene, 0.2, 0.002, method="rk4", references=manipulator.scene_references(pd, manipulator.SEED_MOVE))
    plant = scene.plant
    frame = mechanism_frames(result, [100], stations=11)[0]
    beam = plant.body_index("arm")
    q = np.array([result[name][100] for name in plant.coordinates])
    points = plant.points(q, q * 0)
    angle = points["theta"][beam]
    rotation = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    tip = points["inboard"][beam] + rotation @ plant.beam_point_local(beam, 0, q, q * 0)[0]
    assert frame.bodies["arm"].shape == (11, 2)
    assert np.allclose(frame.bodies["arm"][-1], tip, atol=1e-12)
    deflection = rotation.T @ (frame.bodies["arm"][-1] - points["inboard"][beam])
    assert abs(deflection[1]) > 1e-4                                  # the beam is bent, not drawn straight
    doubled = mechanism_frames(result, [100], stations=11, exaggeration=2.0)[0]
    assert np.allclose(rotation.T @ (doubled.bodies["arm"][-1] - points["inboard"][beam]),
                       [deflection[0], 2 * deflection[1]], atol=1e-6)


@pytest.mark.parametrize("name", ["hinge_spring_motor", "spatial_chain"])
def test_animate_writes_a_gif_with_the_frames_asked(tmp_path, name):
    from PIL import Image

    scene = load_scene(FILES / f"{name}.toml")
    options = {"outputs": drawing_outputs(scene.system)} if name == "spatial_chain" else {}
    _, result = _run(name, **options)
    path = result.animate(tmp_path / "run.gif", frames=3, dpi=40)
    assert path == tmp_path / "run.gif" and [p.name for p in tmp_path.iterdir()] == ["run.gif"]
    with Image.open(path) as image:
        assert image.format == "GIF" and image.n_frames == 3


def test_animate_renders_each_frame_once(tmp_path, monkeypatch):
    """The figure is rendered once per picture written (the grab), not a second time per frame for the canvas's
    idle redraw (FuncAnimation.save did both: twice the drawing time of every animation)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renders = []
    draw = FigureCanvasAgg.draw
    monkeypatch.setattr(FigureCanvasAgg, "draw", lambda canvas, *a, **k: (renders.append(1), draw(canvas, *a, **k))[1])
    _, result = _run("hinge_spring_motor")
    result.animate(tmp_path / "run.gif", frames=4, dpi=40)
    assert len(renders) == 4


def test_refusals(tmp_path):
    _, planar = _run("pendulum_chain", t_final=0.01)
    with pytest.raises(ModelError, match=r"one of \.gif, \.mp4, got suffix '\.avi'"):
        planar.animate(tmp_path / "run.avi")
    with pytest.raises(ModelError, match="does not exist"):
        planar.animate(tmp_path / "missing" / "run.gif")
    with pytest.raises(ModelError, match="frames must be an integer >= 1"):
        planar.animate(tmp_path / "run.gif", frames=0)
    with pytest.raises(ModelError, match="exaggeration must be"):
        planar.animate(tmp_path / "run.gif", exaggeration=-1.0)
    chain = load_scene(FILES / "table7_1.toml")
    with pytest.raises(ModelError, match="a 1-D chain has no geometry"):
        ctmm.simulate(chain.system, 0.01, 1e-3).animate(tmp_path / "run.gif")
    with pytest.raises(ModelError, match="drawing_outputs"):
        _run("spatial_chain", t_final=0.01)[1].animate(tmp_path / "run.gif")
    from matplotlib import animation
    if not animation.writers.is_available("ffmpeg"):
        with pytest.raises(ModelError, match="needs the ffmpeg program"):
            planar.animate(tmp_path / "run.mp4")
    assert not list(tmp_path.iterdir())


def test_frame_rows_spread_evenly():
    assert frame_rows(11, 3).tolist() == [0, 5, 10]
    assert frame_rows(2, 5).tolist() == [0, 1]
    assert frame_rows(4, None).tolist() == [0, 1, 2, 3]


def test_write_results_animates_a_spatial_run_without_stored_points(tmp_path):
    from ctmm.scene_files_run import write_results

    _, spatial = _run("spatial_chain", t_final=0.01)
    chain = load_scene(FILES / "table7_1.toml")
    written = write_results({"rk4": spatial, "chain": ctmm.simulate(chain.system, 0.01, 1e-3)}, tmp_path, "demo",
                            save=False, animate=True, frames=2)
    assert written == {"saved": [], "animations": ["demo_rk4.gif"], "notes": []}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["demo_rk4.gif"]
    with pytest.raises(ModelError, match="dpi must be an integer"):
        spatial.animate(tmp_path / "x.gif", dpi=0)
    assert write_results({}, tmp_path, "none", save=True, animate=True)["notes"] == [
        "'none' returns no time history or response to save", "'none' returns no planar or spatial run to animate"]
