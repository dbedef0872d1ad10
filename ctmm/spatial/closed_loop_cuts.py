"""Cut joints of spatial kinematic loops: :class:`SpatialCutJoint` (spherical, revolute, universal, prismatic) and
the geometry of their constraint rows (:class:`CutFrame`), used by :mod:`ctmm.spatial.closed_loops` (the mechanism
and the derivation are in its docstring and ``docs/closed_loops.md`` section 8)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from ..nonlinear_laws import Law
from ..signals import as_signal
from .elements import parent_point
from .lie import left_jacobian, quaternion_exponential, quaternion_logarithm
from .ports import SpatialInputs

__all__ = ["SpatialCutJoint", "CUT_KINDS", "LAW_KINDS", "ROTATION_LAW_LIMIT", "CutFrame", "CutActuatedInputs",
           "cut_frame", "cut_coordinate", "cross", "perpendicular", "relative_rotation", "spherical_law_moment"]

CUT_KINDS = ("spherical", "revolute", "universal", "prismatic")
"""Kinds of :class:`SpatialCutJoint`."""

LAW_KINDS = ("revolute", "prismatic")
"""Kinds of :class:`SpatialCutJoint` with a free coordinate that a law or an actuation may load."""

ROTATION_LAW_LIMIT = 3.0
"""Largest angle ``|phi|`` [rad] of a spherical cut's relative rotation vector its law is evaluated at (the
logarithm's chart ends at ``pi``)."""


@dataclass(frozen=True, kw_only=True)
class SpatialCutJoint:
    """A smooth joint closing a loop of a spatial tree.

    Parameters
    ----------
    name : str
        Joint name (distinct from the tree's element names).
    parent : str or None
        Parent body name, or ``None`` for the ground.
    child : str
        Child body name.
    point : str or (3,) array, optional
        The parent's point name (default ``"origin"``); at the ground a location in world axes [m] (default the
        origin).
    child_point : str
        The child's point name (default ``"origin"``).
    kind : str
        ``"spherical"`` (ball: the points coincide, 3 rows), ``"revolute"`` (also ``axis`` parallel to
        ``parent_axis``, 5 rows), ``"universal"`` (Hooke: also ``axis`` perpendicular to ``parent_axis``, 4 rows) or
        ``"prismatic"`` (slider: the child point on the line through the parent point along ``parent_axis``,
        ``axis`` parallel to ``parent_axis`` and ``normal`` parallel to ``parent_normal``, 5 rows).
    axis : (3,) array
        Revolute: the hinge axis in child body axes; universal: the child's cross axis in child body axes;
        prismatic: the slide axis in child body axes (normalised).
    parent_axis : (3,) array, optional
        Revolute, prismatic: the hinge or slide axis in parent body axes (world axes at the ground), default
        ``axis``; universal: the parent's cross axis there (required; perpendicular to ``axis`` in the assembled
        loop).
    normal, parent_normal : (3,) array, optional
        Prismatic: a child vector perpendicular to ``axis`` (child body axes) and the parent vector
        perpendicular to ``parent_axis`` (parent body axes, world at the ground) it stays parallel to (fixing the
        roll about the slide axis); revolute: the pair whose angle is the joint angle of ``law`` (zero when they are
        parallel); default for each a unit vector perpendicular to its axis, ``axis x e_k`` with ``e_k`` the
        coordinate axis least aligned with it (the same vector for both when the axes are equal).  Not used by
        the other kinds.
    law : ctmm.nonlinear_laws.Law, optional
        Revolute and prismatic: restoring moment [N m] or force [N] ``law(s - rest, s')`` of the joint
        coordinate ``s`` across the cut (revolute: the angle [rad] from ``parent_normal`` to ``normal`` about the
        axis; prismatic: the slide ``d . a`` [m] of the child point from the parent point along the parent axis
        ``a``); ``docs/closed_loops.md`` §8.1a.  Spherical: the same law on each component of the relative rotation
        vector ``phi = log(R_p^T R_c exp(rest)^T)`` [rad] (parent body axes) and its rate ``phi'``, the three
        loads ``f`` acting as the moment ``-R_p J(phi)^-T f`` on the child (``J`` the left Jacobian of ``SO(3)``: the
        exact work-conjugate of ``phi``, so the law's potential is the energy stored; ``|phi| <= 3`` rad);
        ``docs/closed_loops.md`` §8.1b.  ``None``: a smooth cut.
    rest : float or (3,) array
        The coordinate [rad or m] at which the law's deflection is zero; spherical: the relative rotation vector
        [rad] (parent body axes) at rest, default 0 (child axes parallel to parent axes).
    actuation : float or callable, optional
        Revolute and prismatic only: an actuator torque [N m] about the axis / force [N] along the slide ``u(t)``
        on the child (``-u`` on the parent).
    position, rate, acceleration : float or callable, optional
        Revolute and prismatic only, all three or none: a driven cut, its coordinate prescribed, ``s = position(t)``
        [rad or m], with its first and second time derivatives (checked for consistency by finite differences, as a
        driven tree joint's): one more row, whose unknown is the drive's load along the coordinate; no law or
        actuation then.
    """

    name: str
    parent: str | None
    child: str
    point: Any = None
    child_point: str = "origin"
    kind: str = "spherical"
    axis: Any = (0.0, 0.0, 1.0)
    parent_axis: Any = None
    normal: Any = None
    parent_normal: Any = None
    law: Any = None
    rest: Any = 0.0
    actuation: Any = None
    position: Any = None
    rate: Any = None
    acceleration: Any = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", validation.name("cut joint", self.name))
        validation.option(f"cut joint {self.name!r}: kind", self.kind, CUT_KINDS)
        if self.parent is not None:
            validation.name(f"cut joint {self.name!r}: parent", self.parent)
        object.__setattr__(self, "point", parent_point(f"cut joint {self.name!r}", self.parent, self.point))
        validation.name(f"cut joint {self.name!r}: child", self.child)
        if self.parent == self.child:
            raise ModelError(f"cut joint {self.name!r}: parent and child are both {self.child!r}; a cut joint "
                             "connects two different bodies (or a body and the ground, parent=None)")
        if not isinstance(self.child_point, str):
            raise ModelError(f"cut joint {self.name!r}: child_point must be the name of a point of {self.child!r}, "
                             f"got {self.child_point!r}")
        if self.kind == "universal" and self.parent_axis is None:
            raise ModelError(f"cut joint {self.name!r}: a universal cut needs parent_axis (the parent's cross axis, "
                             "a 3-vector perpendicular to axis in the assembled loop), got None")
        axis = validation.unit_vector(f"cut joint {self.name!r}: axis", self.axis)
        object.__setattr__(self, "axis", axis)
        object.__setattr__(self, "parent_axis", axis.copy() if self.parent_axis is None else
                           validation.unit_vector(f"cut joint {self.name!r}: parent_axis", self.parent_axis))
        for label, owner in (("normal", "axis"), ("parent_normal", "parent_axis")):
            value = getattr(self, label)
            if self.kind not in LAW_KINDS:
                if value is not None:
                    raise ModelError(f"cut joint {self.name!r}: {label} is used only by prismatic and revolute cuts "
                                     f"(kind {self.kind!r}), got {value!r}")
                continue
            direction = getattr(self, owner)
            vector = (perpendicular(direction)[0] if value is None else
                      validation.unit_vector(f"cut joint {self.name!r}: {label}", value))
            if abs(float(vector @ direction)) > 1e-9:
                raise ModelError(f"cut joint {self.name!r}: {label} must be perpendicular to {owner} "
                                 f"{direction.tolist()}, got {value!r}")
            object.__setattr__(self, label, vector)
        self._check_law()

    def _check_law(self) -> None:
        """Validate ``law``, ``rest`` and ``actuation`` (revolute and prismatic cuts only)."""
        spherical = self.kind == "spherical"
        if (self.law is not None and self.kind not in LAW_KINDS + ("spherical",)) or \
                (self.actuation is not None and self.kind not in LAW_KINDS):
            raise ModelError(f"cut joint {self.name!r}: law and actuation act on the coordinate of a revolute or "
                             f"prismatic cut (a law also on a spherical cut's relative rotation); kind {self.kind!r} "
                             f"takes neither (got law={self.law!r}, actuation={self.actuation!r})")
        if self.law is not None and not isinstance(self.law, Law):
            raise ModelError(f"cut joint {self.name!r}: law must be None or a ctmm.nonlinear_laws.Law (e.g. "
                             f"LinearLaw(stiffness, damping)), got {self.law!r}")
        if spherical:
            rest = np.zeros(3) if np.ndim(self.rest) == 0 and self.rest == 0.0 else \
                validation.vector(f"cut joint {self.name!r}: rest (the relative rotation vector at rest)", self.rest,
                                  unit="rad")
            if float(np.linalg.norm(rest)) >= np.pi:
                raise ModelError(f"cut joint {self.name!r}: rest must be a rotation vector shorter than pi rad, got "
                                 f"{rest.tolist()}")
            object.__setattr__(self, "rest", rest)
        else:
            object.__setattr__(self, "rest", validation.finite(f"cut joint {self.name!r}: rest", self.rest))
        if self.actuation is not None:
            object.__setattr__(self, "actuation", as_signal(f"cut joint {self.name!r}: actuation", self.actuation))
        given = [getattr(self, label) is not None for label in ("position", "rate", "acceleration")]
        if not any(given):
            return
        if self.kind not in LAW_KINDS or not all(given) or self.has_law:
            raise ModelError(f"cut joint {self.name!r}: a driven cut is revolute or prismatic (kind {self.kind!r}) "
                             "with position, rate and acceleration all given and no law or actuation; got position="
                             f"{self.position!r}, rate={self.rate!r}, acceleration={self.acceleration!r}, law="
                             f"{self.law!r}, actuation={self.actuation!r}")
        from .elements import Revolute                   # the driven joints' derivative check
        drive = Revolute(name=self.name, parent=None, child=self.child, position=self.position, rate=self.rate,
                         acceleration=self.acceleration)
        for label in ("position", "rate", "acceleration"):
            object.__setattr__(self, label, getattr(drive, label)[0])

    @property
    def driven(self) -> bool:
        """Whether the coordinate is prescribed (:attr:`position`)."""
        return self.position is not None

    @property
    def has_law(self) -> bool:
        """Whether the cut carries a law or an actuation (a load along its free coordinate)."""
        return self.law is not None or self.actuation is not None

    def load(self, coordinate: float, rate: float, t: float) -> float:
        """Generalised load on the child along the cut's coordinate, ``actuation(t) - law(s - rest, s')`` [N m or
        N] of the coordinate ``s`` [rad or m], its rate and the time [s]."""
        value = 0.0 if self.actuation is None else float(self.actuation(t))
        if self.law is not None:
            value -= float(self.law.force(coordinate - self.rest, rate))
        return value

    def potential(self, coordinate: Any) -> float:
        """Energy stored in the law at the coordinate [J] (0 without one); spherical: at the relative rotation
        vector ``phi`` [rad] (:func:`relative_rotation`, the rest already taken out), the sum over its components."""
        if self.law is None:
            return 0.0
        if self.kind == "spherical":
            return float(sum(self.law.potential(float(p)) for p in np.asarray(coordinate, float)))
        return float(self.law.potential(coordinate - self.rest))

    @property
    def n_rows(self) -> int:
        """Constraint rows: 3 (spherical), 4 (universal) or 5 (revolute, prismatic); a driven cut one more."""
        return {"spherical": 3, "universal": 4, "revolute": 5, "prismatic": 5}[self.kind] + int(self.driven)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` over the last axis (3) with broadcasting (``np.cross`` without its axis handling: it is called
    many times per step on tiny arrays)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack(np.broadcast_arrays(a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=-1)


def perpendicular(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing ``axis`` to a right-handed orthonormal triad."""
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    first = cross(axis, helper)
    first /= np.linalg.norm(first)
    return first, cross(axis, first)


def cut_coordinate(cut: SpatialCutJoint, rotation_p: np.ndarray | None, rotation_c: np.ndarray, separation: np.ndarray,
                   relative_velocity: np.ndarray, omega_p: np.ndarray, omega_c: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The coordinate ``s`` of a revolute or prismatic cut, its rate and its world direction ``a`` (the load
    ``f`` along it is ``f a`` on the child: a moment for a revolute cut, a force at the child point for a prismatic
    one).  Revolute: ``a = R_c axis``, ``s = atan2((n_p x n_c) . a, n_p . n_c)`` with ``n_c = R_c normal``,
    ``n_p = R_p parent_normal``, ``s' = (omega_c - omega_p) . a``; prismatic: ``a = R_p parent_axis``, ``s = d . a``,
    ``s' = (v_Pc - v_Pp) . a + d . (omega_p x a)`` (``rotation_p`` None at the ground; world vectors, batched over
    leading axes: ``(..., 3)``, rotations ``(..., 3, 3)``; ``s`` and ``s'`` ``(...)``)."""
    def parent_fixed(vector: np.ndarray) -> np.ndarray:
        return vector if rotation_p is None else rotation_p @ vector

    if cut.kind == "revolute":
        a, n_c, n_p = rotation_c @ cut.axis, rotation_c @ cut.normal, parent_fixed(cut.parent_normal)
        angle = np.arctan2(np.sum(cross(n_p, n_c) * a, axis=-1), np.sum(n_p * n_c, axis=-1))
        return angle, np.sum((omega_c - omega_p) * a, axis=-1), a
    a = parent_fixed(cut.parent_axis)
    return (np.sum(separation * a, axis=-1),
            np.sum(relative_velocity * a + separation * cross(omega_p, a), axis=-1), a)


@dataclass(frozen=True)
class CutFrame:
    """The geometry of a cut's constraint rows (:mod:`ctmm.spatial.closed_loops` docstring).

    Attributes
    ----------
    basis : tuple of (3,) arrays or None
        Prismatic: the parent-fixed unit vectors ``p_j`` (parent body axes, world at the ground) of the point rows
        ``d . p_j``; ``None``: the point rows are the 3 world components of ``d``.
    pairs : tuple of ((3,), (3,)) arrays
        The ``(u_i, b_i)`` of the alignment rows ``u_i . b_i`` [rad]: ``u_i`` child-fixed (child body axes),
        ``b_i`` parent-fixed.
    """

    basis: tuple[np.ndarray, ...] | None
    pairs: tuple[tuple[np.ndarray, np.ndarray], ...]


def cut_frame(cut: SpatialCutJoint) -> CutFrame:
    """The :class:`CutFrame` of a cut: revolute ``(u, b_1)``, ``(u, b_2)`` with ``b_1, b_2`` perpendicular to the
    parent axis; universal ``(u, parent_axis)``; prismatic the point basis ``b_1, b_2`` and the revolute pairs plus
    ``(normal, parent_axis x parent_normal)``; spherical nothing."""
    across = perpendicular(cut.parent_axis)
    if cut.kind == "revolute":
        return CutFrame(None, tuple((cut.axis, b) for b in across))
    if cut.kind == "universal":
        return CutFrame(None, ((cut.axis, cut.parent_axis),))
    if cut.kind == "prismatic":
        return CutFrame(across, tuple((cut.axis, b) for b in across)
                      + ((cut.normal, cross(cut.parent_axis, cut.parent_normal)),))
    return CutFrame(None, ())


@dataclass(frozen=True)
class CutActuatedInputs(SpatialInputs):
    """The tree's actuator values plus loads along the coordinates of revolute and prismatic cuts.

    Attributes
    ----------
    cut_actuation : dict of str to float
        By cut name: a load ``u`` [N m or N] along the cut's coordinate, added to its own ``actuation`` (``u a`` on the
        child with ``a`` the world direction of :func:`cut_coordinate` at the current state, the opposite on the
        parent): the ``"<cut>.torque"`` / ``"<cut>.force"`` ports (:mod:`ctmm.spatial.closed_loop_ports`).
    """

    cut_actuation: Mapping[str, float] = field(default_factory=dict)


def _quaternion_of(R: np.ndarray) -> np.ndarray:
    """Unit quaternion ``[w, x, y, z]`` of a rotation matrix (the largest of the four squares first)."""
    trace = float(np.trace(R))
    squares = np.array([1.0 + trace, 1.0 + 2.0 * R[0, 0] - trace, 1.0 + 2.0 * R[1, 1] - trace,
                        1.0 + 2.0 * R[2, 2] - trace])
    k = int(np.argmax(squares))
    big = 0.5 * np.sqrt(max(squares[k], 0.0))
    quarter = 0.25 / big
    if k == 0:
        quaternion = [big, (R[2, 1] - R[1, 2]) * quarter, (R[0, 2] - R[2, 0]) * quarter, (R[1, 0] - R[0, 1]) * quarter]
    elif k == 1:
        quaternion = [(R[2, 1] - R[1, 2]) * quarter, big, (R[0, 1] + R[1, 0]) * quarter, (R[0, 2] + R[2, 0]) * quarter]
    elif k == 2:
        quaternion = [(R[0, 2] - R[2, 0]) * quarter, (R[0, 1] + R[1, 0]) * quarter, big, (R[1, 2] + R[2, 1]) * quarter]
    else:
        quaternion = [(R[1, 0] - R[0, 1]) * quarter, (R[0, 2] + R[2, 0]) * quarter, (R[1, 2] + R[2, 1]) * quarter, big]
    return np.asarray(quaternion)


def relative_rotation(cut: SpatialCutJoint, rotation_p: np.ndarray | None, rotation_c: np.ndarray,
                      omega_p: np.ndarray, omega_c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A spherical cut's relative rotation vector ``phi = log(R_p^T R_c exp(rest)^T)`` [rad], its rate
    ``phi' = J(phi)^-1 R_p^T (omega_c - omega_p)`` [rad/s] (parent body axes; ``rotation_p`` None at the ground) and
    the left Jacobian ``J(phi)`` of ``SO(3)`` (``d/dt exp(phi) exp(phi)^T = [J(phi) phi']x``)."""
    parent = np.eye(3) if rotation_p is None else rotation_p
    rest = quaternion_exponential(np.asarray(cut.rest, float))
    w, x, y, z = rest
    rest_matrix = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    phi = quaternion_logarithm(_quaternion_of(parent.T @ rotation_c @ rest_matrix.T))
    jacobian = left_jacobian(phi)
    return phi, np.linalg.solve(jacobian, parent.T @ (omega_c - omega_p)), jacobian


def spherical_law_moment(cut: SpatialCutJoint, rotation_p: np.ndarray | None, rotation_c: np.ndarray,
                         omega_p: np.ndarray, omega_c: np.ndarray, t: float) -> np.ndarray:
    """The moment [N m] (world axes) of a spherical cut's law on its child, ``-R_p J(phi)^-T f`` with
    ``f_i = law(phi_i, phi'_i)`` (:func:`relative_rotation`); the parent takes its opposite.

    Raises
    ------
    SimulationError
        ``|phi|`` above :data:`ROTATION_LAW_LIMIT` (the time and the cut named).
    """
    phi, rate, jacobian = relative_rotation(cut, rotation_p, rotation_c, omega_p, omega_c)
    angle = float(np.linalg.norm(phi))
    if not angle <= ROTATION_LAW_LIMIT:
        raise SimulationError(f"cut joint {cut.name!r}: the relative rotation across the spherical cut is {angle:.4g} "
                              f"rad at t = {t} s, beyond the {ROTATION_LAW_LIMIT:g} rad its law is defined for",
                              time=t, element=cut.name)
    loads = np.array([float(cut.law.force(float(p), float(r))) for p, r in zip(phi, rate)])
    parent = np.eye(3) if rotation_p is None else rotation_p
    return -parent @ np.linalg.solve(jacobian.T, loads)
