"""Triangular plate element ctmm.fem.SpatialTrianglePlateElement (DKT bending + constant-strain membrane):
constant-curvature patch test on an irregular mesh, Navier's simply supported frequencies and Leissa's clamped
square with mesh convergence at O(h^2) (also on an irregular mesh), exact lamina inertia integrals, and an
irregular triangle-meshed plate coupled to a spatial chain against the rigid-body chain of the same lamina
(analytic mass, centre and inertia), plus refusals."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.errors import ModelError
from ctmm.fem import SpatialFiniteElementModel, SpatialThickPlateElement, SpatialTrianglePlateElement
from tests.plate_helpers import (STEEL, bending_frequencies, bending_patch_error, bending_stiffness,
                                 hinged_frequencies, navier_frequencies, plate_model, rigid_motion_energies)


def test_constant_curvature_patch_test_on_an_irregular_mesh():
    """w quadratic imposed (value and slopes) on the edge nodes of an irregular 3 x 3 triangle patch: the interior
    takes the exact values and the energy is kappa^T D_b kappa A / 2 (DKT represents constant curvature)."""
    fe = plate_model(3, 1.0, 0.8, 0.01, triangles=True, distortion=0.8)
    edge = {k for k, p in fe.positions.items() if min(p[0], 1.0 - p[0], p[1], 0.8 - p[1]) < 1e-12}
    kappa = np.array([0.3, -0.2, 0.5])
    error, energy = bending_patch_error(fe, tuple(kappa), edge)
    nu = STEEL["poisson_ratio"]
    Db = bending_stiffness(0.01) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    assert error < 1e-10 and energy == pytest.approx(kappa @ Db @ kappa / 2 * 0.8, rel=1e-10)


@pytest.mark.parametrize("distortion", [0.0, 0.5])
def test_simply_supported_square_converges_to_navier(distortion):
    """Four lowest frequencies of a simply supported 1 m square, 1 cm steel (Kirchhoff: w and the slope along
    the edge held): the 12 x 12 mesh (288 triangles) is below and within 1.2 %, errors fall by 2.8 to 4.5 per
    halving (O(h^2), still pre-asymptotic on 6 x 6), on the regular mesh and on an irregular one (interior nodes
    moved by up to a quarter cell)."""
    exact = navier_frequencies(1.0, 1.0, 0.01, 4)
    coarse, fine = (bending_frequencies(plate_model(n, 1.0, 1.0, 0.01, triangles=True, distortion=distortion),
                                        1.0, 1.0, 4, "simply supported") / exact - 1 for n in (6, 12))
    assert np.all((fine < 0) & (fine > -0.012))
    assert np.all((2.8 < coarse / fine) & (coarse / fine < 4.5))


def test_clamped_square_against_leissa():
    """lambda = omega a^2 sqrt(rho h / D) of the clamped square, nu = 0.3: 35.985 (Leissa 1969, NASA SP-160,
    35.99); the meshes converge at O(h^2) (error ratio 3.3 to 4.2 from 8 x 8 to 16 x 16, above 2 from 4 x 4) and the
    Richardson extrapolation is within 1e-3."""
    scale = np.sqrt(STEEL["density"] * 0.01 / bending_stiffness(0.01))
    lam = [bending_frequencies(plate_model(n, 1.0, 1.0, 0.01, triangles=True), 1.0, 1.0, 1, "clamped")[0] * scale
           for n in (4, 8, 16)]
    errors = np.array(lam) / 35.985 - 1
    assert np.all(errors < 0) and abs(errors[2]) < 0.005
    assert 2.0 < errors[0] / errors[1] and 3.3 < errors[1] / errors[2] < 4.2
    assert abs((lam[2] + (lam[2] - lam[1]) / 3) / 35.985 - 1) < 1e-3


def test_rigid_motions_and_exact_lamina_inertia():
    """A free irregular pentagon of five triangles in an oblique plane: no strain energy in the rigid motions;
    mass, first and second moments equal the lamina's (int x x^T dA = A/12 (sum p p^T + s s^T) per triangle,
    s the sum of its corners)."""
    rotation = np.linalg.qr(np.array([[0.3, -0.5, 0.8], [0.9, 0.2, -0.1], [0.1, 0.7, 0.4]]))[0]
    flat = {"c": (0.1, 0.12), "p0": (0.0, 0.0), "p1": (0.35, 0.02), "p2": (0.4, 0.25), "p3": (0.15, 0.4),
            "p4": (-0.1, 0.2)}
    nodes = {k: tuple(rotation @ np.array([x, y, 0.0])) for k, (x, y) in flat.items()}
    h = 0.004
    elements = [SpatialTrianglePlateElement(f"t{k}", ("c", f"p{k}", f"p{(k + 1) % 5}"), h, **STEEL) for k in range(5)]
    fe = SpatialFiniteElementModel("pentagon", nodes, elements)
    assert max(rigid_motion_energies(fe)) < 1e-10 * np.max(np.abs(fe.stiffness))
    inertia = fe.floating_inertia("p0")
    mass, first, second = 0.0, np.zeros(3), np.zeros((3, 3))
    for k in range(5):
        p = np.array([nodes[n] for n in ("c", f"p{k}", f"p{(k + 1) % 5}")]) - np.array(nodes["p0"])
        area = 0.5 * np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
        rho_h = STEEL["density"] * h
        mass += rho_h * area
        first += rho_h * area * p.mean(axis=0)
        second += rho_h * area / 12 * (p.T @ p + np.outer(p.sum(axis=0), p.sum(axis=0)))
    assert inertia.mass == pytest.approx(mass, rel=1e-12)
    assert np.allclose(inertia.first_moment, first, rtol=0, atol=1e-12 * mass)
    assert np.allclose(inertia.second_moment, second, rtol=0, atol=1e-12 * mass)


def _gusset(h: float, youngs_modulus: float) -> SpatialFiniteElementModel:
    """An irregular steel gusset in the x-z plane (normal -y), eight triangles around an interior node."""
    nodes = {f"o{k}": (x, 0.0, z) for k, (x, z) in enumerate(GUSSET)} | {"m": (0.17, 0.0, 0.14)}
    material = STEEL | {"youngs_modulus": youngs_modulus}
    elements = [SpatialTrianglePlateElement(f"t{k}", ("m", f"o{k}", f"o{(k + 1) % 8}"), h, **material)
                for k in range(8)]
    return SpatialFiniteElementModel("gusset", nodes, elements)


GUSSET = [(0.0, 0.0), (0.2, -0.02), (0.42, 0.03), (0.38, 0.2), (0.25, 0.33), (0.05, 0.3), (-0.06, 0.15), (-0.02, 0.06)]


def _hanging(plate):
    """The gusset (or its rigid stand-in) on a spring hinge (axis x) at o0, a body on a spring hinge (axis z) at o3."""
    return sp.SpatialModel("hanging", [
        plate, sp.Revolute(name="hinge", parent=None, child="gusset", axis=(1, 0, 0), stiffness=20.0),
        sp.SpatialBody("load", 0.8, np.diag([2e-3, 3e-3, 1e-3]), center_of_mass=(0.05, 0.0, 0.1)),
        sp.Revolute(name="wrist", parent="gusset", point="o3", child="load", axis=(0, 0, 1), stiffness=4.0)],
        gravity=(0.0, 0.0, 0.0))


def test_triangle_plate_in_a_chain_tends_to_the_rigid_lamina_chain():
    """The gusset in a spatial chain, no gravity: its two joint modes tend to those of the same chain with the
    gusset replaced by a rigid body of the lamina's analytic mass, centre and inertia as the plate stiffens (the
    difference falls as 1/E: by 10 from E to 10 E, to below 1e-4; a stiffer plate spreads the stiffness over too
    many decades and is refused by ctmm.natural_frequencies); clamped by a weld, the chain's modes are the FE
    model's with its inboard node held."""
    h, rho = 0.02, STEEL["density"]
    p = np.array([(x, 0.0, z) for x, z in GUSSET])
    mass, first, second = 0.0, np.zeros(3), np.zeros((3, 3))
    for k in range(8):
        t = np.array([(0.17, 0.0, 0.14), p[k], p[(k + 1) % 8]])
        area = 0.5 * np.linalg.norm(np.cross(t[1] - t[0], t[2] - t[0]))
        mass += rho * h * area
        first += rho * h * area * t.mean(axis=0)
        second += rho * h * area / 12 * (t.T @ t + np.outer(t.sum(axis=0), t.sum(axis=0)))
    com = first / mass
    about_com = second - mass * np.outer(com, com)
    rigid = _hanging(sp.SpatialBody("gusset", mass, np.trace(about_com) * np.eye(3) - about_com,
                                    center_of_mass=tuple(com), points={"o3": tuple(p[3])}))
    expected = ctmm.natural_frequencies(rigid, n_modes=2)
    differences = []
    for E in (2e11, 2e12):
        omega = ctmm.natural_frequencies(_hanging(_gusset(h, E).subsystem("gusset", boundary=("o0", "o3"))), n_modes=3)
        assert omega[2] > 15 * expected[1]
        differences.append(np.abs(omega[:2] / expected - 1))
    assert np.all(differences[1] < 1e-4) and np.all((9 < differences[0] / differences[1])
                                                    & (differences[0] / differences[1] < 11))
    fe = _gusset(0.005, 2e11)
    clamped = sp.SpatialModel("clamped", [fe.subsystem("gusset", boundary=("o0",)),
                                          sp.Weld(name="clamp", parent=None, child="gusset")], gravity=(0, 0, 0))
    assert ctmm.natural_frequencies(clamped, n_modes=6) == pytest.approx(fe.natural_frequencies(["o0"])[:6], rel=1e-8)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_hinged_subsystem_frequencies_equal_the_pinned_finite_element_model(axis):
    """An irregular plate (2 x 2 cells) as a subsystem on a free hinge about x, y or z (no gravity): the elastic
    modes of the floating-frame model = eigh of the assembled matrices with the hinge node pinned.  This checks
    the rotary couplings (J_r, R_c) of the drilling inertia (about the normal; in-plane axes: no rotary
    inertia, Kirchhoff): without R_c the frequencies are off by 15-40 %."""
    fe = plate_model(2, 0.4, 0.3, 0.03, triangles=True, distortion=0.5)
    chain, pinned = hinged_frequencies(fe, "0_0", axis, 6)
    assert chain == pytest.approx(pinned, rel=1e-9)


def test_refusals_name_the_problem():
    element = SpatialTrianglePlateElement("t", ("a", "b", "c"), 0.01, **STEEL)
    with pytest.raises(ModelError, match="thickness"):
        SpatialTrianglePlateElement("t", ("a", "b", "c"), -1.0, **STEEL)
    with pytest.raises(ModelError, match="3 distinct"):
        SpatialTrianglePlateElement("t", ("a", "b", "b"), 0.01, **STEEL)
    with pytest.raises(ModelError, match="drilling_stiffness_ratio"):
        SpatialTrianglePlateElement("t", ("a", "b", "c"), 0.01, **STEEL, drilling_stiffness_ratio=0.0)
    with pytest.raises(ModelError, match="no area"):
        SpatialFiniteElementModel("bad", {"a": (0, 0, 0), "b": (1, 0, 0), "c": (2, 0, 0)}, [element])
    with pytest.raises(ModelError, match="no area"):
        SpatialFiniteElementModel("bad", {"a": (0, 0, 0), "b": (1, 0, 0), "c": (0, 0, 0)}, [element])


def test_scene_file_builds_thick_and_triangular_plates(tmp_path):
    """``type = "SpatialFiniteElementSubsystem"`` with a thick quadrilateral and a triangle = the Python model."""
    path = tmp_path / "panel.toml"
    path.write_text('''
[system]
kind = "spatial"
name = "panel_scene"
gravity = [0.0, 0.0, 0.0]

[[system.elements]]
type = "SpatialFiniteElementSubsystem"
name = "panel"
nodes = { a = [0.0, 0.0, 0.0], b = [0.3, 0.0, 0.0], c = [0.35, 0.2, 0.0], d = [0.0, 0.2, 0.0], e = [0.5, 0.1, 0.0] }
elements = [{ type = "SpatialThickPlateElement", name = "q", nodes = ["a", "b", "c", "d"], thickness = 0.02, youngs_modulus = 7e10, poisson_ratio = 0.33, density = 2700.0, shear_correction = 0.8 },
            { type = "SpatialTrianglePlateElement", name = "t", nodes = ["b", "e", "c"], thickness = 0.003, youngs_modulus = 7e10, poisson_ratio = 0.33, density = 2700.0 }]
boundary = ["a"]

[[system.elements]]
type = "Weld"
name = "clamp"
child = "panel"

[study]
verb = "natural_frequencies"
n_modes = 6
''')
    scene = ctmm.scene_files.load_scene(path)
    nodes = {"a": (0.0, 0.0, 0.0), "b": (0.3, 0.0, 0.0), "c": (0.35, 0.2, 0.0), "d": (0.0, 0.2, 0.0), "e": (0.5, 0.1, 0)}
    material = dict(youngs_modulus=7e10, poisson_ratio=0.33, density=2700.0)
    fe = SpatialFiniteElementModel("panel", nodes, [
        SpatialThickPlateElement("q", ("a", "b", "c", "d"), 0.02, **material, shear_correction=0.8),
        SpatialTrianglePlateElement("t", ("b", "e", "c"), 0.003, **material)])
    expected = fe.natural_frequencies(["a"])[:6]
    assert np.asarray(scene.run()) == pytest.approx(expected, rel=1e-8)
    assert expected[0] > 1.0
