"""Time histories of a compiled manipulator run (:class:`ManipulatorSimulation`): the result of
:class:`~ctmm.manipulator.compiled.CompiledManipulator` (``docs/manipulator.md`` §6; the scene run by
:func:`ctmm.simulate` returns the general :class:`~ctmm.results.SimulationResult`)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["ManipulatorSimulation"]


@dataclass(frozen=True)
class ManipulatorSimulation:
    """Time histories of a manipulator simulation (arrays over the stored times ``t``).

    ``theta``/``theta_dot`` hub angle [rad] and rate, ``desired`` reference angle, ``q``/``q_dot``
    modal coordinates of the arm (beam normalisation, [m]), ``tip_deflection`` ``u(L)`` in the hub
    frame [m], ``voltages`` ``(nt, P)`` applied patch voltages [V] (after saturation),
    ``torque`` motor torque [N m]; the voltage report: ``voltage_limit``, ``peak_voltage`` (before
    saturation), ``time_over_limit`` [s], ``saturated`` (per stored time); ``extra`` holds each
    co-simulated controller output under ``"<output>@samples"`` (columns: sample time [s], value
    as returned by the controller, before saturation).
    """

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    desired: np.ndarray
    q: np.ndarray
    q_dot: np.ndarray
    tip_deflection: np.ndarray
    voltages: np.ndarray
    torque: np.ndarray
    method: str
    dt: float
    wall_time_s: float
    n_evaluations: int
    voltage_limit: float
    peak_voltage: float
    time_over_limit: float
    saturated: np.ndarray
    iterations: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    @property
    def real_time_factor(self) -> float:
        """Simulated time / wall time (> 1: faster than real time)."""
        return float((self.t[-1] - self.t[0]) / self.wall_time_s) if self.wall_time_s > 0 else math.inf

    @property
    def limit_exceeded(self) -> bool:
        return self.peak_voltage > self.voltage_limit

    def plot(self, axes=None, *, label: str | None = None, patch: int = 0):
        """Seed Fig. 9.43 panels: (a) desired and actual hub angle, (b) tip deflection, (c) voltage."""
        import matplotlib.pyplot as plt

        if axes is None:
            _, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 8))
        axes[0].plot(self.t, np.degrees(self.theta), label=label or "actual")
        axes[0].set_ylabel("theta [deg]")
        axes[1].plot(self.t, 1e3 * self.tip_deflection, label=label)
        axes[1].set_ylabel("tip deflection [mm]")
        if self.voltages.shape[1]:
            axes[2].plot(self.t, self.voltages[:, patch], label=label)
        axes[2].set_ylabel(f"V_{patch + 1} [V]")
        axes[2].set_xlabel("t [s]")
        return axes
