"""Implicit DT-TMM schemes on spatial models: every :mod:`ctmm.schemes` scheme in Lie-group form.

Each step is stated in the **local chart at the last configuration** ``q_n``: the unknown
configuration is ``q = q_n (+) delta`` (:func:`ctmm.spatial.lie.retract`: incremental rotation
vectors on ``SO(3)``, body twists on ``SE(3)``, plain increments for angles and displacements), and
the scheme's own nonlinear second-order form (:meth:`ctmm.schemes.Scheme.second_order_step`) is
applied to ``(delta, v, a)`` with the history ``x_n = 0``, ``v_n``, ``a_n`` and, for Houbolt, the
earlier configurations in the same chart, ``x_{n-k} = log(q_n^-1 q_{n-k})``
(:func:`~ctmm.spatial.lie.local_coordinates`):

    delta = delta_hat + b' h^2 a,      v = v_hat + g' h a,      q = q_n (+) delta

with ``a`` the velocity rates ``v_dot`` at the evaluation time (``t_{n+1}``; ``t_n + theta h``
for Wilson-theta).  ``v`` and ``a`` live in the vector space of the velocities (child axes for
rotations), so the velocity relations are the book's schemes unchanged; only positions move on
the group.  For Newmark and generalized-alpha (Arnold & Bruls' form) this is the Lie-group
generalized-alpha method of Brüls & Cardona (2010), second order (Arnold, Brüls & Cardona 2015);
the translational and angle coordinates get exactly the planar schemes.  Backward Euler is
``q_{n+1} = q_n (+) h v_{n+1}``, order 1.  Wilson-theta is a one-step scheme in the same chart and
keeps order 2.  Houbolt differences configurations: its unknowns are the chart rate ``x_dot`` and
acceleration ``x_ddot`` at ``t_{n+1}`` in the chart at ``q_n``, whose body velocity and rate are
``x_dot - 1/2 [x, x_dot]`` and ``x_ddot - 1/2 [x, x_ddot]`` to ``O(h^2)``
(:func:`~ctmm.spatial.lie.bracket`); without that conversion the ``O(h)`` difference of the
accelerations makes Houbolt first order (its positions carry the velocity from step to step).
With it Houbolt is order 2 (measured, ``tests/test_spatial_schemes.py``).

Newton on ``a`` with the tangent of the one articulated sweep in its implicit context: the joint
laws enter linearised, ``tau(a) = tau(a_k) + (tau_q b' h^2 + tau_v g' h)(a - a_k)``, i.e.
``kappa = -(tau_q b' h^2 + tau_v g' h)`` in the pivots ``D = S^T Phi S + kappa`` and
``tau + kappa a_k`` as the law (exact tangents for scalar joints; for quaternion joints the
tangent at zero deflection, ``docs/spatial.md`` §5), so a stiff spring or damper converges about
as fast as a soft one (``tests/test_spatial_schemes.py``: an elastic hinge at
``omega_max dt = 10`` in at most 10 sweeps per step); the
geometric terms (``M(q)``, velocity products) are taken at the iterate (one sweep per iteration),
so convergence is linear with a rate of order ``h |omega|`` and ``h^2 |d h / d q| / m``.  An
iteration that does not converge is a :class:`~ctmm.errors.ConvergenceError` naming the time and
the joint with the largest residual, with the result so far.

Actuator inputs (``input_map``, the loops and controllers of :mod:`ctmm.control.implicit_loops`):
``u = U(t, q, v)`` at every iterate.  For a fixed iterate the sweep is affine in ``u``, so with
``S(a, u)`` the sweep about the acceleration iterate ``a`` and ``P = dS/du dU/da`` the iteration
is ``(I - P) d = S(a, U(a)) - a``, ``a <- a + d``: the inputs' state dependence (real-time loops,
through ``q = q_n (+) (delta_hat + b' h^2 a)``, ``v = v_hat + g' h a``) is in the iteration matrix
exactly as the joint laws are.  ``P`` has the rank of that dependence (one per state-dependent
actuator), so it is never formed: a minimal-residual Krylov solve (:func:`_low_rank_update`) ends
after ``rank + 1`` products, each a directional difference of ``U`` (relative step ``1e-7``) and one
sweep of the changed inputs alone through the iterate's articulated inertias (:func:`input_response`:
no body or joint terms formed again; on rigid trees the inertias eliminated by the iterate's own sweep are
reused and only the changed loads eliminated, :func:`ctmm.articulated.articulated_bias`).  Inputs that do
not depend on the state (delayed loops read from the history, held controller outputs, time
signals) cost one evaluation of ``U`` and no sweep.  The
geometric terms stay at the iterate as above (linear convergence, measured 6-7 sweeps per step at
``h |omega| ~ 0.05``); two stiff coupled loops at ``omega h ~ 1`` converge in at most 10 iterations,
where inputs taken at the previous iterate need 24-37 or diverge (``tests/test_spatial_loop_schemes.py``).
"""
from __future__ import annotations

import dataclasses
import math
import time as clock
import warnings
from typing import Any, Callable, Mapping, NamedTuple

import numpy as np

from .. import validation
from ..articulated import Inward, SingularPivotError, articulated_bias, articulated_inward, articulated_outward
from ..errors import ConvergenceError, ModelError, SimulationError
from ..loop_integration import ProjectionHook
from ..guard import StabilityLimitWarning
from ..low_rank import low_rank_solve
from ..ops import NUMPY
from ..planar.actuated_newton import InputError
from ..planar.integrate import step_total
from ..results import SimulationResult
from ..schemes import History, Houbolt, Scheme, as_scheme
from .beam_terms import beam_load_vector
from .body_forms import SpatialScene
from .dynamics import accelerations
from .integrate import divergence_check, initial_state, state_result
from .lie import bracket, local_coordinates, retract
from .model import SpatialModel, input_values

__all__ = ["simulate_spatial_implicit", "implicit_rates", "implicit_terms", "input_response", "ImplicitTerms",
           "InputMap", "StepCallback"]

#: ``input_map(t, q, v) -> SpatialInputs | None``: actuator values at a state (:mod:`ctmm.spatial.ports`).
InputMap = Callable[[float, np.ndarray, np.ndarray], Any]
#: ``after_step(step, t, q, v) -> bool``: called after every accepted step; true when the inputs jumped at ``t``.
StepCallback = Callable[[int, float, np.ndarray, np.ndarray], bool]


class ImplicitTerms(NamedTuple):
    """The body and joint terms of one iterate in the implicit context (joint laws linearised about it)."""

    bodies: list
    joints: list
    kappa: list
    states: list
    q: Any = None        # the configuration (nq,) of the iterate (beams' modal coordinates in input_response)
    inward: Inward | None = None    # the elimination of these terms (input_response sweeps new loads about it)


def implicit_terms(scene: SpatialScene, q: np.ndarray, v: np.ndarray, t: float, inputs: Mapping[str, Any] | None,
                   position_weight: float, velocity_weight: float, iterate: np.ndarray,
                   wrenches: Mapping[int, Any] | None = None) -> ImplicitTerms:
    """The terms of the implicit context at one iterate (:func:`implicit_rates` sweeps them).

    Parameters
    ----------
    scene : SpatialScene
    q, v : (nq,), (nv,) arrays
        The configuration and velocities at the iterate.
    t : float
        Evaluation time [s].
    inputs : mapping, optional
        Actuator inputs (as :func:`ctmm.spatial.dynamics.solve`).
    position_weight, velocity_weight : float
        ``b' h^2`` [s^2] and ``g' h`` [s] of the scheme.
    iterate : (nv,) array
        The acceleration iterate ``a_k`` [m/s^2, rad/s^2].
    wrenches : mapping, optional
        Extra applied loads by body index (the body actuators of :mod:`ctmm.spatial.ports`, as
        :meth:`ctmm.spatial.body_forms.SpatialScene.terms`).
    """
    model = scene.model
    bodies, joints, states = scene.terms(NUMPY, q[None], v[None], t, scene.numpy_inputs(inputs, t, 1), wrenches)
    kappa, implicit = [], []
    for joint, terms, layout in zip(model.joints, joints, model.layout):
        if terms.tau is None or terms.free == 0 or terms.prescribed is not None or terms.tau_q is None:
            kappa.append(None)
            implicit.append(terms)
            continue
        tangent = (terms.tau_q * position_weight + terms.tau_v * velocity_weight) * -1.0
        column = iterate[layout.velocity][None, :, None]
        kappa.append(tangent)
        implicit.append(dataclasses.replace(terms, tau=terms.tau + tangent @ column))
    for j, layout in enumerate(model.modal):          # beams: modal stiffness and damping in the tangent
        if layout is not None:
            tangent = model.bodies[j].modal_tangent(position_weight, velocity_weight)
            M, h = bodies[j].M.copy(), bodies[j].h.copy()
            M[..., 6:, 6:] += tangent
            h[..., 6:, :] -= tangent @ iterate[layout.velocity][:, None]
            bodies[j] = dataclasses.replace(bodies[j], M=M, h=h)
    return ImplicitTerms(bodies, implicit, kappa, states, np.asarray(q))


# r x f of 3-vectors as np.cross forms it (the same products and differences, without its axis handling)
_NEXT, _LAST = np.array([1, 2, 0]), np.array([2, 0, 1])
_ZERO_COLUMN = np.zeros((1, 6, 1))
_ZERO_COLUMN.flags.writeable = False           # shared by the points of input_response (read only)


def _swept(scene: SpatialScene, bodies: list, joints: list, kappa: list, inward: Inward | None = None
           ) -> tuple[np.ndarray, Inward]:
    """``v_dot`` (nv,) of the one articulated sweep of the terms and its elimination; with ``inward`` (the
    elimination of terms with the same inertias, rigid bodies) only the new biases are eliminated
    (:func:`ctmm.articulated.articulated_bias`)."""
    if inward is None:
        inward = articulated_inward(NUMPY, scene.tree, bodies, joints, kappa)
    else:
        inward = articulated_bias(NUMPY, scene.tree, bodies, joints, inward)
    # the rates read the accelerations and relative accelerations only: no joint wrenches formed
    solution = articulated_outward(NUMPY, scene.tree, bodies, joints, inward, forces=False)
    parts = [np.asarray(a)[0, :, 0] for a in scene.velocity_rates(solution)]
    return (np.concatenate(parts) if parts else np.zeros(0)), inward


def implicit_rates(scene: SpatialScene, q: np.ndarray, v: np.ndarray, t: float, inputs: Mapping[str, Any] | None,
                   position_weight: float, velocity_weight: float, iterate: np.ndarray,
                   wrenches: Mapping[int, Any] | None = None) -> np.ndarray:
    """One sweep of the implicit context: ``v_dot`` (nv,) with the joint laws linearised about ``iterate``
    (arguments as :func:`implicit_terms`)."""
    terms = implicit_terms(scene, q, v, t, inputs, position_weight, velocity_weight, iterate, wrenches)
    return _swept(scene, terms.bodies, terms.joints, terms.kappa)[0]


def input_response(scene: SpatialScene, terms: ImplicitTerms, before: Any, after: Any) -> np.ndarray:
    """The change of the implicit sweep's ``v_dot`` (nv,) when the actuator values go from ``before`` to
    ``after`` (:class:`~ctmm.spatial.ports.SpatialInputs` or ``None``) at the same iterate.

    The sweep is affine in the actuator values at a fixed iterate, so the change is the sweep of the
    same articulated inertias (``M``, ``S``, ``kappa``) with only the changed joint forces and body
    loads (``h = -[f ; m + r x f]`` about the inboard point) and no velocity or gravity terms: no
    body or joint terms are formed again.  When ``terms`` carry their elimination (``terms.inward``) and
    every body is rigid, the articulated inertias are not formed again either: only the changed loads are
    eliminated about them (:func:`ctmm.articulated.articulated_bias`; the same numbers as the full sweep).
    """
    model = scene.model
    reuse = terms.inward is not None and not any(layout is not None for layout in model.modal)
    bodies = []
    for j, (body, state) in enumerate(zip(terms.bodies, terms.states)):
        rotation = np.asarray(state.rotation)[0]
        offset = (np.asarray(state.origin) - np.asarray(state.inboard)).reshape(3)
        changed = []                                 # (point, signed wrench (6,) world axes)
        for sign, values in ((1.0, after), (-1.0, before)):
            for entry in ([] if values is None else values.wrenches.get(j, [])):
                w = sign * np.asarray(entry[1], dtype=float).reshape(6)
                if len(entry) > 2 and entry[2] == "body":
                    w = np.concatenate([rotation @ w[:3], rotation @ w[3:]])
                changed.append((np.asarray(entry[0], float), w))
        layout = model.modal[j]
        if layout is not None:                       # a beam: its modal rows too (exact virtual work)
            h = beam_load_vector(model.bodies[j], rotation, offset, terms.q[layout.position], changed
                                 ).reshape(1, -1, 1)
        else:
            h = np.zeros((1, 6, 1))
            for point, w in changed:
                arm = rotation @ point + offset
                h[0, :3, 0] -= w[:3]
                h[0, 3:, 0] -= w[3:] + (arm[_NEXT] * w[_LAST] - arm[_LAST] * w[_NEXT])     # r x f
        bodies.append(dataclasses.replace(body, h=h, c=dict.fromkeys(body.c, None if reuse else _ZERO_COLUMN)))
    joints = []
    for joint, term in zip(model.joints, terms.joints):
        change = None
        if joint.inputs:
            name, k = joint.inputs[0], joint.velocity_count
            change = sum(sign * np.asarray(values.joint.get(name, np.zeros(k)), dtype=float).reshape(k)
                         for sign, values in ((1.0, after), (-1.0, before)) if values is not None)
        tau = None if term.tau is None else np.zeros(np.shape(term.tau))
        if change is not None and tau is not None:
            tau = tau + np.reshape(change, np.shape(tau))
        prescribed = None if term.prescribed is None else np.zeros(np.shape(term.prescribed))
        joints.append(dataclasses.replace(term, c=None, tau=tau, prescribed=prescribed))
    return _swept(scene, bodies, joints, terms.kappa, terms.inward if reuse else None)[0]


def _joint_of(model: SpatialModel, index: int) -> str:
    for joint, layout in zip(model.joints, model.layout):
        if layout.velocity.start <= index < layout.velocity.stop:
            return joint.name
    return model.name


def _low_rank_update(residual: np.ndarray, product: Callable[[np.ndarray], np.ndarray], limit: int) -> np.ndarray:
    """``d`` with ``(I - P) d = residual``, ``P`` of low rank given by ``product(direction)``
    (:func:`ctmm.low_rank.low_rank_solve`: ``rank P + 1`` directions, at most ``limit``)."""
    coefficients, directions = low_rank_solve(residual, product, limit)
    if not directions:
        return np.zeros_like(residual)
    return np.column_stack(directions) @ coefficients


def _check_inputs(value: Any, t: float) -> Any:
    """The value of an ``input_map``: ``None`` or actuator values with ``joint`` and ``wrenches``."""
    if value is not None and not (hasattr(value, "joint") and hasattr(value, "wrenches")):
        raise SimulationError(f"input_map(t, q, v) must return ctmm.spatial.ports.SpatialInputs or None, got "
                              f"{type(value).__name__} at t = {t:.6g} s", time=float(t), element="inputs")
    return value


def _same_inputs(a: Any, b: Any) -> bool:
    if a is None or b is None:
        return a is b
    return (a.joint.keys() == b.joint.keys() and all(np.array_equal(a.joint[k], b.joint[k]) for k in a.joint)
            and a.wrenches.keys() == b.wrenches.keys()
            and all(len(a.wrenches[k]) == len(b.wrenches[k])
                    and all(len(ea) == len(eb) and tuple(ea[2:]) == tuple(eb[2:]) and np.array_equal(ea[0], eb[0])
                            and np.array_equal(ea[1], eb[1])
                            for ea, eb in zip(a.wrenches[k], b.wrenches[k])) for k in a.wrenches))


def simulate_spatial_implicit(model: SpatialModel, t_final: float, dt: float, *, scheme: Scheme | str = "newmark",
                              x0: Any = None, v0: Any = None, inputs: Mapping[str, Any] | None = None,
                              tolerance: float = 1e-10, max_iterations: int = 50, store_every: int = 1,
                              divergence_bound: float | None = None, input_map: InputMap | None = None,
                              after_step: StepCallback | None = None,
                              project: ProjectionHook | None = None) -> SimulationResult:
    """Implicit DT-TMM run of a spatial model with any scheme (module docstring).

    Parameters
    ----------
    model : SpatialModel
    t_final : float
        End time [s] (start at 0), a whole multiple of ``dt``.
    dt : float
        Step [s].
    scheme : Scheme or str
        ``"newmark"`` (average acceleration, default), ``"generalized_alpha"``, ``"wilson_theta"``,
        ``"houbolt"``, ``"forward_euler"`` (the book's name; backward differences, order 1) or an instance.
    x0, v0 : array or mapping, optional
        Initial coordinates and velocities (as :func:`ctmm.spatial.integrate.simulate_spatial`).
    inputs : mapping, optional
        Actuator inputs ``{"<joint>.torque" | ".force" | ".wrench": value or f(t)}``, evaluated at
        each step's evaluation time.
    tolerance : float
        Iterations stop when ``max |a_(k+1) - a_k| <= tolerance (1 + max |a|)``.
    max_iterations : int
        Sweeps allowed per step.
    store_every : int
        Keep every ``store_every``-th step (and the last).
    divergence_bound : float, optional
        Largest allowed distance of an entry of ``q`` or ``v`` from its initial value
        (:func:`ctmm.spatial.integrate.divergence_check`).
    input_map : callable, optional
        ``input_map(t, q, v) -> SpatialInputs | None``: actuator values that may depend on the state
        (:meth:`ctmm.spatial.ports.SpatialPorts.inputs`; real-time feedback, delayed loops, held
        controller outputs), evaluated at the evaluation time and at every iterate, a function of
        its arguments only; not together with ``inputs``.  Their state dependence is in the
        iteration matrix (module docstring, "Actuator inputs").
    after_step : callable, optional
        ``after_step(step, t, q, v) -> bool`` after every accepted step (``step`` = 1, 2, ...,
        ``t = step dt``); a true value says the inputs jumped at ``t`` (new held controller
        outputs): the next step starts from the acceleration solved again with them.
    project : callable, optional
        ``project(t, q, v) -> (q, v)``, applied to every accepted step before the divergence check and
        ``after_step`` (the cut joints of a spatial kinematic loop model:
        :class:`ctmm.loop_integration.StepProjection`); the next step starts from the projected state (the
        accelerations are kept).  A :class:`~ctmm.errors.SimulationError` it raises ends the run with the
        ``partial_result``.

    Returns
    -------
    SimulationResult
        Signals as :func:`ctmm.spatial.integrate.spatial_signals` (unit quaternions); ``info`` with
        ``dt``, ``scheme``, ``iterations`` (per step), ``wall_time_s``, ``n_evaluations`` (sweeps).

    Raises
    ------
    ModelError
        Bad arguments or an unknown scheme.
    StabilityLimitWarning
        (a warning) A scheme that is not unconditionally stable (Newmark with ``gamma < 1/2`` or
        ``2 beta < gamma``, Wilson-theta with ``theta < 1.37``): the step is not checked yet.
    ConvergenceError
        A step whose iterations do not converge (time, joint, residual; ``partial_result``).
    SimulationError
        A non-finite or diverging state (time, model, ``partial_result``); ``input_map`` that raises
        or returns something else than actuator values (:class:`~ctmm.planar.actuated_newton.InputError`,
        naming the time and the loop or ``"inputs"``).
    """
    scheme = as_scheme(scheme)
    if dt is None:
        raise ModelError(f"dt is required with the DT-TMM scheme {scheme.name!r} (a fixed step [s], > 0), got None")
    n_steps = step_total(t_final, dt)
    dt = float(t_final) / n_steps
    tolerance = validation.positive("tolerance", tolerance)
    max_iterations = validation.integer("max_iterations", max_iterations, minimum=1)
    store_every = validation.integer("store_every", store_every, minimum=1)
    if divergence_bound is not None:
        divergence_bound = validation.positive("divergence_bound", divergence_bound)
    if inputs is not None and not isinstance(inputs, Mapping):
        raise ModelError(f"inputs must be a mapping {{input name: number or f(t)}}, got {inputs!r}")
    if input_map is not None and (inputs is not None or not callable(input_map)):
        raise ModelError(f"input_map must be a callable input_map(t, q, v) -> SpatialInputs | None, without inputs, "
                         f"got input_map={input_map!r}, inputs={inputs!r}")
    if after_step is not None and not callable(after_step):
        raise ModelError(f"after_step must be a callable after_step(step, t, q, v) -> bool, got {after_step!r}")
    if project is not None and not callable(project):
        raise ModelError(f"project must be a callable project(t, q, v) -> (q, v), got {project!r}")
    input_values(model, inputs, 0.0, 1)                      # names and values checked before the run
    limit = scheme.stability_limit()
    if limit < math.inf:
        what = "amplifies every undamped mode at every step" if limit == 0.0 else \
            f"is stable only for omega_max dt <= {limit:.4g}"
        warnings.warn(f"{model.name}: the DT-TMM scheme {scheme!r} {what}; the spatial path does not check the "
                      "step against the model's frequencies yet (docs/spatial.md §6a): use an unconditionally "
                      "stable scheme (Newmark(0.25, 0.5), generalized_alpha, houbolt, WilsonTheta(theta >= 1.37))",
                      StabilityLimitWarning, stacklevel=3)
    if model.n_velocities == 0:
        raise ModelError(f"model {model.name!r} has no coordinates (every joint is welded or driven): no DT-TMM "
                         "step to take")
    state = initial_state(model, x0, v0)
    q, v = model.normalized(state[:model.n_positions]), state[model.n_positions:]
    scene = SpatialScene(model)
    method = f"dt-tmm/{scheme.name}"
    info: dict = {"dt": dt, "scheme": repr(scheme)}
    start = clock.perf_counter()
    def applied(t: float, q_at: np.ndarray, v_at: np.ndarray) -> Any:
        if input_map is None:
            return None
        try:
            return _check_inputs(input_map(t, q_at.copy(), v_at.copy()), t)
        except SimulationError as exc:
            raise InputError(str(exc), time=float(t), element=getattr(exc, "element", None) or "inputs",
                             partial_result=partial()) from exc

    def solved(t: float, q_at: np.ndarray, v_at: np.ndarray) -> np.ndarray:
        u = applied(t, q_at, v_at)
        if u is None:
            return accelerations(model, q_at, v_at, t, inputs)
        return accelerations(model, q_at, v_at, t, u.joint, u.wrenches)

    times, states = [0.0], [np.concatenate([q, v])]
    try:
        rates = solved(0.0, q, v)
    except SimulationError as exc:                 # the start's accelerations: the partial result is the start
        if exc.partial_result is None:
            exc.partial_result = state_result(model, times, states, method, dict(info, n_evaluations=0))
        raise
    algorithmic, earlier = rates.copy(), [q.copy(), q.copy()]
    since = 0                                   # steps since the start or the last jump of held inputs
    zero = np.zeros(model.n_velocities)
    check = divergence_check(model, states[0], divergence_bound)
    iterations = np.zeros(n_steps, dtype=int)
    sweeps = 1

    def partial() -> SimulationResult:
        return state_result(model, times, states, method, dict(info, iterations=iterations.copy(), n_evaluations=sweeps,
                                                          wall_time_s=clock.perf_counter() - start))

    for step in range(n_steps):
        t1 = (step + 1) * dt
        x_old = [local_coordinates(model, q, earlier[0]), local_coordinates(model, q, earlier[1])] \
            if since >= 2 else [zero.copy(), zero.copy()]
        history = History(zero.copy(), v.copy(), algorithmic.copy(), x_old, since, rates.copy())
        plan = scheme.second_order_step(history, dt)
        t_eval = (step + plan.time_fraction) * dt
        a = rates.copy()
        residual = np.inf
        chart = isinstance(scheme, Houbolt) and since >= 2     # velocities are differences of chart positions

        def configuration(acceleration: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            """Increment, configuration and body velocity of the acceleration iterate."""
            delta = plan.q_predictor + plan.position_weight * acceleration
            rate = plan.v_predictor + plan.velocity_weight * acceleration
            if chart:
                rate = rate - 0.5 * bracket(model, delta, rate)
            return delta, retract(model, q, delta), rate

        def linearised(acceleration: np.ndarray, delta: np.ndarray, q_at: np.ndarray, v_at: np.ndarray,
                       u: Any) -> ImplicitTerms:
            """The implicit terms about ``acceleration`` with the actuator values ``u``."""
            joint_inputs, wrenches = (inputs, None) if u is None else (u.joint, u.wrenches)
            iterate = acceleration - 0.5 * bracket(model, delta, acceleration) if chart else acceleration
            return implicit_terms(scene, q_at, v_at, t_eval, joint_inputs, plan.position_weight,
                                  plan.velocity_weight, iterate, wrenches)

        def chart_rates(body_rates: np.ndarray, delta: np.ndarray) -> np.ndarray:
            """Body rates as chart rates (Houbolt after its start-up; linear in ``body_rates``)."""
            return body_rates + 0.5 * bracket(model, delta, body_rates) if chart else body_rates

        def input_product(a_k: np.ndarray, delta: np.ndarray, q_at: np.ndarray, v_at: np.ndarray, u0: Any,
                          terms: ImplicitTerms) -> Callable[[np.ndarray], np.ndarray]:
            """``P d``: the change of the sweep about ``a_k`` per unit change of the acceleration along
            ``d`` through the actuator values alone (a directional difference of ``input_map``, swept by
            :func:`input_response`)."""
            scale = 1e-7 * max(1.0, float(np.abs(q_at).max(initial=0.0)), float(np.abs(v_at).max(initial=0.0))) \
                / max(plan.position_weight, plan.velocity_weight)

            def product(direction: np.ndarray) -> np.ndarray:
                nonlocal sweeps
                largest = float(np.abs(direction).max())
                if not largest > 0.0 or not np.isfinite(largest):
                    return np.zeros_like(direction)
                eps = scale / largest
                _, q_e, v_e = configuration(a_k + eps * direction)
                u = applied(t_eval, q_e, v_e)
                if _same_inputs(u, u0):
                    return np.zeros_like(direction)
                sweeps += 1
                return chart_rates(input_response(scene, terms, u0, u), delta) / eps
            return product

        for iteration in range(1, max_iterations + 1):
            try:
                delta, q_at, v_at = configuration(a)
                u0 = applied(t_eval, q_at, v_at)
                terms = linearised(a, delta, q_at, v_at, u0)
                body_rates, inward = _swept(scene, terms.bodies, terms.joints, terms.kappa)
                swept = chart_rates(body_rates, delta)
                a_new = swept if input_map is None else \
                    a + _low_rank_update(swept - a, input_product(a, delta, q_at, v_at, u0, terms._replace(inward=inward)),
                                         model.n_velocities)
            except InputError:
                raise
            except (SimulationError, np.linalg.LinAlgError) as exc:
                where = model.joints[exc.body].name if isinstance(exc, SingularPivotError) else model.name
                raise ConvergenceError(f"{model.name}: implicit DT-TMM step {step + 1} ({scheme.name}) at t = {t1:.6g} "
                                       f"s failed in iteration {iteration}: {exc}", time=t1, element=where,
                                       partial_result=partial()) from exc
            sweeps += 1
            change = np.abs(a_new - a)
            residual = float(change.max())
            a = a_new
            if not np.isfinite(residual):
                break
            if residual <= tolerance * (1.0 + float(np.abs(a).max())):
                iterations[step] = iteration
                break
        if iterations[step] == 0:
            worst = int(np.nanargmax(change)) if np.any(np.isfinite(change)) else 0
            joint = _joint_of(model, worst)
            raise ConvergenceError(
                f"{model.name}: implicit DT-TMM step {step + 1} ({scheme.name}) at t = {t1:.6g} s did not converge: "
                f"max |change of v_dot| = {residual:.3e} after {max_iterations} sweeps (tolerance {tolerance:g}), "
                f"largest at joint {joint!r} ({model.velocities[worst]}); reduce dt", time=t1, element=joint,
                partial_result=partial())
        new = scheme.second_order_update(history, a, dt, plan)
        earlier, since = [q, earlier[0]], since + 1
        q, v = retract(model, q, new.x), (new.v - 0.5 * bracket(model, new.x, new.v) if chart else new.v)
        if project is not None:
            try:
                q, v = (np.array(part, dtype=float) for part in project(t1, q.copy(), v.copy()))
            except SimulationError as exc:
                if exc.partial_result is None:
                    exc.partial_result = partial()
                raise
        algorithmic = new.a
        rates = new.equation_acceleration if new.equation_acceleration is not None else new.a
        x = np.concatenate([q, v])
        check(t1, x, method, partial)
        if after_step is not None and after_step(step + 1, t1, q.copy(), v.copy()):
            rates = solved(t1, q, v)                  # new held inputs: restart from the acceleration with them
            algorithmic = rates.copy()
            sweeps += 1
            if scheme.restart_on_input_jump:      # Houbolt starts up again (Scheme.restart)
                since = 0
        if (step + 1) % store_every == 0 or step + 1 == n_steps:
            times.append(t1)
            states.append(x)
    info.update({"iterations": iterations, "n_evaluations": sweeps, "wall_time_s": clock.perf_counter() - start})
    return state_result(model, times, states, method, info)
