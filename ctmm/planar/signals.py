"""User signals of a planar model (hinge laws, loads, prescribed motions): evaluation that names a failure.

A signal is a number or a callable of time ``t`` [s] (:func:`ctmm.signals.as_signal`).  During a
run :func:`signal_values` evaluates many of them at once; when one raises, returns a non-finite
value or more than one number, the run stops with :class:`SignalError` (a
:class:`~ctmm.errors.SimulationError`) that names the signal, its element and the time, and the
integrator completes it with the partial result.
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from ..errors import SimulationError
from ..guard import UserFunction, call_user, user_output

__all__ = ["SignalError", "signal_values"]


class SignalError(SimulationError):
    """A user signal of a planar model (hinge law, load, prescribed motion) raised or returned
    something other than one finite number; names the element and the time."""


def signal_values(functions: Sequence[Callable[[float], float]], t: float, labels: Sequence[str],
                  parts: Sequence[str] | str, *, quote: bool = True) -> np.ndarray:
    """``[f(t) for f in functions]`` as floats; a failing one -> :class:`SignalError`.

    Parameters
    ----------
    functions : sequence of callable
        The signals.
    t : float
        Time [s].
    labels, parts : sequence of str
        Element (joint, body or load) and quantity (``"torque"``, ``"force_x"``, ...) of each
        signal, for the message (``parts`` may be one string for all).
    quote : bool
        Quote the label in the message.

    The fast path is one list comprehension over the user's own functions (a
    :class:`ctmm.guard.UserFunction` is unwrapped: its per-call checks are the ones made here on all
    values at once); when that does not give one finite number per signal, the functions are called
    through their guards (which accept a one-element array as its number), and only on failure is
    every function called again one by one (:func:`ctmm.guard.call_user`,
    :func:`ctmm.guard.user_output`) to name it.
    """
    values = _finite_values([f.function if type(f) is UserFunction else f for f in functions], t)
    if values is None:
        values = _finite_values(functions, t)
    if values is not None:
        return values
    if isinstance(parts, str):
        parts = [parts] * len(functions)
    for function, label, part in zip(functions, labels, parts):
        what = f"{part} of {label!r}" if quote else f"{part} of {label}"
        raw = function.function if isinstance(function, UserFunction) else function  # named here, not twice
        try:
            user_output(what, call_user(what, raw, t, time=t), 1, time=t)
        except SimulationError as exc:
            raise SignalError(str(exc), time=float(t), element=str(label)) from exc.__cause__
    raise SignalError(f"user signals returned an invalid set of values at t = {t:.6g} s", time=float(t))


def _finite_values(functions: Sequence[Callable[[float], float]], t: float) -> np.ndarray | None:
    """``[f(t) for f in functions]`` when that is one finite float per function, else None (whatever went wrong
    is found and named by :func:`signal_values`)."""
    try:
        values = np.array([f(t) for f in functions], dtype=float)
    except Exception:  # noqa: BLE001 - user code; found and named by the caller
        return None
    return values if values.shape == (len(functions),) and np.isfinite(values).all() else None
