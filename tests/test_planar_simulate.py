"""``ctmm.simulate`` on planar and flexible models: one SimulationResult for every method.

References: the Lagrange models (:mod:`ctmm.reference.planar_lagrange`,
:mod:`ctmm.reference.flexible_lagrange`), integrated by ``solve_ivp`` at tight tolerance, and the
closed-form geometry of a rod (tip at ``L (cos theta, sin theta)``).  The legacy planar drivers
(``simulate_rk4``, ``simulate_rk4_generated``) must give the same numbers through ``ctmm.simulate``.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm.control import Feedback
from ctmm.control.controlled_model import ControlledModel
from ctmm.errors import ModelError, SimulationError
from ctmm.flexible import ModalBeam
from ctmm.planar import ActuatedHinge, Fixed, PlanarModel, RigidBody, SmoothHinge, simulate_rk4
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.reference.planar_lagrange import PlanarLagrange
from ctmm.results import SimulationResult, load


@pytest.fixture(scope="module")
def double():
    """Double pendulum from the horizontal, its Lagrange solution on a 10 ms grid (0.6 s)."""
    links = [RigidBody.uniform_link(f"l{i}", mass=1.0, length=1.0) for i in (1, 2)]
    model = PlanarModel.chain("double", [Fixed("g"), SmoothHinge("h1"), links[0], SmoothHinge("h2"), links[1]])
    q0 = np.array([0.0, 0.4])
    t = np.linspace(0.0, 0.6, 61)
    ref = PlanarLagrange(model).simulate(q0, np.zeros(2), 0.6, t_eval=t, rtol=1e-12, atol=1e-12)
    return model, q0, t, ref.y


@pytest.mark.parametrize("method, dt, bound", [("rk4", 1e-3, 1e-9), ("DOP853", 0.01, 1e-8),
                                               ("Radau", 0.01, 1e-6), ("newmark", 1e-3, 2e-5),
                                               ("generalized_alpha", 1e-3, 2e-5)])
def test_every_method_matches_lagrange(double, method, dt, bound):
    model, q0, t, ref = double
    result = ctmm.simulate(model, 0.6, dt, method=method, x0={"l1.theta": q0[0], "l2.theta": q0[1]},
                           rtol=1e-11, atol=1e-12, stability_check="ignore") if method in ("DOP853", "Radau") \
        else ctmm.simulate(model, 0.6, dt, method=method, x0=q0)
    assert isinstance(result, SimulationResult)
    rows = np.round(t / dt).astype(int)
    for k, name in enumerate(model.coordinates):
        assert np.max(np.abs(result[name][rows] - ref[k])) < bound, (method, name)
        assert np.max(np.abs(result[name + "_dot"][rows] - ref[2 + k])) < 50 * bound, (method, name)
    assert result.unit("l1.theta") == "rad" and result.unit("l2.theta_dot") == "rad/s"


def test_same_numbers_as_the_planar_drivers(double):
    """RK4 through ctmm.simulate is the legacy simulate_rk4 bit for bit; fast=True, a deprecated alias of
    compiled=True, warns and runs the generated RK4 (same arithmetic, same numbers to round-off)."""
    pytest.importorskip("casadi")
    model, q0, _, _ = double
    legacy = simulate_rk4(model, q0, np.zeros(2), t_final=0.2, dt=1e-3)
    result = ctmm.simulate(model, 0.2, 1e-3, x0=q0)
    np.testing.assert_array_equal(result["l2.theta"], legacy.q[:, 1])
    with pytest.warns(DeprecationWarning, match=r"fast=True\) is deprecated.*compiled=True"):
        fast = ctmm.simulate(model, 0.2, 1e-3, x0=q0, fast=True)
    np.testing.assert_allclose(fast["l2.theta"], legacy.q[:, 1], rtol=0, atol=1e-12)
    assert fast.scheme_name == "rk4-generated"
    compiled = ctmm.simulate(model, 0.2, 1e-3, x0=q0, compiled=True)
    np.testing.assert_array_equal(fast["l2.theta"], compiled["l2.theta"])
    with pytest.raises(ModelError, match="fast=True .* contradicts compiled=False"):
        ctmm.simulate(model, 0.2, 1e-3, x0=q0, fast=True, compiled=False)


def test_outputs_are_named_sensors_with_units_and_round_trip_through_files(tmp_path):
    rod = PlanarModel.chain("rod", [Fixed("g"), SmoothHinge("pin"), RigidBody.uniform_link("r", mass=2.0,
                                                                                           length=0.8)])
    result = ctmm.simulate(rod, 0.3, 1e-3, x0={"r.theta": -0.5}, v0=[0.4],
                           outputs=["r.out.y", "r.out.vx", "pin.angle"])
    theta, omega = result["r.theta"], result["r.theta_dot"]
    np.testing.assert_allclose(result["r.out.y"], 0.8 * np.sin(theta), atol=1e-14)
    np.testing.assert_allclose(result["r.out.vx"], -0.8 * np.sin(theta) * omega, atol=1e-13)
    np.testing.assert_allclose(result["pin.angle"], theta, atol=1e-15)
    assert result.units(["r.out.y", "r.out.vx", "r.theta"]) == {"r.out.y": "m", "r.out.vx": "m/s", "r.theta": "rad"}
    frame = result.to_dataframe(units_in_names=True)
    assert "r.out.y [m]" in frame.columns and len(frame) == 301
    loaded = load(result.save(tmp_path / "rod.h5"))
    for name in ("r.theta", "r.theta_dot", "r.out.y"):
        np.testing.assert_array_equal(loaded[name], result[name])
        assert loaded.unit(name) == result.unit(name)
    assert result.plot("r.theta", "pin.angle") is not None


def test_flexible_beam_with_a_hub_loop_matches_the_flexible_lagrange_model():
    """A modal beam on a hub whose torque closes a real-time PD loop on the beam's angle and rate:
    the reference carries the same law on its own coordinates."""
    def model(hub):
        beam = ModalBeam("b", length=1.0, bending_stiffness=4.0, mass_per_length=0.5, n_modes=2)
        return PlanarModel.chain("flex", [Fixed("g"), hub, beam])

    K, D, target = 6.0, 0.5, -0.8
    loop = Feedback("hub_law", [("b.theta", K), ("b.omega", D)], "hub.torque", gain=1.0)
    q0 = np.array([-0.3, 0.0, 0.0])
    result = ctmm.simulate(ControlledModel(model(SmoothHinge("hub")), [loop]), 0.4, 1e-3, x0=q0,
                           references={"hub_law": K * target}, outputs=["b.out.y"])

    class Torque:
        value = 0.0

        def __call__(self, t):
            return self.value

    torque = Torque()
    lagrange = FlexibleLagrange(model(ActuatedHinge("hub", torque=torque)))

    def rhs(t, y):
        torque.value = -(K * (y[0] - target) + D * y[3])
        return np.concatenate([y[3:], lagrange.accelerations(y[:3], y[3:], t)])

    import scipy.integrate

    ref = scipy.integrate.solve_ivp(rhs, (0.0, 0.4), np.concatenate([q0, np.zeros(3)]), method="DOP853",
                                    t_eval=result.time[::50], rtol=1e-11, atol=1e-12)
    for k, name in enumerate(("b.theta", "b.q1", "b.q2")):
        assert np.max(np.abs(result[name][::50] - ref.y[k])) < 2e-6, name
    assert np.max(np.abs(result["hub_law.u"][::50] + K * (ref.y[0] - target) + D * ref.y[3])) < 1e-4
    assert result.unit("b.out.y") == "m"


def test_divergence_gives_the_partial_result():
    rod = PlanarModel.chain("rod", [Fixed("g"), SmoothHinge("pin"), RigidBody.uniform_link("r", mass=1.0,
                                                                                           length=1.0)])
    with pytest.raises(SimulationError) as info:
        ctmm.simulate(rod, 2.0, 1e-3, inputs={"pin.torque": 200.0}, divergence_bound=10.0)
    partial = info.value.partial_result
    assert isinstance(partial, SimulationResult) and 10 < len(partial.time) < 2001
    assert np.all(np.abs(partial["r.theta"]) <= 10.0)
    assert info.value.time == pytest.approx(partial.time[-1] + 1e-3)


@pytest.mark.parametrize("options", [dict(method="newmark"), dict(compiled=True)])
def test_partial_results_of_the_legacy_drivers_are_simulation_results(options):
    """Implicit and compiled runs keep their own drivers; their partial results are converted."""
    if options.get("compiled"):
        pytest.importorskip("casadi")
    rod = PlanarModel.chain("rod", [Fixed("g"), SmoothHinge("pin"), RigidBody.uniform_link("r", mass=1.0,
                                                                                           length=1.0)])
    with pytest.raises(SimulationError) as info:
        ctmm.simulate(rod, 2.0, 1e-3, x0=[-1.5], v0=[15.0], divergence_bound=3.0, outputs=["r.out.y"], **options)
    partial = info.value.partial_result
    assert isinstance(partial, SimulationResult) and 1 < len(partial.time) < 2001
    assert np.all(np.abs(partial["r.theta"] + 1.5) <= 3.0)
    np.testing.assert_allclose(partial["r.out.y"], np.sin(partial["r.theta"]), atol=1e-14)


def test_refusals_name_the_option():
    rod = PlanarModel.chain("rod", [Fixed("g"), SmoothHinge("pin"), RigidBody.uniform_link("r", mass=1.0,
                                                                                           length=1.0)])
    cases = [
        (dict(method="rk4", dt=None), "dt is required with method='rk4'"),
        (dict(method="newmark", dt=None), "dt is required with the DT-TMM scheme"),
        (dict(method="leapfrog"), "method must be 'rk4'"),
        (dict(method=None), "method must be a method name"),
        (dict(method="rk4", scheme="newmark"), "not both"),
        (dict(x0={"r.phi": 1.0}), "r.phi"),
        (dict(v0={"r.theta": "fast"}), "v0\\['r.theta'\\]"),
        (dict(outputs=["r.out.z"]), "r.out.z"),
        (dict(t0=1.0), "t0=1.0 applies to 1-D chains only"),
        (dict(compiled=True, method="houbolt", inputs={"pin.torque": lambda t: t}), "Python callable of time"),
        (dict(compiled=True, method="RK45"), "compiled=True runs the generated RK4"),
        (dict(method="houbolt", inputs={"pin.torque": 1.0}, dt=None), "dt is required with method='houbolt'"),
        (dict(coupling="previous"), "coupling='previous' only applies"),
        (dict(rtol=1e-6), "rtol=1e-06 applies to the solve_ivp methods"),
        (dict(method="newmark", max_step=0.1), "max_step=0.1 applies to the solve_ivp methods"),
        (dict(method="RK45", store_every=2), "store_every=2 applies to fixed-step methods"),
    ]
    for options, message in cases:
        dt = options.pop("dt", 1e-3)
        with pytest.raises(ModelError, match=message):
            ctmm.simulate(rod, 0.01, dt, **options)


def test_chains_keep_their_scheme_option_and_refuse_planar_options():
    from ctmm.elements import Fixed as Wall, Free, Mass, Spring

    chain = ctmm.Chain("sdof", [Wall("wall"), Spring("k", 100.0), Mass("m", 1.0), Free("tip")])
    a = ctmm.simulate(chain, 0.05, 1e-3, scheme="newmark", x0={"m": 0.01})
    b = ctmm.simulate(chain, 0.05, 1e-3, method="newmark", x0={"m": 0.01})
    np.testing.assert_array_equal(a.states, b.states)
    ode = ctmm.simulate(chain, 0.05, 1e-3, method="rk4", x0={"m": 0.01})      # ODE methods run chains too
    assert np.max(np.abs(ode["m.x"] - a["m.x"])) <= 1e-6
    with pytest.raises(ModelError, match="outputs=.* does not apply to the DT-TMM stepper of a chain"):
        ctmm.simulate(chain, 0.05, 1e-3, outputs=["m.x"])
    with pytest.raises(ModelError, match="dt is required to simulate a chain"):
        ctmm.simulate(chain, 0.05)


def test_progress_bar_and_store_every(double):
    model, q0, _, _ = double
    result = ctmm.simulate(model, 0.1, 1e-3, x0=q0, store_every=10, progress=True)
    assert len(result.time) == 11
    np.testing.assert_allclose(result.time, np.linspace(0.0, 0.1, 11), atol=1e-15)
    assert math.isfinite(result.info["wall_time_s"])


def _delayed_pd_pendulum_reference(theta0: float, t_final: float, delay: float, kp: float, kd: float,
                                   inertia: float, steps_per_delay: int = 20) -> float:
    """``J theta'' = -(kp theta(t - tau) + kd theta'(t - tau))`` (no gravity), history ``theta0`` at rest,
    by the method of steps: RK4 with the delayed terms read from the stored grid (step ``tau / k``)."""
    h = delay / steps_per_delay
    n = int(round(t_final / h))
    theta, rate = np.empty(n + 1), np.empty(n + 1)
    theta[0], rate[0] = theta0, 0.0

    def delayed(k: float) -> tuple[float, float]:      # state at grid index k - steps_per_delay (held before 0)
        j = k - steps_per_delay
        if j <= 0:
            return theta0, 0.0
        lo = int(math.floor(j))
        w = j - lo
        return (1 - w) * theta[lo] + w * theta[min(lo + 1, n)], (1 - w) * rate[lo] + w * rate[min(lo + 1, n)]

    def accel(k: float) -> float:
        a, b = delayed(k)
        return -(kp * a + kd * b) / inertia

    for k in range(n):             # the delayed term is known on the grid (steps_per_delay >= 1): stages at k, k+1/2, k+1
        a0, am, a1 = accel(k), accel(k + 0.5), accel(k + 1)
        theta[k + 1] = theta[k] + h * rate[k] + h * h / 6 * (a0 + 2 * am)
        rate[k + 1] = rate[k] + h / 6 * (a0 + 4 * am + a1)
    return float(theta[-1])


@pytest.mark.parametrize("method", ["RK45", "LSODA"])
def test_adaptive_methods_with_a_loop_delay_shorter_than_their_first_step_guess(method):
    """scipy's first-step guess evaluated the rate beyond the delay history ('delay history requested at
    t=7e-07 beyond the last step 0.0'); the step (first included) is now bounded by the delay."""
    from ctmm.control import with_feedback
    from ctmm.planar import Pinned

    link = RigidBody.uniform_link("link", mass=1.0, length=0.5)
    arm = PlanarModel.chain("arm", [Pinned("motor"), link], gravity=(0.0, 0.0))
    delay, t_final = 1e-6, 1e-3
    pd = Feedback("pd", sensor=[("motor.angle", 2000.0), ("motor.rate", 20.0)], actuator="motor.torque", gain=1.0,
                  delay=delay)
    result = ctmm.simulate(with_feedback(arm, [pd]), t_final, method=method, x0=[0.1])
    expected = _delayed_pd_pendulum_reference(0.1, t_final, delay, 2000.0, 20.0, inertia=1.0 * 0.5 ** 2 / 3)
    assert abs(expected - 0.1) > 1e-3                      # the loop moved the link
    assert abs(result["link.theta"][-1] - expected) <= 1e-8


def test_a_loop_delay_that_forces_too_many_adaptive_steps_is_refused_and_many_are_announced():
    from ctmm.control import with_feedback
    from ctmm.planar import Pinned

    arm = PlanarModel.chain("arm", [Pinned("motor"), RigidBody.uniform_link("link", mass=1.0, length=0.5)])
    pd = Feedback("pd", sensor="motor.angle", actuator="motor.torque", gain=1.0, delay=1e-6)
    with pytest.raises(ModelError, match=r"caps solve_ivp's step.*1e\+08 steps.*method='rk4'"):
        ctmm.simulate(with_feedback(arm, [pd]), 100.0, method="RK45", x0=[0.1])
    with pytest.warns(RuntimeWarning, match=r"at least 2e\+05 steps"), pytest.raises(SimulationError):
        ctmm.simulate(with_feedback(arm, [pd]), 0.2, method="RK45", x0=[0.1], divergence_bound=1e-9)
