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

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .errors import ModelError
from .validation import finite, positive

__all__ = ["ContourError", "RootCount", "RootSet", "SpectralAbscissa",
           "count_roots_in_rectangle", "find_roots_in_rectangle", "rightmost_roots",
           "spectral_abscissa"]

CharacteristicFunction = Callable[[np.ndarray], np.ndarray]
_CIRCLE = 16                                    # points of the Cauchy-integral derivative
_UNIT = np.exp(2j * np.pi * np.arange(_CIRCLE) / _CIRCLE)
_SPLITS = (0.5, 0.5617, 0.4383, 0.6180, 0.3820, 0.5281, 0.4719)


class ContourError(ModelError):
    """The characteristic function vanishes (or is not finite) on or very near a contour.

    Attributes
    ----------
    location : complex
        Point of the contour [1/s] where the problem was detected.
    """

    def __init__(self, message: str, location: complex) -> None:
        super().__init__(message)
        self.location = location


@dataclass(frozen=True)
class RootCount:
    """Number of roots inside a rectangle, from the argument principle.

    Attributes
    ----------
    count : int
        Roots inside, counted with multiplicity.
    reliable : bool
        True when a uniform refinement of the converged contour sampling left the count unchanged.
    winding : float
        Unrounded winding number of Delta along the contour.
    root_sum : complex
        Contour estimate of the sum of the enclosed roots [1/s] (moderate accuracy).
    n_points : int
        Contour samples used.
    n_calls : int
        Calls of the characteristic function.
    """

    count: int
    reliable: bool
    winding: float
    root_sum: complex
    n_points: int
    n_calls: int


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
    """

    roots: np.ndarray
    multiplicities: np.ndarray
    error_estimates: np.ndarray
    count: int
    reliable: bool
    n_calls: int
    n_evaluations: int
    notes: tuple[str, ...] = ()

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
    """

    value: float
    error: float
    root: complex | None
    below_re_min: bool
    roots: RootSet

    @property
    def stable(self) -> bool:
        """Every root of the region lies in Re s < 0 (value + error < 0, or no root right of a
        re_min <= 0), with a reliable search."""
        inside = self.value + self.error < 0.0 or (self.below_re_min and self.value <= 0.0)
        return bool(inside and self.roots.reliable)


# --------------------------------------------------------------------------------------------
# evaluation bookkeeping
# --------------------------------------------------------------------------------------------
class _Evaluator:
    def __init__(self, char_fn: CharacteristicFunction, budget: int) -> None:
        if not callable(char_fn):
            raise ModelError(f"char_fn must be a callable s -> Delta(s), got {char_fn!r}")
        self.char_fn, self.budget = char_fn, budget
        self.calls = self.points = 0

    def __call__(self, s: np.ndarray) -> np.ndarray:
        s = np.asarray(s, dtype=complex)
        if self.points + s.size > self.budget:
            raise _BudgetExceeded()
        self.calls += 1
        self.points += s.size
        value = np.asarray(self.char_fn(s))
        if value.shape != s.shape:
            raise ModelError(f"char_fn must return an array of the same shape as s (vectorised); "
                             f"got shape {value.shape} for s of shape {s.shape}")
        return value.astype(complex, copy=False)


class _BudgetExceeded(Exception):
    pass


def _rectangle(re_range: object, im_range: object) -> tuple[float, float, float, float]:
    out = []
    for label, rng in (("re_range", re_range), ("im_range", im_range)):
        try:
            lo, hi = rng  # type: ignore[misc]
        except (TypeError, ValueError):
            raise ModelError(f"{label} must be a pair (low, high), got {rng!r}") from None
        lo, hi = finite(f"{label}[0]", lo), finite(f"{label}[1]", hi)
        if not hi > lo:
            raise ModelError(f"{label} must satisfy low < high, got ({lo!r}, {hi!r})")
        out += [lo, hi]
    return out[0], out[1], out[2], out[3]


def _corners(rect: tuple[float, float, float, float]) -> np.ndarray:
    a, b, c, d = rect
    return np.array([complex(a, c), complex(b, c), complex(b, d), complex(a, d)])


def _diag(rect: tuple[float, float, float, float]) -> float:
    return math.hypot(rect[1] - rect[0], rect[3] - rect[2])


def _inside(z: np.ndarray, rect: tuple[float, float, float, float]) -> np.ndarray:
    return (z.real > rect[0]) & (z.real < rect[1]) & (z.imag > rect[2]) & (z.imag < rect[3])


# --------------------------------------------------------------------------------------------
# argument principle, many contours at once
# --------------------------------------------------------------------------------------------
class _Contour:
    """Adaptive sampling state of one rectangle boundary (counter-clockwise, closed).

    Every sample s_j carries a companion s_j + delta u_j (u_j the unit tangent of its interval)
    whose value gives the logarithmic derivative g_j = Delta'(s_j)/Delta(s_j) by a forward
    difference; an interval of length h_j is accepted only if both the observed complex-log step
    and the predicted one, h_j max(|g_j|, |g_j+1|), are small.  The prediction guards against
    aliasing of fast oscillations (e^(-s tau) with large tau) by a coarse sampling.
    """

    def __init__(self, rect, initial_points: int, min_step: float | None,
                 max_points: int | None = None) -> None:
        self.rect = rect
        self.max_points = max_points
        corners = _corners(rect)
        edges = np.abs(np.roll(corners, -1) - corners)
        per_edge = np.maximum(4, np.ceil(initial_points * edges / edges.sum())).astype(int)
        s, u = [], []
        for k in range(4):
            direction = corners[(k + 1) % 4] - corners[k]
            s.append(corners[k] + direction * np.arange(per_edge[k]) / per_edge[k])
            u.append(np.full(per_edge[k], direction / abs(direction)))
        self.s = np.append(np.concatenate(s), corners[0])
        self.u = np.append(np.concatenate(u), u[0][0])
        scale = max(1.0, float(np.abs(corners).max()))
        self.delta = max(1e-4 * float(edges.min()), 1e3 * np.finfo(float).eps * scale)
        self.min_step = max(1e-10 * edges.sum(), 64 * np.finfo(float).eps * scale) \
            if min_step is None else min_step
        self.values: np.ndarray | None = None
        self.logderiv: np.ndarray | None = None
        self.pending = self.s[:-1]
        self.pending_u = self.u[:-1]
        self.slots = np.array([], int)
        self.previous_count: int | None = None
        self.verifications = 0
        self.result: RootCount | None = None
        self.error: Exception | None = None
        self.calls = 0

    def finish(self, steps: np.ndarray, reliable: bool) -> None:
        winding = float(steps.imag.sum() / (2 * np.pi))
        mids = 0.5 * (self.s[1:] + self.s[:-1])
        root_sum = complex((mids * steps).sum() / (2j * np.pi))
        self.result = RootCount(int(round(winding)), reliable, winding, root_sum,
                                int(self.s.size - 1), self.calls)


def _log_steps(values: np.ndarray) -> np.ndarray:
    magnitude = np.abs(values)
    unit = values / magnitude
    phase = np.angle(unit[1:] * unit[:-1].conj())
    return (np.log(magnitude[1:]) - np.log(magnitude[:-1])) + 1j * phase


def _check_values(c: _Contour, s: np.ndarray, v: np.ndarray) -> None:
    bad = ~np.isfinite(v)
    if bad.any():
        z = complex(s[bad][0])
        raise ContourError(f"char_fn is not finite on the contour of rectangle re {c.rect[:2]}, "
                           f"im {c.rect[2:]} at s = {z:.10g} (overflow or pole there?)", z)
    zero = v == 0
    if zero.any():
        z = complex(s[zero][0])
        raise ContourError(f"char_fn vanishes on the contour of rectangle re {c.rect[:2]}, "
                           f"im {c.rect[2:]} at s = {z:.10g}; move that edge", z)


def _count_many(ev: _Evaluator, contours: list[_Contour], max_log_step: float) -> None:
    """Run the adaptive sampling of all contours together (one batched call per round)."""
    while True:
        active = [c for c in contours if c.result is None and c.error is None]
        if not active:
            return
        chunks = [np.concatenate([c.pending, c.pending + c.delta * c.pending_u])
                  for c in active]
        try:
            values = ev(np.concatenate(chunks))
        except _BudgetExceeded:
            for c in active:
                c.error = _BudgetExceeded()
            return
        offset = 0
        for c, chunk in zip(active, chunks):
            half = chunk.size // 2
            v, w = values[offset:offset + half], values[offset + half:offset + chunk.size]
            offset += chunk.size
            c.calls += 1
            try:
                _check_values(c, chunk[:half], v)
            except ContourError as exc:
                c.error = exc
                continue
            with np.errstate(all="ignore"):
                g = np.abs((w - v) / (c.delta * c.pending_u) / v)
            g = np.where(np.isfinite(g), g, np.inf)
            if c.values is None:                             # first round: whole contour
                c.values, c.logderiv = np.append(v, v[0]), np.append(g, g[0])
            else:                                  # insert midpoints after their left ends
                c.s = np.insert(c.s, c.slots, c.pending)
                c.u = np.insert(c.u, c.slots, c.pending_u)
                c.values = np.insert(c.values, c.slots, v)
                c.logderiv = np.insert(c.logderiv, c.slots, g)
            steps = _log_steps(c.values)
            h = np.abs(np.diff(c.s))
            observed = np.abs(steps)
            predicted = h * np.maximum(c.logderiv[1:], c.logderiv[:-1])
            bad = (observed > max_log_step) | (predicted > 2.0 * max_log_step)
            if bad.any():
                stuck = bad & (h < c.min_step)
                if stuck.any():
                    j = int(np.argmax(np.where(stuck, observed, -1.0)))
                    z = complex(0.5 * (c.s[j] + c.s[j + 1]))
                    c.error = ContourError(
                        f"char_fn has a zero (or pole) on or within {h[j]:.2g} of the contour of "
                        f"rectangle re {c.rect[:2]}, im {c.rect[2:]} near s = {z:.10g}; "
                        "move that edge", z)
                    continue
                index = np.flatnonzero(bad)
            else:
                count = int(round(float(steps.imag.sum() / (2 * np.pi))))
                if c.previous_count is not None and c.previous_count == count:
                    c.finish(steps, True)
                    continue
                if c.verifications >= 4:
                    c.finish(steps, False)
                    continue
                c.previous_count = count                     # verify: bisect every interval
                c.verifications += 1
                index = np.arange(c.s.size - 1)
            c.slots = index + 1
            c.pending = 0.5 * (c.s[index] + c.s[index + 1])
            c.pending_u = c.u[index]
            if c.max_points is not None and c.s.size + c.pending.size > c.max_points:
                z = complex(c.pending[0])
                c.error = ContourError(
                    f"sampling of the contour of rectangle re {c.rect[:2]}, im {c.rect[2:]} "
                    f"did not settle within {c.max_points} points (char_fn noisy or "
                    f"oscillating near s = {z:.10g}?)", z)


def count_roots_in_rectangle(char_fn: CharacteristicFunction, re_range: tuple[float, float],
                             im_range: tuple[float, float], *, max_log_step: float = 0.5,
                             initial_points: int = 64, min_step: float | None = None,
                             max_evaluations: int = 200_000) -> RootCount:
    """Count the roots of an analytic function inside a rectangle (argument principle).

    The boundary is sampled counter-clockwise; intervals whose complex-log step
    |log(Delta(s_j+1)/Delta(s_j))| exceeds ``max_log_step``, or whose length times the
    logarithmic derivative |Delta'/Delta| at an end (forward difference) exceeds
    2 ``max_log_step``, are bisected (all new points of a round in one call) until none does;
    then every interval is bisected once more and the count must not change (otherwise
    refinement continues, up to four verifications).  The winding number is the sum of the
    phase steps over 2 pi.

    Parameters
    ----------
    char_fn : callable
        Vectorised Delta(s): complex ndarray in, same-shape complex ndarray out, analytic
        inside and on the rectangle.
    re_range, im_range : (float, float)
        Rectangle [re_low, re_high] x [im_low, im_high] [1/s], low < high.
    max_log_step : float, optional
        Largest accepted |complex-log step| between neighbouring samples [-], in (0, 1.5].
    initial_points : int, optional
        Samples on the whole boundary before refinement (>= 16).
    min_step : float, optional
        Shortest interval [1/s]; a root closer than about this to the boundary raises
        :class:`ContourError`.  Default 1e-10 x perimeter (at least 64 eps max|corner|).
    max_evaluations : int, optional
        Budget of function evaluations; when exhausted the count is returned as unreliable.

    Returns
    -------
    RootCount

    Raises
    ------
    ContourError
        Delta vanishes, is not finite, or has a zero within ``min_step`` of the boundary
        (the message gives the location).

    Examples
    --------
    >>> count_roots_in_rectangle(lambda s: s**2 + 1, (-1, 1), (0, 2)).count
    1
    """
    rect = _rectangle(re_range, im_range)
    max_log_step = _log_step_option(max_log_step)
    if isinstance(initial_points, bool) or not isinstance(initial_points, (int, np.integer)) \
            or initial_points < 16:
        raise ModelError(f"initial_points must be an int >= 16, got {initial_points!r}")
    if min_step is not None:
        min_step = positive("min_step", min_step)
    ev = _Evaluator(char_fn, _budget(max_evaluations))
    contour = _Contour(rect, int(initial_points), min_step)
    _count_many(ev, [contour], max_log_step)
    if isinstance(contour.error, _BudgetExceeded):
        steps = _log_steps(contour.values) if contour.values is not None else np.zeros(1)
        winding = float(steps.imag.sum() / (2 * np.pi))
        return RootCount(int(round(winding)), False, winding, complex("nan"),
                         int(contour.s.size - 1), ev.calls)
    if contour.error is not None:
        raise contour.error
    return contour.result


def _log_step_option(value: float) -> float:
    value = positive("max_log_step", value)
    if value > 1.5:
        raise ModelError(f"max_log_step must be in (0, 1.5] (phase aliasing), got {value!r}")
    return value


def _budget(value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 100:
        raise ModelError(f"max_evaluations must be an int >= 100, got {value!r}")
    return int(value)


# --------------------------------------------------------------------------------------------
# Newton's method, many roots at once
# --------------------------------------------------------------------------------------------
def _newton_many(ev: _Evaluator, derivative: CharacteristicFunction | None, z0: np.ndarray,
                 order: np.ndarray, rho: np.ndarray, tol: float, limit: tuple | None,
                 max_iterations: int = 40
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Newton on Delta^(m-1) for roots of multiplicity m (m = ``order``), batched.

    The Taylor coefficients a_k = Delta^(k)(z)/k! come from the trapezoidal Cauchy integral
    on the circle |s - z| = rho (``_CIRCLE`` points; exact up to a_(k+16) rho^16 for entire
    Delta; ``rho`` per root).  The discrete Fourier coefficients k = 9..15 (Taylor terms
    a_k rho^k, negligible for a small circle) measure the evaluation noise sigma of Delta.  Step:
    Delta(z)/Delta'(z) for m = 1, a_(m-1) / (m a_m) otherwise; converged when the step is below
    tol max(1, |z|), or when it stops shrinking at a small size (noise floor).  Error estimate:
    max(|step|, (sigma/|a_m|)^(1/m), (|Delta(z)|/|a_m|)^(1/m) for m > 1).  Iterates that
    leave the disc ``limit`` = (centre, radius) are abandoned.  Also returns whether the
    residual radius is within 10x the noise radius (a cluster at the noise level).
    """
    z = np.asarray(z0, dtype=complex).copy()
    n = z.size
    converged = np.zeros(n, bool)
    alive = np.ones(n, bool)
    error = np.full(n, np.inf)
    previous = np.full(n, np.inf)
    at_noise = np.zeros(n, bool)
    rho = np.broadcast_to(np.asarray(rho, dtype=float), z.shape)
    for iteration in range(max_iterations):
        idx = np.flatnonzero(alive & ~converged)
        if idx.size == 0:
            break
        zi, mi = z[idx], order[idx]
        use_circle = (mi > 1) | (derivative is None)
        circ = idx[use_circle]
        pts = np.concatenate([zi, (z[circ][:, None] + rho[circ][:, None] * _UNIT).ravel()])
        try:
            values = ev(pts)
        except _BudgetExceeded:
            break
        f0 = values[:idx.size]
        coeffs = np.zeros((idx.size, _CIRCLE), complex)
        sigma = np.zeros(idx.size)
        if circ.size:
            raw = np.fft.fft(values[idx.size:].reshape(circ.size, _CIRCLE), axis=1) / _CIRCLE
            coeffs[use_circle] = raw / rho[circ][:, None] ** np.arange(_CIRCLE)
            sigma[use_circle] = np.sqrt(_CIRCLE * np.mean(np.abs(raw[:, 9:]) ** 2, axis=1))
        if derivative is not None and (~use_circle).any():
            coeffs[~use_circle, 1] = np.asarray(derivative(zi[~use_circle]), dtype=complex)
        rows = np.arange(idx.size)
        a_m = np.abs(coeffs[rows, np.minimum(mi, _CIRCLE - 1)])
        numerator = np.where(mi == 1, f0, coeffs[rows, np.minimum(mi - 1, _CIRCLE - 1)])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            step = numerator / (mi * coeffs[rows, np.minimum(mi, _CIRCLE - 1)])
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
    scale = max(_diag(rect), float(np.abs(_corners(rect)).max()))
    rho = 1e-3 * scale                                 # Cauchy radius, capped per rectangle below
    notes: list[str] = []
    pool_z: list[complex] = []
    pool_err: list[float] = []

    def add_pool(zs, errs):
        for zz, ee in zip(zs, errs):
            if not _inside(np.array([zz]), rect)[0]:
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
        radius = np.array([2.0 * _diag(r) for r, _ in group])
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
            inside = np.flatnonzero(_inside(pz, r)) if pz.size else np.array([], int)
            if inside.size == n:                       # known roots account for the count
                for i in inside:
                    accept(pool_z[i], 1, pool_err[i])
                continue
            if _diag(r) <= cluster_size or (failed >= 2 and n >= 2):
                cluster_rects.append((r, cnt, failed))
            elif n == 1 and failed == 0 and inside.size == 0:
                newton_rects.append((r, cnt))
            else:
                to_split.append((r, cnt, failed))
        if newton_rects:
            _, z, ok, err, _ = polish(newton_rects)
            for k, (r, c) in enumerate(newton_rects):
                if ok[k] and _inside(z[k:k + 1], r)[0]:
                    accept(z[k], 1, err[k])
                else:
                    if ok[k]:
                        add_pool([z[k]], [err[k]])      # a root elsewhere: remember it
                    to_split.append((r, c, -1))        # -1: Newton failed, split normally
        if cluster_rects:
            start, z, ok, err, noisy = polish([(r, c) for r, c, _ in cluster_rects])
            for k, (r, c, failed) in enumerate(cluster_rects):
                small = _diag(r) <= cluster_size
                if ok[k] and _inside(z[k:k + 1], r)[0] and \
                        (small or noisy[k] or err[k] <= 1e3 * cluster_size):
                    accept(z[k], c.count, err[k])
                    if not small:
                        notes.append(f"{c.count} roots within ~{err[k]:.2g} of {z[k]:.10g} "
                                     "(sub-rectangles could not be counted: noise level) "
                                     "reported as one multiple root")
                elif failed < len(_SPLITS) and not small:
                    to_split.append((r, c, failed))
                else:
                    accept(start[k], c.count, _diag(r))
                    notes.append(f"rectangle {r} with {c.count} roots unresolved; reported as one "
                                 f"root of multiplicity {c.count} at its contour centroid")
        queue = []
        if not to_split:
            break
        children, parents = [], []
        for r, cnt, failed in to_split:
            r1, r2 = _split(r, _SPLITS[max(failed, 0) % len(_SPLITS)])
            cap = 20_000 + 8 * cnt.n_points          # noise guard, generous for oscillation
            children += [_Contour(r1, 32, None, cap), _Contour(r2, 32, None, cap)]
            parents.append((r, cnt, max(failed, 0)))
        _count_many(ev, children, max_log_step)
        for k, (r, cnt, failed) in enumerate(parents):
            c1, c2 = children[2 * k], children[2 * k + 1]
            if isinstance(c1.error, _BudgetExceeded) or isinstance(c2.error, _BudgetExceeded):
                notes.append(f"evaluation budget exhausted; rectangle {r} with {cnt.count} roots "
                             "unresolved")
                continue
            if c1.error is not None or c2.error is not None or \
                    c1.result.count + c2.result.count != cnt.count:
                failed += 1                            # root on/near the split line, or noise
                if failed < len(_SPLITS):              # (from 2 failures on: try a cluster)
                    queue.append((r, cnt, failed))
                else:
                    accept(cnt.root_sum / cnt.count, cnt.count, _diag(r))
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
    return tol, cluster_size, _log_step_option(max_log_step), _budget(max_evaluations)


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
    rect = _rectangle(re_range, im_range)
    tol, cluster_size, max_log_step, budget = _options(tol, cluster_size, max_log_step,
                                                       max_evaluations)
    if cluster_size is None:
        cluster_size = 1e-7 * max(1.0, float(np.abs(_corners(rect)).max()))
    ev = _Evaluator(char_fn, budget)
    return _find_with(ev, derivative, rect, seeds, tol, cluster_size, max_log_step, [])


def _find_with(ev, derivative, rect, seeds, tol, cluster_size, max_log_step, notes) -> RootSet:
    outer = _Contour(rect, 64, None)
    _count_many(ev, [outer], max_log_step)
    if isinstance(outer.error, _BudgetExceeded):
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
    ev = _Evaluator(char_fn, budget)
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
        strip = _Contour((right, right + 2 * width, -im_max, im_max), 64, None)
        _count_many(ev, [strip], max_log_step)
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
