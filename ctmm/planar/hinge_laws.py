"""Nonlinear hinge laws of a planar model (:class:`~ctmm.planar.elements.NonlinearHinge`), vectorised.

A :class:`~ctmm.planar.model.PlanarModel` lists its nonlinear hinges in ``model.nonlinear_hinges``
(``{body index: hinge}``; their linear coefficients in ``model.stiffness``, ``model.damping`` are 0).
Every consumer of the hinge moments adds :func:`law_torques`; the implicit DT-TMM Newton iteration
adds :func:`law_kappa` (the law's tangent at the iterate) to its ``kappa``; the energy adds
:func:`law_potential`.  The frequency verbs need nothing here: they linearise the sweep about the
operating point, where the hinge terms of :class:`~ctmm.planar.body_forms.PlanarScene` carry the
law's tangents.
"""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["law_torques", "law_kappa", "law_potential", "law_joint_terms"]


def law_torques(model: Any, dtheta: np.ndarray, domega: np.ndarray) -> np.ndarray:
    """Moments ``-law(dtheta - rest, domega)`` [N m] of the nonlinear hinges, 0 for every other body."""
    torque = np.zeros(model.n_bodies)
    for j, hinge in model.nonlinear_hinges.items():
        torque[j] = float(hinge.moment(float(dtheta[j]), float(domega[j])))
    return torque


def law_kappa(model: Any, dtheta: np.ndarray, domega: np.ndarray, bh2: float, gh: float) -> np.ndarray:
    """``k_t bh2 + c_t gh`` of the nonlinear hinges' tangent stiffness ``k_t`` and damping ``c_t`` at
    ``(dtheta, domega)`` (the DT-TMM Newton ``kappa``; 0 for every other body)."""
    kappa = np.zeros(model.n_bodies)
    for j, hinge in model.nonlinear_hinges.items():
        stiffness, damping = hinge.moment_law.tangents(float(dtheta[j]) - hinge.rest_angle, float(domega[j]))
        kappa[j] = float(stiffness) * bh2 + float(damping) * gh
    return kappa


def law_potential(model: Any, dtheta: np.ndarray) -> float:
    """Energy stored in the nonlinear hinges' springs [J]."""
    return float(sum(float(hinge.moment_law.potential(float(dtheta[j]) - hinge.rest_angle))
                     for j, hinge in model.nonlinear_hinges.items()))


def law_joint_terms(ops: Any, hinge: Any, angle: Any, rate: Any, torque: Any) -> tuple[Any, Any, Any]:
    """``(tau, tau_q, tau_v)`` scalars of a nonlinear hinge at relative ``angle`` [rad], ``rate`` [rad/s]
    (ops scalars: numpy batches, complex for complex-step tangents, or casadi symbols), plus the input
    ``torque`` [N m]."""
    delta = angle - hinge.rest_angle
    stiffness, damping = hinge.moment_law.tangents(delta, rate)
    return torque - hinge.moment_law.force(delta, rate), -stiffness, -damping
