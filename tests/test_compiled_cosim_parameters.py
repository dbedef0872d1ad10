"""``ctmm.simulate(..., compiled=True, parameters=..., controllers=[...])``: the compiled co-simulation of
the parameter set's model on the one shared kernel (numbers as inputs), :meth:`ctmm.batch.ParameterKernel.run`.

Independent checks: the exact sampled-data solution of the linear torsion plant with the set's stiffness
(``scipy.signal.cont2discrete`` with the input held, the P law written here), and the numpy path of the model built
with the set's numbers (same RK4, same samples: equal to round-off).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.signal

import ctmm
from ctmm.control import Feedback, with_feedback
from ctmm.planar import ElasticHinge, Fixed, PlanarModel, RigidBody

from _controllers_import import load_controllers

pytest.importorskip("casadi")

INERTIA, KP, REFERENCE, SAMPLE, THETA0 = 0.5, 12.0, 0.2, 0.02, 0.1


@pytest.fixture(autouse=True, scope="module")
def _cache(tmp_path_factory):
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("CTMM_CACHE", str(tmp_path_factory.mktemp("kernels")))
        yield


def torsion(stiffness: float) -> PlanarModel:
    """One body on an elastic hinge at its centre of mass, no gravity: I theta'' = -k theta + torque."""
    return PlanarModel.chain("torsion", [Fixed("g"), ElasticHinge("h", stiffness=stiffness),
                                         RigidBody("b", mass=1.0, inertia=INERTIA, center_of_mass=(0.0, 0.0))],
                             gravity=(0.0, 0.0))


def p_controller():
    return load_controllers().PID("h.angle", "h.torque", kp=KP, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                  sample_time=SAMPLE, reference=REFERENCE)


def test_a_parameter_set_with_a_sampled_controller_equals_the_exact_zoh_solution():
    stiffness, dt = 60.0, SAMPLE / 4
    run = ctmm.simulate(torsion(40.0), 1.0, dt, x0=[THETA0], controllers=[p_controller()], compiled=True,
                        parameters={"h.stiffness": stiffness})
    assert run.scheme_name == "rk4-generated" and run.info["parameters"] == {"h.stiffness": stiffness}
    assert run.info["intervals"] == 50
    plant = (np.array([[0.0, 1.0], [-stiffness / INERTIA, 0.0]]), np.array([[0.0], [1.0 / INERTIA]]),
             np.array([[1.0, 0.0]]), np.zeros((1, 1)))
    phi, gamma, *_ = scipy.signal.cont2discrete(plant, SAMPLE, method="zoh")     # input held over a sample
    closed = phi - KP * gamma @ plant[2]                                        # u_j = kp (r - theta_j)
    exact = [THETA0]
    z = np.array([THETA0, 0.0])
    for _ in range(50):
        z = closed @ z + gamma[:, 0] * KP * REFERENCE
        exact.append(z[0])
    assert np.max(np.abs(run["b.theta"][::4] - exact)) < 1e-6      # RK4 at dt = h / 4 (test_compiled_cosim)


def test_loops_and_controllers_with_parameters_equal_the_numpy_path_of_the_built_model():
    def model(stiffness: float, gain: float):
        return with_feedback(torsion(stiffness), [Feedback("damp", "b.omega", "h.torque", gain=gain, delay=0.01)])

    arguments = dict(x0=[THETA0], outputs=["h.angle"], store_every=3)
    generated = ctmm.simulate(model(40.0, 0.3), 0.3, 2e-3, compiled=True, controllers=[p_controller()],
                              parameters={"h.stiffness": 55.0, "damp.gain": 0.8}, **arguments)
    python = ctmm.simulate(model(55.0, 0.8), 0.3, 2e-3, controllers=[p_controller()], **arguments)
    np.testing.assert_array_equal(generated.time, python.time)
    for name in ("b.theta", "b.theta_dot", "h.angle", "damp.y", "damp.u"):
        np.testing.assert_allclose(generated[name], python[name], rtol=0.0, atol=1e-12, err_msg=name)
    np.testing.assert_allclose(generated["h.torque@samples"], python["h.torque@samples"], rtol=0.0, atol=1e-12)


def test_a_spatial_parameter_set_with_a_controller_equals_the_numpy_path_of_the_built_model():
    from ctmm.parameter_sets import parameter_names, with_parameters
    from test_spatial_control_time import LOOPS, V0, X0, arm

    pid = load_controllers().PID("yaw.angle", "yaw.torque", kp=4.0, ki=2.0, kd=0.3, derivative_filter_time=0.02,
                                 sample_time=0.01, reference=0.1)
    plant = with_feedback(arm(), LOOPS[1:2])
    name, (_, mass) = next((n, entry) for n, entry in parameter_names(plant).items() if n.endswith(".mass"))
    value = 1.3 * mass
    arguments = dict(x0=X0, v0=V0, controllers=[pid], outputs=["hand.tip.z"], store_every=2)
    generated = ctmm.simulate(plant, 0.1, 5e-3, compiled=True, parameters={name: value}, **arguments)
    python = ctmm.simulate(with_parameters(plant, {name: value}), 0.1, 5e-3, **arguments)
    np.testing.assert_array_equal(generated.time, python.time)
    for signal in ["hand.tip.z", "yaw.torque@samples"] + list(arm().coordinates):
        np.testing.assert_allclose(generated[signal], python[signal], rtol=0.0, atol=1e-12, err_msg=signal)
