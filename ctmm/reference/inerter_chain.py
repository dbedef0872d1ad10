"""Global-equation reference for 1-D chains whose connectors may contain inerters (no TMM code).

Same topology as :mod:`ctmm.reference.chain`: ``n`` masses ``0 .. n-1``; connector ``0`` joins
the start boundary to mass 0, connector ``i`` joins mass ``i-1`` to mass ``i``, connector ``n``
joins mass ``n-1`` to the end boundary (its coefficients must be zero at a ``"free"`` end).
Connector ``j`` is a spring ``k_j``, a damper ``c_j`` and an inerter ``b_j`` in parallel; its
tension is ``q_j = b_j (a_out - a_in) + c_j (v_out - v_in) + k_j (x_out - x_in)`` (Smith 2002,
IEEE TAC 47(10), 1648-1662).  Assembled like a finite element, the inerter puts
``b_j [[1, -1], [-1, 1]]`` into the mass matrix, so

.. math:: M \\ddot x + C \\dot x + K x = f(t),\\qquad M = \\operatorname{diag}(m) + \\sum_j b_j\\, L_j

(``L_j`` the connector's incidence Laplacian).  Coordinates are displacements from the
unstretched configuration.  Solved with textbook linear algebra: generalized ``eigh``, dense
solves of the dynamic stiffness, ``solve_ivp`` on the first-order form.  Imports nothing from
ctmm except :mod:`ctmm.errors` and :mod:`ctmm.validation`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.linalg as sla
from scipy.integrate import solve_ivp

from ..errors import ModelError
from ..validation import finite_array

__all__ = ["InerterChain", "assemble", "natural_frequencies", "count_below", "frequency_response",
           "state_matrix", "time_response", "initial_acceleration"]


def _coefficients(name: str, value, size: int) -> np.ndarray:
    array = np.zeros(size) if value is None else finite_array(name, value, ndim=1)
    if array.shape != (size,) or np.any(array < 0.0):
        raise ModelError(f"{name} must be {size} values >= 0, got {value!r}")
    return array


@dataclass(frozen=True)
class InerterChain:
    """A serial chain of masses and spring-damper-inerter connectors.

    Parameters
    ----------
    masses : array_like, shape (n,)
        Masses [kg], >= 0 (the mass matrix must be regular once inertances are added).
    stiffness, damping, inertance : array_like, shape (n + 1,)
        Connector stiffness [N/m], damping [N s/m] and inertance [kg], >= 0.
    start, end : {"fixed", "free"}
        Boundaries.
    """

    masses: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray | None = None
    inertance: np.ndarray | None = None
    start: str = "fixed"
    end: str = "free"

    def __post_init__(self) -> None:
        masses = _coefficients("masses", self.masses, np.size(self.masses))
        n = masses.size
        object.__setattr__(self, "masses", masses)
        for name in ("stiffness", "damping", "inertance"):
            object.__setattr__(self, name, _coefficients(name, getattr(self, name), n + 1))
        for name, index in (("start", 0), ("end", n)):
            kind = getattr(self, name)
            if kind not in ("fixed", "free"):
                raise ModelError(f"{name} must be 'fixed' or 'free', got {kind!r}")
            if kind == "free" and (self.stiffness[index] or self.damping[index] or self.inertance[index]):
                raise ModelError(f"connector {index} touches a free {name}: its coefficients must be 0")


def assemble(chain: InerterChain) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Global ``M`` [kg], ``C`` [N s/m], ``K`` [N/m], shape ``(n, n)``."""
    n = chain.masses.size
    matrices = [np.diag(chain.masses.astype(float)), np.zeros((n, n)), np.zeros((n, n))]
    for j in range(n + 1):
        ends = [i for i in (j - 1, j) if 0 <= i < n]        # masses joined by connector j
        signs = [-1.0, 1.0] if len(ends) == 2 else [1.0]
        for matrix, value in zip(matrices, (chain.inertance[j], chain.damping[j], chain.stiffness[j])):
            for a, sa in zip(ends, signs):
                for b, sb in zip(ends, signs):
                    matrix[a, b] += value * sa * sb
    return tuple(matrices)


def natural_frequencies(chain: InerterChain) -> np.ndarray:
    """Undamped natural frequencies [rad/s], ascending (``eigh(K, M)``)."""
    M, _, K = assemble(chain)
    eigenvalues = sla.eigh(K, M, eigvals_only=True)
    return np.sqrt(np.clip(eigenvalues, 0.0, None))


def count_below(chain: InerterChain, omega) -> np.ndarray:
    """Number of undamped natural frequencies strictly below each ``omega`` [rad/s]."""
    frequencies = natural_frequencies(chain)
    return np.array([int(np.sum(frequencies < w)) for w in np.atleast_1d(omega)])


def frequency_response(chain: InerterChain, omega, force) -> np.ndarray:
    """Displacement phasors [m] of every mass, shape ``(n_omega, n)``, for force phasors ``force`` [N]
    (shape ``(n,)``) at ``omega`` [rad/s]: ``(K + i w C - w^2 M) X = F``."""
    M, C, K = assemble(chain)
    rhs = np.asarray(force, dtype=complex)
    return np.array([np.linalg.solve(K + 1j * w * C - w * w * M, rhs)
                     for w in np.atleast_1d(np.asarray(omega, dtype=float))])


def state_matrix(chain: InerterChain) -> np.ndarray:
    """First-order matrix ``[[0, I], [-M^-1 K, -M^-1 C]]`` [1/s] of the state ``[x, v]``."""
    M, C, K = assemble(chain)
    n = M.shape[0]
    return np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])


def initial_acceleration(chain: InerterChain, x0, v0, force0) -> np.ndarray:
    """``M^-1 (f - C v - K x)`` [m/s^2]: the accelerations at the start."""
    M, C, K = assemble(chain)
    return np.linalg.solve(M, np.asarray(force0, float) - C @ np.asarray(v0, float) - K @ np.asarray(x0, float))


def time_response(chain: InerterChain, t_eval, x0, v0,
                  force: Callable[[float, np.ndarray, np.ndarray], np.ndarray] | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Displacements and velocities ``(nt, n)`` at ``t_eval`` [s] by ``solve_ivp`` (DOP853, rtol 1e-11).

    ``force(t, x, v)`` [N] gives the external (and feedback) forces on the masses, shape ``(n,)``.
    """
    M, C, K = assemble(chain)
    n = M.shape[0]
    t_eval = np.asarray(t_eval, dtype=float)
    force = force or (lambda t, x, v: np.zeros(n))

    def rhs(t, z):
        x, v = z[:n], z[n:]
        return np.concatenate([v, np.linalg.solve(M, force(t, x, v) - C @ v - K @ x)])

    sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), np.concatenate([x0, v0]).astype(float), method="DOP853",
                    t_eval=t_eval, rtol=1e-11, atol=1e-14)
    if not sol.success:
        raise ModelError(f"solve_ivp failed: {sol.message}")
    return sol.y[:n].T, sol.y[n:].T
