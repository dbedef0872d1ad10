"""Values of an entire function at the points where its transfer-matrix evaluation fails.

The characteristic function ``Delta(s)`` of a chain (and the components of a loop's
characteristic function, :class:`ctmm.sweeps.LoopCharacteristic`) is entire in ``s``, but the
transfer-matrix evaluation of it is not defined everywhere:

* at a zero of a connector's dynamic stiffness ``b s^2 + c s + k`` (``s = 0`` for a pure
  ``Damper`` ``c s`` or an ``Inerter`` without spring ``b s^2``; ``s = +-i sqrt(k / b)`` for an
  undamped inerter with a spring) the element matrix has a pole that the factor ``k + c s + b s^2``
  clears only in exact arithmetic: the sum of logarithms is ``inf - inf = NaN``;
* at a resonance of a substructure (the part of the chain already swept by the Riccati transfer,
  e.g. ``m = 1`` on ``k = 100`` at ``s = 10i``) the Riccati pivot is exactly singular and the
  sweep raises ``LinAlgError``.

Both are removable: the function itself is finite there.  :func:`entire_logs` evaluates the
function directly where it can and, at the failing points only, by the mean-value property of
entire functions: ``f(s0)`` is the mean of ``f`` on any circle around ``s0``, and the trapezoidal
rule with ``N`` points on a circle of radius ``r`` has the error ``sum_k a_{kN} r^{kN}`` (``a_n``:
Taylor coefficients at ``s0``), i.e. exponentially small.  The value is certified by comparing
the ``N``- and ``2N``-point means, and the function is checked to be analytic inside the circle
(a pole's negative Laurent powers have zero mean and would go unnoticed: they show up as Fourier
coefficients of negative order on the circle, which must vanish); a value that cannot be
certified raises :class:`~ctmm.errors.SingularSystemError` (never a silently wrong value).
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from .errors import SingularSystemError

__all__ = ["entire_logs", "circle_mean_logs"]

POINTS = 16              # points of the coarse circle rule (the fine rule has twice as many)
RADIUS = 1e-4            # circle radius relative to max(1, |s0|) [-]
AGREEMENT = 1e-9         # largest |coarse - fine| relative to the largest value on the circle
ZERO = 1e-10             # |mean| below this (relative to the circle's largest value) is a zero

LogFunction = Callable[[np.ndarray], np.ndarray]
_FAILURES = (np.linalg.LinAlgError, SingularSystemError)


def entire_logs(log_function: LogFunction, s: np.ndarray, *, label: str = "the characteristic function") -> np.ndarray:
    """Logarithms of an entire (vector) function, with its removable failures repaired.

    Parameters
    ----------
    log_function : callable
        ``s (n,) -> logs (m, n)`` (or ``(n,)``): complex logarithms of the ``m`` components at
        ``s`` [1/s], the same function of ``s`` up to one constant at every ``s`` (so that values
        at different ``s`` may be averaged).  It may raise ``LinAlgError`` or
        :class:`~ctmm.errors.SingularSystemError`, or return NaN or ``+inf``, where its evaluation
        fails; ``-inf`` is a genuine zero of the component.
    s : numpy.ndarray
        Laplace variables [1/s].
    label : str
        What the function is (for error messages).

    Returns
    -------
    numpy.ndarray
        Shape ``(m, n)`` complex logarithms; at the failing samples the logarithms of the
        certified circle means (:func:`circle_mean_logs`).
    """
    s = np.asarray(s, dtype=complex).ravel()
    logs, bad = _direct(log_function, s)
    if not bad.any():
        return logs
    repaired = [circle_mean_logs(log_function, point, label=label) for point in s[bad]]
    if logs is None:
        logs = np.full((repaired[0].size, s.size), np.nan, dtype=complex)
    logs[:, bad] = np.stack(repaired, axis=1)
    return logs


def _direct(log_function: LogFunction, s: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
    """Direct logs and the mask of failed samples (a raising batch is bisected to find them)."""
    try:
        with np.errstate(all="ignore"):
            logs = np.atleast_2d(np.asarray(log_function(s), dtype=complex))
    except _FAILURES:
        if s.size == 1:
            return None, np.ones(1, dtype=bool)
        half = s.size // 2
        parts = [_direct(log_function, s[:half]), _direct(log_function, s[half:])]
        rows = next((p[0].shape[0] for p in parts if p[0] is not None), None)
        bad = np.concatenate([p[1] for p in parts])
        if rows is None:
            return None, bad
        logs = np.concatenate([p[0] if p[0] is not None else np.full((rows, p[1].size), np.nan, complex)
                               for p in parts], axis=1)
        return logs, bad
    return logs, _failed(logs)


def _failed(logs: np.ndarray) -> np.ndarray:
    return np.any(np.isnan(logs) | (logs.real == np.inf), axis=0)


def circle_mean_logs(log_function: LogFunction, s0: complex, *, label: str = "the characteristic function") -> np.ndarray:
    """Logarithms of an entire function at ``s0`` from its mean on a small circle around ``s0``.

    Radii ``RADIUS max(1, |s0|)`` times 1, 0.1, 10, 0.01 are tried (each with a rotation that
    keeps the points off the real and imaginary axes) until the ``POINTS``- and
    ``2 POINTS``-point means agree to ``AGREEMENT`` relative to the largest value on the circle
    and the Fourier coefficients of negative order ``1 .. POINTS / 2`` on the circle (zero for a
    function analytic inside it) are below ``AGREEMENT`` too.
    Components whose mean is below ``ZERO`` (or below 100 times the discrepancy) relative to the
    circle are returned as exact zeros (``-inf``).

    Raises
    ------
    SingularSystemError
        No radius gives a certified value (the function cannot be evaluated near ``s0``).
    """
    s0 = complex(s0)
    base = RADIUS * max(1.0, abs(s0))
    n = 2 * POINTS
    reasons = []
    for attempt, factor in enumerate((1.0, 0.1, 10.0, 0.01)):
        radius = base * factor
        theta = 0.61803398875 * (attempt + 1) + 2.0 * math.pi * np.arange(n) / n
        points = s0 + radius * np.exp(1j * theta)
        try:
            with np.errstate(all="ignore"):
                logs = np.atleast_2d(np.asarray(log_function(points), dtype=complex))
        except _FAILURES as exc:
            reasons.append(f"radius {radius:.3g}: {exc}")
            continue
        if _failed(logs).any():
            reasons.append(f"radius {radius:.3g}: not evaluable on the circle")
            continue
        finite = np.isfinite(logs.real)
        top = np.max(np.where(finite, logs.real, -np.inf))
        if not np.isfinite(top):
            return np.full(logs.shape[0], -np.inf + 0j)      # zero on the whole circle
        with np.errstate(under="ignore"):
            values = np.where(finite, np.exp(logs - top), 0.0)
        fine, coarse = values.mean(axis=1), values[:, ::2].mean(axis=1)
        size = np.abs(values).max(axis=1)
        error = np.abs(fine - coarse)
        # Laurent coefficients of negative powers (a pole, i.e. not entire) vanish from the mean:
        # they are detected as Fourier coefficients of negative order on the circle
        negative = np.abs(np.fft.fft(values, axis=1)[:, n - n // 4:] / n).max(axis=1)
        if np.any(negative > AGREEMENT * size):
            reasons.append(f"radius {radius:.3g}: not analytic inside the circle (a pole: Fourier "
                           f"coefficients of negative order up to {np.max(negative / np.where(size > 0, size, 1)):.3g})")
            continue
        if np.all(error <= AGREEMENT * size):
            zero = np.abs(fine) <= np.maximum(ZERO * size, 100.0 * error)
            with np.errstate(divide="ignore"):
                return np.where(zero, -np.inf + 0j, np.log(np.where(zero, 1.0, fine)) + top)
        reasons.append(f"radius {radius:.3g}: circle means differ by {np.max(error / np.where(size > 0, size, 1)):.3g}")
    raise SingularSystemError(f"{label} cannot be evaluated at s = {s0:.6g} (the transfer-matrix sweep fails "
                              f"there and its circle mean is not certified: {'; '.join(reasons)})")
