"""Spatial mechanisms with closed loops for the tests of ``ctmm.spatial.closed_loops`` and their independent
references (:mod:`ctmm.reference.spatial_loop_dae`): the R-U-S-R four-bar, the DAE of a loop model and the map of a
tree state to the DAE's absolute coordinates are the scenario ``spatial_four_bar``'s; here a revolute-cut pendulum and
a closed triangle of rods."""
from __future__ import annotations

import numpy as np

import ctmm.spatial as sp
from ctmm.scenarios.spatial_four_bar import dae_of, mechanism as rusr, poses, rod
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

__all__ = ["dae_of", "rusr", "poses", "rod", "hinged_pendulum", "hooke_pendulum", "triangle", "triangle_guess"]


def hinged_pendulum(baumgarte: float = 20.0) -> SpatialKinematicLoopModel:
    """A body on a free joint held at the ground by a revolute cut about world y at its origin: a compound
    pendulum (1 degree of freedom, 5 independent cut rows); centre of mass at (0.1, 0, -0.3) body axes."""
    tree = sp.SpatialModel("hinged", [
        sp.SpatialBody("p", 1.2, np.diag([0.02, 0.03, 0.025]), center_of_mass=(0.1, 0.0, -0.3)),
        sp.Free(name="free", parent=None, child="p")])
    return SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="hinge", parent=None, child="p", kind="revolute",
                                                            axis=(0, 1, 0))], baumgarte=baumgarte)


def hooke_pendulum(baumgarte: float = 20.0) -> SpatialKinematicLoopModel:
    """A body on a free joint held at the ground by a universal (Hooke) cut at its origin, cross axes world x
    (parent) and body y (child): 2 degrees of freedom, 4 cut rows; centre of mass at (0, 0, -0.3) body axes."""
    tree = sp.SpatialModel("hooke", [
        sp.SpatialBody("p", 1.2, np.diag([0.02, 0.03, 0.025]), center_of_mass=(0.0, 0.0, -0.3)),
        sp.Free(name="free", parent=None, child="p")])
    return SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="hooke", parent=None, child="p", kind="universal",
                                                            axis=(0, 1, 0), parent_axis=(1, 0, 0))],
                                     baumgarte=baumgarte)


def triangle(baumgarte: float = 20.0) -> SpatialKinematicLoopModel:
    """Three rods in a ring of ball joints hanging from a ball joint at the origin: rod a on the ground, b at a's
    tip, c at b's tip, and the spherical cut joins c's tip to a's origin (6 degrees of freedom: the ring's rotation
    and the rods' spins)."""
    tree = sp.SpatialModel("triangle", [
        rod("a", 0.5, 0.3), sp.Spherical(name="ja", parent=None, child="a"),
        rod("b", 0.7, 0.3), sp.Spherical(name="jb", parent="a", point="tip", child="b"),
        rod("c", 0.6, 0.3), sp.Spherical(name="jc", parent="b", point="tip", child="c")])
    return SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="close", parent="a", child="c", child_point="tip")],
                                     baumgarte=baumgarte)


def triangle_guess() -> dict:
    """A configuration near an assembled triangle (quaternions of the three ball joints)."""
    def about(axis, angle):
        axis = np.asarray(axis, float) / np.linalg.norm(axis)
        return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])
    values = {}
    for joint, quaternion in (("ja", about((0.2, 1, 0.1), 1.0)), ("jb", about((0.1, 1, 0), -2.0)),
                              ("jc", about((0, 1, 0.2), -2.1))):
        values.update({f"{joint}.q{c}": x for c, x in zip("wxyz", quaternion)})
    return values
