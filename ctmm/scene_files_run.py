"""Outputs of ``ctmm run``: scene files run to PNG + JSON, and time histories / responses / animations on request.

* :func:`run_scene_file` runs a scene file (:mod:`ctmm.scene_files`) like a scenario: a PNG of the
  study, ``<scene>.json`` (system, study, arguments, wall time, the result's key numbers), and with
  ``save`` the whole result as ``<scene>.h5`` (``ctmm.results.load`` reads it), with ``animate``
  ``<scene>.gif``. Files are written to a staging folder first and moved into place, the JSON last (written
  whole, then renamed); a ``<scene>.json`` already there that is not the summary of an earlier run of
  that scene is never replaced (the run is refused before it starts), nor a file of the name of an output
  that summary does not list (refused before anything is moved into place).
* :func:`write_results` writes the runs a scenario hands over in its ``results`` argument
  (``{label: result}``, :mod:`ctmm.scenario`) as ``<scenario>_<label>.h5`` (``save``) and
  ``<scenario>_<label>.gif`` (``animate``), the provenance (scenario, ctmm version, accuracy
  figures) added to each file's ``info``.
"""
from __future__ import annotations

import copy
import json
import os
import re
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .errors import ModelError
from .scenario import SCENE_SUMMARY_KEYS, check_output_folder, is_run_summary, write_json_atomic
from .scene_files import Scene, SceneError, load_scene
from .version import __version__

__all__ = ["write_results", "run_scene_file", "quick_arguments", "QUICK_FACTOR"]

QUICK_FACTOR = 10
"""``--quick`` on a scene file: the simulated time ``t_final - t0`` divided by it (simulate), every
``QUICK_FACTOR``-th frequency (frequency_response) and grid value (stability_chart)."""


def _label(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", str(text)).strip("_") or "run"


def _animatable(result: Any) -> bool:
    model = getattr(getattr(result, "system", None), "model", None)
    return type(getattr(model, "plant", model)).__name__ in ("PlanarModel", "SpatialModel")


def _animate(result: Any, path: Path, frames: int) -> None:
    from .animation import drawing_outputs

    model = result.system.model
    model = getattr(model, "plant", model)
    if type(model).__name__ == "SpatialModel" and any(n not in result.extra for n in drawing_outputs(model)):
        from .animation_spatial import with_pose_signals

        result = with_pose_signals(result)
    result.animate(path, frames=frames)


def write_results(results: Mapping[str, Any], folder: str | os.PathLike, name: str, *, save: bool, animate: bool,
                  provenance: Mapping[str, Any] | None = None, frames: int = 60) -> dict:
    """Write the runs of a scenario or scene: HDF5 files (``save``) and GIF animations (``animate``).

    Parameters
    ----------
    results : mapping
        ``{label: SimulationResult or FrequencyResponse}``.
    folder : str or os.PathLike
        Where the files go (the run's staging folder).
    name : str
        Scenario or scene name: files ``<name>_<label>.h5`` / ``.gif`` (``<name>.h5`` for the label ``""``).
    save, animate : bool
        Write the HDF5 files / the animations of planar and spatial simulations.
    provenance : mapping, optional
        Added to each saved result's ``info`` (scenario, accuracy figures, ...).
    frames : int
        Pictures per animation.

    Returns
    -------
    dict
        ``{"saved": [file names], "animations": [file names], "notes": [why something was not written]}``.
    """
    folder = Path(folder)
    out: dict[str, list[str]] = {"saved": [], "animations": [], "notes": []}
    if not isinstance(results, Mapping):
        raise ModelError(f"scenario {name!r}: 'results' must be a mapping of label to result, got "
                         f"{type(results).__name__}")
    for label, result in results.items():
        stem = f"{name}_{_label(label)}" if label else name
        if save:
            if callable(getattr(result, "save", None)):
                stored = copy.copy(result)
                stored.info = {**getattr(result, "info", {}), **dict(provenance or {}), "result_label": str(label)}
                stored.save(folder / f"{stem}.h5")
                out["saved"].append(f"{stem}.h5")
            else:
                out["notes"].append(f"{label!r} ({type(result).__name__}) has no file format: not saved")
        if animate and hasattr(result, "time") and _animatable(result):
            _animate(result, folder / f"{stem}.gif", frames)
            out["animations"].append(f"{stem}.gif")
    if save and not out["saved"]:
        out["notes"].append(f"{name!r} returns no time history or response to save")
    if animate and not out["animations"]:
        out["notes"].append(f"{name!r} returns no planar or spatial run to animate")
    return out


def quick_arguments(scene: Scene) -> dict:
    """The study arguments of ``--quick`` (see :data:`QUICK_FACTOR`); arguments not of the verb's form are left as
    they are, for the verb to name (with their line, :meth:`Scene.run`)."""
    arguments = dict(scene.arguments)
    times = (arguments.get("t0", 0.0), arguments.get("t_final"))
    if scene.verb == "simulate" and all(isinstance(t, (int, float)) and not isinstance(t, bool) for t in times):
        arguments["t_final"] = times[0] + (times[1] - times[0]) / QUICK_FACTOR     # a tenth of the run from t0
    elif scene.verb == "frequency_response" and np.ndim(arguments.get("omega")) == 1:
        arguments["omega"] = np.asarray(arguments["omega"])[::QUICK_FACTOR]
    elif scene.verb == "stability_chart":
        for axis in ("x", "y"):
            spec = arguments.get(axis)
            if isinstance(spec, (list, tuple)) and len(spec) >= 2 and np.ndim(spec[1]) == 1:
                arguments[axis] = [*spec[:1], np.asarray(spec[1])[::QUICK_FACTOR], *spec[2:]]
    return arguments


def _plot(scene: Scene, result: Any, path: Path) -> bool:
    import matplotlib.pyplot as plt

    if scene.verb == "simulate":
        names = scene.output.get("plot")
        if not names:
            model = getattr(getattr(result, "system", None), "model", None)
            names = [n for n in getattr(model, "coordinates", ()) if n in result.signals()][:6] \
                or result.time_signals()[:6]
        for index, name in enumerate(names):       # a plot name the run does not have: its line and key
            try:
                result[name]
            except ModelError as exc:
                raise SceneError(f"[output] plot: {exc}", path=str(scene.path), line=scene.lines.get(("output", "plot")),
                                 key=f"output.plot[{index}]") from exc
        figure = result.plot(*names)
    elif scene.verb in ("frequency_response", "stability_chart"):
        figure = result.plot()
        figure = getattr(figure, "figure", figure)
    else:
        return False
    figure.suptitle(scene.output.get("description", scene.name), fontsize=9)
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return True


def _plain(value: Any) -> Any:
    """A JSON-ready form of a study argument (objects as their ``repr``)."""
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if isinstance(value, dict):
        return {str(key): _plain(item) for key, item in value.items()}
    if isinstance(value, (str, bool, int, float, np.ndarray, np.generic)) or value is None:
        return value
    return repr(value)


def _key_numbers(scene: Scene, result: Any) -> dict:
    if scene.verb == "simulate":
        return {"t_final_s": float(result.time[-1]) if len(result.time) else None,
                "final_values": {n: float(result[n][-1]) for n in result.time_signals()[:12]}}
    if scene.verb == "frequency_response":
        magnitude = np.abs(result.response)
        return {"peak_magnitude": {f"{o} / {i}": float(magnitude[a, b].max()) for a, o in enumerate(result.outputs)
                                   for b, i in enumerate(result.inputs)}}
    if scene.verb == "natural_frequencies":
        return {"natural_frequencies_rad_s": np.asarray(result, float).tolist()}
    return {"stable_fraction": float(np.mean(getattr(result, "stable", np.nan)))}


def run_scene_file(path: str | os.PathLike, output_dir: str | os.PathLike = "results", *, quick: bool = False,
                   save: bool = False, animate: bool = False) -> dict:
    """Run a scene file and write ``<scene>.png``, ``<scene>.json`` (and ``.h5`` / ``.gif`` on request).

    Parameters
    ----------
    path : str or os.PathLike
        The scene file (``.toml``, ``.yaml``, ``.yml`` or ``.json``).
    output_dir : str or os.PathLike
        Output folder (created if needed).
    quick : bool
        Shorter study (:func:`quick_arguments`).
    save, animate : bool
        Also write the whole result to HDF5 / an animation of a planar or spatial simulation.

    Returns
    -------
    dict
        The JSON summary (``accuracy`` is empty: a scene file carries no reference; ``passed`` is True
        when the study ran).

    Raises
    ------
    SceneError
        The file cannot be read or built (line and key named); or ``<scene>.json`` in ``output_dir`` is not
        the summary of an earlier run of this scene (a JSON scene file, any other file, a folder, a link), or
        a file the run would write is there and not listed by that summary: it is kept and nothing is written.
    ModelError, SimulationError
        From the study; nothing of the run is left behind, and the outputs of an earlier run of the
        same scene (its JSON and the files it lists) are removed. A successful run replaces them:
        the old JSON first, the new files, then files of the old run not written again, the JSON last.
    """
    scene = load_scene(path)
    output = check_output_folder(output_dir)
    earlier = _earlier_outputs(output, scene.name, path)      # refuses a file that is not an earlier summary
    staging = Path(tempfile.mkdtemp(dir=output, prefix=f".{scene.name}-{os.getpid()}-"))
    try:
        arguments = quick_arguments(scene) if quick else scene.arguments
        started = time.perf_counter()
        result = scene.run() if not quick else Scene(scene.path, scene.name, scene.system, scene.plant, scene.verb,
                                                     arguments, scene.output, scene.lines).run()
        wall = time.perf_counter() - started
        figures = [f"{scene.name}.png"] if _plot(scene, result, staging / f"{scene.name}.png") else []
        provenance = {"scene_file": str(scene.path), "ctmm_version": __version__}
        files = write_results({"": result}, staging, scene.name, save=save, animate=animate, provenance=provenance)
        summary = {"scene": scene.name, "scene_file": str(scene.path), "description": scene.output.get("description", ""),
                   "system": repr(scene.system), "verb": scene.verb,
                   "arguments": {key: _plain(value) for key, value in arguments.items()},
                   "wall_time_s": wall, "quick": quick, "accuracy": [], "passed": True,
                   "accuracy_note": "a scene file carries no independent reference: no accuracy figure",
                   "results": _key_numbers(scene, result), "ctmm_version": __version__, **files}
        summary["figures"] = figures + files["saved"] + files["animations"]
        write_json_atomic(staging / f"{scene.name}.json", summary)
    except Exception:
        _remove(earlier)                   # the folder never shows a result this run did not produce
        shutil.rmtree(staging, ignore_errors=True)
        raise
    try:
        foreign = [name for name in summary["figures"]
                   if os.path.lexists(output / name) and output / name not in earlier]
        if foreign:                        # a file of the same name that no earlier run of this scene wrote
            raise SceneError(f"the run wrote {', '.join(foreign)}, but {str(output)!r} already holds a file of that "
                             "name that is not an output of an earlier run of this scene; it is kept and nothing "
                             "is written: move it or write the outputs to another folder (--output)", path=str(path))
        _remove(earlier[:1])               # old JSON out first, new files in, new JSON last
        for name in summary["figures"]:
            os.replace(staging / name, output / name)
        _remove([p for p in earlier[1:] if p.name not in summary["figures"]])
        os.replace(staging / f"{scene.name}.json", output / f"{scene.name}.json")
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return summary


def _holds_scene(data: Any) -> bool:
    """Whether parsed JSON is a scene file (a ``system`` and a ``study`` table), not a run's summary."""
    return isinstance(data, dict) and "system" in data and "study" in data



def _earlier_outputs(output: Path, name: str, scene_path: str | os.PathLike) -> list[Path]:
    """``<name>.json`` of an earlier run and the files it lists (first the JSON); ``[]`` when there is none.

    Raises
    ------
    SceneError
        ``<name>.json`` exists but is not the summary of an earlier run of the scene or scenario ``name``
        (:func:`ctmm.scenario.is_run_summary`; a JSON scene
        file, any other file, a folder or a link): the run would replace or remove it, so it is refused
        before anything is written.
    """
    record = output / f"{name}.json"
    if not os.path.lexists(record):
        return []
    reason = None
    if record.is_symlink() or not record.is_file():
        reason = "it is not a regular file"
    else:
        try:
            data = json.loads(record.read_text())
        except (OSError, ValueError, UnicodeDecodeError) as exc:
            data, reason = None, f"it is not readable JSON ({type(exc).__name__})"
        if reason is None and _holds_scene(data):
            raise SceneError(f"{str(record)!r} is a scene file and the summary of this run ({name}.json) would "
                             "replace it; write the outputs to another folder (--output)", path=str(scene_path))
        if reason is None and not is_run_summary(data, name):
            reason = (f"it is not the summary of a run of scene {name!r} or of the scenario {name!r} (a JSON object "
                      f"with scene = {name!r} and the keys {', '.join(SCENE_SUMMARY_KEYS)})")
    if reason is not None:
        raise SceneError(f"{str(record)!r} is where the summary of this run goes, but {reason}; ctmm run "
                         "replaces only its own earlier summary: move that file or write the outputs to another "
                         "folder (--output)", path=str(scene_path))
    files = [output / f for f in data["figures"]
             if isinstance(f, str) and f and (output / f).parent == output and f != record.name]
    return [record] + [f for f in files if f.is_file() and not f.is_symlink()]


def _remove(paths: list[Path]) -> None:
    for path in paths:
        path.unlink(missing_ok=True)
