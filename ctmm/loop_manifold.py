"""The linear layer of closed kinematic loops, planar and spatial: the tangent on the constraint manifold.

One algorithm serves :class:`ctmm.planar.closed_loops.KinematicLoopModel` and
:class:`ctmm.spatial.closed_loops.SpatialKinematicLoopModel`; both offer (duck-typed)

* ``n_velocities``: the size of the tree's velocity space (planar: the coordinates' rates);
* ``constraints(q, v, t) -> (Phi, Phi')`` and ``jacobian(q, t) -> J`` (``Phi' = J v`` at rest, ``(m, nv)``);
* ``retract(q, dx)``: the tree coordinates moved by a velocity-space increment ``dx`` (planar: ``q + dx``; spatial:
  quaternions moved by ``G(q) dx`` and renormalised, first order in ``dx``);
* ``solve(q, v, t, inputs) -> (v', cut loads)``: the closed-loop accelerations with the cut loads as boundary
  unknowns;
* ``name``.

About a resting configuration ``q0`` on the cut joints, with ``N`` the orthonormal null space of ``J0 = J(q0)``
(``f`` columns: the mechanism's degrees of freedom), the independent coordinates ``z`` parametrise the constrained
configurations by the chart ``q = (q0 (+) N z) (+) J0^T y`` with ``y`` from ``Phi(q) = 0`` (Gauss-Newton), and the
rates by ``v = N z' + J0^T w`` with ``J(q) v = 0``; ``z'' = N^T v'``.  ``(+)`` is :meth:`retract`: exact for planar
coordinates, first order for quaternions, so the spatial tangent is exact about an equilibrium (the chart's
second-order terms multiply the accelerations, zero there).  The tangent ``A = [[0, I], [dz''/dz, dz''/dz']]`` is
formed by Richardson-extrapolated central differences with an error estimate (:func:`accurate_tangent`, refused by
name beyond :data:`ctmm.planar_linearization.JACOBIAN_TOLERANCE`); the Newton search for an equilibrium uses plain
central differences (:func:`tangent_matrix`: its error only slows Newton, it does not move the equilibrium).  No
complex step here: the loop models' ``solve`` and ``constraints`` take real states (the planar model casts a
complex state to real, dropping the increment), and the chart's minimum-norm projection (``lstsq``) and the
quaternion renormalisation are not analytic in it.  ``docs/closed_loops.md`` sections 2, 3a and 8.4.
"""
from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np

from .errors import ModelError
from .planar_linearization import JACOBIAN_TOLERANCE, jacobian

__all__ = ["independent_basis", "chart", "tangent_matrix", "accurate_tangent", "at_equilibrium",
           "require_equilibrium", "newton_equilibrium", "undamped_frequencies", "undamped_modes",
           "input_output_matrices", "TANGENT_STEPS", "TANGENT_TARGET"]

TANGENT_STEPS = (1e-3, 1e-4, 1e-5)
"""Steps [rad, m, modal, and their rates] of the Richardson differences of :func:`accurate_tangent`, tried in turn
until the estimated error is below :data:`TANGENT_TARGET` (a modal beam's stiff coordinates need ``1e-4``: at
``1e-3`` the ``h^4`` term leaves ``2e-7 max |A|``)."""
TANGENT_TARGET = 1e-10
"""Estimated error of the tangent, relative to ``max |A|``, at which :func:`accurate_tangent` stops refining the
step (smaller steps trade truncation for round-off, which the estimate does not see)."""
_ZERO_MODE_FACTOR = 8.0     # omega^2 within this times f times the tangent's absolute error is 0 (a neutral mode)


def _label(model: Any) -> str:
    return f"{type(model).__name__} {model.name!r}"


def independent_basis(model: Any, q0: np.ndarray, t: float = 0.0) -> np.ndarray:
    """``N`` ``(nv, f)``: the orthonormal null space of ``J(q0)`` (singular values below ``1e-10`` of the largest
    count as zero).

    Raises
    ------
    ModelError
        No degree of freedom is left by the cut joints.
    """
    _, values, vt = np.linalg.svd(model.jacobian(q0, t))
    rank = int(np.sum(values > 1e-10 * max(values[0], 1e-300)))
    basis = vt[rank:].T
    if basis.shape[1] == 0:
        raise ModelError(f"{_label(model)}: no degree of freedom is left by the cut joints")
    return basis


def chart(model: Any, q0: np.ndarray, basis: np.ndarray, z: np.ndarray, zdot: np.ndarray, t: float = 0.0
          ) -> tuple[np.ndarray, np.ndarray]:
    """The constrained state ``(q, v)`` with independent coordinates ``z`` [rad, m] and rates ``zdot``
    [rad/s, m/s] about ``q0`` (module docstring; ``basis``: ``N``)."""
    normal = model.jacobian(q0, t).T
    q = model.retract(q0, basis @ z)
    rest = np.zeros(model.n_velocities)
    for _ in range(30):
        phi, _ = model.constraints(q, rest, t)
        if np.max(np.abs(phi)) < 1e-14:
            break
        q = model.retract(q, -normal @ np.linalg.lstsq(model.jacobian(q, t) @ normal, phi, rcond=None)[0])
    J = model.jacobian(q, t)
    v = basis @ zdot
    return q, v - normal @ np.linalg.lstsq(J @ normal, J @ v, rcond=None)[0]


def tangent_matrix(model: Any, q0: np.ndarray, basis: np.ndarray, t: float = 0.0, step: float = 1e-5
                   ) -> np.ndarray:
    """``A = [[0, I], [dz''/dz, dz''/dz']]`` ``(2 f, 2 f)`` [1/s^2, 1/s] about ``q0`` on the cut joints, by plain
    central differences of ``z'' = N^T v'`` along the chart (step ``step`` [rad, m]; error ``O(step^2)``, no
    estimate): the Newton tangent of :func:`newton_equilibrium`.  For linearisation use :func:`accurate_tangent`."""
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
    return A


def accurate_tangent(model: Any, q0: np.ndarray, basis: np.ndarray, t: float = 0.0) -> tuple[np.ndarray, float]:
    """``A = [[0, I], [dz''/dz, dz''/dz']]`` ``(2 f, 2 f)`` [1/s^2, 1/s] about ``q0`` on the cut joints and its
    estimated error relative to ``max |A|``.

    Richardson-extrapolated central differences of ``z'' = N^T v'`` along the chart
    (:func:`ctmm.planar_linearization.jacobian`: error ``O(h^4)``, estimated from two extrapolations, a kink
    detected) at the steps :data:`TANGENT_STEPS` in turn, stopping at the first whose estimate is below
    :data:`TANGENT_TARGET`, else keeping the best.  (Plain central differences at step ``1e-5`` limited a modal
    beam four-bar's natural frequencies to ``7e-7``; these give ``2e-11``, ``tests/test_flexible_station_cut.py``.)

    Raises
    ------
    ModelError
        The best estimated error exceeds :data:`ctmm.planar_linearization.JACOBIAN_TOLERANCE` (the closed-loop
        accelerations are not smooth about ``q0``: a switching law, a saturation, a singular loop position).
    """
    f = basis.shape[1]

    def rates(x: np.ndarray) -> np.ndarray:
        q, v = chart(model, q0, basis, x[:f], x[f:], t)
        return basis.T @ model.solve(q, v, t)[0]

    def tangent_of(rows: np.ndarray) -> np.ndarray:
        A = np.zeros((2 * f, 2 * f))
        A[:f, f:] = np.eye(f)
        A[f:] = rows
        return A

    rows, error = _refined_jacobian(model, rates, 2 * f, tangent_of, "the tangent on the constraint manifold")
    return tangent_of(rows), error


def _refined_jacobian(model: Any, function: Callable[[np.ndarray], np.ndarray], size: int,
                      matrix: Callable[[np.ndarray], np.ndarray], what: str) -> tuple[np.ndarray, float]:
    """The Richardson Jacobian of ``function`` at ``0`` (``size`` inputs) at the steps :data:`TANGENT_STEPS` in turn
    (:func:`accurate_tangent`) and its estimated error relative to ``max |matrix(J)|``; refused beyond
    :data:`ctmm.planar_linearization.JACOBIAN_TOLERANCE`."""
    best: tuple[np.ndarray, float] | None = None
    for step in TANGENT_STEPS:
        rows, estimate = jacobian(function, np.zeros(size), relative_step=step)
        scale = max(float(np.max(np.abs(matrix(rows)), initial=0.0)), 1e-300)
        error = float(np.max(estimate, initial=0.0) / scale)
        if best is None or not error >= best[1]:
            best = (rows, error)
        if error <= TANGENT_TARGET:
            break
    rows, error = best
    if not error <= JACOBIAN_TOLERANCE:
        raise ModelError(f"{_label(model)}: {what} is not accurate (estimated relative error {error:.2e} > "
                         f"{JACOBIAN_TOLERANCE:.0e} at steps {list(TANGENT_STEPS)}); the closed-loop accelerations "
                         "or outputs are not smooth about q0 (a switching law, a saturation, or a singular position "
                         "of the loop?)")
    return rows, error


def at_equilibrium(A: np.ndarray, basis: np.ndarray, accelerations: np.ndarray, *, acceleration: float = 1e-8,
                   offset: float = 1e-10) -> bool:
    """Whether a resting state is a static equilibrium: its accelerations [rad/s^2, m/s^2] are below
    ``acceleration``, or the static offset to the equilibrium, ``K^-1 N^T v'`` with the tangent stiffness
    ``K = -dz''/dz`` (``A``: :func:`tangent_matrix`, ``basis``: ``N``), is below ``offset`` [rad, m] -- a stiff
    elastic coordinate (a modal beam's) is at rest to round-off with accelerations of ``|K|`` times that."""
    if np.max(np.abs(accelerations), initial=0.0) <= acceleration:
        return True
    f = basis.shape[1]
    try:
        shift = np.linalg.solve(-A[f:, :f], basis.T @ accelerations)
    except np.linalg.LinAlgError:
        return False
    return bool(np.max(np.abs(shift), initial=0.0) <= offset)


def require_equilibrium(model: Any, A: np.ndarray, basis: np.ndarray, q0: np.ndarray, t: float, remedy: str) -> None:
    """Refuse a resting state ``q0`` that is not an equilibrium (:func:`at_equilibrium`).

    Raises
    ------
    ModelError
        ``q0`` is not an equilibrium (the largest acceleration named; ``remedy``: where to find one).
    """
    accelerations = model.solve(q0, np.zeros(model.n_velocities), t)[0]
    if not at_equilibrium(A, basis, accelerations):
        raise ModelError(f"{_label(model)}: q0 is not an equilibrium (largest acceleration "
                         f"{np.max(np.abs(accelerations)):.3e}); the linearisation on the constraint manifold is "
                         f"taken about an equilibrium: find one with {remedy}")


def newton_equilibrium(model: Any, q: np.ndarray, t: float = 0.0, *, tolerance: float = 1e-10,
                       largest_step: float = 0.2) -> np.ndarray:
    """A static equilibrium near ``q`` (on the cut joints, at rest): Newton on the independent coordinates, each
    step at most ``largest_step`` [rad, m] (a far guess does not leap across the mechanism's range), converged when
    the accelerations or the Newton step are below ``tolerance`` (a stiff spring: the accelerations' round-off is
    ``|dz''/dz|`` times larger).

    Raises
    ------
    ModelError
        No equilibrium after 80 Newton steps, or a singular tangent stiffness.
    """
    rest = np.zeros(model.n_velocities)
    residual = np.full(1, np.inf)
    for _ in range(80):
        basis = independent_basis(model, q, t)
        A = tangent_matrix(model, q, basis, t)
        f = basis.shape[1]
        residual = basis.T @ model.solve(q, rest, t)[0]
        try:
            step = -np.linalg.solve(A[f:, :f], residual)
        except np.linalg.LinAlgError:
            break
        if np.max(np.abs(residual)) < tolerance or np.max(np.abs(step)) < tolerance:
            return q
        step *= min(1.0, largest_step / np.max(np.abs(step)))
        q, _ = chart(model, q, basis, step, np.zeros(f), t)
    raise ModelError(f"{_label(model)}: no equilibrium found near the guess (residual {np.max(np.abs(residual)):.3e}; "
                     "80 Newton steps, or a singular or neutral tangent stiffness: give a better guess)")


def _squared_frequencies(model: Any, A: np.ndarray, verb: str, error: float = 0.0) -> np.ndarray:
    """``omega^2`` [1/s^2] of the tangent ``A`` about an equilibrium, ascending (checks of
    :func:`undamped_frequencies`); entries within the tangent's estimated error ``error`` (relative to ``max |A|``,
    :func:`accurate_tangent`) count as zero."""
    f = A.shape[0] // 2
    floor = _ZERO_MODE_FACTOR * f * error * np.max(np.abs(A), initial=0.0)    # what the differences resolve
    if np.max(np.abs(A[f:, f:]), initial=0.0) > max(1e-6 * np.sqrt(np.max(np.abs(A[f:, :f]), initial=1e-300)), floor):
        raise ModelError(f"{_label(model)}: {verb} needs an undamped model (velocity-dependent forces at q0)")
    squared = np.linalg.eigvals(-A[f:, :f])
    noise = max(1e-8 * np.max(np.abs(squared), initial=1e-300), floor)
    if np.any(squared.real < -noise) or np.max(np.abs(squared.imag), initial=0.0) > noise:
        raise ModelError(f"{_label(model)}: q0 is not a stable equilibrium (omega^2 = {squared})")
    return np.sort(np.where(np.abs(squared.real) <= floor, 0.0, np.clip(squared.real, 0.0, None)))


def undamped_frequencies(model: Any, A: np.ndarray, error: float = 0.0) -> np.ndarray:
    """Undamped natural frequencies [rad/s] of the tangent ``A`` about an equilibrium, ascending (a neutral
    direction, e.g. the free spin of a coupler between two ball joints, gives 0; ``omega^2`` within ``error``, the
    tangent's estimated error relative to ``max |A|``, times ``8 f max |A|`` counts as 0: a floating
    mechanism without springs or gravity).

    Raises
    ------
    ModelError
        Velocity-dependent forces (damping), an unstable equilibrium (``omega^2 < 0`` beyond round-off ``1e-8`` of
        the largest and the tangent's error) or complex ``omega^2``.
    """
    return np.sqrt(_squared_frequencies(model, A, "natural_frequencies", error))


def undamped_modes(model: Any, A: np.ndarray, basis: np.ndarray, error: float = 0.0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Undamped natural frequencies [rad/s] (as :func:`undamped_frequencies`) and mode shapes in the tree's velocity
    space (planar: the tree coordinates) of the tangent ``A`` about an equilibrium.

    With ``K_z = -dz''/dz`` (``A``'s lower left block) a mode is ``N phi`` (``basis``: ``N``) with
    ``K_z phi = omega^2 phi``: ``phi`` the right singular vectors of ``K_z - omega^2 I`` with the smallest singular
    values, one per frequency -- for a cluster of ``omega^2`` within ``1e-8`` of the largest (a repeated frequency)
    as many as it holds, an orthonormal basis of its eigenspace in ``z``.  Each shape is normalised to unit largest
    entry (``+1``).

    Returns
    -------
    omega : ndarray (f,)
        Ascending [rad/s].
    shapes : ndarray (nv, f)
        Column ``k``: mode ``k`` in the velocity space [rad, m, per unit of its largest entry].

    Raises
    ------
    ModelError
        As :func:`undamped_frequencies` (verb ``mode_shapes``).
    """
    squared = _squared_frequencies(model, A, "mode_shapes", error)
    f = squared.size
    stiffness = -A[f:, :f]
    cluster = 1e-8 * max(float(squared[-1]) if f else 0.0, 1e-300)
    vectors = np.zeros((f, f))
    first = 0
    while first < f:
        last = first + 1
        while last < f and squared[last] - squared[first] <= cluster:
            last += 1
        shift = float(np.mean(squared[first:last]))
        vectors[:, first:last] = np.linalg.svd(stiffness - shift * np.eye(f))[2][f - (last - first):].T
        first = last
    shapes = basis @ vectors
    largest = shapes[np.argmax(np.abs(shapes), axis=0), np.arange(f)]
    return np.sqrt(squared), shapes / largest


def input_output_matrices(model: Any, q0: np.ndarray, basis: np.ndarray, t: float,
                          output: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
                          unit_inputs: Sequence[Any], step: float | None = None
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``B``, ``C``, ``D`` of the tangent about the resting ``q0``: the outputs ``output(q, v, cut loads)`` and the
    inputs ``unit_inputs`` (one actuator-input object per input, at unit value, as ``model.solve`` takes them).

    ``B`` and ``D`` are exact (the sweep is affine in the inputs); ``C`` along the chart by Richardson differences
    with an error estimate as :func:`accurate_tangent` (``step=None``; refused by name beyond
    :data:`ctmm.planar_linearization.JACOBIAN_TOLERANCE` relative to ``max |C|``), or by plain central differences
    at ``step`` [rad, m, rad/s, m/s].
    """
    f = basis.shape[1]
    rest = np.zeros(model.n_velocities)
    rates0, loads0 = model.solve(q0, rest, t)
    output0 = output(q0, rest, loads0)

    def row(x: np.ndarray) -> np.ndarray:
        q, v = chart(model, q0, basis, x[:f], x[f:], t)
        return output(q, v, model.solve(q, v, t)[1])

    if step is None:
        C = _refined_jacobian(model, row, 2 * f, lambda rows: rows, "the output matrix C")[0]
    else:
        C = np.column_stack([(row(e) - row(-e)) / (2.0 * step) for e in step * np.eye(2 * f)])
    C = C.reshape(len(output0), 2 * f)
    B = np.zeros((2 * f, len(unit_inputs)))
    D = np.zeros((len(output0), len(unit_inputs)))
    for k, inputs in enumerate(unit_inputs):
        rates, loads = model.solve(q0, rest, t, inputs)
        B[f:, k] = basis.T @ (rates - rates0)
        D[:, k] = output(q0, rest, loads) - output0
    return B, C, D
