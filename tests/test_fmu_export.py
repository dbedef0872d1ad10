"""Plant FMU export (:func:`ctmm.export_fmu`, issue 17 item 1).

Independent checks: the exported FMU is run by fmpy (``simulate_fmu`` and an ``FMU2Slave`` master loop
written here), never by ctmm's own stepping; its outputs at the communication points are compared with
``ctmm.simulate`` (the numpy RK4 of the planar family, and the generated kernels), with co-simulated
controllers (a Python PID and ctmm's ``FMUController`` of the shipped PD FMU) closing the loop in the
master, and with parameters and start values set through the FMI interface.  fmpy's
``validate_fmu`` checks every built FMU.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

import ctmm
from ctmm.errors import ModelError
from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge, SpringDamperHinge

from test_compiled_scene import _state, hub_beam, rigid_tree
from test_compiled_scene_loops import controlled_hub_beam

fmpy = pytest.importorskip("fmpy")
from fmpy.fmi2 import FMU2Slave  # noqa: E402
from fmpy.validation import validate_fmu  # noqa: E402

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")


@pytest.fixture(autouse=True, scope="module")
def _cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CTMM_CACHE", str(tmp_path_factory.mktemp("fmu_export_cache")))
        yield


def arm(rod_mass: float = 1.0) -> PlanarModel:
    """Double pendulum: a spring-damper shoulder and a smooth elbow, both with torque inputs."""
    return PlanarModel.chain("arm", [
        Fixed("ground"), SpringDamperHinge("pivot", stiffness=2.0, damping=0.1),
        RigidBody.uniform_link("rod", mass=rod_mass, length=0.8), SmoothHinge("elbow"),
        RigidBody.uniform_link("fore", mass=0.5, length=0.6)])


X0, V0 = np.array([0.4, -0.3]), np.array([0.0, 0.5])
H, INTERVAL = 1e-3, 0.01


@pytest.fixture(scope="module")
def arm_fmu(tmp_path_factory):
    path = tmp_path_factory.mktemp("fmus") / "arm.fmu"
    return ctmm.export_fmu(arm(), path, step=H, q0=X0, qdot0=V0,
                           outputs=["rod.theta", "rod.omega", "fore.theta", "fore.out.y", "elbow.angle"])


def at(result, times):
    """Rows of a ctmm result at the given times."""
    index = np.searchsorted(result.time, np.asarray(times) - 1e-12)
    assert np.allclose(result.time[index], times, rtol=0, atol=1e-12)
    return index


def assert_round_off(fmu_values, native, name):
    scale = max(1.0, float(np.max(np.abs(native))))
    assert np.max(np.abs(np.asarray(fmu_values) - native)) < 1e-12 * scale, name


def test_the_fmu_is_valid_and_equals_ctmm_simulate(arm_fmu):
    """fmpy.simulate_fmu of the exported FMU equals ctmm.simulate (numpy RK4 and the generated kernel)."""
    assert validate_fmu(str(arm_fmu)) == []
    description = fmpy.read_model_description(str(arm_fmu))
    causality = {v.name: v.causality for v in description.modelVariables}
    assert causality["pivot.torque"] == causality["elbow.torque"] == "input"
    assert causality["fore.out.y"] == "output" and causality["rod.mass"] == "parameter"
    assert causality["rod.theta_start"] == causality["rod.theta_dot_start"] == "parameter"
    out = fmpy.simulate_fmu(str(arm_fmu), stop_time=0.5, output_interval=INTERVAL,
                            start_values={"elbow.torque": 0.3})
    for compiled in (False, True):
        native = ctmm.simulate(arm(), 0.5, H, x0=X0, v0=V0, inputs={"elbow.torque": 0.3}, method="rk4",
                               outputs=["rod.omega", "fore.out.y", "elbow.angle"], compiled=compiled)
        rows = at(native, out["time"])
        for name in ("rod.theta", "rod.omega", "fore.theta", "fore.out.y", "elbow.angle"):
            assert_round_off(out[name], native[name][rows], name)


def test_fmi3_equals_ctmm_simulate(tmp_path):
    """The same plant as FMI 3.0 (Float64 variables, independent time): valid, equal to ctmm.simulate."""
    path = ctmm.export_fmu(arm(), tmp_path / "arm3.fmu", step=H, q0=X0, qdot0=V0, fmi_version="3.0",
                           outputs=["rod.theta", "fore.out.y"])
    assert validate_fmu(str(path)) == []
    description = fmpy.read_model_description(str(path))
    assert description.fmiVersion == "3.0"
    assert [v.name for v in description.modelVariables if v.causality == "independent"] == ["time"]
    out = fmpy.simulate_fmu(str(path), stop_time=0.3, output_interval=INTERVAL,
                            start_values={"elbow.torque": 0.3, "rod.mass": 1.7, "rod.inertia": 1.7 * 0.8 ** 2 / 12})
    native = ctmm.simulate(arm(rod_mass=1.7), 0.3, H, x0=X0, v0=V0, inputs={"elbow.torque": 0.3}, method="rk4",
                           outputs=["fore.out.y"])
    rows = at(native, out["time"])
    for name in ("rod.theta", "fore.out.y"):
        assert_round_off(out[name], native[name][rows], name)
    with pytest.raises(Exception, match="fmi3DoStep failed with status 3"):      # 1.5 steps: an error
        fmpy.simulate_fmu(str(path), stop_time=0.3, output_interval=1.5e-3)


def test_every_coordinate_of_a_tree_by_default(tmp_path):
    """Default outputs are the coordinates and their rates; a rigid tree with hinge laws, a motor and loads
    (modal beams: the controlled hub-beam below)."""
    for model in (rigid_tree(),):
        q0, v0 = _state(model, 3)
        q0, v0 = (0.1 * q0, 0.1 * v0) if model.beams else (q0, v0)
        path = ctmm.export_fmu(model, tmp_path / f"{model.name}.fmu", step=H, q0=q0, qdot0=v0)
        out = fmpy.simulate_fmu(str(path), stop_time=0.2, output_interval=0.02)
        native = ctmm.simulate(model, 0.2, H, x0=q0, v0=v0, method="rk4")
        rows = at(native, out["time"])
        names = [n for c in model.coordinates for n in (c, c + "_dot")]
        assert sorted(out.dtype.names[1:]) == sorted(names)
        for name in names:
            assert_round_off(out[name], native[name][rows], name)


def test_loops_with_delays_and_controllers_inside_the_fmu(tmp_path):
    """A controlled hub-beam (real-time PD, LTI loops, two delayed loops, references) exported whole."""
    system, signals = controlled_hub_beam()
    q0, v0 = _state(system.plant, 4)
    outputs = list(system.plant.coordinates) + ["tip.com.x"] + [f"{loop.name}.{part}" for loop in system.loops
                                                                for part in ("y", "u")]
    path = ctmm.export_fmu(system, tmp_path / "hub_loops.fmu", step=2e-3, q0=q0, qdot0=v0, outputs=outputs,
                           references=signals["references"], inputs=["tip.force_x", "o.torque"])
    assert validate_fmu(str(path)) == []
    out = fmpy.simulate_fmu(str(path), stop_time=0.2, output_interval=0.01, start_values={"tip.force_x": 0.2})
    native = ctmm.simulate(system, 0.2, 2e-3, x0=q0, v0=v0, outputs=["tip.com.x"],
                           references=signals["references"], inputs={"tip.force_x": 0.2})
    rows = at(native, out["time"])
    for name in outputs:
        assert_round_off(out[name], native[name][rows], name)
    description = fmpy.read_model_description(str(path))
    inputs = [v.name for v in description.modelVariables if v.causality == "input"]
    assert inputs == ["tip.force_x", "o.torque"]
    assert "loops pd, end, modal, lag closed inside the step" in description.description


def master_loop(path, controller, t_final, start_values=None):
    """fmpy FMU2Slave of the plant FMU with ``controller`` (ctmm Controller protocol) sampled every
    INTERVAL in the master: outputs read, controller stepped, inputs set, doStep.  Returns ``(times,
    {output: values})`` (and ``{actuator: commands}``, one per sample)."""
    description = fmpy.read_model_description(str(path))
    reference = {v.name: v.valueReference for v in description.modelVariables}
    outputs = [v.name for v in description.modelVariables if v.causality == "output"]
    folder = fmpy.extract(str(path))
    plant = FMU2Slave(guid=description.guid, unzipDirectory=folder, instanceName="plant",
                      modelIdentifier=description.coSimulation.modelIdentifier)
    try:
        plant.instantiate()
        plant.setupExperiment(startTime=0.0)
        plant.enterInitializationMode()
        for name, value in (start_values or {}).items():
            plant.setReal([reference[name]], [value])
        plant.exitInitializationMode()
        state = controller.init(0.0)
        steps = int(round(t_final / INTERVAL))
        rows, commands = [], []
        for k in range(steps + 1):
            t = k * INTERVAL
            rows.append(plant.getReal([reference[name] for name in outputs]))
            if k == steps:
                break
            y = np.array(plant.getReal([reference[name] for name in controller.inputs]))
            u, state = controller.step(t, y, state)
            commands.append(u)
            plant.setReal([reference[name] for name in controller.outputs], [float(x) for x in u])
            plant.doStep(currentCommunicationPoint=t, communicationStepSize=INTERVAL)
        if hasattr(controller, "close"):
            controller.close(state)
        plant.terminate()
    finally:
        plant.freeInstance()
        shutil.rmtree(folder, ignore_errors=True)
    values, commands = np.array(rows), np.array(commands)
    out = {name: values[:, j] for j, name in enumerate(outputs)}
    out.update({name: commands[:, j] for j, name in enumerate(controller.outputs)})
    return INTERVAL * np.arange(len(rows)), out


def pid_controller():
    from ctmm.controllers import PID

    return PID(("rod.theta",), ("pivot.torque",), kp=8.0, ki=2.0, kd=0.4, derivative_filter_time=0.02,
               sample_time=INTERVAL, reference=-0.2)


def fmu_controller():
    from ctmm.control.fmu import FMUController, build_fmu
    from ctmm.controllers import fmu_source

    return FMUController(build_fmu(fmu_source("pd_controller")), inputs={"y": "rod.theta", "ydot": "rod.omega"},
                         outputs={"u": "pivot.torque"}, parameters={"kp": 6.0, "kd": 0.8, "reference": 0.3},
                         sample_time=INTERVAL)


@pytest.mark.parametrize("make", [pid_controller, fmu_controller], ids=["python_pid", "fmu_controller"])
def test_round_trip_with_a_controller_in_the_master_equals_ctmm_cosimulation(arm_fmu, make):
    """The plant FMU driven by a co-simulated controller in an fmpy master loop equals ctmm.simulate of
    the plant with the same controller (zero-order hold, sampled every INTERVAL) to round-off."""
    times, fmu_out = master_loop(arm_fmu, make(), 0.4)
    native = ctmm.simulate(arm(), 0.4, H, x0=X0, v0=V0, method="rk4", controllers=[make()],
                           outputs=["rod.omega", "fore.out.y"])
    rows = at(native, times)
    samples = native["pivot.torque@samples"][:len(times) - 1]          # (time, value) per sample
    np.testing.assert_allclose(samples[:, 0], times[:-1], rtol=0, atol=1e-12)
    assert np.max(np.abs(samples[:, 1])) > 0.1                           # the controller acted
    assert_round_off(fmu_out["pivot.torque"], samples[:, 1], "pivot.torque@samples")
    for name in ("rod.theta", "rod.omega", "fore.theta", "fore.out.y"):
        assert_round_off(fmu_out[name], native[name][rows], name)


def test_parameters_and_start_values_set_through_fmi(arm_fmu):
    """A changed mass and start values set in the FMU equal ctmm.simulate of the changed model."""
    description = fmpy.read_model_description(str(arm_fmu))
    parameters = sorted(v.name for v in description.modelVariables if v.causality == "parameter"
                        and not v.name.endswith("_start"))
    assert parameters == sorted(["rod.mass", "fore.mass", "rod.inertia", "fore.inertia", "gravity.y",
                                 "pivot.stiffness", "pivot.damping"])
    x0, v0 = np.array([-0.2, 0.9]), np.array([0.3, 0.0])
    starts = {"rod.mass": 1.7, "rod.inertia": 1.7 * 0.8 ** 2 / 12, "rod.theta_start": x0[0],
              "fore.theta_start": x0[1], "rod.theta_dot_start": v0[0], "fore.theta_dot_start": v0[1]}
    out = fmpy.simulate_fmu(str(arm_fmu), stop_time=0.3, output_interval=INTERVAL, start_values=starts)
    native = ctmm.simulate(arm(rod_mass=1.7), 0.3, H, x0=x0, v0=v0, method="rk4", outputs=["fore.out.y"])
    rows = at(native, out["time"])
    for name in ("rod.theta", "fore.out.y"):
        assert_round_off(out[name], native[name][rows], name)
    unchanged = ctmm.simulate(arm(), 0.3, H, x0=x0, v0=v0, method="rk4")
    assert np.max(np.abs(unchanged["rod.theta"][rows] - out["rod.theta"])) > 1e-3   # the mass mattered


def test_no_exposed_parameter_is_a_constant_of_the_code():
    """Beam loads, geometry and zero numbers are not exposed (they are constants of the generated code)."""
    from ctmm.fmu_export_model import parameter_names, planar_export

    model = hub_beam()
    exported = planar_export(model, step=H, inputs=None, outputs=None, parameters=None, q0=None, qdot0=None,
                             references=None, stability_check="ignore")
    names = [v.name for v in exported.parameters]
    assert "b.load0.force_y" not in names and "hub.center_of_mass.x" not in names and "o.stiffness" not in names
    assert "hub.mass" in names
    assert len(parameter_names(model)) == exported.parameter_values.size


def test_fmi_calls_outside_the_contract_fail_loudly(arm_fmu):
    """A communication step that is not a multiple of the FMU step, a wrong communication point, a fixed
    parameter set after initialisation, a non-finite input: fmi2Error with a logged message naming it;
    FMU state get/set restores."""
    import collections

    from ctmm.control.fmu_calls import fmi2_callbacks

    description = fmpy.read_model_description(str(arm_fmu))
    reference = {v.name: v.valueReference for v in description.modelVariables}
    folder = fmpy.extract(str(arm_fmu))
    log: collections.deque = collections.deque(maxlen=20)
    callbacks = fmi2_callbacks(log)
    plant = FMU2Slave(guid=description.guid, unzipDirectory=folder, modelIdentifier="arm", instanceName="p")
    try:
        plant.instantiate(callbacks=callbacks)
        plant.setupExperiment(startTime=0.0)
        plant.enterInitializationMode()
        plant.exitInitializationMode()
        for call, words in ((lambda: plant.doStep(0.0, 1.5e-3), "not a whole multiple of the FMU's step 0.001"),
                            (lambda: plant.doStep(0.5, 1e-3), "currentCommunicationPoint 0.5 is not the FMU's time"),
                            (lambda: plant.setReal([reference["rod.mass"]], [2.0]), "fixed parameter")):
            with pytest.raises(Exception, match="status 3"):
                call()
            assert words in log[-1], (words, list(log))
        plant.doStep(currentCommunicationPoint=0.0, communicationStepSize=0.01)
        saved = plant.getFMUState()
        first = plant.getReal([reference["rod.theta"]])
        plant.doStep(currentCommunicationPoint=0.01, communicationStepSize=0.01)
        later = plant.getReal([reference["rod.theta"]])
        plant.setFMUState(saved)
        assert plant.getReal([reference["rod.theta"]]) == first
        plant.doStep(currentCommunicationPoint=0.01, communicationStepSize=0.01)
        assert plant.getReal([reference["rod.theta"]]) == later != first
        plant.freeFMUState(saved)
        plant.setReal([reference["pivot.torque"]], [float("nan")])
        with pytest.raises(Exception, match="status 3"):
            plant.doStep(currentCommunicationPoint=0.02, communicationStepSize=0.01)
        assert "state is not finite after the RK4 step from t = 0.02" in log[-1], list(log)
    finally:
        plant.freeInstance()
        shutil.rmtree(folder, ignore_errors=True)


def test_an_unchanged_export_comes_from_the_cache(arm_fmu, tmp_path):
    again = ctmm.export_fmu(arm(), tmp_path / "arm.fmu", step=H, q0=X0, qdot0=V0,
                            outputs=["rod.theta", "rod.omega", "fore.theta", "fore.out.y", "elbow.angle"])
    assert again.read_bytes() == arm_fmu.read_bytes()


@pytest.mark.parametrize("change, words", [
    ({"inputs": ["rod.force_z"]}, ["inputs", "'rod.force_z'", "pivot.torque"]),
    ({"outputs": ["rod.height"]}, ["outputs", "'rod.height'", "rod.theta"]),
    ({"parameters": ["rod.color"]}, ["parameters", "'rod.color'", "rod.mass"]),
    ({"parameters": ["rod.center_of_mass.x"]}, ["parameters", "'rod.center_of_mass.x'"]),
    ({"step": -1e-3}, ["step", "-0.001", "> 0"]),
    ({"step": float("inf")}, ["step", "inf"]),
    ({"fmi_version": "3"}, ["fmi_version", "'3'", "'2.0', '3.0'"]),
    ({"fmi_version": "1.0"}, ["fmi_version", "'1.0'"]),
    ({"path": "my-arm.fmu"}, ["path", "my-arm.fmu'", "identifier"]),
    ({"path": "arm.zip"}, ["path", "arm.zip'", ".fmu"]),
    ({"q0": [0.1]}, ["q0", "length 2", "[0.1]"]),
    ({"references": {"pd": 1.0}}, ["references", "ControlledModel"]),
    ({"stop_time": -1.0}, ["stop_time", "-1.0"]),
])
def test_bad_arguments_name_the_parameter_and_value(tmp_path, change, words):
    arguments = {"path": "arm.fmu", "step": H, **change}
    path = tmp_path / arguments.pop("path")
    with pytest.raises(ModelError) as error:
        ctmm.export_fmu(arm(), path, **arguments)
    for word in words:
        assert word in str(error.value), (word, str(error.value))
    assert not path.exists()


def test_a_step_beyond_the_rk4_limit_is_refused_or_warned(tmp_path):
    """The step is checked against the plant's linearised RK4 limit at the start values (as ctmm.simulate)."""
    with pytest.raises(ModelError, match=r"omega_max \* dt = 26\.11 exceeds its limit"):
        ctmm.export_fmu(arm(), tmp_path / "arm.fmu", step=10.0, stability_check="error")
    assert not (tmp_path / "arm.fmu").exists()
    with pytest.raises(ModelError, match="stability_check must be"):
        ctmm.export_fmu(arm(), tmp_path / "arm.fmu", step=H, stability_check="loud")


def test_unsupported_systems_are_refused_by_name(tmp_path):
    """1-D chains, controlled spatial models and non-models: ModelError naming the type."""
    import ctmm.spatial as sp
    from ctmm.control import Feedback, with_feedback
    from ctmm.elements import Fixed as ChainFixed, Free, Mass, Spring

    chain = ctmm.Chain("c", [ChainFixed("w"), Spring("k", 1.0), Mass("m", 1.0), Free("e")])
    body = sp.SpatialModel("hinge", [
        sp.SpatialBody("body", 4.0, np.diag([0.05, 0.08, 0.06]), center_of_mass=(0.0, 0.0, 0.25)),
        sp.Elastic6(name="hinge", parent=None, child="body", stiffness=np.eye(6), damping=np.zeros((6, 6)),
                    actuated=True)])
    loop = Feedback("pd", "body.angle_z", "hinge.torque_z", gain=1.0)
    cases = [(chain, "got Chain"), ("arm", "got str"),
             (with_feedback(body, [loop]), "got ControlledModel on a SpatialModel")]
    for system, words in cases:
        with pytest.raises(ModelError, match=words) as error:
            ctmm.export_fmu(system, tmp_path / "x.fmu", step=H)
        assert "system" in str(error.value)
    assert not (tmp_path / "x.fmu").exists()


def test_a_spatial_tree_equals_ctmm_simulate(tmp_path):
    """A random spatial tree (free base, every joint kind, loads, vector inputs; quaternions): the FMU's
    coordinates, velocities, body positions and angular velocities equal ctmm.simulate (numpy RK4)."""
    pytest.importorskip("pinocchio")
    from test_spatial_compiled import random_tree, start

    model = random_tree(2, 4, "free")
    q0, v0, inputs = start(2, model)
    extra = ["b3.position_x", "b2.omega_z"]
    path = ctmm.export_fmu(model, tmp_path / "tree.fmu", step=1e-3, q0=q0, qdot0=v0,
                           outputs=list(model.coordinates) + list(model.velocities) + extra)
    assert validate_fmu(str(path)) == []
    description = fmpy.read_model_description(str(path))
    from ctmm.compiled_spatial_parameters import spatial_parameter_layout

    assert [v.name for v in description.modelVariables if v.causality == "parameter"] == \
        [entry.name for entry in spatial_parameter_layout(model)] + \
        [f"{name}_start" for name in list(model.coordinates) + list(model.velocities)]
    start_values = {}
    for name, value in inputs.items():
        values = np.atleast_1d(value)
        start_values.update({name: float(value)} if np.ndim(value) == 0 else
                            {f"{name}[{k}]": float(x) for k, x in enumerate(values)})
    out = fmpy.simulate_fmu(str(path), stop_time=0.05, output_interval=0.01, start_values=start_values)
    native = ctmm.simulate(model, 0.05, 1e-3, x0=q0, v0=v0, inputs=inputs, method="rk4")
    rows = at(native, out["time"])
    for name in out.dtype.names[1:]:
        assert_round_off(out[name], native[name][rows], name)
    assert max(np.ptp(native[name]) for name in model.coordinates) > 1e-3          # it moved
    with pytest.raises(ModelError, match="parameters has the unknown name 'b0.center_of_mass.x'; allowed: b0.mass"):
        ctmm.export_fmu(model, tmp_path / "tree.fmu", step=1e-3, parameters=["b0.center_of_mass.x"])


def test_beam_station_loads_are_inputs_of_the_fmu_when_named(tmp_path):
    """A station force and a station moment on a modal cantilever (``inputs=["arm.a.force", "arm.tip.moment"]``;
    refused as unknown inputs before): named FMU inputs with SI units, and fmpy's run with them set (held) equals
    ctmm.simulate's numpy RK4 with the same constant loads (the station loads' modal forces and frame wrench in the
    Python sweep) to round-off of the FMU's RK4 (1e-13 of each signal's peak); unnamed, they are no inputs."""
    from test_compiled_station_held_inputs import hub_cantilever

    model = hub_cantilever()
    x0 = np.array([0.05, 0.002, -0.0005, 0.0, 0.0])
    outputs = list(model.coordinates) + ["arm.tip.w", "arm.a.slope"]
    loads = {"arm.a.force": 0.4, "arm.tip.moment": -0.15, "motor.torque": 0.05}
    path = ctmm.export_fmu(model, tmp_path / "stations.fmu", step=1e-3, q0=x0, outputs=outputs,
                           inputs=["motor.torque", "arm.a.force", "arm.tip.moment"])
    assert validate_fmu(str(path)) == []
    description = fmpy.read_model_description(str(path))
    inputs = {v.name: v for v in description.modelVariables if v.causality == "input"}
    assert list(inputs) == ["motor.torque", "arm.a.force", "arm.tip.moment"]
    assert {name: variable.unit for name, variable in inputs.items()} == {
        "motor.torque": "N m", "arm.a.force": "N", "arm.tip.moment": "N m"}
    out = fmpy.simulate_fmu(str(path), stop_time=0.2, output_interval=0.01, start_values=loads)
    native = ctmm.simulate(model, 0.2, 1e-3, x0=x0, inputs=loads, outputs=["arm.tip.w", "arm.a.slope"],
                           method="rk4")
    rows = at(native, out["time"])
    for name in outputs:                # measured 2.4e-16 of the peak
        assert_peak_round_off(out[name], native[name][rows], name)
    alone = ctmm.simulate(model, 0.2, 1e-3, x0=x0, inputs={"motor.torque": 0.05}, outputs=["arm.tip.w"],
                          method="rk4")
    assert np.max(np.abs(alone["arm.tip.w"] - native["arm.tip.w"])) > 1e-4          # the station loads act
    plain = fmpy.read_model_description(str(ctmm.export_fmu(model, tmp_path / "plain.fmu", step=1e-3, q0=x0)))
    assert not [v.name for v in plain.modelVariables if v.causality == "input" and ".a." in v.name]


def test_a_station_force_driven_by_a_controller_in_the_master_equals_ctmm_cosimulation(tmp_path):
    """The station force as the output of a sampled PD on the station's deflection (zero-order hold every INTERVAL)
    in an fmpy master loop around the exported plant = ctmm.simulate's numpy RK4 with the same controller and a
    held motor torque, to round-off (the same held signal on both sides)."""
    from test_compiled_station_held_inputs import hub_cantilever, station_controller

    model = hub_cantilever()
    x0 = np.array([0.05, 0.002, 0.0, 0.0, 0.0])
    path = ctmm.export_fmu(model, tmp_path / "station_loop.fmu", step=H, q0=x0, inputs=["motor.torque", "arm.tip.force"],
                           outputs=[*model.coordinates, "arm.a.w"])
    times, fmu_out = master_loop(path, station_controller(INTERVAL), 0.2, start_values={"motor.torque": 0.05})
    native = ctmm.simulate(model, 0.2, H, x0=x0, inputs={"motor.torque": 0.05}, outputs=["arm.a.w"], method="rk4",
                           controllers=[station_controller(INTERVAL)])
    rows = at(native, times)
    samples = native["arm.tip.force@samples"][:len(times) - 1]
    assert np.ptp(samples[:, 1]) > 1e-3                                  # the controller drove the station force
    assert_peak_round_off(fmu_out["arm.tip.force"], samples[:, 1], "arm.tip.force@samples")
    for name in [*model.coordinates, "arm.a.w"]:        # measured 8e-16 of the peak (7e-16 the force)
        assert_peak_round_off(fmu_out[name], native[name][rows], name)


def assert_peak_round_off(fmu_values, native, name):
    """Round-off of the signal's own peak (a beam's modal coordinates and deflections are ~1e-3)."""
    scale = float(np.max(np.abs(native)))
    assert scale > 0.0 and np.max(np.abs(np.asarray(fmu_values) - native)) < 1e-13 * scale, name


def test_start_values_by_coordinate_name_as_in_simulate(tmp_path):
    """``q0`` / ``qdot0`` as ``{coordinate: value}`` (the others 0), as ``x0`` / ``v0`` of ``ctmm.simulate`` and of a
    spatial export: the FMU's start parameters are those numbers and its run is ``simulate``'s from that start."""
    path = ctmm.export_fmu(arm(), tmp_path / "named.fmu", step=H, q0={"rod.theta": 0.4}, qdot0={"fore.theta": 0.5})
    starts = {v.name: float(v.start) for v in fmpy.read_model_description(str(path)).modelVariables
              if v.name.endswith("_start")}
    assert starts == {"rod.theta_start": 0.4, "fore.theta_start": 0.0, "rod.theta_dot_start": 0.0,
                      "fore.theta_dot_start": 0.5}
    out = fmpy.simulate_fmu(str(path), stop_time=0.1, output_interval=INTERVAL)
    native = ctmm.simulate(arm(), 0.1, H, x0=[0.4, 0.0], v0=[0.0, 0.5], method="rk4", compiled=False)
    assert_round_off(out["rod.theta"], native["rod.theta"][at(native, out["time"])], "rod.theta")
    with pytest.raises(ModelError, match="rod.thet"):
        ctmm.export_fmu(arm(), tmp_path / "bad.fmu", step=H, q0={"rod.thet": 0.4})
