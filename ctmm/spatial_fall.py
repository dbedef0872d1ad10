"""Acceptance of the fall steps of the spatial static-equilibrium search by the potential energy (issue 14).

:func:`ctmm.spatial_linearization.static_equilibrium` with ``stable=True`` falls through unstable directions by
capped pseudo-transient steps (implicit Euler on the overdamped fall ``r' = f``, ``dt <= 0.5 / lambda``).  The
overdamped fall lowers the potential energy (``f = M^-1 Q``, ``Q = -dV/dr``), so a step is judged by it
(:class:`EnergyFall`): the potential energy at rest ``V`` (:func:`potential_at_rest`: :func:`ctmm.spatial.energy`
with zero velocities -- gravity, joint springs and laws, the beams' modal strain and weight) must not rise beyond
its round-off (:data:`FALL_ENERGY_ROUNDOFF`, relative); a rising step is retried four times shorter; a step that
leaves ``V`` level within round-off is taken (near an unstable equilibrium ``V`` is flat to second order and the
capped fall doubles the deviation per step, so its decrease is resolved within a few steps).  Refused
(:class:`~ctmm.errors.ModelError`, naming the fall steps, the largest acceleration and the energy):
:data:`FALL_REJECTIONS` steps in a row without a resolved decrease (stalled), an energy that overflows to
``-inf`` (a potential without a minimum), more than ``FALL_GUARD`` times the former step budget
``NEWTON_ITERATIONS + 5 n_v`` of accepted fall steps (a fall that goes on without end).

Where the static forces have no potential here -- point loads, elastic6 springs, anisotropic spherical springs,
a ``CallableLaw`` without ``potential`` -- :func:`potential_at_rest` is ``None`` and the search keeps the former
budget of ``NEWTON_ITERATIONS + 5 n_v`` fall steps.  The beams' geometric stiffening has no term in
:func:`ctmm.spatial.energy`: the acceptance sees their modal strain and weight only.  Whatever the acceptance,
the search's answer is certified by its residual bound and its stiffness eigenvalues.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .errors import ModelError

__all__ = ["EnergyFall", "potential_at_rest", "FALL_REJECTIONS", "FALL_ENERGY_ROUNDOFF", "FALL_GUARD"]

FALL_REJECTIONS = 30
"""Fall steps in a row without a decrease of the potential energy beyond its round-off before the search is
refused as stalled."""
FALL_ENERGY_ROUNDOFF = 1e-12
"""Relative round-off of the potential energy [-]: changes within it are level."""
FALL_GUARD = 20
"""Runaway guard: more than ``FALL_GUARD (NEWTON_ITERATIONS + 5 n_v)`` accepted fall steps are refused."""


def potential_at_rest(model: Any, q: np.ndarray) -> float | None:
    """Potential energy [J] of the static forces of a spatial model at coordinates ``q`` (module docstring), or
    ``None`` where that is not their potential (point loads; springs and laws without a potential here)."""
    from .spatial.dynamics import energy

    if model.loads:
        return None
    try:
        return float(energy(model, q, np.zeros(model.n_velocities)))
    except ModelError:
        return None


class EnergyFall:
    """The judge of one search's fall steps (module docstring).

    Parameters
    ----------
    model : SpatialModel
    q : ndarray
        Where the search starts (coordinates [rad, m, quaternions]).
    budget : int
        The former step budget ``NEWTON_ITERATIONS + 5 n_v`` (the guard is ``FALL_GUARD`` times it).
    """

    def __init__(self, model: Any, q: np.ndarray, budget: int) -> None:
        self.model = model
        self.energy = potential_at_rest(model, q)       # at the current point; None: stale or no potential
        self.available = self.energy is not None
        self.budget = budget
        self.steps = 0                                  # accepted fall steps
        self.idle = 0                                   # fall steps in a row without a resolved decrease

    def refusal(self, what: str, size: float) -> ModelError:
        told = "" if self.energy is None else f", potential energy {self.energy:.6e} J"
        return ModelError(f"linearize: no static equilibrium of {self.model.name!r} found: {what} after {self.steps} "
                          f"steps of the fall through unstable directions (largest acceleration {size:.3e}{told}); "
                          "pass operating_point=(q, v) to linearise about a chosen equilibrium")

    def exhausted(self) -> bool:
        """Without a potential: the former budget of fall steps is spent."""
        return not self.available and self.steps >= self.budget

    def accept(self, q: np.ndarray, trial: np.ndarray, trial_size: float, size: float) -> bool:
        """Whether the fall step ``q -> trial`` is taken (``False``: retry it shorter); ``trial_size``, ``size``:
        the largest accelerations there.  Raises the refusals of the module docstring."""
        if not self.available:
            return True
        if self.energy is None:
            self.energy = potential_at_rest(self.model, q)
        trial_energy = potential_at_rest(self.model, trial) if np.all(np.isfinite(trial)) else np.nan
        if trial_energy == -np.inf:
            raise self.refusal("the fall runs away (the potential energy overflows to -inf: a potential without a "
                               "minimum)", size)
        finite = np.isfinite(trial_size) and np.isfinite(trial_energy)
        noise = FALL_ENERGY_ROUNDOFF * max(abs(self.energy), abs(trial_energy) if finite else 0.0)
        rises = not (finite and trial_energy <= self.energy + noise)
        self.idle = self.idle + 1 if rises or trial_energy >= self.energy - noise else 0
        if self.idle >= FALL_REJECTIONS:
            raise self.refusal(f"the fall stalled (the potential energy did not fall beyond its round-off in "
                               f"{self.idle} steps in a row)", size)
        if rises:
            return False
        self.energy = trial_energy
        return True

    def taken(self, size: float) -> None:
        """Count an accepted fall step (``size``: the largest acceleration after it); the runaway guard."""
        self.steps += 1
        if self.steps > FALL_GUARD * self.budget:
            raise self.refusal("the fall goes on and on (the potential energy keeps falling: a potential without a "
                               "minimum?)", size)

    def moved(self) -> None:
        """A step without unstable directions was taken: the energy is stale, the stall count starts again."""
        self.energy, self.idle = None, 0
