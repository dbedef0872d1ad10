"""Assembly of planar finite elements with named nodes into global matrices and a subsystem.

:class:`FiniteElementModel` numbers the DOFs (per node ``u_x, u_y`` and, where a beam touches it,
``r_z``), assembles ``M``, ``K`` (elastic plus geometric) and ``C`` (discrete dampers plus Rayleigh
``a M + b K``), and integrates the floating-frame inertia integrals of
:class:`~ctmm.fem.subsystem.FloatingInertia` by Gauss quadrature of the element shape functions
(exact: the integrands are polynomials of degree <= 6, five points per beam element; 3 x 3 points per
membrane quadrilateral, degree <= 3 in each of its parameters).
:meth:`FiniteElementModel.subsystem` turns it into a :class:`~ctmm.fem.GlobalSubsystem`, a body of a
planar model.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .elements import (BeamElement, NodeSpring, PointMass, beam_local_matrices, beam_rotation, beam_section_rotation,
                       beam_shape_functions)
from .membrane import MembraneElement, membrane_matrices, membrane_shape_points
from .nodal_model import NodalModel
from .subsystem import FloatingInertia, GlobalSubsystem
from .timoshenko import shear_parameter

__all__ = ["FiniteElementModel"]

_J = np.array([[0.0, -1.0], [1.0, 0.0]])
_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(5)
_XI, _WEIGHT = 0.5 * (_GAUSS_X + 1.0), 0.5 * _GAUSS_W


def _element_nodes(element: Any) -> tuple[str, ...]:
    if isinstance(element, PointMass):
        return (element.node,)
    if isinstance(element, MembraneElement):
        return element.nodes
    return (element.start, element.end)


class FiniteElementModel(NodalModel):
    """Planar finite-element model with named nodes (the builder shared with the spatial model:
    :class:`~ctmm.fem.nodal_model.NodalModel`).

    Parameters
    ----------
    name : str
    nodes : mapping of str to (x, y)
        Undeformed node positions [m].
    elements : sequence
        :class:`BeamElement`, :class:`PointMass`, :class:`NodeSpring`, :class:`~ctmm.fem.MembraneElement`.
    rayleigh : (float, float)
        Rayleigh damping ``C += a M + b K`` with ``(a [1/s], b [s])``, >= 0; default none.

    Examples
    --------
    >>> from ctmm.fem import BeamElement, FiniteElementModel
    >>> fe = FiniteElementModel("beam", {"n0": (0, 0), "n1": (0.5, 0), "n2": (1, 0)},
    ...     [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", 2.0, 1e4, 0.5) for k in (0, 1)])
    >>> fe.n_dofs
    9
    """

    dimension, rotations = 2, 1
    element_types = (BeamElement, PointMass, NodeSpring, MembraneElement)
    rotating_types = (BeamElement,)
    point_mass_type, spring_type, subsystem_type = PointMass, NodeSpring, GlobalSubsystem

    element_nodes = staticmethod(_element_nodes)

    # ------------------------------------------------------------------------------------
    def _beam(self, e: BeamElement) -> tuple[np.ndarray, float, np.ndarray]:
        idx = np.array(self.dofs[e.start] + self.dofs[e.end])
        length, T = beam_rotation(self.positions[e.start], self.positions[e.end], f"{self.name}: {e.name}")
        return idx, length, T

    def _membrane(self, e: MembraneElement) -> tuple[np.ndarray, np.ndarray]:
        idx = np.array([i for node in e.nodes for i in self.dofs[node][:2]])
        return idx, np.array([self.positions[node] for node in e.nodes])

    def add_element(self, e: Any, M: np.ndarray, K: np.ndarray, cache: dict) -> None:
        """A membrane's or a beam's matrices (global axes) into ``M`` and ``K``."""
        if isinstance(e, MembraneElement):
            idx, corners = self._membrane(e)
            k, m = membrane_matrices(e, corners, self.name)
            K[np.ix_(idx, idx)] += k
            M[np.ix_(idx, idx)] += m
        else:
            idx, length, T = self._beam(e)
            k, m, kg = beam_local_matrices(length, e.bending_stiffness, e.axial_stiffness, e.mass_per_length,
                                           e.axial_force, shear_stiffness=e.shear_stiffness,
                                           rotary_inertia_per_length=e.rotary_inertia_per_length)
            sub = np.ix_(idx, idx)
            K[sub] += T.T @ (k + kg) @ T
            M[sub] += T.T @ m @ T

    def floating_inertia(self, origin: str) -> FloatingInertia:
        """Inertia integrals about node ``origin`` (:class:`~ctmm.fem.subsystem.FloatingInertia`), by quadrature."""
        o = self.origin(origin)
        n = self.n_dofs
        mass, first, polar = 0.0, np.zeros(2), 0.0
        S1, sigma, gamma = np.zeros((2, n)), np.zeros(n), np.zeros(n)
        G, Mt = np.zeros((n, n)), np.zeros((n, n))
        points = []                                     # (masses (P,), positions (P, 2), shapes (P, 2, k), DOFs)
        for e in self.elements:
            if isinstance(e, MembraneElement):
                if e.density == 0.0:
                    continue
                idx, corners = self._membrane(e)
                quadrature, area, S = membrane_shape_points(corners, f"{self.name}: {e.name}")
                X = quadrature - o                                               # (9, 2)
                w = e.density * e.thickness * area                               # (9,) [kg]
                points.append((w, X, S, idx))
            elif isinstance(e, BeamElement):
                if e.mass_per_length == 0.0:
                    continue
                idx, length, T = self._beam(e)
                r2 = T[:2, :2]
                a = self.positions[e.start] - o
                direction = (self.positions[e.end] - self.positions[e.start]) / length
                shear = shear_parameter(e.name, e.bending_stiffness, e.shear_stiffness, length)
                N = beam_shape_functions(_XI, length, shear)                    # (5, 2, 6) local
                S = np.einsum("ji,pjk,kl->pil", r2, N, T)                        # (5, 2, 6) frame axes
                X = a[None, :] + _XI[:, None] * length * direction[None, :]     # (5, 2)
                w = _WEIGHT * e.mass_per_length * length                         # (5,)
                points.append((w, X, S, idx))
                if e.rotary_inertia_per_length:              # sections turn by omega + theta_dot (docs/mixed.md §7c)
                    polar += e.rotary_inertia_per_length * length
                    gamma[idx] += e.rotary_inertia_per_length * length * (_WEIGHT @ beam_section_rotation(
                        _XI, length, shear)) @ T
            elif isinstance(e, PointMass):
                dofs = self.dofs[e.node]
                X = self.positions[e.node] - o
                ix, iy = dofs[:2]
                m = e.mass
                mass += m
                first += m * X
                polar += m * float(X @ X) + e.inertia
                S1[0, ix] += m
                S1[1, iy] += m
                sigma[ix] += m * X[0]
                sigma[iy] += m * X[1]
                gamma[ix] += -m * X[1]
                gamma[iy] += m * X[0]
                G[ix, iy] += -m
                G[iy, ix] += m
                Mt[ix, ix] += m
                Mt[iy, iy] += m
                if len(dofs) == 3:               # else it turns with the frame: in polar only
                    gamma[dofs[2]] += e.inertia
        for w, X, S, idx in points:                     # mass points of beams and membranes (quadrature)
            mass += w.sum()
            first += w @ X
            polar += float(w @ (X * X).sum(1))
            S1[:, idx] += np.einsum("p,pik->ik", w, S)
            sigma[idx] += np.einsum("p,pi,pik->k", w, X, S)
            gamma[idx] += np.einsum("p,pik,ij,pj->k", w, S, _J, X)
            G[np.ix_(idx, idx)] += np.einsum("p,pik,ij,pjl->kl", w, S, _J, S)
            Mt[np.ix_(idx, idx)] += np.einsum("p,pik,pil->kl", w, S, S)
        return FloatingInertia(mass, first, polar, S1, sigma, gamma, G, Mt)
