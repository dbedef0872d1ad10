"""An O(N) iteration for the generated DT-TMM schemes of planar models: one implicit articulated sweep (issue 13).

The generated scheme step (:mod:`ctmm.compiled_scene_schemes`) solves, with ``q = q_hat + w a``,
``v = v_hat + g a`` (``w = b' h^2`` [s^2], ``g = g' h`` [s]), the equations of motion

``M(q) a + b(q, v) = tau_law(q, v) + f(q, v, t)``

for the accelerations ``a`` (``tau_law`` the hinge laws, ``f`` gravity, loads and inputs).  Its ``"mapped"`` and
``"symbolic"`` tangents form the ``n x n`` Newton tangent and factor it: O(N^2) .. O(N^3) per iterate.  Here each
iterate is **one articulated sweep** (O(N)):

``a_(k+1) = (M(q_k) + g C + w K)^-1 (tau_law(q_hat, v_hat) + f(q_k, v_k, t) - b(q_k, v_k))``

with ``K = -d tau_law/dq_rel``, ``C = -d tau_law/dv_rel`` the joint laws' stiffness and damping: the articulated
sweep of the model at the iterate ``(q_k, v_k)`` whose joints carry the tangent ``kappa = w K + g C`` in their
pivots ``D`` (:func:`ctmm.articulated.articulated_sweep`, the Python stepper's ``kappa = k b' h^2 + c g' h``) and
whose laws are evaluated at the predictor.  For laws linear in the relative angle and rate (a relative coordinate
that is linear in ``q``), ``tau_law(q, v) = tau_law(q_hat, v_hat) - (w K + g C) a_rel``, so the sweep solves the
laws **exactly** (implicitly).  Each body's own coordinates (its absolute angle, the body's ``alpha`` in its
unknowns ``x_j = [A_in; eta'']``, and its modal coordinates) enter its terms implicitly too: with
``T = d h_j / d a_own`` and ``S_e = d c_e / d a_own`` (through ``q(a), v(a)``: ``w`` times the stiffness, ``g``
times the damping of the modal forces, gravity and the velocity products), ``M_j[:, own] += T``,
``h_j -= T a_own``, ``Kin_e[:, own] += S_e``, ``c_e -= S_e a_own`` (the Python stepper's third column of ``K``, in
part).  What stays frozen at the iterate is the configuration dependence of the inertia and of the outboard
points' kinematics times the unknown accelerations and forces.

* **Same root.**  A fixed point ``a = a_(k+1) = a_k`` satisfies the equations of motion at ``q(a), v(a)``: the
  root of the residual ``r(a) = a - qddot(q(a), v(a))`` the other tangents solve.
* **Convergence.**  It is Newton's method on the mass-weighted residual ``R(a) = M(q) r(a)`` (the Python stepper's,
  :mod:`ctmm.compiled_newton_weighting`) with those terms of its tangent dropped (``O(w |a|)`` relative to the
  inertia), so it converges linearly, fast at small steps (pendulum chains at ``dt = 1 ms``: ~5 iterates per step
  with the stop below) and more slowly at large ones: a 10-link chain moving at ~2 rad/s needed up to ~40 iterates
  at ``dt = 20 ms`` (Newton 4), so it may take :data:`ITERATIONS_PER_NEWTON` times ``max_iterations`` iterates
  (each one sweep, far cheaper than a Newton iteration's ``2 n`` directional derivatives and factorization).
* **Stop.**  The stopping rule of the other tangents, ``max |a_(k+1) - a_k| <= tolerance (1 + max |a_(k+1)|)``,
  and a stricter one, since the error of ``a_(k+1)`` is the contraction factor times the last change (Newton's:
  the change squared): the change times its ratio to the previous one (the factor's estimate; 1 at the first
  iterate) at most :data:`ERROR_FRACTION` of that bound.  With the common rule alone the generated answer left the
  numpy stepper's by 3.5e-10 in the rates on a stiff bushing (``k = 2e5 N/m``, Newmark, dt = 1 ms; mapped tangent
  2.6e-12); with both, 2.3e-11 at about one iterate more per step.  Not converging in those iterates stays a
  :class:`~ctmm.errors.ConvergenceError` naming the step, time and residual
  (:func:`ctmm.compiled_scene_schemes.not_converged`).

Scope (:func:`sweep_refusal`, a :class:`~ctmm.errors.ModelError` otherwise): planar models without loops whose
joint laws are linear (no :class:`~ctmm.planar.hinge_laws.NonlinearHinge`, no radial bushing law); rigid bodies,
modal beams, bushings, free bases.  Foldable chains sweep folded
(:func:`ctmm.compiled_scene_fold.folded_acceleration` with ``implicit=True``: the joint laws implicit, the bodies'
own terms frozen, which converged in ~5.5 iterates per step on the pendulum chains at 1 ms).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any, Sequence

import numpy as np

from .articulated import articulated_sweep
from .compiled_parameters import parameter_vector, symbolic_numbers
from .compiled_scene import coordinate_accelerations
from .compiled_scene_fold import folded_accelerations_with_inputs
from .compiled_station_loads import symbolic_terms_with_station_loads
from .errors import ModelError
from .ops import CASADI
from .planar.model import PlanarModel
from .planar.ports import PlanarPorts

__all__ = ["ERROR_FRACTION", "ITERATIONS_PER_NEWTON", "STALLED_RATIO", "SWEEP", "iteration_count", "implicit_accelerations", "sweep_iteration", "sweep_refusal"]

SWEEP = "sweep"
"""The name of this iteration among the generated planar schemes' tangents (``tangent="sweep"``)."""
ITERATIONS_PER_NEWTON = 4
"""Iterates of this linear iteration a generated step may take per Newton iteration allowed (``max_iterations``)."""
ERROR_FRACTION = 1e-4
"""The iteration stops when, besides the common rule, its estimated remaining error ``|delta a_k| (|delta a_k| /
|delta a_(k-1)|)`` (linear convergence) is at most this fraction of ``tolerance (1 + max |a|)`` (module docstring)."""
STALLED_RATIO = 0.5
"""... or when the changes no longer shrink by this ratio (the iteration at its round-off floor, or contracting too
slowly for the estimate): then the common rule alone, as the other tangents."""


def iteration_count(tangent: str | None, max_iterations: int) -> int:
    """Iterates a generated step with this ``tangent`` may take for ``max_iterations`` Newton iterations allowed:
    :data:`ITERATIONS_PER_NEWTON` times as many for ``"sweep"``."""
    return int(max_iterations) * (ITERATIONS_PER_NEWTON if tangent == SWEEP else 1)


def sweep_refusal(model: PlanarModel, loops: Any = None) -> str:
    """Why the implicit-sweep iteration does not apply to ``model`` (``""``: it does).  ``loops``: the closed loops
    of the step (``None``: none)."""
    if loops is not None:
        return "feedback loops (their controller terms are not in the implicit sweep)"
    if model.nonlinear_hinges:
        names = [model.joint_names[j] for j in sorted(model.nonlinear_hinges)]
        return f"nonlinear hinge laws {names} (the sweep solves linear laws implicitly)"
    return ""


def implicit_accelerations(model: PlanarModel, actuators: Sequence[str], period: int = 0) -> Any:
    """``implicit(a, q_hat, v_hat, w, g, u, p, t) -> a_next`` (casadi ``Function``): the articulated sweep at
    ``q = q_hat + w a``, ``v = v_hat + g a`` with the joint laws at ``(q_hat, v_hat)`` and the joint tangents
    ``kappa = -(w tau_q + g tau_v)`` in the pivots, and each modal body's elastic terms made implicit by their
    tangent ``T = d h_e / d eta''`` (``w K + g D`` of its modal stiffness and damping, through ``q(a), v(a)``) added
    to its modal block ``C`` with ``h_e - T eta''(a)`` (module docstring), the inputs ``u`` of the ports
    ``actuators``; folded over segments of ``period`` bodies (0: straight-line code).  ``a_next = a`` exactly where
    ``a`` solves the equations of motion.

    Raises
    ------
    ModelError
        A model :func:`sweep_refusal` refuses.
    """
    import casadi as ca

    reason = sweep_refusal(model)
    if reason:
        raise ModelError(f"tangent='sweep': not for a model with {reason}; use tangent='mapped' or 'symbolic'")
    n, n_p = model.n_coordinates, parameter_vector(model).size
    a, q_hat, v_hat = (ca.SX.sym(label, n) for label in ("a", "q_hat", "v_hat"))
    w, g, u, p, t = ca.SX.sym("w"), ca.SX.sym("g"), ca.SX.sym("u", len(actuators)), ca.SX.sym("p", n_p), ca.SX.sym("t")
    q, v = q_hat + w * a, v_hat + g * a
    if period:
        folded = folded_accelerations_with_inputs(model, actuators, (), period, implicit=True)
        a_mx, q_mx, v_mx = (ca.MX.sym(label, n) for label in ("a", "q_hat", "v_hat"))
        w_mx, g_mx, t_mx = ca.MX.sym("w"), ca.MX.sym("g"), ca.MX.sym("t")
        u_mx, p_mx = ca.MX.sym("u", len(actuators)), ca.MX.sym("p", n_p)
        return ca.Function("implicit_acceleration", [a_mx, q_mx, v_mx, w_mx, g_mx, u_mx, p_mx, t_mx], [folded(
            q_mx + w_mx * a_mx, v_mx + g_mx * a_mx, q_mx, v_mx, w_mx, g_mx, u_mx, p_mx, t_mx)])
    ports = PlanarPorts(model)
    units = [ports.inputs({name: 1.0}) for name in actuators]
    numbers = symbolic_numbers(model, p, t)
    scene, bodies, joints = symbolic_terms_with_station_loads(model, units, q, v, u, numbers)
    _, _, laws = symbolic_terms_with_station_loads(model, units, q_hat, v_hat, u, numbers)
    implicit, kappa = [], []
    for joint, law in zip(joints, laws):
        if joint.tau is None:                       # driven, weld
            implicit.append(joint)
            kappa.append(None)
            continue
        size = int(joint.tau.numel())
        stiffness = joint.tau_q if joint.tau_q is not None else ca.SX.zeros(size, size)
        damping = joint.tau_v if joint.tau_v is not None else ca.SX.zeros(size, size)
        implicit.append(replace(joint, tau=law.tau))
        kappa.append(-(w * stiffness + g * damping))
    for j, index in enumerate(model.modal_index):   # M[:, own] += T, h -= T a_own, T = d h / d a_own
        own = ([(2, int(model.theta_index[j]))] if model.theta_index[j] >= 0 else []) + \
            [(3 + c, int(i)) for c, i in enumerate(index)]
        if own:
            body = bodies[j]
            rates = ca.vertcat(*[a[i] for _, i in own])
            tangent = ca.jacobian(body.h, rates)
            mass, kinematics, products = ca.SX(body.M), {}, {}
            for column, (position, _) in enumerate(own):
                mass[:, position] = mass[:, position] + tangent[:, column]
            for point, c in body.c.items():        # the outboard points' velocity products: A_O = Kin x + c(a)
                if c is None:
                    kinematics[point], products[point] = body.Kin[point], c
                    continue
                slope, kinematics[point] = ca.jacobian(c, rates), ca.SX(body.Kin[point])
                for column, (position, _) in enumerate(own):
                    kinematics[point][:, position] = kinematics[point][:, position] + slope[:, column]
                products[point] = c - ca.mtimes(slope, rates)
            bodies[j] = replace(body, M=mass, h=body.h - ca.mtimes(tangent, rates), Kin={**body.Kin, **kinematics},
                                c={**body.c, **products})
    solution = articulated_sweep(CASADI, scene.tree, bodies, implicit, kappa)
    return ca.Function("implicit_acceleration", [a, q_hat, v_hat, w, g, u, p, t],
                       [coordinate_accelerations(model, solution.x, solution.relative)])


def sweep_iteration(model: PlanarModel, actuators: Sequence[str], period: int, tolerance: float,
                    loops: Any = None) -> Any:
    """One iteration of the implicit sweep as the casadi ``Function``
    ``(z, q_hat, v_hat, w, g, t, u, p, c, s) -> z`` of :func:`ctmm.compiled_scene_schemes.newton_iteration`
    (``z = [a; converged; max |delta a|; iterations]``, a converged ``z`` returned unchanged): ``a <-``
    :func:`implicit_accelerations` at ``q_hat + w a, v_hat + g a``, converged when ``max |delta a| <= tolerance
    (1 + max |a|)``.  ``c``, ``s`` (loop controller entries, time since the step start) are not read.

    Raises
    ------
    ModelError
        A model or loops :func:`sweep_refusal` refuses.
    """
    import casadi as ca

    reason = sweep_refusal(model, loops)
    if reason:
        raise ModelError(f"tangent='sweep': not for a model with {reason}; use tangent='mapped' or 'symbolic'")
    implicit = implicit_accelerations(model, actuators, period)
    n = model.n_coordinates
    z, q_hat, v_hat = ca.MX.sym("z", n + 3), ca.MX.sym("q_hat", n), ca.MX.sym("v_hat", n)
    w, g, t, s = ca.MX.sym("w"), ca.MX.sym("g"), ca.MX.sym("t"), ca.MX.sym("s")
    u, p, c = ca.MX.sym("u", len(actuators)), ca.MX.sym("p", implicit.sparsity_in(6)), ca.MX.sym("c", 0)
    a = z[:n]
    new = implicit(a, q_hat, v_hat, w, g, u, p, t)
    change = ca.if_else(ca.sum1(ca.fabs(new - a)) < np.inf, ca.mmax(ca.fabs(new - a)), np.inf) if n else ca.MX(0.0)
    scale = tolerance * (1.0 + (ca.mmax(ca.fabs(new)) if n else 0.0))
    ratio = ca.if_else(z[n + 1] < np.inf, change / z[n + 1], 1.0)        # contraction estimate (first: 1)
    converged = ca.logic_and(change <= scale, ca.logic_or(change * ratio <= ERROR_FRACTION * scale,
                                                          ratio >= STALLED_RATIO))
    arguments = [q_hat, v_hat, w, g, t, u, p, c, s]
    step = ca.Function("sweep_iteration", [z, *arguments], [ca.vertcat(new, converged, change, z[n + 2] + 1.0)])
    return ca.Function("sweep_or_done", [z, *arguments], [ca.if_else(z[n], z, step(z, *arguments), True)])
