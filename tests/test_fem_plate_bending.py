"""Rectangular plate elements (ctmm.fem.SpatialPlateElement, ACM bending + membrane) against analytic plate
frequencies (Navier, simply supported), Leissa's cantilever values with mesh convergence, and a plate with a beam
coupled to a spatial transfer chain against the global model of ctmm/reference/spatial_fe_global.py (own element
code).  The chain's plate is realistic, 4 mm aluminium (omega_max 1.3e5 rad/s): the resolvent and zero-mode rules
scale rows and columns, so stiff plates are answered (tests/test_resolvent_scaling.py)."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.fem import (SpatialBeamElement, SpatialFiniteElementModel, SpatialPlateElement, SpatialPointMass)
from ctmm.reference.spatial_fe_global import FEFrame, FrameBeam, FrameMass, FramePlate, Link, SpatialFEChain

STEEL = dict(youngs_modulus=2e11, poisson_ratio=0.3, density=7850.0)


def plate_mesh(nx, ny, a, b, h, **material):
    """A flat ``a x b`` plate in the x-y plane, ``nx x ny`` elements; nodes ``"i_j"``."""
    nodes = {f"{i}_{j}": (a * i / nx, b * j / ny, 0.0) for i in range(nx + 1) for j in range(ny + 1)}
    elements = [SpatialPlateElement(f"p{i}_{j}", (f"{i}_{j}", f"{i + 1}_{j}", f"{i + 1}_{j + 1}", f"{i}_{j + 1}"), h,
                                    **(material or STEEL)) for i in range(nx) for j in range(ny)]
    return SpatialFiniteElementModel("plate", nodes, elements)


def bending_frequencies(fe, held_w, held_all, count):
    """Lowest bending frequencies [rad/s] of a flat x-y plate: the (u_z, r_x, r_y) DOFs (uncoupled from the
    in-plane ones), ``u_z`` held at ``held_w`` nodes, all three at ``held_all``."""
    keep = []
    for node, dofs in fe.dofs.items():
        if node in held_all:
            continue
        keep += ([] if node in held_w else [dofs[2]]) + [dofs[3], dofs[4]]
    sub = np.ix_(keep, keep)
    values = scipy.linalg.eigh(fe.stiffness[sub], fe.mass[sub], eigvals_only=True, subset_by_index=[0, count - 1])
    return np.sqrt(values)


def test_simply_supported_plate_converges_to_navier_at_second_order():
    """omega_mn = pi^2 (m^2/a^2 + n^2/b^2) sqrt(D / (rho h)); errors fall by 4 per halving (O(h^2)) and the
    Richardson extrapolation of the two meshes (12 x 8, 24 x 16) is within 5e-4 (the meshes alone: 2 % and 0.5 %)."""
    a, b, h = 1.2, 0.8, 0.01
    D = 2e11 * h ** 3 / (12 * (1 - 0.09))
    navier = np.sort([np.pi ** 2 * (m * m / a ** 2 + n * n / b ** 2) * np.sqrt(D / (7850.0 * h))
                      for m in range(1, 5) for n in range(1, 5)])[:5]
    results = []
    for n in (8, 16):
        fe = plate_mesh(3 * n // 2, n, a, b, h)
        edge = {k for k, p in fe.positions.items() if min(p[0], a - p[0], p[1], b - p[1]) < 1e-12}
        results.append(bending_frequencies(fe, edge, (), 5))
    errors = [np.abs(r / navier - 1) for r in results]
    assert np.all(errors[0] < 0.02) and np.all(errors[1] < 0.0055) and np.all(errors[0] > 0.004)
    assert np.all((3.6 < errors[0] / errors[1]) & (errors[0] / errors[1] < 4.4))
    extrapolated = results[1] + (results[1] - results[0]) / 3
    assert np.max(np.abs(extrapolated / navier - 1)) < 5e-4


def test_cantilever_square_plate_against_leissa():
    """lambda = omega a^2 sqrt(rho h / D) of a square plate clamped on one edge, nu = 0.3: Leissa (J. Sound Vib.
    31, 1973, Table 12: 36-term Ritz, upper bounds of the exact values) 3.4917, 8.5246, 21.429, 27.331, 31.111.
    The meshes converge at O(h^2) (differences fall by about 4) to values below those bounds, within 0.8 %."""
    leissa = np.array([3.4917, 8.5246, 21.429, 27.331, 31.111])
    a, h = 1.0, 0.01
    D = 2e11 * h ** 3 / (12 * (1 - 0.09))
    lam = []
    for n in (4, 8, 16):
        fe = plate_mesh(n, n, a, a, h)
        lam.append(bending_frequencies(fe, (), {f"0_{j}" for j in range(n + 1)}, 5) * a * a * np.sqrt(7850.0 * h / D))
    steps = [np.abs(lam[1] - lam[0]), np.abs(lam[2] - lam[1])]
    assert np.all(steps[1] < steps[0] / 2.5)
    converged = lam[2] + (lam[2] - lam[1]) / 3                       # Richardson, O(h^2)
    assert np.all(converged < leissa) and np.all(np.abs(converged / leissa - 1) < 8e-3)
    assert np.all(np.abs(lam[2] / leissa - 1) < 8e-3)


def test_plate_bending_is_uncoupled_and_drilling_modes_are_high():
    """The lowest frequencies of the whole 6-DOF model of a flat cantilever are its bending ones (no spurious
    low membrane or drilling modes), and the rigid motions of a free plate carry no strain energy."""
    fe = plate_mesh(4, 4, 1.0, 1.0, 0.01)
    clamped = [f"0_{j}" for j in range(5)]
    assert fe.natural_frequencies(clamped)[:8] == pytest.approx(
        bending_frequencies(fe, (), set(clamped), 8), rel=1e-9)
    rigid = []
    for k in range(6):
        u = np.zeros(fe.n_dofs)
        for node, dofs in fe.dofs.items():
            twist = np.cross(np.eye(3)[k - 3], fe.positions[node]) if k >= 3 else np.eye(3)[k]
            u[list(dofs[:3])] = twist
            if k >= 3:
                u[list(dofs[3:])] = np.eye(3)[k - 3]
        rigid.append(u @ fe.stiffness @ u)
    assert max(rigid) < 1e-9 * np.max(np.abs(fe.stiffness))
    assert fe.floating_inertia("0_0").mass == pytest.approx(7850.0 * 0.01, rel=1e-12)


def test_oblique_plate_has_the_frequencies_of_the_flat_one():
    """The same cantilever turned into an oblique plane (local axes from the corners): same frequencies."""
    flat = plate_mesh(2, 2, 0.6, 0.4, 0.004)
    rotation = scipy.linalg.expm(np.cross(np.eye(3), np.array([0.3, -0.5, 0.8])))
    nodes = {k: tuple(rotation @ p) for k, p in flat.positions.items()}
    turned = SpatialFiniteElementModel("turned", nodes, list(flat.elements))
    clamped = ["0_0", "0_1", "0_2"]
    assert turned.natural_frequencies(clamped) == pytest.approx(flat.natural_frequencies(clamped), rel=1e-9)


def test_refusals_name_the_problem():
    with pytest.raises(ModelError, match="rectangle"):
        SpatialFiniteElementModel("bad", {"a": (0, 0, 0), "b": (1, 0, 0), "c": (1.2, 1, 0), "d": (0, 1, 0)},
                                  [SpatialPlateElement("p", ("a", "b", "c", "d"), 0.01, **STEEL)])
    with pytest.raises(ModelError, match="poisson_ratio"):
        SpatialPlateElement("p", ("a", "b", "c", "d"), 0.01, 2e11, 0.5, 7850.0)
    with pytest.raises(ModelError, match="density"):
        SpatialPlateElement("p", ("a", "b", "c", "d"), 0.01, 2e11, 0.3, 0.0)
    with pytest.raises(ModelError, match="4 distinct node names"):
        SpatialPlateElement("p", ("a", "b", "c", "c"), 0.01, **STEEL)
    with pytest.raises(ModelError, match="thickness"):
        SpatialPlateElement("p", ("a", "b", "c", "d"), -0.01, **STEEL)


# ---------------------------------------------------------------- a plate with a beam in a spatial chain
EY = np.array([0.0, np.cos(0.4), np.sin(0.4)])
NODES = {f"{i}_{j}": tuple(np.array([0.2 * i, 0.0, 0.0]) + 0.15 * j * EY) for i in range(3) for j in range(2)}
NODES["tip"] = (0.55, 0.0, 0.0)
PLATE = dict(h=0.004, E=7e10, nu=0.33, rho=2700.0)         # 4 mm aluminium
BEAM = (3e4, 12.0, 20.0, 35.0, 0.4, 1e-3)
I1, I2 = np.diag([0.01, 0.02, 0.015]), np.diag([0.004, 0.003, 0.002])


def chain(*, child=True, damping=0.0, gravity=9.81):
    """link1 on a yaw joint; the plate (2 x 1 elements, oblique plane) with a beam from its corner 2_0 to a tip
    mass on a pitch joint (spring) at link1's tip; link2 on a hinge (spring) at the plate corner 2_1.  The joint
    springs keep the lowest elastic mode well above the round-off of the stiff plate's omega^2 (a mode within
    100x of that round-off is refused by ctmm.natural_frequencies, tests/test_zero_modes.py)."""
    quads = [(f"{i}_0", f"{i + 1}_0", f"{i + 1}_1", f"{i}_1") for i in range(2)]
    elements = [SpatialPlateElement(f"p{i}", q, PLATE["h"], PLATE["E"], PLATE["nu"], PLATE["rho"])
                for i, q in enumerate(quads)]
    elements += [SpatialBeamElement("beam", "2_0", "tip", *BEAM, orientation=(0, 0, 1)),
                 SpatialPointMass("mass", "tip", 0.05, (1e-4, 2e-4, 1e-4))]
    fe = SpatialFiniteElementModel("fe", NODES, elements, rayleigh=(0.0, damping))
    parts = [sp.SpatialBody("link1", 1.2, I1, center_of_mass=(0.1, 0.0, 0.15), points={"tip": (0.2, 0.0, 0.3)}),
             sp.Revolute(name="yaw", parent=None, child="link1", axis=(0, 0, 1), actuated=True),
             fe.subsystem("panel", boundary=("0_0", "2_1")),
             sp.Revolute(name="pitch", parent="link1", point="tip", child="panel", axis=(0, 1, 0), stiffness=200.0)]
    segments = [Link(1.2, I1, (0.1, 0.0, 0.15), (0, 0, 1), (0, 0, 0)),
                FEFrame(NODES, "0_0", [FrameBeam("2_0", "tip", *BEAM, (0, 0, 1))],
                        [FrameMass("tip", 0.05, np.diag([1e-4, 2e-4, 1e-4]))], axis=(0, 1, 0), point=(0.2, 0.0, 0.3),
                        stiffness_damping=damping, plates=[FramePlate(q, **PLATE) for q in quads])]
    if child:
        parts += [sp.SpatialBody("link2", 0.3, I2, center_of_mass=(0.0, 0.05, -0.1)),
                  sp.Revolute(name="hinge", parent="panel", point="2_1", child="link2", axis=(1, 0, 0), stiffness=5.0)]
        segments.append(Link(0.3, I2, (0.0, 0.05, -0.1), (1, 0, 0), "2_1"))
    model = sp.SpatialModel("plate_chain", parts, gravity=(0.0, 0.0, -gravity))
    springs = {1: (200.0, 0.0), 2: (5.0, 0.0)} if child else {1: (200.0, 0.0)}
    return model, SpatialFEChain(segments, gravity=(0.0, 0.0, -gravity), joint_springs=springs)


def test_accelerations_and_energy_match_the_global_model():
    model, reference = chain(damping=1e-4)
    assert reference.n == model.n_positions
    rng = np.random.default_rng(7)
    for _ in range(3):
        q = rng.normal(size=model.n_positions) * 0.8
        q[3:] *= 2e-3
        v = rng.normal(size=model.n_velocities)
        a, a_ref = sp.accelerations(model, q, v), reference.accelerations(q, v)
        assert np.max(np.abs(a - a_ref)) < 1e-9 * np.max(np.abs(a_ref))
        assert sp.energy(model, q, v) == pytest.approx(reference.energy(q, v), rel=1e-11)


def test_natural_frequencies_and_frequency_response_match_the_global_linearisation():
    model, reference = chain(gravity=0.0)
    rest = (np.zeros(model.n_positions), np.zeros(model.n_velocities))   # no gravity: the neutral equilibrium
    omega = ctmm.natural_frequencies(model, n_modes=8, operating_point=rest)
    expected = reference.natural_frequencies(rest[0])[:8]
    assert omega[0] == 0.0 and expected[0] < 1e-6                      # the free yaw
    assert np.max(np.abs(omega[1:] - expected[1:]) / expected[1:]) < 1e-8
    model, reference = chain(damping=2e-5, gravity=0.0)
    w = np.array([20.0, 60.0, 150.0])
    response = ctmm.frequency_response(model, w, input="yaw.torque", output="panel.2_1_uz", operating_point=rest)
    values = np.asarray(response.response)[0, 0]
    expected = reference.frequency_response(rest[0], w, load=0, output=model.coordinates.index("panel.2_1_uz"))
    assert np.max(np.abs(values - expected) / np.abs(expected)) < 1e-7


@pytest.mark.parametrize("compiled", [False, True])
def test_simulation_matches_the_global_model(compiled):
    model, reference = chain(child=False)
    q0 = np.zeros(model.n_positions)
    q0[model.coordinates.index("panel.2_1_uz")] = 1e-4
    v0 = np.zeros(model.n_velocities)
    v0[0] = 0.5
    dt, steps = 2e-5, 10               # omega_max dt = 2.6 (plate: 1.29e5 rad/s), inside RK4's 2.83 on the imaginary axis
    result = ctmm.simulate(model, dt * steps, dt, method="rk4", x0=q0, v0=v0, compiled=compiled)
    _, states = reference.rk4(q0, v0, dt * steps, dt)
    final = np.array([result[name][-1] for name in model.coordinates])
    moved = np.max(np.abs(states[-1, :model.n_positions] - q0))
    assert moved > 1e-5 and np.max(np.abs(final - states[-1, :model.n_positions])) < 1e-9 * moved


def test_scene_file_builds_the_same_plate_subsystem(tmp_path):
    """``type = "SpatialFiniteElementSubsystem"`` with plate, beam and point-mass value tables = the Python model."""
    text = '''
[system]
kind = "spatial"
name = "panel_scene"
gravity = [0.0, 0.0, 0.0]

[[system.elements]]
type = "SpatialFiniteElementSubsystem"
name = "panel"
nodes = { a = [0.0, 0.0, 0.0], b = [0.3, 0.0, 0.0], c = [0.3, 0.2, 0.0], d = [0.0, 0.2, 0.0], tip = [0.5, 0.0, 0.0] }
elements = [{ type = "SpatialPlateElement", name = "p", nodes = ["a", "b", "c", "d"], thickness = 0.003, youngs_modulus = 7e10, poisson_ratio = 0.33, density = 2700.0 },
            { type = "SpatialBeamElement", name = "e", start = "b", end = "tip", axial_stiffness = 3e4, torsional_stiffness = 12.0, bending_stiffness_y = 20.0, bending_stiffness_z = 35.0, mass_per_length = 0.4, orientation = [0.0, 0.0, 1.0] },
            { type = "SpatialPointMass", name = "m", node = "tip", mass = 0.05, inertia = [1e-4, 2e-4, 1e-4] }]
boundary = ["a", "tip"]

[[system.elements]]
type = "Weld"
name = "clamp"
child = "panel"

[study]
verb = "natural_frequencies"
n_modes = 6
'''
    path = tmp_path / "panel.toml"
    path.write_text(text)
    scene = ctmm.scene_files.load_scene(path)
    nodes = {"a": (0.0, 0.0, 0.0), "b": (0.3, 0.0, 0.0), "c": (0.3, 0.2, 0.0), "d": (0.0, 0.2, 0.0), "tip": (0.5, 0, 0)}
    fe = SpatialFiniteElementModel("panel", nodes, [
        SpatialPlateElement("p", ("a", "b", "c", "d"), 0.003, 7e10, 0.33, 2700.0),
        SpatialBeamElement("e", "b", "tip", 3e4, 12.0, 20.0, 35.0, 0.4, orientation=(0, 0, 1)),
        SpatialPointMass("m", "tip", 0.05, (1e-4, 2e-4, 1e-4))])
    model = sp.SpatialModel("panel_python", [fe.subsystem("panel", ("a", "tip")),
                                             sp.Weld(name="clamp", parent=None, child="panel")], gravity=(0, 0, 0))
    expected = ctmm.natural_frequencies(model, n_modes=6)
    assert np.asarray(scene.run()) == pytest.approx(expected, rel=1e-12)
    assert expected[0] > 1.0
