"""``ctmm run`` on a scene file never destroys a file it did not write: ``<scene>.json`` in the output folder
is replaced only when it is the summary of an earlier run of that scene (``ctmm.scene_files_run``)."""
from __future__ import annotations

import json
import os

import pytest

from ctmm.scene_files import SceneError
from ctmm.scene_files_run import run_scene_file

from test_cli_outputs import PENDULUM


@pytest.fixture()
def scene(tmp_path):
    path = tmp_path / "pendulum.toml"
    path.write_text(PENDULUM)
    return path


@pytest.mark.parametrize("content", ["my notes, not JSON", "[1, 2, 3]", '{"scene": "pendulum"}',
                                     '{"scene": "other", "scene_file": "x", "verb": "simulate", "figures": ["a.png"], '
                                     '"ctmm_version": "0", "passed": true}'])
def test_a_file_that_is_not_an_earlier_summary_is_kept_and_the_run_refused(tmp_path, scene, content):
    out = tmp_path / "out"
    out.mkdir()
    user_file = out / "pendulum.json"
    user_file.write_text(content)
    (out / "a.png").write_text("the user's picture")
    with pytest.raises(SceneError, match=r"pendulum.json' is where the summary of this run goes, but it is not"):
        run_scene_file(scene, out)
    assert user_file.read_text() == content and (out / "a.png").read_text() == "the user's picture"
    assert sorted(p.name for p in out.iterdir()) == ["a.png", "pendulum.json"]          # no staging left


def test_a_folder_or_link_in_the_summary_place_is_refused(tmp_path, scene):
    out = tmp_path / "out"
    (out / "pendulum.json").mkdir(parents=True)
    with pytest.raises(SceneError, match="not a regular file"):
        run_scene_file(scene, out)
    target = tmp_path / "elsewhere.json"
    summary = run_scene_file(scene, tmp_path / "first")                     # a genuine summary, linked
    target.write_text(json.dumps(summary))
    other = tmp_path / "other"
    other.mkdir()
    os.symlink(target, other / "pendulum.json")
    with pytest.raises(SceneError, match="not a regular file"):
        run_scene_file(scene, other)
    assert json.loads(target.read_text()) == json.loads(json.dumps(summary)) and (other / "pendulum.json").is_symlink()


def test_an_earlier_summary_is_replaced_whole(tmp_path, scene):
    out = tmp_path / "out"
    first = run_scene_file(scene, out, save=True)
    assert sorted(p.name for p in out.iterdir()) == ["pendulum.h5", "pendulum.json", "pendulum.png"]
    second = run_scene_file(scene, out)
    assert sorted(p.name for p in out.iterdir()) == ["pendulum.json", "pendulum.png"]
    assert json.loads((out / "pendulum.json").read_text())["figures"] == second["figures"] == ["pendulum.png"]
    assert first["figures"] == ["pendulum.png", "pendulum.h5"]


@pytest.mark.parametrize("content", ["my notes, not JSON", '{"scene": "table7_1", "figures": []}',
                                     '{"scenario": "other", "figures": ["a.png"], "passed": true}'])
def test_a_scenario_run_keeps_a_file_that_is_not_its_earlier_summary(tmp_path, monkeypatch, content):
    """``ctmm run <scenario>`` follows the same rule (``ctmm.scenario.run_scenario``)."""
    from ctmm import scenario
    from ctmm.errors import ModelError

    from test_cli import FAST, _fake_run, _module

    monkeypatch.setattr(_module(FAST), "run", _fake_run())
    (tmp_path / f"{FAST}.json").write_text(content)
    (tmp_path / "a.png").write_text("the user's picture")
    with pytest.raises(ModelError, match=rf"{FAST}.json' is where the summary of scenario '{FAST}' goes, but it is "
                                         "not the summary of an earlier run"):
        scenario.run_scenario(FAST, tmp_path)
    assert (tmp_path / f"{FAST}.json").read_text() == content and (tmp_path / "a.png").read_text() == "the user's picture"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", f"{FAST}.json"]
    (tmp_path / f"{FAST}.json").unlink()
    with pytest.raises(ModelError, match=rf"scenario '{FAST}' wrote a.png, but .* already holds a file of that name"):
        scenario.run_scenario(FAST, tmp_path)                     # the user's a.png: not an output of a run
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"]
    assert (tmp_path / "a.png").read_text() == "the user's picture"
    (tmp_path / "a.png").unlink()
    scenario.run_scenario(FAST, tmp_path)                         # its own summary: replaced on a rerun
    scenario.run_scenario(FAST, tmp_path)
    assert json.loads((tmp_path / f"{FAST}.json").read_text())["scenario"] == FAST


def test_an_output_name_taken_by_a_file_no_run_wrote_is_kept(tmp_path, scene):
    out = tmp_path / "out"
    out.mkdir()
    (out / "pendulum.png").write_text("the user's picture")
    with pytest.raises(SceneError, match=r"the run wrote pendulum.png, but .* already holds a file of that name"):
        run_scene_file(scene, out)
    assert sorted(p.name for p in out.iterdir()) == ["pendulum.png"]
    assert (out / "pendulum.png").read_text() == "the user's picture"


def test_a_scene_file_and_the_scenario_of_the_same_name_replace_each_others_summary(tmp_path, monkeypatch):
    """``ctmm run single_link`` then ``ctmm run scenarios/files/single_link.toml`` into one folder (and back): both
    are ctmm's own summaries of the same study, so each run replaces the other's; a user's file stays protected."""
    from ctmm import scenario

    from test_cli import FAST, _fake_run, _module

    monkeypatch.setattr(_module(FAST), "run", _fake_run())
    scenario_summary = {"scenario": FAST, "figures": [f"{FAST}.png"], "passed": True}
    scene_summary = {"scene": FAST, "scene_file": "x.toml", "verb": "simulate", "figures": [f"{FAST}.png"],
                     "ctmm_version": "0", "passed": True}
    assert scenario.is_run_summary(scenario_summary, FAST) and scenario.is_run_summary(scene_summary, FAST)
    assert not scenario.is_run_summary(scene_summary, "other") and not scenario.is_run_summary({"scene": FAST}, FAST)
    (tmp_path / f"{FAST}.json").write_text(json.dumps(scene_summary))
    (tmp_path / f"{FAST}.png").write_text("the scene run's figure")
    scenario.run_scenario(FAST, tmp_path)                         # replaces the scene file's summary
    assert json.loads((tmp_path / f"{FAST}.json").read_text())["scenario"] == FAST
    scene = tmp_path / f"{FAST}.toml"
    scene.write_text(PENDULUM)
    out = tmp_path / "out"
    out.mkdir()
    (out / f"{FAST}.json").write_text(json.dumps(scenario_summary))
    run_scene_file(scene, out)                                    # and the other way round
    assert json.loads((out / f"{FAST}.json").read_text())["scene"] == FAST
