"""The builder and the subsystem inputs the planar and spatial finite-element models share
(``ctmm/fem/nodal_model.py``, ``ctmm/fem/model_parts.py``): the same rules in 2-D and 3-D.

Independent checks: the mass and stiffness of two point masses joined by a node spring (axial and rotational)
written here from their definitions (``k (u_b - u_a)^2 / 2`` along the undeformed line, ``k_r (r_b - r_a)^2 / 2``
about each rotation axis); the refusals of a subsystem's nodes, boundary and callables in both dimensions.
"""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.errors import ModelError
from ctmm.fem import (BeamElement, FiniteElementModel, GlobalSubsystem, NodeSpring, PointMass, SpatialBeamElement,
                      SpatialFiniteElementModel, SpatialNodeSpring, SpatialPointMass, SpatialSubsystem)


def test_point_masses_and_node_springs_in_two_and_three_dimensions():
    """Masses m_a, m_b on the diagonal; an axial spring k along the unit line n: K = k (e_b - e_a)(e_b - e_a)^T
    over the translations projected on n; a rotational spring k_r on each rotation DOF pair (a beam gives the
    nodes rotation DOFs; its matrices are subtracted by building the same model without the spring)."""
    k, c, kr, cr = 7.0, 0.3, 2.0, 0.1
    for dimension in (2, 3):
        line = np.array([0.6, 0.8, 0.0][:dimension])
        nodes = {"a": (0.0,) * dimension, "b": tuple(line)}
        if dimension == 2:
            beam = BeamElement("e", "a", "b", 1.0, 10.0, 0.5)
            masses = [PointMass("pa", "a", 1.5, 0.2), PointMass("pb", "b", 2.5, 0.4)]
            spring = NodeSpring("s", "a", "b", k, c, kr, cr)
            build = FiniteElementModel
        else:
            beam = SpatialBeamElement("e", "a", "b", 10.0, 1.0, 1.0, 1.0, 0.5)
            masses = [SpatialPointMass("pa", "a", 1.5, (0.2, 0.2, 0.2)), SpatialPointMass("pb", "b", 2.5, (0.4,) * 3)]
            spring = SpatialNodeSpring("s", "a", "b", k, c, kr, cr)
            build = SpatialFiniteElementModel
        bare = build("m", nodes, [beam])
        full = build("m", nodes, [beam, *masses, spring])
        per_node = bare.n_dofs // 2
        rotations = per_node - dimension
        a, b = np.arange(per_node), per_node + np.arange(per_node)
        added_mass = np.zeros((2 * per_node,) * 2)
        added_mass[a[:dimension], a[:dimension]] = 1.5
        added_mass[b[:dimension], b[:dimension]] = 2.5
        added_mass[a[dimension:], a[dimension:]] = 0.2
        added_mass[b[dimension:], b[dimension:]] = 0.4
        axial = np.zeros(2 * per_node)
        axial[b[:dimension]], axial[a[:dimension]] = line, -line
        added_stiffness = k * np.outer(axial, axial)
        added_damping = c * np.outer(axial, axial)
        for r in range(rotations):
            row = np.zeros(2 * per_node)
            row[b[dimension + r]], row[a[dimension + r]] = 1.0, -1.0
            added_stiffness += kr * np.outer(row, row)
            added_damping += cr * np.outer(row, row)
        np.testing.assert_allclose(full.mass - bare.mass, added_mass, rtol=0, atol=1e-14)
        np.testing.assert_allclose(full.stiffness - bare.stiffness, added_stiffness, rtol=0, atol=1e-12)
        np.testing.assert_allclose(full.damping - bare.damping, added_damping, rtol=0, atol=1e-14)


def _subsystem(dimension, **changes):
    n = 2 * dimension
    arguments = dict(mass_matrix=np.eye(n), damping_matrix=np.zeros((n, n)), stiffness_matrix=np.eye(n),
                     nodes={"a": ((0.0,) * dimension, tuple(range(dimension))),
                            "b": ((1.0,) + (0.0,) * (dimension - 1), tuple(range(dimension, n)))},
                     boundary=("a",))
    arguments.update(changes)
    return (GlobalSubsystem if dimension == 2 else SpatialSubsystem)("g", **arguments)


@pytest.mark.parametrize("dimension", [2, 3])
@pytest.mark.parametrize("change, message", [
    (lambda d: {"nodes": {"a": ((0.0,) * d, tuple(range(d))), "b": ((1.0,) * d, tuple(range(d)))}},
     r"DOF 0 belongs to two nodes \('a' and 'b'\)"),
    (lambda d: {"nodes": {"a": ((0.0,) * d, tuple(range(d)))}}, r"DOFs \[\d(, \d)*\] belong to no node"),
    (lambda d: {"nodes": {"a": ((0.0,) * (d + 1), tuple(range(d))), "b": ((1.0,) * d, tuple(range(d, 2 * d)))}},
     r"nodes\['a'\] must be \(\(x, y"),
    (lambda d: {"boundary": ("a", "a")}, "boundary must name distinct nodes"),
    (lambda d: {"boundary": "a"}, "boundary must be a list of node names"),
    (lambda d: {"frame_nodes": ("a",)}, r"frame_nodes \['a'\] must be nodes that are not boundary nodes"),
    (lambda d: {"potential": 3.0}, r"potential must be callable V\(u\)"),
    (lambda d: {"nonlinear_force": "f"}, r"nonlinear_force must be callable f\(u, u_dot, t\)"),
])
def test_subsystem_inputs_are_refused_by_one_rule_in_both_dimensions(dimension, change, message):
    _subsystem(dimension)                            # the unchanged inputs are valid
    with pytest.raises(ModelError, match=message):
        _subsystem(dimension, **change(dimension))
