"""One generated kernel run over parameter sets (issue 13): ``ctmm.simulate(..., compiled=True,
parameters={...})`` and :func:`simulate_batch`.

:class:`ParameterKernel` compiles the generated RK4 of a system once with its numbers as inputs and
runs it for named parameter sets (:mod:`ctmm.parameter_sets`): each set builds the system with those
numbers (certified), whose parameter vector enters the one compiled kernel and whose sensors and loop
signals give the result, the same :class:`~ctmm.results.SimulationResult` as ``ctmm.simulate(member,
compiled=True)``.

=========================================  ============================================================
system                                     kernel (compiled once, numbers as inputs ``p``)
=========================================  ============================================================
planar model                               :class:`~ctmm.compiled_scene.CompiledScene`, each set's model
                                           on a copy with its numbers (certified by the parameter space)
planar model with loops, ``inputs`` or     the scene of the controlled model; each set's loop laws
``references``                             (gains as entries of ``p``) on the same compiled functions
spatial model (held joint ``inputs``,      :class:`~ctmm.compiled_spatial.CompiledSpatialScene` (rigid
modal beams; no FE subsystems)             bodies' and beams' numbers; a beam's length is structure)
spatial model with loops, port inputs,     :class:`~ctmm.compiled_spatial_loops.CompiledControlledSpatial`
``references`` or ``outputs``              (plant numbers and loop gains in ``p``), each set's loop laws
=========================================  ============================================================

:func:`simulate_batch` runs the sets in a loop (or on any executor, :mod:`ctmm.executors`) with
progress output; a set that fails is reported with its index and exception and the others are kept.
Sequential planar and spatial sets run their RK4 together: one C call per block for all sets
(``casadi.Function.map``, serial, :meth:`ParameterKernel.run_mapped`), each set then checked and stored
as alone, with the same numbers.  With loops, ``references``, inputs or spatial ``outputs`` each set's
controller states and delay ring are part of its state and its loop numbers of its parameter column
(:mod:`ctmm.batch_loops`).  Co-simulated controllers run set by set (called between sample intervals).
"""
from __future__ import annotations

import copy
import math
import os
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .batch_loops import LoopRun, SharedSensors, run_members
from .batch_result import BatchResult
from .compiled_loops import ClosedLoops
from .compiled_parameters import parameter_vector, structure_key
from .compiled_spatial_parameters import spatial_parameter_vector
from .control.controlled_model import ControlledModel
from .control.protocol import check_controllers
from .errors import ModelError, SimulationError, unknown_name
from .executors import parallel_map
from .parameter_sets import ParameterSpace, parameter_set_list, plant_and_loops
from .planar.integrate import coordinate_values, initial_coordinates, step_total, to_result
from .planar.model import PlanarModel
from .results import SimulationResult
from .spatial.integrate import initial_state
from .spatial.model import SpatialModel

__all__ = ["BatchResult", "ParameterKernel", "simulate_batch", "simulate_with_parameters"]


class ParameterKernel:
    """The generated RK4 of ``system`` with its numbers as inputs, compiled once, run per parameter set.

    Parameters
    ----------
    system : PlanarModel, SpatialModel or ControlledModel
        The structure (and the numbers not set by a parameter set).
    t_final, dt : float
        End time and step [s] (``t_final`` a whole multiple of ``dt``, as ``ctmm.simulate``).
    store_every : int
        Keep every ``store_every``-th step (the last one always).
    inputs, references : mapping, optional
        ``{actuator: value}`` and ``{loop: r}`` as in ``ctmm.simulate(..., compiled=True)`` (all sets).
    outputs : sequence of str
        Sensor names stored at every row.
    cache_dir : path, optional
        Of :func:`ctmm.codegen.shared_library`.
    controllers : sequence of Controller, optional
        Co-simulated controllers (checked, :func:`ctmm.control.protocol.check_controllers`): each set runs
        the compiled co-simulation (:func:`ctmm.compiled_cosim.simulate_cosimulated_generated`) on the
        shared kernel with its numbers (the kernel then stores every step and holds the controllers'
        outputs as actuator inputs).
    coupling : {"hold", "previous"}
        Algebraic-loop policy of the ``controllers`` (:class:`~ctmm.control.cosim.CoSimulation`).

    Attributes
    ----------
    kind : str
        ``"planar"``, ``"planar loops"``, ``"spatial"`` or ``"spatial loops"`` (module table).
    compile_time_s : float
        Building (or loading) the shared kernel [s] (0 before the first run).
    """

    def __init__(self, system: Any, t_final: float, dt: float, *, store_every: int = 1,
                 inputs: Mapping[str, Any] | None = None, references: Mapping[str, Any] | None = None,
                 outputs: Sequence[str] = (), cache_dir: Any = None, controllers: Sequence[Any] = (),
                 coupling: str = "hold") -> None:
        self.system = system
        if dt is None:
            raise ModelError("dt is required with compiled=True (the generated RK4; a fixed step [s], > 0), got None")
        self.t_final, self.dt = validation.positive("t_final", t_final), validation.positive("dt", dt)
        self.step = self.t_final / step_total(self.t_final, self.dt)
        self.store_every = validation.integer("store_every", store_every, minimum=1)
        for label, value in (("inputs", inputs), ("references", references)):
            if value is not None and not isinstance(value, Mapping):
                raise ModelError(f"{label} must be a mapping {{name: number or signal}}, got {value!r}")
        self.inputs, self.references = dict(inputs or {}), dict(references or {})
        self.controllers, self.coupling = tuple(check_controllers(controllers)), coupling
        self.space = ParameterSpace(system, references)
        self.plant, self.loops = self.space.plant, self.space.loops
        if isinstance(outputs, (str, Mapping)) or not all(isinstance(name, str) for name in outputs):
            raise ModelError(f"outputs must be a list or tuple of sensor names (str), got {outputs!r}")
        self.outputs, self.cache_dir = tuple(outputs), cache_dir
        self._check_outputs()
        spatial = isinstance(self.plant, SpatialModel)
        port_inputs = spatial and any(name not in self.plant.inputs for name in self.inputs)
        controlled = bool(self.loops or self.references or (self.inputs and not spatial) or port_inputs
                          or (spatial and self.outputs) or self.controllers)
        held = {name: 0.0 for c in self.controllers for name in c.outputs if name not in self.inputs}
        self.scene_inputs = {**self.inputs, **held} if spatial else self.inputs     # as compiled_cosim
        self.kind = ("spatial" if spatial else "planar") + (" loops" if controlled else "")
        self.compile_time_s = 0.0
        self._scene: Any = None
        self._sensors: SharedSensors | None = None
        self._lock = threading.RLock()

    def _check_outputs(self) -> None:
        if isinstance(self.plant, SpatialModel):
            from .spatial.ports import SpatialPorts

            ports = SpatialPorts(self.plant)
            for name in self.outputs:
                ports.check_sensor(name, "output (sensor)")
            return
        from .planar.ports import sensor_names

        known = sensor_names(self.plant)
        for name in self.outputs:
            if name not in known:
                raise unknown_name("output (sensor)", name, sorted(known))

    def __getstate__(self) -> dict:
        """Picklable (process pools): the compiled scene is loaded again from the disk cache."""
        return {**self.__dict__, "_scene": None, "_sensors": None, "_lock": None}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state, _lock=threading.RLock())

    def scene(self) -> Any:
        """The shared compiled scene (numbers as inputs), built (or loaded from the cache) on first use."""
        if self._scene is None:
            from .compiled_scene import CompiledScene
            from .compiled_spatial import CompiledSpatialScene
            from .compiled_spatial_loops import CompiledControlledSpatial

            start = time.perf_counter()
            options = {"store_every": 1 if self.controllers else self.store_every, "cache_dir": self.cache_dir}
            if self.kind == "planar":
                self._scene = CompiledScene(self.plant, **options)
            elif self.kind == "planar loops":
                self._scene = CompiledScene(ControlledModel(self.plant, self.loops), dt=self.step,
                                            references=self.references, signals=self.inputs, **options)
            elif self.kind == "spatial":
                self._scene = CompiledSpatialScene(self.plant, numbers="inputs", **options)
            else:
                self._scene = CompiledControlledSpatial(ControlledModel(self.plant, self.loops), self.step,
                                                        references=self.references, inputs=self.scene_inputs,
                                                        numbers="inputs", **options)
            self.compile_time_s = time.perf_counter() - start
        return self._scene

    def start(self, x0: Any, v0: Any) -> tuple[Any, Any]:
        """The initial state checked once for every set (coordinates are part of the structure): planar
        ``(q0, qdot0)`` arrays, spatial ``(x0, v0)`` as given (checked by :func:`initial_state`)."""
        if isinstance(self.plant, SpatialModel):
            initial_state(self.plant, x0, v0)
            return x0, v0
        return initial_coordinates(self.plant, coordinate_values(self.plant, "x0", x0),
                                   coordinate_values(self.plant, "v0", v0))

    def policy(self, stability_check: str | None) -> str:
        """The step-check policy of a run (``"warn"`` by default; spatial kernels have none yet)."""
        if self.kind.startswith("spatial") and stability_check is not None:
            raise ModelError(f"stability_check={stability_check!r} is not available for the generated RK4 of spatial "
                             "models yet; leave it at None")
        return "warn" if stability_check is None else validation.option("stability_check", stability_check,
                                                                         ("warn", "error", "ignore"))

    def member(self, values: Mapping[str, Any]) -> Any:
        """The system with the numbers ``values`` (:meth:`ctmm.parameter_sets.ParameterSpace.system_with`)."""
        return self.space.system_with(values)

    def run(self, values: Mapping[str, Any], *, x0: Any = None, v0: Any = None,
            divergence_bound: float | None = None, stability_check: str | None = None) -> SimulationResult:
        """The run of the parameter set ``values`` (``{name: number}``) from ``x0``, ``v0`` (as
        ``ctmm.simulate``): ``info["parameters"]`` the set, ``info["kernel"]`` ``"shared"``.

        Raises
        ------
        ModelError
            Bad names or values, a system the generated path refuses.
        SimulationError
            A diverging or non-finite run, with ``partial_result``.

        Notes
        -----
        Threads may run sets on one kernel at once (``simulate_batch(..., executor="threads")``): each set's
        expressions are built and its result stored under the kernel's lock, its compiled run outside it.
        """
        start = {"x0": x0, "v0": v0, "divergence_bound": divergence_bound, "stability_check": stability_check}
        if self.controllers:                # Python controllers between the sample intervals: one set at a time
            with self._lock:
                return self._finish(values, self.member(values), **start)
        ((result, error),) = self._run_together([values], start)
        if error is not None:
            raise error
        return result

    def _finish(self, values: Mapping[str, Any], member: Any, *, x0: Any = None, v0: Any = None,
                divergence_bound: float | None = None, stability_check: str | None = None,
                ran: tuple[np.ndarray, float] | None = None, prepared: LoopRun | None = None) -> SimulationResult:
        """:meth:`run` of the set ``values`` whose system ``member`` :meth:`member` built (certified: the
        structure and parameter vector of the compiled one); ``ran``: its stored states and wall time [s]
        computed already (a set of :meth:`run_mapped`), of a kernel with loops from ``prepared``
        (:meth:`loop_run`)."""
        references = self.space.references_with(values)
        values = {name: float(value) for name, value in values.items()}
        plant, loops = plant_and_loops(member)
        policy = self.policy(stability_check)
        if divergence_bound is not None:
            divergence_bound = validation.positive("divergence_bound", divergence_bound)
        x0, v0 = self.start(x0, v0)
        if self.controllers:
            result = self._run_cosimulated(plant, loops, references, x0, v0, divergence_bound, policy)
        elif self.kind.startswith("spatial"):
            result = self._run_spatial(plant, loops, references, x0, v0, divergence_bound, ran, prepared)
        else:
            result = self._run_planar(plant, loops, references, x0, v0, divergence_bound, policy, ran, prepared)
        result.info.update(parameters=dict(values), kernel="shared")
        return result

    def run_mapped(self, sets: Sequence[Mapping[str, Any]], start: Mapping[str, Any]) -> list[tuple]:
        """``(result, None)`` or ``(None, exception)`` of each set, their RK4 in one C call per block over all
        sets (``casadi.Function.map``, serial: :func:`ctmm.compiled_scene.simulate_batch`,
        :meth:`ctmm.compiled_spatial.CompiledSpatialScene.run` with ``parameters``; with loops each set's
        controller states, delay ring and loop numbers per member, :func:`ctmm.batch_loops.run_members`); each
        set then checked and stored as by :meth:`run`, with the same numbers (the same compiled block per set; a
        diverging set fails alone).  ``start``: the keyword arguments of :meth:`run`.

        Raises
        ------
        ModelError
            A kernel with co-simulated ``controllers`` (called between sample intervals of each set): run its
            sets by :meth:`run`.
        """
        if self.controllers:
            raise ModelError(f"run_mapped runs planar and spatial kernels with or without loops; this {self.kind!r} "
                             f"kernel has co-simulated controllers ({len(self.controllers)}), called between sample "
                             "intervals of each set (run its sets one by one, ParameterKernel.run)")
        return self._run_together(sets, start)

    def _run_together(self, sets: Sequence[Mapping[str, Any]], start: Mapping[str, Any]) -> list[tuple]:
        """:meth:`run_mapped` without its refusal (:meth:`run` of one set: a batch of one).

        Threads may call it on one kernel: the sets' expressions are built, and their results stored, under the
        kernel's lock (casadi releases the GIL while it builds expressions, and the kernel's shared sensors cache
        their kinematics per symbol: two sets built at once could read each other's symbols); only the compiled
        runs go side by side."""
        with self._lock:                    # each set's expressions built one thread at a time
            runs, built, members, prepared, execute = self._prepare(sets, start)
        if not built:
            return runs
        states, wall = execute()            # C calls only: threads run them side by side
        with self._lock:
            for index, k in enumerate(built):
                try:
                    runs[k] = self._finish(sets[k], members[k], **start, ran=(states[index], wall),
                                           prepared=prepared.get(k)), None
                except Exception as exc:  # noqa: BLE001 - a failed set is reported with its index, the others kept
                    runs[k] = None, exc
        return runs

    def _prepare(self, sets: Sequence[Mapping[str, Any]], start: Mapping[str, Any]) -> tuple:
        """``runs`` (``(None, exception)`` of the sets that failed to build), the indices ``built`` of the others,
        their systems ``members`` by index, their :class:`~ctmm.batch_loops.LoopRun` ``prepared`` by index (kernels
        with loops) and ``execute()``: their stored states ``(B, rows, state size)`` and wall time per set [s] of
        the compiled run of all of them (:meth:`run_mapped`)."""
        from .compiled_scene import simulate_batch as scene_batch

        runs: list = []
        members: dict[int, Any] = {}
        for k, values in enumerate(sets):
            try:
                members[k] = self.member(values)
                runs.append((None, None))
            except Exception as exc:  # noqa: BLE001 - as in run_mapped
                runs.append((None, exc))
        built = list(members)
        n_steps = step_total(self.t_final, self.dt)
        prepared: dict[int, LoopRun] = {}
        if self.kind.endswith(" loops"):    # each set's loop laws, controller states and ring per member
            x0, v0 = self.start(start.get("x0"), start.get("v0"))
            for k in built:
                try:
                    plant, loops = plant_and_loops(members[k])
                    prepared[k] = self.loop_run(plant, loops, self.space.references_with(sets[k]), x0, v0)
                except Exception as exc:  # noqa: BLE001 - as in run_mapped
                    runs[k] = None, exc
            built = list(prepared)
            scene, runs_of = self.scene(), [prepared[k] for k in built]
            return runs, built, members, prepared, lambda: run_members(scene, runs_of, self.step, n_steps)
        if self.kind == "spatial":          # as simulate_spatial_generated: steps of dt from the checked state
            numbers = np.array([spatial_parameter_vector(members[k]) for k in built])
            x = initial_state(self.plant, start.get("x0"), start.get("v0"))
            run = lambda: self.scene().run(x, self.dt, n_steps, self.inputs or None, parameters=numbers)  # noqa: E731
        else:
            q0, qdot0 = self.start(start.get("x0"), start.get("v0"))
            numbers = np.array([parameter_vector(members[k]) for k in built])
            run = lambda: scene_batch(self.scene(), numbers, q0, qdot0, dt=self.t_final / n_steps,  # noqa: E731
                                      n_steps=n_steps)

        def execute() -> tuple[np.ndarray, float]:
            clock = time.perf_counter()
            states = run()
            return states, (time.perf_counter() - clock) / len(built)
        return runs, built, members, prepared, execute

    def loop_run(self, plant: Any, loops: tuple, references: dict, x0: Any, v0: Any) -> LoopRun:
        """A set's run with loops prepared on the shared kernel (:class:`~ctmm.batch_loops.LoopRun`): the
        controlled model of its ``plant`` and ``loops``, the scene with its loop laws, ``references`` and
        numbers (:meth:`_loop_scene`), its initial state; ``x0``, ``v0`` as :meth:`start` gives them.

        Raises
        ------
        ModelError
            A planar plant of another structure than the compiled one, a bad initial state.
        """
        from .compiled_planar_sensors import PlanarSymbols
        from .compiled_spatial_loops import SpatialSymbols

        controlled = ControlledModel(plant, loops)
        spatial = isinstance(plant, SpatialModel)
        numbers = spatial_parameter_vector(plant) if spatial else parameter_vector(plant)
        if spatial and any(layout is not None for layout in plant.modal):     # beam shapes from a set's numbers
            symbols: Any = SpatialSymbols(plant, controlled.ports, numbers.size)
        else:                               # the kernel's sensors, stated once (ctmm.batch_loops.SharedSensors)
            if self._sensors is None:
                ports = ControlledModel(self.plant, self.loops).ports
                self._sensors = SharedSensors(SpatialSymbols(self.plant, ports, numbers.size) if spatial
                                              else PlanarSymbols(self.plant, ports))
            symbols = self._sensors
        if spatial:
            scene = self._loop_scene(controlled, references, symbols, numbers)
            state = initial_state(plant, x0, v0)
            q0, v0 = state[:plant.n_positions], state[plant.n_positions:]
            first = scene.loops.initial_state(np.asarray(q0, float), np.asarray(v0, float))
        else:
            scene = self._loop_scene(controlled, references, symbols, numbers)
            if structure_key(plant) != self.scene().structure:
                raise ModelError(f"parameters: model {plant.name!r} with these numbers has another structure than "
                                 "the compiled one; run it with ctmm.simulate without parameters=")
            q0, v0 = x0, v0         # the start of CompiledScene.checked_run (simulate_controlled_generated)
            first = scene.loops.initial_state(*plant.state(*initial_coordinates(plant, q0, v0)))
        return LoopRun(controlled, scene, q0, v0, first)

    def _run_planar(self, plant: PlanarModel, loops: tuple, references: dict, x0: Any, v0: Any, bound: Any,
                    policy: str, ran: tuple[np.ndarray, float] | None = None,
                    prepared: LoopRun | None = None) -> SimulationResult:
        from .compiled_control import simulate_controlled_generated
        from .compiled_scene import simulate_rk4_generated

        q0, qdot0 = x0, v0
        if self.kind == "planar":
            try:
                simulation = simulate_rk4_generated(plant, q0, qdot0, t_final=self.t_final, dt=self.dt,
                                                    store_every=self.store_every, divergence_bound=bound,
                                                    stability_check=policy, scene=self._member_scene(plant), ran=ran)
            except SimulationError as exc:
                if exc.partial_result is not None:
                    exc.partial_result = to_result(exc.partial_result, outputs=self.outputs,
                                                   info={"dt": self.dt, "failed": True})
                raise
            return to_result(simulation, outputs=self.outputs, info={"dt": self.dt})
        return simulate_controlled_generated(prepared.controlled, prepared.q0, prepared.v0, t_final=self.t_final,
                                             dt=self.dt, inputs=self.inputs, references=references,
                                             outputs=self.outputs, store_every=self.store_every,
                                             divergence_bound=bound, stability_check=policy, scene=prepared.scene,
                                             ran=ran)

    def _member_scene(self, plant: PlanarModel) -> Any:
        """The shared planar scene with the numbers of ``plant``, a member certified by :meth:`member` (its
        structure key that of the compiled model, its parameter vector the expected one): what
        :meth:`ctmm.compiled_scene.CompiledScene.with_model` gives, without computing the key again."""
        scene = copy.copy(self.scene())
        scene.model, scene.parameters = plant, parameter_vector(plant)
        return scene

    def _run_spatial(self, plant: SpatialModel, loops: tuple, references: dict, x0: Any, v0: Any, bound: Any,
                     ran: tuple[np.ndarray, float] | None = None, prepared: LoopRun | None = None) -> SimulationResult:
        from .compiled_control import simulate_spatial_controlled_generated
        from .compiled_spatial import simulate_spatial_generated

        if self.kind == "spatial":
            scene = copy.copy(self.scene())     # the same compiled functions with this set's numbers
            scene.model, scene.parameters = plant, spatial_parameter_vector(plant)
            if scene.parameters.shape != self.scene().parameters.shape:
                raise ModelError(f"parameters: model {plant.name!r} with these numbers has another parameter layout "
                                 "than the compiled one; run it with ctmm.simulate without parameters=")
            return simulate_spatial_generated(plant, self.t_final, self.dt, x0=x0, v0=v0, inputs=self.inputs or None,
                                              store_every=self.store_every, divergence_bound=bound, scene=scene,
                                              ran=ran)
        return simulate_spatial_controlled_generated(
            prepared.controlled, prepared.q0, prepared.v0, t_final=self.t_final, dt=self.dt, inputs=self.inputs,
            references=references, outputs=self.outputs, store_every=self.store_every, divergence_bound=bound,
            scene=prepared.scene, ran=ran)

    def _run_cosimulated(self, plant: Any, loops: tuple, references: dict, x0: Any, v0: Any, bound: Any,
                         policy: str) -> SimulationResult:
        """The compiled co-simulation of the set's model on the shared kernel with its numbers."""
        from .compiled_cosim import simulate_cosimulated_generated

        controlled = ControlledModel(plant, loops)
        if isinstance(plant, SpatialModel):
            from .compiled_spatial_loops import SpatialSymbols

            numbers = spatial_parameter_vector(plant)
            symbols = SpatialSymbols(plant, controlled.ports, numbers.size)
            state = initial_state(plant, x0, v0)
            x0, v0 = state[:plant.n_positions], state[plant.n_positions:]
        else:
            numbers, symbols = parameter_vector(plant), None
            if structure_key(plant) != self.scene().structure:
                raise ModelError(f"parameters: model {plant.name!r} with these numbers has another structure than "
                                 "the compiled one; run it with ctmm.simulate without parameters=")
        return simulate_cosimulated_generated(
            plant, loops, x0, v0, t_final=self.t_final, dt=self.dt, controllers=self.controllers, inputs=self.inputs,
            references=references, outputs=self.outputs, coupling=self.coupling, store_every=self.store_every,
            stability_check=policy, divergence_bound=bound,
            scene=self._loop_scene(controlled, references, symbols, numbers))

    def _loop_scene(self, controlled: ControlledModel, references: dict, symbols: Any, numbers: np.ndarray) -> Any:
        """The shared scene with loops for the set's ``controlled`` model and ``references``: the same compiled
        functions, its loop laws (:class:`~ctmm.compiled_loops.ClosedLoops`, numbers as inputs; they give the
        stored loop signals) and its parameter column (the plant's ``numbers``, then the loops')."""
        base = self.scene()
        scene = copy.copy(base)
        scene.controlled, scene.model = controlled, controlled.plant
        scene.loops = ClosedLoops(controlled, base.actuators, self.step, references, self.scene_inputs,
                                  symbols=symbols, numbers="inputs")
        scene.parameters = np.concatenate([numbers, scene.loops.parameter_values])
        if scene.parameters.shape != base.parameters.shape or [entry[0] for entry in scene.loops.parameter_layout] \
                != [entry[0] for entry in base.loops.parameter_layout]:
            raise ModelError(f"parameters: the controlled model of {controlled.plant.name!r} with these numbers has "
                             "another structure than the compiled one; run it with ctmm.simulate without parameters=")
        return scene


_NOT_APPLICABLE = {"t0": 0.0, "coupling": "hold", "solver": "riccati", "fast": None, "force_hook": None,
                   "rtol": 1e-8, "atol": 1e-10, "max_step": None, "progress": None}
"""Options of ``ctmm.simulate`` that a run with ``parameters`` leaves at their defaults."""


def simulate_with_parameters(system: Any, parameters: Mapping[str, Any], options: Mapping[str, Any]
                             ) -> SimulationResult:
    """``ctmm.simulate(system, ..., compiled=True, parameters=parameters)``: the run of one parameter set
    on the kernel of ``system`` with its numbers as inputs (:class:`ParameterKernel`); ``options`` the
    other arguments of :func:`ctmm.simulate` by name (``method`` resolved).

    Raises
    ------
    ModelError
        ``compiled`` not True, a method other than ``"rk4"``, options that do not apply (named), unknown
        parameter names (the allowed ones listed), bad values.  Co-simulated ``controllers`` run the compiled
        co-simulation with the set's numbers (:meth:`ParameterKernel.run`).
    """
    if options.get("compiled") is not True:
        raise ModelError(f"parameters= sets the numbers of a generated kernel at run time; give compiled=True (got "
                         f"compiled={options.get('compiled')!r}), or build the model with these numbers")
    if options.get("method") != "rk4":
        raise ModelError(f"parameters= runs the generated RK4; got method={options.get('method')!r}")
    controllers = options.get("controllers") or ()
    for name, default in _NOT_APPLICABLE.items():
        if name == "coupling" and controllers:
            continue
        value = options.get(name, default)
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} does not apply to a run with parameters= (the generated RK4 from "
                             f"t = 0); leave {name} at {default!r}")
    kernel = ParameterKernel(system, options["t_final"], options.get("dt"), store_every=options.get("store_every", 1),
                             inputs=options.get("inputs"), references=options.get("references"),
                             outputs=options.get("outputs", ()), controllers=controllers,
                             coupling=options.get("coupling", "hold"))
    return kernel.run(parameters, x0=options.get("x0"), v0=options.get("v0"),
                      divergence_bound=options.get("divergence_bound"), stability_check=options.get("stability_check"))


def _run_set(item: tuple) -> tuple:
    """``(result, None)`` or ``(None, exception)`` of one set (module level: picklable)."""
    kernel, values, start = item
    try:
        return kernel.run(values, **start), None
    except Exception as exc:  # noqa: BLE001 - a failed set is reported with its index, the others kept
        return None, exc


def _run_chunk(item: tuple) -> list:
    """:func:`_run_set` of each set of a chunk on one kernel (its scene built once per chunk in a worker)."""
    kernel, chunk, start = item
    return [_run_set((kernel, values, start)) for values in chunk]


def simulate_batch(system: Any, parameter_sets: Any, t_final: float, dt: float, *, x0: Any = None, v0: Any = None,
                   inputs: Mapping[str, Any] | None = None, references: Mapping[str, Any] | None = None,
                   outputs: Sequence[str] = (), store_every: int = 1, divergence_bound: float | None = None,
                   stability_check: str | None = None, executor: Any = None, progress: bool | None = None,
                   cache_dir: Any = None) -> BatchResult:
    """Generated RK4 runs of ``system`` for a batch of parameter sets, compiled once.

    Parameters
    ----------
    system : PlanarModel, SpatialModel or controlled model
        The structure; its numbers not named in a set stay.
    parameter_sets : sequence of mappings, or mapping of str to sequence
        ``[{name: number}, ...]`` or ``{name: [number per set]}`` (:func:`ctmm.parameter_names`:
        ``"<body>.mass"``, ``"<joint>.stiffness"``, ``"gravity.y"``, ``"<loop>.gain"``, ... in SI units).
    t_final, dt : float
        End time and step [s].
    x0, v0, inputs, references, outputs, store_every, divergence_bound, stability_check
        As :func:`ctmm.simulate` with ``compiled=True`` (the same for every set).
    executor : None, "threads", "processes" or Executor
        Where the sets run (:func:`ctmm.executors.parallel_map`): sequentially or on threads every set
        runs on the one compiled scene (sequentially: the RK4 of all sets in one C call per block, with loops
        each set's controller states, delay ring and loop numbers per member, :meth:`ParameterKernel.run_mapped`,
        unless ``progress=True``, which steps set by set to report each); a
        process pool or another executor receives chunks of sets
        (about four per CPU) and the kernel without its scene, which each chunk builds again from the
        disk cache (the C text generated again, nothing compiled).  Each set also builds and checks its
        model and, on planar models, its step against the linearised RK4 limit
        (``stability_check="ignore"`` skips that): milliseconds to tens of milliseconds of Python per
        set (``benchmarks/batch_parameters.py``).
    progress : bool, optional
        Progress bar over the sets (default: on terminals from 50 sets).
    cache_dir : path, optional
        Of :func:`ctmm.codegen.shared_library`.

    Returns
    -------
    BatchResult
        One :class:`~ctmm.results.SimulationResult` per set (``info["parameters"]``), the failures by
        index, :meth:`BatchResult.stacked` signals.

    Raises
    ------
    ModelError
        Bad arguments; a set with unknown names (the allowed ones listed) or bad values, with its index.
    """
    sets = parameter_set_list(parameter_sets)
    kernel = ParameterKernel(system, t_final, dt, store_every=store_every, inputs=inputs, references=references,
                             outputs=outputs, cache_dir=cache_dir)
    for index, values in enumerate(sets):
        try:
            sets[index] = kernel.space.check(values)
        except ModelError as exc:
            raise ModelError(f"parameter_sets[{index}]: {exc} (the set: {values!r:.80})") from None
    kernel.start(x0, v0), kernel.policy(stability_check)        # bad arguments refused before any set runs
    if divergence_bound is not None:
        validation.positive("divergence_bound", divergence_bound)
    kernel.scene()                                  # compiled (or loaded) once, before the sets
    start = {"x0": x0, "v0": v0, "divergence_bound": divergence_bound, "stability_check": stability_check}
    clock = time.perf_counter()
    if executor is None and progress is not True:      # one C call per block for all sets (controllers: one by one)
        runs = kernel.run_mapped(sets, start)
    elif executor is None or (isinstance(executor, str) and executor == "threads") or \
            isinstance(executor, ThreadPoolExecutor):       # one scene shared by every set
        runs = parallel_map(_run_set, [(kernel, values, start) for values in sets], executor=executor,
                            progress=progress, description="simulate_batch")
    else:           # workers receive the kernel without its scene: chunks of sets, one scene build each
        size = max(1, math.ceil(len(sets) / (4 * (os.cpu_count() or 1))))
        chunks = [(kernel, sets[k:k + size], start) for k in range(0, len(sets), size)]
        runs = [run for chunk in parallel_map(_run_chunk, chunks, executor=executor, progress=progress,
                                              description="simulate_batch (chunks of sets)") for run in chunk]
    wall = time.perf_counter() - clock
    return BatchResult(sets, [result for result, _ in runs],
                       {k: error for k, (_, error) in enumerate(runs) if error is not None},
                       kernel.compile_time_s, wall)

