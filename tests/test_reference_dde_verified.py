"""ctmm.reference.dde_verified: only verified roots, where raw collocation has spurious ones.

Checked against the second-order determinant ``det(s^2 M + s C + K + e^(-s tau) s H)`` (not the
first-order form the reference uses) and against the same reference with three times the nodes.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.reference import dde, dde_verified
from ctmm.reference import inerter_chain as ref


# ------------------------------------------------------------------------------ the reference itself
def test_verified_roots_drop_the_spurious_collocation_eigenvalues():
    """3-dof inerter chain, delayed velocity loop across b12 (tau = 0.3 s), 40 nodes: the raw
    eigenvalues with Re s > -30 include spurious ones (residual 1e-2 and more, |s| tau > ~1.1 N);
    the verified roots are zeros of the second-order determinant and, below |s| = N / tau, the
    same as with 120 nodes."""
    chain = ref.InerterChain((1.0, 0.5, 0.8), [97.0, 40.0, 5.0, 60.0], damping=[0.0, 0.7, 0.0, 0.0],
                             inertance=[0.0, 0.3, 0.2, 0.0], start="fixed", end="fixed")
    M, C, K = ref.assemble(chain)
    loop, gain, tau = np.outer([-1.0, 1.0, 0.0], [0.0, 0.0, 1.0]), 5.0, 0.3
    A0, delayed = dde.second_order_system(M, C, K, [(np.zeros((3, 3)), gain * loop, tau)])
    raw = dde.chebyshev_collocation_roots(A0, delayed, 40)
    raw = raw[raw.real > -30.0]
    residuals = np.array([dde_verified.relative_residual(A0, delayed, z) for z in raw])
    assert np.sum(residuals > 1e-3) >= 10
    verified = dde_verified.verified_roots(A0, delayed, 40, re_min=-30.0)
    for s in verified:
        matrix = s * s * M + s * C + K + gain * s * np.exp(-s * tau) * loop
        singular = np.linalg.svd(matrix, compute_uv=False)
        assert singular[-1] < 1e-9 * singular[0]
    fine = dde_verified.verified_roots(A0, delayed, 120, re_min=-30.0)
    limit = 40 / tau
    np.testing.assert_allclose(np.sort_complex(verified[np.abs(verified) < limit]),
                               np.sort_complex(fine[np.abs(fine) < limit]), rtol=1e-9)
    assert np.sum(np.abs(fine) < limit) >= 10


def test_verified_roots_refuse_bad_input_by_name():
    with pytest.raises(ctmm.ModelError, match=r"delayed\[0\] matrix must be \(2, 2\)"):
        dde_verified.verified_roots(np.eye(2), [(np.eye(3), 1.0)], 10)
    with pytest.raises(ctmm.ModelError, match="residual must be > 0"):
        dde_verified.verified_roots(np.eye(2), [(np.eye(2), 1.0)], 10, residual=0.0)
    with pytest.raises(ctmm.ModelError, match="re_min and im_max must be numbers"):
        dde_verified.verified_roots(np.eye(2), [(np.eye(2), 1.0)], 10, re_min=float("nan"))
