"""Time-integration schemes as DT-TMM linearisations.

Each scheme turns velocity and acceleration at the *evaluation level* of a step into affine
functions of the step's unknown displacement ``x`` (seed 002 §7.3, Table 7.2):

    x_eval = cx * x + dx,     v_eval = A * x + B,     a_eval = C * x + D

``cx, A, C`` are constants of the scheme and the step size; ``dx, B, D`` come from the stored
history of each connection point.  After the transfer-matrix solve gives ``x``, the scheme
updates the history (``x, v, a`` at ``t_{n+1}``).

========================  ======================  ===========================================
scheme                    unknown ``x``           evaluation level
========================  ======================  ===========================================
:class:`ForwardEuler`     ``x(t_{n+1})``          ``t_{n+1}`` (backward differences, order 1)
:class:`Newmark`          ``x(t_{n+1})``          ``t_{n+1}`` (order 2 for ``gamma = 1/2``)
:class:`WilsonTheta`      ``x(t_n + theta h)``    ``t_n + theta h`` (order 2)
:class:`Houbolt`          ``x(t_{n+1})``          ``t_{n+1}``, 3-step backward differences (order 2)
:class:`GeneralizedAlpha` ``x(t_{n+1})``          inertia at ``n+1-alpha_m``, others at ``n+1-alpha_f``
========================  ======================  ===========================================

The coefficients are derived in ``docs/schemes.md``; Newmark and Houbolt agree with
FORMULAS §3.1 (Cramer's ``Newmark.m``/``Houbolt.m``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from . import validation
from .errors import ModelError


@dataclass
class History:
    """Kinematic history of all connection points (arrays of shape ``(n_points, d)``).

    ``x, v, a`` are the values at the last completed step ``t_n``; ``x_old`` keeps
    ``[x_{n-1}, x_{n-2}]`` for multistep schemes; ``steps`` counts completed steps.
    """

    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    x_old: list
    steps: int = 0

    def copy(self) -> "History":
        return History(self.x.copy(), self.v.copy(), self.a.copy(), [p.copy() for p in self.x_old],
                       self.steps)


@dataclass(frozen=True)
class StepCoefficients:
    """Linearisation of one step: scalars ``cx, A, C`` and arrays ``dx, B, D`` per point.

    ``unknown_offset`` [s] is the time of the unknown displacement relative to ``t_n``;
    ``load_weight`` is the weight ``w`` of the new load in ``(1 - w) F(t_n) + w F(t_{n+1})``
    (for Wilson-theta ``w = theta`` extrapolates linearly to ``t_n + theta h``).
    """

    cx: float
    A: float
    C: float
    dx: np.ndarray
    B: np.ndarray
    D: np.ndarray
    unknown_offset: float
    load_weight: float


class Scheme:
    """Base class of DT-TMM time-integration schemes (frozen dataclasses)."""

    name: ClassVar[str] = "scheme"
    order: ClassVar[int] = 2

    def coefficients(self, history: History, h: float) -> StepCoefficients:
        """Linearisation coefficients of the next step of size ``h`` [s]."""
        raise NotImplementedError

    def update(self, history: History, x: np.ndarray, h: float, coeffs: StepCoefficients) -> History:
        """New history after the step, from the solved unknown displacement ``x``."""
        raise NotImplementedError

    def interpolate_force(self, f_unknown: np.ndarray, f_previous: np.ndarray) -> np.ndarray:
        """Internal forces at ``t_{n+1}`` from those solved at the evaluation level."""
        return f_unknown


def _check_step(h: float) -> float:
    return validation.positive("dt", h)


@dataclass(frozen=True)
class Newmark(Scheme):
    """Newmark-beta scheme (any ``beta``, ``gamma``).

    Parameters
    ----------
    beta : float
        ``beta > 0``; 1/4 with ``gamma = 1/2`` is the average-acceleration rule
        (unconditionally stable, energy conserving for linear undamped systems).
    gamma : float
        ``gamma >= 0``; second order only for ``gamma = 1/2``.
    """

    beta: float = 0.25
    gamma: float = 0.5
    name: ClassVar[str] = "newmark"

    def __post_init__(self) -> None:
        validation.positive("beta", self.beta)
        validation.nonnegative("gamma", self.gamma)

    @property
    def order(self) -> int:  # type: ignore[override]
        return 2 if abs(self.gamma - 0.5) < 1e-14 else 1

    def _newmark(self, history: History, h: float):
        beta, gamma = self.beta, self.gamma
        C = 1.0 / (beta * h * h)
        D = -C * (history.x + h * history.v + (0.5 - beta) * h * h * history.a)
        A = gamma / (beta * h)
        B = history.v + h * (1.0 - gamma) * history.a + gamma * h * D
        return A, B, C, D

    def coefficients(self, history: History, h: float) -> StepCoefficients:
        A, B, C, D = self._newmark(history, _check_step(h))
        return StepCoefficients(1.0, A, C, np.zeros_like(history.x), B, D, h, 1.0)

    def update(self, history, x, h, coeffs):
        A, B, C, D = self._newmark(history, h)
        return History(x, A * x + B, C * x + D, [history.x] + history.x_old[:1], history.steps + 1)


@dataclass(frozen=True)
class GeneralizedAlpha(Scheme):
    """Generalized-alpha scheme of Chung & Hulbert (1993), parametrised by ``rho_infinity``.

    ``alpha_m = (2 rho - 1)/(rho + 1)``, ``alpha_f = rho/(rho + 1)``,
    ``gamma = 1/2 - alpha_m + alpha_f``, ``beta = (1 - alpha_m + alpha_f)^2 / 4``.
    Inertia is evaluated at ``t_{n+1-alpha_m}``, all other forces at ``t_{n+1-alpha_f}``.

    Parameters
    ----------
    rho_infinity : float
        Spectral radius at infinite frequency, in [0, 1] (1 = no numerical dissipation).
    """

    rho_infinity: float = 0.8
    name: ClassVar[str] = "generalized_alpha"

    def __post_init__(self) -> None:
        validation.in_range("rho_infinity", self.rho_infinity, 0.0, 1.0)

    @property
    def alpha_m(self) -> float:
        return (2.0 * self.rho_infinity - 1.0) / (self.rho_infinity + 1.0)

    @property
    def alpha_f(self) -> float:
        return self.rho_infinity / (self.rho_infinity + 1.0)

    @property
    def gamma(self) -> float:
        return 0.5 - self.alpha_m + self.alpha_f

    @property
    def beta(self) -> float:
        return 0.25 * (1.0 - self.alpha_m + self.alpha_f) ** 2

    def _newmark(self, history: History, h: float):
        return Newmark(self.beta, self.gamma)._newmark(history, h)

    def coefficients(self, history, h):
        A_n, B_n, C_n, D_n = self._newmark(history, _check_step(h))
        am, af = self.alpha_m, self.alpha_f
        return StepCoefficients(
            cx=1.0 - af, A=(1.0 - af) * A_n, C=(1.0 - am) * C_n,
            dx=af * history.x, B=(1.0 - af) * B_n + af * history.v, D=(1.0 - am) * D_n + am * history.a,
            unknown_offset=h, load_weight=1.0 - af)

    def update(self, history, x, h, coeffs):
        A, B, C, D = self._newmark(history, h)
        return History(x, A * x + B, C * x + D, [history.x] + history.x_old[:1], history.steps + 1)

    def interpolate_force(self, f_unknown, f_previous):
        # forces solved at n+1-alpha_f: f_eval = (1-af) f_{n+1} + af f_n
        af = self.alpha_f
        return (f_unknown - af * f_previous) / (1.0 - af)


@dataclass(frozen=True)
class WilsonTheta(Scheme):
    """Wilson-theta scheme (linear acceleration over ``tau = theta h``).

    Parameters
    ----------
    theta : float
        ``theta >= 1``; unconditionally stable for ``theta >= 1.37`` (usual 1.4).
    """

    theta: float = 1.4
    name: ClassVar[str] = "wilson_theta"

    def __post_init__(self) -> None:
        if not (validation.finite("theta", self.theta) >= 1.0):
            raise ModelError(f"theta must be >= 1, got {self.theta!r}")

    def coefficients(self, history, h):
        tau = self.theta * _check_step(h)
        C = 6.0 / tau ** 2
        D = -C * (history.x + tau * history.v) - 2.0 * history.a
        A = 3.0 / tau
        B = -A * history.x - 2.0 * history.v - 0.5 * tau * history.a
        return StepCoefficients(1.0, A, C, np.zeros_like(history.x), B, D, tau, self.theta)

    def update(self, history, x_tau, h, coeffs):
        a_tau = coeffs.C * x_tau + coeffs.D
        a_new = history.a + (a_tau - history.a) / self.theta
        v_new = history.v + 0.5 * h * (history.a + a_new)
        x_new = history.x + h * history.v + h * h / 6.0 * (2.0 * history.a + a_new)
        return History(x_new, v_new, a_new, [history.x] + history.x_old[:1], history.steps + 1)

    def interpolate_force(self, f_unknown, f_previous):
        return f_previous + (f_unknown - f_previous) / self.theta


@dataclass(frozen=True)
class Houbolt(Scheme):
    """Houbolt three-step backward-difference scheme with a second-order start-up.

    The first two steps use the average-acceleration Newmark rule (second order), so the
    global order stays two.
    """

    name: ClassVar[str] = "houbolt"

    def coefficients(self, history, h):
        h = _check_step(h)
        if history.steps < 2:
            return Newmark().coefficients(history, h)
        x1, (x2, x3) = history.x, history.x_old
        C = 2.0 / h ** 2
        D = -(5.0 * x1 - 4.0 * x2 + x3) / h ** 2
        A = 11.0 / (6.0 * h)
        B = -(18.0 * x1 - 9.0 * x2 + 2.0 * x3) / (6.0 * h)
        return StepCoefficients(1.0, A, C, np.zeros_like(x1), B, D, h, 1.0)

    def update(self, history, x, h, coeffs):
        if history.steps < 2:
            return Newmark().update(history, x, h, coeffs)
        return History(x, coeffs.A * x + coeffs.B, coeffs.C * x + coeffs.D,
                       [history.x] + history.x_old[:1], history.steps + 1)


@dataclass(frozen=True)
class ForwardEuler(Scheme):
    """The book's "Forward-Euler" linearisation (first-order differences).

    ``v_{n+1} = (x_{n+1} - x_n)/h`` and ``a_{n+1} = (v_{n+1} - v_n)/h``: the dynamic equation is
    still imposed at ``t_{n+1}`` (seed 002 §7.3.2.1), so the step is implicit and first order.
    """

    name: ClassVar[str] = "forward_euler"
    order: ClassVar[int] = 1

    def coefficients(self, history, h):
        h = _check_step(h)
        A, C = 1.0 / h, 1.0 / h ** 2
        B = -history.x / h
        D = -history.x / h ** 2 - history.v / h
        return StepCoefficients(1.0, A, C, np.zeros_like(history.x), B, D, h, 1.0)

    def update(self, history, x, h, coeffs):
        return History(x, coeffs.A * x + coeffs.B, coeffs.C * x + coeffs.D,
                       [history.x] + history.x_old[:1], history.steps + 1)


SCHEMES: dict[str, type[Scheme]] = {
    cls.name: cls for cls in (ForwardEuler, Newmark, WilsonTheta, Houbolt, GeneralizedAlpha)}


def as_scheme(scheme: "Scheme | str") -> Scheme:
    """Return a scheme instance from an instance or a name (``"newmark"``, ``"houbolt"``, ...)."""
    if isinstance(scheme, Scheme):
        return scheme
    if isinstance(scheme, str) and scheme in SCHEMES:
        return SCHEMES[scheme]()
    raise ModelError(f"unknown scheme {scheme!r}; available: {', '.join(sorted(SCHEMES))} "
                     "or an instance such as Newmark(beta=0.25, gamma=0.5)")
