"""Evaluation of a modal beam's :class:`~ctmm.flexible.beam.ModalForce` ``force`` and ``law`` callables (user code)."""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..planar.signals import SignalError


def hook_value(element: str, size: int, what: str, function: Callable, args: tuple, t: float) -> np.ndarray:
    """A ``force`` or ``law`` value of a :class:`~ctmm.flexible.beam.ModalForce` on beam ``element``: ``size``
    (``n_eta``) finite numbers, complex allowed for the complex-step tangent.

    Raises
    ------
    SignalError
        The callable raised, or returned another shape or non-finite values; named with ``what``, the time ``t``
        [s] and the element.
    """
    try:
        value = np.asarray(function(*args))
        if value.shape == (size,) and np.all(np.isfinite(value)):
            return value
    except Exception as exc:  # noqa: BLE001 - user code: named with the time
        raise SignalError(f"{what} raised {type(exc).__name__} at t = {t:.6g} s: {exc}", time=float(t),
                          element=element) from exc
    raise SignalError(f"{what} returned {value!r} at t = {t:.6g} s; expected {size} finite value(s)",
                      time=float(t), element=element)


__all__ = ["hook_value"]
