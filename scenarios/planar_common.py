"""Accuracy figure and drawing helpers shared by the planar scenarios (pendulum chain, branched tree,
hinge + motor)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

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


def plot_angle_errors(ax: Any, rk4: Any, error_rk4: np.ndarray, newmark: Any, error_newmark: np.ndarray,
                      ylabel: str, suffix: str = "") -> None:
    """Max angle error [rad] of TMM + RK4 and DT-TMM Newmark against time [s], log scale.

    ``rk4`` and ``newmark`` are the runs (:class:`~ctmm.results.SimulationResult`, their ``time``
    [s]); ``suffix`` completes the legend entries."""
    ax.semilogy(rk4.time, error_rk4 + 1e-17, label=f"TMM + RK4{suffix}")
    ax.semilogy(newmark.time, error_newmark + 1e-17, label=f"DT-TMM Newmark{suffix}")
    ax.set(xlabel="t [s]", ylabel=ylabel)
    ax.legend(fontsize="small")


def save_figure(fig: Any, output_dir: str | Path, name: str) -> None:
    """Lay out, write ``<output_dir>/<name>.png`` (100 dpi, the directory made if needed) and close."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    Path(output_dir).mkdir(parents=True, exist_ok=True)
    fig.savefig(Path(output_dir) / f"{name}.png", dpi=100)
    plt.close(fig)
