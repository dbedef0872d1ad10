"""Shared run of the mixed-method scenarios: the mixed model and its global reference with the same RK4 step."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

import ctmm


@dataclass(frozen=True)
class SameStepRun:
    """Histories of the mixed model (``q``, ``v``, its coordinate order) and of the global reference (``q_ref``,
    ``v_ref``, the reference's order), ``error`` = max |q - q_ref| [rad or m], energies [J] every ``every`` steps."""

    time: np.ndarray
    q: np.ndarray
    v: np.ndarray
    q_ref: np.ndarray
    v_ref: np.ndarray
    error: float
    every: int
    energy: np.ndarray
    energy_ref: np.ndarray
    wall_time_s: float

    @property
    def energy_drift(self) -> float:
        """(max - min) / max |E| of the mixed run's energy."""
        return float(np.ptp(self.energy) / np.max(np.abs(self.energy)))

    @property
    def energy_error(self) -> float:
        """max |E - E_ref| / max |E_ref|."""
        return float(np.max(np.abs(self.energy - self.energy_ref)) / np.max(np.abs(self.energy_ref)))


def same_step_run(mixed, reference, q0: np.ndarray, t_final: float, step: float,
                  order: Sequence[int] | None = None) -> SameStepRun:
    """RK4 of ``mixed`` (``ctmm.simulate``) and of ``reference`` (``GlobalChain.rk4``) from ``q0`` at rest.

    ``order``: the mixed coordinates' indices in the reference's order (default: the same order)."""
    names = mixed.coordinates
    order = list(range(len(names))) if order is None else list(order)
    result = ctmm.simulate(mixed, t_final, step, method="rk4", x0=q0)
    q = np.column_stack([result[c] for c in names])
    v = np.column_stack([result[c + "_dot"] for c in names])
    _, q_ref, v_ref = reference.rk4(q0[order], np.zeros(len(order)), t_final, step)
    every = max(1, q.shape[0] // 200)
    energy = np.array([mixed.energy(q[k], v[k]) for k in range(0, q.shape[0], every)])
    energy_ref = np.array([reference.energy(q_ref[k], v_ref[k]) for k in range(0, q.shape[0], every)])
    return SameStepRun(result.time, q, v, q_ref, v_ref, float(np.max(np.abs(q[:, order] - q_ref))), every, energy,
                       energy_ref, result.info["wall_time_s"])
