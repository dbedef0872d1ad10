"""Prismatic (slider) cut joints of spatial kinematic loops (ctmm.spatial.closed_loops): a spatial slider-crank whose
slider runs on an inclined ground guide, and a body sliding along a swinging pendulum (the guide itself moving),
checked against the independent Newton-Euler DAE (ctmm.reference.spatial_loop_dae) with its own prismatic rows."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.spatial import closed_loop_linear as linear
from ctmm.spatial.closed_loop_time import simulate_spatial_loops
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel
from spatial_loop_helpers import dae_of, poses, rod

DOWN = np.diag([1.0, -1.0, -1.0])
GUIDE = np.array([0.0, 1.0, 0.3])                  # the slide direction, world axes (inclined: gravity drives it)


def slider_crank(baumgarte: float = 20.0) -> SpatialKinematicLoopModel:
    """Crank (revolute about world x), connecting rod (ball joint at the crank tip), slider (universal joint at the
    rod tip) and the prismatic cut of the slider on a ground guide along ``GUIDE`` offset by 0.15 m in x from the
    crank plane (1 degree of freedom; the slider's body z kept in the plane of the guide and world z)."""
    tree = sp.SpatialModel("slider_crank", [
        rod("crank", 0.4, 0.2, direction=2),
        sp.Revolute(name="h1", parent=None, child="crank", axis=(1, 0, 0), rotation=DOWN, actuated=True),
        rod("rod", 0.6, 0.7, direction=1),
        sp.Spherical(name="s2", parent="crank", point="tip", child="rod"),
        sp.SpatialBody("slider", 0.5, np.diag([0.002, 0.003, 0.0025]), center_of_mass=(0.01, 0.0, 0.02)),
        sp.Universal(name="u3", parent="rod", point="tip", child="slider", axis1=(0, 0, 1), axis2=(1, 0, 0))])
    cut = SpatialCutJoint(name="slide", parent=None, point=(0.15, 0.0, -0.1), child="slider", kind="prismatic",
                          axis=(0, 1, 0), parent_axis=GUIDE, normal=(0, 0, 1), parent_normal=(0, -0.3, 1))
    return SpatialKinematicLoopModel(tree, [cut], baumgarte=baumgarte)


def sliding_pendulum(baumgarte: float = 20.0) -> SpatialKinematicLoopModel:
    """A rod swinging about world x (revolute) and a sleeve on a free joint held on the rod by a prismatic cut along
    the rod's axis (2 degrees of freedom: the swing and the slide; the guide moves)."""
    tree = sp.SpatialModel("sliding_pendulum", [
        rod("arm", 0.8, 0.6, direction=2),
        sp.Revolute(name="h1", parent=None, child="arm", axis=(1, 0, 0), rotation=DOWN),
        sp.SpatialBody("sleeve", 0.3, np.diag([0.003, 0.002, 0.001]), center_of_mass=(0.02, 0.0, 0.0)),
        sp.Free(name="free", parent=None, child="sleeve")])
    cut = SpatialCutJoint(name="sleeve_on_arm", parent="arm", point="origin", child="sleeve", kind="prismatic",
                          axis=(0, 0, 1), normal=(1, 0, 0), parent_normal=(1, 0, 0))
    return SpatialKinematicLoopModel(tree, [cut], baumgarte=baumgarte)


def dae(loop: SpatialKinematicLoopModel, baumgarte: float = 10.0):
    """The DAE of the loop with the cut's roll reference given explicitly (its prismatic rows are its own)."""
    model = dae_of(loop, baumgarte)
    cut = loop.cuts[0]
    model.joints[-1] = replace(model.joints[-1], child_normal=np.asarray(cut.normal), parent_normal=np.asarray(
        cut.parent_normal))
    return model


def cut_load_of_dae(loop, model, y, mu) -> tuple[np.ndarray, np.ndarray]:
    """Force and moment on the child (world) from the DAE's multipliers of the cut (its last 5 rows)."""
    joint, R = model.joints[-1], model.rotations(y)
    b = [basis if joint.parent < 0 else R[joint.parent] @ basis for basis in joint.parent_vectors()]
    force = mu[-5] * b[0] + mu[-4] * b[1]
    moment = sum(m * np.cross(R[joint.child] @ u, b_local if joint.parent < 0 else R[joint.parent] @ b_local)
                 for m, (u, b_local) in zip(mu[-3:], joint.pairs()))
    return force, moment


def errors(loop, run, model):
    """Largest rotation-matrix [rad] and centre-of-mass [m] differences against the DAE from the same start, the DAE
    states."""
    _, Y = model.simulate(model.state(*poses(loop, run.q[0], run.v[0])), run.t)
    angle = position = 0.0
    for k in range(len(run.t)):
        x, R, _, _ = poses(loop, run.q[k], run.v[k])
        angle = max(angle, max(np.abs(a - b).max() for a, b in zip(R, model.rotations(Y[k]))))
        position = max(position, max(np.abs(a - b).max() for a, b in zip(x, model.split(Y[k])[0])))
    return angle, position, Y


@pytest.fixture(scope="module")
def crank():
    loop = slider_crank()
    q, v = loop.consistent_state({"h1.angle": 0.3}, {"h1.angle_rate": 2.0}, keep=["h1"])
    return loop, q, v


@pytest.fixture(scope="module")
def crank_equilibrium(crank):
    loop, q, _ = crank
    return linear.equilibrium(loop, q)


@pytest.fixture(scope="module")
def pendulum():
    loop = sliding_pendulum()
    q, v = loop.consistent_state({"h1.angle": 0.4, "free.z": -0.3}, {"h1.angle_rate": 1.5, "free.vz": 0.2},
                                 keep=["h1"])
    return loop, q, v


@pytest.mark.parametrize("which", ["crank", "pendulum"])
def test_assembled_state_satisfies_the_dae_rows(which, request):
    """The DAE's own prismatic rows (other alignment pairs) vanish on the state ctmm assembled: same manifold."""
    loop, q, v = request.getfixturevalue(which)
    phi, rate = loop.constraints(q, v)
    assert phi.shape == (5,) and np.max(np.abs(phi)) < 1e-12 and np.max(np.abs(rate)) < 1e-12
    assert np.linalg.matrix_rank(loop.jacobian(q)) == 5
    model = dae(loop)
    y0 = model.state(*poses(loop, q, v))
    phi_dae, J_dae, _ = model.rows(y0)
    assert np.max(np.abs(phi_dae)) < 1e-12 and np.max(np.abs(J_dae @ model.velocities(y0))) < 1e-12


@pytest.mark.parametrize("which", ["crank", "pendulum"])
def test_rk4_with_projection_matches_the_dae_motion_and_cut_loads(which, request):
    loop, q, v = request.getfixturevalue(which)
    run = simulate_spatial_loops(loop, q, v, t_final=0.04, dt=1e-3)
    model = dae(loop)
    angle, position, Y = errors(loop, run, model)
    assert angle < 1e-10 and position < 1e-10                    # measured 6e-13 rad, 1.6e-13 m
    assert run.drift.max() < 1e-14 and run.drift_rate.max() < 1e-13
    force, moment = cut_load_of_dae(loop, model, Y[-1], model.accelerations(Y[-1])[1])
    scale = max(np.abs(force).max(), np.abs(moment).max())
    assert np.max(np.abs(run.cut_force[-1, 0] - force)) < 1e-9 * scale      # measured 7.7e-12
    assert np.max(np.abs(run.cut_moment[-1, 0] - moment)) < 1e-9 * scale
    axis = GUIDE / np.linalg.norm(GUIDE) if which == "crank" else poses(loop, run.q[-1], run.v[-1])[1][0][:, 2]
    assert abs(run.cut_force[-1, 0] @ axis) < 1e-12 * scale         # a smooth slide: no force along the guide


def test_solve_ivp_with_baumgarte_matches_the_dae(crank):
    loop, q, v = crank
    run = simulate_spatial_loops(loop, q, v, t_final=0.06, dt=0.02, method="DOP853", rtol=1e-11, atol=1e-12)
    angle, position, _ = errors(loop, run, dae(loop))
    assert angle < 1e-10 and position < 1e-10 and run.drift.max() < 1e-12     # measured 4e-15, 3e-15


def test_linearize_torque_input_and_cut_force_output_match_the_dae(crank, crank_equilibrium):
    """``B`` and ``D`` of ``ctmm.linearize`` at the slider-crank's equilibrium: the crank's angular acceleration and
    the guide's force per unit crank torque (about world x, the hinge axis), against the DAE with the torque."""
    loop, _, _ = crank
    equilibrium = crank_equilibrium
    lin = ctmm.linearize(loop, equilibrium, inputs=["h1.torque"], outputs=["h1.angle", "slide.force_z"])
    crank_rate = (linear.tangent(loop, equilibrium)[1] @ np.asarray(lin.state_space.B)[1:, 0])[0]
    model = dae(loop)
    y = model.state(*poses(loop, equilibrium, np.zeros(loop.tree.n_velocities)))
    rest, mu0 = model.accelerations(y)
    pushed, mu1 = model.accelerations(y, torques={0: np.array([1.0, 0.0, 0.0])})
    assert abs(crank_rate - (pushed - rest)[3]) < 1e-10 * abs(crank_rate)        # measured 9e-15
    force = cut_load_of_dae(loop, model, y, mu1)[0] - cut_load_of_dae(loop, model, y, mu0)[0]
    assert abs(np.asarray(lin.state_space.D)[1, 0] - force[2]) < 1e-10 * np.abs(force).max()     # measured 6e-15


def test_drift_without_projection_is_reported(pendulum):
    loop, q, v = pendulum
    free = SpatialKinematicLoopModel(loop.tree, loop.cuts, baumgarte=0.0)
    loose = simulate_spatial_loops(free, q, v, t_final=0.05, dt=5e-3, projection=False)
    assert loose.drift[-1] > 1e-12 and loose.drift[-1] == np.max(np.abs(free.constraints(loose.q[-1],
                                                                                          loose.v[-1])[0]))


def test_natural_frequency_matches_the_dae_on_its_manifold(crank, crank_equilibrium):
    loop, _, _ = crank
    equilibrium = crank_equilibrium
    omega = ctmm.natural_frequencies(loop, operating_point=equilibrium)
    model = dae(loop)
    y = model.state(*poses(loop, equilibrium, np.zeros(loop.tree.n_velocities)))
    assert np.max(np.abs(model.accelerations(y)[0])) < 1e-8       # an equilibrium of the DAE too
    reference = model.natural_frequencies(y)
    assert omega.shape == (1,) and abs(omega[0] / reference[0] - 1.0) < 1e-9     # measured 9.6e-11 (5.6651 rad/s)


def test_newmark_with_the_cut_loads_as_tree_inputs_converges_to_the_dae(pendulum):
    """A DT-TMM scheme on the tree with the cut loads as inputs (``cut_inputs``: the guide's reaction at the sleeve's
    point, not at the guide's origin) against the DAE: second order (measured 1.32e-6 / 3.29e-7 rad at 4 / 2 ms)."""
    loop, q, v = pendulum
    model, angles = dae(loop), []
    for dt in (4e-3, 2e-3):
        result = ctmm.simulate(loop, 0.024, dt, x0=q, v0=v, method="newmark")
        qs = np.array([result[name] for name in loop.tree.coordinates]).T
        vs = np.array([result[name] for name in loop.tree.velocities]).T
        _, Y = model.simulate(model.state(*poses(loop, q, v)), result.time)
        angles.append(max(max(np.abs(a - b).max() for a, b in zip(poses(loop, qs[k], vs[k])[1], model.rotations(Y[k])))
                          for k in range(len(result.time))))
    assert 3.5 < angles[0] / angles[1] < 4.5 and angles[1] < 1e-6


def test_refusals():
    with pytest.raises(ModelError, match="normal is used only by prismatic and revolute"):
        SpatialCutJoint(name="c", parent=None, child="p", kind="spherical", normal=(1, 0, 0))
    with pytest.raises(ModelError, match="parent_normal must be perpendicular to parent_axis"):
        SpatialCutJoint(name="c", parent=None, child="p", kind="prismatic", parent_normal=(0, 0.1, 1))
    assert SpatialCutJoint(name="c", parent=None, child="p", kind="prismatic").n_rows == 5
