"""Explicit time integration of planar models driven by the acceleration TMM.

The acceleration-based TMM (:mod:`ctmm.planar.sweep`) turns any planar model into an ODE
``y' = f(t, y)`` with ``y = [q, qdot]``; this module integrates it with a fixed-step classical
Runge-Kutta scheme (own implementation, 4th order) or with any ``scipy.integrate.solve_ivp``
method (RK45, DOP853, Radau, BDF, LSODA).  Results are :class:`PlanarSimulation` objects with
named coordinates.
"""
from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import scipy.integrate

from .. import validation
from ..capabilities import require_planar
from ..errors import ModelError, SimulationError
from .model import PlanarModel
from .sweep import accelerations

SCIPY_METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")


@dataclass(frozen=True)
class PlanarSimulation:
    """Time history of a planar model.

    Attributes
    ----------
    model : PlanarModel
    t : ndarray, shape (n_steps + 1,)
        Times [s].
    q, qdot : ndarray, shape (n_steps + 1, n_coordinates)
        Coordinates and their rates (columns named by ``model.coordinates``).
    method : str
        Integrator used.
    wall_time_s : float
        Wall-clock time of the integration [s].
    iterations : ndarray or None
        Newton iterations per step (implicit DT-TMM only).
    n_evaluations : int
        Number of forward-dynamics (sweep) evaluations.
    """

    model: PlanarModel
    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    method: str
    wall_time_s: float
    iterations: np.ndarray | None = None
    n_evaluations: int = 0
    extra: dict = field(default_factory=dict)

    def coordinate(self, name: str) -> np.ndarray:
        """History of coordinate ``name`` (``"link2.theta"``); ``name + "_dot"`` for its rate."""
        if name.endswith("_dot"):
            return self.qdot[:, self.model.coordinate_index(name[:-4])]
        return self.q[:, self.model.coordinate_index(name)]

    def energy(self) -> np.ndarray:
        """Total mechanical energy [J] at every stored time (see :meth:`PlanarModel.energy`)."""
        return np.array([self.model.energy(q, v, t) for t, q, v in zip(self.t, self.q, self.qdot)])

    def plot(self, names: Sequence[str] | None = None, ax=None):
        """Plot coordinates against time; returns the axes."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots()
        for name in names or self.model.coordinates[:6]:
            ax.plot(self.t, self.coordinate(name), label=name)
        ax.set_xlabel("t [s]")
        ax.legend(fontsize="small")
        return ax


def _initial(model: PlanarModel, q0, qdot0) -> tuple[np.ndarray, np.ndarray]:
    require_planar(model, "ctmm.planar simulation")
    n = model.n_coordinates
    q0 = validation.finite_array("q0", q0, ndim=1)
    qdot0 = validation.finite_array("qdot0", qdot0, ndim=1)
    if q0.shape != (n,) or qdot0.shape != (n,):
        raise ModelError(f"q0 and qdot0 must have shape ({n},) for coordinates "
                         f"{model.coordinates}, got {q0.shape} and {qdot0.shape}")
    return q0.astype(float), qdot0.astype(float)


def _steps(t_final: float, dt: float) -> int:
    t_final = validation.positive("t_final", t_final)
    dt = validation.positive("dt", dt)
    n = int(round(t_final / dt))
    if n < 1 or abs(n * dt - t_final) > 1e-9 * t_final:
        raise ModelError(f"t_final = {t_final!r} must be a whole multiple of dt = {dt!r}")
    return n


def simulate_rk4(model: PlanarModel, q0, qdot0, *, t_final: float, dt: float,
                 store_every: int = 1) -> PlanarSimulation:
    """Classical 4th-order Runge-Kutta with fixed step ``dt`` [s] on the TMM accelerations.

    Parameters
    ----------
    model : PlanarModel
    q0, qdot0 : array_like
        Initial coordinates and rates.
    t_final : float
        End time [s], a whole multiple of ``dt``.
    dt : float
        Step [s].
    store_every : int
        Keep every ``store_every``-th step (the last step is always kept).
    """
    q, v = _initial(model, q0, qdot0)
    n_steps = _steps(t_final, dt)
    h = t_final / n_steps
    ts, qs, vs = [0.0], [q.copy()], [v.copy()]
    start = _time.perf_counter()
    acc = accelerations
    flexible = model.has_flexible
    if flexible:
        from ..flexible.outputs import check_divergence
    for k in range(n_steps):
        t = k * h
        a1 = acc(model, q, v, t)
        q2, v2 = q + 0.5 * h * v, v + 0.5 * h * a1
        a2 = acc(model, q2, v2, t + 0.5 * h)
        q3, v3 = q + 0.5 * h * v2, v + 0.5 * h * a2
        a3 = acc(model, q3, v3, t + 0.5 * h)
        q4, v4 = q + h * v3, v + h * a3
        a4 = acc(model, q4, v4, t + h)
        q = q + (h / 6.0) * (v + 2.0 * v2 + 2.0 * v3 + v4)
        v = v + (h / 6.0) * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        if flexible:
            check_divergence(model, q, t + h, h, "rk4", partial=lambda: PlanarSimulation(
                model, np.array(ts), np.array(qs), np.array(vs), "rk4", 0.0))
        if (k + 1) % store_every == 0 or k + 1 == n_steps:
            if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
                raise SimulationError(f"non-finite state after step {k + 1}", time=t + h)
            ts.append((k + 1) * h)
            qs.append(q.copy())
            vs.append(v.copy())
    wall = _time.perf_counter() - start
    return PlanarSimulation(model, np.array(ts), np.array(qs), np.array(vs), "rk4", wall,
                            n_evaluations=4 * n_steps)


def simulate_scipy(model: PlanarModel, q0, qdot0, *, t_final: float, method: str = "RK45",
                   rtol: float = 1e-8, atol: float = 1e-10, t_eval=None) -> PlanarSimulation:
    """Integrate with ``scipy.integrate.solve_ivp`` (``method`` in :data:`SCIPY_METHODS`).

    Implicit scipy methods (Radau, BDF, LSODA) build their Jacobian by finite differences of
    the TMM right-hand side (``2 n`` sweeps per Jacobian).
    """
    if method not in SCIPY_METHODS:
        raise ModelError(f"method must be one of {SCIPY_METHODS}, got {method!r}")
    q, v = _initial(model, q0, qdot0)
    n = model.n_coordinates
    count = [0]

    def rhs(t, y):
        count[0] += 1
        return np.concatenate([y[n:], accelerations(model, y[:n], y[n:], t)])

    start = _time.perf_counter()
    sol = scipy.integrate.solve_ivp(rhs, (0.0, validation.positive("t_final", t_final)),
                                    np.concatenate([q, v]), method=method, rtol=rtol, atol=atol,
                                    t_eval=t_eval)
    wall = _time.perf_counter() - start
    if model.has_flexible and sol.t.size:
        from ..flexible.outputs import check_divergence
        for k in range(sol.t.size):
            check_divergence(model, sol.y[:n, k], float(sol.t[k]), None, method)
    if not sol.success:
        raise SimulationError(f"solve_ivp({method}) failed: {sol.message}", time=float(sol.t[-1]))
    return PlanarSimulation(model, sol.t, sol.y[:n].T.copy(), sol.y[n:].T.copy(), method, wall,
                            n_evaluations=count[0])


__all__ = ["PlanarSimulation", "simulate_rk4", "simulate_scipy", "SCIPY_METHODS"]
