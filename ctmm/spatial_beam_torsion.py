"""Bars of a spatial beam field (axial, torsion): closed form, the Wagner term, and a varying coefficient.

A bar is ``[y ; f]' = [[0, -1/K(x)], [-q, 0]] [y ; f]`` over ``0 <= x <= L`` (``y`` the displacement or
twist, ``f`` the force or moment exerted by the inboard on the outboard part, ``K`` the stiffness [N] or
[N m^2], ``q = rho s^2 + c s`` the inertia term).

**Wagner term (torsion under tension).**  A doubly symmetric section (shear centre at the centroid)
twisted by ``theta(x)`` moves the fibre at ``(y, z)`` by ``v = -z theta``, ``w = y theta``; its
Green-Lagrange axial strain gains ``1/2 (v'^2 + w'^2) = 1/2 r^2 theta'^2`` (``r^2 = y^2 + z^2``).  The
initial axial stress ``sigma_0 = T / A`` does work on it: the second-order strain energy per length is
``int_A sigma_0 1/2 r^2 theta'^2 dA = 1/2 (T I_p / A) theta'^2`` with ``I_p = I_y + I_z`` the section's
polar second moment about the shear centre (the terms linear in ``y``, ``z`` integrate to zero on a
doubly symmetric section; bending-twist coupling of unsymmetric sections is not modelled).  With Saint-
Venant's ``1/2 GJ theta'^2`` the torsion bar's stiffness is ``K = GJ + T I_p / A`` (the twisting moment
at a cut is ``-K theta'``, the torsional inertia ``rho I_p s^2`` is unchanged).  Section data needed:
``I_p / A`` [m^2]; for a homogeneous section it is ``polar_inertia_per_length / mass_per_length``
(``rho I_p / rho A``), so no new parameter is needed.  ``K <= 0`` (compression beyond
``T = -GJ A / I_p``) is torsional buckling: refused.

**Varying coefficient.**  A tension varying linearly along the bar makes ``K(x)`` linear in ``x``; the
field matrix is integrated by the sixth-order Magnus method with three Gauss points (Blanes, Casas,
Oteo, Ros, Phys. Rep. 470 (2009) 151): per sub-step ``h`` with ``A_1, A_2, A_3`` at the Gauss points,
``a_1 = h A_2``, ``a_2 = sqrt(15) h (A_3 - A_1) / 3``, ``a_3 = 10 h (A_3 - 2 A_2 + A_1) / 3``,
``C_1 = [a_1, a_2]``, ``C_2 = -[a_1, 2 a_3 + C_1] / 60``, ``Omega = a_1 + a_3 / 12 + [-20 a_1 - a_3 +
C_1, a_2 + C_2] / 240``.  ``Omega`` is traceless 2 x 2, so ``expm(Omega) = cosh(w) I + sinh(w)/w Omega``
(``w^2 = -det Omega``) has determinant 1 (symplectic: reciprocity to round-off).  Error control as
:mod:`ctmm.elements.bending_preload`: ``m`` and ``2 m`` sub-steps, the difference of the dimensionless
matrices (``diag(1, K_ref / L)``) over 63 at most ``tolerance`` of ``max(1, |U|)``.

``clamped_bar_count`` (Wittrick-Williams ``J0``): constant ``K``: ``n pi / L sqrt(K / rho)``, ``n >= 1``;
varying ``K``: the bar cut into pieces whose clamped-clamped frequencies all lie above ``omega`` (by the
min-max principle above ``pi / l sqrt(K_min / rho)``), and the Sturm count of the interior nodes' dynamic
stiffness.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .errors import ModelError

__all__ = ["cosh_sinhc", "bar_matrix", "varying_bar_matrix", "clamped_bar_count", "MAX_SUB_STEPS"]

#: Most Magnus sub-steps of one varying bar before it is refused.
MAX_SUB_STEPS = 512
#: Largest wave number ``omega h sqrt(rho / K_min)`` of one Magnus sub-step at the first attempt.
_STEP_LIMIT = 0.25
#: Largest wave number of a piece of the clamped count (below ``pi``: no clamped frequency of the piece).
_COUNT_LIMIT = 3.0


def cosh_sinhc(z2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``cosh z`` and ``sinh z / z`` from ``z^2`` (both even in ``z``; Taylor series for small ``|z|``)."""
    z2 = np.asarray(z2)
    z = np.sqrt(z2.astype(complex))
    small = np.abs(z) < 1e-3
    zs = np.where(small, 1.0, z)
    cosh = np.where(small, 1 + z2 / 2 + z2 * z2 / 24, np.cosh(zs))
    sinhc = np.where(small, 1 + z2 / 6 + z2 * z2 / 120, np.sinh(zs) / zs)
    return cosh, sinhc


def bar_matrix(length: float, stiffness: np.ndarray, inertia_term: np.ndarray) -> np.ndarray:
    """Field matrix ``(..., 2, 2)`` of a uniform bar, ``K`` = ``stiffness``, ``q`` = ``inertia_term`` (module docstring)."""
    ch, shc = cosh_sinhc(inertia_term / stiffness * length * length)
    U = np.empty(np.shape(ch) + (2, 2), dtype=complex)
    U[..., 0, 0] = U[..., 1, 1] = ch
    U[..., 0, 1] = -length * shc / stiffness
    U[..., 1, 0] = -inertia_term * length * shc
    return U


def _magnus(length: float, stiffness_in: np.ndarray, stiffness_out: np.ndarray, inertia_term: np.ndarray,
            reference: float, steps: int) -> np.ndarray:
    """``steps`` Magnus sub-steps (all arrays of one shape ``(B,)``); dimensionless matrices
    ``diag(1, reference / L)^-1 U diag(...)``."""
    h = length / steps
    nodes = np.array([0.5 - math.sqrt(15.0) / 10.0, 0.5, 0.5 + math.sqrt(15.0) / 10.0])
    x = (np.arange(steps)[:, None] + nodes[None, :]) / steps                   # (steps, 3) in [0, 1]
    K = stiffness_in + (stiffness_out - stiffness_in) * x[..., None]           # (steps, 3, B)
    A = np.zeros((steps, 3) + inertia_term.shape + (2, 2), dtype=complex)      # h D_h^-1 A D_h
    A[..., 0, 1] = -reference / K
    A[..., 1, 0] = -inertia_term * h * h / reference
    A1, A2, A3 = A[:, 0], A[:, 1], A[:, 2]
    a1, a2, a3 = A2, math.sqrt(15.0) / 3.0 * (A3 - A1), 10.0 / 3.0 * (A3 - 2.0 * A2 + A1)
    c1 = _bracket(a1, a2)
    c2 = -_bracket(a1, 2.0 * a3 + c1) / 60.0
    omega = a1 + a3 / 12.0 + _bracket(-20.0 * a1 - a3 + c1, a2 + c2) / 240.0
    ch, shc = cosh_sinhc(omega[..., 0, 0] ** 2 + omega[..., 0, 1] * omega[..., 1, 0])
    E = shc[..., None, None] * omega
    E[..., 0, 0] += ch
    E[..., 1, 1] += ch
    U = E[0]
    for step in range(1, steps):                                               # D_h^-1 U D_h: same D per step
        U = E[step] @ U
    U = U.copy()
    U[..., 0, 1] /= steps                                                      # diag(1, ref/h) -> diag(1, ref/L)
    U[..., 1, 0] *= steps
    return U


def _bracket(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    return X @ Y - Y @ X


def varying_bar_matrix(name: str, length: float, stiffness_in: Any, stiffness_out: Any,
                       inertia_term: np.ndarray, tolerance: float) -> np.ndarray:
    """Error-controlled field matrix ``(..., 2, 2)`` of a bar whose stiffness goes linearly from
    ``stiffness_in`` to ``stiffness_out`` (module docstring; numbers, or arrays of ``inertia_term``'s shape
    for a stiffness that depends on ``s``).

    Raises
    ------
    ModelError
        If :data:`MAX_SUB_STEPS` sub-steps do not reach ``tolerance`` (naming ``name``).
    """
    shape = np.shape(inertia_term)
    q = np.asarray(inertia_term, dtype=complex).reshape(-1)
    stiffness_in = np.broadcast_to(np.asarray(stiffness_in, dtype=complex), shape).reshape(-1)
    stiffness_out = np.broadcast_to(np.asarray(stiffness_out, dtype=complex), shape).reshape(-1)
    if q.size == 0:
        return np.broadcast_to(np.eye(2, dtype=complex), shape + (2, 2)).copy()
    reference = float(max(np.max(np.abs(stiffness_in)), np.max(np.abs(stiffness_out))))
    softest = float(min(np.min(np.abs(stiffness_in)), np.min(np.abs(stiffness_out))))
    wave = float(np.sqrt(np.max(np.abs(q), initial=0.0) / softest)) * length
    steps = max(2, math.ceil(wave / _STEP_LIMIT))
    if 2 * steps > MAX_SUB_STEPS:
        raise ModelError(f"{name}: the torsion bar's wave number is {wave:.3g}: more than {MAX_SUB_STEPS} Magnus "
                         "sub-steps; split the field")
    scale = np.array([[1.0, length / reference], [reference / length, 1.0]])   # D_L U_hat D_L^-1
    coarse = _magnus(length, stiffness_in, stiffness_out, q, reference, steps)
    while True:
        fine = _magnus(length, stiffness_in, stiffness_out, q, reference, 2 * steps)
        error = float(np.max(np.abs(fine - coarse), initial=0.0)) / 63.0
        size = max(1.0, float(np.max(np.abs(fine), initial=0.0)))
        if error <= tolerance * size:
            return (fine * scale).reshape(shape + (2, 2))
        if 2 * steps >= MAX_SUB_STEPS:
            raise ModelError(f"{name}: the varying torsion bar reaches an estimated relative error {error / size:.2e} "
                             f"> tolerance {tolerance:.1e} with {2 * steps} sub-steps; split the field (split(n))")
        steps, coarse = 2 * steps, fine


def clamped_bar_count(length: float, stiffness_in: float, stiffness_out: float, density: float,
                      omega: np.ndarray, tolerance: float = 1e-11) -> np.ndarray:
    """Clamped-clamped natural frequencies of the undamped bar strictly below ``omega`` [rad/s] (``J0``).

    ``stiffness_in``, ``stiffness_out`` > 0 at the two ends (equal: the closed form); ``density``: the
    inertia per length (``rho A`` or ``rho I_p``).  Module docstring for the method.
    """
    omega = np.asarray(omega, dtype=float)
    if stiffness_in == stiffness_out:
        x = omega * length / (math.pi * math.sqrt(stiffness_in / density))
        return np.maximum(np.ceil(x) - 1, 0).astype(np.int64)
    flat = omega.reshape(-1)
    softest = min(stiffness_in, stiffness_out)
    pieces = max(1, math.ceil(float(np.max(flat, initial=0.0)) * length * math.sqrt(density / softest) / _COUNT_LIMIT))
    if pieces == 1:
        return np.zeros(omega.shape, dtype=np.int64)
    edges = np.linspace(stiffness_in, stiffness_out, pieces + 1)
    q = -density * flat * flat
    G = np.zeros((flat.size, pieces - 1, pieces - 1))
    for k in range(pieces):
        U = np.real(varying_bar_matrix("clamped count", length / pieces, float(edges[k]), float(edges[k + 1]),
                                       q.astype(complex), tolerance))
        inverse = 1.0 / U[:, 0, 1]                       # dynamic stiffness of the piece, end forces on it
        k_in, k_cross, k_out = -inverse * U[:, 0, 0], inverse, -U[:, 1, 1] * inverse
        if k > 0:
            G[:, k - 1, k - 1] += k_in
        if k < pieces - 1:
            G[:, k, k] += k_out
            if k > 0:
                G[:, k - 1, k] += k_cross
                G[:, k, k - 1] += k_cross
    return np.sum(np.linalg.eigvalsh(G) < 0, axis=-1).astype(np.int64).reshape(omega.shape)
