"""Parameter validation helpers: every check names the parameter, the value and what is allowed."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .errors import ModelError


def _as_float(name: str, value: Any) -> float:
    if isinstance(value, bool):
        raise ModelError(f"{name} must be a real number, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be a real number, got {value!r}") from None
    if not math.isfinite(number):
        raise ModelError(f"{name} must be finite, got {value!r}")
    return number


def finite(name: str, value: Any) -> float:
    """Return ``value`` as a finite float or raise :class:`ModelError`."""
    return _as_float(name, value)


def positive(name: str, value: Any) -> float:
    """Return ``value`` as a float > 0 or raise :class:`ModelError`."""
    number = _as_float(name, value)
    if number <= 0.0:
        raise ModelError(f"{name} must be > 0, got {value!r}")
    return number


def nonnegative(name: str, value: Any) -> float:
    """Return ``value`` as a float >= 0 or raise :class:`ModelError`."""
    number = _as_float(name, value)
    if number < 0.0:
        raise ModelError(f"{name} must be >= 0, got {value!r}")
    return number


def in_range(name: str, value: Any, low: float, high: float, *, low_open: bool = False,
             high_open: bool = False) -> float:
    """Return ``value`` as a float within [low, high] (ends optionally open) or raise."""
    number = _as_float(name, value)
    below = number <= low if low_open else number < low
    above = number >= high if high_open else number > high
    if below or above:
        left = "(" if low_open else "["
        right = ")" if high_open else "]"
        raise ModelError(f"{name} must be in {left}{low}, {high}{right}, got {value!r}")
    return number


def finite_array(name: str, value: Any, *, ndim: int | None = None) -> np.ndarray:
    """Return ``value`` as a float array with only finite entries or raise :class:`ModelError`."""
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be an array of real numbers, got {value!r}") from None
    if ndim is not None and array.ndim != ndim:
        raise ModelError(f"{name} must have {ndim} dimension(s), got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        bad = array[~np.isfinite(array)].ravel()[0]
        raise ModelError(f"{name} must contain only finite values, found {bad!r}")
    return array


def name(kind: str, value: Any) -> str:
    """Validate an element/signal name: non-empty string without dots or whitespace."""
    if not isinstance(value, str) or not value or any(ch in value for ch in ". \t\n"):
        raise ModelError(f"{kind} name must be a non-empty string without '.' or spaces, got {value!r}")
    return value
