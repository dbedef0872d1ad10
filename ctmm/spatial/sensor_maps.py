"""The sensor maps of a spatial model (:mod:`ctmm.spatial.ports`), written once and complex-step safe.

:func:`sensor_values` evaluates resolved sensors at a batch of states ``(q, v)`` through one batched
evaluation of the body states of the one sweep's terms (:meth:`ctmm.spatial.body_forms.SpatialScene.terms`,
analytic in the state).  Real states give the sensors' values (:meth:`ctmm.spatial.ports.SpatialPorts.values`,
the loops' inner reads); complex-step states ``q0 (+) i h e_k``, ``v0 + i h e_k`` (step ``h = 1e-30``) give
``Im y / h``, the derivative to round-off with no subtraction and no step to choose (the rows of ``C`` of
:func:`ctmm.linearize`, :func:`ctmm.spatial.ports.sensor_jacobians`).  Each map is written so that both hold:

* joint coordinates and rates, quaternion components, velocities, beam station sensors: entries of ``q``,
  ``v`` and their weighted sums;
* angular velocities (world or body axes), point positions and velocities (of a beam: the deformed points):
  products and sums;
* x-y-z angles ``(atan2(-R12, R22), asin(R02), atan2(-R01, R00))`` and the rotation vector (through the unit
  quaternion of ``R``, the largest of its components formed first): ``atan2``, ``asin`` and the square roots
  are applied to the real part and their exact derivative multiplies the imaginary part (first-order dual
  arithmetic; the step's square, ``1e-60``, is far below round-off).

Asked for derivatives (``differentiable``), the maps refuse (:class:`~ctmm.errors.ModelError`) a point where
a sensor has none: x-y-z angles at gimbal lock (``|angle_y| = pi/2``), a rotation vector of length ``pi``
(where it flips to its opposite).  Their values there are still defined and given.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ..errors import ModelError
from ..ops import NUMPY
from .beam_ports import deformed_point

__all__ = ["sensor_values", "xyz_angles", "rotation_vector", "SINGULAR_MARGIN"]

SINGULAR_MARGIN = 1e-6
"""Smallest ``cos(angle_y)`` of x-y-z angles and ``cos(|phi| / 2)`` of a rotation vector accepted where
derivatives are asked for."""


def _atan2(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``atan2`` of the real parts plus its exact derivative on the imaginary parts (if any)."""
    yr, xr = np.real(y), np.real(x)
    angle = np.arctan2(yr, xr)
    if not (np.iscomplexobj(y) or np.iscomplexobj(x)):
        return angle
    return angle + 1j * (xr * np.imag(y) - yr * np.imag(x)) / (xr * xr + yr * yr)


def _asin(x: np.ndarray) -> np.ndarray:
    """``asin`` of the real part (clipped to [-1, 1]) plus its exact derivative on the imaginary part."""
    xr = np.clip(np.real(x), -1.0, 1.0)
    angle = np.arcsin(xr)
    if not np.iscomplexobj(x):
        return angle
    return angle + 1j * np.imag(x) / np.sqrt(1.0 - xr * xr)


def _root(x: np.ndarray) -> np.ndarray:
    """``sqrt`` of the real part (negative round-off clipped to 0) plus its exact derivative."""
    root = np.sqrt(np.maximum(np.real(x), 0.0))
    if not np.iscomplexobj(x):
        return root
    return root + 1j * np.imag(x) / (2.0 * root)


def xyz_angles(rotation: np.ndarray) -> np.ndarray:
    """The x-y-z angles ``(a_x, a_y, a_z)`` [rad] of ``R = Rx(a_x) Ry(a_y) Rz(a_z)``
    (:mod:`ctmm.spatial.ports`).

    Parameters
    ----------
    rotation : array_like, shape (..., 3, 3)
        Rotation matrices (complex step allowed: module docstring).

    Returns
    -------
    ndarray, shape (..., 3)
    """
    R = np.asarray(rotation)
    if not np.iscomplexobj(R):
        R = R.astype(float)
    return np.stack([_atan2(-R[..., 1, 2], R[..., 2, 2]), _asin(R[..., 0, 2]), _atan2(-R[..., 0, 1], R[..., 0, 0])],
                    axis=-1)


def _quaternion_branch(R: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Quaternion ``(w, vec)`` of rotations ``R (B, 3, 3)`` formed from component ``k`` (0: ``w``, 1..3: the
    vector part's ``k - 1``)."""
    if k == 0:
        w = 0.5 * _root(1.0 + R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2])
        vec = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
        return w, vec / (4.0 * w)[:, None]
    i = k - 1
    j, m = (i + 1) % 3, (i + 2) % 3
    largest = 0.5 * _root(1.0 + R[:, i, i] - R[:, j, j] - R[:, m, m])
    vec = np.zeros((R.shape[0], 3), dtype=R.dtype)
    vec[:, i] = largest
    vec[:, j] = (R[:, j, i] + R[:, i, j]) / (4.0 * largest)
    vec[:, m] = (R[:, m, i] + R[:, i, m]) / (4.0 * largest)
    return (R[:, m, j] - R[:, j, m]) / (4.0 * largest), vec


def _quaternion(R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit quaternion ``(w (B,), vec (B, 3))``, ``w >= 0``, of rotations ``R (B, 3, 3)``, the largest of the
    four components formed first (chosen on the real part: well conditioned everywhere)."""
    R0 = np.real(R)
    choice = np.argmax(np.stack([R0[:, 0, 0] + R0[:, 1, 1] + R0[:, 2, 2], R0[:, 0, 0], R0[:, 1, 1], R0[:, 2, 2]],
                                axis=1), axis=1)
    if np.all(choice == choice[0]):                  # one state, or a complex-step batch: one branch
        w, vec = _quaternion_branch(R, int(choice[0]))
    else:
        w = np.zeros(R.shape[0], dtype=R.dtype)
        vec = np.zeros((R.shape[0], 3), dtype=R.dtype)
        for k in np.unique(choice):
            rows = choice == k
            w[rows], vec[rows] = _quaternion_branch(R[rows], int(k))
    sign = np.where(np.real(w) < 0.0, -1.0, 1.0)
    return sign * w, sign[:, None] * vec


def _rotation_vectors(w: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """``phi = 2 atan2(|vec|, w) vec / |vec|`` (B, 3) of unit quaternions with ``w >= 0``; below
    ``|phi| = 2e-4`` rad the series of ``2 atan(s / w) / s`` in ``s^2`` (no division by a vanishing ``s``)."""
    s2 = np.sum(vec * vec, axis=1)
    small = np.real(s2) < 1e-8
    factor = None
    if np.any(small):
        with np.errstate(divide="ignore", invalid="ignore"):   # w = 0 (|phi| = pi) is never small
            x = s2 / (w * w)
            factor = (2.0 / w) * (1.0 - x / 3.0 + x * x / 5.0 - x ** 3 / 7.0 + x ** 4 / 9.0)
    if not np.all(small):
        s = _root(np.where(small, 1.0, s2))
        full = 2.0 * _atan2(s, w) / s
        factor = full if factor is None else np.where(small, factor, full)
    return vec * factor[:, None]


def rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """Rotation vector ``phi`` [rad] of a rotation matrix (``R = exp([phi]x)``, ``|phi| <= pi``), through the
    unit quaternion (the largest of its four components is formed first: well conditioned everywhere).

    Parameters
    ----------
    rotation : array_like, shape (3, 3) or (B, 3, 3)
        Rotation matrices (complex step allowed: module docstring).

    Returns
    -------
    ndarray, shape (3,) or (B, 3)
    """
    R = np.asarray(rotation)
    if not np.iscomplexobj(R):
        R = R.astype(float)
    single = R.ndim == 2
    phi = _rotation_vectors(*_quaternion(R[None] if single else R))
    return phi[0] if single else phi


def _refuse_singular(kind: str, R: np.ndarray, sensor: str, caller: str) -> None:
    """:class:`ModelError` if the x-y-z angles / rotation vector of ``R[0]`` have no derivative."""
    R0 = np.real(R[0])
    if kind == "angles" and not np.sqrt(max(1.0 - float(R0[0, 2]) ** 2, 0.0)) > SINGULAR_MARGIN:
        raise ModelError(f"{caller}: sensor {sensor!r} is at gimbal lock at the operating point (angle_y = "
                         f"{np.degrees(np.arcsin(np.clip(R0[0, 2], -1, 1))):.6g} deg): its x and z angles "
                         "have no derivative there; sense the rotation vector or the angular velocity instead")
    if kind == "rotation" and not float(_quaternion(R0[None])[0][0]) > SINGULAR_MARGIN:
        raise ModelError(f"{caller}: sensor {sensor!r} reads a rotation of pi rad at the operating point, where the "
                         "rotation vector flips to its opposite: it has no derivative there; sense the x-y-z angles "
                         "or the angular velocity instead")


def _rows(array: Any, batch: int) -> np.ndarray:
    """A body-state vector ``(3,)``, ``(B, 3)`` or ``(B, 3, 1)`` as ``(batch, 3)``."""
    return np.broadcast_to(np.asarray(array).reshape(-1, 3), (batch, 3))


def sensor_values(model: Any, scene: Any, sensors: Sequence[Any], q: np.ndarray, v: np.ndarray, t: float, *,
                  differentiable: str | None = None) -> np.ndarray:
    """Values ``(B, len(sensors))`` of resolved sensors at a batch of states (module docstring).

    Parameters
    ----------
    model : SpatialModel
    scene : SpatialScene
        The model's scene (:class:`ctmm.spatial.body_forms.SpatialScene`).
    sensors : sequence
        Resolved sensors (:meth:`ctmm.spatial.ports.SpatialPorts.resolve`).
    q, v : ndarray, shape (B, nq), (B, nv)
        States, real or complex step (no validation: for inner loops).
    t : float
        Time [s] (driven joints).
    differentiable : str, optional
        The caller's name: refuse (ModelError) an x-y-z angle sensor at gimbal lock or a rotation vector of
        length ``pi`` at the first state (where they have no derivative).

    Returns
    -------
    ndarray, shape (B, len(sensors))
        Real for real states, complex for complex ones (``Im / h``: the derivative along each row's step).
    """
    q, v = np.asarray(q), np.asarray(v)
    batch = q.shape[0]
    out = np.zeros((batch, len(sensors)), dtype=np.result_type(q, v, float))
    states = None
    cache: dict[tuple, np.ndarray] = {}
    for n, sensor in enumerate(sensors):
        kind = sensor.kind
        if kind == "q":
            out[:, n] = q[:, sensor.index]
            continue
        if kind == "v":
            out[:, n] = v[:, sensor.index]
            continue
        if kind in ("modal", "modal_v"):                 # beam station sensors: linear in eta or eta_dot
            layout = model.modal[sensor.index]
            out[:, n] = (q[:, layout.position] if kind == "modal" else v[:, layout.velocity]) @ np.asarray(
                sensor.weights, dtype=float)
            continue
        if states is None:
            states = scene.terms(NUMPY, q, v, t, kinematics_only=True)[2]
        state = states[sensor.index]
        R = np.broadcast_to(np.asarray(state.rotation), (batch, 3, 3))
        omega = _rows(state.omega, batch)
        if kind == "omega":
            out[:, n] = omega[:, sensor.component]
        elif kind == "omega_body":
            out[:, n] = np.einsum("bi,bi->b", R[:, :, sensor.component], omega)
        elif kind in ("angles", "rotation"):
            key = (kind, sensor.index)
            if key not in cache:
                if differentiable is not None:
                    _refuse_singular(kind, R, sensor.name, differentiable)
                cache[key] = xyz_angles(R) if kind == "angles" else rotation_vector(R)
            out[:, n] = cache[key][:, sensor.component]
        else:
            modal = model.modal[sensor.index]
            if modal is None:
                arm = R @ np.asarray(sensor.point, dtype=float)
                omega_arm = np.cross(omega, arm)
            else:                                        # a beam point moves with the deformation
                body = model.bodies[sensor.index]
                arm = np.einsum("bij,bj->bi", R, deformed_point(body, sensor.point, q[:, modal.position]))
                omega_arm = np.cross(omega, arm) + np.einsum(
                    "bij,bj->bi", R, deformed_point(body, sensor.point, v[:, modal.velocity], rate=True,
                                                    coordinates=q[:, modal.position]))
            if kind == "point":
                out[:, n] = _rows(state.origin, batch)[:, sensor.component] + arm[:, sensor.component]
            else:
                out[:, n] = _rows(state.velocity, batch)[:, sensor.component] + omega_arm[:, sensor.component]
    return out
