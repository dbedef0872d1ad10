"""Planar models about an equilibrium: the static equilibrium, its hanging guess, and the counted
frequency domain.

Small motion about a static configuration ``q_eq`` (hanging chain under gravity, or a
configuration held by hinge springs).  :func:`static_equilibrium` finds ``q_eq`` from a guess
(:func:`hanging_configuration`); :func:`natural_frequencies` / :func:`eigenvalue_count` /
:func:`characteristic_function` are thin calls, for chains **and trees** (rigid or with modal
beams), of the one articulated sweep's frequency context
(:meth:`ctmm.planar.body_forms.PlanarScene.frequency`) and its Wittrick-Williams counting
(:mod:`ctmm.planar_counting`): the joint and modal pivots are those of an LDL^T factorisation of
``K - omega^2 M``, so the number of negative pivots counts the natural frequencies below ``omega``,
and bisection finds them to round-off.  The verbs ``ctmm.natural_frequencies``,
``ctmm.eigenvalue_count`` and ``ctmm.mode_shapes`` take the :class:`PlanarModel` itself.

(The transfer-matrix elements of the linear planar MSTMM -- rigid body with geometric stiffness,
elastic hinge, smooth-hinge composite, ``docs/planar.md`` section 5 -- are test fixtures of the
1-D chain verbs: ``tests/planar_linear_elements.py``.)
"""
from __future__ import annotations

import numpy as np
import scipy.optimize

from .. import validation
from ..capabilities import require_planar
from ..errors import ModelError
from .model import BUSHING, DRIVEN, PlanarModel
from .sweep import solve_instant


# ------------------------------------------------------------------------------------------
# from a nonlinear PlanarModel
# ------------------------------------------------------------------------------------------
def static_equilibrium(model: PlanarModel, q_guess, *, t: float = 0.0,
                       tolerance: float = 1e-12) -> np.ndarray:
    """Coordinates where all accelerations vanish at rest (``scipy.optimize.root`` from ``q_guess``).

    Absolute body angles (coordinates ``"<body>.theta"``) are returned wrapped into
    ``[-pi, pi)``.  Which equilibrium is found depends on the guess (a pendulum also balances
    upright); :func:`hanging_configuration` is the guess for the hanging one.
    """
    from .sweep import accelerations

    q_guess, _ = model.state(q_guess, np.zeros(model.n_coordinates))
    sol = scipy.optimize.root(lambda q: accelerations(model, q, np.zeros_like(q), t),
                              q_guess, tol=tolerance, method="hybr")
    q = sol.x.copy()
    angles = np.array([c.endswith(".theta") for c in model.coordinates], dtype=bool)
    q[angles] = (q[angles] + np.pi) % (2.0 * np.pi) - np.pi
    residual = np.max(np.abs(accelerations(model, q, np.zeros_like(q), t)))
    if residual > 1e-8:        # a root at a huge angle loses digits when wrapped: polish the wrapped point
        sol = scipy.optimize.root(lambda x: accelerations(model, x, np.zeros_like(x), t), q, tol=tolerance,
                                  method="hybr")
        q = sol.x.copy()
        q[angles] = (q[angles] + np.pi) % (2.0 * np.pi) - np.pi
        residual = np.max(np.abs(accelerations(model, q, np.zeros_like(q), t)))
    if residual > 1e-8:
        raise ModelError(f"no static equilibrium found near {q_guess!r} (residual {residual:.2e})")
    return q


def hanging_configuration(model: PlanarModel) -> np.ndarray:
    """Coordinates with every body's centre of mass straight below its inboard end (along gravity).

    A guess for :func:`static_equilibrium` (exact for a chain of bodies on smooth hinges; hinge
    springs and loads move the equilibrium away from it).  A body whose centre of mass is at its
    inboard end (a hub) hangs by what it carries instead: the first moment of the bodies welded or
    driven on it (taken straight) and the masses of the subtrees hinged on it at their points.  A
    body with no such moment, and every body without gravity, keeps angle 0; other coordinates are 0.
    """
    q = np.zeros(model.n_coordinates)
    g = np.asarray(model.gravity, dtype=float)
    if not np.any(g != 0.0):
        return q
    down = float(np.arctan2(g[1], g[0]))
    nb = model.n_bodies
    total = np.asarray(model.mass, dtype=float).copy()            # subtree masses [kg]
    moment = total[:, None] * np.asarray(model.com, dtype=float)   # first moments in the body's frame [kg m]
    for j in range(nb - 1, 0, -1):                                  # tips first (topological order)
        p = int(model.parent[j])
        if p < 0:
            continue
        total[p] += total[j]
        moment[p] += total[j] * model.end_vector[j]
        if model.theta_index[j] < 0:                                # turns with its parent
            moment[p] += moment[j]
    for k, name in enumerate(model.coordinates):
        body, _, what = name.rpartition(".")
        if what != "theta" or body not in model.body_names:
            continue
        j = model.body_index(body)
        lever = model.com[j] if np.any(model.com[j] != 0.0) else moment[j]
        if np.any(lever != 0.0):
            q[k] = down - float(np.arctan2(lever[1], lever[0]))
    return q


def _check_equilibrium(model: PlanarModel, q_eq, t: float):
    require_planar(model, "ctmm.planar.linear")
    if np.any(model.joint_kind == DRIVEN):
        raise ModelError("linearisation about an equilibrium needs a model without driven hinges")
    if np.any(model.joint_kind == BUSHING):
        names = [model.joint_names[j] for j in np.flatnonzero(model.joint_kind == BUSHING)]
        raise ModelError(f"the linear planar module does not support hinges with translational "
                         f"springs yet: {', '.join(names)}")
    q_eq = validation.finite_array("q_eq", q_eq, ndim=1)
    if q_eq.shape != (model.n_coordinates,):
        raise ModelError(f"q_eq must have shape ({model.n_coordinates},), got {q_eq.shape}")
    sol = solve_instant(model, q_eq, np.zeros_like(q_eq), t)
    scale = 1.0 + np.max(np.abs(model.gravity))
    if np.max(np.abs(sol.qddot)) > 1e-8 * scale:
        raise ModelError(f"q_eq is not an equilibrium: accelerations at rest "
                         f"{np.max(np.abs(sol.qddot)):.3e} (use static_equilibrium)")
    return q_eq, sol


def characteristic_function(model: PlanarModel, q_eq, s, *, t: float = 0.0) -> np.ndarray:
    """``Delta(s) = prod det D_j * prod det C_j`` (= det(K + s C + s^2 M) up to a constant) of the
    one sweep's frequency context (:meth:`ctmm.planar.body_forms.PlanarScene.frequency`),
    vectorised over the Laplace variables ``s``."""
    from .body_forms import PlanarScene

    q_eq, _ = _check_equilibrium(model, q_eq, t)
    s = np.atleast_1d(np.asarray(s, dtype=complex))
    value = PlanarScene(model).frequency(q_eq, s.ravel(), t).characteristic
    return np.asarray(value).reshape(s.shape)


def eigenvalue_count(model: PlanarModel, q_eq, omega, *, t: float = 0.0) -> np.ndarray:
    """Number of natural frequencies strictly below each ``omega`` [rad/s] (undamped).

    Wittrick-Williams counting on the one sweep's frequency context
    (:func:`ctmm.planar_counting.eigenvalue_count`): negative pivots of the articulated
    elimination, certified at substructure resonances (a hinge pivot vanishes where ``omega`` is a
    natural frequency of the substructure outboard of that hinge, pinned there).
    """
    from ..planar_counting import FrequencyCounter

    q_eq, _ = _check_equilibrium(model, q_eq, t)
    return FrequencyCounter(model, q_eq, t, verb="eigenvalue_count").count(omega)


def natural_frequencies(model: PlanarModel, q_eq, *, n_modes: int, t: float = 0.0,
                        rtol: float = 1e-15) -> np.ndarray:
    """Lowest ``n_modes`` undamped natural frequencies [rad/s] about the equilibrium ``q_eq``.

    Wittrick-Williams counting on the one sweep's frequency context plus bisection
    (:func:`ctmm.planar_counting.natural_frequencies`); zero-frequency (rigid) modes are returned
    as 0.
    """
    from ..planar_counting import FrequencyCounter

    require_planar(model, "ctmm.planar.linear")
    if np.any(model.damping > 0):
        raise ModelError("natural_frequencies needs an undamped model (hinge damping > 0 found)")
    if not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise ModelError(f"n_modes must be an integer >= 1, got {n_modes!r}")
    q_eq, _ = _check_equilibrium(model, q_eq, t)
    return FrequencyCounter(model, q_eq, t).frequencies(n_modes=int(n_modes), rtol=rtol)


__all__ = ["static_equilibrium", "hanging_configuration", "characteristic_function", "eigenvalue_count",
           "natural_frequencies"]
