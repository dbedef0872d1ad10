"""A spherical cut joint's 3-axis law on casadi symbols (issue 13): the generated kinematic-loop steps' form of
:func:`ctmm.spatial.closed_loop_cuts.spherical_law_moment` (``docs/closed_loops.md`` §8.1b).

The definitions are the numpy path's: the relative rotation vector ``phi = log(R_p^T R_c R_rest^T)`` [rad] (parent
body axes; ``R_rest = exp(rest)``), its rate ``phi' = J(phi)^-1 R_p^T (omega_c - omega_p)`` [rad/s] with the left
Jacobian ``J(phi) = I + (1 - cos a)/a^2 [phi]x + (a - sin a)/a^3 [phi]x^2`` of ``SO(3)`` (``a = |phi|``; the same
series below ``a^2 = 1e-6``), the law ``f_i = law(phi_i, phi'_i)`` on each component (the cut's
:class:`~ctmm.nonlinear_laws.Law` traced on symbols) and the moment ``-R_p J(phi)^-T f`` [N m] (world axes) on the
child, its opposite on the parent.  Only the logarithm is written differently: from the matrix directly (``cos a =
(tr R - 1)/2``, ``[phi]x = a/(2 sin a) (R - R^T)``, the series ``a/sin a = 1 + sin^2 a/6`` below ``sin a = 1e-8``)
instead of through a quaternion, which needs a branch per largest diagonal entry; the law is defined for ``a <=``
:data:`~ctmm.spatial.closed_loop_cuts.ROTATION_LAW_LIMIT` ``= 3`` rad, where ``sin a >= 0.14``, so the two agree to
round-off (``tests/test_compiled_spherical_cut_law.py``: 1e-14 at random rotations).

Beyond the limit the numpy path raises :class:`~ctmm.errors.SimulationError`; a generated step cannot raise, so the
moment is NaN there: the state turns non-finite and the run stops with a ``SimulationError`` whose message names the
cut (:func:`rotation_limit_note` on the last good stored state).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .spatial.closed_loop_cuts import ROTATION_LAW_LIMIT
from .spatial.lie import quaternion_exponential
from .spatial.model import rotation_matrix

__all__ = ["symbolic_relative_rotation", "symbolic_spherical_law_moment", "spherical_law_cuts",
           "rotation_limit_note"]

SMALL_SINE_SQUARED = 1e-16
"""``sin^2 a`` below which the logarithm takes its series ``a / sin a = 1 + sin^2 a / 6`` (error < 1e-32)."""

SMALL_ANGLE_SQUARED = 1e-6
"""``a^2`` below which the left Jacobian takes its series (as :func:`ctmm.spatial.lie.left_jacobian`)."""


def _skew(v: Any) -> Any:
    import casadi as ca

    return ca.vertcat(ca.horzcat(0.0, -v[2], v[1]), ca.horzcat(v[2], 0.0, -v[0]), ca.horzcat(-v[1], v[0], 0.0))


def symbolic_relative_rotation(cut: Any, rotation_p: Any | None, rotation_c: Any, omega_p: Any, omega_c: Any
                               ) -> tuple[Any, Any, Any, Any]:
    """A spherical cut's ``(phi, phi', J(phi), a)`` on symbols (module docstring;
    :func:`ctmm.spatial.closed_loop_cuts.relative_rotation`): ``rotation_p`` (``None``: the ground), ``rotation_c``
    world rotation matrices of the parent and child bodies, ``omega_p``, ``omega_c`` their angular velocities
    [rad/s] (world); ``a = |phi|`` [rad]."""
    import casadi as ca

    parent = ca.DM.eye(3) if rotation_p is None else rotation_p
    rest = ca.DM(rotation_matrix(quaternion_exponential(np.asarray(cut.rest, float))))
    R = ca.mtimes(ca.mtimes(parent.T, rotation_c), rest.T)
    vee = ca.vertcat(R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1])      # 2 sin(a) n
    sine_squared = 0.25 * ca.dot(vee, vee)
    cosine = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    small = sine_squared <= SMALL_SINE_SQUARED
    sine = ca.sqrt(ca.if_else(small, 1.0, sine_squared))
    angle = ca.atan2(ca.sqrt(sine_squared), cosine)
    factor = ca.if_else(small, 1.0 + sine_squared / 6.0, ca.atan2(sine, cosine) / sine)
    phi = 0.5 * factor * vee
    a2 = ca.dot(phi, phi)
    tiny = a2 <= SMALL_ANGLE_SQUARED
    a = ca.sqrt(ca.if_else(tiny, 1.0, a2))
    first = ca.if_else(tiny, 0.5 - a2 / 24.0 + a2 * a2 / 720.0, (1.0 - ca.cos(a)) / (a * a))
    second = ca.if_else(tiny, 1.0 / 6.0 - a2 / 120.0 + a2 * a2 / 5040.0, (a - ca.sin(a)) / (a * a * a))
    K = _skew(phi)
    jacobian = ca.DM.eye(3) + first * K + second * ca.mtimes(K, K)
    rate = ca.solve(jacobian, ca.mtimes(parent.T, omega_c - omega_p))
    return phi, rate, jacobian, angle


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
