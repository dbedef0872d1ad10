"""Independent global references for planar multibody chains and trees (no transfer matrices).

Two formulations written from scratch, sharing no code with :mod:`ctmm.planar` beyond the
model's plain parameter arrays (masses, inertias, body-frame vectors, parent indices, joint
kinds, hinge-law coefficients and signals):

* :class:`PlanarLagrange` -- Lagrange's equations in the model's generalised coordinates
  (absolute body angles, plus ``x, y`` of floating bases).  With ``r_C(q)`` linear in
  ``R(theta_i) v`` terms the kinetic energy is ``T = 1/2 qdot^T M(q) qdot`` with
  ``M = sum_k m_k J_Ck^T J_Ck + J_k Jw_k^T Jw_k`` built from the link geometry; Lagrange's
  equations then read ``M qddot = Q - sum_k J_Ck^T m_k a_bias,k - Jw_k^T J_k alpha_bias,k``
  where the bias terms are the accelerations at ``qddot = 0`` (the Christoffel terms
  ``Jdot qdot`` plus prescribed-motion terms).  Integrated with ``scipy.integrate.solve_ivp``
  at tight tolerance.  :meth:`PlanarLagrange.linearize` gives ``M, C, K`` about an
  equilibrium (``K`` includes the gravity / load geometric stiffness, analytic).
* :func:`newton_euler_kkt` -- the global Newton-Euler equations of all bodies in Cartesian
  centre-of-mass accelerations with the hinge reaction forces as Lagrange multipliers
  (sparse KKT system), giving instantaneous accelerations *and* joint forces.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.integrate
import scipy.linalg
import scipy.sparse
import scipy.sparse.linalg

from .cholesky import cholesky_solve

REVOLUTE, DRIVEN, FREE, BUSHING = 0, 1, 2, 3   # joint kinds, as stored in model.joint_kind


def _rot(theta, v):
    c, s = math.cos(theta), math.sin(theta)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def _perp(r):
    """k x r for a planar vector r."""
    return np.array([-r[1], r[0]])


def _cross(a, b) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


class PlanarLagrange:
    """Lagrange model of a :class:`~ctmm.planar.model.PlanarModel` (O(n^3) per evaluation).

    Parameters
    ----------
    model : PlanarModel
        Only its parameter arrays and signals are read.
    """

    def __init__(self, model) -> None:
        if getattr(model, "nonlinear_hinges", None):      # the linear law arrays would silently drop them
            raise ValueError("PlanarLagrange holds linear hinge laws only; for nonlinear hinges use "
                             "ctmm.reference.planar_dae")
        self.model = model
        self.nb = len(model.mass)
        self.n = len(model.coordinates)
        parent = np.asarray(model.parent)
        if np.any(parent >= np.arange(self.nb)):
            raise ValueError("bodies must be in topological order")
        # angle source: coordinate index that carries the body angle (-1: prescribed only)
        self.src = np.full(self.nb, -1, dtype=int)
        for i in range(self.nb):
            if model.theta_index[i] >= 0:
                self.src[i] = model.theta_index[i]
            elif parent[i] >= 0:
                self.src[i] = self.src[parent[i]]
        # fast path: all coordinates are angles, no prescribed motion
        self._fast = (np.all(model.joint_kind == REVOLUTE))
        if self._fast:
            self._prepare_fast()

    # -- kinematics ---------------------------------------------------------------------------
    def _angles(self, q, qdot, t):
        m = self.model
        theta, omega, alpha_bias = np.zeros(self.nb), np.zeros(self.nb), np.zeros(self.nb)
        driven = {i: (a, r, c) for i, a, r, c in m.driven(t)}
        for i in range(self.nb):
            p = m.parent[i]
            if m.theta_index[i] >= 0:
                theta[i] = q[m.theta_index[i]]
                omega[i] = qdot[m.theta_index[i]]
            else:
                a, r, c = driven[i]
                theta[i] = a + (theta[p] if p >= 0 else m.ground_angle[i])
                omega[i] = r + (omega[p] if p >= 0 else 0.0)
                alpha_bias[i] = c + (alpha_bias[p] if p >= 0 else 0.0)
        return theta, omega, alpha_bias

    def kinematics(self, q, qdot, t):
        """Points, Jacobians and bias accelerations of all bodies (general path)."""
        m = self.model
        theta, omega, alpha_bias = self._angles(q, qdot, t)
        n = self.n
        r_i = np.zeros((self.nb, 2))
        j_i = np.zeros((self.nb, 2, n))
        a_i = np.zeros((self.nb, 2))
        r_c = np.zeros((self.nb, 2))
        j_c = np.zeros((self.nb, 2, n))
        a_c = np.zeros((self.nb, 2))
        for k in range(self.nb):
            p = m.parent[k]
            if p >= 0:
                lever = _rot(theta[p], m.end_vector[k])
                r_i[k] = r_i[p] + lever
                j_i[k] = j_i[p]
                if self.src[p] >= 0:
                    j_i[k][:, self.src[p]] += _perp(lever)
                a_i[k] = a_i[p] + alpha_bias[p] * _perp(lever) - omega[p] ** 2 * lever
            elif m.joint_kind[k] == FREE:
                ix, iy = m.xy_index[k]
                r_i[k] = q[ix], q[iy]
                j_i[k][0, ix] = 1.0
                j_i[k][1, iy] = 1.0
            else:
                r_i[k] = m.ground_position[k]
            if m.joint_kind[k] == BUSHING:              # translational spring hinge: r_I += d
                ix, iy = m.xy_index[k]
                r_i[k] = r_i[k] + (q[ix], q[iy])
                j_i[k] = j_i[k].copy()
                j_i[k][0, ix] += 1.0
                j_i[k][1, iy] += 1.0
            lever = _rot(theta[k], m.com[k])
            r_c[k] = r_i[k] + lever
            j_c[k] = j_i[k]
            if self.src[k] >= 0:
                j_c[k][:, self.src[k]] += _perp(lever)
            a_c[k] = a_i[k] + alpha_bias[k] * _perp(lever) - omega[k] ** 2 * lever
        return dict(theta=theta, omega=omega, alpha_bias=alpha_bias, r_i=r_i, j_i=j_i,
                    r_c=r_c, j_c=j_c, a_c=a_c)

    def _generalised(self, q, qdot, t, kin):
        """Mass matrix and right-hand side ``Q - bias`` (general path)."""
        m = self.model
        n = self.n
        M = np.zeros((n, n))
        rhs = np.zeros(n)
        g = np.asarray(m.gravity)
        for k in range(self.nb):
            jc = kin["j_c"][k]
            M += m.mass[k] * jc.T @ jc
            rhs += jc.T @ (m.mass[k] * (g - kin["a_c"][k]))
            if self.src[k] >= 0:
                s = self.src[k]
                M[s, s] += m.inertia[k]
                rhs[s] -= m.inertia[k] * kin["alpha_bias"][k]
        loads = m.loads(t)
        for (body, point, (fx, fy, mz)) in zip(m.load_body, m.load_point, loads):
            lever = _rot(kin["theta"][body], point)
            je = kin["j_i"][body].copy()
            if self.src[body] >= 0:
                je[:, self.src[body]] += _perp(lever)
            rhs += je.T @ np.array([fx, fy])
            if self.src[body] >= 0:
                rhs[self.src[body]] += mz
        rhs += self._hinge_forces(kin["theta"], kin["omega"], t)
        for k in range(self.nb):
            if m.joint_kind[k] == BUSHING:
                ix, iy = m.xy_index[k]
                rhs[ix] -= m.translational_stiffness[k] * q[ix] + m.translational_damping[k] * qdot[ix]
                rhs[iy] -= m.translational_stiffness[k] * q[iy] + m.translational_damping[k] * qdot[iy]
        return M, rhs

    def _hinge_forces(self, theta, omega, t):
        m = self.model
        reference, rate, torque = m.hinge_laws(t)
        q_h = np.zeros(self.n)
        for k in range(self.nb):
            if m.joint_kind[k] not in (REVOLUTE, BUSHING):
                continue
            p = m.parent[k]
            dth = theta[k] - (theta[p] if p >= 0 else m.ground_angle[k])
            dom = omega[k] - (omega[p] if p >= 0 else 0.0)
            tau = torque[k] - m.stiffness[k] * (dth - reference[k]) - m.damping[k] * (dom - rate[k])
            if self.src[k] >= 0:
                q_h[self.src[k]] += tau
            if p >= 0 and self.src[p] >= 0:
                q_h[self.src[p]] -= tau
        return q_h

    # -- fast path: mass matrix M_ij = cos(th_j - th_i) P_ij + sin(th_j - th_i) S_ij --------
    def _prepare_fast(self):
        m = self.model
        nb = self.nb
        # v[i, k]: body-frame vector of body i towards body k's centre (0 if k not behind i)
        idx = m.theta_index
        P = np.zeros((nb, nb))
        S = np.zeros((nb, nb))
        lever_to = np.zeros((nb, nb, 2))     # lever_to[i, k]
        for k in range(nb):
            lever_to[k, k] = m.com[k]
            c = k
            while m.parent[c] >= 0:
                lever_to[m.parent[c], k] = m.end_vector[c]
                c = m.parent[c]
        mass = np.asarray(m.mass)
        vx, vy = lever_to[:, :, 0], lever_to[:, :, 1]
        P = (vx * mass) @ vx.T + (vy * mass) @ vy.T
        S = (vx * mass) @ vy.T - (vy * mass) @ vx.T
        P[np.diag_indices(nb)] += m.inertia
        order = np.argsort(idx)
        self._P, self._S = P[np.ix_(order, order)], S[np.ix_(order, order)]
        self._lever_to = lever_to[np.ix_(order, order)]
        self._fast_order = order
        self._inverse_order = np.argsort(order)
        # sum_k m_k v_ik (body frame of i): constant, the gravity term of _fast_terms
        self._mass_levers = np.einsum("k,ikc->ic", mass[order], self._lever_to)

    def _fast_terms(self, q, qdot, t):
        m = self.model
        th = np.asarray(q)[: self.nb]
        w = np.asarray(qdot)[: self.nb]
        d = th[None, :] - th[:, None]
        cd, sd = np.cos(d), np.sin(d)
        # (R_i a).(R_j b) = cos(d) a.b - sin(d) a x b,  (R_i a) x (R_j b) = cos(d) a x b + sin(d) a.b
        M = cd * self._P - sd * self._S
        # Christoffel terms: the acceleration at qddot = 0 is -sum_j w_j^2 R_j v_jk; its
        # projection on (k x R_i v_ik) is -(R_i v_ik) x (R_j v_jk) w_j^2
        bias = -(cd * self._S + sd * self._P) @ (w * w)
        # gravity: Q_i = sum_k m_k (k x R_i v_ik) . g
        g = np.asarray(m.gravity)
        mv = self._mass_levers                     # sum_k m_k v_ik (body frame of i)
        c, s = np.cos(th), np.sin(th)
        rx = c * mv[:, 0] - s * mv[:, 1]
        ry = s * mv[:, 0] + c * mv[:, 1]
        Q = -ry * g[0] + rx * g[1]
        return M, Q - bias

    # -- public ---------------------------------------------------------------------------------
    def mass_matrix(self, q, t: float = 0.0) -> np.ndarray:
        """Generalised mass matrix ``M(q)`` (general path)."""
        kin = self.kinematics(np.asarray(q, float), np.zeros(self.n), t)
        return self._generalised(q, np.zeros(self.n), t, kin)[0]

    def accelerations(self, q, qdot, t: float = 0.0) -> np.ndarray:
        """``qddot = M^{-1} (Q - bias)`` by a dense Cholesky solve."""
        q = np.asarray(q, dtype=float)
        qdot = np.asarray(qdot, dtype=float)
        m = self.model
        if self._fast and not len(m.load_body):
            M, rhs = self._fast_terms(q, qdot, t)
            theta = q[: self.nb]
            omega = qdot[: self.nb]
            inv = self._inverse_order
            rhs = rhs + self._hinge_forces(theta[inv], omega[inv], t)
        else:
            kin = self.kinematics(q, qdot, t)
            M, rhs = self._generalised(q, qdot, t, kin)
        return cholesky_solve(M, rhs)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """ODE right-hand side for ``y = [q, qdot]``."""
        n = self.n
        return np.concatenate([y[n:], self.accelerations(y[:n], y[n:], t)])

    def simulate(self, q0, qdot0, t_final: float, *, t_eval=None, rtol: float = 1e-12,
                 atol: float = 1e-12, method: str = "DOP853"):
        """Integrate with ``solve_ivp``; returns the scipy result (``y`` rows = [q, qdot])."""
        y0 = np.concatenate([np.asarray(q0, float), np.asarray(qdot0, float)])
        return scipy.integrate.solve_ivp(self.rhs, (0.0, t_final), y0, method=method,
                                         t_eval=t_eval, rtol=rtol, atol=atol)

    def linearize(self, q_eq, t: float = 0.0):
        """``(M, C, K)`` of the small motion about the equilibrium ``q_eq``.

        ``K`` is the Hessian of the potential (gravity, constant loads, hinge springs)
        including the geometric-stiffness terms of the static preload; ``C`` collects the hinge
        dampers.  Valid for models without driven hinges.
        """
        m = self.model
        if np.any(m.joint_kind == DRIVEN):
            raise ValueError("linearize: driven hinges are not supported")
        q_eq = np.asarray(q_eq, dtype=float)
        kin = self.kinematics(q_eq, np.zeros(self.n), t)
        M, rhs = self._generalised(q_eq, np.zeros(self.n), t, kin)
        K = np.zeros((self.n, self.n))
        C = np.zeros((self.n, self.n))
        g = np.asarray(m.gravity)
        # d Q_i / d theta_i for a constant force F at a point with Jacobian column (k x R v):
        # d/dtheta (k x R v) . F = -(R v) . F,  R v = (J_y, -J_x)
        for k in range(self.nb):
            force = m.mass[k] * g
            jc = kin["j_c"][k]
            for s in set(self.src[[k] + self._ancestors(k)]):
                if s >= 0:
                    K[s, s] += jc[1, s] * force[0] - jc[0, s] * force[1]
        loads = m.loads(t)
        for (body, point, (fx, fy, _)) in zip(m.load_body, m.load_point, loads):
            lever = _rot(kin["theta"][body], point)
            je = kin["j_i"][body].copy()
            if self.src[body] >= 0:
                je[:, self.src[body]] += _perp(lever)
            for s in set(self.src[[body] + self._ancestors(body)]):
                if s >= 0:
                    K[s, s] += je[1, s] * fx - je[0, s] * fy
        for k in range(self.nb):
            if m.joint_kind[k] == BUSHING:
                for i in m.xy_index[k]:
                    K[i, i] += m.translational_stiffness[k]
                    C[i, i] += m.translational_damping[k]
            if m.joint_kind[k] not in (REVOLUTE, BUSHING):
                continue
            e = np.zeros(self.n)
            if self.src[k] >= 0:
                e[self.src[k]] += 1.0
            p = m.parent[k]
            if p >= 0 and self.src[p] >= 0:
                e[self.src[p]] -= 1.0
            K += m.stiffness[k] * np.outer(e, e)
            C += m.damping[k] * np.outer(e, e)
        return M, C, K

    def _ancestors(self, k):
        out, p = [], self.model.parent[k]
        while p >= 0:
            out.append(p)
            p = self.model.parent[p]
        return out

    def natural_frequencies(self, q_eq) -> np.ndarray:
        """Undamped natural frequencies [rad/s] about ``q_eq`` (``eigh(K, M)``)."""
        M, _, K = self.linearize(q_eq)
        values = scipy.linalg.eigh(K, M, eigvals_only=True)
        return np.sqrt(np.maximum(values, 0.0))


@dataclass(frozen=True)
class KKTSolution:
    """Global Newton-Euler solution: coordinate accelerations, body data and joint forces."""

    qddot: np.ndarray
    com_acceleration: np.ndarray     # (nb, 2)
    angular_acceleration: np.ndarray  # (nb,)
    joint_force: np.ndarray          # (nb, 3): force / moment by parent on child at its inboard end


def newton_euler_kkt(model, q, qdot, t: float = 0.0) -> KKTSolution:
    """Instantaneous accelerations and hinge forces from the global Newton-Euler equations.

    Unknowns: centre-of-mass accelerations and angular accelerations of all bodies and the
    reaction forces of all joints (plus the torque of driven joints).  Equations: Newton and
    Euler (about the centre of mass) for every body, and the acceleration-level constraint of
    every joint (coincident points, prescribed relative angle).  Sparse LU solve.
    """
    if getattr(model, "nonlinear_hinges", None):
        raise ValueError("newton_euler_kkt holds linear hinge laws only; for nonlinear hinges use ctmm.reference.planar_dae")
    lag = PlanarLagrange.__new__(PlanarLagrange)
    lag.model, lag.nb, lag.n = model, len(model.mass), len(model.coordinates)
    lag.src = np.full(lag.nb, -1, dtype=int)
    theta, omega, _ = PlanarLagrange._angles(lag, np.asarray(q, float), np.asarray(qdot, float), t)
    nb = lag.nb
    driven = {i: c for i, _, _, c in model.driven(t)}
    c_, s_ = np.cos(theta), np.sin(theta)

    def rot(i, v):
        return np.array([c_[i] * v[0] - s_[i] * v[1], s_[i] * v[0] + c_[i] * v[1]])

    # reaction unknown offsets
    react = np.full(nb, -1, dtype=int)
    nr = 0
    for k in range(nb):
        if model.joint_kind[k] == REVOLUTE:
            react[k], nr = 3 * nb + nr, nr + 2
        elif model.joint_kind[k] == DRIVEN:
            react[k], nr = 3 * nb + nr, nr + 3
    size = 3 * nb + nr
    rows, cols, vals = [], [], []
    rhs = np.zeros(size)

    def add(r, c, v):
        rows.append(r)
        cols.append(c)
        vals.append(v)

    g = np.asarray(model.gravity)
    reference, rate, torque = model.hinge_laws(t)
    r_ci = [-rot(k, model.com[k]) for k in range(nb)]             # C -> I of body k
    # body equations
    for k in range(nb):
        add(3 * k, 3 * k, model.mass[k])
        add(3 * k + 1, 3 * k + 1, model.mass[k])
        add(3 * k + 2, 3 * k + 2, model.inertia[k])
        rhs[3 * k: 3 * k + 2] += model.mass[k] * g
    loads = model.loads(t)
    for (body, point, (fx, fy, mz)) in zip(model.load_body, model.load_point, loads):
        lever = rot(body, point) + r_ci[body]                    # C -> E
        rhs[3 * body] += fx
        rhs[3 * body + 1] += fy
        rhs[3 * body + 2] += _cross(lever, (fx, fy)) + mz
    bushing_force = {}
    for k in range(nb):
        if model.joint_kind[k] != BUSHING:
            continue
        # known spring forces: +f, +tau on the child at I_k; -f, -tau on the parent at O_k
        p = model.parent[k]
        ix, iy = model.xy_index[k]
        d = np.array([q[ix], q[iy]])
        f = -model.translational_stiffness[k] * d \
            - model.translational_damping[k] * np.array([qdot[ix], qdot[iy]])
        dth = theta[k] - (theta[p] if p >= 0 else model.ground_angle[k])
        dom = omega[k] - (omega[p] if p >= 0 else 0.0)
        tau = torque[k] - model.stiffness[k] * (dth - reference[k]) \
            - model.damping[k] * (dom - rate[k])
        bushing_force[k] = (f, tau)
        rhs[3 * k: 3 * k + 2] += f
        rhs[3 * k + 2] += _cross(r_ci[k], f) + tau
        if p >= 0:
            arm = rot(p, model.end_vector[k]) - rot(p, model.com[p])
            rhs[3 * p: 3 * p + 2] -= f
            rhs[3 * p + 2] -= _cross(arm, f) + tau
    for k in range(nb):
        p = model.parent[k]
        kind = model.joint_kind[k]
        if kind in (FREE, BUSHING):
            continue
        # joint force f acts +f on child at I_k, -f on parent at the same point
        col = react[k]
        arm_child = r_ci[k]
        add(3 * k, col, -1.0)
        add(3 * k + 1, col + 1, -1.0)
        add(3 * k + 2, col, arm_child[1])        # -(arm x f) = -(ax fy - ay fx)
        add(3 * k + 2, col + 1, -arm_child[0])
        if p >= 0:
            arm_parent = rot(p, model.end_vector[k]) - rot(p, model.com[p])   # C_p -> O
            add(3 * p, col, 1.0)
            add(3 * p + 1, col + 1, 1.0)
            add(3 * p + 2, col, -arm_parent[1])
            add(3 * p + 2, col + 1, arm_parent[0])
        if kind == REVOLUTE:
            dth = theta[k] - (theta[p] if p >= 0 else model.ground_angle[k])
            dom = omega[k] - (omega[p] if p >= 0 else 0.0)
            tau = torque[k] - model.stiffness[k] * (dth - reference[k]) \
                - model.damping[k] * (dom - rate[k])
            rhs[3 * k + 2] += tau
            if p >= 0:
                rhs[3 * p + 2] -= tau
        else:
            add(3 * k + 2, col + 2, -1.0)
            if p >= 0:
                add(3 * p + 2, col + 2, 1.0)
        # constraint rows: a_I(child) - a_O(parent) = 0 ; driven: alpha_k - alpha_p = acc
        row = col
        lev_k = r_ci[k]                                      # from C_k to I_k
        # a_I = a_Ck + alpha_k k x lev_k - w_k^2 lev_k
        add(row, 3 * k, 1.0)
        add(row + 1, 3 * k + 1, 1.0)
        add(row, 3 * k + 2, -lev_k[1])
        add(row + 1, 3 * k + 2, lev_k[0])
        rhs[row] += omega[k] ** 2 * lev_k[0]
        rhs[row + 1] += omega[k] ** 2 * lev_k[1]
        if p >= 0:
            lev_p = rot(p, model.end_vector[k]) - rot(p, model.com[p])
            add(row, 3 * p, -1.0)
            add(row + 1, 3 * p + 1, -1.0)
            add(row, 3 * p + 2, lev_p[1])
            add(row + 1, 3 * p + 2, -lev_p[0])
            rhs[row] -= omega[p] ** 2 * lev_p[0]
            rhs[row + 1] -= omega[p] ** 2 * lev_p[1]
        if kind == DRIVEN:
            add(row + 2, 3 * k + 2, 1.0)
            if p >= 0:
                add(row + 2, 3 * p + 2, -1.0)
            rhs[row + 2] = driven[k]
    matrix = scipy.sparse.csc_matrix((vals, (rows, cols)), shape=(size, size))
    x = scipy.sparse.linalg.spsolve(matrix, rhs)
    a_c = x[: 3 * nb].reshape(nb, 3)
    force = np.zeros((nb, 3))
    for k in range(nb):
        if react[k] >= 0:
            force[k, :2] = x[react[k]: react[k] + 2]
            if model.joint_kind[k] == DRIVEN:
                force[k, 2] = x[react[k] + 2]
    if np.any(model.joint_kind == REVOLUTE):
        for k in range(nb):
            if model.joint_kind[k] == REVOLUTE:
                p = model.parent[k]
                dth = theta[k] - (theta[p] if p >= 0 else model.ground_angle[k])
                dom = omega[k] - (omega[p] if p >= 0 else 0.0)
                force[k, 2] = torque[k] - model.stiffness[k] * (dth - reference[k]) \
                    - model.damping[k] * (dom - rate[k])
    for k, (f, tau) in bushing_force.items():
        force[k] = (f[0], f[1], tau)
    qddot = np.zeros(lag.n)
    for k in range(nb):
        if model.theta_index[k] >= 0:
            qddot[model.theta_index[k]] = a_c[k, 2]
        if model.joint_kind[k] == BUSHING:       # d_ddot = a_I(child) - a_O(parent end)
            p = model.parent[k]
            lev = r_ci[k]
            a_i = a_c[k, :2] + a_c[k, 2] * _perp(lev) - omega[k] ** 2 * lev
            if p >= 0:
                lev_p = rot(p, model.end_vector[k]) - rot(p, model.com[p])
                a_i = a_i - (a_c[p, :2] + a_c[p, 2] * _perp(lev_p) - omega[p] ** 2 * lev_p)
            qddot[model.xy_index[k, 0]], qddot[model.xy_index[k, 1]] = a_i
        if model.joint_kind[k] == FREE:
            lev = r_ci[k]
            a_i = a_c[k, :2] + a_c[k, 2] * _perp(lev) - omega[k] ** 2 * lev
            qddot[model.xy_index[k, 0]], qddot[model.xy_index[k, 1]] = a_i
    return KKTSolution(qddot, a_c[:, :2].copy(), a_c[:, 2].copy(), force)


__all__ = ["PlanarLagrange", "newton_euler_kkt", "KKTSolution"]
