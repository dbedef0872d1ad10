"""The time integrators of kinematic loop models, planar and spatial: fixed-step RK4 with projection onto the cut
joints after every step, or ``solve_ivp`` with Baumgarte stabilisation alone.

The state is ``y = [q ; v]`` (tree coordinates and velocities) with the closed-loop rates ``rate(t, y)``
(:meth:`ctmm.planar.closed_loops.KinematicLoopModel.solve`,
:meth:`ctmm.spatial.closed_loops.SpatialKinematicLoopModel.solve`); ``finish(y, t)`` is applied after every RK4 step
(the renormalisation of quaternions of a run without projection), or the model's projection onto ``Phi = 0``,
``Phi' = 0`` (``model.project_rows``).
``docs/closed_loops.md`` sections 2, 3d and 8.

The rules every integrator of a kinematic loop model (this RK4, the generated RK4 of
:mod:`ctmm.compiled_kinematic_loops` and :mod:`ctmm.compiled_spatial_kinematic_loops`, the loop driver, the DT-TMM
schemes) applies, stated once here:

* a run starts on the cut joints: ``max |Phi|`` and ``max |Phi'|`` at most :data:`CONSISTENCY_TOLERANCE`
  (:func:`check_consistent`, a :class:`~ctmm.errors.ModelError` otherwise);
* the boundary compliance ``G`` of the cut loads is regular: its condition number (:func:`compliance_condition`) at
  most :data:`CONDITION_LIMIT` (:func:`singular_compliance`: a singular configuration of the loop or redundant cut
  joints), at every evaluation of the closed-loop accelerations;
* the projection after a step lands on the cut joints: ``max |Phi|`` at most :data:`PROJECTION_TOLERANCE` after its
  Gauss-Newton steps (:func:`projection_failure`; a step too large for the loop's curvature).  A run that breaks
  either rule stops with a :class:`~ctmm.errors.SimulationError` naming the time, the cut joint
  (:func:`furthest_cut`) and the partial result;
* a deformable body of the tree stays in its range (the tree runs' rule, given as ``check`` to
  :func:`integrate_loop_model`: a modal beam's deflection bound within its length, a finite-element subsystem within
  its size), after every RK4 step and at every stored ``solve_ivp`` state, with the time, the body and the partial
  result; the generated RK4 by :func:`deformation_failure` on its stored states (the steps in between run again by
  the numpy step).
"""
from __future__ import annotations

import time as _time
from typing import Any, Callable

import numpy as np
import scipy.integrate

from . import validation
from .errors import ModelError, SimulationError
from .ode import rk4_step

__all__ = ["CONDITION_LIMIT", "CONSISTENCY_TOLERANCE", "PROJECTION_SKIP", "PROJECTION_TOLERANCE", "SOLVE_IVP_METHODS",
           "LoopHistory", "ProjectionHook", "StepProjection", "check_consistent", "compliance_condition",
           "deformation_failure", "furthest_cut", "integrate_loop_model", "integrate_loop_run", "projected_residual",
           "projection_failure", "singular_compliance"]

CONSISTENCY_TOLERANCE = 1e-8
"""Largest ``max |Phi|`` [m, rad] and ``max |Phi'|`` [m/s, rad/s] of an initial state on the cut joints."""
PROJECTION_TOLERANCE = 1e-8
"""Largest ``max |Phi|`` [m, rad] after the projection of a step (the bound of a consistent initial state)."""
PROJECTION_SKIP = 1e-14
"""``max |Phi|`` [m, rad] below which the projection's Gauss-Newton steps stop (already on the cut joints)."""
CONDITION_LIMIT = 1e12
"""Largest condition number of the cut joints' boundary compliance ``G`` [-] (:func:`compliance_condition`)."""

ProjectionHook = Callable[[float, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``project(t, q, v) -> (q, v)``: the state of every accepted step of a DT-TMM scheme mapped onto the cut joints
(:class:`StepProjection`; the ``project`` hook of :func:`ctmm.planar.implicit.simulate_implicit` and
:func:`ctmm.spatial.implicit.simulate_spatial_implicit`)."""

SOLVE_IVP_METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")
"""``solve_ivp`` methods of the loop integrators."""

LoopHistory = Callable[[np.ndarray, np.ndarray, np.ndarray, float], Any]
"""``history(t, q, v, wall_time_s) -> run``: a loop model's run from stored times [s], coordinates and velocities
(rows) and the wall time [s] (0 for a failure's partial rows), with its cut loads and drift
(:func:`integrate_loop_run`)."""


def check_consistent(model: Any, q: np.ndarray, v: np.ndarray, names: str = "q0, v0") -> None:
    """Refuse an initial state ``(q, v)`` off the cut joints of ``model`` (planar or spatial kinematic loop model).

    Parameters
    ----------
    model : KinematicLoopModel or SpatialKinematicLoopModel
    q, v : ndarray
        Tree coordinates and velocities.
    names : str
        The arguments they came from, named in the error.

    Raises
    ------
    ModelError
        ``max |Phi|`` or ``max |Phi'|`` above :data:`CONSISTENCY_TOLERANCE` (both named, and the cut furthest off).
    """
    phi, phi_dot = model.constraints(q, v)
    phi, phi_dot = np.abs(np.asarray(phi, float)), np.abs(np.asarray(phi_dot, float))
    worst_phi, worst_rate = np.max(phi, initial=0.0), np.max(phi_dot, initial=0.0)
    if not (worst_phi <= CONSISTENCY_TOLERANCE and worst_rate <= CONSISTENCY_TOLERANCE):
        kind = type(model).__name__
        worst = furthest_cut(model, np.maximum(phi, phi_dot))
        raise ModelError(f"{kind} {model.name!r}: the initial state ({names}) violates the cut joints (|Phi| = "
                         f"{worst_phi:.3e} m or rad, |Phi'| = {worst_rate:.3e} m/s or rad/s, furthest off at the cut "
                         f"{worst!r}; allowed <= {CONSISTENCY_TOLERANCE:g}): start from {kind}.consistent_state")


def furthest_cut(model: Any, rows: np.ndarray) -> str:
    """The name of the cut joint of ``model`` whose rows (stacked as ``model.constraints`` returns them: a spatial
    cut's ``n_rows``, a planar cut's 2, a driven planar cut's 3) hold the largest ``|rows|``."""
    sizes = [getattr(cut, "n_rows", 3 if getattr(cut, "driven", False) else 2) for cut in model.cuts]
    values = np.abs(np.asarray(rows, float))
    if len(values) != sum(sizes) or not np.any(np.isfinite(values)):
        return model.cuts[0].name
    owner = np.repeat(np.arange(len(sizes)), sizes)
    return model.cuts[int(owner[np.nanargmax(values)])].name


def projection_failure(residual: float, iterations: int) -> str:
    """What failed when the projection left ``max |Phi| = residual`` [m, rad] after ``iterations`` Gauss-Newton
    steps (above :data:`PROJECTION_TOLERANCE`)."""
    return (f"the projection onto the cut joints failed (|Phi| = {residual:.3e} after {iterations} Gauss-Newton steps; "
            f"allowed <= {PROJECTION_TOLERANCE:g}: a step too large for the loop, or a singular configuration)")


def compliance_condition(G: np.ndarray) -> float:
    """The condition number ``|G|_F |G^-1|_F`` [-] of the boundary compliance ``G`` checked against
    :data:`CONDITION_LIMIT` (the Frobenius one: the generated step states it on symbols; at most ``m`` times the
    2-norm condition of an ``(m, m)`` ``G``); ``inf`` for a singular ``G`` (``nan`` for a ``G`` with ``nan``
    entries).  The same number as ``numpy.linalg.cond(G, "fro")`` (its inverse and Frobenius norms, without its
    generic checks: it runs at every evaluation of a loop's accelerations)."""
    G = np.asarray(G, dtype=float)
    try:
        with np.errstate(all="ignore"):
            inverse = np.linalg.inv(G)
            condition = float(np.sqrt(np.add.reduce(G * G, axis=(-2, -1)))
                              * np.sqrt(np.add.reduce(inverse * inverse, axis=(-2, -1))))
    except np.linalg.LinAlgError:
        condition = float("nan")
    return float("inf") if np.isnan(condition) and not np.isnan(G).any() else condition


def singular_compliance(condition: float) -> str:
    """What failed when the boundary compliance has the condition number ``condition`` (above
    :data:`CONDITION_LIMIT`, or not finite)."""
    return (f"the cut joints' boundary compliance is singular (condition {condition:.2e} > {CONDITION_LIMIT:g}): "
            "a singular configuration of the loop or redundant cut joints")


def projected_residual(model: Any, q: np.ndarray, v: np.ndarray, t: float, label: str, iterations: int,
                       phi: np.ndarray | None = None) -> tuple[float, SimulationError | None]:
    """``max |Phi|`` [m, rad] of a projected state ``(q, v)`` at ``t`` [s] and, above :data:`PROJECTION_TOLERANCE`,
    the :class:`~ctmm.errors.SimulationError` that stops the run (:func:`projection_failure`, the time, the cut joint
    furthest apart; the caller adds its partial result), else ``None``; ``phi``: ``Phi`` at ``(q, v, t)`` when the
    projection returned it (``model.project_rows``), else evaluated here."""
    phi = np.abs(np.asarray(model.constraints(q, v, t)[0] if phi is None else phi, float))
    residual = float(np.max(phi, initial=0.0))
    if residual <= PROJECTION_TOLERANCE:
        return residual, None
    return residual, SimulationError(f"{label}: {projection_failure(residual, iterations)} at t = {t} s", time=t,
                                     element=furthest_cut(model, phi))


class StepProjection:
    """The projection of a fixed-step run onto the cut joints after every step, checked by the one rule
    (:data:`PROJECTION_TOLERANCE`), with the drift before and after each projection recorded.

    The projection is the model's own (``model.project_rows``: ``model.project`` with ``Phi`` at its result,
    Gauss-Newton on ``Phi(q) = 0`` with the minimum-norm correction along the model's retraction, then
    ``qdot <- qdot - J^+ Phi'``; given the constraints of the state before it, which the drift record evaluates), the
    one the RK4 of :func:`integrate_loop_model` applies; the DT-TMM schemes call it after every accepted step
    (:func:`ctmm.planar.implicit.simulate_implicit`, :func:`ctmm.spatial.implicit.simulate_spatial_implicit`
    ``project=``).

    Parameters
    ----------
    model : KinematicLoopModel or SpatialKinematicLoopModel
    label : str
        The model as named in errors (``"kinematic loop 'name'"``).
    iterations : int
        Gauss-Newton steps of the projection.

    Attributes
    ----------
    drift_before, drift_rate_before : list of float
        ``max |Phi|`` [m, rad] and ``max |Phi'|`` [m/s, rad/s] of each step's state before its projection.
    drift_after : list of float
        ``max |Phi|`` after it (each at most :data:`PROJECTION_TOLERANCE`).
    """

    def __init__(self, model: Any, label: str, iterations: int = 3) -> None:
        self.model, self.label = model, label
        self.iterations = validation.integer("iterations", iterations, minimum=1)
        self.drift_before: list[float] = []
        self.drift_rate_before: list[float] = []
        self.drift_after: list[float] = []

    def __call__(self, t: float, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(q, v)`` at time ``t`` [s] projected onto the cut joints.

        Raises
        ------
        SimulationError
            ``max |Phi|`` above :data:`PROJECTION_TOLERANCE` after the projection (:func:`projection_failure`), with
            the time and the cut joint furthest apart (the stepper adds its partial result).
        """
        q, v = np.asarray(q, float), np.asarray(v, float)
        phi, rate = rows = self.model.constraints(q, v, t)
        self.drift_before.append(float(np.max(np.abs(phi), initial=0.0)))
        self.drift_rate_before.append(float(np.max(np.abs(rate), initial=0.0)))
        q, v, phi = self.model.project_rows(q, v, t, self.iterations, rows)
        after, failure = projected_residual(self.model, q, v, t, self.label, self.iterations, phi)
        if failure is not None:
            raise failure
        self.drift_after.append(after)
        return q, v

    def report(self) -> dict[str, float | bool]:
        """The run's ``info`` entries: ``projection`` (True), ``max_drift_before_projection`` [m, rad],
        ``max_drift_rate_before_projection`` [m/s, rad/s] and ``max_drift_after_projection`` over every step."""
        return {"projection": True,
                "max_drift_before_projection": max(self.drift_before, default=0.0),
                "max_drift_rate_before_projection": max(self.drift_rate_before, default=0.0),
                "max_drift_after_projection": max(self.drift_after, default=0.0)}


def integrate_loop_model(rate: Callable[[float, np.ndarray], np.ndarray], y0: np.ndarray, n_positions: int, *,
                         t_final: float, dt: float | None, method: str, finish: Callable[[np.ndarray, float], np.ndarray],
                         rtol: float, atol: float, store_every: int, t_eval: np.ndarray | None,
                         max_step: float | None, label: str, element: str, velocity_label: str,
                         model: Any = None, iterations: int = 3,
                         check: Callable[[float, np.ndarray], None] | None = None
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
        End time and RK4 step [s] (RK4: ``t_final`` a whole multiple of ``dt``; ``solve_ivp``: ``dt`` the default
        largest step).
    method : str
        ``"rk4"`` or a ``solve_ivp`` method (:data:`SOLVE_IVP_METHODS`).
    finish : callable
        ``(y, t) -> y`` after every RK4 step of a run without projection (``model`` not given: the identity, or the
        renormalisation of quaternions).
    model : KinematicLoopModel or SpatialKinematicLoopModel, optional
        Given when the run projects: after every RK4 step its ``project_rows(q, v, t, iterations)`` (the projection
        with ``Phi`` at its result), whose ``Phi`` must be within :data:`PROJECTION_TOLERANCE`
        (:func:`projection_failure` otherwise).
    iterations : int
        The Gauss-Newton steps of the projection (named in the error).
    check : callable, optional
        ``check(t, y)``: the tree's own run guards (a deformable body's range: a modal beam's deflection bound
        beyond its length, a finite-element subsystem's displacement beyond its size), raising
        :class:`SimulationError`; applied after every RK4 step (after the projection, before its residual is
        checked: a body beyond its range is the cause of a projection that then fails) and, with ``solve_ivp``, to
        every stored state.  The error gets the partial result up to the last good stored state.
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
        A failure of the rates (a singular loop configuration), a non-finite state, a failed projection (RK4 with
        ``model``) or a failed ``solve_ivp`` run, with the time, the cut joint and the partial result up to the last
        good stored state; a failed ``check`` with its own time and element and that partial result.
    """
    n = n_positions
    start = _time.perf_counter()
    if method == "rk4":
        h = validation.positive("dt", dt)
        steps = validation.whole_step_count(validation.positive("t_final", t_final), h)
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
            if model is None:
                y = finish(y, k * h)
            else:                       # the projection, with Phi at its result for the residual check
                q, v, phi = model.project_rows(y[:n], y[n:], k * h, iterations)
                y = np.concatenate([q, v])
            if check is not None:       # a body beyond its range first: the cause of a projection that then fails
                _checked(check, k * h, y, partial)
            if model is not None:
                _, failure = projected_residual(model, y[:n], y[n:], k * h, label, iterations, phi)
                if failure is not None:
                    raise SimulationError(f"{failure} (after t = {ts[-1]} s, the last good stored state)",
                                          time=failure.time, element=failure.element, partial_result=partial())
            if k % store_every == 0 or k == steps:
                ts.append(k * h)
                ys.append(y)
        return np.array(ts), np.array(ys), _time.perf_counter() - start
    validation.option("method", method, ("rk4",) + SOLVE_IVP_METHODS)
    limit = max_step if max_step is not None else (np.inf if dt is None else dt)
    sol = scipy.integrate.solve_ivp(rate, (0.0, t_final), y0, method=method, rtol=rtol, atol=atol, t_eval=t_eval,
                                    max_step=limit)
    if check is not None:
        for row in range(1, len(sol.t)):
            _checked(check, float(sol.t[row]), sol.y[:, row], lambda row=row: {
                "t": sol.t[:row], "q": sol.y[:n, :row].T, velocity_label: sol.y[n:, :row].T})
    if not sol.success:
        raise SimulationError(f"{label}: solve_ivp failed: {sol.message}", time=float(sol.t[-1]), element=element)
    return sol.t, sol.y.T, _time.perf_counter() - start


def integrate_loop_run(history: LoopHistory, rate: Callable[[float, np.ndarray], np.ndarray], y0: np.ndarray,
                       n_positions: int, **integration: Any) -> Any:
    """:func:`integrate_loop_model` (``integration``: its keyword arguments) with its stored rows made the model's run
    by ``history`` (:data:`LoopHistory`), and so the partial rows of a failure: its :class:`SimulationError`
    (message, time and element unchanged) carries ``history`` of the rows before it (wall time 0) as its partial
    result.

    Returns
    -------
    run
        ``history(t, q, v, wall_time_s)`` of the stored rows.
    """
    try:
        t, y, wall = integrate_loop_model(rate, y0, n_positions, **integration)
    except SimulationError as exc:      # the stored rows before the failure, with the cut loads and the drift
        if isinstance(exc.partial_result, dict):
            rows = exc.partial_result
            exc.partial_result = history(rows["t"], rows["q"], rows[integration["velocity_label"]], 0.0)
        raise
    return history(t, y[:, :n_positions], y[:, n_positions:], wall)


def _checked(check: Callable[[float, np.ndarray], None], t: float, y: np.ndarray, partial: Callable[[], dict]
             ) -> None:
    """``check(t, y)``; its :class:`SimulationError` completed with ``partial()`` when it carries no partial result."""
    try:
        check(t, y)
    except SimulationError as exc:
        if exc.partial_result is None:
            exc.partial_result = partial()
        raise


def deformation_failure(model: Any, t: np.ndarray, states: np.ndarray, bad: int | None, dt: float, size: int,
                        beyond: Any, step: Any) -> tuple[int, SimulationError] | None:
    """The tree runs' deformable-body rule on a generated run of a kinematic loop model.

    Stored times ``t`` [s], states ``[x, ...]`` with ``x = [q ; v]`` of ``size``, ``bad`` the row
    :func:`ctmm.compiled_kinematic_loops.first_failure` found.  Returns ``(row, error)`` when a step before the
    generated failure (or, without one, any step) puts a body beyond its range: the error that of the numpy RK4 at
    that step (``beyond(x, t)``: the error or ``None``), ``row`` the first stored row after it; ``None`` otherwise
    (none beyond its range, or the generated failure comes first).  The first stored row beyond the rule, or
    ``bad``, is found on the stored states; the steps since the stored row before it are run again by the numpy
    RK4 step with projection (``step(x, k)``: step ``k`` from ``x`` after step ``k - 1``, ``None`` when not
    finite; generated = numpy to round-off) and checked in the numpy RK4's order (finite, the body, the projection
    residual).
    """
    for row in range(1, len(t) if bad is None else bad + 1):
        if row == bad or beyond(states[row, :size], float(t[row])) is not None:
            break
    else:
        return None
    x = states[row - 1, :size]
    for k in range(int(round(t[row - 1] / dt)) + 1, int(round(t[row] / dt)) + 1):
        try:
            x = step(x, k)
        except SimulationError:
            return None                                 # a singular configuration: the generated failure's
        if x is None:
            return None                                 # non-finite before the projection: the generated failure's
        error = beyond(x, k * dt)
        if error is not None:
            return row, error
        nq = size - model.n_velocities
        if np.max(np.abs(model.constraints(x[:nq], x[nq:], k * dt)[0]), initial=0.0) > PROJECTION_TOLERANCE:
            return None
    return None
