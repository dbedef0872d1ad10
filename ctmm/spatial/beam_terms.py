"""Protocol terms (``d = 6``, ``n`` modal coordinates) of the modal spatial beam, in :mod:`ctmm.ops`.

Notation of :mod:`ctmm.spatial.beam_modes`.  Frame axes (subscript-free below): ``a``, ``alpha`` the
acceleration of the root ``I`` and the frame's angular acceleration, ``omega`` its angular velocity,
``g`` gravity, ``q`` the distributed follower load [N/m].  A mass point of the axis has
``rho = rho0 + Phi eta`` (``rho0 = [x, 0, 0]``) and the acceleration

``a_P = a + alpha x rho + omega x (omega x rho) + 2 omega x Phi eta_dot + Phi eta''``.

**Newton-Euler about I** (integrals of ``rhoA dx``; derivation in ``docs/spatial_modal_beam.md``)::

    F_I = m a - [s]x alpha + B eta'' + omega x (omega x s) + 2 omega x B eta_dot - m g - L q + sum_e f_e
    M_I = [s]x a + J alpha + (Gamma + e1 b_t^T + b_r) eta'' + omega x (J omega)
          + omega x (e1 b_t^T + b_r) eta_dot
          + 2 (omega tr P - P^T omega) - s x g - s/rhoA x q + sum_e (rho_e x f_e + m_e)

with ``s = int rho`` (``= s0 + B eta``), ``J = tr(S) I - S + L J_s`` (``S = int rho rho^T``, ``J_s =
diag(j_p, rho I_y', rho I_z')`` the sections' inertia per length), ``Gamma = int [rho]x Phi``, ``P = int rho (Phi
eta_dot)^T``, the twist's section inertia ``j_p (omega_1 + chi . eta_dot)`` about the axis and the bending
sections' ``b_r`` (:mod:`ctmm.spatial.beam_modes`; zero without rotary inertia).  **Modal equations**
(virtual work, ``delta rho = Phi delta eta``, ``delta theta = Theta Lambda delta eta`` at the points)::

    0 = B^T a + (Gamma^T + b_t e1^T + b_r^T) alpha + M_mod eta''
        + int Phi^T (omega x (omega x rho) + 2 omega x Phi eta_dot)
        - B^T g - B^T q / rhoA + K eta + D eta_dot - Q_hooks(t)
        + sum_e ((Phi_e)^T f_e + (Theta Lambda_e)^T m_e) + G(N) eta

with the geometric stiffness ``G(N) = int N w' w'^T`` of the axial force of the overall motion,
``N(x) = rhoA (L - x)(g_1 - a_1) + rhoA (omega_2^2 + omega_3^2)(L^2 - x^2)/2 + q_1 (L - x)
+ sum_(x_l > x) f_l1 - sum_(x_e > x) f_e1`` (``- rhoA G2 eta`` in the ``a_1`` column of the mass
matrix; ``-G1(x_e) eta`` in the axial column of the point's force map).  The rotation of the frame of
a point is ``E(theta) = Rz(theta_z) Ry(theta_y) Rx(theta_x)`` with ``theta = Lambda eta``; its relative
angular velocity ``Theta(theta) theta_dot``, ``Theta = [Rz Ry e1, Rz e2, e3]``.  Points::

    A_e = [[I, -[rho_e]x, Phi_e], [0, I, Theta Lambda_e]] x + c_e,    RF_e = Kin_e^T (+ stiffening)
    c_e = [omega x (omega x rho_e) + 2 omega x Phi_e eta_dot ;
           omega x Theta Lambda_e eta_dot + Theta_dot theta_dot]

With ``second_order_inertia`` a point moves with the shortening, ``rho_e = rho0_e + Phi_e eta + e1 u_e``,
``u_e = -1/2 eta^T G1(x_e) eta``: ``rho_e' = Phi_u eta_dot``, ``rho_e'' = Phi_u eta'' - e1 eta_dot^T G1 eta_dot`` with
``Phi_u = Phi_e - e1 (G1 eta)^T``, so ``Phi_u`` replaces ``Phi_e`` in ``Kin_e``, ``c_e`` gains
``- e1 eta_dot^T G1 eta_dot`` (and ``rho_e``, ``rho_e'`` the shortening), and ``RF_e = Kin_e^T`` exactly (the
axial force's ``-G1(x_e) eta f_1`` is its ``Phi_u^T`` part; no separate stiffening).  Point loads act at the
shortened point; their modal force ``Phi_u^T f`` is the stiffened ``Phi_e^T f - G1 eta f_1``.

All in frame axes, then turned to world axes with ``T = diag(R, R, I_n)``.  Restricted to the ``x-y``
plane (``omega = omega_3 e3``, no ``z`` or twist modes) every term is the planar
:class:`~ctmm.flexible.beam.ModalBeam`'s.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ..ops import NUMPY, Ops, batch_shape
from ..protocol import BodyTerms
from .beam_second_order import second_order_deltas
from .frames import axis_rotation, block_diagonal, column, constant, cross, entry, skew

__all__ = ["PointFrame", "spatial_beam_terms", "beam_energy", "beam_load_vector"]

_E = np.eye(3)


@dataclass(frozen=True)
class PointFrame:
    """Frame of a beam point (ops values, world axes): ``arm`` (point minus body origin [m]),
    ``velocity`` (point velocity minus the origin's [m/s]), ``rotation`` (point frame to world) and
    ``omega`` (its angular velocity [rad/s])."""

    arm: Any
    velocity: Any
    rotation: Any
    omega: Any


def _scalar_sum(ops: Ops, items: Sequence[Any]) -> Any:
    total = items[0]
    for item in items[1:]:
        total = total + item
    return total


def _rotation_jacobian(ops: Ops, theta: Any) -> tuple[Any, Any, Any]:
    """``(Theta, Rz e2, Rz Ry e1)`` of the point rotation ``Rz Ry Rx`` at ``theta`` (3 x 1)."""
    if ops.name == "numpy":                        # the same entries filled into one array
        cy, sy, cz, sz = np.cos(theta[..., 1, 0]), np.sin(theta[..., 1, 0]), np.cos(theta[..., 2, 0]), np.sin(
            theta[..., 2, 0])
        Theta = np.zeros(theta.shape[:-2] + (3, 3), dtype=cy.dtype)
        Theta[..., 0, 0], Theta[..., 1, 0], Theta[..., 2, 0] = cz * cy, sz * cy, sy * -1.0
        Theta[..., 0, 1], Theta[..., 1, 1], Theta[..., 2, 2] = sz * -1.0, cz, 1.0
        return Theta, Theta[..., :, 1:2], Theta[..., :, 0:1]
    ty, tz = entry(ops, theta, 1), entry(ops, theta, 2)
    cy, sy, cz, sz = ops.cos(ty), ops.sin(ty), ops.cos(tz), ops.sin(tz)
    second = ops.block([[sz * -1.0], [cz], [0.0 * cz]])
    first = ops.block([[cz * cy], [sz * cy], [sy * -1.0]])
    return ops.block([[first, second, constant(ops, _E[:, 2])]]), second, first


def spatial_beam_terms(ops: Ops, beam: Any, *, rotation: Any, offset: Any, omega: Any, eta: Any, eta_dot: Any,
                       t: float, gravity: np.ndarray, loads: Sequence[tuple[np.ndarray, Any]] = (),
                       points: Mapping[str, np.ndarray] | None = None,
                       frames: Sequence[str] = ()) -> tuple[BodyTerms, dict[str, PointFrame]]:
    """Body terms of a :class:`~ctmm.spatial.beam.SpatialBeam` about its inboard point (world axes).

    Parameters
    ----------
    ops : Ops
    beam : SpatialBeam
    rotation : ops (3, 3)
        Floating frame to world.
    offset : ops (3, 1) or None
        Beam root minus the inboard point ``P`` [m] (``None``: the root is ``P``).
    omega : ops (3, 1) or None
        Frame angular velocity, world axes [rad/s].
    eta, eta_dot : ops (n, 1)
        Modal coordinates and rates.
    t : float
        Time [s] (distributed load and hook forces).
    gravity : (3,) array
        [m/s^2].
    loads : sequence of (point (3,) body axes, wrench ops (6, 1) world axes)
        Applied force [N] and moment [N m] at beam points (``point[0]`` is the station).
    points : mapping of str to (3,) array
        Outboard points carrying children (``point[0]`` the station).
    frames : sequence of str
        Points whose :class:`PointFrame` is wanted.

    Returns
    -------
    (BodyTerms, dict of PointFrame)
    """
    data = beam.data
    n, rhoA = data.n, data.rhoA
    R = rotation
    Rt = ops.transpose(R)
    w = ops.zeros(3, 1) if omega is None else ops.matmul(Rt, omega)
    g = ops.matmul(Rt, constant(ops, gravity))
    qv = constant(ops, [float(f(t)) for f in beam.distributed_load])
    e1 = constant(ops, _E[:, 0])
    if ops.name == "numpy":                        # the same terms on stacked integrals (_numpy_body)
        M_b, h_b = _numpy_body(data, data.remembered("numpy_terms", _numpy_constants), w, g, qv, eta, eta_dot, t)
    else:
        M_b, h_b = _ops_body(ops, data, w, g, qv, eta, eta_dot, t)
    if loads:
        load_lin, load_ang, load_mod = _load_rows(ops, data, Rt, eta, loads)
        h_b = h_b + ops.block([[load_lin], [load_ang], [load_mod]])
    if data.second_order is not None:                  # the mass points' shortening (beam_second_order.py)
        dM, dh = second_order_deltas(ops, data, omega=w, gravity=g, load=qv, eta=eta, eta_dot=eta_dot)
        M_b, h_b = M_b + dM, h_b + dh
    T = _turn(ops, R, n)
    T6 = ops.sub(T, slice(0, 6), slice(0, 6))
    Tt = ops.transpose(T)
    M = ops.matmul(ops.matmul(T, M_b), Tt)
    h = ops.matmul(T, h_b)
    Kin, c, RF, out = {}, {}, {}, {}
    anchors = beam.points if frames or points else {}         # (a property: built once per call, not per name)
    for name in set(points or {}) | set(frames):
        x_e = float(anchors[name][0])
        Phi_e, Lam_e, G1_e = data.station(x_e)
        rho = constant(ops, [x_e, 0.0, 0.0]) + ops.matmul(constant(ops, Phi_e), eta)
        theta = ops.matmul(constant(ops, Lam_e), eta)
        theta_dot = ops.matmul(constant(ops, Lam_e), eta_dot)
        Theta, second, first = _rotation_jacobian(ops, theta)
        ThetaLam = ops.matmul(Theta, constant(ops, Lam_e))
        rho_dot = ops.matmul(constant(ops, Phi_e), eta_dot)
        relative = ops.matmul(Theta, theta_dot)
        Phi_u, rate_term = constant(ops, Phi_e), None
        if data.second_order is not None:              # the point moves with the shortening (beam_second_order.py)
            G1_eta, G1_rate = ops.matmul(constant(ops, G1_e), eta), ops.matmul(constant(ops, G1_e), eta_dot)
            rho = rho + e1 * (ops.matmul(ops.transpose(G1_eta), eta) * -0.5)
            rho_dot = rho_dot - e1 * ops.matmul(ops.transpose(G1_eta), eta_dot)
            Phi_u = Phi_u - ops.matmul(e1, ops.transpose(G1_eta))
            rate_term = e1 * (ops.matmul(ops.transpose(G1_rate), eta_dot) * -1.0)
        if name in (points or {}):
            K_b = _point_map(ops, rho, Phi_u, ThetaLam)
            tx, ty, tz = (entry(ops, theta_dot, i) for i in range(3))
            spin = cross(ops, constant(ops, _E[:, 2]) * tz, second) * ty + cross(
                ops, constant(ops, _E[:, 2]) * tz + second * ty, first) * tx
            c_lin = cross(ops, w, cross(ops, w, rho)) + cross(ops, w, rho_dot) * 2.0
            c_b = ops.block([[c_lin if rate_term is None else c_lin + rate_term],
                             [cross(ops, w, relative) + spin]])
            RF_b = ops.transpose(K_b)                  # virtual work (with the option: -e1 eta^T G1 in Phi_u)
            if data.stiffening and data.second_order is None:
                G1_eta = ops.matmul(constant(ops, G1_e), eta)
                if ops.name == "numpy" and G1_eta.shape[:-2] == RF_b.shape[:-2] and G1_eta.dtype == RF_b.dtype:
                    RF_b = RF_b.copy()                 # the same entries: only the axial column changes
                    RF_b[..., 6:, 0:1] -= G1_eta
                else:
                    RF_b = RF_b - ops.block([[ops.zeros(6, 6)], [ops.block([[G1_eta, ops.zeros(n, 5)]])]])
            Kin[name] = ops.matmul(ops.matmul(T6, K_b), Tt)
            c[name] = ops.matmul(T6, c_b)
            RF[name] = ops.matmul(ops.matmul(T, RF_b), ops.transpose(T6))
        if name in frames:
            arm = ops.matmul(R, rho)
            world_omega = ops.zeros(3, 1) if omega is None else omega
            point_rotation = ops.matmul(R, ops.matmul(axis_rotation(ops, _E[:, 2], entry(ops, theta, 2)), ops.matmul(
                axis_rotation(ops, _E[:, 1], entry(ops, theta, 1)), axis_rotation(ops, _E[:, 0], entry(ops, theta, 0)))))
            out[name] = PointFrame(arm, cross(ops, world_omega, arm) + ops.matmul(R, rho_dot), point_rotation,
                                   world_omega + ops.matmul(R, relative))
    terms = BodyTerms(M=M, h=h, Kin=Kin, c=c, RF=RF)
    if offset is not None:
        terms = _about_inboard(ops, terms, offset, omega, n)
    return terms, out


def _point_map(ops: Ops, rho: Any, Phi_u: Any, ThetaLam: Any) -> Any:
    """``K_b = [[I, -[rho]x, Phi_u], [0, I, Theta Lambda]]`` (6 x (6 + n)) of a beam point, frame axes."""
    if ops.name == "numpy":                        # the same entries filled into one allocation
        n = ThetaLam.shape[-1]
        K = np.zeros(batch_shape(rho, Phi_u, ThetaLam) + (6, 6 + n),
                     dtype=np.result_type(rho, Phi_u, ThetaLam))
        K[..., _DIAGONAL6, _DIAGONAL6] = 1.0
        K[..., :3, 3:6] = skew(ops, rho) * -1.0
        K[..., :3, 6:] = Phi_u
        K[..., 3:6, 6:] = ThetaLam
        return K
    eye3 = ops.eye(3)
    return ops.block([[eye3, skew(ops, rho) * -1.0, Phi_u], [ops.zeros(3, 3), eye3, ThetaLam]])


_DIAGONAL6 = np.arange(6)


def _ops_body(ops: Ops, data: Any, w: Any, g: Any, qv: Any, eta: Any, eta_dot: Any,
              t: float) -> tuple[Any, Any]:
    """``(M_b, h_b)`` of :func:`spatial_beam_terms` in frame axes, about the root, without applied loads and the
    second-order terms (any :class:`~ctmm.ops.Ops`; the module docstring's formulas term by term)."""
    n, rhoA = data.n, data.rhoA
    eye3 = ops.eye(3)
    Bmat, Cmat = constant(ops, data.b), constant(ops, data.c)
    Ee = [[constant(ops, data.E[i][k]) for k in range(3)] for i in range(3)]
    E_eta = [[ops.matmul(Ee[i][k], eta) for k in range(3)] for i in range(3)]
    E_rate = [[ops.matmul(Ee[i][k], eta_dot) for k in range(3)] for i in range(3)]
    # Q_k = int rho_k Phi (3 x n): row i = delta_k0 c_i + (E[i][k] eta)^T
    Q = []
    for k in range(3):
        rows = ops.block([[ops.transpose(E_eta[i][k])] for i in range(3)])
        Q.append(rows + Cmat if k == 0 else rows)
    s = constant(ops, [data.first_moment, 0.0, 0.0]) + ops.matmul(Bmat, eta)
    C_eta = ops.matmul(Cmat, eta)
    top = ops.block([[data.second_moment + entry(ops, C_eta, 0), entry(ops, C_eta, 1), entry(ops, C_eta, 2)]])
    S = ops.block([[ops.matmul(Q[0], eta), ops.matmul(Q[1], eta), ops.matmul(Q[2], eta)]]) + \
        ops.matmul(constant(ops, _E[:, :1]), top)
    trace = _scalar_sum(ops, [entry(ops, S, i, i) for i in range(3)])
    e1e1 = constant(ops, np.diag([1.0, 0.0, 0.0]))
    J = eye3 * trace - S + e1e1 * (data.jp * data.L) + constant(ops, np.diag(data.rotary * data.L))
    Gamma = _scalar_sum(ops, [ops.matmul(constant(ops, skew_constant(k)), Q[k]) for k in range(3)])
    P = ops.block([[ops.transpose(ops.matmul(Q[k], eta_dot))] for k in range(3)])
    trace_P = _scalar_sum(ops, [entry(ops, P, i, i) for i in range(3)])
    bt = constant(ops, data.b_t)                                      # (n, 1)
    e1 = constant(ops, _E[:, 0])
    e1_bt = ops.matmul(e1, ops.transpose(bt)) + constant(ops, data.b_r)   # (3, n): twist and bending sections
    s_x = skew(ops, s)
    lower_left = ops.transpose(Bmat)
    w_parts = [entry(ops, w, i) for i in range(3)]
    twist_rate = ops.matmul(ops.transpose(bt), eta_dot)
    Jw = ops.matmul(J, w)
    h_lin = cross(ops, w, cross(ops, w, s)) + cross(ops, w, ops.matmul(Bmat, eta_dot)) * 2.0 - g * data.m - qv * data.L
    section_rate = ops.matmul(constant(ops, data.b_r), eta_dot)        # the bending sections' momentum (3, 1)
    h_ang = (cross(ops, w, Jw) + cross(ops, w, e1) * twist_rate + cross(ops, w, section_rate)
             + (w * trace_P - ops.matmul(ops.transpose(P), w)) * 2.0 - cross(ops, s, g) - cross(ops, s, qv) * (1 / rhoA))
    # modal rows: int Phi^T (Omega2 rho + 2 [omega]x Phi eta_dot), Omega2 = omega omega^T - |omega|^2 I
    w2 = _scalar_sum(ops, [w_parts[i] * w_parts[i] for i in range(3)])
    h_mod = ops.zeros(n, 1)
    for i in range(3):
        for k in range(3):
            coefficient = w_parts[i] * w_parts[k] - w2 if i == k else w_parts[i] * w_parts[k]
            h_mod = h_mod + E_eta[i][k] * coefficient
        coefficient = w_parts[i] * w_parts[0] - w2 if i == 0 else w_parts[i] * w_parts[0]
        h_mod = h_mod + ops.transpose(ops.sub(Cmat, slice(i, i + 1), slice(0, n))) * coefficient
    cross_w = [[None, w_parts[2] * -1.0, w_parts[1]], [w_parts[2], None, w_parts[0] * -1.0],
               [w_parts[1] * -1.0, w_parts[0], None]]
    for i in range(3):
        for k in range(3):
            if i != k:
                h_mod = h_mod + E_rate[i][k] * (cross_w[i][k] * 2.0)
    h_mod = h_mod - ops.matmul(ops.transpose(Bmat), g + qv * (1 / rhoA))
    h_mod = h_mod + ops.matmul(constant(ops, data.K_total), eta) + ops.matmul(constant(ops, data.D_total), eta_dot)
    for _, force in data.forces:
        h_mod = h_mod - constant(ops, np.asarray(force(t), dtype=float).reshape(n))
    modal_left = lower_left
    if data.stiffening:
        stiff = constant(ops, data.G2) * rhoA
        G2_eta = ops.matmul(constant(ops, data.G2), eta)
        axial = entry(ops, g, 0) * rhoA + entry(ops, qv, 0)
        h_mod = h_mod + G2_eta * axial + ops.matmul(constant(ops, data.G3), eta) * (
            (w_parts[1] * w_parts[1] + w_parts[2] * w_parts[2]) * rhoA)
        modal_left = lower_left - ops.matmul(ops.matmul(stiff, eta), ops.transpose(e1))
    M_b = ops.block([[eye3 * data.m, s_x * -1.0, Bmat],
                     [s_x, J, Gamma + e1_bt],
                     [modal_left, ops.transpose(Gamma) + ops.transpose(e1_bt),
                      constant(ops, data.modal_mass)]])
    return M_b, ops.block([[h_lin], [h_ang], [h_mod]])



def _numpy_constants(data: Any) -> dict[str, np.ndarray]:
    """The integrals of ``data`` stacked for :func:`_numpy_body` (numpy constants, read-only: shared by calls)."""
    n = data.n
    out = {
        "E": np.concatenate([data.E[i][k] for i in range(3) for k in range(3)]),        # (9n, n), rows (i, k, a)
        "c_first": np.zeros((3, 3, n)),                     # c_i in the (i, k = 0) rows: Q_k row i = E[i][k] eta + ...
        "b": data.b, "c": data.c, "bT": data.b.T.copy(), "b_r": data.b_r,
        "s0": np.array([[data.first_moment], [0.0], [0.0]]),
        "top": np.array([[data.second_moment, 0.0, 0.0]]),
        "J": np.diag([data.jp * data.L, 0.0, 0.0]) + np.diag(data.rotary * data.L),
        "e1_bt": np.outer(_E[:, 0], data.b_t) + data.b_r,   # (3, n): twist and bending sections
        "bt_row": data.b_t.reshape(1, n), "mass": np.eye(3) * data.m, "modal_mass": data.modal_mass,
        "K": data.K_total, "D": data.D_total, "G2": data.G2, "G3": data.G3,
        "stiff": data.G2 * data.rhoA,
    }
    out["c_first"][:, 0, :] = data.c
    for value in out.values():
        value.flags.writeable = False
    return out


def _numpy_body(data: Any, k: Mapping[str, np.ndarray], w: Any, g: Any, qv: Any, eta: Any, eta_dot: Any,
                t: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_ops_body` on numpy batches with the integrals stacked (``k``: :func:`_numpy_constants`): one
    product gives every ``E[i][k] eta`` and ``E[i][k] eta_dot``, one the columns of ``S`` and rows of ``P``, one
    the modal rows' ``sum_ik Omega2_ik int Phi_i^T rho_k + 2 [omega]x_ik E[i][k] eta_dot``.  The same numbers as
    the term-by-term path up to the order of the sums in ``h_mod`` (round-off)."""
    n, rhoA = data.n, data.rhoA
    if eta.dtype == eta_dot.dtype:                        # one product for both (else each keeps its dtype)
        states = _join([eta, eta_dot], -1)                                         # (..., n, 2)
        X = np.matmul(k["E"], states)
        X = X.reshape(X.shape[:-2] + (3, 3, n, 2))
        E_eta, E_rate = X[..., 0], X[..., 1]              # [i, k] = E[i][k] eta, E[i][k] eta_dot
        Y = E_eta + k["c_first"]                          # Y[i, k] = row i of Q_k = int rho_k Phi (3 x n)
        QS = np.matmul(Y, states[..., None, :, :])        # [i, k, 0] = (Q_k eta)_i = S_ik, [i, k, 1] = P_ki
        S_columns, P_rows = QS[..., 0], QS[..., 1]
    else:
        E_eta, E_rate = (np.matmul(k["E"], x).reshape(x.shape[:-2] + (3, 3, n)) for x in (eta, eta_dot))
        Y = E_eta + k["c_first"]
        S_columns, P_rows = (np.matmul(Y, x[..., None, :, :])[..., 0] for x in (eta, eta_dot))
    C_eta = np.matmul(k["c"], eta)
    S = np.concatenate([S_columns[..., :1, :] + (k["top"] + C_eta.swapaxes(-1, -2)), S_columns[..., 1:, :]], axis=-2)
    trace = (S[..., 0, 0] + S[..., 1, 1] + S[..., 2, 2])[..., None, None]
    J = _E * trace - S + k["J"]
    Gamma = np.stack([Y[..., 2, 1, :] - Y[..., 1, 2, :], Y[..., 0, 2, :] - Y[..., 2, 0, :],
                      Y[..., 1, 0, :] - Y[..., 0, 1, :]], axis=-2)   # sum_k [e_k]x Q_k
    P = P_rows.swapaxes(-1, -2)
    trace_P = (P[..., 0, 0] + P[..., 1, 1] + P[..., 2, 2])[..., None, None]
    s = k["s0"] + np.matmul(k["b"], eta)
    s_x = skew(NUMPY, s)
    e1 = _E[None, :, :1]
    twist_rate = np.matmul(k["bt_row"], eta_dot)
    Jw = np.matmul(J, w)
    h_lin = cross(NUMPY, w, cross(NUMPY, w, s)) + cross(NUMPY, w, np.matmul(k["b"], eta_dot)) * 2.0 - g * data.m - \
        qv * data.L
    section_rate = np.matmul(k["b_r"], eta_dot)
    h_ang = (cross(NUMPY, w, Jw) + cross(NUMPY, w, e1) * twist_rate + cross(NUMPY, w, section_rate)
             + (w * trace_P - np.matmul(P.swapaxes(-1, -2), w)) * 2.0 - cross(NUMPY, s, g)
             - cross(NUMPY, s, qv) * (1 / rhoA))
    # modal rows: sum_ik Omega2_ik Q_k row i + 2 [omega]x_ik E[i][k] eta_dot in one product
    w_row = w.swapaxes(-1, -2)
    omega2 = np.matmul(w, w_row) - _E * np.matmul(w_row, w)
    coefficients = _join([omega2.reshape(omega2.shape[:-2] + (1, 9)),
                          (skew(NUMPY, w) * 2.0).reshape(omega2.shape[:-2] + (1, 9))], -1)
    stacked = _join([Y.reshape(Y.shape[:-3] + (9, n)), E_rate.reshape(E_rate.shape[:-3] + (9, n))], -2)
    h_mod = np.matmul(coefficients, stacked).swapaxes(-1, -2)
    h_mod = h_mod - np.matmul(k["bT"], g + qv * (1 / rhoA))
    h_mod = h_mod + np.matmul(k["K"], eta) + np.matmul(k["D"], eta_dot)
    for _, force in data.forces:
        h_mod = h_mod - np.asarray(force(t), dtype=float).reshape(n, 1)
    modal_left = k["bT"]
    if data.stiffening:
        h_mod = h_mod + np.matmul(k["G2"], eta) * (g[..., :1, :1] * rhoA + qv[..., :1, :1]) + np.matmul(
            k["G3"], eta) * ((w[..., 1:2, :1] * w[..., 1:2, :1] + w[..., 2:3, :1] * w[..., 2:3, :1]) * rhoA)
        modal_left = modal_left - np.matmul(np.matmul(k["stiff"], eta), e1.swapaxes(-1, -2))
    upper = batch_shape(J, Gamma, s_x, modal_left)
    M_b = np.empty(upper + (6 + n, 6 + n), dtype=np.result_type(J, Gamma, s_x, modal_left))
    M_b[..., :3, :3] = k["mass"]
    M_b[..., :3, 3:6] = -s_x
    M_b[..., :3, 6:] = k["b"]
    M_b[..., 3:6, :3] = s_x
    M_b[..., 3:6, 3:6] = J
    M_b[..., 3:6, 6:] = Gamma + k["e1_bt"]
    M_b[..., 6:, :3] = modal_left
    M_b[..., 6:, 3:6] = Gamma.swapaxes(-1, -2) + k["e1_bt"].T
    M_b[..., 6:, 6:] = k["modal_mass"]
    return M_b, _join([h_lin, h_ang, h_mod], -2)


def _join(parts: Sequence[np.ndarray], axis: int) -> np.ndarray:
    """Numpy batches joined along ``axis`` (-1 or -2), their batch axes broadcast when they differ."""
    if len({part.shape[:-2] for part in parts}) > 1:
        parts = [np.broadcast_to(part, batch_shape(*parts) + part.shape[-2:])
                 for part in parts]
    return np.concatenate(parts, axis=axis)


def _turn(ops: Ops, R: Any, n: int) -> Any:
    """``T = diag(R, R, I_n)`` (frame axes to world axes of the body's coordinates)."""
    if ops.name == "numpy":                       # the same matrix, filled in place of the block assembly
        T = np.zeros(R.shape[:-2] + (6 + n, 6 + n), dtype=R.dtype)
        T[..., :3, :3] = R
        T[..., 3:6, 3:6] = R
        T[..., range(6, 6 + n), range(6, 6 + n)] = 1.0
        return T
    return ops.block([[block_diagonal(ops, R, R, 3, 3), ops.zeros(6, n)], [ops.zeros(n, 6), ops.eye(n)]])


def _load_rows(ops: Ops, data: Any, Rt: Any, eta: Any, loads: Sequence[tuple[np.ndarray, Any]]
               ) -> tuple[Any, Any, Any]:
    """The rows ``(h_lin, h_ang, h_mod)`` (frame axes, about the root) of applied wrenches ``[f ; m]`` (world
    axes) at beam points: ``-f``, ``-(rho_l x f + m)``, ``-(Phi_l^T f + (Theta Lambda_l)^T m)`` (+ the
    geometric stiffness of ``f_1``)."""
    if ops.name == "numpy" and data.second_order is None:
        return _numpy_load_rows(data, Rt, eta, loads)
    h_lin, h_ang, h_mod = None, None, None
    for point, wrench in loads:
        Phi_l, Lam_l, G1_l = data.station(float(point[0]))
        f = ops.matmul(Rt, ops.sub(wrench, slice(0, 3), slice(0, 1)))
        m = ops.matmul(Rt, ops.sub(wrench, slice(3, 6), slice(0, 1)))
        rho_l = constant(ops, [float(point[0]), 0.0, 0.0]) + ops.matmul(constant(ops, Phi_l), eta)
        if data.second_order is not None:              # the load point moves with the shortening
            rho_l = rho_l + constant(ops, _E[:, 0]) * (ops.matmul(ops.transpose(ops.matmul(constant(ops, G1_l), eta)),
                                                                 eta) * -0.5)
        Theta, _, _ = _rotation_jacobian(ops, ops.matmul(constant(ops, Lam_l), eta))
        lin = f * -1.0
        ang = (cross(ops, rho_l, f) + m) * -1.0
        mod = (ops.matmul(constant(ops, Phi_l.T), f) + ops.matmul(
            ops.transpose(ops.matmul(Theta, constant(ops, Lam_l))), m)) * -1.0
        if data.stiffening:
            mod = mod + ops.matmul(constant(ops, G1_l), eta) * entry(ops, f, 0)
        h_lin = lin if h_lin is None else h_lin + lin
        h_ang = ang if h_ang is None else h_ang + ang
        h_mod = mod if h_mod is None else h_mod + mod
    return h_lin, h_ang, h_mod


def _load_stations(data: Any, abscissae: tuple[float, ...]) -> dict[str, np.ndarray]:
    """The stations of the load points ``abscissae`` stacked for :func:`_numpy_load_rows` (read-only)."""
    stations = [data.station(x) for x in abscissae]
    out = {"rho0": np.array([[[x], [0.0], [0.0]] for x in abscissae]),
           "Phi": np.stack([Phi for Phi, _, _ in stations]), "PhiT": np.stack([Phi.T for Phi, _, _ in stations]),
           "Lam": np.stack([Lam for _, Lam, _ in stations]), "G1": np.stack([G1 for _, _, G1 in stations])}
    for value in out.values():
        value.flags.writeable = False
    return out


def _stacked_cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` of numpy columns ``(..., 3, 1)`` with any leading axes (:func:`~ctmm.spatial.frames.cross` reads
    one batch axis)."""
    a0, a1, a2 = a[..., 0, :], a[..., 1, :], a[..., 2, :]
    b0, b1, b2 = b[..., 0, :], b[..., 1, :], b[..., 2, :]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-2)


def _numpy_load_rows(data: Any, Rt: np.ndarray, eta: np.ndarray, loads: Sequence[tuple[np.ndarray, Any]]
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_load_rows` (without the second-order option) on numpy batches, the loads stacked on an axis
    before the matrix axes: one product per term for all of them, summed over that axis."""
    abscissae = tuple(float(point[0]) for point, _ in loads)
    k = data.remembered(("numpy_load_stations",) + abscissae, lambda d: _load_stations(d, abscissae))
    wrenches = _join([wrench[..., None, :, :] for _, wrench in loads], -3)     # (..., L, 6, 1)
    Rt = Rt[..., None, :, :]
    f = np.matmul(Rt, wrenches[..., 0:3, :])
    m = np.matmul(Rt, wrenches[..., 3:6, :])
    eta = eta[..., None, :, :]
    rho = k["rho0"] + np.matmul(k["Phi"], eta)
    Theta, _, _ = _rotation_jacobian(NUMPY, np.matmul(k["Lam"], eta))
    lin = f.sum(axis=-3) * -1.0
    ang = (_stacked_cross(rho, f) + m).sum(axis=-3) * -1.0
    mod = np.matmul(k["PhiT"], f) + np.matmul(np.matmul(Theta, k["Lam"]).swapaxes(-1, -2), m)
    mod = mod.sum(axis=-3) * -1.0
    if data.stiffening:
        mod = mod + (np.matmul(k["G1"], eta) * f[..., 0:1, :]).sum(axis=-3)
    return lin, ang, mod


def beam_load_vector(beam: Any, rotation: np.ndarray, offset: np.ndarray, eta: np.ndarray,
                     loads: Sequence[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """The generalised-force rows ``h`` (6 + n,) of applied wrenches alone (numpy, one state): the part of
    :func:`spatial_beam_terms`' ``h`` that the ``loads`` add, world axes, about the inboard point.

    Parameters
    ----------
    beam : SpatialBeam
    rotation : (3, 3) array
        Floating frame to world.
    offset : (3,) array
        Beam root minus the inboard point [m] (zeros when the root is the inboard point).
    eta : (n,) array
        Modal coordinates.
    loads : sequence of (point (3,) body axes, wrench (6,) ``[f ; m]`` world axes [N, N m])
    """

    n = beam.data.n
    if not loads:
        return np.zeros(6 + n)
    R = np.asarray(rotation, float).reshape(1, 3, 3)
    rows = _load_rows(NUMPY, beam.data, np.swapaxes(R, 1, 2), np.asarray(eta).reshape(1, n, 1),
                      [(point, np.asarray(w).reshape(1, 6, 1)) for point, w in loads])
    lin, ang, mod = (np.asarray(r).reshape(-1) for r in rows)
    lin, ang = R[0] @ lin, R[0] @ ang
    return np.concatenate([lin, ang + np.cross(np.asarray(offset, float).reshape(3), lin), mod])


def skew_constant(k: int) -> np.ndarray:
    """``[e_k]x`` (3 x 3)."""
    e = _E[:, k]
    return np.array([[0.0, -e[2], e[1]], [e[2], 0.0, -e[0]], [-e[1], e[0], 0.0]])


def _about_inboard(ops: Ops, terms: BodyTerms, offset: Any, omega: Any, n: int) -> BodyTerms:
    """Terms about the origin ``O = P + offset`` moved to the inboard point ``P``: ``x_O = Tx x_P + c``,
    ``Tx = diag(X(offset), I_n)``, ``c = [omega x (omega x offset) ; 0 ; 0]``."""
    eye3 = ops.eye(3)
    if ops.name == "numpy":                       # the same matrix, filled in place of the block assembly
        offset_x = skew(ops, offset)
        Tx = np.zeros(offset_x.shape[:-2] + (6 + n, 6 + n), dtype=offset_x.dtype)
        Tx[..., range(6 + n), range(6 + n)] = 1.0
        Tx[..., :3, 3:6] = -offset_x
    else:
        X = ops.block([[eye3, skew(ops, offset) * -1.0], [ops.zeros(3, 3), eye3]])
        Tx = ops.block([[X, ops.zeros(6, n)], [ops.zeros(n, 6), ops.eye(n)]])
    Txt = ops.transpose(Tx)
    if omega is None:
        shift = None
    else:
        shift = ops.block([[cross(ops, omega, cross(ops, omega, offset))], [ops.zeros(3 + n, 1)]])
    h = terms.h if shift is None else terms.h + ops.matmul(terms.M, shift)
    return BodyTerms(M=ops.matmul(ops.matmul(Txt, terms.M), Tx), h=ops.matmul(Txt, h),
                     Kin={e: ops.matmul(K, Tx) for e, K in terms.Kin.items()},
                     c={e: (terms.c[e] if shift is None else terms.c[e] + ops.matmul(terms.Kin[e], shift))
                        for e in terms.Kin},
                     RF={e: ops.matmul(Txt, F) for e, F in terms.RF.items()})


def beam_energy(beam: Any, rotation: np.ndarray, origin: np.ndarray, velocity: np.ndarray, omega: np.ndarray,
                eta: np.ndarray, eta_dot: np.ndarray, gravity: np.ndarray) -> np.ndarray:
    """Kinetic, elastic and gravitational energy [J] of a beam (numpy, batch ``B``): ``rotation (B, 3, 3)``,
    ``origin, velocity, omega (B, 3, 1)`` (root position and velocity, frame angular velocity, world axes),
    ``eta, eta_dot (B, n)``.  Kinetic: ``1/2 V^T M_b V`` with ``V = [R^T v ; R^T omega ; eta_dot]`` and the
    mass matrix without geometric stiffening (the exact kinetic energy of the modal kinematics)."""

    data = beam.data
    B = eta.shape[0]
    eye = np.broadcast_to(np.eye(3), (B, 3, 3))
    terms, _ = spatial_beam_terms(NUMPY, beam, rotation=eye, offset=None, omega=None, eta=eta[:, :, None],
                                  eta_dot=np.zeros_like(eta)[:, :, None], t=0.0, gravity=np.zeros(3))
    M_b = np.broadcast_to(terms.M, (B,) + terms.M.shape[-2:]).copy()
    M_b[:, 6:, :3] = np.swapaxes(M_b[:, :3, 6:], 1, 2)      # the mass matrix proper (without stiffening)
    Rt = np.swapaxes(rotation, 1, 2)
    V = np.concatenate([Rt @ velocity, Rt @ omega, eta_dot[:, :, None]], axis=1)
    kinetic = 0.5 * (np.swapaxes(V, 1, 2) @ M_b @ V)[:, 0, 0]
    elastic = 0.5 * np.einsum("bi,ij,bj->b", eta, data.K, eta)
    s = data.b @ eta.T                                                  # (3, B)
    s = s.T[:, :, None] + np.array([data.first_moment, 0.0, 0.0])[None, :, None]
    if data.second_order is not None:                  # the shortening moves the centre of mass: int rhoA u e1
        s[:, 0, 0] -= 0.5 * data.rhoA * np.einsum("bi,ij,bj->b", eta, data.G2, eta)
    height = (data.m * origin + rotation @ s)[:, :, 0] @ gravity
    return kinetic + elastic - height
