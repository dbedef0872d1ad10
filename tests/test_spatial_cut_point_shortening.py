"""A spatial cut joint at a point of a SpatialBeam with ``second_order_inertia`` follows the shortening of the bent
axis (:mod:`ctmm.spatial.cut_points`).

The beam's own points, sensors and point loads move the point at ``x_e`` along the axis by
``u = -1/2 int_0^x_e (w_y'^2 + w_z'^2) dx`` (second order in the deflection); the cut point did not, so the loop
closed at a point ``|u|`` away from the one its load acts at.  Independent reference: the shortening by hand, the
slopes of the deflection ``Phi(x) eta`` by central differences of the beam's station shapes and the integral by
Simpson's rule on 2001 stations (not the beam's ``G1``); the same tree with ``second_order_inertia=False`` gives the
unshortened point.  The acceleration of the shortened point is checked against the closed-loop accelerations
themselves: ``Phi''`` by central differences of ``Phi'`` along the motion equals ``-2 alpha Phi' - alpha^2 Phi`` (the
Baumgarte law the solve imposes).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate

from ctmm.spatial import Revolute, SpatialBeam, SpatialBody, SpatialCutJoint, SpatialKinematicLoopModel, SpatialModel
from ctmm.spatial import Weld

BEAM = dict(length=1.1, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=9.0, n_modes_y=2,
            n_modes_z=2, n_torsion_modes=1, torsional_stiffness=3.0, polar_inertia_per_length=0.002)
HUB_INERTIA = np.array([[0.12, 0.01, 0], [0.01, 0.1, 0.02], [0, 0.02, 0.15]])
BAUMGARTE = 20.0


def loop(second_order: bool, station: str) -> SpatialKinematicLoopModel:
    tree = SpatialModel("pinned_beam", [
        SpatialBody("hub", mass=2.0, inertia=HUB_INERTIA, center_of_mass=(0.03, 0.01, 0.02),
                    points={"out": (0.15, 0.1, 0.05)}),
        Revolute(name="yaw", parent=None, child="hub", axis=(0, 0, 1)),
        SpatialBeam("b", **BEAM, geometric_stiffening=True, second_order_inertia=second_order,
                    stations={"p": 0.7}),
        Weld(name="mount", parent="hub", child="b", point="out")], gravity=(0.5, 0.2, -9.81))
    cut = SpatialCutJoint(name="pin", parent=None, point=(0.9, 0.3, -0.2), child="b", child_point=station)
    return SpatialKinematicLoopModel(tree, [cut], baumgarte=BAUMGARTE)


def state() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    q = np.concatenate([[0.4], [0.05, -0.01, 0.04, 0.008, 0.02]])     # yaw, qy1, qy2, qz1, qz2, twist1
    return q, rng.normal(size=6) * 0.5


def hand_shortening(beam: SpatialBeam, eta: np.ndarray, x_end: float) -> float:
    """``1/2 int_0^x_end |w'|^2 dx`` [m]: slopes by central differences of ``Phi(x) eta`` (the beam's shapes at all
    stations at once: the ``Phi`` of a station, without its ``G1``), Simpson's rule."""
    x = np.linspace(0.0, x_end, 2001)
    step = 1e-6
    ahead, behind = np.minimum(x + step, beam.length), np.maximum(x - step, 0.0)

    def deflection(s: np.ndarray) -> np.ndarray:
        return np.einsum("rnk,n->kr", beam.data.shapes(s)[1:], eta)   # the transverse rows y, z at each station

    slopes = (deflection(ahead) - deflection(behind)) / (ahead - behind)[:, None]
    return 0.5 * scipy.integrate.simpson(np.sum(slopes ** 2, axis=1), x=x)


@pytest.mark.parametrize("station, x_end", [("tip", BEAM["length"]), ("p", 0.7)])
def test_the_cut_point_moves_by_the_shortening_of_the_bent_axis(station, x_end):
    second, first = loop(True, station), loop(False, station)
    q, v = state()
    beam = next(b for b in second.tree.bodies if b.name == "b")
    eta = q[1:]
    shortening = hand_shortening(beam, eta, x_end)
    assert shortening > 1e-4                                    # a bend that matters at the cut's tolerance
    gap = second.constraints(q, v)[0] - first.constraints(q, v)[0]       # shortened minus unshortened point
    assert np.linalg.norm(gap) == pytest.approx(shortening, rel=1e-6)
    # its rate: d/dt of the shortening along the motion (q' = v here: a revolute angle and modal coordinates)
    h = 1e-6
    rate = (second.constraints(q + h * v, v)[0] - second.constraints(q - h * v, v)[0]) / (2 * h)
    np.testing.assert_allclose(second.constraints(q, v)[1], rate, rtol=0.0, atol=1e-8)


@pytest.mark.parametrize("station", ["tip", "p"])
def test_the_closed_loop_accelerations_hold_the_shortened_point(station):
    model = loop(True, station)
    q, v = state()
    acceleration, _ = model.solve(q, v)
    phi, phi_dot = model.constraints(q, v)
    h = 1e-6
    ahead = model.constraints(q + h * v + 0.5 * h * h * acceleration, v + h * acceleration)[1]
    behind = model.constraints(q - h * v + 0.5 * h * h * acceleration, v - h * acceleration)[1]
    phi_ddot = (ahead - behind) / (2 * h)
    np.testing.assert_allclose(phi_ddot, -2.0 * BAUMGARTE * phi_dot - BAUMGARTE ** 2 * phi, rtol=0.0,
                               atol=2e-6 * np.max(np.abs(acceleration)))


def test_the_planar_cut_point_at_a_modal_beam_station_is_foreshortened():
    """The planar counterpart (:mod:`ctmm.planar.cut_points`, ``foreshortening=True`` by default) already moves an
    interior station by ``-1/2 int_0^x_e w'^2 dx``: checked by hand here (slopes of the beam's own shapes, Simpson)."""
    from ctmm.flexible import ModalBeam
    from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
    from ctmm.planar.closed_loops import CutJoint, KinematicLoopModel

    beam = ModalBeam("beam", length=0.6, bending_stiffness=30.0, mass_per_length=1.5, n_modes=2,
                     outboard={"mid": 0.3, "tip": 0.6}, second_order_inertia=True)
    tree = PlanarModel("station", [Fixed("g", position=(0.0, 0.0)), Fixed("g4", position=(0.55, -0.3)), beam,
                                   SmoothHinge("h1", parent="g", child="beam"),
                                   RigidBody.uniform_link("rocker", mass=0.5, length=0.4),
                                   SmoothHinge("h4", parent="g4", child="rocker")])
    q, modal = np.array([0.0, 0.05, -0.01, 2.2]), np.array([0.05, -0.01])       # beam.theta = 0: the axis is x
    gaps = [KinematicLoopModel(tree, [CutJoint("h3", parent="rocker.out", child="beam.mid")],
                               foreshortening=flag).constraints(q, np.zeros(4))[0] for flag in (True, False)]
    x = np.linspace(0.0, 0.3, 2001)
    hand = 0.5 * scipy.integrate.simpson((modal @ beam.shapes(x, 1)) ** 2, x=x)
    assert gaps[1][0] - gaps[0][0] == pytest.approx(hand, rel=1e-6) and gaps[0][1] == gaps[1][1]
