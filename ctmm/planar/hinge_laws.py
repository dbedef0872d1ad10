"""Nonlinear hinge laws of a planar model (:class:`~ctmm.planar.elements.NonlinearHinge`), vectorised.

A :class:`~ctmm.planar.model.PlanarModel` lists its nonlinear hinges in ``model.nonlinear_hinges``
(``{body index: hinge}``; their linear coefficients in ``model.stiffness``, ``model.damping`` are 0).
Every consumer of the hinge moments adds :func:`law_torques`; the implicit DT-TMM Newton iteration
adds :func:`law_kappa` (the law's tangent at the iterate) to its ``kappa``; the energy adds
:func:`law_potential`.  The frequency verbs need nothing here: they linearise the sweep about the
operating point, where the hinge terms of :class:`~ctmm.planar.body_forms.PlanarScene`
(:func:`law_joint_terms`, :func:`radial_terms`) carry the laws' tangents.

Radial spring (``radial_law``): with the offset ``d`` of the child's inboard end from the parent end,
``r = sqrt(d . d + r0^2)`` (``r0 = 1e-150`` m keeps ``d / r`` defined at ``d = 0`` and changes nothing
else), ``g = f(r) / r`` and the force on the child ``F = -g d``; its tangent
``dF/dd = -(g I + (f'(r) - g) d d^T / r^2)``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["law_torques", "law_kappa", "law_potential", "law_joint_terms", "radial_terms", "radial_force"]

_R0_SQUARED = 1e-300


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
        if hinge.moment_law is not None:
            stiffness, damping = hinge.moment_law.tangents(float(dtheta[j]) - hinge.rest_angle, float(domega[j]))
            kappa[j] = float(stiffness) * bh2 + float(damping) * gh
    return kappa


def law_potential(model: Any, dtheta: np.ndarray, q: Any = None) -> float:
    """Energy stored in the nonlinear hinges' springs [J] (radial springs need the coordinates ``q``)."""
    total = 0.0
    for j, hinge in model.nonlinear_hinges.items():
        if hinge.moment_law is not None:
            total += float(hinge.moment_law.potential(float(dtheta[j]) - hinge.rest_angle))
        if hinge.radial_law is not None:
            ix, iy = model.xy_index[j]
            total += float(hinge.radial_law.potential(float(np.hypot(q[ix], q[iy]))))
    return total


def law_joint_terms(ops: Any, hinge: Any, angle: Any, rate: Any, torque: Any) -> tuple[Any, Any, Any]:
    """``(tau, tau_q, tau_v)`` scalars of a nonlinear hinge's moment at relative ``angle`` [rad], ``rate``
    [rad/s] (ops scalars: numpy batches, complex for complex-step tangents, or casadi symbols), plus the
    input ``torque`` [N m]."""
    if hinge.moment_law is None:
        return torque + 0.0 * angle, 0.0 * angle, 0.0 * rate
    delta = angle - hinge.rest_angle
    stiffness, damping = hinge.moment_law.tangents(delta, rate)
    return torque - hinge.moment_law.force(delta, rate), -stiffness, -damping


def radial_terms(ops: Any, hinge: Any, dx: Any, dy: Any) -> tuple[Any, Any, Any, Any, Any]:
    """Force ``(f_x, f_y)`` [N] of a radial spring on the child at the offset ``(dx, dy)`` [m] and its tangent
    ``dF/dd`` entries ``(k_xx, k_xy, k_yy)`` [N/m] (module docstring; ops scalars as :func:`law_joint_terms`)."""
    law = hinge.radial_law
    r = ops.sqrt(dx * dx + dy * dy + _R0_SQUARED)
    g = law.force(r, 0.0 * r) / r
    slope = law.tangents(r, 0.0 * r)[0]
    h = (slope - g) / (r * r)
    return -g * dx, -g * dy, -(g + h * dx * dx), -(h * dx * dy), -(g + h * dy * dy)


def radial_force(hinge: Any, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Numeric force (2,) [N] on the child and tangent ``dF/dd`` (2, 2) [N/m] of a radial spring."""
    from ..ops import NUMPY

    fx, fy, kxx, kxy, kyy = radial_terms(NUMPY, hinge, float(offset[0]), float(offset[1]))
    return np.array([fx, fy], dtype=float), np.array([[kxx, kxy], [kxy, kyy]], dtype=float)
