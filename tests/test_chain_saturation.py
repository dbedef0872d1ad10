"""Saturated loops on 1-D controlled chains (``Feedback(saturation=(low, high))``).

In time the loop driver (``method="rk4"`` or a ``solve_ivp`` method) and the generated RK4 apply the
clipped force; the linear verbs and the DT-TMM schemes (which embed chain loops linearly) refuse.
Independent reference: the global equations of the two-mass chain written here from the element
parameters, with the clipped force, by ``solve_ivp`` (real-time loop) and by the method of steps
(delayed loop: one ODE per delay interval, the delayed signal from the previous interval's dense output).
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ctmm
import ctmm.stability
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.errors import ModelError

M0, M1, K0, K1, C0, C1 = 1.0, 2.0, 100.0, 150.0, 0.5, 0.3
KP, KD, LIMIT, X0 = 50.0, 5.0, 0.8, 0.1
PLANT = ctmm.Chain("two", [Fixed("s"), SpringDamper("k0", K0, C0), Mass("m0", M0), SpringDamper("k1", K1, C1),
                           Mass("m1", M1), Free("e")])
MASS = np.diag([M0, M1])
STIFFNESS = np.array([[K0 + K1, -K1], [-K1, K1]])
DAMPING = np.array([[C0 + C1, -C1], [-C1, C1]])


def realtime(saturation=(-LIMIT, LIMIT)) -> ControlledChain:
    return ControlledChain(PLANT, [Feedback("pd", [("m1.x", KP), ("m1.v", KD)], "m0", gain=1.0,
                                            saturation=saturation)])


def rate(x: np.ndarray, v: np.ndarray, u: float) -> np.ndarray:
    return np.linalg.solve(MASS, np.array([u, 0.0]) - STIFFNESS @ x - DAMPING @ v)


def clipped(demand: float) -> float:
    return min(max(demand, -LIMIT), LIMIT)


def reference_realtime(times: np.ndarray) -> np.ndarray:
    def f(t, y):
        return np.concatenate([y[2:], rate(y[:2], y[2:], clipped(-(KP * y[1] + KD * y[3])))])

    solution = solve_ivp(f, (0.0, times[-1]), [0.0, X0, 0.0, 0.0], method="DOP853", t_eval=times, rtol=1e-12,
                         atol=1e-14)
    return solution.y[:2].T


def reference_delayed(times: np.ndarray, delay: float, gain: float) -> np.ndarray:
    """Method of steps: on [k tau, (k + 1) tau] the delayed x1 is the previous interval's dense output."""
    pieces = []

    def delayed_x1(t: float) -> float:
        if t <= 0.0:
            return X0                                   # the initial state held before t = 0
        k = min(int(t / delay), len(pieces) - 1)
        return float(pieces[k](t)[1])

    y, k = np.array([0.0, X0, 0.0, 0.0]), 0
    while k * delay < times[-1]:
        def f(t, state):
            return np.concatenate([state[2:], rate(state[:2], state[2:], clipped(-gain * delayed_x1(t - delay)))])

        solution = solve_ivp(f, (k * delay, (k + 1) * delay), y, method="DOP853", dense_output=True, rtol=1e-12,
                             atol=1e-14)
        pieces.append(solution.sol)
        y, k = solution.y[:, -1], k + 1
    return np.array([pieces[min(int(t / delay), len(pieces) - 1)](t)[:2] if t > 0 else [0.0, X0] for t in times])


def positions(result) -> np.ndarray:
    return np.column_stack([result["m0.x"], result["m1.x"]])


def test_a_saturated_realtime_loop_in_rk4_and_solve_ivp_meets_the_clipped_reference():
    t_final = 1.0
    errors = []
    for dt in (1e-3, 5e-4):
        result = ctmm.simulate(realtime(), t_final, dt, method="rk4", x0={"m1": X0})
        errors.append(float(np.max(np.abs(positions(result) - reference_realtime(result.time)))))
    assert errors[1] < 1e-7 * X0 and errors[1] < errors[0] / 3.0, errors
    u, demand = result["pd.u"], result["pd.u_demand"]
    assert np.all(np.abs(u) <= LIMIT) and np.max(np.abs(demand)) > 3.0 * LIMIT        # the limit was reached
    assert np.allclose(u, np.clip(demand, -LIMIT, LIMIT), rtol=0, atol=1e-15)
    assert np.array_equal(result["pd.saturated"] == 1.0, np.abs(demand) > LIMIT)
    assert 0.0 < result.info["time_saturated_s"]["pd"] < t_final
    grid = np.linspace(0.0, t_final, 101)
    adaptive = ctmm.simulate(realtime(), t_final, 0.01, method="RK45", x0={"m1": X0}, rtol=1e-10, atol=1e-13)
    assert np.max(np.abs(positions(adaptive) - reference_realtime(grid))) < 1e-6 * X0


def test_a_saturated_delayed_loop_meets_the_method_of_steps():
    delay, gain, dt = 0.02, 40.0, 5e-4
    system = ControlledChain(PLANT, [Feedback("late", "m1.x", "m0", gain=gain, delay=delay,
                                              saturation=(-LIMIT, LIMIT))])
    result = ctmm.simulate(system, 0.6, dt, method="rk4", x0={"m1": X0})
    error = float(np.max(np.abs(positions(result) - reference_delayed(result.time, delay, gain))))
    assert error < 1e-6 * X0, error
    assert np.any(result["late.saturated"] == 1.0) and np.any(result["late.saturated"] == 0.0)


def test_unsaturated_limits_change_nothing():
    wide = ctmm.simulate(realtime((-1e9, 1e9)), 0.3, 1e-3, method="rk4", x0={"m1": X0})
    linear = ctmm.simulate(realtime(None), 0.3, 1e-3, method="rk4", x0={"m1": X0})
    assert np.array_equal(positions(wide), positions(linear))


def test_the_generated_rk4_clips_as_the_python_path():
    pytest.importorskip("casadi")
    python = ctmm.simulate(realtime(), 0.5, 1e-3, method="rk4", x0={"m1": X0})
    generated = ctmm.simulate(realtime(), 0.5, 1e-3, method="rk4", x0={"m1": X0}, compiled=True)
    assert np.max(np.abs(positions(generated) - positions(python))) < 1e-13
    assert np.max(np.abs(generated["pd.u"])) <= LIMIT
    for name in ("pd.u", "pd.u_demand", "pd.saturated"):
        assert np.max(np.abs(generated[name] - python[name])) < 1e-10 * np.max(np.abs(python[name])), name
    assert generated.info["time_saturated_s"] == pytest.approx(python.info["time_saturated_s"])


@pytest.mark.parametrize("verb", [
    lambda s: ctmm.frequency_response(s, np.array([1.0, 2.0]), input="m0.force", output="m1.x"),
    lambda s: ctmm.linearize(s),
    lambda s: ctmm.stability.delay_margin(s),
    lambda s: ctmm.stability.characteristic_roots(s, re_min=-1.0, im_max=40.0, re_max=1.0),
    lambda s: ctmm.stability.stability_chart(s, ("gain", [0.5, 1.0]), ("delay", [0.0, 0.01])),
    lambda s: ctmm.control.loop_transfer_function(s, "pd", [1.0]),
    lambda s: ctmm.simulate(s, 0.1, 0.01, method="newmark", x0={"m1": X0}),
])
def test_linear_verbs_and_dtmm_schemes_refuse_a_saturated_chain_loop(verb):
    with pytest.raises(ModelError, match=r"loop 'pd' saturates at \(-0.8, 0.8\)"):
        verb(realtime())
    verb(realtime().with_loops([realtime().loops[0].unsaturated()]))   # the small-signal loop is answered
