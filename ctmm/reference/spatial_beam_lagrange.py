"""Independent assumed-modes Lagrange model of a hub + spatial beam (+ tip body) (issue 15, item 5).

No transfer matrices and no code of :mod:`ctmm.spatial` or :mod:`ctmm.flexible`: plain parameters in,
the equations from the energy by casadi automatic differentiation.  Shapes from
:func:`ctmm.reference.beams.clamped_free_mode` (bending, both planes) and the rod shapes
``sqrt(2) sin((2k - 1) pi x / (2 L))`` (twist, axial), written here.

System: a rigid **hub** on a revolute (``axes = (a,)``) or universal (``axes = (a1, a2)``: ``R =
Rot(a1, q1) Rot(a2, q2)``) joint at the ground origin, with an optional spring / damper per angle; a
**beam** welded to the hub at ``mount`` (hub axes) with the rotation ``mount_rotation``; an optional
rigid **tip body** welded at the beam tip, its axes those of the tip section
``R_tip = R_beam Rz(w_y'(L)) Ry(-w_z'(L)) Rx(gamma(L))``.  Coordinates ``[hub angles ; q_y ; q_z ; r ; p]``.

Energy: the beam lumped into Gauss-Legendre mass points ``dm = rhoA w_k`` at
``r_k = r_I + R_b [x_k + psi . p, phi . q_y, phi . q_z]``, the twist's section inertia ``1/2 j_p w_k (omega_b1 +
chi . r_dot)^2`` and the bending sections' ``1/2 w_k (j_y (omega_b2 - phi' . q_z_dot)^2 + j_z (omega_b3 + phi' .
q_y_dot)^2)`` (``j_y = rotary_inertia_per_length_z``, turning with ``w_z``, ``j_z = rotary_inertia_per_length_y``;
0 by default: Euler-Bernoulli; frame angular velocity plus the section's small turning, the same order as the
twist's); hub and tip body
``1/2 m v_c^2 + 1/2 omega^T I omega`` with ``omega`` from ``[omega]x = R_dot R^T`` (AD of the rotation
matrices); ``V = 1/2 eta^T K eta - sum m g . r`` plus joint springs.  Lagrange's equations

``d/dt dT/du - dT/dq + dV/dq = -D eta_dot - G(N) eta - c u_hub``

with the geometric stiffness of the axial force of the overall motion (both bending planes)

``G(N) = (g_1 - a_1) rhoA G2 + rhoA (omega_2^2 + omega_3^2) G3 - f_1 G1(L) + q_1 G2`` (``int N w' w'^T`` in each
bending plane: ``int N (w_y' delta w_y' + w_z' delta w_z')``, no coupling of the planes),

``a_1``, ``g_1``, ``f_1``, ``q_1`` the beam-axis components of the root acceleration, gravity, the force of
the beam on the tip body (``m_tip (a_c - g)``, ``G1`` to its station, affine in ``u_dot``) and of the uniform
follower load ``distributed_load = (q_1, q_2, q_3)`` [N/m] in the beam frame (its generalised force: its virtual
power at the mass points) -- the consistent first-order geometric stiffness (Kane, Ryan, Banerjee 1987 for the spinning beam).

**Second-order inertia** (``second_order_inertia=True``, axially rigid beams only): every mass point also moves
along the axis by its foreshortening ``u(x) = -1/2 int_0^x (w_y'^2 + w_z'^2)`` (inner Gauss-Legendre rule on
``[0, x]``), in ``T`` and ``V`` exactly, and so do the tip body (at ``[x_t + u(x_t), w_y(x_t), w_z(x_t)]``) and the
points of the body-axis force actuators; every axial force then comes out of Lagrange's equations (virtual power
at the moved points) and ``G(N)`` is dropped.

``tip_station``: the abscissa ``x_t`` where the tip body is welded (default ``L``; a child at a station).

Two-link arms (the 3-D flexible manipulator): with two axes and ``shoulder`` the hub's origin is
``Rot(a1, q1) shoulder`` (the second axis passes through it), and an optional rigid **base** body
(``base_mass``, ``base_inertia``, ``base_center``) turns with ``Rot(a1, q1)`` only.

**Body-axis actuators** (``actuators``: ``(x, "force" | "moment", axis)``): a force ``F e_axis`` or a
moment ``M e_axis`` given in the beam frame's axes ``R_b`` (turning with the floating frame), applied at
the deformed axis point ``r(x)`` (force) or on the section at ``x`` (moment).  Their generalised forces
come from virtual power alone: ``Q = (dv(x)/du)^T R_b e_axis F`` with ``v(x)`` the velocity of the mass
point (AD of ``r``), and ``Q = (domega_s(x)/du)^T R_b e_axis M`` with ``omega_s`` the angular velocity of the
section frame ``R_s(x) = R_b Rz(w_y'(x)) Ry(-w_z'(x)) Rx(gamma(x))`` (the tip body's convention; AD of
``R_s``, ``[omega_s]x = R_s_dot R_s^T``).  A force's beam-axis component ``F_1`` tensions ``0 < x' < x``:
``- F_1 G1(x)`` in ``G(N)`` (``G1(x) = int_0^x w' w'^T``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import casadi as ca
import numpy as np
import scipy.linalg

from .beams import beta_roots, clamped_free_mode

__all__ = ["HubBeam", "SpatialBeamLagrange"]


@dataclass(frozen=True)
class HubBeam:
    """Plain parameters of the hub + beam + tip body (SI units; see the module docstring)."""

    length: float
    mass_per_length: float
    bending_stiffness_y: float
    bending_stiffness_z: float
    n_modes_y: int
    n_modes_z: int
    hub_mass: float = 1.0
    hub_inertia: Sequence = ((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1))
    hub_center: Sequence[float] = (0.0, 0.0, 0.0)
    axes: Sequence[Sequence[float]] = ((0.0, 0.0, 1.0),)
    joint_stiffness: Sequence[float] = ()
    joint_damping: Sequence[float] = ()
    mount: Sequence[float] = (0.0, 0.0, 0.0)
    mount_rotation: Sequence = ((1, 0, 0), (0, 1, 0), (0, 0, 1))
    n_torsion_modes: int = 0
    torsional_stiffness: float = 0.0
    polar_inertia_per_length: float = 0.0
    n_axial_modes: int = 0
    axial_stiffness: float = 0.0
    geometric_stiffening: bool = True
    damping_ratio: float = 0.0
    stiffness_damping: float = 0.0
    tip_mass: float = 0.0
    tip_inertia: Sequence = ((0, 0, 0), (0, 0, 0), (0, 0, 0))
    tip_center: Sequence[float] = (0.0, 0.0, 0.0)
    gravity: Sequence[float] = (0.0, 0.0, -9.81)
    points: int = 64
    shoulder: Sequence[float] = (0.0, 0.0, 0.0)
    base_mass: float = 0.0
    base_inertia: Sequence = ((0, 0, 0), (0, 0, 0), (0, 0, 0))
    base_center: Sequence[float] = (0.0, 0.0, 0.0)
    actuators: Sequence[tuple] = ()
    second_order_inertia: bool = False
    tip_station: float | None = None
    distributed_load: Sequence[float] = (0.0, 0.0, 0.0)
    rotary_inertia_per_length_y: float = 0.0
    rotary_inertia_per_length_z: float = 0.0


def _rot(axis: np.ndarray, angle) -> ca.SX:
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = ca.DM([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return ca.DM.eye(3) + K * ca.sin(angle) + ca.mtimes(K, K) * (1 - ca.cos(angle))


def _vee_rate(R: ca.SX, q: ca.SX, u: ca.SX) -> ca.SX:
    """World angular velocity of ``R(q)``: ``[omega]x = R_dot R^T``."""
    Rdot = ca.reshape(ca.mtimes(ca.jacobian(ca.reshape(R, 9, 1), q), u), 3, 3)
    W = ca.mtimes(Rdot, R.T)
    return ca.vertcat(W[2, 1], W[0, 2], W[1, 0])


def _rod(x: np.ndarray, length: float, count: int, derivative: int = 0) -> np.ndarray:
    k = np.arange(1, count + 1)[:, None]
    a = (2 * k - 1) * math.pi / (2 * length)
    return math.sqrt(2) * (np.sin(a * x[None]) if derivative == 0 else a * np.cos(a * x[None]))


class SpatialBeamLagrange:
    """Forward dynamics ``u_dot = f(q, u)`` of a :class:`HubBeam` (casadi function, numeric calls).

    Parameters
    ----------
    p : HubBeam
    """

    def __init__(self, p: HubBeam) -> None:
        self.p = p
        L, rhoA = float(p.length), float(p.mass_per_length)
        ny, nz, nt, na = p.n_modes_y, p.n_modes_z, p.n_torsion_modes, p.n_axial_modes
        nh = len(p.axes)
        ne = ny + nz + nt + na
        self.n_hub, self.n_eta = nh, ne
        n = nh + ne
        q, u, ud = ca.SX.sym("q", n), ca.SX.sym("u", n), ca.SX.sym("ud", n)
        qy, qz = q[nh:nh + ny], q[nh + ny:nh + ny + nz]
        tw, ax = q[nh + ny + nz:nh + ny + nz + nt], q[nh + ny + nz + nt:]
        eta_dot = u[nh:]
        betas_y = beta_roots("clamped-free", ny) if ny else np.zeros(0)
        betas_z = beta_roots("clamped-free", nz) if nz else np.zeros(0)

        def bend(betas, x, d):
            if not len(betas):                         # a plane without modes (planar motion)
                return np.zeros((0, np.asarray(x).size))
            return (np.array([clamped_free_mode(b, np.asarray(x) / L, d) for b in betas]).reshape(len(betas), -1)
                    / L ** d)

        xg, wg = np.polynomial.legendre.leggauss(p.points)
        x, w = (xg + 1) / 2 * L, wg / 2 * L
        shortening = [0.0] * p.points

        def shortening_at(x_k: float):
            """u(x_k) = -1/2 int_0^x_k (w_y'^2 + w_z'^2), Gauss-Legendre on [0, x_k] (0 without the option)."""
            if not p.second_order_inertia:
                return 0.0
            s_in, s_w = (xg + 1) / 2 * x_k, wg / 2 * x_k
            slope2 = 0
            for betas, coordinates in ((betas_y, qy), (betas_z, qz)):
                if len(betas):
                    slopes = ca.mtimes(ca.DM(bend(betas, s_in, 1).T), coordinates)     # (points, 1)
                    slope2 = slope2 + ca.dot(ca.DM(s_w), slopes * slopes)
            return -0.5 * slope2

        if p.second_order_inertia and na:
            raise ValueError("second_order_inertia needs an axially rigid beam (n_axial_modes = 0)")
        shortening = [shortening_at(x[k]) for k in range(p.points)]
        # hub rotation and beam frame
        R_h = ca.DM.eye(3)
        for i, axis in enumerate(p.axes):
            R_h = ca.mtimes(R_h, _rot(axis, q[i]))
        R_1 = _rot(p.axes[0], q[0])                                  # the first link (base) turns with q1 only
        o_h = ca.mtimes(R_1, ca.DM(np.asarray(p.shoulder, float)))   # the hub's origin (on the second axis)
        R_b = ca.mtimes(R_h, ca.DM(np.asarray(p.mount_rotation, float)))
        r_I = o_h + ca.mtimes(R_h, ca.DM(np.asarray(p.mount, float)))
        g = ca.DM(np.asarray(p.gravity, float))
        T, V = 0, 0
        if p.base_mass > 0:
            c_1 = ca.mtimes(R_1, ca.DM(np.asarray(p.base_center, float)))
            v_1 = ca.mtimes(ca.jacobian(c_1, q), u)
            w_1 = _vee_rate(R_1, q, u)
            I_1 = ca.mtimes(ca.mtimes(R_1, ca.DM(np.asarray(p.base_inertia, float))), R_1.T)
            T += 0.5 * p.base_mass * ca.dot(v_1, v_1) + 0.5 * ca.mtimes(ca.mtimes(w_1.T, I_1), w_1)
            V -= p.base_mass * ca.dot(g, c_1)
        # hub
        c_h = o_h + ca.mtimes(R_h, ca.DM(np.asarray(p.hub_center, float)))
        v_h = ca.mtimes(ca.jacobian(c_h, q), u)
        w_h = _vee_rate(R_h, q, u)
        I_h = ca.mtimes(ca.mtimes(R_h, ca.DM(np.asarray(p.hub_inertia, float))), R_h.T)
        T += 0.5 * p.hub_mass * ca.dot(v_h, v_h) + 0.5 * ca.mtimes(ca.mtimes(w_h.T, I_h), w_h)
        V -= p.hub_mass * ca.dot(g, c_h)
        # beam mass points
        phi_y, phi_z = bend(betas_y, x, 0), bend(betas_z, x, 0)
        psi, chi = _rod(x, L, na), _rod(x, L, nt)
        w_b = ca.mtimes(R_b.T, _vee_rate(R_b, q, u))              # frame angular velocity, frame axes
        follower = ca.mtimes(R_b, ca.DM(np.asarray(p.distributed_load, float)))     # [N/m], world axes
        load_force = ca.SX.zeros(n)
        for k in range(p.points):
            rho = ca.vertcat(x[k] + shortening[k] + (ca.dot(ca.DM(psi[:, k]), ax) if na else 0),
                             ca.dot(ca.DM(phi_y[:, k]), qy) if ny else 0,
                             ca.dot(ca.DM(phi_z[:, k]), qz) if nz else 0)
            r = r_I + ca.mtimes(R_b, rho)
            v = ca.mtimes(ca.jacobian(r, q), u)
            T += 0.5 * rhoA * w[k] * ca.dot(v, v)
            if any(p.distributed_load):                # virtual power of the follower load at the mass point
                load_force += w[k] * ca.mtimes(ca.jacobian(r, q).T, follower)
            V -= rhoA * w[k] * ca.dot(g, r)
            if nt:
                spin = w_b[0] + ca.dot(ca.DM(chi[:, k]), u[nh + ny + nz:nh + ny + nz + nt])
                T += 0.5 * p.polar_inertia_per_length * w[k] * spin * spin
            if ny and p.rotary_inertia_per_length_y:        # the section turning with w_y' about the frame's z
                turn = w_b[2] + ca.dot(ca.DM(bend(betas_y, x, 1)[:, k]), u[nh:nh + ny])
                T += 0.5 * p.rotary_inertia_per_length_y * w[k] * turn * turn
            if nz and p.rotary_inertia_per_length_z:        # with -w_z' about the frame's y
                turn = w_b[1] - ca.dot(ca.DM(bend(betas_z, x, 1)[:, k]), u[nh + ny:nh + ny + nz])
                T += 0.5 * p.rotary_inertia_per_length_z * w[k] * turn * turn
        # stiffness and damping
        K = np.zeros((ne, ne))
        K[:ny, :ny] = np.diag(p.bending_stiffness_y * betas_y ** 4 / L ** 3)
        K[ny:ny + nz, ny:ny + nz] = np.diag(p.bending_stiffness_z * betas_z ** 4 / L ** 3)
        dchi, dpsi = _rod(x, L, nt, 1), _rod(x, L, na, 1)
        K[ny + nz:ny + nz + nt, ny + nz:ny + nz + nt] = p.torsional_stiffness * (dchi * w) @ dchi.T
        K[ny + nz + nt:, ny + nz + nt:] = p.axial_stiffness * (dpsi * w) @ dpsi.T
        Mm = np.concatenate([np.full(ny + nz, rhoA * L), np.full(nt, p.polar_inertia_per_length * L),
                             np.full(na, rhoA * L)])
        D = p.stiffness_damping * K + 2 * p.damping_ratio * np.diag(np.sqrt(np.diag(K) * Mm))
        self.K = K
        eta = q[nh:]
        V += 0.5 * ca.mtimes(ca.mtimes(eta.T, ca.DM(K)), eta)
        for i, k_joint in enumerate(p.joint_stiffness):
            V += 0.5 * k_joint * q[i] ** 2
        # tip body
        tip = {}
        if p.tip_mass > 0:
            x_tip = np.array([L if p.tip_station is None else float(p.tip_station)])
            rho_L = ca.vertcat(x_tip[0] + shortening_at(x_tip[0])
                               + (ca.dot(ca.DM(_rod(x_tip, L, na)[:, 0]), ax) if na else 0),
                               ca.dot(ca.DM(bend(betas_y, x_tip, 0)[:, 0]), qy) if ny else 0,
                               ca.dot(ca.DM(bend(betas_z, x_tip, 0)[:, 0]), qz) if nz else 0)
            twist = ca.dot(ca.DM(_rod(x_tip, L, nt)[:, 0]), tw) if nt else 0
            slope_y = ca.dot(ca.DM(bend(betas_y, x_tip, 1)[:, 0]), qy) if ny else 0
            slope_z = ca.dot(ca.DM(bend(betas_z, x_tip, 1)[:, 0]), qz) if nz else 0
            R_t = ca.mtimes(R_b, ca.mtimes(_rot([0, 0, 1], slope_y), ca.mtimes(_rot([0, 1, 0], -slope_z),
                                                                               _rot([1, 0, 0], twist))))
            c_t = r_I + ca.mtimes(R_b, rho_L) + ca.mtimes(R_t, ca.DM(np.asarray(p.tip_center, float)))
            v_t = ca.mtimes(ca.jacobian(c_t, q), u)
            w_t = _vee_rate(R_t, q, u)
            I_t = ca.mtimes(ca.mtimes(R_t, ca.DM(np.asarray(p.tip_inertia, float))), R_t.T)
            T += 0.5 * p.tip_mass * ca.dot(v_t, v_t) + 0.5 * ca.mtimes(ca.mtimes(w_t.T, I_t), w_t)
            V -= p.tip_mass * ca.dot(g, c_t)
            tip = {"center": c_t, "velocity": v_t}
        # Lagrange residual
        dT_du = ca.gradient(T, u)
        inertia = ca.jacobian(dT_du, u)                               # d2T/du2: the residual's ud part is inertia ud
        residual = ca.mtimes(ca.jacobian(dT_du, q), u) - ca.gradient(T, q) + ca.gradient(V, q)   # the rest
        tau = ca.SX.sym("tau", n)                                     # applied generalised forces
        generalized = ca.SX(tau)
        for i, c_joint in enumerate(p.joint_damping):
            generalized[i] -= c_joint * u[i]
        generalized[nh:] -= ca.mtimes(ca.DM(D), eta_dot)
        generalized += load_force
        x_tip_station = L if p.tip_station is None else float(p.tip_station)
        if p.geometric_stiffening and (ny or nz):
            a_I = ca.mtimes(ca.jacobian(ca.mtimes(ca.jacobian(r_I, q), u), q), u) + ca.mtimes(ca.jacobian(r_I, q), ud)
            frame_a = ca.mtimes(R_b.T, a_I)
            frame_g = ca.mtimes(R_b.T, g)
            f_tip = ca.SX.zeros(3)
            if tip:
                a_c = ca.mtimes(ca.jacobian(tip["velocity"], q), u) + ca.mtimes(ca.jacobian(tip["velocity"], u), ud)
                f_tip = p.tip_mass * (a_c - g)
            frame_f = ca.mtimes(R_b.T, f_tip)
            blocks = [bend(betas_y, x, 1), bend(betas_z, x, 1)]     # int N (w_y' dw_y' + w_z' dw_z'): per plane

            def gram(weights):
                return scipy.linalg.block_diag(*[(s * weights) @ s.T for s in blocks])

            x_in = (xg + 1) / 2 * x_tip_station
            G1 = scipy.linalg.block_diag(*[(s_ * (wg / 2 * x_tip_station)) @ s_.T
                                           for s_ in (bend(betas_y, x_in, 1), bend(betas_z, x_in, 1))])
            G2, G3 = gram(w * (L - x)), gram(w * (L * L - x * x) / 2)
            G = (ca.DM(G2) * (rhoA * (frame_g[0] - frame_a[0])) + ca.DM(G3) * (rhoA * (w_b[1] ** 2 + w_b[2] ** 2))
                 - ca.DM(G1) * frame_f[0] + ca.DM(G2) * float(p.distributed_load[0]))
            if not p.second_order_inertia:             # with it every axial force (beam's and tip's) is in T and V
                generalized[nh:nh + ny + nz] -= ca.mtimes(G, q[nh:nh + ny + nz])
        # body-axis actuators: generalised forces by virtual power (module docstring)
        act = ca.SX.sym("act", len(p.actuators))
        for k, (x_a, kind, axis) in enumerate(p.actuators):
            x_a = np.array([float(x_a)])
            direction = ca.mtimes(R_b, ca.DM(np.eye(3)[int(axis)]))
            if kind == "force":
                rho_a = ca.vertcat(x_a[0] + shortening_at(x_a[0])
                                   + (ca.dot(ca.DM(_rod(x_a, L, na)[:, 0]), ax) if na else 0),
                                   ca.dot(ca.DM(bend(betas_y, x_a, 0)[:, 0]), qy) if ny else 0,
                                   ca.dot(ca.DM(bend(betas_z, x_a, 0)[:, 0]), qz) if nz else 0)
                jac = ca.jacobian(ca.mtimes(ca.jacobian(r_I + ca.mtimes(R_b, rho_a), q), u), u)
                if p.geometric_stiffening and (ny or nz) and int(axis) == 0 and not p.second_order_inertia:
                    x_in, w_in = (xg + 1) / 2 * x_a[0], wg / 2 * x_a[0]       # Gauss points on [0, x]
                    blocks_a = [bend(betas_y, x_in, 1), bend(betas_z, x_in, 1)]
                    G1_a = scipy.linalg.block_diag(*[(s_ * w_in) @ s_.T for s_ in blocks_a])
                    generalized[nh:nh + ny + nz] -= ca.mtimes(ca.DM(G1_a), q[nh:nh + ny + nz]) * act[k]
            else:
                twist_a = ca.dot(ca.DM(_rod(x_a, L, nt)[:, 0]), tw) if nt else 0
                slope_ya = ca.dot(ca.DM(bend(betas_y, x_a, 1)[:, 0]), qy) if ny else 0
                slope_za = ca.dot(ca.DM(bend(betas_z, x_a, 1)[:, 0]), qz) if nz else 0
                R_s = ca.mtimes(R_b, ca.mtimes(_rot([0, 0, 1], slope_ya), ca.mtimes(_rot([0, 1, 0], -slope_za),
                                                                                    _rot([1, 0, 0], twist_a))))
                jac = ca.jacobian(_vee_rate(R_s, q, u), u)
            generalized += ca.mtimes(jac.T, direction) * act[k]
        # d/dt dT/du - dT/dq + dV/dq - Q = M ud - rhs (affine in ud: Q through the geometric stiffness's N)
        M = inertia - ca.jacobian(generalized, ud)
        rhs = -(residual - ca.substitute(generalized, ud, ca.SX.zeros(n)))
        rates = ca.solve(M, rhs)
        self._rates = ca.Function("rates", [q, u, tau, act], [rates])
        self._symbols = (q, u, tau, act, rates, M, rhs, T + V)
        self._functions: dict[str, ca.Function] = {}
        self.n = n

    def _function(self, name: str) -> ca.Function:
        """The casadi function ``linear``, ``mass_bias`` or ``energy`` of the equations, built on first use (the
        tangent of the symbolic solve is most of the model's construction time)."""
        if name not in self._functions:
            q, u, tau, act, rates, M, rhs, energy = self._symbols
            if name == "linear":
                outputs = [ca.jacobian(rates, ca.vertcat(q, u)), ca.jacobian(rates, tau), ca.jacobian(rates, act)]
                self._functions[name] = ca.Function(name, [q, u, tau, act], outputs)
            elif name == "mass_bias":
                bias = ca.substitute(ca.substitute(rhs, tau, ca.SX.zeros(self.n)), act, ca.SX.zeros(act.numel()))
                self._functions[name] = ca.Function(name, [q, u], [M, bias])
            else:
                self._functions[name] = ca.Function(name, [q, u], [energy])
        return self._functions[name]

    def accelerations(self, q: np.ndarray, u: np.ndarray, force: np.ndarray | None = None,
                      actuation: np.ndarray | None = None) -> np.ndarray:
        """``u_dot`` at ``(q, u)`` with applied generalised forces ``force`` (``(n,)``, along ``u``: hub
        torques [N m] first; default none) and the values of the body-axis ``actuators`` (``(k,)`` [N, N m])."""
        return np.asarray(self._rates(q, u, np.zeros(self.n) if force is None else force,
                                      np.zeros(len(self.p.actuators)) if actuation is None else actuation)).ravel()

    def linearize(self, q: np.ndarray, u: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(A, B_force, B_actuators)`` of ``d/dt [q ; u] = A [q ; u] + B_force force + B_actuators act``
        about ``(q, u)`` with no applied forces (``A``: ``[[0, I], [du_dot/dq, du_dot/du]]``)."""
        n, k = self.n, len(self.p.actuators)
        u = np.zeros(n) if u is None else u
        J, Bf, Ba = (np.asarray(x) for x in self._function("linear")(q, u, np.zeros(n), np.zeros(k)))
        A = np.zeros((2 * n, 2 * n))
        A[:n, n:] = np.eye(n)
        A[n:] = J
        top = np.zeros((n, n))
        return A, np.vstack([top, Bf]), np.vstack([np.zeros((n, k)), Ba])

    def deflection_rows(self, x: float) -> np.ndarray:
        """``(3, n)``: the axis point's displacement ``[psi . p, w_y, w_z](x) = rows @ q`` in the beam frame."""
        p, L = self.p, float(self.p.length)
        ny, nz, nt = p.n_modes_y, p.n_modes_z, p.n_torsion_modes
        nh, out = self.n_hub, np.zeros((3, self.n))
        if ny:
            out[1, nh:nh + ny] = [clamped_free_mode(b, x / L) for b in beta_roots("clamped-free", ny)]
        if nz:
            out[2, nh + ny:nh + ny + nz] = [clamped_free_mode(b, x / L) for b in beta_roots("clamped-free", nz)]
        if p.n_axial_modes:
            out[0, nh + ny + nz + nt:] = _rod(np.array([float(x)]), L, p.n_axial_modes)[:, 0]
        return out

    def section_rows(self, x: float) -> np.ndarray:
        """``(3, n)``: the section rotation ``[gamma, -w_z', w_y'](x) = rows @ q`` (modal part; its rates
        ``rows @ u``), from this model's own shapes."""
        p, L = self.p, float(self.p.length)
        ny, nz, nt = p.n_modes_y, p.n_modes_z, p.n_torsion_modes
        out = np.zeros((3, self.n))
        nh = self.n_hub
        xa = np.array([float(x)])
        if ny:
            out[2, nh:nh + ny] = [clamped_free_mode(b, x / L, 1) / L for b in beta_roots("clamped-free", ny)]
        if nz:
            out[1, nh + ny:nh + ny + nz] = [-clamped_free_mode(b, x / L, 1) / L for b in beta_roots("clamped-free", nz)]
        if nt:
            out[0, nh + ny + nz:nh + ny + nz + nt] = _rod(xa, L, nt)[:, 0]
        return out

    def energy(self, q: np.ndarray, u: np.ndarray) -> float:
        """``T + V`` [J] (joint springs and the elastic energy included; no geometric stiffness)."""
        return float(self._function("energy")(q, u))

    def rk4(self, q0: np.ndarray, u0: np.ndarray, dt: float, steps: int, force=None) -> np.ndarray:
        """Classical RK4 on ``[q ; u]``: states ``(steps + 1, 2 n)``; ``force`` an optional constant
        generalised force (``(n,)``, see :meth:`accelerations`) over the run."""
        n = self.n

        def f(state):
            return np.concatenate([state[n:], self.accelerations(state[:n], state[n:], force)])

        return _rk4(lambda _t, state: f(state), np.concatenate([q0, u0]).astype(float), dt, steps)

    def mass_and_bias(self, q: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(M, rhs)`` of ``M u_dot = rhs`` at ``(q, u)`` without applied forces."""
        M, rhs = self._function("mass_bias")(q, u)
        return np.asarray(M), np.asarray(rhs).ravel()

    def driven_rk4(self, hub, eta0: np.ndarray, eta_dot0: np.ndarray, dt: float, steps: int) -> np.ndarray:
        """Classical RK4 of the modal coordinates with the hub angles prescribed (one hub axis).

        ``hub(t)`` returns ``(angle [rad], rate [rad/s], acceleration [rad/s^2])``; the modal
        accelerations solve the modal rows of ``M u_dot = rhs`` with the hub acceleration given (its
        row is the driving torque).  States ``[eta ; eta_dot]``, ``(steps + 1, 2 n_eta)``.
        """
        nh, ne = self.n_hub, self.n_eta
        if nh != 1:
            raise ValueError("driven_rk4 prescribes one hub angle (axes = (a,))")

        def f(t, state):
            angle, rate, acceleration = hub(t)
            q = np.concatenate([[angle], state[:ne]])
            u = np.concatenate([[rate], state[ne:]])
            M, rhs = self.mass_and_bias(q, u)
            eta_ddot = np.linalg.solve(M[nh:, nh:], rhs[nh:] - M[nh:, :nh] @ np.array([acceleration]))
            return np.concatenate([state[ne:], eta_ddot])

        return _rk4(f, np.concatenate([eta0, eta_dot0]).astype(float), dt, steps)


def _rk4(f, state: np.ndarray, dt: float, steps: int) -> np.ndarray:
    """Classical RK4 of ``y' = f(t, y)`` from ``t = 0``: states ``(steps + 1, len(state))``."""
    out = [state.copy()]
    for k in range(steps):
        t = k * dt
        k1 = f(t, state)
        k2 = f(t + dt / 2, state + dt / 2 * k1)
        k3 = f(t + dt / 2, state + dt / 2 * k2)
        k4 = f(t + dt, state + dt * k3)
        state = state + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(state.copy())
    return np.array(out)
