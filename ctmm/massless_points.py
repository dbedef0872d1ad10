"""Reported signals of the algebraic massless nodes of a 1-D chain on the DT-TMM path.

A massless node between springs is placed by its static balance at every step; its position is not a
state of the integration scheme, so the scheme's velocity and acceleration updates are no derivatives
of it.  :func:`algebraic_points` finds these points, :func:`algebraic_point_rates` reports their
velocity from their positions and their acceleration as ``NaN`` (``docs/schemes.md`` §7).
"""
from __future__ import annotations

import numpy as np

from .chain_ode import ChainDynamics
from .errors import ModelError
from .system import Chain

__all__ = ["algebraic_points", "algebraic_point_rates"]


def algebraic_points(system: Chain) -> np.ndarray:
    """Mask ``(n_points,)`` of the connection points at **algebraic massless nodes** of a 1-D chain.

    A massless node (:func:`~ctmm.lumped_forms.massless_nodes`) whose velocity enters no force (only
    springs, no damper or inerter acts on it) is placed by its static balance at every instant: its
    position is algebraic, not a state of any integrator.  The scheme's kinematic update
    (``v = v_hat + gamma h a``) is then no derivative of it: a start or a load jump off the balance
    makes the trapezoidal velocity ring ``v_{n+1} = 2 (x_{n+1} - x_n) / h - v_n`` for ever (a reported
    velocity of twice, then zero times, the true one).  :func:`ctmm.timestep.simulate` reports the
    velocity of these points from their positions instead (:func:`algebraic_point_rates`) and their
    acceleration as ``NaN``.  Massless nodes next to a damper are first-order states: their scheme
    velocity satisfies the balance at every step and is kept.

    Parameters
    ----------
    system : Chain
        The chain (the one the DT-TMM steps).

    Returns
    -------
    ndarray of bool, shape (n_points,)
        ``True`` at the points of algebraic massless nodes; all ``False`` off the ``d = 1`` protocol.
    """
    try:
        dynamics = ChainDynamics(system)
    except ModelError:
        return np.zeros(system.n_points, dtype=bool)
    q = dynamics.index_Q
    if not q.size:
        return np.zeros(system.n_points, dtype=bool)
    first_order = np.linalg.norm(dynamics.P_r, axis=1) > 1e-9 if dynamics.n_r else np.zeros(q.size, dtype=bool)
    nodes = q[~first_order]
    return np.isin(dynamics.node_of_point, nodes) & (dynamics.node_of_point >= 0)


def algebraic_point_rates(states: np.ndarray, vel: np.ndarray, acc: np.ndarray, row: int, dt: float,
                          algebraic: np.ndarray, consistent: bool) -> None:
    """Velocity [m/s] of the algebraic massless points at ``row`` from their positions, acceleration ``NaN``.

    Parameters
    ----------
    states, vel, acc : ndarray, shape (n_rows, n_points, ...)
        Result arrays of the run (positions [m] in ``states[..., 0]``), filled up to ``row``; ``vel``
        [m/s] and ``acc`` [m/s^2] are overwritten at ``row`` for the ``algebraic`` points.
    row : int
        Row just computed (>= 1).
    dt : float
        Step [s].
    algebraic : ndarray of bool, shape (n_points,)
        :func:`algebraic_points`.
    consistent : bool
        Whether the start was on the balance (then ``vel[0]`` is the true start velocity).

    Second-order backward difference ``(3 x_n - 4 x_{n-1} + x_{n-2}) / (2 h)``; on the first step
    ``2 (x_1 - x_0) / h - v_0`` after a consistent start (second order), ``(x_1 - x_0) / h`` otherwise
    (the start was off the balance, so ``v_0`` is no derivative). A jump of the load (a step) gives a
    finite spike over two steps (the true velocity is an impulse there), then the right values."""
    x = states[:, algebraic, 0]
    if row >= 2:
        vel[row, algebraic, 0] = (3.0 * x[row] - 4.0 * x[row - 1] + x[row - 2]) / (2.0 * dt)
    elif consistent:
        vel[row, algebraic, 0] = 2.0 * (x[row] - x[row - 1]) / dt - vel[row - 1, algebraic, 0]
    else:
        vel[row, algebraic, 0] = (x[row] - x[row - 1]) / dt
    acc[row, algebraic] = np.nan
