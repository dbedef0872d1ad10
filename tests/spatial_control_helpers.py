"""Test helpers for the spatial control tests: a :class:`ctmm.spatial.SpatialModel` written as the
independent reference tree of :mod:`ctmm.reference.spatial_tree` (same bodies, joints, laws), and the
conversion of states between the two conventions (quaternions scalar first in ctmm, scalar last in the
reference; velocities are the same, child axes)."""
from __future__ import annotations

import numpy as np

import ctmm.spatial as sp
from ctmm.reference.spatial_tree import SpatialBody, SpatialTree


def to_reference(model: sp.SpatialModel) -> SpatialTree:
    """The reference tree of ``model`` (no spherical or elastic6 springs: their laws differ)."""
    index = {body.name: j for j, body in enumerate(model.bodies)}
    bodies = []
    for body, joint in zip(model.bodies, model.joints):
        if joint.parent is None:
            parent, position = -1, np.asarray(joint.point, float)
        else:
            parent = index[joint.parent]
            position = np.asarray(model.bodies[parent].points[joint.point], float)
        axes = {"revolute": lambda: [joint.axis], "prismatic": lambda: [joint.axis],
                "universal": lambda: [joint.axis1, joint.axis2]}.get(joint.kind, lambda: [])()
        law = {}
        if joint.kind in ("revolute", "prismatic", "universal"):
            law = {"stiffness": np.diag(np.broadcast_to(joint.stiffness, (joint.velocity_count,))),
                   "damping": np.diag(np.broadcast_to(joint.damping, (joint.velocity_count,)))}
        bodies.append(SpatialBody(body.name, parent, joint.kind, body.mass, body.center_of_mass, body.inertia,
                                  axes=np.asarray(axes, float).reshape(-1, 3), joint_position=position,
                                  joint_rotation=np.asarray(joint.rotation, float), **law))
    return SpatialTree(tuple(bodies), gravity=model.gravity)


def _quaternion_ranges(model: sp.SpatialModel):
    for joint, layout in zip(model.joints, model.layout):
        if joint.kind == "spherical":
            yield layout.position.start
        elif joint.kind in ("free", "elastic6"):
            yield layout.position.start + 3


def q_to_reference(model: sp.SpatialModel, q: np.ndarray) -> np.ndarray:
    """ctmm coordinates -> reference coordinates (quaternion ``(w, x, y, z)`` -> ``(x, y, z, w)``)."""
    out = np.array(q, dtype=float)
    for start in _quaternion_ranges(model):
        out[start:start + 4] = np.roll(q[start:start + 4], -1)
    return out


def q_from_reference(model: sp.SpatialModel, q: np.ndarray) -> np.ndarray:
    """Reference coordinates -> ctmm coordinates."""
    out = np.array(q, dtype=float)
    for start in _quaternion_ranges(model):
        out[start:start + 4] = np.roll(q[start:start + 4], 1)
    return out


def quaternion_joint_state(rng: np.random.Generator, model: sp.SpatialModel, scale: float = 0.8):
    """A random state ``(q, v)``: angles and displacements ~ ``scale``, unit quaternions, velocities ~ 1."""
    q = rng.normal(scale=scale, size=model.n_positions)
    for start in _quaternion_ranges(model):
        quat = rng.normal(size=4)
        q[start:start + 4] = quat / np.linalg.norm(quat)
    return q, rng.normal(size=model.n_velocities)


def random_model(rng: np.random.Generator, actuated: bool = True, free_base: bool = False) -> sp.SpatialModel:
    """A 5-body tree with every lawful joint kind (revolute, prismatic, universal, spherical, free or
    revolute base), random inertias, points and joint frames, and a branch."""
    def body(name):
        a = rng.normal(size=(3, 3))
        inertia = a @ a.T + 0.3 * np.eye(3)
        w = np.linalg.eigvalsh(inertia)
        while not (w[0] + w[1] > w[2]):          # triangle inequality
            inertia = inertia + 0.5 * np.eye(3)
            w = np.linalg.eigvalsh(inertia)
        return sp.SpatialBody(name, rng.uniform(0.5, 2.0), inertia, rng.normal(scale=0.2, size=3),
                              {"tip": rng.normal(scale=0.5, size=3), "side": rng.normal(scale=0.5, size=3)})

    def rotation():
        qm, r = np.linalg.qr(rng.normal(size=(3, 3)))
        qm = qm @ np.diag(np.sign(np.diag(r)))
        return qm if np.linalg.det(qm) > 0 else -qm

    law = {"stiffness": rng.uniform(1, 4), "damping": rng.uniform(0.1, 0.5)}
    base = sp.Free(name="j0", parent=None, child="b0", point=(0.1, -0.2, 0.3), rotation=rotation(),
                   actuated=actuated) if free_base else \
        sp.Revolute(name="j0", parent=None, child="b0", point=(0.1, -0.2, 0.3), rotation=rotation(),
                    axis=rng.normal(size=3), actuated=actuated, **law)
    elements = [body(f"b{i}") for i in range(5)] + [
        base,
        sp.Universal(name="j1", parent="b0", point="tip", child="b1", rotation=rotation(), axis1=(1, 0, 0),
                     axis2=rng.normal(size=3), actuated=actuated, stiffness=rng.uniform(1, 4, 2),
                     damping=rng.uniform(0.1, 0.5, 2)),
        sp.Spherical(name="j2", parent="b1", point="tip", child="b2", rotation=rotation(), actuated=actuated),
        sp.Prismatic(name="j3", parent="b0", point="side", child="b3", rotation=rotation(), axis=rng.normal(size=3),
                     actuated=actuated, stiffness=rng.uniform(5, 10), damping=rng.uniform(0.1, 0.5)),
        sp.Revolute(name="j4", parent="b3", point="tip", child="b4", rotation=rotation(), axis=rng.normal(size=3),
                    actuated=actuated, **law),
    ]
    return sp.SpatialModel("tree", elements, gravity=(0.3, -0.2, -9.81))
