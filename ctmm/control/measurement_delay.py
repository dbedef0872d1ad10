"""A co-simulated controller that reads its measurements late: ``y(t - delay)``.

The controller protocol (:mod:`ctmm.control.protocol`) has no measurement delay: a controller
sampled at ``t`` reads the signals at ``t``.  :class:`DelayedController` wraps any controller
(Python object or :class:`~ctmm.control.fmu.FMUController`) and declares a ``measurement_delay``
[s]; the planar time stepper (:mod:`ctmm.control.planar_time`) then hands it the signals at
``t - delay`` from the one delay history of the run (cubic Hermite between steps; before the
start the initial state held).  Everything else -- sampling, zero-order hold, algebraic-loop
checks, the samples record -- is the co-simulation master's, unchanged.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ModelError
from .protocol import ControllerStep, check_controllers

__all__ = ["DelayedController"]


class DelayedController:
    """``controller`` fed with its inputs ``delay`` seconds late.

    Parameters
    ----------
    controller : Controller
        Any object of the controller protocol (validated here).
    delay : float
        Measurement delay [s], > 0 and finite; with a fixed-step method at least one step ``dt``.

    Attributes
    ----------
    inputs, outputs, sample_time, direct_feedthrough
        Those of ``controller``.
    measurement_delay : float
        ``delay`` [s].

    Raises
    ------
    ModelError
        ``controller`` is not a controller, or ``delay`` is not a finite number > 0.

    Examples
    --------
    >>> from ctmm.control.measurement_delay import DelayedController
    >>> class Zero:
    ...     inputs, outputs, sample_time, direct_feedthrough = ("arm.theta",), ("motor.torque",), 0.01, True
    ...     def init(self, t0): return None
    ...     def step(self, t, y, state): return [0.0], state
    >>> DelayedController(Zero(), 0.02).measurement_delay
    0.02
    """

    def __init__(self, controller: Any, delay: float) -> None:
        check_controllers([controller])
        if isinstance(delay, (bool, np.bool_)) or not isinstance(delay, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(delay) and delay > 0.0):
            raise ModelError(f"delay must be a finite measurement delay > 0 [s] (a number), got {delay!r:.80}")
        delay = float(delay)
        self.controller = controller
        self.measurement_delay = delay
        self.inputs = tuple(controller.inputs)
        self.outputs = tuple(controller.outputs)
        self.sample_time = getattr(controller, "sample_time", None)
        self.direct_feedthrough = bool(getattr(controller, "direct_feedthrough", False))
        self.name = getattr(controller, "name", None) or type(controller).__name__

    def init(self, t0: float) -> Any:
        """The wrapped controller's state at ``t0`` [s]."""
        return self.controller.init(t0)

    def step(self, t: float, y: np.ndarray, state: Any) -> ControllerStep:
        """The wrapped controller's step at ``t`` [s] with ``y`` measured at ``t - delay``."""
        return self.controller.step(t, y, state)

    def close(self, state: Any) -> None:
        """Release the wrapped controller's resources (if it has a ``close``)."""
        closer = getattr(self.controller, "close", None)
        if callable(closer):
            closer(state)

    def __repr__(self) -> str:
        return f"DelayedController({self.controller!r}, delay={self.measurement_delay!r})"
