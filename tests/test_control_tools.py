"""Control tools: python-control export, loop transfer functions and margins, the design cache.

References: the TMM closed loop itself for the export and the cache (metamorphic: the same
closed loop computed another way), closed-form margins of a first-order lag with delay
(``L = k e^{-s tau} / (m s + c)``), the global closed-loop eigenvalues
(``ctmm.reference.delay_chain.closed_loop_roots``) for the gain margin, and the exact
characteristic function on the imaginary axis for the delay margin.
"""
from __future__ import annotations

import math

import control
import matplotlib
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.optimize import brentq

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.control.analysis import (closed_loop_response, encirclements, loop_transfer_function, margins,
                                   open_loop_plant)
from ctmm.control.loop_plots import bode_plot, nyquist_plot
from ctmm.results import FrequencyResponse
from ctmm.control.design import PlantCache
from ctmm.elements import Damper, Elastic, Fixed, Free, GroundedSpring, Mass, PrescribedDisplacement, Spring, SpringDamper
from ctmm.errors import ModelError, UnknownNameError
from ctmm.interop import assemble_matrices, control_name, to_frd, to_state_space
from ctmm.reference import chain as reference_chain
from ctmm.reference.delay_chain import closed_loop_frequency_response, closed_loop_roots

from test_controlled_frequency import OMEGA, build, random_setup, relative_error

S = control.tf("s")


def seed_setup(loops=()):
    return build([1.0, 1.5, 2.0], [100.0, 80.0, 120.0, 0.0], [0.5, 0.3, 0.4, 0.0], [0.0] * 3,
                 start="fixed", end="free", loops=loops)


# --------------------------------------------------------------------------- state space
def ss_response(ss, omega) -> np.ndarray:
    """``C (i w I - A)^{-1} B + D`` by batched dense solves, shape (outputs, inputs, n_omega)."""
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    shifted = 1j * omega[:, None, None] * np.eye(A.shape[0]) - A
    H = C @ np.linalg.solve(shifted, np.broadcast_to(B, (omega.size,) + B.shape)) + D
    return np.moveaxis(H, 0, -1)


def exotic_plant() -> ctmm.Chain:
    """Massless junctions (damped and undamped), grounded spring, elastic end, across actuator."""
    return ctmm.Chain("exotic", [
        Fixed("ground"), SpringDamper("k1", 100.0, 0.5), Mass("m2", 1.0), SpringDamper("k3", 100.0, 0.5),
        Mass("m4", 1.0), Spring("k5a", 200.0), Damper("c5b", 1.0), Mass("m6", 1.0),
        GroundedSpring("g6", 10.0, damping=0.1), Spring("k7", 50.0), Spring("k8", 30.0),
        Elastic("end", 5.0, damping=0.2)])


@pytest.mark.parametrize("n_loops", [0, 1, 3])
def test_state_space_frf_equals_tmm_frf(n_loops):
    loops = [Feedback("l1", "m6.x", "m2", gain=5.0),
             Feedback("l2", [("m4.v", 1.0), ("m2.v", -1.0)], "k3", gain=control.tf([2, 1], [0.1, 1])),
             Feedback("l3", "m2.a", "m6", gain=0.3)][:n_loops]
    plant = exotic_plant()
    system = ControlledChain(plant, loops) if loops else plant
    inputs = ["m2.force", "m4.force", "k3.force", "k7.force"] + [f"{lp.name}.reference" for lp in loops]
    outputs = ["m2.x", "m4.v", "m6.a", "k3.f", "m2.f", "k5a.f", "c5b.f", "g6.f", "k7.f", "k8.x", "k8.f",
               "m6.f"] + [f"{lp.name}.{q}" for lp in loops for q in "yu"]
    ss = to_state_space(system, inputs=inputs, outputs=outputs)
    assert ss.input_labels == [control_name(n) for n in inputs]
    assert ss.output_labels == [control_name(n) for n in outputs]
    H = ss(1j * OMEGA)
    tmm = ctmm.frequency_response(system, OMEGA, input=inputs, output=outputs).response
    error = np.abs(H - tmm) / np.max(np.abs(tmm), axis=2, keepdims=True)
    assert np.max(error) < 1e-10


@settings(max_examples=10, deadline=None, derandomize=True)
@given(st.integers(0, 2**31 - 1))
def test_state_space_of_random_controlled_chains(seed):
    setup = random_setup(seed, delays=False)
    n = setup.chain.size
    inputs = [f"m{i}.force" for i in range(n)]
    outputs = [f"m{i}.x" for i in range(n)] + [f"{lp.name}.u" for lp in setup.loops]
    ss = to_state_space(setup.system, inputs=inputs, outputs=outputs)
    tmm = ctmm.frequency_response(setup.system, OMEGA, input=inputs, output=outputs).response
    assert relative_error(ss_response(ss, OMEGA), tmm) < 1e-10
    # eigenvalues of the realisation are the closed-loop roots of the global reference
    ref = closed_loop_roots(setup.chain, setup.global_loops)
    poles = ss.poles()
    assert poles.size == ref.size
    for root in ref:
        assert np.min(np.abs(poles - root)) < 1e-7 * max(1.0, abs(root))


def test_assembled_matrices_of_the_seed_chain():
    M, C, K, point_dof = assemble_matrices(seed_setup().plant)
    np.testing.assert_array_equal(np.diag(M), [1.0, 1.5, 2.0])
    np.testing.assert_array_equal(K, [[180.0, -80.0, 0.0], [-80.0, 200.0, -120.0], [0.0, -120.0, 120.0]])
    np.testing.assert_array_equal(C, [[0.8, -0.3, 0.0], [-0.3, 0.7, -0.4], [0.0, -0.4, 0.4]])
    assert point_dof[0] == -1


def test_state_space_errors():
    setup = seed_setup([(2, "displacement", 0, 5.0, 0.05, None, False)])
    with pytest.raises(ModelError, match="delay.*to_frd.*pade"):
        to_state_space(setup.system)
    base = ctmm.Chain("base", [PrescribedDisplacement("base"), SpringDamper("k", 10.0, 0.1), Mass("m", 1.0),
                               Free("end")])
    with pytest.raises(ModelError, match="force inputs only"):
        to_state_space(base, inputs="base.displacement", outputs="m.x")
    with pytest.raises(UnknownNameError, match="available"):
        to_state_space(seed_setup().plant, inputs="m7.force", outputs="m0.x")
    with pytest.raises(UnknownNameError, match="available"):
        to_state_space(seed_setup().plant, inputs="m0.force", outputs="m0.q")


def test_default_state_space_signals():
    setup = seed_setup([(2, "displacement", 0, 5.0, 0.0, None, False)])
    ss = to_state_space(setup.system)
    assert ss.input_labels == ["m0_force", "m1_force", "m2_force"]
    assert ss.output_labels == ["m0_x", "m1_x", "m2_x", "loop0_y", "loop0_u"]
    assert ss.nstates == 6


def test_state_names_follow_the_first_mass_of_each_degree_of_freedom():
    """A DOF's states are named after its first mass (``m2`` of the rigid pair ``m2``-``m3``), a massless damped
    point after the point (first-order state); a massless undamped point is condensed (no state)."""
    chain = ctmm.Chain("c", [Fixed("wall"), Spring("k0", 100.0), Damper("d1", 2.0), Mass("m1", 1.0), Spring("k2", 50.0),
                             Mass("m2", 2.0), Mass("m3", 1.0), Spring("k4", 10.0), Spring("k5", 10.0), Mass("m5", 1.0),
                             Free("end")])
    ss = to_state_space(chain, inputs="m1.force", outputs="m2.x")
    assert ss.state_labels == ["m1_x", "m2_x", "m5_x", "m1_v", "m2_v", "m5_v", "k0|d1_x"]


def test_to_frd_from_response_and_system():
    setup = seed_setup([(2, "displacement", 0, 5.0, 0.05, None, False)])
    frf = ctmm.frequency_response(setup.system, OMEGA, input="m1.force", output=["m0.x", "loop0.u"])
    frd = to_frd(frf)
    assert frd.input_labels == ["m1_force"] and frd.output_labels == ["m0_x", "loop0_u"]
    np.testing.assert_array_equal(frd.frdata, frf.response)
    siso = to_frd(setup.system, OMEGA, inputs="m1.force", outputs="m0.x")
    np.testing.assert_array_equal(np.asarray(siso.frdata).reshape(-1), frf("m0.x"))
    with pytest.raises(ModelError, match="needs omega"):
        to_frd(setup.system)
    with pytest.raises(ModelError, match="takes no"):
        to_frd(frf, OMEGA)


def test_frd_export_of_an_unsorted_grid_is_ascending_for_python_control():
    """python-control's FRD needs ascending, distinct frequencies (its margins spline the data):
    a response on a shuffled grid with a repeated point exports as the sorted grid, and its margins
    are those of the hand-written L = (kp + kd s) / (m s^2 + c s + k) (before: a ValueError)."""
    m, c, k, kp, kd = 2.0, 0.3, 50.0, 30.0, 4.0
    plant = ctmm.Chain("sdof", [Fixed("w"), SpringDamper("k", k, c), Mass("m", m), Free("e")])
    system = ControlledChain(plant, [Feedback("pd", [("m.x", kp), ("m.v", kd)], "m", gain=1.0)])
    grid = np.logspace(-1, 3, 2000)
    shuffled = np.concatenate([np.random.default_rng(0).permutation(grid), grid[[5, 700]]])
    frd = loop_transfer_function(system, "pd", shuffled).to_control()
    np.testing.assert_array_equal(frd.omega, grid)
    hand = (kp + kd * S) / (m * S ** 2 + c * S + k)
    np.testing.assert_allclose(np.asarray(frd.frdata).reshape(-1), np.squeeze(hand(1j * grid)), rtol=1e-12)
    np.testing.assert_allclose(control.stability_margins(frd)[:2],
                               control.stability_margins(control.frd(hand, grid))[:2], rtol=1e-9)
    exported = to_frd(plant, shuffled, inputs="m.force", outputs="m.x")
    np.testing.assert_array_equal(exported.omega, grid)
    np.testing.assert_allclose(np.asarray(exported.frdata).reshape(-1), 1 / (k - m * grid ** 2 + 1j * c * grid),
                               rtol=1e-12)


def test_closed_loop_response_wraps_frequency_response():
    setup = seed_setup([(2, "displacement", 0, 5.0, 0.05, None, False)])
    a = closed_loop_response(setup.system, OMEGA, "m1.force", ["m0.x", "m2.x"])
    b = ctmm.frequency_response(setup.system, OMEGA, input="m1.force", output=["m0.x", "m2.x"])
    np.testing.assert_array_equal(a.response, b.response)


# ------------------------------------------------------------------ loop transfer function
def test_loop_transfer_function_convention():
    """Closed loop y/r = L/(1 + L) and u/r = K/(1 + L) with the other loops closed."""
    setup = seed_setup([(2, "displacement", 0, 5.0, 0.05, None, False),
                        (1, "velocity", 1, 3.0, 0.0, 0, True)])
    L = loop_transfer_function(setup.system, "loop0", OMEGA)("loop0.L")
    closed = ctmm.frequency_response(setup.system, OMEGA, input="loop0.reference", output=["loop0.y", "loop0.u"])
    np.testing.assert_allclose(closed("loop0.y"), L / (1 + L), rtol=1e-11)
    K = 5.0 * np.exp(-0.05j * OMEGA)
    np.testing.assert_allclose(closed("loop0.u"), K / (1 + L), rtol=1e-11)
    np.testing.assert_allclose(L, K * open_loop_plant(setup.system, "loop0", OMEGA), rtol=1e-14)


def test_tools_follow_weighted_actuator_inputs():
    """An actuator given as weighted element inputs (here a force pair) in every tool."""
    plant = seed_setup().plant
    loops = [Feedback("pair", "m2.x", [("m0.force", 1.0), ("m1.force", -0.5)], gain=8.0),
             Feedback("damp", "m1.v", "k1.force", gain=0.7)]
    system = ControlledChain(plant, loops)
    inputs, outputs = ["m2.force", "pair.reference"], ["m0.x", "m2.x", "pair.u", "damp.y"]
    direct = ctmm.frequency_response(system, OMEGA, input=inputs, output=outputs).response
    cache = PlantCache(system, OMEGA, inputs=inputs, outputs=outputs).closed_loop().response
    ss = ss_response(to_state_space(system, inputs=inputs, outputs=outputs), OMEGA)
    assert relative_error(cache, direct) < 1e-12 and relative_error(ss, direct) < 1e-10
    L = loop_transfer_function(system, "pair", OMEGA)("pair.L")
    closed = ctmm.frequency_response(system, OMEGA, input="pair.reference", output="pair.y")("pair.y")
    np.testing.assert_allclose(closed, L / (1 + L), rtol=1e-11)


def test_gain_margin_predicts_the_stability_boundary():
    """Scaling the gain by GM (1 -+ 1e-3) moves a closed-loop root pair across the axis."""
    setup = seed_setup([(2, "displacement", 0, 20.0, 0.0, None, False),
                        (1, "velocity", 1, 0.5, 0.0, None, False)])
    result = margins(setup.system, "loop0", np.linspace(0.5, 40.0, 800))
    assert np.isfinite(result.gain_margin) and result.gain_margin > 1.0
    for factor, stable in ((1 - 1e-3, True), (1 + 1e-3, False)):
        loops = [setup.global_loops[0].__class__(2, "displacement", 0, 20.0 * result.gain_margin * factor),
                 setup.global_loops[1]]
        roots = closed_loop_roots(setup.chain, loops)
        assert (np.max(roots.real) < 0) == stable
        if not stable:  # the crossing root sits at the phase-crossover frequency
            crossing = roots[np.argmax(roots.real)]
            assert abs(abs(crossing.imag) - result.phase_crossover_frequency) < 1e-2


def first_order_lag(m=2.0, c=1.0, k=5.0, tau=0.1):
    plant = ctmm.Chain("lag", [Fixed("wall"), Damper("c", c), Mass("m", m), Free("end")])
    return ControlledChain(plant, [Feedback("speed", "m.v", "m", gain=k, delay=tau)])


def test_margins_of_first_order_lag_with_delay_closed_form():
    """L = k e^{-s tau}/(m s + c): w_gc = sqrt(k^2 - c^2)/m, PM = pi - atan(m w_gc / c) - w_gc tau,
    DM = PM / w_gc; phase crossover atan(m w_pc / c) + w_pc tau = pi, GM = |m i w_pc + c| / k."""
    m, c, k, tau = 2.0, 1.0, 5.0, 0.1
    system = first_order_lag(m, c, k, tau)
    result = margins(system, "speed", np.logspace(-2, 2, 600))
    wgc = math.sqrt(k * k - c * c) / m
    pm = math.pi - math.atan(m * wgc / c) - wgc * tau
    wpc = brentq(lambda w: math.atan(m * w / c) + w * tau - math.pi, 1e-3, 1e3)
    assert result.gain_crossover_frequency == pytest.approx(wgc, rel=1e-12)
    assert result.phase_margin == pytest.approx(math.degrees(pm), rel=1e-11)
    assert result.delay_margin == pytest.approx(pm / wgc, rel=1e-11)
    assert result.phase_crossover_frequency == pytest.approx(wpc, rel=1e-11)
    assert result.gain_margin == pytest.approx(math.hypot(c, m * wpc) / k, rel=1e-11)
    assert result.gain_crossovers == (result.gain_crossover_frequency,)
    # the extra delay DM puts a characteristic root exactly on the imaginary axis at w_gc
    at_boundary = ControlledChain(system.plant, [system.loop("speed").with_parameters(delay=tau + pm / wgc)])
    delta = ctmm.characteristic_function(at_boundary, [1j * wgc, 1j * wgc * 1.1])
    assert abs(delta[0]) < 1e-12 * abs(delta[1])
    # the same margins from data: python-control FRD and ctmm FrequencyResponse (interpolated)
    L = loop_transfer_function(system, "speed", np.logspace(-2, 2, 1500))
    for data in (L, to_frd(L)):
        approx = margins(data)
        assert approx.phase_margin == pytest.approx(math.degrees(pm), rel=1e-6)
        assert approx.gain_margin == pytest.approx(math.hypot(c, m * wpc) / k, rel=1e-6)
        assert approx.delay_margin == pytest.approx(pm / wgc, rel=1e-6)
    # python-control itself on the exported FRD agrees
    gm, pm_pc, _, _, wgc_pc, _ = control.stability_margins(to_frd(L))
    assert pm_pc == pytest.approx(math.degrees(pm), rel=1e-4) and wgc_pc == pytest.approx(wgc, rel=1e-4)


def test_a_negative_phase_margin_is_named_in_the_notes_and_the_closed_loop_is_unstable():
    """The first-order lag with a delay beyond its critical one: PM = pi - atan(m w_gc / c) - w_gc tau < 0 (closed
    form) and the closed loop is unstable (ctmm.stability: margin 0, an unstable root).  ``delay_margin`` keeps the
    python-control convention (PM mod 360 deg) / w_gc, and ``notes`` says that it is no tolerated delay there."""
    from ctmm import stability

    m, c, k = 2.0, 1.0, 5.0
    wgc = math.sqrt(k * k - c * c) / m
    tau = 1.2 * (math.pi - math.atan(m * wgc / c)) / wgc
    system = first_order_lag(m, c, k, tau)
    pm = math.pi - math.atan(m * wgc / c) - wgc * tau
    result = margins(system, "speed", np.logspace(-2, 2, 600))
    assert pm < 0.0 and result.phase_margin == pytest.approx(math.degrees(pm), rel=1e-11)
    assert result.delay_margin == pytest.approx((pm % (2.0 * math.pi)) / wgc, rel=1e-11)
    assert any("negative phase margin" in note and "not a delay the loop tolerates" in note for note in result.notes)
    assert stability.delay_margin(system).margin == 0.0
    assert stability.unstable_root_count(system, sigma=1e-3)[0] >= 2       # (the free position: a root at s = 0)
    stable = margins(first_order_lag(m, c, k, 0.1), "speed", np.logspace(-2, 2, 600))
    assert not any("negative phase margin" in note for note in stable.notes)


def test_margins_of_data_on_an_unsorted_grid_closed_form():
    """Margins of L given as data on a shuffled grid with a repeated frequency are the closed form of
    the first-order lag with delay (before: ValueError 'Invalid inputs.' from the spline)."""
    m, c, k, tau = 2.0, 1.0, 5.0, 0.1
    grid = np.logspace(-2, 2, 1500)
    shuffled = np.concatenate([np.random.default_rng(1).permutation(grid), grid[[10, 900]]])
    approx = margins(loop_transfer_function(first_order_lag(m, c, k, tau), "speed", shuffled))
    wgc = math.sqrt(k * k - c * c) / m
    pm = math.pi - math.atan(m * wgc / c) - wgc * tau
    wpc = brentq(lambda w: math.atan(m * w / c) + w * tau - math.pi, 1e-3, 1e3)
    assert approx.phase_margin == pytest.approx(math.degrees(pm), rel=1e-6)
    assert approx.gain_margin == pytest.approx(math.hypot(c, m * wpc) / k, rel=1e-6)
    assert approx.delay_margin == pytest.approx(pm / wgc, rel=1e-6)


def test_gain_margin_at_zero_frequency_of_a_negative_gain():
    """u = +40 x on m s^2 + c s + k: L(0) = -40 / k lies on the negative real axis, so the gain margin is
    k / 40 at omega = 0 (a real root through s = 0), as python-control's margin of the hand-written L says
    (before: inf, the certified search dropped phase crossovers at omega = 0)."""
    m, c, k, g = 2.0, 0.3, 50.0, -40.0
    plant = ctmm.Chain("sdof", [Fixed("w"), SpringDamper("k", k, c), Mass("m", m), Free("e")])
    result = margins(ControlledChain(plant, [Feedback("c", "m.x", "m", gain=g)]), "c", np.logspace(-2, 3, 500))
    gm, _, wpc, _ = control.margin(g / (m * S ** 2 + c * S + k))
    assert result.gain_margin == pytest.approx(k / -g, rel=1e-12) and gm == pytest.approx(k / -g, rel=1e-12)
    assert result.phase_crossover_frequency == 0.0 == wpc
    assert any("phase crossover at 0 rad/s" in note for note in result.notes)


def test_margins_on_a_grid_through_an_undamped_plant_pole():
    """Undamped m s^2 + k under a delayed PD, the grid holding sqrt(k/m) exactly: that grid point (L unbounded) is
    left out and noted; the margins are the closed form: |kp + i kd w| = |k - m w^2| at w_gc, PM = pi + arg L
    (before: SingularSystemError 'batch entries [...]')."""
    m, k, kp, kd, tau = 2.0, 50.0, 30.0, 4.0, 0.01
    plant = ctmm.Chain("undamped", [Fixed("w"), Spring("k", k), Mass("m", m), Free("e")])
    system = ControlledChain(plant, [Feedback("pd", [("m.x", kp), ("m.v", kd)], "m", gain=1.0, delay=tau)])
    pole = math.sqrt(k / m)
    result = margins(system, "pd", np.sort(np.append(np.logspace(-1, 3, 300), pole)))
    wgc = brentq(lambda w: abs(kp + 1j * kd * w) - abs(k - m * w * w), 5.5, 20.0)
    phase = math.pi + np.angle((kp + 1j * kd * wgc) * np.exp(-1j * wgc * tau) / (k - m * wgc * wgc))
    assert result.gain_crossover_frequency == pytest.approx(wgc, rel=1e-12)
    assert result.phase_margin == pytest.approx(math.degrees(phase), rel=1e-10)
    assert result.delay_margin == pytest.approx(phase / wgc, rel=1e-10)
    assert any(f"[{pole}] rad/s at poles of the plant left out" in note for note in result.notes)


def test_margins_without_crossovers_and_errors():
    system = first_order_lag(k=0.5)               # |L| < 1 everywhere: no gain crossover
    result = margins(system, "speed", np.logspace(-2, 2, 200))
    assert math.isinf(result.phase_margin) and math.isinf(result.delay_margin)
    assert math.isnan(result.gain_crossover_frequency)
    with pytest.raises(ModelError, match="loop name and a frequency grid"):
        margins(system)
    with pytest.raises(UnknownNameError, match="unknown loop 'x'.*speed"):
        margins(system, "x", [1.0, 2.0, 3.0, 4.0])
    with pytest.raises(ModelError, match="ControlledChain"):
        loop_transfer_function(system.plant, "speed", [1.0])


@pytest.mark.parametrize("k, expected", [(7.9, 0), (8.1, -2)])
def test_encirclements_of_third_order_lag(k, expected):
    """L = k/(s + 1)^3 closes unstable for k > 8 (Routh): two clockwise encirclements."""
    w = np.linspace(0.0, 300.0, 30001)
    L = FrequencyResponse(w, (k / (1j * w + 1) ** 3)[None, None], ("u",), ("L",))
    assert encirclements(L) == expected


def test_scenario_modules_follow_the_protocol():
    import importlib
    import inspect

    for name in ("controlled_chain_frequency", "controlled_chain_across", "controlled_chain_delay_frequency",
                 "controlled_chain_time", "pd_tuning"):
        module = importlib.import_module(f"ctmm.scenarios.{name}")
        assert module.NAME == name and module.DESCRIPTION
        assert list(inspect.signature(module.run).parameters) == ["output_dir", "quick"]
    assert not hasattr(importlib.import_module("ctmm.scenarios.controlled_chain_common"), "NAME")


def test_plots_return_figures(tmp_path):
    matplotlib.use("Agg")
    system = first_order_lag()
    L = loop_transfer_function(system, "speed", np.logspace(-2, 2, 300))
    result = margins(system, "speed", L.omega)
    fig = bode_plot(L, margins=result, title="first-order lag")
    assert len(fig.axes) == 2
    fig.savefig(tmp_path / "bode.png")
    fig = nyquist_plot([L], margins=result)
    fig.savefig(tmp_path / "nyquist.png")
    assert (tmp_path / "bode.png").stat().st_size > 0


# -------------------------------------------------------------------------- design cache
@settings(max_examples=10, deadline=None, derandomize=True)
@given(st.integers(0, 2**31 - 1))
def test_plant_cache_equals_embedded_closed_loop(seed):
    setup = random_setup(seed)
    system = setup.system
    rng = np.random.default_rng(seed + 7)
    n = setup.chain.size
    inputs = [f"m{int(rng.integers(n))}.force", "loop0.reference"]
    outputs = [f"m{i}.x" for i in range(n)] + ["loop0.y", "loop0.u"] + (["k1.f"] if n > 1 or setup.plant.elements[1].name == "k0" else [])
    cache = PlantCache(system, OMEGA, inputs=inputs, outputs=outputs)
    # new gains (float and LTI) and delays, no TMM sweep
    new_gains = {"loop0": float(rng.uniform(0.5, 1.5)) * (system.loops[0].gain or 1.0)}
    if len(system.loops) > 1:
        new_gains[system.loops[1].name] = control.tf([float(rng.uniform(0.1, 1)), 1.0], [0.05, 1.0])
    new_delays = {system.loops[-1].name: float(rng.uniform(0, 0.05))}
    fast = cache.closed_loop(gains=new_gains, delays=new_delays)
    loops = [lp.with_parameters(gain=new_gains.get(lp.name), delay=new_delays.get(lp.name)) for lp in system.loops]
    direct = ctmm.frequency_response(system.with_loops(loops), OMEGA, input=inputs, output=outputs)
    scale = np.max(np.abs(direct.response), axis=2, keepdims=True)
    assert np.max(np.abs(fast.response - direct.response) / scale) < 1e-10
    # loop transfer function with the others closed
    for lp in loops:
        a = cache.loop_transfer(lp.name, gains=new_gains, delays=new_delays)(f"{lp.name}.L")
        b = loop_transfer_function(system.with_loops(loops), lp.name, OMEGA)(f"{lp.name}.L")
        assert relative_error(a, b) < 1e-10


def test_plant_cache_unchanged_gains_and_response_arrays():
    setup = seed_setup([(2, "displacement", 0, 5.0, 0.05, None, False)])
    cache = PlantCache(setup.system, OMEGA, inputs="m1.force", outputs="m0.x")
    direct = ctmm.frequency_response(setup.system, OMEGA, input="m1.force", output="m0.x")
    assert relative_error(cache.closed_loop().response, direct.response) < 1e-12
    # C(i w) given as an array (e.g. measured controller data)
    pd = 5.0 + 0.3j * OMEGA
    via_array = cache.closed_loop(gains={"loop0": pd})
    via_lti = cache.closed_loop(gains={"loop0": control.tf([0.3, 5.0], [1.0])})
    assert relative_error(via_array.response, via_lti.response) < 1e-14


def test_plant_cache_errors():
    setup = seed_setup([(2, "displacement", 0, 5.0, 0.0, None, False)])
    with pytest.raises(ModelError, match="ControlledChain"):
        PlantCache(setup.plant, OMEGA, inputs="m1.force", outputs="m0.x")
    cache = PlantCache(setup.system, OMEGA, inputs="m1.force", outputs="m0.x")
    with pytest.raises(UnknownNameError, match="unknown loop 'nope'.*loop0"):
        cache.closed_loop(gains={"nope": 1.0})
    with pytest.raises(ModelError, match="delay must be >= 0"):
        cache.closed_loop(delays={"loop0": -1.0})
    with pytest.raises(ModelError, match="gain must be finite"):
        cache.closed_loop(gains={"loop0": math.nan})
    with pytest.raises(UnknownNameError, match="available"):
        PlantCache(setup.system, OMEGA, inputs="m1.force", outputs="loop0.z")


def test_plant_cache_refuses_where_the_superposition_loses_the_digits():
    """An undamped plant closed by two delayed loops, at its natural frequencies: the cached plant responses are
    ~1e13 there and the closed loop their difference -- the algebra was 3 % and 0.6 % off the dense closed loop,
    silently; now those frequencies are refused by name, and the others still equal the dense closed loop."""
    setup = build([1.9, 1.3], [480.0, 660.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0], start="fixed", end="free",
                  loops=[(1, "displacement", 1, 6.9, 0.036, None, False), (0, "displacement", 1, -2.7, 0.045, None,
                                                                             False)])
    M, _, K = reference_chain.assemble(setup.chain)
    natural = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real))
    omega = np.array([3.0, natural[0], 20.0, natural[1]])
    cache = PlantCache(setup.system, omega, inputs="m0.force", outputs="m1.x")
    with pytest.raises(ModelError, match=r"at omega = \[11\.\d+, 31\.\d+\] rad/s .*ctmm.frequency_response"):
        cache.closed_loop()
    with pytest.raises(ModelError, match=r"loop_transfer\('loop0'\): at omega = \[11\.\d+, 31\.\d+\] rad/s"):
        cache.loop_transfer("loop0")           # with loop1 closed: 0.45 % and 0.34 % off before
    regular = PlantCache(setup.system, omega[[0, 2]], inputs="m0.force", outputs="m1.x")
    dense = closed_loop_frequency_response(setup.chain, setup.global_loops, omega[[0, 2]], 0, 1, "displacement")
    np.testing.assert_allclose(regular.closed_loop()("m1.x"), dense, rtol=1e-10)
    np.testing.assert_allclose(regular.loop_transfer("loop0").response,
                               loop_transfer_function(setup.system, "loop0", omega[[0, 2]]).response, rtol=1e-10)
