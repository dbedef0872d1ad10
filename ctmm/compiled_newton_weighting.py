"""The mass-weighted Newton tangent of the generated DT-TMM step of planar models (issue 13).

The Python stepper (:func:`ctmm.planar.implicit.simulate_implicit`) iterates on the transfer form of the
equations of motion: each iteration is one sweep of the body relations linearised about the iterate, which is
Newton's method on the **mass-weighted** residual ``R(a) = M(q) (a - qddot(q, v))`` with
``q = q_hat + b' h^2 a``, ``v = v_hat + g' h a`` (the joint forces and body accelerations of the transfer form
are linear in ``a`` at a given configuration).  Newton on the plain residual ``r(a) = a - qddot(q, v)`` has
the same root and the same quadratic convergence near it, but other iterates far from it: on a steep step
(a beam near divergence) one may converge where the other cycles.  So the generated step
(:mod:`ctmm.compiled_scene_schemes`) iterates on ``R`` as well: with ``G(q) = M(q)^-1`` read as the derivative
of the sweep's accelerations with respect to unit generalised forces ``u`` (``qddot`` is affine in them),

``dR/da = M (I - b' h^2 d qddot/dq - g' h d qddot/dv) + (dM/dq b' h^2) r``,
``M^-1 (dM/dq x) r = -(d/dq (G(q) s)) x`` with ``s = G^-1 r``,

so Newton's step ``delta = (dR/da)^-1 R`` is ``(J - b' h^2 d(G s)/dq)^-1 r`` with ``J`` the plain tangent:
one extra term that vanishes at the root (``r = 0``), the iterates of the Python stepper to round-off.
With the tangent by mapped forward derivatives (:mod:`ctmm.mapped_tangent`, from 8 coordinates) no second
derivative is formed: ``qddot`` is affine in the forces ``f`` and ``G`` depends on ``q`` alone, so
``J - b' h^2 d(G s)/dq`` is the forward derivative of ``qddot(q, v, [u; s])`` (:func:`mapped_weighted_residual`).

The generalised forces are the hinge torques of revolute hinges and the modal forces of modal beams (their
map to the coordinates is constant, so any such basis gives the same Newton iterates).  A model with other
coordinates (free bases, bushings) has no such basis here: :func:`generalized_force_units` returns ``None``
and the generated step keeps the plain residual (a documented difference: same root, same stopping rule).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .compiled_scene import symbolic_accelerations_with_inputs
from .compiled_scene_fold import folded_accelerations_with_inputs
from .flexible.beam import ModalBeam
from . import mapped_tangent
from .mapped_tangent import mapped_columns
from .planar.model import REVOLUTE, PlanarModel
from .planar.ports import ActuatorInputs

__all__ = ["generalized_force_units", "inverse_mass_terms", "mapped_weighted_residual", "weighted_residual_terms"]


def generalized_force_units(model: PlanarModel) -> list[ActuatorInputs] | None:
    """Unit generalised forces, one per coordinate: a hinge torque [N m] per revolute hinge coordinate and a
    modal force per modal coordinate of a :class:`~ctmm.flexible.ModalBeam`; ``None`` when the model has other
    coordinates (free bases, bushings, other deformable bodies)."""
    nb = model.n_bodies
    units = []
    for j in range(nb):
        if model.theta_index[j] >= 0:
            if model.joint_kind[j] != REVOLUTE:
                return None
            torque = np.zeros(nb)
            torque[j] = 1.0
            units.append(ActuatorInputs(torque, np.zeros((nb, 3))))
        size = len(model.modal_index[j])
        if size and not isinstance(model.beams.get(j), ModalBeam):
            return None
        for k in range(size):
            pattern = np.zeros(size)
            pattern[k] = 1.0
            units.append(ActuatorInputs(np.zeros(nb), np.zeros((nb, 3)), {j: pattern}))
    return units if len(units) == model.n_coordinates else None


def inverse_mass_terms(model: PlanarModel, mapped: bool = False) -> Any:
    """``(inverse_mass(q, v, p, t) -> G, inverse_mass_derivative(q, v, p, t, s) -> d(G s)/dq)`` (casadi
    ``Function`` s): ``G = M(q)^-1`` of the coordinates in the basis of :func:`generalized_force_units`
    and the derivative of ``G s`` at fixed ``s``; ``None`` where that basis does not exist.  ``mapped``: their
    columns by mapped forward derivatives of the sweep (:mod:`ctmm.mapped_tangent`, code O(sweep), on MX)
    instead of symbolic Jacobians of it (SX, code growing as ``N^2 .. N^3``); the same numbers to round-off."""
    import casadi as ca

    units = generalized_force_units(model)
    if units is None:
        return None
    acceleration = symbolic_accelerations_with_inputs(model, (), units)
    n = model.n_coordinates
    if mapped:
        return _mapped_inverse_mass_terms(acceleration, n)
    q, v, u, s = (ca.SX.sym(label, n) for label in ("q", "v", "u", "s"))
    p, t = ca.SX.sym("p", acceleration.sparsity_in(3)), ca.SX.sym("t")
    rates = acceleration(q, v, u, p, t)
    inverse = ca.substitute(ca.jacobian(rates, u), u, ca.SX.zeros(n))
    product = ca.substitute(ca.jtimes(rates, u, s), u, ca.SX.zeros(n))      # G s: one directional derivative
    return (ca.Function("inverse_mass", [q, v, p, t], [inverse]),
            ca.Function("inverse_mass_derivative", [q, v, p, t, s], [ca.jacobian(product, q)]))


def _mapped_inverse_mass_terms(acceleration: Any, n: int) -> Any:
    """The pair of :func:`inverse_mass_terms` from ``acceleration(q, v, u, p, t)`` by mapped forward
    derivatives (one forward derivative of the sweep, no second one): ``G`` the derivatives along the unit
    inputs at ``u = 0``; ``d(G s)/dq = d qddot(q, v, s)/dq - d qddot(q, v, 0)/dq`` since ``qddot`` is affine in
    the inputs (``G s = qddot(q, v, s) - qddot(q, v, 0)``), both along the unit coordinates."""
    import casadi as ca

    q, v, s = (ca.MX.sym(label, n) for label in ("q", "v", "s"))
    p, t, zero = ca.MX.sym("p", acceleration.sparsity_in(3)), ca.MX.sym("t"), ca.MX.zeros(n)
    inverse = mapped_columns(acceleration, [2], n, "inverse_mass_columns")(q, v, zero, p, t, ca.DM.eye(n))
    along_q = mapped_columns(acceleration, [0], n, "position_columns")
    derivative = along_q(q, v, s, p, t, ca.DM.eye(n)) - along_q(q, v, zero, p, t, ca.DM.eye(n))
    return (ca.Function("inverse_mass", [q, v, p, t], [inverse]),
            ca.Function("inverse_mass_derivative", [q, v, p, t, s], [derivative]))


def mapped_weighted_residual(model: PlanarModel, actuators: Sequence[str], period: int = 0) -> Any:
    """``residual(a, q_hat, v_hat, w, g, t, u, p, c, s) -> (M-weighted Newton residual terms)`` of a generated scheme
    step without loops by one sweep with the inputs ``actuators`` then unit generalised forces
    (:func:`ctmm.mapped_tangent.weighted_residual_terms`: code O(sweep)), folded over segments of ``period`` bodies
    (:func:`ctmm.compiled_scene_fold.folded_accelerations_with_inputs`; 0: straight-line); ``None`` where the basis
    of :func:`generalized_force_units` does not exist."""
    units = generalized_force_units(model)
    if units is None:
        return None
    sweep = (folded_accelerations_with_inputs(model, actuators, units, period) if period
             else symbolic_accelerations_with_inputs(model, actuators, units))
    return mapped_tangent.weighted_residual_terms(sweep, len(actuators))


def weighted_residual_terms(residual_terms: Any, inverse_mass: Any, derivative: Any) -> Any:
    """``residual_terms(a, q_hat, v_hat, w, g, t, u, p, ...) -> (r, J)`` of the plain residual with ``J``
    replaced by ``J - w d(G s)/dq`` at ``q = q_hat + w a``, ``v = v_hat + g a``, ``s = G^-1 r`` (a QR solve of
    numbers in the generated code): the tangent whose Newton steps are those on ``M r`` (module docstring).
    ``inverse_mass``, ``derivative``: the pair of :func:`inverse_mass_terms`."""
    import casadi as ca

    arguments = [ca.MX.sym(residual_terms.name_in(i), residual_terms.sparsity_in(i))
                 for i in range(residual_terms.n_in())]
    a, q_hat, v_hat, w, g, t, _, p = arguments[:8]
    residual, tangent = residual_terms(*arguments)
    q, v = q_hat + w * a, v_hat + g * a
    weight = ca.solve(inverse_mass(q, v, p, t), residual, "qr")
    return ca.Function("weighted_residual", arguments, [residual, tangent - w * derivative(q, v, p, t, weight)])
