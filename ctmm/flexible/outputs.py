"""Beam outputs of simulations and the divergence check of the integrators."""
from __future__ import annotations

import math

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from ..guard import RK4_LIMIT
from ..planar.guards import linearised_omega_max


def _coordinates(model, q) -> np.ndarray:
    """``q`` (one state or a history, last axis = coordinates) as floats, else ModelError."""
    array = np.asarray(q, dtype=float)
    if array.ndim not in (1, 2) or array.shape[-1] != model.n_coordinates:
        raise ModelError(f"q must have {model.n_coordinates} coordinates ({', '.join(model.coordinates)}) on its last "
                         f"axis, got shape {array.shape}")
    return array


def _modal_beam_index(model, beam: str) -> int:
    """Body index of the modal beam called ``beam``, else ModelError listing the modal beams."""
    beams = getattr(model, "beams", None)
    if not isinstance(beams, dict) or not callable(getattr(model, "body_index", None)):
        raise ModelError(f"model must be a PlanarModel with modal beams, got {model!r}")
    names = [b.name for b in beams.values()]
    if not isinstance(beam, str) or beam not in names:
        raise ModelError(f"beam must name a modal beam (ModalBeam) of the model, got {beam!r}; modal beams: "
                         f"{', '.join(names) or '(none)'}")
    return model.body_index(beam)


def tip_deflection(model, q, beam: str) -> np.ndarray:
    """Transverse tip deflection ``phi(L) . q`` [m] of ``beam`` in its floating frame, for one
    state ``q`` or a history ``(n_times, n_coordinates)``."""
    j = _modal_beam_index(model, beam)
    d = model.beams[j].data
    q = _coordinates(model, q)
    return q[..., model.modal_index[j][:d.nq]] @ d.tip_phi


def axial_tip_displacement(model, q, beam: str) -> np.ndarray:
    """Axial tip displacement ``psi(L) . p - 1/2 int_0^L (phi' . q)^2 dx`` [m]: elastic stretch
    plus the second-order foreshortening of the bent axis (post-processed, not in the state); a float
    for one state ``q``, an array ``(n_times,)`` for a history, as :func:`tip_deflection`."""
    j = _modal_beam_index(model, beam)
    b = model.beams[j]
    d = b.data
    q = _coordinates(model, q)
    single, q = q.ndim == 1, np.atleast_2d(q)
    idx = model.modal_index[j]
    from .modes import gauss_points
    x, w = gauss_points(b.quadrature, b.length)     # the beam's own rule, checked for its n_modes
    dphi = b.shapes(x, 1)
    slope = q[:, idx[:d.nq]] @ dphi
    shortening = -0.5 * (slope ** 2) @ w
    stretch = q[:, idx[d.nq:]] @ d.tip_psi if d.np_ else 0.0
    out = stretch + shortening
    return float(out[0]) if single else out


def highest_frequency(model) -> tuple[float, str]:
    """Largest modal frequency ``sqrt(K_ii / M_ii)`` [rad/s] of all beams and its beam name."""
    best, name = 0.0, ""
    for j, beam in model.beams.items():
        f = float(np.max(beam.data.frequencies))
        if f > best:
            best, name = f, beam.name
    return best, name


def model_highest_frequency(model, t: float = 0.0) -> tuple[float, str]:
    """Highest frequency [rad/s] for a step's stability limit, and where it comes from: the larger of the
    beams' own modal frequencies (:func:`highest_frequency`, each beam clamped in its floating frame) and the
    spectral radius of the model's linearisation about the undeformed state at rest at ``t`` [s]
    (:func:`ctmm.planar.guards.linearised_omega_max`: the joints and the bodies the beams hang on included,
    e.g. a pinned beam, whose modes are higher than its clamped ones)."""
    beams, which = highest_frequency(model)
    zero = np.zeros(model.n_coordinates)
    try:
        linearised = float(linearised_omega_max(model, zero, zero, t))
    except (SimulationError, FloatingPointError, np.linalg.LinAlgError):
        linearised = math.inf                       # no linearisation: the RK4 step cannot be cleared
    if not linearised > beams:
        return beams, f"highest modal frequency {beams:.4g} rad/s of {which!r}"
    return linearised, (f"highest frequency {linearised:.4g} rad/s of the model linearised about its undeformed "
                        f"state at rest ({which!r} alone: {beams:.4g} rad/s)")


def divergence_reason(model, t: float, dt: float | None, method: str, example: str) -> str:
    """Why a deformable body left its range at ``t`` [s], decided where it can be.

    With ``method == "rk4"`` and a fixed step ``dt`` [s] it compares ``dt`` with the RK4 limit
    ``2 sqrt 2 / omega_max`` of :func:`model_highest_frequency` (the model's own highest frequency: the larger of
    the deformable bodies' clamped modes, e.g. a finite-element subsystem's ``eigh(K, M)``, and the model linearised
    about its undeformed state): above it, the explicit step is unstable; within it, the model itself (``example``
    names a typical cause).  Other methods (the implicit schemes, checked against their own limit before the
    run, and the adaptive ``solve_ivp`` methods) are not judged here: the reason says to look at that check's
    warning.
    """
    if dt is not None and method == "rk4":
        w_max, source = model_highest_frequency(model, t)
        if not dt * w_max <= RK4_LIMIT:
            return (f"the explicit RK4 step is unstable: dt = {dt:g} s exceeds the stability "
                    f"limit 2 sqrt 2/omega_max = {RK4_LIMIT / w_max:.4g} s ({source}); reduce dt or "
                    "use an implicit scheme")
        return (f"the model's response grows without bound (dt = {dt:g} s is within the RK4 "
                f"stability limit 2 sqrt 2/omega_max = {RK4_LIMIT / w_max:.4g} s, {source}, so the "
                f"model itself is unstable, e.g. {example})")
    return (f"the model's response grows without bound; {method!r} is not checked against its "
            "stability limit here: if the run warned that the step exceeds the scheme's limit "
            "(StabilityLimitWarning, checked before the run), reduce dt or choose a stable "
            f"scheme; otherwise the model itself is unstable (e.g. {example})")


def check_divergence(model, q, t: float, dt: float | None, method: str, partial=None) -> None:
    """Raise :class:`SimulationError` when a beam's deflection bound exceeds its length.

    ``sum_i |eta_i| max|phi_i|`` > ``L`` is far outside the small-deformation model; the message
    gives the reason (:func:`divergence_reason`: with ``method == "rk4"`` and a fixed step, the step against the
    model's RK4 limit decides between an unstable step and an unstable model).
    """
    for j, beam in model.beams.items():
        d = beam.data
        eta = np.asarray(q)[model.modal_index[j]]
        bound = float(np.abs(eta[:d.nq]) @ d.phi_bound) + (
            float(np.sum(np.abs(eta[d.nq:]))) * np.sqrt(2.0) if d.np_ else 0.0)
        if not np.isfinite(bound) or bound > beam.length:
            reason = divergence_reason(model, t, dt, method,
                                       "geometric stiffening is off above the first critical speed")
            raise SimulationError(
                f"simulation diverged at t = {t:.6g} s: beam {beam.name!r} deflection bound "
                f"{bound:.3g} m exceeds its length {beam.length:g} m; {reason}",
                time=t, element=beam.name,
                partial_result=partial() if callable(partial) else partial)


def mape(y, y_ref, *, floor: float = 0.1) -> float:
    """Mean absolute percentage error [%] of ``y`` against ``y_ref``.

    ``MAPE = 100/|K| sum_{k in K} |y_k - y_ref,k| / |y_ref,k|`` over the samples
    ``K = {k : |y_ref,k| >= floor max |y_ref|}``: the plain MAPE of Sorensen et al. (seed 000,
    Fig. 3) restricted to samples away from the zero crossings of the reference, where the
    relative error is undefined (``floor = 0.1`` by default; ``docs/flexible.md``).
    """
    y = validation.finite_array("y", y)
    y_ref = validation.finite_array("y_ref", y_ref)
    floor = validation.in_range("floor", floor, 0.0, 1.0, low_open=True)
    if y.shape != y_ref.shape or y.size == 0 or not np.any(y_ref):
        raise ModelError(f"y and y_ref must be non-empty, of the same shape, with y_ref not all zero; got "
                         f"y = {y.tolist()!r:.80} (shape {y.shape}) and y_ref = {y_ref.tolist()!r:.80} "
                         f"(shape {y_ref.shape})")
    mask = np.abs(y_ref) >= floor * np.max(np.abs(y_ref))
    return float(100.0 * np.mean(np.abs(y[mask] - y_ref[mask]) / np.abs(y_ref[mask])))


def spinup_law(final_rate: float = 6.0, ramp_time: float = 15.0):
    """Scalar ``(angle, rate, acceleration)`` functions of the Kane-Ryan-Banerjee spin-up
    (FORMULAS 6.1), for :class:`~ctmm.planar.DrivenHinge` (plain ``math``: fast per call)."""
    import math
    W, T = validation.finite("final_rate", final_rate), validation.positive("ramp_time", ramp_time)
    w = 2 * math.pi / T

    def angle(t):
        return W / T * (t * t / 2 + (math.cos(w * t) - 1) / w ** 2) if t <= T else W * (t - T / 2)

    def rate(t):
        return W / T * (t - math.sin(w * t) / w) if t <= T else W

    def acceleration(t):
        return W / T * (1 - math.cos(w * t)) if t <= T else 0.0

    return angle, rate, acceleration


__all__ = ["mape", "spinup_law", "tip_deflection", "axial_tip_displacement", "highest_frequency",
           "model_highest_frequency",
           "check_divergence", "divergence_reason"]
