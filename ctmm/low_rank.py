"""Minimal-residual solve of ``(I - P) d = r`` with ``P`` of low rank, known only through products.

The Newton iterations of the implicit DT-TMM with state-dependent actuator inputs (planar:
:mod:`ctmm.planar.actuated_newton`, spatial: :mod:`ctmm.spatial.implicit`) need ``d`` with
``(I - P) d = r``, where ``P = T J`` is the sweep's response to the inputs times the inputs' state
dependence: its rank is the number of state-dependent actuators, so it is never formed.  GMRES
(Arnoldi with modified Gram-Schmidt, least squares on the small Hessenberg matrix) over the Krylov
space of ``I - P`` started at ``r`` ends after ``rank P + 1`` products (at most ``limit``).

The callers use the solution in two forms: the planar Newton update needs the coefficients of ``d``
in the directions ``product`` was called with (each call records an input change, and the new iterate
is one sweep with the inputs extrapolated by those coefficients); the spatial one forms
``d = sum_k c_k direction_k``.  :func:`low_rank_solve` returns both.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["low_rank_solve"]


def low_rank_solve(residual: np.ndarray, product: Callable[[np.ndarray], np.ndarray], limit: int
                   ) -> tuple[np.ndarray, list[np.ndarray]]:
    """GMRES on ``(I - P) d = residual`` with ``P`` given by ``product(direction) = P direction``.

    Parameters
    ----------
    residual : ndarray, shape (n,)
        Right-hand side ``r`` (the caller's units).
    product : callable
        ``product(direction) -> P direction`` (shape (n,)); called once per direction, in order.
    limit : int
        Most products (the size of the state: the space cannot grow beyond it).

    Returns
    -------
    coefficients : ndarray, shape (k,)
        ``d = sum_i coefficients[i] directions[i]`` (empty if ``residual`` is zero or ``limit`` 0).
    directions : list of ndarray
        The ``k`` orthonormal directions ``product`` was called with, in order.

    Notes
    -----
    Stops when the residual of the least-squares problem, or the part of the newest image outside the
    space, falls below ``1e-13 |r|`` (the space is invariant: ``d`` is exact to round-off).
    """
    beta = float(np.linalg.norm(residual))
    if beta == 0.0 or limit == 0:
        return np.zeros(0), []
    basis = [residual / beta]
    H = np.zeros((limit + 1, limit))
    coefficients = np.zeros(0)
    for j in range(limit):
        w = basis[j] - product(basis[j])
        for i in range(j + 1):
            H[i, j] = basis[i] @ w
            w = w - H[i, j] * basis[i]
        H[j + 1, j] = float(np.linalg.norm(w))
        rhs = np.zeros(j + 2)
        rhs[0] = beta
        coefficients = np.linalg.lstsq(H[:j + 2, :j + 1], rhs, rcond=None)[0]
        left = float(np.linalg.norm(H[:j + 2, :j + 1] @ coefficients - rhs))
        if left <= 1e-13 * beta or H[j + 1, j] <= 1e-13 * beta:
            break
        basis.append(w / H[j + 1, j])
    return coefficients, basis[:len(coefficients)]
