"""Body actuators of a spatial model as inputs of an exported FMU (``ctmm.fmu_export_spatial``): world- and
body-axis forces and moments beside the joint inputs.

Independent reference, closed form: a slider of mass m on a prismatic rail along x pushed by a constant world
force F has ``x = F t^2 / (2 m)``; a wheel on a revolute hub about z (inertia I_zz) driven by a hub torque T and
a body-axis moment M about its own z axis (the hub axis) and a body-axis force P along its y axis at the rim
(radius r on its x axis) has ``theta = (T + M + r P) t^2 / (2 I_zz)``.  RK4 is exact
on these quadratics, so the FMU must agree to round-off.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError

fmpy = pytest.importorskip("fmpy")

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")

MASS, INERTIA_ZZ = 2.0, 0.04
FORCE, TORQUE, MOMENT, PUSH, RIM = 3.0, 0.5, -0.2, 0.4, 0.25


@pytest.fixture(autouse=True)
def _cache(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path / "cache"))


def slider_and_wheel() -> sp.SpatialModel:
    return sp.SpatialModel("slider_wheel", [
        sp.SpatialBody("slider", MASS, np.diag([0.1, 0.2, 0.3])),
        sp.SpatialBody("wheel", 0.5, np.diag([0.02, 0.03, INERTIA_ZZ]), points={"rim": (RIM, 0.0, 0.0)}),
        sp.Prismatic(name="rail", parent=None, child="slider", axis=(1.0, 0.0, 0.0)),
        sp.Revolute(name="hub", parent=None, child="wheel", axis=(0.0, 0.0, 1.0), actuated=True)],
        gravity=(0.0, 0.0, -9.81))


def test_body_forces_and_moments_are_fmu_inputs_with_the_closed_form_motion(tmp_path):
    model = slider_and_wheel()
    inputs = ["hub.torque", "slider.force_x", "wheel.moment_body_z", "wheel.rim.force_body_y"]
    path = ctmm.export_fmu(model, tmp_path / "slider_wheel.fmu", step=1e-3, inputs=inputs)
    description = fmpy.read_model_description(str(path))
    declared = {v.name: v for v in description.modelVariables if v.causality == "input"}
    assert list(declared) == inputs
    assert declared["slider.force_x"].unit == "N" and declared["wheel.moment_body_z"].unit == "N m"
    out = fmpy.simulate_fmu(str(path), stop_time=0.2, output_interval=0.05,
                            start_values={"hub.torque": TORQUE, "slider.force_x": FORCE,
                                          "wheel.moment_body_z": MOMENT, "wheel.rim.force_body_y": PUSH})
    t = out["time"]
    np.testing.assert_allclose(out["rail.position"], FORCE * t ** 2 / (2 * MASS), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(out["hub.angle"], (TORQUE + MOMENT + RIM * PUSH) * t ** 2 / (2 * INERTIA_ZZ), rtol=1e-12, atol=1e-15)
    assert out["hub.angle"][-1] > 0.1                                                  # it moved


def test_an_unknown_input_lists_the_body_actuators(tmp_path):
    with pytest.raises(ModelError, match=r"inputs has the unknown name 'slider.force_w'; allowed: hub.torque, "
                                         r".*slider.force_x"):
        ctmm.export_fmu(slider_and_wheel(), tmp_path / "x.fmu", step=1e-3, inputs=["slider.force_w"])
    assert not (tmp_path / "x.fmu").exists()


def test_joint_inputs_carry_the_unit_of_each_component(tmp_path):
    """A free body pushed through its joint's wrench (zero gravity): component 0 is a force, ``x = F t^2 / (2 m)``
    [m]; component 3 a moment, ``omega_x = M t / I_xx`` [rad/s] (closed form); so their units are N and N m, and a
    revolute hub's torque N m."""
    model = sp.SpatialModel("free_and_hub", [
        sp.SpatialBody("block", MASS, np.diag([0.1, 0.2, 0.3])),
        sp.SpatialBody("wheel", 0.5, np.diag([0.02, 0.03, INERTIA_ZZ])),
        sp.Free(name="float", parent=None, child="block", actuated=True),
        sp.Revolute(name="hub", parent=None, child="wheel", axis=(0.0, 0.0, 1.0), actuated=True)],
        gravity=(0.0, 0.0, 0.0))
    path = ctmm.export_fmu(model, tmp_path / "free.fmu", step=1e-3, outputs=["block.position_x", "block.omega_x"])
    declared = {v.name: v.unit for v in fmpy.read_model_description(str(path)).modelVariables
                if v.causality == "input"}
    assert declared == {**{f"float.wrench[{k}]": "N" for k in range(3)},
                        **{f"float.wrench[{k}]": "N m" for k in range(3, 6)}, "hub.torque": "N m"}
    out = fmpy.simulate_fmu(str(path), stop_time=0.2, output_interval=0.05,
                            start_values={"float.wrench[0]": FORCE, "float.wrench[3]": TORQUE})
    t = out["time"]
    np.testing.assert_allclose(out["block.position_x"], FORCE * t ** 2 / (2 * MASS), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(out["block.omega_x"], TORQUE * t / 0.1, rtol=1e-12, atol=1e-15)
