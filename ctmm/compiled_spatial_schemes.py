"""Generated DT-TMM schemes of spatial models: the Lie-group step + Newton in C (issues 13 and 14).

``ctmm.simulate(spatial_model, t_final, dt, method="newmark" | "generalized_alpha" | "wilson_theta" |
"houbolt" | "forward_euler" | <Scheme>, compiled=True)`` runs here (what
:func:`ctmm.compiled_spatial.spatial_compile_refusal` accepts: rigid trees, :class:`~ctmm.spatial.SpatialBeam`,
spatial finite-element subsystems; loads and driven joints with ctmm.signals on the time symbol, with loops too;
inputs held numbers).  The step is the one of
:func:`ctmm.spatial.implicit.simulate_spatial_implicit`: in the local chart at the last configuration ``q_n`` the
scheme's nonlinear second-order form
(:class:`~ctmm.compiled_scene_schemes.SecondOrderMaps` with the history ``x_n = 0``, ``v_n``, ``a_n``,
``v_dot_n``) gives

``delta = delta_hat + b' h^2 a``,   ``v = v_hat + g' h a``,   ``q = q_n (+) delta``,   ``a = v_dot(q, v, u)``

with ``(+)`` the retraction of :mod:`ctmm.spatial.lie` stated here on casadi symbols (:func:`symbolic_retract`:
incremental rotation vectors on ``SO(3)``, body twists on ``SE(3)``, series below the same small angles) and
``v_dot`` the one articulated sweep of the generated RK4 (:class:`ctmm.compiled_spatial.SpatialRates`).  Newton
on ``r(a) = a - v_dot(q_n (+) delta(a), v(a), u)`` with its exact tangent (casadi's derivative through the
retraction and the sweep, from 3 velocities by one directional derivative along ``a`` mapped over the unit seeds,
:func:`ctmm.mapped_tangent.value_and_jacobian`: 0.4-0.65x the C and 0.35-0.6x the gcc CPU of the symbolic
Jacobian; :func:`ctmm.compiled_scene_schemes.newton_iteration`), so it converges quadratically where
the Python stepper's sweep tangent converges linearly; the same root, the same stopping rule.  Houbolt differences
configurations: after its two Newmark start-up steps the earlier configurations enter in the chart at ``q_n``,
``x_{n-k} = log(q_n^-1 q_{n-k})`` (:func:`symbolic_local_coordinates`, the group logarithm on symbols), and body
velocities and rates are the chart's with the brackets of :func:`ctmm.spatial.lie.bracket`
(:func:`symbolic_bracket`), as on the Python path.

Generated state: ``[q (nq, unit quaternions), v, a, v_dot (nv each), (Houbolt: q_{n-1}, q_{n-2}), failed step,
its residual, Newton iterations]`` (the generated RK4's ``[q ; v]`` followed by the scheme's history).  A step that
does not converge stores NaN from then on and is raised as a :class:`~ctmm.errors.ConvergenceError` (step, time,
residual, the states before it).  The scheme, the Newton options and the model's numbers are constants of the
code; ``dt`` is an input (the maps read at 1 s and scaled, :func:`ctmm.compiled_scene_schemes.check_step_scaling`);
the cache key is the model's description (:func:`ctmm.model_description.describe`), so a cached call builds no symbols.

Refused (:class:`~ctmm.errors.ModelError`): what the generated RK4 refuses.  Loops, references, outputs and port
inputs: :mod:`ctmm.compiled_spatial_scheme_loops` (this step with the hooks of
:class:`~ctmm.compiled_scene_schemes.SchemeHooks`: time and controller entries in the residual and state);
co-simulated controllers: :mod:`ctmm.compiled_scheme_cosim`.
"""
from __future__ import annotations

import os
import time as clock
import warnings
from typing import Any, Callable, Mapping

import numpy as np

from . import validation
from .compiled_scene_schemes import (STATUS, SchemeHooks, newton_iteration, newton_options, reused_or_built,
                                     scheme_maps, symbolic_scheme_step)
from .compiled_spatial import SPATIAL_FLAGS, SpatialRates, spatial_compile_refusal
from .errors import ConvergenceError, ModelError, SimulationError
from .generated_loop import compiled_time_loop
from .guard import StabilityLimitWarning
from .mapped_tangent import SPATIAL_MAPPED_MIN_VELOCITIES, tangent_construction, value_and_jacobian
from .ops import CASADI
from .planar.integrate import step_total
from .results import SimulationResult
from .schemes import Houbolt, Scheme, as_scheme
from .spatial.frames import quaternion_rotation
from .spatial.integrate import divergence_check, initial_state, state_result
from .spatial.lie import quaternion_product
from .spatial.model import SpatialModel

__all__ = ["CompiledSpatialScheme", "checked_spatial_result", "generated_rows", "simulate_spatial_scheme_generated",
           "symbolic_bracket",
           "symbolic_local_coordinates", "symbolic_retract", "warn_conditionally_stable"]


def _exponential(phi: Any) -> Any:
    """Unit quaternion of the rotation vector ``phi`` (casadi column of 3), series below 1e-4 rad."""
    import casadi as ca

    a2 = ca.dot(phi, phi)
    small = a2 <= 1e-8
    angle = ca.sqrt(ca.if_else(small, 1.0, a2))               # never the square root of 0 (its derivative)
    factor = ca.if_else(small, 0.5 - a2 / 48.0, ca.sin(0.5 * angle) / angle)
    cosine = ca.if_else(small, 1.0 - a2 / 8.0 + a2 * a2 / 384.0, ca.cos(0.5 * angle))
    return ca.vertcat(cosine, factor * phi)


def _left_jacobian(phi: Any) -> Any:
    """``J(phi) = I + (1 - cos a)/a^2 [phi]x + (a - sin a)/a^3 [phi]x^2`` on casadi symbols, series below
    ``a^2 = 1e-6`` (the statement of :func:`ctmm.spatial.lie.left_jacobian`)."""
    import casadi as ca

    a2 = ca.dot(phi, phi)
    small = a2 <= 1e-6
    a = ca.sqrt(ca.if_else(small, 1.0, a2))
    first = ca.if_else(small, 0.5 - a2 / 24.0 + a2 * a2 / 720.0, (1.0 - ca.cos(a)) / (a * a))
    second = ca.if_else(small, 1.0 / 6.0 - a2 / 120.0 + a2 * a2 / 5040.0, (a - ca.sin(a)) / (a * a * a))
    skew = ca.skew(phi)
    return ca.SX.eye(3) + first * skew + second * ca.mtimes(skew, skew)


def _product(a: Any, b: Any) -> Any:
    """Hamilton product of two casadi quaternions (the one statement of :func:`ctmm.spatial.lie.quaternion_product`)."""
    import casadi as ca

    return ca.vertcat(*quaternion_product(np.array([a[i] for i in range(4)], dtype=object),
                                          np.array([b[i] for i in range(4)], dtype=object)))


def _unit(quaternion: Any) -> Any:
    import casadi as ca

    return quaternion / ca.norm_2(quaternion)


def _moving_joints(model: SpatialModel) -> list[tuple[str, slice, slice]]:
    """``(kind, position slice, velocity slice)`` of every joint with coordinates that is not driven."""
    return [(joint.kind, layout.position, layout.velocity) for joint, layout in zip(model.joints, model.layout)
            if not joint.driven and layout.velocity.stop > layout.velocity.start]


def symbolic_retract(model: SpatialModel, q: Any, delta: Any) -> Any:
    """``q (+) delta`` (:func:`ctmm.spatial.lie.retract`) on casadi symbols: ``q`` (nq,), ``delta`` (nv,)."""
    import casadi as ca

    out = [q[i] for i in range(model.n_positions)]
    for kind, p, v in _moving_joints(model):
        qj, dj = q[p.start:p.stop], delta[v.start:v.stop]
        if kind == "spherical":
            new = _unit(_product(_unit(qj), _exponential(dj)))
        elif kind in ("free", "elastic6"):
            quaternion = _unit(qj[3:])
            rotation = quaternion_rotation(CASADI, quaternion[0], quaternion[1], quaternion[2], quaternion[3])
            new = ca.vertcat(qj[:3] + ca.mtimes(rotation, ca.mtimes(_left_jacobian(dj[3:]), dj[:3])),
                             _unit(_product(quaternion, _exponential(dj[3:]))))
        else:
            new = qj + dj
        out[p.start:p.stop] = [new[i] for i in range(p.stop - p.start)]
    for layout in model.modal:                       # beams' modal coordinates: a vector space
        if layout is not None:
            p, v = layout.position, layout.velocity
            out[p.start:p.stop] = [out[p.start + i] + delta[v.start + i] for i in range(p.stop - p.start)]
    return ca.vertcat(*out)


def _logarithm(quaternion: Any) -> Any:
    """Rotation vector (``|phi| <= pi``) of a non-zero casadi quaternion, either sign
    (:func:`ctmm.spatial.lie.quaternion_logarithm`, the same series below ``sin = 1e-8``)."""
    import casadi as ca

    quaternion = _unit(quaternion)
    quaternion = ca.if_else(quaternion[0] < 0.0, -quaternion, quaternion)
    w, vector = quaternion[0], quaternion[1:]
    s2 = ca.dot(vector, vector)
    small = s2 <= 1e-16
    sine = ca.sqrt(ca.if_else(small, 1.0, s2))
    factor = ca.if_else(small, 2.0 / w * (1.0 - s2 / (3.0 * w * w)), 2.0 * ca.atan2(sine, w) / sine)
    return factor * vector


def symbolic_local_coordinates(model: SpatialModel, q_base: Any, q: Any) -> Any:
    """``delta`` with ``q_base (+) delta = q`` (:func:`ctmm.spatial.lie.local_coordinates`) on casadi symbols."""
    import casadi as ca

    out = [ca.SX(0.0) for _ in range(model.n_velocities)]
    conjugate = np.array([1.0, -1.0, -1.0, -1.0])
    for kind, p, v in _moving_joints(model):
        base, target = q_base[p.start:p.stop], q[p.start:p.stop]
        if kind == "spherical":
            part = _logarithm(_product(_unit(base) * conjugate, _unit(target)))
        elif kind in ("free", "elastic6"):
            quaternion = _unit(base[3:])
            phi = _logarithm(_product(quaternion * conjugate, _unit(target[3:])))
            rotation = quaternion_rotation(CASADI, quaternion[0], quaternion[1], quaternion[2], quaternion[3])
            part = ca.vertcat(ca.solve(_left_jacobian(phi), ca.mtimes(rotation.T, target[:3] - base[:3])), phi)
        else:
            part = target - base
        out[v.start:v.stop] = [part[i] for i in range(v.stop - v.start)]
    for layout in model.modal:
        if layout is not None:
            p, v = layout.position, layout.velocity
            out[v.start:v.stop] = [q[p.start + i] - q_base[p.start + i] for i in range(v.stop - v.start)]
    return ca.vertcat(*out)


def symbolic_bracket(model: SpatialModel, x: Any, y: Any) -> Any:
    """Lie bracket ``[x, y]`` (:func:`ctmm.spatial.lie.bracket`) on casadi symbols."""
    import casadi as ca

    out = [0.0 * x[i] for i in range(model.n_velocities)]
    for kind, _, v in _moving_joints(model):
        if kind not in ("spherical", "free", "elastic6"):
            continue
        xj, yj = x[v.start:v.stop], y[v.start:v.stop]
        part = ca.cross(xj, yj) if kind == "spherical" else ca.vertcat(
            ca.cross(xj[3:], yj[:3]) + ca.cross(xj[:3], yj[3:]), ca.cross(xj[3:], yj[3:]))
        out[v.start:v.stop] = [part[i] for i in range(v.stop - v.start)]
    return ca.vertcat(*out)


class CompiledSpatialScheme(SchemeHooks):
    """The Lie-group DT-TMM step of a spatial model without loops, with Newton, in compiled C (module docstring).

    Parameters
    ----------
    model : SpatialModel
        What :func:`ctmm.compiled_spatial.spatial_compile_refusal` accepts.
    scheme : Scheme or str
        Any :mod:`ctmm.schemes` scheme with a nonlinear form.
    store_every, tolerance, max_iterations, rows, cache_dir, compiler, tangent
        As in :class:`ctmm.compiled_scene_schemes.CompiledSceneScheme` (``max_iterations`` default 50, as the
        Python spatial stepper; ``tangent``: the residual's Jacobian symbolic or by mapped directional derivatives
        along ``a``, :func:`ctmm.mapped_tangent.value_and_jacobian`; None: mapped from
        :data:`~ctmm.mapped_tangent.SPATIAL_MAPPED_MIN_VELOCITIES` velocities, the code a fraction of the symbolic
        Jacobian's).

    Attributes
    ----------
    rates : SpatialRates
        The sweep on symbols (numbers as constants).
    compile_time_s : float
        Building, generating and compiling (or loading) [s].
    """

    def __init__(self, model: SpatialModel, scheme: Scheme | str = "newmark", *, store_every: int = 1,
                 tolerance: float = 1e-10, max_iterations: int = 50, rows: int = 64,
                 cache_dir: str | os.PathLike | None = None, compiler: str | None = None,
                 tangent: str | None = None) -> None:
        reason = spatial_compile_refusal(model, time_signals=True)    # signals on the step's time symbol (loops too)
        if reason:
            raise ModelError(f"CompiledSpatialScheme: {reason}")
        self.scheme = as_scheme(scheme)
        self.tangent = tangent_construction("CompiledSpatialScheme", tangent, model.n_velocities,
                                            minimum=SPATIAL_MAPPED_MIN_VELOCITIES)
        self.chart = isinstance(self.scheme, Houbolt)    # differences of configurations: the chart-rate conversion
        self.tolerance, self.max_iterations, self.store_every, rows = newton_options(
            "CompiledSpatialScheme", tolerance, max_iterations, store_every, rows)
        start = clock.perf_counter()
        self.model, self.parameters = model, np.zeros(0)      # the numbers are constants of the code
        self.maps, self.checked_steps = scheme_maps(self.scheme, 1.0), set()       # steps the check accepted
        self.rates = SpatialRates(model, fold=False)
        from .model_description import describe       # what build() reads: a cached library loads without symbols

        description = describe((model, self.scheme, self.tolerance, self.max_iterations, "spatial DT-TMM scheme",
                                self.tangent, *self.described()))
        name = f"spatial_{model.n_bodies}b{model.n_positions}q{model.n_velocities}v_{self.scheme.name}" + \
            ("_loops" if self.loops else "")
        options = {"cache_dir": cache_dir, "compiler": compiler, "flags": SPATIAL_FLAGS}
        if description is not None:
            loop = compiled_time_loop(self._build, self.store_every, rows, name,
                                      description=[("spatial scheme", description)], **options)
        else:
            step, extra = self._build()
            loop = compiled_time_loop(step, self.store_every, rows, name, extra=extra, **options)
        (self._acceleration, *more), self._step, self._stride, self._blocks = loop.extra, loop.step, loop.stride, \
            loop.blocks
        self.state_functions = tuple(more)
        self.compile_time_s = clock.perf_counter() - start

    def described(self) -> tuple:
        """What a subclass's step reads besides the model, scheme and Newton options (its cache key's part)."""
        return ()

    @property
    def input_size(self) -> int:
        """Entries of the step's input ``u``: the model's inputs (:attr:`SpatialRates.widths`)."""
        return sum(self.rates.widths)

    def closed_acceleration(self) -> Any:
        """``v_dot = acceleration(q, v, u, p, t)`` (casadi ``Function``) the step solves for: the sweep of
        :attr:`rates` (a subclass closes loops around it)."""
        import casadi as ca

        model = self.model
        q, v, u = ca.SX.sym("q", model.n_positions), ca.SX.sym("v", model.n_velocities), ca.SX.sym("u", self.input_size)
        p, t = ca.SX.sym("p", 0), ca.SX.sym("t")
        return ca.Function("acceleration", [q, v, u, p, t], [self.rates.velocity_rate(q, v, u, p, t)])

    @property
    def status_index(self) -> int:
        """Where :data:`~ctmm.compiled_scene_schemes.STATUS` starts in the state: after ``[q, v, a, v_dot]`` and,
        for Houbolt, the two earlier configurations."""
        return (3 if self.chart else 1) * self.model.n_positions + 3 * self.model.n_velocities

    @property
    def state_size(self) -> int:
        """:attr:`status_index`, :data:`~ctmm.compiled_scene_schemes.STATUS` and :attr:`controller_size`."""
        return self.status_index + len(STATUS) + self.controller_size

    def _build(self) -> tuple[Any, list]:
        """``(step(y, u, h, p, t0, k), [acceleration, *state_functions])`` on casadi symbols."""
        import casadi as ca

        model, n = self.model, self.model.n_velocities
        nq, n_u = model.n_positions, self.input_size
        acceleration = self.closed_acceleration()
        a, delta_hat, v_hat, q = ca.SX.sym("a", n), ca.SX.sym("delta_hat", n), ca.SX.sym("v_hat", n), ca.SX.sym("q", nq)
        w, g, u, p = ca.SX.sym("w"), ca.SX.sym("g"), ca.SX.sym("u", n_u), ca.SX.sym("p", 0)
        t, c, s = ca.SX.sym("t"), ca.SX.sym("c", self.controller_size), ca.SX.sym("s")     # time, controller, since t_n
        chart = ca.SX.sym("chart")              # 1: Houbolt after its start-up (body rates from chart rates)
        delta, rate = delta_hat + w * a, v_hat + g * a
        body_rates = self.iterate_acceleration(acceleration, symbolic_retract(model, q, delta),
                                               rate - 0.5 * chart * symbolic_bracket(model, delta, rate), u, p, t, c, s)
        residual = a - body_rates - 0.5 * chart * symbolic_bracket(model, delta, body_rates)
        arguments = [a, delta_hat, v_hat, w, g, q, chart, u, p, t, c, s]
        residual_terms = value_and_jacobian(ca.Function("residual_value", arguments, [residual]), 0, "residual") \
            if self.tangent == "mapped" else ca.Function("residual", arguments, [residual, ca.jacobian(residual, a)])
        iterate = newton_iteration(residual_terms, self.tolerance)
        y = ca.MX.sym("y", self.state_size)
        u_in, h, p_in, t0, k = ca.MX.sym("u", n_u), ca.MX.sym("h"), ca.MX.sym("p", 0), ca.MX.sym("t0"), ca.MX.sym("k")
        q_n, end = y[:nq], nq + 3 * n
        history = [None, y[nq:nq + n], y[nq + n:nq + 2 * n], y[nq + 2 * n:end], None, None]   # chart: x_n = 0
        on = ca.MX(0.0)
        if self.chart:                          # earlier configurations in the chart at q_n (zero at the start)
            q_base, q_other = ca.SX.sym("q_base", nq), ca.SX.sym("q_other", nq)
            local = ca.Function("local", [q_base, q_other], [symbolic_local_coordinates(model, q_base, q_other)])
            on = k >= 1.5
            history[4:] = [ca.if_else(on, local(q_n, y[end + j * nq:end + (j + 1) * nq]), ca.MX.zeros(n))
                           for j in range(2)]
        controller = y[self.status_index + len(STATUS):]
        new, failed, status = symbolic_scheme_step(
            self.maps, history, h, k,
            lambda z, delta_k, v_hat_k, w_k, g_k, fraction: iterate(z, delta_k, v_hat_k, w_k, g_k, q_n, on, u_in, p_in,
                                                                    t0 + (k + fraction) * h, controller, fraction * h),
            self.max_iterations, y[self.status_index:self.status_index + len(STATUS)])
        retract = ca.Function("retract", [q, delta_hat], [symbolic_retract(model, q, delta_hat)])
        x_new, v_new = ca.MX.sym("x", n), ca.MX.sym("v", n)
        bracket = ca.Function("bracket", [x_new, v_new], [symbolic_bracket(model, x_new, v_new)])
        parts = [retract(q_n, new[0]), new[1] - 0.5 * on * bracket(new[0], new[1]), new[2], new[3]]
        if self.chart:
            parts += [q_n, y[end:end + nq]]
        history_out = ca.if_else(failed, ca.MX.nan(self.status_index, 1), ca.vertcat(*parts))
        out = [history_out, status]
        if self.controller_size:                # at the accepted state: its configuration and body velocity
            q_c, v_c = ca.SX.sym("q", nq), ca.SX.sym("v", n)
            update = ca.Function("controller_update", [q_c, v_c, u, p, t, c, s],
                                 [self.controller_update(q_c, v_c, u, p, t, c, s)])
            after = update(parts[0], parts[1], u_in, p_in, t0 + (k + 1.0) * h, controller, h)
            out.append(ca.if_else(failed, ca.MX.nan(self.controller_size, 1), after))
        return ca.Function("step", [y, u_in, h, p_in, t0, k], [ca.vertcat(*out)]), [acceleration,
                                                                                    *self.state_functions]

    def initial_state(self, x: np.ndarray, inputs: Mapping[str, Any] | None = None) -> np.ndarray:
        """The generated state at ``t = 0`` from ``[q ; v]`` (quaternions normalised): ``a = v_dot``."""
        model = self.model
        q, v = model.normalized(x[:model.n_positions]), x[model.n_positions:]
        state = np.concatenate([q, v, np.zeros(2 * v.size), *([q, q] if self.chart else []), np.zeros(len(STATUS)),
                                self.initial_controller(q, v)])
        return self.restarted(state, self.held_inputs(inputs))

    def held_inputs(self, inputs: Mapping[str, Any] | None) -> np.ndarray:
        """The step's input vector ``u`` of ``inputs`` (numbers by input name)."""
        return self.rates.input_vector(inputs)

    def restarted(self, state: np.ndarray, held: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``state`` with ``a`` and ``v_dot`` solved again at its ``(q, v)`` with the input vector ``held`` (the Python
        stepper's restart where held controller outputs jump; the spatial terms do not depend on ``t`` [s])."""
        nq, n = self.model.n_positions, self.model.n_velocities
        out = np.array(state, dtype=float)
        rates = np.asarray(self._acceleration(out[:nq], out[nq:nq + n], np.asarray(held, dtype=float),
                                              np.zeros(0), validation.finite("t", t))).reshape(-1)
        out[nq + n:nq + 2 * n] = out[nq + 2 * n:nq + 3 * n] = rates
        return out

    def run(self, state: np.ndarray, dt: float, n_steps: int, inputs: Mapping[str, Any] | None = None) -> np.ndarray:
        """Stored states (rows, :attr:`state_size`) of ``n_steps`` steps of ``dt`` [s] from ``state`` at ``t = 0``
        with ``inputs`` held (numbers), initial state excluded; stops after the first block holding a NaN."""
        return self.continue_run(state, self.held_inputs(inputs), dt, n_steps, 0)


def warn_conditionally_stable(model: SpatialModel, scheme: Scheme) -> None:
    """A :class:`~ctmm.guard.StabilityLimitWarning` for a scheme that is not unconditionally stable (the spatial path
    does not check the step against the model's frequencies, as the Python stepper)."""
    limit = scheme.stability_limit()
    if limit < np.inf:
        warnings.warn(f"{model.name}: the DT-TMM scheme {scheme!r} is not unconditionally stable (omega_max dt <= "
                      f"{limit:.4g}); the step is not checked against the model's frequencies on the spatial path",
                      StabilityLimitWarning, stacklevel=3)


def simulate_spatial_scheme_generated(model: SpatialModel, t_final: float, dt: float | None, *,
                                      scheme: Scheme | str = "newmark", x0: Any = None, v0: Any = None,
                                      inputs: Mapping[str, Any] | None = None, store_every: int = 1,
                                      divergence_bound: float | None = None, tolerance: float = 1e-10,
                                      max_iterations: int = 50, cache_dir: str | os.PathLike | None = None,
                                      compiled: CompiledSpatialScheme | None = None) -> SimulationResult:
    """A DT-TMM scheme of a spatial model with its Newton iterations and time loop in generated C.

    Same arguments and result as :func:`ctmm.spatial.implicit.simulate_spatial_implicit` (``scheme_name``
    ``"dt-tmm-generated/<scheme>"``; ``info`` with ``compile_time_s`` and ``newton_iterations``, the total); inputs
    are numbers held over the run.  ``compiled``: a :class:`CompiledSpatialScheme` of ``model`` with this scheme
    and ``store_every`` to reuse.  The divergence bound and the beams' deflection bound are checked on the stored
    states after the run, the steps into the first failing one run again one at a time (:func:`checked_spatial_result`).

    Raises
    ------
    ModelError
        ``dt`` None, bad arguments, Houbolt, a model the generated code refuses.
    ConvergenceError
        A step that does not converge (step, time, residual; the states before it as ``partial_result``).
    SimulationError
        A non-finite or diverging stored state, a beam's deflection beyond its length (``partial_result``).
    """
    scheme = as_scheme(scheme)
    if dt is None:
        raise ModelError(f"dt is required with the DT-TMM scheme {scheme.name!r} (a fixed step [s], > 0), got None")
    n_steps = step_total(t_final, dt)
    dt = float(t_final) / n_steps
    if divergence_bound is not None:
        divergence_bound = validation.positive("divergence_bound", divergence_bound)
    compiled = reused_or_built(CompiledSpatialScheme, compiled, model, scheme, store_every, tolerance=tolerance,
                               max_iterations=max_iterations, cache_dir=cache_dir)
    warn_conditionally_stable(model, scheme)
    start = compiled.initial_state(initial_state(model, x0, v0), inputs)
    times, states, wall, total = generated_rows(compiled, start, dt, n_steps, inputs)
    nq, n = model.n_positions, model.n_velocities
    method = f"dt-tmm-generated/{scheme.name}"
    info = {"dt": dt, "scheme": repr(scheme), "wall_time_s": wall, "compile_time_s": compiled.compile_time_s,
            "newton_iterations": total}

    return checked_spatial_result(compiled, times, states, dt, method, lambda k: state_result(
        model, times[:k], states[:k, :nq + n], method, info), divergence_bound, compiled.held_inputs(inputs))


def generated_rows(compiled: CompiledSpatialScheme, start: np.ndarray, dt: float, n_steps: int,
                   inputs: Mapping[str, Any] | None = None) -> tuple[np.ndarray, np.ndarray, float, int]:
    """``(times, states, wall, total)`` of a run of ``n_steps`` steps of ``dt`` [s] of ``compiled`` from its generated
    state ``start`` with ``inputs`` held: the stored times [s] and generated states with the start first (every
    ``store_every``-th step and the last, up to the first block holding a NaN), the run's wall time [s] and its total
    Newton iterations (-1 when the last stored state is not finite)."""
    began = clock.perf_counter()
    rows = compiled.run(start, dt, n_steps, inputs)
    wall = clock.perf_counter() - began
    every, status = compiled.store_every, compiled.status_index
    steps = np.array([k for k in range(1, n_steps + 1) if k % every == 0 or k == n_steps])[:len(rows)]
    states = np.vstack([start[None], rows])
    total = int(states[-1, status + 2]) if np.isfinite(states[-1, status + 2]) else -1
    return np.concatenate([[0.0], steps * dt]), states, wall, total


def checked_spatial_result(compiled: CompiledSpatialScheme, times: np.ndarray, states: np.ndarray, dt: float,
                           method: str, result: Callable[[int], SimulationResult],
                           divergence_bound: float | None = None, held: np.ndarray | None = None) -> SimulationResult:
    """``result(len(times))`` of the stored generated states ``states`` at ``times`` [s] (step ``dt`` [s]) after the
    checks of a generated spatial scheme run: finite, within ``divergence_bound`` of the start, the beams' deflection
    bound, no failed step.  ``held``: the step's input vector over the run (:meth:`CompiledSpatialScheme.held_inputs`);
    with it, the steps between the last good stored state and the first failing one are run again one at a time
    and checked as the numpy path checks every step, so that the failure is reported at its step (time) as there;
    without it, at the first failing stored state.

    Raises
    ------
    ConvergenceError
        A step that did not converge (step, time, residual; ``result`` of the states before it as
        ``partial_result``).
    SimulationError
        A non-finite or diverging stored state, a beam's deflection beyond its length (``partial_result``).
    """
    from .compiled_control import first_loop_failure, loop_state_failure

    model, status = compiled.model, compiled.status_index
    nq, n = model.n_positions, model.n_velocities
    failed = np.flatnonzero(states[:, status] > 0.0)
    good = len(states) if not failed.size else int(failed[0])
    loops, controller = getattr(compiled, "loops", None), status + len(STATUS)      # loops in the step: their states
    loop_row = first_loop_failure(loops, states[:good], controller) if hasattr(loops, "laws") else good
    trajectory = states[:loop_row, :nq + n]
    check = divergence_check(model, states[0, :nq + n], divergence_bound)
    try:        # the numpy path's guard (bound, finiteness, beams: the first failing row, its message with this label)
        check(times[:loop_row], trajectory, method)
    except SimulationError as exc:
        row = int(np.searchsorted(times, exc.time))
        if held is not None and row > 0:        # the failing interval again, step by step from its last good state
            state = states[row - 1]
            try:
                for k in range(int(round(times[row - 1] / dt)), int(round(times[row] / dt))):
                    state = compiled.continue_run(state, held, dt, 1, k)[-1]
                    check((k + 1) * dt, state[:nq + n], method)
            except SimulationError as earlier:
                earlier.partial_result = result(row)
                raise earlier from None
        exc.partial_result = result(row)
        raise
    if loop_row < good:         # a loop's controller state non-finite: named by loop, at its step with ``held``
        raise loop_state_failure(
            loops, times, states, loop_row, dt,
            None if held is None else (lambda state, k: compiled.continue_run(state, held, dt, 1, k)[-1]),
            lambda pair_times, pair: check(pair_times[-1], pair[-1, :nq + n], method), result, controller)
    if failed.size:
        row = states[failed[0]]
        step = int(row[status])
        raise ConvergenceError(
            f"{model.name}: generated implicit DT-TMM step {step} ({compiled.scheme.name}) at t = {step * dt:.6g} s "
            "did "
            f"not converge: max |change of v_dot| = {row[status + 1]:.3e} after at most {compiled.max_iterations} "
            f"Newton iterations (tolerance {compiled.tolerance:g}); reduce dt", time=step * dt, element=model.name,
            partial_result=result(good))
    return result(len(times))
