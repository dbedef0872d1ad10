"""FMU export of spatial models with flexible bodies (issues 15-17): a yaw hub carrying a ctmm.spatial.SpatialBeam
and the spatial_fem_chain model (a ctmm.fem.SpatialSubsystem between rigid bodies).

Independent check: fmpy runs the exported FMU (generated C behind the FMI interface) and its coordinates,
velocities and body signals equal ctmm.simulate's numpy RK4 (the Python sweep) to 1e-12.  A modal beam's numbers
are FMU parameters (names and units of ctmm.parameter_names): the FMU run with changed numbers equals
ctmm.simulate(compiled=True) of the model rebuilt with them (the beam's data computed anew, its numbers constants of
that code).  A finite-element subsystem's numbers are constants of the code: that FMU has no model parameters.
"""
from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError

fmpy = pytest.importorskip("fmpy")
from fmpy.validation import validate_fmu  # noqa: E402

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


@pytest.fixture(autouse=True, scope="module")
def _cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CTMM_CACHE", str(tmp_path_factory.mktemp("fmu_flexible_cache")))
        yield


def hub_beam(gravity: float = -9.81, **beam_numbers) -> sp.SpatialModel:
    """A yaw hub (revolute about z, a torque input) carrying a 2 m beam bending in both planes, with gravity
    (``beam_numbers``: more or other keyword arguments of the beam)."""
    hub = sp.SpatialBody("hub", 2.0, np.diag([0.1, 0.1, 0.2]), points={"tip": (0.2, 0.0, 0.0)})
    numbers = dict(mass_per_length=0.8, bending_stiffness_y=40.0, bending_stiffness_z=60.0, n_modes_y=2, n_modes_z=1)
    beam = sp.SpatialBeam("arm", length=2.0, **{**numbers, **beam_numbers})
    return sp.SpatialModel("hub_beam", [hub, sp.Revolute(name="yaw", parent=None, child="hub", axis=(0, 0, 1),
                                                         actuated=True),
                                        beam, sp.Weld(name="clamp", parent="hub", child="arm", point="tip")],
                           gravity=(0.0, 0.0, gravity))


def assert_round_off(fmu_values, native, name):
    scale = max(1.0, float(np.max(np.abs(native))))
    assert np.max(np.abs(np.asarray(fmu_values) - native)) < 1e-12 * scale, name


def compare(model, path, step, stop, q0, v0, extra, start_values=None, inputs=None, parameters=()):
    exported = ctmm.export_fmu(model, path, step=step, q0=q0, qdot0=v0,
                               outputs=list(model.coordinates) + list(model.velocities) + extra)
    assert validate_fmu(str(exported)) == []
    description = fmpy.read_model_description(str(exported))
    assert [v.name for v in description.modelVariables if v.causality == "parameter"] == \
        list(parameters) + [f"{name}_start" for name in list(model.coordinates) + list(model.velocities)]
    out = fmpy.simulate_fmu(str(exported), stop_time=stop, output_interval=10 * step, start_values=start_values or {})
    native = ctmm.simulate(model, stop, step, x0=q0, v0=v0, inputs=inputs, method="rk4")
    rows = np.searchsorted(native.time, out["time"] - 1e-12)
    assert np.allclose(native.time[rows], out["time"], rtol=0, atol=1e-12)
    for name in out.dtype.names[1:]:
        assert_round_off(out[name], np.asarray(native[name])[rows], name)
    return native


def test_a_hub_with_a_spatial_beam_equals_ctmm_simulate(tmp_path):
    model = hub_beam()
    native = compare(model, tmp_path / "hub_beam.fmu", 1e-3, 0.1, {"arm.qy1": 0.02, "arm.qz1": -0.01},
                     {"yaw.angle_rate": 2.0}, ["arm.position_y", "arm.omega_z"], start_values={"yaw.torque": 0.5},
                     inputs={"yaw.torque": 0.5}, parameters=["hub.mass", "hub.inertia.xx", "hub.inertia.yy",
                                                             "hub.inertia.zz", "arm.mass_per_length",
                                                             "arm.bending_stiffness_y", "arm.bending_stiffness_z",
                                                             "gravity.z"])
    assert np.ptp(native["arm.qy1"]) > 1e-3 and np.ptp(native["arm.qz1"]) > 1e-3          # it bent
    with pytest.raises(ModelError, match="parameters has the unknown name 'arm.mass'"):
        ctmm.export_fmu(model, tmp_path / "again.fmu", step=1e-3, parameters=["arm.mass"])


BEAM_NUMBERS = {"mass_per_length": 0.8, "polar_inertia_per_length": 0.01, "bending_stiffness_y": 40.0,
                "bending_stiffness_z": 60.0, "torsional_stiffness": 30.0, "axial_stiffness": 4000.0,
                "damping_ratio": 0.02, "stiffness_damping": 1e-3}
"""Every number of a modal spatial beam (one mode per direction)."""
CHANGED = {"mass_per_length": 1.1, "polar_inertia_per_length": 0.015, "bending_stiffness_y": 55.0,
           "bending_stiffness_z": 45.0, "torsional_stiffness": 20.0, "axial_stiffness": 3000.0,
           "damping_ratio": 0.05, "stiffness_damping": 2e-3}


def test_the_beam_numbers_are_parameters_and_a_changed_one_equals_the_rebuilt_model(tmp_path):
    """Every beam number is an FMU parameter (name, unit and start value of ctmm.parameter_names); the FMU with
    all of them and gravity changed equals ctmm.simulate(compiled=True) of the model built with those numbers."""
    modes = dict(n_modes_y=1, n_modes_z=1, n_torsion_modes=1, n_axial_modes=1)
    model = hub_beam(**BEAM_NUMBERS, **modes)
    q0, v0, inputs = {"arm.qy1": 0.02, "arm.twist1": 0.01}, {"yaw.angle_rate": 2.0}, {"yaw.torque": 0.5}
    path = ctmm.export_fmu(model, tmp_path / "beam_numbers.fmu", step=1e-3, q0=q0, qdot0=v0)
    assert validate_fmu(str(path)) == []
    description = fmpy.read_model_description(str(path))
    declared = {v.name: v for v in description.modelVariables
                if v.causality == "parameter" and not v.name.endswith("_start")}
    names = ctmm.parameter_names(model)
    assert list(declared) == list(names)
    assert {f"arm.{number}" for number in BEAM_NUMBERS} <= set(names)
    for name, (unit, value) in names.items():
        assert float(declared[name].start) == value, name
        assert (declared[name].unit or "-") == unit, name                  # damping_ratio: dimensionless
        assert f"[{unit}]" in declared[name].description, name
    changed = {f"arm.{number}": value for number, value in CHANGED.items()} | {"gravity.z": -7.0}
    out = fmpy.simulate_fmu(str(path), stop_time=0.05, output_interval=0.01, start_values={**changed, **inputs})
    rebuilt = ctmm.simulate(hub_beam(-7.0, **CHANGED, **modes), 0.05, 1e-3, x0=q0, v0=v0, inputs=inputs,
                            method="rk4", compiled=True)
    original = ctmm.simulate(model, 0.05, 1e-3, x0=q0, v0=v0, inputs=inputs, method="rk4", compiled=True)
    rows = np.searchsorted(rebuilt.time, out["time"] - 1e-12)
    for name in out.dtype.names[1:]:
        expected = np.asarray(rebuilt[name])[rows]
        scale = max(1.0, float(np.max(np.abs(expected))))
        assert np.max(np.abs(out[name] - expected)) < 1e-10 * scale, name
    moved = max(np.max(np.abs(out[name] - np.asarray(original[name])[rows])) for name in out.dtype.names[1:])
    assert moved > 1e-4                                                 # the changed numbers mattered


def test_the_spatial_fem_chain_equals_ctmm_simulate(tmp_path):
    from scenarios import spatial_fem_chain as scenario

    model = scenario.model()
    native = compare(model, tmp_path / "fem_chain.fmu", scenario.STEP, 0.02, scenario.INITIAL,
                     scenario.INITIAL_RATE, ["body3.position_z", "beam1.omega_x"])
    nodal = [name for name in model.coordinates if name.startswith("beam1.")]
    assert max(np.ptp(native[name]) for name in nodal) > 1e-5                              # the nodes moved


def test_a_beam_past_its_deflection_bound_stops_the_fmu_at_the_time_of_ctmm_simulate(tmp_path):
    """The FMU steps with the beam's guard: the spinner above its critical speed without stiffening stops with
    fmi2Error and a logged message at the step whose end is the failure time of ctmm.simulate (0.19 s)."""
    import collections

    from fmpy.fmi2 import FMU2Slave

    from ctmm.control.fmu_calls import fmi2_callbacks
    from ctmm.errors import SimulationError
    from test_spatial_beam_guard import spinner

    model, x0, v0 = spinner(False), {"arm.qy1": 0.01}, {"hub.angle_rate": 8.0}
    with pytest.raises(SimulationError) as caught:
        ctmm.simulate(model, 2.0, 0.01, method="rk4", x0=x0, v0=v0)
    assert caught.value.element == "arm"
    failure = caught.value.time
    path = ctmm.export_fmu(model, tmp_path / "spinner.fmu", step=0.01, q0=x0, qdot0=v0)
    description = fmpy.read_model_description(str(path))
    folder = fmpy.extract(str(path))
    log: collections.deque = collections.deque(maxlen=20)
    plant = FMU2Slave(guid=description.guid, unzipDirectory=folder, modelIdentifier="spinner", instanceName="s")
    try:
        plant.instantiate(callbacks=fmi2_callbacks(log))
        plant.setupExperiment(startTime=0.0)
        plant.enterInitializationMode()
        plant.exitInitializationMode()
        time = 0.0
        with pytest.raises(Exception, match="status 3"):
            for k in range(200):
                plant.doStep(currentCommunicationPoint=time, communicationStepSize=0.01)
                time = (k + 1) * 0.01
        assert time == pytest.approx(failure - 0.01, abs=1e-12)
        assert "state is not finite after the RK4 step from t = " in log[-1], list(log)
        assert f"(step {round(failure / 0.01) - 1};" in log[-1], list(log)
        assert "flexible body beyond its deformation bound" in log[-1]
    finally:
        plant.freeInstance()
        shutil.rmtree(folder, ignore_errors=True)
