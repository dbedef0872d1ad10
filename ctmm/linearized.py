"""Result types of :func:`ctmm.linearize` and the python-control labels of ctmm names.

Kept apart from :mod:`ctmm.linearize` so that every linearisation path (chains in
:mod:`ctmm.linearize`, planar models in :mod:`ctmm.planar_linearization`) builds the same types
without importing one another.
"""
from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

__all__ = ["DelayedLoop", "OperatingPoint", "LinearizedSystem", "control_name"]


def control_name(name: str) -> str:
    """python-control label of a ctmm signal name: ``"m2.force"`` -> ``"m2_force"``.

    python-control reserves ``'.'`` in signal names (``"system.signal"`` in ``interconnect``);
    ctmm element names contain no dots, so the mapping is unambiguous in practice.
    """
    return str(name).replace(".", "_")


class DelayedLoop(NamedTuple):
    """A loop left open by :func:`linearize`: ``u(t) = -gain * y(t - delay)``.

    Attributes
    ----------
    name : str
        Loop name; its ports are the state-space input ``"<name>_u"`` and output ``"<name>_y"``.
    gain : float or control.LTI
        Static gain or SISO controller ``C(s)``.
    delay : float
        [s], > 0.
    """

    name: str
    gain: Any
    delay: float


class OperatingPoint(NamedTuple):
    """Where a planar model was linearised.

    Attributes
    ----------
    q, qdot : ndarray, shape (n_coordinates,)
        Coordinates [rad, m, modal] and rates.
    t : float
        Time [s] at which time-dependent model data (loads, references) were frozen.
    coordinates : tuple of str
        Names of ``q``.
    equilibrium : bool
        True when the accelerations vanish there at rest (a true equilibrium).
    jacobian_error : float
        Estimated largest error of an entry of ``A`` divided by ``max |A|`` (module docstring).
    """

    q: np.ndarray
    qdot: np.ndarray
    t: float
    coordinates: tuple[str, ...] = ()
    equilibrium: bool = True
    jacobian_error: float = 0.0


class LinearizedSystem(NamedTuple):
    """Result of :func:`linearize`.

    Attributes
    ----------
    state_space : control.StateSpace
        Named states, inputs and outputs; real-time loops closed inside; each delayed loop left
        open as input ``"<loop>_u"`` and output ``"<loop>_y"``.
    delays : tuple of DelayedLoop
        The delayed loops, in the order of their ports.
    operating_point : OperatingPoint or None
        ``None`` for (linear) chains.
    """

    state_space: Any
    delays: tuple[DelayedLoop, ...]
    operating_point: Any
