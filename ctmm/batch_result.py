"""The runs of :func:`ctmm.simulate_batch` over parameter sets: results, failures by index, stacked signals."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["BatchResult"]


@dataclass
class BatchResult:
    """The runs of :func:`simulate_batch`.

    Attributes
    ----------
    parameter_sets : list of dict
        ``{name: number}`` of each set, in order.
    results : list of SimulationResult or None
        One per set (``None`` where it failed).
    failures : dict of int to Exception
        The exception of each failed set by index (a :class:`~ctmm.errors.SimulationError` carries
        its ``partial_result``).
    compile_time_s : float
        Building or loading the shared kernel, once [s].
    wall_time_s : float
        All runs [s].
    """

    parameter_sets: list
    results: list
    failures: dict = field(default_factory=dict)
    compile_time_s: float = 0.0
    wall_time_s: float = 0.0

    @property
    def time(self) -> np.ndarray:
        """Times of the stored rows [s] (of the first set that ran; every set has the same grid)."""
        done = [result for result in self.results if result is not None]
        return done[0].time if done else np.zeros(0)

    def stacked(self, name: str) -> np.ndarray:
        """Signal ``name`` of every set, ``(sets, rows)``; rows of failed sets NaN."""
        rows = len(self.time)
        out = np.full((len(self.results), rows), np.nan)
        for k, result in enumerate(self.results):
            if result is not None:
                out[k] = result[name]
        return out
