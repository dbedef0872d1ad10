"""Positions, velocities, accelerations and internal forces at every connection point of a lumped chain over
many stored rows at once (the result of a chain's ODE run, :mod:`ctmm.chain_ode`).

:func:`point_values_rows` takes the accelerations from the chain's certified affine rates
(:mod:`ctmm.chain_affine`: matrix products over all rows) where it has them, else from one batched sweep,
and the forces from :func:`point_forces_rows`; chains with massless points go row by row
(:meth:`ctmm.chain_ode.ChainDynamics.point_values`, which condenses them).

:func:`point_forces_rows` is :func:`ctmm.chain_start.initial_forces` on arrays of rows (one numpy
operation per element, not one Python loop per row): connectors give the force at their two points
from their law (``-k (dx - free length) - c dv - b da`` plus an actuator force across them),
boundaries with a known force give theirs (spring, damper and applied force at each row's time), and
the remaining points follow from the equilibrium of the point elements between them
(``f_out = f_in - m a - c v - k x + F``), propagated forward then backward.  Which point is set
from which depends on the chain's structure only, so the propagation is the same for every row.
A chain with a connector whose law is not affine (``transmitted_force``) keeps the row-by-row function.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from .chain_start import initial_forces
from .signals import Constant

__all__ = ["point_values_rows", "point_forces_rows"]


def point_values_rows(dynamics: Any, times: np.ndarray, states: np.ndarray,
                      extras: Sequence[Mapping[int, Mapping[str, float]] | None] | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Positions [m], velocities [m/s], accelerations [m/s^2] and forces [N] ``(rows, n_points)`` at every
    point of the chain of ``dynamics`` (:class:`ctmm.chain_ode.ChainDynamics`) from its states ``(rows, size)``
    at ``times`` [s], with the actuator inputs ``extras[i]`` ``{position: {input: value}}`` [N] of each row."""
    times = np.asarray(times, dtype=float)
    rows = len(times)
    extras = list(extras) if extras is not None else [None] * rows
    if dynamics.index_Q.size or rows < 2:
        out = np.zeros((4, rows, dynamics.chain.n_points))
        for i in range(rows):
            out[:, i] = dynamics.point_values(float(times[i]), np.asarray(states[i]), extras[i])
        return out[0], out[1], out[2], out[3]
    n, I = dynamics.tree.n_nodes, dynamics.index_I
    m = I.size
    x, v = np.zeros((rows, n)), np.zeros((rows, n))
    x[:, I], v[:, I] = states[:, :m], states[:, m:2 * m]
    motion = dynamics.boundary_motion_rows(times)
    held = dynamics.held
    x[:, held], v[:, held] = motion[:, [0]], motion[:, [1]]
    linear = dynamics.linear
    if linear is not None:
        a = np.zeros((rows, n))
        a[:, I] = linear.accelerations_rows(times, states[:, :2 * m], motion, extras)
    else:
        merged: dict[int, dict[str, np.ndarray]] = {}
        for i, t in enumerate(times):
            for position, values in dynamics.inputs(float(t), extras[i]).items():
                for name, value in values.items():
                    merged.setdefault(position, {}).setdefault(name, np.zeros(rows))[i] = value
        inputs = {position: {name: column[:, None, None] for name, column in values.items()}
                  for position, values in merged.items()}
        a = dynamics.forces(x, v, float(times[0]), inputs, (motion[:, 3], motion[:, 4], motion[:, 5]))
    a[:, held] = motion[:, [2]]
    k = dynamics.node_of_point
    on_wall = k < 0
    xp, vp, ap = x[:, k], v[:, k], a[:, k]
    for values, part in ((xp, 3), (vp, 4), (ap, 5)):
        values[:, on_wall] = motion[:, [part]]
    across = [{position: sum(values.values()) for position, values in (extra or {}).items()} for extra in extras]
    forces = point_forces_rows(dynamics.chain, times, xp, vp, ap, across)
    if forces is None:                  # a nonlinear connector law: row by row
        forces = np.array([initial_forces(dynamics.chain, xp[i][:, None], vp[i][:, None], across[i], ap[i][:, None],
                                          float(t)) for i, t in enumerate(times)])
    return xp, vp, ap, forces


def point_forces_rows(chain: Any, times: np.ndarray, x: np.ndarray, v: np.ndarray, a: np.ndarray,
                      across: Sequence[Mapping[int, float] | None]) -> np.ndarray | None:
    """Forces [N] ``(rows, n_points)`` at every point from positions [m], velocities [m/s] and
    accelerations [m/s^2] ``(rows, n_points)`` at ``times`` [s], with ``across[i]`` the actuator forces
    [N] of row ``i`` by element position (acting across a connector, or on a point element).

    Returns ``None`` for a chain with a nonlinear connector law (see the module docstring).
    """
    rows, n = x.shape
    body = chain.body
    times = np.asarray(times, dtype=float)
    coefficients = [e.lumped_coefficients() for e in body]
    if any(c is None for c in coefficients):
        return None
    extra = np.zeros((rows, n))                      # actuator force by element position
    for i, values in enumerate(across):
        for position, value in (values or {}).items():
            extra[i, position] += value
    f = np.full((rows, n), np.nan)
    known = np.zeros(n, dtype=bool)
    for j, c in enumerate(coefficients, start=1):
        if c.connector:
            value = -c.stiffness * (x[:, j] - x[:, j - 1] - c.free_length) - c.damping * (v[:, j] - v[:, j - 1]) \
                + extra[:, j]
            if c.mass:
                value = value - c.mass * (a[:, j] - a[:, j - 1])
            f[:, j - 1] = f[:, j] = value
            known[j - 1] = known[j] = True
    for boundary, point, start in ((chain.start, 0, True), (chain.end, n - 1, False)):
        if not known[point] and boundary.known == "force":
            k, c = getattr(boundary, "stiffness", 0.0), getattr(boundary, "damping", 0.0)
            spring = -k * (x[:, point] - getattr(boundary, "anchor", 0.0)) - c * v[:, point]
            if hasattr(boundary, "force"):
                spring = spring + _values(boundary.force, times)
            f[:, point] = spring if start else -spring
            known[point] = True

    def residual(j: int) -> np.ndarray:             # m a + c v + k x - F of the point element at position j
        c, p = coefficients[j - 1], j - 1
        load = _values(body[j - 1].force, times) + extra[:, j]
        return c.mass * a[:, p] + c.damping * v[:, p] + c.stiffness * x[:, p] - load

    for _ in range(2):                               # forward then backward through runs of point elements
        for j in range(1, n):
            if body[j - 1].is_point and not known[j] and known[j - 1]:
                f[:, j] = f[:, j - 1] - residual(j)
                known[j] = True
        for j in range(n - 1, 0, -1):
            if body[j - 1].is_point and not known[j - 1] and known[j]:
                f[:, j - 1] = f[:, j] + residual(j)
                known[j - 1] = True
    return f


def _values(signal: Any, times: np.ndarray) -> np.ndarray:
    """``signal(t)`` at every time [s] (a constant without a Python call per row)."""
    if isinstance(signal, Constant):
        return np.full(times.shape, float(signal.value))
    return np.array([float(signal(t)) for t in times])
