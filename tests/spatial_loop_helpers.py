"""Spatial mechanisms with closed loops for the tests of ``ctmm.spatial.closed_loops`` and their independent
references (:mod:`ctmm.reference.spatial_loop_dae`): the tree models, the matching DAE descriptions and the map of a
tree state to the DAE's absolute coordinates."""
from __future__ import annotations

import numpy as np

import ctmm.spatial as sp
from ctmm.ops import NUMPY
from ctmm.reference.spatial_loop_dae import DaeBody, DaeJoint, SpatialLoopDAE
from ctmm.spatial.body_forms import SpatialScene
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel


def rod(name: str, mass: float, length: float, direction: int = 0, width: float = 0.03, points=None) -> sp.SpatialBody:
    """A slender box of ``length`` along body axis ``direction`` from the origin, centre of mass at mid-length."""
    moments = np.full(3, mass * (length ** 2 + width ** 2) / 12.0)
    moments[direction] = mass * 2 * width ** 2 / 12.0
    com = np.zeros(3)
    com[direction] = 0.5 * length
    tip = np.zeros(3)
    tip[direction] = length
    return sp.SpatialBody(name, mass, np.diag(moments), center_of_mass=com, points={"tip": tip, **(points or {})})


def rusr(baumgarte: float = 20.0) -> SpatialKinematicLoopModel:
    """A spatial four-bar R-U-S-R under gravity: a crank hanging on a revolute about world x at the origin, a
    coupler on a universal joint at the crank's tip, a rocker hanging on a revolute about world y at
    (0.5, 0.2, 0); the spherical cut joins the coupler's tip to the rocker's (1 degree of freedom)."""
    down = np.diag([1.0, -1.0, -1.0])                   # joint frames turned so that the links hang along -z
    tree = sp.SpatialModel("rusr", [
        rod("crank", 0.4, 0.2, direction=2),
        sp.Revolute(name="h1", parent=None, child="crank", axis=(1, 0, 0), rotation=down, actuated=True),
        rod("coupler", 1.0, 0.55),
        sp.Universal(name="u2", parent="crank", point="tip", child="coupler", axis1=(0, 0, 1), axis2=(0, 1, 0)),
        rod("rocker", 0.8, 0.4, direction=2),
        sp.Revolute(name="h4", parent=None, point=(0.5, 0.2, 0.0), child="rocker", axis=(0, 1, 0), rotation=down)])
    return SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="s3", parent="rocker", point="tip",
                                                            child="coupler", child_point="tip")], baumgarte=baumgarte)


def dae_of(loop: SpatialKinematicLoopModel, baumgarte: float = 10.0) -> SpatialLoopDAE:
    """The DAE of a loop model: every tree joint and cut joint as constraint rows, points from the centres of mass."""
    tree = loop.tree
    names = [b.name for b in tree.bodies]
    bodies = [DaeBody(b.name, b.mass, b.inertia) for b in tree.bodies]
    joints = []

    def local(body: str | None, point, rotation=None):
        if body is None:
            return -1, np.asarray(point, float)
        j = names.index(body)
        b = tree.bodies[j]
        return j, (b.points[point] if isinstance(point, str) else np.asarray(point, float)) - b.center_of_mass

    for joint in tree.joints:
        parent, p_point = local(joint.parent, joint.point if joint.parent is not None else joint.point)
        child, c_point = local(joint.child, "origin")
        R_J = np.eye(3) if joint.rotation is None else np.asarray(joint.rotation)
        if joint.kind == "revolute":
            joints.append(DaeJoint(joint.name, "revolute", parent, p_point, child, c_point,
                                   parent_axis=R_J @ joint.axis, child_axis=joint.axis))
        elif joint.kind == "universal":
            joints.append(DaeJoint(joint.name, "universal", parent, p_point, child, c_point,
                                   parent_axis=R_J @ joint.axis1, child_axis=joint.axis2))
        elif joint.kind == "spherical":
            joints.append(DaeJoint(joint.name, "ball", parent, p_point, child, c_point))
        elif joint.kind != "free":                       # a free joint: no rows

            raise ValueError(joint.kind)
    for cut in loop.cuts:
        parent, p_point = local(cut.parent, cut.point)
        child, c_point = local(cut.child, cut.child_point)
        joints.append(DaeJoint(cut.name, "revolute" if cut.kind == "revolute" else "ball", parent, p_point, child,
                               c_point, parent_axis=cut.parent_axis, child_axis=cut.axis))
    return SpatialLoopDAE(bodies, joints, gravity=tree.gravity, baumgarte=baumgarte)


def poses(loop: SpatialKinematicLoopModel, q, v) -> tuple[list, list, list, list]:
    """Centre-of-mass positions, rotations, centre-of-mass velocities and angular velocities (world) of the tree's
    bodies at ``(q, v)``."""
    states = SpatialScene(loop.tree).terms(NUMPY, np.asarray(q, float)[None], np.asarray(v, float)[None])[2]
    x, R, vc, w = [], [], [], []
    for body, s in zip(loop.tree.bodies, states):
        rot = np.asarray(s.rotation)[0]
        arm = rot @ body.center_of_mass
        omega = np.asarray(s.omega).reshape(-1, 3)[0]
        x.append(np.asarray(s.origin).reshape(-1, 3)[0] + arm)
        R.append(rot)
        vc.append(np.asarray(s.velocity).reshape(-1, 3)[0] + np.cross(omega, arm))
        w.append(omega)
    return x, R, vc, w


def hinged_pendulum(baumgarte: float = 20.0) -> SpatialKinematicLoopModel:
    """A body on a free joint held at the ground by a revolute cut about world y at its origin: a compound
    pendulum (1 degree of freedom, 5 independent cut rows); centre of mass at (0.1, 0, -0.3) body axes."""
    tree = sp.SpatialModel("hinged", [
        sp.SpatialBody("p", 1.2, np.diag([0.02, 0.03, 0.025]), center_of_mass=(0.1, 0.0, -0.3)),
        sp.Free(name="free", parent=None, child="p")])
    return SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="hinge", parent=None, child="p", kind="revolute",
                                                            axis=(0, 1, 0))], baumgarte=baumgarte)


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
