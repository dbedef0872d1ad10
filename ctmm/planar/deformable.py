"""Bodies with internal (modal) coordinates in a planar model: what the planar code needs of them.

:class:`~ctmm.planar.PlanarModel` and its sweep and integrators handle rigid bodies themselves;
a body family with internal coordinates (today :class:`ctmm.flexible.ModalBeam`) derives from
:class:`DeformableBody` and names, in its class attribute ``family``, the object that provides
its kernels (:class:`DeformableFamily`).  The planar package therefore never imports the family's
package: ``ctmm.flexible`` imports ``ctmm.planar``, not the other way round.
"""
from __future__ import annotations

from typing import Any, ClassVar, Protocol

import numpy as np

__all__ = ["DeformableBody", "DeformableFamily", "DeformableSystem", "DeformableNewtonStep"]


class DeformableSystem(Protocol):
    """Per-model data of the sweep with internal coordinates (built once, with the model)."""

    def solve(self, q: np.ndarray, qdot: np.ndarray, t: float, inputs: Any = None) -> Any:
        """Forward dynamics: an object with ``qddot``, ``body_acceleration``, ``joint_force``,
        ``hinge_acceleration`` and ``modal_acceleration``; ``inputs`` are actuator values
        (:class:`ctmm.planar.ports.ActuatorInputs`) added to the model's own loads."""

    def accelerations(self, q: np.ndarray, qdot: np.ndarray, t: float, inputs: Any = None) -> np.ndarray:
        """Generalised accelerations [rad/s^2, m/s^2], with optional actuator ``inputs``."""


class DeformableNewtonStep(Protocol):
    """Newton iteration of the implicit DT-TMM (the rigid one is in :mod:`ctmm.planar.implicit`)."""

    bh2: float
    gh: float

    def start(self, q: np.ndarray, v: np.ndarray, t: float) -> None:
        """Iterate data from the explicit solution at the initial state."""

    def sweep(self, q: np.ndarray, v: np.ndarray, t: float, A: Any, F: Any, x: np.ndarray,
              inputs: Any = None) -> tuple:
        """One Newton sweep: ``(body accelerations, joint forces, new coordinate accelerations)``;
        ``solve(linearise(q, v, t, A, F, x), inputs)``."""

    def linearise(self, q: np.ndarray, v: np.ndarray, t: float, A: Any, F: Any, x: np.ndarray) -> Any:
        """The tangent relations about the iterate, before actuator inputs."""

    def solve(self, tangent: Any, inputs: Any = None) -> tuple:
        """One sweep of ``tangent`` with actuator ``inputs`` (:class:`ctmm.planar.ports.ActuatorInputs`),
        as :meth:`sweep` returns it; the solution is the next iterate."""


class DeformableFamily(Protocol):
    """Kernels of one body family with internal coordinates, as the planar code calls them."""

    def system(self, model: Any) -> DeformableSystem:
        """The per-model sweep data of ``model`` (a :class:`~ctmm.planar.PlanarModel`)."""

    def newton_step(self, model: Any, bh2: float, gh: float) -> DeformableNewtonStep:
        """The implicit stepper (``bh2 = beta' h^2`` [s^2], ``gh = gamma' h`` [s])."""

    def check_divergence(self, model: Any, q: np.ndarray, t: float, dt: float | None, method: str) -> None:
        """Raise :class:`~ctmm.errors.SimulationError` when a deformation leaves the model's range."""

    def energy(self, model: Any, q: np.ndarray, qdot: np.ndarray, t: float) -> float:
        """Mechanical energy [J] of the whole model."""


class DeformableBody:
    """Base class of planar bodies with internal coordinates; ``family`` provides their kernels."""

    family: ClassVar[DeformableFamily]

    @property
    def coordinate_units(self) -> tuple[str, ...]:
        """Unit of each internal coordinate (order of ``coordinate_suffixes``): ``"m"``, the amplitudes of shapes
        without a unit (``ModalBeam``: ``w = phi . q``, ``u = psi . p``); a family with rotations overrides it."""
        return ("m",) * len(self.coordinate_suffixes)
