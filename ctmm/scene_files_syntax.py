"""The syntaxes of scene files, TOML, YAML and JSON: parsed data and the line of every key.

:func:`parse` reads a ``.toml``, ``.yaml``, ``.yml`` or ``.json`` text into plain data (tables as ``dict``,
arrays as ``list``) and a map from key paths (``("system", "elements", 2, "mass")``) to 1-based
line numbers, so that :mod:`ctmm.scene_files` can name the line of a wrong key in either syntax.
TOML parsers keep no line numbers, so a TOML text is scanned once more (:func:`key_lines`); a YAML
text is composed into nodes, which carry their marks. YAML needs PyYAML (``pip install
ctmm[scenes]``); a YAML or JSON null is a left-out key (as in TOML, :func:`_without_nulls`). A JSON text is
read by :mod:`json` (its numbers as JSON states them, not as YAML 1.1 would) and its key lines are those of
PyYAML's composition of the same text when PyYAML is installed (JSON is YAML flow syntax), else unknown (messages
then name the key only).
"""
from __future__ import annotations

import json
import re
import sys
from typing import Any

from .errors import ModelError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - python 3.10
    import tomli as tomllib

__all__ = ["SUFFIXES", "parse", "key_lines", "yaml_key_lines", "KeyPath"]

SUFFIXES = {".toml": "TOML", ".yaml": "YAML", ".yml": "YAML", ".json": "JSON"}
"""File name endings of scene files and their syntax."""

KeyPath = tuple  # where a key is in the file: ("system", "elements", 2, "mass")


_BARE = re.compile(r"[A-Za-z0-9_-]+")


def _split_key(text: str) -> list[str]:
    parts, text = [], text.strip()
    while text:
        if text[0] in "\"'":
            end = text.index(text[0], 1)
            parts.append(text[1:end])
            text = text[end + 1:].strip()
        else:
            match = _BARE.match(text)
            if not match:
                return parts
            parts.append(match.group())
            text = text[match.end():].strip()
        text = text[1:].strip() if text.startswith(".") else ""
    return parts


def _code(line: str, quote: str = "") -> tuple[str, str]:
    """The line without its comment and with string contents blanked, position for position (brackets, ``=`` and
    ``#`` in strings do not count; an escaped quote does not end a basic string), and the triple-quoted (multi-line)
    string still open at its end; ``quote`` is the one open at its start."""
    out, i = [], 0
    while i < len(line):
        if quote:
            if quote[0] == '"' and line[i] == "\\":                  # an escape in a basic string
                out.append("_" * len(line[i:i + 2]))
                i += 2
            elif line.startswith(quote, i):
                out.append(quote)
                i, quote = i + len(quote), ""
            else:
                out.append("_")
                i += 1
        elif line[i] in "\"'":
            quote = line[i] * 3 if line.startswith(line[i] * 3, i) else line[i]
            out.append(quote)
            i += len(quote)
        elif line[i] == "#":
            break
        else:
            out.append(line[i])
            i += 1
    return "".join(out), quote if len(quote) == 3 else ""


def key_lines(text: str) -> dict[KeyPath, int]:
    """Line (1-based) of every table header and top-level key of a TOML text, by key path.

    Arrays of tables are indexed (``("system", "elements", 0)``); keys inside inline tables or
    multi-line arrays are found through their enclosing key.
    """
    lines: dict[KeyPath, int] = {}
    counts: dict[KeyPath, int] = {}
    table: KeyPath = ()
    depth, quote = 0, ""
    for number, raw in enumerate(text.splitlines(), 1):
        code, quote = _code(raw, quote)                        # lines inside a multi-line string are blanked
        stripped = code.strip()
        if depth == 0 and stripped.startswith("["):
            array = stripped.startswith("[[")
            inner = raw.strip()[2:raw.strip().index("]]")] if array else raw.strip()[1:raw.strip().index("]")]
            parts = _split_key(inner)
            path: KeyPath = ()
            for n, part in enumerate(parts):
                path += (part,)
                if path in counts and n < len(parts) - 1:      # inside the latest table of an array
                    path += (counts[path],)
            if array:
                counts[path] = counts.get(path, -1) + 1
                path += (counts[path],)
            table = path
            lines.setdefault(table, number)
            continue
        if depth == 0 and "=" in code:
            lines.setdefault(table + tuple(_split_key(raw[:code.index("=")])), number)
        depth += code.count("[") + code.count("{") - code.count("]") - code.count("}")
        depth = max(depth, 0)
    return lines


def _yaml_loader() -> Any:
    """A PyYAML safe loader that also reads ``1e-3`` as a number (YAML 1.1 wants ``1.0e-3``)."""
    try:
        import yaml
    except ModuleNotFoundError:
        raise ModelError("YAML scene files need PyYAML: pip install 'ctmm[scenes]' (or pyyaml), or write the "
                         "scene in TOML") from None

    class Loader(yaml.SafeLoader):
        pass

    Loader.yaml_implicit_resolvers = {key: list(value) for key, value in yaml.SafeLoader.yaml_implicit_resolvers.items()}
    Loader.add_implicit_resolver("tag:yaml.org,2002:float", re.compile(
        r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"), list("-+0123456789"))
    return yaml, Loader


def yaml_key_lines(node: Any, path: KeyPath = (), lines: dict | None = None) -> dict[KeyPath, int]:
    """Line (1-based) of every key and list item of a composed YAML node, by key path.

    Raises
    ------
    ValueError
        A key given twice in one mapping (PyYAML would keep the last one silently).
    """
    lines = {} if lines is None else lines
    kind = type(node).__name__
    if kind == "MappingNode":
        seen: dict[Any, int] = {}
        for key, value in node.value:
            line = key.start_mark.line + 1
            if not isinstance(key.value, str):
                raise ValueError(f"not valid for a scene file: the key at line {line} is not a name")
            if key.value in seen:          # PyYAML would keep the last one silently; TOML refuses it too
                raise ValueError(f"not valid YAML: duplicate key {key.value!r} at line {line} (first at line "
                                 f"{seen[key.value]})")
            seen[key.value] = line
            child = path + (key.value,)
            lines.setdefault(child, line)
            yaml_key_lines(value, child, lines)
    elif kind == "SequenceNode":
        for index, item in enumerate(node.value):
            lines.setdefault(path + (index,), item.start_mark.line + 1)
            yaml_key_lines(item, path + (index,), lines)
    return lines


def parse(text: str, syntax: str) -> tuple[Any, dict[KeyPath, int]]:
    """The data of a scene text and the line of every key.

    Parameters
    ----------
    text : str
        The file's text.
    syntax : str
        ``"TOML"``, ``"YAML"`` or ``"JSON"`` (:data:`SUFFIXES`).

    Returns
    -------
    data : object
        The parsed document (a ``dict`` for a valid scene).
    lines : dict
        Key path -> line (1-based).

    Raises
    ------
    ValueError
        Not valid TOML / YAML / JSON: the parser's message with its line and column.
    ModelError
        YAML without PyYAML installed.
    """
    if syntax == "TOML":
        try:
            return tomllib.loads(text), key_lines(text)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"not valid TOML: {exc}") from None
    if syntax == "JSON":
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"not valid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
        return _without_nulls(data), _json_key_lines(text)
    yaml, loader_class = _yaml_loader()
    loader = loader_class(text)
    try:
        node = loader.get_single_node()
        lines = yaml_key_lines(node) if node is not None else {}
        data = loader.construct_document(node) if node is not None else None
    except yaml.YAMLError as exc:
        raise ValueError(f"not valid YAML: {exc}".replace("\n", " ")) from None
    finally:
        loader.dispose()
    return _without_nulls(data), lines


def _without_nulls(data: Any) -> Any:
    """``data`` with every ``null`` value of a mapping left out, as TOML, which has none, leaves the key out (a
    ``null`` in a list is kept, for the constructor to refuse)."""
    if isinstance(data, dict):
        return {key: _without_nulls(value) for key, value in data.items() if value is not None}
    if isinstance(data, list):
        return [_without_nulls(value) for value in data]
    return data


def _json_key_lines(text: str) -> dict[KeyPath, int]:
    """Key lines of a valid JSON text from PyYAML's composition of it (empty without PyYAML, or where YAML
    reads the text otherwise)."""
    try:
        yaml, loader_class = _yaml_loader()
    except ModelError:
        return {}
    loader = loader_class(text)
    try:
        node = loader.get_single_node()
        return yaml_key_lines(node) if node is not None else {}
    except yaml.YAMLError:
        return {}
    finally:
        loader.dispose()
