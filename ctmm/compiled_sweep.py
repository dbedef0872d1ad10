"""The articulated sweep's frequency context of rigid trees as one compiled C kernel over bodies and frequencies.

:func:`ctmm.articulated.articulated_sweep` is written once for every context on :mod:`ctmm.ops`; on numpy its
per-body work is a few dozen calls on ``(B, d, d)`` batches, whose call overhead dominates.  For the frequency
context of trees whose bodies are rigid (``d`` unknowns each) and whose joints are welds, drives held at zero or
one free direction -- a unit axis (``JointTerms.axis``: planar hinges) or a column ``S`` (``d = 6``: spatial
revolute and prismatic joints) -- :class:`CompiledSweep` runs the same recursion frequency by frequency in C
(:data:`KERNEL_C`), every load case at once (joints of more directions: universal, spherical, free, are not taken):

Tip to base, body ``j`` with ``P = Z_j + sum_children RF Phi_hat Kin``, ``p = h_j + sum_children RF psi_hat``:
joint on ``S`` (unit axis ``a``: row and column ``a`` of ``P``, no products): ``D = S^T P S + kappa``,
``w = (S^T P + G) / D``, ``r = (tau - S^T p) / D``, ``Phi_hat = P - (P S + H) w``, ``psi_hat = p + (P S + H) r``;
weld or held drive: ``Phi_hat = P``, ``psi_hat = p``.  Base to tip: ``A_O = Kin_e x_parent`` (ground 0),
``a = r - w . A_O``, ``x = A_O + S a``.

Both certificates of :mod:`ctmm.sweep_response` are decided in the kernel, per frequency: every pivot against
its terms (``|D| >= PIVOT_TOLERANCE (|s^2 m| + |D - s^2 m|)``, ``m`` the same pivot of the mass terms alone,
:func:`mass_pivots`) and the answer's a-posteriori backward error (the joint residuals of
``F_j = Z_j x_j + h_j + sum_children RF_c (F_c + H_c a_c)`` against the moduli of their terms, at most
``RESIDUAL_TOLERANCE``); a non-finite answer is not certified either.  Frequencies not certified are the
callers' (the dense resolvent), exactly as for the generic sweep.

The kernel is data-driven: the topology (parents, axes), the terms ``M0, C0, K0``, the point maps ``Kin, RF``,
the coupling ``G, H``, the joint laws, loads and frequencies are its arguments, so its code does not depend on
the model; it is compiled once per variant -- the point dimension ``d`` (a constant of the code) and the scalar
type -- and cached on disk by a hash of its text (:func:`ctmm.codegen.load_ctypes`).  Typed: the body terms,
point maps, coupling, body loads and mass pivots are ``double``; the Laplace variables, ``s^2``, the joint
laws and torques, the pivots and the answers are the variant's scalar: ``double`` (undamped terms on the
imaginary axis, real laws and loads: ``s^2 = -omega^2`` real, the same numbers as complex arithmetic) or C99
``double _Complex`` (damped or delayed terms; built with ``-fcx-fortran-rules``: products without the
NaN-recovery calls, quotients with range reduction; an overflow still shows as a non-finite answer, which is
not certified).

The recursion is written out here a second time beside the generic sweep (a hand-written C body, not traced
from :mod:`ctmm.ops`: casadi's symbols are real, and its traced step would not hold the complex variant); its
answers are checked against the generic sweep to round-off in ``tests/test_compiled_sweep.py``.  Without a C
compiler (:func:`ctmm.codegen.find_compiler`) the callers take the generic sweep; a compiler that fails to build
the kernel (:class:`~ctmm.errors.ModelError` from :func:`kernel_library`) is warned about by
:class:`ctmm.sweep_response.ArticulatedResponse`, and the generic sweep answers there too.
"""
from __future__ import annotations

import ctypes
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .articulated import Tree
from .codegen import find_compiler, load_ctypes
from .errors import ModelError

__all__ = ["COMPLEX_FLAGS", "CompiledSweep", "KERNEL_C", "LOAD_CASES", "REAL_FLAGS", "SweepAnswer", "applies",
           "compiler_present", "kernel_library", "kernel_source", "mass_pivots", "one_direction"]

KERNEL_C = r"""
#include <math.h>
#include <stdlib.h>
#include <complex.h>
#define DIM __DIM__
#if __COMPLEX__
typedef double _Complex scalar;
#define MODULUS(z) cabs(z)
#define FINITE(z) (isfinite(creal(z)) && isfinite(cimag(z)))
#else
typedef double scalar;
#define MODULUS(z) fabs(z)
#define FINITE(z) isfinite(z)
#endif

/* A free joint's row = S^T P, column = P S and D = S^T P S (type T): a unit axis a >= 0 takes row and column a of
   P, a general direction (a = -2; variants with __GENERAL__ only) the products with its column u = S (DIM). */
#define UNIT(a) (!__GENERAL__ || (a) >= 0)
#define PROJECT(T, P, a, u, row, column, D) do { \
    for (int k_ = 0; k_ < DIM; ++k_) { \
        T r_ = 0.0, c_ = 0.0; \
        if (UNIT(a)) { r_ = P[a][k_]; c_ = P[k_][a]; } \
        else for (int i_ = 0; i_ < DIM; ++i_) { r_ += (u)[i_] * P[i_][k_]; c_ += P[k_][i_] * (u)[i_]; } \
        row[k_] = r_; column[k_] = c_; \
    } \
    D = UNIT(a) ? P[a][a] : 0.0; \
    if (!UNIT(a)) for (int k_ = 0; k_ < DIM; ++k_) D += row[k_] * (u)[k_]; } while (0)

/* The pivots of the mass terms alone (Z = M0, kappa = 0, no coupling), tip to base; 0 where no free joint. */
void mass_pivots(int n, const int *parent, const int *axis, const double *direction, const double *M0,
                 const double *Kin, const double *RF, double *pivot, double *acc)
{
    for (int i = 0; i < n * DIM * DIM; ++i) acc[i] = 0.0;
    for (int j = n - 1; j >= 0; --j) {
        double P[DIM][DIM], T[DIM][DIM];
        const double *Mj = M0 + DIM * DIM * j, *Aj = acc + DIM * DIM * j;
        for (int i = 0; i < DIM; ++i)
            for (int k = 0; k < DIM; ++k) P[i][k] = Mj[DIM * i + k] + Aj[DIM * i + k];
        const int a = axis[j], q = parent[j];
        pivot[j] = 0.0;
        if (a != -1) {
            double D, w[DIM], column[DIM];
            PROJECT(double, P, a, direction + DIM * j, w, column, D);
            pivot[j] = D;
            if (q < 0) continue;
            for (int k = 0; k < DIM; ++k) w[k] /= D;
            for (int i = 0; i < DIM; ++i)
                for (int k = 0; k < DIM; ++k) P[i][k] -= column[i] * w[k];
        } else if (q < 0) continue;
        const double *F = RF + DIM * DIM * j, *K = Kin + DIM * DIM * j;
        double *Aq = acc + DIM * DIM * q;
        for (int i = 0; i < DIM; ++i)
            for (int k = 0; k < DIM; ++k) {
                double t = 0.0;
                for (int m = 0; m < DIM; ++m) t += F[DIM * i + m] * P[m][k];
                T[i][k] = t;
            }
        for (int i = 0; i < DIM; ++i)
            for (int k = 0; k < DIM; ++k) {
                double t = 0.0;
                for (int m = 0; m < DIM; ++m) t += T[i][m] * K[DIM * m + k];
                Aq[DIM * i + k] += t;
            }
    }
}

/* The loop over the frequencies; inlined by sweep() with the damping flag and, for one load case, the load-case
   count as constants, so the inner loops are unrolled there. */
static inline __attribute__((always_inline)) void frequencies(
    int n, const int L, int B, const int *parent, const int *axis, const int *flags, const double *M0,
    const double *C0, const double *K0, const double *Kin, const double *RF, const double *G, const double *H,
    const double *direction, const scalar *stiffness, const scalar *damping, const double *mass, const double *load,
    const scalar *torque, const scalar *squared, const scalar *rate, const int damped, double pivot_tolerance,
    double residual_tolerance, scalar *x, scalar *relative, scalar *pivot, double *backward, int *good, scalar *acc,
    double *size)
{
    const int DD = DIM * DIM, DL = DIM * L;
    scalar *bias = acc + n * DD, *wrench = bias + n * DL, *w = wrench + n * DL, *r = w + n * DIM;
    for (int b = 0; b < B; ++b) {
        const scalar sq = squared[b], s = rate[b];
        const double sq_modulus = MODULUS(sq), s_modulus = MODULUS(s);
        scalar *xb = x + (size_t)b * n * DL, *pb = pivot + (size_t)b * n;
        scalar *rel = relative ? relative + (size_t)b * n * L : r + n * L;
        int ok = 1;
        for (int i = 0; i < n * DD; ++i) acc[i] = 0.0;
        for (int i = 0; i < n * DL; ++i) bias[i] = 0.0;
        /* tip to base */
        for (int j = n - 1; j >= 0; --j) {
            scalar P[DIM][DIM], T[DIM][DIM];
            const double *Mj = M0 + DD * j, *Kj = K0 + DD * j, *Cj = C0 + DD * j;
            const scalar *Aj = acc + DD * j;
            for (int i = 0; i < DIM; ++i)
                for (int k = 0; k < DIM; ++k) {
                    scalar z = sq * Mj[DIM * i + k] + Kj[DIM * i + k] + Aj[DIM * i + k];
                    if (damped) z += s * Cj[DIM * i + k];
                    P[i][k] = z;
                }
            scalar *pj = bias + DL * j;                     /* p = h_j + children: in place */
            const double *hj = load + DL * j;
            for (int i = 0; i < DL; ++i) pj[i] += hj[i];
            const int a = axis[j], q = parent[j];
            pb[j] = 0.0;
            if (a != -1) {
                const double *u = direction + DIM * j;
                const scalar kappa = -(stiffness[j] + damping[j] * s);
                scalar row[DIM], column[DIM], D, *wj = w + DIM * j, *rj = r + L * j;
                PROJECT(scalar, P, a, u, row, column, D);
                D += kappa;
                const scalar inertia = sq * mass[j];
                pb[j] = D;
                if (!(MODULUS(D) >= pivot_tolerance * (MODULUS(inertia) + MODULUS(D - inertia)))) ok = 0;
                const double *Gj = G + DIM * j, *Hj = H + DIM * j;
                for (int k = 0; k < DIM; ++k) {
                    wj[k] = ((flags[j] & 1) ? row[k] + Gj[k] : row[k]) / D;
                    if (flags[j] & 2) column[k] += Hj[k];
                }
                if (UNIT(a)) for (int l = 0; l < L; ++l) rj[l] = (torque[L * j + l] - pj[a * L + l]) / D;
                else for (int l = 0; l < L; ++l) {
                    scalar along = 0.0;
                    for (int i = 0; i < DIM; ++i) along += u[i] * pj[i * L + l];
                    rj[l] = (torque[L * j + l] - along) / D;
                }
                if (q < 0) continue;
                for (int i = 0; i < DIM; ++i) {
                    for (int k = 0; k < DIM; ++k) P[i][k] -= column[i] * wj[k];
                    for (int l = 0; l < L; ++l) pj[i * L + l] += column[i] * rj[l];
                }
            } else if (q < 0) continue;
            const double *F = RF + DD * j, *K = Kin + DD * j;
            scalar *Aq = acc + DD * q, *pq = bias + DL * q;
            for (int i = 0; i < DIM; ++i)
                for (int k = 0; k < DIM; ++k) {
                    scalar t = 0.0;
                    for (int m = 0; m < DIM; ++m) t += F[DIM * i + m] * P[m][k];
                    T[i][k] = t;
                }
            for (int i = 0; i < DIM; ++i) {
                for (int k = 0; k < DIM; ++k) {
                    scalar t = 0.0;
                    for (int m = 0; m < DIM; ++m) t += T[i][m] * K[DIM * m + k];
                    Aq[DIM * i + k] += t;
                }
                for (int l = 0; l < L; ++l) {
                    scalar t = 0.0;
                    for (int m = 0; m < DIM; ++m) t += F[DIM * i + m] * pj[m * L + l];
                    pq[i * L + l] += t;
                }
            }
        }
        /* base to tip */
        for (int j = 0; j < n; ++j) {
            scalar *A = xb + DL * j;
            const int a = axis[j], q = parent[j];
            if (q < 0) {
                for (int i = 0; i < DL; ++i) A[i] = 0.0;
            } else {
                const double *K = Kin + DD * j;
                const scalar *X = xb + DL * q;
                for (int i = 0; i < DIM; ++i)
                    for (int l = 0; l < L; ++l) {
                        scalar t = 0.0;
                        for (int m = 0; m < DIM; ++m) t += K[DIM * i + m] * X[m * L + l];
                        A[i * L + l] = t;
                    }
            }
            if (a != -1) {
                const scalar *wj = w + DIM * j, *rj = r + L * j;
                const double *u = direction + DIM * j;
                for (int l = 0; l < L; ++l) {
                    scalar t = rj[l];
                    for (int m = 0; m < DIM; ++m) t -= wj[m] * A[m * L + l];
                    rel[L * j + l] = t;
                }
                if (UNIT(a)) for (int l = 0; l < L; ++l) A[a * L + l] += rel[L * j + l];
                else for (int i = 0; i < DIM; ++i) for (int l = 0; l < L; ++l) A[i * L + l] += u[i] * rel[L * j + l];
            } else {
                for (int l = 0; l < L; ++l) rel[L * j + l] = 0.0;
            }
            for (int i = 0; i < DL; ++i) if (!FINITE(A[i])) ok = 0;
        }
        /* the a-posteriori certificate: joint residuals of F_j = Z_j x_j + h_j + sum RF_c (F_c + H_c a_c) */
        for (int i = 0; i < n * DL; ++i) { wrench[i] = 0.0; size[i] = 0.0; }
        double worst = 0.0;
        for (int j = n - 1; j >= 0; --j) {
            scalar F[DIM * __LMAX__];
            double S[DIM * __LMAX__];
            const scalar *A = xb + DL * j, *Wj = wrench + DL * j;
            const double *Mj = M0 + DD * j, *Kj = K0 + DD * j, *Cj = C0 + DD * j, *hj = load + DL * j;
            const double *Sj = size + DL * j;
            for (int i = 0; i < DIM; ++i)
                for (int l = 0; l < L; ++l) {
                    scalar f = hj[i * L + l] + Wj[i * L + l];
                    double bound = fabs(hj[i * L + l]) + Sj[i * L + l];
                    for (int k = 0; k < DIM; ++k) {
                        scalar z = sq * Mj[DIM * i + k] + Kj[DIM * i + k];
                        double zm = sq_modulus * fabs(Mj[DIM * i + k]) + fabs(Kj[DIM * i + k]);
                        if (damped) { z += s * Cj[DIM * i + k]; zm += s_modulus * fabs(Cj[DIM * i + k]); }
                        f += z * A[k * L + l];
                        bound += zm * MODULUS(A[k * L + l]);
                    }
                    F[i * L + l] = f;
                    S[i * L + l] = bound;
                }
            const int a = axis[j], q = parent[j];
            if (a != -1) {
                const scalar kappa = -(stiffness[j] + damping[j] * s);
                const double *Gj = G + DIM * j, *Hj = H + DIM * j, *u = direction + DIM * j;
                for (int l = 0; l < L; ++l) {
                    const scalar rate_j = rel[L * j + l];
                    scalar residual = UNIT(a) ? F[a * L + l] : 0.0;
                    double scale = UNIT(a) ? S[a * L + l] : 0.0;
                    if (!UNIT(a))
                        for (int i = 0; i < DIM; ++i) {
                            residual += u[i] * F[i * L + l];
                            scale += fabs(u[i]) * S[i * L + l];
                        }
                    if (kappa != 0.0) {
                        const scalar law = kappa * rate_j;
                        residual += law;
                        scale += MODULUS(law);
                    }
                    if (flags[j] & 4) {
                        residual -= torque[L * j + l];
                        scale += MODULUS(torque[L * j + l]);
                    }
                    if ((flags[j] & 1) && q >= 0) {
                        const double *K = Kin + DD * j;
                        const scalar *X = xb + DL * q;
                        for (int i = 0; i < DIM; ++i) {
                            scalar origin = 0.0;
                            for (int m = 0; m < DIM; ++m) origin += K[DIM * i + m] * X[m * L + l];
                            residual += Gj[i] * origin;
                            scale += fabs(Gj[i]) * MODULUS(origin);
                        }
                    }
                    if (flags[j] & 2)
                        for (int i = 0; i < DIM; ++i) {
                            F[i * L + l] += Hj[i] * rate_j;
                            S[i * L + l] += fabs(Hj[i]) * MODULUS(rate_j);
                        }
                    double ratio = MODULUS(residual) / (scale > 0.0 ? scale : 1.0);
                    if (!isfinite(ratio)) ratio = INFINITY;
                    if (ratio > worst) worst = ratio;
                }
            }
            if (q < 0) continue;
            const double *R = RF + DD * j;
            scalar *Wq = wrench + DL * q;
            double *Sq = size + DL * q;
            for (int i = 0; i < DIM; ++i)
                for (int l = 0; l < L; ++l) {
                    scalar t = 0.0;
                    double u = 0.0;
                    for (int m = 0; m < DIM; ++m) {
                        t += R[DIM * i + m] * F[m * L + l];
                        u += fabs(R[DIM * i + m]) * S[m * L + l];
                    }
                    Wq[i * L + l] += t;
                    Sq[i * L + l] += u;
                }
        }
        backward[b] = worst;
        if (!(worst <= residual_tolerance)) ok = 0;
        good[b] = ok;
    }
}

/* The sweep (module docstring of ctmm.compiled_sweep) at B frequencies for L load cases.  Per body j (row-major
   DIM x DIM): M0, C0, K0; Kin, RF the parent's point maps of body j; G, H (DIM) its joint coupling (flags bit 1:
   G, bit 2: H, bit 4: torques); axis: the unit free direction, -1 for welds and held drives, -2 for the free
   direction direction[j] (DIM).  load (n, DIM, L), torque (n, L); squared (B) s^2, rate (B) s (complex variant:
   the damping terms); x (B, n, DIM, L), relative (B, n, L) the joints' amplitudes or NULL, pivot (B, n), backward (B),
   good (B).  Returns 0, -1 when the work space cannot be allocated, -2 for more than __LMAX__ load cases. */
int sweep(int n, int L, int B, const int *parent, const int *axis, const int *flags, const double *M0,
          const double *C0, const double *K0, const double *Kin, const double *RF, const double *G, const double *H,
          const double *direction, const scalar *stiffness, const scalar *damping, const double *mass,
          const double *load, const scalar *torque, const scalar *squared, const scalar *rate, double pivot_tolerance,
          double residual_tolerance, scalar *x, scalar *relative, scalar *pivot, double *backward, int *good)
{
    if (L < 1 || L > __LMAX__) return -2;
    const int DL = DIM * L;
    scalar *acc = malloc(sizeof(scalar) * (size_t)(n * DIM * DIM + 2 * n * DL + n * DIM + 2 * n * L + 1));
    double *size = malloc(sizeof(double) * (size_t)(n * DL + 1));
    if (!acc || !size) { free(acc); free(size); return -1; }
#define FREQUENCIES(LOADS, DAMPED) frequencies(n, LOADS, B, parent, axis, flags, M0, C0, K0, Kin, RF, G, H, \
    direction, stiffness, damping, mass, load, torque, squared, rate, DAMPED, pivot_tolerance, residual_tolerance, \
    x, relative, pivot, backward, good, acc, size)
#if __COMPLEX__
    if (L == 1) FREQUENCIES(1, 1);                  /* complex: the damping terms always (zeros add nothing) */
    else FREQUENCIES(L, 1);
#else
    if (L == 1) FREQUENCIES(1, 0);                  /* real: undamped terms only */
    else FREQUENCIES(L, 0);
#endif
#undef FREQUENCIES
    free(acc);
    free(size);
    return 0;
}
"""
"""The C text of the kernel: ``__DIM__`` (the point dimension), ``__COMPLEX__`` (0 or 1), ``__GENERAL__`` (0: unit
axes only) and ``__LMAX__`` (load cases of one call at most) are replaced per variant (:func:`kernel_library`)."""

LOAD_CASES = 16
"""Load cases one kernel call takes at most (more are swept in groups of this size)."""

REAL_FLAGS = ("-O3", "-shared", "-fPIC")
"""Compiler flags of the real variant (``-O3``: the inner loops over ``d`` and the load cases unrolled and
vectorised; measured in ``benchmarks/planar_frf.py`` at N = 100, 1.2x faster than ``-O2`` there; 0.55 s of
compiler CPU)."""
COMPLEX_FLAGS = ("-O3", "-fcx-fortran-rules", "-shared", "-fPIC")
"""Compiler flags of the complex variant (module docstring)."""


def compiler_present() -> bool:
    """True when :func:`ctmm.codegen.find_compiler` finds a C compiler (the kernel is then the default)."""
    try:
        find_compiler()
    except ModelError:
        return False
    return True


_ADDRESS, _INT, _DOUBLE = ctypes.c_void_p, ctypes.c_int, ctypes.c_double


def kernel_source(dimension: int, complex_scalar: bool, general: bool = False) -> str:
    """The C text of one kernel variant (point ``dimension``, scalar type ``double _Complex`` or ``double``;
    ``general``: joints on a column ``S``, else unit axes only)."""
    source = KERNEL_C.replace("__DIM__", str(int(dimension))).replace("__COMPLEX__", "1" if complex_scalar else "0")
    return source.replace("__LMAX__", str(LOAD_CASES)).replace("__GENERAL__", "1" if general else "0")


def kernel_library(dimension: int, complex_scalar: bool, general: bool = False) -> ctypes.CDLL:
    """The compiled kernel of one variant (:func:`kernel_source`), from the disk cache or built now
    (:func:`ctmm.codegen.load_ctypes`; ModelError without a compiler or when the compile fails)."""
    name = f"ctmm_sweep_d{int(dimension)}_{'complex' if complex_scalar else 'real'}{'_general' if general else ''}"
    library = load_ctypes(kernel_source(dimension, complex_scalar, general), name,
                          flags=COMPLEX_FLAGS if complex_scalar else REAL_FLAGS)
    library.sweep.restype = ctypes.c_int
    library.sweep.argtypes = [_INT] * 3 + [_ADDRESS] * 18 + [_DOUBLE] * 2 + [_ADDRESS] * 5
    library.mass_pivots.restype = None
    library.mass_pivots.argtypes = [_INT] + [_ADDRESS] * 8
    return library


def one_direction(joint: Any, dimension: int) -> bool:
    """True for a joint with one free direction the kernel takes: a unit axis (``axis``) or a real column ``S``
    of ``dimension`` rows (a spatial revolute or prismatic joint)."""
    return joint.free == 1 and (joint.axis is not None or (np.size(joint.S) == dimension
                                                           and not np.any(np.imag(joint.S))))


def applies(tree: Tree, bodies: Sequence[tuple], joints: Sequence[Any], coupling: Sequence[Any] | None) -> bool:
    """True when :class:`CompiledSweep` takes these frequency-context terms: every body rigid (``M0`` of size
    ``d``), every joint a weld, a drive held at zero or one free direction (a unit ``axis`` or a column ``S``:
    :func:`one_direction`) without inertance, no joint offset ``c``, scalar joint laws, coupling (if any) only
    on one-direction joints."""
    d = tree.dimension
    for j, (M0, _, _, _, _) in enumerate(bodies):
        if M0.shape != (d, d):
            return False
        joint = joints[j]
        if joint.c is not None or joint.tau_a is not None:
            return False
        if any(law is not None and np.size(law) != 1 for law in (joint.tau_q, joint.tau_v)):
            return False
        if joint.prescribed is not None:
            if np.any(joint.prescribed):
                return False
        elif joint.free and not one_direction(joint, d):
            return False
        if coupling is not None and coupling[j] is not None and any(g is not None for g in coupling[j]) \
                and (not one_direction(joint, d) or joint.prescribed is not None):
            return False
    return True


def _address(array: np.ndarray) -> int:
    """The address of a C-contiguous array's data (the caller keeps the array alive during the call)."""
    if not array.flags.c_contiguous:            # the kernel reads every array densely, row-major
        raise ValueError(f"the compiled sweep takes C-contiguous arrays, got strides {array.strides}")
    return array.ctypes.data


def mass_pivots(library: ctypes.CDLL, kernel: "CompiledSweep") -> np.ndarray:
    """(n,) the pivots of the mass terms alone (``Z = M0``, ``kappa = 0``, no coupling; 0 at bodies without a free
    joint): the scale the pivot certificate measures by."""
    out, work = np.zeros(kernel.n), np.zeros(kernel.n * kernel.d * kernel.d)
    library.mass_pivots(kernel.n, *(_address(a) for a in (kernel.parent, kernel.axis, kernel.direction, kernel.M0,
                                                             kernel.Kin, kernel.RF, out, work)))
    return out


@dataclass(frozen=True)
class SweepAnswer:
    """Result of :meth:`CompiledSweep.solve`.

    Attributes
    ----------
    x : ndarray, shape (n, d, L, B)
        ``A_in`` of every body (load cases, frequencies); a view.
    relative : ndarray, shape (F, L, B), or None
        The one-direction joints' relative amplitudes ``a``, in :attr:`CompiledSweep.free` order (when asked for).
    pivot : ndarray, shape (F, B)
        ``D_j`` of the one-direction joints, in :attr:`CompiledSweep.free` order.
    backward : ndarray, shape (B,)
        The a-posteriori backward error of the answer.
    good : ndarray of bool, shape (B,)
        Both certificates passed and the answer finite.
    """

    x: np.ndarray
    relative: np.ndarray
    pivot: np.ndarray
    backward: np.ndarray
    good: np.ndarray


class CompiledSweep:
    """The frequency-context sweep of one tree's linearised terms by the compiled kernel, prepared once.

    Parameters
    ----------
    tree : Tree
    bodies : sequence of tuple
        ``(M0, C0, K0, Kin, RF)`` per body (``Kin``, ``RF``: dicts of ``(1, d, d)`` point maps).
    joints : sequence of JointTerms
        The held joints (``tau`` is the load cases' business: :meth:`solve`).
    coupling : sequence, optional
        ``(G_j, H_j)`` per joint or ``None`` (:func:`ctmm.articulated.articulated_inward`).

    Raises
    ------
    ModelError
        Terms the kernel does not take (:func:`applies`), no C compiler, or a failed compile.
    """

    def __init__(self, tree: Tree, bodies: Sequence[tuple], joints: Sequence[Any],
                 coupling: Sequence[Any] | None = None) -> None:
        if not applies(tree, bodies, joints, coupling):
            raise ModelError("CompiledSweep: the terms are not those of a rigid tree on welds, held drives and "
                             "one-direction joints (ctmm.compiled_sweep.applies)")
        d = self.d = tree.dimension
        n = self.n = len(bodies)
        self.tree = tree
        self.parent = np.asarray(tree.parent, dtype=np.intc)
        # -1: weld or held drive; a >= 0: unit axis a; -2: the free direction S (``direction``)
        axis = [-1 if joint.prescribed is not None or not joint.free else -2 if joint.axis is None
                else int(joint.axis) for joint in joints]
        self.axis = np.asarray(axis, dtype=np.intc)
        self.free = [j for j, a in enumerate(axis) if a != -1]
        self.direction = np.zeros((n, d))
        for j, a in enumerate(axis):
            if a == -2:
                self.direction[j] = np.real(joints[j].S).reshape(d)
        self.M0, self.C0, self.K0 = (np.ascontiguousarray(np.stack([b[k] for b in bodies]), dtype=float)
                                     for k in range(3))
        self.damped_bodies = bool(np.any(self.C0))
        eye = np.eye(d)
        self.Kin, self.RF = np.tile(eye, (n, 1, 1)), np.tile(eye, (n, 1, 1))
        for j, parent in enumerate(tree.parent):
            if parent >= 0:
                e = tree.point[j]
                self.Kin[j], self.RF[j] = bodies[parent][3][e][0], bodies[parent][4][e][0]
        self.G, self.H = np.zeros((n, d)), np.zeros((n, d))
        self.flags = np.zeros(n, dtype=np.intc)
        for j, pair in enumerate(coupling or ()):
            if pair is not None and axis[j] != -1:
                G, H = pair
                if G is not None:
                    self.G[j], self.flags[j] = np.asarray(G, dtype=float).reshape(d), self.flags[j] | 1
                if H is not None:
                    self.H[j], self.flags[j] = np.asarray(H, dtype=float).reshape(d), self.flags[j] | 2
        laws = np.zeros((2, n), dtype=complex)          # the joints' law tangents tau_q, tau_v (-k, -c)
        for j in self.free:
            for k, law in enumerate((joints[j].tau_q, joints[j].tau_v)):
                if law is not None:
                    laws[k, j] = complex(np.asarray(law).reshape(-1)[0])
        self.real_laws = not np.any(laws.imag)
        self.stiffness, self.damping = laws[0].copy(), laws[1].copy()   # kappa = -(stiffness + damping s)
        self.undamped = not self.damped_bodies and not np.any(self.damping)
        self.addresses = tuple(_address(a) for a in (self.parent, self.axis))
        self.terms = tuple(_address(a) for a in (self.M0, self.C0, self.K0, self.Kin, self.RF, self.G, self.H,
                                                  self.direction))
        self.general = bool(np.any(self.axis == -2))     # a column S: the variant with its products
        self.libraries = {False: kernel_library(d, False, self.general)}
        if not self.undamped or not self.real_laws:     # the complex variant answers every call: built now
            self.library(True)
        self.mass_pivot = mass_pivots(self.libraries[False], self)

    def library(self, complex_scalar: bool) -> ctypes.CDLL:
        """The kernel variant (compiled or loaded on first use)."""
        if complex_scalar not in self.libraries:
            self.libraries[complex_scalar] = kernel_library(self.d, complex_scalar, self.general)
        return self.libraries[complex_scalar]

    def solve(self, s: np.ndarray, loads: np.ndarray, torques: np.ndarray, *, pivot_tolerance: float,
              residual_tolerance: float, relative: bool = False) -> SweepAnswer:
        """The sweep at the Laplace variables ``s`` (B,) for the load cases ``loads`` (n, d, L) (body load columns
        ``h``, real) and ``torques`` (F, L) (the one-direction joints' ``tau``, in :attr:`free` order), with both
        certificates decided at ``pivot_tolerance`` and ``residual_tolerance`` (module docstring), and with
        ``relative`` the joints' relative amplitudes.  Real arithmetic where every term is real (undamped, ``s`` on
        the imaginary axis, real laws and torques)."""
        d, n = self.d, self.n
        s = np.ascontiguousarray(np.asarray(s, dtype=complex).reshape(-1))
        if np.any(np.imag(loads)):
            raise ModelError("CompiledSweep.solve: loads must be real body load columns (the planar ports' are)")
        loads = np.ascontiguousarray(np.real(loads), dtype=float)
        torques = np.asarray(torques)
        real = self.undamped and not np.any(s.real) and self.real_laws and not np.any(np.imag(torques))
        dtype = float if real else complex
        L = loads.shape[2]
        if L > LOAD_CASES:                          # groups of LOAD_CASES load cases
            parts = [self.solve(s, loads[:, :, k:k + LOAD_CASES], torques[:, k:k + LOAD_CASES], relative=relative,
                                pivot_tolerance=pivot_tolerance, residual_tolerance=residual_tolerance)
                     for k in range(0, L, LOAD_CASES)]
            backward = np.max([part.backward for part in parts], axis=0)
            good = np.all([part.good for part in parts], axis=0)
            amplitudes = np.concatenate([part.relative for part in parts], axis=1) if relative else None
            return SweepAnswer(np.concatenate([part.x for part in parts], axis=2), amplitudes, parts[0].pivot,
                               backward, good)
        torque = np.zeros((n, L), dtype=dtype)
        torque[self.free] = torques.real if real else torques
        flags = self.flags | np.where(np.any(torque != 0.0, axis=1), 4, 0).astype(np.intc)
        squared = ((s * s).real if real else s * s).astype(dtype)
        rate = np.zeros(s.size) if real else s
        stiffness = self.stiffness.real.copy() if real else self.stiffness
        damping = self.damping.real.copy() if real else self.damping
        x = np.empty((s.size, n, d, L), dtype=dtype)
        amplitudes = np.empty((s.size, n, L), dtype=dtype) if relative else None
        pivot = np.empty((s.size, n), dtype=dtype)
        backward, good = np.empty(s.size), np.empty(s.size, dtype=np.intc)
        library = self.library(not real)
        status = library.sweep(
            n, L, s.size, *self.addresses, _address(flags), *self.terms, *(_address(a) for a in (
                stiffness, damping, self.mass_pivot, loads, torque, squared, rate)), pivot_tolerance,
            residual_tolerance, _address(x), None if amplitudes is None else _address(amplitudes),
            *(_address(a) for a in (pivot, backward, good)))
        if status == -1:
            raise MemoryError(f"the compiled sweep could not allocate its work space ({n} bodies, {L} load cases)")
        if status != 0:
            raise ModelError(f"CompiledSweep.solve: {L} load cases; the kernel takes 1 to {LOAD_CASES} at once")
        return SweepAnswer(x.transpose(1, 2, 3, 0), None if amplitudes is None else
                           amplitudes[:, self.free].transpose(1, 2, 0), pivot[:, self.free].T, backward, good.astype(bool))
