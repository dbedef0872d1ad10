"""Command line: one-line errors, exit status, final table, atomic and consistent outputs."""
from __future__ import annotations

import importlib
import json
import os
import subprocess
import sys

import pytest

import ctmm
from ctmm import scenario
from ctmm.cli import main
from ctmm.errors import SimulationError

FAST = "table7_1"      # the fastest real scenario (~0.1 s quick)
OTHER = "delay_oscillator"


def _module(name):
    return importlib.import_module(f"ctmm.scenarios.{name}")


def _fake_run(figures=("a.png",), value=1e-9, bound=1e-6, fail=None, fail_after_write=False):
    """A scenario run() that writes small PNG-like files and reports one accuracy figure."""
    def run(output_dir, quick=False):
        if fail is not None and not fail_after_write:
            raise fail
        for figure in figures:
            (output_dir / figure).write_bytes(b"\x89PNG" + b"0" * 2000)
        if fail is not None:
            raise fail
        return {"accuracy": [scenario.accuracy("fake error", value, "m", bound, "test", source="test")],
                "wall_time_s": 0.01, "figures": list(figures)}
    return run


def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"ctmm {ctmm.__version__}"


def test_unknown_scenario_lists_the_available_ones(tmp_path, capsys):
    assert main(["run", "nope", "--output", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("ctmm: error: unknown scenario 'nope'; available:")
    assert FAST in err
    assert list(tmp_path.iterdir()) == []          # nothing ran


@pytest.mark.parametrize("make_output, message", [
    (lambda tmp: str(tmp / "a_file" / "sub"), "is not a writable folder (Not a directory)"),
    (lambda tmp: str(tmp / "a_file"), "exists and is not a folder"),
    (lambda tmp: "", "must name a folder, got ''"),
])
def test_bad_output_is_one_line(tmp_path, capsys, make_output, message):
    (tmp_path / "a_file").write_text("x")
    assert main(["run", FAST, "--quick", "--output", make_output(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("ctmm: error: --output") and message in err


def test_unwritable_output_from_a_subprocess_has_no_traceback(tmp_path):
    (tmp_path / "a_file").write_text("x")
    done = subprocess.run([sys.executable, "-m", "ctmm", "run", FAST, "--output", str(tmp_path / "a_file")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert "Traceback" not in done.stderr and done.stderr.count("\n") == 1


def test_simulation_error_is_one_line_and_run_goes_on(tmp_path, capsys, monkeypatch):
    error = SimulationError("state is not finite", time=0.25, element="K3")
    monkeypatch.setattr(_module(OTHER), "run", _fake_run(fail=error))
    monkeypatch.setattr(_module(FAST), "run", _fake_run())
    assert main(["run", OTHER, FAST, "--output", str(tmp_path)]) == 1
    out, err = capsys.readouterr()
    assert err.count("\n") == 1
    assert "Traceback" not in err
    assert f"ctmm: error: scenario '{OTHER}' failed: simulation error (t = 0.25 s, element 'K3'): " \
           "state is not finite" in err
    assert f"{FAST} | fake error: error 1e-09 m (bound 1e-06)" in out       # ran after the failure
    table = out[out.index("scenario "):]
    assert f"{OTHER}" in table and "FAIL" in table and "pass" in table and "1 of 2 scenarios passed" in table
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", f"{FAST}.json"]


def test_debug_shows_the_traceback(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(_module(FAST), "run", _fake_run(fail=RuntimeError("boom")))
    assert main(["run", FAST, "--output", str(tmp_path), "--debug"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and "ctmm: error: scenario 'table7_1' failed: RuntimeError: boom" in err


def test_disk_full_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(_module(FAST), "run", _fake_run(fail=OSError(28, "No space left on device"),
                                                        fail_after_write=True))
    assert main(["run", FAST, "--output", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot write results: [Errno 28] No space left on device" in err
    assert list(tmp_path.iterdir()) == []          # the half-written PNG is gone


def test_bound_exceeded_fails(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(_module(FAST), "run", _fake_run(value=2e-6, bound=1e-6))
    assert main(["run", FAST, "--output", str(tmp_path)]) == 1
    out, err = capsys.readouterr()
    assert "EXCEEDED" in out and "exceeds its bound" in err
    assert json.loads((tmp_path / f"{FAST}.json").read_text())["passed"] is False   # result kept


def test_outputs_replace_an_earlier_run_consistently(tmp_path, monkeypatch):
    module = _module(FAST)
    monkeypatch.setattr(module, "run", _fake_run(figures=("a.png", "b.png")))
    scenario.run_scenario(FAST, tmp_path)
    (tmp_path / "unrelated.txt").write_text("kept")
    monkeypatch.setattr(module, "run", _fake_run(figures=("a.png",)))
    summary = scenario.run_scenario(FAST, tmp_path)
    assert summary["figures"] == ["a.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "table7_1.json", "unrelated.txt"]
    # a failed run removes the earlier outputs: no stale result stays
    monkeypatch.setattr(module, "run", _fake_run(fail=SimulationError("diverged", time=1.0),
                                                 fail_after_write=True))
    with pytest.raises(SimulationError):
        scenario.run_scenario(FAST, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["unrelated.txt"]


def test_interrupted_run_leaves_earlier_outputs_untouched(tmp_path, monkeypatch):
    module = _module(FAST)
    monkeypatch.setattr(module, "run", _fake_run())
    scenario.run_scenario(FAST, tmp_path)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    monkeypatch.setattr(module, "run", _fake_run(figures=("a.png", "new.png"), fail=KeyboardInterrupt(),
                                                 fail_after_write=True))
    with pytest.raises(KeyboardInterrupt):
        scenario.run_scenario(FAST, tmp_path)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_scenario_without_accuracy_is_refused(tmp_path, monkeypatch):
    monkeypatch.setattr(_module(FAST), "run", lambda output_dir, quick=False: {"max_error": 1e-9})
    with pytest.raises(ctmm.ModelError, match="no accuracy figures"):
        scenario.run_scenario(FAST, tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_accuracy_figure_passes_only_when_finite_and_within_bound():
    assert scenario.accuracy("e", 1e-7, "m", 1e-6, "d", source="s")["passed"] is True
    assert scenario.accuracy("e", 2e-6, "m", 1e-6, "d", source="s")["passed"] is False
    assert scenario.accuracy("e", float("nan"), "m", 1e-6, "d", source="s")["passed"] is False
    with pytest.raises(ctmm.ModelError, match="bound"):
        scenario.accuracy("e", 1.0, "m", 0.0, "d", source="s")


def test_read_only_output_is_one_line(tmp_path, capsys, monkeypatch):
    """A folder the user may not write to (simulated: the tests may run as root)."""
    def refuse(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(scenario.tempfile, "mkstemp", refuse)
    assert main(["run", FAST, "--output", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err == f"ctmm: error: --output '{tmp_path}' is not a writable folder (Permission denied); " \
                  "give a folder you can write to\n"


def test_run_all_reports_a_module_that_cannot_be_imported(tmp_path, capsys, monkeypatch):
    module = _module(FAST)
    monkeypatch.setattr(module, "run", _fake_run())
    monkeypatch.setattr(scenario, "available", lambda: {FAST: module})
    monkeypatch.setattr(scenario, "broken", lambda: {"bad_study": "SyntaxError: invalid syntax (line 3)"})
    assert main(["run", "all", "--output", str(tmp_path)]) == 1
    out, err = capsys.readouterr()
    assert err == "ctmm: error: scenario module 'bad_study' cannot be imported: SyntaxError: invalid syntax " \
                  "(line 3)\n"
    assert "bad_study" in out and "1 of 2 scenarios passed" in out
    assert (tmp_path / f"{FAST}.json").is_file()


def test_unserialisable_summary_fails_cleanly(tmp_path, capsys, monkeypatch):
    module = _module(FAST)
    monkeypatch.setattr(module, "run", _fake_run())
    scenario.run_scenario(FAST, tmp_path)                      # an earlier, good run

    def run(output_dir, quick=False):
        summary = _fake_run()(output_dir, quick)
        summary["model"] = object()                            # not JSON
        return summary

    monkeypatch.setattr(module, "run", run)
    assert main(["run", FAST, "--output", str(tmp_path)]) == 1
    assert "is not JSON serializable" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_all_may_be_combined_with_names(tmp_path, capsys, monkeypatch):
    module = _module(FAST)
    monkeypatch.setattr(module, "run", _fake_run())
    monkeypatch.setattr(scenario, "available", lambda: {FAST: module})
    monkeypatch.setattr(scenario, "broken", lambda: {})
    assert main(["run", FAST, "all", "--output", str(tmp_path)]) == 0
    assert capsys.readouterr().out.count(f"{FAST} | ") == 1    # once, not twice


def test_staging_folders_of_killed_runs_are_removed(tmp_path, monkeypatch):
    """A run killed by SIGKILL leaves a hidden staging folder; the next run of the scenario removes it."""
    monkeypatch.setattr(_module(FAST), "run", _fake_run())
    dead = tmp_path / f".{FAST}-999999999-abc"             # no such process
    live = tmp_path / f".{FAST}-{os.getpid()}-abc"         # a run still going on
    for folder in (dead, live):
        folder.mkdir()
        (folder / "half.png").write_bytes(b"\x89PNG")
    scenario.run_scenario(FAST, tmp_path)
    assert not dead.exists() and live.exists()
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(".")) == ["a.png", f"{FAST}.json"]
