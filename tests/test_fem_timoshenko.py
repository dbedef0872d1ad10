"""Timoshenko beam elements (shear deformation and rotary inertia: ctmm.fem.BeamElement(shear_stiffness=...,
rotary_inertia_per_length=...), ctmm.fem.SpatialBeamElement(shear_stiffness_y/_z=..., bending_rotary_inertia_y/_z=...))
against the analytic Timoshenko frequencies: simply supported in closed form, cantilever from the Timoshenko
equations solved in the test (transfer of the 4-state ODE by a matrix exponential, roots of the 2 x 2 end
determinant); the limit of slender beams (Euler-Bernoulli); the floating-frame terms of hinged subsystems against
the plain finite-element matrices."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.fem import BeamElement, FiniteElementModel, SpatialBeamElement, SpatialFiniteElementModel
from ctmm.planar import PlanarModel, Pinned

# a steel bar, square section 0.1 m x 0.1 m, length 1 m (slenderness L / r = 35: shear matters by a few %)
E, G, RHO, SIDE, LENGTH = 2.1e11, 8.1e10, 7850.0, 0.1, 1.0
AREA, SECOND = SIDE ** 2, SIDE ** 4 / 12
KAPPA = 5.0 / 6.0
EI, KGA, RHO_A, RHO_I = E * SECOND, KAPPA * G * AREA, RHO * AREA, RHO * SECOND


def simply_supported(n, EI=EI, KGA=KGA, RHO_A=RHO_A, RHO_I=RHO_I, L=LENGTH):
    """Lower root of (kGA)^2 k^2 = (EI k^2 + kGA - rhoI w^2)(kGA k^2 - rhoA w^2), k = n pi / L [rad/s]."""
    k = n * np.pi / L
    # rhoI rhoA w^4 - (rhoI kGA k^2 + rhoA (EI k^2 + kGA)) w^2 + EI kGA k^4 = 0
    a, b, c = RHO_I * RHO_A, -(RHO_I * KGA * k * k + RHO_A * (EI * k * k + KGA)), EI * KGA * k ** 4
    if a == 0.0:
        return np.sqrt(-c / b)
    return np.sqrt((-b - np.sqrt(b * b - 4 * a * c)) / (2 * a))


def cantilever(count, EI=EI, KGA=KGA, RHO_A=RHO_A, RHO_I=RHO_I, L=LENGTH):
    """The lowest ``count`` frequencies [rad/s] of the clamped-free Timoshenko beam: y = [v, v', theta, theta'],
    v'' = theta' - rhoA w^2 v / kGA, theta'' = -(kGA (v' - theta) + rhoI w^2 theta) / EI; clamped v = theta = 0,
    free EI theta' = 0 and kGA (v' - theta) = 0 at L."""
    def determinant(w):
        A = np.array([[0, 1, 0, 0], [-RHO_A * w * w / KGA, 0, 0, 1], [0, 0, 0, 1],
                      [0, -KGA / EI, (KGA - RHO_I * w * w) / EI, 0]], float)
        Y = scipy.linalg.expm(A * L)[:, [1, 3]]                         # from v'(0) = 1 and theta'(0) = 1
        ends = np.array([Y[3], Y[1] - Y[2]])
        return np.linalg.det(ends)
    grid = np.linspace(1.0, 2e5, 4000)
    values = [determinant(w) for w in grid]
    roots = [scipy.optimize.brentq(determinant, grid[i], grid[i + 1], xtol=1e-12, rtol=1e-14)
             for i in range(len(grid) - 1) if np.sign(values[i]) != np.sign(values[i + 1])]
    return np.array(roots[:count])


def planar_beam(count, **options):
    nodes = {f"n{k}": (LENGTH * k / count, 0.0) for k in range(count + 1)}
    return FiniteElementModel("bar", nodes, [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", EI, E * AREA, RHO_A, **options)
                                             for k in range(count)])


def bending(fe, held_v, held_all, count):
    """Lowest bending frequencies of a beam along x: DOFs (u_y, r_z), u_y held at ``held_v``, both at ``held_all``."""
    keep = [i for node, dofs in fe.dofs.items() if node not in held_all
            for i in ((dofs[2],) if node in held_v else (dofs[1], dofs[2]))]
    sub = np.ix_(keep, keep)
    return np.sqrt(scipy.linalg.eigh(fe.stiffness[sub], fe.mass[sub], eigvals_only=True,
                                     subset_by_index=[0, count - 1]))


TIMOSHENKO = dict(shear_stiffness=KGA, rotary_inertia_per_length=RHO_I)


def test_simply_supported_frequencies_converge_to_the_closed_form_at_second_order():
    exact = np.array([simply_supported(n) for n in (1, 2, 3, 4)])
    euler = np.array([(n * np.pi / LENGTH) ** 2 * np.sqrt(EI / RHO_A) for n in (1, 2, 3, 4)])
    assert np.all(exact < 0.99 * euler) and exact[3] < 0.85 * euler[3]            # shear and rotary inertia matter
    results = [bending(planar_beam(n, **TIMOSHENKO), {"n0", f"n{n}"}, (), 4) for n in (16, 32)]
    errors = [np.abs(r / exact - 1) for r in results]
    assert np.all(errors[1] < 2e-3) and np.all(errors[1] > 1e-6)
    assert np.all((3.8 < errors[0] / errors[1]) & (errors[0] / errors[1] < 4.3))
    assert np.max(np.abs((results[1] + (results[1] - results[0]) / 3) / exact - 1)) < 5e-5


def test_cantilever_frequencies_match_the_timoshenko_equations_planar_and_spatial():
    """16 and 32 elements: errors below 6e-3 and 1.5e-3, falling by 4 (O(h^2)); their Richardson extrapolation
    within 3e-5 of the roots of the Timoshenko equations."""
    exact = cantilever(4)
    planar = [bending(planar_beam(n, **TIMOSHENKO), (), {"n0"}, 4) for n in (16, 32)]
    other = cantilever(4, EI=EI / 2, KGA=KGA / 3, RHO_I=RHO_I / 2)
    spatial = []                 # two bending planes with different sections (z: half the EI, a third of kappa G A)
    for count in (16, 32):
        nodes = {f"n{k}": (LENGTH * k / count, 0.0, 0.0) for k in range(count + 1)}
        fe = SpatialFiniteElementModel("bar", nodes, [
            SpatialBeamElement(f"e{k}", f"n{k}", f"n{k + 1}", E * AREA, 1e7, EI, EI / 2, RHO_A, 1.0,
                               shear_stiffness_y=KGA, shear_stiffness_z=KGA / 3, bending_rotary_inertia_y=RHO_I,
                               bending_rotary_inertia_z=RHO_I / 2) for k in range(count)])
        planes = []
        for columns in ((1, 5), (2, 4)):                     # (u_y, r_z): deflection along y; (u_z, r_y): along z
            keep = [dofs[c] for node, dofs in fe.dofs.items() if node != "n0" for c in columns]
            sub = np.ix_(keep, keep)
            planes.append(np.sqrt(scipy.linalg.eigh(fe.stiffness[sub], fe.mass[sub], eigvals_only=True,
                                                    subset_by_index=[0, 3])))
        spatial.append(planes)
    for coarse, fine, expected in [(planar[0], planar[1], exact), (spatial[0][0], spatial[1][0], exact),
                                   (spatial[0][1], spatial[1][1], other)]:
        errors = [np.abs(coarse / expected - 1), np.abs(fine / expected - 1)]
        assert np.all(errors[0] < 6e-3) and np.all(errors[1] < 1.5e-3)
        assert np.all((3.6 < errors[0][1:] / errors[1][1:]) & (errors[0][1:] / errors[1][1:] < 4.4))
        assert np.max(np.abs((fine + (fine - coarse) / 3) / expected - 1)) < 3e-5


def test_slender_beams_tend_to_euler_bernoulli():
    """The Timoshenko correction falls like (r / L)^2: frequencies / Euler-Bernoulli -> 1, in the closed form and
    in the elements; shear_stiffness=None with no rotary inertia is the Euler-Bernoulli element itself."""
    gaps = []
    for length in (1.0, 10.0, 100.0):
        nodes = {f"n{k}": (length * k / 8, 0.0) for k in range(9)}
        timoshenko = FiniteElementModel("t", nodes, [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", EI, E * AREA, RHO_A,
                                                                 **TIMOSHENKO) for k in range(8)])
        euler = FiniteElementModel("e", nodes, [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", EI, E * AREA, RHO_A)
                                                for k in range(8)])
        held = {"n0", "n8"}
        ratio = bending(timoshenko, held, (), 2) / bending(euler, held, (), 2)
        closed = simply_supported(1, L=length) / simply_supported(1, KGA=1e30, RHO_I=0.0, L=length)
        assert ratio[0] == pytest.approx(closed, rel=2e-3)
        gaps.append(1 - ratio[0])
    assert gaps[0] > 0.01 and 80 < gaps[0] / gaps[1] < 120 and 80 < gaps[1] / gaps[2] < 120
    euler = planar_beam(3)
    explicit = planar_beam(3, shear_stiffness=None, rotary_inertia_per_length=0.0)
    assert np.array_equal(euler.stiffness, explicit.stiffness) and np.array_equal(euler.mass, explicit.mass)
    huge = planar_beam(3, shear_stiffness=KGA * 1e8)
    assert np.allclose(huge.stiffness, euler.stiffness, rtol=1e-6, atol=1e-6 * np.max(np.abs(euler.stiffness)))


def test_hinged_subsystems_have_the_frequencies_of_the_finite_element_matrices():
    """A Timoshenko beam with rotary inertia on a hinge (no gravity), as a subsystem of a planar and of a spatial
    model: the linearised floating-frame model (polar moment, couplings of the section rotations) = eigh of the
    element matrices with the hinge node's translations held."""
    fe = planar_beam(6, **TIMOSHENKO)
    model = PlanarModel.chain("hinged", [Pinned("base"), fe.subsystem("bar", ("n0", "n6"))], gravity=(0.0, 0.0))
    omega = ctmm.natural_frequencies(model, n_modes=6)
    keep = [i for node, dofs in fe.dofs.items() for i in (dofs[2:] if node == "n0" else dofs)]
    expected = np.sqrt(np.clip(scipy.linalg.eigh(fe.stiffness[np.ix_(keep, keep)], fe.mass[np.ix_(keep, keep)],
                                                 eigvals_only=True)[:6], 0.0, None))
    assert omega[0] == 0.0 and expected[0] < 1e-3
    assert np.max(np.abs(omega[1:] / expected[1:] - 1)) < 1e-8
    count = 4
    nodes = {f"n{k}": (0.0, LENGTH * k / count, 0.0) for k in range(count + 1)}          # along y
    space = SpatialFiniteElementModel("bar", nodes, [
        SpatialBeamElement(f"e{k}", f"n{k}", f"n{k + 1}", E * AREA, 3e5, EI, EI / 2, RHO_A, RHO_I / 5,
                           shear_stiffness_y=KGA, shear_stiffness_z=KGA / 3, bending_rotary_inertia_y=RHO_I,
                           bending_rotary_inertia_z=RHO_I / 2) for k in range(count)])
    model = sp.SpatialModel("hinged", [space.subsystem("bar", ("n0", f"n{count}")),
                                       sp.Revolute(name="hinge", parent=None, child="bar", axis=(1, 0, 0))],
                            gravity=(0.0, 0.0, 0.0))
    omega = ctmm.natural_frequencies(model, n_modes=6)
    held = set(space.dofs["n0"]) - {space.dofs["n0"][3]}                       # r_x (the hinge) stays free
    keep = [i for i in range(space.n_dofs) if i not in held]
    expected = np.sqrt(np.clip(scipy.linalg.eigh(space.stiffness[np.ix_(keep, keep)],
                                                 space.mass[np.ix_(keep, keep)], eigvals_only=True)[:6], 0.0, None))
    assert omega[0] == 0.0 and expected[0] < 1e-3
    assert np.max(np.abs(omega[1:] / expected[1:] - 1)) < 1e-8


@pytest.mark.parametrize("build, message", [
    (lambda: BeamElement("e", "a", "b", 1.0, 1.0, 1.0, shear_stiffness=0.0), "shear_stiffness"),
    (lambda: BeamElement("e", "a", "b", 1.0, 1.0, 1.0, rotary_inertia_per_length=-1.0), "rotary_inertia_per_length"),
    (lambda: SpatialBeamElement("e", "a", "b", 1.0, 1.0, 1.0, 1.0, 1.0, shear_stiffness_z=-2.0), "shear_stiffness_z"),
    (lambda: SpatialBeamElement("e", "a", "b", 1.0, 1.0, 1.0, 1.0, 1.0, bending_rotary_inertia_y=float("nan")),
     "bending_rotary_inertia_y"),
])
def test_bad_timoshenko_options_are_refused_by_name(build, message):
    with pytest.raises(ModelError, match=message):
        build()


def test_timoshenko_frame_in_a_spatial_chain_matches_the_global_model():
    """Yaw link - an L-frame of Timoshenko elements with section rotary inertia (pitch joint) - link on a hinge at its
    corner node, against ctmm/reference/spatial_fe_global.py (own Timoshenko interpolation): accelerations and energy
    at moving, deformed states (the rotary terms of the sections are gyroscopic); natural frequencies."""
    from ctmm.reference.spatial_fe_global import FEFrame, FrameBeam, Link, SpatialFEChain

    nodes = {"n0": (0.0, 0.0, 0.0), "n1": (0.3, 0.0, 0.0), "n2": (0.6, 0.0, 0.0), "n3": (0.6, 0.25, 0.0)}
    beams = [("e0", "n0", "n1", (0.0, 1.0, 0.0)), ("e1", "n1", "n2", (0.0, 0.0, 1.0)), ("e2", "n2", "n3", (0.3, 0, 1))]
    section = dict(EA=4e4, GJ=40.0, EIy=60.0, EIz=90.0, rhoA=1.1, rhoIp=4e-3)
    shear = dict(kGAy=9e3, kGAz=6e3, rhoIy=2e-3, rhoIz=3e-3)
    I1, I2 = np.diag([0.01, 0.02, 0.015]), np.diag([0.004, 0.003, 0.002])
    elements = [SpatialBeamElement(name, a, b, section["EA"], section["GJ"], section["EIy"], section["EIz"],
                                   section["rhoA"], section["rhoIp"], orientation=o, shear_stiffness_y=shear["kGAy"],
                                   shear_stiffness_z=shear["kGAz"], bending_rotary_inertia_y=shear["rhoIy"],
                                   bending_rotary_inertia_z=shear["rhoIz"]) for name, a, b, o in beams]
    fe = SpatialFiniteElementModel("fe", nodes, elements)

    def build(gravity):
        model = sp.SpatialModel("timoshenko_chain", [
            sp.SpatialBody("link1", 1.2, I1, center_of_mass=(0.1, 0.0, 0.15), points={"tip": (0.2, 0.0, 0.3)}),
            sp.Revolute(name="yaw", parent=None, child="link1", axis=(0, 0, 1)),
            fe.subsystem("frame", boundary=("n0", "n3")),
            sp.Revolute(name="pitch", parent="link1", point="tip", child="frame", axis=(0, 1, 0), stiffness=30.0),
            sp.SpatialBody("link2", 0.5, I2, center_of_mass=(0.0, 0.05, -0.1)),
            sp.Revolute(name="hinge", parent="frame", point="n3", child="link2", axis=(1, 0, 0), stiffness=2.0)],
            gravity=(0.0, 0.0, -gravity))
        reference = SpatialFEChain([
            Link(1.2, I1, (0.1, 0.0, 0.15), (0, 0, 1), (0, 0, 0)),
            FEFrame(nodes, "n0", [FrameBeam(a, b, *section.values(), o, **shear) for _, a, b, o in beams],
                    axis=(0, 1, 0), point=(0.2, 0.0, 0.3)),
            Link(0.5, I2, (0.0, 0.05, -0.1), (1, 0, 0), "n3")], gravity=(0.0, 0.0, -gravity),
            joint_springs={1: (30.0, 0.0), 2: (2.0, 0.0)})
        return model, reference
    model, reference = build(9.81)
    rng = np.random.default_rng(11)
    for _ in range(3):
        q = rng.normal(size=model.n_positions) * 0.8
        q[3:] *= 0.02
        v = rng.normal(size=model.n_velocities)
        a, a_ref = sp.accelerations(model, q, v), reference.accelerations(q, v)
        assert np.max(np.abs(a - a_ref)) < 1e-10 * np.max(np.abs(a_ref))
        assert sp.energy(model, q, v) == pytest.approx(reference.energy(q, v), rel=1e-11)
    model, reference = build(0.0)                            # no gravity: the neutral configuration is at rest
    rest = (np.zeros(model.n_positions), np.zeros(model.n_velocities))
    omega = ctmm.natural_frequencies(model, n_modes=6, operating_point=rest)
    expected = reference.natural_frequencies(rest[0])[:6]
    assert omega[0] == 0.0 and expected[0] < 1e-6
    assert np.max(np.abs(omega[1:] / expected[1:] - 1)) < 1e-8
