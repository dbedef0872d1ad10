"""Independent reference for spatial mechanisms with closed loops: a Newton-Euler DAE in absolute coordinates.

Written from scratch for the tests of :mod:`ctmm.spatial.closed_loops`; it shares no code with ``ctmm.spatial``
(or any transfer-matrix module) and no library module may import it.

Every body is free in space (centre of mass ``x`` [m], unit quaternion ``p`` scalar first, velocity ``v`` of the
centre of mass and angular velocity ``w``, both world axes); **every** joint -- those of the spanning tree and the
cut ones alike -- is a set of constraint equations:

* ``ball``: a point of the child coincides with a point of the parent (or of the ground), 3 rows;
* ``revolute``: ball plus the child axis ``u`` perpendicular to two parent vectors ``b_1, b_2`` normal to the
  parent axis (``u . b_i = 0``), 5 rows;
* ``universal``: ball plus the parent's first axis perpendicular to the child's second (``a_1 . a_2 = 0``), 4 rows;
* ``prismatic``: the separation ``d`` of the points perpendicular to the parent axis (``d . b_i = 0``, ``b_1, b_2``
  parent-fixed normal to the axis), 2 rows, and the child's triad ``(a, n, a x n)`` (``child_axis``,
  ``child_normal``) equal to the parent's (``parent_axis``, ``parent_normal``) by the three rows
  ``c_2 . p_3 = c_3 . p_1 = c_1 . p_2 = 0``, 5 rows.  The multipliers of the first two are the force ``mu_i b_i``
  on the child at its point; the parent takes the opposite at the same place.

The Newton-Euler equations ``m a = m g + f_c``, ``I alpha + w x I w = m_c`` with the constraint loads
``[f_c ; m_c] = J^T mu`` and the constraints at the acceleration level with Baumgarte terms form the KKT system::

    [ M   -J^T ] [ acc ]   [ m g ; -w x I w            ]
    [ J    0   ] [ mu  ] = [ -gamma - 2 a Phi' - a^2 Phi ]

(``J`` the velocity Jacobian of the rows, ``gamma`` their acceleration at zero ``acc``).  The multipliers of a
joint's point rows are the force on its child [N] (world), those of its alignment rows the moments
``mu_i (u x b_i)`` [N m].  Integrated with ``scipy.integrate.solve_ivp`` (DOP853, tight tolerances).  Small
oscillations: Lagrange's equations on the constraint manifold, ``M_r z'' + K z = 0`` with ``M_r = N^T M N``
(``N``: null space of ``J``) and ``K`` the Hessian of the potential along the manifold (finite differences of
Newton-projected configurations).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.integrate
import scipy.linalg

from .spatial_kinematics import cross

__all__ = ["DaeBody", "DaeJoint", "SpatialLoopDAE"]


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _rotation(p: np.ndarray) -> np.ndarray:
    w, x, y, z = p / np.linalg.norm(p)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (scalar first) of a rotation matrix (Shepperd)."""
    trace = np.trace(R)
    k = int(np.argmax([trace, R[0, 0], R[1, 1], R[2, 2]]))
    if k == 0:
        w = 0.5 * np.sqrt(1 + trace)
        p = np.array([w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)])
    else:
        i, j, m = k - 1, k % 3, (k + 1) % 3
        s = 0.5 * np.sqrt(1 + R[i, i] - R[j, j] - R[m, m])
        p = np.zeros(4)
        p[1 + i] = s
        p[0] = (R[m, j] - R[j, m]) / (4 * s)
        p[1 + j] = (R[j, i] + R[i, j]) / (4 * s)
        p[1 + m] = (R[m, i] + R[i, m]) / (4 * s)
    return p / np.linalg.norm(p)


def _rotation_vector(phi: np.ndarray) -> np.ndarray:
    return scipy.linalg.expm(_skew(phi))


def _normal_to(a: np.ndarray) -> np.ndarray:
    """A unit vector normal to the unit vector ``a``: ``a x e_k`` with ``e_k`` the axis least aligned with ``a``."""
    b = cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
    return b / np.linalg.norm(b)


@dataclass(frozen=True)
class DaeBody:
    """A rigid body: ``mass`` [kg], ``inertia`` about the centre of mass in body axes [kg m^2]."""

    name: str
    mass: float
    inertia: np.ndarray


@dataclass(frozen=True)
class DaeJoint:
    """A joint as constraint rows.  Points are in body axes **from the centre of mass** [m] (at the ground:
    world location); ``parent = -1`` is the ground.  ``kind``: ``"ball"``, ``"revolute"`` (``child_axis`` in child
    axes parallel to ``parent_axis`` in parent axes / world) or ``"universal"`` (``parent_axis`` perpendicular to
    ``child_axis``)."""

    name: str
    kind: str
    parent: int
    parent_point: np.ndarray
    child: int
    child_point: np.ndarray
    parent_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    child_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    parent_normal: np.ndarray | None = None
    child_normal: np.ndarray | None = None

    @property
    def n_rows(self) -> int:
        return {"ball": 3, "revolute": 5, "universal": 4, "prismatic": 5}[self.kind]

    def pairs(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """``(u, b)`` of the alignment rows ``u . b = 0``: ``u`` child-fixed (child axes), ``b`` parent-fixed."""
        u = np.asarray(self.child_axis, float) / np.linalg.norm(self.child_axis)
        if self.kind != "prismatic":
            return [(u, b) for b in self.parent_vectors()]
        triads = []
        for axis, normal in ((u, self.child_normal), (self.parent_axis, self.parent_normal)):
            a = np.asarray(axis, float) / np.linalg.norm(axis)
            n = _normal_to(a) if normal is None else np.asarray(normal, float) / np.linalg.norm(normal)
            triads.append((a, n, cross(a, n)))
        c, p = triads
        return [(c[1], p[2]), (c[2], p[0]), (c[0], p[1])]

    def parent_vectors(self) -> list[np.ndarray]:
        """Parent-fixed vectors ``b`` of the alignment rows ``u . b = 0`` (prismatic: of the point rows ``d . b = 0``)."""
        a = np.asarray(self.parent_axis, float) / np.linalg.norm(self.parent_axis)
        if self.kind == "universal":
            return [a]
        if self.kind == "ball":
            return []
        b1 = _normal_to(a)
        return [b1, cross(a, b1)]


class SpatialLoopDAE:
    """Bodies and joints in absolute coordinates (module docstring).

    State ``y = [x (3 n), p (4 n), v (3 n), w (3 n)]``.
    """

    def __init__(self, bodies: list[DaeBody], joints: list[DaeJoint], *, gravity=(0.0, 0.0, -9.81),
                 baumgarte: float = 10.0) -> None:
        self.bodies, self.joints = list(bodies), list(joints)
        self.gravity = np.asarray(gravity, float)
        self.baumgarte = float(baumgarte)
        self.n = len(bodies)
        self.n_rows = sum(j.n_rows for j in joints)

    # -- poses ------------------------------------------------------------------------------------------
    def split(self, y: np.ndarray):
        n = self.n
        x = y[:3 * n].reshape(n, 3)
        p = y[3 * n:7 * n].reshape(n, 4)
        v = y[7 * n:10 * n].reshape(n, 3)
        w = y[10 * n:13 * n].reshape(n, 3)
        return x, p, v, w

    def state(self, positions, rotations, velocities, omegas) -> np.ndarray:
        """The state from centre-of-mass positions, rotation matrices, velocities and angular velocities."""
        p = [_quaternion(np.asarray(R, float)) for R in rotations]
        return np.concatenate([np.ravel(positions), np.ravel(p), np.ravel(velocities), np.ravel(omegas)])

    def rotations(self, y: np.ndarray) -> list[np.ndarray]:
        return [_rotation(p) for p in self.split(y)[1]]

    # -- constraint rows --------------------------------------------------------------------------------
    def rows(self, y: np.ndarray):
        """``(Phi, J, gamma)``: the rows, their velocity Jacobian ``(m, 6 n)`` on ``[v ; w]`` per body and their
        acceleration at zero body accelerations."""
        x, _, v, w = self.split(y)
        R = self.rotations(y)
        n = self.n
        phi, gamma, J = [], [], []

        def side(body: int, point: np.ndarray):
            if body < 0:
                return np.asarray(point, float), np.zeros(3), None, np.zeros(3), np.zeros(3)
            r = R[body] @ point
            return x[body] + r, v[body] + cross(w[body], r), r, w[body], cross(w[body], cross(w[body], r))

        for joint in self.joints:
            xp, vp, rp, wp, gp = side(joint.parent, joint.parent_point)
            xc, vc, rc, wc, gc = side(joint.child, joint.child_point)
            block = np.zeros((3, 6 * n))
            for body, r, sign in ((joint.child, rc, 1.0), (joint.parent, rp, -1.0)):
                if body >= 0:
                    block[:, 6 * body:6 * body + 3] += sign * np.eye(3)
                    block[:, 6 * body + 3:6 * body + 6] += -sign * _skew(r)
            if joint.kind != "prismatic":
                phi.append(xc - xp)
                J.append(block)
                gamma.append(gc - gp)
            else:
                d = xc - xp
                for b_local in joint.parent_vectors():
                    b = b_local if joint.parent < 0 else R[joint.parent] @ b_local
                    row = (b @ block)[None]          # (d . b)' = (v_c - v_p) . b + d . (w_p x b)
                    if joint.parent >= 0:
                        row[0, 6 * joint.parent + 3:6 * joint.parent + 6] += cross(b, d)
                    phi.append(np.array([d @ b]))
                    J.append(row)
                    gamma.append(np.array([(gc - gp) @ b + 2 * (vc - vp) @ cross(wp, b)
                                           + d @ cross(wp, cross(wp, b))]))
            for u_local, b_local in joint.pairs():
                u = R[joint.child] @ u_local
                b = b_local if joint.parent < 0 else R[joint.parent] @ b_local
                nvec = cross(u, b)
                row = np.zeros((1, 6 * n))
                row[0, 6 * joint.child + 3:6 * joint.child + 6] = nvec
                if joint.parent >= 0:
                    row[0, 6 * joint.parent + 3:6 * joint.parent + 6] -= nvec
                phi.append(np.array([u @ b]))
                J.append(row)
                gamma.append(np.array([(wc - wp) @ (cross(cross(wc, u), b) + cross(u, cross(wp, b)))]))
        return np.concatenate(phi), np.vstack(J), np.concatenate(gamma)

    def velocities(self, y: np.ndarray) -> np.ndarray:
        """``[v_i ; w_i]`` stacked per body (6 n)."""
        _, _, v, w = self.split(y)
        return np.concatenate([np.concatenate([v[i], w[i]]) for i in range(self.n)])

    def mass_matrix(self, y: np.ndarray) -> np.ndarray:
        R = self.rotations(y)
        M = np.zeros((6 * self.n, 6 * self.n))
        for i, body in enumerate(self.bodies):
            M[6 * i:6 * i + 3, 6 * i:6 * i + 3] = body.mass * np.eye(3)
            M[6 * i + 3:6 * i + 6, 6 * i + 3:6 * i + 6] = R[i] @ np.asarray(body.inertia, float) @ R[i].T
        return M

    def accelerations(self, y: np.ndarray, torques: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Body accelerations ``[a_i ; alpha_i]`` (6 n) and the multipliers ``mu`` (m) at state ``y``;
        ``torques``: ``{body: world moment (3,)}`` applied (optional), or ``{body: [force ; moment] (6,)}`` (world, the
        moment about the centre of mass)."""
        _, _, _, w = self.split(y)
        M = self.mass_matrix(y)
        f = np.zeros(6 * self.n)
        for i, body in enumerate(self.bodies):
            inertia = M[6 * i + 3:6 * i + 6, 6 * i + 3:6 * i + 6]
            f[6 * i:6 * i + 3] = body.mass * self.gravity
            f[6 * i + 3:6 * i + 6] = -cross(w[i], inertia @ w[i])
        for i, load in (torques or {}).items():
            load = np.asarray(load, float)
            if load.shape == (6,):
                f[6 * i:6 * i + 6] += load
            else:
                f[6 * i + 3:6 * i + 6] += load
        phi, J, gamma = self.rows(y)
        a = self.baumgarte
        rhs = -gamma - 2 * a * (J @ self.velocities(y)) - a * a * phi
        m = len(phi)
        K = np.block([[M, -J.T], [J, np.zeros((m, m))]])
        solution = np.linalg.solve(K, np.concatenate([f, rhs]))
        return solution[:6 * self.n], solution[6 * self.n:]

    def rate(self, t: float, y: np.ndarray, torques=None) -> np.ndarray:
        """``y'``; ``torques``: ``{body: world moment (3,)}`` [N m] or a function ``torques(t, y)`` giving one."""
        x, p, v, w = self.split(y)
        acc, _ = self.accelerations(y, torques(t, y) if callable(torques) else torques)
        pdot = []
        for i in range(self.n):
            q0, q1, q2, q3 = p[i]
            wx, wy, wz = w[i]                       # world angular velocity: p' = 1/2 (0, w) (x) p
            pdot.append(0.5 * np.array([-wx * q1 - wy * q2 - wz * q3, wx * q0 + wy * q3 - wz * q2,
                                        wy * q0 + wz * q1 - wx * q3, wz * q0 + wx * q2 - wy * q1]))
        acc = acc.reshape(self.n, 6)
        return np.concatenate([v.ravel(), np.ravel(pdot), acc[:, :3].ravel(), acc[:, 3:].ravel()])

    def simulate(self, y0: np.ndarray, t_eval: np.ndarray, *, rtol: float = 1e-12, atol: float = 1e-13,
                 torques=None):
        """``(t, Y)`` by DOP853 (the initial state must satisfy the rows to 1e-9); ``torques``: world moments
        ``{body: (3,)}`` [N m] applied throughout, or a function ``torques(t, y)`` giving them (a control law)."""
        phi, J, _ = self.rows(y0)
        if np.max(np.abs(phi)) > 1e-9 or np.max(np.abs(J @ self.velocities(y0))) > 1e-9:
            raise ValueError(f"inconsistent initial state: |Phi| = {np.max(np.abs(phi)):.3e}, |Phi'| = "
                             f"{np.max(np.abs(J @ self.velocities(y0))):.3e}")
        sol = scipy.integrate.solve_ivp(lambda t, y: self.rate(t, y, torques), (t_eval[0], t_eval[-1]), y0,
                                        method="DOP853", rtol=rtol, atol=atol, t_eval=t_eval)
        if not sol.success:
            raise RuntimeError(sol.message)
        return sol.t, sol.y.T

    # -- small oscillations -----------------------------------------------------------------------------
    def _moved(self, y: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """Positions of ``y`` moved by ``dx = [dx_i ; dphi_i]`` per body (rotation vectors, world axes)."""
        x, p, v, w = self.split(y)
        d = dx.reshape(self.n, 6)
        R = [_rotation_vector(d[i, 3:]) @ _rotation(p[i]) for i in range(self.n)]
        return self.state(x + d[:, :3], R, v, w)

    def potential(self, y: np.ndarray) -> float:
        x = self.split(y)[0]
        return -sum(body.mass * (x[i] @ self.gravity) for i, body in enumerate(self.bodies))

    def natural_frequencies(self, y0: np.ndarray, *, step: float = 1e-3) -> np.ndarray:
        """Small-oscillation frequencies [rad/s] about the resting configuration ``y0`` (gravity only, an
        equilibrium) from :meth:`small_oscillations`."""
        _, K, Mr = self.small_oscillations(y0, step=step)
        squared = scipy.linalg.eigh(K, Mr, eigvals_only=True)
        return np.sqrt(np.clip(np.sort(squared), 0.0, None))

    def _manifold(self, y0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``y0`` at rest, the orthonormal null space ``N`` of ``J(y0)`` and the normal directions."""
        y0 = y0.copy()
        y0[7 * self.n:] = 0.0
        _, J0, _ = self.rows(y0)
        _, values, vt = np.linalg.svd(J0)
        rank = int(np.sum(values > 1e-10 * values[0]))
        N = vt[rank:].T
        normal = J0[:rank].T if rank == J0.shape[0] else vt[:rank].T
        return y0, N, normal

    def _chart(self, y0: np.ndarray, N: np.ndarray, normal: np.ndarray, z: np.ndarray) -> np.ndarray:
        s = np.zeros(normal.shape[1])
        for _ in range(50):
            y = self._moved(y0, N @ z + normal @ s)
            phi, J, _ = self.rows(y)
            if np.max(np.abs(phi)) < 1e-15:
                break
            s -= np.linalg.lstsq(J @ normal, phi, rcond=None)[0]
        return y

    def manifold_configuration(self, y0: np.ndarray, z: np.ndarray) -> np.ndarray:
        """The resting configuration ``y0 (+) (N z + J^T s)`` on the constraints (Newton on ``s``; ``N`` the null
        space of :meth:`small_oscillations`, ``z`` its independent coordinates)."""
        y0, N, normal = self._manifold(y0)
        return self._chart(y0, N, normal, np.asarray(z, float))

    def small_oscillations(self, y0: np.ndarray, *, step: float = 1e-3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(N, K, M_r)`` about the resting configuration ``y0`` (an equilibrium): ``N`` (6 n, f) the orthonormal
        null space of ``J`` (body twists ``[v_i ; w_i]`` per unit independent rate), ``M_r = N^T M N`` and ``K`` the
        5-point Hessian of the potential of the Newton-projected configurations ``y0 (+) (N z + J^T s)``
        (Lagrange on the manifold: ``M_r z'' + K z = 0``)."""
        y0, N, normal = self._manifold(y0)

        def chart(z: np.ndarray) -> np.ndarray:
            return self._chart(y0, N, normal, z)

        f = N.shape[1]
        weights = {-2: 1.0 / 12, -1: -2.0 / 3, 1: 2.0 / 3, 2: -1.0 / 12}

        def gradient(z: np.ndarray) -> np.ndarray:
            out = np.zeros(f)
            for k in range(f):
                for offset, weight in weights.items():
                    e = np.zeros(f)
                    e[k] = offset * step
                    out[k] += weight * self.potential(chart(z + e)) / step
            return out

        K = np.zeros((f, f))
        for k in range(f):
            for offset, weight in weights.items():
                e = np.zeros(f)
                e[k] = offset * step
                K[:, k] += weight * gradient(e) / step
        K = 0.5 * (K + K.T)
        return N, K, N.T @ self.mass_matrix(y0) @ N
