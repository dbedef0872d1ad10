"""Eigenvalue counts that cannot be fooled by substructure resonances.

Every natural-frequency solver in ctmm (1-D chains, exact beams, planar chains and trees)
counts the natural frequencies below a trial frequency ``omega`` [rad/s] by the signs of the
pivots of a Gaussian elimination of the dynamic stiffness ``K - omega^2 M`` (Sylvester's law
of inertia; Wittrick-Williams).  Each pivot is the dynamic stiffness of a *substructure* (for
a planar chain: everything outboard of a hinge, pinned there); it vanishes exactly when
``omega`` is a natural frequency of that substructure.  There the elimination divides by zero,
and a count taken from ``inf``/``nan`` (or from a pivot that round-off left within a few ulps of
zero) is wrong -- a 2-link arm whose outer link resonates at exactly 10 rad/s on its hinge had
its first natural frequency reported as 10.0 instead of 8.113 rad/s.

:func:`certified_count` evaluates the count together with a *pivot margin* (smallest
``|pivot| / scale`` met, ``nan`` when a pivot or intermediate is non-finite).  Where the margin
is below ``tolerance`` the count is not trusted; it is taken instead at ``omega (1 - eta)`` and
``omega (1 + eta)`` (``eta`` from 1e-7, growing tenfold until both margins are safe):

* both counts equal: no natural frequency lies in between, so the common value is the exact
  count at ``omega`` (certified);
* counts differ by one and a ``side`` test is given (the sign of a characteristic
  determinant that has no poles: the orthonormal transfer of :mod:`ctmm.natural`, the product of
  the planar pivots): the single natural frequency in the window is placed on its side of
  ``omega`` (the planar test compares at ``omega (1 - 1e-12)``, so a frequency within 1e-12
  relative below ``omega`` counts as above it);
* otherwise (no ``side`` test, or several frequencies in the window): a natural frequency of
  the whole model lies within ``eta omega`` of the substructure resonance and the count below
  ``omega (1 - eta)`` is returned, so a bisection on the count places that frequency to
  within ``eta`` relative (never a lost or duplicated mode).
"""
from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["certified_count", "pivot_margin", "relative_singularity", "PIVOT_TOLERANCE", "OFFSETS"]

#: Smallest trusted relative pivot ``|pivot| / scale`` [-].
PIVOT_TOLERANCE = 1e-10
#: Relative frequency offsets tried, in order, around an untrusted trial frequency [-].
OFFSETS = (1e-7, 1e-6, 1e-5, 1e-4)


def certified_count(evaluate: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], omega: np.ndarray, *,
                    tolerance: float = PIVOT_TOLERANCE,
                    side: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> np.ndarray:
    """Number of natural frequencies strictly below each ``omega``, safe at substructure resonances.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(omega) -> (count, margin)``: the raw Sylvester count (int array) and the
        smallest relative pivot met (float array, ``nan`` when the elimination produced a
        non-finite value), both of the shape of ``omega``.
    omega : ndarray
        Trial frequencies [rad/s], finite and ``>= 0``, 1-D.
    tolerance : float
        Smallest relative pivot that is trusted [-].
    side : callable, optional
        ``side(lower, omega) -> bool array``: True where the single natural frequency known to
        lie in ``(lower, upper)`` is below ``omega`` (both arrays of trial frequencies).

    Returns
    -------
    ndarray of int
        Counts, shape of ``omega`` (module docstring for the guarantee).
    """
    omega = np.asarray(omega, dtype=float)
    count, margin = evaluate(omega)
    count = np.array(count, dtype=np.int64, copy=True)
    todo = np.flatnonzero(~(np.asarray(margin) > tolerance))
    for eta in OFFSETS:
        if not todo.size:
            break
        w = omega[todo]
        below, margin_below = evaluate(w * (1.0 - eta))
        above, margin_above = evaluate(w * (1.0 + eta))
        safe = (np.asarray(margin_below) > tolerance) & (np.asarray(margin_above) > tolerance)
        last = eta == OFFSETS[-1]
        take = safe | last
        below, above = np.asarray(below), np.asarray(above)
        chosen = below.copy()
        single = take & (above - below == 1)
        if side is not None and np.any(single):
            chosen[single] = np.where(side(w[single] * (1.0 - eta), w[single]), above[single], below[single])
        count[todo[take]] = chosen[take]
        todo = todo[~take]
    return count


def pivot_margin(pivot: np.ndarray, *terms: np.ndarray) -> np.ndarray:
    """Smallest ``|eigenvalue|`` of the symmetric part of ``pivot`` relative to the size of the
    ``terms`` it is the sum of (``nan`` if non-finite), batched."""
    if pivot.shape[-1] == 0:
        return np.full(pivot.shape[:-2], np.inf)
    finite = np.all(np.isfinite(pivot), axis=(-2, -1))
    sym = np.where(finite[..., None, None], 0.5 * (pivot + np.swapaxes(pivot, -1, -2)), 0.0)
    if sym.shape[-1] == 1:
        smallest = np.abs(sym[..., 0, 0])
    elif sym.shape[-1] == 2:      # closed form: mean -+ radius
        a, c, b = sym[..., 0, 0], sym[..., 1, 1], sym[..., 0, 1]
        smallest = np.abs(np.abs(0.5 * (a + c)) - np.hypot(0.5 * (a - c), b))
    else:
        smallest = np.min(np.abs(np.linalg.eigvalsh(sym)), axis=-1)
    scale = sum(np.abs(term).max(axis=(-2, -1)) for term in terms)
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
    return np.where(finite, smallest / scale, np.nan)


def relative_singularity(U12: np.ndarray) -> np.ndarray:
    """Smallest over largest singular value of the row- and column-equilibrated ``U12`` (batched):
    zero at the field's clamped-clamped frequencies."""
    A = np.where(np.isfinite(U12), U12, 0.0)
    row = np.abs(A).max(axis=-1, keepdims=True)
    A = A / np.where(row > 0, row, 1.0)
    col = np.abs(A).max(axis=-2, keepdims=True)
    A = A / np.where(col > 0, col, 1.0)
    if A.shape[-1] == 2 and A.shape[-2] == 2:     # closed form: s_min s_max = |det|, s_min^2 + s_max^2 = |A|_F^2
        det = np.abs(A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0])
        frobenius = np.sum(A * A, axis=(-2, -1))
        largest2 = 0.5 * (frobenius + np.sqrt(np.maximum(frobenius ** 2 - 4 * det ** 2, 0.0)))
        ratio = det / np.where(largest2 > 0, largest2, 1.0)
    else:
        sv = np.linalg.svd(A, compute_uv=False)
        ratio = sv[..., -1] / np.where(sv[..., 0] > 0, sv[..., 0], 1.0)
    return np.where(np.all(np.isfinite(U12), axis=(-2, -1)), ratio, np.nan)
