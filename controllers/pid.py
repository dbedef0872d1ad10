"""Discrete PID controller with a filtered derivative (Python object, stateful, sampled).

Notation (sample ``k`` at time ``t_k``, sample time ``h`` [s], error ``e_k = r(t_k) - y_k``)::

    P_k     = kp * e_k
    D_k     = a * D_{k-1} + b * (e_k - e_{k-1}),     a = Tf / (Tf + h),  b = kd / (Tf + h)
    u_k     = clip(P_k + ki * I_k + D_k, -limit, limit)
    I_{k+1} = I_k + h * e_k                          (skipped while saturated in the direction of e_k)

Discretisation:

* derivative: **backward Euler** of ``Tf * D' + D = kd * e'`` (the filter ``kd s / (Tf s + 1)``);
  it is stable and free of ringing for every ``Tf >= 0``, and for ``Tf = 0`` reduces to the
  backward difference ``kd (e_k - e_{k-1}) / h``.  On the first sample ``e_{-1} = e_0`` (no kick).
* integral: **forward Euler** ``I_{k+1} = I_k + h e_k``, i.e. the exact integral of the error held
  on ``[t_k, t_k + h)`` (zero-order hold), so ``u_k`` uses only past errors through ``I_k``.
  With ``kd = 0`` and no limit this is the law of the FMU ``controllers/fmu/pi_controller``.
* anti-windup: conditional integration (clamping) when ``limit`` is given.
"""
from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass, field
from typing import Callable, Union

import numpy as np

from ctmm import validation
from ctmm.control.protocol import ControllerStep
from ctmm.errors import SimulationError
from ctmm.signals import as_signal

from .pd import optional_positive, signal_names, saturate

SignalLike = Union[float, int, Callable[[float], float]]

__all__ = ["PID", "PIDState"]


@dataclass(frozen=True)
class PIDState:
    """State of a :class:`PID` (immutable; a new one is returned by every step).

    Attributes
    ----------
    integral : float
        ``I_k``, the integral of the error [measurement unit · s].
    derivative : float
        ``D_{k-1}``, the filtered derivative term of the last sample [actuator unit].
    previous_error : float or None
        ``e_{k-1}`` [measurement unit]; ``None`` before the first sample.
    samples : int
        Number of completed samples.
    saturated_samples : int
        Samples whose output was clipped to ``±limit``.
    """

    integral: float = 0.0
    derivative: float = 0.0
    previous_error: float | None = None
    samples: int = 0
    saturated_samples: int = 0


@dataclass(frozen=True)
class PID:
    """Sampled PID law with first-order derivative filter and optional saturation.

    Parameters
    ----------
    inputs : tuple of 1 str
        Measured signal, e.g. ``("m6.x",)`` [measurement unit].  A single string is accepted.
    outputs : tuple of 1 str
        Actuator signal, e.g. ``("m2.force",)`` [actuator unit].  A single string is accepted.
    kp : float
        Proportional gain [actuator unit / measurement unit].
    ki : float
        Integral gain [actuator unit / (measurement unit · s)].
    kd : float
        Derivative gain [actuator unit · s / measurement unit].
    derivative_filter_time : float
        Time constant ``Tf`` [s], >= 0, of the derivative filter ``kd s / (Tf s + 1)``.
    sample_time : float
        Sample time ``h`` [s], > 0; :meth:`step` must be called once per sample.
    reference : float or callable, optional
        Set point ``r`` [measurement unit], constant or ``r(t)``.
    limit : float, optional
        Saturation level [actuator unit], > 0, with clamping anti-windup; ``None``: no limit.

    Examples
    --------
    >>> import numpy as np
    >>> pid = PID("m6.x", "m2.force", kp=2.0, ki=1.0, kd=0.0, derivative_filter_time=0.0, sample_time=0.5)
    >>> state = pid.init(0.0)
    >>> u, state = pid.step(0.0, np.array([-1.0]), state)   # e = 1: u = kp e + ki I_0 = 2
    >>> u, state = pid.step(0.5, np.array([-1.0]), state)   # I_1 = h e = 0.5: u = 2 + 0.5
    >>> float(u[0])
    2.5
    """

    inputs: tuple[str]
    outputs: tuple[str]
    _: KW_ONLY
    kp: float
    ki: float
    kd: float
    derivative_filter_time: float
    sample_time: float
    reference: SignalLike = 0.0
    limit: float | None = None
    _r: Callable[[float], float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        setter = object.__setattr__
        setter(self, "inputs", signal_names("inputs", self.inputs, 1, "('m6.x',)"))
        setter(self, "outputs", signal_names("outputs", self.outputs, 1, "('m2.force',)"))
        setter(self, "kp", validation.finite("kp", self.kp))
        setter(self, "ki", validation.finite("ki", self.ki))
        setter(self, "kd", validation.finite("kd", self.kd))
        setter(self, "derivative_filter_time",
               validation.nonnegative("derivative_filter_time", self.derivative_filter_time))
        setter(self, "sample_time", validation.positive("sample_time", self.sample_time))
        setter(self, "limit", optional_positive("limit", self.limit))
        setter(self, "_r", as_signal("reference", self.reference))

    @property
    def direct_feedthrough(self) -> bool:
        """True unless ``kp = kd = 0`` (a pure I law uses only past errors)."""
        return self.kp != 0.0 or self.kd != 0.0

    def init(self, t0: float = 0.0) -> PIDState:
        """Return the initial state at time ``t0`` [s]: zero integral, no previous error."""
        validation.finite("t0", t0)
        return PIDState()

    def step(self, t: float, y: np.ndarray, state: PIDState) -> ControllerStep:
        """Compute ``u_k`` from ``y_k = y[0]`` at ``t = t_k`` [s] and advance the state to ``k + 1``.

        Raises
        ------
        SimulationError
            The output is not finite (e.g. a NaN measurement); ``error.time`` is ``t``.
        """
        h = self.sample_time
        tf = self.derivative_filter_time
        error = self._r(t) - float(y[0])
        previous = error if state.previous_error is None else state.previous_error
        derivative = (tf * state.derivative + self.kd * (error - previous)) / (tf + h)
        u = self.kp * error + self.ki * state.integral + derivative
        u, saturated = saturate(u, self.limit)
        if not math.isfinite(u):
            raise SimulationError(f"PID -> {self.outputs[0]}: non-finite output {u!r} at t = {t!r} from "
                                  f"{self.inputs[0]} = {float(y[0])!r}", time=t)
        # clamping anti-windup: do not integrate further into the saturation
        winds_up = saturated and (u > 0.0) == (self.ki * error > 0.0)
        integral = state.integral if winds_up else state.integral + h * error
        next_state = PIDState(integral, derivative, error, state.samples + 1,
                              state.saturated_samples + saturated)
        return ControllerStep(np.array([u]), next_state)
