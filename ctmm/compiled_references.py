"""Time signals of generated kernels: references and open-loop inputs on casadi symbols (issue 13).

:class:`SymbolicReference` is a signal written twice, as numbers and on symbols;
:func:`symbolic_reference` accepts a number, a :mod:`ctmm.signals` object with a symbolic form or a
:class:`SymbolicReference` (checked: both forms equal at a few times) and refuses Python callables;
:func:`reference_at` is its value on a time symbol.  Used by :mod:`ctmm.compiled_loops`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from .errors import ModelError
from .signals import as_signal, signal_parameters, symbolic_signal

__all__ = ["SymbolicReference", "reference_at", "symbolic_reference"]


@dataclass(frozen=True)
class SymbolicReference:
    """A time signal given twice: as numbers and on casadi symbols (for references and inputs that
    :mod:`ctmm.signals` has no class for, e.g. a cycloidal move).  Callable as ``r(t)`` [float], so the
    numpy path takes it too.

    Parameters
    ----------
    numeric : callable
        ``t [s] -> float``.
    symbolic : callable
        ``t`` (casadi symbol) ``->`` casadi expression, the same operations.
    """

    numeric: Callable[[float], float]
    symbolic: Callable[[Any], Any]

    def __call__(self, t: float) -> float:
        return float(self.numeric(t))


def symbolic_reference(label: str, value: Any) -> Any:
    """A number, a :mod:`ctmm.signals` object with a symbolic form or a :class:`SymbolicReference`, as a
    signal; ModelError otherwise."""
    if isinstance(value, SymbolicReference):
        _check_forms(label, value)
        return value
    signal = as_signal(label, value)
    if signal_parameters(signal) is None:
        raise ModelError(f"{label} is a Python callable of time, which generated kernels cannot evaluate; give a "
                         "number, a ctmm.signals Constant, Harmonic, Step, SquareWave or Ramp, or a "
                         "ctmm.compiled_references.SymbolicReference, or use compiled=False")
    return signal


def _check_forms(label: str, reference: SymbolicReference) -> None:
    """Refuse a :class:`SymbolicReference` whose two forms differ (relative 1e-12) at a few times [s]."""
    import casadi as ca

    t = ca.SX.sym("t")
    try:
        function = ca.Function("reference", [t], [reference.symbolic(t)])
    except Exception as exc:  # noqa: BLE001 - report what the user's symbolic form did
        raise ModelError(f"{label}: the symbolic form of the SymbolicReference failed on a casadi symbol "
                         f"({exc!r})") from None
    for time in (0.0, 0.013, 0.31, 0.77, 1.9, 4.3):
        numeric, symbolic = reference(time), float(function(time))
        if not abs(numeric - symbolic) <= 1e-12 * max(1.0, abs(numeric)):
            raise ModelError(f"{label}: the SymbolicReference's numeric and symbolic forms differ at t = {time} s "
                             f"({numeric!r} and {symbolic!r}); they must be the same signal")


def reference_at(signal: Any, t: Any) -> Any:
    """The value of a :func:`symbolic_reference` signal at the time ``t`` (a casadi symbol) [s]."""
    if isinstance(signal, SymbolicReference):
        return signal.symbolic(t)
    return symbolic_signal(type(signal), t, signal_parameters(signal))
