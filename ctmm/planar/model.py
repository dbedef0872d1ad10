"""Planar multibody model: topology (chains and trees), validation and coordinates.

:class:`PlanarModel` turns a list of element descriptions (:mod:`ctmm.planar.elements`)
into an immutable model with the bodies in topological order (every parent before its
children) and plain numpy arrays of all parameters, used by the sweeps
(:mod:`ctmm.planar.sweep`), the integrators and the independent reference
(:mod:`ctmm.reference.planar_lagrange`).

Generalised coordinates (named ``"body.theta"``, ``"body.x"``, ``"body.y"``)
--------------------------------------------------------------------------
* every body behind a non-driven hinge: its **absolute** angle ``theta`` [rad];
* a body on a :class:`~ctmm.planar.elements.FreeBase`: ``x, y`` of its inboard end [m] and
  its angle;
* a body behind a :class:`~ctmm.planar.elements.DrivenHinge` (or welded to the ground):
  no coordinate; its angle is ``theta_parent + angle(t)``;
* a flexible body (:class:`~ctmm.flexible.ModalBeam`) adds its modal coordinates
  ``"beam.q1"``, ... (and ``"beam.u1"``, ... for axial modes) after its angle.  Angles of
  children hanging at a beam end are measured from the end's cross-section
  (``theta_beam + phi'(x_end) . q``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .. import validation
from ..errors import ModelError, unknown_name
from ..signals import Constant
from .elements import (DrivenHinge, Fixed, Free, FreeBase, HINGE_TYPES, Pinned, RigidBody, Hinge, NonlinearHinge,
                       SmoothHinge, translational_law)
from .hinge_laws import law_potential
from .deformable import DeformableBody, DeformableFamily, DeformableSystem
from .signals import signal_values


def is_body(element) -> bool:
    """True for rigid bodies and bodies with internal coordinates (e.g. modal beams)."""
    return isinstance(element, (RigidBody, DeformableBody))


def _end_points(body) -> dict:
    return body.end_points if hasattr(body, "end_points") else body.outboard


REVOLUTE, DRIVEN, FREE, BUSHING = 0, 1, 2, 3
"""Joint kinds in :attr:`PlanarModel.joint_kind` (BUSHING: hinge with translational springs)."""


@dataclass(frozen=True)
class _Joint:
    name: str
    kind: int
    parent: str | None          # parent body name, None = ground
    end: str | None             # parent end name
    ground: Fixed | None        # ground element when parent is None
    hinge: object               # the hinge / boundary element


class PlanarModel:
    """Immutable planar chain or tree of rigid bodies connected by hinges.

    Parameters
    ----------
    name : str
        Model name.
    elements : sequence
        Bodies, hinges (with ``parent`` and ``child`` set) and boundaries
        (:class:`Fixed` ground points, :class:`Pinned`, :class:`FreeBase`, :class:`Free`).
    gravity : (float, float)
        Gravitational acceleration in global axes [m/s^2].

    Raises
    ------
    ModelError
        Unknown or duplicate names, bodies with several inboard hinges, cycles, bodies with no
        path to a base -- all problems found are listed in one message.

    Examples
    --------
    >>> from ctmm.planar import RigidBody, SmoothHinge, Pinned, PlanarModel
    >>> links = [RigidBody.uniform_link(f"l{i}", mass=1.0, length=1.0) for i in (1, 2)]
    >>> model = PlanarModel.chain("double", [Pinned("base"), links[0], SmoothHinge("h2"),
    ...                                      links[1]])
    >>> model.coordinates
    ('l1.theta', 'l2.theta')
    """

    def __init__(self, name: str, elements: Sequence[object], *,
                 gravity: Sequence[float] = (0.0, -9.81)) -> None:
        self.name = validation.name("model", name)
        self.gravity = validation.vector("gravity", gravity, 2, unit="m/s^2")
        self.elements = tuple(elements)
        self._compile()
        family = self.deformable_family   # sweep data of bodies with internal coordinates, built once:
        self.flexible_system: DeformableSystem | None = None if family is None else family.system(self)

    # ------------------------------------------------------------------------------------
    @classmethod
    def chain(cls, name: str, elements: Sequence[object], *,
              gravity: Sequence[float] = (0.0, -9.81)) -> "PlanarModel":
        """Serial chain from an ordered list ``[base, body, hinge, body, ..., (Free)]``.

        The base is :class:`Fixed` (followed by a hinge, or by a body that is then welded),
        :class:`Pinned` or :class:`FreeBase` (followed by a body).  Hinges connect the body
        before them (its single outboard end) to the body after them.
        """
        if not isinstance(elements, (list, tuple)):
            raise ModelError(f"chain {name!r}: elements must be a list or tuple [base, body, hinge, ...], "
                             f"got {elements!r}")
        items = list(elements)
        if not items:
            raise ModelError(f"chain {name!r} has no elements")
        base, rest = items[0], items[1:]
        if not isinstance(base, (Fixed, Pinned, FreeBase)):
            raise ModelError(f"chain {name!r} must start with Fixed, Pinned or FreeBase, got "
                             f"{type(base).__name__} {getattr(base, 'name', base)!r}")
        if rest and isinstance(rest[-1], Free):
            rest = rest[:-1]
        out: list[object] = []
        previous: str = base.name          # name of what the next hinge attaches to
        pending_hinge: Hinge | None = None
        base_element: object = base
        first = True
        for element in rest:
            if is_body(element):
                if first:
                    if isinstance(base, Fixed) and pending_hinge is None:
                        pending_hinge = DrivenHinge(f"{base.name}_weld", angle=0.0)
                        pending_hinge = pending_hinge.connected(base.name, element.name)
                        out.append(base)
                    elif isinstance(base, Fixed):
                        out.append(base)
                    else:
                        base_element = dataclasses.replace(base, child=element.name)
                        out.append(base_element)
                if pending_hinge is not None:
                    out.append(pending_hinge.connected(previous, element.name))
                elif not first:
                    raise ModelError(f"chain {name!r}: body {element.name!r} follows a body "
                                     "directly; put a hinge between them")
                out.append(element)
                if len(element.ends) > 1:
                    previous = element.name + "." + element.ends[0]
                else:
                    previous = element.name
                pending_hinge = None
                first = False
            elif isinstance(element, HINGE_TYPES):
                if pending_hinge is not None:
                    raise ModelError(f"chain {name!r}: hinges {pending_hinge.name!r} and "
                                     f"{element.name!r} follow each other; put a body between")
                if first and not isinstance(base, Fixed):
                    raise ModelError(f"chain {name!r}: {type(base).__name__} {base.name!r} "
                                     f"already contains its joint; hinge {element.name!r} "
                                     "must follow a body")
                pending_hinge = element
            else:
                raise ModelError(f"chain {name!r}: unexpected element {element!r} (Free is only "
                                 "allowed at the end)")
        if pending_hinge is not None:
            raise ModelError(f"chain {name!r}: hinge {pending_hinge.name!r} has no outboard body")
        if first:
            raise ModelError(f"chain {name!r} has no bodies")
        return cls(name, out, gravity=gravity)

    # ------------------------------------------------------------------------------------
    def _compile(self) -> None:
        problems: list[str] = []
        bodies: dict[str, RigidBody] = {}
        grounds: dict[str, Fixed] = {}
        joints: list[_Joint] = []
        names: set[str] = set()
        for element in self.elements:
            element_name = getattr(element, "name", None)
            if element_name in names:
                problems.append(f"duplicate element name {element_name!r}")
            names.add(element_name)
            if is_body(element):
                bodies[element.name] = element
            elif isinstance(element, Fixed):
                grounds[element.name] = element
        for element in self.elements:
            if is_body(element) or isinstance(element, (Fixed, Free)):
                continue
            if isinstance(element, Hinge):
                if element.parent is None or element.child is None:
                    problems.append(f"hinge {element.name!r} needs parent and child "
                                    f"(got parent={element.parent!r}, child={element.child!r})")
                    continue
                kind = DRIVEN if isinstance(element, DrivenHinge) else REVOLUTE
                if kind == REVOLUTE and (sum(translational_law(element)) > 0.0 or getattr(element, "radial_law", None)):
                    kind = BUSHING
                parent_name, _, end = element.parent.partition(".")
                if parent_name in grounds:
                    joints.append(_Joint(element.name, kind, None, None, grounds[parent_name],
                                         element))
                elif parent_name in bodies:
                    body = bodies[parent_name]
                    if not end:
                        if len(body.ends) != 1:
                            problems.append(f"hinge {element.name!r}: parent body {parent_name!r} "
                                            f"has ends {list(body.ends)}; name one as "
                                            f"'{parent_name}.END'")
                            continue
                        end = body.ends[0]
                    elif end not in body.ends:
                        problems.append(f"hinge {element.name!r}: body {parent_name!r} has no "
                                        f"end {end!r}; ends: {', '.join(body.ends) or '(none)'}")
                        continue
                    joints.append(_Joint(element.name, kind, parent_name, end, None, element))
                else:
                    problems.append(f"hinge {element.name!r}: unknown parent {element.parent!r}; "
                                    f"bodies: {', '.join(sorted(bodies)) or '(none)'}; "
                                    f"grounds: {', '.join(sorted(grounds)) or '(none)'}")
                    continue
                if element.child not in bodies:
                    problems.append(f"hinge {element.name!r}: unknown child {element.child!r}; "
                                    f"bodies: {', '.join(sorted(bodies)) or '(none)'}")
                    joints.pop()
            elif isinstance(element, (Pinned, FreeBase)):
                if element.child not in bodies:
                    problems.append(f"{type(element).__name__} {element.name!r}: unknown child "
                                    f"{element.child!r}; bodies: "
                                    f"{', '.join(sorted(bodies)) or '(none)'}")
                    continue
                if isinstance(element, Pinned):
                    ground = Fixed(element.name, position=element.position)
                    joints.append(_Joint(element.name, REVOLUTE, None, None, ground,
                                         SmoothHinge(element.name, parent=element.name,
                                                     child=element.child)))
                else:
                    joints.append(_Joint(element.name, FREE, None, None, None, element))
            else:
                problems.append(f"unknown element {element!r}")
        inboard: dict[str, _Joint] = {}
        for joint in joints:
            child = joint.hinge.child
            if child in inboard:
                problems.append(f"body {child!r} has several inboard hinges: "
                                f"{inboard[child].name!r} and {joint.name!r}")
            else:
                inboard[child] = joint
        if not bodies:
            problems.append("the model has no bodies")
        missing = [b for b in bodies if b not in inboard]
        if missing:
            problems.append(f"bodies without an inboard hinge or base: {', '.join(missing)}")
        # topological order from the roots
        children: dict[str | None, list[str]] = {}
        for child, joint in inboard.items():
            children.setdefault(joint.parent, []).append(child)
        order: list[str] = []
        stack = list(reversed(children.get(None, [])))
        while stack:
            body = stack.pop()
            order.append(body)
            stack.extend(reversed(children.get(body, [])))
        unreachable = [b for b in bodies if b not in set(order) and b in inboard]
        if unreachable:
            cycles = self._cycles(unreachable, inboard)
            for cycle in cycles:
                problems.append("cycle: " + " -> ".join(cycle))
            problems.append(f"bodies with no path to a base: {', '.join(unreachable)}")
        if problems:
            raise ModelError(f"model {self.name!r} is invalid:\n  - " + "\n  - ".join(problems))
        self._bodies = [bodies[b] for b in order]
        self._joints = [inboard[b] for b in order]
        self._arrays(order)

    @staticmethod
    def _cycles(unreachable: list[str], inboard: dict[str, _Joint]) -> list[list[str]]:
        cycles, seen = [], set()
        for start in unreachable:
            path, node = [], start
            while node is not None and node not in seen and node not in path:
                path.append(node)
                node = inboard[node].parent if node in inboard else None
            if node is not None and node in path:
                cycle = path[path.index(node):] + [node]
                cycles.append(cycle)
            seen.update(path)
        return cycles

    def _arrays(self, order: list[str]) -> None:
        nb = len(order)
        index = {b: i for i, b in enumerate(order)}
        self.body_names: tuple[str, ...] = tuple(order)
        self.joint_names: tuple[str, ...] = tuple(j.name for j in self._joints)
        self.mass = np.array([b.mass for b in self._bodies])
        self.inertia = np.array([b.inertia for b in self._bodies])
        inb = np.array([b.inboard for b in self._bodies])
        self.com = np.array([b.center_of_mass for b in self._bodies]) - inb
        self.parent = np.full(nb, -1, dtype=int)
        self.end_vector = np.zeros((nb, 2))     # parent end rel. to parent inboard (body frame)
        self.ground_position = np.zeros((nb, 2))
        self.ground_angle = np.zeros(nb)
        self.joint_kind = np.array([j.kind for j in self._joints], dtype=int)
        self.ends = []                          # per body: {end name: vector rel. inboard}
        for i, body in enumerate(self._bodies):
            self.ends.append({e: np.array(p) - inb[i] for e, p in _end_points(body).items()})
        for i, joint in enumerate(self._joints):
            if joint.parent is not None:
                p = index[joint.parent]
                self.parent[i] = p
                self.end_vector[i] = self.ends[p][joint.end]
            elif joint.ground is not None:
                self.ground_position[i] = joint.ground.position
                self.ground_angle[i] = joint.ground.angle
        # hinge laws tau = u - k (dtheta - r) - c (dtheta_dot - r_dot)
        self.stiffness, self.damping = np.zeros(nb), np.zeros(nb)
        self.translational_stiffness, self.translational_damping = np.zeros(nb), np.zeros(nb)
        self._reference, self._reference_rate, self._torque, self._driven = [], [], [], []
        for i, joint in enumerate(self._joints):
            if joint.kind == BUSHING:
                kt, ct = translational_law(joint.hinge)
                self.translational_stiffness[i], self.translational_damping[i] = kt, ct
            if joint.kind in (REVOLUTE, BUSHING):
                k, c, r, rd, u = joint.hinge.law()
                self.stiffness[i], self.damping[i] = k, c
                self._reference.append(r)
                self._reference_rate.append(rd)
                self._torque.append(u)
            else:
                zero = Constant(0.0)
                self._reference.append(zero)
                self._reference_rate.append(zero)
                self._torque.append(zero)
            if joint.kind == DRIVEN:
                self._driven.append((i, joint.hinge.angle, joint.hinge.rate,
                                     joint.hinge.acceleration))
        self._driven_signals = ([f for _, a, r, c in self._driven for f in (a, r, c)],    # (functions, labels,
                                [self.joint_names[i] for i, *_ in self._driven for _ in range(3)],   # parts) of
                                [part for _ in self._driven for part in ("angle", "rate", "acceleration")])  # driven()
        constant = all(isinstance(f, Constant) for f in self._driven_signals[0])      # driven(): read once
        self._constant_driven = [(i, a.value, r.value, c.value) for i, a, r, c in self._driven] if constant else None
        self.nonlinear_hinges = {i: j.hinge for i, j in enumerate(self._joints) if isinstance(j.hinge, NonlinearHinge)}
        laws = self._reference + self._reference_rate + self._torque           # hinge_laws: constants once,
        self._constant_laws = all(isinstance(f, Constant) for f in laws)        # the others evaluated per call
        self._law_values = tuple(np.array([f.value if isinstance(f, Constant) else 0.0 for f in laws]).reshape(3, nb))
        varying = [k for k, f in enumerate(laws) if not isinstance(f, Constant)]
        self._varying_laws = (varying, [laws[k] for k in varying], [self.joint_names[k % nb] for k in varying],
                              [("reference angle", "reference rate", "torque")[k // nb] for k in varying])
        # loads
        load_body, load_point, load_signals = [], [], []
        for i, body in enumerate(self._bodies):
            for load in body.loads:
                load_body.append(i)
                load_point.append(np.array(load.point) - inb[i])
                load_signals.append((load.force_x, load.force_y, load.moment))
        self.load_body = np.array(load_body, dtype=int)
        self.load_point = np.array(load_point).reshape(-1, 2)
        self._load_signals = load_signals
        self._constant_loads = all(isinstance(f, Constant) for s in load_signals for f in s)
        if self._constant_loads:
            self._load_values = np.array([[f.value for f in s] for s in load_signals]
                                         ).reshape(-1, 3)
        # bodies with internal coordinates (ctmm.flexible.ModalBeam), kernels from their family
        self.beams = {i: b for i, b in enumerate(self._bodies) if isinstance(b, DeformableBody)}
        families = sorted({type(b).__name__: type(b).family for b in self.beams.values()}.items())
        if len({id(f) for _, f in families}) > 1:   # one family's kernels run the whole sweep
            raise ModelError(f"{self.name!r}: one body family only (docs/mixed.md §5), got {[n for n, _ in families]}")
        self.deformable_family: DeformableFamily | None = families[0][1] if families else None
        self.flexible_bodies = np.array(sorted(self.beams), dtype=int)
        self.has_flexible = bool(self.beams)
        self.modal_index = [np.zeros(0, dtype=int) for _ in range(nb)]
        self.parent_end = [j.end for j in self._joints]
        self.parent_end_index = np.array(
            [(self._bodies[index[j.parent]].ends.index(j.end) if j.parent is not None else -1)
             for j in self._joints], dtype=int)
        if self.has_flexible and np.any(self.joint_kind == BUSHING):
            names_ = [self.joint_names[j] for j in np.flatnonzero(self.joint_kind == BUSHING)]
            raise ModelError(f"model {self.name!r}: hinges with translational springs "
                             f"({', '.join(names_)}) are not supported together with flexible "
                             "bodies yet")
        # coordinates
        names, theta_index, xy_index = [], np.full(nb, -1, dtype=int), np.full((nb, 2), -1,
                                                                                  dtype=int)
        for i, (body, joint) in enumerate(zip(order, self._joints)):
            if joint.kind == FREE:
                xy_index[i] = (len(names), len(names) + 1)
                names += [f"{body}.x", f"{body}.y"]
            elif joint.kind == BUSHING:
                xy_index[i] = (len(names), len(names) + 1)
                names += [f"{body}.dx", f"{body}.dy"]
            if joint.kind != DRIVEN:
                theta_index[i] = len(names)
                names.append(f"{body}.theta")
            if i in self.beams:
                start = len(names)
                names += [f"{body}.{suffix}" for suffix in self.beams[i].coordinate_suffixes]
                self.modal_index[i] = np.arange(start, len(names))
        self.coordinates: tuple[str, ...] = tuple(names)
        self.theta_index = theta_index
        self.xy_index = xy_index
        self.coordinate_bodies = np.flatnonzero(theta_index >= 0)
        self.free_bodies = np.flatnonzero(self.joint_kind == FREE)
        self.bushing_bodies = np.flatnonzero(self.joint_kind == BUSHING)
        self.children = [[] for _ in range(nb)]
        for i in range(nb):
            if self.parent[i] >= 0:
                self.children[self.parent[i]].append(i)
        self._parent_list = self.parent.tolist()
        self._kind_list = self.joint_kind.tolist()
        self._zeros = np.zeros(nb)
        self._inboard_index = np.where(self.parent >= 0, self.parent, np.arange(nb) + nb)   # of relative_angles
        self.is_chain = bool(np.all(self.parent == np.arange(-1, nb - 1))) and not self._driven \
            and not len(self.free_bodies) and not self.has_flexible

    # ------------------------------------------------------------------------------------
    @property
    def n_bodies(self) -> int:
        """Number of bodies."""
        return len(self.body_names)

    @property
    def n_coordinates(self) -> int:
        """Number of generalised coordinates."""
        return len(self.coordinates)

    @property
    def bodies(self) -> tuple[RigidBody, ...]:
        """Body descriptions in topological order."""
        return tuple(self._bodies)

    @property
    def hinges(self) -> tuple[object, ...]:
        """Inboard joint element of each body (same order as :attr:`bodies`)."""
        return tuple(j.hinge for j in self._joints)

    def coordinate_index(self, coordinate: str) -> int:
        """Index of a coordinate name such as ``"link3.theta"``."""
        try:
            return self.coordinates.index(coordinate)
        except ValueError:
            raise unknown_name("coordinate", coordinate, self.coordinates) from None

    def body_index(self, body: str) -> int:
        """Index of a body in :attr:`body_names`."""
        try:
            return self.body_names.index(body)
        except ValueError:
            raise unknown_name("body", body, self.body_names) from None

    # -- state vectors ----------------------------------------------------------------------
    def state(self, q, qdot) -> tuple[np.ndarray, np.ndarray]:
        """``q, qdot`` as float arrays of one value per coordinate, else :class:`ModelError`.

        Parameters
        ----------
        q, qdot : array_like
            Coordinates [m, rad, modal] and their rates, ``n_coordinates`` each, in the order of
            :attr:`coordinates`.
        """
        n = self.n_coordinates
        # fast path (the integrators' own float64 arrays, every sweep): no Python loop, no NaN check
        # (the integrators check the states they produce); anything else is checked in full
        if type(q) is np.ndarray and type(qdot) is np.ndarray and q.dtype == np.float64 \
                and qdot.dtype == np.float64 and q.shape == (n,) and qdot.shape == (n,):
            return q, qdot
        out = []
        for label, value in (("q", q), ("qdot", qdot)):
            if np.iscomplexobj(value) and np.any(np.imag(value) != 0):      # float() would drop it silently
                raise ModelError(f"{label} must be {n} real number(s) (a planar model's states), got {value!r}")
            try:
                array = np.asarray(np.real(value), dtype=float)
            except (TypeError, ValueError):
                raise ModelError(f"{label} must be {n} real number(s) (coordinates {', '.join(self.coordinates)}), "
                                 f"got {value!r}") from None
            if array.shape != (n,):
                raise ModelError(f"{label} must have length {n} (coordinates {', '.join(self.coordinates)}) for "
                                 f"model {self.name!r}, got {value!r} (shape {array.shape})")
            if not np.all(np.isfinite(array)):
                raise ModelError(f"{label} must be finite (coordinates {', '.join(self.coordinates)}), got {value!r}")
            out.append(array)
        return out[0], out[1]

    # -- time-dependent inputs -------------------------------------------------------------
    def hinge_laws(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(reference, reference_rate, torque)`` of every joint at time ``t``.

        Raises :class:`~ctmm.planar.signals.SignalError` naming the joint and the time when a user signal raises or
        returns anything but one finite number.
        """
        if self._constant_laws:
            return self._law_values
        index, functions, labels, parts = self._varying_laws
        values = np.array(self._law_values)                 # (3, n_bodies): the constant laws' values
        values.flat[index] = signal_values(functions, t, labels, parts)
        return values[0], values[1], values[2]

    def loads(self, t: float) -> np.ndarray:
        """External loads ``(fx, fy, moment)`` of every :class:`Load` at time ``t``
        (:class:`~ctmm.planar.signals.SignalError` naming the body and the load component when one fails)."""
        if self._constant_loads:
            return self._load_values
        functions = [f for s in self._load_signals for f in s]
        labels = [f"load {k} of body {self.body_names[b]!r}" for k, b in enumerate(self.load_body) for _ in range(3)]
        parts = [part for _ in self._load_signals for part in ("force_x", "force_y", "moment")]
        return signal_values(functions, t, labels, parts, quote=False).reshape(-1, 3)

    def driven(self, t: float) -> list[tuple[int, float, float, float]]:
        """``(body, angle, rate, acceleration)`` of every driven joint at time ``t`` (constant ones, e.g. welded
        mountings, read once; :class:`~ctmm.planar.signals.SignalError` naming the joint when a motion fails)."""
        if self._constant_driven is not None:
            return list(self._constant_driven)
        values = signal_values(self._driven_signals[0], t, *self._driven_signals[1:]).reshape(-1, 3)
        return [(i, float(v[0]), float(v[1]), float(v[2])) for (i, *_), v in zip(self._driven, values)]

    # -- kinematics ---------------------------------------------------------------------------
    def body_angles(self, q: np.ndarray, qdot: np.ndarray, t: float, driven: list | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Absolute angles and angular velocities of all bodies [rad, rad/s] (``driven``: :meth:`driven` at ``t``)."""
        if len(q) != self.n_coordinates or len(qdot) != self.n_coordinates:
            self.state(q, qdot)                        # raises the ModelError with the shapes
        theta = np.empty(self.n_bodies)
        omega = np.empty(self.n_bodies)
        cb = self.coordinate_bodies
        theta[cb] = q[self.theta_index[cb]]
        omega[cb] = qdot[self.theta_index[cb]]
        for i, angle, rate, _ in (self.driven(t) if driven is None else driven):
            p = self.parent[i]
            theta[i] = angle + (theta[p] if p >= 0 else self.ground_angle[i])
            omega[i] = rate + (omega[p] if p >= 0 else 0.0)
            if p in self.beams:
                slope = self.end_slope(i)
                idx = self.modal_index[p][:len(slope)]
                theta[i] += float(slope @ q[idx])
                omega[i] += float(slope @ qdot[idx])
        return theta, omega

    def end_slope(self, i: int) -> np.ndarray:
        """``phi'(x_end)`` of the transverse modes of body ``i``'s parent beam at the end body
        ``i`` hangs on (empty for rigid parents)."""
        p = self.parent[i]
        if p not in self.beams:
            return np.zeros(0)
        return self.beams[p].data.end_dphi[self.parent_end_index[i]]

    def parent_end_angles(self, q, qdot, theta: np.ndarray, omega: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
        """Angle and rate of the parent end each body hangs on (ground angle for roots);
        includes the elastic slope of flexible parents."""
        index = self._inboard_index                  # the parent's angle and rate, a root's ground angle and 0
        th = np.concatenate((theta, self.ground_angle))[index]          # gathered: new arrays
        om = np.concatenate((omega, self._zeros))[index]
        if self.has_flexible:
            q, qdot = np.asarray(q), np.asarray(qdot)
            th, om = th.astype(np.result_type(th, q), copy=False), om.astype(np.result_type(om, qdot), copy=False)
            for i, parent in enumerate(self._parent_list):     # Python ints: no numpy scalar per body
                if parent in self.beams:
                    slope = self.end_slope(i)
                    idx = self.modal_index[parent][:len(slope)]
                    th[i] = th[i] + slope @ q[idx]
                    om[i] = om[i] + slope @ qdot[idx]
        return th, om

    def bushing_offsets(self, q: np.ndarray, qdot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Translational offsets ``d`` and rates of the translational-spring hinges (nb, 2)."""
        if len(q) != self.n_coordinates or len(qdot) != self.n_coordinates:
            self.state(q, qdot)
        d = np.zeros((self.n_bodies, 2))
        dd = np.zeros((self.n_bodies, 2))
        bb = self.bushing_bodies
        if len(bb):
            d[bb] = np.asarray(q)[self.xy_index[bb]]
            dd[bb] = np.asarray(qdot)[self.xy_index[bb]]
        return d, dd

    def relative_angles(self, theta: np.ndarray, omega: np.ndarray, q=None, qdot=None
                        ) -> tuple[np.ndarray, np.ndarray]:
        """Hinge angles ``theta_child - theta_parent_end`` and their rates.

        With flexible parents the parent end angle includes the elastic slope, which needs the
        coordinates ``q, qdot``.
        """
        if self.has_flexible:
            if q is None:
                raise ModelError("relative_angles of a model with flexible bodies needs q, qdot")
            th, om = self.parent_end_angles(q, qdot, theta, omega)
            return theta - th, omega - om
        index = self._inboard_index                  # the parent's angle and rate, a root's ground angle and 0
        return (theta - np.concatenate((theta, self.ground_angle))[index],
                omega - np.concatenate((omega, self._zeros))[index])

    def points(self, q: np.ndarray, qdot: np.ndarray, t: float = 0.0, centres: bool = True) -> dict[str, np.ndarray]:
        """Positions and velocities of inboard ends and centres of mass in global axes.

        Returns a dict with arrays ``inboard``, ``inboard_velocity``, ``com``, ``com_velocity`` (shape
        ``(n_bodies, 2)``; ``centres=False``: without the centres of mass), ``theta`` and ``omega``.
        """
        q, qdot = self.state(q, qdot)
        theta, omega = self.body_angles(q, qdot, t)
        c, s = np.cos(theta), np.sin(theta)
        r_in = np.empty((self.n_bodies, 2))
        v_in = np.empty((self.n_bodies, 2))
        for i in range(self.n_bodies):
            p = self.parent[i]
            if p >= 0:
                e = self.end_vector[i]
                ed = np.zeros(2)
                if p in self.beams:                     # deformed end of a flexible parent
                    e, ed = self.beam_point_local(p, self.parent_end_index[i], q, qdot, True)
                rx, ry = c[p] * e[0] - s[p] * e[1], s[p] * e[0] + c[p] * e[1]
                r_in[i] = r_in[p] + (rx, ry)
                v_in[i] = v_in[p] + omega[p] * np.array([-ry, rx]) + (
                    c[p] * ed[0] - s[p] * ed[1], s[p] * ed[0] + c[p] * ed[1])
            elif self.joint_kind[i] == FREE:
                ix, iy = self.xy_index[i]
                r_in[i] = q[ix], q[iy]
                v_in[i] = qdot[ix], qdot[iy]
            else:
                r_in[i] = self.ground_position[i]
                v_in[i] = 0.0
            if self.joint_kind[i] == BUSHING:
                ix, iy = self.xy_index[i]
                r_in[i] = r_in[i] + (q[ix], q[iy])
                v_in[i] = v_in[i] + (qdot[ix], qdot[iy])
        if not centres:                                 # e.g. the cut points of kinematic loops read no more
            return {"inboard": r_in, "inboard_velocity": v_in, "theta": theta, "omega": omega}
        rcx = c * self.com[:, 0] - s * self.com[:, 1]
        rcy = s * self.com[:, 0] + c * self.com[:, 1]
        com = r_in + np.column_stack([rcx, rcy])
        v_com = v_in + omega[:, None] * np.column_stack([-rcy, rcx])
        for j, beam in self.beams.items():           # deformed centroid s_bar / m of a beam
            d, eta, eta_dot = beam.data, q[self.modal_index[j]], qdot[self.modal_index[j]]
            sb, sbd = d.centroid_local(eta, eta_dot) if hasattr(d, "centroid_local") else (  # ctmm.fem: its own
                np.array([d.Sx + eta[d.nq:] @ d.b_p, eta[:d.nq] @ d.b_q]) / d.m,
                np.array([eta_dot[d.nq:] @ d.b_p, eta_dot[:d.nq] @ d.b_q]) / d.m)
            rot = np.array([[c[j], -s[j]], [s[j], c[j]]])
            com[j] = r_in[j] + rot @ sb
            v_com[j] = v_in[j] + omega[j] * (rot @ np.array([-sb[1], sb[0]])) + rot @ sbd
        return {"inboard": r_in, "inboard_velocity": v_in, "com": com, "com_velocity": v_com,
                "theta": theta, "omega": omega}

    def beam_point_local(self, j: int, end: int, q, qdot, shortening: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Deformed end ``end`` of beam ``j`` in its frame (position, velocity rel. frame); ``shortening``: with a
        second-order beam's foreshortening (where its children and ports sit, ``ctmm.flexible.point_terms``)."""
        d = self.beams[j].data
        eta, eta_dot = q[self.modal_index[j]], qdot[self.modal_index[j]]
        if hasattr(d, "point_local"):                # ctmm.fem subsystems state their own
            return d.point_local(end, eta, eta_dot)
        return d.end_point(end, eta, eta_dot, shortening)

    def energy(self, q: np.ndarray, qdot: np.ndarray, t: float = 0.0) -> float:
        """Kinetic + gravity + hinge-spring energy [J], constant references (stiffened beams: flexible.md §1.3)."""
        pts = self.points(q, qdot, t)
        kinetic = 0.5 * np.sum(self.mass * np.sum(pts["com_velocity"] ** 2, axis=1)
                               + self.inertia * pts["omega"] ** 2)
        potential = -np.sum(self.mass * (pts["com"] @ self.gravity))
        if self.deformable_family is not None:
            return self.deformable_family.energy(self, q, qdot, t)
        dtheta, _ = self.relative_angles(pts["theta"], pts["omega"])
        reference, _, _ = self.hinge_laws(t)
        spring = 0.5 * np.sum(self.stiffness * (dtheta - reference) ** 2) + law_potential(self, dtheta, q)
        bb = self.bushing_bodies
        if len(bb):
            d = np.asarray(q)[self.xy_index[bb]]
            spring += 0.5 * np.sum(self.translational_stiffness[bb] * np.sum(d * d, axis=1))
        return float(kinetic + potential + spring)

    def __repr__(self) -> str:
        return (f"PlanarModel({self.name!r}, bodies={self.n_bodies}, "
                f"coordinates={self.n_coordinates})")


__all__ = ["PlanarModel", "REVOLUTE", "DRIVEN", "FREE", "BUSHING"]
