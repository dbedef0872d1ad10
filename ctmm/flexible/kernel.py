"""Per-model data and body terms of planar trees of rigid bodies and modal beams, swept by the one
articulated sweep (:func:`ctmm.articulated.articulated_sweep`).

Every body ``j`` provides its transfer relations in the generalised form (``n_j`` modal
coordinates, ``n_j = 0`` for a rigid body; ``x_j = [A_I ; eta'']``):

``[F_I ; 0] = M_j x_j + h_j + sum_e RF_e F_e``   (Newton-Euler + modal equations)
``A_e = Kin_e x_j + c_e``                         (kinematics of outboard end ``e``)

``F_e`` is the wrench exerted by body ``j`` on what hangs at end ``e``.  For a rigid body
``M = K``, ``Kin = X``, ``RF = X^T`` (FORMULAS 3.4, ``docs/planar.md``); for a beam see
:mod:`ctmm.flexible.beam`.  :meth:`FlexibleSystem.sweep` hands these terms (unbatched 2-D
matrices, the ``B = 1`` fast path of :mod:`ctmm.ops`) with the joints (revolute ``S = e3`` with the
hinge torque and tangent ``kappa``, driven, free base) to the one sweep, which eliminates the modal
accelerations locally and the joints tip to base (``docs/planar.md``, "The one articulated
sweep"); cost O(sum (3 + n_j)^3), linear in the number of bodies.

The implicit DT-TMM (:mod:`ctmm.flexible.implicit`) feeds the same sweep with Newton-tangent
relations: the body relations depend on the body's own angle, rate, modal coordinates and
rates, which the integrator ties to the body's own unknowns (``d theta = beta' h^2 d alpha``,
``d eta = beta' h^2 d eta''``, rates with ``gamma' h``); the tangent columns are computed by
complex-step differentiation of the body terms (exact to round-off), so every Newton iteration
is again one O(n) sweep of transfer relations.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..articulated import Tree, articulated_sweep
from ..errors import ModelError, SimulationError
from ..ops import NUMPY
from ..planar.model import DRIVEN, FREE, REVOLUTE, PlanarModel
from ..protocol import BodyTerms, JointTerms

_E3_COLUMN = np.array([[0.0], [0.0], [1.0]])
_EYE3 = np.eye(3)
_ZERO3 = np.zeros((3, 1))


@dataclass(frozen=True)
class FlexibleSolution:
    """Accelerations, joint forces and modal accelerations at one instant.

    Attributes
    ----------
    qddot : (n_coordinates,)
    body_acceleration : (n_bodies, 3)
        ``[a_x, a_y, alpha]`` at each body's inboard end.
    joint_force : (n_bodies, 3)
        ``[f_x, f_y, tau]`` exerted on each body at its inboard end by its parent / ground.
    hinge_acceleration : (n_bodies,)
        Relative angular acceleration of each body's joint.
    end_acceleration : (n_bodies, 3)
        State ``A`` of the parent end each body hangs on.
    modal_acceleration : dict
        ``{body name: eta''}`` of the flexible bodies.
    """

    qddot: np.ndarray
    body_acceleration: np.ndarray
    joint_force: np.ndarray
    hinge_acceleration: np.ndarray
    end_acceleration: np.ndarray
    modal_acceleration: dict


class FlexibleSystem:
    """Per-model data of the mixed sweep (built once, by the model's constructor; see :func:`system_of`)."""

    def __init__(self, model: PlanarModel) -> None:
        if np.any(model.joint_kind == 3):
            raise ModelError("hinges with translational springs are not supported together with "
                             "flexible bodies yet")
        self.model = model
        nb = model.n_bodies
        self.nb = nb
        self.parent = model.parent.tolist()
        self.kind = model.joint_kind.tolist()
        self.pend = model.parent_end_index.tolist()
        self.beam_data = {j: b.data for j, b in model.beams.items()}
        self.n_modal = [self.beam_data[j].n if j in self.beam_data else 0 for j in range(nb)]
        self.modal_index = model.modal_index
        self.rigid = [j for j in range(nb) if j not in self.beam_data]
        # rigid loads (beam loads are handled by the beam terms)
        lb = model.load_body
        self.rigid_load_rows = [k for k in range(len(lb)) if int(lb[k]) not in self.beam_data]
        self.end_vectors = [[np.asarray(v, float) for v in model.ends[j].values()]
                            for j in range(nb)]
        self.free_base = [j for j in range(nb) if self.kind[j] == FREE]
        # the tree of the one sweep; a body's points are keyed by their index in its terms' end list
        self.tree = Tree(tuple(self.parent), tuple(None if p < 0 else e for p, e in zip(self.parent, self.pend)), 3)

    # -- per-body terms -------------------------------------------------------------------
    def rigid_terms(self, j: int, theta, omega, t: float, loads):
        """Batched complex-safe rigid-body relations (FORMULAS 3.4 in the generalised form)."""
        m = self.model
        mass, inertia = float(m.mass[j]), float(m.inertia[j])
        B = theta.shape[0]
        dtype = np.result_type(theta, omega, float)
        c, s = np.cos(theta), np.sin(theta)
        cx, cy = m.com[j]
        rcx, rcy = c * cx - s * cy, s * cx + c * cy
        gx, gy = m.gravity
        w2 = omega * omega
        M = np.zeros((B, 3, 3), dtype=dtype)
        M[:, 0, 0] = M[:, 1, 1] = mass
        M[:, 0, 2] = M[:, 2, 0] = -mass * rcy
        M[:, 1, 2] = M[:, 2, 1] = mass * rcx
        M[:, 2, 2] = inertia + mass * (rcx * rcx + rcy * rcy)
        h = np.zeros((B, 3), dtype=dtype)
        h[:, 0] = -mass * (w2 * rcx + gx)
        h[:, 1] = -mass * (w2 * rcy + gy)
        h[:, 2] = -mass * (rcx * gy - rcy * gx)
        for k in self.rigid_load_rows:
            if int(m.load_body[k]) != j:
                continue
            px, py = m.load_point[k]
            rex, rey = c * px - s * py, s * px + c * py
            fx, fy, mz = loads[k]
            h[:, 0] -= fx
            h[:, 1] -= fy
            h[:, 2] -= rex * fy - rey * fx + mz
        ends = []
        for v in self.end_vectors[j]:
            rx, ry = c * v[0] - s * v[1], s * v[0] + c * v[1]
            Kin = np.zeros((B, 3, 3), dtype=dtype)
            Kin[:, 0, 0] = Kin[:, 1, 1] = Kin[:, 2, 2] = 1.0
            Kin[:, 0, 2] = -ry
            Kin[:, 1, 2] = rx
            cc = np.zeros((B, 3), dtype=dtype)
            cc[:, 0] = -w2 * rx
            cc[:, 1] = -w2 * ry
            RF = np.transpose(Kin, (0, 2, 1)).copy()
            ends.append((Kin, cc, RF, theta, omega))
        return M, h, ends

    def body_terms(self, j: int, theta, omega, eta, eta_dot, t: float, loads):
        """Terms of body ``j`` (batched over the leading axis of ``theta``)."""
        if j in self.beam_data:
            return self.beam_data[j].terms(theta, omega, eta, eta_dot, t, self.model.gravity)
        return self.rigid_terms(j, theta, omega, t, loads)

    def state(self, q, qdot, t: float):
        """Angles, rates and modal coordinates of all bodies."""
        m = self.model
        theta, omega = m.body_angles(q, qdot, t)
        eta = [q[idx] for idx in self.modal_index]
        eta_dot = [qdot[idx] for idx in self.modal_index]
        return theta, omega, eta, eta_dot

    def all_terms(self, q, qdot, t: float):
        theta, omega, eta, eta_dot = self.state(q, qdot, t)
        loads = self.model.loads(t) if len(self.model.load_body) else np.zeros((0, 3))
        terms = []
        for j in range(self.nb):
            M, h, ends = self.body_terms(j, theta[j:j + 1], omega[j:j + 1], eta[j][None, :],
                                         eta_dot[j][None, :], t, loads)
            terms.append([M[0], h[0], [(K[0], c[0], R[0]) for K, c, R, _, _ in ends]])
        return terms, (theta, omega, eta, eta_dot, loads)

    def hinge_torques(self, q, qdot, theta, omega, t: float) -> np.ndarray:
        m = self.model
        dtheta, domega = m.relative_angles(theta, omega, q, qdot)
        reference, rate, torque = m.hinge_laws(t)
        return torque - m.stiffness * (dtheta - reference) - m.damping * (domega - rate)

    def driven_alpha(self, t: float) -> list:
        alpha = [0.0] * self.nb
        for i, _, _, acceleration in self.model.driven(t):
            alpha[i] = acceleration
        return alpha

    # -- the sweep ----------------------------------------------------------------------------
    def sweep(self, terms, kappa, tau, alpha_driven):
        """The one articulated sweep (:func:`ctmm.articulated.articulated_sweep`) of these terms.

        ``terms``: per body ``[M (3+n, 3+n), h (3+n,), [(Kin, c, RF) per end]]`` (unbatched, real);
        ``kappa``: joint tangent per body (revolute joints; 0 explicit); ``tau``: hinge torques
        [N m]; ``alpha_driven``: prescribed relative accelerations of driven joints [rad/s^2].

        Returns ``x`` (list of ``[A_I ; eta'']``), ``F`` (nb, 3), ``A_O`` (nb, 3) and the joint
        accelerations (nb,).

        Raises
        ------
        SimulationError
            A singular modal matrix or articulated inertia, naming the element.
        """
        bodies = []                                     # unbatched 2-D matrices: the B = 1 fast path of ops
        for M, h, ends in terms:
            bodies.append(BodyTerms(M, h.reshape(-1, 1), {e: end[0] for e, end in enumerate(ends)},
                                    {e: end[1].reshape(3, 1) for e, end in enumerate(ends)},
                                    {e: end[2] for e, end in enumerate(ends)}))
        tau_c = np.asarray(tau, dtype=float).reshape(-1, 1, 1)
        driven_c = np.asarray(alpha_driven, dtype=float).reshape(-1, 1, 1)
        kappa_c = np.asarray(kappa, dtype=float).reshape(-1, 1, 1)
        joints, kap = [], []
        for j, kj in enumerate(self.kind):
            if kj == REVOLUTE:
                joints.append(JointTerms(S=_E3_COLUMN, tau=tau_c[j]))
                kap.append(kappa_c[j] if kappa[j] else None)
            elif kj == DRIVEN:
                joints.append(JointTerms(S=_E3_COLUMN, prescribed=driven_c[j]))
                kap.append(None)
            else:                                       # FREE: a free base (rejected elsewhere otherwise)
                joints.append(JointTerms(S=_EYE3, tau=_ZERO3))
                kap.append(None)
        with np.errstate(all="ignore"):
            try:
                out = articulated_sweep(NUMPY, self.tree, bodies, joints, kap)
            except np.linalg.LinAlgError as exc:
                raise SimulationError(f"articulated inertia or modal matrix of model {self.model.name!r} is "
                                      f"singular ({exc})", element=self._singular_element(terms)) from exc
        for j, pivot in enumerate(out.pivot):
            if pivot is not None and pivot.shape[-1] == 1:
                d = pivot[0, 0]
                if not (d != 0.0 and abs(d) < np.inf):
                    raise SimulationError(f"articulated inertia of joint {self.model.joint_names[j]!r} is singular "
                                          f"({d!r})", element=self.model.joint_names[j])
        x = [xj[:, 0] for xj in out.x]
        if not np.all(np.isfinite(np.concatenate(x))):
            raise SimulationError(f"articulated inertia or modal matrix of model {self.model.name!r} is singular "
                                  "(non-finite accelerations)", element=self._singular_element(terms))
        F = np.array([f[:, 0] for f in out.force])
        alpha = np.array([0.0 if r is None else r[-1, 0] for r in out.relative])
        AO = np.array([xj[:3] for xj in x])         # A_O = A - S a_rel: revolute and driven S = e3
        AO[:, 2] -= alpha
        AO[self.free_base] = 0.0                     # a free base hangs on the ground
        return x, F, AO, alpha

    def _singular_element(self, terms) -> str | None:
        """Name of the body whose own modal matrix is worst conditioned (for error messages)."""
        beams = [j for j in range(self.nb) if self.n_modal[j]]
        if not beams:
            return None
        worst = max(beams, key=lambda j: np.linalg.cond(terms[j][0][3:, 3:]))
        return self.model.body_names[worst]

    def qddot(self, x) -> np.ndarray:
        m = self.model
        out = np.empty(m.n_coordinates)
        for j in range(self.nb):
            if m.theta_index[j] >= 0:
                out[m.theta_index[j]] = x[j][2]
            if m.joint_kind[j] == FREE:
                out[m.xy_index[j, 0]] = x[j][0]
                out[m.xy_index[j, 1]] = x[j][1]
            if self.n_modal[j]:
                out[self.modal_index[j]] = x[j][3:]
        return out

    def apply_inputs(self, terms: list, theta: np.ndarray, tau: np.ndarray, inputs) -> np.ndarray:
        """Add actuator ``inputs`` (:class:`ctmm.planar.ports.ActuatorInputs`) to the body
        terms (in place: the terms are this step's work arrays) and return the hinge torques."""
        if inputs is None:
            return tau
        wrench = inputs.inboard_wrench(self.model, theta)
        for j in self.rigid:
            terms[j][1] = terms[j][1] - wrench[j]
        for j in set(inputs.modal_force) | set(inputs.frame_wrench):
            h = terms[j][1].copy()
            h[3:] -= inputs.modal_force.get(j, 0.0)
            if j in inputs.frame_wrench:         # station loads on the beam's floating frame
                h[:3] -= wrench[j]
            terms[j][1] = h
        return tau + inputs.hinge_torque

    def solve(self, q, qdot, t: float = 0.0, inputs=None) -> FlexibleSolution:
        """Explicit forward dynamics (one sweep), with optional actuator ``inputs``."""
        q, qdot = self.model.state(q, qdot)
        terms, (theta, omega, _, _, _) = self.all_terms(q, qdot, t)
        tau = self.apply_inputs(terms, theta, self.hinge_torques(q, qdot, theta, omega, t), inputs)
        x, F, AO, alpha = self.sweep(terms, [0.0] * self.nb, tau.tolist(), self.driven_alpha(t))
        A = np.array([xj[:3] for xj in x])
        modal = {self.model.body_names[j]: x[j][3:].copy() for j in self.beam_data}
        return FlexibleSolution(self.qddot(x), A, F, alpha, AO, modal)

    def accelerations(self, q, qdot, t: float = 0.0, inputs=None) -> np.ndarray:
        """Generalised accelerations (one sweep), with optional actuator ``inputs``;
        ``q, qdot`` checked by :meth:`PlanarModel.state`."""
        q, qdot = self.model.state(q, qdot)
        terms, (theta, omega, _, _, _) = self.all_terms(q, qdot, t)
        tau = self.apply_inputs(terms, theta, self.hinge_torques(q, qdot, theta, omega, t), inputs)
        x, _, _, _ = self.sweep(terms, [0.0] * self.nb, tau.tolist(), self.driven_alpha(t))
        return self.qddot(x)


def system_of(model: PlanarModel) -> FlexibleSystem:
    """The :class:`FlexibleSystem` of a model with flexible bodies (built with the model,
    :attr:`ctmm.planar.PlanarModel.flexible_system`)."""
    if model.flexible_system is None:
        raise ModelError(f"model {model.name!r} has no flexible bodies")
    return model.flexible_system


def solve_flexible(model: PlanarModel, q, qdot, t: float = 0.0) -> FlexibleSolution:
    """Forward dynamics of a model with modal beams: accelerations, joint forces, modal
    accelerations (one O(n) sweep)."""
    return system_of(model).solve(q, qdot, t)


__all__ = ["FlexibleSolution", "FlexibleSystem", "solve_flexible", "system_of"]
