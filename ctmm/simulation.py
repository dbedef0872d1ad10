"""The one simulation verb, :func:`ctmm.simulate`: every system is simulated with all it contains.

* A plain :class:`~ctmm.system.Chain` goes to the DT-TMM stepper (:func:`ctmm.timestep.simulate`)
  with a scheme, or to :func:`ctmm.chain_ode.simulate_chain_ode` with ``"rk4"`` or a ``solve_ivp``
  method (state equations from the explicit context of the one sweep, massless nodes condensed);
  a :class:`~ctmm.control.loops.ControlledChain`, or a chain with co-simulated ``controllers`` or
  loop ``references``, goes to the controlled stepper
  (:func:`ctmm.control.simulate.simulate_controlled`) with a scheme, or with ``"rk4"`` / a
  ``solve_ivp`` method to :func:`ctmm.control.planar_time.simulate_closed_loop` on its plant
  (:class:`ctmm.control.chain_plant.ChainPlant`), so that no loop is ever dropped.  Both
  share the pre-run stability check of the scheme (:mod:`ctmm.step_limit`) and the divergence
  guard (:mod:`ctmm.guard`).
* A :class:`~ctmm.planar.model.PlanarModel` (rigid or with flexible beams), or a controlled
  planar model (``plant`` + ``loops``, :func:`ctmm.control.with_feedback`), goes to
  :func:`ctmm.control.planar_time.simulate_closed_loop` when it has loops, controllers or
  open-loop ``inputs`` (``"rk4"``, the ``solve_ivp`` methods and every DT-TMM scheme, the last
  through the Newton-iterate input hook of :func:`ctmm.planar.implicit.simulate_implicit`), to
  the RK4 generated from the element definitions with ``compiled=True`` (:mod:`ctmm.compiled_scene`;
  ``fast=True`` is a deprecated alias), or else to :func:`~ctmm.planar.implicit.simulate_implicit`
  for a scheme.
* A :class:`~ctmm.spatial.model.SpatialModel` goes to :func:`ctmm.spatial.integrate.simulate_spatial`
  (``"rk4"`` or a ``solve_ivp`` method) or, with a DT-TMM scheme, to
  :func:`ctmm.spatial.implicit.simulate_spatial_implicit` (``docs/spatial.md``).

Every path returns one :class:`~ctmm.results.SimulationResult` (named signals with units).
"""
from __future__ import annotations

import contextlib
import math
import warnings
from typing import Any, Iterator, Mapping, Sequence

import numpy as np

from . import validation
from .capabilities import require_chain
from .control.loops import ControlledChain
from .control.planar_time import simulate_closed_loop
from .control.protocol import Controller, check_controllers, check_references, split_loop_references
from .control.simulate import simulate_controlled
from .compiled_default import default_refusal, is_size_refusal, note_size_refusal, run_default
from .errors import ConvergenceError, ModelError, SimulationError, unknown_name
from .guard import unstable_loops_hint
from .ode import refuse_adaptive_options
from .planar.closed_loops import KinematicLoopModel
from .planar.guards import check_resolution
from .planar.integrate import SCIPY_METHODS, PlanarSimulation, coordinate_values, initial_coordinates, to_result
from .planar.model import PlanarModel
from .results import SimulationResult
from .schemes import SCHEMES, Scheme, as_scheme
from .spatial.model import SpatialModel
from .spatial_simulation import simulate_spatial_system
from .system import Chain
from .timestep import ForceHook
from .timestep import simulate as simulate_chain

__all__ = ["simulate", "FIXED_STEP_METHODS"]

FIXED_STEP_METHODS = ("rk4",)
"""Explicit fixed-step methods of :func:`simulate` (planar models)."""


def _model_parts(system: Any, kind: type) -> tuple[Any, tuple] | None:
    """``(model, loops)`` of a model of type ``kind`` or a controlled one, else ``None``."""
    if isinstance(system, kind):
        return system, ()
    plant = getattr(system, "plant", None)
    if isinstance(plant, kind) and hasattr(system, "loops"):
        return plant, tuple(system.loops)
    return None


class _Default:
    """Marks ``method`` / ``scheme`` as not given (``None`` is refused like any other bad value)."""

    def __repr__(self) -> str:
        return "<default>"


_DEFAULT: Any = _Default()


def _method(method: Any, scheme: Any, default: str) -> Any:
    """The chosen method: ``method`` or its alias ``scheme`` (not both), else ``default``."""
    if method is not _DEFAULT and scheme is not _DEFAULT:
        raise ModelError(f"give method={method!r} or its alias scheme={scheme!r}, not both")
    chosen = method if method is not _DEFAULT else scheme
    if chosen is _DEFAULT:
        return default
    if not isinstance(chosen, (str, Scheme)):
        raise ModelError(f"method must be a method name (str) or a ctmm.schemes object, got {chosen!r}")
    return chosen


def simulate(system: Any, t_final: float, dt: float | None = None, *, method: Scheme | str = _DEFAULT,
             scheme: Scheme | str = _DEFAULT, x0: Mapping[str, float] | Any = None,
             v0: Mapping[str, float] | Any = None, t0: float = 0.0, inputs: Mapping[str, Any] | None = None,
             outputs: Sequence[str] = (), controllers: Sequence[Controller] = (),
             references: Mapping[str, Any] | None = None, coupling: str = "hold", solver: str = "riccati",
             fast: bool | None = None, force_hook: ForceHook | None = None, progress: bool | None = None,
             stability_check: str | None = None, divergence_bound: float | None = None,
             rtol: float = 1e-8, atol: float = 1e-10, max_step: float | None = None, store_every: int = 1,
             compiled: bool | None = None, parameters: Mapping[str, float] | None = None) -> SimulationResult:
    """Simulate a chain, a planar or flexible model, with or without loops, in the time domain.

    Parameters
    ----------
    system : Chain, ControlledChain, PlanarModel, controlled planar model or SpatialModel
        The model; every :class:`~ctmm.control.loops.Feedback` loop is closed during the run.
    t_final : float
        End time [s].
    dt : float, optional
        Step [s]: required by the DT-TMM schemes, ``"rk4"`` and co-simulated controllers (their
        sample grid); with a ``solve_ivp`` method the result is stored at the times ``k dt``
        (without it: at every accepted step).
    method : str or Scheme, optional
        ``"rk4"`` (fixed step; planar default), a ``scipy.integrate.solve_ivp`` method
        (``"RK45"``, ``"DOP853"``, ``"Radau"``, ``"BDF"``, ...; planar models and plain lumped chains,
        :mod:`ctmm.chain_ode`; a chain's loops, controllers and actuator ``inputs`` close in the one
        loop driver, :mod:`ctmm.control.chain_plant`) or a DT-TMM scheme
        (``"newmark"`` (chain default), ``"generalized_alpha"``, ``"wilson_theta"``, ``"houbolt"``,
        ``"forward_euler"`` or a :mod:`ctmm.schemes` object); on a planar model every scheme closes
        loops, ``inputs`` and ``controllers`` (``docs/planar.md``, ``docs/control.md`` §4c); on a
        spatial model the schemes run in Lie-group form, with loops and controllers too
        (``docs/spatial.md`` §6a).
    scheme : str or Scheme, optional
        Alias of ``method`` (giving both is an error).
    x0, v0 : mapping or array, optional
        Initial positions / velocities: chains by element name [m]; planar models by coordinate
        name (``{"upper.theta": -1.57}``, others 0) or an array ordered as ``model.coordinates``.
    t0 : float
        Start time [s] (chains; planar runs start at 0).
    inputs : mapping, optional
        Planar: ``{actuator name: number or f(t)}`` open-loop actuator values
        (:mod:`ctmm.planar.ports`, e.g. ``"motor.torque"`` [N m]); ``"<loop>.reference"`` is the
        loop's reference (as in ``references``).  Chains with ``"rk4"`` or a ``solve_ivp`` method:
        ``{"<element>.<input>" or "<element>": ...}`` forces [N] (:mod:`ctmm.control.chain_plant`).
    outputs : sequence of str
        Planar: sensor names stored at every time (``"fore.outboard.y"``); every coordinate and
        its rate are always stored.
    controllers : sequence of Controller
        Co-simulated controllers (Python objects, FMUs) reading sensors and writing actuators by
        name; a :class:`~ctmm.control.measurement_delay.DelayedController` reads its inputs late.
    references : mapping, optional
        ``{loop name: r(t)}`` loop references [sensed unit].
    coupling : {"hold", "previous"}
        Algebraic-loop policy of co-simulated controllers; ``"previous"`` without ``controllers``
        is refused (it would be ignored).
    solver, fast, force_hook
        Options of the uncontrolled chain stepper (:func:`ctmm.timestep.simulate`).  Planar:
        ``fast=True`` is a deprecated alias of ``compiled=True`` (``DeprecationWarning``; it ran a hand-typed C
        RK4 of revolute trees, removed: the generated RK4 gives the same numbers to round-off).
    compiled : bool, optional
        Planar, ``"rk4"``: ``True`` runs the RK4 time loop in C generated from the element definitions
        (:func:`ctmm.compiled_scene.simulate_rk4_generated`; planar scenes -- rigid trees, modal beams, hub-beam,
        hinge and load signals with a symbolic form; compiled once per structure and cached on disk; same numbers as
        the numpy path to round-off).  A controlled planar model's loops close inside the generated step
        (:func:`ctmm.compiled_control.simulate_controlled_generated`: real-time loops at every stage, LTI controller
        states integrated, delayed loops with ``delay = m dt`` from a ring of stored samples; references and inputs
        numbers or :mod:`ctmm.signals` signals with a symbolic form).  What it cannot compile (user callables of time,
        driven motions, translational hinge springs, delays that are not whole multiples of ``dt``, beam station
        forces or moments) raises :class:`ModelError` naming it.  Co-simulated ``controllers`` (planar, spatial,
        chains with ``"rk4"``) are sampled in Python between calls into the generated step, which runs each sample
        interval with their held outputs (:func:`ctmm.compiled_cosim.simulate_cosimulated_generated`).  Spatial,
        ``"rk4"``: ``True`` runs the generated RK4 of :func:`ctmm.compiled_spatial.simulate_spatial_generated`
        (inputs held numbers; the numpy path's result to round-off); with loops, or inputs that are
        :mod:`ctmm.signals` functions of time, :func:`ctmm.compiled_control.simulate_spatial_controlled_generated`
        (docs/spatial.md §6b; the DT-TMM schemes alike).  Planar, a DT-TMM
        scheme: the scheme's step with its Newton iterations in generated C
        (:func:`ctmm.compiled_scene_schemes.simulate_scheme_generated`), co-simulated controllers sampled between
        calls (:func:`ctmm.compiled_scheme_cosim.simulate_cosimulated_scheme_generated`), loops inside its Newton
        step (:func:`ctmm.compiled_scheme_loops.simulate_scheme_loops_generated`: real-time, LTI controller states,
        delayed loops, any delay; with controllers too, sampled between calls); spatial, a
        scheme: its Lie-group step in generated C
        (:func:`ctmm.compiled_spatial_schemes.simulate_spatial_scheme_generated`; loops inside its Newton step,
        :func:`ctmm.compiled_spatial_scheme_loops.simulate_spatial_scheme_loops_generated`; controllers as for planar
        models).
        ``False``: the numpy path always.  Default (``None``): the generated path where it pays and a C compiler
        is present -- RK4 of chains, planar and spatial models (with their loops, inputs and references) and the
        DT-TMM schemes of chains, of planar models up to 300 coordinates where the generated step iterates with the
        implicit sweep (linear hinge laws, no modal bodies, no loops), else up to 15 coordinates (30 with loops),
        and of spatial models up to 10 velocities (``ctmm.compiled_default.SCHEME_MAXIMUM_COORDINATES``, ...), for runs of at least
        ``ctmm.compiled_default.MINIMUM_STEPS`` (5000) steps and no co-simulated controllers -- falling back to
        numpy for what it refuses (the reason in ``result.info["compiled"]``); else numpy
        (:mod:`ctmm.compiled_default`).
    parameters : mapping, optional
        ``compiled=True``: ``{name: number}`` set at run time in the kernel compiled once (:mod:`ctmm.batch`).
    progress : bool, optional
        Show a progress bar (default: long runs on a terminal).
    stability_check : {"warn", "error", "ignore"}, optional
        Pre-run check of ``dt`` against the method's stability limit (plant only).
    divergence_bound : float, optional
        Largest allowed distance from the start, on every path (numpy, DT-TMM schemes, generated
        kernels, loops): chains: of a point from its rest position [m] (default ``1e6 * max(1,
        initial excursion)``); planar: of a coordinate from its initial value, its own unit (same
        default); spatial: of each entry of ``q`` and of ``v`` from its initial value, its own unit
        (default: none, finiteness only).
    rtol, atol, max_step : float
        ``solve_ivp`` tolerances and largest step [s] (planar models, chains).
    store_every : int
        Fixed-step ``"rk4"`` (planar models, chains): keep every ``store_every``-th step (the last
        always).

    Returns
    -------
    SimulationResult
        Named signals with units: chain point signals; planar ``"<coordinate>"``,
        ``"<coordinate>_dot"`` and the outputs; ``"<loop>.y"`` / ``"<loop>.u"`` and
        ``"<output>@samples"`` of controllers when the system is controlled.

    Raises
    ------
    ModelError
        Bad input; a system of another kind; options that do not apply to the run (e.g.
        ``inputs`` for a chain on a DT-TMM scheme); with a DT-TMM scheme on a planar model, a
        loop delay shorter than the step (Wilson-theta: ``theta dt``).
    SimulationError
        A failed run (divergence, non-finite state, failing user code), with ``partial_result``.
    """
    if parameters is not None:                  # a generated kernel's numbers at run time (ctmm.batch)
        from .batch import simulate_with_parameters
        return simulate_with_parameters(system, parameters, {**locals(), "method": _method(method, scheme, "rk4")})
    if compiled is None:                        # the default: generated code where it pays (ctmm.compiled_default)
        call = dict(locals())
        try:
            chosen = _method(method, scheme, "newmark" if isinstance(system, (Chain, ControlledChain)) else "rk4")
        except ModelError:
            chosen = None                       # refused below, as without the default
        if chosen is not None:
            refusal = default_refusal(system, chosen, t_final, t0, dt, controllers=controllers, fast=fast,
                                      force_hook=force_hook, solver=solver, options=call)
            if refusal is None:
                return run_default(lambda: simulate(**{**call, "compiled": True}),
                                   lambda: simulate(**{**call, "compiled": False}))
            if is_size_refusal(refusal):
                return note_size_refusal(simulate(**{**call, "compiled": False}), refusal)
    controllers = check_controllers(controllers)
    references = check_references(references)
    validation.step_budget(t_final, t0, dt)
    if coupling != "hold" and not controllers:
        raise ModelError(f"coupling={coupling!r} only applies to co-simulated controllers, but controllers is "
                         f"empty; leave coupling at 'hold' (embedded loops are always solved implicitly)")
    if isinstance(system, KinematicLoopModel) or isinstance(getattr(system, "plant", None), KinematicLoopModel):
        from .kinematic_loop_time import simulate_kinematic_loop_system     # cut joints: docs/closed_loops.md §3b-c

        if isinstance(inputs, Mapping):
            inputs, references = split_loop_references(getattr(system, "loops", ()), inputs, references)
        return simulate_kinematic_loop_system(
            system, t_final, dt, method=_method(method, scheme, "rk4"), x0=x0, v0=v0, outputs=outputs, inputs=inputs,
            controllers=list(controllers), references=dict(references), coupling=coupling, rtol=rtol, atol=atol,
            max_step=max_step, store_every=store_every, divergence_bound=divergence_bound,
            stability_check=stability_check, progress=progress,
            unsupported={"solver": (solver, "riccati"), "fast": (fast, None), "force_hook": (force_hook, None),
                         "t0": (t0, 0.0), "compiled": (compiled, None)})
    from .spatial.closed_loops import SpatialKinematicLoopModel

    if isinstance(system, SpatialKinematicLoopModel) or isinstance(getattr(system, "plant", None),
                                                                    SpatialKinematicLoopModel):   # closed_loops.md §8
        from .spatial_loop_time import simulate_spatial_loop_system

        if isinstance(inputs, Mapping):
            inputs, references = split_loop_references(getattr(system, "loops", ()), inputs, references)
        return simulate_spatial_loop_system(
            system, t_final, dt, method=_method(method, scheme, "rk4"), x0=x0, v0=v0, inputs=inputs, outputs=outputs,
            controllers=list(controllers), references=dict(references), coupling=coupling, rtol=rtol, atol=atol,
            max_step=max_step, store_every=store_every, progress=progress, stability_check=stability_check,
            divergence_bound=divergence_bound, unsupported={"solver": (solver, "riccati"), "fast": (fast, None),
                                                            "force_hook": (force_hook, None), "t0": (t0, 0.0),
                                                            "compiled": (compiled, None)})
    for kind, run in ((SpatialModel, simulate_spatial_system), (PlanarModel, _simulate_planar)):
        parts = _model_parts(system, kind)
        if parts is not None:
            with _loops_hint(parts[1]):
                return run(parts, t_final, dt, method=_method(method, scheme, "rk4"), x0=x0, v0=v0, t0=t0,
                           inputs=inputs, outputs=outputs, controllers=controllers, references=references,
                           coupling=coupling, solver=solver, fast=fast, force_hook=force_hook, progress=progress,
                           stability_check=stability_check, divergence_bound=divergence_bound, rtol=rtol, atol=atol,
                           max_step=max_step, store_every=store_every, compiled=compiled)
    require_chain(system, "ctmm.simulate")
    chosen = _method(method, scheme, "newmark")
    if validation.flag("compiled", compiled, optional=True):
        return _simulate_chain_generated(system, t_final, dt, method=chosen, x0=x0, v0=v0, t0=t0, inputs=inputs,
                                         outputs=outputs, controllers=controllers, references=references,
                                         store_every=store_every, divergence_bound=divergence_bound,
                                         coupling=coupling, progress=progress, stability_check=stability_check,
                                         others={"solver": (solver, "riccati"), "fast": (fast, None),
                                                 "force_hook": (force_hook, None), "rtol": (rtol, 1e-8),
                                                 "atol": (atol, 1e-10), "max_step": (max_step, None)})
    if isinstance(chosen, str) and chosen not in (*SCHEMES, *FIXED_STEP_METHODS, *SCIPY_METHODS):
        raise ModelError(f"unknown scheme {chosen!r}; available: {', '.join(sorted(SCHEMES))} or a ctmm.schemes "
                         f"object; the method of a chain may also be 'rk4' or a solve_ivp method {SCIPY_METHODS}")
    if isinstance(chosen, str) and (chosen in FIXED_STEP_METHODS or chosen in SCIPY_METHODS):
        return _simulate_chain_ode(system, t_final, dt, method=chosen, x0=x0, v0=v0, t0=t0, inputs=inputs,
                                   outputs=outputs, controllers=controllers, references=references, solver=solver,
                                   fast=fast, force_hook=force_hook, progress=progress,
                                   stability_check=stability_check, divergence_bound=divergence_bound, rtol=rtol,
                                   atol=atol, max_step=max_step, store_every=store_every, coupling=coupling)
    planar_only = {"inputs": (inputs, None), "outputs": (tuple(outputs), ()), "rtol": (rtol, 1e-8),
                   "atol": (atol, 1e-10), "max_step": (max_step, None), "store_every": (store_every, 1)}
    for name, (value, default) in planar_only.items():
        if value != default:
            elsewhere = {"inputs": "a chain's ODE methods ('rk4', solve_ivp) take inputs", "store_every":
                         "method='rk4' takes store_every", **{key: f"its solve_ivp methods take {key}"
                                                              for key in ("rtol", "atol", "max_step")}}
            raise ModelError(f"{name}={value!r} does not apply to the DT-TMM stepper of a chain (method={chosen!r}: it "
                             "stores every signal and takes loads and prescribed motions from its elements"
                             f"{'; ' + elsewhere[name] if name in elsewhere else ''}); leave {name} at {default!r}")
    if dt is None:
        raise ModelError("dt is required to simulate a chain (the DT-TMM step [s], > 0), got None")
    controlled = isinstance(system, ControlledChain) or bool(controllers) or bool(references)
    if not controlled:
        return simulate_chain(system, t_final, dt, scheme=chosen, x0=x0, v0=v0, t0=t0, solver=solver, fast=fast,
                              force_hook=force_hook, progress=progress, stability_check=stability_check,
                              divergence_bound=divergence_bound)
    unsupported = {"solver": (solver, "riccati"), "fast": (fast, None), "force_hook": (force_hook, None)}
    for name, (value, default) in unsupported.items():
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} applies to uncontrolled chains only; a controlled run uses the "
                             f"Riccati DT-TMM stepper (leave {name} at {default!r})")
    return simulate_controlled(system, t_final, dt, scheme=chosen, x0=x0, v0=v0, t0=t0, references=references,
                               controllers=controllers, coupling=coupling, progress=progress,
                               stability_check=stability_check, divergence_bound=divergence_bound)


def _simulate_chain_ode(system: Any, t_final: float, dt: float | None, *, method: str, x0: Any, v0: Any, t0: float,
                        inputs: Any, outputs: Sequence[str], controllers: list, references: dict, solver: str,
                        fast: Any, force_hook: Any, progress: Any, stability_check: Any,
                        divergence_bound: float | None, rtol: float, atol: float, max_step: float | None,
                        store_every: int, coupling: str = "hold") -> SimulationResult:
    """:func:`simulate` of a chain with ``"rk4"`` or a ``solve_ivp`` method: a plain chain by
    :mod:`ctmm.chain_ode`; a :class:`ControlledChain`, or a chain with ``controllers``, ``references``
    or actuator ``inputs``, by the one loop-closing driver (:func:`simulate_closed_loop` on a
    :class:`~ctmm.control.chain_plant.ChainPlant`)."""
    loops = system.loops if isinstance(system, ControlledChain) else ()
    refuse_adaptive_options(method, SCIPY_METHODS, rtol, atol, max_step)
    if inputs is not None and not isinstance(inputs, Mapping):
        raise ModelError(f"inputs must be a mapping {{actuator name: number or f(t)}}, got {inputs!r}")
    inputs, references = split_loop_references(loops, inputs, references)
    controlled = bool(loops) or bool(controllers) or bool(references) or bool(inputs)
    unsupported = {"solver": (solver, "riccati"), "fast": (fast, None), "force_hook": (force_hook, None)}
    if not controlled:
        unsupported.update({"outputs": (tuple(outputs), ()), "progress": (progress, None),
                            "stability_check": (stability_check, None)})
    for name, (value, default) in unsupported.items():
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} does not apply to an ODE run of a chain (method={method!r}: loads "
                             f"and prescribed motions come from its elements; every signal is stored); leave "
                             f"{name} at {default!r}")
    if not controlled:
        from .chain_ode import simulate_chain_ode

        return simulate_chain_ode(system, t_final, dt, method=method, x0=x0, v0=v0, t0=t0, rtol=rtol, atol=atol,
                                  max_step=max_step, store_every=store_every, divergence_bound=divergence_bound)
    if t0 != 0.0:
        raise ModelError(f"t0={t0!r}: a chain with loops, controllers or inputs on the ODE path starts at t = 0 "
                         "(leave t0 at 0, or use a DT-TMM scheme)")
    if isinstance(outputs, (str, Mapping)) or not isinstance(outputs, (list, tuple)) or \
            not all(isinstance(o, str) for o in outputs):
        raise ModelError(f"outputs must be a list or tuple of signal names (str), got {outputs!r}")
    for name in outputs:
        system.signal(name)
    from .control.chain_plant import ChainPlant

    plant = ChainPlant(system)
    q0, qdot0 = plant.start(x0, v0)
    policy = "warn" if stability_check is None else validation.option("stability_check", stability_check,
                                                                       ("warn", "error", "ignore"))
    return simulate_closed_loop(system, q0, qdot0, t_final, dt, method=method, loops=loops, controllers=controllers,
                                inputs=inputs, references=references, outputs=outputs, coupling=coupling,
                                rtol=rtol, atol=atol, max_step=math.inf if max_step is None else max_step,
                                store_every=store_every, progress=progress, stability_check=policy,
                                divergence_bound=divergence_bound)


def _simulate_chain_generated(system: Any, t_final: float, dt: float | None, *, method: Any, x0: Any, v0: Any,
                              t0: float, inputs: Any, outputs: Sequence[str], controllers: list, references: dict,
                              store_every: int, divergence_bound: float | None, others: dict, coupling: str = "hold",
                              progress: bool | None = None, stability_check: str | None = None) -> SimulationResult:
    """:func:`simulate` of a chain with ``compiled=True``: the generated RK4 (:mod:`ctmm.compiled_chain`; with
    ``controllers`` sampled between its calls, :mod:`ctmm.compiled_cosim`) or DT-TMM."""
    if method != "rk4" and (isinstance(method, Scheme) or method in SCHEMES):
        from .compiled_chain_scheme_runs import check_scheme_options, simulate_scheme_verb
        if controllers:                 # their held outputs: the input of the generated step (ctmm.compiled_cosim)
            from .compiled_cosim import simulate_cosimulated_scheme
            check_scheme_options(dt, {**others, "t0": (t0, 0.0), "inputs": (inputs or None, None)})
            return simulate_cosimulated_scheme(
                system, t_final, dt, method, controllers=controllers, x0=x0, v0=v0, references=references or None,
                outputs=tuple(outputs), coupling=coupling, store_every=store_every, progress=progress,
                stability_check=stability_check, divergence_bound=divergence_bound)
        return simulate_scheme_verb(system, t_final, dt, method, x0, v0, store_every, divergence_bound, others,
                                    t0=t0, inputs=inputs, outputs=outputs, references=references)
    if method != "rk4":
        raise ModelError(f"compiled=True runs the generated RK4 or DT-TMM of a chain, got method={method!r} "
                         "(leave compiled at None)")
    for name, (value, default) in {**others, "t0": (t0, 0.0)}.items():
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} does not apply to the generated RK4 of a chain (leave {name} at "
                             f"{default!r})")
    if dt is None:
        raise ModelError("dt is required with method='rk4' (a fixed step [s], > 0), got None")
    if inputs is not None and not isinstance(inputs, Mapping):
        raise ModelError(f"inputs must be a mapping {{actuator name: number or signal}}, got {inputs!r}")
    loops = system.loops if isinstance(system, ControlledChain) else ()
    inputs, references = split_loop_references(loops, inputs, references)
    for name in outputs:
        system.signal(name)
    if controllers:                     # C between the samples of the controllers (ctmm.compiled_cosim)
        from .compiled_cosim import simulate_cosimulated_generated
        from .control.chain_plant import ChainPlant

        q0, w0 = ChainPlant(system).start(x0, v0)
        return simulate_cosimulated_generated(
            system, loops, q0, w0, t_final=t_final, dt=dt, controllers=controllers, inputs=inputs,
            references=references, outputs=tuple(outputs), coupling=coupling, store_every=store_every,
            progress=validation.flag("progress", progress, optional=True), divergence_bound=divergence_bound,
            stability_check="warn" if stability_check is None else validation.option(
                "stability_check", stability_check, ("warn", "error", "ignore")))
    from .compiled_chain import simulate_chain_generated

    return simulate_chain_generated(system, t_final, dt, x0=x0, v0=v0, inputs=inputs or None,
                                    references=references or None, outputs=tuple(outputs), store_every=store_every,
                                    divergence_bound=divergence_bound)


@contextlib.contextmanager
def _loops_hint(loops: Sequence[Any]) -> Iterator[None]:
    """A DT-TMM step of a planar or spatial model with feedback ``loops`` that does not converge: its message also
    says which loops may be unstable (:func:`ctmm.guard.unstable_loops_hint`, as a diverging run with loops says):
    a Newton iteration that fails as the state grows fast is more often a closed loop's instability than a step too
    long."""
    try:
        yield
    except ConvergenceError as exc:
        names = [str(getattr(loop, "name", loop)) for loop in loops]
        if names and exc.args and "may be unstable" not in str(exc.args[0]):
            exc.args = (f"{exc.args[0]}, or {unstable_loops_hint(names)}",) + exc.args[1:]
        raise


@contextlib.contextmanager
def _partial_as_result(outputs: Sequence[str], dt: float) -> Iterator[None]:
    """Turn the partial :class:`PlanarSimulation` of a failed legacy planar run into a
    :class:`SimulationResult` (``ctmm.simulate`` returns one kind of result, also on failure)."""
    try:
        yield
    except SimulationError as exc:
        if isinstance(exc.partial_result, PlanarSimulation):
            exc.partial_result = to_result(exc.partial_result, outputs=outputs, info={"dt": dt, "failed": True})
        raise


def _simulate_planar(parts: tuple[PlanarModel, tuple], t_final: float, dt: float | None, *, method: Any,
                     x0: Any, v0: Any, t0: float, inputs: Mapping[str, Any] | None, outputs: Sequence[str],
                     controllers: list, references: dict, coupling: str, solver: str, fast: bool | None,
                     force_hook: Any, progress: bool | None, stability_check: str | None,
                     divergence_bound: float | None, rtol: float, atol: float, max_step: float | None,
                     store_every: int, compiled: bool | None = None) -> SimulationResult:
    """:func:`simulate` of a planar model or a controlled planar model (dispatch on ``method``)."""
    model, loops = parts
    if model.n_coordinates == 0:
        raise ModelError(f"model {model.name!r} has no coordinates (every body is welded or driven): there is "
                         "nothing to integrate; its prescribed motion is model.points(q=[], qdot=[], t)")
    for name, value, default in (("solver", solver, "riccati"), ("force_hook", force_hook, None), ("t0", t0, 0.0)):
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} applies to 1-D chains only; a planar run starts at t = 0 and "
                             f"takes loads from its elements and inputs (leave {name} at {default!r})")
    if isinstance(outputs, (str, Mapping)) or not isinstance(outputs, (list, tuple)) or \
            not all(isinstance(o, str) for o in outputs):
        raise ModelError(f"outputs must be a list or tuple of sensor names (str), got {outputs!r}")
    from .planar.ports import sensor_names

    known = set(sensor_names(model))
    for name in outputs:
        if name not in known:
            raise unknown_name("output (sensor)", name, sorted(known))
    if inputs is not None and not isinstance(inputs, Mapping):
        raise ModelError(f"inputs must be a mapping {{actuator name: number or f(t)}}, got {inputs!r}")
    inputs, references = split_loop_references(loops, inputs, references)
    fast = validation.flag("fast", fast, optional=True)
    compiled = validation.flag("compiled", compiled, optional=True)
    if fast and compiled is False:
        raise ModelError("fast=True (a deprecated alias of compiled=True) contradicts compiled=False; give compiled")
    if fast:
        warnings.warn("ctmm.simulate(planar model, fast=True) is deprecated: it runs the generated RK4 of "
                      "compiled=True (the hand-typed C it ran is removed); give compiled=True", DeprecationWarning,
                      stacklevel=3)
        compiled = True
    progress = validation.flag("progress", progress, optional=True)
    q0, v0 = initial_coordinates(model, coordinate_values(model, "x0", x0), coordinate_values(model, "v0", v0))
    check_resolution(model, q0, "x0")
    policy = "warn" if stability_check is None else validation.option("stability_check", stability_check,
                                                                       ("warn", "error", "ignore"))
    store_every = validation.integer("store_every", store_every, minimum=1)
    if max_step is not None and not (isinstance(max_step, (int, float)) and max_step == math.inf):
        max_step = validation.positive("max_step", max_step)        # inf (no limit) is solve_ivp's default
    controlled = bool(loops) or bool(controllers) or bool(inputs) or bool(references)
    is_scheme = isinstance(method, Scheme) or (isinstance(method, str) and method in SCHEMES)
    others = bool(loops) or bool(references)        # a generated scheme: loops in its Newton step
    if compiled and method != "rk4" and not is_scheme:
        raise ModelError(f"compiled=True runs the generated RK4 of a planar model with its loops, inputs, references "
                         f"and controllers, or a generated DT-TMM scheme with them; got method={method!r} "
                         "(leave compiled at None)")
    refuse_adaptive_options(method, SCIPY_METHODS, rtol, atol, max_step)
    if store_every != 1 and method in SCIPY_METHODS:
        raise ModelError(f"store_every={store_every!r} applies to fixed-step methods; with {method!r} give dt "
                         "to store the result on the grid k dt (leave store_every at 1)")
    if is_scheme and not controlled:       # (compiled, with inputs or controllers: ctmm.compiled_scheme_cosim below)
        if dt is None:
            raise ModelError(f"dt is required with the DT-TMM scheme {method!r} (a fixed step [s], > 0), got None")
        from .planar.implicit import simulate_implicit as stepper

        if compiled:                                # Newton and the time loop in generated C
            from .compiled_scene_schemes import simulate_scheme_generated as stepper
        with _partial_as_result(outputs, dt):
            simulation = stepper(model, q0, v0, t_final=t_final, dt=dt, scheme=as_scheme(method),
                                           store_every=store_every, divergence_bound=divergence_bound,
                                           stability_check=policy)
        return to_result(simulation, outputs=outputs, info={"dt": dt})
    if not is_scheme and method not in FIXED_STEP_METHODS and method not in SCIPY_METHODS:
        raise ModelError(f"method must be 'rk4', a solve_ivp method {SCIPY_METHODS} or a DT-TMM scheme "
                         f"{tuple(sorted(SCHEMES))} (or a ctmm.schemes object), got {method!r}")
    if compiled and is_scheme:              # controllers sampled between calls into the generated scheme, inputs held
        from .compiled_scheme_cosim import simulate_cosimulated_scheme_generated

        if dt is None:
            raise ModelError(f"dt is required with the DT-TMM scheme {method!r} (a fixed step [s], > 0), got None")
        if others and not controllers:      # loops inside the generated Newton step
            from .compiled_scheme_loops import simulate_scheme_loops_generated
            from .control.controlled_model import ControlledModel

            return simulate_scheme_loops_generated(
                ControlledModel(model, loops), q0, v0, t_final=t_final, dt=dt, scheme=as_scheme(method),
                references=references, inputs=inputs, outputs=outputs, store_every=store_every,
                divergence_bound=divergence_bound, stability_check=policy)
        return simulate_cosimulated_scheme_generated(
            model, q0, v0, t_final=t_final, dt=dt, scheme=method, controllers=controllers, inputs=inputs,
            outputs=outputs, coupling=coupling, store_every=store_every, progress=progress, stability_check=policy,
            divergence_bound=divergence_bound, loops=loops, references=references)
    if compiled:
        if dt is None:
            raise ModelError("dt is required with method='rk4' (a fixed step [s], > 0), got None")
        if controllers:                     # C between the samples of the controllers (ctmm.compiled_cosim)
            from .compiled_cosim import simulate_cosimulated_generated

            return simulate_cosimulated_generated(
                model, loops, q0, v0, t_final=t_final, dt=dt, controllers=controllers, inputs=inputs,
                references=references, outputs=outputs, coupling=coupling, store_every=store_every,
                progress=progress, stability_check=policy, divergence_bound=divergence_bound)
        if controlled:
            from .compiled_control import simulate_controlled_generated
            from .control.controlled_model import ControlledModel

            return simulate_controlled_generated(ControlledModel(model, loops), q0, v0, t_final=t_final, dt=dt,
                                                 inputs=inputs, references=references, outputs=outputs,
                                                 store_every=store_every, divergence_bound=divergence_bound,
                                                 stability_check=policy)
        from .compiled_scene import simulate_rk4_generated

        with _partial_as_result(outputs, dt):
            simulation = simulate_rk4_generated(model, q0, v0, t_final=t_final, dt=dt, store_every=store_every,
                                                divergence_bound=divergence_bound, stability_check=policy)
        return to_result(simulation, outputs=outputs, info={"dt": dt})
    return simulate_closed_loop(model, q0, v0, t_final, dt, method=method, loops=loops, controllers=controllers,
                                inputs=inputs, references=references, outputs=outputs, coupling=coupling,
                                rtol=rtol, atol=atol, max_step=math.inf if max_step is None else max_step,
                                store_every=store_every, progress=progress, stability_check=policy,
                                divergence_bound=divergence_bound)
