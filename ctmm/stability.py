"""Delay stability of controlled chains: characteristic roots, root counts, margins, simulation check.

Everything here works on the characteristic function ``Delta(s)`` of the transfer-matrix model
(:func:`ctmm.characteristic_function`, exact delays ``e^{-s tau}``).  The loop under study enters
it as an affine term (:class:`ctmm.sweeps.LoopCharacteristic`, eq. (1) there), which turns
counts for many parameter sets, crossing frequencies and margins into array arithmetic on a few
transfer-matrix sweeps.  Charts over two parameters are in :mod:`ctmm.stability_chart` (also
reachable as ``ctmm.stability.stability_chart``); the methods are derived in
``docs/stability.md``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Sequence

import numpy as np

from . import validation
from .control.loops import ControlledChain, Feedback
from .certification import ContourCertificate
from .errors import ModelError, unknown_name
from .roots import RootSet, SpectralAbscissa, rightmost_roots
from .roots import spectral_abscissa as _roots_abscissa
from .counting_contour import Contour, build_contour, contour_height, count
from .sweeps import (TINY, LoopCharacteristic, as_controlled, characteristic_callable, check_parameters, find_loop,
                     loop_weight_bound, n_sets)

__all__ = ["LoopCharacteristic", "characteristic_roots", "spectral_abscissa", "spectral_seeds",
           "unstable_root_count", "RootCounts",
           "DelayMargin", "delay_margin", "GainMargin", "gain_margin", "gain_crossovers", "SimulationCheck",
           "crosscheck_by_simulation", "stability_chart", "StabilityChart", "Boundary"]


def __getattr__(name: str):
    """``stability_chart``, ``StabilityChart`` and ``Boundary`` live in :mod:`ctmm.stability_chart`."""
    if name in ("stability_chart", "StabilityChart", "Boundary"):
        from . import stability_chart as charts

        return getattr(charts, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def unstable_root_count(system: ControlledChain, *, loop: str | None = None, gain: Any = None,
                        delay: Any = None, weights: Any = None, sigma: float = 0.0,
                        im_max: float | None = None) -> np.ndarray:
    """Number of characteristic roots with ``Re s > sigma`` for many parameter sets of one loop.

    Parameters
    ----------
    system : ControlledChain
    loop : str, optional
        The loop whose parameters vary (default: the only loop).
    gain, delay : array_like, optional
        Gain factors ``k`` [-] (the loop gain itself for a static gain) and delays [s] (>= 0),
        broadcast together; default: the loop's current values.
    weights : array_like, optional
        Sensor weights, shape ``(n_sets, n_terms)`` or ``(n_terms,)``.
    sigma : float
        Count roots right of ``Re s = sigma`` [1/s] (0: unstable roots).
    im_max : float, optional
        Imaginary extent [rad/s] of the contour (default: the proven height, module
        :mod:`ctmm.certification`).

    Returns
    -------
    RootCounts
        Integer array of counts (with multiplicity); -1 where a root lies on the line
        ``Re s = sigma``.  ``counts.certificate`` says which region was counted and whether no
        root outside it can exist (:class:`~ctmm.certification.ContourCertificate`); a user
        ``im_max`` below the proven height that lets the loop term reach 1/2 warns
        (:class:`~ctmm.certification.StabilityWarning`).

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Free, Mass
    >>> from ctmm.control import ControlledChain, Feedback
    >>> plant = ctmm.Chain("mass", [Free("a"), Mass("m", 1.0), Free("b")])
    >>> system = ControlledChain(plant, [Feedback("pd", [("m.x", 1.0), ("m.v", 1.0)], "m", gain=1.0)])
    >>> unstable_root_count(system, delay=[0.0, 0.5, 1.5]).tolist()
    [0, 0, 2]
    """
    model = LoopCharacteristic(system, loop)
    n = n_sets(gain, delay, weights)
    k, tau, w = model.parameters(n, None if gain is None else np.ravel(gain),
                                 None if delay is None else np.ravel(delay), weights)
    check_parameters(k, tau, w)
    sigma = validation.finite("sigma", sigma)
    contour = build_contour(model, loop_weight_bound(k, w), float(tau.max()), sigma=sigma, im_max=im_max)
    counts, _ = count(contour, k, tau, w)
    return RootCounts(counts, contour.certificate)


class RootCounts(np.ndarray):
    """Root counts (an integer array) with the :class:`~ctmm.certification.ContourCertificate`
    of the region they cover in its ``certificate`` attribute."""

    certificate: ContourCertificate | None

    def __new__(cls, counts: Any, certificate: ContourCertificate | None = None) -> "RootCounts":
        obj = np.asarray(counts).view(cls)
        obj.certificate = certificate
        return obj

    def __array_finalize__(self, obj: Any) -> None:
        self.certificate = getattr(obj, "certificate", None)



# --------------------------------------------------------------------------------------------
# roots and abscissa
# --------------------------------------------------------------------------------------------
def characteristic_roots(system: Any, *, re_min: float, im_max: float, re_max: float | None = None,
                         seeds: Sequence[complex] | str | None = None, tol: float = 1e-12) -> RootSet:
    """Rightmost characteristic roots of a (controlled) chain, from the TMM ``Delta(s)``.

    Every root with ``re_min < Re s < re_max`` and ``|Im s| <= im_max`` is found once with its
    multiplicity (:func:`ctmm.roots.rightmost_roots`: argument-principle counting, bisection,
    Newton), using the conjugate symmetry of real systems.

    Parameters
    ----------
    system : Chain or ControlledChain
    re_min : float
        Left edge of the search region [1/s] (no root may lie on it).
    im_max : float
        Half height of the region [rad/s].
    re_max : float, optional
        Right edge [1/s]; default chosen by :func:`ctmm.roots.rightmost_roots`.
    seeds : sequence of complex or "spectral", optional
        Approximate roots [1/s] to start Newton from; ``"spectral"``: eigenvalues of a
        Chebyshev collocation of the delay equations of a finite-dimensional realisation
        (:func:`spectral_seeds`; lumped chains with static gains).  Seeds only save work: every
        root is still polished on the TMM ``Delta`` and accounted for by the root count.
    tol : float
        Newton tolerance (relative).

    Returns
    -------
    RootSet
        Sorted by decreasing real part, conjugate pairs exact.

    Examples
    --------
    Delayed velocity feedback on a unit mass, ``s^2 + s e^{-s} = 0`` (root 0 and
    ``s + e^{-s} = 0``: Hayes' equation, rightmost pair ``-0.3181 +- 1.3372i``):

    >>> import ctmm
    >>> from ctmm.elements import Fixed, Spring, Mass, Free
    >>> from ctmm.control import ControlledChain, Feedback
    >>> plant = ctmm.Chain("m", [Fixed("w"), Spring("k", 1.0), Mass("m", 1.0), Free("e")])
    >>> system = ControlledChain(plant, [Feedback("v", "m.v", "m", gain=1.0, delay=1.0)])
    >>> roots = characteristic_roots(system, re_min=-1.0, im_max=7.0, re_max=1.0)
    >>> len(roots) > 0
    True
    """
    re_min = validation.finite("re_min", re_min)
    im_max = validation.positive("im_max", im_max)
    if isinstance(seeds, str):
        if seeds != "spectral":
            raise ModelError(f"seeds must be a sequence of complex numbers or 'spectral', got {seeds!r}")
        seeds = spectral_seeds(system)
        seeds = seeds[(seeds.real > re_min) & (np.abs(seeds.imag) <= im_max)]
    found = rightmost_roots(characteristic_callable(system), im_max=im_max, re_min=re_min, re_max=re_max,
                            seeds=seeds, conjugate_symmetric=True, tol=tol)
    return replace(found, certificate=region_certificate(system, re_min, im_max))


def spectral_seeds(system: Any, *, nodes: int = 24) -> np.ndarray:
    """Approximate characteristic roots from a finite-dimensional realisation, when there is one.

    A lumped chain is realised as ``x' = A x + B u``, ``y = C x`` (:func:`ctmm.interop.to_state_space`,
    loop actuators as inputs, sensed signals as outputs); static-gain loops
    ``u_l = -g_l c_l^T y(t - tau_l)`` make it the delay equation
    ``x' = A x - sum_l g_l B_l c_l^T C x(t - tau_l)``, whose rightmost roots come from Chebyshev
    collocation of its infinitesimal generator (Breda, Maset & Vermiglio 2005).  Returns an empty
    array for systems without such a realisation (beams, LTI controllers, feedthrough from
    acceleration or force sensing).
    """
    from .delay_collocation import generator_eigenvalues
    from .interop import to_state_space

    loops = system.loops if isinstance(system, ControlledChain) else ()
    plant = system.plant if isinstance(system, ControlledChain) else system
    if any(lp.is_lti for lp in loops):
        return np.zeros(0, complex)
    outputs = list(dict.fromkeys(sig for lp in loops for sig, _ in lp.terms))
    inputs = list(dict.fromkeys(f"{lp.actuator}.force" for lp in loops))
    try:
        ss = to_state_space(plant, inputs=inputs or None, outputs=outputs or None)
    except (ModelError, ValueError, TypeError):
        return np.zeros(0, complex)
    A, B, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (ss.A, ss.B, ss.C, ss.D))
    if loops and np.any(D != 0):
        return np.zeros(0, complex)
    delayed: dict[float, np.ndarray] = {}
    A0 = A.copy()
    for lp in loops:
        b = B[:, inputs.index(f"{lp.actuator}.force")]
        c = sum(w * C[outputs.index(sig)] for sig, w in lp.terms)
        term = -float(lp.gain) * np.outer(b, c)
        if lp.delay == 0.0:
            A0 = A0 + term
        else:
            delayed[lp.delay] = delayed.get(lp.delay, 0.0) + term
    roots = generator_eigenvalues(A0, [(m, tau) for tau, m in delayed.items()], nodes)
    roots = roots[np.lexsort((roots.imag, -roots.real))]
    return roots[np.isfinite(roots)]


def spectral_abscissa(system: Any, *, re_min: float, im_max: float, re_max: float | None = None,
                      seeds: Sequence[complex] | None = None, tol: float = 1e-12) -> SpectralAbscissa:
    """Largest real part of the characteristic roots (with an error estimate).

    Parameters as in :func:`characteristic_roots`.  ``result.stable`` is True when every root of
    the region has ``Re s < 0`` (value + error < 0) and the search was reliable.

    Returns
    -------
    SpectralAbscissa
    """
    re_min = validation.finite("re_min", re_min)
    im_max = validation.positive("im_max", im_max)
    found = _roots_abscissa(characteristic_callable(system), im_max=im_max, re_min=re_min, re_max=re_max,
                            seeds=seeds, conjugate_symmetric=True, tol=tol)
    certificate = region_certificate(system, re_min, im_max)
    return replace(found, roots=replace(found.roots, certificate=certificate), certificate=certificate)


def region_certificate(system: Any, re_min: float, im_max: float) -> ContourCertificate | None:
    """Whether ``Re s > re_min, |Im s| <= im_max`` holds every root of a controlled chain with
    one loop (:mod:`ctmm.certification`; warns when ``im_max`` is too small); None for other
    systems."""
    if not isinstance(system, ControlledChain) or len(system.loops) != 1:
        return None
    model = LoopCharacteristic(system)
    k, tau, w = model.parameters(1)
    _, _, certificate = contour_height(model, loop_weight_bound(k, w), re_min, float(tau[0]), im_max)
    return certificate


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
        w_ref, v_ref, e_ref = _illinois(contour, sets0, sets1, r, s.imag[j], s.imag[j + 1],
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


def _illinois(contour: Contour, sets0, sets1, rows, a, b, fa, fb, pa, pb, *, grid=None,
              span: float = 1.0, iterations: int = 60):
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

    omega, pa, pb = bracket_solve(evaluate, a, b, fa, fb, pa, pb,
                                  stop=None if grid is None else decided, iterations=iterations)
    value = np.where(np.isfinite(pa) & np.isfinite(pb), 0.5 * (pa + pb), pb)
    error = np.where(np.isfinite(pa) & np.isfinite(pb), 0.5 * np.abs(pa - pb), 0.0)
    return omega, value, error


def bracket_solve(evaluate, a, b, fa, fb, pa, pb, *, stop=None, iterations: int = 60):
    """Batched Illinois (modified regula falsi) on brackets ``[a, b]`` with ``fa fb < 0``.

    ``evaluate(idx, x) -> (f, p)`` gives the function and a tracked quantity ``p`` at points
    ``x`` of the brackets ``idx`` (one call per iteration for all brackets); ``stop(idx, pa, pb)``
    may end brackets early, once they are narrower than 1e-6 relative.  Returns the last point ``b`` and ``p`` at both bracket ends."""
    a, b, fa, fb = (np.asarray(v, float).copy() for v in (a, b, fa, fb))
    pa, pb = np.asarray(pa, float).copy(), np.asarray(pb, float).copy()
    side = np.zeros(a.size, int)
    active = np.ones(a.size, bool)
    for _ in range(iterations):
        idx = np.flatnonzero(active)
        if idx.size == 0:
            break
        c = b[idx] - fb[idx] * (b[idx] - a[idx]) / (fb[idx] - fa[idx])
        bad = ~np.isfinite(c) | (c <= np.minimum(a[idx], b[idx])) | (c >= np.maximum(a[idx], b[idx]))
        c = np.where(bad, 0.5 * (a[idx] + b[idx]), c)
        fc, pc = evaluate(idx, c)
        same = np.sign(fc) == np.sign(fb[idx])
        i_same, i_diff = idx[same], idx[~same]
        fa[i_same] *= np.where(side[i_same] == 1, 0.5, 1.0)      # Illinois step
        side[i_same] = 1
        a[i_diff], fa[i_diff], pa[i_diff] = b[i_diff], fb[i_diff], pb[i_diff]
        side[i_diff] = 0
        b[idx], fb[idx], pb[idx] = c, fc, pc
        done = (fc == 0) | (np.abs(b[idx] - a[idx]) <= 4e-16 * np.maximum(1.0, np.abs(c)))
        pa[idx[fc == 0]] = pc[fc == 0]
        if stop is not None:
            # the tracked values at the bracket ends enclose the crossing value only where p is
            # monotone on the bracket: stop early only once the bracket is narrow (a wide
            # bracket across a resonance misplaced a chart crossing by 0.013 in gain)
            narrow = np.abs(b[idx] - a[idx]) <= 1e-6 * np.maximum(1.0, np.abs(c))
            done |= stop(idx, pa[idx], pb[idx]) & narrow
        active[idx[done]] = False
    return b, pa, pb


# --------------------------------------------------------------------------------------------
# margins
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DelayMargin:
    """Delays at which roots cross the imaginary axis, for a loop at its current gain.

    With ``L0(s) = k C(s) P(s)`` the delay-free loop transfer function (from eq. (1):
    ``L0 = k sum_j w_j T_j / (D Delta_0)``), ``1 + L0(i Omega) e^{-i Omega tau} = 0`` holds iff
    ``|L0(i Omega)| = 1`` (a gain crossover ``Omega_c``) and
    ``tau = tau_0 + 2 pi j / Omega_c`` with ``tau_0 = (-arg(-1/L0)) mod 2 pi / Omega_c``.  Roots
    cross from left to right as the delay grows where ``|L0|`` decreases through 1 (Cooke and
    van den Driessche 1986).

    Attributes
    ----------
    critical_delay : float
        Smallest delay >= 0 [s] at which a root lies on the imaginary axis (``inf``: none, the
        loop is stable for all delays if it is without delay).
    critical_frequency : float
        Its crossing frequency [rad/s] (``nan`` if none).
    delay : float
        The loop's current delay [s].
    margin : float
        Extra delay [s] the loop tolerates from its current delay (next crossing above the
        current delay minus the current delay); 0 if the current loop is unstable.
    stable : bool
        The loop is stable at its current delay.
    unstable_roots_at_zero_delay : int
        Roots in Re s > 0 without delay.
    crossing_delays, crossing_frequencies : tuple of float
        All crossings up to ``delay_max`` [s], [rad/s], ascending in delay.
    crossing_directions : tuple of int
        +1: a pair moves into the right half plane as the delay grows; -1: out of it.
    stable_intervals : tuple of (float, float)
        Delay intervals of stability within [0, delay_max] [s].
    delay_max : float
        Largest delay listed [s].
    certificate : ContourCertificate
        Frequency range searched for crossovers and counted, and whether it is proven to hold
        every crossover (:mod:`ctmm.certification`).
    """

    critical_delay: float
    critical_frequency: float
    delay: float
    margin: float
    stable: bool
    unstable_roots_at_zero_delay: int
    crossing_delays: tuple
    crossing_frequencies: tuple
    crossing_directions: tuple
    stable_intervals: tuple
    delay_max: float
    certificate: ContourCertificate | None = None

    def as_dict(self) -> dict:
        """Plain ``dict`` (JSON-friendly)."""
        out = {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}
        out["certificate"] = None if self.certificate is None else self.certificate.as_dict()
        return out


def _loop_zero_crossings(contour: Contour, function, rows=None):
    """Brackets and refined roots (omega > 0) of a real function of the line samples.

    ``function(s, base, terms) -> (f, extra)`` for one parameter set; returns (omega, f_a sign)."""
    line = contour.line
    f, _ = function(line.s, line.base, line.terms)
    sign = np.sign(f[1:])
    j = np.flatnonzero(sign[:-1] * sign[1:] < 0) + 1
    if j.size == 0:
        return np.zeros(0), np.zeros(0, int)
    model, sigma = contour.model, contour.sigma

    def evaluate(idx, omega):
        s = sigma + 1j * omega
        base, terms = model.components(s)
        return function(s, base, terms)

    a, b = line.s.imag[j], line.s.imag[j + 1]
    omega, _, _ = bracket_solve(evaluate, a, b, f[j], f[j + 1], np.zeros(j.size), np.zeros(j.size))
    return omega, np.sign(f[j]).astype(int)


def _gain_crossings(model: LoopCharacteristic, contour: Contour) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies Omega > 0 on the contour line with ``|L(i Omega)| = 1`` and the sign of
    ``|L| - 1`` below each."""
    def excess(s, base, terms):          # |k C P|^2 - 1, scaled by |D Delta_0|^2
        loop_term = model.gain * (model.weights @ terms)
        return np.abs(loop_term) ** 2 - np.abs(base) ** 2, np.zeros(np.shape(s))

    return _loop_zero_crossings(contour, excess)


def gain_crossovers(system: ControlledChain, loop: str | None = None, *,
                    im_max: float | None = None) -> tuple[np.ndarray, ContourCertificate]:
    """Every gain crossover ``|L(i Omega)| = 1`` (Omega > 0) of a loop at its current gain.

    Parameters
    ----------
    system : ControlledChain
    loop : str, optional
        Loop name (default: the only loop).
    im_max : float, optional
        Frequency range [rad/s] (default: the proven height of :mod:`ctmm.certification`,
        beyond which ``|L| < 1/2``, so no crossover is left out).

    Returns
    -------
    (numpy.ndarray, ContourCertificate)
        Crossover frequencies [rad/s], ascending, and the certificate of the searched range.
    """
    model = LoopCharacteristic(system, loop)
    contour = build_contour(model, loop_weight_bound(np.array([model.gain]), model.weights[None, :]), model.delay,
                       im_max=im_max)
    omega, _ = _gain_crossings(model, contour)
    return np.sort(omega), contour.certificate


def delay_margin(system: ControlledChain, loop: str | None = None, *, delay_max: float | None = None,
                 im_max: float | None = None) -> DelayMargin:
    """Delay margin of a loop from its exact gain crossovers (no Pade approximation).

    Parameters
    ----------
    system : ControlledChain
    loop : str, optional
        Loop name (default: the only loop).
    delay_max : float, optional
        List crossings up to this delay [s] (default: 4 x the larger of the critical and the
        current delay).
    im_max : float, optional
        Frequency range [rad/s] searched for crossovers (default: where the loop term decays).

    Returns
    -------
    DelayMargin

    Examples
    --------
    Delayed PD on a unit mass, ``s^2 + (1 + s) e^{-s tau}``: the gain crossover is
    ``Omega^2 = (1 + sqrt 5)/2`` and the first crossing ``tau = arctan(Omega)/Omega``:

    >>> import math, ctmm
    >>> from ctmm.elements import Free, Mass
    >>> from ctmm.control import ControlledChain, Feedback
    >>> plant = ctmm.Chain("mass", [Free("a"), Mass("m", 1.0), Free("b")])
    >>> pd = Feedback("pd", [("m.x", 1.0), ("m.v", 1.0)], "m", gain=1.0, delay=0.2)
    >>> dm = delay_margin(ControlledChain(plant, [pd]))
    >>> omega = math.sqrt((1 + math.sqrt(5)) / 2)
    >>> abs(dm.critical_delay - math.atan(omega) / omega) < 1e-12, round(dm.margin, 6)
    (True, 0.511119)
    """
    model = LoopCharacteristic(system, loop)
    k = np.array([model.gain])
    w = model.weights[None, :]
    tau_now = model.delay
    contour = build_contour(model, loop_weight_bound(k, w), max(tau_now, 0.0), im_max=im_max)
    omega_c, sign = _gain_crossings(model, contour)
    taus, omegas, directions = [], [], []
    if omega_c.size:
        base, terms = model.components(1j * omega_c)
        L0 = model.gain * (model.weights @ terms) / base
        tau0 = np.mod(-np.angle(-1.0 / L0), 2 * math.pi) / omega_c
        first = float(np.min(tau0))
        limit = delay_max if delay_max is not None else 4.0 * max(first, tau_now)
        limit = validation.positive("delay_max", limit) if delay_max is not None else limit
        for t0, wc, d in zip(tau0, omega_c, sign):
            for j in range(int(max(0, math.floor((limit - t0) * wc / (2 * math.pi)))) + 1):
                if t0 + 2 * math.pi * j / wc > limit:
                    break
                taus.append(t0 + 2 * math.pi * j / wc)
                omegas.append(float(wc))
                directions.append(int(d))
    else:
        limit = float(delay_max) if delay_max is not None else max(tau_now, 1.0)
    order = np.argsort(taus)
    taus = [float(taus[i]) for i in order]
    omegas = [omegas[i] for i in order]
    directions = [directions[i] for i in order]
    counts, _ = count(contour, np.repeat(k, 2), np.array([0.0, tau_now]), np.repeat(w, 2, axis=0))
    n0, n_now = int(counts[0]), int(counts[1])
    running, intervals, start = n0, [], 0.0 if n0 == 0 else None
    for t_c, d in zip(taus, directions):
        new = running + 2 * d
        if running == 0 and new > 0 and start is not None:
            intervals.append((start, t_c))
            start = None
        if new == 0 and running > 0:
            start = t_c
        running = new
    if start is not None:
        intervals.append((start, limit))
    stable = n_now == 0
    later = [t for t in taus if t > tau_now]
    margin = (later[0] - tau_now if later else math.inf) if stable else 0.0
    return DelayMargin(critical_delay=taus[0] if taus else math.inf,
                       critical_frequency=omegas[0] if omegas else math.nan, delay=tau_now,
                       margin=margin, stable=stable, unstable_roots_at_zero_delay=n0,
                       crossing_delays=tuple(taus), crossing_frequencies=tuple(omegas),
                       crossing_directions=tuple(directions), stable_intervals=tuple(intervals),
                       delay_max=float(limit), certificate=contour.certificate)


@dataclass(frozen=True)
class GainMargin:
    """Factors on a loop's gain at which roots reach the imaginary axis (current delay).

    Attributes
    ----------
    upper : float
        Smallest factor > 1 that puts a root on the imaginary axis (the classical gain margin;
        ``inf`` if none up to ``max_factor``).
    lower : float
        Largest factor < 1 doing so (``-inf`` if none down to ``-max_factor``).
    upper_frequency, lower_frequency : float
        Crossing frequencies [rad/s] (0: a real root at s = 0).
    gain : float
        Current gain factor (the loop gain for a static gain, 1 for an LTI controller).
    stable : bool
        The loop is stable at its current gain; then it stays stable for factors in
        (``lower``, ``upper``).
    crossing_factors, crossing_frequencies : tuple of float
        All crossings with ``|factor| <= max_factor``, ascending.
    stable_intervals : tuple of (float, float)
        Factor intervals of stability within [-max_factor, max_factor].
    max_factor : float
        Largest factor searched.
    certificate : ContourCertificate
        Frequency range searched and whether it is proven complete (:mod:`ctmm.certification`).
    """

    upper: float
    lower: float
    upper_frequency: float
    lower_frequency: float
    gain: float
    stable: bool
    crossing_factors: tuple
    crossing_frequencies: tuple
    stable_intervals: tuple
    max_factor: float
    certificate: ContourCertificate | None = None

    @property
    def upper_db(self) -> float:
        """``20 log10(upper)`` [dB]."""
        return 20.0 * math.log10(self.upper) if self.upper > 0 else math.nan

    def as_dict(self) -> dict:
        """Plain ``dict`` (JSON-friendly)."""
        out = {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}
        out["upper_db"] = self.upper_db
        out["certificate"] = None if self.certificate is None else self.certificate.as_dict()
        return out


def gain_margin(system: ControlledChain, loop: str | None = None, *, max_factor: float = 100.0,
                im_max: float | None = None) -> GainMargin:
    """Gain margins of a loop at its current delay, from exact phase crossovers.

    The gain factor ``f`` multiplies the loop's gain (or its controller ``C(s)``); by eq. (1)
    ``Delta = D Delta_0 + f g e^{-s tau} sum_j w_j T_j`` is affine in ``f``, so a root lies at
    ``s = i Omega`` iff ``f = -D Delta_0 / (g e^{-i Omega tau} sum_j w_j T_j)`` is real.

    Parameters
    ----------
    system : ControlledChain
    loop : str, optional
        Loop name (default: the only loop).
    max_factor : float
        Search factors in ``[-max_factor, max_factor]``.
    im_max : float, optional
        Frequency range of the search [rad/s] (default: from the decay of the loop term).

    Returns
    -------
    GainMargin
    """
    model = LoopCharacteristic(system, loop)
    max_factor = validation.positive("max_factor", max_factor)
    g = model.gain
    if g == 0.0:
        raise ModelError(f"loop {model.loop.name!r} has gain 0: a gain margin (a factor on the gain) "
                         "is undefined; give the loop a non-zero gain")
    w = model.weights[None, :]
    tau = np.array([model.delay])
    contour = build_contour(model, loop_weight_bound(np.array([abs(g) * max_factor]), w), model.delay,
                       im_max=im_max)
    sets0 = (np.array([0.0]), tau, w)
    sets1 = (np.array([g]), tau, w)
    crossings = row_crossings(contour, sets0, sets1, (-max_factor, max_factor), refine_all=True)
    factors = crossings.value + 0.0
    # stability of every interval between crossings: count one factor inside each
    edges = np.concatenate([[-max_factor], factors, [max_factor]])
    probes = 0.5 * (edges[:-1] + edges[1:])
    probes = np.append(probes, 1.0)
    counts, _ = count(contour, g * probes, np.repeat(tau, probes.size), np.repeat(w, probes.size, 0))
    stable = bool(counts[-1] == 0)
    intervals = tuple((float(edges[i]), float(edges[i + 1])) for i in range(probes.size - 1)
                      if counts[i] == 0)
    above = np.flatnonzero(factors > 1.0)
    below = np.flatnonzero(factors < 1.0)
    return GainMargin(upper=float(factors[above[0]]) if above.size else math.inf,
                      lower=float(factors[below[-1]]) if below.size else -math.inf,
                      upper_frequency=float(crossings.omega[above[0]]) if above.size else math.nan,
                      lower_frequency=float(crossings.omega[below[-1]]) if below.size else math.nan,
                      gain=g, stable=stable, crossing_factors=tuple(float(f) for f in factors),
                      crossing_frequencies=tuple(float(o) for o in crossings.omega),
                      stable_intervals=intervals, max_factor=max_factor, certificate=contour.certificate)


# --------------------------------------------------------------------------------------------
# cross-check by simulation
# --------------------------------------------------------------------------------------------
def with_loop_parameters(system: ControlledChain, loop: str | None, parameters: dict) -> ControlledChain:
    """The system with one loop's ``"gain"`` (factor), ``"delay"`` or sensor weights replaced."""
    model_loop = find_loop(system, loop)
    names = ("gain", "delay") + tuple(sig for sig, _ in model_loop.terms)
    if not isinstance(parameters, dict):
        raise ModelError(f"parameters must be a dict {{name: value}}, got {parameters!r}")
    for name in parameters:
        if name not in names:
            raise unknown_name(f"parameter of loop {model_loop.name!r}", name, list(names))
    gain = model_loop.gain
    if "gain" in parameters:
        factor = validation.finite("gain", parameters["gain"])
        gain = factor * model_loop.gain if model_loop.is_lti else factor
    delay = validation.nonnegative("delay", parameters.get("delay", model_loop.delay))
    terms = [(sig, validation.finite(sig, parameters.get(sig, w))) for sig, w in model_loop.terms]
    new = Feedback(model_loop.name, terms, model_loop.actuator, gain=gain, delay=delay)
    return system.with_loops([new if lp is model_loop else lp for lp in system.loops])


def envelope_rate(t: np.ndarray, y: np.ndarray, *, start: float = 0.5) -> float:
    """Growth rate [1/s] of the envelope of ``y(t)``: slope of ``log|y|`` at its peaks after
    ``start * t[-1]`` (least squares), or of ``log|y|`` itself when it has fewer than 3 peaks."""
    t, y = np.asarray(t, float), np.abs(np.asarray(y, float))
    keep = t >= start * t[-1]
    tt, yy = t[keep], y[keep]
    peaks = np.flatnonzero((yy[1:-1] > yy[:-2]) & (yy[1:-1] >= yy[2:])) + 1
    if peaks.size >= 3:
        tt, yy = tt[peaks], yy[peaks]
    positive = yy > 0
    if positive.sum() < 2:
        return -math.inf
    return float(np.polyfit(tt[positive], np.log(yy[positive]), 1)[0])


@dataclass(frozen=True)
class SimulationCheck:
    """Spectral abscissa against the envelope growth rate of a time simulation, per point.

    Attributes
    ----------
    points : tuple of dict
        Loop parameters of each point.
    abscissa : numpy.ndarray
        Spectral abscissa from the characteristic roots [1/s] (an upper bound ``re_min`` when no
        root lies to the right of it).
    rate : numpy.ndarray
        Growth rate of the simulated response's envelope [1/s] (:func:`envelope_rate`).
    predicted_stable, simulated_stable : numpy.ndarray of bool
    agree : bool
        Every point is classified alike.
    """

    points: tuple
    abscissa: np.ndarray
    rate: np.ndarray
    predicted_stable: np.ndarray
    simulated_stable: np.ndarray

    @property
    def agree(self) -> bool:
        return bool(np.all(self.predicted_stable == self.simulated_stable))

    def as_dict(self) -> dict:
        """Plain ``dict`` (JSON-friendly)."""
        return {"points": list(self.points), "abscissa": self.abscissa.tolist(),
                "rate": self.rate.tolist(), "predicted_stable": self.predicted_stable.tolist(),
                "simulated_stable": self.simulated_stable.tolist(), "agree": self.agree}


def crosscheck_by_simulation(system: ControlledChain, points: Sequence[dict], *, t_final: float,
                             dt: float, loop: str | None = None, im_max: float = 50.0,
                             re_min: float = -2.0, x0: dict | None = None,
                             output: str | None = None) -> SimulationCheck:
    """Check stability predictions against DT-TMM simulations with the delayed loop.

    For each point (loop parameters, e.g. ``{"gain": 2.0, "delay": 0.1}``) the spectral
    abscissa is computed from the TMM characteristic roots and the closed loop is simulated by
    :func:`ctmm.control.simulate_controlled` (delayed loop from the stored history) from a small
    initial displacement; the envelope of the loop's sensed value must grow where a root lies in
    the right half plane and decay otherwise, at a rate close to the abscissa.

    Parameters
    ----------
    system : ControlledChain
    points : sequence of dict
        Loop parameters per point (``"gain"``, ``"delay"``, sensor signal weights).
    t_final, dt : float
        Simulation length and step [s] (several periods of the dominant root; dt well below it).
    loop : str, optional
        Loop name (default: the only loop).
    im_max, re_min : float
        Root search region for the abscissa [rad/s], [1/s].
    x0 : dict, optional
        Initial displacements by element (default: 1e-3 on the actuator, or the first point
        element).
    output : str, optional
        Signal whose envelope is measured (default: ``"<loop>.y"``).

    Returns
    -------
    SimulationCheck
    """
    from .control.simulate import simulate_controlled
    from .elements.lumped import PointElement

    system = as_controlled(system, "crosscheck_by_simulation")
    lp = find_loop(system, loop)
    t_final, dt = validation.positive("t_final", t_final), validation.positive("dt", dt)
    if x0 is None:
        element = system.plant.element(lp.actuator)
        if not isinstance(element, PointElement):
            element = next(e for e in system.plant.body if isinstance(e, PointElement))
        x0 = {element.name: 1e-3}
    output = output or f"{lp.name}.y"
    abscissa, rate = [], []
    for params in points:
        sys_p = with_loop_parameters(system, lp.name, params)
        result = spectral_abscissa(sys_p, re_min=re_min, im_max=im_max)
        abscissa.append(result.value)
        sim = simulate_controlled(sys_p, t_final, dt, x0=x0)
        rate.append(envelope_rate(sim.time, sim[output]))
    abscissa, rate = np.array(abscissa), np.array(rate)
    return SimulationCheck(tuple(dict(p) for p in points), abscissa, rate, abscissa < 0, rate < 0)
