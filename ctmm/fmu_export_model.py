"""What an exported plant FMU computes and shows: its generated functions and its variables (:mod:`ctmm.fmu_export`).

:func:`planar_export` states a :class:`~ctmm.planar.model.PlanarModel` (rigid trees, modal beams) or a
:class:`~ctmm.control.controlled_model.ControlledModel` on a planar plant (loops closed inside the step)
as an :class:`ExportedSystem`: three casadi functions whose generated C the FMU runs
(``ctmm_initial``, ``ctmm_step``, ``ctmm_outputs``; :mod:`ctmm.fmu_export_runtime`) and the named
variables of its model description.

The step is the one of ``ctmm.simulate(..., compiled=True)``: the symbolic
:attr:`ctmm.compiled_scene.CompiledScene.symbolic_step` (one RK4 step of the articulated sweep,
:func:`ctmm.ode.rk4_step` on symbols, the loops of :mod:`ctmm.compiled_loops` closed at every stage).

Variables (names as in ctmm):

* inputs -- actuators of :mod:`ctmm.planar.ports` (``"<hinge>.torque"``, ``"<body>.force_x"``, modal
  forces ``"<beam>.<coordinate>.force"``; beam station forces and moments ``"<beam>.<station>.force|moment"``
  when named in ``inputs``, :func:`station_inputs`), held over a communication step, added to the model's own
  laws and the loops' outputs;
* outputs -- sensors of :mod:`ctmm.planar.ports` (coordinates ``"<coordinate>"`` and
  ``"<coordinate>_dot"``, angles, rates, point positions and velocities, beam stations) and, of a
  controlled model, each loop's measured signal ``"<loop>.y"`` and output ``"<loop>.u"``
  (:func:`loop_expressions`);
* parameters (:func:`parameter_names`) -- the numbers of the rigid bodies and hinge laws that the
  generated code takes as its input ``p`` and that do not enter the sensors: masses, inertias,
  gravity (no beams), hinge stiffnesses and dampings, hinge-law and load signal parameters.  Geometry
  (centres of mass, points, load points) enters the sensors as constants and is not exposed; numbers
  that are zero in the model are constants 0 of the code and are not exposed; modal beams keep their
  data (and loads) as constants; an entry the generated step does not depend on (its Jacobian
  sparsity) is not exposed, so no exposed parameter is a silent no-op; of a controlled model, each
  static loop's gain ``"<loop>.gain"`` and each loop's reference ``"<loop>.reference"`` (or
  ``"<loop>.reference.<field>"``, a sine's amplitude, ...; :func:`loop_parameter_names`) -- the loop
  outputs ``"<loop>.u"`` use them too; an LTI controller's realisation is an input of the code but not
  exposed (it is the state-space form, not the transfer function's coefficients);
* start values -- ``"<coordinate>_start"`` and ``"<coordinate>_dot_start"``.

The outputs function takes the parameters too (``ctmm_outputs(Y, t, p)``).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from .compiled_loops import ClosedLoops
from .compiled_planar_sensors import SymbolicKinematics, sensor_expression
from .compiled_parameters import compile_refusal, moving_drives, parameter_vector
from .compiled_scene import CompiledScene
from .control.controlled_model import ControlledModel
from .control.loop_rows import loop_unit
from .errors import ModelError
from .planar.guards import check_scheme
from .planar.integrate import coordinate_values, initial_coordinates
from .planar.model import REVOLUTE, PlanarModel
from .planar.ports import PlanarPorts
from .signals import SYMBOLIC_FIELDS

__all__ = ["ExportedSystem", "ExportedVariable", "chosen_names", "loop_expressions", "loop_parameter_names",
           "parameter_names", "planar_export", "station_inputs"]


@dataclass(frozen=True)
class ExportedVariable:
    """One Real variable of an exported FMU.

    Attributes
    ----------
    name : str
        Its name in ctmm (and in the FMU).
    index : int
        Its place in the vector it belongs to (``u``, the outputs, ``p`` or the start values).
    start : float or None
        Start value (inputs, parameters, start values); ``None`` for outputs.
    unit : str
        SI unit text (``"rad"``, ``"N m"``; ``""`` when none is known).
    description : str
        One line for the model description.
    """

    name: str
    index: int
    start: float | None
    unit: str
    description: str


@dataclass(frozen=True)
class ExportedSystem:
    """The generated functions and the variables of an exported system.

    Attributes
    ----------
    name : str
        The system's name.
    initial_function : casadi.Function
        ``ctmm_initial(start, p) -> Y0``: the integrated state from ``[q0; qdot0]``.
    step_function : casadi.Function
        ``ctmm_step(Y, u, h, p, t0, k) -> Y``: RK4 step ``k`` from ``t0 + k h``.
    output_function : casadi.Function
        ``ctmm_outputs(Y, t, p) -> y``.
    parameter_values : ndarray
        The whole input ``p`` (exposed or not).
    n_inputs_total : int
        Length of ``u`` (unexposed inputs are held 0).
    state_size : int
        Length of ``Y``.
    inputs, outputs, parameters, starts : tuple of ExportedVariable
        The exposed variables.
    notes : tuple of str
        What is a constant of the code (for the description and the docs).
    """

    name: str
    initial_function: Any
    step_function: Any
    output_function: Any
    parameter_values: np.ndarray
    n_inputs_total: int
    state_size: int
    inputs: tuple
    outputs: tuple
    parameters: tuple
    starts: tuple
    notes: tuple


_PARAMETER_UNITS = {"mass": "kg", "inertia": "kg m^2", "gravity": "m/s^2", "stiffness": "N m/rad",
                    "damping": "N m s/rad"}
_LAW_UNITS = {"reference": "rad", "reference_rate": "rad/s", "torque": "N m"}
_FIELD_UNITS = {"omega": "rad/s", "phase": "rad", "time": "s", "period": "s", "duration": "s", "start": "s"}


def _field_unit(field: str, unit: str) -> str:
    """The unit of a signal's ``field`` when the signal's value is in ``unit`` (a ramp's slope: per second)."""
    if field == "slope":
        return f"{unit}/s" if unit else "1/s"
    return _FIELD_UNITS.get(field, unit)


def parameter_names(model: PlanarModel) -> list[tuple[str, str, bool]]:
    """``(name, unit, exposed)`` of every entry of :func:`ctmm.compiled_parameters.parameter_vector`
    (same order and length): ``"<body>.mass"``, ``"<body>.inertia"``, ``"<body>.center_of_mass.x"``,
    ``"<body>.<point>.x"``, ``"gravity.x"``, ``"<joint>.stiffness"``, ``"<joint>.damping"``,
    ``"<joint>.law.reference[.<field>]"`` (``reference_rate``, ``torque``),
    ``"<body>.load<k>.force_x[.<field>]"`` (``force_y``, ``moment``), ``"<body>.load<k>.point.x"``,
    ``"<joint>.drive.angle[.<field>]"`` (``rate``, ``acceleration``) of a moving driven hinge;
    a signal with one field (a constant) has no field suffix.

    ``exposed`` is False for what must stay a constant of the code: geometry (it also enters the
    sensors), the numbers of modal beams (they keep their own data), gravity with beams and the signals of
    moving drives (a drive's angle, rate and acceleration are one motion, checked consistent when the hinge is
    built, and enter the loop sensors).

    Raises
    ------
    ModelError
        The names do not match the length of the parameter vector (a layout this function does not know).
    """
    values = parameter_vector(model)
    names: list[tuple[str, str, bool]] = []
    bodies, joints = list(model.body_names), list(model.joint_names)
    rigid = [j not in model.beams for j in range(model.n_bodies)]
    for kind in ("mass", "inertia"):
        names += [(f"{body}.{kind}", _PARAMETER_UNITS[kind], rigid[j]) for j, body in enumerate(bodies)]
    names += [(f"{body}.center_of_mass.{axis}", "m", False) for body in bodies for axis in "xy"]
    names += [(f"{body}.{point}.{axis}", "m", False) for j, body in enumerate(bodies) for point in model.ends[j]
              for axis in "xy"]
    names += [(f"gravity.{axis}", "m/s^2", not model.beams) for axis in "xy"]
    for kind in ("stiffness", "damping"):
        names += [(f"{joint}.{kind}", _PARAMETER_UNITS[kind], True) for joint in joints]
    by_name = {getattr(element, "name", None): element for element in model.elements}
    for kind in ("reference", "reference_rate", "torque"):
        for joint, joint_kind in zip(joints, model.joint_kind):
            element = by_name.get(joint)
            signal = None
            if joint_kind == REVOLUTE and hasattr(element, "law"):
                signal = element.law()[2 + ("reference", "reference_rate", "torque").index(kind)]
            names += _signal_names(f"{joint}.law.{kind}", signal, _LAW_UNITS[kind])
    loads = [(body, k, load) for body in bodies for k, load in enumerate(getattr(by_name[body], "loads", ()))]
    for body, k, load in loads:
        for part, unit in (("force_x", "N"), ("force_y", "N"), ("moment", "N m")):
            names += _signal_names(f"{body}.load{k}.{part}", getattr(load, part), unit)
    names += [(f"{body}.load{k}.point.{axis}", "m", False) for body, k, _ in loads for axis in "xy"]
    for j, hinge in moving_drives(model):       # one motion: its three signals change together or not at all
        for part, unit in (("angle", "rad"), ("rate", "rad/s"), ("acceleration", "rad/s^2")):
            names += [(name, name_unit, False) for name, name_unit, _ in
                      _signal_names(f"{model.joint_names[j]}.drive.{part}", getattr(hinge, part), unit)]
    if len(names) != values.size:
        raise ModelError(f"export_fmu: the parameters of model {model.name!r} are laid out as this version does not "
                         f"know ({values.size} numbers, {len(names)} names); export with parameters=()")
    return names


def _signal_names(prefix: str, signal: Any, unit: str) -> list[tuple[str, str, bool]]:
    """Names of the fields of a hinge-law or load signal (a missing one is the constant 0)."""
    fields = SYMBOLIC_FIELDS.get(type(signal), ("value",)) if signal is not None else ("value",)
    if len(fields) == 1:
        return [(prefix, unit, True)]
    return [(f"{prefix}.{field}", _field_unit(field, unit), True) for field in fields]


def chosen_names(label: str, given: Sequence[str] | None, allowed: Sequence[str],
                 default: Sequence[str]) -> list[str]:
    """The names chosen by the argument ``label`` of :func:`ctmm.export_fmu` (default ``default``), each one of
    ``allowed`` (:class:`ModelError` naming the argument, the unknown name and the allowed ones)."""
    if given is None:
        return list(default)
    if isinstance(given, str) or not all(isinstance(name, str) for name in given):
        raise ModelError(f"export_fmu: {label} must be a sequence of names, got {given!r}")
    chosen = list(dict.fromkeys(given))
    for name in chosen:
        if name not in allowed:
            shown = ", ".join(list(allowed)[:40]) + (" ..." if len(allowed) > 40 else "")
            raise ModelError(f"export_fmu: {label} has the unknown name {name!r}; allowed: {shown or '(none)'}")
    return chosen


def station_inputs(model: PlanarModel, inputs: Sequence[str] | None) -> list[str]:
    """The beam station forces and moments (``"<beam>.<station>.force|moment"``) among the names ``inputs`` of
    :func:`ctmm.export_fmu`: inputs of the exported step only when named (each adds its modal forces and frame
    wrench to the generated sweep, :mod:`ctmm.compiled_station_loads`)."""
    if inputs is None or isinstance(inputs, str):
        return []
    actuators = PlanarPorts(model).actuators
    return [name for name in dict.fromkeys(inputs) if isinstance(name, str) and name in actuators
            and actuators[name].kind == "station"]


def planar_export(system: PlanarModel | ControlledModel, *, step: float, inputs: Sequence[str] | None,
                  outputs: Sequence[str] | None, parameters: Sequence[str] | None, q0: Any, qdot0: Any,
                  references: Mapping[str, Any] | None, stability_check: str,
                  cache_dir: str | os.PathLike | None = None) -> ExportedSystem:
    """The :class:`ExportedSystem` of a planar model or a controlled planar model.

    Parameters
    ----------
    system : PlanarModel or ControlledModel
    step : float
        RK4 step [s] (each loop delay a whole multiple of it).
    inputs, outputs, parameters : sequence of str or None
        Names to expose (module docstring); ``None``: every actuator (but beam station loads: those are inputs when
        named), every coordinate and rate, every exposable parameter.
    q0, qdot0 : array_like, mapping or None
        Start values [rad, m, modal] (default zeros; ``{coordinate: value}`` as ``x0`` of ``ctmm.simulate``).
    references : mapping, optional
        ``{loop: number or symbolic signal}`` of a controlled model (their numbers are parameters of the FMU).
    stability_check : {"warn", "error", "ignore"}
        Policy when ``step`` exceeds the plant's linearised RK4 limit at the start values.
    cache_dir : path, optional
        Where the native library of the scene (built to check the step) is cached.

    Raises
    ------
    ModelError
        A model the generated kernels refuse (named), unknown names, bad start values or step.
    """
    import casadi as ca

    controlled = system if isinstance(system, ControlledModel) else None
    model = system.plant if controlled is not None else system
    reason = compile_refusal(model)
    if reason:
        raise ModelError(f"export_fmu: system: {reason}")
    n = model.n_coordinates
    q, v = initial_coordinates(model, coordinate_values(model, "q0", q0), coordinate_values(model, "qdot0", qdot0))
    scene = CompiledScene(controlled if controlled is not None else model, cache_dir=cache_dir, rows=1,
                          dt=step if controlled is not None else None, references=references,
                          station_inputs=station_inputs(model, inputs))
    check_scheme(model, q, v, step, scheme="rk4", policy=stability_check,
                 accelerations=lambda m, a, b, t: scene.accelerations(a, b, t=t))
    ports = PlanarPorts(model)
    loops = scene.loops
    y_sym, t_sym, p_sym = ca.SX.sym("y", scene.state_size), ca.SX.sym("t"), ca.SX.sym("p", scene.parameters.size)
    loop_signals = {} if loops is None else loop_expressions(loops, y_sym, t_sym, p_sym)
    default_outputs = list(model.coordinates) + [name + "_dot" for name in model.coordinates]
    output_names = chosen_names("outputs", outputs, list(ports.sensors) + list(loop_signals), default_outputs)
    kinematics = SymbolicKinematics(model, y_sym[:n], y_sym[n:2 * n])
    expressions = [loop_signals[name] if name in loop_signals else sensor_expression(ports, name, kinematics)
                   for name in output_names]
    outputs_function = ca.Function("ctmm_outputs", [y_sym, t_sym, p_sym],
                                   [ca.vertcat(*expressions) if expressions else ca.SX(0, 1)])
    initial = _initial_function(loops, n, scene.parameters.size)
    expected = np.concatenate([q, v]) if loops is None else loops.initial_state(q, v)
    got = np.asarray(initial(np.concatenate([q, v]), scene.parameters), dtype=float).reshape(-1)
    if got.shape != expected.shape or not np.array_equal(got, expected):
        raise ModelError(f"export_fmu: the exported initial state of {model.name!r} does not equal the one of the "
                         "compiled scene (a state layout this version does not know); not exported")
    if loop_signals:
        bound = ca.Function("loops", [y_sym, t_sym], [ca.substitute(ca.vertcat(*loop_signals.values()), p_sym,
                                                                      ca.DM(scene.parameters))])
        _check_loop_signals(loops, bound, scene.run(q, v, step, 3), step)

    symbolic = scene.symbolic_step
    arguments = [ca.MX.sym(label, *symbolic.size_in(i)) for i, label in enumerate(("y", "u", "h", "p", "t0", "k"))]
    step_function = ca.Function("ctmm_step", arguments, [symbolic(*arguments)])

    input_names = chosen_names("inputs", inputs, scene.actuators, scene.actuators)
    input_variables = tuple(ExportedVariable(name, scene.actuators.index(name), 0.0, ports.actuator_unit(name),
                                             f"actuator {name}, held over a communication step")
                            for name in input_names)
    output_variables = tuple(ExportedVariable(name, k, None, _sensor_unit(ports, controlled, name, loop_signals),
                                              f"sensor {name}" if name not in loop_signals else
                                              f"{'measured signal' if name.endswith('.y') else 'output'} of loop "
                                              f"{name[:-2]!r}") for k, name in enumerate(output_names))
    values = scene.parameters
    layout = parameter_names(model)
    plant_count = len(layout)
    layout += [] if loops is None else loop_parameter_names(controlled, loops)
    used = set(step_function.jac_sparsity(0, 3).get_col())     # entries of p the step depends on
    # the plant's zero numbers are constants 0 of the code; the loops' numbers are inputs of it, zero or not
    exposable = {name: (k, unit) for k, (name, unit, exposed) in enumerate(layout)
                 if exposed and (values[k] != 0.0 or k >= plant_count) and k in used}
    chosen = chosen_names("parameters", parameters, list(exposable), list(exposable))
    parameter_variables = tuple(ExportedVariable(name, exposable[name][0], float(values[exposable[name][0]]),
                                                 exposable[name][1], f"model number {name}")
                                for name in chosen)
    coordinate_units = [ports.sensor_unit(name) for name in model.coordinates]
    starts = tuple([ExportedVariable(f"{name}_start", k, float(q[k]), coordinate_units[k], f"start value of {name}")
                    for k, name in enumerate(model.coordinates)] +
                   [ExportedVariable(f"{name}_dot_start", n + k, float(v[k]), ports.sensor_unit(name + "_dot"),
                                     f"start value of {name}_dot") for k, name in enumerate(model.coordinates)])
    notes = ["geometry (centres of mass, points), zero numbers and modal beam data are constants of the code"]
    if loops is not None:
        notes.append(f"loops {', '.join(law.name for law in loops.laws)} closed inside the step; static gains and "
                     "references are parameters, sensors, delays and controller orders constants of the code")
    return ExportedSystem(controlled.plant.name if controlled is not None else model.name, initial, step_function,
                          outputs_function, np.asarray(values, dtype=float), len(scene.actuators), scene.state_size,
                          input_variables, output_variables, parameter_variables, starts, tuple(notes))


def _sensor_unit(ports: PlanarPorts, controlled: ControlledModel | None, name: str, loop_signals: Mapping) -> str:
    """Unit of a sensor, or of a loop's measured signal or output."""
    if name in loop_signals:
        return loop_unit(controlled.ports, controlled.loop(name[:-2]), name[-1])
    return ports.sensor_unit(name)


def _initial_function(loops: ClosedLoops | None, n: int, n_parameters: int) -> Any:
    """``ctmm_initial(start, p) -> Y0``: ``[q0, qdot0]``, with loops ``[q0, qdot0, z = 0, ring]``, the ring
    holding the initial signal of each delayed loop with rate 0 in every column (the history before the
    start is the initial state held; :meth:`ClosedLoops.initial_state`)."""
    import casadi as ca

    start, p_sym = ca.SX.sym("start", 2 * n), ca.SX.sym("p", n_parameters)
    pieces = [start]
    if loops is not None:
        pieces.append(ca.SX.zeros(loops.n_controller_states, 1))
        if loops.delayed:
            y0 = loops.sensors(start[:n], start[n:])
            column = ca.vertcat(*[y0[k] for k in loops.delayed], ca.SX.zeros(len(loops.delayed), 1))
            pieces.append(ca.repmat(column, loops.ring_columns, 1))
    return ca.Function("ctmm_initial", [start, p_sym], [ca.vertcat(*pieces)])


def loop_expressions(loops: ClosedLoops, y: Any, t: Any, p: Any) -> dict[str, Any]:
    """``{"<loop>.y": signal now, "<loop>.u": output}`` of every loop on the state symbol ``y``
    (:attr:`ClosedLoops.state_size`: ``[q, v, z, ring]``) at the time symbol ``t`` [s] with the
    parameter symbol ``p`` (the plant's numbers, then the loops'): :meth:`ClosedLoops.loop_signals`.
    :func:`planar_export` checks them against :meth:`ClosedLoops.signals`."""
    now, outputs = loops.loop_signals(y, t, p)[:2]
    out = {}
    for k, law in enumerate(loops.laws):
        out[f"{law.name}.y"] = now[k]
        out[f"{law.name}.u"] = outputs[k]
    return out


def loop_parameter_names(controlled: ControlledModel, loops: ClosedLoops) -> list[tuple[str, str, bool]]:
    """``(name, unit, exposed)`` of the loops' entries of the parameter vector
    (:attr:`ClosedLoops.parameter_layout`): ``"<loop>.gain"`` (a static loop's, unit of ``u`` per unit of
    ``y`` when both are known, else ``""``) and the reference's fields (unit of ``y``, or the field's) are
    exposed; an LTI controller's realisation entries are not."""
    units = {law.name: (loop_unit(controlled.ports, controlled.loop(law.name), "y"),
                        loop_unit(controlled.ports, controlled.loop(law.name), "u")) for law in loops.laws}
    names = []
    for name, role, _ in loops.parameter_layout:
        if role == "gain":
            y_unit, u_unit = units[name[:-len(".gain")]]
            names.append((name, f"{u_unit}/{y_unit}" if y_unit and u_unit else "", True))
        elif role == "controller":
            names.append((name, "", False))
        else:
            field = role.split(".")[1] if "." in role else ""
            owner = name[:name.index(".reference")]
            names.append((name, _field_unit(field, units[owner][0]), True))
    return names


def _check_loop_signals(loops: ClosedLoops, function: Any, states: np.ndarray, step: float) -> None:
    """Refuse the export when :func:`loop_expressions` differ from :meth:`ClosedLoops.signals` on a few
    stored states (a state layout this version does not know)."""
    times = step * np.arange(1, len(states) + 1)
    y, u = loops.signals()(states, times)
    expected = np.stack([y, u], axis=2).reshape(len(states), -1)          # y0, u0, y1, u1, ...
    got = np.array([np.asarray(function(row, t), dtype=float).reshape(-1) for row, t in zip(states, times)])
    scale = max(1.0, float(np.max(np.abs(expected)))) if expected.size else 1.0
    if got.shape != expected.shape or not np.all(np.abs(got - expected) <= 1e-12 * scale):
        raise ModelError("export_fmu: the exported loop signals do not equal those of the compiled scene (a state "
                         "layout this version does not know); not exported")
