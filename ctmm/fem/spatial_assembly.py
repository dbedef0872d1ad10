"""Assembly of spatial finite elements with named nodes into global matrices and a spatial subsystem.

:class:`SpatialFiniteElementModel` numbers the DOFs (per node ``u_x, u_y, u_z`` and, where a beam
touches it or it is a plate corner, ``r_x, r_y, r_z``; thick and triangular plates: their model-axes parts from
:mod:`ctmm.fem.thick_plate` and :mod:`ctmm.fem.triangle_plate`), assembles ``M`` (translational and rotary), ``K`` (elastic plus
geometric) and ``C`` (dampers plus Rayleigh ``a M + b K``), and integrates the floating-frame inertia
integrals of :class:`~ctmm.fem.SpatialInertia` by five-point Gauss quadrature of the element shape
functions (exact: polynomials of degree <= 6).  :meth:`SpatialFiniteElementModel.subsystem` turns it
into a :class:`~ctmm.fem.SpatialSubsystem`, a body of a :class:`ctmm.spatial.SpatialModel`.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .nodal_model import NodalModel
from .spatial_elements import (GAUSS_POINTS, GAUSS_WEIGHTS, SpatialBeamElement, SpatialNodeSpring, SpatialPointMass,
                               node_rotation_block, section_rotary_inertia, spatial_beam_axes,
                               spatial_beam_local_matrices, spatial_beam_shapes, spatial_shear_parameters)
from .spatial_plate import (PLATE_GAUSS_POINTS, PLATE_GAUSS_WEIGHTS, SpatialPlateElement, plate_axes,
                            plate_drilling_inertia, plate_local_matrices, plate_rotation_block, plate_shapes)
from .spatial_subsystem import SpatialInertia, SpatialSubsystem
from .thick_plate import SpatialThickPlateElement, thick_plate_parts
from .triangle_plate import SpatialTrianglePlateElement, triangle_plate_parts

__all__ = ["SpatialFiniteElementModel", "spatial_finite_element_subsystem"]

_FLAT_SHELLS = {SpatialThickPlateElement: thick_plate_parts, SpatialTrianglePlateElement: triangle_plate_parts}


def _element_nodes(element: Any) -> tuple[str, ...]:
    if isinstance(element, (SpatialPlateElement, *_FLAT_SHELLS)):
        return element.nodes
    return (element.node,) if isinstance(element, SpatialPointMass) else (element.start, element.end)


def _add_mass_points(sums: tuple, weights: np.ndarray, X: np.ndarray, S: np.ndarray, idx: np.ndarray) -> None:
    """Add mass points (masses ``weights`` (P,) [kg], positions ``X`` (P, 3) [m], interpolation ``S`` (P, 3, k) onto
    the DOFs ``idx``) to ``sums = (m, s0, int X X^T dm, S1, D, E)`` in place."""
    mass, first, second, S1, D, E = sums
    mass += weights.sum()
    first += weights @ X
    second += np.einsum("p,pi,pk->ik", weights, X, X)
    S1[:, idx] += np.einsum("p,pik->ik", weights, S)
    D[:, :, idx] += np.einsum("p,pi,pkl->ikl", weights, X, S)
    E[np.ix_(range(3), range(3), idx, idx)] += np.einsum("p,pik,pjl->ijkl", weights, S, S)


class SpatialFiniteElementModel(NodalModel):
    """Spatial finite-element model with named nodes (the builder shared with the planar model:
    :class:`~ctmm.fem.nodal_model.NodalModel`).

    Parameters
    ----------
    name : str
    nodes : mapping of str to (x, y, z)
        Undeformed node positions [m].
    elements : sequence
        :class:`~ctmm.fem.SpatialBeamElement`, :class:`~ctmm.fem.SpatialPlateElement`,
        :class:`~ctmm.fem.SpatialThickPlateElement`, :class:`~ctmm.fem.SpatialTrianglePlateElement`,
        :class:`~ctmm.fem.SpatialPointMass`, :class:`~ctmm.fem.SpatialNodeSpring`.
    rayleigh : (float, float)
        Rayleigh damping ``C += a M + b K`` with ``(a [1/s], b [s])``, >= 0; default none.

    Examples
    --------
    >>> from ctmm.fem import SpatialBeamElement, SpatialFiniteElementModel
    >>> fe = SpatialFiniteElementModel("beam", {"n0": (0, 0, 0), "n1": (0.5, 0, 0)},
    ...     [SpatialBeamElement("e0", "n0", "n1", 1e4, 3.0, 2.0, 2.0, 0.5)])
    >>> fe.n_dofs
    12
    """

    dimension, rotations = 3, 3
    element_types = (SpatialBeamElement, SpatialPlateElement, *_FLAT_SHELLS, SpatialPointMass, SpatialNodeSpring)
    rotating_types = (SpatialBeamElement, SpatialPlateElement, *_FLAT_SHELLS)
    point_mass_type, spring_type, subsystem_type = SpatialPointMass, SpatialNodeSpring, SpatialSubsystem

    element_nodes = staticmethod(_element_nodes)

    def _beam(self, e: SpatialBeamElement) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
        idx = np.array(self.dofs[e.start] + self.dofs[e.end])
        length, axes = spatial_beam_axes(self.positions[e.start], self.positions[e.end], e.orientation,
                                         f"{self.name}: {e.name}")
        return idx, length, axes, node_rotation_block(axes)

    def _plate(self, e: SpatialPlateElement) -> tuple[np.ndarray, float, float, np.ndarray, np.ndarray]:
        idx = np.array([i for node in e.nodes for i in self.dofs[node]])
        a, b, axes = plate_axes(np.array([self.positions[node] for node in e.nodes]), f"{self.name}: {e.name}")
        return idx, a, b, axes, plate_rotation_block(axes)

    def _flat_shell(self, e: Any) -> tuple[np.ndarray, Any]:
        """DOF indices and :class:`~ctmm.fem.flat_shell.FlatShellParts` of a thick or triangular plate."""
        idx = np.array([i for node in e.nodes for i in self.dofs[node]])
        corners = np.array([self.positions[node] for node in e.nodes])
        key = (type(e), e.thickness, e.youngs_modulus, e.poisson_ratio, e.density, e.drilling_stiffness_ratio,
               getattr(e, "shear_correction", None), (corners - corners[0]).tobytes())   # a regular mesh: computed once
        shells = self.__dict__.setdefault("_shells", {})
        if key not in shells:
            shells[key] = _FLAT_SHELLS[type(e)](e, corners, self.name)
        return idx, shells[key]

    def add_element(self, e: Any, M: np.ndarray, K: np.ndarray, cache: dict) -> None:
        """A beam's or a plate's matrices (model axes) into ``M`` and ``K``; equal plates of a regular mesh are
        computed once (``cache``)."""
        if isinstance(e, SpatialBeamElement):
            idx, length, _, T = self._beam(e)
            k, m_t, m_r, kg = spatial_beam_local_matrices(e, length)
            sub = np.ix_(idx, idx)
            K[sub] += T.T @ (k + kg) @ T
            M[sub] += T.T @ (m_t + m_r) @ T
        elif isinstance(e, tuple(_FLAT_SHELLS)):
            idx, parts = self._flat_shell(e)
            K[np.ix_(idx, idx)] += parts.stiffness
            M[np.ix_(idx, idx)] += parts.mass
        else:
            idx, a, b, _, T = self._plate(e)
            key = (e.thickness, e.youngs_modulus, e.poisson_ratio, e.density, e.drilling_stiffness_ratio, a, b)
            if key not in cache:
                cache[key] = plate_local_matrices(e, a, b)
            k, m, _ = cache[key]
            sub = np.ix_(idx, idx)
            K[sub] += T.T @ k @ T
            M[sub] += T.T @ m @ T

    def floating_inertia(self, origin: str) -> SpatialInertia:
        """Inertia integrals about node ``origin`` (:class:`~ctmm.fem.SpatialInertia`), by quadrature."""
        o = self.origin(origin)
        n = self.n_dofs
        sums = (np.zeros(()), np.zeros(3), np.zeros((3, 3)), np.zeros((3, n)), np.zeros((3, 3, n)),
                np.zeros((3, 3, n, n)))
        mass, first, second, S1, D, E = sums
        J_r, R_c = np.zeros((3, 3)), np.zeros((3, n))
        for e in self.elements:
            if isinstance(e, SpatialBeamElement):
                idx, length, axes, T = self._beam(e)
                N, _, _, rotations = spatial_beam_shapes(GAUSS_POINTS, length, spatial_shear_parameters(e, length))
                X = (self.positions[e.start] - o)[None, :] + GAUSS_POINTS[:, None] * length * axes[0][None, :]
                if e.mass_per_length:
                    S = np.einsum("ji,pjk,kl->pil", axes, N[:, :3], T)          # (P, 3, 12) model axes
                    _add_mass_points(sums, GAUSS_WEIGHTS * e.mass_per_length * length, X, S, idx)
                rotary = section_rotary_inertia(e)                            # local axes [kg m]
                if np.any(rotary):                 # sections turn by Omega + r(x) (torsion; Timoshenko bending)
                    tensor = axes.T @ np.diag(rotary) @ axes                  # model axes
                    J_r += length * tensor
                    R_c[:, idx] += tensor @ axes.T @ np.einsum("p,pik->ik", GAUSS_WEIGHTS * length, rotations) @ T
            elif isinstance(e, SpatialPlateElement):
                idx, a, b, axes, T = self._plate(e)
                S = np.einsum("ji,pjk,kl->pil", axes, plate_shapes(PLATE_GAUSS_POINTS, a, b), T)   # (P, 3, 24)
                X = (self.positions[e.nodes[0]] - o)[None, :] + np.outer(PLATE_GAUSS_POINTS[:, 0] * a, axes[0]) \
                    + np.outer(PLATE_GAUSS_POINTS[:, 1] * b, axes[1])
                _add_mass_points(sums, PLATE_GAUSS_WEIGHTS * e.density * e.thickness * a * b, X, S, idx)
                drilling = plate_drilling_inertia(e, a, b) * np.outer(axes[2], axes[2])   # lumped, about the normal
                for node in e.nodes:
                    J_r += drilling
                    R_c[:, list(self.dofs[node][3:])] += drilling
            elif isinstance(e, tuple(_FLAT_SHELLS)):
                idx, parts = self._flat_shell(e)
                X = parts.points + (self.positions[e.nodes[0]] - o)[None, :]
                _add_mass_points(sums, parts.point_masses, X, parts.shapes, idx)
                J_r += parts.rotary
                R_c[:, idx] += parts.rotary_coupling
            elif isinstance(e, SpatialPointMass):
                dofs = self.dofs[e.node]
                X = self.positions[e.node] - o
                mass += e.mass
                first += e.mass * X
                second += e.mass * np.outer(X, X)
                for k in range(3):
                    S1[k, dofs[k]] += e.mass
                    D[:, k, dofs[k]] += e.mass * X
                    for i in range(3):                               # E_ik = m e_(dof i) e_(dof k)^T
                        E[i, k, dofs[i], dofs[k]] += e.mass
                J_r += e.inertia
                if len(dofs) == 6:
                    R_c[:, list(dofs[3:])] += e.inertia
        return SpatialInertia(float(mass), first, second, S1, D, E, J_r, R_c)


def spatial_finite_element_subsystem(name: str, nodes: dict, elements: list, boundary: list, *,
                                     rayleigh: tuple[float, float] = (0.0, 0.0),
                                     frame_nodes: tuple[str, ...] = ()) -> SpatialSubsystem:
    """A spatial finite-element model as a body of a spatial model, in one call (scene files:
    ``type = "SpatialFiniteElementSubsystem"``):
    ``SpatialFiniteElementModel(name, nodes, elements, rayleigh=rayleigh).subsystem(name, boundary, frame_nodes=...)``.

    Parameters
    ----------
    name : str
        Model and body name.
    nodes : dict of str to (x, y, z)
        Undeformed node positions [m].
    elements : list
        ``SpatialBeamElement``, ``SpatialPlateElement``, ``SpatialThickPlateElement``,
        ``SpatialTrianglePlateElement``, ``SpatialPointMass``, ``SpatialNodeSpring``.
    boundary : list of str
        Boundary nodes, the inboard one first.
    rayleigh : (float, float)
        Rayleigh damping ``(a [1/s], b [s])``.
    frame_nodes : sequence of str
        Nodes held in the frame.
    """
    model = SpatialFiniteElementModel(name, nodes, elements, rayleigh=rayleigh)
    return model.subsystem(name, boundary, frame_nodes=tuple(frame_nodes))
