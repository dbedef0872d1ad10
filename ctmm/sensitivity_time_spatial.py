"""Exact derivatives of spatial RK4 simulations: forward sensitivities of the generated spatial step.

For a spatial model of rigid bodies and modal beams (compilable, :func:`ctmm.compiled_spatial.spatial_compile_refusal`),
alone or closed by loops (``ctmm.control.with_feedback``), the RK4 step ``y_{k+1} = Phi(y_k, p, t_k)`` of
``y = [q, v]`` (quaternions integrated as coordinates, ``q_dot = G(q) v``; with loops ``[q, v, z, ring]``,
:class:`ctmm.compiled_loops.ClosedLoops` on :class:`ctmm.compiled_spatial_loops.SpatialSymbols`) is stated on
casadi symbols with the model's numbers as inputs (:func:`ctmm.compiled_spatial_loops.loop_acceleration`
with a ``layout``: the one articulated sweep, :mod:`ctmm.compiled_spatial_parameters`), and the loop
numbers are directions in the same parameter column (:mod:`ctmm.sensitivity_loop_numbers`).  The forward
sensitivities ``S_{k+1} = dPhi/dy S_k + dPhi/dp`` are folded with the state by casadi's algorithmic
differentiation (:func:`ctmm.sensitivity_time.forward_sensitivities`): the exact derivative of the RK4
solution ``ctmm.simulate(model, ..., method="rk4")`` computes (the numpy and generated RK4 agree to
round-off), not of the exact ODE solution.

Parameters: the names of :mod:`ctmm.sensitivity_spatial` (``"<body>.mass"``, ``"<body>.inertia.xx"``,
``"<joint>.stiffness"``, ``".damping"``, ``".reference"``, ``"gravity.z"``, ``"<beam>.mass_per_length"``,
``"<beam>.bending_stiffness_y"``, ...) and the loops' ``"<loop>.gain"``,
``"<loop>.<sensor>"`` and realisation entries; outputs: coordinates (``model.coordinates``), velocities
(``model.velocities``) and sensor ports stated on symbols (``"body.angle_z"``, ``"link.tip.x"``; their
derivative ``dy/dp = dy/dx S``).

Loads and driven joints may carry :mod:`ctmm.signals` with a symbolic form (Constant, Harmonic, Step,
SquareWave): the step states them on its stage times, as the generated RK4 does
(:mod:`ctmm.compiled_spatial_signals`), and an output that moves with a driven joint's signals (a body outboard
of it) is evaluated at each stored time.  User callables are refused by name, and so is a loop sensor that
moves with a driven joint's signals (the generated loops state their sensors at the state only).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from . import validation
from .errors import ModelError, unknown_name
from .sensitivity_time import TimeSensitivity

__all__ = ["spatial_simulation_sensitivity"]


def spatial_simulation_sensitivity(model: Any, parameters: str | Sequence[str], *, t_final: float, dt: float,
                                   x0: Any = None, v0: Any = None,
                                   outputs: str | Sequence[str] | None = None) -> TimeSensitivity:
    """RK4 run of a spatial model (loops closed in the step) with the exact derivatives of its outputs.

    Parameters
    ----------
    model : SpatialModel or ControlledModel (spatial plant)
        Rigid bodies and modal beams; compilable (load and driven-joint signals with a symbolic form); no
        open-loop actuator inputs; loop references 0.
    parameters : str or sequence of str
        Plant and loop numbers (module docstring).
    t_final, dt : float
        [s]; ``t_final / dt`` whole (as :func:`ctmm.simulate`, ``method="rk4"``); delays whole multiples of ``dt``.
    x0, v0 : mapping or array_like, optional
        Initial coordinates and velocities as :func:`ctmm.simulate` takes them (default: neutral, at rest).
    outputs : str or sequence of str, optional
        Coordinates, velocities and sensor ports; default every coordinate.

    Returns
    -------
    TimeSensitivity
        ``values`` and ``derivative`` of the outputs at every step (SI units of the outputs).

    Raises
    ------
    ModelError
        Finite-element subsystems, a model that cannot be compiled (user-callable signals), unknown or zero plant
        numbers, loop delays, weights of saturated loops, loop sensors that move with a driven joint's signals,
        unknown outputs, a diverging run.
    """
    import casadi as ca

    from .compiled_loops import ClosedLoops
    from .compiled_spatial import position_rates
    from .compiled_spatial_loops import SpatialSymbols, loop_acceleration
    from .compiled_spatial_parameters import spatial_parameter_layout, spatial_parameter_vector
    from .control.controlled_model import ControlledModel
    from .generated_loop import rk4_step_function
    from .planar.integrate import step_total
    from .sensitivity_loop_numbers import is_loop_number, loop_directions, split_loops
    from .sensitivity_spatial import check_differentiable, spatial_parameter_index
    from .spatial.integrate import initial_state
    from .spatial.model import SpatialModel
    from .spatial.ports import SpatialPorts

    what = "spatial_simulation_sensitivity"
    controlled = model if isinstance(model, ControlledModel) else None
    plant = controlled.plant if controlled is not None else model
    if not isinstance(plant, SpatialModel):
        raise ModelError(f"{what}: model must be a ctmm.spatial.SpatialModel or a ControlledModel on one, got "
                         f"{type(plant).__name__}")
    check_differentiable(plant, what, time_signals=True)
    names = validation.names("parameters", parameters)
    loop_list = controlled.loops if controlled is not None else ()
    split = split_loops(controlled, names, what) if controlled is not None else None
    p0 = spatial_parameter_vector(plant)
    directions = np.zeros((p0.size, len(names)))
    for column, name in enumerate(names):
        if not is_loop_number(loop_list, name):
            directions[spatial_parameter_index(plant, name), column] = 1.0
    ports = split.ports if split is not None else SpatialPorts(plant)
    symbols = SpatialSymbols(plant, ports, p0.size)
    n_steps = step_total(t_final, dt)
    h = t_final / n_steps
    nq, nv = plant.n_positions, plant.n_velocities
    start = np.asarray(initial_state(plant, x0, v0), dtype=float)
    q0, v0 = start[:nq], start[nq:]
    if split is None:
        acceleration = loop_acceleration(plant, ports, (), spatial_parameter_layout(plant))
        y, u, p, t = ca.SX.sym("y", nq + nv), ca.SX.sym("u", 0), ca.SX.sym("p", p0.size), ca.SX.sym("t")
        rate = ca.Function("rate", [y, u, p, t], [ca.vertcat(position_rates(plant, y[:nq], y[nq:]),
                                                             acceleration(y[:nq], y[nq:], u, p, t))])
        step, first = rk4_step_function(rate), np.concatenate([q0, v0])
    else:
        actuators = tuple(dict.fromkeys(name for loop in split.loops for name, _ in loop.actuator_terms))
        loops = ClosedLoops(split, actuators, h, symbols=symbols, numbers="inputs")
        step = loops.step(loop_acceleration(plant, ports, actuators, spatial_parameter_layout(plant)), len(actuators),
                          p0.size)
        first = loops.initial_state(q0, v0)
        size = p0.size + loops.parameter_values.size
        directions = np.vstack([directions, np.zeros((loops.parameter_values.size, len(names)))]) + \
            loop_directions(controlled, split, loops.parameter_layout, names, p0.size, size)
        p0 = np.concatenate([p0, loops.parameter_values])
    from .sensitivity_time import forward_sensitivities

    states, tangents = forward_sensitivities(step, first, p0, directions, n_steps, h, what)
    wanted = list(plant.coordinates) if outputs is None else list(validation.names("outputs", outputs))
    state_names = list(plant.coordinates) + list(plant.velocities)
    q_sym, v_sym, t = ca.SX.sym("q", nq), ca.SX.sym("v", nv), ca.SX.sym("t")
    rows = []
    for name in wanted:            # sensors that move with a driven joint's signals: on the time symbol
        if name in ports.sensors and name not in state_names:
            rows.append(symbols.sensor(name, q_sym, v_sym, t))
        elif name in state_names:
            rows.append(ca.vertcat(q_sym, v_sym)[state_names.index(name)])
        else:
            raise unknown_name("output (coordinate, velocity or sensor port)", name,
                               state_names + [s for s in ports.sensors if s not in state_names])
    x = ca.vertcat(q_sym, v_sym)
    y = ca.vertcat(*rows)
    evaluate = ca.Function("outputs", [x, t], [y, ca.jacobian(y, x)]).map(n_steps + 1)
    time = h * np.arange(n_steps + 1)
    values, slopes = evaluate(states[:, :nq + nv].T, time[None, :])
    values = np.asarray(values, dtype=float).reshape(len(wanted), n_steps + 1)
    slopes = np.asarray(slopes, dtype=float).reshape(len(wanted), n_steps + 1, nq + nv)
    derivative = np.einsum("okx,kxm->mok", slopes, tangents[:, :nq + nv, :])
    return TimeSensitivity(time, tuple(wanted), tuple(names), values, derivative)
