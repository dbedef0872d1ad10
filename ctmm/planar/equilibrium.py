"""Static equilibria of planar models: :func:`static_equilibrium` (all accelerations vanish at rest,
from a guess) and its guess for a hanging model, :func:`hanging_configuration`.

The operating point of :func:`ctmm.linearize` and of the frequency verbs (``ctmm.natural_frequencies``,
``ctmm.eigenvalue_count``, ``ctmm.mode_shapes`` on a :class:`~ctmm.planar.PlanarModel`) defaults to
``static_equilibrium(model, hanging_configuration(model))``.
"""
from __future__ import annotations

import numpy as np
import scipy.optimize

from ..capabilities import require_planar
from ..errors import ModelError
from .model import PlanarModel
from .sweep import accelerations


def static_equilibrium(model: PlanarModel, q_guess, *, t: float = 0.0,
                       tolerance: float = 1e-12) -> np.ndarray:
    """Coordinates where all accelerations vanish at rest (``scipy.optimize.root`` from ``q_guess``).

    Absolute body angles (coordinates ``"<body>.theta"``) are returned wrapped into
    ``[-pi, pi)``.  Which equilibrium is found depends on the guess (a pendulum also balances
    upright); :func:`hanging_configuration` is the guess for the hanging one.
    """
    require_planar(model, "ctmm.planar.equilibrium")
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
    require_planar(model, "ctmm.planar.equilibrium")
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


__all__ = ["static_equilibrium", "hanging_configuration"]
