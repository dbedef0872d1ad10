"""The state of a 1-D chain at the start of a DT-TMM run: rest positions, initial positions and
velocities, the consistent initial accelerations and the internal forces at ``t0``.

Elements are read through :meth:`~ctmm.elements.base.Element.lumped_coefficients` (points and
connectors, connectors possibly with inertance) and ``is_point``; a chain with inerters solves
the coupled equations ``M a = F`` for its initial accelerations (:func:`initial_acceleration`).
"""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from . import validation
from .elements.axial import AxialBody
from .errors import ModelError
from .signals import Constant
from .system import Chain

__all__ = ["rest_positions", "initial_state", "initial_acceleration", "initial_forces", "acceleration_change", "NodeInertia",
           "point_labels", "point_of_element"]

def rest_positions(system: Chain) -> np.ndarray:
    """Absolute positions [m] of the connection points with every connector at its free length."""
    x = np.zeros(system.n_points)
    x[0] = getattr(system.start, "position", 0.0) if system.start.known == "displacement" else 0.0
    for j, e in enumerate(system.body, start=1):
        lumped = e.lumped_coefficients()
        x[j] = x[j - 1] + (lumped.free_length if lumped is not None and lumped.connector else
                           getattr(e, "free_length", 0.0) if not e.is_point else 0.0)
    return x


def point_labels(system: Chain) -> list[str]:
    """Name of each connection point for messages: its point element, else ``"<inboard>|<outboard>"``."""
    labels = []
    for p, name in enumerate(system.point_names()):
        inboard, outboard = system.elements[p], system.elements[p + 1]
        if isinstance(outboard, AxialBody):
            labels.append(outboard.name)
        elif isinstance(inboard, AxialBody):
            labels.append(inboard.name)
        else:
            labels.append(name)
    return labels


def point_of_element(system: Chain, element_name: str) -> int:
    """The connection point an ``x0`` / ``v0`` entry by element name sets (:func:`initial_state`)."""
    pos = system.position(element_name)
    if pos == len(system.elements) - 1:
        return system.n_points - 1
    return max(pos - 1, 0) if system.elements[pos].is_point and 0 < pos else min(pos, system.n_points - 1)


def initial_state(system: Chain, x0: Mapping[str, float] | None, v0: Mapping[str, float] | None):
    """Initial positions and velocities of all connection points.

    ``x0`` / ``v0`` map element names (masses, boundaries) to absolute position [m] / velocity
    [m/s].  Unspecified points keep their rest position (connectors at free length) and zero
    velocity; the time paths then place the points between connectors only (massless junctions)
    at their force balance (:meth:`ctmm.chain_ode.ChainDynamics.start_points`).
    """
    x0 = validation.number_mapping("x0", x0)
    v0 = validation.number_mapping("v0", v0)
    for label, values in (("x0", x0), ("v0", v0)):
        for element_name, value in values.items():
            element = system.element(element_name)
            if getattr(element, "known", None) != "displacement":
                continue
            held = getattr(element, "position", None) if label == "x0" else 0.0
            if held is None or not math.isclose(value, held, rel_tol=1e-12, abs_tol=1e-15):
                raise ModelError(f"{label}[{element_name!r}] = {value!r}: {element_name!r} is a support that "
                                 "prescribes its own motion; give initial values to moving points only")
    x = rest_positions(system)
    v = np.zeros(system.n_points)
    node = np.zeros(system.n_points, dtype=int)     # points tied by point elements move as one node
    for j, e in enumerate(system.body, start=1):
        node[j] = node[j - 1] if e.is_point else node[j - 1] + 1
    for label, values, target in (("x0", x0, x), ("v0", v0, v)):
        setters: dict[int, str] = {}
        for element_name, value in values.items():
            k = node[point_of_element(system, element_name)]
            if k in setters and not math.isclose(value, values[setters[k]], rel_tol=1e-12, abs_tol=1e-15):
                raise ModelError(f"{label}[{element_name!r}] = {value!r} and {label}[{setters[k]!r}] = "
                                 f"{values[setters[k]]!r} set one point (the elements are joined without a "
                                 "connector between them); give one value")
            setters[k] = element_name
            target[node == k] = value
    return x[:, None], v[:, None]


def _connector_forces(system: Chain, x: np.ndarray, v: np.ndarray,
                      across: Mapping[int, float] | None = None, a: np.ndarray | None = None) -> dict[int, float]:
    """Connector forces on their outboard point, including actuator forces ``across`` them.

    A connector with inertance (:class:`~ctmm.elements.inerter.Inerter`) adds ``-b (a_out - a_in)``
    from the accelerations ``a``; without them the state is taken as held (zero accelerations).
    """
    forces = {}
    across = across or {}
    for j, e in enumerate(system.body, start=1):
        lumped = e.lumped_coefficients()
        if lumped is not None and lumped.connector:
            dx = x[j, 0] - x[j - 1, 0] - lumped.free_length
            forces[j] = -lumped.stiffness * dx - lumped.damping * (v[j, 0] - v[j - 1, 0]) + across.get(j, 0.0)
            if lumped.mass and a is not None:
                forces[j] -= lumped.mass * (a[j, 0] - a[j - 1, 0])
        elif hasattr(e, "transmitted_force"):         # a connector with a law (NonlinearSpring)
            forces[j] = e.transmitted_force(x[j, 0] - x[j - 1, 0], v[j, 0] - v[j - 1, 0], across.get(j, 0.0))
    return forces


def _has_inertance(system: Chain) -> bool:
    """True when a connector carries inertia between its points (the node accelerations couple)."""
    return any(c is not None and c.connector and c.mass > 0.0
               for c in (e.lumped_coefficients() for e in system.body))


def _node_mass(system: Chain) -> tuple[np.ndarray, np.ndarray]:
    """Node of every point (points joined by point elements share one) and the nodes' mass matrix
    [kg]: point masses on the diagonal, connector inertances ``b [[1, -1], [-1, 1]]``."""
    node = np.zeros(system.n_points, dtype=int)
    for j, e in enumerate(system.body, start=1):
        node[j] = node[j - 1] if e.is_point else node[j - 1] + 1
    n = int(node[-1]) + 1
    M = np.zeros((n, n))
    for j, e in enumerate(system.body, start=1):
        c = e.lumped_coefficients()
        i, o = node[j - 1], node[j]
        if c.connector:
            M[np.ix_([i, o], [i, o])] += c.mass * np.array([[1.0, -1.0], [-1.0, 1.0]])
        else:
            M[i, i] += c.mass
    return node, M


def _coupled_acceleration(system: Chain, x: np.ndarray, v: np.ndarray, t0: float,
                          extra_forces: Mapping[int, float]) -> np.ndarray:
    """Accelerations [m/s^2] from the global equations ``M a = F(t0, x, v)`` of a lumped chain.

    Used when connectors carry inertance: their terms ``b [[1, -1], [-1, 1]]`` couple the
    accelerations of neighbouring nodes.  Nodes (points joined by point elements) held by a
    displacement boundary start at rest (``a = 0``, as their velocity); nodes without inertia
    get 0 as in :func:`initial_acceleration`.
    """
    inertia = NodeInertia(system)
    node = inertia.node
    F = np.zeros(inertia.mass.shape[0])
    for j, e in enumerate(system.body, start=1):
        c = e.lumped_coefficients()
        i, o, extra = node[j - 1], node[j], extra_forces.get(j, 0.0)
        if not c.connector:
            F[i] += float(e.force(t0)) - c.damping * v[j - 1, 0] - c.stiffness * x[j - 1, 0] + extra
            continue
        f = (-c.stiffness * (x[j, 0] - x[j - 1, 0] - c.free_length) - c.damping * (v[j, 0] - v[j - 1, 0])
             + extra)
        F[o] += f
        F[i] -= f
    for boundary, point, start in ((system.start, 0, True), (system.end, -1, False)):
        if boundary.known == "force":
            F[node[point]] += (1.0 if start else -1.0) * _boundary_force(boundary, x[point, 0], v[point, 0], start, t0)
    return inertia.solve(F)


def acceleration_change(system: Chain, forces: Mapping[int, float], inertia: "NodeInertia | None" = None
                        ) -> np.ndarray:
    """Jump [m/s^2] of every point's acceleration when loads jump (positions and velocities continuous).

    Parameters
    ----------
    system : Chain
        A 1-D chain whose elements all have a lumped form
        (:meth:`~ctmm.elements.base.Element.lumped_coefficients`).
    forces : mapping
        Load jumps [N] by element position: on the point of a point element, across a connector
        (``+F`` outboard, ``-F`` inboard).  Positions of boundaries are ignored.

    inertia : NodeInertia, optional
        The chain's node mass matrix, factorised once (pass it when called every step).

    Returns
    -------
    ndarray, shape (n_points, 1)
        ``M^-1 dF`` over the nodes (inerters couple neighbouring nodes); 0 at held or massless nodes.
    """
    inertia = inertia if inertia is not None else NodeInertia(system)
    F = np.zeros(inertia.mass.shape[0])
    node = inertia.node
    for j, value in forces.items():
        if 1 <= j <= len(system.body):
            if inertia.connector[j - 1]:
                F[node[j]] += value
                F[node[j - 1]] -= value
            else:
                F[node[j - 1]] += value
    return inertia.solve(F)


class NodeInertia:
    """A lumped chain's nodes, node mass matrix and its inverse over the moving nodes, built once.

    Parameters
    ----------
    system : Chain
        A 1-D chain whose elements all have a lumped form.
    """

    def __init__(self, system: Chain) -> None:
        self.node, self.mass = _node_mass(system)
        self.connector = [e.lumped_coefficients().connector for e in system.body]
        held = np.zeros(self.mass.shape[0], dtype=bool)
        for boundary, point in ((system.start, 0), (system.end, -1)):
            held[self.node[point]] |= boundary.known == "displacement"
        self.active = np.flatnonzero(~held & (np.diag(self.mass) > 0.0))
        self.inverse = None
        if self.active.size:
            Maa = self.mass[np.ix_(self.active, self.active)]
            if np.linalg.cond(Maa) > 1e12:
                raise ModelError(f"chain {system.name!r}: the accelerations are not determined (points joined only "
                                 "by inerters, without mass or a support); add a mass or a support")
            self.inverse = np.linalg.inv(Maa)

    def solve(self, F: np.ndarray) -> np.ndarray:
        """Point accelerations ``(n_points, 1)`` [m/s^2] from node forces ``F`` [N] (held or massless: 0)."""
        a_node = np.zeros(self.mass.shape[0])
        if self.inverse is not None:
            a_node[self.active] = self.inverse @ F[self.active]
        return a_node[self.node][:, None]


def initial_acceleration(system: Chain, x: np.ndarray, v: np.ndarray, t0: float,
                         extra_forces: Mapping[int, float] | None = None) -> np.ndarray:
    """Accelerations [m/s^2] of all points from the equations of motion at ``t0``.

    Consecutive point elements (a mass with a grounded spring, ...) form one node: its
    acceleration is (sum of the forces on the node) / (sum of the masses).  Massless nodes get 0.
    Point elements directly on a resting displacement-type boundary (``Fixed``, a constant
    ``PrescribedDisplacement``) rest with it (``a = 0``; their inertia force enters the boundary's
    reaction, :func:`initial_forces`).  Chains with inerters solve the coupled equations
    (:func:`_coupled_acceleration`).

    Raises
    ------
    ModelError
        A point element directly on a *moving* prescribed displacement: a DT-TMM scheme would take
        its acceleration from the scheme's differences of the prescribed motion, whose error does
        not vanish with the step (the reported reaction would be wrong); the ODE methods move it with
        the boundary exactly (:mod:`ctmm.chain_ode`).
    """
    extra_forces = extra_forces or {}
    if _has_inertance(system):
        return _coupled_acceleration(system, x, v, t0, extra_forces)
    a = np.zeros_like(x)
    connector = _connector_forces(system, x, v, extra_forces)
    body = system.body
    j = 1
    while j <= len(body):
        if not body[j - 1].is_point:
            j += 1
            continue
        first = j
        while j <= len(body) and body[j - 1].is_point:
            j += 1
        last = j - 1                     # elements first..last share one point
        point = first - 1
        on_start, on_end = first == 1 and system.start.known == "displacement", \
            last == len(body) and system.end.known == "displacement"
        if on_start or on_end:           # the point rests with its boundary
            boundary = system.start if on_start else system.end
            signal = getattr(boundary, "displacement", None)
            if signal is not None and not isinstance(signal, Constant):
                names = ", ".join(body[pos - 1].name for pos in range(first, last + 1))
                raise ModelError(f"{names} sits directly on the driven boundary {boundary.name!r}: a DT-TMM scheme "
                                 "would take its acceleration from the scheme's differences of the prescribed "
                                 "displacement, whose error does not vanish as dt -> 0 (its inertia force in the "
                                 "reaction would be wrong); use an ODE method (method='rk4' or a solve_ivp method), "
                                 "which moves it with the boundary exactly, or put a connector in between")
            a[point:last + 1, 0] = 0.0
            continue
        total_mass, force = 0.0, 0.0
        for pos in range(first, last + 1):
            e = body[pos - 1]
            if isinstance(e, AxialBody):
                co = e.axial_coefficients()
                total_mass += co.inertia
                force += e.own_load(t0) - co.damping * v[point, 0] - co.stiffness * x[point, 0] - co.rest
            force += extra_forces.get(pos, 0.0)
        if total_mass == 0.0:
            continue
        f_in = connector[first - 1] if (first - 1) in connector else \
            (_boundary_force(system.start, x[0, 0], v[0, 0], True, t0) if first == 1 else 0.0)
        f_out = connector[last + 1] if (last + 1) in connector else \
            (_boundary_force(system.end, x[-1, 0], v[-1, 0], False, t0) if last == len(body) else 0.0)
        a[point:last + 1, 0] = (f_in - f_out + force) / total_mass
    return a


def _boundary_force(boundary, x: float, v: float, start: bool, t: float) -> float:
    """Force [N] of a force-type boundary on its point at time ``t`` [s] (spring, damper, applied force)."""
    if boundary.known != "force":
        raise ModelError(f"cannot start from a point element attached directly to {boundary.name!r}"
                         " with a prescribed displacement; put a connector in between")
    k, c = getattr(boundary, "stiffness", 0.0), getattr(boundary, "damping", 0.0)
    spring = -k * (x - getattr(boundary, "anchor", 0.0)) - c * v
    applied = float(boundary.force(t)) if hasattr(boundary, "force") else 0.0
    return spring + applied if start else -(spring + applied)


def initial_forces(system: Chain, x: np.ndarray, v: np.ndarray,
                    across: Mapping[int, float] | None = None, a: np.ndarray | None = None,
                    t0: float = 0.0) -> np.ndarray:
    """Internal forces at ``t0`` at every point.

    Connectors give the forces at their two points from their law (``across`` holds actuator
    forces acting across connectors, by element position); boundaries with a known force give
    theirs; the remaining points follow from the equilibrium of the point elements between them
    (``f_out = f_in - m a - c v - k x + F``), which needs the accelerations ``a``.
    """
    n = system.n_points
    f = np.full(n, np.nan)
    across = across or {}
    for j, val in _connector_forces(system, x, v, across, a).items():
        f[j - 1] = f[j] = val
    for boundary, point, start in ((system.start, 0, True), (system.end, n - 1, False)):
        if np.isnan(f[point]) and boundary.known == "force":
            f[point] = _boundary_force(boundary, x[point, 0], v[point, 0], start, t0)
    if a is None:
        return f
    body = system.body

    def residual(j: int) -> float:  # m a + c v + k x - F of the point element at position j
        e = body[j - 1]
        c = e.lumped_coefficients()
        if c is None or c.connector:
            return 0.0
        p = j - 1
        load = float(e.force(t0)) + across.get(j, 0.0)
        return c.mass * a[p, 0] + c.damping * v[p, 0] + c.stiffness * x[p, 0] - load

    for _ in range(2):  # forward then backward propagation through runs of point elements
        for j in range(1, n):
            if body[j - 1].is_point and np.isnan(f[j]) and not np.isnan(f[j - 1]):
                f[j] = f[j - 1] - residual(j)
        for j in range(n - 1, 0, -1):
            if body[j - 1].is_point and np.isnan(f[j - 1]) and not np.isnan(f[j]):
                f[j - 1] = f[j] + residual(j)
    return f
