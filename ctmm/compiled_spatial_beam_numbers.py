"""The numbers of a modal spatial beam as inputs of the generated spatial terms (issue 17).

A :class:`~ctmm.spatial.beam.SpatialBeam`'s terms (:func:`~ctmm.spatial.beam_terms.spatial_beam_terms`) are,
at a fixed state, linear in its mass per length ``rhoA`` and its polar mass moment per length ``j_p``: every
modal integral of the mass matrix and of the velocity terms is ``rhoA`` (or ``j_p``) times a shape-only
integral, the geometric stiffening of the axial force too (``rhoA`` times the ``G2``, ``G3`` integrals), and
gravity enters as ``rhoA g``.  The elastic rows are ``K eta + D eta_dot`` with

    K = EI_y K_y + EI_z K_z + GJ K_t + EA K_a  (+ hooks),
    D = mu K + 2 zeta diag(sqrt(diag K  diag M_mod))  (+ hooks),   M_mod = rhoA M_rhoA + j_p M_jp,

(``K_d`` the unit-stiffness block of direction ``d``, :class:`~ctmm.spatial.beam_modes.SpatialBeamData`).  So
the terms with the numbers as expressions are the model's numeric terms plus

    M += (rhoA - rhoA0) M[rhoA] + (j_p - j_p0) M[j_p],
    h += (rhoA - rhoA0) h[rhoA] + (j_p - j_p0) h[j_p] + sum_k (rhoA g_k - rhoA0 g0_k) (h[rhoA, e_k] - h[rhoA])
         + [0 ; (K - K0) eta + (D - D0) eta_dot],

the bracketed terms being :func:`~ctmm.spatial.beam_terms.spatial_beam_terms` of the same beam with unit
numbers on the same pose (``[rhoA]``: unit ``rhoA``, no ``j_p``, stiffness, damping, hooks or distributed load;
``[j_p]``: unit ``j_p`` alone; ``e_k`` unit gravity along world axis ``k``).  This keeps the one statement of
the beam's physics; at the model's numbers the added terms are zero.  The beam's length, mode counts, stations,
hooks and loads are constants (its shapes depend on the length).
"""
from __future__ import annotations

import copy
from dataclasses import replace
from types import SimpleNamespace
from typing import Any, Mapping

import numpy as np

from .errors import ModelError
from .ops import CASADI
from .protocol import BodyTerms
from .signals import Constant
from .spatial.beam_terms import spatial_beam_terms

__all__ = ["BEAM_NUMBERS", "beam_numbers", "parametrised_beam_terms"]

BEAM_NUMBERS = (("mass_per_length", "kg/m"), ("polar_inertia_per_length", "kg m"), ("bending_stiffness_y", "N m^2"),
                ("bending_stiffness_z", "N m^2"), ("torsional_stiffness", "N m^2"), ("axial_stiffness", "N"),
                ("damping_ratio", "-"), ("stiffness_damping", "s"))
"""The numbers of a spatial beam that are parameters (attribute name, unit), when non-zero."""
_DIRECTIONS = (("y", "bending_stiffness_y"), ("z", "bending_stiffness_z"), ("t", "torsional_stiffness"),
               ("a", "axial_stiffness"))


def beam_numbers(beam: Any) -> list[tuple[str, str, float]]:
    """``(attribute, unit, value)`` of the non-zero numbers of ``beam`` (:data:`BEAM_NUMBERS`); a stiffness of a
    direction without modes is left out (it enters nothing)."""
    counts = beam.direction_counts
    out = []
    for attribute, unit in BEAM_NUMBERS:
        value = getattr(beam, attribute)
        direction = next((d for d, name in _DIRECTIONS if name == attribute), None)
        if value is None or float(value) == 0.0 or (direction is not None and not counts[direction]):
            continue
        if getattr(beam, "wagner_term", False) and attribute in ("mass_per_length", "polar_inertia_per_length"):
            continue          # the Wagner block (j_p / rhoA) N is not linear in them: compiled as constants
        out.append((attribute, unit, float(value)))
    return out


def _view(beam: Any, *, mass: float, polar: float, stiffening: bool) -> Any:
    """A stand-in of ``beam`` for :func:`spatial_beam_terms` with mass per length ``mass`` (0 or 1: the
    stiffening integrals are taken at unit mass per length) and polar inertia per length ``polar`` (the model's
    shape integrals rescaled), no stiffness, damping, hooks or distributed load."""
    data = beam.data
    view = copy.copy(data)
    a = mass / data.rhoA
    b = polar / data.jp if data.jp else 0.0
    view.rhoA = 1.0                       # divides only the (zero) distributed load
    view.E = [[a * block for block in row] for row in data.E]
    view.b, view.c, view.m = a * data.b, a * data.c, a * data.m
    view.first_moment, view.second_moment = a * data.first_moment, a * data.second_moment
    view.jp, view.b_t, view.M_t = polar, b * data.b_t, b * data.M_t
    view.modal_mass = view.E[0][0] + view.E[1][1] + view.E[2][2] + view.M_t
    view.K_total = view.D_total = np.zeros_like(data.K)
    view.forces = []
    view.stiffening = stiffening
    return SimpleNamespace(data=view, points=beam.points, distributed_load=(Constant(0.0),) * 3)


def parametrised_beam_terms(beam: Any, terms: BodyTerms, numbers: Mapping[str, Any], gravity: list, *,
                            model_gravity: np.ndarray, rotation: Any, offset: Any, omega: Any, eta: Any,
                            eta_dot: Any) -> BodyTerms:
    """The beam's numeric casadi ``terms`` (of the model's numbers, at the pose ``rotation``, ``offset``,
    ``omega`` and the modal state ``eta``, ``eta_dot``) with the numbers ``numbers`` (``{attribute:
    expression}``; missing ones the model's) and ``gravity`` (3 expressions or numbers) in place of the model's
    (module docstring)."""
    import casadi as ca

    data = beam.data
    if np.any(data.rotary):           # _view does not scale the bending sections' terms: refused, not mis-scaled
        raise ModelError(f"{beam.name}: numbers='inputs' (parameters=, simulate_batch) does not take a SpatialBeam with "
                         "section rotary inertia (rotary_inertia_per_length_y|z); use compiled=True without "
                         "parameters= or compiled=False")
    value = {attribute: numbers.get(attribute, getattr(beam, attribute) or 0.0) for attribute, _ in BEAM_NUMBERS}
    pose = dict(rotation=rotation, offset=offset, omega=omega, eta=eta, eta_dot=eta_dot, t=0.0)

    def unit(view: Any, g: np.ndarray) -> BodyTerms:
        return spatial_beam_terms(CASADI, view, gravity=g, **pose)[0]

    mass_view = _view(beam, mass=1.0, polar=0.0, stiffening=data.stiffening)
    by_mass = unit(mass_view, np.zeros(3))
    rhoA, rhoA0 = value["mass_per_length"], data.rhoA
    M = terms.M + by_mass.M * (rhoA - rhoA0)
    h = terms.h + by_mass.h * (rhoA - rhoA0)
    g0 = np.asarray(model_gravity, dtype=float)
    for k in range(3):
        if isinstance(gravity[k], (int, float)) and gravity[k] == 0.0 and g0[k] == 0.0:
            continue
        h = h + (unit(mass_view, np.eye(3)[k]).h - by_mass.h) * (rhoA * gravity[k] - rhoA0 * g0[k])
    if data.jp:
        by_polar = unit(_view(beam, mass=0.0, polar=1.0, stiffening=False), np.zeros(3))
        M = M + by_polar.M * (value["polar_inertia_per_length"] - data.jp)
        h = h + by_polar.h * (value["polar_inertia_per_length"] - data.jp)
    K = ca.SX.zeros(data.n, data.n)
    for direction, attribute in _DIRECTIONS:
        block = data.columns[direction]
        if block.stop > block.start:
            stiffness = float(getattr(beam, attribute))
            K[block, block] = ca.DM(data.K[block, block] / stiffness) * value[attribute]
    D = K * value["stiffness_damping"]
    if beam.damping_ratio:
        mass_diagonal = np.diag(mass_view.data.modal_mass)
        polar_diagonal = np.diag(data.M_t) / data.jp if data.jp else np.zeros(data.n)
        for i in range(data.n):
            D[i, i] = D[i, i] + 2 * value["damping_ratio"] * ca.sqrt(
                K[i, i] * (rhoA * mass_diagonal[i] + value["polar_inertia_per_length"] * polar_diagonal[i]))
    elastic = ca.mtimes(K - ca.DM(data.K), eta) + ca.mtimes(D - ca.DM(data.D), eta_dot)
    return replace(terms, M=M, h=h + ca.vertcat(ca.SX.zeros(6, 1), elastic))
