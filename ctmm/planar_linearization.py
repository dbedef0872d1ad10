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
from .linearized import DelayedLoop, LinearizedSystem, OperatingPoint, control_name
from .loop_closure import close_loops

__all__ = ["linearize_planar", "operating_point", "tangent", "jacobian", "input_matrix", "output_matrix",
           "JACOBIAN_TOLERANCE", "EQUILIBRIUM_TOLERANCE"]

JACOBIAN_TOLERANCE = 1e-6
"""Largest accepted estimated error of the Jacobians, relative to ``max |A|``."""
EQUILIBRIUM_TOLERANCE = 1e-8
"""Largest accelerations at an equilibrium [rad/s^2, m/s^2], relative to ``1 + |gravity|``."""
TIME_PROBES = (1e-3, 0.0137, 0.1, 0.731, 3.1)
"""Offsets [s] after the operating time at which an equilibrium must still be at rest (time-varying models)."""


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
        :func:`ctmm.planar.equilibrium.hanging_configuration` (every centre of mass below its hinge).
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
            q = static_equilibrium(model, hanging_configuration(model))
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


def _loop_ports(loops: Sequence[Any]) -> tuple[list[str], list[str]]:
    actuators = list(dict.fromkeys(name for lp in loops for name, _ in lp.actuator_terms))
    sensors = list(dict.fromkeys(name for lp in loops for name, _ in lp.terms))
    return actuators, sensors


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


def _exogenous_inputs(model: Any, loops: Sequence[Any], inputs: Any) -> tuple[list[str], dict[int, int]]:
    """Requested inputs and ``{input index: loop index}`` of the ``"<loop>.reference"`` among them."""
    if inputs is None:
        from .planar import ports

        actuated = set(_loop_ports(loops)[0])
        return [name for name in ports.actuator_names(model) if name not in actuated], {}
    if isinstance(inputs, (list, tuple)) and not inputs:
        return [], {}                               # no exogenous input (e.g. for eigenvalues only)
    exo = list(validation.names("inputs", inputs))
    index = {lp.name: j for j, lp in enumerate(loops)}
    references = {}
    for k, name in enumerate(exo):
        head, _, tail = name.partition(".")
        if head in index:
            if tail != "reference" or loops[index[head]].delay > 0.0:
                raise ModelError(f"linearize: input {name!r}: the inputs of a loop are '<loop>.reference' of a "
                                 "loop without delay; a delayed loop is left open (its force is the input "
                                 "'<loop>_u')")
            references[k] = index[head]
    return exo, references


def _requested_outputs(model: Any, loops: Sequence[Any], outputs: Any) -> tuple[list[str], dict[int, tuple]]:
    """Requested outputs and ``{output index: (loop index, "y" or "u")}`` of the loop signals among them."""
    if outputs is None:
        req = list(model.coordinates)
    elif isinstance(outputs, (list, tuple)) and not outputs:
        req = []                                    # only the ports of the delayed loops
    else:
        req = list(validation.names("outputs", outputs))
    index = {lp.name: j for j, lp in enumerate(loops)}
    loop_outputs = {}
    for k, name in enumerate(req):
        head, _, tail = name.partition(".")
        if head in index and tail in ("y", "u"):
            if loops[index[head]].delay > 0.0:
                raise ModelError(f"linearize: output {name!r}: the delayed loop {head!r} is left open, its "
                                 f"sensed value and force are the ports '{head}_y' and '{head}_u' already")
            loop_outputs[k] = (index[head], tail)
    return req, loop_outputs


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
    step itself is exact to round-off).  A disagreement beyond :data:`JACOBIAN_TOLERANCE` (terms
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

        slope, slope_error = jacobian(along, np.zeros(1))
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
    """:func:`ctmm.linearize` of a planar model closed by ``loops`` (module docstring)."""
    import control

    refuse_saturation(loops, "ctmm.linearize")

    A, op = tangent(model, operating_point(model, point, allow_nonequilibrium=allow_nonequilibrium))
    n = model.n_coordinates
    exo, references = _exogenous_inputs(model, loops, inputs)
    req, loop_outputs = _requested_outputs(model, loops, outputs)
    loop_actuators, loop_sensors = _loop_ports(loops)
    plant_in = list(dict.fromkeys([x for k, x in enumerate(exo) if k not in references] + loop_actuators))
    plant_out = list(dict.fromkeys([x for k, x in enumerate(req) if k not in loop_outputs] + loop_sensors))
    col = {name: k for k, name in enumerate(plant_in)}
    row = {name: k for k, name in enumerate(plant_out)}
    # plant ports -> [exogenous inputs, one force per loop], [requested outputs, one sensed sum per loop]
    S_in = np.zeros((len(plant_in), len(exo) + len(loops)))
    S_out = np.zeros((len(req) + len(loops), len(plant_out)))
    for k, name in enumerate(exo):
        if k not in references:
            S_in[col[name], k] = 1.0
    for k, name in enumerate(req):
        if k not in loop_outputs:
            S_out[k, row[name]] = 1.0
        elif loop_outputs[k][1] == "y":             # the sensed value (not y - r)
            for sensor, weight in loops[loop_outputs[k][0]].terms:
                S_out[k, row[sensor]] += weight
    for j, lp in enumerate(loops):
        for name, weight in lp.actuator_terms:
            S_in[col[name], len(exo) + j] += weight
        for name, weight in lp.terms:
            S_out[len(req) + j, row[name]] += weight
    B = np.vstack([np.zeros((n, len(plant_in))), input_matrix(model, plant_in, op)]) @ S_in
    C = S_out @ output_matrix(model, plant_out, op)
    D = np.zeros((C.shape[0], B.shape[1]))
    for k, j in references.items():
        D[len(req) + j, k] = -1.0                   # the loop acts on y - r
    A_cl, B_cl, C_cl, D_cl, sizes, C_u, D_u = close_loops((A, B, C, D), loops, len(exo))
    real_time = [lp for lp in loops if lp.delay == 0.0]
    for k, (j, part) in loop_outputs.items():
        if part == "u":                             # the loop force, from the closure
            C_cl[k], D_cl[k] = C_u[real_time.index(loops[j])], D_u[real_time.index(loops[j])]
    delayed = [lp for lp in loops if lp.delay > 0.0]
    states = list(model.coordinates) + [f"{c}_dot" for c in model.coordinates]
    states += [f"{lp.name}.controller{k}" for lp, size in zip(real_time, sizes) for k in range(size)]
    labels_in = [control_name(x) for x in exo] + [control_name(f"{lp.name}.u") for lp in delayed]
    labels_out = [control_name(x) for x in req] + [control_name(f"{lp.name}.y") for lp in delayed]
    if not labels_in and len(labels_out) == 1:
        raise ModelError(f"linearize: inputs={inputs!r} leaves the linearisation of {model.name!r} with no input and "
                         f"the one output {req + [lp.name for lp in delayed]}, a state space python-control cannot "
                         "hold (its D would be 1 x 0); name an input (an actuator or '<loop>.reference'), a "
                         "second output, or leave inputs=None")
    ss = control.ss(A_cl, B_cl, C_cl, D_cl, inputs=labels_in, outputs=labels_out,
                    states=[control_name(x) for x in states], name=control_name(model.name))
    return LinearizedSystem(ss, tuple(DelayedLoop(lp.name, lp.gain, lp.delay) for lp in delayed), op)
