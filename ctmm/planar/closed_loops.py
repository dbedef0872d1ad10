"""Closed kinematic loops and bodies with several input ends: cut joints with boundary unknowns.

A planar mechanism with closed loops (a four-bar linkage) or a body hanging from several parents
(seed 002 section 7.4.2.1, bodies with several input ends) is modelled as a spanning tree -- an
ordinary :class:`~ctmm.planar.model.PlanarModel` -- plus **cut joints** (:class:`CutJoint`): smooth
revolute joints that make a point of one body coincide with a point of another body or of the ground.
Derivation: ``docs/closed_loops.md``.

Mechanism (the boundary unknowns of the mixed transfer matrix method, seed 001 section 9.2)
------------------------------------------------------------------------------------------
The cut joint's force ``lambda_k`` (global axes [N]; on the child point ``+lambda_k``, on the parent point
``-lambda_k``) is the unknown that closes the transfer equations.  At fixed ``(q, qdot, t)`` the tree's
O(n) articulated sweep (:func:`ctmm.planar.sweep.solve_instant`) is affine in applied forces, so one sweep
without and ``2 m`` sweeps with unit boundary forces (the tree's terms evaluated once for all of them,
:func:`ctmm.planar.sweep.solve_instant_inputs`; on a tree without deformable bodies one batch through one call of
the mapped sweep, :func:`ctmm.planar.sweep.solve_instant_batch`) give the relative acceleration of the cut points as
``a_rel = a_0 + G lambda`` (``G``: the ``2 m x 2 m`` boundary compliance).  The constraint at the
acceleration level with Baumgarte stabilisation::

    G lambda = -a_0 - 2 alpha Phi' - alpha^2 Phi          (Phi: the cut points' separation [m])

fixes ``lambda`` and then ``qddot = qddot_0 + sum_k (dqddot / dlambda_k) lambda_k``.  The tree coordinates
stay the state; the drift of ``Phi`` (which the exact acceleration-level constraint would let grow
from round-off and truncation) is controlled by Baumgarte (``alpha`` [1/s]) and, in the fixed-step
integrator, by projection after every step onto ``Phi = 0`` and ``Phi' = 0`` (minimum-norm Gauss-Newton
with the constraint Jacobian ``J = dPhi'/dqdot``, exact).  The drift is reported in the result
(:attr:`KinematicLoopSimulation.drift`, ``.drift_rate``), with the cut forces.

The library verbs (``ctmm.simulate`` with every method, ``ctmm.linearize``, ``ctmm.natural_frequencies``,
``ctmm.frequency_response``) call this model's functions (:mod:`ctmm.planar.loop_verbs`); feedback loops, actuator
inputs and controllers act on the tree's ports (``ctmm.control.with_feedback(model, loops)``,
:mod:`ctmm.planar.loop_plant`, ``docs/closed_loops.md`` §3c).  A cut joint may carry a rotary spring / damper law
and an actuator torque on the relative angle across the cut (:mod:`ctmm.planar.cut_joints`): a moment pair added to
its constraint force as applied loads of the tree; a driven cut prescribes that angle by one more row, its moment a
boundary unknown with the force (``docs/closed_loops.md`` §2a).
Cut points may be ends of a ``ctmm.flexible.ModalBeam`` (a flexible coupler): the cut force enters the beam's frame
wrench and modal equations as its virtual work, through the end's foreshortening too (``docs/closed_loops.md``
§4a-4b); or outboard boundary nodes of a ``ctmm.fem`` subsystem (a finite-element body closing the loop): the cut
force is a nodal load at that node (§4c).  The sides of every cut are read through :mod:`ctmm.planar.cut_points`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .. import loop_manifold, validation
from ..errors import ModelError, SimulationError
from ..loop_integration import (CONDITION_LIMIT, PROJECTION_SKIP, check_consistent, compliance_condition,
                                integrate_loop_run, singular_compliance)
from .cut_joints import CutJoint
from .cut_points import CutPoints
from .model import PlanarModel
from .ports import ActuatorInputs
from .sweep import solve_instant_batch, solve_instant_inputs

__all__ = ["CutJoint", "KinematicLoopModel", "KinematicLoopSimulation", "simulate_kinematic_loops"]


@dataclass(frozen=True)
class KinematicLoopSimulation:
    """Time history of a closed-loop run.

    Attributes
    ----------
    model : KinematicLoopModel
    t : ndarray (N,)
        Times [s].
    q, qdot : ndarray (N, n_coordinates)
        Tree coordinates and rates (``model.tree.coordinates``).
    cut_force : ndarray (N, n_cuts, 2)
        Force of each cut joint on its child point, global axes [N].
    drift, drift_rate : ndarray (N,)
        ``max |Phi|`` [m] and ``max |Phi'|`` [m/s] of the cut joints (constraint drift).
    method : str
    wall_time_s : float
    n_evaluations : int
        Evaluations of the closed-loop accelerations (each ``1 + 2 n_cuts`` sweeps).
    """

    model: "KinematicLoopModel"
    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    cut_force: np.ndarray
    drift: np.ndarray
    drift_rate: np.ndarray
    method: str
    wall_time_s: float
    n_evaluations: int

    def coordinate(self, name: str) -> np.ndarray:
        """History of tree coordinate ``name`` (``name + "_dot"`` for its rate)."""
        if name.endswith("_dot"):
            return self.qdot[:, self.model.tree.coordinate_index(name[:-4])]
        return self.q[:, self.model.tree.coordinate_index(name)]

    def energy(self) -> np.ndarray:
        """Mechanical energy [J] at every stored time: :meth:`PlanarModel.energy` of the tree plus the energy
        stored in the cut joints' moment laws (:meth:`KinematicLoopModel.cut_potential`)."""
        return np.array([self.model.tree.energy(q, v, t) + self.model.cut_potential(q)
                         for t, q, v in zip(self.t, self.q, self.qdot)])


class KinematicLoopModel:
    """A planar spanning tree plus cut joints (module docstring).

    Parameters
    ----------
    tree : PlanarModel
        The mechanism with the cut joints removed (cut points: ground points, rigid-body ends, ``ModalBeam`` ends,
        outboard boundary nodes of ``ctmm.fem`` subsystems).
    cuts : sequence of CutJoint
        The joints closing the loops.
    baumgarte : float
        Stabilisation rate ``alpha`` [1/s] (>= 0; 0: none).  Default 20.
    foreshortening : bool
        A cut point at a ``ModalBeam`` end moves axially by the second-order shortening
        ``-1/2 q^T G1(x_e) q`` of the bent beam (``G1(x_e) = int_0^x_e phi' phi'^T``, ``docs/closed_loops.md``
        §4b), and the cut force does its virtual work through it (the axial-load stiffening of the end force).
        Default True; False: the linear end position.
    """

    def __init__(self, tree: PlanarModel, cuts: Sequence[CutJoint], *, baumgarte: float = 20.0,
                 foreshortening: bool = True) -> None:
        if not isinstance(tree, PlanarModel):
            raise ModelError(f"KinematicLoopModel: tree must be a ctmm.planar.PlanarModel, got {tree!r}")
        cuts = tuple(cuts)
        if not cuts or not all(isinstance(c, CutJoint) for c in cuts):
            raise ModelError(f"KinematicLoopModel: cuts must be a non-empty sequence of CutJoint, got {cuts!r}")
        taken = {element.name for element in tree.elements}
        for k, cut in enumerate(cuts):      # the ports and results are keyed by the cut's name
            if cut.name in taken or cut.name in {c.name for c in cuts[:k]}:
                raise ModelError(f"KinematicLoopModel: duplicate name {cut.name!r} (cut joint names must differ from "
                                 "each other and from the tree's elements)")
        self.tree, self.cuts = tree, cuts
        self.baumgarte = validation.nonnegative("baumgarte", baumgarte)
        self.foreshortening = validation.flag("foreshortening", foreshortening)
        self.cut_points = CutPoints(tree, cuts, self.foreshortening)
        self._points = self.cut_points.sides
        self._rows = np.cumsum([0] + [3 if cut.driven else 2 for cut in cuts])   # first row of each cut, and m
        self._unit_loads = np.vstack([np.zeros(self._rows[-1]), np.eye(self._rows[-1])])   # none, then each unit load
        self._batched = tree.deformable_family is None     # no deformable side: the unit loads as one batch
        self.name = tree.name
        self._tangents: dict = {}           # (q0, t, baumgarte) -> (A, N, q0, jacobian error): resting_tangent
        self._equilibria: dict = {}         # (guess, t, tolerance, largest step) -> equilibrium (the last 8)

    def __repr__(self) -> str:
        return f"KinematicLoopModel({self.name!r}, cuts={[cut.name for cut in self.cuts]})"

    def _points_at(self, q, qdot, t: float) -> dict:
        """:meth:`PlanarModel.points` with the state itself (``"q"``, ``"qdot"``: the deformable ends read it); the
        cut points read no centre of mass."""
        points = self.tree.points(q, qdot, t, centres=False)
        points["q"], points["qdot"], points["t"] = q, qdot, t
        return points

    def relative_angles(self, q, qdot, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Relative angle ``dtheta = theta_child - theta_parent`` [rad] and its rate [rad/s] across every cut
        (:mod:`ctmm.planar.cut_joints`), each (n_cuts,)."""
        q, qdot = self.tree.state(q, qdot)
        points = self._points_at(np.asarray(q, float), np.asarray(qdot, float), t)
        pairs = [np.subtract(self.cut_points.angle(points, jc, ec), self.cut_points.angle(points, jp, ep))
                 for (jp, ep), (jc, ec) in self._points]
        return np.array([p[0] for p in pairs]), np.array([p[1] for p in pairs])

    def cut_potential(self, q) -> float:
        """Energy stored in the cut joints' moment laws [J] at the coordinates ``q``."""
        angle, _ = self.relative_angles(q, np.zeros(self.tree.n_coordinates))
        return float(sum(cut.potential(a) for cut, a in zip(self.cuts, angle)))

    def constraints(self, q, qdot, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """``Phi`` (child point minus parent point [m]; a driven cut also ``dtheta - angle(t)`` [rad]) and ``Phi'``
        [m/s, rad/s] of every cut, stacked (2 per cut, 3 per driven cut)."""
        return self._constraints_at(self._points_at(q, qdot, t), t)

    def _side_points(self, points: dict) -> list:
        """Per cut ``(parent, child)`` :meth:`CutPoints.point` (position [m], velocity [m/s], lever [m]) at the
        tree's ``points`` (:meth:`_points_at`): evaluated once per state, read by the constraints, the cut loads and
        the relative accelerations of :meth:`solve_loads`."""
        sides = self.cut_points
        return [(sides.point(points, jp, ep), sides.point(points, jc, ec)) for (jp, ep), (jc, ec) in self._points]

    def _law_moments(self, points: dict) -> list:
        """Per cut the moment [N m] of its law and torque (:meth:`CutJoint.moment`) at the tree's ``points``
        (:meth:`_points_at`); ``None`` for a cut without one or a driven cut (its moment is a boundary unknown)."""
        moments = []
        for cut, ((jp, ep), (jc, ec)) in zip(self.cuts, self._points):
            if cut.has_moment and not cut.driven:
                angle, rate = np.subtract(self.cut_points.angle(points, jc, ec), self.cut_points.angle(points, jp, ep))
                moments.append(cut.moment(angle, rate, points["t"]))
            else:
                moments.append(None)
        return moments

    def _constraints_at(self, points: dict, t: float, side_points: list | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`constraints` at the tree's ``points`` (:meth:`_points_at`) of the state (``side_points``:
        :meth:`_side_points` of them when the caller has them)."""
        phi, rate = [], []
        side_points = self._side_points(points) if side_points is None else side_points
        for cut, ((jp, ep), (jc, ec)), ((pp, vp, _), (pc, vc, _)) in zip(self.cuts, self._points, side_points):
            phi.append(pc - pp)
            rate.append(vc - vp)
            if cut.driven:
                angle, angle_rate = np.subtract(self.cut_points.angle(points, jc, ec), self.cut_points.angle(points, jp, ep))
                phi.append([angle - float(cut.angle(t))])
                rate.append([angle_rate - float(cut.angle_rate(t))])
        return np.concatenate(phi), np.concatenate(rate)

    def jacobian(self, q, t: float = 0.0) -> np.ndarray:
        """``J = dPhi/dq`` (rows, n), exact: ``Phi' = J qdot + b(t)`` (``b``: the driven joints' and cuts' prescribed
        rates), ``J`` in one pass from the tree's rate maps at ``q`` (:meth:`CutPoints.rate_maps`,
        :meth:`CutPoints.point_rate_map`)."""
        return self._jacobian_at(self._points_at(q, np.zeros(self.tree.n_coordinates), t))

    def _jacobian_at(self, points: dict) -> np.ndarray:
        """:meth:`jacobian` at the tree's ``points`` (:meth:`_points_at`) of ``q`` and any ``qdot`` (it reads the
        configuration only: the rate maps take zero rates of their own)."""
        maps, sides = self.cut_points.rate_maps(points), self.cut_points
        rows = []
        for cut, ((jp, ep), (jc, ec)) in zip(self.cuts, self._points):
            (vp, wp), (vc, wc) = sides.point_rate_map(points, maps, jp, ep), sides.point_rate_map(points, maps, jc, ec)
            rows.append(vc - vp)
            if cut.driven:
                rows.append((wc - wp)[None, :])
        return np.concatenate(rows)

    def _cut_loads(self, points: dict, loads: np.ndarray, inputs: ActuatorInputs | None = None,
                   sides: tuple[list, list] | None = None) -> ActuatorInputs:
        """Cut loads ``loads`` (the unknowns, stacked as the rows of :meth:`constraints`: each cut's force, global
        axes [N], then a driven cut's moment [N m]) with the cuts' laws and torques as actuator inputs of the tree,
        added to ``inputs``: on a rigid body a force at the centre of mass with the moment of its lever; at a
        deformable body's end its frame wrench and generalised forces (virtual work;
        :meth:`ctmm.planar.cut_points.CutPoints.add_force`).  ``points``: :meth:`_points_at`; ``sides``: its
        :meth:`_side_points` and :meth:`_law_moments` when the caller has them (the unit loads of one state).
        ``loads`` (rows, n_batch) on a tree without deformable bodies: the inputs of each column at once, every array
        with a leading batch axis (:func:`ctmm.planar.sweep.solve_instant_batch`)."""
        side_points, moments = (self._side_points(points), self._law_moments(points)) if sides is None else sides
        m, sides = self.tree, self.cut_points
        body_force = np.zeros((m.n_bodies, 3) + loads.shape[1:])       # a batch along the last axis here
        modal = {j: np.array(v, dtype=float) for j, v in (inputs.modal_force if inputs else {}).items()}
        frame = {j: np.array(v, dtype=float) for j, v in (inputs.frame_wrench if inputs else {}).items()}
        for k, (cut, ((jp, ep), (jc, ec)), ((_, _, lever_p), (_, _, lever_c)), law) in enumerate(
                zip(self.cuts, self._points, side_points, moments)):
            force = loads[self._rows[k]:self._rows[k] + 2]
            sides.add_force(points, jc, ec, force, body_force, modal, frame, lever_c)
            sides.add_force(points, jp, ep, -force, body_force, modal, frame, lever_p)
            if not cut.has_moment and not cut.driven:
                continue
            tau = loads[self._rows[k] + 2] if cut.driven else law
            sides.add_moment(jc, ec, tau, body_force, modal, frame)
            sides.add_moment(jp, ep, -tau, body_force, modal, frame)
        if loads.ndim > 1:
            body_force = np.moveaxis(body_force, -1, 0)
            batch = (loads.shape[1],)
            modal = {j: np.broadcast_to(v, batch + v.shape) for j, v in modal.items()}
            frame = {j: np.broadcast_to(v, batch + v.shape) for j, v in frame.items()}
        hinge_torque = np.zeros(m.n_bodies) if inputs is None else inputs.hinge_torque
        if loads.ndim > 1:
            hinge_torque = np.broadcast_to(hinge_torque, (loads.shape[1], m.n_bodies))
        if inputs is None:
            return ActuatorInputs(hinge_torque, body_force, modal, frame)
        return ActuatorInputs(hinge_torque, inputs.body_force + body_force, modal, frame)

    def torque_inputs(self, name: str) -> ActuatorInputs:
        """A unit torque [N m] across cut ``name`` (``+1`` on the child side, ``-1`` on the parent; at a deformable
        end on the frame and, through the end slope, the internal coordinates) as actuator inputs of the tree: state
        independent, the input ``"<cut>.torque"`` of the linearisation (``docs/closed_loops.md`` §2a); not of a cut
        at a subsystem node without a rotation DOF (a particle takes no moment)."""
        names = {cut.name: k for k, cut in enumerate(self.cuts) if not cut.driven and self.cut_points.takes_moment[k]}
        if name not in names:
            raise ModelError(f"cut torque input: {name!r} names no undriven cut joint of {self.name!r} (allowed: "
                             f"{list(names)})")
        m, (parent, child) = self.tree, self._points[names[name]]
        body, modal, frame = np.zeros((m.n_bodies, 3)), {}, {}
        for (j, e), sign in ((child, 1.0), (parent, -1.0)):
            self.cut_points.add_moment(j, e, sign, body, modal, frame)
        return ActuatorInputs(np.zeros(m.n_bodies), body, modal, frame)

    def cut_inputs(self, q, qdot, t: float = 0.0, inputs: ActuatorInputs | None = None) -> ActuatorInputs:
        """The cut forces at ``(q, qdot, t)`` (:meth:`solve`) as actuator inputs of the tree, added to ``inputs``:
        with them the tree's own sweep (e.g. the Newton iterate of a DT-TMM scheme) moves as the closed loop."""
        q, qdot = self.tree.state(q, qdot)
        return self._cut_loads(self._points_at(q, qdot, t), self.solve_loads(q, qdot, t, inputs)[1], inputs)

    def _relative(self, solution, points: dict, t: float, side_points: list) -> np.ndarray:
        """``Phi''`` of the cuts (relative accelerations of their sides; a driven cut also its angle's, less the
        drive's) in the tree ``solution`` (``points``: :meth:`_points_at` at its state, ``side_points`` their
        :meth:`_side_points`); a solution with a leading batch axis on a tree without deformable bodies
        (:func:`ctmm.planar.sweep.solve_instant_batch`): (n_batch, rows)."""
        sides = self.cut_points
        A, qdd = solution.body_acceleration, solution.qddot
        relative = []
        for cut, ((jp, ep), (jc, ec)), ((_, _, lever_p), (_, _, lever_c)) in zip(self.cuts, self._points, side_points):
            relative.append(sides.acceleration(points, A, qdd, jc, ec, lever_c)     # one side at least on a body:
                            - sides.acceleration(points, A, qdd, jp, ep, lever_p))  # the batch shape
            if cut.driven:      # angular accelerations of the sides (a deformable end: plus its slope's)
                relative.append(np.expand_dims(sides.angular_acceleration(A, qdd, jc, ec)
                                               - sides.angular_acceleration(A, qdd, jp, ep)
                                               - float(cut.angle_acceleration(t)), -1))
        return np.concatenate(relative, axis=-1)

    def solve(self, q, qdot, t: float = 0.0, inputs: ActuatorInputs | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(qddot, cut forces (n_cuts, 2))`` at ``(q, qdot, t)`` (module docstring), with the tree's actuator
        ``inputs`` (:func:`ctmm.planar.ports.actuator_inputs`) if given."""
        qdd, loads = self.solve_loads(q, qdot, t, inputs)
        return qdd, np.array([loads[start:start + 2] for start in self._rows[:-1]])

    def cut_moments(self, q, qdot, t: float = 0.0, inputs: ActuatorInputs | None = None) -> np.ndarray:
        """Moment of every cut on its child side [N m], (n_cuts,): its law and torque (:meth:`CutJoint.moment`), or
        a driven cut's drive moment (:meth:`solve_loads`, with the tree's actuator ``inputs``)."""
        angle, rate = self.relative_angles(q, qdot, t)
        moments = np.array([cut.moment(a, r, t) for cut, a, r in zip(self.cuts, angle, rate)])
        if any(cut.driven for cut in self.cuts):
            loads = self.solve_loads(q, qdot, t, inputs)[1]
            for k, cut in enumerate(self.cuts):
                moments[k] = loads[self._rows[k] + 2] if cut.driven else moments[k]
        return moments

    def solve_loads(self, q, qdot, t: float = 0.0, inputs: ActuatorInputs | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
        """``(qddot, cut loads)``: the boundary unknowns stacked as the rows of :meth:`constraints` (each cut's
        force [N], a driven cut's moment [N m] after it) solved from ``G lambda = -a_0 - 2 alpha Phi' - alpha^2 Phi``."""
        points = self._points_at(q, qdot, t)
        side_points = self._side_points(points)         # the sides' kinematics and laws once for every unit load
        sides = (side_points, self._law_moments(points))
        if self._batched:       # no deformable body: the loads of every column at once, one sweep over them
            solution = solve_instant_batch(self.tree, q, qdot, t, self._cut_loads(points, self._unit_loads.T, inputs,
                                                                                   sides))
            qdd, relative = solution.qddot, self._relative(solution, points, t, side_points)
        else:
            solutions = solve_instant_inputs(self.tree, q, qdot, t, [self._cut_loads(points, load, inputs, sides)
                                                                      for load in self._unit_loads])   # terms once
            qdd = np.array([solution.qddot for solution in solutions])
            relative = np.array([self._relative(solution, points, t, side_points) for solution in solutions])
        qdd0, a0 = qdd[0], relative[0]
        G = np.ascontiguousarray((relative[1:] - a0).T)     # column k: the response to unit load k
        dqdd = np.ascontiguousarray((qdd[1:] - qdd0).T)
        phi, phi_dot = self._constraints_at(points, t, side_points)
        alpha = self.baumgarte
        target = -a0 - 2.0 * alpha * phi_dot - alpha * alpha * phi
        condition = compliance_condition(G)
        if not condition <= CONDITION_LIMIT:
            raise SimulationError(f"kinematic loop {self.name!r}: {singular_compliance(condition)} at t = {t} s",
                                  time=t, element=self.cuts[0].name)
        lam = np.linalg.solve(G, target)
        return qdd0 + dqdd @ lam, lam

    def consistent_state(self, q, qdot, *, keep: Sequence[str] = (), tolerance: float = 1e-12
                         ) -> tuple[np.ndarray, np.ndarray]:
        """A state on the constraints near ``(q, qdot)`` with the coordinates ``keep`` held (e.g. the crank
        angle and rate of a four-bar; one name or a sequence): Gauss-Newton on ``Phi = 0`` and a least-squares
        ``J qdot = 0``."""
        q, qdot = self.tree.state(q, qdot)
        q, qdot = q.astype(float).copy(), qdot.astype(float).copy()
        held = [self.tree.coordinate_index(name) for name in ([keep] if isinstance(keep, str) else keep)]
        free = [k for k in range(len(q)) if k not in held]
        for _ in range(50):
            phi, _ = self.constraints(q, qdot)
            if np.max(np.abs(phi)) < tolerance:
                break
            J = self.jacobian(q)[:, free]
            q[free] -= np.linalg.lstsq(J, phi, rcond=None)[0]
        else:
            raise ModelError(f"kinematic loop {self.name!r}: no assembled configuration near the given coordinates "
                             f"(|Phi| = {np.max(np.abs(phi)):.3e} m after 50 Gauss-Newton steps); check the "
                             "geometry and the held coordinates")
        qdot[free] -= np.linalg.lstsq(self.jacobian(q)[:, free], self.constraints(q, qdot)[1], rcond=None)[0]
        return q, qdot

    def project(self, q: np.ndarray, qdot: np.ndarray, t: float = 0.0, iterations: int = 3
                ) -> tuple[np.ndarray, np.ndarray]:
        """Minimum-norm projection of ``(q, qdot)`` onto ``Phi = 0``, ``Phi' = 0`` (a few Gauss-Newton steps)."""
        return self.project_rows(q, qdot, t, iterations)[:2]

    def project_rows(self, q: np.ndarray, qdot: np.ndarray, t: float = 0.0, iterations: int = 3,
                     rows: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`project` and ``Phi`` [m, rad] at its result; ``rows``: :meth:`constraints` at ``(q, qdot, t)``
        when the caller has them (each evaluation of the constraints serves the step it is needed for; the tree's
        points of each configuration serve its constraints and its Jacobian)."""
        points = None                                   # the tree's points at (q, qdot, t) once evaluated
        if rows is None:
            points = self._points_at(q, qdot, t)
            rows = self._constraints_at(points, t)
        phi, rate = rows
        for _ in range(iterations):
            if np.max(np.abs(phi)) < PROJECTION_SKIP:
                break
            points = self._points_at(q, qdot, t) if points is None else points
            q = q - np.linalg.lstsq(self._jacobian_at(points), phi, rcond=None)[0]
            points = self._points_at(q, qdot, t)
            phi, rate = self._constraints_at(points, t)
        points = self._points_at(q, qdot, t) if points is None else points
        return q, qdot - np.linalg.lstsq(self._jacobian_at(points), rate, rcond=None)[0], phi

    # -- linearisation on the constraint manifold (the algorithm: :mod:`ctmm.loop_manifold`) -----------
    def require_static(self, what: str) -> int:
        """The number of tree coordinates; :class:`ModelError` for a driven cut (its manifold moves in time)."""
        driven = [cut.name for cut in self.cuts if cut.driven]
        if driven:
            raise ModelError(f"{what} of kinematic loop {self.name!r}: the cut joints {driven} are driven (angle "
                             "given), so the constraint manifold moves in time and has no static equilibrium or "
                             "tangent; allowed: cuts without angle (smooth, or with moment_law / torque)")
        return self.tree.n_coordinates

    @property
    def n_velocities(self) -> int:
        """The number of tree coordinates' rates (:mod:`ctmm.loop_manifold` protocol)."""
        return self.tree.n_coordinates

    def retract(self, q: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """``q + dx``: planar coordinates move additively (:mod:`ctmm.loop_manifold` protocol)."""
        return q + dx

    def chart(self, q0: np.ndarray, basis: np.ndarray, z: np.ndarray, zdot: np.ndarray, t: float = 0.0
              ) -> tuple[np.ndarray, np.ndarray]:
        """The state on the constraints with independent coordinates ``z = N^T (q - q0)`` and rates ``zdot``:
        ``q = q0 + N z + J0^T y``, ``qdot = N zdot + J0^T w`` with ``y``, ``w`` from ``Phi = 0``, ``J qdot = 0``
        (``basis``: ``N``, the null space of ``J0 = J(q0)``; angles [rad], rates [rad/s];
        :func:`ctmm.loop_manifold.chart`)."""
        return loop_manifold.chart(self, q0, basis, z, zdot, t)

    def linearize(self, q0, t: float = 0.0, *, step: float | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Linearisation about the resting state ``q0`` (projected onto the constraints) in independent
        coordinates ``z = N^T (q - q0)`` (``N``: orthonormal null space of ``J(q0)``, ``f`` columns).

        Returns ``(A, N, q0)`` with ``A = [[0, I], [dz''/dz, dz''/dz']]`` (2 f x 2 f) of the closed-loop
        accelerations ``z'' = N^T q''`` on the manifold: by Richardson-extrapolated differences with an error
        estimate (:func:`ctmm.loop_manifold.accurate_tangent`, refused by name when not accurate; ``step=None``), or
        by plain central differences at ``step`` [rad] (:func:`ctmm.loop_manifold.tangent_matrix`, no estimate).
        """
        return self._tangent(q0, t, step)[:3]

    def _tangent(self, q0, t: float, step: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        n = self.require_static("linearize")
        q0, _ = self.project(np.asarray(self.tree.state(q0, np.zeros(n))[0], float), np.zeros(n), t, iterations=30)
        basis = loop_manifold.independent_basis(self, q0, t)
        if step is None:
            A, error = loop_manifold.accurate_tangent(self, q0, basis, t)
            return A, basis, q0, error
        return loop_manifold.tangent_matrix(self, q0, basis, t, validation.positive("step", step)), basis, q0, np.nan

    def resting_tangent(self, q0, t: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """:meth:`linearize` about the resting state ``q0`` and its estimated Jacobian error relative to
        ``max |A|`` (:func:`ctmm.loop_manifold.accurate_tangent`), ``(A, N, q0, error)``; kept per
        ``(q0, t, baumgarte)`` on this model (the frequency-domain tools ask for the same tangent at every frequency
        they refine; at most 8 kept)."""
        q0 = np.asarray(q0, dtype=float)
        key = (q0.tobytes(), float(t), self.baumgarte)
        if key not in self._tangents:
            if len(self._tangents) >= 8:
                self._tangents.pop(next(iter(self._tangents)))
            self._tangents[key] = self._tangent(q0, t, None)
        A, basis, q_on, error = self._tangents[key]
        return A.copy(), basis.copy(), q_on.copy(), error

    def natural_frequencies(self, q0, t: float = 0.0) -> np.ndarray:
        """Undamped natural frequencies [rad/s] about the resting state ``q0`` (an equilibrium: refused
        otherwise), ascending, from :meth:`resting_tangent` (:func:`ctmm.loop_manifold.undamped_frequencies`)."""
        A, basis, q0, error = self.resting_tangent(q0, t)
        loop_manifold.require_equilibrium(self, A, basis, q0, t, "KinematicLoopModel.equilibrium")
        return loop_manifold.undamped_frequencies(self, A, error)

    def equilibrium(self, q_guess, t: float = 0.0, *, tolerance: float = 1e-10, largest_step: float = 0.2
                    ) -> np.ndarray:
        """A static equilibrium near ``q_guess`` (projected onto the constraints): Newton on the independent
        coordinates ``z``, each step at most ``largest_step`` [rad] (a far guess, e.g. the tree's hanging
        configuration, does not leap across the mechanism's range), converged when the accelerations are below
        ``tolerance`` or the Newton step is below ``tolerance`` [rad] (:func:`ctmm.loop_manifold.newton_equilibrium`);
        the last 8 kept on this model."""
        n = self.require_static("equilibrium")
        q = np.asarray(self.tree.state(q_guess, np.zeros(n))[0], float)
        key = (q.tobytes(), float(t), float(tolerance), float(largest_step), self.baumgarte)
        if key not in self._equilibria:
            q_on, _ = self.project(q, np.zeros(n), t, iterations=30)
            if len(self._equilibria) >= 8:
                self._equilibria.pop(next(iter(self._equilibria)))
            self._equilibria[key] = loop_manifold.newton_equilibrium(self, q_on, t, tolerance=tolerance,
                                                                     largest_step=largest_step)
        return self._equilibria[key].copy()


def simulate_kinematic_loops(model: KinematicLoopModel, q0, qdot0, *, t_final: float, dt: float | None = None,
                         method: str = "rk4", projection: bool = True, rtol: float = 1e-9, atol: float = 1e-11,
                         store_every: int = 1, t_eval: np.ndarray | None = None,
                         max_step: float | None = None) -> KinematicLoopSimulation:
    """Integrate a closed-loop model from a consistent state (:meth:`KinematicLoopModel.consistent_state`).

    Parameters
    ----------
    model : KinematicLoopModel
    q0, qdot0 : array_like (n_coordinates,)
        Initial tree coordinates and rates (checked against the constraints: ``|Phi|``, ``|Phi'| <= 1e-8``,
        :func:`ctmm.loop_integration.check_consistent`).
    t_final : float
        End time [s] (RK4: a whole multiple of ``dt``, as every fixed-step method).
    dt : float, optional
        Fixed step [s] (required for ``"rk4"``).
    method : str
        ``"rk4"`` (fixed step, projection after every step when ``projection``) or a ``solve_ivp`` method
        (``"RK45"``, ``"DOP853"``, ...; Baumgarte only).
    projection : bool
        Project onto the constraints after every RK4 step.
    rtol, atol : float
        ``solve_ivp`` tolerances.
    store_every : int
        Store every k-th RK4 step.
    t_eval : ndarray, optional
        ``solve_ivp`` methods: the times [s] to store (default: every accepted step).
    max_step : float, optional
        ``solve_ivp`` methods: the largest step [s] (default ``dt``, else no limit).

    Raises
    ------
    ModelError
        Bad arguments or an inconsistent initial state.
    SimulationError
        A singular loop configuration, a non-finite state or (RK4 with projection) a failed projection: ``|Phi|``
        above :data:`ctmm.loop_integration.PROJECTION_TOLERANCE` after it (time, cut joint, partial result); a
        deformable body of the tree beyond its range (the tree runs' rule, ``family.check_divergence``: a modal beam's
        deflection bound beyond its length, a finite-element subsystem's displacement beyond its size; time, body,
        partial result), checked after every RK4 step and at every stored ``solve_ivp`` state.
    """
    if not isinstance(model, KinematicLoopModel):
        raise ModelError(f"model must be a KinematicLoopModel, got {model!r}")
    t_final = validation.positive("t_final", t_final)
    store_every = validation.integer("store_every", store_every, minimum=1)
    q, v = model.tree.state(q0, qdot0)
    q, v = np.asarray(q, float).copy(), np.asarray(v, float).copy()
    check_consistent(model, q, v, "q0, qdot0")
    n = len(q)
    evaluations = [0]
    # RK4: the cut forces of the first stage at every stored time (the stored row itself), reused by loop_history
    solved: dict[float, tuple[bytes, np.ndarray]] = {}
    stored = (lambda t: False) if method != "rk4" else (
        lambda t: (k := int(round(t / dt))) * dt == t and k % store_every == 0)

    def rate(t, y):
        evaluations[0] += 1
        qdd, forces = model.solve(y[:n], y[n:], t)
        if stored(t):
            solved[t] = (y.tobytes(), forces)
        return np.concatenate([y[n:], qdd])

    family, step = model.tree.deformable_family, dt if method == "rk4" else None
    check = None if family is None else (    # the tree runs' rule: a modal beam's deflection, a subsystem's size
        lambda t, y: family.check_divergence(model.tree, y[:n], float(t), step, method))
    return integrate_loop_run(
        lambda t, q_rows, qdot_rows, wall: loop_history(model, t, q_rows, qdot_rows, method, wall, evaluations[0],
                                                        solved),
        rate, np.concatenate([q, v]), n, t_final=t_final, dt=dt, method=method, finish=lambda y, t: y, rtol=rtol,
        atol=atol, store_every=store_every, t_eval=t_eval, max_step=max_step, label=f"kinematic loop {model.name!r}",
        element=model.cuts[0].name, velocity_label="qdot", model=model if projection else None, check=check)


def loop_history(model: KinematicLoopModel, t: np.ndarray, q: np.ndarray, qdot: np.ndarray, method: str,
                 wall: float, evaluations: int, solved: dict | None = None) -> KinematicLoopSimulation:
    """Stored rows of a run (times [s], tree coordinates, rates) with the cut forces [N] solved again at each row and
    the drift ``max |Phi|`` [m], ``max |Phi'|`` [m/s]; ``wall`` [s] and ``evaluations`` as the run reports them.
    ``solved``: ``{t: (state bytes, cut forces)}`` the run already solved at exactly a row's time and state (the
    same numbers :meth:`KinematicLoopModel.solve` gives again), used instead of solving again."""
    forces, drift, drift_rate = [], [], []
    solved = {} if solved is None else solved
    for t_k, q_k, v_k in zip(t, q, qdot):
        phi, phi_dot = model.constraints(q_k, v_k, t_k)
        drift.append(np.max(np.abs(phi)))
        drift_rate.append(np.max(np.abs(phi_dot)))
        state, known = solved.get(float(t_k), (None, None))
        if state is None or state != np.concatenate([q_k, v_k]).tobytes():
            known = model.solve(q_k, v_k, t_k)[1]
        forces.append(known)
    return KinematicLoopSimulation(model, np.asarray(t), np.asarray(q), np.asarray(qdot),
                                   np.array(forces).reshape(len(t), len(model.cuts), 2), np.array(drift),
                                   np.array(drift_rate), method, wall, evaluations)
