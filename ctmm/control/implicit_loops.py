"""Loops, inputs and controllers of a planar or spatial model closed by an implicit DT-TMM scheme.

:func:`run_implicit` is the scheme path of :func:`ctmm.control.planar_time.simulate_closed_loop`:
one :func:`ctmm.planar.implicit.simulate_implicit` run (planar plants) or one
:func:`ctmm.spatial.implicit.simulate_spatial_implicit` run (spatial plants, Lie-group form; its
``input_map`` and ``after_step`` are the same two hooks) whose

* ``inputs`` hook (:meth:`LoopSteps.actuator_inputs`) gives every actuator value at each Newton
  iterate: open-loop inputs, real-time loops (implicit in the step: their state dependence is in
  the Newton tangent), delayed loops from the one delay history, held controller outputs;
* ``after_step`` callback samples the co-simulated controllers (the one master,
  :class:`~ctmm.control.cosim.CoSimulation`), appends to the delay history and stores the row;
  when a controller was sampled the next step starts from the acceleration with its new held
  output (second order in ``dt`` with zero-order hold);
* a kinematic loop plant (``implicit_model``, ``implicit_inputs``, ``step_projection``) steps its spanning tree with
  the cut loads added to the inputs at every iterate and projects every accepted step onto its cut joints
  (:class:`ctmm.loop_integration.StepProjection`) before the controllers see it.

A loop's saturation clips ``u`` at every iterate (piecewise linear: the Newton tangent, by directional
differences, is the slope of the side the iterate is on).  The states ``z`` of an LTI loop controller
``z' = A z + B e``, ``u = -C z - D e`` advance by the
trapezoidal rule from the step start ``t_n`` to the iterate's time ``t``:
``(I - s A / 2) z = (I + s A / 2) z_n + s B (e_n + e) / 2`` with ``s = t - t_n`` (``e`` at the
iterate; implicit in the step, second order), and at the accepted state over the whole step.

A loop delay must be 0 or at least the distance from the step start to the scheme's evaluation
time (``dt``; ``theta dt`` for Wilson-theta): the delayed value must come from a completed step.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .. import validation
from ..errors import ModelError, SimulationError
from ..progress import progress_bar
from ..schemes import Scheme

__all__ = ["FRACTION_STEPS", "check_scheme_delays", "LoopSteps", "run_implicit"]

FRACTION_STEPS = 8
"""Steps whose evaluation fractions :func:`check_scheme_delays` reads (start-ups are shorter: Houbolt's is 2)."""


def check_scheme_delays(loops: Any, scheme: Scheme, dt: float) -> None:
    """Refuse a loop delay that an implicit step reaches (Wilson-theta: shorter than ``theta dt``).

    Parameters
    ----------
    loops : sequence
        Resolved loops with ``name`` and ``delay`` [s].
    scheme : Scheme
        The scheme (its evaluation time as a fraction of the step).
    dt : float
        Step [s].

    Raises
    ------
    ModelError
        A delay ``0 < tau < fraction dt`` with the largest fraction of the scheme's first
        :data:`FRACTION_STEPS` steps (a start-up may evaluate at another fraction than the steps after it; the step
        ``dt`` itself is checked with the loops).
    """
    probe = scheme.start_history(np.zeros(1), np.zeros(1), np.zeros(1))
    fractions = []
    for steps in range(FRACTION_STEPS):
        probe.steps = steps
        fractions.append(float(scheme.second_order_step(probe, dt).time_fraction))
    fraction = max(fractions)
    some = "" if fraction == fractions[0] and fraction == fractions[-1] else " in some steps"
    for loop in loops:
        if fraction > 1.0 and 0.0 < loop.delay < fraction * dt * (1.0 - 1e-9):
            raise ModelError(f"loop {loop.name!r}: delay = {loop.delay!r} s is shorter than {fraction:g} dt = "
                             f"{fraction * dt!r} s; {type(scheme).__name__} imposes the equations of motion at "
                             f"t_n + {fraction:g} dt{some}, where the loop needs y(t - delay) from a completed step: "
                             f"use dt <= {loop.delay / fraction!r} s, another scheme or delay=0")


class LoopSteps:
    """The closed-loop system of a planar run seen step by step by an implicit scheme.

    Parameters
    ----------
    system : object
        The closed loop of :mod:`ctmm.control.planar_time` (``n`` coordinates, state size
        ``size``, ``loops`` with ``A, B, C, D, states``, ``loop_values``, ``actuator_values``,
        ``ports``).
    """

    def __init__(self, system: Any) -> None:
        self.system = system
        self.base = system.base                 # [q, v] (planar: 2 n; spatial: nq + nv) before the states z
        self.stateful = system.size > self.base
        self.start: tuple[float, np.ndarray, list] = (0.0, np.zeros(system.size - self.base), [])

    def begin(self, t: float, y: np.ndarray) -> None:
        """Start the next step at the accepted full state ``y = [q, v, z]`` at ``t`` [s]."""
        self.start = (t, y[self.base:].copy(), [e for _, e, _ in self.system.loop_values(t, y)])

    def _states_at(self, t: float, loop_values: list) -> tuple[np.ndarray, list]:
        """Controller states at ``t`` (trapezoidal rule from the step start) and the loop values
        with ``u = -C z - D e`` at those states (the error ``e`` does not depend on ``z``)."""
        t_n, z_n, e_n = self.start
        z, out, step = z_n.copy(), list(loop_values), t - t_n
        for k, loop in enumerate(self.system.loops):
            if not loop.A.shape[0]:
                continue
            i = loop.states.start - self.base
            j = i + loop.A.shape[0]
            e = loop_values[k][1]
            if step > 0.0:
                half = 0.5 * step
                rhs = z_n[i:j] + half * (loop.A @ z_n[i:j]) + half * loop.B[:, 0] * (e_n[k] + e)
                z[i:j] = np.linalg.solve(np.eye(j - i) - half * loop.A, rhs)
            out[k] = (loop_values[k][0], e, float(loop.loop.saturate(-float((loop.C @ z[i:j])[0]) - loop.D * e)))
        return z, out

    def actuator_inputs(self, t: float, q: np.ndarray, v: np.ndarray) -> Any:
        """The actuator inputs at ``(t, q, v)`` (the ``inputs`` hook of
        :func:`~ctmm.planar.implicit.simulate_implicit`), ``None`` when nothing is driven."""
        system = self.system
        y = np.concatenate([q, v, self.start[1]])
        loop_values = system.loop_values(t, y)
        if self.stateful:
            loop_values = self._states_at(t, loop_values)[1]
        values = system.actuator_values(t, y, loop_values)
        return system.ports.inputs(values) if values else None

    def end(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The full state ``[q, v, z]`` after an accepted step to ``t`` [s]; starts the next one.

        Raises
        ------
        SimulationError
            A non-finite controller state (names the loop and the time).
        """
        y = np.concatenate([q, v, self.start[1]])
        if self.stateful:
            y[self.base:] = self._states_at(t, self.system.loop_values(t, y))[0]
            bad = [loop.name for loop in self.system.loops if not np.all(np.isfinite(y[loop.states]))]
            if bad:
                raise SimulationError(f"non-finite controller state of loop {bad[0]!r} at t = {t:.6g} s",
                                      time=float(t), element=bad[0])
        self.begin(t, y)
        return y


def run_implicit(system: Any, rows: Any, q0: np.ndarray, qdot0: np.ndarray, t_final: float, dt: float,
                 scheme: Scheme, store_every: int, progress: bool | None, stability_check: str,
                 divergence_bound: float | None) -> dict:
    """One implicit DT-TMM run of a closed loop (module docstring).

    Parameters
    ----------
    system : object
        The closed loop of :mod:`ctmm.control.planar_time` (also ``sample``, ``remember``,
        ``master``, ``input_functions``, ``evaluations``); its controllers were sampled and its
        history started at ``t = 0``.
    rows : object
        Row store with ``add(t, y)`` (the initial row already added).
    q0, qdot0 : ndarray
        Initial coordinates and rates.
    t_final, dt : float
        End time and step [s].
    scheme : Scheme
    store_every : int
        Keep every ``store_every``-th step (the last always).
    progress : bool or None
        Progress bar.
    stability_check : {"warn", "error", "ignore"}
        Pre-run check of the scheme (real-time loops included).
    divergence_bound : float or None
        As in :func:`~ctmm.planar.implicit.simulate_implicit`.

    Returns
    -------
    dict
        ``newton_iterations_mean`` and ``newton_iterations_max`` for the result's ``info``; with a projection
        its report (:meth:`ctmm.loop_integration.StepProjection.report`).

    Raises
    ------
    SimulationError
        From the run, without a partial result (the caller builds it from ``rows``).
    """
    from ..planar.implicit import simulate_implicit
    from ..planar.integrate import step_total
    from ..spatial.implicit import simulate_spatial_implicit

    n_steps = step_total(t_final, dt)
    store_every = validation.integer("store_every", store_every, minimum=1)
    steps = LoopSteps(system)
    driven = bool(system.loops or system.input_functions or system.master is not None)
    bar = progress_bar(n_steps, f"ctmm.simulate ({system.plant.label}, {type(scheme).__name__})", enabled=progress)

    def after_step(k: int, t: float, q: np.ndarray, v: np.ndarray) -> bool:
        y = steps.end(t, q, v)
        jumped = system.sample(k, t, y)
        system.remember(t, y)
        if k % store_every == 0 or k == n_steps:
            rows.add(t, y)
        bar.update()
        return jumped

    steps.begin(0.0, np.concatenate([q0, qdot0, np.zeros(system.size - system.base)]))
    plant = system.plant
    hook = steps.actuator_inputs if driven else None
    if hasattr(plant, "implicit_inputs"):          # a kinematic loop: the tree, the cut loads in the inputs
        hook = plant.implicit_inputs(hook)
    projector = plant.step_projection() if hasattr(plant, "step_projection") else None   # onto its cut joints
    try:
        if plant.label.startswith("spatial"):
            simulation = simulate_spatial_implicit(getattr(plant, "implicit_model", system.model), t_final, dt,
                                                   scheme=scheme, x0=q0, v0=qdot0, store_every=n_steps,
                                                   divergence_bound=divergence_bound, input_map=hook,
                                                   after_step=after_step, project=projector)
            iterations, evaluations = simulation.info["iterations"], simulation.info["n_evaluations"]
        else:
            simulation = simulate_implicit(getattr(plant, "implicit_model", system.model), q0, qdot0,
                                           t_final=t_final, dt=dt, scheme=scheme, store_every=n_steps,
                                           divergence_bound=divergence_bound, stability_check=stability_check,
                                           inputs=hook, after_step=after_step, project=projector)
            iterations, evaluations = simulation.iterations, simulation.n_evaluations
    except SimulationError as exc:
        exc.partial_result = None          # the caller's rows are the partial result
        raise
    finally:
        bar.close()
    system.evaluations += int(evaluations)
    return {"newton_iterations_mean": float(np.mean(iterations)), "newton_iterations_max": int(np.max(iterations)),
            **({} if projector is None else projector.report())}
