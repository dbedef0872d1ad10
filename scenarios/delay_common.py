"""Shared helpers of the delay-stability scenarios (``delay_*``): independent references.

Not a scenario itself (no ``NAME``).  The references use only :mod:`ctmm.reference` (closed
forms, Chebyshev collocation of the delay equations assembled from M, C, K): no transfer
matrices.
"""
from __future__ import annotations

import numpy as np

from ctmm.reference.dde import chebyshev_collocation_roots, newton_refine_root

DCURVE_BOUND_SOURCE = "docs/stability.md: D-curve points <= 1e-9 (test bound)"


def collocation_roots(A0, delayed, nodes: int = 32, keep: int = 24) -> np.ndarray:
    """Rightmost roots of x' = A0 x + sum A_k x(t - tau_k): collocation, Newton-polished,
    eigenvalues whose Newton step is large (spurious) dropped."""
    if not delayed:
        return np.linalg.eigvals(np.asarray(A0, float))
    roots = chebyshev_collocation_roots(A0, delayed, nodes)[:keep]
    refined = np.array([newton_refine_root(A0, delayed, z) for z in roots])
    return refined[np.abs(refined - roots) < 1e-4 * np.maximum(1.0, np.abs(roots))]


def compare_classification(chart, first_order, *, stride: int = 1, margin: float = 1e-6) -> dict:
    """Unstable-root counts of ``chart`` against collocation at every ``stride``-th grid point.

    ``first_order(x, y) -> (A0, delayed)`` assembles the reference delay equations.  Points whose
    rightmost reference root is within ``margin`` of the imaginary axis, or that the chart marks
    as lying on a boundary, are skipped."""
    compared = mismatches = skipped = 0
    worst = []
    for iy in range(0, chart.y.size, stride):
        for ix in range(0, chart.x.size, stride):
            count = int(chart.unstable_roots[iy, ix])
            roots = collocation_roots(*first_order(float(chart.x[ix]), float(chart.y[iy])))
            if count < 0 or np.min(np.abs(roots.real)) < margin:
                skipped += 1
                continue
            compared += 1
            if count != int(np.sum(roots.real > 0)):
                mismatches += 1
                worst.append([float(chart.x[ix]), float(chart.y[iy])])
    return {"compared": compared, "mismatches": mismatches, "skipped": skipped,
            "mismatched_points": worst[:10]}


def boundary_points(chart, kind: str = "oscillatory") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All finite points (x, y, omega) of the chart's D-curves of one kind."""
    xs, ys, ws = [], [], []
    for b in chart.boundaries:
        if b.kind != kind:
            continue
        ok = np.isfinite(b.x) & np.isfinite(b.y)
        xs.append(b.x[ok]), ys.append(b.y[ok]), ws.append(b.omega[ok])
    if not xs:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(ws)


def pd_first_order(mass: float, stiffness: float, damping: float, kp: float, kd: float, tau: float):
    """m x'' + c x' + k x = -(kp x + kd x')(t - tau) in first-order form (A0, [(A1, tau)])."""
    A0 = [[0.0, 1.0], [-stiffness / mass, -damping / mass]]
    A1 = [[0.0, 0.0], [-kp / mass, -kd / mass]]
    if tau == 0.0:
        return np.array(A0) + np.array(A1), []
    return A0, [(A1, tau)]
