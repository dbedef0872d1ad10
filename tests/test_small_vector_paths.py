"""The numpy fast paths of one state (B = 1) in :mod:`ctmm.ops`, :mod:`ctmm.spatial.frames` and the references' cross
product (:mod:`ctmm.reference.spatial_kinematics`) give the values of
independent formulas: ``np.block`` for a tiling grid of blocks, ``np.cross`` for the cross product, the explicit
``[v]x``, scipy's rotation of an axis and an angle; grids that do not tile (an entry broadcast into a wider slot,
numbers, mixed batches or dtypes) keep the general assembly, and the cached axis terms cannot be written."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ctmm.ops import CASADI, NUMPY
from ctmm.spatial.frames import axis_rotation, cross, skew

RNG = np.random.default_rng(7)


@pytest.mark.parametrize("batch", [(1,), (4,), ()])
@pytest.mark.parametrize("dtype", [float, complex])
def test_a_tiling_grid_is_np_block(batch, dtype):
    def random(rows, columns):
        value = RNG.normal(size=batch + (rows, columns))
        return (value + 1j * RNG.normal(size=value.shape)).astype(dtype) if dtype is complex else value

    grid = [[random(3, 3), random(3, 2), random(3, 1)], [random(2, 3), random(2, 2), random(2, 1)]]
    got = NUMPY.block(grid)
    assert got.dtype == np.dtype(dtype)
    np.testing.assert_array_equal(got, np.block(grid))


def test_grids_that_do_not_tile_keep_the_general_assembly():
    a, b = RNG.normal(size=(1, 3, 3)), RNG.normal(size=(1, 3, 3))
    scalar = RNG.normal(size=(1, 1, 1))
    # a 1 x 1 entry broadcasts into the 3 x 3 slot of its row and column
    np.testing.assert_array_equal(NUMPY.block([[a, scalar], [b, a]]),
                                  np.block([[a, np.broadcast_to(scalar, (1, 3, 3))], [b, a]]))
    # Python numbers and a batch-1 constant with a batch-4 entry
    batched = RNG.normal(size=(4, 3, 3))
    np.testing.assert_array_equal(NUMPY.block([[batched, a], [0.0, np.eye(3)[None]]]),
                                  np.block([[batched, np.broadcast_to(a, (4, 3, 3))],
                                            [np.zeros((4, 3, 3)), np.broadcast_to(np.eye(3), (4, 3, 3))]]))
    # mixed dtypes: the result type of both
    complex_block = a * (1 + 1j)
    got = NUMPY.block([[a, complex_block], [complex_block, a]])
    assert got.dtype == np.complex128
    np.testing.assert_array_equal(got, np.block([[a, complex_block], [complex_block, a]]))


def test_a_grid_of_numbers_is_one_float_or_complex_constant():
    """Numbers only (Python or numpy scalars, as the rigid-body terms of one state give): one ``(1, r, c)``
    constant, integers as floats, complex kept; a number first and an array later keeps the general assembly."""
    x, y = np.float64(RNG.normal()), RNG.normal()
    got = NUMPY.block([[x, 0.0, y], [0, 1, np.float64(2.5)]])
    assert got.shape == (1, 2, 3) and got.dtype == np.float64
    np.testing.assert_array_equal(got[0], [[x, 0.0, y], [0.0, 1.0, 2.5]])
    integers = NUMPY.block([[1], [2]])
    assert integers.dtype == np.float64 and integers.shape == (1, 2, 1)
    np.testing.assert_array_equal(integers[0], [[1.0], [2.0]])
    complex_grid = NUMPY.block([[1j * x, 2.0]])
    assert complex_grid.dtype == np.complex128
    np.testing.assert_array_equal(complex_grid, [[[1j * x, 2.0]]])
    batched = RNG.normal(size=(4, 1, 1))
    mixed = NUMPY.block([[x, batched], [0.0, 1.0]])
    assert mixed.shape == (4, 2, 2)
    np.testing.assert_array_equal(mixed[:, 0, 1], batched[:, 0, 0])
    np.testing.assert_array_equal(mixed[:, 1], np.broadcast_to([0.0, 1.0], (4, 2)))
    np.testing.assert_array_equal(mixed[:, 0, 0], np.full(4, x))


def test_a_column_of_arrays_is_concatenated_and_a_grid_is_not_a_column():
    top, bottom = RNG.normal(size=(1, 3, 1)), RNG.normal(size=(1, 2, 1))
    np.testing.assert_array_equal(NUMPY.block([[top], [bottom]]), np.concatenate([top, bottom], axis=1))
    # rows of two entries: a grid, not a column
    a, b, c = (RNG.normal(size=(1, 1, 1)) for _ in range(3))
    np.testing.assert_array_equal(NUMPY.block([[a, b], [c, a]]), np.block([[a, b], [c, a]]))


@pytest.mark.parametrize("batch", [1, 5])
def test_cross_and_skew_are_the_cross_product(batch):
    for dtype in (float, complex):
        a = RNG.normal(size=(batch, 3, 1)).astype(dtype)
        b = RNG.normal(size=(batch, 3, 1)).astype(dtype)
        expected = np.cross(a[..., 0], b[..., 0])[..., None]
        np.testing.assert_allclose(cross(NUMPY, a, b), expected, rtol=1e-15, atol=1e-15)
        np.testing.assert_allclose(skew(NUMPY, a) @ b, expected, rtol=1e-15, atol=1e-15)
        x, y, z = a[:, 0, 0], a[:, 1, 0], a[:, 2, 0]
        zero = np.zeros_like(x)
        np.testing.assert_array_equal(skew(NUMPY, a), np.stack([np.stack([zero, -z, y], -1),
                                                                np.stack([z, zero, -x], -1),
                                                                np.stack([-y, x, zero], -1)], -2))
    a, b = RNG.normal(size=(1, 3, 1)), RNG.normal(size=(batch, 3, 1))     # a constant against a batch
    np.testing.assert_allclose(cross(NUMPY, a, b), np.cross(a[..., 0], b[..., 0])[..., None], rtol=1e-15, atol=1e-15)


def test_axis_rotation_is_the_rotation_of_axis_and_angle_and_its_cached_terms_are_read_only():
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    angles = RNG.normal(size=(3, 1, 1))
    got = axis_rotation(NUMPY, axis, angles)
    expected = Rotation.from_rotvec(angles[:, 0, 0, None] * axis).as_matrix()
    np.testing.assert_allclose(got, expected, atol=1e-15)
    np.testing.assert_allclose(axis_rotation(NUMPY, list(axis), angles[:1]), expected[:1], atol=1e-15)
    got[...] = 0.0                                 # the result is the caller's own array ...
    np.testing.assert_allclose(axis_rotation(NUMPY, axis, angles), expected, atol=1e-15)   # ... the cache unchanged
    import casadi

    angle = casadi.SX.sym("angle")
    symbolic = casadi.Function("R", [angle], [axis_rotation(CASADI, axis, angle)])
    np.testing.assert_allclose(np.array(symbolic(angles[1, 0, 0])), expected[1], atol=1e-15)


@pytest.mark.parametrize("shapes", [((3,), (3,)), ((5, 3), (3,)), ((3,), (4, 3)), ((2, 4, 3), (2, 1, 3)), ((0, 3), (3,))])
@pytest.mark.parametrize("dtype", [float, complex])
def test_the_reference_cross_product_is_np_cross(shapes, dtype):
    """The independent references' cross product (``ctmm.reference.spatial_kinematics.cross``): the values and
    dtype of ``np.cross`` for one pair, broadcast stacks and complex steps."""
    from ctmm.reference.spatial_kinematics import cross as reference_cross

    a, b = (RNG.normal(size=shape).astype(dtype) for shape in shapes)
    if dtype is complex:
        a, b = a + 1j * RNG.normal(size=a.shape), b + 1e-20j
    got = reference_cross(a, b)
    assert got.dtype == np.cross(a, b).dtype
    np.testing.assert_array_equal(got, np.cross(a, b))


@pytest.mark.parametrize("batch", [1, 3])
def test_quaternion_rotation_and_rate_are_scipys(batch):
    """The rotation of an unnormalised quaternion (scalar first) is scipy's of the normalised one, and
    ``q_dot = 1/2 q (x) (0, omega)`` is the Hamilton product written out by scipy's composition's derivative."""
    from ctmm.spatial.frames import quaternion_rate, quaternion_rotation

    q = RNG.normal(size=(batch, 4)) * 1.7
    got = quaternion_rotation(NUMPY, *(q[:, i, None, None] for i in range(4)))
    expected = Rotation.from_quat(np.c_[q[:, 1:], q[:, :1]]).as_matrix()
    np.testing.assert_allclose(got, expected, atol=2e-15)
    omega, h = RNG.normal(size=(batch, 3)), 1e-7
    later = (Rotation.from_quat(np.c_[q[:, 1:], q[:, :1]]) * Rotation.from_rotvec(h * omega)).as_quat()
    later = np.c_[later[:, 3:], later[:, :3]] * np.linalg.norm(q, axis=1, keepdims=True)
    later *= np.sign(np.sum(later * q, axis=1, keepdims=True))          # the same sign as q
    np.testing.assert_allclose(quaternion_rate(q, omega), (later - q) / h, atol=1e-6 * np.abs(q).max())


def test_one_real_system_is_solved_as_np_linalg_solve():
    """A 2-D float system (the single-state sweeps' modal blocks and pivots) gives ``np.linalg.solve``'s values bit
    for bit, as a C-ordered array; an exactly singular matrix raises ``LinAlgError``; batches, complex and 1-D
    right-hand sides keep the general path."""
    for n, k in [(1, 1), (3, 4), (5, 1), (9, 3)]:
        for scale in (1e-6, 1.0, 1e6):
            a, b = scale * RNG.normal(size=(n, n)), RNG.normal(size=(n, k))
            got = NUMPY.solve(a, b)
            assert got.flags.c_contiguous and got.shape == (n, k)
            np.testing.assert_array_equal(got, np.linalg.solve(a, b))
    with pytest.raises(np.linalg.LinAlgError):
        NUMPY.solve(np.zeros((3, 3)), np.ones((3, 2)))
    a, b = RNG.normal(size=(4, 3, 3)), RNG.normal(size=(4, 3, 2))
    np.testing.assert_array_equal(NUMPY.solve(a, b), np.linalg.solve(a, b))
    np.testing.assert_array_equal(NUMPY.solve(a[0] * 1j, b[0]), np.linalg.solve(a[0] * 1j, b[0]))
