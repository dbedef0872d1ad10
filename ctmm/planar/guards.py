"""Run guards of the planar (rigid and flexible) integrators: step limits, divergence, partial results.

Built on :mod:`ctmm.guard` (shared by every ctmm simulator):

* **Before the run** -- :func:`check_scheme` compares the step with the known stability limit of
  the scheme (classical RK4: ``omega_max h <= 2 sqrt 2``; every :mod:`ctmm.schemes` scheme by its
  :meth:`~ctmm.schemes.Scheme.stability_limit`: Newmark-beta :func:`ctmm.guard.newmark_limit`,
  Wilson-theta :func:`ctmm.guard.wilson_limit`, backward Euler, Houbolt and generalized-alpha
  unconditionally stable) and warns (:class:`~ctmm.guard.StabilityLimitWarning`),
  raises :class:`~ctmm.errors.ModelError` or does nothing (``stability_check="warn" | "error" |
  "ignore"``).  ``omega_max`` [rad/s] is the spectral radius of the linearisation of
  ``y' = [qdot, qddot(q, qdot, t)]`` about the initial state (central differences of the
  acceleration TMM, ``4 n`` sweeps).  Implicit schemes, stable at any step, are also checked for
  resolution: a step longer than half the period of the SLOWEST motion (smallest non-zero
  eigenvalue modulus, up to 20 coordinates) resolves no motion, and Newton can settle on a
  spurious root of the step equations (a pendulum at 6 periods per step winds round), so it is
  warned about in the same way.
* **During the run** -- :func:`divergence_guard` stops a run whose coordinates go non-finite or
  move farther than ``divergence_bound`` from their initial values (default: ``1e6 * max(1,
  |q0|)``), naming the coordinate and the time.
* **On failure** -- :func:`with_partial` completes a :class:`~ctmm.errors.SimulationError` with
  the :class:`~ctmm.planar.integrate.PlanarSimulation` of the states stored so far.
"""
from __future__ import annotations

import math
import warnings
from typing import Callable

import numpy as np

from ..errors import ModelError, SimulationError
from ..guard import RK4_LIMIT, DivergenceGuard, StabilityLimitWarning, check_step, newmark_limit
from ..schemes import Newmark, Scheme
from .model import PlanarModel

__all__ = ["STABILITY_CHECKS", "check_resolution", "linearised_omega_max", "check_scheme", "divergence_guard", "check_stored",
           "with_partial"]

#: Allowed values of the ``stability_check`` option.
STABILITY_CHECKS = ("warn", "error", "ignore")


def linearised_omega_max(model: PlanarModel | None, q: np.ndarray, qdot: np.ndarray, t: float = 0.0, *,
                         accelerations: Callable | None = None, slowest: bool = False) -> float | tuple:
    """Spectral radius [rad/s] of ``d[qdot, qddot]/d[q, qdot]`` at ``(q, qdot, t)``.

    With ``slowest``, returns ``(fastest, slowest)``: also the smallest non-zero eigenvalue modulus
    (the slowest motion; NaN when it is not computed, above 20 coordinates).

    For an undamped linear model this is the highest natural frequency; about an unstable
    configuration (an inverted pendulum) it is the fastest growth rate.  Jacobian-vector
    products by central differences of ``accelerations(model, q, qdot, t)`` (default
    :func:`ctmm.planar.sweep.accelerations`, steps ``1e-6 max(1, |y|)``): the dense Jacobian up to
    20 coordinates (``4 n`` sweeps), above that ARPACK on the products (a few dozen sweeps,
    relative accuracy 1e-3, ample for a stability check).
    """
    if accelerations is None:
        from .sweep import accelerations

    n = len(q)
    y0 = np.concatenate([np.asarray(q, dtype=float), np.asarray(qdot, dtype=float)])
    scale = 1e-6 * max(1.0, float(np.max(np.abs(y0), initial=0.0)))

    def product(direction: np.ndarray) -> np.ndarray:
        direction = np.real(np.asarray(direction, dtype=float).reshape(-1))
        size = float(np.max(np.abs(direction), initial=0.0))
        if size == 0.0:
            return np.zeros(2 * n)
        step = scale / size
        plus, minus = y0 + step * direction, y0 - step * direction
        derivative = (accelerations(model, plus[:n], plus[n:], t)
                      - accelerations(model, minus[:n], minus[n:], t)) / (2.0 * step)
        return np.concatenate([direction[n:], derivative])

    if n <= 20:
        jacobian = np.column_stack([product(e) for e in np.eye(2 * n)])
        if not np.all(np.isfinite(jacobian)):
            return (math.inf, math.nan) if slowest else math.inf
        moduli = np.abs(np.linalg.eigvals(jacobian))
        fastest = float(np.max(moduli, initial=0.0))
        if not slowest:
            return fastest
        moving = moduli[moduli > 1e-6 * fastest]        # rigid-body modes (0) are not motions to resolve
        return fastest, float(np.min(moving)) if moving.size else math.nan
    import scipy.sparse.linalg

    operator = scipy.sparse.linalg.LinearOperator((2 * n, 2 * n), matvec=product, dtype=float)
    try:
        value = scipy.sparse.linalg.eigs(operator, k=1, which="LM", tol=1e-3, return_eigenvectors=False,
                                         v0=np.ones(2 * n))[0]
    except scipy.sparse.linalg.ArpackNoConvergence as exc:
        value = exc.eigenvalues[0] if len(exc.eigenvalues) else math.inf
    fastest = float(abs(value)) if np.isfinite(value) else math.inf
    return (fastest, math.nan) if slowest else fastest


def check_scheme(model: PlanarModel | None, q0: np.ndarray, qdot0: np.ndarray, dt: float, *, scheme: str | Scheme,
                 policy: str, beta: float | None = None, gamma: float | None = None,
                 accelerations: Callable | None = None, label: str | None = None) -> str | None:
    """Compare ``dt`` [s] with the stability limit of ``scheme`` before a run (module docstring).

    Parameters
    ----------
    scheme : {"rk4", "newmark"} or ctmm.schemes.Scheme
        A scheme object is checked against :meth:`~ctmm.schemes.Scheme.stability_limit`
        (Newmark-beta: :func:`ctmm.guard.newmark_limit`; Wilson-theta: :func:`ctmm.guard.wilson_limit`;
        backward Euler, Houbolt and generalized-alpha: unconditionally stable, so only the
        resolution check applies).  ``"newmark"`` takes ``beta`` and ``gamma``.
    policy : {"warn", "error", "ignore"}
        The ``stability_check`` option.
    beta, gamma : float, optional
        Newmark parameters (``scheme="newmark"``).
    accelerations : callable, optional
        Forward dynamics for :func:`linearised_omega_max` (e.g. the compiled kernel).
    label : str, optional
        What is simulated, for the message (default ``model 'name'``).

    Returns
    -------
    str or None
        The warning text when the limit is exceeded (and the policy is not ``"error"``).
    """
    if policy not in STABILITY_CHECKS:
        raise ModelError(f"stability_check must be one of {STABILITY_CHECKS}, got {policy!r}")
    if policy == "ignore":
        return None
    if isinstance(scheme, Newmark):
        scheme, beta, gamma = "newmark", scheme.beta, scheme.gamma
    if isinstance(scheme, Scheme):
        limit, what = scheme.stability_limit(), repr(scheme)
    elif scheme == "rk4":
        limit, what = RK4_LIMIT, "classical RK4"
    else:
        limit, what = newmark_limit(beta, gamma), f"Newmark(beta={beta:g}, gamma={gamma:g})"
    if math.isinf(limit) and len(q0) > 20:   # slowest motion only from the dense Jacobian (<= 20 coordinates)
        return None
    omega_max, omega_min = linearised_omega_max(model, q0, qdot0, accelerations=accelerations, slowest=True)
    try:   # raise here and warn below, so that the warning points at the user's call
        label = label or f"model {model.name!r}"
        if not math.isinf(limit):
            check_step(f"{what} on {label} (linearised about the initial state)", omega_max, dt, limit,
                       policy="error")
        if scheme != "rk4" and omega_min * dt > math.pi:   # NaN (not computed) compares False
            # an implicit scheme is stable at any step, but a step longer than half the period of the
            # SLOWEST motion resolves no motion at all, and Newton can settle on a spurious solution
            # of the step equations (a pendulum that winds round at every step)
            raise ModelError(f"{what} on {label}: dt = {dt:g} s is longer than half the period of the slowest "
                             f"motion ({2 * math.pi / omega_min:.4g} s, linearised about the initial state): "
                             f"no motion is resolved; use dt <= {math.pi / omega_min:.4g} s")
    except ModelError as exc:
        if policy == "error":
            raise
        warnings.warn(str(exc), StabilityLimitWarning, stacklevel=3)
        return str(exc)
    return None


def divergence_guard(model: PlanarModel, q0: np.ndarray, bound: float | None) -> DivergenceGuard:
    """Guard on the model's coordinates, measured from ``q0`` (``bound`` = ``divergence_bound``)."""
    return DivergenceGuard.from_start(model.coordinates, q0, q0, bound=bound)


def check_stored(guard: DivergenceGuard, t: np.ndarray, q: np.ndarray, qdot: np.ndarray,
                 build: Callable[[int], object], *, model: PlanarModel | None = None, step: float | None = None,
                 method: str = "rk4", replay: Callable[[np.ndarray, int], np.ndarray] | None = None,
                 states: np.ndarray | None = None) -> None:
    """Check a whole stored history (compiled paths: no per-step Python work).

    Raises the :class:`SimulationError` of the first stored row that is non-finite or beyond
    the bound, with ``partial_result = build(k)``: the history truncated before that row.  With
    ``model``, a deformable family's own rule (modal beams, finite-element subsystems:
    ``family.check_divergence`` with the fixed step ``step`` [s] of ``method``, the numpy path's label, so
    that the message is the numpy path's) is checked on the stored rows after the first, in the order of
    :func:`ctmm.planar.integrate.check_state`: at one row the coordinates and rates first.  With ``replay``
    (``replay(state, k)``: the state after step ``k`` from ``state`` after step ``k - 1``; needs ``step`` and the
    whole stored ``states`` of which ``q`` and ``qdot`` are the first columns), the steps between the last good
    stored row and the failing one are run again one by one and checked, so that the failure is reported at its
    step (time) as on the numpy path, which checks after every step.
    """
    n = q.shape[1]

    def rules(time: float, q_k: np.ndarray, qdot_k: np.ndarray) -> None:    # check_state's, in its order
        guard.check(time, q_k)
        if not np.all(np.isfinite(qdot_k)):
            column = int(np.flatnonzero(~np.isfinite(qdot_k))[0])
            raise SimulationError(f"non-finite rate at t = {time:.6g} s in {guard.names[column] + '_dot'!r}",
                                  time=float(time), element=guard.names[column])
        if family is not None:
            family.check_divergence(model, q_k, float(time), step, method)

    def fail(row: int) -> None:
        try:
            if replay is not None and row > 0:
                state = states[row - 1]
                for k in range(int(round(t[row - 1] / step)), int(round(t[row] / step))):
                    state = replay(state, k)
                    rules((k + 1) * step, state[:n], state[n:2 * n])
            rules(t[row], q[row], qdot[row])
        except SimulationError as exc:
            raise with_partial(exc, lambda: build(row)) from None

    bad = ~np.all(np.isfinite(q), axis=1) | ~np.all(np.isfinite(qdot), axis=1)
    if not math.isinf(guard.bound):
        with np.errstate(invalid="ignore"):
            bad |= np.max(np.abs(q - guard.reference), axis=1, initial=0.0) > guard.bound
    first = int(np.argmax(bad)) if np.any(bad) else len(t)
    family = None if model is None else model.deformable_family
    for row in (_deformation_suspects(model, q[1:first]) + 1).tolist() if family is not None else ():
        try:
            family.check_divergence(model, q[row], float(t[row]), step, method)
        except SimulationError:
            fail(row)
    if first < len(t):
        fail(first)


def _deformation_suspects(model: PlanarModel, q: np.ndarray) -> np.ndarray:
    """Indices of the rows of ``q`` (rows, coordinates) that the deformable family's rule must see: every row,
    except for modal beams only (:func:`ctmm.flexible.outputs.check_divergence`: ``sum |eta_i| max|phi_i|`` plus
    ``sqrt 2 sum |u_j|`` of the axial modes), whose rows with that bound below 0.999 of every beam's length
    pass at once (a block test in place of one Python call per row)."""
    suspect = np.zeros(len(q), dtype=bool)
    for j, beam in model.beams.items():
        data = beam.data
        if not all(hasattr(data, name) for name in ("phi_bound", "nq", "np_")):
            return np.arange(len(q))                       # another family (finite-element subsystems): each row
        eta = np.abs(q[:, model.modal_index[j]])
        with np.errstate(invalid="ignore", over="ignore"):
            bound = eta[:, :data.nq] @ np.asarray(data.phi_bound, dtype=float) + math.sqrt(2.0) * eta[:, data.nq:].sum(
                axis=1)
            suspect |= ~(bound <= 0.999 * beam.length)
    return np.flatnonzero(suspect)


def with_partial(error: SimulationError, build: Callable[[], object]) -> SimulationError:
    """Attach ``build()`` as ``error.partial_result`` unless it already carries one; returns ``error``."""
    if error.partial_result is None:
        error.partial_result = build()
    return error


def check_resolution(model: PlanarModel, q: np.ndarray, label: str = "x0") -> None:
    """Refuse initial coordinates too large for double precision to resolve their motion.

    At ``|theta| = 1e20`` rad one unit in the last place is 16 384 rad: every step's increment
    is lost and the angle stays put while its rate evolves -- a silent wrong answer.  Allowed:
    angles ``|theta| <= 1e6`` rad (resolved to 1.2e-10 rad) and positions ``|x| <= 1e6 L``
    (resolved to 1.2e-10 L, ``L`` the model's largest body dimension, at least 1 m).  Modal
    coordinates are not limited here (their scale is the beam's).

    Parameters
    ----------
    model : PlanarModel
    q : ndarray (n_coordinates,)
        Coordinates [m, rad, modal].
    label : str
        Name of the argument in the error message.
    """
    q = np.asarray(q, dtype=float)
    lengths = [np.linalg.norm(v) for ends in model.ends for v in ends.values()]
    lengths += [float(np.linalg.norm(c)) for c in model.com]
    scale = max([1.0] + lengths)
    angle = set(int(k) for k in model.theta_index if k >= 0)
    position = set(int(k) for k in np.ravel(model.xy_index) if k >= 0)
    for k in sorted(angle | position):
        limit = 1e6 if k in angle else 1e6 * scale
        if abs(q[k]) > limit:
            unit = "rad" if k in angle else "m"
            raise ModelError(f"{label}[{model.coordinates[k]!r}] = {q[k]!r} {unit}: double precision "
                             f"resolves only {np.spacing(abs(q[k])):.3g} {unit} at this magnitude, so the "
                             f"motion would be lost; allowed |value| <= {limit:.3g} {unit} (shift angles by "
                             "whole turns, positions by a new origin)")
