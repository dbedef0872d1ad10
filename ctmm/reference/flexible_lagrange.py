"""Independent assumed-modes Lagrange model of planar trees with modal beams (no transfer matrices).

Reads only plain parameters: the model's arrays (masses, inertias, body-frame vectors, parents,
joint kinds, hinge laws, loads, coordinate names) and each beam's ``length``,
``bending_stiffness``, ``mass_per_length``, ``n_modes``, ``n_axial_modes``, ``axial_stiffness``,
switches, stations, loads and modal-force hooks.  Shapes come from
:func:`ctmm.reference.beams.clamped_free_mode` (references may share with references); no code of
:mod:`ctmm.flexible` or of the TMM sweep is used.

Formulation (Kane / Lagrange in generalised speeds ``u = qdot``): every beam is lumped into
Gauss-Legendre mass points ``dm = rhoA w_k`` on its axis, each with the section's rotary inertia ``rho I w_k``
turning with ``theta + phi'(x_k) . q`` (``rotary_inertia_per_length``, 0: Euler-Bernoulli), rigid bodies into
their centre of mass plus rotary inertia.  For every point the position
Jacobian ``J_P`` and the bias acceleration ``a_P(u, udot = 0)`` follow from a forward recursion
over the tree (``r_P = r_frame + R(theta) [x + psi . p, phi . q]``, children attached at the
deformed end with angle ``theta + phi'(x_e) . q``).  Then

``sum_P dm J_P^T (J_P udot + a_P - g) + sum_rigid J Jw^T (Jw udot + alpha_bias) = Q``,

``Q`` = hinge torques, loads, ``-K eta - D eta_dot`` and the geometric stiffness
``-G(N) q``, ``G_ij = int N(x) phi_i' phi_j' dx`` with the axial force of the overall motion

``N(x) = rhoA (L - x) (g - a_I) . e1 + rhoA omega^2 (L^2 - x^2)/2 + q_x (L - x)
         + sum_{x_l > x} f_l . e1 - sum_{x_e > x} f_e . e1``

(``f_e`` = force the beam exerts on the subtree at end ``e`` = that subtree's momentum rate
minus its external forces).  ``a_I`` and ``f_e`` are affine in ``udot``, so the geometric term
adds non-symmetric rows to the mass matrix; without stiffening the model is Lagrange's
equations of the kinetic energy of the mass points (Kane, Ryan, Banerjee 1987 for the single
spinning beam: ``KG = rhoA int (L^2 - x^2)/2 phi' phi'``, FORMULAS 6.1).

Joint forces: the force and moment (about the body's inboard point) on each body from its
parent equal its subtree's momentum / angular-momentum rate minus the subtree's external loads.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.integrate

from .beams import beta_roots, clamped_free_mode

REVOLUTE, DRIVEN, FREE = 0, 1, 2


def _perp(r):
    return np.array([-r[1], r[0]])


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


class _Beam:
    """Shapes of one beam on its own Gauss points (96 points)."""

    def __init__(self, beam, points: int = 96) -> None:
        self.L = float(beam.length)
        self.rhoA = float(beam.mass_per_length)
        self.EI = float(beam.bending_stiffness)
        self.rhoI = float(getattr(beam, "rotary_inertia_per_length", 0.0))
        self.nq, self.np_ = int(beam.n_modes), int(beam.n_axial_modes)
        self.betas = beta_roots("clamped-free", self.nq)
        xg, wg = np.polynomial.legendre.leggauss(points)
        self.x = (xg + 1) / 2 * self.L
        self.w = wg / 2 * self.L
        self.phi = self.shape(self.x, 0)
        self.dphi = self.shape(self.x, 1)
        self.psi = self.axial(self.x, 0)
        M = self.rhoA * (self.phi * self.w) @ self.phi.T
        # EI phi'''' = (b/L)^4 EI phi  =>  K = (b/L)^4 EI / rhoA * M
        Kq = np.diag((self.betas / self.L) ** 4 * self.EI / self.rhoA) @ M
        Mp = self.rhoA * (self.psi * self.w) @ self.psi.T
        k = np.arange(1, self.np_ + 1)
        EA = float(beam.axial_stiffness or 0.0)
        Kp = np.diag(EA * ((2 * k - 1) * math.pi / (2 * self.L)) ** 2 / self.rhoA) @ Mp
        n = self.nq + self.np_
        self.K = np.zeros((n, n))
        self.K[:self.nq, :self.nq] = Kq
        self.K[self.nq:, self.nq:] = Kp
        Mm = np.zeros((n, n))
        Mm[:self.nq, :self.nq] = M + self.rhoI * (self.dphi * self.w) @ self.dphi.T
        Mm[self.nq:, self.nq:] = Mp
        omega = np.sqrt(np.diag(self.K) / np.diag(Mm))
        self.D = beam.stiffness_damping * self.K + 2 * beam.damping_ratio * np.diag(
            omega * np.diag(Mm))
        self.stiffening = bool(beam.geometric_stiffening)
        self.ends = {e: float(x) for e, x in beam.outboard.items()}
        self.loads = [(float(ld.point[0]), ld.force_x, ld.force_y, ld.moment) for ld in beam.loads]
        self.distributed = beam.distributed_load
        self.hooks = beam.modal_forces
        self._partials: dict = {}          # station xs [m] -> int_0^xs phi' phi'^T dx (:meth:`partial`)
        self._stations: dict = {}          # station xs [m] -> (phi, phi', psi) there (:meth:`station`)

    def partial(self, xs: float, q) -> np.ndarray:
        """``int_0^xs phi' (phi' . q) dx`` on its own Gauss points (96 on ``[0, xs]``): ``P(xs) q`` with the
        matrix ``P(xs) = int_0^xs phi' phi'^T dx`` built once per station ``xs`` (the stations are the beam's
        loads and ends, fixed)."""
        if xs <= 0.0:
            return np.zeros(self.nq)
        matrix = self._partials.get(xs)
        if matrix is None:
            xg, wg = np.polynomial.legendre.leggauss(96)
            d = self.shape((xg + 1) / 2 * xs, 1)
            matrix = self._partials[xs] = (d * (wg / 2 * xs)) @ d.T
        return matrix @ q

    def station(self, xs: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(phi, phi', psi)`` at the station ``xs`` [m] (a load or an end: fixed), each per mode, evaluated once."""
        values = self._stations.get(xs)
        if values is None:
            values = self._stations[xs] = (self.shape(xs, 0)[:, 0], self.shape(xs, 1)[:, 0], self.axial(xs, 0)[:, 0])
        return values

    def shape(self, x, d):
        xi = np.atleast_1d(np.asarray(x, float)) / self.L
        return np.array([clamped_free_mode(b, xi, d) for b in self.betas]) / self.L ** d

    def axial(self, x, d):
        x = np.atleast_1d(np.asarray(x, float))
        k = np.arange(1, self.np_ + 1)[:, None]
        a = (2 * k - 1) * math.pi / (2 * self.L)
        return math.sqrt(2) * (np.sin(a * x) if d == 0 else a * np.cos(a * x))


class FlexibleLagrange:
    """Global assumed-modes model of a :class:`~ctmm.planar.PlanarModel` with modal beams.

    Parameters
    ----------
    model : PlanarModel
        Chain or tree of rigid bodies and :class:`~ctmm.flexible.ModalBeam` bodies (revolute,
        driven / fixed-mounting joints, pinned / fixed / free bases).
    """

    def __init__(self, model) -> None:
        if getattr(model, "nonlinear_hinges", None):      # the linear law arrays would silently drop them
            raise ValueError("this Lagrange reference holds linear hinge laws only (nonlinear hinges given)")
        self.model = model
        self.nb = len(model.mass)
        self.n = len(model.coordinates)
        names = model.coordinates
        self.beams = {}
        self.eta_index = {}
        for j, body in enumerate(model.bodies):
            if hasattr(body, "bending_stiffness"):
                self.beams[j] = _Beam(body)
                bn = model.body_names[j]
                idx = [names.index(f"{bn}.q{i + 1}") for i in range(body.n_modes)]
                idx += [names.index(f"{bn}.u{k + 1}") for k in range(body.n_axial_modes)]
                self.eta_index[j] = np.array(idx, dtype=int)
        self.children = [[] for _ in range(self.nb)]
        for j in range(self.nb):
            if model.parent[j] >= 0:
                self.children[model.parent[j]].append(j)
        self.end_name = [None] * self.nb
        for j, joint_end in enumerate(model.parent_end):
            self.end_name[j] = joint_end

    # -- kinematics -------------------------------------------------------------------------
    def _frames(self, q, u, t):
        """Frame origin / angle with Jacobians and bias terms of every body."""
        m, n = self.model, self.n
        driven = {i: (a, r, c) for i, a, r, c in m.driven(t)}
        F = []
        for j in range(self.nb):
            p = m.parent[j]
            if p >= 0:
                pf = F[p]
                th_p, w_p, Jth_p, ab_p = pf["th"], pf["w"], pf["Jth"], pf["ab"]
                R = np.array([[math.cos(th_p), -math.sin(th_p)], [math.sin(th_p), math.cos(th_p)]])
                if p in self.beams:
                    bm = self.beams[p]
                    xe = bm.ends[self.end_name[j]]
                    eta, etad = q[self.eta_index[p]], u[self.eta_index[p]]
                    phi_e, dphi_e, psi_e = bm.station(xe)
                    rb = np.array([xe + psi_e @ eta[bm.nq:], phi_e @ eta[:bm.nq]])
                    rbd = np.array([psi_e @ etad[bm.nq:], phi_e @ etad[:bm.nq]])
                    dR = np.zeros((2, n))
                    dR[0, self.eta_index[p][bm.nq:]] = psi_e
                    dR[1, self.eta_index[p][:bm.nq]] = phi_e
                    slope = np.zeros(n)
                    slope[self.eta_index[p][:bm.nq]] = dphi_e
                else:
                    rb = np.asarray(m.ends[p][self.end_name[j]], float)
                    rbd = np.zeros(2)
                    dR = np.zeros((2, n))
                    slope = np.zeros(n)
                rho = R @ rb
                r = pf["r"] + rho
                Jr = pf["Jr"] + np.outer(_perp(rho), Jth_p) + R @ dR
                ar = pf["ar"] + ab_p * _perp(rho) - w_p ** 2 * rho + 2 * w_p * _perp(R @ rbd)
                th_e = th_p + slope @ q
                w_e = w_p + slope @ u
                Jth_e = Jth_p + slope
                ab_e = ab_p
            else:
                r = np.asarray(m.ground_position[j], float).copy()
                Jr = np.zeros((2, n))
                ar = np.zeros(2)
                th_e, w_e, Jth_e, ab_e = float(m.ground_angle[j]), 0.0, np.zeros(n), 0.0
                if m.joint_kind[j] == FREE:
                    ix, iy = m.xy_index[j]
                    r = np.array([q[ix], q[iy]])
                    Jr[0, ix] = Jr[1, iy] = 1.0
            if m.joint_kind[j] == DRIVEN:
                a, rr, cc = driven[j]
                th, w, Jth, ab = th_e + a, w_e + rr, Jth_e.copy(), ab_e + cc
            else:
                k = m.theta_index[j]
                th, w = q[k], u[k]
                Jth = np.zeros(n)
                Jth[k] = 1.0
                ab = 0.0
            F.append(dict(r=r, Jr=Jr, ar=ar, th=th, w=w, Jth=Jth, ab=ab, th_e=th_e, w_e=w_e,
                          Jth_e=Jth_e))
        return F

    def _points(self, q, u, t, frames):
        """Mass points of every body: list per body of (m, r, J, a_bias, extra)."""
        m = self.model
        pts = []
        for j in range(self.nb):
            f = frames[j]
            c, s = math.cos(f["th"]), math.sin(f["th"])
            R = np.array([[c, -s], [s, c]])
            if j in self.beams:
                bm = self.beams[j]
                eta, etad = q[self.eta_index[j]], u[self.eta_index[j]]
                qq, pp = eta[:bm.nq], eta[bm.nq:]
                rb = np.vstack([bm.x + pp @ bm.psi, qq @ bm.phi])          # (2, K)
                rbd = np.vstack([etad[bm.nq:] @ bm.psi, etad[:bm.nq] @ bm.phi])
                rho = R @ rb
                r = f["r"][:, None] + rho
                perp = np.vstack([-rho[1], rho[0]])
                J = (f["Jr"][None, :, :] + perp.T[:, :, None] * f["Jth"][None, None, :])
                J = J.copy()
                ie = self.eta_index[j]
                J[:, :, ie[:bm.nq]] += (R[:, 1][None, :, None] * bm.phi.T[:, None, :])
                if bm.np_:
                    J[:, :, ie[bm.nq:]] += (R[:, 0][None, :, None] * bm.psi.T[:, None, :])
                vel = R @ rbd
                a = (f["ar"][:, None] + f["ab"] * perp - f["w"] ** 2 * rho
                     + 2 * f["w"] * np.vstack([-vel[1], vel[0]]))
                pts.append(dict(m=bm.rhoA * bm.w, r=r.T, J=J, a=a.T, R=R))
            else:
                rc = R @ m.com[j]
                r = f["r"] + rc
                J = f["Jr"] + np.outer(_perp(rc), f["Jth"])
                a = f["ar"] + f["ab"] * _perp(rc) - f["w"] ** 2 * rc
                pts.append(dict(m=np.array([m.mass[j]]), r=r[None], J=J[None], a=a[None], R=R))
        return pts

    def _subtree(self, j):
        out = [j]
        for c in self.children[j]:
            out += self._subtree(c)
        return out

    # -- generalised forces -----------------------------------------------------------------
    def _external(self, q, u, t, frames, pts):
        """External generalised forces (without inertia) and per-body external wrenches."""
        m = self.model
        n = self.n
        g = np.asarray(m.gravity, float)
        Q = np.zeros(n)
        ext = []     # per body: (point forces (K, 2) of the distributed load or None, list of (point, force, moment))
        for j in range(self.nb):
            P = pts[j]
            Q += np.einsum("k,kin,i->n", P["m"], P["J"], g)
            items = []
            distributed = None
            f = frames[j]
            if j in self.beams:
                bm = self.beams[j]
                qx, qy = float(bm.distributed[0](t)), float(bm.distributed[1](t))
                fd = P["R"] @ np.array([qx, qy])
                Q += np.einsum("k,kin,i->n", bm.w, P["J"], fd)
                distributed = bm.w[:, None] * fd[None, :]           # w_k fd at the mass points P["r"]
                eta, etad = q[self.eta_index[j]], u[self.eta_index[j]]
                gen = -bm.K @ eta - bm.D @ etad
                for hook in bm.hooks:
                    if hook.force is not None:
                        gen = gen + np.asarray(hook.force(t), float)
                    if hook.stiffness is not None:
                        gen = gen - hook.stiffness @ eta
                    if hook.damping is not None:
                        gen = gen - hook.damping @ etad
                    if hook.law is not None:
                        gen = gen + np.asarray(hook.law(t, eta, etad), float)
                Q[self.eta_index[j]] += gen
                for (xl, fx, fy, mz) in bm.loads:
                    force = np.array([float(fx(t)), float(fy(t))])
                    moment = float(mz(t))
                    phi_l, dphi_l, psi_l = bm.station(xl)
                    rb = np.array([xl + psi_l @ eta[bm.nq:], phi_l @ eta[:bm.nq]])
                    rho = P["R"] @ rb
                    Jl = f["Jr"] + np.outer(_perp(rho), f["Jth"])
                    Jl[:, self.eta_index[j][:bm.nq]] += np.outer(P["R"][:, 1], phi_l)
                    Jl[:, self.eta_index[j][bm.nq:]] += np.outer(P["R"][:, 0], psi_l)
                    Jw = f["Jth"].copy()
                    Jw[self.eta_index[j][:bm.nq]] += dphi_l
                    Q += Jl.T @ force + Jw * moment
                    items.append((f["r"] + rho, force, moment))
            ext.append((distributed, items))
        loads = m.loads(t) if len(m.load_body) else np.zeros((0, 3))
        for k, body in enumerate(m.load_body):
            body = int(body)
            if body in self.beams:
                continue
            f = frames[body]
            R = pts[body]["R"]
            rho = R @ m.load_point[k]
            Jl = f["Jr"] + np.outer(_perp(rho), f["Jth"])
            Q += Jl.T @ loads[k, :2] + f["Jth"] * loads[k, 2]
            ext[body][1].append((f["r"] + rho, loads[k, :2].copy(), float(loads[k, 2])))
        # hinge torques: tau on the child, -tau on the parent end (relative to its end angle)
        reference, rate, torque = m.hinge_laws(t)
        for j in range(self.nb):
            if m.joint_kind[j] != REVOLUTE:
                continue
            f = frames[j]
            dth, dw = f["th"] - f["th_e"], f["w"] - f["w_e"]
            tau = torque[j] - m.stiffness[j] * (dth - reference[j]) - m.damping[j] * (dw - rate[j])
            Q += tau * (f["Jth"] - f["Jth_e"])
        return Q, ext

    def _system(self, q, u, t, stiffening: bool = True):
        """``A udot = b`` (non-symmetric with stiffening) and the pieces for joint forces
        (``stiffening=False``: the equations without the geometric stiffening of any beam)."""
        m = self.model
        n = self.n
        frames = self._frames(q, u, t)
        pts = self._points(q, u, t, frames)
        Q, ext = self._external(q, u, t, frames, pts)
        A = np.zeros((n, n))
        b = Q.copy()
        for j in range(self.nb):
            P = pts[j]
            A += np.einsum("k,kin,kim->nm", P["m"], P["J"], P["J"])
            b -= np.einsum("k,kin,ki->n", P["m"], P["J"], P["a"])
            if j not in self.beams:
                Jth = frames[j]["Jth"]
                A += m.inertia[j] * np.outer(Jth, Jth)
                b -= m.inertia[j] * Jth * frames[j]["ab"]
            elif self.beams[j].rhoI:
                inertia, turn = self._sections(j, frames)
                A += np.einsum("k,kn,km->nm", inertia, turn, turn)
                b -= frames[j]["ab"] * (inertia @ turn)
        g = np.asarray(m.gravity, float)
        # geometric stiffening: -G(N) q with N affine in udot
        for j, bm in self.beams.items():
            if not (bm.stiffening and stiffening):
                continue
            f = frames[j]
            e1 = np.array([math.cos(f["th"]), math.sin(f["th"])])
            qq = q[self.eta_index[j][:bm.nq]]
            x = bm.x
            # N(x_k) = N0_k + N1_k . udot
            N0 = bm.rhoA * (bm.L - x) * ((g - f["ar"]) @ e1) + bm.rhoA * f["w"] ** 2 * (
                bm.L ** 2 - x ** 2) / 2 + float(bm.distributed[0](t)) * (bm.L - x)
            N1 = -bm.rhoA * np.outer(bm.L - x, e1 @ f["Jr"])
            weight = bm.w * (bm.dphi.T @ qq)                       # w_k (phi'_k . q)
            rows = self.eta_index[j][:bm.nq]
            Gv = bm.dphi * weight                                  # (nq, K)
            b[rows] -= Gv @ N0
            A[rows] += Gv @ N1
            # point loads / ends at station s: N jumps there, integrate int_0^s exactly
            for (xl, fx, fy, _) in bm.loads:
                force = np.array([float(fx(t)), float(fy(t))])
                b[rows] -= (force @ e1) * bm.partial(xl, qq)
            for c in self.children[j]:
                xe = bm.ends[self.end_name[c]]
                f0, f1 = self._subtree_force(c, pts, ext)
                gq = bm.partial(xe, qq)
                b[rows] += (f0 @ e1) * gq
                A[rows] -= np.outer(gq, e1 @ f1)
        return A, b, frames, pts, ext

    def _sections(self, j, frames):
        """Rotary inertias ``rho I w_k`` [kg m^2] of beam ``j``'s sections and the Jacobians ``(K, n)`` of their
        angles ``theta + phi'(x_k) . q`` (their bias acceleration is the frame's)."""
        bm = self.beams[j]
        turn = np.tile(frames[j]["Jth"], (len(bm.x), 1))
        turn[:, self.eta_index[j][:bm.nq]] += bm.dphi.T
        return bm.rhoI * bm.w, turn

    def _subtree_force(self, c, pts, ext):
        """Force on the subtree of body ``c`` from its parent, affine in udot: ``f0 + f1 udot``."""
        f0 = np.zeros(2)
        f1 = np.zeros((2, self.n))
        g = np.asarray(self.model.gravity, float)
        for k in self._subtree(c):
            P = pts[k]
            f0 += np.einsum("k,ki->i", P["m"], P["a"]) - P["m"].sum() * g
            f1 += np.einsum("k,kin->in", P["m"], P["J"])
            distributed, items = ext[k]
            if distributed is not None and np.any(distributed):     # the load's point forces, in order
                for force in distributed:
                    f0 -= force
            for (_, force, _) in items:
                f0 -= force
        return f0, f1

    def _external_items(self, j, pts, ext) -> list:
        """Every external ``(point, force, moment)`` on body ``j``: the weights of its mass points, the point
        forces of a beam's distributed load, then its point loads."""
        P, g = pts[j], np.asarray(self.model.gravity, float)
        distributed, items = ext[j]
        out = [(P["r"][k], P["m"][k] * g, 0.0) for k in range(len(P["m"]))]
        if distributed is not None:
            out += [(P["r"][k], distributed[k], 0.0) for k in range(len(distributed))]
        return out + items

    # -- public -------------------------------------------------------------------------------
    def accelerations(self, q, qdot, t: float = 0.0) -> np.ndarray:
        """Generalised accelerations from the global equations (dense solve)."""
        q = np.asarray(q, float)
        u = np.asarray(qdot, float)
        A, b, *_ = self._system(q, u, t)
        return np.linalg.solve(A, b)

    def energy(self, q, qdot, t: float = 0.0) -> float:
        """Kinetic + gravitational + modal strain + hinge-spring energy [J] from the mass points.

        ``sum dm |J u|^2 / 2 + sum I (J_theta u)^2 / 2 - sum dm g . r + eta^T K eta / 2
        + sum k (dtheta - reference)^2 / 2``; models without driven joints (their rates are not
        in ``J u``).  Without stiffening and damping it is conserved; with stiffening it changes
        by the work of :meth:`stiffening_force`.
        """
        q = np.asarray(q, float)
        u = np.asarray(qdot, float)
        m = self.model
        if len(list(m.driven(t))):
            raise ValueError("energy: models with driven joints are not covered by this reference")
        frames = self._frames(q, u, t)
        pts = self._points(q, u, t, frames)
        g = np.asarray(m.gravity, float)
        energy = 0.0
        for j in range(self.nb):
            P = pts[j]
            v = np.einsum("kin,n->ki", P["J"], u)
            energy += 0.5 * np.sum(P["m"] * np.sum(v * v, axis=1)) - np.sum(P["m"] * (P["r"] @ g))
            if j in self.beams:
                eta = q[self.eta_index[j]]
                energy += 0.5 * eta @ self.beams[j].K @ eta
                inertia, turn = self._sections(j, frames)
                energy += 0.5 * inertia @ (turn @ u) ** 2
            else:
                energy += 0.5 * m.inertia[j] * (frames[j]["Jth"] @ u) ** 2
        reference, _, _ = m.hinge_laws(t)
        for j in range(self.nb):
            if m.joint_kind[j] == REVOLUTE:
                f = frames[j]
                energy += 0.5 * m.stiffness[j] * (f["th"] - f["th_e"] - reference[j]) ** 2
        return float(energy)

    def stiffening_force(self, q, qdot, t: float = 0.0) -> np.ndarray:
        """Generalised force ``-G(N) q`` [N, N m] of the geometric stiffening at the model's own
        accelerations (the residual of the equations without stiffening; zero without it)."""
        q = np.asarray(q, float)
        u = np.asarray(qdot, float)
        A, b, *_ = self._system(q, u, t)
        udot = np.linalg.solve(A, b)
        A0, b0, *_ = self._system(q, u, t, stiffening=False)
        return A0 @ udot - b0

    def joint_forces(self, q, qdot, t: float = 0.0) -> np.ndarray:
        """``(n_bodies, 3)``: force and moment (about the inboard point) on each body from its
        parent / ground, from the subtree momentum balance."""
        q = np.asarray(q, float)
        u = np.asarray(qdot, float)
        A, b, frames, pts, ext = self._system(q, u, t)
        ud = np.linalg.solve(A, b)
        m = self.model
        out = np.zeros((self.nb, 3))
        for j in range(self.nb):
            r0 = frames[j]["r"]
            f = np.zeros(2)
            tau = 0.0
            for k in self._subtree(j):
                P = pts[k]
                acc = np.einsum("kin,n->ki", P["J"], ud) + P["a"]
                force = P["m"][:, None] * acc
                f += force.sum(axis=0)
                tau += sum(_cross(P["r"][i] - r0, force[i]) for i in range(len(P["m"])))
                if k not in self.beams:
                    tau += m.inertia[k] * (frames[k]["Jth"] @ ud + frames[k]["ab"])
                else:
                    inertia, turn = self._sections(k, frames)
                    tau += inertia @ (turn @ ud + frames[k]["ab"])
                for (point, fe, me) in self._external_items(k, pts, ext):
                    f -= fe
                    tau -= _cross(point - r0, fe) + me
            out[j] = (f[0], f[1], tau)
        return out

    def simulate(self, q0, qdot0, t_final: float, *, t_eval=None, rtol: float = 1e-11,
                 atol: float = 1e-12, method: str = "DOP853"):
        """``solve_ivp`` of the global equations; returns the scipy solution (``y = [q, qdot]``)."""
        n = self.n

        def rhs(t, y):
            return np.concatenate([y[n:], self.accelerations(y[:n], y[n:], t)])

        y0 = np.concatenate([np.asarray(q0, float), np.asarray(qdot0, float)])
        return scipy.integrate.solve_ivp(rhs, (0.0, t_final), y0, method=method, rtol=rtol,
                                         atol=atol, t_eval=t_eval)


__all__ = ["FlexibleLagrange"]
