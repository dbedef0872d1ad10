"""Spatial finite-element subsystems in a SpatialModel (issue 16, docs/mixed.md §7) against independent
references: ctmm/reference/fe_beam3d.py (linear 3-D FE) and ctmm/reference/spatial_fe_global.py (the whole
chain as one global model in minimal coordinates)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError, SimulationError
from ctmm.fem import (SmallDeformationWarning, SpatialBeamElement, SpatialFiniteElementModel, SpatialNodeSpring,
                      SpatialPointMass, SpatialSubsystem)
from ctmm.reference.fe_beam3d import FEBeam, FEBody, FEChain
from ctmm.reference.spatial_fe_global import FEFrame, FrameBeam, FrameMass, Link, SpatialFEChain

NODES = {"n0": (0.0, 0.0, 0.0), "n1": (0.3, 0.0, 0.0), "n2": (0.6, 0.0, 0.0), "n3": (0.6, 0.25, 0.0)}
BEAMS = [("e0", "n0", "n1", (0.0, 1.0, 0.0)), ("e1", "n1", "n2", (0.0, 0.0, 1.0)), ("e2", "n2", "n3", (0.3, 0.0, 1.0))]
EA, GJ, EIY, EIZ, RHOA, RHOIP = 4e3, 10.0, 25.0, 40.0, 0.9, 5e-3
TIP_MASS, TIP_INERTIA = 0.2, np.diag([1e-3, 2e-3, 1.5e-3])
I1, I2 = np.diag([0.01, 0.02, 0.015]), np.diag([0.004, 0.003, 0.002])


def chain(*, gravity=9.81, damping=0.0, force=None, child=True):
    """The same chain twice: a SpatialModel (link1 on a yaw joint, the FE L-frame on a pitch joint at its tip,
    link2 on a hinge at the frame's node n3) and the global reference."""
    elements = [SpatialBeamElement(name, a, b, EA, GJ, EIY, EIZ, RHOA, RHOIP, orientation=o) for name, a, b, o in BEAMS]
    elements.append(SpatialPointMass("tip", "n3", TIP_MASS, TIP_INERTIA))
    fe = SpatialFiniteElementModel("fe", NODES, elements, rayleigh=(0.0, damping))
    full = None
    if force is not None:
        def full(u, ud, t):                       # ctmm passes all DOFs (inboard ones 0)
            out = np.zeros_like(u)
            out[6:] = force(u[6:], ud[6:])
            return out
    frame = fe.subsystem("frame", boundary=("n0", "n3"), nonlinear_force=full)
    parts = [sp.SpatialBody("link1", 1.2, I1, center_of_mass=(0.1, 0.0, 0.15), points={"tip": (0.2, 0.0, 0.3)}),
             sp.Revolute(name="yaw", parent=None, child="link1", axis=(0, 0, 1), actuated=True), frame,
             sp.Revolute(name="pitch", parent="link1", point="tip", child="frame", axis=(0, 1, 0))]
    segments = [Link(1.2, I1, (0.1, 0.0, 0.15), (0, 0, 1), (0, 0, 0)),
                FEFrame(NODES, "n0", [FrameBeam(a, b, EA, GJ, EIY, EIZ, RHOA, RHOIP, o) for _, a, b, o in BEAMS],
                        [FrameMass("n3", TIP_MASS, TIP_INERTIA)], axis=(0, 1, 0), point=(0.2, 0.0, 0.3),
                        stiffness_damping=damping)]
    if child:
        parts += [sp.SpatialBody("link2", 0.5, I2, center_of_mass=(0.0, 0.05, -0.1)),
                  sp.Revolute(name="hinge", parent="frame", point="n3", child="link2", axis=(1, 0, 0))]
        segments.append(Link(0.5, I2, (0.0, 0.05, -0.1), (1, 0, 0), "n3"))
    model = sp.SpatialModel("fe_chain", parts, gravity=(0.0, 0.0, -gravity))
    return model, SpatialFEChain(segments, gravity=(0.0, 0.0, -gravity), force=force)


def states(model, count, seed=3):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q = rng.normal(size=model.n_positions) * 0.8
        q[3:] *= 0.03
        yield q, rng.normal(size=model.n_velocities)


def test_element_matrices_match_independent_fe_cantilever():
    """An oblique clamped cantilever with a tip body: frequencies of the welded subsystem = fe_beam3d."""
    direction = np.array([1.0, 2.0, 2.0]) / 3.0
    orientation = np.array([0.0, 0.0, 1.0])
    y = orientation - (orientation @ direction) * direction
    y /= np.linalg.norm(y)
    axes = np.column_stack([direction, y, np.cross(direction, y)])        # local -> model
    length, count = 1.2, 6
    nodes = {f"n{k}": tuple(direction * length * k / count) for k in range(count + 1)}
    elements = [SpatialBeamElement(f"e{k}", f"n{k}", f"n{k + 1}", 3e4, 12.0, 20.0, 45.0, 0.7, 4e-3,
                                   orientation=orientation) for k in range(count)]
    elements.append(SpatialPointMass("tip", f"n{count}", 0.3, axes @ np.diag([2e-3, 1e-3, 3e-3]) @ axes.T))
    fe = SpatialFiniteElementModel("cantilever", nodes, elements)
    model = sp.SpatialModel("welded", [fe.subsystem("beam", ("n0", f"n{count}")),
                                       sp.Weld(name="clamp", parent=None, child="beam")], gravity=(0, 0, 0))
    omega = ctmm.natural_frequencies(model, n_modes=10)
    reference = FEChain([FEBeam(length, 3e4, 12.0, 45.0, 20.0, 0.7, 4e-3, rotation=axes, elements=count),
                         FEBody(0.3, axes @ np.diag([2e-3, 1e-3, 3e-3]) @ axes.T)]).frequencies(10)
    assert np.max(np.abs(omega - reference) / reference) < 1e-9


def test_accelerations_energy_and_interaction_force_match_global_model():
    model, ref = chain(damping=2e-4)
    for q, v in states(model, 4):
        a, a_ref = sp.accelerations(model, q, v), ref.accelerations(q, v)
        assert np.max(np.abs(a - a_ref)) < 1e-10 * np.max(np.abs(a_ref))
        assert abs(sp.energy(model, q, v) - ref.energy(q, v)) < 1e-11 * abs(ref.energy(q, v))
        force = sp.reactions(model, q, v)[model.body_index("link2"), :3]
        assert np.max(np.abs(force - ref.interaction_force(q, v))) < 1e-10 * np.max(np.abs(force))


def test_nonlinear_force_matches_global_model():
    def cubic(u, ud):
        out = np.zeros_like(u)
        out[-4] = -4e5 * u[-4] ** 3 - 0.3 * ud[-4]           # n3_uz: hardening spring and damper
        return out
    model, ref = chain(force=cubic)
    for q, v in states(model, 3, seed=5):
        q[-4] = 0.02
        a, a_ref = sp.accelerations(model, q, v), ref.accelerations(q, v)
        assert np.max(np.abs(a - a_ref)) < 1e-10 * np.max(np.abs(a_ref))


def test_generated_code_refuses_a_subsystems_nonlinear_force_by_name():
    """docs/mixed.md §7: a nonlinear_force is Python code and is refused by compiled=True -- by its name, not as
    'modal forces or distributed load' of a beam with advice to use ctmm.signals (which cannot state a law)."""
    model, _ = chain(force=lambda u, ud: -1e3 * u)
    with pytest.raises(ModelError, match=r"subsystems with a nonlinear_force: 'frame'.*without compiled=True") as info:
        ctmm.simulate(model, 0.01, 1e-3, method="rk4", compiled=True)
    assert "ctmm.signals" not in str(info.value)


@pytest.mark.parametrize("compiled", [False, True])
def test_rk4_history_matches_global_model(compiled):
    model, ref = chain(child=False)
    q0 = np.zeros(model.n_positions)
    q0[1], q0[5] = 0.4, 0.004                                # pitch, n1_uz
    v0 = np.zeros(model.n_velocities)
    v0[0] = 2.0                                              # yaw rate
    result = ctmm.simulate(model, 0.03, 5e-4, method="rk4", x0=q0, v0=v0, compiled=compiled)
    _, reference = ref.rk4(q0, v0, 0.03, 5e-4)
    for k, name in enumerate(model.coordinates):
        assert np.max(np.abs(result[name] - reference[:, k])) < 1e-9 * max(1.0, np.max(np.abs(reference[:, k])))


def test_newmark_converges_to_global_model_at_second_order():
    model, ref = chain(child=False)
    q0 = np.zeros(model.n_positions)
    q0[1], q0[5] = 0.4, 0.004
    v0 = np.zeros(model.n_velocities)
    v0[0] = 2.0
    _, fine = ref.rk4(q0, v0, 0.02, 2.5e-4)
    errors = []
    for dt in (1e-3, 5e-4):
        result = ctmm.simulate(model, 0.02, dt, method="newmark", x0=q0, v0=v0)
        errors.append(max(abs(result[name][-1] - fine[-1, k]) for k, name in enumerate(model.coordinates)))
    assert 3.0 < errors[0] / errors[1] < 5.0


def test_natural_frequencies_and_frequency_response_match_global_linearisation():
    model, ref = chain()
    omega = ctmm.natural_frequencies(model, n_modes=8)
    q0 = np.asarray(ctmm.linearize(model).operating_point.q)
    expected = ref.natural_frequencies(q0)[:8]
    assert omega[0] == 0.0 and expected[0] < 1e-6                     # the free yaw
    assert np.max(np.abs(omega[1:] - expected[1:]) / expected[1:]) < 1e-8
    damped, damped_ref = chain(damping=3e-4)
    q0 = np.asarray(ctmm.linearize(damped).operating_point.q)
    w = np.array([0.7, 3.0, 20.0, 55.0])
    response = ctmm.frequency_response(damped, w, input="yaw.torque", output="frame.n3_uz")
    index = damped.coordinates.index("frame.n3_uz")
    expected = damped_ref.frequency_response(q0, w, load=0, output=index)
    values = np.asarray(response.response)[0, 0]
    assert np.max(np.abs(values - expected) / np.abs(expected)) < 1e-7


def test_small_deformation_guard_stops_a_diverging_run_with_the_partial_result():
    model, _ = chain(child=False)
    v0 = np.zeros(model.n_velocities)
    v0[0] = 2.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SmallDeformationWarning)
        with pytest.raises(SimulationError) as caught:
            ctmm.simulate(model, 0.2, 4e-3, method="rk4", v0=v0)       # above the explicit step limit
    error = caught.value
    assert error.element == "frame" and "small deformation" in str(error) and error.partial_result is not None


def test_refusals_name_the_problem():
    nodes = {"a": (0, 0, 0), "b": (1, 0, 0)}
    with pytest.raises(ModelError, match="positive definite.*b_rx"):   # Euler-Bernoulli twist without rho I_p
        SpatialFiniteElementModel("fe", nodes, [SpatialBeamElement("e", "a", "b", 1e3, 1.0, 1.0, 1.0, 0.5)]
                                  ).subsystem("s", ("a", "b"))
    with pytest.raises(ModelError, match="not lumped"):
        M = np.eye(6) + 0.1 * np.ones((6, 6))
        SpatialSubsystem("s", mass_matrix=M, damping_matrix=np.zeros((6, 6)), stiffness_matrix=np.eye(6),
                         nodes={"a": ((0, 0, 0), (0, 1, 2)), "b": ((1, 0, 0), (3, 4, 5))}, boundary=("a", "b"))
    with pytest.raises(ModelError, match="orientation"):
        SpatialFiniteElementModel("fe", nodes, [SpatialBeamElement("e", "a", "b", 1e3, 1.0, 1.0, 1.0, 0.5, 1e-3,
                                                                   orientation=(2, 0, 0))])
    with pytest.raises(ModelError, match="rotation DOFs"):
        SpatialFiniteElementModel("fe", nodes, [SpatialPointMass("p", "b", 1.0),
                                                SpatialNodeSpring("s", "a", "b", rotational_stiffness=1.0)])
    model, _ = chain(child=False)
    with pytest.raises(ModelError, match="not a node"):              # a load off the nodes (the centre of mass)
        sp.SpatialScene(model).solve(model.neutral(), np.zeros(model.n_velocities),
                                     wrenches={1: [(np.array([0.1, 0.0, 0.0]), np.ones((1, 6, 1)))]})

def test_lumped_particle_subsystem_matches_its_finite_element_twin():
    """A GlobalSubsystem-style lumped M (particles and a spring) gives the same accelerations as the same
    particles built from SpatialPointMass / SpatialNodeSpring elements (two routes to the inertia integrals)."""
    nodes = {"a": (0, 0, 0), "b": (0.4, 0.1, 0.0), "c": (0.2, -0.3, 0.1)}
    fe = SpatialFiniteElementModel("net", nodes, [SpatialPointMass("pa", "a", 0.5), SpatialPointMass("pb", "b", 0.3),
                                                  SpatialPointMass("pc", "c", 0.2),
                                                  SpatialNodeSpring("s1", "a", "b", 400.0, 0.2),
                                                  SpatialNodeSpring("s2", "b", "c", 300.0),
                                                  SpatialNodeSpring("s3", "a", "c", 250.0)])
    lumped = SpatialSubsystem("net", mass_matrix=fe.mass, damping_matrix=fe.damping, stiffness_matrix=fe.stiffness,
                              nodes={k: (p, fe.dofs[k]) for k, p in nodes.items()}, boundary=("a",))
    models = [sp.SpatialModel("m", [sp.SpatialBody("arm", 1.0, np.diag([0.01, 0.01, 0.01]), points={"end": (0.5, 0, 0)}),
                                    sp.Revolute(name="yaw", parent=None, child="arm", axis=(0, 0, 1)), body,
                                    sp.Spherical(name="ball", parent="arm", point="end", child="net")])
              for body in (fe.subsystem("net", ("a",)), lumped)]
    for q, v in states(models[0], 2):
        q[1:5] = np.array([0.9, 0.1, -0.3, 0.2]) / np.linalg.norm([0.9, 0.1, -0.3, 0.2])
        a = [sp.accelerations(m, q, v) for m in models]
        assert np.max(np.abs(a[0] - a[1])) < 1e-11 * np.max(np.abs(a[0]))


def test_small_deformation_warning_beyond_a_tenth_of_the_size():
    """A soft cantilever sagging under gravity past 10 % of its length: the run goes on with a warning."""
    nodes = {"a": (0.0, 0.0, 0.0), "b": (0.5, 0.0, 0.0), "c": (1.0, 0.0, 0.0)}
    fe = SpatialFiniteElementModel("soft", nodes, [SpatialBeamElement(e, s, t, 1e3, 5.0, 4.0, 4.0, 0.9, 1e-2)
                                                   for e, s, t in (("e0", "a", "b"), ("e1", "b", "c"))])
    model = sp.SpatialModel("sag", [fe.subsystem("beam", ("a", "c")), sp.Weld(name="clamp", parent=None, child="beam")])
    with pytest.warns(SmallDeformationWarning, match="beam"):
        result = ctmm.simulate(model, 0.25, 5e-3, method="rk4")
    assert np.max(np.abs(result["beam.c_uz"])) > 0.1


@pytest.mark.parametrize("joint", ["free", "prismatic"])
def test_energy_is_conserved_on_translating_joints(joint):
    """A subsystem on a Free or Prismatic joint (its terms moved from the frame origin to the inboard point by
    the joint's translation): the energy change of an undamped RK4 run is the integrator's own and falls at its
    order (a wrong coupling would leave a drift that does not vanish with the step)."""
    elements = [SpatialBeamElement(name, a, b, EA, GJ, EIY, EIZ, RHOA, RHOIP, orientation=o) for name, a, b, o in BEAMS]
    elements.append(SpatialPointMass("tip", "n3", TIP_MASS, TIP_INERTIA))
    frame = SpatialFiniteElementModel("fe", NODES, elements).subsystem("frame", boundary=("n0", "n3"))
    if joint == "free":
        parts, gravity = [frame, sp.Free(name="float", parent=None, child="frame")], (0.0, 0.0, 0.0)
    else:
        parts = [sp.SpatialBody("cart", 0.7, np.diag([0.01, 0.01, 0.01]), points={"top": (0.0, 0.0, 0.1)}),
                 sp.Revolute(name="yaw", parent=None, child="cart", axis=(0, 0, 1)), frame,
                 sp.Prismatic(name="slide", parent="cart", point="top", child="frame", axis=(0.6, 0.0, 0.8),
                              stiffness=300.0)]
        gravity = (0.0, 0.0, -9.81)
    model = sp.SpatialModel("translating", parts, gravity=gravity)
    v0 = np.zeros(model.n_velocities)
    v0[:model.n_velocities - frame.n_eta] = [0.3, -0.2, 0.1, 1.5, -2.0, 3.0] if joint == "free" else [2.0, 0.5]
    x0 = model.neutral()
    x0[model.coordinates.index("frame.n3_uz")] = 0.004
    drift = []
    for dt in (2.5e-4, 1.25e-4):
        result = ctmm.simulate(model, 0.03, dt, method="rk4", x0=x0, v0=v0)
        rows = [(np.array([result[c][k] for c in model.coordinates]), np.array([result[c][k] for c in model.velocities]))
                for k in (0, -1)]
        start, end = (sp.energy(model, q, v) for q, v in rows)
        drift.append(abs(end - start) / abs(start))
    assert drift[1] < 1e-4 and drift[0] / drift[1] > 10.0      # RK4's own dissipation, order 4: no model drift


def test_node_ports_match_global_model():
    """Port actuators and sensors at a boundary node: a world force at n3 -> the node's world height and its
    displacement coordinate, vs the global linearisation with the load ``J^T f`` and the output row ``J``."""
    model, ref = chain(damping=3e-4)
    q0 = np.asarray(ctmm.linearize(model).operating_point.q)
    _, J = ref.node_point(q0, "n3")
    w = np.array([1.5, 25.0, 70.0])
    response = np.asarray(ctmm.frequency_response(model, w, input="frame.n3.force_z",
                                                  output=["frame.n3.z", "frame.n3_uz"]).response)
    index = model.coordinates.index("frame.n3_uz")
    for row, output in enumerate((J[2], index)):
        expected = ref.frequency_response(q0, w, load=J[2], output=output)
        assert np.max(np.abs(response[row, 0] - expected) / np.abs(expected)) < 1e-7


def test_feedback_loop_on_the_mixed_model_matches_a_joint_spring_of_the_global_model():
    """A PD loop (ctmm.control.with_feedback) on the yaw of the mixed model = a yaw spring-damper of the
    global model, RK4 same step."""
    from ctmm.control import Feedback, with_feedback

    model, _ = chain(child=False)
    _, ref = chain(child=False)
    ref.joint_springs = {0: (6.0, 0.5)}
    controlled = with_feedback(model, [Feedback("pd", [("yaw.angle", 6.0), ("yaw.angle_rate", 0.5)], "yaw.torque",
                                                gain=1.0)])
    q0 = np.zeros(model.n_positions)
    q0[0], q0[1], q0[5] = 0.3, 0.4, 0.004
    result = ctmm.simulate(controlled, 0.02, 5e-4, method="rk4", x0=q0)
    _, reference = ref.rk4(q0, np.zeros(model.n_velocities), 0.02, 5e-4)
    for k, name in enumerate(model.coordinates):
        assert np.max(np.abs(result[name] - reference[:, k])) < 1e-9 * max(1.0, np.max(np.abs(reference[:, k])))


def test_solve_ivp_run_matches_global_model():
    model, ref = chain(child=False)
    q0 = np.zeros(model.n_positions)
    q0[1], q0[5] = 0.4, 0.004
    result = ctmm.simulate(model, 0.01, 1e-3, method="DOP853", x0=q0, rtol=1e-10, atol=1e-12)
    _, reference = ref.rk4(q0, np.zeros(model.n_velocities), 0.01, 6.25e-5)      # its error ~2e-9 here
    for k, name in enumerate(model.coordinates):
        assert np.max(np.abs(result[name] - reference[::16, k])) < 1e-8 * max(1.0, np.max(np.abs(reference[:, k])))
