"""Checks shared by the planar and spatial finite-element models (:mod:`ctmm.fem.assembly`,
:mod:`ctmm.fem.spatial_assembly`): node names and positions, the element list, Rayleigh damping, DOF
numbering and spring sanity; the one record of a spring between two nodes (:class:`TwoNodeSpring`); the
inputs of a subsystem body, planar and spatial (:func:`subsystem_nodes`, :func:`subsystem_boundary`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError
from ..spatial_frequency import rayleigh_modes

__all__ = ["TwoNodeSpring", "node_name", "node_positions", "checked_elements", "rayleigh_pair", "number_dofs", "check_springs",
           "square_matrix", "clamped_frequencies", "known_nodes", "subsystem_nodes", "subsystem_boundary",
           "lumped_masses"]


def node_name(owner: str, label: str, value: object) -> str:
    """``value`` as a node name (non-empty str), else :class:`ModelError` naming ``owner`` and ``label``."""
    if not isinstance(value, str) or not value:
        raise ModelError(f"{owner}: {label} must be a node name (non-empty str), got {value!r}")
    return value


@dataclass(frozen=True)
class TwoNodeSpring:
    """Linear spring and viscous damper between two nodes, along the line of their undeformed positions, and a
    rotational spring-damper between their rotations (small displacements): the record of
    :class:`~ctmm.fem.NodeSpring` (planar) and :class:`~ctmm.fem.SpatialNodeSpring` (spatial; isotropic about
    each axis), assembled by :class:`~ctmm.fem.nodal_model.NodalModel`.

    Attributes
    ----------
    name, start, end : str
        Element name and the two node names.
    stiffness, damping, rotational_stiffness, rotational_damping : float
        [N/m], [N s/m], [N m/rad], [N m s/rad], >= 0 (the subclasses say where each acts).
    """

    name: str
    start: str
    end: str
    stiffness: float = 0.0
    damping: float = 0.0
    rotational_stiffness: float = 0.0
    rotational_damping: float = 0.0

    def __post_init__(self) -> None:
        n = validation.name("element", self.name)
        node_name(n, "start", self.start)
        node_name(n, "end", self.end)
        for attribute in ("stiffness", "damping", "rotational_stiffness", "rotational_damping"):
            object.__setattr__(self, attribute, validation.nonnegative(f"{n}: {attribute}", getattr(self, attribute)))


def known_nodes(owner: str, label: str, value: Any, positions: Mapping[str, np.ndarray], *,
                allow_empty: bool) -> tuple[str, ...]:
    """``value`` (a list or tuple of node names) as a tuple of known, distinct nodes, else :class:`ModelError`."""
    allowed = f"a list of node names (one of {list(positions)})"
    if not isinstance(value, (list, tuple)):
        raise ModelError(f"{owner}: {label} must be {allowed}, got {value!r}")
    for node in value:
        if not isinstance(node, str) or node not in positions:
            raise ModelError(f"{owner}: {label} must be {allowed}; {node!r} in {value!r} is not a node")
    if len(set(value)) != len(value) or (not value and not allow_empty):
        raise ModelError(f"{owner}: {label} must be {allowed}, {'distinct' if value else 'at least one'}, "
                         f"got {value!r}")
    return tuple(value)


def node_positions(name: str, nodes: Any, dimension: int) -> dict[str, np.ndarray]:
    """Validated undeformed node positions ``{node: (dimension,) array}`` [m]."""
    shape = "(x, y)" if dimension == 2 else "(x, y, z)"
    if not isinstance(nodes, Mapping) or not nodes:
        raise ModelError(f"{name}: nodes must be a non-empty mapping {{name: {shape}}}, got {nodes!r}")
    positions: dict[str, np.ndarray] = {}
    for node, xyz in nodes.items():
        validation.name(f"{name}: nodes key {node!r}:", node)
        if isinstance(xyz, (str, bytes)):
            raise ModelError(f"{name}: nodes[{node!r}] must be {shape} [m], got {xyz!r}")
        p = validation.finite_array(f"{name}: nodes[{node!r}]", xyz)
        if p.shape != (dimension,):
            raise ModelError(f"{name}: nodes[{node!r}] must be {shape} [m], got {xyz!r}")
        positions[node] = p
    return positions


def checked_elements(name: str, elements: Sequence[Any], allowed: tuple, nodes_of: Callable[[Any], tuple],
                     positions: Mapping[str, np.ndarray]) -> tuple:
    """The elements as a non-empty tuple: each of an ``allowed`` type, names unique, nodes known."""
    kinds = ", ".join(t.__name__ for t in allowed)
    if not isinstance(elements, (list, tuple)) or not elements:
        raise ModelError(f"{name}: elements must be a non-empty list of {kinds}, got {elements!r}")
    elements = tuple(elements)
    seen = set()
    for e in elements:
        if not isinstance(e, allowed):
            raise ModelError(f"{name}: elements must be {kinds}, got {e!r}")
        if e.name in seen:
            raise ModelError(f"{name}: duplicate element name {e.name!r}")
        seen.add(e.name)
        for node in nodes_of(e):
            if node not in positions:
                raise ModelError(f"{name}: element {e.name!r} names unknown node {node!r}; nodes: {list(positions)}")
    return elements


def rayleigh_pair(name: str, rayleigh: Any) -> np.ndarray:
    """``(a [1/s], b [s])`` >= 0 of ``C += a M + b K``."""
    ray = validation.finite_array(f"{name}: rayleigh", rayleigh)
    if ray.shape != (2,) or np.any(ray < 0):
        raise ModelError(f"{name}: rayleigh must be (a [1/s], b [s]) >= 0, got {rayleigh!r}")
    return ray


def number_dofs(positions: Mapping[str, np.ndarray], rotating: set, translations: int, rotations: int
                ) -> tuple[dict[str, tuple[int, ...]], int]:
    """DOF indices per node in node order (``translations``, plus ``rotations`` at ``rotating`` nodes) and
    their count."""
    dofs, count = {}, 0
    for node in positions:
        k = translations + (rotations if node in rotating else 0)
        dofs[node] = tuple(range(count, count + k))
        count += k
    return dofs, count


def check_springs(name: str, springs: Sequence[Any], dofs: Mapping[str, tuple], positions: Mapping[str, np.ndarray],
                  full: int) -> None:
    """Rotational springs need rotation DOFs at both nodes (``full`` DOFs); axial ones distinct positions."""
    for e in springs:
        if (e.rotational_stiffness or e.rotational_damping) and (len(dofs[e.start]) != full or len(dofs[e.end]) != full):
            raise ModelError(f"{name}: {e.name!r} has a rotational spring but its nodes {e.start!r}, {e.end!r} need "
                             "rotation DOFs (a beam at each)")
        if (e.stiffness or e.damping) and not np.linalg.norm(positions[e.end] - positions[e.start]) > 0:
            raise ModelError(f"{name}: {e.name!r} joins coincident nodes; its line of action is undefined")


def square_matrix(owner: str, label: str, value: Any, n: int | None) -> np.ndarray:
    """A finite symmetric square matrix (``n x n`` when given), else :class:`ModelError`."""
    a = validation.finite_array(f"{owner}: {label}", value, ndim=2)
    if a.shape[0] != a.shape[1] or (n is not None and a.shape[0] != n):
        raise ModelError(f"{owner}: {label} must be square{'' if n is None else f' ({n} x {n})'}, got shape {a.shape}")
    if np.max(np.abs(a - a.T), initial=0.0) > 1e-10 * max(np.max(np.abs(a), initial=0.0), 1e-300):
        raise ModelError(f"{owner}: the {label} matrix must be symmetric")
    return a


def lumped_masses(owner: str, M: np.ndarray, couplings: str, model: str, record: str) -> np.ndarray:
    """The diagonal of a lumped (diagonal) mass matrix ``M`` [kg, kg m^2], else :class:`ModelError`: a consistent
    ``M`` does not determine the floating-frame ``couplings``; the message names the finite-element ``model`` class
    and the inertia ``record`` to use instead."""
    off = M - np.diag(np.diag(M))
    if np.max(np.abs(off), initial=0.0) > 1e-12 * max(np.max(np.abs(M), initial=0.0), 1e-300):
        raise ModelError(f"{owner}: M is not lumped (diagonal); a consistent mass matrix does not determine the "
                         f"floating-frame couplings {couplings}: build the subsystem with ctmm.fem.{model} or pass "
                         f"inertia_integrals={record}(...)")
    return np.diag(M)


def clamped_frequencies(owner: str, stiffness: np.ndarray, mass: np.ndarray, dofs: Mapping[str, tuple],
                        clamped: Sequence[str]) -> np.ndarray:
    """Natural frequencies [rad/s] with the DOFs of the ``clamped`` nodes held (``eigh(K, M)``, Rayleigh quotients);
    a mode with ``omega^2`` below minus its round-off (``rayleigh_modes``) is refused (statically unstable)."""
    clamped = known_nodes(owner, "clamped", clamped, dofs, allow_empty=True)
    held = {i for node in clamped for i in dofs[node]}
    keep = [i for i in range(stiffness.shape[0]) if i not in held]
    free_mass = mass[np.ix_(keep, keep)]
    if keep and not np.min(np.linalg.eigvalsh(free_mass)) > 1e-12 * np.max(np.abs(free_mass), initial=0.0):
        massless = [node for node, node_dofs in dofs.items() if node not in clamped
                    and any(mass[i, i] <= 0.0 for i in node_dofs)] or "none on the diagonal, but M is singular"
        raise ModelError(f"{owner}: natural frequencies need a positive definite mass matrix on the free DOFs; "
                         f"nodes without mass: {massless}; clamp them (clamped=...) or give them mass (PointMass)")
    values, _, noise = rayleigh_modes(stiffness[np.ix_(keep, keep)], free_mass)
    unstable = values < -noise
    if np.any(unstable):
        raise ModelError(f"{owner}: statically unstable with {list(clamped)} clamped: {int(np.sum(unstable))} mode(s) "
                         f"with negative stiffness (omega^2 = {values[unstable].tolist()} rad^2/s^2 < 0, e.g. a "
                         "compressive axial_force above the buckling load); natural frequencies exist only for a "
                         "stable structure")
    return np.sqrt(np.clip(values, 0.0, None))


def subsystem_nodes(owner: str, nodes: Any, n: int, dimension: int, rotations: int
                    ) -> tuple[dict[str, np.ndarray], dict[str, tuple[int, ...]]]:
    """The ``nodes`` of a subsystem body, ``{name: (position, DOF indices)}`` with ``dimension`` coordinates [m] and
    ``dimension`` or ``dimension + rotations`` DOF indices each, every DOF ``0..n-1`` held by exactly one node.

    Returns
    -------
    positions, node_dofs : dict
        Position array and DOF index tuple by node name.

    Raises
    ------
    ModelError
        Naming the node and what is allowed.
    """
    axes = "(x, y)" if dimension == 2 else "(x, y, z)"
    translations = ", ".join(f"i{a}" for a in "xyz"[:dimension])
    rotation_names = ", ".join(f"ir{a}" for a in ("z" if rotations == 1 else "xyz"))
    form = f"({axes}, ({translations}[, {rotation_names}]))"
    if not isinstance(nodes, Mapping) or not nodes:
        raise ModelError(f"{owner}: nodes must be a non-empty mapping {{name: {form}}}, got {nodes!r}")
    owners: list[str | None] = [None] * n
    positions, node_dofs = {}, {}
    for node, spec in nodes.items():
        validation.name(f"{owner}: nodes key {node!r}:", node)
        try:
            position, dofs = spec
            position = validation.finite_array(f"{owner}: nodes[{node!r}] position", position)
            dofs = tuple(dofs)
            if any(isinstance(i, (bool, np.bool_)) or not isinstance(i, (int, np.integer)) for i in dofs):
                raise TypeError("a DOF index is not an integer")
            dofs = tuple(int(i) for i in dofs)
        except (TypeError, ValueError) as exc:
            raise ModelError(f"{owner}: nodes[{node!r}] must be {form} with integer DOF indices, got {spec!r}") from exc
        if position.shape != (dimension,) or len(dofs) not in (dimension, dimension + rotations) \
                or any(not 0 <= i < n for i in dofs):
            raise ModelError(f"{owner}: nodes[{node!r}] must be {form} with DOF indices in 0..{n - 1}, got {spec!r}")
        for i in dofs:
            if owners[i] is not None:
                raise ModelError(f"{owner}: DOF {i} belongs to two nodes ({owners[i]!r} and {node!r})")
            owners[i] = node
        positions[node], node_dofs[node] = position, dofs
    if any(o is None for o in owners):
        raise ModelError(f"{owner}: nodes must hold every DOF 0..{n - 1}; DOFs "
                         f"{[i for i, o in enumerate(owners) if o is None]} belong to no node (nodes: {list(node_dofs)})")
    return positions, node_dofs


def subsystem_boundary(owner: str, boundary: Any, frame_nodes: Any, node_dofs: Mapping[str, tuple],
                       nonlinear_force: Any, potential: Any) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """A subsystem body's ``boundary`` (distinct nodes, the inboard one first) and ``frame_nodes`` (nodes that are not
    boundary nodes) as tuples; ``nonlinear_force`` and ``potential`` callable or ``None``; else :class:`ModelError`."""
    if not isinstance(boundary, (list, tuple)):
        raise ModelError(f"{owner}: boundary must be a list of node names, the inboard one first; got "
                         f"{boundary!r:.80}, nodes: {', '.join(node_dofs)}")
    checked = tuple(boundary)
    if not checked or any(b not in node_dofs for b in checked) or len(set(checked)) != len(checked):
        raise ModelError(f"{owner}: boundary must name distinct nodes, the inboard one first; got {boundary!r}, "
                         f"nodes: {', '.join(node_dofs)}")
    frame = tuple(frame_nodes)
    wrong = [f for f in frame if f not in node_dofs or f in checked]
    if wrong:
        raise ModelError(f"{owner}: frame_nodes {wrong} must be nodes that are not boundary nodes; nodes: "
                         f"{', '.join(node_dofs)}")
    if nonlinear_force is not None and not callable(nonlinear_force):
        raise ModelError(f"{owner}: nonlinear_force must be callable f(u, u_dot, t), got {nonlinear_force!r}")
    if potential is not None and not callable(potential):
        raise ModelError(f"{owner}: potential must be callable V(u) [J], got {potential!r}")
    return checked, frame
