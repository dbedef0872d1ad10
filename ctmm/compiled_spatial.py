"""Generated kernels of spatial models (issues 13 and 14): the RK4 time loop in C.

A :class:`~ctmm.spatial.model.SpatialModel` is stated on the element protocol by
:class:`~ctmm.spatial.body_forms.SpatialScene`; its body and joint terms run here on casadi symbols
through the one articulated sweep (:func:`ctmm.articulated.articulated_sweep`, ``d = 6``) and give
the rates of the state ``y = [q ; v]``

    y_dot = [G(q) v ; v_dot(q, v, u)]

as one SX expression (:class:`SpatialRates`, the :class:`~ctmm.generated_loop.SymbolicRates` of the
scene); :mod:`ctmm.generated_loop` builds the RK4 step, strides and blocks from it exactly as for
planar scenes (:class:`~ctmm.compiled_scene.CompiledScene`), and :mod:`ctmm.codegen` compiles and
caches the C.

Quaternions are integrated as coordinates, as on the numpy path
(:func:`ctmm.spatial.integrate.simulate_spatial`): ``q_dot = 1/2 q (x) (0, omega)``, every rotation
formed from the normalised quaternion, stored quaternions as integrated; the two paths agree to
round-off.

Long serial chains of equal segments (:func:`chain_period`; from :data:`FOLD_MIN_VELOCITIES` velocities, or
``fold=True``) are compiled as three folds over their segments (:func:`folded_velocity_rate`): the
code of one segment, called once per segment, instead of straight-line code of every body, so the C
and its compile time do not grow with N.

Numbers: with ``numbers="constants"`` (the default of ``compiled=True``) they are constants of the
generated code (one library per model, cached by the hash of its C text; ``p`` empty).  With
``numbers="inputs"`` the masses, non-zero inertia entries, the numbers of modal beams (not their lengths),
the 1- and 2-DOF joint laws and gravity are the parameter column ``p`` (:mod:`ctmm.compiled_spatial_parameters`:
the body terms summed from :func:`~ctmm.spatial.body_forms.rigid_body_terms` of unit numbers, the beams'
by :mod:`ctmm.compiled_spatial_beam_numbers`, the laws on the symbols; finite-element bodies refused), so one
library serves every model of one structure (its zeros, geometry, axes, loads and driven motions;
the applied loads' part of a body's terms keeps that body's numbers in the code); the folded chain
takes one column of ``p`` per segment.  Actuator inputs
(``"<joint>.torque" | ".force" | ".wrench"``) are inputs ``u`` of every function, numbers held over
a run.

Loads and driven joints may carry :mod:`ctmm.signals` Constant, Harmonic, Step, SquareWave or Ramp signals: the
terms state them on the time symbol of the rates (:mod:`ctmm.compiled_spatial_signals`), evaluated at every
RK4 stage time.  Refused (:class:`~ctmm.errors.ModelError`, by name): anything but a spatial model, a model
without coordinates, loads and driven joints whose signals are Python callables (no symbolic form), and
actuator inputs that are functions of time.
"""
from __future__ import annotations

import os
import time as clock
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .articulated import articulated_sweep
from .errors import ModelError, SimulationError
from .codegen import STRAIGHT_LINE_FLAGS
from .generated_loop import compiled_time_loop, rk4_step_function, run_blocks
from .ops import CASADI
from .results import SimulationResult
from .segment_fold import fold_segments
from .signal_results import SignalSystem, signal_result
from .spatial.body_forms import SpatialScene, child_motion, joint_motion, rigid_body_terms
from .spatial.frames import constant, cross, quaternion_rate, quaternion_rotation
from .spatial.integrate import beam_deflection_weights, check_beam_deflection, initial_state, spatial_signals
from .spatial.model import SpatialModel
from .compiled_spatial_guard import guarded_step, replay_failure
from .compiled_spatial_signals import spatial_compile_refusal
from .compiled_spatial_parameters import (SpatialNumbers, parametrised_body_terms, parametrised_joint_law,
                                          parametrised_scene_terms, spatial_parameter_layout, spatial_parameter_vector,
                                          unparametrised_refusal)

__all__ = ["SpatialRates", "CompiledSpatialScene", "spatial_compile_refusal", "simulate_spatial_generated",
           "chain_period"]

FOLD_MIN_VELOCITIES = 20
"""Foldable models (:func:`chain_period`) with at least this many velocities are compiled through the fold
over segments, smaller ones as straight-line code (whose C, and gcc's time, grows with the velocities: about
0.07 s of CPU per revolute and 0.15 s per ball joint).  Measured (session 9, ``docs/spatial.md`` §6b; CPU
time, fresh cache, load 2-6 on 2 cores): revolute chains N = 20 / 30 first compile 1.6 / 2.7-3.1 s straight,
0.8 / 0.9 s folded, per step 11.9 / 18-19 us straight, 12.5 / 19-23 us folded; ball chains N = 10 / 30 compile
1.5 / 7.1 s straight, 0.8 / 1.1 s folded, per step 11.3 / 35.5 and 11.0 / 33.4 us."""
FOLD_KINDS = ("revolute", "prismatic", "universal", "spherical")
DEFAULT_ROWS = 64
"""Stored states per generated block call."""
SPATIAL_FLAGS = STRAIGHT_LINE_FLAGS
"""Compiler flags of spatial kernels: their straight-line C is long (about 700 instructions per revolute body
and rate), and ``-O1`` compiles it 3.5x faster than ``-O2`` and runs it as fast (a 100-link revolute
chain, one run on the 2-core machine: 50 s and 222 us per step against 172 s and 249 us).  The kernels of spatial
kinematic loops (alone and in the loop driver) use them too: the R-U-S-R four-bar's RK4 with projection compiles in
0.62x the gcc CPU of ``-O2`` at 0.93x its kernel CPU per step (``benchmarks/generated_flags.py``)."""
FOLD_FLAGS = ("-O3", "-shared", "-fPIC")
"""Compiler flags of folded kernels (:func:`folded_velocity_rate`): their C holds one segment whatever N (about
120 kB), so ``-O3`` costs a few tenths of a second more than ``-O1`` and runs the step about 25 % faster."""


class SpatialRates:
    """The rates ``y_dot = [G(q) v ; v_dot]`` of a spatial model on casadi symbols (a
    :class:`~ctmm.generated_loop.SymbolicRates`).

    Parameters
    ----------
    model : SpatialModel
        Compilable (:func:`spatial_compile_refusal`).
    fold : bool or None
        ``True``: the folds over equal segments (:func:`folded_velocity_rate`; refused for a model
        :func:`chain_period` does not fold); ``False``: straight-line; ``None``: the fold for foldable
        models of at least :data:`FOLD_MIN_VELOCITIES` velocities.
    numbers : {"constants", "inputs"}
        The model's numbers as constants of the code (``p`` empty) or as the parameter column ``p``
        (:func:`~ctmm.compiled_spatial_parameters.spatial_parameter_layout`).

    Attributes
    ----------
    period : int
        Bodies per folded segment (0: straight-line code).
    rate : casadi.Function
        ``(y, u, p, t) -> y_dot``, calling :attr:`velocity_rate`.
    velocity_rate : casadi.Function
        ``(q, v, u, p, t) -> v_dot`` (``t`` [s]: the loads' and driven joints' signals).
    layout : list of SpatialParameter
        The entries of ``p`` (empty with ``numbers="constants"``).
    actuators : tuple of str
        Input names, in the order of ``u``; :attr:`widths` their sizes.
    """

    def __init__(self, model: SpatialModel, *, fold: bool | None = None, numbers: str = "constants") -> None:
        reason = spatial_compile_refusal(model, time_signals=True)
        if reason:
            raise ModelError(f"SpatialRates: {reason}")
        if numbers not in ("constants", "inputs"):
            raise ModelError(f"SpatialRates: numbers must be 'constants' (one library per model) or 'inputs' (one "
                             f"library per structure), got {numbers!r}")
        refusal = unparametrised_refusal(model, "SpatialRates") if numbers == "inputs" else ""
        if refusal:
            raise ModelError(refusal)
        self.model = model
        self.layout = spatial_parameter_layout(model) if numbers == "inputs" else []
        self.actuators = tuple(model.inputs)
        self.widths = tuple(joint.velocity_count for joint in model.joints for _ in joint.inputs)
        period = chain_period(model)
        if fold and not period:
            raise ModelError(f"SpatialRates: fold=True needs a serial chain of at least two equal segments of "
                             f"{', '.join(FOLD_KINDS)} joints without loads or inputs; model {model.name!r} is not one")
        self.period = period if (fold or (fold is None and model.n_velocities >= FOLD_MIN_VELOCITIES)) else 0
        self._symbols: tuple | None = None      # (rate, velocity_rate): built when first read

    @property
    def rate(self) -> Any:
        """``(y, u, p, t) -> y_dot`` (casadi.Function, built on first use)."""
        if self._symbols is None:
            self._symbols = self._build()
        return self._symbols[0]

    @property
    def velocity_rate(self) -> Any:
        """``(q, v, u, p, t) -> v_dot`` (casadi.Function, built on first use)."""
        if self._symbols is None:
            self._symbols = self._build()
        return self._symbols[1]

    def _build(self) -> tuple[Any, Any]:
        """``(rate, velocity_rate)`` on casadi symbols."""
        import casadi as ca

        model, n_p = self.model, len(self.layout)
        nq, nv = model.n_positions, model.n_velocities
        if self.period:
            velocity_rate = folded_velocity_rate(model, self.period, self.layout)
            y, u_mx, p, t = ca.MX.sym("y", nq + nv), ca.MX.sym("u", 0), ca.MX.sym("p", n_p), ca.MX.sym("t")
            q_dot = y[nq:] if nq == nv else folded_position_rate(model, self.period)(y[:nq], y[nq:])
            return ca.Function("rate", [y, u_mx, p, t], [ca.vertcat(q_dot, velocity_rate(
                y[:nq], y[nq:], u_mx, p, t))]), velocity_rate
        q, v, t_sx = ca.SX.sym("q", nq), ca.SX.sym("v", nv), ca.SX.sym("t")
        u = ca.SX.sym("u", sum(self.widths))
        offsets = np.concatenate([[0], np.cumsum(self.widths)]).astype(int)
        inputs = {name: u[int(offsets[i]):int(offsets[i + 1])] for i, name in enumerate(self.actuators)}
        scene = SpatialScene(model)     # signals that are not constants (strict refusal): on the symbol t
        bodies, joints, states = scene.terms(CASADI, q, v, t_sx if spatial_compile_refusal(model) else 0.0, inputs)
        p_sx = ca.SX.sym("p", n_p)
        if self.layout:
            bodies, joints = parametrised_scene_terms(model, SpatialNumbers(self.layout, p_sx), bodies, joints, states,
                                                      q, v, inputs)
        solution = articulated_sweep(CASADI, scene.tree, bodies, joints)
        v_dot = ca.vertcat(*scene.velocity_rates(solution))
        velocity_rate = ca.Function("velocity_rate", [q, v, u, p_sx, t_sx], [v_dot])
        position_rate = ca.Function("position_rate", [q, v], [position_rates(model, q, v)])
        # on MX symbols the sweep stays one C function (an SX call would inline a second copy of it)
        y, u_mx, p, t = ca.MX.sym("y", nq + nv), ca.MX.sym("u", u.size1()), ca.MX.sym("p", n_p), ca.MX.sym("t")
        q_y, v_y = y[:nq], y[nq:]
        return ca.Function("rate", [y, u_mx, p, t], [ca.vertcat(position_rate(q_y, v_y),
                                                                velocity_rate(q_y, v_y, u_mx, p, t))]), velocity_rate

    def input_vector(self, inputs: Mapping[str, Any] | None) -> np.ndarray:
        """``u`` from ``{input name: number or (k,) numbers}`` held over a run (missing inputs zero).

        Raises
        ------
        ModelError
            Unknown names, wrong sizes, non-finite values, functions of time.
        """
        if inputs is not None and not isinstance(inputs, Mapping):
            raise ModelError(f"inputs must be a mapping {{input name: number}}, got {inputs!r}")
        values = [np.zeros(k) for k in self.widths]
        for name, value in dict(inputs or {}).items():
            if name not in self.actuators:
                raise ModelError(f"unknown spatial input {name!r}; allowed: {', '.join(self.actuators) or 'none'}")
            k = self.widths[self.actuators.index(name)]
            if callable(value):
                raise ModelError(f"input {name!r} is a function of time; the compiled path holds inputs as numbers "
                                 "over the run (give a number, or use ctmm.simulate without compiled=True)")
            array = np.asarray(value, dtype=float) if not isinstance(value, (str, bool)) else np.array(np.nan)
            array = np.full(k, float(array)) if array.ndim == 0 else array
            if array.shape != (k,) or not np.all(np.isfinite(array)):
                raise ModelError(f"input {name!r} must be {k} finite number(s) held over the run, got {value!r}")
            values[self.actuators.index(name)] = array
        return np.concatenate(values) if values else np.zeros(0)


def chain_period(model: SpatialModel) -> int:
    """The shortest segment length ``p`` of a model that the fold compiles, 0 when it cannot.

    Foldable: a serial chain (body ``j`` on body ``j - 1``, body 0 on the ground) of non-driven
    revolute, prismatic, universal or spherical joints without actuator inputs and loads, whose bodies
    ``0..N-1`` are ``N / p >= 2`` repetitions of ``p`` bodies with equal numbers (mass, inertia,
    centre of mass, the point carrying the next body, joint kind, axes, joint rotation, law, and from
    the second segment on the parent point of the joint).
    """
    n = model.n_bodies
    if model.loads or any(model.parent[j] != j - 1 for j in range(n)) or any(model.modal):
        return 0
    if any(joint.kind not in FOLD_KINDS or joint.driven or joint.inputs for joint in model.joints):
        return 0

    def numbers(values: Sequence[Any]) -> tuple:
        return tuple(None if value is None else tuple(np.ravel(value).tolist()) for value in values)

    def fixed(j: int) -> tuple:
        body, joint = model.bodies[j], model.joints[j]
        return (joint.kind,) + numbers([body.mass, body.inertia, body.center_of_mass, joint.rotation, joint.stiffness,
                                        joint.damping] + [getattr(joint, name, None) for name in
                                                          ("reference", "axis", "axis1", "axis2")]) + (
            repr(getattr(joint, "law", None)),)

    def outboard(j: int, period: int) -> Any:         # the last body: the point of its place in segment 0
        name = model.joints[j + 1].point if j + 1 < n else model.joints[j % period + 1].point
        return numbers([model.bodies[j].points.get(name)])[0]

    def inboard(j: int) -> Any:
        return numbers([model.bodies[j - 1].points[model.joints[j].point]])[0]

    for period in range(1, n // 2 + 1):
        if n % period:
            continue
        if all(fixed(j) == fixed(j % period) and outboard(j, period) is not None
               and outboard(j, period) == outboard(j % period, period)
               and (j < period or inboard(j) == inboard(j % period if j % period else period)) for j in range(n)):
            return period
    return 0


def folded_velocity_rate(model: SpatialModel, period: int, layout: Sequence[Any] = ()) -> Any:
    """``velocity_rate(q, v, u, p, t) -> v_dot`` of a chain of equal segments (:func:`chain_period`) as three
    folds over its ``N / period`` segments, so the generated code holds one segment whatever N:

    * ``kinematics`` (base to tip): pose and velocity of each segment's parent;
    * ``eliminate`` (tip to base) and ``accelerate`` (base to tip): the segment's articulated sweep between a
      virtual parent and a virtual welded child (:func:`ctmm.segment_fold.fold_segments`), giving the
      segment's joint accelerations.

    The segment's terms are formed once (the eliminate fold hands the accelerate fold the terms it reads),
    in code whose size does not grow with N.  With a parameter ``layout``
    (:func:`~ctmm.compiled_spatial_parameters.spatial_parameter_layout`, body by body, then gravity)
    each segment takes its own column of the bodies' entries and every segment the gravity entries.
    Spherical joints' quaternions enter as in the straight-line code (rotation of ``q / |q|``); their
    rates ``q_dot`` are :func:`folded_position_rate`.
    """
    import casadi as ca

    n = model.n_bodies
    count = n // period
    segment = range(period)
    nq = [model.layout[i].position.stop - model.layout[i].position.start for i in segment]
    nv = [model.layout[i].velocity.stop - model.layout[i].velocity.start for i in segment]
    nq_segment, nv_segment = sum(nq), sum(nv)
    child_point = model.joints[period % n].point           # the point of body period - 1 carrying the next
    first_point = np.asarray(model.bodies[period - 1].points[child_point], dtype=float)
    ground = np.asarray(model.joints[0].point, dtype=float) - first_point
    state, q, v = ca.SX.sym("parent", 18), ca.SX.sym("q", nq_segment), ca.SX.sym("v", nv_segment)
    segment_layout = [entry for entry in layout if entry.kind != "gravity" and entry.index < period]
    gravity_layout = [entry for entry in layout if entry.kind == "gravity"]
    p_segment, p_gravity = ca.SX.sym("p", len(segment_layout)), ca.SX.sym("g", len(gravity_layout))
    numbers = None
    if layout:
        gravity = SpatialNumbers(gravity_layout, p_gravity).gravity
        numbers = SpatialNumbers(segment_layout, p_segment, gravity)

    def terms(parent: Any) -> tuple[list, list, Any]:
        rotation, origin, velocity, omega = ca.reshape(parent[:9], 3, 3), parent[9:12], parent[12:15], parent[15:18]
        bodies, joints, offset_q, offset_v = [], [], 0, 0
        inboard = first_point
        for i in segment:
            body, joint = model.bodies[i], model.joints[i]
            qi = [q[offset_q + k] for k in range(nq[i])]
            vi = [v[offset_v + k] for k in range(nv[i])]
            offset_q, offset_v = offset_q + nq[i], offset_v + nv[i]
            outboard = model.joints[(i + 1) % n].point
            rotation, origin, velocity, omega, body_terms, joint_terms = _segment_body(
                model, body, joint, qi, vi, rotation, origin, velocity, omega, inboard, outboard, numbers, i)
            bodies.append(body_terms)
            joints.append(joint_terms)
            inboard = np.asarray(body.points[outboard], dtype=float)
        return bodies, joints, ca.vertcat(ca.reshape(rotation, 9, 1), origin, velocity, omega)

    bodies, joints, last = terms(state)
    kinematics = ca.Function("kinematics", [state, q, v], [last, state])
    # the folds (ctmm.segment_fold): columns are segments
    q_all, v_all, u = ca.MX.sym("q", model.n_positions), ca.MX.sym("v", model.n_velocities), ca.MX.sym("u", 0)
    p_all, t = ca.MX.sym("p", len(layout)), ca.MX.sym("t")          # t: no time signals in a folded chain
    Q, V = ca.reshape(q_all, nq_segment, count), ca.reshape(v_all, nv_segment, count)
    P = ca.reshape(p_all[:count * len(segment_layout)], len(segment_layout), count)
    G = ca.repmat(p_all[count * len(segment_layout):], 1, count)
    start = ca.DM(np.r_[np.eye(3).ravel(), ground, np.zeros(6)])
    _, parents = kinematics.mapaccum("kinematics_fold", count)(start, Q, V)
    accelerations = fold_segments(bodies, joints, [model.joints[(i + 1) % n].point for i in segment],
                                  [state, q, v, p_segment, p_gravity], [parents, Q, V, P, G],
                                  lambda solution: ca.vertcat(*solution.relative[1:period + 1]))
    return ca.Function("velocity_rate", [q_all, v_all, u, p_all, t], [ca.reshape(accelerations, model.n_velocities,
                                                                                 1)])


def folded_position_rate(model: SpatialModel, period: int) -> Any:
    """``position_rate(q, v) -> q_dot = G(q) v`` of a chain of equal segments (:func:`chain_period`): the
    segment's rates (:func:`position_rates` of its joints) mapped over the ``N / period`` segments."""
    import casadi as ca

    layouts = model.layout[:period]
    nq, nv = layouts[period - 1].position.stop, layouts[period - 1].velocity.stop
    q, v = ca.SX.sym("q", nq), ca.SX.sym("v", nv)
    parts = [_quaternion_rate(q[lay.position], v[lay.velocity]) if joint.kind == "spherical" else v[lay.velocity]
             for joint, lay in zip(model.joints[:period], layouts)]
    count = model.n_bodies // period
    segment = ca.Function("position_rate_segment", [q, v], [ca.vertcat(*parts)]).map(count)
    q_all, v_all = ca.MX.sym("q", nq * count), ca.MX.sym("v", nv * count)
    rates = segment(ca.reshape(q_all, nq, count), ca.reshape(v_all, nv, count))
    return ca.Function("position_rate", [q_all, v_all], [ca.reshape(rates, nq * count, 1)])


def _segment_body(model: SpatialModel, body: Any, joint: Any, q: list, v: list, rotation: Any, origin: Any,
                  velocity: Any, omega: Any, inboard: np.ndarray, outboard: str,
                  numbers: SpatialNumbers | None = None, index: int = 0) -> tuple:
    """Pose, velocity, body and joint terms of one body of a folded chain on its parent's pose and
    velocity (:func:`ctmm.spatial.body_forms.child_motion`, the per-body statements of
    :meth:`SpatialScene.terms`, for a non-driven joint without loads on a moving parent); with ``numbers``,
    body ``index`` of the segment takes them."""
    import casadi as ca

    rel = joint_motion(CASADI, joint, q, v, None, None)
    arm = ca.mtimes(rotation, constant(CASADI, inboard))
    motion = child_motion(CASADI, joint.rotation, rel, rotation, origin + arm, velocity + cross(CASADI, omega, arm),
                          omega)
    state = motion.state
    joint_terms = motion.joint
    pose = dict(center_of_mass=body.center_of_mass, points={outboard: body.points[outboard]}, rotation=state.rotation,
                offset=motion.offset, omega=motion.omega)
    if numbers is None:
        body_terms = rigid_body_terms(CASADI, mass=body.mass, inertia=body.inertia, gravity=model.gravity, **pose)
    else:
        mass, inertia = numbers.body(index)
        body_terms = parametrised_body_terms(mass, inertia, numbers.gravity, **pose)
        if numbers.has_law(index, len(v)):
            joint_terms = parametrised_joint_law(joint_terms, numbers.law(index, len(v)), q, v, None)
    return state.rotation, state.origin, state.velocity, state.omega, body_terms, joint_terms


def position_rates(model: SpatialModel, q: Any, v: Any) -> Any:
    """``q_dot = G(q) v`` on casadi symbols (:meth:`SpatialModel.position_rates` on numbers)."""
    import casadi as ca

    parts = []
    for joint, layout in zip(model.joints, model.layout):
        qj, vj = q[layout.position], v[layout.velocity]
        if joint.kind == "spherical":
            parts.append(_quaternion_rate(qj, vj))
        elif joint.kind in ("free", "elastic6"):
            rotation = quaternion_rotation(CASADI, qj[3], qj[4], qj[5], qj[6])
            parts += [ca.mtimes(rotation, vj[:3]), _quaternion_rate(qj[3:], vj[3:])]
        elif layout.position.stop > layout.position.start:
            parts.append(vj)
    parts += [v[layout.velocity] for layout in model.modal if layout is not None]      # beams: eta_dot
    return ca.vertcat(*parts)


def _quaternion_rate(quaternion: Any, omega: Any) -> Any:
    import casadi as ca

    # the numpy statement on object arrays of symbols (one row): the same formula, no second copy
    rate = quaternion_rate(np.array([[quaternion[i] for i in range(4)]], dtype=object),
                           np.array([[omega[i] for i in range(3)]], dtype=object))
    return ca.vertcat(*rate[0])


class CompiledSpatialScene:
    """Generated and compiled RK4 time loop of one spatial model.

    Parameters
    ----------
    model : SpatialModel
        Compilable (:func:`spatial_compile_refusal`).
    store_every : int
        Steps per stored state.
    rows : int
        Stored states per generated block (one C call) [-].
    cache_dir, compiler, flags
        Of :func:`ctmm.codegen.shared_library` (``flags`` default :data:`SPATIAL_FLAGS`, folded rates
        :data:`FOLD_FLAGS`; ``-O0`` compiles faster still and runs slower, same numbers to round-off).
    fold : bool or None
        Compile the rates as folds over equal segments (:func:`chain_period`, :func:`folded_velocity_rate`):
        ``True`` (refused for a model that is not such a chain), ``False`` straight-line code, ``None``
        (default) the fold for foldable models of at least :data:`FOLD_MIN_VELOCITIES` velocities.
    numbers : {"constants", "inputs"}
        The model's numbers as constants of the code (one library per model) or as the parameter
        column ``p`` (one library per structure; :mod:`ctmm.compiled_spatial_parameters`).

    Attributes
    ----------
    rates : SpatialRates
        The rates on symbols.
    parameters : ndarray
        The model's :func:`~ctmm.compiled_spatial_parameters.spatial_parameter_vector` (empty with
        ``numbers="constants"``), the ``p`` of every call.
    compile_time_s : float
        Wall time of building the expressions, generating C and compiling (or loading) [s].
    plain_step : callable
        The compiled ``step(y, u, h, p, t0, k)`` without the flexible bodies' guard (the run steps with
        :func:`~ctmm.compiled_spatial_guard.guarded_step`).
    """

    def __init__(self, model: SpatialModel, *, store_every: int = 1, rows: int = DEFAULT_ROWS,
                 cache_dir: str | os.PathLike | None = None, compiler: str | None = None,
                 flags: Sequence[str] | None = None, fold: bool | None = None, numbers: str = "constants") -> None:
        reason = spatial_compile_refusal(model, time_signals=True)
        if reason:
            raise ModelError(f"CompiledSpatialScene: {reason}")
        store_every = validation.integer("store_every", store_every, minimum=1)
        if isinstance(rows, bool) or not isinstance(rows, (int, np.integer)) or rows < 1:
            raise ModelError(f"CompiledSpatialScene: rows must be an integer >= 1 (stored states per block), got "
                             f"{rows!r}")
        start = clock.perf_counter()
        self.model, self.store_every, self.rows = model, store_every, int(rows)
        self.rates = SpatialRates(model, fold=fold, numbers=numbers)
        self.parameters = spatial_parameter_vector(model) if numbers == "inputs" else np.zeros(0)

        def build() -> tuple[Any, list]:
            plain_step = rk4_step_function(self.rates.rate)
            step = guarded_step(model, plain_step)          # NaN once a flexible body leaves its bounds
            return step, [self.rates.velocity_rate, *([] if step is plain_step else [plain_step])]

        name = f"spatial_{model.n_bodies}b{model.n_positions}q{model.n_velocities}v" + (
            f"_fold{self.rates.period}" if self.rates.period else "")
        options = {"cache_dir": cache_dir, "compiler": compiler,
                   "flags": (FOLD_FLAGS if self.rates.period else SPATIAL_FLAGS) if flags is None else tuple(flags)}
        from .model_description import describe   # what build() reads: a cached library loads without symbols

        description = describe((model, fold, numbers)) if numbers == "constants" else None   # "inputs": by structure
        if description is not None:
            loop = compiled_time_loop(build, store_every, self.rows, name, description=[("spatial", description)],
                                      **options)
        else:
            step, extra = build()
            loop = compiled_time_loop(step, store_every, self.rows, name, extra=extra, **options)
        self._velocity_rate, self._step, self._stride, self._blocks = loop.extra[0], loop.step, loop.stride, loop.blocks
        self.plain_step = loop.extra[1] if len(loop.extra) > 1 else self._step
        self.compile_time_s = clock.perf_counter() - start

    def accelerations(self, q: Any, v: Any, inputs: Mapping[str, Any] | None = None, t: float = 0.0) -> np.ndarray:
        """``v_dot`` (nv,) at ``q`` (nq,), ``v`` (nv,), time ``t`` [s] with held ``inputs`` (generated code)."""
        q, v = self.model.check_state(q, v)
        return np.asarray(self._velocity_rate(q[0], v[0], self.rates.input_vector(inputs), self.parameters,
                                              validation.finite("t", t))).reshape(-1)

    def run(self, x0: np.ndarray, dt: float, n_steps: int, inputs: Mapping[str, Any] | None = None,
            parameters: np.ndarray | None = None) -> np.ndarray:
        """Stored states ``[q ; v]`` (rows, nq + nv) after each ``store_every`` steps and after the last of
        ``n_steps`` RK4 steps of ``dt`` [s] from ``x0`` at ``t = 0`` (initial state excluded); a step after which a
        flexible body leaves its bounds gives NaN (:func:`~ctmm.compiled_spatial_guard.guarded_step`); stops
        after the first block holding a non-finite state.  ``parameters`` (B, n_p): B parameter columns of models
        of this structure (``numbers="inputs"``), run together in one C call per block (``casadi.Function.map``,
        serial; rows of a diverged member non-finite): states (B, rows, nq + nv)."""
        x0 = np.asarray(x0, dtype=float).reshape(-1)
        nq = self.model.n_positions
        self.model.check_state(x0[:nq], x0[nq:])
        p = self.parameters[None] if parameters is None else np.asarray(parameters, dtype=float)
        if p.ndim != 2 or p.shape[1] != self.parameters.size or not len(p):
            raise ModelError(f"parameters must be a (B, {self.parameters.size}) array, got shape {p.shape}")
        states = run_blocks(self._blocks, self._stride, self._step, self.store_every, np.repeat(x0[:, None], len(p), 1),
                            self.rates.input_vector(inputs), validation.positive("dt", dt),
                            validation.integer("n_steps", n_steps, minimum=1), 0.0, p.T.copy())
        return states[0] if parameters is None else states


def simulate_spatial_generated(model: SpatialModel, t_final: float, dt: float, *, x0: Any = None, v0: Any = None,
                               inputs: Mapping[str, Any] | None = None, store_every: int = 1,
                               divergence_bound: float | None = None, cache_dir: str | os.PathLike | None = None,
                               scene: CompiledSpatialScene | None = None,
                               ran: tuple[np.ndarray, float] | None = None) -> SimulationResult:
    """RK4 of a spatial model with the time loop in generated C (``ctmm.simulate(..., compiled=True)``).

    Same arguments and result as :func:`ctmm.spatial.integrate.simulate_spatial` with ``method="rk4"``
    (signals, units, times; ``scheme_name`` ``"rk4-generated"``; ``info`` adds ``compile_time_s``);
    inputs are numbers held over the run.  ``scene``: a :class:`CompiledSpatialScene` of ``model`` with
    this ``store_every`` to reuse (default: built now, the C cached on disk); ``ran``: its stored states and wall
    time [s] computed already (one member of :meth:`CompiledSpatialScene.run` with ``parameters``).

    Raises
    ------
    ModelError
        A model the generated path cannot compile (:func:`spatial_compile_refusal`), bad arguments.
    SimulationError
        A non-finite stored state, one farther than ``divergence_bound`` from the start, or a step after which a
        :class:`~ctmm.spatial.SpatialBeam`'s deflection bound exceeds its length or a
        :class:`ctmm.fem.SpatialSubsystem` leaves its small deformation (checked inside the generated run after
        every step, :mod:`ctmm.compiled_spatial_guard`; the time and element of the numpy RK4), with the result
        up to the last good stored state.
    """
    t_final = validation.positive("t_final", t_final)
    if dt is None:
        raise ModelError("dt is required with method='rk4' (a fixed step [s], > 0), got None")
    dt = validation.positive("dt", dt)
    store_every = validation.integer("store_every", store_every, minimum=1)
    if divergence_bound is not None:
        divergence_bound = validation.positive("divergence_bound", divergence_bound)
    n_steps = validation.whole_step_count(t_final, dt)
    reason = spatial_compile_refusal(model, time_signals=True)
    if reason:
        raise ModelError(f"compiled=True: {reason}")
    x = initial_state(model, x0, v0)
    if scene is None:
        scene = CompiledSpatialScene(model, store_every=store_every, cache_dir=cache_dir)
    elif not isinstance(scene, CompiledSpatialScene) or scene.model is not model or scene.store_every != store_every:
        raise ModelError(f"scene must be a CompiledSpatialScene of this model with store_every={store_every!r}, got "
                         f"{scene!r}")
    start = clock.perf_counter()
    states = scene.run(x, dt, n_steps, inputs) if ran is None else ran[0]
    wall = clock.perf_counter() - start if ran is None else ran[1]
    steps = np.array([k for k in range(1, n_steps + 1) if k % store_every == 0 or k == n_steps])[:len(states)]
    times = np.concatenate([[0.0], steps * dt])
    states = np.vstack([x[None], states])
    info = {"dt": dt, "method": "rk4-generated", "wall_time_s": wall, "n_evaluations": 4 * n_steps,
            "compile_time_s": scene.compile_time_s}
    bad = ~np.all(np.isfinite(states), axis=1)
    if divergence_bound is not None:
        bad |= np.any(np.abs(np.where(np.isfinite(states), states - states[:1], 0.0)) > divergence_bound, axis=1)
    if np.any(bad):
        first = int(np.flatnonzero(bad)[0])

        def partial() -> SimulationResult:
            return _result(model, times[:first], states[:first], info)

        # the guarded run stopped (NaN) or a stored state is bad: step again from the last good stored state,
        # checking every step as the numpy RK4 does (the same time and element, also between stored states)
        replay_failure(model, scene.plain_step, x, states[first - 1], scene.rates.input_vector(inputs),
                       scene.parameters, dt, int(round(times[first - 1] / dt)), int(round(times[first] / dt)),
                       divergence_bound, partial)
        finite = np.all(np.isfinite(states[first]))
        what = f"beyond divergence_bound = {divergence_bound}" if finite else "non-finite"
        raise SimulationError(f"{model.name}: the state became {what} at t = {times[first]} s (rk4-generated; checked "
                              f"on the stored states)", time=float(times[first]), element=model.name,
                              partial_result=partial())
    try:                    # the subsystems' small-deformation warnings (their bounds were checked in the run)
        check_beam_deflection(model, beam_deflection_weights(model), times, states, "rk4-generated")
    except SimulationError as exc:
        first = int(np.searchsorted(times, exc.time))
        exc.partial_result = _result(model, times[:first], states[:first], info) if first else None
        raise
    return _result(model, times, states, info)


def _result(model: SpatialModel, times: np.ndarray, states: np.ndarray, info: dict) -> SimulationResult:
    signals, units = spatial_signals(model, times, states)
    return signal_result(SignalSystem(model, units), times, signals, "rk4-generated", info)

