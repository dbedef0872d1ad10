"""The spatial static-equilibrium search finds the hanging equilibrium of a long chain started upright (issue 14).

A sprung revolute chain (axes z, y, x in turn) standing along +x in gravity along -x with a sideways part
falls through ~N/2 unstable directions before it hangs; the capped pseudo-transient fall needs more steps than
the Newton budget (``NEWTON_ITERATIONS``: the search refused it before it had its own budget).  Independent
check: the global Newton-Euler reference (``ctmm/reference/spatial_tree.py``) certifies the point found as an
equilibrium (its residual generalised force below its own bound) whose stiffness ``K`` is positive definite.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm.spatial as sp
from ctmm.reference import spatial_tree as ref
from ctmm.spatial_linearization import static_equilibrium

AXES = ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0))
INERTIA = (0.002, 0.014, 0.014)


def upright_chain(n: int, gravity: tuple) -> sp.SpatialModel:
    elements: list = []
    for j in range(n):
        elements.append(sp.SpatialBody(f"link{j}", 1.0, INERTIA, center_of_mass=(0.2, 0.0, 0.0),
                                       points={"tip": (0.4, 0.0, 0.0)}))
        elements.append(sp.Revolute(name=f"j{j}", parent=None if j == 0 else f"link{j - 1}", child=f"link{j}",
                                    point=(0.0, 0.0, 0.0) if j == 0 else "tip", axis=AXES[j % 3],
                                    stiffness=50.0, damping=0.2))
    return sp.SpatialModel(f"upright_chain{n}", elements, gravity=gravity)


def reference_chain(n: int, gravity: tuple) -> ref.SpatialTree:
    return ref.SpatialTree([ref.SpatialBody(f"link{j}", j - 1, "revolute", 1.0, np.array([0.2, 0.0, 0.0]),
                                            np.diag(INERTIA), axes=np.array([AXES[j % 3]]),
                                            joint_position=np.array([0.0 if j == 0 else 0.4, 0.0, 0.0]),
                                            stiffness=50.0, damping=0.2) for j in range(n)],
                           gravity=np.array(gravity))


@pytest.mark.slow
def test_long_upright_chain_falls_to_a_certified_stable_equilibrium():
    # 20 links in 30x the benchmark's gravity (-9.81, 0, -0.5): the fall alone takes > 200 steps (~3 s; the
    # benchmark's own chain needs N >= 80 for that, ~15 s)
    n, gravity = 20, (-294.3, 0.0, -15.0)
    q = static_equilibrium(upright_chain(n, gravity), stable=True)
    tree = reference_chain(n, gravity)
    mass, _, stiffness = ref.linearize(tree, q)              # refuses a q that is not an equilibrium
    assert np.max(np.abs(ref.forward_dynamics(tree, q, np.zeros(n)))) < 1e-6
    assert np.min(np.linalg.eigvalsh(0.5 * (stiffness + stiffness.T))) > 0.0   # statically stable
    assert np.max(np.abs(q)) > 2.0                           # it did fall (the upright start is q = 0)

