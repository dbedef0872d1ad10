"""Real-time, LTI and delayed feedback loops inside a generated DT-TMM Newton step, for planar and spatial plants.

:class:`SchemeLoopTerms` is the one statement of the loop part of a generated scheme step that
:class:`ctmm.compiled_scheme_loops.CompiledSchemeLoops` (planar, :mod:`ctmm.compiled_scene_schemes`) and
:class:`ctmm.compiled_spatial_scheme_loops.CompiledSpatialSchemeLoops` (spatial, :mod:`ctmm.compiled_spatial_schemes`)
mix into their step: both families call the hooks ``closed_acceleration``, ``iterate_acceleration``,
``controller_update`` and ``initial_controller`` where the controller entries of the generated state enter, and the
loops are stated on casadi symbols by :class:`~ctmm.compiled_loops.ClosedLoops` (planar sensors, or the spatial ones
of :class:`~ctmm.compiled_spatial_loops.SpatialSymbols`: ``q`` of ``nq`` entries, ``v`` of ``nv``, so nothing here
depends on the plant's dimension).

The closed-loop acceleration is ``a(q, v, t) = sweep(q, v, u(q, v, t), t)``, ``u = sum_loops w_j sat(-C_j z_j - D_j
e_j) + inputs(t)``, ``e_j = y_j(q, v) - r_j(t)``, evaluated at the Newton iterate and the scheme's evaluation time
``t_n + fraction dt`` (where the Python path, :mod:`ctmm.control.implicit_loops`, evaluates it).  LTI controller
states follow the Python path's trapezoidal rule from the step start to the iterate's time, ``(I - s A / 2) z =
(I + s A / 2) z_n + s B (e_n + e) / 2``, and over the whole step at the accepted state; the generated state carries
``[z_n, e_n]``.  Delayed loops read a ring of the loop signals at the last accepted steps (after ``[z_n, e_n]``; the
initial signal held before ``t = 0``): a stored sample when ``tau`` is a whole number of steps after the evaluation
point, otherwise cubic Hermite between two samples from their values and rates (as
:class:`ctmm.control.history.DelayHistory`), the rates ``dy/dt = J_q q_dot + J_v a`` with ``a`` the closed loop's
acceleration at the accepted state; a scheme whose start-up evaluates at another fraction of the step is read at each
step's own fraction (:attr:`SchemeLoopTerms.fractions`).  Details and checks: ``docs/spatial.md`` §6b,
``tests/test_compiled_scheme_delays.py``, ``tests/test_compiled_spatial_scheme_loops.py``.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import validation
from .compiled_loops import ClosedLoops
from .compiled_scene_schemes import scheme_maps
from .control.implicit_loops import check_scheme_delays
from .errors import ModelError
from .generated_loop import BlockRunner
from .schemes import Scheme

__all__ = ["BufferedCall", "SchemeLoopTerms", "loop_actuators"]


def loop_actuators(controlled: Any, inputs: Any, held: Any) -> tuple[str, ...]:
    """The port actuators of a generated step's input ``u``: the loops', then those of the open-loop ``inputs``
    (mapping) and the ``held`` ones (names), each once, checked against ``controlled.ports``.

    Raises
    ------
    ModelError
        An unknown actuator (named by the ports' check).
    """
    ports = controlled.ports
    for name in inputs or {}:
        ports.check_actuator(name, "inputs: actuator")
    for name in held:
        ports.check_actuator(name, "held: actuator")
    return tuple(dict.fromkeys([name for loop in controlled.loops for name, _ in loop.actuator_terms]
                               + list(inputs or {}) + list(held)))


class BufferedCall:
    """A casadi ``Function`` of dense column inputs and outputs called through its buffer interface: the numbers are
    copied into arrays the buffer points at, not converted through casadi ``DM`` objects (a restart between two
    sample intervals of co-simulated controllers: about 110 us through ``DM``, a few us here).  A function with a
    sparse input or output is called the ordinary way.

    Parameters
    ----------
    function : casadi.Function
    """

    def __init__(self, function: Any) -> None:
        self.function = function
        dense = all(function.sparsity_in(i).is_dense() and function.size2_in(i) <= 1 for i in range(function.n_in())) \
            and all(function.sparsity_out(i).is_dense() and function.size2_out(i) <= 1 for i in range(function.n_out()))
        self.buffer = None
        if dense:
            self.buffer, self.evaluate = function.buffer()
            self.inputs = [np.zeros(function.nnz_in(i)) for i in range(function.n_in())]
            self.outputs = [np.zeros(function.nnz_out(i)) for i in range(function.n_out())]
            for i, array in enumerate(self.inputs):
                self.buffer.set_arg(i, memoryview(array))
            for i, array in enumerate(self.outputs):
                self.buffer.set_res(i, memoryview(array))

    def __call__(self, *values: Any) -> list[np.ndarray]:
        """The outputs (new 1-D arrays) at the inputs ``values`` (numbers or arrays of the inputs' sizes).

        Raises
        ------
        RuntimeError
            The generated function returned a failure status.
        """
        if self.buffer is None:
            return [np.asarray(out, dtype=float).reshape(-1) for out in self.function.call(list(values))]
        for array, value in zip(self.inputs, values):
            array[:] = np.asarray(value, dtype=float).reshape(-1)
        self.evaluate()
        if self.buffer.ret():
            raise RuntimeError(f"the generated function {self.function.name()!r} failed (status {self.buffer.ret()})")
        return [array.copy() for array in self.outputs]


class SchemeLoopTerms:
    """The loop part of a generated DT-TMM scheme step (a mixin of the planar and spatial scheme classes).

    The class it is mixed into sets :attr:`loops`, :attr:`parameters` (the ``p`` column, numbers) and
    :attr:`actuators` before the step is built, and provides :meth:`plant_sweep`.

    Attributes
    ----------
    loops : ClosedLoops
        The loops on symbols.
    dt : float or None
        The step [s] the delay ring is built for (required with delayed loops).
    stateful : list of (int, int, int)
        ``(loop index, offset in z, order)`` of the loops with controller states.
    fraction : float
        The scheme's evaluation time after ``t_n`` as a fraction of the step (after its start-up).
    fractions : tuple of float
        Every evaluation fraction of its steps, sorted (more than one: a start-up at another fraction, whose steps
        the ring reads at their own; :meth:`iterate_acceleration`).
    reads : dict
        ``{lead: [(j, f) per delayed loop]}``: ``y(t_n + lead dt - tau)`` lies ``j + f`` steps after ``t_n``
        (``j`` whole, ``0 <= f < 1``), for the leads 0 (restarts, records), each of :attr:`fractions` (Newton) and
        1 (the accepted state).
    hermite : bool
        Some read falls between two samples: the ring also stores the signals' rates (cubic Hermite).
    columns : int
        Samples per delayed loop in the ring.
    controller_size : int
        ``[z, e_n, ring]`` entries of the generated state after the status.
    state_functions : tuple
        ``(restart, loop_errors, delayed_sensors, delayed_at)`` (compiled with the step):
        ``restart(q, v, u, p, t, c) -> (a, c)``, ``loop_errors(q, v, p, t)``, ``delayed_sensors(q, v)``,
        ``delayed_at(c, t)``.
    """

    loops: ClosedLoops
    dt: float | None
    parameters: np.ndarray
    actuators: tuple
    state_functions: tuple = ()

    def plant_sweep(self) -> Any:
        """``acceleration(q, v, u, p, t)`` of the plant (casadi ``Function``), ``u`` the :attr:`actuators` followed
        by the loops' channels (:attr:`ClosedLoops.channels`)."""
        raise NotImplementedError

    def setup_loops(self, scheme: Scheme) -> None:
        """:attr:`stateful`, the ring plan and :attr:`controller_size` from :attr:`loops` and :attr:`dt`."""
        self.stateful, offset = [], 0
        for k, law in enumerate(self.loops.laws):
            if law.A.shape[0]:
                self.stateful.append((k, offset, law.A.shape[0]))
                offset += law.A.shape[0]
        self.fraction, self.reads, self.hermite, self.columns = 1.0, {}, False, 0
        self.fractions: tuple = (1.0,)
        if self.loops.delayed:
            self._plan_ring(scheme)
        self.ring_start = offset + len(self.stateful)
        self.ring_rows = len(self.loops.delayed) * (2 if self.hermite else 1)     # values [, rates]
        self.controller_size = self.ring_start + self.ring_rows * self.columns     # [z, e_n, ring]

    def _plan_ring(self, scheme: Scheme) -> None:
        """:attr:`fraction`, :attr:`reads`, :attr:`hermite` and :attr:`columns` of the delayed loops, after the
        checks of the Python path (each delay at least ``dt``, and at least the largest evaluation fraction of any
        step times ``dt``: Wilson-theta's ``1.4 dt``, a start-up's later fraction too,
        :func:`ctmm.control.implicit_loops.check_scheme_delays`)."""
        laws = [self.loops.laws[k] for k in self.loops.delayed]
        if self.dt is None:
            raise ModelError(f"loop {laws[0].name!r}: a delayed loop (delay = {laws[0].delay!r} s) needs the step "
                             "dt to compile its history ring")
        per_step = [float(m.time_fraction) for m in scheme_maps(scheme, 1.0)]
        self.fraction, self.fractions = per_step[-1], tuple(sorted(set(per_step)))
        for law in laws:
            if law.delay < self.dt * (1.0 - 1e-9):
                raise ModelError(f"loop {law.name!r}: delay = {law.delay!r} s is shorter than the step dt = "
                                 f"{self.dt!r} s; a fixed-step integrator evaluates the loop inside the step, so "
                                 f"the delay must be 0 or at least dt: use dt <= {law.delay!r} s (or delay=0)")
        check_scheme_delays(laws, scheme, self.dt)      # every step's fraction, a start-up's too (the Python rule)
        for lead in (0.0, *self.fractions, 1.0):
            self.reads[lead] = []
            for law in laws:
                x = lead - law.delay / self.dt
                node = abs(x - round(x)) <= 1e-9 * max(1.0, abs(x))      # a stored sample (whole multiple)
                j = round(x) if node else math.floor(x)
                self.reads[lead].append((int(j), 0.0 if node else x - j))
        self.hermite = any(f for read in self.reads.values() for _, f in read)
        self.columns = 1 + max(-j for read in self.reads.values() for j, _ in read)

    def closed_acceleration(self) -> Any:
        """``a = acceleration(q, v, u, p, t)`` of the closed loop: the plant's sweep with the loops' outputs at
        ``(q, v, t)`` added to the held inputs ``u`` (:meth:`ctmm.compiled_loops.ClosedLoops.rate`), controller
        states at zero (their value at ``t = 0``; the step moves them, :meth:`iterate_acceleration`).  Also sets
        :attr:`state_functions` (on symbols; the class it is mixed into compiles them with the step)."""
        import casadi as ca

        loops = self.loops
        self.sweep = self.plant_sweep()
        q, v, t = ca.SX.sym("q", loops.nq), ca.SX.sym("v", loops.nv), ca.SX.sym("t")
        u, p = ca.SX.sym("u", len(self.actuators)), ca.SX.sym("p", self.parameters.size)
        now = self._delayed_now(q, v)                       # the history before t = 0: held
        loop_errors = ca.Function("loop_errors", [q, v, p, t], [ca.vertcat(*self.errors(q, v, p, t, now))])
        delayed_sensors = ca.Function("delayed_sensors", [q, v], [ca.vertcat(*now)])
        c, nz = ca.SX.sym("c", self.controller_size), loops.n_controller_states
        delayed_at = ca.Function("delayed_at", [c, t], [ca.vertcat(*self.delayed_values(c, 0.0, t))])
        # one closed-loop rate at given controller states z and delayed signals d, called (MX) by the acceleration
        # and the restart: the generated C holds the sweep once for both
        z, d = ca.SX.sym("z", nz), ca.SX.sym("d", len(now))
        rate = ca.Function("loop_rate", [q, v, u, p, t, z, d],
                           [loops.rate(self.sweep, u, p, t, ca.vertcat(q, v, z), [d[i] for i in range(len(now))])[1]])
        acceleration = ca.SX.sym("acceleration", loops.nv)
        sample = ca.Function("restart_sample", [c, q, v, acceleration],
                             [self.with_sample(c, q, v, acceleration, replace=True)])
        Q, V, T = ca.MX.sym("q", loops.nq), ca.MX.sym("v", loops.nv), ca.MX.sym("t")
        U, P, C = ca.MX.sym("u", len(self.actuators)), ca.MX.sym("p", self.parameters.size), ca.MX.sym("c", c.size1())
        restart = rate(Q, V, U, P, T, C[:nz], delayed_at(C, T))
        self.state_functions = (ca.Function("restart", [Q, V, U, P, T, C], [restart, sample(C, Q, V, restart)]),
                                loop_errors, delayed_sensors, delayed_at)
        return ca.Function("acceleration", [Q, V, U, P, T], [rate(Q, V, U, P, T, ca.MX.zeros(nz),
                                                                  delayed_sensors(Q, V))])

    def _delayed_now(self, q: Any, v: Any) -> list:
        """The delayed loops' signals at ``(q, v)`` on symbols."""
        sensed = self.loops.sensors(q, v)
        return [sensed[k] for k in self.loops.delayed]

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

    def _delayed_at_evaluation(self, c: Any, s: Any, t_n: Any) -> list:
        """:meth:`delayed_values` at the scheme's evaluation time ``t_n + s`` inside Newton, ``s`` [s] the step's
        evaluation offset (symbolic: a start-up's steps evaluate at other fractions of ``dt`` than the later ones,
        :attr:`fractions`; the read of the fraction nearest ``s / dt``, as the Python path reads its history at
        each step's own evaluation time)."""
        import casadi as ca

        values = self.delayed_values(c, self.fractions[-1], t_n)
        for k in range(len(self.fractions) - 2, -1, -1):
            lower = self.delayed_values(c, self.fractions[k], t_n)
            middle = 0.5 * (self.fractions[k] + self.fractions[k + 1]) * self.dt
            values = [ca.if_else(s < middle, a, b) for a, b in zip(lower, values)]
        return values

    def with_sample(self, c: Any, q: Any, v: Any, acceleration: Any, replace: bool = False) -> Any:
        """``c`` with the delayed loops' signals at ``(q, v)`` [and their rates along ``acceleration``] as the
        ring's newest sample: shifted in (``replace``: the newest sample's rates replaced, a restart at the same
        state)."""
        import casadi as ca

        if not self.loops.delayed or (replace and not self.hermite):
            return c
        column = ca.vertcat(*self._delayed_now(q, v))
        if self.hermite:
            column = ca.vertcat(column, self.loops.sensor_rates(q, v, acceleration)[self.loops.delayed])
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
        """The closed loop's acceleration at a Newton iterate: controller states advanced trapezoidally from the
        step start to ``t`` with the iterate's errors (implicit, as the Python path's ``inputs`` hook)."""
        import casadi as ca

        delayed = self._delayed_at_evaluation(c, s, t - s)
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
        acceleration = self.loops.rate(self.sweep, u, p, t, ca.vertcat(q, v, z), delayed)[1] if self.hermite \
            else None
        return self.with_sample(ca.vertcat(z, *e, c[self.ring_start:]), q, v, acceleration)

    def initial_controller(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``[z = 0, e(q0, v0, 0), ring]``, every ring sample the initial loop signal (the history before 0;
        rates zero, the newest set by the restart)."""
        _, loop_errors, delayed_sensors, _ = self.state_functions
        errors = np.asarray(loop_errors(q, v, self.parameters, 0.0), dtype=float).reshape(-1)
        start = np.asarray(delayed_sensors(q, v), dtype=float).reshape(-1)
        column = np.concatenate([start, np.zeros(self.ring_rows - start.size)])
        return np.concatenate([np.zeros(self.loops.n_controller_states), errors, np.tile(column, self.columns)])

    def held_inputs(self, inputs: Any) -> np.ndarray:
        """The step's input vector ``u`` of held port actuator values ``{name: number}`` (open-loop ``inputs`` are
        compiled in; zero for the others).

        Raises
        ------
        ModelError
            A name that is not among :attr:`actuators`.
        """
        held = dict(inputs or {})
        for name in held:
            if name not in self.actuators:
                raise ModelError(f"held input {name!r}: the generated step drives the port actuators "
                                 f"{', '.join(self.actuators) or '(none)'}")
        return np.array([float(held.get(name, 0.0)) for name in self.actuators])

    def restart_terms(self, q: np.ndarray, v: np.ndarray, held: np.ndarray, t: float, c: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
        """``(a, c)``: the closed loop's acceleration at a stored state ``(q, v)``, time ``t`` [s] and held inputs
        with its controller entries ``c``, and ``c`` with the newest ring sample's rates from it (the Python path
        stores them after the controllers due at ``t`` were sampled)."""
        if getattr(self, "restart_call", None) is None:
            self.restart_call = BufferedCall(self.state_functions[0])
        acceleration, controller = self.restart_call(q, v, held, self.parameters, t, c)
        return acceleration, controller

    def continue_run(self, state: np.ndarray, held: np.ndarray, dt: float, n_steps: int, first_step: int,
                     since_start: int | None = None, runner: BlockRunner | None = None) -> np.ndarray:
        """The scheme's ``continue_run``, refusing a step other than :attr:`dt` with delayed loops (the ring holds
        one sample per step of :attr:`dt`).

        Raises
        ------
        ModelError
            ``dt`` is not the step the delay rings were built for.
        """
        dt = validation.positive("dt", dt)
        if self.loops.delayed and not abs(dt - self.dt) <= 1e-12 * self.dt:        # (np.isclose: 10 us a call)
            raise ModelError(f"compiled has delay rings for dt = {self.dt!r} s, this run's step is {dt!r} s: build "
                             f"a {type(self).__name__} with this dt")
        return super().continue_run(state, held, dt, n_steps, first_step, since_start,   # type: ignore[misc]
                                      runner=runner)

    def signal_states(self, controller: np.ndarray, times: np.ndarray) -> np.ndarray:
        """Rows of stored controller entries at ``times`` [s] as the ``[z, ring]`` tail of
        :meth:`ClosedLoops.signals`' state: every sample of its ring the delayed signal ``y(t - tau)`` read from
        this ring (:meth:`delayed_values`; rates unused there: zero)."""
        rows, count = controller.shape[0], len(self.loops.delayed)
        theirs = np.zeros((rows, self.loops.ring_columns, 2 * count))
        if count and rows:
            delayed = np.asarray(self.state_functions[3].map(rows)(controller.T, np.asarray(times, float)[None, :])).T
            theirs[:, :, :count] = delayed[:, None, :]
        return np.hstack([controller[:, :self.loops.n_controller_states],
                          theirs.reshape(rows, self.loops.ring_columns * 2 * count)])
