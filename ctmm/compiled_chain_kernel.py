"""The ``O(n)`` part of the generated DT-TMM step of a 1-D chain as C loops over the nodes (issue 13).

:class:`ctmm.compiled_chain_schemes.CompiledChainScheme` imposes the equation of motion at a scheme's evaluation
level: every node's correction solves ``S delta = Ax dx + Av B + a0 + f - D`` with ``dx, B, D`` the scheme's linear
maps of the node's stored history ``h = (x_n, v_n, a_n, x_{n-1}, x_{n-2})`` and ``S = C I - cx Ax - A Av``.  For a
chain without inerters ``Ax``, ``Av`` and ``S`` are tridiagonal, and :func:`step_kernel` writes the whole node part
of the step as one C function (a casadi ``Function.jit`` body, inlined into the generated library, its inputs read
in place), the chain's bands, the factors of ``S`` and the loops' solved columns as constant arrays:

1. the maps ``dx``, ``B`` of node ``i + 1`` and the right-hand side of node ``i`` fused with the forward
   substitution; 2. the backward substitution (``delta0 = S^-1 (Ax dx + Av B + a0 + f - D)``); 3. the real-time
   loops' forces ``s = gain (row [dx; B]) + c`` (``c`` from the caller's graph: references, controller states) and
   their implicit part by the Woodbury identity (:func:`woodbury_parts`); 4. the scheme's update of every node.

The code size does not depend on the chain (its numbers are data): the first compile takes about 1 s of CPU at
1000 masses, against 15-18 s for the straight-line code of every node's arithmetic (casadi ``expand``, where gcc's
optimisation passes over one function of 40 000 statements dominate), at that code's speed within a few per cent
(``benchmarks/chain_schemes_generated.py``).  A serialized casadi ``Function.jit`` does not hold its body: the
caller keys its cache on the bodies (:class:`ctmm.compiled_chain_schemes.CompiledChainScheme`).

:func:`banded_solver` is the same solve as a casadi graph (``mapaccum`` substitutions), for the straight-line step.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import scipy.sparse

from .errors import ModelError

__all__ = ["TridiagonalFactors", "banded_solver", "step_kernel", "step_matrix", "tridiagonal_factors",
           "woodbury_parts"]


def step_matrix(C: float, cx: float, A: float, Ax: Any, Av: Any) -> Any:
    """``S = C I - cx Ax - A Av`` of a scheme's step (``C`` [1/s^2], ``cx`` [-], ``A`` [1/s]); sparse
    (:class:`scipy.sparse.csr_matrix`, ``O(n)``) when ``Ax`` and ``Av`` are, else a dense array."""
    m = Ax.shape[0]
    if scipy.sparse.issparse(Ax) and scipy.sparse.issparse(Av):
        return scipy.sparse.csr_matrix(C * scipy.sparse.identity(m, format="csr") - cx * Ax - A * Av)
    return C * np.eye(m) - cx * _dense(Ax) - A * _dense(Av)


def _dense(matrix: Any) -> np.ndarray:
    return matrix.toarray() if scipy.sparse.issparse(matrix) else np.asarray(matrix)


def _diagonal(matrix: Any, k: int = 0) -> np.ndarray:
    """Diagonal ``k`` of a dense or sparse matrix (a copy, float)."""
    return np.asarray(matrix.diagonal(k) if scipy.sparse.issparse(matrix) else np.diag(matrix, k), dtype=float).copy()


def _outside_bands(matrix: Any) -> float:
    """Largest ``|entry|`` outside the three central diagonals of a dense or sparse matrix."""
    if scipy.sparse.issparse(matrix):
        entries = scipy.sparse.coo_matrix(matrix)
        outside = np.abs(entries.row - entries.col) >= 2
        return float(np.max(np.abs(entries.data[outside]), initial=0.0))
    return float(np.max(np.abs(np.triu(matrix, 2) + np.tril(matrix, -2)), initial=0.0))


def _largest(matrix: Any) -> float:
    values = matrix.data if scipy.sparse.issparse(matrix) else matrix
    return float(np.max(np.abs(values), initial=0.0))


class TridiagonalFactors:
    """LU factors of a tridiagonal matrix ``S`` without pivoting (Thomas; the step matrices are diagonally dominant).

    Attributes
    ----------
    factors : ndarray, shape (m,)
        Unit lower factors (``factors[0] = 0``): forward ``p_i = r_i - factors_i p_{i-1}``.
    upper : ndarray, shape (m - 1,)
        Upper diagonal of ``S``.
    reciprocals : ndarray, shape (m,)
        Reciprocals of the eliminated diagonal: backward ``d_i = (p_i - upper_i d_{i+1}) reciprocals_i``.
    """

    def __init__(self, matrix: Any) -> None:
        m = matrix.shape[0]
        diagonal = _diagonal(matrix)
        lower, self.upper = _diagonal(matrix, -1), _diagonal(matrix, 1)
        self.factors = np.zeros(m)
        for i in range(1, m):
            self.factors[i] = lower[i - 1] / diagonal[i - 1]
            diagonal[i] -= self.factors[i] * self.upper[i - 1]
        self.reciprocals = 1.0 / diagonal

    def solve(self, rhs: np.ndarray) -> np.ndarray:
        """``S^-1 rhs`` for ``rhs`` of shape ``(m,)`` or ``(m, k)`` (the two substitutions, ``O(m k)``)."""
        out = np.array(rhs, dtype=float)
        m = out.shape[0]
        for i in range(1, m):
            out[i] -= self.factors[i] * out[i - 1]
        out[m - 1] *= self.reciprocals[m - 1]
        for i in range(m - 2, -1, -1):
            out[i] = (out[i] - self.upper[i] * out[i + 1]) * self.reciprocals[i]
        return out


def tridiagonal_factors(matrix: Any, *others: Any) -> TridiagonalFactors | None:
    """The factors of ``matrix`` (``m >= 3``) if it and the ``others`` (its terms, ``Ax`` and ``Av``) are tridiagonal,
    else None.  Entries outside the three central diagonals count as zero up to round-off of the affine form read
    from the sweep (``|entry| <= 1e-13 max |matrix|``, each matrix against itself); they are then left out.  Dense
    arrays or :mod:`scipy.sparse` matrices (read in ``O(nonzeros)``)."""
    if matrix.shape[0] < 3:
        return None
    for each in (matrix, *others):
        if _outside_bands(each) > 1e-13 * _largest(each):
            return None
    return TridiagonalFactors(matrix)


def banded_solver(matrix: Any) -> Any:
    """A casadi ``Function`` ``rhs -> matrix^-1 rhs``: for a tridiagonal matrix its factors as constants and the two
    substitutions as ``mapaccum`` (written out when the step is expanded); else the constant inverse."""
    import casadi as ca

    m = matrix.shape[0]
    rhs = ca.MX.sym("rhs", m)
    factors = tridiagonal_factors(matrix)
    if factors is None:
        return ca.Function("solve", [rhs], [ca.mtimes(ca.DM(np.linalg.inv(_dense(matrix))), rhs)])
    previous, factor, value, scale = (ca.SX.sym(label) for label in ("previous", "factor", "value", "scale"))
    forward = ca.Function("forward", [previous, factor, value], [value - factor * previous]).mapaccum("forward_all", m)
    backward = ca.Function("backward", [previous, factor, value, scale],
                           [(value - factor * previous) * scale]).mapaccum("backward_all", m)
    reverse = list(range(m - 1, -1, -1))
    partial = forward(0, ca.DM(factors.factors).T, rhs.T)
    solution = backward(0, ca.DM(np.concatenate([[0.0], factors.upper[::-1]])).T, partial[:, reverse],
                        ca.DM(factors.reciprocals[::-1]).T)                  # reciprocals: no division per step
    return ca.Function("solve", [rhs], [solution[:, reverse].T])


def woodbury_parts(names: Sequence[str], columns: np.ndarray, rows: np.ndarray, matrix: Any,
                   dt: float, factors: TridiagonalFactors | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(W, Q)`` of the real-time loops ``names``: ``W = S^-1 columns`` (shape (m, k), their weighted actuator
    columns [1/kg] through the step matrix ``S``) and ``Q = (I + R W)^-1 R`` with ``R = rows`` (shape (k, m), their
    gains times rows on the correction), so that ``(S + columns R) delta = rhs`` is ``delta = S^-1 rhs - W Q S^-1
    rhs`` (Woodbury).  ``factors``: those of a tridiagonal ``S`` (then ``O(m k)``; else a dense solve).
    ModelError if ``I + R W`` is singular at the step ``dt`` [s]."""
    m = matrix.shape[0]
    if not len(names):
        return np.zeros((m, 0)), np.zeros((0, m))
    W = factors.solve(columns) if factors is not None else np.linalg.solve(_dense(matrix), columns)
    small = np.eye(len(names)) + rows @ W
    if np.linalg.cond(small) > 1e12:
        raise ModelError(f"the real-time loops {list(names)} make the step singular at dt = {dt!r} s (their gains "
                         "cancel the inertia); change their gains")
    return W, np.linalg.solve(small, rows)


def _array(name: str, values: np.ndarray) -> str:
    """A C ``static const`` array of ``values`` (exact: ``repr`` of every double)."""
    numbers = ", ".join(repr(float(value)) for value in np.ravel(values)) or "0.0"
    return f"static const casadi_real {name}[{max(np.size(values), 1)}] = {{{numbers}}};\n"


def _combination(row: np.ndarray, width: int, index: str = "i") -> str:
    """``sum_c row_c h[c m + index]`` as C (the zero terms dropped)."""
    terms = [f"{float(value)!r} * h[{c * width} + {index}]" for c, value in enumerate(row) if value]
    return " + ".join(terms) or "0.0"


def _sparse_dot(values: np.ndarray, vector: str) -> str:
    """``sum_i values_i vector[i]`` over the nonzero ``values`` as C (``0.0`` without any)."""
    return " + ".join(f"{float(values[i])!r} * {vector}[{i}]" for i in np.flatnonzero(values)) or "0.0"


def step_kernel(label: str, Ax: np.ndarray, Av: np.ndarray, a0: np.ndarray, coefficients: np.ndarray,
                update: np.ndarray, factors: TridiagonalFactors, forced: bool,
                loops: Sequence[tuple[float, np.ndarray]] = (), columns: np.ndarray | None = None,
                woodbury: np.ndarray | None = None) -> tuple[Any, str]:
    """``(h[5m], f[m], c[k]) -> new history[5m]`` of one step as one C body (``f`` only if ``forced``, ``c`` only
    with real-time ``loops``): the casadi function and its body.  A serialized casadi ``Function.jit`` does not
    hold its body (the chain's numbers): a cache key of a graph calling it must hold the body itself.

    Parameters
    ----------
    label : str
        Function name (unique within the library).
    Ax, Av : ndarray or scipy.sparse matrix, shape (m, m)
        Tridiagonal ``d a / d x`` [1/s^2] and ``d a / d v`` [1/s] of the chain's affine rates.
    a0 : ndarray, shape (m,)
        Constant accelerations [m/s^2].
    coefficients, update : ndarray, shapes (3, 5) and (5, 6)
        The scheme's maps (:class:`ctmm.compiled_chain_schemes.SchemeMaps`).
    factors : TridiagonalFactors
        Of ``S = C I - cx Ax - A Av``.
    forced : bool
        Whether the input ``f`` [m/s^2] (loads, held inputs, delayed loops) is added to ``a0``.
    loops : sequence of (float, ndarray)
        Real-time loops: ``(gain, row)``, ``row`` of length ``2 m`` on ``[dx; B]``; their forces
        ``s_l = gain (row [dx; B]) + c_l`` act on ``columns[:, l]``.
    columns : ndarray, shape (m, k)
        ``S^-1`` of the loops' columns (``W``).
    woodbury : ndarray, shape (k, m)
        ``Q = (I + R W)^-1 R`` with ``R`` the loops' rows on ``delta``: the implicit part,
        ``delta = delta0 - W (s + Q delta0 - Q W s)``.

    Returns
    -------
    (casadi.Function, str)
        The function (inputs unbuffered: read in place) and its C body.
    """
    import casadi as ca

    m, k = Ax.shape[0], len(loops)
    bands = [_diagonal(Ax), _diagonal(Ax, -1), _diagonal(Ax, 1), _diagonal(Av), _diagonal(Av, -1), _diagonal(Av, 1)]
    names = ["xd", "xl", "xu", "vd", "vl", "vu"]
    body = "".join(_array(name, band) for name, band in zip(names, bands))
    body += _array("a0", a0) + _array("lf", factors.factors) + _array("up", factors.upper) + \
        _array("rc", factors.reciprocals) + "".join(_array(f"w{j}", columns[:, j]) for j in range(k))
    force = " + f[i]" if forced else ""

    def forward(lower: bool, upper: bool) -> str:          # node i: its right-hand side, forward substitution
        return (f"  r = a0[i]{force} - ({_combination(coefficients[2], m)}) + xd[i] * dx[i] + vd[i] * B[i]"
                + (" + xl[i - 1] * dx[i - 1] + vl[i - 1] * B[i - 1]" if lower else "")
                + (" + xu[i] * dx[i + 1] + vu[i] * B[i + 1]" if upper else "")
                + ";\n  previous = r - lf[i] * previous;\n  d0[i] = previous;\n")

    body += (                                       # scratch in out: d0 read before out[2m + i] is written
        f"casadi_int i;\ncasadi_real r, previous = 0.0, delta;\n"
        f"casadi_real *d0 = out + {2 * m}, *dx = out + {3 * m}, *B = out + {4 * m};\n"
        f"if (!out) return 0;\n"                    # a structurally zero input arrives as NULL: zeros
        f"static const casadi_real no_history[{5 * m}] = {{0.0}};\nif (!h) h = no_history;\n"
        + (f"static const casadi_real no_force[{m}] = {{0.0}};\nif (!f) f = no_force;\n" if forced else "")
        + (f"static const casadi_real no_offset[{k}] = {{0.0}};\nif (!c) c = no_offset;\n" if loops else "")
        + "".join(f"dx[{j}] = {_combination(coefficients[0], m, str(j))};\n"
                  f"B[{j}] = {_combination(coefficients[1], m, str(j))};\n" for j in (0, 1))
        + f"i = 0;\n{forward(False, True)}"
        f"for (i = 1; i < {m - 1}; ++i) {{\n  dx[i + 1] = {_combination(coefficients[0], m, 'i + 1')};\n"
        f"  B[i + 1] = {_combination(coefficients[1], m, 'i + 1')};\n{forward(True, True)}}}\n"
        f"i = {m - 1};\n{forward(True, False)}"
        f"previous = d0[{m - 1}] * rc[{m - 1}];\nd0[{m - 1}] = previous;\n"
        f"for (i = {m - 2}; i >= 0; --i) {{\n"
        f"  previous = (d0[i] - up[i] * previous) * rc[i];\n  d0[i] = previous;\n}}\n")
    for j, (gain, row) in enumerate(loops):           # s_j, then e_j = s_j + (Q delta0)_j - (Q W s)_j
        body += f"casadi_real s{j} = {float(gain)!r} * ({_sparse_dot(row[:m], 'dx')} + {_sparse_dot(row[m:], 'B')})" \
                f" + c[{j}];\n"
    coupling = woodbury @ columns if k else np.zeros((0, 0))
    for j in range(k):
        body += f"casadi_real e{j} = s{j} + {_sparse_dot(woodbury[j], 'd0')}" + "".join(
            f" - {float(coupling[j, l])!r} * s{l}" for l in range(k) if coupling[j, l]) + ";\n"
    correction = "".join(f" - w{j}[i] * e{j}" for j in range(k))
    lines = [f"  delta = d0[i]{correction};\n"]
    for r in range(5):
        terms = [f"{float(value)!r} * h[{c * m} + i]" for c, value in enumerate(update[r, :5]) if value]
        if update[r, 5]:
            terms.append(f"{float(update[r, 5])!r} * delta")
        lines.append(f"  n{r} = {' + '.join(terms) or '0.0'};\n")
    stores = "".join(f"  out[{r * m} + i] = n{r};\n" for r in range(5))
    body += f"for (i = 0; i < {m}; ++i) {{\n  casadi_real n0, n1, n2, n3, n4;\n{''.join(lines)}{stores}}}\n"
    inputs, sparsity = ["h"], [ca.Sparsity.dense(5 * m)]
    if forced:
        inputs, sparsity = inputs + ["f"], sparsity + [ca.Sparsity.dense(m)]
    if k:
        inputs, sparsity = inputs + ["c"], sparsity + [ca.Sparsity.dense(k)]
    function = ca.Function.jit(label, body, inputs, ["out"], sparsity, [ca.Sparsity.dense(5 * m)], {"buffered": False})
    return function, body
