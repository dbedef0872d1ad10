"""Newton iterations of the implicit DT-TMM with state-dependent actuator inputs.

:func:`ctmm.planar.simulate_implicit` takes ``inputs(t, q, qdot) -> ActuatorInputs | None``
(:mod:`ctmm.planar.ports`): actuator values that may depend on the state (a feedback law closed
around the plant in real time).  They are evaluated at the step's evaluation time and at every
Newton iterate ``q = q_hat + b' h^2 x``, ``v = v_hat + g' h x``, and the Newton tangent includes
their state dependence.

One tangent sweep ``S`` (:meth:`linearise` / :meth:`solve` of the steppers) is affine in the
inputs ``u`` for a fixed linearisation, ``S(u + du) = S(u) + T du``; with ``u = U(x)`` and
``J = dU/dx`` the Newton update ``d = x_new - x`` solves

    (I - T J) d = r,        r = S(U(x)) - x.

``T J`` has the rank of the inputs' state dependence (one per feedback actuator), so it is never
formed: GMRES on ``I - T J`` (:func:`ctmm.low_rank.low_rank_solve`) ends after ``rank + 1`` products, each a **directional finite
difference** of the input map (``(U(x + eps v) - U(x)) / eps``, step ``1e-7`` of the state's size)
and one sweep with those inputs.  The new iterate is one more sweep with the extrapolated inputs
``U(x) + J d``, so body accelerations, joint forces and modal accelerations stay consistent.
Time-only inputs cost one extra evaluation of ``inputs`` per iteration and no extra sweep.
Convergence is quadratic up to the finite-difference accuracy (relative ``~1e-8``), then linear
with a rate of that size.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ..errors import SimulationError
from ..guard import call_user
from ..low_rank import low_rank_solve
from .model import PlanarModel
from .ports import ActuatorInputs

__all__ = ["InputMap", "InputError", "ActuatedNewton"]

#: ``inputs(t, q, qdot)``: actuator values at a state, or ``None`` for none.
InputMap = Callable[[float, np.ndarray, np.ndarray], "ActuatorInputs | None"]

_RELATIVE_STEP = 1e-7


class InputError(SimulationError):
    """The actuator input map of a run raised or returned something other than finite actuator
    values of the model; names the time (``element = "inputs"``)."""


def _zero_inputs(model: PlanarModel) -> ActuatorInputs:
    return ActuatorInputs(np.zeros(model.n_bodies), np.zeros((model.n_bodies, 3)), {})


def _same(a: ActuatorInputs, b: ActuatorInputs) -> bool:
    return (np.array_equal(a.hinge_torque, b.hinge_torque) and np.array_equal(a.body_force, b.body_force)
            and a.modal_force.keys() == b.modal_force.keys()
            and all(np.array_equal(a.modal_force[k], b.modal_force[k]) for k in a.modal_force)
            and a.frame_wrench.keys() == b.frame_wrench.keys()
            and all(np.array_equal(a.frame_wrench[k], b.frame_wrench[k]) for k in a.frame_wrench))


def _combine(base: ActuatorInputs, shifts: list[tuple[ActuatorInputs, float]]) -> ActuatorInputs:
    """``base + sum w (u - base)`` over ``shifts = [(u, w), ...]``."""
    torque, force = base.hinge_torque.copy(), base.body_force.copy()
    modal = {k: np.array(v, dtype=float) for k, v in base.modal_force.items()}
    frame = {k: np.array(v, dtype=float) for k, v in base.frame_wrench.items()}
    for u, weight in shifts:
        torque += weight * (u.hinge_torque - base.hinge_torque)
        force += weight * (u.body_force - base.body_force)
        for k in set(u.modal_force) | set(base.modal_force):
            size = len(u.modal_force.get(k, base.modal_force.get(k)))
            change = u.modal_force.get(k, np.zeros(size)) - base.modal_force.get(k, np.zeros(size))
            modal[k] = modal.get(k, np.zeros(size)) + weight * change
        for k in set(u.frame_wrench) | set(base.frame_wrench):
            change = u.frame_wrench.get(k, np.zeros(3)) - base.frame_wrench.get(k, np.zeros(3))
            frame[k] = frame.get(k, np.zeros(3)) + weight * change
    return ActuatorInputs(torque, force, modal, frame)


class ActuatedNewton:
    """Newton iterations of one run with the actuator input map ``inputs`` (module docstring).

    Parameters
    ----------
    model : PlanarModel
    inputs : callable
        ``inputs(t, q, qdot) -> ActuatorInputs | None`` (``t`` [s], SI state); called at many
        iterates, so it must be a function of its arguments only.
    """

    def __init__(self, model: PlanarModel, inputs: InputMap) -> None:
        self.model = model
        self.inputs = inputs
        self.sweeps = 0

    def evaluate(self, t: float, q: np.ndarray, v: np.ndarray) -> ActuatorInputs:
        """``inputs(t, q, v)`` checked: an :class:`ActuatorInputs` of this model with finite values
        (``None`` -> zeros); else :class:`InputError` naming the time."""
        try:
            value = call_user("inputs(t, q, qdot)", self.inputs, t, q.copy(), v.copy(), time=t)
        except SimulationError as exc:
            raise InputError(str(exc), time=float(t), element="inputs") from exc.__cause__
        if value is None:
            return _zero_inputs(self.model)
        nb = self.model.n_bodies
        if not isinstance(value, ActuatorInputs):
            raise InputError(f"inputs(t, q, qdot) must return ctmm.planar.ports.ActuatorInputs or None "
                                  f"(see actuator_inputs), got {type(value).__name__} at t = {t:.6g} s",
                                  time=float(t), element="inputs")
        arrays = [np.asarray(value.hinge_torque, float), np.asarray(value.body_force, float),
                  *(np.asarray(f, float) for f in value.modal_force.values()),
                  *(np.asarray(f, float) for f in value.frame_wrench.values())]
        if (arrays[0].shape != (nb,) or arrays[1].shape != (nb, 3)
                or not np.isfinite(np.concatenate([a.ravel() for a in arrays])).all()):    # one check for all
            raise InputError(f"inputs(t, q, qdot) returned actuator values of the wrong shape or not "
                                  f"finite at t = {t:.6g} s (hinge torques {arrays[0]!r}, body forces "
                                  f"{arrays[1]!r})", time=float(t), element="inputs")
        return value

    def iterate(self, stepper: Any, q_hat: np.ndarray, v_hat: np.ndarray, t: float, A: Any, F: Any,
                x: np.ndarray) -> tuple[Any, Any, np.ndarray]:
        """One Newton iteration from the acceleration iterate ``x``; returns ``(A, F, x_new)``."""
        bh2, gh = stepper.bh2, stepper.gh
        q, v = q_hat + bh2 * x, v_hat + gh * x
        u0 = self.evaluate(t, q, v)
        tangent = stepper.linearise(q, v, t, A, F, x)
        A_s, F_s, x_s = stepper.solve(tangent, u0)
        self.sweeps += 1
        residual = x_s - x
        scale = _RELATIVE_STEP * max(1.0, float(np.max(np.abs(q), initial=0.0)),
                                     float(np.max(np.abs(v), initial=0.0))) / max(bh2, gh)
        shifts: list[tuple[ActuatorInputs, float]] = []      # input change per unit of each direction

        def product(direction: np.ndarray) -> np.ndarray:
            """``T J direction`` by a directional finite difference of the input map."""
            eps = scale / float(np.max(np.abs(direction)))
            u = self.evaluate(t, q + eps * bh2 * direction, v + eps * gh * direction)
            if _same(u, u0):
                shifts.append((u0, 0.0))
                return np.zeros_like(direction)
            shifts.append((u, 1.0 / eps))
            self.sweeps += 1
            return (stepper.solve(tangent, u)[2] - x_s) / eps

        weights, _ = low_rank_solve(residual, product, len(x))
        if not any(unit for _, unit in shifts):                # no state dependence along the way
            return A_s, F_s, x_s
        extrapolated = _combine(u0, [(u, weight * unit) for (u, unit), weight in zip(shifts, weights)])
        self.sweeps += 1
        return stepper.solve(tangent, extrapolated)          # also the flexible stepper's new iterate

