"""Linearisation of spatial models about an operating point: the linear spatial MSTMM (issue 14).

The path of :func:`ctmm.linearize` for a :class:`~ctmm.spatial.model.SpatialModel`
(``docs/spatial.md`` §9).  States are **tangent coordinates** about the operating point ``q0``:

* revolute, prismatic, universal joints: the deviation of their angles / displacements;
* spherical joints: the rotation vector ``r`` (3, child axes) with ``quat = quat0 (x) exp(r)``
  (right perturbation: ``r_dot = omega`` to first order, ``omega`` in child axes as the velocities);
* free and elastic joints: ``[p ; r]`` with ``t = t0 + R0 p`` (``p`` in the child axes at ``q0``,
  ``p_dot = v_o`` to first order) and the rotation vector ``r`` as above;

followed by the velocities ``v`` (``model.velocities``, their deviations).  Named
``"<joint>.angle"``, ``"<joint>.rx"``, ``"<joint>.x"``, ... (:func:`tangent_names`) and
``model.velocities``.  ``x' = A x + B u``, ``y = C x`` with

* ``A = [[0, I], [df/dr, df/dv]]``, ``f = v_dot(q0 (+) r, v, u)`` by complex step through the batched
  terms of the one articulated sweep (:class:`ctmm.spatial.body_forms.SpatialScene`, ``d = 6``), exact to
  round-off, cross-checked along one direction by a Richardson difference of
  :func:`ctmm.spatial.accelerations` (``OperatingPoint.jacobian_error``, refused above
  :data:`~ctmm.planar_linearization.JACOBIAN_TOLERANCE` at each of the steps
  :data:`~ctmm.planar_linearization.CROSS_CHECK_STEPS`, the planar tangent's: the
  difference's truncation error falls like ``h^4`` where the accelerations are smooth, a kink does not);
* ``B = [[0], [df/du]]`` -- ``f`` is affine in the actuator inputs, a symmetric unit difference is
  exact; one input per component (:func:`input_names`: ``"yaw.torque"``, ``"ball.torque_x"``,
  ``"base.wrench_fx"``, ... in the joint's own axes, child axes for spherical and free joints);
* ``B`` columns of actuator ports (:mod:`ctmm.spatial.ports`: ``"link.tip.force_y"``, ``"base.moment_z"``) by the
  same exact differences through :meth:`ctmm.spatial.ports.SpatialPorts.accelerations`;
* ``C``: rows of sensor ports by complex step through
  :func:`ctmm.spatial_sensors_complex.complex_sensor_values` (exact to round-off; a name that is both a port and
  a tangent coordinate is the port), and the selection of tangent coordinates that are not ports (``D = 0``).

The loops of a ``ControlledModel`` on a spatial plant are closed around this linearisation by
:func:`ctmm.controlled_linearization.close_model_loops` (real-time loops in ``A``, delayed loops beside it), the
function the planar path uses.

The operating point is the static equilibrium when none is given: the root of the sweep's
accelerations ``f(q0 (+) r, 0) = 0`` from the neutral configuration by pseudo-transient continuation
(implicit Euler steps of the overdamped fall ``r' = f``, which lowers the potential energy, with a
step ``dt`` grown as ``|f|`` falls until they are Newton steps; minimum-norm solves, so neutral
directions such as a free yaw stay where they are).  The default is statically stable
(``static_equilibrium(..., stable=True)``: pushed off an unstable one along its most unstable direction,
:func:`unstable_directions`, or refused naming them).  While unstable directions remain, the fall's steps
(``dt <= 0.5 / lambda``) are judged by the potential energy at rest (:mod:`ctmm.spatial_fall`: taken unless it
rises beyond its round-off; refused, naming the steps, the largest acceleration and the energy, when it stalls
or runs away).  The search's answer is certified independently of that rule (residual bound, stiffness
eigenvalues).  A free joint under gravity has no equilibrium: refused.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .errors import ModelError, UnknownNameError, unknown_name
from .controlled_linearization import close_model_loops, loop_ports
from .linearized import LinearizedSystem, OperatingPoint
from .ops import NUMPY
from .planar.equilibrium import STABLE_RESTARTS, describe_directions, negative_stiffness, restart_until_stable
from .planar_linearization import CROSS_CHECK_STEPS, EQUILIBRIUM_TOLERANCE, JACOBIAN_TOLERANCE, TIME_PROBES, jacobian
from .saturation import refuse_saturation
from .spatial_fall import EnergyFall
from .spatial_sensors_complex import complex_sensor_values

__all__ = ["linearize_spatial", "tangent_names", "input_names", "retract", "static_equilibrium",
           "operating_point", "tangent", "input_matrix", "output_matrix", "NEWTON_ITERATIONS",
           "unstable_directions", "STABLE_RESTARTS"]

NEWTON_ITERATIONS = 200
"""Largest number of (pseudo-transient Newton) steps of :func:`static_equilibrium` at points without unstable
directions (the Newton phase, and every step of an uncapped search).  The capped fall through unstable
directions (``stable=True``) is not counted against it: its steps are accepted by the decrease of the potential
energy (:mod:`ctmm.spatial_fall`); only a model whose static forces have no potential here (point loads, springs
without one) keeps a budget of ``NEWTON_ITERATIONS + 5 n_v`` fall steps."""
_CONFIGURATION_SENSORS = frozenset({"q", "modal", "angles", "rotation", "point"})
"""Kinds of :class:`ctmm.spatial.ports.SpatialPorts` sensors whose values depend on ``q`` alone."""
_COMPONENTS = {3: ("x", "y", "z"), 6: ("fx", "fy", "fz", "mx", "my", "mz"), 2: ("1", "2")}


def _require_model(model: Any, function: str) -> None:
    """Refuse anything that is not a spatial model (a clear ``ModelError`` instead of an ``AttributeError``)."""
    if not all(hasattr(model, name) for name in ("joints", "bodies", "n_bodies", "name")):
        raise ModelError(f"{function}: model must be a ctmm.spatial.SpatialModel, got {type(model).__name__} "
                         f"{model!r:.80}")


def tangent_names(model: Any) -> tuple[str, ...]:
    """Names of the tangent coordinates (one per velocity, module docstring)."""
    _require_model(model, "tangent_names")
    names = []
    for joint in model.joints:
        if joint.driven or joint.kind == "weld":
            continue
        if joint.kind == "spherical":
            parts: tuple[str, ...] = ("rx", "ry", "rz")
        elif joint.kind in ("free", "elastic6"):
            parts = ("x", "y", "z", "rx", "ry", "rz")
        elif joint.kind == "universal":
            parts = ("angle1", "angle2")
        else:
            parts = ("angle",) if joint.kind == "revolute" else ("position",)
        names += [f"{joint.name}.{p}" for p in parts]
    names += [f"{body.name}.{c}" for body, layout in zip(model.bodies, model.modal) if layout is not None
              for c in body.coordinate_suffixes]                 # beams' modal coordinates
    return tuple(names)


def input_names(model: Any) -> tuple[str, ...]:
    """One name per actuator input component: the input's own name for a scalar input, else
    ``"<input>_<component>"`` (``x, y, z``; ``1, 2`` for universal joints; ``fx ... mz`` for wrenches)."""
    _require_model(model, "input_names")
    return tuple(name for name, _, _ in _input_components(model))


def _input_components(model: Any) -> list[tuple[str, str, int]]:
    out = []
    for joint in model.joints:
        for name in joint.inputs:
            k = joint.velocity_count
            if k == 1:
                out.append((name, name, 0))
            else:
                out += [(f"{name}_{c}", name, i) for i, c in enumerate(_COMPONENTS[k])]
    return out


# ------------------------------------------------------------------------------ rotations
def _quaternion_exp(r: np.ndarray) -> np.ndarray:
    """``exp(r)`` as a unit quaternion ``(..., 4)`` scalar first; analytic (complex step safe)."""
    theta2 = np.sum(r * r, axis=-1)
    small = np.abs(theta2) < 1e-8
    theta = np.sqrt(np.where(small, 1.0, theta2).astype(np.result_type(r, complex)))
    if not np.iscomplexobj(r):
        theta = theta.real
    w = np.where(small, 1.0 - theta2 / 8.0 + theta2 ** 2 / 384.0, np.cos(theta / 2.0))
    s = np.where(small, 0.5 - theta2 / 48.0 + theta2 ** 2 / 3840.0, np.sin(theta / 2.0) / theta)
    return np.concatenate([w[..., None], s[..., None] * r], axis=-1)


def _quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    wa, va = a[..., :1], a[..., 1:]
    wb, vb = b[..., :1], b[..., 1:]
    return np.concatenate([wa * wb - np.sum(va * vb, axis=-1, keepdims=True),
                           wa * vb + wb * va + np.cross(va, vb)], axis=-1)


def retract(model: Any, q0: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """``q0 (+) delta`` (module docstring) for a batch ``delta (B, nv)`` (complex allowed) -> ``(B, nq)``."""
    _require_model(model, "retract")
    from .spatial.model import rotation_matrix

    delta = np.atleast_2d(delta)
    q = np.repeat(np.asarray(q0)[None, :], delta.shape[0], axis=0).astype(np.result_type(q0, delta, float))
    for joint, layout in zip(model.joints, model.layout):
        qs, d = layout.position, delta[:, layout.velocity]
        if joint.driven or joint.kind == "weld":
            continue
        if joint.kind == "spherical":
            q[:, qs] = _quaternion_product(q[:, qs], _quaternion_exp(d))
        elif joint.kind in ("free", "elastic6"):
            start = qs.start
            R0 = rotation_matrix(np.asarray(q0, dtype=float)[start + 3:start + 7])
            q[:, start:start + 3] = q[:, start:start + 3] + d[:, :3] @ R0.T
            q[:, start + 3:start + 7] = _quaternion_product(q[:, start + 3:start + 7], _quaternion_exp(d[:, 3:]))
        else:
            q[:, qs] = q[:, qs] + d
    for layout in model.modal:                      # beams' modal coordinates: plain increments
        if layout is not None:
            q[:, layout.position] = q[:, layout.position] + delta[:, layout.velocity]
    return q


def _rates(model: Any, q: np.ndarray, v: np.ndarray, t: float, inputs: Mapping[str, Any] | None = None
           ) -> np.ndarray:
    """``v_dot (B, nv)`` of a batch through the one sweep, complex states allowed (no float check)."""
    from .spatial.body_forms import SpatialScene

    scene = SpatialScene(model)
    batch = max(q.shape[0], v.shape[0])
    solution = scene.sweep(NUMPY, q, v, t, scene.numpy_inputs(inputs, t, batch))
    parts = [np.broadcast_to(np.asarray(a), (batch,) + np.asarray(a).shape[1:])[:, :, 0]
             for a in scene.velocity_rates(solution)]
    return np.concatenate(parts, axis=1) if parts else np.zeros((batch, 0))


def _position_jacobian(model: Any, q: np.ndarray, v: np.ndarray, t: float, step: float = 1e-30,
                       velocities: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """``df/dr, df/dv`` (nv, nv) at ``(q, v)`` by complex step, one batched sweep over ``2 nv`` states
    (``velocities=False``: ``df/dr`` alone, over ``nv`` states, and ``None`` for ``df/dv``)."""
    n = model.n_velocities
    if n == 0:
        return np.zeros((0, 0)), (np.zeros((0, 0)) if velocities else None)
    perturb = 1j * step * np.eye(2 * n if velocities else n, 2 * n)
    qs = retract(model, q, perturb[:, :n])
    vs = v[None, :] + perturb[:, n:]
    J = _rates(model, qs, vs, t).imag / step          # row k: d f / d x_k
    return J[:n].T, (J[n:].T if velocities else None)


# ---------------------------------------------------------------------------- equilibrium
def _scale(model: Any) -> float:
    return EQUILIBRIUM_TOLERANCE * (1.0 + float(np.max(np.abs(model.gravity))))


def static_equilibrium(model: Any, t: float = 0.0, start: Any = None, *, stable: bool = False) -> np.ndarray:
    """A static equilibrium ``q0`` (unit quaternions) of a spatial model reached from ``start`` (default
    ``model.neutral()``) by pseudo-transient continuation on the sweep's accelerations at rest
    (module docstring).

    Parameters
    ----------
    model : SpatialModel
    t : float
        Time [s] of the loads.
    start : array_like, optional
        Coordinates [rad, m, quaternions] where the search starts; default ``model.neutral()``.
    stable : bool
        Find a statically stable equilibrium (no direction of negative stiffness,
        :func:`unstable_directions`): from an unstable one (e.g. a pendulum whose neutral configuration
        is upright) the search is pushed along its most unstable direction and continued with its time
        step kept below the inverse growth rate of the unstable directions it meets, so it falls to a
        stable one (:data:`STABLE_RESTARTS` pushes).  The default (``False``) returns the equilibrium reached.

    Raises
    ------
    ModelError
        A ``start`` that is not one configuration (sizes, finite values, non-zero quaternions) or a
        non-finite ``t``; a free joint under gravity; no convergence (no equilibrium near ``start``, or loads that
        keep a body moving); with ``stable=True`` an equilibrium reached that is still unstable (its
        unstable directions named).
    """
    _require_model(model, "static_equilibrium")
    validation.flag("stable", stable)
    t = validation.finite("t", t)
    if start is not None:                      # one configuration: sizes, finite values, non-zero quaternions
        try:
            rows = model.check_state(start, np.zeros(model.n_velocities))[0]
        except ModelError as exc:
            raise ModelError(f"static_equilibrium: start: {exc}") from None
        if rows.shape[0] != 1:
            raise ModelError(f"static_equilibrium: start must be one configuration ({model.n_positions} coordinates "
                             f"{model.coordinates}), got shape {np.shape(start)}")
        start = rows[0]
    free = [joint.name for joint in model.joints if joint.kind == "free" and not joint.driven]
    if free and np.any(model.gravity != 0.0):
        raise ModelError(f"linearize: {model.name!r} has the free joint(s) {free} under gravity "
                         f"{model.gravity.tolist()} m/s^2: it falls, there is no static equilibrium; hold the body "
                         "(Elastic6, Weld), set gravity=(0, 0, 0), or pass operating_point with "
                         "allow_nonequilibrium=True for the tangent at one instant")
    q = _continuation(model, model.normalized(model.neutral() if start is None else start), t, capped=stable)
    if not stable:
        return q

    def push(x: np.ndarray, direction: np.ndarray, value: float) -> np.ndarray:
        step = 1e-2 * direction / max(float(np.max(np.abs(direction))), 1e-300)
        return _continuation(model, model.normalized(retract(model, x, step)[0]), t, capped=True)

    return restart_until_stable(
        q, directions=lambda x: unstable_directions(model, x, t), restart=push,
        refusal=lambda x, values, vectors: (
            f"linearize: no statically stable equilibrium of {model.name!r} found: the one reached, "
            f"q = {np.round(x, 12).tolist()}, has {describe_directions(list(tangent_names(model)), values, vectors)}; "
            "pass operating_point=(q, v) to linearise about a chosen equilibrium"),
        restarts=STABLE_RESTARTS)


def unstable_directions(model: Any, q: Any, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The directions of negative stiffness of the equilibrium ``q`` (coordinates [rad, m, quaternions], at
    rest, loads at time ``t`` [s]) of a spatial model: :func:`ctmm.planar.equilibrium.negative_stiffness` of
    ``d v_dot / d r`` by complex step, i.e. the values ``omega^2 < 0`` [rad^2/s^2] (most negative first; empty
    for a statically stable or neutral equilibrium) and the vectors (columns) in the tangent coordinates
    :func:`tangent_names`."""
    _require_model(model, "unstable_directions")
    q = model.normalized(np.asarray(q, dtype=float))
    Jq, _ = _position_jacobian(model, q, np.zeros(model.n_velocities), t, velocities=False)
    return negative_stiffness(Jq)


def _continuation(model: Any, q: np.ndarray, t: float, *, capped: bool) -> np.ndarray:
    """Pseudo-transient continuation from ``q`` to a root of the accelerations at rest (module docstring);
    ``capped``: the step ``dt`` stays below ``0.5 / lambda`` of the fastest unstable direction at each
    point (implicit Euler then follows the fall away from an unstable equilibrium instead of jumping back),
    and such fall steps are judged by the potential energy (:class:`ctmm.spatial_fall.EnergyFall`)."""
    zero = np.zeros((1, model.n_velocities))
    limit = _scale(model)
    residual = _rates(model, q[None], zero, t)[0]
    size = float(np.max(np.abs(residual), initial=0.0))
    # pseudo-transient continuation on r' = f (the overdamped fall, which lowers the potential energy):
    # implicit Euler steps (I / dt - df/dr) step = f, dt grown as |f| falls (Newton once dt is large)
    dt = 0.1 / max(size, 1e-300)
    eye = np.eye(model.n_velocities)
    fall = EnergyFall(model, q, NEWTON_ITERATIONS + 5 * model.n_velocities) if capped else None
    newton_steps = NEWTON_ITERATIONS
    while newton_steps > 0:
        if size <= 1e-6 * limit:
            break
        Jq, _ = _position_jacobian(model, q, zero[0], t, velocities=False)
        values, _ = negative_stiffness(Jq) if capped else (np.zeros(0), None)
        if values.size and fall.exhausted():
            break                                   # no potential: the former budget of fall steps
        if not values.size:
            newton_steps -= 1
        step_size = min(dt, -0.5 / values[0]) if values.size else dt
        step = np.linalg.lstsq(eye / step_size - Jq, residual, rcond=1e-13)[0]
        trial = model.normalized(retract(model, q, step)[0])
        trial_residual = _rates(model, trial[None], zero, t)[0]
        trial_size = float(np.max(np.abs(trial_residual), initial=0.0))
        if values.size:                             # a fall step: judged by the potential energy
            if not fall.accept(q, trial, trial_size, size):
                dt = step_size / 4.0
                continue
            fall.taken(trial_size)
        elif not (np.isfinite(trial_size) and trial_size < 2.0 * size):
            dt /= 4.0
            continue
        elif fall is not None:
            fall.moved()
        ratio = trial_size / max(size, 1e-300)
        q, residual, size = trial, trial_residual, trial_size
        if size <= limit and ratio > 0.1 and not values.size:
            break                                   # Newton's quadratic convergence has reached round-off
        dt *= min(10.0, 1.0 / max(ratio, 1e-300))
    if not size <= limit:
        raise ModelError(f"linearize: no static equilibrium of {model.name!r} found near the neutral configuration "
                         f"(pseudo-transient Newton stopped at a largest acceleration {size:.3e} > {limit:.1e}); "
                         "a load without a restoring spring, or a drift direction; pass operating_point=(q, v)")
    return q


def _parse_point(model: Any, point: Any) -> tuple[Any, Any, float]:
    n_q, n_v = model.n_positions, model.n_velocities
    if isinstance(point, OperatingPoint):
        return point.q, point.qdot, point.t
    if isinstance(point, Mapping):
        if not set(point) <= {"q", "v", "t"}:
            raise ModelError(f"operating_point mapping keys must be 'q' ({n_q} coordinates {model.coordinates}), 'v' "
                             f"({n_v} velocities) and 't' [s], got {sorted(point)}")
        return point.get("q", model.neutral()), point.get("v", np.zeros(n_v)), point.get("t", 0.0)
    if isinstance(point, (tuple, list)) and len(point) in (2, 3):
        return point[0], point[1], (point[2] if len(point) == 3 else 0.0)
    raise ModelError(f"operating_point must be None, an OperatingPoint, (q, v), (q, v, t) or a mapping with keys 'q', "
                     f"'v', 't' for the spatial model {model.name!r} (q: {n_q} coordinates {model.coordinates}), got "
                     f"{point!r}")


def _time_varying(model: Any) -> bool:
    """True when the sweep's accelerations without inputs may depend on the time: the time enters
    :meth:`ctmm.spatial.body_forms.SpatialScene.terms` only through driven joints' motions, applied loads'
    signals and the terms of flexible bodies (beams, ``ctmm.fem`` subsystems)."""
    return bool(model.loads) or any(joint.driven for joint in model.joints) or any(
        layout is not None for layout in model.modal)


def operating_point(model: Any, point: Any = None, *, allow_nonequilibrium: bool = False) -> OperatingPoint:
    """The :class:`OperatingPoint` of a spatial model: the static equilibrium for ``None``
    (:func:`static_equilibrium`), else ``(q, v)``, ``(q, v, t)``, a mapping or an OperatingPoint,
    checked to be an equilibrium (at rest now and at a few later times
    :data:`~ctmm.planar_linearization.TIME_PROBES` unless nothing in the model depends on the time: no driven
    joint, load or flexible body) unless allowed."""
    _require_model(model, "operating_point")
    if point is None:                       # then checked like a given point (time-varying loads)
        q, v, t = static_equilibrium(model, stable=True), np.zeros(model.n_velocities), 0.0
    else:
        q, v, t = _parse_point(model, point)
    try:
        q_rows, v_rows = model.check_state(q, v)
    except ModelError as exc:
        raise ModelError(f"operating_point: {exc}") from None
    if q_rows.shape[0] != 1 or v_rows.shape[0] != 1:
        raise ModelError(f"operating_point: one state, got q of shape {np.shape(q)} and v of shape {np.shape(v)}")
    q, v = model.normalized(q_rows[0]), v_rows[0].copy()
    t = validation.finite("operating_point t", t)
    quaternion_rates = [joint.name for joint, layout in zip(model.joints, model.layout)
                        if joint.kind in ("spherical", "free", "elastic6") and np.any(v[layout.velocity] != 0.0)]
    if quaternion_rates:
        raise ModelError(f"linearize: the operating point of {model.name!r} has rates on the rotating joints "
                         f"{quaternion_rates}; the spatial tangent is built about rest for them (their tangent "
                         "kinematics are not [0, I] in motion); give v = 0 for spherical, free and elastic joints")
    limit = _scale(model)
    residual = float(np.max(np.abs(_rates(model, q[None], v[None], t)[0]), initial=0.0))
    equilibrium = residual <= limit and not np.any(v != 0.0)
    if equilibrium and _time_varying(model):    # else every later probe repeats this evaluation exactly
        for later in (t + offset for offset in TIME_PROBES):
            drift = float(np.max(np.abs(_rates(model, q[None], v[None], later)[0]), initial=0.0))
            if not drift <= limit:
                equilibrium, residual = False, drift
                break
    if not equilibrium and not allow_nonequilibrium:
        raise ModelError(f"linearize: the operating point of {model.name!r} is not an equilibrium (largest "
                         f"acceleration {residual:.3e} > {limit:.1e} now or later, largest rate "
                         f"{float(np.max(np.abs(v), initial=0.0)):.3e}); pass operating_point=None for the static "
                         "equilibrium, or allow_nonequilibrium=True for the tangent at this instant")
    return OperatingPoint(q, v, t, tuple(model.coordinates), bool(equilibrium), 0.0)


# ------------------------------------------------------------------------------- matrices
def tangent(model: Any, point: OperatingPoint) -> tuple[np.ndarray, OperatingPoint]:
    """``A = [[0, I], [df/dr, df/dv]]`` (2 nv, 2 nv) at ``point`` and the point with its
    ``jacobian_error`` (complex step, cross-checked by a Richardson difference along one direction)."""
    _require_model(model, "tangent")
    from .spatial.dynamics import accelerations

    n = model.n_velocities
    Jq, Jv = _position_jacobian(model, point.q, point.qdot, point.t)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [Jq, Jv]])
    if n == 0:
        return A, point
    direction = np.random.default_rng(20261125).uniform(-1.0, 1.0, 2 * n)
    direction /= np.max(np.abs(direction))

    def along(e: np.ndarray) -> np.ndarray:
        q = retract(model, point.q, e[0] * direction[None, :n])[0]
        return accelerations(model, q, point.qdot + e[0] * direction[n:], point.t)

    # the truncation error of the Richardson difference falls like h^4 where f is smooth: steps shrink (to
    # CROSS_CHECK_STEPS) until it is below the tolerance, as the high modal coordinates of a beam need (their
    # nonlinear terms grow with the mode number); a kink or a wrong Jacobian keeps the disagreement at every step
    errors = []
    for relative_step in CROSS_CHECK_STEPS:
        slope, slope_error = jacobian(along, np.zeros(1), relative_step=relative_step)
        disagreement = np.abs(np.hstack([Jq, Jv]) @ direction - slope[:, 0]) + slope_error[:, 0]
        errors.append(float(np.max(disagreement, initial=0.0) / max(float(np.max(np.abs(A))), 1e-300)))
        if errors[-1] <= JACOBIAN_TOLERANCE:
            break
    error = errors[-1]
    if not error <= JACOBIAN_TOLERANCE:
        raise ModelError(f"linearize: the Jacobians of {model.name!r} at the operating point disagree with a "
                         f"Richardson difference (relative {', '.join(f'{e:.2e}' for e in errors)} > "
                         f"{JACOBIAN_TOLERANCE:.0e} at relative steps {list(CROSS_CHECK_STEPS)}); the accelerations "
                         "are not smooth there")
    return A, point._replace(jacobian_error=error)


def input_matrix(model: Any, names: Sequence[str], point: OperatingPoint) -> np.ndarray:
    """``df/du`` (nv, len(names)) of input components ``names`` (:func:`input_names`) and actuator ports
    (:class:`ctmm.spatial.ports.SpatialPorts`: joint torques and forces, body forces and moments); exact
    (``f`` is affine in the inputs: symmetric unit differences)."""
    _require_model(model, "input_matrix")
    from .spatial.ports import SpatialPorts

    components = {name: (base, i) for name, base, i in _input_components(model)}
    ports = None
    columns = np.zeros((model.n_velocities, len(names)))
    own = [k for k, name in enumerate(names) if name in components]
    for k, name in enumerate(names):
        if name in components:
            continue
        if ports is None:
            ports = SpatialPorts(model)
        try:
            ports.check_actuator(name, "input")                # says why for driven, welded, unactuated joints
        except UnknownNameError:
            raise unknown_name("spatial input (input component or actuator port)", name,
                               list(components) + list(ports.actuators)) from None
        up, down = (ports.accelerations(point.q, point.qdot, point.t, ports.inputs({name: sign}))
                    for sign in (1.0, -1.0))
        columns[:, k] = 0.5 * (np.asarray(up) - np.asarray(down))
    if not own:
        return columns
    m = len(own)
    values: dict[str, np.ndarray] = {}
    for row, k in enumerate(own):
        base, i = components[names[k]]
        size = next(j.velocity_count for j in model.joints if base in j.inputs)
        block = values.setdefault(base, np.zeros((2 * m, size)))
        block[row, i], block[m + row, i] = 1.0, -1.0
    q = np.repeat(point.q[None], 2 * m, axis=0)
    v = np.repeat(point.qdot[None], 2 * m, axis=0)
    rates = _rates(model, q, v, point.t, values)
    columns[:, own] = (0.5 * (rates[:m] - rates[m:])).T
    return columns


def output_matrix(model: Any, names: Sequence[str], point: OperatingPoint, ports: Any = None) -> np.ndarray:
    """``dy/dx`` (len(names), 2 nv) of sensor ports (:class:`ctmm.spatial.ports.SpatialPorts`) and of the
    tangent coordinates that are not ports (``"ball.rx"``, ``"u.angle1"``), in the state ``x = [r ; v]``.

    Sensor rows by complex step through :func:`ctmm.spatial_sensors_complex.complex_sensor_values` (exact to
    round-off); a name that is both (joint angles, velocities, free-joint positions) is the sensor: for
    ``"<free joint>.x|y|z"`` the world position, equal to the tangent coordinate where ``R0 = I``.  When every
    sensor asked for reads the configuration alone (coordinates, angles, rotation vectors, point positions), only
    the ``nv`` position directions are stepped: the velocity columns are zero.

    Parameters
    ----------
    model : SpatialModel
    names : sequence of str
        Sensor ports and tangent coordinates.
    point : OperatingPoint
    ports : SpatialPorts, optional
        The model's resolved ports (built when omitted).
    """
    _require_model(model, "output_matrix")
    from .spatial.ports import SpatialPorts

    n = model.n_velocities
    states = list(tangent_names(model)) + list(model.velocities)
    index = {name: k for k, name in enumerate(states)}
    ports = SpatialPorts(model) if ports is None else ports
    rows = np.zeros((len(names), 2 * n))
    sensed = []
    for k, name in enumerate(names):
        if isinstance(name, str) and name in ports.sensors:
            sensed.append(k)
        elif isinstance(name, str) and name in index:
            rows[k, index[name]] = 1.0
        else:
            try:
                ports.check_sensor(name, "output")
            except UnknownNameError:
                raise unknown_name("output of a spatial linearisation (sensor port or tangent coordinate)", name,
                                   sorted(set(states) | set(ports.sensors))) from None
    if sensed and n:
        step = 1e-30
        sensors = [names[k] for k in sensed]
        # sensors of the configuration alone (coordinates, angles, rotation vectors, point positions) read no
        # velocity: their velocity columns are zero, and only the n position directions are stepped
        count = n if all(sensor.kind in _CONFIGURATION_SENSORS for sensor in ports.resolve(sensors)) else 2 * n
        perturb = 1j * step * np.eye(2 * n)[:count]
        q = retract(model, point.q, perturb[:, :n])
        v = point.qdot[None, :] + perturb[:, n:]
        values = complex_sensor_values(model, sensors, q, v, point.t, ports)
        rows[np.ix_(sensed, range(count))] = (values.imag / step).T
    return rows


def linearize_spatial(model: Any, point: Any = None, *, inputs: Any = None, outputs: Any = None,
                      allow_nonequilibrium: bool = False, loops: Sequence[Any] = ()) -> LinearizedSystem:
    """:func:`ctmm.linearize` of a spatial model, closed by the ``loops`` of a ``ControlledModel``
    (module docstring).

    Parameters
    ----------
    model : SpatialModel
    point : optional
        ``None`` (static equilibrium of ``model``), ``(q, v)``, ``(q, v, t)``, ``{"q", "v", "t"}`` or an
        OperatingPoint.
    inputs : str or sequence of str, optional
        Input components (:func:`input_names`), actuator ports (``"body.force_x"``, ``"ball.torque_x"``)
        and ``"<loop>.reference"`` of a loop without delay; default: the input components not driven by
        a loop; ``[]`` for none.
    outputs : str or sequence of str, optional
        Sensor ports (:mod:`ctmm.spatial.ports`), tangent coordinates (:func:`tangent_names`) and
        velocities, ``"<loop>.y"`` / ``"<loop>.u"`` of a loop without delay; default the tangent coordinates.
    allow_nonequilibrium : bool
        Accept a point that is not an equilibrium (rates of 1-/2-DOF joints, accelerations): the
        tangent at that instant only.
    loops : sequence of Feedback
        Loops without delay are closed inside ``A``, delayed loops left open beside it
        (:func:`ctmm.controlled_linearization.close_model_loops`).
    """
    _require_model(model, "linearize_spatial")
    from .spatial.ports import SpatialPorts

    validation.flag("allow_nonequilibrium", allow_nonequilibrium)
    loops = tuple(loops)
    refuse_saturation(loops, "ctmm.linearize")
    A, op = tangent(model, operating_point(model, point, allow_nonequilibrium=allow_nonequilibrium))
    n = model.n_velocities
    default_inputs: list[str] = []
    if inputs is None:
        actuators = SpatialPorts(model).actuators
        driven = {(actuators[name].target, actuators[name].component) for name in loop_ports(loops)[0]
                  if actuators[name].kind == "joint"}
        default_inputs = [name for name, base, i in _input_components(model) if (base, i) not in driven]
    states = list(tangent_names(model)) + list(model.velocities)
    return close_model_loops(
        A, loops, inputs=inputs, outputs=outputs, default_inputs=default_inputs,
        default_outputs=list(tangent_names(model)),
        input_columns=lambda names: np.vstack([np.zeros((n, len(names))), input_matrix(model, names, op)]),
        output_rows=lambda names: output_matrix(model, names, op), states=states, name=model.name, point=op)
