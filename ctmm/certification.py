"""Certified height of the root-counting contour: a model-based bound on the loop term.

The stability tools (:mod:`ctmm.sweeps`, :mod:`ctmm.stability`, :mod:`ctmm.stability_chart`)
count the characteristic roots of one delayed loop ``u = -k C(s) e^{-s tau} y`` in the rectangle
``Re s >= sigma, |Im s| <= R``.  With ``L(s) = k C(s) P(s)`` the delay-free loop transfer
function, a root needs ``|L(s)| e^{-Re(s) tau} = 1``; if

    e^{max(0, -sigma) tau} |L(s)| < 1/2        for every s with Re s >= sigma, |s| >= R      (B)

no root lies outside the rectangle, and on its far edges ``arg Delta = arg(D Delta_0) +
Arg(1 + L e^{-s tau})`` with a principal argument, which the counting uses.

How ``R`` is proved (lumped chains, state-space models)
------------------------------------------------------
The open chain (the loop removed, every other delay-free loop closed) has a finite-dimensional
realisation ``x' = A x + b f``, ``y_j = c_j x + d_j f`` (:func:`ctmm.lumped_realisation.chain_state_space`), and
an LTI controller one of its own.  A linear(ised) state-space model
(:class:`ctmm.state_space_characteristic.StateSpaceCharacteristic`) gives its realisation with
the controller states appended (``open_loop_realisation()``): one factor below.  Balance ``A`` by a diagonal similarity ``B = T^-1 A T``
(:func:`scipy.linalg.matrix_balance`, exact in floating point: powers of 2) and let
``beta = ||B||_inf``.  For ``|s| > beta`` the Neumann series gives
``||(sI - B)^-1||_inf <= 1/(|s| - beta)``, hence

    |P_j(s)| = |(c_j T)(sI - B)^-1 (T^-1 b) + d_j| <= ||c_j T||_1 ||T^-1 b||_inf / (|s| - beta) + |d_j|,

and the same for ``C(s)``.  The product of these bounds decreases with ``|s|``; ``R`` is where it
reaches 1/2 (found by bisection, then enlarged by 1 %).  The bound covers every ``s`` of the
half plane with ``|s| >= R``, not only the sampled line, so two close resonances, a pole-zero pair
or any narrow peak cannot hide beyond ``R``: nothing is sampled there.  Every open-loop pole
(eigenvalue of ``A``) satisfies ``|p| <= beta < R``.

Inside ``R`` the line ``Re s = sigma`` is sampled adaptively; its initial samples include the
imaginary parts of the open-loop poles (eigenvalues of ``A``, up to ``MAX_EIGEN_STATES`` states)
and the points at their half-power distance on either side, so each resonance peak, however
narrow, is a sample, and two close modes are two samples (a phase change of 2 pi between two
samples cannot go unseen).

Neutral and improper loops
--------------------------
If ``e^{max(0,-sigma) tau} |L(infinity)| >= 1/2`` (``|L(infinity)| = |k d C(infinity)|``: direct
feedthrough, e.g. acceleration feedback at the actuated mass) or the controller is not proper,
(B) fails for every ``R``: such a loop can have infinitely many roots near a vertical line.  The
tools then raise a :class:`~ctmm.errors.ModelError` naming the loop unless the user gives
``im_max`` (a bounded frequency range, reported as not certified).

Models without a realisation
----------------------------
Chains with distributed elements (beams, rods) or other delayed loops have no realisation here:
``R`` then comes from sampling ``|L|`` on the line (log-spaced, refined adaptively on the complex
logarithms of the components) and the result says it is not certified.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .controller_state_space import controller_state_space
from .errors import ModelError

__all__ = ["ContourCertificate", "LoopBound", "loop_bound", "StabilityWarning", "MAX_EIGEN_STATES"]

MAX_EIGEN_STATES = 2400       # open-loop poles are computed (dense eigenvalues) up to this size


class StabilityWarning(UserWarning):
    """A stability result could not be certified (e.g. a user ``im_max`` that is too small)."""


@dataclass(frozen=True)
class ContourCertificate:
    """What a root count (or a margin, a chart) certifies.

    Attributes
    ----------
    sigma : float
        Roots are counted in ``Re s > sigma`` [1/s].
    im_max : float
        Half height ``R`` [rad/s] of the counted rectangle ``|Im s| <= R``.
    source : str
        How ``R`` was obtained: ``"bound"`` (model-based bound (B), module docstring),
        ``"user"`` (the ``im_max`` option) or ``"sampled"`` (sampled loop term, no realisation).
    bound : float
        The proven height [rad/s] beyond which the loop term is below 1/2 in ``Re s >= sigma``
        (``nan`` when no bound exists: no realisation, neutral loop).
    certified : bool
        No root with ``Re s > sigma`` can lie outside the rectangle (``im_max >= bound``).
    notes : tuple of str
        Why a result is not certified, and what was sampled.
    """

    sigma: float
    im_max: float
    source: str
    bound: float
    certified: bool
    notes: tuple = field(default=())

    def describe(self) -> str:
        """One line: the region and how it was obtained."""
        head = (f"roots counted in Re s > {self.sigma:.6g}, |Im s| <= {self.im_max:.6g} rad/s "
                f"({self.source})")
        notes = "".join(f"; {n}" for n in self.notes)
        if self.certified:
            return head + f"; certified: loop term < 1/2 for |s| >= {self.bound:.6g} rad/s" + notes
        return head + "; NOT certified beyond it" + notes

    def as_dict(self) -> dict:
        """Plain ``dict`` (JSON-friendly)."""
        return {"sigma": self.sigma, "im_max": self.im_max, "source": self.source,
                "bound": self.bound, "certified": self.certified, "notes": list(self.notes)}


@dataclass(frozen=True)
class LoopBound:
    """Factors ``G_i / (r - beta_i) + H_i`` whose product bounds ``|L(s)|`` for ``|s| = r``.

    Attributes
    ----------
    factors : tuple of (float, float, float)
        ``(G, beta, H)`` per factor: plant (sensor terms summed with the weight bounds) and
        controller.
    poles : numpy.ndarray
        Open-loop poles [1/s] (eigenvalues of the realisations; empty when too large).
    n_states : int
        States of the plant realisation.
    """

    factors: tuple
    poles: np.ndarray
    n_states: int = 0

    def value(self, r: float) -> float:
        """Upper bound of ``|L(s)|`` over ``|s| = r`` (inf for ``r`` <= the largest beta)."""
        out = 1.0
        for g, beta, h in self.factors:
            if r <= beta:
                return math.inf
            out *= g / (r - beta) + h
        return out

    @property
    def at_infinity(self) -> float:
        """``lim sup |L|`` for ``|s| -> inf`` (0 for strictly proper loops)."""
        return float(np.prod([h for _, _, h in self.factors]))

    def radius(self, level: float) -> float:
        """Smallest ``r`` (up to 1 %) with ``value(r) < level``; inf if the limit is >= level."""
        if self.at_infinity >= level:
            return math.inf
        lo = max(beta for _, beta, _ in self.factors)
        hi = 2.0 * lo + 1.0
        while self.value(hi) >= level:
            hi *= 2.0
        lo = max(lo, 0.0)
        for _ in range(200):
            if hi - lo <= 1e-3 * hi:
                break
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if self.value(mid) < level else (mid, hi)
        return 1.01 * hi


def _balanced(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(B, t)`` with ``B = diag(t)^-1 A diag(t)`` (powers of two: exact)."""
    import scipy.linalg

    if A.size == 0:
        return A, np.ones(A.shape[0])
    B, (scale, _) = scipy.linalg.matrix_balance(A, permute=False, separate=True)
    return B, np.asarray(scale, float)


def _factor(A: np.ndarray, b: np.ndarray, C: np.ndarray, d: np.ndarray,
            weights: np.ndarray) -> tuple[float, float, float]:
    """``(G, beta, H)``: ``sum_j weights_j |c_j (sI-A)^-1 b + d_j| <= G/(|s|-beta) + H``."""
    B, t = _balanced(A)
    beta = float(np.abs(B).sum(axis=1).max()) if B.size else 0.0
    b_norm = float(np.abs(b / t).max()) if b.size else 0.0
    c_norms = np.abs(C * t[None, :]).sum(axis=1) if C.size else np.zeros(len(d))
    g = float(np.sum(weights * c_norms) * b_norm)
    h = float(np.sum(weights * np.abs(d)))
    # rounding of the balanced products: a relative safety margin
    return g * (1 + 1e-9), beta * (1 + 1e-9), h * (1 + 1e-12)


def plant_realisation(model: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(A, b, C, d)`` of the open loop: ``x' = A x + b f``, sensor terms ``y = C x + d f``.

    A state-space characteristic gives its own (controller states included); a chain's open
    system is realised by :func:`ctmm.lumped_realisation.chain_state_space` (its LTI controller is not included).
    Raises :class:`~ctmm.errors.ModelError` when there is no realisation (distributed elements,
    other delayed loops).
    """
    from .control.loops import actuator_inputs
    from .lumped_realisation import chain_state_space

    realisation = getattr(model, "open_loop_realisation", None)
    if realisation is not None:
        return realisation()
    lp = model.loop
    actuators = actuator_inputs(model.system, lp.name)
    inputs = list(dict.fromkeys(name for name, _ in actuators))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ss = chain_state_space(model.open_system, inputs=inputs, outputs=list(model.term_names))
    except (ModelError, ValueError, TypeError, KeyError) as exc:
        raise ModelError(f"loop {lp.name!r}: the open chain has no state-space realisation ({exc})") from exc
    A, Bm, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (ss.A, ss.B, ss.C, ss.D))
    A = A.reshape(A.shape[0], A.shape[0]) if A.size else np.zeros((0, 0))
    b = np.zeros(A.shape[0])
    d = np.zeros(len(model.term_names))
    for name, weight in actuators:
        column = inputs.index(name)
        if A.size:
            b = b + weight * Bm[:, column]
        d = d + weight * D[:, column]
    return A, b, C.reshape(len(model.term_names), A.shape[0]), d


@dataclass(frozen=True)
class Realisation:
    """The open loop's ``x' = A x + b f``, ``y = C x + d f`` (:func:`plant_realisation`) and the eigenvalues
    of ``A`` [1/s] (empty without states or beyond ``MAX_EIGEN_STATES``): built once (:func:`realise`)
    for :func:`fixed_roots` and :func:`loop_bound` (a 500-mass chain: 1000 states, each an eigenvalue
    problem of about a second)."""

    A: np.ndarray
    b: np.ndarray
    C: np.ndarray
    d: np.ndarray
    eigenvalues: np.ndarray


def realise(model: Any) -> Realisation:
    """:class:`Realisation` of the loop of ``model`` (raises :class:`~ctmm.errors.ModelError` as
    :func:`plant_realisation`)."""
    A, b, C, d = plant_realisation(model)
    eigenvalues = open_loop_poles(A) if 0 < A.shape[0] <= MAX_EIGEN_STATES else np.zeros(0, complex)
    return Realisation(A, b, C, d, eigenvalues)


def open_loop_poles(A: np.ndarray) -> np.ndarray:
    """Eigenvalues of ``A`` [1/s]; ``O(n^2)`` for a proportionally damped lumped chain, else dense.

    A lumped chain whose every degree of freedom has mass is realised as ``A = [[0, I], [-Kt, -Ct]]`` with
    ``Kt = M^-1 K``, ``Ct = M^-1 C`` tridiagonal.  The characteristic polynomial of a tridiagonal matrix depends on
    its diagonal and on the products of its facing off-diagonal entries only, so where those products are
    ``>= 0`` the eigenvalues ``w2`` of ``Kt`` are those of the symmetric tridiagonal matrix with the same diagonal
    and their square roots off it (:func:`scipy.linalg.eigvalsh_tridiagonal`).  Where also ``Ct = alpha I + beta
    Kt`` to round-off (``|Ct - alpha I - beta Kt| <= 1e-14 max|Ct|``: Rayleigh damping, e.g. a uniform chain
    with uniform damping), each ``w2`` gives the two roots of ``s^2 + (alpha + beta w2) s + w2``.  Any other
    ``A`` takes :func:`numpy.linalg.eigvals`.
    """
    poles = _proportional_chain_poles(A)
    return np.linalg.eigvals(A) if poles is None else poles


def _proportional_chain_poles(A: np.ndarray) -> np.ndarray | None:
    n = A.shape[0]
    m = n // 2
    if n < 8 or n != 2 * m or np.any(A[:m, :m]) or not np.array_equal(A[:m, m:], np.eye(m)):
        return None
    Kt, Ct = -A[m:, :m], -A[m:, m:]
    band = np.eye(m, dtype=bool) | np.eye(m, k=1, dtype=bool) | np.eye(m, k=-1, dtype=bool)
    if np.any(Kt[~band]) or np.any(Ct[~band]):
        return None
    upper, lower = np.diag(Kt, 1), np.diag(Kt, -1)
    products = upper * lower
    if np.any(products < 0.0) or not np.all(upper):
        return None
    beta = float(np.mean(np.diag(Ct, 1) / upper))
    alpha = float(np.mean(np.diag(Ct) - beta * np.diag(Kt)))
    scale = float(np.max(np.abs(Ct)))
    if scale == 0.0:                               # undamped
        alpha = beta = 0.0
    elif np.max(np.abs(Ct - beta * Kt - alpha * np.eye(m))) > 1e-14 * scale:
        return None
    from scipy.linalg import eigvalsh_tridiagonal

    w2 = eigvalsh_tridiagonal(np.diag(Kt).copy(), np.sqrt(products))
    b = alpha + beta * w2                          # s^2 + b s + w2 = 0 per mode
    disc = b * b - 4.0 * w2
    root = np.sqrt(disc.astype(complex))
    q = -0.5 * (b + np.where(b >= 0.0, 1.0, -1.0) * root)   # the root without cancellation ...
    with np.errstate(divide="ignore", invalid="ignore"):
        other = np.where(q != 0.0, w2 / q, -b - q)          # ... and its partner by Vieta
    return np.concatenate([q, other])


def fixed_roots(model: Any, sigma: float = 0.0, realisation: Realisation | None = None) -> np.ndarray:
    """Characteristic roots on the line ``Re s = sigma`` that the loop cannot move [1/s].

    Eigenvalues ``p`` of the open loop's ``A`` (:func:`plant_realisation`) with
    ``|Re p - sigma| <= 1e-6 max(1, |p|)`` that are uncontrollable from the loop's actuator or
    unobservable through every sensor term (Popov-Belevitch-Hautus: ``[pI - A, b]`` or
    ``[pI - A; C]`` rank deficient, smallest singular value ``<= 1e-7`` of the matrix's norm).
    They are roots of ``Delta`` for every gain, delay and weighting: undamped modes and free
    motions the loop neither drives nor senses.  Returns those with ``Im p >= 0`` (one per
    distinct value); empty when the model has no realisation or more than ``MAX_EIGEN_STATES``.
    ``realisation``: the model's :func:`realise` when the caller has it already.
    """
    if realisation is None:
        try:
            realisation = realise(model)
        except ModelError:
            return np.zeros(0, complex)
    A, b, C = realisation.A, realisation.b, realisation.C
    n = A.shape[0]
    if not 0 < n <= MAX_EIGEN_STATES:
        return np.zeros(0, complex)
    found: list[complex] = []
    for p in realisation.eigenvalues:
        if p.imag < 0 or abs(p.real - sigma) > 1e-6 * max(1.0, abs(p)) or \
                any(abs(p - q) <= 1e-6 * max(1.0, abs(p)) for q in found):
            continue
        shifted = complex(sigma, p.imag) * np.eye(n) - A
        reach = np.column_stack([shifted, b])
        sense = np.vstack([shifted, np.atleast_2d(C)])
        if min(np.linalg.svd(m, compute_uv=False)[-1] / max(np.linalg.norm(m, 2), 1e-300)
               for m in (reach, sense)) <= 1e-7:
            found.append(complex(sigma, p.imag))
    return np.array(found, dtype=complex)


def loop_bound(model: Any, weight_bound: np.ndarray, realisation: Realisation | None = None) -> LoopBound:
    """A :class:`LoopBound` for the loop of a :class:`ctmm.sweeps.LoopCharacteristic`.

    Parameters
    ----------
    model : LoopCharacteristic or StateSpaceCharacteristic
        The loop; its open system (every other loop closed) must have a state-space
        realisation (a state-space characteristic gives its own, ``open_loop_realisation()``).
    weight_bound : numpy.ndarray
        Bound of ``|k w_j|`` per sensor term over the parameter sets.
    realisation : Realisation, optional
        The model's :func:`realise` when the caller has it already.

    Raises
    ------
    ModelError
        No realisation (distributed elements, other delayed loops) or an improper controller;
        the message says which.
    """
    realisation = realise(model) if realisation is None else realisation
    A, b, C, d = realisation.A, realisation.b, realisation.C, realisation.d
    if getattr(model, "open_loop_realisation", None) is not None:   # controller states included
        return LoopBound((_factor(A, b, C, d, np.asarray(weight_bound, float)),),
                         realisation.eigenvalues.astype(complex), int(A.shape[0]))
    lp = model.loop
    factors = [_factor(A, b, C, d, np.asarray(weight_bound, float))]
    poles = [realisation.eigenvalues] if 0 < A.shape[0] <= MAX_EIGEN_STATES else []
    if lp.is_lti:
        Ac, Bc, Cc, dc = controller_state_space(lp.name, lp.gain, "for the state-space bound of the certificate "
                                                "(with the plant the loop may still decay, or be neutral or advanced)")
        if Ac.shape[0]:
            factors.append(_factor(Ac, Bc, Cc.reshape(1, -1), np.array([dc]), np.ones(1)))
            poles.append(np.linalg.eigvals(Ac))
        else:
            factors.append((0.0, 0.0, abs(dc)))
    poles_all = np.concatenate(poles) if poles else np.zeros(0, complex)
    return LoopBound(tuple(factors), poles_all.astype(complex), int(A.shape[0]))
