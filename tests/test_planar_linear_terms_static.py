"""The static sweep of PlanarScene.linear_terms on rigid trees (the traced rigid sweep) against the numpy
articulated sweep on the same terms, and against the Lagrange model's accelerations.

Off equilibrium (so every acceleration and wrench is non-zero): a free base carrying a two-ended body, a
spring-damper hinge, a driven hinge with a prescribed acceleration, a point load and gravity.
"""
from __future__ import annotations

import re

import numpy as np
import pytest

from ctmm.articulated import articulated_sweep
from ctmm.errors import ModelError
from ctmm.ops import NUMPY
from ctmm.planar import DrivenHinge, FreeBase, Load, Pinned, PlanarModel, RigidBody, SpringDamperHinge
from ctmm.planar.body_forms import PlanarScene
from ctmm.reference.planar_lagrange import PlanarLagrange


def tree() -> PlanarModel:
    return PlanarModel("tree", [
        FreeBase("base", child="b0"),
        RigidBody("b0", mass=1.5, inertia=0.2, center_of_mass=(0.3, 0.1), outboard={"e0": (0.8, 0.2), "e1": (0, 1)}),
        SpringDamperHinge("h1", parent="b0.e0", child="b1", stiffness=4.0, damping=0.3, rest_angle=0.2),
        RigidBody("b1", mass=0.7, inertia=0.05, center_of_mass=(0.35, -0.05),
                  loads=(Load(point=(0.2, 0.0), force_x=0.4, force_y=-1.1, moment=0.3),)),
        DrivenHinge("h2", parent="b0.e1", child="b2", angle=lambda t: 0.1 + 0.5 * t * t,
                    rate=lambda t: t, acceleration=1.0),
        RigidBody.uniform_link("b2", mass=0.2, length=0.3),
    ], gravity=(0.0, -9.81))


def test_rigid_static_sweep_equals_the_numpy_sweep_on_the_same_terms():
    model = tree()
    scene = PlanarScene(model)
    q = np.array([0.1, -0.2, 0.4, -0.3])
    bodies, joints = scene.terms(NUMPY, q[None, :, None], np.zeros((1, 4, 1)), 0.7)
    numpy_sweep = articulated_sweep(NUMPY, scene.tree, bodies, joints)
    residual, force = scene._static(bodies, joints)
    accelerations = np.abs(scene.coordinate_accelerations(numpy_sweep)).max()
    assert accelerations > 1.0 and abs(residual - accelerations) <= 1e-13 * accelerations
    scale = max(np.abs(f).max() for f in numpy_sweep.force)            # the free base's wrench is zero
    assert scale > 1.0
    for mine, reference in zip(force, numpy_sweep.force):
        np.testing.assert_allclose(mine, reference[0], rtol=0, atol=1e-13 * scale)


def test_rigid_static_residual_is_the_lagrange_acceleration():
    model = PlanarModel.chain("pend", [Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=1.0),
                                       SpringDamperHinge("h", stiffness=3.0, damping=0.1),
                                       RigidBody.uniform_link("b", mass=0.5, length=0.8)], gravity=(0.0, -9.81))
    q = np.array([-1.2, -0.9])
    expected = np.abs(PlanarLagrange(model).accelerations(q, np.zeros(2))).max()
    with pytest.raises(ModelError, match=re.escape(f"largest acceleration {expected:.3e}")):
        PlanarScene(model).linear_terms(q)
