"""The one low-rank Newton correction (ctmm.low_rank) against a dense solve."""
from __future__ import annotations

import numpy as np

from ctmm.low_rank import low_rank_solve


def test_low_rank_solve_is_exact_after_rank_plus_one_products() -> None:
    rng = np.random.default_rng(2)
    n, rank = 12, 3
    P = rng.normal(size=(n, rank)) @ rng.normal(size=(rank, n)) * 0.2
    r = rng.normal(size=n)
    calls = []

    def product(direction: np.ndarray) -> np.ndarray:
        calls.append(direction)
        return P @ direction

    coefficients, directions = low_rank_solve(r, product, n)
    d = np.column_stack(directions) @ coefficients
    np.testing.assert_allclose(d, np.linalg.solve(np.eye(n) - P, r), rtol=1e-10, atol=0)
    assert len(calls) == len(directions) == len(coefficients) <= rank + 1
    assert all(a is b for a, b in zip(calls, directions))
    empty, none = low_rank_solve(np.zeros(n), product, n)
    assert empty.size == 0 and none == []
