"""Counting the characteristic roots of one loop on a contour, vectorised over parameter sets.

Builds on :class:`ctmm.sweeps.LoopCharacteristic` (``Delta(s; k, tau, w) = D Delta_0 +
k e^{-s tau} sum_j w_j T_j``).  Methods: ``docs/stability.md`` section 4.

:func:`count` applies the argument principle to the rectangle ``[sigma, sigma + R] x [-R, R]``,
using ``Delta(conj s) = conj Delta(s)``: the count is the phase change of ``Delta`` along the
upper half of the boundary divided by ``pi``.  Beyond ``R`` the loop term is smaller than half
the open-loop term (``e^{max(0, -sigma) tau} |L| < 1/2``); ``R`` is proven from a state-space
bound of the loop term when the model has a realisation (:mod:`ctmm.certification`), so on the
far edges ``arg Delta`` is ``arg D Delta_0`` (computed once) plus the principal ``arg(1 + L)``,
and only the line ``Re s = sigma`` has to be sampled for every parameter set.  The line's first
samples include every open-loop resonance and its half-power points.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace
from typing import Sequence

import numpy as np

from . import validation
from .certification import (MAX_EIGEN_STATES, ContourCertificate, Realisation, StabilityWarning, fixed_roots,
                            loop_bound, realise)
from .errors import ModelError, SingularSystemError
from .sweeps import TINY, LoopCharacteristic

__all__ = ["Contour", "build_contour", "contour_height", "count", "fixed_root_note", "listed_roots", "neutral_factor",
           "proven_right"]

_MAX_STEP = 0.4          # largest complex-log step of a component between samples
_COUNT_STEP = 1.0        # largest phase step of Delta(s; p) between samples when counting
_MAX_SAMPLES = 200_000   # largest initial line sampling for a proven contour height
_LINE_LIMIT = 5_000_000   # largest line sampling at all (about 0.2 GB of components)


# --------------------------------------------------------------------------------------------
# sampling the contour
# --------------------------------------------------------------------------------------------
class _Path:
    """Adaptive samples of the components on a polyline ``vertices[0] -> vertices[1] -> ...``."""

    def __init__(self, model: LoopCharacteristic, vertices: Sequence[complex], n_initial: int,
                 rate: float, min_step: float, seeds: Sequence[complex] = ()) -> None:
        self.model, self.rate, self.min_step = model, rate, min_step
        v = np.asarray(vertices, dtype=complex)
        lengths = np.abs(np.diff(v))
        per = np.maximum(8, np.ceil(n_initial * lengths / lengths.sum())).astype(int)
        pts = [v[k] + (v[k + 1] - v[k]) * np.arange(per[k]) / per[k] for k in range(len(v) - 1)]
        self.s = np.append(np.concatenate(pts), v[-1])
        if len(seeds):               # extra samples on a vertical line (open-loop resonances)
            self.s = np.unique(np.concatenate([self.s, np.asarray(seeds, dtype=complex)]).imag) * 1j \
                + v[0].real
        self.delta = 1e-7 * float(lengths.sum())
        self.values, self.logderiv = self._evaluate(self.s)
        self._refine_components()

    def _evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Components at ``s`` and their logarithmic rates along the path (forward difference)."""
        direction = self._direction(s)
        base, terms = self.model.components(np.concatenate([s, s + self.delta * direction]))
        both = np.vstack([base[None, :], terms])
        n = s.size
        v, w = both[:, :n], both[:, n:]
        with np.errstate(all="ignore"):
            rate = np.log(w / v) / self.delta
        rate = np.where(np.isfinite(rate) & (np.abs(v) > TINY), rate, 0.0)
        return v, rate

    def _direction(self, s: np.ndarray) -> np.ndarray:  # unit tangent at each sample
        raise NotImplementedError

    def bad_intervals(self) -> np.ndarray:
        """Intervals where a component turns by more than ``_MAX_STEP`` rad (observed or
        predicted from the rates) or changes its modulus by more than a factor e^1.5."""
        v, rate = self.values, self.logderiv
        h = np.abs(np.diff(self.s))
        big = (np.abs(v[:, 1:]) > TINY) & (np.abs(v[:, :-1]) > TINY)
        with np.errstate(all="ignore"):
            step = np.log(v[:, 1:] / v[:, :-1])
        step = np.where(big & np.isfinite(step), step, 0.0)
        phase_rate = np.maximum(np.abs(rate.imag[:, 1:]), np.abs(rate.imag[:, :-1]))
        modulus_rate = np.maximum(np.abs(rate.real[:, 1:]), np.abs(rate.real[:, :-1]))
        bad = (np.abs(step.imag) > _MAX_STEP) | (h * phase_rate > 2 * _MAX_STEP) | \
            (np.abs(step.real) > 1.5) | (h * modulus_rate > 3.0)
        bad = np.any(bad, axis=0) | (h * self.rate > _MAX_STEP)
        return bad & (h > self.min_step)

    def insert(self, intervals: np.ndarray, *, rates: bool = False) -> None:
        """Add the midpoints of ``intervals`` (with companion points for the rates only when
        ``rates``: they serve the component refinement of the constructor)."""
        if not intervals.any():
            return
        j = np.flatnonzero(intervals)
        mid = 0.5 * (self.s[j] + self.s[j + 1])
        if rates:
            v, g = self._evaluate(mid)
        else:
            base, terms = self.model.components(mid)
            v, g = np.vstack([base[None, :], terms]), np.zeros((1 + terms.shape[0], mid.size), complex)
        self.s = np.insert(self.s, j + 1, mid)
        self.values = np.insert(self.values, j + 1, v, axis=1)
        self.logderiv = np.insert(self.logderiv, j + 1, g, axis=1)

    def _refine_components(self) -> None:
        for _ in range(60):
            bad = self.bad_intervals()
            if not bad.any():
                return
            self.insert(bad, rates=True)

    @property
    def base(self) -> np.ndarray:
        return self.values[0]

    @property
    def terms(self) -> np.ndarray:
        return self.values[1:]


class _VerticalPath(_Path):
    def _direction(self, s: np.ndarray) -> np.ndarray:
        return np.full(s.size, 1j)


class _FarPath(_Path):
    """``sigma + X -> sigma + X + iR -> sigma + iR`` (right edge up, top edge left)."""

    def __init__(self, model, sigma, X, R, n_initial, rate, min_step):
        self._corner = complex(sigma + X, R)
        super().__init__(model, [sigma + X, self._corner, complex(sigma, R)], n_initial, rate,
                         min_step)

    def _direction(self, s: np.ndarray) -> np.ndarray:
        on_top = np.abs(s.imag - self._corner.imag) <= 1e-12 * max(1.0, abs(self._corner))
        return np.where(on_top, -1.0 + 0j, 1j)


@dataclass
class Contour:
    """Everything :func:`count` needs for one line ``Re s = sigma`` and one parameter box."""

    model: LoopCharacteristic
    sigma: float
    radius: float
    line: _VerticalPath            # sigma -> sigma + iR (ascending imaginary part)
    far_phase: float               # phase change of Delta_0 along sigma+R -> sigma+R+iR -> sigma+iR
    notes: list = field(default_factory=list)
    certificate: ContourCertificate | None = None
    fixed: np.ndarray = field(default_factory=lambda: np.zeros(0, complex))   # roots on the line no set moves

    @property
    def omega(self) -> np.ndarray:
        return self.line.s.imag


def _loop_bound(base: np.ndarray, terms: np.ndarray, weight_bound: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (weight_bound[:, None] * np.abs(terms)).sum(0) / np.abs(base)
    return np.where(np.isfinite(ratio), ratio, np.inf)


def _sampled_ratio(model: LoopCharacteristic, weight_bound: np.ndarray, sigma: float, growth: float,
                   low: float, high: float, seeds: Sequence[complex] = ()) -> tuple[np.ndarray, np.ndarray]:
    """``(omega, e^{max(0,-sigma) tau} |L|)`` on ``sigma + i [low, high]``: log-spaced samples
    refined until every component turns by less than ``_MAX_STEP`` between samples."""
    low = max(low, 1e-3)
    decades = max(1, int(math.ceil(math.log10(high / low))))
    vertices = sigma + 1j * np.logspace(math.log10(low), math.log10(high), 4 * decades + 1)
    path = _VerticalPath(model, vertices, 40 * decades, 0.0, 1e-13 * high,
                         [sigma + 1j * w for w in np.asarray(seeds, float) if 0 <= w <= high])
    return path.s.imag, growth * _loop_bound(path.base, path.terms, weight_bound)


def _neutral_error(model: LoopCharacteristic, detail: str) -> ModelError:
    return ModelError(
        f"loop {model.loop.name!r} is neutral or improper: {detail}; such a loop can have infinitely "
        "many roots near a vertical line and no finite contour encloses them all. Pass im_max=<rad/s> "
        "to count roots in a bounded frequency range (the result is then reported as not certified)")


def neutral_factor(model: LoopCharacteristic, weight_bound: np.ndarray) -> float:
    """Factor on the loop's ``|k w_j|`` (``weight_bound``) from which the proven high-frequency limit of
    the loop term reaches 1/2 (a neutral or improper loop, refused without ``im_max``); ``nan`` when the
    model has no realisation to bound, ``inf`` when the loop term decays."""
    try:
        at_infinity = loop_bound(model, weight_bound).at_infinity
    except ModelError:
        return math.nan
    return 0.5 / at_infinity if at_infinity > 0.0 else math.inf


def proven_right(certificate: ContourCertificate | None, re_min: float, re_max: float | None) -> float | None:
    """Right edge [1/s] of a root search right of ``re_min``: the user's ``re_max``, else the proven
    height of the certificate (every root with ``Re s >= re_min`` has ``|s|`` below it), else None
    (a heuristic edge, which can step over a root far to the right)."""
    if re_max is not None or certificate is None or not re_min < certificate.bound < math.inf:
        return re_max
    return float(certificate.bound)


def listed_roots(roots: np.ndarray) -> str:
    """``"0, ±5.81615j, -1±2j"``: roots with ``Im >= 0`` and their conjugates, 6 digits."""
    out = []
    for p in roots:
        tiny = 1e-6 * max(1.0, abs(p))
        re = "" if abs(p.real) <= tiny else f"{p.real:.6g}"
        out.append(re or "0" if abs(p.imag) <= tiny else f"{re}±{p.imag:.6g}j")
    return ", ".join(dict.fromkeys(out))


def fixed_root_note(roots: np.ndarray, sigma: float) -> str:
    """The note that reports roots on ``Re s = sigma`` no gain or delay moves (a marginal system)."""
    return (f"roots on Re s = {sigma:g} that no gain or delay of the loop moves (modes it neither drives nor "
            f"senses: undamped modes or free motions): s = {listed_roots(roots)}; the system is at best "
            "marginally stable for every delay")


def contour_height(model: LoopCharacteristic, weight_bound: np.ndarray, sigma: float, tau_max: float,
            im_max: float | None, *, fixed_on_line: np.ndarray | None = None,
                   realisation: Realisation | None = None) -> tuple[float, np.ndarray, ContourCertificate]:
    """Contour height ``R`` [rad/s], open-loop poles (line seeds) and the certificate of the
    region ``Re s >= sigma, |Im s| <= R`` for a parameter box (:mod:`ctmm.certification`); a
    user ``im_max`` too small for the loop warns (:class:`StabilityWarning`).  ``fixed_on_line``:
    :func:`~ctmm.certification.fixed_roots` ``(model, sigma)`` when the caller has it already (an
    eigenvalue problem of the open loop's realisation); ``realisation``: the model's
    :func:`~ctmm.certification.realise` when the caller has it (built once for the roots and the bound)."""
    growth = math.exp(max(0.0, -sigma) * tau_max)
    if im_max is not None:
        im_max = validation.positive("im_max", im_max)
    notes: list[str] = []
    for line in (sigma, 0.0) if sigma < 0 else (sigma,):
        fixed = fixed_on_line if line == sigma and fixed_on_line is not None else fixed_roots(model, line, realisation)
        if fixed.size:
            notes.append(fixed_root_note(fixed, line) + ("; counts on this line are -1" if line == sigma else ""))
    try:
        bound = loop_bound(model, weight_bound, realisation)
    except ModelError as exc:
        bound, reason = None, str(exc)
    if bound is None:
        notes.append(f"{reason}; no bound on the loop term")
        seeds = np.zeros(0)
        if im_max is not None:
            return im_max, seeds, ContourCertificate(sigma, im_max, "user", math.nan, False, tuple(notes))
        for top in (1e7, 1e6, 1e5, 1e4):      # distributed models may fail to evaluate very high
            try:
                omega, ratio = _sampled_ratio(model, weight_bound, sigma, growth, 1e-3, top)
                break
            except (np.linalg.LinAlgError, SingularSystemError):
                continue
        else:
            raise ModelError(f"loop {model.loop.name!r}: the model cannot be evaluated on Re s = "
                             f"{sigma:.6g} above 1e3 rad/s to find a contour height; pass im_max")
        big = np.flatnonzero(ratio >= 0.5)
        if big.size and omega[big[-1]] >= 0.1 * top:
            raise _neutral_error(model, f"its sampled loop term does not decay (|L| = {ratio[big[-1]]:.3g} "
                                        f"at omega = {omega[big[-1]]:.3g} rad/s)")
        radius = float(max(2.0 * omega[big[-1]], 1e-2)) if big.size else 1e-2
        notes.append(f"height from |L| sampled on Re s = {sigma:.6g} up to {top:.0e} rad/s")
        radius = max(radius, _open_chain_height(model, sigma, notes))
        return radius, seeds, ContourCertificate(sigma, radius, "sampled", math.nan, False, tuple(notes))
    proven = bound.radius(0.5 / growth)
    seeds = bound.poles
    if bound.n_states > MAX_EIGEN_STATES:
        notes.append(f"open-loop poles not computed ({bound.n_states} states > {MAX_EIGEN_STATES}): the "
                     "line samples are not seeded with the resonances, only refined adaptively")
    if not math.isfinite(proven):
        if im_max is None:
            raise _neutral_error(model, f"its loop term tends to {bound.at_infinity * growth:.6g} >= 1/2 at "
                                        "high frequency (direct feedthrough, e.g. acceleration feedback at "
                                        "the actuated mass, or a controller that is not strictly proper)")
        notes.append("neutral loop: the loop term does not decay, roots may exist at any frequency")
    if im_max is None:
        if proven * tau_max / _MAX_STEP <= _MAX_SAMPLES:
            return proven, seeds, ContourCertificate(sigma, proven, "bound", proven, True, tuple(notes))
        omega, ratio = _sampled_ratio(model, weight_bound, sigma, growth, 1e-3, proven, seeds.imag)
        big = np.flatnonzero(ratio >= 0.5)
        radius = float(max(2.0 * omega[big[-1]], 1e-2)) if big.size else 1e-2
        notes.append(f"the proven height {proven:.6g} rad/s would need more than {_MAX_SAMPLES} samples "
                     f"at delay {tau_max:.6g} s; height from |L| sampled up to it (poles as samples)")
        return radius, seeds, ContourCertificate(sigma, radius, "sampled", proven, False, tuple(notes))
    certified = im_max >= proven
    if not certified and math.isfinite(proven):
        # a root beyond im_max needs growth |L| >= 1 there: possible near an open-loop pole of the
        # region (|L| unbounded) or where the sampled line already reaches 1
        reasons = []
        near = seeds[(seeds.real >= sigma) & (np.abs(seeds.imag) > im_max)]
        if near.size:
            reasons.append(f"{near.size} open-loop pole(s) lie in Re s >= {sigma:.6g} beyond it (e.g. "
                           f"{near[np.argmin(np.abs(near.imag))]:.6g})")
        omega, ratio = _sampled_ratio(model, weight_bound, sigma, growth, im_max, proven, seeds.imag)
        beyond = ratio[omega > im_max]
        if beyond.size and beyond.max() >= 1.0:
            reasons.append(f"its loop term reaches {beyond.max():.3g} (>= 1) at omega = "
                           f"{omega[omega > im_max][np.argmax(beyond)]:.6g} rad/s")
        if reasons:
            message = (f"im_max = {im_max:.6g} rad/s is too small for loop {model.loop.name!r}: "
                       f"{'; '.join(reasons)}; roots beyond im_max may be missed; the proven height is "
                       f"{proven:.6g} rad/s (any im_max >= it is certified)")
            warnings.warn(message, StabilityWarning, stacklevel=4)
            notes.append(message)
        else:
            notes.append(f"im_max = {im_max:.6g} rad/s is below the proven height {proven:.6g} rad/s (no "
                         "open-loop pole beyond it, the sampled loop term stays below 1 in between)")
    return im_max, seeds, ContourCertificate(sigma, im_max, "user", proven, certified, tuple(notes))


def _open_chain_height(model: LoopCharacteristic, sigma: float, notes: list[str]) -> float:
    """Height [rad/s] that holds every root of the open chain ``Delta_0`` (this loop removed, the other
    delayed loops closed) right of ``sigma``.  Those roots are poles of the loop term, so ``|L|``
    sampled on the line does not see them; each other delayed loop's own contour height does."""
    system = getattr(model, "system", None)
    others = [lp for lp in getattr(system, "loops", ()) if lp is not model.loop]
    if not any(lp.delay for lp in others):
        return 0.0
    open_chain = type(system)(system.plant, others)
    height = 0.0
    for lp in others:
        if not lp.delay:
            continue
        other = LoopCharacteristic(open_chain, lp.name)
        try:
            radius, _, _ = contour_height(other, np.abs(other.gain * other.weights), sigma, other.delay, None)
        except ModelError as exc:
            notes.append(f"roots of the open chain (loop {model.loop.name!r} removed) not bounded: {exc}")
            continue
        height = max(height, radius)
    if height:
        notes.append(f"height raised to {height:.6g} rad/s to hold the roots of the open chain (loop "
                     f"{model.loop.name!r} removed, delayed loops {', '.join(lp.name for lp in others if lp.delay)} "
                     "closed), which |L| on the line does not see")
    return height


def _line_samples(length: float, tau_max: float, sigma: float) -> float:
    """Samples a contour piece of ``length`` [rad/s] needs at delay ``tau_max`` [s] (the factor
    ``e^(-s tau)`` turns once per ``2 pi / tau``), or a :class:`ModelError` beyond ``_LINE_LIMIT``."""
    needed = length * tau_max / _MAX_STEP
    if needed > _LINE_LIMIT:
        raise ModelError(f"delay {tau_max:.6g} s with a contour {length:.6g} rad/s long (right of Re s = {sigma:g}) "
                         f"would need {needed:.3g} samples (e^(-s tau) turns once per 2 pi / tau rad/s); at most "
                         f"{_LINE_LIMIT:.0e} are allowed: use delays below {_LINE_LIMIT * _MAX_STEP / length:.3g} s "
                         "or a smaller im_max")
    return needed


def build_contour(model: LoopCharacteristic, weight_bound: np.ndarray, tau_max: float, *,
                  sigma: float = 0.0, im_max: float | None = None, resolution: int = 256) -> Contour:
    """The counting contour of a parameter box: height (proven when possible), far-edge phase,
    line samples seeded with the open-loop resonances, and the certificate.

    Parameters
    ----------
    model : LoopCharacteristic
    weight_bound : numpy.ndarray
        Largest ``|k w_j|`` per sensor term over the box (:func:`loop_weight_bound`).
    tau_max : float
        Largest delay of the box [s].
    sigma : float
        Abscissa of the counting line [1/s].
    im_max : float, optional
        User height [rad/s] (default: the proven height, :mod:`ctmm.certification`).
    resolution : int
        Initial number of line samples.
    """
    try:                                              # A, b, C, d and eig(A): once for the roots and the bound
        realisation = realise(model)
    except ModelError:
        realisation = None                            # (the bound names the reason)
    fixed = fixed_roots(model, sigma, realisation)    # for the certificate's notes and the contour
    radius, poles, certificate = contour_height(model, weight_bound, sigma, tau_max, im_max, fixed_on_line=fixed,
                                                realisation=realisation)
    growth = math.exp(max(0.0, -sigma) * tau_max)
    notes = list(certificate.notes)
    for _ in range(8):
        _line_samples(2.0 * radius, tau_max, sigma)
        far = _FarPath(model, sigma, radius, radius, 48, tau_max, 1e-12 * radius)
        ratio = growth * _loop_bound(far.base, far.terms, weight_bound)
        if np.all(ratio < 0.5) or certificate.source != "sampled":
            if not np.all(ratio < 0.5):
                notes.append(f"the loop term is not small on the far contour edges (max ratio "
                             f"{ratio.max():.3g}); roots beyond im_max = {radius:.6g} rad/s may be missed")
            break
        radius *= 2.0
    else:
        raise ModelError(f"no contour height found for loop {model.loop.name!r}: the loop term stays "
                         "large far from the origin; pass im_max")
    if radius != certificate.im_max or notes != list(certificate.notes):
        certificate = replace(certificate, im_max=radius, notes=tuple(notes))
    with np.errstate(all="ignore"):
        steps = np.angle(far.base[1:] / far.base[:-1])
    if not np.all(np.isfinite(steps)):
        raise ModelError("the open-loop characteristic function vanishes on the far contour edge; "
                         "pass a different im_max")
    n0 = max(resolution, int(math.ceil(_line_samples(radius, tau_max, sigma))))
    seeds = _resonance_samples(poles, sigma, radius)
    line = _VerticalPath(model, [complex(sigma, 0.0), complex(sigma, radius)], n0, tau_max,
                         1e-13 * radius, seeds)
    return Contour(model, sigma, radius, line, float(steps.sum()), notes, certificate, fixed)


def _resonance_samples(poles: np.ndarray, sigma: float, radius: float) -> np.ndarray:
    """Samples of ``sigma + i omega`` at each open-loop pole's imaginary part and half-power
    points (distance of the pole to the line) on either side, inside ``[0, radius]``."""
    if poles.size == 0:
        return np.zeros(0, complex)
    width = np.maximum(np.abs(poles.real - sigma), 1e-9 * radius)
    omega = np.concatenate([poles.imag, poles.imag - width, poles.imag + width])
    omega = omega[(omega > 0) & (omega < radius)]
    return sigma + 1j * omega


# --------------------------------------------------------------------------------------------
# counting, vectorised over parameter sets
# --------------------------------------------------------------------------------------------
def _phase_steps(delta: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):
        return np.angle(delta[:, :-1] * np.conj(delta[:, 1:]))    # from sample j+1 down to j


def count(contour: Contour, gain: np.ndarray, delay: np.ndarray, weights: np.ndarray, *,
           chunk: int = 2048, refine: bool = True, rounds: int = 80,
           min_step: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Roots in Re s > sigma for each parameter set: ``(counts, reliable)``.

    Samples are added to the line where a set's phase step exceeds ``_COUNT_STEP`` (sets that
    are resolved keep their count).  ``counts`` is -1 where ``Delta`` vanishes at a sample of the
    line (a root on it), and for every set when the line carries roots no set moves
    (``contour.fixed``, named in ``contour.notes``).  Intervals are not split below ``min_step``
    [rad/s]: sets that need finer samples (a root that close to the line) are returned as not
    reliable."""
    n = gain.size
    counts = np.full(n, -1, dtype=int)
    reliable = np.zeros(n, dtype=bool)
    if contour.fixed.size:           # a root on the line for every set (contour.notes names it)
        return counts, np.ones(n, dtype=bool)
    line = contour.line
    pending = np.arange(n)
    for round_ in range(rounds):
        if pending.size == 0:
            break
        last = round_ == rounds - 1 or not refine
        h = np.diff(line.s.imag)
        refine_here = np.zeros(h.size, bool)
        unresolved = []
        for start in range(0, pending.size, chunk):
            idx = pending[start:start + chunk]
            delta = LoopCharacteristic.combine(line.s, line.base, line.terms, gain[idx], delay[idx],
                                               weights[idx])
            steps = _phase_steps(delta)
            bad = (np.abs(steps) > _COUNT_STEP) & (h > max(line.min_step, min_step))[None, :]
            open_ = bad.any(axis=1) & (not last)
            if open_.any():
                refine_here |= bad[open_].any(axis=0)
                unresolved.append(idx[open_])
            done = ~open_
            d, st = delta[done], steps[done]
            zero = np.any(d == 0, axis=1) | ~np.all(np.isfinite(d), axis=1)
            with np.errstate(all="ignore"):
                top = np.angle(d[:, -1] / line.base[-1])
                total = (contour.far_phase + top + st.sum(axis=1)) / math.pi
            rounded = np.round(np.where(np.isfinite(total), total, 0.0))
            counts[idx[done]] = np.where(zero, -1, rounded.astype(int))
            reliable[idx[done]] = ~zero & (np.abs(total - rounded) < 0.05) & \
                ~np.any(np.abs(st) > _COUNT_STEP, axis=1)
        pending = np.concatenate(unresolved) if unresolved else np.array([], int)
        if pending.size:
            line.insert(refine_here)
    return counts, reliable
