"""Reused call buffers of the generated time loop (:class:`ctmm.generated_loop.BlockRunner`, issue 13).

A co-simulation calls :func:`ctmm.generated_loop.run_blocks` once per sample interval with one runner per run:
the answers must be those of fresh buffers bit for bit, the held inputs, start index and parameters of each
interval must reach the function (not the first interval's ones), and a batch must map its members.  The
reference is a plain numpy RK4 loop (no casadi), on an uncompiled casadi step (nothing is generated)."""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.generated_loop import BlockRunner, rk4_step_function, run_blocks, time_loop_functions


def loop_functions(store_every: int, rows: int):
    """``(blocks, stride, step)`` of ``y' = [y1, -p y0 + u + t]`` (a forced oscillator, time-dependent)."""
    import casadi as ca

    y, u, p, t = ca.MX.sym("y", 2), ca.MX.sym("u", 1), ca.MX.sym("p", 1), ca.MX.sym("t")
    rate = ca.Function("rate", [y, u, p, t], [ca.vertcat(y[1], -p * y[0] + u + t)])
    step = rk4_step_function(rate)
    stride, sizes, blocks = time_loop_functions(step, store_every, rows)
    return list(zip(sizes, blocks)), stride, step


def numpy_rk4(y: np.ndarray, u: float, p: float, h: float, t: float) -> np.ndarray:
    """One classical RK4 step of the same rates, in numpy."""
    def rate(time: float, state: np.ndarray) -> np.ndarray:
        return np.array([state[1], -p * state[0] + u + time])

    k1 = rate(t, y)
    k2 = rate(t + h / 2, y + h / 2 * k1)
    k3 = rate(t + h / 2, y + h / 2 * k2)
    k4 = rate(t + h, y + h * k3)
    return y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


@pytest.mark.parametrize("store_every", [1, 2])
def test_reused_runner_matches_fresh_buffers_and_a_numpy_rk4_over_changing_intervals(store_every):
    blocks, stride, step = loop_functions(store_every, rows=8)
    h, p = 0.01, np.array([[4.0]])
    runner = BlockRunner()
    y = np.array([0.3, -0.1])
    reference = y.copy()
    k = 0
    for n_steps, u in [(3, 0.5), (7, -1.0), (1, 2.0), (20, 0.0), (5, 1.5)]:    # held input jumps per interval
        held = np.array([u])
        reused = run_blocks(blocks, stride, step, store_every, y[:, None], held, h, n_steps, 0.0, p,
                            first_step=k, runner=runner)[0]
        fresh = run_blocks(blocks, stride, step, store_every, y[:, None], held, h, n_steps, 0.0, p, first_step=k)[0]
        assert np.array_equal(reused, fresh)
        stored = []
        for j in range(n_steps):
            reference = numpy_rk4(reference, u, 4.0, h, (k + j) * h)
            if (j + 1) % store_every == 0 or j + 1 == n_steps:
                stored.append(reference)
        np.testing.assert_allclose(reused, np.array(stored), rtol=1e-12, atol=1e-14)
        y, k = reused[-1], k + n_steps


def test_reused_runner_maps_a_batch_and_takes_each_calls_parameters():
    blocks, stride, step = loop_functions(1, rows=4)
    runner = BlockRunner()
    y = np.array([[0.3, 0.0], [-0.1, 1.0]])                  # two members (columns)
    for p in (np.array([[4.0, 9.0]]), np.array([[1.0, 2.0]])):
        reused = run_blocks(blocks, stride, step, 1, y, np.array([0.5]), 0.02, 6, 0.1, p, runner=runner)
        fresh = run_blocks(blocks, stride, step, 1, y, np.array([0.5]), 0.02, 6, 0.1, p)
        assert np.array_equal(reused, fresh)
        for member in range(2):
            state = y[:, member]
            for j in range(6):
                state = numpy_rk4(state, 0.5, float(p[0, member]), 0.02, 0.1 + j * 0.02)
            np.testing.assert_allclose(reused[member, -1], state, rtol=1e-12, atol=1e-14)


def test_a_step_without_inputs_or_parameters_keeps_its_six_inputs_and_its_numbers_bit_for_bit():
    """Empty ``u`` and ``p`` (no actuators, numbers as constants) are left out of the functions the time loop is
    built from (casadi sweeps a called graph for zero outputs when an argument is empty): the stride and blocks
    still take ``(y, u, h, p, t0, k)`` and return, bit for bit, the states of the step called one step at a time
    (casadi's virtual machine, nothing compiled), for an odd block (two halves and a stride) and its halves."""
    import casadi as ca

    y, u, p, t = ca.MX.sym("y", 2), ca.MX.sym("u", 0), ca.MX.sym("p", 0), ca.MX.sym("t")
    step = rk4_step_function(ca.Function("rate", [y, u, p, t], [ca.vertcat(y[1], -4.0 * y[0] + ca.sin(t))]))
    store_every, h, t0, first = 3, 0.01, 0.2, 5.0
    stride, sizes, blocks = time_loop_functions(step, store_every, rows=5)
    assert sizes == [5, 2]
    for function in (stride, *blocks):
        assert [function.size_in(i) for i in range(6)] == [step.size_in(i) for i in range(6)]
        assert function.name_in() == step.name_in() and function.n_out() == 1
    x, stored = np.array([0.3, -0.1]), []
    for j in range(store_every * sizes[0]):
        x = np.asarray(step(x, [], h, [], t0, first + j)).reshape(-1)
        if (j + 1) % store_every == 0:
            stored.append(x)
    assert np.array_equal(np.asarray(stride([0.3, -0.1], [], h, [], t0, first)).reshape(-1), stored[0])
    for size, block in zip(sizes, blocks):
        assert np.array_equal(np.asarray(block([0.3, -0.1], [], h, [], t0, first)), np.array(stored[:size]).T)
