"""Parameter values at which a characteristic root lies on the line ``Re s = sigma``.

``Delta`` is affine in one loop parameter ``p`` (a gain factor or a sensor weight; eq. (1) of
:mod:`ctmm.sweeps`), ``Delta = B + p A``, so for each sample ``s = sigma + i omega`` of the
counting line there is one ``p`` making ``Delta`` real-aligned, and a root lies on the line where
``Im(B conj A)`` changes sign.  Used by the stability charts (one row per value of the other
parameter) and by the gain margin.  Methods: ``docs/stability.md`` section 5.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .counting_contour import Contour
from .roots1d import refine_sign_change
from .sweeps import TINY, LoopCharacteristic

__all__ = ["Crossings", "row_crossings", "bracket_solve", "combine_pointwise", "delay_intervals"]


# --------------------------------------------------------------------------------------------
# crossings along a linear parameter (one "row" of a chart, or the gain of a margin)
# --------------------------------------------------------------------------------------------
@dataclass
class Crossings:
    """Parameter values at which a root lies on the line ``Re s = sigma``, per row.

    Attributes
    ----------
    row : numpy.ndarray of int
        Row index of each crossing.
    value : numpy.ndarray
        Value of the linear parameter ``p`` at the crossing.
    omega : numpy.ndarray
        Imaginary part of the root on the line [rad/s] (0: a real root, ``static``).
    error : numpy.ndarray
        Bound on the error of ``value`` (bracket width; ~1e-13 relative once refined).
    static : numpy.ndarray of bool
        Real root (one root crosses) rather than a conjugate pair.
    direction : numpy.ndarray of int
        +1 when the root(s) move to the right as ``p`` increases, -1 to the left, 0 unknown:
        the number of roots right of the line jumps by ``direction * (1 if static else 2)``.
    """

    row: np.ndarray
    value: np.ndarray
    omega: np.ndarray
    error: np.ndarray
    static: np.ndarray
    direction: np.ndarray

    _FIELDS = ("row", "value", "omega", "error", "static", "direction")

    def for_row(self, r: int) -> "Crossings":
        keep = self.row == r
        return Crossings(*(getattr(self, f)[keep] for f in self._FIELDS))

    @property
    def jump(self) -> np.ndarray:
        """Change of the root count across each crossing (increasing ``p``)."""
        return self.direction * np.where(self.static, 1, 2)


def combine_pointwise(s: np.ndarray, base: np.ndarray, terms: np.ndarray, gain: np.ndarray,
                      delay: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Eq. (1) with one parameter set per ``s`` (all arrays of length n; weights (n, n_terms))."""
    with np.errstate(over="ignore", invalid="ignore"):
        return base + gain * np.exp(-delay * s) * np.einsum("nt,tn->n", weights, terms)


def _row_coefficients(s, base, terms, sets0, sets1):
    """``B`` (p = 0) and ``A`` (coefficient of p) for rows: arrays (n_rows, n_s)."""
    d0 = LoopCharacteristic.combine(s, base, terms, *sets0)
    d1 = LoopCharacteristic.combine(s, base, terms, *sets1)
    return d0, d1 - d0


def row_crossings(contour: Contour, sets0, sets1, p_range: tuple[float, float], *,
                  grid: np.ndarray | None = None, refine_all: bool = False) -> Crossings:
    """Values of a linear parameter ``p`` at which ``Delta(sigma + i omega; p) = 0``, per row.

    ``sets0``/``sets1`` are the parameter sets of each row at ``p = 0`` and ``p = 1`` (Delta is
    affine in ``p``: ``B + p A``).  A crossing at ``omega > 0`` is a sign change of
    ``Im(B conj A)`` between samples of the line, refined by the Illinois method on the TMM values
    when a ``grid`` value lies inside its bracket (or always with ``refine_all``); the static
    crossing is ``p = -B/A`` at ``s = sigma``.
    """
    line = contour.line
    s = line.s
    B, A = _row_coefficients(s, line.base, line.terms, sets0, sets1)
    phi = np.imag(B * np.conj(A))
    with np.errstate(all="ignore"):
        p_at = -np.real(B * np.conj(A)) / np.abs(A) ** 2
    lo, hi = p_range
    span = max(hi - lo, 1e-300)
    keep_lo, keep_hi = lo - 1e-6 * span, hi + 1e-6 * span
    # static crossing (s = sigma real): direction from ds/dp = -A / Delta_s, with
    # Delta_s = Im Delta(sigma + i eps) / eps (Delta(sigma) = 0 there; the scale is positive)
    p0 = p_at[:, 0]
    ok = np.isfinite(p0) & (np.abs(A[:, 0]) > TINY) & (p0 >= keep_lo) & (p0 <= keep_hi)
    r_static = np.flatnonzero(ok)
    d_static = np.zeros(r_static.size, int)
    if r_static.size:
        eps = 1e-7 * max(contour.radius, 1.0)
        s_eps = np.full(r_static.size, contour.sigma + 1j * eps)
        base_e, terms_e = contour.model.components(s_eps)
        k0, tau0, w0 = (x[r_static] for x in sets0)
        k1, tau1, w1 = (x[r_static] for x in sets1)
        d0 = combine_pointwise(s_eps, base_e, terms_e, k0, tau0, w0)
        d1 = combine_pointwise(s_eps, base_e, terms_e, k1, tau1, w1)
        at_eps = d0 + p0[r_static] * (d1 - d0)
        slope = np.imag(at_eps)
        simple = np.abs(slope) > 1e-3 * np.abs(at_eps)     # else a multiple root: direction unknown
        d_static = np.where(simple, -np.sign(A[r_static, 0].real) * np.sign(slope), 0).astype(int)
    rows, values, omegas = list(r_static), list(p0[r_static]), [0.0] * r_static.size
    errors, statics, directions = [0.0] * r_static.size, [True] * r_static.size, list(d_static)
    # oscillatory crossings: sign changes of phi on intervals j >= 1
    sign = np.sign(phi[:, 1:])
    change = (sign[:, :-1] * sign[:, 1:] < 0)
    r_idx, j_idx = np.nonzero(change)
    j_idx = j_idx + 1                                        # interval [j, j+1] of the line
    pa, pb = p_at[r_idx, j_idx], p_at[r_idx, j_idx + 1]
    fa, fb = phi[r_idx, j_idx], phi[r_idx, j_idx + 1]
    t = fa / (fa - fb)
    p_est = pa + t * (pb - pa)
    width = np.abs(pb - pa)
    finite = np.isfinite(p_est) & np.isfinite(width)
    inside = finite & (p_est + width >= keep_lo) & (p_est - width <= keep_hi)
    r_idx, j_idx, p_est, width = r_idx[inside], j_idx[inside], p_est[inside], width[inside]
    # every bracket is refined: the parameter values at its ends enclose the crossing value only
    # where p is monotone on it, which a zero of A (an anti-resonance) inside the bracket breaks
    # (a benchmark chart cell was misclassified that way); with a grid, refinement stops once the
    # bracket is narrow and its ends enclose no grid value
    todo = np.ones(r_idx.size, bool)
    ta = t[inside]
    direction = np.sign(fa[inside]).astype(int)        # Re ds/dp has the sign of -d(phi)/d(omega)
    omega = s.imag[j_idx] + ta * (s.imag[j_idx + 1] - s.imag[j_idx])
    value, error = 0.5 * (pa + pb)[inside], 0.5 * width             # bracket of the value
    if todo.any():
        r, j = r_idx[todo], j_idx[todo]
        w_ref, v_ref, e_ref = _refine_crossings(contour, sets0, sets1, r, s.imag[j], s.imag[j + 1],
                                                phi[r, j], phi[r, j + 1], p_at[r, j], p_at[r, j + 1],
                                                grid=None if refine_all or grid is None else np.sort(grid),
                                                span=span)
        omega[todo], value[todo], error[todo] = w_ref, v_ref, e_ref
    good = np.isfinite(value) & (value >= keep_lo) & (value <= keep_hi)
    row = np.concatenate([np.asarray(rows, int), r_idx[good].astype(int)])
    value = np.concatenate([np.asarray(values, float), value[good]])
    omega = np.concatenate([np.asarray(omegas, float), omega[good]])
    error = np.concatenate([np.asarray(errors, float), error[good]])
    static = np.concatenate([np.asarray(statics, bool), np.zeros(int(good.sum()), bool)])
    direction = np.concatenate([np.asarray(directions, int), direction[good]])
    order = np.lexsort((value, row))
    return Crossings(row[order], value[order], omega[order], error[order], static[order],
                     direction[order])


def _undecided(grid: np.ndarray, low: np.ndarray, high: np.ndarray, span: float) -> np.ndarray:
    """Brackets [low, high] of a crossing value that still contain a grid value."""
    pad = 1e-10 * span
    left = np.searchsorted(grid, low - pad, side="left")
    right = np.searchsorted(grid, high + pad, side="right")
    return right > left


def _refine_crossings(contour: Contour, sets0, sets1, rows, a, b, fa, fb, pa, pb, *, grid=None,
                      span: float = 1.0):
    """Refine brackets [a, b] of sign changes of Im(B conj A) (one per crossing, batched).

    With ``grid``, a bracket stops as soon as the parameter values at its ends enclose no grid
    value (the side of every grid point is then decided)."""
    model, sigma = contour.model, contour.sigma
    k0, tau0, w0 = (x[rows] for x in sets0)
    k1, tau1, w1 = (x[rows] for x in sets1)

    def evaluate(idx, omega):
        s = sigma + 1j * omega
        base, terms = model.components(s)
        d0 = combine_pointwise(s, base, terms, k0[idx], tau0[idx], w0[idx])
        d1 = combine_pointwise(s, base, terms, k1[idx], tau1[idx], w1[idx])
        A = d1 - d0
        with np.errstate(all="ignore"):
            return np.imag(d0 * np.conj(A)), -np.real(d0 * np.conj(A)) / np.abs(A) ** 2

    def decided(idx, pa_, pb_):
        ends = np.isfinite(pa_) & np.isfinite(pb_)
        return ends & ~_undecided(grid, np.minimum(pa_, pb_), np.maximum(pa_, pb_), span)

    omega, pa, pb = bracket_solve(evaluate, a, b, fa, fb, pa, pb, stop=None if grid is None else decided)
    value = np.where(np.isfinite(pa) & np.isfinite(pb), 0.5 * (pa + pb), pb)
    error = np.where(np.isfinite(pa) & np.isfinite(pb), 0.5 * np.abs(pa - pb), 0.0)
    return omega, value, error


def bracket_solve(evaluate, a, b, fa, fb, pa, pb, *, stop=None, rtol: float = 4e-16):
    """Refine brackets ``[a, b]`` (``0 < a < b``, frequencies [rad/s]) of sign changes, batched.

    The refiner is :func:`ctmm.roots1d.refine_sign_change` (Illinois with a bisection safeguard);
    ``evaluate(idx, x) -> (f, p)`` gives the function and a tracked quantity ``p`` at points ``x``
    of the brackets ``idx`` (one call per step for all brackets); ``stop(idx, pa, pb)`` may end
    brackets early, once they are narrower than 1e-6 relative.  A bracket otherwise stops at
    ``b - a <= rtol b`` (or 4 ulp).  Returns the last trial point of every bracket and ``p``
    at both bracket ends (``fa fb`` not negative: the bracket is not refined, its ``b``)."""
    lo, up = np.array(a, dtype=float), np.array(b, dtype=float)
    pa, pb = np.array(pa, dtype=float), np.array(pb, dtype=float)
    last = up.copy()

    def function(x, idx):
        last[idx] = x
        return evaluate(idx, x)

    def narrow_and_decided(idx):
        # the tracked values at the bracket ends enclose the crossing value only where p is
        # monotone on the bracket: stop early only once the bracket is narrow (a wide
        # bracket across a resonance misplaced a chart crossing by 0.013 in gain)
        narrow = up[idx] - lo[idx] <= 1e-6 * np.maximum(1.0, up[idx])
        return narrow & stop(idx, pa[idx], pb[idx])

    refine_sign_change(function, lo, up, fa, fb, rtol, tracked=(pa, pb),
                       stop=None if stop is None else narrow_and_decided)
    return last, pa, pb


# --------------------------------------------------------------------------------------------
# stable delay intervals from the crossings along the delay
# --------------------------------------------------------------------------------------------
def delay_intervals(taus: list[float], directions: list[int], n0: int, limit: float,
                    count_at: Callable[[np.ndarray], np.ndarray]) -> tuple[list[tuple[float, float]], str | None]:
    """Stable delay intervals in ``[0, limit]`` [s] from the count ``n0`` at zero delay and the
    crossings (delays ``taus`` [s], ascending, and ``directions`` +1 / -1, one pair each).

    A crossing that would take the count below zero proves that roots enter or leave the counted
    region through its far edges (a neutral loop, or an ``im_max`` below the proven height): the
    running count is then meaningless, and each interval between crossings is counted directly by
    ``count_at(delays) -> counts`` at its midpoint instead.  Returns the intervals and, in that
    case, a note for the certificate (else ``None``)."""
    running, intervals, start, consistent = n0, [], 0.0 if n0 == 0 else None, True
    for t_c, d in zip(taus, directions):
        new = running + 2 * d
        consistent = consistent and new >= 0
        if running == 0 and new > 0 and start is not None:
            intervals.append((start, t_c))
            start = None
        if new == 0 and running > 0:
            start = t_c
        running = new
    if start is not None:
        intervals.append((start, limit))
    if consistent or n0 < 0:
        return intervals, None
    edges = np.unique(np.clip(np.concatenate([[0.0], taus, [limit]]), 0.0, limit))
    counts = count_at(0.5 * (edges[:-1] + edges[1:]))
    intervals = []
    for lo, hi, n in zip(edges[:-1], edges[1:], counts):
        if n == 0:
            intervals.append((intervals.pop()[0], hi) if intervals and intervals[-1][1] == lo else (lo, hi))
    note = (f"a crossing at delay {taus[int(np.argmax(n0 + 2 * np.cumsum(directions) < 0))]:.6g} s moves roots out of "
            f"Re s > 0 that the counted region does not hold (roots enter through its far edges: a neutral loop or "
            "an im_max below the proven height); the stable intervals are direct counts at the midpoints between "
            "crossings, not the running count")
    return intervals, note
