"""``x0``/``v0`` by coordinate name: one conversion (``ctmm.planar.integrate.coordinate_values``) for
``ctmm.simulate`` of planar models, ``ctmm.simulate_batch`` and the kinematic-loop verbs, with the same
refusals (unknown name listed, wrong length, not finite) naming the argument.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.errors import ModelError, UnknownNameError
from ctmm.planar import ActuatedHinge, ElasticHinge, Fixed, PlanarModel, RigidBody
from ctmm.planar.integrate import coordinate_values
from ctmm.scenarios.four_bar import mechanism as four_bar


def double_pendulum() -> PlanarModel:
    return PlanarModel.chain("arm", [Fixed("ground"), ActuatedHinge("pivot"),
                                     RigidBody.uniform_link("rod", mass=1.0, length=0.8),
                                     ElasticHinge("elbow", stiffness=3.0),
                                     RigidBody.uniform_link("fore", mass=0.5, length=0.6)], gravity=(0.0, -9.81))


def test_names_go_to_their_coordinates_and_the_rest_are_zero():
    model = double_pendulum()
    assert list(model.coordinates) == ["rod.theta", "fore.theta"]
    np.testing.assert_array_equal(coordinate_values(model, "x0", {"fore.theta": 0.3}), [0.0, 0.3])
    np.testing.assert_array_equal(coordinate_values(model, "v0", None), [0.0, 0.0])
    np.testing.assert_array_equal(coordinate_values(model, "x0", (0.1, 0.2)), [0.1, 0.2])
    with pytest.raises(ModelError, match=r"x0\['rod.theta'\] must be a real number, got '1'"):
        coordinate_values(model, "x0", {"rod.theta": "1"})
    with pytest.raises(ModelError, match=r"v0 must be finite, got \[0.0, nan\]"):
        coordinate_values(model, "v0", [0.0, np.nan])


def test_every_planar_time_verb_refuses_the_same_way():
    model, loop = double_pendulum(), four_bar()
    runs = {"simulate": lambda **k: ctmm.simulate(model, 0.01, 1e-3, **k),
            "simulate_batch": lambda **k: ctmm.simulate_batch(model, [{"rod.mass": 2.0}], 0.01, 1e-3, **k),
            "kinematic loop": lambda **k: ctmm.simulate(loop, 0.01, 1e-3, **k)}
    for name, run in runs.items():
        n = 3 if name == "kinematic loop" else 2
        with pytest.raises(UnknownNameError, match=r"unknown coordinate of x0 'rod.angle'; available: "):
            run(x0={"rod.angle": 0.1})
        with pytest.raises(ModelError, match=rf"v0 must be a mapping \{{coordinate: value\}} or an array of length {n} "
                                             r"\(coordinates .*\), got \[0.0, 0.0, 0.0, 0.0\]"):
            run(v0=[0.0] * 4)
