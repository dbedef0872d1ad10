"""The C text of the compiled frequency sweep's multi-direction variant (:mod:`ctmm.compiled_sweep`: spatial rigid
trees with universal, spherical or free joints, ``k x k`` pivot blocks); kept apart from the one-direction text of
:mod:`ctmm.compiled_sweep_kernel`, which it leaves unchanged."""
from __future__ import annotations

__all__ = ["KERNEL_MULTI_C"]

from .compiled_sweep_kernel import (BODY_FORCES, BODY_TERMS, INBOARD_ORIGIN, MASS_PARENT_TERMS, PARENT_TERMS,
                                   WRENCH_TO_PARENT)

KERNEL_MULTI_C = r"""
#include <math.h>
#include <stdlib.h>
#include <complex.h>
#define DIM __DIM__
#if __COMPLEX__
typedef double _Complex scalar;
#define MODULUS(z) cabs(z)
#define CONJUGATE(z) conj(z)
#define FINITE(z) (isfinite(creal(z)) && isfinite(cimag(z)))
#else
typedef double scalar;
#define MODULUS(z) fabs(z)
#define CONJUGATE(z) (z)
#define FINITE(z) isfinite(z)
#endif

/* Every free joint of k = count[j] directions (1 <= k <= DIM) on the columns of its S (direction[j]: DIM x DIM,
   row-major, the first k columns used); the joint blocks (laws, coupling, mass pivots) are DIM x DIM with their
   k x k, k x DIM or DIM x k parts used. */

/* The smallest singular value of the k x k block A by one-sided (Hestenes) Jacobi rotations of its columns: at
   convergence the columns are orthogonal and their norms the singular values (0 for a non-finite block). */
static double smallest_singular(int k, scalar A[DIM][DIM])
{
    scalar a[DIM][DIM];
    for (int i = 0; i < k; ++i)
        for (int c = 0; c < k; ++c) {
            if (!FINITE(A[i][c])) return 0.0;
            a[i][c] = A[i][c];
        }
    for (int sweep = 0; sweep < 60; ++sweep) {
        int rotated = 0;
        for (int p = 0; p < k - 1; ++p)
            for (int q = p + 1; q < k; ++q) {
                double alpha = 0.0, beta = 0.0;
                scalar gamma = 0.0;
                for (int i = 0; i < k; ++i) {
                    alpha += MODULUS(a[i][p]) * MODULUS(a[i][p]);
                    beta += MODULUS(a[i][q]) * MODULUS(a[i][q]);
                    gamma += CONJUGATE(a[i][p]) * a[i][q];
                }
                const double g = MODULUS(gamma);
                if (!(g > 1e-17 * sqrt(alpha * beta))) continue;
                rotated = 1;
                const scalar phase = CONJUGATE(gamma) / g;     /* column q times phase: a_p^H a_q = g real */
                const double zeta = (beta - alpha) / (2.0 * g);
                const double t = (zeta >= 0.0 ? 1.0 : -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta));
                const double c = 1.0 / sqrt(1.0 + t * t), s = c * t;
                for (int i = 0; i < k; ++i) {
                    const scalar u = a[i][p], v = a[i][q] * phase;
                    a[i][p] = c * u - s * v;
                    a[i][q] = s * u + c * v;
                }
            }
        if (!rotated) break;
    }
    double smallest = INFINITY;
    for (int c = 0; c < k; ++c) {
        double norm = 0.0;
        for (int i = 0; i < k; ++i) norm += MODULUS(a[i][c]) * MODULUS(a[i][c]);
        norm = sqrt(norm);
        if (norm < smallest) smallest = norm;
    }
    return smallest;
}

/* X = D^-1 X in place (k x k D, m columns of X, row stride DIM + __LMAX__) by Gaussian elimination with partial
   pivoting on the moduli; an exactly singular D leaves non-finite numbers (not certified). */
static void solve_block(int k, int m, scalar D[DIM][DIM], scalar X[DIM][DIM + __LMAX__])
{
    for (int c = 0; c < k; ++c) {
        int best = c;
        for (int i = c + 1; i < k; ++i) if (MODULUS(D[i][c]) > MODULUS(D[best][c])) best = i;
        if (best != c) {
            for (int e = 0; e < k; ++e) { scalar t = D[c][e]; D[c][e] = D[best][e]; D[best][e] = t; }
            for (int e = 0; e < m; ++e) { scalar t = X[c][e]; X[c][e] = X[best][e]; X[best][e] = t; }
        }
        for (int i = c + 1; i < k; ++i) {
            const scalar f = D[i][c] / D[c][c];
            for (int e = c; e < k; ++e) D[i][e] -= f * D[c][e];
            for (int e = 0; e < m; ++e) X[i][e] -= f * X[c][e];
        }
    }
    for (int c = k - 1; c >= 0; --c)
        for (int e = 0; e < m; ++e) {
            scalar t = X[c][e];
            for (int i = c + 1; i < k; ++i) t -= D[c][i] * X[i][e];
            X[c][e] = t / D[c][c];
        }
}

/* The rows S^T P (k x DIM, into the first DIM columns of X) and the columns P S (DIM x k) of a joint on the k
   columns of S (DIM x DIM, row-major). */
static void project(int k, const double *S, scalar P[DIM][DIM], scalar X[DIM][DIM + __LMAX__], scalar column[DIM][DIM])
{
    for (int c = 0; c < k; ++c)
        for (int e = 0; e < DIM; ++e) {
            scalar r = 0.0, t = 0.0;
            for (int i = 0; i < DIM; ++i) { r += S[DIM * i + c] * P[i][e]; t += P[e][i] * S[DIM * i + c]; }
            X[c][e] = r;
            column[e][c] = t;
        }
}

/* The k x k pivots of the mass terms alone (Z = M0, kappa = 0, no coupling), tip to base, in pivot (n, DIM, DIM). */
void mass_pivots(int n, const int *parent, const int *count, const double *direction, const double *M0,
                 const double *Kin, const double *RF, double *pivot, double *acc)
{
    const int DD = DIM * DIM;
    for (int i = 0; i < n * DD; ++i) { acc[i] = 0.0; pivot[i] = 0.0; }
    for (int j = n - 1; j >= 0; --j) {
        double P[DIM][DIM], T[DIM][DIM];
        scalar Z[DIM][DIM];
        const double *Mj = M0 + DD * j, *Aj = acc + DD * j, *S = direction + DD * j;
        for (int i = 0; i < DIM; ++i)
            for (int e = 0; e < DIM; ++e) Z[i][e] = P[i][e] = Mj[DIM * i + e] + Aj[DIM * i + e];
        const int k = count[j], q = parent[j];
        if (k > 0) {
            scalar D[DIM][DIM], X[DIM][DIM + __LMAX__], column[DIM][DIM];
            project(k, S, Z, X, column);
            for (int c = 0; c < k; ++c)
                for (int e = 0; e < k; ++e) {
                    scalar t = 0.0;
                    for (int i = 0; i < DIM; ++i) t += X[c][i] * S[DIM * i + e];
                    D[c][e] = t;
                    pivot[DD * j + DIM * c + e] = creal(t);
                }
            if (q < 0) continue;
            solve_block(k, DIM, D, X);
            for (int i = 0; i < DIM; ++i)
                for (int e = 0; e < DIM; ++e)
                    for (int c = 0; c < k; ++c) P[i][e] -= creal(column[i][c] * X[c][e]);
        } else if (q < 0) continue;
""" + MASS_PARENT_TERMS + r"""    }
}

/* The sweep of ctmm.compiled_sweep with joints of k directions; arguments as the one-direction kernel's, with
   count (n) the directions of each joint (0: weld or held drive), direction, G, H, stiffness, damping, mass
   (n, DIM, DIM) blocks, torque (n, DIM, L), relative (B, n, DIM, L), pivot (B, n) the smallest singular value of
   each pivot block (0 where none).  Returns 0, -1 when the work space cannot be allocated, -2 for more than
   __LMAX__ load cases. */
int sweep(int n, int L, int B, const int *parent, const int *count, const int *flags, const double *M0,
          const double *C0, const double *K0, const double *Kin, const double *RF, const double *G, const double *H,
          const double *direction, const scalar *stiffness, const scalar *damping, const double *mass,
          const double *load, const scalar *torque, const scalar *squared, const scalar *rate, double pivot_tolerance,
          double residual_tolerance, scalar *x, scalar *relative, double *pivot, double *backward, int *good)
{
    if (L < 1 || L > __LMAX__) return -2;
    const int DD = DIM * DIM, DL = DIM * L;
    scalar *acc = malloc(sizeof(scalar) * (size_t)(n * DD + 2 * n * DL + n * DD + n * DL + n * DL + 1));
    double *size = malloc(sizeof(double) * (size_t)(n * DL + 1));
    if (!acc || !size) { free(acc); free(size); return -1; }
    const int damped = __COMPLEX__;             /* the damping terms (BODY_FORCES) */
    scalar *bias = acc + n * DD, *wrench = bias + n * DL, *w = wrench + n * DL, *r = w + n * DD;
    scalar *own = r + n * DL;
    for (int b = 0; b < B; ++b) {
        const scalar sq = squared[b], s = rate[b];
        const double sq_modulus = MODULUS(sq), s_modulus = MODULUS(s);
        scalar *xb = x + (size_t)b * n * DL;
        double *pb = pivot + (size_t)b * n;
        scalar *rel = relative ? relative + (size_t)b * n * DL : own;
        int ok = 1;
        for (int i = 0; i < n * DD; ++i) acc[i] = 0.0;
        for (int i = 0; i < n * DL; ++i) bias[i] = 0.0;
        /* tip to base */
        for (int j = n - 1; j >= 0; --j) {
""" + BODY_TERMS + r"""            const int k = count[j], q = parent[j];
            pb[j] = 0.0;
            if (k > 0) {
                const double *S = direction + DD * j, *Gj = G + DD * j, *Hj = H + DD * j, *Mp = mass + DD * j;
                const scalar *stiff = stiffness + DD * j, *damp = damping + DD * j, *tj = torque + DL * j;
                scalar D[DIM][DIM], X[DIM][DIM + __LMAX__], column[DIM][DIM];
                project(k, S, P, X, column);
                double inertia = 0.0, rest = 0.0;
                for (int c = 0; c < k; ++c)
                    for (int e = 0; e < k; ++e) {
                        scalar t = -(stiff[DIM * c + e] + damp[DIM * c + e] * s);
                        for (int i = 0; i < DIM; ++i) t += X[c][i] * S[DIM * i + e];
                        D[c][e] = t;
                        const scalar m = sq * Mp[DIM * c + e];
                        if (MODULUS(m) > inertia) inertia = MODULUS(m);
                        if (MODULUS(t - m) > rest) rest = MODULUS(t - m);
                    }
                const double smallest = smallest_singular(k, D);
                pb[j] = smallest;
                if (!(smallest >= pivot_tolerance * (inertia + rest))) ok = 0;
                for (int c = 0; c < k; ++c) {
                    if (flags[j] & 1) for (int e = 0; e < DIM; ++e) X[c][e] += Gj[DIM * c + e];
                    for (int l = 0; l < L; ++l) {
                        scalar along = 0.0;
                        for (int i = 0; i < DIM; ++i) along += S[DIM * i + c] * pj[i * L + l];
                        X[c][DIM + l] = tj[c * L + l] - along;
                    }
                }
                if (flags[j] & 2)
                    for (int i = 0; i < DIM; ++i) for (int c = 0; c < k; ++c) column[i][c] += Hj[DIM * i + c];
                solve_block(k, DIM + L, D, X);
                scalar *wj = w + DD * j, *rj = r + DL * j;
                for (int c = 0; c < k; ++c) {
                    for (int e = 0; e < DIM; ++e) wj[DIM * c + e] = X[c][e];
                    for (int l = 0; l < L; ++l) rj[c * L + l] = X[c][DIM + l];
                }
                if (q < 0) continue;
                for (int i = 0; i < DIM; ++i)
                    for (int c = 0; c < k; ++c) {
                        for (int e = 0; e < DIM; ++e) P[i][e] -= column[i][c] * X[c][e];
                        for (int l = 0; l < L; ++l) pj[i * L + l] += column[i][c] * X[c][DIM + l];
                    }
            } else if (q < 0) continue;
""" + PARENT_TERMS + r"""        }
        /* base to tip: a = r - w A_O, x = A_O + S a */
        for (int j = 0; j < n; ++j) {
            scalar *A = xb + DL * j, *aj = rel + DL * j;
            const int k = count[j], q = parent[j];
""" + INBOARD_ORIGIN + r"""            for (int i = 0; i < DL; ++i) aj[i] = 0.0;
            if (k > 0) {
                const scalar *wj = w + DD * j, *rj = r + DL * j;
                const double *S = direction + DD * j;
                for (int c = 0; c < k; ++c)
                    for (int l = 0; l < L; ++l) {
                        scalar t = rj[c * L + l];
                        for (int m = 0; m < DIM; ++m) t -= wj[DIM * c + m] * A[m * L + l];
                        aj[c * L + l] = t;
                    }
                for (int i = 0; i < DIM; ++i)
                    for (int l = 0; l < L; ++l) {
                        scalar t = A[i * L + l];
                        for (int c = 0; c < k; ++c) t += S[DIM * i + c] * aj[c * L + l];
                        A[i * L + l] = t;
                    }
            }
            for (int i = 0; i < DL; ++i) if (!FINITE(A[i])) ok = 0;
        }
        /* the a-posteriori certificate: joint residuals S^T F_j + G_j A_O + kappa_j a_j - tau_j */
        for (int i = 0; i < n * DL; ++i) { wrench[i] = 0.0; size[i] = 0.0; }
        double worst = 0.0;
        for (int j = n - 1; j >= 0; --j) {
            scalar F[DIM * __LMAX__];
            double S[DIM * __LMAX__];
            const scalar *A = xb + DL * j, *Wj = wrench + DL * j, *aj = rel + DL * j;
            const double *Mj = M0 + DD * j, *Kj = K0 + DD * j, *Cj = C0 + DD * j, *hj = load + DL * j;
            const double *Sj = size + DL * j;
""" + BODY_FORCES + r"""            const int k = count[j], q = parent[j];
            if (k > 0) {
                const double *U = direction + DD * j, *Gj = G + DD * j, *Hj = H + DD * j;
                const scalar *stiff = stiffness + DD * j, *damp = damping + DD * j, *tj = torque + DL * j;
                for (int c = 0; c < k; ++c)
                    for (int l = 0; l < L; ++l) {
                        scalar residual = -tj[c * L + l];
                        double scale = MODULUS(tj[c * L + l]);
                        for (int i = 0; i < DIM; ++i) {
                            residual += U[DIM * i + c] * F[i * L + l];
                            scale += fabs(U[DIM * i + c]) * S[i * L + l];
                        }
                        for (int e = 0; e < k; ++e) {
                            const scalar kappa = -(stiff[DIM * c + e] + damp[DIM * c + e] * s);
                            residual += kappa * aj[e * L + l];
                            scale += MODULUS(kappa) * MODULUS(aj[e * L + l]);
                        }
                        if ((flags[j] & 1) && q >= 0) {
                            const double *K = Kin + DD * j;
                            const scalar *X = xb + DL * q;
                            for (int i = 0; i < DIM; ++i) {
                                scalar origin = 0.0;
                                for (int m = 0; m < DIM; ++m) origin += K[DIM * i + m] * X[m * L + l];
                                residual += Gj[DIM * c + i] * origin;
                                scale += fabs(Gj[DIM * c + i]) * MODULUS(origin);
                            }
                        }
                        double ratio = MODULUS(residual) / (scale > 0.0 ? scale : 1.0);
                        if (!isfinite(ratio)) ratio = INFINITY;
                        if (ratio > worst) worst = ratio;
                    }
                if (flags[j] & 2)
                    for (int i = 0; i < DIM; ++i)
                        for (int l = 0; l < L; ++l)
                            for (int c = 0; c < k; ++c) {
                                F[i * L + l] += Hj[DIM * i + c] * aj[c * L + l];
                                S[i * L + l] += fabs(Hj[DIM * i + c]) * MODULUS(aj[c * L + l]);
                            }
            }
""" + WRENCH_TO_PARENT + r"""        }
        backward[b] = worst;
        if (!(worst <= residual_tolerance)) ok = 0;
        good[b] = ok;
    }
    free(acc);
    free(size);
    return 0;
}

/* The smallest singular value of each of B k x k blocks (B, DIM, DIM) into out (B): for the tests. */
void smallest_singular_values(int B, int k, const scalar *blocks, double *out)
{
    for (int b = 0; b < B; ++b) {
        scalar A[DIM][DIM];
        for (int i = 0; i < DIM; ++i)
            for (int e = 0; e < DIM; ++e) A[i][e] = blocks[(size_t)b * DIM * DIM + DIM * i + e];
        out[b] = smallest_singular(k, A);
    }
}
"""
"""The C text of the kernel variant with joints of several free directions (universal, spherical, free: ``k x k``
pivot blocks, solved by Gaussian elimination with partial pivoting, certified by their smallest singular value from
one-sided Jacobi rotations); placeholders as :data:`KERNEL_C`'s."""
