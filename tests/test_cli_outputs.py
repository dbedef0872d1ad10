"""``ctmm run --save / --animate`` and scene files on the command line: files written, read back, provenance."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import ctmm
from ctmm.cli import main
from ctmm.results import load
from ctmm.scene_files import load_scene

FILES = Path(__file__).resolve().parents[1] / "scenarios" / "files"

PENDULUM = """[system]
kind = "planar_chain"
name = "pendulum"

[[system.elements]]
type = "Pinned"
name = "o"

[[system.elements]]
type = "RigidBody.uniform_link"
name = "link"
mass = 1.0
length = 0.5

[study]
verb = "simulate"
t_final = 0.01
dt = 0.001
method = "rk4"
x0 = [0.4]

[output]
plot = ["link.theta"]
description = "one link"
"""


def test_save_writes_the_scenario_runs_with_provenance(tmp_path, capsys):
    assert main(["run", "table7_1", "--quick", "--save", "--output", str(tmp_path)]) == 0
    line = capsys.readouterr().out
    assert "data table7_1_reading_A.h5" in line and "data table7_1_reading_B.h5" in line
    summary = json.loads((tmp_path / "table7_1.json").read_text())
    assert summary["saved"] == ["table7_1_reading_A.h5", "table7_1_reading_B.h5"] and "results" not in summary
    assert set(summary["figures"]) == {"table7_1.png", "table7_1_reading_A.h5", "table7_1_reading_B.h5"}
    stored = load(tmp_path / "table7_1_reading_A.h5")
    assert stored.info["scenario"] == "table7_1" and stored.info["quick"] is True
    assert stored.info["ctmm_version"] == ctmm.__version__ and stored.info["dt"] == 1e-3
    assert stored.info["accuracy"] == summary["accuracy"] and stored.scheme_name
    # the saved history is the run's: the scenario's own JSON error against the exact solution, from the file
    from ctmm.reference import chain as reference

    names = [f"m{2 * i + 2}" for i in range(5)]
    chain = reference.GlobalChain(np.full(5, 0.1), np.r_[np.full(5, 1000.0), 0.0],
                                  free_length=np.r_[np.full(5, 0.1), 0.0], start="fixed", end="free")
    exact = reference.exact_response(chain, stored.time, np.zeros(5), np.zeros(5), np.r_[100.0, np.zeros(4)])
    x = np.column_stack([stored[f"{n}.x"] for n in names])
    error = np.max(np.abs(x - exact.displacement - 0.1 * np.arange(1, 6)))
    assert error == pytest.approx(summary["reading_A"]["dt_tmm_max_error_m"], rel=1e-12)
    assert len(stored.time) == 101


def test_without_save_nothing_but_png_and_json(tmp_path):
    assert main(["run", "table7_1", "--quick", "--output", str(tmp_path)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table7_1.json", "table7_1.png"]


def test_scene_file_run_save_animate(tmp_path, capsys):
    scene = tmp_path / "pendulum.toml"
    scene.write_text(PENDULUM)
    out = tmp_path / "out"
    assert main(["run", str(scene), "--save", "--animate", "--output", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["pendulum.gif", "pendulum.h5", "pendulum.json", "pendulum.png"]
    summary = json.loads((out / "pendulum.json").read_text())
    assert summary["verb"] == "simulate" and summary["accuracy"] == [] and summary["passed"] is True
    stored = load(out / "pendulum.h5")
    direct = load_scene(scene).run()
    assert np.array_equal(stored["link.theta"], direct["link.theta"])
    assert summary["results"]["final_values"]["link.theta"] == direct["link.theta"][-1]
    assert stored.info["scene_file"] == str(scene)
    captured = capsys.readouterr()
    assert "animation pendulum.gif" in captured.out and captured.err == ""      # no progress bar in a pipe


def test_scene_file_quick_and_frequency_study(tmp_path):
    assert main(["run", str(FILES / "controlled_chain_delay_frequency.toml"), "--quick", "--save",
                 "--output", str(tmp_path)]) == 0
    response = load(tmp_path / "controlled_chain_delay_frequency.h5")
    assert response.response.shape == (3, 1, 300)                   # every 10th of the 3000 frequencies
    assert np.array_equal(response.omega, np.linspace(0.02, 6.0, 3000)[::10])


def test_scene_file_errors_are_one_line(tmp_path, capsys):
    scene = tmp_path / "bad.toml"
    scene.write_text(PENDULUM.replace("length = 0.5", "lenght = 0.5"))
    assert main(["run", str(scene), "--output", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1
    assert f"{scene}, line 13, key 'system.elements[1].lenght': unknown key 'lenght'" in error
    assert main(["run", str(tmp_path / "missing.toml")]) == 2
    assert "scene file" in capsys.readouterr().err


def test_scene_rerun_replaces_and_a_failed_run_removes_earlier_outputs(tmp_path, capsys):
    scene = tmp_path / "pendulum.toml"
    scene.write_text(PENDULUM)
    out = tmp_path / "out"
    assert main(["run", str(scene), "--save", "--output", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["pendulum.h5", "pendulum.json", "pendulum.png"]
    assert main(["run", str(scene), "--output", str(out)]) == 0          # without --save: the old .h5 goes
    assert sorted(p.name for p in out.iterdir()) == ["pendulum.json", "pendulum.png"]
    scene.write_text(PENDULUM.replace("t_final = 0.01", "t_final = -1.0"))
    assert main(["run", str(scene), "--output", str(out)]) == 1
    assert "t_final" in capsys.readouterr().err
    assert list(out.iterdir()) == []
