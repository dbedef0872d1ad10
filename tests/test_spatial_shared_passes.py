"""Passes shared or skipped for speed give the numbers of the full computations, to the bit.

* ``SpatialScene.terms(..., kinematics_only=True)`` (poses for sensors, energy, recorders): the same body states
  as the full terms, rigid bodies' terms not formed;
* the equilibrium search's position Jacobian without the velocity columns: the same ``df/dr``;
* the Newton-Euler reference's ``forward_dynamics`` / ``inverse_dynamics`` on one kinematics pass for ``M`` and
  ``h``: the same values as ``M`` and ``h`` each from its own pass.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

from ctmm.ops import NUMPY
from ctmm.reference import spatial_tree as ref
from ctmm.scenarios import flexible_manipulator_3d
from ctmm.spatial.body_forms import SpatialScene
from ctmm.spatial_linearization import _position_jacobian

from test_spatial_equilibrium_long import reference_chain, upright_chain


def test_kinematics_only_gives_the_states_of_the_full_terms():
    model = flexible_manipulator_3d.plant(gravity=(0.0, 0.0, -9.81))       # rigid bodies, a beam, welds
    scene = SpatialScene(model)
    rng = np.random.default_rng(7)
    q = rng.normal(size=(3, model.n_positions)) * 0.3
    v = rng.normal(size=(3, model.n_velocities))
    full_bodies, _, full = scene.terms(NUMPY, q, v, 0.2)
    bodies, _, states = scene.terms(NUMPY, q, v, 0.2, kinematics_only=True)
    for a, b in zip(full, states):
        for field in ("rotation", "origin", "velocity", "omega", "inboard"):
            np.testing.assert_array_equal(np.asarray(getattr(a, field)), np.asarray(getattr(b, field)))
    for body, modal, terms in zip(model.bodies, model.modal, bodies):
        assert (terms is None) == (modal is None), body.name      # a beam's terms carry its points' frames


def test_position_jacobian_without_velocity_columns_is_the_same():
    model = upright_chain(6, (-9.81, 0.0, -0.5))
    rng = np.random.default_rng(2)
    q, v = rng.normal(size=model.n_positions), np.zeros(model.n_velocities)
    full, rate = _position_jacobian(model, q, v, 0.0)
    alone, none = _position_jacobian(model, q, v, 0.0, velocities=False)
    np.testing.assert_array_equal(alone, full)
    assert none is None and rate.shape == full.shape


def test_reference_dynamics_on_one_kinematics_pass_are_unchanged():
    tree = reference_chain(6, (-9.81, 0.0, -0.5))
    rng = np.random.default_rng(5)
    for _ in range(3):
        q, v, vdot, tau = (rng.normal(size=tree.nv) for _ in range(4))
        mass, bias = ref.mass_matrix(tree, q), ref.bias_forces(tree, q, v, 0.0)   # each from its own pass
        np.testing.assert_array_equal(ref.mass_matrix(tree, q, ref.kinematics(tree, q, v)), mass)
        np.testing.assert_array_equal(ref.forward_dynamics(tree, q, v, tau),
                                      scipy.linalg.cho_solve(scipy.linalg.cho_factor(mass), tau - bias))
        np.testing.assert_array_equal(ref.inverse_dynamics(tree, q, v, vdot), mass @ vdot + bias)
