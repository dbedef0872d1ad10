"""Scenario discovery and running (``ctmm run NAME``).

A scenario is a module of the ``scenarios/`` folder (installed as ``ctmm.scenarios``) that
defines ``NAME: str``, ``DESCRIPTION: str`` and ``run(output_dir: Path, quick: bool = False)
-> dict``.  ``run`` writes its PNG(s) into ``output_dir`` and returns a JSON-serialisable
summary containing at least ``"max_error"`` (with ``"error_definition"``) and
``"wall_time_s"``.  :func:`run_scenario` adds timing and writes ``<NAME>.json`` atomically
(whole or not at all).
"""
from __future__ import annotations

import importlib
import json
import os
import pkgutil
import tempfile
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from .errors import ModelError, unknown_name


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


def run_scenario(name: str, output_dir: str | Path = "results", *, quick: bool = False) -> dict:
    """Run scenario ``name``, write ``<output_dir>/<name>.json`` and return the summary."""
    scenarios, failed = _discover()
    if name not in scenarios:
        if name in failed:
            raise ModelError(f"scenario module {name!r} cannot be imported: {failed[name]}")
        raise unknown_name("scenario", name, list(scenarios))
    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    import matplotlib

    matplotlib.use("Agg")
    started = time.perf_counter()
    summary = scenarios[name].run(output_dir, quick=quick)
    summary = dict(summary)
    summary.setdefault("scenario", name)
    summary["total_wall_time_s"] = time.perf_counter() - started
    summary["quick"] = quick
    write_json_atomic(output_dir / f"{name}.json", summary)
    return summary
