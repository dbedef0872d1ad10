"""Beam station forces and moments in the generated planar kernels (ctmm.compiled_station_loads, issue 13 item 1).

Open-loop inputs and loops on ``"<beam>.<station>.force|moment"`` enter the generated sweep with their modal forces and
their wrench on the beam's floating frame.  Checks: the generated accelerations against the independent Lagrange model
(:mod:`ctmm.reference.flexible_lagrange`, the same load as a beam point load turning with the frame); whole runs of
the generated RK4 and of the generated DT-TMM scheme against the numpy path (its station loads Lagrange-checked in
tests/test_beam_stations.py).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.compiled_scene import CompiledScene
from ctmm.control import ControlledModel, Feedback
from ctmm.flexible import ModalBeam
from ctmm.planar import ActuatedHinge, Fixed, Load, PlanarModel, RigidBody
from ctmm.planar.elements import FixedMounting
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.signals import Harmonic

pytest.importorskip("casadi")

STATIONS = {"a": 0.3, "b": 0.8}


def hub_beam(loads: tuple = ()) -> PlanarModel:
    """A hub on a motor hinge with a welded two-mode beam carrying two stations (gravity in the plane)."""
    beam = ModalBeam("arm", length=1.0, bending_stiffness=20.0, mass_per_length=0.5, n_modes=2, stations=STATIONS,
                     loads=loads)
    return PlanarModel.chain("hb", [Fixed("ground"), ActuatedHinge("motor", kp=3.0, kd=0.2),
                                    RigidBody("hub", mass=2.0, inertia=0.1, outboard=(0.1, 0.0)),
                                    FixedMounting("mount"), beam], gravity=(0.0, -9.81))


def test_generated_station_loads_equal_the_lagrange_model_with_the_same_point_load():
    model = hub_beam()
    force, moment = 0.8, -0.3
    scene = CompiledScene(ControlledModel(model, []), signals={"arm.a.force": force, "arm.b.moment": moment})
    rng = np.random.default_rng(5)
    q, v = rng.normal(size=model.n_coordinates) * 0.02, rng.normal(size=model.n_coordinates) * 0.1
    theta = 0.7                                         # the station force turns with the beam frame
    q[model.coordinate_index("hub.theta")] = theta
    loads = (Load(point=(STATIONS["a"], 0.0), force_x=-np.sin(theta) * force, force_y=np.cos(theta) * force),
             Load(point=(STATIONS["b"], 0.0), moment=moment))
    reference = FlexibleLagrange(hub_beam(loads)).accelerations(q, v)
    unloaded = FlexibleLagrange(model).accelerations(q, v)
    generated = scene.closed_loop_rates(np.concatenate([q, v]))[model.n_coordinates:]
    assert np.max(np.abs(reference - unloaded)) > 0.1               # the loads matter at this state
    np.testing.assert_allclose(generated, reference, rtol=1e-9, atol=1e-9)


def test_station_inputs_run_as_the_numpy_path():
    model = hub_beam()
    x0 = np.array([0.2, 0.01, -0.005])
    inputs = {"arm.b.force": Harmonic(0.5, 7.0), "arm.a.moment": 0.2, "motor.torque": 0.1}
    numpy_run = ctmm.simulate(model, 0.2, 1e-3, x0=x0, inputs=inputs, method="rk4")
    generated = ctmm.simulate(model, 0.2, 1e-3, x0=x0, inputs=inputs, compiled=True)
    for name in model.coordinates:
        scale = float(np.max(np.abs(numpy_run[name])))
        assert scale > 0.0 and np.max(np.abs(generated[name] - numpy_run[name])) < 1e-11 * scale, name


@pytest.mark.parametrize("delay", [0.0, 2e-3])
def test_a_loop_on_a_station_force_with_a_frame_wrench_runs_as_the_numpy_path(delay):
    """A PD loop on one station force (its frame wrench does not cancel), real-time and delayed."""
    model = hub_beam()
    loop = Feedback("pd", [("arm.b.w", 1.0), ("arm.b.w_dot", 0.05)], "arm.b.force", gain=40.0, delay=delay)
    system = ControlledModel(model, [loop])
    x0 = np.array([0.1, 0.02, 0.0])
    numpy_run = ctmm.simulate(system, 0.1, 1e-3, x0=x0, inputs={"motor.torque": 0.3})
    generated = ctmm.simulate(system, 0.1, 1e-3, x0=x0, inputs={"motor.torque": 0.3}, compiled=True)
    for name in [*model.coordinates, "pd.u"]:
        scale = float(np.max(np.abs(numpy_run[name])))
        assert scale > 0.0 and np.max(np.abs(generated[name] - numpy_run[name])) < 1e-11 * scale, name


def test_a_station_loop_and_input_in_the_generated_newmark_step_equal_the_python_scheme():
    """The same channels in the generated DT-TMM Newton step (ctmm.compiled_scheme_loops)."""
    model = hub_beam()
    loop = Feedback("pd", [("arm.b.w", 1.0), ("arm.b.w_dot", 0.05)], "arm.b.force", gain=40.0)
    system = ControlledModel(model, [loop])
    options = dict(x0=np.array([0.1, 0.02, 0.0]), inputs={"arm.a.moment": Harmonic(0.3, 5.0)}, method="newmark")
    python = ctmm.simulate(system, 0.1, 1e-3, **options)
    generated = ctmm.simulate(system, 0.1, 1e-3, compiled=True, **options)
    for name in [*model.coordinates, "pd.u"]:
        assert np.ptp(python[name]) > 0.0 and np.max(np.abs(generated[name] - python[name])) <= 1e-10, name
