"""Delay history: past values of a sensed signal, interpolated at any time ``t - tau``.

One class, :class:`DelayHistory`, serves every delayed loop of the package (the controlled chains
of :mod:`ctmm.control.simulate` and the planar models of :mod:`ctmm.control.planar_time`).  It
keeps only the samples a delay ``tau`` can reach -- a window of ``O(tau / dt)`` samples, trimmed
when it reaches twice that length (with ``"hermite"`` never below the samples ``t - tau`` can still
read, whatever the steps: a ``solve_ivp`` method may step shorter than the ``step`` the window is
counted in) -- so its memory and its cost per step do not grow with the run length.  Two
interpolations share the interface:

* ``"hermite"`` (default): cubic Hermite between two stored steps from the values ``y`` and
  their time derivatives ``dy`` (exact on cubics, third order), or linear where a derivative is
  unknown (``None``: accelerations, forces); times are found by bisection, so the stored times
  need not be uniform;
* ``"lagrange"``: derivative-free 4-point Lagrange interpolation on a uniform step grid
  ``t_k = t0 + k dt`` (exact on cubics, fourth order); values may be arrays.

Before the start time the history is the state held: ``before`` (default: the start value),
and exactly at the start the start value.  Asking for a time after the last stored sample (a
delay shorter than the step) or before the window (an internal error) raises
:class:`~ctmm.errors.SimulationError` instead of extrapolating.
"""
from __future__ import annotations

import bisect
import math
from typing import Any

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError

__all__ = ["DelayHistory", "INTERPOLATIONS"]

INTERPOLATIONS = ("hermite", "lagrange")


class DelayHistory:
    """Sensed values of one signal, interpolated at any past time, in O(1) memory and time per step.

    Parameters
    ----------
    start_time : float
        Time of the first sample ``t0`` [s].
    start_value : float or numpy.ndarray
        Value at ``t0`` (unit of the signal; an array for ``"lagrange"`` vector signals).
    start_derivative : float or None
        Time derivative at ``t0`` [unit/s] (``"hermite"``; ``None``: unknown, linear
        interpolation on the first interval).
    before : float or numpy.ndarray, optional
        Value returned for times before ``t0`` (the initial state held; default ``start_value``).
    delay : float
        Largest delay ``tau`` [s] the history is asked for (sets the window length).
    step : float
        Time step ``dt`` [s] between appended samples (the grid spacing for ``"lagrange"``).
    interpolation : {"hermite", "lagrange"}
        See the module docstring.

    Raises
    ------
    ModelError
        A non-finite time, a negative delay, a step <= 0 or an unknown interpolation.
    """

    def __init__(self, start_time: float, start_value: Any, start_derivative: float | None = None, *,
                 before: Any = None, delay: float = 0.0, step: float = 1.0,
                 interpolation: str = "hermite") -> None:
        if interpolation not in INTERPOLATIONS:
            raise ModelError(f"interpolation must be one of {INTERPOLATIONS}, got {interpolation!r}")
        validation.finite("start_time", start_time)
        step = validation.positive("step", step)
        if not delay >= 0.0 or not math.isfinite(delay):
            raise ModelError(f"delay must be a finite number >= 0 [s], got {delay!r}")
        self.start_time = start_time
        self.start_value = _stored(start_value)
        self.before = self.start_value if before is None else before
        self.step = step
        self.delay = delay
        self.interpolation = interpolation
        self.times = [start_time]
        self.values = [self.start_value]
        self.derivatives = [start_derivative]
        self.first_index = 0          # grid index of values[0] ("lagrange")
        # samples a lookup at (last time + dt - delay) can reach, plus the interpolation stencil
        self.keep = int(math.ceil(delay / step)) + (3 if interpolation == "hermite" else 4)

    @property
    def window_length(self) -> int:
        """Number of samples currently stored (at most ``2 * (ceil(delay / step) + 4)``)."""
        return len(self.times)

    @property
    def last_time(self) -> float:
        """Time of the last stored sample [s]."""
        return self.times[-1]

    def append(self, time: float, value: Any, derivative: float | None = None) -> None:
        """Store the sample at ``time`` [s] (after the last one); trims the window when it is full.

        Raises
        ------
        SimulationError
            ``"lagrange"``: ``time`` is not the next point of the step grid.
        """
        if self.interpolation == "lagrange":
            index = self.first_index + len(self.times)
            grid = self.start_time + index * self.step
            if abs(time - grid) > 1e-9 * max(self.step, abs(grid)):
                raise SimulationError(f"delay history sample at t = {time!r} s is off the step grid "
                                      f"(expected t = {grid!r} s; internal error)", time=float(time))
        self.times.append(time)
        self.values.append(_stored(value))
        self.derivatives.append(derivative)
        if len(self.times) > 2 * self.keep:
            drop = len(self.times) - self.keep
            if self.interpolation == "hermite":     # steps shorter than `step` (solve_ivp): keep what t - delay reads
                drop = min(drop, max(bisect.bisect_right(self.times, time - self.delay) - 2, 0))
            if 2 * drop >= len(self.times):         # at least half at a time: O(1) per sample
                del self.times[:drop], self.values[:drop], self.derivatives[:drop]
                self.first_index += drop

    def __call__(self, time: float) -> Any:
        """Value at ``time`` [s] (see the module docstring for the rules)."""
        t0 = self.start_time
        if time < t0 - 1e-12 * max(1.0, abs(t0)):
            return self.before
        if time <= t0:
            return self.start_value
        if self.interpolation == "lagrange":
            return self._lagrange(time)
        return self._hermite(time)

    def _hermite(self, t: float) -> Any:
        ts = self.times
        if t >= ts[-1]:
            if t - ts[-1] > 1e-9 * max(1.0, abs(t)):
                raise SimulationError(f"delay history requested at t={t} beyond the last step {ts[-1]} "
                                      "(a delay shorter than the step?)", time=t)
            return self.values[-1]
        if t < ts[0]:
            raise SimulationError(f"delay history requested at t={t}, before its window {ts[0]} (internal error)",
                                  time=t)
        k = bisect.bisect_left(ts, t) - 1
        k = min(max(k, 0), len(ts) - 2)
        h = ts[k + 1] - ts[k]
        x = (t - ts[k]) / h
        y0, y1, d0, d1 = self.values[k], self.values[k + 1], self.derivatives[k], self.derivatives[k + 1]
        if d0 is None or d1 is None:
            return (1 - x) * y0 + x * y1
        h00 = 2 * x ** 3 - 3 * x ** 2 + 1
        h10 = x ** 3 - 2 * x ** 2 + x
        h01 = -2 * x ** 3 + 3 * x ** 2
        h11 = x ** 3 - x ** 2
        return h00 * y0 + h10 * h * d0 + h01 * y1 + h11 * h * d1

    def _lagrange(self, t: float) -> Any:
        x = (t - self.start_time) / self.step             # position on the grid, in steps
        first = self.first_index
        last = first + len(self.values) - 1
        k = int(math.floor(x + 1e-9))
        if k >= last:
            if x > last + 1e-6:
                raise SimulationError(f"delayed signal needed at t = {t:.6g} s beyond the stored history "
                                      f"(last sample t = {self.times[-1]:.6g} s; a delay shorter than the step?)",
                                      time=t)
            return self.values[-1]
        lo = min(max(k - 1, 0), max(last - 3, 0))
        if lo < first:
            raise SimulationError(f"delay history requested at t = {t:.6g} s, before its window "
                                  f"{self.times[0]:.6g} s (internal error)", time=t)
        xs = range(lo, min(lo + 4, last + 1))
        weights = []
        for i in xs:
            p = 1.0
            for j in xs:
                if j != i:
                    p *= (x - j) / (i - j)
            weights.append(p)
        return np.asarray(weights) @ np.array(self.values[lo - first:lo - first + len(xs)])


def _stored(value: Any) -> Any:
    """A private copy of an array sample (the caller may reuse its buffer); scalars as given."""
    return value.copy() if isinstance(value, np.ndarray) else value
