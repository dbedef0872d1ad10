"""Exact-field frequency form of a straight spatial chain of beams and rigid bodies (``fields="exact"``).

The bridge from a :class:`~ctmm.spatial.model.SpatialModel` built of modal
:class:`~ctmm.spatial.beam.SpatialBeam` bodies to the exact 12 x 12 spatial beam fields of
:mod:`ctmm.spatial_beam_fields` (docs/spatial_beams.md): about its rest configuration (gravity only
where every branch hangs or stands along it, :mod:`ctmm.spatial_exact_gravity`; no loads, joints at zero, beams undeformed, nothing moving) a serial spatial chain vibrates as a
spatial beam chain, answered by the Riccati transfer and the Wittrick-Williams count, so its
frequencies are exact at any mode number -- the limit the modal beam reaches as its modes increase.
:func:`exact_form` converts, in **chain axes** (the world axes turned so that a base revolute or
prismatic axis, or a base universal joint's ``axis1 x axis2``, is the chain's ``z``; the first beam's
axes where they allow it):

* the joints (:mod:`ctmm.spatial_exact_joints`): at the ground a weld -> :class:`SpatialClamped`; a
  revolute, prismatic, universal or spherical joint -> :class:`SpatialSupport` holding the directions it
  does not free (a spherical joint: a pinned root; a prismatic joint: a sliding root); a free or elastic6
  joint -> :class:`SpatialFree`; every linear law (``k + c s``, a spherical joint's 3 x 3 rotary spring, an
  elastic6 joint's 6 x 6 spring) a :class:`SpatialGroundSpring`; between bodies a weld -> continuity, a
  revolute -> :class:`SpatialHinge`, a universal joint -> two hinges, a spherical joint -> three hinges
  about its stiffness's principal axes, an elastic6 joint -> :class:`SpatialSpring` (each needs a law in
  every free direction); joint inputs -> point moments and forces on the markers on both sides;
* a :class:`~ctmm.spatial.elements.SpatialBody` -> :class:`SpatialRigidBody` (mass, inertia and
  centre of mass turned to chain axes, its child's point as the offset);
* a :class:`~ctmm.spatial.beam.SpatialBeam` -> :class:`SpatialBeamField` pieces between its stations
  (``EA``, ``GJ``, ``rho I_p``, Kelvin-Voigt ``stiffness_damping``, the sections' rotary inertias (Rayleigh; refused
  in gravity); the modal beam's ``bending_stiffness_y`` and ``rotary_inertia_per_length_y`` govern ``w_y``, bending
  in the x-y plane, which are the field's ``bending_stiffness_z`` and ``rotary_inertia_per_length_z``) with a
  :class:`SpatialPointLoad` marker at the root, every station and the tip;
* the free outboard end -> :class:`SpatialFree`;
* a **tree** (a body with several children) -> :class:`~ctmm.spatial_beam_trees.SpatialBeamTree`: the
  main path is the base and every body's first child (in model order), every other child starts a
  serial branch condensed onto the main chain at its point (a beam station's marker, or a rigid body's
  root marker through a massless rigid link to the point); a branch's own further children start its
  branches, condensed onto it first (any depth); inputs on the main path only.

**Rigid directions.**  A direction of a beam without modes (``n_axial_modes = 0``: inextensible,
``n_torsion_modes = 0``: torsionally rigid, ``n_modes_y = 0`` or ``n_modes_z = 0``: rigid in that
plane) is rigid in the modal beam.  The field needs a finite stiffness there: it is given
``RIGID_FACTOR`` times a stiffness scale of the beam (and a section inertia ``rhoA L^2 /
RIGID_FACTOR`` when ``polar_inertia_per_length = 0``), and :func:`natural_frequencies` answers
only if the frequencies with ``RIGID_FACTOR`` and ``RIGID_FACTOR / RIGID_CHECK_RATIO`` agree to
``RIGID_TOLERANCE`` (relative); otherwise a :class:`ModelError` names the rigid directions (a
frequency that depends on a rigid direction's stiffness).

Ports: joint coordinates and rates, body ``omega_x|y|z`` and ``omega_body_x|y|z``, point positions and
velocities (world), point forces and moments in world and body axes (about the rest configuration the
body axes stand still: their turning is second order), beam station sensors.

Refused (:class:`~ctmm.errors.ModelError`, naming the part): several bases,
actuators on a branch, a main path that goes on from a beam's mid-span station, prismatic and free joints between bodies and joints free in a direction between bodies (no
transfer matrix), a spherical joint whose damping and stiffness have different principal axes,
driven joints, nonlinear laws and joint references, gravity whose rest configuration is no equilibrium
(:mod:`ctmm.spatial_exact_gravity`: free or prismatic joints, beams across it, bodies whose outboard
first moment is off its vertical), loads, distributed loads and modal hooks (a preload or no field counterpart), modal damping ratios, a given operating point, loops in
:func:`natural_frequencies` (pass ``system.plant``; :func:`frequency_response` closes them), and
ports without an exact-field counterpart (modal coordinates, quaternion components, body angles
and rotation vectors).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from . import validation
from .errors import ModelError
from .results import FrequencyResponse
from .spatial_exact_gravity import (beam_gravity, beam_tension, check_gravity, hung_masses, rigid_preload,
                                    subtree_masses, warn_stretch)
from .spatial_exact_joints import CONVERTED_KINDS

__all__ = ["SpatialExactForm", "exact_form", "natural_frequencies", "frequency_response", "RIGID_FACTOR"]

#: Stiffness of a rigid direction relative to the beam's stiffness scale (module docstring).
RIGID_FACTOR = 1e12
#: The rigid-direction check compares with ``RIGID_FACTOR / RIGID_CHECK_RATIO``.
RIGID_CHECK_RATIO = 100.0
#: Largest relative change of a frequency between the two rigid stiffnesses.
RIGID_TOLERANCE = 1e-9

Terms = list[tuple[str, float]]
_DISPLACEMENTS = ("ux", "uy", "uz", "theta_x", "theta_y", "theta_z")


@dataclass(frozen=True)
class SpatialExactForm:
    """A spatial chain as a spatial beam chain of exact fields, with its port map.

    Attributes
    ----------
    chain : ctmm.Chain
        The spatial beam chain (layout ``SPATIAL_BEAM``, chain axes).
    axes : (3, 3) ndarray
        ``Q``: chain axes from world axes (``v_chain = Q v_world``).
    sensors : dict of str to list of (str, float)
        Sensor name -> weighted chain displacement signals (``"_dot"`` for rates).
    actuators : dict of str to list of (str, float)
        Actuator name -> weighted chain inputs (``"<marker>.fx"`` ...).
    rigid : list of str
        Rigid beam directions given the stiffness ``RIGID_FACTOR`` (``"<beam>.axial"`` ...).
    """

    chain: Any
    axes: np.ndarray
    sensors: dict
    actuators: dict
    rigid: list

    def sensor(self, name: str) -> Terms:
        """Chain signal terms of sensor ``name`` (or a :class:`ModelError`)."""
        if name not in self.sensors:
            raise ModelError(f"sensor {name!r} has no exact-field counterpart (fields='exact' maps joint angles and "
                             f"rates, point positions and velocities, body angular velocities and beam station "
                             f"sensors); available: {', '.join(sorted(self.sensors))}")
        return self.sensors[name]

    def actuator(self, name: str) -> Terms:
        """Chain input terms of actuator ``name`` (or a :class:`ModelError`)."""
        if name not in self.actuators:
            raise ModelError(f"actuator {name!r} has no exact-field counterpart; available: "
                             f"{', '.join(sorted(self.actuators))}")
        return self.actuators[name]


def _refuse(model: Any, reason: str) -> ModelError:
    return ModelError(f"fields='exact' cannot convert spatial model {model.name!r}: {reason}")


def _axis_rotation(axis: np.ndarray) -> np.ndarray:
    """A proper rotation ``Q`` with ``Q axis = e_z``."""
    e3 = axis / np.linalg.norm(axis)
    helper = np.eye(3)[int(np.argmin(np.abs(e3)))]
    e1 = np.cross(helper, e3)
    e1 /= np.linalg.norm(e1)
    return np.array([e1, np.cross(e3, e1), e3])


def _chain_axes(model: Any) -> np.ndarray:
    """``Q`` (chain from world axes): a base revolute or prismatic axis (a universal joint's ``axis1 x
    axis2``) is the chain's ``z``; the first beam's axes are the chain axes (up to a signed permutation
    when that axis is one of them), so that its field is not turned (the static rigid-mode count of
    turned fields is less robust)."""
    from .spatial.beam import SpatialBeam
    from .spatial_exact_joints import base_axis

    axis = base_axis(model.joints[0])
    R = np.eye(3)
    beam_axes = None
    for j in _paths(model)[0]:
        body, joint = model.bodies[j], model.joints[j]
        R = R @ joint.rotation
        if isinstance(body, SpatialBeam):
            beam_axes = R
            break
    if beam_axes is None:
        return np.eye(3) if axis is None else _axis_rotation(axis)
    if axis is None:
        return beam_axes.T
    b = [beam_axes[:, i] for i in range(3)]
    for i in range(3):
        sign = float(b[i] @ axis)
        if abs(sign) > 1.0 - 1e-12:
            j, k = (i + 1) % 3, (i + 2) % 3          # (b_j, b_k, b_i) is right-handed
            return np.array([b[j], np.sign(sign) * b[k], np.sign(sign) * b[i]])
    return _axis_rotation(axis)


def _paths(model: Any) -> tuple[list[int], list[tuple]]:
    """The main path (from the base, every body's first child) and the branches hung on it, each ``(path,
    its own branches)`` (recursively), of a spatial model, or a :class:`ModelError` for several bases."""
    children: list[list[int]] = [[] for _ in model.bodies]
    bases = [j for j, p in enumerate(model.parent) if p < 0]
    for j, p in enumerate(model.parent):
        if p >= 0:
            children[p].append(j)
    if bases != [0]:
        raise _refuse(model, f"it has several bases {[model.bodies[j].name for j in bases]}")

    def path(start: int) -> list[int]:
        out = [start]
        while children[out[-1]]:
            out.append(children[out[-1]][0])
        return out

    def hung(on: list[int]) -> list[tuple]:
        return [(path(c), hung(path(c))) for j in on for c in children[j][1:]]

    main = path(0)
    return main, hung(main)


def _snap(rotation: np.ndarray) -> np.ndarray:
    """Entries within ``1e-12`` of 0 or +-1 made exact (a signed permutation stays one exactly)."""
    out = np.where(np.abs(rotation) < 1e-12, 0.0, rotation)
    return np.where(np.abs(np.abs(out) - 1.0) < 1e-12, np.sign(out), out)


def _skew(r: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def _check(model: Any, operating_point: Any) -> None:
    from .spatial.beam import SpatialBeam

    if operating_point is not None:
        raise _refuse(model, "an operating point is given; the exact form is about the rest configuration (leave "
                             "operating_point=None)")
    if model.loads:
        raise _refuse(model, f"loads {[load.name for load in model.loads]} preload the chain")
    _paths(model)
    check_gravity(model)
    for body, joint in zip(model.bodies, model.joints):
        if joint.kind not in CONVERTED_KINDS:
            raise _refuse(model, f"joint {joint.name!r} is a {joint.kind} joint (converted: {', '.join(CONVERTED_KINDS)})")
        if joint.kind in ("revolute", "prismatic", "universal"):
            if joint.driven or joint.law is not None or np.any(joint.reference):
                raise _refuse(model, f"{joint.kind} joint {joint.name!r} is driven, has a nonlinear law or a non-zero "
                                     "reference")
        if isinstance(body, SpatialBeam):
            if body.damping_ratio:
                raise _refuse(model, f"beam {body.name!r} has damping_ratio = {body.damping_ratio!r} (no field "
                                     "counterpart; use stiffness_damping, Kelvin-Voigt)")
            if body.modal_forces:
                raise _refuse(model, f"beam {body.name!r} has modal-force hooks (use station ports)")
            if any(getattr(q, "value", None) != 0.0 for q in body.distributed_load):
                raise _refuse(model, f"beam {body.name!r} carries a distributed load (a preload)")


class _Builder:
    """Walks a checked serial spatial chain and collects the field elements and the port map."""

    def __init__(self, model: Any, rigid_factor: float, omega_max: float | None) -> None:
        self.model = model
        self.rigid_factor = rigid_factor
        self.omega_max = omega_max
        self.elements: list = []
        self.sensors: dict[str, Terms] = {}
        self.actuators: dict[str, Terms] = {}
        self.rigid: list[str] = []
        self.Q = _chain_axes(model)
        self.subtree = subtree_masses(model)           # mass of every body's subtree [kg]
        self.rotations: dict[int, np.ndarray] = {}      # world rotation of each body at rest
        self.points: dict[int, dict] = {}               # body -> {point: (marker, offset from it, chain axes)}
        self.beam_markers: dict[str, str] = {}          # the last beam's points -> their markers

    # -- port helpers -------------------------------------------------------------------------
    def marker(self, name: str) -> str:
        from .spatial_beam_elements import SpatialPointLoad
        self.elements.append(SpatialPointLoad(name))
        return name

    def rigid_point(self, marker: str, offset: np.ndarray) -> list[Terms]:
        """Chain displacement terms of ``u`` (3 chain components) at ``marker`` + ``offset`` (chain axes)."""
        S = _skew(offset)
        rows = []
        for i in range(3):
            terms = [(f"{marker}.{_DISPLACEMENTS[i]}", 1.0)]
            terms += [(f"{marker}.{_DISPLACEMENTS[3 + k]}", -S[i, k]) for k in range(3) if S[i, k]]
            rows.append(terms)
        return rows

    def world(self, rows: list[Terms]) -> list[Terms]:
        """World components ``Q^T`` of chain-axes rows."""
        return [[(n, self.Q[k, i] * w) for k in range(3) for n, w in rows[k] if self.Q[k, i]] for i in range(3)]

    def point_sensors(self, label: str, rows: list[Terms]) -> None:
        for axis, terms in zip("xyz", self.world(rows)):
            self.sensors[f"{label}.{axis}"] = terms
            self.sensors[f"{label}.v{axis}"] = [(f"{n}_dot", w) for n, w in terms]

    def force_inputs(self, label: str, marker: str, offset: np.ndarray, kinds: Sequence[str],
                     body: np.ndarray | None = None) -> None:
        """World-axes force (at ``offset`` from ``marker``) and moment inputs ``label.force_x`` ...; with the
        body's rest axes ``body`` (body -> chain axes) also ``label.force_body_x`` ... (about the rest
        configuration the body axes stand still: their turning is second order)."""
        S = _skew(offset)                      # moment at the marker = offset x force
        axes = [("", self.Q)] + ([] if body is None else [("_body", body)])
        for suffix, directions in axes:
            for i, axis in enumerate("xyz"):
                f = directions[:, i]           # unit force (world or body axis) in chain axes
                if "force" in kinds:
                    terms = [(f"{marker}.f{c}", f[k]) for k, c in enumerate("xyz") if f[k]]
                    moment = S @ f
                    terms += [(f"{marker}.m{c}", moment[k]) for k, c in enumerate("xyz") if moment[k]]
                    self.actuators[f"{label}.force{suffix}_{axis}"] = terms
                if "moment" in kinds:
                    self.actuators[f"{label}.moment{suffix}_{axis}"] = [
                        (f"{marker}.m{c}", f[k]) for k, c in enumerate("xyz") if f[k]]

    # -- elements -----------------------------------------------------------------------------
    def build(self) -> SpatialExactForm:
        from .spatial_beam_trees import SpatialBeamTree
        from .system import Chain

        model = self.model
        main, branches = _paths(model)
        self.walk(main, np.eye(3))
        trunk = self.elements
        hung = self.hang(trunk, branches)
        chain = (SpatialBeamTree(f"{model.name}_exact", trunk, hung) if hung
                 else Chain(f"{model.name}_exact", trunk))
        return SpatialExactForm(chain, self.Q, self.sensors, self.actuators, self.rigid)

    def hang(self, on: list, branches: Sequence[tuple]) -> dict:
        """``{marker: elements or (elements, their branches)}`` of ``branches`` hung on the elements ``on``."""
        from .spatial_beam_elements import SpatialPointLoad, SpatialRigidBody

        model = self.model
        hung: dict = {}
        for path, nested in branches:          # each hangs at a marker of the chain it hangs on
            joint = model.joints[path[0]]
            marker, offset = self.points[model.parent[path[0]]][joint.point]
            if marker in hung:                 # a second branch there: a marker of its own just after
                extra = SpatialPointLoad(f"{marker}__{len(hung)}")
                on.insert(next(k for k, e in enumerate(on) if e.name == marker) + 1, extra)
                marker = extra.name
            self.elements = [] if not np.any(offset) else [SpatialRigidBody(f"{joint.name}__link", 0.0,
                                                                            offset=offset)]
            self.walk(path, self.rotations[model.parent[path[0]]])
            own = self.elements
            below = self.hang(own, nested)
            hung[marker] = (own, below) if below else own
        return hung

    def walk(self, path: Sequence[int], parent_rotation: np.ndarray) -> None:
        """Elements and ports of the serial ``path`` of bodies onto ``self.elements``, ending free."""
        from .spatial.beam import SpatialBeam
        from .spatial_beam_elements import SpatialFree
        from .spatial_exact_joints import base_elements, inner_elements, joint_ports, motion_matrix

        model = self.model
        R = parent_rotation                    # world rotation of the parent body
        for k, j in enumerate(path):
            body, joint = model.bodies[j], model.joints[j]
            R_joint = R @ joint.rotation
            A = motion_matrix(joint, _snap(self.Q @ R_joint))
            before = None
            if model.parent[j] < 0:
                self.elements += base_elements(model.name, joint, A)
            elif joint.kind != "weld":
                elements = inner_elements(model.name, joint, A)
                before = self.marker(f"{joint.name}__before")
                self.elements += elements
            root = self.marker(f"{body.name}__root")
            sensors, actuators = joint_ports(joint, A, root, before)
            self.sensors.update(sensors)
            self.actuators.update(actuators)
            R = self.rotations[j] = R_joint    # the body's world rotation at rest
            B = _snap(self.Q @ R)              # body axes -> chain axes
            for i, axis_name in enumerate("xyz"):      # angular velocity: Q^T theta_dot (world), B^T theta_dot (body)
                self.sensors[f"{body.name}.omega_{axis_name}"] = [
                    (f"{root}.theta_{c_}_dot", self.Q[k_, i]) for k_, c_ in enumerate("xyz") if self.Q[k_, i]]
                self.sensors[f"{body.name}.omega_body_{axis_name}"] = [
                    (f"{root}.theta_{c_}_dot", B[k_, i]) for k_, c_ in enumerate("xyz") if B[k_, i]]
            child = model.joints[path[k + 1]].point if k + 1 < len(path) else None
            hung = hung_masses(model, j, self.subtree)
            if isinstance(body, SpatialBeam):
                self.beam(body, root, B, child, [(body.points[name][0], mass) for name, mass in hung])
                self.points[j] = {name: (marker, np.zeros(3)) for name, marker in self.beam_markers.items()}
            else:
                self.rigid_body(body, root, B, child, [(B @ body.points[name], mass) for name, mass in hung])
                self.points[j] = {name: (root, B @ p) for name, p in body.points.items()}
        self.elements.append(SpatialFree(f"{model.bodies[path[-1]].name}__end"))

    def rigid_body(self, body: Any, root: str, B: np.ndarray, child: str | None,
                   hung: Sequence[tuple[np.ndarray, float]]) -> None:
        from .spatial_beam_elements import SpatialRigidBody

        points = dict(body.points)
        points["com"] = body.center_of_mass
        for name, p in points.items():
            self.point_sensors(f"{body.name}.{name}", self.rigid_point(root, B @ p))
            self.force_inputs(f"{body.name}.{name}", root, B @ p, ("force",), B if name != "com" else None)
        self.force_inputs(body.name, root, B @ body.center_of_mass, ("force",), B)
        self.force_inputs(body.name, root, np.zeros(3), ("moment",), B)
        offset = B @ body.points[child] if child is not None else np.zeros(3)
        self.elements.append(SpatialRigidBody(body.name, body.mass, B @ body.inertia @ B.T,
                                              center_of_mass=B @ body.center_of_mass, offset=offset))
        self.elements += rigid_preload(self.model, self.Q, body, B @ body.center_of_mass, hung)

    def stiffness(self, beam: Any) -> dict:
        """Field parameters of ``beam``, rigid directions at ``rigid_factor`` times its stiffness scale."""
        L, rhoA = beam.length, beam.mass_per_length
        scale = max(beam.bending_stiffness_y, beam.bending_stiffness_z) / (L * L)
        out = {"bending_stiffness_z": beam.bending_stiffness_y, "bending_stiffness_y": beam.bending_stiffness_z,
               "axial_stiffness": beam.axial_stiffness, "torsional_stiffness": beam.torsional_stiffness,
               "polar_inertia_per_length": beam.polar_inertia_per_length,
               "wagner_term": bool(beam.wagner_term and beam.n_torsion_modes),
               "rotary_inertia_per_length_z": beam.rotary_inertia_per_length_y,     # x-y plane, turning with w_y
               "rotary_inertia_per_length_y": beam.rotary_inertia_per_length_z}
        for count, key, value, label in (
                (beam.n_modes_y, "bending_stiffness_z", self.rigid_factor * scale * L * L, "bending_y"),
                (beam.n_modes_z, "bending_stiffness_y", self.rigid_factor * scale * L * L, "bending_z"),
                (beam.n_axial_modes, "axial_stiffness", self.rigid_factor * scale, "axial"),
                (beam.n_torsion_modes, "torsional_stiffness", self.rigid_factor * scale * L * L, "torsion")):
            if count == 0:
                out[key] = value
                self.rigid.append(f"{beam.name}.{label}")
        if out["axial_stiffness"] is None:
            out["axial_stiffness"] = self.rigid_factor * scale
        if out["torsional_stiffness"] is None:
            out["torsional_stiffness"] = self.rigid_factor * scale * L * L
        if out["polar_inertia_per_length"] == 0.0:
            out["polar_inertia_per_length"] = rhoA * L * L / self.rigid_factor
            self.rigid.append(f"{beam.name}.polar_inertia")
        return out

    def beam(self, beam: Any, root: str, B: np.ndarray, child: str | None,
             hung: Sequence[tuple[float, float]]) -> None:
        from .spatial_beam_fields import SpatialBeamField, SpatialVaryingTensionField

        if child is not None and child != "tip" and beam.points[child][0] < beam.length * (1 - 1e-12):
            raise _refuse(self.model, f"the first child of beam {beam.name!r} hangs at point {child!r} (x = "
                                      f"{beam.points[child][0]} m < L): the path goes on from mid-span (later "
                                      "children hang there as branches: list the body hung at the tip first)")
        parameters = self.stiffness(beam)
        along = beam_gravity(self.model, self.Q, beam, B[:, 0])
        if along:
            warn_stretch(self.model, beam, beam_tension(along, beam, hung, 0.0, 0.0)[0])
        places = sorted([(x, name) for name, x in beam.stations.items() if 0.0 < x < beam.length]
                        + [(beam.length, "tip")])
        markers = {"origin": (root, 0.0)}
        markers.update({name: (root, 0.0) for name, x in beam.stations.items() if x == 0.0})
        position, pieces = 0.0, 0
        for x, name in places:
            if x - position > 1e-12 * beam.length:
                pieces += 1
                if along:
                    rotary = {key: parameters.pop(key) for key in list(parameters) if key.startswith("rotary")}
                    if any(rotary.values()):
                        raise _refuse(self.model, f"beam {beam.name!r} has section rotary inertia {rotary} kg m in "
                                                  "gravity: the varying-tension field has no Rayleigh term (give "
                                                  "gravity=(0, 0, 0) or use fields='modal')")
                    tension = beam_tension(along, beam, hung, position, x)
                    field = SpatialVaryingTensionField(f"{beam.name}__{pieces}", x - position, rotation=B,
                                                       inboard_tension=tension[0], outboard_tension=tension[1],
                                                       kelvin_voigt_time=beam.stiffness_damping, **parameters,
                                                       mass_per_length=beam.mass_per_length)
                else:
                    field = SpatialBeamField(f"{beam.name}__{pieces}", x - position, rotation=B,
                                             kelvin_voigt_time=beam.stiffness_damping, **parameters,
                                             mass_per_length=beam.mass_per_length)
                self.elements += ([field] if self.omega_max is None
                                  else list(field.split(field.pieces_for(self.omega_max))))
                position = x
            markers[name] = (self.marker(f"{beam.name}__at_{name}"), x)
            if name == "tip":
                markers.update({n: markers["tip"] for n, xs in beam.stations.items() if xs == x})
        self.beam_markers = {name: marker for name, (marker, _) in markers.items()}
        b1 = B[:, 0]
        for name, (marker, x) in markers.items():
            self.point_sensors(f"{beam.name}.{name}", self.rigid_point(marker, np.zeros(3)))
            self.force_inputs(f"{beam.name}.{name}", marker, np.zeros(3), ("force", "moment"), B)
            if name == "origin":
                continue
            rigid = self.rigid_point(root, x * b1)          # the root frame's motion at x
            relative = [[(n, w) for n, w in self.rigid_point(marker, np.zeros(3))[i]]
                        + [(n, -w) for n, w in rigid[i]] for i in range(3)]
            local = [[(n, B[k, i] * w) for k in range(3) for n, w in relative[k] if B[k, i]] for i in range(3)]
            turn = [[(f"{marker}.theta_{c}", B[k, i]) for k, c in enumerate("xyz") if B[k, i]]
                    + [(f"{root}.theta_{c}", -B[k, i]) for k, c in enumerate("xyz") if B[k, i]] for i in range(3)]
            for label, terms in (("axial", local[0]), ("w_y", local[1]), ("w_z", local[2]), ("twist", turn[0]),
                                 ("slope_y", turn[2]), ("slope_z", [(n, -w) for n, w in turn[1]])):
                self.sensors[f"{beam.name}.{name}.{label}"] = terms
                self.sensors[f"{beam.name}.{name}.{label}_rate"] = [(f"{n}_dot", w) for n, w in terms]


def exact_form(model: Any, operating_point: Any = None, *, rigid_factor: float = RIGID_FACTOR,
               omega_max: float | None = None) -> SpatialExactForm:
    """The exact-field spatial beam chain of a straight spatial chain and its port map (module docstring).

    Parameters
    ----------
    model : SpatialModel
    operating_point : None
        The rest configuration only (anything else is refused).
    rigid_factor : float, optional
        Stiffness of rigid beam directions relative to the beam's stiffness scale (default
        ``RIGID_FACTOR``).
    omega_max : float, optional
        Split every field into pieces well conditioned up to ``omega_max`` [rad/s] (for frequency
        responses; the counting verbs subdivide by themselves).
    """
    from .spatial.model import SpatialModel

    if not isinstance(model, SpatialModel):
        loops = [lp.name for lp in getattr(model, "loops", ())]
        raise ModelError(f"fields='exact' converts a SpatialModel; got {type(model).__name__} (for the loops {loops} "
                         "use frequency_response; natural_frequencies describes the plant: pass system.plant)")
    _check(model, operating_point)
    return _Builder(model, float(rigid_factor), omega_max).build()


def natural_frequencies(system: Any, *, n_modes: int | None = None, omega_max: float | None = None,
                        operating_point: Any = None) -> np.ndarray:
    """Undamped natural frequencies [rad/s] of a spatial chain's exact-field form (ascending, rigid as 0).

    The spatial beam chain of :func:`exact_form` is counted by Wittrick-Williams
    (:func:`ctmm.natural.natural_frequencies`): no mode is missed.  Frequencies that depend on the
    stiffness given to a rigid beam direction are refused (module docstring).

    Parameters
    ----------
    system : SpatialModel
    n_modes : int, optional
        Number of lowest frequencies.
    omega_max : float, optional
        All frequencies below ``omega_max`` [rad/s] instead.
    operating_point : None
        As for :func:`exact_form`.
    """
    from .natural import natural_frequencies as chain_natural
    from .spatial_exact_joints import rigid_mode_count
    from .system import Chain

    form = exact_form(system, operating_point, rigid_factor=RIGID_FACTOR)
    def count(chain: Any) -> np.ndarray:           # a chain (Wittrick-Williams) or a tree (its own count)
        if isinstance(chain, Chain):
            return chain_natural(chain, n_modes=n_modes, omega_max=omega_max)
        return chain.natural_frequencies(n_modes=n_modes, omega_max=omega_max)

    omega = count(form.chain)
    rigid_modes = rigid_mode_count(system.joints[0])
    if np.count_nonzero(omega == 0.0) > rigid_modes:
        raise _refuse(system, f"the chain count found {np.count_nonzero(omega == 0.0)} rigid-body modes where the "
                              f"model has {rigid_modes} (a safety check of the chain's static rigid-mode count); "
                              "use fields='modal'")
    if form.rigid:
        softer = exact_form(system, operating_point, rigid_factor=RIGID_FACTOR / RIGID_CHECK_RATIO)
        check = count(softer.chain)
        scale = max(float(np.max(omega, initial=0.0)), 1e-300)
        if check.shape != omega.shape or np.max(np.abs(check - omega) / np.maximum(omega, 1e-6 * scale),
                                                initial=0.0) > RIGID_TOLERANCE:
            raise _refuse(system, f"its frequencies depend on the stiffness given to the rigid beam directions "
                                  f"{form.rigid} (no modes there; changes of up to "
                                  f"{np.max(np.abs(check - omega)) if check.shape == omega.shape else 'count'} rad/s): "
                                  "give those directions modes")
    return omega


def frequency_response(system: Any, omega: Any, *, input: str | Sequence[str],  # noqa: A002
                       output: str | Sequence[str], operating_point: Any = None) -> FrequencyResponse:
    """Frequency response of a spatial chain's exact-field form between its ports, loops closed with exact delays.

    Parameters
    ----------
    system : SpatialModel or ControlledModel
        A controlled model's :class:`~ctmm.control.Feedback` loops ``u = -C(s) e^{-s tau} (y - r)`` are
        closed at every frequency (:func:`ctmm.exact_fields.form_response`).
    omega : array_like
        Angular frequencies [rad/s], >= 0.
    input : str or sequence of str
        Actuator port names (``"<joint>.torque"``, ``"<body>.<point>.force_x"`` ... world axes,
        ``"<body>.moment_body_x"`` ... body axes) or ``"<loop>.reference"``.
    output : str or sequence of str
        Sensor port names (``"<joint>.angle"``, ``"<body>.<point>.x"``, ``"<beam>.<station>.w_y"`` ...) or
        ``"<loop>.y"``, ``"<loop>.u"``.
    operating_point : None
        As for :func:`exact_form`.

    Returns
    -------
    FrequencyResponse
        ``response[i_out, i_in, k]``: output phasor per unit input phasor.
    """
    from .exact_fields import form_response
    from .saturation import refuse_saturation
    from .spatial.model import SpatialModel
    from .spatial.ports import SpatialPorts

    started = time.perf_counter()
    model, loops = (system, ()) if isinstance(system, SpatialModel) else (system.plant, tuple(system.loops))
    refuse_saturation(loops, "the frequency-domain verbs (fields='exact')")
    inputs = list(validation.names("input", input))
    outputs = list(validation.names("output", output))
    omega = validation.frequencies("omega", omega)
    form = exact_form(model, operating_point, omega_max=float(np.max(omega, initial=0.0)))
    if hasattr(form.chain, "on_branch"):       # a tree: inputs on the main path only
        driven = [n for n in inputs if n in form.actuators] + [n for lp in loops for n, _ in lp.actuator_terms]
        hung = [n for n in driven if any(form.chain.on_branch(term) for term, _ in form.actuator(n))]
        if hung:
            raise _refuse(model, f"actuators {hung} act on a branch of the tree (the exact tree takes inputs on its "
                                 "main path: the base and every body's first child)")
    response = form_response(form, loops, omega, inputs, outputs)
    ports = SpatialPorts(model)
    units = {name: ports.actuator_unit(name) for name in inputs if name in ports.actuators}
    units.update({name: ports.sensor_unit(name) for name in outputs if name in ports.sensors})
    info = {"method": "exact spatial beam fields (ctmm.spatial_exact_fields), Riccati transfer, delays exact",
            "wall_time_s": time.perf_counter() - started, "n_frequencies": int(omega.size),
            "chain_elements": len(getattr(form.chain, "elements", ())), "rigid_directions": list(form.rigid)}
    return FrequencyResponse(omega, response, tuple(inputs), tuple(outputs), model.name, info=info, units=units)
