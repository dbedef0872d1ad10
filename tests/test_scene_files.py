"""Scene files: the shipped files build the systems of the Python scenarios and give the same numbers;
mistakes are refused naming the line, the key and what is allowed; the schema reference is current."""
from __future__ import annotations

import importlib
import re
from pathlib import Path

import numpy as np
import pytest

import ctmm
from ctmm import scene_files_schema as schema
from ctmm.scene_files import SceneError, key_lines, load_scene

FILES = Path(__file__).resolve().parents[1] / "scenarios" / "files"
DOC = Path(__file__).resolve().parents[1] / "docs" / "scene_files.md"


def _scenario(name):
    return importlib.import_module(f"ctmm.scenarios.{name}")


def _parts(system):
    """Every element of a model (a spatial model keeps bodies and joints apart)."""
    return getattr(system, "elements", None) or (*system.bodies, *system.joints)


def _short(scene, t_final=0.05):
    return dict(scene.arguments, t_final=t_final)


def _python_systems():
    """The scenarios' own systems and the arguments their runs use (independent of the files)."""
    from ctmm.planar import ActuatedHinge

    pendulum, hinge, spatial = _scenario("pendulum_chain"), _scenario("hinge_spring_motor"), _scenario("spatial_chain")
    import ctmm.spatial as sp
    from ctmm.elements import Fixed, Free, Mass, Spring

    # spatial_chain and table7_1 build their systems from their files: their former Python construction here
    links = [spatial.link(f"link{k + 1}", m, l) for k, (m, l) in enumerate(zip(spatial.MASSES, spatial.LENGTHS))]
    spatial_model = sp.SpatialModel("spatial_chain", [
        *links,
        sp.Spherical(name="j1", parent=None, child="link1"),
        sp.Revolute(name="j2", parent="link1", point="tip", child="link2", axis=(1, 0, 0)),
        sp.Spherical(name="j3", parent="link2", point="tip", child="link3"),
        sp.Revolute(name="j4", parent="link3", point="tip", child="link4", axis=(0, 1, 1))])
    table = _scenario("table7_1")
    elements = [Fixed("wall")]
    for i in range(5):
        elements.append(Spring(f"K{2 * i + 1}", table.STIFFNESS, free_length=table.FREE_LENGTH))
        elements.append(Mass(f"m{2 * i + 2}", table.MASS, force=table.FORCE if i == 0 else 0.0))
    elements.append(Free("end"))
    q0, v0 = spatial.initial_state()
    motor = ActuatedHinge("motor", kp=200.0, kd=20.0, reference=hinge.reference_angle,
                          reference_rate=hinge.reference_rate)
    names = [f"m{2 * i + 2}" for i in range(5)]
    return {
        "pendulum_chain": (pendulum.model(), dict(method="rk4", x0=np.array([0.3, 0.9, -0.4]), v0=np.zeros(3))),
        "hinge_spring_motor": (hinge.arm(motor), dict(method="rk4", x0=np.array([-np.pi / 2, -np.pi / 2]),
                                                      v0=np.zeros(2))),
        "spatial_chain": (spatial_model, dict(method="rk4", x0=q0, v0=v0)),
        "table7_1": (ctmm.Chain("table7_1", elements),
                     dict(method="newmark", x0={name: 0.1 * (i + 1) for i, name in enumerate(names)})),
    }


@pytest.mark.parametrize("name", ["pendulum_chain", "hinge_spring_motor", "spatial_chain", "table7_1"])
def test_shipped_file_builds_the_scenario_system_with_the_same_numbers(name):
    scene = load_scene(FILES / f"{name}.toml")
    system, arguments = _python_systems()[name]
    assert repr(scene.system) == repr(system)
    assert [repr(e) for e in _parts(scene.system)] == [repr(e) for e in _parts(system)]
    from_file_by_scenario = {"spatial_chain": "model", "table7_1": "build_chain"}.get(name)
    if from_file_by_scenario:                   # the scenario builds its system from the file
        built = getattr(_scenario(name), from_file_by_scenario)()
        assert [repr(e) for e in _parts(built)] == [repr(e) for e in _parts(system)]
    assert scene.arguments["dt"] == 1e-3 and scene.arguments["method"] == arguments["method"]
    from_file = ctmm.simulate(scene.system, 0.05, scene.arguments["dt"], method=scene.arguments["method"],
                              x0=scene.arguments["x0"], v0=scene.arguments.get("v0"))
    from_python = ctmm.simulate(system, 0.05, 1e-3, **arguments)
    assert from_file.signals() == from_python.signals()
    for signal in from_python.time_signals():
        assert np.array_equal(from_file[signal], from_python[signal]), signal
    assert np.ptp(from_file[from_file.time_signals()[0]]) > 0        # the run moved: not a vacuous match


def test_flagship_file_builds_the_manipulator_scene_with_the_same_numbers():
    from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_MOVE, SEED_PZT_GAIN, HubPD, PZTFeedback, manipulator_scene,
                                  scene_references, seed_manipulator)

    scene = load_scene(FILES / "flexible_manipulator.toml")
    arm, pd = seed_manipulator(), HubPD(SEED_KP, SEED_KD)
    system = manipulator_scene(arm, pd=pd, pzt=PZTFeedback.per_patch([SEED_PZT_GAIN] * arm.n_patches))
    assert repr(scene.system) == repr(system)
    assert [repr(e) for e in scene.plant.elements] == [repr(e) for e in system.plant.elements]
    assert [(loop.name, loop.terms, loop.actuator_terms, loop.gain, loop.delay) for loop in scene.system.loops] == \
        [(loop.name, loop.terms, loop.actuator_terms, loop.gain, loop.delay) for loop in system.loops]
    scene.arguments = _short(scene, 0.1)
    from_file = scene.run()
    from_python = ctmm.simulate(system, 0.1, 0.002, method="rk4", store_every=5, outputs=["arm.tip.w"],
                                references=scene_references(pd, SEED_MOVE))
    assert from_file.signals() == from_python.signals()
    for signal in from_python.time_signals():
        assert np.array_equal(from_file[signal], from_python[signal]), signal
    assert np.abs(from_file["arm.tip.w"]).max() > 1e-4


def test_scene_run_equals_the_scenario_run():
    """``Scene.run`` is the verb with the file's arguments (here shortened): same numbers as the scenario."""
    scene = load_scene(FILES / "pendulum_chain.toml")
    scene.arguments = _short(scene)
    system, arguments = _python_systems()["pendulum_chain"]
    assert np.array_equal(scene.run()["b3.theta"], ctmm.simulate(system, 0.05, 1e-3, **arguments)["b3.theta"])


def test_loops_and_frequency_study_match_the_python_scenario():
    common = _scenario("controlled_chain_common")
    scene = load_scene(FILES / "controlled_chain_delay_frequency.toml")
    scene.arguments["omega"] = scene.arguments["omega"][::100]
    system, _ = common.controlled("m2", common.KA, common.DELAY)
    assert repr(scene.system) == repr(system) and scene.system.loops == system.loops
    expected = ctmm.frequency_response(system, np.linspace(0.02, 6.0, 3000)[::100], input="m6.force",
                                       output=["m2.x", "m4.x", "m6.x"])
    response = scene.run()
    assert np.array_equal(response.response, expected.response) and response.outputs == expected.outputs


def _write(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


CHAIN = """[system]
kind = "chain"
name = "c"

[[system.elements]]
type = "Fixed"
name = "wall"

[[system.elements]]
type = "Spring"
name = "k"
stiffness = 100.0

[[system.elements]]
type = "Mass"
name = "m"
mass = 1.0

[[system.elements]]
type = "Free"
name = "end"

[study]
verb = "natural_frequencies"
n_modes = 1
"""


def test_small_scene_runs_natural_frequencies(tmp_path):
    scene = load_scene(_write(tmp_path, CHAIN))
    assert scene.name == "scene" and scene.verb == "natural_frequencies"
    assert np.allclose(scene.run(), [10.0], rtol=1e-10)            # sqrt(k / m)


@pytest.mark.parametrize("old, new, line, key, words", [
    ("mass = 1.0", "mas = 1.0", 17, "system.elements[2].mas", ["unknown key 'mas' of Mass", "allowed keys: name, mass, force"]),
    ('type = "Mass"', 'type = "Mas"', 15, "system.elements[2].type", ["unknown chain element type 'Mas'", "Mass", "Spring"]),
    ('kind = "chain"', 'kind = "chains"', 2, "system.kind", ["chain, planar, planar_chain, spatial", "'chains'"]),
    ("stiffness = 100.0", "", 9, "system.elements[1]", ["Spring needs the key(s) stiffness"]),
    ("mass = 1.0", "mass = -1.0", 17, "system.elements[2].mass", ["Mass: m: mass must be > 0, got -1.0"]),
    ('verb = "natural_frequencies"', 'verb = "simulat"', 24, "study.verb", ["simulate, frequency_response"]),
    ('verb = "natural_frequencies"\nn_modes = 1', 'verb = "simulate"\nt_finale = 1.0\ndt = 0.1', 25,
     "study.t_finale",
     ["unknown key 't_finale' of simulate", "t_final"]),
    ('verb = "natural_frequencies"\nn_modes = 1', 'verb = "simulate"', 23, "study",
     ["simulate needs the key(s) t_final"]),
    ('name = "end"', 'name = "end"\n\n[outputs]\nplot = ["m.x"]', 23, "outputs", ["unknown table 'outputs'",
                                                                               "system, loops, controllers, study, output"]),
    ("mass = 1.0", 'mass = 1.0\nforce = { type = "Harmonc", amplitude = 1.0 }', 18, "system.elements[2].force.type",
     ["unknown value type 'Harmonc'", "Harmonic"]),
    ("mass = 1.0", 'mass = 1.0\nforce = { python = "ctmm.signals:nothing_here" }', 18,
     "system.elements[2].force.python", ["cannot be imported"]),
    ("mass = 1.0", 'mass = 1.0\nforce = { call = "ctmm.signals:Harmonic", amplitud = 1.0, omega = 2.0 }', 18,
     "system.elements[2].force.amplitud", ["unknown key 'amplitud' of ctmm.signals:Harmonic",
                                           "allowed keys: amplitude, omega, phase"]),
    ("mass = 1.0", 'mass = 1.0\nforce = { call = "ctmm.version:__version__", x = 1 }', 18,
     "system.elements[2].force.call", ["'ctmm.version:__version__' is not callable"]),    ("[study]", '[[loops]]\ntype = "Feedback"\nname = "pd"\nsensor = "m.x"\nactuator = "m"\n\n[study]', 23,
     "loops[0]", ["Feedback needs the key(s) gain"]),     # no silent zero-gain (open) loop
])
def test_mistakes_name_line_key_and_allowed_values(tmp_path, old, new, line, key, words):
    assert old in CHAIN
    path = _write(tmp_path, CHAIN.replace(old, new, 1))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    error = info.value
    assert isinstance(error, ctmm.ModelError)
    assert (error.line, error.key) == (line, key), str(error)
    text = str(error)
    assert text.startswith(f"{path}, line {line}, key {key!r}: ")
    for word in words:
        assert word in text


def test_not_toml_bad_name_and_missing_file(tmp_path):
    with pytest.raises(SceneError, match=r"not valid TOML: .*line 3"):
        load_scene(_write(tmp_path, '[system]\nkind = "chain"\nname = \n'))
    with pytest.raises(SceneError, match="must end with .toml, .yaml, .yml, .json"):
        load_scene(tmp_path / "scene.txt")
    with pytest.raises(SceneError, match="cannot read the scene file"):
        load_scene(tmp_path / "missing.toml")
    with pytest.raises(SceneError, match=r"needs a \[study\] table"):
        load_scene(_write(tmp_path, CHAIN.split("[study]")[0]))


def test_value_types_signals_grids_and_transfer_functions(tmp_path):
    text = CHAIN.replace("mass = 1.0", 'mass = 1.0\nforce = { type = "Harmonic", amplitude = 2.0, omega = 3.0 }')
    text = text.replace('verb = "natural_frequencies"\nn_modes = 1', 'verb = "frequency_response"\n'
                        'omega = { type = "logspace", start = 0, stop = 0.9, num = 5 }\ninput = "m.force"\noutput = "m.x"')
    scene = load_scene(_write(tmp_path, text))
    force = scene.system.elements[2].force
    assert force(0.5) == pytest.approx(2.0 * np.sin(1.5), abs=1e-15)
    assert np.array_equal(scene.arguments["omega"], np.logspace(0, 0.9, 5))
    frf = scene.run()
    assert np.allclose(frf.response[0, 0], 1.0 / (100.0 - np.logspace(0, 0.9, 5) ** 2), rtol=1e-12)
    loop = '\n[[loops]]\ntype = "Feedback"\nname = "pd"\nsensor = "m.x"\nactuator = "m"\n' \
           'gain = { type = "TransferFunction", numerator = [2.0, 5.0], denominator = [1.0] }\n'
    scene = load_scene(_write(tmp_path, text.replace("[study]", loop + "\n[study]")))
    assert scene.system.loops[0].gain.num[0][0].tolist() == [2.0, 5.0]


def test_key_lines_tracks_arrays_of_tables_and_skips_multiline_values():
    text = ('[system]\nkind = "x"  # c\n[[system.elements]]\ntype = "A"\nv = [1,\n  {a = 2},\n]\n'
            '[[system.elements]]\n"quoted key" = "[not a table]"\n[study]\nverb = "simulate"\n')
    lines = key_lines(text)
    assert lines[("system", "kind")] == 2 and lines[("system", "elements", 0)] == 3
    assert lines[("system", "elements", 0, "v")] == 5 and ("system", "elements", 0, "a") not in lines
    assert lines[("system", "elements", 1, "quoted key")] == 9 and lines[("study", "verb")] == 11


def test_schema_is_generated_from_the_constructors():
    planar = schema.element_types("planar")
    assert planar["RigidBody"].keys() == ["name", "mass", "inertia", "center_of_mass", "inboard", "outboard", "loads"]
    assert "RigidBody.uniform_link" in planar and "ModalBeam" in planar
    import dataclasses

    from ctmm.spatial import Revolute
    assert set(schema.element_types("spatial")["Revolute"].keys()) == {f.name for f in dataclasses.fields(Revolute)
                                                                         if f.init}
    assert schema.verb("simulate").keys()[:2] == ["t_final", "dt"]


def test_docs_hold_the_generated_schema():
    text = DOC.read_text()
    block = re.search(r"<!-- schema: begin.*?-->\n(.*)<!-- schema: end -->", text, re.S)
    assert block, "docs/scene_files.md lacks the schema markers"
    assert block.group(1) == schema.schema_markdown(), ("docs/scene_files.md is out of date: paste "
                                                        "ctmm.scene_files_schema.schema_markdown() between the markers")


def test_stability_chart_study_matches_the_python_call(tmp_path):
    loop = '\n[[loops]]\ntype = "Feedback"\nname = "pd"\nsensor = "m.x"\nactuator = "m"\ngain = 1.0\ndelay = 0.1\n'
    study = ('verb = "stability_chart"\nx = ["gain", { type = "linspace", start = -50.0, stop = 150.0, num = 6 }]\n'
             'y = ["delay", { type = "linspace", start = 0.0, stop = 0.5, num = 5 }]')
    text = CHAIN.replace("[study]", loop + "\n[study]").replace('verb = "natural_frequencies"\nn_modes = 1', study)
    text = text.replace('type = "Spring"', 'type = "SpringDamper"').replace("stiffness = 100.0",
                                                                          "stiffness = 100.0\ndamping = 2.0")
    scene = load_scene(_write(tmp_path, text))
    chart = scene.run()
    from ctmm.stability import stability_chart
    expected = stability_chart(scene.system, ("gain", np.linspace(-50.0, 150.0, 6)), ("delay", np.linspace(0.0, 0.5, 5)))
    assert np.array_equal(chart.stable, expected.stable) and chart.stable.any() and not chart.stable.all()
