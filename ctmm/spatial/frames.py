"""Rotations and small vector algebra in :mod:`ctmm.ops` operations (numpy batched and casadi).

Quaternions are scalar first, ``(w, x, y, z)``, Hamilton product; the rotation of a quaternion is
formed from the quaternion divided by its norm (:func:`quaternion_rotation` is exact for any
non-zero quaternion), so integration drift of the norm never enters the physics (``docs/spatial.md``).
"""
from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from ..ops import Ops, batch_shape

__all__ = ["constant", "entry", "column", "skew", "cross", "axis_rotation", "quaternion_rotation",
           "quaternion_rate", "block_diagonal", "axis_terms"]


def constant(ops: Ops, array: Any) -> Any:
    """A numeric constant matrix as an ops value (``(1, r, c)`` numpy or ``casadi.DM``)."""
    array = np.asarray(array, dtype=float)
    if array.ndim == 1:
        array = array[:, None]
    if ops.name == "numpy":
        return array[None]
    import casadi

    return casadi.DM(array)


def entry(ops: Ops, matrix: Any, row: int, col: int = 0) -> Any:
    """The scalar ``matrix[row, col]`` (a 1 x 1 ops value)."""
    return ops.sub(matrix, slice(row, row + 1), slice(col, col + 1))


def column(ops: Ops, values: Any) -> Any:
    """A column from a sequence of scalars."""
    return ops.block([[v] for v in values])


def skew(ops: Ops, v: Any) -> Any:
    """``[v]x`` (3 x 3) of a column ``v`` (3 x 1): ``skew(v) w = v x w``."""
    if ops.name == "numpy":                     # same values, without nine-block assembly
        v = np.asarray(v)
        if v.shape == (1, 3, 1) and v.dtype == np.float64:                   # one state: from Python floats
            x, y, z = v.ravel().tolist()
            return np.array(((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0))).reshape(1, 3, 3)
        x, y, z = v[..., 0, 0], v[..., 1, 0], v[..., 2, 0]          # any leading shape (a family of batches)
        out = np.zeros(v.shape[:-2] + (3, 3), dtype=v.dtype)
        out[..., 0, 1], out[..., 0, 2], out[..., 1, 2] = -z, y, -x
        out[..., 1, 0], out[..., 2, 0], out[..., 2, 1] = z, -y, x
        return out
    x, y, z = (entry(ops, v, i) for i in range(3))
    return ops.block([[0.0, z * -1.0, y], [z, 0.0, x * -1.0], [y * -1.0, x, 0.0]])


def cross(ops: Ops, a: Any, b: Any) -> Any:
    """``a x b`` of two columns."""
    if ops.name == "numpy":
        if a.shape == b.shape == (1, 3, 1) and a.dtype == b.dtype == np.float64:   # one state: on Python floats,
            a0, a1, a2 = a.ravel().tolist()                                     # the same IEEE operations
            b0, b1, b2 = b.ravel().tolist()
            return np.array((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0)).reshape(1, 3, 1)
        a0, a1, a2 = a[..., 0, :], a[..., 1, :], a[..., 2, :]     # any leading shape (a family of batches)
        b0, b1, b2 = b[..., 0, :], b[..., 1, :], b[..., 2, :]
        first = a1 * b2 - a2 * b1                                   # (B, k): filled, not np.stack (its checks)
        out = np.empty(first.shape[:-1] + (3,) + first.shape[-1:], dtype=first.dtype)
        out[..., 0, :], out[..., 1, :], out[..., 2, :] = first, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        return out
    return ops.matmul(skew(ops, a), b)


def axis_rotation(ops: Ops, axis: np.ndarray, angle: Any) -> Any:
    """``Rot(axis, angle) = I + sin(angle) [a]x + (1 - cos(angle)) [a]x^2`` for a unit numeric ``axis``."""
    eye, k, k2 = axis_terms(ops, tuple(np.asarray(axis, dtype=float).reshape(3).tolist()))
    return eye + k * ops.sin(angle) + k2 * (1.0 - ops.cos(angle))


@lru_cache(maxsize=256)
def axis_terms(ops: Ops, axis: tuple[float, float, float]) -> tuple[Any, Any, Any]:
    """``(I, [a]x, [a]x^2)`` of an axis as constants of ``ops`` (numpy ones read-only: shared)."""
    a = np.asarray(axis)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    terms = (constant(ops, np.eye(3)), constant(ops, k), constant(ops, k @ k))
    if ops.name == "numpy":
        for term in terms:
            term.flags.writeable = False
    return terms


def quaternion_rotation(ops: Ops, w: Any, x: Any, y: Any, z: Any) -> Any:
    """Rotation matrix of the quaternion ``(w, x, y, z)`` divided by its norm (any non-zero quaternion)."""
    if ops.name == "numpy":
        if all(type(c) is np.ndarray and c.shape == (1, 1, 1) and c.dtype == np.float64 for c in (w, x, y, z)):
            w, x, y, z = (c.item() for c in (w, x, y, z))          # one state: the same operations on floats
            n2 = w * w + x * x + y * y + z * z
            R = np.array(((w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)),
                          (2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)),
                          (2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z)))
            return (R / n2).reshape(1, 3, 3)
        n2 = w * w + x * x + y * y + z * z
        w, x, y, z = np.broadcast_arrays(*(np.asarray(c)[:, 0, 0] for c in (w, x, y, z)))
        n2 = np.asarray(n2)[:, 0, 0]
        R = np.stack([np.stack([w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                      np.stack([2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)], -1),
                      np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z], -1)], -2)
        return R / np.broadcast_to(n2, w.shape)[:, None, None]
    n2 = w * w + x * x + y * y + z * z
    rows = [[w * w + x * x - y * y - z * z, (x * y - w * z) * 2.0, (x * z + w * y) * 2.0],
            [(x * y + w * z) * 2.0, w * w - x * x + y * y - z * z, (y * z - w * x) * 2.0],
            [(x * z - w * y) * 2.0, (y * z + w * x) * 2.0, w * w - x * x - y * y + z * z]]
    return ops.block(rows) * (1.0 / n2)


def quaternion_rate(q: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``q_dot = 1/2 q (x) (0, omega)`` for quaternions ``q (..., 4)`` and child-axes angular velocities
    ``omega (..., 3)`` [rad/s] (numpy)."""
    w, x, y, z = (q[..., i] for i in range(4))
    p, r, s = (omega[..., i] for i in range(3))
    return 0.5 * np.stack([-x * p - y * r - z * s, w * p + y * s - z * r, w * r + z * p - x * s,
                           w * s + x * r - y * p], axis=-1)


def block_diagonal(ops: Ops, a: Any, b: Any, rows_a: int, rows_b: int) -> Any:
    """``diag(a, b)`` of two square blocks of sizes ``rows_a``, ``rows_b``."""
    if ops.name == "numpy":                     # the same matrix filled into one allocation
        a, b = np.asarray(a), np.asarray(b)
        out = np.zeros(batch_shape(a, b) + (rows_a + rows_b,) * 2,
                       dtype=np.result_type(a, b))
        out[..., :rows_a, :rows_a] = a
        out[..., rows_a:, rows_a:] = b
        return out
    return ops.block([[a, ops.zeros(rows_a, rows_b)], [ops.zeros(rows_b, rows_a), b]])
