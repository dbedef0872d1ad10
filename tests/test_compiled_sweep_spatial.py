"""The compiled frequency sweep of ``ctmm.compiled_sweep`` on spatial rigid trees (``d = 6``, issue 13).

Spatial revolute and prismatic joints have one free direction ``S`` (a column of 6 rows, world axes, not a unit
axis): the kernel's ``-2`` joints.  Here the kernel must equal the generic numpy sweep to round-off (random trees,
gravity-loaded -- the joint coupling ``G`` and, below prismatic joints, ``H`` -- and weightless; damped: the complex
variant, undamped: the real one; a held drive), hand over exactly the frequencies the generic sweep hands over
(next to an undamped pole), and equal the independent Newton-Euler linearisation of
``ctmm/reference/spatial_tree.py`` to the bound of ``tests/test_spatial_frf_sweep_gravity.py`` (1e-9).  Joints with
more directions (universal, spherical, free): the multi-direction variant, ``tests/test_compiled_sweep_multi.py``.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
import ctmm.sweep_response as sweep_module
from ctmm.compiled_sweep import compiler_present
from ctmm.spatial_linearization import operating_point, tangent_names
from ctmm.spatial_transfer_response import SpatialSweepResponse
from spatial_linear_helpers import random_spring_tree, reference_configuration, reference_tree
from test_spatial_frf_sweep import SWEEP, assert_close, joint_torques
from test_spatial_frf_sweep_gravity import reference_response

pytestmark = pytest.mark.skipif(not compiler_present(), reason="no C compiler: the generic sweep answers")

ONE_DIRECTION = ("revolute", "prismatic", "revolute", "weld")
OMEGA = np.array([0.07, 0.4, 1.3, 3.1, 7.7, 16.0])


def one_direction_tree(seed: int, n: int, damped: bool, weightless: bool = False) -> sp.SpatialModel:
    """A random branched tree of revolute, prismatic and weld joints (sprung, random axes and joint frames) under
    random gravity (every spring deflected at the equilibrium) or weightless."""
    model = random_spring_tree(np.random.default_rng(seed), n, "revolute", damped=damped, kinds=ONE_DIRECTION)
    if weightless:
        model = sp.SpatialModel("weightless", list(model.bodies) + list(model.joints), gravity=(0.0, 0.0, 0.0))
    return model


def both(model: sp.SpatialModel, point, s: np.ndarray, inputs: list, outputs: list, monkeypatch):
    """``(G, good)`` of the compiled kernel and of the generic sweep (no compiler) on the same plant."""
    plant = SpatialSweepResponse(model, point)
    assert plant.compiled is not None
    answer = plant.response(s, inputs, outputs)
    with monkeypatch.context() as patch:
        patch.setattr(sweep_module, "compiler_present", lambda: False)
        generic = SpatialSweepResponse(model, point)
    assert generic.compiled is None
    return plant, answer, generic.response(s, inputs, outputs)


@pytest.mark.parametrize("seed, n, damped, weightless", [(5, 7, True, False), (8, 6, False, False),
                                                         (11, 6, True, True), (3, 5, False, True)])
def test_kernel_equals_the_generic_sweep_and_the_newton_euler_reference(seed, n, damped, weightless, monkeypatch):
    kernel = equals_the_generic_sweep_and_the_reference(one_direction_tree(seed, n, damped, weightless), monkeypatch)
    assert set(kernel.axis.tolist()) <= {-2, -1} and -2 in kernel.axis         # general directions, welds
    assert kernel.undamped == (not damped)                                      # undamped: the real variant
    assert (kernel.flags[kernel.free] != 0).any() == (not weightless)          # the preload coupling G (and H)


def equals_the_generic_sweep_and_the_reference(model: sp.SpatialModel, monkeypatch):
    """Joint torques to the tangent coordinates at the equilibrium: the kernel certifies every frequency as the
    generic sweep does, equals it to 1e-12 and the Newton-Euler reference to 1e-9 (also through
    ``ctmm.frequency_response``); returns the kernel."""
    point = operating_point(model)
    inputs, forcing = joint_torques(model)
    outputs = list(tangent_names(model))
    plant, (G, good), (G_generic, good_generic) = both(model, point, 1j * OMEGA, inputs, outputs, monkeypatch)
    assert good.all() and np.array_equal(good, good_generic)
    assert np.max(np.abs(G - G_generic)) <= 1e-12 * np.max(np.abs(G_generic))
    expected = reference_response(reference_tree(model), reference_configuration(model, point.q), OMEGA, forcing)
    assert_close(np.moveaxis(G, 0, -1), expected, 1e-9)
    frf = ctmm.frequency_response(model, OMEGA, input=inputs, output=outputs)
    assert frf.info["method"] == SWEEP and frf.info["n_dense_frequencies"] == 0
    assert_close(frf.response, expected, 1e-9)
    return plant.compiled


def test_body_loads_sensors_and_a_held_drive_equal_the_generic_sweep(monkeypatch):
    """Body forces and moments (world and body axes, at points), position and rate sensors, complex ``s`` off the
    axis, and a revolute joint driven by signals (held at zero: the kernel's weld)."""
    model = one_direction_tree(6, 7, True)
    joints = list(model.joints)
    index = [joint.name for joint in joints].index("j3")
    held = joints[index]
    joints[index] = sp.Revolute(name=held.name, parent=held.parent, child=held.child, point=held.point,
                            rotation=held.rotation, axis=held.axis, position=0.0, rate=0.0, acceleration=0.0)
    model = sp.SpatialModel("driven", list(model.bodies) + joints, gravity=model.gravity)
    point = operating_point(model)
    inputs = ["b2.p1.force_body_y", "b4.moment_z", "b1.origin.force_x", "j1.torque"]
    outputs = ["j1.angle", "j1.rate", "b4.origin.vy", "b3.p0.z", "b6.origin.x"]
    s = np.concatenate([1j * OMEGA, 0.3 + 1j * OMEGA[:3]])
    plant, (G, good), (G_generic, good_generic) = both(model, point, s, inputs, outputs, monkeypatch)
    assert plant.compiled.axis[index] == -1 and model.joints[index].driven      # the held drive
    assert good.all() and np.array_equal(good, good_generic)
    scale = np.max(np.abs(G_generic), axis=0, keepdims=True)
    assert np.max(np.abs(G - G_generic) / scale) <= 1e-11


def test_the_pivot_certificate_decides_as_the_generic_sweep(monkeypatch):
    """Undamped, weightless: at an undamped pole (1e-12 from it) and next to it (1e-5) the kernel hands over the
    frequencies the generic sweep hands over and agrees with it at the others."""
    hands_over_as_the_generic_sweep(one_direction_tree(3, 5, False, weightless=True), 3, ["j1.angle", "j3.angle"],
                                    monkeypatch)


def hands_over_as_the_generic_sweep(model: sp.SpatialModel, modes: int, outputs: list, monkeypatch) -> None:
    """From ``j1.torque`` at half, 1 + 1e-12 and 1 + 1e-5 times and twice the first of ``modes`` natural
    frequencies: the kernel certifies ``[True, False, True, True]`` as the generic sweep does and agrees with it
    to 1e-9 at those."""
    first = ctmm.natural_frequencies(model, n_modes=modes)
    first = first[first > 0][0]
    omega = np.array([0.5 * first, first * (1 + 1e-12), first * (1 + 1e-5), 2.0 * first])
    _, (G, good), (G_generic, good_generic) = both(model, operating_point(model), 1j * omega, ["j1.torque"],
                                                   outputs, monkeypatch)
    assert good.tolist() == good_generic.tolist() == [True, False, True, True]
    assert np.max(np.abs(G[good] - G_generic[good])) <= 1e-9 * np.max(np.abs(G_generic[good]))


def test_trees_with_multi_direction_joints_take_the_multi_direction_variant():
    """(Its checks: tests/test_compiled_sweep_multi.py.)  Trees of one-direction joints keep the one-direction
    variant."""
    model = random_spring_tree(np.random.default_rng(11), 5, "universal")
    assert SpatialSweepResponse(model, operating_point(model)).compiled.multi
    model = one_direction_tree(3, 5, False)
    assert not SpatialSweepResponse(model, operating_point(model)).compiled.multi
