"""Reported signals of the algebraic massless nodes of a 1-D chain on the DT-TMM path.

A massless node between springs is placed by its static balance at every step; its position is not a
state of the integration scheme, so the scheme's velocity and acceleration updates are no derivatives
of it.  :func:`algebraic_points` finds these points, :func:`algebraic_point_rates` reports their
velocity from their positions and their acceleration as ``NaN`` (``docs/schemes.md`` §7).
"""
from __future__ import annotations

import numpy as np

from .chain_ode import ChainDynamics
from .chain_start import initial_state, point_of_element
from .errors import ModelError
from .system import Chain

__all__ = ["algebraic_points", "algebraic_point_rates", "balanced_start", "hold_supports"]


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


def balanced_start(system: Chain, x0, v0, t0: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~ctmm.chain_start.initial_state` with the massless points at their static balance, by Newton's method.

    For the chains whose massless points :class:`~ctmm.chain_ode.ChainDynamics` does not condense (nonlinear
    connectors next to them: their tangents depend on the point): the chain held at the given positions, velocities
    left out, as :meth:`~ctmm.chain_ode.ChainDynamics.consistent_start` does for the linear ones (a massless point
    left at its rest length gave the first step, and the scheme's history, the wrong connector forces).  Newton on
    the forces on the massless nodes with central-difference tangents, to ``1e-13 (1 + |x|)`` [m].  Chains off the
    ``d = 1`` protocol keep :func:`~ctmm.chain_start.initial_state`.

    Returns
    -------
    x, v : ndarray, shape (n_points, 1)
        Positions [m] and velocities [m/s] of the connection points (massless points' velocities as given).

    Raises
    ------
    ModelError
        The balance does not determine the massless nodes, Newton does not converge in 50 iterations, or an ``x0``
        of a massless point is off its balance.
    """
    x_points, v_points = initial_state(system, x0, v0)
    try:
        dynamics = ChainDynamics(system, balance_only=True)
    except ModelError:
        return x_points, v_points
    q, n = dynamics.index_Q, dynamics.tree.n_nodes
    if not q.size:
        return x_points, v_points
    x = np.zeros(n)
    for p, k in enumerate(dynamics.node_of_point):
        if k >= 0:
            x[k] = x_points[p, 0]
    try:                                          # a prescribed start where it is at t0 (closed forms)
        dynamics.hold(t0, x, np.zeros(n))
    except ModelError:
        pass
    given = {name: int(dynamics.node_of_point[point_of_element(system, name)]) for name in (x0 or {})}
    given = {name: (k, x[k]) for name, k in given.items() if k in q}
    inputs, wall, still = dynamics.inputs(t0), dynamics.wall_motion(t0), np.zeros((1 + 2 * q.size, n))
    names = ", ".join(dynamics.node_name(k) for k in q)
    for _ in range(50):
        steps = 1e-7 * (1.0 + np.abs(x[q]))
        probes = np.tile(x, (1 + 2 * q.size, 1))
        probes[1 + np.arange(q.size), q] += steps
        probes[1 + q.size + np.arange(q.size), q] -= steps
        forces = dynamics.forces(probes, still, t0, inputs, wall)[:, q]
        tangent = ((forces[1:1 + q.size] - forces[1 + q.size:]) / (2.0 * steps[:, None])).T   # d force_i / d x_j
        if np.linalg.cond(tangent) > 1e12:
            raise ModelError(f"chain {system.name!r}: the massless nodes ({names}) are not determined by their force "
                             "balance at the start (singular tangent stiffness); give them a mass, or a spring to a "
                             "neighbour")
        move = np.linalg.solve(tangent, -forces[0])
        x[q] += move
        if np.all(np.abs(move) <= 1e-13 * (1.0 + np.abs(x[q]))):
            break
    else:
        raise ModelError(f"chain {system.name!r}: the static balance of the massless nodes ({names}) at the start did "
                         "not converge in 50 Newton iterations; give them a mass, or their positions in x0")
    for name, (k, value) in given.items():
        if abs(x[k] - value) > 1e-9 * max(1.0, abs(value)):
            raise ModelError(f"x0[{name!r}] = {float(value)!r}: the point of {name!r} has no mass and its position "
                             "follows from the force balance of the elements around it "
                             f"({x[k]:.9g} m under the other initial positions); leave it out of x0, or give it a mass")
    massless = np.isin(dynamics.node_of_point, q)
    x_points[massless, 0] = x[dynamics.node_of_point[massless]]
    hold_supports(dynamics, x_points, v_points, t0)
    return x_points, v_points


def hold_supports(dynamics: ChainDynamics, x: np.ndarray, v: np.ndarray, t0: float) -> None:
    """Put the points held by displacement-type supports (``x``, ``v``: ``(n_points, 1)``, in place) on their motion
    at ``t0`` [s]; a support whose signal has no closed-form rate stays where it is."""
    for points, motion in dynamics.held_points():
        try:
            x[points, 0], v[points, 0] = motion(t0)[:2]
        except ModelError:
            pass
