"""One generated kernel over parameter sets: ``ctmm.simulate(..., compiled=True, parameters=...)`` and
``ctmm.simulate_batch`` (issue 13).

Independent checks: every member equals a model *built by hand with the member's numbers* and run by the
numpy path (``ctmm.simulate`` without ``compiled``), to round-off; one spatial member equals the
independent global reference ``ctmm.reference.spatial_tree`` (its own RK4 on ``M(q) v_dot = tau - b``);
the cache folder's files (counted by the operating system) show that one library served every set.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.errors import ModelError, SimulationError
from ctmm.flexible import ModalBeam
from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody, SpringDamperHinge
from ctmm.planar.elements import FixedMounting
from ctmm.reference import spatial_tree as ref
from ctmm.signals import Harmonic

pytest.importorskip("casadi")

from spatial_linear_helpers import reference_tree  # noqa: E402

DT, T_FINAL = 2e-3, 0.2
X0, V0 = np.array([0.4, -0.3]), np.array([0.0, 0.5])


def arm(rod_mass=1.0, rod_inertia=0.06, fore_mass=0.5, stiffness=3.0, damping=0.2, amplitude=0.4,
        gravity=-9.81) -> PlanarModel:
    """A double pendulum with a harmonic motor torque and a sprung, damped elbow, written out number by number."""
    return PlanarModel.chain("arm", [
        Fixed("ground"), ActuatedHinge("pivot", torque=Harmonic(amplitude, 5.0, 0.1)),
        RigidBody("rod", mass=rod_mass, inertia=rod_inertia, center_of_mass=(0.4, 0.0), outboard=(0.8, 0.0)),
        SpringDamperHinge("elbow", stiffness=stiffness, damping=damping),
        RigidBody("fore", mass=fore_mass, inertia=0.015, center_of_mass=(0.3, 0.0), outboard=(0.6, 0.0))],
        gravity=(0.0, gravity))


PLANAR_SETS = [({"rod.mass": 1.4, "elbow.stiffness": 5.0, "pivot.law.torque.amplitude": 0.9},
                dict(rod_mass=1.4, stiffness=5.0, amplitude=0.9)),
               ({"rod.inertia": 0.09, "fore.mass": 0.8, "elbow.damping": 0.05, "gravity.y": -3.0},
                dict(rod_inertia=0.09, fore_mass=0.8, damping=0.05, gravity=-3.0)),
               ({}, {})]


def libraries(folder) -> list[str]:
    return sorted(path.name for path in (folder / "kernels").iterdir())


def assert_round_off(value, expected, name, tolerance=1e-12):
    scale = max(1.0, float(np.max(np.abs(expected))))
    assert np.max(np.abs(np.asarray(value) - expected)) < tolerance * scale, name


def test_planar_sets_on_one_library_equal_models_built_with_their_numbers(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    outputs = ["fore.out.y"]
    batch = ctmm.simulate_batch(arm(), [values for values, _ in PLANAR_SETS], T_FINAL, DT, x0=X0, v0=V0,
                                outputs=outputs)
    assert not batch.failures and len(libraries(tmp_path)) == 1
    names = ["rod.theta", "fore.theta", "rod.theta_dot", "fore.theta_dot", "fore.out.y"]
    for k, (values, numbers) in enumerate(PLANAR_SETS):
        numpy_run = ctmm.simulate(arm(**numbers), T_FINAL, DT, method="rk4", x0=X0, v0=V0, outputs=outputs)
        assert batch.results[k].info["parameters"] == values and batch.results[k].info["kernel"] == "shared"
        for name in names:
            assert_round_off(batch.results[k][name], numpy_run[name], (k, name))
            assert_round_off(batch.stacked(name)[k], numpy_run[name], (k, name))
    assert np.max(np.abs(batch.stacked("rod.theta")[0] - batch.stacked("rod.theta")[2])) > 1e-3   # numbers matter
    single = ctmm.simulate(arm(), T_FINAL, DT, x0=X0, v0=V0, compiled=True, parameters=PLANAR_SETS[0][0])
    assert_round_off(single["fore.theta"], batch.results[0]["fore.theta"], "simulate(parameters=)", 1e-15)
    assert len(libraries(tmp_path)) == 1


def hub_beam(hub_inertia: float = 0.05, torque: float = 2.0) -> PlanarModel:
    """A hub on a harmonic motor carrying a modal beam (3 modes, stiffening): the beam's data stay constants."""
    beam = ModalBeam("beam", length=1.0, bending_stiffness=12.0, mass_per_length=0.8, n_modes=3,
                     geometric_stiffening=True, damping_ratio=0.005)
    return PlanarModel.chain("hub_beam", [
        Fixed("ground"), ActuatedHinge("motor", torque=Harmonic(torque, 3.0, 0.0)),
        RigidBody("hub", mass=2.0, inertia=hub_inertia, center_of_mass=(0.0, 0.0), outboard=(0.1, 0.0)),
        FixedMounting("mount"), beam], gravity=(0.0, 0.0))


def test_hub_beam_sets_keep_the_beam_and_equal_the_numpy_path(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    assert list(ctmm.parameter_names(hub_beam())) == ["hub.mass", "hub.inertia", "motor.law.torque.amplitude",
                                                      "motor.law.torque.omega"]
    sets = [(0.05, 2.0), (0.08, 3.5)]
    batch = ctmm.simulate_batch(hub_beam(), [{"hub.inertia": inertia, "motor.law.torque.amplitude": torque}
                                             for inertia, torque in sets], 0.1, 1e-3)
    assert not batch.failures and len(libraries(tmp_path)) == 1
    for k, (inertia, torque) in enumerate(sets):
        numpy_run = ctmm.simulate(hub_beam(inertia, torque), 0.1, 1e-3, method="rk4")
        for name in hub_beam().coordinates:
            assert_round_off(batch.results[k][name], numpy_run[name], (k, name))


def controlled_arm(gain: float, rod_mass: float = 1.0) -> ControlledModel:
    """The arm with a real-time PD on the shoulder and a delayed loop (3 steps) on the elbow."""
    loops = [Feedback("pd", [("rod.theta", 1.0), ("rod.omega", 0.3)], "pivot.torque", gain=gain),
             Feedback("late", "elbow.angle", "elbow.torque", gain=-0.8 * gain, delay=3 * DT)]
    return ControlledModel(arm(rod_mass=rod_mass), loops)


def test_controlled_planar_gain_sweep_equals_the_numpy_loop_driver(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    sets = {"pd.gain": [4.0, 9.0], "late.gain": [-3.2, 0.0], "rod.mass": [1.0, 1.6],
            "pd.reference.amplitude": [0.1, 0.3], "late.reference": [0.0, -0.2]}
    references = {"pd": Harmonic(0.1, 7.0, 0.2)}
    assert {"pd.reference.amplitude", "pd.reference.omega", "late.reference"} <= set(
        ctmm.parameter_names(controlled_arm(4.0), references))
    batch = ctmm.simulate_batch(controlled_arm(4.0), sets, 0.1, DT, x0=X0, v0=V0, references=references)
    assert not batch.failures and len(libraries(tmp_path)) == 1
    for k in range(2):
        model = controlled_arm(sets["pd.gain"][k], sets["rod.mass"][k])
        late = model.loops[1].with_parameters(gain=sets["late.gain"][k])
        model = ControlledModel(model.plant, [model.loops[0], late])
        numpy_run = ctmm.simulate(model, 0.1, DT, method="rk4", x0=X0, v0=V0,
                                  references={"pd": Harmonic(sets["pd.reference.amplitude"][k], 7.0, 0.2),
                                              "late": sets["late.reference"][k]})
        for name in ["rod.theta", "fore.theta_dot", "pd.u", "late.u", "late.y"]:
            assert_round_off(batch.results[k][name], numpy_run[name], (k, name))


def spatial_arm(masses=(1.0, 0.7, 0.5), inertia_zz=0.05, stiffness=2.0, damping=0.3, gravity_z=-9.81):
    """Three links on revolute joints (sprung, damped), written out number by number."""
    elements = []
    for i, mass in enumerate(masses):
        inertia = np.diag([0.01, 0.04, inertia_zz if i == 1 else 0.05])
        elements.append(sp.SpatialBody(f"l{i}", mass, inertia, (0.25, 0.02, 0.0), {"end": (0.5, 0.0, 0.05)}))
        elements.append(sp.Revolute(name=f"j{i}", parent=None if i == 0 else f"l{i - 1}", child=f"l{i}",
                                    point=(0.0, 0.0, 0.0) if i == 0 else "end", axis=(0, 1, 0) if i != 1 else (1, 0, 1),
                                    stiffness=stiffness if i == 2 else 0.5, damping=damping if i == 2 else 0.1,
                                    actuated=i == 1))
    return sp.SpatialModel("arm3", elements, gravity=(0.0, 0.4, gravity_z))


SPATIAL_SETS = [({"l0.mass": 1.5, "l1.inertia.zz": 0.045, "j2.stiffness": 6.0}, dict(masses=(1.5, 0.7, 0.5),
                                                                                      inertia_zz=0.045, stiffness=6.0)),
                ({"l2.mass": 0.9, "j2.damping": 0.05, "gravity.z": -4.0}, dict(masses=(1.0, 0.7, 0.9), damping=0.05,
                                                                               gravity_z=-4.0))]


def test_spatial_sets_on_one_library_equal_the_numpy_path_and_the_reference(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    q0, v0 = np.array([0.3, -0.5, 0.2]), np.array([0.1, 0.4, -0.2])
    batch = ctmm.simulate_batch(spatial_arm(), [values for values, _ in SPATIAL_SETS], T_FINAL, DT, x0=q0, v0=v0)
    assert not batch.failures and len(libraries(tmp_path)) == 1
    for k, (values, numbers) in enumerate(SPATIAL_SETS):
        model = spatial_arm(**numbers)
        numpy_run = ctmm.simulate(model, T_FINAL, DT, method="rk4", x0=q0, v0=v0)
        for name in list(model.coordinates) + list(model.velocities):
            assert_round_off(batch.results[k][name], numpy_run[name], (k, name))
    single = ctmm.simulate(spatial_arm(), T_FINAL, DT, x0=q0, v0=v0, compiled=True, parameters=SPATIAL_SETS[1][0])
    assert_round_off(single["j2.angle"], batch.results[1]["j2.angle"], "simulate(parameters=)", 1e-15)
    assert len(libraries(tmp_path)) == 1
    model = spatial_arm(**SPATIAL_SETS[0][1])                    # the independent global reference
    run = ref.simulate(reference_tree(model), q0, v0, T_FINAL, DT)
    for i, name in enumerate(model.coordinates):
        assert_round_off(batch.results[0][name], run.q[:, i], name, 1e-11)


def test_controlled_spatial_sets_on_one_library_equal_the_numpy_path(tmp_path, monkeypatch):
    """Plant numbers and loop gains as inputs of one CompiledControlledSpatial: a joint-torque loop, a delayed
    body-force loop at a point (its wrench part of the body's terms kept from the numeric terms), an output."""
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    q0, v0 = np.array([0.3, -0.5, 0.2]), np.zeros(3)

    def controlled(gain, push, mass, stiffness):
        plant = spatial_arm(masses=(1.0, 0.7, mass), stiffness=stiffness)
        return ControlledModel(plant, [Feedback("hold", "j1.angle", "j1.torque", gain=gain),
                                       Feedback("push", "l2.end.vz", "l2.end.force_z", gain=push, delay=2 * DT)])

    sets = {"hold.gain": [5.0, 1.5], "push.gain": [0.8, 2.0], "l2.mass": [0.5, 0.9], "j2.stiffness": [2.0, 7.0]}
    batch = ctmm.simulate_batch(controlled(2.0, 1.0, 0.5, 2.0), sets, 0.1, DT, x0=q0, v0=v0, outputs=["l2.end.z"],
                                references={"hold": 0.05})
    assert not batch.failures and len(libraries(tmp_path)) == 1
    for k in range(2):
        model = controlled(*(sets[name][k] for name in sets))
        numpy_run = ctmm.simulate(model, 0.1, DT, method="rk4", x0=q0, v0=v0, outputs=["l2.end.z"],
                                  references={"hold": 0.05})
        assert batch.results[k].info["kernel"] == "shared"
        for name in ["j0.angle", "j1.angle", "j2.angle_rate", "hold.u", "push.u", "l2.end.z"]:
            assert_round_off(batch.results[k][name], numpy_run[name], (k, name))


def test_a_failing_set_is_reported_by_index_and_the_others_kept(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    sets = [{"pivot.law.torque.amplitude": 0.4}, {"pivot.law.torque.amplitude": 400.0},
            {"pivot.law.torque.amplitude": 0.5}]
    batch = ctmm.simulate_batch(arm(), sets, T_FINAL, DT, x0=X0, v0=V0, divergence_bound=2.0, executor="threads")
    assert list(batch.failures) == [1] and isinstance(batch.failures[1], SimulationError)
    assert batch.results[1] is None and batch.failures[1].partial_result is not None
    assert np.all(np.isnan(batch.stacked("rod.theta")[1])) and np.all(np.isfinite(batch.stacked("rod.theta")[[0, 2]]))
    numpy_run = ctmm.simulate(arm(amplitude=0.5), T_FINAL, DT, method="rk4", x0=X0, v0=V0)
    assert_round_off(batch.results[2]["fore.theta"], numpy_run["fore.theta"], "set 2 on a thread")


def test_a_body_inertia_is_set_as_a_whole():
    """xx, yy, zz together (one at a time the second would break the triangle inequality) equal a hand-built
    body; a set that breaks it as a whole is refused by the body's own check."""
    values = {"l1.inertia.xx": 0.03, "l1.inertia.yy": 0.08, "l1.inertia.zz": 0.1}
    changed = ctmm.parameter_sets.with_parameters(spatial_arm(), values)
    assert np.array_equal(changed.bodies[1].inertia, np.diag([0.03, 0.08, 0.1]))
    with pytest.raises(ModelError, match="triangle inequality"):
        ctmm.parameter_sets.with_parameters(spatial_arm(), {"l1.inertia.zz": 0.2})


def test_sets_on_worker_processes_load_the_kernel_from_the_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    sets = [{"fore.mass": 0.5}, {"pivot.law.torque.amplitude": 400.0}, {"fore.mass": 0.9}]
    batch = ctmm.simulate_batch(arm(), sets, T_FINAL, DT, x0=X0, executor="processes", divergence_bound=2.0)
    assert list(batch.failures) == [1] and isinstance(batch.failures[1], SimulationError)
    assert batch.failures[1].time > 0.0 and batch.failures[1].partial_result is not None
    assert len(libraries(tmp_path)) == 1
    numpy_run = ctmm.simulate(arm(fore_mass=0.9), T_FINAL, DT, method="rk4", x0=X0)
    assert_round_off(batch.stacked("fore.theta")[2], numpy_run["fore.theta"], "set 2 in a worker process")


def test_bad_parameters_are_refused_by_name(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    with pytest.raises(ModelError, match=r"unknown parameter 'rod.length'; allowed: rod.mass, fore.mass"):
        ctmm.simulate(arm(), T_FINAL, DT, compiled=True, parameters={"rod.length": 1.0})
    with pytest.raises(ModelError, match=r"parameter_sets\[1\]: .*'elbow.stiffness'\] = 0"):
        ctmm.simulate_batch(arm(), [{"rod.mass": 2.0}, {"elbow.stiffness": 0.0}], T_FINAL, DT)
    with pytest.raises(ModelError, match=r"must be a finite number .*got nan"):
        ctmm.simulate(arm(), T_FINAL, DT, compiled=True, parameters={"rod.mass": float("nan")})
    with pytest.raises(ModelError, match="give compiled=True"):
        ctmm.simulate(arm(), T_FINAL, DT, parameters={"rod.mass": 2.0})
    with pytest.raises(ModelError, match="method='newmark'"):
        ctmm.simulate(arm(), T_FINAL, DT, method="newmark", compiled=True, parameters={"rod.mass": 2.0})
    with pytest.raises(ModelError, match="1-D chains"):
        ctmm.simulate_batch(object(), [{"m": 1.0}], T_FINAL, DT)
    with pytest.raises(ModelError, match=r"unknown parameter 'l0.inertia.xy'"):
        ctmm.parameter_sets.with_parameters(spatial_arm(), {"l0.inertia.xy": 0.001})
    with pytest.raises(ModelError, match=r"x0 must be .* an array of length 2"):      # before any set runs
        ctmm.simulate_batch(arm(), [{"rod.mass": 2.0}], T_FINAL, DT, x0=[0.1, 0.2, 0.3])
    with pytest.raises(ModelError, match="stability_check='error' is not available .* spatial"):
        ctmm.simulate_batch(spatial_arm(), [{"l0.mass": 2.0}], T_FINAL, DT, stability_check="error")
    with pytest.raises(ModelError, match="divergence_bound"):
        ctmm.simulate_batch(arm(), [{"rod.mass": 2.0}], T_FINAL, DT, divergence_bound=-1.0)
    control = pytest.importorskip("control")
    lagged = ControlledModel(arm(), [Feedback("lag", "fore.omega", "elbow.torque", gain=control.tf([2.0], [1.0, 5.0]))])
    assert "lag.gain" not in ctmm.parameter_names(lagged) and "lag.reference" in ctmm.parameter_names(lagged)
    with pytest.raises(ModelError, match=r"unknown parameter 'lag.gain'; allowed: .*elbow.stiffness"):
        ctmm.simulate(lagged, T_FINAL, DT, compiled=True, parameters={"lag.gain": 3.0})
    with pytest.raises(ModelError, match="equally long 1-D columns"):
        ctmm.simulate_batch(arm(), {"rod.mass": [1.0, 2.0], "fore.mass": [1.0]}, T_FINAL, DT)
