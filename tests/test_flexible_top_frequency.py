"""Why the planar flexible pendulum's top linearised frequency falls from ~920 to 426 rad/s when the first-order
modal beam is bent by q1 = 0.02, but not with ``second_order_inertia`` (docs/flexible.md §1.3.1, "The top linearised
frequency of a bent beam").

* The library's tangent is right: the independent Lagrange model (:mod:`ctmm.reference.flexible_lagrange`, its
  equations differentiated here by central differences) has the same top frequency at both points.
* The top mode is the arm's rotation against its own three modes: the clamped-free shapes nearly span the rigid
  rotation field, so the arm's rotary inertia left over after the modal coordinates (a Schur complement of the mass
  matrix) is only 1.7e-4 of its 0.12 kg m^2, and the mode's frequency scales with one over its square root.
* The first-order beam carries its mass points on lines normal to the undeformed axis, so bending adds
  ``sum dm w^2 = q1^2`` (unit modal mass) = 4e-4 kg m^2 to the arm's rotary inertia: the leftover inertia triples
  and the top frequency halves.  With the shortening (``second_order_inertia``) the points move back along the axis,
  the inertia changes by -8e-5 and the leftover inertia and the top frequency stay.  A truncation mode, not a
  physical vibration (its frequency is set by how well three shapes span a rotation: 460 rad/s with two modes).
"""
from __future__ import annotations

import numpy as np

import ctmm
from ctmm.flexible import ModalBeam
from ctmm.flexible.beam import ModalForce
from ctmm.planar import Fixed, PlanarModel, RigidBody, SmoothHinge
from ctmm.reference.flexible_lagrange import FlexibleLagrange

from test_flexible_second_order import RHO_A

INPUTS = ["h1.torque", "h2.torque", "arm.q1.force", "arm.q2.force", "arm.q3.force"]
TORQUES = np.array([[1.0, -1.0, 0, 0, 0], [0, 1.0, 0, 0, 0], [0, 0, 1.0, 0, 0], [0, 0, 0, 1.0, 0], [0, 0, 0, 0, 1.0]])
"""Generalised forces of unit ``INPUTS`` (``h2`` turns the arm against the crank)."""


def pendulum(second_order: bool, preload: float = 0.0) -> PlanarModel:
    """The crank + 3-mode beam of ``test_flexible_second_order._pendulum``, with a constant modal force on q1 [N]."""
    hooks = [ModalForce(force=lambda t: np.array([preload, 0.0, 0.0]))] if preload else []
    beam = ModalBeam("arm", length=0.6, bending_stiffness=6.0, mass_per_length=RHO_A, n_modes=3,
                     second_order_inertia=second_order, modal_forces=hooks)
    return PlanarModel("flexible_pendulum", [
        Fixed("g", position=(0.0, 0.0)),
        RigidBody.uniform_link("crank", mass=0.4, length=0.2), SmoothHinge("h1", parent="g", child="crank"),
        beam, SmoothHinge("h2", parent="crank", child="arm")], gravity=(0.0, -9.81))


def top(matrix: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(matrix).imag)))


def reference_tangent(reference: FlexibleLagrange, q: np.ndarray, mass: np.ndarray | None = None) -> np.ndarray:
    """``[[0, I], [da/dq, da/dqdot]]`` of the reference's accelerations at ``(q, 0)`` (central differences); with
    ``mass``, the accelerations ``mass^-1 b`` of the reference's right-hand side ``b``."""
    n = len(q)

    def acceleration(x: np.ndarray, v: np.ndarray) -> np.ndarray:
        matrix, b, *_ = reference._system(x, v, 0.0)
        return np.linalg.solve(matrix if mass is None else mass, b)

    tangent = np.zeros((2 * n, 2 * n))
    tangent[:n, n:] = np.eye(n)
    for k in range(n):
        e = np.zeros(n)
        e[k] = 1e-6
        tangent[n:, k] = (acceleration(q + e, 0 * q) - acceleration(q - e, 0 * q)) / 2e-6
        tangent[n:, n + k] = (acceleration(q, e) - acceleration(q, -e)) / 2e-6
    return tangent


def library(model: PlanarModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The library's tangent at ``(q, 0)`` and its mass matrix (from the input matrix: ``M = T B^-1``)."""
    n = len(q)
    lin = ctmm.linearize(model, operating_point=(q, np.zeros(n)), allow_nonequilibrium=True, inputs=INPUTS)
    return np.asarray(lin.state_space.A), TORQUES @ np.linalg.inv(np.asarray(lin.state_space.B)[n:])


def leftover(mass: np.ndarray) -> float:
    """The arm's rotary inertia beyond its modal coordinates [kg m^2] (Schur complement)."""
    return float(mass[1, 1] - mass[1, 2:] @ np.linalg.solve(mass[2:, 2:], mass[2:, 1]))


def test_first_order_tangent_equals_the_independent_lagrange_linearisation():
    """The closing note's points (crank at 0.3 rad, at rest): 922 and 426 rad/s from both."""
    model = pendulum(False)
    reference = FlexibleLagrange(model)
    tops = []
    for bend in (0.0, 0.02):
        q = np.array([0.3, 0.0, bend, 0.0, 0.0])
        tangent, _ = library(model, q)
        tops.append(top(tangent))
        assert abs(tops[-1] - top(reference_tangent(reference, q))) < 1e-5 * tops[-1]
    assert 900 < tops[0] < 940 and 410 < tops[1] < 440, tops


def test_the_bent_first_order_beam_adds_rotary_inertia_the_shortening_removes():
    """Hanging, at rest: the first-order arm's inertia grows by exactly q1^2 (the reference's mass matrix, and the
    library's equal to it); its leftover inertia triples (1.7e-4 -> 5.7e-4 kg m^2) and the top frequency halves
    (964 -> 450 rad/s), while with the second-order inertia both stay (1.74e-4, 958 rad/s)."""
    bend = 0.02
    straight, bent = (np.array([-np.pi / 2, -np.pi / 2, b, 0.0, 0.0]) for b in (0.0, bend))
    first = pendulum(False)
    reference = FlexibleLagrange(first)
    masses = [reference._system(q, 0 * q, 0.0)[0] for q in (straight, bent)]
    assert abs(masses[1][1, 1] - masses[0][1, 1] - bend ** 2) < 1e-9
    (tangent_straight, mass_straight), (tangent_bent, mass_bent) = (library(first, q) for q in (straight, bent))
    for own, independent in ((mass_straight, masses[0]), (mass_bent, masses[1])):
        assert np.max(np.abs(own - independent)) < 1e-8
    assert 1.6e-4 < leftover(masses[0]) < 1.9e-4 and 5.5e-4 < leftover(masses[1]) < 6.0e-4
    assert top(tangent_bent) < 0.5 * top(tangent_straight)
    second = pendulum(True)
    (tangent_straight, mass_straight), (tangent_bent, mass_bent) = (library(second, q) for q in (straight, bent))
    assert -1e-4 < mass_bent[1, 1] - mass_straight[1, 1] < 0.0                      # measured -7.7e-5
    assert abs(leftover(mass_bent) / leftover(mass_straight) - 1.0) < 0.02
    assert top(tangent_bent) > 0.98 * top(tangent_straight)


def test_the_straight_beams_inertia_restores_the_top_frequency_at_a_bent_equilibrium():
    """A modal force holds the first-order beam bent by q1 = 0.02 in a true equilibrium: the top frequency is 510
    rad/s (library and reference); the reference's equations with the mass matrix of the straight beam at the same
    angles (the stiffness unchanged) give 949 rad/s, the straight beam's 964: the inertia is the cause."""
    model = pendulum(False, preload=7.0)
    lin = ctmm.linearize(model)
    q = np.asarray(lin.operating_point.q)
    assert abs(q[2] - 0.02) < 1e-3 and lin.operating_point.equilibrium
    reference = FlexibleLagrange(model)
    bent = top(np.asarray(lin.state_space.A))
    assert abs(bent - top(reference_tangent(reference, q))) < 1e-5 * bent
    unbent = q.copy()
    unbent[2:] = 0.0
    mass = reference._system(unbent, 0 * q, 0.0)[0]
    restored = top(reference_tangent(reference, q, mass))
    assert bent < 550 and 920 < restored < 980, (bent, restored)
