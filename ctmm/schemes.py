"""Time-integration schemes as DT-TMM linearisations.

Each scheme turns velocity and acceleration at the *evaluation level* of a step into affine
functions of the step's unknown displacement ``x`` (seed 002 §7.3, Table 7.2):

    x_eval = cx * x + dx,     v_eval = A * x + B,     a_eval = C * x + D

``cx, A, C`` are constants of the scheme and the step size; ``dx, B, D`` come from the stored
history of each connection point.  After the transfer-matrix solve gives ``x``, the scheme
updates the history (``x, v, a`` at ``t_{n+1}``).

Predictor (incremental) form.  The unknown actually solved for is the correction
``delta = x - x_pred`` to the scheme's predictor ``x_pred`` (e.g. ``x_n + h v_n + (1/2 - beta) h^2 a_n``
for Newmark), so that ``a = C delta`` and ``v = v_pred + A delta``.  The transfer matrices are the
same as in the book's form (same ``cx, A, C``); only the known terms change.  In the book's form
``v = A x + B`` is the difference of two numbers of size ``|x|/h``, which costs about
``eps |x| / h`` per step (an energy drift 1e4 times the round-off of a global Newmark code at
``h = 1e-4``); the predictor form has no such cancellation (tests/test_time_domain.py).

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

Nonlinear second-order form (the planar and flexible stepper, :mod:`ctmm.planar.implicit`).
:meth:`Scheme.second_order_step` states the same scheme for ``M(q, t) q'' = f(q, q', t)`` with the
acceleration ``a`` at the evaluation level as unknown (Newton on ``a``):

    q_eval = q_pred + b' h^2 a,     v_eval = v_pred + g' h a,     t_eval = t_n + fraction h

derived from the coefficients above when ``cx = 1`` and ``D = 0`` (``a = C delta``, so
``b' h^2 = 1/C`` and ``g' h = A/C``); :meth:`Scheme.second_order_update` then calls
:meth:`Scheme.update` with ``delta = b' h^2 a``.  Newmark and generalized-alpha use the form of
Arnold & Bruls (2007), which imposes the equations of motion exactly at ``t_{n+1}``
(``docs/planar.md``, "Every DT-TMM scheme on a planar model").
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from . import validation
from .errors import ModelError
from .guard import newmark_limit, wilson_limit


@dataclass
class History:
    """Kinematic history of all connection points (arrays of shape ``(n_points, d)``).

    ``x, v, a`` are the values at the last completed step ``t_n``; ``x_old`` keeps
    ``[x_{n-1}, x_{n-2}]`` for multistep schemes; ``steps`` counts completed steps.
    ``equation_acceleration`` (nonlinear form only, :meth:`Scheme.second_order_update`) is the
    acceleration that satisfied the equations of motion in the last step; generalized-alpha keeps
    it apart from its algorithmic acceleration ``a`` (Arnold & Bruls), ``None`` in the chain core.
    """

    x: np.ndarray
    v: np.ndarray
    a: np.ndarray
    x_old: list
    steps: int = 0
    equation_acceleration: np.ndarray | None = None

    def copy(self) -> "History":
        equation = None if self.equation_acceleration is None else self.equation_acceleration.copy()
        return History(self.x.copy(), self.v.copy(), self.a.copy(), [p.copy() for p in self.x_old],
                       self.steps, equation)


@dataclass(frozen=True)
class StepCoefficients:
    """Linearisation of one step: scalars ``cx, A, C`` and arrays ``dx, B, D`` per point.

    ``x_pred`` is the predictor: the unknown solved for is ``delta = x - x_pred``, and
    ``x_eval = cx delta + dx`` etc. are written in terms of ``delta``.
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
    x_pred: np.ndarray


@dataclass(frozen=True)
class SecondOrderStep:
    """One step of a scheme on a nonlinear second-order system ``M(q, t) q'' = f(q, q', t)``.

    With the acceleration ``a`` [unit/s^2] that satisfies the equations of motion at the
    evaluation time ``t_n + time_fraction h`` as the unknown, the coordinates and rates there are

        q_eval = q_predictor + position_weight a,    v_eval = v_predictor + velocity_weight a.

    Attributes
    ----------
    q_predictor, v_predictor : ndarray
        Known parts [unit, unit/s].
    position_weight : float
        ``b' h^2`` [s^2].
    velocity_weight : float
        ``g' h`` [s]; a hinge law ``k q + c v`` contributes ``kappa = k b' h^2 + c g' h``.
    time_fraction : float
        Evaluation time as a fraction of the step [-] (1, or ``theta`` for Wilson-theta).
    coefficients : StepCoefficients or None
        The scheme's linearisation the step was derived from (for :meth:`Scheme.update`).
    known_acceleration : ndarray or None
        Generalized-alpha (Arnold & Bruls): the known part of the new algorithmic acceleration,
        ``a_{n+1} = (1 - af)/(1 - am) a + known_acceleration``.
    """

    q_predictor: np.ndarray
    v_predictor: np.ndarray
    position_weight: float
    velocity_weight: float
    time_fraction: float
    coefficients: StepCoefficients | None = None
    known_acceleration: np.ndarray | None = None


class Scheme:
    """Base class of DT-TMM time-integration schemes (frozen dataclasses)."""

    name: ClassVar[str] = "scheme"
    order: ClassVar[int] = 2
    start_up_steps: ClassVar[int] = 0
    """Steps after a start (``History.steps`` below it) that use the scheme's start-up formulas."""

    @property
    def restart_on_input_jump(self) -> bool:
        """Whether the stepper restarts the history (:meth:`restart`) where a held input jumps.

        True for multistep schemes (a start-up, :attr:`start_up_steps` > 0): their differences
        would span the jump of the acceleration a zero-order-held input makes, which costs one
        order; the one-step schemes only need the acceleration at the jump restarted.
        """
        return self.start_up_steps > 0

    def restart(self, history: History) -> None:
        """Forget the multistep memory of ``history`` in place: the next steps run the start-up.

        Called at a sample where a held input jumps (after the acceleration ``a_n`` was restarted
        with the new input): the steps from ``t_n`` then only difference states after the jump.
        """
        if self.restart_on_input_jump:
            history.steps = 0

    def coefficients(self, history: History, h: float) -> StepCoefficients:
        """Linearisation coefficients of the next step of size ``h`` [s]."""
        raise NotImplementedError

    def update(self, history: History, delta: np.ndarray, h: float, coeffs: StepCoefficients) -> History:
        """New history after the step, from the solved correction ``delta = x - x_pred``."""
        raise NotImplementedError

    def interpolate_force(self, f_unknown: np.ndarray, f_previous: np.ndarray) -> np.ndarray:
        """Internal forces at ``t_{n+1}`` from those solved at the evaluation level."""
        return f_unknown

    def second_order_step(self, history: History, h: float) -> SecondOrderStep:
        """The next step of size ``h`` [s] in the nonlinear form (module docstring).

        Derived from :meth:`coefficients`: with ``cx = 1`` and ``D = 0`` the acceleration at the
        evaluation level is ``a = C delta``, so ``x = x_pred + a / C`` and ``v = B + (A / C) a``.
        """
        coefficients = self.coefficients(history, h)
        if coefficients.cx != 1.0 or np.any(coefficients.D != 0.0):
            raise ModelError(f"scheme {self!r} has no nonlinear second-order form "
                             "(its evaluation level mixes two times)")
        weight = 1.0 / coefficients.C
        return SecondOrderStep(coefficients.x_pred, coefficients.B, weight, coefficients.A * weight,
                               coefficients.unknown_offset / h, coefficients)

    def second_order_update(self, history: History, acceleration: np.ndarray, h: float,
                            step: SecondOrderStep) -> History:
        """History at ``t_{n+1}`` from the acceleration solved at the evaluation level of ``step``."""
        new = self.update(history, step.position_weight * acceleration, h, step.coefficients)
        new.equation_acceleration = acceleration
        return new

    def start_history(self, x: np.ndarray, v: np.ndarray, a: np.ndarray) -> History:
        """History at the initial time: state ``x, v`` and the acceleration ``a`` it implies."""
        return History(x.copy(), v.copy(), a.copy(), [x.copy(), x.copy()], 0, a.copy())

    def stability_limit(self) -> float:
        """Largest stable ``omega h`` [-] on an undamped mode: ``inf`` if unconditionally stable.

        ``0`` means no step is stable (every undamped mode is amplified).  The base class, the
        backward-difference schemes (:class:`ForwardEuler`, :class:`Houbolt`) and
        :class:`GeneralizedAlpha` (``0 <= rho_infinity <= 1``) are unconditionally stable.
        """
        return math.inf


def _check_step(h: float) -> float:
    return validation.positive("dt", h)


def _arnold_bruls_step(beta: float, gamma: float, alpha_m: float, alpha_f: float, history: History,
                       h: float) -> SecondOrderStep:
    """Newmark relations on the algorithmic acceleration ``a`` of Arnold & Bruls (2007).

    ``(1 - am) a_{n+1} + am a_n = (1 - af) q''_{n+1} + af q''_n`` with the equations of motion
    exact at ``t_{n+1}``; ``a_{n+1} = f q''_{n+1} + a_known`` with ``f = (1 - af)/(1 - am)``.
    """
    h = _check_step(h)
    q, v, a = history.x, history.v, history.a
    xdd = a if history.equation_acceleration is None else history.equation_acceleration
    a_known = (alpha_f * xdd - alpha_m * a) / (1.0 - alpha_m)
    fac = (1.0 - alpha_f) / (1.0 - alpha_m)
    q_hat = q + h * v + h * h * (0.5 - beta) * a + beta * h * h * a_known
    v_hat = v + h * (1.0 - gamma) * a + gamma * h * a_known
    return SecondOrderStep(q_hat, v_hat, beta * fac * h * h, gamma * fac * h, 1.0, known_acceleration=a_known)


def _arnold_bruls_update(history: History, acceleration: np.ndarray, step: SecondOrderStep,
                         fac: float) -> History:
    return History(step.q_predictor + step.position_weight * acceleration,
                   step.v_predictor + step.velocity_weight * acceleration,
                   fac * acceleration + step.known_acceleration,
                   [history.x, history.x_old[0]], history.steps + 1, acceleration)


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

    def _predictor(self, history: History, h: float):
        """Newmark predictors and constants: ``x = x_pred + delta``, ``v = v_pred + A delta``, ``a = C delta``."""
        beta, gamma = self.beta, self.gamma
        x_pred = history.x + h * history.v + (0.5 - beta) * h * h * history.a
        v_pred = history.v + (1.0 - gamma) * h * history.a
        return x_pred, v_pred, gamma / (beta * h), 1.0 / (beta * h * h)

    def coefficients(self, history: History, h: float) -> StepCoefficients:
        x_pred, v_pred, A, C = self._predictor(history, _check_step(h))
        zero = np.zeros_like(history.x)
        return StepCoefficients(1.0, A, C, x_pred, v_pred, zero, h, 1.0, x_pred)

    def stability_limit(self) -> float:
        """Limit of :func:`ctmm.guard.newmark_limit`: ``inf`` for ``2 beta >= gamma >= 1/2``."""
        return newmark_limit(self.beta, self.gamma)

    def update(self, history, delta, h, coeffs):
        x_pred, v_pred, A, C = self._predictor(history, h)
        return History(x_pred + delta, v_pred + A * delta, C * delta, [history.x, history.x_old[0]],
                       history.steps + 1)

    def second_order_step(self, history: History, h: float) -> SecondOrderStep:
        """Arnold & Bruls' form with ``alpha_m = alpha_f = 0``: ``b' = beta``, ``g' = gamma``."""
        return _arnold_bruls_step(self.beta, self.gamma, 0.0, 0.0, history, h)

    def second_order_update(self, history, acceleration, h, step):
        return _arnold_bruls_update(history, acceleration, step, 1.0)


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

    def _newmark(self) -> Newmark:
        return Newmark(self.beta, self.gamma)

    def coefficients(self, history, h):
        x_pred, v_pred, A_n, C_n = self._newmark()._predictor(history, _check_step(h))
        am, af = self.alpha_m, self.alpha_f
        return StepCoefficients(
            cx=1.0 - af, A=(1.0 - af) * A_n, C=(1.0 - am) * C_n,
            dx=(1.0 - af) * x_pred + af * history.x, B=(1.0 - af) * v_pred + af * history.v,
            D=am * history.a, unknown_offset=h, load_weight=1.0 - af, x_pred=x_pred)

    def update(self, history, delta, h, coeffs):
        return self._newmark().update(history, delta, h, coeffs)

    def second_order_step(self, history: History, h: float) -> SecondOrderStep:
        """Arnold & Bruls' form: ``b' = beta (1 - af)/(1 - am)``, ``g' = gamma (1 - af)/(1 - am)``.

        The equations of motion hold exactly at ``t_{n+1}`` (no mixed evaluation level), which
        is what a nonlinear stepper needs; same order (2) and spectral radius ``rho_infinity``
        as Chung & Hulbert's form on linear systems.
        """
        return _arnold_bruls_step(self.beta, self.gamma, self.alpha_m, self.alpha_f, history, h)

    def second_order_update(self, history, acceleration, h, step):
        return _arnold_bruls_update(history, acceleration, step,
                                    (1.0 - self.alpha_f) / (1.0 - self.alpha_m))

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
        # a_tau = 6/tau^2 (x_tau - x_pred),  v_tau = v_pred + 3/tau (x_tau - x_pred)
        tau = self.theta * _check_step(h)
        x_pred = history.x + tau * history.v + tau * tau / 3.0 * history.a
        v_pred = history.v + 0.5 * tau * history.a
        return StepCoefficients(1.0, 3.0 / tau, 6.0 / tau ** 2, x_pred, v_pred, np.zeros_like(history.x),
                                tau, self.theta, x_pred)

    def stability_limit(self) -> float:
        """Limit of :func:`ctmm.guard.wilson_limit`: ``inf`` for ``theta >= 1.37``."""
        return wilson_limit(self.theta)

    def update(self, history, delta, h, coeffs):
        a_tau = coeffs.C * delta
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
    global order stays two.  The start-up runs again after every jump of a held input
    (:meth:`Scheme.restart`), which keeps sampled-data loops at order two (``docs/schemes.md``).
    """

    name: ClassVar[str] = "houbolt"
    start_up_steps: ClassVar[int] = 2

    def coefficients(self, history, h):
        h = _check_step(h)
        if history.steps < self.start_up_steps:
            return Newmark().coefficients(history, h)
        x1, (x2, x3) = history.x, history.x_old
        # a = 2/h^2 (x - x_pred), v = v_pred + 11/(6h) (x - x_pred): FORMULAS §3.1 rewritten
        x_pred = 0.5 * (5.0 * x1 - 4.0 * x2 + x3)
        v_pred = (19.0 * x1 - 26.0 * x2 + 7.0 * x3) / (12.0 * h)
        return StepCoefficients(1.0, 11.0 / (6.0 * h), 2.0 / h ** 2, x_pred, v_pred, np.zeros_like(x1),
                                h, 1.0, x_pred)

    def update(self, history, delta, h, coeffs):
        if history.steps < self.start_up_steps:
            return Newmark().update(history, delta, h, coeffs)
        return History(coeffs.x_pred + delta, coeffs.B + coeffs.A * delta, coeffs.C * delta,
                       [history.x, history.x_old[0]], history.steps + 1)


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
        # v = (x - x_n)/h = v_n + (x - x_pred)/h,  a = (v - v_n)/h = (x - x_pred)/h^2
        x_pred = history.x + h * history.v
        return StepCoefficients(1.0, 1.0 / h, 1.0 / h ** 2, x_pred, history.v.copy(),
                                np.zeros_like(history.x), h, 1.0, x_pred)

    def update(self, history, delta, h, coeffs):
        return History(coeffs.x_pred + delta, coeffs.B + coeffs.A * delta, coeffs.C * delta,
                       [history.x, history.x_old[0]], history.steps + 1)


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
