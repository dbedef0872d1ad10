"""Global baselines of the lumped benchmark chain: banded solves of its dynamic stiffness and a banded Newmark.

Independent of the transfer matrix method: they work on the banded global ``M, C, K`` of
:func:`ctmm.reference.chain.assemble_banded` (``solve_banded((1, 1))`` layout: row 0 superdiagonal, row 1 diagonal,
row 2 subdiagonal) or on bands built straight from the chain data (:func:`uniform_bands`).

* :func:`banded_frequency_loop` -- ``scipy.linalg.solve_banded`` per frequency;
* :func:`thomas_frequency_batch` -- the same tridiagonal system for all frequencies at once (a Thomas elimination,
  every step a numpy operation over the frequency vector): the fastest plain-numpy global baseline;
* :func:`global_newmark_banded_linear` -- textbook global Newmark with a banded Cholesky factorised once and
  tridiagonal mat-vecs: the O(n) global time-stepping baseline.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla


def banded_frequency_loop(Mb: np.ndarray, Cb: np.ndarray, Kb: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Driving-point and tip responses to a unit force on the first mass by ``solve_banded`` per frequency.

    ``Mb, Cb, Kb`` [kg, N s/m, N/m] in ``solve_banded((1, 1))`` layout (:func:`ctmm.reference.chain.assemble_banded`),
    ``omega`` [rad/s]; both outputs from one solve per frequency.  Returns (2, n_omega) [m/N].
    """
    rhs = np.zeros(Mb.shape[1], dtype=complex)
    rhs[0] = 1.0
    X = np.empty((2, omega.size), dtype=complex)
    for k, w in enumerate(omega):
        x = sla.solve_banded((1, 1), Kb - w ** 2 * Mb + 1j * w * Cb, rhs)
        X[0, k], X[1, k] = x[0], x[-1]
    return X


def thomas_frequency_batch(Mb: np.ndarray, Cb: np.ndarray, Kb: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Driving-point and tip responses to a unit force on the first mass, all frequencies at once.

    Tridiagonal dynamic stiffness ``Z = K - w^2 M + i w C`` in ``solve_banded((1, 1))`` layout
    (row 0 superdiagonal, row 1 diagonal, row 2 subdiagonal); forward elimination and back
    substitution over the rows, each a numpy operation over the frequency vector.  Returns (2, n_omega).
    """
    w = omega[:, None]
    Z = Kb[:, None, :] - (w ** 2) * Mb[:, None, :] + 1j * w * Cb[:, None, :]     # (3, n_omega, n)
    upper, diag, lower = Z[0], Z[1], Z[2]
    n = diag.shape[1]
    c_prime = np.empty_like(diag)
    d_prime = np.empty_like(diag)
    c_prime[:, 0] = upper[:, 1] / diag[:, 0] if n > 1 else 0.0
    d_prime[:, 0] = 1.0 / diag[:, 0]
    for i in range(1, n):
        denominator = diag[:, i] - lower[:, i - 1] * c_prime[:, i - 1]
        if i < n - 1:
            c_prime[:, i] = upper[:, i + 1] / denominator
        d_prime[:, i] = -lower[:, i - 1] * d_prime[:, i - 1] / denominator
    x = d_prime[:, n - 1].copy()
    tip = x.copy()
    for i in range(n - 2, -1, -1):
        x = d_prime[:, i] - c_prime[:, i] * x
    return np.stack([x, tip])



def global_newmark_banded_linear(glob, n_steps: int, dt: float, x0: np.ndarray, v0: np.ndarray, force: np.ndarray,
                                 beta: float = 0.25, gamma: float = 0.5) -> np.ndarray:
    """Textbook global Newmark(beta, gamma) with a banded Cholesky factorised once and tridiagonal mat-vecs.

    ``glob`` a :class:`ctmm.reference.chain.GlobalChain` with a fixed start; ``dt`` [s]; ``x0`` [m], ``v0`` [m/s]
    and the constant ``force`` [N] per mass.  Returns the displacements [m] after ``n_steps`` steps.
    """
    Mb, Cb, Kb = uniform_bands(glob)
    h = dt

    def matvec(band, x):
        y = band[1] * x
        y[:-1] += band[0, 1:] * x[1:]
        y[1:] += band[2, :-1] * x[:-1]
        return y
    eff = Mb + gamma * h * Cb + beta * h * h * Kb
    upper = np.vstack([eff[0], eff[1]])  # (2, n) upper form for cholesky_banded
    chol = sla.cholesky_banded(upper, lower=False)
    x, v = x0.copy(), v0.copy()
    a = (force - matvec(Cb, v) - matvec(Kb, x)) / glob.masses
    for _ in range(n_steps):
        x_p = x + h * v + (0.5 - beta) * h * h * a
        v_p = v + (1.0 - gamma) * h * a
        a = sla.cho_solve_banded((chol, False), force - matvec(Cb, v_p) - matvec(Kb, x_p))
        x = x_p + beta * h * h * a
        v = v_p + gamma * h * a
    return x


def uniform_bands(glob) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bands of ``M, C, K`` [kg, N s/m, N/m] straight from the chain data (no dense matrices; fixed start)."""
    n = glob.size
    k, c = glob.stiffness, glob.damping
    def band(conn, ground):
        b = np.zeros((3, n))
        b[1] = conn[:-1] + conn[1:] + ground
        b[0, 1:] = -conn[1:-1]
        b[2, :-1] = -conn[1:-1]
        return b
    Mb = np.zeros((3, n))
    Mb[1] = glob.masses
    return Mb, band(c, glob.ground_damping), band(k, glob.ground_stiffness)
