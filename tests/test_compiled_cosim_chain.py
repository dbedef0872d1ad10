"""Co-simulated controllers around the generated RK4 of 1-D lumped chains: ``ctmm.simulate(chain, ...,
method="rk4", compiled=True, controllers=[...])`` (:mod:`ctmm.compiled_cosim` on :mod:`ctmm.compiled_chain`).

Independent checks:

* the exact sampled-data solution of a one-mass chain (``scipy.linalg.expm`` of ``m x'' = -k x + F_j`` with the
  held force, the P law written here): the generated RK4 between the samples converges to it at fourth order;
* the numpy path of the same chain and controllers (``compiled`` off: the one loop driver on the chain's plant,
  ``ctmm.control.planar_time``): the same RK4 of the same ODE with the same samples, so every stored signal --
  including the forces and accelerations, which depend on the held controller outputs -- and every sample record
  agree to round-off, for a Python PID, the shipped PD FMU read late (``DelayedController``), real-time, LTI and
  delayed loops inside the step, references and inputs; failures carry the same time and partial result.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, ControlledModel, Feedback, FMUController
from ctmm.control.measurement_delay import DelayedController
from ctmm.elements import Fixed, Free, Mass, Spring, SpringDamper
from ctmm.errors import ModelError, SimulationError
from ctmm.signals import Harmonic

from _controllers_import import load_controllers
from test_compiled_cosim import Failing, assert_same, kernel_cache, pd_fmu, sampled_p_loop  # noqa: F401 (fixtures)

pytest.importorskip("casadi")

STIFFNESS, MASS = 50.0, 2.0


def one_mass() -> ctmm.Chain:
    """m x'' = -k x + F (the wall fixed, the end free)."""
    return ctmm.Chain("one", [Fixed("w"), Spring("k", STIFFNESS), Mass("m", MASS), Free("e")])


def three_masses() -> ctmm.Chain:
    return ctmm.Chain("three", [Fixed("s"), SpringDamper("k0", 100.0, 0.5), Mass("m0", 1.0, force=Harmonic(0.3, 9.0)),
                                SpringDamper("k1", 80.0, 0.3), Mass("m1", 1.5), SpringDamper("k2", 60.0, 0.2),
                                Mass("m2", 1.2), Free("e")])


def test_one_mass_with_a_sampled_p_controller_equals_the_exact_zoh_solution():
    """F_j = kp (r - x_j) held on [t_j, t_j + h): the generated RK4 converges to the matrix-exponential solution
    of the sampled-data loop (error ~ dt^4), and the numpy path gives the same numbers."""
    kp, r, h, x0 = 30.0, 0.02, 0.02, 0.05
    pid = load_controllers().PID("m.x", "m.force", kp=kp, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                 sample_time=h, reference=r)
    exact = sampled_p_loop(STIFFNESS, MASS, kp, r, h, x0, 50)
    errors = []
    for dt in (h / 2, h / 4):
        run = ctmm.simulate(one_mass(), 1.0, dt, method="rk4", x0={"m": x0}, controllers=[pid], compiled=True)
        assert run.scheme_name == "rk4-generated" and run.info["intervals"] == 50
        errors.append(np.max(np.abs(run["m.x"][::round(h / dt)] - exact)))
        held = np.repeat(run["m.force@samples"][:, 1], round(h / dt))[:len(run.time)]
        np.testing.assert_allclose(run["m.a"], (held - STIFFNESS * run["m.x"]) / MASS, rtol=0, atol=1e-12)
    assert errors[0] < 1e-6
    assert errors[1] < errors[0] / 12.0            # fourth order: 16x per halving
    python = ctmm.simulate(one_mass(), 1.0, h / 4, method="rk4", x0={"m": x0}, controllers=[pid])
    assert_same(run, python, ["m.x", "m.v", "m.a", "k.f"])


def test_controlled_chain_with_pid_fmu_loops_and_inputs_equals_the_numpy_path(pd_fmu):
    """A PID on m2 (every 3 steps), the PD FMU reading m0 two steps late (every 2 steps), an LTI lag loop with a
    reference, a delayed loop, a harmonic input on m1 and a load signal on m0, stored every 4th step: equal to the
    numpy path to round-off."""
    control = pytest.importorskip("control")
    system = ControlledChain(three_masses(), [Feedback("lag", "m1.x", "m0", gain=control.tf([20.0], [0.05, 1.0])),
                                              Feedback("late", "k1.f", "m1", gain=0.01, delay=0.02)])
    pid = load_controllers().PID("m2.x", "m2.force", kp=40.0, ki=10.0, kd=3.0, derivative_filter_time=0.01,
                                 sample_time=0.003, reference=0.01)
    fmu = FMUController(pd_fmu, inputs={"y": "m0.x", "ydot": "m0.v"}, outputs={"u": "m0.force"},
                        parameters={"kp": 30.0, "kd": 1.0, "reference": -0.01}, sample_time=0.002)
    arguments = dict(method="rk4", x0={"m1": 0.02}, v0={"m0": 0.1}, controllers=[pid, DelayedController(fmu, 0.002)],
                     references={"lag": Harmonic(0.01, 3.0)}, inputs={"m1.force": Harmonic(0.2, 5.0)},
                     store_every=4)
    generated = ctmm.simulate(system, 0.3, 1e-3, compiled=True, **arguments)
    python = ctmm.simulate(system, 0.3, 1e-3, **arguments)
    assert generated.scheme_name == "rk4-generated" and generated.info["controllers"] == python.info["controllers"]
    assert generated.info["loops"] == python.info["loops"]
    assert_same(generated, python, [f"{p}.{q}" for p in ("m0", "m1", "m2") for q in ("x", "v", "a")]
                + ["k0.f", "k1.f", "k2.f", "lag.y", "lag.u", "late.y", "late.u"])


def test_failures_and_refusals_carry_what_the_numpy_path_does():
    chain = one_mass()
    runs = {}
    for compiled in (True, None):
        with pytest.raises(SimulationError, match="controller broke") as failed:
            ctmm.simulate(chain, 0.1, 5e-3, method="rk4", x0={"m": 0.1}, controllers=[Failing("m.x", "m.force")],
                          compiled=compiled)
        runs[compiled] = failed.value
    assert runs[True].time == pytest.approx(0.02)
    assert_partial_equal(runs[True].partial_result, runs[None].partial_result)
    wild = load_controllers().PID("m.x", "m.force", kp=-1e4, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                  sample_time=5e-3)
    for compiled in (True, None):                   # the chain's default bound (1e6 x the start), no argument
        with pytest.raises(SimulationError, match="diverged|bound") as diverged:
            ctmm.simulate(chain, 2.0, 5e-3, method="rk4", x0={"m": 0.1}, controllers=[wild], compiled=compiled)
        runs[compiled] = diverged.value
    assert runs[True].time == runs[None].time and 0 < runs[True].time < 2.0
    assert_partial_equal(runs[True].partial_result, runs[None].partial_result)
    pid = load_controllers().PID("m.x", "m.force", kp=1.0, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                 sample_time=0.01)
    with pytest.raises(ModelError, match="not a whole multiple of dt"):
        ctmm.simulate(chain, 0.1, 5e-3, method="rk4", controllers=[DelayedController(pid, 0.007)], compiled=True)
    with pytest.raises(ModelError, match="method='RK45'"):       # the schemes: tests/test_compiled_cosim_schemes.py
        ctmm.simulate(chain, 0.1, 5e-3, method="RK45", controllers=[pid], compiled=True)



class FailingAtFirstSample(Failing):
    def init(self, t0: float) -> int:
        return 2                        # Failing raises at the sample with state 2: here t = 0


@pytest.mark.parametrize("system", ["chain", "planar"])
def test_a_controller_failing_at_the_first_sample_leaves_no_row_on_either_path(system):
    """docs/control.md §4a: the failure at t = 0 is a SimulationError with the partial result cut to the last good
    step, none (the numpy path's); the generated RK4 of a chain raised IndexError building it, a planar one kept
    the unsampled start row."""
    from ctmm.planar import Fixed as Ground, PlanarModel, RigidBody, SmoothHinge

    if system == "chain":
        model, x0, sensor, actuator, signal = one_mass(), {"m": 0.1}, "m.x", "m.force", "m.x"
    else:
        model = PlanarModel.chain("p", [Ground("g"), SmoothHinge("h"), RigidBody.uniform_link("rod", mass=1.0,
                                                                                              length=1.0)])
        x0, sensor, actuator, signal = {"rod.theta": -1.0}, "h.angle", "h.torque", "rod.theta"
    for compiled in (True, False):
        with pytest.raises(SimulationError, match="controller broke") as failed:
            ctmm.simulate(model, 0.1, 5e-3, method="rk4", x0=x0, controllers=[FailingAtFirstSample(sensor, actuator)],
                          compiled=compiled)
        assert failed.value.time == 0.0
        assert len(failed.value.partial_result.time) == 0 and len(failed.value.partial_result[signal]) == 0


def assert_partial_equal(generated: ctmm.SimulationResult, python: ctmm.SimulationResult) -> None:
    np.testing.assert_array_equal(generated.time, python.time)
    for name in ("m.x", "m.v", "m.a", "k.f"):
        scale = max(1.0, float(np.max(np.abs(python[name]))))
        np.testing.assert_allclose(generated[name], python[name], rtol=0, atol=1e-12 * scale, err_msg=name)


def test_stored_rows_carry_the_held_outputs_of_their_interval():
    """Stored every 4th of 19 steps, sampled every 3rd: each stored row's force and acceleration use the output
    held over the step that ended there (the new one at a sample row), equal to the numpy path."""
    pid = load_controllers().PID("m.x", "m.force", kp=30.0, ki=2.0, kd=1.0, derivative_filter_time=0.01,
                                 sample_time=0.015, reference=0.02)
    arguments = dict(method="rk4", x0={"m": 0.05}, controllers=[pid], store_every=4)
    generated = ctmm.simulate(one_mass(), 0.095, 5e-3, compiled=True, **arguments)
    assert generated.info["intervals"] == 7
    assert_same(generated, ctmm.simulate(one_mass(), 0.095, 5e-3, **arguments), ["m.x", "m.v", "m.a", "k.f"])


class FailingInit(Failing):
    def init(self, t0: float) -> int:
        raise RuntimeError("controller broke")


@pytest.mark.parametrize("compiled", [True, False])
def test_a_controller_failing_in_init_leaves_every_loop_signal_empty(compiled):
    """docs/control.md §4a: the partial result of a controller's failing init carries the plant's and every loop's
    signals (``"<loop>.y"``, ``".u"``, ``.u_demand``, ``.saturated``) with no rows, as a run's result names them (the
    loop-driver and generated RK4 paths left out the loops')."""
    from ctmm.planar import Fixed as Ground, PlanarModel, RigidBody, SmoothHinge

    rod = PlanarModel.chain("p", [Ground("g"), SmoothHinge("h"), RigidBody.uniform_link("rod", mass=1.0, length=1.0)])
    system = ControlledModel(rod, [Feedback("pd", [("rod.theta", 3.0), ("rod.omega", 0.4)], "h.torque", gain=1.0,
                                            delay=0.01, saturation=(-2.0, 2.0))])
    chain = ControlledChain(one_mass(), [Feedback("fb", "m.x", "m", gain=3.0, delay=0.01)])
    for model, x0, sensor, actuator in ((system, {"rod.theta": -1.0}, "h.angle", "rod.moment"),
                                        (chain, {"m": 0.1}, "m.x", "m.force")):
        full = ctmm.simulate(model, 0.02, 5e-3, method="rk4", x0=x0, compiled=compiled)
        with pytest.raises(SimulationError, match="controller broke") as failed:
            ctmm.simulate(model, 0.02, 5e-3, method="rk4", x0=x0, controllers=[FailingInit(sensor, actuator)],
                          compiled=compiled)
        partial = failed.value.partial_result
        assert set(partial.signals()) == set(full.signals())
        assert all(len(partial[name]) == 0 and partial.unit(name) == full.unit(name) for name in full.signals())
