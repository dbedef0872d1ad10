"""Approximate roots of linear delay equations by collocation of their generator (library use).

``x'(t) = A_0 x(t) + sum_k A_k x(t - tau_k)`` has the characteristic roots of its infinitesimal
generator on the state space ``C([-tau_max, 0])``.  Representing a state by its values at
``N + 1`` Chebyshev points of ``[-tau_max, 0]`` turns the generator into a matrix (Breda, Maset
& Vermiglio 2005): rows at the inner and left points are the derivative of the interpolant,
the row at ``theta = 0`` is the right-hand side of the equation.  Its eigenvalues of modulus
well below ``N / tau_max`` approximate the rightmost roots; they are used as *seeds* only
(:func:`ctmm.stability.spectral_seeds`): every root reported by ctmm is polished on the
transfer-matrix characteristic function and accounted for by an argument-principle count.
The independent test model is :mod:`ctmm.reference.dde`; this module does not use it.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import scipy.linalg

from .errors import ModelError

__all__ = ["generator_eigenvalues"]


def _chebyshev_points(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points ``cos(j pi / n)``, their barycentric weights and the differentiation matrix."""
    j = np.arange(n + 1)
    x = np.cos(np.pi * j / n)
    weights = (-1.0) ** j
    weights[[0, -1]] *= 0.5
    difference = x[:, None] - x[None, :] + np.eye(n + 1)
    D = (weights[None, :] / weights[:, None]) / difference
    np.fill_diagonal(D, 0.0)
    np.fill_diagonal(D, -D.sum(axis=1))          # rows of a differentiation matrix sum to zero
    return x, weights, D


def _interpolation_row(x: np.ndarray, weights: np.ndarray, point: float) -> np.ndarray:
    """Values of the Lagrange basis polynomials at ``point`` (barycentric formula)."""
    gap = point - x
    exact = np.flatnonzero(np.abs(gap) < 1e-14)
    row = np.zeros(x.size)
    if exact.size:
        row[exact[0]] = 1.0
        return row
    terms = weights / gap
    return terms / terms.sum()


def generator_eigenvalues(A0: np.ndarray, delayed: Sequence[tuple[np.ndarray, float]],
                          nodes: int = 24) -> np.ndarray:
    """Eigenvalues [1/s] of the collocated generator of ``x' = A0 x + sum_k A_k x(t - tau_k)``.

    Parameters
    ----------
    A0 : numpy.ndarray, shape (d, d)
        Undelayed matrix [1/s].
    delayed : sequence of (A_k, tau_k)
        Delayed matrices [1/s] and delays [s] > 0 (empty: the eigenvalues of ``A0``).
    nodes : int
        Number of Chebyshev intervals ``N`` (>= 2).

    Returns
    -------
    numpy.ndarray of complex
        ``d (N + 1)`` approximations; only those with ``|s| tau_max`` well below ``N`` are
        accurate.
    """
    A0 = np.atleast_2d(np.asarray(A0, dtype=float))
    if isinstance(nodes, bool) or not isinstance(nodes, (int, np.integer)) or nodes < 2:
        raise ModelError(f"nodes must be an int >= 2, got {nodes!r}")
    if not delayed:
        return np.linalg.eigvals(A0).astype(complex)
    tau_max = max(float(tau) for _, tau in delayed)
    if not tau_max > 0:
        raise ModelError(f"delays must be > 0 [s], got {[tau for _, tau in delayed]!r}")
    d = A0.shape[0]
    x, weights, D = _chebyshev_points(int(nodes))
    # theta = tau_max (x - 1) / 2: d/dtheta = (2 / tau_max) d/dx; x = 1 is theta = 0
    generator = np.kron((2.0 / tau_max) * D, np.eye(d))
    top = np.zeros((d, d * (int(nodes) + 1)))
    top[:, :d] = A0
    for Ak, tau in delayed:
        row = _interpolation_row(x, weights, 1.0 - 2.0 * float(tau) / tau_max)
        top += np.kron(row[None, :], np.atleast_2d(np.asarray(Ak, dtype=float)))
    generator[:d, :] = top
    return scipy.linalg.eigvals(generator)
