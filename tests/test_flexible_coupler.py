"""A four-bar whose coupler is a modal beam cut at its end (ctmm.planar.closed_loops with a ModalBeam end).

Independent reference: the same linkage as a global DAE with the coupler as rigid finite segments joined by
rotational springs ``EI / h`` (:func:`ctmm.scenarios.four_bar.flexible_reference`, ctmm.reference.planar_dae:
absolute coordinates, Lagrange multipliers), sharing no code with the sweep, the modal beam or the cut joints.
The modal beam's end is foreshortened in the cut joint (``u = -1/2 q^T G1 q``, the default
``foreshortening=True``; ``docs/closed_loops.md`` §4b, checked in ``tests/test_closed_loops_foreshortening.py``),
but the floating-frame beam leaves out the axial motion of its own mass points and is truncated to a few modes,
so the two models still differ at second order in the deflection: the check is that the modal coupler carries
nearly all of the flexible effect (the difference between the rigid and the flexible linkage), and that the cut
force on the beam end does no work.
"""
from __future__ import annotations

import numpy as np

import ctmm
from ctmm.planar.closed_loops import simulate_kinematic_loops
from ctmm.scenarios.four_bar import flexible_mechanism, flexible_reference, flexible_start, mechanism, start


def test_flexible_coupler_matches_the_finite_segment_dae():
    loop = flexible_mechanism(80.0)
    q0, v0 = flexible_start(loop)
    run = ctmm.simulate(loop, 0.06, 5e-4, x0=q0, v0=v0)
    assert np.max(run["drift"]) < 1e-12 and np.ptp(run["coupler.q1"]) > 1e-4       # it bends
    rigid_loop = mechanism()
    rigid = ctmm.simulate(rigid_loop, 0.06, 5e-4, x0=start(rigid_loop)[0], v0=start(rigid_loop)[1])
    n = 4
    dae = flexible_reference(80.0, n)
    angles = {"crank": q0[0], "rocker": q0[-1], **{f"s{i}": q0[1] for i in range(n)}}
    rates = {"crank": v0[0], "rocker": v0[-1], **{f"s{i}": v0[1] for i in range(n)}}
    state = dae.assemble(angles, rates)
    assert np.max(np.abs(dae.constraints(*state)[0])) < 1e-12
    reference = dae.simulate(state, 0.06, t_eval=run.time, rtol=1e-10, atol=1e-12)
    effect = np.max(np.abs(rigid["crank.theta"] - reference.angle("crank")))         # what flexibility changes
    error = np.max(np.abs(run["crank.theta"] - reference.angle("crank")))
    assert effect > 1e-4 and error < 0.05 * effect
    force = reference.forces[:, -1, 1]                     # the cut joint's force on the coupler's end
    assert np.max(np.abs(run["h3.force_y"] - force)) < 0.15 * np.max(np.abs(rigid["h3.force_y"] - force))


def test_cut_force_on_the_beam_end_does_no_work():
    """Undamped, without geometric stiffening (whose centrifugal form has no potential in the model's energy):
    the linkage's energy is conserved as well as the open tree's -- the cut force enters the beam's frame and
    modal equations exactly as its virtual work."""
    loop = flexible_mechanism(20.0, geometric_stiffening=False)
    q0, v0 = flexible_start(loop)
    simulation = simulate_kinematic_loops(loop, q0, v0, t_final=0.05, dt=2.5e-4)
    energy = simulation.energy()
    assert np.ptp(simulation.coordinate("coupler.q1")) > 1e-3
    assert np.max(np.abs(energy - energy[0])) < 1e-8 * np.max(np.abs(energy))
