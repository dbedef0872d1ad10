"""The one home of two loop rules: the unit of a loop signal (:func:`ctmm.signal_units.loop_unit`) and the
realisation of a loop's controller (:func:`ctmm.control.planar_time.controller_realisation`, also the generated
kernels' through :mod:`ctmm.compiled_loops`).

Checked against stated units and against the transfer function ``C(s)`` itself (closed form), not against
another realisation.
"""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.errors import ModelError
from ctmm.signal_units import UNKNOWN, loop_unit, signal_unit
from ctmm.system import Chain


class _StatedPorts:
    """Ports whose units are stated by hand (a sensor or actuator name ending in ``"_rad"`` is in rad or N*m)."""

    def sensor_unit(self, name: str) -> str:
        return "rad" if name.endswith("_rad") else "m"

    def actuator_unit(self, name: str) -> str:
        return "N*m" if name.endswith("_rad") else "N"


def test_loop_unit_is_the_common_unit_of_the_terms_and_unknown_when_they_mix():
    ports = _StatedPorts()
    same = Feedback("same", [("a.x", 1.0), ("b.x", -1.0)], "m.torque_rad", gain=2.0)
    mixed = Feedback("mixed", [("a.x", 1.0), ("h_rad", 0.5)], [("m.f", 1.0), ("n.torque_rad", 1.0)], gain=2.0)
    assert [loop_unit(ports, same, q) for q in ("y", "reference", "u", "L", "e")] == ["m", "m", "N*m", "1", UNKNOWN]
    assert loop_unit(ports, mixed, "y") == UNKNOWN
    assert loop_unit(ports, mixed, "u") == UNKNOWN


def test_a_weight_other_than_plus_or_minus_one_makes_the_unit_unknown_on_every_path():
    """A weight's unit is not known (the manipulator's PZT loop: slope rates [rad/s] times gains [V s/rad], moment
    pair [N m] per volt: its ``y`` and ``u`` are volts, docs/manipulator.md §6).  The time paths named them by the
    terms' unit ('rad/s', 'N m') while the frequency response left them unknown; now one rule everywhere."""
    import ctmm
    from ctmm.manipulator import HubPD, PZTFeedback, SEED_MOVE, manipulator_scene, scene_references, seed_manipulator
    ports = _StatedPorts()
    weighted = Feedback("w", [("a.x", 2.0), ("b.x", -2.0)], [("m.torque_rad", -1e-3), ("n.torque_rad", 1e-3)], gain=1.0)
    assert [loop_unit(ports, weighted, q) for q in ("y", "reference", "u", "L")] == [UNKNOWN, UNKNOWN, UNKNOWN, "1"]
    pd = HubPD(200.0, 30.0)
    scene = manipulator_scene(seed_manipulator(), pd=pd, pzt=PZTFeedback.per_patch([1000.0] * 3))
    names = ["pzt1.u", "pzt1.y", "hub_pd.u", "hub_pd.y"]
    expected = {"pzt1.u": UNKNOWN, "pzt1.y": UNKNOWN, "hub_pd.u": "N m", "hub_pd.y": UNKNOWN}
    run = ctmm.simulate(scene, 0.01, 0.002, method="rk4", references=scene_references(pd, SEED_MOVE))
    assert run.units(names) == expected
    for fields in ("modal", "exact"):
        response = ctmm.frequency_response(scene, [5.0], input="hub_pd.reference", output=names, fields=fields)
        assert {name: response.units[name] for name in names} == expected, fields


def test_a_controlled_chain_names_its_loop_units_by_the_same_rule():
    plant = Chain("one", [Fixed("wall"), SpringDamper("k0", 100.0, 0.5), Mass("m0", 1.0), Free("end")])
    system = ControlledChain(plant, [Feedback("pos", "m0.x", "m0", gain=3.0),
                                     Feedback("vel", "m0.v", "k0.force", gain=1.0)])
    units = {name: signal_unit(name, system) for name in ("pos.y", "pos.reference", "pos.u", "pos.L", "vel.y")}
    assert units == {"pos.y": "m", "pos.reference": "m", "pos.u": "N", "pos.L": "1", "vel.y": "m/s"}


def test_controller_realisation_is_the_transfer_function_of_the_loop():
    control = pytest.importorskip("control")
    from ctmm import compiled_loops
    from ctmm.control.planar_time import controller_realisation

    assert compiled_loops.controller_realisation is controller_realisation     # one function, both time paths
    # C(s) = (3 s + 1) / (s^2 + 2 s + 5): at s = 1j w, C = (3 j w + 1) / (5 - w^2 + 2 j w)
    A, B, C, D = controller_realisation(Feedback("lti", "m0.x", "m0", gain=control.tf([3.0, 1.0], [1.0, 2.0, 5.0])))
    assert (A.shape, B.shape, C.shape, type(D)) == ((2, 2), (2,), (2,), float)
    for w in (0.0, 0.7, 4.0):
        s = 1j * w
        realised = C @ np.linalg.solve(s * np.eye(2) - A, B) + D
        assert realised == pytest.approx((3 * s + 1) / (s * s + 2 * s + 5), rel=1e-12, abs=1e-14)
    A, B, C, D = controller_realisation(Feedback("p", "m0.x", "m0", gain=2.5))
    assert (A.shape, B.shape, C.shape, D) == ((0, 0), (0,), (0,), 2.5)


def test_an_improper_controller_is_refused_with_one_message_on_every_time_path():
    control = pytest.importorskip("control")
    from ctmm.control.planar_time import controller_realisation

    pd = Feedback("pd", "m0.x", "m0", gain=control.tf([0.5, 10.0], [1.0]))
    with pytest.raises(ModelError, match=r"loop 'pd': the controller C\(s\) cannot be realised in time .*improper PD"):
        controller_realisation(pd)
