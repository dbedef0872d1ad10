"""Derivation checks for the Riccati transfer, Wittrick-Williams counting and the
characteristic function (docs/riccati.md).

1. The Riccati recursion ``f_j = S_j e_j + P_j`` is derived with sympy from one element's block
   equations and compared with :func:`ctmm.assembly.riccati_solve` on random chains.
2. Determinant identity: ``det(Bm Z_N) = det(H) * prod_j det(G_j)`` -- the plain overall
   boundary determinant equals the product accumulated by the sweep (symbolic, 3 elements).
3. Digit loss of the plain product: one DT-TMM Newmark step of the Table 7.1 chain, plain
   against Riccati against the global banded solve (FORMULAS §4.1).
4. Wittrick-Williams: the stiffness-form sweep of :func:`ctmm.frequency.eigenvalue_count`
   produces exactly the pivots of Gaussian elimination of the dynamic stiffness matrix
   (symbolic, 3 masses), hence the eigenvalue count (checked against ``eigh``).
5. Characteristic function: ``characteristic_function(s)`` is proportional to
   ``det(s^2 M + s C + K)`` of the global model.

Run ``python docs/derivations/riccati.py``; ``tests/test_derivations.py`` runs every ``check_*``.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

import ctmm
from ctmm.assembly import BoundaryEnd, BoundaryStart, plain_solve, riccati_solve
from ctmm.elements.boundary import Fixed, Free
from ctmm.elements.lumped import GroundedSpring, Mass, Spring, SpringDamper
from ctmm.reference import chain as reference


def solve_linear(equations, unknowns) -> dict:
    """Solve equations that are linear in ``unknowns`` (a unique solution is asserted)."""
    if isinstance(equations, sp.Eq):
        equations = [equations]
    unknowns = list(unknowns) if isinstance(unknowns, (list, tuple)) else [unknowns]
    matrix, rhs = sp.linear_eq_to_matrix([e.lhs - e.rhs for e in equations], unknowns)
    assert matrix.shape[0] == matrix.shape[1] and sp.cancel(matrix.det()) != 0, \
        f"equations do not determine {unknowns} uniquely"
    sol = matrix.LUsolve(rhs)
    return {q: sp.cancel(v) for q, v in zip(unknowns, sol)}


RNG = np.random.default_rng(42)


# -- 1. the recursion ---------------------------------------------------------------------------
def derive_recursion():
    """Eliminate the state at the inboard point: returns (G, S_new, P_new, e_back) for d = 1."""
    U11, U12, U21, U22, u1, u2, S, P, e_in, e_out = sp.symbols("U11 U12 U21 U22 u1 u2 S P e_in e_out")
    f_in = S * e_in + P                                   # Riccati relation at the inboard point
    f_out = U11 * f_in + U12 * e_in + u1                  # element, f-rows
    e_out_expr = U21 * f_in + U22 * e_in + u2             # element, e-rows
    e_in_sol = solve_linear(sp.Eq(e_out, e_out_expr), e_in)[e_in]
    f_out_e = sp.expand(sp.cancel(f_out.subs(e_in, e_in_sol)))
    S_new = sp.cancel(f_out_e.coeff(e_out))
    P_new = sp.cancel(f_out_e.subs(e_out, 0))
    G = U21 * S + U22
    return dict(symbols=(U11, U12, U21, U22, u1, u2, S, P, e_out), G=G, S=S_new, P=P_new, e_in=e_in_sol)


def check_recursion_formulas():
    """S_j = (U11 S + U12) G^-1, P_j = U11 P + u1 - S_j (U21 P + u2), e_in = G^-1 (e_out - U21 P - u2)."""
    d = derive_recursion()
    U11, U12, U21, U22, u1, u2, S, P, e_out = d["symbols"]
    G = d["G"]
    assert sp.cancel(d["S"] - (U11 * S + U12) / G) == 0
    assert sp.cancel(d["P"] - (U11 * P + u1 - (U11 * S + U12) / G * (U21 * P + u2))) == 0
    assert sp.cancel(d["e_in"] - (e_out - U21 * P - u2) / G) == 0


def _random_chain_problem(n_elements=6, n=4, batch=3, complex_=True):
    """Random element matrices (d = 2), fixed-type start, mixed end: (Us, us, start, end)."""
    dtype = complex if complex_ else float

    def rnd(*shape):
        a = RNG.normal(size=shape)
        return a + 1j * RNG.normal(size=shape) if complex_ else a
    Us = [np.eye(n)[None].repeat(batch, 0).astype(dtype) + 0.5 * rnd(batch, n, n) for _ in range(n_elements)]
    us = [rnd(batch, n) for _ in range(n_elements)]
    d = n // 2
    start = BoundaryStart(list(range(d, n)), 0.3 * rnd(batch, d, d), rnd(batch, d))
    end = BoundaryEnd(rnd(batch, d, n), rnd(batch, d))
    return Us, us, start, end


def _dense_solve(Us, us, start, end):
    """All states by one dense linear system (independent of both sweeps)."""
    N, (B, n, _) = len(Us), Us[0].shape
    e_idx = start.e_indices
    f_idx = [i for i in range(n) if i not in e_idx]
    m = (N + 1) * n
    states = np.empty((N + 1, B, n), dtype=complex)
    for b in range(B):
        M = np.zeros((m, m), dtype=complex)
        r = np.zeros(m, dtype=complex)
        row = 0
        for k, i in enumerate(f_idx):          # start: z_f - S0 z_e = P0
            M[row, i] = 1.0
            M[row, e_idx] -= start.S0[b, k]
            r[row] = start.P0[b, k]
            row += 1
        for j, (U, u) in enumerate(zip(Us, us), start=1):
            M[row:row + n, j * n:(j + 1) * n] = np.eye(n)
            M[row:row + n, (j - 1) * n:j * n] = -U[b]
            r[row:row + n] = u[b]
            row += n
        M[row:, N * n:] = end.Bm[b]
        r[row:] = end.b[b]
        states[:, b, :] = np.linalg.solve(M, r).reshape(N + 1, n)
    return states


def check_riccati_equals_plain_and_dense():
    """On short random chains Riccati = plain products = one dense solve of all equations."""
    for complex_ in (True, False):
        Us, us, start, end = _random_chain_problem(complex_=complex_)
        ric = riccati_solve(Us, us, start, end).states
        pla = plain_solve(Us, us, start, end).states
        den = _dense_solve(Us, us, start, end)
        scale = np.max(np.abs(den))
        assert np.max(np.abs(ric - den)) < 1e-10 * scale, np.max(np.abs(ric - den))
        assert np.max(np.abs(pla - den)) < 1e-10 * scale, np.max(np.abs(pla - den))


# -- 2. determinant identity --------------------------------------------------------------------
def _determinant_identity(n_elements: int, values: dict | None = None):
    """plain boundary determinant - H prod G_j for generic 2x2 elements (d = 1), start f = S0 e."""
    syms = [sp.symbols(f"a{j} b{j} c{j} d{j}") for j in range(n_elements)]
    S0, bf, be = sp.symbols("S0 b_f b_e")
    sub = values or {}
    Us = [sp.Matrix([[a, b], [c, d]]).subs(sub) for a, b, c, d in syms]   # order (f, e)
    Z = sp.Matrix([S0, 1]).subs(sub)                                      # z_0 = [S0; 1] e_0
    for U in Us:
        Z = U * Z
    bfv, bev = sp.sympify(bf).subs(sub), sp.sympify(be).subs(sub)
    plain = bfv * Z[0] + bev * Z[1]
    S, prod = sp.sympify(S0).subs(sub), 1
    for U in Us:
        G = U[1, 0] * S + U[1, 1]
        prod *= G
        S = (U[0, 0] * S + U[0, 1]) / G
    H = bfv * S + bev
    return plain - H * prod, [s for group in syms for s in group] + [S0, bf, be]


def check_determinant_identity():
    """det(Bm Z_N) = det(H) prod_j det(G_j): symbolic for two elements, exact rational
    arithmetic at random points for five (polynomial identity test)."""
    diff, _ = _determinant_identity(2)
    assert sp.cancel(diff) == 0
    rng = np.random.default_rng(3)
    _, symbols = _determinant_identity(5, {})
    for _ in range(5):
        values = {sym: sp.Rational(int(rng.integers(-50, 50)), int(rng.integers(1, 20))) for sym in symbols}
        diff, _ = _determinant_identity(5, values)
        assert diff == 0, diff


def check_log_det_matches_plain():
    """riccati_solve's log_det equals log det of the plain boundary matrix (random, d = 2)."""
    Us, us, start, end = _random_chain_problem()
    ric = riccati_solve(Us, us, start, end, want_states=False).log_det
    pla = plain_solve(Us, us, start, end).log_det
    assert np.allclose(np.exp(ric - pla), 1.0, rtol=1e-9), np.exp(ric - pla)


# -- 3. digit loss of the plain product ---------------------------------------------------------
def table_7_1_chain():
    elements = [Fixed("wall")]
    for i in range(1, 6):
        elements += [Spring(f"k{i}", 1000.0, free_length=0.1), Mass(f"m{i}", 0.1, force=100.0 if i == 1 else 0.0)]
    return ctmm.Chain("table_7_1", elements + [Free("end")])


def check_plain_product_loses_digits():
    """One Newmark step, h = 1e-4 (FORMULAS §4.1): Riccati at round-off, plain product far off."""
    system = table_7_1_chain()
    glob = reference.GlobalChain(np.full(5, 0.1), [1000.0] * 5 + [0.0], free_length=[0.1] * 5 + [0.0],
                                 start="fixed", end="free")
    rest = reference.unstretched_positions(glob)
    x0 = {f"m{i}": 0.1 * i for i in range(1, 6)}
    h = 1e-4
    force = np.array([100.0, 0, 0, 0, 0])
    ref_x = rest + reference.newmark_global(glob, h, h, np.zeros(5), np.zeros(5), lambda t: force,
                                            banded=True).displacement[-1]
    errors = {}
    for solver in ("riccati", "plain"):
        sim = ctmm.simulate(system, h, h, x0=x0, solver=solver, fast=False)
        x = np.array([sim[f"m{i}.x"][-1] for i in range(1, 6)])
        errors[solver] = float(np.max(np.abs(x - ref_x)))
    assert errors["riccati"] < 1e-13, errors
    # the plain product's error depends on the unknown it is applied to; it must be far above
    # the Riccati round-off (FORMULAS §4.1 measured 3.0e-4 m in the book's absolute form)
    assert errors["plain"] > 1e3 * max(errors["riccati"], 1e-17), errors
    return errors


# -- 4. Wittrick-Williams -----------------------------------------------------------------------
def check_wittrick_williams_pivots():
    """The sweep's pivots are the Gaussian-elimination pivots of D = K - w^2 M (3 masses)."""
    k1, k2, k3, m1, m2, m3, w2 = sp.symbols("k1 k2 k3 m1 m2 m3 w2", positive=True)
    ks, ms = (k1, k2, k3), (m1, m2, m3)
    # global dynamic stiffness, fixed-free: wall-k1-m1-k2-m2-k3-m3
    D = sp.Matrix([[k1 + k2 - m1 * w2, -k2, 0], [-k2, k2 + k3 - m2 * w2, -k3], [0, -k3, k3 - m3 * w2]])
    pivots_ge = []
    A = D
    for i in range(3):
        pivots_ge.append(sp.cancel(A[0, 0]))
        A = (A[1:, 1:] - A[1:, 0] * A[0, 1:] / A[0, 0]).applyfunc(sp.cancel)
    # stiffness-form sweep (frequency.eigenvalue_count): f = S x, clamped start
    # connector U = [[1, -1/k], [0, 1]], point U = [[1, 0], [m w^2, 1]] (s = i w, U21 = -m s^2)
    pivots_tmm = []
    S = None
    for j in range(3):
        U11, U12, U21, U22 = 1, -1 / ks[j], 0, 1
        if S is None:                                  # first field element after the wall
            S = U22 / U12
        else:
            G = U11 + U12 * S
            pivots_tmm.append(sp.cancel(-G / U12))     # pivot = -U12^-1 (U11 + U12 S)
            S = (U21 + U22 * S) / G
        S = S + ms[j] * w2                             # mass: S <- U21 + S
    pivots_tmm.append(sp.cancel(0 - S))                # free end: k_end - S, k_end = 0
    for p_ge, p_tmm in zip(pivots_ge, pivots_tmm):
        assert sp.cancel(p_ge - p_tmm) == 0, (p_ge, p_tmm)


def check_eigenvalue_count():
    """eigenvalue_count(omega) = number of eigh frequencies below omega (random chain)."""
    n = 6
    m = RNG.uniform(0.5, 2.0, n)
    k = RNG.uniform(50, 200, n)
    kg = np.where(RNG.uniform(size=n) < 0.5, RNG.uniform(10, 50, n), 0.0)
    elements = [Fixed("wall")]
    for i in range(n):
        elements.append(Spring(f"k{i}", k[i]))
        elements.append(Mass(f"m{i}", m[i]))
        if kg[i] > 0:
            elements.append(GroundedSpring(f"g{i}", kg[i]))
    system = ctmm.Chain("ww", elements + [Free("end")])
    glob = reference.GlobalChain(m, np.append(k, 0.0), ground_stiffness=kg, start="fixed", end="free")
    exact = reference.natural_frequencies(glob)
    omega = np.sort(np.concatenate([RNG.uniform(0, 1.2 * exact[-1], 40), exact * (1 - 1e-9), exact * (1 + 1e-9)]))
    count = ctmm.eigenvalue_count(system, omega)
    assert np.array_equal(count, np.searchsorted(exact, omega)), (count, np.searchsorted(exact, omega))


# -- 5. characteristic function -----------------------------------------------------------------
def check_characteristic_function():
    """characteristic_function(s) / det(s^2 M + s C + K) is one constant (damped chain)."""
    n = 4
    m, k, c = RNG.uniform(0.5, 2.0, n), RNG.uniform(50, 200, n), RNG.uniform(0.1, 1.0, n)
    elements = [Fixed("wall")]
    for i in range(n):
        elements += [SpringDamper(f"k{i}", k[i], c[i]), Mass(f"m{i}", m[i])]
    system = ctmm.Chain("cf", elements + [Free("end")])
    glob = reference.GlobalChain(m, np.append(k, 0.0), np.append(c, 0.0), start="fixed", end="free")
    M, C, K = reference.assemble(glob)
    s = np.array([0.3 + 2.0j, -0.5 + 7.0j, 1.0 + 0.0j, 0.1 + 15.0j])
    delta = ctmm.characteristic_function(system, s)
    dets = np.array([np.linalg.det(sv ** 2 * M + sv * C + K) for sv in s])
    ratio = delta / dets
    assert np.allclose(ratio, ratio[0], rtol=1e-10), ratio


CHECKS = [check_recursion_formulas, check_riccati_equals_plain_and_dense, check_determinant_identity,
          check_log_det_matches_plain, check_plain_product_loses_digits, check_wittrick_williams_pivots,
          check_eigenvalue_count, check_characteristic_function]


if __name__ == "__main__":
    d = derive_recursion()
    print("G =", d["G"], "  S_new =", d["S"], "  P_new =", d["P"], "  e_in =", d["e_in"])
    for check in CHECKS:
        out = check()
        print("ok", check.__name__, "" if out is None else out)
