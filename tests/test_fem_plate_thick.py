"""Thick (Mindlin MITC4) plate element ctmm.fem.SpatialThickPlateElement against Mindlin's closed form for the
simply supported plate (h/a = 0.1, 0.2; tests/plate_helpers.py, itself checked against the published 0.0930),
Navier's Kirchhoff frequencies in the thin limit (no shear locking, also on an irregular mesh), mesh
convergence at O(h^2), the constant-curvature patch test, rigid motions, and refusals."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from ctmm.errors import ModelError
from ctmm.fem import SpatialFiniteElementModel, SpatialThickPlateElement
from tests.plate_helpers import (STEEL, bending_frequencies, bending_patch_error, bending_stiffness, hinged_frequencies,
                                 mindlin_frequency, navier_frequencies, plate_model, rigid_motion_energies)


def test_the_mindlin_reference_reproduces_the_published_value():
    """Mindlin (1951) / Srinivas, Joga Rao and Rao (1970): omega h sqrt(rho / G) = 0.0930 for the (1, 1) mode of
    a simply supported square plate, h/a = 0.1, nu = 0.3, k = 5/6 (3-D elasticity: 0.0932); Kirchhoff in the
    thin limit."""
    G = STEEL["youngs_modulus"] / 2.6
    omega = mindlin_frequency(1.0, 1.0, 0.1, 1, 1)
    assert omega * 0.1 * np.sqrt(STEEL["density"] / G) == pytest.approx(0.0930, abs=5e-5)
    thin = [mindlin_frequency(1.0, 0.7, 1e-4, m, n) for m, n in ((1, 1), (2, 1), (1, 2))]
    assert thin == pytest.approx(np.sort([navier_frequencies(1.0, 0.7, 1e-4, 25)[k] for k in (0, 1, 2)]), rel=1e-6)


@pytest.mark.parametrize("thickness", [0.1, 0.2])
def test_simply_supported_thick_plate_converges_to_mindlin_at_second_order(thickness):
    """Four lowest frequencies, square plate a = 1 m (modes (1,1), (1,2), (2,1), (2,2)): errors fall by 4 per
    halving (O(h^2)), the 16 x 16 mesh is within 1.5 %, its Richardson extrapolation with 8 x 8 within 1e-3;
    shear and rotary inertia lower the frequencies by 3 % to 30 % from Kirchhoff's, so the test sees them."""
    a = 1.0
    exact = np.array([mindlin_frequency(a, a, thickness, m, n) for m, n in ((1, 1), (1, 2), (2, 1), (2, 2))])
    assert np.all(exact < 0.97 * navier_frequencies(a, a, thickness, 4))
    results = [bending_frequencies(plate_model(n, a, a, thickness), a, a, 4, "simply supported") for n in (4, 8, 16)]
    errors = [r / exact - 1 for r in results]
    assert np.all(errors[2] > 0) and np.all(errors[2] < 0.015)
    assert np.all((3.8 < errors[1] / errors[2]) & (errors[1] / errors[2] < 4.2))
    assert np.all(errors[0] / errors[1] > 3.5)
    extrapolated = results[2] + (results[2] - results[1]) / 3
    assert np.max(np.abs(extrapolated / exact - 1)) < 1e-3


@pytest.mark.parametrize("distortion", [0.0, 0.5])
def test_no_shear_locking_in_the_thin_limit(distortion):
    """h/a = 1e-2 and 1e-3 on a 12 x 12 mesh, regular and irregular (interior nodes moved by up to a quarter
    cell): the errors against Mindlin's frequencies (Kirchhoff's to 4e-6 at h/a = 1e-3) stay the same as the
    plate thins (a locking element gets stiffer without bound as h falls: 1/h^2 in its shear energy) and within
    4 %; on the regular mesh they fall by 4 to 4.4 from 6 x 6 to 12 x 12 at h/a = 1e-3.  (Below h/a ~ 3e-4 the
    generalised eigenproblem itself loses digits -- rotary inertia rho h^3/12 against k G h -- docs/mixed.md
    §7d.)"""
    a = 1.0
    errors = []
    for h in (1e-2, 1e-3):
        exact = np.array([mindlin_frequency(a, a, h, m, n) for m, n in ((1, 1), (1, 2), (2, 1), (2, 2))])
        fe = plate_model(12, a, a, h, distortion=distortion)
        errors.append(bending_frequencies(fe, a, a, 4, "simply supported") / exact - 1)
    assert np.all((errors[0] > 0) & (errors[0] < 0.04))
    assert np.max(np.abs(errors[1] / errors[0] - 1)) < 0.01
    if not distortion:
        exact = np.array([mindlin_frequency(a, a, 1e-3, m, n) for m, n in ((1, 1), (1, 2), (2, 1), (2, 2))])
        coarse = bending_frequencies(plate_model(6, a, a, 1e-3), a, a, 4, "simply supported") / exact - 1
        assert np.all((3.8 < coarse / errors[1]) & (coarse / errors[1] < 4.5))


@pytest.mark.parametrize("thickness", [1e-3, 0.2])
def test_constant_curvature_patch_test_on_an_irregular_mesh(thickness):
    """w quadratic with psi = -grad w (no shear strain) imposed on the edges of an irregular 3 x 3 patch: the
    interior nodes take the exact values and the energy is D/2 kappa^T D_b kappa A."""
    fe = plate_model(3, 1.0, 0.8, thickness, distortion=0.8)
    edge = {k for k, p in fe.positions.items() if min(p[0], 1.0 - p[0], p[1], 0.8 - p[1]) < 1e-12}
    kappa = np.array([0.3, -0.2, 0.5])
    error, energy = bending_patch_error(fe, tuple(kappa), edge)
    nu = STEEL["poisson_ratio"]
    Db = bending_stiffness(thickness) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    assert error < 1e-10 and energy == pytest.approx(kappa @ Db @ kappa / 2 * 0.8, rel=1e-10)


def test_rigid_motions_mass_and_oblique_plane():
    """A free irregular thick plate: no strain energy in its six rigid motions, mass rho h A; the same plate turned
    into an oblique plane has the same frequencies."""
    fe = plate_model(2, 0.6, 0.4, 0.05, distortion=0.6)
    assert max(rigid_motion_energies(fe)) < 1e-10 * np.max(np.abs(fe.stiffness))
    assert fe.floating_inertia("0_0").mass == pytest.approx(STEEL["density"] * 0.05 * 0.24, rel=1e-12)
    rotation = scipy.linalg.expm(np.cross(np.eye(3), np.array([0.3, -0.5, 0.8])))
    turned = SpatialFiniteElementModel("turned", {k: tuple(rotation @ p) for k, p in fe.positions.items()},
                                       list(fe.elements))
    clamped = ["0_0", "0_1", "0_2"]
    assert turned.natural_frequencies(clamped) == pytest.approx(fe.natural_frequencies(clamped), rel=1e-9)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_hinged_subsystem_frequencies_equal_the_pinned_finite_element_model(axis):
    """An irregular plate (2 x 2 cells) as a subsystem on a free hinge about x, y or z (no gravity): the elastic
    modes of the floating-frame model = eigh of the assembled matrices with the hinge node pinned.  This checks
    the rotary couplings (J_r, R_c) of the sections' rotary inertia (about in-plane axes) and the
    drilling inertia (about the normal): without R_c the frequencies are off by 15-40 %."""
    fe = plate_model(2, 0.4, 0.3, 0.03, triangles=False, distortion=0.5)
    chain, pinned = hinged_frequencies(fe, "0_0", axis, 6)
    assert chain == pytest.approx(pinned, rel=1e-9)


def test_refusals_name_the_problem():
    square = {"a": (0, 0, 0), "b": (1, 0, 0), "c": (1, 1, 0), "d": (0, 1, 0)}
    element = SpatialThickPlateElement("p", ("a", "b", "c", "d"), 0.01, **STEEL)
    with pytest.raises(ModelError, match="thickness"):
        SpatialThickPlateElement("p", ("a", "b", "c", "d"), 0.0, **STEEL)
    with pytest.raises(ModelError, match="shear_correction"):
        SpatialThickPlateElement("p", ("a", "b", "c", "d"), 0.01, **STEEL, shear_correction=-1.0)
    with pytest.raises(ModelError, match="poisson_ratio"):
        SpatialThickPlateElement("p", ("a", "b", "c", "d"), 0.01, 2e11, 0.5, 7850.0)
    with pytest.raises(ModelError, match="4 distinct"):
        SpatialThickPlateElement("p", ("a", "b", "c"), 0.01, **STEEL)
    with pytest.raises(ModelError, match="not in one plane"):
        SpatialFiniteElementModel("bad", {**square, "c": (1, 1, 0.1)}, [element])
    with pytest.raises(ModelError, match="not convex"):
        SpatialFiniteElementModel("bad", {**square, "c": (0.2, 0.2, 0)}, [element])
    with pytest.raises(ModelError, match="not convex"):                 # crossed (bow tie)
        SpatialFiniteElementModel("bad", {**square, "c": (0.2, 1, 0), "d": (1, 1.1, 0)}, [element])
    with pytest.raises(ModelError, match="no area"):
        SpatialFiniteElementModel("bad", {k: (float(i), 0.0, 0.0) for i, k in enumerate("abcd")}, [element])
    turned = {**square, "b": (0, 1, 0), "d": (1, 0, 0)}                 # clockwise about +z: normal -z, accepted
    assert SpatialFiniteElementModel("ok", turned, [element]).natural_frequencies()[6:] == pytest.approx(
        SpatialFiniteElementModel("ok", square, [element]).natural_frequencies()[6:], rel=1e-9)
