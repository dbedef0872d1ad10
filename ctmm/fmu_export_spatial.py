"""What an exported FMU of a spatial model computes and shows (:mod:`ctmm.fmu_export`).

:func:`spatial_export` states a :class:`~ctmm.spatial.model.SpatialModel` that
``ctmm.simulate(..., compiled=True)`` compiles as an :class:`~ctmm.fmu_export_model.ExportedSystem`:
the step is :func:`ctmm.generated_loop.rk4_step_function` of the model's
:class:`~ctmm.compiled_spatial.SpatialRates` (the one articulated sweep at ``d = 6``, quaternion
coordinates), the step of ``compiled=True``, with the flexible bodies' guard
(:func:`~ctmm.compiled_spatial_guard.guarded_step`): a step after which a beam's deflection bound
exceeds its length or a finite-element subsystem leaves its small deformation gives a non-finite
state, which ends the FMU's step with an error naming the time.

Variables (names as in ctmm):

* inputs -- the model's joint inputs (:attr:`~ctmm.compiled_spatial.SpatialRates.actuators`; the default); an
  input of ``k > 1`` components (a spherical joint's torque) is ``"<input>[0]"`` ... ``"<input>[k-1]"``; on
  request the body actuators of :mod:`ctmm.spatial.ports` (world-axis ``"<body>.force_x"``,
  ``"<body>.moment_z"``, ``"<body>.<point>.force_y"``, body-axis ``"<body>.force_body_x"``,
  ``"<body>.moment_body_z"``, beam ports), after the joint inputs in ``u``: the step is then that of
  :func:`~ctmm.compiled_spatial_loops.loop_acceleration`, the generated acceleration of the compiled
  controlled spatial models;
* outputs -- coordinates and velocities (``model.coordinates``, ``model.velocities``), each body's
  origin ``"<body>.position_x|y|z"`` [m] and angular velocity ``"<body>.omega_x|y|z"`` [rad/s] in world
  axes (the signals of ``ctmm.simulate``); default the coordinates and velocities;
* parameters -- the numbers the generated step takes as inputs
  (:func:`~ctmm.compiled_spatial_parameters.spatial_parameter_layout`): ``"<body>.mass"``, the non-zero
  ``"<body>.inertia.xx"`` ... ``".yz"``, the non-zero ``"<joint>.stiffness"`` and ``".damping"`` of
  revolute, prismatic and universal joints (``"[k]"`` on a 2-DOF joint) with ``".reference"`` of each
  stiff coordinate, the non-zero numbers of each modal :class:`~ctmm.spatial.SpatialBeam`
  (:mod:`ctmm.compiled_spatial_beam_numbers`: ``"<beam>.mass_per_length"`` [kg/m],
  ``".polar_inertia_per_length"`` [kg m], ``".bending_stiffness_y|z"`` [N m^2], ``".torsional_stiffness"``
  [N m^2], ``".axial_stiffness"`` [N], ``".damping_ratio"`` [-], ``".stiffness_damping"`` [s]; a stiffness of
  a direction without modes enters nothing and is left out), the non-zero ``"gravity.x|y|z"`` -- the names
  of ``ctmm.parameter_names``; geometry, axes, loads, driven motions, zeros, beams' lengths and mode counts
  and the laws of spherical, free and elastic joints are constants of the code (loads and driven joints may
  carry :mod:`ctmm.signals` with a symbolic form: stated at the time symbol of the step and of the outputs, the
  FMU's time; user callables refused, :func:`~ctmm.compiled_spatial.spatial_compile_refusal`); a model with a
  finite-element body (:class:`ctmm.fem.SpatialSubsystem`,
  :func:`~ctmm.compiled_spatial_parameters.unparametrised_bodies`) has no parameters -- every number,
  gravity included, is a constant of the code;
* start values -- ``"<coordinate>_start"`` (quaternion entries as given: set a unit quaternion) and
  ``"<velocity>_start"``.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .compiled_spatial import SpatialRates, position_rates, spatial_compile_refusal
from .compiled_spatial_loops import loop_acceleration
from .compiled_spatial_parameters import unparametrised_bodies
from .compiled_spatial_guard import guarded_step
from .errors import ModelError
from .fmu_export_model import ExportedSystem, ExportedVariable, chosen_names
from .generated_loop import rk4_step_function
from .ops import CASADI
from .spatial.body_forms import SpatialScene
from .spatial.integrate import initial_state, spatial_signals
from .spatial.model import SpatialModel
from .spatial.ports import SpatialPorts

__all__ = ["spatial_export"]


def spatial_export(model: SpatialModel, *, inputs: Sequence[str] | None, outputs: Sequence[str] | None,
                   parameters: Sequence[str] | None, q0: Any, qdot0: Any) -> ExportedSystem:
    """The :class:`~ctmm.fmu_export_model.ExportedSystem` of a spatial model.

    Parameters
    ----------
    model : SpatialModel
    inputs, outputs : sequence of str or None
        Names to expose (module docstring); ``None``: every joint input component; every coordinate and
        velocity.
    parameters : sequence of str or None
        Parameters to expose (module docstring); ``None``: all of them.
    q0, qdot0 : array_like, mapping or None
        Start positions and velocities, as ``x0`` and ``v0`` of ``ctmm.simulate`` (default the neutral
        configuration at rest).

    Raises
    ------
    ModelError
        A model the generated kernels refuse (named), unknown names, bad start values.
    """
    import casadi as ca

    reason = spatial_compile_refusal(model, time_signals=True)     # signals on the step's and outputs' time
    if reason:
        raise ModelError(f"export_fmu: system: {reason}")
    start_values = initial_state(model, q0, qdot0)
    finite_element = unparametrised_bodies(model)
    rates = SpatialRates(model, fold=False, numbers="constants" if finite_element else "inputs")
    layout = rates.layout
    ports = SpatialPorts(model)
    joint_units = {(actuator.target, actuator.component): actuator.unit for actuator in ports.actuators.values()
                   if actuator.kind == "joint"}       # a free joint's wrench: [0..2] N, [3..5] N m
    components, input_units, offset = [], {}, 0
    for name, width in zip(rates.actuators, rates.widths):
        for k in range(width):
            label = name if width == 1 else f"{name}[{k}]"
            components.append((label, offset + k))
            input_units[label] = joint_units.get((name, k), "")
        offset += width
    index = dict(components)
    body_actuators = [name for name, actuator in ports.actuators.items() if actuator.kind != "joint"]
    input_names = chosen_names("inputs", inputs, list(index) + body_actuators, list(index))
    applied = [name for name in input_names if name not in index]
    index.update({name: offset + k for k, name in enumerate(applied)})
    rate = _rate_with_body_actuators(model, ports, rates, applied) if applied else rates.rate
    step = guarded_step(model, rk4_step_function(rate))     # NaN once a flexible body leaves its bounds
    arguments = [ca.MX.sym(label, *step.size_in(i)) for i, label in enumerate(("y", "u", "h", "p", "t0", "k"))]
    step_function = ca.Function("ctmm_step", arguments, [step(*arguments)])
    nq, nv = model.n_positions, model.n_velocities
    y_sym = ca.SX.sym("y", nq + nv)
    q_sym, v_sym = y_sym[:nq], y_sym[nq:]
    zero_inputs = {name: ca.SX.zeros(width, 1) for name, width in zip(rates.actuators, rates.widths)}
    t_sym, p_outputs = ca.SX.sym("t"), ca.SX.sym("p", len(layout))
    bodies = SpatialScene(model).terms(CASADI, q_sym, v_sym, t_sym, zero_inputs)[2]     # driven joints at t
    expressions = {name: y_sym[k] for k, name in enumerate(list(model.coordinates) + list(model.velocities))}
    for body, state in zip(model.bodies, bodies):
        for axis, label in enumerate("xyz"):
            expressions[f"{body.name}.position_{label}"] = state.origin[axis]
            expressions[f"{body.name}.omega_{label}"] = state.omega[axis]
    default_outputs = list(model.coordinates) + list(model.velocities)
    output_names = chosen_names("outputs", outputs, list(expressions), default_outputs)
    output_function = ca.Function("ctmm_outputs", [y_sym, t_sym, p_outputs],
                                  [ca.vertcat(*[expressions[name] for name in output_names])
                                   if output_names else ca.SX(0, 1)])
    start, p_sym = ca.SX.sym("start", nq + nv), ca.SX.sym("p", len(layout))
    initial_function = ca.Function("ctmm_initial", [start, p_sym], [start])

    _, units = spatial_signals(model, np.zeros(1), start_values[None, :])
    input_variables = tuple(
        ExportedVariable(name, index[name], 0.0, ports.actuator_unit(name), f"body actuator {name}, held over a "
                         "communication step") if name in applied else     # the description gets the unit appended
        ExportedVariable(name, index[name], 0.0, input_units[name], f"joint input {name}, held over a communication "
                         "step") for name in input_names)
    output_variables = tuple(ExportedVariable(name, k, None, units.get(name, ""), f"signal {name}")
                             for k, name in enumerate(output_names))
    starts = tuple(ExportedVariable(f"{name}_start", k, float(start_values[k]), units.get(name, ""),
                                    f"start value of {name}")
                   for k, name in enumerate(list(model.coordinates) + list(model.velocities)))
    exposable = {entry.name: (k, entry) for k, entry in enumerate(layout)}
    chosen = chosen_names("parameters", parameters, list(exposable), list(exposable))
    parameter_variables = tuple(ExportedVariable(name, exposable[name][0], exposable[name][1].value,
                                                 exposable[name][1].unit, f"model number {name}") for name in chosen)
    notes = (f"spatial model with the finite-element bodies {', '.join(finite_element)}: every number is a constant "
             "of the code",) if finite_element else (
        "spatial model: masses, inertias, modal beams' numbers, 1- and 2-DOF joint laws and gravity are parameters; "
        "geometry, axes, loads, zeros, beams' lengths and the other joint laws are constants of the code",)
    return ExportedSystem(model.name, initial_function, step_function, output_function,
                          np.array([entry.value for entry in layout], dtype=float), offset + len(applied), nq + nv,
                          input_variables,
                          output_variables, parameter_variables, starts, notes)


def _rate_with_body_actuators(model: SpatialModel, ports: SpatialPorts, rates: SpatialRates,
                              applied: Sequence[str]) -> Any:
    """``(y, u, p, t) -> y_dot`` of ``model`` with ``u`` the joint input components of ``rates`` followed by
    one value per body actuator of ``applied`` (the generated acceleration of the compiled controlled
    spatial models, :func:`~ctmm.compiled_spatial_loops.loop_acceleration`: forces at their points and
    moments, world or body axes)."""
    import casadi as ca

    joint_ports = []                              # the port name of each joint input component, in u's order
    for name, width in zip(rates.actuators, rates.widths):
        for k in range(width):
            joint_ports += [port for port, actuator in ports.actuators.items()
                            if actuator.kind == "joint" and actuator.target == name and actuator.component == k]
    acceleration = loop_acceleration(model, ports, joint_ports + list(applied), rates.layout)
    nq, nv = model.n_positions, model.n_velocities
    q, v = ca.SX.sym("q", nq), ca.SX.sym("v", nv)
    position_rate = ca.Function("position_rate", [q, v], [position_rates(model, q, v)])
    y, u = ca.MX.sym("y", nq + nv), ca.MX.sym("u", len(joint_ports) + len(applied))
    p, t = ca.MX.sym("p", len(rates.layout)), ca.MX.sym("t")
    return ca.Function("rate", [y, u, p, t], [ca.vertcat(position_rate(y[:nq], y[nq:]),
                                                        acceleration(y[:nq], y[nq:], u, p, t))])
