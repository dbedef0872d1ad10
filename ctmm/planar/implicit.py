"""Implicit DT-TMM for planar chains and trees: every :mod:`ctmm.schemes` scheme + Newton.

Each step solves the nonlinear equations of motion at the scheme's evaluation time
``t_n + fraction h`` (``t_{n+1}``; ``t_n + theta h`` for Wilson-theta) in the scheme's
nonlinear second-order form (:meth:`ctmm.schemes.Scheme.second_order_step`,
``docs/planar.md`` section "Every DT-TMM scheme on a planar model")

``q = q_hat + beta' h^2 qdd``,   ``v = v_hat + gamma' h qdd``

with ``qdd`` the acceleration that satisfies them.  Newmark and generalized-alpha use the form
of Arnold & Bruls (FORMULAS 3.1, 3.5), which keeps the equations of motion exact at ``t_{n+1}``:
``a_{n+1} = ((1 - af) qdd_{n+1} + af qdd_n - am a_n) / (1 - am)``,
``q_{n+1} = q_n + h v_n + h^2 (1/2 - beta) a_n + h^2 beta a_{n+1}``,
``v_{n+1} = v_n + h (1 - gamma) a_n + h gamma a_{n+1}``, so
``beta' = beta (1-af)/(1-am)``, ``gamma' = gamma (1-af)/(1-am)`` (Newmark: ``am = af = 0``).
Backward Euler (``forward_euler``, the book's name): ``beta' = gamma' = 1``; Wilson-theta:
``beta' h^2 = tau^2/6``, ``gamma' h = tau/2`` at ``tau = theta h``; Houbolt: ``beta' h^2 = h^2/2``,
``gamma' h = 11 h/12`` after two average-acceleration start-up steps.

Hinge laws are linear in the hinge angle and rate, hence exactly implicit:
``tau = tau_tilde - kappa alpha`` with ``kappa = k beta' h^2 + c gamma' h`` (FORMULAS 3.4).
The geometric nonlinearity (``R(theta)``, ``omega^2``) is solved by **Newton's method**: the
body relations ``A_O = X(theta) A_I + c(theta, omega)`` and
``F_I = K(theta) A_I + b(theta, omega) + sum X^T(theta) F_O`` are linearised about the
current iterate with ``d theta = beta' h^2 d alpha``, ``d omega = gamma' h d alpha``; the
linearised relations keep the transfer form (only the third column of ``X`` and of ``K``
change), so each Newton iteration is one O(n) articulated sweep with a non-symmetric articulated
matrix and the joint tangents ``kappa``: :func:`ctmm.articulated.articulated_sweep`
(:meth:`_NewtonStep.tangent_sweep`; rigid revolute trees through
:class:`ctmm.planar.rigid_sweep.RigidTreeSweep`, the same sweep traced once per structure).
Convergence is quadratic.

Actuator inputs (``inputs=``, :mod:`ctmm.planar.ports`) enter the tangent sweep like loads
(:meth:`_NewtonStep.solve`); their state dependence is added to the Newton tangent by
:mod:`ctmm.planar.actuated_newton`.
"""
from __future__ import annotations

import time as _time
from collections.abc import Callable
from typing import Any

import numpy as np

from .. import validation
from ..articulated import Tree, articulated_sweep
from ..errors import ConvergenceError, ModelError, SimulationError
from ..loop_integration import ProjectionHook
from ..ops import NUMPY
from ..protocol import BodyTerms, JointTerms
from ..schemes import Newmark, Scheme, as_scheme
from .actuated_newton import ActuatedNewton, InputError, InputMap
from .guards import check_scheme, divergence_guard, with_partial
from .integrate import PlanarSimulation, check_store_every, initial_coordinates, step_total, guard_rates
from .model import BUSHING, DRIVEN, REVOLUTE, PlanarModel
from .ports import ActuatorInputs
from .signals import SignalError
from .rigid_sweep import model_sweep
from .hinge_laws import law_kappa, radial_force
from .sweep import accelerations, body_terms, coordinate_accelerations, hinge_torques, solve_instant

_E3 = np.array([[0.0], [0.0], [1.0]])
_I3 = np.eye(3)
_ZERO3 = np.zeros((3, 1))

#: ``after_step(step, t, q, qdot) -> bool``: called once per accepted step (``step`` = 1, 2, ...;
#: ``t`` [s]); returns whether the actuator inputs jumped at ``t`` (held controller outputs).
StepCallback = Callable[[int, float, np.ndarray, np.ndarray], bool]



def name_of(scheme: Any) -> str:
    return type(scheme).__name__.lower()


class _NewtonStep:
    """One implicit step: Newton iterations on the O(n) tangent sweep."""

    def __init__(self, model: PlanarModel, bh2: float, gh: float) -> None:
        self.model = model
        self.bh2, self.gh = bh2, gh
        self.parent = model.parent.tolist()
        self.kind = model.joint_kind.tolist()
        self.has_parent = model.parent >= 0
        self.roots = np.flatnonzero(model.parent < 0)       # bodies on the ground (their parent terms are zero)
        self.p = np.maximum(model.parent, 0)
        self.two_mass = 2.0 * model.mass
        self.gravity = complex(*model.gravity)
        # loads on distinct bodies: added in place (np.add.at accumulates repeated bodies in order)
        self.distinct_loads = len(set(model.load_body.tolist())) == len(model.load_body)
        self.kappa = (model.stiffness * bh2 + model.damping * gh)
        self.kappa_t = (model.translational_stiffness * bh2 + model.translational_damping * gh)
        self.kappa_column = [np.full((1, 1), k) if k else None for k in self.kappa]
        self.children = [np.flatnonzero(model.parent == j).tolist() for j in range(model.n_bodies)]
        self.tree = Tree(tuple(self.parent), tuple(None if p < 0 else j for j, p in enumerate(self.parent)), 3)

    def sweep(self, q, v, t, A, F, x=None, inputs: ActuatorInputs | None = None):
        """Solve the tangent problem linearised about ``(q, v, A, F, qdd = x)``.

        Returns the new body accelerations, joint forces and coordinate accelerations.
        """
        return self.solve(self.linearise(q, v, t, A, F, x), inputs)

    def linearise(self, q, v, t, A, F, x=None) -> dict:
        """The tangent relations about ``(q, v, A, F, qdd = x)``, before actuator inputs (plane vectors as complex
        numbers ``x + i y``, as in :func:`~ctmm.planar.sweep.body_terms`)."""
        m = self.model
        bh2, gh = self.bh2, self.gh
        theta, omega = m.body_angles(q, v, t)
        K, b, E, (rcx, rcy, rx, ry) = body_terms(m, theta, omega, t)
        rc, r = rcx + 1j * rcy, rx + 1j * ry
        alpha = A[:, 2]
        w2 = omega * omega
        # kinematic column of X: d/dtheta (X A_I + c) = -alpha_p r - w_p^2 k x r ; d/dw = -2 w r
        p = self.p
        ap, wp = alpha[p], omega[p]
        g = -((ap + 1j * w2[p]) * r) * bh2 - 2.0 * wp * r * gh       # (gx, gy)
        g[self.roots] = 0.0
        ends = E.view(complex)                 # (k, l, c) of body_terms as complex columns: E[:, 0:2] += g ...
        ends[:, 0] += g
        ends[:, 2] -= g * ap
        # third column of K: d F_I / d theta, d F_I / d omega at fixed A_I, F_O
        mass = m.mass
        ac = (A[:, 0] + 1j * A[:, 1] + alpha * (1j * rc)) - w2 * rc        # centre-of-mass acceleration
        h = mass * ((-alpha - 1j * w2) * rc) * bh2 - self.two_mass * omega * rc * gh     # (hx, hy)
        ht = -(rc.conjugate() * mass * (ac - self.gravity)).real - mass * w2 * (rcx * rcx + rcy * rcy)
        if len(m.load_body):
            loads = m.loads(t)
            lb = m.load_body
            c, s = np.cos(theta[lb]), np.sin(theta[lb])
            rex = c * m.load_point[:, 0] - s * m.load_point[:, 1]
            rey = s * m.load_point[:, 0] + c * m.load_point[:, 1]
            if self.distinct_loads:
                ht[lb] += rex * loads[:, 0] + rey * loads[:, 1]
            else:
                np.add.at(ht, lb, rex * loads[:, 0] + rey * loads[:, 1])
        child_term = (r.conjugate() * (F[:, 0] + 1j * F[:, 1])).real
        child_term[self.roots] = 0.0
        ht -= np.bincount(p, child_term, minlength=m.n_bodies)       # each body's children, in order
        ht *= bh2
        K[:, 2:6:3] += h.view(float).reshape(-1, 2)                   # columns 2, 5: (hx, hy)
        K[:, 8] += ht
        b[:, :2] -= (h * alpha).view(float).reshape(-1, 2)
        b[:, 2] -= ht * alpha
        # exactly implicit hinge laws: tau = tau(iterate) - kappa (alpha_rel - alpha_rel_iterate)
        tau = hinge_torques(m, theta, omega, t)
        ap[self.roots] = 0.0                    # a root's hinge angle is its own
        rel = alpha - ap
        kappa = self.kappa                      # nonlinear hinge laws: their tangent at the iterate (Newton)
        if m.nonlinear_hinges:
            kappa = kappa + law_kappa(m, *m.relative_angles(theta, omega), bh2, gh)
        tau_tilde = tau + kappa * rel
        alpha_d = [0.0] * m.n_bodies
        for i, _, _, acc in m.driven(t):
            alpha_d[i] = acc
        return dict(q=q, v=v, x=x, F=F, theta=theta, alpha=alpha, rc=(rcx, rcy), K=K, b=b, E=E,
                    tau_tilde=tau_tilde, alpha_d=alpha_d, kappa=kappa)

    def solve(self, tangent: dict, inputs: ActuatorInputs | None = None):
        """One O(n) sweep of the tangent relations of :meth:`linearise` with actuator ``inputs``.

        A body force ``f`` at the centre of mass adds ``-(f, r_C x f + M)`` to ``b`` and, since its
        moment turns with the body, ``(r_C . f) beta' h^2`` to the third column of ``K`` (as a load).
        """
        m = self.model
        K, b, tau_tilde = tangent["K"], tangent["b"], tangent["tau_tilde"]
        if inputs is not None and inputs.has_wrench():      # (without: the wrench and its turn are zero)
            rcx, rcy = tangent["rc"]
            force = inputs.body_force
            turn = (rcx * force[:, 0] + rcy * force[:, 1]) * self.bh2
            K, b = K.copy(), b - inputs.inboard_wrench(m, tangent["theta"])
            K[:, 8] += turn
            b[:, 2] -= turn * tangent["alpha"]
        if inputs is not None:
            tau_tilde = tau_tilde + inputs.hinge_torque
        if not len(m.bushing_bodies):           # rigid revolute trees: the sweep traced once per structure
            A_new, F_new, _ = model_sweep(m)(K, b, tangent["E"], tangent["kappa"], tau_tilde, tangent["alpha_d"])
            return A_new, F_new, coordinate_accelerations(m, A_new)
        joint_force, radial_kappa = None, None
        if len(m.bushing_bodies):
            # translational springs, exactly implicit: f = f(iterate) - kappa_t (d'' - d''_iterate)
            xy = m.xy_index
            x = tangent["x"]
            offset, offset_rate = m.bushing_offsets(tangent["q"], tangent["v"])
            joint_force, radial_kappa = {}, {}
            for j in m.bushing_bodies.tolist():
                if j in m.nonlinear_hinges:     # radial spring: its 2 x 2 tangent at the iterate (Newton)
                    f, slope = radial_force(m.nonlinear_hinges[j], offset[j])
                    radial_kappa[j] = -slope * self.bh2
                    joint_force[j] = f + radial_kappa[j] @ np.array([x[xy[j, 0]], x[xy[j, 1]]])
                    continue
                f = -m.translational_stiffness[j] * offset[j] - m.translational_damping[j] * offset_rate[j]
                joint_force[j] = f + self.kappa_t[j] * np.array([x[xy[j, 0]], x[xy[j, 1]]])
        A_new, F_new, translation = self.tangent_sweep(K, b, tangent["E"], tau_tilde, tangent["alpha_d"],
                                                       joint_force, tangent["kappa"], radial_kappa)
        return A_new, F_new, coordinate_accelerations(m, A_new, translation)

    def tangent_sweep(self, K: np.ndarray, b: np.ndarray, E: Any, tau: np.ndarray, alpha_driven: list,
                      joint_force: dict | None, hinge_kappa: np.ndarray | None = None,
                      radial_kappa: dict | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
        """The one articulated sweep (:func:`ctmm.articulated.articulated_sweep`) of the tangent relations.

        Body ``j``: ``M = K_j`` (3 x 3), ``h = b_j``; the point each child ``c`` hangs on has the
        kinematics ``[[1, 0, kx], [0, 1, ky], [0, 0, 1]]``, ``c = (cx, cy, 0)`` and the wrench map
        ``[[1, 0, 0], [0, 1, 0], [lx, ly, 1]]`` of ``E_c`` (the tangent-modified columns).  Joints:
        revolute ``S = e3``, ``tau = tau_tilde``, ``kappa = k beta' h^2 + c gamma' h``; driven;
        free base; translational springs ``S = I3``, ``tau = (f_tilde, tau_tilde)``,
        ``kappa = diag(kappa_t, kappa_t, kappa)``.  Unbatched 2-D matrices (the ``B = 1`` path of ops).

        Returns body accelerations (nb, 3), joint forces (nb, 3) and ``{j: (dx'', dy'')}`` of the
        translational-spring hinges.

        Raises
        ------
        SimulationError
            A singular articulated inertia (naming the joint).
        """
        m = self.model
        nb = m.n_bodies
        E = np.asarray(E, dtype=float).reshape(nb, 6)
        Kin = np.zeros((nb, 3, 3))
        Kin[:, 0, 0] = Kin[:, 1, 1] = Kin[:, 2, 2] = 1.0
        RF = Kin.copy()
        Kin[:, 0, 2], Kin[:, 1, 2] = E[:, 0], E[:, 1]
        RF[:, 2, 0], RF[:, 2, 1] = E[:, 2], E[:, 3]
        c = np.zeros((nb, 3, 1))
        c[:, 0, 0], c[:, 1, 0] = E[:, 4], E[:, 5]
        M, h = np.asarray(K, dtype=float).reshape(nb, 3, 3), np.asarray(b, dtype=float).reshape(nb, 3, 1)
        bodies = [BodyTerms(M[j], h[j], {k: Kin[k] for k in self.children[j]}, {k: c[k] for k in self.children[j]},
                            {k: RF[k] for k in self.children[j]}) for j in range(nb)]
        tau_c = np.asarray(tau, dtype=float).reshape(nb, 1, 1)
        driven_c = np.asarray(alpha_driven, dtype=float).reshape(nb, 1, 1)
        joints, kappa = [], []
        for j, kind in enumerate(self.kind):
            if kind == REVOLUTE:
                joints.append(JointTerms(S=_E3, tau=tau_c[j], axis=2))
                kappa.append(self.kappa_column[j] if hinge_kappa is None or hinge_kappa[j] == self.kappa[j]
                             else np.full((1, 1), hinge_kappa[j]))
            elif kind == DRIVEN:
                joints.append(JointTerms(S=_E3, prescribed=driven_c[j], axis=2))
                kappa.append(None)
            elif kind == BUSHING:
                f = joint_force[j]
                joints.append(JointTerms(S=_I3, tau=np.array([[f[0]], [f[1]], [tau_c[j, 0, 0]]])))
                block = np.diag([self.kappa_t[j], self.kappa_t[j], self.kappa[j] if hinge_kappa is None else hinge_kappa[j]])
                if radial_kappa and j in radial_kappa:
                    block[:2, :2] = radial_kappa[j]
                kappa.append(block)
            else:                                   # free base
                joints.append(JointTerms(S=_I3, tau=_ZERO3))
                kappa.append(None)
        with np.errstate(all="ignore"):
            out = articulated_sweep(NUMPY, self.tree, bodies, joints, kappa)
        A = np.array([x[:, 0] for x in out.x])
        if not np.all(np.isfinite(A)):
            bad = next((j for j in range(nb) if not np.all(np.isfinite(A[j]))), 0)
            raise SimulationError(f"articulated inertia of hinge {m.joint_names[bad]!r} is singular (non-finite "
                                  "accelerations in the Newton tangent sweep)", element=m.joint_names[bad])
        F = np.array([f[:, 0] for f in out.force])
        translation = {j: (float(out.relative[j][0, 0]), float(out.relative[j][1, 0]))
                       for j in m.bushing_bodies.tolist()}
        return A, F, translation


def _stepper(model: PlanarModel, position_weight: float, velocity_weight: float):
    family = model.deformable_family
    if family is not None:
        return family.newton_step(model, position_weight, velocity_weight)
    return _NewtonStep(model, position_weight, velocity_weight)


def simulate_implicit(model: PlanarModel, q0, qdot0, *, t_final: float, dt: float,
                      scheme: Scheme | str | None = None, tolerance: float = 1e-10, max_iterations: int = 20,
                      store_every: int = 1, divergence_bound: float | None = None,
                      stability_check: str = "warn", inputs: InputMap | None = None,
                      after_step: StepCallback | None = None,
                      project: ProjectionHook | None = None) -> PlanarSimulation:
    """Implicit DT-TMM (any :mod:`ctmm.schemes` scheme) with Newton iterations per step.

    Parameters
    ----------
    model : PlanarModel
    q0, qdot0 : array_like
        Initial coordinates and rates.
    t_final, dt : float
        End time and step [s]; ``t_final`` a whole multiple of ``dt``.
    scheme : ctmm.schemes.Scheme or str, optional
        A scheme object or its name (:data:`ctmm.schemes.SCHEMES`: ``"forward_euler"`` (backward
        differences, order 1), ``"newmark"``, ``"wilson_theta"``, ``"houbolt"``,
        ``"generalized_alpha"``).  Default ``Newmark(beta=0.25, gamma=0.5)`` (average acceleration).
        Each is used in its nonlinear form (:meth:`ctmm.schemes.Scheme.second_order_step`,
        ``docs/planar.md``); Wilson-theta imposes the equations of motion at ``t_n + theta dt``
        (every time-dependent input evaluated there) and interpolates back to ``t_n + dt``.
    tolerance : float
        Newton stops when ``max |delta qdd| <= tolerance * (1 + max |qdd|)``.
    max_iterations : int
        Newton iterations allowed per step.
    store_every : int
        Keep every ``store_every``-th step (the last step is always kept), >= 1.
    divergence_bound : float, optional
        As in :func:`~ctmm.planar.integrate.simulate_rk4`.
    stability_check : {"warn", "error", "ignore"}
        Before the run: the step is checked against the scheme's stability limit
        (:meth:`ctmm.schemes.Scheme.stability_limit`: Newmark with ``gamma < 1/2`` is unstable at
        every step, ``2 beta < gamma`` and Wilson-theta with ``theta < 1.37`` are conditionally
        stable) with ``omega_max`` of the linearisation about the initial state, and for
        resolution (:func:`~ctmm.planar.guards.check_scheme`); with ``inputs``, ``omega_max``
        includes their state dependence.
    inputs : callable, optional
        ``inputs(t, q, qdot) -> ActuatorInputs | None``: actuator values
        (:func:`ctmm.planar.ports.actuator_inputs`) added to the model's own loads and hinge laws,
        evaluated at the evaluation time of each step (``t_{n+1}``; ``t_n + theta dt`` for
        Wilson-theta) and at every Newton iterate; a function of its arguments only (it is
        called several times per iteration).  The Newton tangent includes their state
        dependence by directional finite differences (:mod:`ctmm.planar.actuated_newton`), so a
        stiff feedback closed through ``inputs`` converges like the same law in a hinge.
    after_step : callable, optional
        ``after_step(step, t, q, qdot) -> bool``, called once after every accepted step (``step``
        = 1, 2, ..., ``t = step dt`` [s], after the divergence checks, before the step is stored):
        where a stepper samples controllers and appends to a delay history (the inputs of the
        next step may read both).  A true return value says the inputs jumped at ``t`` (new held
        outputs): the acceleration at ``t`` is then solved again with the new inputs and the
        next step starts from it, as a restart of the run at ``t`` would (Houbolt runs its
        start-up again, :meth:`ctmm.schemes.Scheme.restart`).  An exception ends the run as it is (``partial_result`` up to the
        previous stored step).
    project : callable, optional
        ``project(t, q, qdot) -> (q, qdot)``, applied to every accepted step before the divergence checks and
        ``after_step`` (the cut joints of a kinematic loop model: :class:`ctmm.loop_integration.StepProjection`);
        the scheme's history continues from the projected positions and rates (its accelerations are kept).  A
        :class:`~ctmm.errors.SimulationError` it raises ends the run with the ``partial_result``.

    Returns
    -------
    PlanarSimulation
        With ``iterations`` (Newton sweeps per step).

    Raises
    ------
    ModelError
        An unknown scheme name or a scheme without a nonlinear form.
    ConvergenceError
        Naming the step, time, last residual and iteration count.
    SimulationError
        Divergence, a failing user signal (as :func:`~ctmm.planar.integrate.simulate_rk4`) or
        ``inputs`` that raise or return something other than finite actuator values;
        every error carries the :class:`PlanarSimulation` stored so far as ``partial_result``.
    """
    scheme = Newmark() if scheme is None else as_scheme(scheme)
    tolerance = validation.positive("tolerance", tolerance)
    max_iterations = validation.integer("max_iterations", max_iterations, minimum=1)
    store_every = validation.integer("store_every", store_every, minimum=1)
    q, v = initial_coordinates(model, q0, qdot0)
    n_steps = step_total(t_final, dt)
    store_every = check_store_every(store_every)
    h = t_final / n_steps
    guard = divergence_guard(model, q, divergence_bound)
    if inputs is not None and not callable(inputs):
        raise ModelError(f"inputs must be a callable inputs(t, q, qdot) -> ActuatorInputs | None, got {inputs!r}")
    if after_step is not None and not callable(after_step):
        raise ModelError(f"after_step must be a callable after_step(step, t, q, qdot) -> bool, got {after_step!r}")
    if project is not None and not callable(project):
        raise ModelError(f"project must be a callable project(t, q, qdot) -> (q, qdot), got {project!r}")
    actuated = None if inputs is None else ActuatedNewton(model, inputs)
    closed = None if actuated is None else (
        lambda m, qk, vk, t: accelerations(m, qk, vk, t, inputs=actuated.evaluate(t, qk, vk)))
    check_scheme(model, q, v, h, scheme=scheme, policy=stability_check, accelerations=closed)
    family = model.deformable_family
    first = solve_instant(model, q, v, 0.0, inputs=None if actuated is None else actuated.evaluate(0.0, q, v))
    xdd, A, F = first.qddot.copy(), first.body_acceleration, first.joint_force
    history = scheme.start_history(q, v, xdd)
    weights = None
    stepper: Any = None
    ts, qs, vs = [0.0], [q.copy()], [v.copy()]
    iterations = np.zeros(n_steps, dtype=int)
    start = _time.perf_counter()
    evaluations = 1
    try:
        for step in range(n_steps):
            t1 = (step + 1) * h
            plan = scheme.second_order_step(history, h)
            if weights != (plan.position_weight, plan.velocity_weight):   # once, or at a start-up's end
                weights = (plan.position_weight, plan.velocity_weight)
                stepper = _stepper(model, *weights)
                if family is not None:
                    stepper.start(q, v, step * h)
            t_eval = t1 if plan.time_fraction == 1.0 else (step + plan.time_fraction) * h
            q_hat, v_hat = plan.q_predictor, plan.v_predictor
            x = xdd.copy()
            residual = np.inf
            for it in range(1, max_iterations + 1):
                try:
                    if actuated is None:
                        A, F, x_new = stepper.sweep(q_hat + stepper.bh2 * x, v_hat + stepper.gh * x,
                                                    t_eval, A, F, x)
                        evaluations += 1
                    else:
                        before = actuated.sweeps
                        A, F, x_new = actuated.iterate(stepper, q_hat, v_hat, t_eval, A, F, x)
                        evaluations += actuated.sweeps - before
                except (SignalError, InputError):
                    raise
                except (SimulationError, np.linalg.LinAlgError) as exc:
                    raise ConvergenceError(
                        f"implicit DT-TMM step {step + 1} (t = {t1:.6g} s): Newton iteration {it} "
                        f"failed ({exc}); last residual {residual:.3e}; reduce dt", time=t1) from exc
                residual = float(np.abs(x_new - x).max()) if x.size else 0.0
                x = x_new
                if not np.isfinite(residual):
                    break
                if residual <= tolerance * (1.0 + float(np.abs(x).max())):
                    iterations[step] = it
                    break
            else:
                it = max_iterations
            if iterations[step] == 0:
                raise ConvergenceError(
                    f"implicit DT-TMM step {step + 1} (t = {t1:.6g} s) did not converge: residual "
                    f"max|delta qdd| = {residual:.3e} after {it} Newton iterations "
                    f"(tolerance {tolerance:g}); reduce dt", time=t1)
            history = scheme.second_order_update(history, x, h, plan)
            if project is not None:
                history.x, history.v = (np.array(part, dtype=float) for part in project(t1, history.x.copy(),
                                                                                        history.v.copy()))
            q, v = history.x, history.v
            xdd = x
            guard.check(t1, q)
            guard_rates(model, t1, v)
            if family is not None:
                family.check_divergence(model, q, t1, h, name_of(scheme))
            if after_step is not None and after_step(step + 1, t1, q.copy(), v.copy()):
                restart = solve_instant(model, q, v, t1,
                                        inputs=None if actuated is None else actuated.evaluate(t1, q, v))
                evaluations += 1
                xdd, A, F = restart.qddot.copy(), restart.body_acceleration, restart.joint_force
                history.a = xdd.copy()
                history.equation_acceleration = xdd.copy()
                scheme.restart(history)             # a multistep scheme (Houbolt) starts up again
            if (step + 1) % store_every == 0 or step + 1 == n_steps:
                ts.append(t1)
                qs.append(q.copy())
                vs.append(v.copy())
    except SimulationError as exc:
        raise with_partial(exc, lambda: PlanarSimulation(
            model, np.array(ts), np.array(qs), np.array(vs), f"dt-tmm/{type(scheme).__name__}",
            _time.perf_counter() - start, iterations=iterations.copy(),
            n_evaluations=evaluations)) from exc.__cause__
    wall = _time.perf_counter() - start
    name = type(scheme).__name__
    return PlanarSimulation(model, np.array(ts), np.array(qs), np.array(vs), f"dt-tmm/{name}",
                            wall, iterations=iterations, n_evaluations=evaluations)


__all__ = ["simulate_implicit", "StepCallback"]
