"""DT-TMM schemes on planar kinematic loop models (:class:`~ctmm.planar.closed_loops.KinematicLoopModel`).

The tree's implicit stepper (:func:`ctmm.planar.implicit.simulate_implicit`, the O(n) Newton sweep) runs with the cut
forces re-solved from the boundary compliance ``G`` at every Newton iterate and applied as body forces
(:meth:`KinematicLoopModel.cut_inputs`: the boundary unknowns eliminated by their Schur complement inside each
residual, their state dependence in the Newton tangent by directional differences).  After every accepted step the
positions and rates are projected onto the cut joints by the one rule of the RK4
(:class:`ctmm.loop_integration.StepProjection`: the model's Gauss-Newton projection, checked against
``PROJECTION_TOLERANCE``), the drift before and after reported; ``projection=False`` keeps Baumgarte alone for
comparison (``docs/closed_loops.md`` §3b).
"""
from __future__ import annotations

import time

import numpy as np

from ..errors import SimulationError
from ..loop_integration import StepProjection
from ..schemes import Scheme
from .closed_loops import KinematicLoopModel, KinematicLoopSimulation, loop_history
from .implicit import simulate_implicit
from .integrate import PlanarSimulation

__all__ = ["simulate_loop_scheme"]


def simulate_loop_scheme(model: KinematicLoopModel, q0: np.ndarray, v0: np.ndarray, *, t_final: float, dt: float,
                         scheme: Scheme, store_every: int = 1, divergence_bound: float | None = None,
                         stability_check: str = "warn", projection: bool = True
                         ) -> tuple[KinematicLoopSimulation, dict]:
    """A DT-TMM scheme on the spanning tree of ``model`` with the cut forces as iterate inputs (module docstring).

    Parameters
    ----------
    model : KinematicLoopModel
    q0, v0 : ndarray (n_coordinates,)
        Tree coordinates and rates on the cut joints (checked by the caller,
        :func:`ctmm.loop_integration.check_consistent`).
    t_final, dt : float
        End time and step [s].
    scheme : Scheme
        A :mod:`ctmm.schemes` scheme.
    store_every : int
        Store every k-th step (and the last).
    divergence_bound : float, optional
        As in :func:`ctmm.planar.implicit.simulate_implicit`.
    stability_check : {"warn", "error", "ignore"}
        The step against the scheme's stability limit (:func:`ctmm.planar.implicit.simulate_implicit`).
    projection : bool
        Project onto the cut joints after every step (default); False: Baumgarte alone (the drift grows as the
        scheme's truncation error, ``O(dt^2)`` for Newmark).

    Returns
    -------
    run : KinematicLoopSimulation
        Coordinates, rates, cut forces [N], drift [m] and its rate [m/s] at the stored times.
    info : dict
        ``dt``, ``projection`` and, when projecting, ``max_drift_before_projection`` [m],
        ``max_drift_rate_before_projection`` [m/s] and ``max_drift_after_projection`` [m] over every step; the
        Newton iterations per step (``newton_iterations_mean``, ``newton_iterations_max``).

    Raises
    ------
    ConvergenceError, SimulationError
        As :func:`ctmm.planar.implicit.simulate_implicit`; a failed projection (``|Phi|`` above
        :data:`ctmm.loop_integration.PROJECTION_TOLERANCE` after it) with the time, the cut joint and the partial
        result.
    """
    projector = StepProjection(model, f"kinematic loop {model.name!r}") if projection else None
    started = time.perf_counter()
    try:
        implicit = simulate_implicit(model.tree, q0, v0, t_final=t_final, dt=dt, scheme=scheme,
                                     store_every=store_every, divergence_bound=divergence_bound,
                                     stability_check=stability_check, inputs=lambda t, q, v: model.cut_inputs(q, v, t),
                                     project=projector)
    except SimulationError as exc:       # the tree's partial run, with the cut forces and the drift as a whole run's
        if isinstance(exc.partial_result, PlanarSimulation):
            exc.partial_result = _tree_history(model, exc.partial_result, time.perf_counter() - started)
        raise
    run = _tree_history(model, implicit, time.perf_counter() - started)
    info: dict = {"dt": dt, **(projector.report() if projector is not None else {"projection": False})}
    if implicit.iterations is not None and len(implicit.iterations):
        info["newton_iterations_mean"] = float(np.mean(implicit.iterations))
        info["newton_iterations_max"] = int(np.max(implicit.iterations))
    return run, info



def _tree_history(model: KinematicLoopModel, implicit: PlanarSimulation, wall: float) -> KinematicLoopSimulation:
    """The tree run's stored rows as a kinematic loop run (:func:`ctmm.planar.closed_loops.loop_history`)."""
    return loop_history(model, implicit.t, implicit.q, implicit.qdot, implicit.method, wall, implicit.n_evaluations)
