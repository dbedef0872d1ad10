"""Chain assembly: Riccati transfer (default) and plain transfer-matrix products.

Both solve the two-point boundary-value problem

    z_j = U_j z_{j-1} + u_j   (j = 1..N),   z_f,0 = S0 z_e,0 + P0   (start),   Bm z_N = b   (end)

for all connection-point states ``z_0..z_N``, batched over a leading axis (frequencies or
parameter sets).

Riccati transfer (Horner & Pilkey 1978; FORMULAS §4.2)
-----------------------------------------------------
Split ``z = [f; e]`` with ``e`` the components unknown at the start.  Carry the relation
``f_j = S_j e_j + P_j`` instead of the overall product.  For an element with blocks
``U11 (f<-f), U12 (f<-e), U21 (e<-f), U22 (e<-e)`` and affine parts ``u1, u2``:

    G_j     = U21 S_{j-1} + U22
    S_j     = (U11 S_{j-1} + U12) G_j^{-1}
    P_j     = U11 P_{j-1} + u1 - S_j (U21 P_{j-1} + u2)

At the end ``(Bm_f S_N + Bm_e) e_N = b - Bm_f P_N``; back-substitution
``e_{j-1} = G_j^{-1} (e_j - U21 P_{j-1} - u2)``, ``f_j = S_j e_j + P_j``.  Every quantity stays
of order one, so no digits are lost to cancellation between huge products; the plain product
loses them on long chains, stiff DT-TMM steps and high frequencies (tests/test_riccati_hard.py).

The characteristic function (determinant of the boundary equations) is accumulated without
cancellation as ``log det`` of the ``G_j`` and of the final boundary matrix.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .errors import SingularSystemError


@dataclass
class BoundaryStart:
    """Start relation ``z_f = S0 z_e + P0`` (arrays batched on axis 0)."""

    e_indices: list[int]
    S0: np.ndarray  # (B, nf, m)
    P0: np.ndarray  # (B, nf)


@dataclass
class BoundaryEnd:
    """End condition ``Bm z_N = b`` (arrays batched on axis 0)."""

    Bm: np.ndarray  # (B, m, n)
    b: np.ndarray   # (B, m)


@dataclass
class ChainSolution:
    """States at the connection points, shape ``(N + 1, B, n)``, and ``log det`` of the BVP.

    With ``points`` set (a solve asked for some points only), ``states`` holds those points'
    states in that order, shape ``(len(points), B, n)``; :meth:`at` reads either form.
    """

    states: np.ndarray
    log_det: np.ndarray  # (B,) complex: log of the characteristic determinant (up to a constant)
    points: tuple[int, ...] | None = None
    kernel: str = "numpy"  # "compiled": the C recursion of ctmm.compiled_chain_frequency answered

    def at(self, point: int) -> np.ndarray:
        """States ``(B, n)`` at connection point ``point`` (0 = start)."""
        if self.points is None:
            return self.states[point]
        return self.states[self.points.index(point)]


def _solve_small(G: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve ``G x = rhs`` for batched small square ``G`` (rhs (..., m) or (..., m, k))."""
    if G.shape[-1] == 1:
        return rhs / G[..., 0:1, 0:1] if rhs.ndim == G.ndim else rhs / G[..., 0, :]
    if rhs.ndim == G.ndim - 1:
        return np.linalg.solve(G, rhs[..., None])[..., 0]
    return np.linalg.solve(G, rhs)


def _solve_boundary(H: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``_solve_small(H, rhs)`` for the end equations, NaN in the batch entries where ``H`` is singular
    (numpy raises ``LinAlgError`` for an exactly singular matrix; the callers name those entries)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        try:
            return _solve_small(H, rhs)
        except np.linalg.LinAlgError:
            batch = np.broadcast_shapes(H.shape[:-2], rhs.shape[:-1])
            H, rhs = np.broadcast_to(H, batch + H.shape[-2:]), np.broadcast_to(rhs, batch + rhs.shape[-1:])
            e = np.full(rhs.shape, np.nan, dtype=np.result_type(H, rhs))
            for k in np.ndindex(*batch):
                try:
                    e[k] = _solve_small(H[k], rhs[k])
                except np.linalg.LinAlgError:
                    pass
            return e


def _logdet(G: np.ndarray) -> np.ndarray:
    if G.shape[-1] == 1:
        return np.log(G[..., 0, 0].astype(complex))
    sign, logabs = np.linalg.slogdet(G)
    return np.log(sign.astype(complex)) + logabs


def riccati_solve(Us: Sequence[np.ndarray], us: Sequence[np.ndarray], start: BoundaryStart,
                  end: BoundaryEnd, *, want_states: bool = True, homogeneous: bool = False,
                  want_log_det: bool = True) -> ChainSolution:
    """Solve the chain BVP by Riccati transfer.

    Parameters
    ----------
    Us : sequence of ndarray
        Element transfer matrices, each ``(B, n, n)``.
    us : sequence of ndarray
        Affine parts, each ``(B, n)``.
    start, end : BoundaryStart, BoundaryEnd
        Boundary relations.  For ``n > 2``, leading batch axes broadcast: load cases sharing their
        matrices pass ``Us`` as ``(1, B, n, n)`` and ``us``, ``P0``, ``b`` as ``(k, B, ...)``; the
        states are then ``(N + 1, k, B, n)`` (:func:`ctmm.chain_assembly.solve_load_cases`).
    want_states : bool
        If False, only the characteristic ``log_det`` is computed (no back-substitution).
    want_log_det : bool
        If False, skip the characteristic determinant (``log_det`` is returned as zeros); the
        frequency response does not need it.
    homogeneous : bool
        If True, return the non-trivial solution of the homogeneous problem (a mode shape):
        ``e_N`` is the right singular vector of the (singular) end matrix for its smallest
        singular value; loads ``u``, ``P0`` and ``b`` must be zero.

    Raises
    ------
    SingularSystemError
        If the boundary equations are singular for some batch entry.
    """
    n = Us[0].shape[-1]
    e_idx = list(start.e_indices)
    f_idx = [i for i in range(n) if i not in e_idx]
    if n == 2 and len(e_idx) == 1 and want_states and not homogeneous:
        return _riccati_scalar(Us, us, start, end, f_idx[0], e_idx[0], want_log_det)
    perm = np.array(f_idx + e_idx)
    nf = len(f_idx)
    S, P = start.S0, start.P0
    dtype = np.result_type(S, P, *Us[:1], *us[:1])
    log_det = np.zeros(S.shape[0], dtype=complex)
    record = []
    for U, u in zip(Us, us):
        Up = U[..., perm[:, None], perm[None, :]]
        up = u[..., perm]
        U11, U12, U21, U22 = Up[..., :nf, :nf], Up[..., :nf, nf:], Up[..., nf:, :nf], Up[..., nf:, nf:]
        u1, u2 = up[..., :nf], up[..., nf:]
        G = U21 @ S + U22
        numer = U11 @ S + U12
        # S_new = numer G^{-1}  <=>  G^T S_new^T = numer^T
        S_new = np.swapaxes(_solve_small(np.swapaxes(G, -1, -2), np.swapaxes(numer, -1, -2)), -1, -2)
        r = np.einsum("...ij,...j->...i", U21, P) + u2
        P_new = np.einsum("...ij,...j->...i", U11, P) + u1 - np.einsum("...ij,...j->...i", S_new, r)
        if want_log_det:
            log_det = log_det + _logdet(G)
        if want_states:
            record.append((G, r, S, P))
        S, P = S_new, P_new
    Bp = end.Bm[..., perm]
    Bf, Be = Bp[..., :nf], Bp[..., nf:]
    H = Bf @ S + Be
    if want_log_det:
        log_det = log_det + _logdet(H)
    if not want_states:
        return ChainSolution(np.empty((0,)), log_det)
    if homogeneous:
        e = np.conj(np.linalg.svd(H)[2][..., -1, :])
    else:
        e = _solve_boundary(H, end.b - np.einsum("...ij,...j->...i", Bf, P))
    if not np.all(np.isfinite(e)):
        bad = np.flatnonzero(~np.all(np.isfinite(e), axis=-1))
        raise SingularSystemError(
            f"the boundary equations are singular for batch entries {bad[:10].tolist()}"
            " (e.g. a free-free chain under a static load, or a frequency exactly at a natural frequency)")
    N = len(Us)
    states = np.empty((N + 1,) + e.shape[:-1] + (n,), dtype=np.result_type(dtype, e))
    inv = np.argsort(perm)
    for j in range(N, 0, -1):
        G, r, S_prev, P_prev = record[j - 1]
        f = np.einsum("...ij,...j->...i", S, e) + P
        states[j] = np.concatenate([f, e], axis=-1)[..., inv]
        e = _solve_small(G, e - r)
        S, P = S_prev, P_prev
    f = np.einsum("...ij,...j->...i", S, e) + P
    states[0] = np.concatenate([f, e], axis=-1)[..., inv]
    return ChainSolution(states, log_det)


def _riccati_scalar(Us, us, start: BoundaryStart, end: BoundaryEnd, f: int, e: int,
                    want_log_det: bool) -> ChainSolution:
    """:func:`riccati_solve` for 2-component states with one unknown: the same recursion on
    ``(B,)`` arrays (no permutation copies, no ``(B, 1, 1)`` temporaries)."""
    entries = [(U[:, f, f], U[:, f, e], U[:, e, f], U[:, e, e], u[:, f], u[:, e]) for U, u in zip(Us, us)]
    return riccati_scalar_entries(entries, start, end, f, e, want_log_det)


def _scalar(value: Any, constant: float) -> bool:
    """``value`` is a Python number equal to ``constant`` (a unit or zero entry kept as a scalar)."""
    return isinstance(value, (int, float)) and value == constant


def riccati_scalar_entries(entries, start: BoundaryStart, end: BoundaryEnd, f: int, e: int,
                           want_log_det: bool = False, points: Sequence[int] | None = None) -> ChainSolution:
    """Riccati transfer of a 2-component chain given element *entries* instead of matrices.

    ``entries[j] = (U_ff, U_fe, U_ef, U_ee, u_f, u_e)`` in the start partition (``f`` known at
    the start, ``e`` unknown), each a ``(B,)`` array or a Python scalar (identity and zero entries
    of lumped elements stay scalars, which saves most of the work: a connector in compliance form
    costs one array operation forward, a mass five).  ``points``: return the states of these
    connection points only (memory ``O(len(points) B)`` for the Riccati pairs instead of ``O(N B)``;
    :attr:`ChainSolution.points`).
    """
    S = start.S0[:, 0, 0]
    P = start.P0[:, 0]
    B = S.shape[0]
    keep = None if points is None else {int(j) for j in points}
    G_all, R_all, S_all, P_all = [], [], [S], [P]
    log_det = np.zeros(B, dtype=complex)
    N = len(entries)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for U11, U12, U21, U22, uf, ue in entries:
            if _scalar(U21, 0.0) and _scalar(U11, 1.0) and _scalar(U22, 1.0):
                # field type (a connector in compliance form): G = 1, det(U) = 1
                G = 1.0
                if not _scalar(U12, 0.0):
                    S = S + U12
                r = ue
                if not _scalar(ue, 0.0):
                    P = P - S * ue
                if not _scalar(uf, 0.0):
                    P = P + uf
            elif _scalar(U12, 0.0) and _scalar(U11, 1.0) and _scalar(U22, 1.0):
                # point type (a mass in compliance form): G = U21 S + 1, det(U) = 1
                G = U21 * S + 1.0
                S = S / G
                r = U21 * P + ue
                P = P / G
                if not _scalar(ue, 0.0):
                    P = P - S * ue
                if not _scalar(uf, 0.0):
                    P = P + uf
            else:
                G = U21 * S + U22
                S = (U11 * S + U12) / G
                r = U21 * P + ue
                # U11 P + uf - S r with U11 - S U21 = det(U) / G: no cancellation when S U21 ~ U11
                # (e.g. a soft connector after a stiff part in stiffness form)
                P = (U11 * U22 - U12 * U21) / G * P + uf - S * ue
            G_all.append(G)
            R_all.append(r)
            wanted = keep is None or len(S_all) in keep
            S_all.append(S if wanted else None)
            P_all.append(P if wanted else None)
        Bf, Be = end.Bm[:, 0, f], end.Bm[:, 0, e]
        H = Bf * S + Be
        ev = (end.b[:, 0] - Bf * P) / H
    if want_log_det:
        log_det = (np.sum([np.log(np.broadcast_to(G, (B,)).astype(complex)) for G in G_all], axis=0)
                   + np.log(H.astype(complex)))
    if not np.all(np.isfinite(ev)):
        bad = np.flatnonzero(~np.isfinite(ev))
        raise SingularSystemError(
            f"the boundary equations are singular for batch entries {bad[:10].tolist()}"
            " (e.g. a free-free chain under a static load, or a frequency exactly at a natural frequency)")
    dtype = np.result_type(ev, S, P)
    rows = list(range(N + 1)) if points is None else [int(j) for j in points]
    if any(not 0 <= j <= N for j in rows):
        raise ValueError(f"points must lie in 0..{N}, got {list(points)}")
    row_of: dict[int, list[int]] = {}
    for k, j in enumerate(rows):
        row_of.setdefault(j, []).append(k)
    states = np.empty((len(rows), B, 2), dtype=dtype)
    for j in range(N, -1, -1):
        for k in row_of.get(j, ()):
            states[k, :, e] = ev
            states[k, :, f] = S_all[j] * ev + P_all[j]
        if j:
            r, G = R_all[j - 1], G_all[j - 1]
            if not _scalar(r, 0.0):
                ev = ev - r
            if not _scalar(G, 1.0):
                ev = ev / G
    return ChainSolution(states, log_det, None if points is None else tuple(rows))


def clamped_start_solve(Us: Sequence[np.ndarray], us: Sequence[np.ndarray], start: BoundaryStart,
                        end: BoundaryEnd, *, want_log_det: bool = True) -> ChainSolution:
    """:func:`riccati_solve` in stiffness form for a chain whose start displacements are known.

    A known start displacement makes the Riccati relation the compliance form
    ``x_j = S_j F_j + P_j``, with ``P_j`` the displacement of the chain cut at ``j`` under its
    loads.  On stiff chains (a soft field element near the start, stiff ones further out; a
    DT-TMM step at a large step size) ``P_j`` is orders of magnitude larger than the solution and
    the digits are lost when ``x_j`` is formed.  The stiffness form ``F_j = S_j x_j + P_j``
    carries ``P_j``, the reaction of the chain clamped at ``j``, which its loads bound: its
    recursion is Gaussian elimination without pivoting of the effective stiffness matrix.

    Elements whose displacement does not depend on the inboard force (``U_xF = 0``: point
    elements) pass the known displacement on, ``x <- U_xx x + u_x``.  The first element with an
    invertible ``U_xF`` (a field element) turns it into a force-type start at its outboard point:
    from ``x_1 = U_xx x_0 + U_xF F_0 + u_x`` and ``F_1 = U_Fx x_0 + U_FF F_0 + u_F``,

        F_1 = S' x_1 + P',   S' = U_FF U_xF^-1,   P' = U_Fx x_0 + u_F - S' (U_xx x_0 + u_x)

    The rest of the chain is solved by :func:`riccati_solve`; the forces of the clamped prefix
    follow backwards from ``F_in = U_FF^-1 (F_out - U_Fx x_in - u_F)``.  Falls back to
    :func:`riccati_solve` when the start is not of displacement type or no such element exists
    before the last one.  ``log_det`` is that of the rebased problem (not used in time stepping: pass
    ``want_log_det=False`` to skip it, as :func:`riccati_solve`).
    """
    n = Us[0].shape[-1]
    d = n // 2
    if 2 * d != n or sorted(start.e_indices) != list(range(d, n)):
        return riccati_solve(Us, us, start, end, want_log_det=want_log_det)
    xs, fs = slice(0, d), slice(d, n)
    x = start.P0
    prefix = [x]
    for c, (U, u) in enumerate(zip(Us[:-1], us[:-1])):
        UxF = U[:, xs, fs]
        if not np.any(UxF):
            x = np.einsum("bij,bj->bi", U[:, xs, xs], x) + u[:, xs]
            prefix.append(x)
            continue
        try:
            S_new = np.swapaxes(np.linalg.solve(np.swapaxes(UxF, 1, 2), np.swapaxes(U[:, fs, fs], 1, 2)), 1, 2)
        except np.linalg.LinAlgError:
            break
        P_new = (np.einsum("bij,bj->bi", U[:, fs, xs], x) + u[:, fs]
                 - np.einsum("bij,bj->bi", S_new, np.einsum("bij,bj->bi", U[:, xs, xs], x) + u[:, xs]))
        rest = riccati_solve(Us[c + 1:], us[c + 1:], BoundaryStart(list(range(d)), S_new, P_new), end,
                             want_log_det=want_log_det)
        states = np.empty((len(Us) + 1,) + rest.states.shape[1:], dtype=rest.states.dtype)
        states[c + 1:] = rest.states
        for j in range(c, -1, -1):  # prefix points: known x, forces backwards
            U, u = Us[j], us[j]
            states[j, :, xs] = prefix[j]
            F_out = states[j + 1, :, fs] - np.einsum("bij,bj->bi", U[:, fs, xs], prefix[j]) - u[:, fs]
            states[j, :, fs] = np.linalg.solve(U[:, fs, fs], F_out[..., None])[..., 0]
        return ChainSolution(states, rest.log_det)
    return riccati_solve(Us, us, start, end, want_log_det=want_log_det)


def plain_solve(Us: Sequence[np.ndarray], us: Sequence[np.ndarray], start: BoundaryStart,
                end: BoundaryEnd) -> ChainSolution:
    """Solve the chain BVP with the plain overall transfer matrix (for comparison only).

    The unknown start components are found from the overall product and the states are then
    propagated element by element; precision is lost when the product grows large.
    """
    n = Us[0].shape[-1]
    e_idx = list(start.e_indices)
    f_idx = [i for i in range(n) if i not in e_idx]
    B = start.S0.shape[0]
    m = len(e_idx)
    Z0 = np.zeros((B, n, m), dtype=np.result_type(start.S0, Us[0]))
    Z0[:, f_idx, :] = start.S0
    Z0[:, e_idx, :] = np.eye(m)
    p0 = np.zeros((B, n), dtype=Z0.dtype)
    p0[:, f_idx] = start.P0
    Z, p = Z0, p0
    for U, u in zip(Us, us):
        Z = U @ Z
        p = np.einsum("...ij,...j->...i", U, p) + u
    H = end.Bm @ Z
    rhs = end.b - np.einsum("...ij,...j->...i", end.Bm, p)
    e = _solve_boundary(H, rhs)
    if not np.all(np.isfinite(e)):
        raise SingularSystemError("the boundary equations are singular (plain transfer)")
    states = np.empty((len(Us) + 1, B, n), dtype=np.result_type(Z, e))
    z = np.einsum("...ij,...j->...i", Z0, e) + p0
    states[0] = z
    for j, (U, u) in enumerate(zip(Us, us), start=1):
        z = np.einsum("...ij,...j->...i", U, z) + u
        states[j] = z
    return ChainSolution(states, _logdet(H))


SOLVERS = {"riccati": riccati_solve, "plain": plain_solve}


def predicted_forces(Us: Sequence[np.ndarray], us: Sequence[np.ndarray], d: int) -> np.ndarray:
    """Forces at every point when all displacement corrections vanish (``delta = 0``).

    For a field element with ``delta_out = U_dd delta_in + U_dF F_in + u_d`` the force that keeps
    ``delta_in = delta_out = 0`` is ``F_in = -U_dF^{-1} u_d`` and ``F_out = U_FF F_in + u_F``; points
    that only touch point elements inherit the value of their inboard neighbour.  Used as the
    reference ``f_pred`` of the incremental-force form (:func:`shift_forces`).

    Returns
    -------
    ndarray
        ``(N + 1, B, d)`` reference forces (first ``d`` force components of the layout).
    """
    N = len(Us)
    B = Us[0].shape[0]
    ref = np.full((N + 1, B, d), np.nan)
    for j, (U, u) in enumerate(zip(Us, us), start=1):
        UdF = U[:, :d, d:2 * d]
        if not np.any(UdF):
            continue
        try:
            F_in = -np.linalg.solve(UdF, u[:, :d, None])[..., 0]
        except np.linalg.LinAlgError:
            continue
        ref[j - 1] = F_in
        ref[j] = np.einsum("bij,bj->bi", U[:, d:2 * d, d:2 * d], F_in) + u[:, d:2 * d]
    if np.isnan(ref[0]).any():
        ref[0] = 0.0
    for j in range(1, N + 1):
        if np.isnan(ref[j]).any():
            ref[j] = ref[j - 1]
    return ref


def shift_forces(Us: Sequence[np.ndarray], us: Sequence[np.ndarray], start: BoundaryStart, end: BoundaryEnd,
                 reference: np.ndarray, d: int):
    """Rewrite the BVP for force corrections ``phi = f - reference`` (incremental-force form).

    Exact change of variables: ``u_j' = u_j + U_j[:, F] ref_{j-1} - [0; ref_j; 0]``, the known start
    forces and the end right-hand side shifted alike.  Add ``reference`` back to the solved
    force components afterwards.
    """
    fs = slice(d, 2 * d)
    new_us = []
    for j, (U, u) in enumerate(zip(Us, us), start=1):
        shifted = u + np.einsum("bij,bj->bi", U[:, :, fs], reference[j - 1])
        shifted[:, fs] -= reference[j]
        new_us.append(shifted)
    n = Us[0].shape[-1]
    e_idx = list(start.e_indices)
    f_idx = [i for i in range(n) if i not in e_idx]
    P0 = start.P0.copy()
    for row, comp in enumerate(f_idx):
        if d <= comp < 2 * d:
            P0[:, row] = P0[:, row] - reference[0][:, comp - d]
    b = end.b - np.einsum("bij,bj->bi", end.Bm[:, :, fs], reference[-1])
    return new_us, BoundaryStart(e_idx, start.S0, P0), BoundaryEnd(end.Bm, b)
