"""Integrating a model-exchange FMU between communication points (used by :class:`FMUController`).

A model-exchange FMU provides derivatives, event indicators and event handling but no solver.
:class:`ModelExchangeIntegrator` advances it over one communication step ``[t, t + h]`` with the
inputs held:

* classical fourth-order Runge-Kutta with a fixed step ``solver_step`` (the communication step is
  split into ``ceil(h / solver_step)`` equal steps; there is **no error control**: the user
  chooses the step; the global error is O(solver_step**4)),
* time events (``nextEventTime``) are hit exactly: the step is shortened to end on them,
* state events (a sign change of an event indicator over a step) are located by bisection of the
  RK4 step length to ``event_tolerance`` [s], then handled (event mode, discrete-state
  iteration, continuous-time mode) and the integration restarts from the event,
* ``completedIntegratorStep`` is called after every accepted step (step events are honoured),
* discrete inputs are set in event mode at every communication point (the caller enters event
  mode, sets them and calls :meth:`ModelExchangeIntegrator.settle`).

A sign change caused by an input change at a communication point, or two sign changes of the
same indicator within one solver step, are not seen (as in any fixed-step scheme).
"""
from __future__ import annotations

import ctypes
import math
from typing import Any

import numpy as np

from ..ode import rk4_step

__all__ = ["ModelExchangeIntegrator", "ModelExchangeTerminated"]


class ModelExchangeTerminated(Exception):
    """The FMU asked to terminate the simulation during an event."""


class ModelExchangeIntegrator:
    """Fixed-step RK4 with time and located state events for one model-exchange instance.

    Parameters
    ----------
    instance : fmpy.fmi2.FMU2Model or fmpy.fmi3.FMU3Model
        Instantiated and initialized (``exitInitializationMode`` done) FMU.
    major : int
        FMI major version (2 or 3).
    n_states, n_indicators : int
        Numbers of continuous states and event indicators from the model description.
    solver_step : float
        Largest RK4 step [s].
    event_tolerance : float
        Width [s] to which state events are located.
    max_events : int
        Most events handled within one communication step, beyond one step event per RK4 step;
        more is reported as chattering.
    """

    def __init__(self, instance: Any, major: int, n_states: int, n_indicators: int, solver_step: float,
                 event_tolerance: float = 1e-12, max_events: int = 10_000) -> None:
        self.instance = instance
        self.major = major
        self.n_states = n_states
        self.n_indicators = n_indicators
        self.solver_step = solver_step
        self.event_tolerance = event_tolerance
        self.max_events = max_events
        self.events = 0
        self.next_event_time: float | None = None
        self._x = (ctypes.c_double * max(n_states, 1))()
        self._dx = (ctypes.c_double * max(n_states, 1))()
        self._z = (ctypes.c_double * max(n_indicators, 1))()
        self._x_view = np.ctypeslib.as_array(self._x)[:n_states]
        self._dx_view = np.ctypeslib.as_array(self._dx)[:n_states]
        self._z_view = np.ctypeslib.as_array(self._z)[:n_indicators]
        if major == 2:
            self._get_derivatives = instance.getDerivatives
        else:
            self._get_derivatives = instance.getContinuousStateDerivatives

    # -- FMU evaluations
    def _set(self, t: float, x: np.ndarray) -> None:
        self.instance.setTime(t)
        if self.n_states:
            self._x_view[:] = x
            self.instance.setContinuousStates(self._x, self.n_states)

    def _derivatives(self, t: float, x: np.ndarray) -> np.ndarray:
        self._set(t, x)
        if not self.n_states:
            return np.zeros(0)
        self._get_derivatives(self._dx, self.n_states)
        return self._dx_view.copy()

    def _indicators(self) -> np.ndarray:
        if not self.n_indicators:
            return np.zeros(0)
        self.instance.getEventIndicators(self._z, self.n_indicators)
        return self._z_view.copy()

    def _states(self) -> np.ndarray:
        if not self.n_states:
            return np.zeros(0)
        self.instance.getContinuousStates(self._x, self.n_states)
        return self._x_view.copy()

    def _rk4(self, t: float, x: np.ndarray, dt: float) -> np.ndarray:
        return rk4_step(self._derivatives, t, x, dt)

    # -- events
    def _event_iteration(self) -> None:
        """Discrete-state iteration in event mode, then continuous-time mode."""
        update = self.instance.newDiscreteStates if self.major == 2 else self.instance.updateDiscreteStates
        for _ in range(1000):
            needed, terminate, _, _, defined, next_time = update()
            if terminate:
                raise ModelExchangeTerminated("the FMU requested termination (terminateSimulation = true) "
                                              "during event handling")
            if not needed:
                break
        else:
            raise ModelExchangeTerminated("the discrete-state iteration did not settle in 1000 rounds")
        self.next_event_time = float(next_time) if defined else None
        self.instance.enterContinuousTimeMode()

    def start(self) -> None:
        """After ``exitInitializationMode``: settle the discrete states and enter continuous time."""
        self._event_iteration()

    def settle(self) -> None:
        """In event mode (e.g. after discrete inputs were set): iterate, enter continuous time."""
        self._event_iteration()
        self.events += 1

    @staticmethod
    def _crossed(z_a: np.ndarray, z_b: np.ndarray) -> bool:
        return bool(np.any((z_a > 0.0) != (z_b > 0.0)))

    def advance(self, t: float, h: float) -> None:
        """Integrate from ``t`` to ``t + h`` [s] with the inputs held; handles events on the way.

        Raises
        ------
        fmpy.fmi1.FMICallException
            An FMI call failed (the caller names the FMU and time).
        ModelExchangeTerminated
            The FMU asked to stop.
        """
        steps = max(1, math.ceil(h / self.solver_step - 1e-9))
        events_before = self.events
        t_a = t
        x_a = self._states()
        self._set(t_a, x_a)
        z_a = self._indicators()
        for i in range(1, steps + 1):
            t_b = t + h * i / steps if i < steps else t + h
            while t_a < t_b:
                target = t_b
                time_event = self.next_event_time is not None and self.next_event_time <= t_b
                if time_event:
                    target = max(self.next_event_time, t_a)
                x_b = self._rk4(t_a, x_a, target - t_a) if target > t_a else x_a
                self._set(target, x_b)
                z_b = self._indicators()
                state_event = self.n_indicators > 0 and self._crossed(z_a, z_b)
                if state_event:
                    target, x_b = self._locate(t_a, x_a, z_a, target)
                    time_event = False
                self._set(target, x_b)
                step_event, terminate = self.instance.completedIntegratorStep()
                if terminate:
                    raise ModelExchangeTerminated("the FMU requested termination in completedIntegratorStep")
                if state_event or time_event or step_event:
                    self.instance.enterEventMode()
                    self._event_iteration()
                    self.events += 1
                    if self.events - events_before > self.max_events + steps:  # one step event per step is fine
                        raise ModelExchangeTerminated(f"more than {self.max_events} events between t = {t!r} s and "
                                                      f"{t + h!r} s (chattering); last event at {target!r} s")
                    if self.next_event_time is not None and self.next_event_time <= target:
                        raise ModelExchangeTerminated(f"the FMU announced its next time event at "
                                                      f"{self.next_event_time!r} s, not after the current "
                                                      f"time {target!r} s")
                    x_b = self._states()
                    self._set(target, x_b)
                    z_b = self._indicators()
                t_a, x_a, z_a = target, x_b, z_b

    def _locate(self, t_a: float, x_a: np.ndarray, z_a: np.ndarray, t_b: float) -> tuple[float, np.ndarray]:
        """Bisect the RK4 step length until the sign change is bracketed within the tolerance."""
        low, high = 0.0, t_b - t_a
        x_high = None
        while high - low > self.event_tolerance * max(1.0, abs(t_a)):
            middle = 0.5 * (low + high)
            x_m = self._rk4(t_a, x_a, middle)
            self._set(t_a + middle, x_m)
            if self._crossed(z_a, self._indicators()):
                high, x_high = middle, x_m
            else:
                low = middle
        if x_high is None:
            x_high = self._rk4(t_a, x_a, high)
        return t_a + high, x_high
