"""Planar frequency responses by the one sweep's frequency context (ctmm.planar_transfer_response).

Independent references (no transfer matrices): the Lagrange models of ``ctmm.reference`` -- for rigid
trees ``PlanarLagrange.linearize`` (analytic ``M, C, K`` about the equilibrium, gravity's geometric
stiffness included), inputs and outputs from its own point Jacobians; for a hub with a modal beam
``FlexibleLagrange.accelerations`` linearised here by Richardson central differences, its input column
the difference of the model with and without a unit motor torque -- solved densely at every frequency,
delayed loops as ``e^{-s tau}`` terms of the dynamic stiffness.  Second path: the dense resolvent of
``ctmm.linearize`` (``delayed_loop_response``), which the sweep must equal to round-off.
"""
from __future__ import annotations

import math

import control
import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledModel, Feedback
from ctmm.controlled_linearization import FrequencyAtPoleError, delayed_loop_response
from ctmm.flexible import ModalBeam
from ctmm.planar import (ActuatedHinge, DamperHinge, ElasticHinge, Fixed, FreeBase, Pinned, PlanarModel,
                         RigidBody, SmoothHinge, SpringDamperHinge)
from ctmm.planar.elements import FixedMounting
from ctmm.planar_linearization import linearize_planar, operating_point
from ctmm.reference.flexible_lagrange import FlexibleLagrange
from ctmm.reference.planar_lagrange import PlanarLagrange

OMEGA = np.logspace(-1, 2, 37)
SWEEP = "one sweep's frequency context (ctmm.planar_transfer_response), delays exact"


def rigid_chain(n: int = 3) -> PlanarModel:
    elements = [Pinned("base")]
    for i in range(n):
        if i:
            elements.append(SpringDamperHinge(f"h{i}", stiffness=3.0 + i, damping=0.2 * i))
        elements.append(RigidBody(f"link{i}", mass=1.0 + 0.3 * i, inertia=0.1 + 0.02 * i,
                                  center_of_mass=(0.4, 0.05 * i), outboard=(0.9, 0.1)))
    return PlanarModel.chain("chain", elements, gravity=(0.0, -9.81))


def rigid_tree() -> PlanarModel:
    return PlanarModel("tree", [
        Pinned("base", position=(0.2, -0.1), child="b0"),
        RigidBody("b0", mass=1.5, inertia=0.2, center_of_mass=(0.3, 0.1),
                  outboard={"e0": (0.8, 0.2), "e1": (0.5, -0.4)}),
        SpringDamperHinge("h1", parent="b0.e0", child="b1", stiffness=4.0, damping=0.3),
        RigidBody("b1", mass=0.7, inertia=0.05, center_of_mass=(0.35, -0.05), outboard={"out": (0.7, 0.0)}),
        ElasticHinge("h2", parent="b0.e1", child="b2", stiffness=6.0, rest_angle=0.3),
        RigidBody("b2", mass=0.9, inertia=0.08, center_of_mass=(0.25, 0.0), outboard={"out": (0.6, 0.1)}),
        DamperHinge("h3", parent="b1.out", child="b3", damping=0.5),
        RigidBody("b3", mass=0.4, inertia=0.03, center_of_mass=(0.2, 0.02)),
    ], gravity=(0.0, -9.81))


def hub_beam(torque: float = 0.0, gravity=(0.0, -9.81)) -> PlanarModel:
    beam = ModalBeam("beam", length=1.2, bending_stiffness=40.0, mass_per_length=0.6, n_modes=3,
                     damping_ratio=0.02, stations={"mid": 0.6})
    return PlanarModel.chain("hub_beam", [
        Fixed("ground"), ActuatedHinge("motor", kp=30.0, kd=0.4, torque=torque),
        RigidBody("hub", mass=2.0, inertia=0.05, center_of_mass=(0.05, 0.0), outboard=(0.1, 0.0)),
        FixedMounting("mount"), beam], gravity=gravity)


def hanging(model: PlanarModel) -> np.ndarray:
    """The static equilibrium ctmm finds (the references take it as the point to linearise about)."""
    return operating_point(model).q


def dense(model, loops, omega, inputs, outputs, point):
    """The resolvent path: ctmm.linearize's state space, delayed loops closed by phasors."""
    return delayed_loop_response(lambda a, b: linearize_planar(model, loops, point, inputs=a, outputs=b), loops,
                                 1j * np.asarray(omega), list(inputs), list(outputs), model.name)[0]


def assert_close(value, reference, rtol):
    """Elementwise relative error, each entry against the largest entry of its (output, input) pair."""
    scale = np.max(np.abs(reference), axis=-1, keepdims=True)
    error = float(np.max(np.abs(value - reference) / scale))
    assert error <= rtol, error


# ------------------------------------------------------------------------------ rigid: PlanarLagrange
class RigidReference:
    """Ports of a rigid model written from PlanarLagrange's own kinematics at ``q0``."""

    def __init__(self, model: PlanarModel, q0: np.ndarray) -> None:
        self.model, self.lagrange = model, PlanarLagrange(model)
        self.M, self.C, self.K = self.lagrange.linearize(q0)
        self.kin = self.lagrange.kinematics(q0, np.zeros(q0.size), 0.0)
        self.n = q0.size

    def angle(self, body: str) -> np.ndarray:
        row = np.zeros(self.n)
        row[self.lagrange.src[self.model.body_names.index(body)]] = 1.0
        return row

    def hinge(self, child: str) -> np.ndarray:
        k = self.model.body_names.index(child)
        return self.angle(child) - self.angle(self.model.body_names[self.model.parent[k]])

    def com(self, body: str, axis: int) -> np.ndarray:
        return self.kin["j_c"][self.model.body_names.index(body)][axis]

    def response(self, s, columns, rows, rates=(), loop=None):
        """``rows @ Z(s)^-1 @ columns``; ``rates``: indices of rows multiplied by ``s`` (velocity sensors);
        ``loop = (b, c(s))``: the term ``b c(s)^T`` of a closed loop added to the dynamic stiffness."""
        B, C = np.array(columns).T, np.array(rows)
        out = np.empty((len(rows), len(columns), s.size), dtype=complex)
        for k, sk in enumerate(s):
            Z = sk * sk * self.M + sk * self.C + self.K
            if loop is not None:
                Z = Z + np.outer(loop[0], loop[1](sk))
            y = C @ np.linalg.solve(Z, B)
            y[list(rates)] *= sk
            out[:, :, k] = y
        return out


RIGID_INPUTS = ["h2.torque", "link2.force_x", "link1.moment"]
RIGID_OUTPUTS = ["link2.theta", "link2.com.x", "link2.com.vy", "h1.angle"]


@pytest.mark.parametrize("chunk", [512, 5])
def test_rigid_chain_equals_the_lagrange_model(chunk, monkeypatch):
    import ctmm.sweep_response as sweep_module

    monkeypatch.setattr(sweep_module, "CHUNK", chunk)           # 5: the 37 frequencies swept 5 at a time
    model = rigid_chain()
    q0 = hanging(model)
    ref = RigidReference(model, q0)
    frf = ctmm.frequency_response(model, OMEGA, input=RIGID_INPUTS, output=RIGID_OUTPUTS)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    columns = [ref.hinge("link2"), ref.com("link2", 0), ref.angle("link1")]
    rows = [ref.angle("link2"), ref.com("link2", 0), ref.com("link2", 1), ref.hinge("link1")]
    assert_close(frf.response, ref.response(1j * OMEGA, columns, rows, rates=[2]), 1e-9)


def test_rigid_tree_equals_the_lagrange_model():
    model = rigid_tree()
    q0 = hanging(model)
    ref = RigidReference(model, q0)
    inputs, outputs = ["h1.torque", "b3.force_y", "b2.moment"], ["b3.theta", "b2.com.y", "h3.angle", "b1.omega"]
    frf = ctmm.frequency_response(model, OMEGA, input=inputs, output=outputs)
    assert frf.info["method"] == SWEEP
    columns = [ref.hinge("b1"), ref.com("b3", 1), ref.angle("b2")]
    rows = [ref.angle("b3"), ref.com("b2", 1), ref.hinge("b3"), ref.angle("b1")]
    assert_close(frf.response, ref.response(1j * OMEGA, columns, rows, rates=[3]), 1e-9)


@pytest.mark.parametrize("gain, delay", [(None, 0.05), (None, 0.0), (control.tf([0.5, 2.0], [0.1, 1.0]), 0.03)])
def test_loop_closed_per_frequency_equals_the_lagrange_model(gain, delay):
    model = rigid_chain(2)
    kp, kd = 8.0, 0.6
    if gain is None:        # PD on the hinge angle and rate: the law in the sensor weights, static gain 1
        loop = Feedback("pd", sensor=[("h1.angle", kp), ("h1.rate", kd)], actuator="h1.torque", gain=1.0,
                        delay=delay)
        sensed, law = (lambda s: kp + kd * s), (lambda s: 1.0)                         # noqa: E731
    else:                   # an LTI controller C(s) = (0.5 s + 2) / (0.1 s + 1) on the hinge angle
        loop = Feedback("pd", sensor="h1.angle", actuator="h1.torque", gain=gain, delay=delay)
        sensed, law = (lambda s: 1.0), (lambda s: (0.5 * s + 2.0) / (0.1 * s + 1.0))   # noqa: E731
    system = ControlledModel(model, [loop])
    q0 = hanging(model)
    ref = RigidReference(model, q0)
    b = c = ref.hinge("link1")
    s = 1j * OMEGA
    K = np.array([law(sk) for sk in s]) * np.exp(-s * delay)
    w = np.array([sensed(sk) for sk in s])
    frf = ctmm.frequency_response(system, OMEGA, input=["link1.force_x", "pd.reference"],
                                  output=["link1.theta", "pd.u"])
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    # u = -K (y - r), y = w(s) c q:  (Z + b K w c^T) q = B f + b K r
    closed = ref.response(s, [ref.com("link1", 0), b], [ref.angle("link1"), c],
                          loop=(b, lambda sk: law(sk) * np.exp(-sk * delay) * sensed(sk) * c))
    expected = np.empty((2, 2, s.size), dtype=complex)
    expected[0, 0], expected[0, 1] = closed[0, 0], K * closed[0, 1]
    expected[1, 0] = -K * w * closed[1, 0]
    expected[1, 1] = K * (1.0 - w * K * closed[1, 1])
    assert_close(frf.response, expected, 1e-9)


# ------------------------------------------------------------------------------ flexible: FlexibleLagrange
def richardson(function, x, h=1e-3):
    """Central differences at h and h/2, Richardson-extrapolated (error O(h^4))."""
    columns = []
    for i in range(x.size):
        e = np.zeros(x.size)
        e[i] = 1.0
        d1 = (function(x + h * e) - function(x - h * e)) / (2 * h)
        d2 = (function(x + h / 2 * e) - function(x - h / 2 * e)) / h
        columns.append((4.0 * d2 - d1) / 3.0)
    return np.array(columns).T


def test_hub_with_a_damped_modal_beam_equals_the_lagrange_model():
    model = hub_beam()
    q0 = hanging(model)
    n = q0.size
    lagrange, pushed = FlexibleLagrange(model), FlexibleLagrange(hub_beam(torque=1.0))
    zero = np.zeros(n)
    Jq = richardson(lambda q: lagrange.accelerations(q, zero), q0)
    Jv = richardson(lambda v: lagrange.accelerations(q0, v), zero)
    b = pushed.accelerations(q0, zero) - lagrange.accelerations(q0, zero)      # affine in the torque
    A = np.block([[np.zeros((n, n)), np.eye(n)], [Jq, Jv]])
    B = np.concatenate([zero, b])
    outputs = list(model.coordinates) + ["beam.q2_dot"]
    C = np.vstack([np.eye(n, 2 * n), np.eye(2 * n)[n + 2]])
    expected = np.array([C @ np.linalg.solve(1j * w * np.eye(2 * n) - A, B) for w in OMEGA]).T[:, None, :]
    frf = ctmm.frequency_response(model, OMEGA, input="motor.torque", output=outputs)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    assert_close(frf.response, expected, 1e-9)


# ------------------------------------------------------------------------------ the resolvent path
def free_base_tree() -> PlanarModel:
    return PlanarModel("floating", [
        FreeBase("base", child="b0"),
        RigidBody("b0", mass=1.5, inertia=0.2, center_of_mass=(0.3, 0.1), outboard={"e0": (0.8, 0.2)}),
        SpringDamperHinge("h1", parent="b0.e0", child="b1", stiffness=4.0, damping=0.3),
        RigidBody("b1", mass=0.7, inertia=0.05, center_of_mass=(0.35, -0.05)),
    ], gravity=(0.0, 0.0))


def deflected_beam_with_a_link() -> PlanarModel:
    """A beam out from a spring hinge, bent by gravity (static modal deflection), a link hanging at its tip."""
    beam = ModalBeam("beam", length=1.0, bending_stiffness=30.0, mass_per_length=0.8, n_modes=3, damping_ratio=0.01)
    return PlanarModel.chain("beam_tip", [Fixed("ground"), SpringDamperHinge("motor", stiffness=80.0, damping=0.5),
                                          beam, SmoothHinge("tip"), RigidBody.uniform_link("link", mass=0.3, length=0.4)],
                             gravity=(0.0, -9.81))


CASES = {
    "deflected_beam": (deflected_beam_with_a_link, ["motor.torque", "beam.q2.force", "link.force_x"],
                       ["link.theta", "beam.out.y", "beam.q1", "tip.rate"]),
    "hub_beam": (hub_beam, ["beam.q1.force", "beam.mid.force", "beam.mid.moment", "motor.torque", "hub.force_y"],
                 ["beam.mid.w", "beam.mid.slope_rate", "beam.out.y", "beam.theta", "motor.rate"]),
    "tree": (rigid_tree, ["h3.torque", "b0.force_x"], ["b1.out.vx", "b2.inboard.x", "h2.rate"]),
    "free_base": (free_base_tree, ["b1.force_x", "h1.torque", "b0.moment"], ["b0.x", "b1.com.y", "h1.angle"]),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_sweep_equals_the_resolvent_path(name):
    build, inputs, outputs = CASES[name]
    model = build()
    point = (np.zeros(model.n_coordinates), np.zeros(model.n_coordinates)) if name == "free_base" else None
    frf = ctmm.frequency_response(model, OMEGA, input=inputs, output=outputs, operating_point=point)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    assert_close(frf.response, dense(model, (), OMEGA, inputs, outputs, point), 1e-10)


def test_delayed_loop_on_a_beam_equals_the_resolvent_path():
    model = hub_beam()
    loops = [Feedback("tip", sensor=[("beam.mid.w", 50.0), ("beam.mid.w_dot", 2.0)], actuator="beam.q1.force",
                      gain=1.0, delay=0.02),
             Feedback("hubloop", sensor="motor.angle", actuator="motor.torque", gain=control.tf([3.0], [0.05, 1.0]))]
    system = ControlledModel(model, loops)
    inputs, outputs = ["hub.force_x", "tip.reference", "hubloop.reference"], ["beam.out.y", "tip.u", "hubloop.y"]
    frf = ctmm.frequency_response(system, OMEGA, input=inputs, output=outputs)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    assert_close(frf.response, dense(model, loops, OMEGA, inputs, outputs, None), 1e-10)


# ------------------------------------------------------------------------------ pivots: certify or hand back
def undamped_double_pendulum() -> PlanarModel:
    return PlanarModel.chain("double", [Pinned("base"), RigidBody.uniform_link("l0", mass=1.0, length=1.0),
                                        SmoothHinge("h1"), RigidBody.uniform_link("l1", mass=1.0, length=1.0)],
                             gravity=(0.0, -9.81))


def test_a_substructure_resonance_is_answered_by_the_resolvent_and_correct():
    """At omega^2 = m g (L/2) / J_pin of the outer link alone (J_pin = m L^2 / 3) its joint pivot is zero:
    the sweep hands that frequency to the resolvent, which answers (it is no pole of the whole model)."""
    model = undamped_double_pendulum()
    w_sub = math.sqrt(9.81 * 0.5 / (1.0 / 3.0))
    omega = np.array([1.0, w_sub, 7.0])
    frf = ctmm.frequency_response(model, omega, input="l1.force_x", output=["l0.theta", "l1.theta"])
    assert frf.info["n_dense_frequencies"] == 1
    q0 = hanging(model)
    ref = RigidReference(model, q0)
    expected = ref.response(1j * omega, [ref.com("l1", 0)], [ref.angle("l0"), ref.angle("l1")])
    assert_close(frf.response, expected, 1e-9)


def test_a_pole_is_refused_by_the_resolvent_rule():
    model = undamped_double_pendulum()
    q0 = hanging(model)
    ref = RigidReference(model, q0)
    poles = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(ref.M, ref.K)).real))
    with pytest.raises(FrequencyAtPoleError, match="singular at omega"):
        ctmm.frequency_response(model, [1.0, float(poles[1])], input="l1.force_x", output="l1.theta")
    near = ctmm.frequency_response(model, [poles[1] * (1 + 1e-6)], input="l1.force_x", output="l1.theta")
    assert near.info["n_dense_frequencies"] == 0
    expected = ref.response(1j * poles[1:2] * (1 + 1e-6), [ref.com("l1", 0)], [ref.angle("l1")])
    assert_close(near.response, expected, 1e-8)


def test_rigid_body_mode_at_zero_frequency_is_refused():
    model = free_base_tree()
    point = (np.zeros(model.n_coordinates), np.zeros(model.n_coordinates))
    with pytest.raises(FrequencyAtPoleError, match="omega = 0.0"):
        ctmm.frequency_response(model, [0.0, 1.0], input="b1.force_x", output="b0.x", operating_point=point)


def test_models_off_the_sweep_take_the_dense_path():
    model = PlanarModel.chain("bushing", [Pinned("base"), RigidBody.uniform_link("l0", mass=1.0, length=1.0),
                                          ElasticHinge("h1", stiffness=5.0, translational_stiffness=400.0),
                                          RigidBody.uniform_link("l1", mass=1.0, length=1.0)], gravity=(0.0, -9.81))
    frf = ctmm.frequency_response(model, [1.0, 3.0], input="h1.torque", output="l1.theta")
    assert frf.info["method"].startswith("linearisation") and frf.info["n_dense_frequencies"] == 2


def test_finite_element_subsystem_equals_the_global_dynamic_stiffness():
    """A ctmm.fem beam subsystem (Rayleigh damping) between two links: the sweep states it like a modal body;
    reference: the global model of tests/test_mixed.py (its own M, K and, by complex step, C)."""
    from test_mixed import build, global_matrices

    model, reference = build(rayleigh=(0.5, 1e-4))
    n = reference.n
    M, C, K = global_matrices(reference)
    inputs, outputs = ["flex.n3_uy.force", "flex.n1_rz.force"], ["lower.theta", "flex.n2_uy", "upper.theta"]
    frf = ctmm.frequency_response(model, OMEGA, input=inputs, output=outputs)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    columns = np.eye(n)[:, [model.coordinates.index(name[:-len(".force")]) for name in inputs]]
    rows = np.eye(n)[[model.coordinates.index(name) for name in outputs]]
    expected = np.array([rows @ np.linalg.solve(K - w * w * M + 1j * w * C, columns) for w in OMEGA])
    assert_close(frf.response, np.moveaxis(expected, 0, -1), 1e-9)


def test_acceleration_outputs_are_s_squared_times_the_positions():
    """Outputs of frequency_response only (not port sensors): the Lagrange model's accelerations -omega^2 x."""
    model = rigid_chain()
    ref = RigidReference(model, hanging(model))
    outputs = ["link2.com.ax", "link2.alpha", "link1.theta_ddot", "link2.com.y"]
    frf = ctmm.frequency_response(model, OMEGA, input="link2.force_x", output=outputs)
    assert frf.info["method"] == SWEEP
    assert [frf.units[name] for name in outputs] == ["m/s^2", "rad/s^2", "rad/s^2", "m"]
    s = 1j * OMEGA
    positions = ref.response(s, [ref.com("link2", 0)], [ref.com("link2", 0), ref.angle("link2"), ref.angle("link1"),
                                                       ref.com("link2", 1)])
    expected = positions * np.array([s * s, s * s, s * s, np.ones_like(s)])[:, None, :]
    assert_close(frf.response, expected, 1e-9)
    undamped = undamped_double_pendulum()       # the dense path (a substructure resonance) answers them too
    w_sub = math.sqrt(9.81 * 0.5 / (1.0 / 3.0))
    both = ctmm.frequency_response(undamped, [1.0, w_sub], input="l1.force_x", output=["l1.alpha", "l1.theta"])
    assert both.info["n_dense_frequencies"] == 1
    np.testing.assert_allclose(both.response[0], -np.array([1.0, w_sub]) ** 2 * both.response[1], rtol=1e-14)
    with pytest.raises(ctmm.errors.ModelError, match="l1.beta"):
        ctmm.frequency_response(undamped, [1.0], input="l1.force_x", output="l1.beta")


@pytest.mark.parametrize("delay", [0.0, 0.02])
def test_a_closed_loop_pole_on_the_axis_goes_to_the_resolvent_rule(delay):
    """A P loop on the outer hinge of the undamped double pendulum: where I + K G_yu is singular (a closed-loop
    pole on the imaginary axis) the sweep hands the frequency back; with the loop closed inside A (no delay)
    the resolvent refuses it; next to it both paths answer alike."""
    model = undamped_double_pendulum()
    loop = Feedback("p", sensor="h1.angle", actuator="h1.torque", gain=5.0, delay=delay)
    system = ControlledModel(model, [loop])
    kind = (FrequencyAtPoleError,) if delay == 0.0 else ()
    # closed-loop poles: det(Z(i w) + b K c^T) = 0 on the axis (real for delay 0), from the Lagrange model
    ref = RigidReference(model, hanging(model))
    b = ref.hinge("l1")
    M, K = ref.M, ref.K + 5.0 * np.outer(b, b)
    poles = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    if kind:
        with pytest.raises(FrequencyAtPoleError):
            ctmm.frequency_response(system, [1.0, float(poles[0])], input="l1.force_x", output="l1.theta")
    near = poles[0] * (1 + 1e-5)
    frf = ctmm.frequency_response(system, [1.0, near], input="l1.force_x", output="l1.theta")
    expected = dense(model, [loop], [1.0, near], ["l1.force_x"], ["l1.theta"], None)
    assert_close(frf.response, expected, 1e-8)
