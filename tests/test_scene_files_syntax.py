"""Scene files in YAML (same tables, errors with the line of the key) and co-simulated controllers in scene files
(a Python controller by ``call = "module:attribute"``, an FMU by a path relative to the scene file)."""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

import ctmm
from ctmm.scene_files import SceneError, load_scene

FILES = Path(__file__).resolve().parents[1] / "scenarios" / "files"

YAML = """system:
  kind: chain
  name: c
  elements:
    - type: Fixed
      name: wall
    - type: Spring
      name: k
      stiffness: 100.0
    - type: Mass
      name: m
      mass: 1.0
    - type: Free
      name: end
study:
  verb: natural_frequencies
  n_modes: 1
"""


def _write(folder, text, name):
    path = folder / name
    path.write_text(text)
    return path


def test_yaml_file_builds_the_same_scene_as_the_toml_file():
    pytest.importorskip("yaml")
    from_yaml, from_toml = load_scene(FILES / "pendulum_chain_yaml.yaml"), load_scene(FILES / "pendulum_chain.toml")
    assert [repr(e) for e in from_yaml.system.elements] == [repr(e) for e in from_toml.system.elements]
    assert from_yaml.arguments == from_toml.arguments and from_yaml.arguments["dt"] == 1e-3   # "1e-3" is a number
    short = dict(from_toml.arguments, t_final=0.02)
    a, b = ctmm.simulate(from_yaml.system, **short), ctmm.simulate(from_toml.system, **short)
    assert np.array_equal(a["b3.theta"], b["b3.theta"]) and np.ptp(a["b3.theta"]) > 0


def test_small_yaml_scene_runs(tmp_path):
    pytest.importorskip("yaml")
    scene = load_scene(_write(tmp_path, YAML, "scene.yml"))
    assert scene.name == "scene" and np.allclose(scene.run(), [10.0], rtol=1e-10)          # sqrt(k / m)


@pytest.mark.parametrize("old, new, line, key, words", [
    ("mass: 1.0", "mas: 1.0", 12, "system.elements[2].mas", ["unknown key 'mas' of Mass", "allowed keys: name, mass"]),
    ("type: Mass", "type: Mas", 10, "system.elements[2].type", ["unknown chain element type 'Mas'"]),
    ("stiffness: 100.0", "stiffness: -100.0", 9, "system.elements[1].stiffness", ["Spring"]),
    ("  n_modes: 1", "  n_modes: 1\noutputs:\n  plot: [m.x]", 18, "outputs", ["unknown table 'outputs'"]),
    ("verb: natural_frequencies", "verb: simulat", 16, "study.verb", ["simulate, frequency_response"]),
])
def test_yaml_mistakes_name_line_and_key(tmp_path, old, new, line, key, words):
    pytest.importorskip("yaml")
    assert old in YAML
    path = _write(tmp_path, YAML.replace(old, new, 1), "scene.yaml")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert (info.value.line, info.value.key) == (line, key), str(info.value)
    assert str(info.value).startswith(f"{path}, line {line}, key {key!r}: ")
    for word in words:
        assert word in str(info.value)


def test_yaml_syntax_errors_and_missing_pyyaml(tmp_path, monkeypatch):
    pytest.importorskip("yaml")
    with pytest.raises(SceneError, match=r"not valid YAML: .*line 3"):
        load_scene(_write(tmp_path, "system:\n  kind: chain\n  name: [c\n", "bad.yaml"))
    with pytest.raises(SceneError, match=r"duplicate key 'mass' at line 13 \(first at line 12\)"):
        load_scene(_write(tmp_path, YAML.replace("mass: 1.0", "mass: 1.0\n      mass: 2.0"), "twice.yaml"))
    with pytest.raises(SceneError, match="the key at line 1 is not a name"):
        load_scene(_write(tmp_path, "? [a, b]\n: 1\n", "key.yaml"))
    with pytest.raises(SceneError, match=r"line 19, key 'loops\[0\]': a loop must be a table with a 'type' \(Feedback\)"):
        load_scene(_write(tmp_path, YAML + "loops:\n  - 1\n", "loop.yaml"))
    with pytest.raises(SceneError, match="a scene file holds the tables system, loops"):
        load_scene(_write(tmp_path, "- 1\n- 2\n", "list.yaml"))
    monkeypatch.setitem(sys.modules, "yaml", None)                        # as if PyYAML were not installed
    with pytest.raises(SceneError, match=r"YAML scene files need PyYAML: pip install 'ctmm\[scenes\]'"):
        load_scene(_write(tmp_path, YAML, "scene.yaml"))


def _tables(*elements: str) -> str:
    """``[[system.elements]]`` tables from ``"Type name key=value ..."`` lines."""
    text = ""
    for element in elements:
        kind, name, *pairs = element.split()
        text += f'[[system.elements]]\ntype = "{kind}"\nname = "{name}"\n' + "".join(
            f"{pair.replace('=', ' = ')}\n" for pair in pairs) + "\n"
    return text


CHAIN = ('[system]\nkind = "chain"\nname = "two_mass"\n\n'
         + _tables("Fixed wall", "SpringDamper k1 stiffness=40.0 damping=0.4", "Mass m1 mass=1.0",
                   "SpringDamper k2 stiffness=40.0 damping=0.4", "Mass m2 mass=0.5", "Free end")
         + 'CONTROLLER\n[study]\nverb = "simulate"\nt_final = 0.5\ndt = 0.001\nx0 = { m2 = 0.05 }\n')

PYTHON_CONTROLLER = """[[controllers]]
call = "ctmm.controllers:SaturatedPD"
inputs = ["m2.x", "m2.v"]
outputs = ["m1.force"]
kp = 30.0
kd = 3.0
limit = 1.0
sample_time = 0.001
"""


def _python_pd():
    from ctmm.controllers import SaturatedPD

    return SaturatedPD(("m2.x", "m2.v"), ("m1.force",), kp=30.0, kd=3.0, limit=1.0, sample_time=0.001)


def test_python_controller_in_a_scene_file_gives_the_python_run(tmp_path):
    scene = load_scene(_write(tmp_path, CHAIN.replace("CONTROLLER", PYTHON_CONTROLLER), "pd.toml"))
    (controller,) = scene.arguments["controllers"]
    assert repr(controller) == repr(_python_pd())
    from_file = scene.run()
    from_python = ctmm.simulate(scene.system, 0.5, 0.001, x0={"m2": 0.05}, controllers=[_python_pd()])
    assert np.array_equal(from_file["m2.x"], from_python["m2.x"])
    free = ctmm.simulate(scene.system, 0.5, 0.001, x0={"m2": 0.05})
    assert not np.allclose(from_file["m2.x"], free["m2.x"])                 # the controller acted


@pytest.mark.parametrize("controller, line, key, words", [
    (PYTHON_CONTROLLER.replace("kd = 3.0", "kdd = 3.0"), 40, "controllers[0].kdd",
     ["unknown key 'kdd' of ctmm.controllers:SaturatedPD", "kp, kd"]),
    ('[[controllers]]\nfmu = "missing/pd.fmu"\ninputs = { y = "m2.x" }\n', 36, "controllers[0].fmu",
     ["FMU not found: 'missing/pd.fmu'", "relative to the scene file's folder"]),
    ('[[controllers]]\nkp = 1.0\n', 35, "controllers[0]", ["needs exactly one of the keys fmu", "got ['kp']"]),
    ('[[controllers]]\ncall = "ctmm.controllers:NoSuchController"\n', 36, "controllers[0].call", ["cannot be imported"]),
])
def test_controller_mistakes_name_line_and_key(tmp_path, controller, line, key, words):
    path = _write(tmp_path, CHAIN.replace("CONTROLLER", controller), "pd.toml")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert (info.value.line, info.value.key) == (line, key), str(info.value)
    for word in words:
        assert word in str(info.value)


def test_controllers_once_and_in_a_simulate_study(tmp_path):
    both = CHAIN.replace("CONTROLLER", PYTHON_CONTROLLER).replace(
        "x0 = { m2 = 0.05 }", 'x0 = { m2 = 0.05 }\ncontrollers = { python = "ctmm.controllers:SaturatedPD" }')
    with pytest.raises(SceneError, match="either as \\[\\[controllers\\]\\] tables or as \\[study\\] controllers"):
        load_scene(_write(tmp_path, both, "pd.toml"))
    text = CHAIN.replace("CONTROLLER", PYTHON_CONTROLLER).replace(
        'verb = "simulate"\nt_final = 0.5\ndt = 0.001\nx0 = { m2 = 0.05 }', 'verb = "natural_frequencies"')
    with pytest.raises(SceneError, match="co-simulated .*must be simulate, got 'natural_frequencies'"):
        load_scene(_write(tmp_path, text, "pd.toml"))


def test_fmu_controller_path_relative_to_the_scene_file(tmp_path):
    pytest.importorskip("fmpy")
    if not shutil.which("gcc"):
        pytest.skip("gcc builds the test FMU")
    from ctmm import controllers
    from ctmm.control.fmu import FMUController, build_fmu

    fmu = build_fmu(controllers.fmu_source("pd_controller"), tmp_path / "fmus", compiler="gcc")
    relative = fmu.relative_to(tmp_path).as_posix()
    text = CHAIN.replace("CONTROLLER", f'''[[controllers]]
fmu = "{relative}"
inputs = {{ y = "m2.x", ydot = "m2.v" }}
outputs = {{ u = "m1.force" }}
parameters = {{ kp = 30.0, kd = 3.0 }}
sample_time = 0.001
''')
    scene = load_scene(_write(tmp_path, text, "fmu_pd.toml"))
    from_file = scene.run()
    python = FMUController(fmu, inputs={"y": "m2.x", "ydot": "m2.v"}, outputs={"u": "m1.force"},
                           parameters={"kp": 30.0, "kd": 3.0}, sample_time=0.001)
    from_python = ctmm.simulate(scene.system, 0.5, 0.001, x0={"m2": 0.05}, controllers=[python])
    assert np.array_equal(from_file["m2.x"], from_python["m2.x"])
    free = ctmm.simulate(scene.system, 0.5, 0.001, x0={"m2": 0.05})
    assert not np.allclose(from_file["m2.x"], free["m2.x"])                 # the FMU acted
