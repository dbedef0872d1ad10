"""A sampled static-gain controller: ``u = clip(K y, -limits, +limits)`` on named signals.

:class:`StaticGainController` is the generic co-simulated form of any memoryless linear output
feedback (a matrix of gains from measured signals to actuators, optionally saturated per output),
for example the manipulator's PZT slope-rate law read at the arm's station ports and written as the
patch moment pairs (``docs/manipulator.md`` §6): ``inputs`` the ``"arm.<patch>_x1|x2.slope_rate"``
stations, ``outputs`` the ``"arm.<patch>_x1|x2.moment"`` stations, ``K`` the product
``B_moment (-G) C_slope``.  It follows the :class:`~ctmm.control.protocol.Controller` protocol, so
:func:`ctmm.simulate` samples it on its grid and holds its outputs (zero-order hold).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from .protocol import ControllerStep

__all__ = ["StaticGainController"]


def _names(argument: str, value: Any) -> tuple[str, ...]:
    names = (value,) if isinstance(value, str) else tuple(value) if isinstance(value, (list, tuple)) else None
    if not names or not all(isinstance(name, str) and name for name in names) or len(set(names)) != len(names):
        raise ModelError(f"StaticGainController: {argument} must be a non-empty sequence of distinct signal "
                         f"names, got {value!r}")
    return names


@dataclass(frozen=True, eq=False)
class StaticGainController:
    """Memoryless linear output feedback ``u = K y`` with an optional symmetric limit per output.

    Parameters
    ----------
    inputs : sequence of str
        Measured signals ``y`` (ctmm sensor names) [their SI units].
    outputs : sequence of str
        Actuators ``u`` (ctmm actuator names) [their SI units].
    gains : array_like (len(outputs), len(inputs))
        ``K`` [actuator unit per sensor unit], finite.
    limits : array_like (len(outputs),) or None
        ``|u_i| <= limits_i`` [actuator unit], each > 0 (``inf`` for an unlimited output); ``None``:
        no saturation.
    sample_time : float or None
        Sample time [s], > 0 (zero-order hold by the stepper); ``None``: every integrator step.

    Notes
    -----
    The state is the number of samples at which some output was clipped (an ``int``).
    ``direct_feedthrough`` is True.

    Examples
    --------
    >>> c = StaticGainController(["m.x", "m.v"], ["m.force"], [[-40.0, -4.0]], limits=[5.0])
    >>> u, clipped = c.step(0.0, np.array([0.01, 2.0]), c.init(0.0))
    >>> float(u[0]), clipped
    (-5.0, 1)
    """

    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    gains: np.ndarray
    limits: np.ndarray | None = None
    sample_time: float | None = None

    direct_feedthrough = True

    def __post_init__(self) -> None:
        inputs, outputs = _names("inputs", self.inputs), _names("outputs", self.outputs)
        K = validation.finite_array("StaticGainController: gains", self.gains, ndim=2)
        if K.shape != (len(outputs), len(inputs)):
            raise ModelError(f"StaticGainController: gains must have shape ({len(outputs)}, {len(inputs)}) "
                             f"(outputs, inputs), got {K.shape}")
        K = K.copy()
        K.setflags(write=False)
        object.__setattr__(self, "inputs", inputs)
        object.__setattr__(self, "outputs", outputs)
        object.__setattr__(self, "gains", K)
        if self.limits is not None:
            try:
                limits = np.array(self.limits, dtype=float, ndmin=1) if not isinstance(self.limits, (str, bool)) \
                    else np.zeros(0)
            except (TypeError, ValueError):  # a mapping, text, complex numbers: refused below by name
                limits = np.zeros(0)
            if limits.shape != (len(outputs),) or np.any(np.isnan(limits)) or np.any(limits <= 0):
                raise ModelError(f"StaticGainController: limits must be {len(outputs)} values > 0 (inf: no limit) "
                                 f"[actuator unit], one per output, got {self.limits!r}")
            limits.setflags(write=False)
            object.__setattr__(self, "limits", limits)
        if self.sample_time is not None:
            object.__setattr__(self, "sample_time", validation.positive("StaticGainController: sample_time",
                                                                        self.sample_time))

    def init(self, t0: float = 0.0) -> int:
        """State at ``t0`` [s]: no clipped samples yet."""
        return 0

    def step(self, t: float, y: np.ndarray, state: int) -> ControllerStep:
        """``u = clip(K y)`` valid from ``t`` [s]; the state counts the clipped samples."""
        try:
            values = np.asarray(y, dtype=float)
        except (TypeError, ValueError):
            values = None
        if values is None or values.shape != (len(self.inputs),):
            raise SimulationError(f"StaticGainController: y must be {len(self.inputs)} real numbers ordered like "
                                  f"{self.inputs}, got {y!r} at t = {t!r} s", time=float(t))
        u = self.gains @ values
        if not np.all(np.isfinite(u)):
            raise SimulationError(f"StaticGainController: non-finite output at t = {t!r} s from inputs {y!r}",
                                  time=float(t))
        if self.limits is not None:
            clipped = np.clip(u, -self.limits, self.limits)
            return ControllerStep(clipped, state + int(np.any(clipped != u)))
        return ControllerStep(u, state)
