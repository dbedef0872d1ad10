"""Spatial frequency responses by the one sweep's frequency context (ctmm.spatial_transfer_response).

Independent references: the global Newton-Euler linearisation ``M, C, K`` of ``ctmm/reference/spatial_tree.py``
(rigid trees; joint torques are unit generalised forces of their velocities) and the assumed-modes Lagrange
model ``ctmm/reference/spatial_beam_lagrange.py`` (hub + spatial beam + tip body), both in zero gravity
(preloaded equilibria: tests/test_spatial_frf_sweep_gravity.py).  Second path: the dense resolvent of
``ctmm.linearize`` (``delayed_loop_response``), which the sweep must equal to round-off.  Tolerance 1e-9 of
each (output, input) pair's largest entry, away from poles.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback, with_feedback
from ctmm.controlled_linearization import FrequencyAtPoleError, delayed_loop_response
from ctmm.errors import ModelError
from ctmm.reference.spatial_beam_lagrange import HubBeam, SpatialBeamLagrange
from ctmm.spatial.ports import SpatialPorts
from ctmm.spatial_linearization import linearize_spatial, operating_point, tangent_names
from spatial_linear_helpers import random_spring_tree, reference_matrices

SWEEP = "one sweep's frequency context (ctmm.spatial_transfer_response), delays exact"
DENSE = "linearisation (ctmm.linearize), delays exact"
OMEGA = np.array([0.07, 0.4, 1.3, 3.1, 7.7, 16.0])


def weightless(seed: int, n: int, damped: bool = True) -> sp.SpatialModel:
    """The random sprung tree of the linearisation tests (revolute, universal, prismatic, unsprung spherical,
    weld) in zero gravity."""
    model = random_spring_tree(np.random.default_rng(seed), n, "universal", damped=damped)
    return sp.SpatialModel("weightless", list(model.bodies) + list(model.joints), gravity=(0.0, 0.0, 0.0))


def turned(model: sp.SpatialModel, seed: int) -> np.ndarray:
    """An equilibrium away from the neutral pose: the unsprung spherical joints turned at random."""
    rng = np.random.default_rng(seed)
    q = model.neutral()
    for joint, layout in zip(model.joints, model.layout):
        if joint.kind == "spherical":
            quaternion = rng.normal(size=4)
            q[layout.position] = quaternion / np.linalg.norm(quaternion)
    return q


def dense(model, loops, omega, inputs, outputs, point):
    return delayed_loop_response(lambda a, b: linearize_spatial(model, point, inputs=a, outputs=b, loops=loops),
                                 loops, 1j * np.asarray(omega), list(inputs), list(outputs), model.name)[0]


def assert_close(value, reference, rtol):
    scale = np.max(np.abs(reference), axis=-1, keepdims=True)
    assert np.all(np.abs(value - reference) <= rtol * scale), np.max(np.abs(value - reference) / scale)


def joint_torques(model: sp.SpatialModel) -> tuple[list, np.ndarray]:
    """Joint-torque actuators and their generalised-force columns (unit entries on their velocities)."""
    actuators = SpatialPorts(model).actuators
    names, rows = [], []
    for name, actuator in actuators.items():
        if actuator.kind == "joint":
            layout = next(lay for joint, lay in zip(model.joints, model.layout) if actuator.target in joint.inputs)
            names.append(name)
            rows.append(layout.velocity.start + actuator.component)
    forcing = np.zeros((model.n_velocities, len(names)))
    forcing[rows, np.arange(len(names))] = 1.0
    return names, forcing


def reference_response(model, q0, omega, forcing):
    mass, damping, stiffness = reference_matrices(model, q0)
    return np.stack([np.linalg.solve(stiffness + 1j * w * damping - w * w * mass, forcing) for w in omega], axis=-1)


@pytest.mark.parametrize("seed", [11, 5])
def test_rigid_tree_equals_the_newton_euler_reference(seed):
    model = weightless(seed, 6)
    q0 = turned(model, seed)
    inputs, forcing = joint_torques(model)
    outputs = list(tangent_names(model))
    frf = ctmm.frequency_response(model, OMEGA, input=inputs, output=outputs,
                                  operating_point=(q0, np.zeros(model.n_velocities)))
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    assert_close(frf.response, reference_response(model, q0, OMEGA, forcing), 1e-9)


def test_body_forces_sensors_and_rates_equal_the_dense_path():
    model = weightless(11, 6)
    point = operating_point(model, (turned(model, 3), np.zeros(model.n_velocities)))
    inputs = ["b2.p1.force_body_y", "b4.moment_z", "b1.origin.force_x", "b5.force_body_z", "j1.torque"]
    outputs = ["j1.angle", "j1.rate", "j0.angle2", "b4.origin.vy", "b3.p0.z"]
    outputs = [name for name in outputs if name in SpatialPorts(model).sensors] + ["j3.rx"]
    assert len(outputs) >= 4
    frf = ctmm.frequency_response(model, OMEGA, input=inputs, output=outputs, operating_point=point)
    assert frf.info["method"] == SWEEP
    assert_close(frf.response, dense(model, (), OMEGA, inputs, outputs, point), 1e-9)


def hub_beam(axes):
    """Hub on a sprung revolute or universal joint, a spatial beam welded to it, a tip body; zero gravity."""
    beam = dict(length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0, n_modes_y=2,
                n_modes_z=2, n_torsion_modes=1, torsional_stiffness=3.0, polar_inertia_per_length=0.002,
                n_axial_modes=1, axial_stiffness=400.0)
    hub_inertia = np.array([[0.12, 0.01, 0], [0.01, 0.1, 0.02], [0, 0.02, 0.15]])
    tip_inertia = np.array([[0.004, 0.0005, 0], [0.0005, 0.005, 0.0003], [0, 0.0003, 0.006]])
    reference = SpatialBeamLagrange(HubBeam(
        **beam, hub_mass=2.0, hub_inertia=hub_inertia, hub_center=(0.03, 0.01, 0.02), axes=axes,
        mount=(0.2, 0.0, 0.05), damping_ratio=0.01, tip_mass=0.3, tip_inertia=tip_inertia,
        tip_center=(0.03, 0.02, -0.01), gravity=(0.0, 0.0, 0.0), joint_stiffness=[2.0] * len(axes),
        joint_damping=[0.1] * len(axes)))
    law = dict(stiffness=2.0, damping=0.1, actuated=True)
    joint = (sp.Revolute(name="hubj", parent=None, child="hub", axis=axes[0], **law) if len(axes) == 1 else
             sp.Universal(name="hubj", parent=None, child="hub", axis1=axes[0], axis2=axes[1], **law))
    model = sp.SpatialModel("hub_beam", [
        sp.SpatialBody("hub", mass=2.0, inertia=hub_inertia, center_of_mass=(0.03, 0.01, 0.02),
                       points={"out": (0.2, 0, 0.05)}), joint,
        sp.SpatialBeam("b", **beam, damping_ratio=0.01),
        sp.Weld(name="mount", parent="hub", child="b", point="out"),
        sp.SpatialBody("tip", mass=0.3, inertia=tip_inertia, center_of_mass=(0.03, 0.02, -0.01)),
        sp.Weld(name="m2", parent="b", child="tip", point="tip")], gravity=(0.0, 0.0, 0.0))
    return model, reference


@pytest.mark.parametrize("axes", [((0, 0, 1),), ((0, 0, 1), (0, 1, 0))], ids=["revolute", "universal"])
def test_hub_beam_equals_the_lagrange_model(axes):
    model, reference = hub_beam(axes)
    n = model.n_velocities
    A, B, _ = reference.linearize(np.zeros(n))
    inputs = ["hubj.torque"] if len(axes) == 1 else ["hubj.torque1", "hubj.torque2"]
    outputs = list(tangent_names(model))
    frf = ctmm.frequency_response(model, OMEGA, input=inputs, output=outputs)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    expected = np.stack([np.linalg.solve(1j * w * np.eye(2 * n) - A, B[:, :len(axes)])[:n] for w in OMEGA], axis=-1)
    assert_close(frf.response, expected, 1e-9)


@pytest.mark.parametrize("delay", [0.04, 0.0])
def test_delayed_loop_closed_per_frequency_equals_the_reference(delay):
    model = weightless(11, 6)
    kp, kd = 6.0, 0.5
    loop = Feedback("pd", sensor=[("j1.angle", kp), ("j1.rate", kd)], actuator="j1.torque", gain=1.0, delay=delay)
    system = with_feedback(model, [loop])
    inputs, forcing = joint_torques(model)
    frf = ctmm.frequency_response(system, OMEGA, input=[inputs[0], "pd.reference"], output=["j2.angle1", "pd.u"])
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    q0 = model.neutral()
    mass, damping, stiffness = reference_matrices(model, q0)
    names = list(tangent_names(model))
    c, b = np.zeros(model.n_velocities), forcing[:, inputs.index("j1.torque")]
    c[names.index("j1.angle")] = 1.0
    expected = np.zeros((2, 2, OMEGA.size), dtype=complex)
    for k, w in enumerate(OMEGA):
        s = 1j * w
        K, weight = np.exp(-s * delay), kp + kd * s          # u = -K (weight c.q - r)
        Z = stiffness + s * damping + s * s * mass + K * weight * np.outer(b, c)
        q = np.linalg.solve(Z, np.column_stack([forcing[:, 0], K * b]))
        u = -K * (weight * c @ q - np.array([0.0, 1.0]))
        expected[:, :, k] = np.vstack([q[names.index("j2.angle1")], u])
    assert_close(frf.response, expected, 1e-9)
    point = operating_point(model)
    assert_close(frf.response, dense(model, [loop], OMEGA, [inputs[0], "pd.reference"], ["j2.angle1", "pd.u"], point),
                 1e-9)


def test_a_pole_is_handed_back():
    """(Gravity and static loads: tests/test_spatial_frf_sweep_gravity.py.)"""
    model = weightless(11, 4)
    # omega = 0: the free spin of the unsprung ball joint is a pole; the sweep hands it to the resolvent, which refuses
    with pytest.raises(ModelError, match="singular at omega = 0.0"):
        ctmm.frequency_response(model, [0.0, 1.0], input="j1.torque", output="j1.angle")
    undamped = weightless(11, 4, damped=False)
    first = ctmm.natural_frequencies(undamped, n_modes=4)
    first = first[first > 0][0]
    # next to an undamped pole: the sweep's pivot closes, the frequency goes to the resolvent, which refuses it
    with pytest.raises(FrequencyAtPoleError, match="singular at omega"):
        ctmm.frequency_response(undamped, [0.5 * first, first * (1.0 + 1e-12)], input="j1.torque", output="j1.angle")
    frf = ctmm.frequency_response(undamped, [0.5 * first, first * (1.0 + 1e-5)], input="j1.torque", output="j1.angle")
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0


def test_finite_element_subsystem_equals_the_global_fe_model():
    """The FE L-frame chain of tests/test_spatial_fem.py (a ctmm.fem spatial subsystem between two links, Rayleigh
    damping) in zero gravity against its global FE reference's (K + i omega C - omega^2 M)^-1."""
    from test_spatial_fem import chain as fe_chain

    model, reference = fe_chain(gravity=0.0, damping=3e-4)
    point = operating_point(model)
    omega = np.array([0.7, 3.0, 20.0, 55.0])
    outputs = ["frame.n3_uz", "hinge.angle"]
    frf = ctmm.frequency_response(model, omega, input="yaw.torque", output=outputs)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    expected = reference.frequency_response(point.q, omega, load=0, output=model.coordinates.index("frame.n3_uz"))
    assert_close(frf.response[0, 0], expected, 1e-9)
    assert_close(frf.response, dense(model, (), omega, ["yaw.torque"], outputs, point), 1e-9)


@pytest.mark.parametrize("steps, accurate", [(None, True), ((1e-3,), False)], ids=["cross_check_steps", "one_step"])
def test_dense_fallback_keeps_the_exact_tangent_of_a_long_planar_chain(steps, accurate, monkeypatch):
    """The dense path's error on the last link's angle of a long hanging chain (1.1e-4 at N = 100) came from its
    tangent: the Richardson cross-check of the exact complex-step Jacobian, at one relative step 1e-3, exceeded
    its tolerance past about 54 links and the tangent fell back to differences (~1e-8 max|A|).  With the steps
    ctmm.planar_linearization.CROSS_CHECK_STEPS the complex step is kept and the resolvent equals the Lagrange
    model to 1e-9 (the one-step variant shows the test can fail)."""
    import sys
    from pathlib import Path

    import ctmm.planar_linearization as planar_linearization
    from ctmm.reference.planar_lagrange import PlanarLagrange

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from planar_chain import chain

    if steps is not None:
        monkeypatch.setattr(planar_linearization, "CROSS_CHECK_STEPS", steps)
    n, omega = 56, np.array([0.38, 0.48, 0.92, 3.0])
    model = chain(n)
    q0 = np.full(n, -np.pi / 2)
    force, angle = f"link{n - 1}.force_x", f"link{n - 1}.theta"
    got = delayed_loop_response(lambda a, b: planar_linearization.linearize_planar(model, (), (q0, np.zeros(n)),
                                                                                   inputs=a, outputs=b),
                                (), 1j * omega, [force], [angle], model.name)[0][0, 0]
    reference = PlanarLagrange(model)
    M, _, K = reference.linearize(q0)
    column = reference.kinematics(q0, np.zeros(n), 0.0)["j_c"][n - 1][0]     # force_x at the last link's centre
    row = np.zeros(n)
    row[reference.src[n - 1]] = 1.0                                           # its absolute angle
    expected = np.array([row @ np.linalg.solve(K - w * w * M, column) for w in omega])
    error = float(np.max(np.abs(got - expected) / np.abs(expected)))
    assert (error <= 1e-9) == accurate, error
