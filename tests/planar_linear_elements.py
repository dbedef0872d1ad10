"""Test fixtures: the transfer-matrix elements of the linear planar MSTMM about an equilibrium
(``docs/planar.md`` section 5), for the 1-D chain verbs (``ctmm.Chain``, ``ctmm.frequency_response``,
the generic Wittrick-Williams count of ``ctmm.natural``).  Moved here from ``ctmm/planar/linear.py``:
the library's planar frequency domain is the one articulated sweep's frequency context; these
classes only serve tests that build a ``Chain`` from a planar model.

State ``z = [X, Y, Theta, f_x, f_y, tau]`` (layout :data:`ctmm.layouts.PLANAR`; forces by the
inboard on the outboard part).  Rigid body (FORMULAS 2.5 with ``-omega^2 -> s^2``, plus the
**geometric stiffness** of the static preload)::

    X_O = X_I + (k x r_IO) Theta,   Theta_O = Theta_I
    f_O = f_I - m s^2 (X_I + (k x r_IC) Theta) + F_e
    tau_O = tau_I - J_C s^2 Theta - r_IC x f_I - r_CO x f_O + G Theta + M_e
    G = r_IC . f_I0 + r_CO . f_O0        (static forces at the two ends)

Hinges: elastic / damper ``Theta_O = Theta_I + (u - tau)/(k + c s)``; smooth hinges follow
seed 002 section 7.6.3.1: with zero moment at the outboard end of the next body, the hinge
angle is eliminated through that body's moment row (``Theta_O`` from ``tau_O = tau_I``).
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from ctmm import validation
from ctmm.elements.base import Element
from ctmm.elements.boundary import Fixed as FixedBoundary, Free as FreeBoundary
from ctmm.errors import ModelError
from ctmm.layouts import PLANAR
from ctmm.planar.model import REVOLUTE, PlanarModel
from ctmm.planar.sweep import solve_instant
from ctmm.system import Chain


def _cross_row(r):
    """Row vector ``v -> r x v`` for planar vectors."""
    return np.array([-r[1], r[0]])


class LinearRigidBody(Element):
    """Planar rigid body about a reference configuration, with static preload.

    Parameters
    ----------
    name : str
    mass : float
        [kg], > 0.
    inertia : float
        About the centre of mass [kg m^2], > 0.
    center_of_mass : (float, float)
        ``r_IC``: centre of mass relative to the inboard end, global axes at the reference [m].
    outboard : (float, float)
        ``r_IO``: outboard end relative to the inboard end, global axes [m].
    inboard_force, outboard_force : (float, float)
        Static forces ``f_I0``, ``f_O0`` at the two ends (by the inboard on the outboard part)
        in the reference configuration [N]; they give the geometric stiffness ``G``.

    Inputs ``force_x``, ``force_y`` [N] (at the centre of mass, global axes) and ``moment``
    [N m].
    """

    layout = PLANAR
    inputs = ("force_x", "force_y", "moment")

    def __init__(self, name: str, *, mass: float, inertia: float, center_of_mass, outboard,
                 inboard_force=(0.0, 0.0), outboard_force=(0.0, 0.0)) -> None:
        super().__init__(name)
        self.mass = validation.positive(f"{name}: mass", mass)
        self.inertia = validation.positive(f"{name}: inertia", inertia)
        self.r_ic = self._vector(f"{name}: center_of_mass", center_of_mass)
        self.r_io = self._vector(f"{name}: outboard", outboard)
        self.f_i0 = self._vector(f"{name}: inboard_force", inboard_force)
        self.f_o0 = self._vector(f"{name}: outboard_force", outboard_force)
        self.r_co = self.r_io - self.r_ic
        self.geometric_stiffness = float(self.r_ic @ self.f_i0 + self.r_co @ self.f_o0)

    @staticmethod
    def _vector(label, value):
        array = validation.finite_array(label, value)
        if array.shape != (2,):
            raise ModelError(f"{label} must be a 2-vector, got {value!r}")
        return array.astype(float)

    def parameters(self) -> dict[str, Any]:
        return {"mass": self.mass, "inertia": self.inertia, "center_of_mass": tuple(self.r_ic),
                "outboard": tuple(self.r_io), "geometric_stiffness": self.geometric_stiffness}

    def transfer_matrix(self, s) -> np.ndarray:
        s = np.asarray(s, dtype=complex)
        s2 = (s * s)[..., None]
        m = self.mass
        U = np.zeros(s.shape + (6, 6), dtype=complex)
        # kinematics: X_O = X_I + (k x r_IO) Theta, Theta_O = Theta_I
        U[..., :3, :3] = np.eye(3)
        U[..., 0, 2] = -self.r_io[1]
        U[..., 1, 2] = self.r_io[0]
        # forces: f_O = f_I - m s^2 (X_I + (k x r_IC) Theta)
        kin_c = np.zeros((2, 3))
        kin_c[:, :2] = np.eye(2)
        kin_c[:, 2] = (-self.r_ic[1], self.r_ic[0])
        f_i = np.zeros((2, 6))
        f_i[:, 3:5] = np.eye(2)
        f_o = f_i[None] - m * s2[..., None] * np.concatenate([kin_c, np.zeros((2, 3))], axis=1)
        U[..., 3:5, :] = f_o
        # moment: tau_O = tau_I - J s^2 Theta - r_IC x f_I - r_CO x f_O + G Theta
        tau = np.zeros(s.shape + (6,), dtype=complex)
        tau[..., 5] = 1.0
        tau[..., 2] += -self.inertia * s2[..., 0] + self.geometric_stiffness
        tau = tau - _cross_row(self.r_ic) @ f_i - np.einsum("i,...ij->...j", _cross_row(self.r_co),
                                                            f_o)
        U[..., 5, :] = tau
        # reorder rows/cols: layout is [x, y, theta, fx, fy, tau]; rows 3,4 = fx, fy; 5 = tau
        return U

    def load_vector(self, s, amplitudes: Mapping[str, Any]) -> np.ndarray:
        self.check_inputs(amplitudes)
        s = np.asarray(s)
        u = np.zeros(s.shape + (6,), dtype=complex)
        fx = amplitudes.get("force_x", 0.0)
        fy = amplitudes.get("force_y", 0.0)
        u[..., 3] = fx
        u[..., 4] = fy
        u[..., 5] = amplitudes.get("moment", 0.0) - (self.r_co[0] * fy - self.r_co[1] * fx)
        return u


class LinearElasticHinge(Element):
    """Rotary spring / damper hinge: ``Theta_O = Theta_I + (u - tau)/(k + c s)``.

    Parameters
    ----------
    stiffness : float
        [N m/rad], >= 0.
    damping : float
        [N m s/rad], >= 0; ``stiffness + damping > 0``.

    Input ``torque`` [N m]: actuator moment on the outboard body (reaction on the inboard one).
    """

    layout = PLANAR
    inputs = ("torque",)
    is_point = True

    def __init__(self, name: str, *, stiffness: float, damping: float = 0.0) -> None:
        super().__init__(name)
        self.stiffness = validation.nonnegative(f"{name}: stiffness", stiffness)
        self.damping = validation.nonnegative(f"{name}: damping", damping)
        if self.stiffness + self.damping <= 0.0:
            raise ModelError(f"{name}: stiffness + damping must be > 0 (use LinearHingedBody)")

    def parameters(self):
        return {"stiffness": self.stiffness, "damping": self.damping}

    def transfer_matrix(self, s) -> np.ndarray:
        s = np.asarray(s, dtype=complex)
        U = np.broadcast_to(np.eye(6, dtype=complex), s.shape + (6, 6)).copy()
        U[..., 2, 5] = -1.0 / (self.stiffness + self.damping * s)
        return U

    def load_vector(self, s, amplitudes):
        self.check_inputs(amplitudes)
        s = np.asarray(s, dtype=complex)
        u = np.zeros(s.shape + (6,), dtype=complex)
        u[..., 2] = amplitudes.get("torque", 0.0) / (self.stiffness + self.damping * s)
        return u


class LinearHingedBody(Element):
    """A smooth hinge followed by its outboard body, as one element (seed 002 7.6.3.1).

    A smooth hinge has no regular transfer matrix of its own (its angle is a new unknown and
    its moment a new known).  When the body behind it has zero moment at its outboard end
    (next element a smooth hinge or the free end), the hinge angle follows from the body's
    moment row: ``Theta`` is chosen so that the body passes the moment on unchanged
    (``tau_O = tau_I``, the "u44 = 1" form); the chain's end condition ``tau = 0`` then gives
    zero moment at every such hinge.  The composite keeps the body's name and inputs.

    Parameters
    ----------
    body : LinearRigidBody
        The outboard body of the hinge.
    """

    layout = PLANAR

    def __init__(self, body: LinearRigidBody) -> None:
        if not isinstance(body, LinearRigidBody):
            raise ModelError(f"LinearHingedBody needs a LinearRigidBody, got {body!r}")
        super().__init__(body.name)
        self.body = body
        self.inputs = body.inputs

    def parameters(self):
        return {"body": self.body.parameters()}

    def _hinge(self, s):
        Ub = self.body.transfer_matrix(s)
        row = Ub[..., 5, :]
        Uh = np.broadcast_to(np.eye(6, dtype=complex), np.shape(s) + (6, 6)).copy()
        Uh[..., 2, :] = -row / row[..., 2:3]     # Theta_O = -(row . z)/row_theta, without
        Uh[..., 2, 2] = 0.0                       # the Theta_I and tau_I terms
        Uh[..., 2, 5] = 0.0
        return Ub, Uh, row[..., 2]

    def transfer_matrix(self, s) -> np.ndarray:
        s = np.asarray(s, dtype=complex)
        Ub, Uh, _ = self._hinge(s)
        return Ub @ Uh

    def load_vector(self, s, amplitudes):
        s = np.asarray(s, dtype=complex)
        ub = self.body.load_vector(s, amplitudes)
        Ub, _, row_theta = self._hinge(s)
        uh = np.zeros(s.shape + (6,), dtype=complex)
        uh[..., 2] = -ub[..., 5] / row_theta
        return ub + np.einsum("...ij,...j->...i", Ub, uh)


def linear_chain(model: PlanarModel, q_eq, *, name: str | None = None, t: float = 0.0):
    """:class:`ctmm.Chain` of linear elements for a serial ``model`` about ``q_eq``.

    The chain is ``Fixed(base), hinge, body, ..., Free(tip)``: elastic / damper hinges become
    :class:`LinearElasticHinge` (joint names), a smooth hinge and its body one
    :class:`LinearHingedBody` (body name); bodies keep their names.
    """
    q_eq = np.asarray(q_eq, dtype=float)
    if np.any(model.joint_kind != REVOLUTE):
        raise ModelError("linear_chain needs revolute hinges only (no driven, free or translational-spring joints)")
    sol = solve_instant(model, q_eq, np.zeros_like(q_eq), t)
    if np.max(np.abs(sol.qddot)) > 1e-8 * (1.0 + np.max(np.abs(model.gravity))):
        raise ModelError("linear_chain: q_eq is not an equilibrium")
    nb = model.n_bodies
    if not np.array_equal(model.parent, np.arange(-1, nb - 1)):
        raise ModelError("linear_chain needs a serial chain attached to the ground")
    theta, _ = model.body_angles(q_eq, np.zeros_like(q_eq), t)
    bodies = []
    for j in range(nb):
        c, s_ = np.cos(theta[j]), np.sin(theta[j])
        rot = np.array([[c, -s_], [s_, c]])
        ends = model.ends[j]
        if len(ends) > 1:
            raise ModelError(f"linear_chain: body {model.body_names[j]!r} has several ends")
        r_io = rot @ next(iter(ends.values())) if ends else np.zeros(2)
        f_o0 = sol.joint_force[j + 1, :2] if j + 1 < nb else np.zeros(2)
        if len(model.load_body):
            raise ModelError("linear_chain: static loads are not supported; use gravity")
        bodies.append(LinearRigidBody(model.body_names[j], mass=model.mass[j],
                                      inertia=model.inertia[j], center_of_mass=rot @ model.com[j],
                                      outboard=r_io, inboard_force=sol.joint_force[j, :2],
                                      outboard_force=f_o0))
    elements = [FixedBoundary(f"{model.name}_base")]
    for j in range(nb):
        k, c = model.stiffness[j], model.damping[j]
        if k + c > 0:
            elements.append(LinearElasticHinge(model.joint_names[j], stiffness=k, damping=c))
        else:
            if j + 1 < nb and model.stiffness[j + 1] + model.damping[j + 1] > 0:
                raise ModelError(f"linear_chain: smooth hinge {model.joint_names[j]!r} needs zero "
                                 "moment at the outboard end of its body (next hinge is elastic)")
            elements.append(LinearHingedBody(bodies[j]))
            continue
        elements.append(bodies[j])
    elements.append(FreeBoundary(f"{model.name}_tip"))
    return Chain(name or f"{model.name}_linear", elements)


# ------------------------------------------------------------------------------------------
# chains and trees: the one articulated sweep's frequency context (ctmm.planar_counting)
# ------------------------------------------------------------------------------------------
