"""Casadi scalars that numpy's object arrays treat as numbers, to run numpy code on symbols (issue 13).

The generated kernels state a few element definitions by running the numpy path's own statements on casadi SX
scalars wrapped as :class:`TracedScalar` in object arrays (:func:`traced_array`), and unwrapping the results
(:func:`untraced`): the cut points of :mod:`ctmm.compiled_cut_points` and :mod:`ctmm.compiled_spatial_cut_points`,
the deformed points of beams and ``ctmm.fem`` subsystems of :mod:`ctmm.symbolic_beam_points`.  The generated
expression is then the numpy definition by construction, not a second statement of it.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

__all__ = ["TracedScalar", "traced_array", "untraced"]


class TracedScalar:
    """A casadi SX scalar that numpy's object arrays and functions treat as a number.

    ``np.cos`` / ``np.sin`` call :meth:`cos` / :meth:`sin`; ``+ - * /`` with numbers or other traced scalars give
    traced scalars, with a numpy array numpy's own element-wise operator; ``float()`` refuses (a symbol has no
    value: the numpy routine traced must not convert it).  :attr:`value` is the casadi expression.
    """

    __slots__ = ("value",)
    __array_priority__ = -1.0

    def __init__(self, value: Any) -> None:
        self.value = value

    @staticmethod
    def _of(other: Any) -> Any:
        if isinstance(other, TracedScalar):
            return other.value
        if isinstance(other, (int, float, np.floating, np.integer)):
            return float(other)
        return NotImplemented

    def _apply(self, other: Any, operation: Any) -> Any:
        other = self._of(other)
        return NotImplemented if other is NotImplemented else TracedScalar(operation(self.value, other))

    def __add__(self, other: Any) -> Any:
        return self._apply(other, lambda a, b: a + b)

    def __radd__(self, other: Any) -> Any:
        return self._apply(other, lambda a, b: b + a)

    def __sub__(self, other: Any) -> Any:
        return self._apply(other, lambda a, b: a - b)

    def __rsub__(self, other: Any) -> Any:
        return self._apply(other, lambda a, b: b - a)

    def __mul__(self, other: Any) -> Any:
        return self._apply(other, lambda a, b: a * b)

    def __rmul__(self, other: Any) -> Any:
        return self._apply(other, lambda a, b: b * a)

    def __truediv__(self, other: Any) -> Any:
        return self._apply(other, lambda a, b: a / b)

    def __neg__(self) -> "TracedScalar":
        return TracedScalar(-self.value)

    def __pos__(self) -> "TracedScalar":
        return self

    def cos(self) -> "TracedScalar":
        import casadi as ca

        return TracedScalar(ca.cos(self.value))

    def sin(self) -> "TracedScalar":
        import casadi as ca

        return TracedScalar(ca.sin(self.value))

    def __float__(self) -> float:
        raise TypeError("a traced casadi symbol has no float value (the traced numpy routine converted it)")

    def __bool__(self) -> bool:
        raise TypeError("a traced casadi symbol has no truth value (the traced numpy routine branched on it)")


def untraced(value: Any) -> Any:
    """The casadi expression of a traced scalar (numbers as they are)."""
    return value.value if isinstance(value, TracedScalar) else value


def traced_array(values: Sequence[Any]) -> np.ndarray:
    """A 1-D object array of :class:`TracedScalar` of the casadi scalars ``values``."""
    out = np.empty(len(values), dtype=object)
    out[:] = [TracedScalar(value) for value in values]
    return out
