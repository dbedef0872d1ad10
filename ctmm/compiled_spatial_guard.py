"""The deformation guard of flexible bodies inside the generated RK4 of spatial models (issues 15 and 16).

The numpy RK4 (:func:`ctmm.spatial.integrate.simulate_spatial`) checks after every step that each
:class:`~ctmm.spatial.SpatialBeam`'s deflection bound ``sum_i max|phi_i| |eta_i|`` stays below its length
and that each :class:`ctmm.fem.SpatialSubsystem`'s nodes move by less than its size and turn by less
than 1 rad (:func:`~ctmm.spatial.integrate.check_beam_deflection`).  The generated time loop
(:mod:`ctmm.compiled_spatial`) states the same bounds on symbols (:func:`deformation_exceeded`) and
steps with :func:`guarded_step`: a step whose new state leaves them returns NaN, which the loop carries
to its end, so the run stops after the block holding it (:func:`ctmm.generated_loop.run_blocks`)
instead of integrating a diverged model.  :func:`replay_failure` then runs the plain generated step
again from the last good stored state and checks every step as the numpy path does
(:func:`~ctmm.spatial.integrate.divergence_check`): the :class:`~ctmm.errors.SimulationError` names the
same time and element, with the stored states before that time as the partial result.
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from .spatial.integrate import beam_deflection_weights, divergence_check
from .spatial.model import SpatialModel

__all__ = ["deformation_exceeded", "guarded_step", "replay_failure"]


def deformation_exceeded(model: SpatialModel, y: Any) -> Any:
    """``1`` when the state ``y = [q ; v]`` (casadi column) leaves a flexible body's bounds (module
    docstring), else ``0``; ``None`` for a model without flexible bodies."""
    import casadi as ca

    conditions = []
    for body, indices, weights in beam_deflection_weights(model):
        if weights is None:                         # a finite-element subsystem: node displacements and rotations
            translational = body.data.translational
            moved = [ca.fabs(y[int(i)]) for i in indices[translational]]
            turned = [ca.fabs(y[int(i)]) for i in indices[~translational]]
            if moved:
                conditions.append(ca.mmax(ca.vertcat(*moved)) > float(body.data.size))
            if turned:
                conditions.append(ca.mmax(ca.vertcat(*turned)) > 1.0)
        elif len(indices):
            deflection = sum(float(w) * ca.fabs(y[int(i)]) for i, w in zip(indices, weights))
            conditions.append(deflection > float(body.length))
    if not conditions:
        return None
    exceeded = conditions[0]
    for condition in conditions[1:]:
        exceeded = ca.logic_or(exceeded, condition)
    return exceeded


def guarded_step(model: SpatialModel, step: Any) -> Any:
    """The generated ``step(y, u, h, p, t0, k)`` (:func:`ctmm.generated_loop.rk4_step_function`) returning
    NaN in every entry when its new state exceeds :func:`deformation_exceeded`; ``step`` itself for a
    model without flexible bodies."""
    import casadi as ca

    arguments = [ca.MX.sym(label, *step.size_in(i)) for i, label in enumerate(("y", "u", "h", "p", "t0", "k"))]
    y = ca.SX.sym("y", step.size1_in(0))
    exceeded = deformation_exceeded(model, y)
    if exceeded is None:
        return step
    check = ca.Function("deformation_exceeded", [y], [exceeded])
    after = step(*arguments)
    return ca.Function("guarded_step", arguments, [ca.if_else(check(after), ca.DM.nan(after.size1(), 1), after)])


def replay_failure(model: SpatialModel, plain_step: Callable[..., Any], start: np.ndarray, stored: np.ndarray,
                   u: np.ndarray, p: np.ndarray, dt: float, first_step: int, last_step: int,
                   divergence_bound: float | None, partial: Callable[[], Any], *, label: str = "rk4-generated",
                   size: int | None = None) -> None:
    """Run ``plain_step`` (the unguarded generated step) from the stored state ``stored`` after
    ``first_step`` steps up to step ``last_step``, checking each new state as the numpy RK4 does
    (:func:`~ctmm.spatial.integrate.divergence_check` from the initial state ``start``, at
    ``t = k dt + dt``, on the first ``size`` entries ``[q ; v]`` of a state that carries more, e.g. controller
    states); raises its :class:`~ctmm.errors.SimulationError` (method ``label``, ``partial()`` as the partial
    result) and returns when no step fails."""
    size = len(start) if size is None else size
    check = divergence_check(model, np.asarray(start, dtype=float)[:size], divergence_bound)
    x = np.asarray(stored, dtype=float).reshape(-1)
    for k in range(first_step, last_step):
        x = np.asarray(plain_step(x, u, dt, p, 0.0, float(k))).reshape(-1)
        check(k * dt + dt, x[:size], label, partial)
