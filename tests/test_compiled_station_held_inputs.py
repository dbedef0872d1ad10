"""Beam station forces and moments as held inputs of the generated planar kernels (issue 13).

``"<beam>.<station>.force|moment"`` named in ``station_inputs`` are inputs ``u`` of a generated kernel like any other
actuator (:func:`ctmm.compiled_parameters.compiled_actuators`; their modal forces and floating-frame wrench:
:mod:`ctmm.compiled_station_loads`): held through :meth:`CompiledScene.advance`, over the members of an unlooped
:func:`simulate_batch`; a co-simulated controller driving one names it for the generated RK4 and the generated DT-TMM
scheme itself.

Independent checks:

* statics: a station force ``P`` at ``x = a`` on a hub + welded cantilever ``ModalBeam`` (modal damping, no gravity,
  the hub on a PD hinge of stiffness ``kp``) settles to the hinge angle ``theta = (r + a) P / kp`` (the force turns
  with the beam frame; its moment about the hinge, ``r`` the hub's arm) and to the modal static deflection
  ``eta = K^-1 phi(a) P`` with ``K = EI int phi'' phi''^T dx`` (quadrature here, not the beam's integrals), which is
  the Euler-Bernoulli deflection ``P x^2 (3 a - x) / (6 EI)`` (``x <= a``), ``P a^2 (3 x - a) / (6 EI)`` (``x >= a``)
  up to the truncation of the four modes;
* the numpy path (``ctmm.simulate`` without ``compiled``) of the same model, inputs and controllers: the same RK4 or
  scheme of the same ODE, so the runs agree to round-off.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.compiled_scene import CompiledScene, parameter_vector, simulate_batch
from ctmm.flexible import ModalBeam
from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody
from ctmm.planar.elements import FixedMounting

from _controllers_import import load_controllers

pytest.importorskip("casadi")

EI, LENGTH, STATION, ARM, FORCE = 20.0, 1.0, 0.6, 0.1, 0.4


@pytest.fixture(autouse=True, scope="module")
def kernel_cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CTMM_CACHE", str(tmp_path_factory.mktemp("kernels")))
        yield


def hub_cantilever(kp: float = 3.0) -> PlanarModel:
    """A hub on a PD hinge (stiffness ``kp`` [N m/rad]) with a welded four-mode cantilever, stations ``a`` and
    ``tip``, modal damping 0.7, no gravity."""
    beam = ModalBeam("arm", length=LENGTH, bending_stiffness=EI, mass_per_length=0.5, n_modes=4,
                     stations={"a": STATION, "tip": LENGTH}, damping_ratio=0.7)
    return PlanarModel.chain("hub_cantilever", [
        Fixed("ground"), ActuatedHinge("motor", kp=kp, kd=1.5),
        RigidBody("hub", mass=2.0, inertia=0.1, outboard=(ARM, 0.0)), FixedMounting("mount"), beam],
        gravity=(0.0, 0.0))


def modal_static_deflection(beam: ModalBeam, force: float, at: float) -> np.ndarray:
    """``eta = K^-1 phi(at) force`` with ``K = EI int phi'' phi''^T`` by Gauss-Legendre quadrature."""
    x, w = np.polynomial.legendre.leggauss(200)
    x, w = 0.5 * beam.length * (x + 1.0), 0.5 * beam.length * w
    curvature = beam.shapes(x, 2)
    stiffness = beam.bending_stiffness * (curvature * w) @ curvature.T
    return np.linalg.solve(stiffness, beam.shapes([at], 0)[:, 0] * force)


def euler_bernoulli(x: float) -> float:
    """Static deflection [m] at ``x`` of a cantilever under ``FORCE`` at ``STATION``."""
    a = STATION
    return FORCE * x * x * (3 * a - x) / (6 * EI) if x <= a else FORCE * a * a * (3 * x - a) / (6 * EI)


def test_a_held_station_force_settles_to_the_static_deflection_and_hinge_angle():
    model = hub_cantilever()
    scene = CompiledScene(model, station_inputs=["arm.a.force"])
    assert scene.actuators[-1] == "arm.a.force" and "arm.tip.moment" not in scene.actuators
    zero = np.zeros(model.n_coordinates)
    q, qdot = zero, zero
    for k in range(12):                      # one held interval of 1 s after another, as a sampled controller would
        q, qdot = scene.advance(q, qdot, 1e-3, 1000, inputs={"arm.a.force": FORCE}, t0=float(k))
    beam = model.beams[model.body_names.index("arm")]
    eta = modal_static_deflection(beam, FORCE, STATION)
    assert abs(q[0] - (ARM + STATION) * FORCE / 3.0) < 1e-10          # the frame wrench's moment on the hinge
    np.testing.assert_allclose(q[1:], eta, rtol=0, atol=1e-10 * np.max(np.abs(eta)))
    assert np.max(np.abs(qdot)) < 1e-10
    for x in (0.3, STATION, LENGTH):       # the modal basis's static deflection is Euler-Bernoulli's (4 modes: 1e-3)
        deflection = float(beam.shapes([x], 0)[:, 0] @ q[1:])
        assert abs(deflection / euler_bernoulli(x) - 1.0) < 1.5e-3, x


def test_held_station_loads_through_advance_equal_the_numpy_path():
    model = hub_cantilever()
    scene = CompiledScene(model, station_inputs=["arm.a.force", "arm.tip.moment"])
    x0 = np.array([0.05, 0.002, -0.0005, 0.0, 0.0])
    inputs = {"arm.a.force": FORCE, "arm.tip.moment": -0.15, "motor.torque": 0.05}
    python = ctmm.simulate(model, 0.2, 1e-3, x0=x0, inputs=inputs, method="rk4")
    q, qdot = scene.advance(x0, np.zeros(5), 1e-3, 200, inputs=inputs)
    for k, name in enumerate(model.coordinates):
        scale = float(np.max(np.abs(python[name])))
        assert scale > 0.0 and abs(q[k] - python[name][-1]) < 1e-12 * scale, name
        assert abs(qdot[k] - python[f"{name}_dot"][-1]) < 1e-11 * max(1.0, scale / 0.2), name
    alone = ctmm.simulate(model, 0.2, 1e-3, x0=x0, inputs={"motor.torque": 0.05}, method="rk4")
    assert np.max(np.abs(alone["arm.q1"] - python["arm.q1"])) > 1e-4          # the station loads matter


def test_an_unlooped_batch_with_a_held_station_force_runs_each_member_as_the_numpy_path():
    stiffnesses = (2.0, 3.0, 5.0)
    models = [hub_cantilever(kp) for kp in stiffnesses]
    scene = CompiledScene(models[0], station_inputs=["arm.tip.force", "arm.a.force"])
    parameters = np.array([parameter_vector(model) for model in models])
    x0 = np.array([0.02, 0.001, 0.0, 0.0, 0.0])
    states = simulate_batch(scene, parameters, x0, np.zeros(5), dt=1e-3, n_steps=150, inputs={"arm.tip.force": -0.3})
    for member, model in zip(states, models):
        python = ctmm.simulate(model, 0.15, 1e-3, x0=x0, inputs={"arm.tip.force": -0.3}, method="rk4")
        for k, name in enumerate(model.coordinates):
            scale = float(np.max(np.abs(python[name])))
            assert abs(member[-1, k] - python[name][-1]) < 1e-12 * scale, name
    settled = simulate_batch(scene, parameters, np.zeros(5), np.zeros(5), dt=1e-3, n_steps=12000,
                             inputs={"arm.a.force": FORCE})
    for member, kp in zip(settled, stiffnesses):          # each member's hinge carries the load's moment
        assert abs(member[-1, 0] - (ARM + STATION) * FORCE / kp) < 1e-10, kp


def station_controller(sample_time: float):
    """A sampled PD from the station's deflection and rate to the force at the tip."""
    return load_controllers().PID("arm.a.w", "arm.tip.force", kp=30.0, ki=0.0, kd=0.5, derivative_filter_time=0.0,
                                  sample_time=sample_time, reference=0.001)


def test_a_cosimulated_controller_on_a_station_force_equals_the_numpy_path():
    model = hub_cantilever()
    arguments = dict(x0=np.array([0.05, 0.002, 0.0, 0.0, 0.0]), inputs={"motor.torque": 0.05}, outputs=["arm.a.w"])
    generated = ctmm.simulate(model, 0.2, 1e-3, compiled=True, controllers=[station_controller(4e-3)], **arguments)
    python = ctmm.simulate(model, 0.2, 1e-3, controllers=[station_controller(4e-3)], **arguments)
    assert generated.scheme_name == "rk4-generated"
    np.testing.assert_array_equal(generated.time, python.time)
    for name in [*model.coordinates, "arm.a.w"]:
        scale = max(1e-3, float(np.max(np.abs(python[name]))))
        assert np.max(np.abs(generated[name] - python[name])) < 1e-12 * scale, name
    samples = python["arm.tip.force@samples"]
    assert np.ptp(samples[:, 1]) > 1e-3                    # the controller drove the station force
    np.testing.assert_allclose(generated["arm.tip.force@samples"], samples, rtol=0, atol=1e-12)


@pytest.mark.parametrize("scheme", ["newmark", "houbolt"])
def test_a_cosimulated_controller_on_a_station_force_beside_a_generated_scheme_equals_the_python_path(scheme):
    model = hub_cantilever()
    arguments = dict(method=scheme, x0=np.array([0.05, 0.002, 0.0, 0.0, 0.0]),
                     inputs={"motor.torque": 0.05, "arm.a.moment": -0.02}, outputs=["arm.a.w"])
    generated = ctmm.simulate(model, 0.2, 2e-3, compiled=True, controllers=[station_controller(6e-3)], **arguments)
    python = ctmm.simulate(model, 0.2, 2e-3, controllers=[station_controller(6e-3)], **arguments)
    assert generated.scheme_name.startswith("dt-tmm-generated/")
    assert np.array_equal(generated.time, python.time) and generated.signals() == python.signals()
    assert np.ptp(python["arm.tip.force@samples"][:, 1]) > 1e-3
    for name in python.signals():
        assert np.max(np.abs(np.asarray(generated[name]) - np.asarray(python[name]))) <= 1e-10, name


def test_a_cosimulated_controller_on_a_spatial_beam_station_force_beside_a_generated_scheme_equals_the_python_path():
    """A spatial beam's body-axis station force (a port actuator, not an input of the plain generated scheme) driven by
    a sampled controller: the generated Newmark step with the port actuators (no loops) = the Python path."""
    from test_spatial_beam_body_actuators import spatial_arm

    model = spatial_arm("xy")

    def controller():
        return load_controllers().PID("b.p2.w_y", "b.p2.force_body_y", kp=5.0, ki=0.0, kd=0.1,
                                      derivative_filter_time=0.0, sample_time=2e-3, reference=0.01)

    generated = ctmm.simulate(model, 0.05, 1e-3, compiled=True, controllers=[controller()], method="newmark",
                              outputs=["b.p2.w_y"])
    python = ctmm.simulate(model, 0.05, 1e-3, controllers=[controller()], method="newmark", outputs=["b.p2.w_y"])
    assert generated.scheme_name.startswith("dt-tmm-generated/")
    assert np.ptp(python["b.p2.w_y"]) > 1e-6
    for name in python.signals():
        scale = max(1e-6, float(np.max(np.abs(np.asarray(python[name])))))
        assert np.max(np.abs(np.asarray(generated[name]) - np.asarray(python[name]))) <= 1e-10 * scale, name
