"""The joints of a spatial model as elements of its exact-field spatial beam chain (``fields="exact"``).

About the rest configuration a joint of :class:`~ctmm.spatial.model.SpatialModel` moves its child
relative to its parent by ``[u ; theta] = A q_dot dt`` (the joint's **motion matrix** ``A``, 6 x nv,
chain axes: :func:`motion_matrix`) and its linear law is a stiffness ``K_q`` and damping ``C_q`` on its
velocity coordinates (:func:`joint_law`: per coordinate for revolute, prismatic and universal joints;
the 3 x 3 rotary law of a spherical joint, the 6 x 6 law of an elastic6 joint on the child-axes
translation and ``2 w (x, y, z)`` of its quaternion, both ``[u ; theta]`` to first order).

**At the ground** (:func:`base_elements`) the held directions are the complement of ``A``'s range:

* a weld -> :class:`SpatialClamped`; a free or elastic6 joint -> :class:`SpatialFree`;
* a revolute, prismatic, universal or spherical joint -> :class:`SpatialSupport` holding the chain
  components outside ``A``'s range (a spherical joint: the three translations, :class:`SpatialPinned`'s
  condition; a universal joint: the translations and the rotation about ``axis1 x axis2``), so ``A``'s
  range must be spanned by chain axes (the bridge turns the chain axes so: a revolute or prismatic axis,
  or a universal joint's ``axis1 x axis2``, is the chain's ``z``; otherwise refused);
* the law as a :class:`SpatialGroundSpring` ``K = A^+T K_q A^+`` (``A^+`` the pseudo-inverse: the
  generalised forces ``A^T [f ; m]`` of the wrench; the held part is taken by the support).

**Between bodies** (:func:`inner_elements`) a joint needs a law in every free direction (a free direction
inside the chain has no transfer matrix): a revolute -> :class:`SpatialHinge`; a universal joint -> two
hinges in series about ``axis1`` and ``axis2`` (the relative rotation ``a1 q1 + a2 q2`` with
``a_i . m = -(k_i + c_i s) q_i``, for any angle between the axes); a spherical joint -> three hinges about
the principal axes of its stiffness (its damping must share them); an elastic6 joint with a positive
definite stiffness -> :class:`SpatialSpring`.  Prismatic and free joints between bodies are refused.

Ports (:func:`joint_ports`): the joint's coordinate sensors ``A^+ [u ; theta]`` of the relative motion
(``"<joint>.angle"``, ``".position"``, ``".q1|q2"``, a free joint's ``".x|y|z"``), their rates and the
velocity sensors (``".rate"``, ``".wx|wy|wz"``, ``".vx|vy|vz"``, child axes), and the actuators of an
actuated joint: the wrench ``A^+T e_k`` on the child (and its opposite on the parent).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .errors import ModelError

__all__ = ["motion_matrix", "joint_law", "base_axis", "base_elements", "inner_elements", "joint_ports",
           "rigid_mode_count", "CONVERTED_KINDS"]

#: Joint kinds the bridge converts (at the ground; between bodies all but prismatic and free).
CONVERTED_KINDS = ("weld", "revolute", "prismatic", "universal", "spherical", "free", "elastic6")
_DISPLACEMENTS = ("ux", "uy", "uz", "theta_x", "theta_y", "theta_z")
_FORCES = ("fx", "fy", "fz", "mx", "my", "mz")
#: Relative size below which a term or a projector entry is zero.
_SMALL = 1e-12


def _refuse(model_name: str, reason: str) -> ModelError:
    return ModelError(f"fields='exact' cannot convert spatial model {model_name!r}: {reason}")


def base_axis(joint: Any) -> np.ndarray | None:
    """The world direction a ground joint wants as the chain's ``z`` (a revolute or prismatic axis, a universal
    joint's ``axis1 x axis2``), else ``None``."""
    if joint.kind in ("revolute", "prismatic"):
        return joint.rotation @ joint.axis
    if joint.kind == "universal":
        normal = np.cross(joint.axis1, joint.axis2)
        return joint.rotation @ (normal / np.linalg.norm(normal))
    return None


def motion_matrix(joint: Any, frame: np.ndarray) -> np.ndarray:
    """``A`` (6, nv): the child's ``[u ; theta]`` (chain axes) per unit joint velocity at rest; ``frame`` the
    joint frame (= the child's axes at rest) in chain axes."""
    A = np.zeros((6, joint.velocity_count))
    if joint.kind == "revolute":
        A[3:, 0] = frame @ joint.axis
    elif joint.kind == "prismatic":
        A[:3, 0] = frame @ joint.axis
    elif joint.kind == "universal":
        A[3:, 0], A[3:, 1] = frame @ joint.axis1, frame @ joint.axis2
    elif joint.kind == "spherical":
        A[3:, :] = frame
    elif joint.kind in ("free", "elastic6"):
        A[:3, :3], A[3:, 3:] = frame, frame
    return np.where(np.abs(A) < _SMALL, 0.0, A)


def joint_law(joint: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(K_q, C_q)`` (nv, nv) of the joint's linear law [N/m, N m/rad; N s/m, N m s/rad]."""
    n = joint.velocity_count
    if joint.kind in ("revolute", "prismatic", "universal"):
        return np.diag(np.asarray(joint.stiffness, float)), np.diag(np.asarray(joint.damping, float))
    if joint.kind in ("spherical", "elastic6"):
        return np.asarray(joint.stiffness, float), np.asarray(joint.damping, float)
    return np.zeros((n, n)), np.zeros((n, n))


def rigid_mode_count(joint: Any) -> int:
    """Free directions of a ground joint without stiffness (its rigid-body modes, at zero frequency)."""
    stiffness = joint_law(joint)[0]
    if stiffness.size == 0:
        return 0
    return joint.velocity_count - int(np.linalg.matrix_rank(stiffness, tol=_SMALL * max(np.abs(stiffness).max(),
                                                                                        1e-300)))


def _chain_law(A: np.ndarray, law: np.ndarray) -> np.ndarray:
    inverse = np.linalg.pinv(A)
    out = inverse.T @ law @ inverse
    return np.where(np.abs(out) < _SMALL * max(np.abs(out).max(), 1e-300), 0.0, out)


def base_elements(model_name: str, joint: Any, A: np.ndarray) -> list:
    """The boundary (and ground spring) of a ground joint with motion matrix ``A`` (module docstring)."""
    from .spatial_beam_elements import SpatialClamped, SpatialFree, SpatialGroundSpring, SpatialSupport

    n = A.shape[1]
    if n == 0:
        return [SpatialClamped(f"{joint.name}__base")]
    if n == 6:
        elements = [SpatialFree(f"{joint.name}__base")]
    else:
        projector = A @ np.linalg.pinv(A)
        diagonal = np.diag(projector)
        off = projector - np.diag(diagonal)
        if np.abs(off).max() > 1e-9 or np.any(np.minimum(np.abs(diagonal), np.abs(diagonal - 1.0)) > 1e-9):
            raise _refuse(model_name, f"the free directions of ground joint {joint.name!r} ({joint.kind}) are oblique "
                                      "to the chain axes (the first beam's axes): a support holds chain components; "
                                      "align the joint with the beam axes or use fields='modal'")
        held = [name for name, d in zip(_DISPLACEMENTS, diagonal) if abs(d) < 0.5]
        elements = [SpatialSupport(f"{joint.name}__base", held)]
    stiffness, damping = joint_law(joint)
    if np.any(stiffness) or np.any(damping):
        elements.append(SpatialGroundSpring(f"{joint.name}__law", _chain_law(A, stiffness),
                                            damping=_chain_law(A, damping)))
    return elements


def inner_elements(model_name: str, joint: Any, A: np.ndarray) -> list:
    """The transfer elements of a joint between bodies with motion matrix ``A`` (module docstring)."""
    from .spatial_beam_elements import SpatialHinge, SpatialSpring

    stiffness, damping = joint_law(joint)
    if joint.kind == "weld":
        return []
    if joint.kind in ("prismatic", "free"):
        raise _refuse(model_name, f"joint {joint.name!r} between bodies is a {joint.kind} joint (no transfer matrix "
                                  "of a sliding or free joint inside the chain; welds, revolute, universal, spherical "
                                  "and elastic6 joints with laws convert)")
    if joint.kind == "elastic6":
        if np.linalg.eigvalsh(stiffness).min() <= _SMALL * max(np.abs(stiffness).max(), 1e-300):
            raise _refuse(model_name, f"elastic6 joint {joint.name!r} between bodies has a stiffness that is not "
                                      "positive definite (a free direction inside the chain has no transfer matrix)")
        return [SpatialSpring(joint.name, _chain_law(A, stiffness), damping=_chain_law(A, damping))]
    if joint.kind == "spherical":                 # three hinges about the principal axes of the rotary law
        scale = max(np.abs(stiffness).max(), np.abs(damping).max(), 1e-300)
        _, axes = np.linalg.eigh(stiffness if np.any(stiffness) else damping)
        k = np.diag(axes.T @ stiffness @ axes)
        c = np.diag(axes.T @ damping @ axes)
        for law in (stiffness, damping):
            turned = axes.T @ law @ axes
            if np.abs(turned - np.diag(np.diag(turned))).max() > 1e-10 * scale:
                raise _refuse(model_name, f"spherical joint {joint.name!r}: its damping and stiffness have different "
                                          "principal axes (three hinges in series need common ones)")
        A = A @ axes
    else:                                         # revolute, universal: a hinge per axis
        k, c = np.diag(stiffness), np.diag(damping)
    hinges = []
    for i in range(A.shape[1]):
        if not (k[i] > 0.0 or c[i] > 0.0):
            raise _refuse(model_name, f"{joint.kind} joint {joint.name!r} between bodies is free in a direction (no "
                                      "stiffness or damping): a free joint inside the chain has no transfer matrix")
        name = joint.name if A.shape[1] == 1 else f"{joint.name}__{i + 1}"
        hinges.append(SpatialHinge(name, A[3:, i], float(max(k[i], 0.0)), damping=float(max(c[i], 0.0))))
    return hinges


def _names(joint: Any) -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
    """``(coordinate sensors, rate sensors, actuators)`` suffixes, one per velocity coordinate."""
    kind = joint.kind
    if kind == "revolute":
        return ("angle",), ("rate",), ("torque",)
    if kind == "prismatic":
        return ("position",), ("rate",), ("force",)
    if kind == "universal":
        return ("q1", "q2"), ("q1_rate", "q2_rate"), ("torque1", "torque2")
    if kind == "spherical":
        return (), ("wx", "wy", "wz"), ("torque_x", "torque_y", "torque_z")
    if kind in ("free", "elastic6"):
        return (("x", "y", "z"), ("vx", "vy", "vz", "wx", "wy", "wz"),
                ("force_x", "force_y", "force_z", "torque_x", "torque_y", "torque_z"))
    return (), (), ()


def joint_ports(joint: Any, A: np.ndarray, root: str, before: str | None) -> tuple[dict, dict]:
    """``(sensors, actuators)`` of a joint (module docstring): chain signal and input terms of its child's
    root marker ``root`` relative to the parent's marker ``before`` (``None``: the ground)."""
    inverse = np.linalg.pinv(A) if A.size else np.zeros((0, 6))
    inverse = np.where(np.abs(inverse) < _SMALL, 0.0, inverse)
    coordinates, rates, inputs = _names(joint)
    ends = [(root, 1.0)] + ([] if before is None else [(before, -1.0)])
    sensors: dict[str, list] = {}
    actuators: dict[str, list] = {}
    for k, row in enumerate(inverse):
        terms = [(f"{marker}.{name}", sign * w) for marker, sign in ends for name, w in zip(_DISPLACEMENTS, row) if w]
        if k < len(coordinates):
            sensors[f"{joint.name}.{coordinates[k]}"] = terms
        sensors[f"{joint.name}.{rates[k]}"] = [(f"{n}_dot", w) for n, w in terms]
        if joint.inputs:
            actuators[f"{joint.name}.{inputs[k]}"] = [(f"{marker}.{name}", sign * w) for marker, sign in ends
                                                      for name, w in zip(_FORCES, row) if w]
    return sensors, actuators
