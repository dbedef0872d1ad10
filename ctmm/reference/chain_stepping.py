"""Global time-stepping schemes for 1-D chains in any precision (no transfer-matrix code).

The five integrators of :mod:`ctmm.schemes` written in their textbook *global* form
``M a + C v + K x = f`` on the tridiagonal matrices of :mod:`ctmm.reference.chain`, with the
arithmetic of a chosen number type: ``float`` gives the plain double-precision global code
(the baseline a DT-TMM step must match), ``mpmath.mpf`` at 50 digits gives the *exact* solution
of the same linear recurrence from the same double-precision data (its own rounding is ~1e-50).
Nothing here imports :mod:`ctmm.schemes` or any transfer-matrix module.

Schemes (``h`` step, ``n`` -> ``n+1``; ``x~ = x_n + h v_n + (1/2 - beta) h^2 a_n``,
``v~ = v_n + (1 - gamma) h a_n``):

* ``newmark`` (Newmark 1959; Hughes ch. 9): ``(M + gamma h C + beta h^2 K) a_{n+1} =
  f_{n+1} - C v~ - K x~``, ``x_{n+1} = x~ + beta h^2 a_{n+1}``, ``v_{n+1} = v~ + gamma h a_{n+1}``;
* ``generalized_alpha`` (Chung & Hulbert 1993): the same update with
  ``M a_{n+1-am} + C v_{n+1-af} + K x_{n+1-af} = (1 - af) f_{n+1} + af f_n``,
  ``am = (2 rho - 1)/(rho + 1)``, ``af = rho/(rho + 1)``, ``gamma = 1/2 - am + af``,
  ``beta = (1 - am + af)^2 / 4``;
* ``wilson_theta`` (Wilson et al. 1973): linear acceleration over ``tau = theta h``,
  ``(M + tau/2 C + tau^2/6 K) a_tau = f_n + theta (f_{n+1} - f_n) - C (v_n + tau/2 a_n)
  - K (x_n + tau v_n + tau^2/3 a_n)``, then ``a_{n+1} = a_n + (a_tau - a_n)/theta``,
  ``v_{n+1} = v_n + h/2 (a_n + a_{n+1})``, ``x_{n+1} = x_n + h v_n + h^2/6 (2 a_n + a_{n+1})``;
* ``houbolt`` (Houbolt 1950): ``a_{n+1} = (2 x_{n+1} - 5 x_n + 4 x_{n-1} - x_{n-2}) / h^2``,
  ``v_{n+1} = (11 x_{n+1} - 18 x_n + 9 x_{n-1} - 2 x_{n-2}) / (6 h)``; the first two steps are
  average-acceleration Newmark steps (as ctmm);
* ``forward_euler`` (the DT-TMM book's first-order differences): ``v_{n+1} = (x_{n+1} - x_n)/h``,
  ``a_{n+1} = (v_{n+1} - v_n)/h``, equation of motion at ``t_{n+1}``.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..errors import ModelError
from ..validation import positive
from .chain import GlobalChain, TimeHistory, assemble, time_grid

SCHEMES = ("newmark", "generalized_alpha", "wilson_theta", "houbolt", "forward_euler")


def _tridiagonal_solve(lower, diagonal, upper, rhs):
    """Thomas algorithm (no pivoting; the effective matrices here are diagonally dominant or SPD)."""
    n = len(diagonal)
    c, d = [None] * n, [None] * n
    c[0] = upper[0] / diagonal[0] if n > 1 else 0
    d[0] = rhs[0] / diagonal[0]
    for i in range(1, n):
        pivot = diagonal[i] - lower[i] * c[i - 1]
        c[i] = upper[i] / pivot if i < n - 1 else 0
        d[i] = (rhs[i] - lower[i] * d[i - 1]) / pivot
    x = [None] * n
    x[-1] = d[-1]
    for i in range(n - 2, -1, -1):
        x[i] = d[i] - c[i] * x[i + 1]
    return x


class _Tridiagonal:
    """A tridiagonal matrix as three lists of numbers of the working type."""

    def __init__(self, matrix: np.ndarray, number: Callable) -> None:
        n = matrix.shape[0]
        self.diagonal = [number(float(matrix[i, i])) for i in range(n)]
        self.lower = [number(0.0)] + [number(float(matrix[i, i - 1])) for i in range(1, n)]
        self.upper = [number(float(matrix[i, i + 1])) for i in range(n - 1)] + [number(0.0)]

    def times(self, x):
        n = len(x)
        return [self.diagonal[i] * x[i] + (self.lower[i] * x[i - 1] if i else 0)
                + (self.upper[i] * x[i + 1] if i < n - 1 else 0) for i in range(n)]

    def combine(self, others, weights) -> "_Tridiagonal":
        out = object.__new__(_Tridiagonal)
        for name in ("diagonal", "lower", "upper"):
            rows = [getattr(self, name)] + [getattr(o, name) for o in others]
            setattr(out, name, [sum(w * r[i] for w, r in zip(weights, rows)) for i in range(len(rows[0]))])
        return out

    def solve(self, rhs):
        return _tridiagonal_solve(self.lower, self.diagonal, self.upper, rhs)


def _add(*terms):
    """Element-wise linear combination of ``(weight, vector)`` pairs."""
    n = len(terms[0][1])
    return [sum(w * v[i] for w, v in terms) for i in range(n)]


def step_global(chain: GlobalChain, t_final: float, dt: float, x0, v0, *, scheme: str = "newmark",
                number: Callable = float, force_fn: Callable[[float], np.ndarray] | None = None,
                beta: float = 0.25, gamma: float = 0.5, rho_infinity: float = 0.8,
                theta: float = 1.4) -> TimeHistory:
    """Integrate the global equations with one of :data:`SCHEMES` in the arithmetic of ``number``.

    Parameters
    ----------
    chain : GlobalChain
        The chain (displacements from the unstretched configuration).
    t_final, dt : float
        End time and step [s]; ``t_final/dt`` must be an integer.
    x0, v0 : array_like, shape (n,)
        Initial displacements [m] and velocities [m/s] (double precision data).
    scheme : str
        One of :data:`SCHEMES`.
    number : callable
        Number type of the arithmetic: ``float`` (double precision) or e.g. ``mpmath.mpf`` under
        ``mpmath.workdps(50)`` (the caller sets the precision).
    force_fn : callable, optional
        ``f(t) -> (n,)`` external forces [N]; zero when omitted.
    beta, gamma, rho_infinity, theta : float
        Newmark, generalized-alpha and Wilson parameters.

    Returns
    -------
    TimeHistory
        Displacements, velocities and accelerations rounded to double precision.
    """
    if scheme not in SCHEMES:
        raise ModelError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    times = time_grid(t_final, dt)
    n = chain.size
    M, C, K = (_Tridiagonal(m, number) for m in assemble(chain))
    h = number(float(times[1]))
    one, half = number(1.0), number(0.5)
    force = (lambda t: [number(0.0)] * n) if force_fn is None else \
        (lambda t: [number(float(f)) for f in np.asarray(force_fn(t), dtype=float)])
    x = [number(float(value)) for value in np.asarray(x0, dtype=float)]
    v = [number(float(value)) for value in np.asarray(v0, dtype=float)]
    if len(x) != n or len(v) != n:
        raise ModelError(f"x0 and v0 must have {n} entries, got {len(x)} and {len(v)}")
    a = [r / m for r, m in zip(_add((one, force(0.0)), (-one, C.times(v)), (-one, K.times(x))), M.diagonal)]
    old = [x, x]                                    # x_{n-1}, x_{n-2} for Houbolt
    out = {"x": [x], "v": [v], "a": [a]}
    if scheme == "generalized_alpha":
        rho = number(float(rho_infinity))
        am, af = (2 * rho - 1) / (rho + 1), rho / (rho + 1)
        gamma_, beta_ = half - am + af, (one - am + af) ** 2 / 4
    else:
        am = af = number(0.0)
        gamma_, beta_ = number(float(gamma)), number(float(beta))
    if scheme == "wilson_theta":
        th = number(float(positive("theta", theta)))
    for i in range(times.size - 1):
        t0, t1 = float(times[i]), float(times[i + 1])
        f0, f1 = force(t0), force(t1)
        if scheme in ("newmark", "generalized_alpha") or (scheme == "houbolt" and i < 2):
            b_, g_ = (beta_, gamma_) if scheme != "houbolt" else (number(0.25), half)
            x_t = _add((one, x), (h, v), ((half - b_) * h * h, a))
            v_t = _add((one, v), ((one - g_) * h, a))
            E = M.combine([C, K], [one - am, (one - af) * g_ * h, (one - af) * b_ * h * h])
            rhs = _add((one - af, f1), (af, f0), (-am, M.times(a)), (-af, C.times(v)), (-af, K.times(x)),
                       (-(one - af), C.times(v_t)), (-(one - af), K.times(x_t)))
            a_new = E.solve(rhs)
            x_new = _add((one, x_t), (b_ * h * h, a_new))
            v_new = _add((one, v_t), (g_ * h, a_new))
        elif scheme == "wilson_theta":
            tau = th * h
            E = M.combine([C, K], [one, tau / 2, tau * tau / 6])
            rhs = _add((one - th, f0), (th, f1), (-one, C.times(_add((one, v), (tau / 2, a)))),
                       (-one, K.times(_add((one, x), (tau, v), (tau * tau / 3, a)))))
            a_tau = E.solve(rhs)
            a_new = _add((one - one / th, a), (one / th, a_tau))
            v_new = _add((one, v), (h / 2, a), (h / 2, a_new))
            x_new = _add((one, x), (h, v), (h * h / 3, a), (h * h / 6, a_new))
        elif scheme == "houbolt":
            x1, x2 = old
            E = M.combine([C, K], [2 / (h * h), number(11.0) / (6 * h), one])
            rhs = _add((one, f1), (one / (h * h), M.times(_add((5, x), (-4, x1), (1, x2)))),
                       (one / (6 * h), C.times(_add((18, x), (-9, x1), (2, x2)))))
            x_new = E.solve(rhs)
            a_new = [(2 * xn - 5 * xa + 4 * xb - xc) / (h * h) for xn, xa, xb, xc in zip(x_new, x, x1, x2)]
            v_new = [(11 * xn - 18 * xa + 9 * xb - 2 * xc) / (6 * h) for xn, xa, xb, xc in zip(x_new, x, x1, x2)]
        else:  # forward_euler
            E = M.combine([C, K], [one / (h * h), one / h, one])
            rhs = _add((one, f1), (one / (h * h), M.times(x)), (one / h, M.times(v)), (one / h, C.times(x)))
            x_new = E.solve(rhs)
            v_new = [(xn - xa) / h for xn, xa in zip(x_new, x)]
            a_new = [(vn - va) / h for vn, va in zip(v_new, v)]
        old = [x, old[0]]
        x, v, a = x_new, v_new, a_new
        out["x"].append(x)
        out["v"].append(v)
        out["a"].append(a)
    as_array = lambda rows: np.array([[float(value) for value in row] for row in rows])  # noqa: E731
    return TimeHistory(times, as_array(out["x"]), as_array(out["v"]), as_array(out["a"]))
