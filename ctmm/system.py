"""Systems: a validated, immutable chain of elements between two boundaries.

Connection points are numbered ``0 .. N`` for a chain ``[start, e_1, ..., e_N, end]``:
element ``e_j`` maps the state at point ``j-1`` (its inboard end) to point ``j`` (outboard).

Signals are addressed by dotted names (see :meth:`Chain.signal`):

* ``"m1.x"``, ``"m1.v"``, ``"m1.a"``: displacement [m], velocity [m/s], acceleration [m/s^2]
  at the element's outboard point (for a mass: the mass itself);
* ``"k1.f"``: internal force [N] at the outboard point (for a connector: its force, exerted on
  the outboard part);
* ``"k1.in.x"`` / ``"k1.out.f"``: explicit side; boundaries have a single point;
* ``"<component>_dot"`` / ``"<component>_ddot"``: first/second time derivative of any displacement
  component, e.g. ``"beam.theta_dot"`` (``v``/``a`` are aliases for the first component);
* inputs: ``"m1.force"`` (external force on a mass), ``"base.displacement"``, ``"tip.force"``.
"""
from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Iterable, Mapping
from typing import Any, Sequence

from .elements.axial import derive_shared
from .elements.base import Element
from .elements.boundary import Boundary
from .errors import ModelError, unknown_name
from .layouts import StateLayout

KINEMATIC_ALIASES = {"v": 1, "a": 2}  # derivative order of the first displacement component


@dataclass(frozen=True)
class Signal:
    """A resolved output signal: connection point, layout component and time-derivative order."""

    name: str
    point: int
    component: int
    derivative: int = 0


@dataclass(frozen=True)
class Input:
    """A resolved input: element position in the chain and its input name."""

    name: str
    position: int
    element: Element
    input: str


class Chain:
    """A serial chain of elements between a start and an end boundary.

    Parameters
    ----------
    name : str
        System name.
    elements : sequence of Element
        ``[start_boundary, element_1, ..., element_N, end_boundary]``.

    Raises
    ------
    ModelError
        Every problem found (missing/misplaced boundaries, duplicate names, mixed layouts),
        reported together.
    """

    def __init__(self, name: str, elements: Sequence[Element]) -> None:
        if not isinstance(name, str) or not name.strip():
            raise ModelError(f"chain name must be a non-empty string, got {name!r}")
        self.name = name
        if isinstance(elements, (str, bytes, Mapping, Element)) or not isinstance(elements, Iterable):
            raise ModelError(f"chain {name!r}: elements must be a list [start boundary, element, ..., "
                             f"end boundary], got {elements!r}")
        self.elements: tuple[Element, ...] = tuple(elements)
        problems = list(self._validate())
        if problems:
            raise ModelError(f"chain {name!r} is invalid:\n  - " + "\n  - ".join(problems))
        self.start: Boundary = self.elements[0]  # type: ignore[assignment]
        self.end: Boundary = self.elements[-1]  # type: ignore[assignment]
        self.body: tuple[Element, ...] = self.elements[1:-1]
        self.layout: StateLayout = self.body[0].layout   # boundaries receive it as an argument
        self._by_name = {e.name: i for i, e in enumerate(self.elements)}
        derive_shared(self.body)                         # the 1-D forms, one probe per equal element

    def _validate(self) -> Iterable[str]:
        elements = self.elements
        if len(elements) < 3:
            yield f"needs a start boundary, at least one element and an end boundary, got {len(elements)} element(s)"
            return
        for i, e in enumerate(elements):
            if not isinstance(e, Element):
                yield f"item {i} is not an Element: {e!r}"
        if not isinstance(elements[0], Boundary):
            yield f"first element must be a boundary (Fixed, Free, Elastic, ...), got {elements[0]!r}"
        if not isinstance(elements[-1], Boundary):
            yield f"last element must be a boundary (Fixed, Free, Elastic, ...), got {elements[-1]!r}"
        for i, e in enumerate(elements[1:-1], start=1):
            if isinstance(e, Boundary):
                yield f"boundary {e.name!r} at position {i} is inside the chain; boundaries go first or last"
        names = [getattr(e, "name", None) for e in elements]
        seen: set = set()
        for n in names:
            if n in seen:
                yield f"duplicate element name {n!r}"
            seen.add(n)
        layouts = {e.layout for e in elements[1:-1] if isinstance(e, Element) and not isinstance(e, Boundary)}
        if len(layouts) > 1:
            yield "elements use different state layouts: " + ", ".join(sorted(lay.name for lay in layouts))
        if not layouts:
            yield "chain has no elements between its boundaries"
        for boundary in (elements[0], elements[-1]):
            fixed = getattr(boundary, "layout", None) if isinstance(boundary, Boundary) else None
            if fixed is not None and len(layouts) == 1 and fixed.name != next(iter(layouts)).name:
                yield (f"boundary {boundary.name!r} ({type(boundary).__name__}) is for the {fixed.name!r} layout, "
                       f"the elements use {next(iter(layouts)).name!r}; use Fixed, Free or Elastic (any layout)")

    # -- structure ----------------------------------------------------------------------
    @property
    def n_points(self) -> int:
        """Number of connection points ``N + 1``."""
        return len(self.body) + 1

    def position(self, element_name: str) -> int:
        """Index of an element in :attr:`elements`."""
        if not isinstance(element_name, str):
            raise unknown_name("element", repr(element_name), list(self._by_name))
        try:
            return self._by_name[element_name]
        except KeyError:
            raise unknown_name("element", element_name, list(self._by_name)) from None

    def element(self, element_name: str) -> Element:
        """The element called ``element_name``."""
        return self.elements[self.position(element_name)]

    def point_names(self) -> list[str]:
        """Readable names of the connection points ``0..N`` (``"<inboard>|<outboard>"``)."""
        return [f"{self.elements[j].name}|{self.elements[j + 1].name}" for j in range(self.n_points)]

    def reversed(self, name: str | None = None) -> "Chain":
        """The same chain traversed from the end to the start (for metamorphic checks)."""
        return Chain(name or self.name + "_reversed", list(reversed(self.elements)))

    # -- signals ------------------------------------------------------------------------
    def signal_names(self) -> list[str]:
        """All output signal names of the chain."""
        names = []
        for i, e in enumerate(self.elements):
            for q in self._quantities():
                names.append(f"{e.name}.{q}")
        return names

    def _quantities(self) -> list[str]:
        comps = list(self.layout.components)
        derived = [f"{c}_{suffix}" for c in self.layout.displacements for suffix in ("dot", "ddot")]
        return comps + list(KINEMATIC_ALIASES) + derived

    def signal(self, name: str) -> Signal:
        """Resolve an output signal name such as ``"m1.x"`` or ``"k2.in.f"``."""
        parts = name.split(".") if isinstance(name, str) else []
        if len(parts) not in (2, 3):
            raise unknown_name("signal", str(name), self.signal_names())
        elem_name, quantity = parts[0], parts[-1]
        if elem_name not in self._by_name:
            raise unknown_name("signal", name, self.signal_names())
        pos = self._by_name[elem_name]
        side = parts[1] if len(parts) == 3 else ("in" if pos == len(self.elements) - 1 else "out")
        if side not in ("in", "out"):
            raise ModelError(f"signal {name!r}: side must be 'in' or 'out', got {side!r}")
        point = pos - 1 if side == "in" else pos
        point = min(max(point, 0), self.n_points - 1)
        if quantity in KINEMATIC_ALIASES:
            return Signal(name, point, 0, KINEMATIC_ALIASES[quantity])
        for suffix, order in (("_ddot", 2), ("_dot", 1)):
            base = quantity[: -len(suffix)]
            if quantity.endswith(suffix) and base in self.layout.displacements:
                return Signal(name, point, self.layout.index(base), order)
        if quantity in self.layout.components:
            return Signal(name, point, self.layout.index(quantity), 0)
        raise unknown_name("signal", name, self.signal_names())

    def input_names(self) -> list[str]:
        """All input names (``"element.input"``)."""
        return [f"{e.name}.{i}" for e in self.elements for i in e.inputs]

    def input(self, name: str) -> Input:
        """Resolve an input name such as ``"m1.force"``."""
        parts = name.split(".") if isinstance(name, str) else []
        if len(parts) != 2 or parts[0] not in self._by_name:
            raise unknown_name("input", str(name), self.input_names())
        pos = self._by_name[parts[0]]
        element = self.elements[pos]
        if parts[1] not in element.inputs:
            raise unknown_name("input", name, self.input_names())
        return Input(name, pos, element, parts[1])

    def __repr__(self) -> str:
        return f"Chain({self.name!r}, {len(self.body)} elements, {self.start.name!r} -> {self.end.name!r})"


def require_system(value: Any, *, parameter: str = "system", controlled: bool = True) -> Any:
    """Return ``value`` if it is a :class:`Chain` (or, when ``controlled``, a controlled chain).

    A controlled chain (:class:`~ctmm.control.loops.ControlledChain`) is recognised by its
    ``plant`` (a :class:`Chain`) and ``loops``; this module cannot import it (it builds on this one).

    Raises
    ------
    ModelError
        Naming ``parameter``, the value and what is allowed.
    """
    if isinstance(value, Chain):
        return value
    is_controlled = isinstance(getattr(value, "plant", None), Chain) and hasattr(value, "loops")
    if controlled and is_controlled:
        return value
    allowed = "a ctmm.Chain or ctmm.control.ControlledChain" if controlled else "a ctmm.Chain"
    hint = ("; use ctmm.simulate for a controlled chain (it honours every loop)" if is_controlled else "")
    text = repr(value)
    raise ModelError(f"{parameter} must be {allowed}, got {text if len(text) <= 80 else text[:77] + '...'}{hint}")
