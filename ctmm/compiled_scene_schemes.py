"""Generated DT-TMM schemes of planar models: every :mod:`ctmm.schemes` scheme + Newton in C (issue 13).

``ctmm.simulate(planar_model, t_final, dt, method="newmark" | "generalized_alpha" | "wilson_theta" |
"houbolt" | "forward_euler" | <Scheme>, compiled=True)`` runs here (rigid trees, modal beams, hub-beam
scenes: what :func:`ctmm.compiled_parameters.compile_refusal` accepts).  The step is the one of
:func:`ctmm.planar.implicit.simulate_implicit`, the scheme's nonlinear second-order form
(:meth:`ctmm.schemes.Scheme.second_order_step`, ``docs/planar.md``)

``q = q_hat + b' h^2 a``,   ``v = v_hat + g' h a``,   ``a = qddot(q, v, t_n + fraction h)``

with the acceleration ``qddot(q, v, u, p, t)`` the casadi expression of the one articulated sweep that the
generated RK4 compiles (:func:`ctmm.compiled_scene.symbolic_accelerations_with_inputs`).  Two readings:

* **the scheme** -- its second-order step is linear in the stored history of every coordinate
  ``(q_n, v_n, a_n, qddot_n, q_{n-1}, q_{n-2})`` (``a_n`` the algorithmic acceleration of generalized-alpha,
  ``qddot_n`` the one of the equations of motion): :class:`SecondOrderMaps` reads the predictors, the
  weights, the evaluation time and the new history from :meth:`~ctmm.schemes.Scheme.second_order_step` and
  :meth:`~ctmm.schemes.Scheme.second_order_update` by unit probes on one coordinate and checks them at random
  histories, so any scheme with a nonlinear form compiles without touching this module.  The maps are read
  at ``h = 1 s`` and scaled by the powers of ``h`` their units give (``v h``, ``a h^2``; checked against the
  maps read at the run's step before every run), so the step ``h`` is an input of the code: one library per
  model structure and scheme serves every step.  Houbolt's two average-acceleration start-up steps are the
  maps at steps 0 and 1, selected on the step index.
* **Newton** -- on the residual ``r(a) = a - qddot(q_hat + b' h^2 a, v_hat + g' h a, t)`` with its exact
  tangent ``I - b' h^2 d qddot/dq - g' h d qddot/dv`` (algorithmic derivative of the sweep, :mod:`ctmm.mapped_tangent`),
  a QR solve per iteration (``tangent="sweep"``: O(N) iterates, :mod:`ctmm.compiled_sweep_newton`), at most
  ``max_iterations`` (each a short-circuit branch: converged steps skip the rest),
  the stopping rule of the Python stepper (``max |delta a| <= tolerance (1 + max |a|)``).
  Same root as :func:`~ctmm.planar.implicit.simulate_implicit` (whose Newton runs on the transfer form of
  the same equations): the two agree to round-off (``tests/test_compiled_scene_schemes.py``); same iterates
  where :mod:`ctmm.compiled_newton_weighting` gives the tangent of the mass-weighted residual ``M r`` (hinge
  angles and modal coordinates), as the transfer form is (``tests/test_compiled_newton_weighting.py``).

Generated state: the history ``6 n`` followed by ``[first failed step, its residual, Newton iterations so far]``. A
step that does not converge (or gives a non-finite acceleration) stores NaN from then on, which ends the run
(:func:`ctmm.generated_loop.run_blocks`) and is raised as a :class:`~ctmm.errors.ConvergenceError` naming the step,
time and residual with the states stored before it as ``partial_result``. The scheme and the Newton options are
constants of the code, the model's numbers the input ``p`` (:func:`parameter_vector`); the library is keyed before
anything is built (:func:`ctmm.compiled_scene_key.scheme_description`, a hit certified against the numpy sweep; with
loops on the serialized step: :func:`ctmm.generated_loop.compiled_time_loop`).

Refused (:class:`~ctmm.errors.ModelError`): what the generated RK4 refuses, a scheme whose step is not linear in its
history (loops: :mod:`ctmm.compiled_scheme_loops`; controllers: :mod:`ctmm.compiled_scheme_cosim`).
"""
from __future__ import annotations

import os
import time as _time
from typing import Any, Sequence

import numpy as np

from . import validation
from .compiled_parameters import compile_refusal, compiled_actuators, parameter_vector
from .compiled_newton_weighting import inverse_mass_terms, mapped_weighted_residual, weighted_residual_terms
from .compiled_scene import symbolic_accelerations_with_inputs
from .compiled_scene_key import certified_hit, described_time_loop, scheme_description
from .compiled_scene_fold import folded_accelerations_with_inputs, scheme_fold_period
from .compiled_sweep_newton import iteration_count, sweep_iteration, sweep_refusal
from .errors import ConvergenceError, ModelError
from .generated_loop import BlockRunner, run_blocks
from .mapped_tangent import residual_terms as mapped_residual_terms, tangent_construction
from .planar.guards import check_scheme, check_stored, divergence_guard
from .planar.integrate import PlanarSimulation, check_store_every, initial_coordinates, step_total
from .planar.model import PlanarModel
from .schemes import History, Scheme, as_scheme

__all__ = ["HISTORY", "SecondOrderMaps", "CompiledSceneScheme", "SchemeHooks", "check_step_scaling",
           "newton_iteration", "newton_options", "not_converged", "reused_or_built", "scheme_maps", "selected",
           "simulate_scheme_generated", "symbolic_scheme_step"]

HISTORY = ("q", "v", "a", "equation_acceleration", "q_old1", "q_old2")
"""The stored history of every coordinate, in the order of the generated state (blocks of ``n``)."""

STATUS = ("failed_step", "failed_residual", "newton_iterations")
"""The entries after the history in the generated state."""

TIME_POWER = np.array([0, 1, 2, 2, 0, 0])
"""Powers of seconds in the units of :data:`HISTORY` (``q``: unit, ``v``: unit/s, ``a``: unit/s^2): an entry of
the maps from history ``i`` to history ``j`` scales as ``h^(TIME_POWER[i] - TIME_POWER[j])``."""


class SecondOrderMaps:
    """A scheme's nonlinear step of size ``h`` [s] as linear maps of one coordinate's history.

    Parameters
    ----------
    scheme : Scheme
        Any scheme with a nonlinear second-order form.
    h : float
        The step the maps are read at [s] (1 s for the generated code, scaled by :meth:`scaled`).
    steps : int
        Steps done before (a start-up such as Houbolt's two Newmark steps has maps of its own).

    Attributes
    ----------
    position_weight, velocity_weight : float
        ``b' h^2`` [s^2] and ``g' h`` [s].
    time_fraction : float
        Evaluation time after ``t_n`` as a fraction of ``h`` [-].
    predictor : ndarray, shape (2, 6)
        Rows ``q_hat``, ``v_hat`` on the history :data:`HISTORY`.
    update : ndarray, shape (6, 7)
        The new history from ``[history; a]``.

    Raises
    ------
    ModelError
        The scheme has no nonlinear form or its step is not linear in the history.
    """

    def __init__(self, scheme: Scheme, h: float, steps: int = 0) -> None:
        self.scheme, self.h, self.steps = scheme, float(h), int(steps)
        scalars, _, _ = self._apply(np.zeros(6), 0.0)
        self.position_weight, self.velocity_weight, self.time_fraction = scalars
        probes = [self._apply(column[:6], column[6]) for column in np.eye(7)]       # unit histories
        self.predictor = np.array([predictor for _, predictor, _ in probes[:6]]).T
        self.update = np.array([new for _, _, new in probes]).T
        for sample in np.random.default_rng(5).standard_normal((2, 7)):     # linear: checked at random histories
            values, predictor, new = self._apply(sample[:6], sample[6])
            if not (_close(self.predictor @ sample[:6], predictor) and _close(self.update @ sample, new)
                    and _close(np.array(values), np.array(scalars))):
                raise ModelError(f"scheme {scheme!r}: its nonlinear step is not linear in the stored history, "
                                 "which the generated DT-TMM step of planar models needs (use compiled=None)")

    def _apply(self, history: np.ndarray, acceleration: float) -> tuple[tuple, np.ndarray, np.ndarray]:
        """``((b' h^2, g' h, fraction), (q_hat, v_hat), new history)`` of one coordinate."""
        point = [np.array([value]) for value in history]
        state = History(point[0], point[1], point[2], [point[4], point[5]], self.steps, point[3])
        plan = self.scheme.second_order_step(state, self.h)
        new = self.scheme.second_order_update(state, np.array([acceleration]), self.h, plan)
        equation = new.a if new.equation_acceleration is None else new.equation_acceleration
        scalars = (float(plan.position_weight), float(plan.velocity_weight), float(plan.time_fraction))
        predictor = np.array([float(plan.q_predictor[0]), float(plan.v_predictor[0])])
        after = np.array([float(new.x[0]), float(new.v[0]), float(new.a[0]), float(equation[0]),
                          float(new.x_old[0][0]), float(new.x_old[1][0])])
        return scalars, predictor, after

    def same(self, other: "SecondOrderMaps") -> bool:
        """Whether ``other`` is the same step (Houbolt's start-up ends where the maps stop changing)."""
        return (np.array_equal(self.predictor, other.predictor) and np.array_equal(self.update, other.update)
                and (self.position_weight, self.velocity_weight, self.time_fraction)
                == (other.position_weight, other.velocity_weight, other.time_fraction))

    def scaled(self, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(scalars, predictor, update)`` of maps read at ``h = 1 s`` scaled to the step ``h`` [s] by the
        units of the history (:data:`TIME_POWER`), to compare with the maps read at ``h``."""
        power = np.concatenate([TIME_POWER, [2]])
        scalars = np.array([self.position_weight * h ** 2, self.velocity_weight * h, self.time_fraction])
        predictor = self.predictor * h ** (power[None, :6] - TIME_POWER[:2, None])
        return scalars, predictor, self.update * h ** (power[None, :] - TIME_POWER[:, None])


def check_step_scaling(scheme: Scheme, maps: list[SecondOrderMaps], h: float) -> None:
    """Refuse a scheme whose step at ``h`` [s] is not its step at 1 s scaled by the units (a time scale of its
    own), which the generated step (``h`` an input, maps read at 1 s) would get wrong.

    Raises
    ------
    ModelError
        Naming the scheme and the step.
    """
    for steps, unit in enumerate(maps):
        at_h = SecondOrderMaps(scheme, h, steps)
        for mine, theirs in zip(unit.scaled(h), (np.array([at_h.position_weight, at_h.velocity_weight,
                                                           at_h.time_fraction]), at_h.predictor, at_h.update)):
            if not _close(mine, theirs):
                raise ModelError(f"scheme {scheme!r}: its step at dt = {h!r} s is not its step at 1 s scaled by "
                                 "the units of q, v and a (a time scale of its own), which the generated DT-TMM "
                                 "step of planar models needs (use compiled=None)")


def _close(mine: np.ndarray, theirs: np.ndarray) -> bool:
    """Equal to round-off (relative ``1e-12`` of the largest entry)."""
    return bool(np.allclose(mine, theirs, rtol=1e-12, atol=1e-12 * (1.0 + np.max(np.abs(theirs), initial=0.0))))


def scheme_maps(scheme: Scheme, h: float) -> list[SecondOrderMaps]:
    """The maps of steps ``0, 1, ...`` up to the first that every later step repeats (checked one step on)."""
    maps = [SecondOrderMaps(scheme, h, 0)]
    for steps in range(1, 6):
        later = SecondOrderMaps(scheme, h, steps)
        if later.same(maps[-1]) and SecondOrderMaps(scheme, h, steps + 1).same(later):
            return maps
        maps.append(later)
    raise ModelError(f"scheme {scheme!r}: its step still changes after 5 steps (a start-up longer than the "
                     "generated DT-TMM step of planar models selects); use compiled=None")


def newton_iteration(residual_terms: Any, tolerance: float) -> Any:
    """One Newton iteration on ``r(a) = 0`` as a casadi ``Function`` ``(z, *arguments) -> z`` with
    ``z = [a; converged; max |delta a|; iterations]``: ``a <- a - J^-1 r`` (QR) from ``residual_terms(a, *arguments)
    -> (r, J)``, converged when ``max |delta a| <= tolerance (1 + max |a|)``; a converged ``z`` is returned
    unchanged (a short-circuit branch: the iterations after convergence cost nothing)."""
    import casadi as ca

    n = residual_terms.size1_in(0)
    z = ca.MX.sym("z", n + 3)
    arguments = [ca.MX.sym(residual_terms.name_in(i), residual_terms.sparsity_in(i))
                 for i in range(1, residual_terms.n_in())]
    r, jacobian = residual_terms(z[:n], *arguments)
    delta = ca.solve(jacobian, r, "qr")
    new = z[:n] - delta
    change = ca.mmax(ca.fabs(delta)) if n else ca.MX(0.0)
    converged = change <= tolerance * (1.0 + (ca.mmax(ca.fabs(new)) if n else 0.0))
    step = ca.Function("newton_iteration", [z, *arguments], [ca.vertcat(new, converged, change, z[n + 2] + 1.0)])
    return ca.Function("newton_or_done", [z, *arguments], [ca.if_else(z[n], z, step(z, *arguments), True)])


def newton_options(owner: str, tolerance: float, max_iterations: int, store_every: int, rows: int
                   ) -> tuple[float, int, int, int]:
    """``(tolerance, max_iterations, store_every, rows)`` of a generated scheme checked (``owner`` names it).

    Raises
    ------
    ModelError
        ``tolerance`` not > 0, ``max_iterations``, ``store_every`` or ``rows`` not integers >= 1.
    """
    if isinstance(rows, bool) or not isinstance(rows, (int, np.integer)) or rows < 1:
        raise ModelError(f"{owner}: rows must be an integer >= 1 (stored states per block), got {rows!r}")
    return (validation.positive("tolerance", tolerance),
            validation.integer("max_iterations", max_iterations, minimum=1),
            check_store_every(validation.integer("store_every", store_every, minimum=1)), int(rows))


def symbolic_scheme_step(maps: list[SecondOrderMaps], history: list, h: Any, k: Any, iterate: Any,
                         max_iterations: int, status: Any) -> tuple[list, Any, Any]:
    """One scheme step with Newton on casadi MX symbols (the step of both generated families).

    Parameters
    ----------
    maps : list of SecondOrderMaps
        Read at ``h = 1 s`` (:func:`scheme_maps`).
    history : list of 6 columns or None
        :data:`HISTORY` at ``t_n`` (``None``: zero, e.g. positions in a chart at ``q_n``).
    h, k : casadi.MX
        Step [s] and the index of the step.
    iterate : callable
        ``iterate(z, predictor, v_hat, b' h^2, g' h, fraction) -> z``: one Newton iteration
        (:func:`newton_iteration` bound to the family's other arguments), ``z = [a; converged; change; count]``.
    max_iterations : int
    status : casadi.MX
        :data:`STATUS` before the step.

    Returns
    -------
    new : list of 6 casadi.MX
        :data:`HISTORY` after the step (positions: the predictor's row of the map plus ``b' h^2 a``).
    failed : casadi.MX
        True when this or an earlier step did not converge.
    status : casadi.MX
        :data:`STATUS` after the step.
    """
    import casadi as ca

    n = next(part for part in history if part is not None).numel()
    scale = [1.0, h, h * h, h * h, 1.0, 1.0]                # the history in units of h = 1 s (TIME_POWER)
    scaled = [None if part is None else part * factor for part, factor in zip(history, scale)]

    def combination(row: np.ndarray, extra: Any = None) -> Any:
        terms = [float(c) * scaled[j] for j, c in enumerate(row[:6]) if c != 0.0 and scaled[j] is not None]
        if extra is not None and row[6] != 0.0:
            terms.append(float(row[6]) * extra)
        return sum(terms[1:], terms[0]) if terms else ca.MX.zeros(n)

    predictor = selected(maps, k, lambda m: combination(m.predictor[0]))
    v_hat = selected(maps, k, lambda m: combination(m.predictor[1])) / h
    weights = (selected(maps, k, lambda m: m.position_weight) * h * h,
               selected(maps, k, lambda m: m.velocity_weight) * h)
    fraction = selected(maps, k, lambda m: m.time_fraction)
    z = ca.vertcat(history[3], 0.0, np.inf, 0.0)              # Newton from the last acceleration
    for _ in range(max_iterations):
        z = iterate(z, predictor, v_hat, *weights, fraction)
    solved, ok, change, used = z[:n], z[n], z[n + 1], z[n + 2]
    new = [selected(maps, k, lambda m, i=i: combination(m.update[i], solved * h * h)) / factor
           for i, factor in enumerate(scale)]
    failed_before = status[0] > 0.0
    fail = ca.if_else(failed_before, status[0], ca.if_else(ok, 0.0, k + 1.0))
    out = ca.vertcat(fail, ca.if_else(failed_before, status[1], ca.if_else(ok, 0.0, change)), status[2] + used)
    return new, fail > 0.0, out


def selected(maps: list[SecondOrderMaps], k: Any, value: Any) -> Any:
    """``value(maps[j])`` of step ``k`` (the last maps from ``len(maps) - 1`` on), on casadi symbols."""
    import casadi as ca

    out = value(maps[-1])
    for j in range(len(maps) - 2, -1, -1):
        out = ca.if_else(k < j + 0.5, value(maps[j]), out)
    return out


class SchemeHooks:
    """Where a generated scheme step (planar :class:`CompiledSceneScheme`, spatial
    :class:`ctmm.compiled_spatial_schemes.CompiledSpatialScheme`) lets loops in: without loops, the plant's
    acceleration at the iterate and no controller entries (:class:`ctmm.compiled_scheme_loop_terms.SchemeLoopTerms`
    overrides them)."""

    loops: Any = None
    """The :class:`~ctmm.compiled_loops.ClosedLoops` closed in the step (:mod:`ctmm.compiled_scheme_loops`), or None."""
    state_functions: tuple = ()
    """Further casadi Functions of the library (a subclass's :meth:`closed_acceleration` sets them; compiled after)."""
    controller_size: int = 0
    """Entries of the generated state after :data:`STATUS` (a subclass's loop controller states; none here)."""
    parameters: np.ndarray
    """The step's input ``p`` (numbers; empty where they are constants of the code), set by the subclass."""

    def continue_run(self, state: np.ndarray, held: np.ndarray, dt: float, n_steps: int, first_step: int,
                     since_start: int | None = None, runner: BlockRunner | None = None) -> np.ndarray:
        """Stored states (rows, :attr:`state_size`) of ``n_steps`` steps of ``dt`` [s] from ``state`` at step
        ``first_step`` with the input vector ``held`` over them (a sample interval, :mod:`ctmm.compiled_scheme_cosim`).
        ``since_start``: steps since the scheme's start-up last began (default ``first_step``; ``0`` where a multistep
        scheme restarts at a held input's jump, :meth:`ctmm.schemes.Scheme.restart`): the failed-step status's count."""
        dt = validation.positive("dt", dt)
        if dt not in self.checked_steps:            # (once per step: a co-simulation calls once per sample)
            check_step_scaling(self.scheme, self.maps, dt)
            self.checked_steps.add(dt)
        since = first_step if since_start is None else since_start
        return run_blocks(self._blocks, self._stride, self._step, self.store_every, np.asarray(state)[:, None],
                          np.asarray(held, dtype=float), dt, validation.integer("n_steps", n_steps, minimum=1),
                          (first_step - since) * dt, self.parameters[:, None], first_step=since, runner=runner)[0]

    def iterate_acceleration(self, acceleration: Any, q: Any, v: Any, u: Any, p: Any, t: Any, c: Any, s: Any) -> Any:
        """``qddot`` at a Newton iterate ``(q, v)`` and time ``t`` on casadi SX symbols, ``c`` the
        :attr:`controller_size` entries at the step start, ``s`` [s] the time since it: here
        ``acceleration(q, v, u, p, t)``."""
        return acceleration(q, v, u, p, t)

    def controller_update(self, q: Any, v: Any, u: Any, p: Any, t: Any, c: Any, h: Any) -> Any:
        """The :attr:`controller_size` entries after a step of ``h`` [s] to ``(q, v, t)`` from ``c`` (SX)."""
        return c

    def initial_controller(self, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """The :attr:`controller_size` entries at ``t = 0``."""
        return np.zeros(self.controller_size)


class CompiledSceneScheme(SchemeHooks):
    """The generated and compiled DT-TMM step of one planar model without loops (module docstring).

    Parameters
    ----------
    model : PlanarModel
        Compilable (:func:`ctmm.compiled_parameters.compile_refusal`).
    scheme : Scheme or str
        A :mod:`ctmm.schemes` scheme or its name.
    store_every : int
        Steps per stored state.
    tolerance : float
        Newton stops when ``max |delta a| <= tolerance (1 + max |a|)`` (as the Python stepper).
    max_iterations : int
        Newton iterations allowed per step.
    rows : int
        Stored states per generated block.
    cache_dir, compiler, tangent, station_inputs
        Of :func:`ctmm.codegen.shared_library`; the Newton tangent's construction ("mapped", "symbolic", "sweep":
        :mod:`ctmm.compiled_sweep_newton`; None: by size, :func:`ctmm.mapped_tangent.tangent_construction`); beam
        station loads that are inputs too (:func:`~ctmm.compiled_parameters.compiled_actuators`, cosimulation).

    Attributes
    ----------
    actuators : tuple of str
        The inputs ``u`` of the step (held at zero on the verb's path).
    maps : list of SecondOrderMaps
        The scheme's steps read at ``h = 1 s`` (more than one: a start-up).
    compile_time_s : float
        Building, generating and compiling (or loading) [s].
    """

    def __init__(self, model: PlanarModel, scheme: Scheme | str = "newmark", *, store_every: int = 1,
                 tolerance: float = 1e-10, max_iterations: int = 20, rows: int = 64,
                 cache_dir: str | os.PathLike | None = None, compiler: str | None = None,
                 tangent: str | None = None, station_inputs: Sequence[str] = ()) -> None:
        if not isinstance(model, PlanarModel):
            raise ModelError(f"CompiledSceneScheme: model must be a PlanarModel, got {type(model).__name__}")
        reason = compile_refusal(model, driven_signals=True)    # moving drives at the step's evaluation time
        if reason:
            raise ModelError(f"CompiledSceneScheme: {reason}")
        self.scheme = as_scheme(scheme)
        self.tangent = tangent_construction("CompiledSceneScheme", tangent, model.n_coordinates,
                                            sweep_refusal(model, self.loops))
        self.period = scheme_fold_period(model, self.tangent, self.loops)     # sweep folded over segments (0: not)
        self.tolerance, self.max_iterations, self.store_every, rows = newton_options(
            "CompiledSceneScheme", tolerance, max_iterations, store_every, rows)
        start = _time.perf_counter()
        self.model, self.checked_steps = model, set()      # steps [s] check_step_scaling accepted
        self.maps, self.actuators = scheme_maps(self.scheme, 1.0), compiled_actuators(model, station_inputs)
        self.parameters = parameter_vector(model)
        name = f"scene_{model.n_bodies}b{model.n_coordinates}q_{self.scheme.name}" + ("_loops" if self.loops else "")
        described = (self.scheme, self.tangent, self.period, self.tolerance, self.max_iterations, self.actuators)
        loop = described_time_loop(scheme_description(model, described) if type(self) is CompiledSceneScheme else None,
                                   self._built, lambda extra: certified_hit(model, extra[0], self.parameters),
                                   self.store_every, rows, name, cache_dir=cache_dir, compiler=compiler)  # (loops: read
        (self._acceleration, *more), self._step, self._stride, self._blocks = loop.extra, loop.step, loop.stride, \
            loop.blocks                         # more, keyed on the built functions)
        self.state_functions, self.compile_time_s = tuple(more), _time.perf_counter() - start

    def closed_acceleration(self) -> Any:
        """``qddot = acceleration(q, v, u, p, t)`` the step solves for (casadi ``Function``): the plant's sweep with
        the inputs :attr:`actuators` (a subclass closes loops around it, :mod:`ctmm.compiled_scheme_loops`)."""
        return folded_accelerations_with_inputs(self.model, self.actuators, (), self.period) if self.period else \
            symbolic_accelerations_with_inputs(self.model, self.actuators)

    @property
    def status_index(self) -> int:
        """Where :data:`STATUS` starts in the state: after the history ``6 n``."""
        return 6 * self.model.n_coordinates

    @property
    def state_size(self) -> int:
        """Length of the generated state: the history ``6 n``, :data:`STATUS` and :attr:`controller_size`."""
        return self.status_index + len(STATUS) + self.controller_size

    def _built(self) -> tuple[Any, list]:
        """``(step(y, u, h, p, t0, k), [closed_acceleration(), *state_functions])`` on symbols (on a cache miss)."""
        import casadi as ca

        closed = self.closed_acceleration()
        n, n_u, n_p = self.model.n_coordinates, len(self.actuators), self.parameters.size
        a, q_hat, v_hat = (ca.SX.sym(label, n) for label in ("a", "q_hat", "v_hat"))
        w, g, t = ca.SX.sym("w"), ca.SX.sym("g"), ca.SX.sym("t")
        u, p = ca.SX.sym("u", n_u), ca.SX.sym("p", n_p)
        q, v = ca.SX.sym("q", n), ca.SX.sym("v", n)
        c, s = ca.SX.sym("c", self.controller_size), ca.SX.sym("s")        # controller entries, time since t_n
        mapped = self.tangent == "mapped"   # columns by mapped forward derivatives (code O(sweep)), one sweep
        residual_terms = mapped_weighted_residual(self.model, self.actuators, self.period) if mapped and \
            self.loops is None else None
        if residual_terms is None and self.tangent != "sweep":
            rates = self.iterate_acceleration(closed, q, v, u, p, t, c, s)
            if mapped:
                residual_terms = mapped_residual_terms(ca.Function("rates", [q, v, u, p, t, c, s], [rates]))
            else:                       # the symbolic Jacobian of the straight-line sweep
                tangent_q = ca.Function("tangent", [q, v, u, p, t, c, s],
                                        [rates, ca.jacobian(rates, q), ca.jacobian(rates, v)])
                value, d_q, d_v = tangent_q(q_hat + w * a, v_hat + g * a, u, p, t, c, s)
                residual_terms = ca.Function("residual", [a, q_hat, v_hat, w, g, t, u, p, c, s],
                                             [a - value, ca.SX.eye(n) - w * d_q - g * d_v])
            weighting = inverse_mass_terms(self.model, mapped)      # Newton on M (a - qddot), as the Python stepper
            residual_terms = weighted_residual_terms(residual_terms, *weighting) if weighting else residual_terms
        iterate = sweep_iteration(self.model, self.actuators, self.period, self.tolerance, self.loops) \
            if self.tangent == "sweep" else newton_iteration(residual_terms, self.tolerance)     # O(N) / Newton
        y = ca.MX.sym("y", self.state_size)
        u_in, h, p_in, t0, k = ca.MX.sym("u", n_u), ca.MX.sym("h"), ca.MX.sym("p", n_p), ca.MX.sym("t0"), ca.MX.sym("k")
        controller = y[self.status_index + len(STATUS):]
        new, failed, status = symbolic_scheme_step(
            self.maps, [y[j * n:(j + 1) * n] for j in range(6)], h, k,
            lambda z, q_hat_k, v_hat_k, w_k, g_k, fraction: iterate(z, q_hat_k, v_hat_k, w_k, g_k,
                                                                    t0 + (k + fraction) * h, u_in, p_in,
                                                                    controller, fraction * h),
            iteration_count(self.tangent, self.max_iterations), y[6 * n:6 * n + len(STATUS)])
        history_out = ca.if_else(failed, ca.MX.nan(6 * n, 1), ca.vertcat(*new))
        out = [history_out, status]
        if self.controller_size:
            update = ca.Function("controller_update", [q, v, u, p, t, c, s],
                                 [self.controller_update(q, v, u, p, t, c, s)])
            after = update(new[0], new[1], u_in, p_in, t0 + (k + 1.0) * h, controller, h)
            out.append(ca.if_else(failed, ca.MX.nan(self.controller_size, 1), after))
        return ca.Function("step", [y, u_in, h, p_in, t0, k], [ca.vertcat(*out)]), [closed, *self.state_functions]

    def accelerations(self, q: Any, qdot: Any, t: float = 0.0) -> np.ndarray:
        """``qddot`` [unit/s^2] of the generated sweep at ``(q, qdot, t)`` without actuator inputs."""
        q, qdot = self.model.state(q, qdot)
        return np.asarray(self._acceleration(q, qdot, np.zeros(len(self.actuators)), self.parameters,
                                             validation.finite("t", t))).reshape(-1)

    def initial_state(self, q: np.ndarray, qdot: np.ndarray, held: np.ndarray | None = None) -> np.ndarray:
        """The generated state at ``t = 0``: history ``(q, qdot, qddot, qddot, q, q)``, no failure; ``held``: the
        values of :attr:`actuators` (default zero)."""
        return self.restarted(np.concatenate([q, qdot, np.zeros(4 * q.size + len(STATUS)),
                                              self.initial_controller(q, qdot)]), held, 0.0, start=True)

    def restarted(self, state: np.ndarray, held: np.ndarray | None, t: float, start: bool = False) -> np.ndarray:
        """``state`` with the acceleration of its history (``a`` and ``qddot``) solved again at its ``(q, qdot)``
        and time ``t`` [s] with the actuator values ``held`` (the Python stepper's restart where held controller
        outputs jump); ``start``: also the earlier positions (the state at ``t = 0``)."""
        n = self.model.n_coordinates
        out = np.array(state, dtype=float)
        held = np.zeros(len(self.actuators)) if held is None else np.asarray(held, dtype=float)
        acceleration = np.asarray(self._acceleration(out[:n], out[n:2 * n], held, self.parameters,
                                                     validation.finite("t", t))).reshape(-1)
        out[2 * n:3 * n] = out[3 * n:4 * n] = acceleration
        if start:
            out[4 * n:5 * n] = out[5 * n:6 * n] = out[:n]
        return out

    def run(self, state: np.ndarray, dt: float, n_steps: int) -> np.ndarray:
        """Stored states (rows, :attr:`state_size`) of ``n_steps`` steps of ``dt`` [s] from ``state`` at ``t = 0``
        (after each ``store_every`` steps and after the last; stops after the first block holding a NaN).

        Raises
        ------
        ModelError
            Bad arguments; a scheme whose step at ``dt`` is not its step at 1 s scaled (:func:`check_step_scaling`).
        """
        return self.continue_run(state, np.zeros(len(self.actuators)), dt, n_steps, 0)


def not_converged(compiled: Any, row: np.ndarray, h: float, partial: Any = None, offset: int = 0
                  ) -> ConvergenceError:
    """The :class:`ConvergenceError` of a stored state ``row`` whose status says a step did not converge (its step,
    time and residual; ``partial``: the result before it; ``offset``: steps before the run's step count began)."""
    status, tangent = compiled.status_index, getattr(compiled, "tangent", None)
    step, kind = offset + int(row[status]), "sweep" if tangent == "sweep" else "Newton"
    return ConvergenceError(
        f"generated implicit DT-TMM step {step} (t = {step * h:.6g} s) did not converge: residual max|delta qdd| = "
        f"{row[status + 1]:.3e} after {iteration_count(tangent, compiled.max_iterations)} {kind} iterations "
        f"(tolerance {compiled.tolerance:g}); reduce dt", time=step * h, partial_result=partial)


def reused_or_built(kind: type, compiled: Any, model: Any, scheme: Scheme, store_every: int, **options: Any) -> Any:
    """``compiled`` when it is a ``kind`` (a compiled scheme class) of ``model`` with ``scheme`` and ``store_every``;
    a new ``kind(model, scheme, store_every=store_every, **options)`` when it is ``None``.

    Raises
    ------
    ModelError
        ``compiled`` is something else.
    """
    if compiled is None:
        return kind(model, scheme, store_every=store_every, **options)
    if not isinstance(compiled, kind) or compiled.model is not model or compiled.scheme != scheme or \
            compiled.store_every != store_every:
        raise ModelError(f"compiled must be a {kind.__name__} of this model with scheme={scheme!r} and "
                         f"store_every={store_every!r}, got {compiled!r}")
    return compiled


def simulate_scheme_generated(model: PlanarModel, q0: Any, qdot0: Any, *, t_final: float, dt: float,
                              scheme: Scheme | str = "newmark", store_every: int = 1,
                              divergence_bound: float | None = None, stability_check: str = "warn",
                              tolerance: float = 1e-10, max_iterations: int = 20,
                              cache_dir: str | os.PathLike | None = None,
                              compiled: CompiledSceneScheme | None = None) -> PlanarSimulation:
    """A DT-TMM scheme of a planar model with its Newton iterations and time loop in generated C.

    Same arguments and result as :func:`ctmm.planar.implicit.simulate_implicit` (method label
    ``"dt-tmm-generated/<Scheme>"``, ``iterations`` ``None``, ``extra`` with ``compile_time_s`` and
    ``newton_iterations``, the total).  The step is checked against the scheme's stability limit before the
    run (:func:`ctmm.planar.guards.check_scheme`); the divergence bound on the stored states after it.

    Parameters
    ----------
    compiled : CompiledSceneScheme, optional
        Of ``model`` with this scheme, ``store_every`` and Newton options, to reuse (default: built now).

    Raises
    ------
    ModelError
        A model the generated code refuses, bad arguments (``dt`` not > 0, unknown scheme), no compiler.
    ConvergenceError
        A step whose Newton iterations did not converge, naming step, time and residual, with the states
        stored before it as ``partial_result``.
    SimulationError
        Divergence (the states up to the last good one as ``partial_result``).
    """
    if dt is None:
        raise ModelError("dt is required with a DT-TMM scheme (a fixed step [s], > 0), got None")
    scheme = as_scheme(scheme)
    q, v = initial_coordinates(model, q0, qdot0)
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps
    compiled = reused_or_built(CompiledSceneScheme, compiled, model, scheme, store_every, tolerance=tolerance,
                               max_iterations=max_iterations, cache_dir=cache_dir)
    guard = divergence_guard(model, q, divergence_bound)
    closed = None if compiled.loops is None else (lambda _, q_k, v_k, t_k: compiled.accelerations(q_k, v_k, t_k))
    check_scheme(model, q, v, h, scheme=scheme, policy=stability_check, accelerations=closed)   # loops included
    start = _time.perf_counter()
    first = compiled.initial_state(q, v)
    rows = compiled.run(first, h, n_steps)
    wall, every, n = _time.perf_counter() - start, compiled.store_every, model.n_coordinates
    steps = np.array([k for k in range(1, n_steps + 1) if k % every == 0 or k == n_steps])[:len(rows)]
    states = np.vstack([first[None], rows])
    t = np.concatenate([[0.0], steps * h])
    label = f"dt-tmm-generated/{type(scheme).__name__}"
    qs, vs = states[:, :n], states[:, n:2 * n]
    controller = states[:, compiled.status_index + len(STATUS):]       # loop controller entries (a subclass's)
    extra = {"controller_states": controller} if compiled.controller_size else {}

    def partial(k: int) -> PlanarSimulation:
        return PlanarSimulation(model, t[:k], qs[:k], vs[:k], label, wall,
                                extra={name: value[:k] for name, value in extra.items()})

    from .compiled_control import first_loop_failure, loop_state_failure
    failed = np.flatnonzero(states[:, 6 * n] > 0.0)
    good = len(states) if not failed.size else int(failed[0])
    held = np.zeros(len(compiled.actuators))   # modal beams' deflection too; a failing interval replayed step by step
    replay, rule = (lambda x, k: compiled.continue_run(x, held, h, 1, k)[-1]), type(scheme).__name__.lower()
    controller_entries = compiled.status_index + len(STATUS)
    loop_row = good if compiled.loops is None else first_loop_failure(compiled.loops, states[:good], controller_entries)
    check_stored(guard, t[:loop_row], qs[:loop_row], vs[:loop_row], partial, model=model, step=h, states=states,
                 method=rule, replay=replay)
    if loop_row < good:                 # a loop's controller state non-finite: named by loop, at its step
        raise loop_state_failure(compiled.loops, t, states, loop_row, h, replay, lambda times, pair: check_stored(
            guard, times, pair[:, :n], pair[:, n:2 * n], lambda _: partial(loop_row), model=model, step=h,
            method=rule), partial, controller_entries)
    if failed.size:
        raise not_converged(compiled, states[failed[0]], h, partial(good))
    return PlanarSimulation(model, t, qs, vs, label, wall, n_evaluations=int(states[-1, 6 * n + 2]) + 1,
                            extra={"compile_time_s": compiled.compile_time_s,
                                   "newton_iterations": int(states[-1, 6 * n + 2]), **extra})
