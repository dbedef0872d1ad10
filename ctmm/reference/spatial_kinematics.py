"""Rotations, joint motions and forward kinematics of :mod:`ctmm.reference.spatial_tree`.

Complex-step safe (no ``abs`` or norms inside values) so that :func:`spatial_tree.linearize`
can differentiate through it.  Conventions: see :mod:`ctmm.reference.spatial_tree`.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: joint kind -> (number of configuration coordinates nq, number of velocities nv)
JOINT_SIZES = {"revolute": (1, 1), "prismatic": (1, 1), "universal": (2, 2),
               "spherical": (4, 3), "free": (7, 6), "elastic6": (7, 6), "weld": (0, 0)}


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross(a, b)`` of vectors along the last axis (broadcast), by the same products and differences
    without ``np.cross``'s axis handling, which dominated the reference's time on small vectors (the same values
    to the bit, complex included)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape == b.shape == (3,) and a.dtype == b.dtype == np.float64:     # one pair: on Python floats
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        return np.array((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    first = a1 * b2 - a2 * b1                 # each component already has the broadcast shape of a and b
    out = np.empty(first.shape + (3,), first.dtype)
    out[..., 0] = first
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


_EYE3 = np.eye(3)
_EYE3.flags.writeable = False


# -- rotations (complex-step safe: no abs, no norm) -------------------------------------------
def skew(x: np.ndarray) -> np.ndarray:
    """``[x]`` with ``[x] y = x cross y``."""
    return np.array([[0 * x[0], -x[2], x[1]], [x[2], 0 * x[0], -x[0]], [-x[1], x[0], 0 * x[0]]])


def quaternion_matrix(quat: np.ndarray) -> np.ndarray:
    """Rotation matrix of a scalar-last quaternion (normalised inside)."""
    vec, w = quat[:3], quat[3]
    s = quat @ quat
    vx = skew(vec)
    return _EYE3 + (2.0 / s) * (w * vx + vx @ vx)


def quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a b`` of scalar-last quaternions."""
    return np.concatenate([a[3] * b[:3] + b[3] * a[:3] + cross(a[:3], b[:3]),
                           [a[3] * b[3] - a[:3] @ b[:3]]])


def exp_quaternion(phi: np.ndarray) -> np.ndarray:
    """Unit quaternion of the rotation vector ``phi`` [rad]."""
    s = phi @ phi
    if abs(s) < 1e-8:
        half_sinc, cos_half = 0.5 - s / 48.0 + s * s / 3840.0, 1.0 - s / 8.0 + s * s / 384.0
    else:
        theta = np.sqrt(s)
        half_sinc, cos_half = np.sin(theta / 2) / theta, np.cos(theta / 2)
    return np.concatenate([half_sinc * phi, [cos_half]])


def rotation_vector(quat: np.ndarray) -> np.ndarray:
    """Rotation vector ``phi = log(R)`` [rad] of a scalar-last quaternion, |phi| <= pi."""
    quat = quat / np.sqrt(quat @ quat)
    if np.real(quat[3]) < 0:
        quat = -quat
    vec, w = quat[:3], quat[3]
    s = vec @ vec
    u = s / (w * w) if abs(w) > 1e-3 else None
    if u is not None and abs(u) < 1e-6:
        return vec * (2.0 / w) * (1.0 - u / 3.0 + u * u / 5.0 - u ** 3 / 7.0)
    theta = np.sqrt(s)
    angle = np.arctan(theta / w) if np.iscomplexobj(quat) else np.arctan2(theta, w)
    return vec * (2.0 * angle / theta)


# -- joints ------------------------------------------------------------------------------------
def joint_rotation(body, qj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One joint's relative rotation ``R`` (joint -> child axes) and angular motion axes ``angular`` (child
    axes, (3, nv)), each rotation of its coordinates built once; :func:`joint_terms` adds the linear terms."""
    kind = body.joint
    dtype = np.result_type(qj, float)
    angular = np.zeros((3, JOINT_SIZES[kind][1]), dtype)
    if kind == "revolute":
        rel = quaternion_matrix(exp_quaternion(body.axes[0] * qj[0]))
        angular[:, 0] = body.axes[0]
    elif kind == "universal":
        second = quaternion_matrix(exp_quaternion(body.axes[1] * qj[1]))
        rel = quaternion_matrix(exp_quaternion(body.axes[0] * qj[0])) @ second
        angular[:, 0] = second.T @ body.axes[0]
        angular[:, 1] = body.axes[1]
    elif kind == "spherical":
        rel = quaternion_matrix(qj)
        angular[:, :] = np.eye(3)
    elif kind in ("free", "elastic6"):
        rel = quaternion_matrix(qj[3:7])
        angular[:, 3:] = np.eye(3)
    else:                                       # prismatic, weld
        rel = np.eye(3)
    return rel, angular


def joint_terms(body, qj: np.ndarray, vj: np.ndarray):
    """One joint's terms, each rotation of its coordinates built once: relative rotation ``R`` (joint -> child
    axes), child origin ``d`` in joint axes, motion axes ``angular`` (child axes) and ``linear`` (joint axes),
    (3, nv) each, and the rates of the motion columns times ``vj`` at ``vdot = 0`` (angular child, linear joint)."""
    kind = body.joint
    dtype = np.result_type(qj, float)
    rel, angular = joint_rotation(body, qj)
    d = np.zeros(3, dtype=dtype)
    linear = np.zeros(angular.shape, dtype)
    bias_w = bias_d = np.zeros(3, dtype=np.result_type(qj, vj, float))
    if kind == "prismatic":
        d = body.axes[0] * qj[0]
        linear[:, 0] = body.axes[0]
    elif kind == "universal":
        bias_w = -cross(body.axes[1] * vj[1], angular[:, 0] * vj[0])
    elif kind in ("free", "elastic6"):
        d = qj[:3]
        linear[:, :3] = rel
        bias_d = rel @ cross(vj[3:6], vj[:3])
    return rel, d, angular, linear, bias_w, bias_d


# -- kinematics ----------------------------------------------------------------------------------
class Kinematics(NamedTuple):
    """World poses, velocities, bias accelerations (``vdot = 0``) and Jacobians of all bodies."""

    rotation: np.ndarray        # (nb, 3, 3) body -> world
    origin: np.ndarray          # (nb, 3) body origins [m]
    omega: np.ndarray           # (nb, 3) [rad/s]
    com: np.ndarray             # (nb, 3) centres of mass [m]
    com_velocity: np.ndarray    # (nb, 3) [m/s]
    alpha_bias: np.ndarray      # (nb, 3) [rad/s^2]
    com_bias: np.ndarray        # (nb, 3) [m/s^2]
    jacobian_angular: np.ndarray  # (nb, 3, nv)
    jacobian_com: np.ndarray    # (nb, 3, nv)
    joint_axes: list            # per body: (world angular, world linear of child origin) (3, nv_j)


class Orientations(NamedTuple):
    """World rotations and angular velocities of all bodies (the part of :class:`Kinematics` they need)."""

    rotation: np.ndarray        # (nb, 3, 3) body -> world
    omega: np.ndarray           # (nb, 3) [rad/s]


def joint_coordinates(tree, i: int, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body ``i``'s joint coordinates ``qj`` and velocities ``vj`` (views of ``q`` and ``v``)."""
    nq, nv = JOINT_SIZES[tree.bodies[i].joint]
    qs, vs = tree.q_start[i], tree.v_start[i]
    return q[qs: qs + nq], v[vs: vs + nv]


def orientations(tree, q: np.ndarray, v: np.ndarray) -> Orientations:
    """World rotations and angular velocities [rad/s] of all bodies by the same operations as
    :func:`kinematics` (the same values to the bit), without positions, accelerations or Jacobians."""
    nb = len(tree.bodies)
    dtype = np.result_type(q, v, float)
    rot, omega = np.zeros((nb, 3, 3), dtype), np.zeros((nb, 3), dtype)
    for i, body in enumerate(tree.bodies):
        qj, vj = joint_coordinates(tree, i, q, v)
        p = body.parent
        rp, wp = (rot[p], omega[p]) if p >= 0 else (np.eye(3), np.zeros(3))
        rel, ang = joint_rotation(body, qj)
        rot[i] = (rp @ body.joint_rotation) @ rel
        omega[i] = wp + (rot[i] @ ang) @ vj
    return Orientations(rot, omega)


def kinematics(tree, q: np.ndarray, v: np.ndarray) -> Kinematics:
    """Forward kinematics of positions, velocities and accelerations at ``vdot = 0``."""
    nb, nv = len(tree.bodies), tree.nv
    dtype = np.result_type(q, v, float)
    rot = np.zeros((nb, 3, 3), dtype)
    origin, omega, velocity = (np.zeros((nb, 3), dtype) for _ in range(3))
    alpha, accel = np.zeros((nb, 3), dtype), np.zeros((nb, 3), dtype)
    jw, jo = np.zeros((nb, 3, nv), dtype), np.zeros((nb, 3, nv), dtype)
    axes = []
    for i, body in enumerate(tree.bodies):
        qj, vj = joint_coordinates(tree, i, q, v)
        vs = tree.v_start[i]
        p = body.parent
        if p >= 0:
            rp, op, wp, vp, ap, acp = rot[p], origin[p], omega[p], velocity[p], alpha[p], accel[p]
        else:
            rp, op = np.eye(3), np.zeros(3)
            wp = vp = ap = acp = np.zeros(3)
        r_joint = rp @ body.joint_rotation
        rel, d, ang, lin, bias_w, bias_d = joint_terms(body, qj, vj)
        rot[i] = r_joint @ rel
        origin[i] = op + rp @ body.joint_position + r_joint @ d
        s_w, s_v = rot[i] @ ang, r_joint @ lin
        axes.append((s_w, s_v))
        w_rel, d_rel = s_w @ vj, s_v @ vj
        lever = origin[i] - op
        omega[i] = wp + w_rel
        if p >= 0:
            transport = cross(wp, lever)
            velocity[i] = vp + transport + d_rel
            alpha[i] = ap + rot[i] @ bias_w + cross(wp, w_rel)
            accel[i] = (acp + cross(ap, lever) + cross(wp, transport)
                        + 2.0 * cross(wp, d_rel) + r_joint @ bias_d)
            jw[i] = jw[p]
            jo[i] = jo[p] + cross(jw[p].T, lever).T
        else:       # at rest: the cross products with the ground's zero rates are zeros, 0 + (+-0) = 0 = vp
            velocity[i] = vp + d_rel
            alpha[i] = ap + rot[i] @ bias_w
            accel[i] = acp + r_joint @ bias_d
        jw[i][:, vs: vs + s_w.shape[1]] += s_w
        jo[i][:, vs: vs + s_w.shape[1]] += s_v
    arm = np.einsum("bij,bj->bi", rot, np.array([b.com for b in tree.bodies]))
    com = origin + arm
    com_velocity = velocity + cross(omega, arm)
    com_bias = accel + cross(alpha, arm) + cross(omega, cross(omega, arm))
    jc = jo + cross(jw.transpose(0, 2, 1), arm[:, None, :]).transpose(0, 2, 1)
    return Kinematics(rot, origin, omega, com, com_velocity, alpha, com_bias, jw, jc, axes)


def point_jacobian(kin: Kinematics, body: int, point_world: np.ndarray) -> np.ndarray:
    """(3, nv) Jacobian of the world velocity of a body point (world position ``point_world``)."""
    arm = point_world - kin.com[body]
    return kin.jacobian_com[body] + cross(kin.jacobian_angular[body].T, arm).T
