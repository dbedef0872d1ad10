"""Global Newmark integration of a chain closed by real-time and delayed feedback loops.

Independent reference for the controlled DT-TMM (:func:`ctmm.control.simulate_controlled`):
the textbook acceleration-form Newmark method on the global matrices ``M, C, K`` of
:mod:`ctmm.reference.chain`, with the loop forces

.. math:: u_l(t) = -g_l \\, y_l(t - \\tau_l), \\qquad y_l = c_l^T x^{(p_l)},

acting as ``+u_l`` on the actuator mass (``-u_l`` on a reaction mass), treated by the rule
documented in :mod:`ctmm.control.simulate` -- and nothing else of ctmm (it imports no TMM
code, only :mod:`ctmm.reference.chain`, :mod:`ctmm.reference.delay_chain`'s
:class:`~ctmm.reference.delay_chain.GlobalLoop` and its loop vectors
(:func:`~ctmm.reference.delay_chain.loop_terms`), :mod:`ctmm.errors` and
:mod:`ctmm.validation`):

* **real time** (``tau < h``): the force at ``t_{n+1}`` uses the unknown state.  With
  ``theta = tau/h`` the sensed value at ``t_{n+1} - tau`` is interpolated linearly between the
  stored ``y_n`` and the unknown ``y_{n+1}``; since ``x_{n+1} = x~ + beta h^2 a``,
  ``v_{n+1} = v~ + gamma h a`` and ``a_{n+1} = a``, the loop adds
  ``g (1 - theta) kappa_p b c^T`` to the effective matrix (``kappa = beta h^2, gamma h, 1`` for
  ``p = 0, 1, 2``) and ``-g b [(1 - theta) c^T q~_p + theta y_n]`` to the right-hand side;
* **delayed** (``tau >= h``): ``u_{n+1} = -g Y(t_{n+1} - tau)`` is known from the history: the
  stored ``(t_k, y_k, y'_k)`` interpolated by cubic Hermite polynomials (``y' = c^T x^{(p+1)}``
  for displacement and velocity sensing) or linearly (acceleration sensing).  Samples are taken
  from the state at ``t_k`` (at ``t_0`` with the true initial acceleration: right limits).

History before ``t_0``: the held initial state ``(x_0, v_0, 0)`` -- the default of
:func:`ctmm.reference.delay_chain.method_of_steps` -- so a delayed displacement or velocity
loop starts with ``u = -g y_0`` and a delayed acceleration loop with ``u = 0``.  The initial
acceleration solves the equation of motion at ``t_0`` with these forces (an undelayed
acceleration loop acts on ``a_0`` itself: ``M + g b c^T``).

Delayed *acceleration* feedback is a neutral equation: the acceleration jumps at ``t_0 + k tau``
and any fixed-step method without discontinuity tracking (this one, and the DT-TMM) is then only
first order.

Newmark (Newmark 1959; Hughes, *The Finite Element Method*, ch. 9): predictors
``x~ = x + h v + (1/2 - beta) h^2 a``, ``v~ = v + (1 - gamma) h a``; solve
``(M + gamma h C + beta h^2 K + sum_rt g (1 - theta) kappa b c^T) a+ = f(t+) - C v~ - K x~ + loads``.
"""
from __future__ import annotations

import bisect
from typing import Callable, NamedTuple, Sequence

import numpy as np
import scipy.linalg as sla

from ..errors import ModelError, SimulationError
from ..validation import finite_array, nonnegative, positive
from .chain import GlobalChain, assemble, force_function, time_grid
from .delay_chain import GlobalLoop, loop_terms

__all__ = ["ClosedLoopHistory", "newmark_closed_loop"]


class ClosedLoopHistory(NamedTuple):
    """Time response of the closed loop.

    Attributes
    ----------
    time : ndarray (nt,)
        [s].
    displacement, velocity, acceleration : ndarray (nt, n)
        Mass motion [m], [m/s], [m/s^2].
    sensed : ndarray (nt, n_loops)
        Sensed values ``y_l(t_k)``.
    control : ndarray (nt, n_loops)
        Control forces ``u_l(t_k) = -g_l y_l(t_k - tau_l)`` [N] (history-interpolated).
    """

    time: np.ndarray
    displacement: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    sensed: np.ndarray
    control: np.ndarray


class _HermiteHistory:
    """Stored samples ``(t_k, y_k, y'_k)`` with cubic Hermite (or linear) interpolation.

    Queries before the first sample return the pre-history value ``before``; queries at or after
    it interpolate the samples (right-continuous at ``t_0``, as the method of steps).
    """

    def __init__(self, hermite: bool, before: float) -> None:
        self.hermite = hermite
        self.before = before
        self.t: list[float] = []
        self.y: list[float] = []
        self.dy: list[float] = []

    def append(self, t: float, y: float, dy: float) -> None:
        self.t.append(t)
        self.y.append(y)
        self.dy.append(dy)

    def __call__(self, t: float) -> float:
        ts = self.t
        if t < ts[0] - 1e-12 * max(1.0, abs(ts[0])):
            return self.before
        if t <= ts[0]:
            return self.y[0]
        if t >= ts[-1]:
            if t - ts[-1] > 1e-9 * max(1.0, abs(t)):
                raise SimulationError(f"history requested at t={t} after the last sample {ts[-1]}", time=t)
            return self.y[-1]
        k = min(max(bisect.bisect_right(ts, t) - 1, 0), len(ts) - 2)
        h = ts[k + 1] - ts[k]
        s = (t - ts[k]) / h
        y0, y1 = self.y[k], self.y[k + 1]
        if not self.hermite:
            return (1.0 - s) * y0 + s * y1
        d0, d1 = self.dy[k], self.dy[k + 1]
        return ((2 * s ** 3 - 3 * s ** 2 + 1) * y0 + (s ** 3 - 2 * s ** 2 + s) * h * d0
                + (-2 * s ** 3 + 3 * s ** 2) * y1 + (s ** 3 - s ** 2) * h * d1)


def newmark_closed_loop(chain: GlobalChain, loops: Sequence[GlobalLoop], t_final: float, dt: float,
                        x0, v0, force_fn: Callable[[float], np.ndarray] | None = None, *,
                        beta: float = 0.25, gamma: float = 0.5) -> ClosedLoopHistory:
    """Newmark integration of ``M x'' + C x' + K x = f + sum_l b_l u_l`` with the loop rule above.

    Parameters
    ----------
    chain : GlobalChain
    loops : sequence of GlobalLoop
        Static-gain loops (displacement, velocity or acceleration sensing; relative sensing and
        across actuators allowed).
    t_final, dt : float
        End time and step [s] (``t_final/dt`` an integer).
    x0, v0 : array_like (n,)
        Initial displacements [m] and velocities [m/s].
    force_fn : callable, optional
        External forces ``f(t) -> (n,)`` [N].
    beta, gamma : float
        Newmark parameters.

    Returns
    -------
    ClosedLoopHistory
    """
    beta, gamma = positive("beta", beta), nonnegative("gamma", gamma)
    times = time_grid(t_final, dt)
    h = float(times[1] - times[0])
    terms = loop_terms(chain, loops)
    force = force_function(chain, force_fn)
    M, C, K = assemble(chain)
    n, nl = chain.size, len(terms)
    x = np.empty((times.size, n))
    v, a = np.empty_like(x), np.empty_like(x)
    x[0] = finite_array("x0", x0, ndim=1)
    v[0] = finite_array("v0", v0, ndim=1)
    if x[0].shape != (n,) or v[0].shape != (n,):
        raise ModelError(f"x0 and v0 must have shape ({n},)")
    realtime = [k for k, lp in enumerate(terms) if lp.delay < h]
    delayed = [k for k, lp in enumerate(terms) if lp.delay >= h]
    kappa = (beta * h * h, gamma * h, 1.0)
    # initial acceleration.  Before t0 the motion is the held initial state (x0, v0, zero
    # acceleration), as in delay_chain.method_of_steps, so u_l(t0) = -g y_l(t0 - tau) is
    # -g c.q0 for displacement/velocity sensing, 0 for delayed acceleration sensing, and
    # -g c.a0 (implicit: M + g b c^T) for an undelayed acceleration loop.
    M0 = M.copy()
    load0 = force(0.0) - C @ v[0] - K @ x[0]
    for lp in terms:
        if lp.order == 2:
            if lp.delay == 0.0:
                M0 = M0 + lp.gain * np.outer(lp.actuator, lp.sensor)
        else:
            load0 = load0 - lp.gain * lp.actuator * float(lp.sensor @ (x[0], v[0])[lp.order])
    a[0] = np.linalg.solve(M0, load0)
    histories = []
    q = (x[0], v[0], a[0])
    for lp in terms:
        hist = _HermiteHistory(hermite=lp.order < 2,
                               before=float(lp.sensor @ q[lp.order]) if lp.order < 2 else 0.0)
        hist.append(float(times[0]), float(lp.sensor @ q[lp.order]),
                    float(lp.sensor @ q[lp.order + 1]) if lp.order < 2 else 0.0)
        histories.append(hist)
    sensed = np.empty((times.size, nl))
    control = np.empty((times.size, nl))
    for k, lp in enumerate(terms):
        sensed[0, k] = histories[k].y[0]
        control[0, k] = -lp.gain * histories[k](float(times[0]) - lp.delay)
    effective = M + gamma * h * C + beta * h * h * K
    for k in realtime:
        lp = terms[k]
        theta = lp.delay / h
        effective = effective + lp.gain * (1.0 - theta) * kappa[lp.order] * np.outer(lp.actuator, lp.sensor)
    factors = sla.lu_factor(effective)
    for i in range(times.size - 1):
        t_next = float(times[i + 1])
        x_pred = x[i] + h * v[i] + (0.5 - beta) * h * h * a[i]
        v_pred = v[i] + (1.0 - gamma) * h * a[i]
        rhs = force(t_next) - C @ v_pred - K @ x_pred
        for k in realtime:
            lp = terms[k]
            theta = lp.delay / h
            q_pred = (x_pred, v_pred, np.zeros(n))[lp.order]
            rhs = rhs - lp.gain * lp.actuator * ((1.0 - theta) * float(lp.sensor @ q_pred) + theta * histories[k].y[-1])
        for k in delayed:
            lp = terms[k]
            rhs = rhs - lp.gain * lp.actuator * histories[k](t_next - lp.delay)
        a[i + 1] = sla.lu_solve(factors, rhs)
        x[i + 1] = x_pred + beta * h * h * a[i + 1]
        v[i + 1] = v_pred + gamma * h * a[i + 1]
        if not (np.all(np.isfinite(x[i + 1])) and np.all(np.isfinite(v[i + 1]))):
            raise SimulationError(f"non-finite state at t = {t_next} s", time=t_next)
        q = (x[i + 1], v[i + 1], a[i + 1])
        for k, lp in enumerate(terms):
            y = float(lp.sensor @ q[lp.order])
            histories[k].append(t_next, y, float(lp.sensor @ q[lp.order + 1]) if lp.order < 2 else 0.0)
            sensed[i + 1, k] = y
            control[i + 1, k] = -lp.gain * histories[k](t_next - lp.delay)
    return ClosedLoopHistory(times, x, v, a, sensed, control)
