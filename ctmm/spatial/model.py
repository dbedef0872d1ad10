"""Spatial multibody model: a validated, immutable tree of bodies on joints (issue 14).

:class:`SpatialModel` turns a list of element descriptions (:mod:`ctmm.spatial.elements`) into an
immutable model with the bodies in topological order (every parent before its children), one
inboard joint per body (a joint to the ground is a boundary: :class:`~ctmm.spatial.elements.Weld`
fixed, :class:`~ctmm.spatial.elements.Free` floating, :class:`~ctmm.spatial.elements.Elastic6`
elastic), and the coordinate layout.

State
-----
``q`` (``n_positions``) stacks each body's joint coordinates in body order, ``v`` (``n_velocities``)
its joint velocities (``docs/spatial.md``); ``nq != nv`` for spherical, free and elastic joints,
with ``q_dot = G(q) v`` (:meth:`SpatialModel.position_rates`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError, unknown_name
from .beam import SpatialBeam
from .elements import JOINT_TYPES, Load, SpatialBody
from .frames import quaternion_rate

__all__ = ["SpatialModel", "Layout"]

_FLOAT = np.dtype(float)


@dataclass(frozen=True)
class Layout:
    """Where one body's joint coordinates live: ``q[position]``, ``v[velocity]`` (slices)."""

    position: slice
    velocity: slice


def _quaternion_blocks(kind: str, position: slice) -> slice | None:
    if kind == "spherical":
        return position
    if kind in ("free", "elastic6"):
        return slice(position.start + 3, position.stop)
    return None


class SpatialModel:
    """Immutable spatial tree of rigid bodies on joints.

    Parameters
    ----------
    name : str
    elements : sequence
        :class:`SpatialBody`, joints (:data:`~ctmm.spatial.elements.JOINT_TYPES`, each naming its
        ``parent`` -- ``None`` for the ground -- and ``child``) and :class:`Load` elements.
    gravity : 3 numbers
        Gravitational acceleration in world axes [m/s^2].

    Raises
    ------
    ModelError
        Unknown or duplicate names, a body without or with several inboard joints, cycles, unknown points.
    """

    def __init__(self, name: str, elements: Sequence[object], *, gravity: Sequence[float] = (0.0, 0.0, -9.81)):
        self.name = validation.name("model", name)
        self.gravity = validation.vector("gravity", gravity, unit="m/s^2")   # world axes
        if not isinstance(elements, (list, tuple)):
            raise ModelError(f"{self.name}: elements must be a list of SpatialBody, SpatialBeam, joints and Load, "
                             f"got {elements!r:.80}")
        bodies: dict[str, SpatialBody] = {}
        joints: dict[str, object] = {}
        loads: list[Load] = []
        names: set[str] = set()
        for element in elements:
            if not (isinstance(element, (SpatialBody, SpatialBeam, Load) + JOINT_TYPES)
                    or hasattr(element, "spatial_terms")):             # ctmm.fem.SpatialSubsystem
                raise ModelError(f"{name}: elements must be SpatialBody, SpatialBeam, a joint ({', '.join(t.__name__ for t in JOINT_TYPES)}) "
                                 f"or Load, got {element!r}")
            if element.name in names:
                raise ModelError(f"{name}: duplicate element name {element.name!r}")
            names.add(element.name)
            if isinstance(element, (SpatialBody, SpatialBeam)) or hasattr(element, "spatial_terms"):
                bodies[element.name] = element
            elif isinstance(element, Load):
                loads.append(element)
            else:
                joints[element.name] = element
        if not bodies:
            raise ModelError(f"{name}: elements need at least one SpatialBody or SpatialBeam (a spatial model has a "
                             f"body), got {elements!r:.120}")
        inboard: dict[str, object] = {}
        for joint in joints.values():
            if joint.child not in bodies:
                raise unknown_name(f"{joint.name}: child body", joint.child, sorted(bodies))
            if joint.parent is not None:
                if joint.parent not in bodies:
                    raise unknown_name(f"{joint.name}: parent body", joint.parent, sorted(bodies))
                if joint.point not in bodies[joint.parent].points:
                    raise unknown_name(f"{joint.name}: point of {joint.parent}", joint.point,
                                       sorted(bodies[joint.parent].points))
            if joint.child in inboard:
                raise ModelError(f"{name}: body {joint.child!r} has two inboard joints ({inboard[joint.child].name!r} "
                                 f"and {joint.name!r}); a spatial model is a tree")
            inboard[joint.child] = joint
        missing = [b for b in bodies if b not in inboard]
        if missing:
            raise ModelError(f"{name}: bodies {missing} have no inboard joint; hang every body on a parent body or on "
                             "the ground (parent=None) through a joint (Weld, Free or Elastic6 for boundaries); "
                             f"elements: {elements!r:.120}")
        order: list[str] = []
        placed: set[str] = set()
        pending = list(bodies)
        while pending:
            ready = [b for b in pending if inboard[b].parent is None or inboard[b].parent in placed]
            if not ready:
                raise ModelError(f"{name}: bodies {pending} form a cycle (no path to the ground)")
            for b in ready:
                order.append(b)
                placed.add(b)
            pending = [b for b in pending if b not in placed]
        for load in loads:
            if load.body not in bodies:
                raise unknown_name(f"{load.name}: body", load.body, sorted(bodies))
            if load.point not in bodies[load.body].points:
                raise unknown_name(f"{load.name}: point of {load.body}", load.point, sorted(bodies[load.body].points))
        self._bodies = tuple(bodies[b] for b in order)
        self._joints = tuple(inboard[b] for b in order)
        self.loads = tuple(loads)
        index = {b: j for j, b in enumerate(order)}
        self.parent = tuple(-1 if joint.parent is None else index[joint.parent] for joint in self._joints)
        layouts, nq, nv = [], 0, 0
        for joint in self._joints:
            k_q = 0 if joint.driven else joint.coordinate_count
            k_v = 0 if joint.driven else joint.velocity_count
            layouts.append(Layout(slice(nq, nq + k_q), slice(nv, nv + k_v)))
            nq, nv = nq + k_q, nv + k_v
        self.layout = tuple(layouts)
        modal = []
        for body in self._bodies:                      # modal coordinates of beams follow all joint coordinates
            count = body.n_eta if isinstance(body, SpatialBeam) or hasattr(body, "spatial_terms") else 0
            modal.append(Layout(slice(nq, nq + count), slice(nv, nv + count)) if count else None)
            nq, nv = nq + count, nv + count
        self.modal = tuple(modal)
        """Per body: where a beam's modal coordinates ``eta`` live in ``q`` and their rates in ``v``
        (``None`` for rigid bodies); after every joint coordinate, in body order."""
        self.n_positions, self.n_velocities = nq, nv
        self.inputs = tuple(name for joint in self._joints for name in joint.inputs)
        blocks = [_quaternion_blocks(joint.kind, layout.position) for joint, layout in zip(self._joints, self.layout)]
        self._quaternion_columns = np.array([range(b.start, b.stop) for b in blocks if b is not None],
                                            dtype=int).reshape(-1, 4)       # (k, 4): check_state's fast path

    @property
    def bodies(self) -> tuple[SpatialBody | SpatialBeam, ...]:
        """Bodies in topological order."""
        return self._bodies

    @property
    def joints(self) -> tuple[object, ...]:
        """Inboard joint of each body (same order)."""
        return self._joints

    @property
    def n_bodies(self) -> int:
        """Number of bodies."""
        return len(self._bodies)

    def body_index(self, body: str) -> int:
        """Index of a body by name."""
        for j, b in enumerate(self._bodies):
            if b.name == body:
                return j
        raise unknown_name("body", body, [b.name for b in self._bodies])

    @property
    def coordinates(self) -> tuple[str, ...]:
        """Names of the entries of ``q``."""
        names = []
        for joint in self._joints:
            if joint.driven:
                continue
            names += [f"{joint.name}.{c}" for c in _coordinate_names(joint.kind, joint.coordinate_count)]
        return tuple(names) + self._modal_names("")

    @property
    def velocities(self) -> tuple[str, ...]:
        """Names of the entries of ``v`` (rates of 1-/2-DOF joints, child-axes components otherwise)."""
        names = []
        for joint in self._joints:
            if joint.driven:
                continue
            if joint.kind == "spherical":
                parts = ("wx", "wy", "wz")
            elif joint.kind in ("free", "elastic6"):
                parts = ("vx", "vy", "vz", "wx", "wy", "wz")
            else:
                parts = tuple(f"{c}_rate" for c in _coordinate_names(joint.kind, joint.coordinate_count))
            names += [f"{joint.name}.{c}" for c in parts]
        return tuple(names) + self._modal_names("_rate")

    def _modal_names(self, suffix: str) -> tuple[str, ...]:
        return tuple(f"{body.name}.{c}{suffix}" for body, layout in zip(self._bodies, self.modal) if layout is not None
                     for c in body.coordinate_suffixes)

    def neutral(self) -> np.ndarray:
        """The zero configuration ``q`` (zero angles and positions, identity quaternions)."""
        q = np.zeros(self.n_positions)
        for joint, layout in zip(self._joints, self.layout):
            block = _quaternion_blocks(joint.kind, layout.position)
            if block is not None and not joint.driven:
                q[block.start] = 1.0
        return q

    def position_rates(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``q_dot = G(q) v`` (batched over leading axes): rates of angles and displacements are the
        velocities; a quaternion's rate is ``1/2 q (x) (0, omega)``; a free joint's position rate is
        ``R_rel v_o`` (joint-frame velocity of the child origin)."""
        q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
        out = np.zeros(np.broadcast_shapes(q.shape[:-1], v.shape[:-1]) + (self.n_positions,))
        for joint, layout in zip(self._joints, self.layout):
            qj, vj = q[..., layout.position], v[..., layout.velocity]
            if joint.kind == "spherical":
                out[..., layout.position] = quaternion_rate(qj, vj)
            elif joint.kind in ("free", "elastic6"):
                quat = qj[..., 3:]
                out[..., layout.position.start:layout.position.start + 3] = np.einsum(
                    "...ij,...j->...i", rotation_matrix(quat), vj[..., :3])
                out[..., layout.position.start + 3:layout.position.stop] = quaternion_rate(quat, vj[..., 3:])
            else:
                out[..., layout.position] = vj
        for layout in self.modal:
            if layout is not None:
                out[..., layout.position] = v[..., layout.velocity]
        return out

    def normalized(self, q: np.ndarray) -> np.ndarray:
        """``q`` with every quaternion scaled to unit norm (a copy)."""
        q = np.array(q, dtype=float)
        for joint, layout in zip(self._joints, self.layout):
            block = _quaternion_blocks(joint.kind, layout.position)
            if block is not None and not joint.driven:
                q[..., block] /= np.linalg.norm(q[..., block], axis=-1, keepdims=True)
        return q

    def check_state(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(q, v)`` as float arrays ``(B, nq)``, ``(B, nv)``; raises :class:`ModelError` on wrong sizes,
        non-finite values or zero quaternions.

        The states of inner loops (float64 ndarrays of the right sizes, finite, quaternions clearly non-zero)
        pass a cheap test and come back as they are (a leading axis added to a 1-D state); anything else gets
        the full check, which converts or refuses with the clear error."""
        if type(q) is np.ndarray and type(v) is np.ndarray and q.dtype is _FLOAT and v.dtype is _FLOAT:
            q_rows = q[None] if q.ndim == 1 else q
            v_rows = v[None] if v.ndim == 1 else v
            if (q_rows.ndim == 2 and v_rows.ndim == 2 and q_rows.shape[1] == self.n_positions
                    and v_rows.shape[1] == self.n_velocities
                    and (len(q_rows) == len(v_rows) or len(q_rows) == 1 or len(v_rows) == 1)
                    and math.isfinite(q_rows.sum() + v_rows.sum())):
                if not len(self._quaternion_columns) or not len(q_rows):
                    return q_rows, v_rows
                blocks = q_rows[:, self._quaternion_columns]            # (B, k, 4)
                if (blocks * blocks).sum(axis=2).min() >= 1e-17:        # every norm >= 3e-9 > 1e-9
                    return q_rows, v_rows
        return self._checked_state(q, v)

    def _checked_state(self, q: Any, v: Any) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`check_state`'s full check: conversion and every refusal with its message."""
        given_q, given_v = q, v
        q, v = (_numbers(self.name, label, value) for label, value in (("q", q), ("v", v)))
        q = q[None] if q.ndim == 1 else q
        v = v[None] if v.ndim == 1 else v
        if q.ndim != 2 or q.shape[1] != self.n_positions:
            raise ModelError(f"{self.name}: q must have {self.n_positions} entries {self.coordinates} (or be (B, "
                             f"{self.n_positions})), got shape {q.shape}: {given_q!r:.80}")
        if v.ndim != 2 or v.shape[1] != self.n_velocities:
            raise ModelError(f"{self.name}: v must have {self.n_velocities} entries {self.velocities} (or be (B, "
                             f"{self.n_velocities})), got shape {v.shape}: {given_v!r:.80}")
        if q.shape[0] != v.shape[0] and 1 not in (q.shape[0], v.shape[0]):
            raise ModelError(f"{self.name}: q and v must hold as many states (rows) or one of them one, got "
                             f"{q.shape[0]} and {v.shape[0]}")
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            raise ModelError(f"{self.name}: q and v must be finite, got q={q.tolist()}, v={v.tolist()}")
        for joint, layout in zip(self._joints, self.layout):
            block = _quaternion_blocks(joint.kind, layout.position)
            if block is not None and np.any(np.linalg.norm(q[:, block], axis=1) < 1e-9):
                raise ModelError(f"{self.name}: the quaternion of joint {joint.name!r} is zero; a rotation needs a "
                                 "non-zero quaternion (w, x, y, z), e.g. (1, 0, 0, 0)")
        return q, v

    def __repr__(self) -> str:
        return (f"SpatialModel({self.name!r}, {self.n_bodies} bodies, nq={self.n_positions}, "
                f"nv={self.n_velocities})")


def _coordinate_names(kind: str, count: int) -> tuple[str, ...]:
    if kind == "revolute":
        return ("angle",)
    if kind == "prismatic":
        return ("position",)
    if kind == "universal":
        return ("angle1", "angle2")
    if kind == "spherical":
        return ("qw", "qx", "qy", "qz")
    if kind in ("free", "elastic6"):
        return ("x", "y", "z", "qw", "qx", "qy", "qz")
    return ()


def rotation_matrix(quaternion: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of quaternions ``(..., 4)`` (scalar first, normalised here)."""
    quaternion = np.asarray(quaternion, dtype=float)
    w, x, y, z = np.moveaxis(quaternion / np.linalg.norm(quaternion, axis=-1, keepdims=True), -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def input_values(model: SpatialModel, inputs: Mapping[str, object] | None, t: float, batch: int) -> dict:
    """Actuator inputs at time ``t`` as ``{name: (B, k) array}`` (missing inputs are zero)."""
    inputs = dict(inputs or {})
    unknown = [name for name in inputs if name not in model.inputs]
    if unknown:
        raise unknown_name("spatial input", unknown[0], list(model.inputs))
    out = {}
    for joint in model.joints:
        for name in joint.inputs:
            k = joint.velocity_count
            value = inputs.get(name, np.zeros(k))
            if callable(value):
                value = value(t)
            raw = np.asarray(value)                # a string, boolean or complex number is not a real input
            array = np.asarray(value, dtype=float) if raw.dtype.kind in "iuf" else np.array(np.nan)
            if array.ndim == 0:
                array = np.full(k, float(array)) if k == 1 else array
            if array.shape[-1:] != (k,) or array.ndim > 2 or (array.ndim == 2 and array.shape[0] not in (1, batch)) \
                    or not np.all(np.isfinite(array)):
                raise ModelError(f"input {name!r} must be {k} finite number(s) (or (B, {k})) at t = {t} s, got "
                                 f"{raw.tolist()!r}")
            out[name] = np.broadcast_to(array, (batch, k))
    return out


def _numbers(model_name: str, label: str, value: Any) -> np.ndarray:
    """``value`` as a float array, or a :class:`ModelError` naming ``label`` and the value (strings, bools,
    mappings and other objects are not numbers)."""
    if isinstance(value, (str, bytes, bool, Mapping)) or value is None:
        raise ModelError(f"{model_name}: {label} must be an array of numbers, got {value!r:.80}")
    if np.iscomplexobj(value) and np.any(np.imag(value) != 0):      # a float conversion would drop it silently
        raise ModelError(f"{model_name}: {label} must be real numbers (a spatial model's states), got {value!r:.80}")
    try:
        array = np.asarray(np.real(value), dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{model_name}: {label} must be an array of numbers, got {value!r:.80}") from None
    return array
