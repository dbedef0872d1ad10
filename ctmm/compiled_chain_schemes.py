"""Generated DT-TMM steps of 1-D lumped chains: every implicit scheme of :mod:`ctmm.schemes` in C (issue 13).

``ctmm.simulate(chain, t_final, dt, method="newmark" | "generalized_alpha" | "wilson_theta" | "houbolt" |
"forward_euler" | <Scheme>, compiled=True)`` runs here.  Two readings, both exact and both certified
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
the C, the solve unrolled: ``O(n)`` per step), or the constant inverse for chains whose inerters couple
every node.  Houbolt's two Newmark start-up steps are the other branch of a short-circuit
``if_else`` on the step index.  The step, ``store_every`` strides and blocks of stored states are those
of every generated scene (:mod:`ctmm.generated_loop`); ``dt`` is a constant of the code (the cache key).

Stored: positions and velocities of the scheme; accelerations and forces at the points are those of the
equation of motion at the stored states (as the ODE path; the Python DT-TMM path stores the scheme's own
acceleration, which differs from it by the scheme's error for Wilson-theta and generalized-alpha).

Refused (:class:`~ctmm.errors.ModelError`): what the generated RK4 of chains refuses (massless points,
prescribed boundary motions, load signals without a symbolic form) and loops (a ``ControlledChain`` with a
DT-TMM scheme keeps the Python path: ``compiled=False``).
"""
from __future__ import annotations

import os
import time as _time
from typing import Any, Mapping

import numpy as np
import scipy.sparse

from . import validation
from .chain_ode import ChainDynamics, chain_result
from .codegen import load_casadi
from .compiled_chain import affine_form, whole_steps
from .control.chain_plant import ChainPlant
from .errors import ModelError, SimulationError
from .generated_loop import run_blocks, time_loop_functions
from .results import SimulationResult
from .schemes import History, Scheme, as_scheme
from .signals import signal_parameters, symbolic_signal

__all__ = ["SchemeMaps", "CompiledChainScheme", "simulate_chain_scheme_generated", "simulate_scheme_verb"]

HISTORY = ("x", "v", "a", "x_old1", "x_old2")
"""The stored history of every point, in the order of the generated state."""


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
    coefficients : ndarray, shape (3, 5)
        Rows ``dx``, ``B``, ``D`` on the history ``(x, v, a, x_{n-1}, x_{n-2})``.
    update : ndarray, shape (5, 6)
        The new history from ``[history; delta]``.
    """

    def __init__(self, scheme: Scheme, h: float, steps: int = 0) -> None:
        self.scheme, self.h, self.steps = scheme, float(h), int(steps)
        zero = self._apply(np.zeros(5), 0.0)
        self.cx, self.A, self.C, self.load_weight = zero[0]
        self.coefficients = np.zeros((3, 5))
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

    def _apply(self, history: np.ndarray, delta: float) -> tuple[tuple, np.ndarray, np.ndarray]:
        """``((cx, A, C, w), (dx, B, D), new history)`` of one point with this history and correction."""
        point = [np.array([[value]]) for value in history]
        state = History(point[0], point[1], point[2], [point[3], point[4]], self.steps)
        coefficients = self.scheme.coefficients(state, self.h)
        new = self.scheme.update(state, np.array([[delta]]), self.h, coefficients)
        scalars = (float(coefficients.cx), float(coefficients.A), float(coefficients.C),
                   float(coefficients.load_weight))
        parts = np.array([float(coefficients.dx[0, 0]), float(coefficients.B[0, 0]), float(coefficients.D[0, 0])])
        after = np.array([float(new.x[0, 0]), float(new.v[0, 0]), float(new.a[0, 0]), float(new.x_old[0][0, 0]),
                          float(new.x_old[1][0, 0])])
        return scalars, parts, after


def _solver(matrix: np.ndarray) -> Any:
    """A casadi ``Function`` ``rhs -> matrix^-1 rhs`` [SX, unrolled]: the LU factors of a tridiagonal matrix
    as constants (no pivoting: the step matrices are diagonally dominant), or the constant inverse."""
    import casadi as ca

    m = matrix.shape[0]
    rhs = ca.SX.sym("rhs", m)
    banded = m < 3 or not np.any(np.triu(matrix, 2)) and not np.any(np.tril(matrix, -2))
    if not banded:
        return ca.Function("solve", [rhs], [ca.mtimes(ca.DM(np.linalg.inv(matrix)), rhs)])
    diagonal = np.diag(matrix).astype(float).copy()
    lower = np.diag(matrix, -1).astype(float)
    upper = np.diag(matrix, 1).astype(float)
    factors = np.zeros(max(m - 1, 0))
    for i in range(1, m):                                        # Thomas: L U with unit lower L
        factors[i - 1] = lower[i - 1] / diagonal[i - 1]
        diagonal[i] -= factors[i - 1] * upper[i - 1]
    forward = [rhs[0]]
    for i in range(1, m):
        forward.append(rhs[i] - factors[i - 1] * forward[i - 1])
    out = [None] * m
    out[m - 1] = forward[m - 1] / diagonal[m - 1]
    for i in range(m - 2, -1, -1):
        out[i] = (forward[i] - upper[i] * out[i + 1]) / diagonal[i]
    return ca.Function("solve", [rhs], [ca.vertcat(*out)])


class CompiledChainScheme:
    """Generated and compiled DT-TMM time loop of one plain lumped chain (module docstring).

    Parameters
    ----------
    chain : Chain
        A plain chain (a ``ControlledChain`` is refused: its loops keep the Python DT-TMM path).
    dt : float
        Step [s] (a constant of the generated code).
    scheme : Scheme or str
    store_every, rows : int
        Steps per stored state, stored states per generated block.
    cache_dir, compiler
        Of :func:`ctmm.codegen.shared_library`.

    Attributes
    ----------
    dynamics : ChainDynamics
    scheme : Scheme
    state_size : int
        ``5 m``: ``[x, v, a, x_{n-1}, x_{n-2}]`` of the ``m`` moving masses.
    compile_time_s : float
    """

    def __init__(self, chain: Any, dt: float, scheme: Any = "newmark", *, store_every: int = 1, rows: int = 64,
                 cache_dir: str | os.PathLike | None = None, compiler: str | None = None) -> None:
        import casadi as ca

        started = _time.perf_counter()
        if getattr(chain, "loops", None) is not None:
            raise ModelError(f"compiled=True with a DT-TMM scheme runs plain chains; {chain.name!r} closes loops "
                             f"{[lp.name for lp in chain.loops]}, which keep the Python DT-TMM path (compiled=False) "
                             "or run in the generated RK4 of a chain (method='rk4', compiled=True)")
        self.dt = validation.positive("dt", dt)
        self.scheme = as_scheme(scheme)
        self.store_every = validation.integer("store_every", store_every, minimum=1)
        self.plant = ChainPlant(chain)
        self.dynamics: ChainDynamics = self.plant.dynamics
        form = affine_form(self.dynamics)
        m = self.m = self.plant.n_positions
        self.state_size = 5 * m
        rates = np.hstack([form.Ax, form.Av])
        python = self.dynamics.swept_rate
        rng = np.random.default_rng(12)
        for _ in range(2):                                      # the affine form is the sweep (certified)
            y, t = rng.standard_normal(2 * m) * 0.01, float(rng.uniform(0.0, 3.0))
            swept = python(t, y)[m:]
            affine = rates @ y + form.a0 + sum((column * float(signal(t)) for column, signal in form.loads),
                                               np.zeros(m))
            if not np.all(np.abs(swept - affine) <= 1e-10 * max(1.0, float(np.max(np.abs(swept))))):
                raise ModelError(f"chain {chain.name!r}: its rates are not affine in the state (an element family "
                                 "with non-linear terms); the generated DT-TMM step needs the affine form: use "
                                 "compiled=False")
        for _, signal in form.loads:
            if signal_parameters(signal) is None:
                raise ModelError(f"chain {chain.name!r}: a load signal {signal!r} is a Python callable of time, "
                                 "which generated kernels cannot evaluate; give a ctmm.signals Constant, Harmonic, "
                                 "Step or SquareWave, or use compiled=False")
        maps = [SchemeMaps(self.scheme, self.dt, 0)]
        later = SchemeMaps(self.scheme, self.dt, 2)
        if not (np.array_equal(later.coefficients, maps[0].coefficients) and
                np.array_equal(later.update, maps[0].update)):
            maps.append(later)                                  # a start-up (Houbolt): steps 0 and 1 differ
        y, u, h, p = ca.MX.sym("y", 5 * m), ca.MX.sym("u", 0), ca.MX.sym("h"), ca.MX.sym("p", 0)
        t0, k = ca.MX.sym("t0"), ca.MX.sym("k")
        branches = [self._step_function(f"step{j}", form, scheme_maps) for j, scheme_maps in enumerate(maps)]
        t_n = t0 + k * self.dt
        new = branches[0](y, t_n) if len(maps) == 1 else ca.if_else(k < 2, branches[0](y, t_n), branches[1](y, t_n),
                                                                  True)
        step = ca.Function("step", [y, u, h, p, t0, k], [new])
        stride, sizes, blocks = time_loop_functions(step, self.store_every, rows)
        name = f"chain_{m}m_{self.scheme.name}"
        loaded = load_casadi([step, stride, *blocks], name, cache_dir=cache_dir, compiler=compiler)
        self._step, self._stride = loaded[:2]
        self._blocks = list(zip(sizes, loaded[2:]))
        self.form = form
        self.compile_time_s = _time.perf_counter() - started

    def _step_function(self, label: str, form: Any, maps: SchemeMaps) -> Any:
        """``(history, t_n) -> new history`` of every node for one set of scheme maps."""
        import casadi as ca

        m, dt = self.m, self.dt
        Ax, Av = form.Ax, form.Av
        matrix = maps.C * np.eye(m) - maps.cx * Ax - maps.A * Av
        solve = _solver(matrix)
        y, t_n = ca.SX.sym("y", 5 * m), ca.SX.sym("t")
        parts = [y[j * m:(j + 1) * m] for j in range(5)]
        dx, B, D = (sum((float(maps.coefficients[r, c]) * parts[c] for c in range(5) if maps.coefficients[r, c]),
                        ca.SX.zeros(m)) for r in range(3))
        w = maps.load_weight
        forcing = ca.DM(form.a0)
        for column, signal in form.loads:
            symbolic = symbolic_signal(type(signal), t_n + dt, signal_parameters(signal))
            if w != 1.0:
                symbolic = (1.0 - w) * symbolic_signal(type(signal), t_n, signal_parameters(signal)) + w * symbolic
            forcing = forcing + ca.DM(column) * symbolic
        rhs = ca.mtimes(ca.DM(scipy.sparse.csc_matrix(Ax)), dx) + ca.mtimes(ca.DM(scipy.sparse.csc_matrix(Av)), B) \
            + forcing - D
        delta = solve(rhs)
        every = parts + [delta]
        new = [sum((float(maps.update[r, c]) * every[c] for c in range(6) if maps.update[r, c]), ca.SX.zeros(m))
               for r in range(5)]
        return ca.Function(label, [y, t_n], [ca.vertcat(*new)])

    def start(self, x0: Mapping[str, float] | None, v0: Mapping[str, float] | None) -> np.ndarray:
        """The generated state at ``t = 0``: positions, velocities, the acceleration of the equation of motion
        and the positions as the older history (as :func:`ctmm.timestep.simulate` starts)."""
        q, w = self.plant.start(x0, v0)
        a = self.dynamics.rate(0.0, np.concatenate([q, w]))[self.m:]
        return np.concatenate([q, w, a, q, q])

    def run(self, state: np.ndarray, n_steps: int) -> np.ndarray:
        """Stored states (rows, :attr:`state_size`) after every ``store_every`` steps and the last."""
        return run_blocks(self._blocks, self._stride, self._step, self.store_every, np.asarray(state, float)[:, None],
                          np.zeros(0), self.dt, n_steps, 0.0, np.zeros((0, 1)))[0]


def simulate_chain_scheme_generated(chain: Any, t_final: float, dt: float, scheme: Any = "newmark", *,
                                    x0: Mapping[str, float] | None = None, v0: Mapping[str, float] | None = None,
                                    store_every: int = 1, divergence_bound: float | None = None,
                                    cache_dir: str | os.PathLike | None = None,
                                    compiled: CompiledChainScheme | None = None) -> SimulationResult:
    """A DT-TMM scheme on a plain chain in generated C; the result of the ODE path's form.

    Parameters
    ----------
    chain : Chain
    t_final, dt : float
        End time and step [s] (``t_final`` a whole multiple of ``dt``).
    scheme : Scheme or str
    x0, v0 : mapping, optional
        Initial positions [m] / velocities [m/s] by element name.
    store_every : int
        Keep every ``store_every``-th step (the last one always).
    divergence_bound : float, optional
        As in :func:`ctmm.chain_ode.simulate_chain_ode` (checked on the stored rows).
    cache_dir : path, optional
    compiled : CompiledChainScheme, optional
        A compiled kernel of this chain, step, scheme and ``store_every`` to reuse.

    Returns
    -------
    SimulationResult
        The point signals of :func:`ctmm.chain_ode.simulate_chain_ode`; ``info["method"]`` is
        ``"<scheme>-generated"``, with ``info["compile_time_s"]`` [s].

    Raises
    ------
    ModelError
        Bad arguments, no compiler, or what the generated step cannot do (named).
    SimulationError
        A diverging or non-finite state (``partial_result``: the rows before it).
    """
    t_final, dt, n_steps = whole_steps(t_final, dt)
    if compiled is None:
        compiled = CompiledChainScheme(chain, dt, scheme, store_every=store_every, cache_dir=cache_dir)
    elif not isinstance(compiled, CompiledChainScheme) or compiled.dt != dt or compiled.store_every != store_every \
            or compiled.scheme != as_scheme(scheme):
        raise ModelError(f"compiled must be a CompiledChainScheme of this chain with dt={dt!r}, scheme={scheme!r} and "
                         f"store_every={store_every!r}, got {compiled!r}")
    first = compiled.start(x0, v0)
    started = _time.perf_counter()
    states = compiled.run(first, n_steps)
    wall = _time.perf_counter() - started
    every, m = compiled.store_every, compiled.m
    steps = np.array([k for k in range(1, n_steps + 1) if k % every == 0 or k == n_steps])[:len(states)]
    times = np.concatenate([[0.0], steps * dt])
    states = np.vstack([first[None], states])[:, :2 * m]
    label = f"{compiled.scheme.name}-generated"
    info = {"dt": dt, "method": label, "path": "generated-dttmm", "compile_time_s": compiled.compile_time_s,
            "wall_time_s": wall, "n_steps": n_steps}
    guard = compiled.plant.guard(states[0, :m], divergence_bound)
    for k in range(len(times)):
        try:
            guard(float(times[k]), states[k], dt, label)
        except SimulationError as exc:
            exc.partial_result = chain_result(compiled.dynamics, list(times[:k]), list(states[:k]), label, dict(info))
            raise
    return chain_result(compiled.dynamics, list(times), list(states), label, info)


def simulate_scheme_verb(system: Any, t_final: float, dt: float | None, scheme: Any, x0: Any, v0: Any,
                         store_every: int, divergence_bound: float | None, others: Mapping[str, tuple], *,
                         t0: float, inputs: Any, outputs: Any, references: Mapping[str, Any]) -> SimulationResult:
    """``ctmm.simulate(chain, method=<scheme>, compiled=True)``: the options that do not apply are refused by
    name (``others``: ``{name: (value, default)}`` of the verb), then :func:`simulate_chain_scheme_generated`."""
    options = {**others, "t0": (t0, 0.0), "inputs": (inputs or None, None), "outputs": (tuple(outputs), ()),
               "references": (dict(references or {}), {})}
    for name, (value, default) in options.items():
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} does not apply to the generated DT-TMM step of a chain (leave {name} "
                             f"at {default!r}, or use compiled=False)")
    if dt is None:
        raise ModelError("dt is required to simulate a chain (the DT-TMM step [s], > 0), got None")
    return simulate_chain_scheme_generated(system, t_final, dt, scheme, x0=x0, v0=v0, store_every=store_every,
                                           divergence_bound=divergence_bound)
