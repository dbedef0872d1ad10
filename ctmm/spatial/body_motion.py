"""The body kinematics of the spatial sweep, one body at a time: its pose and velocity from the inboard point and
its joint's relative motion, and the joint's terms in world axes (:func:`child_motion`; the statements of
:meth:`ctmm.spatial.body_forms.SpatialScene.terms` per body and the segment of :mod:`ctmm.compiled_spatial`'s
folds; issue 14, ``docs/spatial.md``)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..ops import Ops, batch_shape
from ..protocol import JointTerms
from .frames import block_diagonal, constant, cross
from .joint_kinematics import JointMotion

__all__ = ["BodyState", "ChildMotion", "child_motion"]


@dataclass(frozen=True)
class BodyState:
    """Pose and velocity of one body (ops values, world axes).

    Attributes
    ----------
    rotation : (3, 3)
        Body axes to world axes.
    origin : (3, 1)
        Body origin [m].
    velocity : (3, 1)
        Velocity of the body origin [m/s].
    omega : (3, 1)
        Angular velocity [rad/s].
    inboard : (3, 1)
        The inboard point ``P`` [m].
    """

    rotation: Any
    origin: Any
    velocity: Any
    omega: Any
    inboard: Any


@dataclass(frozen=True)
class ChildMotion:
    """The pose, velocity and world-axes joint terms of one body (:func:`child_motion`).

    Attributes
    ----------
    state : BodyState
        The body's pose and velocity (zero columns where the motion has none).
    joint : JointTerms
        Its inboard joint's terms in world axes (``S``, bias ``c``, laws; ``prescribed`` of a driven joint).
    offset : ops (3, 1) or None
        The joint's translation in world axes [m] (``None``: none, the origin is the inboard point).
    omega : ops (3, 1) or None
        The body's angular velocity [rad/s] (``None``: the body does not turn, for the body terms).
    """

    state: BodyState
    joint: JointTerms
    offset: Any
    omega: Any


def child_motion(ops: Ops, joint_rotation: np.ndarray, rel: JointMotion, parent_rotation: Any, point: Any,
                 point_velocity: Any, parent_omega: Any) -> ChildMotion:
    """The body kinematics of the sweep for one body: its pose and velocity from the inboard point's and the
    joint's relative motion, and the joint terms in world axes (the statements of :meth:`SpatialScene.terms`
    per body, also the segment of :mod:`ctmm.compiled_spatial`'s folds).

    Parameters
    ----------
    ops : Ops
    joint_rotation : ndarray, shape (3, 3)
        The joint frame in the parent's axes (``joint.rotation``).
    rel : JointMotion
        The joint's relative motion (:func:`joint_motion`).
    parent_rotation : ops (3, 3) or None
        The parent's axes (``None``: the ground).
    point, point_velocity : ops (3, 1); point_velocity may be None
        The inboard point [m] and its velocity [m/s] (``None``: at rest).
    parent_omega : ops (3, 1) or None
        The parent's angular velocity [rad/s] (``None``: not turning).

    On numpy ``joint_rotation`` may also be the constant ``(1, 3, 3)`` itself (a scene's, formed once), and
    ``diag(R_PJ, R_PJ)`` and the bias ``c`` are filled into one allocation each (:func:`_frames`, :func:`_stacked`).
    """
    numpy = ops.name == "numpy"
    R_J = joint_rotation if numpy and np.ndim(joint_rotation) == 3 else constant(ops, joint_rotation)
    R_PJ = R_J if parent_rotation is None else ops.matmul(parent_rotation, R_J)
    R_c = ops.matmul(R_PJ, rel.rotation)
    offset = None if rel.translation is None else ops.matmul(R_PJ, rel.translation)
    o_c = point if offset is None else point + offset
    w_rel = None if rel.angular is None else ops.matmul(R_PJ, rel.angular)
    u_rel = None if rel.linear is None else ops.matmul(R_PJ, rel.linear)
    w_c = _add(parent_omega, w_rel)
    v_C = _add(point_velocity, u_rel)
    v_o = v_C if (offset is None or w_c is None) else _add(v_C, cross(ops, w_c, offset))
    state = BodyState(R_c, o_c, v_o if v_o is not None else ops.zeros(3, 1), w_c if w_c is not None else ops.zeros(3, 1),
                      point)
    S = ops.matmul(_frames(ops, R_PJ, numpy), rel.S) if rel.S is not None else None
    c_lin = None if rel.bias is None else ops.matmul(R_PJ, ops.sub(rel.bias, slice(0, 3), slice(0, 1)))
    c_ang = None if rel.bias is None else ops.matmul(R_PJ, ops.sub(rel.bias, slice(3, 6), slice(0, 1)))
    if parent_omega is not None:
        if u_rel is not None:
            c_lin = _add(c_lin, cross(ops, parent_omega, u_rel) * 2.0)
        if w_rel is not None:
            c_ang = _add(c_ang, cross(ops, parent_omega, w_rel))
    c = None if c_lin is None and c_ang is None else _stacked(ops, c_lin, c_ang, numpy)
    joint = JointTerms(S=S, c=c, tau=rel.tau, tau_q=rel.tau_q, tau_v=rel.tau_v, prescribed=rel.prescribed)
    return ChildMotion(state, joint, offset, w_c)


def _frames(ops: Ops, R_PJ: Any, numpy: bool) -> Any:
    """``diag(R_PJ, R_PJ)`` (6, 6); on numpy one allocation filled (no generic block checks)."""
    if not numpy:
        return block_diagonal(ops, R_PJ, R_PJ, 3, 3)
    frames = np.zeros(R_PJ.shape[:-2] + (6, 6), dtype=R_PJ.dtype)
    frames[..., :3, :3] = R_PJ
    frames[..., 3:, 3:] = R_PJ
    return frames


def _stacked(ops: Ops, c_lin: Any, c_ang: Any, numpy: bool) -> Any:
    """``[c_lin; c_ang]`` (6, 1), a missing part zero; on numpy one allocation filled."""
    if not numpy:
        return ops.block([[c_lin if c_lin is not None else ops.zeros(3, 1)],
                          [c_ang if c_ang is not None else ops.zeros(3, 1)]])
    parts = [part for part in (c_lin, c_ang) if part is not None]
    c = np.zeros(batch_shape(*parts) + (6, 1), dtype=np.result_type(*parts, float))
    if c_lin is not None:
        c[..., :3, :] = c_lin
    if c_ang is not None:
        c[..., 3:, :] = c_ang
    return c


def _add(a: Any, b: Any) -> Any:
    if a is None:
        return b
    if b is None:
        return a
    return a + b
