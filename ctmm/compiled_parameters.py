"""What a generated kernel of a planar scene takes as inputs and keeps as constants (issue 13).

:func:`compile_refusal` says why a model cannot be compiled; :func:`parameter_vector` lists the
numbers a kernel takes as its input ``p`` and :func:`symbolic_numbers` states them on symbols;
:func:`structure_key` hashes what the generated code keeps as constants (the scenes one library
serves); :func:`compiled_actuators` lists the actuator inputs ``u``.  Used by
:class:`ctmm.compiled_scene.CompiledScene`.

Loops closed inside the step (:class:`ctmm.compiled_loops.ClosedLoops`) append their numbers to ``p``
(:func:`loop_parameter_layout`, :func:`symbolic_loop_numbers`): each loop's static gain or controller
realisation ``(A, B, C, D)`` and its reference's signal parameters, so one library serves every gain,
controller coefficient and reference of a loop structure.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .errors import ModelError
from .planar.body_forms import PlanarScene, SceneNumbers
from .planar.deformable import DeformableBody
from .planar.elements import DrivenHinge, Hinge
from .planar.model import BUSHING, REVOLUTE, PlanarModel
from .planar.ports import PlanarPorts
from .signals import SYMBOLIC_FIELDS, Constant, signal_parameters, symbolic_signal

__all__ = ["LoopNumbers", "compile_refusal", "compiled_actuators", "constants_key", "loop_parameter_layout",
           "moving_drives", "parameter_vector", "station_loads", "structure_key", "symbolic_drives",
           "symbolic_loop_numbers", "symbolic_numbers"]


def compile_refusal(model: Any, *, driven_signals: bool = False) -> str:
    """Why ``model`` cannot be compiled by :class:`CompiledScene` (empty string when it can).

    Parameters
    ----------
    model : object
        A :class:`~ctmm.planar.model.PlanarModel` compiles when its time signals have a symbolic form, its hinge
        laws a casadi form and its beams no time-dependent loads or modal force hooks.
    driven_signals : bool
        ``True``: driven hinges may move by signals with a symbolic form (:data:`ctmm.signals.SYMBOLIC_FIELDS`;
        the generated RK4 of :class:`~ctmm.compiled_scene.CompiledScene`, with or without loops and over
        parameter sets, states their angle, rate and acceleration on its time symbol); ``False``: every driven
        hinge must be constant (a fixed mounting; the paths that state the model at one time or export it).
    """
    if not isinstance(model, PlanarModel):
        return f"a ctmm.planar.PlanarModel is compiled, got {type(model).__name__}"
    moving = [model.joint_names[j] for j, _ in moving_drives(model)]
    if moving and not driven_signals:
        return (f"model {model.name!r} has driven hinges whose motion is not constant: {', '.join(map(repr, moving))} "
                "(this generated path takes a driven hinge's constant angle only, as a fixed mounting; the generated "
                "RK4 and DT-TMM schemes of a planar model without kinematic loops follow ctmm.signals drives, Ramp "
                "and Harmonic included; or use the numpy path, compiled=False)")
    reasons = [f"time-dependent signals without a symbolic form in {name!r}"
               for name in [model.joint_names[j] for j, hinge in moving_drives(model)
                            if any(signal_parameters(f) is None for f in _drive_signals(hinge))]
               + _time_dependent_elements(model)]
    laws = [f"{model.joint_names[j]!r} ({law!r})" for j, hinge in model.nonlinear_hinges.items()
            for law in (hinge.moment_law, hinge.radial_law) if law is not None and not law.expressible]
    if laws:
        return (f"model {model.name!r} has nonlinear hinge laws without a casadi form: {', '.join(laws)} (user code "
                "with given derivatives; give CallableLaw a casadi-compatible force and no derivatives, or use the "
                "numpy path, compiled=False)")
    forces = [repr(model.body_names[j]) for j, beam in model.beams.items()
              if getattr(beam, "nonlinear_force", None) is not None]
    if forces:
        return (f"model {model.name!r} has subsystems with a nonlinear_force: {', '.join(forces)} (Python code "
                "f(u, u_dot, t), which generated kernels cannot evaluate; use the numpy path, compiled=False)")
    for j, beam in model.beams.items():
        data = beam.data
        if not data.constant_distributed or data.forces or data.laws:
            reasons.append(f"time-dependent loads or modal force hooks on beam {model.body_names[j]!r}")
    if reasons:
        return (f"model {model.name!r} has " + "; ".join(reasons) + " (Python callables of time, not compiled; "
                "use ctmm.signals Constant, Harmonic, Step, SquareWave or Ramp, or the numpy path, compiled=False)")
    try:
        PlanarScene(model)
    except ModelError as exc:
        return str(exc)
    return ""


def _time_dependent_elements(model: PlanarModel) -> list[str]:
    """Names of the elements with a time signal that the generated code cannot evaluate (driven hinges aside,
    :func:`compile_refusal`): hinge references and torques and rigid-body loads
    without a symbolic form (:data:`ctmm.signals.SYMBOLIC_FIELDS`: user callables), beam loads that are
    not constant."""
    names = []
    for element in model.elements:
        symbolic: list = []
        constant: list = []
        if isinstance(element, DrivenHinge):      # moving drives: compile_refusal
            pass
        elif isinstance(element, Hinge):
            symbolic = list(element.law()[2:])
        loads = [f for load in getattr(element, "loads", ()) for f in (load.force_x, load.force_y, load.moment)]
        if isinstance(element, DeformableBody):
            constant += loads
        else:
            symbolic += loads
        if any(f is not None and not isinstance(f, Constant) for f in constant) or \
                any(f is not None and signal_parameters(f) is None for f in symbolic):
            names.append(element.name)
    return names


def parameter_vector(model: PlanarModel) -> np.ndarray:
    """The numbers of ``model`` that generated kernels take as inputs, in their order: masses, inertias,
    centres of mass, outboard points, gravity, hinge stiffnesses, dampings, then the parameters of the
    hinge references, reference rates, torques and loads (each signal's
    :func:`ctmm.signals.signal_parameters`: a constant's value, a sine's amplitude, frequency and phase,
    ...), the load points (:class:`~ctmm.planar.body_forms.SceneNumbers`, SI units) and, for every driven hinge
    whose motion is not constant (:func:`moving_drives`, in joint order), the parameters of its angle [rad], rate
    [rad/s] and acceleration [rad/s^2] signals (fixed mountings stay constants of the code).

    Raises
    ------
    ModelError
        A hinge, load or drive signal without a symbolic form (a user callable).
    """
    numbers = SceneNumbers.of(model)
    parts = [numbers.mass, numbers.inertia, np.reshape(numbers.center_of_mass, -1)]
    parts += [np.reshape(point, -1) for ends in numbers.ends for point in ends.values()]
    parts += [numbers.gravity, numbers.stiffness, numbers.damping]
    signals = _signals(model)
    signal_parts = [signal_parameters(signal) for signal in signals]
    without = [signal for signal, part in zip(signals, signal_parts) if part is None]
    if without:
        raise ModelError(f"parameter_vector: model {model.name!r} has hinge or load signals without a symbolic form "
                         f"({without[0]!r}); allowed: ctmm.signals Constant, Harmonic, Step, SquareWave, Ramp")
    drives = [signal_parameters(f) for _, hinge in moving_drives(model) for f in _drive_signals(hinge)]
    if any(part is None for part in drives):
        raise ModelError(f"parameter_vector: model {model.name!r} has driven hinges moving by signals without a "
                         "symbolic form; allowed: ctmm.signals " + ", ".join(kind.__name__ for kind in SYMBOLIC_FIELDS))
    parts += signal_parts + [np.reshape(numbers.load_point, -1)] + drives
    return np.concatenate([np.asarray(part, dtype=float).reshape(-1) for part in parts])


def _signals(model: PlanarModel) -> list:
    """The hinge references, reference rates and torques (per body, its inboard joint; zero for other
    joints) and the rigid-body load components ``(fx, fy, moment)`` of ``model``, in
    :func:`parameter_vector` order."""
    by_name = {getattr(element, "name", None): element for element in model.elements}
    zero = Constant(0.0)
    laws = []
    for name, kind in zip(model.joint_names, model.joint_kind):
        element = by_name.get(name)
        if kind in (REVOLUTE, BUSHING) and isinstance(element, Hinge):     # bushings: their rotary law
            laws.append(tuple(zero if f is None else f for f in element.law()[2:]))
        else:
            laws.append((zero, zero, zero))
    loads = [f for name in model.body_names for load in getattr(by_name[name], "loads", ())
             for f in (load.force_x, load.force_y, load.moment)]
    return [law[c] for c in range(3) for law in laws] + loads


def symbolic_numbers(model: PlanarModel, p: Any, t: Any) -> SceneNumbers:
    """:class:`SceneNumbers` of entries of the symbol column ``p`` (:func:`parameter_vector` order) at
    the time symbol ``t``: signals by their symbolic form; the entries that are zero in ``model`` are
    the constant 0.  ``p = None``: every entry the model's number (constants of the code)."""
    nb, nl = model.n_bodies, len(model.load_body)
    # the model's zeros stay constants of the code (part of the structure): a smooth hinge, a centred
    # mass, a zero gravity component cost nothing, as when every number was a constant
    values = parameter_vector(model)
    entries = list(values) if p is None else [0.0 if value == 0.0 else p[k] for k, value in enumerate(values)]
    cursor = [0]

    def take(count: int) -> list:
        start = cursor[0]
        cursor[0] += count
        return entries[start:start + count]

    def pairs(count: int) -> list:
        flat = take(2 * count)
        return [(flat[2 * k], flat[2 * k + 1]) for k in range(count)]

    mass, inertia, com = take(nb), take(nb), pairs(nb)
    ends = [dict(zip(points, pairs(len(points)))) for points in model.ends]
    gravity = take(2)
    stiffness, damping = take(nb), take(nb)
    values = [symbolic_signal(type(signal), t, take(len(SYMBOLIC_FIELDS[type(signal)])))
              for signal in _signals(model)]
    reference, reference_rate, torque = values[:nb], values[nb:2 * nb], values[2 * nb:3 * nb]
    loads = [values[3 * nb + 3 * k:3 * nb + 3 * k + 3] for k in range(nl)]
    load_point = pairs(nl)
    driven = {i: values for i, *values in model.driven(0.0)}           # fixed mountings: constants of the code
    for j, hinge in moving_drives(model):
        driven[j] = tuple(symbolic_signal(type(f), t, take(len(SYMBOLIC_FIELDS[type(f)])))
                          for f in _drive_signals(hinge))
    return SceneNumbers(mass, inertia, com, ends, gravity, stiffness, damping, reference, reference_rate, torque,
                        loads, load_point, driven)


def moving_drives(model: PlanarModel) -> list[tuple[int, DrivenHinge]]:
    """``(body, hinge)`` of every driven hinge of ``model`` whose angle, rate or acceleration is not a
    :class:`~ctmm.signals.Constant` (fixed mountings are constants), in joint order."""
    by_name = {getattr(element, "name", None): element for element in model.elements}
    return [(j, by_name[name]) for j, name in enumerate(model.joint_names)
            if isinstance(by_name.get(name), DrivenHinge)
            and any(not isinstance(f, Constant) for f in _drive_signals(by_name[name]))]


def _drive_signals(hinge: DrivenHinge) -> tuple:
    """The angle [rad], rate [rad/s] and acceleration [rad/s^2] signals of a driven hinge."""
    return hinge.angle, hinge.rate, hinge.acceleration


def symbolic_drives(model: PlanarModel, t: Any) -> dict[int, tuple]:
    """``{body: (angle, rate, acceleration)}`` of every driven hinge of ``model`` at the time symbol ``t``
    [rad, rad/s, rad/s^2]: the moving ones by the symbolic form of their signals with the model's numbers
    (:func:`ctmm.signals.symbolic_signal`), fixed mountings by their constants.

    Raises
    ------
    ModelError
        A moving drive's signal without a symbolic form.
    """
    driven = {i: tuple(values) for i, *values in model.driven(0.0)}
    for j, hinge in moving_drives(model):
        for f in _drive_signals(hinge):
            if signal_parameters(f) is None:
                raise ModelError(f"driven hinge {model.joint_names[j]!r} of model {model.name!r}: the signal {f!r} "
                                 "has no symbolic form; allowed: ctmm.signals "
                                 + ", ".join(kind.__name__ for kind in SYMBOLIC_FIELDS))
        driven[j] = tuple(symbolic_signal(type(f), t, signal_parameters(f)) for f in _drive_signals(hinge))
    return driven


def structure_key(model: PlanarModel) -> str:
    """SHA-256 (hex) of what a generated kernel keeps as constants: the tree, joint kinds, point and
    load layout, coordinates, actuators, ground angles, fixed mountings, the kinds of the time signals,
    which numbers are zero (constants 0 of the code), the translational springs of bushings (stiffness
    and damping of hinges with translational springs) and the modal beams' data (with gravity, which the
    beams take as a constant).  Two models with one key run on one compiled
    :class:`CompiledScene` with their own :func:`parameter_vector`; a beam whose definition holds an
    object without a value ``repr`` makes the key unique to the model (never shared)."""
    digest = hashlib.sha256()
    parts: list[Any] = [model.parent, model.joint_kind, model.ground_angle, model.theta_index, model.load_body,
                        [list(ends) for ends in model.ends], [np.asarray(idx).tolist() for idx in model.modal_index],
                        [np.asarray(idx).tolist() for idx in model.xy_index], model.n_coordinates,
                        model.parent_end, model.parent_end_index, list(compiled_actuators(model)),
                        [drive for drive in model.driven(0.0) if drive[0] not in dict(moving_drives(model))],
                        [type(signal).__name__ for signal in _signals(model)],
                        np.flatnonzero(parameter_vector(model) == 0.0),
                        [(j, repr(h.moment_law), repr(h.radial_law), h.rest_angle)
                         for j, h in sorted(model.nonlinear_hinges.items())],
                        model.translational_stiffness, model.translational_damping]
    if moving_drives(model):        # their numbers are entries of p (parameter_vector), their classes structure
        parts.append([(j, [type(f).__name__ for f in _drive_signals(hinge)]) for j, hinge in moving_drives(model)])
    # the actuators' unit patterns follow from their names (a hinge torque, a force at a centre of mass)
    # and, on beams, from the beam definitions below
    if model.beams:
        parts.append(model.gravity)
        for j, beam in sorted(model.beams.items()):
            # the beam's data derive from its definition (a dataclass of numbers and constant signals);
            # a definition whose text shows an object address makes the key unique to the model
            text = repr(beam)
            parts.append((j, text if " at 0x" not in text else f"model {id(model)}"))
    digest.update(repr(_plain(parts)).encode())
    return digest.hexdigest()


def constants_key(model: PlanarModel) -> str:
    """:func:`structure_key` and every number: the scenes a kernel with the numbers as constants serves."""
    return hashlib.sha256((structure_key(model) + repr(parameter_vector(model).tolist())).encode()).hexdigest()


def _plain(value: Any) -> Any:
    """Arrays as nested lists of Python numbers (full precision in ``repr``), recursively."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [_plain(x) for x in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def station_loads(model: PlanarModel, names: Sequence[str]) -> tuple[str, ...]:
    """The beam station forces and moments among the actuator ``names`` of ``model``, in order, each once (other and
    unknown names are left to the caller): the ``stations`` of :func:`compiled_actuators` that drive them."""
    actuators = PlanarPorts(model).actuators
    return tuple(dict.fromkeys(name for name in names if getattr(actuators.get(name), "kind", "") == "station"))


def compiled_actuators(model: PlanarModel, stations: Sequence[str] = ()) -> tuple[str, ...]:
    """The actuators a generated kernel takes as inputs ``u``: every actuator of ``model`` but the station forces and
    moments of beams, then the station loads named in ``stations`` (``"<beam>.<station>.force|moment"``).

    Each station load in ``u`` adds its modal forces and floating-frame wrench to the generated sweep
    (:mod:`ctmm.compiled_station_loads`), so only the named ones are inputs (a loop or open-loop input on another
    one reaches it as a channel of its own, :attr:`ctmm.compiled_loops.ClosedLoops.channels`).

    Raises
    ------
    ModelError
        A name in ``stations`` that is not a station force or moment of ``model`` (the message lists them).
    """
    ports = PlanarPorts(model)
    if isinstance(stations, str):
        stations = (stations,)
    allowed = [name for name, actuator in ports.actuators.items() if actuator.kind == "station"]
    for name in stations:
        if name not in allowed:
            raise ModelError(f"station input {name!r} is not a beam station force or moment of model {model.name!r}; "
                             f"allowed: {', '.join(allowed) or '(none)'}")
    return tuple(name for name, actuator in ports.actuators.items() if actuator.kind != "station") + tuple(
        dict.fromkeys(stations))


# ------------------------------------------------------------------------------------------
# numbers of the loops closed inside the step
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class LoopNumbers:
    """The numbers of one loop law on symbols (or numbers): ``u = -(C z + D e)``, ``z' = A z + B e``.

    Attributes
    ----------
    A : casadi matrix ``(k, k)``; B, C : casadi columns ``(k,)``; D : scalar
        Controller realisation; a static gain is ``D`` alone (``k = 0``).
    reference : sequence
        The reference's :func:`ctmm.signals.signal_parameters` (empty for a
        :class:`~ctmm.compiled_references.SymbolicReference`, whose numbers stay constants of the code).
    """

    A: Any
    B: Any
    C: Any
    D: Any
    reference: Sequence[Any]


def _reference_fields(reference: Any) -> tuple[str, ...]:
    """Field names of a reference with a symbolic form (none for other callables)."""
    return SYMBOLIC_FIELDS.get(type(reference), ())


def loop_parameter_layout(laws: Sequence[Any]) -> list[tuple[str, str, float]]:
    """``(name, role, value)`` of the loop numbers a generated step with loops takes after the model's
    :func:`parameter_vector`, in order, loop by loop: a static loop's ``"<loop>.gain"`` (role ``"gain"``);
    an LTI controller's realisation ``"<loop>.A[i,j]"`` (row by row), ``"<loop>.B[i]"``, ``"<loop>.C[i]"``,
    ``"<loop>.D"`` (role ``"controller"``, the state-space form of ``control.ss``, not the transfer
    function's coefficients); then every loop's reference ``"<loop>.reference"`` (one field) or
    ``"<loop>.reference.<field>"`` (role ``"reference"`` or ``"reference.<field>"``).

    ``laws`` are :class:`~ctmm.compiled_loops.LoopLaw` objects (``name``, ``A``, ``B``, ``C``, ``D``,
    ``reference``).
    """
    layout: list[tuple[str, str, float]] = []
    for law in laws:
        k = law.A.shape[0]
        if k == 0:
            layout.append((f"{law.name}.gain", "gain", float(law.D)))
            continue
        layout += [(f"{law.name}.A[{i},{j}]", "controller", float(law.A[i, j])) for i in range(k) for j in range(k)]
        layout += [(f"{law.name}.B[{i}]", "controller", float(law.B[i])) for i in range(k)]
        layout += [(f"{law.name}.C[{i}]", "controller", float(law.C[i])) for i in range(k)]
        layout.append((f"{law.name}.D", "controller", float(law.D)))
    for law in laws:
        fields = _reference_fields(law.reference)
        values = signal_parameters(law.reference) if fields else ()
        if len(fields) == 1:
            layout.append((f"{law.name}.reference", "reference", float(values[0])))
        else:
            layout += [(f"{law.name}.reference.{field}", f"reference.{field}", float(value))
                       for field, value in zip(fields, values)]
    return layout


def symbolic_loop_numbers(laws: Sequence[Any], theta: Any) -> list[LoopNumbers]:
    """:class:`LoopNumbers` of every law from the entries of ``theta`` (a casadi column in
    :func:`loop_parameter_layout` order, or ``None``: the laws' own numbers as constants)."""
    import casadi as ca

    if theta is None:
        theta = ca.DM([value for _, _, value in loop_parameter_layout(laws)])
    cursor = [0]

    def take(count: int) -> Any:
        start = cursor[0]
        cursor[0] += count
        return theta[start:start + count]

    gains = []
    for law in laws:
        k = law.A.shape[0]
        if k == 0:
            gains.append((ca.DM(0, 0), ca.DM(0, 1), ca.DM(0, 1), take(1)))
        else:
            A = ca.reshape(take(k * k), k, k).T                  # stored row by row
            gains.append((A, take(k), take(k), take(1)))
    numbers = []
    for law, (A, B, C, D) in zip(laws, gains):
        count = len(_reference_fields(law.reference))
        reference = take(count) if count else None
        numbers.append(LoopNumbers(A, B, C, D, [] if reference is None else [reference[i] for i in range(count)]))
    return numbers
