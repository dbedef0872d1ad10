"""The JSON Schema of scene files (ctmm.scene_files_schema.json_schema, ``ctmm scene schema``) and JSON scene files.

Every shipped scene file (TOML and YAML) is valid under the schema, and files with the mistakes the loader refuses
(unknown table, type, key, kind or verb; a missing required key) are invalid under it -- checked with the
``jsonschema`` package when it is installed, and always with the small validator below, which implements every
keyword the schema uses (the test fails if the schema starts using another one). A JSON scene file builds the
same system and study as the TOML file it was converted from, and its mistakes name their line.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from ctmm.cli import main
from ctmm.scene_files import SceneError, load_scene
from ctmm.scene_files_schema import JSON_SCHEMA_DIALECT, json_schema
from ctmm.scene_files_syntax import SUFFIXES, parse
from tests.test_scene_files import CHAIN, _parts

FILES = sorted(p for p in (Path(__file__).resolve().parents[1] / "scenarios" / "files").iterdir()
               if p.suffix in SUFFIXES)
KEYWORDS = {"$schema", "$defs", "$ref", "title", "description", "type", "const", "properties", "required",
            "additionalProperties", "items", "minItems", "minLength", "pattern", "anyOf", "oneOf", "not"}
TYPES = {"object": dict, "array": list, "string": str, "boolean": bool}


def errors(instance, schema, root) -> list[str]:
    """Where ``instance`` breaks ``schema`` (the keywords of :data:`KEYWORDS`, draft 2020-12 meaning)."""
    if "$ref" in schema:
        return errors(instance, root["$defs"][schema["$ref"].rpartition("/")[2]], root)
    found = []
    if "type" in schema:
        kinds = [schema["type"]] if isinstance(schema["type"], str) else schema["type"]
        number = isinstance(instance, (int, float)) and not isinstance(instance, bool)
        if not any(number if kind == "number" else isinstance(instance, TYPES[kind]) for kind in kinds):
            return [f"{instance!r:.60} is not of type {kinds}"]
    if "const" in schema and instance != schema["const"]:
        found.append(f"{instance!r} is not {schema['const']!r}")
    if "pattern" in schema and not re.search(schema["pattern"], instance):
        found.append(f"{instance!r} does not match {schema['pattern']}")
    if len(instance) < schema.get("minLength", schema.get("minItems", 0)) if isinstance(instance, (str, list)) else 0:
        found.append(f"{instance!r:.60} is too short")
    if isinstance(instance, dict):
        properties = schema.get("properties", {})
        found += [f"missing {key!r}" for key in schema.get("required", []) if key not in instance]
        for key, value in instance.items():
            if key in properties:
                found += [f"{key}: {e}" for e in errors(value, properties[key], root)]
            elif schema.get("additionalProperties", True) is False:
                found.append(f"unknown key {key!r}")
            elif isinstance(schema.get("additionalProperties"), dict):
                found += [f"{key}: {e}" for e in errors(value, schema["additionalProperties"], root)]
    if isinstance(instance, list) and "items" in schema:
        found += [f"[{i}]: {e}" for i, item in enumerate(instance) for e in errors(item, schema["items"], root)]
    if "anyOf" in schema and all(errors(instance, s, root) for s in schema["anyOf"]):
        found.append(f"{instance!r:.60} matches none of anyOf")
    if "oneOf" in schema and sum(not errors(instance, s, root) for s in schema["oneOf"]) != 1:
        found.append(f"{instance!r:.60} does not match exactly one of oneOf")
    if "not" in schema and not errors(instance, schema["not"], root):
        found.append(f"{instance!r:.60} matches a 'not'")
    return found


def keywords(schema) -> set[str]:
    if isinstance(schema, list):
        return set().union(*map(keywords, schema)) if schema else set()
    if not isinstance(schema, dict):
        return set()
    out = set(schema)
    for key, value in schema.items():
        if key in ("properties", "$defs"):
            out |= set().union(*map(keywords, value.values()))
        elif key not in ("const", "required", "description", "title", "type", "pattern"):
            out |= keywords(value)
    return out


def invalid(data, schema) -> bool:
    """Whether ``data`` breaks ``schema``; with jsonschema installed, both validators must agree."""
    ours = bool(errors(data, schema, schema))
    try:
        import jsonschema
    except ModuleNotFoundError:
        return ours
    theirs = not jsonschema.Draft202012Validator(schema).is_valid(data)
    assert ours == theirs, (ours, theirs)
    return ours


@pytest.fixture(scope="module")
def schema():
    return json_schema()


def test_the_schema_uses_only_keywords_the_checks_know(schema):
    assert schema["$schema"] == JSON_SCHEMA_DIALECT == "https://json-schema.org/draft/2020-12/schema"
    assert keywords(schema) <= KEYWORDS, keywords(schema) - KEYWORDS
    json.dumps(schema)                                     # plain JSON
    try:
        import jsonschema
    except ModuleNotFoundError:
        return
    jsonschema.Draft202012Validator.check_schema(schema)


def test_every_shipped_scene_file_is_valid(schema):
    assert len(FILES) >= 30 and {p.suffix for p in FILES} >= {".toml", ".yaml"}
    for path in FILES:
        data, _ = parse(path.read_text(encoding="utf-8"), SUFFIXES[path.suffix])
        assert not invalid(data, schema), (path.name, errors(data, schema, schema)[:3])


@pytest.mark.parametrize("old, new, words", [
    ('[study]', '[plot]\nx = 1\n\n[study]', "unknown table 'plot'"),
    ('type = "Mass"', 'type = "Mas"', "unknown chain element type 'Mas'"),
    ('mass = 1.0', 'mass = 1.0\nmas = 2.0', "unknown key 'mas' of Mass"),
    ('kind = "chain"', 'kind = "chains"', "kind must be one of"),
    ('verb = "natural_frequencies"', 'verb = "natural_frequency"', "verb must be one of"),
    ('verb = "natural_frequencies"\nn_modes = 1', 'verb = "simulate"', "simulate needs the key(s) t_final"),
    ('mass = 1.0', 'mass = 1.0\nforce = { type = "Harmonc", amplitude = 1.0, omega = 2.0 }', "unknown value type"),
    ('mass = 1.0', 'mass = 1.0\nforce = { python = "ctmm.signals:Harmonic", x = 1 }', "takes no other key"),
    ('verb = "natural_frequencies"\nn_modes = 1', 'verb = "simulate"\nt_final = 0.1\n\n[output]\nplot = "m.x"',
     "plot must be a list of signal names"),
])
def test_mistakes_the_loader_refuses_are_invalid_under_the_schema(tmp_path, schema, old, new, words):
    assert old in CHAIN
    data, _ = parse(CHAIN.replace(old, new, 1), "TOML")
    assert not invalid(parse(CHAIN, "TOML")[0], schema)
    assert invalid(data, schema)
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(data, indent=2))
    with pytest.raises(SceneError, match=re.escape(words)):
        load_scene(path)


@pytest.mark.parametrize("name", ["controlled_chain_time.toml", "spatial_hub_beam.toml", "hub_beam.toml"])
def test_a_json_scene_file_builds_what_its_toml_file_builds(tmp_path, name):
    source = FILES[[p.name for p in FILES].index(name)]
    data, _ = parse(source.read_text(encoding="utf-8"), "TOML")
    path = tmp_path / (source.stem + ".json")
    path.write_text(json.dumps(data, indent=1))
    toml, converted = load_scene(source), load_scene(path)
    assert converted.name == toml.name and converted.verb == toml.verb
    assert repr(converted.arguments) == repr(toml.arguments) and converted.output == toml.output
    assert repr(_parts(converted.plant)) == repr(_parts(toml.plant))
    assert type(converted.system) is type(toml.system)


def test_json_mistakes_name_their_line(tmp_path):
    pytest.importorskip("yaml")                  # JSON key lines come from PyYAML's composition of the text
    data, _ = parse(CHAIN, "TOML")
    data["system"]["elements"][2]["mas"] = 2.0
    text = json.dumps(data, indent=2)
    line = next(i for i, row in enumerate(text.splitlines(), 1) if '"mas"' in row)
    path = tmp_path / "scene.json"
    path.write_text(text)
    with pytest.raises(SceneError, match=rf"line {line}, key 'system.elements\[2\].mas'"):
        load_scene(path)
    path.write_text(text.replace('"mas": 2.0', '"mas": 2.0,'))
    with pytest.raises(SceneError, match=r"not valid JSON: .*line \d+, column \d+"):
        load_scene(path)


def test_cli_writes_the_schema(tmp_path, capsys, schema):
    target = tmp_path / "scene.schema.json"
    assert main(["scene", "schema", "--output", str(target)]) == 0
    assert json.loads(target.read_text()) == json.loads(json.dumps(schema))
    capsys.readouterr()
    assert main(["scene", "schema"]) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(json.dumps(schema))
    assert main(["scene", "schema", "--output", str(tmp_path / "missing" / "x.json")]) == 2
    assert "cannot write the schema" in capsys.readouterr().err


def test_a_run_does_not_replace_a_json_scene_file_with_its_summary(tmp_path):
    from ctmm.scene_files_run import run_scene_file

    data, _ = parse(CHAIN, "TOML")
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(data))
    with pytest.raises(SceneError, match="is a scene file and the summary of this run"):
        run_scene_file(path, tmp_path)
    assert json.loads(path.read_text()) == data
