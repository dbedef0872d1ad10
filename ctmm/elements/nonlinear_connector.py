"""A massless 1-D connector with a nonlinear law: :class:`NonlinearSpring` (seed 002 section 7.6.1).

The connector transmits ``f = -law.force(x_out - x_in - l, v_out - v_in) + F`` to its outboard point
(``F``: the actuator input ``"force"`` across it), with any :class:`~ctmm.nonlinear_laws.Law`
(``CubicSpring`` -- a Duffing chain --, ``ClearanceSpring``, ``PowerDamper``, their sums, ``CallableLaw``).
Its joint terms (:meth:`NonlinearSpring.terms`) carry the law's value and analytic tangents at the given
kinematics; derivation in ``docs/elements/lumped.md`` §"Nonlinear connector".

* **Time, DT-TMM** (:class:`DiscreteNonlinearSpring`): the step's transfer matrix is the connector's,
  linearised about a point ``(e_k, r_k)`` of elongation and rate at the step's evaluation level,

      k_eff = k_t cx + c_t A,   U12 = -1 / k_eff,
      u0 = (-f_k - k_t (ddx - e_k) - c_t (dB - r_k) + F) / k_eff    (k_t, c_t, f_k: the law at (e_k, r_k))

  which is exactly the linear connector's step when the law is linear.  The stepper iterates
  (:func:`newton_step`): it solves the chain's step with the point at the predictor, moves the point to the
  solution's elongation and rate and solves again, until the point no longer moves -- Newton's method on
  the step's nonlinear equations with the exact tangent (quadratic convergence), the number of iterations
  reported.
* **Time, ODE methods** (``"rk4"``, ``solve_ivp``; :mod:`ctmm.chain_ode`): the explicit context evaluates
  the terms at the state, so the law enters as it is; a nonlinear connector next to a massless point is
  refused there (its static condensation reads the tangent once).
* **Frequency**: the frequency forms (``U(s)``, natural frequencies, frequency responses) are those of the
  connector linearised about its static operating point ``operating_deflection`` (the deflection ``x_out -
  x_in - l`` [m] in the chain's static equilibrium): tangent stiffness and damping there.  Without it they are
  refused by name (the chain's frequency path has no operating point of its own), and so are the lumped fast
  paths (the connector has no constant coefficients: :meth:`NonlinearSpring.lumped_coefficients` is None).
"""
from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from ..nonlinear_laws import Law
from ..ops import Ops
from ..protocol import JointTerms
from .axial import AxialCoefficients, AxialJoint
from .base import DiscreteElement, Linearisation

__all__ = ["NonlinearSpring", "DiscreteNonlinearSpring", "newton_step"]

MAX_ITERATIONS = 25
"""Newton iterations allowed per DT-TMM step."""


class NonlinearSpring(AxialJoint):
    """Massless connector with a nonlinear law ``f(deflection, rate)`` (module docstring).

    Parameters
    ----------
    name : str
        Element name.
    law : Law
        Restoring force [N] of the deflection [m] and its rate [m/s] (:mod:`ctmm.nonlinear_laws`).
    free_length : float
        Free length ``l`` [m]: the deflection is ``x_out - x_in - l``.
    operating_deflection : float, optional
        The deflection [m] in the chain's static equilibrium, about which the frequency forms are linearised
        (e.g. 0 for a chain without static load through the connector); ``None``: frequency forms refused.
    """

    inputs = ("force",)
    inertance = 0.0          # [kg]: massless

    def __init__(self, name: str, law: Law, *, free_length: float = 0.0,
                 operating_deflection: float | None = None) -> None:
        super().__init__(name)
        if not isinstance(law, Law):
            raise ModelError(f"{name}: law must be a ctmm.nonlinear_laws.Law (CubicSpring, ClearanceSpring, "
                             f"PowerDamper, CallableLaw, ...), got {law!r}")
        self.law = law
        self.free_length = validation.finite(f"{name}: free_length", free_length)
        self.operating_deflection = (None if operating_deflection is None else
                                     validation.finite(f"{name}: operating_deflection", operating_deflection))

    def terms(self, ops: Ops, q_rel: Any, v_rel: Any, t: float = 0.0,
              u: Mapping[str, Any] | None = None) -> JointTerms:
        """The law as joint terms at the elongation ``q_rel`` [m] and its rate ``v_rel`` [m/s].

        Returns
        -------
        JointTerms
            ``S = [1]``, ``tau = -f(q_rel - l, v_rel) + F`` [N] (force on the outboard point),
            ``tau_q = -df/ddeflection``, ``tau_v = -df/drate`` at these kinematics.
        """
        force = (u or {}).get("force", 0.0)
        deflection = q_rel - self.free_length
        stiffness, damping = self.law.tangents(deflection, v_rel)
        zero = ops.zeros(1, 1)
        return JointTerms(S=ops.eye(1), tau=zero - self.law.force(deflection, v_rel) + force,
                          tau_q=zero - stiffness, tau_v=zero - damping)

    def transmitted_force(self, elongation: float, rate: float, across: float = 0.0) -> float:
        """Force [N] on the outboard point at elongation ``x_out - x_in`` [m] and rate [m/s]."""
        return float(-self.law.force(elongation - self.free_length, rate) + across)

    def axial_coefficients(self) -> AxialCoefficients:
        """Tangent coefficients at the operating deflection (frequency forms); refused without one."""
        if self.operating_deflection is None:
            raise ModelError(f"{self.name}: a NonlinearSpring has no constant coefficients; its frequency forms "
                             "(transfer matrix, natural frequencies, frequency responses, linearisation) need the "
                             "static operating point: give operating_deflection=<deflection in the static "
                             "equilibrium [m]> (0 when no static load passes through it)")
        stiffness, damping = self.law.tangents(self.operating_deflection, 0.0)
        if stiffness < 0.0 or damping < 0.0:
            raise ModelError(f"{self.name}: the tangent of its law at operating_deflection={self.operating_deflection} "
                             f"is negative (k_t = {stiffness}, c_t = {damping}); the frequency forms need k_t, c_t >= 0")
        return AxialCoefficients(0.0, float(damping), float(stiffness), 0.0, {"force": 1.0})

    def lumped_coefficients(self) -> None:
        """None: the connector has no constant coefficients (the lumped fast paths do not take it)."""
        return None

    def discretize(self, scheme: Any) -> "DiscreteNonlinearSpring":
        return DiscreteNonlinearSpring(self)

    def parameters(self) -> dict[str, Any]:
        return {"law": self.law, "free_length": self.free_length, "operating_deflection": self.operating_deflection}


class DiscreteNonlinearSpring(DiscreteElement):
    """DT-TMM form of a :class:`NonlinearSpring`: linearised about its Newton point (module docstring).

    The point ``(e_k, r_k)`` (elongation [m] and rate [m/s] at the evaluation level) is stepper state of one
    run, set by :func:`newton_step`.
    """

    newton = True

    def __init__(self, element: NonlinearSpring) -> None:
        self.element = element
        self.point: tuple[float, float] | None = None        # set by newton_step during a step only

    def step_matrices(self, t: float, inboard: Linearisation, outboard: Linearisation, force: float = 0.0):
        law, free = self.element.law, self.element.free_length
        if self.point is None:
            raise ModelError(f"{self.element.name}: a NonlinearSpring is stepped by the DT-TMM Newton iteration of "
                             "ctmm.simulate on a plain chain or one with delayed loops only (newton_step); a chain with "
                             "real-time loops, co-simulated controllers or bending beams does not take it yet")
        e_k, r_k = self.point
        ddx, dB = float(outboard.dx - inboard.dx), float(outboard.B - inboard.B)
        stiffness, damping = (float(value) for value in law.tangents(e_k - free, r_k))
        k_eff = stiffness * inboard.cx + damping * inboard.A
        if not k_eff > 0.0:
            raise SimulationError(f"{self.element.name}: the law's tangent at deflection {e_k - free:.6g} m, rate "
                                  f"{r_k:.6g} m/s gives k_eff = k_t cx + c_t A = {k_eff:.6g} <= 0 at t = {t:.6g} s: "
                                  "the step's transfer matrix does not exist (a clearance without damping, a "
                                  "softening law beyond its peak); add damping or use an ODE method",
                                  time=float(t), element=self.element.name)
        f_k = float(law.force(e_k - free, r_k))
        U = np.eye(2)
        U[0, 1] = -1.0 / k_eff
        u = np.array([(-f_k - stiffness * (ddx - e_k) - damping * (dB - r_k) + force) / k_eff, 0.0])
        return U, u


def newton_step(solve: Callable[[], tuple[np.ndarray, np.ndarray]], discrete: Sequence[DiscreteElement],
                coefficients: Any, t: float, iterations: list[int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """One DT-TMM step of a chain with nonlinear connectors: Newton on their linearisation points.

    Parameters
    ----------
    solve : callable
        ``solve() -> (delta, forces)``: the chain's linear step with the elements' current step matrices
        (``delta``: the step's unknown per point, shape ``(n_points,)``).
    discrete : sequence of DiscreteElement
        The chain's discrete elements (position ``j`` joins points ``j - 1`` and ``j``).
    coefficients : StepCoefficients
        The step's scheme coefficients (:meth:`ctmm.schemes.Scheme.coefficients`): ``x = cx delta + dx``,
        ``v = A delta + B`` at the evaluation level, ``dx``, ``B`` of shape ``(n_points, 1)``.
    t : float
        Evaluation time [s] (messages).
    iterations : list, optional
        The number of iterations of the step is appended to it.

    Returns
    -------
    delta, forces
        As returned by the converged ``solve``.

    Raises
    ------
    SimulationError
        No convergence in :data:`MAX_ITERATIONS` iterations (time and element named).
    """
    dx = np.asarray(coefficients.dx, dtype=float)[:, 0]
    B = np.asarray(coefficients.B, dtype=float)[:, 0]
    cx, A = float(coefficients.cx), float(coefficients.A)
    nonlinear = [(j, disc) for j, disc in enumerate(discrete, start=1) if getattr(disc, "newton", False)]
    for j, disc in nonlinear:                           # start at the predictor (unknowns zero)
        disc.point = (dx[j] - dx[j - 1], B[j] - B[j - 1])
    try:
        return _iterate(solve, nonlinear, dx, B, cx, A, t, iterations)
    finally:
        for _, disc in nonlinear:
            disc.point = None


def _iterate(solve, nonlinear, dx, B, cx, A, t, iterations):
    change, worst = np.inf, nonlinear[0][1]
    for iteration in range(1, MAX_ITERATIONS + 1):
        delta, forces = solve()
        relative = np.diff(np.asarray(delta, dtype=float).reshape(len(dx), -1)[:, 0])
        change = 0.0
        for j, disc in nonlinear:
            point = (cx * relative[j - 1] + dx[j] - dx[j - 1], A * relative[j - 1] + B[j] - B[j - 1])
            # the rate moves by A / cx times the elongation (both follow the one unknown): testing it as well
            # only amplified the round-off of the unknown by ~1 / h, so small steps never converged
            moved = abs(point[0] - disc.point[0]) / (1.0 + abs(point[0]))
            if moved > change:
                change, worst = moved, disc
            disc.point = point
        if change <= 1e-12:          # the elongation moved by less than 1e-12 (1 + |e|) [m]: converged
            if iterations is not None:
                iterations.append(iteration)
            return delta, forces
    raise SimulationError(f"the Newton iteration of the nonlinear connector {worst.element.name!r} did not converge "
                          f"at t = {t:.6g} s in {MAX_ITERATIONS} iterations (last move {change:.3e} relative); "
                          "reduce dt", time=float(t), element=worst.element.name)
