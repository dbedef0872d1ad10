"""Argument-principle root counting on rectangles (the counting layer of :mod:`ctmm.roots`).

Evaluates a vectorised analytic ``char_fn(s)`` on the boundary of rectangles with adaptive
sampling: an interval is bisected while the complex-log step ``log(Delta(s_j+1)/Delta(s_j))`` or
its prediction from ``Delta'/Delta`` is too large, then every interval is bisected once more and
the winding number must not change.  All contours of a round are evaluated in one call.
Methods, guarantees and limits: docs/characteristic_roots.md.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .errors import ModelError
from .validation import finite, positive

__all__ = ["ContourError", "RootCount", "count_roots_in_rectangle"]

CharacteristicFunction = Callable[[np.ndarray], np.ndarray]
CIRCLE_POINTS = 16                                    # points of the Cauchy-integral derivative
UNIT_CIRCLE = np.exp(2j * np.pi * np.arange(CIRCLE_POINTS) / CIRCLE_POINTS)
SPLIT_FRACTIONS = (0.5, 0.5617, 0.4383, 0.6180, 0.3820, 0.5281, 0.4719)


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


# --------------------------------------------------------------------------------------------
# evaluation bookkeeping
# --------------------------------------------------------------------------------------------
class ContourEvaluator:
    def __init__(self, char_fn: CharacteristicFunction, budget: int) -> None:
        if not callable(char_fn):
            raise ModelError(f"char_fn must be a callable s -> Delta(s), got {char_fn!r}")
        self.char_fn, self.budget = char_fn, budget
        self.calls = self.points = 0

    def __call__(self, s: np.ndarray) -> np.ndarray:
        return self.scaled(s, unscaled=True)[0]

    def scaled(self, s: np.ndarray, *, unscaled: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """``(values, g)``: ``char_fn(s)`` and the log of the positive function ``e^g`` it was divided by, so that
        ``values e^g`` is holomorphic (a char_fn says so by a ``scaled`` attribute returning both, as
        :meth:`ctmm.sweeps.AffineCharacteristic.char_fn`; else ``g = 0``).  ``unscaled``: ``g`` not wanted."""
        s = np.asarray(s, dtype=complex)
        if self.points + s.size > self.budget:
            raise BudgetExceeded()
        self.calls += 1
        self.points += s.size
        both = None if unscaled else getattr(self.char_fn, "scaled", None)
        value, scale = both(s) if both is not None else (np.asarray(self.char_fn(s)), np.zeros(s.shape))
        value = np.asarray(value)
        if value.shape != s.shape:
            raise ModelError(f"char_fn must return an array of the same shape as s (vectorised); "
                             f"got shape {value.shape} for s of shape {s.shape}")
        return value.astype(complex, copy=False), np.asarray(scale, dtype=float)


class BudgetExceeded(Exception):
    pass


def as_rectangle(re_range: object, im_range: object) -> tuple[float, float, float, float]:
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


def rectangle_corners(rect: tuple[float, float, float, float]) -> np.ndarray:
    a, b, c, d = rect
    return np.array([complex(a, c), complex(b, c), complex(b, d), complex(a, d)])


def rectangle_diagonal(rect: tuple[float, float, float, float]) -> float:
    return math.hypot(rect[1] - rect[0], rect[3] - rect[2])


def inside_rectangle(z: np.ndarray, rect: tuple[float, float, float, float]) -> np.ndarray:
    return (z.real > rect[0]) & (z.real < rect[1]) & (z.imag > rect[2]) & (z.imag < rect[3])


# --------------------------------------------------------------------------------------------
# argument principle, many contours at once
# --------------------------------------------------------------------------------------------
class RectangleContour:
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
        corners = rectangle_corners(rect)
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


def _check_values(c: RectangleContour, s: np.ndarray, v: np.ndarray) -> None:
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


def count_contours(ev: ContourEvaluator, contours: list[RectangleContour], max_log_step: float) -> None:
    """Run the adaptive sampling of all contours together (one batched call per round)."""
    while True:
        active = [c for c in contours if c.result is None and c.error is None]
        if not active:
            return
        chunks = [np.concatenate([c.pending, c.pending + c.delta * c.pending_u])
                  for c in active]
        try:
            values = ev(np.concatenate(chunks))
        except BudgetExceeded:
            for c in active:
                c.error = BudgetExceeded()
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
    rect = as_rectangle(re_range, im_range)
    max_log_step = log_step_option(max_log_step)
    if isinstance(initial_points, bool) or not isinstance(initial_points, (int, np.integer)) \
            or initial_points < 16:
        raise ModelError(f"initial_points must be an int >= 16, got {initial_points!r}")
    if min_step is not None:
        min_step = positive("min_step", min_step)
    ev = ContourEvaluator(char_fn, evaluation_budget(max_evaluations))
    contour = RectangleContour(rect, int(initial_points), min_step)
    count_contours(ev, [contour], max_log_step)
    if isinstance(contour.error, BudgetExceeded):
        steps = _log_steps(contour.values) if contour.values is not None else np.zeros(1)
        winding = float(steps.imag.sum() / (2 * np.pi))
        return RootCount(int(round(winding)), False, winding, complex("nan"),
                         int(contour.s.size - 1), ev.calls)
    if contour.error is not None:
        raise contour.error
    return contour.result


def log_step_option(value: float) -> float:
    value = positive("max_log_step", value)
    if value > 1.5:
        raise ModelError(f"max_log_step must be in (0, 1.5] (phase aliasing), got {value!r}")
    return value


def evaluation_budget(value: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 100:
        raise ModelError(f"max_evaluations must be an int >= 100, got {value!r}")
    return int(value)


