"""Named numbers of a system and the same system with other numbers (issue 13: parameter sets).

A generated kernel with its numbers as inputs (:mod:`ctmm.compiled_parameters`,
:mod:`ctmm.compiled_spatial_parameters`, the loops' :func:`~ctmm.compiled_parameters.loop_parameter_layout`)
serves every system of one structure.  This module names the numbers a user may change
(:func:`parameter_names`) and builds the system with changed numbers (:func:`with_parameters`), so
that the result of a run is computed from a model that holds those numbers (its sensors, its loop
signals), not from the model the kernel was generated for.

Names:

* planar plants: ``"<body>.mass"``, ``"<body>.inertia"`` (rigid bodies), ``"gravity.x|y"`` (without
  modal beams), ``"<joint>.stiffness"``, ``"<joint>.damping"``, ``"<joint>.law.reference[.<field>]"``
  (``reference_rate``, ``torque``) and ``"<body>.load<k>.force_x[.<field>]"`` (``force_y``,
  ``moment``) -- the names of :func:`ctmm.fmu_export_model.parameter_names` that it exposes (geometry
  and the data of modal beams stay constants of the code);
* spatial plants: :func:`~ctmm.compiled_spatial_parameters.spatial_parameter_layout` (masses, non-zero
  inertia entries, the non-zero numbers of modal beams, 1-/2-DOF joint laws, gravity; a beam's length and
  mode counts are refused with that reason: its shapes depend on them; a model with finite-element
  subsystems has no parameters here, refused by name);
* loops: ``"<loop>.gain"`` of every loop with a static gain and, given the run's ``references``, each
  loop's reference ``"<loop>.reference"`` (a number or constant) or ``"<loop>.reference.<field>"`` (a
  :mod:`ctmm.signals` signal with a symbolic form: ``amplitude``, ``omega``, ``phase``, ...).

A number that is zero in the system is a constant 0 of the generated code (part of its structure):
it is not a parameter, and a parameter may not be set to 0 (refused, naming it) -- but loop gains and
references and the references of sprung spatial joints, which are entries of ``p`` whatever their
value.  Every built system is certified: its kernel parameter vector equals the original one with
exactly the named entries replaced, else :class:`~ctmm.errors.ModelError` (never a silently different
model).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .compiled_parameters import parameter_vector, structure_key
from .compiled_spatial_beam_numbers import BEAM_NUMBERS, beam_numbers
from .compiled_spatial_parameters import (INERTIA_ENTRIES, spatial_parameter_layout, spatial_parameter_vector,
                                          unparametrised_refusal)
from .control.controlled_model import ControlledModel
from .errors import ModelError
from .planar.model import PlanarModel
from .signals import SYMBOLIC_FIELDS, as_signal, signal_parameters
from .spatial.beam import SpatialBeam
from .spatial.model import SpatialModel

_BEAM_KINDS = tuple(kind for kind, _ in BEAM_NUMBERS)

__all__ = ["ParameterSpace", "parameter_names", "parameter_set_list", "parameter_values", "plant_and_loops",
           "with_parameters"]

_HINGE_FIELDS = {"stiffness": ("stiffness", "kp"), "damping": ("damping", "kd"),
                 "reference": ("reference", "rest_angle"), "reference_rate": ("reference_rate",),
                 "torque": ("torque",)}
"""Element attributes holding a hinge law's number, by the law entry's name (the first one present)."""


def plant_and_loops(system: Any) -> tuple[PlanarModel | SpatialModel, tuple]:
    """``(plant, loops)`` of a planar or spatial model or of a controlled one (``plant`` and ``loops``
    attributes, e.g. :func:`ctmm.control.with_feedback`).

    Raises
    ------
    ModelError
        Any other system (chains keep their numbers as constants of their generated code).
    """
    if isinstance(system, (PlanarModel, SpatialModel)):
        return system, ()
    plant = getattr(system, "plant", None)
    if isinstance(plant, (PlanarModel, SpatialModel)) and hasattr(system, "loops"):
        return plant, tuple(system.loops)
    raise ModelError(f"system must be a planar or spatial model, with or without loops (parameters apply to their "
                     f"generated kernels); got {type(system).__name__} ({system!r:.60}) (1-D chains keep their numbers as constants of their "
                     "kernel: build the chain with the numbers)")


class ParameterSpace:
    """The named numbers of one system (module docstring) and that system with other numbers.

    Parameters
    ----------
    system : PlanarModel, SpatialModel or controlled model
    references : mapping, optional
        ``{loop: number or signal}`` of a run (default 0): their fields are parameters too.

    Attributes
    ----------
    names : dict of str to (str, float)
        ``{name: (unit, value)}`` a run may set, in the order of the kernel's parameter vector, the
        loops' last.
    """

    def __init__(self, system: Any, references: Mapping[str, Any] | None = None) -> None:
        self.system = system
        self.plant, self.loops = plant_and_loops(system)
        plant = self.plant
        if isinstance(plant, SpatialModel):
            refusal = unparametrised_refusal(plant, "parameters")
            if refusal:             # a finite-element body's numbers would be read as a rigid body's
                raise ModelError(refusal)
            layout = spatial_parameter_layout(plant)
            self._order = [entry.name for entry in layout]
            self._layout = {entry.name: entry for entry in layout}
            self.names = {entry.name: (entry.unit, entry.value) for entry in layout}
            # entries of p whatever their value: the references of sprung joints
            free = {entry.name for entry in layout if entry.kind == "reference"}
        else:
            from .fmu_export_model import parameter_names as planar_names

            vector = parameter_vector(plant)
            entries = planar_names(plant)
            self._order = [name for name, _, _ in entries]
            self._structure = structure_key(plant)
            self.names = {name: (unit, float(value)) for (name, unit, exposed), value in zip(entries, vector)
                          if exposed and value != 0.0}
            free = set()
        self._vector = spatial_parameter_vector(plant) if isinstance(plant, SpatialModel) else vector
        self._gains = {f"{loop.name}.gain": loop.name for loop in self.loops if not loop.is_lti}
        self.names.update({name: ("", float(self.loop(loop).gain)) for name, loop in self._gains.items()})
        if references is not None and not isinstance(references, Mapping):
            raise ModelError(f"references must be a mapping {{loop name: number or signal}} or None, got {references!r:.80}")
        self.references = dict(references or {})
        self._signals = {loop.name: as_signal(f"references[{loop.name!r}]", self.references.get(loop.name, 0.0))
                         for loop in self.loops}
        self._fields: dict[str, tuple[str, str]] = {}          # name -> (loop, field of its reference)
        for loop, signal in self._signals.items():
            fields = SYMBOLIC_FIELDS.get(type(signal), ())
            for field, value in zip(fields, signal_parameters(signal) or ()):
                name = f"{loop}.reference" + (f".{field}" if len(fields) > 1 else "")
                self._fields[name] = (loop, field)
                self.names[name] = ("", float(value))
        self._free = free | set(self._gains) | set(self._fields)

    def loop(self, name: str) -> Any:
        """The loop ``name`` of the system."""
        return next(loop for loop in self.loops if loop.name == name)

    def check(self, values: Mapping[str, Any]) -> dict[str, float]:
        """``values`` checked against :attr:`names`: known names, finite numbers, none zero (a zero is a
        constant of the code) but loop gains and references and spatial joint references."""
        if not isinstance(values, Mapping):
            raise ModelError(f"parameters must be a mapping {{name: number}}, got {values!r}")
        checked = {}
        for name, value in values.items():
            if name not in self.names:
                _refuse_beam_structure(self.plant, name)
                shown = ", ".join(list(self.names)[:60]) + (" ..." if len(self.names) > 60 else "")
                raise ModelError(f"parameters: unknown parameter {name!r}; allowed: {shown or '(none)'} (numbers that "
                                 "are zero in the model, geometry and the data of modal beams are constants of the "
                                 "generated code: build a model with them instead)")
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not math.isfinite(value):
                raise ModelError(f"parameters[{name!r}] must be a finite number [{self.names[name][0] or '-'}], got "
                                 f"{value!r}")
            if value == 0.0 and name not in self._free:
                raise ModelError(f"parameters[{name!r}] = 0: a zero number is a constant 0 of the generated code (part "
                                 "of its structure), not a parameter; build the model with it, or give a non-zero "
                                 "value")
            checked[name] = float(value)
        return checked

    def system_with(self, values: Mapping[str, Any]) -> Any:
        """The system with the numbers ``values`` (``{name: number}``), everything else the same: a
        :class:`PlanarModel`, :class:`SpatialModel` or :class:`ControlledModel` of the same structure.

        Raises
        ------
        ModelError
            Unknown names (the allowed ones listed), non-finite or zero values, an element whose class
            keeps the number where this class does not set it (certified, module docstring).
        """
        checked = self.check(values)
        plant_values = {name: value for name, value in checked.items()
                        if name not in self._gains and name not in self._fields}
        if not plant_values:
            changed = self.plant
        elif isinstance(self.plant, SpatialModel):
            changed = _spatial(self.plant, plant_values, self._layout)
        else:
            changed = _planar(self.plant, plant_values)
        expected = self._vector.copy()
        expected[[self._order.index(name) for name in plant_values]] = list(plant_values.values())
        if isinstance(changed, SpatialModel):
            same = [entry.name for entry in spatial_parameter_layout(changed)] == self._order
            _certify(changed.name, spatial_parameter_vector(changed) if same else np.zeros(0), expected, same)
        else:
            _certify(changed.name, parameter_vector(changed), expected, structure_key(changed) == self._structure)
        if not self.loops and self.system is self.plant:
            return changed
        gains = {self._gains[name]: value for name, value in checked.items() if name in self._gains}
        loops = [loop.with_parameters(gain=gains[loop.name]) if loop.name in gains else loop for loop in self.loops]
        return ControlledModel(changed, loops)

    def references_with(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """The run's references with the reference fields of ``values`` set (:meth:`check`ed)."""
        signals = dict(self._signals)
        changed = set()
        for name, value in self.check(values).items():
            if name in self._fields:
                loop, field = self._fields[name]
                signals[loop] = dataclasses.replace(signals[loop], **{field: value})
                changed.add(loop)
        return {**self.references, **{loop: signals[loop] for loop in changed}}


def parameter_names(system: Any, references: Mapping[str, Any] | None = None) -> dict[str, tuple[str, float]]:
    """``{name: (unit, value)}`` of the numbers of ``system`` that a run may set (module docstring), in
    the order of the kernel's parameter vector, the loops' last (:class:`ParameterSpace`; ``references``
    of a run add the loops' reference fields)."""
    return ParameterSpace(system, references).names


def parameter_values(system: Any, values: Mapping[str, Any]) -> dict[str, float]:
    """``values`` checked against :func:`parameter_names` of ``system`` (:meth:`ParameterSpace.check`)."""
    return ParameterSpace(system).check(values)


def with_parameters(system: Any, values: Mapping[str, Any]) -> Any:
    """``system`` with the numbers ``values`` (:meth:`ParameterSpace.system_with`)."""
    return ParameterSpace(system).system_with(values)


def _planar(model: PlanarModel, values: Mapping[str, float]) -> PlanarModel:
    """The planar model with the named numbers replaced (certified by the caller)."""
    elements = {element.name: element for element in model.elements}
    gravity = np.array(model.gravity, dtype=float)
    for name, value in values.items():
        owner, _, rest = name.partition(".")
        parts = rest.split(".")
        if owner == "gravity":
            gravity["xy".index(parts[0])] = value
        elif parts[0] in ("mass", "inertia"):
            elements[owner] = dataclasses.replace(elements[owner], **{parts[0]: value})
        elif parts[0] in ("stiffness", "damping"):
            elements[owner] = _set_attribute(elements[owner], _HINGE_FIELDS[parts[0]], None, value, name)
        elif parts[0] == "law":
            elements[owner] = _set_attribute(elements[owner], _HINGE_FIELDS[parts[1]], parts[2:], value, name)
        else:                                   # "load<k>.<part>[.<field>]"
            element, k = elements[owner], int(parts[0][len("load"):])
            loads = list(element.loads)
            loads[k] = _set_attribute(loads[k], (parts[1],), parts[2:], value, name)
            elements[owner] = dataclasses.replace(element, loads=tuple(loads))
    return PlanarModel(model.name, [elements[element.name] for element in model.elements], gravity=gravity)


def _set_attribute(element: Any, attributes: tuple[str, ...], field: list[str] | None, value: float,
                   name: str) -> Any:
    """``element`` with the first of ``attributes`` it has set to ``value`` (a number) or, for a signal,
    with the signal's ``field`` (its only field when ``field`` is empty) set to ``value``."""
    attribute = next((a for a in attributes if hasattr(element, a)), None)
    if attribute is None:
        raise ModelError(f"parameters[{name!r}]: element {getattr(element, 'name', element)!r} "
                         f"({type(element).__name__}) has none of {attributes}; build the model with the number")
    current = getattr(element, attribute)
    if field is None or (not field and isinstance(current, (int, float))):
        return dataclasses.replace(element, **{attribute: value})
    fields = SYMBOLIC_FIELDS.get(type(current), ())
    chosen = field[0] if field else (fields[0] if len(fields) == 1 else None)
    if chosen not in fields:
        raise ModelError(f"parameters[{name!r}]: the signal {current!r} has the fields {fields}")
    return dataclasses.replace(element, **{attribute: dataclasses.replace(current, **{chosen: value})})


def _spatial(model: SpatialModel, values: Mapping[str, float], layout: Mapping[str, Any]) -> SpatialModel:
    """The spatial model with the named numbers (entries of ``layout`` by name) replaced (certified by the
    caller)."""
    joints = list(model.joints)
    # a body's numbers are replaced at once (its inertia is checked as a whole, not entry by entry)
    bodies = [{} if isinstance(body, SpatialBeam) else {"mass": body.mass, "inertia": np.array(body.inertia, dtype=float)}
              for body in model.bodies]
    gravity = np.array(model.gravity, dtype=float)
    for name, value in values.items():
        entry = layout[name]
        if entry.kind == "gravity":
            gravity[entry.entry] = value
        elif entry.kind == "mass":
            bodies[entry.index]["mass"] = value
        elif entry.kind == "inertia":
            _, a, b = INERTIA_ENTRIES[entry.entry]
            bodies[entry.index]["inertia"][a, b] = bodies[entry.index]["inertia"][b, a] = value
        elif entry.kind in _BEAM_KINDS:          # a modal beam's number (ctmm.compiled_spatial_beam_numbers)
            bodies[entry.index][entry.kind] = value
        else:                                   # stiffness, damping, reference of a 1- or 2-DOF joint
            joint = joints[entry.index]
            numbers = np.array(getattr(joint, entry.kind), dtype=float).reshape(-1)
            numbers[entry.entry] = value
            joints[entry.index] = dataclasses.replace(joint, **{entry.kind: numbers if numbers.size > 1 else
                                                                float(numbers[0])})
    touched = {layout[name].index for name in values if layout[name].kind in ("mass", "inertia") + _BEAM_KINDS}
    bodies = [dataclasses.replace(body, **bodies[j]) if j in touched else body for j, body in enumerate(model.bodies)]
    return SpatialModel(model.name, bodies + joints + list(model.loads), gravity=gravity)


def _refuse_beam_structure(plant: Any, name: str) -> None:
    """Refuse ``"<beam>.<attribute>"`` of a modal spatial beam's number that is not a parameter (its length,
    mode counts, ...) with the reason, not as an unknown name."""
    owner, _, attribute = name.partition(".")
    beam = next((body for body in getattr(plant, "bodies", ()) if isinstance(body, SpatialBeam) and body.name == owner),
                None)
    if beam is None or attribute in _BEAM_KINDS or not hasattr(beam, attribute):
        return
    reason = "its mode shapes depend on it" if attribute == "length" else "it sets the beam's modes"
    allowed = ", ".join(f"{owner}.{kind}" for kind, _, _ in beam_numbers(beam))
    raise ModelError(f"parameters[{name!r}]: the {attribute} of beam {beam.name!r} is part of the compiled structure "
                     f"({reason}), not a parameter; build the model with it and run it without "
                     f"parameters= (the beam's parameters: {allowed or '(none)'})")


def _certify(name: str, got: np.ndarray, expected: np.ndarray, same_structure: bool) -> None:
    """Refuse a built model whose parameter vector is not the expected one, or whose structure changed."""
    if not same_structure or got.shape != expected.shape or not np.array_equal(got, expected):
        raise ModelError(f"parameters: model {name!r} with the given numbers does not have the expected parameter "
                         "vector or structure (an element class that keeps the number elsewhere); build the model "
                         "with these numbers and run it without parameters=")


def parameter_set_list(parameter_sets: Any) -> list[dict]:
    """A list of ``{name: number}`` from a sequence of mappings or a mapping of equally long columns
    ``{name: [value per set]}`` (the ``parameter_sets`` of :func:`ctmm.simulate_batch`; names checked later).

    Raises
    ------
    ModelError
        Neither form, empty, columns of different lengths or with non-finite values.
    """
    if isinstance(parameter_sets, Mapping):
        columns = {name: np.atleast_1d(validation.finite_array(f"parameter_sets[{name!r}]", values))
                   for name, values in parameter_sets.items()}
        lengths = {column.shape for column in columns.values()}
        if len(lengths) != 1 or len(next(iter(lengths))) != 1 or next(iter(lengths))[0] < 1:
            raise ModelError(f"parameter_sets as a mapping must hold equally long 1-D columns (non-empty) {{name: "
                             f"[value per set]}}, got shapes {sorted(lengths)}: {parameter_sets!r:.80}")
        count = next(iter(lengths))[0]
        return [{name: float(column[k]) for name, column in columns.items()} for k in range(count)]
    if isinstance(parameter_sets, (str, bytes)) or not isinstance(parameter_sets, Sequence) or not parameter_sets \
            or not all(isinstance(values, Mapping) for values in parameter_sets):
        raise ModelError(f"parameter_sets must be a non-empty sequence of mappings {{name: number}} or a mapping "
                         f"{{name: [value per set]}}, got {parameter_sets!r}")
    return [dict(values) for values in parameter_sets]
