"""Co-simulated controllers around the generated DT-TMM schemes of 1-D chains: ``ctmm.simulate(chain,
method=<scheme>, compiled=True, controllers=[...])`` (:func:`ctmm.compiled_cosim.simulate_cosimulated_scheme` on
:class:`ctmm.compiled_chain_schemes.CompiledChainScheme` with held inputs).

Independent checks:

* the exact sampled-data solution of a one-mass chain (``scipy.linalg.expm`` of ``m x'' = -k x + F_j`` with the
  held force, the P law written in ``test_compiled_cosim.sampled_p_loop``): the generated Newmark between the
  samples converges to it at second order;
* the Python DT-TMM path of the same chain and controllers (``compiled`` off,
  :func:`ctmm.control.simulate.simulate_controlled`): the same scheme, samples and acceleration restarts, so the
  positions, velocities, loop signals and every sample record agree to round-off for every scheme (also the
  accelerations and forces where the scheme's own acceleration is the equation of motion's: Newmark, Houbolt,
  forward Euler);
* failures stop at the same time with the same partial result; what the generated step cannot do is refused by name,
  (planar and spatial models' generated schemes with controllers: ``tests/test_compiled_scheme_cosim.py``).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.control.measurement_delay import DelayedController
from ctmm.errors import ModelError, SimulationError
from ctmm.signals import Harmonic

from _controllers_import import load_controllers
from test_compiled_cosim import Failing, assert_same, kernel_cache, sampled_p_loop, torsion  # noqa: F401 (fixture)
from test_compiled_cosim_chain import MASS, STIFFNESS, one_mass, three_masses

pytest.importorskip("casadi")

SCHEMES = ("newmark", "generalized_alpha", "wilson_theta", "houbolt", "forward_euler")


def pid(sensor: str, actuator: str, sample_time: float, **gains: float):
    values = {"kp": 1.0, "ki": 0.0, "kd": 0.0, "derivative_filter_time": 0.0, **gains}
    return load_controllers().PID(sensor, actuator, sample_time=sample_time, **values)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_sampled_controllers_and_loops_equal_the_python_dttmm_path(scheme):
    """A PID on m2 every 3 steps and a P law across the connector k1 every 2 steps, a real-time loop and a delayed
    loop with a reference inside the step, a harmonic load on m0."""
    system = ControlledChain(three_masses(), [Feedback("late", "m1.x", "m1", gain=20.0, delay=0.004),
                                              Feedback("now", "m0.v", "m0", gain=2.0)])
    controllers = [pid("m2.x", "m2.force", 0.003, kp=40.0, ki=10.0, kd=3.0, derivative_filter_time=0.01,
                       reference=0.01), pid("m0.v", "k1.force", 0.002, kp=4.0)]
    arguments = dict(method=scheme, x0={"m1": 0.02}, v0={"m0": 0.1}, controllers=controllers,
                     references={"late": Harmonic(0.005, 4.0)})
    generated = ctmm.simulate(system, 0.09, 1e-3, compiled=True, **arguments)
    python = ctmm.simulate(system, 0.09, 1e-3, **arguments)
    assert generated.scheme_name == f"{scheme}-generated" and generated.info["intervals"] == 60
    assert generated.info["controllers"] == python.info["controllers"]
    assert generated.info["loops"] == python.info["loops"]
    names = [f"{p}.{q}" for p in ("m0", "m1", "m2") for q in ("x", "v")] + ["late.y", "late.u", "now.y", "now.u"]
    if scheme in ("newmark", "houbolt", "forward_euler"):  # the scheme's acceleration is the equation of motion's
        names += ["m0.a", "m1.a", "m2.a", "k0.f", "k1.f", "k2.f"]
    assert_same(generated, python, names)


def test_one_mass_with_a_sampled_p_controller_converges_to_the_exact_zoh_solution():
    """F_j = kp (r - x_j) held on [t_j, t_j + h): the generated Newmark converges to the matrix-exponential
    solution of the sampled-data loop at second order (the acceleration restarts where the force jumps)."""
    kp, r, h, x0 = 30.0, 0.02, 0.02, 0.05
    controller = pid("m.x", "m.force", h, kp=kp, reference=r)
    exact = sampled_p_loop(STIFFNESS, MASS, kp, r, h, x0, 25)
    errors = []
    for dt in (h / 4, h / 8):
        run = ctmm.simulate(one_mass(), 0.5, dt, method="newmark", x0={"m": x0}, controllers=[controller],
                            compiled=True)
        errors.append(np.max(np.abs(run["m.x"][::round(h / dt)] - exact)))
    assert errors[0] < 2e-4 * x0
    assert 3.5 < errors[0] / errors[1] < 4.5            # second order: 4x per halving


def test_stored_every_few_steps_are_the_rows_of_every_step():
    """``store_every`` keeps every k-th step and the last (the Python path stores every step): the same rows as the
    run storing every step, the accelerations formed with the held outputs of each row's step."""
    arguments = dict(method="wilson_theta", x0={"m1": 0.02}, compiled=True,
                     controllers=[pid("m2.x", "m2.force", 0.003, kp=40.0, reference=0.01)])
    every = ctmm.simulate(three_masses(), 0.05, 1e-3, **arguments)
    fourth = ctmm.simulate(three_masses(), 0.05, 1e-3, store_every=4, **arguments)
    rows = list(range(0, 51, 4)) + [50]
    np.testing.assert_array_equal(fourth.time, every.time[rows])
    for name in ("m0.x", "m2.v", "m2.a", "k2.f"):
        np.testing.assert_array_equal(fourth[name], every[name][rows], err_msg=name)


def test_failures_stop_where_the_python_path_stops():
    failed = []
    for compiled in (True, None):
        with pytest.raises(SimulationError, match="controller broke") as error:
            ctmm.simulate(one_mass(), 0.1, 5e-3, method="newmark", x0={"m": 0.1},
                          controllers=[Failing("m.x", "m.force")], compiled=compiled)
        failed.append(error.value)
    assert failed[0].time == pytest.approx(0.02) == failed[1].time
    np.testing.assert_array_equal(failed[0].partial_result.time, failed[1].partial_result.time)
    np.testing.assert_allclose(failed[0].partial_result["m.x"], failed[1].partial_result["m.x"], rtol=0, atol=1e-15)
    wild = pid("m.x", "m.force", 5e-3, kp=-1e4)
    stops = []
    for compiled in (True, None):
        with pytest.raises(SimulationError, match="diverged|bound") as error:
            ctmm.simulate(one_mass(), 2.0, 5e-3, method="newmark", x0={"m": 0.1}, controllers=[wild],
                          compiled=compiled, stability_check="ignore")
        stops.append(error.value.time)
    assert stops[0] == stops[1] and 0 < stops[0] < 2.0


def test_what_the_generated_scheme_cosimulation_refuses():
    chain = three_masses()
    arguments = dict(method="newmark", compiled=True)
    with pytest.raises(ModelError, match="'m1.a' .*positions and velocities"):
        ctmm.simulate(chain, 0.1, 1e-3, controllers=[pid("m1.a", "m1.force", 1e-3)], **arguments)
    with pytest.raises(ModelError, match="'k1.f' .*positions and velocities"):
        ctmm.simulate(chain, 0.1, 1e-3, controllers=[pid("k1.f", "m1.force", 1e-3)], **arguments)
    with pytest.raises(ModelError, match="measurement delay"):
        ctmm.simulate(chain, 0.1, 1e-3, controllers=[DelayedController(pid("m1.x", "m1.force", 1e-3), 2e-3)],
                      **arguments)
    with pytest.raises(ModelError, match="t0=0.5 does not apply"):
        ctmm.simulate(chain, 1.0, 1e-3, t0=0.5, controllers=[pid("m1.x", "m1.force", 1e-3)], **arguments)
    with pytest.raises(ModelError, match="unknown input 'm1'"):
        ctmm.simulate(chain, 0.1, 1e-3, controllers=[pid("m1.x", "m1", 1e-3)], **arguments)
