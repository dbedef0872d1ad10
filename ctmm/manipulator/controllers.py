"""The PZT law as a co-simulation controller (``ctmm.control.protocol.Controller``).

:class:`SlopeRateFeedback` is :class:`~ctmm.manipulator.PZTFeedback` as a sampled Python
object: ``V = clip(-G dtheta_dot, +-limit)`` from the patch slope-rate signals
``"<patch>.slope_rate"`` of :class:`~ctmm.manipulator.FlexibleManipulator` to the voltages
``"<patch>.voltage"``.  Together with :class:`ctmm.controllers.SaturatedPD` on
``("hub.theta", "hub.theta_dot") -> "motor.torque"`` it reproduces the embedded laws as the
sample time shrinks (first order in the sample time, zero-order hold).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .. import validation
from ..control.protocol import ControllerStep
from ..errors import ModelError, SimulationError

__all__ = ["SlopeRateFeedback"]


@dataclass(frozen=True)
class SlopeRateFeedback:
    """Sampled ``V = -G dtheta_dot`` with optional saturation.

    Parameters
    ----------
    patches : sequence of str
        Patch names (inputs ``"<patch>.slope_rate"``, outputs ``"<patch>.voltage"``).
    gains : array (P, P)
        ``G`` [V s/rad].
    limit : float or None
        Saturation ``|V| <= limit`` [V].
    sample_time : float or None
        [s]; ``None``: every integrator step.
    """

    patches: Sequence[str]
    gains: np.ndarray
    limit: float | None = None
    sample_time: float | None = None

    def __post_init__(self) -> None:
        names = tuple(self.patches)
        G = validation.finite_array("gains", self.gains, ndim=2)
        if G.shape != (len(names), len(names)):
            raise ModelError(f"gains must be ({len(names)}, {len(names)}) for patches {names}, got {G.shape}")
        object.__setattr__(self, "patches", names)
        object.__setattr__(self, "gains", G)
        if self.limit is not None:
            object.__setattr__(self, "limit", validation.positive("limit", self.limit))
        if self.sample_time is not None:
            object.__setattr__(self, "sample_time", validation.positive("sample_time", self.sample_time))

    def __hash__(self) -> int:
        return hash((self.patches, self.gains.tobytes(), self.limit, self.sample_time))

    @property
    def inputs(self) -> tuple[str, ...]:
        return tuple(f"{p}.slope_rate" for p in self.patches)

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(f"{p}.voltage" for p in self.patches)

    direct_feedthrough = True

    def init(self, t0: float = 0.0) -> int:
        """State: number of saturated samples."""
        return 0

    def step(self, t: float, y: np.ndarray, state: int) -> ControllerStep:
        V = -self.gains @ np.asarray(y, dtype=float)
        saturated = 0
        if self.limit is not None and np.any(np.abs(V) > self.limit):
            V = np.clip(V, -self.limit, self.limit)
            saturated = 1
        if not np.all(np.isfinite(V)):
            raise SimulationError(f"SlopeRateFeedback: non-finite voltage at t = {t!r}", time=t)
        return ControllerStep(V, state + saturated)
