"""Closed-form rates of load and motion signals: what an ODE of a chain needs from a prescribed motion.

:func:`signal_derivatives` gives ``t -> (value, rate, second rate)`` for the signals whose derivatives
are known exactly (:class:`~ctmm.signals.Constant`, :class:`~ctmm.signals.Harmonic`, a
:class:`~ctmm.signals.Ramp` rising from ``start <= 0``); any other signal (a ramp starting later: its rate
jumps, its second rate is an impulse) is refused when its rates are needed (:mod:`ctmm.chain_ode`: a
prescribed start or wall motion, a varying force on a massless node).
"""
from __future__ import annotations

import math
from typing import Callable

from .errors import ModelError
from .signals import Constant, Harmonic, Ramp

__all__ = ["signal_derivatives"]


def signal_derivatives(owner: str, what: str, signal: Callable[[float], float]
                       ) -> Callable[[float], tuple[float, float, float]]:
    """``t -> (value, rate, second rate)`` of a signal whose derivatives are known exactly.

    For any other signal the returned function raises :class:`ModelError` when called (an ODE
    needs the rates of a prescribed motion, or of a force on a massless node, in closed form).
    """
    if isinstance(signal, Constant):
        value = signal.value
        return lambda t: (value, 0.0, 0.0)
    if isinstance(signal, Harmonic):
        a, w, p = signal.amplitude, signal.omega, signal.phase
        return lambda t: (a * math.sin(w * t + p), a * w * math.cos(w * t + p), -a * w * w * math.sin(w * t + p))
    if isinstance(signal, Ramp) and signal.start <= 0.0:
        ramp, slope = signal, signal.slope
        return lambda t: (ramp(t), slope if t >= ramp.start else 0.0, 0.0)

    def refuse(t: float) -> tuple[float, float, float]:
        raise ModelError(f"{owner}: the {what} signal {signal!r} has no closed-form rate, which an ODE method "
                         "needs (the velocity and acceleration of a prescribed motion, or the rate of a force on a "
                         "massless node); give a Constant, Harmonic or Ramp signal (a ramp with start <= 0: a later "
                         "start makes the rate jump and the second rate an impulse), or use a DT-TMM scheme "
                         "(method='newmark', ...)")

    return refuse
