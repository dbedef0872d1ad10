"""The kernels of :class:`~ctmm.fem.GlobalSubsystem` as the planar code calls them
(:class:`ctmm.planar.deformable.DeformableFamily`).

The sweep and the implicit Newton step are inherited from :class:`ctmm.flexible.family.ModalBeamFamily`
(:class:`ctmm.flexible.kernel.FlexibleSystem`, :class:`ctmm.flexible.implicit.FlexibleNewtonStep`): they ask
each body with internal coordinates only for its terms (``data.terms``) and its number of internal
coordinates (``data.n``), so a subsystem runs through them unchanged.  Energy and the divergence check
are this family's own.
"""
from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from ..errors import SimulationError
from ..flexible.family import ModalBeamFamily
from ..flexible.outputs import divergence_reason

__all__ = ["SubsystemFamily", "SmallDeformationWarning", "subsystem_energy", "SMALL_DEFORMATION"]

#: Largest displacement of a subsystem node, as a fraction of the subsystem's size, inside the
#: small-deformation range of the floating frame; beyond it a :class:`SmallDeformationWarning` is issued.
SMALL_DEFORMATION = 0.1


class SmallDeformationWarning(UserWarning):
    """A subsystem deforms beyond :data:`SMALL_DEFORMATION` of its size: the linear elasticity in its
    floating frame no longer describes it (the run goes on; the answer is the model's, not the structure's)."""


def subsystem_energy(model: Any, q: np.ndarray, qdot: np.ndarray, t: float = 0.0) -> float:
    """Kinetic + gravitational + hinge-spring + subsystem strain energy [J] of a planar model whose
    bodies with internal coordinates are subsystems.

    The kinetic energy of a subsystem is ``xi^T M(u) xi / 2`` with ``xi = [v_I, omega, u_dot]`` and ``M``
    its mass matrix of the transfer relations (global axes); gravity ``-g . (m r_I + R s(u))``; strain
    ``u^T K u / 2``; the ``potential`` of a ``nonlinear_force`` (refused without it).
    """
    q, qdot = model.state(q, qdot)
    pts = model.points(q, qdot, t)
    g = model.gravity
    rigid = np.array([j for j in range(model.n_bodies) if j not in model.beams], dtype=int)
    velocity = pts["com_velocity"][rigid]
    energy = float(np.sum(0.5 * model.mass[rigid] * np.sum(velocity * velocity, axis=1)
                          + 0.5 * model.inertia[rigid] * pts["omega"][rigid] ** 2
                          - model.mass[rigid] * (pts["com"][rigid] @ g)))
    for j, body in model.beams.items():
        d = body.data
        eta, etad = q[model.modal_index[j]], qdot[model.modal_index[j]]
        th, w = pts["theta"][j], pts["omega"][j]
        M, _, _ = d.terms(np.array([th]), np.array([w]), eta[None], etad[None], t, (0.0, 0.0))
        xi = np.concatenate([pts["inboard_velocity"][j], [w], etad])
        sv = d.s0 + d.S1 @ eta
        rs = np.array([np.cos(th) * sv[0] - np.sin(th) * sv[1], np.sin(th) * sv[0] + np.cos(th) * sv[1]])
        energy += (0.5 * xi @ M[0] @ xi + 0.5 * eta @ d.K @ eta - g @ (d.m * pts["inboard"][j] + rs)
                   + d.nonlinear_energy(eta))
    dtheta, _ = model.relative_angles(pts["theta"], pts["omega"], q, qdot)
    reference, _, _ = model.hinge_laws(t)
    energy += 0.5 * np.sum(model.stiffness * (dtheta - reference) ** 2)
    return float(energy)


class SubsystemFamily(ModalBeamFamily):
    """Stateless: the sweep and Newton stepper of :class:`~ctmm.flexible.family.ModalBeamFamily` (generic over
    ``data.terms``), this family's divergence check and energy."""

    @staticmethod
    def check_divergence(model: Any, q: np.ndarray, t: float, dt: float | None, method: str) -> None:
        """Raise :class:`SimulationError` when a subsystem's displacement is larger than the subsystem itself
        (divergence); warn (:class:`SmallDeformationWarning`) beyond :data:`SMALL_DEFORMATION` of its size when
        it has a linear stiffness (the kinematics are exact for any displacement: only ``K u`` is linearised).
        The message decides the cause (:func:`ctmm.flexible.outputs.divergence_reason`): with ``"rk4"`` and a fixed
        step ``dt`` [s], a step above ``2 sqrt 2 / omega_max`` (the subsystem's highest clamped frequency
        ``eigh(K, M)`` or the model's linearised one, the larger) is named as the cause, else the model."""
        for j, body in model.beams.items():
            d = body.data
            u = np.asarray(q)[model.modal_index[j]]
            bound = float(np.max(np.abs(u[d.translational]), initial=0.0))
            if d.linear_elastic and np.isfinite(bound) and SMALL_DEFORMATION * d.size < bound <= d.size:
                warnings.warn(f"subsystem {body.name!r}: a node moves by more than {SMALL_DEFORMATION:g} of the "
                              f"subsystem's size {d.size:.3g} m: outside the small-deformation range of its floating "
                              "frame (docs/mixed.md §5)", SmallDeformationWarning, stacklevel=2)
            if not np.isfinite(bound) or bound > d.size:
                reason = divergence_reason(model, t, dt, method,
                                           "a compressive load above its buckling load, or loads that deform it "
                                           "beyond its size")
                raise SimulationError(
                    f"simulation diverged at t = {t:.6g} s: subsystem {body.name!r} displacement {bound:.3g} m exceeds "
                    f"its size {d.size:.3g} m (small deformation in the floating frame); {reason}", time=t,
                    element=body.name)

    @staticmethod
    def energy(model: Any, q: np.ndarray, qdot: np.ndarray, t: float) -> float:
        """:func:`subsystem_energy` [J]."""
        return subsystem_energy(model, q, qdot, t)
