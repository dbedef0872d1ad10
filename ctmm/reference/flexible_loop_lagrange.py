"""Independent assumed-modes Lagrange model of a four-bar linkage whose coupler is a flexible beam.

Written from scratch for the question of ``docs/closed_loops.md`` §4b: which second-order terms of the bent
coupler matter?  No code of :mod:`ctmm.flexible`, :mod:`ctmm.planar` or of the TMM sweep is used; the shapes come
from :func:`ctmm.reference.beams.clamped_free_mode` (references may share with references).

Model.  Crank (uniform link, mass ``m_c``, length ``l_c``, pivot at the origin) and rocker (``m_r``, ``l_r``, pivot
at ``(d, 0)``) are rigid; the coupler (length ``L``, ``rhoA``, ``EI``) hangs on the crank tip ``B`` with the root
tangent frame ``R(theta_b)`` and ``n`` clamped-free modes ``phi`` (``int_0^L phi_i^2 = L``).  Coordinates
``Q = [theta_c, theta_b, q_1..q_n, theta_r]`` (absolute angles).  The coupler is lumped into Gauss-Legendre mass
points ``dm = rhoA w_k`` (Euler-Bernoulli, no rotary inertia) at

``r_k = r_B + R(theta_b) [x_k + s u(x_k), phi(x_k) . q]``,   ``u(x) = -1/2 q^T G1(x) q``,
``G1(x) = int_0^x phi' phi'^T``

(the axial shortening of an inextensible bent beam).  ``inertia`` selects what the mass points carry:

* ``"second_order"``: ``s = 1``, every mass point moves with its shortening; Lagrange's equations of the exact
  kinetic and potential energy of these points, ``M(Q) Q'' + h(Q, Q') = Q_gravity - K q + C^T lambda``, carry the
  geometric stiffening (centrifugal, gravity, base acceleration) *and* its second-order reactions on the frame
  (the inertia of the shortening, its Coriolis forces, the changed first and second moments of mass);
* ``"stiffening"``: ``s = 0`` plus only the first-order geometric stiffness in the modal equations,
  ``Q_q = -sum_k dm (e1 . (g - a_rigid,k)) G1(x_k) q`` with the frame-axial acceleration
  ``e1 . a_rigid,k = e1 . a_B - omega_b^2 x_k`` of the undeformed point (``a_B`` affine in ``Q''``: non-symmetric
  rows of the mass matrix) -- what a floating-frame modal beam with geometric stiffening carries;
* ``"linear"``: ``s = 0``, nothing else.

The loop is closed at the coupler's station ``x_s`` (``cut_station``, default the end ``x = L``; shortened by
``u(x_s)`` when ``end_shortening``) and the rocker tip by two holonomic constraints with Lagrange multipliers (index-1 form, DOP853; the drift is reported).  The strain
energy is ``1/2 q^T K q``, ``K = EI int phi'' phi''^T``.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.integrate

from .beams import beta_roots, clamped_free_mode

INERTIA_FORMS = ("second_order", "stiffening", "linear")


def _gauss(n: int, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (b - a) * x + 0.5 * (a + b), 0.5 * (b - a) * w


def _rotation(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


class FlexibleFourBarLagrange:
    """Crank - flexible coupler - rocker, closed at the coupler's end or a station (see the module text).

    Parameters
    ----------
    crank, rocker : (mass [kg], length [m])
        Uniform rigid links.
    coupler : (length [m], mass per length [kg/m], bending stiffness [N m^2])
    ground : float
        Distance of the rocker pivot from the crank pivot along x [m].
    n_modes : int
        Clamped-free modes of the coupler.
    gravity : (2,) [m/s^2]
    inertia : {"second_order", "stiffening", "linear"}
    end_shortening : bool
        Close the loop at the shortened end ``x = L + u(L)`` (True) or at ``x = L`` (False).
    points : int
        Gauss points along the coupler (and for each ``G1(x_k)``).
    cut_station : float, optional
        Station ``x_s`` [m] of the coupler joined to the rocker tip (default ``L``; ``x_s < L``: the coupler
        overhangs the joint).
    """

    def __init__(self, crank, coupler, rocker, ground: float, n_modes: int, *, gravity=(0.0, -9.81),
                 inertia: str = "second_order", end_shortening: bool = True, points: int = 48,
                 cut_station: float | None = None) -> None:
        if inertia not in INERTIA_FORMS:
            raise ValueError(f"inertia must be one of {INERTIA_FORMS}, got {inertia!r}")
        self.mc, self.lc = map(float, crank)
        self.mr, self.lr = map(float, rocker)
        self.L, self.rhoA, self.EI = map(float, coupler)
        self.d = float(ground)
        self.n = int(n_modes)
        self.g = np.asarray(gravity, dtype=float)
        self.inertia = inertia
        self.s = 1.0 if inertia == "second_order" else 0.0
        self.s_end = 1.0 if end_shortening else 0.0
        betas = beta_roots("clamped-free", self.n)
        L = self.L

        def shapes(x, derivative):
            return np.array([clamped_free_mode(b, np.asarray(x) / L, derivative) for b in betas]) / L ** derivative

        def g1(x_end):
            xs, ws = _gauss(points, 0.0, x_end)
            dphi = shapes(xs, 1)
            return (dphi * ws) @ dphi.T

        x, w = _gauss(points, 0.0, L)
        self.x, self.dm = x, self.rhoA * w
        self.phi = shapes(x, 0).T                                  # (points, n)
        self.G1 = np.array([g1(xk) for xk in x])                   # (points, n, n)
        self.x_cut = L if cut_station is None else float(cut_station)
        if not 0.0 < self.x_cut <= L:
            raise ValueError(f"cut_station must lie on the coupler, 0 < x <= {L}, got {cut_station!r}")
        self.phi_end = shapes([self.x_cut], 0)[:, 0]
        self.G1_end = g1(self.x_cut)
        ddphi = shapes(x, 2)
        self.K = self.EI * (ddphi * w) @ ddphi.T
        self.nQ = self.n + 3

    # ------------------------------------------------------------------------------------------------
    def _split(self, Q):
        return Q[0], Q[1], Q[2:2 + self.n], Q[-1]

    def _coupler_points(self, Q, V, x, phi, G1, s):
        """Positions, Jacobians (P, 2, nQ) and bias accelerations (P, 2) of coupler points."""
        tc, tb, q, _ = self._split(Q)
        wc, wb, qd, _ = self._split(V)
        P = len(x)
        R = _rotation(tb)
        G1q = G1 @ q                                               # (P, n)
        u = -0.5 * (G1q @ q)
        ud = -(G1q @ qd)
        rho = np.stack([x + s * u, phi @ q], axis=1)               # (P, 2)
        rho_dot = np.stack([s * ud, phi @ qd], axis=1)
        rB = self.lc * np.array([math.cos(tc), math.sin(tc)])
        J = np.zeros((P, 2, self.nQ))
        J[:, :, 0] = self.lc * np.array([-math.sin(tc), math.cos(tc)])
        J[:, :, 1] = np.stack([-rho[:, 1], rho[:, 0]], axis=1) @ R.T
        local = np.stack([-s * G1q, phi], axis=1)                  # (P, 2, n): d rho / dq
        J[:, :, 2:2 + self.n] = np.einsum("ab,pbn->pan", R, local)
        bias_local = (-wb * wb * rho + 2 * wb * np.stack([-rho_dot[:, 1], rho_dot[:, 0]], axis=1)
                      + np.stack([-s * np.einsum("i,pij,j->p", qd, G1, qd), np.zeros(P)], axis=1))
        bias = -self.lc * wc * wc * np.array([math.cos(tc), math.sin(tc)]) + bias_local @ R.T
        position = rB + rho @ R.T
        return position, J, bias

    def _crank_rocker(self, Q):
        tc, _, _, tr = self._split(Q)
        M = np.zeros((self.nQ, self.nQ))
        M[0, 0] = self.mc * self.lc ** 2 / 3
        M[-1, -1] = self.mr * self.lr ** 2 / 3
        F = np.zeros(self.nQ)
        F[0] = self.mc * self.lc / 2 * (-math.sin(tc) * self.g[0] + math.cos(tc) * self.g[1])
        F[-1] = self.mr * self.lr / 2 * (-math.sin(tr) * self.g[0] + math.cos(tr) * self.g[1])
        return M, F

    def dynamics(self, Q, V):
        """``M (nQ, nQ)``, right-hand side ``f`` (nQ,) of ``M Q'' = f + C^T lambda``."""
        tc, tb, q, _ = self._split(Q)
        wc, wb, _, _ = self._split(V)
        _, J, bias = self._coupler_points(Q, V, self.x, self.phi, self.G1, self.s)
        M, f = self._crank_rocker(Q)
        M = M + np.einsum("p,pai,paj->ij", self.dm, J, J)
        f = f + np.einsum("p,pai,pa->i", self.dm, J, self.g[None, :] - bias)
        f[2:2 + self.n] -= self.K @ q
        if self.inertia == "stiffening":
            e1 = np.array([math.cos(tb), math.sin(tb)])
            JB = np.zeros(self.nQ)
            JB[0] = self.lc * (e1 @ np.array([-math.sin(tc), math.cos(tc)]))   # e1 . a_B = JB Q'' + bias_B
            bias_B = -self.lc * wc * wc * (e1 @ np.array([math.cos(tc), math.sin(tc)]))
            G1q = self.G1 @ q                                                     # (P, n)
            axial = e1 @ self.g - bias_B + wb * wb * self.x                        # e1 . (g - a_rigid) without Q''
            f[2:2 + self.n] -= np.einsum("p,p,pn->n", self.dm, axial, G1q)
            M[2:2 + self.n, :] -= np.outer(self.dm @ G1q, JB)
        return M, f

    def constraints(self, Q, V):
        """``Phi`` (2,), ``C = dPhi/dQ`` (2, nQ), bias ``gamma`` (``Phi'' = C Q'' + gamma``)."""
        _, _, _, tr = self._split(Q)
        _, _, _, wr = self._split(V)
        position, J, bias = self._coupler_points(Q, V, np.array([self.x_cut]), self.phi_end[None, :],
                                                 self.G1_end[None], self.s_end)
        tip = np.array([self.d, 0.0]) + self.lr * np.array([math.cos(tr), math.sin(tr)])
        C = J[0].copy()
        C[:, -1] -= self.lr * np.array([-math.sin(tr), math.cos(tr)])
        gamma = bias[0] + self.lr * wr * wr * np.array([math.cos(tr), math.sin(tr)])
        return position[0] - tip, C, gamma

    def accelerations(self, Q, V, baumgarte: float = 0.0):
        """``(Q'', lambda)`` of the index-1 system (optional Baumgarte rate ``baumgarte`` [1/s])."""
        M, f = self.dynamics(Q, V)
        phi, C, gamma = self.constraints(Q, V)
        rhs_c = -gamma - 2 * baumgarte * (C @ V) - baumgarte ** 2 * phi
        A = np.block([[M, -C.T], [C, np.zeros((2, 2))]])
        sol = np.linalg.solve(A, np.concatenate([f, rhs_c]))
        return sol[:self.nQ], sol[self.nQ:]

    def energy(self, Q, V) -> float:
        """Kinetic + gravity + strain energy [J] (conserved by ``"second_order"`` and ``"linear"``)."""
        tc, _, q, tr = self._split(Q)
        wc, _, _, wr = self._split(V)
        position, J, _ = self._coupler_points(Q, V, self.x, self.phi, self.G1, self.s)
        velocity = J @ V
        T = 0.5 * np.einsum("p,pa,pa->", self.dm, velocity, velocity)
        T += 0.5 * (self.mc * self.lc ** 2 / 3 * wc ** 2 + self.mr * self.lr ** 2 / 3 * wr ** 2)
        U = -np.einsum("p,pa,a->", self.dm, position, self.g) + 0.5 * q @ self.K @ q
        U -= self.mc * self.lc / 2 * (self.g @ [math.cos(tc), math.sin(tc)])
        U -= self.mr * self.lr / 2 * (self.g @ [math.cos(tr), math.sin(tr)])
        return float(T + U)

    def simulate(self, Q0, V0, t_eval, *, rtol: float = 1e-11, atol: float = 1e-12, baumgarte: float = 0.0):
        """States at ``t_eval`` (from ``t_eval[0]``): ``(Q (T, nQ), V (T, nQ), max |Phi| [m])``."""
        nQ = self.nQ

        def rhs(t, y):
            return np.concatenate([y[nQ:], self.accelerations(y[:nQ], y[nQ:], baumgarte)[0]])

        t_eval = np.asarray(t_eval, dtype=float)
        sol = scipy.integrate.solve_ivp(rhs, (t_eval[0], t_eval[-1]), np.concatenate([Q0, V0]), method="DOP853",
                                        t_eval=t_eval, rtol=rtol, atol=atol)
        if not sol.success:
            raise RuntimeError(f"FlexibleFourBarLagrange: {sol.message}")
        Q, V = sol.y[:nQ].T, sol.y[nQ:].T
        drift = max(float(np.max(np.abs(self.constraints(Qk, Vk)[0]))) for Qk, Vk in zip(Q, V))
        return Q, V, drift


__all__ = ["FlexibleFourBarLagrange", "INERTIA_FORMS"]
