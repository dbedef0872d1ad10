"""A singular multi-direction pivot of the spatial sweep is a SimulationError naming the time and the joint
(with the partial result in a run), not numpy's raw LinAlgError.

The model: a spherical joint at the origin of a body whose centre of mass is at (1, 1, 0) m and whose own
inertia (1e-20 kg m^2) is below round-off of the point mass's: the rotational inertia about the joint,
``m (|c|^2 I - c c^T) = [[1, -1, 0], [-1, 1, 0], [0, 0, 2]]`` kg m^2, is exactly singular (no inertia about
the axis through the centre of mass), so the 3 x 3 pivot of joint ``ball`` cannot be solved.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback, with_feedback
from ctmm.errors import SimulationError


def rod_on_a_ball() -> sp.SpatialModel:
    return sp.SpatialModel("m", [sp.SpatialBody("a", 1.0, (1.0, 1.0, 1.0)),
                                 sp.SpatialBody("rod", 1.0, (1e-20,) * 3, center_of_mass=(1.0, 1.0, 0.0)),
                                 sp.Revolute(name="r", parent=None, child="a", actuated=True),
                                 sp.Spherical(name="ball", parent="a", child="rod")])


def test_the_sweep_names_the_singular_joint() -> None:
    model = rod_on_a_ball()
    with pytest.raises(SimulationError, match=r"pivot of joint 'ball' \(spherical, 3 free directions\) is "
                                              r"singular at t = 0\.5 s") as failure:
        sp.accelerations(model, model.neutral(), np.zeros(model.n_velocities), 0.5)
    assert failure.value.element == "ball" and failure.value.time == 0.5


@pytest.mark.parametrize("method", ["rk4", "newmark", "loops"])
def test_a_run_stops_with_the_time_the_joint_and_the_partial_result(method: str) -> None:
    model = rod_on_a_ball()
    with pytest.raises(SimulationError, match="pivot of joint 'ball'") as failure:
        if method == "loops":
            ctmm.simulate(with_feedback(model, [Feedback("f", "r.angle", "r.torque", gain=1.0)]), 0.1, 0.01)
        else:
            ctmm.simulate(model, 0.1, 0.01, method=method)
    error = failure.value
    assert error.element == "ball" and error.time == 0.0
    assert error.partial_result is not None and list(error.partial_result.time) in ([], [0.0])
