"""Verified characteristic roots of linear delay equations (an independent reference).

:func:`ctmm.reference.dde.chebyshev_collocation_roots` returns the eigenvalues of a
collocation of the infinitesimal generator: candidates, of which those of large modulus are
spurious (spectral pollution: too few Chebyshev nodes per wavelength of ``e^{s theta}``,
``|s| tau_max > ~1.1 N``; docs/characteristic_roots.md section 5).  :func:`verified_roots`
reports only candidates that Newton's method confirms and whose backward error
(:func:`relative_residual`) is at rounding level.  Tests only: no library module imports this.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import ModelError
from ..validation import positive
from .dde import characteristic_function, chebyshev_collocation_roots, newton_refine_root

__all__ = ["relative_residual", "verified_roots"]


def _validated(A0: object, delayed: Sequence[tuple[object, float]]) -> tuple[np.ndarray, list[tuple[np.ndarray, float]]]:
    """``A0`` and ``[(A_k, tau_k)]`` as arrays, validated by :func:`ctmm.reference.dde.characteristic_function`."""
    characteristic_function(A0, delayed)          # ModelError naming the bad matrix or delay
    return np.asarray(A0, dtype=float), [(np.asarray(Ak, dtype=float), float(tau)) for Ak, tau in delayed]


def relative_residual(A0: object, delayed: Sequence[tuple[object, float]], s: complex) -> float:
    """Backward error of a candidate root ``s`` [1/s]: ``sigma_min(T(s))`` relative to the size of
    its terms, ``|s| + ||A0|| + sum_k ||A_k|| |e^(-s tau_k)|`` (2-norms), with
    ``T(s) = s I - A0 - sum_k A_k e^(-s tau_k)``: 0 at a root, O(1) far from one [-]."""
    A0, terms = _validated(A0, delayed)
    s = complex(s)
    T = s * np.eye(A0.shape[0]) - A0
    size = abs(s) + np.linalg.norm(A0, 2)
    for Ak, tau in terms:
        T = T - Ak * np.exp(-s * tau)
        size += np.linalg.norm(Ak, 2) * abs(np.exp(-s * tau))
    smallest = np.linalg.svd(T, compute_uv=False)[-1]
    return float(smallest / size) if size > 0 else 0.0


def verified_roots(A0: object, delayed: Sequence[tuple[object, float]], n_nodes: int, *,
                   re_min: float = -np.inf, im_max: float = np.inf, residual: float = 1e-12,
                   move: float = 1e-3) -> np.ndarray:
    """Characteristic roots found by collocation and *verified*: only roots checked by residual.

    Every eigenvalue of :func:`chebyshev_collocation_roots` in the region is polished by
    :func:`newton_refine_root` and kept only if (a) the polished root has
    :func:`relative_residual` <= ``residual`` and (b) Newton moved it by at most ``move``
    ``max(1, |s|)`` (a candidate that Newton carries far away was not a root of the
    discretisation's resolved part; its target, if real, is found from its own candidate).
    Roots that coincide to 1e-9 relative are reported once.

    Parameters
    ----------
    A0, delayed, n_nodes
        As for :func:`chebyshev_collocation_roots`.
    re_min : float
        Keep roots with ``Re s > re_min`` [1/s].
    im_max : float
        Keep roots with ``|Im s| < im_max`` [rad/s].
    residual : float
        Largest accepted relative residual [-].
    move : float
        Largest accepted Newton correction relative to ``max(1, |s|)`` [-].

    Returns
    -------
    numpy.ndarray of complex
        Verified roots [1/s], sorted by decreasing real part.  Only roots of modulus below about
        ``n_nodes / tau_max`` are reliably *all* found (see :func:`chebyshev_collocation_roots`);
        every root returned is a root.

    Examples
    --------
    >>> roots = verified_roots([[0.0]], [([[-1.0]], 1.0)], 30, re_min=-1.0)
    >>> [round(complex(z).real, 9) for z in roots]
    [-0.318131505, -0.318131505]
    """
    A0, terms = _validated(A0, delayed)
    re_min = float(re_min)
    im_max = float(im_max)
    if np.isnan(re_min) or np.isnan(im_max):
        raise ModelError(f"re_min and im_max must be numbers, got {re_min!r} and {im_max!r}")
    residual = positive("residual", residual)
    move = positive("move", move)
    candidates = chebyshev_collocation_roots(A0, terms, n_nodes)
    kept: list[complex] = []
    for candidate in candidates[(candidates.real > re_min - 1.0) & (np.abs(candidates.imag) < im_max + 1.0)]:
        root = newton_refine_root(A0, terms, candidate)
        if not (np.isfinite(root) and root.real > re_min and abs(root.imag) < im_max):
            continue
        if abs(root - candidate) > move * max(1.0, abs(root)):
            continue
        if relative_residual(A0, terms, root) > residual:
            continue
        if any(abs(root - other) <= 1e-9 * max(1.0, abs(root)) for other in kept):
            continue
        kept.append(complex(root))
    out = np.array(kept, dtype=complex)
    return out[np.lexsort((out.imag, -out.real))] if out.size else out
