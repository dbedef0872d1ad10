"""A planar model as an articulated tree (:class:`PlanarScene`) for the one sweep (:mod:`ctmm.articulated`):
its bodies and joints on the element protocol (:mod:`ctmm.protocol`), and their terms linearised about a
static operating point (:class:`LinearTerms`, the frequency context).

* the rigid-body and hinge families -- :mod:`ctmm.planar.family_terms` (:func:`rigid_body_terms`,
  :func:`revolute_terms`, :func:`driven_terms`, :func:`free_base_terms`, :func:`bushing_terms`,
  :class:`SceneNumbers`; re-exported here);
* :func:`beam_terms` -- the modal beam (:mod:`ctmm.planar.beam_body_terms`: an adapter over
  :meth:`ctmm.flexible.beam.BeamData.terms`, numpy and casadi).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..articulated import Articulated, Tree, articulated_sweep, frequency_kappa
from ..errors import ModelError, SimulationError
from ..ops import NUMPY, Ops
from ..protocol import BodyTerms, JointTerms
from .beam_body_terms import beam_terms, symbolic_beam_terms
from .family_terms import (SceneNumbers, bushing_terms, driven_terms, free_base_terms, nonlinear_bushing_terms,
                           numeric_value, revolute_terms, rigid_body_terms)
from .hinge_laws import law_joint_terms
from .model import BUSHING, DRIVEN, FREE, REVOLUTE, PlanarModel
from .rigid_sweep import model_sweep

__all__ = ["rigid_body_terms", "revolute_terms", "driven_terms", "free_base_terms", "bushing_terms", "beam_terms",
           "PlanarScene", "LinearTerms", "SceneNumbers"]


#: ``S`` of a planar revolute hinge (the rotation about e3), shared by the hinges of :meth:`PlanarScene.linear_terms`
_HINGE_AXIS = np.array([[[0.0], [0.0], [1.0]]])
_HINGE_AXIS.flags.writeable = False
#: a held hinge's zero torque amplitude (read-only, shared)
_NO_TORQUE = np.zeros((1, 1, 1), dtype=complex)
_NO_TORQUE.flags.writeable = False


def _entry(ops: Ops, column: Any, k: int) -> Any:
    return ops.sub(column, slice(k, k + 1), slice(0, 1))


@dataclass(frozen=True)
class LinearTerms:
    """Body and joint terms of a planar model linearised about a static operating point
    (:meth:`PlanarScene.linear_terms`).

    Attributes
    ----------
    tree : Tree
    bodies : tuple of (M0, C0, K0, Kin, RF)
        Per body: mass, damping and stiffness matrices ``(3 + n, 3 + n)`` of ``Z(s) = s^2 M0 + s C0 + K0``
        [kg, N s, N and their moment and modal units], and the point kinematics and wrench maps at
        the operating point.
    joints : tuple of JointTerms
        Driven joints held; others with their law's tangents and torque amplitudes.
    """

    tree: Tree
    bodies: tuple
    joints: tuple

    def sweep(self, s: Any) -> Articulated:
        """The frequency context of the one sweep at the Laplace variables ``s`` (B,) [1/s], batched."""
        s = np.asarray(s, dtype=complex).reshape(-1, 1, 1)
        linear = [BodyTerms(s * s * M0 + s * C0 + K0, np.zeros((1, M0.shape[0], 1), dtype=complex), Kin,
                            dict.fromkeys(Kin), RF)
                  for M0, C0, K0, Kin, RF in self.bodies]
        return articulated_sweep(NUMPY, self.tree, linear, self.joints, frequency_kappa(NUMPY, self.joints, s),
                                 characteristic=True)




def _modal(ops: Ops, column: Any, idx: np.ndarray) -> Any:
    """Modal coordinates ``idx`` of a column: numpy ``(B, n)``; symbolic: an object array ``(1, n)``."""
    if not len(idx):
        return None
    if ops is NUMPY:
        return column[:, idx, 0]
    out = np.empty((1, len(idx)), dtype=object)
    out[0, :] = [column[int(k)] for k in idx]
    return out


class PlanarScene:
    """A :class:`~ctmm.planar.model.PlanarModel` (rigid bodies and modal beams) as bodies and joints
    on the protocol, for :func:`ctmm.articulated.articulated_sweep`.

    Parameters
    ----------
    model : PlanarModel
        Any planar model: rigid bodies and modal beams; revolute (every law), driven, free-base and
        translational-spring hinges.
    """

    def __init__(self, model: PlanarModel) -> None:
        if not isinstance(model, PlanarModel):
            raise ModelError(f"PlanarScene: model must be a ctmm.planar.PlanarModel, got {model!r}")
        self.model = model
        self.beam_points = {j: tuple(b.ends) for j, b in model.beams.items()}
        points = []
        for j in range(model.n_bodies):
            p = int(model.parent[j])
            if p < 0:
                points.append(None)
            elif p in self.beam_points:
                points.append(self.beam_points[p][model.parent_end_index[j]])
            else:
                points.append(model.parent_end[j])
        self.tree = Tree(tuple(int(p) for p in model.parent), tuple(points), 3)

    def terms(self, ops: Ops, q: Any, qdot: Any, t: float = 0.0, inputs: Any = None,
              numbers: SceneNumbers | None = None) -> tuple[list[BodyTerms], list[JointTerms]]:
        """Body and joint terms at coordinates ``q`` and rates ``qdot`` (ops columns
        ``(B, n, 1)`` for numpy, ``(n, 1)`` for casadi) and time ``t`` [s].

        ``inputs``: :class:`ctmm.planar.ports.ActuatorInputs` (numeric), optional.  ``numbers``: the
        bodies', hinge laws' and loads' numbers (default the model's at ``t``, :meth:`SceneNumbers.of`);
        symbols for generated code that takes them as inputs.
        """
        if inputs is not None and getattr(inputs, "frame_wrench", None):
            raise ModelError("station forces and moments on a beam's floating frame (actuators "
                             "'<beam>.<station>.force|moment') are not on the element protocol yet; use the "
                             "sweep of ctmm.planar.accelerations (ctmm.simulate without compiled=True)")
        m = self.model
        numbers = SceneNumbers.of(m, t) if numbers is None else numbers
        # the prescribed motions: the numbers' (symbols of t in generated code) or the model's at t
        driven = numbers.driven if numbers.driven is not None else {i: (a, r, acc) for i, a, r, acc in m.driven(t)}
        all_loads = numbers.loads
        end_motion, bodies, joints = {}, [], []
        for j in range(m.n_bodies):
            p = int(m.parent[j])
            if p >= 0:
                th_end, om_end = end_motion[(p, self.tree.point[j])]
            else:
                th_end, om_end = float(m.ground_angle[j]), 0.0
            if j in driven:
                angle, rate, _ = driven[j]
                th, om = th_end + angle, om_end + rate
            else:
                k = int(m.theta_index[j])
                th, om = _entry(ops, q, k), _entry(ops, qdot, k)
            idx = m.modal_index[j]
            e = _modal(ops, q, idx)
            ed = _modal(ops, qdot, idx)
            body, ends = self.body_terms(ops, j, th, om, e, ed, t, inputs, all_loads, numbers)
            end_motion.update({(j, name): motion for name, motion in ends.items()})
            bodies.append(body)
            joints.append(self._joint_terms(ops, j, th - th_end, om - om_end, q, qdot, inputs, numbers, driven))
        return bodies, joints

    def _joint_terms(self, ops: Ops, j: int, angle: Any, rate: Any, q: Any, qdot: Any, inputs: Any,
                     numbers: SceneNumbers, driven: Mapping[int, tuple]) -> JointTerms:
        """The inboard joint of body ``j`` at relative angle ``angle`` [rad] and rate ``rate`` [rad/s] (ops
        scalars); ``q, qdot``: the coordinate columns of :meth:`terms` (offsets of translational springs);
        ``driven``: ``{body: (angle, rate, acceleration)}`` of ``model.driven(t)``."""
        m = self.model
        kind = int(m.joint_kind[j])
        if j in driven:
            return driven_terms(ops, driven[j][2])
        if kind == FREE:
            return free_base_terms(ops)
        extra = 0.0 if inputs is None else numeric_value(inputs.hinge_torque[j])
        if kind == BUSHING and j in m.nonlinear_hinges:
            ix, iy = (int(i) for i in m.xy_index[j])
            return nonlinear_bushing_terms(ops, m.nonlinear_hinges[j], _entry(ops, q, ix), _entry(ops, q, iy), angle,
                                           rate, extra)
        if kind == BUSHING:
            ix, iy = (int(i) for i in m.xy_index[j])
            return bushing_terms(
                ops, offset=(_entry(ops, q, ix), _entry(ops, q, iy)),
                offset_rate=(_entry(ops, qdot, ix), _entry(ops, qdot, iy)), angle=angle, rate=rate,
                translational_stiffness=m.translational_stiffness[j],
                translational_damping=m.translational_damping[j], stiffness=numbers.stiffness[j],
                damping=numbers.damping[j], reference=numbers.reference[j], reference_rate=numbers.reference_rate[j],
                torque=numbers.torque[j] + extra)
        if j in m.nonlinear_hinges:
            tau, tau_q, tau_v = law_joint_terms(ops, m.nonlinear_hinges[j], angle, rate, extra)
            return JointTerms(S=ops.block([[0.0], [0.0], [1.0]]), tau=ops.block([[tau]]), tau_q=ops.block([[tau_q]]),
                              tau_v=ops.block([[tau_v]]), axis=2)
        return revolute_terms(ops, angle=angle, rate=rate, stiffness=numbers.stiffness[j], damping=numbers.damping[j],
                              reference=numbers.reference[j], reference_rate=numbers.reference_rate[j],
                              torque=numbers.torque[j] + extra)

    def body_terms(self, ops: Ops, j: int, theta: Any, omega: Any, eta: Any, eta_dot: Any, t: float,
                   inputs: Any = None, loads: Any = None, numbers: SceneNumbers | None = None
                   ) -> tuple[BodyTerms, dict]:
        """Terms of body ``j`` at absolute angle ``theta`` [rad], rate ``omega`` [rad/s] and, for a beam,
        modal coordinates ``eta`` and rates ``eta_dot`` (numpy ``(B, n)``); also ``{point: (angle, rate)}``
        of its outboard points.  ``loads``: ``model.loads(t)`` (evaluated when omitted); ``numbers``: of
        :meth:`terms` (default the model's)."""
        m = self.model
        if loads is None:
            loads = m.loads(t) if len(m.load_body) else np.zeros((0, 3))
        if numbers is None:
            numbers = SceneNumbers(m.mass, m.inertia, m.com, m.ends, m.gravity, m.stiffness, m.damping, (), (), (),
                                   loads, m.load_point)
        if j in m.beams and ops is not NUMPY:
            return symbolic_beam_terms(ops, m.beams[j].data, self.beam_points[j], theta, omega, eta, eta_dot, t,
                                        m.gravity, None if inputs is None else inputs.modal_force.get(j))
        if j in m.beams:
            th_b, om_b = np.asarray(theta).reshape(-1), np.asarray(omega).reshape(-1)
            batch = max(eta.shape[0], eta_dot.shape[0], th_b.size, om_b.size)
            modal = None if inputs is None else inputs.modal_force.get(j)
            body, ends = beam_terms(m.beams[j].data, self.beam_points[j], np.broadcast_to(th_b, (batch,)),
                                    np.broadcast_to(om_b, (batch,)), np.broadcast_to(eta, (batch, eta.shape[1])),
                                    np.broadcast_to(eta_dot, (batch, eta_dot.shape[1])), t, m.gravity, modal)
            return body, {name: (a.reshape(-1, 1, 1), r.reshape(-1, 1, 1))
                          for name, (a, r) in zip(self.beam_points[j], ends)}
        rows = [k for k in range(len(m.load_body)) if int(m.load_body[k]) == j]
        force = None if inputs is None else tuple(numeric_value(v) for v in inputs.body_force[j])
        body = rigid_body_terms(ops, mass=numbers.mass[j], inertia=numbers.inertia[j],
                                center_of_mass=numbers.center_of_mass[j], points=numbers.ends[j],
                                gravity=numbers.gravity, theta=theta, omega=omega,
                                loads=[(*numbers.load_point[k], *loads[k]) for k in rows], body_force=force)
        return body, {name: (theta, omega) for name in m.ends[j]}

    def frequency(self, q0: Any, s: Any, t: float = 0.0, torque: Mapping[int, complex] | None = None,
                  *, step: float = 1e-30) -> Articulated:
        """The frequency context of the one sweep about a static operating point ``q0`` (rates 0).

        Each body's terms are linearised about ``q0`` (:meth:`linear_terms`): ``Z(s) = s^2 M0 + s C0 + K0``
        with ``K0 = d(h + sum_e RF_e F_e0)/d(theta, eta)`` (``F_e0``: the static wrenches at its points, the
        geometric stiffness of the preload) and ``C0 = dh/d(omega, eta_dot)``, both by complex step
        through the batched terms (exact to round-off); ``Kin`` and ``RF`` at ``q0``, ``c = 0``.  Joints:
        ``kappa(s) = k + c s``, driven joints held.  The unknowns are displacement amplitudes
        ``x = [dx, dy, dtheta ; d eta]``.

        Parameters
        ----------
        q0 : array_like (n_coordinates,)
            An equilibrium (else :class:`ModelError`).
        s : array_like (B,)
            Laplace variables [1/s].
        t : float
            Time of the operating point [s] (loads, hinge references).
        torque : mapping of body index to complex, optional
            Hinge-torque amplitudes [N m] across the inboard joints (default none: the homogeneous
            problem, whose :attr:`~ctmm.articulated.Articulated.characteristic` is
            ``prod det D_j prod det C_j``).
        step : float
            Complex step.

        Returns
        -------
        Articulated
            Batched over ``s``.
        """
        return self.linear_terms(q0, t, torque, step=step).sweep(s)

    def linear_terms(self, q0: Any, t: float = 0.0, torque: Mapping[int, complex] | None = None,
                     *, step: float = 1e-30) -> "LinearTerms":
        """The terms of :meth:`frequency` about ``q0``, linearised once, to sweep at many ``s``
        (:meth:`LinearTerms.sweep`); arguments as for :meth:`frequency`.

        Each body is evaluated at ``q0`` and at a complex step per own coordinate and rate (rigid bodies with
        the same points and number of loads in one batched :func:`rigid_body_terms`); the evaluation at ``q0``
        is the static one (equilibrium check, wrenches ``F_e0``: the explicit sweep on those terms, traced for rigid
        trees)."""
        m = self.model
        q0 = np.asarray(q0, dtype=float)
        n = m.n_coordinates
        if q0.shape != (n,) or not np.all(np.isfinite(q0)):
            raise ModelError(f"PlanarScene.frequency: q0 must be {n} finite coordinates "
                             f"({', '.join(m.coordinates)}), got {q0!r}")
        zero = np.zeros(n)
        numbers = SceneNumbers.of(m, t)
        theta, omega = m.body_angles(q0, zero, t)
        evaluated = self._perturbed_terms(q0, theta, omega, t, numbers, step)
        driven = {i: (a, r, acc) for i, a, r, acc in m.driven(t)}
        # plain revolute hinges (the law of revolute_terms) stated here directly: numbers, not ops
        plain = (m.joint_kind == REVOLUTE) & ~np.isin(np.arange(m.n_bodies), [*driven, *m.nonlinear_hinges])
        tau_q = np.negative(np.asarray(numbers.stiffness, dtype=float)).reshape(-1, 1, 1)
        tau_v = np.negative(np.asarray(numbers.damping, dtype=float)).reshape(-1, 1, 1)
        groups: dict = {}                           # the bodies of one batched evaluation
        for j, (body, _, _) in enumerate(evaluated):
            groups.setdefault(id(body), (body, []))[1].append(j)
        at_point = {}                               # each group's terms at the operating point: (members, ...)
        for key, (body, members) in groups.items():
            rows = body.M.shape[0] // len(members)
            at_point[key] = (rows, BodyTerms(body.M[::rows].real, body.h[::rows].real,
                                             *({e: v[::rows].real for e, v in part.items()}
                                               for part in (body.Kin, body.c, body.RF))))
        # Python floats in the loop (the same IEEE arithmetic as numpy scalars, without their overhead)
        angle, rate, parent, is_plain = theta.tolist(), omega.tolist(), m.parent.tolist(), plain.tolist()
        reference, reference_rate, torque_law, stiffness, damping = (
            np.asarray(x, dtype=float).tolist() for x in (numbers.reference, numbers.reference_rate, numbers.torque,
                                                         numbers.stiffness, numbers.damping))
        bodies, joints, end_motion = [], [], {}
        for j, (body, row, ends) in enumerate(evaluated):
            rows, own = at_point[id(body)]
            at = slice(row // rows, row // rows + 1)
            bodies.append(BodyTerms(own.M[at], own.h[at], {e: v[at] for e, v in own.Kin.items()},
                                    {e: v[at] for e, v in own.c.items()}, {e: v[at] for e, v in own.RF.items()}))
            for name, motion in ends.items():
                end_motion[(j, name)] = motion
            p = parent[j]
            th_end, om_end = end_motion[(p, self.tree.point[j])] if p >= 0 else (float(m.ground_angle[j]), 0.0)
            if is_plain[j]:
                tau = ((angle[j] - th_end) - reference[j]) * -stiffness[j] \
                    - ((rate[j] - om_end) - reference_rate[j]) * damping[j] + (torque_law[j] + 0.0)
                joints.append(JointTerms(S=_HINGE_AXIS, tau=np.full((1, 1, 1), tau), tau_q=tau_q[j:j + 1],
                                         tau_v=tau_v[j:j + 1], axis=2))
                continue
            joints.append(self._joint_terms(NUMPY, j, np.full((1, 1, 1), theta[j] - th_end),
                                            np.full((1, 1, 1), omega[j] - om_end), q0[None, :, None],
                                            zero[None, :, None], None, numbers, driven))
        residual, static_force = self._static(bodies, joints)
        limit = 1e-8 * (1.0 + float(np.max(np.abs(m.gravity))))
        if not residual <= limit:
            raise ModelError(f"PlanarScene.frequency: q0 is not an equilibrium of {m.name!r} (largest acceleration "
                             f"{residual:.3e} > {limit:.1e})")
        end_force: dict = {}
        for c in range(m.n_bodies):
            if self.tree.parent[c] >= 0:
                key = (self.tree.parent[c], self.tree.point[c])
                end_force[key] = end_force.get(key, 0.0) + static_force[c]
        linear: list = [None] * m.n_bodies
        for body, members in groups.values():
            # Q = h + sum_e RF_e F_e0 at every row; its complex-step slopes are K0 (theta, eta) and C0 (rates)
            k = (body.M.shape[0] // len(members) - 1) // 2           # own coordinates: theta, eta
            rows = 1 + 2 * k
            Q = body.h
            for e, RF in body.RF.items():
                F = np.zeros((len(members), 3, 1))
                for g, j in enumerate(members):
                    if (j, e) in end_force:
                        F[g] = end_force[(j, e)]
                if np.any(F):
                    Q = Q + RF @ np.repeat(F, rows, axis=0)
            size = Q.shape[1]
            slopes = Q.reshape(len(members), rows, size).imag.swapaxes(1, 2) / step   # (members, 3 + n, rows)
            K0, C0 = np.zeros((2, len(members), size, size))
            K0[:, :, [2, *range(3, size)]] = slopes[:, :, 1:k + 1]
            C0[:, :, [2, *range(3, size)]] = slopes[:, :, k + 1:]
            M0 = at_point[id(body)][1].M
            for g, j in enumerate(members):
                linear[j] = (M0[g], C0[g], K0[g], bodies[j].Kin, bodies[j].RF)
        amplitudes = dict(torque or {})
        held = []
        for j, joint in enumerate(joints):
            if is_plain[j]:
                amplitude = complex(amplitudes.pop(j, 0.0))
                held.append(JointTerms(S=_HINGE_AXIS, tau=np.full((1, 1, 1), amplitude) if amplitude else _NO_TORQUE,
                                       tau_q=joint.tau_q, tau_v=joint.tau_v, axis=2))
            elif joint.prescribed is not None:
                held.append(JointTerms(S=joint.S, prescribed=np.zeros((1, 1, 1)), axis=joint.axis))
            elif joint.free == 3:
                held.append(JointTerms(S=joint.S, tau=np.zeros((1, 3, 1)), tau_q=joint.tau_q, tau_v=joint.tau_v))
            else:
                amplitude = complex(amplitudes.pop(j, 0.0))
                held.append(JointTerms(S=joint.S, tau=np.full((1, 1, 1), amplitude) if amplitude else _NO_TORQUE,
                                       tau_q=joint.tau_q, tau_v=joint.tau_v, axis=joint.axis))
        if amplitudes:
            raise ModelError(f"PlanarScene.frequency: torque given for bodies {sorted(amplitudes)} whose inboard "
                             "joints are not revolute")
        return LinearTerms(self.tree, tuple(linear), tuple(held))

    def _static(self, bodies: list, joints: list) -> tuple[float, Any]:
        """The explicit sweep on the terms at the operating point (B = 1): the largest coordinate acceleration
        (``nan`` where the articulated inertia is singular) and each body's inboard joint wrench ``(3, 1)``.

        Rigid trees on revolute and driven hinges (a free base at the ground) run the traced sweep of
        :func:`ctmm.planar.rigid_sweep.model_sweep` (the one recursion, the same terms: ``K = M``, ``b = h``, the
        parent points' ``Kin``, ``RF``, ``c``), the others :func:`~ctmm.articulated.articulated_sweep` on numpy."""
        m = self.model
        kinds = set(m.joint_kind.tolist())
        if m.beams or not kinds <= {REVOLUTE, DRIVEN, FREE} or any(m.joint_kind[m.parent >= 0] == FREE) or \
                any(body.M.shape[-1] != 3 for body in bodies):
            static = articulated_sweep(NUMPY, self.tree, bodies, joints)
            return (float(np.max(np.abs(self.coordinate_accelerations(static)), initial=0.0)),
                    [f[0] for f in static.force])
        nb = m.n_bodies
        E = np.zeros((nb, 6))
        hung = np.flatnonzero(m.parent >= 0)
        if hung.size:
            carried = [(bodies[self.tree.parent[j]], self.tree.point[j]) for j in hung]
            Kin, RF, c = (np.concatenate([getattr(body, part)[point] for body, point in carried])
                          for part in ("Kin", "RF", "c"))
            E[hung] = np.column_stack([Kin[:, 0, 2], Kin[:, 1, 2], RF[:, 2, 0], RF[:, 2, 1], c[:, 0, 0], c[:, 1, 0]])
        tau, driven = np.zeros(nb), np.zeros(nb)
        for j, joint in enumerate(joints):
            if joint.prescribed is not None:
                driven[j] = joint.prescribed[0, 0, 0]
            elif joint.free == 1:
                tau[j] = joint.tau[0, 0, 0]
        K = np.concatenate([body.M for body in bodies]).reshape(nb, 9)
        b = np.concatenate([body.h for body in bodies]).reshape(nb, 3)
        try:
            A, F, _ = model_sweep(m)(K, b, E, np.zeros(nb), tau, driven)
        except SimulationError:
            return float("nan"), None
        qddot = np.zeros(m.n_coordinates)
        qddot[m.theta_index[m.theta_index >= 0]] = A[m.theta_index >= 0, 2]
        for j in np.flatnonzero(m.joint_kind == FREE):
            qddot[m.xy_index[j]] = A[j, :2]
        return float(np.max(np.abs(qddot), initial=0.0)), F[:, :, None]

    def _perturbed_terms(self, q0: np.ndarray, theta: np.ndarray, omega: np.ndarray, t: float,
                         numbers: SceneNumbers, step: float) -> list:
        """Per body ``(terms, row, ends)``: its terms at ``1 + 2 k`` rows (``k = 1 + n_j`` own coordinates; row 0
        at the operating point, then ``i step`` on theta, each eta, omega, each eta rate), stacked in the batch
        of its group's evaluation from row ``row`` on, and ``{point: (angle, rate)}`` at the operating point."""
        m = self.model
        out: list = [None] * m.n_bodies
        load_rows: dict = {}
        for k in range(len(m.load_body)):
            load_rows.setdefault(int(m.load_body[k]), []).append(k)
        groups: dict = {}
        for j in range(m.n_bodies):
            if j in m.beams:
                idx = m.modal_index[j]
                k = 1 + len(idx)
                perturb = np.zeros((1 + 2 * k, 2 * k), dtype=complex)
                perturb[1:, :] = 1j * step * np.eye(2 * k)
                body, ends = self.body_terms(NUMPY, j, (theta[j] + perturb[:, 0]).reshape(-1, 1, 1),
                                             (omega[j] + perturb[:, k]).reshape(-1, 1, 1),
                                             q0[idx][None, :] + perturb[:, 1:k], perturb[:, k + 1:], t, None,
                                             numbers.loads)
                out[j] = (body, 0, {e: (float(a[0, 0, 0].real), float(r[0, 0, 0].real)) for e, (a, r) in ends.items()})
            else:
                groups.setdefault((tuple(m.ends[j]), len(load_rows.get(j, ()))), []).append(j)
        def rows(values: Any) -> np.ndarray:            # one value per member -> (3 members, 1, 1)
            return np.repeat(np.asarray(values, dtype=float), 3).reshape(-1, 1, 1)

        at_loads = np.column_stack([np.reshape(numbers.load_point, (-1, 2)), np.reshape(numbers.loads, (-1, 3))])
        for (names, count), members in groups.items():
            shift, rate = (np.tile(u, len(members)).reshape(-1, 1, 1) for u in ([0, 1j * step, 0], [0, 0, 1j * step]))
            com = np.asarray([numbers.center_of_mass[j] for j in members], dtype=float).reshape(-1, 2)
            points = {e: tuple(rows([numbers.ends[j][e][i] for j in members]) for i in (0, 1)) for e in names}
            loads = [tuple(rows(column) for column in at_loads[[load_rows[j][slot] for j in members]].T)
                     for slot in range(count)]
            body = rigid_body_terms(NUMPY, mass=rows(np.asarray(numbers.mass)[members]),
                                    inertia=rows(np.asarray(numbers.inertia)[members]),
                                    center_of_mass=(rows(com[:, 0]), rows(com[:, 1])), points=points,
                                    gravity=numbers.gravity, theta=rows(theta[members]) + shift,
                                    omega=rows(omega[members]) + rate, loads=loads)
            for g, j in enumerate(members):
                out[j] = (body, 3 * g, {e: (float(theta[j]), float(omega[j])) for e in names})
        return out

    def coordinate_accelerations(self, solution: Articulated) -> np.ndarray:
        """``qddot`` (B, n) from a numpy sweep's result."""
        m = self.model
        batch = max(np.shape(x)[0] for x in solution.x)
        dtype = np.result_type(*solution.x)
        out = np.zeros((batch, m.n_coordinates), dtype=dtype)
        for j, x in enumerate(solution.x):
            if np.shape(x)[0] != batch:
                x = np.broadcast_to(x, (batch,) + np.shape(x)[1:])
            if m.theta_index[j] >= 0:
                out[:, m.theta_index[j]] = x[:, 2, 0]
            if m.joint_kind[j] == FREE:
                out[:, m.xy_index[j]] = x[:, :2, 0]
            elif m.joint_kind[j] == BUSHING:         # the offset's acceleration: the joint's relative one
                out[:, m.xy_index[j]] = np.broadcast_to(solution.relative[j], (batch, 3, 1))[:, :2, 0]
            if len(m.modal_index[j]):
                out[:, m.modal_index[j]] = x[:, 3:, 0]
        return out

    def accelerations(self, q: Any, qdot: Any, t: float = 0.0, inputs: Any = None) -> np.ndarray:
        """Generalised accelerations by the one sweep, batched: ``q, qdot`` (B, n) -> (B, n)
        (float or complex; complex for complex-step tangents).

        Raises
        ------
        SimulationError
            A singular articulated inertia (non-finite accelerations), naming the time.
        """
        return self.coordinate_accelerations(self.solution(q, qdot, t, inputs))

    def solution(self, q: Any, qdot: Any, t: float = 0.0, inputs: Any = None) -> Articulated:
        """The explicit sweep's whole result (accelerations, joint forces, relative accelerations),
        batched: ``q, qdot`` (B, n) or (n,) as for :meth:`accelerations`.

        Raises
        ------
        SimulationError
            A singular articulated inertia (non-finite accelerations), naming the time.
        """
        q, qdot = np.asarray(q), np.asarray(qdot)
        if q.ndim == 1:
            q = q[None]
        if qdot.ndim == 1:
            qdot = qdot[None]
        n = self.model.n_coordinates
        if q.shape[1:] != (n,) or qdot.shape[1:] != (n,):
            raise ModelError(f"PlanarScene.accelerations: q and qdot must be (B, {n}) arrays (coordinates "
                             f"{', '.join(self.model.coordinates)}), got shapes {q.shape} and {qdot.shape}")
        bodies, joints = self.terms(NUMPY, q[:, :, None], qdot[:, :, None], t, inputs)
        with np.errstate(all="ignore"):
            try:
                solution = articulated_sweep(NUMPY, self.tree, bodies, joints)
            except np.linalg.LinAlgError as exc:
                raise SimulationError(f"articulated inertia of model {self.model.name!r} is singular ({exc})",
                                      time=t) from exc
        if not all(np.all(np.isfinite(x)) for x in solution.x):
            raise SimulationError(f"articulated inertia of model {self.model.name!r} is singular (non-finite "
                                  "accelerations)", time=t)
        return solution
