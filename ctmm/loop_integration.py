"""The time integrators of kinematic loop models, planar and spatial: fixed-step RK4 with projection onto the cut
joints after every step, or ``solve_ivp`` with Baumgarte stabilisation alone.

The state is ``y = [q ; v]`` (tree coordinates and velocities) with the closed-loop rates ``rate(t, y)``
(:meth:`ctmm.planar.closed_loops.KinematicLoopModel.solve`,
:meth:`ctmm.spatial.closed_loops.SpatialKinematicLoopModel.solve`); ``finish(y, t)`` is applied after every RK4 step
(the projection onto ``Phi = 0``, ``Phi' = 0``, or the renormalisation of quaternions without it).
``docs/closed_loops.md`` sections 2 and 8.
"""
from __future__ import annotations

import time as _time
from typing import Callable

import numpy as np
import scipy.integrate

from . import validation
from .errors import SimulationError
from .ode import rk4_step

__all__ = ["SOLVE_IVP_METHODS", "integrate_loop_model"]

SOLVE_IVP_METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")
"""``solve_ivp`` methods of the loop integrators."""


def integrate_loop_model(rate: Callable[[float, np.ndarray], np.ndarray], y0: np.ndarray, n_positions: int, *,
                         t_final: float, dt: float | None, method: str, finish: Callable[[np.ndarray, float], np.ndarray],
                         rtol: float, atol: float, store_every: int, t_eval: np.ndarray | None,
                         max_step: float | None, label: str, element: str, velocity_label: str
                         ) -> tuple[np.ndarray, np.ndarray, float]:
    """Integrate ``y' = rate(t, y)`` from ``y0`` over ``[0, t_final]`` [s].

    Parameters
    ----------
    rate : callable
        ``(t, y) -> y'``.
    y0 : ndarray
        ``[q ; v]`` on the cut joints.
    n_positions : int
        The length of ``q`` (for the partial result).
    t_final, dt : float
        End time and RK4 step [s] (``solve_ivp``: ``dt`` the default largest step).
    method : str
        ``"rk4"`` or a ``solve_ivp`` method (:data:`SOLVE_IVP_METHODS`).
    finish : callable
        ``(y, t) -> y`` after every RK4 step (projection or renormalisation).
    rtol, atol : float
        ``solve_ivp`` tolerances.
    store_every : int
        Store every k-th RK4 step (and the last).
    t_eval : ndarray, optional
        ``solve_ivp``: the times to store (default: every accepted step).
    max_step : float, optional
        ``solve_ivp``: the largest step [s] (default ``dt``, else no limit).
    label, element : str
        The model (``"kinematic loop 'name'"``) and the cut joint named in errors.
    velocity_label : str
        The key of the velocities in the partial result (``"qdot"`` or ``"v"``).

    Returns
    -------
    t, y : ndarray
        Stored times [s] and states.
    wall_time_s : float

    Raises
    ------
    SimulationError
        A failure of the rates (a singular loop configuration), a non-finite state or a failed ``solve_ivp`` run,
        with the time, the cut joint and the partial result.
    """
    n = n_positions
    start = _time.perf_counter()
    if method == "rk4":
        h = validation.positive("dt", dt)
        steps = max(1, int(round(t_final / h)))
        ts, ys = [0.0], [y0]
        y = y0

        def partial() -> dict:
            stored = np.array(ys)
            return {"t": np.array(ts), "q": stored[:, :n], velocity_label: stored[:, n:]}

        for k in range(1, steps + 1):
            t = (k - 1) * h
            try:
                y = rk4_step(rate, t, y, h)
            except SimulationError as exc:
                raise SimulationError(str(exc), time=t, element=element, partial_result=partial()) from exc
            if not np.all(np.isfinite(y)):
                raise SimulationError(f"{label}: non-finite state at t = {k * h} s", time=k * h, element=element,
                                      partial_result=partial())
            y = finish(y, k * h)
            if k % store_every == 0 or k == steps:
                ts.append(k * h)
                ys.append(y)
        return np.array(ts), np.array(ys), _time.perf_counter() - start
    validation.option("method", method, ("rk4",) + SOLVE_IVP_METHODS)
    limit = max_step if max_step is not None else (np.inf if dt is None else dt)
    sol = scipy.integrate.solve_ivp(rate, (0.0, t_final), y0, method=method, rtol=rtol, atol=atol, t_eval=t_eval,
                                    max_step=limit)
    if not sol.success:
        raise SimulationError(f"{label}: solve_ivp failed: {sol.message}", time=float(sol.t[-1]), element=element)
    return sol.t, sol.y.T, _time.perf_counter() - start
