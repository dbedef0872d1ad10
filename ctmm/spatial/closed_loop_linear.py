"""Linearisation, equilibria and natural frequencies of spatial kinematic loop models on the constraint manifold.

About a resting configuration ``q0`` on the cut joints, with ``N`` the orthonormal null space of the velocity
Jacobian ``J(q0)`` (``f`` columns: the mechanism's degrees of freedom, in the tree's velocity space), the
independent coordinates ``z`` parametrise the constrained configurations by the chart
``q = (q0 (+) N z) (+) J0^T y`` with ``y`` from ``Phi(q) = 0`` (Gauss-Newton), and the rates by
``v = N z' + J0^T w`` with ``J(q) v = 0``; ``z'' = N^T v'`` with ``v'`` the closed-loop accelerations
(:meth:`SpatialKinematicLoopModel.solve`).  ``(+)`` is the first-order retraction of the tree coordinates
(:meth:`SpatialKinematicLoopModel.retract`: quaternions move by ``G(q) dx`` and are renormalised), so the chart is
exact to first order in ``z``: the tangent is exact **about an equilibrium** (the second-order terms of the chart
multiply the accelerations, zero there), and the functions here refuse other resting states by name.  The tangent
``A = [[0, I], [dz''/dz, dz''/dz']]`` is formed by Richardson-extrapolated central differences with an error
estimate, refused by name when not accurate (:func:`ctmm.loop_manifold.accurate_tangent`).  The algorithm is the one of
the planar loops (:mod:`ctmm.loop_manifold`); this module adds the spatial resting configuration and the tangent
cache.  ``docs/closed_loops.md`` section 8.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .. import loop_manifold, validation
from ..errors import ModelError
from .closed_loops import SpatialKinematicLoopModel

__all__ = ["resting_configuration", "chart", "tangent", "tangent_error", "equilibrium", "natural_frequencies"]


def resting_configuration(model: SpatialKinematicLoopModel, q0: Any, t: float = 0.0) -> np.ndarray:
    """``q0`` (array or ``{coordinate: value}`` mapping) projected onto the cut joints (at rest)."""
    if not isinstance(model, SpatialKinematicLoopModel):
        raise ModelError(f"model must be a SpatialKinematicLoopModel, got {model!r:.80}")
    driven = [joint.name for joint in model.tree.joints if joint.driven] + [cut.name for cut in model.cuts if cut.driven]
    if driven:
        raise ModelError(f"spatial kinematic loop {model.name!r}: the driven joints {driven} prescribe a motion in "
                         "time; the linearisation on the constraint manifold is about a resting equilibrium of a "
                         "model without driven joints")
    q, v = model.state(q0, None)
    return model.project(q, np.zeros_like(v), t, iterations=30)[0]


def chart(model: SpatialKinematicLoopModel, q0: np.ndarray, basis: np.ndarray, z: np.ndarray, zdot: np.ndarray,
          t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The constrained state ``(q, v)`` with independent coordinates ``z`` and rates ``zdot`` about ``q0``
    (module docstring; ``basis``: ``N``; :func:`ctmm.loop_manifold.chart`)."""
    return loop_manifold.chart(model, q0, basis, z, zdot, t)


def _tangent(model: SpatialKinematicLoopModel, q0: np.ndarray, t: float, step: float | None
             ) -> tuple[np.ndarray, np.ndarray, float]:
    basis = loop_manifold.independent_basis(model, q0, t)
    if step is None:
        A, error = loop_manifold.accurate_tangent(model, q0, basis, t)
        return A, basis, error
    return loop_manifold.tangent_matrix(model, q0, basis, t, step), basis, np.nan


def _cached(model: SpatialKinematicLoopModel, q0: Any, t: float, step: float | None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    q0 = resting_configuration(model, q0, t)
    if step is not None:
        step = validation.positive("step", step)
    key = ("tangent", q0.tobytes(), float(t), step, model.baumgarte)
    cache = model.linear_cache
    if key not in cache:
        if len(cache) >= 8:
            cache.pop(next(iter(cache)))
        cache[key] = _tangent(model, q0, t, step)
    A, basis, error = cache[key]
    A, basis = A.copy(), basis.copy()
    loop_manifold.require_equilibrium(model, A, basis, q0, t, "ctmm.spatial.closed_loop_linear.equilibrium")
    return A, basis, q0, error


def tangent_error(model: SpatialKinematicLoopModel, q0: Any, t: float = 0.0) -> float:
    """The estimated error of :func:`tangent` (``step=None``) about the equilibrium ``q0``, relative to ``max |A|``
    (:func:`ctmm.loop_manifold.accurate_tangent`; the tangent is cached on the model, so this costs nothing after
    it)."""
    return _cached(model, q0, t, None)[3]


def tangent(model: SpatialKinematicLoopModel, q0: Any, t: float = 0.0, *, step: float | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linearisation about the equilibrium ``q0`` (projected onto the cut joints, at rest): by
    Richardson-extrapolated differences with an error estimate (``step=None``:
    :func:`ctmm.loop_manifold.accurate_tangent`; the estimate from :func:`tangent_error`), or by plain central
    differences at ``step`` [rad, m] (no estimate).

    Returns
    -------
    A : ndarray (2 f, 2 f)
        ``[[0, I], [dz''/dz, dz''/dz']]`` [1/s^2, 1/s].
    N : ndarray (nv, f)
        The basis of the independent coordinates ``z = N^T dx``.
    q0 : ndarray (nq,)
        The configuration on the cut joints.

    Raises
    ------
    ModelError
        ``q0`` is not an equilibrium (the first-order chart is exact only there; find one with
        :func:`equilibrium`), no degree of freedom is left, or the tangent is not accurate (the estimated error
        beyond :data:`ctmm.planar_linearization.JACOBIAN_TOLERANCE`).
    """
    return _cached(model, q0, t, step)[:3]


def equilibrium(model: SpatialKinematicLoopModel, q_guess: Any, t: float = 0.0, *, tolerance: float = 1e-10,
                largest_step: float = 0.2) -> np.ndarray:
    """A static equilibrium near ``q_guess`` (array or mapping): Newton on the independent coordinates, each step at
    most ``largest_step`` [rad, m], converged when the accelerations or the Newton step are below ``tolerance``.

    Raises
    ------
    ModelError
        No equilibrium after 80 Newton steps (a singular tangent stiffness included).
    """
    q = resting_configuration(model, q_guess, t)
    return loop_manifold.newton_equilibrium(model, q, t, tolerance=tolerance, largest_step=largest_step)


def natural_frequencies(model: SpatialKinematicLoopModel, q0: Any, t: float = 0.0) -> np.ndarray:
    """Undamped natural frequencies [rad/s] about the equilibrium ``q0``, ascending (a neutral direction, e.g. the
    free spin of a coupler between two ball joints, gives 0).

    Raises
    ------
    ModelError
        ``q0`` not an equilibrium (:func:`tangent`), velocity-dependent forces at ``q0`` (damping), an unstable
        equilibrium (``omega^2 < 0``).
    """
    return loop_manifold.undamped_frequencies(model, tangent(model, q0, t)[0], tangent_error(model, q0, t))
