"""Body terms of a spatial subsystem (:class:`~ctmm.fem.SpatialSubsystem`) on the element protocol (d = 6).

Floating frame at the inboard boundary node (origin, and orientation of the node); internal DOFs
``u`` (n) in frame axes.  A material point at ``X`` (undeformed, frame) is at ``rho = X + S(X) u``;
the section and point rotary inertias turn with ``Omega = omega + P u_dot`` (frame axes, constant
inertia in the frame: small node rotations).  With ``x = [a_I ; alpha ; u'']`` in frame axes, Kane's
equations for the particles and Lagrange's (Euler-Poincare for the frame) for the rotary part give
(``docs/mixed.md`` §7)::

    M_b = [[m I,     -[s]x,      S1        ],     s = s0 + S1 u,  J = tr(S_rr) I - S_rr + J_r,
           [[s]x,     J,         Gam + R_c ],     S_rr = int rho rho^T dm,  Gam = int [rho]x S dm,
           [S1^T,  (Gam + R_c)^T, M        ]]     P_ij = int rho_i (S u')_j dm
    h_b = [w x (w x s) + 2 w x S1 u' - m g ;
           w x (J w + R_c u') + 2 (w tr P - P^T w) - s x g ;
           sum_ik (w w^T - |w|^2 I)_ik int S_i^T rho_k dm + 2 sum_ik [w]x_ik E_ik u' - S1^T g + K u + C u' - f]
    A_e = [[I, -[rho_e]x, S_e], [0, I, Theta_e P_e]] x + [w x (w x rho_e) + 2 w x S_e u' ;
                                                         w x Theta_e P_e u' + Theta_dot_e theta_dot_e],

with ``E_ik = int S_i^T S_k dm`` and ``int rho_i S_k dm = D_ik^T + u^T E_ik`` (``D_ik = int X_i S_k dm``),
``J_r`` and ``R_c`` the rotary integrals, ``M`` the full mass matrix (translational plus rotary).  A
point's frame is the node frame ``R E(theta_e)``, ``E = Rz Ry Rx`` of the node's rotation DOFs
``theta_e``, ``Theta`` its angular-velocity map.  Turned to world axes by ``T = diag(R, R, I_n)``; a
joint translation (``offset``) moves the terms to the inboard point.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import ModelError, SimulationError
from ..ops import Ops
from ..protocol import BodyTerms
from ..spatial.beam_terms import PointFrame
from ..spatial.frames import axis_rotation, block_diagonal, constant, cross, entry, skew

__all__ = ["subsystem_terms", "node_rotation_jacobian"]

_E = np.eye(3)


def node_rotation_jacobian(ops: Ops, theta: Any) -> tuple[Any, Any]:
    """``(Theta, spin)``: the angular velocity ``Theta theta_dot`` of ``E(theta) = Rz Ry Rx`` relative to its
    parent frame (3 x 3) and a function giving ``Theta_dot theta_dot`` from ``theta_dot`` (3 x 1)."""
    ty, tz = entry(ops, theta, 1), entry(ops, theta, 2)
    cy, sy, cz, sz = ops.cos(ty), ops.sin(ty), ops.cos(tz), ops.sin(tz)
    second = ops.block([[sz * -1.0], [cz], [0.0 * cz]])                    # Rz e2
    first = ops.block([[cz * cy], [sz * cy], [sy * -1.0]])                 # Rz Ry e1
    Theta = ops.block([[first, second, constant(ops, _E[:, 2])]])

    def spin(theta_dot: Any) -> Any:
        tx, ty_dot, tz_dot = (entry(ops, theta_dot, i) for i in range(3))
        e3 = constant(ops, _E[:, 2])
        return cross(ops, e3 * tz_dot, second) * ty_dot + cross(ops, e3 * tz_dot + second * ty_dot, first) * tx
    return Theta, spin


def _rows(ops: Ops, vector: Any, indices: Sequence[int] | None) -> Any:
    """``vector[indices]`` (3 x 1) of a column, or zeros."""
    if indices is None:
        return ops.zeros(3, 1)
    return ops.block([[entry(ops, vector, i)] for i in indices])


def _selection(n: int, indices: Sequence[int] | None) -> np.ndarray:
    out = np.zeros((3, n))
    if indices is not None:
        out[np.arange(3), list(indices)] = 1.0
    return out


def _nonlinear(ops: Ops, data: Any, eta: Any, eta_dot: Any, t: float) -> Any:
    """``f(u, u_dot, t)`` on the internal DOFs as an ops column (numpy: per batch row)."""
    body = data.body
    if ops.name != "numpy":
        raise ModelError(f"subsystem {body.name!r}: a nonlinear_force is Python code; generated code (compiled=True) "
                         "cannot hold it: run without compiled=True")
    eta, eta_dot = np.asarray(eta), np.asarray(eta_dot)
    B = max(eta.shape[0], eta_dot.shape[0])
    eta, eta_dot = np.broadcast_to(eta, (B,) + eta.shape[1:]), np.broadcast_to(eta_dot, (B,) + eta_dot.shape[1:])
    out = np.zeros((B, data.n, 1), dtype=np.result_type(eta, eta_dot, float))
    for b in range(B):
        u = np.zeros(data.n_all, dtype=out.dtype)
        v = np.zeros(data.n_all, dtype=out.dtype)
        u[data.keep], v[data.keep] = eta[b, :, 0], eta_dot[b, :, 0]
        try:
            value = np.asarray(body.nonlinear_force(u, v, t))
        except Exception as exc:  # noqa: BLE001 - user code: named with the time
            raise SimulationError(f"nonlinear_force of subsystem {body.name!r} raised {type(exc).__name__} at "
                                  f"t = {t:.6g} s: {exc}", time=float(t), element=body.name) from exc
        if value.shape != (data.n_all,) or not np.all(np.isfinite(value)):
            raise SimulationError(f"nonlinear_force of subsystem {body.name!r} returned {value!r} at t = {t:.6g} s; "
                                  f"expected {data.n_all} finite values", time=float(t), element=body.name)
        out[b, :, 0] = value[data.keep]
    return out


def subsystem_terms(ops: Ops, data: Any, *, rotation: Any, offset: Any, omega: Any, eta: Any, eta_dot: Any,
                    t: float, gravity: np.ndarray, loads: Sequence[tuple[np.ndarray, Any]] = (),
                    points: Mapping[str, np.ndarray] | None = None, frames: Sequence[str] = ()
                    ) -> tuple[BodyTerms, dict[str, PointFrame]]:
    """Body terms of a spatial subsystem about its inboard point, world axes (module docstring).

    Parameters
    ----------
    ops : Ops
    data : SpatialSubsystemData
        The reduced matrices and inertia integrals (:class:`~ctmm.fem.spatial_subsystem.SpatialSubsystemData`).
    rotation : ops (3, 3)
        Floating frame to world.
    offset : ops (3, 1) or None
        Frame origin minus the inboard point [m] (a joint translation; ``None``: none).
    omega : ops (3, 1) or None
        Frame angular velocity, world axes [rad/s].
    eta, eta_dot : ops (n, 1)
        Internal DOFs and rates (frame axes).
    t : float
        Time [s].
    gravity : (3,) array
        [m/s^2], world axes.
    loads : sequence of (point (3,) frame [m], wrench ops (6, 1) world axes [N, N m])
        Applied loads at nodes (the point is a node position).
    points : mapping of str to (3,) array
        Points carrying children (node names).
    frames : sequence of str
        Points whose :class:`~ctmm.spatial.beam_terms.PointFrame` is wanted.

    Returns
    -------
    (BodyTerms, dict of PointFrame)
    """
    n = data.n
    R = rotation
    Rt = ops.transpose(R)
    w = ops.zeros(3, 1) if omega is None else ops.matmul(Rt, omega)
    g = ops.matmul(Rt, constant(ops, gravity))
    u, ud = eta, eta_dot
    eye3 = ops.eye(3)
    S1 = constant(ops, data.S1)
    Eu, Eud = ops.matmul(constant(ops, data.E_stack), u), ops.matmul(constant(ops, data.E_stack), ud)
    Du = ops.matmul(constant(ops, data.D_stack), u)

    def block(stack: Any, i: int, k: int) -> Any:
        start = (3 * i + k) * n
        return ops.sub(stack, slice(start, start + n), slice(0, 1))

    # Y[i][k] = (int rho_i S_k dm)^T = D_ik + E_ki u  (n x 1)
    Y = [[constant(ops, data.D[i, k]) + block(Eu, k, i) for k in range(3)] for i in range(3)]
    ut = ops.transpose(u)
    Srr = [[None] * 3 for _ in range(3)]
    for i in range(3):
        for k in range(i, 3):
            value = (entry(ops, Du, 3 * i + k) + entry(ops, Du, 3 * k + i) + ops.matmul(ut, block(Eu, i, k))
                     + float(data.SXX[i, k]))
            Srr[i][k] = Srr[k][i] = value
    trace = Srr[0][0] + Srr[1][1] + Srr[2][2]
    J = ops.block([[Srr[i][k] * -1.0 for k in range(3)] for i in range(3)]) + eye3 * trace + constant(ops, data.J_rot)
    Gam = ops.block([[ops.transpose(Y[1][2] - Y[2][1])], [ops.transpose(Y[2][0] - Y[0][2])],
                     [ops.transpose(Y[0][1] - Y[1][0])]]) + constant(ops, data.R_c)
    P = ops.block([[ops.matmul(ops.transpose(Y[i][k]), ud) for k in range(3)] for i in range(3)])
    trace_P = entry(ops, P, 0, 0) + entry(ops, P, 1, 1) + entry(ops, P, 2, 2)
    s = constant(ops, data.s0) + ops.matmul(S1, u)
    S1ud = ops.matmul(S1, ud)
    Rc_ud = ops.matmul(constant(ops, data.R_c), ud)
    h_lin = cross(ops, w, cross(ops, w, s)) + cross(ops, w, S1ud) * 2.0 - g * data.m
    h_ang = (cross(ops, w, ops.matmul(J, w) + Rc_ud) + (w * trace_P - ops.matmul(ops.transpose(P), w)) * 2.0
             - cross(ops, s, g))
    wp = [entry(ops, w, i) for i in range(3)]
    w2 = wp[0] * wp[0] + wp[1] * wp[1] + wp[2] * wp[2]
    skew_w = [[None, wp[2] * -1.0, wp[1]], [wp[2], None, wp[0] * -1.0], [wp[1] * -1.0, wp[0], None]]
    h_mod = ops.matmul(constant(ops, data.K), u) + ops.matmul(constant(ops, data.C), ud) - ops.matmul(
        ops.transpose(S1), g)
    for i in range(3):
        for k in range(3):
            coefficient = wp[i] * wp[k] - w2 if i == k else wp[i] * wp[k]
            h_mod = h_mod + Y[k][i] * coefficient
            if i != k:
                h_mod = h_mod + block(Eud, i, k) * (skew_w[i][k] * 2.0)
    if data.body.nonlinear_force is not None:
        h_mod = h_mod - _nonlinear(ops, data, u, ud, t)
    kinematics = {}

    def point(name: str) -> tuple:
        if name not in kinematics:
            X, trans, rot = data.point_rows[name]
            S_e = constant(ops, _selection(n, trans))
            rho = constant(ops, X) + _rows(ops, u, trans)
            rho_dot = _rows(ops, ud, trans)
            if rot is None:
                kinematics[name] = (S_e, rho, rho_dot, None, None, None, None)
            else:
                theta, theta_dot = _rows(ops, u, rot), _rows(ops, ud, rot)
                Theta, spin = node_rotation_jacobian(ops, theta)
                kinematics[name] = (S_e, rho, rho_dot, theta, ops.matmul(Theta, constant(ops, _selection(n, rot))),
                                    ops.matmul(Theta, theta_dot), spin(theta_dot))
        return kinematics[name]

    by_position = data.node_at_position
    for position, wrench in loads:
        key = tuple(np.round(np.asarray(position, dtype=float), 12))
        if key not in by_position:
            raise ModelError(f"subsystem {data.body.name!r}: a load or actuator acts at {np.asarray(position).tolist()} m, "
                             f"which is not a node; loads on a subsystem act at its nodes ({', '.join(data.point_rows)})")
        S_e, rho, _, _, TP, _, _ = point(by_position[key])
        f = ops.matmul(Rt, ops.sub(wrench, slice(0, 3), slice(0, 1)))
        m_l = ops.matmul(Rt, ops.sub(wrench, slice(3, 6), slice(0, 1)))
        h_lin = h_lin - f
        h_ang = h_ang - cross(ops, rho, f) - m_l
        h_mod = h_mod - ops.matmul(ops.transpose(S_e), f)
        if TP is not None:                                  # (at a node without rotation DOFs: on the frame only)
            h_mod = h_mod - ops.matmul(ops.transpose(TP), m_l)
    M_b = ops.block([[eye3 * data.m, skew(ops, s) * -1.0, S1],
                     [skew(ops, s), J, Gam],
                     [ops.transpose(S1), ops.transpose(Gam), constant(ops, data.M)]])
    T6 = block_diagonal(ops, R, R, 3, 3)
    T = ops.block([[T6, ops.zeros(6, n)], [ops.zeros(n, 6), ops.eye(n)]])
    Tt = ops.transpose(T)
    M = ops.matmul(ops.matmul(T, M_b), Tt)
    h = ops.matmul(T, ops.block([[h_lin], [h_ang], [h_mod]]))
    Kin, c, RF, out = {}, {}, {}, {}
    for name in set(points or {}) | set(frames):
        S_e, rho, rho_dot, theta, TP, relative, spin = point(name)
        if name in (points or {}):
            angular = ops.zeros(3, n) if TP is None else TP
            K_b = ops.block([[eye3, skew(ops, rho) * -1.0, S_e], [ops.zeros(3, 3), eye3, angular]])
            c_ang = ops.zeros(3, 1) if TP is None else cross(ops, w, relative) + spin
            c_b = ops.block([[cross(ops, w, cross(ops, w, rho)) + cross(ops, w, ops.matmul(S_e, ud)) * 2.0], [c_ang]])
            Kin[name] = ops.matmul(ops.matmul(T6, K_b), Tt)
            c[name] = ops.matmul(T6, c_b)
            RF[name] = ops.transpose(Kin[name])
        if name in frames:
            arm = ops.matmul(R, rho)
            world_omega = ops.zeros(3, 1) if omega is None else omega
            if theta is None:
                point_rotation, point_omega = R, world_omega
            else:
                point_rotation = ops.matmul(R, ops.matmul(axis_rotation(ops, _E[:, 2], entry(ops, theta, 2)), ops.matmul(
                    axis_rotation(ops, _E[:, 1], entry(ops, theta, 1)), axis_rotation(ops, _E[:, 0], entry(ops, theta, 0)))))
                point_omega = world_omega + ops.matmul(R, relative)
            out[name] = PointFrame(arm, cross(ops, world_omega, arm) + ops.matmul(R, rho_dot), point_rotation,
                                   point_omega)
    terms = BodyTerms(M=M, h=h, Kin=Kin, c=c, RF=RF)
    if offset is not None:
        terms = _moved_to_inboard(ops, terms, offset, omega, n)
    return terms, out


def _moved_to_inboard(ops: Ops, terms: BodyTerms, offset: Any, omega: Any, n: int) -> BodyTerms:
    """Terms about the frame origin ``O = P + offset`` restated about the inboard point ``P``:
    ``x_O = X x_P + c`` with ``X = diag([[I, -[offset]x], [0, I]], I_n)``, ``c = [omega x (omega x offset) ; 0]``;
    ``M -> X^T M X``, ``h -> X^T (h + M c)``, ``Kin_e -> Kin_e X``, ``c_e -> c_e + Kin_e c``, ``RF_e -> X^T RF_e``."""
    eye3 = ops.eye(3)
    X = ops.block([[eye3, skew(ops, offset) * -1.0, ops.zeros(3, n)], [ops.zeros(3, 3), eye3, ops.zeros(3, n)],
                   [ops.zeros(n, 3), ops.zeros(n, 3), ops.eye(n)]])
    Xt = ops.transpose(X)
    bias = None if omega is None else ops.block([[cross(ops, omega, cross(ops, omega, offset))],
                                                 [ops.zeros(3 + n, 1)]])
    h = terms.h if bias is None else terms.h + ops.matmul(terms.M, bias)
    return BodyTerms(M=ops.matmul(ops.matmul(Xt, terms.M), X), h=ops.matmul(Xt, h),
                     Kin={e: ops.matmul(K, X) for e, K in terms.Kin.items()},
                     c={e: terms.c[e] if bias is None else terms.c[e] + ops.matmul(terms.Kin[e], bias)
                        for e in terms.Kin},
                     RF={e: ops.matmul(Xt, F) for e, F in terms.RF.items()})
