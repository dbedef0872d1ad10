"""Natural frequencies and mode shapes of beam assemblies through ctmm.natural_frequencies.

References (sharing no code with ctmm.frequency): the classical frequency equations solved in
ctmm.reference.beams.beta_roots (FORMULAS §2.6; 30-digit mpmath checks there), the analytic
clamped-free mode ctmm.reference.beams.clamped_free_mode, the Hermite FE model
ctmm.reference.beams.HermiteBeam, and FORMULAS §2.3 check 16.  A *single* BeamField is given
to the solver: the subdivision hook, the Wittrick-Williams count (isolation) and the
determinant-sign refinement are all exercised.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.elements import (BeamClamped, BeamField, BeamFree, BeamHinge, BeamPinned, BeamPointMass,
                           BeamSliding, BeamSpring)
from ctmm.frequency import assemble
from ctmm.reference.beams import HermiteBeam, Section, beta_roots, clamped_free_mode, omega_from_beta
from test_beams_exact import root_near

EI, RHOA, L = 2.3, 0.7, 1.3
N_MODES = 40
BOUNDARY = {"clamped": BeamClamped, "free": BeamFree, "pinned": BeamPinned, "sliding": BeamSliding}
# achieved: <= 1.5e-15 relative for every case below (brief: 1e-12)
RTOL = 1e-14


def beam(name: str = "beam", length: float = L, **kw) -> BeamField:
    return BeamField(name, length, EI, RHOA, **kw)


def chain(start: str, end: str, *body) -> ctmm.Chain:
    return ctmm.Chain(f"{start}_{end}", [BOUNDARY[start]("start"), *(body or (beam(),)), BOUNDARY[end]("end")])


def exact(case: str, n: int = N_MODES, length: float = L, **kw) -> np.ndarray:
    return omega_from_beta(beta_roots(case, n, **kw), length, EI, RHOA)


# --------------------------------------------------------------------------------------------
# single beams, every boundary pair, modes 1-40
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("start, end, case, rigid", [
    ("clamped", "free", "clamped-free", 0),
    ("clamped", "clamped", "clamped-clamped", 0),
    ("free", "free", "free-free", 2),
    ("pinned", "free", "pinned-free", 1),
    ("clamped", "pinned", "clamped-pinned", 0),
    ("pinned", "pinned", "pinned-pinned", 0),
    ("clamped", "sliding", "clamped-sliding", 0),
    ("sliding", "free", "sliding-free", 1),
    ("pinned", "sliding", "pinned-sliding", 0),
    ("sliding", "sliding", "sliding-sliding", 1),
    ("free", "clamped", "clamped-free", 0),        # the same beams swept from the other end
    ("free", "pinned", "pinned-free", 1),
    ("sliding", "clamped", "clamped-sliding", 0),
])
def test_single_beam_modes_1_to_40(start, end, case, rigid):
    found = ctmm.natural_frequencies(chain(start, end), n_modes=N_MODES + rigid)
    np.testing.assert_array_equal(found[:rigid], 0.0)
    np.testing.assert_allclose(found[rigid:], exact(case), rtol=RTOL)


@pytest.mark.parametrize("mu, j", [(0.1, 0.0), (1.0, 0.0), (2.0, 0.0), (0.5, 0.05), (1.0, 0.1)])
def test_tip_mass_and_inertia_modes_1_to_40(mu, j):
    tip = BeamPointMass("tip_mass", mu * RHOA * L, j * RHOA * L ** 3)
    found = ctmm.natural_frequencies(chain("clamped", "free", beam(), tip), n_modes=N_MODES)
    np.testing.assert_allclose(found, exact("tip-mass", tip_mass_ratio=mu, tip_inertia_ratio=j), rtol=RTOL)


@pytest.mark.parametrize("eta", [0.01, 0.1, 1.0, 10.0])
def test_hub_beam_modes_1_to_40(eta):
    """Pinned root + hub inertia (FORMULAS §2.6, '-η' sign): rigid rotation first, returned as 0."""
    hub = BeamPointMass("hub", 0.0, eta * RHOA * L ** 3)
    found = ctmm.natural_frequencies(chain("pinned", "free", hub, beam()), n_modes=N_MODES + 1)
    assert found[0] == 0.0
    np.testing.assert_allclose(found[1:], exact("hub-beam", hub_inertia_ratio=eta), rtol=RTOL)


def test_omega_max_returns_every_mode_below():
    expected = exact("clamped-free")
    limit = 0.5 * (expected[24] + expected[25])
    found = ctmm.natural_frequencies(chain("clamped", "free"), omega_max=limit)
    assert found.size == 25
    np.testing.assert_allclose(found, expected[:25], rtol=RTOL)


# --------------------------------------------------------------------------------------------
# metamorphic: a beam equals pieces in series (including the exactly symmetric cases where a
# one-sided Riccati graph has a partial resonance *on* the root)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("start, end, case, rigid", [
    ("clamped", "free", "clamped-free", 0),
    ("pinned", "pinned", "pinned-pinned", 0),
    ("free", "free", "free-free", 2),
    ("clamped", "clamped", "clamped-clamped", 0),
])
@pytest.mark.parametrize("halves", [2, 4])
def test_beam_equals_equal_pieces_in_series(start, end, case, rigid, halves):
    pieces = beam().split(halves)
    whole = ctmm.natural_frequencies(chain(start, end), n_modes=30 + rigid)
    split = ctmm.natural_frequencies(chain(start, end, *pieces), n_modes=30 + rigid)
    np.testing.assert_allclose(split, whole, rtol=RTOL)
    np.testing.assert_allclose(split[rigid:], exact(case, 30), rtol=RTOL)


def test_beam_equals_two_unequal_beams_with_a_point_mass_between():
    """Two stretches of different length; a zero-mass station would be the identity."""
    a, b = beam("a", 0.4 * L), beam("b", 0.6 * L)
    joined = ctmm.natural_frequencies(chain("clamped", "free", a, b), n_modes=N_MODES)
    np.testing.assert_allclose(joined, exact("clamped-free"), rtol=RTOL)


# --------------------------------------------------------------------------------------------
# the Wittrick-Williams count with mixed boundaries, hinges and subdivision
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("start, end, case, rigid", [
    ("pinned", "free", "pinned-free", 1), ("clamped", "sliding", "clamped-sliding", 0),
    ("sliding", "sliding", "sliding-sliding", 1), ("free", "free", "free-free", 2),
])
def test_count_between_exact_roots_is_exact(start, end, case, rigid):
    roots = exact(case)
    probes = np.concatenate([[0.5 * roots[0]], 0.5 * (roots[:-1] + roots[1:])])
    counts = ctmm.eigenvalue_count(chain(start, end), probes)
    np.testing.assert_array_equal(counts, np.arange(N_MODES) + rigid)


def test_in_span_hinge_matches_check16_and_fe():
    """FORMULAS §2.3 check 16: clamped root, hinge k_h = 3 at x = 0.76, tip spring k_t = 4."""
    length = 1.9
    system = ctmm.Chain("hinged", [BeamClamped("root"), beam("b1", 0.76), BeamHinge("hinge", 3.0),
                                   beam("b2", length - 0.76), BeamSpring("tip_spring", 4.0, 0.0),
                                   BeamFree("tip")])
    found = ctmm.natural_frequencies(system, n_modes=8)
    np.testing.assert_allclose(found[:3], [3.6910028, 9.7587229, 28.6155868], rtol=0, atol=5.5e-8)
    fe = HermiteBeam([Section(length, EI, RHOA)], left="clamped", right="free", hinges=[(0.76, 3.0)],
                     springs=[(length, 4.0, 0.0)], elements=240)
    np.testing.assert_allclose(fe.frequencies(8), found, rtol=3e-7)


def test_hinge_at_a_clamp_equals_pinned_end_with_rotational_spring():
    """A hinge next to a clamp is a root (or tip) rotational spring on a pinned end: exact identity."""
    k = 5.0
    hinge_root = ctmm.natural_frequencies(chain("clamped", "free", BeamHinge("h", k), beam()), n_modes=30)
    spring_root = ctmm.natural_frequencies(chain("pinned", "free", BeamSpring("s", 0.0, k), beam()), n_modes=30)
    np.testing.assert_allclose(hinge_root, spring_root, rtol=RTOL)
    hinge_tip = ctmm.natural_frequencies(chain("free", "clamped", beam(), BeamHinge("h", k)), n_modes=30)
    spring_tip = ctmm.natural_frequencies(chain("free", "pinned", beam(), BeamSpring("s", 0.0, k)), n_modes=30)
    np.testing.assert_allclose(hinge_tip, spring_tip, rtol=RTOL)
    # a hinge on a pinned end adds nothing (massless free rotation): pinned-free again
    pinned = ctmm.natural_frequencies(chain("pinned", "free", BeamHinge("h", k), beam()), n_modes=11)
    assert pinned[0] == 0.0
    np.testing.assert_allclose(pinned[1:], exact("pinned-free", 10), rtol=RTOL)


@pytest.mark.parametrize("left, right", [("pinned", "free"), ("sliding", "pinned"), ("clamped", "sliding"),
                                         ("free", "pinned"), ("sliding", "free")])
def test_assembly_with_mixed_ends_matches_fe(left, right):
    """Two stretches, a point mass with rotary inertia, a grounded spring and a hinge vs Hermite FE."""
    sections = [Section(0.7, EI, RHOA), Section(0.9, 1.6 * EI, 0.8 * RHOA)]
    body = [BeamPointMass("m0", 0.2, 0.01), beam("s1", 0.7), BeamHinge("hinge", 6.0),
            BeamField("s2a", 0.5, 1.6 * EI, 0.8 * RHOA), BeamSpring("k", 9.0, 1.5),
            BeamField("s2b", 0.4, 1.6 * EI, 0.8 * RHOA), BeamPointMass("m1", 0.3, 0.02)]
    found = ctmm.natural_frequencies(chain(left, right, *body), n_modes=6)
    fe = HermiteBeam(sections, left=left, right=right, point_masses=[(0.0, 0.2, 0.01), (1.6, 0.3, 0.02)],
                     springs=[(1.2, 9.0, 1.5)], hinges=[(0.7, 6.0)], elements=120)
    expected = fe.frequencies(6)                  # FE: ~3e-7 (finer meshes lose low modes to round-off)
    rigid = expected < 1e-6 * expected.max()
    np.testing.assert_array_equal(found[rigid], 0.0)
    np.testing.assert_allclose(found[~rigid], expected[~rigid], rtol=2e-6)   # same modes, none missed
    # exact: the independent Riccati sign bisection of test_beams_exact around the FE values
    refined = root_near(body, left, right, expected[~rigid], width=1e-5)
    np.testing.assert_allclose(found[~rigid], refined, rtol=1e-13)


def test_compression_beyond_buckling_is_reported():
    from ctmm.errors import ModelError

    buckled = BeamField("b", 1.5, 2.0, 0.5, axial_force=-1.5 * np.pi ** 2 * 2.0 / 1.5 ** 2)
    with pytest.raises(ModelError, match="statically unstable: 1 mode"):
        ctmm.natural_frequencies(ctmm.Chain("pp", [BeamPinned("a"), buckled, BeamPinned("z")]), n_modes=3)


def test_beam_under_tension_single_field():
    """Pinned-pinned under tension, one field of 30 modes (FORMULAS §2.4 closed form)."""
    from ctmm.reference.beams import pinned_pinned_tension_frequencies

    for force in (30.0, 400.0, -5.0):
        element = BeamField("b", 1.5, 2.0, 0.5, axial_force=force)
        found = ctmm.natural_frequencies(ctmm.Chain("pp", [BeamPinned("a"), element, BeamPinned("z")]),
                                         n_modes=30)
        np.testing.assert_allclose(found, pinned_pinned_tension_frequencies(30, 1.5, 2.0, 0.5, force),
                                   rtol=RTOL)


# --------------------------------------------------------------------------------------------
# mode shapes
# --------------------------------------------------------------------------------------------
def test_cantilever_mode_shapes_match_the_analytic_modes():
    """13 user pieces (auto-subdivided further): w, theta and moment at the 14 points, modes 1-40."""
    pieces = 13
    system = chain("clamped", "free", *beam().split(pieces))
    modes = ctmm.mode_shapes(system, n_modes=N_MODES)
    beta = beta_roots("clamped-free", N_MODES)
    xi = np.arange(pieces + 1) / pieces
    worst = 0.0
    for k in range(N_MODES):
        w, theta, moment = (modes.shapes[k, :, i] for i in (0, 1, 3))
        phi = [clamped_free_mode(beta[k], xi, order) for order in range(3)]
        scale = w[-1] / phi[0][-1]
        for got, ref in ((w, phi[0]), (theta, phi[1] / L), (moment, -EI * phi[2] / L ** 2)):
            worst = max(worst, np.abs(got / scale - ref).max() / np.abs(ref).max())
    assert worst < 1e-11                                      # brief: 1e-9; achieved 4e-13


def test_rigid_body_mode_shapes_of_a_free_free_beam():
    modes = ctmm.mode_shapes(chain("free", "free", *beam().split(4)), n_modes=3)
    np.testing.assert_array_equal(modes.natural_frequencies[:2], 0.0)
    x = np.linspace(0.0, L, 5)
    for k in range(2):
        w, theta = modes.shapes[k, :, 0], modes.shapes[k, :, 1]
        np.testing.assert_allclose(theta, theta[0], atol=1e-12)                 # straight line
        np.testing.assert_allclose(w, w[0] + theta[0] * x, atol=1e-12)
        np.testing.assert_allclose(modes.shapes[k, :, 2:], 0.0, atol=1e-9)    # no shear, no moment
    lines = np.array([[modes.shapes[k, 0, 0], modes.shapes[k, 0, 1]] for k in range(2)])
    assert abs(np.linalg.det(lines)) > 1e-3


def test_hinged_beam_mode_shape_has_the_slope_jump_of_the_hinge():
    """Across BeamHinge(k): theta_out - theta_in = -moment / k (FORMULAS §2.3)."""
    system = ctmm.Chain("hinged", [BeamClamped("root"), beam("b1", 0.5), BeamHinge("hinge", 3.0),
                                   beam("b2", 0.8), BeamFree("tip")])
    modes = ctmm.mode_shapes(system, n_modes=5)
    for k in range(5):
        before, after = modes.shapes[k, 1], modes.shapes[k, 2]
        assert after[1] - before[1] == pytest.approx(-before[3] / 3.0, rel=1e-9, abs=1e-12)
        np.testing.assert_allclose(after[[0, 2, 3]], before[[0, 2, 3]], rtol=1e-12, atol=1e-14)


# --------------------------------------------------------------------------------------------
# the subdivision hook and the element exports
# --------------------------------------------------------------------------------------------
def test_subdivide_hook_bounds_beta_and_keeps_the_product():
    element = beam(axial_force=40.0)
    omega = exact("clamped-free")[-1]
    pieces = element.subdivide(omega)
    beta = pieces[0].length * (RHOA * omega ** 2 / EI) ** 0.25
    assert len(pieces) == element.pieces_for(omega, max_beta=4.0) and beta <= 4.0
    assert len(element.subdivide(1.0)) == 2                     # tension sqrt(T/EI) L = 5.4 > 4
    short = beam()
    assert short.subdivide(1.0) == [short]                      # beta < 4: the element itself
    s = 1j * np.array([3.0, 200.0])
    product = np.eye(4)
    for piece in pieces:
        product = piece.transfer_matrix(s) @ product
    direct = element.transfer_matrix(s)
    scale = np.diag([1 / L, 1.0, L ** 2 / EI, L / EI])
    inv = np.linalg.inv(scale)
    assert np.abs(scale @ (product - direct) @ inv).max() < 1e-12 * np.abs(scale @ direct @ inv).max()


def test_assemble_with_subdivision_maps_points_and_refuses_loads_on_split_elements():
    from ctmm.elements import BeamPointLoad
    from ctmm.errors import ModelError
    from ctmm.chain_assembly import subdivided as _subdivided

    system = chain("clamped", "free", beam(), BeamPointLoad("load"))
    s = 1j * np.array([500.0])
    Us, us, _, _ = assemble(system, s, subdivide=True)
    body, points = _subdivided(system, 500.0)
    assert len(Us) == len(body) == points[-1] and points[0] == 0 and points[-2] == len(body) - 1
    assert len(assemble(system, s)[0]) == 2                     # default: one matrix per element
    with pytest.raises(ModelError, match="'beam' is subdivided and cannot take loads"):
        assemble(ctmm.Chain("c", [BeamClamped("a"), beam(), BeamFree("z")]), s, {1: {"force": 1.0}},
                 subdivide=True)


def test_beam_elements_are_exported():
    import ctmm.elements as elements

    for name in ("BeamField", "BeamPointMass", "BeamSpring", "BeamHinge", "BeamPointLoad", "BeamClamped",
                 "BeamFree", "BeamPinned", "BeamSliding"):
        assert name in elements.__all__ and getattr(elements, name).__module__ in ("ctmm.elements.beams",
                                                                                  "ctmm.elements.bending")


def test_constrained_dofs_of_every_boundary():
    from ctmm.elements import Elastic, Fixed, Free
    from ctmm.layouts import AXIAL, BENDING

    assert BeamPinned("p").constrained_dofs(BENDING) == ((0,), (1,))
    assert BeamSliding("s").constrained_dofs(BENDING) == ((1,), (0,))
    assert BeamClamped("c").constrained_dofs(BENDING) == ((0, 1), ())
    assert BeamFree("f").constrained_dofs(BENDING) == ((), (0, 1))
    assert Fixed("x").constrained_dofs(AXIAL) == ((0,), ())
    assert Free("x").constrained_dofs(AXIAL) == Elastic("e", 3.0).constrained_dofs(AXIAL) == ((), (0,))


# --------------------------------------------------------------------------------------------
# the generic count beyond beams: the same code path for other layouts
# --------------------------------------------------------------------------------------------
def test_generic_count_equals_the_scalar_lumped_count():
    """The generic (matrix) recursion on 1-D lumped chains equals the scalar fast path."""
    from _chain_convert import random_chain
    from ctmm.natural import _count, _lumped_count

    for seed, (start, end) in enumerate([("fixed", "free"), ("free", "elastic"), ("elastic", "fixed")]):
        system = random_chain(np.random.default_rng(seed), 30, start=start, end=end, grounded=True)
        omega = np.geomspace(1e-2, 1e3, 400)
        np.testing.assert_array_equal(_count(system, list(system.body), omega), _lumped_count(system, omega))


def test_planar_elastic_hinge_chain_through_the_generic_count():
    """Rigid bodies (U12 = 0, U11 != I) and elastic hinges (rank-1 U12) after a fixed base."""
    from ctmm.planar import ElasticHinge, Fixed, PlanarModel, RigidBody
    from ctmm.planar.linear import static_equilibrium
    from planar_linear_elements import linear_chain
    from ctmm.reference.planar_lagrange import PlanarLagrange

    model = PlanarModel.chain("springs", [
        Fixed("g"), ElasticHinge("k0", stiffness=60.0, rest_angle=-1.2),
        RigidBody.uniform_link("a", mass=1.0, length=1.0), ElasticHinge("k1", stiffness=25.0, rest_angle=0.3),
        RigidBody("b", mass=0.7, inertia=0.05, center_of_mass=(0.4, 0.05), outboard=(0.8, 0.0)),
        ElasticHinge("k2", stiffness=10.0, rest_angle=0.2), RigidBody.uniform_link("c", mass=0.5, length=0.6)])
    q_eq = static_equilibrium(model, [-1.3, -1.2, -1.5])
    expected = PlanarLagrange(model).natural_frequencies(q_eq)
    np.testing.assert_allclose(ctmm.natural_frequencies(linear_chain(model, q_eq), n_modes=3), expected,
                               rtol=1e-13)


def test_non_reciprocal_elements_are_refused():
    """Smooth-hinge composites are not symplectic: a count would be silently wrong."""
    from ctmm.errors import ModelError
    from ctmm.planar.linear import static_equilibrium
    from planar_linear_elements import linear_chain
    from planar_helpers import uniform_chain

    model = uniform_chain(3)
    q_eq = static_equilibrium(model, np.full(model.n_coordinates, -1.5))
    with pytest.raises(ModelError, match=r"symplectic.*'link0', 'link1', 'link2'.*PlanarModel itself to ctmm.natural_frequencies"):
        ctmm.natural_frequencies(linear_chain(model, q_eq), n_modes=2)
