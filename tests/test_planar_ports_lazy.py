"""Planar ports resolved name by name (ctmm.planar.ports): every look-up equals the whole table.

The whole table (built by iterating) is the reference; each name is looked up in a fresh
:class:`~ctmm.planar.ports.PlanarPorts` (so nothing is built but that name's owners) on models with rigid bodies,
modal beams with stations and axial modes, driven, welded, free-base and translational-spring hinges, and
coordinates whose names are also body sensors ("b0.theta").
"""
from __future__ import annotations

import pytest

from ctmm.errors import ModelError, UnknownNameError
from ctmm.flexible import ModalBeam
from ctmm.planar import (ActuatedHinge, DrivenHinge, ElasticHinge, Fixed, FreeBase, PlanarModel, RigidBody,
                         SpringDamperHinge)
from ctmm.planar.elements import FixedMounting
from ctmm.planar.ports import PlanarPorts


def beam_model() -> PlanarModel:
    arm = ModalBeam("arm", length=1.0, bending_stiffness=20.0, mass_per_length=0.5, n_modes=2,
                    stations={"a": 0.3, "tip": 1.0})
    axial = ModalBeam("rod", length=0.5, bending_stiffness=5.0, mass_per_length=0.2, n_modes=1, n_axial_modes=1,
                      axial_stiffness=1e4, stations={"mid": 0.25})
    return PlanarModel.chain("hb", [Fixed("ground"), ActuatedHinge("motor"),
                                    RigidBody("hub", mass=2.0, inertia=0.1, outboard=(0.1, 0.0)),
                                    FixedMounting("mount"), arm, DrivenHinge("drive", angle=0.2), axial],
                            gravity=(0.0, -9.81))


def free_base_tree() -> PlanarModel:
    return PlanarModel("floating", [
        FreeBase("base", child="b0"),
        RigidBody("b0", mass=1.5, inertia=0.2, center_of_mass=(0.3, 0.1), outboard={"e0": (0.8, 0.2), "e1": (0, 1)}),
        SpringDamperHinge("h1", parent="b0.e0", child="b1", stiffness=4.0, damping=0.3),
        RigidBody("b1", mass=0.7, inertia=0.05, center_of_mass=(0.35, -0.05)),
        DrivenHinge("h2", parent="b0.e1", child="b2", angle=0.1),
        RigidBody.uniform_link("b2", mass=0.2, length=0.3),
        ElasticHinge("h3", parent="b2", child="b3", stiffness=3.0, translational_stiffness=50.0),
        RigidBody.uniform_link("b3", mass=0.2, length=0.3),
    ], gravity=(0.0, 0.0))


MODELS = {"beams": beam_model, "free_base": free_base_tree}


@pytest.mark.parametrize("build", MODELS.values(), ids=MODELS)
def test_each_look_up_equals_the_whole_table(build):
    model = build()
    whole = PlanarPorts(model)
    sensors, actuators = dict(whole.sensors), dict(whole.actuators)
    assert len(sensors) == len(whole.sensors) > 20 and len(actuators) == len(whole.actuators) > 3
    assert "b0.theta" in model.coordinates or "arm.tip.w" in sensors      # both kinds of models are covered
    near = [n + "x" for n in list(sensors)[:5]] + ["motor", "arm.q9.force", "rod.mid.force", "drive.torque",
                                                    "b0", "b0.", ".theta", "b0.x_dot_dot", "base.theta"]
    for name in list(sensors) + list(actuators) + near:
        ports = PlanarPorts(model)
        assert (name in ports.sensors, name in ports.actuators) == (name in sensors, name in actuators), name
        assert ports.sensors.get(name) == sensors.get(name) and ports.actuators.get(name) == actuators.get(name)
    assert list(PlanarPorts(model).sensors) == list(sensors)               # the whole table, in its order
    assert list(PlanarPorts(model).actuators) == list(actuators)


def test_a_look_up_builds_only_its_owners_and_errors_list_every_name():
    model = free_base_tree()
    ports = PlanarPorts(model)
    assert ports.sensors["b0.theta"].kind == "body_angle" and ports.sensors["b0.theta_dot"].kind == "coordinate"
    assert ports.check_actuator("h1.torque") == "h1.torque" and ports.sensor_unit("b1.com.vy") == "m/s"
    assert ports.sensors._owners.whole is None                                     # nothing built but the names asked
    with pytest.raises(UnknownNameError) as error:
        ports.check_sensor("b1.thetaa")
    assert "b2.out.vy" in str(error.value) and "b0.x_dot" in str(error.value)
    with pytest.raises(ModelError, match="'h2' is driven or welded"):
        ports.check_actuator("h2.torque")
    assert 3 not in ports.sensors and ports.sensors.get(None) is None
