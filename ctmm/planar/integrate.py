"""Explicit time integration of planar models driven by the acceleration TMM.

The acceleration-based TMM (:mod:`ctmm.planar.sweep`) turns any planar model into an ODE
``y' = f(t, y)`` with ``y = [q, qdot]``; this module integrates it with a fixed-step classical
Runge-Kutta scheme (:func:`ctmm.ode.integrate_rk4`, 4th order) or with any ``scipy.integrate.solve_ivp``
method (RK45, DOP853, Radau, BDF, LSODA).  Results are :class:`PlanarSimulation` objects with
named coordinates.  Initial states given by coordinate name become arrays by :func:`coordinate_values`
(for :func:`ctmm.simulate`, :func:`ctmm.simulate_batch` and the kinematic-loop verbs alike).

The per-step work of a fixed-step run (guards, storing, progress) is :func:`run_fixed_step` and
the guards of one state :func:`check_state`, for every planar run: :func:`simulate_rk4` here, and
meant for the loops of :func:`ctmm.simulate` (``ctmm.control.planar_time``) too, so that there is
one RK4 driver.  :func:`simulate_rk4` and :func:`simulate_scipy` are the older entry points (a
:class:`PlanarSimulation`); :func:`ctmm.simulate` is the one verb (a
:class:`~ctmm.results.SimulationResult`, same numbers).
"""
from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
import scipy.integrate

from .. import validation
from ..capabilities import require_planar
from ..errors import ModelError, SimulationError, unknown_name
from ..ode import integrate_rk4, second_order_rate
from ..progress import progress_bar
from .guards import check_scheme, divergence_guard, with_partial
from .model import PlanarModel
from .sweep import accelerations

SCIPY_METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")


@dataclass(frozen=True)
class PlanarSimulation:
    """Time history of a planar model.

    Attributes
    ----------
    model : PlanarModel
    t : ndarray, shape (n_steps + 1,)
        Times [s].
    q, qdot : ndarray, shape (n_steps + 1, n_coordinates)
        Coordinates and their rates (columns named by ``model.coordinates``).
    method : str
        Integrator used.
    wall_time_s : float
        Wall-clock time of the integration [s].
    iterations : ndarray or None
        Newton iterations per step (implicit DT-TMM only).
    n_evaluations : int
        Number of forward-dynamics (sweep) evaluations.
    """

    model: PlanarModel
    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    method: str
    wall_time_s: float
    iterations: np.ndarray | None = None
    n_evaluations: int = 0
    extra: dict = field(default_factory=dict)

    def coordinate(self, name: str) -> np.ndarray:
        """History of coordinate ``name`` (``"link2.theta"``); ``name + "_dot"`` for its rate."""
        if name.endswith("_dot"):
            return self.qdot[:, self.model.coordinate_index(name[:-4])]
        return self.q[:, self.model.coordinate_index(name)]

    def energy(self) -> np.ndarray:
        """Total mechanical energy [J] at every stored time (see :meth:`PlanarModel.energy`)."""
        return np.array([self.model.energy(q, v, t) for t, q, v in zip(self.t, self.q, self.qdot)])

    def plot(self, names: Sequence[str] | None = None, ax=None):
        """Plot coordinates against time; returns the axes."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots()
        for name in names or self.model.coordinates[:6]:
            ax.plot(self.t, self.coordinate(name), label=name)
        ax.set_xlabel("t [s]")
        ax.legend(fontsize="small")
        return ax


def coordinate_values(model: PlanarModel, label: str, value: Any) -> np.ndarray:
    """Coordinates [m, rad, modal] or their rates of a planar model as one float array.

    Parameters
    ----------
    model : PlanarModel
        The model whose :attr:`~PlanarModel.coordinates` name and order the values.
    label : str
        The argument's name in messages (``"x0"``, ``"v0"``, ``"operating_point"``).
    value : None, mapping or array_like
        ``None`` (all 0), ``{coordinate name: value}`` (the others 0) or ``n_coordinates`` numbers in
        the order of ``model.coordinates``.

    Raises
    ------
    ModelError
        An unknown coordinate name (the available ones listed), a value that is not a finite number,
        an array of another length.
    """
    n = model.n_coordinates
    if value is None:
        return np.zeros(n)
    if isinstance(value, Mapping):
        out = np.zeros(n)
        for key, number in value.items():
            if key not in model.coordinates:
                raise unknown_name(f"coordinate of {label}", key, list(model.coordinates))
            out[model.coordinate_index(key)] = validation.finite(f"{label}[{key!r}]", number)
        return out
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        array = None
    if array is None or array.shape != (n,):
        raise ModelError(f"{label} must be a mapping {{coordinate: value}} or an array of length {n} "
                         f"(coordinates {', '.join(model.coordinates)}), got {value!r}")
    if not np.all(np.isfinite(array)):
        raise ModelError(f"{label} must be finite, got {value!r}")
    return array


def initial_coordinates(model: PlanarModel, q0, qdot0) -> tuple[np.ndarray, np.ndarray]:
    """``q0, qdot0`` [m, rad, modal] checked against the model's coordinates, as float arrays."""
    require_planar(model, "ctmm.planar simulation")
    n = model.n_coordinates
    given = (q0, qdot0)
    q0 = validation.finite_array("q0", q0, ndim=1)
    qdot0 = validation.finite_array("qdot0", qdot0, ndim=1)
    if q0.shape != (n,) or qdot0.shape != (n,):
        raise ModelError(f"q0 and qdot0 must have shape ({n},) for coordinates "
                         f"{model.coordinates}, got q0={given[0]!r} and qdot0={given[1]!r}")
    return q0.astype(float), qdot0.astype(float)


def step_total(t_final: float, dt: float) -> int:
    """Number of steps ``t_final / dt`` (a whole number >= 1, within the shared step budget)."""
    t_final = validation.positive("t_final", t_final)
    dt = validation.positive("dt", dt)
    validation.step_count(t_final, 0.0, dt)
    return validation.whole_step_count(t_final, dt)


def check_store_every(store_every: int) -> int:
    """``store_every`` as an int ``>= 1`` (keep every ``store_every``-th step), else :class:`ModelError`."""
    if isinstance(store_every, bool) or not isinstance(store_every, (int, np.integer)) or store_every < 1:
        raise ModelError(f"store_every must be an integer >= 1, got {store_every!r}")
    return int(store_every)


def simulate_rk4(model: PlanarModel, q0, qdot0, *, t_final: float, dt: float,
                 store_every: int = 1, divergence_bound: float | None = None,
                 stability_check: str = "warn") -> PlanarSimulation:
    """Classical 4th-order Runge-Kutta with fixed step ``dt`` [s] on the TMM accelerations.

    Parameters
    ----------
    model : PlanarModel
    q0, qdot0 : array_like
        Initial coordinates and rates (one value per ``model.coordinates``).
    t_final : float
        End time [s], a whole multiple of ``dt``.
    dt : float
        Step [s].
    store_every : int
        Keep every ``store_every``-th step (the last step is always kept), >= 1.
    divergence_bound : float, optional
        Largest allowed distance of any coordinate from its initial value (its own unit, m or
        rad); default ``1e6 * max(1, max |q0|)``; ``math.inf`` checks only finiteness.
    stability_check : {"warn", "error", "ignore"}
        Before the run, compare ``omega_max dt`` with RK4's limit ``2 sqrt 2`` (``omega_max``
        of the linearisation about the initial state): warn
        (:class:`~ctmm.guard.StabilityLimitWarning`), raise :class:`~ctmm.errors.ModelError`,
        or skip.

    Raises
    ------
    SimulationError
        A coordinate goes non-finite or beyond the bound, or a user signal (load, hinge law,
        driven motion) raises or returns a non-finite value: names the coordinate or element
        and the time; ``partial_result`` is the :class:`PlanarSimulation` stored so far.
    """
    store_every = validation.integer("store_every", store_every, minimum=1)
    q, v = initial_coordinates(model, q0, qdot0)
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps
    guard = divergence_guard(model, q, divergence_bound)
    check_scheme(model, q, v, h, scheme="rk4", policy=stability_check)
    ts, ys = [0.0], [np.concatenate((q, v))]
    start = _time.perf_counter()
    n = model.n_coordinates

    def result(n_evaluations: int = 0) -> PlanarSimulation:
        y = np.array(ys).reshape(-1, 2 * n)
        return PlanarSimulation(model, np.array(ts), y[:, :n].copy(), y[:, n:].copy(), "rk4",
                                _time.perf_counter() - start, n_evaluations=n_evaluations)

    def record(t: float, y: np.ndarray) -> None:
        ts.append(t)
        ys.append(y)

    rate = second_order_rate(lambda q, v, t: accelerations(model, q, v, t), n)
    try:
        run_fixed_step(rate, ys[0], h=h, n_steps=n_steps, store_every=store_every, record=record,
                       check=lambda t, y: check_state(model, guard, t, y, h, "rk4"))
    except SimulationError as exc:
        raise with_partial(exc, result) from exc.__cause__
    return result(4 * n_steps)


def check_state(model: PlanarModel, guard, t: float, y: np.ndarray, step: float | None, method: str) -> None:
    """The guards of a planar run at one accepted state ``y = [q, qdot, ...]`` at ``t`` [s].

    ``guard`` (:func:`~ctmm.planar.guards.divergence_guard`) checks the coordinates against the
    divergence bound and for finiteness, :func:`guard_rates` the rates, and a deformable family
    (flexible beams) its own divergence with the fixed step ``step`` [s] (``None``: adaptive) of
    ``method``.  Raises :class:`SimulationError` naming the coordinate or element and the time.
    """
    n = model.n_coordinates
    guard.check(t, y[:n])
    guard_rates(model, t, y[n:2 * n])
    family = model.deformable_family
    if family is not None:
        family.check_divergence(model, y[:n], float(t), step, method)


def run_fixed_step(rate: Callable[[float, np.ndarray], np.ndarray], y0: np.ndarray, *, h: float, n_steps: int,
                   store_every: int, check: Callable[[float, np.ndarray], None],
                   record: Callable[[float, np.ndarray], None],
                   on_step: Callable[[int, float, np.ndarray], None] | None = None,
                   progress: bool | None = False, description: str = "planar rk4") -> None:
    """The fixed-step RK4 driver of planar runs: ``n_steps`` steps of ``y' = rate(t, y)`` from
    ``y(0) = y0`` (:func:`ctmm.ode.integrate_rk4`), and after every step ``k`` at time ``t`` [s]:
    ``check(t, y)`` (guards; raise to stop), ``on_step(k, t, y)`` (e.g. sample controllers,
    extend a delay history), ``record(t, y)`` every ``store_every``-th step and at the last one,
    then the progress bar (``progress``: ``None`` shows it for long runs on a terminal).
    """
    bar = progress_bar(n_steps, description, enabled=progress)

    def after_step(k: int, t: float, y: np.ndarray) -> None:
        check(t, y)
        if on_step is not None:
            on_step(k, t, y)
        if k % store_every == 0 or k == n_steps:
            record(t, y)
        bar.update()

    try:
        integrate_rk4(rate, y0, h=h, n_steps=n_steps, after_step=after_step)
    finally:
        bar.close()


def guard_rates(model: PlanarModel, t: float, qdot: np.ndarray) -> None:
    """Raise :class:`SimulationError` naming the first non-finite rate ``qdot`` at ``t`` [s]."""
    if not np.isfinite(qdot).all():
        name = model.coordinates[int(np.flatnonzero(~np.isfinite(qdot))[0])]
        raise SimulationError(f"non-finite rate at t = {t:.6g} s in {name + '_dot'!r}", time=float(t),
                              element=name)


def accepted_steps(solver, method: str):
    """Step a ``scipy.integrate`` solver object to its end, yielding the start time [s] of every
    accepted step (the solver then holds the step's end); a failed step raises
    :class:`SimulationError` with the time and the solver's message."""
    while solver.status == "running":
        t_old = solver.t
        message = solver.step()
        if solver.status == "failed":
            raise SimulationError(f"scipy {method} failed at t = {solver.t:.6g} s: {message}", time=float(solver.t))
        yield t_old


def simulate_scipy(model: PlanarModel, q0, qdot0, *, t_final: float, method: str = "RK45",
                   rtol: float = 1e-8, atol: float = 1e-10, t_eval=None,
                   divergence_bound: float | None = None) -> PlanarSimulation:
    """Integrate with a ``scipy.integrate`` solver (``method`` in :data:`SCIPY_METHODS`).

    The solver is stepped here (the loop of ``solve_ivp``) so that every accepted step is
    checked: ``divergence_bound`` as in :func:`simulate_rk4` (adaptive steps control their own
    stability).  Without ``t_eval`` every accepted step is stored, with it the dense output at
    those times [s].  Implicit methods (Radau, BDF, LSODA) build their Jacobian by finite
    differences of the TMM right-hand side (``2 n`` sweeps per Jacobian).

    Raises
    ------
    SimulationError
        Divergence, a solver failure or a failing user signal, with the time, the coordinate or
        element, and ``partial_result`` (the :class:`PlanarSimulation` up to the last good step).
    """
    if method not in SCIPY_METHODS:
        raise ModelError(f"method must be one of {SCIPY_METHODS}, got {method!r}")
    t_final = validation.positive("t_final", t_final)
    rtol, atol = validation.positive("rtol", rtol), validation.positive("atol", atol)
    if t_eval is not None:
        given = t_eval
        t_eval = validation.finite_array("t_eval", t_eval, ndim=1)
        if t_eval.size == 0 or t_eval.min() < 0.0 or t_eval.max() > t_final or np.any(np.diff(t_eval) < 0):
            raise ModelError(f"t_eval must be ascending times in [0, t_final={t_final!r}] s, got {given!r}")
    q, v = initial_coordinates(model, q0, qdot0)
    t_final = validation.positive("t_final", t_final)
    if t_eval is not None:
        t_eval = validation.finite_array("t_eval", t_eval, ndim=1)
        if np.any(np.diff(t_eval) <= 0) or t_eval.size and (t_eval[0] < 0 or t_eval[-1] > t_final):
            raise ModelError(f"t_eval must be increasing times within [0, t_final = {t_final:g}] s, got "
                             f"{t_eval.size} value(s) from {t_eval.min(initial=np.nan):g} to "
                             f"{t_eval.max(initial=np.nan):g}")
    n = model.n_coordinates
    count = [0]
    guard = divergence_guard(model, q, divergence_bound)

    def rhs(t, y):
        count[0] += 1
        return np.concatenate([y[n:], accelerations(model, y[:n], y[n:], t)])

    y0 = np.concatenate([q, v])
    ts: list[float] = []
    ys: list[np.ndarray] = []
    if t_eval is None or (t_eval.size and t_eval[0] == 0.0):
        ts.append(0.0)
        ys.append(y0)
    start = _time.perf_counter()

    def result() -> PlanarSimulation:
        y = np.array(ys).reshape(-1, 2 * n)
        return PlanarSimulation(model, np.array(ts), y[:, :n].copy(), y[:, n:].copy(), method,
                                _time.perf_counter() - start, n_evaluations=count[0])

    solver_type = getattr(scipy.integrate, method)
    try:
        solver = solver_type(rhs, 0.0, y0, t_final, rtol=rtol, atol=atol)
        for t_old in accepted_steps(solver, method):
            check_state(model, guard, solver.t, solver.y, None, method)
            if t_eval is None:
                ts.append(float(solver.t))
                ys.append(solver.y.copy())
            else:
                inside = t_eval[(t_eval > t_old) & (t_eval <= solver.t)]
                if inside.size:
                    dense = solver.dense_output()
                    ts.extend(inside.tolist())
                    ys.extend(np.atleast_2d(dense(inside).T))
    except SimulationError as exc:
        raise with_partial(exc, result) from exc.__cause__
    return result()


def model_signals(model: PlanarModel, t: np.ndarray, q: np.ndarray, qdot: np.ndarray,
                  outputs: Sequence[str] = ()) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Named signals of a planar history and their units.

    Parameters
    ----------
    model : PlanarModel
    t : ndarray, shape (n_rows,)
        Times [s].
    q, qdot : ndarray, shape (n_rows, n_coordinates)
        Coordinates and rates.
    outputs : sequence of str
        Sensor names of :mod:`ctmm.planar.ports` to add (``"fore.outboard.y"``, ``"motor.angle"``).

    Returns
    -------
    signals, units : dict
        ``"<coordinate>"`` and ``"<coordinate>_dot"`` for every coordinate, plus the outputs,
        one value per row; ``{name: unit}`` from :func:`ctmm.planar.ports.sensor_unit`.
    """
    from .ports import PlanarPorts

    ports = PlanarPorts(model)
    signals: dict[str, np.ndarray] = {}
    for k, name in enumerate(model.coordinates):
        signals[name] = np.asarray(q[:, k], dtype=float).copy() if len(q) else np.zeros(0)
        signals[name + "_dot"] = np.asarray(qdot[:, k], dtype=float).copy() if len(qdot) else np.zeros(0)
    outputs = list(dict.fromkeys(outputs))
    if outputs:
        sensors = ports.resolve(outputs)
        values = np.array([ports.values(sensors, np.asarray(qk, dtype=float), np.asarray(vk, dtype=float), float(tk))
                           for tk, qk, vk in zip(t, q, qdot)])
        values = values.reshape(len(t), len(outputs))
        for k, name in enumerate(outputs):
            signals[name] = values[:, k]
    units = {name: ports.sensor_unit(name) for name in signals}
    return signals, units


def to_result(simulation: PlanarSimulation, *, outputs: Sequence[str] = (), info: dict | None = None):
    """The :class:`~ctmm.results.SimulationResult` of a :class:`PlanarSimulation` (named signals).

    Parameters
    ----------
    simulation : PlanarSimulation
    outputs : sequence of str
        Sensor names (:mod:`ctmm.planar.ports`) evaluated at every stored time.
    info : dict, optional
        Provenance added to the result's ``info``.
    """
    from ..signal_results import SignalSystem, signal_result

    sim = simulation
    signals, units = model_signals(sim.model, sim.t, sim.q, sim.qdot, outputs)
    details = {"method": sim.method, "wall_time_s": float(sim.wall_time_s),
               "n_evaluations": int(sim.n_evaluations)}
    if sim.iterations is not None and len(sim.iterations):
        details["newton_iterations_mean"] = float(np.mean(sim.iterations))
        details["newton_iterations_max"] = int(np.max(sim.iterations))
    details.update(info or {})
    return signal_result(SignalSystem(sim.model, units), sim.t, signals, sim.method, details)


__all__ = ["PlanarSimulation", "simulate_rk4", "simulate_scipy", "guard_rates", "accepted_steps", "check_state",
           "run_fixed_step",
           "check_store_every", "SCIPY_METHODS", "model_signals", "to_result", "coordinate_values"]
