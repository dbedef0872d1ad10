"""The Riccati solve of a 1-D lumped chain in the frequency domain as one compiled C loop (issue 13).

:func:`ctmm.chain_assembly.solve` answers a chain of springs, dampers, masses and the other lumped axial elements
(:class:`~ctmm.elements.axial.AxialBody`, :class:`~ctmm.elements.axial.AxialJoint`) by the scalar Riccati recursion of
:func:`ctmm.assembly.riccati_scalar_entries` batched over the frequencies (numpy: one array operation per element
and step, ``G_j, r_j`` of every element kept for the back-substitution, memory ``O(N B)``).  This module runs the
same recursion in C on blocks of :data:`BLOCK` frequencies side by side (independent recursions: one frequency at a
time the loop waits on each division's latency, about 3x slower): per block the forward pass over the elements, the
end condition, its certificate and the back-substitution, with ``G_j^-1, r_j`` of the point steps in a work array of
``O(N)`` reused for every block and only the requested points' states stored (memory ``O(N + points x B)``).

What is typed here and what is derived
--------------------------------------
Each element enters through the affine form derived from its definition
(:meth:`~ctmm.elements.axial.AxialBody.axial_coefficients`: ``inertia``, ``damping``, ``stiffness`` and the input
derivatives).  In the start partition (``f`` known at the start, ``e`` unknown) a lumped element is of *field* type
(``U11 = U22 = 1``, ``U21 = 0``, ``U12 = v``) or *point* type (``U12 = 0``, ``U21 = v``), with
``v = a2 s^2 + a1 s + a0`` or its reciprocal, the coefficients signed as :func:`ctmm.chain_assembly.solve` forms
them (a joint's ``-1 / (k + c s + b s^2)``, a body's ``-(m s^2 + c s + k)``); loads are ``u = alpha + beta v``.
The C text types only the two scalar Riccati steps of ``docs/riccati.md`` §2 (field: ``S <- S + v``, ``G = 1``;
point: ``G = v S + 1``, ``S <- S / G``, ``r = v P + u_e``, ``P <- P / G``), complex numbers by real and imaginary
parts; a division is a reciprocal by Smith's rule (without branches) times the numerator, so the answers equal
the numpy recursion's to round-off, not bit for bit.  The C text does not depend on the chain (its numbers are
data): one compile per machine (0.3 s), cached on disk by :func:`ctmm.codegen.load_ctypes`; there is nothing to
generate per chain, so no casadi graph is built.

Certificate: the same as the numpy recursion's.  The end unknown ``e_N = (b - Bm_f P_N) / H`` must be finite at
every frequency, else :class:`~ctmm.errors.SingularSystemError` names the batch entries (a free-free chain under a
static load, a frequency exactly at a natural frequency of an undamped chain).

The characteristic log-determinant (``want_log_det``) is the product of the pivots ``G_j`` and ``H`` accumulated as a
mantissa times a power of two (one complex product per point step, one logarithm per frequency at the end).
Controlled chains are answered on this kernel by :mod:`ctmm.controlled_chain_frequency` (the loops closed over the
plant's responses).  Not here: chains with beams (numpy, :func:`ctmm.assembly.riccati_solve`), coefficients that are
arrays (numpy).
"""
from __future__ import annotations

import ctypes
import functools
from typing import Sequence

import numpy as np

from .assembly import BoundaryEnd, BoundaryStart, ChainSolution
from .errors import ModelError, SingularSystemError

__all__ = ["FIELD", "POINT", "RECIPROCAL", "SOURCE", "compiled_library", "solve_entries"]

FIELD, POINT, RECIPROCAL = 0, 1, 2
"""Element kind flags: field type (``U12 = v``) or point type (``U21 = v``), ``RECIPROCAL``: ``v = 1 / poly``."""

SOURCE = r"""
#include <math.h>
#define K 8                              /* frequencies per block: independent recursions side by side */

/* 1 / (br + i bi) by Smith's rule without branches (the larger part divides) */
static inline void reciprocal(double br, double bi, double *qr, double *qi)
{
    const int big = fabs(br) >= fabs(bi);
    const double p = big ? br : bi, q = big ? bi : br;
    const double rat = q / p, scl = 1.0 / (p + q * rat);
    *qr = big ? scl : rat * scl;
    *qi = big ? -rat * scl : -scl;
}

/* Riccati transfer of a 2-component lumped chain in blocks of K frequencies (ctmm.compiled_chain_frequency).
   unique_of[j]: the element's row u of the table of distinct elements; kind_of[u]: bit 0 point type (U21 = v) else
   field type (U12 = v), bit 1 v = 1 / poly, else v = poly = a2 s^2 + a1 s + a0 (coefficients[3 u..]); loads sorted by
   element, terms[8 l..]: alpha_f, beta_f, alpha_e, beta_e (re, im), u = alpha + beta v; s[2 b..]; start[4 b..]:
   S0, P0; end[6 b..]: Bm_f, Bm_e, b; B a multiple of K; slot[j] (j = 0..n): the stored point's index or -1;
   states[((k B + b) 2 + c) 2 ..]; finite[b]: the certificate; work: stack 4 K per point-type or loaded element,
   kept 4 K per stored point, table 2 K n_unique doubles.  determinant (NULL: not wanted): per frequency the
   product of the pivots G_j and of H as mantissa (re, im) times 2^exponent, determinant[3 b..] = re, im, exponent
   (the log-determinant of docs/riccati.md section 4 without one logarithm per element). */
static inline void renormalise(double *mr, double *mi, double *ex)
{
    const double big = fmax(fabs(*mr), fabs(*mi));
    if (big > 0x1p-200 && big < 0x1p200) return;
    if (!(big > 0.0) || !isfinite(big)) return;   /* zero, infinite or NaN: the logarithm says so */
    int shift;
    frexp(big, &shift);
    *mr = ldexp(*mr, -shift); *mi = ldexp(*mi, -shift); *ex += shift;
}

static inline void multiply(double *mr, double *mi, double *ex, double gr, double gi)
{
    const double tr = *mr * gr - *mi * gi, ti = *mr * gi + *mi * gr;
    *mr = tr; *mi = ti;
    renormalise(mr, mi, ex);
}

void chain_frequency(int n, int B, int f, const int *unique_of, int n_unique, const int *kind_of,
                     const double *coefficients, int n_loads, const int *load_element,
                     const double *terms, const double *s, const double *start, const double *end, const int *slot,
                     double *states, int *finite, double *stack, double *kept, double *table, double *determinant)
{
    const int e = 1 - f;
    int any_slot = 0;
    for (int j = 0; j <= n; ++j) any_slot |= slot[j] >= 0;
    for (int b0 = 0; b0 < B; b0 += K) {
        double sr[K], si[K], Sr[K], Si[K], Pr[K], Pi[K], Dr[K], Di[K], De[K];
        for (int k = 0; k < K; ++k) { Dr[k] = 1.0; Di[k] = 0.0; De[k] = 0.0; }
        for (int k = 0; k < K; ++k) {
            sr[k] = s[2 * (b0 + k)]; si[k] = s[2 * (b0 + k) + 1];
            const double *z = start + 4 * (b0 + k);
            Sr[k] = z[0]; Si[k] = z[1]; Pr[k] = z[2]; Pi[k] = z[3];
        }
        for (int u = 0; u < n_unique; ++u) {             /* v of every distinct element, once per block */
            const double *a = coefficients + 3 * u;
            double *vr = table + 2 * K * u, *vi = vr + K;
            for (int k = 0; k < K; ++k) {
                const double s2r = sr[k] * sr[k] - si[k] * si[k], s2i = sr[k] * si[k] + si[k] * sr[k];
                vr[k] = (a[2] + a[1] * sr[k]) + a[0] * s2r; vi[k] = a[1] * si[k] + a[0] * s2i;
                if (kind_of[u] & 2) reciprocal(vr[k], vi[k], vr + k, vi + k);
            }
        }
        int top = 0, next = 0;
        if (slot[0] >= 0) {
            double *c = kept + 4 * K * slot[0];
            for (int k = 0; k < K; ++k) { c[k] = Sr[k]; c[K + k] = Si[k]; c[2 * K + k] = Pr[k]; c[3 * K + k] = Pi[k]; }
        }
        for (int j = 0; j < n; ++j) {
            const double *vr = table + 2 * K * unique_of[j], *vi = vr + K;
            const int loaded = next < n_loads && load_element[next] == j;
            if (kind_of[unique_of[j]] & 1) {                          /* point type: G = v S + 1, S <- S / G, P <- P / G */
                double *w = stack + 4 * K * top++;
                for (int k = 0; k < K; ++k) {
                    double gr, gi;
                    const double Gr = vr[k] * Sr[k] - vi[k] * Si[k] + 1.0, Gi = vr[k] * Si[k] + vi[k] * Sr[k];
                    if (determinant) multiply(Dr + k, Di + k, De + k, Gr, Gi);
                    reciprocal(Gr, Gi, &gr, &gi);
                    const double tr = Sr[k] * gr - Si[k] * gi, ti = Sr[k] * gi + Si[k] * gr;
                    w[k] = gr; w[K + k] = gi;           /* 1 / G and r = v P (+ u_e below) */
                    w[2 * K + k] = vr[k] * Pr[k] - vi[k] * Pi[k]; w[3 * K + k] = vr[k] * Pi[k] + vi[k] * Pr[k];
                    const double qr = Pr[k] * gr - Pi[k] * gi, qi = Pr[k] * gi + Pi[k] * gr;
                    Sr[k] = tr; Si[k] = ti; Pr[k] = qr; Pi[k] = qi;
                }
            } else {                                    /* field type: S <- S + v, G = 1, r = u_e */
                for (int k = 0; k < K; ++k) { Sr[k] += vr[k]; Si[k] += vi[k]; }
                if (loaded) {
                    double *w = stack + 4 * K * top++;
                    for (int k = 0; k < K; ++k) { w[k] = 1.0; w[K + k] = 0.0; w[2 * K + k] = 0.0; w[3 * K + k] = 0.0; }
                }
            }
            if (loaded) {                               /* r += u_e, P <- P - S u_e + u_f */
                const double *t = terms + 8 * next;
                double *w = stack + 4 * K * (top - 1);
                for (int k = 0; k < K; ++k) {
                    const double ufr = t[0] + t[2] * vr[k] - t[3] * vi[k], ufi = t[1] + t[2] * vi[k] + t[3] * vr[k];
                    const double uer = t[4] + t[6] * vr[k] - t[7] * vi[k], uei = t[5] + t[6] * vi[k] + t[7] * vr[k];
                    w[2 * K + k] += uer; w[3 * K + k] += uei;
                    const double qr = Pr[k] - (Sr[k] * uer - Si[k] * uei), qi = Pi[k] - (Sr[k] * uei + Si[k] * uer);
                    Pr[k] = qr + ufr; Pi[k] = qi + ufi;
                }
                ++next;
            }
            if (slot[j + 1] >= 0) {
                double *c = kept + 4 * K * slot[j + 1];
                for (int k = 0; k < K; ++k) { c[k] = Sr[k]; c[K + k] = Si[k]; c[2 * K + k] = Pr[k]; c[3 * K + k] = Pi[k]; }
            }
        }
        double er[K], ei[K];
        for (int k = 0; k < K; ++k) {                   /* H e_N = b - Bm_f P_N, H = Bm_f S_N + Bm_e */
            const double *m = end + 6 * (b0 + k);
            double hr, hi;
            const double Hr = m[0] * Sr[k] - m[1] * Si[k] + m[2], Hi = m[0] * Si[k] + m[1] * Sr[k] + m[3];
            if (determinant) {
                multiply(Dr + k, Di + k, De + k, Hr, Hi);
                double *d = determinant + 3 * (b0 + k);
                d[0] = Dr[k]; d[1] = Di[k]; d[2] = De[k];
            }
            reciprocal(Hr, Hi, &hr, &hi);
            const double xr = m[4] - (m[0] * Pr[k] - m[1] * Pi[k]), xi = m[5] - (m[0] * Pi[k] + m[1] * Pr[k]);
            er[k] = xr * hr - xi * hi; ei[k] = xr * hi + xi * hr;
            finite[b0 + k] = isfinite(er[k]) && isfinite(ei[k]);
        }
        if (!any_slot) continue;                         /* the determinant only: no way back */
        next = n_loads - 1;
        for (int j = n; j >= 0; --j) {                  /* e_{j-1} = (e_j - r_j) / G_j; f_j = S_j e_j + P_j */
            if (slot[j] >= 0) {
                const double *c = kept + 4 * K * slot[j];
                for (int k = 0; k < K; ++k) {
                    double *z = states + 4 * ((long)slot[j] * B + b0 + k);
                    z[2 * e] = er[k]; z[2 * e + 1] = ei[k];
                    z[2 * f] = c[k] * er[k] - c[K + k] * ei[k] + c[2 * K + k];
                    z[2 * f + 1] = c[k] * ei[k] + c[K + k] * er[k] + c[3 * K + k];
                }
            }
            if (j == 0) break;
            const int loaded = next >= 0 && load_element[next] == j - 1;
            if (loaded) --next;
            if ((kind_of[unique_of[j - 1]] & 1) || loaded) {
                const double *w = stack + 4 * K * --top;
                for (int k = 0; k < K; ++k) {
                    const double xr = er[k] - w[2 * K + k], xi = ei[k] - w[3 * K + k];
                    er[k] = xr * w[k] - xi * w[K + k]; ei[k] = xr * w[K + k] + xi * w[k];
                }
            }
        }
    }
}
"""


BLOCK = 8
"""Frequencies per block of the C loop (``K`` in :data:`SOURCE`): their recursions run side by side."""


@functools.lru_cache(maxsize=1)
def compiled_library() -> ctypes.CDLL | None:
    """The compiled :data:`SOURCE` (built once per machine, cached on disk by :func:`ctmm.codegen.load_ctypes`), or
    None when no C compiler is found or the build fails (the numpy recursion answers then)."""
    from .codegen import load_ctypes

    try:
        library = load_ctypes(SOURCE, "chain_frequency")
    except ModelError:
        return None
    integers, doubles = ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_double)
    library.chain_frequency.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int, integers, ctypes.c_int, integers,
                                        doubles, ctypes.c_int, integers, doubles, doubles, doubles, doubles, integers,
                                        doubles, integers, doubles, doubles, doubles, doubles]
    library.chain_frequency.restype = None
    return library


def solve_entries(library: ctypes.CDLL, s: np.ndarray, unique_of: Sequence[int], table: Sequence[tuple],
                  loads: dict[int, tuple[complex, complex, complex, complex]], start: BoundaryStart, end: BoundaryEnd,
                  f: int, e: int, points: Sequence[int], *, want_log_det: bool = False,
                  certify: bool = True) -> ChainSolution:
    """States at ``points`` of a lumped chain by the compiled recursion (see the module text).

    Parameters
    ----------
    library : ctypes.CDLL
        :func:`compiled_library`.
    s : ndarray, shape (B,)
        Laplace variables [1/s].
    unique_of : sequence of int
        Per element (``N``): its row in ``table``.
    table : sequence of tuple
        The distinct elements ``(kind, a2, a1, a0)``: ``kind`` :data:`FIELD` or :data:`POINT`, plus
        :data:`RECIPROCAL` when ``v = 1 / poly``; ``poly = a2 s^2 + a1 s + a0`` (``v`` in N/m or m/N), floats.
    loads : dict
        ``{element index (0-based): (alpha_f, beta_f, alpha_e, beta_e)}``, the load ``u = alpha + beta v``.
    start, end : BoundaryStart, BoundaryEnd
        Boundary relations (``(B, 1, 1)``, ``(B, 1)``, ``(B, 1, 2)``, ``(B, 1)``).
    f, e : int
        State components known (``f``) and unknown (``e``) at the start.
    points : sequence of int
        Connection points ``0..N`` to return, in that order (empty: the determinant only, no back-substitution).
    want_log_det : bool
        Also the characteristic log-determinant ``sum log G_j + log H`` (``docs/riccati.md`` §4), accumulated in C
        as a product scaled by powers of two (no overflow); equal to the numpy recursion's modulo ``2 pi i``.
    certify : bool
        Raise where the end unknown is not finite (default).  False: return the non-finite entries (the
        characteristic function repairs them by circle means, :func:`ctmm.entire_values.entire_logs`).

    Returns
    -------
    ChainSolution
        ``states`` ``(len(points), B, 2)``, ``points``, ``kernel = "compiled"``; ``log_det`` zeros unless wanted.

    Raises
    ------
    SingularSystemError
        The end unknown is not finite at some frequencies (the same certificate as the numpy recursion).
    """
    unique_of = np.ascontiguousarray(unique_of, dtype=np.intc)
    n, B = unique_of.size, s.shape[0]
    rows = [int(j) for j in points]
    if any(not 0 <= j <= n for j in rows):
        raise ValueError(f"points must lie in 0..{n}, got {list(points)}")
    unique = sorted(set(rows))
    slot = np.full(n + 1, -1, dtype=np.intc)
    slot[unique] = np.arange(len(unique), dtype=np.intc)
    values = np.array(table, dtype=float).reshape(-1, 4)
    kind_of = np.ascontiguousarray(values[:, 0], dtype=np.intc)
    coefficients = np.ascontiguousarray(values[:, 1:])
    order = sorted(loads)
    load_element = np.array(order, dtype=np.intc)
    terms = np.array([loads[j] for j in order], dtype=complex).reshape(len(order), 4)
    padded = -(-B // BLOCK) * BLOCK                                   # the last block repeats the last frequency
    take = np.minimum(np.arange(padded), B - 1)
    s_values = np.ascontiguousarray(np.asarray(s, dtype=complex)[take])
    start_values = np.ascontiguousarray(np.stack([start.S0[:, 0, 0], start.P0[:, 0]], axis=1)[take], dtype=complex)
    end_values = np.ascontiguousarray(np.stack([end.Bm[:, 0, f], end.Bm[:, 0, e], end.b[:, 0]], axis=1)[take],
                                      dtype=complex)
    states = np.empty((len(unique), padded, 2), dtype=complex)
    determinant = np.empty((padded, 3)) if want_log_det else None
    finite = np.zeros(padded, dtype=np.intc)
    pushed = int(np.count_nonzero(kind_of[unique_of] & POINT)) + len(order)   # G_j, r_j kept for the way back
    work = [np.empty(4 * BLOCK * max(pushed, 1)), np.empty(4 * BLOCK * len(unique)), np.empty(2 * BLOCK * len(values))]
    integers, doubles = ctypes.POINTER(ctypes.c_int), ctypes.POINTER(ctypes.c_double)

    def pointer(array: np.ndarray, kind=doubles):
        return array.ctypes.data_as(kind)

    library.chain_frequency(n, padded, f, pointer(unique_of, integers), len(values), pointer(kind_of, integers),
                            pointer(coefficients), len(order), pointer(load_element, integers), pointer(terms),
                            pointer(s_values), pointer(start_values), pointer(end_values), pointer(slot, integers),
                            pointer(states), pointer(finite, integers), *(pointer(w) for w in work),
                            pointer(determinant) if want_log_det else None)
    log_det = np.zeros(B, dtype=complex)
    if want_log_det:
        mantissa = determinant[:B, 0] + 1j * determinant[:B, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            log_det = np.log(mantissa) + determinant[:B, 2] * np.log(2.0)
    if certify and not np.all(finite[:B]):
        bad = np.flatnonzero(finite[:B] == 0)
        raise SingularSystemError(
            f"the boundary equations are singular for batch entries {bad[:10].tolist()}"
            " (e.g. a free-free chain under a static load, or a frequency exactly at a natural frequency)")
    states = states[:, :B]
    if rows != unique:
        states = states[[unique.index(j) for j in rows]]
    return ChainSolution(states, log_det, tuple(rows), kernel="compiled")
