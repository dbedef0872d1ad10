"""One bracketing real-axis root refiner, batched over brackets.

Two questions about a real variable ``x`` (a frequency [rad/s], a gain, ...) are answered here
for many brackets at once, each function evaluation taking all active brackets in one call:

* :func:`count_upper_bound` -- a power of two above the ``k``-th root of a counting function
  (the upper end of the first bracket);
* :func:`bisect_count` -- the ``k``-th root of a *counting* function (the number of roots
  below ``x``, e.g. Wittrick-Williams): ``root_k = inf{x : count(x) >= k}``, by bisection;
  clustered and repeated roots are handled exactly because only counts are compared.
* :func:`refine_sign_change` -- a simple root of a continuous *sign* function inside a bracket
  whose end values have opposite signs: Illinois (regula falsi, halving an end value retained
  twice) with a bisection step whenever three steps have not halved the bracket, and a
  Brent-style minimal step so a converged end closes the bracket; optionally it carries a
  tracked quantity along with the bracket ends and lets the caller end brackets early.

Both work in place on the bracket arrays ``lo``, ``up`` and stop at ``up - lo <= rtol up``.
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from .errors import ModelError

__all__ = ["count_upper_bound", "bisect_count", "refine_sign_change"]


def _check_rtol(rtol: float) -> float:
    if not (np.isfinite(rtol) and rtol > 0.0):
        raise ModelError(f"rtol must be a finite relative bracket width > 0, got {rtol!r}")
    return float(rtol)


def count_upper_bound(count: Callable[[np.ndarray], np.ndarray], target: int, *, limit: float, what: str) -> float:
    """Smallest ``x = 2^m`` (``m >= 0``) with ``count(x) >= target``, by doubling from 1.

    Parameters
    ----------
    count : callable
        ``count(x)`` -> integer array: number of roots below each ``x`` (units of ``x``).
    target : int
        Number of roots the bound must lie above, >= 1.
    limit : float
        Largest ``x`` tried (units of ``x``); beyond it the roots are taken not to exist.
    what : str
        The system named in the error, e.g. ``"chain 'rod'"``.

    Raises
    ------
    ModelError
        ``"<what> has fewer than <target> natural frequencies"`` when ``count`` stays below
        ``target`` up to ``limit``.
    """
    x = 1.0
    while count(np.array([x]))[0] < target:
        x *= 2.0
        if x > limit:
            raise ModelError(f"{what} has fewer than {target} natural frequencies")
    return x


def bisect_count(count: Callable[[np.ndarray], np.ndarray], targets, lo: np.ndarray, up: np.ndarray,
                 c_lo: np.ndarray, c_up: np.ndarray, rtol: float, which=None, *, isolate: bool = False,
                 max_iterations: int | None = None) -> None:
    """Bisection on a counting function for the brackets ``which`` (in place).

    Bracket ``i`` holds the ``targets[i]``-th root: ``count(lo[i]) < targets[i] <= count(up[i])``.
    Each round evaluates ``count`` once at the midpoints of all active brackets and keeps the half
    that still holds the root.  A bracket stops when ``up - lo <= rtol up``, or (``isolate``)
    as soon as it holds exactly one root (``c_up - c_lo == 1``).

    Parameters
    ----------
    count : callable
        ``count(x)`` -> integer array: number of roots below each ``x`` (units of ``x``).
    targets : array_like of int
        Root index sought in each bracket (1 = lowest root).
    lo, up : ndarray of float
        Bracket ends (units of ``x``), updated in place.
    c_lo, c_up : ndarray of int
        ``count`` at ``lo`` and ``up``, updated in place.
    rtol : float
        Relative bracket width at which bisection stops, > 0.
    which : array_like of int, optional
        Brackets to work on (default all).
    isolate : bool
        Stop a bracket once it holds a single root.
    max_iterations : int, optional
        Largest number of rounds (default: until every bracket stops; a bracket whose root is 0
        with ``lo = 0`` only stops at underflow, so pass a bound there).
    """
    rtol = _check_rtol(rtol)
    targets = np.asarray(targets)
    idx = np.arange(lo.size) if which is None else np.asarray(which, dtype=int)
    rounds = 0
    while idx.size and (max_iterations is None or rounds < max_iterations):
        active = up[idx] - lo[idx] > rtol * up[idx]
        if isolate:
            active &= c_up[idx] - c_lo[idx] > 1
        idx = idx[active]
        if not idx.size:
            break
        mid = 0.5 * (lo[idx] + up[idx])
        c = count(mid)
        below = c >= targets[idx]
        up[idx[below]], c_up[idx[below]] = mid[below], c[below]
        lo[idx[~below]], c_lo[idx[~below]] = mid[~below], c[~below]
        rounds += 1


def refine_sign_change(function: Callable[[np.ndarray, np.ndarray], Any], lo: np.ndarray, up: np.ndarray,
                       f_lo: np.ndarray, f_up: np.ndarray, rtol: float, *,
                       tracked: tuple[np.ndarray, np.ndarray] | None = None,
                       stop: Callable[[np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Refine a sign change of ``function`` in every bracket ``[lo[i], up[i]]`` (in place).

    Illinois steps (the secant through the bracket ends, an end value retained twice in a row
    is halved), a bisection step when three steps have not halved the bracket or the secant is
    not finite, every trial point at least ``max(0.4 rtol up, 2 ulp)`` inside the bracket.  A
    bracket stops when ``up - lo <= rtol up`` (or 4 ulp), or at an exact zero (``lo = up``).

    Parameters
    ----------
    function : callable
        ``function(x, active)`` -> real values at the trial points ``x`` of the brackets
        ``active`` (indices into ``lo``; lets the caller keep per-bracket data such as a scaling).
    lo, up : ndarray of float
        Bracket ends (units of ``x``), ``0 < lo < up``, updated in place.
    f_lo, f_up : ndarray of float
        ``function`` at ``lo`` and ``up``.
    rtol : float
        Relative bracket width at which a bracket stops, > 0.
    tracked : (ndarray, ndarray), optional
        Values of a quantity carried along with ``x`` (e.g. the parameter value at which a root
        lies on the counting line) at ``lo`` and ``up``, updated in place with the ends; then
        ``function`` returns the pair ``(f, tracked value)`` at the trial points.
    stop : callable, optional
        ``stop(active)`` -> bool per bracket of ``active``, asked after every step (with
        ``lo``, ``up`` and ``tracked`` already updated): ``True`` ends that bracket early.

    Returns
    -------
    ndarray of bool
        Which brackets had end values of strictly opposite signs and were refined; the others
        are left unchanged (the caller decides: another method, or an error).
    """
    rtol = _check_rtol(rtol)
    f_lo, f_up = np.asarray(f_lo, dtype=float), np.asarray(f_up, dtype=float)
    good = np.sign(f_lo) * np.sign(f_up) < 0       # signs, not the product: no under- or overflow
    idx = np.flatnonzero(good)
    f_lo, f_up = f_lo[good], f_up[good]
    width = up[idx] - lo[idx]             # bracket width when the stall counter was last reset
    stall = np.zeros(idx.size, dtype=int)
    last = np.zeros(idx.size, dtype=int)   # end moved in the previous step: -1 lo, +1 up
    while idx.size:
        a, b = lo[idx], up[idx]
        with np.errstate(divide="ignore", invalid="ignore"):
            x = b - f_up * (b - a) / (f_up - f_lo)
        x = np.where((stall >= 3) | ~np.isfinite(x), 0.5 * (a + b), x)
        step_min = np.maximum(0.4 * rtol * b, 2 * np.spacing(b))   # Brent-style minimal step:
        x = np.clip(x, a + step_min, b - step_min)                # a converged end closes the bracket
        if tracked is None:
            f_x = np.asarray(function(x, idx), dtype=float)
        else:
            f_x, t_x = function(x, idx)
            f_x, t_x = np.asarray(f_x, dtype=float), np.asarray(t_x, dtype=float)
        left = np.sign(f_x) == np.sign(f_lo)       # the root is in (x, up)
        zero = f_x == 0
        f_up = np.where(left & (last == -1), 0.5 * f_up, f_up)
        f_lo = np.where(~left & (last == 1), 0.5 * f_lo, f_lo)
        lo[idx[left]], f_lo = x[left], np.where(left, f_x, f_lo)
        up[idx[~left]], f_up = x[~left], np.where(~left, f_x, f_up)
        lo[idx[zero]] = up[idx[zero]] = x[zero]
        if tracked is not None:
            tracked[0][idx[left | zero]] = t_x[left | zero]
            tracked[1][idx[~left | zero]] = t_x[~left | zero]
        last = np.where(left, -1, 1)
        gap = up[idx] - lo[idx]
        halved = gap <= 0.5 * width
        width, stall = np.where(halved, gap, width), np.where(halved, 0, stall + 1)
        keep = (gap > rtol * up[idx]) & (gap > 4 * np.spacing(up[idx]))
        if stop is not None and keep.any():
            keep[keep] = ~np.asarray(stop(idx[keep]), dtype=bool)
        idx, f_lo, f_up = idx[keep], f_lo[keep], f_up[keep]
        width, stall, last = width[keep], stall[keep], last[keep]
    return good
