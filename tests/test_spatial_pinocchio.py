"""Spatial trees on the one sweep against Pinocchio (a peer reference sharing no code): ABA
accelerations and RNEA joint wrenches of random trees with every joint type, branches, a free base,
gravity, joint laws, actuator inputs and applied loads.  Conversions to Pinocchio's conventions
(quaternion (x, y, z, w), local-frame wrenches at the joint origin) are done here, never in ctmm.

Tolerance: 1e-10 relative to the largest entry compared (double round-off through ~10 bodies).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm.spatial as sp
from ctmm.signals import Harmonic

pin = pytest.importorskip("pinocchio")

TOLERANCE = 1e-10


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def random_body(rng: np.random.Generator, name: str) -> sp.SpatialBody:
    moments = rng.uniform(0.6, 1.1, 3)            # triangle inequality holds
    R = random_rotation(rng)
    inertia = R @ np.diag(moments) @ R.T
    points = {f"p{i}": rng.uniform(-1, 1, 3) for i in range(3)}
    return sp.SpatialBody(name, rng.uniform(0.5, 3.0), inertia, rng.uniform(-0.5, 0.5, 3), points)


def random_joint(rng: np.random.Generator, kind: str, name: str, parent: str | None, point, child: str):
    common = dict(name=name, parent=parent, child=child, point=point, rotation=random_rotation(rng))
    if kind == "revolute":
        return sp.Revolute(axis=rng.normal(size=3), stiffness=rng.uniform(0, 5), damping=rng.uniform(0, 1),
                           reference=rng.normal(), actuated=True, **common)
    if kind == "prismatic":
        return sp.Prismatic(axis=rng.normal(size=3), stiffness=rng.uniform(0, 5), damping=rng.uniform(0, 1),
                            actuated=True, **common)
    if kind == "universal":
        return sp.Universal(axis1=rng.normal(size=3), axis2=rng.normal(size=3), stiffness=rng.uniform(0, 5, 2),
                            damping=rng.uniform(0, 1, 2), reference=rng.normal(size=2), actuated=True, **common)
    if kind == "spherical":
        return sp.Spherical(stiffness=np.diag(rng.uniform(0, 5, 3)), damping=rng.uniform(0, 1), actuated=True,
                            **common)
    if kind == "free":
        return sp.Free(actuated=True, **common)
    if kind == "elastic6":
        A = rng.normal(size=(6, 6))
        return sp.Elastic6(stiffness=A @ A.T, damping=np.diag(rng.uniform(0, 1, 6)), **common)
    if kind == "weld":
        return sp.Weld(**common)
    raise AssertionError(kind)


KINDS = ("revolute", "prismatic", "universal", "spherical", "free", "elastic6", "weld")


def random_tree(rng: np.random.Generator, n: int, base: str = "free", kinds=KINDS, loads: bool = True
                ) -> sp.SpatialModel:
    """A random tree: body 0 on ``base`` to the ground, every other body on a random earlier body's
    random point (branches), joint kinds cycling through ``kinds``."""
    elements = []
    for j in range(n):
        elements.append(random_body(rng, f"b{j}"))
        if j == 0:
            elements.append(random_joint(rng, base, "j0", None, rng.normal(size=3), "b0"))
        else:
            parent = int(rng.integers(0, j))
            point = f"p{int(rng.integers(0, 3))}"
            elements.append(random_joint(rng, kinds[(j - 1) % len(kinds)], f"j{j}", f"b{parent}", point, f"b{j}"))
    if loads:
        force = list(rng.normal(size=3))
        force[0] = Harmonic(force[0], 3.0, 0.2)                               # a time signal
        elements.append(sp.Load("push", f"b{n - 1}", "p1", force=force, moment=rng.normal(size=3)))
        elements.append(sp.Load("twist", "b0", "p2", force=rng.normal(size=3), moment=rng.normal(size=3),
                                axes="body"))
    return sp.SpatialModel("tree", elements, gravity=rng.normal(size=3) * 5)


def random_state(rng: np.random.Generator, model: sp.SpatialModel) -> tuple[np.ndarray, np.ndarray]:
    q = rng.normal(size=model.n_positions)
    for joint, layout in zip(model.joints, model.layout):
        if joint.kind == "spherical":
            q[layout.position] *= rng.uniform(0.5, 2)            # non-unit quaternions: normalised inside
    return q, rng.normal(size=model.n_velocities)


def random_inputs(rng: np.random.Generator, model: sp.SpatialModel) -> dict:
    out = {}
    for joint in model.joints:
        for name in joint.inputs:
            out[name] = rng.normal(size=joint.velocity_count) if joint.velocity_count > 1 else float(rng.normal())
    return out


# --- the conversion to Pinocchio (test side only) -------------------------------------------------------------

def _pin_joint(joint):
    if joint.kind == "revolute":
        return pin.JointModelRevoluteUnaligned(joint.axis)
    if joint.kind == "prismatic":
        return pin.JointModelPrismaticUnaligned(joint.axis)
    if joint.kind == "universal":
        return pin.JointModelUniversal(joint.axis1, joint.axis2)
    if joint.kind == "spherical":
        return pin.JointModelSpherical()
    return pin.JointModelFreeFlyer()


class PinTree:
    """A :class:`SpatialModel` as a Pinocchio model (welded bodies merged into their parent's joint)."""

    def __init__(self, model: sp.SpatialModel) -> None:
        self.model = model
        self.pin = pin.Model()
        self.pin.gravity = pin.Motion(model.gravity, np.zeros(3))
        self.frame = []                 # per body: (pin joint id, placement of the body frame in that joint's frame)
        for j, (body, joint) in enumerate(zip(model.bodies, model.joints)):
            if joint.parent is None:
                parent_id, parent_frame, point = 0, pin.SE3.Identity(), joint.point
            else:
                parent_id, parent_frame = self.frame[model.parent[j]]
                point = model.bodies[model.parent[j]].points[joint.point]
            placement = parent_frame * pin.SE3(joint.rotation, point)
            if joint.kind == "weld":
                self.frame.append((parent_id, placement))
            else:
                jid = self.pin.addJoint(parent_id, _pin_joint(joint), placement, joint.name)
                self.frame.append((jid, pin.SE3.Identity()))
            jid, frame = self.frame[-1]
            self.pin.appendBodyToJoint(jid, pin.Inertia(body.mass, body.center_of_mass, body.inertia), frame)
        self.data = self.pin.createData()

    def configuration(self, q: np.ndarray) -> np.ndarray:
        """Our ``q`` in Pinocchio's layout (quaternions normalised, (x, y, z, w))."""
        out = []
        for joint, layout in zip(self.model.joints, self.model.layout):
            qj = q[layout.position]
            if joint.kind == "spherical":
                qj = qj / np.linalg.norm(qj)
                out.append(np.r_[qj[1:], qj[0]])
            elif joint.kind in ("free", "elastic6"):
                quat = qj[3:] / np.linalg.norm(qj[3:])
                out.append(np.r_[qj[:3], quat[1:], quat[0]])
            else:
                out.append(qj)
        return np.concatenate(out) if out else np.zeros(0)

    def torques(self, q: np.ndarray, v: np.ndarray, inputs: dict) -> np.ndarray:
        """Joint laws and inputs, written out here from the element parameters."""
        out = []
        for joint, layout in zip(self.model.joints, self.model.layout):
            qj, vj = q[layout.position], v[layout.velocity]
            u = np.atleast_1d(inputs.get(joint.inputs[0], 0.0)) if joint.inputs else 0.0
            if joint.kind in ("revolute", "prismatic", "universal"):
                out.append(u - joint.stiffness * (qj - joint.reference) - joint.damping * vj)
            elif joint.kind == "spherical":
                w, x, y, z = qj / np.linalg.norm(qj)
                out.append(u - joint.stiffness @ (2 * w * np.array([x, y, z])) - joint.damping @ vj)
            elif joint.kind == "free":
                out.append(u + np.zeros(6))
            elif joint.kind == "elastic6":
                w, x, y, z = qj[3:] / np.linalg.norm(qj[3:])
                R = pin.Quaternion(w, x, y, z).toRotationMatrix()
                e = np.r_[R.T @ qj[:3], 2 * w * np.array([x, y, z])]
                out.append(-joint.stiffness @ e - joint.damping @ vj)
        return np.concatenate(out) if out else np.zeros(0)

    def external(self, q_pin: np.ndarray, t: float) -> list:
        """Applied loads as Pinocchio local-frame forces per joint."""
        pin.forwardKinematics(self.pin, self.data, q_pin)
        fext = [pin.Force.Zero() for _ in range(self.pin.njoints)]
        self.body_loads = [pin.Force.Zero() for _ in self.model.bodies]     # per body, in its pin joint's frame
        for load in self.model.loads:
            j = self.model.body_index(load.body)
            jid, frame = self.frame[j]
            world = self.data.oMi[jid] * frame                     # body frame in world
            values = load.values(t)
            R = world.rotation
            f_body, m_body = (values[:3], values[3:]) if load.axes == "body" else (R.T @ values[:3], R.T @ values[3:])
            force_in_body = pin.Force(f_body, m_body + np.cross(self.model.bodies[j].points[load.point], f_body))
            fext[jid] += frame.act(force_in_body)
            self.body_loads[j] += frame.act(force_in_body)
        return fext

    def solve(self, q: np.ndarray, v: np.ndarray, inputs: dict, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """``(v_dot, reactions (n_bodies, 6) world axes at each body's inboard point)`` from ABA and RNEA."""
        qp = self.configuration(q)
        tau = self.torques(q, v, inputs)
        fext = self.external(qp, t)
        a = pin.aba(self.pin, self.data, qp, v, tau, fext)
        pin.rnea(self.pin, self.data, qp, v, a, fext)
        wrenches = []
        for j, joint in enumerate(self.model.joints):
            jid, frame = self.frame[j]
            if joint.kind == "weld":
                wrenches.append(self.welded_subtree_wrench(j))
                continue
            world = self.data.oMi[jid]
            f = world.rotation @ self.data.f[jid].linear
            m = world.rotation @ self.data.f[jid].angular
            if joint.parent is None:
                P = joint.point
            else:
                pid, pframe = self.frame[self.model.parent[j]]
                P = (self.data.oMi[pid] * pframe).act(self.model.bodies[self.model.parent[j]].points[joint.point])
            wrenches.append(np.r_[f, m + np.cross(world.translation - P, f)])
        return np.array(a), np.array(wrenches)


    def welded_subtree_wrench(self, j: int) -> np.ndarray:
        """Reaction of a weld (no Pinocchio joint): Newton-Euler of body ``j``'s subtree from Pinocchio's
        velocities and accelerations (``data.v``, ``data.a_gf``), world axes, moment about the weld point."""
        model = self.model
        subtree = {j}
        for k in range(j + 1, model.n_bodies):
            if model.parent[k] in subtree:
                subtree.add(k)
        total = np.zeros(6)
        for k in subtree:
            jid, frame = self.frame[k]
            body = model.bodies[k]
            inertia = frame.act(pin.Inertia(body.mass, body.center_of_mass, body.inertia))
            v = self.data.v[jid]
            local = inertia * self.data.a_gf[jid] + v.cross(inertia * v) - self.body_loads[k]
            world = self.data.oMi[jid].act(local)                   # at the world origin
            total += np.r_[world.linear, world.angular]
        joint = model.joints[j]
        if joint.parent is None:
            P = joint.point
        else:
            pid, pframe = self.frame[model.parent[j]]
            P = (self.data.oMi[pid] * pframe).act(model.bodies[model.parent[j]].points[joint.point])
        return np.r_[total[:3], total[3:] - np.cross(P, total[:3])]


def assert_close(ours: np.ndarray, theirs: np.ndarray, label: str) -> None:
    mask = np.isfinite(theirs)
    scale = max(1.0, float(np.abs(theirs[mask]).max()))
    error = float(np.abs(ours[mask] - theirs[mask]).max()) / scale
    assert error < TOLERANCE, f"{label}: relative difference {error:.3e} to Pinocchio"


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("base", ["free", "elastic6", "revolute", "weld"])
def test_random_trees_match_pinocchio(seed: int, base: str) -> None:
    rng = np.random.default_rng(100 * seed + len(base))
    model = random_tree(rng, 9, base=base)
    reference = PinTree(model)
    q, v = random_state(rng, model)
    inputs = random_inputs(rng, model)
    ours = sp.solve(model, q, v, 0.3, inputs)
    a_pin, f_pin = reference.solve(q, v, inputs, 0.3)
    assert_close(ours.velocity_rates[0], a_pin, "accelerations")
    assert_close(ours.reactions[0], f_pin, "joint wrenches")


def test_batched_states_equal_one_by_one() -> None:
    rng = np.random.default_rng(7)
    model = random_tree(rng, 6)
    states = [random_state(rng, model) for _ in range(4)]
    q = np.array([s[0] for s in states])
    v = np.array([s[1] for s in states])
    batch = sp.accelerations(model, q, v)
    for k in range(4):
        np.testing.assert_allclose(batch[k], sp.accelerations(model, q[k], v[k]), rtol=0, atol=1e-12)


def test_casadi_terms_equal_numpy() -> None:
    casadi = pytest.importorskip("casadi")
    from ctmm.ops import CASADI

    rng = np.random.default_rng(11)
    model = random_tree(rng, 8, loads=False)
    scene = sp.SpatialScene(model)
    qs, vs = casadi.SX.sym("q", model.n_positions), casadi.SX.sym("v", model.n_velocities)
    names = [(joint.inputs[0], joint.velocity_count) for joint in model.joints if joint.inputs]
    us = {name: casadi.SX.sym(name, k) for name, k in names}
    solution = scene.sweep(CASADI, qs, vs, 0.0, us)
    rates = casadi.vertcat(*scene.velocity_rates(solution))
    forces = casadi.vertcat(*solution.force)
    function = casadi.Function("f", [qs, vs] + list(us.values()), [rates, forces])
    q, v = random_state(rng, model)
    inputs = random_inputs(rng, model)
    rates_value, forces_value = function(q, v, *[np.atleast_1d(inputs[name]) for name, _ in names])
    ours = sp.solve(model, q, v, 0.0, inputs)
    assert names                                        # actuated joints take symbolic inputs
    np.testing.assert_allclose(np.array(rates_value).ravel(), ours.velocity_rates[0], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(np.array(forces_value).ravel(), ours.reactions[0].ravel(), rtol=1e-10, atol=1e-10)
