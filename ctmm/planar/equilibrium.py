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
from ..errors import ModelError, SimulationError
from .body_forms import PlanarScene
from .model import PlanarModel
from .sweep import accelerations


def static_equilibrium(model: PlanarModel, q_guess, *, t: float = 0.0, tolerance: float = 1e-12,
                       stable: bool = False) -> np.ndarray:
    """Coordinates where all accelerations vanish at rest (``scipy.optimize.root`` from ``q_guess``, polished by
    Newton steps to round-off).

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
    """A root of the accelerations at rest from ``q_guess``, body angles wrapped into ``[-pi, pi)``.

    The guess itself is returned (wrapped) when its residual already meets :data:`RESIDUAL_TOLERANCE` (the
    certificate of every root returned here; e.g. the hanging configuration of a chain on smooth hinges), as it
    is when its residual is at most :data:`POLISHED_RESIDUAL`, else polished (below).
    Otherwise ``scipy.optimize.root`` (``hybr``) runs, with the complex-step Jacobian of
    :func:`complex_step_jacobian` where :func:`complex_step_applies` (one batched sweep per Jacobian instead of
    ``n`` evaluations), else with its own forward differences; should the complex-step search not certify, it
    is repeated with the differences.  The root found is then polished by Newton steps on
    :func:`position_jacobian` (:data:`POLISH_STEPS` at most, each kept only when it at least halves the largest
    residual): ``hybr`` stops on its step size, which can leave accelerations of ~1e-11 at rest, and a
    linearisation about the point (its preloads) is consistent only to that residual."""
    angles = np.array([c.endswith(".theta") for c in model.coordinates], dtype=bool)

    def residual(q: np.ndarray) -> np.ndarray:
        return accelerations(model, q, np.zeros_like(q), t)

    def wrapped(q: np.ndarray) -> np.ndarray:
        q = q.copy()
        q[angles] = (q[angles] + np.pi) % (2.0 * np.pi) - np.pi
        return q

    def search(start: np.ndarray, jacobian: Callable[[np.ndarray], np.ndarray] | None) -> tuple[np.ndarray, float]:
        q = wrapped(scipy.optimize.root(residual, start, jac=jacobian, tol=tolerance, method="hybr").x)
        error = float(np.max(np.abs(residual(q)), initial=0.0))
        if not error <= RESIDUAL_TOLERANCE:  # a huge angle loses digits when wrapped: polish
            q = wrapped(scipy.optimize.root(residual, q, jac=jacobian, tol=tolerance, method="hybr").x)
            error = float(np.max(np.abs(residual(q)), initial=0.0))
        return q, error

    def polished(q: np.ndarray, error: float) -> np.ndarray:
        for _ in range(POLISH_STEPS):
            if error == 0.0:
                break
            try:
                step = np.linalg.solve(position_jacobian(model, q, t), residual(q))
            except np.linalg.LinAlgError:    # a singular stiffness (neutral direction): keep the root found
                break
            trial = wrapped(q - step)
            trial_error = float(np.max(np.abs(residual(trial)), initial=0.0))
            if not trial_error <= 0.5 * error:
                break
            q, error = trial, trial_error
        return q

    q = wrapped(q_guess)
    error = float(np.max(np.abs(residual(q)), initial=0.0))
    if error <= RESIDUAL_TOLERANCE:
        return q if error <= POLISHED_RESIDUAL else polished(q, error)
    if complex_step_applies(model):
        q, error = search(q_guess, lambda x: complex_step_jacobian(model, x, t))
    if not error <= RESIDUAL_TOLERANCE:
        q, error = search(q_guess, None)
    if not error <= RESIDUAL_TOLERANCE:      # not-a-number included
        raise ModelError(f"no static equilibrium found near {q_guess!r} (residual {error:.2e})")
    return polished(q, error)


POLISH_STEPS = 3
"""Newton steps at most that polish a root of :func:`static_equilibrium` (each kept when it halves the residual)."""
POLISHED_RESIDUAL = 1e-12
"""Largest accelerations at rest [rad/s^2, m/s^2, modal] of a guess that :func:`static_equilibrium` returns as it
is; a guess with more (up to :data:`RESIDUAL_TOLERANCE`) is polished by Newton steps first."""
RESIDUAL_TOLERANCE = 1e-8
"""Largest accelerations [rad/s^2, m/s^2, modal] at rest of an equilibrium returned by :func:`static_equilibrium`."""
CROSS_CHECK_TOLERANCE = 1e-6
"""Largest disagreement of the complex-step ``d qddot / d q`` with a central difference along one direction,
relative to its largest entry (:func:`position_jacobian`); beyond it the stiffness is taken by differences."""
CROSS_CHECK_STEP = 1e-6
"""Relative step [rad, m, modal] of the central differences of :func:`position_jacobian`."""


def complex_step_applies(model: PlanarModel) -> bool:
    """True when the complex-step ``d qddot / d q`` (:func:`complex_step_jacobian`) is the cheaper way to the
    stiffness of ``model``: its accelerations may be evaluated at complex coordinates through the one sweep
    (:class:`~ctmm.planar.body_forms.PlanarScene`; no user state-feedback laws on beams, whose code may not
    accept complex coordinates) and they are not on the real rigid-tree kernel of
    :func:`ctmm.planar.accelerations` (modal beams, ``ctmm.fem`` subsystems or bushings: there each evaluation
    is a sweep, and one sweep batched over ``n`` states is 4-8 times cheaper than ``2 n`` differences; on the
    rigid kernel, ``2 n`` real evaluations are cheaper than the batched complex sweep: 13.7 against 15.8 ms
    for a 100-link chain)."""
    on_rigid_kernel = model.flexible_system is None and not len(model.bushing_bodies)
    return not on_rigid_kernel and not any(beam.data.laws for beam in model.beams.values())


def complex_step_jacobian(model: PlanarModel, q: np.ndarray, t: float = 0.0, step: float = 1e-30) -> np.ndarray:
    """``d qddot / d q`` (n, n) [1/s^2] at rest at ``q`` by complex step: one sweep of
    :class:`~ctmm.planar.body_forms.PlanarScene` batched over the ``n`` states ``q + i step e_k`` (exact to
    round-off for terms analytic in ``q``; unchecked -- :func:`position_jacobian` checks it).  Raises
    :class:`ModelError` for models with user beam laws (:func:`complex_step_applies`)."""
    if any(beam.data.laws for beam in model.beams.values()):
        raise ModelError(f"complex_step_jacobian: {model.name!r} has beams with user state laws, which may not "
                         "accept complex coordinates; use position_jacobian (central differences there)")
    n = q.size
    if n == 0:
        return np.zeros((0, 0))
    states = np.asarray(q, dtype=float)[None, :] + 1j * step * np.eye(n)
    return PlanarScene(model).accelerations(states, np.zeros((n, n)), t).imag.T / step


def position_jacobian(model: PlanarModel, q, t: float = 0.0) -> np.ndarray:
    """``d qddot / d q`` (n_coordinates, n_coordinates) [1/s^2] at rest at ``q`` [rad, m, modal] (loads at
    time ``t`` [s]).

    Where :func:`complex_step_applies`, by complex step (:func:`complex_step_jacobian`), accepted when it
    agrees with a central difference of :func:`ctmm.planar.accelerations` along one fixed pseudo-random
    direction to :data:`CROSS_CHECK_TOLERANCE` of its largest entry; otherwise (rigid trees, user beam laws,
    terms not analytic in ``q``) by central differences of every column (step :data:`CROSS_CHECK_STEP`
    relative; ``~1e-10`` relative error on a 100-link chain).
    """
    q = np.asarray(q, dtype=float)
    n = q.size
    zero = np.zeros(n)

    def difference(direction: np.ndarray) -> np.ndarray:
        h = CROSS_CHECK_STEP * max(1.0, float(np.max(np.abs(q[direction != 0.0]), initial=0.0)))
        up = accelerations(model, q + h * direction, zero, t)
        return (up - accelerations(model, q - h * direction, zero, t)) / (2 * h)

    if n and complex_step_applies(model):
        jacobian = complex_step_jacobian(model, q, t)
        direction = np.random.default_rng(20261125).uniform(-1.0, 1.0, n)
        direction /= np.max(np.abs(direction))
        disagreement = float(np.max(np.abs(jacobian @ direction - difference(direction))))
        size = float(np.max(np.abs(jacobian)))
        if np.isfinite(size) and disagreement <= CROSS_CHECK_TOLERANCE * max(size, 1e-300):
            return jacobian
    return np.array([difference(column) for column in np.eye(n)]).T.reshape(n, n)


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
        The eigenvalues ``omega^2 < 0`` [rad^2/s^2] of ``-d qddot / d q`` at rest (``M^-1 K``, by
        :func:`position_jacobian`) below ``-1e-8 max |omega^2|``, most negative
        first; empty for a statically stable (or neutral) equilibrium.
    vectors : ndarray, shape (n_coordinates, len(values))
        Their eigenvectors (columns, largest entry 1).
    """
    return negative_stiffness(position_jacobian(model, q, t))


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
    values = np.linalg.eigvals(-jacobian).real       # the common, stable case needs no eigenvectors
    if not np.any(values < -1e-8 * max(float(np.max(np.abs(values), initial=0.0)), 1e-300)):
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
    try:
        solution = scipy.integrate.solve_ivp(flow, (0.0, horizon), start, method="Radau", events=settled,
                                             rtol=1e-6, atol=1e-9)
    except SimulationError as error:
        raise ModelError(f"no statically stable equilibrium of {model.name!r} found: the descent from the unstable "
                         f"equilibrium q = {q.tolist()} along its direction of negative stiffness (omega^2 = "
                         f"{-rate:.6g} rad^2/s^2) ran away ({error}); the model may have no stable equilibrium (e.g. a "
                         "subsystem compressed above its buckling load); pass operating_point=(q, qdot) to linearise "
                         "about a chosen state") from error
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
           "describe_directions", "restart_until_stable", "STABLE_RESTARTS", "position_jacobian",
           "complex_step_jacobian", "complex_step_applies", "RESIDUAL_TOLERANCE", "CROSS_CHECK_TOLERANCE",
           "CROSS_CHECK_STEP"]
