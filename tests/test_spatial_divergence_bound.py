"""``divergence_bound`` of spatial models has one meaning on every path (ctmm.spatial.integrate.divergence_check):
the largest allowed distance of an entry of ``q`` or ``v`` from its initial value.

A slider far from the origin (x0 = 50 m) coasting at 1 m/s without forces: ``x = 50 + t`` exactly.  With
``divergence_bound = 2`` every path (numpy RK4 and solve_ivp, a DT-TMM scheme, the loop driver, generated kernels) runs 1.5 s (it moves 1.5 m; the former "largest entry" meaning stopped
the implicit and RK4 paths at the first step) and stops between 2 s and 2 s + dt on a 3 s run, with the
partial result.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback, with_feedback
from ctmm.errors import SimulationError

DT = 0.01


def slider() -> sp.SpatialModel:
    return sp.SpatialModel("slider", [sp.SpatialBody("s", 1.0, (0.1, 0.1, 0.1)),
                                      sp.Prismatic(name="p", parent=None, child="s", axis=(1, 0, 0),
                                                   actuated=True)], gravity=(0.0, 0.0, 0.0))


PATHS = {
    "rk4": lambda model, t: ctmm.simulate(model, t, DT, x0=[50.0], v0=[1.0], divergence_bound=2.0),
    "RK45": lambda model, t: ctmm.simulate(model, t, DT, method="RK45", x0=[50.0], v0=[1.0], divergence_bound=2.0),
    "newmark": lambda model, t: ctmm.simulate(model, t, DT, method="newmark", x0=[50.0], v0=[1.0],
                                              divergence_bound=2.0),
    "loops-rk4": lambda model, t: ctmm.simulate(with_feedback(model, [Feedback("f", "p.rate", "p.force", gain=0.0)]),
                                                t, DT, x0=[50.0], v0=[1.0], divergence_bound=2.0),
    "loops-newmark": lambda model, t: ctmm.simulate(
        with_feedback(model, [Feedback("f", "p.rate", "p.force", gain=0.0)]), t, DT, method="newmark", x0=[50.0],
        v0=[1.0], divergence_bound=2.0),
    "compiled": lambda model, t: ctmm.simulate(model, t, DT, x0=[50.0], v0=[1.0], divergence_bound=2.0,
                                               compiled=True),
    "loops-compiled": lambda model, t: ctmm.simulate(
        with_feedback(model, [Feedback("f", "p.rate", "p.force", gain=0.0)]), t, DT, x0=[50.0], v0=[1.0],
        divergence_bound=2.0, compiled=True),
}


@pytest.mark.parametrize("path", sorted(PATHS))
def test_divergence_bound_is_the_distance_from_the_start(path: str) -> None:
    model = slider()
    result = PATHS[path](model, 1.5)
    assert result["p.position"][-1] == pytest.approx(51.5, abs=1e-9)
    with pytest.raises(SimulationError, match="divergence_bound") as failure:
        PATHS[path](model, 3.0)
    error = failure.value
    assert 2.0 < error.time <= 2.0 + DT + 1e-9 or path == "RK45"     # solve_ivp: checked on the output grid
    assert error.partial_result is not None and error.partial_result.time[-1] < error.time
    assert "'p.position' moved" in str(error) or "compiled" in path      # generated paths: checked on stored rows
