"""Random planar chains and trees for the planar tests (seeded, reproducible)."""
from __future__ import annotations

import math

import numpy as np

from ctmm.planar import (ActuatedHinge, DamperHinge, DrivenHinge, ElasticHinge, Fixed, FreeBase,
                         Load, Pinned, PlanarModel, RigidBody, SmoothHinge, SpringDamperHinge)


def random_body(rng, name, n_ends):
    ends = {f"e{k}": tuple(rng.uniform(-1.0, 1.5, 2)) for k in range(n_ends)}
    loads = ()
    if rng.random() < 0.4:
        fx, fy, mz = rng.normal(size=3)
        w = rng.uniform(0.5, 3.0)
        loads = (Load(point=tuple(rng.uniform(-1, 1, 2)), force_x=float(fx),
                      force_y=lambda t, a=float(fy), w=w: a * math.cos(w * t),
                      moment=float(mz)),)
    return RigidBody(name, mass=rng.uniform(0.3, 2.0), inertia=rng.uniform(0.02, 0.3),
                     center_of_mass=tuple(rng.uniform(-0.5, 1.0, 2)),
                     inboard=tuple(rng.uniform(-0.3, 0.3, 2)), outboard=ends, loads=loads)


def random_hinge(rng, name, parent, child, allow_driven=True, allow_translation=True):
    if allow_translation and rng.random() < 0.2:
        if rng.random() < 0.5:
            return ElasticHinge(name, parent=parent, child=child, stiffness=rng.uniform(1, 30),
                                rest_angle=rng.normal(),
                                translational_stiffness=rng.uniform(50, 500))
        return SpringDamperHinge(name, parent=parent, child=child, stiffness=rng.uniform(1, 30),
                                 damping=rng.uniform(0.1, 2), rest_angle=rng.normal(),
                                 translational_stiffness=rng.uniform(50, 500),
                                 translational_damping=rng.uniform(0.1, 3))
    kind = rng.integers(0, 7 if allow_driven else 6)
    if kind == 0:
        return SmoothHinge(name, parent=parent, child=child)
    if kind == 1:
        return ElasticHinge(name, parent=parent, child=child, stiffness=rng.uniform(1, 30),
                            rest_angle=rng.normal())
    if kind == 2:
        return DamperHinge(name, parent=parent, child=child, damping=rng.uniform(0.1, 2))
    if kind == 3:
        return SpringDamperHinge(name, parent=parent, child=child, stiffness=rng.uniform(1, 30),
                                 damping=rng.uniform(0.1, 2), rest_angle=rng.normal())
    if kind == 4:
        a, w = rng.normal(), rng.uniform(0.5, 2)
        return ActuatedHinge(name, parent=parent, child=child,
                             torque=lambda t, a=a, w=w: a * math.sin(w * t),
                             kp=rng.uniform(0, 20), kd=rng.uniform(0, 2),
                             reference=lambda t, w=w: 0.3 * math.sin(w * t),
                             reference_rate=lambda t, w=w: 0.3 * w * math.cos(w * t))
    if kind == 5:
        return ActuatedHinge(name, parent=parent, child=child, torque=float(rng.normal()))
    a, w = rng.normal(), rng.uniform(0.5, 2)
    return DrivenHinge(name, parent=parent, child=child,
                       angle=lambda t, a=a, w=w: a + 0.5 * math.sin(w * t),
                       rate=lambda t, w=w: 0.5 * w * math.cos(w * t),
                       acceleration=lambda t, w=w: -0.5 * w * w * math.sin(w * t))


def random_tree(seed, n_bodies, *, chain=False, base=None, allow_driven=True,
                allow_translation=True):
    """Random tree (or chain) with all hinge types, loads and a random base."""
    rng = np.random.default_rng(seed)
    elements = []
    bodies = []
    for i in range(n_bodies):
        body = random_body(rng, f"b{i}", 1 if chain else int(rng.integers(1, 4)))
        bodies.append(body)
        elements.append(body)
    base = base or ["pinned", "free", "fixed"][int(rng.integers(0, 3))]
    if base == "pinned":
        elements.append(Pinned("base", position=tuple(rng.normal(size=2)), child="b0"))
    elif base == "free":
        elements.append(FreeBase("base", child="b0"))
    else:
        elements.append(Fixed("ground", position=tuple(rng.normal(size=2)), angle=rng.normal()))
        elements.append(random_hinge(rng, "h0", "ground", "b0", allow_driven,
                                     allow_translation))
    for i in range(1, n_bodies):
        if chain:
            p = i - 1
        else:
            p = int(rng.integers(0, i))
        parent = bodies[p]
        end = parent.ends[int(rng.integers(0, len(parent.ends)))]
        elements.append(random_hinge(rng, f"h{i}", f"b{p}.{end}", f"b{i}", allow_driven,
                                     allow_translation))
    g = (0.0, -9.81) if rng.random() < 0.7 else tuple(rng.normal(size=2))
    return PlanarModel(f"tree{seed}", elements, gravity=g)


def random_state(model, seed):
    rng = np.random.default_rng(seed + 1000)
    n = model.n_coordinates
    q = rng.uniform(-math.pi, math.pi, n)
    translational = [i for i, c in enumerate(model.coordinates) if c.endswith((".dx", ".dy"))]
    q[translational] *= 0.02            # small spring deflections [m]
    return q, rng.normal(0.0, 2.0, n), float(rng.uniform(0, 3))


def uniform_chain(n, *, length=1.0, mass=1.0, gravity=(0.0, -9.81)):
    """Pinned chain of n uniform links joined by smooth hinges."""
    elements = [Pinned("base")]
    for i in range(n):
        if i:
            elements.append(SmoothHinge(f"h{i}"))
        elements.append(RigidBody.uniform_link(f"link{i}", mass=mass, length=length))
    return PlanarModel.chain(f"chain{n}", elements, gravity=gravity)
