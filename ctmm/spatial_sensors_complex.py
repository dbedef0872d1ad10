"""Complex-step-safe values of the named sensors of a spatial model (:mod:`ctmm.spatial.ports`): exact rows of ``C``.

The output rows of :func:`ctmm.linearize` on a spatial model (``docs/spatial.md`` §9): the derivative
of each sensor's value with respect to the state ``x = [r ; v]`` of
:mod:`ctmm.spatial_linearization` (tangent coordinates ``r``, ``q = q0 (+) r``, and velocities ``v``)
at the operating point.  Taken by **complex step** (step ``1e-30``): the ``2 nv`` states
``q0 (+) i h e_k`` and ``v0 + i h e_k`` go through one batched evaluation of the body states of the
one sweep's terms (:meth:`ctmm.spatial.body_forms.SpatialScene.terms`, analytic in the state), and each
sensor map is written in complex-step-safe form, so that ``Im y / h`` is the derivative to round-off
(no subtraction, no step to choose):

* joint coordinates and rates, quaternion components, velocities: entries of ``q``, ``v``;
* angular velocities (world or body axes), point positions and velocities: products and sums;
* x-y-z angles ``(atan2(-R12, R22), asin(R02), atan2(-R01, R00))`` and the rotation vector (through the
  unit quaternion of ``R``): ``atan2`` and ``asin`` are applied to the real part and their exact
  derivative multiplies the imaginary part (first-order dual arithmetic; the step's square, ``1e-60``,
  is far below round-off).

Refused (:class:`~ctmm.errors.ModelError`) where a sensor is not differentiable at the operating point:
x-y-z angles at gimbal lock (``|angle_y| = pi/2``), a rotation vector of length ``pi`` (where it flips).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .errors import ModelError
from .ops import NUMPY

__all__ = ["complex_sensor_values", "SINGULAR_MARGIN"]

SINGULAR_MARGIN = 1e-6
"""Smallest ``cos(angle_y)`` of x-y-z angles and ``cos(|phi| / 2)`` of a rotation vector accepted."""


def _atan2(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``atan2`` of complex-step values: real ``atan2`` plus its exact derivative on the imaginary parts."""
    yr, xr = y.real, x.real
    return np.arctan2(yr, xr) + 1j * (xr * y.imag - yr * x.imag) / (xr * xr + yr * yr)


def _asin(x: np.ndarray) -> np.ndarray:
    xr = x.real
    return np.arcsin(xr) + 1j * x.imag / np.sqrt(1.0 - xr * xr)


def _xyz_angles(R: np.ndarray, sensor: str) -> np.ndarray:
    """``(B, 3)`` x-y-z angles of rotations ``R (B, 3, 3)`` (complex step), as :func:`ctmm.spatial.ports.xyz_angles`."""
    if not np.sqrt(max(1.0 - float(R[0, 0, 2].real) ** 2, 0.0)) > SINGULAR_MARGIN:
        raise ModelError(f"linearize: sensor {sensor!r} is at gimbal lock at the operating point (angle_y = "
                         f"{np.degrees(np.arcsin(np.clip(R[0, 0, 2].real, -1, 1))):.6g} deg): its x and z angles "
                         "have no derivative there; sense the rotation vector or the angular velocity instead")
    return np.stack([_atan2(-R[:, 1, 2], R[:, 2, 2]), _asin(R[:, 0, 2]), _atan2(-R[:, 0, 1], R[:, 0, 0])], axis=1)


def _rotation_vectors(R: np.ndarray, sensor: str) -> np.ndarray:
    """``(B, 3)`` rotation vectors of ``R (B, 3, 3)`` (complex step) through the unit quaternion, the branch
    chosen on the (common) real part as in :func:`ctmm.spatial.ports.rotation_vector`."""
    R0 = R[0].real
    trace = R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2]
    k = int(np.argmax([np.trace(R0), R0[0, 0], R0[1, 1], R0[2, 2]]))
    if k == 0:
        w = 0.5 * np.sqrt(1.0 + trace)
        vec = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
        vec = vec / (4.0 * w)[:, None]
    else:
        i = k - 1
        j, m = (i + 1) % 3, (i + 2) % 3
        parts = [None, None, None]
        parts[i] = 0.5 * np.sqrt(1.0 + R[:, i, i] - R[:, j, j] - R[:, m, m])
        w = (R[:, m, j] - R[:, j, m]) / (4.0 * parts[i])
        parts[j] = (R[:, j, i] + R[:, i, j]) / (4.0 * parts[i])
        parts[m] = (R[:, m, i] + R[:, i, m]) / (4.0 * parts[i])
        vec = np.stack(parts, axis=1)
    if w[0].real < 0.0:
        w, vec = -w, -vec
    if not w[0].real > SINGULAR_MARGIN:
        raise ModelError(f"linearize: sensor {sensor!r} reads a rotation of pi rad at the operating point, where the "
                         "rotation vector flips to its opposite: it has no derivative there; sense the x-y-z angles "
                         "or the angular velocity instead")
    s2 = np.sum(vec * vec, axis=1)
    if s2[0].real < 1e-8:                           # |phi| < 2e-4 rad: the series of 2 atan(s / w) / s in s^2
        x = s2 / (w * w)
        factor = (2.0 / w) * (1.0 - x / 3.0 + x * x / 5.0 - x ** 3 / 7.0 + x ** 4 / 9.0)
    else:
        s = np.sqrt(s2)
        factor = 2.0 * _atan2(s, w) / s
    return vec * factor[:, None]


def _values(model: Any, sensors: list, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
    """``(B, len(sensors))`` values of resolved sensors at a complex batch of states."""
    from .spatial.body_forms import SpatialScene

    batch = q.shape[0]
    out = np.zeros((batch, len(sensors)), dtype=complex)
    states = None
    cache: dict[tuple, np.ndarray] = {}
    for n, sensor in enumerate(sensors):
        if sensor.kind == "q":
            out[:, n] = q[:, sensor.index]
            continue
        if sensor.kind == "v":
            out[:, n] = v[:, sensor.index]
            continue
        if states is None:
            states = SpatialScene(model).terms(NUMPY, q, v, t)[2]
        state = states[sensor.index]
        R = np.broadcast_to(np.asarray(state.rotation), (batch, 3, 3))
        omega = np.broadcast_to(np.asarray(state.omega).reshape(-1, 3), (batch, 3))
        if sensor.kind == "omega":
            out[:, n] = omega[:, sensor.component]
        elif sensor.kind == "omega_body":
            out[:, n] = np.einsum("bi,bi->b", R[:, :, sensor.component], omega)
        elif sensor.kind in ("angles", "rotation"):
            key = (sensor.kind, sensor.index)
            if key not in cache:
                cache[key] = (_xyz_angles if sensor.kind == "angles" else _rotation_vectors)(R, sensor.name)
            out[:, n] = cache[key][:, sensor.component]
        else:
            arm = R @ np.asarray(sensor.point, dtype=float)
            if sensor.kind == "point":
                out[:, n] = np.broadcast_to(np.asarray(state.origin).reshape(-1, 3), (batch, 3))[:, sensor.component] \
                    + arm[:, sensor.component]
            else:
                velocity = np.broadcast_to(np.asarray(state.velocity).reshape(-1, 3), (batch, 3)) + np.cross(omega, arm)
                out[:, n] = velocity[:, sensor.component]
    return out


def complex_sensor_values(model: Any, names: Sequence[str], q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
    """Values ``(B, len(names))`` of the sensors ``names`` at a batch of complex-step states (module docstring).

    Parameters
    ----------
    model : SpatialModel
    names : sequence of str
        Sensor names of :class:`ctmm.spatial.ports.SpatialPorts`.
    q, v : ndarray, shape (B, nq), (B, nv)
        States with real parts equal (the operating point) and tiny imaginary parts (the complex step:
        ``q0 (+) i h e_k``, :func:`ctmm.spatial_linearization.retract`).
    t : float
        Time [s].

    Returns
    -------
    ndarray, shape (B, len(names)), complex
        ``Im / h`` is the derivative along each row's step.
    """
    from .spatial.ports import SpatialPorts

    sensors = SpatialPorts(model).resolve(list(names))
    return _values(model, sensors, np.asarray(q), np.asarray(v), float(t))
