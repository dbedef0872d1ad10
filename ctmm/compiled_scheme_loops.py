"""Generated DT-TMM schemes of planar models with real-time Feedback loops closed inside the Newton step (issue 13).

``ctmm.simulate(ControlledModel(planar_model, loops), t_final, dt, method=<scheme>, compiled=True)`` (and
``ctmm.simulate(planar_model, ..., loops=..., method=<scheme>, compiled=True)``) runs here: the step of
:mod:`ctmm.compiled_scene_schemes` (the scheme's second-order form, Newton in generated C) on the closed-loop
acceleration

``qddot(q, v, t) = sweep(q, v, u(q, v, t), t)``,   ``u = sum_loops w_j sat(-C_j z_j - D_j e_j) + inputs(t)``,
``e_j = y_j(q, v) - r_j(t)``

with every loop stated by :class:`~ctmm.compiled_loops.ClosedLoops` (its sensors, weights, saturation,
references and open-loop inputs on casadi symbols: the ones the generated RK4 compiles).  ``u`` is evaluated at
the Newton iterate ``(q, v)`` and the scheme's evaluation time ``t_n + fraction dt`` -- where the Python path
(:mod:`ctmm.control.implicit_loops`, its ``inputs`` hook) evaluates it -- so the loops are implicit in the step
(no added lag) and their state dependence is in the Newton tangent (casadi's exact derivative through the
sensors and the sweep).  The initial acceleration is the closed-loop one at ``t = 0``; the scheme's stability
check uses the closed-loop linearisation (:func:`ctmm.planar.guards.check_scheme`).  The two paths agree to
round-off (``tests/test_compiled_scene_schemes_loops.py``, which also checks a PD loop against the independent
Lagrange model in a Newmark step written in the test).

LTI controllers ``C(s)`` (proper, SISO; states ``z``, ``z' = A z + B e``) are stepped as the Python path steps
them: by the trapezoidal rule from the step start ``t_n`` to the iterate's time ``t_n + s``,
``(I - s A / 2) z = (I + s A / 2) z_n + s B (e_n + e) / 2`` with ``e`` at the iterate (so implicit in the step and
in the Newton tangent), and over the whole step at the accepted state.  The generated state carries ``[z_n, e_n]``
after :data:`~ctmm.compiled_scene_schemes.STATUS` (:attr:`CompiledSchemeLoops.controller_size`).

Delayed loops (any ``tau >= dt``, and ``>= 1.4 dt`` with Wilson-theta, as the Python path requires; the step
``dt`` is then a constant of the code) read a ring of the loop signals stored at the last accepted steps, carried
after ``[z_n, e_n]`` (the initial signal held before ``t = 0``).  ``y(t_n + lead dt - tau)`` lies ``j + f`` steps
after ``t_n`` (``j`` whole, ``0 <= f < 1``; lead = the scheme's evaluation fraction inside Newton, 1 at the
accepted state, 0 at restarts and records): on a sample (``f = 0``: ``tau`` a whole multiple of ``dt`` with
Newmark, generalized-alpha, Houbolt, forward Euler) the ring returns it; between two samples it interpolates them
by cubic Hermite from their values and rates, as the Python path's delay history
(:class:`ctmm.control.history.DelayHistory`) does.  The ring then also stores each sample's rate
``dy/dt = J_q qdot + J_v qddot`` with ``qddot`` the closed loop's acceleration at the accepted state (one more sweep
per step; the Python path forms the same derivative by a fourth-order difference, ~1e-12 apart), and restarts
(:meth:`CompiledSchemeLoops.restarted`, where co-simulated controllers were sampled) replace the newest rate with
the one at the new held outputs, as the Python path's history records it after sampling.  The two paths agree to
round-off (``tests/test_compiled_scheme_delays.py``).  The initial acceleration and the stability check take the
delayed loops at the current state (exact at ``t = 0``; the check then also counts their gain, conservatively).

The loop part (controller states, the delay ring, the restarts) is
:class:`ctmm.compiled_scheme_loop_terms.SchemeLoopTerms`, shared with the spatial schemes
(:mod:`ctmm.compiled_spatial_scheme_loops`).

Co-simulated controllers together with loops: :mod:`ctmm.compiled_scheme_cosim` runs this step between their
samples, their held outputs the input ``u``, and restarts it with :meth:`CompiledSchemeLoops.restarted` (the
loops at the stored controller states and ring).

What compiles: static-gain loops ``u = -K e`` with weighted sensor terms (a PD: ``sensor=[(angle, kp),
(rate, kd)]``, ``gain=1``), LTI controllers, saturation, references and open-loop inputs that are numbers or
symbolic :mod:`ctmm.signals`, loops on beam station moment pairs (:attr:`ctmm.compiled_loops.ClosedLoops.channels`),
delayed loops with every scheme (a start-up at another evaluation fraction: the ring read at each step's own),
co-simulated controllers beside them.  Refused by name (:class:`~ctmm.errors.ModelError`; ``compiled=None`` runs
them in Python): a delay shorter than a start-up's later fraction times ``dt``, and what :class:`ClosedLoops`, the
Python path (delays shorter than ``dt`` or ``1.4 dt``) and :class:`~ctmm.compiled_scene_schemes.CompiledSceneScheme`
refuse.
"""
from __future__ import annotations

import os
from typing import Any, Mapping, Sequence

import numpy as np

from .compiled_control import add_loop_signals
from .compiled_loops import ClosedLoops
from .control.planar_time import controller_realisation
from .compiled_scheme_loop_terms import SchemeLoopTerms
from .compiled_parameters import compiled_actuators
from .compiled_scene import symbolic_accelerations_with_inputs
from .compiled_scene_schemes import STATUS, CompiledSceneScheme, simulate_scheme_generated
from .control.controlled_model import ControlledModel
from . import validation
from .errors import ModelError, SimulationError
from .planar.integrate import PlanarSimulation, model_signals, step_total
from .planar.model import PlanarModel
from .results import SimulationResult
from .schemes import Scheme, as_scheme
from .signal_results import SignalSystem, signal_result

__all__ = ["CompiledSchemeLoops", "loop_refusal", "simulate_scheme_loops_generated"]


def loop_refusal(controlled: Any) -> str:
    """Why the generated DT-TMM step cannot close the loops of ``controlled`` ("" when it can)."""
    if not isinstance(controlled, ControlledModel) or not isinstance(controlled.plant, PlanarModel):
        return f"needs a ctmm.control.ControlledModel of a PlanarModel, got {controlled!r}"
    for loop in controlled.loops:
        controller_realisation(loop)                # an improper C(s) raises, naming the loop
    return ""


class CompiledSchemeLoops(SchemeLoopTerms, CompiledSceneScheme):
    """The generated and compiled DT-TMM step of a planar plant with its real-time loops closed inside Newton.

    Parameters
    ----------
    controlled : ControlledModel
        A compilable planar plant and loops :func:`loop_refusal` accepts.
    scheme : Scheme or str
        A :mod:`ctmm.schemes` scheme or its name.
    references : mapping, optional
        ``{loop name: number or symbolic ctmm.signals signal}`` [sensed unit] (default 0), constants of the code.
    inputs : mapping, optional
        ``{actuator name: number or symbolic signal}`` open-loop actuator values [SI], constants of the code.
    store_every, tolerance, max_iterations, rows, cache_dir, compiler
        As in :class:`~ctmm.compiled_scene_schemes.CompiledSceneScheme`.
    dt : float, optional
        The step [s]; required with delayed loops (each delay at least ``dt``, and ``fraction dt`` with
        Wilson-theta; the library serves this step only).

    Attributes
    ----------
    controlled : ControlledModel
    loops : ClosedLoops
        The loops on symbols (the ring plan and controller entries: :class:`SchemeLoopTerms`).

    Raises
    ------
    ModelError
        What :func:`loop_refusal`, :class:`ClosedLoops` or the generated scheme refuses (named); a delayed loop
        without ``dt`` or with a delay the Python path refuses (shorter than ``dt``, or ``fraction dt``).
    """

    def __init__(self, controlled: ControlledModel, scheme: Scheme | str = "newmark", *,
                 references: Mapping[str, Any] | None = None, inputs: Mapping[str, Any] | None = None,
                 store_every: int = 1, tolerance: float = 1e-10, max_iterations: int = 20, rows: int = 64,
                 dt: float | None = None, cache_dir: str | os.PathLike | None = None,
                 compiler: str | None = None, station_inputs: Sequence[str] = ()) -> None:
        reason = loop_refusal(controlled)
        if reason:
            raise ModelError(f"CompiledSchemeLoops: {reason}")
        self.controlled, self.dt = controlled, None if dt is None else validation.positive("dt", dt)
        self.loops = ClosedLoops(controlled, compiled_actuators(controlled.plant, station_inputs), self.dt,
                                 references, inputs, whole_delays=False)
        self.setup_loops(as_scheme(scheme))
        super().__init__(controlled.plant, scheme, store_every=store_every, tolerance=tolerance,
                         max_iterations=max_iterations, rows=rows, cache_dir=cache_dir, compiler=compiler,
                         station_inputs=station_inputs)

    def plant_sweep(self) -> Any:
        """The planar sweep with the inputs :attr:`actuators` and the loops' channels."""
        return symbolic_accelerations_with_inputs(self.model, self.actuators,
                                                  [unit for _, unit in self.loops.channels])

    def restarted(self, state: np.ndarray, held: np.ndarray | None, t: float, start: bool = False) -> np.ndarray:
        """:meth:`CompiledSceneScheme.restarted` with the loops at the stored controller entries (states, delayed
        signals from the ring) and the newest ring sample's rates from the new acceleration (the Python path
        stores them after the controllers due at ``t`` were sampled)."""
        n, first = self.model.n_coordinates, self.status_index + len(STATUS)
        out = np.array(state, dtype=float)
        held = np.zeros(len(self.actuators)) if held is None else np.asarray(held, dtype=float)
        acceleration, out[first:] = self.restart_terms(out[:n], out[n:2 * n], held, validation.finite("t", t),
                                                       out[first:])
        out[2 * n:3 * n] = out[3 * n:4 * n] = acceleration
        if start:
            out[4 * n:5 * n] = out[5 * n:6 * n] = out[:n]
        return out


def simulate_scheme_loops_generated(controlled: ControlledModel, q0: Any, qdot0: Any, *, t_final: float, dt: float,
                                    scheme: Scheme | str = "newmark", references: Mapping[str, Any] | None = None,
                                    inputs: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                                    store_every: int = 1, divergence_bound: float | None = None,
                                    stability_check: str = "warn", tolerance: float = 1e-10,
                                    max_iterations: int = 20, cache_dir: str | os.PathLike | None = None,
                                    compiled: CompiledSchemeLoops | None = None) -> SimulationResult:
    """A DT-TMM scheme of a controlled planar model with its real-time loops closed in generated C.

    The result is the one of :func:`ctmm.control.planar_time.simulate_closed_loop` with the same scheme
    (coordinates, rates, ``outputs``, ``"<loop>.y"``, ``"<loop>.u"``; method label ``"dt-tmm-generated/<Scheme>"``,
    ``info`` with ``dt``, ``compile_time_s`` and ``newton_iterations`` (the total)).

    Parameters
    ----------
    controlled : ControlledModel
        Plant and loops (:func:`loop_refusal`).
    q0, qdot0 : array_like
        Initial coordinates [rad, m] and rates.
    t_final, dt : float
        End time and step [s].
    scheme : Scheme or str
    references, inputs : mapping, optional
        As in :class:`CompiledSchemeLoops` (with ``compiled``: its own; giving them too is refused).
    outputs : sequence of str
        Sensor names stored at every row.
    store_every, divergence_bound, stability_check, tolerance, max_iterations, cache_dir
        As in :func:`ctmm.compiled_scene_schemes.simulate_scheme_generated` (the stability check with the loops).
    compiled : CompiledSchemeLoops, optional
        Of ``controlled`` with this scheme and ``store_every``, to reuse (default: built now).

    Raises
    ------
    ModelError
        What the generated step refuses (named), bad arguments, no compiler.
    ConvergenceError, SimulationError
        As :func:`~ctmm.compiled_scene_schemes.simulate_scheme_generated`, with the result stored before the
        failure (loop signals included) as ``partial_result``.
    """
    step = None if dt is None else t_final / step_total(t_final, dt)        # (None: refused by the scheme's run)
    if compiled is None:
        compiled = CompiledSchemeLoops(controlled, scheme, references=references, inputs=inputs,
                                       store_every=store_every, tolerance=tolerance, max_iterations=max_iterations,
                                       dt=step, cache_dir=cache_dir)
    elif not isinstance(compiled, CompiledSchemeLoops) or compiled.controlled is not controlled or \
            references or inputs:
        raise ModelError(f"compiled must be a CompiledSchemeLoops of this controlled model (its references and "
                         f"inputs are its own: leave references and inputs out), got {compiled!r}")
    signals_of = compiled.loops.signals()

    def result(simulation: PlanarSimulation, failed: bool = False) -> SimulationResult:
        model = controlled.plant
        signals, units = model_signals(model, simulation.t, simulation.q, simulation.qdot, outputs)
        states = simulation.extra.get("controller_states", np.zeros((len(simulation.t), compiled.controller_size)))
        block = np.hstack([simulation.q, simulation.qdot, compiled.signal_states(states, simulation.t)])
        extra = add_loop_signals(controlled, compiled.loops, signals_of, block, simulation.t, signals, units)
        kept = {key: value for key, value in simulation.extra.items() if key != "controller_states"}
        info = {"dt": dt, "method": simulation.method, "wall_time_s": simulation.wall_time_s,
                "n_evaluations": simulation.n_evaluations,
                "loops": {law.name: "real-time" if law.steps == 0 else "history" for law in compiled.loops.laws},
                **kept, **extra, **({"failed": True} if failed else {})}
        return signal_result(SignalSystem(model, units, list(controlled.loops)), simulation.t, signals,
                             simulation.method, info)

    try:
        simulation = simulate_scheme_generated(
            controlled.plant, q0, qdot0, t_final=t_final, dt=dt, scheme=as_scheme(scheme), store_every=store_every,
            divergence_bound=divergence_bound, stability_check=stability_check, tolerance=tolerance,
            max_iterations=max_iterations, compiled=compiled)
    except SimulationError as exc:
        if isinstance(exc.partial_result, PlanarSimulation):
            exc.partial_result = result(exc.partial_result, failed=True)
        raise
    return result(simulation)
