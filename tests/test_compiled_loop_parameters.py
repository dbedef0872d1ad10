"""Loop gains, controller realisations and references as parameters of the generated step (issue 13/17).

Independent checks: the numpy path (``ctmm.simulate`` without ``compiled``, the loop driver of
:mod:`ctmm.control.planar_time`) of a controlled model built with the changed numbers, to round-off;
the cache folder's files (counted by the operating system) show that no library was compiled for the
changed numbers; the FMU is run by fmpy with the changed numbers set through FMI.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.compiled_loops import ClosedLoops
from ctmm.compiled_scene import CompiledScene
from ctmm.control import Feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.errors import ModelError
from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.signals import Harmonic

casadi = pytest.importorskip("casadi")
control = pytest.importorskip("control")
fmpy = pytest.importorskip("fmpy")

DT, T_FINAL = 2e-3, 0.3
X0, V0 = np.array([0.5, -0.2]), np.array([0.0, 0.4])


def controlled(pd_gain: float, late_gain: float, lag_gain: float, lag_pole: float) -> ControlledModel:
    """Double pendulum: a real-time PD on the shoulder, a delayed loop (3 steps) and an LTI lag on the elbow."""
    plant = PlanarModel.chain("arm", [Fixed("ground"), SmoothHinge("pivot"),
                                      RigidBody.uniform_link("rod", mass=1.0, length=0.8), SmoothHinge("elbow"),
                                      RigidBody.uniform_link("fore", mass=0.5, length=0.6)])
    loops = [Feedback("pd", [("rod.theta", 1.0), ("rod.omega", 0.3)], "pivot.torque", gain=pd_gain),
             Feedback("late", "elbow.angle", "elbow.torque", gain=late_gain, delay=3 * DT),
             Feedback("lag", "fore.omega", "elbow.torque", gain=control.tf([lag_gain * lag_pole], [1.0, lag_pole]))]
    return ControlledModel(plant, loops)


def references(amplitude: float, offset: float) -> dict:
    return {"pd": Harmonic(amplitude, 7.0, 0.2), "late": offset}


def libraries(folder) -> list[str]:
    return sorted(path.name for path in (folder / "kernels").iterdir())


def assert_round_off(value, reference, name):
    scale = max(1.0, float(np.max(np.abs(reference))))
    assert np.max(np.abs(np.asarray(value) - reference)) < 1e-12 * scale, name


def test_a_gain_sweep_runs_on_one_library_and_equals_the_numpy_path(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    numbers = [((6.0, 2.0, 1.5, 30.0), (0.2, 0.05)), ((11.0, -1.0, 3.0, 12.0), (-0.4, 0.3))]
    names = ["rod.theta", "fore.theta", "pd.u", "late.u", "lag.u", "lag.y"]
    for index, (gains, reference) in enumerate(numbers):
        system = controlled(*gains)
        generated = ctmm.simulate(system, T_FINAL, DT, x0=X0, v0=V0, compiled=True,
                                  references=references(*reference))
        numpy_path = ctmm.simulate(system, T_FINAL, DT, x0=X0, v0=V0, references=references(*reference))
        for name in names:
            assert_round_off(generated[name], numpy_path[name], name)
        if index == 0:
            first, built = generated, libraries(tmp_path)
    assert libraries(tmp_path) == built and len(built) == 1            # the second set found the library
    assert np.max(np.abs(generated["rod.theta"] - first["rod.theta"])) > 1e-2    # the numbers matter
    scene = CompiledScene(controlled(*numbers[1][0]), dt=DT, references=references(*numbers[1][1]))
    layout = [name for name, _, _ in scene.loops.parameter_layout]
    assert layout == ["pd.gain", "late.gain", "lag.A[0,0]", "lag.B[0]", "lag.C[0]", "lag.D",
                      "pd.reference.amplitude", "pd.reference.omega", "pd.reference.phase", "late.reference",
                      "lag.reference"]
    assert scene.parameters.size == scene.loops.plant_parameter_count + len(layout)
    assert scene.parameters[scene.loops.plant_parameter_count] == 11.0
    constants = CompiledScene(controlled(*numbers[1][0]), dt=DT, references=references(*numbers[1][1]),
                              numbers="constants")                  # one library per model: loops too
    assert constants.loops.parameter_layout == [] and constants.parameters.size == scene.loops.plant_parameter_count
    assert len(libraries(tmp_path)) == 2
    with pytest.raises(ModelError, match="numbers must be 'constants' or 'inputs'.*got 'gains'"):
        ClosedLoops(controlled(*numbers[0][0]), scene.actuators, DT, numbers="gains")


def test_gains_and_references_set_through_fmi_equal_ctmm_simulate(tmp_path):
    exported = controlled(6.0, 2.0, 1.5, 30.0)
    outputs = ["rod.theta", "fore.theta", "pd.u", "late.u", "lag.u"]
    path = ctmm.export_fmu(exported, tmp_path / "arm_loops.fmu", step=DT, q0=X0, qdot0=V0, outputs=outputs,
                           references=references(0.2, 0.05))
    description = fmpy.read_model_description(str(path))
    parameters = {v.name for v in description.modelVariables if v.causality == "parameter"}
    assert {"pd.gain", "late.gain", "pd.reference.amplitude", "late.reference", "lag.reference"} <= parameters
    assert not parameters & {"lag.A[0,0]", "lag.B[0]", "lag.C[0]", "lag.D"}     # a realisation is not exposed
    changed = {"pd.gain": 11.0, "late.gain": -1.0, "pd.reference.amplitude": -0.4, "pd.reference.omega": 3.0,
               "late.reference": 0.3}
    out = fmpy.simulate_fmu(str(path), stop_time=T_FINAL, output_interval=0.01, start_values=changed)
    native = ctmm.simulate(controlled(11.0, -1.0, 1.5, 30.0), T_FINAL, DT, x0=X0, v0=V0,
                           references={"pd": Harmonic(-0.4, 3.0, 0.2), "late": 0.3})
    rows = np.searchsorted(native.time, out["time"] - 1e-12)
    np.testing.assert_allclose(native.time[rows], out["time"], rtol=0, atol=1e-12)
    for name in outputs:
        assert_round_off(out[name], native[name][rows], name)
    unchanged = fmpy.simulate_fmu(str(path), stop_time=T_FINAL, output_interval=0.01)
    assert np.max(np.abs(unchanged["rod.theta"] - out["rod.theta"])) > 1e-3
