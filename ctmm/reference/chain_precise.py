"""Natural frequencies of lumped chains to many digits (mpmath): the reference where double
precision ``eigh`` is not accurate enough (low modes of chains with a wide stiffness spread)."""
from __future__ import annotations

import numpy as np

from .chain import GlobalChain, assemble

__all__ = ["natural_frequencies_precise"]


def natural_frequencies_precise(chain: GlobalChain, digits: int = 40) -> np.ndarray:
    """Undamped natural frequencies [rad/s], ascending, to ``digits`` significant digits
    (mpmath symmetric eigensolver on ``M^{-1/2} K M^{-1/2}``; lumped masses only, ``M``
    diagonal and positive), rounded to float at the end.

    ``eigh`` in double precision is accurate to about ``eps * lambda_max`` in each eigenvalue, so
    a low mode of a stiff chain carries a relative error ``eps * lambda_max / lambda`` (1e-12 for
    a spread of 1e4); this reference has none of it.
    """
    import mpmath

    M, _, K = assemble(chain)
    mass = np.diag(M)
    if not (np.allclose(M, np.diag(mass)) and np.all(mass > 0)):
        raise ValueError("natural_frequencies_precise needs positive lumped masses (diagonal M)")
    with mpmath.workdps(digits):
        scale = [1 / mpmath.sqrt(mpmath.mpf(float(m))) for m in mass]
        n = len(mass)
        A = mpmath.matrix(n, n)
        for i in range(n):
            for j in range(n):
                A[i, j] = mpmath.mpf(float(K[i, j])) * scale[i] * scale[j]
        values = mpmath.eigsy(A, eigvals_only=True)
        out = sorted(float(mpmath.sqrt(v)) if v > 0 else 0.0 for v in values)
    return np.array(out)
