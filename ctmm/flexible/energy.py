"""Mechanical energy of planar models with modal beams (kinetic + gravity + elastic)."""
from __future__ import annotations

import numpy as np

from ..planar.hinge_laws import law_potential


def flexible_energy(model, q, qdot, t: float = 0.0) -> float:
    """Kinetic + gravitational + hinge-spring + modal strain energy [J].

    Beam kinetic energy from the floating-frame kinematics (``docs/flexible.md``):
    ``T = m |v_I|^2/2 + v_I . (omega k x s + R s_bar') + omega^2 I_P/2
    + omega ((c_q + N^T p) . q' - (N q) . p') + eta'^T M eta'/2`` plus the sections' turning ``1/2 (J_r omega^2
    + 2 omega r_q . q' + q'^T R_q q')`` (zero without rotary inertia).  Conserved by the exact
    solution when the model has no damping, no time-varying inputs and no geometric stiffening
    (the stiffening force is a first-order, non-conservative addition) -- or when every stiffened
    beam has ``second_order_inertia=True``, whose terms this energy includes
    (:meth:`ctmm.flexible.second_order.SecondOrderInertia.energy_delta`).
    """
    q, qdot = model.state(q, qdot)
    pts = model.points(q, qdot, t)
    g = model.gravity
    energy = 0.0
    for j in range(model.n_bodies):
        if j in model.beams:
            d = model.beams[j].data
            eta, etad = q[model.modal_index[j]], qdot[model.modal_index[j]]
            qq, pp, qd, pd = eta[:d.nq], eta[d.nq:], etad[:d.nq], etad[d.nq:]
            th, w = pts["theta"][j], pts["omega"][j]
            c, s = np.cos(th), np.sin(th)
            R = np.array([[c, -s], [s, c]])
            sb = np.array([d.Sx + pp @ d.b_p, qq @ d.b_q])
            sbd = np.array([pd @ d.b_p, qd @ d.b_q])
            sg = R @ sb
            vI = pts["inboard_velocity"][j]
            IP = d.I0 + 2 * pp @ d.c_p + pp @ d.M_p @ pp + qq @ d.M_q @ qq
            energy += (0.5 * d.m * vI @ vI + vI @ (w * np.array([-sg[1], sg[0]]) + R @ sbd)
                       + 0.5 * w * w * IP + w * ((d.c_q + d.N.T @ pp) @ qd - (d.N @ qq) @ pd)
                       + 0.5 * qd @ d.M_q @ qd + 0.5 * pd @ d.M_p @ pd
                       + 0.5 * (d.J_r * w * w + 2 * w * d.r_q @ qd + qd @ d.R_q @ qd))     # the sections' turning
            energy += 0.5 * eta @ d.K @ eta - g @ (d.m * pts["inboard"][j] + sg)
            if getattr(d, "second_order", None) is not None:     # the mass points' shortening (second_order.py)
                energy += d.second_order.energy_delta(qq, qd, R.T @ vI, w, R.T @ g)
        else:
            v = pts["com_velocity"][j]
            energy += 0.5 * model.mass[j] * v @ v + 0.5 * model.inertia[j] * pts["omega"][j] ** 2
            energy -= model.mass[j] * g @ pts["com"][j]
    dtheta, _ = model.relative_angles(pts["theta"], pts["omega"], q, qdot)
    reference, _, _ = model.hinge_laws(t)
    energy += 0.5 * np.sum(model.stiffness * (dtheta - reference) ** 2) + law_potential(model, dtheta, q)
    return float(energy)


__all__ = ["flexible_energy"]
