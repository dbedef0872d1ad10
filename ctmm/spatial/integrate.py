"""Time integration of spatial models (issue 14): classical RK4 and ``scipy.integrate.solve_ivp`` on the
state ``x = [q ; v]`` with ``x_dot = [G(q) v ; v_dot]``, ``v_dot`` from the one articulated sweep.

Quaternions are integrated as coordinates (no Euler angles: no gimbal lock); their norm drifts by the
integrator's local error only and never enters the physics, because every rotation is formed from the
normalised quaternion (:func:`ctmm.spatial.frames.quaternion_rotation`).  Stored quaternions are as
integrated (``model.normalized(q)`` gives unit ones).
"""
from __future__ import annotations

import time as clock
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError, unknown_name
from ..ode import output_grid, rk4_step
from ..results import SimulationResult
from ..signal_results import SignalSystem, signal_result
from .body_forms import SpatialScene
from .dynamics import scene_state_rates
from .model import SpatialModel

__all__ = ["simulate_spatial", "initial_state", "spatial_signals", "state_result", "divergence_check", "beam_deflection_weights",
           "check_beam_deflection", "SCIPY_METHODS"]

SCIPY_METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")
"""``solve_ivp`` methods accepted for spatial models."""


def _initial(model: SpatialModel, label: str, value: Any, names: Sequence[str], start: np.ndarray) -> np.ndarray:
    out = start.copy()
    if value is None:
        return out
    if isinstance(value, Mapping):
        for key, number in value.items():
            if key not in names:
                raise unknown_name(f"entry of {label}", key, list(names))
            out[list(names).index(key)] = validation.finite(f"{label}[{key!r}]", number)
        return out
    array = validation.finite_array(label, value)
    if array.shape != (len(names),):
        raise ModelError(f"{label} must be a mapping {{name: value}} or {len(names)} numbers ({', '.join(names)}), "
                         f"got {value!r:.80} (shape {array.shape})")
    return array.astype(float)


def initial_state(model: SpatialModel, x0: Any = None, v0: Any = None) -> np.ndarray:
    """``[q0 ; v0]`` from ``x0`` (positions: array or ``{coordinate: value}`` over :meth:`SpatialModel.neutral`)
    and ``v0`` (velocities: array or ``{velocity: value}`` over zeros)."""
    q0 = _initial(model, "x0", x0, model.coordinates, model.neutral())
    v = _initial(model, "v0", v0, model.velocities, np.zeros(model.n_velocities))
    try:
        model.check_state(q0, v)
    except ModelError as exc:
        raise ModelError(f"x0 = {q0.tolist()}, v0 = {v.tolist()}: {exc}") from None
    return np.concatenate([q0, v])


def spatial_signals(model: SpatialModel, time: np.ndarray, states: np.ndarray) -> tuple[dict, dict]:
    """Named signals of stored states: every coordinate and velocity, each body's origin
    ``"<body>.position_x|y|z"`` [m] and angular velocity ``"<body>.omega_x|y|z"`` [rad/s] (world axes)."""
    from ..ops import NUMPY

    q, v = states[:, :model.n_positions], states[:, model.n_positions:]
    signals, units = {}, {}
    for k, name in enumerate(model.coordinates):
        signals[name] = q[:, k]
        units[name] = "m" if name.split(".")[-1] in ("x", "y", "z", "position") else \
            ("" if name.split(".")[-1].startswith("q") else "rad")
    for k, name in enumerate(model.velocities):
        signals[name] = v[:, k]
        units[name] = "m/s" if name.split(".")[-1] in ("vx", "vy", "vz", "position_rate") else "rad/s"
    for body, layout in zip(model.bodies, model.modal):           # beams: modal coordinates [m], twist [rad]
        if layout is not None:
            for suffix, unit in zip(body.coordinate_suffixes, body.coordinate_units):
                units[f"{body.name}.{suffix}"], units[f"{body.name}.{suffix}_rate"] = unit, f"{unit}/s"
    scene = SpatialScene(model)
    driven = any(joint.driven for joint in model.joints)        # body poses depend on t only through driven joints
    chunks = [(q[i:i + 1], v[i:i + 1], float(t)) for i, t in enumerate(time)] if driven else [(q, v, 0.0)]
    origins = [[] for _ in model.bodies]
    omegas = [[] for _ in model.bodies]
    for q_rows, v_rows, t in chunks:
        for j, state in enumerate(scene.terms(NUMPY, q_rows, v_rows, t, kinematics_only=True)[2]):
            origins[j].append(np.broadcast_to(state.origin, (len(q_rows), 3, 1)))
            omegas[j].append(np.broadcast_to(state.omega, (len(q_rows), 3, 1)))
    for j, body in enumerate(model.bodies):
        origin, omega = np.concatenate(origins[j]), np.concatenate(omegas[j])
        for axis, label in enumerate("xyz"):
            signals[f"{body.name}.position_{label}"] = origin[:, axis, 0].copy()
            units[f"{body.name}.position_{label}"] = "m"
            signals[f"{body.name}.omega_{label}"] = omega[:, axis, 0].copy()
            units[f"{body.name}.omega_{label}"] = "rad/s"
    return signals, units


def state_result(model: SpatialModel, time: list, states: list, method: str, info: dict) -> SimulationResult:
    """The :class:`SimulationResult` of stored states ``[q ; v]`` at ``time`` [s] (signals of
    :func:`spatial_signals`; also the partial result of a failed run)."""
    time_array, state_array = np.asarray(time), np.asarray(states)
    signals, units = spatial_signals(model, time_array, state_array)
    return signal_result(SignalSystem(model, units), time_array, signals, method, info)


def beam_deflection_weights(model: SpatialModel) -> list[tuple[Any, np.ndarray, np.ndarray]]:
    """Per :class:`~ctmm.spatial.SpatialBeam` of ``model``: ``(beam, indices, weights)``, the state indices of
    its translational modal coordinates (bending ``y``, ``z`` and axial, [m]) and the largest ``|phi_i(x)|``
    of each shape on the beam (sampled at 401 stations), so that ``sum_i weights_i |eta_i|`` bounds the
    deflection [m] (twist [rad] is left out)."""
    index = {name: k for k, name in enumerate(model.coordinates)}
    out = []
    for body in model.bodies:
        if hasattr(body, "check_deformation"):                  # a ctmm.fem.SpatialSubsystem: its own guard
            out.append((body, np.array([index[f"{body.name}.{s}"] for s in body.coordinate_suffixes]), None))
            continue
        data = getattr(body, "data", None)
        if data is None or not hasattr(data, "direction_shapes") or not getattr(body, "n_eta", 0):
            continue
        stations = np.linspace(0.0, body.length, 401)
        suffixes = body.coordinate_suffixes
        weights = np.zeros(len(suffixes))
        for direction, prefix in (("y", "qy"), ("z", "qz"), ("a", "u")):
            columns = [k for k, suffix in enumerate(suffixes) if suffix.startswith(prefix)]
            if columns:
                weights[columns] = np.abs(data.direction_shapes(direction, stations)).max(axis=1)
        indices = np.array([index[f"{body.name}.{suffix}"] for suffix in suffixes])
        out.append((body, indices, weights))
    return out


def check_beam_deflection(model: SpatialModel, beams: list, t: Any, rows: np.ndarray, method: str,
                          partial: Callable[[], Any] | None = None) -> None:
    """Raise :class:`SimulationError` (time, beam, ``partial()``) when a beam's deflection bound
    ``sum_i max|phi_i| |eta_i|`` of a state row exceeds the beam's length: far outside the small-deformation
    model (a diverging run, e.g. a spin-up above the first critical speed without geometric stiffening).
    ``beams`` from :func:`beam_deflection_weights`; ``rows`` (n, size) at times ``t`` (n,) or one state."""
    for beam, indices, weights in beams:
        if weights is None:
            beam.check_deformation(model.name, t, rows[:, indices], method, partial)
            continue
        deflection = np.abs(rows[:, indices]) @ weights
        bad = np.flatnonzero(deflection > beam.length)
        if len(bad):
            row = int(bad[0])
            time = float(np.atleast_1d(t)[row] if np.ndim(t) else t)
            raise SimulationError(
                f"{model.name}: simulation diverged at t = {time:.6g} s ({method}): beam {beam.name!r} deflection "
                f"bound {deflection[row]:.3g} m exceeds its length {beam.length:g} m (far outside the "
                f"small-deformation model; a diverging model, e.g. geometric_stiffening=False above the first "
                f"critical speed, or too large a step)", time=time, element=beam.name,
                partial_result=partial() if partial is not None else None)


def divergence_check(model: SpatialModel, start: np.ndarray, bound: float | None
                     ) -> Callable[..., None]:
    """The run guard of spatial models: the one meaning of ``divergence_bound`` (:func:`ctmm.simulate`).

    Parameters
    ----------
    model : SpatialModel
    start : ndarray, shape (n_positions + n_velocities,)
        The initial state ``[q0 ; v0]``.
    bound : float or None
        Largest allowed distance ``|x_i - start_i|`` of each entry of the state ``x = [q ; v]`` from its
        initial value, in its own unit (coordinates [rad, m, 1], velocities [rad/s, m/s]); ``None``: only
        finiteness is checked.

    Returns
    -------
    callable
        ``check(t, x, method, partial=None)``: ``x`` one state (size,) at time ``t`` [s], or stored states
        (n, size) at times ``t`` (n,) (the first bad row is reported).  Raises :class:`SimulationError`
        (time, the model as element, ``partial()`` as the partial result) on a non-finite entry or one
        beyond the bound, or when a :class:`~ctmm.spatial.SpatialBeam`'s deflection bound exceeds its length
        (:func:`check_beam_deflection`, whatever ``bound``).
    """
    names = list(model.coordinates) + list(model.velocities)
    start = np.array(start, dtype=float).reshape(-1)
    beams = beam_deflection_weights(model)

    def check(t: Any, x: np.ndarray, method: str, partial: Callable[[], Any] | None = None) -> None:
        rows = np.atleast_2d(np.asarray(x, dtype=float))
        distance = np.abs(rows - start)
        finite = np.isfinite(rows)
        if np.all(finite) and (bound is None or float(distance.max(initial=0.0)) <= bound):
            check_beam_deflection(model, beams, t, rows, method, partial)
            return
        bad = ~np.all(finite, axis=1)
        if bound is not None:
            bad |= np.any(np.where(finite, distance, 0.0) > bound, axis=1)
        row = int(np.flatnonzero(bad)[0])
        if row:                                             # a beam that left its range before this row
            check_beam_deflection(model, beams, np.atleast_1d(t)[:row], rows[:row], method, partial)
        time = float(np.atleast_1d(t)[row] if np.ndim(t) else t)
        if not np.all(finite[row]):
            k = int(np.flatnonzero(~finite[row])[0])
            what = f"the state became non-finite in {names[k]!r}"
        else:
            k = int(np.argmax(distance[row]))
            what = f"{names[k]!r} moved {distance[row, k]:.6g} from its start, beyond divergence_bound = {bound}"
        raise SimulationError(f"{model.name}: {what} at t = {time:.6g} s ({method})", time=time, element=model.name,
                              partial_result=partial() if partial is not None else None)
    return check


def simulate_spatial(model: SpatialModel, t_final: float, dt: float | None, *, method: str = "rk4", x0: Any = None,
                     v0: Any = None, inputs: Mapping[str, Any] | None = None, rtol: float = 1e-8,
                     atol: float = 1e-10, max_step: float | None = None, store_every: int = 1,
                     divergence_bound: float | None = None) -> SimulationResult:
    """Simulate a spatial model (the spatial branch of :func:`ctmm.simulate`).

    Parameters
    ----------
    model : SpatialModel
    t_final : float
        End time [s] (start at 0).
    dt : float or None
        RK4 step [s] (``t_final`` a whole multiple); with a ``solve_ivp`` method the output grid (``None``:
        the solver's own steps).
    method : str
        ``"rk4"`` or one of :data:`SCIPY_METHODS`.
    x0, v0 : array or mapping, optional
        Initial coordinates (default :meth:`SpatialModel.neutral`) and velocities (default zero).
    inputs : mapping, optional
        Actuator inputs ``{"<joint>.torque" | ".force" | ".wrench": value or f(t)}``.
    rtol, atol, max_step
        ``solve_ivp`` options.
    store_every : int
        RK4: keep every ``store_every``-th step (and the last).
    divergence_bound : float, optional
        Largest allowed distance of an entry of ``q`` or ``v`` from its initial value (:func:`divergence_check`).

    Returns
    -------
    SimulationResult
        Signals named as in :func:`spatial_signals`; ``info`` with ``dt``, ``wall_time_s``, ``n_evaluations``.

    Raises
    ------
    ModelError
        Bad arguments; SimulationError a non-finite or diverging state (with the partial result).
    """
    if not isinstance(model, SpatialModel):
        raise ModelError(f"model must be a ctmm.spatial.SpatialModel, got {model!r:.80}")
    t_final = validation.positive("t_final", t_final)
    validation.step_budget(t_final, 0.0, dt)           # a tiny dt or huge t_final is refused before any work
    store_every = validation.integer("store_every", store_every, minimum=1)
    if divergence_bound is not None:
        divergence_bound = validation.positive("divergence_bound", divergence_bound)
    if method != "rk4" and method not in SCIPY_METHODS:
        raise ModelError(f"method for a spatial model must be 'rk4' or a solve_ivp method {SCIPY_METHODS}, got "
                         f"{method!r} (DT-TMM schemes: ctmm.spatial.implicit.simulate_spatial_implicit)")
    if inputs is not None and not isinstance(inputs, Mapping):
        raise ModelError(f"inputs must be a mapping {{input name: number or f(t)}}, got {inputs!r}")
    for name in inputs or {}:
        if name not in model.inputs:
            raise unknown_name("spatial input", name, list(model.inputs))
    if model.n_velocities == 0:
        raise ModelError(f"model {model.name!r} has no coordinates (every joint is welded or driven): nothing to "
                         "integrate")
    x = initial_state(model, x0, v0)
    check = divergence_check(model, x, divergence_bound)
    count = [0]
    scene = SpatialScene(model)                         # one scene for the run: its numbers formed once

    def rates(t: float, state: np.ndarray) -> np.ndarray:
        count[0] += 1
        return scene_state_rates(scene, state, t, inputs)

    start = clock.perf_counter()
    if method == "rk4":
        if dt is None:
            raise ModelError("dt is required with method='rk4' (a fixed step [s], > 0), got None")
        dt = validation.positive("dt", dt)
        n = validation.whole_step_count(t_final, dt)
        info = {"dt": dt}
        times, states = [0.0], [x.copy()]
        for step in range(n):
            t = step * dt
            try:
                x = rk4_step(rates, t, x, dt)
            except SimulationError as exc:
                raise SimulationError(f"{exc} (RK4 step from t = {t} s)", time=t, element=exc.element or model.name,
                                      partial_result=state_result(model, times, states, method, info)) from exc
            check(t + dt, x, method, lambda: state_result(model, times, states, method, info))
            if (step + 1) % store_every == 0 or step == n - 1:
                times.append((step + 1) * dt)
                states.append(x.copy())
    else:
        from scipy.integrate import solve_ivp

        for name, value, default in (("store_every", store_every, 1),):
            if value != default:
                raise ModelError(f"{name}={value!r} applies to method='rk4'; give dt as the output grid")
        grid = None
        rtol, atol = validation.positive("rtol", rtol), validation.positive("atol", atol)
        info = {"rtol": rtol, "atol": atol}
        if dt is not None:
            dt = validation.positive("dt", dt)
            grid = output_grid(0.0, t_final, dt)
            info["dt"] = dt
        options = {} if max_step is None else {"max_step": validation.positive("max_step", max_step)}
        try:
            solution = solve_ivp(rates, (0.0, t_final), x, method=method, t_eval=grid, rtol=rtol, atol=atol,
                                 **options)
        except SimulationError as exc:
            raise SimulationError(f"{exc} ({method})", time=exc.time, element=exc.element or model.name) from exc
        times, states = list(solution.t), list(solution.y.T)
        if not solution.success:
            raise SimulationError(f"{model.name}: solve_ivp ({method}) failed: {solution.message}",
                                  time=float(times[-1]) if times else 0.0, element=model.name,
                                  partial_result=state_result(model, times, states, method, info) if times else None)
        try:
            check(np.asarray(times), np.asarray(states), method)
        except SimulationError as exc:                     # the partial result: the stored rows before it
            good = int(np.searchsorted(np.asarray(times), exc.time))
            exc.partial_result = state_result(model, times[:good], states[:good], method, info) if good else None
            raise
    info.update({"method": method, "wall_time_s": clock.perf_counter() - start, "n_evaluations": count[0]})
    return state_result(model, times, states, method, info)
