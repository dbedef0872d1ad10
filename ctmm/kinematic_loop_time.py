""":func:`ctmm.simulate` of a kinematic loop model with feedback loops, actuator inputs or controllers.

A :class:`~ctmm.planar.closed_loops.KinematicLoopModel` alone runs its own integrators
(:func:`ctmm.planar.loop_verbs.simulate_loops`: RK4 with projection, ``solve_ivp``, the DT-TMM schemes).
With feedback loops (``ctmm.control.with_feedback(loop_model, loops)``), open-loop actuator ``inputs``,
``references`` or co-simulated ``controllers`` it runs in the one loop-closing driver
(:func:`ctmm.control.planar_time.simulate_closed_loop`) on its plant
(:class:`~ctmm.planar.loop_plant.KinematicLoopPlant`): the closed-loop accelerations with the cut forces
solved as boundary unknowns under the actuator values of every stage or Newton iterate; real-time loops
at the current state, delayed loops from the delay history; ``"rk4"``, the ``solve_ivp`` methods and the
DT-TMM schemes.  Constraint drift is held by Baumgarte stabilisation and projection (RK4 and the schemes after every
step, ``solve_ivp`` at every controller sample) and reported (``"drift"`` [m], ``"drift_rate"`` [m/s]) with the cut forces (``docs/closed_loops.md`` §3c).  With
``compiled=True`` and ``"rk4"`` the same run is generated C (:mod:`ctmm.compiled_kinematic_loop_control`;
co-simulated controllers sampled between calls into it).
"""
from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

from . import validation
from .control.planar_time import simulate_closed_loop
from .errors import ModelError, unknown_name
from .planar.closed_loops import KinematicLoopModel
from .planar.loop_verbs import initial_state, simulate_loops
from .planar.loop_ports import KinematicLoopPorts
from .results import SimulationResult

__all__ = ["simulate_kinematic_loop_system"]


def simulate_kinematic_loop_system(system: Any, t_final: float, dt: float | None, *, method: Any, x0: Any, v0: Any,
                                   outputs: Sequence[str], inputs: Mapping[str, Any] | None, controllers: list,
                                   references: dict, coupling: str, rtol: float, atol: float,
                                   max_step: float | None, store_every: int, divergence_bound: float | None,
                                   stability_check: str | None, progress: bool | None,
                                   unsupported: Mapping[str, tuple[Any, Any]]) -> SimulationResult:
    """Simulate a kinematic loop model, alone or with loops, inputs or controllers (module docstring).

    Parameters
    ----------
    system : KinematicLoopModel or ControlledModel
        The model, or a controlled model whose plant is one (``ctmm.control.with_feedback``).
    t_final, dt : float
        End time and step [s] (``dt``: required by ``"rk4"``, the schemes and controllers).
    method : str or Scheme
        ``"rk4"``, a ``solve_ivp`` method or a DT-TMM scheme.
    x0, v0 : mapping or array
        A consistent initial state of the tree coordinates (:meth:`KinematicLoopModel.consistent_state`).
    outputs : sequence of str
        Sensors to store: the tree's and the cut joints' (:mod:`ctmm.planar.loop_ports`).
    inputs : mapping, optional
        ``{actuator: number or f(t)}`` [N, N m]: the tree's and the cut torques ``"<cut>.torque"`` (the caller moved ``"<loop>.reference"`` entries to
        ``references``).
    controllers : list
        Co-simulated controllers on the model's ports (tree and cut joints).
    references : dict
        ``{loop name: r(t)}``.
    coupling, rtol, atol, max_step, store_every, divergence_bound, stability_check, progress
        As for :func:`ctmm.simulate`.
    unsupported : mapping
        ``{option: (value, default)}`` of options that do not apply to a kinematic loop model (``solver``,
        ``fast``, ``force_hook``, ``t0``, ``compiled``): refused by name unless at the default (but ``compiled=True``
        with ``"rk4"``: the model alone :mod:`ctmm.compiled_kinematic_loops`, with loops, inputs or controllers
        :mod:`ctmm.compiled_kinematic_loop_control`).

    Returns
    -------
    SimulationResult
        Tree coordinates, rates, outputs, cut forces ``"<cut>.force_x|y"`` [N], ``"drift"`` [m],
        ``"drift_rate"`` [m/s] and, with loops, ``"<loop>.y"``, ``"<loop>.u"``.
    """
    model = system if isinstance(system, KinematicLoopModel) else system.plant
    loops = () if system is model else tuple(system.loops)
    if not (loops or inputs or controllers or references):
        others = {name: value for name, (value, _) in unsupported.items()}
        others.update({"inputs": inputs or None, "controllers": list(controllers), "references": dict(references),
                       "coupling": coupling, "progress": progress})
        generated = None
        if others["compiled"]:          # the generated RK4 with projection (ctmm.compiled_kinematic_loops)
            from .compiled_kinematic_loops import simulate_kinematic_loops_generated as generated
        return simulate_loops(model, t_final, dt, method=method, x0=x0, v0=v0, outputs=outputs, rtol=rtol, atol=atol,
                              max_step=max_step, store_every=store_every, divergence_bound=divergence_bound,
                              stability_check=stability_check, other_options=others, generated=generated)
    compiled = unsupported.get("compiled", (None, None))[0]
    if compiled is True and method == "rk4":     # generated C: ctmm.compiled_kinematic_loop_control
        from . import compiled_kinematic_loop_control as generated

        unsupported = {name: pair for name, pair in unsupported.items() if name != "compiled"}
    for name, (value, default) in unsupported.items():
        if value is not default and value != default:
            raise ModelError(f"{name}={value!r} is not available for the kinematic loop model {model.name!r} with "
                             f"loops, inputs or controllers (the loop-closing driver on its closed-loop "
                             f"accelerations; runs start at t = 0); leave {name} at {default!r}")
    if isinstance(outputs, (str, Mapping)) or not isinstance(outputs, (list, tuple)):
        raise ModelError(f"outputs must be a list or tuple of sensor names (str), got {outputs!r}")
    ports = KinematicLoopPorts(model)
    for name in outputs:
        ports.check_sensor(name, "output (sensor)")
    if inputs is not None and not isinstance(inputs, Mapping):
        raise ModelError(f"inputs must be a mapping {{actuator name: number or f(t)}}, got {inputs!r}")
    for key in references:
        if key not in {loop.name for loop in loops}:
            raise unknown_name("reference (loop)", key, [loop.name for loop in loops])
    q0, v0 = initial_state(model, x0, v0)
    policy = "warn" if stability_check is None else validation.option("stability_check", stability_check,
                                                                       ("warn", "error", "ignore"))
    store_every = validation.integer("store_every", store_every, minimum=1)
    limit = math.inf if max_step is None else validation.positive("max_step", max_step)
    if compiled is True and method == "rk4":
        return generated.simulate_generated_driver_run(
            system, q0, v0, t_final=t_final, dt=dt, controllers=controllers, inputs=inputs, references=references,
            outputs=outputs, coupling=coupling, store_every=store_every, progress=progress, stability_check=policy,
            divergence_bound=divergence_bound, max_step=max_step)
    return simulate_closed_loop(model, q0, v0, t_final, dt, method=method, loops=loops, controllers=controllers,
                                inputs=dict(inputs or {}), references=references, outputs=tuple(outputs),
                                coupling=coupling, rtol=rtol, atol=atol, max_step=limit, store_every=store_every,
                                progress=progress, stability_check=policy, divergence_bound=divergence_bound)
