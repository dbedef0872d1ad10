"""Delay stability of controlled models: characteristic roots, root counts, margins, simulation check.

Everything here works on the characteristic function ``Delta(s)`` with exact delays ``e^{-s tau}``:
of the transfer-matrix model for chains (:class:`ctmm.sweeps.LoopCharacteristic`), of a linear(ised)
state-space model for ``ctmm.linearize`` results and planar ``ControlledModel`` s
(:mod:`ctmm.state_space_characteristic`).  The loop under study enters it as an affine term, which
turns counts for many parameter sets, crossing frequencies and margins into array arithmetic.
Charts are in :mod:`ctmm.stability_chart` (also ``ctmm.stability.stability_chart``), root counts
in :mod:`ctmm.root_counts`; the methods are derived in ``docs/stability.md``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .control.loops import ControlledChain, Feedback
from .certification import ContourCertificate
from .errors import ModelError, unknown_name
from .roots import RootSet, SpectralAbscissa, rightmost_roots
from .roots import spectral_abscissa as _roots_abscissa
from .counting_contour import Contour, build_contour, contour_height, count, neutral_factor, proven_right
from .parameter_crossings import bracket_solve, delay_intervals, row_crossings
from .root_counts import RootCounts, region_certificate, unstable_root_count
from .stability_chart import Boundary, StabilityChart, stability_chart
from .state_space_characteristic import characteristic_of, is_loop_system, loop_characteristic
from .sweeps import LoopCharacteristic, as_controlled, find_loop, loop_weight_bound

__all__ = ["LoopCharacteristic", "characteristic_roots", "spectral_abscissa", "spectral_seeds",
           "unstable_root_count", "RootCounts",
           "DelayMargin", "delay_margin", "GainMargin", "gain_margin", "gain_crossovers", "SimulationCheck",
           "crosscheck_by_simulation", "stability_chart", "StabilityChart", "Boundary"]

_MAX_CROSSINGS = 1_000_000   # largest number of delay crossings delay_margin lists


# --------------------------------------------------------------------------------------------
# roots and abscissa
# --------------------------------------------------------------------------------------------
def characteristic_roots(system: Any, *, re_min: float, im_max: float, re_max: float | None = None,
                         seeds: Sequence[complex] | str | None = None, tol: float = 1e-12) -> RootSet:
    """Rightmost characteristic roots of a model, from its ``Delta(s)`` (TMM or state space).

    Every root with ``re_min < Re s < re_max`` and ``|Im s| <= im_max`` is found once with its
    multiplicity (:func:`ctmm.roots.rightmost_roots`: argument-principle counting, bisection,
    Newton), using the conjugate symmetry of real systems.

    Parameters
    ----------
    system : Chain, ControlledChain, LinearizedSystem or ControlledModel (one delayed loop)
    re_min : float
        Left edge of the search region [1/s] (no root may lie on it).
    im_max : float
        Half height of the region [rad/s].
    re_max : float, optional
        Right edge [1/s]; default: the certificate's proven height, else :func:`ctmm.roots.rightmost_roots`'s.
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
    certificate = region_certificate(system, re_min, im_max)
    found = rightmost_roots(characteristic_of(system), im_max=im_max, re_min=re_min, re_max=proven_right(
        certificate, re_min, re_max), seeds=seeds, conjugate_symmetric=True, tol=tol)
    return replace(found, certificate=certificate)


def spectral_seeds(system: Any, *, nodes: int = 24) -> np.ndarray:
    """Approximate characteristic roots from a finite-dimensional realisation, when there is one.

    A lumped chain is realised as ``x' = A x + B u``, ``y = C x`` (:func:`ctmm.lumped_realisation.chain_state_space`,
    loop actuators as inputs, sensed signals as outputs); static-gain loops
    ``u_l = -g_l c_l^T y(t - tau_l)`` make it the delay equation
    ``x' = A x - sum_l g_l B_l c_l^T C x(t - tau_l)``, whose rightmost roots come from Chebyshev
    collocation of its infinitesimal generator (Breda, Maset & Vermiglio 2005).  Returns an empty
    array for systems without such a realisation (beams, LTI controllers, feedthrough from
    acceleration or force sensing).
    """
    from .delay_collocation import generator_eigenvalues
    from .lumped_realisation import chain_state_space

    loops = system.loops if isinstance(system, ControlledChain) else ()
    plant = system.plant if isinstance(system, ControlledChain) else system
    if any(lp.is_lti for lp in loops):
        return np.zeros(0, complex)
    outputs = list(dict.fromkeys(sig for lp in loops for sig, _ in lp.terms))
    inputs = list(dict.fromkeys(f"{lp.actuator}.force" for lp in loops))
    try:
        ss = chain_state_space(plant, inputs=inputs or None, outputs=outputs or None)
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
    certificate = region_certificate(system, re_min, im_max)
    found = _roots_abscissa(characteristic_of(system), im_max=im_max, re_min=re_min, re_max=proven_right(
        certificate, re_min, re_max), seeds=seeds, conjugate_symmetric=True, tol=tol)
    return replace(found, roots=replace(found.roots, certificate=certificate), certificate=certificate)


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
        Roots in Re s > 0 without delay (-1: a root on the imaginary axis; certificate.notes names fixed ones).
    crossing_delays, crossing_frequencies : tuple of float
        All crossings up to ``delay_max`` [s], [rad/s], ascending in delay.
    crossing_directions : tuple of int
        +1: a pair moves into the right half plane as the delay grows; -1: out of it.
    stable_intervals : tuple of (float, float)
        Delay intervals of stability within [0, delay_max] [s] (direct counts between crossings if a crossing would take the count below 0; certificate.notes says so).
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
    system : ControlledChain, LinearizedSystem or ControlledModel
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
    model = loop_characteristic(system, loop)
    contour = build_contour(model, loop_weight_bound(np.array([model.gain]), model.weights[None, :]), model.delay,
                       im_max=im_max)
    omega, _ = _gain_crossings(model, contour)
    return np.sort(omega), contour.certificate


def delay_margin(system: ControlledChain, loop: str | None = None, *, delay_max: float | None = None,
                 im_max: float | None = None) -> DelayMargin:
    """Delay margin of a loop from its exact gain crossovers (no Pade approximation).

    Parameters
    ----------
    system : ControlledChain, LinearizedSystem or ControlledModel
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
    model = loop_characteristic(system, loop)
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
        limit = validation.positive("delay_max", delay_max) if delay_max is not None else 4.0 * max(first, tau_now)
        listed = float(np.sum(np.maximum(0.0, limit - tau0) * omega_c / (2 * math.pi)))
        if listed > _MAX_CROSSINGS:
            raise ModelError(f"delay_max={delay_max!r} s would list {listed:.3g} stability crossings (each gain "
                             f"crossover recurs every 2 pi / omega s); at most {_MAX_CROSSINGS:.0e} are allowed: "
                             f"give delay_max <= {first + _MAX_CROSSINGS * 2 * math.pi / omega_c.max():.3g} s")
        for t0, wc, d in zip(tau0, omega_c, sign):
            for j in range(int(max(0, math.floor((limit - t0) * wc / (2 * math.pi)))) + 1):
                if t0 + 2 * math.pi * j / wc > limit:
                    break
                taus.append(t0 + 2 * math.pi * j / wc)
                omegas.append(float(wc))
                directions.append(int(d))
    else:
        tau0, limit = omega_c, float(delay_max) if delay_max is not None else max(tau_now, 1.0)
    order = np.argsort(taus)
    taus = [float(taus[i]) for i in order]
    omegas = [omegas[i] for i in order]
    directions = [directions[i] for i in order]
    counts, _ = count(contour, np.repeat(k, 2), np.array([0.0, tau_now]), np.repeat(w, 2, axis=0))
    n0, n_now = int(counts[0]), int(counts[1])
    intervals, note = delay_intervals(taus, directions, n0, limit, lambda d: count(
        contour, np.repeat(k, d.size), d, np.repeat(w, d.size, axis=0))[0])
    certificate = contour.certificate if note is None else replace(contour.certificate, notes=contour.certificate.notes + (note,))
    stable, period, first = n_now == 0, 2 * math.pi / omega_c, int(np.argmin(tau0)) if tau0.size else None
    later = tau0 + period * np.maximum(0.0, np.floor((tau_now - tau0) / period) + 1.0)   # listed or beyond delay_max
    margin = (float(np.min(later)) - tau_now if later.size else math.inf) if stable else 0.0
    if note is not None:         # the running count failed: the margin from the direct counts only
        margin = min(margin, max([hi - tau_now for lo, hi in intervals if lo <= tau_now <= hi], default=0.0))
    return DelayMargin(critical_delay=float(tau0[first]) if first is not None else math.inf,
                       critical_frequency=float(omega_c[first]) if first is not None else math.nan, delay=tau_now,
                       margin=margin, stable=stable, unstable_roots_at_zero_delay=n0,
                       crossing_delays=tuple(taus), crossing_frequencies=tuple(omegas),
                       crossing_directions=tuple(directions), stable_intervals=tuple(intervals),
                       delay_max=float(limit), certificate=certificate)


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
    system : ControlledChain, LinearizedSystem or ControlledModel
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
    model = loop_characteristic(system, loop)
    max_factor = validation.positive("max_factor", max_factor)
    g = model.gain
    if g == 0.0:
        raise ModelError(f"loop {model.loop.name!r} has gain 0: a gain margin (a factor on the gain) "
                         "is undefined; give the loop a non-zero gain")
    w = model.weights[None, :]
    tau = np.array([model.delay])
    try:
        contour = build_contour(model, loop_weight_bound(np.array([abs(g) * max_factor]), w), model.delay, im_max=im_max)
    except ModelError as exc:    # the box is the gain scaled by max_factor: name it and what is allowed
        limit = neutral_factor(model, loop_weight_bound(np.array([abs(g)]), w))
        limit = f"max_factor < {limit:.6g}" if 0.0 < limit < math.inf else "a smaller max_factor"
        raise ModelError(f"{exc} [gain_margin scales the loop term by factors up to max_factor = {max_factor:g}; "
                         f"{limit} keeps its high-frequency limit below 1/2]") from None
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
    """The system with one loop's ``"gain"`` (factor), ``"delay"``, sensor weights replaced; saturation kept."""
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
    new = Feedback(model_loop.name, terms, model_loop.actuator, gain, delay, model_loop.saturation)
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
    if not isinstance(points, (list, tuple)) or not points or not all(isinstance(p, Mapping) for p in points):
        raise ModelError(f"points must be a non-empty list of mappings such as {{'gain': 2.0, 'delay': 0.1}}, "
                         f"got {points!r}")
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
