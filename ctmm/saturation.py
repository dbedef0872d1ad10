"""Actuator saturation of a feedback loop: ``u_applied = min(max(u, low), high)``.

A :class:`~ctmm.control.Feedback` with ``saturation=(low, high)`` [actuator unit] applies its force
clipped to the limits.  The clip is piecewise linear: slope 1 strictly inside the limits, 0 beyond
them.  The time paths of planar and spatial models, and of 1-D chains with ``"rk4"`` or a
``solve_ivp`` method (the one loop driver :mod:`ctmm.control.planar_time` and the generated RK4),
apply it at every evaluation (:func:`clip`: branch-free, so a complex-step or directional-difference
tangent through it is the slope of the side it is on); the linear verbs (frequency responses,
``ctmm.linearize``, stability, loop transfer functions) and the DT-TMM schemes of 1-D chains, whose
loops are embedded linearly, refuse a saturated loop (:func:`refuse_saturation`) rather than silently
linearising it: the small-signal loop about an operating point inside the limits is the loop without
its saturation (``Feedback.unsaturated()``).
"""
from __future__ import annotations

from typing import Any, Iterable

import numpy as np

from .errors import ModelError

__all__ = ["check_limits", "clip", "refuse_saturation"]


def check_limits(loop: str, value: Any) -> tuple[float, float]:
    """``(low, high)`` of loop ``loop``'s saturation [actuator unit], checked.

    Raises
    ------
    ModelError
        ``value`` is not a pair of numbers, holds NaN, or ``low >= high`` (``-inf`` / ``inf`` are
        allowed for a one-sided limit).
    """
    try:
        if isinstance(value, (str, bytes)) or any(isinstance(v, bool) for v in value):
            raise TypeError("not numbers")
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ModelError(f"loop {loop!r}: saturation must be None or a pair (low, high) of numbers [actuator "
                         f"unit], got {value!r}") from None
    if np.isnan(low) or np.isnan(high) or not low < high:
        raise ModelError(f"loop {loop!r}: saturation must satisfy low < high (-inf/inf allowed for one side), "
                         f"got {value!r}")
    return low, high


def clip(limits: tuple[float, float] | None, u: Any) -> Any:
    """``u`` clipped to ``limits`` (``u`` itself for ``None``); the real part decides, so a complex
    step through it has slope 1 inside the limits and 0 at them."""
    if limits is None:
        return u
    low, high = limits
    real = np.real(u)
    return np.where(real > high, high, np.where(real < low, low, u))[()]


def refuse_saturation(loops: Iterable[Any], what: str) -> None:
    """Refuse loops with a saturation where a linear loop is needed (``what`` names the verb).

    Raises
    ------
    ModelError
        Names the first saturated loop and its limits, and what to use instead.
    """
    for loop in loops:
        if getattr(loop, "saturation", None) is not None:
            raise ModelError(f"{what} needs linear loops, but loop {loop.name!r} saturates at {loop.saturation}: "
                             "a saturation is honoured in time (ctmm.simulate; a 1-D chain with method='rk4' or a "
                             "solve_ivp method); for the "
                             "small-signal loop about an operating point inside the limits use loop.unsaturated() "
                             "(slope 1; a loop at its limit is open, slope 0)")
