"""Generated DT-TMM schemes of spatial kinematic loop models with feedback loops closed inside the Newton step (issue 13).

``ctmm.simulate(with_feedback(spatial_loop_model, loops), t_final, dt, method=<scheme>, compiled=True)`` (references,
open-loop port inputs and sensor outputs too) runs here: the Lie-group step of
:class:`~ctmm.compiled_spatial_loop_schemes.CompiledSpatialLoopScheme` (Newton in generated C on the closed-loop
velocity rates of the cut joints, projected after every step) with the loop part every generated scheme shares,
:class:`~ctmm.compiled_scheme_loop_terms.SchemeLoopTerms`: real-time loops at the Newton iterate, LTI controller
states by the Python path's trapezoidal rule, delayed loops from the ring of samples.  The loops' actuators are port
actuators of the tree and the cuts' ``"<cut>.torque"`` / ``"<cut>.force"`` applied with the cut loads
(:func:`ctmm.compiled_spatial_kinematic_loops.symbolic_spatial_closed_loop`), the sensors the ones of the generated
loop driver (:class:`ctmm.compiled_spatial_loop_symbols.SpatialKinematicLoopSymbols`).

As the numpy path (:func:`ctmm.control.implicit_loops.run_implicit` with the plant's ``step_projection``), every
accepted step is projected onto the cut joints before the controller states, the loop errors and the delay ring
are updated from it: the step's controller update runs on the projected state.  Generated state: the one of
:class:`CompiledSpatialLoopScheme` with the loops' entries ``[z_n, e_n, ring]`` before its ``[condition,
residual]``.  The result equals the numpy loop driver's (:func:`ctmm.control.planar_time.simulate_closed_loop` with
the scheme) to round-off (``tests/test_compiled_spatial_loop_scheme_control.py``).

Co-simulated controllers beside them run this step between their samples (:mod:`ctmm.compiled_scheme_cosim`, their
outputs ``held`` port actuators of ``u``).  Refused by name (:class:`~ctmm.errors.ModelError`): what
:class:`CompiledSpatialLoopScheme` and :class:`~ctmm.compiled_loops.ClosedLoops` refuse, a delay the Python path
refuses.
"""
from __future__ import annotations

import os
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .compiled_control import add_loop_signals
from .compiled_kinematic_loop_control import applied_loop_inputs
from .compiled_spatial_loop_symbols import SpatialKinematicLoopSymbols
from .compiled_loops import ClosedLoops
from .compiled_scene_schemes import STATUS
from .compiled_scheme_loop_terms import SchemeLoopTerms, loop_actuators
from .compiled_spatial_kinematic_loops import spatial_kinematic_loop_compile_refusal
from .compiled_spatial_loop_schemes import CompiledSpatialLoopScheme, check_cut_rows
from .compiled_spatial_scheme_loops import restarted_loop_state
from .compiled_spatial_schemes import checked_spatial_result, generated_rows, warn_conditionally_stable
from .control.controlled_model import ControlledModel
from .control.planar_time import controller_realisation
from .control.plants import plant_of
from .errors import ModelError
from .planar.integrate import check_store_every, step_total
from .results import SimulationResult
from .schemes import Scheme, as_scheme
from .signal_results import SignalSystem, signal_result
from .signals import as_signal
from .spatial.closed_loops import SpatialKinematicLoopModel

__all__ = ["CompiledSpatialLoopSchemeControl", "simulate_spatial_loop_scheme_control_generated"]


class CompiledSpatialLoopSchemeControl(SchemeLoopTerms, CompiledSpatialLoopScheme):
    """The generated DT-TMM step of a spatial kinematic loop model with its feedback loops (module docstring).

    Parameters
    ----------
    controlled : ControlledModel
        A compilable :class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel` and its loops.
    scheme : Scheme or str
    references, inputs : mapping, optional
        ``{loop: number or symbolic signal}`` [sensed unit], ``{port actuator: number or symbolic signal}`` [SI]:
        constants of the code (:class:`~ctmm.compiled_loops.ClosedLoops`).
    dt : float, optional
        The step [s]; required with delayed loops.
    held : sequence of str
        Further port actuators of the input ``u``, held between calls.
    store_every, tolerance, max_iterations, rows, projection, iterations, cache_dir, compiler
        As :class:`CompiledSpatialLoopScheme`.

    Raises
    ------
    ModelError
        A model or loop the generated step refuses (named), a delayed loop without ``dt`` or with a delay the Python
        path refuses.
    """

    def __init__(self, controlled: ControlledModel, scheme: Scheme | str = "newmark", *,
                 references: Mapping[str, Any] | None = None, inputs: Mapping[str, Any] | None = None,
                 dt: float | None = None, held: Sequence[str] = (), store_every: int = 1, tolerance: float = 1e-10,
                 max_iterations: int = 50, rows: int = 64, projection: bool = True, iterations: int = 3,
                 cache_dir: str | os.PathLike | None = None, compiler: str | None = None) -> None:
        if not isinstance(controlled, ControlledModel) or not isinstance(controlled.plant, SpatialKinematicLoopModel):
            raise ModelError(f"CompiledSpatialLoopSchemeControl: controlled must be a ctmm.control.ControlledModel of "
                             f"a SpatialKinematicLoopModel, got {controlled!r:.80}")
        reason = spatial_kinematic_loop_compile_refusal(controlled.plant)
        if reason:
            raise ModelError(f"CompiledSpatialLoopSchemeControl: {reason}")
        for loop in controlled.loops:
            controller_realisation(loop)                # an improper C(s) raises, naming the loop
        self.controlled, self.dt = controlled, None if dt is None else validation.positive("dt", dt)
        self.references, self.open_inputs = dict(references or {}), dict(inputs or {})
        self.actuators, self.parameters = loop_actuators(controlled, inputs, held), np.zeros(0)
        self.scheme_of_loops = as_scheme(scheme)
        super().__init__(controlled.plant, scheme, store_every=store_every, tolerance=tolerance,
                         max_iterations=max_iterations, rows=rows, projection=projection, iterations=iterations,
                         cache_dir=cache_dir, compiler=compiler)

    def step_actuators(self) -> tuple[str, ...]:
        """The loops', the open-loop inputs' and the held port actuators (set before the step is built)."""
        return self.actuators

    def prepare(self) -> None:
        """The loops on the closed-loop functions' symbols, the ring plan and the controller entries
        ``[z, e_n, ring, condition, residual]``."""
        self.loops = ClosedLoops(self.controlled, self.actuators, self.dt, self.references, self.open_inputs,
                                 symbols=SpatialKinematicLoopSymbols(self.loop_model, self.controlled.ports,
                                                                     self.cut_coordinates, self.law_moments),
                                 whole_delays=False)
        self.setup_loops(self.scheme_of_loops)
        self.loop_size = self.controller_size
        self.controller_size = self.loop_size + 2

    def described(self) -> tuple:
        """The loop model's part, the loops, their references and inputs, and the step with delayed loops."""
        return CompiledSpatialLoopScheme.described(self) + (
            self.controlled, self.references, self.open_inputs, self.dt if self.loops.delayed else None, "loops")

    def plant_sweep(self) -> Any:
        """``v_dot = sweep(q, v, u, p, t)``: the closed-loop velocity rates with the port actuators ``u``."""
        import casadi as ca

        tree = self.loop_model.tree
        q, v, u = ca.SX.sym("q", tree.n_positions), ca.SX.sym("v", tree.n_velocities), ca.SX.sym("u", self.input_size)
        p, t = ca.SX.sym("p", 0), ca.SX.sym("t")
        return ca.Function("sweep", [q, v, u, p, t], [self._closed(q, v, u, p, t)[0]])

    def closed_acceleration(self) -> Any:
        """:meth:`SchemeLoopTerms.closed_acceleration`, its state functions on the loops' entries alone."""
        size, self.controller_size = self.controller_size, self.loop_size
        try:
            return SchemeLoopTerms.closed_acceleration(self)
        finally:
            self.controller_size = size

    def iterate_acceleration(self, acceleration: Any, q: Any, v: Any, u: Any, p: Any, t: Any, c: Any, s: Any) -> Any:
        """:meth:`SchemeLoopTerms.iterate_acceleration` on the loops' entries of ``c``."""
        return SchemeLoopTerms.iterate_acceleration(self, acceleration, q, v, u, p, t, c[:self.loop_size], s)

    def controller_update(self, q: Any, v: Any, u: Any, p: Any, t: Any, c: Any, h: Any) -> Any:
        """The condition of ``G`` at the accepted state; the loops' entries are updated after the projection
        (:meth:`_build`)."""
        return CompiledSpatialLoopScheme.controller_update(self, q, v, u, p, t, c, h)

    def initial_controller(self, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """``[z = 0, e(q0, v0, 0), ring, condition of G at the start, 0]``."""
        return np.concatenate([SchemeLoopTerms.initial_controller(self, q, qdot),
                               CompiledSpatialLoopScheme.initial_controller(self, q, qdot)])

    def _build(self) -> tuple[Any, list]:
        """The projected step of :class:`CompiledSpatialLoopScheme`, then the loops' entries updated over the step
        at the projected state (:meth:`SchemeLoopTerms.controller_update`), as the numpy path updates them after its
        projection."""
        import casadi as ca

        step, extra = CompiledSpatialLoopScheme._build(self)
        tree = self.loop_model.tree
        nq, nv, first = tree.n_positions, tree.n_velocities, self.status_index + len(STATUS)
        q, v, u = ca.SX.sym("q", nq), ca.SX.sym("v", nv), ca.SX.sym("u", self.input_size)
        p, t, c, h = ca.SX.sym("p", 0), ca.SX.sym("t"), ca.SX.sym("c", self.loop_size), ca.SX.sym("h")
        update = ca.Function("loop_update", [q, v, u, p, t, c, h],
                             [SchemeLoopTerms.controller_update(self, q, v, u, p, t, c, h)])
        y, u_in, step_h = ca.MX.sym("y", self.state_size), ca.MX.sym("u", self.input_size), ca.MX.sym("h")
        p_in, t0, k = ca.MX.sym("p", 0), ca.MX.sym("t0"), ca.MX.sym("k")
        out = step(y, u_in, step_h, p_in, t0, k)
        after = update(out[:nq], out[nq:nq + nv], u_in, p_in, t0 + (k + 1.0) * step_h, y[first:first + self.loop_size],
                       step_h)
        out = ca.vertcat(out[:first], after, out[first + self.loop_size:])
        return ca.Function("step", [y, u_in, step_h, p_in, t0, k], [out]), extra

    def held_inputs(self, inputs: Mapping[str, Any] | None) -> np.ndarray:
        """:meth:`SchemeLoopTerms.held_inputs` (by port actuator name)."""
        return SchemeLoopTerms.held_inputs(self, inputs)

    def restarted(self, state: np.ndarray, held: np.ndarray | None, t: float = 0.0) -> np.ndarray:
        """``state`` with ``a`` and ``v_dot`` solved again at its ``(q, v)``, time ``t`` [s] and the held inputs with
        the loops at the stored entries (:func:`~ctmm.compiled_spatial_scheme_loops.restarted_loop_state`)."""
        return restarted_loop_state(self, state, held, t, self.loop_size)

    def signal_states(self, controller: np.ndarray, times: np.ndarray) -> np.ndarray:
        """:meth:`SchemeLoopTerms.signal_states` of the loops' entries of stored controller rows."""
        return SchemeLoopTerms.signal_states(self, controller[:, :self.loop_size], times)


def simulate_spatial_loop_scheme_control_generated(controlled: ControlledModel, q0: Any, v0: Any, *, t_final: float,
                                                   dt: float, scheme: Scheme | str,
                                                   references: Mapping[str, Any] | None = None,
                                                   inputs: Mapping[str, Any] | None = None,
                                                   outputs: Sequence[str] = (), store_every: int = 1,
                                                   divergence_bound: float | None = None, projection: bool = True,
                                                   cache_dir: str | os.PathLike | None = None) -> SimulationResult:
    """A DT-TMM scheme of a spatial kinematic loop model with its feedback loops in generated C (module docstring).

    The result is the numpy loop driver's (:func:`ctmm.control.planar_time.simulate_closed_loop` with the scheme):
    the tree's signals, the cut loads with each row's actuator values, ``"drift"``, ``"drift_rate"``, ``outputs``,
    ``"<loop>.y"``, ``"<loop>.u"``; method ``"dt-tmm-generated/<scheme>"``, ``info`` with ``compiled``,
    ``compile_time_s``, ``newton_iterations`` (the total), ``loops``, ``projection``.

    Raises
    ------
    ModelError
        What the generated step refuses (named), bad arguments.
    ConvergenceError, SimulationError
        A step that does not converge, a non-finite or diverging state (``divergence_bound``: the numpy path's rule),
        a singular loop configuration, a failed projection: time, element, partial result.
    """
    scheme = as_scheme(scheme)
    model = controlled.plant
    n_steps = step_total(t_final, dt)
    dt = float(t_final) / n_steps
    store_every = check_store_every(validation.integer("store_every", store_every, minimum=1))
    if divergence_bound is not None:
        divergence_bound = validation.positive("divergence_bound", divergence_bound)
    compiled = CompiledSpatialLoopSchemeControl(controlled, scheme, references=references, inputs=inputs, dt=dt,
                                                store_every=store_every, projection=projection, cache_dir=cache_dir)
    for name in outputs:
        controlled.ports.check_sensor(name, "output (sensor)")
    q, v = model.state(q0, v0)
    warn_conditionally_stable(model.tree, scheme)
    start = compiled.initial_state(np.concatenate([q, v]))
    times, states, wall, total = generated_rows(compiled, start, dt, n_steps)
    nq, n, status = model.tree.n_positions, model.tree.n_velocities, compiled.status_index
    method = f"dt-tmm-generated/{scheme.name}"
    info = {"dt": dt, "method": method, "scheme": repr(scheme), "wall_time_s": wall, "compiled": True,
            "compile_time_s": compiled.compile_time_s, "newton_iterations": total,
            "loops": {law.name: "real-time" if law.steps == 0 else "history" for law in compiled.loops.laws},
            "projection": compiled.projection}
    plant, signals_of = plant_of(model), compiled.loops.signals()
    input_signals = {name: as_signal(f"inputs[{name!r}]", value) for name, value in (inputs or {}).items()}
    first = status + len(STATUS)

    def result(count: int) -> SimulationResult:
        t, block = times[:count], states[:count]
        entries = compiled.signal_states(block[:, first:], t)
        loop_states = np.hstack([block[:, :nq + n], entries])
        applied = applied_loop_inputs(controlled, compiled.loops, input_signals, t, signals_of(loop_states, t)[1])
        signals, units = plant.signals(t, block[:, :nq], block[:, nq:nq + n], outputs, inputs=applied)
        extra = add_loop_signals(controlled, compiled.loops, signals_of, loop_states, t, signals, units)
        failed = {"failed": True} if count < len(times) else {}
        return signal_result(SignalSystem(model, units, list(controlled.loops)), t, signals, method,
                             {**info, **extra, **failed})

    run = checked_spatial_result(compiled, times, states, dt, method, result, divergence_bound,
                                 compiled.held_inputs(None))
    check_cut_rows(compiled, times, states, f"spatial kinematic loop {model.name!r} with loops ({method})", result)
    if compiled.projection:
        run.info["max_drift_after_projection"] = float(np.max(states[:, -1]))
    return run
