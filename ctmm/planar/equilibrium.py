"""Static equilibria of planar models: :func:`static_equilibrium` (all accelerations vanish at rest,
from a guess) and its guess for a hanging model, :func:`hanging_configuration`.

The operating point of :func:`ctmm.linearize` and of the frequency verbs (``ctmm.natural_frequencies``,
``ctmm.eigenvalue_count``, ``ctmm.mode_shapes`` on a :class:`~ctmm.planar.PlanarModel`) defaults to
``static_equilibrium(model, hanging_configuration(model), stable=True)`` (a statically stable one).
"""
from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.integrate
import scipy.optimize

from ..capabilities import require_planar
from ..errors import ModelError
from .model import PlanarModel
from .sweep import accelerations


def static_equilibrium(model: PlanarModel, q_guess, *, t: float = 0.0, tolerance: float = 1e-12,
                       stable: bool = False) -> np.ndarray:
    """Coordinates where all accelerations vanish at rest (``scipy.optimize.root`` from ``q_guess``).

    Absolute body angles (coordinates ``"<body>.theta"``) are returned wrapped into
    ``[-pi, pi)``.  Which equilibrium is found depends on the guess (a pendulum also balances
    upright); :func:`hanging_configuration` is the guess for the hanging one.

    Parameters
    ----------
    model : PlanarModel
    q_guess : array_like
        Start of the search [rad, m, modal].
    t : float
        Time [s] of the loads.
    tolerance : float
        Of ``scipy.optimize.root``.
    stable : bool
        Find a statically stable equilibrium (no direction of negative stiffness, :func:`unstable_directions`):
        from an unstable root, the search follows the descent of the potential energy in the mass
        metric (``q' = qddot(q, 0)``, started off the root along its unstable directions) to a stable
        one and polishes it -- e.g. a double pendulum whose search from ``q = 0`` lands on a link
        balanced upright ends hanging.  The default (``False``) returns the root nearest the guess.

    Raises
    ------
    ModelError
        No equilibrium found; with ``stable=True`` also when the equilibrium reached is still unstable
        (its unstable directions named).
    """
    require_planar(model, "ctmm.planar.equilibrium")
    q_guess, _ = model.state(q_guess, np.zeros(model.n_coordinates))
    q = _root(model, q_guess, t, tolerance)
    if not stable:
        return q
    return restart_until_stable(
        q, directions=lambda x: unstable_directions(model, x, t),
        restart=lambda x, direction, value: _root(model, _descend(model, x, direction, -value, t), t, tolerance),
        refusal=lambda x, values, vectors: (
            f"no statically stable equilibrium of {model.name!r} found from q = {q_guess.tolist()}: the one reached, "
            f"q = {x.tolist()}, has {describe_directions(list(model.coordinates), values, vectors)}; give a guess "
            "nearer a stable one (e.g. hanging_configuration(model))"),
        restarts=STABLE_RESTARTS)


STABLE_RESTARTS = 4
"""Restarts from an unstable equilibrium that :func:`static_equilibrium` tries with ``stable=True``."""


def restart_until_stable(q: np.ndarray, *, directions: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                         restart: Callable[[np.ndarray, np.ndarray, float], np.ndarray],
                         refusal: Callable[[np.ndarray, np.ndarray, np.ndarray], str],
                         restarts: int = STABLE_RESTARTS) -> np.ndarray:
    """From the equilibrium ``q``, restart the search off its most unstable direction until it is statically
    stable: the one loop of the stable-equilibrium searches (planar :func:`static_equilibrium`, spatial
    :func:`ctmm.spatial_linearization.static_equilibrium`).

    Parameters
    ----------
    q : ndarray
        An equilibrium (coordinates [rad, m, modal, quaternions]).
    directions : callable
        ``directions(q) -> (values, vectors)``: the directions of negative stiffness of ``q``
        (:func:`negative_stiffness`: ``omega^2 < 0`` [rad^2/s^2], most negative first, and vector columns).
    restart : callable
        ``restart(q, vector, value) -> q_new``: another equilibrium reached from ``q`` pushed along its most
        unstable direction ``vector`` (``omega^2 = value`` [rad^2/s^2]).
    refusal : callable
        ``refusal(q, values, vectors) -> str``: the :class:`ModelError` message when the last equilibrium reached
        is still unstable.
    restarts : int
        Largest number of restarts.

    Returns
    -------
    ndarray
        A statically stable (or neutral) equilibrium.

    Raises
    ------
    ModelError
        The equilibrium reached after ``restarts`` restarts is still unstable (``refusal``).
    """
    for _ in range(restarts):
        values, vectors = directions(q)
        if not values.size:
            return q
        q = restart(q, vectors[:, 0], float(values[0]))
    values, vectors = directions(q)
    if values.size:
        raise ModelError(refusal(q, values, vectors))
    return q


def _root(model: PlanarModel, q_guess: np.ndarray, t: float, tolerance: float) -> np.ndarray:
    """A root of the accelerations at rest from ``q_guess``, body angles wrapped into ``[-pi, pi)``."""
    def residual(q: np.ndarray) -> np.ndarray:
        return accelerations(model, q, np.zeros_like(q), t)

    sol = scipy.optimize.root(residual, q_guess, tol=tolerance, method="hybr")
    q = sol.x.copy()
    angles = np.array([c.endswith(".theta") for c in model.coordinates], dtype=bool)
    q[angles] = (q[angles] + np.pi) % (2.0 * np.pi) - np.pi
    if np.max(np.abs(residual(q))) > 1e-8:   # a root at a huge angle loses digits when wrapped: polish the wrapped point
        q = scipy.optimize.root(residual, q, tol=tolerance, method="hybr").x.copy()
        q[angles] = (q[angles] + np.pi) % (2.0 * np.pi) - np.pi
    error = np.max(np.abs(residual(q)))
    if error > 1e-8:
        raise ModelError(f"no static equilibrium found near {q_guess!r} (residual {error:.2e})")
    return q


def unstable_directions(model: PlanarModel, q, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The directions of negative stiffness of the equilibrium ``q`` of a planar model.

    Parameters
    ----------
    model : PlanarModel
    q : array_like
        Coordinates [rad, m, modal] of an equilibrium (at rest).
    t : float
        Time [s] of the loads.

    Returns
    -------
    values : ndarray
        The eigenvalues ``omega^2 < 0`` [rad^2/s^2] of ``-d qddot / d q`` at rest (``M^-1 K``, by central
        differences) below ``-1e-8 max |omega^2|``, most negative first; empty for a statically stable
        (or neutral) equilibrium.
    vectors : ndarray, shape (n_coordinates, len(values))
        Their eigenvectors (columns, largest entry 1).
    """
    q = np.asarray(q, dtype=float)
    n = q.size
    jacobian = np.empty((n, n))
    for k in range(n):
        h = 1e-6 * max(1.0, abs(q[k]))
        up, down = q.copy(), q.copy()
        up[k] += h
        down[k] -= h
        jacobian[:, k] = (accelerations(model, up, np.zeros(n), t) - accelerations(model, down, np.zeros(n), t)) / (2 * h)
    return negative_stiffness(jacobian)


def negative_stiffness(jacobian: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The directions of negative stiffness of a Jacobian ``d qddot / d q`` at rest [1/s^2].

    Parameters
    ----------
    jacobian : ndarray, shape (n, n)
        ``d qddot / d q`` at an equilibrium (``-M^-1 K``) [1/s^2].

    Returns
    -------
    values : ndarray
        Real parts of the eigenvalues ``omega^2`` [rad^2/s^2] of ``-jacobian`` below ``-1e-8 max |omega^2|``,
        most negative first.
    vectors : ndarray, shape (n, len(values))
        Their eigenvectors (real parts, columns, largest entry 1).
    """
    if not jacobian.size:
        return np.zeros(0), np.zeros((jacobian.shape[0], 0))
    values, vectors = np.linalg.eig(-jacobian)
    values, vectors = values.real, vectors.real
    top = max(float(np.max(np.abs(values), initial=0.0)), 1e-300)
    keep = np.flatnonzero(values < -1e-8 * top)
    keep = keep[np.argsort(values[keep])]
    vectors = vectors[:, keep]
    vectors = vectors / vectors[np.argmax(np.abs(vectors), axis=0), np.arange(keep.size)] if keep.size else vectors
    return values[keep], vectors


def describe_directions(names: list[str], values: np.ndarray, vectors: np.ndarray) -> str:
    """``"<n> direction(s) of negative stiffness (omega^2 = ... rad^2/s^2 along (<name> <entry>, ...))"``: the
    most negative of :func:`negative_stiffness` and the three largest entries of its vector, by coordinate name."""
    main = [f"{names[i]} {vectors[i, 0]:+.3g}" for i in np.argsort(-np.abs(vectors[:, 0]))[:3]]
    return (f"{values.size} direction(s) of negative stiffness (omega^2 = {values[0]:.6g} rad^2/s^2 along "
            f"({', '.join(main)}))")


def _descend(model: PlanarModel, q: np.ndarray, direction: np.ndarray, rate: float, t: float) -> np.ndarray:
    """Follow ``q' = qddot(q, 0)`` (the potential energy falls along it: ``dV/dtau = -F^T M^-1 F``) from
    ``q`` pushed by 1e-3 along the unstable ``direction`` (growth rate ``rate`` [1/s^2] in this flow)
    until the accelerations nearly vanish; the point reached (a guess for the polishing root)."""
    n = q.size

    def flow(_: float, x: np.ndarray) -> np.ndarray:
        return accelerations(model, x, np.zeros(n), t)

    def settled(_: float, x: np.ndarray) -> float:
        return float(np.max(np.abs(flow(0.0, x)))) - 1e-6 * rate

    settled.terminal = True
    start = q + 1e-3 * direction / max(float(np.max(np.abs(direction))), 1e-300)
    horizon = 1e4 / rate           # escape takes ~ ln(1e3) / rate; the descent towards the stable point its own rate
    solution = scipy.integrate.solve_ivp(flow, (0.0, horizon), start, method="Radau", events=settled,
                                         rtol=1e-6, atol=1e-9)
    return solution.y[:, -1]


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


__all__ = ["static_equilibrium", "hanging_configuration", "unstable_directions", "negative_stiffness",
           "describe_directions", "restart_until_stable", "STABLE_RESTARTS"]
