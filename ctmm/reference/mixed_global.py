"""Independent global model of a planar pendulum chain of rigid links and finite-element beams.

No code of :mod:`ctmm.fem`, of the planar model or of any transfer / Riccati sweep is used: the
whole system is one set of Lagrange (Kane) equations in minimal coordinates, assembled globally.

Coordinates, segment by segment from the ground pivot: the absolute angle ``theta_j`` of each
segment and, for a beam segment, the displacements ``[u_x, u_y, r_z]`` of its nodes ``1..n`` in the
segment's frame (node 0 carries the frame: origin at the joint, x along the undeformed beam, angle
``theta_j``; small deformation).  The next segment hangs at the outboard point (rigid link) or at the
last node (beam), its hinge angle measured from the node's cross-section ``theta_j + r_z,n``.

A :class:`ParticleNet` (seed 001 Example 9.1's reticulated particle-spring system, here welded to a
rigid link) adds the particles' displacements in the link's axes; its springs are exact (length from
the global positions) or, with ``linear=True``, act along their undeformed lines; with ``outboard``
the next segment hangs (pinned) at one of its particles (seed 001 Figs. 9.8-9.9).  A
:class:`MembranePlate` (Example 9.2's equivalent flexible plate, in its own plane) adds the nodal
displacements of plane-stress bilinear rectangles welded to the last rigid link.

Mass is lumped into points: a rigid link is its centre of mass (plus rotary inertia on ``theta``),
a beam element is ``rhoA L w_k`` at its four Gauss-Legendre points (exact for the cubic Hermite
kinetic energy).  The displacement field of an element is written here once more: axial linear,
transverse Hermite cubic.  With ``r_P(q)`` the position of point ``P``, ``J_P = dr_P/dq`` and
``b_P = (d J_P/dt) q_dot`` (analytic: ``R J rho`` per angle, ``-omega^2 R rho + 2 omega R J E u'``),
``sum_P m_P J_P^T (J_P q'' + b_P - g) + J_rot q'' = Q`` with ``Q`` the hinge laws, the elastic
forces ``-K u - C u'`` (``K`` from the strain energy ``1/2 int EA u'^2 + EI v''^2`` by quadrature;
``C = a M_e + b K``, ``M_e`` the element mass by quadrature) and an optional ``f(u, u', t)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import scipy.integrate
import scipy.linalg

__all__ = ["RigidSegment", "BeamSegment", "ParticleNet", "MembranePlate", "GlobalChain"]

_J = np.array([[0.0, -1.0], [1.0, 0.0]])


@dataclass(frozen=True)
class RigidSegment:
    """Rigid link: ``length`` [m] (outboard point at ``(length, 0)``), centre of mass at ``(com, 0)``,
    ``mass`` [kg], ``inertia`` about the centre [kg m^2]; hinge to its parent ``stiffness`` [N m/rad],
    ``damping`` [N m s/rad]."""

    length: float
    mass: float
    inertia: float
    com: float
    stiffness: float = 0.0
    damping: float = 0.0


@dataclass(frozen=True)
class BeamSegment:
    """Straight beam of ``elements`` equal elements on its frame's x axis, clamped to the frame at node 0.

    ``force(u, u_dot, t)``: optional generalised force on the ``3 elements`` node DOFs ``[u_x, u_y, r_z]``
    of nodes ``1..n``; ``rayleigh = (a, b)``.  Hinge law as for :class:`RigidSegment`."""

    length: float
    elements: int
    bending_stiffness: float
    axial_stiffness: float
    mass_per_length: float
    rayleigh: tuple = (0.0, 0.0)
    force: Callable | None = None
    stiffness: float = 0.0
    damping: float = 0.0


@dataclass(frozen=True)
class ParticleNet:
    """Particles welded to the previous (rigid) segment: in its axes, origin at its outboard point.

    ``positions`` (P, 2) [m] undeformed, ``masses`` (P,) [kg]; ``springs``: ``(a, b, stiffness)`` with ``a, b``
    particle indices or ``(x, y)`` anchor points fixed on the segment (same axes) -- exact springs with the
    undeformed distance as rest length, force ``k (|r_b - r_a| - l0)`` along the line; ``damping`` [N s/m] on
    every spring, along the line.  Coordinates: the displacements ``[u_x, u_y]`` of each particle in the
    segment's axes.  ``linear=True``: the springs act along their undeformed line in the segment's axes,
    ``f = -k n n^T (u_b - u_a)`` (no damping), as a small-deformation net.  ``outboard``: index of the
    particle where the next segment hangs (pinned); ``None``: it must be the last segment."""

    positions: tuple
    masses: tuple
    springs: tuple
    damping: float = 0.0
    linear: bool = False
    outboard: int | None = None


@dataclass(frozen=True)
class MembranePlate:
    """Plane-stress plate moving in its own plane, welded to the previous (rigid) segment: in its axes, origin
    at its outboard point (seed 001 Example 9.2's equivalent flexible plate).

    ``positions`` (N, 2) [m] undeformed nodes; ``quads`` (Q, 4) node indices of axis-parallel rectangles
    (counter-clockwise); ``clamped`` node indices held on the segment; ``thickness`` [m], ``youngs_modulus``
    [Pa], ``poisson_ratio``, ``density`` [kg/m^3], ``rayleigh = (a, b)``.  Coordinates: ``[u_x, u_y]`` of every
    other node in the segment's axes, in node order.  Written here once more: bilinear interpolation on
    each rectangle, mass lumped at its 3 x 3 Gauss points (exact kinetic energy), stiffness from the strain
    energy ``t/2 int eps^T D eps dA`` by the same quadrature.  It must be the last segment."""

    positions: tuple
    quads: tuple
    clamped: tuple
    thickness: float
    youngs_modulus: float
    poisson_ratio: float
    density: float
    rayleigh: tuple = (0.0, 0.0)


@dataclass
class _Plate:
    points: np.ndarray            # (P, 2) undeformed mass points
    weights: np.ndarray           # (P,) masses [kg]
    shape: np.ndarray             # (P, 2, n)
    stiffness: np.ndarray         # (n, n)
    damping: np.ndarray           # (n, n)


def _plate(seg: MembranePlate) -> _Plate:
    X = np.asarray(seg.positions, float)
    free = [k for k in range(len(X)) if k not in set(seg.clamped)]
    column = {node: 2 * i for i, node in enumerate(free)}
    n = 2 * len(free)
    E, nu, t = seg.youngs_modulus, seg.poisson_ratio, seg.thickness
    D = E / (1 - nu ** 2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    gx, gw = np.polynomial.legendre.leggauss(3)
    pts, ws, shapes = [], [], []
    K, Me = np.zeros((n, n)), np.zeros((n, n))
    for quad in seg.quads:
        corner = X[list(quad)]
        lo, hi = corner.min(0), corner.max(0)
        half, centre = (hi - lo) / 2, (hi + lo) / 2
        for a, wa in zip(gx, gw):
            for b, wb in zip(gx, gw):
                p = centre + half * np.array([a, b])
                area = wa * wb * half[0] * half[1]
                row, strain = np.zeros((2, n)), np.zeros((3, n))
                for node in quad:
                    if node not in column:
                        continue
                    sx, sy = np.sign(X[node] - centre)
                    value = (1 + sx * a) * (1 + sy * b) / 4
                    dx, dy = sx * (1 + sy * b) / (4 * half[0]), sy * (1 + sx * a) / (4 * half[1])
                    c = column[node]
                    row[0, c] = row[1, c + 1] = value
                    strain[0, c], strain[1, c + 1] = dx, dy
                    strain[2, c], strain[2, c + 1] = dy, dx
                pts.append(p)
                ws.append(seg.density * t * area)
                shapes.append(row)
                K += t * area * strain.T @ D @ strain
                Me += seg.density * t * area * row.T @ row
    a, b = seg.rayleigh
    return _Plate(np.array(pts), np.array(ws), np.array(shapes), K, a * Me + b * K)


def _linear_net(seg: ParticleNet) -> np.ndarray:
    """Stiffness (2P x 2P) of a net's springs along their undeformed lines (anchors carry no coordinates)."""
    X = np.asarray(seg.positions, float)
    K = np.zeros((2 * len(X), 2 * len(X)))
    for a, b, k in seg.springs:
        ends = [np.asarray(e, float) if not isinstance(e, (int, np.integer)) else X[e] for e in (a, b)]
        n = (ends[1] - ends[0]) / np.linalg.norm(ends[1] - ends[0])
        row = np.zeros(2 * len(X))
        for e, sign in ((a, -1.0), (b, 1.0)):
            if isinstance(e, (int, np.integer)):
                row[2 * e:2 * e + 2] = sign * n
        K += k * np.outer(row, row)
    return K


def _hermite(xi: np.ndarray, le: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows of ``(u, v)`` interpolation and ``u'``, ``v''`` for element DOFs ``[ua, va, ra, ub, vb, rb]``."""
    n = np.zeros(xi.shape + (2, 6))
    n[..., 0, 0], n[..., 0, 3] = 1 - xi, xi
    n[..., 1, 1] = 2 * xi ** 3 - 3 * xi ** 2 + 1
    n[..., 1, 2] = le * (xi ** 3 - 2 * xi ** 2 + xi)
    n[..., 1, 4] = -2 * xi ** 3 + 3 * xi ** 2
    n[..., 1, 5] = le * (xi ** 3 - xi ** 2)
    du = np.zeros(xi.shape + (6,))
    du[..., 0], du[..., 3] = -1 / le, 1 / le
    d2v = np.zeros(xi.shape + (6,))
    d2v[..., 1] = (12 * xi - 6) / le ** 2
    d2v[..., 2] = (6 * xi - 4) / le
    d2v[..., 4] = (-12 * xi + 6) / le ** 2
    d2v[..., 5] = (6 * xi - 2) / le
    return n, du, d2v


@dataclass
class _Beam:
    points_x: np.ndarray          # (P,) undeformed x of the mass points
    weights: np.ndarray           # (P,) masses [kg]
    shape: np.ndarray             # (P, 2, n) displacement of the points per DOF
    stiffness: np.ndarray         # (n, n)
    damping: np.ndarray           # (n, n)
    end: np.ndarray               # (2, n): tip translation
    end_rotation: np.ndarray      # (n,)
    force: Callable | None = field(default=None)


def _beam(seg: BeamSegment) -> _Beam:
    ne, L = seg.elements, seg.length
    le = L / ne
    n = 3 * ne                                   # nodes 1..ne
    gx, gw = np.polynomial.legendre.leggauss(4)
    xi, w = 0.5 * (gx + 1), 0.5 * gw
    nn, du, d2v = _hermite(xi, le)
    xs, ws, shapes = [], [], []
    K, Me = np.zeros((n, n)), np.zeros((n, n))
    for e in range(ne):
        cols = np.arange(3 * e - 3, 3 * e + 3)    # DOFs of nodes e, e+1 (node 0 held: negative)
        live = cols >= 0
        for k in range(4):
            row = np.zeros((2, n))
            row[:, cols[live]] = nn[k][:, live]
            xs.append((e + xi[k]) * le)
            ws.append(seg.mass_per_length * le * w[k])
            shapes.append(row)
            a, b = np.zeros(n), np.zeros(n)
            a[cols[live]], b[cols[live]] = du[k][live], d2v[k][live]
            K += le * w[k] * (seg.axial_stiffness * np.outer(a, a) + seg.bending_stiffness * np.outer(b, b))
            Me += seg.mass_per_length * le * w[k] * row.T @ row
    end = np.zeros((2, n))
    end[0, n - 3], end[1, n - 2] = 1.0, 1.0
    rot = np.zeros(n)
    rot[n - 1] = 1.0
    a, b = seg.rayleigh
    return _Beam(np.array(xs), np.array(ws), np.array(shapes), K, a * Me + b * K, end, rot, seg.force)


class GlobalChain:
    """Serial planar chain from a ground pivot at the origin (module docstring).

    Parameters
    ----------
    segments : sequence of RigidSegment or BeamSegment
    gravity : (2,)
        [m/s^2].
    """

    def __init__(self, segments: Sequence[object], gravity: Sequence[float] = (0.0, -9.81)) -> None:
        self.segments = list(segments)
        self.gravity = np.asarray(gravity, float)
        self.theta_index, self.u_index, self.beams, self.plates, self.net_stiffness = [], [], {}, {}, {}
        self._rest: dict[int, list] = {}          # a net's exact springs: rest lengths [m], in order
        k = 0
        for j, seg in enumerate(self.segments):
            if isinstance(seg, (ParticleNet, MembranePlate)):
                last = j == len(self.segments) - 1 or getattr(seg, "outboard", None) is not None
                if not last or j == 0 or not isinstance(self.segments[j - 1], RigidSegment):
                    raise ValueError("a ParticleNet or MembranePlate is the last segment, welded to a rigid one")
                self.theta_index.append(self.theta_index[j - 1])
                if isinstance(seg, MembranePlate):
                    self.plates[j] = _plate(seg)
                elif seg.linear:
                    self.net_stiffness[j] = _linear_net(seg)
                else:
                    X = np.asarray(seg.positions, float)
                    ends = [[X[e] if isinstance(e, (int, np.integer)) else np.asarray(e, float) for e in (a, b)]
                            for a, b, _ in seg.springs]
                    self._rest[j] = [np.linalg.norm(rb - ra) for ra, rb in ends]
                count = self.plates[j].stiffness.shape[0] if j in self.plates else 2 * len(seg.masses)
                self.u_index.append(np.arange(k, k + count))
                k += count
                continue
            self.theta_index.append(k)
            k += 1
            if isinstance(seg, BeamSegment):
                self.beams[j] = _beam(seg)
                n = self.beams[j].stiffness.shape[0]
                self.u_index.append(np.arange(k, k + n))
                k += n
            else:
                self.u_index.append(np.zeros(0, dtype=int))
        self.n = k

    # -- kinematics of all mass points ------------------------------------------------------
    def _points(self, q: np.ndarray, qd: np.ndarray):
        """Per rigid link (one point) or beam (its P points): mass, position (2,) / (P, 2), Jacobian (2, n) /
        (P, 2, n), bias (2,) / (P, 2), segment; the rotary inertias (index, J); the exact springs; and the
        outboard point of the last segment (position, Jacobian, bias)."""
        nq = self.n
        base = np.zeros(2)
        J_base = np.zeros((2, nq), dtype=q.dtype)
        b_base = np.zeros(2, dtype=q.dtype)
        base = base.astype(q.dtype)
        out, rotary, springs = [], [], []
        for j, seg in enumerate(self.segments):
            it = self.theta_index[j]
            th, w = q[it], qd[it]
            R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
            if j in self.plates:
                pl = self.plates[j]
                iu = self.u_index[j]
                rho = pl.points + pl.shape @ q[iu]                                                   # (P, 2)
                Jp = np.broadcast_to(J_base, (len(pl.weights),) + J_base.shape).copy()
                Jp[:, :, it] += rho @ (R @ _J).T
                Jp[:, :, iu] += R @ pl.shape
                bias = b_base - w * w * rho @ R.T + 2 * w * (pl.shape @ qd[iu]) @ (R @ _J).T
                out.append((pl.weights, base + rho @ R.T, Jp, bias, j))
                continue
            if isinstance(seg, ParticleNet):
                iu = self.u_index[j]
                X = np.asarray(seg.positions, float)
                u, ud = q[iu].reshape(-1, 2), qd[iu].reshape(-1, 2)
                rho = X + u
                P = X.shape[0]
                Jp = np.broadcast_to(J_base, (P,) + J_base.shape).copy()
                Jp[:, :, it] += rho @ (R @ _J).T
                Jp[np.arange(P)[:, None], :, iu.reshape(P, 2)] += R.T          # particle p's own (x, y) columns
                bias = b_base - w * w * rho @ R.T + 2 * w * ud @ (R @ _J).T
                out.append((np.asarray(seg.masses, float), base + rho @ R.T, Jp, bias, j))
                if seg.outboard is not None:                       # the next segment hangs at this particle
                    e = seg.outboard
                    base, J_base, b_base = base + R @ rho[e], Jp[e], bias[e]
                for (a, b, k), rest in zip(() if seg.linear else seg.springs, self._rest.get(j, ())):
                    ends = []
                    for e in (a, b):
                        if isinstance(e, (int, np.integer)):
                            ends.append((base + R @ rho[e], Jp[e]))
                        else:
                            anchor = np.asarray(e, float)
                            Ja = J_base.copy()
                            Ja[:, it] += R @ _J @ anchor
                            ends.append((base + R @ anchor, Ja))
                    springs.append((ends[0], ends[1], k, rest, seg.damping))
                continue
            if j in self.beams:
                bm = self.beams[j]
                iu = self.u_index[j]
                u, ud = q[iu], qd[iu]
                rho = np.stack([bm.points_x, np.zeros_like(bm.points_x)], axis=1) + bm.shape @ u     # (P, 2)
                Jp = np.broadcast_to(J_base, (len(bm.weights),) + J_base.shape).copy()               # (P, 2, n)
                Jp[:, :, it] += rho @ (R @ _J).T
                Jp[:, :, iu] += R @ bm.shape
                bias = b_base - w * w * rho @ R.T + 2 * w * (bm.shape @ ud) @ (R @ _J).T
                out.append((bm.weights, base + rho @ R.T, Jp, bias, j))
                rho = np.array([seg.length, 0.0]) + bm.end @ u
                Jn = J_base.copy()
                Jn[:, it] += R @ _J @ rho
                Jn[:, iu] += R @ bm.end
                b_base = b_base - w * w * (R @ rho) + 2 * w * (R @ _J @ (bm.end @ ud))
                base, J_base = base + R @ rho, Jn
            else:
                rho = np.array([seg.com, 0.0])
                Jp = J_base.copy()
                Jp[:, it] += R @ _J @ rho
                out.append((seg.mass, base + R @ rho, Jp, b_base - w * w * (R @ rho), j))
                rotary.append((it, seg.inertia))
                rho = np.array([seg.length, 0.0])
                Jn = J_base.copy()
                Jn[:, it] += R @ _J @ rho
                b_base = b_base - w * w * (R @ rho)
                base, J_base = base + R @ rho, Jn
        return out, rotary, springs, (base, J_base, b_base)

    def hinge_angles(self, q: np.ndarray) -> np.ndarray:
        """Relative hinge angles (from the parent's outboard cross-section) [rad]."""
        out = []
        for j in range(len(self.segments)):
            parent = 0.0
            if j > 0:
                parent = q[self.theta_index[j - 1]]
                if j - 1 in self.beams:
                    parent = parent + self.beams[j - 1].end_rotation @ q[self.u_index[j - 1]]
            out.append(q[self.theta_index[j]] - parent)
        return np.array(out)

    def _generalised(self, q, qd, t):
        """``M (n, n)`` and ``Q - sum m J^T b`` (n,)."""
        pts, rotary, springs, _ = self._points(q, qd)
        dtype = np.result_type(q, qd, float)
        M = np.zeros((self.n, self.n), dtype=dtype)
        rhs = np.zeros(self.n, dtype=dtype)
        for m, _, Jp, bias, _ in pts:                 # a rigid link's point, or all points of a beam (batched)
            m, Jp, bias = np.atleast_1d(m), Jp.reshape(-1, 2, self.n), bias.reshape(-1, 2)
            M += np.einsum("p,pik,pil->kl", m, Jp, Jp)
            rhs += np.einsum("p,pik,pi->k", m, Jp, self.gravity - bias)
        for it, inertia in rotary:
            M[it, it] += inertia
        # hinge laws: tau_j = -k phi - c phi_dot acts on theta_j and (-) on the parent cross-section
        phi = self.hinge_angles(q)
        phid = self.hinge_angles(qd)
        for j, seg in enumerate(self.segments):
            if isinstance(seg, (ParticleNet, MembranePlate)):
                continue
            tau = -seg.stiffness * phi[j] - seg.damping * phid[j]
            rhs[self.theta_index[j]] += tau
            if j > 0:
                rhs[self.theta_index[j - 1]] -= tau
                if j - 1 in self.beams:
                    rhs[self.u_index[j - 1]] -= tau * self.beams[j - 1].end_rotation
        for (ra, Ja), (rb, Jb), k, rest, c in springs:     # exact springs of particle nets
            d = rb - ra
            length = np.sqrt(d @ d)
            e = d / length
            rate = e @ ((Jb - Ja) @ qd)
            force = -(k * (length - rest) + c * rate) * e     # on end b
            rhs += Jb.T @ force - Ja.T @ force
        for j, pl in self.plates.items():
            iu = self.u_index[j]
            rhs[iu] -= pl.stiffness @ q[iu] + pl.damping @ qd[iu]
        for j, K in self.net_stiffness.items():
            rhs[self.u_index[j]] -= K @ q[self.u_index[j]]
        for j, bm in self.beams.items():
            iu = self.u_index[j]
            u, ud = q[iu], qd[iu]
            rhs[iu] -= bm.stiffness @ u + bm.damping @ ud
            if bm.force is not None:
                rhs[iu] += np.asarray(bm.force(u, ud, t))
        return M, rhs

    def generalised(self, q: np.ndarray, qd: np.ndarray, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Mass matrix ``M`` (n, n) and the generalised forces less the bias, ``Q - sum m J^T b`` (n,)
        (complex allowed)."""
        return self._generalised(q, qd, t)

    def outboard_point(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The outboard point of the last segment (a rigid link's ``(length, 0)``, a beam's last node): position
        (2,) [m] from the ground pivot, Jacobian ``dr/dq`` (2, n) and bias ``(dJ/dt) q_dot`` (2,) [m/s^2]
        (complex allowed)."""
        return self._points(q, qd)[3]

    def accelerations(self, q: np.ndarray, qd: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``q''`` [rad/s^2, m/s^2]."""
        M, rhs = self._generalised(np.asarray(q), np.asarray(qd), t)
        return np.linalg.solve(M, rhs)

    def hinge_positions(self, q: np.ndarray) -> np.ndarray:
        """Global positions [m] of the hinge of each segment (its inboard point), ``(n_segments, 2)``."""
        q = np.asarray(q, float)
        out, base = [], np.zeros(2)
        for j, seg in enumerate(self.segments):
            out.append(base.copy())
            th = q[self.theta_index[j]]
            R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
            if isinstance(seg, ParticleNet) and seg.outboard is not None:
                e = seg.outboard
                base = base + R @ (np.asarray(seg.positions[e], float) + q[self.u_index[j][2 * e:2 * e + 2]])
                continue
            if isinstance(seg, (ParticleNet, MembranePlate)):
                break
            rho = np.array([seg.length, 0.0])
            if j in self.beams:
                rho = rho + self.beams[j].end @ q[self.u_index[j]]
            base = base + R @ rho
        return np.array(out)

    def interaction_force(self, q: np.ndarray, qd: np.ndarray, j: int, t: float = 0.0) -> np.ndarray:
        """Force [N] (global axes) exerted on segment ``j`` by its parent at the hinge: the momentum rate of
        segments ``j, j+1, ...`` minus their weight."""
        qdd = self.accelerations(q, qd, t)
        pts, _, _, _ = self._points(np.asarray(q, float), np.asarray(qd, float))
        return sum(np.einsum("p,pi->i", np.atleast_1d(m), Jp.reshape(-1, 2, self.n) @ qdd + bias.reshape(-1, 2)
                             - self.gravity) for m, _, Jp, bias, k in pts if k >= j)

    def energy(self, q: np.ndarray, qd: np.ndarray) -> float:
        """Kinetic + gravity + strain + hinge-spring energy [J] (no ``force`` potential)."""
        pts, rotary, springs, _ = self._points(np.asarray(q, float), np.asarray(qd, float))
        e = sum(0.5 * k * (np.linalg.norm(rb - ra) - rest) ** 2 for (ra, _), (rb, _), k, rest, _ in springs)
        for m, r, Jp, _, _ in pts:
            m, v = np.atleast_1d(m), Jp.reshape(-1, 2, self.n) @ qd
            e += float(0.5 * m @ np.sum(v * v, axis=1) - m @ (r.reshape(-1, 2) @ self.gravity))
        for it, inertia in rotary:
            e += 0.5 * inertia * qd[it] ** 2
        stiffness = [bm.stiffness for bm in self.beams.values()] + [pl.stiffness for pl in self.plates.values()]
        for j, K in zip(list(self.beams) + list(self.plates) + list(self.net_stiffness),
                        stiffness + list(self.net_stiffness.values())):
            u = q[self.u_index[j]]
            e += 0.5 * u @ K @ u
        phi = self.hinge_angles(q)
        e += sum(0.5 * seg.stiffness * phi[j] ** 2 for j, seg in enumerate(self.segments)
                 if not isinstance(seg, (ParticleNet, MembranePlate)))
        return float(e)

    # -- integration ----------------------------------------------------------------------
    def rk4(self, q0, qd0, t_final: float, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Classical fixed-step RK4: times, ``q`` and ``q_dot`` histories."""
        steps = int(round(t_final / dt))
        y = np.concatenate([np.asarray(q0, float), np.asarray(qd0, float)])
        n = self.n
        out = np.empty((steps + 1, 2 * n))
        out[0] = y

        def f(t, y):
            return np.concatenate([y[n:], self.accelerations(y[:n], y[n:], t)])
        for k in range(steps):
            t = k * dt
            k1 = f(t, y)
            k2 = f(t + dt / 2, y + dt / 2 * k1)
            k3 = f(t + dt / 2, y + dt / 2 * k2)
            k4 = f(t + dt, y + dt * k3)
            y = y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            out[k + 1] = y
        return np.arange(steps + 1) * dt, out[:, :n], out[:, n:]

    def solve(self, q0, qd0, times: np.ndarray, rtol: float = 1e-12, atol: float = 1e-13):
        """``solve_ivp`` (DOP853) at ``times``: ``q`` and ``q_dot`` histories."""
        n = self.n
        sol = scipy.integrate.solve_ivp(lambda t, y: np.concatenate([y[n:], self.accelerations(y[:n], y[n:], t)]),
                                        (times[0], times[-1]), np.concatenate([q0, qd0]), method="DOP853",
                                        t_eval=times, rtol=rtol, atol=atol)
        return sol.y[:n].T, sol.y[n:].T

    # -- linearisation ----------------------------------------------------------------------
    def equilibrium(self, q_guess) -> np.ndarray:
        """Static equilibrium by Newton on the generalised forces (complex-step tangent)."""
        q = np.asarray(q_guess, float).copy()
        for _ in range(50):
            _, rhs = self._generalised(q, np.zeros(self.n), 0.0)
            Kt = self._stiffness(q)
            dq = np.linalg.solve(Kt, rhs)
            q = q + dq
            if np.max(np.abs(dq)) < 1e-14 * (1 + np.max(np.abs(q))):
                break
        return q

    def _stiffness(self, q) -> np.ndarray:
        """``K = -dQ/dq`` at rest, by complex step."""
        K = np.zeros((self.n, self.n))
        for i in range(self.n):
            dq = np.zeros(self.n, complex)
            dq[i] = 1e-30j
            _, rhs = self._generalised(q + dq, np.zeros(self.n), 0.0)
            K[:, i] = -rhs.imag / 1e-30
        return K

    def natural_frequencies(self, q0) -> np.ndarray:
        """Undamped natural frequencies [rad/s] about the rest point ``q0``: ``eigh(K, M)``."""
        M, _ = self._generalised(np.asarray(q0, float), np.zeros(self.n), 0.0)
        K = self._stiffness(np.asarray(q0, float))
        values = scipy.linalg.eigh(0.5 * (K + K.T), M, eigvals_only=True)
        return np.sqrt(np.clip(values, 0.0, None))
