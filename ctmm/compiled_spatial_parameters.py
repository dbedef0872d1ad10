"""The numbers of a spatial model as inputs of its generated kernels (issues 13 and 14).

:func:`spatial_parameter_layout` lists the numbers a generated spatial step takes as its parameter
column ``p`` (one library per structure): every body's mass and the non-zero entries of its inertia
tensor, the non-zero stiffnesses and dampings of the 1- and 2-DOF joint laws (revolute, prismatic,
universal; ``tau = u - k (q - q_ref) - c v``) with the reference of every coordinate that has a
stiffness, the non-zero numbers of every modal beam (:mod:`ctmm.compiled_spatial_beam_numbers`: mass and polar
inertia per length, bending, torsional and axial stiffnesses, damping ratio and Kelvin-Voigt coefficient; in place
of a mass and inertia), and the non-zero components of gravity.  Zeros of the model are constants 0 of the code
(part of the structure, as for planar scenes); the geometry, joint axes, loads, driven motions, the
laws of spherical, free and elastic joints, beams' lengths and finite-element subsystems stay constants.

:class:`SpatialNumbers` states them on the entries of a symbol column, and
:func:`parametrised_body_terms` forms a rigid body's terms from them without the body's numbers in the
code: the terms are linear in the mass and the inertia (and in mass times gravity), so they are
summed from :func:`~ctmm.spatial.body_forms.rigid_body_terms` of unit numbers on the same pose
(unit mass, each unit inertia entry, each unit gravity component), which keeps the one statement of
the Newton-Euler terms.  :func:`parametrised_joint_law` gives a joint's law on the symbols, and
:func:`parametrised_scene_terms` a whole scene's terms (used by :class:`~ctmm.compiled_spatial.SpatialRates`
and by the loops of :class:`~ctmm.compiled_spatial_loops.CompiledControlledSpatial` with ``numbers="inputs"``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Mapping, Sequence

import numpy as np

from .ops import CASADI
from .protocol import BodyTerms, JointTerms
from .compiled_spatial_beam_numbers import BEAM_NUMBERS, beam_numbers, parametrised_beam_terms
from .spatial.beam import SpatialBeam
from .spatial.body_forms import rigid_body_terms
from .spatial.elements import SpatialBody
from .spatial.model import SpatialModel

__all__ = ["INERTIA_ENTRIES", "LAW_KINDS", "SpatialNumbers", "SpatialParameter", "parametrised_body_terms",
           "parametrised_joint_law", "parametrised_scene_terms", "spatial_parameter_layout", "spatial_parameter_vector",
           "unparametrised_bodies", "unparametrised_refusal"]

INERTIA_ENTRIES = (("xx", 0, 0), ("yy", 1, 1), ("zz", 2, 2), ("xy", 0, 1), ("xz", 0, 2), ("yz", 1, 2))
"""Names and (row, column) of the inertia entries (the tensor is symmetric)."""
LAW_KINDS = ("revolute", "prismatic", "universal")
"""Joint kinds whose law numbers are parameters."""
_LAW_UNITS = {"revolute": ("N m/rad", "N m s/rad", "rad"), "prismatic": ("N/m", "N s/m", "m"),
              "universal": ("N m/rad", "N m s/rad", "rad")}


@dataclass(frozen=True)
class SpatialParameter:
    """One entry of a spatial model's parameter column.

    Attributes
    ----------
    name : str
        ``"<body>.mass"``, ``"<body>.inertia.xx"`` (``yy, zz, xy, xz, yz``), ``"<joint>.stiffness"``,
        ``".damping"``, ``".reference"`` (``"[k]"`` appended on a 2-DOF joint), ``"gravity.x"``.
    unit : str
    value : float
        The model's number.
    kind : str
        ``"mass"``, ``"inertia"``, ``"stiffness"``, ``"damping"``, ``"reference"`` or ``"gravity"``.
    index : int
        Body or joint index (0 for gravity).
    entry : int
        Coordinate of the joint, axis of gravity, or position in :data:`INERTIA_ENTRIES`.
    """

    name: str
    unit: str
    value: float
    kind: str
    index: int
    entry: int


def _has_law(joint: Any) -> bool:
    return joint.kind in LAW_KINDS and not joint.driven


def unparametrised_bodies(model: SpatialModel) -> list[str]:
    """Names of the bodies of ``model`` whose numbers have no parametrised terms here: neither a rigid
    :class:`~ctmm.spatial.SpatialBody` nor a modal :class:`~ctmm.spatial.SpatialBeam` (the
    :class:`ctmm.fem.SpatialSubsystem` finite-element bodies).  A model with one has no kernel with its
    numbers as inputs (``numbers="inputs"``: refused by name)."""
    return [body.name for body in model.bodies if not isinstance(body, (SpatialBody, SpatialBeam))]


def unparametrised_refusal(model: SpatialModel, caller: str) -> str:
    """The refusal of ``numbers="inputs"`` for a model with :func:`unparametrised_bodies` (empty string
    when there are none), starting with ``caller``."""
    names = unparametrised_bodies(model)
    if not names:
        return ""
    return (f"{caller}: numbers='inputs' (one library per structure: parameters=, simulate_batch) takes the numbers "
            f"of rigid bodies and modal SpatialBeams; model {model.name!r} has the finite-element bodies "
            f"{', '.join(map(repr, names))}; run it with ctmm.simulate(..., compiled=True) without parameters= (its "
            "numbers constants of the code)")


def spatial_parameter_layout(model: SpatialModel) -> list[SpatialParameter]:
    """The parameters of ``model`` in the order of ``p``: body by body its mass, non-zero inertia entries
    and its joint's non-zero stiffnesses and dampings with the references of the stiff coordinates;
    then the non-zero gravity components (module docstring)."""
    layout = []
    for j, (body, joint) in enumerate(zip(model.bodies, model.joints)):
        if isinstance(body, SpatialBeam):
            layout += [SpatialParameter(f"{body.name}.{kind}", unit, value, kind, j, 0)
                       for kind, unit, value in beam_numbers(body)]
        else:
            layout.append(SpatialParameter(f"{body.name}.mass", "kg", float(body.mass), "mass", j, 0))
            inertia = np.asarray(body.inertia, dtype=float)
            layout += [SpatialParameter(f"{body.name}.inertia.{label}", "kg m^2", float(inertia[a, b]), "inertia", j,
                                        e) for e, (label, a, b) in enumerate(INERTIA_ENTRIES) if inertia[a, b] != 0.0]
        if not _has_law(joint):
            continue
        units = _LAW_UNITS[joint.kind]
        count = joint.velocity_count
        for i in range(count):
            suffix = f"[{i}]" if count > 1 else ""
            k, c, ref = (float(np.asarray(x, dtype=float).reshape(-1)[i])
                         for x in (joint.stiffness, joint.damping, joint.reference))
            if k != 0.0:
                layout.append(SpatialParameter(f"{joint.name}.stiffness{suffix}", units[0], k, "stiffness", j, i))
            if c != 0.0:
                layout.append(SpatialParameter(f"{joint.name}.damping{suffix}", units[1], c, "damping", j, i))
            if k != 0.0:
                layout.append(SpatialParameter(f"{joint.name}.reference{suffix}", units[2], ref, "reference", j, i))
    layout += [SpatialParameter(f"gravity.{axis}", "m/s^2", float(g), "gravity", 0, a)
               for a, (axis, g) in enumerate(zip("xyz", np.asarray(model.gravity, dtype=float))) if g != 0.0]
    return layout


def spatial_parameter_vector(model: SpatialModel) -> np.ndarray:
    """The values of :func:`spatial_parameter_layout` (SI units)."""
    return np.array([entry.value for entry in spatial_parameter_layout(model)], dtype=float)


class SpatialNumbers:
    """The parameters of a model's bodies and joints on casadi expressions.

    Parameters
    ----------
    layout : sequence of SpatialParameter
        Entries of ``p`` (:func:`spatial_parameter_layout`, or the part of one segment of a folded chain).
    p : casadi column
        Their symbols, in order.
    gravity : sequence of 3 expressions or numbers, optional
        Gravity [m/s^2] (default: the layout's gravity entries, zero components 0).
    """

    def __init__(self, layout: Sequence[SpatialParameter], p: Any, gravity: Sequence[Any] | None = None) -> None:
        self.entries: dict[tuple[str, int, int], Any] = {(e.kind, e.index, e.entry): p[k]
                                                         for k, e in enumerate(layout)}
        self.gravity = list(gravity) if gravity is not None else \
            [self.entries.get(("gravity", 0, a), 0.0) for a in range(3)]

    def body(self, j: int) -> tuple[Any, list[tuple[int, int, Any]]]:
        """``(mass, [(row, column, value)])`` of body ``j``: its mass and its non-zero inertia entries."""
        inertia = [(a, b, self.entries[("inertia", j, e)]) for e, (_, a, b) in enumerate(INERTIA_ENTRIES)
                   if ("inertia", j, e) in self.entries]
        return self.entries[("mass", j, 0)], inertia

    def beam(self, j: int) -> dict[str, Any]:
        """``{attribute: expression}`` of the numbers of beam ``j`` in the layout (:data:`BEAM_NUMBERS`)."""
        return {kind: self.entries[(kind, j, 0)] for kind, _ in BEAM_NUMBERS if (kind, j, 0) in self.entries}

    def law(self, j: int, count: int) -> list[tuple[Any, Any, Any]]:
        """``(k, c, q_ref)`` per coordinate of joint ``j`` (zeros of the model as 0)."""
        return [tuple(self.entries.get((kind, j, i), 0.0) for kind in ("stiffness", "damping", "reference"))
                for i in range(count)]

    def has_law(self, j: int, count: int) -> bool:
        """Whether joint ``j`` has a non-zero stiffness or damping."""
        return any((kind, j, i) in self.entries for kind in ("stiffness", "damping") for i in range(count))


def parametrised_body_terms(mass: Any, inertia: Sequence[tuple[int, int, Any]], gravity: Sequence[Any], *,
                            center_of_mass: Any, points: Mapping[str, Any], rotation: Any, offset: Any,
                            omega: Any, extra_h: Any = None) -> BodyTerms:
    """:func:`~ctmm.spatial.body_forms.rigid_body_terms` (casadi) with the mass, the inertia entries
    ``(row, column, value)`` (symmetric, the others 0) and gravity as expressions: the sum of the terms of
    unit numbers on the same pose, ``M = m M_m + sum I_ab M_ab``,
    ``h = m (h_m + sum g_k G_k) + sum I_ab h_ab`` (the terms are linear in ``m`` and ``I`` and in
    ``m g``), plus ``extra_h`` (the applied loads' part, or ``None``)."""
    zero3 = np.zeros(3)
    pose = dict(center_of_mass=center_of_mass, points=points, rotation=rotation, offset=offset, omega=omega)
    unit_mass = rigid_body_terms(CASADI, mass=1.0, inertia=np.zeros((3, 3)), gravity=zero3, **pose)
    M = unit_mass.M * mass
    h = unit_mass.h * mass
    for a, b, value in inertia:
        unit = np.zeros((3, 3))
        unit[a, b] = unit[b, a] = 1.0
        terms = rigid_body_terms(CASADI, mass=0.0, inertia=unit, gravity=zero3, **pose)
        M = M + terms.M * value
        h = h + terms.h * value
    for axis in range(3):
        if isinstance(gravity[axis], (int, float)) and gravity[axis] == 0.0:
            continue
        weighted = rigid_body_terms(CASADI, mass=1.0, inertia=np.zeros((3, 3)), gravity=np.eye(3)[axis], **pose)
        h = h + (weighted.h - unit_mass.h) * (mass * gravity[axis])
    if extra_h is not None:
        h = h + extra_h
    return BodyTerms(M=M, h=h, Kin=unit_mass.Kin, c=unit_mass.c, RF=unit_mass.RF)


def parametrised_joint_law(terms: JointTerms, law: Sequence[tuple[Any, Any, Any]], q: Sequence[Any],
                           v: Sequence[Any], u: Any) -> JointTerms:
    """Joint terms with the law ``tau = u - k (q - q_ref) - c v`` of the expressions ``law`` (per
    coordinate ``(k, c, q_ref)``) in place of the numeric one (``u`` the actuator input or ``None``)."""
    import casadi as ca

    def column(values: list) -> Any:
        return ca.vertcat(*[ca.SX(x) if isinstance(x, float) else x for x in values])

    tau = column([-k * (qi - ref) - c * vi for (k, c, ref), qi, vi in zip(law, q, v)])
    if u is not None:
        tau = tau + u
    return replace(terms, tau=tau, tau_q=ca.diag(column([-k for k, _, _ in law])),
                   tau_v=ca.diag(column([-c for _, c, _ in law])))


def parametrised_scene_terms(model: SpatialModel, numbers: SpatialNumbers, bodies: list, joints: list, states: list,
                             q: Any, v: Any, inputs: Mapping[str, Any], applied: Sequence[int] = ()
                             ) -> tuple[list, list]:
    """A scene's body and joint terms (casadi, :meth:`~ctmm.spatial.body_forms.SpatialScene.terms` at the
    symbols ``q``, ``v`` with the joint ``inputs``) with the numbers of ``numbers`` in place of the
    model's: every rigid body by :func:`parametrised_body_terms`, every modal beam by
    :func:`~ctmm.compiled_spatial_beam_numbers.parametrised_beam_terms`, every joint with a law by
    :func:`parametrised_joint_law`.  The applied loads' part of a body's ``h`` -- of the model's loads and
    of the bodies ``applied`` (indices; e.g. body-force actuators passed as ``wrenches`` to ``terms``) --
    is kept from the numeric terms (their ``h`` less the terms without loads)."""
    bodies, joints = list(bodies), list(joints)
    loaded = {load.body for load in model.loads} | {model.bodies[j].name for j in applied}
    for j, (body, joint, state) in enumerate(zip(model.bodies, model.joints, states)):
        offset = state.origin - state.inboard if joint.kind in ("prismatic", "free", "elastic6") else None
        if isinstance(body, SpatialBeam):          # the loads' rows carry no beam number: kept as they are
            modal = model.modal[j]
            bodies[j] = parametrised_beam_terms(
                body, bodies[j], numbers.beam(j), numbers.gravity, model_gravity=model.gravity,
                rotation=state.rotation, offset=offset, omega=state.omega,
                eta=q[modal.position.start:modal.position.stop], eta_dot=v[modal.velocity.start:modal.velocity.stop])
        else:
            pose = dict(center_of_mass=body.center_of_mass, rotation=state.rotation, offset=offset,
                        omega=state.omega, points={name: body.points[name] for name in bodies[j].Kin})
            extra = None
            if body.name in loaded:        # the loads' part: the numeric terms less those without loads
                extra = bodies[j].h - rigid_body_terms(CASADI, mass=body.mass, inertia=body.inertia,
                                                       gravity=model.gravity, **pose).h
            mass, inertia = numbers.body(j)
            bodies[j] = parametrised_body_terms(mass, inertia, numbers.gravity, extra_h=extra, **pose)
        count = joint.velocity_count
        if numbers.has_law(j, count):
            layout = model.layout[j]
            joints[j] = parametrised_joint_law(
                joints[j], numbers.law(j, count), [q[i] for i in range(layout.position.start, layout.position.stop)],
                [v[i] for i in range(layout.velocity.start, layout.velocity.stop)],
                inputs.get(joint.inputs[0]) if joint.inputs else None)
    return bodies, joints
