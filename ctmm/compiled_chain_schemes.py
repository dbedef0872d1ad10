"""Generated DT-TMM steps of 1-D lumped chains: every implicit scheme of :mod:`ctmm.schemes` in C (issue 13).

``ctmm.simulate(chain, t_final, dt, method="newmark" | "generalized_alpha" | "wilson_theta" | "houbolt" |
"forward_euler" | <Scheme>, compiled=True)`` runs the step generated here (:class:`CompiledChainScheme`; the run, its
guard and its result: :mod:`ctmm.compiled_chain_scheme_runs`).  Two readings, both exact and both certified
before anything is generated:

* **the chain** -- its explicit rates are affine (:func:`ctmm.compiled_chain.affine_form`:
  ``a = Ax x + Av v + a0 + sum_j L_j s_j(t)``, certified against the sweep);
* **the scheme** -- its step is linear in the stored history ``h = (x_n, v_n, a_n, x_{n-1}, x_{n-2})``
  of every point (:class:`SchemeMaps`: ``x_eval = cx delta + P_dx h``, ``v_eval = A delta + P_B h``,
  ``a_eval = C delta + P_D h`` and the new history ``U [h; delta]``, read from
  :meth:`~ctmm.schemes.Scheme.coefficients` and :meth:`~ctmm.schemes.Scheme.update` by unit probes on
  one point and checked at random histories), so a new scheme compiles without touching this module.

The step imposes the equation of motion at the scheme's evaluation level, as the Python DT-TMM path
(:func:`ctmm.timestep.simulate`) does: ``a_eval = Ax x_eval + Av v_eval + a0 + sum_j L_j s_j^eval``
with the loads weighted ``(1 - w) s(t_n) + w s(t_n + h)`` (``w`` the scheme's load weight), so the
correction of every node solves ``(C I - cx Ax - A Av) delta = Ax P_dx h + Av P_B h + f_eval - P_D h``:
a tridiagonal matrix for chains without inerters, factorised once (its LU factors are constants of
the C, the two substitutions ``O(n)`` per step), or the constant inverse for chains whose inerters couple
every node.  Up to :data:`UNROLLED_POINTS` moving masses (``unrolled=``) the step is written out as
straight-line scalar code (casadi ``expand``: the constants folded in, the zeros of the matrices and of the
loops' rows dropped; code and compile time grow with ``n``); above, a tridiagonal step is one C function with a
loop per sweep over the nodes (:mod:`ctmm.compiled_chain_kernel`: the chain's numbers as constant arrays, code size
independent of ``n``, the real-time loops' rank-``k`` part inside it), and the inerters' dense inverse is vector
operations.  A scheme's start-up (Houbolt's two Newmark steps,
:attr:`~ctmm.schemes.Scheme.start_up_steps`) is the other branch of a short-circuit ``if_else`` on the steps since the
history (re)started, the last entry of the state: :mod:`ctmm.compiled_cosim` sets it to zero where a held input jumps
(:meth:`~ctmm.schemes.Scheme.restart`, as the Python path does).  The step, ``store_every`` strides and blocks of stored states are those
of every generated scene (:mod:`ctmm.generated_loop`); ``dt`` is a constant of the code (the cache key).

Stored: positions and velocities of the scheme; accelerations and forces at the points are those of the
equation of motion at the stored states (as the ODE path; the Python DT-TMM path stores the scheme's own
acceleration, which differs from it by the scheme's error for Wilson-theta and generalized-alpha).

Loops (:class:`SchemeLoop`) close as :mod:`ctmm.control.simulate` closes them: real-time loops implicit in
the step (their rank-``k`` part by the Woodbury identity on the banded solve), delayed loops (``delay = m
dt``) from rings of samples in the generated state with the scheme's load weighting, LTI controllers on
the step grid by the trapezoidal rule, references as :mod:`ctmm.signals` signals.

Chains with massless points or a prescribed (signal) start or end motion step their every node and moving support
(:mod:`ctmm.compiled_chain_scheme_nodes`, as the Python DT-TMM path keeps a history at every point); loops and
held actuators on them are refused by name (the generated RK4 takes them).

Refused (:class:`~ctmm.errors.ModelError`): what the generated RK4 of chains refuses (load signals without a
symbolic form, delays that are not whole multiples of ``dt``), loops and held actuators on chains with massless
points or a prescribed motion, and saturated loops (linear in the step).

Co-simulated controllers: their held outputs are the input ``u`` of the step (``actuators``, constant over a
step, so the load weighting leaves them unchanged), and :func:`ctmm.compiled_cosim.simulate_cosimulated_scheme`
samples them in Python between calls into the C (:meth:`CompiledChainScheme.continue_run`).
"""
from __future__ import annotations

import os
import time as _time
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np
import scipy.sparse

from . import validation
from .chain_ode import ChainDynamics
from .compiled_chain import affine_form, sensor_row
from .compiled_chain_condensed import needs_condensed_form
from .compiled_chain_scheme_nodes import node_form, node_start, node_step
from .compiled_chain_kernel import banded_solver, step_kernel, step_matrix, tridiagonal_factors, woodbury_parts
from .compiled_loops import delay_steps
from .control.planar_time import controller_realisation
from .compiled_references import reference_at, symbolic_reference
from .control.chain_plant import ChainPlant
from .errors import ModelError
from .generated_loop import BlockRunner, compiled_time_loop, inlined_call, run_blocks
from .model_description import describe
from .saturation import refuse_saturation
from .schemes import History, Scheme, as_scheme
from .signals import signal_parameters, symbolic_signal

__all__ = ["SchemeMaps", "CompiledChainScheme"]

HISTORY = ("x", "v", "a", "x_old1", "x_old2")
"""The stored history of every point, in the order of the generated state."""
UNROLLED_POINTS = 100
"""Moving masses up to which :class:`CompiledChainScheme` writes its step out as straight-line code by default; above,
the C loops of :mod:`ctmm.compiled_chain_kernel` (``benchmarks/chain_schemes_generated.py``: as fast within ~10 %,
first compile ~1 s of CPU at 1000 masses instead of ~18 s)."""


class SchemeMaps:
    """A scheme's step of size ``h`` [s] as linear maps of one point's history (module docstring).

    Parameters
    ----------
    scheme : Scheme
    h : float
        Step [s].
    steps : int
        Completed steps of the history the maps are read at (Houbolt starts with two Newmark steps).

    Attributes
    ----------
    cx, A, C : float
        ``x_eval = cx delta + ...``, ``v_eval = A delta + ...`` [1/s], ``a_eval = C delta + ...`` [1/s^2].
    load_weight : float
        ``w`` of the new load.
    offset : float
        Time of the evaluation level after ``t_n`` [s].
    coefficients : ndarray, shape (3, 5)
        Rows ``dx``, ``B``, ``D`` on the history ``(x, v, a, x_{n-1}, x_{n-2})``.
    predictor : ndarray, shape (5,)
        The predictor ``x_pred`` on the history (``delta = x - x_pred``; a prescribed point's correction is
        ``X(t_eval) - x_pred``, as :meth:`ctmm.elements.boundary.Boundary.start_discrete` states it).
    update : ndarray, shape (5, 6)
        The new history from ``[history; delta]``.
    """

    def __init__(self, scheme: Scheme, h: float, steps: int = 0) -> None:
        self.scheme, self.h, self.steps = scheme, float(h), int(steps)
        zero = self._apply(np.zeros(5), 0.0)
        self.cx, self.A, self.C, self.load_weight, self.offset = zero[0]
        self.coefficients = np.zeros((4, 5))
        self.update = np.zeros((5, 6))
        for k in range(6):
            unit = np.zeros(6)
            unit[k] = 1.0
            scalars, coefficients, new = self._apply(unit[:5], unit[5])
            if k < 5:
                self.coefficients[:, k] = coefficients
            self.update[:, k] = new
        rng = np.random.default_rng(3)
        for _ in range(2):                         # linear: the maps reproduce the scheme at random histories
            sample = rng.standard_normal(6)
            scalars, coefficients, new = self._apply(sample[:5], sample[5])
            if not (np.allclose(coefficients, self.coefficients @ sample[:5], rtol=1e-12, atol=1e-12 * (
                    1.0 + np.max(np.abs(coefficients)))) and np.allclose(new, self.update @ sample, rtol=1e-12,
                    atol=1e-12 * (1.0 + np.max(np.abs(new)))) and np.allclose(scalars, zero[0])):
                raise ModelError(f"scheme {scheme!r}: its step is not linear in the stored history, which the "
                                 "generated DT-TMM step of chains needs (use compiled=False)")
        self.coefficients, self.predictor = self.coefficients[:3], self.coefficients[3]

    def _apply(self, history: np.ndarray, delta: float) -> tuple[tuple, np.ndarray, np.ndarray]:
        """``((cx, A, C, w), (dx, B, D, x_pred), new history)`` of one point with this history and correction."""
        point = [np.array([[value]]) for value in history]
        state = History(point[0], point[1], point[2], [point[3], point[4]], self.steps)
        coefficients = self.scheme.coefficients(state, self.h)
        new = self.scheme.update(state, np.array([[delta]]), self.h, coefficients)
        scalars = (float(coefficients.cx), float(coefficients.A), float(coefficients.C),
                   float(coefficients.load_weight), float(coefficients.unknown_offset))
        parts = np.array([float(coefficients.dx[0, 0]), float(coefficients.B[0, 0]), float(coefficients.D[0, 0]),
                          float(np.ravel(coefficients.x_pred)[0])])
        after = np.array([float(new.x[0, 0]), float(new.v[0, 0]), float(new.a[0, 0]), float(new.x_old[0][0, 0]),
                          float(new.x_old[1][0, 0])])
        return scalars, parts, after


@dataclass(frozen=True)
class SchemeLoop:
    """One loop of a controlled chain in the generated DT-TMM step: ``u = -C[y - r]`` with ``y = row [x; v] +
    offset`` [sensed unit], on the accelerations ``column`` [1/kg] (the weighted actuator columns), delay
    ``steps * dt`` (``0``: real time, implicit in the step; else from the ring of the last ``steps + 1``
    samples of ``y`` in the generated state, starting at ``ring``).  The controller on the step grid as
    :mod:`ctmm.control.simulate` realises it (trapezoidal rule): ``z' = M1 z + M2 (e_n + e_{n+1})``,
    ``u = -(Cz z + D e)``, ``gain = Cz M2 + D`` (a static gain: ``k = 0``, ``gain = D``); ``[z, e_n, u_n]``
    at ``memory`` in the generated state (``-1`` for a static real-time loop, which keeps none)."""

    loop: Any
    gain: float
    row: np.ndarray
    offset: float
    column: np.ndarray
    steps: int
    reference: Any
    ring: int
    M1: np.ndarray
    M2: np.ndarray
    Cz: np.ndarray
    D: float
    memory: int

    @property
    def order(self) -> int:
        """Controller states ``k``."""
        return self.M2.size


def _trapezoidal(loop: Any, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(M1, M2, Cz, D)`` of the loop's controller on steps ``dt`` [s] (trapezoidal rule; ``k = 0`` for a gain)."""
    A, B, C, D = controller_realisation(loop)
    if not A.size:
        return np.zeros((0, 0)), np.zeros(0), np.zeros(0), float(D)
    left = np.eye(A.shape[0]) - 0.5 * dt * A
    return np.linalg.solve(left, np.eye(A.shape[0]) + 0.5 * dt * A), np.linalg.solve(left, 0.5 * dt * B), C, float(D)


class CompiledChainScheme:
    """Generated and compiled DT-TMM time loop of one lumped chain, with its loops (module docstring).

    Parameters
    ----------
    system : Chain or ControlledChain
        The chain; a controlled chain's loops (static gains and LTI controllers, real-time or delayed by
        whole steps) are closed in the step as the Python DT-TMM path closes them.
    dt : float
        Step [s] (a constant of the generated code).
    scheme : Scheme or str
    store_every, rows : int
        Steps per stored state, stored states per generated block.
    references : mapping, optional
        ``{loop: number or ctmm.signals signal}`` [sensed unit].
    actuators : sequence of str, optional
        Actuators (first inputs of body elements, [N]) driven by values held over each step: the input ``u`` of
        the generated step (the outputs of co-simulated controllers, :mod:`ctmm.compiled_cosim`).
    cache_dir, compiler
        Of :func:`ctmm.codegen.shared_library`.
    unrolled : bool, optional
        Generate the step as straight-line scalar code (every point's arithmetic written out, the constants
        folded in; code and compile time growing with the chain) instead of C loops over the nodes
        (:mod:`ctmm.compiled_chain_kernel`, code size independent of the chain, within ~10 % per step; chains
        with inerters: vector operations, 2-3x slower).  Default: unrolled up to :data:`UNROLLED_POINTS`
        moving masses.

    Attributes
    ----------
    dynamics : ChainDynamics
    scheme : Scheme
    loops : list of SchemeLoop
    state_size : int
        ``5 m`` (``[x, v, a, x_{n-1}, x_{n-2}]`` of the ``m`` moving masses), then each loop's memory and ring, then
        (a scheme with a start-up) the steps since the history (re)started.
    start_up_index : int or None
        Where the state holds the steps since the history (re)started (a scheme with a start-up), else None.
    actuators : tuple of str
        The held inputs ``u``, in order.
    held_columns : ndarray, shape (m, len(actuators))
        Accelerations [m/s^2] of the moving masses per unit held input [N] (``M^-1`` of the unit forces).
    compile_time_s : float
    """

    def __init__(self, system: Any, dt: float, scheme: Any = "newmark", *, store_every: int = 1, rows: int = 64,
                 references: Mapping[str, Any] | None = None, actuators: Sequence[str] = (),
                 cache_dir: str | os.PathLike | None = None, compiler: str | None = None,
                 unrolled: bool | None = None) -> None:
        import casadi as ca

        started = _time.perf_counter()
        self.system = system
        self.dt = validation.positive("dt", dt)
        self.scheme = as_scheme(scheme)
        self.store_every = validation.integer("store_every", store_every, minimum=1)
        self.plant = ChainPlant(system)
        self.dynamics: ChainDynamics = self.plant.dynamics
        chain = self.plant.chain
        loops = tuple(getattr(system, "loops", ()))
        refuse_saturation(loops, "the generated DT-TMM step of a chain (its loops are linear in the step; use "
                                 "method='rk4')")
        ports = self.plant.ports
        for loop in loops:
            for name, _ in loop.terms:
                ports.check_sensor(name, f"sensor of loop {loop.name!r}")
            for name, _ in loop.actuator_terms:
                ports.check_actuator(name, f"actuator of loop {loop.name!r}")
        references = dict(references or {})
        for name in references:
            if name not in [loop.name for loop in loops]:
                raise ModelError(f"references[{name!r}]: not a loop; loops: {', '.join(lp.name for lp in loops) or '(none)'}")
        self.actuators = tuple(ports.check_actuator(name, "held actuator") for name in actuators)
        self.nodes = None
        if needs_condensed_form(self.dynamics):
            if loops or self.actuators:
                raise ModelError(f"chain {chain.name!r}: loops and held actuators on a chain with points without "
                                 "inertia or a prescribed motion are generated in the RK4 (method='rk4'), not in the "
                                 "DT-TMM step; use method='rk4' or compiled=False")
            self._compile_nodes(rows, cache_dir, compiler, started)
            return
        looped = list(dict.fromkeys(name for loop in loops for name, _ in loop.actuator_terms))
        actuators = list(dict.fromkeys([*looped, *self.actuators]))
        form = affine_form(self.dynamics, [ports.inputs({name: 1.0}) for name in actuators], sparse=True)
        self.held_columns = np.column_stack([form.B[:, actuators.index(name)] for name in self.actuators]) \
            if self.actuators else np.zeros((form.Ax.shape[0], 0))
        m = self.m = self.plant.n_positions
        if unrolled is not None and not isinstance(unrolled, bool):
            raise ModelError(f"unrolled must be True, False or None (up to {UNROLLED_POINTS} masses), got {unrolled!r}")
        self.unrolled = m <= UNROLLED_POINTS if unrolled is None else unrolled
        self._certify(form)
        self.loops, size = [], 5 * m
        for loop in loops:
            row, offset = sensor_row(ports, loop.terms, 2 * m)
            column = sum((weight * form.B[:, actuators.index(name)] for name, weight in loop.actuator_terms),
                         np.zeros(m))
            steps = delay_steps(loop.name, loop.delay, self.dt)
            reference = symbolic_reference(f"references[{loop.name!r}]", references.get(loop.name, 0.0))
            M1, M2, Cz, D = _trapezoidal(loop, self.dt)
            memory = size if (M2.size or steps) else -1
            size += M2.size + 2 if memory >= 0 else 0
            self.loops.append(SchemeLoop(loop, float(Cz @ M2) + D, row, float(offset), column, steps, reference,
                                         size, M1, M2, Cz, D, memory))
            size += steps + 1 if steps else 0
        start_up = self.scheme.start_up_steps
        maps = [SchemeMaps(self.scheme, self.dt, 0)]
        later = SchemeMaps(self.scheme, self.dt, max(start_up, 2))
        if start_up:
            maps.append(later)                                  # a start-up (Houbolt): its first steps differ
        elif not (np.array_equal(later.coefficients, maps[0].coefficients) and
                  np.array_equal(later.update, maps[0].update)):
            raise ModelError(f"scheme {self.scheme!r}: its step depends on the completed steps but it declares no "
                             "start_up_steps, which the generated DT-TMM step of chains needs (use compiled=False)")
        self.start_up_index = size if start_up else None
        self.state_size = size = size + (1 if start_up else 0)

        def build() -> tuple[Any, list]:
            y, u, h = ca.MX.sym("y", size), ca.MX.sym("u", len(self.actuators)), ca.MX.sym("h")
            p, t0, k = ca.MX.sym("p", 0), ca.MX.sym("t0"), ca.MX.sym("k")
            branches = [self._step_function(f"step{j}", form, scheme_maps) for j, scheme_maps in enumerate(maps)]
            t_n = t0 + k * self.dt
            first, *later = (inlined_call(branch, [y, t_n, u]) for branch in branches)
            new = first if not later else ca.if_else(y[self.start_up_index] < start_up, first, later[0], True)
            return ca.Function("step", [y, u, h, p, t0, k], [new]), []

        name = f"chain_{m}m_{self.scheme.name}" + (f"_{len(self.loops)}l" if self.loops else "") + (
            f"_{len(self.actuators)}u" if self.actuators else "")
        # the step reads the chain, dt, the scheme, the references and the held actuators only (and the code):
        # described, a cached library loads without building it (else the key is the built step's)
        description = describe((system, self.dt, self.scheme, references, self.actuators, self.unrolled))
        options = {"cache_dir": cache_dir, "compiler": compiler}
        self._bodies: list[str] = []                            # C bodies of the node loops, if any
        if description is None:
            built = build()
            # a serialized step does not hold its node loops' C bodies: the key is the step and the bodies
            parts = [("chain scheme step", built[0].serialize().encode())] + [
                (f"node loops {j}", body.encode()) for j, body in enumerate(self._bodies)]
            loop = compiled_time_loop(built[0], self.store_every, rows, name, **options) if not self._bodies else \
                compiled_time_loop(lambda: built, self.store_every, rows, name, description=parts, **options)
        else:
            loop = compiled_time_loop(build, self.store_every, rows, name, description=[("chain scheme", description)],
                                      **options)
        self._step, self._stride, self._blocks = loop.step, loop.stride, loop.blocks
        self.form = form
        self.compile_time_s = _time.perf_counter() - started

    def _compile_nodes(self, rows: int, cache_dir: Any, compiler: Any, started: float) -> None:
        """The step of a chain with massless points or a prescribed motion (:mod:`ctmm.compiled_chain_scheme_nodes`):
        the histories of the free nodes and the moving supports, then (a start-up) the steps since the start."""
        import casadi as ca

        self.nodes = form = node_form(self.dynamics)
        self.form, self.loops, self.unrolled, self.m = form, [], True, self.plant.n_positions
        self.held_columns = np.zeros((self.m, 0))
        start_up = self.scheme.start_up_steps
        maps = [SchemeMaps(self.scheme, self.dt, 0)] + ([SchemeMaps(self.scheme, self.dt, max(start_up, 2))]
                                                          if start_up else [])
        used = 5 * (form.free.size + len(form.supports))
        self.start_up_index = used if start_up else None
        self.state_size = size = used + (1 if start_up else 0)

        def build() -> tuple[Any, list]:
            y, u, h = ca.MX.sym("y", size), ca.MX.sym("u", 0), ca.MX.sym("h")
            p, t0, k = ca.MX.sym("p", 0), ca.MX.sym("t0"), ca.MX.sym("k")
            branches = [node_step(form, scheme_maps, self.dt, size).expand() for scheme_maps in maps]
            t_n = t0 + k * self.dt
            new = branches[0](y, t_n) if len(maps) == 1 else ca.if_else(
                y[used] < start_up, branches[0](y, t_n), branches[1](y, t_n), True)
            if start_up:
                new = ca.vertcat(new, y[used] + 1.0)
            return ca.Function("step", [y, u, h, p, t0, k], [new]), []

        description = describe(("nodes", self.system, self.dt, self.scheme))
        name = f"chain_{form.free.size}n{len(form.supports)}s_{self.scheme.name}"
        options = {"cache_dir": cache_dir, "compiler": compiler}
        loop = compiled_time_loop(build()[0], self.store_every, rows, name, **options) if description is None else \
            compiled_time_loop(build, self.store_every, rows, name, description=[("chain scheme nodes", description)],
                               **options)
        self._step, self._stride, self._blocks = loop.step, loop.stride, loop.blocks
        self.compile_time_s = _time.perf_counter() - started

    def _certify(self, form: Any) -> None:
        """The affine form equals the sweep at random states and times (relative 1e-10), else ModelError (a form
        read from the certified rates was checked so already: the same check)."""
        m, rng = self.m, np.random.default_rng(12)
        for _ in range(0 if form.certified else 2):
            y, t = rng.standard_normal(2 * m) * 0.01, float(rng.uniform(0.0, 3.0))
            swept = self.dynamics.swept_rate(t, y)[m:]
            affine = form.Ax @ y[:m] + form.Av @ y[m:] + form.a0 + sum(
                (column * float(signal(t)) for column, signal in form.loads), np.zeros(m))
            if not np.all(np.abs(swept - affine) <= 1e-10 * max(1.0, float(np.max(np.abs(swept))))):
                raise ModelError(f"chain {self.plant.chain.name!r}: its rates are not affine in the state (an element "
                                 "family with non-linear terms); the generated DT-TMM step needs the affine form: use "
                                 "compiled=False")
        for _, signal in form.loads:
            if signal_parameters(signal) is None:
                raise ModelError(f"chain {self.plant.chain.name!r}: a load signal {signal!r} is a Python callable of "
                                 "time, which generated kernels cannot evaluate; give a ctmm.signals Constant, "
                                 "Harmonic, Step, SquareWave or Ramp, or use compiled=False")

    def _step_function(self, label: str, form: Any, maps: SchemeMaps) -> Any:
        """``(state, t_n, u) -> new state`` for one set of scheme maps: the equation of motion at the evaluation
        level with the loads weighted by ``w`` and the inputs ``u`` held over the step, the real-time loops
        implicit (their rank-``k`` part by the Woodbury identity on the banded solve), the delayed loops' forces
        ``(1 - w) u_n + w u_{n+1}`` from the rings, which then take the new sample."""
        import casadi as ca

        m, dt, w = self.m, self.dt, maps.load_weight
        Ax, Av = form.Ax, form.Av
        matrix = step_matrix(maps.C, maps.cx, maps.A, Ax, Av)
        banded = tridiagonal_factors(matrix, Ax, Av)
        factors = None if self.unrolled else banded
        y, t_n, u = ca.MX.sym("y", self.state_size), ca.MX.sym("t"), ca.MX.sym("u", len(self.actuators))
        parts = [y[j * m:(j + 1) * m] for j in range(5)]
        forcing = []                                   # beyond a0: the loads, held inputs, delayed loops
        for column, signal in form.loads:
            symbolic = symbolic_signal(type(signal), t_n + dt, signal_parameters(signal))
            if w != 1.0:
                symbolic = (1.0 - w) * symbolic_signal(type(signal), t_n, signal_parameters(signal)) + w * symbolic
            forcing.append(ca.DM(column) * symbolic)
        if self.actuators:                             # held over the step: (1 - w) u + w u = u
            forcing.append(ca.mtimes(ca.DM(self.held_columns), u))
        t_eval = t_n + maps.offset
        now, offsets = [lp for lp in self.loops if lp.steps == 0], {}
        for lp in self.loops:                          # u_eval = -(gain e_eval + controller offset)
            k, memory = lp.order, lp.memory
            offsets[lp.loop.name] = 0.0
            if k:
                z, e_n = y[memory:memory + k], y[memory + k]
                offsets[lp.loop.name] = ca.dot(ca.DM(lp.Cz), ca.mtimes(ca.DM(lp.M1), z) + ca.DM(lp.M2) * e_n)
            if lp.steps:
                tau = lp.steps * dt
                after = -(lp.gain * (y[lp.ring + 1] - reference_at(lp.reference, t_n + dt - tau))
                          + offsets[lp.loop.name])
                forcing.append(ca.DM(lp.column) * ((1.0 - w) * y[memory + k + 1] + w * after if w != 1.0 else after))
        if factors is None:                            # the banded solve (or the inverse) as a casadi graph
            dx, B, D = (sum((float(maps.coefficients[r, c]) * parts[c] for c in range(5) if maps.coefficients[r, c]),
                            ca.MX.zeros(m)) for r in range(3))
            rhs = ca.mtimes(ca.DM(scipy.sparse.csc_matrix(Ax)), dx) + ca.mtimes(ca.DM(scipy.sparse.csc_matrix(Av)), B) \
                + sum(forcing, ca.DM(form.a0)) - D
            for lp in now:                             # real time: the known part here, the rest implicit
                known = ca.dot(ca.DM(lp.row[:m]), dx) + ca.dot(ca.DM(lp.row[m:]), B) + lp.offset
                rhs = rhs - ca.DM(lp.column) * (lp.gain * (known - reference_at(lp.reference, t_eval))
                                                + offsets[lp.loop.name])
            delta = banded_solver(matrix)(rhs)
        W, Q = woodbury_parts([lp.loop.name for lp in now], np.array([lp.column for lp in now]).reshape(-1, m).T,
                              np.array([lp.gain * (maps.cx * lp.row[:m] + maps.A * lp.row[m:]) for lp in now]
                                       ).reshape(-1, m), matrix, dt, banded)
        if factors is None:
            if now:                                    # (S + b g r_delta^T) delta = rhs, r_delta = cx r_x + A r_v
                delta = delta - ca.mtimes(ca.DM(W), ca.mtimes(ca.DM(Q), delta))
            every = parts + [delta]
            new = [sum((float(maps.update[r, c]) * every[c] for c in range(6) if maps.update[r, c]), ca.MX.zeros(m))
                   for r in range(5)]
            history = ca.vertcat(new[0], new[1])
        else:                                          # one C loop per sweep over the nodes
            kernel, body = step_kernel(f"{label}_nodes", Ax, Av, form.a0, maps.coefficients, maps.update, factors,
                                 bool(forcing), [(lp.gain, lp.row) for lp in now], W, Q)
            self._bodies.append(body)
            arguments = [y[:5 * m]] + ([sum(forcing[1:], forcing[0])] if forcing else []) + (
                [ca.vertcat(*[lp.gain * (lp.offset - reference_at(lp.reference, t_eval)) + offsets[lp.loop.name]
                              for lp in now])] if now else [])
            new = [kernel(*arguments)]
            history = new[0]
        for lp in self.loops:                          # the controller advances, the ring takes the new sample
            k, memory = lp.order, lp.memory
            row = scipy.sparse.csc_matrix(np.concatenate([lp.row, np.zeros(history.numel() - 2 * m)])[None, :])
            sample = ca.mtimes(ca.DM(row), history) + lp.offset     # the new [x; v] sensed
            if memory < 0:
                continue
            t_next = t_n + dt - lp.steps * dt
            e_now = (y[lp.ring + 1] if lp.steps else sample) - reference_at(lp.reference, t_next)
            z = ca.mtimes(ca.DM(lp.M1), y[memory:memory + k]) + ca.DM(lp.M2) * (y[memory + k] + e_now) if k \
                else ca.MX(0, 1)
            u_now = -(ca.dot(ca.DM(lp.Cz), z) if k else 0.0) - lp.D * e_now
            new.append(ca.vertcat(z, e_now, u_now))
            if lp.steps:
                new.append(ca.vertcat(y[lp.ring + 1:lp.ring + lp.steps + 1], sample))
        if self.start_up_index is not None:            # one more step since the history (re)started
            new.append(y[self.start_up_index] + 1.0)
        step = ca.Function(label, [y, t_n, u], [ca.vertcat(*new)])
        return step.expand() if self.unrolled else step

    def loop_forces(self, t: float, state: np.ndarray) -> list[float]:
        """``u`` [actuator unit] of every loop at ``t`` [s] in a generated ``state`` (a static real-time loop from
        the positions and velocities; the others keep their last output in the state)."""
        m, out = self.m, []
        for lp in self.loops:
            if lp.memory >= 0:
                out.append(float(state[lp.memory + lp.order + 1]))
            else:
                y = float(lp.row @ state[:2 * m]) + lp.offset
                out.append(-lp.gain * (y - float(lp.reference(t))))
        return out

    def actuator_inputs(self, forces: Sequence[float], held: Mapping[str, float] | None = None) -> dict | None:
        """The loops' forces and the ``held`` inputs ``{actuator: value}`` as ``{element position: {input: value}}``
        [N] (None without either)."""
        values: dict[str, float] = dict(held or {})
        for lp, u in zip(self.loops, forces):
            for name, weight in lp.loop.actuator_terms:
                values[name] = values.get(name, 0.0) + weight * u
        return self.plant.ports.inputs(values) if values else None

    def start(self, x0: Mapping[str, float] | None, v0: Mapping[str, float] | None,
              held: Mapping[str, float] | None = None) -> np.ndarray:
        """The generated state at ``t = 0``: positions, velocities, the acceleration of the equation of motion
        with the loops' start forces ``u_0 = -D (y_0 - r(-tau))`` and the ``held`` inputs ``{actuator: value}``
        [N], the positions as the older history, each loop's ``[z = 0, e_0 = y_0 - r(0), u_0]`` and ring holding
        ``y_0`` (the state held before ``t = 0``, as :func:`ctmm.control.simulate.simulate_controlled` starts), and zero
        steps since the start (a scheme with a start-up)."""
        if self.nodes is not None:
            state, self.consistent = node_start(self.dynamics, self.nodes, x0, v0)
            return np.concatenate([state, [0.0] if self.start_up_index is not None else []])
        q, w = self.plant.start(x0, v0)
        blocks, forces = [], []
        for lp in self.loops:
            y0 = float(lp.row @ np.concatenate([q, w])) + lp.offset
            forces.append(-lp.D * (y0 - float(lp.reference(-lp.steps * self.dt))))
            if lp.memory >= 0:
                blocks.append(np.concatenate([np.zeros(lp.order), [y0 - float(lp.reference(0.0)), forces[-1]]]))
            if lp.steps:
                blocks.append(np.full(lp.steps + 1, y0))
        a = self.dynamics.rate(0.0, np.concatenate([q, w]), self.actuator_inputs(forces, held))[self.m:]
        start_up = [0.0] if self.start_up_index is not None else []
        return np.concatenate([q, w, a, q, q, *blocks, start_up])

    def run(self, state: np.ndarray, n_steps: int) -> np.ndarray:
        """Stored states (rows, :attr:`state_size`) after every ``store_every`` steps and the last."""
        return self.continue_run(state, np.zeros(len(self.actuators)), n_steps, 0)

    def continue_run(self, state: np.ndarray, held: np.ndarray, n_steps: int, first_step: int,
                     runner: BlockRunner | None = None) -> np.ndarray:
        """Stored states (rows, :attr:`state_size`) of ``n_steps`` steps from ``state`` at step ``first_step`` with the
        values ``held`` [N] of :attr:`actuators` (one co-simulation interval, :mod:`ctmm.compiled_cosim`)."""
        return run_blocks(self._blocks, self._stride, self._step, self.store_every, np.asarray(state, float)[:, None],
                          held, self.dt, n_steps, 0.0, np.zeros((0, 1)), first_step=first_step, runner=runner)[0]
