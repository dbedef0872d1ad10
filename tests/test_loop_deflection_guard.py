"""Kinematic loop runs stop when a modal beam of the tree leaves its range, as the tree runs do.

The tree runs (:func:`ctmm.planar.integrate.check_state`) stop with a :class:`SimulationError` (time, beam, partial
result) once a ``ModalBeam``'s deflection bound ``sum_i max|phi_i| |q_i|`` passes its length.  The RK4 of a
kinematic loop model (:func:`ctmm.loop_integration.integrate_loop_model`) checked only finiteness and its projection:
a flexible four-bar whose coupler is struck hard (modal rate 40 1/s) went on past the beam's length until the
projection broke down, and the error named the cut joint.

Independent reference: the bound by hand, ``max|phi_i|`` from the coupler's shape functions sampled at 2001
stations (not the beam's own ``phi_bound``): every stored row of a run that ends one step before the failure is
within the length, one more RK4 step with projection from its last row is beyond it, and the failing run names
that step's time, the coupler and the partial result up to the row before.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from ctmm.errors import SimulationError
from ctmm.ode import rk4_step
from ctmm.planar.closed_loops import simulate_kinematic_loops
from ctmm.scenarios.four_bar import COUPLER, flexible_mechanism

DT = 1e-3


@pytest.fixture(scope="module")
def struck():
    loop = flexible_mechanism(80.0, n_modes=2)
    names = loop.tree.coordinates
    q = [math.pi / 2 if n == "crank.theta" else 0.5 if n == "coupler.theta" else 1.8 if n == "rocker.theta" else 0.0
         for n in names]
    v = [3.0 if n == "crank.theta" else 40.0 if n == "coupler.q1" else 0.0 for n in names]
    q0, v0 = loop.consistent_state(q, v, keep=["crank.theta", "coupler.q1", "coupler.q2"])
    return loop, q0, v0


def hand_bound(loop, q: np.ndarray) -> np.ndarray:
    """``sum_i max_x |phi_i(x)| |q_i|`` [m] of rows ``q`` (the coupler's shapes sampled densely)."""
    coupler = next(e for e in loop.tree.elements if getattr(e, "name", None) == "coupler")
    stations = np.linspace(0.0, COUPLER, 2001)
    peaks = np.abs(coupler.shapes(stations, 0)).max(axis=1)
    columns = [loop.tree.coordinates.index(f"coupler.q{k + 1}") for k in range(len(peaks))]
    return np.abs(np.atleast_2d(q)[:, columns]) @ peaks


def test_a_struck_flexible_four_bar_stops_at_the_step_its_coupler_passes_its_length(struck):
    loop, q0, v0 = struck
    with pytest.raises(SimulationError, match="beam 'coupler' deflection bound") as info:
        simulate_kinematic_loops(loop, q0, v0, t_final=0.05, dt=DT)
    error = info.value
    assert error.element == "coupler"
    partial = error.partial_result
    steps = int(round(error.time / DT))
    assert partial.t[-1] == pytest.approx(error.time - DT, abs=1e-12) and len(partial.t) == steps
    # the run up to the step before passes, every row within the length by hand; one more step is beyond it
    before = simulate_kinematic_loops(loop, q0, v0, t_final=(steps - 1) * DT, dt=DT)
    np.testing.assert_allclose(before.q, partial.q, rtol=0.0, atol=0.0)
    assert np.all(hand_bound(loop, before.q) <= COUPLER)
    n = loop.tree.n_coordinates

    def rate(t, y):
        return np.concatenate([y[n:], loop.solve(y[:n], y[n:], t)[0]])

    y = rk4_step(rate, before.t[-1], np.concatenate([before.q[-1], before.qdot[-1]]), DT)
    q_next, _ = loop.project(y[:n], y[n:], error.time)
    assert hand_bound(loop, q_next)[0] > COUPLER
    stated = float(str(error).split("deflection bound ")[1].split(" m")[0])
    assert stated == pytest.approx(hand_bound(loop, q_next)[0], rel=5e-3)       # stated to 3 digits


def struck_spatial_loop():
    """The pinned SpatialBeam loop of tests/test_spatial_cut_points.py, struck (``(loop, q0, v0)``)."""
    from test_spatial_cut_points import PinnedBeamReference, assembled, beam_loop, beam_state

    q0, u0 = beam_state(4)
    u0, p0 = assembled(PinnedBeamReference(True, 1.1), q0, 100.0 * u0)
    return beam_loop(True, "tip", p0), q0, u0


def test_a_struck_spatial_beam_loop_stops_at_the_step_its_beam_passes_its_length():
    """The spatial RK4 of a kinematic loop model (:func:`ctmm.spatial.closed_loop_time.simulate_spatial_loops`): a
    SpatialBeam on a yawing hub, its tip pinned to the ground, struck (velocities 100 times those of
    tests/test_spatial_cut_points.py's state, projected onto the pin by the Lagrange reference): the tree runs' rule
    (:func:`ctmm.spatial.integrate.check_beam_deflection`), bound by hand from the beam's station shapes."""
    from ctmm.spatial.closed_loop_time import simulate_spatial_loops

    loop, q0, u0 = struck_spatial_loop()
    beam = next(b for b in loop.tree.bodies if b.name == "b")
    # the largest |Phi| of each mode over 2001 stations (the beam's shapes at all of them at once)
    peaks = np.abs(beam.data.shapes(np.linspace(0.0, beam.length, 2001))).max(axis=(0, 2))
    columns = [loop.tree.coordinates.index(f"b.{suffix}") for suffix in beam.coordinate_suffixes]

    def bound(q: np.ndarray) -> np.ndarray:
        return np.abs(np.atleast_2d(q)[:, columns]) @ peaks

    with pytest.raises(SimulationError, match="beam 'b' deflection bound") as info:
        simulate_spatial_loops(loop, q0, u0, t_final=0.3, dt=DT)
    error = info.value
    assert error.element == "b"
    steps = int(round(error.time / DT))
    assert len(error.partial_result.t) == steps and error.partial_result.t[-1] == pytest.approx(
        error.time - DT, abs=1e-12)
    before = simulate_spatial_loops(loop, q0, u0, t_final=(steps - 1) * DT, dt=DT)
    np.testing.assert_allclose(before.q, error.partial_result.q, rtol=0.0, atol=0.0)
    assert np.all(bound(before.q) <= beam.length)
    stated = float(str(error).split("deflection bound ")[1].split(" m")[0])
    assert stated > beam.length


@pytest.mark.parametrize("store_every", [1, 4])
def test_the_generated_rk4_stops_with_the_numpy_error(struck, store_every):
    """The generated RK4 of the same loop (:func:`ctmm.compiled_kinematic_loops.simulate_kinematic_loops_generated`)
    stops with the numpy RK4's error: time, body, message, partial rows (generated = numpy to round-off); with
    ``store_every=4`` the failing step lies between stored rows and is found as the numpy path finds it."""
    from ctmm.compiled_kinematic_loops import simulate_kinematic_loops_generated

    loop, q0, v0 = struck
    with pytest.raises(SimulationError) as numpy_info:
        simulate_kinematic_loops(loop, q0, v0, t_final=0.05, dt=DT, store_every=store_every)
    with pytest.raises(SimulationError) as generated_info:
        simulate_kinematic_loops_generated(loop, q0, v0, t_final=0.05, dt=DT, store_every=store_every)
    expected, got = numpy_info.value, generated_info.value
    assert (got.element, got.time) == (expected.element, expected.time) == ("coupler", got.time)
    assert str(got) == str(expected)
    np.testing.assert_array_equal(got.partial_result.t, expected.partial_result.t)
    assert np.max(np.abs(got.partial_result.q - expected.partial_result.q)) <= 1e-12


@pytest.mark.parametrize("store_every", [1, 3])
def test_the_generated_spatial_rk4_stops_with_the_numpy_error(store_every):
    """The generated RK4 of the struck spatial loop
    (:func:`ctmm.compiled_spatial_kinematic_loops.simulate_spatial_kinematic_loops_generated`) stops with the numpy
    RK4's error: time, body, message, partial rows."""
    from ctmm.compiled_spatial_kinematic_loops import simulate_spatial_kinematic_loops_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loops

    loop, q0, u0 = struck_spatial_loop()
    with pytest.raises(SimulationError) as numpy_info:
        simulate_spatial_loops(loop, q0, u0, t_final=0.3, dt=DT, store_every=store_every)
    with pytest.raises(SimulationError) as generated_info:
        simulate_spatial_kinematic_loops_generated(loop, q0, u0, t_final=0.3, dt=DT, store_every=store_every)
    expected, got = numpy_info.value, generated_info.value
    assert (got.element, got.time) == (expected.element, expected.time) == ("b", got.time)
    assert str(got) == str(expected)
    np.testing.assert_array_equal(got.partial_result.t, expected.partial_result.t)
    assert np.max(np.abs(got.partial_result.q - expected.partial_result.q)) <= 1e-12
