"""Generated RK4 of spatial kinematic loop models (issues 13 and 16): cut joints inside the generated step.

The spatial counterpart of :mod:`ctmm.compiled_kinematic_loops`: a
:class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel` compiles into one generated RK4 step with the
projection onto the cut joints after it, the time loop in generated C.  On casadi symbols, as
:meth:`SpatialKinematicLoopModel.solve` and :meth:`~SpatialKinematicLoopModel.project` state them in numpy:

* the tree's velocity rates are the generated articulated sweep of its terms on :data:`ctmm.ops.CASADI`
  (:class:`ctmm.spatial.body_forms.SpatialScene`), the cut loads applied as wrenches at the cut points (the force
  ``lambda`` [N] on the child point -- prismatic: ``lambda_j p_j`` -- and for revolute, universal and prismatic cuts
  the moments ``mu_i n_i`` [N m], ``n_i = u_i x b_i``; their opposites on the parent, a prismatic cut's force at the
  child point, i.e. at the parent point with the moment ``d x f`` added), so ``1 + m`` sweeps give
  ``v' = v'_0 + D lambda``;
* ``Phi`` and ``Phi'`` from the same terms' body states at the time symbol (separation ``d = x_c - x_p`` [m] --
  prismatic: ``d . p_j`` -- and alignments ``u_i . b_i``),
  ``J = dPhi'/dv``, ``Phi'' = J v' + (dPhi'/dq) G(q) v + (dPhi'/dtheta) rate(t) + (dPhi'/dtheta') acceleration(t)``
  (``q_dot = G(q) v``, quaternions; ``theta``, ``theta'``: the driven tree joints' coordinates and rates, symbols
  while differentiating, then their signals' symbolic forms -- the prescribed rate and acceleration the numpy path's
  body accelerations carry), ``G = J D`` and ``G lambda = -Phi''_0 - 2 alpha Phi' - alpha^2 Phi``;
* a revolute or prismatic cut's law and actuation add the load ``actuation(t) - law(s - rest, s')`` along the
  cut's coordinate ``s`` (:func:`ctmm.spatial.closed_loop_cuts.cut_coordinate` on symbols: a moment about the axis,
  or a force at the child point along the guide; the opposite on the parent) to the applied wrenches of every load
  case, the law traced on symbols, the actuation by its symbolic form; a driven cut adds the row ``s -
  position(t)`` (``s' - rate(t)``, ``- acceleration(t)`` in ``Phi''``), its unknown the drive's load along ``s``;
* a spherical cut's 3-axis law (``docs/closed_loops.md`` §8.1b) adds its moment ``-R_p J(phi)^-T f`` on the child
  (the opposite on the parent) to the applied wrenches of every load case, the law traced on symbols
  (:func:`ctmm.compiled_spherical_cut_law.symbolic_spherical_law_moment`; beyond ``|phi| = 3`` rad the moment is NaN
  and the run stops with a :class:`~ctmm.errors.SimulationError` naming the cut, as the numpy path refuses there);
* after the RK4 step (at its end time): quaternions normalised, ``iterations`` minimum-norm Gauss-Newton steps
  ``q <- normalised(q + G(q) dx)``, ``dx = -J^T (J J^T)^-1 Phi`` (skipped once ``max |Phi| < 1e-14``), then
  ``v <- v - J^T (J J^T)^-1 Phi'``.

A cut at a deformable point (a ``SpatialBeam`` tip or station, a ``ctmm.fem`` subsystem node) is placed and, for
revolute and universal cuts, turned with the cross-section by :mod:`ctmm.compiled_spatial_cut_points` (the numpy
``side_point`` and ``side_frame`` traced); its loads are the same wrench at that point, taken by the body's own load
path.

State, failures and result as :mod:`ctmm.compiled_kinematic_loops` (residual and condition carried in the state,
:class:`~ctmm.errors.SimulationError` with time, cut joint and partial result); the stored rows' cut loads and drift
are outputs of the generated library (``F``, ``M``, ``Phi``, ``Phi'`` of :func:`symbolic_spatial_closed_loop` mapped
over the rows in one call).  Refused (:class:`ModelError`, by
name): trees :func:`ctmm.compiled_spatial.spatial_compile_refusal` refuses with ``time_signals=True`` (the tree's
loads may carry :mod:`ctmm.signals` with a symbolic form, stated at the sweep's time symbol; user callables refused),
laws casadi cannot express and actuations or drives without a symbolic form (user callables:
:func:`spatial_cut_load_refusal`; a driven tree joint's signals likewise, by :func:`spatial_compile_refusal`).  Driven
tree joints run here, in :mod:`ctmm.compiled_spatial_loop_schemes` and in the loop driver's generated run
(:mod:`ctmm.compiled_kinematic_loop_control`, with feedback loops, inputs or controllers: its sensors, the cut
coordinates and law moments read the time too).
"""
from __future__ import annotations

import os
from typing import Any, Sequence

import numpy as np

from .articulated import articulated_sweep
from .compiled_kinematic_loops import (CompiledKinematicLoops, first_failure, generated_failure, generated_run,
                                       cut_load_refusal, projected_rk4_step, symbolic_time_signal,
                                       tree_refusal)
from .compiled_spatial import position_rates, spatial_compile_refusal
from .compiled_spherical_cut_law import rotation_limit_note, symbolic_spherical_law_moment
from .errors import SimulationError
from .generated_loop import selected_outputs
from .compiled_spatial_cut_points import (SymbolicStates, deformable_sides, symbolic_deformable_frame,
                                          symbolic_deformable_point)
from .loop_integration import PROJECTION_SKIP, deformation_failure
from .ode import rk4_step
from .ops import CASADI
from .spatial.body_forms import SpatialScene
from .spatial.closed_loop_cuts import cut_frame
from .spatial.closed_loop_time import SpatialLoopSimulation
from .spatial.closed_loops import SpatialKinematicLoopModel
from .spatial.integrate import beam_deflection_weights, divergence_check
from .spatial.ports import SpatialPorts

__all__ = ["CompiledSpatialKinematicLoops", "loop_simulation",
           "spatial_cut_load_refusal",
           "spatial_kinematic_loop_compile_refusal", "simulate_spatial_kinematic_loops_generated", "symbolic_normalized", "symbolic_spatial_closed_loop",
           "symbolic_spatial_projection"]


def spatial_kinematic_loop_compile_refusal(model: Any) -> str:
    """Why ``model`` cannot run the generated RK4 of this module (an empty string when it can)."""
    reason = tree_refusal(model, SpatialKinematicLoopModel, "ctmm.spatial.SpatialKinematicLoopModel",
                          _tree_compile_refusal)
    if reason:
        return reason
    for cut in model.cuts:
        reason = spatial_cut_load_refusal(cut)
        if reason:
            return reason
    return ""


def _tree_compile_refusal(tree: Any) -> str:
    """Why a loop model's tree cannot be compiled: loads and driven joints may carry signals with a symbolic form
    (stated at the time symbol of the sweep and of the rows)."""
    return spatial_compile_refusal(tree, time_signals=True)


def spatial_cut_load_refusal(cut: Any) -> str:
    """Why the law, actuation or drive of spatial cut joint ``cut`` cannot be stated on symbols (an empty string when
    it can; :func:`ctmm.compiled_kinematic_loops.cut_load_refusal`)."""
    fields = ("position", "rate", "acceleration") if cut.driven else ("actuation",)
    return cut_load_refusal(cut.name, "law", cut.law, {field: getattr(cut, field) for field in fields})


def symbolic_spatial_closed_loop(model: SpatialKinematicLoopModel, extra_actuators: Sequence[str] = ()
                                 ) -> tuple[Any, Any, Any, Any]:
    """The closed-loop velocity rates of a spatial kinematic loop model on symbols (module docstring):
    ``closed(q, v, u, p, t) -> (v', condition, cut unknowns, Phi, Phi', G, F, M)`` with the actuator values ``u`` of
    ``extra_actuators`` (the tree's port actuators, :mod:`ctmm.spatial.ports`, and the undriven revolute and
    prismatic cuts' ``"<cut>.torque"`` / ``"<cut>.force"``, applied with the cut loads), ``p`` empty, ``F`` the cuts'
    forces on the child [N] (3 per cut, world axes; the ``"<cut>.force_x|y|z"`` sensors), ``M`` their moments on the
    child [N m] (3 per cut, world axes: the unknowns' moments, a driven revolute cut's drive moment included, plus a
    spherical cut's law moment -- a run's stored ``cut_force``, ``cut_moment``, :func:`loop_simulation`);
    ``constraint(q, v, t) -> (Phi, Phi', J)``; ``cut_coordinates(q, v, t) -> [s_1, s_1', ...]`` (0 for cuts without
    a coordinate); ``law_moments(q, v, t) -> [m_1 ; m_2 ; ...]`` (3 per cut: a spherical cut's law moment on the
    child [N m], world axes, :meth:`SpatialKinematicLoopModel.law_moments`; zeros for the other cuts); the last two
    at the time ``t`` [s] too: driven tree joints move them (the loop driver's sensors,
    :mod:`ctmm.compiled_kinematic_loop_control`)."""
    import casadi as ca

    tree = model.tree
    nq, nv, m = tree.n_positions, tree.n_velocities, model.n_constraints
    scene = SpatialScene(tree)
    sides, frames = _cut_sides(model), [cut_frame(cut) for cut in model.cuts]
    deformable = deformable_sides(model)
    q, v, lam = ca.SX.sym("q", nq), ca.SX.sym("v", nv), ca.SX.sym("lambda", m)
    extra_actuators = tuple(extra_actuators)
    u = ca.SX.sym("u", len(extra_actuators))
    along_ports = {f"{cut.name}.{'torque' if cut.kind == 'revolute' else 'force'}": cut.name
                   for cut in model.cuts if cut.kind in ("revolute", "prismatic") and not cut.driven}
    port_loads = {name: sum((u[k] for k, port in enumerate(extra_actuators) if along_ports.get(port) == name),
                            ca.SX(0.0)) for name in along_ports.values()}
    joint_inputs, tree_wrenches = _tree_actuators(model, [(k, name) for k, name in enumerate(extra_actuators)
                                                          if name not in along_ports], u)
    p, t = ca.SX.sym("p", 0), ca.SX.sym("t")
    held, (held_q, held_v), (signal_q, signal_v, signal_a) = _driven_symbols(tree, t)

    def kinematics(q_: Any, v_: Any, t_: Any, driven: dict | None = None) -> list:
        return SymbolicStates(scene.terms(CASADI, q_, v_, t_, driven=driven)[2], q_, v_)

    def point(states: list, side: tuple[int, np.ndarray]) -> tuple[Any, Any]:
        body, location = side
        if body < 0:
            return ca.DM(location), ca.DM.zeros(3)
        if (body, tuple(float(x) for x in location)) in deformable:     # ctmm.compiled_spatial_cut_points
            return symbolic_deformable_point(states[body], deformable[body, tuple(float(x) for x in location)],
                                             states.q, states.v, tree.modal[body])
        s = states[body]
        arm = ca.mtimes(s.rotation, ca.DM(location))
        return s.origin + arm, s.velocity + ca.cross(s.omega, arm)

    def axes(states: list, side: tuple[int, np.ndarray]) -> tuple[Any, Any]:
        """Axes and angular velocity of a side's body, or at a deformable point of its cross-section."""
        body, location = side
        if (body, tuple(float(x) for x in location)) in deformable:     # ctmm.compiled_spatial_cut_points
            return symbolic_deformable_frame(states[body], deformable[body, tuple(float(x) for x in location)],
                                             states.q, states.v, tree.modal[body])
        return states[body].rotation, states[body].omega

    def parent_fixed(states: list, parent: tuple[int, np.ndarray], local: np.ndarray) -> Any:
        return ca.DM(local) if parent[0] < 0 else ca.mtimes(axes(states, parent)[0], ca.DM(local))

    def coordinate(states: list, cut: Any, parent: tuple, child: tuple) -> tuple[Any, Any, Any]:
        """The cut's coordinate ``s``, its rate and direction ``a`` on symbols
        (:func:`ctmm.spatial.closed_loop_cuts.cut_coordinate`)."""
        xp, vp = point(states, parent)
        xc, vc = point(states, child)
        omega_c = axes(states, child)[1]
        omega_p = ca.DM.zeros(3) if parent[0] < 0 else axes(states, parent)[1]
        rotation_c = axes(states, child)[0]
        if cut.kind == "revolute":
            a = ca.mtimes(rotation_c, ca.DM(np.asarray(cut.axis, float)))
            n_c = ca.mtimes(rotation_c, ca.DM(np.asarray(cut.normal, float)))
            n_p = parent_fixed(states, parent, np.asarray(cut.parent_normal, float))
            return ca.atan2(ca.dot(ca.cross(n_p, n_c), a), ca.dot(n_p, n_c)), ca.dot(omega_c - omega_p, a), a
        a = parent_fixed(states, parent, np.asarray(cut.parent_axis, float))
        return ca.dot(xc - xp, a), ca.dot(vc - vp, a) + ca.dot(xc - xp, ca.cross(omega_p, a)), a

    def law_moment(states: list, cut: Any, parent: tuple, child: tuple) -> Any:
        """A spherical cut's law moment on the child (world; :func:`symbolic_spherical_law_moment`)."""
        rotation_p, omega_p = (None, ca.DM.zeros(3)) if parent[0] < 0 else (states[parent[0]].rotation,
                                                                           states[parent[0]].omega)
        return symbolic_spherical_law_moment(cut, rotation_p, states[child[0]].rotation, omega_p,
                                             states[child[0]].omega)

    def rows(q_: Any, v_: Any, t_: Any, driven: dict | None = None) -> tuple[Any, Any]:
        states = kinematics(q_, v_, t_, driven)
        phi, rate = [], []
        for cut, (parent, child), frame in zip(model.cuts, sides, frames):
            xp, vp = point(states, parent)
            xc, vc = point(states, child)
            omega_c = axes(states, child)[1]
            omega_p = ca.DM.zeros(3) if parent[0] < 0 else axes(states, parent)[1]
            if frame.basis is None:
                phi.append(xc - xp)
                rate.append(vc - vp)
            for b_local in frame.basis or ():        # prismatic: d . b_j, b_j parent-fixed
                b = parent_fixed(states, parent, b_local)
                phi.append(ca.dot(xc - xp, b))
                rate.append(ca.dot(vc - vp, b) + ca.dot(xc - xp, ca.cross(omega_p, b)))
            for u_local, b_local in frame.pairs:
                u = ca.mtimes(axes(states, child)[0], ca.DM(u_local))
                b = ca.DM(b_local) if parent[0] < 0 else ca.mtimes(axes(states, parent)[0], ca.DM(b_local))
                phi.append(ca.dot(u, b))
                rate.append(ca.dot(omega_c - omega_p, ca.cross(u, b)))
            if cut.driven:                           # s - position(t), s' - rate(t)
                value, value_rate, _ = coordinate(states, cut, parent, child)
                phi.append(value - symbolic_time_signal(cut.position, t_))
                rate.append(value_rate - symbolic_time_signal(cut.rate, t_))
        return ca.vertcat(*phi), ca.vertcat(*rate)

    def wrenches(states: list, values: Any, t_: Any, spherical_laws: Any, constraint_loads: list) -> dict:
        """The cut loads of the unknowns ``values`` and the cuts' laws and actuations at time ``t_`` as wrenches
        ``(point, [f ; m] world)`` per body (``spherical_laws``: 3 per cut, the spherical laws' moments, formed once
        outside the ``1 + m`` load cases); each cut's ``(force, moment)`` on the child from the unknowns alone
        appended to ``constraint_loads`` (:meth:`SpatialKinematicLoopModel.cut_loads`: a driven cut's drive force or
        moment included, laws and actuations not)."""
        out: dict[int, list] = {}
        row = 0
        for k, (cut, (parent, child), frame) in enumerate(zip(model.cuts, sides, frames)):
            if frame.basis is None:
                force = values[row:row + 3]
                row += 3
            else:                                   # prismatic: lambda_j b_j
                force = ca.DM.zeros(3)
                for b_local in frame.basis:
                    force = force + values[row] * parent_fixed(states, parent, b_local)
                    row += 1
            moment = ca.DM.zeros(3)
            for u_local, b_local in frame.pairs:
                u = ca.mtimes(axes(states, child)[0], ca.DM(u_local))
                b = ca.DM(b_local) if parent[0] < 0 else ca.mtimes(axes(states, parent)[0], ca.DM(b_local))
                moment = moment + values[row] * ca.cross(u, b)
                row += 1
            constraint, constraint_moment = force, moment
            along = None
            if cut.driven:                          # the drive's load along the coordinate: an unknown
                along = values[row]
                row += 1
            elif cut.kind == "spherical" and cut.law is not None:     # the 3-axis law's moment
                moment = moment + spherical_laws[3 * k:3 * k + 3]
            elif cut.has_law or cut.name in port_loads:     # actuation(t) + u - law(s - rest, s')
                value, value_rate, _ = coordinate(states, cut, parent, child)
                along = 0.0 if cut.actuation is None else symbolic_time_signal(cut.actuation, t_)
                along = along + port_loads.get(cut.name, 0.0)
                if cut.law is not None:
                    along = along - cut.law.force(value - cut.rest, value_rate)
            if along is not None:
                a = coordinate(states, cut, parent, child)[2]
                if cut.kind == "revolute":
                    moment = moment + along * a
                    constraint_moment = moment if cut.driven else constraint_moment
                else:                               # prismatic: a force at the child point
                    force = force + along * a
                    constraint = force if cut.driven else constraint
            constraint_loads.append((constraint, constraint_moment))
            load = ca.vertcat(force, moment)
            out.setdefault(child[0], []).append((child[1], load))
            if parent[0] >= 0:                      # prismatic: the force acts at the child point
                shift = ca.DM.zeros(3) if frame.basis is None else ca.cross(
                    point(states, child)[0] - point(states, parent)[0], force)
                out.setdefault(parent[0], []).append((parent[1], -ca.vertcat(force, moment + shift)))
        return out

    states = kinematics(q, v, t)
    moments = [law_moment(states, cut, parent, child) if cut.kind == "spherical" and cut.law is not None
               else ca.DM.zeros(3) for cut, (parent, child) in zip(model.cuts, sides)]
    spherical_laws = ca.SX.sym("spherical_laws", 3 * len(model.cuts))
    constraint_loads: list = []
    loads = wrenches(states, lam, t, spherical_laws, constraint_loads)
    for body, entries in tree_wrenches.items():
        loads.setdefault(body, []).extend(entries)
    # the tree's load signals and driven joints on the time symbol
    body_terms, joint_terms, _ = scene.terms(CASADI, q, v, t, joint_inputs or None, loads)
    solution = articulated_sweep(CASADI, scene.tree, body_terms, joint_terms)
    sweep = ca.Function("loaded_sweep", [q, v, t, lam, u, spherical_laws],
                        [ca.vertcat(*scene.velocity_rates(solution))])
    law_values = ca.vertcat(*moments)
    v_dot0 = sweep(q, v, t, ca.DM.zeros(m), u, law_values)
    D = ca.horzcat(*[sweep(q, v, t, ca.DM.eye(m)[:, i], u, law_values) - v_dot0 for i in range(m)])
    phi, phi_dot = rows(q, v, t, held)              # driven tree joints' position and rate as symbols
    J = ca.jacobian(phi_dot, v)
    q_dot = position_rates(tree, q, v)
    drive = []                                      # - acceleration(t) on a driven cut's row
    for cut in model.cuts:
        drive += [0.0] * (cut.n_rows - 1) + [symbolic_time_signal(cut.acceleration, t) if cut.driven else 0.0]
    c0 = ca.mtimes(J, v_dot0) + ca.jtimes(phi_dot, q, q_dot) - ca.vertcat(*drive)
    if held:                                        # along the prescribed motion: its rate and acceleration
        c0 = c0 + ca.jtimes(phi_dot, held_q, signal_v) + ca.jtimes(phi_dot, held_v, signal_a)
        phi, phi_dot, J, c0 = ca.substitute([phi, phi_dot, J, c0], [held_q, held_v], [signal_q, signal_v])
    G = ca.mtimes(J, D)
    alpha = model.baumgarte
    forces = ca.solve(G, -c0 - 2.0 * alpha * phi_dot - alpha * alpha * phi)
    condition = ca.norm_fro(G) * ca.norm_fro(ca.solve(G, ca.SX.eye(m)))
    child_forces, child_moments = ca.substitute([ca.vertcat(*(f for f, _ in constraint_loads)),
                                                 ca.vertcat(*(mu for _, mu in constraint_loads))], [lam], [forces])
    closed = ca.Function("closed", [q, v, u, p, t], [v_dot0 + ca.mtimes(D, forces), condition, forces, phi,
                                                      phi_dot, G, child_forces, child_moments + law_values])
    coordinates = []                                # at time t: driven tree joints move them
    for cut, (parent, child) in zip(model.cuts, sides):
        value, value_rate, _ = coordinate(states, cut, parent, child) if cut.kind in ("revolute", "prismatic") \
            else (0.0, 0.0, None)
        coordinates += [value, value_rate]
    return (closed, ca.Function("constraint", [q, v, t], [phi, phi_dot, J]),
            ca.Function("cut_coordinates", [q, v, t], [ca.vertcat(*coordinates)]),
            ca.Function("law_moments", [q, v, t], [law_values]))


def _driven_symbols(tree: Any, t: Any) -> tuple[dict, tuple[Any, Any], tuple[Any, Any, Any]]:
    """The driven joints of ``tree`` on symbols: ``({joint index: (positions, rates)}, (position symbols, rate
    symbols), (positions, rates, accelerations))``, the last their signals' symbolic forms at the time symbol ``t``
    (:meth:`ctmm.spatial.body_forms.SpatialScene.terms` ``driven``; empty when none is driven)."""
    import casadi as ca

    joints = [(j, joint) for j, joint in enumerate(tree.joints) if joint.driven]
    count = sum(len(joint.position) for _, joint in joints)
    positions, rates = ca.SX.sym("driven_q", count), ca.SX.sym("driven_v", count)
    held, start, signals = {}, 0, ([], [], [])
    for j, joint in joints:
        n = len(joint.position)
        held[j] = ([positions[start + i] for i in range(n)], [rates[start + i] for i in range(n)])
        for values, field in zip(signals, ("position", "rate", "acceleration")):
            values += [symbolic_time_signal(f, t) for f in getattr(joint, field)]
        start += n
    return held, (positions, rates), tuple(ca.SX(ca.vertcat(*values)) if values else ca.SX(0, 1)
                                            for values in signals)


def _cut_sides(model: SpatialKinematicLoopModel) -> list[tuple[tuple[int, np.ndarray], tuple[int, np.ndarray]]]:
    """Per cut ``((parent body or -1, point), (child body, point))``: body axes from the body origin, or the ground
    location in world axes."""
    bodies = model.tree.bodies
    names = [b.name for b in bodies]
    out = []
    for cut in model.cuts:
        parent = ((-1, np.asarray(cut.point, float)) if cut.parent is None else
                  (names.index(cut.parent), np.asarray(bodies[names.index(cut.parent)].points[cut.point], float)))
        child = names.index(cut.child)
        out.append((parent, (child, np.asarray(bodies[child].points[cut.child_point], float))))
    return out


def _tree_actuators(model: SpatialKinematicLoopModel, actuators: Sequence[tuple[int, str]], u: Any
                    ) -> tuple[dict, dict]:
    """The tree's port actuators ``[(index in u, name)]`` on the symbols ``u``: ``(joint inputs, wrenches)`` for
    :meth:`SpatialScene.terms`, each the port's unit load (:meth:`SpatialPorts.inputs`) times its value."""
    import casadi as ca

    ports = SpatialPorts(model.tree)
    joints: dict[str, Any] = {}
    wrenches: dict[int, list] = {}
    for k, name in actuators:
        unit = ports.inputs({name: 1.0})
        for target, value in unit.joint.items():
            column = ca.DM(np.reshape(np.asarray(value, float), (-1, 1)))
            joints[target] = joints.get(target, ca.SX.zeros(column.size1(), 1)) + column * u[k]
        for body, entries in unit.wrenches.items():
            for point, load, *axes in entries:
                wrenches.setdefault(int(body), []).append(
                    (np.asarray(point, float), ca.DM(np.reshape(np.asarray(load, float), (6, 1))) * u[k], *axes))
    return joints, wrenches


class CompiledSpatialKinematicLoops(CompiledKinematicLoops):
    """The generated RK4 with projection of one spatial kinematic loop model (module docstring).

    Parameters
    ----------
    model : SpatialKinematicLoopModel
        Compilable (:func:`spatial_kinematic_loop_compile_refusal`).
    store_every, rows, iterations, cache_dir, compiler
        As :class:`ctmm.compiled_kinematic_loops.CompiledKinematicLoops`.

    Attributes
    ----------
    state_size : int
        ``nq + nv + 2``: ``[q, v, residual, condition]``.
    """

    @staticmethod
    def _refusal(model: Any) -> str:
        return spatial_kinematic_loop_compile_refusal(model)

    def _layout(self) -> tuple[np.ndarray, int, str, tuple]:
        """``(parameters, state size, library name, what the builder reads)``."""
        model, tree = self.model, self.model.tree
        return (np.zeros(0), tree.n_positions + tree.n_velocities + 2,
                f"spatial_kinematic_loops_{tree.n_bodies}b{tree.n_velocities}v{len(model.cuts)}c",
                (tree, model.cuts, model.baumgarte, "spatial kinematic loop rk4"))

    def _build(self) -> tuple[Any, list]:
        """``(step, [outputs])`` on symbols: the RK4 step with projection and ``outputs(y, p, t) -> (lambda, Phi,
        Phi', G, F, M)`` (``F``, ``M``: the stored cut loads, :func:`symbolic_spatial_closed_loop`)."""
        import casadi as ca

        tree = self.model.tree
        nq, nv = tree.n_positions, tree.n_velocities
        closed, constraint, _, _ = symbolic_spatial_closed_loop(self.model)
        q, v, p, t = ca.SX.sym("q", nq), ca.SX.sym("v", nv), ca.SX.sym("p", 0), ca.SX.sym("t")
        v_dot, condition, forces, phi, phi_dot, G, child_forces, child_moments = closed(q, v, ca.DM.zeros(0), p, t)
        terms = ca.Function("closed_terms", [ca.vertcat(q, v), p, t], [ca.vertcat(position_rates(tree, q, v), v_dot),
                                                                        condition, forces, phi, phi_dot, G,
                                                                        child_forces, child_moments])
        rate, outputs = selected_outputs(terms, [("closed_rate", (0, 1)), ("outputs", (2, 3, 4, 5, 6, 7))])

        project = symbolic_spatial_projection(tree, constraint, self.iterations)
        return projected_rk4_step(rate, project, nq + nv, 0), [outputs]

    def cut_history(self, t: np.ndarray, states: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Cut forces [N] and moments [N m] on the children (rows, n_cuts, 3; world axes, as
        :func:`loop_simulation` stores them), ``Phi`` and ``Phi'`` (rows, m) of stored times ``t`` [s] and states, by
        the generated function mapped over the rows (one call)."""
        rows, cuts, m, size = len(t), len(self.model.cuts), self.model.n_constraints, self.state_size - 2
        if rows == 0:
            return np.zeros((0, cuts, 3)), np.zeros((0, cuts, 3)), np.zeros((0, m)), np.zeros((0, m))
        _, phi, phi_dot, _, forces, moments = self._outputs.map(rows)(states[:, :size].T, np.zeros((0, rows)),
                                                                      np.asarray(t, dtype=float)[None, :])
        return (np.asarray(forces).T.reshape(rows, cuts, 3), np.asarray(moments).T.reshape(rows, cuts, 3),
                np.asarray(phi).T.copy(), np.asarray(phi_dot).T.copy())


def simulate_spatial_kinematic_loops_generated(model: SpatialKinematicLoopModel, q0: Any, v0: Any, *, t_final: float,
                                               dt: float, store_every: int = 1,
                                               compiled: CompiledSpatialKinematicLoops | None = None,
                                               cache_dir: str | os.PathLike | None = None) -> SpatialLoopSimulation:
    """RK4 with projection of a spatial kinematic loop model, the time loop in generated C (module docstring): the
    steps of :func:`ctmm.spatial.closed_loop_time.simulate_spatial_loops` with ``method="rk4"``, method label
    ``"rk4-generated"``.  Parameters, refusals and failures as
    :func:`ctmm.compiled_kinematic_loops.simulate_kinematic_loops_generated` (``q0``, ``v0`` arrays or mappings,
    :meth:`SpatialKinematicLoopModel.state`; ``compiled`` a :class:`CompiledSpatialKinematicLoops`); the partial
    result of a :class:`~ctmm.errors.SimulationError` is a :class:`SpatialLoopSimulation`.
    """
    q, v = model.state(q0, v0) if isinstance(model, SpatialKinematicLoopModel) else (q0, v0)
    compiled, t, states, wall, n_steps = generated_run(CompiledSpatialKinematicLoops, model, q, v, t_final, dt,
                                                       store_every, compiled, cache_dir)
    size = compiled.state_size - 2
    bad = first_failure(states, size)
    good = len(t) if bad is None else bad
    forces, moments, phi, phi_dot = compiled.cut_history(t[:good], states[:good])

    def history(k: int) -> SpatialLoopSimulation:
        return loop_simulation(model, t[:k], states[:k, :size], forces[:k], moments[:k], "rk4-generated", wall,
                               4 * n_steps, phi[:k], phi_dot[:k])

    out_of_range = _deformation_failure(model, t, states, bad, float(dt), size, compiled.iterations)
    if out_of_range is not None:
        row, error = out_of_range
        error.partial_result = history(row)
        raise error
    if bad is not None:
        error = generated_failure(model, f"spatial kinematic loop {model.name!r}", t, states, bad, size,
                                  compiled.iterations, history(bad))
        note, cut = ("", None) if bad == 0 or np.all(np.isfinite(states[bad])) else rotation_limit_note(
            model, states[bad - 1, :model.tree.n_positions], states[bad - 1, model.tree.n_positions:size],
            float(t[bad - 1]))
        if note:
            raise SimulationError(str(error) + note, time=error.time, element=cut,
                                  partial_result=error.partial_result) from None
        raise error
    return history(len(t))


def _deformation_failure(model: SpatialKinematicLoopModel, t: np.ndarray, states: np.ndarray, bad: int | None,
                         dt: float, size: int, iterations: int) -> tuple[int, SimulationError] | None:
    """:func:`ctmm.loop_integration.deformation_failure` of a spatial loop model: the tree's guard
    (:func:`ctmm.spatial.integrate.divergence_check` without a bound: a SpatialBeam's deflection bound, a ``ctmm.fem``
    subsystem's size and rotation; ``"rk4"``), the numpy step of
    :func:`ctmm.spatial.closed_loop_time.simulate_spatial_loops` (:func:`ctmm.ode.rk4_step` of ``[G(q) v ; v']``, then
    :meth:`SpatialKinematicLoopModel.project` with the generated step's Gauss-Newton ``iterations``)."""
    tree = model.tree
    if not beam_deflection_weights(tree):
        return None
    nq = tree.n_positions
    guard = divergence_check(tree, states[0, :size], None)

    def beyond(x: np.ndarray, time: float) -> SimulationError | None:
        try:
            guard(time, x, "rk4")
        except SimulationError as exc:
            return exc
        return None

    def rate(time: float, x: np.ndarray) -> np.ndarray:
        return np.concatenate([tree.position_rates(x[None, :nq], x[None, nq:])[0],
                               model.solve(x[:nq], x[nq:], time)[0]])

    def step(x: np.ndarray, k: int) -> np.ndarray | None:
        x = rk4_step(rate, (k - 1) * dt, x, dt)
        return np.concatenate(model.project(x[:nq], x[nq:], k * dt, iterations)) if np.all(np.isfinite(x)) else None

    return deformation_failure(model, t, states, bad, dt, size, beyond, step)


def loop_simulation(model: SpatialKinematicLoopModel, t: np.ndarray, states: np.ndarray, forces: np.ndarray,
                    moments: np.ndarray, method: str, wall: float, evaluations: int, phi: np.ndarray,
                    phi_dot: np.ndarray) -> SpatialLoopSimulation:
    """The :class:`SpatialLoopSimulation` of stored times ``t`` [s], states ``[q, v]``, the cut forces [N] and moments
    [N m] on the children (rows, n_cuts, 3; world axes: :meth:`SpatialKinematicLoopModel.cut_loads` of the unknowns,
    a spherical cut's law moment added, as the numpy run stores them; the generated ``F``, ``M`` of
    :func:`symbolic_spatial_closed_loop`) and the drift from ``Phi``, ``Phi'`` (rows, m)."""
    nq = model.tree.n_positions
    return SpatialLoopSimulation(model, np.asarray(t), states[:, :nq], states[:, nq:], forces, moments,
                                 np.max(np.abs(phi), axis=1, initial=0.0), np.max(np.abs(phi_dot), axis=1, initial=0.0),
                                 method, wall, evaluations)


def symbolic_normalized(tree: Any, q: Any) -> Any:
    """``q`` (symbols) with every quaternion block of ``tree`` scaled to unit norm (:meth:`SpatialModel.normalized` on
    symbols)."""
    import casadi as ca

    parts = [q[k] for k in range(q.size1())]
    for joint, layout in zip(tree.joints, tree.layout):
        start = layout.position.start + (3 if joint.kind in ("free", "elastic6") else 0)
        if joint.kind not in ("spherical", "free", "elastic6"):
            continue
        block = ca.vertcat(*parts[start:start + 4])
        norm = ca.norm_2(block)
        for i in range(4):
            parts[start + i] = block[i] / norm
    return ca.vertcat(*parts)


def symbolic_spatial_projection(tree: Any, constraint: Any, iterations: int) -> Any:
    """The projection onto the cut joints of a spatial kinematic loop model on symbols (as
    :meth:`SpatialKinematicLoopModel.project`): ``project(y, t) -> (y projected, max |Phi| after)`` on ``y = [q, v]``
    of ``tree``: ``q`` normalized, ``iterations`` Gauss-Newton steps along the retraction ``q + G(q) dx`` (each
    skipped once ``max |Phi| < PROJECTION_SKIP``), then ``v <- v - J^T (J J^T)^-1 Phi'``; ``constraint(q, v, t) ->
    (Phi, Phi', J)`` of :func:`symbolic_spatial_closed_loop`."""
    import casadi as ca

    nq, nv = tree.n_positions, tree.n_velocities
    q, v, t, dx = ca.SX.sym("q", nq), ca.SX.sym("v", nv), ca.SX.sym("t"), ca.SX.sym("dx", nv)
    normalize = ca.Function("normalized", [q], [symbolic_normalized(tree, q)])
    retract = ca.Function("retract", [q, dx], [normalize(q + position_rates(tree, q, dx))])
    qk = normalize(q)
    residual, rate_k, Jk = constraint(qk, v, t)
    for _ in range(iterations):
        step_q = retract(qk, -ca.mtimes(Jk.T, ca.solve(ca.mtimes(Jk, Jk.T), residual)))
        moved = ca.mmax(ca.fabs(residual)) >= PROJECTION_SKIP
        qk = ca.if_else(moved, step_q, qk)
        residual, rate_k, Jk = constraint(qk, v, t)
    vk = v - ca.mtimes(Jk.T, ca.solve(ca.mtimes(Jk, Jk.T), rate_k))
    return ca.Function("project", [ca.vertcat(q, v), t], [ca.vertcat(qk, vk), ca.mmax(ca.fabs(residual))])
