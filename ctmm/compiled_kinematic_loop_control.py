"""Generated RK4 of kinematic loop models with feedback loops, inputs and co-simulated controllers (issues 13 x 16).

``ctmm.simulate(with_feedback(loop_model, loops), ..., compiled=True)`` (or the model alone with ``inputs=``) runs
here: the time loop of :func:`ctmm.control.planar_time.simulate_closed_loop` on a
:class:`~ctmm.planar.loop_plant.KinematicLoopPlant` with the loops and the closed-loop accelerations in generated C.
Nothing of the loop engine is new:

* the closed-loop accelerations with the actuator values ``u`` applied are
  :func:`ctmm.compiled_kinematic_loops.symbolic_closed_loop` (the cut unknowns solved from ``G lambda = ...`` with
  the loads of the tree's actuators and of the cut torques ``"<cut>.torque"`` included, as
  :meth:`KinematicLoopModel.solve` with ``inputs``);
* the loops are :class:`ctmm.compiled_loops.ClosedLoops` on :class:`KinematicLoopSymbols` (the tree's sensors by
  :func:`ctmm.compiled_planar_sensors.sensor_expression`, the cut sensors ``"<cut>.angle"``, ``"<cut>.rate"`` and, for a cut
  whose torque is constant, ``"<cut>.moment"``; the cut forces ``"<cut>.force_x|y"`` under the kernel's actuator
  values, :meth:`KinematicLoopSymbols.input_sensor_map`, closed by
  :class:`~ctmm.compiled_input_sensors.InputDependentSensors`: a real-time loop on one solved as an algebraic loop, a
  delayed one sampled with its exact rate): real-time loops at every RK4 stage, LTI controller states integrated
  with the plant, delayed loops (``tau = m dt``) from the ring of samples in the state, saturation, references and
  open-loop inputs with a symbolic form; its step is :meth:`ClosedLoops.step`.

As the numpy driver (:class:`ctmm.loop_integration.StepProjection` after every RK4 step), the state is projected onto
the cut joints after every step, before the loops' delay ring and the co-simulated controllers read it: the
projection of the generated RK4 of the model alone on symbols
(:func:`ctmm.compiled_kinematic_loops.symbolic_projection`,
:func:`ctmm.compiled_spatial_kinematic_loops.symbolic_spatial_projection`; ``projection=False``: Baumgarte alone, as
the numpy driver's ``projection=False``).  The generated state is ``[q, qdot, z, ring, condition, residual]``:
``condition`` the largest Frobenius condition of the boundary compliance ``G``
(:func:`ctmm.loop_integration.compliance_condition`) at every step's start and end state so far (``G`` depends on
``q`` only; the numpy path checks every stage, so a singular configuration reached only inside a step is found one
step later here), ``residual`` the largest ``max |Phi|`` after a projection so far.  A non-finite stored row, a
condition above :data:`~ctmm.loop_integration.CONDITION_LIMIT` or a residual above
:data:`~ctmm.loop_integration.PROJECTION_TOLERANCE` raises :class:`~ctmm.errors.SimulationError` with the time, the
first cut joint and the partial result.  The stored signals are the numpy path's
(:meth:`KinematicLoopPlant.signals` on the stored rows with their actuator values, ``"<loop>.y"``, ``"<loop>.u"``):
coordinates, outputs, cut forces, ``"drift"``, ``"drift_rate"``.

Spatial kinematic loop models (:class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel`, the loop driver's run
of :mod:`ctmm.spatial_loop_time`) compile the same way: the closed-loop velocity rates
:func:`ctmm.compiled_spatial_kinematic_loops.symbolic_spatial_closed_loop` (the tree's port actuators and the cuts'
``"<cut>.torque"`` / ``"<cut>.force"`` applied with the cut loads), the sensors
:class:`ctmm.compiled_spatial_loop_symbols.SpatialKinematicLoopSymbols` (the cut forces ``"<cut>.force_x|y|z"`` of
every cut kind under the kernel's actuator values, closed by
:class:`~ctmm.compiled_input_sensors.InputDependentSensors` as the planar ones), the stored signals
:meth:`ctmm.spatial.closed_loop_plant.SpatialLoopPlant.signals`.  A tree with driven joints
(signals with a symbolic form) runs too: the sensors read the time as well as the state (the tree's sensors outboard
of a drive, the cut coordinates and law moments at the time symbol; a delayed loop's sampled sensor rate adds
``dy/dt``), as the numpy driver reads them at each stage time.

Co-simulated controllers (:func:`simulate_cosimulated_kinematic_loops_generated`): the same kernel with the
controllers' outputs as held inputs ``u``, run one sample interval per call by
:func:`ctmm.compiled_cosim.simulate_cosimulated_generated` (:meth:`CompiledKinematicLoopControl.continue_run`), the
stored cut forces with each row's held values (:meth:`CompiledKinematicLoopControl.applied_inputs`).

Refused (:class:`~ctmm.errors.ModelError`, by name): models :func:`kinematic_loop_compile_refusal` refuses, methods
other than ``"rk4"``, a ``"<cut>.moment"`` sensor of a cut with a time-varying torque, loops on cut forces beside
co-simulated controllers, what :class:`~ctmm.compiled_input_sensors.InputDependentSensors` refuses (a saturating
real-time loop on a cut force, an algebraic loop singular at the start, a neutral delayed one) and what
:class:`ClosedLoops` refuses (non-integer delays, references and inputs without a symbolic form).  A spherical cut
with a law senses its law's moment ``"<cut>.moment_x|y|z"`` (world axes, a function of the state:
:func:`ctmm.compiled_spherical_cut_law.symbolic_spherical_law_moment`); the spatial cut forces ``"<cut>.force_x|y|z"``
are loop sensors as the planar ones (a real-time loop on one solved as an algebraic loop, a delayed one sampled with
its exact rate; the same refusals), not in the generated DT-TMM schemes with loops
(:mod:`ctmm.compiled_spatial_loop_scheme_control`, refused by name there).
"""
from __future__ import annotations

import os
import time as _time
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .codegen import STRAIGHT_LINE_FLAGS
from .compiled_control import add_loop_signals
from .compiled_input_sensors import affine_sensor_map
from .compiled_kinematic_loops import (cut_rows, kinematic_loop_compile_refusal, symbolic_closed_loop,
                                       symbolic_projection, symbolic_relative_angles, symbolic_time_signal)
from .compiled_loops import ClosedLoops
from .compiled_planar_sensors import SymbolicKinematics, sensor_expression
from .compiled_parameters import parameter_vector
from .compiled_scene import DEFAULT_ROWS
from .compiled_spatial_loop_symbols import SpatialKinematicLoopSymbols
from .compiled_spherical_cut_law import rotation_limit_note
from .control.controlled_model import ControlledModel
from .errors import ModelError, SimulationError
from .generated_loop import BlockRunner, compiled_time_loop, run_blocks
from .loop_integration import (CONDITION_LIMIT, PROJECTION_TOLERANCE, check_consistent, compliance_condition,
                               projection_failure, singular_compliance)
from .planar.closed_loops import KinematicLoopModel
from .planar.integrate import check_store_every, step_total
from .control.plants import plant_of
from .spatial.closed_loops import SpatialKinematicLoopModel
from .planar.ports import PlanarPorts
from .signal_results import SignalSystem, signal_result
from .signals import Constant, as_signal

__all__ = ["CompiledKinematicLoopControl", "KinematicLoopSymbols", "applied_loop_inputs",
           "simulate_controlled_kinematic_loops_generated",
           "simulate_cosimulated_kinematic_loops_generated", "simulate_generated_driver_run"]


class KinematicLoopSymbols:
    """A planar kinematic loop model on symbols for :class:`ctmm.compiled_loops.ClosedLoops` (module docstring).

    Parameters
    ----------
    model : KinematicLoopModel
    ports : KinematicLoopPorts
        The ports of the controlled model (the tree's and the cut joints').
    """

    def __init__(self, model: KinematicLoopModel, ports: Any, closed: Any = None, parameters: Any = None) -> None:
        self.model, self.ports, self.closed = model, ports, closed
        self.parameters = parameter_vector(model.tree) if parameters is None else np.asarray(parameters, float)
        self.tree_ports = PlanarPorts(model.tree)
        self.n_positions = self.n_velocities = model.tree.n_coordinates
        self.cut_index = {cut.name: k for k, cut in enumerate(model.cuts)}
        self.input_dependent = frozenset(f"{cut.name}.{part}" for cut in model.cuts for part in ("force_x", "force_y")
                                         ) if closed is not None else frozenset()
        self._kinematics: tuple[Any, Any, SymbolicKinematics, list] | None = None

    def input_sensor_map(self, names: Sequence[str], n_actuators: int) -> Any:
        """``(q, v, p, t) -> (F_0, J)``: the cut forces ``names`` (``"<cut>.force_x|y"`` [N], on the child point,
        global axes, as :meth:`KinematicLoopModel.solve`) ``F = F_0 + J w`` under the kernel's actuator values ``w``
        (``n_actuators``, the ``closed`` accelerations' inputs), exactly: the cut unknowns are affine in ``w`` (the
        applied loads are linear in ``w``, the tree's accelerations affine in the loads, the boundary compliance
        ``G`` a function of ``q`` alone), so ``J`` is the Jacobian at ``w = 0``.
        """
        import casadi as ca

        n = self.model.tree.n_coordinates
        q, v, w = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("w", n_actuators)
        p, t = ca.SX.sym("p", self.parameters.size), ca.SX.sym("t")
        forces, rows = self.closed(q, v, w, p, t)[2], cut_rows(self.model)
        F = ca.vertcat(*[forces[rows[self.cut_index[name.rpartition(".")[0]]] + name.endswith("force_y")]
                         for name in names])
        return affine_sensor_map(F, w, [q, v, p, t])

    def position_rates(self, q: Any, v: Any) -> Any:
        """``qdot = v``."""
        return v

    def sensor(self, name: str, q: Any, v: Any) -> Any:
        """Sensor ``name`` as an expression of the symbols ``q``, ``v``.

        Raises
        ------
        ModelError
            ``"<cut>.moment"`` of a cut whose torque varies in time (the loop sensors are functions of the state).
        """
        if self._kinematics is None or self._kinematics[0] is not q or self._kinematics[1] is not v:
            kinematics = SymbolicKinematics(self.model.tree, q, v)
            self._kinematics = (q, v, kinematics, symbolic_relative_angles(self.model, kinematics))
        kinematics, angles = self._kinematics[2], self._kinematics[3]
        cut_name, _, part = name.rpartition(".")
        if cut_name in self.cut_index and part in ("force_x", "force_y"):     # (input_sensor_map, with closed)
            raise ModelError(f"sensor {name!r}: a cut force responds to the actuators at once, not a function of the "
                             "state alone; read it with the kernel's actuator values (input_sensor_map)")
        if cut_name not in self.cut_index or part not in ("angle", "rate", "moment"):
            return sensor_expression(self.tree_ports, name, kinematics)
        k = self.cut_index[cut_name]
        angle, rate = angles[k]
        if part != "moment":
            return angle if part == "angle" else rate
        cut = self.model.cuts[k]
        if cut.torque is not None and not isinstance(cut.torque, Constant):
            raise ModelError(f"sensor {name!r}: cut joint {cut_name!r} has a time-varying torque {cut.torque!r}, so "
                             "its moment is not a function of the state, as the generated loop sensors are; sense "
                             f"{cut_name}.angle / {cut_name}.rate, or use compiled=None")
        moment = 0.0 if cut.torque is None else symbolic_time_signal(cut.torque, 0.0)
        if cut.moment_law is not None:
            moment = moment - cut.moment_law.force(angle - cut.rest_angle, rate)
        return moment


def _step(loops: ClosedLoops, closed: Any, project: Any, nq: int, nv: int, n_inputs: int, n_parameters: int) -> Any:
    """``step(Y, u, h, p, t0, k)`` on ``[q, v, z, ring, condition, residual]``: :meth:`ClosedLoops.step` on the
    closed-loop accelerations, then ``project`` (``([q, v], t) -> ([q, v], max |Phi|)``, ``None``: none) of ``q, v``
    at the step's end; the condition of ``G`` at the step's start and end (projected) and the residual after the
    projection carried as the largest so far."""
    import casadi as ca

    q, v, u = ca.MX.sym("q", nq), ca.MX.sym("v", nv), ca.MX.sym("u", n_inputs)
    p, t = ca.MX.sym("p", n_parameters), ca.MX.sym("t")
    # calls of the one ``closed`` (MX): the generated C holds its sweep once, not once per function
    acceleration = ca.Function("acceleration", [q, v, u, p, t], [closed(q, v, u, p, t)[0]])
    condition = ca.Function("condition", [q, v, p, t], [closed(q, v, ca.MX.zeros(n_inputs), p, t)[1]])
    inner = loops.step(acceleration, n_inputs, n_parameters)
    size = loops.state_size
    Y, held, h = ca.MX.sym("y", size + 2), ca.MX.sym("u", n_inputs), ca.MX.sym("h")
    P, t0, index = ca.MX.sym("p", n_parameters), ca.MX.sym("t0"), ca.MX.sym("k")
    after = inner(Y[:size], held, h, P, t0, index)
    start = t0 + index * h
    residual = Y[size + 1]
    if project is not None:
        moved, after_residual = project(after[:nq + nv], start + h)
        after = ca.vertcat(moved, after[nq + nv:])
        residual = ca.fmax(residual, after_residual)
    worst = ca.fmax(Y[size], ca.fmax(condition(Y[:nq], Y[nq:nq + nv], P, start),
                                     condition(after[:nq], after[nq:nq + nv], P, start + h)))
    return ca.Function("step", [Y, held, h, P, t0, index], [ca.vertcat(after, worst, residual)])


class CompiledKinematicLoopControl:
    """The generated RK4 of a controlled planar kinematic loop model (module docstring).

    Parameters
    ----------
    controlled : ControlledModel
        A planar or spatial kinematic loop model (compilable: :func:`kinematic_loop_compile_refusal`,
        :func:`ctmm.compiled_spatial_kinematic_loops.spatial_kinematic_loop_compile_refusal`) with its loops.
    dt : float
        Step [s] (every loop delay a whole multiple of it).
    inputs, references : mapping, optional
        Open-loop actuator values [SI] and loop references: numbers or :mod:`ctmm.signals` signals.
    held : sequence of str
        Actuators driven by held values (co-simulated controllers' outputs): inputs ``u`` of the kernel too.
    store_every, rows, cache_dir
        Steps per stored state, stored states per generated block, :func:`ctmm.codegen.shared_library` folder.
    projection : bool
        Project ``q, v`` onto the cut joints after every step (the numpy driver's default); ``False``: Baumgarte
        alone.
    iterations : int
        Gauss-Newton steps of the projection (as :class:`~ctmm.loop_integration.StepProjection`: 3).
    start : (q, v), optional
        The start state: a loop singular or neutral there is refused before anything is compiled; its loop state is
        :attr:`start`.

    Attributes
    ----------
    actuators : tuple of str
        The kernel's actuators (the loops', the inputs', the held ones), the order of ``u``.
    loops : ClosedLoops
    compile_time_s : float
    start : ndarray or None
        :meth:`ClosedLoops.initial_state` at the ``start`` state.
    """

    def __init__(self, controlled: ControlledModel, dt: float, *, inputs: Mapping[str, Any] | None = None,
                 references: Mapping[str, Any] | None = None, held: Sequence[str] = (), store_every: int = 1,
                 rows: int = DEFAULT_ROWS, cache_dir: str | os.PathLike | None = None, projection: bool = True,
                 iterations: int = 3, start: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        model = controlled.plant
        spatial = not isinstance(model, KinematicLoopModel)
        if spatial:
            from .compiled_spatial_kinematic_loops import (spatial_kinematic_loop_compile_refusal,
                                                           symbolic_spatial_closed_loop, symbolic_spatial_projection)
        reason = spatial_kinematic_loop_compile_refusal(model) if spatial else kinematic_loop_compile_refusal(model)
        if reason:
            raise ModelError(f"compiled=True with loops, inputs or controllers: {reason}")
        started = _time.perf_counter()
        self.controlled, self.model, self.dt = controlled, model, validation.positive("dt", dt)
        self.store_every, rows = check_store_every(store_every), validation.integer("rows", rows, minimum=1)
        self.inputs = dict(inputs or {})
        self.projection = validation.flag("projection", projection)
        self.iterations = validation.integer("iterations", iterations, minimum=1)
        self.actuators = tuple(dict.fromkeys([name for loop in controlled.loops for name, _ in loop.actuator_terms]
                                             + list(self.inputs) + list(held)))
        if spatial:
            self.parameters, (self.nq, self.nv) = np.zeros(0), (model.tree.n_positions, model.tree.n_velocities)
            self.closed, constraint, coordinates, law_moments = symbolic_spatial_closed_loop(model, self.actuators)
            symbols: Any = SpatialKinematicLoopSymbols(model, controlled.ports, coordinates, law_moments, self.closed)
            project = symbolic_spatial_projection(model.tree, constraint, self.iterations)
        else:
            self.parameters, self.nq = parameter_vector(model.tree), model.tree.n_coordinates
            self.nv = self.nq
            self.closed, constraint = symbolic_closed_loop(model, self.parameters.size, self.actuators)
            symbols = KinematicLoopSymbols(model, controlled.ports, self.closed, self.parameters)
            project = symbolic_projection(constraint, self.nq, self.iterations)
        self.loops = ClosedLoops(controlled, self.actuators, dt=self.dt, references=references, inputs=self.inputs,
                                 symbols=symbols)
        if held and self.loops.dependent is not None:
            raise ModelError(f"loops on the cut forces {list(self.loops.dependent.names)} beside co-simulated "
                             "controllers are not available (their held outputs make the forces jump at every sample); "
                             "sense them in a controller")
        self.start = None
        if start is not None:                # refusals at the start state (singular or neutral loops) before compiling
            if self.loops.dependent is not None:
                self.loops.dependent.check_start(self.loops, *start)
            self.start = self.loops.initial_state(*start)
        step = _step(self.loops, self.closed, project if self.projection else None, self.nq, self.nv,
                     len(self.actuators), self.parameters.size)
        loop = compiled_time_loop(step, self.store_every, rows, f"kinematic_loop_control_{'spatial_' * spatial}"
                                  f"{self.nq}q{len(model.cuts)}c", cache_dir=cache_dir, flags=STRAIGHT_LINE_FLAGS)
        self._blocks, self._stride, self._step = loop.blocks, loop.stride, loop.step
        self._signals = self.loops.signals()
        self._input_signals = {name: as_signal(f"inputs[{name!r}]", value) for name, value in self.inputs.items()}
        self.compile_time_s = _time.perf_counter() - started

    def condition(self, q: np.ndarray, v: np.ndarray, t: float = 0.0) -> float:
        """The Frobenius condition of the boundary compliance ``G`` at ``(q, qdot)`` and time ``t`` [s] (driven tree
        joints move the configuration)."""
        G = self.closed(q, v, np.zeros(len(self.actuators)), self.parameters, t)[5]
        return compliance_condition(np.asarray(G))

    def run_states(self, state: np.ndarray, held: np.ndarray, n_steps: int, first_step: int = 0,
                   runner: BlockRunner | None = None) -> np.ndarray:
        """Stored states ``[q, qdot, z, ring, condition, residual]`` (rows, :attr:`ClosedLoops.state_size` + 2) of
        ``n_steps``
        steps of :attr:`dt` from the loops' state ``state`` at step ``first_step``, the ``held`` values of
        :attr:`actuators` held over them."""
        y = np.concatenate([state, [self.condition(state[:self.nq], state[self.nq:self.nq + self.nv],
                                                   first_step * self.dt), 0.0]])
        return run_blocks(self._blocks, self._stride, self._step, self.store_every, y[:, None], held, self.dt,
                          n_steps, 0.0, self.parameters[:, None], first_step=first_step, runner=runner)[0]

    def continue_run(self, state: np.ndarray, held: np.ndarray, dt: float, n_steps: int, first_step: int,
                     runner: BlockRunner | None = None) -> np.ndarray:
        """The loops' states (rows, :attr:`ClosedLoops.state_size`) of one sample interval of co-simulated
        controllers (:func:`ctmm.compiled_cosim.simulate_cosimulated_generated`; every step stored).

        Raises
        ------
        SimulationError
            A singular loop configuration or a failed projection in the interval (time, first cut joint); a
            non-finite state of a spatial model with a spherical cut law (time, the cut turned furthest, its angle:
            :func:`ctmm.compiled_spherical_cut_law.rotation_limit_note`).
        """
        if abs(dt - self.dt) > 1e-12 * self.dt or self.store_every != 1:
            raise ModelError(f"continue_run: this kernel steps dt = {self.dt!r} s storing every step, got dt = "
                             f"{dt!r}, store_every = {self.store_every!r}")
        block = self.run_states(state, held, n_steps, first_step, runner)
        broken = np.flatnonzero(~np.all(np.isfinite(block), axis=1))
        if broken.size and isinstance(self.model, SpatialKinematicLoopModel):     # a spherical law beyond 3 rad?
            k, size = int(broken[0]), self.nq + self.nv
            before = block[k - 1, :size] if k else np.asarray(state[:size], dtype=float)
            note, cut = rotation_limit_note(self.model, before[:self.nq], before[self.nq:], (first_step + k) * dt)
            if note:
                t = (first_step + 1 + k) * dt
                raise SimulationError(f"kinematic loop {self.model.name!r} (generated RK4): a non-finite state by t = "
                                      f"{t:.6g} s{note}", time=t, element=cut)
        over = np.flatnonzero((block[:, -2] > CONDITION_LIMIT) | (block[:, -1] > PROJECTION_TOLERANCE))
        if over.size:
            t = (first_step + 1 + int(over[0])) * dt
            raise SimulationError(f"kinematic loop {self.model.name!r} (generated RK4): "
                                  f"{self.failure(block[over[0]])} by t = {t:.6g} s", time=t,
                                  element=self.model.cuts[0].name)
        return block[:, :-2]

    def failure(self, row: np.ndarray) -> str:
        """What failed in a stored row ``[..., condition, residual]``: a non-finite state, a singular configuration
        or a projection left off the cut joints."""
        if not np.all(np.isfinite(row[:-2])):
            return "a non-finite state (a singular loop configuration or divergence)"
        if not row[-2] <= CONDITION_LIMIT:
            return singular_compliance(float(row[-2]))
        return projection_failure(float(row[-1]), self.iterations)

    def applied_inputs(self, t: np.ndarray, block: np.ndarray, held: Sequence[Mapping[str, float]] | None = None
                       ) -> list:
        """The tree's actuator inputs of stored rows (``block``: loops' states at times ``t`` [s]): the open-loop
        inputs, the loops' outputs and the ``held`` values of each row (``{actuator: value}``), as
        :meth:`KinematicLoopPorts.inputs` (``None`` where nothing drives)."""
        _, u = self._signals(block[:, :self.loops.state_size], t)
        return applied_loop_inputs(self.controlled, self.loops, self._input_signals, t, u, held)


def applied_loop_inputs(controlled: ControlledModel, loops: ClosedLoops, input_signals: Mapping[str, Any],
                        t: np.ndarray, u: np.ndarray, held: Sequence[Mapping[str, float]] | None = None) -> list:
    """The actuator inputs of stored rows at times ``t`` [s] of a controlled kinematic loop model: the open-loop
    ``input_signals`` (``{actuator: signal}``), the loops' outputs ``u`` (rows, loops; :meth:`ClosedLoops.signals`)
    and the ``held`` values of each row (``{actuator: value}``), as the ports' inputs
    (``controlled.ports.inputs``; ``None`` where nothing drives)."""
    out = []
    for k, moment in enumerate(t):
        values = {name: float(signal(moment)) for name, signal in input_signals.items()}
        for j, law in enumerate(loops.laws):
            for name, weight in law.actuators:
                values[name] = values.get(name, 0.0) + float(weight) * float(u[k, j])
        for name, value in (held[k] if held is not None else {}).items():
            values[name] = values.get(name, 0.0) + float(value)
        out.append(controlled.ports.inputs(values) if values else None)
    return out


def _start(model: Any, q0: Any, v0: Any) -> tuple[np.ndarray, np.ndarray]:
    """The checked initial state ``(q, v)`` of a planar or spatial kinematic loop model (on the cut joints)."""
    if isinstance(model, KinematicLoopModel):
        q, v = model.tree.state(q0, v0)
    elif isinstance(model, SpatialKinematicLoopModel):
        q, v = model.state(q0, v0)
    else:
        raise ModelError(f"a planar or spatial kinematic loop model (or one with loops) is compiled here, got "
                         f"{model!r:.80}")
    q, v = np.asarray(q, dtype=float), np.asarray(v, dtype=float)
    check_consistent(model, q, v, "x0, v0")
    return q, v


def simulate_controlled_kinematic_loops_generated(system: Any, q0: Any, v0: Any, *, t_final: float, dt: float,
                                                  inputs: Mapping[str, Any] | None = None,
                                                  references: Mapping[str, Any] | None = None,
                                                  outputs: Sequence[str] = (), store_every: int = 1,
                                                  stability_check: str = "warn", rows: int = DEFAULT_ROWS,
                                                  cache_dir: str | os.PathLike | None = None,
                                                  projection: bool = True) -> Any:
    """Fixed-step RK4 of a kinematic loop model with its feedback loops and inputs in generated C (module docstring).

    Parameters
    ----------
    system : ControlledModel, KinematicLoopModel or SpatialKinematicLoopModel
        ``ctmm.control.with_feedback(loop_model, loops)``, or the model alone (open-loop ``inputs``).
    q0, v0 : array_like
        A consistent initial state (``|Phi|``, ``|Phi'| <= 1e-8``): tree coordinates and rates (spatial: positions
        and velocities, arrays or mappings).
    t_final, dt : float
        End time and step [s]; ``t_final`` a whole multiple of ``dt``, every loop delay too.
    inputs : mapping, optional
        ``{actuator: number or ctmm.signals signal}`` open-loop values [SI] (tree actuators and ``"<cut>.torque"``).
    references : mapping, optional
        ``{loop: number or ctmm.signals signal}`` [sensed unit].
    outputs : sequence of str
        Sensors stored at every row.
    store_every : int
        Keep every ``store_every``-th step (and the last).
    stability_check : {"warn", "error", "ignore"}
        The RK4 step against the closed-loop accelerations' limit at the start (loops not included), as the numpy
        driver.
    rows : int
        Stored states per generated block.
    cache_dir : path, optional
        Of :func:`ctmm.codegen.shared_library`.
    projection : bool
        Project onto the cut joints after every step (default, as the numpy driver); ``False``: Baumgarte alone.

    Returns
    -------
    SimulationResult
        As the numpy driver's, method ``"rk4-generated"``, ``info["compiled"] = True``, ``info["projection"]`` and
        ``info["max_drift_after_projection"]`` [m, rad] (the largest ``max |Phi|`` after a projection).

    Raises
    ------
    ModelError
        What the generated kernel cannot do (named), bad arguments, an inconsistent initial state.
    SimulationError
        A non-finite state, a singular loop configuration or a failed projection: time, cut joint and partial
        result.
    """
    controlled = system if isinstance(system, ControlledModel) else ControlledModel(system, [])
    model = controlled.plant
    plant = plant_of(model)
    q, v = _start(model, q0, v0)
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps
    kernel = CompiledKinematicLoopControl(controlled, h, inputs=inputs, references=references, store_every=store_every,
                                          rows=rows, cache_dir=cache_dir, projection=projection, start=(q, v))
    plant.check_step(q, v, h, validation.option("stability_check", stability_check, ("warn", "error", "ignore")))
    loops, nq, nv, every, start = kernel.loops, kernel.nq, kernel.nv, kernel.store_every, kernel.start
    started = _time.perf_counter()
    states = kernel.run_states(start, np.zeros(len(kernel.actuators)), n_steps)
    wall = _time.perf_counter() - started
    steps = np.array([k for k in range(1, n_steps + 1) if k % every == 0 or k == n_steps])[:len(states)]
    t = np.concatenate([[0.0], steps * h])
    full = np.vstack([np.concatenate([start, [kernel.condition(q, v), 0.0]])[None], states])
    signals_of = loops.signals()
    info = {"dt": h, "method": "rk4-generated", "compiled": True, "compile_time_s": kernel.compile_time_s,
            "wall_time_s": wall, "n_evaluations": 4 * n_steps,
            "loops": {law.name: ("real-time" if law.steps == 0 else "history") for law in loops.laws},
            "projection": kernel.projection}
    if kernel.projection:
        info["max_drift_after_projection"] = float(np.max(full[:, -1]))

    def result(count: int) -> Any:
        time, block = t[:count], full[:count, :loops.state_size]
        signals, units = plant.signals(time, block[:, :nq], block[:, nq:nq + nv], outputs,
                                       inputs=kernel.applied_inputs(time, block))
        extra = add_loop_signals(controlled, loops, signals_of, block, time, signals, units)
        return signal_result(SignalSystem(model, units, list(controlled.loops)), time, signals, "rk4-generated",
                             {**info, **extra})

    bad = np.flatnonzero(~np.all(np.isfinite(full), axis=1) | (full[:, -2] > CONDITION_LIMIT)
                         | (full[:, -1] > PROJECTION_TOLERANCE))
    if bad.size:
        k = int(bad[0])
        note, cut = "", None
        if k and isinstance(model, SpatialKinematicLoopModel) and not np.all(np.isfinite(full[k])):
            note, cut = rotation_limit_note(model, full[k - 1, :nq], full[k - 1, nq:nq + nv], float(t[k - 1]))
        raise SimulationError(f"kinematic loop {model.name!r} with loops (generated RK4): {kernel.failure(full[k])} by "
                              f"t = {t[k]} s "
                              f"(after t = {t[k - 1] if k else 0.0} s, the last good stored state){note}",
                              time=float(t[k]), element=cut or model.cuts[0].name, partial_result=result(k))
    return result(len(t))


def simulate_cosimulated_kinematic_loops_generated(model: Any, loops: Sequence[Any], q0: Any, v0: Any,
                                                   *, t_final: float, dt: float, controllers: Sequence[Any],
                                                   **options: Any) -> Any:
    """Co-simulated controllers around the generated kernel of a kinematic loop model with its ``loops``: the kernel
    (:class:`CompiledKinematicLoopControl`, the controllers' outputs among its held actuators, every step stored)
    run by :func:`ctmm.compiled_cosim.simulate_cosimulated_generated`, one call into C per sample interval, the
    controllers sampled in Python at the numpy driver's instants; ``options`` (``inputs``, ``references``,
    ``outputs``, ``coupling``, ``store_every``, ``progress``, ``stability_check``, ``divergence_bound``) as there.
    The stored cut forces carry each row's actuator values (:meth:`CompiledKinematicLoopControl.applied_inputs`)."""
    from .compiled_cosim import simulate_cosimulated_generated

    q, v = _start(model, q0, v0)
    step = t_final / step_total(t_final, dt)
    held = [name for controller in controllers for name in controller.outputs]
    kernel = CompiledKinematicLoopControl(ControlledModel(model, loops), step, inputs=options.get("inputs"),
                                          references=options.get("references"), held=held)
    return simulate_cosimulated_generated(model, loops, q, v, t_final=t_final, dt=step, controllers=controllers,
                                          scene=kernel, **options)


def simulate_generated_driver_run(system: Any, q0: np.ndarray, v0: np.ndarray, *, t_final: float, dt: float,
                                  controllers: Sequence[Any], inputs: Mapping[str, Any] | None,
                                  references: Mapping[str, Any], outputs: Sequence[str], coupling: str,
                                  store_every: int, progress: bool | None, stability_check: str,
                                  divergence_bound: float | None, max_step: float | None) -> Any:
    """``ctmm.simulate(..., compiled=True)`` of the loop driver's run of a planar or spatial kinematic loop model
    (``system``: the model or a ControlledModel on it): with co-simulated ``controllers``
    :func:`simulate_cosimulated_kinematic_loops_generated`, else :func:`simulate_controlled_kinematic_loops_generated`
    (``divergence_bound``, ``max_step`` and ``progress`` refused there by name)."""
    model = getattr(system, "plant", system)
    loops = tuple(getattr(system, "loops", ()))
    if controllers:
        return simulate_cosimulated_kinematic_loops_generated(
            model, loops, q0, v0, t_final=t_final, dt=dt, controllers=controllers, inputs=dict(inputs or {}),
            references=references, outputs=tuple(outputs), coupling=coupling, store_every=store_every,
            progress=progress, stability_check=stability_check, divergence_bound=divergence_bound)
    for name, value in (("divergence_bound", divergence_bound), ("max_step", max_step), ("progress", progress)):
        if value is not None:
            raise ModelError(f"{name}={value!r} is not available with compiled=True on the kinematic loop model "
                             f"{model.name!r} with loops or inputs (no co-simulated controllers); leave it at None")
    return simulate_controlled_kinematic_loops_generated(system, q0, v0, t_final=t_final, dt=dt, inputs=inputs,
                                                         references=references, outputs=tuple(outputs),
                                                         store_every=store_every, stability_check=stability_check)
