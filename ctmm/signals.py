"""Time signals for external loads, prescribed motions and references.

Every signal is a callable ``f(t) -> float`` of time [s]; the helpers here add validation,
a readable ``repr`` and, where known, the harmonic amplitude used by the frequency domain and the
symbolic form used by generated code (:func:`symbolic_signal`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Sequence, Union

import numpy as np

from . import validation
from .errors import ModelError
from .guard import UserFunction

TimeFunction = Callable[[float], float]


@dataclass(frozen=True)
class Constant:
    """Constant signal ``value`` [unit of the signal]."""

    value: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", validation.finite("value", self.value))

    def __call__(self, t: float) -> float:
        return self.value


@dataclass(frozen=True)
class Harmonic:
    """``amplitude * sin(omega * t + phase)``.

    Parameters
    ----------
    amplitude : float
        Amplitude [unit of the signal].
    omega : float
        Angular frequency [rad/s], >= 0.
    phase : float
        Phase [rad].
    """

    amplitude: float
    omega: float
    phase: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "amplitude", validation.finite("amplitude", self.amplitude))
        object.__setattr__(self, "omega", validation.nonnegative("omega", self.omega))
        object.__setattr__(self, "phase", validation.finite("phase", self.phase))

    def __call__(self, t: float) -> float:
        return self.amplitude * math.sin(self.omega * t + self.phase)


@dataclass(frozen=True)
class Step:
    """Step of height ``value`` at time ``time`` [s] (0 before, ``value`` from ``time`` on)."""

    value: float
    time: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "value", validation.finite("value", self.value))
        object.__setattr__(self, "time", validation.finite("time", self.time))

    def __call__(self, t: float) -> float:
        return self.value if t >= self.time else 0.0


@dataclass(frozen=True)
class SquareWave:
    """Square wave: ``+amplitude`` for the first half of each period, ``-amplitude`` after.

    Parameters
    ----------
    amplitude : float
        Level [unit of the signal].
    period : float
        Period [s], > 0.
    duration : float, optional
        After this time [s] the signal is 0 (``inf`` = never).
    """

    amplitude: float
    period: float
    duration: float = math.inf

    def __post_init__(self) -> None:
        object.__setattr__(self, "amplitude", validation.finite("amplitude", self.amplitude))
        object.__setattr__(self, "period", validation.positive("period", self.period))
        if self.duration != math.inf:
            object.__setattr__(self, "duration", validation.positive("duration", self.duration))

    def __call__(self, t: float) -> float:
        if t < 0 or t >= self.duration:
            return 0.0
        return self.amplitude if (t % self.period) < 0.5 * self.period else -self.amplitude


@dataclass(frozen=True)
class Ramp:
    """Ramp ``offset + slope * max(t - start, 0)``: ``offset`` until ``start``, then rising at ``slope``.

    A crank turning at constant speed ``omega`` from ``theta0`` is ``Ramp(omega, theta0)`` (its rate the
    constant ``omega``, its acceleration 0); a force growing linearly from 0 is ``Ramp(slope)``.  A ramp
    has no steady-state harmonic amplitude: the frequency verbs refuse it (:func:`harmonic_amplitude`).

    Parameters
    ----------
    slope : float
        Rate of rise [unit of the signal / s].
    offset : float, optional
        Value until ``start`` [unit of the signal].
    start : float, optional
        Time the rise begins [s]; the signal's rate jumps from 0 to ``slope`` there.
    """

    slope: float
    offset: float = 0.0
    start: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "slope", validation.finite("slope", self.slope))
        object.__setattr__(self, "offset", validation.finite("offset", self.offset))
        object.__setattr__(self, "start", validation.finite("start", self.start))

    def __call__(self, t: float) -> float:
        return self.offset + self.slope * max(t - self.start, 0.0)

    def rate(self) -> Step:
        """The ramp's time derivative: ``slope`` from ``start`` on, 0 before [unit of the signal / s]."""
        return Step(self.slope, self.start)


SignalLike = Union[float, int, TimeFunction]


def as_signal(name: str, value: SignalLike) -> TimeFunction:
    """Turn a number or a callable of time into a validated time signal.

    Parameters
    ----------
    name : str
        Parameter name used in error messages.
    value : float or callable
        A constant or a function of time ``t`` [s] returning a float.
    """
    if callable(value):
        try:
            probe = float(value(0.0))
        except Exception as exc:  # noqa: BLE001 - report what the user's callable did
            raise ModelError(f"{name} must be callable as f(t) -> float; f(0.0) raised {exc!r}") from exc
        if not np.isfinite(probe):
            raise ModelError(f"{name}(0.0) must be finite, got {probe!r}")
        known = (Constant, Harmonic, Step, SquareWave, Ramp, UserFunction)
        return value if isinstance(value, known) else UserFunction(name, value)  # failures named (guard)
    return Constant(validation.finite(name, value))


def harmonic_amplitude(signal: TimeFunction) -> complex:
    """Complex amplitude of a signal in the frequency domain (phasor of ``e^{i w t}``).

    Constants and harmonics have one; other callables (a :class:`Step`, :class:`SquareWave`,
    :class:`Ramp` or a user function) are not steady-state signals and are refused by name.
    """
    if isinstance(signal, Constant):
        return complex(signal.value)
    if isinstance(signal, Harmonic):
        # a sin(wt + phi) = Im(a e^{i phi} e^{i w t}) -> phasor convention: Re(A e^{iwt}) with A = a e^{i(phi - pi/2)}
        return complex(signal.amplitude * np.exp(1j * (signal.phase - 0.5 * np.pi)))
    raise ModelError(f"signal {signal!r} has no steady-state harmonic amplitude; the "
                     "frequency domain takes ctmm.signals Constant or Harmonic signals only")


SYMBOLIC_FIELDS: dict[type, tuple[str, ...]] = {
    Constant: ("value",), Harmonic: ("amplitude", "omega", "phase"), Step: ("value", "time"),
    SquareWave: ("amplitude", "period", "duration"), Ramp: ("slope", "offset", "start")}
"""The signal classes with a symbolic form (:func:`symbolic_signal`) and the fields it takes, in order."""


def signal_parameters(signal: TimeFunction) -> tuple[float, ...] | None:
    """The numbers of a signal with a symbolic form (:data:`SYMBOLIC_FIELDS` order), ``None`` for any
    other callable (a user function has no symbolic form)."""
    fields = SYMBOLIC_FIELDS.get(type(signal))
    return None if fields is None else tuple(float(getattr(signal, name)) for name in fields)


def symbolic_signal(kind: type, t: Any, parameters: Sequence[Any]) -> Any:
    """The value at time ``t`` [s] of a signal of class ``kind`` with ``parameters`` (its
    :func:`signal_parameters`, numbers or casadi symbols), as a casadi expression: the same operations
    as the class's ``__call__``.

    Raises
    ------
    ModelError
        ``kind`` has no symbolic form.
    """
    import casadi as ca

    if kind is Constant:
        return parameters[0]
    if kind is Harmonic:
        amplitude, omega, phase = parameters
        return amplitude * ca.sin(omega * t + phase)
    if kind is Step:
        value, time = parameters
        return ca.if_else(t >= time, value, 0.0)
    if kind is SquareWave:
        amplitude, period, duration = parameters
        level = ca.if_else(ca.fmod(t, period) < 0.5 * period, amplitude, -amplitude)
        return ca.if_else(ca.logic_or(t < 0, t >= duration), 0.0, level)
    if kind is Ramp:
        slope, offset, start = parameters
        return offset + slope * ca.fmax(t - start, 0.0)
    raise ModelError(f"signal class {getattr(kind, '__name__', kind)!r} has no symbolic form; symbolic signals: "
                     + ", ".join(k.__name__ for k in SYMBOLIC_FIELDS))
