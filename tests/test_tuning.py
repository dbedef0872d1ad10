"""ctmm.control.tune on a problem with a known optimum (an active nonlinear constraint)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm.control import Constraint, ControlledChain, Feedback, Quantity, tune
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.errors import ModelError


def velocity_loop(kd: float = 0.1) -> ControlledChain:
    """m x'' + (c + kd) x' + k x = F with m = k = 1, c = 0.1: roots -(c + kd)/2 +- i..."""
    plant = ctmm.Chain("sdof", [Fixed("w"), SpringDamper("k", 1.0, 0.1), Mass("m", 1.0), Free("e")])
    return ControlledChain(plant, [Feedback("rate", [("m.v", kd)], "m", gain=1.0)])


@pytest.mark.filterwarnings("ignore:delta_grad == 0.0")
@pytest.mark.parametrize("method", ["SLSQP", "trust-constr"])
def test_smallest_peak_with_a_decay_rate_cap_is_the_analytic_optimum(method):
    """min max|X/F| subject to abscissa >= -0.3: total damping c + kd = 0.6, peak 1/(0.6 sqrt(0.91))."""
    omega = np.linspace(0.2, 2.0, 400)
    steps = []
    result = tune(velocity_loop(), ["rate.m.v"], Quantity("response_peak", input="m.force", output="m.x",
                                                          omega=omega),
                  [Constraint(Quantity("spectral_abscissa"), lower=-0.3)], bounds={"rate.m.v": (0.0, 1.2)},
                  method=method, progress=steps.append)
    assert result.success and result.feasible, result.message
    # SLSQP lands on the active constraint; trust-constr (interior point) stops inside it, by its barrier
    tolerance = 1e-7 if method == "SLSQP" else 1e-3
    assert 0.5 - tolerance < result.parameters["rate.m.v"] <= 0.5 + 1e-9
    assert abs(result.objective - 1.0 / (0.6 * math.sqrt(1.0 - 0.09))) < 10 * tolerance
    assert steps and steps[0].parameters == {"rate.m.v": 0.1} and result.history[0].evaluation == 0
    assert result.system.loop("rate").terms[0][1] == pytest.approx(result.parameters["rate.m.v"])


def test_maximize_and_bounds():
    """Maximising the decay rate (minimising the abscissa) runs to the upper bound of the gain."""
    result = tune(velocity_loop(), ["rate.m.v"], Quantity("spectral_abscissa"), bounds=[(0.0, 1.0)])
    assert result.success and abs(result.parameters["rate.m.v"] - 1.0) < 1e-9
    assert abs(result.objective + 0.55) < 1e-9
    worst = tune(velocity_loop(0.5), ["rate.m.v"], Quantity("spectral_abscissa"), bounds=[(0.0, 1.0)],
                 maximize=True)
    assert abs(worst.parameters["rate.m.v"]) < 1e-9 and abs(worst.objective + 0.05) < 1e-9


def test_bad_requests_are_refused_by_name():
    system = velocity_loop()
    with pytest.raises(ModelError, match="kind 'damping'.*spectral_abscissa"):
        Quantity("damping")
    with pytest.raises(ModelError, match="needs loop, omega"):
        Quantity("delay_margin")
    with pytest.raises(ModelError, match="lower= or upper="):
        Constraint(Quantity("spectral_abscissa"))
    with pytest.raises(ModelError, match="outside its bounds"):
        tune(system, ["rate.m.v"], Quantity("spectral_abscissa"), bounds={"rate.m.v": (0.5, 1.0)})
    with pytest.raises(ModelError, match="not tuned"):
        tune(system, ["rate.m.v"], Quantity("spectral_abscissa"), bounds={"m.mass": (0.5, 1.0)})
    with pytest.raises(ModelError, match="method"):
        tune(system, ["rate.m.v"], Quantity("spectral_abscissa"), method="BFGS")
    with pytest.raises(ModelError, match="rate.*gain"):
        tune(system, ["rate.kd"], Quantity("spectral_abscissa"))
