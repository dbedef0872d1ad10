"""Scene files: a system, its feedback loops, its co-simulated controllers and its study in one TOML, YAML or
JSON file (``ctmm run scene.toml``).

::

    [system]
    kind = "planar_chain"          # chain | planar | planar_chain | planar_closed | spatial
    name = "pendulum"
    gravity = [0.0, -9.81]

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
    t_final = 1.0
    dt = 0.001

Every table with a ``type`` calls the Python constructor of that name with the other keys
(:mod:`ctmm.scene_files_schema` derives the allowed types and keys from the code); ``[study]``
calls the verb with the system first. Inline tables ``{type = "Harmonic", ...}`` build values
(time signals, grids, transfer functions), ``{python = "module:attribute"}`` names a Python
object (e.g. a reference motion ``f(t)``) imported from an installed module and
``{call = "module:attribute", ...}`` calls one with the other keys (checked against its
signature). ``[[controllers]]`` tables name co-simulated controllers (``call``, ``python`` or an
``fmu`` path relative to the scene file) passed to ``simulate``. The same tables may be written in
YAML or JSON (:mod:`ctmm.scene_files_syntax`); :func:`ctmm.scene_files_schema.json_schema` states the format as a
JSON Schema (``ctmm scene schema``). A mistake is a :class:`SceneError` naming the file, the line,
the table and the key, and what is allowed. ``docs/scene_files.md`` is the reference.
"""
from __future__ import annotations

import importlib
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from . import scene_files_schema as schema
from .errors import ModelError
from .scene_files_syntax import SUFFIXES, KeyPath, key_lines, parse

__all__ = ["Scene", "SceneError", "load_scene", "key_lines", "TOP_LEVEL_TABLES", "OUTPUT_KEYS"]

TOP_LEVEL_TABLES = ("system", "loops", "controllers", "study", "output")
"""Tables of a scene file: ``[system]`` (required), ``[[loops]]``, ``[[controllers]]``, ``[study]`` (required),
``[output]``."""

OUTPUT_KEYS = {"plot": "signal names drawn by `ctmm run` (default: the coordinates or the first 6 signals)",
               "description": "one line shown by `ctmm run` and written into the JSON"}
"""Keys of the optional ``[output]`` table."""


class SceneError(ModelError):
    """A scene file that cannot be read or built: names the file, line, table and key.

    Attributes
    ----------
    path : str
        The scene file.
    line : int or None
        Line of the offending key or table (1-based), if known.
    key : str
        Dotted key path, e.g. ``"system.elements[2].mass"``.
    """

    def __init__(self, message: str, *, path: str = "", line: int | None = None, key: str = "") -> None:
        where = ", ".join(part for part in (path, f"line {line}" if line else "", f"key {key!r}" if key else "") if part)
        super().__init__(f"{where}: {message}" if where else message)
        self.path, self.line, self.key = path, line, key


def _dotted(path: KeyPath) -> str:
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


@dataclass
class _Reader:
    """Builds objects from the parsed file, raising :class:`SceneError` with line and key."""

    path: str
    lines: dict[KeyPath, int]
    types: dict[str, schema.Constructor] = field(default_factory=dict)
    values: dict[str, schema.Constructor] = field(default_factory=schema.value_types)

    def fail(self, where: KeyPath, message: str) -> SceneError:
        probe = tuple(where)
        while probe and probe not in self.lines:
            probe = probe[:-1]
        return SceneError(message, path=self.path, line=self.lines.get(probe), key=_dotted(where))

    def call(self, item: schema.Constructor, table: dict, where: KeyPath, skip: tuple[str, ...] = ("type",),
             extra: dict | None = None) -> Any:
        """Call ``item`` with the keys of ``table`` (checked against its parameters)."""
        keys = item.keys()
        arguments = dict(extra or {})
        for key, value in table.items():
            if key in skip:
                continue
            if key not in keys and not item.open:
                raise self.fail(where + (key,), f"unknown key {key!r} of {item.name}; allowed keys: "
                                f"{', '.join(keys)}")
            arguments[key] = self.value(value, where + (key,))
        missing = [key for key in item.required() if key not in arguments]
        if missing:
            raise self.fail(where, f"{item.name} needs the key(s) {', '.join(missing)} (allowed keys: "
                            f"{', '.join(keys)})")
        for parameter in item.parameters:           # TOML has no null: a left-out key that admits None
            if parameter.required and parameter.name not in arguments:
                arguments[parameter.name] = None
        try:
            return item.target(**arguments)
        except ModelError as exc:
            named = self._named_key(where, {key: value for key, value in table.items() if key not in skip}, str(exc))
            raise self.fail(named, f"{item.name}: {exc}") from exc
        except (TypeError, ValueError) as exc:
            raise self.fail(where, f"{item.name}: {type(exc).__name__}: {exc}") from exc

    @staticmethod
    def _named_key(where: KeyPath, table: dict, message: str) -> KeyPath:
        """The key a constructor's message names (when exactly one key of the table is named), else the table."""
        named = [key for key in table if key not in ("type", "name") and re.search(rf"\b{re.escape(key)}\b", message)]
        return where + (named[0],) if len(named) == 1 else where

    def typed(self, table: dict, where: KeyPath, types: dict[str, schema.Constructor], what: str) -> Any:
        """Build the object of a table with a ``type`` key from ``types``."""
        kind = table.get("type")
        if kind is None:
            raise self.fail(where, f"{what} needs a key 'type'; allowed types: {', '.join(types)}")
        if kind not in types:
            raise self.fail(where + ("type",), f"unknown {what} type {kind!r}; allowed types: {', '.join(types)}")
        return self.call(types[kind], table, where)

    def value(self, value: Any, where: KeyPath) -> Any:
        """A key's value: inline tables with ``type`` or ``python`` built, lists element by element."""
        if isinstance(value, list):
            return [self.value(item, where + (index,)) for index, item in enumerate(value)]
        if not isinstance(value, dict):
            return value
        if "python" in value:
            if set(value) != {"python"}:
                raise self.fail(where, f"a {{python = ...}} value takes no other key (to call it with keys use "
                                f"{{call = ...}}), got {sorted(value)}")
            return self.python(value["python"], where + ("python",))
        if "call" in value:
            target = self.python(value["call"], where + ("call",))
            if not callable(target):
                raise self.fail(where + ("call",), f"{value['call']!r} is not callable")
            try:
                item = schema.constructor(str(value["call"]), target)
            except (TypeError, ValueError):    # no inspectable signature (some builtins)
                raise self.fail(where + ("call",), f"{value['call']!r} has no signature to check keys against; "
                                "call a Python function or class") from None
            return self.call(item, value, where, skip=("call",))
        if "type" in value:
            return self.typed(value, where, {**self.values, **self.types}, "value")
        return {key: self.value(item, where + (key,)) for key, item in value.items()}

    def python(self, reference: Any, where: KeyPath) -> Any:
        module, _, attribute = str(reference).partition(":")
        if not module or not attribute:
            raise self.fail(where, f"python reference must be 'module:attribute', got {reference!r}")
        try:
            target: Any = importlib.import_module(module)
            for part in attribute.split("."):
                target = getattr(target, part)
        except (ImportError, AttributeError) as exc:
            raise self.fail(where, f"python reference {reference!r} cannot be imported: {exc}") from None
        return target


@dataclass
class Scene:
    """A loaded scene file.

    Attributes
    ----------
    path : Path
        The file.
    name : str
        The scene name (the file name without its ``.toml`` / ``.yaml`` / ``.json`` ending): names the outputs of
        ``ctmm run``.
    system : object
        The model (``Chain``, ``PlanarModel``, ``SpatialModel``), with its loops closed
        (``ctmm.control.with_feedback``) when the file has ``[[loops]]``.
    plant : object
        The model without loops.
    verb : str
        The study (``"simulate"``, ``"frequency_response"``, ``"natural_frequencies"``, ``"stability_chart"``).
    arguments : dict
        The study's keyword arguments, built (the co-simulated controllers of ``[[controllers]]`` under
        ``"controllers"``).
    output : dict
        The ``[output]`` table (``plot``, ``description``).
    lines : dict
        Line (1-based) of each key path of the file (``("output", "plot")``), for errors found when it runs.
    """

    path: Path
    name: str
    system: Any
    plant: Any
    verb: str
    arguments: dict
    output: dict
    lines: dict = field(default_factory=dict, repr=False, compare=False)

    def run(self) -> Any:
        """Run the study: ``verb(system, **arguments)`` (a ``SimulationResult``, ``FrequencyResponse`` ...).

        Raises
        ------
        SceneError
            The verb refuses an argument of a loaded file (``dt = "1 ms"``, an unknown ``method``, an option
            ``natural_frequencies`` does not take): its :class:`~ctmm.errors.ModelError` (or ``TypeError`` of an
            unexpected keyword) with the line and key of the ``[study]`` key it names, else of ``[study]``.
        """
        try:
            return schema.verb(self.verb).target(self.system, **self.arguments)
        except SceneError:
            raise
        except (ModelError, TypeError) as exc:
            unexpected = re.search(r"unexpected keyword argument '([^']+)'", str(exc))
            if not self.lines or (isinstance(exc, TypeError) and not (unexpected and unexpected.group(1) in
                                                                      self.arguments)):
                raise
            where = ("study", unexpected.group(1)) if isinstance(exc, TypeError) else \
                _study_key(self.arguments, self.lines, str(exc))
            inside = [number for path, number in self.lines.items() if path[:len(where)] == where]   # x0.m9 = ...
            line = min(inside, default=None) or self.lines.get(where[:2], self.lines.get(("study",)))
            text = f"unknown option {where[1]!r} ({exc})" if isinstance(exc, TypeError) else str(exc)
            raise SceneError(f"{self.verb}: {text}", path=str(self.path), line=line, key=_dotted(where)) from exc


def _study_key(arguments: dict, lines: dict, message: str) -> KeyPath:
    """The key of a verb's refusal: the ``[study]`` key ``message`` names, else the one whose value holds a name it
    quotes (``x0 = { m9 = 0.1 }``: "unknown element 'm9'"); a controller's signal the ``[[controllers]]`` table's
    ``inputs`` / ``outputs``; else ``[study]``."""
    where = _Reader._named_key(("study",), dict.fromkeys(arguments), message)
    controller = re.search(r"\b(input|output)s? of controller (\d+)|\bcontrollers\[(\d+)\]", message)
    if where == ("study", "controllers") and where not in lines and controller:      # [[controllers]] tables
        if controller.group(3):
            return ("controllers", int(controller.group(3)))
        return ("controllers", int(controller.group(2)), controller.group(1) + "s")
    if where == ("study",):
        quoted = set(re.findall(r"'([^']+)'", message))
        for key, value in arguments.items():
            names = value if isinstance(value, (dict, list, tuple)) else [value]
            if quoted & {name for name in names if isinstance(name, str)}:
                return ("study", key)
    return where


def _check_table(reader: _Reader, data: dict, key: str, want: type, required: bool) -> Any:
    value = data.get(key)
    if value is None:
        if required:
            raise reader.fail((), f"a scene file needs a [{key}] table")
        return want()
    if not isinstance(value, want):
        shape = f"[[{key}]] tables (an array of tables)" if want is list else f"a [{key}] table"
        raise reader.fail((key,), f"{key!r} must be {shape}, got {type(value).__name__}")
    return value


def _element(reader: _Reader, element: Any, where: KeyPath, kind: str) -> list:
    """The element(s) of one ``[[system.elements]]`` table: a ``type`` of the kind, or ``call = "module:attribute"``
    (a Python function returning an element or a list of elements); a list (``finite_segment_beam``) is spliced in."""
    if not isinstance(element, dict):
        raise reader.fail(where, f"an element must be a table with a 'type' ({', '.join(reader.types)}), "
                          f"got {type(element).__name__}")
    if "call" in element and "type" not in element:
        built = reader.value(element, where)
    else:
        built = reader.typed(element, where, reader.types, f"{kind} element")
    return list(built) if isinstance(built, (list, tuple)) else [built]


def _system(reader: _Reader, table: dict) -> Any:
    kind = table.get("kind")
    if kind not in schema.SYSTEM_KINDS:
        where = ("system", "kind") if "kind" in table else ("system",)
        raise reader.fail(where, f"[system] kind must be one of {', '.join(schema.SYSTEM_KINDS)}, got {kind!r}")
    reader.types = schema.element_types(kind)
    elements = table.get("elements")
    if not isinstance(elements, list) or not elements:
        raise reader.fail(("system",), "[system] needs its elements as [[system.elements]] tables, each with a "
                          f"'type' ({', '.join(reader.types)})")
    built = [part for i, element in enumerate(elements)
             for part in _element(reader, element, ("system", "elements", i), kind)]
    try:
        return reader.call(schema.system_constructor(kind), table, ("system",), skip=("kind", "elements"),
                           extra={"elements": built})
    except SceneError as exc:
        if not isinstance(exc.__cause__, ModelError):
            raise
        message = str(exc.__cause__)
        groups = [(elements, ("system", "elements"))]
        if isinstance(table.get("cuts"), list):              # a cut joint's own check first when it names one
            groups.insert(0 if "cut joint" in message else 1, (table["cuts"], ("system", "cuts")))
        where = next((found for tables, path in groups if (found := _named_table(tables, path, message))), None)
        if where is None:
            raise
        raise reader.fail(where, f"{kind}: {exc.__cause__}") from exc.__cause__


def _named_table(tables: list, where: KeyPath, message: str) -> KeyPath | None:
    """The table (and key) of ``tables`` a model's own check names in the first problem of ``message``: the second
    table of a duplicate name, else the table whose ``name`` the message names first (``'h2'`` or ``h2:``) with the
    one key the message names; ``None`` when no table is named."""
    first = message.split("\n  - ")[1] if "\n  - " in message else message
    names = [table.get("name") if isinstance(table, dict) and isinstance(table.get("name"), str) else None
             for table in tables]
    duplicate = re.search(r"duplicate element name '([^']*)'", first)
    if duplicate:
        twice = [i for i, name in enumerate(names) if name == duplicate.group(1)]
        return where + (twice[1], "name") if len(twice) > 1 else None
    named = []
    for i, name in enumerate(names):
        found = re.search(rf"'{re.escape(name)}'|(?<![\w.]){re.escape(name)}:", first) if name else None
        if found:
            named.append((found.start(), i))
    if not named:
        return None
    index = min(named)[1]
    return _Reader._named_key(where + (index,), tables[index], first)


def _controller(reader: _Reader, table: Any, where: KeyPath, folder: Path) -> Any:
    """One ``[[controllers]]`` table: ``fmu = "path"`` (relative to the scene file) with the keys of
    ``FMUController``, ``call = "module:attribute"`` with the keys of that callable, or ``python = "module:attribute"``
    (an object used as it is)."""
    kinds = ("fmu", "call", "python")
    given = [kind for kind in kinds if isinstance(table, dict) and kind in table]
    if len(given) != 1:
        raise reader.fail(where, "a [[controllers]] table needs exactly one of the keys fmu (an FMU file, relative to "
                          "the scene file), call (a Python controller class or function 'module:attribute', called "
                          "with the other keys) or python (a Python controller object 'module:attribute'), got "
                          f"{sorted(table) if isinstance(table, dict) else type(table).__name__}")
    if given[0] != "fmu":
        return reader.value(table, where)
    path = table["fmu"]
    if not isinstance(path, str) or not path:
        raise reader.fail(where + ("fmu",), f"fmu must be the path of an .fmu file or FMU folder, got {path!r}")
    resolved = Path(path) if Path(path).is_absolute() else folder / path
    if not resolved.exists():
        raise reader.fail(where + ("fmu",), f"FMU not found: {path!r} (looked for {str(resolved)!r}; a relative "
                          "path is relative to the scene file's folder)")
    return reader.call(schema.controller_kinds()["fmu"], table, where, skip=("fmu",), extra={"path": resolved})


def _study(reader: _Reader, study: dict) -> tuple[str, dict]:
    verb = study.get("verb")
    if verb not in schema.VERBS:
        where = ("study", "verb") if "verb" in study else ("study",)
        raise reader.fail(where, f"[study] verb must be one of {', '.join(schema.VERBS)}, got {verb!r}")
    item = schema.verb(verb)
    arguments = {}
    for key, value in study.items():
        if key == "verb":
            continue
        if key not in item.keys() and not item.open:
            raise reader.fail(("study", key), f"unknown key {key!r} of {verb}; allowed keys: {', '.join(item.keys())}")
        arguments[key] = reader.value(value, ("study", key))
    missing = [key for key in item.required() if key not in arguments]
    if missing:
        raise reader.fail(("study",), f"{verb} needs the key(s) {', '.join(missing)}")
    return verb, arguments


def load_scene(path: str | os.PathLike) -> Scene:
    """Read, check and build a scene file.

    Parameters
    ----------
    path : str or os.PathLike
        A TOML (``.toml``), YAML (``.yaml``, ``.yml``; needs PyYAML) or JSON (``.json``; key lines with PyYAML)
        file with ``[system]``, optional
        ``[[loops]]`` and ``[[controllers]]``, ``[study]`` and optional ``[output]`` (``docs/scene_files.md``).

    Returns
    -------
    Scene
        The built system and study; :meth:`Scene.run` runs it.

    Raises
    ------
    SceneError
        No such file, not UTF-8 text, not TOML / YAML / JSON (the parser's line and column), PyYAML missing for a YAML file, or a
        table, key or value that is not
        allowed: the message names the file, the line, the key and the allowed values; a
        constructor's own :class:`~ctmm.errors.ModelError` is passed on with the line and key of its table.
    """
    source = Path(path)
    syntax = SUFFIXES.get(source.suffix.lower())
    if syntax is None:
        raise SceneError(f"a scene file is TOML, YAML or JSON and its name must end with {', '.join(SUFFIXES)}, "
                         f"got {str(source)!r}")
    try:
        text = source.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError(f"cannot read the scene file: {exc.strerror or exc}", path=str(source)) from None
    except UnicodeDecodeError as exc:
        line = source.read_bytes()[:exc.start].count(b"\n") + 1
        raise SceneError(f"a scene file is UTF-8 text, got the byte {exc.object[exc.start:exc.start + 1]!r} (save it "
                         "as UTF-8)", path=str(source), line=line) from None
    try:
        data, lines = parse(text, syntax)
    except ValueError as exc:
        raise SceneError(str(exc), path=str(source)) from None
    except ModelError as exc:
        raise SceneError(str(exc), path=str(source)) from None
    reader = _Reader(str(source), lines)
    if not isinstance(data, dict):
        raise reader.fail((), f"a scene file holds the tables {', '.join(TOP_LEVEL_TABLES)}, got "
                          f"{type(data).__name__}")
    for key in data:
        if key not in TOP_LEVEL_TABLES:
            raise reader.fail((key,), f"unknown table {key!r}; allowed: {', '.join(TOP_LEVEL_TABLES)}")
    system_table = _check_table(reader, data, "system", dict, True)
    loops_tables = _check_table(reader, data, "loops", list, False)
    controller_tables = _check_table(reader, data, "controllers", list, False)
    study = _check_table(reader, data, "study", dict, True)
    output = _check_table(reader, data, "output", dict, False)
    plant = _system(reader, system_table)
    system = plant
    if loops_tables:
        from .control import with_feedback

        for i, loop in enumerate(loops_tables):
            if not isinstance(loop, dict):
                raise reader.fail(("loops", i), "a loop must be a table with a 'type' "
                                  f"({', '.join(schema.loop_types())}), got {type(loop).__name__}")
        loops = [reader.typed(loop, ("loops", i), schema.loop_types(), "loop") for i, loop in enumerate(loops_tables)]
        try:
            system = with_feedback(plant, loops)
        except ModelError as exc:
            where = _named_table(loops_tables, ("loops",), str(exc)) or ("loops",)
            raise reader.fail(where, f"the loops cannot be closed on the system: {exc}") from exc
    verb, arguments = _study(reader, study)
    if controller_tables:
        if verb != "simulate":
            raise reader.fail(("controllers",), f"co-simulated [[controllers]] run in time: the study verb must be "
                              f"simulate, got {verb!r}")
        if "controllers" in arguments:
            raise reader.fail(("study", "controllers"), "give the controllers either as [[controllers]] tables or as "
                              "[study] controllers, not both")
        arguments["controllers"] = [_controller(reader, table, ("controllers", i), source.parent)
                                    for i, table in enumerate(controller_tables)]
    _check_output(reader, output, verb)
    return Scene(source, source.stem, system, plant, verb, arguments, dict(output), lines)


def _check_output(reader: _Reader, output: dict, verb: str) -> None:
    """The keys of ``[output]``: ``plot`` a list of signal names of a ``simulate`` study (``ctmm run`` draws the other
    verbs' results whole), ``description`` a string."""
    for key in output:
        if key not in OUTPUT_KEYS:
            raise reader.fail(("output", key), f"unknown key {key!r} of [output]; allowed keys: {', '.join(OUTPUT_KEYS)}")
    plot = output.get("plot")
    if plot is not None and verb != "simulate":
        raise reader.fail(("output", "plot"), f"plot names the signals drawn for a simulate study; a {verb} study "
                          f"takes no plot (leave it out), got {plot!r}")
    if plot is not None and not (isinstance(plot, list) and all(isinstance(name, str) and name for name in plot)):
        raise reader.fail(("output", "plot"), f"plot must be a list of signal names, e.g. [\"m1.x\"], got {plot!r}")
    description = output.get("description")
    if description is not None and not isinstance(description, str):
        raise reader.fail(("output", "description"), f"description must be a string, got {description!r}")
