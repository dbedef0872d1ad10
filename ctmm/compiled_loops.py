"""Feedback loops closed inside generated kernels (issue 13: real-time and delayed loops, LTI controllers).

A :class:`~ctmm.control.controlled_model.ControlledModel` is a planar (or spatial:
:mod:`ctmm.compiled_spatial_loops` gives its symbols) plant with
:class:`~ctmm.control.loops.Feedback` loops ``u = -C [ y(t - tau) - r(t - tau) ]``,
``y = sum_i c_i sensor_i``.  :class:`ClosedLoops` states every loop on casadi symbols so that
:class:`~ctmm.compiled_scene.CompiledScene` closes it inside the generated RK4 step, exactly as the
numpy path of :mod:`ctmm.control.planar_time` does:

* **sensors** (planar: :mod:`ctmm.compiled_planar_sensors`; spatial and chain plants give their own):
  coordinates and their rates, body angles and rates, hinge angles and rates, positions and velocities
  of named points, beam station deflections, slopes and their rates -- every port of
  :mod:`ctmm.planar.ports` (all are functions of the state ``(q, qdot)``); plants whose symbols name sensors that
  respond to the actuators at once (``symbols.input_dependent``: the cut forces of planar and spatial kinematic loops) close
  them by :class:`~ctmm.compiled_input_sensors.InputDependentSensors` (:meth:`ClosedLoops.close`: real-time loops on
  them solved as an algebraic system, delayed ones sampled with their exact rate);
* **real-time loops** (``tau = 0``): evaluated at the state of every RK4 stage (no added lag);
* **saturation** ``(low, high)``: ``u`` clipped at every evaluation (the controller states integrate
  the unclipped error, as on the numpy path);
* **LTI controllers** ``C(s)`` (proper, SISO; the realisation of ``control.ss``): their states
  ``z`` are appended to the integrated state, ``z' = A z + B e``, ``u = -(C z + D e)``;
* **delayed loops** with ``tau = m dt`` (``m >= 1`` whole): the loop signal ``y`` and its time
  derivative ``J_q qdot + J_qdot qddot`` (exact, by forward differentiation of the sensor
  expression) are stored at every step in a ring of ``max m + 1`` samples carried in the fold
  state; a stage at ``t_n`` or ``t_n + dt`` reads a stored sample, a stage at ``t_n + dt/2``
  the cubic Hermite interpolant between two samples (third order, the interpolation of the
  numpy path's :class:`~ctmm.control.history.DelayHistory`).  Before ``t = 0`` the history is
  the initial value held (as the numpy path).  A delay that is not a whole multiple of ``dt``
  is refused (:class:`~ctmm.errors.ModelError`).

References ``r(t)`` and open-loop inputs are numbers or :mod:`ctmm.signals` objects with a
symbolic form (constants, sines, steps, square waves), evaluated in the generated code at the
stage times.  With ``numbers="inputs"`` (what :class:`~ctmm.compiled_scene.CompiledScene` asks for)
the loop gains, controller realisations ``(A, B, C, D)`` and the references' signal parameters are
entries of the step's parameter vector ``p`` after the plant's numbers
(:func:`ctmm.compiled_parameters.loop_parameter_layout`; :attr:`ClosedLoops.parameter_values`), so
one library serves a sweep of them; with ``numbers="constants"`` they are constants of the code.  The
sensors, delays, controller orders, reference classes and open-loop inputs are always constants.
Loops and open-loop inputs acting on beam station forces or moments (not among the held actuator inputs,
:func:`ctmm.compiled_scene.compiled_actuators`) enter the sweep as extra inputs, :attr:`ClosedLoops.channels`:
their modal forces and floating-frame wrench in the beam's element terms (:mod:`ctmm.compiled_station_loads`).
Refused: user callables as references or inputs, co-simulated controllers.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .control.controlled_model import ControlledModel
from .control.planar_time import controller_realisation
from .errors import ModelError
from .ode import rk4_step
from .planar.model import PlanarModel
from .planar.ports import ActuatorInputs, PlanarPorts
from .compiled_input_sensors import InputDependentSensors
from .compiled_planar_sensors import PlanarSymbols
from .compiled_parameters import LoopNumbers, loop_parameter_layout, parameter_vector, symbolic_loop_numbers
from .compiled_references import SymbolicReference, reference_at, symbolic_reference
from .signals import symbolic_signal

__all__ = ["ClosedLoops", "LoopLaw", "delay_steps"]


@dataclass(frozen=True)
class LoopLaw:
    """One loop stated for generated code.

    Attributes
    ----------
    name : str
    sensors, actuators : tuple of (str, float)
        Weighted sensor and actuator terms.
    A, B, C : ndarray
        Controller realisation ``(k, k)``, ``(k,)``, ``(k,)`` (``k = 0`` for a static gain).
    D : float
        Feedthrough (the static gain).
    delay : float
        ``tau`` [s].
    steps : int
        ``tau / dt`` (0 for a real-time loop).
    reference : callable
        ``r(t)`` [sensed unit], a :mod:`ctmm.signals` object with a symbolic form.
    saturation : tuple of float or None
        ``(low, high)`` limits of ``u`` [actuator unit] (the controller states integrate the unclipped
        error, as on the numpy path).
    """

    name: str
    sensors: tuple
    actuators: tuple
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: float
    delay: float
    steps: int
    reference: Any
    saturation: Any = None

    def output(self, demand: Any) -> Any:
        """The applied ``u``: ``demand`` clipped to :attr:`saturation` on symbols."""
        if self.saturation is None:
            return demand
        import casadi as ca

        low, high = self.saturation
        return ca.fmin(ca.fmax(demand, float(low)), float(high))


def _state_only_refusal(*_: Any) -> Any:
    """``ClosedLoops.sensors`` of loops whose sensors move with time (driven joints): the paths that read the sensors
    at the state only refuse them."""
    raise ModelError("the loop sensors move with the prescribed motion of driven joints (functions of the state and "
                     "the time); this generated path states them at the state only: use the generated RK4 "
                     "(method='rk4', compiled=True) or compiled=False")


def delay_steps(name: str, delay: float, dt: float | None) -> int:
    """``tau / dt`` of loop ``name`` as a whole number (0 for ``tau = 0``).

    Raises
    ------
    ModelError
        ``tau > 0`` without ``dt``, or not a whole multiple (>= 1) of ``dt``.
    """
    delay = float(delay)
    if delay == 0.0:
        return 0
    if dt is None:
        raise ModelError(f"loop {name!r}: a delayed loop (delay = {delay!r} s) needs the step dt to compile its "
                         "history ring")
    steps = int(round(delay / dt))
    if steps < 1 or abs(steps * dt - delay) > 1e-9 * delay:
        raise ModelError(f"loop {name!r}: delay = {delay!r} s is not a whole multiple of dt = {dt!r} s; generated "
                         "kernels keep the history as a ring of samples stored every step (cubic Hermite at the "
                         "half steps): choose dt = delay / m for a whole m >= 1, or compiled=False")
    return steps


# ------------------------------------------------------------------------------------------
# the closed loop on symbols
# ------------------------------------------------------------------------------------------
class ClosedLoops:
    """The loops of a controlled model stated on casadi symbols (module docstring).

    Parameters
    ----------
    controlled : ControlledModel, or a ControlledChain with its ``symbols``
    actuators : sequence of str
        The actuator inputs ``u`` of the generated kernel, in order.
    dt : float or None
        Step [s]; required with delayed loops (each delay a whole multiple of it, unless ``whole_delays`` is False:
        then any delay, ``steps`` 1, for a caller that keeps its own history, :mod:`ctmm.compiled_scheme_loops`).
    references : mapping, optional
        ``{loop name: number or symbolic signal}`` [sensed unit] (default 0).
    inputs : mapping, optional
        ``{actuator name: number or symbolic signal}`` open-loop actuator values [SI], added to the loops'.
    symbols : object, optional
        The plant on symbols (``ports``, ``n_positions``, ``n_velocities``, ``position_rates(q, v)``,
        ``sensor(name, q, v)``); default :class:`PlanarSymbols` of a planar plant (spatial and chain plants:
        :class:`ctmm.compiled_spatial_loops.SpatialSymbols`, :class:`ctmm.compiled_chain.ChainSymbols`).
    numbers : {"constants", "inputs"}
        The loops' gains, controller realisations and references as constants of the code, or as entries
        of ``p`` after the plant's numbers (planar: :func:`~ctmm.compiled_parameters.parameter_vector`; spatial:
        ``symbols.parameter_count`` entries, :class:`~ctmm.compiled_spatial_loops.SpatialSymbols`).

    Attributes
    ----------
    laws : tuple of LoopLaw
    channels : list of (int or signal, ActuatorInputs)
        Loops acting on beam station forces or moments (the loop's index) and open-loop ``inputs`` on them
        (the input's symbolic signal), with their loads per unit value, modal and floating-frame
        (:mod:`ctmm.compiled_station_loads`): extra inputs of the sweep after ``actuators``.
    n_controller_states : int
    plant_parameter_count : int
        Length of the plant's numbers, the first entries of ``p`` (0 for a spatial plant with its numbers
        in the code).
    parameter_layout : list of (str, str, float)
        ``(name, role, value)`` of the loop numbers that follow in ``p``
        (:func:`~ctmm.compiled_parameters.loop_parameter_layout`; empty with ``numbers="constants"``).
    parameter_values : ndarray
        Their values (this controlled model's gains, controllers and references).
    ring_columns : int
        Stored samples per delayed loop (``max tau / dt + 1``; 0 without delayed loops).
    state_size : int
        Length of the integrated and folded state ``[q, v, z, ring]``.
    """

    def __init__(self, controlled: ControlledModel, actuators: Sequence[str], dt: float | None = None,
                 references: Mapping[str, Any] | None = None, inputs: Mapping[str, Any] | None = None,
                 symbols: Any = None, numbers: str = "constants", whole_delays: bool = True) -> None:
        if not isinstance(controlled, ControlledModel) and symbols is None:   # (chains come with their symbols)
            raise ModelError(f"ClosedLoops: controlled must be a ctmm.control.ControlledModel, got {controlled!r}")
        if numbers not in ("constants", "inputs"):
            raise ModelError(f"ClosedLoops: numbers must be 'constants' or 'inputs' (the loops' gains, controllers and "
                             f"references as entries of p), got {numbers!r}")
        import casadi as ca

        plant, ports = controlled.plant, controlled.ports if symbols is None else symbols.ports
        references = dict(references or {})
        for name in references:
            controlled.loop(name)                   # unknown loop names raise
        self.actuators = tuple(actuators)
        self.inputs, station_inputs = [], []
        for name, value in dict(inputs or {}).items():
            ports.check_actuator(name, "inputs: actuator")
            signal = symbolic_reference(f"inputs[{name!r}]", value)
            if name in self.actuators:
                self.inputs.append((self.actuators.index(name), signal))
            elif isinstance(ports, PlanarPorts) and ports.actuators[name].kind == "station":
                station_inputs.append((signal, ports.inputs({name: 1.0})))     # a channel of its own
            else:
                raise ModelError(f"inputs[{name!r}]: generated kernels drive the actuators "
                                 f"{', '.join(self.actuators) or '(none)'} and the station forces and moments of "
                                 "planar beams; use compiled=False")
        laws, self.channels = [], []
        for loop in controlled.loops:
            if any(actuator not in self.actuators for actuator, _ in loop.actuator_terms):
                self.channels.append((len(laws), self._channel(ports, loop)))
            A, B, C, D = controller_realisation(loop)
            reference = symbolic_reference(f"references[{loop.name!r}]", references.get(loop.name, 0.0))
            laws.append(LoopLaw(loop.name, tuple(loop.terms), tuple(loop.actuator_terms), A, B, C, D,
                                float(loop.delay), delay_steps(loop.name, loop.delay, dt) if whole_delays else
                                int(loop.delay > 0.0), reference, loop.saturation))
        self.laws = tuple(laws)
        self.channels += station_inputs
        symbols = PlanarSymbols(plant, ports) if symbols is None else symbols
        self.nq, self.nv = symbols.n_positions, symbols.n_velocities
        self.base = self.nq + self.nv           # [q, v] (planar: v = qdot), then z and the ring
        self.position_rates = symbols.position_rates
        self.plant_parameter_count = parameter_vector(plant).size if isinstance(plant, PlanarModel) else \
            getattr(symbols, "parameter_count", 0) if numbers == "inputs" else 0
        self.parameter_layout = loop_parameter_layout(self.laws) if numbers == "inputs" else []
        self.parameter_values = np.array([value for _, _, value in self.parameter_layout], dtype=float)
        self.n_controller_states = sum(law.A.shape[0] for law in laws)
        self.delayed = [k for k, law in enumerate(laws) if law.steps]
        self.ring_columns = max((law.steps for law in laws), default=0) + 1 if self.delayed else 0
        self.state_size = self.base + self.n_controller_states + 2 * len(self.delayed) * self.ring_columns
        q, v, a = ca.SX.sym("q", self.nq), ca.SX.sym("v", self.nv), ca.SX.sym("a", self.nv)
        time, timed = ca.SX.sym("t"), bool(getattr(symbols, "time_sensors", False))
        cache: dict[str, Any] = {}
        dependent = frozenset(getattr(symbols, "input_dependent", ())) & {s for law in laws for s, _ in law.sensors}

        def sensed(name: str) -> Any:
            if name in dependent:               # the input-dependent part: InputDependentSensors
                return 0.0
            if name not in cache:
                cache[name] = symbols.sensor(name, q, v, time) if timed else symbols.sensor(name, q, v)
            return cache[name]

        self.dependent = InputDependentSensors(symbols, self.laws, sorted(dependent), self.actuators, self.channels) \
            if dependent else None
        y = ca.vertcat(*[sum((w * sensed(s) for s, w in law.sensors), 0.0) for law in laws]) if laws else ca.SX(0, 1)
        rates = ca.jtimes(y, ca.vertcat(q, v), ca.vertcat(self.position_rates(q, v), a)) if laws else ca.SX(0, 1)
        self.time_dependent_sensors = bool(laws) and bool(ca.depends_on(y, time))
        self._timed: tuple[Any, Any] | None = None
        if self.time_dependent_sensors:         # sensors moving with driven joints: y(q, v, t), y' + dy/dt
            self._timed = (ca.Function("loop_sensors", [q, v, time], [y]),
                           ca.Function("loop_sensor_rates", [q, v, a, time], [rates + ca.jacobian(y, time)]))
            self.sensors = self.sensor_rates = _state_only_refusal
        else:
            self.sensors = ca.Function("loop_sensors", [q, v], [y])
            self.sensor_rates = ca.Function("loop_sensor_rates", [q, v, a], [rates])
        self._state_sensors = (self.sensors, self.sensor_rates)
        if self.dependent is not None:          # the state part alone is not the loop signal: other paths refuse
            self.sensors = self.sensor_rates = self.dependent.refusal
        weights = np.zeros((len(self.actuators), len(laws)))
        channelled = {k for k, _ in self.channels if isinstance(k, int)}
        for k, law in enumerate(laws):
            for actuator, w in ([] if k in channelled else law.actuators):
                weights[self.actuators.index(actuator), k] += float(w)
        self.weights = weights

    def sensors_at(self, q: Any, v: Any, t: Any) -> Any:
        """The loops' signals at the state ``(q, v)`` and time ``t`` [s] (:attr:`sensors` when they do not move with
        time)."""
        return self._timed[0](q, v, t) if self._timed is not None else self._state_sensors[0](q, v)

    def sensor_rates_at(self, q: Any, v: Any, a: Any, t: Any) -> Any:
        """The loops' signal rates at ``(q, v)``, accelerations ``a`` and time ``t`` [s] (with ``dy/dt``)."""
        return self._timed[1](q, v, a, t) if self._timed is not None else self._state_sensors[1](q, v, a)

    @staticmethod
    def _channel(ports: PlanarPorts, loop: Any) -> ActuatorInputs:
        """The loads of a loop acting on beam station forces or moments, per unit output: modal forces and the
        wrench on the beam's floating frame (:mod:`ctmm.compiled_station_loads`; a piezo patch's moment pair
        ``-M`` at ``x1``, ``+M`` at ``x2`` leaves modal forces only)."""
        if not isinstance(ports, PlanarPorts):
            raise ModelError(f"loop {loop.name!r} acts on actuators outside the generated kernel's inputs; use "
                             "compiled=False")
        weights: dict[str, float] = {}
        for actuator, w in loop.actuator_terms:
            weights[actuator] = weights.get(actuator, 0.0) + float(w)
        return ports.inputs(weights)

    # -- pieces of the state -----------------------------------------------------------------
    def _split(self, x: Any) -> tuple:
        nq, base, nz = self.nq, self.base, self.n_controller_states
        return x[:nq], x[nq:base], x[base:base + nz]

    def _ring(self, state: Any) -> Any:
        import casadi as ca

        start = self.base + self.n_controller_states
        return ca.reshape(state[start:], 2 * len(self.delayed), self.ring_columns)

    def initial_state(self, q: np.ndarray, qdot: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``[q, qdot, z = 0, ring]`` at the start time ``t`` [s]: every stored sample the initial loop signal
        with rate 0 (the history before the start is the initial state held)."""
        y0 = np.asarray(self.sensors_at(q, qdot, t), dtype=float).reshape(-1)[self.delayed] \
            if self.dependent is None or not self.delayed else self.dependent.initial_samples(self, q, qdot, t)
        column = np.concatenate([y0, np.zeros(len(self.delayed))])
        ring = np.tile(column[:, None], (1, self.ring_columns)).reshape(-1, order="F")
        return np.concatenate([q, qdot, np.zeros(self.n_controller_states), ring])

    # -- the closed-loop rate and step -----------------------------------------------------
    def numbers(self, p: Any) -> list[LoopNumbers]:
        """The laws' numbers from the whole parameter column ``p`` (the plant's, then the loops'), or
        the laws' own numbers (constants) for ``p = None`` or ``numbers="constants"``."""
        inputs = p is not None and self.parameter_layout
        return symbolic_loop_numbers(self.laws, p[self.plant_parameter_count:] if inputs else None)

    @staticmethod
    def law_output(law: LoopLaw, numbers: LoopNumbers, signal: Any, z: Any, t: Any) -> tuple:
        """``(u, e)`` of one loop: ``e = signal - r(t - tau)``, ``u = -(C z + D e)`` (``z`` its controller
        states), on symbols."""
        import casadi as ca

        reference = law.reference
        at = t - law.delay
        r = reference.symbolic(at) if isinstance(reference, SymbolicReference) else \
            symbolic_signal(type(reference), at, numbers.reference)
        e = signal - r
        controller = ca.dot(numbers.C, z) if law.A.shape[0] else 0.0
        return -controller - numbers.D * e, e

    def close(self, u: Any, p: Any, t: Any, x: Any, delayed: Sequence[Any]) -> tuple:
        """The loops closed at time ``t`` and ``x = [q, qdot, z]`` with the held actuator values ``u`` and the delayed
        loop signals ``delayed`` (one per delayed loop, in order), on symbols; ``p`` the whole parameter column, or
        ``None`` for the laws' and the plant's own numbers.  Returns ``(y, outputs, demands, z rates, total)``: every
        loop's signal now, its applied output (clipped) and unclipped demand, the controller states' rates, and the
        actuator values ``total`` (``u``, the loops' outputs and the open-loop inputs; then one entry per
        :attr:`channels` entry).  Real-time loops on sensors that respond to the actuators at once (cut forces,
        :class:`~ctmm.compiled_input_sensors.InputDependentSensors`) are solved exactly with their actuators: the
        sensors are affine in them."""
        import casadi as ca

        q, v, z = self._split(x)
        now, numbers = self.sensors_at(q, v, t), self.numbers(p)
        dependent = self.dependent
        algebraic = dependent.algebraic if dependent is not None else ()
        base = u
        for index, signal in self.inputs:
            unit = np.zeros(len(self.actuators))
            unit[index] = 1.0
            base = base + ca.DM(unit) * reference_at(signal, t)
        offsets = np.cumsum([0] + [law.A.shape[0] for law in self.laws])
        demands: list[Any] = [None] * len(self.laws)
        errors: list[Any] = [None] * len(self.laws)
        for k, (law, number) in enumerate(zip(self.laws, numbers)):
            if k not in algebraic:
                signal = delayed[self.delayed.index(k)] if law.steps else now[k]
                demands[k], errors[k] = self.law_output(law, number, signal, z[offsets[k]:offsets[k + 1]], t)
        outputs = [None if d is None else law.output(d) for law, d in zip(self.laws, demands)]
        weights = ca.DM(self.weights)
        known = base
        for k, out in enumerate(outputs):
            if out is not None:
                known = known + weights[:, k] * out
        y = now
        if dependent is not None:
            offset, gain = dependent.law_terms(q, v, self.plant_numbers(p), t)
            if algebraic:
                solved = dependent.solve_algebraic(
                    [self.law_output(self.laws[k], numbers[k], now[k] + offset[k] + ca.mtimes(gain[k, :], known),
                                     z[offsets[k]:offsets[k + 1]], t)[0] for k in algebraic],
                    [numbers[k].D for k in algebraic], gain, weights)
                for j, k in enumerate(algebraic):
                    outputs[k] = demands[k] = solved[j]
                    known = known + weights[:, k] * solved[j]
            y = now + offset + ca.mtimes(gain, known)
            for k in algebraic:
                errors[k] = self.law_output(self.laws[k], numbers[k], y[k], z[offsets[k]:offsets[k + 1]], t)[1]
        rates = [ca.mtimes(number.A, z[offsets[k]:offsets[k + 1]]) + number.B * errors[k]
                 for k, (law, number) in enumerate(zip(self.laws, numbers)) if law.A.shape[0]]
        total = ca.vertcat(known, *[outputs[k] if isinstance(k, int) else reference_at(k, t)
                                    for k, _ in self.channels])
        return y, outputs, demands, rates, total

    def plant_numbers(self, p: Any) -> Any:
        """The plant's part of the whole parameter column ``p`` (``None``: the plant's own numbers)."""
        if p is None:
            return None
        return p[:self.plant_parameter_count] if self.parameter_layout else p

    def rate(self, acceleration: Any, u: Any, p: Any, t: Any, x: Any, delayed: Sequence[Any]) -> tuple:
        """``(dx/dt, qddot)`` at time ``t`` and ``x = [q, qdot, z]`` with the delayed loop signals
        ``delayed`` (one per delayed loop, in order); ``p`` the whole parameter column (the plant's
        numbers, then :attr:`parameter_layout`)."""
        import casadi as ca

        q, v, _ = self._split(x)
        _, _, _, rates, total = self.close(u, p, t, x, delayed)
        qddot = acceleration(q, v, total, self.plant_numbers(p), t)
        return ca.vertcat(self.position_rates(q, v), qddot, *rates), qddot

    def step(self, acceleration: Any, n_inputs: int, n_parameters: int) -> Any:
        """``step(Y, u, h, p, t0, k)``: RK4 step ``k`` (from ``t0 + k h``) of the closed loop, ``Y`` the
        state ``[q, qdot, z, ring]`` (:attr:`state_size`), ``u`` the ``n_inputs`` held actuator values,
        ``p`` the plant's ``n_parameters`` numbers, then the loops' :attr:`parameter_values` entries;
        ``acceleration(q, v, [u; channels], p_plant, t)`` the plant's generated sweep (a casadi Function)
        whose inputs continue with one per :attr:`channels` entry.

        Raises
        ------
        ModelError
            Loop numbers as inputs with ``n_parameters`` other than :attr:`plant_parameter_count`.
        """
        import casadi as ca

        if self.parameter_layout and n_parameters != self.plant_parameter_count:
            raise ModelError(f"ClosedLoops.step: n_parameters = {n_parameters!r}, the loops' numbers follow the "
                             f"plant's {self.plant_parameter_count} numbers")
        Y, u, h = ca.MX.sym("y", self.state_size), ca.MX.sym("u", n_inputs), ca.MX.sym("h")
        p = ca.MX.sym("p", n_parameters + self.parameter_values.size)
        t0, k = ca.MX.sym("t0"), ca.MX.sym("k")
        x = Y[:self.base + self.n_controller_states]
        t = t0 + k * h
        if not self.delayed:
            def rate(stage: Any, state: Any) -> Any:
                return self.rate(acceleration, u, p, stage, state, ())[0]

            return ca.Function("step", [Y, u, h, p, t0, k], [rk4_step(rate, t, x, h)])
        ring, last = self._ring(Y), self.ring_columns - 1
        shifted = ring[:, 1:]
        steps = [self.laws[j].steps for j in self.delayed]
        count = len(self.delayed)

        def read(table: Any, stage: str) -> list:
            out = []
            for d, m in enumerate(steps):
                left, right = table[d, last - m], table[d, last - m + 1]
                if stage == "start":
                    out.append(left)
                elif stage == "end":
                    out.append(right)
                else:                       # cubic Hermite at the half step; the state held before t = 0
                    middle = 0.5 * (left + right) + 0.125 * h * (table[count + d, last - m]
                                                                 - table[count + d, last - m + 1])
                    out.append(ca.if_else(k < m, left, middle))
            return out

        placeholder = ca.horzcat(shifted, ca.MX.zeros(2 * count, 1))       # sample n not read at t_n
        first, qddot = self.rate(acceleration, u, p, t, x, read(placeholder, "start"))
        q, v, _ = self._split(x)
        if self.dependent is None:
            sample = ca.vertcat(self.sensors_at(q, v, t)[self.delayed],
                                self.sensor_rates_at(q, v, qddot, t)[self.delayed])
        else:       # under the actuator values now, the rate along the motion: the delayed signals read move too,
            # but not those held before the start (the numpy driver's backward difference: 0 at t - tau = 0)
            held = [ca.if_else(k > m, placeholder[count + d, last - m], 0.0) for d, m in enumerate(steps)]
            sample = ca.vertcat(*self.dependent.sample_function(self, n_inputs, p.size1())(
                x, first, ca.vertcat(*read(placeholder, "start")), ca.vertcat(*held), u, p, t))
        table = ca.horzcat(shifted, sample)
        calls = [0]

        def rate(stage: Any, state: Any) -> Any:
            calls[0] += 1
            if calls[0] == 1:
                return first
            return self.rate(acceleration, u, p, stage, state, read(table, "end" if calls[0] == 4 else "half"))[0]

        out = ca.vertcat(rk4_step(rate, t, x, h), ca.reshape(table, -1, 1))
        return ca.Function("step", [Y, u, h, p, t0, k], [out])

    def loop_signals(self, Y: Any, t: Any, p: Any) -> tuple:
        """``(y, u, u_demand)`` columns (one entry per loop) at the stored state ``Y`` (:attr:`state_size`) and
        time ``t`` [s] on symbols: each loop's signal now, its output (clipped to its saturation) and its
        unclipped demand (a delayed loop's from its sample ``steps`` columns back in the ring); ``p`` the
        whole parameter column, or ``None`` for the laws' own numbers.  Signals that respond to the actuators (cut
        forces) are read under the loops' and inputs' actuator values (no held values)."""
        import casadi as ca

        x = Y[:self.base + self.n_controller_states]
        ring = self._ring(Y) if self.delayed else None
        delayed = [ring[d, self.ring_columns - self.laws[k].steps] for d, k in enumerate(self.delayed)]
        now, outputs, demands, _, _ = self.close(ca.DM.zeros(len(self.actuators)), p, t, x, delayed)
        empty = ca.SX(0, 1)
        return (now, ca.vertcat(*outputs) if outputs else empty, ca.vertcat(*demands) if demands else empty)

    def signals(self) -> Callable[..., tuple]:
        """``(y, u)`` (rows, loops) of stored states ``Y`` (rows, :attr:`state_size`) at times ``t``
        (rows,): :meth:`loop_signals` with the laws' own numbers (:attr:`parameter_values`; as the numpy
        path's ``<loop>.y`` and ``<loop>.u``); ``evaluate(Y, t, demand=True)`` adds the unclipped demand
        (``<loop>.u_demand`` of a saturating loop)."""
        import casadi as ca

        Y, t = ca.SX.sym("y", self.state_size), ca.SX.sym("t")
        function = ca.Function("loop_signals", [Y, t], list(self.loop_signals(Y, t, None)))

        def evaluate(states: np.ndarray, times: np.ndarray, demand: bool = False) -> tuple:
            rows = len(times)
            if rows == 0 or not self.laws:
                out = tuple(np.zeros((rows, len(self.laws))) for _ in range(3))
            else:
                out = tuple(np.asarray(a).T for a in function.map(rows)(np.asarray(states, float).T,
                                                                        np.asarray(times, float)[None, :]))
            return out if demand else out[:2]

        return evaluate
