"""Dense symmetric positive definite solves of the reference models (mass matrices), at LAPACK cost.

``scipy.linalg.cho_solve(scipy.linalg.cho_factor(M), b)`` spends about 35 us per call on a small matrix in its
argument checks and array-API wrappers, around 2 us of LAPACK (``potrf``, ``potrs``); a reference right-hand side
evaluated tens of thousands of times by ``solve_ivp`` pays that on every call.  :func:`cholesky_solve` calls the
same two LAPACK routines directly (the same numbers, bit for bit) and refuses a matrix that is not positive
definite as ``cho_factor`` does.
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

__all__ = ["cholesky_solve"]


def cholesky_solve(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``matrix^-1 rhs`` by the Cholesky factor of a symmetric positive definite ``matrix`` (n, n).

    Parameters
    ----------
    matrix : ndarray, shape (n, n)
        Symmetric positive definite (a mass matrix [kg, kg m, kg m^2]); its upper triangle is read.
    rhs : ndarray, shape (n,) or (n, k)
        Right-hand side(s) [N, N m].

    Returns
    -------
    ndarray
        The solution, shaped as ``rhs`` [m/s^2, rad/s^2].

    Raises
    ------
    numpy.linalg.LinAlgError
        ``matrix`` is not positive definite (or has non-finite entries where the factorisation reads them).
    """
    matrix, rhs = np.asarray(matrix, dtype=float), np.asarray(rhs, dtype=float)
    factor, info = lapack.dpotrf(matrix, lower=False, clean=False)
    if info != 0:
        raise np.linalg.LinAlgError(f"cholesky_solve: the {info}-th leading minor of the {matrix.shape} matrix is not "
                                    "positive definite" if info > 0 else f"cholesky_solve: LAPACK dpotrf argument "
                                    f"{-info} is invalid (matrix shape {matrix.shape})")
    solution, info = lapack.dpotrs(factor, rhs, lower=False)
    if info != 0:
        raise np.linalg.LinAlgError(f"cholesky_solve: LAPACK dpotrs argument {-info} is invalid (matrix shape "
                                    f"{matrix.shape}, right-hand side shape {rhs.shape})")
    return solution
