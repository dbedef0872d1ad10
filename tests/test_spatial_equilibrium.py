"""The default operating point of the spatial linear verbs is a statically stable equilibrium.

A spatial double pendulum (spherical or universal joints) whose neutral configuration is upright: the
pseudo-transient search alone stays on the inverted equilibrium (its accelerations vanish there);
``static_equilibrium(..., stable=True)`` -- the default of ``ctmm.linearize`` and the frequency verbs --
falls to the hanging one, or refuses naming the directions of negative stiffness.

Independent reference: the compound double pendulum in one vertical plane, ``M theta'' + K theta = 0``
with ``M = [[m1 c1^2 + I1 + m2 L1^2, m2 L1 c2], [m2 L1 c2, m2 c2^2 + I2]]`` and
``K = +-g diag(m1 c1 + m2 L1, m2 c2)`` (+ hanging, - upright); the spatial model swings alike in two
perpendicular planes, and a spherical joint adds a free twist (zero frequency).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm import spatial_linearization
from ctmm.spatial_linearization import static_equilibrium, unstable_directions

MASS, COM, LENGTH, INERTIA, GRAVITY = 1.0, 0.5, 1.0, 0.01, 9.81


def double_pendulum(joint: str) -> sp.SpatialModel:
    """Two equal links, centres of mass above their joints at the neutral configuration (upright)."""
    links = [sp.SpatialBody("a", MASS, (INERTIA,) * 3, center_of_mass=(0, 0, COM), points={"tip": (0, 0, LENGTH)}),
             sp.SpatialBody("b", MASS, (INERTIA,) * 3, center_of_mass=(0, 0, COM))]
    if joint == "spherical":
        joints = [sp.Spherical(name="j1", parent=None, child="a"),
                  sp.Spherical(name="j2", parent="a", point="tip", child="b")]
    else:
        joints = [sp.Universal(name="j1", parent=None, child="a", axis1=(1, 0, 0), axis2=(0, 1, 0)),
                  sp.Universal(name="j2", parent="a", point="tip", child="b", axis1=(1, 0, 0), axis2=(0, 1, 0))]
    return sp.SpatialModel("double", links + joints, gravity=(0, 0, -GRAVITY))


def planar_squares() -> np.ndarray:
    """``omega^2`` [rad^2/s^2] of the hanging compound double pendulum in one plane (ascending)."""
    mass = np.array([[MASS * COM ** 2 + INERTIA + MASS * LENGTH ** 2, MASS * LENGTH * COM],
                     [MASS * LENGTH * COM, MASS * COM ** 2 + INERTIA]])
    stiffness = GRAVITY * np.diag([MASS * COM + MASS * LENGTH, MASS * COM])
    return np.sort(np.linalg.eigvals(np.linalg.solve(mass, stiffness)).real)


def potential(model: sp.SpatialModel, q: np.ndarray) -> float:
    """Gravitational energy [J] at rest (``ctmm.spatial.energy``, no springs here)."""
    return float(sp.energy(model, q, np.zeros(model.n_velocities)))


HANGING_POTENTIAL = -MASS * GRAVITY * COM - MASS * GRAVITY * (LENGTH + COM)   # both links straight down [J]


@pytest.mark.parametrize("joint", ["spherical", "universal"])
def test_default_operating_point_hangs(joint):
    model = double_pendulum(joint)
    linear = ctmm.linearize(model)
    eigenvalues = np.linalg.eigvals(linear.state_space.A)
    assert np.max(np.abs(eigenvalues.real)) <= 1e-9
    squares = np.sort(np.abs(eigenvalues.imag)) ** 2
    expected = np.repeat(planar_squares(), 4)                     # two planes, +- i omega
    if joint == "spherical":
        expected = np.concatenate([np.zeros(4), expected])          # the two free twists
    assert np.allclose(squares, expected, rtol=1e-9, atol=1e-9)
    assert unstable_directions(model, linear.operating_point.q)[0].size == 0
    assert potential(model, linear.operating_point.q) == pytest.approx(HANGING_POTENTIAL, rel=1e-9)
    omegas = ctmm.natural_frequencies(model, n_modes=len(expected) // 2)
    assert np.allclose(omegas ** 2, np.sort(expected[::2]), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("joint", ["spherical", "universal"])
def test_near_upright_the_plain_search_stays_inverted_and_the_stable_search_falls(joint):
    model = double_pendulum(joint)
    tilt = np.zeros(model.n_velocities)
    tilt[0] = 1e-6
    start = spatial_linearization.retract(model, model.neutral(), tilt)[0]
    upright = static_equilibrium(model, start=start)
    values, vectors = unstable_directions(model, upright)
    assert np.allclose(np.sort(values), np.sort(-np.repeat(planar_squares(), 2)), rtol=1e-7)
    assert vectors.shape == (model.n_velocities, 4)
    hanging = static_equilibrium(model, start=start, stable=True)
    assert unstable_directions(model, hanging)[0].size == 0
    assert potential(model, upright) == pytest.approx(-HANGING_POTENTIAL, rel=1e-9)
    assert potential(model, hanging) == pytest.approx(HANGING_POTENTIAL, rel=1e-9)


def test_no_stable_equilibrium_reached_is_refused_naming_the_directions(monkeypatch):
    model = double_pendulum("spherical")
    monkeypatch.setattr(spatial_linearization, "STABLE_RESTARTS", 0)
    with pytest.raises(ctmm.ModelError, match=r"negative stiffness .*j1\.r"):
        static_equilibrium(model, stable=True)
    with pytest.raises(ctmm.ModelError, match="stable"):
        static_equilibrium(model, stable="yes")
