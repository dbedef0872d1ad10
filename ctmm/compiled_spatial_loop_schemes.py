"""Generated DT-TMM schemes of spatial kinematic loop models (issue 13): cut joints inside the generated Newton step.

The generated counterpart of :func:`ctmm.spatial.closed_loop_time.simulate_spatial_loop_scheme`: the Lie-group step
of :class:`~ctmm.compiled_spatial_schemes.CompiledSpatialScheme` on the spanning tree, Newton in generated C on
``r(a) = a - v_dot(q_n (+) delta(a), v(a), t)`` with ``v_dot`` the closed-loop velocity rates of
:func:`ctmm.compiled_spatial_kinematic_loops.symbolic_spatial_closed_loop` (the cut loads solved from the boundary
compliance at the iterate, laws, actuations and drives of the cuts included: the numpy path's ``input_map`` of
:meth:`SpatialKinematicLoopModel.cut_inputs`, the same root), then ``q``, ``v`` projected onto the cut joints after
every step (:func:`ctmm.compiled_spatial_kinematic_loops.symbolic_spatial_projection`, the rule of
:class:`ctmm.loop_integration.StepProjection`; the scheme's acceleration history is kept, as there).  Two entries
after the scheme's status carry the largest Frobenius condition of the boundary compliance ``G`` at the accepted
states and the largest ``max |Phi|`` after a projection; above :data:`~ctmm.loop_integration.CONDITION_LIMIT` /
:data:`~ctmm.loop_integration.PROJECTION_TOLERANCE` the run stops with :class:`~ctmm.errors.SimulationError` (time,
cut joint, partial result).  The numpy path checks ``G`` at every Newton iterate, here at the accepted states.

Every scheme of :class:`CompiledSpatialScheme` (Houbolt's earlier configurations are the projected states, as in
the numpy path).  The tree's joint inputs are the step's input ``u`` (:attr:`CompiledSpatialLoopScheme.actuators`,
applied with the cut loads as :meth:`SpatialKinematicLoopModel.cut_inputs` applies them), numbers held over a run;
``divergence_bound`` is the numpy path's rule (:func:`ctmm.spatial.integrate.divergence_check` on the projected
states, the failing step found by :func:`ctmm.compiled_spatial_schemes.checked_spatial_result`).  Refused by name
(:class:`~ctmm.errors.ModelError`, by :mod:`ctmm.spatial_loop_time`): what
:func:`ctmm.compiled_spatial_kinematic_loops.spatial_kinematic_loop_compile_refusal` refuses, joint inputs that are
functions of time, feedback loops and controllers (the loop driver's run: generated with ``"rk4"`` only).
"""
from __future__ import annotations

import os
from typing import Any, Mapping

import numpy as np

from . import validation
from .compiled_spatial_kinematic_loops import (loop_simulation, spatial_kinematic_loop_compile_refusal,
                                               symbolic_spatial_closed_loop, symbolic_spatial_projection)
from .compiled_spatial_schemes import (CompiledSpatialScheme, checked_spatial_result, generated_rows,
                                       warn_conditionally_stable)
from .compiled_spherical_cut_law import spherical_law_cuts
from .errors import ModelError, SimulationError
from .loop_integration import CONDITION_LIMIT, PROJECTION_TOLERANCE, projection_failure, singular_compliance
from .planar.integrate import step_total
from .schemes import Scheme, as_scheme
from .spatial.closed_loop_time import SpatialLoopSimulation
from .spatial.closed_loops import SpatialKinematicLoopModel
from .spatial.ports import SpatialPorts

__all__ = ["CompiledSpatialLoopScheme", "check_cut_rows", "joint_input_ports", "simulate_spatial_loop_scheme_generated"]


def joint_input_ports(tree: Any) -> tuple[str, ...]:
    """The port actuator names (:class:`~ctmm.spatial.ports.SpatialPorts`) of the joint inputs of spatial model
    ``tree``, one per input component in the order of its input vector (:meth:`SpatialRates.input_vector`:
    ``tree.inputs`` by name, then component; e.g. ``"s.torque_x|y|z"`` for a spherical joint's ``"s.torque"``)."""
    ports, order = SpatialPorts(tree).actuators, list(tree.inputs)
    first: dict[tuple[int, int], str] = {}
    for name, actuator in ports.items():
        if actuator.kind == "joint" and actuator.target in order:
            first.setdefault((order.index(actuator.target), int(actuator.component)), name)
    return tuple(first[key] for key in sorted(first))


class CompiledSpatialLoopScheme(CompiledSpatialScheme):
    """The generated DT-TMM step of a spatial kinematic loop model, projected after every step (module docstring).

    Parameters
    ----------
    loop_model : SpatialKinematicLoopModel
        Compilable (:func:`~ctmm.compiled_spatial_kinematic_loops.spatial_kinematic_loop_compile_refusal`).
    scheme : Scheme or str
        A :mod:`ctmm.schemes` scheme.
    store_every, tolerance, max_iterations, rows, cache_dir, compiler, tangent
        As :class:`~ctmm.compiled_spatial_schemes.CompiledSpatialScheme` (``tangent`` None: ``"mapped"`` where a
        spherical cut carries a law, else by size).
    projection : bool
        Project after every step (default); ``False``: Baumgarte alone.
    iterations : int
        Gauss-Newton steps of the projection (3, as :class:`~ctmm.loop_integration.StepProjection`).
    """

    controller_size = 2       # [largest condition of G at the accepted states, largest residual after projection]

    def __init__(self, loop_model: SpatialKinematicLoopModel, scheme: Scheme | str = "newmark", *,
                 store_every: int = 1, tolerance: float = 1e-10, max_iterations: int = 50, rows: int = 64,
                 projection: bool = True, iterations: int = 3, cache_dir: str | os.PathLike | None = None,
                 compiler: str | None = None, tangent: str | None = None) -> None:
        reason = spatial_kinematic_loop_compile_refusal(loop_model)
        if reason:
            raise ModelError(f"CompiledSpatialLoopScheme: {reason}")
        self.loop_model, self.projection, self.iterations = loop_model, bool(projection), int(iterations)
        self.actuators = self.step_actuators()
        self._closed, self._constraint, self.cut_coordinates, self.law_moments = symbolic_spatial_closed_loop(
            loop_model, self.actuators)
        self.prepare()
        if tangent is None and spherical_law_cuts(loop_model):     # the law inside the symbolic Jacobian: slow
            tangent = "mapped"          # compile (ball, Newmark, CPU incl. gcc: 16.6 s -> 5.8 s; 61 -> 107 us/step)
        super().__init__(loop_model.tree, scheme, store_every=store_every, tolerance=tolerance,
                         max_iterations=max_iterations, rows=rows, cache_dir=cache_dir, compiler=compiler,
                         tangent=tangent)

    def step_actuators(self) -> tuple[str, ...]:
        """The port actuators of the step's input ``u``: the tree's joint inputs (:func:`joint_input_ports`)."""
        return joint_input_ports(self.loop_model.tree)

    def prepare(self) -> None:
        """What a subclass sets up on the closed-loop functions before the step is built (nothing here)."""

    @property
    def input_size(self) -> int:
        """Entries of the step's input ``u``: one per port actuator of :attr:`actuators`."""
        return len(self.actuators)

    def described(self) -> tuple:
        """The cuts, the Baumgarte rate and the projection options (the cache key's part)."""
        return (self.loop_model.cuts, self.loop_model.baumgarte, self.projection, self.iterations, self.actuators,
                "spatial kinematic loop scheme")

    def closed_acceleration(self) -> Any:
        """``v_dot = acceleration(q, v, u, p, t)``: the closed-loop velocity rates, ``u`` the tree's joint inputs
        (:attr:`actuators`, the layout of :meth:`held_inputs`) applied with the cut loads."""
        import casadi as ca

        tree = self.model
        q, v, u = ca.SX.sym("q", tree.n_positions), ca.SX.sym("v", tree.n_velocities), ca.SX.sym("u", self.input_size)
        p, t = ca.SX.sym("p", 0), ca.SX.sym("t")
        return ca.Function("acceleration", [q, v, u, p, t], [self._closed(q, v, u, p, t)[0]])

    def controller_update(self, q: Any, v: Any, u: Any, p: Any, t: Any, c: Any, h: Any) -> Any:
        """``c`` with its last two entries ``[condition, residual]`` as ``[max(condition, condition of G at (q, v,
        t)), residual]`` at the accepted state (before its projection); the entries before them kept."""
        import casadi as ca

        return ca.vertcat(c[:-2], ca.fmax(c[-2], self._closed(q, v, u, p, t)[1]), c[-1])

    def initial_controller(self, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        """``[condition of G at the start, 0]`` (``G`` does not depend on the inputs)."""
        return np.array([float(self._closed(q, qdot, np.zeros(self.input_size), np.zeros(0), 0.0)[1]), 0.0])

    def cut_history(self, t: np.ndarray, states: np.ndarray, held: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Cut forces [N] and moments [N m] on the children (rows, n_cuts, 3; world axes, as
        :func:`~ctmm.compiled_spatial_kinematic_loops.loop_simulation` stores them), ``Phi`` and ``Phi'`` (rows, m) of
        stored times ``t`` [s] and states ``[q, v]`` with the input vector ``held`` (:meth:`held_inputs`; default
        zero): the closed-loop functions on symbols mapped over the rows (one call)."""
        m, rows, nq, cuts = self.loop_model.n_constraints, len(t), self.model.n_positions, len(self.loop_model.cuts)
        if rows == 0:
            return np.zeros((0, cuts, 3)), np.zeros((0, cuts, 3)), np.zeros((0, m)), np.zeros((0, m))
        q, v, t = states[:, :nq].T, states[:, nq:].T, np.asarray(t, dtype=float)[None, :]
        u = np.zeros(self.input_size) if held is None else np.asarray(held, dtype=float)
        _, _, _, phi, phi_dot, _, forces, moments = self._closed.map(rows)(q, v, np.tile(u[:, None], (1, rows)),
                                                                        np.zeros((0, rows)), t)
        return (np.asarray(forces).T.reshape(rows, cuts, 3), np.asarray(moments).T.reshape(rows, cuts, 3),
                np.asarray(phi).T.copy(), np.asarray(phi_dot).T.copy())

    def _build(self) -> tuple[Any, list]:
        """The scheme's step followed by the projection of ``q``, ``v`` at the step's end (module docstring)."""
        import casadi as ca

        step, extra = super()._build()
        if not self.projection:
            return step, extra
        tree = self.model
        size = tree.n_positions + tree.n_velocities
        project = symbolic_spatial_projection(tree, self._constraint, self.iterations)
        y, u, h = ca.MX.sym("y", self.state_size), ca.MX.sym("u", self.input_size), ca.MX.sym("h")
        p, t0, k = ca.MX.sym("p", 0), ca.MX.sym("t0"), ca.MX.sym("k")
        out = step(y, u, h, p, t0, k)
        moved, residual = project(out[:size], t0 + (k + 1.0) * h)
        last = self.state_size - 1
        out = ca.vertcat(moved, out[size:last], ca.fmax(out[last], residual))
        return ca.Function("step", [y, u, h, p, t0, k], [out]), extra


def simulate_spatial_loop_scheme_generated(model: SpatialKinematicLoopModel, q0: Any, v0: Any, *, t_final: float,
                                           dt: float, scheme: Scheme | str, inputs: Mapping[str, Any] | None = None,
                                           store_every: int = 1, divergence_bound: float | None = None,
                                           projection: bool = True, compiled: CompiledSpatialLoopScheme | None = None,
                                           cache_dir: str | os.PathLike | None = None
                                           ) -> tuple[SpatialLoopSimulation, dict]:
    """:func:`ctmm.spatial.closed_loop_time.simulate_spatial_loop_scheme` with the steps in generated C (module
    docstring): ``(run, info)``, the method ``"dt-tmm-generated/<scheme>"``.

    ``inputs``: the tree's joint inputs ``{"<joint>.torque": number or (k,) numbers}`` held over the run (functions
    of time refused by name).  ``divergence_bound``: the rule of the numpy path
    (:func:`ctmm.spatial.integrate.divergence_check` on the projected states), checked on the stored states after the
    run and, in the first failing stored interval, step by step (:func:`checked_spatial_result`): the failure is
    reported at its step's time with the states before it.

    Raises
    ------
    ModelError
        What the generated step refuses (named), bad arguments.
    ConvergenceError, SimulationError
        A step that does not converge, a non-finite state, a singular loop configuration, a failed projection:
        time, cut joint, partial result.
    """
    scheme = as_scheme(scheme)
    q, v = model.state(q0, v0)
    n_steps = step_total(t_final, dt)
    dt = float(t_final) / n_steps
    if divergence_bound is not None:
        divergence_bound = validation.positive("divergence_bound", divergence_bound)
    if compiled is None:
        compiled = CompiledSpatialLoopScheme(model, scheme, store_every=store_every, projection=projection,
                                             cache_dir=cache_dir)
    elif not isinstance(compiled, CompiledSpatialLoopScheme) or compiled.loop_model is not model or \
            compiled.scheme != scheme or compiled.store_every != store_every or compiled.projection != projection:
        raise ModelError(f"compiled must be a CompiledSpatialLoopScheme of this model with scheme={scheme!r}, "
                         f"store_every={store_every!r} and projection={projection!r}, got {compiled!r:.80}")
    warn_conditionally_stable(model.tree, scheme)
    held = compiled.held_inputs(inputs)
    start = compiled.initial_state(np.concatenate([q, v]), inputs)
    times, states, wall, total = generated_rows(compiled, start, dt, n_steps, inputs)
    method = f"dt-tmm-generated/{scheme.name}"
    size = model.tree.n_positions + model.tree.n_velocities
    info = {"dt": dt, "scheme": repr(scheme), "wall_time_s": wall, "compile_time_s": compiled.compile_time_s,
            "newton_iterations": total, "projection": compiled.projection}

    def result(k: int) -> SpatialLoopSimulation:
        forces, moments, phi, phi_dot = compiled.cut_history(times[:k], states[:k, :size], held)
        return loop_simulation(model, times[:k], states[:k, :size], forces, moments, method, wall, total, phi, phi_dot)

    run = checked_spatial_result(compiled, times, states, dt, method, result, divergence_bound, held)
    check_cut_rows(compiled, times, states, f"spatial kinematic loop {model.name!r} ({method})", result)
    if compiled.projection:
        info["max_drift_after_projection"] = float(np.max(states[:, -1]))
    return run, info


def check_cut_rows(compiled: CompiledSpatialLoopScheme, times: np.ndarray, states: np.ndarray, label: str,
                   result: Any) -> None:
    """Stop at the first stored row (times ``times`` [s]) whose ``[condition, residual]`` (the last two entries of
    the generated ``states``) exceeds :data:`~ctmm.loop_integration.CONDITION_LIMIT` or
    :data:`~ctmm.loop_integration.PROJECTION_TOLERANCE`.

    Raises
    ------
    SimulationError
        ``"<label>: <what> by t = ..."`` with the time, the first cut joint and ``result(row)`` as partial result.
    """
    condition, residual = states[:, -2], states[:, -1]
    over = np.flatnonzero((condition > CONDITION_LIMIT) | (residual > PROJECTION_TOLERANCE))
    if over.size:
        k = int(over[0])
        what = singular_compliance(float(condition[k])) if condition[k] > CONDITION_LIMIT else \
            projection_failure(float(residual[k]), compiled.iterations)
        raise SimulationError(f"{label}: {what} by t = {times[k]:.6g} s", time=float(times[k]),
                              element=compiled.loop_model.cuts[0].name, partial_result=result(k))
