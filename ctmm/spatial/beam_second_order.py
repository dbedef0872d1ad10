"""Second-order (foreshortening) inertia of the modal spatial beam (``SpatialBeam(second_order_inertia=True)``).

The spatial counterpart of :mod:`ctmm.flexible.second_order` (``docs/spatial_modal_beam.md`` §2c).  An axially rigid
bent beam keeps the length of its axis: the mass point at abscissa ``x`` sits at

``rho = rho1 + e1 u``,  ``rho1 = [x, 0, 0] + Phi eta``,  ``u(x) = -1/2 eta^T G1(x) eta``,
``G1(x) = int_0^x (w_y' w_y'^T + w_z' w_z'^T)``

in the floating frame.  The first-order beam keeps ``u = 0`` in its mass points and adds only the geometric stiffness
of the axial inertia and weight (:mod:`ctmm.spatial.beam_terms`).  With ``u`` in every mass point the body is the exact
Newton-Euler / virtual-work statement of this kinematics (``delta rho = Phi_u delta eta``, ``Phi_u = Phi - e1 eta^T
G1``), whose difference to the first-order terms with stiffening is, in frame axes about the root (integrals of
``rhoA dx``; ``Om2 = omega omega^T - |omega|^2 I``)::

    ds = e1 rhoA U0,  U0 = int u dx = -1/2 eta^T G2 eta
    dM[lin, ang] = -[ds]x,  dM[ang, lin] = [ds]x,  dM[lin, mod] = -e1 rhoA (G2 eta)^T
    dM[ang, ang] = tr(dS) I - dS,  dS = m_u e1^T + e1 m_u^T + e1 e1^T int rhoA u^2,  m_u = int rhoA u rho1
    dM[ang, mod] = dM[mod, ang]^T = [e1]x (Z + X),  Z = int rhoA u Phi,  X = int rhoA rho1 eta^T G1
    dM[mod, mod] = rhoA H(., eta, ., eta)
    dh_lin = omega x (omega x ds) - 2 rhoA (eta^T G2 eta_dot) omega x e1 - e1 rhoA eta_dot^T G2 eta_dot
    dh_ang = omega x (dJ omega) + 2 (omega tr dP - dP^T omega) + e1 x X_d - rhoA U0 e1 x (g + q / rhoA)
        dP = int rhoA rho rho_dot^T - (first order) = -(X eta_dot) e1^T + e1 (Z eta_dot)^T + e1 e1^T int rhoA u u_dot
        X_d = int rhoA rho1 eta_dot^T G1 eta_dot
    dh_mod = (Z - X_perp)^T Om2 e1 + 1/2 Om2_11 rhoA H(., eta, eta, eta) + 2 (X_rate - Z_rate)^T (omega x e1)
             + rhoA H(., eta, eta_dot, eta_dot)

with ``X_perp`` the rows ``y, z`` of ``X`` (its row ``x`` is the first-order stiffening's ``G3`` term), ``Z_rate =
int rhoA Phi (eta^T G1 eta_dot)`` and ``X_rate = int rhoA (G1 eta) (Phi eta_dot)^T`` transposed.  All are
polynomials in ``eta`` with the constant tensors (built once by :class:`SecondOrderTensors`)

``T_r[k, i, j] = int Phi_rk G1_ij`` (``r = y, z``),  ``H_ijkl = int G1_ij G1_kl``,  ``G2 = int G1``,  ``G3 = int x G1``.

Restricted to a plane every term is the planar ``ModalBeam(second_order_inertia=True)``'s.  The points (children,
point loads, body-axis forces) move with the shortening too, as on the planar beam (:mod:`ctmm.flexible.point_terms`):
``rho_e = rho1_e + e1 u(x_e)``, ``Kin_e[lin, mod] = Phi_u(x_e) = Phi_e - e1 (G1(x_e) eta)^T``, the rate term
``-e1 eta_dot^T G1(x_e) eta_dot`` in ``c_e`` and ``RF_e = Kin_e^T`` (virtual work; it holds the axial force's
``-f_1 G1(x_e) eta``), stated in :func:`ctmm.spatial.beam_terms.spatial_beam_terms`; the point sensors
(:func:`ctmm.spatial.beam_ports.deformed_point`) report the shortened point too.
Not covered: axial modes (the extensible beam's shortening belongs to its axial strain) -- refused by
:func:`ctmm.flexible.second_order.check_second_order` (the planar option's refusals, same attributes).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..flexible.modes import gauss_points
from ..ops import Ops
from .frames import constant, cross, entry, skew

__all__ = ["SecondOrderTensors", "second_order_deltas"]

_E1 = np.array([1.0, 0.0, 0.0])


class SecondOrderTensors:
    """Constant tensors of the second-order inertia of one spatial beam.

    Parameters
    ----------
    data : SpatialBeamData
        The beam's modal integrals (its ``shapes``, ``slopes``, ``columns``, ``rhoA``, ``L``, ``G2``, ``G3``).
    quadrature : int
        Gauss-Legendre points on ``[0, L]`` and on each ``[0, x]`` of ``G1(x)``.

    Attributes
    ----------
    T : (3, n, n, n) array
        ``T[r, k, i, j] = int Phi_rk G1_ij`` [m] (row ``r = 0`` is zero: no axial modes).
    H_pairs : (n * n, n * n) array
        ``H_ijkl = int G1_ij G1_kl`` [1/m] arranged ``[(i, k), (j, l)]``: ``vec H(., a, ., b) = H_pairs (a kron b)``.
    """

    def __init__(self, data: Any, quadrature: int) -> None:
        n = data.n
        x, w = gauss_points(quadrature, data.L)
        inner, inner_w = gauss_points(quadrature, 1.0)
        slopes = data.slopes(np.outer(x, inner).ravel()).reshape(n, len(x), len(inner))
        mask = np.zeros((n, n))
        for plane in ("y", "z"):
            mask[data.columns[plane], data.columns[plane]] = 1.0
        G1 = np.einsum("ipq,jpq,pq->pij", slopes, slopes, np.outer(x, inner_w)) * mask     # (P, n, n) [1/m]
        Phi = data.shapes(x)                                                                 # (3, n, P)
        self.n = n
        self.T = np.einsum("p,rkp,pij->rkij", w, Phi, G1)
        H = np.einsum("p,pij,pkl->ijkl", w, G1, G1)
        self.H_pairs = H.transpose(0, 2, 1, 3).reshape(n * n, n * n)


def _pair(ops: Ops, a: Any, b: Any, n: int) -> Any:
    """``a kron b`` (n^2 x 1): entry ``j n + l`` is ``a_j b_l``."""
    return ops.block([[b * entry(ops, a, j)] for j in range(n)])


def _square(ops: Ops, vector: Any, n: int) -> Any:
    """The n x n matrix whose row ``i`` is entries ``i n .. i n + n - 1`` of ``vector`` (n^2 x 1)."""
    return ops.block([[ops.transpose(ops.sub(vector, slice(i * n, (i + 1) * n), slice(0, 1)))] for i in range(n)])


def _contract(ops: Ops, tensor: np.ndarray, v: Any, axis: int) -> Any:
    """``sum_m v_m tensor[..., m, ...]`` over ``axis`` (0 or 2) of a constant (n, n, n) tensor: an n x n ops value."""
    total = None
    for m in range(tensor.shape[axis]):
        part = constant(ops, np.take(tensor, m, axis=axis)) * entry(ops, v, m)
        total = part if total is None else total + part
    return total


def _dot(ops: Ops, a: Any, b: Any) -> Any:
    return ops.matmul(ops.transpose(a), b)


def _rows(ops: Ops, rows: list, n: int) -> Any:
    """3 x n from the row-``y`` and row-``z`` columns (n x 1); row ``x`` zero."""
    return ops.block([[ops.zeros(1, n)], [ops.transpose(rows[0])], [ops.transpose(rows[1])]])


def second_order_deltas(ops: Ops, data: Any, *, omega: Any, gravity: Any, load: Any, eta: Any,
                        eta_dot: Any) -> tuple[Any, Any]:
    """``(dM (6 + n, 6 + n), dh (6 + n, 1))``: the second-order terms (module docstring) added to the first-order
    body terms with stiffening, frame axes, about the root.

    Parameters
    ----------
    ops : Ops
    data : SpatialBeamData
        With ``data.second_order`` a :class:`SecondOrderTensors`.
    omega, gravity, load : ops (3, 1)
        Frame angular velocity [rad/s], gravity [m/s^2] and distributed follower load [N/m], frame axes.
    eta, eta_dot : ops (n, 1)
        Modal coordinates and rates.
    """
    # mass per length as the data's mass over length: the mass-scaled views of the parametrised kernels
    # (ctmm.compiled_spatial_beam_numbers) scale these terms with the rest of the mass integrals
    tensors, n, r = data.second_order, data.n, data.m / data.L
    G2, G3 = constant(ops, data.G2), constant(ops, data.G3)
    e1 = constant(ops, _E1)
    G2e = ops.matmul(G2, eta)
    U0 = _dot(ops, eta, G2e) * -0.5
    U1 = _dot(ops, eta, ops.matmul(G3, eta)) * -0.5
    X, Z, Z_rate, X_rate, Y, X_d = [], [], [], [], [], []
    for row in (1, 2):
        T = tensors.T[row]
        A_eta, B_eta = _contract(ops, T, eta, 0), _contract(ops, T, eta, 2)          # T(eta, ., .), T(., ., eta)
        A_rate, B_rate = _contract(ops, T, eta_dot, 0), _contract(ops, T, eta_dot, 2)
        X.append(ops.matmul(A_eta, eta) * r)                 # T(eta; ., eta)
        z = ops.matmul(B_eta, eta) * (-0.5 * r)              # -1/2 T(.; eta, eta)
        Z.append(z)
        Y.append(_dot(ops, z, eta))                          # int rhoA u Phi_r eta
        Z_rate.append(ops.matmul(B_rate, eta) * r)           # T(.; eta, eta_dot)
        X_rate.append(ops.matmul(A_rate, eta) * r)           # T(eta_dot; ., eta)
        X_d.append(_dot(ops, eta, ops.matmul(B_rate, eta_dot)) * r)     # T(eta; eta_dot, eta_dot)
    X_perp, Z_m = _rows(ops, X, n), _rows(ops, Z, n)
    Z_rate_m, X_rate_m = _rows(ops, Z_rate, n), _rows(ops, X_rate, n)
    X_full = X_perp + ops.matmul(e1, ops.transpose(ops.matmul(G3, eta))) * r
    H_pairs = constant(ops, tensors.H_pairs)
    HH = _square(ops, ops.matmul(H_pairs, _pair(ops, eta, eta, n)), n)                    # H(., eta, ., eta)
    H3 = ops.matmul(HH, eta)                                                             # H(., eta, eta, eta)
    H_rate = ops.matmul(_square(ops, ops.matmul(H_pairs, _pair(ops, eta, eta_dot, n)), n), eta_dot)
    # mass matrix
    ds = e1 * (U0 * r)
    ds_x = skew(ops, ds)
    m_u = ops.block([[U1 * r], [Y[0]], [Y[1]]])
    dS = ops.matmul(m_u, ops.transpose(e1)) + ops.matmul(e1, ops.transpose(m_u)) + ops.matmul(
        e1, ops.transpose(e1)) * (_dot(ops, eta, H3) * (0.25 * r))
    dJ = ops.eye(3) * (entry(ops, dS, 0, 0) + entry(ops, dS, 1, 1) + entry(ops, dS, 2, 2)) - dS
    dGamma = ops.matmul(skew(ops, e1), Z_m + X_perp)
    dM = ops.block([[ops.zeros(3, 3), ds_x * -1.0, ops.matmul(e1, ops.transpose(G2e)) * -r],
                    [ds_x, dJ, dGamma],
                    [ops.zeros(n, 3), ops.transpose(dGamma), HH * r]])
    # velocity, gravity and load terms
    w = omega
    w_parts = [entry(ops, w, i) for i in range(3)]
    w_e1 = cross(ops, w, e1)
    Om2_e1 = w * w_parts[0] - e1 * (w_parts[0] * w_parts[0] + w_parts[1] * w_parts[1] + w_parts[2] * w_parts[2])
    dh_lin = (cross(ops, w, cross(ops, w, ds)) + w_e1 * (_dot(ops, eta, ops.matmul(G2, eta_dot)) * (-2.0 * r))
              - e1 * (_dot(ops, eta_dot, ops.matmul(G2, eta_dot)) * r))
    u_rate = _dot(ops, eta_dot, H3) * (0.5 * r)             # int rhoA u u_dot
    dP = (ops.matmul(ops.matmul(X_full, eta_dot), ops.transpose(e1)) * -1.0
          + ops.matmul(e1, ops.transpose(ops.matmul(Z_m, eta_dot))) + ops.matmul(e1, ops.transpose(e1)) * u_rate)
    trace_dP = entry(ops, dP, 0, 0) + entry(ops, dP, 1, 1) + entry(ops, dP, 2, 2)
    X_dv = ops.block([[_dot(ops, eta_dot, ops.matmul(G3, eta_dot)) * r], [X_d[0]], [X_d[1]]])
    dh_ang = (cross(ops, w, ops.matmul(dJ, w)) + (w * trace_dP - ops.matmul(ops.transpose(dP), w)) * 2.0
              + cross(ops, e1, X_dv) - cross(ops, e1, gravity * r + load) * U0)
    dh_mod = (ops.matmul(ops.transpose(Z_m - X_perp), Om2_e1)
              - H3 * ((w_parts[1] * w_parts[1] + w_parts[2] * w_parts[2]) * (0.5 * r))
              + ops.matmul(ops.transpose(X_rate_m - Z_rate_m), w_e1) * 2.0 + H_rate * r)
    return dM, ops.block([[dh_lin], [dh_ang], [dh_mod]])
