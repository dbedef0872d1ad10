"""A spherical cut joint's 3-axis law on casadi symbols (issue 13): the generated kinematic-loop steps' form of
:func:`ctmm.spatial.closed_loop_cuts.spherical_law_moment` (``docs/closed_loops.md`` §8.1b).

The definitions are the numpy path's: the relative rotation vector ``phi = log(R_p^T R_c R_rest^T)`` [rad] (parent
body axes; ``R_rest = exp(rest)``), its rate ``phi' = J(phi)^-1 R_p^T (omega_c - omega_p)`` [rad/s] with the left
Jacobian ``J(phi) = I + (1 - cos a)/a^2 [phi]x + (a - sin a)/a^3 [phi]x^2`` of ``SO(3)`` (``a = |phi|``; the same
series below ``a^2 = 1e-6``), the law ``f_i = law(phi_i, phi'_i)`` on each component (the cut's
:class:`~ctmm.nonlinear_laws.Law` traced on symbols) and the moment ``-R_p J(phi)^-T f`` [N m] (world axes) on the
child, its opposite on the parent.  The logarithm is :func:`symbolic_rotation_vector`, the symbolic form of
:func:`ctmm.spatial.sensor_maps.rotation_vector` (through the unit quaternion formed from its largest component,
one branch per choice), the one logarithm on symbols: also the generated ``"<body>.rotation_x|y|z"`` sensors
(:class:`ctmm.compiled_spatial_loops.SpatialSymbols`); ``tests/test_compiled_spherical_cut_law.py``: 1e-13 at random
rotations from 1e-9 rad to ``pi``.

The law is defined for ``a <=`` :data:`~ctmm.spatial.closed_loop_cuts.ROTATION_LAW_LIMIT` ``= 3`` rad.  Beyond the
limit the numpy path raises :class:`~ctmm.errors.SimulationError`; a generated step cannot raise, so the
moment is NaN there: the state turns non-finite and the run stops with a ``SimulationError`` whose message names the
cut (:func:`rotation_limit_note` on the last good stored state).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .spatial.closed_loop_cuts import ROTATION_LAW_LIMIT
from .spatial.lie import quaternion_exponential
from .spatial.model import rotation_matrix

__all__ = ["symbolic_rotation_vector", "symbolic_relative_rotation", "symbolic_spherical_law_moment",
           "spherical_law_cuts", "rotation_limit_note"]

SMALL_HALF_SINE_SQUARED = 1e-8
"""``|vec|^2 = sin^2(a / 2)`` below which the logarithm takes the series of ``2 atan(s / w) / s`` in ``s^2 / w^2``
(as :func:`ctmm.spatial.sensor_maps.rotation_vector`)."""

SMALL_ANGLE_SQUARED = 1e-6
"""``a^2`` below which the left Jacobian takes its series (as :func:`ctmm.spatial.lie.left_jacobian`)."""


def _skew(v: Any) -> Any:
    import casadi as ca

    return ca.vertcat(ca.horzcat(0.0, -v[2], v[1]), ca.horzcat(v[2], 0.0, -v[0]), ca.horzcat(-v[1], v[0], 0.0))


def symbolic_rotation_vector(rotation: Any) -> Any:
    """The rotation vector ``phi`` [rad] (a 3-column; ``R = exp([phi]x)``, ``|phi| <= pi``) of a rotation matrix on
    casadi symbols, the logarithm of :func:`ctmm.spatial.sensor_maps.rotation_vector` step by step: the unit
    quaternion ``(w, vec)`` formed from its largest component (chosen as numpy's ``argmax`` of ``(tr R, R00, R11,
    R22)``, ties to the first), turned to ``w >= 0``, then ``phi = 2 atan2(|vec|, w) vec / |vec|`` (its series below
    ``|vec|^2 =`` :data:`SMALL_HALF_SINE_SQUARED`).  Well conditioned up to and at ``|phi| = pi``, where ``phi`` flips
    to its opposite as numpy's does.  The branches not chosen are evaluated with their square root's argument held
    at 1 or more (the chosen one's is at least 1: the four sum to 4), so none is NaN."""
    import casadi as ca

    R = rotation
    trace = R[0, 0] + R[1, 1] + R[2, 2]
    branches = []
    for k in range(4):
        if k == 0:
            w = 0.5 * ca.sqrt(ca.fmax(1.0 + trace, 1.0))
            vec = ca.vertcat(R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]) / (4.0 * w)
        else:
            i = k - 1
            j, m = (i + 1) % 3, (i + 2) % 3
            largest = 0.5 * ca.sqrt(ca.fmax(1.0 + R[i, i] - R[j, j] - R[m, m], 1.0))
            entries = [None, None, None]
            entries[i] = largest
            entries[j] = (R[j, i] + R[i, j]) / (4.0 * largest)
            entries[m] = (R[m, i] + R[i, m]) / (4.0 * largest)
            w, vec = (R[m, j] - R[j, m]) / (4.0 * largest), ca.vertcat(*entries)
        branches.append(ca.vertcat(w, vec))
    first_rest = ca.if_else(R[0, 0] >= ca.fmax(R[1, 1], R[2, 2]), branches[1],
                            ca.if_else(R[1, 1] >= R[2, 2], branches[2], branches[3]))
    quaternion = ca.if_else(trace >= ca.fmax(R[0, 0], ca.fmax(R[1, 1], R[2, 2])), branches[0], first_rest)
    quaternion = ca.if_else(quaternion[0] < 0.0, -quaternion, quaternion)
    w, vec = quaternion[0], quaternion[1:]
    s2 = ca.dot(vec, vec)
    small = s2 < SMALL_HALF_SINE_SQUARED
    x = s2 / (w * w)
    series = (2.0 / w) * (1.0 - x / 3.0 + x * x / 5.0 - x ** 3 / 7.0 + x ** 4 / 9.0)
    s = ca.sqrt(ca.if_else(small, 1.0, s2))
    return vec * ca.if_else(small, series, 2.0 * ca.atan2(s, w) / s)


def symbolic_relative_rotation(cut: Any, rotation_p: Any | None, rotation_c: Any, omega_p: Any, omega_c: Any
                               ) -> tuple[Any, Any, Any, Any]:
    """A spherical cut's ``(phi, phi', J(phi), a)`` on symbols (module docstring;
    :func:`ctmm.spatial.closed_loop_cuts.relative_rotation`): ``rotation_p`` (``None``: the ground), ``rotation_c``
    world rotation matrices of the parent and child bodies, ``omega_p``, ``omega_c`` their angular velocities
    [rad/s] (world); ``a = |phi|`` [rad]."""
    import casadi as ca

    parent = ca.DM.eye(3) if rotation_p is None else rotation_p
    rest = ca.DM(rotation_matrix(quaternion_exponential(np.asarray(cut.rest, float))))
    phi = symbolic_rotation_vector(ca.mtimes(ca.mtimes(parent.T, rotation_c), rest.T))
    a2 = ca.dot(phi, phi)
    tiny = a2 <= SMALL_ANGLE_SQUARED
    a = ca.sqrt(ca.if_else(tiny, 1.0, a2))
    first = ca.if_else(tiny, 0.5 - a2 / 24.0 + a2 * a2 / 720.0, (1.0 - ca.cos(a)) / (a * a))
    second = ca.if_else(tiny, 1.0 / 6.0 - a2 / 120.0 + a2 * a2 / 5040.0, (a - ca.sin(a)) / (a * a * a))
    K = _skew(phi)
    jacobian = ca.DM.eye(3) + first * K + second * ca.mtimes(K, K)
    rate = ca.solve(jacobian, ca.mtimes(parent.T, omega_c - omega_p))
    return phi, rate, jacobian, ca.sqrt(a2)


def symbolic_spherical_law_moment(cut: Any, rotation_p: Any | None, rotation_c: Any, omega_p: Any, omega_c: Any
                                  ) -> Any:
    """The moment [N m] (world axes, a 3-column) of a spherical cut's law on its child, ``-R_p J(phi)^-T f`` with
    ``f_i = law(phi_i, phi'_i)`` (arguments as :func:`symbolic_relative_rotation`); NaN where ``|phi|`` exceeds
    :data:`~ctmm.spatial.closed_loop_cuts.ROTATION_LAW_LIMIT` (module docstring)."""
    import casadi as ca

    phi, rate, jacobian, angle = symbolic_relative_rotation(cut, rotation_p, rotation_c, omega_p, omega_c)
    loads = ca.vertcat(*[cut.law.force(phi[i], rate[i]) for i in range(3)])
    parent = ca.DM.eye(3) if rotation_p is None else rotation_p
    moment = -ca.mtimes(parent, ca.solve(jacobian.T, loads))
    return ca.if_else(angle <= ROTATION_LAW_LIMIT, moment, ca.DM.nan(3, 1))


def spherical_law_cuts(model: Any) -> list[int]:
    """Indices of the spherical cuts with a law among ``model.cuts``."""
    return [k for k, cut in enumerate(model.cuts) if cut.kind == "spherical" and cut.law is not None]


def rotation_limit_note(model: Any, q: np.ndarray, v: np.ndarray, t: float) -> tuple[str, str | None]:
    """``(sentence, cut name)`` for the failure of a generated run of the spatial kinematic loop ``model`` whose
    state turned non-finite after the stored state ``(q, v)`` at time ``t`` [s]: the spherical cut with a law whose
    relative rotation is the largest there (the law's moment is NaN beyond the limit, module docstring);
    ``("", None)`` without such cuts."""
    indices = spherical_law_cuts(model)
    if not indices:
        return "", None
    rotations = model.relative_rotations(q, v, t)
    angle, name = max((float(np.linalg.norm(rotations[k][0])), model.cuts[k].name) for k in indices)
    return (f"; a spherical cut's law is defined up to |phi| = {ROTATION_LAW_LIMIT:g} rad (beyond it the generated "
            f"moment is NaN): at t = {t} s, the last good stored state, cut joint {name!r} is turned {angle:.4g} rad "
            "from its rest", name)
