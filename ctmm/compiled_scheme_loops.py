"""Generated DT-TMM schemes of planar models with real-time Feedback loops closed inside the Newton step (issue 13).

``ctmm.simulate(ControlledModel(planar_model, loops), t_final, dt, method=<scheme>, compiled=True)`` (and
``ctmm.simulate(planar_model, ..., loops=..., method=<scheme>, compiled=True)``) runs here: the step of
:mod:`ctmm.compiled_scene_schemes` (the scheme's second-order form, Newton in generated C) on the closed-loop
acceleration

``qddot(q, v, t) = sweep(q, v, u(q, v, t), t)``,   ``u = sum_loops w_j sat(-C_j z_j - D_j e_j) + inputs(t)``,
``e_j = y_j(q, v) - r_j(t)``

with every loop stated by :class:`~ctmm.compiled_loops.ClosedLoops` (its sensors, weights, saturation,
references and open-loop inputs on casadi symbols: the ones the generated RK4 compiles).  ``u`` is evaluated at
the Newton iterate ``(q, v)`` and the scheme's evaluation time ``t_n + fraction dt`` -- where the Python path
(:mod:`ctmm.control.implicit_loops`, its ``inputs`` hook) evaluates it -- so the loops are implicit in the step
(no added lag) and their state dependence is in the Newton tangent (casadi's exact derivative through the
sensors and the sweep).  The initial acceleration is the closed-loop one at ``t = 0``; the scheme's stability
check uses the closed-loop linearisation (:func:`ctmm.planar.guards.check_scheme`).  The two paths agree to
round-off (``tests/test_compiled_scene_schemes_loops.py``, which also checks a PD loop against the independent
Lagrange model in a Newmark step written in the test).

LTI controllers ``C(s)`` (proper, SISO; states ``z``, ``z' = A z + B e``) are stepped as the Python path steps
them: by the trapezoidal rule from the step start ``t_n`` to the iterate's time ``t_n + s``,
``(I - s A / 2) z = (I + s A / 2) z_n + s B (e_n + e) / 2`` with ``e`` at the iterate (so implicit in the step and
in the Newton tangent), and over the whole step at the accepted state.  The generated state carries ``[z_n, e_n]``
after :data:`~ctmm.compiled_scene_schemes.STATUS` (:attr:`CompiledSchemeLoops.controller_size`).

Delayed loops (any ``tau >= dt``, and ``>= 1.4 dt`` with Wilson-theta, as the Python path requires; the step
``dt`` is then a constant of the code) read a ring of the loop signals stored at the last accepted steps, carried
after ``[z_n, e_n]`` (the initial signal held before ``t = 0``).  ``y(t_n + lead dt - tau)`` lies ``j + f`` steps
after ``t_n`` (``j`` whole, ``0 <= f < 1``; lead = the scheme's evaluation fraction inside Newton, 1 at the
accepted state, 0 at restarts and records): on a sample (``f = 0``: ``tau`` a whole multiple of ``dt`` with
Newmark, generalized-alpha, Houbolt, forward Euler) the ring returns it; between two samples it interpolates them
by cubic Hermite from their values and rates, as the Python path's delay history
(:class:`ctmm.control.history.DelayHistory`) does.  The ring then also stores each sample's rate
``dy/dt = J_q qdot + J_v qddot`` with ``qddot`` the closed loop's acceleration at the accepted state (one more sweep
per step; the Python path forms the same derivative by a fourth-order difference, ~1e-12 apart), and restarts
(:meth:`CompiledSchemeLoops.restarted`, where co-simulated controllers were sampled) replace the newest rate with
the one at the new held outputs, as the Python path's history records it after sampling.  The two paths agree to
round-off (``tests/test_compiled_scheme_delays.py``).  The initial acceleration and the stability check take the
delayed loops at the current state (exact at ``t = 0``; the check then also counts their gain, conservatively).

Co-simulated controllers together with loops: :mod:`ctmm.compiled_scheme_cosim` runs this step between their
samples, their held outputs the input ``u``, and restarts it with :meth:`CompiledSchemeLoops.restarted` (the
loops at the stored controller states and ring).

What compiles: static-gain loops ``u = -K e`` with weighted sensor terms (a PD: ``sensor=[(angle, kp),
(rate, kd)]``, ``gain=1``), LTI controllers, saturation, references and open-loop inputs that are numbers or
symbolic :mod:`ctmm.signals`, loops on beam station moment pairs (:attr:`ctmm.compiled_loops.ClosedLoops.channels`),
delayed loops with every scheme, co-simulated controllers beside them.  Refused by name
(:class:`~ctmm.errors.ModelError`; ``compiled=None`` runs them in Python): a scheme whose start-up evaluates at
another fraction of the step than its later steps (with delayed loops; none of :data:`ctmm.schemes.SCHEMES`), and
what :class:`ClosedLoops`, the Python path (delays shorter than ``dt`` or ``1.4 dt``) and
:class:`~ctmm.compiled_scene_schemes.CompiledSceneScheme` refuse.
"""
from __future__ import annotations

import math
import os
from typing import Any, Mapping, Sequence

import numpy as np

from .compiled_control import add_loop_signals
from .compiled_loops import ClosedLoops, controller_realisation
from .compiled_parameters import compiled_actuators
from .compiled_scene import symbolic_accelerations_with_inputs
from .compiled_scene_schemes import STATUS, CompiledSceneScheme, scheme_maps, simulate_scheme_generated
from .control.controlled_model import ControlledModel
from .control.implicit_loops import check_scheme_delays
from . import validation
from .errors import ModelError, SimulationError
from .planar.integrate import PlanarSimulation, model_signals, step_total
from .planar.model import PlanarModel
from .results import SimulationResult
from .schemes import Scheme, as_scheme
from .signal_results import SignalSystem, signal_result

__all__ = ["CompiledSchemeLoops", "loop_refusal", "simulate_scheme_loops_generated"]


def loop_refusal(controlled: Any) -> str:
    """Why the generated DT-TMM step cannot close the loops of ``controlled`` ("" when it can)."""
    if not isinstance(controlled, ControlledModel) or not isinstance(controlled.plant, PlanarModel):
        return f"needs a ctmm.control.ControlledModel of a PlanarModel, got {controlled!r}"
    for loop in controlled.loops:
        controller_realisation(loop)                # an improper C(s) raises, naming the loop
    return ""


class CompiledSchemeLoops(CompiledSceneScheme):
    """The generated and compiled DT-TMM step of a planar plant with its real-time loops closed inside Newton.

    Parameters
    ----------
    controlled : ControlledModel
        A compilable planar plant and loops :func:`loop_refusal` accepts.
    scheme : Scheme or str
        A :mod:`ctmm.schemes` scheme or its name.
    references : mapping, optional
        ``{loop name: number or symbolic ctmm.signals signal}`` [sensed unit] (default 0), constants of the code.
    inputs : mapping, optional
        ``{actuator name: number or symbolic signal}`` open-loop actuator values [SI], constants of the code.
    store_every, tolerance, max_iterations, rows, cache_dir, compiler
        As in :class:`~ctmm.compiled_scene_schemes.CompiledSceneScheme`.
    dt : float, optional
        The step [s]; required with delayed loops (each delay at least ``dt``, and ``fraction dt`` with
        Wilson-theta; the library serves this step only).

    Attributes
    ----------
    controlled : ControlledModel
    loops : ClosedLoops
        The loops on symbols.
    stateful : list of (int, int, int)
        ``(loop index, offset in z, order)`` of the loops with controller states.
    fraction : float
        The scheme's evaluation time after ``t_n`` as a fraction of the step.
    reads : dict
        ``{lead: [(j, f) per delayed loop]}``: ``y(t_n + lead dt - tau)`` lies ``j + f`` steps after ``t_n``
        (``j`` whole, ``0 <= f < 1``), for the leads 0 (restarts, records), :attr:`fraction` (Newton) and 1 (the
        accepted state).
    hermite : bool
        Some read falls between two samples: the ring also stores the signals' rates (cubic Hermite).
    columns : int
        Samples per delayed loop in the ring.
    controller_size : int
        ``[z, e_n, ring]`` entries of the generated state after the status (0 without controller states or delays).

    Raises
    ------
    ModelError
        What :func:`loop_refusal`, :class:`ClosedLoops` or the generated scheme refuses (named); a delayed loop
        without ``dt`` or with a delay the Python path refuses (shorter than ``dt``, or ``fraction dt``).
    """

    def __init__(self, controlled: ControlledModel, scheme: Scheme | str = "newmark", *,
                 references: Mapping[str, Any] | None = None, inputs: Mapping[str, Any] | None = None,
                 store_every: int = 1, tolerance: float = 1e-10, max_iterations: int = 20, rows: int = 64,
                 dt: float | None = None, cache_dir: str | os.PathLike | None = None,
                 compiler: str | None = None) -> None:
        reason = loop_refusal(controlled)
        if reason:
            raise ModelError(f"CompiledSchemeLoops: {reason}")
        self.controlled, self.dt = controlled, None if dt is None else validation.positive("dt", dt)
        self.loops = ClosedLoops(controlled, compiled_actuators(controlled.plant), self.dt, references, inputs,
                                 whole_delays=False)
        self.stateful, offset = [], 0          # (loop index, offset in z, order) of the loops with controller states
        for k, law in enumerate(self.loops.laws):
            if law.A.shape[0]:
                self.stateful.append((k, offset, law.A.shape[0]))
                offset += law.A.shape[0]
        self.fraction, self.reads, self.hermite, self.columns = 1.0, {}, False, 0
        if self.loops.delayed:
            self._plan_ring(as_scheme(scheme))
        self.ring_start = offset + len(self.stateful)
        self.ring_rows = len(self.loops.delayed) * (2 if self.hermite else 1)     # values [, rates]
        self.controller_size = self.ring_start + self.ring_rows * self.columns     # [z, e_n, ring]
        super().__init__(controlled.plant, scheme, store_every=store_every, tolerance=tolerance,
                         max_iterations=max_iterations, rows=rows, cache_dir=cache_dir, compiler=compiler)

    def _plan_ring(self, scheme: Scheme) -> None:
        """:attr:`fraction`, :attr:`reads`, :attr:`hermite` and :attr:`columns` of the delayed loops, after the
        checks of the Python path (each delay at least ``dt``; ``fraction dt`` with Wilson-theta)."""
        laws = [self.loops.laws[k] for k in self.loops.delayed]
        if self.dt is None:
            raise ModelError(f"loop {laws[0].name!r}: a delayed loop (delay = {laws[0].delay!r} s) needs the step "
                             "dt to compile its history ring")
        fractions = {m.time_fraction for m in scheme_maps(scheme, 1.0)}
        if len(fractions) > 1:
            raise ModelError(f"loop {laws[0].name!r}: {scheme!r} imposes the equations of motion at different "
                             f"fractions of the step {sorted(fractions)} (a start-up), which the generated delay "
                             "ring does not follow; use compiled=None")
        self.fraction = float(fractions.pop())
        for law in laws:
            if law.delay < self.dt * (1.0 - 1e-9):
                raise ModelError(f"loop {law.name!r}: delay = {law.delay!r} s is shorter than the step dt = "
                                 f"{self.dt!r} s; a fixed-step integrator evaluates the loop inside the step, so "
                                 f"the delay must be 0 or at least dt: use dt <= {law.delay!r} s (or delay=0)")
        check_scheme_delays(laws, scheme, self.dt)
        for lead in (0.0, self.fraction, 1.0):
            self.reads[lead] = []
            for law in laws:
                x = lead - law.delay / self.dt
                node = abs(x - round(x)) <= 1e-9 * max(1.0, abs(x))      # a stored sample (whole multiple)
                j = round(x) if node else math.floor(x)
                self.reads[lead].append((int(j), 0.0 if node else x - j))
        self.hermite = any(f for read in self.reads.values() for _, f in read)
        self.columns = 1 + max(-j for read in self.reads.values() for j, _ in read)

    def closed_acceleration(self) -> Any:
        """``qddot = acceleration(q, v, u, p, t)`` of the closed loop: the plant's sweep with the loops' outputs
        at ``(q, v, t)`` added to the held inputs ``u`` (:meth:`ctmm.compiled_loops.ClosedLoops.rate`), controller
        states at zero (their value at ``t = 0``; the step moves them, :meth:`iterate_acceleration`).  Also builds
        :attr:`state_functions`: ``restart(q, v, u, p, t, c) -> (qddot, c)``, the acceleration at a stored state
        with its controller entries ``c`` (states ``z_n``, delayed signals from the ring at ``t``) and ``c`` with
        the last ring sample's rates from it (the restart where held controller outputs jump)."""
        import casadi as ca

        loops, n = self.loops, self.model.n_coordinates
        self.sweep = symbolic_accelerations_with_inputs(self.model, self.actuators,
                                                        [unit for _, unit in loops.channels])
        q, v, t = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("t")
        u, p = ca.SX.sym("u", len(self.actuators)), ca.SX.sym("p", self.parameters.size)
        now = [loops.sensors(q, v)[k] for k in loops.delayed]       # the history before t = 0: held
        self.loop_errors = ca.Function("loop_errors", [q, v, p, t], [ca.vertcat(*self.errors(q, v, p, t, now))])
        self.delayed_sensors = ca.Function("delayed_sensors", [q, v], [ca.vertcat(*now)])
        _, qddot = loops.rate(self.sweep, u, p, t, ca.vertcat(q, v, ca.SX.zeros(loops.n_controller_states)), now)
        c = ca.SX.sym("c", self.controller_size)
        state = ca.vertcat(q, v, c[:loops.n_controller_states])
        restart = loops.rate(self.sweep, u, p, t, state, self.delayed_values(c, 0.0, t))[1]
        self.delayed_at = ca.Function("delayed_at", [c, t], [ca.vertcat(*self.delayed_values(c, 0.0, t))])
        self.state_functions = (ca.Function("restart", [q, v, u, p, t, c], [restart, self.with_sample(
            c, q, v, restart, replace=True)]),)
        return ca.Function("acceleration", [q, v, u, p, t], [qddot])

    def errors(self, q: Any, v: Any, p: Any, t: Any, delayed: list) -> list:
        """The errors ``e = y(t - tau) - r(t - tau)`` of the loops with controller states (in :attr:`stateful`
        order), ``delayed`` the delayed loops' signals, on symbols."""
        import casadi as ca

        now, numbers, laws = self.loops.sensors(q, v), self.loops.numbers(p), self.loops.laws
        return [ClosedLoops.law_output(laws[k], numbers[k], delayed[self.loops.delayed.index(k)] if laws[k].steps
                                       else now[k], ca.SX.zeros(size), t)[1] for k, _, size in self.stateful]

    def ring(self, c: Any) -> Any:
        """The delay ring of the controller entries ``c``: (:attr:`ring_rows`, :attr:`columns`), rows the delayed
        loops' signals [then their rates], column ``j`` stored at step ``n - columns + 1 + j`` (the last: ``t_n``)."""
        import casadi as ca

        return ca.reshape(c[self.ring_start:], self.ring_rows, self.columns)

    def delayed_values(self, c: Any, lead: float, t_n: Any) -> list:
        """The delayed loops' signals ``y(t_n + lead dt - tau)`` from the ring as the Python path's delay history
        (:class:`ctmm.control.history.DelayHistory`) gives them: a stored sample, or cubic Hermite between two
        samples from their values and rates; the initial signal before ``t = 0``."""
        import casadi as ca

        if not self.loops.delayed:
            return []
        ring, count, out = self.ring(c), len(self.loops.delayed), []
        for d, (j, f) in enumerate(self.reads[lead]):
            left, right = self.columns - 1 + j, self.columns + j
            if not f:
                out.append(ring[d, left])
                continue
            h = self.dt
            hermite = ((2 * f ** 3 - 3 * f ** 2 + 1) * ring[d, left] + (-2 * f ** 3 + 3 * f ** 2) * ring[d, right]
                       + (f ** 3 - 2 * f ** 2 + f) * h * ring[count + d, left] + (f ** 3 - f ** 2) * h * ring[count + d, right])
            out.append(ca.if_else(t_n + (j + 1) * h < 0.5 * h, ring[d, right], hermite))
        return out

    def with_sample(self, c: Any, q: Any, v: Any, qddot: Any, replace: bool = False) -> Any:
        """``c`` with the delayed loops' signals at ``(q, v)`` [and their rates along ``qddot``] as the ring's newest
        sample: shifted in (``replace``: the newest sample's rates replaced, a restart at the same state)."""
        import casadi as ca

        if not self.loops.delayed or (replace and not self.hermite):
            return c
        column = self.delayed_sensors(q, v)
        if self.hermite:
            column = ca.vertcat(column, self.loops.sensor_rates(q, v, qddot)[self.loops.delayed])
        ring = self.ring(c)
        ring = ca.horzcat(ring[:, :-1], column) if replace else ca.horzcat(ring[:, 1:], column)
        return ca.vertcat(c[:self.ring_start], ca.reshape(ring, -1, 1))

    def trapezoidal(self, c: Any, e: list, s: Any) -> Any:
        """Controller states ``z`` at ``s`` [s] after the step start by the trapezoidal rule of the Python path
        (:class:`ctmm.control.implicit_loops.LoopSteps`): ``(I - s A / 2) z = (I + s A / 2) z_n + s B (e_n + e) / 2``
        per loop, ``c = [z_n, e_n]``, ``e`` the errors at ``t_n + s``."""
        import casadi as ca

        nz, blocks = self.loops.n_controller_states, []
        for j, (k, offset, size) in enumerate(self.stateful):
            law = self.loops.laws[k]
            A, B, z_n = ca.DM(law.A), ca.DM(law.B), c[offset:offset + size]
            rhs = z_n + 0.5 * s * ca.mtimes(A, z_n) + 0.5 * s * B * (c[nz + j] + e[j])
            blocks.append(ca.solve(ca.SX.eye(size) - 0.5 * s * A, rhs))
        return ca.vertcat(*blocks) if blocks else ca.SX(0, 1)

    def iterate_acceleration(self, acceleration: Any, q: Any, v: Any, u: Any, p: Any, t: Any, c: Any, s: Any) -> Any:
        """The closed loop's ``qddot`` at a Newton iterate: controller states advanced trapezoidally from the step
        start to ``t`` with the iterate's errors (implicit, as the Python path's ``inputs`` hook)."""
        import casadi as ca

        delayed = self.delayed_values(c, self.fraction, t - s)
        z = self.trapezoidal(c, self.errors(q, v, p, t, delayed), s) if self.stateful else ca.SX(0, 1)
        return self.loops.rate(self.sweep, u, p, t, ca.vertcat(q, v, z), delayed)[1]

    def controller_update(self, q: Any, v: Any, u: Any, p: Any, t: Any, c: Any, h: Any) -> Any:
        """``[z_{n+1}, e_{n+1}, ring]``: the states over the whole step with the errors at the accepted state, the
        ring shifted by one sample, the accepted state's delayed loop signals last (with their rates along the
        closed loop's acceleration there when the ring interpolates, as the Python path's history stores them)."""
        import casadi as ca

        delayed = self.delayed_values(c, 1.0, t - h)
        e = self.errors(q, v, p, t, delayed)
        z = self.trapezoidal(c, e, h)
        qddot = self.loops.rate(self.sweep, u, p, t, ca.vertcat(q, v, z), delayed)[1] if self.hermite else None
        return self.with_sample(ca.vertcat(z, *e, c[self.ring_start:]), q, v, qddot)

    def initial_controller(self, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """``[z = 0, e(q0, qdot0, 0), ring]``, every ring sample the initial loop signal (the history before 0;
        rates zero, the newest set by :meth:`restarted`)."""
        errors = np.asarray(self.loop_errors(q, qdot, self.parameters, 0.0), dtype=float).reshape(-1)
        start = np.asarray(self.delayed_sensors(q, qdot), dtype=float).reshape(-1)
        column = np.concatenate([start, np.zeros(self.ring_rows - start.size)])
        return np.concatenate([np.zeros(self.loops.n_controller_states), errors, np.tile(column, self.columns)])

    def restarted(self, state: np.ndarray, held: np.ndarray | None, t: float, start: bool = False) -> np.ndarray:
        """:meth:`CompiledSceneScheme.restarted` with the loops at the stored controller entries (states, delayed
        signals from the ring) and the newest ring sample's rates from the new acceleration (the Python path
        stores them after the controllers due at ``t`` were sampled)."""
        n, first = self.model.n_coordinates, self.status_index + len(STATUS)
        out = np.array(state, dtype=float)
        held = np.zeros(len(self.actuators)) if held is None else np.asarray(held, dtype=float)
        acceleration, controller = (np.asarray(part, dtype=float).reshape(-1) for part in self.state_functions[0](
            out[:n], out[n:2 * n], held, self.parameters, validation.finite("t", t), out[first:]))
        out[2 * n:3 * n] = out[3 * n:4 * n] = acceleration
        out[first:] = controller
        if start:
            out[4 * n:5 * n] = out[5 * n:6 * n] = out[:n]
        return out

    def continue_run(self, state: np.ndarray, held: np.ndarray, dt: float, n_steps: int, first_step: int,
                     since_start: int | None = None) -> np.ndarray:
        """:meth:`CompiledSceneScheme.continue_run`, refusing a step other than :attr:`dt` with delayed loops (the ring
        holds one sample per step of :attr:`dt`).

        Raises
        ------
        ModelError
            ``dt`` is not the step the delay rings were built for.
        """
        if self.loops.delayed and not np.isclose(dt, self.dt, rtol=1e-12, atol=0.0):
            raise ModelError(f"compiled has delay rings for dt = {self.dt!r} s, this run's step is {dt!r} s: build a "
                             "CompiledSchemeLoops with this dt")
        return super().continue_run(state, held, dt, n_steps, first_step, since_start)

    def signal_states(self, controller: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Rows of stored controller entries at ``times`` [s] as the ``[z, ring]`` tail of
        :meth:`ClosedLoops.signals`' state: every sample of its ring the delayed signal ``y(t - tau)`` read from
        this ring (:meth:`delayed_values`; rates unused there: zero)."""
        rows, count = controller.shape[0], len(self.loops.delayed)
        theirs = np.zeros((rows, self.loops.ring_columns, 2 * count))
        if count and rows:
            delayed = np.asarray(self.delayed_at.map(rows)(controller.T, np.asarray(times, float)[None, :])).T
            theirs[:, :, :count] = delayed[:, None, :]
        return np.hstack([controller[:, :self.loops.n_controller_states], theirs.reshape(rows, -1)])


def simulate_scheme_loops_generated(controlled: ControlledModel, q0: Any, qdot0: Any, *, t_final: float, dt: float,
                                    scheme: Scheme | str = "newmark", references: Mapping[str, Any] | None = None,
                                    inputs: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                                    store_every: int = 1, divergence_bound: float | None = None,
                                    stability_check: str = "warn", tolerance: float = 1e-10,
                                    max_iterations: int = 20, cache_dir: str | os.PathLike | None = None,
                                    compiled: CompiledSchemeLoops | None = None) -> SimulationResult:
    """A DT-TMM scheme of a controlled planar model with its real-time loops closed in generated C.

    The result is the one of :func:`ctmm.control.planar_time.simulate_closed_loop` with the same scheme
    (coordinates, rates, ``outputs``, ``"<loop>.y"``, ``"<loop>.u"``; method label ``"dt-tmm-generated/<Scheme>"``,
    ``info`` with ``dt``, ``compile_time_s`` and ``newton_iterations`` (the total)).

    Parameters
    ----------
    controlled : ControlledModel
        Plant and loops (:func:`loop_refusal`).
    q0, qdot0 : array_like
        Initial coordinates [rad, m] and rates.
    t_final, dt : float
        End time and step [s].
    scheme : Scheme or str
    references, inputs : mapping, optional
        As in :class:`CompiledSchemeLoops` (with ``compiled``: its own; giving them too is refused).
    outputs : sequence of str
        Sensor names stored at every row.
    store_every, divergence_bound, stability_check, tolerance, max_iterations, cache_dir
        As in :func:`ctmm.compiled_scene_schemes.simulate_scheme_generated` (the stability check with the loops).
    compiled : CompiledSchemeLoops, optional
        Of ``controlled`` with this scheme and ``store_every``, to reuse (default: built now).

    Raises
    ------
    ModelError
        What the generated step refuses (named), bad arguments, no compiler.
    ConvergenceError, SimulationError
        As :func:`~ctmm.compiled_scene_schemes.simulate_scheme_generated`, with the result stored before the
        failure (loop signals included) as ``partial_result``.
    """
    step = None if dt is None else t_final / step_total(t_final, dt)        # (None: refused by the scheme's run)
    if compiled is None:
        compiled = CompiledSchemeLoops(controlled, scheme, references=references, inputs=inputs,
                                       store_every=store_every, tolerance=tolerance, max_iterations=max_iterations,
                                       dt=step, cache_dir=cache_dir)
    elif not isinstance(compiled, CompiledSchemeLoops) or compiled.controlled is not controlled or \
            references or inputs:
        raise ModelError(f"compiled must be a CompiledSchemeLoops of this controlled model (its references and "
                         f"inputs are its own: leave references and inputs out), got {compiled!r}")
    signals_of = compiled.loops.signals()

    def result(simulation: PlanarSimulation, failed: bool = False) -> SimulationResult:
        model = controlled.plant
        signals, units = model_signals(model, simulation.t, simulation.q, simulation.qdot, outputs)
        states = simulation.extra.get("controller_states", np.zeros((len(simulation.t), compiled.controller_size)))
        block = np.hstack([simulation.q, simulation.qdot, compiled.signal_states(states, simulation.t)])
        extra = add_loop_signals(controlled, compiled.loops, signals_of, block, simulation.t, signals, units)
        kept = {key: value for key, value in simulation.extra.items() if key != "controller_states"}
        info = {"dt": dt, "method": simulation.method, "wall_time_s": simulation.wall_time_s,
                "n_evaluations": simulation.n_evaluations,
                "loops": {law.name: "real-time" if law.steps == 0 else "history" for law in compiled.loops.laws},
                **kept, **extra, **({"failed": True} if failed else {})}
        return signal_result(SignalSystem(model, units, list(controlled.loops)), simulation.t, signals,
                             simulation.method, info)

    try:
        simulation = simulate_scheme_generated(
            controlled.plant, q0, qdot0, t_final=t_final, dt=dt, scheme=as_scheme(scheme), store_every=store_every,
            divergence_bound=divergence_bound, stability_check=stability_check, tolerance=tolerance,
            max_iterations=max_iterations, compiled=compiled)
    except SimulationError as exc:
        if isinstance(exc.partial_result, PlanarSimulation):
            exc.partial_result = result(exc.partial_result, failed=True)
        raise
    return result(simulation)
