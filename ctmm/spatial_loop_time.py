""":func:`ctmm.simulate` of a spatial kinematic loop model (``ctmm.spatial.SpatialKinematicLoopModel``), alone or with
feedback loops, port actuator inputs, references, sensor outputs or controllers (``docs/closed_loops.md`` §8.3, §8.6).

Alone (joint actuator inputs at most) it runs its own integrators
(:func:`ctmm.spatial.closed_loop_time.simulate_spatial_loops`: RK4 with projection, ``solve_ivp`` with Baumgarte) or
a DT-TMM scheme on the tree with the cut loads as iterate inputs, projected after every step (:func:`_scheme_run`);
otherwise the one loop-closing driver (:func:`ctmm.control.planar_time.simulate_closed_loop`) on its plant
(:class:`~ctmm.spatial.closed_loop_plant.SpatialLoopPlant`).  Top level (not in ``ctmm.spatial``): it reaches into
``ctmm.control``, which imports ``ctmm.spatial``.
"""
from __future__ import annotations

import contextlib
from typing import Any, Iterator, Mapping, Sequence

import numpy as np

from . import validation
from .control.planar_time import simulate_closed_loop
from .errors import ModelError, SimulationError
from .loop_integration import check_consistent
from .results import SimulationResult
from .schemes import SCHEMES, Scheme
from .signal_results import SignalSystem, signal_result
from .spatial.closed_loop_plant import add_cut_signals
from .spatial.closed_loop_time import SpatialLoopSimulation, simulate_spatial_loop_scheme, simulate_spatial_loops
from .spatial.closed_loops import SpatialKinematicLoopModel
from .spatial.integrate import SCIPY_METHODS, spatial_signals

__all__ = ["simulate_spatial_loop_system"]


def simulate_spatial_loop_system(system: Any, t_final: float, dt: float | None, *, method: Any, x0: Any, v0: Any,
                                 inputs: Any, outputs: Sequence[str], controllers: list, references: dict,
                                 coupling: str, rtol: float, atol: float, max_step: float | None, store_every: int,
                                 progress: bool | None, stability_check: str | None, divergence_bound: float | None,
                                 unsupported: Mapping[str, tuple[Any, Any]]) -> SimulationResult:
    """:func:`ctmm.simulate` of a spatial kinematic loop model, alone or with feedback loops.

    Alone, with joint actuator ``inputs`` only: RK4 with projection (default), a ``solve_ivp`` method
    (:func:`simulate_spatial_loops`) or a DT-TMM scheme (:func:`_scheme_run`).  With feedback loops (``ctmm.control.with_feedback(loop_model, loops)``), port
    actuator inputs, ``references``, sensor ``outputs`` or ``controllers``: the one loop-closing driver
    (:func:`ctmm.control.planar_time.simulate_closed_loop`) on :class:`~ctmm.spatial.closed_loop_plant.SpatialLoopPlant`
    (``"rk4"`` projected after every step, ``solve_ivp`` at every controller sample).  ``compiled=True`` with ``"rk4"``: the model alone
    runs the generated RK4 with projection (:mod:`ctmm.compiled_spatial_kinematic_loops`), the driver's run is
    generated C (:mod:`ctmm.compiled_kinematic_loop_control`); with a DT-TMM scheme the model alone (held joint
    inputs) runs :mod:`ctmm.compiled_spatial_loop_schemes`, with loops, references, outputs or port inputs
    :mod:`ctmm.compiled_spatial_loop_scheme_control`.

    The result holds the tree's signals (:func:`ctmm.spatial.integrate.spatial_signals`: coordinates, velocities,
    body positions and angular velocities), ``"<cut>.force_x|y|z"`` [N] and, for revolute and universal cuts,
    ``"<cut>.moment_x|y|z"`` [N m] (on the child, world axes), ``"drift"`` and ``"drift_rate"``, with loops
    ``"<loop>.y"``, ``"<loop>.u"``.

    Raises
    ------
    ModelError
        A DT-TMM scheme or another option that does not apply (``unsupported``: ``{option: (value, default)}``,
        refused by name unless at the default), an inconsistent initial state.
    """
    model = system if isinstance(system, SpatialKinematicLoopModel) else system.plant
    loops = () if system is model else tuple(system.loops)
    unsupported = dict(unsupported)
    compiled = validation.flag("compiled", unsupported.pop("compiled", (None, None))[0], optional=True)
    through_driver = bool(loops or controllers or references or tuple(outputs)) or (isinstance(inputs, Mapping) and any(
        name not in model.tree.inputs for name in inputs))
    generated_scheme = compiled and (isinstance(method, Scheme) or (isinstance(method, str) and method in SCHEMES))
    if compiled and ((method != "rk4" and not generated_scheme) or (inputs and not through_driver
                                                                     and not generated_scheme)):
        raise ModelError(f"compiled=True runs the generated RK4 of the spatial kinematic loop model {model.name!r} "
                         f"(method='rk4'): alone with projection, or with loops, controllers, references, outputs or "
                         f"port inputs as the loop driver (ctmm.compiled_kinematic_loop_control); also a DT-TMM "
                         f"scheme, alone with held joint inputs (ctmm.compiled_spatial_loop_schemes) or with loops, "
                         f"references, outputs, port inputs (ctmm.compiled_spatial_loop_scheme_control) or "
                         f"co-simulated controllers (ctmm.compiled_scheme_cosim); not the RK4 with joint inputs alone; "
                         f"got method={method!r}, inputs={inputs!r:.60}; leave compiled at None")
    for name, (value, default) in unsupported.items():
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} is not available for the spatial kinematic loop model {model.name!r} "
                             f"(RK4 or solve_ivp on the closed-loop accelerations, from t = 0); leave {name} at "
                             f"{default!r}")
    scheme = isinstance(method, Scheme) or (isinstance(method, str) and method in SCHEMES)
    if not scheme and (not isinstance(method, str) or method not in ("rk4",) + SCIPY_METHODS):
        raise ModelError(f"method={method!r} is not available for the spatial kinematic loop model {model.name!r}: "
                         f"use 'rk4', a solve_ivp method {SCIPY_METHODS} or a DT-TMM scheme {tuple(SCHEMES)}")
    if inputs is not None and not isinstance(inputs, Mapping):
        raise ModelError(f"inputs must be a mapping {{actuator name: number or f(t)}}, got {inputs!r:.80}")
    port_inputs = any(name not in model.tree.inputs for name in inputs or {})
    q0, v0 = model.state(x0, v0)
    driver = bool(loops or controllers or references or tuple(outputs) or port_inputs)
    if driver or scheme:
        check_consistent(model, q0, v0, "x0, v0")
    if scheme and not driver:
        return _scheme_run(model, t_final, dt, method, q0, v0, inputs, store_every, divergence_bound, compiled)
    if driver:
        if isinstance(outputs, (str, Mapping)) or not isinstance(outputs, (list, tuple)):
            raise ModelError(f"outputs must be a list or tuple of sensor names (str), got {outputs!r}")
        policy = "warn" if stability_check is None else validation.option("stability_check", stability_check,
                                                                           ("warn", "error", "ignore"))
        if compiled and scheme and controllers:     # generated scheme steps between the controllers' samples
            from .compiled_scheme_cosim import simulate_cosimulated_scheme_generated

            return simulate_cosimulated_scheme_generated(
                model, q0, v0, t_final=t_final, dt=validation.positive("dt", dt), scheme=method,
                controllers=controllers, inputs=dict(inputs or {}), outputs=tuple(outputs), loops=loops,
                references=references, coupling=coupling, store_every=store_every, progress=progress,
                stability_check=policy, divergence_bound=divergence_bound)
        if compiled and scheme:     # the DT-TMM scheme with the loops in the generated Newton step
            return _scheme_loops_run(system, model, t_final, dt, method, q0, v0, inputs, references, outputs,
                                     store_every, divergence_bound, progress, max_step)
        if compiled:                # the driver's run in generated C (ctmm.compiled_kinematic_loop_control)
            from .compiled_kinematic_loop_control import simulate_generated_driver_run

            return simulate_generated_driver_run(
                system, q0, v0, t_final=t_final, dt=dt, controllers=controllers, inputs=inputs,
                references=references, outputs=outputs, coupling=coupling, store_every=store_every,
                progress=progress, stability_check=policy, divergence_bound=divergence_bound, max_step=max_step)
        return simulate_closed_loop(model, q0, v0, t_final, dt, method=method, loops=loops, controllers=controllers,
                                    inputs=dict(inputs or {}), references=references, outputs=tuple(outputs),
                                    coupling=coupling, rtol=rtol, atol=atol,
                                    max_step=np.inf if max_step is None else validation.positive("max_step", max_step),
                                    store_every=store_every, progress=progress, stability_check=policy,
                                    divergence_bound=divergence_bound)
    for name, value, default in (("coupling", coupling, "hold"), ("progress", progress, None),
                                 ("stability_check", stability_check, None),
                                 ("divergence_bound", divergence_bound, None)):
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} applies to runs with loops, controllers or port inputs; the spatial "
                             f"kinematic loop model {model.name!r} alone runs its own integrator: leave {name} at "
                             f"{default!r}")
    details = {"projection": method == "rk4", **({"compiled": True} if compiled else {})}
    if compiled:                # the generated RK4 with projection (ctmm.compiled_spatial_kinematic_loops)
        from .compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated

        for name, value, default in (("rtol", rtol, 1e-8), ("atol", atol, 1e-10), ("max_step", max_step, None)):
            if value != default:
                raise ModelError(f"{name}={value!r} applies to solve_ivp methods, not to compiled=True (RK4)")
        with _partial_as_result(model, details):
            run = simulate_spatial_kinematic_loops_generated(model, q0, v0, t_final=t_final,
                                                             dt=validation.positive("dt", dt), store_every=store_every)
    else:
        with _partial_as_result(model, details, method):
            run = simulate_spatial_loops(model, q0, v0, t_final=t_final, dt=dt, method=method, inputs=inputs,
                                         rtol=rtol, atol=atol, store_every=store_every, max_step=max_step)
    info = {"wall_time_s": run.wall_time_s, "n_evaluations": run.n_evaluations, **details}
    return _loop_result(model, run, info, None if compiled else method)


def _loop_result(model: SpatialKinematicLoopModel, run: SpatialLoopSimulation, info: dict,
                 method: str | None = None) -> SimulationResult:
    """A loop run as the result of :func:`ctmm.simulate`: the tree's signals, the cut loads, ``"drift"`` and
    ``"drift_rate"``; ``info`` with ``"max_drift"`` and ``"baumgarte"`` added; ``method``: the label (default the
    run's)."""
    signals, units = spatial_signals(model.tree, run.t, np.concatenate([run.q, run.v], axis=1))
    add_cut_signals(model, signals, units, run.cut_force, run.cut_moment, run.drift, run.drift_rate)
    info = {**info, "max_drift": float(run.drift.max(initial=0.0)), "baumgarte": model.baumgarte}
    return signal_result(SignalSystem(model, units), run.t, signals, run.method if method is None else method, info)


@contextlib.contextmanager
def _partial_as_result(model: SpatialKinematicLoopModel, info: dict, method: str | None = None) -> Iterator[None]:
    """Turn the partial :class:`SpatialLoopSimulation` of a failed run into the :class:`SimulationResult` a whole run
    returns (:func:`_loop_result`: the same signals, cut loads and drift included; ``info["failed"]``)."""
    try:
        yield
    except SimulationError as exc:
        if isinstance(exc.partial_result, SpatialLoopSimulation):
            exc.partial_result = _loop_result(model, exc.partial_result, {**info, "failed": True}, method)
        raise


def _scheme_run(model: SpatialKinematicLoopModel, t_final: float, dt: float | None, scheme: Any, q0: np.ndarray,
                v0: np.ndarray, inputs: Mapping[str, Any] | None, store_every: int,
                divergence_bound: float | None, compiled: bool | None = None) -> SimulationResult:
    """A DT-TMM scheme on the spanning tree with the cut loads as iterate inputs, projected onto the cut joints after
    every step (:func:`ctmm.spatial.closed_loop_time.simulate_spatial_loop_scheme`; ``compiled``: in generated C,
    :func:`ctmm.compiled_spatial_loop_schemes.simulate_spatial_loop_scheme_generated`), as a result with the tree's
    signals, the cut loads and the drift."""
    details = {"dt": dt, **({"compiled": True} if compiled else {})}
    if compiled:
        from .compiled_spatial_loop_schemes import simulate_spatial_loop_scheme_generated

        with _partial_as_result(model, details):
            run, info = simulate_spatial_loop_scheme_generated(model, q0, v0, t_final=t_final,
                                                               dt=validation.positive("dt", dt), scheme=scheme,
                                                               inputs=inputs, store_every=store_every,
                                                               divergence_bound=divergence_bound)
        info["compiled"] = True
    else:
        with _partial_as_result(model, details):
            run, info = simulate_spatial_loop_scheme(model, q0, v0, t_final=t_final, dt=validation.positive("dt", dt),
                                                     scheme=scheme, inputs=inputs, store_every=store_every,
                                                     divergence_bound=divergence_bound)
    return _loop_result(model, run, info)


def _scheme_loops_run(system: Any, model: SpatialKinematicLoopModel, t_final: float, dt: float | None, scheme: Any,
                      q0: np.ndarray, v0: np.ndarray, inputs: Mapping[str, Any] | None, references: dict,
                      outputs: Sequence[str], store_every: int, divergence_bound: float | None,
                      progress: bool | None, max_step: float | None) -> SimulationResult:
    """``compiled=True`` with a DT-TMM scheme and loops, references, outputs or port inputs:
    :func:`ctmm.compiled_spatial_loop_scheme_control.simulate_spatial_loop_scheme_control_generated` (``progress``
    and ``max_step`` refused by name)."""
    from .compiled_spatial_loop_scheme_control import simulate_spatial_loop_scheme_control_generated
    from .control.controlled_model import ControlledModel

    for name, value in (("progress", progress), ("max_step", max_step)):
        if value is not None:
            raise ModelError(f"{name}={value!r} is not available with compiled=True and a DT-TMM scheme on the spatial "
                             f"kinematic loop model {model.name!r} with loops; leave it at None")
    controlled = system if isinstance(system, ControlledModel) else ControlledModel(model, [])
    return simulate_spatial_loop_scheme_control_generated(
        controlled, q0, v0, t_final=t_final, dt=validation.positive("dt", dt), scheme=scheme, references=references,
        inputs=dict(inputs or {}), outputs=tuple(outputs), store_every=store_every, divergence_bound=divergence_bound)
