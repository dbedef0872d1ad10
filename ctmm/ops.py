"""One namespace of array operations for physics written once (issue 12, ``docs/plans/one_core.md`` §2.1).

Element physics (:mod:`ctmm.protocol`) and the articulated sweep (:mod:`ctmm.articulated`) use only
the operations of an :class:`Ops` object and the arithmetic operators ``+ - *`` (elementwise, with a
scalar broadcasting against a matrix).  Two implementations:

* :data:`NUMPY` -- every value is a **batched matrix** of shape ``(B, rows, columns)`` (a scalar is
  ``(B, 1, 1)``, a vector a column ``(B, n, 1)``); float or complex (complex-step tangents and
  frequency sweeps use the complex dtype; ``B`` may be 1 for constants, which broadcast).  An
  unbatched ``(rows, columns)`` array is one evaluation (``B = 1``): numpy's calls on 2-D arrays
  are cheaper, which is the fast path of single-state callers (``flexible/kernel.py``); results
  stay 2-D while every operand is;
* :data:`CASADI` -- every value is a ``casadi.SX`` (or ``MX``) matrix ``(rows, columns)``, no batch axis.

Rules for code written against :class:`Ops`: no in-place writes (``SX`` is immutable), no Python
branching on values (use :meth:`Ops.if_else`), no ``abs``/``max``/``clip`` on state-dependent
values (not complex-step safe).  Python branching on *structure* (sizes, kinds, names) is fine.
"""
from __future__ import annotations

from typing import Any, Protocol, Sequence

import numpy as np
from scipy.linalg import lapack

_SCALARS = (int, float, complex, np.number)
_FLOAT = np.dtype(np.float64)

__all__ = ["Ops", "NumpyOps", "CasadiOps", "NUMPY", "CASADI", "batch_scalars", "batch_column", "batch_shape"]


class Ops(Protocol):
    """Operations valid on batched numpy matrices (float or complex) and casadi symbols."""

    name: str

    def sin(self, x: Any) -> Any: ...
    def cos(self, x: Any) -> Any: ...
    def sqrt(self, x: Any) -> Any: ...
    def exp(self, x: Any) -> Any: ...
    def block(self, rows: Sequence[Sequence[Any]]) -> Any:
        """Matrix from a grid of blocks; an entry is a matrix or a scalar (Python number or 1 x 1)."""
    def matmul(self, a: Any, b: Any) -> Any: ...
    def solve(self, a: Any, b: Any) -> Any:
        """``a^-1 b`` for a small square ``a``."""
    def det(self, a: Any) -> Any:
        """Determinant of a square matrix, as a 1 x 1 matrix."""
    def transpose(self, a: Any) -> Any: ...
    def sub(self, a: Any, rows: slice, columns: slice) -> Any:
        """The block ``a[rows, columns]`` (no copy semantics assumed)."""
    def zeros(self, rows: int, columns: int) -> Any:
        """A zero constant (broadcasts against any batch)."""
    def eye(self, n: int) -> Any:
        """An identity constant (broadcasts against any batch)."""
    def if_else(self, condition: Any, a: Any, b: Any) -> Any: ...
    def shape(self, a: Any) -> tuple[int, int]:
        """``(rows, columns)`` of a matrix (without the batch axis)."""


def _tiling(rows: Sequence[Sequence[Any]]) -> tuple[list[int], list[int], bool] | None:
    """``(heights, widths, uniform)`` when a grid of blocks is numpy arrays of one rank whose heights agree along
    each row and widths along each column (the blocks tile the matrix, no entry broadcasts into a larger slot),
    ``uniform`` when they also share one dtype and batch (then concatenation is :meth:`NumpyOps.block`); else
    None."""
    first = rows[0][0]
    if type(first) is not np.ndarray or first.ndim < 2:
        return None
    ndim, dtype, lead = first.ndim, first.dtype, first.shape[:-2]
    widths = [e.shape[-1] if type(e) is np.ndarray else -1 for e in rows[0]]
    heights, uniform = [], True
    for row in rows:
        if len(row) != len(widths) or type(row[0]) is not np.ndarray:
            return None
        height = row[0].shape[-2]
        for e, width in zip(row, widths):
            if type(e) is not np.ndarray or e.ndim != ndim or e.shape[-1] != width or e.shape[-2] != height:
                return None
            uniform = uniform and e.dtype == dtype and e.shape[:-2] == lead
        heights.append(height)
    return heights, widths, uniform


def _numbers_only(rows: Sequence[Sequence[Any]]) -> bool:
    """Whether every entry of a grid is a Python or numpy number (plain loops: no generator frame per call)."""
    for row in rows:
        for entry in row:
            if not isinstance(entry, _SCALARS):
                return False
    return True


def _assembled(grid: Sequence[Sequence[Any]], heights: Sequence[int], widths: Sequence[int], batch: int | None = None,
               batched: bool = True) -> np.ndarray:
    """One allocation of the matrix of ``grid`` (row ``heights``, column ``widths``), one broadcasting assignment
    per entry; ``batch``: the batch size (default the largest leading size of the entries); ``batched=False``: a
    matrix without the batch axis."""
    entries = [e for row in grid for e in row]
    if batch is None:
        batch = max(e.shape[0] for e in entries)
    shape = (sum(heights), sum(widths))
    out = np.empty((batch,) + shape if batched else shape, dtype=np.result_type(*entries, float))
    r0 = 0
    for row, height in zip(grid, heights):
        c0 = 0
        for entry, width in zip(row, widths):
            out[..., r0:r0 + height, c0:c0 + width] = entry
            c0 += width
        r0 += height
    return out


class NumpyOps:
    """:class:`Ops` on numpy arrays of shape ``(B, rows, columns)``; Python numbers are ``(1, 1, 1)``."""

    name = "numpy"

    @staticmethod
    def _matrix(x: Any) -> np.ndarray:
        array = np.asarray(x)
        if array.ndim == 0:
            return array.reshape(1, 1, 1)
        if array.ndim == 2:
            return array[None]
        if array.ndim != 3:
            raise ValueError(f"numpy ops values are (B, rows, columns) arrays, got shape {array.shape}")
        return array

    sin = staticmethod(np.sin)
    cos = staticmethod(np.cos)
    sqrt = staticmethod(np.sqrt)
    exp = staticmethod(np.exp)

    def block(self, rows: Sequence[Sequence[Any]]) -> np.ndarray:
        if type(rows[0][0]) is not np.ndarray and _numbers_only(rows):   # numbers only: one call, B = 1
            out = np.array(rows)
            return (out if out.dtype.kind in "fc" else out.astype(float))[None]
        if len(rows) == 1:
            parts, axis = rows[0], -1
        elif len(rows[0]) == 1:                     # a column (plain loop: no generator frame per call)
            parts, axis = [], -2
            for row in rows:
                if len(row) != 1:
                    parts = None
                    break
                parts.append(row[0])
        else:
            parts = None
        if parts:                                   # one row or column of equal-kind arrays: concatenate
            first = parts[0]
            if type(first) is np.ndarray:
                ndim, dtype, lead = first.ndim, first.dtype, first.shape[:-2]
                for e in parts:
                    if type(e) is not np.ndarray or e.ndim != ndim or e.dtype != dtype or e.shape[:-2] != lead:
                        break
                else:
                    return np.concatenate(parts, axis=axis)
        elif (tiling := _tiling(rows)) is not None:     # a grid of arrays that tile: no broadcasting into a slot
            heights, widths, uniform = tiling
            if uniform:                                 # one dtype and batch: concatenation
                return np.concatenate([np.concatenate(row, axis=-1) for row in rows], axis=-2)
            if rows[0][0].ndim == 3:                    # batches B and 1, or mixed dtypes: one allocation
                return _assembled(rows, heights, widths)
        # one allocation, one broadcasting assignment per entry (scalars and B = 1 entries broadcast)
        grid = [[entry if isinstance(entry, (int, float, complex)) else np.asarray(entry) for entry in row]
                for row in rows]
        arrays = [e for row in grid for e in row if isinstance(e, np.ndarray) and e.ndim]
        if any(e.ndim not in (2, 3) for e in arrays):
            bad = next(e for e in arrays if e.ndim not in (2, 3))
            raise ValueError(f"numpy ops values are (B, rows, columns) arrays, got shape {bad.shape}")
        batch = max([e.shape[0] for e in arrays if e.ndim == 3], default=None)
        heights = [max([e.shape[-2] for e in row if isinstance(e, np.ndarray) and e.ndim], default=1) for row in grid]
        widths = [max([row[c].shape[-1] for row in grid if isinstance(row[c], np.ndarray) and row[c].ndim],
                      default=1) for c in range(len(grid[0]))]
        return _assembled(grid, heights, widths, batch or 1, batched=batch is not None or not arrays)

    matmul = staticmethod(np.matmul)           # no Python frame: the sweep's most frequent call

    @staticmethod
    def solve(a: Any, b: Any) -> np.ndarray:
        if type(a) is np.ndarray and type(b) is np.ndarray and a.ndim == 2 == b.ndim and a.dtype == _FLOAT \
                and b.dtype == _FLOAT and a.shape[0] == a.shape[1] == b.shape[0] > 0:
            # one real system (the single-state sweeps): LAPACK dgesv, the routine np.linalg.solve calls, without
            # its batched-ufunc set-up (3 us instead of 10-20 us for a 3 x 3); an exactly singular matrix raises
            # the same LinAlgError
            _, _, x, info = lapack.dgesv(a, b)
            if info > 0:
                raise np.linalg.LinAlgError("Singular matrix")
            if info == 0:
                return np.ascontiguousarray(x)
        a, b = np.asarray(a), np.asarray(b)
        if a.shape[:-2] == b.shape[:-2]:
            return np.linalg.solve(a, b)
        batch = np.broadcast_shapes(a.shape[:-2], b.shape[:-2])
        return np.linalg.solve(np.broadcast_to(a, batch + a.shape[-2:]), np.broadcast_to(b, batch + b.shape[-2:]))

    @staticmethod
    def det(a: Any) -> np.ndarray:
        return np.linalg.det(a)[..., None, None]

    @staticmethod
    def transpose(a: Any) -> np.ndarray:
        return a.swapaxes(-1, -2) if type(a) is np.ndarray else np.swapaxes(a, -1, -2)

    @staticmethod
    def sub(a: Any, rows: slice, columns: slice) -> np.ndarray:
        return a[..., rows, columns]

    @staticmethod
    def zeros(rows: int, columns: int) -> np.ndarray:
        return np.zeros((1, rows, columns))

    @staticmethod
    def eye(n: int) -> np.ndarray:
        return np.eye(n)[None]

    @staticmethod
    def if_else(condition: Any, a: Any, b: Any) -> np.ndarray:
        return np.where(condition, a, b)

    @staticmethod
    def shape(a: Any) -> tuple[int, int]:
        return a.shape[-2:] if type(a) is np.ndarray else tuple(np.shape(a)[-2:])


class CasadiOps:
    """:class:`Ops` on ``casadi.SX`` / ``casadi.MX`` matrices (imported on first use)."""

    name = "casadi"

    @property
    def _ca(self):
        import casadi

        return casadi

    def sin(self, x: Any) -> Any:
        return self._ca.sin(x)

    def cos(self, x: Any) -> Any:
        return self._ca.cos(x)

    def sqrt(self, x: Any) -> Any:
        return self._ca.sqrt(x)

    def exp(self, x: Any) -> Any:
        return self._ca.exp(x)

    def block(self, rows: Sequence[Sequence[Any]]) -> Any:
        ca = self._ca
        return ca.vertcat(*[ca.horzcat(*[ca.SX(e) if isinstance(e, (int, float)) else e for e in row])
                            for row in rows])

    def matmul(self, a: Any, b: Any) -> Any:
        return self._ca.mtimes(a, b)

    def solve(self, a: Any, b: Any) -> Any:
        return self._ca.solve(a, b)

    def det(self, a: Any) -> Any:
        return self._ca.det(a)

    @staticmethod
    def transpose(a: Any) -> Any:
        return a.T

    @staticmethod
    def sub(a: Any, rows: slice, columns: slice) -> Any:
        return a[rows, columns]

    def zeros(self, rows: int, columns: int) -> Any:
        return self._ca.SX.zeros(rows, columns)

    def eye(self, n: int) -> Any:
        return self._ca.SX.eye(n)

    def if_else(self, condition: Any, a: Any, b: Any) -> Any:
        return self._ca.if_else(condition, a, b)

    @staticmethod
    def shape(a: Any) -> tuple[int, int]:
        return tuple(a.shape)


NUMPY = NumpyOps()
"""Batched numpy implementation (float or complex)."""
CASADI = CasadiOps()
"""casadi implementation (``SX`` / ``MX`` symbols)."""


def batch_scalars(values: Any) -> list[np.ndarray]:
    """Columns of a ``(B, n)`` numpy array as ``n`` batched scalars ``(B, 1, 1)`` for :data:`NUMPY`."""
    values = np.asarray(values)
    if values.ndim == 1:
        values = values[None]
    return [values[:, k].reshape(-1, 1, 1) for k in range(values.shape[1])]


def batch_column(values: Any) -> np.ndarray:
    """A ``(B, n)`` (or ``(n,)``) numpy array as a batched column ``(B, n, 1)`` for :data:`NUMPY`."""
    values = np.asarray(values)
    if values.ndim == 1:
        values = values[None]
    return values[:, :, None]


def batch_shape(*arrays: np.ndarray) -> tuple[int, ...]:
    """The broadcast leading shape of numpy ops values (their shapes without the last two axes): the result of
    ``np.broadcast_shapes`` on those, without its cost (about 5 us a call) for the usual leads ``(B,)`` and ``(1,)``
    (incompatible leads: ``np.broadcast_shapes``'s ``ValueError``)."""
    first = arrays[0].shape[:-2]
    leads = [a.shape[:-2] for a in arrays]
    if all(lead == first for lead in leads):
        return first
    if all(len(lead) == 1 for lead in leads):
        sizes = {lead[0] for lead in leads} - {1}
        if len(sizes) == 1:
            return (sizes.pop(),)
    return np.broadcast_shapes(*leads)

