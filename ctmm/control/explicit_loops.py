"""The explicit runs of the loop-closing driver (:func:`ctmm.control.planar_time.simulate_closed_loop`): fixed-step
RK4 and a ``scipy.integrate`` solver stepped here, on the state ``y = [q, v, controller states]`` of its closed loop
(``system``: rates, controller sampling, delay history; ``rows``: the stored rows).

A kinematic loop plant (one with ``step_projection``: :class:`~ctmm.planar.loop_plant.KinematicLoopPlant`,
:class:`~ctmm.spatial.closed_loop_plant.SpatialLoopPlant`) has its state projected onto the cut joints by the one
rule of :class:`ctmm.loop_integration.StepProjection` (the RK4 of the model alone, the DT-TMM schemes):

* RK4: after every step, before the loops, the controllers and the delay history read it;
* ``solve_ivp``: at every controller sample, where the solver restarts anyway (a segment per sample).  Without
  co-simulated controllers the solver runs in one piece and the drift is held by Baumgarte alone: a projection
  between its own steps would move the state under the solver's error control and dense output (and restart its
  step-size history), so it is not done (``docs/closed_loops.md`` §3c).

The projection's report (``info``: ``projection``, ``max_drift_before_projection``, ...) is returned.
"""
from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np
import scipy.integrate

from .. import validation
from ..loop_integration import StepProjection
from ..planar.integrate import accepted_steps, run_fixed_step, step_total
from ..progress import progress_bar

__all__ = ["project_state", "run_rk4", "run_scipy", "state_projection"]


def state_projection(system: Any, projection: bool = True) -> StepProjection | None:
    """The projection of a kinematic loop plant's state onto its cut joints (its ``step_projection``), else (or
    without ``projection``: Baumgarte alone) ``None``."""
    return system.plant.step_projection() if projection and hasattr(system.plant, "step_projection") else None


def project_state(projector: StepProjection, system: Any, t: float, y: np.ndarray) -> None:
    """Map ``y``'s ``q, v`` at time ``t`` [s] onto the cut joints in place (controller states unchanged)."""
    n, base = system.n, system.base
    y[:n], y[n:base] = projector(t, y[:n], y[n:base])


def run_rk4(system: Any, rows: Any, check_state: Callable[[float, np.ndarray], None], dt: float, n_steps: int,
            store_every: int, progress: bool | None, projection: bool = True) -> dict:
    """Fixed-step RK4; a kinematic loop plant's state projected after every step, before the loops, controllers and
    history read it (returns the projection's ``info`` entries)."""
    system.use_cache = True
    projector = state_projection(system, projection)

    def check(t: float, y: np.ndarray) -> None:
        check_state(t, y)
        if projector is not None:       # in place: the fresh state the next step starts from
            project_state(projector, system, t, y)

    def on_step(k: int, t: float, y: np.ndarray) -> None:
        system.sample(k, t, y)
        system.remember(t, y)

    run_fixed_step(system.rate, rows.y[0], h=dt, n_steps=n_steps, store_every=store_every, check=check,
                   record=rows.add, on_step=on_step, progress=progress,
                   description=f"ctmm.simulate ({system.plant.label}, rk4)")
    return {} if projector is None else projector.report()


def run_scipy(system: Any, rows: Any, check_state: Callable[[float, np.ndarray], None], y0: np.ndarray,
              t_final: float, dt: float | None, method: str, rtol: float, atol: float, max_step: float,
              progress: bool | None, projection: bool = True) -> dict:
    """Solver stepped segment by segment: one segment per controller sample (restart), else one; a kinematic loop
    plant's state projected at every segment end (where the solver restarts; returns the projection's ``info``)."""
    rtol, atol = validation.positive("rtol", rtol), validation.positive("atol", atol)
    if system.master is not None:
        n_segments = step_total(t_final, dt)
        ends = [(k + 1) * dt for k in range(n_segments)]
    else:
        ends = [t_final]
    grid_next = 1
    y, t = y0, 0.0
    projector = state_projection(system, projection) if system.master is not None else None
    solver_type: Callable = getattr(scipy.integrate, method)
    bar = progress_bar(len(ends), f"ctmm.simulate ({system.plant.label}, {method})", enabled=progress and len(ends) > 1)
    try:
        for k, t_end in enumerate(ends):
            if k > 0:
                system.sample(k, t, y)
            # a finite max_step (a loop delay) bounds the first step too: scipy's own first-step guess
            # evaluates the rate at t + h0 with h0 unbounded, i.e. beyond the stored delay history
            first = {"first_step": min(max_step, t_end - t)} if math.isfinite(max_step) else {}
            solver = solver_type(system.rate, t, y, t_end, rtol=rtol, atol=atol, max_step=max_step, **first)
            for t_old in accepted_steps(solver, method):
                t_new, y_new = float(solver.t), solver.y.copy()
                check_state(t_new, y_new)
                if projector is not None and solver.status == "finished":    # a sample (restart) is next
                    project_state(projector, system, t_new, y_new)
                if dt is None:
                    rows.add(t_new, y_new)
                else:
                    dense = None
                    while grid_next * dt <= t_new + 1e-12 * max(1.0, t_new) and grid_next * dt > t_old:
                        t_row = grid_next * dt
                        if abs(t_row - t_new) <= 1e-12 * max(1.0, t_new):
                            rows.add(t_new, y_new)
                        else:
                            dense = dense or solver.dense_output()
                            rows.add(t_row, dense(t_row))
                        grid_next += 1
                system.remember(t_new, y_new)
                t, y = t_new, y_new
            bar.update()
    finally:
        bar.close()
    if dt is not None and (not rows.t or rows.t[-1] < t_final - 1e-9 * t_final):
        rows.add(t, y)
    return {} if projector is None else projector.report()
