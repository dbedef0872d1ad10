"""One fixed-step classical Runge-Kutta (RK4) integrator for every explicit time loop.

``y' = f(t, y)`` with a vector state ``y`` (a 1-D array of any length, [SI units of the
caller]) and a step ``h`` [s].  :func:`rk4_step` is the scheme; :func:`integrate_rk4` runs it
over ``n_steps`` steps with an optional callback after every step (the caller's divergence
guards, co-simulation sampling and storing every ``k``-th step live there).  The scheme's
stability limit on an undamped mode is :data:`ctmm.guard.RK4_LIMIT` (``omega h <= 2 sqrt 2``),
checked by the callers before their runs.

The scheme is written once, in :func:`rk4_step`.  The compiled paths do not transcribe it: the
generated kernels (:mod:`ctmm.generated_loop`) call :func:`rk4_step` on casadi symbols.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .errors import ModelError

__all__ = ["rk4_step", "integrate_rk4", "second_order_rate", "output_grid", "refuse_adaptive_options"]

#: ``f(t, y) -> y'``: rate of a vector state at time ``t`` [s].
Rate = Callable[[float, np.ndarray], np.ndarray]


def rk4_step(rate: Rate, t: float, y: np.ndarray, h: float) -> np.ndarray:
    """One classical RK4 step of ``y' = rate(t, y)`` from ``t`` [s] by ``h`` [s].

    Parameters
    ----------
    rate : callable
        ``rate(t, y)`` -> array of ``y``'s shape.
    t : float
        Time at the start of the step [s].
    y : ndarray
        State at ``t``.
    h : float
        Step [s].

    Returns
    -------
    ndarray
        State at ``t + h``: ``y + h/6 (k1 + 2 k2 + 2 k3 + k4)``.
    """
    k1 = rate(t, y)
    k2 = rate(t + 0.5 * h, y + 0.5 * h * k1)
    k3 = rate(t + 0.5 * h, y + 0.5 * h * k2)
    k4 = rate(t + h, y + h * k3)
    return y + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def integrate_rk4(rate: Rate, y0, *, h: float, n_steps: int, t0: float = 0.0,
                  after_step: Callable[[int, float, np.ndarray], None] | None = None) -> np.ndarray:
    """``n_steps`` fixed RK4 steps of ``y' = rate(t, y)`` from ``y(t0) = y0``.

    Parameters
    ----------
    rate : callable
        ``rate(t, y)`` -> array of ``y``'s shape.
    y0 : array_like
        Initial state (copied).
    h : float
        Step [s], > 0 and finite.
    n_steps : int
        Number of steps, >= 0.
    t0 : float
        Initial time [s]; step ``k`` (1-based) ends at ``t0 + k h`` (computed as a product, no
        accumulated round-off).
    after_step : callable, optional
        ``after_step(k, t, y)`` after step ``k`` with the time ``t`` [s] and state ``y`` at its
        end: guards raise from here, storing keeps ``y`` (a fresh array each step, safe to keep).

    Returns
    -------
    ndarray
        State at ``t0 + n_steps h``.
    """
    if not (np.isfinite(h) and h > 0.0):
        raise ModelError(f"h must be a finite step > 0 [s], got {h!r}")
    if isinstance(n_steps, bool) or not isinstance(n_steps, (int, np.integer)) or n_steps < 0:
        raise ModelError(f"n_steps must be an integer >= 0, got {n_steps!r}")
    y = np.array(y0, dtype=float)
    for k in range(int(n_steps)):
        y = rk4_step(rate, t0 + k * h, y, h)
        if after_step is not None:
            after_step(k + 1, t0 + (k + 1) * h, y)
    return y


def second_order_rate(acceleration: Callable[[np.ndarray, np.ndarray, float], np.ndarray],
                      n: int) -> Rate:
    """Rate of ``y = [q, v]`` for ``q'' = acceleration(q, v, t)`` with ``n`` coordinates.

    Parameters
    ----------
    acceleration : callable
        ``acceleration(q, v, t)`` -> ``q''`` (``n`` values).
    n : int
        Number of coordinates ``q``; ``y`` has ``2 n`` entries.
    """
    def rate(t: float, y: np.ndarray) -> np.ndarray:
        q, v = y[:n], y[n:]
        return np.concatenate((v, acceleration(q, v, t)))

    return rate


def output_grid(t0: float, t_final: float, dt: float) -> np.ndarray:
    """The times [s] a ``solve_ivp`` run with an output step stores: ``t0 + k dt`` up to ``t_final``, and
    ``t_final`` itself (appended when the step does not divide the run; the last grid time set to it where
    round-off put it beside it: ``solve_ivp`` refuses a ``t_eval`` beyond its span)."""
    grid = t0 + dt * np.arange(int(np.floor((t_final - t0) / dt + 1e-9)) + 1)
    if abs(grid[-1] - t_final) <= 1e-9 * max(abs(t_final), dt):
        grid[-1] = t_final
    elif grid[-1] < t_final:
        grid = np.append(grid, t_final)
    return grid


def refuse_adaptive_options(method: object, methods: tuple[str, ...], rtol: float, atol: float,
                            max_step: float | None) -> None:
    """Refuse, by name, ``rtol``, ``atol`` or ``max_step`` [s] other than :func:`ctmm.simulate`'s defaults
    (``1e-8``, ``1e-10``, ``None``) with a ``method`` that is not one of the ``solve_ivp`` ``methods``: a
    fixed-step run would ignore them.

    Raises
    ------
    ModelError
        Naming the option, its value, the methods it applies to and the default to leave it at.
    """
    for name, (value, default) in {"rtol": (rtol, 1e-8), "atol": (atol, 1e-10), "max_step": (max_step, None)}.items():
        if value != default and method not in methods:
            raise ModelError(f"{name}={value!r} applies to the solve_ivp methods {methods}, not to "
                             f"method={method!r} (leave {name} at {default!r})")
