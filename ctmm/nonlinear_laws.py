"""Nonlinear spring and damper laws: scalar constitutive laws ``f(delta, rate)`` as objects.

A law gives the **restoring** force [N] (or moment [N m]) a connector exerts against its deflection
``delta`` [m or rad] and deflection rate ``rate`` [m/s or rad/s]; the element applying it acts with
``-f(delta, rate)`` on its outboard side (for a planar hinge ``tau = -f(dtheta - rest, dtheta_dot)``).
Every law states its value, its analytic tangents ``(df/ddelta, df/drate)`` -- the tangent stiffness
and damping that the implicit DT-TMM Newton iteration and the linearisation about an operating point
use -- and, when it is conservative, its potential energy.

Laws (seed 002 section 7.6.1, Fig. 7.12 forms and their usual companions)

* :class:`LinearLaw` -- ``k delta + c rate`` (the linear hinges' law, for composition);
* :class:`CubicSpring` -- ``k1 delta + k2 delta^3`` (hardening ``k2 > 0``, softening ``k2 < 0``; the
  seed's ``q = K1 dl + K2 dl^3`` and ``M = K1 theta + K2 theta^3``);
* :class:`ClearanceSpring` -- piecewise linear: zero inside the clearance ``|delta| <= gap`` (dead
  zone), ``k (|delta| - gap)`` outside, and an optional stop adding ``k_stop (|delta| - stop)``
  beyond ``|delta| > stop``;
* :class:`PowerDamper` -- ``c rate (rate^2 + eps^2)^((n - 1) / 2)``: the power law ``c |rate|^n
  sign(rate)`` regularised near zero rate by ``eps`` (``regularization_rate``) so that its tangent
  ``df/drate`` stays finite for ``n < 1`` (``c eps^(n - 1)`` at rest); for ``|rate| >> eps`` the
  relative difference from the pure power law is about ``(n - 1) eps^2 / (2 rate^2)``;
* :class:`CallableLaw` -- a user function ``force(delta, rate)`` with its derivatives, or without
  them when ``force`` is written with casadi-compatible arithmetic (the derivatives then come from
  casadi's automatic differentiation).  Given derivatives are checked by central differences at
  construction.

Laws add: ``CubicSpring(...) + PowerDamper(...)`` is a spring parallel to a damper.

Evaluation (:meth:`Law.force`) accepts Python floats, numpy arrays and casadi symbols
(:attr:`Law.expressible`: whether casadi can express it -- generated kernels need that, and refuse
the other laws by name).  A **complex** numpy argument ``x + i y`` is evaluated as
``f(x) + i (f_delta y_delta + f_rate y_rate)``: exact for the complex-step tangents of the
linearisation whatever the law (kinks and user code included), since only first order in ``y`` is
ever used there.
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import Any, Callable

import numpy as np

from . import validation
from .errors import ModelError

__all__ = ["Law", "LinearLaw", "CubicSpring", "ClearanceSpring", "PowerDamper", "CallableLaw", "ParallelLaw",
           "is_symbolic"]


def is_symbolic(value: Any) -> bool:
    """True for casadi symbols (``SX``, ``MX``, ``DM``)."""
    return type(value).__module__.startswith("casadi")


def _select(condition_real: Any, a: Any, b: Any) -> Any:
    """``a`` where the (real) condition holds, else ``b``: casadi ``if_else`` for symbols, numpy ``where``
    (a Python ``bool`` condition -- a float compared -- picks ``a`` or ``b`` itself)."""
    if type(condition_real) is bool:
        return a if condition_real else b
    if is_symbolic(condition_real) or is_symbolic(a) or is_symbolic(b):
        import casadi
        return casadi.if_else(condition_real, a, b)
    return np.where(condition_real, a, b)


class Law(ABC):
    """A scalar constitutive law ``f(delta, rate)`` (module docstring): restoring force or moment."""

    #: casadi can express the law (generated kernels); ``False`` for user code without AD.
    expressible: bool = True

    def force(self, delta: Any, rate: Any = 0.0) -> Any:
        """Restoring force ``f(delta, rate)`` [N or N m] for floats, numpy arrays or casadi symbols.

        A complex numpy argument is evaluated to first order in its imaginary part (module docstring).
        """
        if type(delta) is float and type(rate) is float:     # the time loops' per-hinge call: no symbol, no complex
            return self._value(delta, rate)
        if is_symbolic(delta) or is_symbolic(rate):
            self._require_expressible()
            return self._value(delta, rate)
        if np.iscomplexobj(delta) or np.iscomplexobj(rate):
            d, v = np.asarray(delta), np.asarray(rate)
            stiffness, damping = self._tangents(d.real, v.real)
            return self._value(d.real, v.real) + 1j * (stiffness * d.imag + damping * v.imag)
        return self._value(delta, rate)

    def tangents(self, delta: Any, rate: Any = 0.0) -> tuple[Any, Any]:
        """``(df/ddelta, df/drate)``: tangent stiffness [N/m or N m/rad] and damping [N s/m or N m s/rad]."""
        if type(delta) is float and type(rate) is float:
            return self._tangents(delta, rate)
        if is_symbolic(delta) or is_symbolic(rate):
            self._require_expressible()
        elif np.iscomplexobj(delta) or np.iscomplexobj(rate):
            return self._tangents(np.real(delta), np.real(rate))
        return self._tangents(delta, rate)

    def _require_expressible(self) -> None:
        if not self.expressible:
            raise ModelError(f"law {self!r} is not expressible with casadi (user code without automatic "
                             "differentiation); generated kernels cannot hold it -- run without compiled=True, "
                             "or give CallableLaw a casadi-compatible force and no derivatives")

    def potential(self, delta: Any) -> Any:
        """Energy stored at deflection ``delta`` [J] (``f(delta, 0)`` integrated from 0); ``0`` for a pure
        damper.  :class:`CallableLaw` without a ``potential`` raises :class:`ModelError`."""
        return self._potential(delta)

    @property
    def velocity_dependent(self) -> bool:
        """Whether the law depends on the rate (dissipative part)."""
        return True

    @abstractmethod
    def _value(self, delta: Any, rate: Any) -> Any: ...

    @abstractmethod
    def _tangents(self, delta: Any, rate: Any) -> tuple[Any, Any]: ...

    @abstractmethod
    def _potential(self, delta: Any) -> Any: ...

    def __add__(self, other: "Law") -> "ParallelLaw":
        if not isinstance(other, Law):
            return NotImplemented
        return ParallelLaw(self, other)


class ParallelLaw(Law):
    """Laws acting in parallel: ``f = sum f_i``."""

    def __init__(self, *laws: Law) -> None:
        parts: list[Law] = []
        for law in laws:
            if not isinstance(law, Law):
                raise ModelError(f"ParallelLaw: every part must be a ctmm.nonlinear_laws.Law, got {law!r}")
            parts.extend(law.laws if isinstance(law, ParallelLaw) else (law,))
        if not parts:
            raise ModelError(f"ParallelLaw: laws must be one or more Law instances, got {list(laws)!r}")
        self.laws = tuple(parts)
        self.expressible = all(law.expressible for law in parts)

    def _value(self, delta, rate):
        total = self.laws[0]._value(delta, rate)
        for law in self.laws[1:]:
            total = total + law._value(delta, rate)
        return total

    def _tangents(self, delta, rate):
        pairs = [law._tangents(delta, rate) for law in self.laws]
        stiffness, damping = pairs[0]
        for k, c in pairs[1:]:
            stiffness, damping = stiffness + k, damping + c
        return stiffness, damping

    def _potential(self, delta):
        total = self.laws[0]._potential(delta)
        for law in self.laws[1:]:
            total = total + law._potential(delta)
        return total

    @property
    def velocity_dependent(self) -> bool:
        return any(law.velocity_dependent for law in self.laws)

    def __repr__(self) -> str:
        return " + ".join(repr(law) for law in self.laws)


class LinearLaw(Law):
    """``f = stiffness delta + damping rate``.

    Parameters
    ----------
    stiffness : float
        [N/m or N m/rad], >= 0.
    damping : float
        [N s/m or N m s/rad], >= 0.
    """

    def __init__(self, stiffness: float = 0.0, damping: float = 0.0) -> None:
        self.stiffness = validation.nonnegative("LinearLaw: stiffness", stiffness)
        self.damping = validation.nonnegative("LinearLaw: damping", damping)

    def _value(self, delta, rate):
        return delta * self.stiffness + rate * self.damping

    def _tangents(self, delta, rate):
        return self.stiffness + 0.0 * delta, self.damping + 0.0 * rate

    def _potential(self, delta):
        return 0.5 * self.stiffness * delta * delta

    @property
    def velocity_dependent(self) -> bool:
        return self.damping != 0.0

    def __repr__(self) -> str:
        return f"LinearLaw(stiffness={self.stiffness!r}, damping={self.damping!r})"


class CubicSpring(Law):
    """``f = linear_stiffness delta + cubic_stiffness delta^3`` (seed 002 Fig. 7.12).

    Parameters
    ----------
    linear_stiffness : float
        ``K1`` [N/m or N m/rad], >= 0.
    cubic_stiffness : float
        ``K2`` [N/m^3 or N m/rad^3]: > 0 hardening, < 0 softening (the tangent ``K1 + 3 K2 delta^2``
        vanishes at ``|delta| = sqrt(-K1 / (3 K2))``, beyond which a softening spring is unstable).
    """

    def __init__(self, linear_stiffness: float, cubic_stiffness: float) -> None:
        self.linear_stiffness = validation.nonnegative("CubicSpring: linear_stiffness", linear_stiffness)
        self.cubic_stiffness = validation.finite("CubicSpring: cubic_stiffness", cubic_stiffness)
        if self.linear_stiffness == 0.0 and self.cubic_stiffness <= 0.0:
            raise ModelError(f"CubicSpring: with linear_stiffness = 0 the cubic_stiffness must be > 0 (a spring), "
                             f"got {cubic_stiffness!r}")

    def _value(self, delta, rate):
        return delta * self.linear_stiffness + delta * delta * delta * self.cubic_stiffness + 0.0 * rate

    def _tangents(self, delta, rate):
        return self.linear_stiffness + 3.0 * self.cubic_stiffness * delta * delta, 0.0 * rate

    def _potential(self, delta):
        d2 = delta * delta
        return 0.5 * self.linear_stiffness * d2 + 0.25 * self.cubic_stiffness * d2 * d2

    @property
    def velocity_dependent(self) -> bool:
        return False

    def __repr__(self) -> str:
        return f"CubicSpring(linear_stiffness={self.linear_stiffness!r}, cubic_stiffness={self.cubic_stiffness!r})"


class ClearanceSpring(Law):
    """Piecewise-linear spring with a clearance (dead zone) and an optional stop.

    ``f = 0`` for ``|delta| <= clearance``; ``f = sign(delta) stiffness (|delta| - clearance)`` outside;
    beyond ``|delta| > stop`` the stop adds ``sign(delta) stop_stiffness (|delta| - stop)``.  The force
    is continuous, its tangent jumps at the corners (the implicit Newton uses the tangent of the side the
    iterate is on; a linearisation exactly at a corner is refused by the linearisation's kink check).

    Parameters
    ----------
    stiffness : float
        Stiffness outside the clearance [N/m or N m/rad], >= 0.
    clearance : float
        Half-width of the dead zone [m or rad], >= 0.
    stop : float, optional
        Deflection at which the stop engages [m or rad], > clearance.
    stop_stiffness : float, optional
        Additional stiffness of the stop [N/m or N m/rad], > 0; required with ``stop``.
    """

    def __init__(self, stiffness: float, *, clearance: float = 0.0, stop: float | None = None,
                 stop_stiffness: float | None = None) -> None:
        self.stiffness = validation.nonnegative("ClearanceSpring: stiffness", stiffness)
        self.clearance = validation.nonnegative("ClearanceSpring: clearance", clearance)
        if (stop is None) != (stop_stiffness is None):
            raise ModelError(f"ClearanceSpring: stop and stop_stiffness go together, got stop={stop!r}, "
                             f"stop_stiffness={stop_stiffness!r}")
        self.stop = None if stop is None else validation.finite("ClearanceSpring: stop", stop)
        self.stop_stiffness = None if stop_stiffness is None else validation.positive(
            "ClearanceSpring: stop_stiffness", stop_stiffness)
        if self.stop is not None and not self.stop > self.clearance:
            raise ModelError(f"ClearanceSpring: stop must be > clearance = {self.clearance!r}, got {stop!r}")
        if self.stiffness == 0.0 and self.stop is None:
            raise ModelError("ClearanceSpring: stiffness = 0 without a stop exerts no force; give stiffness > 0 "
                             "or a stop")

    @staticmethod
    def _ramp(delta, corner, stiffness):
        """``sign(delta) k (|delta| - corner)`` outside ``|delta| <= corner``, 0 inside; and its slope."""
        value = _select(delta > corner, (delta - corner) * stiffness,
                        _select(delta < -corner, (delta + corner) * stiffness, 0.0 * delta))
        slope = _select(delta > corner, stiffness + 0.0 * delta,
                        _select(delta < -corner, stiffness + 0.0 * delta, 0.0 * delta))
        return value, slope

    def _value(self, delta, rate):
        value, _ = self._ramp(delta, self.clearance, self.stiffness)
        if self.stop is not None:
            value = value + self._ramp(delta, self.stop, self.stop_stiffness)[0]
        return value + 0.0 * rate

    def _tangents(self, delta, rate):
        _, slope = self._ramp(delta, self.clearance, self.stiffness)
        if self.stop is not None:
            slope = slope + self._ramp(delta, self.stop, self.stop_stiffness)[1]
        return slope, 0.0 * rate

    def _potential(self, delta):
        def energy(corner, k):
            outside = _select(delta > corner, delta - corner, _select(delta < -corner, delta + corner, 0.0 * delta))
            return 0.5 * k * outside * outside
        total = energy(self.clearance, self.stiffness)
        if self.stop is not None:
            total = total + energy(self.stop, self.stop_stiffness)
        return total

    @property
    def velocity_dependent(self) -> bool:
        return False

    def __repr__(self) -> str:
        return (f"ClearanceSpring(stiffness={self.stiffness!r}, clearance={self.clearance!r}, stop={self.stop!r}, "
                f"stop_stiffness={self.stop_stiffness!r})")


class PowerDamper(Law):
    """Power-law damper ``f = coefficient rate (rate^2 + eps^2)^((exponent - 1) / 2)`` (module docstring).

    Parameters
    ----------
    coefficient : float
        ``c`` [N (s/m)^n or N m (s/rad)^n], > 0.
    exponent : float
        ``n`` > 0 (``n = 1``: linear viscous; ``n = 2``: quadratic (turbulent) damping; ``n < 1``:
        softening, e.g. friction-like dampers).
    regularization_rate : float, optional
        ``eps`` [m/s or rad/s]: below this rate the law turns linear with slope ``c eps^(n - 1)``.
        Required (> 0) when ``exponent < 1``; default 0 (the exact power law) for ``exponent >= 1``.
    """

    def __init__(self, coefficient: float, exponent: float, *, regularization_rate: float | None = None) -> None:
        self.coefficient = validation.positive("PowerDamper: coefficient", coefficient)
        self.exponent = validation.positive("PowerDamper: exponent", exponent)
        if regularization_rate is None:
            if self.exponent < 1.0:
                raise ModelError(f"PowerDamper: exponent = {exponent!r} < 1 has an infinite tangent at zero rate; "
                                 "give regularization_rate > 0 [m/s or rad/s]")
            regularization_rate = 0.0
        self.regularization_rate = validation.nonnegative("PowerDamper: regularization_rate", regularization_rate)
        if self.exponent < 1.0 and self.regularization_rate == 0.0:
            raise ModelError(f"PowerDamper: exponent = {exponent!r} < 1 needs regularization_rate > 0, got 0")

    def _value(self, delta, rate):
        n, eps2 = self.exponent, self.regularization_rate ** 2
        if n == 1.0:
            return rate * self.coefficient + 0.0 * delta
        return rate * self.coefficient * (rate * rate + eps2) ** (0.5 * (n - 1.0)) + 0.0 * delta

    def _tangents(self, delta, rate):
        n, eps2 = self.exponent, self.regularization_rate ** 2
        if n == 1.0:
            return 0.0 * delta, self.coefficient + 0.0 * rate
        r2 = rate * rate + eps2
        if eps2:   # d/dv [v r2^p] = r2^(p - 1) (r2 + (n - 1) v^2), p = (n - 1) / 2
            slope = self.coefficient * r2 ** (0.5 * (n - 3.0)) * (r2 + (n - 1.0) * rate * rate)
        else:      # exact power law, n > 1: n c |v|^(n - 1)
            slope = self.coefficient * n * r2 ** (0.5 * (n - 1.0))
        return 0.0 * delta, slope

    def _potential(self, delta):
        return 0.0 * delta

    def __repr__(self) -> str:
        return (f"PowerDamper(coefficient={self.coefficient!r}, exponent={self.exponent!r}, "
                f"regularization_rate={self.regularization_rate!r})")


_CHECK_POINTS = ((-0.31, -0.7), (0.013, 0.21), (0.47, -0.05), (1.3, 1.7))


class CallableLaw(Law):
    """A user law ``force(delta, rate) -> float`` with its derivatives (or casadi AD).

    Parameters
    ----------
    force : callable
        ``force(delta, rate)`` [N or N m], the restoring value (module docstring).
    stiffness, damping : callable, optional
        ``df/ddelta (delta, rate)`` and ``df/drate (delta, rate)``.  Both given: checked against central
        differences of ``force`` at a few points (:data:`_CHECK_POINTS`, scaled by ``scale``).  Both
        omitted: ``force`` must accept casadi symbols; the derivatives come from casadi's automatic
        differentiation and the law is casadi-expressible (generated kernels).
    potential : callable, optional
        ``V(delta)`` [J] for energy checks (``force(delta, 0) = dV/ddelta``, checked likewise).
    scale : (float, float)
        Typical ``(delta, rate)`` magnitudes for the derivative checks [m or rad, m/s or rad/s].
    name : str
        Label in messages.
    """

    def __init__(self, force: Callable[[float, float], float], *, stiffness: Callable | None = None,
                 damping: Callable | None = None, potential: Callable | None = None,
                 scale: tuple[float, float] = (1.0, 1.0), name: str = "user law") -> None:
        if not callable(force):
            raise ModelError(f"CallableLaw {name!r}: force must be callable force(delta, rate), got {force!r}")
        if not isinstance(name, str) or not name.strip():
            raise ModelError(f"CallableLaw name must be a non-empty string, got {name!r:.80}")
        self.name = name
        self.function = force
        if not isinstance(scale, (tuple, list)) or len(scale) != 2:
            raise ModelError(f"CallableLaw {name!r}: scale must be two numbers (delta, rate) > 0, got {scale!r:.80}")
        self.scale = (validation.positive(f"CallableLaw {name!r}: scale[0]", scale[0]),
                      validation.positive(f"CallableLaw {name!r}: scale[1]", scale[1]))
        self.potential_function = validation.callable_or_none(f"CallableLaw {name!r}: potential", potential)
        for label, value in (("stiffness", stiffness), ("damping", damping)):
            validation.callable_or_none(f"CallableLaw {name!r}: {label}", value)
        if (stiffness is None) != (damping is None):
            raise ModelError(f"CallableLaw {name!r}: give both stiffness and damping derivatives or neither "
                             "(casadi automatic differentiation)")
        if stiffness is None:
            self._casadi_derivatives()
        else:
            self.stiffness_function, self.damping_function = stiffness, damping
            self.expressible = False
        self._check()

    def _casadi_derivatives(self) -> None:
        import casadi
        d, v = casadi.SX.sym("delta"), casadi.SX.sym("rate")
        try:
            f = self.function(d, v)
            f = casadi.SX(f)
        except Exception as exc:  # noqa: BLE001 - user code, named with what it did
            raise ModelError(f"CallableLaw {self.name!r}: without stiffness and damping derivatives, force must "
                             f"accept casadi symbols (automatic differentiation); it raised {type(exc).__name__}: "
                             f"{exc}") from exc
        self._expression = str(f)        # the law's content: part of its repr (generated-kernel structure keys)
        self._casadi = casadi.Function(self.name.replace(" ", "_") or "law", [d, v],
                                       [f, casadi.jacobian(f, d), casadi.jacobian(f, v)])
        self._rate_dependent = bool(casadi.depends_on(f, v))   # structural: exact for the casadi form
        self.stiffness_function = lambda a, b: self._numeric(1, a, b)
        self.damping_function = lambda a, b: self._numeric(2, a, b)
        self.expressible = True

    def _numeric(self, output: int, delta: Any, rate: Any) -> Any:
        d, v = np.broadcast_arrays(np.asarray(delta, float), np.asarray(rate, float))
        values = np.array([float(self._casadi(a, b)[output]) for a, b in zip(d.ravel(), v.ravel())])
        return values.reshape(d.shape) if d.shape else float(values[0])

    def _call(self, label: str, function: Callable, *args: Any) -> float:
        try:
            return float(function(*args))
        except Exception as exc:  # noqa: BLE001 - user code, named with what it did
            raise ModelError(f"CallableLaw {self.name!r}: {label}{args} raised {type(exc).__name__}: {exc}") from exc

    def _check(self) -> None:
        step = 1e-6
        for a, b in _CHECK_POINTS:
            d, v = a * self.scale[0], b * self.scale[1]
            hd, hv = step * self.scale[0], step * self.scale[1]
            f = lambda x, y: self._call("force", self.function, x, y)  # noqa: E731
            checks = [("stiffness", (f(d + hd, v) - f(d - hd, v)) / (2 * hd),
                       self._call("stiffness", self.stiffness_function, d, v)),
                      ("damping", (f(d, v + hv) - f(d, v - hv)) / (2 * hv),
                       self._call("damping", self.damping_function, d, v))]
            if self.potential_function is not None:
                p = lambda x: self._call("potential", self.potential_function, x)  # noqa: E731
                checks.append(("force(delta, 0) as dV/ddelta", (p(d + hd) - p(d - hd)) / (2 * hd), f(d, 0.0)))
            for label, numeric, given in checks:
                if not math.isfinite(given) or abs(numeric - given) > 1e-5 * max(1.0, abs(given), abs(numeric)):
                    raise ModelError(f"CallableLaw {self.name!r}: {label} at delta = {d!r}, rate = {v!r} is "
                                     f"{given!r}, but central differences of force give {numeric!r}")

    def _value(self, delta, rate):
        if is_symbolic(delta) or is_symbolic(rate):
            return self._casadi(delta, rate)[0]
        return self._vectorised(self.function, delta, rate)

    @staticmethod
    def _vectorised(function: Callable, delta: Any, rate: Any) -> Any:
        if np.ndim(delta) == 0 and np.ndim(rate) == 0:
            return float(function(float(delta), float(rate)))
        d, v = np.broadcast_arrays(np.asarray(delta, float), np.asarray(rate, float))
        return np.array([float(function(a, b)) for a, b in zip(d.ravel(), v.ravel())]).reshape(d.shape)

    def _tangents(self, delta, rate):
        if is_symbolic(delta) or is_symbolic(rate):
            _, stiffness, damping = self._casadi(delta, rate)
            return stiffness, damping
        return (self._vectorised(self.stiffness_function, delta, rate),
                self._vectorised(self.damping_function, delta, rate))

    @property
    def velocity_dependent(self) -> bool:
        """Whether the law depends on the rate: from the casadi form's structure; with given derivatives, assumed."""
        return self.__dict__.get("_rate_dependent", True)

    def _potential(self, delta):
        if self.potential_function is None:
            raise ModelError(f"CallableLaw {self.name!r}: no potential was given; energy needs potential=V(delta)")
        if np.ndim(delta) == 0:
            return float(self.potential_function(float(delta)))
        return np.array([float(self.potential_function(x)) for x in np.ravel(delta)]).reshape(np.shape(delta))

    def __repr__(self) -> str:
        expression = self.__dict__.get("_expression")
        return f"CallableLaw({self.name!r})" if expression is None else f"CallableLaw({self.name!r}, force={expression})"
