"""Scenario discovery and running (``ctmm run NAME``).

A scenario is a module of the ``scenarios/`` folder (installed as ``ctmm.scenarios``) that
defines ``NAME: str``, ``DESCRIPTION: str`` and ``run(output_dir: Path, quick: bool = False)
-> dict``.  ``run`` writes its PNG(s) into ``output_dir`` and returns a JSON-serialisable
summary containing ``"accuracy"`` (a list of figures made by :func:`accuracy`: name, value,
unit, definition and the scenario's own bound) and ``"wall_time_s"``.  A scenario whose ``run``
also takes ``results: dict | None = None`` puts its runs there (``results[label] = result``, a
``SimulationResult`` or ``FrequencyResponse``) when given a dict: ``ctmm run NAME --save / --animate``
writes them (:func:`run_scenario`, ``write_results``); the summary stays JSON-serialisable.

:func:`run_scenario` runs a scenario in a private staging folder inside the output folder and
only then moves its files into place, each by ``os.replace`` (atomic on one file system), the
JSON last: a failed or interrupted run leaves no half-written file and no new PNG beside an old
JSON.  Files of an earlier run of the same scenario (listed in its JSON) that the new run does
not write again are removed; when a run fails, the earlier outputs of that scenario are removed
too, so the folder never shows a result the current code did not produce.
"""
from __future__ import annotations

import importlib
import inspect
import json
import math
import os
import pkgutil
import shutil
import tempfile
import time
from pathlib import Path
from types import ModuleType
from typing import Any, Callable

import numpy as np

from .errors import ModelError, unknown_name

__all__ = ["accuracy", "available", "broken", "check_output_folder", "run_scenario", "write_json_atomic"]


def accuracy(name: str, value: float, unit: str, bound: float, definition: str, *, source: str) -> dict:
    """One accuracy figure of a scenario, with its unit, definition and bound.

    Parameters
    ----------
    name : str
        Short name, e.g. ``"tip deflection error vs Lagrange"``.
    value : float
        The measured error, in ``unit``.
    unit : str
        Unit of ``value`` and ``bound`` (``"m"``, ``"rad"``, ``"% of peak"``, ``"relative"`` ...).
    bound : float
        Largest acceptable value, from the scenario's documented target or reference.
    definition : str
        How ``value`` is computed and against which independent reference.
    source : str
        Where ``bound`` comes from (document and statement).

    Returns
    -------
    dict
        ``name, value, unit, bound, definition, bound_source, passed`` (``passed`` is False for a
        non-finite value).
    """
    value = float(value)
    bound = float(bound)
    if not (math.isfinite(bound) and bound > 0):
        raise ModelError(f"bound of accuracy figure {name!r} must be finite and > 0, got {bound!r}")
    return {"name": name, "value": value, "unit": unit, "bound": bound, "definition": definition,
            "bound_source": source, "passed": bool(math.isfinite(value) and value <= bound)}


def _package() -> ModuleType:
    return importlib.import_module("ctmm.scenarios")


def available() -> dict[str, ModuleType]:
    """All scenarios by name (modules defining ``NAME`` and ``run``).

    A module that fails to import is left out here and reported by :func:`broken`.
    """
    return _discover()[0]


def broken() -> dict[str, str]:
    """Scenario modules that failed to import: ``{module name: error}``."""
    return _discover()[1]


def _discover() -> tuple[dict[str, ModuleType], dict[str, str]]:
    found, failed = {}, {}
    pkg = _package()
    for info in pkgutil.iter_modules(pkg.__path__):
        if info.name.startswith("_"):
            continue
        try:
            module = importlib.import_module(f"{pkg.__name__}.{info.name}")
        except Exception as exc:  # noqa: BLE001 - one broken study must not hide the others
            failed[info.name] = f"{type(exc).__name__}: {exc}"
            continue
        if hasattr(module, "run") and hasattr(module, "NAME"):
            found[module.NAME] = module
    return dict(sorted(found.items())), failed


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if np.isfinite(v) else str(v)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, complex):
        return {"re": value.real, "im": value.imag}
    return value


def write_json_atomic(path: Path, data: dict) -> None:
    """Write ``data`` as JSON to ``path`` whole or not at all (temporary file + rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(_jsonable(data), indent=2, sort_keys=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as handle:
            handle.write(text + "\n")
        os.chmod(tmp, 0o644)  # mkstemp creates 0600; results are ordinary files
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def check_output_folder(output_dir: str | Path) -> Path:
    """Create ``output_dir`` if needed and check that files can be written in it.

    Raises
    ------
    ModelError
        The folder cannot be created or written (names the folder and the reason).
    """
    if not isinstance(output_dir, (str, os.PathLike)) or not str(output_dir).strip():
        raise ModelError(f"--output must name a folder, got {output_dir!r}")
    path = Path(output_dir)
    if path.exists() and not path.is_dir():
        raise ModelError(f"--output {str(path)!r} exists and is not a folder; give a folder you can write to")
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(dir=path, prefix=".ctmm-write-check-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise ModelError(f"--output {str(path)!r} is not a writable folder ({reason}); "
                         "give a folder you can write to") from None
    return path


def _accuracy_figures(name: str, summary: dict) -> list[dict]:
    figures = summary.get("accuracy")
    if not isinstance(figures, list) or not figures:
        raise ModelError(f"scenario {name!r} reports no accuracy figures (its run() must return "
                         "'accuracy': [ctmm.scenario.accuracy(...), ...])")
    keys = {"name", "value", "unit", "bound", "definition", "bound_source", "passed"}
    for figure in figures:
        if not isinstance(figure, dict) or not keys <= set(figure):
            raise ModelError(f"scenario {name!r}: accuracy figure {figure!r} lacks one of {sorted(keys)}")
    return figures


SCENE_SUMMARY_KEYS = ("scene", "scene_file", "verb", "figures", "ctmm_version", "passed")
"""Keys of the JSON summary that ``ctmm run scene.toml`` writes (:mod:`ctmm.scene_files_run`)."""


def is_run_summary(data: Any, name: str) -> bool:
    """Whether ``data`` (a parsed JSON file) is a summary that ``ctmm run`` wrote for the study ``name``.

    Either form counts -- a scenario's (``scenario = name``, ``figures``, ``passed``) or a scene file's
    (:data:`SCENE_SUMMARY_KEYS`, ``scene = name``) -- because both write ``<name>.json`` into the same folder:
    a run may replace the other's summary of the same study, never any other file.
    """
    if not isinstance(data, dict) or not isinstance(data.get("figures"), list) or "passed" not in data:
        return False
    return data.get("scenario") == name or (all(key in data for key in SCENE_SUMMARY_KEYS) and data["scene"] == name)


def _previous_outputs(output_dir: Path, name: str) -> list[Path]:
    """Files of an earlier run of ``name``: its JSON and the figures it lists; ``[]`` when there is none.

    Raises
    ------
    ModelError
        ``<name>.json`` exists but is not the summary of an earlier run of scenario ``name`` or of a scene
        file of that name (:func:`is_run_summary`; any other file, a folder, a link): a run would replace or remove it, so it is refused before anything is written.
    """
    record = output_dir / f"{name}.json"
    if not os.path.lexists(record):
        return []
    try:
        data = json.loads(record.read_text()) if record.is_file() and not record.is_symlink() else None
    except (OSError, ValueError, UnicodeDecodeError):
        data = None
    if not is_run_summary(data, name):
        raise ModelError(f"{str(record)!r} is where the summary of scenario {name!r} goes, but it is not the summary "
                         f"of an earlier run of it or of the scene file {name!r} (a JSON object with scenario = "
                         f"{name!r}, figures and passed); "
                         "ctmm run replaces only its own earlier summary: move that file or write the outputs to "
                         "another folder (--output)")
    files = [record]
    for figure in data["figures"]:
        candidate = output_dir / str(figure)
        if candidate.parent == output_dir and candidate.is_file() and candidate != record:
            files.append(candidate)
    return files


def _remove(paths: list[Path]) -> None:
    for path in paths:
        try:
            path.unlink()
        except FileNotFoundError:
            pass


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True
    return True


def _remove_dead_staging(output_dir: Path, name: str) -> None:
    """Remove staging folders of ``name`` left by killed runs (their process no longer exists)."""
    for folder in output_dir.glob(f".{name}-*-*"):
        pid = folder.name[len(name) + 2:].split("-", 1)[0]
        if folder.is_dir() and pid.isdigit() and not _process_alive(int(pid)):
            shutil.rmtree(folder, ignore_errors=True)


def run_scenario(name: str, output_dir: str | Path = "results", *, quick: bool = False,
                 write_results: Callable[..., dict] | None = None) -> dict:
    """Run scenario ``name`` and write its PNG(s) and ``<output_dir>/<name>.json`` atomically.

    Parameters
    ----------
    name : str
        Scenario name (see :func:`available`).
    output_dir : str or Path
        Output folder (created if needed).
    quick : bool
        Run the short version.
    write_results : callable, optional
        ``write_results(results, folder, name, provenance=...) -> dict`` writes the runs the scenario
        put into its ``results`` argument (``{label: result}``; see the module docstring) into the
        run's folder, e.g. HDF5 files and animations (``ctmm run --save --animate``:
        :func:`ctmm.scene_files_run.write_results`); its answer is added to the JSON.

    Returns
    -------
    dict
        The summary written to the JSON, with ``passed`` (every accuracy figure within its bound),
        ``figures``, ``total_wall_time_s`` and ``quick`` added.

    Raises
    ------
    ModelError
        Unknown scenario, unwritable output folder, a scenario that reports no accuracy, or a
        ``<name>.json`` in the output folder that is not the summary of an earlier run of the scenario
        (kept; nothing is written).
    Exception
        Whatever the scenario raised (e.g. :class:`~ctmm.errors.SimulationError`); the outputs of
        earlier runs of that scenario are then removed and nothing of this run is left behind.
    """
    scenarios, failed = _discover()
    if name not in scenarios:
        if name in failed:
            raise ModelError(f"scenario module {name!r} cannot be imported: {failed[name]}")
        raise unknown_name("scenario", name, list(scenarios))
    output_dir = check_output_folder(output_dir)
    import matplotlib

    matplotlib.use("Agg")
    _remove_dead_staging(output_dir, name)
    previous = _previous_outputs(output_dir, name)        # refuses a <name>.json that is not an earlier summary
    staging = Path(tempfile.mkdtemp(dir=output_dir, prefix=f".{name}-{os.getpid()}-"))
    try:
        try:
            started = time.perf_counter()
            results: dict = {}
            if write_results is not None and "results" in inspect.signature(scenarios[name].run).parameters:
                summary = scenarios[name].run(staging, quick=quick, results=results)
            else:
                summary = scenarios[name].run(staging, quick=quick)
            if not isinstance(summary, dict):
                raise ModelError(f"scenario {name!r}: run() must return a dict, got {type(summary).__name__}")
            summary = dict(summary, total_wall_time_s=time.perf_counter() - started)
            figures = _accuracy_figures(name, summary)
            if write_results is not None:
                summary.update(write_results(results, staging, name, provenance={
                    "scenario": name, "quick": quick, "accuracy": figures}))
            summary.setdefault("scenario", name)
            summary["quick"] = quick
            summary["passed"] = all(f["passed"] for f in figures)
            written = sorted(p.name for p in staging.iterdir() if p.is_file() and p.name != f"{name}.json")
            summary["figures"] = written
            write_json_atomic(staging / f"{name}.json", summary)
        except Exception:
            _remove(previous)
            raise
        _commit(staging, output_dir, name, written, previous)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return summary


def _commit(staging: Path, output_dir: Path, name: str, written: list[str], previous: list[Path]) -> None:
    """Move a finished run into place: old JSON out first, new files in, new JSON last (``previous``: the
    earlier run's JSON and figures, :func:`_previous_outputs`); a file of the name of a new one that no
    earlier run wrote is kept and the run refused (ModelError) before anything moves."""
    foreign = [file_name for file_name in written
               if os.path.lexists(output_dir / file_name) and output_dir / file_name not in previous]
    if foreign:
        raise ModelError(f"scenario {name!r} wrote {', '.join(foreign)}, but {str(output_dir)!r} already holds a file "
                         "of that name that is not an output of an earlier run of it; it is kept and nothing is "
                         "written: move it or write the outputs to another folder (--output)")
    _remove(previous[:1])                      # no old JSON may describe the new figures
    for file_name in written:
        os.replace(staging / file_name, output_dir / file_name)
    _remove([p for p in previous[1:] if p.name not in written])
    os.replace(staging / f"{name}.json", output_dir / f"{name}.json")
