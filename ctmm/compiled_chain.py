"""Generated RK4 of 1-D lumped chains, with their loops closed inside the step (issues 12 and 13).

``ctmm.simulate(chain_or_controlled_chain, t_final, dt, method="rk4", compiled=True)`` runs here.
The rate is the chain's explicit form (:mod:`ctmm.chain_ode`: the one articulated sweep of the element
terms), which for the lumped families is affine in the motion and the inputs:
:func:`affine_form` reads it exactly from one batched sweep of unit
probes, ``a = Ax x + Av v + B u + a0 + sum_j L_j s_j(t)``, and :class:`CompiledChain` certifies it
against the Python sweep at random states, times and inputs before anything is generated (a family
whose terms were not affine would be refused, not silently linearised).  The generated functions are
those of every scene (:mod:`ctmm.generated_loop`: ``step``, ``stride``, ``block``), the matrices
sparse constants of the C (a banded mat-vec per stage), the load signals symbolic
(:func:`ctmm.signals.symbolic_signal`).

Loops (:class:`ChainLoops`, the laws of :class:`ctmm.compiled_loops.ClosedLoops` on the chain's
sensors): real-time loops at every RK4 stage, LTI controller states integrated with the chain, delayed
loops with ``delay = m dt`` from the ring of samples carried in the fold state (cubic Hermite at the
half steps, the initial value held before ``t = 0``), references and open-loop ``inputs`` numbers or
:mod:`ctmm.signals` signals with a symbolic form.  Sensors and actuators are those of
:class:`ctmm.control.chain_plant.ChainPorts` (positions, velocities, connector law forces; forces on
point elements and across connectors); a sensor is affine in the state, read exactly by unit probes.

Refused (:class:`~ctmm.errors.ModelError`, named): points without inertia, prescribed boundary motions,
co-simulated controllers, delays that are not whole multiples of ``dt``, user callables of time, other
methods than ``"rk4"``.
"""
from __future__ import annotations

import os
import time as _time
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
import scipy.sparse

from . import validation
from .chain_ode import ChainDynamics, chain_result
from .codegen import load_casadi
from .compiled_loops import ClosedLoops, LoopLaw, controller_realisation, delay_steps, symbolic_value
from .control.chain_plant import ChainPlant
from .control.planar_time import loop_unit
from .errors import ModelError, SimulationError
from .generated_loop import rk4_step_function, run_blocks, time_loop_functions
from .results import SimulationResult
from .signal_results import SignalSystem, signal_result
from .signals import Constant, signal_parameters, symbolic_signal

__all__ = ["AffineRates", "ChainLoops", "CompiledChain", "affine_form", "sensor_row", "simulate_chain_generated",
           "whole_steps"]

DEFAULT_ROWS = 64
"""Stored states per generated block call."""


@dataclass(frozen=True)
class AffineRates:
    """``a = Ax x_I + Av v_I + B u + a0 + sum_j L_j s_j(t)`` of a lumped chain
    (:func:`affine_form`): ``Ax`` [1/s^2], ``Av`` [1/s] (m, m), ``B`` (m, actuators)
    [1/kg], ``a0`` [m/s^2] (m,), ``loads`` ``[(L_j [1/kg] (m,), signal s_j [N])]``."""

    Ax: np.ndarray
    Av: np.ndarray
    B: np.ndarray
    a0: np.ndarray
    loads: list


def affine_form(dynamics: ChainDynamics, actuators: Sequence[Mapping[int, Mapping[str, float]]] = ()) -> AffineRates:
    """The accelerations as ``a = Ax x_I + Av v_I + B u + a0 + sum_j L_j s_j(t)`` (exact for the
    lumped families, whose terms are affine in the motion and the inputs): one batched sweep of
    unit probes, one sweep per actuator (``actuators``: unit inputs ``{position: {input: 1}}``) and
    one per time-varying load of the chain's elements (``s_j`` its signal; constant loads are in
    ``a0``).

    Raises
    ------
    ModelError
        Massless nodes (their condensation is not generated yet), a prescribed start or end
        motion (its rates enter the form in time).  (A connector with inertance couples every
        node: its form is exact but dense.)
    """
    chain = dynamics.chain
    if dynamics.index_Q.size:
        names = ", ".join(dynamics.node_name(k) for k in dynamics.index_Q)
        raise ModelError(f"chain {chain.name!r}: points without inertia ({names}) are condensed in Python only; "
                         "generated kernels need a mass at every moving point (or use compiled=False)")
    for boundary in (chain.start, chain.end):
        if hasattr(boundary, "displacement"):
            raise ModelError(f"chain {chain.name!r}: the prescribed motion of {boundary.name!r} is not generated "
                             "yet (use compiled=False)")
    I, n = dynamics.index_I, dynamics.tree.n_nodes
    m = I.size
    x, v = np.zeros((1 + 2 * m, n)), np.zeros((1 + 2 * m, n))
    x[1 + np.arange(m), I] = 1.0
    v[1 + m + np.arange(m), I] = 1.0
    dynamics.hold(0.0, x, v)
    wall = dynamics.wall_motion(0.0)
    constant: dict[int, dict[str, float]] = {}
    for position, name, signal, _ in dynamics.loads:
        if isinstance(signal, Constant) and signal.value != 0.0:
            constant.setdefault(position, {})[name] = signal.value
    probes = dynamics.forces(x, v, 0.0, constant, wall)[:, I]
    base = probes[0]
    Ax, Av = (probes[1:1 + m] - base).T, (probes[1 + m:] - base).T

    def column(inputs: Mapping[int, Mapping[str, float]]) -> np.ndarray:
        both = {position: dict(values) for position, values in constant.items()}
        for position, values in inputs.items():
            slot = both.setdefault(position, {})
            for name, value in values.items():
                slot[name] = slot.get(name, 0.0) + value
        return dynamics.forces(x[:1], v[:1], 0.0, both, wall)[0, I] - base

    B = np.column_stack([column(unit) for unit in actuators]) if len(actuators) else np.zeros((m, 0))
    loads = [(column({position: {name: 1.0}}), signal) for position, name, signal, _ in dynamics.loads
             if not isinstance(signal, Constant)]
    return AffineRates(Ax, Av, B, base, loads)



def sensor_row(ports: Any, terms: Sequence[tuple[str, float]], size: int) -> tuple[np.ndarray, float]:
    """``(row, offset)`` of the weighted sensed signal ``y = row [q; v] + offset`` of a chain (``terms``
    ``[(sensor, weight)]`` of :class:`ctmm.control.chain_plant.ChainPorts`; ``size = 2 m``): unit probes, exact
    because the chain's sensors are affine in its state."""
    names = [name for name, _ in terms]
    weights = np.array([w for _, w in terms], dtype=float)
    sensors = ports.resolve(names)
    half = size // 2

    def value(state: np.ndarray) -> float:
        return float(weights @ ports.values(sensors, state[:half], state[half:], 0.0))

    zero = np.zeros(size)
    offset = value(zero)
    row = np.zeros(size)
    for i in range(size):
        zero[i] = 1.0
        row[i] = value(zero) - offset
        zero[i] = 0.0
    return row, offset


class ChainLoops(ClosedLoops):
    """The loops of a controlled chain on casadi symbols: the laws, ring and step of
    :class:`~ctmm.compiled_loops.ClosedLoops` with the chain's affine sensors.

    Parameters
    ----------
    plant : ChainPlant
        The chain's plant (its ports resolve the sensors and actuators).
    loops : sequence of Feedback
    actuators : sequence of str
        The actuator inputs ``u`` of the generated kernel, in order.
    dt : float or None
        Step [s]; required with delayed loops (each delay a whole multiple of it).
    references, inputs : mapping, optional
        ``{loop: r}`` [sensed unit] and ``{actuator: value}`` [N], numbers or symbolic signals.
    """

    def __init__(self, plant: ChainPlant, loops: Sequence[Any], actuators: Sequence[str], dt: float | None = None,
                 references: Mapping[str, Any] | None = None, inputs: Mapping[str, Any] | None = None) -> None:
        import casadi as ca

        ports = plant.ports
        references = dict(references or {})
        names = [loop.name for loop in loops]
        for name in references:
            if name not in names:
                raise ModelError(f"references[{name!r}]: not a loop; loops: {', '.join(names) or '(none)'}")
        self.actuators = tuple(actuators)
        self.inputs = [(self.actuators.index(name), symbolic_value(f"inputs[{name!r}]", value))
                       for name, value in dict(inputs or {}).items()]
        self.channels = []
        laws = []
        for loop in loops:
            A, B, C, D = controller_realisation(loop)
            reference = symbolic_value(f"references[{loop.name!r}]", references.get(loop.name, 0.0))
            laws.append(LoopLaw(loop.name, tuple(loop.terms), tuple(loop.actuator_terms), A, B, C, D,
                                float(loop.delay), delay_steps(loop.name, loop.delay, dt), reference,
                                loop.saturation))
        self.laws = tuple(laws)
        self.n = n = plant.n_positions
        self.nq = self.nv = n
        self.base = 2 * n                       # [q, v], then z and the ring (the ClosedLoops layout)
        self.position_rates = lambda q, v: v
        self.plant_parameter_count = 0          # the chain's numbers and the loops' are constants of the code
        self.parameter_layout = []
        self.parameter_values = np.zeros(0)
        self.n_controller_states = sum(law.A.shape[0] for law in laws)
        self.delayed = [k for k, law in enumerate(laws) if law.steps]
        self.ring_columns = max((law.steps for law in laws), default=0) + 1 if self.delayed else 0
        self.state_size = 2 * n + self.n_controller_states + 2 * len(self.delayed) * self.ring_columns
        q, v, a = (ca.SX.sym(label, n) for label in ("q", "v", "a"))
        rows = [sensor_row(ports, law.sensors, 2 * n) for law in laws]
        y = ca.vertcat(*[ca.mtimes(ca.DM(row[None, :]), ca.vertcat(q, v)) + offset for row, offset in rows]) \
            if laws else ca.SX(0, 1)
        self.sensors = ca.Function("loop_sensors", [q, v], [y])
        rates = ca.jtimes(y, ca.vertcat(q, v), ca.vertcat(v, a)) if laws else ca.SX(0, 1)
        self.sensor_rates = ca.Function("loop_sensor_rates", [q, v, a], [rates])
        weights = np.zeros((len(self.actuators), len(laws)))
        for k, law in enumerate(laws):
            for actuator, w in law.actuators:
                weights[self.actuators.index(actuator), k] += float(w)
        self.weights = weights


class CompiledChain:
    """Generated and compiled RK4 time loop of one lumped chain, with its loops (module docstring).

    Parameters
    ----------
    system : Chain or ControlledChain
        The chain (a controlled chain's loops are closed inside the step).
    dt : float, optional
        Step [s] the delayed loops' rings are built for.
    store_every : int
        Steps per stored state.
    rows : int
        Stored states per generated block (one C call).
    references, inputs : mapping, optional
        ``{loop: r}`` and ``{actuator: value}`` (numbers or symbolic :mod:`ctmm.signals` signals).
    cache_dir, compiler
        Of :func:`ctmm.codegen.shared_library`.

    Attributes
    ----------
    plant : ChainPlant
    loops : ChainLoops or None
        ``None`` for a chain without loops and inputs.
    state_size : int
        ``2 m`` (``m`` moving masses), with loops ``[x, v, z, ring]``.
    compile_time_s : float
        Wall time of forming, generating, compiling (or loading) [s].
    """

    def __init__(self, system: Any, *, dt: float | None = None, store_every: int = 1, rows: int = DEFAULT_ROWS,
                 references: Mapping[str, Any] | None = None, inputs: Mapping[str, Any] | None = None,
                 cache_dir: str | os.PathLike | None = None, compiler: str | None = None) -> None:
        import casadi as ca

        start = _time.perf_counter()
        self.plant = plant = ChainPlant(system)
        self.store_every = validation.integer("store_every", store_every, minimum=1)
        self.rows = validation.integer("rows", rows, minimum=1)
        loops = tuple(getattr(system, "loops", ()))
        for loop in loops:
            for name, _ in loop.terms:
                plant.ports.check_sensor(name, f"sensor of loop {loop.name!r}")
            for name, _ in loop.actuator_terms:
                plant.ports.check_actuator(name, f"actuator of loop {loop.name!r}")
        for name in inputs or {}:
            plant.ports.check_actuator(name, "input")
        self.actuators = tuple(dict.fromkeys([name for loop in loops for name, _ in loop.actuator_terms]
                                             + list(inputs or {})))
        dynamics: ChainDynamics = plant.dynamics
        units = [plant.ports.inputs({name: 1.0}) for name in self.actuators]
        form = affine_form(dynamics, units)
        m = plant.n_positions
        self._certify(dynamics, form, units)
        q, v = ca.MX.sym("q", m), ca.MX.sym("v", m)
        u, p, t = ca.MX.sym("u", len(units)), ca.MX.sym("p", 0), ca.MX.sym("t")
        stiffness = ca.DM(scipy.sparse.csc_matrix(np.hstack([form.Ax, form.Av])))
        acceleration = ca.mtimes(stiffness, ca.vertcat(q, v))
        if units:
            acceleration += ca.mtimes(ca.DM(scipy.sparse.csc_matrix(form.B)), u)
        for column, signal in form.loads:
            parameters = signal_parameters(signal)
            if parameters is None:
                raise ModelError(f"chain {plant.chain.name!r}: a load signal {signal!r} is a Python callable of time, "
                                 "which generated kernels cannot evaluate; give a ctmm.signals Constant, Harmonic, "
                                 "Step or SquareWave, or use compiled=False")
            acceleration += ca.DM(column) * symbolic_signal(type(signal), t, parameters)
        acceleration += ca.DM(form.a0)
        accelerations = ca.Function("acceleration", [q, v, u, p, t], [acceleration])
        self.loops = None if not (loops or inputs) else ChainLoops(plant, loops, self.actuators, dt, references,
                                                                    inputs)
        if self.loops is None:
            y = ca.MX.sym("y", 2 * m)
            step = rk4_step_function(ca.Function("rate", [y, u, p, t], [ca.vertcat(y[m:], accelerations(
                y[:m], y[m:], u, p, t))]))
            self.state_size = 2 * m
        else:
            step = self.loops.step(accelerations, len(units), 0)
            self.state_size = self.loops.state_size
        stride, sizes, blocks = time_loop_functions(step, self.store_every, self.rows)
        name = f"chain_{m}m" + (f"{len(self.loops.laws)}l" if self.loops else "")
        loaded = load_casadi([step, stride, *blocks], name, cache_dir=cache_dir, compiler=compiler)
        self._step, self._stride = loaded[:2]
        self._blocks = list(zip(sizes, loaded[2:]))
        self.compile_time_s = _time.perf_counter() - start

    def _certify(self, dynamics: ChainDynamics, form: Any, units: Sequence[Mapping]) -> None:
        """The affine form equals the Python sweep at random states, times and inputs (1e-10 relative)."""
        rng = np.random.default_rng(12)
        m = self.plant.n_positions
        for trial in range(2):
            y = rng.standard_normal(2 * m) * 0.01
            t = float(rng.uniform(0.0, 3.0))
            u = rng.standard_normal(len(units))
            extra: dict[int, dict[str, float]] = {}
            for value, unit in zip(u, units):
                for position, slot in unit.items():
                    for name, one in slot.items():
                        extra.setdefault(position, {})
                        extra[position][name] = extra[position].get(name, 0.0) + value * one
            python = dynamics.swept_rate(t, y, extra)[m:]
            affine = form.Ax @ y[:m] + form.Av @ y[m:] + form.B @ u + form.a0 + \
                sum((column * float(signal(t)) for column, signal in form.loads), np.zeros(m))
            scale = max(1.0, float(np.max(np.abs(python))))
            if not np.all(np.abs(python - affine) <= 1e-10 * scale):
                raise ModelError(f"chain {self.plant.chain.name!r}: its rates are not affine in the state and the "
                                 "inputs (an element family with non-linear terms); generated kernels of chains read "
                                 "the affine form only: use compiled=False")

    def run(self, state: np.ndarray, dt: float, n_steps: int) -> np.ndarray:
        """Stored states (rows, :attr:`state_size`) after each ``store_every`` steps and the last, from ``state``
        at ``t = 0`` (stops after the first block holding a non-finite state)."""
        held = np.zeros(len(self.actuators))
        return run_blocks(self._blocks, self._stride, self._step, self.store_every, np.asarray(state, float)[:, None],
                          held, dt, n_steps, 0.0, np.zeros((0, 1)))[0]


def whole_steps(t_final: float, dt: float) -> tuple[float, float, int]:
    """``(t_final, dt, n_steps)`` checked: positive, ``t_final`` [s] a whole number (>= 1) of steps ``dt`` [s]."""
    t_final, dt = validation.positive("t_final", t_final), validation.positive("dt", dt)
    n_steps = int(round(t_final / dt))
    if n_steps < 1 or abs(n_steps * dt - t_final) > 1e-9 * max(1.0, t_final):
        raise ModelError(f"t_final = {t_final!r} s must be a whole number of steps dt = {dt!r} s (>= 1)")
    validation.step_count(t_final, 0.0, dt)
    return t_final, dt, n_steps


def simulate_chain_generated(system: Any, t_final: float, dt: float, *, x0: Mapping[str, float] | None = None,
                             v0: Mapping[str, float] | None = None, inputs: Mapping[str, Any] | None = None,
                             references: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                             store_every: int = 1, divergence_bound: float | None = None,
                             cache_dir: str | os.PathLike | None = None,
                             chain: CompiledChain | None = None) -> SimulationResult:
    """Fixed-step RK4 of a chain (with its loops) in generated C; the result of the Python path.

    Parameters
    ----------
    system : Chain or ControlledChain
    t_final, dt : float
        End time and step [s] (``t_final`` a whole multiple of ``dt``, and each loop delay too).
    x0, v0 : mapping, optional
        Initial positions [m] / velocities [m/s] by element name.
    inputs, references : mapping, optional
        ``{actuator: number or signal}`` [N], ``{loop: number or signal}`` [sensed unit].
    outputs : sequence of str
        Extra signal names (every chain signal is stored).
    store_every : int
        Keep every ``store_every``-th step (the last one always).
    divergence_bound : float, optional
        As in :func:`ctmm.chain_ode.simulate_chain_ode` (checked on the stored rows after the run).
    cache_dir : path, optional
        Of :func:`ctmm.codegen.shared_library`.
    chain : CompiledChain, optional
        A compiled chain of ``system`` with this step, ``store_every``, inputs and references, to reuse.

    Returns
    -------
    SimulationResult
        As :func:`ctmm.chain_ode.simulate_chain_ode` without loops (point arrays), as the loop driver with
        them (named signals, ``"<loop>.y"``, ``"<loop>.u"``); method label ``"rk4-generated"``,
        ``info["compile_time_s"]``.

    Raises
    ------
    ModelError
        What the generated kernel cannot do (named), bad arguments, no compiler.
    SimulationError
        Divergence or non-finite states, with ``partial_result``.
    """
    t_final, dt, n_steps = whole_steps(t_final, dt)
    if chain is None:
        chain = CompiledChain(system, dt=dt, store_every=store_every, references=references, inputs=inputs,
                              cache_dir=cache_dir)
    elif not isinstance(chain, CompiledChain) or chain.store_every != store_every:
        raise ModelError(f"chain must be a CompiledChain of this system with store_every={store_every!r}, got {chain!r}")
    plant = chain.plant
    q0, w0 = plant.start(x0, v0)
    m = plant.n_positions
    first = np.concatenate([q0, w0]) if chain.loops is None else chain.loops.initial_state(q0, w0)
    started = _time.perf_counter()
    states = chain.run(first, dt, n_steps)
    wall = _time.perf_counter() - started
    every = chain.store_every
    steps = np.array([k for k in range(1, n_steps + 1) if k % every == 0 or k == n_steps])[:len(states)]
    times = np.concatenate([[0.0], steps * dt])
    states = np.vstack([first[None], states])
    info = {"dt": dt, "method": "rk4-generated", "path": "generated", "compile_time_s": chain.compile_time_s,
            "wall_time_s": wall, "n_steps": n_steps}
    guard = plant.guard(q0, divergence_bound)

    def result(rows: int) -> SimulationResult:
        return _result(system, chain, times[:rows], states[:rows], outputs, info)

    for k in range(len(times)):
        try:
            guard(float(times[k]), states[k, :2 * m], dt, "rk4-generated")
            if not np.all(np.isfinite(states[k])):
                raise SimulationError(f"non-finite controller state or delay history at t = {times[k]:.6g} s",
                                      time=float(times[k]), element=plant.chain.name)
        except SimulationError as exc:
            exc.partial_result = result(k)
            raise
    return result(len(times))


def _result(system: Any, chain: CompiledChain, times: np.ndarray, states: np.ndarray, outputs: Sequence[str],
            info: dict) -> SimulationResult:
    plant, m = chain.plant, chain.plant.n_positions
    if chain.loops is None:
        return chain_result(plant.dynamics, list(times), list(states), "rk4-generated", dict(info))
    loops = chain.loops
    y, u = loops.signals()(states, times)
    rows = []
    for k, t in enumerate(times):
        values: dict[str, float] = {}
        for j, law in enumerate(loops.laws):
            for name, weight in law.actuators:
                values[name] = values.get(name, 0.0) + weight * float(u[k, j])
        for index, signal in loops.inputs:
            name = loops.actuators[index]
            values[name] = values.get(name, 0.0) + float(signal(float(t)))
        rows.append(plant.ports.inputs(values) if values else None)
    signals, units = plant.signals(times, states[:, :m], states[:, m:2 * m], outputs, inputs=rows)
    for j, law in enumerate(loops.laws):
        loop = system.loop(law.name)
        signals[f"{law.name}.y"], signals[f"{law.name}.u"] = y[:, j], u[:, j]
        units[f"{law.name}.y"] = loop_unit(plant.ports, loop, "y")
        units[f"{law.name}.u"] = loop_unit(plant.ports, loop, "u")
    info = {**info, "loops": {law.name: ("real-time" if law.steps == 0 else "history") for law in loops.laws}}
    return signal_result(SignalSystem(system, units, list(getattr(system, "loops", ()))), times, signals,
                         "rk4-generated", info)
