"""The schema of scene files, generated from the Python constructors (no second list to maintain).

A scene file (:mod:`ctmm.scene_files`) names Python constructors: ``type = "RigidBody"`` in a table
means ``ctmm.planar.RigidBody(**the other keys)``. The allowed ``type`` values of each system kind
are the public element classes of its package (``ctmm.elements``, ``ctmm.planar`` and
``ctmm.flexible``, ``ctmm.spatial``), the allowed keys of each type the parameters of its
constructor (:func:`inspect.signature`, i.e. the dataclass fields), and the allowed keys of the
study those of the verb (``ctmm.simulate`` ...). A new element class or field is therefore in the
schema as soon as it is exported. ``docs/scene_files.md`` holds :func:`schema_markdown` (checked
by a test).
"""
from __future__ import annotations

import dataclasses
import importlib
import inspect
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

__all__ = ["Parameter", "Constructor", "SYSTEM_KINDS", "VERBS", "element_types", "value_types", "loop_types",
           "system_constructor", "verb", "constructor", "schema_markdown", "transfer_function"]


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
    return dataclasses.is_dataclass(cls) and cls.__module__ == "ctmm.spatial.elements"


SYSTEM_KINDS: dict[str, tuple[str, str]] = {
    "chain": ("ctmm.system:Chain", "1-D chain, elements in order from the start boundary"),
    "planar": ("ctmm.planar.model:PlanarModel", "planar tree: every hinge names its parent and child"),
    "planar_chain": ("ctmm.planar.model:PlanarModel.chain", "planar serial chain: hinge connections from the "
                     "element order"),
    "spatial": ("ctmm.spatial.model:SpatialModel", "spatial tree: every joint names its parent and child"),
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
    if kind in ("planar", "planar_chain"):
        classes = _public_classes("ctmm.planar.elements", _is_planar_element)
        classes.update(_public_classes("ctmm.flexible", _is_planar_element))
        return _with_factories(classes)
    if kind == "spatial":
        return _with_factories(_public_classes("ctmm.spatial.elements", _is_spatial_element))
    raise KeyError(kind)


def loop_types() -> dict[str, Constructor]:
    """``type`` values of ``[[loops]]`` tables (feedback loops closed by ``ctmm.control.with_feedback``)."""
    from .control.loops import Feedback

    return {"Feedback": constructor("Feedback", Feedback)}


def transfer_function(numerator: list[float], denominator: list[float]) -> Any:
    """A python-control transfer function ``numerator(s) / denominator(s)`` (coefficients, highest power first)."""
    import control

    return control.tf(numerator, denominator)


def value_types() -> dict[str, Constructor]:
    """``type`` values of inline tables usable as any value: time signals, grids, transfer functions."""
    from . import signals

    out = {name: constructor(name, getattr(signals, name)) for name in ("Constant", "Harmonic", "Step", "SquareWave")}
    for name in ("linspace", "logspace", "geomspace"):
        out[name] = Constructor(name, getattr(np, name), (
            Parameter("start", True, "float", ""), Parameter("stop", True, "float", ""),
            Parameter("num", False, "int", "50")))
    out["TransferFunction"] = constructor("TransferFunction", transfer_function)
    return out


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
        label = "planar and planar_chain" if kind == "planar" else kind
        lines += _table(element_types(kind), f"`[[system.elements]]` of kind {label}")
    lines += _table(loop_types(), "`[[loops]]`")
    lines += _table({name: verb(name) for name in VERBS}, "`[study]` (`verb` = `type`)")
    lines += _table(value_types(), "values: inline tables `{type = ...}` anywhere")
    return "\n".join(lines).rstrip() + "\n"
