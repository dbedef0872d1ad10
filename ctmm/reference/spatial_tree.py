"""Independent global reference model of spatial rigid-body trees (no transfer matrices).

Written from scratch for the tests of the spatial transfer-matrix code; it shares no code with
``ctmm.spatial`` (or any other library module) and no library module may import it.

Description (plain data): :class:`SpatialBody` (parent index, joint kind, joint axes, joint
placement, mass, centre of mass, inertia, joint spring/damper law), :class:`PointLoad` and
:class:`SpatialTree` (bodies in topological order, gravity, loads).

Equations of motion are the **global** projected Newton-Euler (Lagrange / Kane) equations
with body Jacobians, not a recursion over the tree::

    M(q) = sum_i  m_i Jc_i^T Jc_i + Jw_i^T I_i Jw_i
    h(q, v, t) = sum_i  Jc_i^T m_i (ac_i - g) + Jw_i^T (I_i alpha_i + w_i x I_i w_i)
                 - Q_loads - Q_joint_laws
    M(q) vdot + h(q, v, t) = tau

``Jc_i`` (3 x nv) maps ``v`` to the world velocity of the centre of mass of body ``i``,
``Jw_i`` (3 x nv) to its world angular velocity; ``I_i = R_i I_C R_i^T`` (world);
``ac_i = Jdot_c v`` and ``alpha_i = Jdot_w v`` are the accelerations at ``vdot = 0`` from the
forward kinematics of positions, velocities and accelerations.  The Jacobian columns are built
joint by joint from the joint's motion axes (``Jw`` column = world axis, ``Jc`` column = axis
velocity of the child origin + axis x lever).  Joint reaction wrenches follow from Newton-Euler
on each subtree with the accelerations of :func:`forward_dynamics`.

Conventions (the same as Pinocchio's, which the tests use as a second reference):

* every body frame is its joint's child frame; joint frame at ``q = 0`` = parent body frame
  moved by ``joint_position`` [m] (parent body axes) and turned by ``joint_rotation``
  (columns = joint axes in parent body axes, as Pinocchio's joint placement ``SE3(R, p)``);
* quaternions are **scalar-last** ``(x, y, z, w)``; ``spherical`` has ``q = quat``, ``v`` =
  angular velocity of the child relative to the joint frame **in child axes** [rad/s];
  ``free`` and ``elastic6`` have ``q = (d, quat)`` with ``d`` the child origin in joint axes
  [m] and ``v = (R^T d_dot, omega)``, both in child axes;
* ``universal`` with axes ``a1, a2``: ``R = exp(a1 q1) exp(a2 q2)``;
* joint laws (linear): ``revolute``, ``prismatic``, ``universal``: ``Q = -K q - C v``;
  ``spherical``: moment on the child, child axes, ``-K phi - C omega`` with
  ``phi = log(R)`` the **rotation vector** (same components in joint and child axes);
  ``elastic6``: force on the child ``f = -K_tt d - K_tr phi - C_tt d_dot - C_tr omega`` in joint
  axes, moment ``m = -K_rt d - K_rr phi - C_rt d_dot - C_rr omega`` in child axes, generalised
  force ``(R^T f, m)``.  Rotation-vector springs derive from the potential ``1/2 phi^T K phi``
  only for isotropic ``K`` (and ``elastic6`` only without translation-rotation coupling);
  otherwise they are a linear law without a potential.  ``free`` and ``weld`` have no law.

Rotations, joint motions and forward kinematics are in :mod:`.spatial_kinematics`; the
description, equations, integrator and linearisation here; documentation in
``docs/reference_models.md`` section 7.

Numbers: float64 (complex128 inside :func:`linearize`, which differentiates the global model
by the complex step: ``K = Im h(q0 (+) i eps e_k, 0) / eps``, ``C`` likewise in ``v``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np
import scipy.linalg

from ..errors import ModelError, SimulationError
from .cholesky import cholesky_solve
from .spatial_kinematics import (JOINT_SIZES, Kinematics, cross, exp_quaternion, joint_coordinates,
                                 kinematics, point_jacobian, quaternion_matrix, quaternion_product,
                                 rotation_vector)

_AXES_NEEDED = {"revolute": 1, "prismatic": 1, "universal": 2}


def _matrix(value, size: int, name: str, body: str) -> np.ndarray:
    """A (size, size) law matrix from None, a scalar, a vector (diagonal) or a matrix."""
    if value is None:
        return np.zeros((size, size))
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        array = array * np.eye(size)
    elif array.ndim == 1 and array.shape == (size,):
        array = np.diag(array)
    if array.shape != (size, size) or not np.all(np.isfinite(array)):
        raise ModelError(f"body {body!r}: {name} must be a finite scalar, ({size},) or "
                         f"({size}, {size}) array, got shape {array.shape}")
    return array


@dataclass(frozen=True)
class SpatialBody:
    """One rigid body and the joint that connects it to its parent.

    Parameters
    ----------
    name : str
        Label.
    parent : int
        Index of the parent body (smaller than this body's index), -1 for the ground.
    joint : str
        One of ``revolute, prismatic, universal, spherical, free, elastic6, weld``.
    mass : float
        Mass [kg], > 0.
    com : (3,) array
        Centre of mass in body axes from the body origin [m].
    inertia : (3, 3) array
        Inertia tensor about the centre of mass in body axes [kg m^2], symmetric positive
        definite.
    axes : (k, 3) array
        Unit joint axes in joint axes: one for revolute / prismatic, two for universal.
    joint_position : (3,) array
        Joint frame origin in parent body axes [m] (ground: world axes).
    joint_rotation : (3, 3) array
        Orientation of the joint frame at ``q = 0`` in parent body axes: columns = joint axes
        in parent axes (maps joint-axes components to parent-axes components; Pinocchio's
        placement rotation); orthonormal, det +1.
    stiffness, damping : scalar, (nv,) or (nv, nv) array
        Joint law ``K`` [N/m, N m/rad] and ``C`` [N s/m, N m s/rad] (module docstring).
    """

    name: str
    parent: int
    joint: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    axes: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    joint_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    joint_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    stiffness: object = None
    damping: object = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if self.joint not in JOINT_SIZES:
            raise ModelError(f"body {self.name!r}: joint={self.joint!r} unknown; allowed: "
                             f"{', '.join(JOINT_SIZES)}")
        if not (np.isfinite(self.mass) and self.mass > 0):
            raise ModelError(f"body {self.name!r}: mass={self.mass!r} must be finite and > 0 kg")
        com = np.asarray(self.com, dtype=float).reshape(3)
        inertia = np.asarray(self.inertia, dtype=float)
        if inertia.shape != (3, 3) or not np.allclose(inertia, inertia.T, atol=1e-14) \
                or np.min(np.linalg.eigvalsh(inertia)) <= 0:
            raise ModelError(f"body {self.name!r}: inertia must be a symmetric positive "
                             f"definite (3, 3) matrix [kg m^2], got {inertia.tolist()}")
        axes = np.asarray(self.axes, dtype=float).reshape(-1, 3)
        needed = _AXES_NEEDED.get(self.joint, 0)
        if len(axes) != needed or not np.allclose(np.linalg.norm(axes, axis=1), 1.0, atol=1e-12):
            raise ModelError(f"body {self.name!r}: a {self.joint} joint needs {needed} unit "
                             f"axes, got {axes.tolist()}")
        rotation = np.asarray(self.joint_rotation, dtype=float)
        if rotation.shape != (3, 3) or not np.allclose(rotation.T @ rotation, np.eye(3),
                                                        atol=1e-12) \
                or np.linalg.det(rotation) < 0:
            raise ModelError(f"body {self.name!r}: joint_rotation must be a proper rotation "
                             f"matrix, got {rotation.tolist()}")
        nv = JOINT_SIZES[self.joint][1]
        stiffness = _matrix(self.stiffness, nv, "stiffness", self.name)
        damping = _matrix(self.damping, nv, "damping", self.name)
        if self.joint in ("free", "weld") and (np.any(stiffness) or np.any(damping)):
            raise ModelError(f"body {self.name!r}: a {self.joint} joint has no spring/damper "
                             f"law (use 'elastic6' for a 6-DOF elastic hinge)")
        set_(self, "com", com)
        set_(self, "inertia", inertia)
        set_(self, "axes", axes)
        set_(self, "joint_position", np.asarray(self.joint_position, dtype=float).reshape(3))
        set_(self, "joint_rotation", rotation)
        set_(self, "stiffness", stiffness)
        set_(self, "damping", damping)


@dataclass(frozen=True)
class PointLoad:
    """A force [N] and moment [N m], world axes, on a body point (body axes) [m]; constant or
    a callable of time ``t`` [s]."""

    body: int
    point: np.ndarray
    force: object = (0.0, 0.0, 0.0)
    moment: object = (0.0, 0.0, 0.0)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Force and moment at time ``t``."""
        force = self.force(t) if callable(self.force) else self.force
        moment = self.moment(t) if callable(self.moment) else self.moment
        return np.asarray(force, dtype=float), np.asarray(moment, dtype=float)


@dataclass(frozen=True)
class SpatialTree:
    """Bodies in topological order, gravity [m/s^2] (world axes) and point loads."""

    bodies: tuple
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))
    loads: tuple = ()

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "bodies", tuple(self.bodies))
        set_(self, "loads", tuple(self.loads))
        set_(self, "gravity", np.asarray(self.gravity, dtype=float).reshape(3))
        q_start, v_start, nq, nv = [], [], 0, 0
        for index, body in enumerate(self.bodies):
            if not -1 <= body.parent < index:
                raise ModelError(f"body {index} ({body.name!r}): parent={body.parent} must be "
                                 f"-1 (ground) or an earlier body index (0..{index - 1})")
            q_start.append(nq)
            v_start.append(nv)
            nq += JOINT_SIZES[body.joint][0]
            nv += JOINT_SIZES[body.joint][1]
        for load in self.loads:
            if not 0 <= load.body < len(self.bodies):
                raise ModelError(f"PointLoad body={load.body} must be a body index "
                                 f"0..{len(self.bodies) - 1}")
        set_(self, "q_start", tuple(q_start))
        set_(self, "v_start", tuple(v_start))
        set_(self, "nq", nq)
        set_(self, "nv", nv)

    def neutral_configuration(self) -> np.ndarray:
        """``q`` with all joints at zero (identity quaternions)."""
        q = np.zeros(self.nq)
        for body, start in zip(self.bodies, self.q_start):
            if body.joint == "spherical":
                q[start + 3] = 1.0
            elif body.joint in ("free", "elastic6"):
                q[start + 6] = 1.0
        return q

    def subtree(self, index: int) -> list[int]:
        """Indices of body ``index`` and all its descendants."""
        inside = [index]
        for k in range(index + 1, len(self.bodies)):
            if self.bodies[k].parent in inside:
                inside.append(k)
        return inside


# -- generalised forces --------------------------------------------------------------------------
def joint_deflection(tree: SpatialTree, index: int, q: np.ndarray, v: np.ndarray):
    """Deflection ``e`` and its rate of joint ``index`` as used by its law (module docstring)."""
    body = tree.bodies[index]
    qj, vj = joint_coordinates(tree, index, q, v)
    if body.joint == "spherical":
        return rotation_vector(qj), vj
    if body.joint == "elastic6":
        rel = quaternion_matrix(qj[3:7])
        return (np.concatenate([qj[:3], rotation_vector(qj[3:7])]),
                np.concatenate([rel @ vj[:3], vj[3:]]))
    return qj, vj


def joint_law_forces(tree: SpatialTree, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Generalised forces of the joint springs and dampers, (nv,) [N, N m]."""
    out = np.zeros(tree.nv, dtype=np.result_type(q, v, float))
    for i, body in enumerate(tree.bodies):
        if not (np.any(body.stiffness) or np.any(body.damping)):
            continue
        e, rate = joint_deflection(tree, i, q, v)
        law = -body.stiffness @ e - body.damping @ rate
        if body.joint == "elastic6":
            rel = quaternion_matrix(joint_coordinates(tree, i, q, v)[0][3:7])
            law = np.concatenate([rel.T @ law[:3], law[3:]])
        out[tree.v_start[i]: tree.v_start[i] + len(law)] = law
    return out


def _world_inertia(tree: SpatialTree, kin: Kinematics) -> np.ndarray:
    inertia = np.array([b.inertia for b in tree.bodies])
    return np.einsum("bij,bjk,blk->bil", kin.rotation, inertia, kin.rotation)


def mass_matrix(tree: SpatialTree, q: np.ndarray, kin: Kinematics | None = None) -> np.ndarray:
    """``M(q) = sum_i m_i Jc_i^T Jc_i + Jw_i^T I_i Jw_i``, (nv, nv); ``kin``: the kinematics at ``q`` if at hand
    (at any ``v``: the rotations and Jacobians it reads do not depend on the velocities)."""
    kin = kinematics(tree, q, np.zeros(tree.nv)) if kin is None else kin
    mass = np.array([b.mass for b in tree.bodies])
    jw, jc = kin.jacobian_angular, kin.jacobian_com
    return (np.einsum("b,bin,bim->nm", mass, jc, jc)
            + np.einsum("bin,bij,bjm->nm", jw, _world_inertia(tree, kin), jw))


def bias_forces(tree: SpatialTree, q: np.ndarray, v: np.ndarray, t: float = 0.0,
                kin: Kinematics | None = None) -> np.ndarray:
    """``h(q, v, t)`` with ``M vdot + h = tau``: inertial bias, gravity, loads, joint laws."""
    kin = kinematics(tree, q, v) if kin is None else kin
    mass = np.array([b.mass for b in tree.bodies])
    inertia = _world_inertia(tree, kin)
    spin = np.einsum("bij,bj->bi", inertia, kin.omega)
    moment = np.einsum("bij,bj->bi", inertia, kin.alpha_bias) + cross(kin.omega, spin)
    force = mass[:, None] * (kin.com_bias - tree.gravity)
    h = (np.einsum("bin,bi->n", kin.jacobian_com, force)
         + np.einsum("bin,bi->n", kin.jacobian_angular, moment))
    for load in tree.loads:
        f, m = load.at(t)
        point = kin.origin[load.body] + kin.rotation[load.body] @ load.point
        h = h - point_jacobian(kin, load.body, point).T @ f \
            - kin.jacobian_angular[load.body].T @ m
    return h - joint_law_forces(tree, q, v)


def forward_dynamics(tree: SpatialTree, q: np.ndarray, v: np.ndarray, tau=None,
                     t: float = 0.0) -> np.ndarray:
    """``vdot = M^{-1} (tau - h)`` (dense Cholesky), (nv,)."""
    q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
    kin = kinematics(tree, q, v)                   # one forward pass for both M and h
    rhs = -bias_forces(tree, q, v, t, kin)
    if tau is not None:
        rhs = rhs + np.asarray(tau, dtype=float)
    return cholesky_solve(mass_matrix(tree, q, kin), rhs)


def inverse_dynamics(tree: SpatialTree, q: np.ndarray, v: np.ndarray, vdot: np.ndarray,
                     t: float = 0.0) -> np.ndarray:
    """Joint forces ``tau = M vdot + h`` (actuation on top of the joint laws), (nv,)."""
    kin = kinematics(tree, q, v)
    return mass_matrix(tree, q, kin) @ np.asarray(vdot, dtype=float) + bias_forces(tree, q, v, t, kin)


def joint_reactions(tree: SpatialTree, q: np.ndarray, v: np.ndarray, vdot: np.ndarray,
                    t: float = 0.0) -> np.ndarray:
    """Total wrench the parent exerts on each body across its joint, (nb, 6).

    Newton-Euler on the subtree of each body with the given accelerations:
    ``W = sum_subtree (m (a_C - g), I alpha + w x I w) - loads``, moment about the body origin;
    rows ``(force [N], moment [N m])`` in body axes (Pinocchio's ``data.f`` after ``rnea``).
    Includes constraint reactions, joint law and actuation.
    """
    kin = kinematics(tree, q, v)
    mass = np.array([b.mass for b in tree.bodies])
    inertia = _world_inertia(tree, kin)
    vdot = np.asarray(vdot, dtype=float)
    acc_c = kin.com_bias + kin.jacobian_com @ vdot
    alpha = kin.alpha_bias + kin.jacobian_angular @ vdot
    force = mass[:, None] * (acc_c - tree.gravity)
    moment = np.einsum("bij,bj->bi", inertia, alpha) \
        + cross(kin.omega, np.einsum("bij,bj->bi", inertia, kin.omega))
    applied = [(load.body, kin.origin[load.body] + kin.rotation[load.body] @ load.point,
                *load.at(t)) for load in tree.loads]
    out = np.zeros((len(tree.bodies), 6))
    for i in range(len(tree.bodies)):
        inside = tree.subtree(i)
        o = kin.origin[i]
        total_f = force[inside].sum(axis=0)
        total_m = (cross(kin.com[inside] - o, force[inside]) + moment[inside]).sum(axis=0)
        for body, point, f, m in applied:
            if body in inside:
                total_f = total_f - f
                total_m = total_m - cross(point - o, f) - m
        out[i] = np.concatenate([kin.rotation[i].T @ total_f, kin.rotation[i].T @ total_m])
    return out


def energy(tree: SpatialTree, q: np.ndarray, v: np.ndarray) -> tuple[float, float]:
    """Kinetic and potential energy [J]: ``1/2 v^T M v``; ``-sum m g.c + 1/2 e^T K e``.

    The spring term is the potential of the joint law only where one exists (module
    docstring); loads are not included.
    """
    kin = kinematics(tree, q, v)
    mass = np.array([b.mass for b in tree.bodies])
    inertia = _world_inertia(tree, kin)
    kinetic = 0.5 * (np.sum(mass * np.sum(kin.com_velocity ** 2, axis=1))
                     + np.einsum("bi,bij,bj->", kin.omega, inertia, kin.omega))
    potential = -np.sum(mass * (kin.com @ tree.gravity))
    for i, body in enumerate(tree.bodies):
        if np.any(body.stiffness):
            e = joint_deflection(tree, i, q, v)[0]
            potential += 0.5 * e @ body.stiffness @ e
    return float(kinetic), float(potential)


# -- configuration -------------------------------------------------------------------------------
def configuration_rate(tree: SpatialTree, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``q_dot = G(q) v``: quaternion rate ``1/2 quat (x) (omega, 0)``, ``d_dot = R v_lin``."""
    out = np.zeros(tree.nq, dtype=np.result_type(q, v, float))
    for i, body in enumerate(tree.bodies):
        qj, vj = joint_coordinates(tree, i, q, v)
        s = tree.q_start[i]
        if body.joint == "spherical":
            out[s: s + 4] = 0.5 * quaternion_product(qj, np.concatenate([vj, [0.0]]))
        elif body.joint in ("free", "elastic6"):
            out[s: s + 3] = quaternion_matrix(qj[3:7]) @ vj[:3]
            out[s + 3: s + 7] = 0.5 * quaternion_product(qj[3:7],
                                                         np.concatenate([vj[3:], [0.0]]))
        else:
            out[s: s + len(qj)] = vj
    return out


def retract(tree: SpatialTree, q: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """``q (+) delta``: ``q + delta`` for scalar joints, ``quat (x) exp(delta_rot)`` and
    ``d + R delta_lin`` for quaternion joints (``delta`` in velocity coordinates, (nv,))."""
    out = np.array(q, dtype=np.result_type(q, delta, float))
    for i, body in enumerate(tree.bodies):
        qj, dj = joint_coordinates(tree, i, q, delta)
        s = tree.q_start[i]
        if body.joint == "spherical":
            out[s: s + 4] = quaternion_product(qj, exp_quaternion(dj))
        elif body.joint in ("free", "elastic6"):
            out[s: s + 3] = qj[:3] + quaternion_matrix(qj[3:7]) @ dj[:3]
            out[s + 3: s + 7] = quaternion_product(qj[3:7], exp_quaternion(dj[3:]))
        else:
            out[s: s + len(qj)] = qj + dj
    return out


def normalized(tree: SpatialTree, q: np.ndarray) -> np.ndarray:
    """``q`` with every quaternion scaled to unit length."""
    out = np.array(q, dtype=float)
    for i, body in enumerate(tree.bodies):
        if body.joint in ("spherical", "free", "elastic6"):
            s = tree.q_start[i] + (3 if body.joint != "spherical" else 0)
            out[s: s + 4] /= np.sqrt(out[s: s + 4] @ out[s: s + 4])
    return out


# -- time stepping and linearisation ----------------------------------------------------------
class Trajectory(NamedTuple):
    """Stored samples: ``time`` (ns,) [s], ``q`` (ns, nq), ``v`` (ns, nv)."""

    time: np.ndarray
    q: np.ndarray
    v: np.ndarray


def simulate(tree: SpatialTree, q0, v0, t_final: float, dt: float,
             torque: Callable | None = None, store_every: int = 1) -> Trajectory:
    """Classical fixed-step RK4 on ``(q, v)`` (quaternions integrated as 4-vectors and
    normalised after each step); ``torque(t, q, v) -> (nv,)`` optional actuation."""
    if not (np.isfinite(dt) and dt > 0 and np.isfinite(t_final) and t_final > 0):
        raise ModelError(f"simulate: dt={dt!r} and t_final={t_final!r} must be finite and > 0 s")
    steps = int(round(t_final / dt))
    if steps < 1 or abs(steps * dt - t_final) > 1e-9 * t_final:
        raise ModelError(f"simulate: t_final={t_final!r} must be a whole number of steps "
                         f"dt={dt!r}")
    if store_every < 1:
        raise ModelError(f"simulate: store_every={store_every!r} must be an integer >= 1")

    def rates(t, q, v):
        tau = None if torque is None else torque(t, q, v)
        return configuration_rate(tree, q, v), forward_dynamics(tree, q, v, tau, t)

    q, v = normalized(tree, q0), np.array(v0, dtype=float)
    times, qs, vs = [0.0], [q.copy()], [v.copy()]
    h = dt
    for k in range(steps):
        t = k * h
        k1q, k1v = rates(t, q, v)
        k2q, k2v = rates(t + h / 2, q + h / 2 * k1q, v + h / 2 * k1v)
        k3q, k3v = rates(t + h / 2, q + h / 2 * k2q, v + h / 2 * k2v)
        k4q, k4v = rates(t + h, q + h * k3q, v + h * k3v)
        q = normalized(tree, q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q))
        v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise SimulationError("spatial reference RK4: non-finite state", time=t + h,
                                  element=None, partial_result=Trajectory(
                                      np.array(times), np.array(qs), np.array(vs)))
        if (k + 1) % store_every == 0 or k + 1 == steps:
            times.append((k + 1) * h)
            qs.append(q.copy())
            vs.append(v.copy())
    return Trajectory(np.array(times), np.array(qs), np.array(vs))


def linearize(tree: SpatialTree, q0, t: float = 0.0, tolerance: float = 1e-9):
    """``(M, C, K)`` of small motions ``q = q0 (+) x`` (:func:`retract`) about an equilibrium.

    ``M = M(q0)``; ``K = d h / d x`` and ``C = d h / d v`` at ``(q0, v = 0)`` by the complex
    step (step 1e-30, exact to round-off); ``K`` includes the geometric stiffness of gravity
    and constant loads.  Refuses (``ModelError``) a ``q0`` where ``|h(q0, 0)|`` exceeds
    ``tolerance`` times the largest generalised gravity force (not an equilibrium).
    """
    q0 = normalized(tree, q0)
    zero = np.zeros(tree.nv)
    kin = kinematics(tree, q0, zero)
    scale = 1.0 + np.max(np.abs(np.einsum("bin,b,i->n", kin.jacobian_com,
                                          np.array([b.mass for b in tree.bodies]),
                                          tree.gravity)))
    residual = bias_forces(tree, q0, zero, t, kin)
    if np.max(np.abs(residual)) > tolerance * scale:
        raise ModelError(f"linearize: q0 is not an equilibrium (largest residual generalised "
                         f"force {np.max(np.abs(residual)):.3e}, allowed "
                         f"{tolerance * scale:.3e})")
    step = 1e-30
    stiffness, damping = np.zeros((tree.nv, tree.nv)), np.zeros((tree.nv, tree.nv))
    for k in range(tree.nv):
        unit = np.zeros(tree.nv, dtype=complex)
        unit[k] = 1j * step
        stiffness[:, k] = bias_forces(tree, retract(tree, q0, unit), zero, t).imag / step
        damping[:, k] = bias_forces(tree, q0, unit, t).imag / step
    return mass_matrix(tree, q0, kin), damping, stiffness


def natural_frequencies(tree: SpatialTree, q0, t: float = 0.0) -> np.ndarray:
    """Undamped natural frequencies [rad/s], ascending: ``sqrt(eig(K, M))`` of :func:`linearize`."""
    mass, _, stiffness = linearize(tree, q0, t)
    values = np.sort(scipy.linalg.eigvals(stiffness, mass).real)
    return np.sqrt(np.maximum(values, 0.0))


__all__ = ["SpatialBody", "PointLoad", "SpatialTree", "JOINT_SIZES", "mass_matrix",
           "bias_forces", "forward_dynamics", "inverse_dynamics", "joint_reactions",
           "joint_law_forces", "joint_deflection", "energy", "configuration_rate", "retract",
           "normalized", "simulate", "Trajectory", "linearize", "natural_frequencies"]
