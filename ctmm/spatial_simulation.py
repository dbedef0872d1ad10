"""The spatial branch of :func:`ctmm.simulate`: a :class:`~ctmm.spatial.model.SpatialModel`, plain or controlled,
by RK4, ``solve_ivp``, a DT-TMM scheme, the generated RK4 or a generated DT-TMM scheme, with co-simulated controllers
between calls into it (``docs/spatial.md`` §6, §6a, §6b)."""
from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

from . import validation
from .control.planar_time import simulate_closed_loop
from .control.protocol import split_loop_references
from .errors import ModelError, unknown_name
from .ode import refuse_adaptive_options
from .results import SimulationResult
from .schemes import SCHEMES, Scheme
from .spatial.implicit import simulate_spatial_implicit
from .spatial.integrate import SCIPY_METHODS, initial_state, simulate_spatial
from .spatial.model import SpatialModel
from .spatial.ports import SpatialPorts

__all__ = ["simulate_spatial_system"]


def simulate_spatial_system(parts: tuple[SpatialModel, tuple], t_final: float, dt: float | None, *, method: Any,
                            x0: Any, v0: Any, t0: float, inputs: Any, outputs: Sequence[str], controllers: list,
                            references: dict, coupling: str, solver: str, fast: Any, force_hook: Any, progress: Any,
                            stability_check: Any, divergence_bound: float | None, rtol: float, atol: float,
                            max_step: float | None, store_every: int, compiled: Any) -> SimulationResult:
    """:func:`simulate` of a :class:`~ctmm.spatial.model.SpatialModel` or a controlled one (RK4, ``solve_ivp`` or a
    DT-TMM scheme; ``docs/spatial.md`` §6, §6a, §6b): loops, controllers, references, outputs or port actuator
    inputs go to the one loop-closing driver :func:`~ctmm.control.planar_time.simulate_closed_loop`.

    Parameters are those of :func:`ctmm.simulate` (already checked there: ``controllers``, ``references``, the
    step budget); ``parts`` is ``(model, loops)``.
    """
    model, loops = parts
    unsupported = {"solver": (solver, "riccati"), "fast": (fast, None), "force_hook": (force_hook, None),
                   "t0": (t0, 0.0)}
    for name, (value, default) in unsupported.items():
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} is not available for spatial models yet (runs start at t = 0); "
                             f"leave {name} at {default!r}")
    if isinstance(method, str) and method == "rk4":      # the schemes' refusals below name the scheme
        refuse_adaptive_options(method, SCIPY_METHODS, rtol, atol, max_step)
    if inputs is not None and not isinstance(inputs, Mapping):
        raise ModelError(f"inputs must be a mapping {{actuator name: number or f(t)}}, got {inputs!r}")
    port_inputs = any(name not in model.inputs for name in inputs or {})
    controlled = bool(loops or controllers or references or tuple(outputs) or port_inputs)
    if validation.flag("compiled", compiled, optional=True):        # the generated RK4 (ctmm.compiled_spatial)
        if port_inputs and not (loops or controllers or references or tuple(outputs)):
            known = SpatialPorts(model).actuators
            for name in inputs:
                if name not in model.inputs and name not in known:
                    raise unknown_name("spatial input", name, list(model.inputs) + list(known))
        cosimulated = bool(controllers)         # between calls into the generated scheme, ctmm.compiled_scheme_cosim
        # inputs that are functions of time (ctmm.signals with a symbolic form) on port actuators are stated on the
        # time symbol of the step with loops (none here); the plain generated step holds numbers (and refuses a
        # function of time on a joint's vector input by name)
        timed = [name for name, value in (inputs or {}).items() if callable(value)]
        controlled = controlled or bool(timed) and all(name in SpatialPorts(model).actuators for name in timed)
        if (isinstance(method, Scheme) or method in SCHEMES) and controlled and not controllers:
            from .compiled_spatial_scheme_loops import simulate_spatial_scheme_loops_generated  # loops in Newton
            from .control.controlled_model import ControlledModel

            for name, (value, default) in {"rtol": (rtol, 1e-8), "atol": (atol, 1e-10), "max_step": (max_step, None),
                                           "progress": (progress, None),
                                           "stability_check": (stability_check, None)}.items():
                if value is not default and value != default:
                    raise ModelError(f"{name}={value!r} does not apply to the generated DT-TMM scheme {method!r} of a "
                                     f"spatial model with loops; leave {name} at {default!r}")
            inputs, references = split_loop_references(loops, inputs, references)
            return simulate_spatial_scheme_loops_generated(
                ControlledModel(model, loops), t_final, dt, scheme=method, x0=x0, v0=v0, references=references,
                inputs=inputs, outputs=tuple(outputs), store_every=store_every, divergence_bound=divergence_bound)
        if (isinstance(method, Scheme) or method in SCHEMES) and (not controlled or cosimulated):
            from .compiled_scheme_cosim import simulate_cosimulated_scheme_generated
            from .compiled_spatial_schemes import simulate_spatial_scheme_generated

            options = {"rtol": (rtol, 1e-8), "atol": (atol, 1e-10), "max_step": (max_step, None)}
            if not cosimulated:
                options.update({"progress": (progress, None), "stability_check": (stability_check, None)})
            for name, (value, default) in options.items():
                if value is not default and value != default:
                    raise ModelError(f"{name}={value!r} does not apply to the generated DT-TMM scheme {method!r} of a "
                                     f"spatial model; leave {name} at {default!r}")
            if not cosimulated:
                return simulate_spatial_scheme_generated(model, t_final, dt, scheme=method, x0=x0, v0=v0,
                                                         inputs=inputs, store_every=store_every,
                                                         divergence_bound=divergence_bound)
            if dt is None:
                raise ModelError(f"dt is required with the DT-TMM scheme {method!r} (a fixed step [s], > 0), got None")
            state = initial_state(model, x0, v0)
            inputs, references = split_loop_references(loops, inputs, references)
            return simulate_cosimulated_scheme_generated(
                model, state[:model.n_positions], state[model.n_positions:], t_final=t_final, dt=dt, scheme=method,
                controllers=controllers, inputs=inputs, outputs=tuple(outputs), coupling=coupling, loops=loops,
                references=references,
                store_every=validation.integer("store_every", store_every, minimum=1),
                progress=validation.flag("progress", progress, optional=True), divergence_bound=divergence_bound)
        if not isinstance(method, str) or method != "rk4":
            raise ModelError(f"compiled=True runs the generated RK4 of a spatial model or a generated DT-TMM scheme "
                             f"({', '.join(map(repr, SCHEMES))}), with its loops, inputs, references and controllers; "
                             f"got method={method!r} (leave compiled at None for the solve_ivp methods)")
        if controllers:                 # C between the samples of the controllers (ctmm.compiled_cosim)
            from .compiled_cosim import simulate_cosimulated_generated

            for name in outputs:
                SpatialPorts(model).check_sensor(name, "output (sensor)")
            inputs, references = split_loop_references(loops, inputs, references)
            state = initial_state(model, x0, v0)
            policy = "warn" if stability_check is None else validation.option("stability_check", stability_check,
                                                                               ("warn", "error", "ignore"))
            return simulate_cosimulated_generated(
                model, loops, state[:model.n_positions], state[model.n_positions:], t_final=t_final, dt=dt,
                controllers=controllers, inputs=inputs, references=references, outputs=tuple(outputs),
                coupling=coupling, store_every=validation.integer("store_every", store_every, minimum=1),
                progress=validation.flag("progress", progress, optional=True), stability_check=policy,
                divergence_bound=divergence_bound)
        for name, (value, default) in {"progress": (progress, None), "stability_check": (stability_check, None)}.items():
            if value is not default and value != default:
                raise ModelError(f"{name}={value!r} is not available with compiled=True for spatial models (the whole "
                                 f"run is one call into C); leave {name} at {default!r}")
        if controlled:                  # loops closed in the generated step (ctmm.compiled_spatial_loops)
            from .compiled_control import simulate_spatial_controlled_generated
            from .control.controlled_model import ControlledModel

            for name in outputs:
                SpatialPorts(model).check_sensor(name, "output (sensor)")
            inputs, references = split_loop_references(loops, inputs, references)
            state = initial_state(model, x0, v0)
            return simulate_spatial_controlled_generated(
                ControlledModel(model, loops), state[:model.n_positions], state[model.n_positions:], t_final=t_final,
                dt=dt, inputs=inputs, references=references, outputs=tuple(outputs), store_every=store_every,
                divergence_bound=divergence_bound)
        from .compiled_spatial import simulate_spatial_generated
        return simulate_spatial_generated(model, t_final, dt, x0=x0, v0=v0, inputs=inputs, store_every=store_every,
                                          divergence_bound=divergence_bound)
    scheme = isinstance(method, Scheme) or method in SCHEMES     # the implicit DT-TMM (docs/spatial.md §6a)
    if scheme:
        solve_ivp_options = {"rtol": (rtol, 1e-8), "atol": (atol, 1e-10), "max_step": (max_step, None)}
        for name, (value, default) in solve_ivp_options.items():
            if value != default:
                raise ModelError(f"{name}={value!r} applies to solve_ivp methods, not to the DT-TMM scheme {method!r}")
    if scheme and not controlled:
        for name, (value, default) in {"progress": (progress, None), "stability_check": (stability_check, None)}.items():
            if value is not default and value != default:
                raise ModelError(f"{name}={value!r} is not available for DT-TMM runs of spatial models yet; leave "
                                 f"{name} at {default!r}")
        return simulate_spatial_implicit(model, t_final, dt, scheme=method, x0=x0, v0=v0, inputs=inputs,
                                         store_every=store_every, divergence_bound=divergence_bound)
    if not isinstance(method, (str, Scheme)):
        raise ModelError(f"method for a spatial model must be 'rk4', a solve_ivp method or a DT-TMM scheme "
                         f"{tuple(SCHEMES)}, got {method!r}")
    if controlled:
        if isinstance(outputs, (str, Mapping)) or not isinstance(outputs, (list, tuple)):
            raise ModelError(f"outputs must be a list or tuple of sensor names (str), got {outputs!r}")
        ports = SpatialPorts(model)
        for name in outputs:
            ports.check_sensor(name, "output (sensor)")
        if model.n_velocities == 0:
            raise ModelError(f"model {model.name!r} has no coordinates (every joint is welded or driven): nothing "
                             "to integrate")
        inputs, references = split_loop_references(loops, inputs, references)
        state = initial_state(model, x0, v0)
        policy = "warn" if stability_check is None else validation.option("stability_check", stability_check,
                                                                           ("warn", "error", "ignore"))
        return simulate_closed_loop(model, state[:model.n_positions], state[model.n_positions:], t_final, dt,
                                    method=method, loops=loops, controllers=controllers, inputs=inputs,
                                    references=references, outputs=tuple(outputs), coupling=coupling, rtol=rtol,
                                    atol=atol, max_step=math.inf if max_step is None else max_step,
                                    store_every=validation.integer("store_every", store_every, minimum=1),
                                    progress=validation.flag("progress", progress, optional=True),
                                    stability_check=policy, divergence_bound=divergence_bound)
    for name, (value, default) in {"progress": (progress, None), "stability_check": (stability_check, None)}.items():
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} is not available for uncontrolled spatial models yet; leave {name} "
                             f"at {default!r}")
    return simulate_spatial(model, t_final, dt, method=method, x0=x0, v0=v0, inputs=inputs, rtol=rtol, atol=atol,
                            max_step=max_step, store_every=store_every, divergence_bound=divergence_bound)
