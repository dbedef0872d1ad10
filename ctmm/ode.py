"""One fixed-step classical Runge-Kutta (RK4) integrator for every explicit time loop.

``y' = f(t, y)`` with a vector state ``y`` (a 1-D array of any length, [SI units of the
caller]) and a step ``h`` [s].  :func:`rk4_step` is the scheme; :func:`integrate_rk4` runs it
over ``n_steps`` steps with an optional callback after every step (the caller's divergence
guards, co-simulation sampling and storing every ``k``-th step live there).  The scheme's
stability limit on an undamped mode is :data:`ctmm.guard.RK4_LIMIT` (``omega h <= 2 sqrt 2``),
checked by the callers before their runs.

The scheme is written once, in :func:`rk4_step`.  The compiled paths do not transcribe it: the
casadi path (``manipulator/compiled.py``) calls :func:`rk4_step` on casadi symbols, and the C
kernel (``planar/compiled.py``) takes its step from :func:`second_order_rk4_c`, which runs
:func:`rk4_step` on symbolic C operands and prints the expressions it builds.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from .errors import ModelError

__all__ = ["rk4_step", "integrate_rk4", "second_order_rate", "second_order_rk4_c"]

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


class _CExpression:
    """A C expression (its text) standing for one element ``[i]`` of a state array while
    :func:`rk4_step` is traced; arithmetic builds fully parenthesised C text."""

    def __init__(self, text: str) -> None:
        self.text = text

    @staticmethod
    def _of(value) -> "_CExpression":
        if isinstance(value, _CExpression):
            return value
        if isinstance(value, (int, float, np.floating)) and not isinstance(value, bool):
            return _CExpression(repr(float(value)))
        raise TypeError(f"cannot write {value!r} into C")

    def _combine(self, operator: str, other, reflected: bool):
        if isinstance(other, _CState):
            return NotImplemented
        left, right = (self._of(other), self) if reflected else (self, self._of(other))
        return _CExpression(f"({left.text} {operator} {right.text})")

    def __add__(self, other):
        return self._combine("+", other, False)

    def __radd__(self, other):
        return self._combine("+", other, True)

    def __mul__(self, other):
        return self._combine("*", other, False)

    def __rmul__(self, other):
        return self._combine("*", other, True)

    def __truediv__(self, other):
        return self._combine("/", other, False)


class _CState:
    """The traced state ``[q, v]`` of a second-order system: two :class:`_CExpression` halves."""

    def __init__(self, position: _CExpression, velocity: _CExpression) -> None:
        self.halves = (position, velocity)

    def __add__(self, other):
        if not isinstance(other, _CState):
            return NotImplemented
        return _CState(*(a + b for a, b in zip(self.halves, other.halves)))

    def __rmul__(self, factor):
        return _CState(*(factor * a for a in self.halves))


def second_order_rk4_c(acceleration_call: Callable[[str, str, str], str], *, position: str = "th",
                       velocity: str = "w", step: str = "h", count: str = "nb", index: str = "i") -> str:
    """C statements of one :func:`rk4_step` of ``q'' = a(q, v)``, generated from :func:`rk4_step`.

    :func:`rk4_step` is run on symbolic operands that write C: every stage state is stored in the
    arrays ``q2, v2, q3, v3, q4, v4`` and every stage acceleration in ``a1 .. a4`` (the caller
    declares them, ``count`` doubles each), and the new state overwrites ``position`` and
    ``velocity`` in place.  The expressions keep the operations of :func:`rk4_step` in its order
    (``y + 0.5 h k``, ``y + (h / 6) (k1 + 2 k2 + 2 k3 + k4)``), so the compiled step rounds as the
    Python one does when the compiler keeps IEEE semantics (no ``-ffast-math``).

    Parameters
    ----------
    acceleration_call : callable
        ``acceleration_call(q, v, a)`` -> C statement that writes the accelerations of the
        state arrays named ``q``, ``v`` into the array named ``a`` (the time is not passed: the
        system must be autonomous).
    position, velocity : str
        Names of the C arrays of the coordinates [caller's units] and rates, updated in place.
    step : str
        Name of the C step variable ``h`` [s].
    count : str
        Name of the C variable with the number of coordinates.
    index : str
        Loop index name.

    Returns
    -------
    str
        C statements (one step; no declarations).
    """
    lines: list[str] = []
    start = _CState(_CExpression(f"{position}[{index}]"), _CExpression(f"{velocity}[{index}]"))
    stages = 0

    def loop(targets: tuple[str, str], state: _CState) -> None:
        body = " ".join(f"{name}[{index}] = {half.text};" for name, half in zip(targets, state.halves))
        lines.append(f"for (int {index} = 0; {index} < {count}; {index}++) {{ {body} }}")

    def rate(t, y: _CState) -> _CState:
        nonlocal stages
        stages += 1
        names = (position, velocity)
        if y is not start:
            names = (f"q{stages}", f"v{stages}")
            loop(names, y)
        lines.append(acceleration_call(names[0], names[1], f"a{stages}"))
        return _CState(_CExpression(f"{names[1]}[{index}]"), _CExpression(f"a{stages}[{index}]"))

    new = rk4_step(rate, _CExpression("t"), start, _CExpression(step))
    if f"{position}[" in new.halves[1].text:
        raise ModelError("the traced RK4 step reads the coordinates in the rate update (internal error)")
    loop((position, velocity), new)
    return "\n".join(lines)
