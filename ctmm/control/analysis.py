"""Frequency-domain analysis of controlled chains: closed loops, loop transfer functions, margins.

Loop transfer function and sign convention
------------------------------------------
A :class:`~ctmm.control.loops.Feedback` loop applies ``u = -C(s) e^{-s tau} (y - r)`` at its
actuator (negative feedback).  Breaking the loop at the actuator, injecting a force ``u`` there
and reading what the controller sends back gives ``-L(s) u`` with

    L(s) = C(s) e^{-s tau} P_yu(s),

where ``P_yu`` is the response of the loop's sensed value ``y`` to a unit actuator force with
*this* loop removed and every other loop of the system closed.  The closed-loop characteristic
equation of the loop is ``1 + L(s) = 0``, so with the usual Nyquist criterion the closed loop is
stable iff the Nyquist curve of ``L`` (``omega`` from ``-inf`` to ``inf``) encircles ``-1``
counter-clockwise as many times as ``L`` has right-half-plane poles -- in particular, for a
stable ``P_yu`` (a damped chain with stable other loops) and a stable ``C``: iff it does **not**
encircle ``-1``.

Margins (:func:`margins`): gain margin ``1/|L(i w_pc)|`` at the phase crossovers
(``L`` real negative), phase margin ``180 deg + arg L(i w_gc)`` at the gain crossovers
(``|L| = 1``), and the **delay margin** -- the smallest extra loop delay that puts ``L`` on
``-1`` -- ``min_gc PM_gc / w_gc`` (``PM`` in rad, taken in ``[0, 2 pi)``).  python-control's
``stability_margins`` on the FRD of a dense grid locates the crossovers; each is then refined
by the Illinois method (:mod:`ctmm.roots1d`) on the exact TMM ``L(i w)`` (no interpolation error left).

Bode and Nyquist plots of these responses: :mod:`ctmm.control.loop_plots`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np
from scipy.optimize import minimize_scalar

from .. import validation
from ..controlled_linearization import FrequencyAtPoleError, delayed_loop_response_function
from ..errors import ModelError, SingularSystemError
from ..frequency import frequency_response
from ..results import FrequencyResponse
from ..roots1d import refine_sign_change
from ..saturation import refuse_saturation
from ..system import Chain
from .controlled_model import ControlledModel
from .loops import ControlledChain, actuator_inputs

__all__ = ["closed_loop_response", "loop_transfer_function", "open_loop_plant", "actuator_inputs", "Margins",
           "margins", "encirclements"]


def _omega(omega: Any) -> np.ndarray:
    return validation.frequencies("omega", omega)


def closed_loop_response(system: Any, omega: Any, inputs: str | Sequence[str],
                         outputs: str | Sequence[str]) -> FrequencyResponse:
    """Closed-loop frequency response of a (controlled) chain (thin wrapper of
    :func:`ctmm.frequency_response`).

    Parameters
    ----------
    system : Chain or ControlledChain
    omega : array_like
        Angular frequencies [rad/s].
    inputs, outputs : str or sequence of str
        Input names (``"m4.force"``, ``"<loop>.reference"``) and output signal names
        (``"m2.x"``, ``"<loop>.u"``, ...).
    """
    return frequency_response(system, omega, input=inputs, output=outputs)


def open_loop_plant(system: ControlledChain | ControlledModel, loop: str, omega: Any, *,
                    fields: str | None = None) -> np.ndarray:
    """``P_yu(i omega)``: sensed value of ``loop`` per unit force of its actuator, with this loop
    removed and all other loops closed [sensed unit / N].  A planar model (:class:`ControlledModel`)
    is linearised about its operating point (:func:`ctmm.linearize`), or with ``fields="exact"``
    answered by exact beam fields (:mod:`ctmm.exact_fields`); delays stay exact."""
    return _open_loop_plant_function(system, loop, fields)(_omega(omega))


def _open_loop_plant_function(system: ControlledChain | ControlledModel, loop: str,
                              fields: str | None) -> Callable[[np.ndarray], np.ndarray]:
    """``omega [rad/s] (validated array) -> P_yu(i omega)`` of :func:`open_loop_plant`; a planar or spatial model
    (``fields`` ``None`` / ``"modal"``) is linearised once, at the first call, and that answers every call
    (:func:`ctmm.frequency_response`'s numbers); a planar model with exact fields builds its exact form once
    (:class:`ctmm.exact_fields.ExactResponse`); chains answer each call afresh."""
    if not isinstance(system, (ControlledChain, ControlledModel)):
        raise ModelError(f"a loop transfer function needs a ControlledChain or a ControlledModel, got {system!r}")
    lp = system.loop(loop)
    refuse_saturation(system.loops, "a loop transfer function")
    others = [other for other in system.loops if other.name != lp.name]
    open_system = system.with_loops(others) if others else system.plant
    signals = list(dict.fromkeys(sig for sig, _ in lp.terms))
    actuators = (actuator_inputs(system, loop) if isinstance(system, ControlledChain)
                 else [(name, float(weight)) for name, weight in lp.actuator_terms])
    inputs = list(dict.fromkeys(a for a, _ in actuators))
    if fields is not None and not isinstance(system, ControlledModel):
        raise ModelError(f"fields={fields!r} applies to planar models (ControlledModel), not to {type(system).__name__}")
    options = {} if fields is None else {"fields": fields}
    modal = isinstance(system, ControlledModel) and validation.option("fields", fields or "modal",
                                                                      ("modal", "exact")) == "modal"
    from ..planar_frequency import PlanarResponse, is_planar_system
    exact = None
    if modal:                                   # one linearisation (at the first call) answers every call
        from ..linearize import linearize
        respond = PlanarResponse(open_system, inputs, signals) if is_planar_system(open_system) else \
            delayed_loop_response_function(lambda into, out: linearize(open_system, inputs=into, outputs=out),
                                           getattr(open_system, "loops", ()), inputs, signals,
                                           getattr(open_system, "plant", open_system).name)
    elif fields is not None and is_planar_system(open_system):   # exact fields: one form answers every call
        from ..exact_fields import ExactResponse
        exact = ExactResponse(open_system, inputs, signals)

    def plant(w: np.ndarray) -> np.ndarray:
        if modal:
            frf = FrequencyResponse(w, respond(1j * w), tuple(inputs), tuple(signals), "P")
        elif exact is not None:
            frf = FrequencyResponse(w, exact(validation.frequencies("omega", w)), tuple(inputs), tuple(signals), "P")
        else:
            frf = frequency_response(open_system, w, input=inputs, output=signals, **options)
        P = np.zeros(w.size, dtype=complex)
        for inp, a_weight in actuators:
            for sig, weight in lp.terms:
                P = P + a_weight * weight * frf(sig, inp)
        return P
    return plant


def loop_transfer_function(system: ControlledChain | ControlledModel, loop: str, omega: Any, *,
                           fields: str | None = None) -> FrequencyResponse:
    """Open loop ``L(i omega) = C(i omega) e^{-i omega tau} P_yu(i omega)`` broken at the actuator.

    Parameters
    ----------
    system : ControlledChain or ControlledModel
    loop : str
        Loop name.
    omega : array_like
        Angular frequencies [rad/s].

    Returns
    -------
    FrequencyResponse
        Input ``"<loop>.u"``, output ``"<loop>.L"`` (dimensionless); negative feedback: the
        closed loop is stable iff the Nyquist curve of ``L`` does not encircle ``-1`` (for
        stable ``P_yu`` and ``C``; see the module docstring).

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Fixed, Damper, Mass, Free
    >>> from ctmm.control import Feedback, ControlledChain
    >>> plant = ctmm.Chain("lag", [Fixed("wall"), Damper("c", 1.0), Mass("m", 1.0), Free("end")])
    >>> system = ControlledChain(plant, [Feedback("speed", "m.v", "m", gain=2.0)])
    >>> L = loop_transfer_function(system, "speed", [1.0])
    >>> complex(np.round(L("speed.L")[0], 12))       # 2 / (i + 1)
    (1-1j)
    """
    w = _omega(omega)
    P = open_loop_plant(system, loop, w, fields=fields)
    lp = system.loop(loop)
    L = lp.loop_gain(1j * w) * P
    return FrequencyResponse(w, L[None, None, :], (f"{lp.name}.u",), (f"{lp.name}.L",),
                             f"L_{lp.name}")


# ------------------------------------------------------------------------------- margins
@dataclass(frozen=True)
class Margins:
    """Stability margins of a loop transfer function ``L`` (negative feedback).

    Attributes
    ----------
    gain_margin : float
        ``1/|L(i w_pc)|`` over the phase crossovers, the one closest to 1 in log scale
        (python-control's choice; ``inf`` if none) [-].
    phase_margin : float
        ``180 + arg L(i w_gc)`` in ``[-180, 180)`` over the gain crossovers, the one smallest in
        magnitude (``inf`` if none) [deg].
    delay_margin : float
        Smallest extra delay that destabilises: ``min (PM_gc mod 360 deg) [rad] / w_gc`` [s] (``inf`` if
        no gain crossover; python-control's and MATLAB's convention).  With a negative phase margin the
        closed loop may already be unstable, and this number is then the delay that turns that
        crossover's phase by the rest of a whole turn, not a delay the loop tolerates: ``notes`` says
        so, and :func:`ctmm.stability.delay_margin` (the characteristic roots) decides.
    gain_crossover_frequency, phase_crossover_frequency : float
        Frequencies [rad/s] of the returned phase and gain margins (``nan`` if none).
    delay_crossover_frequency : float
        Gain crossover [rad/s] that sets the delay margin.
    stability_margin : float
        ``min |1 + L|`` on the grid (refined) [-]; ``stability_margin_frequency`` [rad/s].
    gain_crossovers, phase_margins, phase_crossovers, gain_margins, delay_margins : tuple
        All crossovers found, ascending, with their margins.
    notes : tuple of str
        Crossovers the grid missed and that were added from the certified search, or why no
        certified search was possible.
    certificate : ContourCertificate or None
        Frequency range of the certified gain-crossover search (controlled chains;
        :mod:`ctmm.certification`).
    """

    gain_margin: float
    phase_margin: float
    delay_margin: float
    gain_crossover_frequency: float
    phase_crossover_frequency: float
    delay_crossover_frequency: float
    stability_margin: float
    stability_margin_frequency: float
    gain_crossovers: tuple = field(default=())
    phase_margins: tuple = field(default=())
    phase_crossovers: tuple = field(default=())
    gain_margins: tuple = field(default=())
    delay_margins: tuple = field(default=())
    notes: tuple = field(default=())
    certificate: Any = None

    def as_dict(self) -> dict:
        """Plain ``dict`` (JSON-friendly, tuples as lists)."""
        out = {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}
        out["certificate"] = None if self.certificate is None else self.certificate.as_dict()
        return out


def _certified_crossovers(system: ControlledChain | ControlledModel, loop: str) -> tuple[list, list, Any, list]:
    """Gain and phase crossovers [rad/s] of a controlled chain's (or linearised model's) loop from the certified
    contour search of :mod:`ctmm.stability` (phase crossovers: gain factors in (0, 100], at omega = 0 too: a real
    root through s = 0, as python-control's margins count it)."""
    from ..stability import gain_crossovers, gain_margin

    try:
        gc, certificate = gain_crossovers(system, loop)
        factors = gain_margin(system, loop)
    except ModelError as exc:
        return [], [], None, [f"crossovers not certified (only the grid was searched): {exc}"]
    pc = [w for f, w in zip(factors.crossing_factors, factors.crossing_frequencies) if f > 0 and w >= 0]
    return [float(x) for x in gc], pc, certificate, []


def _refine(fun: Callable[[float], float], w: np.ndarray, w_est: float) -> float:
    """Root of ``fun`` near ``w_est`` [rad/s] to 1e-14 relative in a grid bracket
    (:func:`ctmm.roots1d.refine_sign_change`), or ``w_est`` itself when no bracket changes sign."""
    k = int(np.clip(np.searchsorted(w, w_est), 1, w.size - 1))
    for lo, hi in ((k - 1, k), (max(k - 2, 0), min(k + 1, w.size - 1)), (max(k - 3, 0), min(k + 2, w.size - 1))):
        a, b = float(w[lo]), float(w[hi])
        fa, fb = fun(a), fun(b)
        if fa == 0.0:
            return a
        if fb == 0.0:
            return b
        if np.isfinite(fa) and np.isfinite(fb) and fa * fb < 0:
            lo_end, up_end = np.array([a]), np.array([b])
            refine_sign_change(lambda x, active: np.array([fun(float(v)) for v in x]), lo_end, up_end,
                               np.array([fa]), np.array([fb]), 1e-14)
            return float(0.5 * (lo_end[0] + up_end[0]))
    return float(w_est)


def _grid_roots(values: np.ndarray, w: np.ndarray, keep: np.ndarray | None = None) -> list[float]:
    """Linear-interpolation estimates of the sign changes of ``values`` on the grid."""
    roots = []
    for k in range(w.size - 1):
        a, b = values[k], values[k + 1]
        if a == 0.0 and (keep is None or keep[k]):
            roots.append(float(w[k]))
        elif a * b < 0 and (keep is None or keep[k] or keep[k + 1]):
            roots.append(float(w[k] - a * (w[k + 1] - w[k]) / (b - a)))
    return roots


_AT_POLE = (FrequencyAtPoleError, SingularSystemError)      # a chain refuses a pole as a singular boundary problem


def _value_or_none(evaluate: Callable[[float], complex], x: float) -> complex | None:
    """``evaluate(x)``, or ``None`` at an undamped pole of the plant (refused there)."""
    try:
        return evaluate(x)
    except _AT_POLE:
        return None


def _dedupe(values: Sequence[float], tol: float = 1e-9) -> list[float]:
    out: list[float] = []
    for v in sorted(values):
        if not out or abs(v - out[-1]) > tol * max(1.0, abs(v)):
            out.append(v)
    return out


def margins(source: Any, loop: str | None = None, omega: Any = None, *, fields: str | None = None) -> Margins:
    """Gain, phase, stability and delay margins of a loop.

    Parameters
    ----------
    source : ControlledChain or ControlledModel or FrequencyResponse or control.FrequencyResponseData
        A controlled chain or planar model (with ``loop`` and ``omega``: ``L`` is computed by
        :func:`loop_transfer_function` and crossovers are refined on the exact ``L``), or a SISO
        loop transfer function given as data (refinement then interpolates the data, so use a
        dense grid).
    loop : str, optional
        Loop name (with a controlled chain).
    omega : array_like, optional
        Dense frequency grid [rad/s] covering all crossovers (with a controlled chain).
    fields : {"modal", "exact"}, optional
        Planar models: ``"exact"`` computes ``L`` from exact beam fields (:mod:`ctmm.exact_fields`);
        the certified crossover search then does not apply (it works on the linearisation) and the
        crossovers come from the grid, refined on the exact ``L``.

    Returns
    -------
    Margins

    Notes
    -----
    The crossovers are located with :func:`control.stability_margins` on the FRD (``returnall``)
    and, as a safeguard, by sign changes on the grid; each is refined by the Illinois method
    (:mod:`ctmm.roots1d`).  For a controlled chain the gain crossovers (and the phase crossovers
    with a gain margin up to 100) also come from the certified contour search of :func:`ctmm.stability.gain_crossovers`
    and :func:`ctmm.stability.gain_margin`; crossovers the grid missed (narrow resonances, or
    outside it) are added and listed in ``notes``.  For FRD data only crossovers inside the
    grid are found.
    """
    import control

    at_poles: list[float] = []
    if isinstance(source, (ControlledChain, ControlledModel)):
        if loop is None or omega is None:
            raise ModelError(f"margins(system, loop, omega): give the loop name and a frequency grid [rad/s] "
                             f"(loops: {[lp.name for lp in source.loops]}), got loop={loop!r}, omega={omega!r:.80}")
        w = _omega(omega)
        lp = source.loop(loop)
        plant = _open_loop_plant_function(source, loop, fields)     # planar / spatial: linearised once per call

        def evaluate(x: float) -> complex:
            x_array = _omega([x])
            return complex((lp.loop_gain(1j * x_array) * plant(x_array))[0])
        try:
            L = lp.loop_gain(1j * w) * plant(w)
        except _AT_POLE:                # grid points at an undamped pole of the plant: left out, noted below
            values = [_value_or_none(evaluate, x) for x in w]
            at_poles = [float(x) for x, value in zip(w, values) if value is None]
            w, L = np.array([x for x in w if x not in at_poles]), np.array([v for v in values if v is not None])
    else:
        if isinstance(source, Chain):
            raise ModelError(f"margins needs a ControlledChain with loop {loop!r}, got the plain Chain "
                             f"{source.name!r}; close it with ctmm.control.ControlledChain(plant, [Feedback(...)])")
        if fields is not None:
            raise ModelError(f"fields={fields!r} applies to a ControlledModel, not to a loop transfer function "
                             "given as data")
        if loop is not None or omega is not None:
            raise ModelError(f"margins(system, loop, omega) needs a ControlledChain, got {type(source).__name__} "
                             f"({source!r:.80}); a ControlledModel is accepted too (ctmm.control.with_feedback), and a "
                             "loop transfer function given as data takes no loop/omega (they come with the data)")
        if isinstance(source, FrequencyResponse):
            if source.response.shape[:2] != (1, 1):
                raise ModelError("margins needs a SISO loop transfer function")
            w, L = np.asarray(source.omega, float), source.response[0, 0]
        elif isinstance(source, control.FrequencyResponseData):
            if source.ninputs != 1 or source.noutputs != 1:
                raise ModelError("margins needs a SISO loop transfer function")
            w = np.asarray(source.omega, float)
            L = np.asarray(source.frequency_response(w).complex, complex).reshape(-1)
        else:
            raise ModelError(f"margins needs a ControlledChain, ControlledModel, FrequencyResponse or FRD, "
                             f"got {source!r:.80}")
        w, first = np.unique(w, return_index=True)      # the spline below needs ascending, distinct frequencies
        L = L[first]
        frd_smooth = control.frd(L, w, smooth=True)

        def evaluate(x: float) -> complex:
            return complex(np.asarray(frd_smooth(1j * x)).reshape(-1)[0])
    order = np.argsort(w)
    w, L = w[order], L[order]
    if w.size < 4:
        raise ModelError(f"margins needs a frequency grid (omega) with at least 4 points, got {w.size}: {w.tolist()}")
    pos = w > 0
    wg, Lg = w[pos], L[pos]
    # python-control first (crossover estimates on the smoothed FRD), grid sign changes second
    # (python-control interpolates the FRD point by point with splines: give it at most ~1000
    # points; its crossovers are only estimates, refined below, and the grid scan covers the rest)
    pick = np.unique(np.linspace(0, wg.size - 1, min(wg.size, 1000)).round().astype(int))
    with np.errstate(all="ignore"):
        try:
            gm_pc, pm_pc, sm_pc, wpc_pc, wgc_pc, wms_pc = control.stability_margins(
                control.frd(Lg[pick], wg[pick]), returnall=True)
        except Exception:  # noqa: BLE001 - fall back on the grid estimates
            wpc_pc, wgc_pc = [], []
    wpc_pc = [float(x) for x in np.atleast_1d(wpc_pc) if np.isfinite(x) and wg[0] <= x <= wg[-1]]
    wgc_pc = [float(x) for x in np.atleast_1d(wgc_pc) if np.isfinite(x) and wg[0] <= x <= wg[-1]]
    mag1 = np.abs(Lg) - 1.0
    gc_est = wgc_pc + _grid_roots(mag1, wg)
    pc_est = wpc_pc + _grid_roots(np.imag(Lg), wg, keep=np.real(Lg) < 0)

    def f_mag(x: float) -> float:
        return abs(evaluate(x)) - 1.0

    def f_imag(x: float) -> float:
        return evaluate(x).imag

    def at(x: float) -> complex | None:
        """``L(i x)``, or ``None`` at an undamped pole of the plant (refused there: no crossing)."""
        return _value_or_none(evaluate, x)

    def crossings(fun: Callable[[float], float], estimates: list[float]) -> list[float]:
        found = []
        for x in estimates:
            try:
                found.append(_refine(fun, wg, x))
            except _AT_POLE:                    # L changes sign through infinity at an undamped pole: no crossing
                continue
        return _dedupe(found)

    gcs, pcs = crossings(f_mag, gc_est), crossings(f_imag, pc_est)
    notes: list[str] = []
    certificate = None
    if fields == "exact":
        notes.append("exact beam fields: crossovers located on the grid and refined on the exact L; the certified "
                      "search works on the linearisation and is not applied")
    elif isinstance(source, (ControlledChain, ControlledModel)):
        gc_cert, pc_cert, certificate, notes = _certified_crossovers(source, lp.name)
        for kind, found, exact in (("gain", gcs, gc_cert), ("phase", pcs, pc_cert)):
            for x in exact:
                if at(x) is None:           # a pole of the plant on the imaginary axis, not a crossover
                    continue
                if not any(abs(x - y) <= 1e-7 * max(1.0, x) for y in found):
                    where = "between the samples of" if wg[0] <= x <= wg[-1] else "outside"
                    notes.append(f"{kind} crossover at {x:.6g} rad/s {where} the grid: added from the "
                                 "certified search")
                    found.append(x)
        gcs, pcs = sorted(gcs), sorted(pcs)
        if at_poles:
            notes.append(f"grid frequencies {at_poles[:5]} rad/s at poles of the plant left out (L is unbounded there)")
        if isinstance(source, ControlledModel):
            from ..spatial.model import SpatialModel

            kind = "spatial" if isinstance(source.plant, SpatialModel) else "planar"
            notes.append(f"{kind} model: L is that of the linearisation about the operating point")
        if certificate is not None and (wg[0] > 0.0 or wg[-1] < certificate.im_max):
            notes.append(f"stability_margin (min |1 + L|) searched on the grid only, [{wg[0]:.6g}, "
                         f"{wg[-1]:.6g}] rad/s")
    values = {x: at(x) for x in gcs + pcs}
    gcs = [x for x in gcs if values[x] is not None and abs(abs(values[x]) - 1.0) < 1e-6]
    pcs = [x for x in pcs if values[x] is not None and values[x].real < 0
           and abs(values[x].imag) < 1e-6 * max(1.0, abs(values[x]))]
    pms = []
    dms = []
    for x in gcs:
        pm = 180.0 + math.degrees(np.angle(evaluate(x)))
        pm = (pm + 180.0) % 360.0 - 180.0  # in [-180, 180)
        pms.append(pm)
        dms.append(math.radians(pm % 360.0) / x)
    gms = [1.0 / abs(evaluate(x)) for x in pcs]
    notes.extend(f"negative phase margin {pm:.4g} deg at the gain crossover {x:.6g} rad/s: the closed loop may "
                 f"already be unstable; delay_margin there, (PM mod 360 deg) / w = {dm:.4g} s, is then not a delay "
                 "the loop tolerates (ctmm.stability.delay_margin and unstable_root_count decide from the roots)"
                 for x, pm, dm in zip(gcs, pms, dms) if pm < 0.0)
    # stability margin: min |1 + L| on the grid, refined by a bounded scalar search
    dist = np.abs(1.0 + Lg)
    k = int(np.argmin(dist))
    lo, hi = wg[max(k - 1, 0)], wg[min(k + 1, wg.size - 1)]
    if hi > lo:
        res = minimize_scalar(lambda x: abs(1.0 + evaluate(x)), bounds=(lo, hi), method="bounded",
                              options={"xatol": 1e-12 * hi})
        sm, wsm = (float(res.fun), float(res.x)) if res.fun <= dist[k] else (float(dist[k]), float(wg[k]))
    else:
        sm, wsm = float(dist[k]), float(wg[k])
    i_pm = int(np.argmin(np.abs(pms))) if pms else None
    i_gm = int(np.argmin(np.abs(np.log(gms)))) if gms else None
    i_dm = int(np.argmin(dms)) if dms else None
    return Margins(
        gain_margin=gms[i_gm] if i_gm is not None else math.inf,
        phase_margin=pms[i_pm] if i_pm is not None else math.inf,
        delay_margin=dms[i_dm] if i_dm is not None else math.inf,
        gain_crossover_frequency=gcs[i_pm] if i_pm is not None else math.nan,
        phase_crossover_frequency=pcs[i_gm] if i_gm is not None else math.nan,
        delay_crossover_frequency=gcs[i_dm] if i_dm is not None else math.nan,
        stability_margin=sm, stability_margin_frequency=wsm,
        gain_crossovers=tuple(gcs), phase_margins=tuple(pms), phase_crossovers=tuple(pcs),
        gain_margins=tuple(gms), delay_margins=tuple(dms), notes=tuple(notes), certificate=certificate)


def encirclements(loop_transfer: FrequencyResponse) -> int:
    """Net counter-clockwise encirclements of ``-1`` by the Nyquist curve of ``L``.

    ``L`` is given on ``omega`` from (near) 0 to a frequency where ``|L|`` has become small;
    the negative-frequency branch is the complex conjugate, so the winding number of ``1 + L``
    over ``(-inf, inf)`` is ``Delta arg(1 + L) / pi`` over the grid.  With ``P`` open-loop poles in
    the right half plane the closed loop is stable iff the result equals ``P`` (0 for a damped
    chain and stable controllers).  The grid must resolve the phase of ``1 + L`` (no jump of more
    than pi between neighbours).
    """
    if not isinstance(loop_transfer, FrequencyResponse) or loop_transfer.response.shape[:2] != (1, 1):
        raise ModelError("encirclements needs a SISO FrequencyResponse (e.g. from loop_transfer_function)")
    w = np.asarray(loop_transfer.omega, float)
    if np.any(np.diff(w) <= 0):
        raise ModelError("encirclements needs an increasing frequency grid")
    phase = np.unwrap(np.angle(1.0 + loop_transfer.response[0, 0]))
    return int(round((phase[-1] - phase[0]) / np.pi))
