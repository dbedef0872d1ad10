"""Command line: ``ctmm list``, ``ctmm run NAME|FILE.toml... [--quick] [--save] [--animate] [--output DIR]
[--debug]``, ``ctmm scene schema [--output FILE]``, ``ctmm --version``.

``NAME`` is a scenario (``ctmm list``); a path ending in ``.toml``, ``.yaml``, ``.yml`` or ``.json`` is a scene
file (:mod:`ctmm.scene_files`). ``ctmm scene schema`` writes the JSON Schema of scene files
(:func:`ctmm.scene_files_schema.json_schema`) to a file or to standard output. ``--save`` also writes the runs as HDF5 result files, ``--animate`` the
planar and spatial runs as GIF animations (:mod:`ctmm.scene_files_run`). With several runs on a
terminal a progress bar counts them (:mod:`ctmm.progress`; quiet in pipes and CI).

Exit status: 0 when every scenario ran and met its accuracy bounds; 1 when a scenario failed
(it raised, or an accuracy figure exceeded its bound); 2 for a usage error (unknown scenario,
output folder not writable, bad option).  Errors are one line, ``ctmm: error: ...``; ``--debug``
adds the Python traceback.
"""
from __future__ import annotations

import argparse
import signal
import sys
import time
import traceback
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Sequence

from . import __version__, scenario
from .errors import ModelError, SimulationError
from .progress import progress_bar
from .scene_files_syntax import SUFFIXES

SCENE_SUFFIXES = tuple(SUFFIXES)   # scene files: .toml, .yaml, .yml, .json

EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def format_value(value: float) -> str:
    """A number in 2 significant digits (``7.8e-06``, ``0.05``)."""
    return f"{value:.2g}"


def accuracy_text(figures: list[dict]) -> str:
    """``"error 7.8e-06 % of peak (bound 0.1)"`` for each figure, joined by ``"; "``."""
    parts = []
    for figure in figures:
        flag = "" if figure["passed"] else " EXCEEDED"
        parts.append(f"{figure['name']}: error {format_value(figure['value'])} {figure['unit']} "
                     f"(bound {format_value(figure['bound'])}){flag}")
    return "; ".join(parts)


def summary_line(name: str, summary: dict) -> str:
    """One line per finished scenario: accuracy figures with units and bounds, wall times, plots."""
    parts = [name, accuracy_text(summary.get("accuracy", []))]
    if isinstance(summary.get("wall_time_s"), (int, float)):
        parts.append(f"TMM wall time {summary['wall_time_s']:.3g} s")
    if isinstance(summary.get("reference_wall_time_s"), (int, float)):
        parts.append(f"reference {summary['reference_wall_time_s']:.3g} s")
    kinds = {".h5": "data", ".gif": "animation", ".mp4": "animation"}
    for file_name in summary.get("figures", []):
        parts.append(f"{kinds.get(Path(file_name).suffix, 'plot')} {file_name}")
    parts += [f"note: {note}" for note in summary.get("notes", [])]
    return " | ".join(p for p in parts if p)


def failure_text(name: str, exc: BaseException) -> str:
    """One line for a scenario that raised: scenario, what failed, and time/element if known (a message of
    several lines, such as a model's list of problems, joined into the one line)."""
    message = " ".join(line.strip() for line in str(exc).splitlines() if line.strip()) or type(exc).__name__
    if isinstance(exc, SimulationError):
        where = []
        if getattr(exc, "time", None) is not None:
            where.append(f"t = {exc.time:.6g} s")
        if getattr(exc, "element", None):
            where.append(f"element {exc.element!r}")
        detail = f" ({', '.join(where)})" if where else ""
        return f"scenario {name!r} failed: simulation error{detail}: {message}"
    if isinstance(exc, ModelError):
        return f"scenario {name!r} failed: invalid model or option: {message}"
    if isinstance(exc, OSError):
        return f"scenario {name!r} failed: cannot write results: {message}"
    return f"scenario {name!r} failed: {type(exc).__name__}: {message}"


def _error(text: str) -> None:
    print(f"ctmm: error: {text}", file=sys.stderr)


def _table(rows: list[tuple[str, str, str, float]]) -> str:
    """Final table: scenario, pass/fail, accuracy (with units and bounds) or the failure, wall time."""
    width = max([8] + [len(r[0]) for r in rows])
    lines = [f"{'scenario':{width}s}  {'result':6s}  {'wall [s]':>8s}  error (unit, bound) / failure",
             f"{'-' * width}  {'-' * 6}  {'-' * 8}  {'-' * 30}"]
    for name, result, detail, wall in rows:
        lines.append(f"{name:{width}s}  {result:6s}  {wall:8.2f}  {detail}")
    passed = sum(r[1] == "pass" for r in rows)
    lines.append(f"{passed} of {len(rows)} scenarios passed")
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ctmm", description="ctmm scenarios: validated studies that write "
                                     "PNG figures and a JSON summary")
    parser.add_argument("--version", action="version", version=f"ctmm {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("list", help="list the scenarios")
    run = sub.add_parser("run", help="run scenarios or scene files and write PNG + JSON")
    run.add_argument("names", nargs="+", metavar="NAME", help="scenario name(s), 'all', or scene files (.toml, .yaml, .json)")
    run.add_argument("--output", default="results", help="output folder (default: results)")
    run.add_argument("--quick", action="store_true", help="shorter version (smoke test)")
    run.add_argument("--save", action="store_true", help="also write the time histories / responses as HDF5 "
                     "(read back with ctmm.results.load)")
    run.add_argument("--animate", action="store_true", help="also write GIF animations of planar and spatial runs")
    run.add_argument("--debug", action="store_true", help="print Python tracebacks of failures")
    scene = sub.add_parser("scene", help="scene-file tools")
    tools = scene.add_subparsers(dest="scene_command", required=True)
    schema = tools.add_parser("schema", help="write the JSON Schema (draft 2020-12) of scene files")
    schema.add_argument("--output", default="-", help="file to write (default: standard output)")
    return parser


def _scene_schema(output: str) -> int:
    """Write :func:`ctmm.scene_files_schema.json_schema` as indented JSON to ``output`` (``"-"``: stdout)."""
    import json

    from .scene_files_schema import json_schema

    text = json.dumps(json_schema(), indent=2) + "\n"
    if output == "-":
        sys.stdout.write(text)
        return 0
    try:
        Path(output).write_text(text, encoding="utf-8")
    except OSError as exc:
        _error(f"cannot write the schema to {output!r}: {exc.strerror or exc}")
        return EXIT_USAGE
    print(f"wrote {output}")
    return 0


def _list() -> int:
    for name, module in scenario.available().items():
        print(f"{name:28s} {getattr(module, 'DESCRIPTION', '')}")
    for name, error in scenario.broken().items():
        print(f"{name:28s} (cannot be imported: {error})", file=sys.stderr)
    return 0


def _run(names: list[str], output: str, quick: bool, debug: bool, save: bool = False, animate: bool = False) -> int:
    known = scenario.available()
    broken = scenario.broken()
    rows = []
    names = list(dict.fromkeys(names))             # a name given twice runs once
    if "all" in names:
        names = list(dict.fromkeys(n for name in names for n in (known if name == "all" else [name])))
        for name, error in broken.items():          # reported, and the run goes on
            _error(f"scenario module {name!r} cannot be imported: {error}")
            rows.append((name, "FAIL", f"cannot be imported: {error}", 0.0))
    missing_files = [n for n in names if n.lower().endswith(SCENE_SUFFIXES) and not Path(n).is_file()]
    for name in missing_files:
        _error(f"scene file {name!r} " + ("is not a file" if Path(name).exists() else "does not exist"))
    unknown = [n for n in names if n not in known and not n.lower().endswith(SCENE_SUFFIXES)]
    if missing_files and not unknown:
        return EXIT_USAGE
    if unknown:
        for name in unknown:
            if name in broken:
                _error(f"scenario {name!r} cannot be imported: {broken[name]}")
            else:
                _error(f"unknown scenario {name!r}; available: {', '.join(known) or '(none)'}, all")
        return EXIT_USAGE
    try:
        scenario.check_output_folder(output)
    except ModelError as exc:
        _error(str(exc))
        return EXIT_USAGE
    bar = progress_bar(len(names), "runs", min_total=2)
    for name in names:
        started = time.perf_counter()
        try:
            summary = _run_one(name, output, quick, save, animate)
        except KeyboardInterrupt:
            bar.close()
            _error(f"scenario {name!r} interrupted; its earlier results (if any) are unchanged, "
                   "scenarios after it did not run")
            if rows:
                print(_table(rows), file=sys.stderr)
            return EXIT_INTERRUPTED
        except Exception as exc:  # noqa: BLE001 - one failed study must not stop the others
            if debug:
                traceback.print_exc()
            text = failure_text(name, exc)
            _error(text)
            rows.append((name, "FAIL", text, time.perf_counter() - started))
            bar.update()
            continue
        bar.update()
        print(summary_line(name, summary))
        rows.append((name, "pass" if summary["passed"] else "FAIL",
                     accuracy_text(summary["accuracy"]), time.perf_counter() - started))
        if not summary["passed"]:
            _error(f"scenario {name!r} failed: an accuracy figure exceeds its bound "
                   f"({accuracy_text([f for f in summary['accuracy'] if not f['passed']])})")
    bar.close()
    if len(rows) > 1:
        print(_table(rows))
    return 0 if all(r[1] == "pass" for r in rows) else EXIT_FAILED


def _run_one(name: str, output: str, quick: bool, save: bool, animate: bool) -> dict:
    """One scenario or scene file (``.toml``, ``.yaml``, ``.json``), with its HDF5 files / animations on request."""
    from .scene_files_run import run_scene_file, write_results

    if name.lower().endswith(SCENE_SUFFIXES):
        return run_scene_file(name, output, quick=quick, save=save, animate=animate)
    if not (save or animate):
        return scenario.run_scenario(name, output, quick=quick)

    def writer(results, folder, scenario_name, provenance):
        return write_results(results, folder, scenario_name, save=save, animate=animate, provenance=provenance)
    return scenario.run_scenario(name, output, quick=quick, write_results=writer)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``ctmm`` console command; returns the exit status."""
    args = _parser().parse_args(argv)
    if args.command == "list":
        return _list()
    if args.command == "scene":
        return _scene_schema(args.output)
    with _terminate_as_interrupt():
        return _run(args.names, args.output, args.quick, args.debug, args.save, args.animate)


@contextmanager
def _terminate_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM into KeyboardInterrupt while scenarios run, so their staging folders are removed."""
    def interrupt(signum, frame):
        raise KeyboardInterrupt
    try:
        previous = signal.signal(signal.SIGTERM, interrupt)
    except ValueError:                      # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
