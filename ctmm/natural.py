"""Natural frequencies and mode shapes of undamped chains (frequency domain).

Natural frequencies: Wittrick-Williams counting
-----------------------------------------------
For an undamped (conservative) chain the number of natural frequencies below ``omega`` is

    J(omega) = sum_j J0_j(omega) + s{K(omega)}

where ``s{K}`` is the number of negative eigenvalues met in the Gaussian elimination of the
dynamic stiffness matrix (Sylvester's law of inertia) and ``J0_j`` counts the natural frequencies
of element ``j`` with both ends clamped (0 for massless springs; see
:meth:`~ctmm.elements.beams.BeamField.clamped_frequency_count`).  The stiffness-form Riccati
transfer ``F_j = S_j d_j`` *is* that elimination: crossing a field element the pivot is
``Pi = -U12^{-1} (U11 + U12 S)`` = (element's inboard dynamic stiffness) + (condensed stiffness
``-S`` of everything inboard).  Bisection on ``J`` isolates every root, clustered or repeated,
without missing or duplicating any (Wittrick & Williams, Q. J. Mech. Appl. Math. 24, 1971).

* Constrained displacements are not degrees of freedom: a start that fixes some of them
  (:meth:`~ctmm.elements.boundary.Boundary.constrained_dofs`, e.g. pinned ``w = 0``) starts the
  condensation on the free ones, ``d = T q``, ``T^T F = S q``; an end counts the pivots of the
  free-displacement block of ``k_end - S``.
* An element with singular ``U12`` (hinge: only the slope jumps; rigid and point elements:
  ``U12 = 0``) is a massless connector ``d_out = d_in + X F`` (``X = U11^-1 U12``) followed by a
  rigid map; its pivot lives on the range ``R`` of ``X``: ``-(R^T X R)^-1 - R^T S R``.
* Elements with a ``subdivide(omega_max)`` hook (long beams) are replaced by short pieces.

Substructure resonances: a pivot vanishes where the part of the chain it condenses resonates
(clamped at the pivot's far end), and a field's ``U12`` is singular at the field's own
clamped-clamped frequencies.  The count therefore carries a pivot margin and is certified by
:func:`ctmm.counting.certified_count` (recount at ``omega (1 -+ eta)``; a single root in the
window is placed by the sign of :class:`_Determinant`).  Lumped chains use the scalar Sturm
recursion, exact with a zero pivot.  Near (not at) a root the count may still flicker within
~1e-9 when a substructure resonates within ``e^-beta`` of it; :func:`natural_frequencies`
therefore only *isolates* roots by counting and refines them on the sign of the characteristic
determinant, evaluated by orthonormal (QR) transfer (:class:`_Determinant`).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from . import validation
from .counting import certified_count, pivot_margin, relative_singularity
from .assembly import ChainSolution  # noqa: F401
from .capabilities import refuse_damping, refuse_loops
from .errors import ModelError
from .results import ModalResult
from .roots1d import bisect_count, count_upper_bound, refine_sign_change
from .system import Chain
from .chain_assembly import MatrixCache as _MatrixCache, assemble_body as _assemble_body, subdivided as _subdivided


_CLOSED_LOOP = ("ctmm.stability.characteristic_roots(system, re_min=..., im_max=...) or "
                "ctmm.stability.unstable_root_count(system)")
_DAMPED = "ctmm.frequency_response, or ctmm.stability.characteristic_roots for damped roots"


def _undamped_plant(system, verb: str) -> Chain:
    """The undamped plain chain the natural-frequency verbs answer for, or a clear refusal."""
    chain = refuse_loops(system, verb, _CLOSED_LOOP)
    refuse_damping(chain, verb, _DAMPED)
    return chain


def eigenvalue_count(system: Chain, omega: Any) -> np.ndarray:
    """Number of natural frequencies strictly below each ``omega`` [rad/s] (Wittrick-Williams).

    ``J = sum_j J0_j + s{K}``: the elements' clamped-clamped counts (optional hook
    ``clamped_frequency_count``) plus the negative pivots of the stiffness-form Riccati
    condensation (module docstring).  Elements with a ``subdivide`` hook (long beams) are
    first cut into pieces that are well conditioned up to ``max(omega)``.  Boundaries may
    constrain any subset of the displacements (:meth:`~ctmm.elements.boundary.Boundary.constrained_dofs`,
    e.g. pinned or sliding beam ends); elements whose ``U12`` block is singular (in-span
    hinges, rigid bodies, point elements) are eliminated on the range of their flexibility.

    Parameters
    ----------
    system : Chain
        An undamped chain (a ``ControlledChain`` without loops counts as its plant).
    omega : array_like
        Frequencies [rad/s] > 0.

    Raises
    ------
    ModelError
        If an element matrix is not symplectic (not reciprocal), see :func:`_check_reciprocal`;
        if ``system`` is damped or closes feedback loops (the count of undamped natural
        frequencies would ignore them; :mod:`ctmm.capabilities`).

    Notes
    -----
    Exact in exact arithmetic, and exact at trial frequencies that hit a substructure
    resonance (a vanishing pivot; module docstring).  In floating point the count may flicker
    within about ``1e-9`` relative of a natural frequency when an inboard substructure has a
    natural frequency within ``e^-β`` of it (e.g. clamped-clamped and clamped-free beam roots);
    :func:`natural_frequencies` therefore uses the count only to isolate roots.
    """
    system = _undamped_plant(system, "eigenvalue_count")
    omega = validation.frequencies("omega", omega)
    if _is_lumped(system):
        return _lumped_count(system, omega)
    body, points = _subdivided(system, float(np.max(omega, initial=0.0)))
    real = _check_reciprocal(body, float(np.max(omega, initial=0.0)) or 1.0)
    return _count(system, body, omega, _Side(system, body, points) if real else None)


def _count(system, body: Sequence, omega: np.ndarray, side: "_Side | None" = None) -> np.ndarray:
    """Wittrick-Williams count over the (subdivided) ``body`` at real frequencies ``omega``,
    certified at substructure resonances (:func:`ctmm.counting.certified_count`)."""
    return certified_count(lambda w: _raw_count(system, body, w), omega, side=side)


class _Side:
    """``side(lower, omega)``: True where the single root in a window from ``lower`` lies below
    ``omega``, from the sign of the pole-free determinant :class:`_Determinant`."""

    def __init__(self, system, body: Sequence, points: Sequence[int]) -> None:
        self.determinant = _Determinant(system, body, points)

    def __call__(self, lower: np.ndarray, omega: np.ndarray) -> np.ndarray:
        delta = self.determinant
        D = delta.scaling(omega)
        return np.sign(delta(lower, D)) != np.sign(delta(omega, D))


def _raw_count(system, body: Sequence, omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Wittrick-Williams count and smallest relative pivot at real frequencies ``omega``.

    The margin is the smallest ``|eigenvalue| / scale`` of the eliminated pivot blocks (a block
    vanishes where the structure inboard of its far end, clamped there, resonates) and the
    smallest relative singular value of regular fields' ``U12`` (zero at the field's own
    clamped-clamped frequencies, where ``J0`` jumps); ``nan`` when the condensation went
    non-finite.  The end block is final and excluded (it vanishes at the chain's own roots).

    The condensed inboard structure is carried as ``d = T q``, ``T^T F = S q``: ``q`` are the
    free displacement coordinates of the current point (``T = I`` once the first element with a
    regular ``U12`` has been passed), ``S = -K_inboard`` in those coordinates.
    """
    layout = system.layout
    d = layout.half
    s = 1j * omega
    B = omega.size
    eye = np.eye(d)
    count = np.zeros(B, dtype=np.int64)
    margin = np.full(B, np.inf)
    _, free = system.start.constrained_dofs(layout)
    m = len(free)
    k_start = np.broadcast_to(np.real(system.start._stiffness(s)), (B,))
    T = np.broadcast_to(eye[:, list(free)], (B, d, m)).copy()
    S = -k_start[:, None, None] * np.eye(m)
    identity = m == d
    matrices = _MatrixCache(s)
    known: dict[int, tuple[Any, np.ndarray, int]] = {}   # per element object: (element, J0, rank)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for element in body:
            U = np.real(matrices(element))
            U11, U12, U21, U22 = U[:, :d, :d], U[:, :d, d:], U[:, d:, :d], U[:, d:, d:]
            hit = known.get(id(element))
            if hit is None or hit[0] is not element:
                j0 = (np.asarray(element.clamped_frequency_count(omega), dtype=np.int64)
                      if hasattr(element, "clamped_frequency_count") else 0)
                hit = known[id(element)] = (element, j0, _structural_rank(U12))
            _, j0, rank = hit
            count += j0
            if rank == d:
                margin = np.minimum(margin, relative_singularity(U12))
            if identity:
                G = U11 + U12 @ S
                if rank == d:       # regular field: pivot -U12^-1 G = K_aa - S
                    count += _negative_eigenvalues(-_solve(U12, G))
                    margin = np.minimum(margin, pivot_margin(-_solve(U12, G), -_solve(U12, U11), S))
                elif rank > 0:      # hinge-like: pivot on the range R of the flexibility
                    R, _, Kc = _connector(U11, U12, rank)
                    RSR = _t(R) @ S @ R
                    count += _negative_eigenvalues(Kc - RSR)
                    margin = np.minimum(margin, pivot_margin(Kc - RSR, Kc, RSR))
                S = _t(_solve(_t(G), _t(U21 + U22 @ S)))    # (U21 + U22 S) G^-1
            else:
                T, S, negative, step_margin = _reduced_step(T, S, U11, U12, U21, U22, rank)
                count += negative
                margin = np.minimum(margin, step_margin)
                if T.shape[-1] == d:                        # all displacements free again: T -> I
                    Ti = _solve(T, np.broadcast_to(eye, T.shape))
                    S = _t(Ti) @ S @ Ti
                    identity = True
        fixed_end, free_end = system.end.constrained_dofs(layout)
        k_end = np.broadcast_to(np.real(system.end._stiffness(s)), (B,))
        E = eye[:, list(free_end)]
        if identity:
            block = k_end[:, None, None] * np.eye(E.shape[1]) - E.T @ S @ E
        else:
            Q = _null_space(eye[:, list(fixed_end)].T @ T)
            K = k_end[:, None, None] * (_t(T) @ (E @ E.T) @ T) - S
            block = _t(Q) @ K @ Q
        count += _negative_eigenvalues(block)
        margin = np.where(np.all(np.isfinite(block), axis=(-2, -1)), margin, np.nan)
    return count, margin


def _t(A: np.ndarray) -> np.ndarray:
    return np.swapaxes(A, -1, -2)


def _solve(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched ``A^-1 b`` (explicit for 1x1 and 2x2); an exactly singular ``A`` (a pivot exactly
    at a partial resonance) is moved by a few ulps so that the count takes a one-sided limit."""
    n = A.shape[-1]
    if n == 0:
        return b
    if n <= 2:
        if n == 1:
            det = A[..., 0, 0]
            adj = np.ones_like(A)
        else:
            det = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
            adj = np.stack([np.stack([A[..., 1, 1], -A[..., 0, 1]], -1),
                            np.stack([-A[..., 1, 0], A[..., 0, 0]], -1)], -2)
        tiny = np.abs(A).max(axis=(-2, -1)) * 4 * np.finfo(float).eps
        det = np.where(det == 0, np.where(tiny > 0, tiny, np.finfo(float).tiny) ** n, det)
        return (adj @ b) / det[..., None, None]
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        scale = np.abs(A).max(axis=(-2, -1), keepdims=True) * 4 * np.finfo(float).eps
        return np.linalg.solve(A + scale * np.eye(n), b)


def _structural_rank(U12: np.ndarray) -> int:
    """Rank of the ``U12`` blocks after row/column equilibration (unit-free), max over the batch.

    0 for point and rigid elements, ``d`` for regular fields (a beam at one of its own
    clamped-clamped frequencies stays "regular": the ``J0`` term accounts for it), in between
    for hinge-like elements (e.g. :class:`~ctmm.elements.beams.BeamHinge`: rank 1).
    """
    A = np.abs(U12)
    if not np.any(A):
        return 0
    row = A.max(axis=-1, keepdims=True)
    A = A / np.where(row > 0, row, 1.0)
    col = A.max(axis=-2, keepdims=True)
    A = A / np.where(col > 0, col, 1.0)
    sv = np.linalg.svd(A, compute_uv=False)
    return int(np.max(np.sum(sv > 1e-12 * sv[..., :1], axis=-1)))


def _connector(U11: np.ndarray, U12: np.ndarray, rank: int):
    """Range ``R``, null space ``N`` and stiffness ``Kc = -(R^T X R)^-1`` of ``X = U11^-1 U12``.

    A symplectic ``U`` with invertible ``U11`` factors as
    ``[[U11, 0], [U21, U11^-T]] @ [[I, X], [0, I]]``: a massless connector ``d_out = d_in + X F``
    (``X`` symmetric; ``-X^-1`` is the connector stiffness on its range) followed by a rigid
    map without new degrees of freedom.
    """
    X = _solve(U11, U12)
    lam, V = np.linalg.eigh(0.5 * (X + _t(X)))
    order = np.argsort(-np.abs(lam), axis=-1)
    lam = np.take_along_axis(lam, order, axis=-1)
    V = np.take_along_axis(V, order[..., None, :], axis=-1)
    Kc = np.zeros(lam.shape[:-1] + (rank, rank))
    idx = np.arange(rank)
    Kc[..., idx, idx] = -1.0 / lam[..., :rank]
    return V[..., :rank], V[..., rank:], Kc


def _null_space(A: np.ndarray) -> np.ndarray:
    """Orthonormal null-space basis of batched ``A`` (rank taken as the max over the batch)."""
    B, r, c = A.shape
    if r == 0 or c == 0:
        return np.broadcast_to(np.eye(c), (B, c, c)).copy()
    _, sv, vh = np.linalg.svd(A, full_matrices=True)
    rank = int(np.max(np.sum(sv > 1e-12 * np.maximum(sv[..., :1], np.finfo(float).tiny), axis=-1)))
    return _t(vh[..., rank:, :])


def _reduced_step(T, S, U11, U12, U21, U22, rank):
    """One element when the current point has constrained displacements (``T`` has ``m < d`` columns).

    Returns the new ``(T, S)``, the number of negative pivots of the eliminated coordinates and
    their smallest relative pivot (:func:`ctmm.counting.pivot_margin`).
    """
    B, d, m = T.shape
    negative = np.zeros(B, dtype=np.int64)
    margin = np.full(B, np.inf)
    if rank == d:  # regular field: eliminate q against the element's dynamic stiffness
        X = _solve(U12, np.broadcast_to(np.eye(d), U12.shape))
        Kaa, Kab, Kba, Kbb = -X @ U11, X, -U21 + U22 @ X @ U11, -U22 @ X
        if m == 0:
            return np.broadcast_to(np.eye(d), (B, d, d)).copy(), -Kbb, negative, margin
        P = _t(T) @ Kaa @ T - S
        negative += _negative_eigenvalues(P)
        margin = pivot_margin(P, _t(T) @ Kaa @ T, S)
        S_new = -(Kbb - Kba @ T @ _solve(P, _t(T) @ Kab))
        return np.broadcast_to(np.eye(d), (B, d, d)).copy(), S_new, negative, margin
    if rank > 0:  # connector part on its range R: new coordinates a (outboard R-components)
        R, N, Kc = _connector(U11, U12, rank)
        TR = _t(T) @ R                                           # (B, m, r)
        W = np.concatenate([N @ _t(N) @ T, R], axis=-1)          # d_out = W [q; a]
        H = np.concatenate([np.concatenate([-S + TR @ Kc @ _t(TR), -TR @ Kc], axis=-1),
                            np.concatenate([-Kc @ _t(TR), Kc], axis=-1)], axis=-2)
        _, sv, vh = np.linalg.svd(W, full_matrices=True)
        seen = int(np.max(np.sum(sv > 1e-12 * sv[..., :1], axis=-1)))
        Y1, Y0 = _t(vh[..., :seen, :]), _t(vh[..., seen:, :])   # Y0: coordinates W does not see
        H11 = _t(Y1) @ H @ Y1
        if Y0.shape[-1]:
            P = _t(Y0) @ H @ Y0
            negative += _negative_eigenvalues(P)
            margin = pivot_margin(P, H)
            H10 = _t(Y1) @ H @ Y0
            H11 = H11 - H10 @ _solve(P, _t(H10))
        T, S = W @ Y1, -H11
    # rigid part d' = U11 d, F' = U21 d + U11^-T F (symplectic): no new coordinates
    return U11 @ T, S + _t(T) @ _t(U11) @ U21 @ T, negative, margin


def _is_lumped(system) -> bool:
    return system.layout.size == 2 and all(e.lumped_coefficients() is not None for e in system.body)


def _lumped_count(system, omega: np.ndarray) -> np.ndarray:
    """Scalar Wittrick-Williams count for 1-D lumped chains (same recursion as the general one).

    Elements are read through :meth:`~ctmm.elements.base.Element.lumped_coefficients`.
    ``S = -K_L`` (condensed dynamic stiffness of the inboard part, negated); a point element adds
    ``m w^2 - k_g``; a connector of undamped dynamic stiffness ``k = k_c - b w^2`` (``b`` its
    inertance, 0 for springs; ``k`` may then be negative or zero, the connector has no internal
    degrees of freedom so ``J_0 = 0``) has pivot ``k - S`` and maps ``S -> k^2 / (k - S) - k``
    (evaluated as ``k S / (k - S)`` while ``|S| < |k|/2``, where that form has no cancellation).
    This is the Sturm sequence of the tridiagonal ``K - w^2 M`` in ratio form, whose count is
    backward stable (exact for a matrix within a few ulps of the given one) however small a
    pivot.  A pivot exactly zero (``w`` exactly at a resonance of the inboard part clamped at
    the connector's far end) is taken as ``+0``: the next pivot is then ``-inf`` and the pair
    counts one, the limit from either side; a zero final pivot (a root at ``w``) counts none, as
    "strictly below" requires.  No ``0 * inf`` can occur in this form.
    """
    w2 = omega * omega
    count = np.zeros(omega.size, dtype=int)
    clamped = system.start.known == "displacement"
    S = np.zeros(omega.size) if clamped else np.full(omega.size, -float(np.real(system.start._stiffness(0.0))))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for e in system.body:
            lumped = e.lumped_coefficients()
            if lumped.connector:
                k = lumped.stiffness - lumped.mass * w2
                if clamped:
                    S = -k
                    clamped = False
                    continue
                pivot = k - S
                pivot = np.where(pivot == 0.0, np.finfo(float).tiny, pivot)
                count += pivot < 0
                # k S / (k - S) keeps the relative accuracy of a small S (a rigid-body mode at
                # tiny w: k^2/pivot - k would cancel it to 0); k^2 / pivot - k avoids 0 * inf
                # when the pivot vanishes.  Both are the same map; each is used where it is exact.
                small = np.abs(S) < 0.5 * np.abs(k)
                S = np.where(small, k * S / np.where(small, pivot, 1.0), k * k / pivot - k)
            elif not clamped:
                S = S + (lumped.mass * w2 - lumped.stiffness)
    if system.end.known == "force" and not clamped:
        count += (float(np.real(system.end._stiffness(0.0))) - S) < 0
    return count


def _negative_eigenvalues(pivot: np.ndarray) -> np.ndarray:
    """Number of negative eigenvalues of the symmetric part of each (batched) pivot block."""
    if pivot.shape[-1] == 0:
        return np.zeros(pivot.shape[:-2], dtype=np.int64)
    if pivot.shape[-1] == 1:
        return (pivot[:, 0, 0] < 0).astype(int)
    if pivot.shape[-1] == 2:  # signs of det and trace (Sylvester)
        a, c, b = pivot[:, 0, 0], pivot[:, 1, 1], 0.5 * (pivot[:, 0, 1] + pivot[:, 1, 0])
        det = a * c - b * b
        return np.where(det < 0, 1, np.where(a + c < 0, np.where(det > 0, 2, 1), 0)).astype(np.int64)
    sym = 0.5 * (pivot + np.swapaxes(pivot, -1, -2))
    return np.sum(np.linalg.eigvalsh(sym) < 0, axis=-1)


def natural_frequencies(system: Chain, *, n_modes: int | None = None, omega_max: float | None = None,
                        rtol: float = 1e-15) -> np.ndarray:
    """Undamped natural frequencies [rad/s]: Wittrick-Williams isolation, determinant-sign refinement.

    1. Every root is isolated by bisection on :func:`eigenvalue_count` until its bracket
       holds exactly one natural frequency (count jump 1), so none is missed or duplicated.
    2. Within such a bracket the root is refined by bisection on the sign of the chain's
       characteristic determinant ``Delta(omega) = det(Bm Z_N)`` (real for undamped systems),
       evaluated by orthonormal (QR) transfer of the start subspace ``Z`` in balanced
       coordinates: no cancellation, no poles, and no loss at partial resonances (unlike the
       graph form of the Riccati transfer, whose ``det G_j`` factors become ``0 * inf`` when
       a substructure resonates exactly at a root, e.g. equal halves of a symmetric beam).
    3. Brackets with a count jump >= 2 that shrink to ``rtol`` (repeated roots) and brackets
       whose determinant signs disagree with the count stay on count-only bisection.

    Lumped 1-D chains use the scalar count alone (already at round-off).  Elements with a
    ``subdivide`` hook (long beams) are cut once for the highest frequency sought, so a single
    long :class:`~ctmm.elements.beams.BeamField` gives its high modes to ~1e-15 relative.

    Parameters
    ----------
    system : Chain
        An undamped chain (a ``ControlledChain`` without loops counts as its plant).
    n_modes : int, optional
        Number of lowest frequencies wanted (rigid-body modes count, returned as 0).
    omega_max : float, optional
        Return all natural frequencies below ``omega_max`` [rad/s] instead.
    rtol : float
        Relative bracket width at which bisection stops.

    Returns
    -------
    ndarray
        Ascending natural frequencies; a repeated frequency appears once per multiplicity.

    Raises
    ------
    ModelError
        ``system`` is damped or closes feedback loops: closed-loop roots are not undamped natural
        frequencies (use :func:`ctmm.stability.characteristic_roots`, or pass ``system.plant``).
    """
    system = _undamped_plant(system, "natural_frequencies")
    if (n_modes is None) == (omega_max is None):
        raise ModelError("give exactly one of n_modes (int >= 1) or omega_max (rad/s > 0)")
    rtol = validation.positive("rtol", rtol)
    if n_modes is not None:
        n_modes = validation.integer("n_modes", n_modes, minimum=1)
        hi = count_upper_bound(lambda w: eigenvalue_count(system, w), n_modes, limit=1e15,
                               what=f"chain {system.name!r}")
        targets = np.arange(1, n_modes + 1)
    else:
        hi = validation.positive("omega_max", omega_max)
        targets = np.arange(1, int(eigenvalue_count(system, [hi])[0]) + 1)
    if targets.size == 0:
        return np.zeros(0)
    if _is_lumped(system):
        count, sign = (lambda w: _lumped_count(system, w)), None
    else:
        body, points = _subdivided(system, hi)
        sign = _Determinant(system, body, points) if _check_reciprocal(body, hi) else None
        side = _Side(system, body, points) if sign is not None else None
        count = lambda w: _count(system, body, w, side)  # noqa: E731
    tiny = hi * 1e-12
    # rigid-body modes (w = 0): the count at a tiny w is exact for lumped chains; for fields the
    # O(w^2) stiffness change drowns in round-off there, so use the static nullity instead
    n_tiny = int(count(np.array([tiny]))[0])
    n_rigid = n_tiny if sign is None else sign.static_nullity()
    if n_tiny > n_rigid:  # round-off can only hide a rigid mode from the count, not add one
        raise ModelError(f"chain {system.name!r} is statically unstable: {n_tiny - n_rigid} mode(s) with "
                         "negative stiffness (omega^2 < 0, e.g. compression beyond buckling)")
    roots = np.zeros(targets.size)
    k = targets[targets > n_rigid]
    if k.size == 0:
        return roots
    # 1. brackets from one batched count on a grid, then count bisection
    #    (root_k = inf{w : count(w) >= k}) until isolated or narrow
    isolate = sign is not None
    grid = np.concatenate([[tiny], np.geomspace(tiny, hi, 2 * k.size + 2)[1:-1],
                           np.linspace(0.0, hi, 4 * k.size + 2)[1:]])
    grid = np.unique(grid) if isolate else np.array([tiny, hi])
    c_grid = count(grid)
    c_grid[0], c_grid[-1] = n_rigid, max(int(c_grid[-1]), int(k.max()))
    first = np.argmax(c_grid[None, :] >= k[:, None], axis=1)     # first grid point with count >= k
    lo, up = grid[first - 1], grid[first]
    c_lo, c_up = c_grid[first - 1].astype(np.int64), c_grid[first].astype(np.int64)
    bisect_count(count, k, lo, up, c_lo, c_up, rtol, np.arange(k.size), isolate=isolate)
    if isolate:
        # 2. refine isolated roots on the sign of Delta; 3. the rest on the count
        idx = np.flatnonzero((c_up - c_lo == 1) & (up - lo > rtol * up))
        if idx.size:
            bad = _refine_sign(sign, lo, up, idx, rtol)
            bisect_count(count, k, lo, up, c_lo, c_up, rtol, bad, isolate=False)
        bisect_count(count, k, lo, up, c_lo, c_up, rtol, np.flatnonzero(c_up - c_lo > 1), isolate=False)
    roots[targets > n_rigid] = 0.5 * (lo + up)
    return roots


def _refine_sign(delta: "_Determinant", lo, up, idx, rtol) -> np.ndarray:
    """Refine isolated roots ``idx`` (in place) where ``Delta`` changes sign, by
    :func:`ctmm.roots1d.refine_sign_change` (Illinois with bisection safeguard).

    Works on ``f = det(Bm D^-1 Q_N)`` (:class:`_Determinant`): same sign as ``Delta``, O(1) and
    smooth, with one fixed balancing ``D`` per root.  Returns the targets whose end signs
    agree (left to the count).
    """
    D = delta.scaling(0.5 * (lo[idx] + up[idx]))
    lo_i, up_i = lo[idx], up[idx]
    good = refine_sign_change(lambda x, active: delta(x, D[active]), lo_i, up_i,
                              delta(lo_i, D), delta(up_i, D), rtol)
    lo[idx], up[idx] = lo_i, up_i
    return idx[~good]


def _check_reciprocal(body: Sequence, omega: float) -> bool:
    """Check the matrices the count relies on at ``s = i omega``; return whether all are real.

    Wittrick-Williams counting needs symplectic element matrices, ``U^T J U = J`` with
    ``J = [[0, I], [-I, 0]]`` (reciprocity: every force work-conjugate to its displacement,
    as for a conservative element).  Elements that are not (e.g. a composite of a rigid body and
    the smooth hinge it hangs on) raise :class:`~ctmm.errors.ModelError` instead of giving a wrong
    count.
    """
    s = 1j * np.array([omega, 0.37 * omega])
    real, bad, seen = True, [], set()
    for element in body:
        if id(element) in seen:
            continue
        seen.add(id(element))
        U = np.asarray(element.transfer_matrix(s))
        real &= not np.any(np.abs(U.imag) > 1e-12 * np.maximum(np.abs(U.real), 1.0))
        n = U.shape[-1]
        J = np.block([[np.zeros((n // 2, n // 2)), np.eye(n // 2)], [-np.eye(n // 2), np.zeros((n // 2, n // 2))]])
        residual = np.abs(_t(U.real) @ J @ U.real - J).max(axis=(-2, -1))
        if n % 2 or np.any(residual > 1e-8 * np.maximum(np.abs(U.real).max(axis=(-2, -1)) ** 2, 1.0)):
            bad.append(element.name)
    if bad:
        raise ModelError("natural_frequencies and eigenvalue_count need reciprocal (symplectic) element "
                         f"matrices U^T J U = J; not satisfied by {', '.join(repr(b) for b in bad)}"
                         " (for planar chains with smooth hinges give the PlanarModel itself to ctmm.natural_frequencies)")
    return real


def _balance(Us: Sequence[np.ndarray], sweeps: int = 8) -> np.ndarray:
    """Positive diagonal scaling ``D`` (batched, ``(B, n)``) that balances ``sum_j |U_j - I|``.

    Osborne's iteration: row and column sums of ``D M D^-1`` made equal, component by
    component; it brings the mixed units of a state (e.g. ``w`` [m] and ``shear`` [N]) to
    comparable size, which the QR transfer of :func:`_determinant_sign` needs.  Any positive
    ``D`` gives the same determinant sign; only round-off depends on it.
    """
    n = Us[0].shape[-1]
    M = sum(np.abs(U - np.eye(n)) for U in Us)
    logd = np.zeros(M.shape[:-1])
    off = ~np.eye(n, dtype=bool)
    for _ in range(sweeps):
        for i in range(n):
            W = M * np.exp(logd[:, :, None] - logd[:, None, :])
            r = np.sum(W[:, i, :] * off[i], axis=-1)
            c = np.sum(W[:, :, i] * off[:, i], axis=-1)
            ok = (r > 0) & (c > 0)
            logd[ok, i] += 0.5 * np.log(c[ok] / r[ok])
    return np.exp(logd - logd.mean(axis=-1, keepdims=True))


class _Determinant:
    """Sign function of the characteristic determinant ``Delta(omega) = det(Bm Z_N)`` of an
    undamped chain, ``Z_N = U_N ... U_1 Z_0`` (``Z_0`` spans the start relation).

    Orthonormal transfer: ``Z <- Q`` with ``Q R = D U_j D^-1 Z`` (Gram-Schmidt with
    re-orthogonalisation, ``diag R > 0``), so ``Delta = det(Bm D^-1 Q_N) prod det R_j`` with a
    positive product: ``det(Bm D^-1 Q_N)`` is an O(1), smooth function with the sign of
    ``Delta``.  The subspace ``Q`` never degenerates (unlike the graph coordinates ``S`` of the
    Riccati transfer), so there are no poles and no ``0 * inf`` at partial resonances;
    the balancing ``D`` (:func:`_balance`) only affects round-off.
    """

    def __init__(self, system, body: Sequence, points: Sequence[int]) -> None:
        self.system, self.body, self.points = system, body, points

    def _matrices(self, omega):
        Us, _, start, end = _assemble_body(self.system, self.body, self.points, 1j * omega, {})
        return [np.real(U) for U in Us], start, end

    def scaling(self, omega: np.ndarray) -> np.ndarray:
        """Balancing ``D`` (``(B, n)``) at ``omega``, to be reused for nearby frequencies."""
        return _balance(self._matrices(omega)[0])

    def static_nullity(self) -> int:
        """Number of rigid-body modes: ``dim null(Bm Z_N)`` at ``omega = 0`` (singular values below ``1e-9``
        of the largest, balanced coordinates, rows and columns equilibrated: scale-aware for turned fields)."""
        Us, start, end = self._matrices(np.zeros(1))
        M = self._final(Us, start, end, _balance(Us))[0]
        if M.size == 0:
            return 0
        for _ in range(3):  # row/column equilibration: a turned field mixes stiff and soft directions
            M = M / np.maximum(np.linalg.norm(M, axis=1, keepdims=True), np.finfo(float).tiny)
            M = M / np.maximum(np.linalg.norm(M, axis=0, keepdims=True), np.finfo(float).tiny)
        sv = np.linalg.svd(M, compute_uv=False)
        return int(np.sum(sv <= 1e-9 * sv[0]))

    def __call__(self, omega: np.ndarray, D: np.ndarray) -> np.ndarray:
        """``det(Bm D^-1 Q_N)`` at ``omega`` (``D`` from :meth:`scaling`)."""
        M = self._final(*self._matrices(omega), D)
        return np.linalg.det(M) if M.shape[-1] else np.ones(omega.shape)

    @staticmethod
    def _final(Us, start, end, D) -> np.ndarray:
        """``Bm D^-1 Q_N``."""
        n = Us[0].shape[-1]
        e_idx = list(start.e_indices)
        f_idx = [i for i in range(n) if i not in e_idx]
        Z = np.zeros((D.shape[0], n, len(e_idx)))
        Z[:, f_idx, :] = np.real(start.S0)
        Z[:, e_idx, :] = np.eye(len(e_idx))
        Q = _qr(D[:, :, None] * Z)[0]
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            for U in Us:
                Q = _qr((D[:, :, None] * U / D[:, None, :]) @ Q)[0]
        return (np.real(end.Bm) / D[:, None, :]) @ Q


def _qr(Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched Gram-Schmidt with re-orthogonalisation: ``Z = Q R``, ``diag R > 0``."""
    m = Z.shape[-1]
    Q = Z.copy()
    R = np.zeros(Z.shape[:-2] + (m, m))
    for j in range(m):
        q = Q[..., j]
        for _ in range(2):
            for i in range(j):
                r = np.sum(Q[..., i] * q, axis=-1)
                q = q - r[..., None] * Q[..., i]
                R[..., i, j] += r
        R[..., j, j] = np.sqrt(np.sum(q * q, axis=-1))
        Q[..., j] = q / R[..., j, j][..., None]
    return Q, R


def _orthonormal_solve(Us, us, start, end, *, null_space: int = 0) -> np.ndarray:
    """States ``(N + 1, B, n)`` of a real chain BVP by orthonormal transfer (Conte's method).

    In balanced coordinates ``y = D z`` every state is ``y_j = Q_j c_j + p_j``: ``Q_j``
    orthonormal spans the start-admissible subspace (``D U_j D^-1 Q_{j-1} = Q_j R_j``), the
    particular part ``p_j`` is kept orthogonal to it (``a_j`` = its removed component), so
    ``c_j = R_j c_{j-1} + a_j``.  The end condition gives ``c_N``; then
    ``c_{j-1} = R_j^-1 (c_j - a_j)``.  No graph coordinates, hence no breakdown when a
    substructure resonates at the solve frequency (unlike the Riccati transfer).  With
    ``null_space = r`` the loads are ignored and entry ``i`` of the batch gets the ``i``-th of
    the ``r`` right singular vectors of the (singular) end matrix with smallest singular values.
    """
    Us = [np.real(U) for U in Us]
    B, n = Us[0].shape[0], Us[0].shape[-1]
    e_idx = list(start.e_indices)
    f_idx = [i for i in range(n) if i not in e_idx]
    D = _balance(Us)
    Z = np.zeros((B, n, len(e_idx)))
    Z[:, f_idx, :] = np.real(start.S0)
    Z[:, e_idx, :] = np.eye(len(e_idx))
    p = np.zeros((B, n))
    if not null_space:
        p[:, f_idx] = np.real(start.P0)
    Q, _ = _qr(D[:, :, None] * Z)
    p = D * p
    p = p - np.einsum("bij,bj->bi", Q, np.einsum("bji,bj->bi", Q, p))
    record = [(Q, p, None, None)]
    for U, u in zip(Us, us):
        V = D[:, :, None] * U / D[:, None, :]
        Q, R = _qr(V @ Q)
        w = np.einsum("bij,bj->bi", V, p) + (0.0 if null_space else D * np.real(u))
        a = np.einsum("bji,bj->bi", Q, w)
        p = w - np.einsum("bij,bj->bi", Q, a)
        record.append((Q, p, R, a))
    M = (np.real(end.Bm) / D[:, None, :]) @ Q
    if null_space:
        vh = np.linalg.svd(M)[2]
        c = np.stack([vh[i % B, -1 - (i % null_space), :] for i in range(B)])
    else:
        rhs = np.real(end.b) - np.einsum("bij,bj->bi", np.real(end.Bm) / D[:, None, :], p)
        c = _solve(M, rhs[..., None])[..., 0]
    states = np.empty((len(Us) + 1, B, n))
    for j in range(len(Us), -1, -1):
        Q, p, R, a = record[j]
        states[j] = (np.einsum("bij,bj->bi", Q, c) + p) / D
        if j:
            c = _solve(R, (c - a)[..., None])[..., 0]
    return states


def mode_shapes(system: Chain, *, n_modes: int | None = None, omega_max: float | None = None) -> ModalResult:
    """Natural frequencies and mode shapes (states at all connection points).

    A shape is computed by one step of inverse iteration done with the transfer matrices: the
    forced response at the computed natural frequency to a generic load (fixed pseudo-random
    point forces at every connection point, including those inside subdivided elements).
    This is a backward-stable solve whose result is the mode to relative accuracy
    ``|w - w_k| / gap``, also for strongly localised modes where a homogeneous
    back-substitution from one end would amplify round-off.  Rigid-body modes (``w = 0``) are
    the null vectors of the static boundary equations.  Shapes are normalised so that the
    largest displacement component is +1.  Refuses damped chains and chains with feedback loops
    like :func:`natural_frequencies`.
    """
    system = _undamped_plant(system, "mode_shapes")
    omega = natural_frequencies(system, n_modes=n_modes, omega_max=omega_max)
    if omega.size == 0:   # no natural frequency below omega_max
        return ModalResult(omega, np.zeros((0, system.n_points, system.layout.size)), system.layout.components,
                           tuple(system.point_names()))
    layout = system.layout
    d, n = layout.half, layout.size
    body, points = _subdivided(system, float(np.max(omega, initial=0.0)))
    states = np.zeros((len(points), omega.size, n))
    flexible = omega > 0
    if np.any(flexible):
        Us, us, start, end = _assemble_body(system, body, points, 1j * omega[flexible], {})
        rng = np.random.default_rng(20260101)
        for u in us:
            u[:, d:2 * d] += 1.0 + rng.random(d)
        states[:, flexible] = _orthonormal_solve(Us, us, start, end)[list(points)]
    rigid = int(np.sum(~flexible))
    if rigid:
        Us, us, start, end = _assemble_body(system, body, points, np.zeros(rigid, dtype=complex), {})
        states[:, ~flexible] = _orthonormal_solve(Us, us, start, end, null_space=rigid)[list(points)]
    return _modal_result(system, omega, states)


def _modal_result(system, omega: np.ndarray, states: np.ndarray) -> ModalResult:
    shapes = np.transpose(states, (1, 0, 2))  # (modes, points, components)
    d = system.layout.half
    disp = shapes[..., :d].reshape(len(omega), -1)
    ref = disp[np.arange(len(omega)), np.argmax(np.abs(disp), axis=1)]
    shapes = np.real_if_close(shapes / ref[:, None, None], tol=1e6)
    return ModalResult(omega, shapes, system.layout.components, tuple(system.point_names()))
