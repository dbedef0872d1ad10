"""A loop rebuilt with new numbers keeps its saturation (``ctmm.stability.with_loop_parameters``).

The rebuild behind ``ctmm.sensitivity.with_parameters`` (and so tuning, parameter sets, the
cross-check by simulation) used to drop ``saturation``: the copy was silently linear.  Two
consequences are checked: in time the kept limit is honoured (a rigid link about a hinge, no
gravity, a demand far beyond the limit: constant torque, the closed-form parabola
``theta = theta0 - (limit / J) t^2 / 2``, ``J = m L^2 / 3``), and the linear verbs refuse the copy
by the loop's name (frequency response, delay margin of a 1-D chain).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.sensitivity
import ctmm.stability
from ctmm.control import ControlledChain, Feedback, with_feedback
from ctmm.elements import Fixed, Free, Mass, Spring
from ctmm.planar import ActuatedHinge, PlanarModel, RigidBody
from ctmm.planar import Fixed as PlanarFixed

MASS, LENGTH, LIMIT, THETA0 = 3.0, 1.0, 0.5, 1.0


def test_a_saturated_planar_loop_with_a_new_gain_stays_saturated_in_time():
    plant = PlanarModel.chain("arm", [PlanarFixed("ground"), ActuatedHinge("motor"),
                                      RigidBody.uniform_link("link", mass=MASS, length=LENGTH)], gravity=(0.0, 0.0))
    system = with_feedback(plant, [Feedback("hold", "motor.angle", "motor.torque", gain=1.0,
                                            saturation=(-LIMIT, LIMIT))])
    tuned = ctmm.sensitivity.with_parameters(system, {"hold.gain": 100.0})
    assert tuned.loops[0].gain == 100.0 and tuned.loops[0].saturation == (-LIMIT, LIMIT)
    result = ctmm.simulate(tuned, 0.4, 1e-3, x0={"link.theta": THETA0}, outputs=["motor.angle"])
    inertia = MASS * LENGTH ** 2 / 3.0            # uniform rod about its end [kg m^2]
    expected = THETA0 - 0.5 * LIMIT / inertia * result.time ** 2   # demand -100 theta < -LIMIT throughout
    np.testing.assert_allclose(np.ravel(result["motor.angle"]), expected, rtol=0.0, atol=1e-12)


def test_a_saturated_chain_loop_with_new_numbers_is_refused_by_the_linear_verbs():
    plant = ctmm.Chain("c", [Fixed("wall"), Spring("k", 100.0), Mass("m", 1.0), Free("end")])
    system = ControlledChain(plant, [Feedback("pd", "m.x", "m", gain=1.0, saturation=(-1.0, 1.0))])
    changed = ctmm.stability.with_loop_parameters(system, "pd", {"gain": 5.0, "delay": 0.01})
    assert (changed.loops[0].gain, changed.loops[0].delay, changed.loops[0].saturation) == (5.0, 0.01, (-1.0, 1.0))
    with pytest.raises(ctmm.ModelError, match=r"loop 'pd' saturates at \(-1\.0, 1\.0\)"):
        ctmm.frequency_response(changed, np.array([1.0, 2.0]), input="m.force", output="m.x")
    with pytest.raises(ctmm.ModelError, match=r"loop 'pd' saturates at \(-1\.0, 1\.0\)"):
        ctmm.stability.delay_margin(changed)
