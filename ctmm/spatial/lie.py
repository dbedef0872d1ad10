"""Configuration increments of spatial models on their Lie group (numpy, one state).

The configuration of a :class:`~ctmm.spatial.model.SpatialModel` is a product of groups, one per
joint: ``R^k`` for revolute, prismatic and universal joints, ``SO(3)`` for spherical joints (unit
quaternion ``(w, x, y, z)``) and ``SE(3)`` for free and elastic 6-DOF joints (child origin ``t`` in
the joint frame and quaternion).  An increment ``delta`` has the size of the velocity ``v`` and the
same meaning (child axes for rotations and for the 6-DOF translation), so ``q(s) = q (+) s v`` is the
motion at constant ``v``:

* scalar joints and the modal coordinates of beams: ``q + delta``;
* spherical: ``quat (x) exp(phi)``, ``exp(phi) = (cos(|phi|/2), sin(|phi|/2) phi/|phi|)``: the
  incremental rotation vector ``phi`` in child axes (no gimbal lock: no angles are stored);
* free / elastic6 with ``delta = [u ; phi]``: ``quat (x) exp(phi)`` and ``t + R(quat) J(phi) u``
  with ``J(phi) = I + (1 - cos a)/a^2 [phi]x + (a - sin a)/a^3 [phi]x^2`` (``a = |phi|``), the
  exponential of the body twist ``(u, phi)`` on ``SE(3)`` (``t_dot = R v_o``, ``R_dot = R [omega]x``).

:func:`local_coordinates` is the inverse (the logarithm): ``q_base (+) delta = q``.
"""
from __future__ import annotations

import numpy as np

from .model import SpatialModel

__all__ = ["quaternion_product", "quaternion_exponential", "quaternion_logarithm", "left_jacobian",
           "retract", "local_coordinates", "bracket"]


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a (x) b`` of quaternions ``(w, x, y, z)``."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def quaternion_exponential(phi: np.ndarray) -> np.ndarray:
    """Unit quaternion of the rotation vector ``phi`` [rad] (rotation by ``|phi|`` about ``phi``)."""
    angle = float(np.linalg.norm(phi))
    half = 0.5 * angle
    # sin(a/2)/a, with its series below 1e-4 rad (error < 1e-18)
    factor = np.sin(half) / angle if angle > 1e-4 else 0.5 - angle * angle / 48.0
    return np.concatenate([[np.cos(half)], factor * np.asarray(phi, dtype=float)])


def quaternion_logarithm(quaternion: np.ndarray) -> np.ndarray:
    """Rotation vector ``phi`` (``|phi| <= pi``) of a non-zero quaternion (either sign)."""
    quaternion = np.asarray(quaternion, dtype=float) / np.linalg.norm(quaternion)
    if quaternion[0] < 0.0:
        quaternion = -quaternion
    w, vector = quaternion[0], quaternion[1:]
    sine = float(np.linalg.norm(vector))
    angle = 2.0 * np.arctan2(sine, w)
    factor = angle / sine if sine > 1e-8 else 2.0 / w * (1.0 - sine * sine / (3.0 * w * w))
    return factor * vector


def left_jacobian(phi: np.ndarray) -> np.ndarray:
    """``J(phi) = I + (1 - cos a)/a^2 [phi]x + (a - sin a)/a^3 [phi]x^2`` (``a = |phi|``): the
    translation of the ``SE(3)`` exponential per unit body-frame velocity."""
    a2 = float(np.dot(phi, phi))
    if a2 > 1e-6:
        a = np.sqrt(a2)
        first, second = (1.0 - np.cos(a)) / a2, (a - np.sin(a)) / (a2 * a)
    else:                                            # series, error < 1e-16
        first, second = 0.5 - a2 / 24.0 + a2 * a2 / 720.0, 1.0 / 6.0 - a2 / 120.0 + a2 * a2 / 5040.0
    K = _skew(phi)
    return np.eye(3) + first * K + second * (K @ K)


def _rotation(quaternion: np.ndarray) -> np.ndarray:
    w, x, y, z = quaternion / np.linalg.norm(quaternion)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _unit(quaternion: np.ndarray) -> np.ndarray:
    return quaternion / np.linalg.norm(quaternion)


def retract(model: SpatialModel, q: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """``q (+) delta`` (module docstring): ``q`` (nq,), ``delta`` (nv,) in velocity coordinates.

    Quaternions of the result are unit (those of ``q`` are normalised first)."""
    out = np.array(q, dtype=float)
    for joint, layout in zip(model.joints, model.layout):
        if joint.driven or layout.velocity.stop == layout.velocity.start:
            continue
        qj, dj = out[layout.position], np.asarray(delta[layout.velocity], dtype=float)
        if joint.kind == "spherical":
            out[layout.position] = _unit(quaternion_product(_unit(qj), quaternion_exponential(dj)))
        elif joint.kind in ("free", "elastic6"):
            quaternion = _unit(qj[3:])
            out[layout.position.start:layout.position.start + 3] = \
                qj[:3] + _rotation(quaternion) @ (left_jacobian(dj[3:]) @ dj[:3])
            out[layout.position.start + 3:layout.position.stop] = \
                _unit(quaternion_product(quaternion, quaternion_exponential(dj[3:])))
        else:
            out[layout.position] = qj + dj
    for layout in model.modal:                       # beams' modal coordinates: a vector space
        if layout is not None:
            out[layout.position] = out[layout.position] + np.asarray(delta[layout.velocity], dtype=float)
    return out


def local_coordinates(model: SpatialModel, q_base: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``delta`` (nv,) with ``q_base (+) delta = q`` (rotations of less than pi per joint)."""
    delta = np.zeros(model.n_velocities)
    for joint, layout in zip(model.joints, model.layout):
        if joint.driven or layout.velocity.stop == layout.velocity.start:
            continue
        base, target = q_base[layout.position], q[layout.position]
        if joint.kind == "spherical":
            inverse = _unit(base) * np.array([1.0, -1.0, -1.0, -1.0])
            delta[layout.velocity] = quaternion_logarithm(quaternion_product(inverse, _unit(target)))
        elif joint.kind in ("free", "elastic6"):
            quaternion = _unit(base[3:])
            inverse = quaternion * np.array([1.0, -1.0, -1.0, -1.0])
            phi = quaternion_logarithm(quaternion_product(inverse, _unit(target[3:])))
            u = np.linalg.solve(left_jacobian(phi), _rotation(quaternion).T @ (target[:3] - base[:3]))
            delta[layout.velocity] = np.concatenate([u, phi])
        else:
            delta[layout.velocity] = target - base
    for layout in model.modal:
        if layout is not None:
            delta[layout.velocity] = q[layout.position] - q_base[layout.position]
    return delta


def bracket(model: SpatialModel, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Lie bracket ``[x, y]`` (nv,) of two increments: 0 for scalar joints, ``x x y`` on ``SO(3)``,
    ``(phi_x x u_y + u_x x phi_y, phi_x x phi_y)`` on ``SE(3)`` (``[u ; phi]`` blocks).

    To second order in ``x``, the body velocity of ``q (+) x(t)`` is ``x_dot - 1/2 [x, x_dot]`` and its
    rate ``x_ddot - 1/2 [x, x_ddot] - 1/2 [x_dot, x_dot]`` (the last term is zero)."""
    out = np.zeros(model.n_velocities)
    for joint, layout in zip(model.joints, model.layout):
        if joint.driven:
            continue
        xj, yj = x[layout.velocity], y[layout.velocity]
        if joint.kind == "spherical":
            out[layout.velocity] = np.cross(xj, yj)
        elif joint.kind in ("free", "elastic6"):
            out[layout.velocity] = np.concatenate([np.cross(xj[3:], yj[:3]) + np.cross(xj[:3], yj[3:]),
                                                   np.cross(xj[3:], yj[3:])])
    return out
