"""The spatial static-equilibrium search accepts the steps of its fall by the potential energy (issue 14).

``static_equilibrium(..., stable=True)`` falls through unstable directions by capped pseudo-transient steps;
each is taken only if the potential energy at rest (``ctmm.spatial.energy``: gravity, joint springs and laws)
does not rise beyond its round-off, a rising one is retried shorter, and the search is refused -- naming the
steps, the largest acceleration and the energy -- when the energy stalls or the fall goes on without end.

Independent checks: the compound double pendulum's hanging potential written here; a sagging softening spring
whose static force cannot carry the weight has no stable equilibrium (its one equilibrium, far up the
spring, is unstable), by the algebra in the test.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
import ctmm.spatial.dynamics
import ctmm.spatial_fall
from ctmm.nonlinear_laws import CubicSpring
from ctmm.spatial_linearization import retract, static_equilibrium, unstable_directions

MASS, COM, LENGTH, INERTIA, GRAVITY = 1.0, 0.5, 1.0, 0.01, 9.81


def inverted_pendulum() -> sp.SpatialModel:
    """A universal-joint double pendulum standing upright at its neutral configuration."""
    return sp.SpatialModel("double", [
        sp.SpatialBody("a", MASS, (INERTIA,) * 3, center_of_mass=(0, 0, COM), points={"tip": (0, 0, LENGTH)}),
        sp.SpatialBody("b", MASS, (INERTIA,) * 3, center_of_mass=(0, 0, COM)),
        sp.Universal(name="j1", parent=None, child="a", axis1=(1, 0, 0), axis2=(0, 1, 0)),
        sp.Universal(name="j2", parent="a", point="tip", child="b", axis1=(1, 0, 0), axis2=(0, 1, 0))],
        gravity=(0, 0, -GRAVITY))


def tilted(model: sp.SpatialModel) -> np.ndarray:
    tilt = np.zeros(model.n_velocities)
    tilt[0] = 0.05
    return retract(model, model.neutral(), tilt)[0]


def test_an_inverted_start_falls_to_the_hanging_equilibrium_through_falling_energy():
    model = inverted_pendulum()
    q = static_equilibrium(model, start=tilted(model), stable=True)
    assert unstable_directions(model, q)[0].size == 0
    hanging = -MASS * GRAVITY * COM - MASS * GRAVITY * (LENGTH + COM)        # both links straight down [J]
    assert float(sp.energy(model, q, np.zeros(model.n_velocities))) == pytest.approx(hanging, rel=1e-9)


def test_a_fall_whose_energy_cannot_fall_is_refused_as_stalled(monkeypatch):
    model = inverted_pendulum()
    true_energy = ctmm.spatial.dynamics.energy
    # the search is told an energy that rises as the pendulum falls (minus the true one): no step is a descent
    monkeypatch.setattr(ctmm.spatial.dynamics, "energy", lambda *args, **kwargs: -true_energy(*args, **kwargs))
    with pytest.raises(ctmm.ModelError, match=r"the fall stalled .* in 30 steps in a row\) after \d+ steps of the fall "
                                              r".*largest acceleration .*potential energy -1\.9\d*e\+01 J"):
        static_equilibrium(model, start=tilted(model), stable=True)


def sagging_spring() -> sp.SpatialModel:
    """1 kg on a vertical slide held by a softening spring ``10 d - 10 d^3`` [N]: its largest upward force on the
    way down, ``(2/3) 10 sqrt(10 / 30) = 3.85 N``, is below the weight 9.81 N, so the only equilibrium is up the
    spring, at ``10 d - 10 d^3 = -9.81`` (``d^3 - d - 0.981 = 0``: one real root, ``d = 1.32 m``), where its
    tangent ``10 - 30 d^2 < 0``: unstable; no stable equilibrium."""
    return sp.SpatialModel("sagging", [
        sp.SpatialBody("a", 1.0, (0.1, 0.1, 0.1)),
        sp.Prismatic(name="slide", parent=None, child="a", axis=(0, 0, 1), law=CubicSpring(10.0, -10.0))],
        gravity=(0, 0, -GRAVITY))


def test_a_model_without_a_stable_equilibrium_is_refused_as_an_endless_fall(monkeypatch):
    monkeypatch.setattr(ctmm.spatial_fall, "FALL_GUARD", 0.2)             # 41 fall steps (4101 by default)
    with pytest.raises(ctmm.ModelError, match=r"the fall goes on and on .* after 42 steps of the fall through "
                                              r"unstable directions \(largest acceleration .*potential energy -\d"):
        static_equilibrium(sagging_spring(), stable=True)
