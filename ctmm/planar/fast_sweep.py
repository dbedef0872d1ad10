"""The registered fast path of the one articulated sweep: rigid revolute trees on Python floats.

:func:`riccati_kernel` is :func:`ctmm.articulated.articulated_sweep` specialised by hand to planar
rigid bodies (``d = 3``, ``n = 0``) whose joints are revolute (``S = e3``, with the joint tangent
``kappa``), driven (prescribed relative acceleration) or a free base at the ground (``S = I3``,
``tau = 0``), written on Python floats: one small block per body and no numpy call per body.  It
exists only for speed and is registered as such (``docs/architecture.md`` section 4): the generic
sweep on numpy is slower per sweep at ``B = 1`` than the Python floats by the measured factors in
``docs/planar.md`` section 8a (explicit accelerations of ``benchmarks/planar_chain.py`` chains
and implicit Newton steps).  Everything else -- translational-spring hinges, modal beams, batches,
complex steps, the frequency context, symbols -- is the generic sweep.

Guard: ``tests/test_forms_contract.py::test_same_recursion_as_the_planar_riccati_kernel_with_joint_tangents``
(equal to the one sweep on the same terms with arbitrary ``kappa`` to 1e-12); its explicit numbers
are also gated against the independent Lagrange model (``tests/test_planar_sweep.py``).

Notation (one body ``j``, inboard end ``I``, outboard end ``O`` where child ``c`` hangs):

* kinematics, rigid body I -> O:   ``A_O = X A_I + c``,
  ``X = [[1, 0, -r_y], [0, 1, r_x], [0, 0, 1]]``, ``c = [-w^2 r_x, -w^2 r_y, 0]``,
  ``r = R(theta) (O - I)``;
* Newton-Euler of the body about ``I`` (all loads moved to ``I`` by ``X^T``):
  ``F_I = K A_I + b + sum_c X_c^T F_Oc``;
* hinge ``c``: ``A_c = A_O + e3 alpha``, law ``tau_c = e3^T F_c = tau_tilde - kappa alpha``
  (``kappa = 0`` explicit); driven: ``alpha`` given.

Riccati form ``F = Phi A + psi`` from the tips to the base (FORMULAS 4.3): ``D = Phi_22 + kappa``,
``Phi_hat = Phi - Phi[:, 2] Phi[2, :] / D``, ``psi_hat = psi + Phi[:, 2] (tau_tilde - psi_2) / D``,
moved to the parent's inboard point with ``X_c^T (.) X_c``.  Base to tips:
``alpha = (tau_tilde - Phi[2, :] A_O - psi_2) / D``, ``A_c = A_O + e3 alpha``, ``F_c = Phi A_c + psi``.
``Phi`` may be non-symmetric (the Newton tangent of :mod:`ctmm.planar.implicit` changes the third
column of ``X`` and ``K``).
"""
from __future__ import annotations

import numpy as np

from ..errors import SimulationError
from .model import DRIVEN, FREE, REVOLUTE

__all__ = ["riccati_kernel"]


def riccati_kernel(parent: list, kind: list, K: list, b: list, E: list, kappa: list,
                   tau: list, alpha_driven: list, want_forces: bool = True):
    """Tip-to-base Riccati sweep and base-to-tip pass (pure Python floats, O(n)).

    Parameters
    ----------
    parent, kind : list of int
        Parent body (-1: ground) and joint kind (``REVOLUTE``, ``DRIVEN``, ``FREE`` at the ground)
        of each body, in topological order.
    K : list of 9 floats per body
        Inertia about the inboard point (row-major 3 x 3) [kg, kg m, kg m^2].
    b : list of 3 floats per body
        Velocity, gravity and load terms [N, N m].
    E : list of 6 floats per body
        ``(kx, ky, lx, ly, cx, cy)`` of the parent point carrying the body (kinematic third column
        of ``X``, lever row of ``X^T``, velocity term ``c``), :func:`ctmm.planar.sweep.body_terms`.
    kappa : list of float
        Joint tangent of revolute joints [N m s^2/rad] (0: explicit).
    tau : list of float
        ``tau_tilde`` of revolute joints [N m].
    alpha_driven : list of float
        Prescribed relative angular acceleration of driven joints [rad/s^2].
    want_forces : bool
        Also return the joint forces.

    Returns
    -------
    A, F : list of (float, float, float)
        Body accelerations at the inboard ends [m/s^2, rad/s^2] and joint forces [N, N m]
        (``F`` is ``None`` unless ``want_forces``).
    alpha : list of float
        Relative hinge accelerations [rad/s^2].

    Raises
    ------
    SimulationError
        A singular articulated inertia of a hinge (naming its index).
    """
    nb = len(parent)
    acc = [list(row) for row in K]
    accb = [list(row) for row in b]
    denominators = [0.0] * nb
    for j in range(nb - 1, -1, -1):
        p00, p01, p02, p10, p11, p12, p20, p21, p22 = acc[j]
        s0, s1, s2 = accb[j]
        kj = kind[j]
        if kj == REVOLUTE:
            d = p22 + kappa[j]
            if not (d != 0.0 and abs(d) < float("inf")):
                raise SimulationError(f"articulated inertia of hinge {j} is singular ({d!r})")
            denominators[j] = d
            r = (tau[j] - s2) / d
            f0, f1, f2 = p02 / d, p12 / d, p22 / d
            q00, q01, q02 = p00 - f0 * p20, p01 - f0 * p21, p02 - f0 * p22
            q10, q11, q12 = p10 - f1 * p20, p11 - f1 * p21, p12 - f1 * p22
            q20, q21, q22 = p20 - f2 * p20, p21 - f2 * p21, p22 - f2 * p22
            t0, t1, t2 = s0 + p02 * r, s1 + p12 * r, s2 + p22 * r
        elif kj == DRIVEN:
            ad = alpha_driven[j]
            q00, q01, q02, q10, q11, q12, q20, q21, q22 = p00, p01, p02, p10, p11, p12, p20, p21, p22
            t0, t1, t2 = s0 + p02 * ad, s1 + p12 * ad, s2 + p22 * ad
        else:
            continue
        par = parent[j]
        if par < 0:
            continue
        kx, ky, lx, ly, cx, cy = E[j]
        z0 = q00 * cx + q01 * cy + t0
        z1 = q10 * cx + q11 * cy + t1
        z2 = q20 * cx + q21 * cy + t2
        c02 = kx * q00 + ky * q01 + q02
        c12 = kx * q10 + ky * q11 + q12
        c22 = kx * q20 + ky * q21 + q22
        a = acc[par]
        a[0] += q00
        a[1] += q01
        a[2] += c02
        a[3] += q10
        a[4] += q11
        a[5] += c12
        a[6] += lx * q00 + ly * q10 + q20
        a[7] += lx * q01 + ly * q11 + q21
        a[8] += lx * c02 + ly * c12 + c22
        bb = accb[par]
        bb[0] += z0
        bb[1] += z1
        bb[2] += lx * z0 + ly * z1 + z2
    A = [None] * nb
    F = [None] * nb
    alpha = [0.0] * nb
    for j in range(nb):
        par = parent[j]
        if par >= 0:
            a0, a1, al = A[par]
            kx, ky, lx, ly, cx, cy = E[j]
            o0, o1, o2 = a0 + kx * al + cx, a1 + ky * al + cy, al
        else:
            o0 = o1 = o2 = 0.0
        p00, p01, p02, p10, p11, p12, p20, p21, p22 = acc[j]
        s0, s1, s2 = accb[j]
        kj = kind[j]
        if kj == REVOLUTE:
            al = (tau[j] - p20 * o0 - p21 * o1 - p22 * o2 - s2) / denominators[j]
            a_j = (o0, o1, o2 + al)
        elif kj == DRIVEN:
            al = alpha_driven[j]
            a_j = (o0, o1, o2 + al)
        elif kj == FREE and par < 0:
            sol = np.linalg.solve(np.array(acc[j]).reshape(3, 3), -np.array(accb[j]))
            a_j = (float(sol[0]), float(sol[1]), float(sol[2]))
            al = a_j[2]
        else:
            raise SimulationError(f"riccati_kernel: joint kind {kj} of body {j} is not on the fast path "
                                  "(rigid revolute, driven and free-base trees only; use ctmm.articulated)")
        alpha[j] = al
        A[j] = a_j
        if want_forces:
            x0, x1, x2 = a_j
            F[j] = (p00 * x0 + p01 * x1 + p02 * x2 + s0,
                    p10 * x0 + p11 * x1 + p12 * x2 + s1,
                    p20 * x0 + p21 * x1 + p22 * x2 + s2)
    return A, (F if want_forces else None), alpha
