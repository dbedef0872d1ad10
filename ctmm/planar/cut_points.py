"""The points a planar cut joint joins: where they are, how they move and how the cut's loads act on them.

A side of a :class:`~ctmm.planar.cut_joints.CutJoint` is one of

* the **ground** (a :class:`~ctmm.planar.elements.Fixed` point): fixed, takes no load;
* a **rigid-body point** (a named end of a rigid body): moves with the body; a force acts at the centre of mass
  with the moment of its lever, a moment acts on the body;
* an **end of a deformable body**: an outboard end of a ``ctmm.flexible.ModalBeam`` or an outboard boundary node
  of a ``ctmm.fem`` subsystem (``FiniteElementModel.subsystem`` / ``GlobalSubsystem``).  Its position in the
  body's floating frame is ``X_e + S_e eta`` (``eta`` the body's internal coordinates; a modal beam's end:
  ``S_e = [[0, psi(x_e)], [phi(x_e), 0]]``, plus the foreshortening ``-1/2 w^T G1(x_e) w`` of the bent beam,
  ``docs/closed_loops.md`` §4b; a subsystem node: ``S_e`` picks the node's ``u_x, u_y``), its cross-section angle
  the frame angle plus ``d_e . eta`` (a beam's end slope ``phi'(x_e)``; a node's rotation ``r_z``, none for a
  particle).  A force ``f`` (frame components) does its virtual work through the same position: the frame
  wrench ``(f_x, f_y, x_P f_y - y_P f_x)`` (``(x_P, y_P)`` the deformed point) and the generalised force
  ``S_e^T f`` on ``eta`` (for a subsystem: a nodal load at that node); a moment ``tau`` the frame moment and
  ``tau d_e`` (``docs/closed_loops.md`` §4a, ``docs/mixed.md`` §5).

Every mechanism of :class:`~ctmm.planar.closed_loops.KinematicLoopModel` (constraints, their accelerations, the
cut loads as actuator inputs of the tree, the relative angles) reads the sides through :class:`CutPoints`.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..errors import ModelError
from .cut_joints import CutJoint
from .elements import Fixed
from .model import BUSHING, FREE, PlanarModel

__all__ = ["CutPoints"]


def _turn(angle: float, vector: np.ndarray) -> np.ndarray:
    """``R(angle) vector`` (frame to global axes)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * vector[0] - s * vector[1], s * vector[0] + c * vector[1]])


class CutPoints:
    """The two sides of every cut joint of a spanning tree (module docstring).

    Parameters
    ----------
    tree : PlanarModel
        The spanning tree.
    cuts : sequence of CutJoint
    foreshortening : bool
        A modal beam's end moves by the second-order shortening of the bent beam (``docs/closed_loops.md`` §4b).

    Attributes
    ----------
    sides : list of ((int, side), (int, side))
        Per cut ``(parent, child)``: ``(-1, ground position)``, ``(body index, body-frame vector from its inboard
        end)`` of a rigid-body point, or ``(body index, end index)`` of a deformable body's end.
    """

    def __init__(self, tree: PlanarModel, cuts: Sequence[CutJoint], foreshortening: bool) -> None:
        self.tree, self.foreshortening = tree, foreshortening
        grounds = {e.name: e for e in tree.elements if isinstance(e, Fixed)}
        self.sides = [(self._resolve(cut, cut.parent, grounds), self._resolve(cut, cut.child, {})) for cut in cuts]
        self.takes_moment = []
        """Per cut: whether its sides take a moment (not at a subsystem node without a rotation DOF)."""
        for cut, sides in zip(cuts, self.sides):
            (parent, _), (child, _) = sides
            if parent == child and child not in tree.beams:     # the points of one rigid body never move apart
                raise ModelError(f"cut joint {cut.name!r}: parent {cut.parent!r} and child {cut.child!r} are points of "
                                 f"the same rigid body {tree.body_names[child]!r}; a cut joint connects two different "
                                 "bodies (or a body and a ground point)")
            particles = [self.tree.body_names[j] + "." + self.tree.beams[j].data.end_names[e] for j, e in sides
                         if j >= 0 and not isinstance(e, np.ndarray) and self.is_subsystem(j)
                         and self.tree.beams[j].data.end_rows[e][2] is None]
            self.takes_moment.append(not particles)
            if particles and (cut.has_moment or cut.driven):
                raise ModelError(f"cut joint {cut.name!r}: {particles} are subsystem nodes without a rotation DOF (a "
                                 "particle takes no moment); a cut there takes no moment_law, torque or angle")

    def _resolve(self, cut: CutJoint, label: str, grounds: Mapping[str, Fixed]) -> tuple[int, np.ndarray | int]:
        """``(body index or -1 for ground, body-frame vector from the inboard end or ground position)``; on a
        deformable body ``(body index, end index)``."""
        m = self.tree
        if label in grounds:
            return -1, np.asarray(grounds[label].position, float)
        body, _, end = label.partition(".")
        if body not in m.body_names:
            raise ModelError(f"cut joint {cut.name!r}: {label!r} names no body of {m.name!r} (bodies: "
                             f"{', '.join(m.body_names)}; grounds: {', '.join(grounds) or 'none'})")
        j = m.body_names.index(body)
        if j in m.beams:
            data = m.beams[j].data
            if end not in data.end_names:
                what = ("outboard boundary nodes (subsystem(boundary=...))" if self.is_subsystem(j)
                        else "outboard points, stations named in ModalBeam(outboard={name: x})")
                raise ModelError(f"cut joint {cut.name!r}: deformable body {body!r} has no end {end!r}; cut points on "
                                 f"it are its {what}: {', '.join(data.end_names) or '(none)'}")
            return j, list(data.end_names).index(end)
        if end not in m.ends[j]:
            raise ModelError(f"cut joint {cut.name!r}: body {body!r} has no end {end!r}; ends: "
                             f"{', '.join(m.ends[j]) or '(none)'}")
        return j, np.asarray(m.ends[j][end], float)

    # -- the deformable end: shape, slope, foreshortening ------------------------------------------
    def is_subsystem(self, j: int) -> bool:
        """Whether body ``j`` is a ``ctmm.fem`` subsystem (it states its own point kinematics)."""
        return hasattr(self.tree.beams[j].data, "point_local")

    def _foreshortens(self, j: int) -> bool:
        return self.foreshortening and not self.is_subsystem(j)

    def end_shape(self, j: int, e: int) -> np.ndarray:
        """``S_e`` (2, n_eta): the frame displacement of end ``e`` of deformable body ``j`` per internal coordinate
        (its linear part; the foreshortening aside)."""
        data = self.tree.beams[j].data
        n = len(self.tree.modal_index[j])
        shape = np.zeros((2, n))
        if self.is_subsystem(j):
            ix, iy, _ = data.end_rows[e]
            shape[0, ix] = shape[1, iy] = 1.0
        else:
            shape[1, :data.nq] = data.end_phi[e]
            shape[0, data.nq:] = data.end_psi[e]
        return shape

    def end_slope(self, j: int, e: int) -> np.ndarray:
        """``d_e`` (n_eta,): the cross-section rotation of end ``e`` of deformable body ``j`` relative to its frame
        per internal coordinate (a beam's ``phi'(x_e)``, a node's ``r_z``; zeros for a particle)."""
        row = np.zeros(len(self.tree.modal_index[j]))
        slope = self.tree.beams[j].data.end_dphi[e]
        row[:len(slope)] = slope
        return row

    def end_local(self, j: int, e: int, q: np.ndarray, qdot: np.ndarray, qddot: np.ndarray | None = None
                  ) -> tuple[np.ndarray, ...]:
        """End ``e`` of deformable body ``j`` in its frame: position, velocity relative to the frame and, with
        ``qddot``, acceleration relative to the frame [m, m/s, m/s^2]; on a modal beam with the foreshortening
        ``u = -1/2 w^T G1 w`` of the transverse modal coordinates ``w`` (``u' = -w^T G1 w'``,
        ``u'' = -w'^T G1 w' - w^T G1 w''``) when :attr:`foreshortening`."""
        m = self.tree
        position, velocity = m.beam_point_local(j, e, q, qdot)
        acceleration = None if qddot is None else m.beam_point_local(j, e, q, qddot)[1]   # linear in the rates
        if self._foreshortens(j):
            data = m.beams[j].data
            index = m.modal_index[j][:data.nq]
            G, w, w_dot = data.end_G1[e], q[index], qdot[index]
            position[0] -= 0.5 * w @ G @ w
            velocity[0] -= w @ G @ w_dot
            if acceleration is not None:
                acceleration[0] -= w_dot @ G @ w_dot + w @ G @ qddot[index]
        return (position, velocity) if qddot is None else (position, velocity, acceleration)

    # -- kinematics --------------------------------------------------------------------------------
    def point(self, points: dict, j: int, e: np.ndarray | int) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Position [m], velocity [m/s] and lever ``r`` (from the inboard end, global) of a side (``points``:
        :meth:`PlanarModel.points` with ``"q"``, ``"qdot"``, ``"t"``)."""
        if j < 0:
            return e, np.zeros(2), None
        th, om = points["theta"][j], points["omega"][j]
        velocity = np.zeros(2)
        if not isinstance(e, np.ndarray):               # a deformable body's end: deformed, moving in the frame
            e, local = self.end_local(j, e, points["q"], points["qdot"])
            velocity = _turn(th, local)
        r = _turn(th, e)
        return points["inboard"][j] + r, points["inboard_velocity"][j] + om * np.array([-r[1], r[0]]) + velocity, r

    def rate_maps(self, points: dict) -> tuple[np.ndarray, np.ndarray]:
        """The tree's body rates as linear maps of ``qdot`` at the configuration of ``points`` (:meth:`point`):
        ``d omega / d qdot`` (n_bodies, n) [-] and ``d v_in / d qdot`` (n_bodies, 2, n) [m] of the inboard ends
        (:meth:`PlanarModel.body_angles` and :meth:`PlanarModel.points` differentiated in ``qdot``; a driven joint's
        prescribed rate is their affine part, not in the maps)."""
        m = self.tree
        n, q, theta = m.n_coordinates, points["q"], points["theta"]
        omega, inboard = np.zeros((m.n_bodies, n)), np.zeros((m.n_bodies, 2, n))
        for i in range(m.n_bodies):
            p = m.parent[i]
            if m.theta_index[i] >= 0:
                omega[i, m.theta_index[i]] = 1.0
            elif p >= 0:                                # driven: the parent's rate, plus its beam end's slope
                omega[i] = omega[p]
                slope = m.end_slope(i)
                omega[i, m.modal_index[p][:len(slope)]] += slope
            if p >= 0:
                e, local = m.end_vector[i], None
                if p in m.beams:                        # deformed end of a flexible parent
                    e, _ = m.beam_point_local(p, m.parent_end_index[i], q, np.zeros(n), True)
                    local = self._attachment_shape(p, m.parent_end_index[i], q)
                r = _turn(theta[p], e)
                inboard[i] = inboard[p] + np.outer((-r[1], r[0]), omega[p])
                if local is not None:
                    inboard[i][:, m.modal_index[p]] += _turn(theta[p], local)
            elif m.joint_kind[i] == FREE:
                inboard[i, (0, 1), m.xy_index[i]] = 1.0
            if m.joint_kind[i] == BUSHING:
                inboard[i, (0, 1), m.xy_index[i]] += 1.0
        return omega, inboard

    def _attachment_shape(self, j: int, e: int, q: np.ndarray) -> np.ndarray:
        """``d v_loc / d eta_dot`` (2, n_eta) of end ``e`` of deformable body ``j`` where a child body hangs
        (:meth:`PlanarModel.beam_point_local` with the shortening: a second-order modal beam's ``-w^T G1 w'``)."""
        shape = self.end_shape(j, e)
        data = self.tree.beams[j].data
        if not self.is_subsystem(j) and data.second_order is not None:
            shape[0, :data.nq] -= q[self.tree.modal_index[j][:data.nq]] @ data.end_G1[e]
        return shape

    def point_rate_map(self, points: dict, maps: tuple[np.ndarray, np.ndarray], j: int, e: np.ndarray | int
                       ) -> tuple[np.ndarray, np.ndarray]:
        """The velocity [m/s] and angular rate [rad/s] of a side (:meth:`point`, :meth:`angle`) as linear maps of
        ``qdot``: ``(2, n)`` and ``(n,)``, from the tree's :meth:`rate_maps` ``maps`` (their affine part, the
        driven joints' rates, aside)."""
        n = self.tree.n_coordinates
        if j < 0:
            return np.zeros((2, n)), np.zeros(n)
        omega, inboard = maps
        th = points["theta"][j]
        rate = omega[j].copy()
        if isinstance(e, np.ndarray):
            r = _turn(th, e)
            return inboard[j] + np.outer((-r[1], r[0]), omega[j]), rate
        index = self.tree.modal_index[j]
        position, _ = self.end_local(j, e, points["q"], np.zeros(n))
        local = self.end_shape(j, e)
        if self._foreshortens(j):                      # u' = -w^T G1 w'
            data = self.tree.beams[j].data
            local[0, :data.nq] -= points["q"][index[:data.nq]] @ data.end_G1[e]
        r = _turn(th, position)
        velocity = inboard[j] + np.outer((-r[1], r[0]), omega[j])
        velocity[:, index] += _turn(th, local)
        rate[index] += self.end_slope(j, e)
        return velocity, rate

    def acceleration(self, points: dict, A: np.ndarray, qddot: np.ndarray, j: int, e: np.ndarray | int,
                     lever: np.ndarray | None = None) -> np.ndarray:
        """Acceleration [m/s^2] of a side from the sweep's body accelerations ``A`` (inboard ends, ``(a_x, a_y,
        alpha)``) and ``qddot``: ``a_in + alpha k x r - omega^2 r`` and, at a deformable end,
        ``2 omega k x (R v_loc) + R a_loc``; ``lever``: its ``r`` from :meth:`point` at ``points`` when the caller
        has it.  At a rigid-body point or the ground ``A`` may have a leading batch axis (several solutions at the
        state of ``points``): the accelerations (n_batch, 2)."""
        if j < 0:
            return np.zeros(2)
        r = self.point(points, j, e)[2] if lever is None else lever
        om, al = points["omega"][j], A[..., j, 2:]
        acc = A[..., j, :2] + al * np.array([-r[1], r[0]]) - om * om * r
        if not isinstance(e, np.ndarray):
            th = points["theta"][j]
            _, local_v, local_a = self.end_local(j, e, points["q"], points["qdot"], qddot)
            v = _turn(th, local_v)
            acc = acc + 2.0 * om * np.array([-v[1], v[0]]) + _turn(th, local_a)
        return acc

    def angle(self, points: dict, j: int, e: np.ndarray | int) -> tuple[float, float]:
        """Angle [rad] and rate [rad/s] of a side: 0 at the ground, the body angle, or at a deformable end the frame
        angle plus ``d_e . eta`` (no conversion to float: traced on symbols, :mod:`ctmm.compiled_cut_points`)."""
        if j < 0:
            return 0.0, 0.0
        angle, rate = points["theta"][j], points["omega"][j]
        if not isinstance(e, np.ndarray):
            index, slope = self.tree.modal_index[j], self.end_slope(j, e)
            angle = angle + slope @ points["q"][index]
            rate = rate + slope @ points["qdot"][index]
        return angle, rate

    def angular_acceleration(self, A: np.ndarray, qddot: np.ndarray, j: int, e: np.ndarray | int) -> float:
        """Angular acceleration [rad/s^2] of a side (a deformable end: plus ``d_e . eta''``); at a rigid-body point
        ``A`` may have a leading batch axis (:meth:`acceleration`): (n_batch,)."""
        if j < 0:
            return 0.0
        if isinstance(e, np.ndarray):
            return A[..., j, 2] if A.ndim > 2 else float(A[j, 2])
        return float(A[j, 2] + self.end_slope(j, e) @ qddot[self.tree.modal_index[j]])

    # -- loads -------------------------------------------------------------------------------------
    def add_force(self, points: dict, j: int, e: np.ndarray | int, force: np.ndarray, body_force: np.ndarray,
                  modal: dict, frame: dict, lever: np.ndarray | None = None) -> None:
        """Add the force ``force`` (global axes [N]) on a side to the tree's loads, in place: ``body_force``
        (n_bodies, 3) at the centres of mass, ``modal`` / ``frame`` the generalised forces and frame wrenches of
        deformable bodies by index (module docstring); ``lever``: the side's ``r`` from :meth:`point` at ``points``
        when the caller has it."""
        if j < 0:
            return
        m, th = self.tree, points["theta"][j]
        if not isinstance(e, np.ndarray):
            c, s = np.cos(th), np.sin(th)
            local, _ = self.end_local(j, e, points["q"], points["qdot"])
            fx, fy = c * force[0] + s * force[1], -s * force[0] + c * force[1]
            frame[j] = frame.get(j, np.zeros(3)) + (fx, fy, local[0] * fy - local[1] * fx)
            generalised = self.end_shape(j, e).T @ np.array([fx, fy])
            if self._foreshortens(j):   # virtual work through the shortening d(-1/2 w^T G1 w) = -G1 w dw
                data = m.beams[j].data
                generalised[:data.nq] -= fx * (data.end_G1[e] @ points["q"][m.modal_index[j][:data.nq]])
            modal[j] = modal.get(j, np.zeros(len(m.modal_index[j]))) + generalised
            return
        r = self.point(points, j, e)[2] if lever is None else lever
        arm = r - _turn(th, m.com[j])
        body_force[j] += (force[0], force[1], arm[0] * force[1] - arm[1] * force[0])

    def add_moment(self, j: int, e: np.ndarray | int, moment: float, body_force: np.ndarray, modal: dict,
                   frame: dict) -> None:
        """Add the moment ``moment`` [N m] on a side to the tree's loads, in place (:meth:`add_force`): a pure
        moment on a rigid body; at a deformable end the frame moment and ``moment d_e``."""
        if j < 0:
            return
        if isinstance(e, np.ndarray):
            body_force[j, 2] += moment
            return
        frame[j] = frame.get(j, np.zeros(3)) + (0.0, 0.0, moment)
        modal[j] = modal.get(j, np.zeros(len(self.tree.modal_index[j]))) + moment * self.end_slope(j, e)
