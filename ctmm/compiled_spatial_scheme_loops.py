"""Generated DT-TMM schemes of spatial models with their feedback loops closed inside the Newton step (issues 13, 14).

``ctmm.simulate(ControlledModel(spatial_model, loops), t_final, dt, method=<scheme>, compiled=True)`` (and
``ctmm.simulate(spatial_model, ..., loops=..., method=<scheme>, compiled=True)``) runs here: the Lie-group step of
:class:`~ctmm.compiled_spatial_schemes.CompiledSpatialScheme` (Newton in generated C on
``r(a) = a - v_dot(q_n (+) delta(a), v(a), t_n + fraction dt)``) on the closed-loop acceleration of
:class:`~ctmm.compiled_scheme_loop_terms.SchemeLoopTerms`, the loop part the planar schemes use too
(:class:`~ctmm.compiled_scheme_loops.CompiledSchemeLoops`): real-time loops evaluated at the Newton iterate (their
state dependence in the exact Newton tangent), LTI controller states by the Python path's trapezoidal rule, delayed
loops read from a ring of samples (cubic Hermite between samples), saturation, references and open-loop port inputs
that are numbers or symbolic :mod:`ctmm.signals`; the plant's loads and driven joints may carry symbolic signals too
(stated at the step's time symbol).  The sensors are the spatial ones of
:class:`~ctmm.compiled_spatial_loops.SpatialSymbols`, the loops' actuators port actuators of
:func:`~ctmm.compiled_spatial_loops.loop_acceleration` (the input ``u`` of the step).  Generated state: the one of
:class:`~ctmm.compiled_spatial_schemes.CompiledSpatialScheme` followed by the controller entries ``[z_n, e_n, ring]``.
The result equals the Python path's (:func:`ctmm.control.planar_time.simulate_closed_loop` through
:func:`ctmm.spatial.implicit.simulate_spatial_implicit`) to round-off (``tests/test_compiled_spatial_scheme_loops.py``,
which also checks a delayed PD pendulum against the Newton-Euler equations by the method of steps).

Refused by name (:class:`~ctmm.errors.ModelError`; ``compiled=None`` runs them in Python): what
:func:`~ctmm.compiled_spatial.spatial_compile_refusal`, :class:`~ctmm.compiled_loops.ClosedLoops` and the delay
checks of the Python path refuse (and a delay shorter than a start-up's later evaluation fraction times ``dt``).
"""
from __future__ import annotations

import os
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .compiled_control import add_loop_signals
from .compiled_loops import ClosedLoops
from .control.planar_time import controller_realisation
from .compiled_scene_schemes import STATUS
from .compiled_scheme_loop_terms import SchemeLoopTerms, loop_actuators
from .compiled_spatial_loops import SpatialSymbols, loop_acceleration
from .compiled_spatial_signals import spatial_compile_refusal
from .compiled_spatial_schemes import (CompiledSpatialScheme, checked_spatial_result, generated_rows,
                                       warn_conditionally_stable)
from .control.controlled_model import ControlledModel
from .control.plants import plant_of
from .errors import ModelError
from .planar.integrate import check_store_every, step_total
from .results import SimulationResult
from .schemes import Scheme, as_scheme
from .signal_results import SignalSystem, signal_result
from .spatial.integrate import initial_state
from .spatial.model import SpatialModel

__all__ = ["CompiledSpatialSchemeLoops", "restarted_loop_state", "simulate_spatial_scheme_loops_generated"]


class CompiledSpatialSchemeLoops(SchemeLoopTerms, CompiledSpatialScheme):
    """The generated Lie-group DT-TMM step of a spatial plant with its loops closed inside Newton (module docstring).

    Parameters
    ----------
    controlled : ControlledModel
        A spatial plant (:func:`~ctmm.compiled_spatial.spatial_compile_refusal`) and its loops.
    scheme : Scheme or str
        A :mod:`ctmm.schemes` scheme or its name.
    references : mapping, optional
        ``{loop name: number or symbolic ctmm.signals signal}`` [sensed unit] (default 0), constants of the code.
    inputs : mapping, optional
        ``{port actuator name: number or symbolic signal}`` open-loop values [SI], constants of the code.
    dt : float, optional
        The step [s]; required with delayed loops (each delay at least ``dt``, and ``fraction dt`` with
        Wilson-theta; the library then serves this step only).
    held : sequence of str
        Further port actuators of the input ``u``, held between calls (co-simulated controllers' outputs,
        :mod:`ctmm.compiled_scheme_cosim`).
    store_every, tolerance, max_iterations, rows, cache_dir, compiler
        As in :class:`~ctmm.compiled_spatial_schemes.CompiledSpatialScheme`.

    Attributes
    ----------
    controlled : ControlledModel
    actuators : tuple of str
        The port actuators of the step's input ``u`` (those of the loops, of ``inputs`` and ``held``).
    loops : ClosedLoops
        The loops on spatial symbols.

    Raises
    ------
    ModelError
        A plant or loop the generated step refuses (named), a delayed loop without ``dt`` or with a delay the
        Python path refuses.
    """

    def __init__(self, controlled: ControlledModel, scheme: Scheme | str = "newmark", *,
                 references: Mapping[str, Any] | None = None, inputs: Mapping[str, Any] | None = None,
                 dt: float | None = None, held: Sequence[str] = (), store_every: int = 1, tolerance: float = 1e-10,
                 max_iterations: int = 50, rows: int = 64, cache_dir: str | os.PathLike | None = None,
                 compiler: str | None = None) -> None:
        if not isinstance(controlled, ControlledModel) or not isinstance(controlled.plant, SpatialModel):
            raise ModelError(f"CompiledSpatialSchemeLoops: controlled must be a ctmm.control.ControlledModel of a "
                             f"SpatialModel, got {controlled!r}")
        for loop in controlled.loops:
            controller_realisation(loop)                # an improper C(s) raises, naming the loop
        ports, model = controlled.ports, controlled.plant
        reason = spatial_compile_refusal(model, time_signals=True)         # signals on the step's time symbol
        if reason:
            raise ModelError(f"CompiledSpatialSchemeLoops: {reason}")
        self.controlled, self.dt = controlled, None if dt is None else validation.positive("dt", dt)
        self.references, self.open_inputs = dict(references or {}), dict(inputs or {})
        self.actuators, self.parameters = loop_actuators(controlled, inputs, held), np.zeros(0)
        self.loops = ClosedLoops(controlled, self.actuators, self.dt, references, inputs,
                                 symbols=SpatialSymbols(model, ports), whole_delays=False)
        self.setup_loops(as_scheme(scheme))
        super().__init__(model, scheme, store_every=store_every, tolerance=tolerance, max_iterations=max_iterations,
                         rows=rows, cache_dir=cache_dir, compiler=compiler)

    def described(self) -> tuple:
        """The loops, their references and inputs, the actuators of ``u``, and the step with delayed loops."""
        return (self.controlled, self.references, self.open_inputs, self.actuators,
                self.dt if self.loops.delayed else None, "loops")

    @property
    def input_size(self) -> int:
        """Entries of the step's input ``u``: one per port actuator of :attr:`actuators`."""
        return len(self.actuators)

    def plant_sweep(self) -> Any:
        """The spatial sweep with the port actuators :attr:`actuators` (:func:`loop_acceleration`)."""
        return loop_acceleration(self.model, self.controlled.ports, self.actuators)

    def restarted(self, state: np.ndarray, held: np.ndarray | None, t: float = 0.0) -> np.ndarray:
        """``state`` with ``a`` and ``v_dot`` solved again at its ``(q, v)``, time ``t`` [s] and the held inputs with
        the loops at the stored controller entries, and the newest ring sample's rates from that acceleration."""
        return restarted_loop_state(self, state, held, t, self.controller_size)


def restarted_loop_state(compiled: Any, state: np.ndarray, held: np.ndarray | None, t: float, entries: int
                         ) -> np.ndarray:
    """The generated state ``state`` of a spatial scheme with loops in its step (``compiled``: a
    :class:`CompiledSpatialScheme` with :class:`SchemeLoopTerms`) with ``a`` and ``v_dot`` solved again at its
    ``(q, v)``, time ``t`` [s] and the ``held`` input vector, the loops at their stored controller entries (the first
    ``entries`` after the status), and the newest ring sample's rates from that acceleration."""
    model = compiled.model
    nq, n, first = model.n_positions, model.n_velocities, compiled.status_index + len(STATUS)
    out = np.array(state, dtype=float)
    held = np.zeros(len(compiled.actuators)) if held is None else np.asarray(held, dtype=float)
    acceleration, out[first:first + entries] = compiled.restart_terms(
        out[:nq], out[nq:nq + n], held, validation.finite("t", t), out[first:first + entries])
    out[nq + n:nq + 2 * n] = out[nq + 2 * n:nq + 3 * n] = acceleration
    return out


def simulate_spatial_scheme_loops_generated(controlled: ControlledModel, t_final: float, dt: float | None, *,
                                            scheme: Scheme | str = "newmark", x0: Any = None, v0: Any = None,
                                            references: Mapping[str, Any] | None = None,
                                            inputs: Mapping[str, Any] | None = None, outputs: Sequence[str] = (),
                                            store_every: int = 1, divergence_bound: float | None = None,
                                            tolerance: float = 1e-10, max_iterations: int = 50,
                                            cache_dir: str | os.PathLike | None = None,
                                            compiled: CompiledSpatialSchemeLoops | None = None) -> SimulationResult:
    """A DT-TMM scheme of a controlled spatial model with its loops closed in generated C.

    The result is the one of :func:`ctmm.control.planar_time.simulate_closed_loop` with the same scheme (coordinates,
    velocities, ``outputs``, ``"<loop>.y"``, ``"<loop>.u"``; method ``"dt-tmm-generated/<scheme>"``, ``info`` with
    ``dt``, ``compile_time_s``, ``newton_iterations`` (the total) and ``loops``).

    Parameters
    ----------
    controlled : ControlledModel
        Spatial plant and loops (:class:`CompiledSpatialSchemeLoops`).
    t_final, dt : float
        End time and step [s].
    scheme : Scheme or str
    x0, v0 : optional
        Initial configuration and velocities (as :func:`ctmm.spatial.integrate.initial_state`).
    references, inputs : mapping, optional
        As in :class:`CompiledSpatialSchemeLoops` (with ``compiled``: its own; giving them too is refused).
    outputs : sequence of str
        Sensor names stored at every row.
    store_every, divergence_bound, tolerance, max_iterations, cache_dir
        As in :func:`ctmm.compiled_spatial_schemes.simulate_spatial_scheme_generated`.
    compiled : CompiledSpatialSchemeLoops, optional
        Of ``controlled`` with this scheme, ``store_every`` and step, to reuse (default: built now).

    Raises
    ------
    ModelError
        What the generated step refuses (named), bad arguments, no compiler.
    ConvergenceError, SimulationError
        As :func:`~ctmm.compiled_spatial_schemes.simulate_spatial_scheme_generated`, with the result stored before
        the failure (loop signals included) as ``partial_result``.
    """
    scheme = as_scheme(scheme)
    if dt is None:
        raise ModelError(f"dt is required with the DT-TMM scheme {scheme.name!r} (a fixed step [s], > 0), got None")
    n_steps = step_total(t_final, dt)
    dt = float(t_final) / n_steps
    store_every = check_store_every(validation.integer("store_every", store_every, minimum=1))
    if divergence_bound is not None:
        divergence_bound = validation.positive("divergence_bound", divergence_bound)
    model = controlled.plant if isinstance(controlled, ControlledModel) else None
    if compiled is None:
        compiled = CompiledSpatialSchemeLoops(controlled, scheme, references=references, inputs=inputs, dt=dt,
                                              store_every=store_every, tolerance=tolerance,
                                              max_iterations=max_iterations, cache_dir=cache_dir)
    elif not isinstance(compiled, CompiledSpatialSchemeLoops) or compiled.controlled is not controlled or \
            compiled.scheme != scheme or compiled.store_every != store_every or references or inputs:
        raise ModelError(f"compiled must be a CompiledSpatialSchemeLoops of this controlled model with scheme="
                         f"{scheme!r} and store_every={store_every!r} (its references and inputs are its own: leave "
                         f"references and inputs out), got {compiled!r}")
    for name in outputs:
        controlled.ports.check_sensor(name, "output (sensor)")
    warn_conditionally_stable(model, scheme)
    start = compiled.initial_state(initial_state(model, x0, v0))
    times, states, wall, total = generated_rows(compiled, start, dt, n_steps)
    nq, n, status = model.n_positions, model.n_velocities, compiled.status_index
    method = f"dt-tmm-generated/{scheme.name}"
    info = {"dt": dt, "method": method, "scheme": repr(scheme), "wall_time_s": wall,
            "compile_time_s": compiled.compile_time_s, "newton_iterations": total,
            "loops": {law.name: "real-time" if law.steps == 0 else "history" for law in compiled.loops.laws}}
    plant, signals_of = plant_of(model), compiled.loops.signals()

    def result(count: int) -> SimulationResult:
        t, block = times[:count], states[:count]
        signals, units = plant.signals(t, block[:, :nq], block[:, nq:nq + n], outputs)
        entries = compiled.signal_states(block[:, status + len(STATUS):], t)
        extra = add_loop_signals(controlled, compiled.loops, signals_of, np.hstack([block[:, :nq + n], entries]), t,
                                 signals, units)
        failed = {"failed": True} if count < len(times) else {}
        return signal_result(SignalSystem(model, units, list(controlled.loops)), t, signals, method,
                             {**info, **extra, **failed})

    return checked_spatial_result(compiled, times, states, dt, method, result, divergence_bound,
                                  compiled.held_inputs(None))
