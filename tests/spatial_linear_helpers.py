"""Shared pieces of the spatial linearisation tests: the conversion of a ``SpatialModel`` to the
independent global reference (``ctmm/reference/spatial_tree.py``, written here, never in ctmm) and the
test models."""
from __future__ import annotations

import numpy as np

import ctmm.spatial as sp
from ctmm.reference import spatial_tree as ref


def reference_tree(model: sp.SpatialModel) -> ref.SpatialTree:
    """The reference description of a spatial model (bodies in the model's order)."""
    bodies = []
    for j, (body, joint) in enumerate(zip(model.bodies, model.joints)):
        parent = model.parent[j]
        position = joint.point if parent < 0 else model.bodies[parent].points[joint.point]
        axes = {"revolute": lambda: [joint.axis], "prismatic": lambda: [joint.axis],
                "universal": lambda: [joint.axis1, joint.axis2]}.get(joint.kind, lambda: np.zeros((0, 3)))()
        stiffness = getattr(joint, "stiffness", None)
        damping = getattr(joint, "damping", None)
        if joint.kind in ("revolute", "prismatic", "universal"):
            assert not np.any(joint.reference), "the reference has no spring reference angle"
            stiffness, damping = np.diag(np.atleast_1d(stiffness)), np.diag(np.atleast_1d(damping))
        if joint.kind in ("free", "weld"):
            stiffness = damping = None
        bodies.append(ref.SpatialBody(body.name, parent, joint.kind, body.mass, body.center_of_mass, body.inertia,
                                      axes=np.array(axes, dtype=float), joint_position=np.asarray(position, float),
                                      joint_rotation=joint.rotation, stiffness=stiffness, damping=damping))
    return ref.SpatialTree(tuple(bodies), gravity=model.gravity)


def reference_configuration(model: sp.SpatialModel, q: np.ndarray) -> np.ndarray:
    """Our ``q`` in the reference layout (quaternions scalar last)."""
    out = []
    for joint, layout in zip(model.joints, model.layout):
        qj = q[layout.position]
        if joint.kind == "spherical":
            out.append(np.r_[qj[1:], qj[0]])
        elif joint.kind in ("free", "elastic6"):
            out.append(np.r_[qj[:3], qj[4:], qj[3]])
        else:
            out.append(qj)
    return np.concatenate(out) if out else np.zeros(0)


def reference_matrices(model: sp.SpatialModel, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(M, C, K)`` of the reference about ``q0`` (tangent coordinates of its ``retract``)."""
    return ref.linearize(reference_tree(model), reference_configuration(model, q0))


def reference_blocks(model: sp.SpatialModel, q0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``-M^-1 K``, ``-M^-1 C`` of the reference about ``q0``."""
    mass, damping, stiffness = reference_matrices(model, q0)
    return -np.linalg.solve(mass, stiffness), -np.linalg.solve(mass, damping)


def rotation(rng: np.random.Generator) -> np.ndarray:
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q @ np.diag(np.sign(np.diag(R)))
    return Q if np.linalg.det(Q) > 0 else -Q


def random_body(rng: np.random.Generator, name: str) -> sp.SpatialBody:
    R = rotation(rng)
    inertia = R @ np.diag(rng.uniform(0.6, 1.1, 3)) @ R.T
    return sp.SpatialBody(name, rng.uniform(0.5, 3.0), inertia, rng.uniform(-0.5, 0.5, 3),
                          {f"p{i}": rng.uniform(-1, 1, 3) for i in range(3)})


def random_spring_tree(rng: np.random.Generator, n: int, base: str, damped: bool = True,
                       kinds: tuple[str, ...] = ("revolute", "universal", "spherical", "prismatic", "weld", "revolute")
                       ) -> sp.SpatialModel:
    """Branches of sprung revolute / universal / prismatic joints, unsprung spherical joints and welds
    under gravity: the equilibrium deflects every spring (dampers unless ``damped=False``)."""
    elements = [random_body(rng, f"b{j}") for j in range(n)]
    for j in range(n):
        kind = base if j == 0 else kinds[(j - 1) % len(kinds)]
        common = dict(name=f"j{j}", parent=None if j == 0 else f"b{int(rng.integers(0, j))}", child=f"b{j}",
                      point=rng.normal(size=3) if j == 0 else f"p{int(rng.integers(0, 3))}",
                      rotation=rotation(rng))
        if kind == "revolute":
            joint = sp.Revolute(axis=rng.normal(size=3), stiffness=rng.uniform(20, 60),
                                damping=rng.uniform(0, 1) * damped, actuated=True, **common)
        elif kind == "universal":
            joint = sp.Universal(axis1=rng.normal(size=3), axis2=rng.normal(size=3), stiffness=rng.uniform(20, 60, 2),
                                 damping=rng.uniform(0, 1, 2) * damped, actuated=True, **common)
        elif kind == "prismatic":
            joint = sp.Prismatic(axis=rng.normal(size=3), stiffness=rng.uniform(50, 90),
                                 damping=rng.uniform(0, 1) * damped, **common)
        elif kind == "spherical":
            joint = sp.Spherical(damping=rng.uniform(0, 1) * damped, actuated=True, **common)
        else:
            joint = sp.Weld(**common)
        elements.append(joint)
    return sp.SpatialModel("springs", elements, gravity=rng.normal(size=3) * 3)


def elastic_hinge_body(gravity=(0.0, 0.0, -9.81), damped: bool = True) -> sp.SpatialModel:
    """A rigid body on a 6-DOF elastic hinge (seed 001 Fig. 9.44; our parameters): isotropic
    translational stiffness, anisotropic rotary stiffness, centre of mass on the vertical through the
    hinge (the spring is loaded in translation only)."""
    rotary = np.array([[40.0, 3.0, 0.0], [3.0, 55.0, 1.0], [0.0, 1.0, 30.0]])
    stiffness = np.block([[2.0e4 * np.eye(3), np.zeros((3, 3))], [np.zeros((3, 3)), rotary]])
    damping = np.diag([5.0, 5.0, 5.0, 0.2, 0.3, 0.1]) * damped
    return sp.SpatialModel("hinge", [
        sp.SpatialBody("body", 4.0, np.diag([0.05, 0.08, 0.06]), center_of_mass=(0.0, 0.0, 0.25)),
        sp.Elastic6(name="hinge", parent=None, child="body", stiffness=stiffness, damping=damping, actuated=True)],
        gravity=gravity)
