"""Roots of analytic characteristic functions in rectangles of the complex plane.

Generic machinery for delay-stability studies: it only needs a *vectorised* callable
``char_fn(s) -> Delta(s)`` (complex array in, same-shape complex array out) that is analytic in
the search rectangle, such as det of a transfer-matrix boundary block with exact delays
e^(-s tau).  Three layers:

* :func:`count_roots_in_rectangle`: argument principle on the rectangle boundary with adaptive
  sampling (the complex-log step log(Delta(s_j+1)/Delta(s_j)) between neighbouring samples is
  kept below ``max_log_step``), verified by a uniform refinement that must leave the count
  unchanged;
* :func:`find_roots_in_rectangle`: bisection of the rectangle driven by counts, with Newton's
  method (derivative from ``derivative`` or from a Cauchy integral on a small circle) started
  from the contour estimate of the enclosed root; every rectangle is resolved when the roots
  found in it account for its count, so each root is reported once with its multiplicity;
* :func:`rightmost_roots` and :func:`spectral_abscissa` for stability studies.

All evaluations of ``char_fn`` are batched: every refinement round of every contour, and every
Newton iteration of every active root, is one call.  ``s`` is the Laplace variable [1/s]
(imaginary part in [rad/s]); methods, guarantees and limits are in docs/characteristic_roots.md.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import ModelError
from .validation import finite, positive

from .contour import (CIRCLE_POINTS, SPLIT_FRACTIONS, UNIT_CIRCLE, CharacteristicFunction, ContourError, RootCount,  # noqa: F401
                      BudgetExceeded, RectangleContour, ContourEvaluator, evaluation_budget, rectangle_corners, count_contours, rectangle_diagonal,
                      inside_rectangle, log_step_option, as_rectangle, count_roots_in_rectangle)

__all__ = ["ContourError", "RootCount", "RootSet", "SpectralAbscissa",
           "count_roots_in_rectangle", "find_roots_in_rectangle", "rightmost_roots",
           "spectral_abscissa"]

@dataclass(frozen=True)
class RootSet:
    """Roots found in a region, each listed once with its multiplicity.

    Attributes
    ----------
    roots : numpy.ndarray of complex
        Distinct roots [1/s] sorted by decreasing real part (ties: increasing imaginary part).
    multiplicities : numpy.ndarray of int
        Multiplicity of each root (roots closer than ``cluster_size`` are reported as one).
    error_estimates : numpy.ndarray of float
        A-posteriori error estimate per root [1/s]: max(last Newton step, (sigma/|a_m|)^(1/m),
        (|Delta(z)|/|a_m|)^(1/m) if m > 1), with a_m = Delta^(m)(z)/m! and sigma the measured
        evaluation noise of Delta: how far noise (or an unresolved cluster) can move the root.
    count : int
        Roots in the region by the argument principle (with multiplicity).
    reliable : bool
        True when every count was verified and sum(multiplicities) == count.
    n_calls : int
        Calls of the characteristic function.
    n_evaluations : int
        Points at which it was evaluated.
    notes : tuple of str
        Diagnostics (unresolved rectangles, heuristics used).
    certificate : ContourCertificate or None
        For a controlled chain with one loop (:func:`ctmm.stability.characteristic_roots`):
        whether no root with ``Re s > re_min`` lies outside ``|Im s| <= im_max``
        (:mod:`ctmm.certification`); None otherwise.
    """

    roots: np.ndarray
    multiplicities: np.ndarray
    error_estimates: np.ndarray
    count: int
    reliable: bool
    n_calls: int
    n_evaluations: int
    notes: tuple[str, ...] = ()
    certificate: Any = None

    def __len__(self) -> int:
        return int(self.roots.size)

    def expanded(self) -> np.ndarray:
        """All roots repeated according to multiplicity [1/s]."""
        return np.repeat(self.roots, self.multiplicities)

    def plot(self, ax=None):
        """Scatter the roots in the complex plane (multiple roots annotated); returns the axes."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots()
        ax.plot(self.roots.real, self.roots.imag, "x", label=f"{self.count} roots")
        for z, m in zip(self.roots, self.multiplicities):
            if m > 1:
                ax.annotate(f"x{m}", (z.real, z.imag))
        ax.axvline(0.0, color="0.6", linewidth=0.8)
        ax.set_xlabel("Re s [1/s]")
        ax.set_ylabel("Im s [rad/s]")
        ax.legend()
        return ax


@dataclass(frozen=True)
class SpectralAbscissa:
    """Largest real part of the characteristic roots in the searched region.

    Attributes
    ----------
    value : float
        max Re(s) over the roots [1/s]; equals ``re_min`` when no root has Re s > re_min
        (then ``below_re_min`` is True and ``value`` is only an upper bound).
    error : float
        Error bound of ``value`` [1/s] (the root's error estimate; 0 when ``below_re_min``).
    root : complex or None
        The rightmost root (the one with Im >= 0 of a conjugate pair).
    below_re_min : bool
        No root was found to the right of ``re_min``.
    roots : RootSet
        All roots found in the region.
    certificate : ContourCertificate or None
        As for :class:`RootSet`: whether the region holds every root right of ``re_min``.
    """

    value: float
    error: float
    root: complex | None
    below_re_min: bool
    roots: RootSet
    certificate: Any = None

    @property
    def stable(self) -> bool:
        """Every root of the region lies in Re s < 0 (value + error < 0, or no root right of a
        re_min <= 0), with a reliable search."""
        inside = self.value + self.error < 0.0 or (self.below_re_min and self.value <= 0.0)
        return bool(inside and self.roots.reliable)


# --------------------------------------------------------------------------------------------
# Newton's method, many roots at once
# --------------------------------------------------------------------------------------------
def _newton_many(ev: ContourEvaluator, derivative: CharacteristicFunction | None, z0: np.ndarray,
                 order: np.ndarray, rho: np.ndarray, tol: float, limit: tuple | None,
                 max_iterations: int = 40
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Newton on Delta^(m-1) for roots of multiplicity m (m = ``order``), batched.

    The Taylor coefficients a_k = Delta^(k)(z)/k! come from the trapezoidal Cauchy integral
    on the circle |s - z| = rho (``CIRCLE_POINTS`` points; exact up to a_(k+16) rho^16 for entire
    Delta; ``rho`` per root).  The discrete Fourier coefficients k = 9..15 (Taylor terms
    a_k rho^k, negligible for a small circle) measure the evaluation noise sigma of Delta.  Step:
    Delta(z)/Delta'(z) for m = 1, a_(m-1) / (m a_m) otherwise; converged when the step is below
    tol max(1, |z|), or when it stops shrinking at a small size (noise floor).  Error estimate:
    max(|step|, (sigma/|a_m|)^(1/m), (|Delta(z)|/|a_m|)^(1/m) for m > 1).  Iterates that
    leave the disc ``limit`` = (centre, radius) are abandoned.  Also returns whether the
    residual radius is within 10x the noise radius (a cluster at the noise level).  A Delta divided by a positive
    function ``e^g`` (:meth:`ContourEvaluator.scaled`) is multiplied back on each circle (else no Cauchy integral).
    """
    z = np.asarray(z0, dtype=complex).copy()
    n = z.size
    converged, alive, at_noise = np.zeros(n, bool), np.ones(n, bool), np.zeros(n, bool)
    error, previous = np.full(n, np.inf), np.full(n, np.inf)
    rho = np.broadcast_to(np.asarray(rho, dtype=float), z.shape)
    for iteration in range(max_iterations):
        idx = np.flatnonzero(alive & ~converged)
        if idx.size == 0:
            break
        zi, mi = z[idx], order[idx]
        use_circle = (mi > 1) | (derivative is None)
        circ = idx[use_circle]
        pts = np.concatenate([zi, (z[circ][:, None] + rho[circ][:, None] * UNIT_CIRCLE).ravel()])
        try:            # Delta / e^g (g real): each circle's values are brought to the scale of its centre
            values, g = ev.scaled(pts)
        except BudgetExceeded:
            break
        f0 = values[:idx.size]
        coeffs, sigma = np.zeros((idx.size, CIRCLE_POINTS), complex), np.zeros(idx.size)
        if circ.size:
            with np.errstate(over="ignore", invalid="ignore"):
                ring = values[idx.size:].reshape(circ.size, CIRCLE_POINTS) * np.exp(
                    g[idx.size:].reshape(circ.size, CIRCLE_POINTS) - g[:idx.size][use_circle][:, None])
            raw = np.fft.fft(ring, axis=1) / CIRCLE_POINTS
            coeffs[use_circle] = raw / rho[circ][:, None] ** np.arange(CIRCLE_POINTS)
            sigma[use_circle] = np.sqrt(CIRCLE_POINTS * np.mean(np.abs(raw[:, 9:]) ** 2, axis=1))
        if derivative is not None and (~use_circle).any():
            coeffs[~use_circle, 1] = np.asarray(derivative(zi[~use_circle]), dtype=complex)
        rows = np.arange(idx.size)
        a_m = np.abs(coeffs[rows, np.minimum(mi, CIRCLE_POINTS - 1)])
        numerator = np.where(mi == 1, f0, coeffs[rows, np.minimum(mi - 1, CIRCLE_POINTS - 1)])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            step = numerator / (mi * coeffs[rows, np.minimum(mi, CIRCLE_POINTS - 1)])
            radius_noise = (sigma / a_m) ** (1.0 / mi)
            radius_residual = np.where(mi > 1, (np.abs(f0) / a_m) ** (1.0 / mi), 0.0)
        ok = np.isfinite(step) & np.isfinite(f0)
        alive[idx[~ok]] = False
        step = np.where(ok, step, 0)
        znew = zi - step
        size, bound = np.abs(step), np.maximum(1.0, np.abs(znew))
        done = ok & ((size <= tol * bound) | (f0 == 0))
        # noise floor of Delta: the steps stop shrinking
        done |= (ok & (iteration >= 3) & (size >= 0.5 * previous[idx])
                 & (size <= np.sqrt(tol) * bound))
        previous[idx] = size
        z[idx] = znew
        converged[idx[done]] = True
        estimate = np.maximum(size, np.maximum(radius_noise, radius_residual))
        error[idx] = np.where(np.isfinite(estimate), estimate, np.inf)
        at_noise[idx] = radius_residual <= 10.0 * radius_noise
        if limit is not None:
            centre, radius = limit
            away = np.abs(z[idx] - centre[idx]) > radius[idx]
            alive[idx[away & ~done]] = False
    return z, converged & alive, error, at_noise


# --------------------------------------------------------------------------------------------
# bisection driven by counts
# --------------------------------------------------------------------------------------------
def _split(rect, fraction: float):
    a, b, c, d = rect
    if (b - a) >= (d - c):
        x = a + fraction * (b - a)
        return (a, x, c, d), (x, b, c, d)
    y = c + fraction * (d - c)
    return (a, b, c, y), (a, b, y, d)


def _find(ev, derivative, rect, *, seeds, tol, cluster_size, max_log_step,
          outer_count: RootCount):
    """Core of :func:`find_roots_in_rectangle` (rect validated, outer count done)."""
    scale = max(rectangle_diagonal(rect), float(np.abs(rectangle_corners(rect)).max()))
    rho = 1e-3 * scale                                 # Cauchy radius, capped per rectangle below
    notes: list[str] = []
    pool_z: list[complex] = []
    pool_err: list[float] = []

    def add_pool(zs, errs):
        for zz, ee in zip(zs, errs):
            if not inside_rectangle(np.array([zz]), rect)[0]:
                continue
            if any(abs(zz - p) <= 1e3 * max(ee, pe, tol * max(1.0, abs(zz)))
                   for p, pe in zip(pool_z, pool_err)):
                continue
            pool_z.append(complex(zz))
            pool_err.append(float(ee))

    if seeds is not None and len(seeds):
        s0 = np.asarray(seeds, dtype=complex).ravel()
        if not np.all(np.isfinite(s0)):
            raise ModelError("seeds must be finite complex numbers")
        gap = np.abs(s0[:, None] - s0[None, :]) + np.diag(np.full(s0.size, np.inf))
        rho_seed = np.minimum(rho, 1e-2 * gap.min(axis=1)) if s0.size > 1 else rho
        rho_seed = np.maximum(rho_seed, 1e3 * np.finfo(float).eps * np.maximum(1.0, np.abs(s0)))
        z, ok, err, _ = _newton_many(ev, derivative, s0, np.ones(s0.size, int), rho_seed, tol,
                                     None)
        add_pool(z[ok], err[ok])

    found_z: list[complex] = []
    found_m: list[int] = []
    found_err: list[float] = []

    def accept(z, m, e):
        found_z.append(complex(z)); found_m.append(int(m)); found_err.append(float(e))

    def centre_of(r):
        return complex(0.5 * (r[0] + r[1]), 0.5 * (r[2] + r[3]))

    def polish(group):
        """Batched Newton for [(rect, count)] from the contour estimate of the root (centroid)."""
        counts = np.array([c.count for _, c in group])
        start = np.array([c.root_sum / c.count if np.isfinite(c.root_sum) else centre_of(r)
                          for r, c in group])
        centre = np.array([centre_of(r) for r, _ in group])
        radius = np.array([2.0 * rectangle_diagonal(r) for r, _ in group])
        floor = 1e3 * np.finfo(float).eps * np.maximum(1.0, np.abs(centre))
        # small circles for simple roots (fast oscillation of Delta), wider ones for clusters
        # (derivatives of order m - 1 amplify the noise by rho^-(m-1))
        rhos = np.maximum(np.minimum(rho, np.where(counts > 1, 5.0, 1e-2) * radius), floor)
        z, ok, err, noisy = _newton_many(ev, derivative, start, counts, rhos, tol,
                                         (centre, radius))
        return start, z, ok, err, noisy

    queue = [(rect, outer_count, 0)]                   # (rectangle, its count, failed splits)
    while queue:
        to_split, newton_rects, cluster_rects = [], [], []
        for r, cnt, failed in queue:
            n = cnt.count
            if n == 0:
                continue
            pz = np.array(pool_z, complex)
            inside = np.flatnonzero(inside_rectangle(pz, r)) if pz.size else np.array([], int)
            if inside.size == n:                       # known roots account for the count
                for i in inside:
                    accept(pool_z[i], 1, pool_err[i])
                continue
            if rectangle_diagonal(r) <= cluster_size or (failed >= 2 and n >= 2):
                cluster_rects.append((r, cnt, failed))
            elif n == 1 and failed == 0 and inside.size == 0:
                newton_rects.append((r, cnt))
            else:
                to_split.append((r, cnt, failed))
        if newton_rects:
            _, z, ok, err, _ = polish(newton_rects)
            for k, (r, c) in enumerate(newton_rects):
                if ok[k] and inside_rectangle(z[k:k + 1], r)[0]:
                    accept(z[k], 1, err[k])
                else:
                    if ok[k]:
                        add_pool([z[k]], [err[k]])      # a root elsewhere: remember it
                    to_split.append((r, c, -1))        # -1: Newton failed, split normally
        if cluster_rects:
            start, z, ok, err, noisy = polish([(r, c) for r, c, _ in cluster_rects])
            for k, (r, c, failed) in enumerate(cluster_rects):
                small = rectangle_diagonal(r) <= cluster_size
                if ok[k] and inside_rectangle(z[k:k + 1], r)[0] and \
                        (small or noisy[k] or err[k] <= 1e3 * cluster_size):
                    accept(z[k], c.count, err[k])
                    if not small:
                        notes.append(f"{c.count} roots within ~{err[k]:.2g} of {z[k]:.10g} "
                                     "(sub-rectangles could not be counted: noise level) "
                                     "reported as one multiple root")
                elif failed < len(SPLIT_FRACTIONS) and not small:
                    to_split.append((r, c, failed))
                else:
                    accept(start[k], c.count, rectangle_diagonal(r))
                    notes.append(f"rectangle {r} with {c.count} roots unresolved; reported as one "
                                 f"root of multiplicity {c.count} at its contour centroid")
        queue = []
        if not to_split:
            break
        children, parents = [], []
        for r, cnt, failed in to_split:
            r1, r2 = _split(r, SPLIT_FRACTIONS[max(failed, 0) % len(SPLIT_FRACTIONS)])
            cap = 20_000 + 8 * cnt.n_points          # noise guard, generous for oscillation
            children += [RectangleContour(r1, 32, None, cap), RectangleContour(r2, 32, None, cap)]
            parents.append((r, cnt, max(failed, 0)))
        count_contours(ev, children, max_log_step)
        for k, (r, cnt, failed) in enumerate(parents):
            c1, c2 = children[2 * k], children[2 * k + 1]
            if isinstance(c1.error, BudgetExceeded) or isinstance(c2.error, BudgetExceeded):
                notes.append(f"evaluation budget exhausted; rectangle {r} with {cnt.count} roots "
                             "unresolved")
                continue
            if c1.error is not None or c2.error is not None or \
                    c1.result.count + c2.result.count != cnt.count:
                failed += 1                            # root on/near the split line, or noise
                if failed < len(SPLIT_FRACTIONS):              # (from 2 failures on: try a cluster)
                    queue.append((r, cnt, failed))
                else:
                    accept(cnt.root_sum / cnt.count, cnt.count, rectangle_diagonal(r))
                    notes.append(f"rectangle {r} with {cnt.count} roots unresolved (no consistent "
                                 "split); reported at its contour centroid")
                continue
            if not (c1.result.reliable and c2.result.reliable):
                notes.append(f"unverified count in a sub-rectangle of {r}")
            queue += [(c1.rect, c1.result, 0), (c2.rect, c2.result, 0)]
    return found_z, found_m, found_err, notes


def _sort_order(z: np.ndarray, err: np.ndarray) -> np.ndarray:
    """Decreasing real part; real parts equal within error (conjugate pairs) by imaginary part."""
    if z.size == 0:
        return np.array([], int)
    order = list(np.argsort(-z.real, kind="stable"))
    out, group = [], [order[0]]
    for i in order[1:]:
        j = group[-1]
        slack = max(err[i], err[j], 1e-12 * max(1.0, abs(z[i]), abs(z[j])))
        if abs(z[j].real - z[i].real) <= slack:
            group.append(i)
        else:
            out += sorted(group, key=lambda k: z[k].imag)
            group = [i]
    out += sorted(group, key=lambda k: z[k].imag)
    return np.array(out, int)


def _root_set(ev, zs, ms, errs, count, reliable, notes) -> RootSet:
    z = np.array(zs, complex)
    m = np.array(ms, int)
    e = np.array(errs, float)
    order = _sort_order(z, e)
    total = int(m.sum())
    if total != count:
        notes = list(notes) + [f"found {total} roots (with multiplicity) but the count is {count}"]
    reliable = bool(reliable and total == count and not any("unresolved" in t for t in notes))
    return RootSet(z[order], m[order], e[order], int(count), reliable, ev.calls, ev.points,
                   tuple(notes))


def _options(tol, cluster_size, max_log_step, max_evaluations):
    tol = positive("tol", tol)
    if tol >= 1e-3:
        raise ModelError(f"tol must be in (0, 1e-3), got {tol!r}")
    if cluster_size is not None:
        cluster_size = positive("cluster_size", cluster_size)
    return tol, cluster_size, log_step_option(max_log_step), evaluation_budget(max_evaluations)


def find_roots_in_rectangle(char_fn: CharacteristicFunction, re_range: tuple[float, float],
                            im_range: tuple[float, float], *,
                            seeds: Sequence[complex] | None = None,
                            derivative: CharacteristicFunction | None = None, tol: float = 1e-12,
                            cluster_size: float | None = None, max_log_step: float = 0.5,
                            max_evaluations: int = 2_000_000) -> RootSet:
    """Every root of an analytic function inside a rectangle, each once with its multiplicity.

    The rectangle is counted (:func:`count_roots_in_rectangle`); a rectangle with one root is
    solved by Newton's method from the contour estimate of that root, and the result accepted
    only if it lies inside; otherwise (or with several roots) the rectangle is bisected across
    its longer side and both halves are counted, which must add up to the parent's count (if a
    root lies on the split line, the line is moved).  A rectangle smaller than ``cluster_size``
    that still holds m > 1 roots is reported as one root of multiplicity m, polished by Newton
    on Delta^(m-1) (whose root is the cluster centroid).  Roots converged to from ``seeds`` or
    from other rectangles are reused when they account for a rectangle's whole count.

    Parameters
    ----------
    char_fn : callable
        Vectorised Delta(s) (complex ndarray in, same shape out), analytic in the rectangle.
    re_range, im_range : (float, float)
        The rectangle [1/s]; no root may lie on its boundary.
    seeds : sequence of complex, optional
        Approximate roots [1/s] (e.g. from the previous point of a parameter sweep).
    derivative : callable, optional
        Vectorised Delta'(s); without it Delta' comes from a 16-point Cauchy integral.
    tol : float, optional
        Newton stops when |step| <= tol max(1, |z|).
    cluster_size : float, optional
        Diagonal [1/s] below which a multi-root rectangle is a single multiple root.  Default
        1e-7 max(1, max |corner|) (distinct roots closer than that are merged).
    max_log_step : float, optional
        Contour sampling threshold, see :func:`count_roots_in_rectangle`.
    max_evaluations : int, optional
        Budget of function evaluations.

    Returns
    -------
    RootSet

    Raises
    ------
    ContourError
        A root lies on (or within ~1e-10 perimeter of) the outer boundary.

    Examples
    --------
    >>> found = find_roots_in_rectangle(lambda s: (s - 0.5) ** 2 * (s + 1j), (-1, 1), (-2, 2))
    >>> found.count, found.multiplicities.tolist(), bool(abs(found.roots[0] - 0.5) < 1e-12)
    (3, [2, 1], True)
    """
    rect = as_rectangle(re_range, im_range)
    tol, cluster_size, max_log_step, budget = _options(tol, cluster_size, max_log_step,
                                                       max_evaluations)
    if cluster_size is None:
        cluster_size = 1e-7 * max(1.0, float(np.abs(rectangle_corners(rect)).max()))
    ev = ContourEvaluator(char_fn, budget)
    return _find_with(ev, derivative, rect, seeds, tol, cluster_size, max_log_step, [])


def _find_with(ev, derivative, rect, seeds, tol, cluster_size, max_log_step, notes) -> RootSet:
    outer = RectangleContour(rect, 64, None)
    count_contours(ev, [outer], max_log_step)
    if isinstance(outer.error, BudgetExceeded):
        return _root_set(ev, [], [], [], 0, False, notes + ["evaluation budget exhausted "
                                                             "while counting the rectangle"])
    if outer.error is not None:
        raise outer.error
    zs, ms, errs, more = _find(ev, derivative, rect, seeds=seeds, tol=tol,
                               cluster_size=cluster_size, max_log_step=max_log_step,
                               outer_count=outer.result)
    return _root_set(ev, zs, ms, errs, outer.result.count, outer.result.reliable, notes + more)


# --------------------------------------------------------------------------------------------
# stability-oriented wrappers
# --------------------------------------------------------------------------------------------
def rightmost_roots(char_fn: CharacteristicFunction, *, im_max: float, re_min: float,
                    re_max: float | None = None, seeds: Sequence[complex] | None = None,
                    derivative: CharacteristicFunction | None = None,
                    conjugate_symmetric: bool = False, tol: float = 1e-12,
                    cluster_size: float | None = None, max_log_step: float = 0.5,
                    max_evaluations: int = 2_000_000) -> RootSet:
    """Roots with re_min < Re s < re_max and |Im s| <= im_max, rightmost first.

    Parameters
    ----------
    char_fn : callable
        Vectorised Delta(s), analytic in the region.
    im_max : float
        Half-height of the region [rad/s], > 0.
    re_min : float
        Left edge [1/s]; no root may lie on it.
    re_max : float, optional
        Right edge [1/s].  For retarded systems (leading term s^n undelayed) roots lie in a left
        half plane; give a bound when you know one.  If omitted it is chosen heuristically by
        widening strips to the right until one holds no root (noted in ``notes``).
    seeds, derivative, tol, cluster_size, max_log_step, max_evaluations
        As in :func:`find_roots_in_rectangle`.
    conjugate_symmetric : bool, optional
        Delta(conj s) = conj Delta(s) (real systems): search 0 <= Im s <= im_max only (from a
        small negative offset, to keep real roots off the contour) and mirror the roots.

    Returns
    -------
    RootSet
        Sorted by decreasing real part.  With ``conjugate_symmetric`` roots whose imaginary part
        is within their error estimate of 0 are returned as exactly real, the others in exact
        conjugate pairs, and ``count`` is the mirrored count of the upper half.
    """
    im_max = positive("im_max", im_max)
    re_min = finite("re_min", re_min)
    if not isinstance(conjugate_symmetric, bool):
        raise ModelError(f"conjugate_symmetric must be True or False, got {conjugate_symmetric!r}")
    tol, cluster_size, max_log_step, budget = _options(tol, cluster_size, max_log_step,
                                                       max_evaluations)
    ev = ContourEvaluator(char_fn, budget)
    notes: list[str] = []
    if re_max is None:
        re_max = _right_bound(ev, re_min, im_max, max_log_step, notes)
    else:
        re_max = finite("re_max", re_max)
        if not re_max > re_min:
            raise ModelError(f"re_max must be > re_min = {re_min!r}, got {re_max!r}")
    if cluster_size is None:
        cluster_size = 1e-7 * max(1.0, abs(re_min), abs(re_max), im_max)
    if not conjugate_symmetric:
        return _find_with(ev, derivative, (re_min, re_max, -im_max, im_max), seeds, tol,
                          cluster_size, max_log_step, notes)
    if seeds is not None:
        seeds = np.asarray(seeds, dtype=complex).ravel()
        seeds = np.where(seeds.imag < 0, seeds.conj(), seeds)
    offset = 1e-3 * im_max          # lower edge just below the real axis, off the real roots
    for attempt in range(6):
        try:
            half = _find_with(ev, derivative, (re_min, re_max, -offset, im_max), seeds, tol,
                              cluster_size, max_log_step, notes)
            break
        except ContourError as exc:
            if abs(exc.location.imag + offset) > 1e-9 * im_max or attempt == 5:
                raise                     # not on the auxiliary edge: the user's rectangle
            offset *= 1.618
    # roots in -offset < Im s < 0 are conjugates of roots found above the axis: drop them
    z, m, e = half.roots, half.multiplicities, half.error_estimates
    real = np.abs(z.imag) <= np.maximum(e, 1e-14 * np.abs(z))
    upper = ~real & (z.imag > 0)
    consistent = int(m.sum()) == half.count
    return _root_set(ev, np.concatenate([z[real].real + 0j, z[upper], z[upper].conj()]),
                     np.concatenate([m[real], m[upper], m[upper]]),
                     np.concatenate([e[real], e[upper], e[upper]]),
                     int(m[real].sum() + 2 * m[upper].sum()), half.reliable and consistent,
                     list(half.notes))


def _right_bound(ev, re_min, im_max, max_log_step, notes) -> float:
    width = max(1.0, im_max)
    right = re_min + width
    for _ in range(12):
        strip = RectangleContour((right, right + 2 * width, -im_max, im_max), 64, None)
        count_contours(ev, [strip], max_log_step)
        if strip.error is None and strip.result.count == 0:
            notes.append(f"re_max = {right:.6g} chosen heuristically (no root in "
                         f"{right:.6g} < Re s < {right + 2 * width:.6g}, |Im s| <= {im_max:.6g})")
            return right
        right += 2 * width
        width *= 2.0
    raise ModelError("re_max could not be chosen automatically (roots keep appearing to the "
                     f"right up to Re s = {right:.6g}); pass re_max explicitly")


def spectral_abscissa(char_fn: CharacteristicFunction, *, im_max: float, re_min: float,
                      re_max: float | None = None, seeds: Sequence[complex] | None = None,
                      derivative: CharacteristicFunction | None = None,
                      conjugate_symmetric: bool = False, tol: float = 1e-12) -> SpectralAbscissa:
    """Largest real part of the roots in re_min < Re s < re_max, |Im s| <= im_max.

    Parameters are those of :func:`rightmost_roots`.  The system is exponentially stable (as
    far as the region sees) when ``value + error < 0``.

    Returns
    -------
    SpectralAbscissa

    Examples
    --------
    Hayes' equation lambda + e^(-lambda) = 0:

    >>> import numpy as np
    >>> a = spectral_abscissa(lambda s: s + np.exp(-s), im_max=10, re_min=-3, re_max=2)
    >>> round(a.value, 9), a.error < 1e-10
    (-0.318131505, True)
    """
    roots = rightmost_roots(char_fn, im_max=im_max, re_min=re_min, re_max=re_max, seeds=seeds,
                            derivative=derivative, conjugate_symmetric=conjugate_symmetric,
                            tol=tol)
    if roots.roots.size == 0:
        return SpectralAbscissa(float(re_min), 0.0, None, True, roots)
    top = roots.roots.real.max()
    slack = np.maximum(roots.error_estimates, 1e-12 * abs(top))
    near = np.flatnonzero(roots.roots.real >= top - slack)
    k = near[np.argmax(roots.roots.imag[near])]           # of a pair, the one with Im >= 0
    return SpectralAbscissa(float(top), float(roots.error_estimates[k]), complex(roots.roots[k]),
                            False, roots)
