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
``A = [[0, I], [dz''/dz, dz''/dz']]`` is formed by central differences (step 1e-5).  ``docs/closed_loops.md``
section 8.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ModelError
from ..planar.closed_loops import at_equilibrium
from .closed_loops import SpatialKinematicLoopModel

__all__ = ["resting_configuration", "chart", "tangent", "equilibrium", "natural_frequencies"]


def resting_configuration(model: SpatialKinematicLoopModel, q0: Any, t: float = 0.0) -> np.ndarray:
    """``q0`` (array or ``{coordinate: value}`` mapping) projected onto the cut joints (at rest)."""
    if not isinstance(model, SpatialKinematicLoopModel):
        raise ModelError(f"model must be a SpatialKinematicLoopModel, got {model!r:.80}")
    driven = [joint.name for joint in model.tree.joints if joint.driven]
    if driven:
        raise ModelError(f"spatial kinematic loop {model.name!r}: the driven joints {driven} prescribe a motion in "
                         "time; the linearisation on the constraint manifold is about a resting equilibrium of a "
                         "model without driven joints")
    q, v = model.state(q0, None)
    return model.project(q, np.zeros_like(v), t, iterations=30)[0]


def chart(model: SpatialKinematicLoopModel, q0: np.ndarray, basis: np.ndarray, z: np.ndarray, zdot: np.ndarray,
          t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The constrained state ``(q, v)`` with independent coordinates ``z`` and rates ``zdot`` about ``q0``
    (module docstring; ``basis``: ``N``)."""
    normal = model.jacobian(q0, t).T
    q = model.retract(q0, basis @ z)
    for _ in range(30):
        phi, _ = model.constraints(q, np.zeros(model.tree.n_velocities), t)
        if np.max(np.abs(phi)) < 1e-14:
            break
        q = model.retract(q, -normal @ np.linalg.lstsq(model.jacobian(q, t) @ normal, phi, rcond=None)[0])
    J = model.jacobian(q, t)
    v = basis @ zdot
    return q, v - normal @ np.linalg.lstsq(J @ normal, J @ v, rcond=None)[0]


def _basis(model: SpatialKinematicLoopModel, q0: np.ndarray, t: float) -> np.ndarray:
    J = model.jacobian(q0, t)
    _, values, vt = np.linalg.svd(J)
    rank = int(np.sum(values > 1e-10 * max(values[0], 1e-300)))
    basis = vt[rank:].T
    if basis.shape[1] == 0:
        raise ModelError(f"spatial kinematic loop {model.name!r}: no degree of freedom is left by the cut joints")
    return basis


def _tangent(model: SpatialKinematicLoopModel, q0: np.ndarray, t: float, step: float) -> tuple[np.ndarray, np.ndarray]:
    basis = _basis(model, q0, t)
    f = basis.shape[1]

    def rates(x: np.ndarray) -> np.ndarray:
        q, v = chart(model, q0, basis, x[:f], x[f:], t)
        return basis.T @ model.solve(q, v, t)[0]

    columns = []
    for k in range(2 * f):
        e = np.zeros(2 * f)
        e[k] = step
        columns.append((rates(e) - rates(-e)) / (2.0 * step))
    A = np.zeros((2 * f, 2 * f))
    A[:f, f:] = np.eye(f)
    A[f:] = np.column_stack(columns)
    return A, basis


def tangent(model: SpatialKinematicLoopModel, q0: Any, t: float = 0.0, *, step: float = 1e-5
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The linearisation about the equilibrium ``q0`` (projected onto the cut joints, at rest).

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
        :func:`equilibrium`), or no degree of freedom is left.
    """
    q0 = resting_configuration(model, q0, t)
    key = ("tangent", q0.tobytes(), float(t), float(step), model.baumgarte)
    cache = model.linear_cache
    if key not in cache:
        if len(cache) >= 8:
            cache.pop(next(iter(cache)))
        cache[key] = _tangent(model, q0, t, step)
    A, basis = (a.copy() for a in cache[key])
    accelerations = model.solve(q0, np.zeros(model.tree.n_velocities), t)[0]
    if not at_equilibrium(A, basis, accelerations):
        raise ModelError(f"spatial kinematic loop {model.name!r}: q0 is not an equilibrium (largest acceleration "
                         f"{np.max(np.abs(accelerations)):.3e}); the linearisation on the constraint manifold is "
                         "taken about an equilibrium: find one with ctmm.spatial.closed_loop_linear.equilibrium")
    return A, basis, q0


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
    nv = model.tree.n_velocities
    residual = np.full(1, np.inf)
    for _ in range(80):
        A, basis = _tangent(model, q, t, 1e-5)
        f = basis.shape[1]
        residual = basis.T @ model.solve(q, np.zeros(nv), t)[0]
        try:
            step = -np.linalg.solve(A[f:, :f], residual)
        except np.linalg.LinAlgError:
            break
        if np.max(np.abs(residual)) < tolerance or np.max(np.abs(step)) < tolerance:
            return q
        step *= min(1.0, largest_step / np.max(np.abs(step)))
        q, _ = chart(model, q, basis, step, np.zeros(f), t)
    raise ModelError(f"spatial kinematic loop {model.name!r}: no equilibrium found near the guess (residual "
                     f"{np.max(np.abs(residual)):.3e}; a singular or neutral tangent stiffness stops Newton: give a "
                     "better guess)")


def natural_frequencies(model: SpatialKinematicLoopModel, q0: Any, t: float = 0.0) -> np.ndarray:
    """Undamped natural frequencies [rad/s] about the equilibrium ``q0``, ascending (a neutral direction, e.g. the
    free spin of a coupler between two ball joints, gives 0).

    Raises
    ------
    ModelError
        ``q0`` not an equilibrium (:func:`tangent`), velocity-dependent forces at ``q0`` (damping), an unstable
        equilibrium (``omega^2 < 0``).
    """
    A, _, _ = tangent(model, q0, t)
    f = A.shape[0] // 2
    stiffness = np.max(np.abs(A[f:, :f]), initial=1e-300)
    if np.max(np.abs(A[f:, f:]), initial=0.0) > 1e-6 * np.sqrt(stiffness):
        raise ModelError(f"spatial kinematic loop {model.name!r}: natural_frequencies needs an undamped model "
                         "(velocity-dependent forces at q0)")
    squared = np.linalg.eigvals(-A[f:, :f])
    scale = np.max(np.abs(squared), initial=1e-300)
    if np.any(squared.real < -1e-8 * scale) or np.max(np.abs(squared.imag), initial=0.0) > 1e-8 * scale:
        raise ModelError(f"spatial kinematic loop {model.name!r}: q0 is not a stable equilibrium "
                         f"(omega^2 = {squared})")
    return np.sort(np.sqrt(np.clip(squared.real, 0.0, None)))
