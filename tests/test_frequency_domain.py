"""Frequency domain of 1-D chains against the independent global model (ctmm.reference.chain)."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ctmm
from ctmm.elements import Damper, Elastic, Fixed, Free, GroundedSpring, Mass, PrescribedDisplacement, Spring
from ctmm.reference import chain as ref

from _chain_convert import random_chain, to_global

ENDS = ["fixed", "free", "elastic"]


def three_mass(start, end):
    """FORMULAS §2.1 chain: m = 1, 2, 1.5; k = 100, 200, 150, 120."""
    m, k = [1.0, 2.0, 1.5], [100.0, 200.0, 150.0, 120.0]
    els = [start]
    for i in range(3):
        if not (i == 0 and isinstance(start, Free)):
            els.append(Spring(f"k{i}", k[i]))
        els.append(Mass(f"m{i}", m[i]))
    if isinstance(end, Fixed):
        els.append(Spring("k3", k[3]))
    els.append(end)
    return ctmm.Chain("three", els)


@pytest.mark.parametrize("start, end, expected", [
    (Fixed("w"), Free("e"), [3.96143496, 12.62168899, 20.0]),
    (Fixed("w"), Fixed("e"), [6.5320391, 14.47052161, 20.0732775]),
    (Free("w"), Free("e"), [0.0, 11.43240802, 18.55532395]),
])
def test_published_three_mass_frequencies(start, end, expected):
    """FORMULAS §2.1 values (eigh of the 3-mass chain, 8 printed digits)."""
    w = ctmm.natural_frequencies(three_mass(start, end), n_modes=3)
    np.testing.assert_allclose(w, expected, rtol=0, atol=5e-8)


def test_uniform_chain_closed_form():
    """w_j = 2 sqrt(k/m) sin((2j-1) pi / (2(2n+1))) for a uniform fixed-free chain (FORMULAS §2.1)."""
    n, k, m = 40, 1000.0, 0.1
    els = [Fixed("w")]
    for i in range(n):
        els += [Spring(f"k{i}", k), Mass(f"m{i}", m)]
    chain = ctmm.Chain("uniform", els + [Free("e")])
    j = np.arange(1, n + 1)
    exact = 2 * np.sqrt(k / m) * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1)))
    np.testing.assert_allclose(ctmm.natural_frequencies(chain, n_modes=n), exact, rtol=1e-12)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31), n=st.integers(1, 60), start=st.sampled_from(ENDS),
       end=st.sampled_from(ENDS), grounded=st.booleans())
def test_natural_frequencies_equal_eigh(seed, n, start, end, grounded):
    """Random chains: every natural frequency equals scipy eigh(K, M) to 1e-10 relative."""
    chain = random_chain(np.random.default_rng(seed), n, start=start, end=end, grounded=grounded)
    exact = ref.natural_frequencies(to_global(chain))
    w = ctmm.natural_frequencies(chain, n_modes=exact.size)
    scale = np.maximum(exact, 1e-9 * exact.max())
    assert np.all(np.abs(w - exact) <= 1e-10 * scale + 1e-12)


@pytest.mark.parametrize("start, end", [("fixed", "free"), ("free", "free"), ("elastic", "elastic")])
def test_natural_frequencies_200_masses(start, end):
    chain = random_chain(np.random.default_rng(7), 200, start=start, end=end, grounded=True)
    exact = ref.natural_frequencies(to_global(chain))
    w = ctmm.natural_frequencies(chain, n_modes=exact.size)
    np.testing.assert_allclose(w, exact, rtol=1e-10, atol=1e-9)


def test_clustered_roots_are_all_found():
    """Two identical heavy oscillators weakly coupled: a pair of roots 1e-7 apart, none missed."""
    els = [Fixed("w"), Spring("k1", 1000.0), Mass("m1", 10.0), Spring("c", 1e-4), Mass("m2", 10.0),
           Spring("k2", 1000.0), Fixed("e")]
    chain = ctmm.Chain("cluster", els)
    exact = ref.natural_frequencies(to_global(chain))
    assert exact[1] - exact[0] < 1e-4
    w = ctmm.natural_frequencies(chain, omega_max=20.0)
    assert w.size == 2
    np.testing.assert_allclose(w, exact, rtol=1e-12)


def test_omega_max_counts_match_eigh():
    chain = random_chain(np.random.default_rng(3), 30, start="fixed", end="fixed")
    exact = ref.natural_frequencies(to_global(chain))
    limit = 0.5 * (exact[9] + exact[10])
    w = ctmm.natural_frequencies(chain, omega_max=limit)
    assert w.size == 10
    np.testing.assert_allclose(w, exact[:10], rtol=1e-11)


def test_reversed_chain_has_same_frequencies():
    """Metamorphic: traversing the chain from the other end keeps its spectrum."""
    chain = random_chain(np.random.default_rng(5), 25, start="fixed", end="elastic", grounded=True)
    w1 = ctmm.natural_frequencies(chain, n_modes=25)
    w2 = ctmm.natural_frequencies(chain.reversed(), n_modes=25)
    np.testing.assert_allclose(w1, w2, rtol=1e-12)


def test_mode_shapes_match_eigh():
    chain = random_chain(np.random.default_rng(11), 12, start="fixed", end="free")
    modes = ctmm.mode_shapes(chain, n_modes=12)
    _, shapes = ref.mode_shapes(to_global(chain))
    masses = [j - 1 for j, e in enumerate(chain.body, start=1) if isinstance(e, Mass)]
    for k in range(12):
        tmm = modes.shapes[k, masses, 0]
        exact = shapes[:, k] / shapes[np.argmax(np.abs(shapes[:, k])), k]
        tmm = tmm / tmm[np.argmax(np.abs(tmm))]
        np.testing.assert_allclose(tmm, exact, atol=1e-9)


@pytest.mark.parametrize("quantity, suffix", [("displacement", "x"), ("velocity", "v"), ("acceleration", "a")])
@pytest.mark.parametrize("start, end", [("fixed", "free"), ("elastic", "fixed"), ("free", "elastic")])
def test_damped_frf_equals_direct_solve(quantity, suffix, start, end):
    chain = random_chain(np.random.default_rng(2), 15, start=start, end=end, damped=True, grounded=True)
    g = to_global(chain)
    omega = np.linspace(0.1, 80.0, 200)
    frf = ctmm.frequency_response(chain, omega, input="m3.force", output=f"m11.{suffix}")
    exact = ref.frequency_response(g, omega, 3, 11, quantity)
    np.testing.assert_allclose(frf(f"m11.{suffix}", "m3.force"), exact, rtol=1e-10, atol=0)


def test_internal_force_frf():
    chain = random_chain(np.random.default_rng(4), 6, start="fixed", end="free", damped=True)
    g = to_global(chain)
    omega = np.linspace(0.5, 50.0, 50)
    frf = ctmm.frequency_response(chain, omega, input="m1.force", output="k4.f")
    np.testing.assert_allclose(frf("k4.f", "m1.force"), ref.frequency_response(g, omega, 1, 4, "force"),
                               rtol=1e-10)


def test_base_excitation_equals_analytic_sdof():
    """Prescribed base displacement X: x/X = k/(k - m w^2) for a single spring-mass."""
    chain = ctmm.Chain("base", [PrescribedDisplacement("base"), Spring("k", 400.0), Mass("m", 1.0), Free("e")])
    omega = np.array([0.0, 5.0, 30.0])
    h = ctmm.frequency_response(chain, omega, input="base.displacement", output="m.x")("m.x", "base.displacement")
    np.testing.assert_allclose(h, 400.0 / (400.0 - omega ** 2), rtol=1e-14)


def test_frequency_response_result_object(tmp_path):
    import control

    chain = three_mass(Fixed("w"), Free("e"))
    omega = np.logspace(0, 2, 100)
    frf = ctmm.frequency_response(chain, omega, input=["m0.force", "m2.force"], output=["m2.x", "m0.v"])
    assert frf.response.shape == (2, 2, 100)
    x0_per_f2 = ctmm.frequency_response(chain, omega, input="m2.force", output="m0.x")("m0.x", "m2.force")
    np.testing.assert_allclose(frf("m0.v", "m2.force"), 1j * omega * x0_per_f2, rtol=1e-12)
    # reciprocity (Maxwell-Betti): x2/F0 == x0/F2
    recip = ctmm.frequency_response(chain, omega, input="m2.force", output="m0.x")("m0.x", "m2.force")
    np.testing.assert_allclose(frf("m2.x", "m0.force"), recip, rtol=1e-12)
    frd = frf.to_control()
    assert isinstance(frd, control.FrequencyResponseData)
    assert frd.input_labels == ["m0_force", "m2_force"]
    np.testing.assert_allclose(frd.fresp[0, 0], frf("m2.x", "m0.force"))
    fig = frf.plot()
    fig.savefig(tmp_path / "bode.png")
    with pytest.raises(ctmm.UnknownNameError, match="available"):
        frf("m9.x", "m0.force")


def test_plain_and_riccati_agree_on_short_chain():
    chain = random_chain(np.random.default_rng(8), 4, start="fixed", end="free", damped=True)
    omega = np.linspace(0.1, 30, 40)
    a = ctmm.frequency_response(chain, omega, input="m0.force", output="m3.x")
    b = ctmm.frequency_response(chain, omega, input="m0.force", output="m3.x", solver="plain")
    np.testing.assert_allclose(a.response, b.response, rtol=1e-10)


def test_characteristic_function_vanishes_at_damped_roots():
    chain = random_chain(np.random.default_rng(9), 5, start="fixed", end="free", damped=True)
    roots = ref.complex_eigenvalues(to_global(chain))
    delta = ctmm.characteristic_function(chain, roots)
    off = ctmm.characteristic_function(chain, roots + 0.05)
    assert np.max(np.abs(delta)) < 1e-8 * np.min(np.abs(off))


def test_undamped_required_for_natural_frequencies():
    chain = ctmm.Chain("d", [Fixed("w"), Damper("c", 1.0), Mass("m", 1.0), Free("e")])
    with pytest.raises(ctmm.ModelError, match="undamped"):
        ctmm.natural_frequencies(chain, n_modes=1)


def test_static_free_free_is_singular():
    chain = ctmm.Chain("ff", [Free("a"), Mass("m1", 1.0), Spring("k", 10.0), Mass("m2", 1.0), Free("b")])
    with pytest.raises(ctmm.SingularSystemError, match="free-free"):
        ctmm.frequency_response(chain, [0.0], input="m1.force", output="m2.x")


def test_static_free_free_beam_is_singular():
    """The same for vector states (beam fields: the Riccati and plain end solves) and for a planar hub + beam
    with exact fields at omega = 0 (free rotation): numpy's LinAlgError of the exactly singular end equations
    used to escape; it is the documented SingularSystemError naming the batch entry."""
    from ctmm.elements import BeamClamped, BeamField, BeamFree, BeamPointLoad
    from ctmm.flexible import ModalBeam
    from ctmm.planar import ActuatedHinge, Fixed as PlanarFixed, PlanarModel, RigidBody
    from ctmm.planar.elements import FixedMounting
    field = dict(length=1.0, bending_stiffness=2.0, mass_per_length=0.5)
    for solver in ("riccati", "plain"):
        chain = ctmm.Chain("ff", [BeamFree("a"), BeamField("f", **field), BeamPointLoad("p"), BeamField("g", **field),
                                  BeamFree("b")])
        with pytest.raises(ctmm.SingularSystemError, match="singular"):
            ctmm.frequency_response(chain, [0.0, 1.0], input="p.force", output="p.w", solver=solver)
        clamped = ctmm.Chain("cf", [BeamClamped("a"), BeamField("f", **field), BeamPointLoad("p"), BeamFree("b")])
        response = ctmm.frequency_response(clamped, [0.0], input="p.force", output="p.w", solver=solver)
        assert abs(response("p.w", "p.force")[0] - 1.0 / (3 * 2.0)) < 1e-12      # L^3 / (3 EI)
    hub_beam = PlanarModel.chain("hub_beam", [
        PlanarFixed("ground"), ActuatedHinge("motor"),
        RigidBody("hub", mass=1.0, inertia=0.05, center_of_mass=(0.0, 0.0), outboard=(0.1, 0.0)), FixedMounting("m"),
        ModalBeam("arm", n_modes=3, stations={"tip": 1.0}, **field)], gravity=(0.0, 0.0))
    with pytest.raises(ctmm.SingularSystemError, match=r"batch entries \[0\]"):
        ctmm.frequency_response(hub_beam, [0.0, 1.0], input="motor.torque", output="arm.tip.w", fields="exact")


@pytest.mark.parametrize("seed, n", [(0, 5), (3, 12), (11, 40)])
def test_free_free_rigid_mode_is_exactly_zero(seed, n):
    """A free-free chain's rigid-body mode is returned as 0 (the count at a tiny frequency must not
    lose the O(w^2) point stiffness to cancellation), the rest equal eigh(K, M)."""
    chain = random_chain(np.random.default_rng(seed), n, start="free", end="free", grounded=False)
    exact = ref.natural_frequencies(to_global(chain))
    w = ctmm.natural_frequencies(chain, n_modes=exact.size)
    assert w[0] == 0.0 and exact[0] < 1e-6 * exact[-1]
    np.testing.assert_allclose(w[1:], exact[1:], rtol=1e-10)


def test_frf_of_many_outputs_from_points_only_solve():
    """frequency_response keeps only the requested points of a lumped chain; several outputs at
    several points, a connector force and a repeated point still equal the dense global solve, and
    the point-restricted solve equals the full one at those points."""
    from ctmm.chain_assembly import laplace_variables, solve

    chain = random_chain(np.random.default_rng(7), 12, start="elastic", end="fixed", damped=True, grounded=True)
    g = to_global(chain)
    omega = np.linspace(0.3, 60.0, 90)
    outputs = ["m11.x", "m2.v", "k5.f", "m2.a", "m7.x"]
    frf = ctmm.frequency_response(chain, omega, input="m4.force", output=outputs)
    for name, (index, quantity) in {"m11.x": (11, "displacement"), "m2.v": (2, "velocity"),
                                    "k5.f": (5, "force"), "m2.a": (2, "acceleration"),
                                    "m7.x": (7, "displacement")}.items():
        np.testing.assert_allclose(frf(name, "m4.force"), ref.frequency_response(g, omega, 4, index, quantity),
                                   rtol=1e-10, atol=0)
    s = laplace_variables(omega)
    amplitudes = {chain.input("m4.force").position: {"force": 1.0}}
    full = solve(chain, s, amplitudes)
    points = [9, 2, 9, 0]
    part = solve(chain, s, amplitudes, points=points, compiled=False)   # the numpy recursion: bit-identical
    assert part.points == (9, 2, 9, 0) and part.states.shape[0] == 4
    for j in points:
        np.testing.assert_array_equal(part.at(j), full.at(j))
        np.testing.assert_array_equal(full.at(j), full.states[j])
    with pytest.raises(ValueError, match="points must lie"):
        solve(chain, s, amplitudes, points=[len(full.states)])
