"""Parameter validation helpers: every check names the parameter, the value and what is allowed."""
from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from .errors import ModelError


def _as_float(name: str, value: Any) -> float:
    if isinstance(value, (bool, np.bool_, str, bytes)) or (isinstance(value, np.ndarray) and value.ndim != 0):
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
    """Return ``value`` as a float array with only finite entries or raise :class:`ModelError`.

    Booleans are refused, also inside a (nested) list or tuple and as a boolean array: ``[1.0, True]``
    is not read as ``[1.0, 1.0]``.
    """
    if value is None or isinstance(value, (bool, np.bool_, str, bytes, Mapping)):
        raise ModelError(f"{name} must be an array of real numbers, got {_shown(value)}")
    if _holds_boolean(value):
        raise ModelError(f"{name} must be an array of real numbers (a boolean is not read as 0 or 1), got "
                         f"{_shown(value)}")
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be an array of real numbers, got {_shown(value)}") from None
    if ndim is not None and array.ndim != ndim:
        raise ModelError(f"{name} must have {ndim} dimension(s), got {_shown(value)} (shape {array.shape})")
    if not np.all(np.isfinite(array)):
        bad = array[~np.isfinite(array)].ravel()[0]
        raise ModelError(f"{name} must contain only finite values, found {bad!r}")
    return array


def vector(name: str, value: Any, size: int = 3, *, unit: str = "") -> np.ndarray:
    """Return ``value`` as a 1-D float array of exactly ``size`` finite numbers or raise :class:`ModelError`.

    For points, offsets, loads and gravity given as plain vectors (booleans refused, as in :func:`finite_array`).

    Parameters
    ----------
    name : str
        The parameter as the message names it (e.g. ``"b: center_of_mass"``).
    value : Any
        The value as the user gave it.
    size : int
        Number of components (3 in space, 2 in the plane).
    unit : str
        Unit shown in the message (e.g. ``"m"``, ``"m/s^2"``); empty for none.

    Returns
    -------
    ndarray, shape (size,)
        The components, in the unit of ``value`` (a new array: later changes to ``value`` do not reach it).
    """
    array = finite_array(name, value)
    if array.shape != (size,):
        unit_text = f" [{unit}]" if unit else ""
        raise ModelError(f"{name} must be a {size}-vector ({size} finite numbers){unit_text}, got {_shown(value)} "
                         f"(shape {array.shape})")
    return array.copy()


def unit_vector(name: str, value: Any, size: int = 3) -> np.ndarray:
    """Return the direction ``value`` (``size`` finite numbers, not all zero) normalised to length 1, or raise.

    For joint axes, slide directions and orientation hints, which are given at any length and normalised.

    Parameters
    ----------
    name : str
        The parameter as the message names it (e.g. ``"j: axis"``).
    value : Any
        The direction as the user gave it (any length > 1e-12, dimensionless).
    size : int
        Number of components (3 in space).

    Returns
    -------
    ndarray, shape (size,)
        ``value / |value|``.
    """
    array = vector(name, value, size)
    length = float(np.linalg.norm(array))
    if length < 1e-12:
        raise ModelError(f"{name} must be a non-zero {size}-vector (it is normalised), got {_shown(value)}")
    return array / length


def _holds_boolean(value: Any) -> bool:
    """Whether ``value`` is a boolean or holds one (nested lists and tuples, boolean or object arrays)."""
    if isinstance(value, (bool, np.bool_)):
        return True
    if isinstance(value, np.ndarray):
        return value.dtype == np.bool_ or (value.dtype == object and any(_holds_boolean(item) for item in value.flat))
    if isinstance(value, (list, tuple)):
        return any(_holds_boolean(item) for item in value)
    return False


def name(kind: str, value: Any) -> str:
    """Validate an element/signal name: non-empty string without dots or whitespace."""
    if not isinstance(value, str) or not value or any(ch in value for ch in ". \t\n"):
        raise ModelError(f"{kind} name must be a non-empty string without '.' or spaces, got {value!r}")
    return value


def _shown(value: Any) -> str:
    """``repr`` of a value, shortened for messages."""
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def integer(name: str, value: Any, *, minimum: int = 1) -> int:
    """Return ``value`` as an int >= ``minimum`` (bools and non-integral numbers refused)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ModelError(f"{name} must be an integer >= {minimum}, got {_shown(value)}")
    return int(value)


def option(name: str, value: Any, allowed: Any) -> Any:
    """Return ``value`` if it is one of ``allowed`` (a collection of strings) or raise."""
    choices = sorted(allowed)
    if not isinstance(value, str) or value not in choices:
        raise ModelError(f"{name} must be one of {choices}, got {_shown(value)}")
    return value


def flag(name: str, value: Any, *, optional: bool = False) -> bool | None:
    """Return ``value`` as a bool (``None`` kept when ``optional``) or raise."""
    if value is None and optional:
        return None
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    allowed = "True, False or None" if optional else "True or False"
    raise ModelError(f"{name} must be {allowed}, got {_shown(value)}")


def callable_or_none(name: str, value: Any) -> Any:
    """Return ``value`` if it is callable or ``None``, else raise."""
    if value is not None and not callable(value):
        raise ModelError(f"{name} must be a callable or None, got {_shown(value)}")
    return value


def names(name: str, value: Any, *, allow_empty: bool = False) -> tuple[str, ...]:
    """A name or a sequence of names as a tuple of strings (no mapping, no other container)."""
    if isinstance(value, str):
        return (value,)
    if isinstance(value, (list, tuple)):
        bad = [item for item in value if not isinstance(item, str)]
        if bad:
            raise ModelError(f"{name} must be a name or a sequence of names (str), got {_shown(value)} "
                             f"(not a str: {_shown(bad[0])})")
        if not value and not allow_empty:
            raise ModelError(f"{name} must name at least one signal, got {_shown(value)}")
        return tuple(value)
    raise ModelError(f"{name} must be a name (str) or a list/tuple of names, got {_shown(value)}")


def instances(name: str, value: Any, kind: type) -> tuple:
    """A list or tuple of ``kind`` objects as a tuple (one bare object is refused, naming the wrapping)."""
    if not isinstance(value, (list, tuple)):
        hint = f"; wrap one in a tuple: ({kind.__name__}(...),)" if isinstance(value, kind) else ""
        raise ModelError(f"{name} must be a list or tuple of {kind.__name__} objects, got {_shown(value)}{hint}")
    for item in value:
        if not isinstance(item, kind):
            raise ModelError(f"{name} must be {kind.__name__} objects, got {_shown(item)}")
    return tuple(value)


def number_mapping(name: str, value: Any) -> dict[str, float]:
    """A mapping ``{name: finite number}`` (``None`` means empty) or raise."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ModelError(f"{name} must be a mapping {{element name: number}} or None, got {_shown(value)}")
    out = {}
    for key, item in value.items():
        if not isinstance(key, str):
            raise ModelError(f"{name} keys must be element names (str), got {_shown(key)}")
        out[key] = finite(f"{name}[{key!r}]", item)
    return out


def frequencies(name: str, value: Any, *, scalar: bool = False) -> np.ndarray:
    """Angular frequencies [rad/s]: finite, >= 0, a non-empty 1-D array (or one number if ``scalar``)."""
    if isinstance(value, (bool, np.bool_, str, bytes)) or value is None or isinstance(value, Mapping):
        raise ModelError(f"{name} must be {'a number' if scalar else 'a 1-D array of numbers'} [rad/s] >= 0, "
                         f"got {_shown(value)}")
    if scalar:
        if np.ndim(value) != 0:
            raise ModelError(f"{name} must be one frequency [rad/s] (a number), got {_shown(value)}; "
                             "call once per frequency")
        return np.atleast_1d(nonnegative(name, value))
    array = finite_array(name, value)
    if array.ndim > 1:
        raise ModelError(f"{name} must be a scalar or 1-D array [rad/s], got {_shown(value)} (shape {array.shape})")
    array = np.atleast_1d(array)
    if array.size == 0:
        raise ModelError(f"{name} must contain at least one frequency [rad/s], got {_shown(value)}")
    if np.any(array < 0):
        raise ModelError(f"{name} must be >= 0 [rad/s], got min {float(array.min())!r}")
    return array


def complex_array(name: str, value: Any) -> np.ndarray:
    """Finite complex array (e.g. Laplace variables [1/s]) or raise."""
    if isinstance(value, (bool, np.bool_, str, bytes)) or value is None or isinstance(value, Mapping):
        raise ModelError(f"{name} must be a complex number or array of them, got {_shown(value)}")
    try:
        array = np.asarray(value, dtype=complex)
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be a complex number or array of them, got {_shown(value)}") from None
    if array.size == 0:
        raise ModelError(f"{name} must not be empty, got {_shown(value)}")
    if not np.all(np.isfinite(array)):
        bad = array[~np.isfinite(array)].ravel()[0]
        raise ModelError(f"{name} must contain only finite values, found {complex(bad)!r}")
    return array


MAX_STEPS = 50_000_000
"""Largest number of time steps a simulation accepts (a longer run is refused before it starts)."""

MAX_RESULT_BYTES = 2 * 1024 ** 3
"""Largest estimated size [bytes] of a simulation's stored result (2 GiB)."""


def step_count(t_final: float, t0: float, dt: float, *, bytes_per_step: float = 0.0) -> int:
    """Number of steps ``(t_final - t0) / dt``, refused when too many or too much memory.

    Parameters
    ----------
    t_final, t0 : float
        End and start time [s] (already validated).
    dt : float
        Step size [s] (already validated > 0).
    bytes_per_step : float
        Stored result size per step [bytes]; refused above :data:`MAX_RESULT_BYTES`.
    """
    steps = (t_final - t0) / dt
    if not math.isfinite(steps) or steps > MAX_STEPS:
        raise ModelError(f"dt={dt!r} s over (t_final - t0) = {t_final - t0!r} s gives {steps:.3g} steps; "
                         f"at most {MAX_STEPS:.0e} are allowed: increase dt or shorten the interval")
    memory = steps * bytes_per_step
    if memory > MAX_RESULT_BYTES:
        raise ModelError(f"dt={dt!r} s over (t_final - t0) = {t_final - t0!r} s gives {steps:.3g} steps whose "
                         f"stored result would need about {memory / 1024 ** 3:.3g} GiB (limit "
                         f"{MAX_RESULT_BYTES / 1024 ** 3:.0f} GiB): increase dt or shorten the interval")
    return int(round(steps))


def whole_step_count(t_final: float, dt: float) -> int:
    """Number of fixed steps ``t_final / dt``: a whole number >= 1 (to 1e-9 of ``t_final``), else :class:`ModelError`.

    Parameters
    ----------
    t_final, dt : float
        End time and step [s] (already validated > 0; the run starts at 0).
    """
    steps = int(round(t_final / dt))
    if steps < 1 or abs(steps * dt - t_final) > 1e-9 * t_final:
        raise ModelError(f"t_final = {t_final!r} must be a whole multiple of dt = {dt!r}")
    return steps


def nonempty_array(name: str, value: Any) -> np.ndarray:
    """A non-empty array of finite real numbers (e.g. a sweep of gains) or raise."""
    array = finite_array(name, value)
    if array.size == 0:
        raise ModelError(f"{name} must contain at least one value, got {_shown(value)}")
    return array


def coordinates(name: str, value: Any, size: int, *, labels: Any = None) -> np.ndarray:
    """A 1-D array of exactly ``size`` finite numbers (generalised coordinates, rates) or raise.

    A float64 ndarray of the right shape is returned as is, without the finiteness check: the
    integrators call the instantaneous solvers with their own state arrays every stage, and a
    non-finite state there is theirs to report as a :class:`~ctmm.errors.SimulationError`.
    """
    if isinstance(value, np.ndarray) and value.dtype == np.float64 and value.shape == (size,):
        return value
    array = finite_array(name, value)
    if array.shape != (size,):
        which = f" for coordinates {list(labels)}" if labels is not None else ""
        raise ModelError(f"{name} must be a 1-D array of {size} number(s){which}, got {_shown(value)} "
                         f"(shape {array.shape})")
    return array


def path(name: str, value: Any):
    """A file-system path (str or ``os.PathLike``) as :class:`pathlib.Path`, or raise."""
    import os
    from pathlib import Path

    if isinstance(value, bool) or not isinstance(value, (str, os.PathLike)) or value == "":
        raise ModelError(f"{name} must be a file-system path (str or pathlib.Path), got {_shown(value)}")
    return Path(value)


def indices(name: str, value: Any, count: int) -> list[int]:
    """A sequence of integer indices ``0 <= k < count`` (e.g. mode numbers), or raise."""
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise ModelError(f"{name} must be a sequence of indices (0 to {count - 1}), got {_shown(value)}")
    items = list(value)
    bad = [k for k in items if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k < count]
    if bad:
        raise ModelError(f"{name} must hold indices 0 to {count - 1}, got {bad[0]!r} in {_shown(value)}")
    return [int(k) for k in items]


def weight_rows(name: str, value: Any, n_terms: int) -> np.ndarray:
    """Weights of shape ``(n_terms,)`` or ``(n_sets, n_terms)`` with finite entries, or raise."""
    array = finite_array(name, value)
    if array.ndim not in (1, 2) or array.shape[-1] != n_terms:
        raise ModelError(f"{name} must have shape (n_terms,) or (n_sets, n_terms) with n_terms = {n_terms} (the "
                         f"sensor terms of the loop), got shape {array.shape}: {_shown(value)}")
    return array


def one_mode_limit(n_modes: Any, omega_max: Any) -> None:
    """Refuse unless exactly one of ``n_modes`` and ``omega_max`` is given (mode selection of the
    frequency verbs)."""
    if (n_modes is None) == (omega_max is None):
        raise ModelError("give exactly one of n_modes (int >= 1) or omega_max (rad/s > 0)")


def selected_modes(omega: np.ndarray, n_modes: Any, omega_max: Any, owner: str) -> np.ndarray:
    """Indices of the ascending natural frequencies ``omega`` [rad/s] to keep: the first ``n_modes``
    (refused when there are fewer; ``owner`` says what they belong to) or those below ``omega_max``."""
    if n_modes is not None:
        n_modes = integer("n_modes", n_modes, minimum=1)
        if n_modes > omega.size:
            raise ModelError(f"{owner} has {omega.size} natural frequencies, n_modes={n_modes} requested")
        return np.arange(n_modes)
    return np.flatnonzero(omega < positive("omega_max", omega_max))


def step_budget(t_final: Any, t0: Any, dt: Any) -> None:
    """Refuse, before any work, a run whose step or output grid ``dt`` has more than :data:`MAX_STEPS`
    points over ``[t0, t_final]`` (:func:`step_count`); :func:`ctmm.simulate` calls it on every path
    (chains, planar, spatial, generated kernels, ``solve_ivp`` output grids).  Values that are not finite
    positive numbers are left to each path's own validation, which names the parameter.

    Parameters
    ----------
    t_final, t0 : Any
        End and start time [s], as the user gave them.
    dt : Any
        Step or output grid spacing [s], as the user gave it (``None``: nothing to check).
    """
    values = (t_final, t0, dt)
    if not all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))
               for v in values):
        return
    if not all(math.isfinite(float(v)) for v in values) or float(dt) <= 0.0 or float(t_final) <= float(t0):
        return
    step_count(float(t_final), float(t0), float(dt))
