"""Second-order (foreshortening) inertia of the axially rigid modal beam (``ModalBeam(second_order_inertia=True)``).

An axially rigid bent beam keeps the length of its centre line: the material point at abscissa ``x`` sits at

``rho(x) = [x + u(x), w(x)]``,  ``w = phi(x) . q``,  ``u(x) = -1/2 q^T G1(x) q``,  ``G1(x) = int_0^x phi' phi'^T``

in the floating (root tangent) frame (``docs/flexible.md`` §1.3.1).  The first-order beam keeps ``u = 0`` in its mass
points and adds only the geometric stiffness of the axial inertia and weight to the modal equations (what ``u``
contributes to them at first order in ``q``).  With ``u`` in every mass point the kinetic energy
``T = 1/2 int rhoA |v_I + omega k x R rho + R rho'|^2 dx`` and the weight's potential are exact for this
kinematics; Lagrange's equations then hold the same geometric stiffness *and* its reactions: the symmetric
partner of the base-acceleration coupling (the inertia of the shortening on the frame's axial force), the changed
first and second moments of mass (``int rhoA u``, ``int rhoA x u``, ``int rhoA u^2``), the axial velocities
``u' = -q^T G1 q'`` in the Coriolis forces and the quadratic rate term ``-q'^T G1 q'`` of the axial acceleration.
The model conserves its mechanical energy (:func:`ctmm.flexible.energy.flexible_energy` adds these terms).

All terms are polynomials in ``q`` with constant coefficients, built once from the beam's quadrature
(``rhoA`` uniform, integrals over ``[0, L]``):

``G2 = int G1``,  ``G3 = int x G1``,  ``T_kij = int phi_k G1_ij``,  ``H_ijkl = int G1_ij G1_kl``.

The body terms are written in this module as the *difference* to the first-order beam with geometric stiffening
(:meth:`SecondOrderInertia.add_terms`), in the floating frame and with the coordinates ``[a_1, a_2, alpha, q'']``:

``dM[0, q] = -rhoA G2 q``  (the partner of the stiffening's ``M[q, 0]``),
``dM[1, 2] = rhoA U0``,  ``U0 = int u = -1/2 q^T G2 q``,
``dM[2, 2] = rhoA (-q^T G3 q + 1/4 H(q, q, q, q))``,
``dM[2, q] = rhoA (T(q, ., q) - 1/2 T(., q, q))``,  ``dM[q, q] = rhoA H(., q, ., q)``,
``dh_0 = -omega^2 rhoA U0 - rhoA q'^T G2 q'``,  ``dh_1 = -2 omega rhoA q^T G2 q'``,
``dh_2 = rhoA T(q, q', q') + 2 omega rhoA (-q^T G3 q' + 1/2 H(q, q, q, q')) - gamma_2 rhoA U0``,
``dh_q = rhoA (-1/2 omega^2 H(., q, q, q) + 2 omega T(q', ., q) + H(., q, q', q') - 2 omega T(., q, q'))``,

``T(a, b, c) = T_kij a_k b_i c_j``, ``H(a, b, c, d) = H_ijkl a_i b_j c_k d_l`` (a ``.`` leaves that index free) and
``gamma_2 = g_2 + q_y / rhoA`` the transverse gravity and distributed load per unit mass in the frame.  Complex-safe
and object-array-safe (the generated kernels run the same numpy statements on casadi scalars).

The beam's points (children at its ends and stations, point loads) move with the shortening too; their kinematics
and force maps are stated in :mod:`ctmm.flexible.point_terms` (``Kin_e[a_1, q] = -(G1(x_e) q)^T``, the rate term
``-q'^T G1(x_e) q'``, ``RF_e = Kin_e^T``), the children's positions by ``BeamData.end_point`` (so the energy of the
whole model is conserved).  A cut joint at an end is not a child: it adds the end shortening itself
(``docs/closed_loops.md`` §4b).
Not covered: axial modes (``n_axial_modes > 0``: the extensible beam's shortening belongs to its axial strain;
refused).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ModelError
from .modes import gauss_points


def check_second_order(beam: Any) -> None:
    """Raise :class:`ModelError` unless ``beam.second_order_inertia`` is a bool and, when True, the beam is axially
    rigid with its geometric stiffening on (a :class:`~ctmm.flexible.beam.ModalBeam` under construction)."""
    value = beam.second_order_inertia
    if not isinstance(value, bool):
        raise ModelError(f"{beam.name}: second_order_inertia must be True or False, got {value!r}")
    if value and (beam.n_axial_modes or not beam.geometric_stiffening):
        raise ModelError(f"{beam.name}: second_order_inertia=True needs an axially rigid beam with its geometric "
                         f"stiffening (n_axial_modes = 0, geometric_stiffening = True), got n_axial_modes = "
                         f"{beam.n_axial_modes}, geometric_stiffening = {beam.geometric_stiffening}")


class SecondOrderInertia:
    """Coefficient tensors of the second-order inertia of one axially rigid modal beam.

    Parameters
    ----------
    beam : ModalBeam
        The beam (its ``mass_per_length`` [kg/m], ``quadrature`` and transverse ``shapes``).
    x, w : (P,)
        Gauss-Legendre points [m] and weights [m] on ``[0, L]``.
    phi : (n, P)
        Transverse shapes at ``x``.
    G2, G3 : (n, n)
        ``int G1`` [-] and ``int x G1`` [m].
    """

    def __init__(self, beam: Any, x: np.ndarray, w: np.ndarray, phi: np.ndarray, G2: np.ndarray,
                 G3: np.ndarray) -> None:
        self.rhoA = float(beam.mass_per_length)
        inner, inner_w = gauss_points(beam.quadrature, 1.0)          # G1(x_k) on [0, x_k]: one evaluation
        inner_dphi = beam.shapes(np.outer(x, inner).ravel(), 1).reshape(-1, len(x), len(inner))
        G1 = np.einsum("ikj,lkj,kj->kil", inner_dphi, inner_dphi, np.outer(x, inner_w))   # (P, n, n) [1/m]
        self.G2 = G2
        self.G3 = G3
        self.T = np.einsum("p,kp,pij->kij", w, phi, G1)            # (n, n, n) [m]
        self.H = np.einsum("p,pij,pkl->ijkl", w, G1, G1)           # (n, n, n, n) [1/m]

    def mass_delta(self, q: np.ndarray) -> tuple:
        """Changed entries of the frame mass matrix at modal coordinates ``q`` (B, n):
        ``(dM_0q (B, n), dM_12 (B,), dM_22 (B,), dM_2q (B, n), dM_qq (B, n, n))``."""
        r = self.rhoA
        G2q = q @ self.G2                                          # G2 symmetric
        Hq = np.einsum("ijkl,bl->bijk", self.H, q)                  # H(., ., ., q)
        Hqq = np.einsum("bijk,bj->bik", Hq, q)                     # H(., q, ., q)
        Tq = np.einsum("kij,bj->bki", self.T, q)                    # T(., ., q)
        dM_0q = -r * G2q
        U0 = -0.5 * (G2q * q).sum(1)
        dM_12 = r * U0
        dM_22 = r * (-((q @ self.G3) * q).sum(1) + 0.25 * np.einsum("bik,bi,bk->b", Hqq, q, q))
        dM_2q = r * (np.einsum("bki,bk->bi", Tq, q) - 0.5 * np.einsum("bki,bi->bk", Tq, q))
        dM_qq = r * Hqq
        return dM_0q, dM_12, dM_22, dM_2q, dM_qq

    def add_terms(self, M: np.ndarray, h: np.ndarray, omega: np.ndarray, q: np.ndarray, qd: np.ndarray,
                  gamma_2: np.ndarray) -> None:
        """Add the second-order terms to the frame mass matrix ``M`` (B, 3 + n, 3 + n) and velocity / load vector
        ``h`` (B, 3 + n) of the first-order beam with geometric stiffening (in place).

        ``omega`` (B,) frame rate [rad/s]; ``q, qd`` (B, n) modal coordinates [m] and rates [m/s]; ``gamma_2`` (B,)
        transverse gravity plus distributed load per unit mass in the frame [m/s^2]."""
        r = self.rhoA
        n = q.shape[1]
        dM_0q, dM_12, dM_22, dM_2q, dM_qq = self.mass_delta(q)
        M[:, 0, 3:3 + n] = M[:, 0, 3:3 + n] + dM_0q
        M[:, 1, 2] = M[:, 1, 2] + dM_12
        M[:, 2, 1] = M[:, 2, 1] + dM_12
        M[:, 2, 2] = M[:, 2, 2] + dM_22
        M[:, 2, 3:3 + n] = M[:, 2, 3:3 + n] + dM_2q
        M[:, 3:3 + n, 2] = M[:, 3:3 + n, 2] + dM_2q
        M[:, 3:3 + n, 3:3 + n] = M[:, 3:3 + n, 3:3 + n] + dM_qq
        w = omega
        w2 = w * w
        U0 = dM_12 / r
        Hq = np.einsum("ijkl,bl->bijk", self.H, q)                  # H(., ., ., q)
        Hqq = np.einsum("bijk,bk->bij", Hq, q)                      # H(., ., q, q)
        Hqqq = np.einsum("bij,bj->bi", Hqq, q)                      # H(., q, q, q)
        Hqdqd = np.einsum("ijkl,bk,bl->bij", self.H, qd, qd)        # H(., ., q', q')
        Tq = np.einsum("kij,bj->bki", self.T, q)                    # T(., ., q)
        Tqd = np.einsum("kij,bj->bki", self.T, qd)                  # T(., ., q')
        h[:, 0] = h[:, 0] - w2 * r * U0 - r * ((qd @ self.G2) * qd).sum(1)
        h[:, 1] = h[:, 1] - 2 * w * r * ((q @ self.G2) * qd).sum(1)
        h[:, 2] = h[:, 2] + (r * np.einsum("bki,bk,bi->b", Tqd, q, qd)
                             + 2 * w * r * (-((q @ self.G3) * qd).sum(1) + 0.5 * (Hqqq * qd).sum(1))
                             - gamma_2 * r * U0)
        h[:, 3:3 + n] = h[:, 3:3 + n] + r * (-0.5 * w2[:, None] * Hqqq
                                             + 2 * w[:, None] * np.einsum("bki,bk->bi", Tq, qd)
                                             + np.einsum("bij,bj->bi", Hqdqd, q)
                                             - 2 * w[:, None] * np.einsum("bki,bi->bk", Tqd, q))

    def add_terms_single(self, M: np.ndarray, h: np.ndarray, omega: float, q: np.ndarray, qd: np.ndarray,
                         gamma_2: float) -> None:
        """:meth:`add_terms` at one real state (no batch axis; ``M`` (3 + n, 3 + n), ``h`` (3 + n,), ``q, qd`` (n,),
        ``omega`` [rad/s] and ``gamma_2`` [m/s^2] floats): the same sums as matrix products, equal to round-off."""
        r = self.rhoA
        n = q.shape[0]
        G2q = q @ self.G2
        Hq = self.H @ q                                            # H(., ., ., q)
        Hq_q = q @ Hq                                              # H(., q, ., q)
        Tq = self.T @ q                                            # T(., ., q)
        Tqd = self.T @ qd                                          # T(., ., q')
        U0 = -0.5 * float(G2q @ q)
        M[0, 3:3 + n] += -r * G2q
        M[1, 2] += r * U0
        M[2, 1] += r * U0
        M[2, 2] += r * (-float((q @ self.G3) @ q) + 0.25 * float(q @ Hq_q @ q))
        dM_2q = r * (q @ Tq - 0.5 * (Tq @ q))
        M[2, 3:3 + n] += dM_2q
        M[3:3 + n, 2] += dM_2q
        M[3:3 + n, 3:3 + n] += r * Hq_q
        w2 = omega * omega
        Hqqq = (Hq @ q) @ q                                        # H(., q, q, q)
        h[0] += -w2 * r * U0 - r * float((qd @ self.G2) @ qd)
        h[1] += -2 * omega * r * float(G2q @ qd)
        h[2] += (r * float(q @ Tqd @ qd) + 2 * omega * r * (-float((q @ self.G3) @ qd) + 0.5 * float(Hqqq @ qd))
                 - gamma_2 * r * U0)
        h[3:3 + n] += r * (-0.5 * w2 * Hqqq + 2 * omega * (qd @ Tq) + ((self.H @ qd) @ qd) @ q
                           - 2 * omega * (Tqd @ q))

    def energy_delta(self, q: np.ndarray, qd: np.ndarray, velocity_frame: np.ndarray, omega: float,
                     gravity_frame: np.ndarray) -> float:
        """Kinetic plus gravity energy the second-order kinematics add [J] (unbatched ``q, qd`` (n,), inboard
        velocity and gravity in the frame (2,), frame rate [rad/s]): ``1/2 v^T dM v - g_1 rhoA U0``."""
        dM_0q, dM_12, dM_22, dM_2q, dM_qq = (v[0] for v in self.mass_delta(q[None, :]))
        v0, v1 = velocity_frame
        kinetic = (v0 * (dM_0q @ qd) + v1 * omega * dM_12 + 0.5 * omega * omega * dM_22
                   + omega * (dM_2q @ qd) + 0.5 * qd @ dM_qq @ qd)
        return float(kinetic - gravity_frame[0] * dM_12)


__all__ = ["SecondOrderInertia", "check_second_order"]
