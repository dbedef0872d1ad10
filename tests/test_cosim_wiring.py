"""One wiring rule on every co-simulation path (:func:`ctmm.control.cosim.check_wiring`, run by the master).

Two controllers writing one actuator are refused -- never added -- on the chain's Python DT-TMM step
(``ctmm.control.simulate``), the chain's RK4 (the loop driver on its plant), the generated RK4 and the generated
DT-TMM step of a chain (``ctmm.compiled_cosim``; refused before anything is compiled) and a planar model; unknown
names and sample times off the step grid of the chain's DT-TMM step are reported together, one per line.
"""
from __future__ import annotations

import pytest

import ctmm
from ctmm.control.cosim import CoSimulation, check_wiring
from ctmm.errors import ModelError
from ctmm.planar import PlanarModel, Pinned, RigidBody

from _controllers_import import load_controllers
from test_compiled_cosim_chain import three_masses

TWICE = r"'m1.force' is written by controllers 0 and 1 \(each actuator by one controller"


def pid(sensor: str, actuator: str, sample_time: float = 1e-3):
    return load_controllers().PID(sensor, actuator, kp=1.0, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                  sample_time=sample_time)


@pytest.mark.parametrize("method, compiled", [("newmark", None), ("rk4", None), ("rk4", True), ("newmark", True)])
def test_two_controllers_on_one_chain_actuator_are_refused_on_every_path(method, compiled):
    controllers = [pid("m1.x", "m1.force"), pid("m2.v", "m1.force")]
    with pytest.raises(ModelError, match=TWICE):
        ctmm.simulate(three_masses(), 0.01, 1e-3, method=method, compiled=compiled, controllers=controllers)


def test_one_controller_per_actuator_still_runs_on_the_chain():
    run = ctmm.simulate(three_masses(), 0.005, 1e-3, method="newmark", x0={"m1": 0.01},
                        controllers=[pid("m1.x", "m1.force"), pid("m2.x", "m2.force")])
    assert run["m1.force@samples"].shape == run["m2.force@samples"].shape == (5, 2)   # sampled before each step


def test_the_chain_dttmm_step_lists_every_wiring_problem_at_once():
    controllers = [pid("m1.nothing", "m1.force"), pid("m1.x", "m1.force", 1.5e-3), pid("m2.x", "m9.force")]
    with pytest.raises(ModelError) as caught:
        ctmm.simulate(three_masses(), 0.01, 1e-3, method="newmark", controllers=controllers)
    lines = str(caught.value).splitlines()
    assert lines[0] == "co-simulated controllers of the chain are invalid:"
    assert "input of controller 0" in lines[1] and "'m1.nothing'" in lines[1]
    assert "'m1.force' is written by controllers 0 and 1" in lines[2]
    assert "controller 1: sample_time 0.0015 must be a whole multiple of dt = 0.001" in lines[3]
    assert "output of controller 2" in lines[4] and "'m9.force'" in lines[4]


def test_two_controllers_on_one_planar_actuator_are_refused():
    model = PlanarModel.chain("p", [Pinned("o"), RigidBody.uniform_link("l", mass=1.0, length=1.0)])
    with pytest.raises(ModelError, match=r"'o.torque' is written by controllers 0 and 1"):
        ctmm.simulate(model, 0.01, 1e-3, method="rk4", x0=[0.1],
                      controllers=[pid("o.angle", "o.torque"), pid("o.rate", "o.torque")])


def test_check_wiring_takes_names_lookups_or_nothing():
    """Names as a list, as a look-up that raises ModelError, or None (the stepper checks them itself); the
    master runs the rule before any controller is started."""
    a, b = pid("x", "u"), pid("y", "u")
    assert check_wiring([a], ["x"], ["u"], 1e-3) == {"u"}
    assert check_wiring([a], None, None, 1e-3) == {"u"}

    def lookup(name):
        if name != "x":
            raise ModelError(f"no signal {name!r}")

    with pytest.raises(ModelError, match=r"input of controller 0: no signal 'y'"):
        check_wiring([b], lookup, None, 1e-3)
    with pytest.raises(ModelError, match=r"'u' is written by controllers 0 and 1"):
        CoSimulation([a, b], 1e-3, 0.0)
