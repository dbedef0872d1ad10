"""The C text of the compiled frequency sweep of :mod:`ctmm.compiled_sweep` (its recursion, both certificates and
the variants' constants are described there); kept apart from its Python driver, one text compiled per variant.
The blocks both this kernel and the multi-direction one (:mod:`ctmm.compiled_sweep_multi_kernel`) run are named
constants here, joined into :data:`KERNEL_C` (its text is unchanged by the split)."""
from __future__ import annotations

__all__ = ["BODY_FORCES", "BODY_TERMS", "INBOARD_ORIGIN", "KERNEL_C", "MASS_PARENT_TERMS", "PARENT_TERMS",
           "WRENCH_TO_PARENT"]

BODY_TERMS = r"""            scalar P[DIM][DIM], T[DIM][DIM];
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
"""
"""C text of the sweep shared by both kernels: body ``j``'s ``P = Z_j(s) + children`` and ``p = h_j + children``."""

MASS_PARENT_TERMS = r"""        const double *F = RF + DIM * DIM * j, *K = Kin + DIM * DIM * j;
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
"""
"""C text shared by both kernels' mass pivots: body ``j``'s eliminated mass terms carried to its parent
(``Aq += RF P Kin``, real)."""

PARENT_TERMS = r"""            const double *F = RF + DD * j, *K = Kin + DD * j;
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
"""
"""C text of the sweep shared by both kernels: body ``j``'s eliminated terms carried to its parent
(``Aq += RF P Kin``, ``pq += RF p``)."""

INBOARD_ORIGIN = r"""            if (q < 0) {
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
"""
"""C text of the sweep shared by both kernels: the inboard point's amplitude ``A_O = Kin x_parent`` (0 on the
ground)."""

BODY_FORCES = r"""            for (int i = 0; i < DIM; ++i)
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
"""
"""C text of the sweep shared by both kernels: the body's force ``F = Z x + h + children`` and its size ``S`` (the
moduli of its terms)."""

WRENCH_TO_PARENT = r"""            if (q < 0) continue;
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
"""
"""C text of the sweep shared by both kernels: the joint's wrench and its size carried to the parent (``RF F``,
``|RF| S``)."""

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
   P, a general direction (a = -2) the products with its column u = S (DIM): the axes say which, one text for
   both (a text without the products for unit axes only was measured no faster: CPU time ratio 0.97 - 1.00 at
   N = 100, planar_frf's chain). */
#define UNIT(a) ((a) >= 0)
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
""" + MASS_PARENT_TERMS + r"""    }
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
""" + BODY_TERMS + r"""            const int a = axis[j], q = parent[j];
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
""" + PARENT_TERMS + r"""        }
        /* base to tip */
        for (int j = 0; j < n; ++j) {
            scalar *A = xb + DL * j;
            const int a = axis[j], q = parent[j];
""" + INBOARD_ORIGIN + r"""            if (a != -1) {
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
""" + BODY_FORCES + r"""            const int a = axis[j], q = parent[j];
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
""" + WRENCH_TO_PARENT + r"""        }
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
"""The C text of the kernel: ``__DIM__`` (the point dimension), ``__COMPLEX__`` (0 or 1) and ``__LMAX__`` (load cases
of one call at most) are replaced per variant (:func:`ctmm.compiled_sweep.kernel_library`); whether a joint is on a
column ``S`` (``axis`` -2) is data, read per joint from the axes (one text for unit axes and columns)."""
