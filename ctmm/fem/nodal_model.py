"""What the planar and spatial finite-element models share: one dimension-generic builder.

:class:`NodalModel` is the base of :class:`~ctmm.fem.FiniteElementModel` (planar, ``d = 2`` translations and
one rotation per rotating node) and :class:`~ctmm.fem.SpatialFiniteElementModel` (``d = 3``, three rotations).
It checks the nodes, elements and Rayleigh damping, numbers the DOFs (rotations at the nodes of the
``rotating_types`` elements), assembles ``M``, ``K`` and ``C`` -- point masses and node springs here, in ``d``
dimensions; beams, membranes and plates in the subclass's :meth:`NodalModel.add_element` -- and turns the model
into a subsystem (:meth:`NodalModel.subsystem`) or its clamped natural frequencies.  What differs in physics
(element matrices, the floating-frame inertia integrals of each dimension) stays in the subclasses.
"""
from __future__ import annotations

from typing import Any, Callable, ClassVar, Mapping, Sequence

import numpy as np

from .. import validation
from ..errors import ModelError
from .model_parts import (check_springs, checked_elements, clamped_frequencies, known_nodes, node_positions,
                          number_dofs, rayleigh_pair)

__all__ = ["NodalModel"]


class NodalModel:
    """A finite-element model with named nodes in ``dimension`` dimensions (module docstring).

    Subclasses set the class attributes and implement :meth:`element_nodes`, :meth:`add_element` and
    ``floating_inertia``.

    Parameters
    ----------
    name : str
    nodes : mapping of str to coordinates
        Undeformed node positions [m] (``dimension`` numbers each).
    elements : sequence
        Elements of the ``element_types``.
    rayleigh : (float, float)
        Rayleigh damping ``C += a M + b K`` with ``(a [1/s], b [s])``, >= 0; default none.
    """

    dimension: ClassVar[int]
    """Translations per node (2 planar, 3 spatial)."""
    rotations: ClassVar[int]
    """Rotations per rotating node (1 planar, 3 spatial)."""
    element_types: ClassVar[tuple]
    """Element classes allowed."""
    rotating_types: ClassVar[tuple]
    """Element classes whose nodes get rotation DOFs."""
    point_mass_type: ClassVar[type]
    """Point masses (``node``, ``mass`` [kg], ``inertia`` about the node [kg m^2])."""
    spring_type: ClassVar[type]
    """Node springs (``start``, ``end``, axial and rotational stiffness and damping)."""
    subsystem_type: ClassVar[type]
    """The subsystem body :meth:`subsystem` builds."""

    def __init__(self, name: str, nodes: Mapping[str, Sequence[float]], elements: Sequence[Any], *,
                 rayleigh: Sequence[float] = (0.0, 0.0)) -> None:
        self.name = validation.name("model", name)
        self.positions = node_positions(name, nodes, self.dimension)
        self.elements = checked_elements(name, elements, self.element_types, self.element_nodes, self.positions)
        self.rayleigh = rayleigh_pair(name, rayleigh)
        rotating = {n for e in self.elements if isinstance(e, self.rotating_types) for n in self.element_nodes(e)}
        self.dofs, self.n_dofs = number_dofs(self.positions, rotating, self.dimension, self.rotations)
        check_springs(name, [e for e in self.elements if isinstance(e, self.spring_type)], self.dofs, self.positions,
                      self.dimension + self.rotations)
        self.mass, self.stiffness, self.damping = self._assemble()

    @staticmethod
    def element_nodes(element: Any) -> tuple[str, ...]:
        """The nodes an element joins."""
        raise NotImplementedError

    def add_element(self, element: Any, M: np.ndarray, K: np.ndarray, cache: dict) -> None:
        """Add a beam, membrane or plate element's matrices to ``M`` and ``K`` in place (``cache``: shared by the
        elements of one assembly, e.g. equal plates of a regular mesh)."""
        raise NotImplementedError

    def _assemble(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n, d = self.n_dofs, self.dimension
        M, K, C = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
        cache: dict = {}
        for e in self.elements:
            if isinstance(e, self.point_mass_type):
                dofs = self.dofs[e.node]
                for i in dofs[:d]:
                    M[i, i] += e.mass
                if len(dofs) > d:                       # else it turns with the floating frame
                    M[np.ix_(dofs[d:], dofs[d:])] += e.inertia
            elif isinstance(e, self.spring_type):
                self._add_spring(e, K, C)
            else:
                self.add_element(e, M, K, cache)
        C += self.rayleigh[0] * M + self.rayleigh[1] * K
        return M, K, C

    def _add_spring(self, e: Any, K: np.ndarray, C: np.ndarray) -> None:
        """A node spring: axial along the undeformed line of its nodes, rotational on each rotation DOF pair."""
        n, d = self.n_dofs, self.dimension
        a, b = self.dofs[e.start], self.dofs[e.end]
        if e.stiffness or e.damping:
            line = self.positions[e.end] - self.positions[e.start]
            unit = line / np.linalg.norm(line)
            row = np.zeros(n)
            row[list(b[:d])] = unit
            row[list(a[:d])] -= unit
            K += e.stiffness * np.outer(row, row)
            C += e.damping * np.outer(row, row)
        if e.rotational_stiffness or e.rotational_damping:
            for k in range(self.rotations):
                row = np.zeros(n)
                row[b[d + k]], row[a[d + k]] = 1.0, -1.0
                K += e.rotational_stiffness * np.outer(row, row)
                C += e.rotational_damping * np.outer(row, row)

    def origin(self, node: str) -> np.ndarray:
        """Undeformed position [m] of ``node``, the origin of the inertia integrals, else :class:`ModelError`."""
        if node not in self.positions:
            raise ModelError(f"{self.name}: unknown node {node!r}; nodes: {', '.join(self.positions)}")
        return self.positions[node]

    def subsystem(self, name: str, boundary: Sequence[str], *, nonlinear_force: Callable | None = None,
                  frame_nodes: Sequence[str] = (), potential: Callable | None = None) -> Any:
        """This model as a body of a planar or spatial model (:attr:`subsystem_type`:
        :class:`~ctmm.fem.GlobalSubsystem`, :class:`~ctmm.fem.SpatialSubsystem`).

        Parameters
        ----------
        name : str
            Body name (coordinates ``"name.<node>_ux"`` ...).
        boundary : sequence of str
            Boundary nodes, the inboard one first (it carries the frame); the others are the body's points.
        nonlinear_force : callable, optional
            ``f(u, u_dot, t)`` over all DOFs (as the subsystem takes it).
        frame_nodes : sequence of str
            Nodes fixed in the frame.
        potential : callable, optional
            ``V(u)`` [J] of ``nonlinear_force``, for the energy.
        """
        boundary = known_nodes(self.name, "boundary (the inboard node first)", boundary, self.positions,
                               allow_empty=False)
        inertia = self.floating_inertia(boundary[0])
        o = self.positions[boundary[0]]
        nodes = {node: (tuple(self.positions[node] - o), self.dofs[node]) for node in self.positions}
        return self.subsystem_type(name, mass_matrix=self.mass, damping_matrix=self.damping,
                                   stiffness_matrix=self.stiffness, nodes=nodes, boundary=boundary,
                                   nonlinear_force=nonlinear_force, inertia_integrals=inertia,
                                   frame_nodes=frame_nodes, potential=potential)

    def floating_inertia(self, origin: str) -> Any:
        """Inertia integrals about node ``origin`` (the subclass's record), by quadrature."""
        raise NotImplementedError

    def natural_frequencies(self, clamped: Sequence[str] = ()) -> np.ndarray:
        """Natural frequencies [rad/s] with the DOFs of the ``clamped`` nodes held (``eigh(K, M)``); a statically
        unstable structure (e.g. compressed above buckling) is refused with :class:`~ctmm.errors.ModelError`."""
        return clamped_frequencies(self.name, self.stiffness, self.mass, self.dofs, clamped)
