"""Generated RK4 of planar kinematic loop models (issues 13 and 16): cut joints inside the generated step.

A :class:`~ctmm.planar.closed_loops.KinematicLoopModel` (a spanning tree plus cut joints, ``docs/closed_loops.md``)
compiles here into one generated RK4 step with the projection onto the cut joints after it, the whole time loop in
generated C (:func:`ctmm.generated_loop.compiled_time_loop`).  The step states, on casadi symbols, exactly what
:meth:`KinematicLoopModel.solve` and :meth:`KinematicLoopModel.project` state in numpy:

* the tree's accelerations ``qddot(q, qdot, u, p, t)`` are the generated articulated sweep of
  :func:`ctmm.compiled_scene.symbolic_accelerations_with_inputs` (the element definitions on
  :data:`ctmm.ops.CASADI`), with the cut forces entering as the body forces ``"<body>.force_x"``,
  ``"<body>.force_y"``, ``"<body>.moment"`` of the bodies they act on (force at the centre of mass and the moment
  of its lever, :meth:`KinematicLoopModel.cut_inputs`);
* a cut point on a deformable body (a ``ModalBeam`` end or outboard station, a ``ctmm.fem`` subsystem's outboard
  node) is stated by :mod:`ctmm.compiled_cut_points`: the numpy path's :class:`ctmm.planar.cut_points.CutPoints`
  traced on casadi scalars gives its position, velocity and cross-section angle and turns the cut's force and
  moment into a wrench on the body's floating frame and generalised forces on its internal coordinates (with the
  foreshortening of a bent modal beam's end), which enter the body's element terms
  (:func:`~ctmm.compiled_cut_points.symbolic_accelerations_with_frame_loads`);
* the cut points' positions and velocities are the symbolic kinematics of the tree
  (:class:`ctmm.compiled_planar_sensors.SymbolicKinematics`): ``Phi`` (child point minus parent point [m]), ``Phi'`` and
  the constraint Jacobian ``J = dPhi'/dqdot``;
* one sweep without and ``2 m`` sweeps with unit cut forces give ``qddot = qddot_0 + D lambda`` and the boundary
  compliance ``G = J D``; the relative acceleration of the cut points is ``a_0 = J qddot_0 + (dPhi'/dq) qdot``; the
  cut forces solve ``G lambda = -a_0 - 2 alpha Phi' - alpha^2 Phi`` (Baumgarte rate ``alpha`` [1/s]);
* a cut's moment law and torque add the moment pair ``tau = torque(t) - law(dtheta - rest, dtheta')`` (``+tau``
  on the child body, ``-tau`` on the parent; ``dtheta`` the relative angle of the bodies, :mod:`ctmm.planar.cut_joints`)
  to the applied loads, the law traced on symbols (:attr:`ctmm.nonlinear_laws.Law.expressible`), the torque by its
  symbolic form (:func:`ctmm.signals.symbolic_signal`); a driven cut adds the row ``dtheta - angle(t)`` to ``Phi``
  (``dtheta' - angle_rate(t)`` to ``Phi'``, ``- angle_acceleration(t)`` to ``a_0``), its unknown the drive's moment
  pair, stacked after the cut's force as :meth:`KinematicLoopModel.constraints` stacks them;
* after the RK4 step, ``iterations`` (default 3) minimum-norm Gauss-Newton steps on ``Phi = 0`` at the step's end
  time (``q <- q - J^T (J J^T)^-1 Phi``, skipped once ``max |Phi| < 1e-14``, as the numpy projection stops) and the
  velocity projection ``qdot <- qdot - J^T (J J^T)^-1 Phi'``.

The generated state is ``[q, qdot, residual, condition]``: ``residual`` is the largest ``max |Phi|`` [m] after the
projection of every step so far, ``condition`` the largest Frobenius condition number ``|G|_F |G^-1|_F`` of every RK4
stage so far (:func:`ctmm.loop_integration.compliance_condition`, which the numpy path checks at every stage), so
every step is checked whatever ``store_every``.  The run fails with a :class:`~ctmm.errors.SimulationError` (time,
cut joint, partial result up to the last good stored state) at the first stored state that is not finite, or by
which a projection residual exceeded :data:`~ctmm.loop_integration.PROJECTION_TOLERANCE` or a condition
:data:`~ctmm.loop_integration.CONDITION_LIMIT` (a singular configuration of the loop): the rules and messages of the
numpy RK4 (:mod:`ctmm.loop_integration`), which checks the same after every step.  A deformable body of the tree
beyond its range (the tree runs' rule: a modal beam's deflection bound beyond its length, a ``ctmm.fem`` subsystem
beyond its size) stops it with the numpy RK4's error, time, body and partial rows
(:func:`planar_deformation_failure`: the stored states checked, the steps since the stored row before the first one
beyond it run again by the numpy step).  ``drift`` [m] and ``drift_rate``
[m/s] and the cut forces of the result are those of the stored states (as the numpy path reports them), evaluated by
a generated function of the same library.

Refused (:class:`~ctmm.errors.ModelError`): a tree that :func:`ctmm.compiled_parameters.compile_refusal` refuses,
cut laws that casadi cannot express and torques or drives without a symbolic form (user callables:
:func:`cut_moment_refusal`).  Feedback loops and open-loop inputs on a kinematic loop model run in
:mod:`ctmm.compiled_kinematic_loop_control` on the same closed-loop accelerations (:func:`symbolic_closed_loop`;
cut points on deformable bodies too);
co-simulated controllers keep running in :mod:`ctmm.kinematic_loop_time` (``compiled=True`` refused there by name).
"""
from __future__ import annotations

import os
import time as _time
from typing import Any

import numpy as np

from . import validation
from .codegen import STRAIGHT_LINE_FLAGS
from .compiled_cut_points import (SymbolicCutSides, deformable_bodies, is_deformable_side,
                                  symbolic_accelerations_with_frame_loads)
from .compiled_planar_sensors import SymbolicKinematics
from .compiled_parameters import compile_refusal, parameter_vector
from .compiled_scene import DEFAULT_ROWS, symbolic_accelerations_with_inputs
from .errors import ModelError, SimulationError
from .generated_loop import compiled_time_loop, run_blocks, selected_outputs
from .loop_integration import (CONDITION_LIMIT, PROJECTION_SKIP, PROJECTION_TOLERANCE, check_consistent,
                               compliance_condition, deformation_failure, furthest_cut, projection_failure,
                               singular_compliance)
from .model_description import describe
from .ode import rk4_step
from .planar.closed_loops import KinematicLoopModel, KinematicLoopSimulation
from .planar.elements import Fixed
from .planar.ports import PlanarPorts
from .signals import SYMBOLIC_FIELDS, signal_parameters, symbolic_signal

__all__ = ["CompiledKinematicLoops", "cut_load_refusal", "cut_moment_refusal", "cut_rows", "failure_message",
           "first_failure", "generated_failure", "generated_run", "kinematic_loop_compile_refusal",
           "planar_deformation_failure", "projected_rk4_step", "simulate_kinematic_loops_generated",
           "symbolic_closed_loop", "symbolic_projection", "symbolic_relative_angles", "symbolic_time_signal",
           "tree_refusal"]
_BODY_PARTS = ("force_x", "force_y", "moment")


def _cut_points(model: KinematicLoopModel) -> list[tuple[tuple[int, Any], tuple[int, Any]]]:
    """``[((parent body or -1, end name or ground position), (child body, end name))]`` of the cut joints."""
    tree = model.tree
    grounds = {e.name: np.asarray(e.position, dtype=float) for e in tree.elements if isinstance(e, Fixed)}
    out = []
    for cut in model.cuts:
        pair = []
        for label in (cut.parent, cut.child):
            if label in grounds:
                pair.append((-1, grounds[label]))
            else:
                body, _, end = label.partition(".")
                pair.append((tree.body_names.index(body), end))
        out.append((pair[0], pair[1]))
    return out


def tree_refusal(model: Any, kind: type, kind_label: str, refusal: Any) -> str:
    """Why ``model`` is not a kinematic loop model of ``kind`` (named ``kind_label``) whose spanning tree compiles
    (``refusal(tree)``); an empty string when it is: the first checks of :func:`kinematic_loop_compile_refusal` and
    its spatial counterpart."""
    if not isinstance(model, kind):
        return f"a {kind_label} is compiled here, got {type(model).__name__}"
    reason = refusal(model.tree)
    return f"its tree cannot be compiled: {reason}" if reason else ""


def kinematic_loop_compile_refusal(model: Any) -> str:
    """Why ``model`` cannot run a generated RK4 (this module's, or the loop-closing driver's of
    :mod:`ctmm.compiled_kinematic_loop_control`; an empty string when it can)."""
    reason = tree_refusal(model, KinematicLoopModel, "ctmm.planar.closed_loops.KinematicLoopModel", compile_refusal)
    if reason:
        return reason
    for cut in model.cuts:
        reason = cut_moment_refusal(cut)
        if reason:
            return reason
    return ""


def cut_moment_refusal(cut: Any) -> str:
    """Why the moment law, torque or drive of planar cut joint ``cut`` cannot be stated on symbols (an empty string
    when it can; :func:`cut_load_refusal`)."""
    fields = ("angle", "angle_rate", "angle_acceleration") if cut.driven else ("torque",)
    return cut_load_refusal(cut.name, "moment_law", cut.moment_law, {field: getattr(cut, field) for field in fields})


def cut_load_refusal(name: str, law_label: str, law: Any, signals: dict[str, Any]) -> str:
    """Why cut joint ``name``'s law (field ``law_label``) or time signals (``{field: signal or None}``) cannot be
    stated on symbols, an empty string when they can: a law must be :attr:`ctmm.nonlinear_laws.Law.expressible`, a
    signal a :mod:`ctmm.signals` class with a symbolic form (:data:`ctmm.signals.SYMBOLIC_FIELDS`)."""
    if law is not None and not law.expressible:
        return (f"cut joint {name!r}: its {law_label} {law!r} is not expressible with casadi (user code without "
                "automatic differentiation); give a CallableLaw a casadi-compatible force and no derivatives, or use "
                "compiled=None (the numpy RK4 with projection)")
    for field, signal in signals.items():
        if signal is not None and signal_parameters(signal) is None:
            return (f"cut joint {name!r}: its {field} {signal!r} has no symbolic form (a user callable); allowed "
                    f"in generated code: ctmm.signals {', '.join(kind.__name__ for kind in SYMBOLIC_FIELDS)}; or use "
                    "compiled=None (the numpy RK4 with projection)")
    return ""


def symbolic_time_signal(signal: Any, t: Any) -> Any:
    """The value of a signal with a symbolic form at the time symbol ``t`` (its numbers fixed in the code)."""
    return symbolic_signal(type(signal), t, signal_parameters(signal))


def cut_rows(model: Any) -> list[int]:
    """First row of every planar cut's unknowns and constraints, then their number: 2 per cut (its force), 3 per
    driven cut (the drive's moment after the force), as :meth:`KinematicLoopModel.constraints` stacks them."""
    return [int(row) for row in np.cumsum([0] + [3 if cut.driven else 2 for cut in model.cuts])]


class CompiledKinematicLoops:
    """The generated RK4 with projection of one planar kinematic loop model (module docstring).

    Parameters
    ----------
    model : KinematicLoopModel
        Compilable (:func:`kinematic_loop_compile_refusal`).
    store_every : int
        Steps per stored state [-].
    rows : int
        Stored states per generated block (one C call) [-].
    iterations : int
        Gauss-Newton steps of the projection after every step (as :meth:`KinematicLoopModel.project`: 3).
    cache_dir, compiler
        Of :func:`ctmm.codegen.shared_library`.

    Attributes
    ----------
    parameters : ndarray
        The tree's :func:`ctmm.compiled_parameters.parameter_vector` (the input ``p``).
    state_size : int
        ``2 n + 2``: ``[q, qdot, residual, condition]``.
    compile_time_s : float
        Wall time of building, generating and compiling (or loading from the cache) [s].
    """

    flags: tuple[str, ...] = STRAIGHT_LINE_FLAGS
    """Compiler flags of the kernel (straight-line code, :data:`ctmm.codegen.STRAIGHT_LINE_FLAGS`)."""

    def __init__(self, model: Any, *, store_every: int = 1, rows: int = DEFAULT_ROWS, iterations: int = 3,
                 cache_dir: str | os.PathLike | None = None, compiler: str | None = None) -> None:
        reason = self._refusal(model)
        if reason:
            raise ModelError(f"{type(self).__name__}: {reason}")
        self.store_every = validation.integer("store_every", store_every, minimum=1)
        self.rows = validation.integer("rows", rows, minimum=1)
        self.iterations = validation.integer("iterations", iterations, minimum=1)
        start = _time.perf_counter()
        self.model = model
        self.parameters, self.state_size, name, parts = self._layout()
        description = describe((*parts, self.iterations))
        options = {"cache_dir": cache_dir, "compiler": compiler, "flags": self.flags}
        if description is None:         # something in the tree cannot be described: key on the built functions
            step, extra = self._build()
            loop = compiled_time_loop(step, self.store_every, self.rows, name, extra=extra, **options)
        else:
            loop = compiled_time_loop(self._build, self.store_every, self.rows, name,
                                      description=[("kinematic loop model", description)], **options)
        (self._outputs,), self._step, self._stride, self._blocks = loop.extra, loop.step, loop.stride, loop.blocks
        self.compile_time_s = _time.perf_counter() - start

    @staticmethod
    def _refusal(model: Any) -> str:
        return kinematic_loop_compile_refusal(model)

    def _layout(self) -> tuple[np.ndarray, int, str, tuple]:
        """``(parameters, state size, library name, what the builder reads)``."""
        model, n = self.model, self.model.tree.n_coordinates
        return (parameter_vector(model.tree), 2 * n + 2, f"kinematic_loops_{model.tree.n_bodies}b{n}q{len(model.cuts)}c",
                (model.tree, model.cuts, model.baumgarte, model.foreshortening, "planar kinematic loop rk4"))

    # -- the expressions ------------------------------------------------------------------------------
    def _build(self) -> tuple[Any, list]:
        """``(step, [outputs])`` on symbols: the RK4 step with projection and ``outputs(y, p, t) -> (lambda, Phi,
        Phi', G)``."""
        import casadi as ca

        n, n_p = self.model.tree.n_coordinates, self.parameters.size
        closed, constraint = symbolic_closed_loop(self.model, n_p)
        q, v, p, t = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("p", n_p), ca.SX.sym("t")
        qdd, condition, forces, phi, phi_dot, G = closed(q, v, ca.DM.zeros(0), p, t)
        terms = ca.Function("closed_terms", [ca.vertcat(q, v), p, t], [ca.vertcat(v, qdd), condition, forces, phi,
                                                                        phi_dot, G])
        rate, outputs = selected_outputs(terms, [("closed_rate", (0, 1)), ("outputs", (2, 3, 4, 5))])
        project = symbolic_projection(constraint, n, self.iterations)
        step = projected_rk4_step(rate, project, 2 * n, n_p)
        return step, [outputs]

    # -- running --------------------------------------------------------------------------------------
    def run(self, q0: np.ndarray, v0: np.ndarray, dt: float, n_steps: int) -> tuple[np.ndarray, np.ndarray]:
        """Stored times [s] and states ``[q, qdot, residual, condition]`` (rows, :attr:`state_size`) of ``n_steps``
        steps of ``dt`` [s] from ``(q0, v0)`` at ``t = 0``, the initial state first (its residual and condition
        from the outputs function); the rows after the first non-finite block are not computed."""
        size = self.state_size - 2
        y0 = np.concatenate([q0, v0, [0.0, 0.0]])
        outputs = self._outputs(y0[:size], self.parameters, 0.0)      # lambda, Phi, Phi', G (and more)
        phi, G = outputs[1], outputs[3]
        y0[size] = float(np.max(np.abs(np.asarray(phi))))
        y0[size + 1] = compliance_condition(np.asarray(G))
        states = run_blocks(self._blocks, self._stride, self._step, self.store_every, y0[:, None], np.zeros(0), dt,
                            n_steps, 0.0, self.parameters[:, None])[0]
        steps = np.array([k for k in range(1, n_steps + 1) if k % self.store_every == 0 or k == n_steps])
        steps = steps[:len(states)]
        return np.concatenate([[0.0], steps * dt]), np.vstack([y0[None], states])

    def cut_history(self, t: np.ndarray, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Cut forces (rows, n_cuts, 2) [N], ``Phi`` (rows, constraint rows) [m, rad] and ``Phi'`` [m/s, rad/s] of
        stored times ``t`` [s] and states (rows, at least ``2 n`` columns ``[q, qdot, ...]``), by the generated
        function mapped over the rows (one call)."""
        rows, n, m = len(t), self.model.tree.n_coordinates, len(self.model.cuts)
        starts = cut_rows(self.model)
        if rows == 0:
            return np.zeros((0, m, 2)), np.zeros((0, starts[-1])), np.zeros((0, starts[-1]))
        mapped = self._outputs.map(rows)
        unknowns, phi, phi_dot, _ = mapped(states[:, :2 * n].T, np.repeat(self.parameters[:, None], rows, axis=1),
                                           np.asarray(t, dtype=float)[None, :])
        unknowns = np.asarray(unknowns).T
        forces = np.stack([unknowns[:, start:start + 2] for start in starts[:-1]], axis=1)
        return forces, np.asarray(phi).T.copy(), np.asarray(phi_dot).T.copy()

    def cut_outputs(self, q: np.ndarray, qdot: np.ndarray, t: float = 0.0
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Cut forces (n_cuts, 2) [N], ``Phi`` [m, rad], ``Phi'`` [m/s, rad/s] and the boundary compliance ``G`` at a
        state, by the generated function (as :meth:`KinematicLoopModel.solve` and
        :meth:`~KinematicLoopModel.constraints`)."""
        unknowns, phi, phi_dot, G = self._outputs(np.concatenate([q, qdot]), self.parameters, float(t))
        unknowns = np.asarray(unknowns).reshape(-1)
        forces = np.array([unknowns[start:start + 2] for start in cut_rows(self.model)[:-1]])
        return forces, np.asarray(phi).reshape(-1), np.asarray(phi_dot).reshape(-1), np.asarray(G)


def symbolic_projection(constraint: Any, n: int, iterations: int) -> Any:
    """The projection onto the cut joints of a planar kinematic loop model on symbols (module docstring, as
    :meth:`KinematicLoopModel.project`): ``project(y, t) -> (y projected, max |Phi| after)`` on ``y = [q, qdot]``
    (``n`` coordinates each), ``iterations`` Gauss-Newton steps on ``Phi(q) = 0`` (each skipped once
    ``max |Phi| < PROJECTION_SKIP``), then ``qdot <- qdot - J^T (J J^T)^-1 Phi'``; ``constraint(q, qdot, t) -> (Phi,
    Phi', J)`` of :func:`symbolic_closed_loop`."""
    import casadi as ca

    q, v, t = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("t")
    projected_q = q
    for _ in range(iterations):
        residual, _, J = constraint(projected_q, v, t)
        correction = ca.mtimes(J.T, ca.solve(ca.mtimes(J, J.T), residual))
        skip = ca.mmax(ca.fabs(residual)) < PROJECTION_SKIP
        projected_q = ca.if_else(skip, projected_q, projected_q - correction)
    residual, residual_rate, J = constraint(projected_q, v, t)
    projected_v = v - ca.mtimes(J.T, ca.solve(ca.mtimes(J, J.T), residual_rate))
    return ca.Function("project", [ca.vertcat(q, v), t], [ca.vertcat(projected_q, projected_v),
                                                          ca.mmax(ca.fabs(residual))])


def symbolic_closed_loop(model: KinematicLoopModel, n_parameters: int, extra_actuators: tuple[str, ...] = ()
                         ) -> tuple[Any, Any]:
    """The closed-loop accelerations of a planar kinematic loop model on symbols (module docstring):
    ``closed(q, qdot, u, p, t) -> (qddot, condition, cut unknowns, Phi, Phi', G)`` with the actuator values ``u`` of
    ``extra_actuators`` (the tree's actuators of :class:`~ctmm.planar.ports.PlanarPorts` and the undriven cuts'
    ``"<cut>.torque"``, applied with the cut loads: the cut unknowns react to them), ``p`` the tree's
    ``n_parameters`` numbers; and ``constraint(q, qdot, t) -> (Phi, Phi', J)``."""
    import casadi as ca

    tree, n_p, extra_actuators = model.tree, n_parameters, tuple(extra_actuators)
    n = tree.n_coordinates
    points, sides = _cut_points(model), model.cut_points.sides
    flexible = deformable_bodies(model)
    bodies = sorted({j for pair in points for j, _ in pair if j >= 0 and j not in flexible})
    actuators = [f"{tree.body_names[j]}.{part}" for j in bodies for part in _BODY_PARTS]
    ports = PlanarPorts(tree)
    for k, name in enumerate(actuators):         # the ports' body force is the load the cut force is stated as
        unit = ports.inputs({name: 1.0}).body_force
        if unit[bodies[k // 3], k % 3] != 1.0 or np.count_nonzero(unit) != 1:
            raise ModelError(f"kinematic loop {model.name!r}: actuator {name!r} is not the body force the cut forces "
                             "are stated as")
    cut_torques = [name for name in extra_actuators if name.endswith(".torque") and name[:-7] in
                   {cut.name for cut in model.cuts if not cut.driven}]
    tree_inputs = [name for name in extra_actuators if name not in cut_torques and name not in actuators]
    if flexible:        # cut points on deformable bodies: their loads as frame wrenches (ctmm.compiled_cut_points)
        acceleration = symbolic_accelerations_with_frame_loads(tree, actuators + tree_inputs, flexible)
    else:
        acceleration = symbolic_accelerations_with_inputs(tree, actuators + tree_inputs)
    rows = cut_rows(model)
    q, v, p, t = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("p", n_p), ca.SX.sym("t")
    lam, u = ca.SX.sym("lambda", rows[-1]), ca.SX.sym("u", len(extra_actuators))
    kinematics = SymbolicKinematics(tree, q, v)
    deformable = SymbolicCutSides(model, kinematics)
    phi, phi_dot, drive_acceleration = [], [], []
    loads, moments = [ca.SX(0.0)] * len(actuators), [ca.SX(0.0)] * len(actuators)
    for k, (cut, pair) in enumerate(zip(model.cuts, points)):
        motion, angles = [], []
        for (j, end), side, sign in zip(pair, sides[k], (-1.0, 1.0)):
            if j < 0:
                motion.append((ca.DM(end), ca.DM.zeros(2)))
                angles.append((0.0, 0.0))
                continue
            if is_deformable_side(side):
                motion.append(deformable.motion(side))
                angles.append(deformable.angle(side))
                deformable.add_force(side, sign * lam[rows[k]:rows[k] + 2])
                continue
            position, velocity = kinematics.point(j, end)
            com, _ = kinematics.point(j, "com")
            motion.append((ca.vertcat(*position), ca.vertcat(*velocity)))
            angles.append((kinematics.theta[j], kinematics.omega[j]))
            arm = ca.vertcat(*position) - ca.vertcat(*com)
            f = sign * lam[rows[k]:rows[k] + 2]
            b = 3 * bodies.index(j)
            loads[b] = loads[b] + f[0]
            loads[b + 1] = loads[b + 1] + f[1]
            loads[b + 2] = loads[b + 2] + arm[0] * f[1] - arm[1] * f[0]
        phi.append(motion[1][0] - motion[0][0])
        phi_dot.append(motion[1][1] - motion[0][1])
        drive_acceleration += [0.0, 0.0]
        angle, angle_rate = angles[1][0] - angles[0][0], angles[1][1] - angles[0][1]
        if cut.driven:          # one more row: dtheta = angle(t); its unknown the drive's moment on the child
            phi.append(angle - symbolic_time_signal(cut.angle, t))
            phi_dot.append(angle_rate - symbolic_time_signal(cut.angle_rate, t))
            drive_acceleration.append(symbolic_time_signal(cut.angle_acceleration, t))
            tau = lam[rows[k] + 2]
        elif cut.has_moment or f"{cut.name}.torque" in cut_torques:   # torque(t) + u - law(...): applied
            tau = 0.0 if cut.torque is None else symbolic_time_signal(cut.torque, t)
            if f"{cut.name}.torque" in cut_torques:
                tau = tau + u[list(extra_actuators).index(f"{cut.name}.torque")]
            if cut.moment_law is not None:
                tau = tau - cut.moment_law.force(angle - cut.rest_angle, angle_rate)
        else:
            continue
        for (j, _), side, sign in zip(pair, sides[k], (-1.0, 1.0)):
            if is_deformable_side(side):
                deformable.add_moment(side, sign * tau)
            elif j >= 0:
                b = 3 * bodies.index(j) + 2
                moments[b] = moments[b] + sign * tau
    phi, phi_dot = ca.vertcat(*phi), ca.vertcat(*phi_dot)
    jacobian = ca.jacobian(phi_dot, v)                      # Phi' = J qdot - (drive rates), J = J(q)
    applied = ca.vertcat(*loads) + ca.vertcat(*moments)
    for k, name in enumerate(extra_actuators):      # the tree's own actuators: an input each
        if name in actuators:
            applied[actuators.index(name)] += u[k]
    tree_values = [u[list(extra_actuators).index(name)] for name in tree_inputs]
    unknown = ca.Function("cut_loads", [q, v, t, lam, u], [ca.vertcat(applied, *tree_values, *deformable.loads())])
    qdd0 = acceleration(q, v, unknown(q, v, t, ca.DM.zeros(rows[-1]), u), p, t)
    columns = [acceleration(q, v, unknown(q, v, t, ca.DM.eye(rows[-1])[:, i], u), p, t) - qdd0
               for i in range(rows[-1])]
    D = ca.horzcat(*columns)
    G = ca.mtimes(jacobian, D)
    a0 = ca.mtimes(jacobian, qdd0) + ca.jtimes(phi_dot, q, v) - ca.vertcat(*drive_acceleration)
    alpha = model.baumgarte
    target = -a0 - 2.0 * alpha * phi_dot - alpha * alpha * phi
    forces = ca.solve(G, target)
    qdd = qdd0 + ca.mtimes(D, forces)
    condition = ca.norm_fro(G) * ca.norm_fro(ca.solve(G, ca.SX.eye(rows[-1])))
    closed = ca.Function("closed", [q, v, u, p, t], [qdd, condition, forces, phi, phi_dot, G])
    return closed, ca.Function("constraint", [q, v, t], [phi, phi_dot, jacobian])


def symbolic_relative_angles(model: KinematicLoopModel, kinematics: SymbolicKinematics) -> list[tuple[Any, Any]]:
    """``[(dtheta, dtheta')]`` of every cut on the symbols of ``kinematics`` (of ``model.tree``): the child side's
    angle and rate minus the parent's (0 at the ground; a deformable side's cross-section angle,
    :class:`ctmm.compiled_cut_points.SymbolicCutSides`), as :meth:`KinematicLoopModel.relative_angles`."""
    deformable = SymbolicCutSides(model, kinematics)
    out = []
    for pair in model.cut_points.sides:
        sides = [deformable.angle(side) if is_deformable_side(side) else (0.0, 0.0) if side[0] < 0
                 else (kinematics.theta[side[0]], kinematics.omega[side[0]]) for side in pair]
        out.append((sides[1][0] - sides[0][0], sides[1][1] - sides[0][1]))
    return out


def generated_run(kind: type, model: Any, q: np.ndarray, v: np.ndarray, t_final: float, dt: float, store_every: int,
                  compiled: Any, cache_dir: str | os.PathLike | None) -> tuple[Any, np.ndarray, np.ndarray, float, int]:
    """The generated run of the simulate functions: ``compiled`` checked (an instance of ``kind``, a
    :class:`CompiledKinematicLoops` class, of ``model`` with ``store_every``) or built, the start checked
    (:func:`ctmm.loop_integration.check_consistent`), ``t_final / dt`` steps of ``dt`` [s] (a whole number); ``(compiled, t,
    states, wall time [s], steps)``."""
    if compiled is None:
        compiled = kind(model, store_every=store_every, cache_dir=cache_dir)
    elif not isinstance(compiled, kind) or compiled.model is not model or compiled.store_every != store_every:
        raise ModelError(f"compiled must be a {kind.__name__} of this model with store_every={store_every!r}, got "
                         f"{compiled!r:.80}")
    t_final, h = validation.positive("t_final", t_final), validation.positive("dt", dt)
    check_consistent(model, q, v)
    n_steps = validation.whole_step_count(t_final, h)
    started = _time.perf_counter()
    t, states = compiled.run(np.asarray(q, float), np.asarray(v, float), h, n_steps)
    return compiled, t, states, _time.perf_counter() - started, n_steps


def projected_rk4_step(rate: Any, project: Any, size: int, n_parameters: int) -> Any:
    """The generated ``step(y, u, h, p, t0, k)`` of a kinematic loop model on the state ``[x, residual, condition]``
    (``x`` of ``size``): one RK4 step of ``rate`` (``(x, p, t) -> (x_dot, condition)``) from ``t0 + k h`` by ``h``
    (:func:`ctmm.ode.rk4_step` on symbols), then ``project`` (``(x, t) -> (x, residual)`` at the step's end time
    ``t``); ``residual`` and ``condition``
    carried as the largest so far (the condition of the four stages)."""
    import casadi as ca

    state, u = ca.MX.sym("y", size + 2), ca.MX.sym("u", 0)
    h, p, t0, index = ca.MX.sym("h"), ca.MX.sym("p", n_parameters), ca.MX.sym("t0"), ca.MX.sym("k")
    conditions: list = []

    def stage_rate(stage: Any, x: Any) -> Any:
        x_dot, stage_condition = rate(x, p, stage)
        conditions.append(stage_condition)
        return x_dot

    projected, residual = project(rk4_step(stage_rate, t0 + index * h, state[:size], h), t0 + (index + 1) * h)
    worst = conditions[0]
    for value in conditions[1:]:
        worst = ca.fmax(worst, value)
    carried = ca.vertcat(ca.fmax(state[size], residual), ca.fmax(state[size + 1], worst))     # largest so far
    return ca.Function("step", [state, u, h, p, t0, index], [ca.vertcat(projected, carried)])


def first_failure(states: np.ndarray, size: int) -> int | None:
    """The first stored row of ``[x, residual, condition]`` states (``x`` of ``size``) that is not finite, whose
    residual exceeds :data:`PROJECTION_TOLERANCE` or whose condition exceeds :data:`CONDITION_LIMIT` (``None``)."""
    bad = np.flatnonzero(~np.all(np.isfinite(states), axis=1) | (states[:, size] > PROJECTION_TOLERANCE)
                         | (states[:, size + 1] > CONDITION_LIMIT))
    return int(bad[0]) if bad.size else None


def failure_message(state: np.ndarray, size: int, iterations: int) -> str:
    """What failed in a row :func:`first_failure` found (the messages of :mod:`ctmm.loop_integration`)."""
    if not np.all(np.isfinite(state)):
        return "a non-finite state (a singular loop configuration or divergence)"
    if state[size] > PROJECTION_TOLERANCE:
        return projection_failure(float(state[size]), iterations)
    return singular_compliance(float(state[size + 1]))


def generated_failure(model: Any, label: str, t: np.ndarray, states: np.ndarray, bad: int, size: int,
                      iterations: int, partial: Any) -> SimulationError:
    """The :class:`SimulationError` of the stored row ``bad`` that :func:`first_failure` found in a generated run of
    ``model`` (stored times ``t`` [s], states ``[q, v, residual, condition]`` with ``q, v`` of ``size``): the time, the
    cut joint furthest apart (:func:`ctmm.loop_integration.furthest_cut`; the first cut when the row is not finite)
    and the ``partial`` result up to the last good stored state."""
    cut = model.cuts[0].name
    if np.all(np.isfinite(states[bad])):
        nq = size - model.n_velocities
        cut = furthest_cut(model, model.constraints(states[bad, :nq], states[bad, nq:size], float(t[bad]))[0])
    return SimulationError(f"{label} (generated RK4): {failure_message(states[bad], size, iterations)} by t = "
                           f"{t[bad]} s (after t = {t[bad - 1] if bad else 0.0} s, the last good stored state)",
                           time=float(t[bad]), element=cut, partial_result=partial)


def planar_deformation_failure(model: KinematicLoopModel, t: np.ndarray, states: np.ndarray, bad: int | None,
                               dt: float, iterations: int) -> tuple[int, SimulationError] | None:
    """:func:`ctmm.loop_integration.deformation_failure` of a planar loop model: the tree's
    ``family.check_divergence`` (``"rk4"``, ``dt`` [s]; a modal beam's deflection bound, a ``ctmm.fem`` subsystem's
    size), the numpy step :func:`ctmm.ode.rk4_step`
    then :meth:`KinematicLoopModel.project` with the generated step's Gauss-Newton ``iterations``."""
    tree = model.tree
    family, n = tree.deformable_family, tree.n_coordinates
    if family is None:
        return None

    def beyond(x: np.ndarray, time: float) -> SimulationError | None:
        try:
            family.check_divergence(tree, x[:n], time, dt, "rk4")
        except SimulationError as exc:
            return exc
        return None

    def rate(time: float, x: np.ndarray) -> np.ndarray:
        return np.concatenate([x[n:], model.solve(x[:n], x[n:], time)[0]])

    def step(x: np.ndarray, k: int) -> np.ndarray | None:
        x = rk4_step(rate, (k - 1) * dt, x, dt)
        return np.concatenate(model.project(x[:n], x[n:], k * dt, iterations)) if np.all(np.isfinite(x)) else None

    return deformation_failure(model, t, states, bad, dt, 2 * n, beyond, step)


def simulate_kinematic_loops_generated(model: KinematicLoopModel, q0: Any, qdot0: Any, *, t_final: float, dt: float,
                                       store_every: int = 1, compiled: CompiledKinematicLoops | None = None,
                                       cache_dir: str | os.PathLike | None = None) -> KinematicLoopSimulation:
    """RK4 with projection of a planar kinematic loop model, the time loop in generated C (module docstring).

    The same steps as :func:`ctmm.planar.closed_loops.simulate_kinematic_loops` with ``method="rk4"`` (``t_final / dt``
    steps of ``dt``, a whole number, stored every ``store_every`` and at the last), method label
    ``"rk4-generated"``.

    Parameters
    ----------
    model : KinematicLoopModel
    q0, qdot0 : array_like (n_coordinates,)
        A consistent initial state (``|Phi| <= 1e-8`` m, ``|Phi'| <= 1e-8`` m/s).
    t_final, dt : float
        End time and step [s].
    store_every : int
        Store every k-th step (and the last).
    compiled : CompiledKinematicLoops, optional
        A compiled model of ``model`` with this ``store_every`` to reuse (default: built now, from the kernel cache).
    cache_dir : path, optional
        Of :func:`ctmm.codegen.shared_library`.

    Raises
    ------
    ModelError
        A model that cannot be compiled, bad arguments, an inconsistent initial state.
    SimulationError
        A non-finite state, a failed projection or a singular loop configuration: the time, the cut joint and the
        partial :class:`KinematicLoopSimulation` up to the last good state; a deformable body of the tree beyond its
        range (:func:`planar_deformation_failure`: the numpy RK4's error, time and body).
    """
    q, v = model.tree.state(q0, qdot0)
    compiled, t, states, wall, n_steps = generated_run(CompiledKinematicLoops, model, q, v, t_final, dt, store_every,
                                                       compiled, cache_dir)
    n = model.tree.n_coordinates
    bad = first_failure(states, 2 * n)
    good = len(t) if bad is None else bad
    forces, phi, phi_dot = compiled.cut_history(t[:good], states[:good])
    drift, drift_rate = np.max(np.abs(phi), axis=1), np.max(np.abs(phi_dot), axis=1)
    out_of_range = planar_deformation_failure(model, t, states, bad, validation.positive("dt", dt),
                                              compiled.iterations)
    if out_of_range is not None:
        row, error = out_of_range
        error.partial_result = _simulation(model, t[:row], states[:row], forces[:row], drift[:row], drift_rate[:row],
                                           wall, n_steps)
        raise error
    if bad is not None:
        raise generated_failure(model, f"kinematic loop {model.name!r}", t, states, bad, 2 * n, compiled.iterations,
                                _simulation(model, t[:bad], states[:bad], forces, drift, drift_rate, wall, n_steps))
    return _simulation(model, t, states, forces, drift, drift_rate, wall, n_steps)


def _simulation(model: KinematicLoopModel, t: np.ndarray, states: np.ndarray, forces: np.ndarray, drift: np.ndarray,
                drift_rate: np.ndarray, wall: float, n_steps: int) -> KinematicLoopSimulation:
    n = model.tree.n_coordinates
    return KinematicLoopSimulation(model, np.asarray(t), states[:, :n], states[:, n:2 * n], forces, drift, drift_rate,
                                   "rk4-generated", wall, 4 * n_steps)
