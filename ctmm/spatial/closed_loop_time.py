"""Time integration of spatial kinematic loop models (:class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel`).

The state is the tree's ``x = [q ; v]`` with ``q' = G(q) v`` and ``v'`` the closed-loop accelerations (cut loads as
boundary unknowns, :meth:`SpatialKinematicLoopModel.solve`).  ``"rk4"`` projects onto the cut joints after every
step (and renormalises the quaternions); the ``solve_ivp`` methods hold the drift by Baumgarte alone.  Every
result reports the drift ``max |Phi|`` and ``max |Phi'|`` and the cut loads (``docs/closed_loops.md`` section 8).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .. import validation
from ..errors import ModelError
from ..loop_integration import check_consistent, integrate_loop_model
from .closed_loops import SpatialKinematicLoopModel

__all__ = ["SpatialLoopSimulation", "simulate_spatial_loops"]


@dataclass(frozen=True)
class SpatialLoopSimulation:
    """Time history of a spatial closed-loop run.

    Attributes
    ----------
    model : SpatialKinematicLoopModel
    t : ndarray (N,)
        Times [s].
    q : ndarray (N, nq)
        Tree coordinates (``model.tree.coordinates``; quaternions unit after every RK4 step).
    v : ndarray (N, nv)
        Tree velocities (``model.tree.velocities``).
    cut_force, cut_moment : ndarray (N, n_cuts, 3)
        Force [N] and moment [N m] of each cut joint on its child, world axes (moment zero for spherical cuts).
    drift, drift_rate : ndarray (N,)
        ``max |Phi|`` (separations [m], alignments [rad]) and ``max |Phi'|`` [m/s, rad/s].
    method : str
    wall_time_s : float
    n_evaluations : int
        Evaluations of the closed-loop accelerations (each one batched sweep of ``1 + m`` load cases).
    """

    model: SpatialKinematicLoopModel
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    cut_force: np.ndarray
    cut_moment: np.ndarray
    drift: np.ndarray
    drift_rate: np.ndarray
    method: str
    wall_time_s: float
    n_evaluations: int


def simulate_spatial_loops(model: SpatialKinematicLoopModel, q0: Any, v0: Any, *, t_final: float,
                           dt: float | None = None, method: str = "rk4", projection: bool = True,
                           inputs: Mapping[str, Any] | None = None, rtol: float = 1e-9, atol: float = 1e-11,
                           store_every: int = 1, max_step: float | None = None) -> SpatialLoopSimulation:
    """Integrate a spatial closed-loop model from a consistent state (:meth:`~SpatialKinematicLoopModel.consistent_state`).

    Parameters
    ----------
    model : SpatialKinematicLoopModel
    q0, v0 : array_like or mapping
        Initial tree coordinates and velocities (checked: ``|Phi|``, ``|Phi'| <= 1e-8``).
    t_final : float
        End time [s].
    dt : float, optional
        Fixed step [s] (required for ``"rk4"``; for ``solve_ivp`` the output grid and largest step).
    method : str
        ``"rk4"`` or a ``solve_ivp`` method (``"RK45"``, ``"DOP853"``, ...; Baumgarte only).
    projection : bool
        Project onto the cut joints after every RK4 step.
    inputs : mapping, optional
        The tree's joint actuator inputs ``{"<joint>.torque": number or f(t)}`` (:func:`ctmm.spatial.dynamics.solve`).
    rtol, atol : float
        ``solve_ivp`` tolerances.
    store_every : int
        Store every k-th RK4 step.
    max_step : float, optional
        ``solve_ivp``: the largest step [s] (default ``dt``, else no limit).

    Raises
    ------
    ModelError
        Bad arguments or an inconsistent initial state.
    SimulationError
        A singular loop configuration, a non-finite state or (RK4 with projection) a failed projection: ``|Phi|``
        above :data:`ctmm.loop_integration.PROJECTION_TOLERANCE` after it (time, cut joint, partial result).
    """
    if not isinstance(model, SpatialKinematicLoopModel):
        raise ModelError(f"model must be a SpatialKinematicLoopModel, got {model!r:.80}")
    t_final = validation.positive("t_final", t_final)
    store_every = validation.integer("store_every", store_every, minimum=1)
    projection = validation.flag("projection", projection)
    q, v = model.state(q0, v0)
    check_consistent(model, q, v)
    nq = len(q)
    tree = model.tree
    evaluations = [0]

    def rate(t: float, y: np.ndarray) -> np.ndarray:
        evaluations[0] += 1
        vdot, _ = model.solve(y[:nq], y[nq:], t, inputs)
        return np.concatenate([tree.position_rates(y[None, :nq], y[None, nq:])[0], vdot])

    def finish(y: np.ndarray, t: float) -> np.ndarray:
        return np.concatenate(model.project(y[:nq], y[nq:], t)) if projection else \
            np.concatenate([tree.normalized(y[:nq]), y[nq:]])

    grid = None if method == "rk4" or dt is None else \
        np.linspace(0.0, t_final, max(1, int(round(t_final / dt))) + 1)
    t_out, y_out, wall = integrate_loop_model(rate, np.concatenate([q, v]), nq, t_final=t_final, dt=dt, method=method,
                                              finish=finish, rtol=rtol, atol=atol, store_every=store_every,
                                              t_eval=grid, max_step=max_step,
                                              label=f"spatial kinematic loop {model.name!r}",
                                              element=model.cuts[0].name, velocity_label="v",
                                              model=model if projection else None)
    forces, moments, drift, drift_rate = [], [], [], []
    for t, y in zip(t_out, y_out):
        phi, phi_dot = model.constraints(y[:nq], y[nq:], t)
        drift.append(np.max(np.abs(phi)))
        drift_rate.append(np.max(np.abs(phi_dot)))
        loads = model.cut_loads(y[:nq], model.solve(y[:nq], y[nq:], t, inputs)[1], t)
        forces.append([f for f, _ in loads])
        moments.append([m for _, m in loads])
    return SpatialLoopSimulation(model, t_out, y_out[:, :nq], y_out[:, nq:], np.array(forces), np.array(moments),
                                 np.array(drift), np.array(drift_rate), method, wall, evaluations[0])
