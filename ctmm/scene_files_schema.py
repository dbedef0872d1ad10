"""The schema of scene files, generated from the Python constructors (no second list to maintain).

A scene file (:mod:`ctmm.scene_files`) names Python constructors: ``type = "RigidBody"`` in a table
means ``ctmm.planar.RigidBody(**the other keys)``. The allowed ``type`` values of each system kind
are the public element classes of its package (``ctmm.elements``, ``ctmm.planar`` and
``ctmm.flexible``, ``ctmm.spatial``), the allowed keys of each type the parameters of its
constructor (:func:`inspect.signature`, i.e. the dataclass fields), and the allowed keys of the
study those of the verb (``ctmm.simulate`` ...). A new element class or field is therefore in the
schema as soon as it is exported. A few builders that are not classes are named here so that the
shipped scenarios can be files: :func:`finite_element_subsystem` (a ``ctmm.fem`` model as a planar
body), ``finite_segment_beam`` (one table, several elements), :func:`closed_planar_model` (``kind =
"planar_closed"``), :func:`spin_up_law` and :func:`parallel_law` (values); the FMU controller's keys
come from ``FMUController`` (:func:`controller_kinds`). ``docs/scene_files.md`` holds
:func:`schema_markdown` (checked by a test); :func:`json_schema` states the same as a JSON Schema
(draft 2020-12; ``ctmm scene schema`` writes it) for editors and other tools.
"""
from __future__ import annotations

import dataclasses
import importlib
import inspect
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

__all__ = ["Parameter", "Constructor", "SYSTEM_KINDS", "VERBS", "element_types", "value_types", "loop_types",
           "controller_kinds", "system_constructor", "verb", "constructor", "schema_markdown", "json_schema",
           "JSON_SCHEMA_DIALECT", "transfer_function", "finite_element_subsystem", "closed_planar_model", "spin_up_law",
           "parallel_law"]


@dataclass(frozen=True)
class Parameter:
    """One key of a table: the constructor parameter it maps to.

    Attributes
    ----------
    name : str
        Key (= parameter name).
    required : bool
        No default in the constructor (a parameter that admits ``None`` may be left out: TOML has
        no null, leaving the key out gives ``None``).
    annotation : str
        The parameter's type annotation, as text.
    default : str
        ``repr`` of the default (``""`` when required).
    """

    name: str
    required: bool
    annotation: str
    default: str


@dataclass(frozen=True)
class Constructor:
    """A ``type`` of a scene table: the callable it names and its keys.

    Attributes
    ----------
    name : str
        The ``type`` value (``"RigidBody"``, ``"RigidBody.uniform_link"``).
    target : callable
        What is called with the table's keys.
    parameters : tuple of Parameter
        Its keys, in signature order.
    open : bool
        The callable also takes further keyword options (``**options``): keys not listed are passed
        on and checked by the callable itself.
    """

    name: str
    target: Callable[..., Any]
    parameters: tuple[Parameter, ...]
    open: bool = False

    def keys(self) -> list[str]:
        """Allowed keys, in signature order."""
        return [p.name for p in self.parameters]

    def required(self) -> list[str]:
        """Keys that must be given (no default, ``None`` not allowed)."""
        return [p.name for p in self.parameters if p.required and "None" not in p.annotation]


def _annotation(parameter: inspect.Parameter) -> str:
    annotation = parameter.annotation
    if annotation is inspect.Parameter.empty:
        return ""
    return annotation if isinstance(annotation, str) else getattr(annotation, "__name__", str(annotation))


def constructor(name: str, target: Callable[..., Any], skip: tuple[str, ...] = ()) -> Constructor:
    """The :class:`Constructor` of ``target`` from its signature (``self``, ``_`` markers and
    ``skip`` left out)."""
    parameters, open_ = [], False
    for parameter in inspect.signature(target).parameters.values():
        if parameter.kind is inspect.Parameter.VAR_KEYWORD:
            open_ = True
            continue
        if parameter.kind is inspect.Parameter.VAR_POSITIONAL or parameter.name in ("self", "_") \
                or parameter.name in skip:
            continue
        required = parameter.default is inspect.Parameter.empty
        parameters.append(Parameter(parameter.name, required, _annotation(parameter),
                                    "" if required else repr(parameter.default)))
    return Constructor(name, target, tuple(parameters), open_)


def _public_classes(module_name: str, accept: Callable[[type], bool]) -> dict[str, type]:
    module = importlib.import_module(module_name)
    found = {}
    for name in getattr(module, "__all__", ()):
        item = getattr(module, name, None)
        if inspect.isclass(item) and not name.startswith("_") and not inspect.isabstract(item) and accept(item):
            found[name] = item
    return found


def _with_factories(classes: dict[str, type]) -> dict[str, Constructor]:
    """Constructors of the classes and of their public ``classmethod`` factories (``"Class.factory"``)."""
    out = {}
    for name, cls in sorted(classes.items()):
        out[name] = constructor(name, cls)
        for attribute, member in vars(cls).items():
            if isinstance(member, classmethod) and not attribute.startswith("_"):
                out[f"{name}.{attribute}"] = constructor(f"{name}.{attribute}", getattr(cls, attribute))
    return out


def _is_chain_element(cls: type) -> bool:
    from .elements.base import Element

    return issubclass(cls, Element) and cls.__module__ != "ctmm.elements.base" \
        and cls.__name__ not in ("Boundary",)


def _is_planar_element(cls: type) -> bool:
    return dataclasses.is_dataclass(cls) and cls.__module__.startswith(("ctmm.planar.elements", "ctmm.flexible.beam"))


def _is_spatial_element(cls: type) -> bool:
    return dataclasses.is_dataclass(cls) and cls.__module__ in ("ctmm.spatial.elements", "ctmm.spatial.beam")


def finite_element_subsystem(name: str, nodes: dict, elements: list, boundary: list, *,
                             rayleigh: tuple[float, float] = (0.0, 0.0), frame_nodes: tuple[str, ...] = ()) -> Any:
    """A ``ctmm.fem`` model as a body of a planar model:
    ``FiniteElementModel(name, nodes, elements, rayleigh=rayleigh).subsystem(name, boundary, frame_nodes=frame_nodes)``.

    Parameters
    ----------
    name : str
        Model and body name.
    nodes : dict of str to (x, y)
        Undeformed node positions [m].
    elements : list
        ``BeamElement``, ``PointMass``, ``NodeSpring``, ``MembraneElement`` (value tables ``{type = ...}``).
    boundary : list of str
        Boundary nodes, the inboard one first.
    rayleigh : (float, float)
        Rayleigh damping ``(a [1/s], b [s])``.
    frame_nodes : sequence of str
        Nodes held in the frame.
    """
    from .fem import FiniteElementModel

    model = FiniteElementModel(name, nodes, elements, rayleigh=rayleigh)
    return model.subsystem(name, boundary, frame_nodes=tuple(frame_nodes))


def closed_planar_model(name: str, elements: list, cuts: list, *, gravity: tuple[float, float] = (0.0, -9.81),
                        baumgarte: float = 20.0) -> Any:
    """A planar tree closed by cut joints: ``KinematicLoopModel(PlanarModel(name, elements, gravity=gravity),
    cuts, baumgarte=baumgarte)``.

    Parameters
    ----------
    name : str
        Model name.
    elements : list
        The tree's elements (as for ``kind = "planar"``).
    cuts : list of CutJoint
        The loop-closing joints (value tables ``{type = "CutJoint", ...}``).
    gravity : (float, float)
        [m/s^2].
    baumgarte : float
        Constraint stabilisation rate [1/s] of ``KinematicLoopModel``.
    """
    from .planar.closed_loops import KinematicLoopModel
    from .planar.model import PlanarModel

    return KinematicLoopModel(PlanarModel(name, elements, gravity=gravity), cuts, baumgarte=baumgarte)


def closed_spatial_model(name: str, elements: list, cuts: list, *, gravity: tuple[float, float, float] = (0.0, 0.0, -9.81),
                         baumgarte: float = 20.0) -> Any:
    """A spatial tree closed by cut joints: ``SpatialKinematicLoopModel(SpatialModel(name, elements,
    gravity=gravity), cuts, baumgarte=baumgarte)`` (``docs/closed_loops.md`` §8).

    Parameters
    ----------
    name : str
        Model name.
    elements : list
        The tree's elements (as for ``kind = "spatial"``).
    cuts : list of SpatialCutJoint
        The loop-closing joints (value tables ``{type = "SpatialCutJoint", ...}``).
    gravity : (float, float, float)
        [m/s^2].
    baumgarte : float
        Constraint stabilisation rate [1/s].
    """
    from .spatial.closed_loops import SpatialKinematicLoopModel
    from .spatial.model import SpatialModel

    return SpatialKinematicLoopModel(SpatialModel(name, elements, gravity=gravity), cuts, baumgarte=baumgarte)


def parallel_law(laws: list) -> Any:
    """Laws acting in parallel (their forces added): ``ctmm.nonlinear_laws.ParallelLaw(*laws)``, as ``law1 + law2``."""
    from .nonlinear_laws import ParallelLaw

    return ParallelLaw(*laws)


SPIN_UP_QUANTITIES = ("angle", "rate", "acceleration")


def spin_up_law(final_rate: float, ramp_time: float, quantity: str) -> Callable[[float], float]:
    """One function of ``ctmm.flexible.outputs.spinup_law(final_rate, ramp_time)``: the hub ``"angle"`` [rad],
    ``"rate"`` [rad/s] or ``"acceleration"`` [rad/s^2] of the Kane-Ryan-Banerjee spin-up, for ``DrivenHinge``."""
    from .errors import ModelError
    from .flexible.outputs import spinup_law

    if quantity not in SPIN_UP_QUANTITIES:
        raise ModelError(f"quantity must be one of {', '.join(SPIN_UP_QUANTITIES)}, got {quantity!r}")
    return spinup_law(final_rate, ramp_time)[SPIN_UP_QUANTITIES.index(quantity)]


SYSTEM_KINDS: dict[str, tuple[str, str]] = {
    "chain": ("ctmm.system:Chain", "1-D chain, elements in order from the start boundary"),
    "planar": ("ctmm.planar.model:PlanarModel", "planar tree: every hinge names its parent and child"),
    "planar_chain": ("ctmm.planar.model:PlanarModel.chain", "planar serial chain: hinge connections from the "
                     "element order"),
    "spatial": ("ctmm.spatial.model:SpatialModel", "spatial tree: every joint names its parent and child"),
    "planar_closed": ("ctmm.scene_files_schema:closed_planar_model", "planar tree closed by cut joints "
                      "(`KinematicLoopModel`): elements as for `planar`, `cuts = [{ type = \"CutJoint\", ... }]`"),
    "spatial_closed": ("ctmm.scene_files_schema:closed_spatial_model", "spatial tree closed by cut joints "
                       "(`SpatialKinematicLoopModel`): elements as for `spatial`, "
                       "`cuts = [{ type = \"SpatialCutJoint\", ... }]`"),
}
"""``[system] kind`` values: the model constructor (``module:attribute``) and what it builds."""

VERBS: dict[str, str] = {
    "simulate": "ctmm.simulation:simulate",
    "frequency_response": "ctmm.frequency:frequency_response",
    "natural_frequencies": "ctmm.frequency:natural_frequencies",
    "stability_chart": "ctmm.stability_chart:stability_chart",
}
"""``[study] verb`` values and the function each calls (the system is its first argument)."""


def _resolve(path: str) -> Callable[..., Any]:
    module, _, attribute = path.partition(":")
    target: Any = importlib.import_module(module)
    for part in attribute.split("."):
        target = getattr(target, part)
    return target


def system_constructor(kind: str) -> Constructor:
    """The model constructor of ``[system] kind`` (its ``elements`` come from the element tables)."""
    return constructor(kind, _resolve(SYSTEM_KINDS[kind][0]))


def verb(name: str) -> Constructor:
    """The study verb ``name``; its first parameter (the system) is not a key."""
    target = _resolve(VERBS[name])
    first = next(iter(inspect.signature(target).parameters))
    return constructor(name, target, skip=(first,))


def element_types(kind: str) -> dict[str, Constructor]:
    """``type`` values allowed in ``[[system.elements]]`` of a system ``kind``, with their keys."""
    if kind == "chain":
        return _with_factories(_public_classes("ctmm.elements", _is_chain_element))
    if kind in ("planar", "planar_chain", "planar_closed"):
        classes = _public_classes("ctmm.planar.elements", _is_planar_element)
        classes.update(_public_classes("ctmm.flexible", _is_planar_element))
        out = _with_factories(classes)
        out["FiniteElementSubsystem"] = constructor("FiniteElementSubsystem", finite_element_subsystem)
        out["finite_segment_beam"] = constructor("finite_segment_beam", _resolve(
            "ctmm.flexible.segments:finite_segment_beam"))
        return out
    if kind in ("spatial", "spatial_closed"):
        classes = _public_classes("ctmm.spatial.elements", _is_spatial_element)
        classes.update(_public_classes("ctmm.spatial", _is_spatial_element))
        out = _with_factories(classes)
        out["SpatialFiniteElementSubsystem"] = constructor("SpatialFiniteElementSubsystem", _resolve(
            "ctmm.fem.spatial_assembly:spatial_finite_element_subsystem"))
        return out
    raise KeyError(kind)


def loop_types() -> dict[str, Constructor]:
    """``type`` values of ``[[loops]]`` tables (feedback loops closed by ``ctmm.control.with_feedback``)."""
    from .control.loops import Feedback

    return {"Feedback": constructor("Feedback", Feedback)}


def transfer_function(numerator: list[float], denominator: list[float]) -> Any:
    """A python-control transfer function ``numerator(s) / denominator(s)`` (coefficients, highest power first).

    Raises
    ------
    ModelError
        A coefficient list that is empty (``numerator = []`` is not a zero controller), not of finite real numbers,
        or a denominator of zeros only.
    """
    import control

    from . import validation
    from .errors import ModelError

    coefficients = {}
    for label, value in (("numerator", numerator), ("denominator", denominator)):
        coefficients[label] = validation.finite_array(label, value, ndim=1)
        if coefficients[label].size == 0:
            raise ModelError(f"{label} must list at least one coefficient (highest power of s first), got {value!r}")
    if not np.any(coefficients["denominator"]):
        raise ModelError(f"denominator must have a non-zero coefficient, got {denominator!r}")
    return control.tf(coefficients["numerator"], coefficients["denominator"])


def value_types() -> dict[str, Constructor]:
    """``type`` values of inline tables usable as any value: time signals, grids, transfer functions."""
    from . import signals

    out = {name: constructor(name, getattr(signals, name))
           for name in ("Constant", "Harmonic", "Step", "SquareWave", "Ramp")}
    for name in ("linspace", "logspace", "geomspace"):
        out[name] = Constructor(name, getattr(np, name), (
            Parameter("start", True, "float", ""), Parameter("stop", True, "float", ""),
            Parameter("num", False, "int", "50")))
    out["TransferFunction"] = constructor("TransferFunction", transfer_function)
    out["SpinUpLaw"] = constructor("SpinUpLaw", spin_up_law)
    out["ParallelLaw"] = constructor("ParallelLaw", parallel_law)
    for module, names in (("ctmm.nonlinear_laws", ("LinearLaw", "CubicSpring", "ClearanceSpring", "PowerDamper")),
                          ("ctmm.fem", ("BeamElement", "PointMass", "NodeSpring", "MembraneElement", "SpatialBeamElement",
                                        "SpatialPlateElement", "SpatialPointMass", "SpatialNodeSpring",
                                        "SpatialThickPlateElement", "SpatialTrianglePlateElement")),
                          ("ctmm.planar.closed_loops", ("CutJoint",)),
                          ("ctmm.spatial.closed_loops", ("SpatialCutJoint",))):
        for name in names:
            out[name] = constructor(name, _resolve(f"{module}:{name}"))
    return out


def controller_kinds() -> dict[str, Constructor]:
    """Keys of ``[[controllers]]`` tables besides ``call`` / ``python``: an FMU (``fmu = "path"``, relative to the
    scene file) takes the keys of ``ctmm.control.fmu.FMUController``."""
    from .control.fmu import FMUController

    return {"fmu": constructor("fmu", FMUController, skip=("path",))}


def _table(constructors: dict[str, Constructor], where: str) -> list[str]:
    lines = [f"| `type` | calls | keys (required **bold**) |", "|---|---|---|"]
    for name, item in constructors.items():
        keys = ", ".join(f"**{p.name}**" if p.name in item.required() else f"{p.name}" for p in item.parameters)
        if item.open:
            keys += ", ... (further options of the callable)"
        target = getattr(item.target, "__qualname__", name)
        module = getattr(item.target, "__module__", "") or ""
        lines.append(f"| `{name}` | `{module}.{target}` | {keys} |")
    return [f"#### {where}", ""] + lines + [""]


def schema_markdown() -> str:
    """The generated schema reference of ``docs/scene_files.md`` (between its ``schema`` markers)."""
    lines = ["### `[system]`", "", "| `kind` | builds |", "|---|---|"]
    lines += [f"| `{kind}` | `{path}`: {text} |" for kind, (path, text) in SYSTEM_KINDS.items()]
    lines.append("")
    for kind in SYSTEM_KINDS:
        system = system_constructor(kind)
        lines.append(f"`kind = \"{kind}\"`: keys of `[system]`: `kind`, "
                     + ", ".join(f"`{p.name}`" for p in system.parameters) + ".")
        lines.append("")
    for kind in ("chain", "planar", "spatial"):
        label = {"planar": "planar, planar_chain and planar_closed", "spatial": "spatial and spatial_closed"}.get(kind, kind)
        lines += _table(element_types(kind), f"`[[system.elements]]` of kind {label}")
    lines += _table(loop_types(), "`[[loops]]`")
    lines += _table(controller_kinds(), "`[[controllers]]` with `fmu = \"path\"` (else `call` / `python`)")
    lines += _table({name: verb(name) for name in VERBS}, "`[study]` (`verb` = `type`)")
    lines += _table(value_types(), "values: inline tables `{type = ...}` anywhere")
    return "\n".join(lines).rstrip() + "\n"


JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"
"""The JSON Schema dialect of :func:`json_schema`."""


def _keys_schema(item: Constructor, fixed: dict[str, Any], skip: tuple[str, ...] = ()) -> dict[str, Any]:
    """An object schema of a table calling ``item``: the ``fixed`` keys (``{"type": {"const": ...}}``), every
    parameter a value, the required ones required, no other key unless the callable takes ``**options``."""
    properties = dict(fixed)
    for parameter in item.parameters:
        if parameter.name not in skip and parameter.name not in properties:
            entry: dict[str, Any] = {"$ref": "#/$defs/value"}
            if parameter.annotation:
                entry["description"] = parameter.annotation + (f", default {parameter.default}" if parameter.default
                                                               else "")
            properties[parameter.name] = entry
    required = list(fixed) + [key for key in item.required() if key not in skip and key not in fixed]
    return {"type": "object", "properties": properties, "required": required, "additionalProperties": item.open}


def _typed(constructors: dict[str, Constructor]) -> list[dict[str, Any]]:
    """One object schema per ``type`` value."""
    return [_keys_schema(item, {"type": {"const": name}}) for name, item in constructors.items()]


def _python_reference(key: str) -> dict[str, Any]:
    return {key: {"type": "string", "pattern": "^[^:]+:.+$", "description": "'module:attribute'"}}


def json_schema() -> dict[str, Any]:
    """The scene-file format (:mod:`ctmm.scene_files`) as a JSON Schema (draft 2020-12), generated from the same
    constructors as :func:`schema_markdown`.

    It states the tables, the allowed ``type`` values of every table and their keys (required ones required, no
    others unless the callable takes further options), the ``kind`` of ``[system]`` and the ``verb`` of
    ``[study]``; the values of keys are any JSON value (numbers, strings, lists, or inline tables with ``type``,
    ``python`` or ``call``), their ranges being checked by the constructors when the file is loaded.  A file that
    passes it may still be refused by :func:`ctmm.scene_files.load_scene` (a negative mass, an unknown Python
    reference); a file it rejects is refused there too.

    Returns
    -------
    dict
        The schema, ready for ``json.dump``.
    """
    kinds = list(SYSTEM_KINDS)
    element_sets = {"chain": "chain", "planar": "planar", "planar_chain": "planar", "planar_closed": "planar",
                    "spatial": "spatial", "spatial_closed": "spatial"}
    defs: dict[str, Any] = {"value_table": {"anyOf": _typed(value_types())}}
    for label in ("chain", "planar", "spatial"):
        types = element_types(label)
        call = {"type": "object", "properties": _python_reference("call"), "required": ["call"],
                "not": {"required": ["type"]}, "description": "a Python function returning an element or a list"}
        defs[f"{label}_element"] = {"anyOf": _typed(types) + [call]}
    defs["value"] = {
        "description": "a number, string, boolean, list of values, or inline table: {type = ...} (a value type or an "
                       "element type), {python = 'module:attribute'}, {call = 'module:attribute', ...} or a plain "
                       "mapping of values",
        "anyOf": [
            {"type": ["number", "string", "boolean"]},
            {"type": "array", "items": {"$ref": "#/$defs/value"}},
            {"type": "object", "properties": _python_reference("python"), "required": ["python"],
             "additionalProperties": False},
            {"type": "object", "properties": _python_reference("call"), "required": ["call"],
             "additionalProperties": {"$ref": "#/$defs/value"}},
            {"type": "object", "required": ["type"], "anyOf": [{"$ref": f"#/$defs/{name}"} for name in (
                "value_table", "chain_element", "planar_element", "spatial_element")]},
            {"type": "object", "not": {"anyOf": [{"required": [key]} for key in ("type", "python", "call")]},
             "additionalProperties": {"$ref": "#/$defs/value"}}]}
    systems = []
    for kind in kinds:
        item = system_constructor(kind)
        fixed = {"kind": {"const": kind, "description": SYSTEM_KINDS[kind][1]},
                 "elements": {"type": "array", "minItems": 1,
                              "items": {"$ref": f"#/$defs/{element_sets[kind]}_element"}}}
        systems.append(_keys_schema(item, fixed))
    studies = [_keys_schema(verb(name), {"verb": {"const": name}}) for name in VERBS]
    others = {"fmu": ("call", "python"), "call": ("fmu", "python"), "python": ("fmu", "call")}
    fmu = _keys_schema(controller_kinds()["fmu"], {"fmu": {"type": "string", "minLength": 1,
                                                           "description": "FMU path, relative to the scene file"}})
    controllers = [fmu,
                   {"type": "object", "properties": _python_reference("call"), "required": ["call"],
                    "not": {"anyOf": [{"required": [key]} for key in others["call"]]},
                    "additionalProperties": {"$ref": "#/$defs/value"}},
                   {"type": "object", "properties": _python_reference("python"), "required": ["python"],
                    "additionalProperties": False}]
    plot = {"type": "array", "items": {"type": "string", "minLength": 1},
            "description": "signal names drawn for a simulate study"}
    output = {"type": "object", "properties": {"plot": plot, "description": {"type": "string"}},
              "additionalProperties": False}
    return {
        "$schema": JSON_SCHEMA_DIALECT,
        "title": "ctmm scene file",
        "description": "A system, its feedback loops, its co-simulated controllers and its study (TOML, YAML or "
                       "JSON; docs/scene_files.md). Generated by ctmm.scene_files_schema.json_schema().",
        "type": "object",
        "properties": {"system": {"oneOf": systems},
                       "loops": {"type": "array", "items": {"oneOf": _typed(loop_types())}},
                       "controllers": {"type": "array", "items": {"oneOf": controllers}},
                       "study": {"oneOf": studies},
                       "output": output},
        "required": ["system", "study"],
        "additionalProperties": False,
        "$defs": defs}
