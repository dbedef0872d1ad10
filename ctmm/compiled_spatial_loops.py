"""Feedback loops of spatial models closed inside generated C (issues 13 and 14).

A :class:`~ctmm.control.controlled_model.ControlledModel` on a
:class:`~ctmm.spatial.model.SpatialModel` compiles through the loops of planar scenes,
:class:`ctmm.compiled_loops.ClosedLoops` (real-time loops at every RK4 stage, LTI controller states
integrated with the plant, delayed loops ``tau = m dt`` from a ring of samples and their rates in
the fold state, references and open-loop inputs with a symbolic form); this module gives it the
spatial plant on symbols:

* :class:`SpatialSymbols` -- sizes ``nq``, ``nv``, ``q_dot = G(q) v``
  (:func:`ctmm.compiled_spatial.position_rates`) and every sensor of :mod:`ctmm.spatial.ports` that is a
  smooth function of the state, from the body states of
  :meth:`~ctmm.spatial.body_forms.SpatialScene.terms` on casadi symbols (joint coordinates and rates,
  body angular velocities in world and body axes, x-y-z angles, positions and velocities of named
  points, rotation vectors through :func:`~ctmm.compiled_spherical_cut_law.symbolic_rotation_vector`); the
  loop signal's time derivative for the ring is its forward derivative along ``(G(q) v, v_dot)``, exact;
* :func:`loop_acceleration` -- ``v_dot(q, v, u, p, t)`` with ``u`` one scalar per port actuator (joint
  torques and forces, body forces at points and moments), through the one articulated sweep;
* :class:`CompiledControlledSpatial` -- the generated step, strides and blocks
  (:mod:`ctmm.generated_loop`) of the closed loop, compiled once and cached by :mod:`ctmm.codegen`;
  with ``numbers="inputs"`` the plant's numbers (:mod:`ctmm.compiled_spatial_parameters`) and the loops'
  gains, controllers and references are its input ``p`` (one library per structure, :mod:`ctmm.batch`).

Loads and driven joints may carry :mod:`ctmm.signals` with a symbolic form (Constant, Harmonic, Step,
SquareWave, Ramp): the sweep states them on its time symbol ``t``, the RK4 stage time
(:func:`~ctmm.compiled_spatial.spatial_compile_refusal` with ``time_signals=True``, as the generated RK4 without
loops).  The sensors are stated at the state ``(q, v)`` and the time ``t``: a sensor that moves with a driven
joint's time signal (a body outboard of it) is read as the numpy path reads it, a delayed loop's sampled sensor rate
with ``dy/dt`` (the DT-TMM scheme loops, :mod:`ctmm.compiled_spatial_scheme_loops`, state them at the state only and
refuse such a sensor by name).  The rotation vector ``"<body>.rotation_x|y|z"`` is
:func:`~ctmm.compiled_spherical_cut_law.symbolic_rotation_vector` of the body's rotation matrix.

Refused by name (:class:`~ctmm.errors.ModelError`): what
:func:`~ctmm.compiled_spatial.spatial_compile_refusal` refuses (user callables), and (by the caller) co-simulated
controllers.
"""
from __future__ import annotations

import os
import time as clock
from typing import Any, Mapping, Sequence

import numpy as np

from .articulated import articulated_sweep
from .compiled_loops import ClosedLoops
from .compiled_spatial import DEFAULT_ROWS, SPATIAL_FLAGS, position_rates, spatial_compile_refusal
from .compiled_spatial_parameters import (SpatialNumbers, parametrised_scene_terms, spatial_parameter_layout,
                                          spatial_parameter_vector, unparametrised_refusal)
from .compiled_spherical_cut_law import symbolic_rotation_vector
from .control.controlled_model import ControlledModel
from .errors import ModelError
from .generated_loop import BlockRunner, compiled_time_loop, run_blocks
from .ops import CASADI
from .spatial.body_forms import SpatialScene
from .spatial.model import SpatialModel
from .spatial.ports import SpatialPorts
from .symbolic_beam_points import spatial_deformed_point

__all__ = ["SpatialSymbols", "loop_acceleration", "CompiledControlledSpatial"]


class SpatialSymbols:
    """A spatial plant on casadi symbols for :class:`~ctmm.compiled_loops.ClosedLoops` (module docstring).

    Parameters
    ----------
    model : SpatialModel
    ports : SpatialPorts
        Its sensors and actuators.
    parameter_count : int
        Length of the plant's part of the parameter column ``p`` (0: its numbers are constants of the code).
    time_sensors : bool
        Whether :class:`~ctmm.compiled_loops.ClosedLoops` states the sensors at its time symbol too (the RK4 with
        loops: sensors that move with a driven joint's signals); ``False``: at the state only, such sensors refused.
    """

    def __init__(self, model: SpatialModel, ports: SpatialPorts, parameter_count: int = 0,
                 time_sensors: bool = False) -> None:
        self.model, self.ports, self.parameter_count = model, ports, parameter_count
        self.time_sensors = bool(time_sensors)
        self.n_positions, self.n_velocities = model.n_positions, model.n_velocities
        self._states: tuple[Any, Any, list] | None = None
        # driven joints with time signals: the body states on a time symbol, so a sensor that moves with them is seen
        symbolic = not spatial_compile_refusal(model, time_signals=True)       # (user callables: refused elsewhere)
        self._time: Any = _time_symbol() if symbolic and spatial_compile_refusal(model) else 0.0

    def position_rates(self, q: Any, v: Any) -> Any:
        """``q_dot = G(q) v`` on symbols."""
        return position_rates(self.model, q, v)

    def _body_states(self, q: Any, v: Any) -> list:
        if self._states is None or self._states[0] is not q or self._states[1] is not v:
            self._states = (q, v, SpatialScene(self.model).terms(CASADI, q, v, self._time)[2])
        return self._states[2]

    def sensor(self, name: str, q: Any, v: Any, t: Any = None) -> Any:
        """Sensor ``name`` of :mod:`ctmm.spatial.ports` as an expression of the symbols ``q`` (nq), ``v`` (nv) and,
        given, the time symbol ``t`` [s] (the driven joints' signals at ``t``).

        The one reading of a sensor on symbols: loops that state their sensors at their stage time
        (:attr:`time_sensors`) and outputs evaluated at known times (time-history sensitivities) pass ``t``; a
        sensor that does not move with time signals does not depend on it.  The rotation vector ``"<body>.rotation_x|y|z"`` is
        :func:`~ctmm.compiled_spherical_cut_law.symbolic_rotation_vector` of the body's rotation matrix.

        Raises
        ------
        ModelError
            Without ``t``, a sensor that moves with a driven joint's time signals (these loops state their
            sensors at the state only).
        """
        expression = self._sensor(name, q, v)
        if isinstance(self._time, float) or not _depends_on_time(expression, self._time):
            return expression
        if t is not None:
            import casadi as ca

            return ca.substitute(expression, self._time, t)
        driven = ", ".join(repr(joint.name) for joint in self.model.joints if joint.driven)
        raise ModelError(f"sensor {name!r} moves with the time signals of the driven joints {driven} of model "
                         f"{self.model.name!r}; generated loops (compiled=True, time-history sensitivities) "
                         "state their sensors (and the delayed loops' sensor rates) at the state only, so they "
                         "cannot close a loop on it; drive those joints with ctmm.signals.Constant, sense a body "
                         "inboard of them, or use compiled=False")

    def _sensor(self, name: str, q: Any, v: Any) -> Any:
        """Sensor ``name`` on symbols (:meth:`sensor`), the body states at :attr:`_time`."""
        import casadi as ca

        sensor = self.ports.resolve([name])[0]
        if sensor.kind == "q":
            return q[sensor.index]
        if sensor.kind == "v":
            return v[sensor.index]
        if sensor.kind in ("modal", "modal_v"):               # beam station sensors: linear in eta or eta_dot
            layout = self.model.modal[sensor.index]
            values = q[layout.position] if sensor.kind == "modal" else v[layout.velocity]
            return ca.dot(ca.DM(np.asarray(sensor.weights, float)), values)
        state = self._body_states(q, v)[sensor.index]
        rotation, omega, c = state.rotation, state.omega, sensor.component
        if sensor.kind == "rotation":                      # the one logarithm on symbols (numpy's, to pi)
            return symbolic_rotation_vector(rotation)[c]
        if sensor.kind == "omega":
            return omega[c]
        if sensor.kind == "omega_body":
            return ca.dot(rotation[:, c], omega)
        if sensor.kind == "angles":
            return [ca.atan2(-rotation[1, 2], rotation[2, 2]), ca.asin(ca.fmin(ca.fmax(rotation[0, 2], -1.0), 1.0)),
                    ca.atan2(-rotation[0, 1], rotation[0, 0])][c]
        layout = self.model.modal[sensor.index]
        if layout is None:
            arm = ca.mtimes(rotation, ca.DM(np.asarray(sensor.point, float)))
            relative = ca.DM.zeros(3, 1)
        else:                                                  # a beam or FE subsystem: the deformed point (numpy's)
            local, rate = spatial_deformed_point(self.model.bodies[sensor.index], sensor.point, q[layout.position],
                                                 v[layout.velocity])
            arm, relative = ca.mtimes(rotation, local), ca.mtimes(rotation, rate)
        if sensor.kind == "point":
            return state.origin[c] + arm[c]
        return state.velocity[c] + ca.cross(omega, arm)[c] + relative[c]


def _time_symbol() -> Any:
    """A casadi time symbol (the body states of :class:`SpatialSymbols` of a model with time signals)."""
    import casadi as ca

    return ca.SX.sym("t")


def _depends_on_time(expression: Any, time: Any) -> bool:
    """Whether a sensor ``expression`` (casadi or a number) depends on the symbol ``time``."""
    import casadi as ca

    return isinstance(expression, (ca.SX, ca.MX)) and ca.depends_on(expression, time)


def loop_acceleration(model: SpatialModel, ports: SpatialPorts, actuators: Sequence[str], layout: Sequence[Any] = ()
                      ) -> Any:
    """``v_dot = acceleration(q, v, u, p, t)`` (a ``casadi.Function``) of ``model`` with ``u`` one value per
    entry of ``actuators`` (port actuator names [N m, N]): joint actuators add to their joint's input, body
    actuators are forces at their points and moments, world axes (``force_body`` / ``moment_body``: the body's
    axes, of a beam its floating frame's); ``p`` the numbers of ``layout``
    (:func:`~ctmm.compiled_spatial_parameters.spatial_parameter_layout`; empty: the model's numbers in the code)."""
    import casadi as ca

    nq, nv = model.n_positions, model.n_velocities
    q, v, u = ca.SX.sym("q", nq), ca.SX.sym("v", nv), ca.SX.sym("u", len(actuators))
    p, t = ca.SX.sym("p", len(layout)), ca.SX.sym("t")
    widths = {name: joint.velocity_count for joint in model.joints for name in joint.inputs}
    inputs: dict[str, Any] = {}
    loads: dict[tuple[int, tuple], Any] = {}
    for k, name in enumerate(actuators):
        actuator = ports.actuators[ports.check_actuator(name)]
        if actuator.kind == "joint":
            size = widths[actuator.target]
            unit = np.zeros((size, 1))
            unit[actuator.component] = 1.0
            inputs[actuator.target] = inputs.get(actuator.target, ca.SX.zeros(size, 1)) + ca.DM(unit) * u[k]
        else:
            unit = np.zeros((6, 1))
            unit[actuator.component] = 1.0
            key = (int(actuator.target), tuple(actuator.point), actuator.axes)
            loads[key] = loads.get(key, ca.SX.zeros(6, 1)) + ca.DM(unit) * u[k]
    wrenches: dict[int, list] = {}
    for (body, point, axes), wrench in loads.items():
        entry = (np.asarray(point, float), wrench)
        wrenches.setdefault(body, []).append(entry if axes == "world" else entry + (axes,))
    scene = SpatialScene(model)
    bodies, joints, states = scene.terms(CASADI, q, v, t, inputs, wrenches)       # time signals on the symbol t
    if layout:                          # the numbers as inputs (ctmm.compiled_spatial_parameters)
        bodies, joints = parametrised_scene_terms(model, SpatialNumbers(layout, p), bodies, joints, states, q, v,
                                                  inputs, applied=list(wrenches))
    solution = articulated_sweep(CASADI, scene.tree, bodies, joints)
    return ca.Function("loop_acceleration", [q, v, u, p, t], [ca.vertcat(*scene.velocity_rates(solution))])


class CompiledControlledSpatial:
    """Generated and compiled RK4 of a controlled spatial model with its loops closed in the step.

    Parameters
    ----------
    controlled : ControlledModel
        A spatial plant (:func:`~ctmm.compiled_spatial.spatial_compile_refusal`) and its loops.
    dt : float
        Step [s] (each loop delay a whole multiple of it).
    references, inputs : mapping, optional
        ``{loop: r}``, ``{actuator: value}``: numbers or symbolic signals (constants of the code).
    store_every, rows : int
        Steps per stored state; stored states per block call.
    cache_dir, compiler, flags
        Of :func:`ctmm.codegen.shared_library` (``flags`` default :data:`ctmm.compiled_spatial.SPATIAL_FLAGS`).
    numbers : {"constants", "inputs"}
        The plant's numbers (:func:`~ctmm.compiled_spatial_parameters.spatial_parameter_layout`) and the loops'
        gains, controllers and references as constants of the code, or as the input ``p`` (one library per
        structure; :mod:`ctmm.batch`).

    Attributes
    ----------
    loops : ClosedLoops
        The loops on symbols (state ``[q, v, z, ring]``, :attr:`ClosedLoops.state_size`).
    actuators : tuple of str
        Port actuators of the kernel (those of the loops and of ``inputs``).
    compile_time_s : float
        Building the expressions, generating C and compiling (or loading) [s].
    parameters : ndarray
        ``p``: the plant's numbers, then the loops' (:attr:`ClosedLoops.parameter_values`); empty with
        ``numbers="constants"``.
    """

    def __init__(self, controlled: ControlledModel, dt: float, *, references: Mapping[str, Any] | None = None,
                 inputs: Mapping[str, Any] | None = None, store_every: int = 1, rows: int = DEFAULT_ROWS,
                 cache_dir: str | os.PathLike | None = None, compiler: str | None = None,
                 flags: Sequence[str] | None = None, numbers: str = "constants") -> None:
        if not isinstance(controlled, ControlledModel) or not isinstance(controlled.plant, SpatialModel):
            raise ModelError(f"CompiledControlledSpatial: controlled must be a ControlledModel of a spatial model, "
                             f"got {controlled!r}")
        model = controlled.plant
        reason = spatial_compile_refusal(model, time_signals=True)
        if reason:
            raise ModelError(f"compiled=True: {reason}")
        start = clock.perf_counter()
        from .model_description import describe   # what the step reads: a cached library loads without symbols

        description = describe((controlled, dt, references, inputs)) if numbers == "constants" else None
        ports = controlled.ports
        names = [name for loop in controlled.loops for name, _ in loop.actuator_terms] + list(inputs or {})
        for name in inputs or {}:
            ports.check_actuator(name, "inputs: actuator")
        self.controlled, self.model, self.store_every, self.rows = controlled, model, int(store_every), int(rows)
        self.actuators = tuple(dict.fromkeys(names))
        refusal = unparametrised_refusal(model, "CompiledControlledSpatial") if numbers == "inputs" else ""
        if refusal:
            raise ModelError(refusal)
        layout = spatial_parameter_layout(model) if numbers == "inputs" else []
        symbols = SpatialSymbols(model, ports, len(layout), time_sensors=True)
        self.loops = ClosedLoops(controlled, self.actuators, dt, references, inputs, symbols=symbols, numbers=numbers)
        self.parameters = np.concatenate([spatial_parameter_vector(model), self.loops.parameter_values]) \
            if layout else np.zeros(0)

        def build() -> tuple[Any, list]:
            acceleration = loop_acceleration(model, ports, self.actuators, layout)
            return self.loops.step(acceleration, len(self.actuators), len(layout)), []

        name = (f"spatial_loops_{model.n_bodies}b{model.n_positions}q{len(self.loops.laws)}l"
                f"{self.loops.n_controller_states}z{self.loops.ring_columns}r")
        options = {"cache_dir": cache_dir, "compiler": compiler,
                   "flags": SPATIAL_FLAGS if flags is None else tuple(flags)}
        loop = compiled_time_loop(build()[0], self.store_every, self.rows, name, **options) if description is None \
            else compiled_time_loop(build, self.store_every, self.rows, name,
                                    description=[("spatial loops", description)], **options)
        self._step, self._stride, self._blocks = loop.step, loop.stride, loop.blocks
        self.plain_step = loop.step             # step(y, u, h, p, t0, k): a failing interval replayed step by step
        self.compile_time_s = clock.perf_counter() - start

    def continue_run(self, state: np.ndarray, held: np.ndarray, dt: float, n_steps: int, first_step: int,
                     runner: BlockRunner | None = None) -> np.ndarray:
        """Stored states (rows, state size) of ``n_steps`` RK4 steps of ``dt`` [s] from the whole state ``state``
        at step ``first_step`` (time ``first_step dt``), the values ``held`` [SI] of :attr:`actuators` held over
        them (one sample interval of co-simulated controllers, :mod:`ctmm.compiled_cosim`)."""
        return run_blocks(self._blocks, self._stride, self._step, self.store_every, state[:, None], held, dt,
                          n_steps, 0.0, self.parameters[:, None], first_step=first_step, runner=runner)[0]

    def run_members(self, states: np.ndarray, parameters: np.ndarray, dt: float, n_steps: int) -> np.ndarray:
        """Stored states (B, rows, state size) of B members run together from ``t = 0``, one C call per block for
        all (``casadi.Function.map``, serial; :mod:`ctmm.batch_loops`): whole initial states ``states`` (state
        size, B), parameter columns ``parameters`` (parameters, B); each member's rows are those of :meth:`run` of
        it alone (a non-finite member does not stop the others)."""
        return run_blocks(self._blocks, self._stride, self._step, self.store_every, states,
                          np.zeros(len(self.actuators)), dt, n_steps, 0.0, parameters)

    def run(self, q0: np.ndarray, v0: np.ndarray, dt: float, n_steps: int) -> tuple[np.ndarray, np.ndarray]:
        """The initial state ``[q, v, z, ring]`` and the stored states (rows, state size) after each
        ``store_every`` steps and after the last of ``n_steps`` RK4 steps of ``dt`` [s] from ``t = 0``;
        stops after the first block holding a non-finite state."""
        first = self.loops.initial_state(np.asarray(q0, float), np.asarray(v0, float))
        states = run_blocks(self._blocks, self._stride, self._step, self.store_every, first[:, None],
                            np.zeros(len(self.actuators)), dt, n_steps, 0.0, self.parameters[:, None])[0]
        return first, states
