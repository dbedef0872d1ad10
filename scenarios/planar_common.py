"""Accuracy figure shared by the planar scenarios (pendulum chain, branched tree, hinge + motor)."""
from __future__ import annotations

import numpy as np

from ctmm.scenario import accuracy

TARGET_HORIZON_S = 1.0     # docs/planar.md: the 1e-6 rad target of RK4 at h = 1 ms is defined over 1 s
TARGET_RAD = 1e-6


def angle_accuracy(t: np.ndarray, error: np.ndarray, what: str) -> list[dict]:
    """Accuracy of TMM + RK4 angles against the Lagrange reference over the target horizon.

    Parameters
    ----------
    t : ndarray
        Sample times [s].
    error : ndarray
        Max angle error over the coordinates at each sample [rad].
    what : str
        Which coordinates, step and reference (completes the definition).
    """
    window = np.asarray(t) <= TARGET_HORIZON_S + 1e-9
    return [accuracy("angle error vs Lagrange over 1 s", float(np.max(np.asarray(error)[window])), "rad",
                     TARGET_RAD, f"max over t in [0, min(T, 1 s)] of |theta_TMM+RK4 - theta_Lagrange| {what}",
                     source="docs/planar.md: planar RK4 (h = 1 ms) target 1e-6 rad over 1 s")]
