"""Spatial body and joint terms on the one protocol (d = 6) and the :class:`SpatialScene` (issue 14).

Physics written once in :mod:`ctmm.ops` (numpy batched, casadi), solved by the one
:func:`ctmm.articulated.articulated_sweep` with ``Tree(..., dimension=6)``.  Point state
``A = [a (3) ; alpha (3)]`` (classical acceleration of a material point and angular acceleration,
world axes), ``F = [f (3) ; m (3)]`` (force and moment about the point, world axes, exerted by the
inboard side on the outboard side).  Derivations: ``docs/spatial.md``.

Every body's terms are taken about its **inboard point** ``P``: the material point of the child that
is at the parent's connection point at this instant (the child origin for revolute, universal,
spherical and weld joints; for prismatic, free and elastic joints the child point the joint's
translation has carried to ``P``), so that ``A_child = A_parent(P) + S a_rel + c`` holds exactly.
"""
from __future__ import annotations

from functools import partial
from typing import Any, Mapping, Sequence

import numpy as np

from ..articulated import Articulated, Tree, articulated_sweep
from ..errors import ModelError
from ..ops import NUMPY, Ops, batch_column, batch_scalars, batch_shape
from ..protocol import BodyTerms, JointTerms
from .body_motion import BodyState, ChildMotion, child_motion
from .frames import constant, cross, skew
from .joint_kinematics import AxisJointFamily, joint_motion
from .beam_terms import spatial_beam_terms
from .model import SpatialModel, input_values
from ..signals import signal_parameters, symbolic_signal

__all__ = ["rigid_body_terms", "SpatialScene", "BodyState", "ChildMotion", "child_motion"]


def rigid_body_terms(ops: Ops, *, mass: float, inertia: np.ndarray, center_of_mass: np.ndarray,
                     points: Mapping[str, np.ndarray], rotation: Any, offset: Any, omega: Any,
                     gravity: np.ndarray, loads: Sequence[tuple[np.ndarray, Any]] = ()) -> BodyTerms:
    """Newton-Euler terms of a rigid body about its inboard point ``P``.

    Parameters
    ----------
    mass : float
        [kg].
    inertia : (3, 3) array
        About the centre of mass in body axes [kg m^2].
    center_of_mass : (3,) array
        Body axes, from the body origin [m].
    points : mapping of name to (3,) array
        Outboard points in body axes [m].
    rotation : ops (3, 3)
        Body axes to world axes.
    offset : ops (3, 1) or None
        Body origin minus ``P`` in world axes [m] (``None``: the origin is ``P``).
    omega : ops (3, 1) or None
        Angular velocity in world axes [rad/s] (``None``: zero).
    gravity : (3,) array
        [m/s^2].
    loads : sequence of (point (3,) array in body axes, wrench ops (6, 1) world axes)
        Applied force [N] and moment [N m] at body points.

    Returns
    -------
    BodyTerms
        ``M = [[m I, -m [r_c]x], [m [r_c]x, I_P]]``, ``h`` the velocity, gravity and load terms,
        ``Kin[e] = [[I, -[r_e]x], [0, I]]``, ``c[e] = [omega x (omega x r_e) ; 0]``, ``RF[e] = Kin[e]^T``.
    """
    if ops.name == "numpy":
        return _numpy_rigid_body_terms(mass, inertia, center_of_mass, points, rotation, offset, omega, gravity, loads)

    def located(p: np.ndarray) -> Any:
        r = ops.matmul(rotation, constant(ops, p))
        return r if offset is None else r + offset

    r_c = located(center_of_mass)
    inertia_world = ops.matmul(ops.matmul(rotation, constant(ops, inertia)), ops.transpose(rotation))
    rc_x = skew(ops, r_c)
    eye = ops.eye(3)
    M = ops.block([[eye * mass, rc_x * -mass],
                   [rc_x * mass, inertia_world - ops.matmul(rc_x, rc_x) * mass]])
    g = constant(ops, gravity)
    h_lin = g * -mass
    h_ang = cross(ops, r_c, g) * -mass
    if omega is not None:
        centripetal = cross(ops, omega, cross(ops, omega, r_c))
        h_lin = h_lin + centripetal * mass
        h_ang = h_ang + cross(ops, omega, ops.matmul(inertia_world, omega)) + cross(ops, r_c, centripetal) * mass
    for point, wrench in loads:
        f = ops.sub(wrench, slice(0, 3), slice(0, 1))
        h_lin = h_lin - f
        h_ang = h_ang - ops.sub(wrench, slice(3, 6), slice(0, 1)) - cross(ops, located(point), f)
    Kin, c, RF = {}, {}, {}
    for name, p in points.items():
        r_e = located(p)
        accel = ops.zeros(3, 1) if omega is None else cross(ops, omega, cross(ops, omega, r_e))
        K = ops.block([[eye, skew(ops, r_e) * -1.0], [ops.zeros(3, 3), eye]])
        c[name] = ops.block([[accel], [ops.zeros(3, 1)]])
        Kin[name] = K
        RF[name] = ops.transpose(K)
    return BodyTerms(M=M, h=ops.block([[h_lin], [h_ang]]), Kin=Kin, c=c, RF=RF)


def _numpy_rigid_body_terms(mass: float, inertia: np.ndarray, center_of_mass: np.ndarray,
                            points: Mapping[str, np.ndarray], rotation: np.ndarray, offset: Any, omega: Any,
                            gravity: np.ndarray, loads: Sequence[tuple[np.ndarray, Any]]) -> BodyTerms:
    """:func:`rigid_body_terms` on numpy batches ``(B, r, c)``: the same operations on the same operands, the
    blocks filled into one allocation each in place of the block assembly (the batch of a result is that of
    its operands, as there)."""
    def located(p: np.ndarray) -> np.ndarray:
        r = np.matmul(rotation, np.asarray(p, dtype=float).reshape(3, 1))
        return r if offset is None else r + offset

    r_c = located(center_of_mass)
    M, inertia_world = _numpy_mass_matrix(mass, np.asarray(inertia, dtype=float), rotation, r_c)
    g = np.asarray(gravity, dtype=float).reshape(1, 3, 1)
    h_lin = g * -mass
    h_ang = cross(NUMPY, r_c, g) * -mass
    if omega is not None:
        centripetal = cross(NUMPY, omega, cross(NUMPY, omega, r_c))
        h_lin = h_lin + centripetal * mass
        h_ang = h_ang + cross(NUMPY, omega, np.matmul(inertia_world, omega)) + cross(NUMPY, r_c, centripetal) * mass
    for point, wrench in loads:
        f = wrench[..., 0:3, 0:1]
        h_lin = h_lin - f
        h_ang = h_ang - wrench[..., 3:6, 0:1] - cross(NUMPY, located(point), f)
    h = np.empty(batch_shape(h_lin, h_ang) + (6, 1),
                 dtype=np.result_type(h_lin, h_ang))
    h[..., :3, :] = h_lin
    h[..., 3:, :] = h_ang
    Kin, c, RF = {}, {}, {}
    for name, p in points.items():
        r_e = located(p)
        K = np.zeros(r_e.shape[:-2] + (6, 6), dtype=r_e.dtype)
        K[..., _DIAGONAL6, _DIAGONAL6] = 1.0
        K[..., :3, 3:] = skew(NUMPY, r_e) * -1.0
        if omega is None:
            c[name] = np.zeros((1, 6, 1))
        else:
            accel = cross(NUMPY, omega, cross(NUMPY, omega, r_e))
            c[name] = np.concatenate([accel, np.zeros(accel.shape[:-2] + (3, 1), dtype=accel.dtype)], axis=-2)
        Kin[name] = K
        RF[name] = K.swapaxes(-1, -2)
    return BodyTerms(M=M, h=h, Kin=Kin, c=c, RF=RF)


def _numpy_mass_matrix(mass: Any, inertia: np.ndarray, rotation: np.ndarray, r_c: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """``(M, I_world)`` of :func:`rigid_body_terms` on numpy, filled into one allocation (leading axes broadcast)."""
    inertia_world = np.matmul(np.matmul(rotation, inertia), rotation.swapaxes(-1, -2))
    rc_x = skew(NUMPY, r_c)
    lower = inertia_world - np.matmul(rc_x, rc_x) * mass
    M = np.empty(batch_shape(rc_x, lower) + (6, 6), dtype=lower.dtype)
    M[..., :3, :3] = _EYE3 * mass
    M[..., :3, 3:] = rc_x * -mass
    M[..., 3:, :3] = rc_x * mass
    M[..., 3:, 3:] = lower
    return M, inertia_world


def _numpy_family_terms(mass: np.ndarray, inertia: np.ndarray, columns: np.ndarray, rotation: np.ndarray,
                        offset: Any, omega: Any, gravity: np.ndarray, wrenches: Sequence[np.ndarray]
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, Any]:
    """:func:`rigid_body_terms` of a family of ``n`` rigid bodies at once on numpy (the same operations on the same
    operands as :func:`_numpy_rigid_body_terms`, every operand with a leading family axis; the located points of a
    body as the columns of one product, the cross products of equal operands as the columns of one call).

    Parameters
    ----------
    mass : (n, 1, 1, 1) array
        [kg].
    inertia : (n, 1, 3, 3) array
        About the centre of mass, body axes [kg m^2].
    columns : (n, 1, 3, 1 + L + P) array
        Body axes [m]: the centre of mass, the ``L`` load points, the ``P`` outboard points (padded with zeros).
    rotation : (n, B, 3, 3)
    offset, omega : (n, B, 3, 1) or None
        As in :func:`rigid_body_terms` (``None``: zero for every body).
    gravity : (3,) array
        [m/s^2].
    wrenches : sequence of ``L`` (n, B, 6, 1)
        Applied ``[f ; m]`` [N, N m] at the load points (world axes).

    Returns
    -------
    M (n, B, 6, 6), h (n, B, 6, 1), Kin (n, B, P, 6, 6) and c (n, B, P, 6, 1) (``(1, 6, 1)`` zeros: ``omega`` None).
    """
    located = np.matmul(rotation, columns)
    if offset is not None:
        located = located + offset
    loaded = 1 + len(wrenches)
    r_c = located[..., 0:1]
    M, inertia_world = _numpy_mass_matrix(mass, inertia, rotation, r_c)
    g = np.asarray(gravity, dtype=float).reshape(1, 3, 1)
    h_lin = g * -mass
    moving = located if loaded == 1 else np.concatenate([r_c, located[..., loaded:]], axis=-1)   # r_c, points
    if omega is None:
        h_ang = cross(NUMPY, r_c, g) * -mass
    else:
        accelerations = cross(NUMPY, omega, cross(NUMPY, omega, moving))
        centripetal = accelerations[..., 0:1]
        h_lin = h_lin + centripetal * mass
        arms = np.concatenate([r_c, omega, r_c], axis=-1)
        turned = cross(NUMPY, arms, np.concatenate([np.broadcast_to(g, r_c.shape), np.matmul(inertia_world, omega),
                                                    centripetal], axis=-1))
        h_ang = turned[..., 0:1] * -mass + turned[..., 1:2] + turned[..., 2:3] * mass
    if wrenches:
        forces = np.concatenate([wrench[..., 0:3, 0:1] for wrench in wrenches], axis=-1)
        moments = cross(NUMPY, located[..., 1:loaded], forces)
        for slot, wrench in enumerate(wrenches):
            h_lin = h_lin - forces[..., slot:slot + 1]
            h_ang = h_ang - wrench[..., 3:6, 0:1] - moments[..., slot:slot + 1]
    h = np.empty(batch_shape(h_lin, h_ang) + (6, 1), dtype=np.result_type(h_lin, h_ang))
    h[..., :3, :] = h_lin
    h[..., 3:, :] = h_ang
    points = moving[..., 1:].swapaxes(-1, -2)[..., None]          # (n, B, P, 3, 1)
    K = np.zeros(points.shape[:-2] + (6, 6), dtype=points.dtype)
    K[..., _DIAGONAL6, _DIAGONAL6] = 1.0
    K[..., :3, 3:] = skew(NUMPY, points) * -1.0
    if omega is None:
        return M, h, K, np.zeros((1, 6, 1))
    rows = accelerations[..., 1:].swapaxes(-1, -2)[..., None]
    c = np.zeros(rows.shape[:-2] + (6, 1), dtype=rows.dtype)
    c[..., :3, :] = rows
    return M, h, K, c


_EYE3 = np.eye(3)
_DIAGONAL6 = np.arange(6)


def _scalars(ops: Ops, values: Any, count: int) -> list:
    if ops.name == "numpy":
        return batch_scalars(values) if count else []
    return [values[i] for i in range(count)]


class SpatialScene:
    """A :class:`SpatialModel` as protocol terms: forward kinematics, body and joint terms, the sweep.

    Parameters
    ----------
    model : SpatialModel
    """

    def __init__(self, model: SpatialModel) -> None:
        if not isinstance(model, SpatialModel):
            raise ModelError(f"model must be a SpatialModel, got {model!r:.80}")
        self.model = model
        self.tree = Tree(model.parent, tuple(None if joint.parent is None else joint.point for joint in model.joints),
                         dimension=6)
        self._loads = [[load for load in model.loads if load.body == body.name] for body in model.bodies]
        used = [set() for _ in model.bodies]                    # outboard points that carry a child
        for j, joint in enumerate(model.joints):
            if model.parent[j] >= 0:
                used[model.parent[j]].add(joint.point)
        self._outboard = [{name: p for name, p in body.points.items() if name in names}
                          for body, names in zip(model.bodies, used)]
        self._families: dict = {}           # members -> their stacked numbers (:meth:`_rigid_family_terms`)
        # numpy constants of the joints, formed once: each joint frame (1, 3, 3) and its point on the parent (1, 3, 1)
        self._joint_frames = [constant(NUMPY, joint.rotation) for joint in model.joints]
        self._joint_points = [constant(NUMPY, joint.point if par < 0 else model.bodies[par].points[joint.point])
                              for joint, par in zip(model.joints, model.parent)]       # at the ground: its place
        for value in self._joint_frames + self._joint_points:      # shared by every call: read-only
            value.flags.writeable = False
        kinds: dict = {}                    # revolute and prismatic joints (not driven, no nonlinear law) by kind
        for j, joint in enumerate(model.joints):
            if joint.kind in ("revolute", "prismatic") and not joint.driven and joint.law is None:
                kinds.setdefault(joint.kind, []).append(j)
        self._joint_families = [(members, AxisJointFamily(*zip(*((model.joints[j], model.layout[j].position.start,
                                                                   model.layout[j].velocity.start) for j in members))))
                                for members in kinds.values() if len(members) > 1]

    def terms(self, ops: Ops, q: Any, v: Any, t: float = 0.0, inputs: Mapping[str, Any] | None = None,
              wrenches: Mapping[int, Sequence[tuple[np.ndarray, Any]]] | None = None, turn: Any = None,
              driven: Mapping[int, tuple[list, list]] | None = None, kinematics_only: bool = False
              ) -> tuple[list[BodyTerms | None], list[JointTerms], list[BodyState]]:
        """Body terms, joint terms (world axes) and body states at ``(q, v, t)``.

        Parameters
        ----------
        q, v : numpy ``(B, nq)``, ``(B, nv)`` or casadi columns
        t : float or casadi symbol
            Time [s] (signals of loads and driven joints: their values; at a symbol their symbolic forms).
        inputs : mapping of input name to ops column ``(k, 1)`` (numpy ``(B, k, 1)``), optional
        wrenches : mapping of body index to a list of (point (3,) body axes [m], ops column (6, 1)
            ``[f ; m]`` world axes [N, N m]), optional
            Extra applied loads (the body-force actuators of :mod:`ctmm.spatial.ports`); an entry
            ``(point, column, "body")`` has ``[f ; m]`` in the body's axes.
        turn : ops column (3, 1) (numpy ``(B, 3, 1)``), optional
            A rotation ``delta`` [rad] (world axes) applied to every body's terms to first order -- its axes
            ``R + [delta]x R`` and its origin about its inboard point -- but not to the states the children
            are placed by: the complex step of ``i h e_k`` gives each body's ``d(terms)/d(phi_k)`` (the
            rotation columns of the frequency context's stiffness, :mod:`ctmm.spatial_transfer_response`).
        driven : mapping of joint index to (positions, rates), optional
            Values (lists of ops scalars [rad, m; rad/s, m/s]) taking the place of a driven joint's position and
            rate signals at ``t`` (its acceleration stays the signal's): symbols standing for the prescribed motion,
            so that generated code can differentiate the kinematics along it
            (:mod:`ctmm.compiled_spatial_kinematic_loops`).
        kinematics_only : bool
            For callers that want the body states alone (poses, sensors, energy): a rigid body's terms are
            not formed (``None`` in their place; a beam's are, its points' frames come with them).
        """
        model = self.model
        inputs = inputs or {}
        qs, vs = _scalars(ops, q, model.n_positions), _scalars(ops, v, model.n_velocities)
        states: list[BodyState] = []
        point_frames: list[dict] = []
        bodies, joints, pending = [], [], []
        motions: dict = {}                          # numpy: the joint families' motions, each family at once
        numpy = ops.name == "numpy"
        if numpy and self._joint_families:
            q_rows, v_rows = (values if np.ndim(values) == 2 else np.asarray(values)[None] for values in (q, v))
            for members, family in self._joint_families:
                motions.update(zip(members, family.motions(q_rows, v_rows, inputs)))
        for j, (body, joint, layout) in enumerate(zip(model.bodies, model.joints, model.layout)):
            rel = motions.get(j)
            if rel is None:
                if joint.driven:
                    qj = [_signal_column(ops, [f], t) for f in joint.position]
                    vj = [_signal_column(ops, [f], t) for f in joint.rate]
                    acc = [_signal_column(ops, [f], t) for f in joint.acceleration]
                    if driven is not None and j in driven:
                        qj, vj = list(driven[j][0]), list(driven[j][1])
                else:
                    qj, vj, acc = qs[layout.position], vs[layout.velocity], None
                u = inputs.get(joint.inputs[0]) if joint.inputs else None
                rel = joint_motion(ops, joint, qj, vj, u, acc)
            par = model.parent[j]
            if par < 0:
                R_p, o_p, v_p, w_p = None, None, None, None
                P = self._joint_points[j] if numpy else constant(ops, joint.point)
                v_P = None
            else:
                ps = states[par]
                R_p, o_p, v_p, w_p = ps.rotation, ps.origin, ps.velocity, ps.omega
                frame = point_frames[par].get(joint.point)
                if frame is None:
                    arm = ops.matmul(R_p, self._joint_points[j] if numpy else
                                     constant(ops, model.bodies[par].points[joint.point]))
                    P = o_p + arm
                    v_P = v_p + cross(ops, w_p, arm)
                else:                                   # a beam point: its frame follows the deformation
                    P, v_P = o_p + frame.arm, v_p + frame.velocity
                    R_p, w_p = frame.rotation, frame.omega
            motion = child_motion(ops, self._joint_frames[j] if numpy else joint.rotation, rel, R_p, P, v_P, w_p)
            states.append(motion.state)
            joints.append(motion.joint)
            R_c, offset, w_c = motion.state.rotation, motion.offset, motion.omega
            if kinematics_only and model.modal[j] is None:      # a rigid body's state needs no terms of it
                point_frames.append({})
                bodies.append(None)
                continue
            if turn is not None:                    # the body's terms turned by delta, its state as it is
                R_c = R_c + ops.matmul(skew(ops, turn), R_c)
                offset = None if offset is None else offset + cross(ops, turn, offset)
            loads = []
            for load in self._loads[j]:
                wrench = _signal_column(ops, load.force + load.moment, t)
                if load.axes == "body":
                    wrench = _turned_wrench(ops, R_c, wrench)
                loads.append((body.points[load.point], wrench))
            for entry in (wrenches or {}).get(j, ()):       # (point, [f ; m] world) or (point, [f ; m], "body")
                wrench = entry[1]
                if len(entry) > 2 and entry[2] == "body":
                    wrench = _turned_wrench(ops, R_c, wrench)
                loads.append((entry[0], wrench))
            modal = model.modal[j]
            if modal is not None:
                form = getattr(body, "spatial_terms", None) or partial(spatial_beam_terms, beam=body)  # or ctmm.fem's
                arguments = dict(omega=w_c, eta=_modal(ops, q, modal.position), eta_dot=_modal(ops, v, modal.velocity),
                                 t=t, gravity=model.gravity, loads=loads, points=self._outboard[j])
                terms, frames = form(ops, rotation=R_c, offset=offset, frames=tuple(self._outboard[j]), **arguments)
                if turn is not None:                # the frames the children are placed by: not turned
                    frames = form(ops, rotation=motion.state.rotation, offset=motion.offset,
                                  frames=tuple(self._outboard[j]), **arguments)[1]
                bodies.append(terms)
                point_frames.append(frames)
                continue
            point_frames.append({})
            if ops.name == "numpy":                 # the rigid bodies' terms after the tree, per family at once
                pending.append((j, R_c, offset, w_c, loads))
                bodies.append(None)
                continue
            bodies.append(rigid_body_terms(ops, mass=body.mass, inertia=body.inertia,
                                           center_of_mass=body.center_of_mass, points=self._outboard[j], rotation=R_c,
                                           offset=offset, omega=w_c, gravity=model.gravity, loads=loads))
        groups: dict = {}                           # rigid bodies by their number of loads: one evaluation each
        for entry in pending:
            groups.setdefault(len(entry[4]), []).append(entry)
        for members in groups.values():
            for j, terms in zip((entry[0] for entry in members), self._rigid_family_terms(members)):
                bodies[j] = terms
        return bodies, joints, states

    def _rigid_family_terms(self, members: list) -> list[BodyTerms]:
        """The numpy terms of rigid bodies ``(j, rotation, offset, omega, loads)`` with equal numbers of loads: one
        :func:`_numpy_family_terms` over the bodies stacked on a leading axis (their numbers stacked once per
        family), split into each body's terms (views); one body: :func:`rigid_body_terms`."""
        model = self.model
        if len(members) == 1:
            j, rotation, offset, omega, loads = members[0]
            body = model.bodies[j]
            return [rigid_body_terms(NUMPY, mass=body.mass, inertia=body.inertia, center_of_mass=body.center_of_mass,
                                     points=self._outboard[j], rotation=rotation, offset=offset, omega=omega,
                                     gravity=model.gravity, loads=loads)]
        key = tuple(entry[0] for entry in members) + tuple(np.asarray(p, dtype=float).tobytes() for entry in members
                                                           for p, *_ in entry[4])
        family = self._families.get(key)
        if family is None:
            if len(self._families) > 64:                # load points change from call to call: no growth
                self._families.clear()
            bodies = [model.bodies[j] for j, *_ in members]
            count, zero = max(len(self._outboard[j]) for j, *_ in members), (0.0, 0.0, 0.0)
            columns = np.array([[body.center_of_mass, *(point for point, *_ in loads), *self._outboard[j].values(),
                                 *(zero,) * (count - len(self._outboard[j]))]
                                for body, (j, _, _, _, loads) in zip(bodies, members)], dtype=float)
            columns = columns.reshape(len(members), 1, -1, 3).swapaxes(-1, -2)
            family = self._families[key] = (
                np.array([body.mass for body in bodies], dtype=float).reshape(-1, 1, 1, 1),
                np.array([body.inertia for body in bodies], dtype=float).reshape(-1, 1, 3, 3), columns)
        mass, inertia, columns = family
        rotation = _stacked([entry[1] for entry in members], (3, 3))
        offset = _stacked([entry[2] for entry in members], (3, 1))
        omega = _stacked([entry[3] for entry in members], (3, 1))
        wrenches = [_stacked([entry[4][slot][1] for entry in members], (6, 1)) for slot in range(len(members[0][4]))]
        M, h, K, c = _numpy_family_terms(mass, inertia, columns, rotation, offset, omega, model.gravity, wrenches)
        out = []
        for k, (j, *_) in enumerate(members):
            Kin = {name: K[k, ..., slot, :, :] for slot, name in enumerate(self._outboard[j])}
            out.append(BodyTerms(M[k], h[k], Kin, {name: c if omega is None else c[k, ..., slot, :, :]
                                                   for slot, name in enumerate(self._outboard[j])},
                                 {name: value.swapaxes(-1, -2) for name, value in Kin.items()}))
        return out

    def sweep(self, ops: Ops, q: Any, v: Any, t: float = 0.0, inputs: Mapping[str, Any] | None = None,
              wrenches: Mapping[int, Sequence[tuple[np.ndarray, Any]]] | None = None) -> Articulated:
        """The one articulated sweep (explicit context) at ``(q, v, t)`` (``wrenches`` as in :meth:`terms`)."""
        bodies, joints, _ = self.terms(ops, q, v, t, inputs, wrenches)
        return articulated_sweep(ops, self.tree, bodies, joints)

    def velocity_rates(self, solution: Articulated) -> list:
        """``v_dot`` pieces (one ops column per non-driven, non-welded joint, then one per beam: its modal
        accelerations; in state order)."""
        model = self.model
        joints = [solution.relative[j] for j, joint in enumerate(model.joints) if not joint.driven and joint.kind != "weld"]
        return joints + [_modal_rows(solution.x[j]) for j, layout in enumerate(model.modal) if layout is not None]

    def numpy_inputs(self, inputs: Mapping[str, Any] | None, t: float, batch: int) -> dict:
        """Actuator inputs at ``t`` as numpy batched columns ``(B, k, 1)``."""
        return {name: batch_column(value) for name, value in input_values(self.model, inputs, t, batch).items()}

    def solve(self, q: Any, v: Any, t: float = 0.0, inputs: Mapping[str, Any] | None = None,
              wrenches: Mapping[int, Sequence[tuple[np.ndarray, Any]]] | None = None) -> Articulated:
        """Numpy sweep of a batch ``q (B, nq)``, ``v (B, nv)`` (inputs as in :func:`input_values`,
        ``wrenches`` as in :meth:`terms`)."""
        q, v = self.model.check_state(q, v)
        return self.sweep(NUMPY, q, v, t, self.numpy_inputs(inputs, t, q.shape[0]), wrenches)


def _stacked(values: list, shape: tuple[int, int]) -> Any:
    """Numpy ops values ``(B, *shape)`` (or ``None``: zero) of a family's bodies stacked on a leading axis
    ``(n, B, *shape)`` (their batches broadcast); ``None`` when every one is ``None``."""
    present = [value for value in values if value is not None]
    if not present:
        return None
    lead = batch_shape(*present)
    if len(present) < len(values) or any(value.shape[:-2] != lead for value in present):
        dtype = np.result_type(*present)
        values = [np.zeros(lead + shape, dtype=dtype) if value is None else np.broadcast_to(value, lead + shape)
                  for value in values]
    return np.stack(values)


def _turned_wrench(ops: Ops, rotation: Any, wrench: Any) -> Any:
    """``[R f ; R m]`` of a wrench ``[f ; m]`` (6, 1) given in the axes ``rotation`` turns to world axes."""
    if ops.name == "numpy":                     # both halves in one product (the same entries)
        pair = np.matmul(rotation[..., None, :, :], wrench.reshape(wrench.shape[:-2] + (2, 3, 1)))
        return pair.reshape(pair.shape[:-3] + (6, 1))
    return ops.block([[ops.matmul(rotation, ops.sub(wrench, slice(0, 3), slice(0, 1)))],
                      [ops.matmul(rotation, ops.sub(wrench, slice(3, 6), slice(0, 1)))]])


def _signal_column(ops: Ops, signals: Sequence[Any], t: Any) -> Any:
    """Time ``signals`` at ``t`` as an ops column ``(k, 1)``: their values at a number ``t`` [s]; at a casadi
    time symbol (generated code, :mod:`ctmm.compiled_spatial_signals`) their symbolic forms
    (:func:`ctmm.signals.symbolic_signal`, which refuses a user callable)."""
    if type(t).__module__.split(".")[0] != "casadi":           # a number (float, numpy scalar or 0-d array)
        return constant(ops, [[float(f(t))] for f in signals])
    import casadi as ca

    return ca.vertcat(*[symbolic_signal(type(f), t, signal_parameters(f) or ()) for f in signals])


def _modal(ops: Ops, values: Any, rows: slice) -> Any:
    """Modal coordinates (or rates) ``values[rows]`` as an ops column."""
    if ops.name == "numpy":
        return np.asarray(values)[:, rows, None]
    return values[rows.start:rows.stop]


def _modal_rows(x: Any) -> Any:
    """``eta''``: the rows of a beam's ``x = [A_in (6) ; eta'']`` after the point state."""
    return x[..., 6:, :] if isinstance(x, np.ndarray) else x[6:, :]
