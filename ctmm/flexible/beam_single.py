"""Body terms of a planar modal beam at one real state: the unbatched numpy fast path of
:meth:`ctmm.flexible.beam.BeamData.terms`.

The batched routine (``B`` states, complex for the complex-step tangents, object arrays of casadi symbols for the
generated code) writes every statement on a leading batch axis; the explicit sweep
(:meth:`ctmm.flexible.kernel.FlexibleSystem.accelerations`) needs one real state per body and step, where that axis
costs more than the arithmetic.  The kernel calls this function as ``BeamData.terms_at_state`` (body data without
that method, e.g. finite-element subsystems, keep their batched terms at ``B = 1``).  This module states the same
equations (``docs/flexible.md``, the module docstrings of :mod:`ctmm.flexible.beam` and
:mod:`ctmm.flexible.point_terms`) on Python floats and 1-D / 2-D float arrays, in the same order of operations,
and rotates to global axes by products with ``R`` on two rows and two columns (``T = diag(R, 1, I_n)``) instead
of two ``(3 + n)``-square products.  The results equal the batched
routine's to round-off (tests/test_beam_single_terms.py: 1e-13 relative, on beams with and without stiffening,
axial modes, point and distributed loads, modal forces and laws, several ends, second-order inertia).
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from .hooks import hook_value
from .point_terms import point_shortening

__all__ = ["single_terms"]


def single_terms(data: Any, theta: float, omega: float, eta: np.ndarray, eta_dot: np.ndarray, t: float,
                 gravity: Sequence[float], ends: Sequence[int] | None = None) -> tuple[np.ndarray, np.ndarray, list]:
    """Terms of :meth:`ctmm.flexible.beam.BeamData.terms` at one real state (no batch axis).

    Parameters
    ----------
    data : BeamData
        The beam's modal integrals.
    theta, omega : float
        Frame angle [rad] and rate [rad/s].
    eta, eta_dot : (n,) float arrays
        Modal coordinates ``[q, p]`` [m] and rates [m/s].
    t : float
        Time [s] (loads, modal forces and laws).
    gravity : (2,)
        [m/s^2], global axes.
    ends : sequence of int, optional
        Indices of the ends whose terms are wanted (the explicit sweep reads only the ends that carry a child);
        the others are ``None`` in the returned list.  Default: every end.

    Returns
    -------
    M : (3 + n, 3 + n), h : (3 + n,)
        ``[F_I ; 0] = M [A_I ; eta''] + h + sum_e RF_e F_e`` in global axes.
    ends : list of (Kin (3, 3 + n), c (3,), RF (3 + n, 3), theta_e float, omega_e float)
        ``A_e = Kin [A_I ; eta''] + c`` per outboard end.
    """
    d = data
    nq = d.nq
    rhoA = d.rhoA
    q, p = eta[:nq], eta[nq:]
    qd, pd = eta_dot[:nq], eta_dot[nq:]
    c, s = math.cos(theta), math.sin(theta)
    gx, gy = float(gravity[0]), float(gravity[1])
    g1 = c * gx + s * gy                                 # gravity in the frame
    g2 = -s * gx + c * gy
    if d.load_signals or not d.constant_distributed:
        loads, (qx, qy) = d.external(t)
    else:
        loads, qx, qy = (), d.distributed[0].value, d.distributed[1].value
    w2 = omega * omega
    F, sl = d.functionals
    V = eta @ F
    Vd = eta_dot @ F
    bq_q, bp_p = float(V[sl["bq"].start]), float(V[sl["bp"].start])
    sx = d.Sx + bp_p
    Np, Nq, Mqq, Mpp = V[sl["Np"]], V[sl["Nq"]], V[sl["Mq"]], V[sl["Mp"]]
    # -- mass matrix in the frame -------------------------------------------------------------
    M = d.constant_mass.copy()
    M[0, 2] = M[2, 0] = -bq_q
    M[1, 2] = M[2, 1] = sx
    axial = d.np_ > 0                                    # axial modes (their terms are empty sums otherwise)
    M[2, 2] = (d.I0 + d.J_r + 2 * float(V[sl["cp"].start]) + (float(Mpp @ p) if axial else 0.0)
               + float(Mqq @ q))
    M[2, 3:3 + nq] = M[3:3 + nq, 2] = d.c_q + d.r_q + Np
    if axial:
        M[2, 3 + nq:] = M[3 + nq:, 2] = -Nq
    # -- velocity, gravity and load terms in the frame ------------------------------------------
    h = np.empty(3 + d.n)
    h0 = -w2 * sx - 2 * omega * float(Vd[sl["bq"].start]) - d.m * g1 - qx * d.L
    h1 = -w2 * bq_q + 2 * omega * float(Vd[sl["bp"].start]) - d.m * g2 - qy * d.L
    h2 = (2 * omega * (float(Vd[sl["cp"].start]) + (float(Mpp @ pd) if axial else 0.0) + float(Mqq @ qd))
          - (sx * g2 - bq_q * g1)
          - qy * (d.L ** 2 / 2 + bp_p / rhoA) + qx * bq_q / rhoA)
    hq = -w2 * Mqq + 2 * omega * Vd[sl["Np"]] - (g2 + qy / rhoA) * d.b_q
    hp = -w2 * (d.c_p + Mpp) - 2 * omega * Vd[sl["Nq"]] - (g1 + qx / rhoA) * d.b_p if axial else None
    if d.stiffening:
        G2q = V[sl["G2"]]
        hq = hq + (rhoA * g1 + qx) * G2q + (rhoA * w2) * V[sl["G3"]]
        M[3:3 + nq, 0] -= rhoA * G2q
    for k in range(len(loads)):
        fx, fy, mz = (float(v) for v in loads[k])
        f1, f2 = c * fx + s * fy, -s * fx + c * fy       # load in the frame
        lv = V[sl[f"l{k}"]]
        rb_x = d.load_x[k] + float(lv[0])
        if d.second_order is not None:                   # the load point moves with the shortening
            rb_x = rb_x + float(point_shortening(V[None, sl[f"lG{k}"]], q[None])[0])
        rb_y = float(lv[1])
        h0 -= f1
        h1 -= f2
        h2 -= rb_x * f2 - rb_y * f1 + mz
        hq = hq - f2 * d.load_phi[k] - mz * d.load_dphi[k]
        if axial:
            hp = hp - f1 * d.load_psi[k]
        if d.stiffening:
            hq = hq + f1 * V[sl[f"lG{k}"]]
    h[0], h[1], h[2] = h0, h1, h2
    h[3:3 + nq] = hq
    if axial:
        h[3 + nq:] = hp
    if d.second_order is not None:
        d.second_order.add_terms_single(M, h, omega, q, qd, g2 + qy / rhoA)
    h[3:] += d.K_total @ eta + d.D_total @ eta_dot
    name = d.beam.name
    for label, f in d.forces:
        h[3:] -= hook_value(name, d.n, f"force of {label!r} on beam {name!r}", f, (t,), t)
    for label, law in d.laws:
        h[3:] -= hook_value(name, d.n, f"law of {label!r} on beam {name!r}", law, (t, eta, eta_dot), t)
    # -- rotate to global axes: M <- T M T^T, h <- T h ------------------------------------------
    R = np.array([[c, -s], [s, c]])
    M[:2] = R @ M[:2]
    M[:, :2] = M[:, :2] @ R.T
    h[:2] = R @ h[:2]
    return M, h, [_single_end(d, k, Kin0, V, Vd, sl, q, qd, theta, omega, R) if ends is None or k in ends else None
                  for k, Kin0 in enumerate(d.constant_ends)]


def _single_end(d: Any, k: int, constant_kin: np.ndarray, V: np.ndarray, Vd: np.ndarray, slices: dict,
                q: np.ndarray, qd: np.ndarray, theta: float, omega: float, R: np.ndarray) -> tuple:
    """:func:`ctmm.flexible.point_terms.end_terms` at one real state (see there), rotated to global axes by the
    frame's rotation ``R`` (2, 2)."""
    nq = d.nq
    ev, evd = V[slices[f"e{k}"]], Vd[slices[f"e{k}"]]
    G1q = V[slices[f"eG{k}"]]
    rb_x, rb_y, rate_x = d.end_x[k] + float(ev[0]), float(ev[1]), float(evd[0])
    Kb = constant_kin.copy()
    w2 = omega * omega
    if d.second_order is not None:                       # the point moves with the shortening u(x_e)
        rb_x = rb_x + float(point_shortening(G1q[None], q[None])[0])
        rate_x = rate_x - float((G1q * qd).sum())
        Kb[0, 3:3 + nq] = -G1q
        c0 = -float((Vd[slices[f"eG{k}"]] * qd).sum()) - w2 * rb_x - 2 * omega * float(evd[1])
    else:
        c0 = -w2 * rb_x - 2 * omega * float(evd[1])
    Kb[0, 2] = -rb_y
    Kb[1, 2] = rb_x
    c1 = -w2 * rb_y + 2 * omega * rate_x
    RF = Kb.T.copy()                                     # virtual work (with the option: -G1(x_e) q included)
    if d.stiffening and d.second_order is None:          # first order: the one-directional stiffening only
        RF[3:3 + nq, 0] -= G1q
    Kb[:2] = R @ Kb[:2]                                  # Kin = T_3 Kb T^T
    Kb[:, :2] = Kb[:, :2] @ R.T
    RF[:2] = R @ RF[:2]                                  # RF = T RFb T_3^T
    RF[:, :2] = RF[:, :2] @ R.T
    cg = np.array([R[0, 0] * c0 + R[0, 1] * c1, R[1, 0] * c0 + R[1, 1] * c1, 0.0])
    return Kb, cg, RF, theta + float(ev[2]), omega + float(evd[2])
