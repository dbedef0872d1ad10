"""Foreshortening of a modal beam's end at a cut joint (ctmm.planar.closed_loops, docs/closed_loops.md §4b).

An axially rigid bent beam's end moves towards its root by ``u = -1/2 int_0^x_e w'^2 dx = -1/2 q^T G1 q``
(second order in the deflection); the cut joint at the end of a ``ModalBeam`` uses it in its constraint and the
cut force does its virtual work through it.  Checks: the end position against the inextensible arc length of the
bent beam (an independent root solve), energy conservation of the undamped flexible four-bar (the cut force does no
work), and the flexible four-bar against the finite-segment global DAE (``ctmm.reference.planar_dae``, coupler as
rigid segments with springs ``EI / h``; no code shared) as the segments converge.
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.optimize

import ctmm
from ctmm.planar.closed_loops import KinematicLoopModel, simulate_kinematic_loops
from ctmm.scenarios.four_bar import COUPLER, flexible_mechanism, flexible_reference, flexible_start, mechanism, start


def _with(loop: KinematicLoopModel, foreshortening: bool) -> KinematicLoopModel:
    return KinematicLoopModel(loop.tree, loop.cuts, foreshortening=foreshortening)


def test_end_position_follows_the_inextensible_arc_length():
    """The shortening equals 1/2 int w'^2 (by adaptive quadrature of the bent shape) and approaches the exact
    inextensible arc-length position at second order: its relative error quarters when the deflection halves."""
    loop = flexible_mechanism(80.0, n_modes=3)
    tree = loop.tree
    coupler = next(e for e in tree.elements if getattr(e, "name", None) == "coupler")
    index = {name: k for k, name in enumerate(tree.coordinates)}
    errors = []
    for scale in (1.0, 0.5):
        modal = scale * np.array([0.01, -0.002, 0.0005])
        q = np.zeros(tree.n_coordinates)
        q[index["crank.theta"]], q[index["coupler.theta"]], q[index["rocker.theta"]] = 1.5, 0.4, 1.8
        for k, value in enumerate(modal):
            q[index[f"coupler.q{k + 1}"]] = value
        rate = np.zeros_like(q)
        gap = _with(loop, True).constraints(q, rate)[0] - _with(loop, False).constraints(q, rate)[0]
        shortening = -(np.cos(0.4) * gap[0] + np.sin(0.4) * gap[1])       # along the frame's x axis [m]
        assert abs(-np.sin(0.4) * gap[0] + np.cos(0.4) * gap[1]) < 1e-15    # purely axial

        def slope(x, modal=modal):
            return float(modal @ coupler.shapes(np.atleast_1d(x), 1)[:, 0])

        def arc(x_end, slope=slope):
            return scipy.integrate.quad(lambda x: np.sqrt(1.0 + slope(x) ** 2), 0.0, x_end, epsabs=1e-16)[0]

        half_square = 0.5 * scipy.integrate.quad(lambda x: slope(x) ** 2, 0.0, COUPLER, epsabs=1e-16)[0]
        assert shortening == pytest.approx(half_square, rel=1e-10)
        exact = COUPLER - scipy.optimize.brentq(lambda x: arc(x) - COUPLER, 0.9 * COUPLER, COUPLER, xtol=1e-16)
        errors.append(shortening / exact - 1.0)
    assert 0.0 < errors[0] < 1e-2 and errors[0] / errors[1] == pytest.approx(4.0, rel=0.01)   # measured 5.7e-3, 4.00


def test_the_cut_force_does_no_work_through_the_foreshortening():
    loop = _with(flexible_mechanism(20.0, geometric_stiffening=False), True)
    q0, v0 = flexible_start(loop)
    # 0.025 s: the coupler's first mode already spans 2.6e-3 (measured energy error 1.1e-9 relative)
    simulation = simulate_kinematic_loops(loop, q0, v0, t_final=0.025, dt=2.5e-4)
    energy = simulation.energy()
    assert np.ptp(simulation.coordinate("coupler.q1")) > 1e-3
    assert np.max(np.abs(energy - energy[0])) < 1e-8 * np.max(np.abs(energy))


def _dae_crank(bending_stiffness: float, segments: int, q0, v0, times):
    dae = flexible_reference(bending_stiffness, segments)
    angles = {"crank": q0[0], "rocker": q0[-1], **{f"s{i}": q0[1] for i in range(segments)}}
    rates = {"crank": v0[0], "rocker": v0[-1], **{f"s{i}": v0[1] for i in range(segments)}}
    state = dae.assemble(angles, rates)
    assert np.max(np.abs(dae.constraints(*state)[0])) < 1e-12
    return dae.simulate(state, times[-1], t_eval=times, rtol=1e-10, atol=1e-12).angle("crank")


def test_foreshortening_closes_most_of_the_gap_to_the_finite_segment_dae():
    """EI = 20 N m^2, 3 modes, 0.06 s.  Measured (max crank-angle difference / flexible effect, DAE with 4, 8, 16
    segments): linear end 6.68, 6.09, 6.03 %; with the foreshortening 2.80, 2.33, 2.28 %.  The gap closes as the
    segments converge and the foreshortening removes ~60 % of it; the rest is not the cut joint's (it does not
    shrink with segments and grows with more modes: 5 modes 3.3 %): the floating-frame modal beam itself carries
    no other second-order term of the bent beam than its geometric stiffening (docs/closed_loops.md §4b)."""
    flexible = flexible_mechanism(20.0)
    q0, v0 = flexible_start(flexible)
    runs = {fs: ctmm.simulate(_with(flexible, fs), 0.06, 5e-4, x0=q0, v0=v0) for fs in (False, True)}
    times = runs[True].time
    rigid_loop = mechanism()
    rigid = ctmm.simulate(rigid_loop, 0.06, 5e-4, x0=start(rigid_loop)[0], v0=start(rigid_loop)[1])
    gaps = {}
    for segments in (4, 8):
        crank = _dae_crank(20.0, segments, q0, v0, times)
        effect = np.max(np.abs(rigid["crank.theta"] - crank))
        for fs, run in runs.items():
            gaps[fs, segments] = np.max(np.abs(run["crank.theta"] - crank)) / effect
    assert gaps[True, 8] < gaps[True, 4]                       # closes toward the converging DAE
    assert gaps[True, 8] < 0.45 * gaps[False, 8]               # 2.33 % vs 6.09 %
    assert gaps[True, 8] < 0.025                               # measured 0.0233 (16 segments: 0.0228)


def test_default_operating_point_of_the_flexible_linkage_is_at_rest():
    """The linear verbs' default operating point (the hanging configuration assembled with the beam straight, then
    Newton; accepted by the scale-aware equilibrium test: a stiff modal coordinate is at rest to round-off with
    accelerations of |K| times that) is a static equilibrium: released there, the linkage stays put."""
    loop = flexible_mechanism(80.0)
    lin = ctmm.linearize(loop, inputs=["h1.torque"])
    assert lin.operating_point.equilibrium
    q_eq = lin.operating_point.q
    run = ctmm.simulate(loop, 0.05, 5e-4, x0=q_eq, v0=np.zeros_like(q_eq))      # measured moved 1.1e-12
    moved = max(np.max(np.abs(run[name] - value)) for name, value in zip(loop.tree.coordinates, q_eq))
    assert moved < 1e-9 and abs(run["coupler.q1"][0]) > 1e-5       # at rest, the beam bent by its own weight
    omega = ctmm.natural_frequencies(loop, n_modes=2)
    assert 7.0 < omega[0] < 7.1 and omega[1] > 100.0               # the mechanism mode, then the first bending mode
