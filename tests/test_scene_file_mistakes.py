"""Scene files edited by hand with mistakes the model's own checks find (a duplicate name, a hinge or joint naming a
body that does not exist, a loop sensing an unknown signal): the error names the line and the key of the mistake,
and ``ctmm run`` prints the whole reason on one line."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ctmm.cli import main
from ctmm.scene_files import SceneError, load_scene

FILES = Path(__file__).resolve().parents[1] / "scenarios" / "files"

CHAIN = """[system]
kind = "chain"
name = "two_mass"

[[system.elements]]
type = "Fixed"
name = "wall"

[[system.elements]]
type = "SpringDamper"
name = "k1"
stiffness = 100.0
damping = 0.5

[[system.elements]]
type = "Mass"
name = "m1"
mass = 1.0

[[system.elements]]
type = "Free"
name = "tip"

[[loops]]
type = "Feedback"
name = "pd"
sensor = "m1.v"
actuator = "m1"
gain = 3.0

[study]
verb = "simulate"
t_final = 0.01
dt = 0.001
"""


def line_of(text: str, fragment: str, occurrence: int = 0) -> int:
    """1-based line of the ``occurrence``-th line holding ``fragment`` (counted by hand, not by ctmm)."""
    return [number for number, line in enumerate(text.splitlines(), start=1) if fragment in line][occurrence]


def mistake(tmp_path: Path, text: str) -> SceneError:
    scene = tmp_path / "scene.toml"
    scene.write_text(text)
    with pytest.raises(SceneError) as caught:
        load_scene(scene)
    return caught.value


def test_duplicate_name_names_the_second_table(tmp_path):
    text = CHAIN.replace('name = "tip"', 'name = "m1"')
    error = mistake(tmp_path, text)
    assert (error.line, error.key) == (line_of(text, 'name = "m1"', 1), "system.elements[3].name")
    assert "duplicate element name 'm1'" in str(error)


@pytest.mark.parametrize("file_name, old, new, key", [
    ("branched_tree.toml", 'parent = "l1"', 'parent = "l9"', "parent"),
    ("branched_tree.toml", 'child = "l2"', 'child = "l9"', "child"),
    ("spatial_chain.toml", 'parent = "link1"', 'parent = "link9"', "parent"),
])
def test_unknown_parent_or_child_names_the_joint_and_its_key(tmp_path, file_name, old, new, key):
    text = (FILES / file_name).read_text()
    assert old in text
    text = text.replace(old, new, 1)
    error = mistake(tmp_path, text)
    assert error.line == line_of(text, new) and error.key.endswith(f"].{key}")
    assert "l9" in str(error) or "link9" in str(error)


@pytest.mark.parametrize("old, new, key", [('sensor = "m1.v"', 'sensor = "m9.v"', "sensor"),
                                           ('actuator = "m1"', 'actuator = "m9"', "actuator")])
def test_loop_naming_an_unknown_signal_names_its_line(tmp_path, old, new, key):
    text = CHAIN.replace(old, new)
    error = mistake(tmp_path, text)
    assert (error.line, error.key) == (line_of(text, new), f"loops[0].{key}")


def test_command_line_prints_the_reason_of_a_model_check_on_one_line(tmp_path, capsys):
    scene = tmp_path / "twice.toml"
    scene.write_text(CHAIN.replace('name = "tip"', 'name = "m1"'))
    assert main(["run", str(scene), "--output", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "duplicate element name 'm1'" in error


PLOTTED = CHAIN + """
[output]
plot = ["m1.x"]
description = "two masses"
"""


@pytest.mark.parametrize("old, new, key", [
    ('plot = ["m1.x"]', 'plot = "m1.x"', "output.plot"),                       # a string, not a list of names
    ('description = "two masses"', "description = 3", "output.description"),
    ('verb = "simulate"\nt_final = 0.01\ndt = 0.001', 'verb = "natural_frequencies"', "output.plot"),   # not drawn
])
def test_output_table_of_the_wrong_form_is_refused_with_its_line(tmp_path, old, new, key):
    text = PLOTTED.replace(old, new)
    error = mistake(tmp_path, text)
    assert (error.line, error.key) == (line_of(text, key.split(".")[1] + " ="), key)


def test_plot_name_the_run_does_not_have_names_its_line(tmp_path, capsys):
    text = PLOTTED.replace('plot = ["m1.x"]', 'plot = ["m1.x", "m9.x"]')
    scene = tmp_path / "plotted.toml"
    scene.write_text(text)
    assert main(["run", str(scene), "--output", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err.strip()
    assert f"line {line_of(text, 'plot =')}, key 'output.plot[1]'" in error and "unknown signal 'm9.x'" in error
    assert not any((tmp_path / "out").iterdir())                # nothing of the failed run is left


@pytest.mark.parametrize("old, new, key", [("dt = 0.001", 'dt = "1 ms"', "study.dt"),            # a unit typed in
                                           ("t_final = 0.01", "t_final = -0.01", "study.t_final"),
                                           ("dt = 0.001", 'dt = 0.001\nmethod = "rk5"', "study.method")])
def test_study_argument_the_verb_refuses_names_its_line(tmp_path, capsys, old, new, key):
    text = CHAIN.replace(old, new)
    scene = tmp_path / "study.toml"
    scene.write_text(text)
    with pytest.raises(SceneError) as caught:
        load_scene(scene).run()
    assert (caught.value.line, caught.value.key) == (line_of(text, key.split(".")[1] + " ="), key)
    assert main(["run", str(scene), "--quick", "--output", str(tmp_path / "out")]) == 1    # --quick alike
    assert f"line {caught.value.line}, key '{key}'" in capsys.readouterr().err


def test_study_argument_in_yaml_names_its_line(tmp_path):
    text = "\n".join(["system:", "  kind: chain", "  name: one", "  elements:", "    - {type: Fixed, name: wall}",
                      "    - {type: Spring, name: k, stiffness: 10.0}", "    - {type: Mass, name: m, mass: 1.0}",
                      "    - {type: Free, name: tip}", "study:", "  verb: simulate", "  t_final: 0.01",
                      "  dt: 1 ms", ""])
    scene = tmp_path / "one.yaml"
    scene.write_text(text)
    with pytest.raises(SceneError) as caught:
        load_scene(scene).run()
    assert (caught.value.line, caught.value.key) == (line_of(text, "dt: 1 ms"), "study.dt")


def test_a_file_that_is_not_utf8_is_a_scene_error_with_its_line(tmp_path, capsys):
    scene = tmp_path / "latin1.toml"
    scene.write_bytes(CHAIN.replace('name = "two_mass"', 'name = "m\u00e4sse"').encode("latin-1"))
    with pytest.raises(SceneError, match="UTF-8") as caught:
        load_scene(scene)
    assert caught.value.line == line_of(CHAIN, 'name = "two_mass"')
    assert main(["run", str(scene), "--output", str(tmp_path / "out")]) == 1
    assert "invalid model or option" in capsys.readouterr().err


def test_a_folder_named_like_a_scene_file_is_a_usage_error_saying_so(tmp_path, capsys):
    (tmp_path / "folder.toml").mkdir()
    assert main(["run", str(tmp_path / "folder.toml"), "--output", str(tmp_path / "out")]) == 2
    assert "is not a file" in capsys.readouterr().err


CONTROLLED = CHAIN.split("[[loops]]")[0] + """[[controllers]]
call = "ctmm.controllers:SaturatedPD"
inputs = ["m1.x", "m1.v"]
outputs = ["m1.force"]
kp = 30.0
kd = 3.0
sample_time = 1e-3

[study]
verb = "simulate"
t_final = 0.01
dt = 0.001
"""


@pytest.mark.parametrize("old, new, key", [('inputs = ["m1.x", "m1.v"]', 'inputs = ["m9.x", "m1.v"]', "inputs"),
                                           ('outputs = ["m1.force"]', 'outputs = ["m9.force"]', "outputs")])
def test_controller_signal_the_system_does_not_have_names_its_line(tmp_path, old, new, key):
    text = CONTROLLED.replace(old, new)
    scene = tmp_path / "controlled.toml"
    scene.write_text(text)
    with pytest.raises(SceneError, match="m9") as caught:
        load_scene(scene).run()
    assert (caught.value.line, caught.value.key) == (line_of(text, new), f"controllers[0].{key}")


def test_fmu_controller_option_the_fmu_refuses_names_its_key_not_the_path(tmp_path):
    import shutil

    if shutil.which("cc") is None:
        pytest.skip("no C compiler")
    pytest.importorskip("fmpy")
    from ctmm.control.fmu import build_fmu
    from ctmm.controllers import fmu_source

    shutil.copy(build_fmu(fmu_source("pd_controller")), tmp_path / "pd.fmu")
    text = CONTROLLED.replace('call = "ctmm.controllers:SaturatedPD"', 'fmu = "pd.fmu"').replace(
        'inputs = ["m1.x", "m1.v"]', 'inputs = { y = "m1.x", ydot = "m1.v" }').replace(
        'outputs = ["m1.force"]', 'outputs = { u = "m1.force" }').replace(
        "kp = 30.0\nkd = 3.0\n", "").replace("sample_time = 1e-3", "sample_time = -1e-3")
    error = mistake(tmp_path, text)
    assert (error.line, error.key) == (line_of(text, "sample_time ="), "controllers[0].sample_time")


def test_quick_runs_a_tenth_of_the_time_from_t0(tmp_path):
    from ctmm.results import load

    scene = tmp_path / "late.toml"
    scene.write_text(CHAIN.replace("t_final = 0.01", "t_final = 1.2\nt0 = 1.0"))
    assert main(["run", str(scene), "--quick", "--save", "--output", str(tmp_path / "out")]) == 0
    stored = load(tmp_path / "out" / "late.h5")
    assert stored.time[0] == 1.0 and stored.time[-1] == pytest.approx(1.0 + 0.2 / 10, abs=1e-12)


@pytest.mark.parametrize("old, new, key", [("t_final = 0.01", 't_final = "10 ms"', "study.t_final")])
def test_quick_leaves_a_wrong_argument_to_the_verb_with_its_line(tmp_path, capsys, old, new, key):
    text = CHAIN.replace(old, new)
    scene = tmp_path / "quick.toml"
    scene.write_text(text)
    assert main(["run", str(scene), "--quick", "--output", str(tmp_path / "out")]) == 1
    assert f"line {line_of(text, new)}, key '{key}'" in capsys.readouterr().err


def test_quick_stability_chart_with_a_malformed_axis_names_its_line(tmp_path, capsys):
    text = (Path(__file__).resolve().parents[1] / "scenarios" / "files" / "delay_oscillator.toml").read_text()
    old = next(line for line in text.splitlines() if line.startswith("x = "))
    text = text.replace(old, 'x = "m.x"')
    scene = tmp_path / "chart.toml"
    scene.write_text(text)
    assert main(["run", str(scene), "--quick", "--output", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err
    line = line_of(text, 'x = "m.x"')
    assert f"line {line}, key 'study.x'" in error and "IndexError" not in error


def test_start_value_of_an_unknown_element_names_the_x0_key(tmp_path):
    text = CHAIN.replace("dt = 0.001", "dt = 0.001\nx0 = { m9 = 0.1 }")
    scene = tmp_path / "start.toml"
    scene.write_text(text)
    with pytest.raises(SceneError, match="unknown element 'm9'") as caught:
        load_scene(scene).run()
    assert (caught.value.line, caught.value.key) == (line_of(text, "x0 ="), "study.x0")


@pytest.mark.parametrize("file_name, old, new", [
    ("four_bar.toml", 'parent = "rocker.out"', 'parent = "rockr.out"'),
    ("spatial_four_bar.toml", 'parent = "rocker", point = "tip", child = "coupler"',
     'parent = "rockr", point = "tip", child = "coupler"'),
])
def test_cut_joint_naming_an_unknown_body_names_the_cuts_line(tmp_path, file_name, old, new):
    text = (FILES / file_name).read_text()
    assert old in text
    text = text.replace(old, new, 1)
    error = mistake(tmp_path, text)
    assert error.line == line_of(text, new) and error.key == "system.cuts[0]" and "rockr" in str(error)


def test_an_option_natural_frequencies_does_not_take_names_its_line(tmp_path, capsys):
    text = CHAIN.split("[[loops]]")[0] + '[study]\nverb = "natural_frequencies"\nn_mode = 1\n'
    scene = tmp_path / "modes.toml"
    scene.write_text(text)
    assert main(["run", str(scene), "--output", str(tmp_path / "out")]) == 1
    error = capsys.readouterr().err
    assert f"line {line_of(text, 'n_mode =')}, key 'study.n_mode'" in error and "unknown option 'n_mode'" in error


YAML_CHAIN = "\n".join(["system:", "  kind: chain", "  name: one", "  elements:", "    - {type: Fixed, name: wall}",
                        "    - {type: SpringDamper, name: k, stiffness: 10.0, damping: 0.5, free_length: null}",
                        "    - {type: Mass, name: m, mass: 1.0}", "    - {type: Free, name: tip}",
                        "study:", "  verb: simulate", "  t_final: 0.01", ""])


def test_a_yaml_or_json_null_is_a_left_out_key(tmp_path):
    """docs/scene_files.md: a null is the same as leaving the key out -- the parameter's default applies, and a
    required key is missing."""
    import json

    from ctmm.elements import SpringDamper
    from ctmm.scene_files_syntax import parse

    scene = tmp_path / "nulls.yaml"
    scene.write_text(YAML_CHAIN)
    assert repr(load_scene(scene).system.elements[1]) == repr(SpringDamper("k", 10.0, 0.5))   # free_length: default
    as_json = tmp_path / "nulls.json"
    as_json.write_text(json.dumps({**parse(YAML_CHAIN.replace(", free_length: null", ""), "YAML")[0],
                                   "output": None}))
    assert repr(load_scene(as_json).system.elements[1]) == repr(SpringDamper("k", 10.0, 0.5))
    scene.write_text(YAML_CHAIN.replace("mass: 1.0", "mass: null"))
    with pytest.raises(SceneError, match=r"Mass needs the key\(s\) mass"):
        load_scene(scene)


def test_lines_inside_a_multi_line_string_are_not_read_as_tables_or_keys(tmp_path):
    """A triple-quoted description holding a line that looks like a table header (and an escaped quote): the keys
    after it keep their own lines (it shifted every later [[system.elements]] by one table)."""
    import tomllib

    text = ('[output]\ndescription = """\nnotes: "quoted \\" [x = 1\n[[system.elements]]\nmass = 3\n"""\n\n'
            + CHAIN.replace("mass = 1.0", "mas = 1.0"))
    assert tomllib.loads(text)["output"]["description"].count("[[system.elements]]") == 1     # valid TOML
    error = mistake(tmp_path, text)
    assert (error.line, error.key) == (line_of(text, "mas = 1.0"), "system.elements[2].mas")


def test_an_object_that_is_no_controller_names_its_controllers_table(tmp_path):
    text = CHAIN.split("[[loops]]")[0] + '[[controllers]]\npython = "math:pi"\n\n' + "[study]" + \
        CHAIN.split("[study]")[1]
    scene = tmp_path / "pi.toml"
    scene.write_text(text)
    with pytest.raises(SceneError, match="Controller protocol") as caught:
        load_scene(scene).run()
    assert (caught.value.line, caught.value.key) == (line_of(text, "[[controllers]]"), "controllers[0]")


@pytest.mark.parametrize("numerator, denominator, key", [("[]", "[1.0]", "numerator"),      # not a zero controller
                                                         ("[1.0, true]", "[1.0, 2.0]", "numerator"),
                                                         ("[1.0]", "[0.0, 0.0]", "denominator")])
def test_a_transfer_function_gain_without_coefficients_is_refused(tmp_path, numerator, denominator, key):
    gain = f'gain = {{ type = "TransferFunction", numerator = {numerator}, denominator = {denominator} }}'
    text = CHAIN.replace("gain = 3.0", gain)
    error = mistake(tmp_path, text)
    assert (error.line, error.key) == (line_of(text, gain), f"loops[0].gain.{key}")


def test_a_transfer_function_gain_is_python_controls(tmp_path):
    import control

    scene = tmp_path / "lead.toml"
    scene.write_text(CHAIN.replace("gain = 3.0", 'gain = { type = "TransferFunction", numerator = [2.0, 1.0], '
                                                 "denominator = [0.1, 1.0] }"))
    gain = load_scene(scene).system.loops[0].gain
    reference = control.tf([2.0, 1.0], [0.1, 1.0])
    assert np.array_equal(gain.num[0][0], reference.num[0][0]) and np.array_equal(gain.den[0][0], reference.den[0][0])
