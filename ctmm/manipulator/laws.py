"""Parameters of the manipulator's control laws (seed 001 eqs. (9.64)-(9.65)) as immutable descriptions.

Nothing here closes a loop or integrates: :func:`~ctmm.manipulator.manipulator_scene` turns these
parameters into :class:`~ctmm.control.Feedback` loops on the scene's ports (run by
:func:`ctmm.simulate` and every other verb), and
:class:`~ctmm.manipulator.compiled.CompiledManipulator` compiles the same scene.

* :class:`HubPD` -- motor torque ``tau = kp (theta_d - theta) + kd (theta_d_dot - theta_dot)``
  evaluated at ``t - delay`` (FORMULAS §3.4: a damper/elastic hinge with moving rest angle).
* :class:`PZTFeedback` -- patch voltages ``V = -G dtheta_dot(t - delay)`` from the sensed
  slope-rate differences over the patches ``dtheta_dot_j = u_dot'(x2_j) - u_dot'(x1_j)``
  (the rate of a collocated PZT sensor signal).  In a modal model with modes ``phi_k`` the
  sensed value is ``Psi eta_dot`` (``Psi_jk = phi_k'(x2_j) - phi_k'(x1_j)``), so the law is the
  modal-velocity feedback ``V = -(G Psi) eta_dot``; the seed's eq. (9.65)
  ``V_i = -Ka_i sum_k [Y_k'(x2_i) - Y_k'(x1_i)] q_dot_k`` is ``G = diag(Ka_i)``
  (:meth:`PZTFeedback.per_patch`).  A law given on modal velocities
  ``V = -Ka eta_dot[:n]`` becomes ``G = Ka Psi_n^+`` (modal filter from the slope sensors,
  :meth:`PZTFeedback.modal`; exact when ``P = n`` and only those modes respond).

Voltage limit policy (``on_limit``): ``"report"`` (default: unsaturated loops; the demanded
voltages are the result's ``"<patch>.u"``, and :class:`~ctmm.manipulator.ManipulatorSimulation` of
the compiled path reports the peak and the time above the limit), ``"saturate"`` (each patch loop
clips at the limit, ``Feedback(saturation=...)``; a nonlinear loop, so time domain only),
``"raise"`` (only :class:`~ctmm.manipulator.compiled.CompiledManipulator`: a
:class:`~ctmm.errors.SimulationError` at the first stored violation after its run; the scene refuses it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import validation
from ..errors import ModelError

__all__ = ["HubPD", "PZTFeedback", "LIMIT_POLICIES", "check_pzt"]

LIMIT_POLICIES = ("report", "saturate", "raise")


@dataclass(frozen=True)
class HubPD:
    """PD motor law at the hub (seed eq. (9.64)).

    Parameters
    ----------
    kp : float
        Proportional gain [N m/rad], > 0 (a manipulator without it has no restoring torque).
    kd : float
        Derivative gain [N m s/rad], >= 0.
    delay : float
        Loop delay [s], >= 0 (measurement and reference both at ``t - delay``).
    """

    kp: float
    kd: float
    delay: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "kp", validation.positive("hub PD: kp", self.kp))
        object.__setattr__(self, "kd", validation.nonnegative("hub PD: kd", self.kd))
        object.__setattr__(self, "delay", validation.nonnegative("hub PD: delay", self.delay))


@dataclass(frozen=True)
class PZTFeedback:
    """Slope-rate (modal-velocity) feedback to the PZT patches.

    Parameters
    ----------
    gains : array (P, P)
        ``G`` [V s/rad]: ``V = -G dtheta_dot``.
    delay : float
        Loop delay [s], >= 0.
    on_limit : {"report", "saturate", "raise"}
        What happens when ``|V|`` exceeds the manipulator's ``voltage_limit``.
    """

    gains: np.ndarray
    delay: float = 0.0
    on_limit: str = "report"

    def __post_init__(self) -> None:
        G = validation.finite_array("PZT feedback: gains", self.gains)
        if G.ndim != 2 or G.shape[0] != G.shape[1]:
            raise ModelError(f"PZT feedback: gains must be a square (P, P) matrix [V s/rad], got shape {G.shape}")
        G = G.copy()
        G.setflags(write=False)
        object.__setattr__(self, "gains", G)
        object.__setattr__(self, "delay", validation.nonnegative("PZT feedback: delay", self.delay))
        if self.on_limit not in LIMIT_POLICIES:
            raise ModelError(f"PZT feedback: on_limit must be one of {LIMIT_POLICIES}, got {self.on_limit!r}")

    def __hash__(self) -> int:
        return hash((self.gains.tobytes(), self.gains.shape, self.delay, self.on_limit))

    def __eq__(self, other) -> bool:
        return (isinstance(other, PZTFeedback) and self.gains.shape == other.gains.shape
                and bool(np.all(self.gains == other.gains)) and self.delay == other.delay
                and self.on_limit == other.on_limit)

    @property
    def n_patches(self) -> int:
        return self.gains.shape[0]

    @classmethod
    def per_patch(cls, gains, *, delay: float = 0.0, on_limit: str = "report") -> "PZTFeedback":
        """Seed eq. (9.65): ``V_i = -Ka_i dtheta_dot_i`` (each patch fed by its own slope rate).

        ``gains`` ``Ka_i`` [V s/rad] must be >= 0 (a negative gain pumps energy into the arm).
        """
        g = validation.finite_array("PZT feedback: per-patch gains", gains, ndim=1)
        bad = [f"Ka_{i + 1} = {float(v)!r}" for i, v in enumerate(g) if v < 0]
        if bad:
            raise ModelError("PZT feedback: per-patch gains must be >= 0 [V s/rad] "
                             f"(negative velocity feedback destabilises), got {', '.join(bad)}")
        return cls(np.diag(g), delay=delay, on_limit=on_limit)

    @classmethod
    def modal(cls, modal_gains, slope_matrix, *, delay: float = 0.0, on_limit: str = "report") -> "PZTFeedback":
        """``V = -Ka eta_dot`` on ``n`` modal velocities estimated from the P slope sensors.

        Parameters
        ----------
        modal_gains : array (P, n)
            ``Ka`` [V per unit modal velocity] (modes as normalised by ``slope_matrix``).
        slope_matrix : array (P, n)
            ``Psi_jk = phi_k'(x2_j) - phi_k'(x1_j)`` of the same modes; needs ``n <= P`` and full
            column rank (the estimate is ``eta_dot ~ Psi^+ dtheta_dot``).
        """
        Ka = validation.finite_array("PZT feedback: modal_gains", modal_gains, ndim=2)
        Psi = validation.finite_array("PZT feedback: slope_matrix", slope_matrix, ndim=2)
        if Ka.shape != Psi.shape:
            raise ModelError(f"PZT feedback: modal_gains {Ka.shape} and slope_matrix {Psi.shape} must "
                             "have the same shape (patches, modes)")
        P, n = Psi.shape
        if n > P or np.linalg.matrix_rank(Psi) < n:
            raise ModelError(f"PZT feedback: {n} modal velocities cannot be estimated from {P} patch "
                             f"sensors (slope matrix rank {np.linalg.matrix_rank(Psi)})")
        return cls(Ka @ np.linalg.pinv(Psi), delay=delay, on_limit=on_limit)

    def modal_gains(self, slope_matrix) -> np.ndarray:
        """``G Psi``: the gains on the modal velocities of a modal model with slope matrix ``Psi``."""
        return self.gains @ np.asarray(slope_matrix, dtype=float)

    def voltages(self, slope_rates) -> np.ndarray:
        """``-G dtheta_dot`` [V] (no saturation)."""
        return -self.gains @ np.asarray(slope_rates, dtype=float)


def check_pzt(pzt: "PZTFeedback | None", n_patches: int) -> None:
    """Check the ``pzt`` argument of a manipulator with ``n_patches`` patches (``None``: no PZT loop).

    Raises
    ------
    ModelError
        ``pzt`` is not a :class:`PZTFeedback` or ``None``, or its gains are for another number of patches.
    """
    if pzt is None:
        return
    if not isinstance(pzt, PZTFeedback):
        raise ModelError(f"pzt must be a PZTFeedback or None, got {pzt!r}")
    if pzt.n_patches != n_patches:
        raise ModelError(f"pzt gains are for {pzt.n_patches} patches, the manipulator has {n_patches}")
