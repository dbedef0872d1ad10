"""Planar, flexible and spatial models in time with feedback loops, co-simulated controllers and inputs.

:func:`simulate_closed_loop` integrates a :class:`~ctmm.planar.model.PlanarModel` (rigid or with
flexible beams) or a :class:`~ctmm.spatial.model.SpatialModel` -- any model with a
:class:`~ctmm.control.plants.Plant` (its ports and a few dynamics) -- whose named actuators
(:mod:`ctmm.planar.ports`, :mod:`ctmm.spatial.ports`) are driven by

* open-loop ``inputs`` ``{actuator name: number or f(t)}``;
* embedded :class:`~ctmm.control.loops.Feedback` loops ``u = -C (y(t - tau) - r(t - tau))``
  with ``y`` a weighted sum of named sensors: a **real-time** loop (``tau = 0``) is evaluated at
  the current state at every stage of the integrator; a **delayed** loop reads the one delay
  history (:class:`~ctmm.control.history.DelayHistory`, cubic Hermite from the sensed values
  and their time derivatives at every step; before the start the initial state held); an LTI
  controller ``C(s)`` (proper, SISO) has its states integrated with the plant (an improper
  ``C(s)`` such as ``kp + kd s`` is refused: write it as sensor terms);
* a loop with ``saturation=(low, high)`` applies ``u`` clipped to its limits at every evaluation
  (:func:`ctmm.saturation.clip`; an LTI controller's states integrate the unclipped error, no
  anti-windup); the result adds ``"<loop>.u_demand"`` (the unclipped ``-C e``), ``"<loop>.saturated"``
  (1 where the demand is beyond a limit) and ``info["time_saturated_s"]`` (seconds at a limit,
  summed over the stored rows);
* co-simulated controllers (Python objects, FMUs) through the one co-simulation master
  (:class:`~ctmm.control.cosim.CoSimulation`): sampled on the step grid, outputs held
  (zero-order hold) -- the integrator restarts at every sample; a controller wrapped in
  :class:`~ctmm.control.measurement_delay.DelayedController` reads its inputs ``delay`` seconds
  late from the same delay history.

Methods: fixed-step ``"rk4"`` (:func:`ctmm.ode.integrate_rk4`), a ``scipy.integrate``
solver (``"RK45"``, ``"DOP853"``, ``"Radau"``, ...; stepped here, every accepted step checked;
``max_step`` at most the shortest loop delay) -- both in :mod:`ctmm.control.explicit_loops`, which projects a
kinematic loop plant onto its cut joints after every RK4 step and at every controller sample of ``solve_ivp`` --,
or an implicit DT-TMM scheme of :mod:`ctmm.schemes` (:mod:`ctmm.control.implicit_loops`: one
:func:`~ctmm.planar.implicit.simulate_implicit` run): loops, inputs and
held controller outputs enter through its ``inputs`` hook, evaluated at every Newton iterate
(a real-time loop is implicit in the step, its state dependence in the Newton tangent), and its
per-step callback samples the controllers and appends to the delay history; a step after a
sample starts from the acceleration with the new held outputs; the states of an LTI controller
advance by the trapezoidal rule from the step start to the iterate's time (implicit in the
step, second order).  A loop delay must be 0 or at least one step (``theta dt`` with
Wilson-theta, whose equations are imposed at ``t_n + theta dt``), on planar and spatial plants
(``docs/spatial.md`` §6d).  The plant's guards apply (planar: those of
:mod:`ctmm.planar.guards`, step limit of the plant before the run; every plant: divergence bound,
non-finite states) and a failed run raises :class:`~ctmm.errors.SimulationError` with the result up
to the last good step.

The state is ``y = [q, v, controller states]`` with ``q_dot = G(q) v`` (planar: ``v = q_dot``;
spatial: quaternion rates from child-axes angular velocities), so the same code closes the loops
on both plants.  The stored rows and their result (loop signals and units, saturation, controller samples):
:mod:`ctmm.control.loop_rows`.
"""
from __future__ import annotations

import math
import time as _time
import warnings
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from .. import validation
from ..controller_state_space import controller_state_space
from ..errors import ModelError, SimulationError, unknown_name
from ..planar.guards import with_partial
from ..planar.integrate import SCIPY_METHODS
from ..planar.signals import signal_values
from ..results import SimulationResult
from ..schemes import SCHEMES, Scheme, as_scheme
from ..signals import as_signal
from .cosim import CoSimulation
from .explicit_loops import run_rk4, run_scipy
from .history import DelayHistory
from .implicit_loops import check_scheme_delays, run_implicit
from .loop_rows import LoopRows, empty_result, rows_result
from .plants import Plant, plant_of

__all__ = ["controller_realisation", "simulate_closed_loop"]


@dataclass(frozen=True)
class _Loop:
    """A :class:`Feedback` resolved on a planar model."""

    loop: Any
    sensors: tuple[str, ...]
    weights: np.ndarray
    actuators: tuple[tuple[str, float], ...]
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: float
    states: slice

    @property
    def name(self) -> str:
        return self.loop.name

    @property
    def delay(self) -> float:
        return float(self.loop.delay)


def controller_realisation(loop: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(A, B, C, D)`` of a loop's controller ``z' = A z + B e``, ``u = -(C z + D e)``.

    The time paths' reading (this driver and the generated kernels of :mod:`ctmm.compiled_loops`) of the
    one realisation, :func:`ctmm.controller_state_space.controller_state_space`: an LTI ``C(s)`` as
    ``control.ss`` realises it, a static gain as ``D`` alone (no states).

    Parameters
    ----------
    loop : Feedback
        The loop; its ``gain`` is a number or a proper SISO python-control system.

    Returns
    -------
    A : ndarray, shape (k, k)
    B, C : ndarray, shape (k,)
        Flat input and output vectors (``k = 0`` for a static gain).
    D : float
        Feedthrough [actuator unit per sensed unit].

    Raises
    ------
    ModelError
        An improper (e.g. ``kp + kd s``), non-SISO or non-finite ``C(s)``.
    """
    return controller_state_space(loop.name, loop.gain, "in time")


def _resolve(ports: Any, loops: Sequence[Any], step: float | None, n: int) -> list[_Loop]:
    """Check every loop's sensors, actuators and delay against the model's ports and the step (the
    controller states start at ``n``, the size of ``[q, v]``)."""
    resolved, offset = [], n
    for loop in loops:
        for name, _ in loop.terms:
            ports.check_sensor(name, f"sensor of loop {loop.name!r}")
        for name, _ in loop.actuator_terms:
            ports.check_actuator(name, f"actuator of loop {loop.name!r}")
        if step is not None and 0.0 < loop.delay < step * (1.0 - 1e-9):
            raise ModelError(f"loop {loop.name!r}: delay = {loop.delay!r} s is shorter than the step dt = {step!r} s; "
                             "a fixed-step integrator evaluates the loop inside the step, so the delay must be 0 "
                             f"or at least dt: use dt <= {loop.delay!r} s (or delay=0)")
        A, B, C, D = controller_realisation(loop)
        k = A.shape[0]
        resolved.append(_Loop(loop, tuple(t for t, _ in loop.terms), np.array([w for _, w in loop.terms], float),
                              tuple(loop.actuator_terms), A, B.reshape(k, 1), C.reshape(1, k), D,
                              slice(offset, offset + k)))
        offset += k
    return resolved


class _ClosedLoop:
    """State ``y = [q, v, controller states]`` and its rate with every actuator input applied."""

    def __init__(self, plant: Plant, loops: list[_Loop], controllers: Sequence[Any],
                 inputs: Mapping[str, Any], references: Mapping[str, Any], step: float | None,
                 coupling: str, history_step: float) -> None:
        self.plant = plant
        self.ports = ports = plant.ports
        self.model = plant.model
        self.n = plant.n_positions              # q = y[:n], v = y[n:n + nv]
        self.nv = plant.n_velocities
        self.base = self.n + self.nv            # controller states from here
        self.loops = loops
        self.all_names = list(dict.fromkeys(name for lp in loops for name in lp.sensors))
        self.now_names = list(dict.fromkeys(name for lp in loops if lp.delay == 0.0 for name in lp.sensors))
        self.all_sensors, self.now_sensors = ports.resolve(self.all_names), ports.resolve(self.now_names)
        self.all_index = {name: k for k, name in enumerate(self.all_names)}
        self.now_index = {name: k for k, name in enumerate(self.now_names)}
        self.size = self.base + sum(lp.A.shape[0] for lp in loops)
        self.input_names = list(inputs)
        for name in self.input_names:
            ports.check_actuator(name, "input")
        self.input_functions = [as_signal(f"inputs[{name!r}]", inputs[name]) for name in self.input_names]
        loop_names = [lp.name for lp in loops]
        for name in references:
            if name not in loop_names:
                raise unknown_name("reference (loop)", name, loop_names)
        self.references = {name: as_signal(f"references[{name!r}]", r) for name, r in references.items()}
        self.controllers = list(controllers)
        self.controller_delays = []
        for c in self.controllers:
            label = f"controller {getattr(c, 'name', None) or type(c).__name__!r}"
            for name in c.inputs:
                ports.check_sensor(name, f"input of {label}")
            for name in c.outputs:
                ports.check_actuator(name, f"output of {label}")
            delay = validation.nonnegative("controller measurement_delay", getattr(c, "measurement_delay", 0.0))
            if step is not None and 0.0 < delay < step * (1.0 - 1e-9):
                raise ModelError(f"controller with outputs {list(c.outputs)}: measurement_delay = {delay!r} s is "
                                 f"shorter than the step dt = {step!r} s; use 0 or at least dt")
            self.controller_delays.append(delay)
        self.master = CoSimulation(self.controllers, step, 0.0, coupling=coupling, measurement_delays=True) \
            if self.controllers else None
        delayed = [name for lp in loops if lp.delay > 0 for name in lp.sensors]
        delayed += [name for c, d in zip(self.controllers, self.controller_delays) if d > 0 for name in c.inputs]
        self.delayed_names = list(dict.fromkeys(delayed))
        self.delayed_sensors = ports.resolve(self.delayed_names)
        self.controller_sensors = [ports.resolve(list(c.inputs)) for c in self.controllers]
        self.delayed_index = {name: k for k, name in enumerate(self.delayed_names)}
        # every sensor read at a step's end (the loops' and the delayed ones), evaluated once there: all_names first,
        # so a loop's rows into the all-sensor vector index it too
        self.point_names = list(dict.fromkeys(self.all_names + self.delayed_names))
        self.point_sensors = ports.resolve(self.point_names)
        self.delayed_in_point = np.array([self.point_names.index(name) for name in self.delayed_names], dtype=np.intp)
        self._point: tuple[float, np.ndarray, np.ndarray] | None = None
        self.input_dependent = frozenset(getattr(ports, "input_dependent", ())) & set(
            self.all_names + [name for c in self.controllers for name in c.inputs])
        self._refuse_input_dependent(loops)
        # a step end's sensors are shared by the loops, the delay history and the stored row where they depend on the
        # state alone (a cut force depends on the actuators, which the held outputs and the loops change)
        self.share_points = bool(self.delayed_names) and not self.input_dependent
        self.max_delay = max([lp.delay for lp in loops] + self.controller_delays + [0.0])
        self.history_step = history_step
        self.history: DelayHistory | None = None
        self.evaluations = 0
        self.use_cache = False      # RK4 only: its first stage reuses the history's evaluation
        self._cache: tuple[float, np.ndarray, np.ndarray] | None = None
        # RK4 only: the loops' signals of the last stored row, which are those of the next step's first stage (the
        # same t and state object, after the controllers were sampled and the history extended)
        self._recorded: tuple[float, np.ndarray, list] | None = None
        self._plans = [self._plan(lp) for lp in loops]

    def _plan(self, lp: _Loop) -> tuple:
        """What :meth:`loop_values` reads of loop ``lp`` at every call, resolved once: its delay [s], the rows of its
        sensors in the real-time, recorded and delayed sensor vectors (``None`` where it is not read there), its
        reference (or ``None``), whether it has controller states and whether it saturates."""
        delay = lp.delay

        def rows(index: dict[str, int], used: bool) -> np.ndarray | None:
            return np.array([index[s] for s in lp.sensors], dtype=np.intp) if used else None

        return (lp, delay, rows(self.now_index, delay == 0.0), rows(self.all_index, True),
                rows(self.delayed_index, delay > 0.0), self.references.get(lp.name), lp.A.shape[0] > 0,
                lp.loop.saturation is not None)

    def _refuse_input_dependent(self, loops: list[_Loop]) -> None:
        """Refuse by name what this driver cannot honour of sensors that respond to the actuators at once (cut
        forces): a real-time loop on one (algebraic), a delayed one beside co-simulated controllers or read with a
        measurement delay (the held outputs make the force jump at every sample; the delay history is smooth)."""
        for lp in loops:
            sensed = sorted(self.input_dependent.intersection(lp.sensors))
            if sensed and (lp.delay == 0.0 or self.controllers):
                raise ModelError(f"loop {lp.name!r} on {sensed}: " + (
                    "a real-time loop on a cut force is algebraic (it responds to the loop's own actuator at once), "
                    "which this driver does not solve; give it a delay >= dt (ctmm.linearize closes it exactly, and so "
                    "does the generated RK4 of planar cut joints, compiled=True with method='rk4')"
                    if lp.delay == 0.0 else "a delayed loop on a cut force beside co-simulated controllers is not "
                    "available (their held outputs make it jump at every sample); sense it in a controller"))
        late = [x for c, d in zip(self.controllers, self.controller_delays) if d > 0 for x in c.inputs
                if x in self.input_dependent]
        if late:
            raise ModelError(f"controller inputs {late}: a cut force read with a measurement delay is not available "
                             "(it jumps at every sample of the held outputs); read it without measurement_delay")

    def sensor_values(self, names: Sequence[str], sensors: list, t: float, y: np.ndarray) -> np.ndarray:
        """Values of the resolved ``sensors`` (named ``names``) at ``(t, y)``; those that depend on the actuators
        (:attr:`input_dependent`) solved with the actuator values there (inputs, loops, held controller outputs)."""
        q, v = y[:self.n], y[self.n:self.base]
        if not self.input_dependent.intersection(names):
            return self.ports.values(sensors, q, v, t)
        actuators = self.actuator_values(t, y, self.loop_values(t, y))
        return self.ports.values(sensors, q, v, t, inputs=self.ports.inputs(actuators) if actuators else None)

    # -- signals --------------------------------------------------------------------------
    def loop_values(self, t: float, y: np.ndarray, record: bool = False) -> list[tuple[float, float, float]]:
        """``(y now, e, u)`` of every loop at state ``y`` and time ``t``, with the error
        ``e = y(t - tau) - r(t - tau)`` and ``u = -C e`` (``y now`` is NaN for a delayed loop
        unless ``record``: the integrator needs only ``u``)."""
        point = self._point
        shared = self.share_points and (record or (point is not None and point[0] == t and point[1] is y))
        if shared:                      # a step's end: the sensors of every loop, evaluated once there
            now = self.point_values(t, y)
        else:
            names, sensors = (self.all_names, self.all_sensors) if record else (self.now_names, self.now_sensors)
            now = self.sensor_values(names, sensors, t, y) if names else np.zeros(0)
        past_by_delay: dict[float, np.ndarray] = {}
        out = []
        for lp, delay, now_rows, all_rows, past_rows, ref, stateful, saturates in self._plans:
            rows = all_rows if record or (shared and now_rows is not None) else now_rows
            y_now = float(lp.weights @ now[rows]) if rows is not None else math.nan
            if past_rows is not None:
                past = past_by_delay.get(delay)
                if past is None:
                    past = past_by_delay[delay] = self.history(t - delay)
                y_then = float(lp.weights @ past[past_rows])
            else:
                y_then = y_now
            e = y_then - (float(ref(t - delay)) if ref is not None else 0.0)
            u = -(float((lp.C @ y[lp.states])[0]) if stateful else 0.0) - lp.D * e
            out.append((y_now, e, float(lp.loop.saturate(u) if saturates else u)))
        if record and self.use_cache:
            self._recorded = (t, y, out)
        return out

    def point_values(self, t: float, y: np.ndarray) -> np.ndarray:
        """The sensors of every loop and the delayed ones (:attr:`point_names`) at a step's end ``(t, y)``, evaluated
        once there (kept for the same ``t`` and state object: the rate, the delay history and the stored row read
        them; the state is not changed in place after the step's checks and projection)."""
        point = self._point
        if point is None or point[0] != t or point[1] is not y:
            point = self._point = (t, y, np.asarray(self.sensor_values(self.point_names, self.point_sensors, t, y),
                                                    float))
        return point[2]

    def actuator_values(self, t: float, y: np.ndarray, loop_values) -> dict[str, float]:
        """Total value of every driven actuator: inputs + loops + held controller outputs."""
        values: dict[str, float] = {}
        if self.input_functions:
            for name, value in zip(self.input_names,
                                   signal_values(self.input_functions, t, self.input_names, "input")):
                values[name] = values.get(name, 0.0) + float(value)
        for lp, (_, _, u) in zip(self.loops, loop_values):
            if not math.isfinite(u):        # a stage of a diverging step: a run failure, not bad input
                raise SimulationError(f"loop {lp.name!r}: non-finite output u = {u} at t = {t:.6g} s (the state "
                                      "diverged inside the step)", time=float(t), element=lp.name)
            for name, weight in lp.actuators:
                values[name] = values.get(name, 0.0) + weight * u
        if self.master is not None:
            for c, held in zip(self.controllers, self.master.held):
                for name, value in zip(c.outputs, held):
                    values[name] = values.get(name, 0.0) + float(value)
        return values

    def rate(self, t: float, y: np.ndarray) -> np.ndarray:
        """``dy/dt``; the last evaluation is kept (RK4's first stage reuses the history's one)."""
        cached = self._cache
        if self.use_cache and cached is not None and cached[0] == t and cached[1] is y:
            return cached[2]
        q, v = y[:self.n], y[self.n:self.base]
        recorded = self._recorded       # a stored row's (y now, e, u): e and u are what the rate needs
        loop_values = recorded[2] if self.use_cache and recorded is not None and recorded[0] == t \
            and recorded[1] is y else self.loop_values(t, y)
        values = self.actuator_values(t, y, loop_values)
        inputs = self.ports.inputs(values) if values else None
        out = np.empty(self.size)
        out[:self.n] = self.plant.position_rates(q, v)
        out[self.n:self.base] = self.plant.accelerations(q, v, t, inputs)
        for lp, (_, e, _) in zip(self.loops, loop_values):
            if lp.A.shape[0]:
                out[lp.states] = lp.A @ y[lp.states] + lp.B[:, 0] * e
        self.evaluations += 1
        self._cache = (t, y, out)
        return out

    # -- history and controllers ----------------------------------------------------------
    def _delayed_now(self, t: float, y: np.ndarray, rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Delayed sensors at ``(t, y)`` and their time derivatives ``J_q qdot + J_v vdot``: the
        derivative along the state's own motion, by a fourth-order central difference (exact
        Jacobians would cost one column per coordinate; this costs four sensor evaluations)."""
        q, v = y[:self.n], y[self.n:self.base]
        qdot, a = rate[:self.n], rate[self.n:self.base]
        names, sensors = self.delayed_names, self.delayed_sensors
        values = self.point_values(t, y)[self.delayed_in_point] if self.share_points else \
            np.asarray(self.sensor_values(names, sensors, t, y), float)
        largest_v = float(np.abs(v).max(initial=0.0))
        speed = max(largest_v / max(1.0, float(np.abs(q).max(initial=0.0))),
                    float(np.abs(a).max(initial=0.0)) / max(1.0, largest_v))
        h = 1e-3 / max(speed, 1.0)      # the state moves by ~1e-3 of its size: truncation ~1e-12

        def along(s: float) -> np.ndarray:
            return np.asarray(self.sensor_values(names, sensors, t + s, y + s * rate), float)

        if self.input_dependent.intersection(names):
            # a cut force reads the delayed loops' forces, from the history up to t - tau: backward differences
            # only (the history holds nothing after the last step), fourth order, on a step ten times shorter (its
            # truncation is ~12x the central one's, and a real-time loop on the same actuator moves the force faster
            # than the state's speed says: four-bar, a crank loop beside the delayed force loop, 3e-10 of the crank
            # rate at 1e-3 of the state's size against the exact rate of the generated kernel, 2e-15 at 1e-4)
            h = 0.1 * h
            derivative = (25.0 * values - 48.0 * along(-h) + 36.0 * along(-2 * h) - 16.0 * along(-3 * h)
                          + 3.0 * along(-4 * h)) / (12.0 * h)
        else:
            derivative = (8.0 * (along(h) - along(-h)) - (along(2 * h) - along(-2 * h))) / (12.0 * h)
        return values, derivative

    def begin(self, t0: float, y0: np.ndarray) -> None:
        """Start the delay history at ``t0`` (the initial state, held before ``t0``; a cut force: the fixed point
        ``F = F(u(F))`` the loops reading it would hold at that state, by iteration, which converges when their gain
        through the force's response to their own actuators is below 1 -- else a neutral delay loop, refused)."""
        if not self.delayed_names:
            return
        q, v = y0[:self.n], y0[self.n:self.base]
        values = np.asarray(self.ports.values(self.delayed_sensors, q, v, t0, **(
            {"inputs": None} if self.input_dependent.intersection(self.delayed_names) else {})), float)
        window = self.max_delay + (5e-3 if self.input_dependent else 0.0)     # _delayed_now reaches 4e-3 s further back
        self.history, before = DelayHistory(t0, values, None, delay=window, step=self.history_step), math.inf
        while self.input_dependent.intersection(self.delayed_names):
            new = np.asarray(self.sensor_values(self.delayed_names, self.delayed_sensors, t0, y0), float)
            change = float(np.max(np.abs(new - values), initial=0.0))
            if not change < before:         # not contracting
                raise ModelError(f"delayed loops on the cut forces {sorted(self.input_dependent)}: the force held "
                                 "before the start does not settle (the loops' gain through its response to their own "
                                 "actuators is 1 or more: a neutral delay loop, unstable at high frequency)")
            values, before = new, change
            self.history = DelayHistory(t0, values, None, delay=window, step=self.history_step)
            if change <= 1e-13 * max(1.0, float(np.max(np.abs(new)))):
                return

    def remember(self, t: float, y: np.ndarray) -> None:
        """Store the delayed sensors and their rates at ``(t, y)`` (after the controllers due at ``t``
        were sampled; at the last stored time: its rate only)."""
        if self.history is None:
            return
        self._recorded = None           # the history changes: a stored row's delayed signals are not reused
        if self.share_points:           # the step end's sensors, for the rate below, the history and the stored row
            self.point_values(t, y)
        values, derivative = self._delayed_now(t, y, self.rate(t, y))
        if t > self.history.last_time:
            self.history.append(t, values, derivative)
        else:
            self.history.derivatives[-1] = derivative

    def sample(self, step: int, t: float, y: np.ndarray) -> bool:
        """Sample the controllers due at step ``step`` (time ``t`` [s], state ``y``); returns
        whether one was sampled (its held outputs may have jumped)."""
        if self.master is None:
            return False

        def measure(i: int) -> np.ndarray:
            c, delay = self.controllers[i], self.controller_delays[i]
            if delay > 0.0:
                past = self.history(t - delay)
                return np.array([past[self.delayed_index[name]] for name in c.inputs], dtype=float)
            return np.asarray(self.sensor_values(c.inputs, self.controller_sensors[i], t, y), dtype=float)

        if self.master.sample(step, t, measure):
            self._cache = self._recorded = None     # held outputs changed: the rate at (t, y) changed too
            return True
        return False

    def close(self) -> None:
        if self.master is not None:
            self.master.close()


def _check_state(system: _ClosedLoop, guard, t: float, y: np.ndarray, step: float | None, method: str) -> None:
    guard(t, y, step, method)
    if system.size > system.base and not np.isfinite(y[system.base:]).all():
        name = next(lp.name for lp in system.loops if not np.all(np.isfinite(y[lp.states])))
        raise SimulationError(f"non-finite controller state of loop {name!r} at t = {t:.6g} s", time=float(t),
                              element=name)


def simulate_closed_loop(model: Any, q0: np.ndarray, qdot0: np.ndarray, t_final: float,
                         dt: float | None, *, method: str | Scheme = "rk4", loops: Sequence[Any] = (),
                         controllers: Sequence[Any] = (), inputs: Mapping[str, Any] | None = None,
                         references: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                         coupling: str = "hold", rtol: float = 1e-8, atol: float = 1e-10,
                         max_step: float = math.inf, store_every: int = 1, progress: bool | None = None,
                         stability_check: str = "warn", divergence_bound: float | None = None,
                         projection: bool = True) -> SimulationResult:
    """Integrate a planar or spatial model with its loops, controllers and inputs (module docstring).

    Parameters
    ----------
    model : PlanarModel or SpatialModel
        The plant (:func:`ctmm.control.plants.plant_of`).
    q0, qdot0 : ndarray
        Initial coordinates ``q`` and velocities ``v`` (checked by the caller; planar: ``v = qdot``).
    t_final : float
        End time [s].
    dt : float or None
        Step [s] of ``"rk4"`` and the schemes and the sample grid of controllers (required for
        these); for a scipy method with ``dt`` the result is stored on the grid ``k dt`` (dense
        output), without it at every accepted step.
    method : str or Scheme
        ``"rk4"``, a name of :data:`~ctmm.planar.integrate.SCIPY_METHODS`, or a DT-TMM
        scheme (a name of :data:`ctmm.schemes.SCHEMES` or a :mod:`ctmm.schemes` object).
    loops : sequence of Feedback
        Loops on named sensors and actuators of :mod:`ctmm.planar.ports` / :mod:`ctmm.spatial.ports`.
    controllers : sequence of Controller
        Co-simulated controllers (validated by the caller).
    inputs : mapping, optional
        ``{actuator name: number or f(t)}`` open-loop actuator values [N, N m].
    references : mapping, optional
        ``{loop name: r(t)}`` [sensed unit].
    outputs : sequence of str
        Sensor names stored at every row.
    coupling : {"hold", "previous"}
        As in :class:`~ctmm.control.cosim.CoSimulation`.
    rtol, atol, max_step : float
        scipy tolerances and largest step [s].
    store_every : int
        ``"rk4"`` and the schemes: keep every ``store_every``-th step (the last one always).
    progress : bool, optional
        Progress bar (long runs on a terminal by default).
    stability_check : {"warn", "error", "ignore"}
        ``"rk4"``: step against the plant's linearised limit before the run (loops not included);
        a scheme: against its own limit with the real-time loops included
        (:func:`~ctmm.planar.implicit.simulate_implicit`).
    divergence_bound : float, optional
        As in :func:`~ctmm.planar.integrate.simulate_rk4`.
    projection : bool
        A kinematic loop plant, ``"rk4"`` and ``solve_ivp``: project onto the cut joints
        (:mod:`ctmm.control.explicit_loops`; ``info`` reports the drift before and after); ``False`` holds the
        drift by Baumgarte alone (as :mod:`ctmm.compiled_kinematic_loop_control` with ``projection=False``, for
        comparison).

    Returns
    -------
    SimulationResult
        Coordinates, rates, outputs, ``"<loop>.y"``, ``"<loop>.u"`` [sensed unit, actuator
        unit] and ``"<controller output>@samples"``.

    Raises
    ------
    ModelError
        Unknown sensor, actuator, loop or method; a delay between 0 and ``dt`` (``theta dt``
        with Wilson-theta); an improper C(s).
    SimulationError
        Divergence, non-finite states, failing controller or user code; ``partial_result``.
    """
    plant = plant_of(model)
    scheme = as_scheme(method) if isinstance(method, Scheme) or (isinstance(method, str) and method in SCHEMES) \
        else None
    if scheme is not None and not plant.schemes:
        raise ModelError(f"method={method!r}: the DT-TMM schemes are not implemented for {plant.label} models yet; "
                         f"use method='rk4' or a solve_ivp method {SCIPY_METHODS}")
    if method != "rk4" and method not in SCIPY_METHODS and scheme is None:
        raise ModelError(f"method must be 'rk4', one of {SCIPY_METHODS} or a DT-TMM scheme "
                         f"{tuple(sorted(SCHEMES))} for a planar model with loops, controllers or inputs, "
                         f"got {method!r}")
    fixed = method == "rk4" or scheme is not None
    if not fixed and store_every != 1:
        raise ModelError(f"store_every={store_every!r} applies to fixed-step methods; with {method!r} give dt to "
                         "store the result on the grid k dt (leave store_every at 1)")
    t_final = validation.positive("t_final", t_final)
    projection = validation.flag("projection", projection)
    if dt is not None:
        dt = validation.positive("dt", dt)
    if fixed and dt is None:
        raise ModelError(f"dt is required with method={method!r} (a fixed step [s], > 0), got None")
    if controllers and dt is None:
        raise ModelError("dt is required with co-simulated controllers: it is the sample grid [s] "
                         "(each controller's sample_time is a whole multiple of it)")
    n, nv = plant.n_positions, plant.n_velocities
    resolved = _resolve(plant.ports, loops, dt if fixed else None, n + nv)
    delays = [lp.delay for lp in resolved if lp.delay > 0]
    if scheme is not None:
        check_scheme_delays(resolved, scheme, dt)
    if not fixed and delays:
        max_step = min(max_step, min(delays))
        forced = t_final / max_step
        advice = (f"the loop delay {min(delays):.3g} s caps solve_ivp's step (the delayed signal must come from "
                  f"the stored history), so method={method!r} takes at least {forced:.3g} steps over {t_final!r} s")
        if forced > validation.MAX_STEPS:
            raise ModelError(f"{advice}; at most {validation.MAX_STEPS:.0e} are allowed: shorten t_final, or use "
                             "method='rk4' with a dt that divides the delay, or a DT-TMM scheme")
        if forced > 1e5:
            warnings.warn(f"{advice}; for a delay this short relative to the run, method='rk4' with a dt that "
                          "divides the delay, or a DT-TMM scheme, is faster", RuntimeWarning, stacklevel=3)
    history_step = dt if fixed else (min(delays) if delays else t_final) * 1e-5
    label = method if scheme is None else f"dt-tmm/{type(scheme).__name__}"
    try:
        system = _ClosedLoop(plant, resolved, controllers, inputs or {}, references or {}, dt, coupling,
                             history_step=max(history_step, 1e-300))
    except SimulationError as exc:     # a controller's init failed: nothing was simulated
        raise with_partial(exc, lambda: empty_result(plant, model, loops, outputs, label, {"dt": dt})) \
            from exc.__cause__
    try:
        y0 = np.concatenate([q0, qdot0, np.zeros(system.size - n - nv)])
        guard = plant.guard(q0, divergence_bound, qdot0)
        rows = LoopRows(system)
        start = _time.perf_counter()
        info = {"dt": dt, "method": label}

        def partial() -> SimulationResult:
            return rows_result(rows, outputs, label, {**info, "wall_time_s": _time.perf_counter() - start})

        def check(t: float, y: np.ndarray) -> None:
            _check_state(system, guard, t, y, dt if method == "rk4" else None, method)

        try:
            system.begin(0.0, y0)
            system.sample(0, 0.0, y0)
            system.remember(0.0, y0)
            rows.add(0.0, y0)
            if method == "rk4":
                from ..planar.integrate import step_total

                n_steps = step_total(t_final, dt)
                plant.check_step(q0, qdot0, dt, stability_check)
                info.update(run_rk4(system, rows, check, dt, n_steps, store_every, progress, projection))
            elif scheme is not None:
                info.update(run_implicit(system, rows, q0, qdot0, t_final, dt, scheme, store_every, progress,
                                          stability_check, divergence_bound))
            else:
                info.update(run_scipy(system, rows, check, y0, t_final, dt, method, rtol, atol, max_step, progress,
                                      projection))
        except SimulationError as exc:
            raise with_partial(exc, partial) from exc.__cause__
        return rows_result(rows, outputs, label, {**info, "wall_time_s": _time.perf_counter() - start})
    finally:
        system.close()
