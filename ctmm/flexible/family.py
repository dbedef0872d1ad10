"""The kernels of :class:`~ctmm.flexible.ModalBeam` as the planar model calls them
(:class:`ctmm.planar.deformable.DeformableFamily`)."""
from __future__ import annotations

from typing import Any

import numpy as np

from .energy import flexible_energy
from .implicit import FlexibleNewtonStep
from .kernel import FlexibleSystem
from .outputs import check_divergence

__all__ = ["ModalBeamFamily"]


class ModalBeamFamily:
    """Stateless: the mixed rigid / modal-beam sweep, its Newton stepper, divergence check, energy."""

    @staticmethod
    def system(model: Any) -> FlexibleSystem:
        """The per-model sweep data (:class:`~ctmm.flexible.kernel.FlexibleSystem`)."""
        return FlexibleSystem(model)

    @staticmethod
    def newton_step(model: Any, bh2: float, gh: float) -> FlexibleNewtonStep:
        """The implicit DT-TMM stepper (``bh2 = beta' h^2`` [s^2], ``gh = gamma' h`` [s])."""
        return FlexibleNewtonStep(model, bh2, gh)

    @staticmethod
    def check_divergence(model: Any, q: np.ndarray, t: float, dt: float | None, method: str) -> None:
        """:func:`ctmm.flexible.outputs.check_divergence`."""
        check_divergence(model, q, t, dt, method)

    @staticmethod
    def energy(model: Any, q: np.ndarray, qdot: np.ndarray, t: float) -> float:
        """:func:`ctmm.flexible.energy.flexible_energy` [J]."""
        return flexible_energy(model, q, qdot, t)
