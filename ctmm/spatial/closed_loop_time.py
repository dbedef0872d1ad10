"""Time integration of spatial kinematic loop models (:class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel`).

The state is the tree's ``x = [q ; v]`` with ``q' = G(q) v`` and ``v'`` the closed-loop accelerations (cut loads as
boundary unknowns, :meth:`SpatialKinematicLoopModel.solve`).  ``"rk4"`` projects onto the cut joints after every
step (and renormalises the quaternions); the ``solve_ivp`` methods hold the drift by Baumgarte alone; the DT-TMM
schemes (:func:`simulate_spatial_loop_scheme`) run the tree's implicit stepper with the cut loads as iterate inputs
and project after every step.  Every
result reports the drift ``max |Phi|`` and ``max |Phi'|`` and the cut loads (``docs/closed_loops.md`` section 8).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from ..loop_integration import StepProjection, check_consistent, integrate_loop_run
from ..ode import output_grid
from ..results import SimulationResult
from ..schemes import Scheme
from .closed_loops import SpatialKinematicLoopModel
from .implicit import simulate_spatial_implicit
from .integrate import divergence_check

__all__ = ["SpatialLoopSimulation", "simulate_spatial_loop_scheme", "simulate_spatial_loops"]


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
        Force [N] and moment [N m] of each cut joint on its child, world axes (a spherical cut's moment: its law's,
        :meth:`SpatialKinematicLoopModel.law_moments`; zero without one).
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
        End time [s] (RK4: a whole multiple of ``dt``, as every fixed-step method).
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
        above :data:`ctmm.loop_integration.PROJECTION_TOLERANCE` after it (time, cut joint, partial result); a
        deformable body of the tree beyond its range (the tree runs' rule,
        :func:`ctmm.spatial.integrate.check_beam_deflection`: a beam's deflection bound beyond its length, a
        finite-element subsystem beyond its size or 1 rad; time, body, partial result), checked after every RK4
        step and at every stored ``solve_ivp`` state.
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

    def finish(y: np.ndarray, t: float) -> np.ndarray:       # without projection (model.project_rows with it)
        return np.concatenate([tree.normalized(y[:nq]), y[nq:]])

    guard = divergence_check(tree, np.concatenate([q, v]), None)      # finite, and the tree's deformable bodies

    def check(t: float, y: np.ndarray) -> None:
        guard(t, y, method)

    grid = None if method == "rk4" or dt is None else output_grid(0.0, t_final, dt)
    return integrate_loop_run(
        lambda t, q_rows, v_rows, wall: _history(model, t, q_rows, v_rows, inputs, method, wall, evaluations[0]),
        rate, np.concatenate([q, v]), nq, t_final=t_final, dt=dt, method=method, finish=finish, rtol=rtol, atol=atol,
        store_every=store_every, t_eval=grid, max_step=max_step, label=f"spatial kinematic loop {model.name!r}",
        element=model.cuts[0].name, velocity_label="v", model=model if projection else None, check=check)


def _history(model: SpatialKinematicLoopModel, t_out: np.ndarray, q: np.ndarray, v: np.ndarray,
             inputs: Mapping[str, Any] | None, method: str, wall: float, evaluations: int) -> SpatialLoopSimulation:
    """The run's stored rows with the cut loads (solved again at each row with ``inputs``) and the drift."""
    forces, moments, drift, drift_rate = [], [], [], []
    for t, q_k, v_k in zip(t_out, q, v):
        t = float(t)
        phi, phi_dot, loads, law = model.stored_row(q_k, v_k, t, inputs)
        drift.append(np.max(np.abs(phi)))
        drift_rate.append(np.max(np.abs(phi_dot)))
        forces.append([f for f, _ in loads])
        moments.append(np.array([m for _, m in loads]) + law)
    return SpatialLoopSimulation(model, np.asarray(t_out), q, v, np.array(forces), np.array(moments), np.array(drift),
                                 np.array(drift_rate), method, wall, evaluations)


def simulate_spatial_loop_scheme(model: SpatialKinematicLoopModel, q0: np.ndarray, v0: np.ndarray, *,
                                 t_final: float, dt: float, scheme: Scheme | str,
                                 inputs: Mapping[str, Any] | None = None, store_every: int = 1,
                                 divergence_bound: float | None = None, projection: bool = True
                                 ) -> tuple[SpatialLoopSimulation, dict]:
    """A DT-TMM scheme on the spanning tree (:func:`ctmm.spatial.implicit.simulate_spatial_implicit`, Lie-group form)
    with the cut loads re-solved at every iterate from the boundary compliance and applied as actuator values
    (:meth:`SpatialKinematicLoopModel.cut_inputs` as its ``input_map``: their state dependence enters the iteration
    matrix), projected onto the cut joints after every step by the RK4's rule
    (:class:`ctmm.loop_integration.StepProjection`).

    Parameters
    ----------
    model : SpatialKinematicLoopModel
    q0, v0 : ndarray
        Tree coordinates and velocities on the cut joints (checked: ``|Phi|``, ``|Phi'| <= 1e-8``).
    t_final, dt : float
        End time and step [s].
    scheme : Scheme or str
        Any :mod:`ctmm.schemes` scheme (``"newmark"``, ``"generalized_alpha"``, ``"houbolt"``, ...).
    inputs : mapping, optional
        The tree's joint actuator inputs ``{"<joint>.torque": number or f(t)}``.
    store_every : int
        Store every k-th step (and the last).
    divergence_bound : float, optional
        As in :func:`ctmm.spatial.implicit.simulate_spatial_implicit`.
    projection : bool
        Project after every step (default); False: Baumgarte alone (the drift grows as the scheme's truncation
        error), for comparison.

    Returns
    -------
    run : SpatialLoopSimulation
    info : dict
        The stepper's (``dt``, ``scheme``, ``iterations``, ...), ``projection`` and, when projecting,
        ``max_drift_before_projection`` [m, rad], ``max_drift_rate_before_projection`` [m/s, rad/s],
        ``max_drift_after_projection`` over every step.

    Raises
    ------
    ModelError
        Bad arguments or an inconsistent initial state.
    ConvergenceError, SimulationError
        As :func:`ctmm.spatial.implicit.simulate_spatial_implicit`; a failed projection (time, cut joint, partial
        result).
    """
    if not isinstance(model, SpatialKinematicLoopModel):
        raise ModelError(f"model must be a SpatialKinematicLoopModel, got {model!r:.80}")
    projection = validation.flag("projection", projection)
    q, v = model.state(q0, v0)
    check_consistent(model, q, v)
    tree = model.tree
    projector = StepProjection(model, f"spatial kinematic loop {model.name!r}") if projection else None
    try:
        run = simulate_spatial_implicit(tree, t_final, validation.positive("dt", dt), scheme=scheme, x0=q, v0=v,
                                        input_map=lambda t, q_at, v_at: model.cut_inputs(q_at, v_at, t, inputs),
                                        store_every=store_every, divergence_bound=divergence_bound, project=projector)
    except SimulationError as exc:      # the tree's partial run, with the cut loads and the drift as a whole run's
        if isinstance(exc.partial_result, SimulationResult):
            exc.partial_result = _tree_history(model, exc.partial_result, inputs)
        raise
    info = dict(run.info)
    history = _tree_history(model, run, inputs)
    info.update(projector.report() if projector is not None else {"projection": False})
    return history, info


def _tree_history(model: SpatialKinematicLoopModel, run: SimulationResult, inputs: Mapping[str, Any] | None
                  ) -> SpatialLoopSimulation:
    """The tree scheme's result as a loop run (:func:`_history`: the cut loads and the drift at its stored rows)."""
    tree = model.tree
    q_out = np.array([run[name] for name in tree.coordinates]).T.reshape(len(run.time), tree.n_positions)
    v_out = np.array([run[name] for name in tree.velocities]).T.reshape(len(run.time), tree.n_velocities)
    return _history(model, run.time, q_out, v_out, inputs, run.scheme_name, float(run.info.get("wall_time_s", 0.0)),
                    int(run.info.get("n_evaluations", 0)))
