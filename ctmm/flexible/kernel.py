"""O(n) articulated (Riccati) sweep for planar trees of rigid bodies and modal beams.

Every body ``j`` provides its transfer relations in the generalised form (``n_j`` modal
coordinates, ``n_j = 0`` for a rigid body; ``x_j = [A_I ; eta'']``):

``[F_I ; 0] = M_j x_j + h_j + sum_e RF_e F_e``   (Newton-Euler + modal equations)
``A_e = Kin_e x_j + c_e``                         (kinematics of outboard end ``e``)

``F_e`` is the wrench exerted by body ``j`` on what hangs at end ``e``.  For a rigid body
``M = K``, ``Kin = X``, ``RF = X^T`` (FORMULAS 3.4, ``docs/planar.md``); for a beam see
:mod:`ctmm.flexible.beam`.

Tip-to-base pass (children first): each child ``c`` at end ``e`` gives its articulated
relation at the connection point, ``F_e = Phi_hat_c A_e + psi_hat_c``; substituting the end
kinematics,

``M_j += RF_e Phi_hat_c Kin_e``,   ``h_j += RF_e (Phi_hat_c c_e + psi_hat_c)``.

Then the modal accelerations are eliminated locally (seed 003's second transfer equation),
``eta'' = -C^-1 (B A_I + d)`` with ``M_j = [[P, Q], [B, C]]``, ``h_j = [r ; d]``, which leaves the
3x3 articulated relation ``F_I = Phi A_I + psi``, ``Phi = P - Q C^-1 B``, ``psi = r - Q C^-1 d``.
The joint is eliminated as in ``docs/planar.md`` (revolute / implicit elastic: ``D = Phi_22 +
kappa``; driven: ``alpha`` given).  Base-to-tip pass: ``A_e`` of the parent end, joint
``alpha``, ``A_I``, ``eta''``, ``F_I``.  Cost O(sum (3 + n_j)^3): linear in the number of bodies.

The implicit DT-TMM (:mod:`ctmm.flexible.implicit`) feeds the same kernel with Newton-tangent
relations: the body relations depend on the body's own angle, rate, modal coordinates and
rates, which the integrator ties to the body's own unknowns (``d theta = beta' h^2 d alpha``,
``d eta = beta' h^2 d eta''``, rates with ``gamma' h``); the tangent columns are computed by
complex-step differentiation of the body terms (exact to round-off), so every Newton iteration
is again one O(n) sweep of transfer relations.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError, SimulationError
from ..planar.model import DRIVEN, FREE, REVOLUTE, PlanarModel

_E3 = np.array([0.0, 0.0, 1.0])


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
        """Tip-to-base elimination and base-to-tip pass (see the module docstring).

        Returns ``x`` (list of ``[A_I ; eta'']``), ``F`` (nb, 3), ``A_O`` (nb, 3) and the joint
        accelerations (nb,).
        """
        nb = self.nb
        parent, kind, pend = self.parent, self.kind, self.pend
        Macc = [t[0].copy() for t in terms]
        hacc = [t[1].copy() for t in terms]
        Phi, psi, W, w, D = [None] * nb, [None] * nb, [None] * nb, [None] * nb, [0.0] * nb
        for j in range(nb - 1, -1, -1):
            M, h = Macc[j], hacc[j]
            if self.n_modal[j]:
                C = M[3:, 3:]
                try:
                    sol = np.linalg.solve(C, np.column_stack([M[3:, :3], h[3:]]))
                except np.linalg.LinAlgError as exc:
                    raise SimulationError(f"modal matrix of body {self.model.body_names[j]!r} "
                                          f"is singular ({exc})", element=self.model.body_names[j]
                                          ) from exc
                W[j], w[j] = sol[:, :3], sol[:, 3]
                P = M[:3, :3] - M[:3, 3:] @ W[j]
                s = h[:3] - M[:3, 3:] @ w[j]
            else:
                P, s = M, h
            Phi[j], psi[j] = P, s
            kj = kind[j]
            if kj == REVOLUTE:
                d = P[2, 2] + kappa[j]
                if not (d != 0.0 and abs(d) < np.inf):
                    raise SimulationError(f"articulated inertia of joint "
                                          f"{self.model.joint_names[j]!r} is singular ({d!r})")
                D[j] = d
                Ph = P - np.outer(P[:, 2], P[2, :]) / d
                ph = s + P[:, 2] * ((tau[j] - s[2]) / d)
            elif kj == DRIVEN:
                Ph = P
                ph = s + P[:, 2] * alpha_driven[j]
            else:
                continue
            par = parent[j]
            if par < 0:
                continue
            Kin, cc, RF = terms[par][2][pend[j]]
            RP = RF @ Ph
            Macc[par] += RP @ Kin
            hacc[par] += RP @ cc + RF @ ph
        x = [None] * nb
        F = np.zeros((nb, 3))
        AO = np.zeros((nb, 3))
        alpha = np.zeros(nb)
        for j in range(nb):
            par = parent[j]
            if par >= 0:
                Kin, cc, _ = terms[par][2][pend[j]]
                a_o = Kin @ x[par] + cc
            else:
                a_o = np.zeros(3)
            kj = kind[j]
            P, s = Phi[j], psi[j]
            if kj == REVOLUTE:
                al = (tau[j] - P[2, :] @ a_o - s[2]) / D[j]
                A = a_o + _E3 * al
            elif kj == DRIVEN:
                al = alpha_driven[j]
                A = a_o + _E3 * al
            elif kj == FREE:
                A = np.linalg.solve(P, -s)
                al = A[2]
            else:  # pragma: no cover - rejected at construction
                raise ModelError(f"joint kind {kj} not supported with flexible bodies")
            if self.n_modal[j]:
                x[j] = np.concatenate([A, -(W[j] @ A + w[j])])
            else:
                x[j] = A
            F[j] = P @ A + s
            AO[j] = a_o
            alpha[j] = al
        return x, F, AO, alpha

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
