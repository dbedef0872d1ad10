"""Independent reference: analytic natural frequencies of separable spatial cantilevers.

Shares no code with ctmm's transfer-matrix solvers.  A uniform cantilever (clamped at ``x = 0``,
along ``x``) whose tip body has its centre of mass on the axis at ``e`` beyond the tip and
principal axes along ``x, y, z`` vibrates in four uncoupled families; each frequency equation
below is written from the textbook boundary conditions of the mode functions and solved by
bracketing sign changes on a fine grid and Brent's method (bending determinant in 60-digit
arithmetic, where its hyperbolic terms cancel).

* bending in one plane (``EI``, ``rhoA``), tip mass ``M`` at ``e``, inertia ``J`` about its centre of
  mass: ``w = a (cos bx - cosh bx) + b (sin bx - sinh bx)`` (clamped), and at ``x = L``
  (``w_c = w + e w'``)::

      EI w'''(L) = -omega^2 M (w + e w')(L)
      EI w''(L) + e EI w'''(L) = omega^2 J w'(L)

  (``e = M = J = 0``: ``1 + cos bL cosh bL = 0``);
* axial (``EA``, ``rhoA``, tip mass ``M``): ``u = sin kx``, ``EA k cos kL = omega^2 M sin kL``;
* torsion (``GJ``, ``rhoIp``, tip inertia ``J_x``): the same with ``GJ``, ``rhoIp``, ``J_x``.
"""
from __future__ import annotations

import mpmath
import numpy as np
from scipy.optimize import brentq

__all__ = ["bending_tip_body", "bar_tip_body", "cantilever_spectrum"]


def _roots(f, upper: float, n_grid: int) -> list[float]:
    """All sign changes of ``f`` on ``(0, upper]`` refined by Brent's method (poles rejected)."""
    x = np.linspace(upper / n_grid, upper, n_grid)
    y = np.array([f(v) for v in x])
    out = []
    for a, b, fa, fb in zip(x[:-1], x[1:], y[:-1], y[1:]):
        if np.sign(fa) != np.sign(fb):
            r = brentq(f, a, b, xtol=1e-15 * b, rtol=1e-15, maxiter=200)
            if abs(f(r)) < 1e-6 * (abs(fa) + abs(fb)):      # a root, not a pole of a tangent form
                out.append(r)
    return out


def bending_tip_body(EI: float, rhoA: float, L: float, omega_max: float, *, mass: float = 0.0,
                     offset: float = 0.0, inertia: float = 0.0, n_grid: int = 20000) -> np.ndarray:
    """Bending frequencies [rad/s] below ``omega_max`` of a cantilever with a tip body (module docstring)."""

    def det(omega: float) -> float:
        # 60-digit arithmetic: the hyperbolic terms (~ e^(2 b L)) cancel down to ~ e^(b L)
        with mpmath.workdps(60):
            b = (mpmath.mpf(rhoA) * mpmath.mpf(omega) ** 2 / EI) ** mpmath.mpf(0.25)
            bl = b * L
            c, s, ch, sh = mpmath.cos(bl), mpmath.sin(bl), mpmath.cosh(bl), mpmath.sinh(bl)
            # derivatives 0..3 at L of the two clamped shapes cos - cosh and sin - sinh
            w = (c - ch, s - sh)
            w1 = (b * (-s - sh), b * (c - ch))
            w2 = (b ** 2 * (-c - ch), b ** 2 * (-s - sh))
            w3 = (b ** 3 * (s - sh), b ** 3 * (-c - ch))
            rows = [(EI * w3[k] + omega ** 2 * mass * (w[k] + offset * w1[k]),
                     EI * w2[k] + offset * EI * w3[k] - omega ** 2 * inertia * w1[k]) for k in range(2)]
            value = (rows[0][0] * rows[1][1] - rows[1][0] * rows[0][1]) / (EI ** 2 * b ** 5 * mpmath.cosh(bl))
            return float(value)

    return np.array(_roots(det, omega_max, n_grid))


def bar_tip_body(stiffness: float, density: float, L: float, omega_max: float, *, tip: float = 0.0,
                 n_grid: int = 20000) -> np.ndarray:
    """Axial (``EA, rhoA``, tip mass) or torsional (``GJ, rhoIp``, tip inertia) cantilever frequencies below
    ``omega_max`` [rad/s]: roots of ``K k cos kL - omega^2 tip sin kL`` (``k = omega sqrt(rho / K)``)."""

    def f(omega: float) -> float:
        k = omega * np.sqrt(density / stiffness)
        value = stiffness * k * np.cos(k * L) - omega * omega * tip * np.sin(k * L)
        return value / (stiffness * k + omega ** 2 * tip)

    return np.array(_roots(f, omega_max, n_grid))


def cantilever_spectrum(*, EA: float, GJ: float, EIy: float, EIz: float, rhoA: float, rhoIp: float, L: float,
                        omega_max: float, mass: float = 0.0, offset: float = 0.0,
                        inertia: tuple[float, float, float] = (0.0, 0.0, 0.0), n_grid: int = 20000) -> np.ndarray:
    """All natural frequencies below ``omega_max`` [rad/s] of a spatial cantilever with a tip body whose
    centre of mass is on the axis at ``offset`` beyond the tip and principal moments ``inertia = (J_x,
    J_y, J_z)`` about it, ascending (the union of the four families)."""
    parts = [bending_tip_body(EIz, rhoA, L, omega_max, mass=mass, offset=offset, inertia=inertia[2], n_grid=n_grid),
             bending_tip_body(EIy, rhoA, L, omega_max, mass=mass, offset=offset, inertia=inertia[1], n_grid=n_grid),
             bar_tip_body(EA, rhoA, L, omega_max, tip=mass, n_grid=n_grid),
             bar_tip_body(GJ, rhoIp, L, omega_max, tip=inertia[0], n_grid=n_grid)]
    return np.sort(np.concatenate(parts))
