"""Relative motion of a spatial joint in its joint frame: rotation, translation, motion subspace ``S``, bias and
law (:func:`joint_motion`), for :meth:`ctmm.spatial.body_forms.SpatialScene.terms` (issue 14, ``docs/spatial.md``).

One ops statement for numpy and casadi; on numpy the spherical, free and elastic joints take a fast path
(:func:`_numpy_joint_motion`): the same operations on the same operands, their blocks filled into one allocation
and the law's scalar arithmetic on whole columns, in place of block-by-block assembly of ``(B, 1, 1)`` scalars
(``tests/test_spatial_numpy_terms.py`` holds the two paths equal).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Mapping, Sequence

import numpy as np

from ..ops import NUMPY, Ops, batch_shape
from .frames import axis_rotation, axis_terms, column, constant, cross, quaternion_rotation, skew

__all__ = ["JointMotion", "joint_motion", "AxisJointFamily"]

@dataclass(frozen=True)
class JointMotion:
    """Relative motion of a joint in its joint frame (ops values; ``None`` for zero).

    Attributes
    ----------
    rotation : (3, 3)
        Child axes relative to the joint frame ``R_rel``.
    translation : (3, 1) or None
        Child origin in the joint frame [m].
    S : (6, k)
        Relative twist ``[u ; w]`` of the inboard point per unit ``v`` (joint frame).
    bias : (6, 1) or None
        ``S_dot v`` seen in the joint frame (relative acceleration at ``v_dot = 0``).
    linear : (3, 1) or None
        ``u``: velocity of the inboard point relative to the parent [m/s].
    angular : (3, 1) or None
        ``w``: relative angular velocity [rad/s].
    tau, tau_q, tau_v, prescribed
        As in :class:`~ctmm.protocol.JointTerms`.
    """

    rotation: Any
    translation: Any
    S: Any
    bias: Any
    linear: Any
    angular: Any
    tau: Any = None
    tau_q: Any = None
    tau_v: Any = None
    prescribed: Any = None


def _axis_columns(ops: Ops, axis: Any, start: int) -> tuple[Any, Any]:
    """``(a, S)``: a joint axis as an ops column and its unit twist ``S`` (6 x 1) with the axis in rows
    ``start:start + 3`` (numpy constants read-only, shared by the calls with that axis)."""
    return _axis_constants(ops, tuple(np.asarray(axis, dtype=float).reshape(3).tolist()), start)


@lru_cache(maxsize=256)
def _axis_constants(ops: Ops, axis: tuple[float, float, float], start: int) -> tuple[Any, Any]:
    twist = np.zeros(6)
    twist[start:start + 3] = axis
    out = (constant(ops, axis), constant(ops, twist))
    if ops.name == "numpy":
        for value in out:
            value.flags.writeable = False
    return out


def _law(ops: Ops, joint, q: list, v: list, u: Any) -> tuple[Any, Any, Any]:
    """``tau = u - k (q - q_ref) - c v`` of a 1- or 2-DOF joint, with its tangents."""
    k, c, ref = joint.stiffness, joint.damping, joint.reference
    law = getattr(joint, "law", None)
    if not (np.any(k) or np.any(c)) and u is None and law is None:
        return None, None, None
    terms = [q[i] * -k[i] + k[i] * ref[i] - v[i] * c[i] for i in range(len(v))]
    tau_q, tau_v = constant(ops, -np.diag(k)), constant(ops, -np.diag(c))
    if law is not None:                     # nonlinear law per coordinate, its tangents on the diagonal
        tangents = [law.tangents(q[i] - ref[i], v[i]) for i in range(len(v))]
        terms = [terms[i] - law.force(q[i] - ref[i], v[i]) for i in range(len(v))]
        n = len(v)
        tau_q = tau_q + ops.block([[-tangents[i][0] if i == j else 0.0 for j in range(n)] for i in range(n)])
        tau_v = tau_v + ops.block([[-tangents[i][1] if i == j else 0.0 for j in range(n)] for i in range(n)])
    tau = column(ops, terms)
    if u is not None:
        tau = tau + u
    return tau, tau_q, tau_v


def joint_motion(ops: Ops, joint, q: list, v: list, u: Any = None, acceleration: list | None = None) -> JointMotion:
    """Relative kinematics and law of one joint from its coordinates ``q`` and velocities ``v`` (lists of
    ops scalars), actuator input ``u`` (ops column or ``None``) and, for a driven joint, its prescribed
    ``acceleration`` (list of ops scalars)."""
    kind = joint.kind
    if ops.name == "numpy" and kind in ("spherical", "free", "elastic6"):
        return _numpy_joint_motion(joint, q, v, u, acceleration)
    zero3 = ops.zeros(3, 1)
    if kind == "weld":
        return JointMotion(ops.eye(3), None, ops.zeros(6, 0), None, None, None)
    if kind == "revolute":
        a, S = _axis_columns(ops, joint.axis, 3)
        motion = dict(rotation=axis_rotation(ops, joint.axis, q[0]), translation=None,
                      S=S, bias=None, linear=None, angular=a * v[0])
    elif kind == "prismatic":
        a, S = _axis_columns(ops, joint.axis, 0)
        motion = dict(rotation=ops.eye(3), translation=a * q[0], S=S, bias=None, linear=a * v[0], angular=None)
    elif kind == "universal":
        first = axis_rotation(ops, joint.axis1, q[0])
        a1 = constant(ops, joint.axis1)
        s2 = ops.matmul(first, constant(ops, joint.axis2))
        motion = dict(rotation=ops.matmul(first, axis_rotation(ops, joint.axis2, q[1])), translation=None,
                      S=ops.block([[ops.zeros(3, 2)], [ops.block([[a1, s2]])]]),
                      bias=ops.block([[zero3], [cross(ops, a1, s2) * (v[0] * v[1])]]), linear=None,
                      angular=a1 * v[0] + s2 * v[1])
    elif kind == "spherical":
        R = quaternion_rotation(ops, *q)
        omega = column(ops, v)
        motion = dict(rotation=R, translation=None, S=ops.block([[ops.zeros(3, 3)], [R]]), bias=None, linear=None,
                      angular=ops.matmul(R, omega))
    elif kind in ("free", "elastic6"):
        R = quaternion_rotation(ops, *q[3:])
        t = column(ops, q[:3])
        w = ops.matmul(R, column(ops, v[3:]))
        linear = ops.matmul(R, column(ops, v[:3])) - cross(ops, w, t)
        motion = dict(rotation=R, translation=t,
                      S=ops.block([[R, ops.matmul(skew(ops, t), R)], [ops.zeros(3, 3), R]]),
                      bias=ops.block([[cross(ops, w, linear)], [zero3]]), linear=linear, angular=w)
    else:                                       # pragma: no cover - guarded by the model
        raise AssertionError(kind)
    if acceleration is not None:
        return JointMotion(**motion, prescribed=column(ops, acceleration))
    tau = tau_q = tau_v = None
    if kind in ("revolute", "prismatic", "universal"):
        tau, tau_q, tau_v = _law(ops, joint, q, v, u)
    elif kind == "spherical":
        w0, x, y, z = q
        n2 = w0 * w0 + x * x + y * y + z * z
        s = column(ops, [w0 * x * 2.0 / n2, w0 * y * 2.0 / n2, w0 * z * 2.0 / n2])
        if np.any(joint.stiffness) or np.any(joint.damping) or u is not None:
            tau = (ops.matmul(constant(ops, joint.stiffness), s) + ops.matmul(constant(ops, joint.damping),
                                                                               column(ops, v))) * -1.0
            tau = tau if u is None else tau + u
            tau_q, tau_v = constant(ops, -joint.stiffness), constant(ops, -joint.damping)
    else:
        if kind == "elastic6":
            w0, x, y, z = q[3:]
            n2 = w0 * w0 + x * x + y * y + z * z
            R = motion["rotation"]
            e = ops.block([[ops.matmul(ops.transpose(R), motion["translation"])],
                           [column(ops, [w0 * x * 2.0 / n2, w0 * y * 2.0 / n2, w0 * z * 2.0 / n2])]])
            tau = (ops.matmul(constant(ops, joint.stiffness), e) + ops.matmul(constant(ops, joint.damping),
                                                                               column(ops, v))) * -1.0
            tau_q, tau_v = constant(ops, -joint.stiffness), constant(ops, -joint.damping)
        if u is not None:
            tau = u if tau is None else tau + u
    return JointMotion(**motion, tau=tau, tau_q=tau_q, tau_v=tau_v)


def _numpy_joint_motion(joint, q: list, v: list, u: Any, acceleration: list | None) -> JointMotion:
    """:func:`joint_motion` of a spherical, free or elastic joint on numpy batches: the same operations on the same
    operands (entry by entry), the coordinates stacked once, ``S``, the bias and the law's deformation filled into
    one allocation each, and the law's ``2 w (x, y, z) / |q|^2`` on the column ``(x, y, z)`` (one state: on Python
    floats, the same IEEE operations); a spherical joint without law or input forms no law terms (the ops statement
    forms its ``s`` and drops it)."""
    kind = joint.kind
    positions, velocities = _stacked(q), _stacked(v)
    quaternion = positions if kind == "spherical" else positions[:, 3:]
    R = quaternion_rotation(NUMPY, *q[-4:])
    if kind == "spherical":
        S = np.zeros(R.shape[:-2] + (6, 3), dtype=np.result_type(R, float))
        S[..., 3:, :] = R
        motion = dict(rotation=R, translation=None, S=S, bias=None, linear=None, angular=np.matmul(R, velocities))
    else:
        t = positions[:, :3]
        w = np.matmul(R, velocities[:, 3:])
        linear = np.matmul(R, velocities[:, :3]) - cross(NUMPY, w, t)
        upper = np.matmul(skew(NUMPY, t), R)
        S = np.zeros(batch_shape(R, upper) + (6, 6), dtype=np.result_type(R, upper, float))
        S[..., :3, :3] = R
        S[..., :3, 3:] = upper
        S[..., 3:, 3:] = R
        drift = cross(NUMPY, w, linear)
        bias = np.zeros(drift.shape[:-2] + (6, 1), dtype=np.result_type(drift, float))
        bias[..., :3, :] = drift
        motion = dict(rotation=R, translation=t, S=S, bias=bias, linear=linear, angular=w)
    if acceleration is not None:
        return JointMotion(**motion, prescribed=column(NUMPY, acceleration))
    if kind == "free":
        return JointMotion(**motion, tau=u)
    if kind == "spherical" and not (joint.stiffness.any() or joint.damping.any() or u is not None):
        return JointMotion(**motion)
    if quaternion.shape == (1, 4, 1) and quaternion.dtype == np.float64:      # one state: on Python floats
        w0, x, y, z = quaternion.ravel().tolist()
        n2 = w0 * w0 + x * x + y * y + z * z
        s = np.array((w0 * x * 2.0 / n2, w0 * y * 2.0 / n2, w0 * z * 2.0 / n2)).reshape(1, 3, 1)
    else:
        w0, x, y, z = (quaternion[:, k:k + 1] for k in range(4))
        s = w0 * quaternion[:, 1:] * 2.0 / (w0 * w0 + x * x + y * y + z * z)    # w0 * x * 2.0 / n2, ...
    if kind == "elastic6":
        turned = np.matmul(R.swapaxes(-1, -2), motion["translation"])
        e = np.empty(batch_shape(turned, s) + (6, 1), dtype=np.result_type(turned, s))
        e[..., :3, :] = turned
        e[..., 3:, :] = s
        s = e
    tau = (np.matmul(constant(NUMPY, joint.stiffness), s) + np.matmul(constant(NUMPY, joint.damping), velocities)) * -1.0
    if u is not None:
        tau = tau + u
    return JointMotion(**motion, tau=tau, tau_q=constant(NUMPY, -joint.stiffness), tau_v=constant(NUMPY, -joint.damping))


def _stacked(values: list) -> np.ndarray:
    """Batched scalars ``(B, 1, 1)`` as one column ``(B, k, 1)`` (:func:`~ctmm.spatial.frames.column`'s entries;
    one concatenation when they share a batch and dtype)."""
    first = values[0]
    if type(first) is np.ndarray and first.ndim == 3:
        lead, dtype = first.shape[0], first.dtype
        if all(type(e) is np.ndarray and e.ndim == 3 and e.shape[0] == lead and e.dtype == dtype for e in values):
            return np.concatenate(values, axis=-2)
    return column(NUMPY, values)


class AxisJointFamily:
    """The revolute (or the prismatic) joints of a model that are neither driven nor carry a nonlinear law:
    :func:`joint_motion` of all of them at once on numpy (the same operations on the same operands, every operand
    with a leading axis over the joints; their numbers stacked once), split into each joint's motion (views).

    Parameters
    ----------
    joints : sequence of Revolute or of Prismatic joints (one kind)
    positions, velocities : sequence of int
        Each joint's coordinate and velocity column in the state.
    """

    def __init__(self, joints: Sequence, positions: Sequence[int], velocities: Sequence[int]) -> None:
        self.joints = tuple(joints)
        self.kind = self.joints[0].kind
        self.positions, self.velocities = np.asarray(positions, dtype=int), np.asarray(velocities, dtype=int)
        start = 3 if self.kind == "revolute" else 0
        constants = [_axis_columns(NUMPY, joint.axis, start) for joint in self.joints]
        self.axes = np.concatenate([axis for axis, _ in constants]).reshape(-1, 1, 3, 1)
        self.twists = [twist for _, twist in constants]
        if self.kind == "revolute":
            terms = [axis_terms(NUMPY, tuple(np.asarray(joint.axis, dtype=float).reshape(3).tolist()))
                     for joint in self.joints]
            self.eye = terms[0][0]
            self.k = np.concatenate([k for _, k, _ in terms]).reshape(-1, 1, 3, 3)
            self.k2 = np.concatenate([k2 for _, _, k2 in terms]).reshape(-1, 1, 3, 3)
        numbers = [(joint.stiffness[0], joint.damping[0], joint.reference[0]) for joint in self.joints]
        self.stiffness, self.damping, self.reference = (np.array(column, dtype=float).reshape(-1, 1, 1, 1)
                                                        for column in zip(*numbers))
        self.lawful = [bool(k or c) for k, c, _ in numbers]     # a law of its own (else: an input or none)
        self.tangents = np.negative(self.stiffness), np.negative(self.damping)    # each joint's -k, -c (1, 1, 1)
        for value in self.tangents:
            value.flags.writeable = False

    def motions(self, q: np.ndarray, v: np.ndarray, inputs: Mapping[str, Any]) -> list[JointMotion]:
        """Each joint's :func:`joint_motion` at the numpy state ``q (B, nq)``, ``v (B, nv)``."""
        count = len(self.joints)
        angle = q[:, self.positions].T.reshape(count, -1, 1, 1)
        rate = v[:, self.velocities].T.reshape(count, -1, 1, 1)
        moved = self.axes * rate
        law = angle * -self.stiffness + self.stiffness * self.reference - rate * self.damping
        if self.kind == "revolute":
            rotation = self.eye + self.k * np.sin(angle) + self.k2 * (1.0 - np.cos(angle))
            shift = None
        else:
            rotation, shift = NUMPY.eye(3), self.axes * angle
        out = []
        for i, joint in enumerate(self.joints):
            u = inputs.get(joint.inputs[0]) if joint.inputs else None
            if self.lawful[i] or u is not None:
                tau, tau_q, tau_v = law[i] if u is None else law[i] + u, self.tangents[0][i], self.tangents[1][i]
            else:
                tau = tau_q = tau_v = None
            if shift is None:
                out.append(JointMotion(rotation[i], None, self.twists[i], None, None, moved[i], tau, tau_q, tau_v))
            else:
                out.append(JointMotion(rotation, shift[i], self.twists[i], None, moved[i], None, tau, tau_q, tau_v))
        return out
