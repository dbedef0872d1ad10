"""Linear MSTMM of planar multibody systems about an equilibrium (frequency domain).

Small motion about a static configuration ``q_eq`` (hanging chain under gravity, or a
configuration held by hinge springs).  State ``z = [X, Y, Theta, f_x, f_y, tau]``
(layout :data:`ctmm.layouts.PLANAR`; forces by the inboard on the outboard part).

Rigid body (FORMULAS 2.5 with ``-omega^2 -> s^2``, plus the **geometric stiffness** of the
static preload, derived in ``docs/planar.md``)::

    X_O = X_I + (k x r_IO) Theta,   Theta_O = Theta_I
    f_O = f_I - m s^2 (X_I + (k x r_IC) Theta) + F_e
    tau_O = tau_I - J_C s^2 Theta - r_IC x f_I - r_CO x f_O + G Theta + M_e
    G = r_IC . f_I0 + r_CO . f_O0        (static forces at the two ends)

Hinges: elastic / damper ``Theta_O = Theta_I + (u - tau)/(k + c s)``; smooth hinges follow
seed 002 section 7.6.3.1: with zero moment at the outboard end of the next body, the hinge
angle is eliminated through that body's moment row (``Theta_O`` from ``tau_O = tau_I``).

Two ways to use it:

* Element classes (:class:`LinearRigidBody`, :class:`LinearElasticHinge`,
  :class:`LinearHingedBody`) for :class:`ctmm.Chain` and :func:`ctmm.frequency_response`;
  :func:`linear_chain` builds such a chain from a :class:`PlanarModel`.
* :func:`natural_frequencies` / :func:`eigenvalue_count` / :func:`characteristic_function` for
  chains **and trees** (rigid or with modal beams): thin calls of the one articulated sweep's
  frequency context (:meth:`ctmm.planar.body_forms.PlanarScene.frequency`) and its
  Wittrick-Williams counting (:mod:`ctmm.planar_counting`): the joint and modal pivots are those
  of an LDL^T factorisation of ``K - omega^2 M``, so the number of negative pivots counts the
  natural frequencies below ``omega``, and bisection finds them to round-off.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np
import scipy.optimize

from .. import validation
from ..capabilities import require_planar
from ..elements.base import Element
from ..errors import ModelError
from ..layouts import PLANAR
from .model import BUSHING, DRIVEN, FREE, PlanarModel
from .sweep import solve_instant


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


# ------------------------------------------------------------------------------------------
# from a nonlinear PlanarModel
# ------------------------------------------------------------------------------------------
def static_equilibrium(model: PlanarModel, q_guess, *, t: float = 0.0,
                       tolerance: float = 1e-12) -> np.ndarray:
    """Coordinates where all accelerations vanish at rest (``scipy.optimize.root`` from ``q_guess``).

    Absolute body angles (coordinates ``"<body>.theta"``) are returned wrapped into
    ``[-pi, pi)``.  Which equilibrium is found depends on the guess (a pendulum also balances
    upright); :func:`hanging_configuration` is the guess for the hanging one.
    """
    from .sweep import accelerations

    q_guess, _ = model.state(q_guess, np.zeros(model.n_coordinates))
    sol = scipy.optimize.root(lambda q: accelerations(model, q, np.zeros_like(q), t),
                              q_guess, tol=tolerance, method="hybr")
    q = sol.x.copy()
    angles = np.array([c.endswith(".theta") for c in model.coordinates], dtype=bool)
    q[angles] = (q[angles] + np.pi) % (2.0 * np.pi) - np.pi
    residual = np.max(np.abs(accelerations(model, q, np.zeros_like(q), t)))
    if residual > 1e-8:        # a root at a huge angle loses digits when wrapped: polish the wrapped point
        sol = scipy.optimize.root(lambda x: accelerations(model, x, np.zeros_like(x), t), q, tol=tolerance,
                                  method="hybr")
        q = sol.x.copy()
        q[angles] = (q[angles] + np.pi) % (2.0 * np.pi) - np.pi
        residual = np.max(np.abs(accelerations(model, q, np.zeros_like(q), t)))
    if residual > 1e-8:
        raise ModelError(f"no static equilibrium found near {q_guess!r} (residual {residual:.2e})")
    return q


def hanging_configuration(model: PlanarModel) -> np.ndarray:
    """Coordinates with every body's centre of mass straight below its inboard end (along gravity).

    A guess for :func:`static_equilibrium` (exact for a chain of bodies on smooth hinges; hinge
    springs and loads move the equilibrium away from it).  A body whose centre of mass is at its
    inboard end (a hub) hangs by what it carries instead: the first moment of the bodies welded or
    driven on it (taken straight) and the masses of the subtrees hinged on it at their points.  A
    body with no such moment, and every body without gravity, keeps angle 0; other coordinates are 0.
    """
    q = np.zeros(model.n_coordinates)
    g = np.asarray(model.gravity, dtype=float)
    if not np.any(g != 0.0):
        return q
    down = float(np.arctan2(g[1], g[0]))
    nb = model.n_bodies
    total = np.asarray(model.mass, dtype=float).copy()            # subtree masses [kg]
    moment = total[:, None] * np.asarray(model.com, dtype=float)   # first moments in the body's frame [kg m]
    for j in range(nb - 1, 0, -1):                                  # tips first (topological order)
        p = int(model.parent[j])
        if p < 0:
            continue
        total[p] += total[j]
        moment[p] += total[j] * model.end_vector[j]
        if model.theta_index[j] < 0:                                # turns with its parent
            moment[p] += moment[j]
    for k, name in enumerate(model.coordinates):
        body, _, what = name.rpartition(".")
        if what != "theta" or body not in model.body_names:
            continue
        j = model.body_index(body)
        lever = model.com[j] if np.any(model.com[j] != 0.0) else moment[j]
        if np.any(lever != 0.0):
            q[k] = down - float(np.arctan2(lever[1], lever[0]))
    return q


def _check_equilibrium(model: PlanarModel, q_eq, t: float):
    require_planar(model, "ctmm.planar.linear")
    if np.any(model.joint_kind == DRIVEN):
        raise ModelError("linearisation about an equilibrium needs a model without driven hinges")
    if np.any(model.joint_kind == BUSHING):
        names = [model.joint_names[j] for j in np.flatnonzero(model.joint_kind == BUSHING)]
        raise ModelError(f"the linear planar module does not support hinges with translational "
                         f"springs yet: {', '.join(names)}")
    q_eq = validation.finite_array("q_eq", q_eq, ndim=1)
    if q_eq.shape != (model.n_coordinates,):
        raise ModelError(f"q_eq must have shape ({model.n_coordinates},), got {q_eq.shape}")
    sol = solve_instant(model, q_eq, np.zeros_like(q_eq), t)
    scale = 1.0 + np.max(np.abs(model.gravity))
    if np.max(np.abs(sol.qddot)) > 1e-8 * scale:
        raise ModelError(f"q_eq is not an equilibrium: accelerations at rest "
                         f"{np.max(np.abs(sol.qddot)):.3e} (use static_equilibrium)")
    return q_eq, sol


def linear_chain(model: PlanarModel, q_eq, *, name: str | None = None, t: float = 0.0):
    """:class:`ctmm.Chain` of linear elements for a serial ``model`` about ``q_eq``.

    The chain is ``Fixed(base), hinge, body, ..., Free(tip)``: elastic / damper hinges become
    :class:`LinearElasticHinge` (joint names), a smooth hinge and its body one
    :class:`LinearHingedBody` (body name); bodies keep their names.
    """
    from ..elements.boundary import Fixed as FixedBoundary, Free as FreeBoundary
    from ..system import Chain

    q_eq, sol = _check_equilibrium(model, q_eq, t)
    nb = model.n_bodies
    if not np.array_equal(model.parent, np.arange(-1, nb - 1)) or np.any(model.joint_kind == FREE):
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
def characteristic_function(model: PlanarModel, q_eq, s, *, t: float = 0.0) -> np.ndarray:
    """``Delta(s) = prod det D_j * prod det C_j`` (= det(K + s C + s^2 M) up to a constant) of the
    one sweep's frequency context (:meth:`ctmm.planar.body_forms.PlanarScene.frequency`),
    vectorised over the Laplace variables ``s``."""
    from .body_forms import PlanarScene

    q_eq, _ = _check_equilibrium(model, q_eq, t)
    s = np.atleast_1d(np.asarray(s, dtype=complex))
    value = PlanarScene(model).frequency(q_eq, s.ravel(), t).characteristic
    return np.asarray(value).reshape(s.shape)


def eigenvalue_count(model: PlanarModel, q_eq, omega, *, t: float = 0.0) -> np.ndarray:
    """Number of natural frequencies strictly below each ``omega`` [rad/s] (undamped).

    Wittrick-Williams counting on the one sweep's frequency context
    (:func:`ctmm.planar_counting.eigenvalue_count`): negative pivots of the articulated
    elimination, certified at substructure resonances (a hinge pivot vanishes where ``omega`` is a
    natural frequency of the substructure outboard of that hinge, pinned there).
    """
    from ..planar_counting import FrequencyCounter

    q_eq, _ = _check_equilibrium(model, q_eq, t)
    return FrequencyCounter(model, q_eq, t, verb="eigenvalue_count").count(omega)


def natural_frequencies(model: PlanarModel, q_eq, *, n_modes: int, t: float = 0.0,
                        rtol: float = 1e-15) -> np.ndarray:
    """Lowest ``n_modes`` undamped natural frequencies [rad/s] about the equilibrium ``q_eq``.

    Wittrick-Williams counting on the one sweep's frequency context plus bisection
    (:func:`ctmm.planar_counting.natural_frequencies`); zero-frequency (rigid) modes are returned
    as 0.
    """
    from ..planar_counting import FrequencyCounter

    require_planar(model, "ctmm.planar.linear")
    if np.any(model.damping > 0):
        raise ModelError("natural_frequencies needs an undamped model (hinge damping > 0 found)")
    if not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise ModelError(f"n_modes must be an integer >= 1, got {n_modes!r}")
    q_eq, _ = _check_equilibrium(model, q_eq, t)
    return FrequencyCounter(model, q_eq, t).frequencies(n_modes=int(n_modes), rtol=rtol)


__all__ = ["LinearRigidBody", "LinearElasticHinge", "LinearHingedBody", "linear_chain",
           "static_equilibrium", "hanging_configuration", "characteristic_function", "eigenvalue_count",
           "natural_frequencies"]
