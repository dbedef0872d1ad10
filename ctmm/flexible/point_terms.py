"""Kinematics and force maps of the points of a planar modal beam (children at its ends and stations, point loads).

A point at abscissa ``x_e`` of a :class:`~ctmm.flexible.beam.ModalBeam` sits in the floating frame at

``rho_e = [x_e + psi(x_e) . p + u_e, phi(x_e) . q]``,  ``u_e = -1/2 q^T G1(x_e) q``  (``G1(x) = int_0^x phi' phi'^T``)

with ``u_e = 0`` on the first-order beam and the foreshortening of the bent, axially rigid axis with
``second_order_inertia=True`` (the beam's own mass points move with it too, :mod:`ctmm.flexible.second_order`).
Differentiating twice in the rotating frame (angle ``theta``, rate ``omega``, ``k x [a, b] = [-b, a]``):

``a_e = a_I + alpha k x rho_e - omega^2 rho_e + 2 omega k x rho_e' + rho_e''``,
``rho_e'' = [psi . p'' - q'^T G1 q' - q^T G1 q'',  phi . q'']``,  ``u_e' = -q^T G1 q'``,

so with ``x = [a_I ; alpha ; q'' ; p'']`` the point's kinematics ``A_e = Kin_e x + c_e`` (``A_e = [a_e ; alpha_e]``,
``alpha_e = alpha + phi'(x_e) . q''``) have, in the frame,

``Kin_e[a_1, alpha] = -rho_e2``,  ``Kin_e[a_2, alpha] = rho_e1``,  ``Kin_e[a_1, q] = -(G1 q)^T``  (second order only),
``c_e1 = -omega^2 rho_e1 - 2 omega rho_e2' - q'^T G1 q'``,  ``c_e2 = -omega^2 rho_e2 + 2 omega rho_e1'``.

The wrench ``F_e`` the beam exerts on the child at ``e`` enters the beam's equations by virtual work,
``RF_e = Kin_e^T``: with the option the child's axial force ``f_1`` reaches the modal equations as ``-f_1 G1(x_e) q``
through ``Kin_e[a_1, q]`` and the beam's own ``Kin_e`` row carries the reaction of the modal accelerations on the
child's axial acceleration -- the coupling is two-sided and the model with children is Lagrangian (its energy,
:func:`ctmm.flexible.energy.flexible_energy`, with the children at their shortened positions, is conserved).
The first-order beam with stiffening keeps ``u_e = 0`` and adds only the one-directional
``RF_e[q, a_1] = -G1(x_e) q`` (the tension of the child's axial force, stiffening the modes).

A point load ``(f_1, f_2, m)`` (frame axes) acts on the same point: its moment about the root uses ``rho_e`` (with the
shortening when the option is on), its modal force ``f_2 phi + m phi' - f_1 G1 q`` is the virtual work through
``delta rho_e = [-(G1 q) . delta q, phi . delta q]`` either way (with stiffening on).
All statements are numpy on a batch axis and run unchanged on complex numbers and casadi scalars.
"""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["end_terms", "point_shortening"]


def point_shortening(G1q: Any, q: Any) -> Any:
    """``u_e = -1/2 q^T G1(x_e) q`` [m] (B,) from ``G1q = q @ G1(x_e)`` (B, n_q) and ``q`` (B, n_q)."""
    return -0.5 * (G1q * q).sum(1)


def end_terms(data: Any, k: int, constant_kin: np.ndarray, V: Any, Vd: Any, slices: dict, q: Any, qd: Any,
              theta: Any, omega: Any, T: Any) -> tuple:
    """Kinematics and force map of end ``k`` of a modal beam (module docstring), rotated to global axes.

    Parameters
    ----------
    data : BeamData
        The beam's modal integrals (``end_x``, ``nq``, ``n``, ``second_order``, ``stiffening``).
    k : int
        End index.
    constant_kin : (3, 3 + n)
        ``Kin_e`` of the undeformed beam in the frame.
    V, Vd : (B, r)
        The beam's stacked linear functionals of ``eta`` and ``eta_dot`` (``BeamData.functionals``); ``slices``
        names their columns.
    q, qd : (B, n_q)
        Transverse modal coordinates [m] and rates [m/s].
    theta, omega : (B,)
        Frame angle [rad] and rate [rad/s].
    T : (B, 3 + n, 3 + n)
        Rotation ``diag(R, 1, I_n)`` from frame to global axes.

    Returns
    -------
    Kin (B, 3, 3 + n), c (B, 3), RF (B, 3 + n, 3), theta_e (B,), omega_e (B,)
        ``A_e = Kin [A_I ; eta''] + c``; ``RF`` maps the end wrench onto the beam's equations.
    """
    nq, N3 = data.nq, 3 + data.n
    B = theta.shape[0]
    dtype = T.dtype
    ev, evd = V[:, slices[f"e{k}"]], Vd[:, slices[f"e{k}"]]
    G1q = V[:, slices[f"eG{k}"]]
    rb_x, rb_y, rate_x = data.end_x[k] + ev[:, 0], ev[:, 1], evd[:, 0]
    Kb = np.empty((B, 3, N3), dtype=dtype)
    Kb[:] = constant_kin
    cb = np.zeros((B, 3, 1), dtype=dtype)
    w2 = omega * omega
    if data.second_order is not None:                  # the point moves with the shortening u(x_e)
        rb_x = rb_x + point_shortening(G1q, q)
        rate_x = rate_x - (G1q * qd).sum(1)
        Kb[:, 0, 3:3 + nq] = -G1q
        cb[:, 0, 0] = -(Vd[:, slices[f"eG{k}"]] * qd).sum(1) - w2 * rb_x - 2 * omega * evd[:, 1]
    else:
        cb[:, 0, 0] = -w2 * rb_x - 2 * omega * evd[:, 1]
    Kb[:, 0, 2] = -rb_y
    Kb[:, 1, 2] = rb_x
    cb[:, 1, 0] = -w2 * rb_y + 2 * omega * rate_x
    RFb = np.transpose(Kb, (0, 2, 1)).copy()           # virtual work (with the option: -G1(x_e) q included)
    if data.stiffening and data.second_order is None:   # first order: the one-directional stiffening only
        RFb[:, 3:3 + nq, 0] -= G1q
    T3 = T[:, :3, :3]
    Tt = np.transpose(T, (0, 2, 1))
    return (T3 @ Kb @ Tt, (T3 @ cb)[:, :, 0], T @ RFb @ np.transpose(T3, (0, 2, 1)),
            theta + ev[:, 2], omega + evd[:, 2])
