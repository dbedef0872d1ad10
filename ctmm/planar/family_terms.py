"""Planar body and joint families stated once on the element protocol (:mod:`ctmm.protocol`), in
:mod:`ctmm.ops` (numpy batched, complex, casadi); :mod:`ctmm.planar.body_forms` assembles them into a
:class:`~ctmm.planar.body_forms.PlanarScene` (and re-exports them).

* :func:`rigid_body_terms` -- :class:`~ctmm.planar.elements.RigidBody`:
  ``M = X_C^T diag(m, m, J_C) X_C``, ``h`` velocity, gravity, load and input terms, ``Kin_e = X(r_e)``,
  ``c_e = -omega^2 r_e``, ``RF_e = X(r_e)^T`` (``docs/planar.md`` FORMULAS 3.4);
* :func:`revolute_terms` -- one law for the smooth, elastic, damper, spring-damper and actuated
  hinges, ``tau = u - k (q_rel - r) - c (v_rel - r_dot)`` along ``S = e3``; :func:`driven_terms`
  (driven hinge, fixed mounting: prescribed ``a_rel``); :func:`free_base_terms` (``S = I3``);
  :func:`bushing_terms` (hinge with translational springs: ``S = I3``, the revolute law about
  ``e3`` and ``f = -k_t d - c_t d_dot`` along the global offset ``d`` of the child's inboard point
  from the parent's point); :func:`nonlinear_bushing_terms` (a nonlinear hinge with a radial spring);
* :class:`SceneNumbers` -- the numbers these are stated with (numeric or symbols).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ..ops import Ops
from ..protocol import BodyTerms, JointTerms
from .hinge_laws import law_joint_terms, radial_terms
from .model import PlanarModel

__all__ = ["SceneNumbers", "rigid_body_terms", "revolute_terms", "driven_terms", "free_base_terms", "bushing_terms",
           "nonlinear_bushing_terms", "numeric_value"]


@dataclass(frozen=True)
class SceneNumbers:
    """The numbers of a planar model's rigid bodies, hinge laws and loads that :class:`PlanarScene`
    states its terms with: numeric (:meth:`of`, the model's own) or symbols (generated code that takes
    them as inputs, :mod:`ctmm.compiled_scene`).  Modal beams keep their own data.

    Attributes
    ----------
    mass, inertia : sequence (n_bodies,)
        [kg], about the centre of mass [kg m^2].
    center_of_mass : sequence (n_bodies,) of (x, y)
        Relative to the inboard point, body frame [m].
    ends : sequence (n_bodies,) of mapping str -> (x, y)
        Outboard points relative to the inboard point, body frame [m].
    gravity : (gx, gy)
        [m/s^2].
    stiffness, damping : sequence (n_bodies,)
        Hinge law [N m/rad], [N m s/rad].
    reference, reference_rate, torque : sequence (n_bodies,)
        Hinge law [rad], [rad/s], [N m] (at the time of the terms).
    loads : sequence (n_loads,) of (fx, fy, moment)
        [N, N, N m] (at the time of the terms).
    load_point : sequence (n_loads,) of (x, y)
        Body frame [m].
    driven : mapping int -> (angle, rate, acceleration), optional
        The prescribed relative motion of every driven joint by body [rad, rad/s, rad/s^2] (at the time of
        the terms); ``None``: the model's ``driven(t)`` at the time of the terms.
    """

    mass: Sequence[Any]
    inertia: Sequence[Any]
    center_of_mass: Sequence[Any]
    ends: Sequence[Mapping[str, Any]]
    gravity: Sequence[Any]
    stiffness: Sequence[Any]
    damping: Sequence[Any]
    reference: Sequence[Any]
    reference_rate: Sequence[Any]
    torque: Sequence[Any]
    loads: Sequence[Any]
    load_point: Sequence[Any]
    driven: Mapping[int, tuple] | None = None

    @classmethod
    def of(cls, model: PlanarModel, t: float = 0.0) -> "SceneNumbers":
        """The numbers of ``model`` at time ``t`` [s] (hinge-law and load signals evaluated)."""
        reference, reference_rate, torque = model.hinge_laws(t)
        loads = model.loads(t) if len(model.load_body) else np.zeros((0, 3))
        driven = {i: (angle, rate, acceleration) for i, angle, rate, acceleration in model.driven(t)}
        return cls(model.mass, model.inertia, model.com, model.ends, model.gravity, model.stiffness, model.damping,
                   reference, reference_rate, torque, loads, model.load_point, driven)


def rigid_body_terms(ops: Ops, *, mass: float, inertia: float, center_of_mass: Sequence[float],
                     points: Mapping[str, Sequence[float]], gravity: Sequence[float], theta: Any, omega: Any,
                     loads: Sequence[Sequence[float]] = (), body_force: Sequence[Any] | None = None
                     ) -> BodyTerms:
    """Transfer relations of a planar rigid body about its inboard point.

    Parameters
    ----------
    ops : Ops
    mass : float or symbol
        [kg].  Numbers (``mass`` ... ``gravity``, loads) may be symbols (casadi) for generated code
        that takes them as inputs (:class:`SceneNumbers`).
    inertia : float
        About the centre of mass [kg m^2].
    center_of_mass : (float, float)
        Relative to the inboard point, body frame [m].
    points : mapping of str to (float, float)
        Outboard points relative to the inboard point, body frame [m].
    gravity : (float, float)
        [m/s^2], global axes.
    theta, omega : ops scalars
        Absolute angle [rad] and angular velocity [rad/s].
    loads : sequence of (px, py, fx, fy, moment)
        External loads at body-frame points [m] (global forces [N], moment [N m]).
    body_force : (fx, fy, moment), optional
        Actuator force at the centre of mass (global axes) [N, N m].

    Returns
    -------
    BodyTerms
        ``d = 3``, ``n = 0``.
    """
    c, s = ops.cos(theta), ops.sin(theta)
    cx, cy = numeric_value(center_of_mass[0]), numeric_value(center_of_mass[1])
    rcx, rcy = c * cx - s * cy, s * cx + c * cy
    m, gx, gy = numeric_value(mass), numeric_value(gravity[0]), numeric_value(gravity[1])
    w2 = omega * omega
    M = ops.block([[m, 0.0, rcy * -m], [0.0, m, rcx * m],
                   [rcy * -m, rcx * m, (rcx * rcx + rcy * rcy) * m + numeric_value(inertia)]])
    hx = (w2 * rcx + gx) * -m
    hy = (w2 * rcy + gy) * -m
    hz = (rcx * gy - rcy * gx) * -m
    for px, py, fx, fy, mz in loads:
        rex, rey = c * px - s * py, s * px + c * py
        hx, hy, hz = hx - fx, hy - fy, hz - (rex * fy - rey * fx + mz)
    if body_force is not None:
        fx, fy, mz = body_force
        hx, hy, hz = hx - fx, hy - fy, hz - (rcx * fy - rcy * fx + mz)
    h = ops.block([[hx], [hy], [hz]])
    Kin, cc, RF = {}, {}, {}
    for name, (vx, vy) in points.items():
        vx, vy = numeric_value(vx), numeric_value(vy)
        rx, ry = c * vx - s * vy, s * vx + c * vy
        Kin[name] = ops.block([[1.0, 0.0, ry * -1.0], [0.0, 1.0, rx], [0.0, 0.0, 1.0]])
        cc[name] = ops.block([[w2 * rx * -1.0], [w2 * ry * -1.0], [0.0]])
        RF[name] = ops.transpose(Kin[name])
    return BodyTerms(M, h, Kin, cc, RF)


def revolute_terms(ops: Ops, *, angle: Any, rate: Any, stiffness: float = 0.0, damping: float = 0.0,
                   reference: float = 0.0, reference_rate: float = 0.0, torque: Any = 0.0) -> JointTerms:
    """Revolute hinge law ``tau = torque - k (angle - reference) - c (rate - reference_rate)``.

    ``angle``, ``rate``: relative hinge angle [rad] and rate [rad/s] (ops scalars); ``stiffness`` k
    [N m/rad], ``damping`` c [N m s/rad]; ``torque`` the input across the hinge [N m].  Numbers may
    be symbols (casadi).  Smooth
    (k = c = 0), elastic, damper, spring-damper and actuated hinges are this one law.
    """
    k, c = numeric_value(stiffness), numeric_value(damping)
    tau = (angle - reference) * -k - (rate - reference_rate) * c + torque
    return JointTerms(S=ops.block([[0.0], [0.0], [1.0]]), tau=ops.block([[tau]]),
                      tau_q=ops.block([[-k]]), tau_v=ops.block([[-c]]), axis=2)


def driven_terms(ops: Ops, acceleration: Any) -> JointTerms:
    """Driven hinge / fixed mounting: prescribed relative angular acceleration [rad/s^2]."""
    return JointTerms(S=ops.block([[0.0], [0.0], [1.0]]), prescribed=ops.block([[acceleration]]), axis=2)


def free_base_terms(ops: Ops) -> JointTerms:
    """Free base: every direction free, zero force (``S = I3``, ``tau = 0``)."""
    return JointTerms(S=ops.eye(3), tau=ops.zeros(3, 1), tau_q=ops.zeros(3, 3), tau_v=ops.zeros(3, 3))


def bushing_terms(ops: Ops, *, offset: Sequence[Any], offset_rate: Sequence[Any], angle: Any, rate: Any,
                  translational_stiffness: float, translational_damping: float, stiffness: float = 0.0,
                  damping: float = 0.0, reference: float = 0.0, reference_rate: float = 0.0,
                  torque: Any = 0.0) -> JointTerms:
    """Hinge with translational springs: every direction free (``S = I3``, ``c = 0``).

    The child's inboard point sits at the parent's point plus the offset ``d = (dx, dy)`` [m] in
    global axes (``offset_rate`` [m/s]); the joint's wrench on the child is
    ``(f, tau) = (-k_t d - c_t d_dot, torque - k (angle - reference) - c (rate - reference_rate))``
    and ``-(f, tau)`` acts on the parent at its point (a force pair, power ``f . d_dot + tau rate``).
    ``translational_stiffness`` k_t [N/m], ``translational_damping`` c_t [N s/m]; the rotational law
    as :func:`revolute_terms`.
    """
    kt, ct = numeric_value(translational_stiffness), numeric_value(translational_damping)
    k, c = numeric_value(stiffness), numeric_value(damping)
    fx = offset[0] * -kt - offset_rate[0] * ct
    fy = offset[1] * -kt - offset_rate[1] * ct
    tau = (angle - reference) * -k - (rate - reference_rate) * c + torque
    return JointTerms(S=ops.eye(3), tau=ops.block([[fx], [fy], [tau]]),
                      tau_q=ops.block([[-kt, 0.0, 0.0], [0.0, -kt, 0.0], [0.0, 0.0, -k]]),
                      tau_v=ops.block([[-ct, 0.0, 0.0], [0.0, -ct, 0.0], [0.0, 0.0, -c]]))


def nonlinear_bushing_terms(ops: Ops, hinge: Any, dx: Any, dy: Any, angle: Any, rate: Any, torque: Any) -> JointTerms:
    """A :class:`~ctmm.planar.elements.NonlinearHinge` with a radial spring: every direction free (``S = I3``),
    the radial force and its 2 x 2 tangent (:func:`ctmm.planar.hinge_laws.radial_terms`) and the moment law."""
    fx, fy, kxx, kxy, kyy = radial_terms(ops, hinge, dx, dy)
    tau, tau_q, tau_v = law_joint_terms(ops, hinge, angle, rate, torque)
    zero = 0.0 * tau_q
    return JointTerms(S=ops.eye(3), tau=ops.block([[fx], [fy], [tau]]),
                      tau_q=ops.block([[kxx, kxy, zero], [kxy, kyy, zero], [zero, zero, tau_q]]),
                      tau_v=ops.block([[zero, zero, zero], [zero, zero, zero], [zero, zero, tau_v]]))


def numeric_value(entry: Any) -> Any:
    """A numeric actuator value as float; a symbolic one (casadi, object arrays) as it is."""
    return float(entry) if isinstance(entry, (int, float, np.number)) else entry
