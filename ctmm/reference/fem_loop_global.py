"""Independent global model of a planar mechanism with closed loops whose branches hold finite-element beams.

No code of :mod:`ctmm.fem`, of the planar model, of the cut joints or of any sweep is used.  The mechanism is a set
of serial branches, each a :class:`ctmm.reference.mixed_global.GlobalChain` (Lagrange equations in minimal
coordinates: absolute angles, finite-element beams by their nodal displacements in the floating frame of their root
node, mass lumped into Gauss points, stiffness from the strain energy) hanging from its own ground pivot, and
**loop constraints**, each joining the outboard points of the last segments of two branches (a revolute joint:
the points coincide; for a beam its last node).  With ``r_a(q)``, ``J_a`` and the bias ``b_a = (dJ_a/dt) q_dot``
of the two points (``a`` the child side) and ``J = J_c - J_p``, the index-1 equations::

    [[M, -J^T], [J, 0]] [q''; lambda] = [Q - sum m J_P^T b_P;  -(b_c - b_p) - 2 alpha Phi' - alpha^2 Phi]

give the accelerations and ``lambda``, the constraint force on the child point [N] (``-lambda`` on the parent's),
``Phi = r_c - r_p``, with optional Baumgarte stabilisation ``alpha`` [1/s].  DOP853 solves it tightly.

Frequency domain: about a static equilibrium ``q0`` on the constraints (:meth:`GlobalLoop.equilibrium`: Newton on
``(q, lambda)``) with the static constraint forces ``lambda0``, the stiffness of the Lagrangian
``K = -d(Q + J^T lambda0)/dq`` (complex step), reduced to the null space ``N`` of ``J(q0)``:
``eig(N^T K N, N^T M N)``.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import scipy.integrate
import scipy.linalg

from .mixed_global import GlobalChain

__all__ = ["GlobalLoop"]


class GlobalLoop:
    """Serial branches from ground pivots closed by revolute loop constraints (module docstring).

    Parameters
    ----------
    branches : sequence of (GlobalChain, (x, y))
        Each branch and its ground pivot [m].
    cuts : sequence of (int, int)
        ``(parent branch, child branch)``: the outboard points of their last segments coincide.
    baumgarte : float
        ``alpha`` [1/s] (0: none).
    cut_laws : sequence of (float, float, float) or None
        Per cut an optional linear rotary law ``(k [N m/rad], c [N m s/rad], rest [rad])`` on the relative angle
        ``dtheta = theta_c - theta_p`` of the two outboard cross-sections (a beam's: its frame angle plus the last
        node's rotation): the moment ``-k (dtheta - rest) - c dtheta'`` on the child side, its opposite on the
        parent's.
    """

    def __init__(self, branches: Sequence[tuple[GlobalChain, Sequence[float]]], cuts: Sequence[tuple[int, int]],
                 baumgarte: float = 0.0, cut_laws: Sequence[tuple[float, float, float] | None] | None = None) -> None:
        self.chains = [chain for chain, _ in branches]
        self.pivots = [np.asarray(pivot, float) for _, pivot in branches]
        self.cuts = list(cuts)
        self.baumgarte = float(baumgarte)
        self.cut_laws = list(cut_laws) if cut_laws is not None else [None] * len(self.cuts)
        sizes = [chain.n for chain in self.chains]
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        self.n = int(self.offsets[-1])

    def _slice(self, b: int) -> slice:
        return slice(self.offsets[b], self.offsets[b + 1])

    def _tip(self, b: int, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, Jacobian (2, n) over all coordinates and bias of branch ``b``'s outboard point."""
        r, Jb, bias = self.chains[b].outboard_point(q[self._slice(b)], qd[self._slice(b)])
        J = np.zeros((2, self.n), dtype=Jb.dtype)
        J[:, self._slice(b)] = Jb
        return self.pivots[b] + r, J, bias

    def angle_row(self, b: int) -> np.ndarray:
        """The absolute angle of branch ``b``'s outboard cross-section as a row over all coordinates (linear)."""
        chain, row = self.chains[b], np.zeros(self.n)
        last = len(chain.segments) - 1
        row[self.offsets[b] + chain.theta_index[last]] = 1.0
        if last in chain.beams:
            row[self.offsets[b] + chain.u_index[last]] = chain.beams[last].end_rotation
        return row

    def relative_angles(self, q: np.ndarray) -> np.ndarray:
        """``dtheta = theta_c - theta_p`` [rad] of every cut (the same of the rates for ``q_dot``)."""
        return np.array([(self.angle_row(c) - self.angle_row(p)) @ q for p, c in self.cuts])

    def mass_and_forces(self, q: np.ndarray, qd: np.ndarray, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Block-diagonal ``M`` of the free branches and ``Q - sum m J^T b`` with the cut laws (complex allowed)."""
        dtype = np.result_type(q, qd, float)
        M, rhs = np.zeros((self.n, self.n), dtype=dtype), np.zeros(self.n, dtype=dtype)
        for b, chain in enumerate(self.chains):
            s = self._slice(b)
            M[s, s], rhs[s] = chain.generalised(q[s], qd[s], t)
        for (p, c), law in zip(self.cuts, self.cut_laws):
            if law is None:
                continue
            k, damping, rest = law
            row = self.angle_row(c) - self.angle_row(p)
            rhs = rhs + (-k * (row @ q - rest) - damping * (row @ qd)) * row
        return M, rhs

    def constraints(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``Phi`` (2 m,) [m], ``J`` (2 m, n), ``Phi' = J q_dot`` [m/s] and the bias ``(dJ/dt) q_dot`` [m/s^2]."""
        phi, J, bias = [], [], []
        for parent, child in self.cuts:
            rp, Jp, bp = self._tip(parent, q, qd)
            rc, Jc, bc = self._tip(child, q, qd)
            phi.append(rc - rp)
            J.append(Jc - Jp)
            bias.append(bc - bp)
        J = np.vstack(J)
        return np.concatenate(phi), J, J @ qd, np.concatenate(bias)

    def solve(self, q: np.ndarray, qd: np.ndarray, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """``(q'', lambda (n_cuts, 2))``: accelerations and the constraint force on each child point [N]."""
        q, qd = np.asarray(q, float), np.asarray(qd, float)
        M, rhs = self.mass_and_forces(q, qd, t)
        phi, J, phi_dot, bias = self.constraints(q, qd)
        m = J.shape[0]
        a = self.baumgarte
        A = np.block([[M, -J.T], [J, np.zeros((m, m))]])
        x = np.linalg.solve(A, np.concatenate([rhs, -bias - 2 * a * phi_dot - a * a * phi]))
        return x[:self.n], x[self.n:].reshape(-1, 2)

    def simulate(self, q0, qd0, times: np.ndarray, rtol: float = 1e-12, atol: float = 1e-13
                 ) -> tuple[np.ndarray, np.ndarray]:
        """DOP853 at ``times``: ``q`` and ``q_dot`` histories."""
        n = self.n
        sol = scipy.integrate.solve_ivp(lambda t, y: np.concatenate([y[n:], self.solve(y[:n], y[n:], t)[0]]),
                                        (times[0], times[-1]), np.concatenate([q0, qd0]), method="DOP853",
                                        t_eval=times, rtol=rtol, atol=atol)
        return sol.y[:n].T, sol.y[n:].T

    def rk4(self, q0, qd0, t_final: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Classical fixed-step RK4 of the index-1 equations (no projection): ``q`` and ``q_dot`` histories."""
        n, steps = self.n, int(round(t_final / dt))
        y = np.concatenate([np.asarray(q0, float), np.asarray(qd0, float)])
        out = [y]

        def f(t, y):
            return np.concatenate([y[n:], self.solve(y[:n], y[n:], t)[0]])
        for k in range(steps):
            t = k * dt
            k1 = f(t, y)
            k2 = f(t + dt / 2, y + dt / 2 * k1)
            k3 = f(t + dt / 2, y + dt / 2 * k2)
            k4 = f(t + dt, y + dt * k3)
            y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            out.append(y)
        out = np.array(out)
        return out[:, :n], out[:, n:]

    def energy(self, q: np.ndarray, qd: np.ndarray) -> float:
        """Kinetic + gravity + strain + hinge-spring energy [J] of the branches, each branch's gravity potential
        from its own pivot (a constant offset per branch), plus the cut laws' springs."""
        laws = sum(0.5 * law[0] * (angle - law[2]) ** 2
                   for law, angle in zip(self.cut_laws, self.relative_angles(q)) if law is not None)
        return float(laws + sum(chain.energy(q[self._slice(b)], qd[self._slice(b)])
                                for b, chain in enumerate(self.chains)))

    # -- statics and small oscillations ----------------------------------------------------------
    def _static_residual(self, q: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """``Q(q) + J(q)^T lambda`` at rest (complex allowed)."""
        zero = np.zeros(self.n, dtype=np.result_type(q, float))
        _, rhs = self.mass_and_forces(q, zero)
        _, J, _, _ = self.constraints(q, zero)
        return rhs + J.T @ lam

    def stiffness(self, q: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """``K = -d(Q + J^T lambda)/dq`` at fixed ``lambda`` (complex step)."""
        K = np.zeros((self.n, self.n))
        for i in range(self.n):
            dq = np.zeros(self.n, complex)
            dq[i] = 1e-30j
            K[:, i] = -self._static_residual(q + dq, lam).imag / 1e-30
        return K

    def equilibrium(self, q_guess, iterations: int = 60) -> tuple[np.ndarray, np.ndarray]:
        """Static equilibrium on the constraints near ``q_guess``: Newton on ``(q, lambda)`` of
        ``Q + J^T lambda = 0``, ``Phi = 0``; returns ``(q0, lambda0)``."""
        q = np.asarray(q_guess, float).copy()
        zero = np.zeros(self.n)
        lam = np.zeros(2 * len(self.cuts))
        for _ in range(iterations):
            phi, J, _, _ = self.constraints(q, zero)
            residual = np.concatenate([self._static_residual(q, lam), phi])
            K = self.stiffness(q, lam)
            m = J.shape[0]
            step = np.linalg.lstsq(np.block([[-K, J.T], [J, np.zeros((m, m))]]), -residual, rcond=None)[0]
            q, lam = q + step[:self.n], lam + step[self.n:]
            if np.max(np.abs(step)) < 1e-13 * (1.0 + np.max(np.abs(q))):
                break
        return q, lam

    def natural_frequencies(self, q0: np.ndarray, lam0: np.ndarray) -> np.ndarray:
        """Undamped natural frequencies [rad/s] about the equilibrium ``(q0, lambda0)``: ``eig(N^T K N, N^T M N)``
        on the null space ``N`` of ``J(q0)``."""
        zero = np.zeros(self.n)
        M, _ = self.mass_and_forces(q0, zero)
        _, J, _, _ = self.constraints(q0, zero)
        N = scipy.linalg.null_space(J)
        K = self.stiffness(q0, lam0)
        Kr, Mr = N.T @ K @ N, N.T @ M @ N
        values = scipy.linalg.eigh(0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T), eigvals_only=True)
        return np.sqrt(np.clip(values, 0.0, None))
