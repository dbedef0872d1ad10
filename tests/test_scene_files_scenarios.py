"""Every shipped scenario's system as a scene file: the file builds the scenario's own Python system (element by
element, loop by loop) and gives the same numbers on a short run, a few frequency-response points or a small
stability chart; ``ctmm run`` runs the files."""
from __future__ import annotations

import importlib
import re
from pathlib import Path

import numpy as np
import pytest

import ctmm
from ctmm.scene_files import load_scene

FILES = Path(__file__).resolve().parents[1] / "scenarios" / "files"
SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


def _scenario(name):
    return importlib.import_module(f"ctmm.scenarios.{name}")


def _parts(system):
    """Every element of a model (a spatial model keeps bodies and joints apart; loops keep their plant or tree)."""
    system = getattr(system, "plant", system)
    system = getattr(system, "tree", system)
    return getattr(system, "elements", None) or (*system.bodies, *system.joints)


def _loops(system):
    return [(loop.name, loop.terms, loop.actuator_terms, loop.gain, loop.delay) for loop in getattr(system, "loops", ())]


def _text(element):
    """An element's repr without the addresses of the functions it holds (two builds of one closure differ there;
    the runs compare what the functions give)."""
    return re.sub(r" at 0x[0-9a-f]+", "", repr(element))


def _same_elements(scene, system):
    assert type(scene.system) is type(system)
    assert [_text(e) for e in _parts(scene.system)] == [_text(e) for e in _parts(system)]
    assert _loops(scene.system) == _loops(system)
    assert [repr(cut) for cut in getattr(scene.system, "cuts", ())] == [repr(cut) for cut in getattr(system, "cuts", ())]


def _same_run(scene, system, steps=20, **arguments):
    """A few steps of the file's study (its dt and method) on both systems: bit for bit."""
    short = dict(scene.arguments, t_final=steps * scene.arguments["dt"], **arguments)
    from_file = ctmm.simulate(scene.system, **short)
    from_python = ctmm.simulate(system, **short)
    assert from_file.signals() == from_python.signals()
    for signal in from_python.time_signals():
        assert np.array_equal(from_file[signal], from_python[signal]), signal
    moved = [np.ptp(from_file[s]) for s in from_file.time_signals()]
    assert max(moved) > 0.0                                        # the run moved: not a vacuous match
    return from_file


def _same_frequency_response(scene, system, every=200):
    omega = np.asarray(scene.arguments["omega"])[::every]
    arguments = dict(scene.arguments, omega=omega)
    from_file, from_python = ctmm.frequency_response(scene.system, **arguments), ctmm.frequency_response(system, **arguments)
    assert from_file.outputs == from_python.outputs and np.array_equal(from_file.response, from_python.response)
    assert np.abs(from_file.response).max() > 0.0


def _same_chart(scene, system, every=25):
    from ctmm.stability_chart import stability_chart

    axes = {}
    for axis in ("x", "y"):
        spec = list(scene.arguments[axis])
        spec[1] = np.asarray(spec[1])[::every]
        axes[axis] = tuple(spec)
    from_file, from_python = stability_chart(scene.system, **axes), stability_chart(system, **axes)
    assert np.array_equal(from_file.stable, from_python.stable) and from_file.stable.any()


def _chain(name):
    common = _scenario("controlled_chain_common")
    return {
        "controlled_chain_frequency": lambda: common.controlled("m2", common.KA)[0],
        "controlled_chain_across": lambda: common.controlled("K3", common.KA)[0],
        "controlled_chain_time": lambda: common.controlled("m2", common.KA, common.DELAY)[0],
        "delay_chain_chart": lambda: common.controlled("m2", common.KA, common.DELAY)[0],
        "pd_tuning": lambda: _scenario("pd_tuning").system_with(common.KA, 0.0),
        "delay_oscillator": lambda: _scenario("delay_oscillator").system(),
        "delay_pd_single_mass": lambda: _scenario("delay_pd_single_mass").system(),
        "delay_hub_beam_chart": _hub_pd,
    }[name]()


def _hub_pd():
    """The plant and hub loop of ``delay_hub_beam_chart`` (its chart runs on the exact fields of this plant)."""
    from ctmm.control import Feedback, with_feedback
    from ctmm.manipulator import manipulator_plant
    from ctmm.manipulator.parameters import SEED_KD, SEED_KP, seed_manipulator

    loop = Feedback("pd", [("motor.angle", SEED_KP), ("motor.rate", SEED_KD)], "motor.torque", gain=1.0, delay=0.01)
    return with_feedback(manipulator_plant(seed_manipulator()), [loop])


@pytest.mark.parametrize("name, check", [("controlled_chain_frequency", _same_frequency_response),
                                         ("controlled_chain_across", _same_frequency_response),
                                         ("pd_tuning", _same_frequency_response), ("delay_chain_chart", _same_chart),
                                         ("delay_hub_beam_chart", _same_frequency_response),
                                         ("delay_oscillator", _same_chart), ("delay_pd_single_mass", _same_chart)])
def test_chain_files_give_the_scenario_numbers(name, check):
    scene = load_scene(FILES / f"{name}.toml")
    system = _chain(name)
    _same_elements(scene, system)
    check(scene, system)


def test_controlled_chain_time_file():
    scene = load_scene(FILES / "controlled_chain_time.toml")
    system = _chain("controlled_chain_time")
    _same_elements(scene, system)
    assert scene.arguments["x0"] == {"m6": 0.1} and scene.arguments["dt"] == 0.01
    _same_run(scene, system)


def _thetas(name):
    """The scenario's start vector as its ``run`` computes it (angles of its links, the rest 0)."""
    scenario = _scenario(name)
    names = scenario.model().coordinates
    q0 = np.zeros(len(names))
    if name == "fem_chain":
        q0[[names.index(c) for c in names if c.endswith(".theta")]] = scenario.INITIAL_ANGLE
    elif name == "particle_chain":
        q0[[names.index("body2.theta"), names.index("body6.theta")]] = scenario.INITIAL
    else:
        q0[[names.index(f"{b}.theta") for b in scenario.BODY_NAMES]] = scenario.INITIAL_ANGLE
    return q0


def _spin_up_sag():
    scenario = _scenario("spatial_spin_up")
    return scenario.static_sag(scenario.reference(True))


def _elastic_hinge():
    from ctmm.control import with_feedback

    return with_feedback(_python_elastic_hinge_plant(), [_scenario("spatial_elastic_hinge_control").loop()])


def _robot_arm():
    from ctmm.control import with_feedback

    scenario = _scenario("spatial_robot_arm")
    return with_feedback(_python_robot_arm_plant(), scenario.loops(scenario.DELAY))


def _four_bar_start():
    scenario = _scenario("four_bar")
    return scenario.start(scenario.mechanism(scenario.SPRING + scenario.DAMPER))


def _spatial_four_bar_start():
    scenario = _scenario("spatial_four_bar")
    return scenario.start(scenario.mechanism())


def _planar_and_spatial():
    """``file: (the scenario's Python system, the scenario's run arguments the file must hold)``."""
    branch, hub, rotary = _scenario("branch_system"), _scenario("hub_beam"), _scenario("rotary_base_segments")
    q_branch, v_branch = branch.initial_state()
    return {
        "branched_tree": (None, dict(dt=1e-3, method="rk4", x0=[0.4, 1.0, 0.2, 0.0, -0.6])),
        "branch_system": (None, dict(dt=1e-3, method="rk4", x0=q_branch.tolist(), v0=v_branch.tolist())),
        "nonlinear_spring": (lambda: _scenario("nonlinear_spring").link(
            _scenario("nonlinear_spring").LAWS["hardening K2 = +60"] + _scenario("nonlinear_spring").DAMPER),
            dict(dt=1e-3, method="rk4", x0={"l.theta": 0.8})),
        "hub_beam": (hub.model, dict(dt=1e-3, method="rk4", store_every=5)),
        "hub_beam_tip_body": (lambda: hub.model(tip_mass=0.2), dict(dt=1e-3, method="rk4", store_every=5)),
        "single_link": (None, dict(dt=1e-3, method="newmark")),
        "spin_up": (_scenario("spin_up").model, dict(dt=5e-3, method="rk4")),
        "rotary_base_segments": (lambda: rotary.model(10), dict(dt=rotary.STEPS[10], method="rk4")),
        "finite_segments_modal": (None, dict(dt=1e-3, method="newmark", store_every=10)),
        "fem_chain": (None, dict(dt=2.5e-4, method="rk4", x0=_thetas("fem_chain"))),
        "particle_chain": (None, dict(dt=5e-4, method="rk4", x0=_thetas("particle_chain"))),
        "plate_chain": (_scenario("plate_chain").model, dict(dt=2.5e-4, method="rk4", x0=_thetas("plate_chain"))),
        "four_bar": (lambda: _scenario("four_bar").mechanism(_scenario("four_bar").SPRING + _scenario("four_bar").DAMPER),
                     dict(dt=1e-3, method="rk4", x0=list(_four_bar_start()[0]), v0=list(_four_bar_start()[1]))),
        "spatial_hub_beam": (_scenario("spatial_hub_beam").model, dict(dt=5e-5, method="rk4", store_every=20)),
        "spatial_hub_beam_tip_body": (lambda: _scenario("spatial_hub_beam").model(tip_mass=0.2),
                                      dict(dt=5e-5, method="rk4", store_every=20)),
        "spatial_spin_up": (lambda: _scenario("spatial_spin_up").model(True, _scenario("spatial_spin_up").FULL),
                            dict(dt=1e-2, method="rk4", x0=_spin_up_sag())),
        "spatial_elastic_hinge_control": (_elastic_hinge, dict(dt=1e-3, x0=list(_scenario(
            "spatial_elastic_hinge_control").initial_state()[0]), outputs=["body.angle_z"])),
        "spatial_robot_arm": (_robot_arm, dict(dt=1e-3, x0=list(_scenario("spatial_robot_arm").initial_state()[0]))),
        "particle_net": (None, dict(dt=5e-4, method="rk4", x0=_thetas("particle_net"))),
        "flexible_manipulator_3d": (lambda: _scenario("flexible_manipulator_3d").controlled(True),
                                    dict(dt=2e-3, method="rk4", store_every=5)),
        "spatial_four_bar": (_scenario("spatial_four_bar").mechanism, dict(dt=1e-3, method="rk4", x0=list(
            _spatial_four_bar_start()[0]), v0=list(_spatial_four_bar_start()[1]))),
        "spatial_fem_chain": (_scenario("spatial_fem_chain").model,
                              dict(dt=5e-4, method="rk4", x0=_scenario("spatial_fem_chain").INITIAL,
                                   v0=_scenario("spatial_fem_chain").INITIAL_RATE)),
    }


SIMULATED = list(_planar_and_spatial())


@pytest.mark.parametrize("name", SIMULATED)
def test_simulated_files_give_the_scenario_numbers(name):
    build, expected = _planar_and_spatial()[name]
    scene = load_scene(FILES / f"{name}.toml")
    if build is None:
        build = _python_builders()[name]
    system = build()
    _same_elements(scene, system)
    for key, value in expected.items():
        given = scene.arguments[key]
        if isinstance(given, dict) and not isinstance(value, dict):      # {coordinate: value} against a vector
            given = [given.get(name, 0.0) for name in scene.system.coordinates]
        assert np.array_equal(given, value) if not isinstance(value, dict) else given == value, key
    _same_run(scene, system, store_every=1)


def _python_builders():
    """Systems written in Python here: one a scenario builds inside its ``run``, and those of the scenarios whose
    ``model()`` loads its scene file (their former Python construction, the independent side of the check)."""
    from ctmm.flexible import ModalBeam
    from ctmm.planar import Fixed, Load, PlanarModel

    segments = _scenario("finite_segments")
    beam = ModalBeam("beam", n_modes=6, loads=(Load(point=(1.0, 0.0), force_y=segments.FORCE),), **segments.BEAM)
    return {"finite_segments_modal": lambda: PlanarModel.chain("modal", [Fixed("ground"), beam], gravity=(0.0, 0.0)),
            "branched_tree": _python_branched_tree, "branch_system": _python_branch_system,
            "fem_chain": _python_fem_chain, "particle_chain": _python_particle_chain,
            "single_link": _python_single_link, "particle_net": _python_particle_net,
            "spatial_elastic_hinge_control": _python_elastic_hinge_plant, "spatial_robot_arm": _python_robot_arm_plant}


def _python_single_link():
    from ctmm.flexible import ModalBeam
    from ctmm.flexible.outputs import spinup_law
    from ctmm.planar import DrivenHinge, Fixed, PlanarModel

    angle, rate, acceleration = spinup_law(4.0, 2.0)
    return PlanarModel.chain("single_link", [
        Fixed("base"), DrivenHinge("motor", angle=angle, rate=rate, acceleration=acceleration),
        ModalBeam("link", **_scenario("single_link").LINK)], gravity=(0.0, 0.0))


def _python_particle_net():
    from ctmm.planar import Pinned, PlanarModel, RigidBody, SmoothHinge
    from ctmm.planar.elements import FixedMounting

    s = _scenario("particle_net")
    links = [RigidBody.uniform_link(name, mass=m, length=s.LINK) for name, m in zip(s.BODY_NAMES, s.MASSES)]
    items = [Pinned("base"), links[0]]
    for k, link in enumerate(links[1:]):
        items += [SmoothHinge(f"h{k + 2}"), link]
    return PlanarModel.chain(s.NAME, items + [FixedMounting("weld"), s.net_subsystem()])


def _python_elastic_hinge_plant():
    import ctmm.spatial as sp

    s = _scenario("spatial_elastic_hinge_control")
    return sp.SpatialModel("hinge_body", [
        sp.SpatialBody("body", s.MASS, np.diag(s.INERTIA), center_of_mass=s.COM),
        sp.Elastic6(name="hinge", parent=None, child="body", stiffness=s.stiffness(), damping=np.diag(s.DAMPING),
                    actuated=True)], gravity=s.GRAVITY)


def _python_robot_arm_plant():
    import ctmm.spatial as sp

    s = _scenario("spatial_robot_arm")
    names = list(s.BODIES)
    bodies = [sp.SpatialBody(name, mass, inertia, center_of_mass=com, points={"tip": tip} if name != "hand" else
                             {"tcp": tip}) for name, (mass, inertia, com, tip) in s.BODIES.items()]
    joints = [sp.Revolute(name=joint, parent=None if k == 0 else names[k - 1], point=None if k == 0 else "tip",
                          child=names[k], axis=axis, actuated=True)
              for k, (joint, axis) in enumerate(zip(s.JOINTS, s.AXES))]
    joints.append(sp.Spherical(name="wrist", parent="fore", point="tip", child="hand", actuated=True))
    return sp.SpatialModel("robot_arm", bodies + joints, gravity=s.GRAVITY)


def _python_branched_tree():
    from ctmm.planar import ElasticHinge, Pinned, PlanarModel, RigidBody, SmoothHinge

    trunk = RigidBody("trunk", mass=2.0, inertia=0.3, center_of_mass=(0.6, 0.0),
                      outboard={"left": (1.2, 0.3), "right": (1.1, -0.3)})
    links = [RigidBody.uniform_link(n, mass=m, length=l) for n, m, l in
             (("l1", 0.8, 0.8), ("l2", 0.5, 0.6), ("r1", 0.7, 0.7), ("r2", 0.4, 0.5))]
    return PlanarModel("tree", [trunk, *links, Pinned("root", child="trunk"),
                                SmoothHinge("hl1", parent="trunk.left", child="l1"),
                                SmoothHinge("hl2", parent="l1", child="l2"),
                                ElasticHinge("kr1", parent="trunk.right", child="r1", stiffness=15.0, rest_angle=-0.5),
                                ElasticHinge("kr2", parent="r1", child="r2", stiffness=6.0, rest_angle=0.4)])


def _python_branch_system():
    import ctmm.spatial as sp

    link = _scenario("spatial_chain").link
    bodies = [link(name, mass, length) for name, mass, length in _scenario("branch_system").BODIES]
    trunk = bodies[0]
    bodies[0] = sp.SpatialBody(trunk.name, trunk.mass, trunk.inertia, trunk.center_of_mass,
                               {"left": (0.3, 0.0, -0.8), "right": (-0.3, 0.0, -0.8)})
    return sp.SpatialModel("branch_system", [
        *bodies,
        sp.Spherical(name="j1", parent=None, child="e1"),
        sp.Universal(name="j2", parent="e1", point="left", child="e2", axis1=(1, 0, 0), axis2=(0, 1, 0)),
        sp.Revolute(name="j3", parent="e2", point="tip", child="e3", axis=(0, 1, 0)),
        sp.Spherical(name="j4", parent="e1", point="right", child="e4"),
        sp.Revolute(name="j5", parent="e4", point="tip", child="e5", axis=(1, 1, 0)),
        sp.Revolute(name="j6", parent="e5", point="tip", child="e6", axis=(1, 0, 0))])


def _python_fem_chain():
    from ctmm.fem import BeamElement, FiniteElementModel
    from ctmm.planar import Pinned, PlanarModel, RigidBody, SmoothHinge

    scenario = _scenario("fem_chain")
    b = scenario.BEAM
    le = b["length"] / b["elements"]
    nodes = {f"n{k}": (k * le, 0.0) for k in range(b["elements"] + 1)}
    fe = FiniteElementModel("beam1", nodes, [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", b["bending_stiffness"],
                                                         b["axial_stiffness"], b["mass_per_length"])
                                             for k in range(b["elements"])], rayleigh=scenario.RAYLEIGH)
    beam = fe.subsystem("beam1", ("n0", f"n{b['elements']}"))
    links = [RigidBody.uniform_link(f"body{k + 1}", mass=m, length=scenario.LINK) for k, m in enumerate(scenario.MASSES)]
    items = [Pinned("base"), links[0], SmoothHinge("h2"), links[1], SmoothHinge("h3"), links[2],
             SmoothHinge("connection"), beam, SmoothHinge("h4"), links[3], SmoothHinge("h5"), links[4]]
    return PlanarModel.chain("fem_chain", items)


def _python_particle_chain():
    from ctmm.fem import FiniteElementModel, NodeSpring, PointMass
    from ctmm.planar import Pinned, PlanarModel, RigidBody, SmoothHinge
    from ctmm.planar.elements import FixedMounting

    s = _scenario("particle_chain")
    elements = [PointMass(f"m_{p}", p, s.PARTICLE_MASS) for p in s.PARTICLES]
    elements += [NodeSpring(f"k{i}", a, b, s.STIFFNESS) for i, (a, b) in enumerate(s.SPRINGS)]
    fe = FiniteElementModel("net", {**s.ANCHORS, **s.PARTICLES}, elements)
    net = fe.subsystem("net", boundary=("hub", "p5"), frame_nodes=("a_up", "a_down"))
    return PlanarModel.chain(s.NAME, [Pinned("base"), RigidBody.uniform_link("body2", mass=s.BODY2[1], length=s.BODY2[0]),
                                      FixedMounting("weld"), net, SmoothHinge("h6"),
                                      RigidBody.uniform_link("body6", mass=s.BODY6[1], length=s.BODY6[0])])


@pytest.mark.parametrize("name", ["branched_tree", "branch_system", "fem_chain", "particle_chain", "single_link",
                                  "particle_net", "spatial_elastic_hinge_control", "spatial_robot_arm"])
def test_scenarios_built_from_their_files(name):
    """These scenarios' ``model()`` loads the file: the same elements as the Python construction above."""
    model, python = _scenario(name).model(), _python_builders()[name]()
    assert [_text(e) for e in _parts(model)] == [_text(e) for e in _parts(python)]


def test_finite_segments_file_gives_the_scenario_frequencies():
    scene = load_scene(FILES / "finite_segments.toml")
    system = _scenario("finite_segments").segment_model(10)
    _same_elements(scene, system)
    assert np.array_equal(scene.run(), ctmm.natural_frequencies(system, n_modes=3))


def _scenario_names():
    return sorted(path.stem for path in SCENARIOS.glob("*.py")
                  if any(line.startswith("NAME = ") for line in path.read_text().splitlines()))


def test_every_scenario_has_a_scene_file_and_every_file_is_checked():
    names = _scenario_names()
    assert len(names) >= 30
    assert [name for name in names if not (FILES / f"{name}.toml").is_file()] == []
    checked = {*SIMULATED, "controlled_chain_frequency", "controlled_chain_across", "pd_tuning", "delay_chain_chart",
               "delay_hub_beam_chart", "delay_oscillator", "delay_pd_single_mass", "controlled_chain_time",
               "finite_segments",
               # tests/test_scene_files.py and tests/test_scene_files_syntax.py
               "pendulum_chain", "hinge_spring_motor", "spatial_chain", "table7_1", "flexible_manipulator",
               "controlled_chain_delay_frequency", "pendulum_chain_yaml"}
    assert sorted(path.stem for path in FILES.iterdir() if path.stem not in checked) == []


@pytest.mark.parametrize("name", ["pendulum_chain_yaml.yaml", "controlled_chain_across.toml"])
def test_ctmm_run_runs_the_files(tmp_path, name):
    from ctmm.scene_files_run import run_scene_file

    summary = run_scene_file(FILES / name, tmp_path, quick=True)
    stem = Path(name).stem
    assert summary["passed"] and summary["scene"] == stem
    assert (tmp_path / f"{stem}.png").is_file() and (tmp_path / f"{stem}.json").is_file()


def test_value_type_mistakes_in_a_shipped_file_name_line_and_key(tmp_path):
    text = (FILES / "single_link.toml").read_text()
    path = tmp_path / "single_link.toml"
    path.write_text(text.replace('quantity = "rate"', 'quantity = "speed"'))
    with pytest.raises(ctmm.ModelError, match=r"line 19, key 'system\.elements\[1\]\.rate\.quantity': SpinUpLaw: "
                                              r"quantity must be one of angle, rate, acceleration, got 'speed'"):
        load_scene(path)
    path.write_text(text.replace('n_modes = 3', 'n_modes = 3\nmodes = 4'))
    with pytest.raises(ctmm.ModelError, match=r"line 29, key 'system\.elements\[2\]\.modes': unknown key 'modes' of "
                                              r"ModalBeam"):
        load_scene(path)
