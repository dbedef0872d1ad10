"""Saturated PD controller as a Python object (co-simulation controller of ctmm).

Law, evaluated at each call time ``t`` with the measurements ``x(t)``, ``v(t)``::

    u_raw = kp * (r(t) - x) + kd * (rdot(t) - v)
    u     = clip(u_raw, -limit, limit)                    (no clipping when limit is None)

The same law (with constant ``r`` and ``rdot = 0``) is compiled into the FMU
``controllers/fmu/pd_controller``; both give bit-identical outputs.
"""
from __future__ import annotations

import math
from dataclasses import KW_ONLY, dataclass, field
from typing import Any, Callable, Union

import numpy as np

from ctmm import validation
from ctmm.control.protocol import ControllerStep
from ctmm.errors import ModelError, SimulationError
from ctmm.signals import as_signal

SignalLike = Union[float, int, Callable[[float], float]]

__all__ = ["SaturatedPD", "SaturatedPDState"]


def signal_names(argument: str, value: Any, count: int, example: str) -> tuple[str, ...]:
    """Return ``value`` as a tuple of ``count`` ctmm signal names or raise :class:`ModelError`.

    A single string is accepted when ``count == 1``.
    """
    if isinstance(value, str):
        value = (value,)
    try:
        names = tuple(value)
    except TypeError:
        raise ModelError(f"{argument} must be a sequence of {count} signal name(s), e.g. {example}, "
                         f"got {value!r}") from None
    if len(names) != count:
        raise ModelError(f"{argument} must name exactly {count} signal(s), e.g. {example}, got {value!r}")
    for name in names:
        if not isinstance(name, str) or not name or any(ch.isspace() for ch in name):
            raise ModelError(f"{argument} must contain non-empty signal names without spaces, got {name!r}")
    return names


def saturate(u: float, limit: float | None) -> tuple[float, bool]:
    """Clip ``u`` to ``[-limit, limit]`` (no clipping for ``limit=None``); returns ``(u, saturated)``."""
    if limit is not None:
        if u > limit:
            return limit, True
        if u < -limit:
            return -limit, True
    return u, False


def optional_positive(argument: str, value: Any) -> float | None:
    """``None`` or a finite float > 0."""
    return None if value is None else validation.positive(argument, value)


@dataclass(frozen=True)
class SaturatedPDState:
    """State of a :class:`SaturatedPD` (immutable; a new one is returned by every step).

    Attributes
    ----------
    samples : int
        Number of completed calls.
    saturated_samples : int
        How many of them clipped the output to ``±limit``.
    last_saturated : bool
        Whether the most recent call clipped the output.
    """

    samples: int = 0
    saturated_samples: int = 0
    last_saturated: bool = False


@dataclass(frozen=True)
class SaturatedPD:
    """Proportional-derivative law with optional symmetric saturation.

    Parameters
    ----------
    inputs : tuple of 2 str
        Measured signals ``(position, velocity)``, e.g. ``("m6.x", "m6.v")`` [m, m/s] (or rad,
        rad/s for rotations).
    outputs : tuple of 1 str
        Actuator signal, e.g. ``("m2.force",)`` [N] (or N·m).  A single string is accepted.
    kp : float
        Proportional gain [actuator unit / position unit], e.g. [N/m].
    kd : float
        Derivative gain [actuator unit · s / position unit], e.g. [N·s/m].
    reference : float or callable, optional
        Set point ``r`` [position unit], a constant or a function ``r(t)`` of time [s].
    reference_rate : float or callable, optional
        ``rdot`` [position unit / s].  Default 0: the derivative acts on the measured velocity only
        ("derivative on measurement", no kick at reference steps).  Give ``r'(t)`` to track a
        moving reference with the error derivative.
    limit : float, optional
        Saturation level [actuator unit], > 0; ``None`` means no saturation.
    sample_time : float, optional
        Sample time [s], > 0, of a sampled controller (zero-order hold by the stepper), or
        ``None`` to be evaluated at every integrator step.

    Notes
    -----
    Stateless apart from the saturation bookkeeping in :class:`SaturatedPDState`; the output
    depends on the inputs at the same instant (``direct_feedthrough`` is True).

    Examples
    --------
    >>> import numpy as np
    >>> pd = SaturatedPD(("m6.x", "m6.v"), ("m2.force",), kp=40.0, kd=4.0, limit=5.0, sample_time=1e-3)
    >>> state = pd.init(0.0)
    >>> u, state = pd.step(0.0, np.array([0.01, -0.2]), state)
    >>> float(u[0]), state.saturated_samples
    (0.4, 0)
    """

    inputs: tuple[str, str]
    outputs: tuple[str]
    _: KW_ONLY
    kp: float
    kd: float
    reference: SignalLike = 0.0
    reference_rate: SignalLike = 0.0
    limit: float | None = None
    sample_time: float | None = None
    _r: Callable[[float], float] = field(init=False, repr=False, compare=False)
    _rdot: Callable[[float], float] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        setter = object.__setattr__
        setter(self, "inputs", signal_names("inputs", self.inputs, 2, "('m6.x', 'm6.v')"))
        setter(self, "outputs", signal_names("outputs", self.outputs, 1, "('m2.force',)"))
        setter(self, "kp", validation.finite("kp", self.kp))
        setter(self, "kd", validation.finite("kd", self.kd))
        setter(self, "limit", optional_positive("limit", self.limit))
        setter(self, "sample_time", optional_positive("sample_time", self.sample_time))
        setter(self, "_r", as_signal("reference", self.reference))
        setter(self, "_rdot", as_signal("reference_rate", self.reference_rate))

    @property
    def direct_feedthrough(self) -> bool:
        """Always True: ``u(t)`` depends on ``x(t)`` and ``v(t)``."""
        return True

    def init(self, t0: float = 0.0) -> SaturatedPDState:
        """Return the initial state (no samples yet) at time ``t0`` [s]."""
        validation.finite("t0", t0)
        return SaturatedPDState()

    def step(self, t: float, y: np.ndarray, state: SaturatedPDState) -> ControllerStep:
        """Evaluate the law at time ``t`` [s] for ``y = [position, velocity]``.

        Returns
        -------
        ControllerStep
            ``outputs`` of shape ``(1,)`` [actuator unit] and the next :class:`SaturatedPDState`.

        Raises
        ------
        SimulationError
            The output is not finite (e.g. a NaN measurement); ``error.time`` is ``t``.
        """
        position, velocity = float(y[0]), float(y[1])
        u = self.kp * (self._r(t) - position) + self.kd * (self._rdot(t) - velocity)
        u, saturated = saturate(u, self.limit)
        if not math.isfinite(u):
            raise SimulationError(f"SaturatedPD -> {self.outputs[0]}: non-finite output {u!r} at t = {t!r} "
                                  f"from {self.inputs[0]} = {position!r}, {self.inputs[1]} = {velocity!r}", time=t)
        next_state = SaturatedPDState(state.samples + 1, state.saturated_samples + saturated, saturated)
        return ControllerStep(np.array([u]), next_state)
