"""Second-order (foreshortening) inertia of the modal beam (``ModalBeam(second_order_inertia=True)``,
:mod:`ctmm.flexible.second_order`, ``docs/flexible.md`` §1.3.1, ``docs/closed_loops.md`` §4b).

Independent reference: :mod:`ctmm.reference.flexible_loop_lagrange`, an assumed-modes Lagrange model of the flexible
four-bar written from scratch (mass points on Gauss points, Lagrange multipliers at the cut; no ctmm.flexible code),
with every mass point moved by its shortening (``"second_order"``) or with the first-order geometric stiffness only
(``"stiffening"``).  The accelerations of the closed loop at a bent, moving state must agree with the matching form
and differ from the other one.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.compiled_parameters import parameter_vector
from ctmm.compiled_scene import symbolic_plant_accelerations
from ctmm.errors import ModelError
from ctmm.flexible import ModalBeam
from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel
from ctmm.reference.flexible_loop_lagrange import FlexibleFourBarLagrange
from ctmm.scenarios.four_bar import COUPLER, CRANK, GROUND, MASSES, ROCKER

RHO_A = MASSES["coupler"] / COUPLER


def _coupler(bending_stiffness: float, n_modes: int, second_order: bool) -> ModalBeam:
    return ModalBeam("coupler", length=COUPLER, bending_stiffness=bending_stiffness, mass_per_length=RHO_A,
                     n_modes=n_modes, second_order_inertia=second_order)


def _four_bar(bending_stiffness: float, n_modes: int, second_order: bool) -> KinematicLoopModel:
    tree = PlanarModel("four_bar_second_order", [
        Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(GROUND, 0.0)),
        RigidBody.uniform_link("crank", mass=MASSES["crank"], length=CRANK),
        SmoothHinge("h1", parent="g", child="crank"),
        _coupler(bending_stiffness, n_modes, second_order), SmoothHinge("h2", parent="crank", child="coupler"),
        RigidBody.uniform_link("rocker", mass=MASSES["rocker"], length=ROCKER),
        SmoothHinge("h4", parent="g4", child="rocker")], gravity=(0.0, -9.81))
    return KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="coupler.out")])


def _bent_moving_state(loop: KinematicLoopModel) -> tuple[np.ndarray, np.ndarray]:
    """Crank at 80 deg turning at 6 rad/s, the coupler bent (end slope ~ 0.1) and vibrating, the rest assembled."""
    names = loop.tree.coordinates
    q = {"crank.theta": 1.4, "coupler.theta": 0.5, "rocker.theta": 1.8,
         "coupler.q1": 0.012, "coupler.q2": -0.003, "coupler.q3": 0.001}
    v = {"crank.theta": 6.0, "coupler.q1": 0.4, "coupler.q2": -0.5, "coupler.q3": 0.3}
    modal = [name for name in names if name.startswith("coupler.q")]
    return loop.consistent_state([q.get(n, 0.0) for n in names], [v.get(n, 0.0) for n in names],
                                 keep=["crank.theta", *modal])


def test_four_bar_accelerations_match_the_independent_lagrange_model():
    """At a bent, vibrating state the loop's accelerations equal the Lagrange model's with the same physics to
    1e-10 of their size (both exact for the state) and so does the energy, while the two forms' accelerations differ
    by 44 % of their size (the modal rates' second-order Coriolis and axial terms)."""
    accelerations = {}
    for second_order, form in ((False, "stiffening"), (True, "second_order")):
        loop = _four_bar(20.0, 3, second_order)
        q, v = _bent_moving_state(loop)
        reference = FlexibleFourBarLagrange((MASSES["crank"], CRANK), (COUPLER, RHO_A, 20.0),
                                            (MASSES["rocker"], ROCKER), GROUND, 3, inertia=form)
        assert np.max(np.abs(reference.constraints(q, v)[0])) < 1e-12          # the same assembled state
        assert np.max(np.abs(reference.constraints(q, v)[1] @ v)) < 1e-12
        expected = reference.accelerations(q, v)[0]
        got = loop.solve(q, v, 0.0)[0]
        # kinetic (with the shortening when second order), gravity and strain energy: measured 3e-16
        assert loop.tree.energy(q, v) == pytest.approx(reference.energy(q, v), rel=1e-12)
        scale = np.max(np.abs(expected))
        assert np.max(np.abs(got - expected)) < 1e-10 * scale                    # measured 1.3e-12, 9e-13
        accelerations[form] = expected
    difference = np.abs(accelerations["second_order"] - accelerations["stiffening"])
    assert np.max(difference) > 0.1 * np.max(np.abs(accelerations["second_order"]))      # measured 0.44
    assert difference[0] > 0.1 * abs(accelerations["second_order"][0])         # the crank feels it: 0.57


def _pendulum(second_order: bool) -> PlanarModel:
    beam = ModalBeam("arm", length=0.6, bending_stiffness=6.0, mass_per_length=RHO_A, n_modes=3,
                     second_order_inertia=second_order)
    return PlanarModel("flexible_pendulum", [
        Fixed("g", position=(0.0, 0.0)),
        RigidBody.uniform_link("crank", mass=0.4, length=0.2), SmoothHinge("h1", parent="g", child="crank"),
        beam, SmoothHinge("h2", parent="crank", child="arm")], gravity=(0.0, -9.81))


def test_the_second_order_beam_conserves_its_energy():
    """A swinging, bending double pendulum (crank + stiffened modal beam, no damping): with the second-order
    inertia the model is Lagrangian and its energy (with the shortening's kinetic and gravity terms) stays
    constant to the integrator's error (RK4, fourth order in the step); the first-order stiffened beam's energy changes
    by the work of its non-conservative stiffening force, orders of magnitude more."""
    drift = {}
    for second_order in (False, True):
        model = _pendulum(second_order)
        names = model.coordinates
        q0 = np.array([{"crank.theta": 0.3, "arm.theta": 0.0, "arm.q1": 0.02}.get(n, 0.0) for n in names])
        v0 = np.array([{"crank.theta": 4.0, "arm.theta": -6.0}.get(n, 0.0) for n in names])
        run = ctmm.simulate(model, 0.02, 2e-4, x0=q0, v0=v0)
        q = np.column_stack([run[n] for n in names])
        v = np.column_stack([run[f"{n}_dot"] for n in names])
        energy = np.array([model.energy(a, b) for a, b in zip(q, v)])
        assert np.ptp(run["arm.q1"]) > 5e-3                                         # it bends
        drift[second_order] = np.max(np.abs(energy - energy[0])) / np.max(np.abs(energy))
    assert drift[True] < 2e-6 and drift[False] > 1000 * drift[True]          # measured 9.4e-7 (RK4), 3.0e-3


def test_generated_kernel_states_the_same_accelerations():
    """The generated (casadi) path runs the same numpy statements on symbols: its accelerations equal the numeric
    sweep's at a bent, moving state."""
    model = _pendulum(True)
    names = model.coordinates
    q = np.array([{"crank.theta": 0.3, "arm.theta": -0.4, "arm.q1": 0.02, "arm.q2": -0.004}.get(n, 0.0) for n in names])
    v = np.array([{"crank.theta": 4.0, "arm.theta": -6.0, "arm.q1": 0.3, "arm.q3": -0.2}.get(n, 0.0) for n in names])
    function = symbolic_plant_accelerations(model)
    symbolic = np.asarray(function(q, v, parameter_vector(model), 0.0)).reshape(-1)
    numeric = model.flexible_system.accelerations(q, v, 0.0)
    assert np.max(np.abs(symbolic - numeric)) < 1e-10 * np.max(np.abs(numeric))          # measured 2.7e-13
    first_order = _pendulum(False).flexible_system.accelerations(q, v, 0.0)
    assert np.max(np.abs(first_order - numeric)) > 0.1 * np.max(np.abs(numeric))        # measured 0.76


@pytest.mark.parametrize("changes, message", [
    ({"second_order_inertia": 1}, "second_order_inertia must be True or False"),
    ({"second_order_inertia": True, "geometric_stiffening": False}, "geometric_stiffening = False"),
    ({"second_order_inertia": True, "n_axial_modes": 1, "axial_stiffness": 1e6}, "n_axial_modes = 1"),
])
def test_refused_combinations_name_the_parameter(changes, message):
    arguments = dict(length=0.6, bending_stiffness=6.0, mass_per_length=1.0, n_modes=2)
    with pytest.raises(ModelError, match=message):
        ModalBeam("arm", **{**arguments, **changes})
