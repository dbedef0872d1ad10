"""Independent reference: a spatial chain of rigid links on revolute joints carrying a finite-element
frame, as one global model in minimal coordinates (tests only; no code of ``ctmm.fem``, of
``ctmm.spatial`` or of a sweep).

Coordinates ``q = [joint angles (chain order) ; u]``, ``u`` the frame's node DOFs (all nodes but the
inboard one, in the given node order; per node ``ux, uy, uz`` and, at beam nodes, ``rx, ry, rz``, frame
axes).  The FE frame's floating frame is its inboard node's frame (the child frame of its joint); a
material point is at ``r = o_F + R_F (X + S(X) u)``.

* **Interpolation** (own construction): per element local axes ``e1`` along it, ``e2`` the component
  of ``orientation`` perpendicular to it, ``e3 = e1 x e2``; axial displacement and twist linear,
  deflections cubic with the end values and slopes (``v' = r_z``, ``w' = -r_y``), their coefficients
  from solving the 4 x 4 end-condition system numerically;
* **mass**: four Gauss points per element (exact for the degree-6 integrands), particles' kinetic energy
  by Kane (``J^T m (J q'' + J' q')``, ``J' q'`` by complex step along ``q'``); the section twist inertia
  ``1/2 rho I_p (e1 . omega_F + phi')^2`` and node inertias ``1/2 Omega^T I Omega`` (``Omega = omega_F +
  r'``, frame axes) by Lagrange's equations (``d/dt dT/dq' - dT/dq``, the derivatives by complex steps);
* **stiffness** from the strain energy ``1/2 int EA u'^2 + EI_y v''^2 + EI_z w''^2 + GJ phi'^2`` by
  quadrature; optional stiffness-proportional damping ``C = b K``;
* **plates** (:class:`FramePlate`, own construction of the flat rectangle of ``ctmm.fem.SpatialPlateElement``):
  local axes from the corners; in-plane displacements bilinear in ``(x, y)`` and the deflection a
  combination of the twelve ACM monomials ``1, x, y, x^2, x y, y^2, x^3, x^2 y, x y^2, y^3, x^3 y, x y^3``,
  both with coefficients from solving the corner-value systems numerically (``w, dw/dy = r_x, -dw/dx = r_y``
  at the corners); mass points at 5 x 5 Gauss points; strain energy ``1/2 int (kappa^T D_b kappa +
  eps^T h C eps)`` by the same quadrature; the drilling rotation (about the normal) tied to the membrane's
  rotation ``(v_x - u_y)/2`` at each corner by the penalty ``k_d = ratio G h A / 4`` and a corner inertia
  ``rho h A (a^2 + b^2) / 192`` about the normal;
* **Timoshenko beams** (``FrameBeam(kGAy=..., kGAz=..., rhoIy=..., rhoIz=...)``): per bending plane the
  deflection cubic and the section rotation quadratic, their seven coefficients from the four end values and
  the three polynomial identities of the static Timoshenko equations (solved numerically); strain energy
  ``1/2 int (EI theta'^2 + kGA (v' - theta)^2)``, the sections' rotary inertia ``1/2 Omega_s^T I_s Omega_s``
  with ``Omega_s`` the frame's angular velocity plus the section rotation rates ``[phi', r_y', r_z']``;
* **links**: rigid bodies, Kane with world angular velocities; a link after the frame hangs on a node
  on a revolute joint whose axis is given in the node frame ``R_F Rz(r_z) Ry(r_y) Rx(r_x)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import scipy.linalg

__all__ = ["Link", "FrameBeam", "FrameMass", "FramePlate", "FEFrame", "SpatialFEChain"]

_G4, _W4 = np.polynomial.legendre.leggauss(4)
_XI, _WT = 0.5 * (_G4 + 1.0), 0.5 * _W4
_H = 1e-30


def _hat(v) -> np.ndarray:
    return np.array([[0.0 * v[0], -v[2], v[1]], [v[2], 0.0 * v[0], -v[0]], [-v[1], v[0], 0.0 * v[0]]])


def _axis_terms(axis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``([a]x, [a]x^2, a)`` of the unit vector ``a`` along ``axis``: the constant parts of :func:`_rotation`."""
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return _hat(a), _hat(a) @ _hat(a), a


def _rotation(terms: tuple[np.ndarray, ...], angle) -> np.ndarray:
    return np.eye(3) + np.sin(angle) * terms[0] + (1 - np.cos(angle)) * terms[1]


_NODE_AXES = tuple(_axis_terms(axis) for axis in ((1, 0, 0), (0, 1, 0), (0, 0, 1)))   # a node's rotations x, y, z
_NODE_HATS = (_hat([1.0, 0, 0]), _hat([0, 1.0, 0]), _hat([0, 0, 1.0]))


@dataclass
class Link:
    """Rigid link on a revolute joint: mass [kg], inertia about the centre (3 x 3, body axes) [kg m^2],
    centre ``com`` (body axes) [m], joint ``axis`` (parent point frame), ``point`` on the parent (a (3,)
    vector in the parent's axes, a node name of a frame parent, or the world location for the first)."""

    mass: float
    inertia: Any
    com: Any
    axis: Any
    point: Any = (0.0, 0.0, 0.0)


@dataclass
class FrameBeam:
    start: str
    end: str
    EA: float
    GJ: float
    EIy: float
    EIz: float
    rhoA: float
    rhoIp: float
    orientation: Any
    kGAy: Any = None            # Timoshenko: kappa G A of the deflection along e2 / e3 (None: rigid in shear)
    kGAz: Any = None
    rhoIy: float = 0.0          # rotary inertia of the sections of the bending along e2 (about e3) / e3 (about e2)
    rhoIz: float = 0.0


def _bending_plane(L: float, EI: float, kGA: Any, ends: np.ndarray):
    """Coefficients of ``v = [1, x, x^2, x^3] a`` and the section rotation ``theta = [1, x, x^2] b`` from the end
    values ``ends`` (4, nu) ``[v_a, theta_a, v_b, theta_b]``: without shear ``theta = v'`` (the cubic through the
    end values and slopes); with ``kGA`` the static Timoshenko solution (``v'' = theta'``, ``EI theta'' + kGA (v' -
    theta) = 0`` as polynomial identities), solved numerically as a 7 x 7 system."""
    if kGA is None:
        a = np.linalg.solve(np.array([[1, 0, 0, 0], [0, 1, 0, 0], [1, L, L * L, L ** 3], [0, 1, 2 * L, 3 * L * L]],
                                     float), ends)
        return a, np.array([a[1], 2 * a[2], 3 * a[3]])
    system = np.array([[1, 0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 1, 0, 0], [1, L, L * L, L ** 3, 0, 0, 0],
                       [0, 0, 0, 0, 1, L, L * L], [0, 0, 2, 0, 0, -1, 0], [0, 0, 0, 3, 0, 0, -1],
                       [0, kGA, 0, 0, -kGA, 0, 2 * EI]], float)
    c = np.linalg.solve(system, np.vstack([ends, np.zeros((3, ends.shape[1]))]))
    return c[:4], c[4:]


@dataclass
class FrameMass:
    node: str
    mass: float
    inertia: Any = field(default_factory=lambda: np.zeros((3, 3)))


@dataclass
class FramePlate:
    """Rectangular plate: corner nodes (counter-clockwise about the normal), thickness [m], E [Pa], nu, rho
    [kg/m^3], drilling penalty ratio."""

    nodes: tuple
    h: float
    E: float
    nu: float
    rho: float
    ratio: float = 0.1


@dataclass
class FEFrame:
    """FE frame welded (``axis=None``) or on a revolute joint at ``point`` of the previous link; ``nodes``
    positions in the frame [m] relative to ``inboard`` (which must be at the origin)."""

    nodes: dict
    inboard: str
    beams: Sequence[FrameBeam]
    masses: Sequence[FrameMass] = ()
    axis: Any = None
    point: Any = (0.0, 0.0, 0.0)
    stiffness_damping: float = 0.0
    plates: Sequence[FramePlate] = ()


class SpatialFEChain:
    """Global model of ``segments`` (``Link``s and one ``FEFrame``) in chain order, gravity [m/s^2] and an
    extra generalised force ``force(u, u_dot) -> (n_u,)`` on the frame's DOFs; ``joint_springs`` ``{joint
    index: (k [N m/rad], c [N m s/rad])}`` adds ``-k q - c q'`` on those joint angles."""

    def __init__(self, segments: Sequence[Any], gravity=(0.0, 0.0, -9.81), force: Any = None,
                 joint_springs: Any = None) -> None:
        self.segments = list(segments)
        self.force = force
        self.joint_springs = {} if joint_springs is None else dict(joint_springs)    # {joint index: (k, c)}
        self.gravity = np.asarray(gravity, dtype=float)
        frames = [k for k, s in enumerate(self.segments) if isinstance(s, FEFrame)]
        assert len(frames) == 1
        self.frame_index = frames[0]
        fe = self.segments[self.frame_index]
        rotating = {n for b in fe.beams for n in (b.start, b.end)} | {n for p in fe.plates for n in p.nodes}
        self.n_joints = sum(1 for s in self.segments if isinstance(s, Link) or s.axis is not None)
        self.node_index, count = {}, 0
        for name in fe.nodes:
            if name == fe.inboard:
                continue
            k = 6 if name in rotating else 3
            self.node_index[name] = list(range(count, count + k))
            count += k
        self.n_u = count
        self.n = self.n_joints + count
        self._joint_axes = {k: _axis_terms(s.axis) for k, s in enumerate(self.segments) if s.axis is not None}
        self._elements()

    # -------------------------------------------------------------------------------- the frame
    def _dofs(self, node: str) -> list:
        """Indices into ``u`` of a node's six (or three) DOFs; None entries for the inboard node."""
        fe = self.segments[self.frame_index]
        if node == fe.inboard:
            return [None] * 6
        return self.node_index[node]

    def _elements(self) -> None:
        fe = self.segments[self.frame_index]
        nu = self.n_u
        points, masses, rotary = [], [], []               # (X (3,), S (3, nu)), m; (inertia k x k, A k x 3, B k x nu)
        K = np.zeros((nu, nu))
        cubic = np.linalg.inv
        for b in fe.beams:
            pa, pb = np.asarray(fe.nodes[b.start], float), np.asarray(fe.nodes[b.end], float)
            L = np.linalg.norm(pb - pa)
            e1 = (pb - pa) / L
            y = np.asarray(b.orientation, float) - (np.asarray(b.orientation, float) @ e1) * e1
            e2 = y / np.linalg.norm(y)
            e3 = np.cross(e1, e2)
            Q = np.vstack([e1, e2, e3])                    # local = Q frame
            Ac = cubic(np.array([[1, 0, 0, 0], [0, 1, 0, 0], [1, L, L * L, L ** 3], [0, 1, 2 * L, 3 * L * L]], float))
            Al = cubic(np.array([[1.0, 0.0], [1.0, L]]))
            da, db = self._dofs(b.start), self._dofs(b.end)

            def local(node_dofs, part):                   # (3, nu): local components of a node's vector part
                out = np.zeros((3, nu))
                for k in range(3):
                    i = node_dofs[3 * part + k]
                    if i is not None:
                        out[:, i] += Q[:, k]
                return out
            ta, ra, tb, rb = local(da, 0), local(da, 1), local(db, 0), local(db, 1)
            ends_v = np.vstack([ta[1], ra[2], tb[1], rb[2]])           # v, v', at a and b
            ends_w = np.vstack([ta[2], -ra[1], tb[2], -rb[1]])
            ends_u, ends_p = np.vstack([ta[0], tb[0]]), np.vstack([ra[0], rb[0]])
            timoshenko = b.kGAy is not None or b.kGAz is not None or b.rhoIy or b.rhoIz
            planes = [_bending_plane(L, b.EIy, b.kGAy, ends_v), _bending_plane(L, b.EIz, b.kGAz, ends_w)]
            for xi, wt in zip(_XI, _WT):
                x = xi * L
                pc, dc2 = np.array([1, x, x * x, x ** 3]), np.array([0, 0, 2, 6 * x])
                pl, dl = np.array([1, x]), np.array([0, 1.0])
                u_row, phi_row = pl @ Al @ ends_u, pl @ Al @ ends_p
                if not timoshenko:
                    v_row, w_row = pc @ Ac @ ends_v, pc @ Ac @ ends_w
                    strains = [(b.EA, dl @ Al @ ends_u), (b.EIy, dc2 @ Ac @ ends_v), (b.EIz, dc2 @ Ac @ ends_w),
                               (b.GJ, dl @ Al @ ends_p)]
                else:
                    dc1, pq, dq = np.array([0, 1, 2 * x, 3 * x * x]), np.array([1, x, x * x]), np.array([0, 1, 2 * x])
                    (av, bv), (aw, bw) = planes
                    v_row, w_row = pc @ av, pc @ aw
                    strains = [(b.EA, dl @ Al @ ends_u), (b.EIy, dq @ bv), (b.EIz, dq @ bw), (b.GJ, dl @ Al @ ends_p)]
                    for kGA, (a_, b_) in ((b.kGAy, planes[0]), (b.kGAz, planes[1])):
                        if kGA is not None:
                            strains.append((kGA, dc1 @ a_ - pq @ b_))
                    rotation = np.vstack([phi_row, -(pq @ bw), pq @ bv])      # local [twist, r_y, r_z]
                    rotary.append((np.diag([b.rhoIp, b.rhoIz, b.rhoIy]) * L * wt, Q, rotation))
                S = Q.T @ np.vstack([u_row, v_row, w_row])             # frame components
                points.append((pa + x * e1, S))
                masses.append(b.rhoA * L * wt)
                if b.rhoIp and not timoshenko:
                    rotary.append((np.array([[b.rhoIp * L * wt]]), e1[None, :], phi_row[None, :]))
                for modulus, row in strains:
                    K += modulus * L * wt * np.outer(row, row)
        for plate in fe.plates:
            K += self._plate(plate, points, masses, rotary)
        for pm in fe.masses:
            d = self._dofs(pm.node)
            S = np.zeros((3, nu))
            for k in range(3):
                if d[k] is not None:
                    S[k, d[k]] = 1.0
            points.append((np.asarray(fe.nodes[pm.node], float), S))
            masses.append(pm.mass)
            I = np.asarray(pm.inertia, float)
            I = np.diag(I) if I.shape == (3,) else I
            B = np.zeros((3, nu))
            if len(d) == 6 and d[3] is not None:
                for k in range(3):
                    B[k, d[3 + k]] = 1.0
            rotary.append((I, np.eye(3), B))
        self.X = np.array([p[0] for p in points])
        self.S = np.array([p[1] for p in points])
        self.m = np.array(masses)
        self.rotary = rotary
        self.K = K
        self.C = fe.stiffness_damping * K

    def _plate(self, plate: FramePlate, points: list, masses: list, rotary: list) -> np.ndarray:
        """Append a plate's mass points and drilling inertias; return its stiffness (n_u x n_u)."""
        fe = self.segments[self.frame_index]
        nu_ = self.n_u
        corners = np.array([fe.nodes[k] for k in plate.nodes], float)
        ex, ey = corners[1] - corners[0], corners[3] - corners[0]
        a, b = np.linalg.norm(ex), np.linalg.norm(ey)
        Q = np.vstack([ex / a, ey / b, np.cross(ex / a, ey / b)])            # local = Q frame
        local_xy = np.array([[0.0, 0.0], [a, 0.0], [a, b], [0.0, b]])

        def node_rows(node):                     # (6, nu): local [u, v, w, r_x, r_y, r_z] of a corner
            out = np.zeros((6, nu_))
            d = self._dofs(node)
            for part in range(2):
                for k in range(3):
                    i = d[3 * part + k]
                    if i is not None:
                        out[3 * part:3 * part + 3, i] += Q[:, k]
            return out
        rows = [node_rows(k) for k in plate.nodes]

        def mono(x, y):
            return (np.array([1, x, y, x * x, x * y, y * y, x ** 3, x * x * y, x * y * y, y ** 3, x ** 3 * y, x * y ** 3]),
                    np.array([0, 1, 0, 2 * x, y, 0, 3 * x * x, 2 * x * y, y * y, 0, 3 * x * x * y, y ** 3]),
                    np.array([0, 0, 1, 0, x, 2 * y, 0, x * x, 2 * x * y, 3 * y * y, x ** 3, 3 * x * y * y]),
                    np.array([0, 0, 0, 2, 0, 0, 6 * x, 2 * y, 0, 0, 6 * x * y, 0]),
                    np.array([0, 0, 0, 0, 0, 2, 0, 0, 2 * x, 6 * y, 0, 6 * x * y]),
                    np.array([0, 0, 0, 0, 1, 0, 0, 2 * x, 2 * y, 0, 3 * x * x, 3 * y * y]))
        system, ends = [], []
        for (x, y), r in zip(local_xy, rows):
            p, px, py = mono(x, y)[:3]
            system += [p, py, -px]
            ends += [r[2], r[3], r[4]]
        coeff_w = np.linalg.solve(np.array(system, float), np.array(ends))          # (12, nu)
        bil = np.array([[1.0, x, y, x * y] for x, y in local_xy])
        coeff_u = np.linalg.solve(bil, np.array([r[0] for r in rows]))             # (4, nu)
        coeff_v = np.linalg.solve(bil, np.array([r[1] for r in rows]))
        E, nu, h, rho = plate.E, plate.nu, plate.h, plate.rho
        Dm = E / (1 - nu * nu) * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1 - nu) / 2]])
        Db = Dm * h ** 3 / 12
        K = np.zeros((nu_, nu_))
        g, wg = np.polynomial.legendre.leggauss(5)
        for gx, wx in zip(0.5 * (g + 1) * a, 0.5 * wg * a):
            for gy, wy in zip(0.5 * (g + 1) * b, 0.5 * wg * b):
                p, _, _, pxx, pyy, pxy = mono(gx, gy)
                lin, lin_x, lin_y = np.array([1.0, gx, gy, gx * gy]), np.array([0, 1.0, 0, gy]), np.array([0, 0, 1.0, gx])
                S = Q.T @ np.vstack([lin @ coeff_u, lin @ coeff_v, p @ coeff_w])
                points.append((corners[0] + gx * Q[0] + gy * Q[1], S))
                masses.append(rho * h * wx * wy)
                kappa = np.vstack([pxx @ coeff_w, pyy @ coeff_w, 2 * pxy @ coeff_w])
                eps = np.vstack([lin_x @ coeff_u, lin_y @ coeff_v, lin_y @ coeff_u + lin_x @ coeff_v])
                K += wx * wy * (kappa.T @ Db @ kappa + h * eps.T @ Dm @ eps)
        k_d = plate.ratio * E / (2 * (1 + nu)) * h * a * b / 4
        j = rho * h * a * b * (a * a + b * b) / 192
        for (x, y), r, node in zip(local_xy, rows, plate.nodes):
            omega = 0.5 * (np.array([0, 1.0, 0, y]) @ coeff_v - np.array([0, 0, 1.0, x]) @ coeff_u)
            row = r[5] - omega
            K += k_d * np.outer(row, row)
            d = self._dofs(node)
            B = np.zeros((3, nu_))
            if d[3] is not None:
                for k in range(3):
                    B[k, d[3 + k]] = 1.0
            rotary.append((j * np.outer(Q[2], Q[2]), np.eye(3), B))
        return K

    # --------------------------------------------------------------------------- kinematics
    def _node_frame(self, u, node: str):
        """``(rho, E, Theta_cols)``: deformed node position, rotation ``Rz Ry Rx`` and the map of the node's
        rotation rates to its angular velocity (frame axes, 3 x nu)."""
        fe = self.segments[self.frame_index]
        d = self._dofs(node)
        X = np.asarray(fe.nodes[node], float)
        rho = X + np.array([u[i] if i is not None else 0.0 for i in d[:3]])
        Smap = np.zeros((3, self.n_u))
        for k in range(3):
            if d[k] is not None:
                Smap[k, d[k]] = 1.0
        if len(d) < 6 or d[3] is None:
            return rho, np.eye(3), np.zeros((3, self.n_u)), Smap
        a, b, c = u[d[3]], u[d[4]], u[d[5]]
        Rx, Ry, Rz = (_rotation(terms, angle) for terms, angle in zip(_NODE_AXES, (a, b, c)))
        E = Rz @ Ry @ Rx
        dE = [Rz @ Ry @ (_NODE_HATS[0] @ Rx), Rz @ (_NODE_HATS[1] @ Ry) @ Rx, (_NODE_HATS[2] @ Rz) @ Ry @ Rx]
        W = np.zeros((3, self.n_u), dtype=np.result_type(u, float))
        for k in range(3):
            w = dE[k] @ E.T
            W[:, d[3 + k]] = [w[2, 1], w[0, 2], w[1, 0]]
        return rho, E, W, Smap

    def kinematics(self, q, points: bool = True) -> dict:
        """Jacobians at ``q`` (complex allowed): links ``(R, r_com, Jv_com, Jw)``, the frame ``(R_F, o_F,
        Jv_F, Jw_F)``, mass points ``(r_p, J_p)`` (left out when not ``points``)."""
        dtype = np.result_type(q, float)
        n = self.n
        u = q[self.n_joints:]
        Su = np.zeros((self.n_u, n))
        Su[:, self.n_joints:] = np.eye(self.n_u)
        R, o = np.eye(3, dtype=dtype), np.zeros(3, dtype=dtype)
        Jv, Jw = np.zeros((3, n), dtype=dtype), np.zeros((3, n), dtype=dtype)
        links, frame, joint = [], None, 0
        for k, seg in enumerate(self.segments):
            point = seg.point
            if k == 0:
                Rp, op, Jvp, Jwp = R, np.asarray(point, float).astype(dtype), Jv, Jw
            elif isinstance(self.segments[k - 1], FEFrame):
                R_F, o_F, Jv_F, Jw_F = frame
                rho, E, W, Smap = self._node_frame(u, point)
                Rp, op = R_F @ E, o_F + R_F @ rho
                Jvp = Jv_F - _hat(R_F @ rho) @ Jw_F + R_F @ Smap @ Su
                Jwp = Jw_F + R_F @ W @ Su
            else:
                arm = R @ np.asarray(point, float)
                Rp, op, Jvp, Jwp = R, o + arm, Jv - _hat(arm) @ Jw, Jw
            if isinstance(seg, Link) or seg.axis is not None:
                R = Rp @ _rotation(self._joint_axes[k], q[joint])
                Jw = Jwp.copy()
                Jw[:, joint] = Jw[:, joint] + Rp @ self._joint_axes[k][2]
                joint += 1
            else:
                R, Jw = Rp, Jwp
            o, Jv = op, Jvp
            if isinstance(seg, Link):
                arm = R @ np.asarray(seg.com, float)
                links.append((R, o + arm, Jv - _hat(arm) @ Jw, Jw))
            else:
                frame = (R, o, Jv, Jw)
        if not points:
            return {"links": links, "frame": frame, "Su": Su}
        R_F, o_F, Jv_F, Jw_F = frame
        rho = self.X + np.einsum("pij,j->pi", self.S, u)
        arms = rho @ R_F.T
        r_p = o_F[None, :] + arms
        hats = np.array([_hat(a) for a in arms])
        J_p = Jv_F[None] - hats @ Jw_F[None] + np.einsum("ij,pjk,kl->pil", R_F, self.S, Su)
        return {"links": links, "frame": frame, "points": (r_p, J_p), "Su": Su}

    def node_point(self, q, node: str) -> tuple[np.ndarray, np.ndarray]:
        """World position [m] of a frame node and its Jacobian ``d r / d q`` (3 x n)."""
        q = np.asarray(q, float)
        R_F, o_F, Jv_F, Jw_F = self.kinematics(q, points=False)["frame"]
        rho, _, _, Smap = self._node_frame(q[self.n_joints:], node)
        Su = np.zeros((self.n_u, self.n))
        Su[:, self.n_joints:] = np.eye(self.n_u)
        return o_F + R_F @ rho, Jv_F - _hat(R_F @ rho) @ Jw_F + R_F @ Smap @ Su

    def node_acceleration_terms(self, q, qd, node: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(r, J, J' q')`` of a frame node: world position [m], ``J = d r / d q`` (3 x n) and the velocity part
        of its acceleration ``a = J q'' + J' q'`` [m/s^2] (``J'`` by a complex step of ``J`` along ``q'``)."""
        def point(qc):
            R_F, o_F, Jv_F, Jw_F = self.kinematics(qc, points=False)["frame"]
            rho, _, _, Smap = self._node_frame(qc[self.n_joints:], node)
            Su = np.zeros((self.n_u, self.n))
            Su[:, self.n_joints:] = np.eye(self.n_u)
            return o_F + R_F @ rho, Jv_F - _hat(R_F @ rho) @ Jw_F + R_F @ Smap @ Su
        q, qd = np.asarray(q, float), np.asarray(qd, float)
        r, J = point(q)
        return r, J, (point(q + 1j * _H * qd)[1].imag / _H) @ qd

    def node_axis_terms(self, q, qd, node: str, axis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(a, J, J' q')`` of an axis fixed in a frame node's axes (``axis``, node axes): the world vector
        ``a = R_F E(r) axis``, ``J = d a / d q = -[a]x J_omega`` (3 x n, ``J_omega`` the node frame's angular velocity
        Jacobian) and ``J' q'`` (complex step of ``J`` along ``q'``)."""
        def frame_axis(qc):
            R_F, _, _, Jw_F = self.kinematics(qc, points=False)["frame"]
            _, E, W, _ = self._node_frame(qc[self.n_joints:], node)
            Su = np.zeros((self.n_u, self.n))
            Su[:, self.n_joints:] = np.eye(self.n_u)
            a = R_F @ E @ np.asarray(axis, float)
            return a, -_hat(a) @ (Jw_F + R_F @ W @ Su)
        q, qd = np.asarray(q, float), np.asarray(qd, float)
        a, J = frame_axis(q)
        return a, J, (frame_axis(q + 1j * _H * qd)[1].imag / _H) @ qd

    def mass_and_forces(self, q, qd) -> tuple[np.ndarray, np.ndarray]:
        """``(M, rhs)`` of ``M q'' = rhs`` at ``(q, q')`` (gravity, velocity terms, stiffness, damping, ``force``)."""
        M, rhs, _, _ = self._terms(np.asarray(q, float), np.asarray(qd, float))
        return M, rhs

    def _rotary_jacobians(self, kin: dict) -> list:
        R_F, _, _, Jw_F = kin["frame"]
        out = []
        for I, A, B in self.rotary:
            out.append((I, A @ R_F.T @ Jw_F + B @ kin["Su"]))
        return out

    # ------------------------------------------------------------------------------ dynamics
    def _terms(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict, dict]:
        """``M``, ``Q - b`` (generalised forces minus velocity terms), the kinematics and their rates."""
        kin = self.kinematics(q)
        kin_d = self.kinematics(q + 1j * _H * qd)                     # J' = imag / h
        n = self.n
        M = np.zeros((n, n))
        rhs = np.zeros(n)
        g = self.gravity
        for (R, _, Jv, Jw), (_, _, Jv_c, Jw_c), seg in zip(kin["links"], kin_d["links"],
                                                         [s for s in self.segments if isinstance(s, Link)]):
            Iw = R @ np.asarray(seg.inertia, float) @ R.T
            w = Jw @ qd
            M += seg.mass * Jv.T @ Jv + Jw.T @ Iw @ Jw
            rhs += Jv.T @ (seg.mass * (g - (Jv_c.imag / _H) @ qd)) - Jw.T @ (Iw @ (Jw_c.imag / _H) @ qd
                                                                              + np.cross(w, Iw @ w))
        _, J_p = kin["points"]
        Jd_p = kin_d["points"][1].imag / _H
        M += np.einsum("p,pik,pil->kl", self.m, J_p, J_p)
        rhs += np.einsum("p,pik,pi->k", self.m, J_p, g[None, :] - Jd_p @ qd)
        rot, rot_d = self._rotary_jacobians(kin), self._rotary_jacobians(kin_d)
        probes = []
        for k in range(self.frame_joints()):
            e = np.zeros(n)
            e[k] = 1.0
            probes.append(self._rotary_jacobians(self.kinematics(q + 1j * _H * e, points=False)))
        for r, ((I, J), (_, Jc)) in enumerate(zip(rot, rot_d)):
            Jd = Jc.imag / _H
            Omega = J @ qd
            dT = np.zeros(n)
            for k, probe in enumerate(probes):
                dT[k] = Omega @ I @ ((probe[r][1].imag / _H) @ qd)
            M += J.T @ I @ J
            rhs -= J.T @ I @ Jd @ qd + Jd.T @ I @ Omega - dT
        u, ud = q[self.n_joints:], qd[self.n_joints:]
        rhs[self.n_joints:] -= self.K @ u + self.C @ ud
        if self.force is not None:
            rhs[self.n_joints:] += self.force(u, ud)
        for k, (stiffness, damping) in self.joint_springs.items():
            rhs[k] -= stiffness * q[k] + damping * qd[k]
        return M, rhs, kin, kin_d

    def frame_joints(self) -> int:
        """Number of joint angles inboard of (and including) the frame's joint."""
        return sum(1 for s in self.segments[:self.frame_index + 1] if isinstance(s, Link) or s.axis is not None)

    def accelerations(self, q, qd) -> np.ndarray:
        """``q''`` at ``(q, q')``."""
        M, rhs, _, _ = self._terms(np.asarray(q, float), np.asarray(qd, float))
        return np.linalg.solve(M, rhs)

    def interaction_force(self, q, qd) -> np.ndarray:
        """Force [N] (world axes) of the frame on the links hung on it: ``sum m (a_com - g)`` over them."""
        q, qd = np.asarray(q, float), np.asarray(qd, float)
        M, rhs, kin, kin_d = self._terms(q, qd)
        qdd = np.linalg.solve(M, rhs)
        links = [s for s in self.segments if isinstance(s, Link)]
        before = sum(1 for s in self.segments[:self.frame_index] if isinstance(s, Link))
        force = np.zeros(3)
        for seg, (_, _, Jv, _), (_, _, Jv_c, _) in list(zip(links, kin["links"], kin_d["links"]))[before:]:
            force += seg.mass * (Jv @ qdd + (Jv_c.imag / _H) @ qd - self.gravity)
        return force

    def energy(self, q, qd) -> float:
        """Kinetic + strain (frame and joint springs) + gravitational energy [J]."""
        q, qd = np.asarray(q, float), np.asarray(qd, float)
        kin = self.kinematics(q)
        total = 0.0
        for (R, r_c, Jv, Jw), seg in zip(kin["links"], [s for s in self.segments if isinstance(s, Link)]):
            v, w = Jv @ qd, Jw @ qd
            total += 0.5 * seg.mass * v @ v + 0.5 * w @ R @ np.asarray(seg.inertia, float) @ R.T @ w \
                - seg.mass * self.gravity @ r_c
        r_p, J_p = kin["points"]
        v_p = J_p @ qd
        total += 0.5 * np.sum(self.m * np.sum(v_p * v_p, axis=1)) - np.sum(self.m * (r_p @ self.gravity))
        for I, J in self._rotary_jacobians(kin):
            total += 0.5 * (J @ qd) @ I @ (J @ qd)
        u = q[self.n_joints:]
        total += sum(0.5 * stiffness * q[k] ** 2 for k, (stiffness, _) in self.joint_springs.items())
        return float(total + 0.5 * u @ self.K @ u)

    def rk4(self, q0, qd0, t_final: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Fixed-step RK4 of ``[q ; q']``: times and states (steps + 1, 2 n)."""
        n = self.n
        x = np.concatenate([np.asarray(q0, float), np.asarray(qd0, float)])
        steps = int(round(t_final / dt))
        out = [x.copy()]

        def f(y):
            return np.concatenate([y[n:], self.accelerations(y[:n], y[n:])])
        for _ in range(steps):
            k1 = f(x)
            k2 = f(x + dt / 2 * k1)
            k3 = f(x + dt / 2 * k2)
            k4 = f(x + dt * k3)
            x = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            out.append(x.copy())
        return np.arange(steps + 1) * dt, np.array(out)

    def linear_matrices(self, q0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``M, K_t, C`` about the static equilibrium ``q0``: the tangent stiffness ``K_t = -d(Q - b)/dq`` at rest
        by complex step; ``C`` the frame's damping and the joint dampers (the velocity terms are quadratic: no tangent
        at rest)."""
        q0 = np.asarray(q0, float)
        n = self.n
        M, _, _, _ = self._terms(q0, np.zeros(n))
        Kt = np.zeros((n, n))
        for k in range(n):
            e = np.zeros(n)
            e[k] = 1.0
            _, rhs, _, _ = self._terms_complex(q0 + 1j * _H * e)
            Kt[:, k] = -rhs.imag / _H
        C = np.zeros((n, n))
        C[self.n_joints:, self.n_joints:] = self.C
        for k, (_, damping) in self.joint_springs.items():
            C[k, k] += damping
        return M, 0.5 * (Kt + Kt.T), C

    def natural_frequencies(self, q0) -> np.ndarray:
        """Undamped natural frequencies [rad/s] about the static equilibrium ``q0``: ``eigh(K_t, M)``."""
        M, Kt, _ = self.linear_matrices(q0)
        return np.sqrt(np.clip(scipy.linalg.eigh(Kt, M, eigvals_only=True), 0.0, None))

    def frequency_response(self, q0, omega, load: Any, output: Any) -> np.ndarray:
        """Phasor of an output per unit harmonic load: ``load`` a coordinate index (a generalised force) or a
        vector ``(n,)`` of generalised forces; ``output`` a coordinate index or a row ``(n,)``."""
        M, Kt, C = self.linear_matrices(q0)
        b = np.eye(self.n)[load] if np.ndim(load) == 0 else np.asarray(load, float)
        c = np.eye(self.n)[output] if np.ndim(output) == 0 else np.asarray(output, float)
        return np.array([c @ np.linalg.solve(Kt - w * w * M + 1j * w * C, b) for w in np.atleast_1d(omega)])

    def _terms_complex(self, q: np.ndarray):
        """Generalised forces at rest for a complex ``q`` (gravity, elastic and joint springs: ``q' = 0``)."""
        kin = self.kinematics(q)
        n = self.n
        rhs = np.zeros(n, dtype=complex)
        for (R, _, Jv, _), seg in zip(kin["links"], [s for s in self.segments if isinstance(s, Link)]):
            rhs += Jv.T @ (seg.mass * self.gravity)
        _, J_p = kin["points"]
        rhs += np.einsum("p,pik,i->k", self.m, J_p, self.gravity)
        rhs[self.n_joints:] -= self.K @ q[self.n_joints:]
        if self.force is not None:
            rhs[self.n_joints:] += self.force(q[self.n_joints:], np.zeros(self.n_u))
        for k, (stiffness, _) in self.joint_springs.items():
            rhs[k] -= stiffness * q[k]
        return None, rhs, kin, None
