"""Closed kinematic loops in spatial models: cut joints whose loads are the boundary unknowns.

A spatial mechanism with closed loops (a spatial four-bar, a ring of bodies) is modelled as a spanning tree --
an ordinary :class:`~ctmm.spatial.model.SpatialModel` -- plus **cut joints** (:class:`SpatialCutJoint`): a
spherical (ball) cut makes a point of the child coincide with a point of the parent (or of the ground); a
revolute cut also keeps a child axis parallel to a parent axis, a universal (Hooke) cut a child axis
perpendicular to a parent axis; a prismatic (slider) cut keeps the child point on a parent-fixed line and the
child's orientation fixed relative to the parent.  The planar counterpart and the derivation are
in :mod:`ctmm.planar.closed_loops` and ``docs/closed_loops.md`` (section 8 for this module).

Mechanism (the boundary unknowns of the mixed transfer matrix method)
---------------------------------------------------------------------
A cut has ``3`` (spherical), ``4`` (universal) or ``5`` (revolute, prismatic) constraint rows: the separation of
its points ``Phi = d = r_Pc - r_Pp`` [m] (prismatic: only ``d . p_j`` along the two parent-fixed ``p_1``, ``p_2``
perpendicular to the slide axis) and the alignments ``Phi_i = u_i . b_i`` of child-fixed ``u_i`` and parent-fixed
``b_i`` (revolute: ``u`` the child axis, ``b_1``, ``b_2`` perpendicular to the parent axis; universal: ``b_1`` the
parent axis; prismatic: the revolute pair plus ``u_3`` the child ``normal``, ``b_3 = parent_axis x parent_normal``;
small angles [rad]).  Their rates are linear in the tree velocities ``v``: ``Phi' = v_Pc - v_Pp`` (prismatic:
``(v_Pc - v_Pp) . p_j + d . (omega_p x p_j)``) and ``Phi_i' = (omega_c - omega_p) . n_i`` with ``n_i = u_i x b_i``.
The dual loads -- the unknowns ``lambda`` -- are a force (world axes [N]; prismatic: ``lambda_j p_j``) on the child
point and its opposite on the parent at the same place, and moments ``mu_i n_i`` [N m] on the child and their
opposites on the parent.  At fixed
``(q, v, t)`` the tree's articulated sweep (:func:`ctmm.spatial.dynamics.solve`) is affine in these loads, so one
batched sweep with ``1 + m`` load cases gives ``Phi'' = c_0 + G lambda`` (``G``: the ``m x m`` boundary
compliance, exact) and ``v' = v'_0 + D lambda``; the constraint at the acceleration level with Baumgarte
stabilisation (rate ``alpha`` [1/s])::

    G lambda = -c_0 - 2 alpha Phi' - alpha^2 Phi

Drift of ``Phi`` is held by Baumgarte and, in the fixed-step RK4, by projection after every step (Gauss-Newton
on ``Phi = 0`` along ``q (+) dx`` with the exact velocity Jacobian ``J = dPhi'/dv``, then ``v <- v - J^+ J v``);
it is reported with the cut loads (:class:`SpatialLoopSimulation`).  Linearisation and natural frequencies
about an equilibrium on the constraint manifold: :mod:`ctmm.spatial.closed_loop_linear`.

Scope: cut points on rigid bodies, and for spherical, revolute and universal cuts also on
:class:`~ctmm.spatial.beam.SpatialBeam` points and ``ctmm.fem`` spatial subsystem boundary nodes (the deformed point
and its cross-section, the loads point loads of the body: :mod:`ctmm.spatial.cut_points`; prismatic cuts there
refused by name).  A revolute or
prismatic cut may carry a law and an actuation on its free coordinate (the angle about the axis, the slide along it;
:func:`~ctmm.spatial.closed_loop_cuts.cut_coordinate`): an applied load of the tree added with the cut loads in every
load case, so the boundary compliance is unchanged; or be driven: that coordinate prescribed by one more row, its load
one more unknown (``docs/closed_loops.md`` §8.1a).  The tree may have any joints,
actuators and loads.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any, Mapping, Sequence

import numpy as np

from .. import validation
from ..articulated import SingularPivotError, articulated_sweep
from ..errors import ModelError, SimulationError, unknown_name
from ..loop_integration import CONDITION_LIMIT, PROJECTION_SKIP, compliance_condition, singular_compliance
from ..ops import NUMPY
from .body_forms import SpatialScene
from .cut_points import CutSide, resolve_side, side_acceleration, side_frame, side_point
from .closed_loop_cuts import (CUT_KINDS, LAW_KINDS, CutActuatedInputs, CutFrame, SpatialCutJoint, cross, cut_coordinate,
                               cut_frame, relative_rotation, spherical_law_moment)
from .integrate import initial_state
from .model import SpatialModel
from .ports import SpatialInputs

__all__ = ["SpatialCutJoint", "SpatialKinematicLoopModel", "CUT_KINDS"]


class SpatialKinematicLoopModel:
    """A spatial spanning tree plus cut joints (module docstring).

    Parameters
    ----------
    tree : SpatialModel
        The mechanism with the cut joints removed.
    cuts : sequence of SpatialCutJoint
        The joints closing the loops.
    baumgarte : float
        Stabilisation rate ``alpha`` [1/s] (>= 0; 0: none).  Default 20.

    Raises
    ------
    ModelError
        Not a spatial tree, no cuts, unknown bodies or points, prismatic cuts at beam or subsystem points, duplicate names.
    """

    def __init__(self, tree: SpatialModel, cuts: Sequence[SpatialCutJoint], *, baumgarte: float = 20.0) -> None:
        if not isinstance(tree, SpatialModel):
            raise ModelError(f"SpatialKinematicLoopModel: tree must be a ctmm.spatial.SpatialModel, got {tree!r:.80}")
        cuts = tuple(cuts) if isinstance(cuts, (list, tuple)) else (cuts,)
        if not cuts or not all(isinstance(c, SpatialCutJoint) for c in cuts):
            raise ModelError(f"SpatialKinematicLoopModel: cuts must be a non-empty sequence of SpatialCutJoint, got "
                             f"{cuts!r:.120}")
        taken = {b.name for b in tree.bodies} | {j.name for j in tree.joints} | {ld.name for ld in tree.loads}
        for k, cut in enumerate(cuts):
            if cut.name in taken or cut.name in {c.name for c in cuts[:k]}:
                raise ModelError(f"SpatialKinematicLoopModel: duplicate name {cut.name!r} (cut joint names must "
                                 "differ from each other and from the tree's elements)")
        self.tree, self.cuts = tree, cuts
        self.name = tree.name
        self.baumgarte = validation.nonnegative("baumgarte", baumgarte)
        self._sides = [(resolve_side(tree, cut, cut.parent, cut.point), resolve_side(tree, cut, cut.child, cut.child_point))
                       for cut in cuts]
        self.deformable_cuts = tuple(cut.name for cut, sides in zip(cuts, self._sides) if any(s.deformable for s in sides))
        """Names of the cuts with a side on a SpatialBeam or ``ctmm.fem`` subsystem point (spherical only)."""
        self._frames = [cut_frame(cut) for cut in cuts]
        self.n_constraints = sum(cut.n_rows for cut in cuts)
        self._scene = SpatialScene(tree)
        self.linear_cache: dict = {}
        """Tangents of :func:`ctmm.spatial.closed_loop_linear.tangent` by ``(q0, t, step, baumgarte)`` (the last 8:
        the frequency verbs ask for the same tangent repeatedly)."""

    def __repr__(self) -> str:
        return f"SpatialKinematicLoopModel({self.name!r}, cuts={[cut.name for cut in self.cuts]})"

    # -- kinematics ------------------------------------------------------------------------------------
    def state(self, x0: Any = None, v0: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """``(q, v)`` from arrays or ``{coordinate: value}`` / ``{velocity: value}`` mappings over the tree's
        neutral state (:func:`ctmm.spatial.integrate.initial_state`)."""
        x = initial_state(self.tree, x0, v0)
        return x[:self.tree.n_positions].copy(), x[self.tree.n_positions:].copy()

    def _bodies(self, q: np.ndarray, v: np.ndarray, t: float) -> list[tuple[np.ndarray, ...]]:
        """Per body ``(R, origin, velocity of the origin, omega, inboard point)`` (world, batched ``(B, ...)``; on a
        deformable body also its internal coordinates and their rates ``(B, n)``)."""
        q, v = self.tree.check_state(q, v)
        return self._states(self._scene.terms(NUMPY, q, v, t, kinematics_only=True)[2], q, v)

    def _states(self, states: list, q: np.ndarray, v: np.ndarray) -> list[tuple[np.ndarray, ...]]:
        """:meth:`_bodies` of the body states of :meth:`SpatialScene.terms` at ``q``, ``v`` ``(B, ...)``."""
        out, batch = [], q.shape[0]
        for s, modal in zip(states, self.tree.modal):
            parts = tuple(np.broadcast_to(np.asarray(a), (batch,) + np.asarray(a).shape[1:]).reshape(batch, -1)
                          if k else np.broadcast_to(np.asarray(a), (batch, 3, 3))
                          for k, a in enumerate((s.rotation, s.origin, s.velocity, s.omega, s.inboard)))
            out.append(parts if modal is None else parts + (q[:, modal.position], v[:, modal.velocity]))
        return out

    @staticmethod
    def _point(bodies: list, side: CutSide) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """World position, velocity (``(B, 3)``) and rotation ``(B, 3, 3)`` of a cut side (ground: fixed)."""
        return side_point(bodies, side)

    def _rows(self, bodies: list, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``Phi`` and ``Phi'`` ``(B, m)`` from body states (:meth:`_bodies`) at time ``t`` [s] (a driven cut's row
        ``s - position(t)``)."""
        phi, rate = [], []
        for cut, (parent, child), frame in zip(self.cuts, self._sides, self._frames):
            xp, vp, _ = self._point(bodies, parent)
            xc, vc, _ = self._point(bodies, child)
            (Rp, omega_p), (Rc, omega_c) = side_frame(bodies, parent), side_frame(bodies, child)
            omega_p = np.broadcast_to(omega_p, omega_c.shape)

            def parent_fixed(b_local: np.ndarray) -> np.ndarray:
                return np.broadcast_to(b_local, omega_c.shape) if Rp is None else Rp @ b_local

            if frame.basis is None:
                phi.append(xc - xp)
                rate.append(vc - vp)
            for b_local in frame.basis or ():
                b = parent_fixed(b_local)
                phi.append(np.sum((xc - xp) * b, axis=-1, keepdims=True))
                rate.append(np.sum((vc - vp) * b + (xc - xp) * cross(omega_p, b), axis=-1, keepdims=True))
            for u_local, b_local in frame.pairs:
                u, b = Rc @ u_local, parent_fixed(b_local)
                phi.append(np.sum(u * b, axis=-1, keepdims=True))
                rate.append(np.sum((omega_c - omega_p) * cross(u, b), axis=-1, keepdims=True))
            if cut.driven:
                value, value_rate, _ = cut_coordinate(cut, Rp, Rc, xc - xp, vc - vp, omega_p, omega_c)
                phi.append((value - float(cut.position(t)))[:, None])
                rate.append((value_rate - float(cut.rate(t)))[:, None])
        batch = max(max(a.shape[0] for a in phi), max(a.shape[0] for a in rate))
        return (np.concatenate([np.broadcast_to(a, (batch, a.shape[1])) for a in phi], axis=1),
                np.concatenate([np.broadcast_to(a, (batch, a.shape[1])) for a in rate], axis=1))

    def constraints(self, q: Any, v: Any, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """``Phi`` (separations [m], alignments [rad]) and ``Phi'`` [m/s, rad/s] of every cut, stacked ``(m,)``."""
        phi, rate = self._rows(self._bodies(np.asarray(q, float), np.asarray(v, float), t), t)
        return phi[0], rate[0]

    def jacobian(self, q: Any, t: float = 0.0) -> np.ndarray:
        """``J = dPhi'/dv`` ``(m, nv)``: ``Phi'`` is affine in ``v`` (linear without driven joints), so column ``k``
        is ``Phi'(q, e_k) - Phi'(q, 0)`` (one batched pass of the tree's kinematics).  ``dPhi = J dx`` along
        ``q (+) dx`` (:meth:`retract`)."""
        q = np.asarray(q, float)
        return self._rows_and_jacobian(q, np.zeros(self.tree.n_velocities), t)[2]

    @property
    def n_velocities(self) -> int:
        """The size of the tree's velocity space (:mod:`ctmm.loop_manifold` protocol)."""
        return self.tree.n_velocities

    def retract(self, q: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """``q (+) dx``: the tree coordinates moved by the velocity-space increment ``dx`` (``q + G(q) dx``,
        quaternions renormalised; first order in ``dx``)."""
        return self.tree.normalized(q + self.tree.position_rates(q[None], dx[None])[0])

    # -- the boundary unknowns ---------------------------------------------------------------------------
    def _accelerations(self, bodies: list, A: np.ndarray, rates: np.ndarray, t: float) -> np.ndarray:
        """``Phi''`` ``(B, m)`` from the inboard point accelerations ``A`` ``(B, n_bodies, 6)`` (``[a ; alpha]``,
        world) and ``v'`` ``(B, nv)`` of a batched sweep at one state (body states :meth:`_bodies`) at time ``t``
        [s]."""
        rows = []
        for cut, (parent, child), frame in zip(self.cuts, self._sides, self._frames):
            xp, vp, ap, alpha_p = side_acceleration(bodies, parent, A, rates)
            xc, vc, ac, alpha_c = side_acceleration(bodies, child, A, rates)
            (Rp, omega_p), (Rc, omega_c) = side_frame(bodies, parent), side_frame(bodies, child)
            Rc, omega_c, omega_p = Rc[0], omega_c[0], omega_p[0]

            def parent_fixed(b_local: np.ndarray) -> np.ndarray:
                return b_local if Rp is None else Rp[0] @ b_local

            if frame.basis is None:
                rows.append(ac - ap)
            def point_row(b: np.ndarray) -> np.ndarray:
                """``(d . b)''`` with ``d = xc - xp`` and the parent-fixed ``b`` (world), ``b' = omega_p x b``."""
                spin = cross(omega_p, b)
                return ((ac - ap) @ b + 2.0 * (vc - vp) @ spin + cross(alpha_p, b) @ (xc - xp)
                        + (xc - xp) @ cross(omega_p, spin))[:, None]

            rows.extend(point_row(parent_fixed(b_local)) for b_local in frame.basis or ())
            for u_local, b_local in frame.pairs:
                u, b = Rc @ u_local, parent_fixed(b_local)
                n = cross(u, b)
                n_dot = cross(cross(omega_c, u), b) + cross(u, cross(omega_p, b))
                rows.append(((alpha_c - alpha_p) @ n + (omega_c - omega_p) @ n_dot)[:, None])
            if cut.driven and cut.kind == "revolute":      # ((omega_c - omega_p) . a)' with a = R_c axis
                a = Rc @ cut.axis
                rows.append(((alpha_c - alpha_p) @ a + (omega_c - omega_p) @ cross(omega_c, a))[:, None]
                            - float(cut.acceleration(t)))
            elif cut.driven:                                 # the slide (d . a)'' along the guide a
                rows.append(point_row(parent_fixed(cut.parent_axis)) - float(cut.acceleration(t)))
        return np.concatenate(rows, axis=1)

    def _law_wrenches(self, bodies: list, t: float, extra: Mapping[str, float] | None = None
                      ) -> list[np.ndarray | None]:
        """Per cut: ``[force ; moment]`` (world) of its law and actuation on the child, ``f a`` along the cut's
        coordinate (:func:`~ctmm.spatial.closed_loop_cuts.cut_coordinate`; prismatic: a force at the child point),
        the parent taking the opposite at the same place; ``None`` for a smooth cut (``bodies``: :meth:`_bodies`);
        ``extra``: port loads ``u`` by cut name added (:class:`~ctmm.spatial.closed_loop_cuts.CutActuatedInputs`)."""
        out: list[np.ndarray | None] = []
        extra = extra or {}
        for cut, (parent, child) in zip(self.cuts, self._sides):
            if not cut.has_law and cut.name not in extra:
                out.append(None)
                continue
            if cut.kind == "spherical":
                out.append(self._spherical_law_wrench(bodies, cut, parent, child, t))
                continue
            coordinate, rate, a = self._coordinate(bodies, cut, parent, child)
            load = (cut.load(coordinate, rate, t) if cut.has_law else 0.0) + float(extra.get(cut.name, 0.0))
            out.append(np.concatenate([np.zeros(3), load * a]) if cut.kind == "revolute" else
                       np.concatenate([load * a, np.zeros(3)]))
        return out

    def _spherical_law_wrench(self, bodies: list, cut: SpatialCutJoint, parent: CutSide, child: CutSide, t: float
                              ) -> np.ndarray:
        """``[0 ; m]`` (world) of a spherical cut's law on the child
        (:func:`~ctmm.spatial.closed_loop_cuts.spherical_law_moment`) at the first state of ``bodies``."""
        Rp = None if parent.body < 0 else bodies[parent.body][0][0]
        omega_p = np.zeros(3) if parent.body < 0 else bodies[parent.body][3][0]
        moment = spherical_law_moment(cut, Rp, bodies[child.body][0][0], omega_p, bodies[child.body][3][0], t)
        return np.concatenate([np.zeros(3), moment])

    def _coordinate(self, bodies: list, cut: SpatialCutJoint, parent: CutSide, child: CutSide
                    ) -> tuple[float, float, np.ndarray]:
        """:func:`~ctmm.spatial.closed_loop_cuts.cut_coordinate` of one cut at the first state of ``bodies``."""
        xp, vp, _ = self._point(bodies, parent)
        xc, vc, _ = self._point(bodies, child)
        (Rp, omega_p), (Rc, omega_c) = side_frame(bodies, parent), side_frame(bodies, child)
        value, rate, a = cut_coordinate(cut, None if Rp is None else Rp[0], Rc[0], xc[0] - xp[0], vc[0] - vp[0],
                                        omega_p[0], omega_c[0])
        return float(value), float(rate), a

    @property
    def actuation_names(self) -> tuple[str, ...]:
        """``"<cut>.torque"`` (revolute) and ``"<cut>.force"`` (prismatic) of the undriven revolute and prismatic cuts:
        a unit load along the cut's coordinate, inputs of the linearisation (:meth:`actuation_inputs`)."""
        return tuple(f"{cut.name}.{'torque' if cut.kind == 'revolute' else 'force'}" for cut in self.cuts
                     if cut.kind in LAW_KINDS and not cut.driven)

    def actuation_inputs(self, name: str, q: Any, t: float = 0.0) -> SpatialInputs:
        """The unit load ``a`` along the coordinate of the cut named by ``name`` (:attr:`actuation_names`) at the
        configuration ``q``, as the tree's actuator values: on the child at its point, its opposite on the parent (a
        prismatic cut's at the child point); world axes, so valid at ``q`` (the linearisation's operating point)."""
        if name not in self.actuation_names:
            raise ModelError(f"cut actuation input: {name!r} is not one of {list(self.actuation_names)} of "
                             f"{self.name!r}")
        k = [cut.name for cut in self.cuts].index(name.rpartition(".")[0])
        (parent, child), cut = self._sides[k], self.cuts[k]
        bodies = self._bodies(np.asarray(q, float), np.zeros(self.tree.n_velocities), t)
        a = np.broadcast_to(self._coordinate(bodies, cut, parent, child)[2], (3,))
        load = np.concatenate([np.zeros(3), a] if cut.kind == "revolute" else [a, np.zeros(3)])
        wrenches = {child.body: [(child.point, load.reshape(1, 6, 1))]}
        if parent.body >= 0:
            R, origin = bodies[parent.body][0][0], bodies[parent.body][1][0]
            at = parent.point if cut.kind == "revolute" else R.T @ (self._point(bodies, child)[0][0] - origin)
            wrenches[parent.body] = [(at, -load.reshape(1, 6, 1))]
        return SpatialInputs({}, wrenches, checked=True)

    def cut_coordinates(self, q: Any, v: Any, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """The coordinate across every revolute or prismatic cut (angle [rad] or slide [m]; NaN for the other kinds)
        and its rate, each ``(n_cuts,)`` (:func:`~ctmm.spatial.closed_loop_cuts.cut_coordinate`)."""
        bodies = self._bodies(np.asarray(q, float), np.asarray(v, float), t)
        values, rates = np.full(len(self.cuts), np.nan), np.full(len(self.cuts), np.nan)
        for k, (cut, (parent, child)) in enumerate(zip(self.cuts, self._sides)):
            if cut.kind in LAW_KINDS:
                values[k], rates[k], _ = self._coordinate(bodies, cut, parent, child)
        return values, rates

    def cut_potential(self, q: Any) -> float:
        """Energy stored in the cuts' laws [J] at the coordinates ``q``."""
        values, _ = self.cut_coordinates(q, np.zeros(self.tree.n_velocities))
        return float(sum(cut.potential(s) for cut, s in zip(self.cuts, values) if cut.kind in LAW_KINDS)) + \
            sum(cut.potential(pair[0]) for cut, pair in zip(self.cuts, self.relative_rotations(q)) if pair is not None)

    def relative_rotations(self, q: Any, v: Any = None, t: float = 0.0) -> list[tuple[np.ndarray, np.ndarray] | None]:
        """Per cut: a spherical cut's relative rotation vector ``phi`` [rad] and its rate [rad/s] (parent body axes,
        :func:`~ctmm.spatial.closed_loop_cuts.relative_rotation`); ``None`` for the other kinds."""
        v = np.zeros(self.tree.n_velocities) if v is None else v
        bodies = self._bodies(np.asarray(q, float), np.asarray(v, float), t)
        out: list[tuple[np.ndarray, np.ndarray] | None] = []
        for cut, (parent, child) in zip(self.cuts, self._sides):
            rigid = [(None, np.zeros(3)) if side.body < 0 else (bodies[side.body][0][0], bodies[side.body][3][0])
                     for side in (parent, child)]
            out.append(relative_rotation(cut, rigid[0][0], rigid[1][0], rigid[0][1], rigid[1][1])[:2]
                       if cut.kind == "spherical" else None)
        return out

    def law_moments(self, q: Any, v: Any, t: float = 0.0) -> np.ndarray:
        """``(n_cuts, 3)``: the moment [N m] (world axes) of each spherical cut's law on its child
        (:func:`~ctmm.spatial.closed_loop_cuts.spherical_law_moment`; zero without a law and for the other kinds)."""
        return self._law_moments(self._bodies(np.asarray(q, float), np.asarray(v, float), t), t)

    def _law_moments(self, bodies: list, t: float) -> np.ndarray:
        out = np.zeros((len(self.cuts), 3))
        for k, (cut, (parent, child)) in enumerate(zip(self.cuts, self._sides)):
            if cut.kind == "spherical" and cut.law is not None:
                out[k] = self._spherical_law_wrench(bodies, cut, parent, child, t)[3:]
        return out

    def _unit_loads(self, bodies: list, t: float, extra: Mapping[str, float] | None = None
                    ) -> tuple[dict[int, np.ndarray], dict[int, list]]:
        """Per loaded rigid body: the change ``[f ; m + r x f]`` (``(1 + m, 6, 1)``, world axes, about its inboard
        point) of its applied load in the ``1 + m`` load cases: case 0 none, case ``1 + k`` the unit value of unknown
        ``k`` (its force or moment on the child, the opposite on the parent; ``bodies``: :meth:`_bodies`); the
        cuts' laws and actuations (:meth:`_law_wrenches`, at time ``t`` [s]) in every case.  Per deformable body:
        the same loads as point wrenches ``[(point, (1 + m, 6, 1))]`` for its own load path
        (:meth:`SpatialScene.terms` ``wrenches``, :mod:`ctmm.spatial.cut_points`)."""
        m = self.n_constraints
        loads: dict[int, np.ndarray] = {}
        point_loads: dict[int, list] = {}
        row = 0
        for cut, (parent, child), frame, law in zip(self.cuts, self._sides, self._frames,
                                                    self._law_wrenches(bodies, t, extra)):
            wrench = np.zeros((1 + m, 6)) if law is None else np.tile(law, (1 + m, 1))
            unit = self._unit_wrenches(bodies, cut, parent, child, frame)
            wrench[1 + row:1 + row + len(unit)] += unit
            row += len(unit)
            for side, sign in ((child, 1.0), (parent, -1.0)):
                if side.body < 0:
                    continue
                if side.deformable:                          # spherical: at its own point
                    point_loads.setdefault(side.body, []).append((side.point, sign * wrench[:, :, None]))
                    continue
                R, origin, _, _, inboard = (a[0] for a in bodies[side.body])
                lever = (origin + R @ side.point if frame.basis is None or side is child else  # prismatic: the
                         self._point(bodies, child)[0][0]) - inboard                          # child point
                about = np.concatenate([wrench[:, :3], wrench[:, 3:] + cross(lever, wrench[:, :3])], axis=1)
                loads[side.body] = loads.get(side.body, 0.0) + sign * about
        return {j: load[:, :, None] for j, load in loads.items()}, point_loads

    @staticmethod
    def _unit_wrenches(bodies: list, cut: SpatialCutJoint, parent: CutSide, child: CutSide, frame: CutFrame) -> np.ndarray:
        """``[force ; moment]`` (world) on the child per unit value of each unknown of one cut ``(rows, 6)`` (a
        driven cut's last: the unit load along its coordinate, a moment about the axis or a force along the guide)."""
        rotation_p, rotation_c = side_frame(bodies, parent)[0], side_frame(bodies, child)[0][0]
        rotation_p = None if rotation_p is None else rotation_p[0]
        basis = np.eye(3) if frame.basis is None else np.array([b if rotation_p is None else rotation_p @ b
                                                                 for b in frame.basis])
        out = np.zeros((len(basis) + len(frame.pairs) + int(cut.driven), 6))
        out[:len(basis), :3] = basis
        for i, (u_local, b_local) in enumerate(frame.pairs):
            b = b_local if rotation_p is None else rotation_p @ b_local
            out[len(basis) + i, 3:] = cross(rotation_c @ u_local, b)
        if cut.driven and cut.kind == "revolute":
            out[-1, 3:] = rotation_c @ cut.axis
        elif cut.driven:
            out[-1, :3] = cut.parent_axis if rotation_p is None else rotation_p @ cut.parent_axis
        return out

    def _sweep(self, q: np.ndarray, v: np.ndarray, t: float, inputs: Mapping[str, Any] | None
               ) -> tuple[list, np.ndarray, np.ndarray]:
        """Body states (:meth:`_bodies`), ``v'`` ``(1 + m, nv)`` and inboard point accelerations
        ``(1 + m, n_bodies, 6)`` of the ``1 + m`` load cases: the tree's terms once, the cut loads added to the
        loaded bodies' applied terms (``h``), one batched articulated sweep."""
        scene, tree = self._scene, self.tree
        q_rows, v_rows = tree.check_state(q, v)
        wrenches = None
        extra = inputs.cut_actuation if isinstance(inputs, CutActuatedInputs) else None
        if isinstance(inputs, SpatialInputs):               # the tree's ports (ctmm.spatial.ports)
            inputs, wrenches = inputs.joint, inputs.wrenches
        elif inputs is not None and not isinstance(inputs, Mapping):
            raise ModelError(f"inputs must be a mapping {{joint input: value or f(t)}} or SpatialInputs, got "
                             f"{inputs!r:.80}")
        body_terms, joint_terms, states = scene.terms(NUMPY, q_rows, v_rows, t, scene.numpy_inputs(inputs, t, 1),
                                                      wrenches)
        bodies = self._states(states, q_rows, v_rows)
        loads, point_loads = self._unit_loads(bodies, t, extra)
        for j, load in loads.items():
            body_terms[j] = replace(body_terms[j], h=body_terms[j].h - load)
        if point_loads:                                    # deformable sides: their terms again with the point loads
            merged = {j: list(entries) for j, entries in (wrenches or {}).items()}
            for j, entries in point_loads.items():
                merged[j] = merged.get(j, []) + entries
            loaded = scene.terms(NUMPY, q_rows, v_rows, t, scene.numpy_inputs(inputs, t, 1), merged)[0]
            for j in point_loads:
                body_terms[j] = loaded[j]
        try:
            solution = articulated_sweep(NUMPY, scene.tree, body_terms, joint_terms)
        except SingularPivotError as exc:
            joint = tree.joints[exc.body]
            raise SimulationError(f"{tree.name}: the articulated pivot of joint {joint.name!r} ({joint.kind}) is "
                                  f"singular at t = {t} s: the subtree it carries has no inertia in some free "
                                  "direction (to round-off)", time=t, element=joint.name) from exc
        batch = 1 + self.n_constraints
        parts = [np.broadcast_to(np.asarray(a), (batch,) + np.asarray(a).shape[1:])[:, :, 0]
                 for a in scene.velocity_rates(solution)]
        rates = np.concatenate(parts, axis=1) if parts else np.zeros((batch, 0))
        points = np.stack([np.broadcast_to(np.asarray(x)[:, :6], (batch, 6, 1))[:, :, 0] for x in solution.x], axis=1)
        if not (np.all(np.isfinite(rates)) and np.all(np.isfinite(points))):
            raise SimulationError(f"spatial kinematic loop {self.name!r}: the articulated sweep gave non-finite "
                                  f"accelerations at t = {t} s", time=t, element=self.cuts[0].name)
        return bodies, rates, points

    def solve(self, q: Any, v: Any, t: float = 0.0, inputs: Mapping[str, Any] | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
        """``(v', lambda)`` at ``(q, v, t)`` with the tree's actuator ``inputs`` (``{"<joint>.torque": value or
        f(t)}`` or the :class:`~ctmm.spatial.ports.SpatialInputs` of the tree's ports): the closed-loop accelerations
        ``(nv,)`` and the cut loads ``(m,)`` (per cut: the force on the child [N], world axes -- prismatic: its two
        components along ``p_1``, ``p_2`` -- then for a revolute, universal or prismatic cut the moment multipliers
        [N m] along ``n_i = u_i x b_i``; :meth:`cut_loads` gives vectors).

        Raises
        ------
        SimulationError
            A singular boundary compliance (a singular configuration of the loop, or redundant cut rows), naming
            the time and the first cut joint.
        """
        return self._solution(q, v, t, inputs)[1:]

    def _solution(self, q: Any, v: Any, t: float, inputs: Mapping[str, Any] | None
                  ) -> tuple[list, np.ndarray, np.ndarray]:
        """Body states (:meth:`_bodies`) and :meth:`solve`'s ``(v', lambda)`` from one pass of the tree's terms."""
        bodies, rates, points = self._sweep(np.asarray(q, float), np.asarray(v, float), t, inputs)
        second = self._accelerations(bodies, points, rates, t)
        G = (second[1:] - second[0]).T
        phi, phi_dot = self._rows(bodies, t)
        alpha = self.baumgarte
        target = -second[0] - 2.0 * alpha * phi_dot[0] - alpha * alpha * phi[0]
        condition = compliance_condition(G)
        if not condition <= CONDITION_LIMIT:
            raise SimulationError(f"spatial kinematic loop {self.name!r}: {singular_compliance(condition)} at t = {t} "
                                  "s (e.g. a revolute cut closing a planar loop: use a spherical cut there)", time=t,
                                  element=self.cuts[0].name)
        lam = np.linalg.solve(G, target)
        return bodies, rates[0] + (rates[1:] - rates[0]).T @ lam, lam

    def cut_loads(self, q: Any, lam: np.ndarray, t: float = 0.0) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per cut: ``(force, moment)`` on the child [N, N m], world axes, from the unknowns ``lam``
        (:meth:`solve`) at ``q`` (a spherical cut's moment is zero; the parent carries their opposites at the child
        point)."""
        return self._cut_loads(self._bodies(np.asarray(q, float), np.zeros(self.tree.n_velocities), t), lam)

    def _cut_loads(self, bodies: list, lam: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """:meth:`cut_loads` from the body states of any velocity at ``q`` (only their rotations are read)."""
        out, row = [], 0
        for cut, (parent, child), frame in zip(self.cuts, self._sides, self._frames):
            unit = self._unit_wrenches(bodies, cut, parent, child, frame)
            wrench = np.asarray(lam[row:row + len(unit)], float) @ unit
            out.append((wrench[:3], wrench[3:]))
            row += len(unit)
        return out

    def stored_row(self, q: Any, v: Any, t: float = 0.0, inputs: Mapping[str, Any] | None = None
                   ) -> tuple[np.ndarray, np.ndarray, list[tuple[np.ndarray, np.ndarray]], np.ndarray]:
        """A run's row at ``(q, v, t)`` from one pass of the tree's terms: :meth:`constraints`, :meth:`cut_loads` of
        :meth:`solve` with ``inputs`` and :meth:`law_moments`."""
        bodies, _, lam = self._solution(q, v, t, inputs)
        phi, rate = self._rows(bodies, t)
        return phi[0], rate[0], self._cut_loads(bodies, lam), self._law_moments(bodies, t)

    def cut_inputs(self, q: Any, v: Any, t: float = 0.0, inputs: Mapping[str, Any] | SpatialInputs | None = None
                   ) -> SpatialInputs:
        """The cut loads at ``(q, v, t)`` (:meth:`solve` with the actuator ``inputs``) as actuator values of the tree
        -- the force and moment on each cut's child point, their opposites on the parent at the same place (world
        axes; the parent point itself except for a prismatic cut) --
        together with ``inputs``: with them the tree's own sweep (e.g. an iterate of a DT-TMM scheme,
        :func:`ctmm.spatial.implicit.simulate_spatial_implicit` ``input_map``) moves as the closed loop."""
        q, v = np.asarray(q, float), np.asarray(v, float)
        bodies, _, lam = self._solution(q, v, t, inputs)    # one pass: the loads read positions and rotations only
        joint = dict(inputs.joint) if isinstance(inputs, SpatialInputs) else dict(inputs or {})
        wrenches: dict[int, list] = {}
        if isinstance(inputs, SpatialInputs):
            for body, entries in inputs.wrenches.items():
                wrenches[body] = list(entries)
        laws = self._law_wrenches(bodies, t, inputs.cut_actuation if isinstance(inputs, CutActuatedInputs) else None)
        for (parent, child), frame, (force, moment), law in zip(self._sides, self._frames, self._cut_loads(bodies, lam),
                                                                laws):
            load = (np.concatenate([force, moment]) + (0.0 if law is None else law)).reshape(1, 6, 1)
            wrenches.setdefault(child.body, []).append((child.point, load))
            if parent.body >= 0:                       # prismatic: at the child point, in parent body axes
                R, origin = bodies[parent.body][0][0], bodies[parent.body][1][0]
                at = parent.point if frame.basis is None else R.T @ (self._point(bodies, child)[0][0] - origin)
                wrenches.setdefault(parent.body, []).append((at, -load))
        return SpatialInputs(joint, wrenches, checked=True)

    # -- assembly and projection -------------------------------------------------------------------------
    def _held(self, keep: Sequence[str]) -> list[int]:
        """Velocity indices held by ``keep`` (joint names, velocity names, or coordinate names of 1- and 2-DOF
        joints)."""
        tree = self.tree
        names: dict[str, list[int]] = {}
        for joint, layout in zip(tree.joints, tree.layout):
            indices = list(range(layout.velocity.start, layout.velocity.stop))
            if indices:
                names[joint.name] = indices
        for k, name in enumerate(tree.velocities):
            names[name] = [k]
        for joint, layout in zip(tree.joints, tree.layout):
            if joint.kind in ("revolute", "prismatic", "universal") and not joint.driven:
                for i, name in enumerate(tree.coordinates[layout.position]):
                    names[name] = [layout.velocity.start + i]
        if isinstance(keep, str):
            keep = [keep]
        held: list[int] = []
        for name in keep:
            if name not in names:
                raise unknown_name("keep (joint, velocity or 1-/2-DOF coordinate)", name, list(names))
            held += names[name]
        return sorted(set(held))

    def consistent_state(self, q: Any = None, v: Any = None, *, keep: Sequence[str] = (), tolerance: float = 1e-12
                         ) -> tuple[np.ndarray, np.ndarray]:
        """A state on the cut joints near ``(q, v)`` (arrays or mappings, :meth:`state`) with the motions ``keep``
        held (joint names, e.g. the crank's, or coordinate / velocity names): Gauss-Newton on ``Phi = 0`` along
        ``q (+) dx`` and a least-squares ``J v = 0`` over the free velocities.

        Raises
        ------
        ModelError
            No assembled configuration found (50 Gauss-Newton steps).
        """
        q, v = self.state(q, v)
        held = self._held(keep)
        free = [k for k in range(self.tree.n_velocities) if k not in held]
        for _ in range(50):
            phi, _ = self.constraints(q, v)
            if np.max(np.abs(phi)) < tolerance:
                break
            dx = np.zeros(self.tree.n_velocities)
            dx[free] = -np.linalg.lstsq(self.jacobian(q)[:, free], phi, rcond=None)[0]
            q = self.retract(q, dx)
        else:
            raise ModelError(f"spatial kinematic loop {self.name!r}: no assembled configuration near the given "
                             f"coordinates (|Phi| = {np.max(np.abs(phi)):.3e} after 50 Gauss-Newton steps); check "
                             "the geometry, the cut points and the held motions")
        _, rate, J = self._rows_and_jacobian(q, v, 0.0)
        v = v.copy()
        v[free] -= np.linalg.lstsq(J[:, free], rate, rcond=None)[0]     # Phi'(q, v) = 0 (driven rates included)
        return q, v

    def _rows_and_jacobian(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``Phi``, ``Phi'`` and ``J`` at ``(q, v)`` from one batched kinematics pass (states ``(q, v)``, ``(q, 0)``,
        ``(q, e_k)``: ``J`` column ``k`` is ``Phi'(q, e_k) - Phi'(q, 0)``, the rate of driven joints taken out)."""
        nv = self.tree.n_velocities
        phi, rate = self._rows(self._bodies(np.broadcast_to(q, (2 + nv, len(q))),
                                            np.vstack([v[None], np.zeros((1, nv)), np.eye(nv)]), t), t)
        return phi[0], rate[0], (rate[2:] - rate[1]).T.copy()

    def project(self, q: np.ndarray, v: np.ndarray, t: float = 0.0, iterations: int = 3
                ) -> tuple[np.ndarray, np.ndarray]:
        """Minimum-norm projection of ``(q, v)`` onto ``Phi = 0``, ``Phi' = 0`` (a few Gauss-Newton steps along
        ``q (+) dx``; quaternions renormalised)."""
        return self.project_rows(q, v, t, iterations)[:2]

    def project_rows(self, q: np.ndarray, v: np.ndarray, t: float = 0.0, iterations: int = 3, rows: Any = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`project` and ``Phi`` at its result (``rows``, the constraints at ``(q, v)``, unused: they are
        evaluated with ``J`` at the renormalised ``q``)."""
        q = self.tree.normalized(q)
        phi, rate, J = self._rows_and_jacobian(q, v, t)
        for _ in range(iterations):
            if np.max(np.abs(phi)) < PROJECTION_SKIP:
                break
            q = self.retract(q, -np.linalg.lstsq(J, phi, rcond=None)[0])
            phi, rate, J = self._rows_and_jacobian(q, v, t)
        return q, v - np.linalg.lstsq(J, rate, rcond=None)[0], phi     # Phi'(q, v) = 0 (driven rates included)
