"""Forward dynamics of spatial models through the one articulated sweep: accelerations, joint
reactions and the first-order ODE right-hand side (issue 14, ``docs/spatial.md``)."""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Any, Mapping

import numpy as np

from .. import validation
from ..articulated import SingularPivotError
from ..errors import ModelError, SimulationError
from .beam_terms import beam_energy
from .body_forms import SpatialScene
from .model import SpatialModel

__all__ = ["SpatialSolution", "solve", "solve_scene", "scene_solution", "accelerations", "reactions", "state_rates",
           "scene_state_rates", "scene_of", "energy"]


def _batched(column: Any, batch: int) -> np.ndarray:
    """A batched column ``(b, k, 1)`` (``b`` is ``batch`` or 1) as ``(batch, k)`` (a view)."""
    column = np.asarray(column)
    if column.shape[0] != batch:
        column = np.broadcast_to(column, (batch,) + column.shape[1:])
    return column[:, :, 0]


def scene_of(model: SpatialModel) -> SpatialScene:
    """The :class:`SpatialScene` of a model (cheap; the model is immutable); anything else is refused."""
    if not isinstance(model, SpatialModel):
        raise ModelError(f"model must be a ctmm.spatial.SpatialModel, got {model!r:.80}")
    return SpatialScene(model)


@dataclass(frozen=True)
class SpatialSolution:
    """One instant of a spatial model (batched over ``B``).

    Attributes
    ----------
    velocity_rates : (B, nv) array
        ``v_dot`` [m/s^2, rad/s^2] in the model's velocity convention (child axes).
    reactions : (B, n_bodies, 6) array
        Wrench ``[f ; m]`` of the parent (or ground) on each body at its inboard point, world axes
        [N, N m] (moment about the inboard point).
    point_accelerations : (B, n_bodies, 6) array
        ``[a ; alpha]`` of each body's inboard point, world axes [m/s^2, rad/s^2].
    """

    velocity_rates: np.ndarray
    reactions: np.ndarray
    point_accelerations: np.ndarray


def solve(model: SpatialModel, q: Any, v: Any, t: float = 0.0, inputs: Mapping[str, Any] | None = None,
          wrenches: Mapping[int, Any] | None = None) -> SpatialSolution:
    """Accelerations and reactions at one state (or a batch of states).

    Parameters
    ----------
    model : SpatialModel
    q : (nq,) or (B, nq) array
        Joint coordinates (quaternions need not be unit: rotations are formed from the normalised ones).
    v : (nv,) or (B, nv) array
        Joint velocities (child axes for spherical, free and elastic joints).
    t : float
        Time [s].
    inputs : mapping, optional
        ``{"<joint>.torque" | "<joint>.force" | "<joint>.wrench": value or f(t)}`` (missing: zero).
    wrenches : mapping, optional
        Extra applied loads ``{body index: [(point (3,) body axes [m], (6, 1) [f ; m] world axes)]}``
        (the body-force actuators of :mod:`ctmm.spatial.ports`).

    Raises
    ------
    ModelError
        Wrong sizes, non-finite or zero-quaternion states, unknown inputs.
    SimulationError
        A singular articulated pivot (a joint whose free directions carry no inertia to round-off), naming the
        time and the joint (``element``).
    """
    return solve_scene(scene_of(model), q, v, t, inputs, wrenches)


def solve_scene(scene: SpatialScene, q: Any, v: Any, t: float = 0.0, inputs: Mapping[str, Any] | None = None,
                wrenches: Mapping[int, Any] | None = None) -> SpatialSolution:
    """:func:`solve` on a model's :class:`SpatialScene` (built once per model and run by the callers that hold
    one, e.g. :class:`~ctmm.spatial.ports.SpatialPorts`); the same checks of ``t``, ``inputs`` and ``wrenches``."""
    t = validation.finite("t", t)
    if inputs is not None and not isinstance(inputs, Mapping):
        raise ModelError(f"inputs must be a mapping {{input name: number or f(t)}}, got {inputs!r:.80}")
    return scene_solution(scene, q, v, t, inputs, _checked_wrenches(scene.model, wrenches))


def scene_solution(scene: SpatialScene, q: Any, v: Any, t: float, inputs: Mapping[str, Any] | None = None,
                   wrenches: Mapping[int, Any] | None = None) -> SpatialSolution:
    """:func:`solve` on a model's :class:`SpatialScene` with a finite time ``t`` [s], an ``inputs`` mapping (or
    ``None``) and ``wrenches`` of the checked form (callers that built them, e.g. the ports' actuators, in inner
    loops); the state is checked and failures are reported as there."""
    model = scene.model
    try:
        solution = scene.solve(q, v, t, inputs, wrenches)
    except SingularPivotError as exc:
        joint = model.joints[exc.body]
        raise SimulationError(f"{model.name}: the articulated pivot of joint {joint.name!r} ({joint.kind}, "
                              f"{joint.velocity_count} free directions) is singular at t = {t} s: the subtree "
                              "it carries has no inertia in some free direction (to round-off)", time=t,
                              element=joint.name) from exc
    batch = np.asarray(solution.force[0]).shape[0]
    pieces = scene.velocity_rates(solution)
    if all(type(a) is np.ndarray and a.ndim == 3 and a.shape[0] == batch for a in (*pieces, *solution.force,
                                                                                  *solution.x)):
        # every column of the batch's size (the usual case): one copy each, the columns' entries as they are
        rates = np.concatenate(pieces, axis=1)[:, :, 0] if pieces else np.zeros((batch, 0))
        forces = np.stack(solution.force, axis=1)[..., 0]
        points = np.stack([x[:, :6] for x in solution.x], axis=1)[..., 0]
    else:
        parts = [_batched(a, batch) for a in pieces]
        rates = np.concatenate(parts, axis=1) if parts else np.zeros((batch, 0))
        forces = np.stack([_batched(f, batch) for f in solution.force], axis=1)
        points = np.stack([_batched(np.asarray(x)[:, :6], batch) for x in solution.x], axis=1)
    if not (np.all(np.isfinite(rates)) and np.all(np.isfinite(forces))):
        raise SimulationError(f"{model.name}: the articulated sweep gave non-finite accelerations at t = {t} s "
                              "(a singular pivot: a joint whose free directions carry no inertia)", time=t,
                              element=model.name)
    return SpatialSolution(rates, forces, points)


def _checked_wrenches(model: SpatialModel, wrenches: Any) -> Mapping[int, Any] | None:
    """``wrenches`` of :func:`solve` checked: ``{body index: [(point, [f ; m]) or (point, [f ; m], "body")]}``
    with a known body index, a finite (3,) point [m] and six finite load components [N, N m], else
    :class:`ModelError` naming the entry."""
    if wrenches is None:
        return None
    allowed = (f"a mapping {{body index 0..{len(model.bodies) - 1}: list of (point (3,) [m], [f ; m] (6, 1) "
               "[N, N m]) or (point, [f ; m], 'body')}")
    if not isinstance(wrenches, Mapping):
        raise ModelError(f"wrenches must be {allowed}, got {wrenches!r:.80}")
    for body, entries in wrenches.items():
        if isinstance(body, bool) or not isinstance(body, (int, np.integer)) or not 0 <= body < len(model.bodies):
            raise ModelError(f"wrenches must be {allowed}; the key {body!r} is not a body index")
        if not isinstance(entries, (list, tuple)):
            raise ModelError(f"wrenches[{body}] must be a list of (point, [f ; m]) entries, got {entries!r:.80}")
        for entry in entries:
            if not (isinstance(entry, tuple) and len(entry) in (2, 3) and (len(entry) == 2 or entry[2] == "body")):
                raise ModelError(f"wrenches[{body}] entries must be (point, [f ; m]) or (point, [f ; m], 'body'), "
                                 f"got {entry!r:.80}")
            point = validation.finite_array(f"wrenches[{body}] point", entry[0])
            load = validation.finite_array(f"wrenches[{body}] [f ; m]", entry[1])
            if point.shape != (3,) or load.shape[-2:] != (6, 1):
                raise ModelError(f"wrenches[{body}] entries must be (point (3,), [f ; m] (6, 1) or (B, 6, 1)), got "
                                 f"shapes {point.shape} and {load.shape}")
    return wrenches


def _unbatch(array: np.ndarray, q: Any) -> np.ndarray:
    return array[0] if np.ndim(q) == 1 else array


def accelerations(model: SpatialModel, q: Any, v: Any, t: float = 0.0, inputs: Mapping[str, Any] | None = None,
                  wrenches: Mapping[int, Any] | None = None) -> np.ndarray:
    """``v_dot`` (nv,) or (B, nv) of a spatial model (:func:`solve`)."""
    return _unbatch(solve(model, q, v, t, inputs, wrenches).velocity_rates, q)


def reactions(model: SpatialModel, q: Any, v: Any, t: float = 0.0, inputs: Mapping[str, Any] | None = None
              ) -> np.ndarray:
    """Joint reactions (n_bodies, 6) or (B, n_bodies, 6): wrench ``[f ; m]`` of the parent on each body at
    its inboard point, world axes [N, N m] (:func:`solve`)."""
    return _unbatch(solve(model, q, v, t, inputs).reactions, q)


def state_rates(model: SpatialModel, x: np.ndarray, t: float, inputs: Mapping[str, Any] | None = None
                ) -> np.ndarray:
    """``x_dot = [G(q) v ; v_dot]`` of the state ``x = [q ; v]`` (1-D or ``(B, nq + nv)``)."""
    return scene_state_rates(scene_of(model), x, t, inputs)


def scene_state_rates(scene: SpatialScene, x: np.ndarray, t: float, inputs: Mapping[str, Any] | None = None
                      ) -> np.ndarray:
    """:func:`state_rates` on a model's :class:`SpatialScene` (one scene per run: its per-model numbers are
    formed once, :func:`ctmm.spatial.integrate.simulate_spatial`)."""
    model = scene.model
    size = model.n_positions + model.n_velocities
    if isinstance(x, (str, bytes, bool, Mapping)) or x is None or np.shape(x)[-1:] != (size,):
        raise ModelError(f"x must be the state [q ; v]: {size} numbers (or (B, {size})), got {x!r:.80}")
    x = validation.finite_array("x (the state [q ; v])", x)
    q, v = x[..., :model.n_positions], x[..., model.n_positions:]
    if inputs is not None and not isinstance(inputs, Mapping):
        raise ModelError(f"inputs must be a mapping {{input name: number or f(t)}}, got {inputs!r:.80}")
    rates = scene_solution(scene, q, v, validation.finite("t", t), inputs).velocity_rates
    out = np.concatenate([model.position_rates(q if q.ndim == 2 else q[None], v if v.ndim == 2 else v[None]),
                          rates], axis=-1)
    return out[0] if x.ndim == 1 else out


def energy(model: SpatialModel, q: Any, v: Any, t: float = 0.0) -> np.ndarray:
    """Kinetic + gravitational + joint-spring energy [J] (scalar, or (B,) for a batch).

    Beams (:class:`~ctmm.spatial.beam.SpatialBeam`): kinetic, modal elastic ``1/2 eta^T K eta`` and
    gravitational energy (the geometric stiffening has no potential here).
    Springs counted: revolute, prismatic and universal ``1/2 k (q - q_ref)^2``; spherical joints with a
    scalar stiffness ``k I``: ``2 k (1 - w^2)`` (unit quaternion).  A spherical joint with an anisotropic
    stiffness and :class:`~ctmm.spatial.elements.Elastic6` have no potential here (``ModelError``).
    """
    from ..ops import NUMPY

    scene = scene_of(model)                            # anything but a SpatialModel: ModelError
    q_rows, v_rows = model.check_state(q, v)
    _, _, states = scene.terms(NUMPY, q_rows, v_rows, t, kinematics_only=True)
    total = np.zeros(q_rows.shape[0])
    for body, state, modal in zip(model.bodies, states, model.modal):
        if modal is not None:                          # a beam: kinetic, elastic and gravitational energy
            B = len(total)
            energy_of = getattr(body, "energy", None) or partial(beam_energy, body)      # or ctmm.fem's subsystem
            total = total + energy_of(np.broadcast_to(state.rotation, (B, 3, 3)),
                                        np.broadcast_to(state.origin, (B, 3, 1)),
                                        np.broadcast_to(state.velocity, (B, 3, 1)),
                                        np.broadcast_to(state.omega, (B, 3, 1)), q_rows[:, modal.position],
                                        v_rows[:, modal.velocity], model.gravity)
            continue
        R = state.rotation
        arm = R @ body.center_of_mass[:, None]
        v_com = (state.velocity + np.cross(state.omega, arm, axis=1))[..., 0]
        omega = state.omega[..., 0]
        inertia = R @ body.inertia @ np.swapaxes(R, -1, -2)
        total = total + 0.5 * body.mass * np.sum(v_com ** 2, axis=-1) \
            + 0.5 * np.einsum("bi,bij,bj->b", np.broadcast_to(omega, (len(total), 3)),
                              np.broadcast_to(inertia, (len(total), 3, 3)), np.broadcast_to(omega, (len(total), 3))) \
            - body.mass * ((state.origin + arm)[..., 0] @ model.gravity)
    for joint, layout in zip(model.joints, model.layout):
        if joint.driven or joint.kind in ("weld", "free"):
            continue
        qj = q_rows[:, layout.position]
        if joint.kind in ("revolute", "prismatic", "universal"):
            total = total + 0.5 * np.sum(joint.stiffness * (qj - joint.reference) ** 2, axis=1)
            if joint.law is not None:
                total = total + np.sum(joint.law.potential(qj - joint.reference), axis=1)
        elif joint.kind == "spherical":
            k = joint.stiffness[0, 0]
            if not np.allclose(joint.stiffness, k * np.eye(3)):
                raise ModelError(f"energy: spherical joint {joint.name!r} has an anisotropic stiffness, whose law "
                                 "has no potential; energy is defined for scalar stiffness k I only")
            total = total + 2 * k * (1 - qj[:, 0] ** 2 / np.sum(qj ** 2, axis=1))
        elif np.any(joint.stiffness):
            raise ModelError(f"energy: the Elastic6 joint {joint.name!r} has no potential here (its linear law is "
                             "for small deformations); energy is defined without elastic 6-DOF springs")
    return total[0] if np.ndim(q) == 1 else total
