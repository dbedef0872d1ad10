"""The compiled frequency sweep's multi-direction variant (``ctmm.compiled_sweep``, issue 13): spatial rigid trees
with universal (k = 2), spherical (k = 3) and free (k = 6) joints beside revolute, prismatic and weld joints.

The kernel must equal the generic numpy sweep to round-off and certify the same frequencies (random trees, gravity
-- the joint coupling ``G``, ``H`` and the universal joints' own stiffness -- and weightless, damped: the complex
variant, undamped: the real one), equal the independent Newton-Euler linearisation of
``ctmm/reference/spatial_tree.py`` to 1e-9, and hand over the frequencies next to an undamped pole that the generic
sweep hands over.  Its pivot certificate on a ``k x k`` block is the generic sweep's rule
(:meth:`ctmm.sweep_response.ArticulatedResponse.pivots_certified`: the smallest singular value against the largest
moduli of the block's terms); the kernel's one-sided Jacobi singular value is checked against numpy's SVD on random
and near-singular blocks.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm.spatial as sp
import ctmm.sweep_response as sweep_module
from ctmm.compiled_sweep import compiler_present, kernel_library
from ctmm.spatial_linearization import operating_point
from spatial_linear_helpers import random_spring_tree
from ctmm.spatial_transfer_response import SpatialSweepResponse
from test_compiled_sweep_spatial import both as both_sweeps, equals_the_generic_sweep_and_the_reference, \
    hands_over_as_the_generic_sweep
from test_spatial_frf_sweep import weightless

pytestmark = pytest.mark.skipif(not compiler_present(), reason="no C compiler: the generic sweep answers")

OMEGA = np.array([0.07, 0.4, 1.3, 3.1, 7.7, 16.0])


def both(model: sp.SpatialModel, point, s: np.ndarray, inputs: list, outputs: list, monkeypatch):
    """:func:`test_compiled_sweep_spatial.both` on a tree the multi-direction variant takes."""
    plant, answer, generic = both_sweeps(model, point, s, inputs, outputs, monkeypatch)
    assert plant.compiled.multi
    return plant, answer, generic


@pytest.mark.parametrize("seed, base, n, damped, gravity", [(11, "universal", 6, True, True),
                                                            (3, "spherical", 7, False, True),
                                                            (7, "universal", 5, False, False),
                                                            (5, "revolute", 7, True, False)])
def test_multi_direction_trees_equal_the_generic_sweep_and_the_newton_euler_reference(seed, base, n, damped,
                                                                                       gravity, monkeypatch):
    model = random_spring_tree(np.random.default_rng(seed), n, base, damped=damped)
    if not gravity:
        model = sp.SpatialModel("weightless", list(model.bodies) + list(model.joints), gravity=(0.0, 0.0, 0.0))
    kernel = equals_the_generic_sweep_and_the_reference(model, monkeypatch)
    assert kernel.multi and {2, 3} <= set(kernel.axis.tolist())             # universal and spherical blocks
    assert kernel.undamped == (not damped)                                  # undamped: the real variant
    assert (kernel.flags != 0).any() == gravity                             # the preload coupling G (and H)


def test_a_free_base_and_complex_s_equal_the_generic_sweep(monkeypatch):
    """A weightless tree on a free joint (a 6 x 6 pivot at the ground; omega = 0 is a pole of its rigid motion),
    body loads, sensors and ``s`` off the imaginary axis."""
    tree = weightless(11, 5)
    joints = list(tree.joints)
    joints[0] = sp.Free(name="j0", parent=None, child="b0", point=np.zeros(3))
    model = sp.SpatialModel("floating", list(tree.bodies) + joints, gravity=(0.0, 0.0, 0.0))
    inputs = ["b2.p1.force_body_y", "b4.moment_z", "b1.origin.force_x", "j1.torque"]
    outputs = ["j2.angle1", "j3.rx", "j0.x", "b4.origin.vy", "b3.p0.z"]
    s = np.concatenate([1j * OMEGA, 0.3 + 1j * OMEGA[:3], [0.0]])
    plant, (G, good), (G_generic, good_generic) = both(model, operating_point(model), s, inputs, outputs, monkeypatch)
    assert plant.compiled.axis[0] == 6
    assert good[:-1].all() and not good[-1] and np.array_equal(good, good_generic)
    scale = np.max(np.abs(G_generic[:-1]), axis=0, keepdims=True)
    assert np.max(np.abs(G[:-1] - G_generic[:-1]) / scale) <= 1e-11


def test_the_pivot_certificate_decides_as_the_generic_sweep(monkeypatch):
    """Undamped, weightless, universal and spherical joints: at an undamped pole (1e-12 from it) and next to it
    (1e-5) the kernel hands over the frequencies the generic sweep hands over and agrees with it at the others."""
    model = weightless(11, 4, damped=False)
    assert SpatialSweepResponse(model, operating_point(model)).compiled.multi
    hands_over_as_the_generic_sweep(model, 4, ["j1.angle", "j0.angle2"], monkeypatch)


def kernel_singular(blocks: np.ndarray, k: int, complex_scalar: bool) -> np.ndarray:
    """The kernel's smallest singular value of each (B, k, k) block."""
    library = kernel_library(6, complex_scalar, multi=True)
    padded = np.zeros((blocks.shape[0], 6, 6), dtype=complex if complex_scalar else float)
    padded[:, :k, :k] = blocks
    out = np.empty(blocks.shape[0])
    library.smallest_singular_values(blocks.shape[0], k, padded.ctypes.data, out.ctypes.data)
    return out


@pytest.mark.parametrize("k", [2, 3, 6])
@pytest.mark.parametrize("complex_scalar", [False, True])
def test_the_jacobi_singular_value_equals_numpys_and_decides_alike(k, complex_scalar):
    """Random blocks with a prescribed smallest singular value from 1 down to 1e-15 of the largest (the
    certificate's bound 1e-6 straddled by 1e-3 either side), scaled over 12 decades: the kernel's value equals
    numpy's SVD to round-off of the largest, and the certificate's decision is numpy's; a non-finite block is
    never certified."""
    rng = np.random.default_rng(k + 10 * complex_scalar)
    blocks, expected = [], []
    ratios = [1.0, 0.3, 1e-3, 1e-6 * (1 + 1e-3), 1e-6 * (1 - 1e-3), 1e-9, 1e-15, 0.0]
    for ratio in ratios * 6:
        def orthonormal() -> np.ndarray:
            a = rng.normal(size=(k, k)) + (1j * rng.normal(size=(k, k)) if complex_scalar else 0.0)
            return np.linalg.qr(a)[0]
        sigma = np.sort(rng.uniform(0.5, 2.0, k))[::-1]
        sigma[-1] = ratio * sigma[0]
        blocks.append(10.0 ** rng.uniform(-6, 6) * (orthonormal() * sigma) @ orthonormal().conj().T)
    blocks = np.array(blocks)
    numpy_values = sweep_module.smallest_singular(blocks)
    values = kernel_singular(blocks, k, complex_scalar)
    largest = np.linalg.svd(blocks, compute_uv=False)[:, 0]
    assert np.all(np.abs(values - numpy_values) <= 1e-14 * k * largest)
    scale = np.abs(blocks).max(axis=(1, 2))
    assert np.array_equal(values >= 1e-6 * largest, numpy_values >= 1e-6 * largest)
    assert np.array_equal(values >= 1e-6 * scale, numpy_values >= 1e-6 * scale)
    bad = blocks[:2].copy()
    bad[0, 0, 0], bad[1, -1, -1] = np.nan, np.inf
    assert np.array_equal(kernel_singular(bad, k, complex_scalar), [0.0, 0.0])     # never certified (numpy: raises,
    with pytest.raises(np.linalg.LinAlgError):                                     # the frequency is handed over)
        sweep_module.smallest_singular(bad)
