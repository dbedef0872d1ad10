"""The articulated sweep in two halves (ctmm.articulated: articulated_inward, articulated_outward), as the
segment fold uses them (ctmm.segment_fold hands the base-to-tip half only the elimination's terms and the
points' kinematics): checked against the independent Lagrange model."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ctmm.articulated import articulated_inward, articulated_outward
from ctmm.ops import NUMPY
from ctmm.planar.body_forms import PlanarScene
from ctmm.reference.planar_lagrange import PlanarLagrange
from planar_helpers import random_state, random_tree


@pytest.mark.parametrize("seed", [0, 3])
def test_the_outward_half_reads_no_inertia_bias_or_wrench_map_and_equals_lagrange(seed) -> None:
    """The base-to-tip half on bodies stripped of ``M``, ``h`` and ``RF`` (it may not read them: the fold
    does not hand them on) gives the accelerations of the Lagrange model of random trees (every hinge
    kind, loads, driven joints)."""
    model = random_tree(seed, 5)
    scene = PlanarScene(model)
    q, v, t = random_state(model, seed)
    bodies, joints = scene.terms(NUMPY, q[None, :, None], v[None, :, None], t)
    inward = articulated_inward(NUMPY, scene.tree, bodies, joints)
    stripped = [dataclasses.replace(body, M=None, h=None, RF={}) for body in bodies]
    solution = articulated_outward(NUMPY, scene.tree, stripped, joints, inward)
    got = scene.coordinate_accelerations(solution)[0]
    expected = PlanarLagrange(model).accelerations(q, v, t)
    assert np.max(np.abs(got - expected)) <= 1e-12 * np.max(np.abs(expected))
