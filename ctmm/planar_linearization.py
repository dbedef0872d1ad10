"""Linearisation of planar (rigid and flexible) models about an operating point.

The path of :func:`ctmm.linearize` for a :class:`~ctmm.planar.model.PlanarModel` and a
``ctmm.control.ControlledModel`` (documented there and in ``docs/control.md``, "Linearisation").
State ``x = [q, qdot]`` (deviations from the operating point), ``x' = A x + B u``, ``y = C x``:

* ``A = [[0, I], [df/dq, df/dqdot]]`` with ``f = qddot(q, qdot, u)`` -- by complex step through
  the batched terms of the one articulated sweep (:mod:`ctmm.articulated`,
  :class:`ctmm.planar.body_forms.PlanarScene`), exact to round-off, cross-checked along one
  direction by a Richardson difference of :func:`ctmm.planar.accelerations`; models not on the
  element protocol with complex-safe terms (user state laws on beams): central differences
  with Richardson extrapolation and an error estimate (:func:`jacobian`);
* ``B = [[0], [df/du]]`` -- ``f`` is affine in the actuator inputs of
  :func:`ctmm.planar.ports.actuator_inputs`, so a symmetric unit difference is exact;
* ``C`` -- coordinates and their rates directly, other sensors from
  :func:`ctmm.planar.ports.sensor_jacobians`; ``D = 0``.
"""
from __future__ import annotations

import math
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from . import validation
from .errors import ModelError, unknown_name
from .saturation import refuse_saturation
from .controlled_linearization import close_model_loops, loop_ports
from .linearized import LinearizedSystem, OperatingPoint

__all__ = ["linearize_planar", "operating_point", "tangent", "jacobian", "input_matrix", "output_matrix",
           "JACOBIAN_TOLERANCE", "EQUILIBRIUM_TOLERANCE", "CROSS_CHECK_STEPS"]

JACOBIAN_TOLERANCE = 1e-6
"""Largest accepted estimated error of the Jacobians, relative to ``max |A|``."""
EQUILIBRIUM_TOLERANCE = 1e-8
"""Largest accelerations at an equilibrium [rad/s^2, m/s^2], relative to ``1 + |gravity|``."""
TIME_PROBES = (1e-3, 0.0137, 0.1, 0.731, 3.1)
"""Offsets [s] after the operating time at which an equilibrium must still be at rest (time-varying models)."""


CROSS_CHECK_STEPS = (1e-3, 1e-4, 1e-5)
"""Relative steps of the Richardson cross-check of the complex-step tangent, tried in turn until it agrees: of
:func:`tangent` and of :func:`ctmm.spatial_linearization.tangent` (one rule for both)."""


def jacobian(function: Callable[[np.ndarray], np.ndarray], x: np.ndarray, *, relative_step: float = 1e-3
             ) -> tuple[np.ndarray, np.ndarray]:
    """Jacobian of a smooth ``function`` at ``x`` by Richardson-extrapolated central differences.

    Steps ``h, h/2, h/4`` with ``h = relative_step * max(1, min(|x_i|, 2 pi), |x_i| / 1e4)``
    (bounded for ``|x_i|`` up to ``2 pi 1e4``: an angle's scale is the radian, not its value, so a
    step relative to a large angle (many turns) would span whole periods; beyond, relative
    ``1e-7`` keeps ``x + h`` exact enough); ``D(h)`` central differences,
    ``R(h) = (4 D(h/2) - D(h)) / 3`` (error ``O(h^4)``).  A kink at ``x`` (one-sided slopes that
    differ by ``j``, e.g. a saturation switching exactly there) leaves every ``D`` equal to the mean
    slope, so it is detected separately: the second difference ``S(h) = f(x+h) - 2 f(x) + f(x-h)``
    falls like ``h^2`` when ``f`` is smooth and like ``h`` (``S = j h``) at a kink; where
    ``|S(h/2)| > 0.4 |S(h)|`` and ``S(h)`` is above round-off, ``|S(h)| / h`` is added to the error.

    Returns
    -------
    J : ndarray, shape (m, n)
        ``R(h/2)``.
    error : ndarray, shape (m, n)
        ``|R(h/2) - R(h)|`` (an estimate of the truncation error of ``J``, conservative since
        ``R(h)``'s is 16 times ``R(h/2)``'s; round-off, ``~1e-13 |f| / h``, is of the same size
        only where the estimate is already negligible), plus the slope jump of a detected kink.
    """
    x = np.asarray(x, dtype=float)
    f0 = np.asarray(function(x), dtype=float)
    columns, errors = [], []
    for i in range(x.size):
        h = relative_step * max(1.0, min(abs(x[i]), 2.0 * math.pi), abs(x[i]) / 1e4)
        diffs, second = [], []
        for k in range(3):
            step = np.zeros_like(x)
            step[i] = h / 2.0 ** k
            up, down = np.asarray(function(x + step)), np.asarray(function(x - step))
            diffs.append((up - down) / (2.0 * step[i]))
            second.append(np.abs(up - 2.0 * f0 + down))
        coarse = (4.0 * diffs[1] - diffs[0]) / 3.0
        fine = (4.0 * diffs[2] - diffs[1]) / 3.0
        noise = 1e-12 * (np.abs(f0) + h * np.abs(fine)) + 1e-300
        kink = (second[0] > noise) & (second[1] > 0.4 * second[0])
        columns.append(fine)
        errors.append(np.abs(fine - coarse) + np.where(kink, second[0] / h, 0.0))
    return np.array(columns).T, np.array(errors).T


def operating_point(model: Any, point: Any = None, *, allow_nonequilibrium: bool = False) -> OperatingPoint:
    """The operating point of ``model`` from the forms :func:`ctmm.linearize` accepts.

    Parameters
    ----------
    model : PlanarModel
    point : OperatingPoint, (q, qdot[, t]), mapping or None
        A mapping has keys ``"q"``, ``"qdot"``, ``"t"`` or coordinate names (values [rad, m,
        modal]; the others 0, rates 0).  ``None``: the static equilibrium found by
        :func:`ctmm.planar.equilibrium.static_equilibrium` at ``t = 0`` from
        :func:`ctmm.planar.equilibrium.hanging_configuration` (every centre of mass below its hinge), ``stable=True``.
    allow_nonequilibrium : bool
        Accept nonzero rates or accelerations (otherwise :class:`ModelError`).

    Returns
    -------
    OperatingPoint
        ``jacobian_error`` not yet set (0).
    """
    if getattr(model, "n_coordinates", 1) == 0:
        raise ModelError(f"model {model.name!r} has no coordinates (every body is welded or driven): there is no "
                         "motion to linearise about an operating point")
    from .planar.equilibrium import hanging_configuration, static_equilibrium
    from .planar.sweep import accelerations

    n = model.n_coordinates
    t = 0.0
    if point is None:
        try:
            q = static_equilibrium(model, hanging_configuration(model), stable=True)
        except ModelError as exc:
            raise ModelError(f"linearize: no operating point given and {exc}; pass operating_point=(q, qdot) "
                             "(with allow_nonequilibrium=True for a point that is not an equilibrium, e.g. a "
                             "free-flying body under gravity)") from None
        qdot = np.zeros(n)
    elif isinstance(point, OperatingPoint):
        q, qdot, t = point.q, point.qdot, point.t
    elif isinstance(point, Mapping):
        keys = set(point)
        if keys <= {"q", "qdot", "t"}:
            q, qdot, t = point.get("q", np.zeros(n)), point.get("qdot", np.zeros(n)), point.get("t", 0.0)
        else:
            q = np.zeros(n)
            for name, value in point.items():
                if name not in model.coordinates:
                    raise unknown_name("coordinate of operating_point (or its keys 'q', 'qdot', 't')", name,
                                       list(model.coordinates))
                q[model.coordinate_index(name)] = validation.finite(f"operating_point[{name!r}]", value)
            qdot = np.zeros(n)
    elif isinstance(point, (tuple, list)) and len(point) in (2, 3):
        q, qdot = point[0], point[1]
        t = point[2] if len(point) == 3 else 0.0
    else:
        raise ModelError(f"operating_point must be None, an OperatingPoint, (q, qdot), (q, qdot, t) or a mapping "
                         f"(coordinates {', '.join(model.coordinates)}), got {point!r}")
    try:
        q, qdot = model.state(q, qdot)
    except ModelError as exc:
        raise ModelError(f"operating_point: {exc}") from None
    q, qdot = q.copy(), qdot.copy()
    t = validation.finite("operating_point t", t)
    residual = float(np.max(np.abs(accelerations(model, q, qdot, t)), initial=0.0))
    limit = EQUILIBRIUM_TOLERANCE * (1.0 + float(np.max(np.abs(model.gravity))))
    equilibrium = residual <= limit and not np.any(qdot != 0.0)
    if not equilibrium and not allow_nonequilibrium:
        raise ModelError(f"linearize: the operating point of {model.name!r} is not an equilibrium (largest "
                         f"acceleration {residual:.3e} > {limit:.1e}, largest rate "
                         f"{float(np.max(np.abs(qdot), initial=0.0)):.3e}); pass operating_point=None for the "
                         "static equilibrium, or allow_nonequilibrium=True for the tangent at this instant")
    if equilibrium:
        # at rest now is not enough: a driven hinge in motion or a time-varying load moves the point later
        # (the tangent of a time-varying system at one instant has no eigenvalues or frequency response)
        for later in (t + offset for offset in TIME_PROBES):
            drift = float(np.max(np.abs(accelerations(model, q, qdot, later)), initial=0.0))
            if not drift <= limit:
                equilibrium = False
                if not allow_nonequilibrium:
                    raise ModelError(
                        f"linearize: the operating point of {model.name!r} is at rest at t = {t:g} s but not an "
                        f"equilibrium in time: at t = {later:.4g} s its largest acceleration is {drift:.3e} > "
                        f"{limit:.1e} (a driven hinge in motion or a time-varying load); the system is time-varying "
                        "there, so its linearisation has no eigenvalues or frequency response; pass "
                        "allow_nonequilibrium=True for the tangent at this instant only")
                break
    return OperatingPoint(q, qdot, t, tuple(model.coordinates), bool(equilibrium), 0.0)


def input_matrix(model: Any, names: Sequence[str], point: OperatingPoint) -> np.ndarray:
    """``df/du`` (n_coordinates, len(names)) of the actuator inputs ``names`` (exact: ``f`` is affine in u)."""
    if not names:
        return np.zeros((model.n_coordinates, 0))
    from . import planar
    from .planar import ports

    accelerations = planar.accelerations
    columns = []
    for name in names:
        up = accelerations(model, point.q, point.qdot, point.t, inputs=ports.actuator_inputs(model, {name: 1.0}))
        down = accelerations(model, point.q, point.qdot, point.t,
                             inputs=ports.actuator_inputs(model, {name: -1.0}))
        columns.append(0.5 * (np.asarray(up) - np.asarray(down)))
    return np.array(columns).T.reshape(model.n_coordinates, len(names))


def output_matrix(model: Any, names: Sequence[str], point: OperatingPoint) -> np.ndarray:
    """``[dy/dq, dy/dqdot]`` (len(names), 2 n_coordinates) of the sensors ``names``."""
    n = model.n_coordinates
    index = {c: k for k, c in enumerate(model.coordinates)}
    index.update({f"{c}_dot": n + k for k, c in enumerate(model.coordinates)})
    rows = np.zeros((len(names), 2 * n))
    others = [name for name in names if name not in index]
    if others:
        from .planar import ports

        dq, dv = ports.sensor_jacobians(model, others, point.q, point.qdot, point.t)
        other_rows = np.hstack([np.asarray(dq, dtype=float), np.asarray(dv, dtype=float)])
    for k, name in enumerate(names):
        if name in index:
            rows[k, index[name]] = 1.0
        else:
            rows[k] = other_rows[others.index(name)]
    return rows


def _one_sweep_applies(model: Any) -> bool:
    """True when every element of ``model`` is stated on the element protocol with complex-safe terms
    (:class:`ctmm.planar.body_forms.PlanarScene`, hinges with translational springs included): no user
    state-feedback laws on beams (user code may not accept complex coordinates)."""
    return not any(beam.data.laws for beam in model.beams.values())


def _complex_step_jacobians(model: Any, point: OperatingPoint, step: float = 1e-30
                            ) -> tuple[np.ndarray, np.ndarray]:
    """``df/dq, df/dqdot`` by complex step through the batched terms of the one articulated sweep.

    One sweep batched over ``2 n`` complex states ``q + i h e_k``, ``qdot + i h e_k``;
    ``Im f / h`` is exact to round-off (no subtraction) for terms that are analytic in the state.
    """
    from .planar.body_forms import PlanarScene

    n = model.n_coordinates
    perturb = 1j * step * np.eye(2 * n)
    q = point.q[None, :] + perturb[:, :n]
    qdot = point.qdot[None, :] + perturb[:, n:]
    J = PlanarScene(model).accelerations(q, qdot, point.t).imag / step      # (2 n, n): row k = d f / d x_k
    return J[:n].T, J[n:].T


def tangent(model: Any, point: OperatingPoint) -> tuple[np.ndarray, OperatingPoint]:
    """``A = [[0, I], [df/dq, df/dqdot]]`` at ``point`` and the point with its ``jacobian_error``.

    Models on the element protocol (:func:`_one_sweep_applies`): complex step through the one
    articulated sweep (:func:`_complex_step_jacobians`), cross-checked along a fixed pseudo-random
    direction ``d`` against a Richardson difference of :func:`ctmm.planar.accelerations` (today's
    kernel): ``jacobian_error`` is their disagreement ``|J d - (df/dd)_Richardson|`` plus that
    difference's own error estimate, relative to ``max |A|`` (a conservative bound: the complex
    step itself is exact to round-off), at the relative steps :data:`CROSS_CHECK_STEPS` in turn until it
    agrees (the difference's truncation error grows with the chain: a 60-link pendulum needs ``1e-4``; falling
    back at ``1e-3`` replaced an exact tangent by differences accurate to ``~1e-8 max |A|``, and its last
    angle's FRF at 0.48 rad/s by one wrong by ``6e-6`` relative).  A disagreement beyond :data:`JACOBIAN_TOLERANCE` (terms
    that are not analytic in the state, a kink) falls back to Richardson differences of every
    column (:func:`jacobian`), which report the kink.  Other models: Richardson differences.
    """
    from .planar.sweep import accelerations

    n = model.n_coordinates
    if _one_sweep_applies(model):
        Jq, Jv = _complex_step_jacobians(model, point)
        A = np.block([[np.zeros((n, n)), np.eye(n)], [Jq, Jv]])
        direction = np.random.default_rng(20261124).uniform(-1.0, 1.0, 2 * n)
        direction /= np.max(np.abs(direction))

        def along(e: np.ndarray) -> np.ndarray:
            x = np.concatenate([point.q, point.qdot]) + e[0] * direction
            return accelerations(model, x[:n], x[n:], point.t)

        for relative_step in CROSS_CHECK_STEPS:        # the difference's h^4 error falls as h shrinks (long chains)
            slope, slope_error = jacobian(along, np.zeros(1), relative_step=relative_step)
            disagreement = np.abs(np.hstack([Jq, Jv]) @ direction - slope[:, 0]) + slope_error[:, 0]
            error = float(np.max(disagreement, initial=0.0) / np.max(np.abs(A)))
            if error <= JACOBIAN_TOLERANCE:
                return A, point._replace(jacobian_error=error)
    Jq, eq = jacobian(lambda q: accelerations(model, q, point.qdot, point.t), point.q)
    Jv, ev = jacobian(lambda v: accelerations(model, point.q, v, point.t), point.qdot)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [Jq, Jv]])
    error = float(max(np.max(eq, initial=0.0), np.max(ev, initial=0.0)) / np.max(np.abs(A)))
    if not error <= JACOBIAN_TOLERANCE:
        raise ModelError(f"linearize: the Jacobians of {model.name!r} at the operating point are not accurate "
                         f"(estimated relative error {error:.2e} > {JACOBIAN_TOLERANCE:.0e}); the accelerations "
                         "are not smooth there (a switching law, a saturation or a contact?)")
    return A, point._replace(jacobian_error=error)


def linearize_planar(model: Any, loops: Sequence[Any], point: Any, *, inputs=None, outputs=None,
                     allow_nonequilibrium: bool = False) -> LinearizedSystem:
    """:func:`ctmm.linearize` of a planar model closed by ``loops`` (module docstring; the loops by
    :func:`ctmm.controlled_linearization.close_model_loops`)."""
    from .planar import ports

    refuse_saturation(loops, "ctmm.linearize")

    A, op = tangent(model, operating_point(model, point, allow_nonequilibrium=allow_nonequilibrium))
    n = model.n_coordinates
    actuated = set(loop_ports(loops)[0])
    default_inputs = [name for name in ports.actuator_names(model) if name not in actuated] if inputs is None else []
    states = list(model.coordinates) + [f"{c}_dot" for c in model.coordinates]
    return close_model_loops(
        A, loops, inputs=inputs, outputs=outputs, default_inputs=default_inputs,
        default_outputs=list(model.coordinates),
        input_columns=lambda names: np.vstack([np.zeros((n, len(names))), input_matrix(model, names, op)]),
        output_rows=lambda names: output_matrix(model, names, op), states=states, name=model.name, point=op)
