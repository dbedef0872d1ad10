"""The shared vector checks of ctmm.validation (``vector``, ``unit_vector``) as the spatial, planar and finite-element
constructors use them, and the scenario's ``dae_of`` carrying a prismatic cut's roll reference to the independent DAE."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm.spatial as sp
from ctmm import validation
from ctmm.errors import ModelError
from ctmm.fem import SpatialBeamElement
from ctmm.planar import RigidBody
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel
from spatial_loop_helpers import dae_of, poses, rod


def test_vector_returns_the_components_and_refuses_other_sizes_naming_parameter_value_and_unit():
    assert validation.vector("p", (1, 2, 3)).tolist() == [1.0, 2.0, 3.0]
    assert validation.vector("p", [0.5, -1.0], 2).dtype == float
    given = np.array([1.0, 2.0, 3.0])
    kept = validation.vector("p", given)
    given[0] = 9.0
    assert kept[0] == 1.0                                       # a copy: the caller's array may change later
    with pytest.raises(ModelError, match=r"p must be a 3-vector \(3 finite numbers\) \[m\], got \(1, 2\) "
                                         r"\(shape \(2,\)\)"):
        validation.vector("p", (1, 2), unit="m")
    with pytest.raises(ModelError, match="p must contain only finite values"):
        validation.vector("p", (1.0, np.inf, 0.0))
    with pytest.raises(ModelError, match="boolean"):
        validation.vector("p", (1.0, True, 0.0))


def test_unit_vector_normalises_and_refuses_a_zero_direction():
    assert np.allclose(validation.unit_vector("a", (0.0, 3.0, 4.0)), [0.0, 0.6, 0.8])
    with pytest.raises(ModelError, match=r"a must be a non-zero 3-vector \(it is normalised\), got \(0, 0, 0\)"):
        validation.unit_vector("a", (0, 0, 0))
    with pytest.raises(ModelError, match="a must be a 3-vector"):
        validation.unit_vector("a", (1.0, 0.0))


@pytest.mark.parametrize("make, words", [
    (lambda: sp.Prismatic(name="j", parent=None, child="b", axis=(0.0, 0.0, 0.0)), ["j: axis", "non-zero 3-vector"]),
    (lambda: sp.Revolute(name="j", parent=None, child="b", point=(0.0, 1.0)), ["j: point (ground location)",
                                                                              "3-vector", "[m]"]),
    (lambda: SpatialCutJoint(name="c", parent=None, child="b", axis=(0, 0, 0)), ["'c': axis", "non-zero"]),
    (lambda: SpatialCutJoint(name="c", parent=None, child="b", point=(1.0,)), ["point (ground location)", "[m]"]),
    (lambda: SpatialCutJoint(name="c", parent=None, child="b", kind="prismatic", normal=(0, 0, 0)),
     ["'c': normal", "non-zero"]),
    (lambda: SpatialBeamElement("e", "a", "b", 1.0, 1.0, 1.0, 1.0, 1.0, orientation=(0, 0, 0)),
     ["e: orientation", "non-zero"]),
    (lambda: sp.SpatialModel("m", [], gravity=(0.0, -9.81)), ["gravity must be a 3-vector", "[m/s^2]"]),
    (lambda: RigidBody("b", mass=1.0, inertia=0.1, center_of_mass=(0.0, 0.0, 0.0)),
     ["b: center_of_mass must be a 2-vector", "[m]"]),
])
def test_constructors_refuse_bad_vectors_through_the_shared_checks(make, words):
    with pytest.raises(ModelError) as error:
        make()
    for word in words:
        assert word in str(error.value)


def test_dae_of_passes_the_roll_reference_of_a_prismatic_cut():
    """A sleeve sliding on a swinging rod, its body x kept along the rod's body y (a quarter turn from the default
    roll reference): the independent DAE's own rows vanish on the state ctmm assembled only with both normals."""
    tree = sp.SpatialModel("sleeve", [
        rod("arm", 0.8, 0.6, direction=2),
        sp.Revolute(name="h1", parent=None, child="arm", axis=(1, 0, 0), rotation=np.diag([1.0, -1.0, -1.0])),
        sp.SpatialBody("sleeve", 0.3, np.diag([0.003, 0.002, 0.001]), center_of_mass=(0.02, 0.0, 0.0)),
        sp.Free(name="free", parent=None, child="sleeve")])
    cut = SpatialCutJoint(name="on_arm", parent="arm", child="sleeve", kind="prismatic", axis=(0, 0, 1),
                          normal=(1, 0, 0), parent_normal=(0, 1, 0))
    loop = SpatialKinematicLoopModel(tree, [cut])
    turned = {"free.qw": 0.0, "free.qx": 0.5 ** 0.5, "free.qy": -0.5 ** 0.5}    # sleeve x along world -y at rest
    q, v = loop.consistent_state({"h1.angle": 0.4, "free.z": -0.3, **turned}, {"h1.angle_rate": 1.5, "free.vz": 0.2},
                                 keep=["h1"])
    assert np.max(np.abs(loop.constraints(q, v)[0])) < 1e-12
    dae = dae_of(loop)
    y0 = dae.state(*poses(loop, q, v))
    phi, J, _ = dae.rows(y0)
    assert np.max(np.abs(phi)) < 1e-12 and np.max(np.abs(J @ dae.velocities(y0))) < 1e-12
