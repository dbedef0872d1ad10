"""1-D chains with loops on the ODE path: ``ctmm.simulate(controlled_chain, method="rk4" | solve_ivp)``.

The loops close in the one driver (:mod:`ctmm.control.planar_time`) on the chain's plant
(:mod:`ctmm.control.chain_plant`).  References, independent of the TMM code:

* ``ctmm.reference.delay_chain.method_of_steps`` -- the exact closed-loop (delay) differential equation
  on the global ``M, C, K`` (DOP853, rtol 1e-12);
* global state-space ODEs written here on ``ctmm.reference.chain.assemble`` for an LTI controller and a
  zero-order-held co-simulated PD (``solve_ivp``, tight tolerances).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.errors import ModelError
from ctmm.reference.chain import assemble
from ctmm.reference.delay_chain import GlobalLoop, method_of_steps

from _controllers_import import load_controllers
from test_controlled_frequency import build

controllers = load_controllers()

X0 = [-0.05, 0.0, 0.1]
V0 = [0.0, 0.3, 0.0]
REAL_TIME = [(2, "displacement", 0, 5.0, 0.0, None, False), (1, "velocity", 1, 3.0, 0.0, 0, True)]
DELAYED = [(2, "displacement", 0, 5.0, 0.05, None, False), (0, "velocity", 2, 2.0, 0.03, None, False)]


def seed_setup(loops):
    """Seed Fig. 9.37 chain: ground -[k0]- m0 -[k1]- m1 -[k2]- m2 (free end)."""
    return build([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0], [0.0] * 3,
                 start="fixed", end="free", loops=loops)


def initial(values):
    return {f"m{i}": v for i, v in enumerate(values) if v != 0.0}


def positions(result) -> np.ndarray:
    return np.column_stack([result[f"m{i}.x"] for i in range(3)])


def run(system, t_final, dt, method="rk4", **options):
    return ctmm.simulate(system, t_final, dt, method=method, x0=initial(X0), v0=initial(V0), **options)


def test_real_time_loops_rk4_converge_at_order_four_to_the_exact_closed_loop():
    setup = seed_setup(REAL_TIME)
    exact = method_of_steps(setup.chain, setup.global_loops, 0.4, X0, V0, rtol=1e-12, atol=1e-14)
    errors = []
    for dt in (0.004, 0.002, 0.001):
        result = run(setup.system, 0.4, dt)
        errors.append(np.max(np.abs(positions(result) - exact.evaluate(result.time).displacement)))
    assert result.info["loops"] == {"loop0": "real-time", "loop1": "real-time"}
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(orders > 3.7), (errors, orders)
    assert errors[-1] < 1e-10


def test_real_time_loops_dop853_match_the_exact_closed_loop():
    setup = seed_setup(REAL_TIME)
    result = run(setup.system, 0.6, 0.01, method="DOP853", rtol=1e-11, atol=1e-13)
    exact = method_of_steps(setup.chain, setup.global_loops, 0.6, X0, V0, rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(positions(result) - exact.evaluate(result.time).displacement)) < 1e-10
    # the loop signals: y is the sensed value, u = -g y
    np.testing.assert_allclose(result["loop0.y"], result["m2.x"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(result["loop0.u"], -5.0 * result["m2.x"], rtol=0, atol=1e-14)
    assert result.unit("loop0.u") == "N" and result.unit("m2.v") == "m/s"


def test_delayed_loops_rk4_from_the_one_history_match_the_delay_equation():
    setup = seed_setup(DELAYED)
    exact = method_of_steps(setup.chain, setup.global_loops, 0.6, X0, V0, rtol=1e-12, atol=1e-14)
    errors = []
    for dt in (0.002, 0.001):            # both divide the delays: the kinks at k tau fall on the grid
        result = run(setup.system, 0.6, dt)
        errors.append(np.max(np.abs(positions(result) - exact.evaluate(result.time).displacement)))
    assert result.info["loops"] == {"loop0": "history", "loop1": "history"}
    assert errors[1] < 1e-10 and errors[0] / errors[1] > 8.0, errors


def test_accelerations_and_forces_of_a_controlled_run_include_the_loop_forces():
    setup = seed_setup(REAL_TIME)
    result = run(setup.system, 0.3, 0.001)
    exact = method_of_steps(setup.chain, setup.global_loops, 0.3, X0, V0, rtol=1e-12, atol=1e-14).evaluate(result.time)
    np.testing.assert_allclose(result["m0.a"], exact.acceleration[:, 0], rtol=0, atol=1e-7)
    np.testing.assert_allclose(result["m2.a"], exact.acceleration[:, 2], rtol=0, atol=1e-7)
    # the force of connector k1 carries the across loop's force -3 (v1 - v0) besides its law
    law = -80.0 * (exact.displacement[:, 1] - exact.displacement[:, 0]) \
        - 0.3 * (exact.velocity[:, 1] - exact.velocity[:, 0])
    np.testing.assert_allclose(result["k1.f"], law + result["loop1.u"], rtol=0, atol=1e-7)


def test_connector_force_sensor_is_its_law():
    """``k2.f = -120 (x2 - x1) - 0.4 (v2 - v1)`` fed back to m0 with gain g is two relative loops."""
    g = 0.05
    setup = seed_setup([])
    system = ControlledChain(setup.plant,
                             [Feedback("force", "k2.f", "m0", gain=g)])
    loops = [GlobalLoop(2, "displacement", 0, -g * 120.0, 0.0, relative_to=1),
             GlobalLoop(2, "velocity", 0, -g * 0.4, 0.0, relative_to=1)]
    result = run(system, 0.4, 0.01, method="DOP853", rtol=1e-11, atol=1e-13)
    exact = method_of_steps(setup.chain, loops, 0.4, X0, V0, rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(positions(result) - exact.evaluate(result.time).displacement)) < 1e-10
    assert result.unit("force.y") == "N"


def global_matrices(setup):
    M, C, K = assemble(setup.chain)
    return M, C, K, np.linalg.inv(M)


def test_lti_controller_states_integrate_with_the_chain():
    """``C(s) = g / (T s + 1)`` from m2.x to m0: the global ODE with the controller state beside it."""
    control = pytest.importorskip("control")
    g, T = 20.0, 0.05
    setup = seed_setup([])
    system = ControlledChain(setup.plant,
                             [Feedback("lag", "m2.x", "m0", gain=control.tf([g], [T, 1.0]))])
    result = run(system, 0.5, 0.0005)
    M, C, K, Minv = global_matrices(setup)

    def rate(t, y):
        x, v, z = y[:3], y[3:6], y[6]
        u = -z                            # z: the lag's output, z' = (g x2 - z) / T
        f = np.array([u, 0.0, 0.0])
        return np.concatenate([v, Minv @ (f - C @ v - K @ x), [(g * x[2] - z) / T]])

    reference = scipy.integrate.solve_ivp(rate, (0, 0.5), np.r_[X0, V0, 0.0], method="DOP853", t_eval=result.time,
                                          rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(positions(result) - reference.y[:3].T)) < 1e-10
    np.testing.assert_allclose(result["lag.u"], -reference.y[6], rtol=0, atol=1e-9)


def test_cosimulated_pd_is_sampled_and_held_on_the_ode_path():
    kp, kd, h = 30.0, 2.0, 0.01
    setup = seed_setup([])
    plant = setup.plant
    pd = controllers.SaturatedPD(("m2.x", "m2.v"), ("m0.force",), kp=kp, kd=kd, sample_time=h)
    M, C, K, Minv = global_matrices(setup)
    y, rows = np.r_[X0, V0], [np.r_[X0, V0]]
    for k in range(50):                   # zero-order hold: u sampled at k h, held over the interval
        u = -kp * y[2] - kd * y[5]
        f = np.array([u, 0.0, 0.0])
        segment = scipy.integrate.solve_ivp(lambda t, s: np.concatenate([s[3:], Minv @ (f - C @ s[3:] - K @ s[:3])]),
                                            (k * h, (k + 1) * h), y, method="DOP853", rtol=1e-12, atol=1e-14)
        y = segment.y[:, -1]
        rows.append(y)
    reference = np.array(rows)[:, :3]
    errors = []
    for substeps in (4, 8):              # RK4 inside each held interval: order 4 to the held reference
        result = run(plant, 0.5, h / substeps, controllers=[pd])
        errors.append(np.max(np.abs(positions(result)[::substeps] - reference)))
    assert errors[1] < 3e-10 and errors[0] / errors[1] > 12.0, errors
    assert result.info["controllers"]


def test_open_loop_inputs_on_a_chain_actuator():
    setup = seed_setup([])
    plant = setup.plant
    result = run(plant, 0.4, 0.01, method="DOP853", rtol=1e-11, atol=1e-13, inputs={"m1.force": lambda t: np.sin(7 * t)})
    M, C, K, Minv = global_matrices(setup)
    reference = scipy.integrate.solve_ivp(
        lambda t, s: np.concatenate([s[3:], Minv @ (np.array([0.0, np.sin(7 * t), 0.0]) - C @ s[3:] - K @ s[:3])]),
        (0, 0.4), np.r_[X0, V0], method="DOP853", t_eval=result.time, rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(positions(result) - reference.y[:3].T)) < 1e-10


@pytest.mark.parametrize("loop, message", [
    (Feedback("acc", "m2.a", "m0", gain=0.1), "accelerations are not sensors"),
    (Feedback("own", "k1.f", "k1", gain=0.1), "direct feedthrough"),
    (Feedback("mass", "m1.f", "m0", gain=0.1), "law force of a"),
])
def test_signals_that_close_an_algebraic_loop_are_refused_by_name(loop, message):
    setup = seed_setup([])
    plant = setup.plant
    with pytest.raises(ModelError, match=message):
        run(ControlledChain(plant, [loop]), 0.1, 0.01)


def test_actuator_on_a_massless_point_is_refused():
    from ctmm.elements import Fixed, Free, Mass, Spring, SpringDamper

    chain = ctmm.Chain("q", [Fixed("s"), SpringDamper("k0", 100.0, 0.1), Mass("m0", 1.0), Spring("k1", 50.0),
                             Spring("k2", 50.0), Mass("m1", 1.0), Free("e")])
    with pytest.raises(ModelError, match="without inertia"):
        ctmm.simulate(ControlledChain(chain, [Feedback("l", "m1.x", "k2", gain=1.0)]), 0.1, 0.01, method="rk4")
    # sensing it is fine: its position follows from the balance (midway between equal springs)
    result = ctmm.simulate(ControlledChain(chain, [Feedback("l", "k1.x", "m0", gain=1.0)]), 0.1, 0.01, method="rk4",
                           x0={"m1": 0.01})
    np.testing.assert_allclose(result["l.y"], 0.5 * (result["m0.x"] + result["m1.x"]), rtol=0, atol=1e-15)


def test_start_time_other_than_zero_is_refused_on_the_loop_path():
    setup = seed_setup(REAL_TIME)
    with pytest.raises(ModelError, match="t0"):
        ctmm.simulate(setup.system, 0.1, 0.01, method="rk4", t0=0.5)


@pytest.fixture(scope="module")
def pd_fmu(tmp_path_factory):
    import shutil

    from ctmm.control import build_fmu

    if not shutil.which("gcc"):
        pytest.skip("gcc is required to build the test FMU")
    return build_fmu(controllers.fmu_source("pd_controller"), tmp_path_factory.mktemp("fmu_ode"), compiler="gcc")


def test_fmu_and_python_controllers_give_the_same_closed_loop_on_the_ode_path(pd_fmu):
    from ctmm.control import FMUController

    plant = seed_setup([]).plant
    h, kp, kd, limit = 2e-3, 60.0, 5.0, 4.0
    fmu = FMUController(pd_fmu, inputs={"y": "m2.x", "ydot": "m2.v"}, outputs={"u": "m0.force"},
                        parameters={"kp": kp, "kd": kd, "limit": limit, "reference": 0.02}, sample_time=2 * h)
    python = controllers.SaturatedPD(("m2.x", "m2.v"), ("m0.force",), kp=kp, kd=kd, limit=limit, reference=0.02,
                                     sample_time=2 * h)
    a, b = (run(plant, 0.5, h, controllers=[c]) for c in (fmu, python))
    samples = a["m0.force@samples"]
    assert np.any(np.abs(samples[:, 1]) == limit)          # the saturation is exercised
    np.testing.assert_array_equal(samples, b["m0.force@samples"])
    np.testing.assert_allclose(positions(a), positions(b), rtol=0, atol=1e-15)


def test_a_diverging_loop_stops_with_the_partial_result():
    setup = seed_setup([(2, "displacement", 2, -6.5e4, 0.0, None, False)])        # real-time positive feedback
    with pytest.raises(ctmm.SimulationError) as caught:
        run(setup.system, 5.0, 0.001)
    error = caught.value
    assert error.time is not None and 0.0 < error.time < 5.0
    partial = error.partial_result
    assert partial is not None and 1 < len(partial.time) and partial.time[-1] < error.time
    assert np.all(np.isfinite(partial["m2.x"])) and "loop0.u" in partial.extra


@pytest.mark.parametrize("method", ["DOP853", "Radau"])
def test_store_every_is_refused_with_a_solve_ivp_method_on_the_loop_path(method):
    """store_every thins a fixed-step run; with a solve_ivp method the output grid is dt (the plain chain's ODE
    path and planar models refuse it; the loop driver kept every row)."""
    setup = seed_setup(DELAYED)
    with pytest.raises(ModelError, match="store_every=10 applies to fixed-step methods"):
        run(setup.system, 0.1, 0.01, method=method, store_every=10)
