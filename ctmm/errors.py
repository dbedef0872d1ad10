"""Exception types of ctmm.

All errors raised for bad input derive from :class:`ModelError` (a ``ValueError``);
failures during a simulation derive from :class:`SimulationError` (a ``RuntimeError``).
"""
from __future__ import annotations


class ModelError(ValueError):
    """A model, parameter or option is invalid (names the parameter, value and what is allowed)."""


class UnknownNameError(ModelError, KeyError):
    """A signal, element, boundary or loop name does not exist; the message lists the known names."""

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return str(self.args[0]) if self.args else ""


class SingularSystemError(ModelError):
    """The boundary-value problem has no unique solution (e.g. free-free chain under static load)."""


class SimulationError(RuntimeError):
    """A time simulation failed (non-finite state, divergence); carries ``time`` and ``element``.

    Parameters
    ----------
    message : str
        Human-readable description.
    time : float, optional
        Simulation time [s] at which the failure was detected.
    element : str, optional
        Name of the element where the failure was first seen.
    partial_result : object, optional
        Result object holding everything computed up to the failure.
    """

    def __init__(self, message: str, *, time: float | None = None, element: str | None = None,
                 partial_result: object | None = None) -> None:
        super().__init__(message)
        self.time = time
        self.element = element
        self.partial_result = partial_result


class ConvergenceError(SimulationError):
    """An implicit step or iterative solve did not converge (says which step, residual, iterations)."""


def unknown_name(kind: str, name: str, known: "list[str] | tuple[str, ...]") -> UnknownNameError:
    """Build an :class:`UnknownNameError` that lists the available names.

    Parameters
    ----------
    kind : str
        What was looked up, e.g. ``"signal"`` or ``"element"``.
    name : str
        The name that was not found.
    known : sequence of str
        The names that exist.
    """
    listing = ", ".join(sorted(known)) if known else "(none)"
    return UnknownNameError(f"unknown {kind} {name!r}; available: {listing}")
