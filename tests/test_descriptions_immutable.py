"""Descriptions are not state (DESIGN principle 1; issue 12, plan §1.8 and step S1d).

Running a verb on a system must leave every element object exactly as it was built: no layout
written onto boundaries, no ``state_index`` or chart limits written during assembly, no cache
filled in on first use.  Each test snapshots the elements' ``__dict__`` (recursively: arrays by
value, nested objects by their own ``__dict__``) before the verbs and compares after them.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback, simulate_controlled
from ctmm.elements import Fixed, Free, Mass, Spring, SpringDamper
from ctmm.flexible import ModalBeam
from ctmm.planar import Pinned, PlanarModel, RigidBody, accelerations, simulate_implicit, simulate_rk4
from ctmm.planar.elements import FixedMounting, Load
from ctmm.stability import stability_chart, unstable_root_count


def snapshot(value, seen=None):
    """A comparable picture of ``value``: containers and object ``__dict__``s recursively, arrays
    by dtype, shape and bytes, anything else (functions, signals without ``__dict__``) by identity
    unless it compares by value."""
    seen = {} if seen is None else seen
    if isinstance(value, (str, bytes, int, float, complex, bool, type(None))):
        return value
    if isinstance(value, np.ndarray):
        return ("array", value.dtype.str, value.shape, value.tobytes())
    if id(value) in seen:
        return ("seen", seen[id(value)])
    seen[id(value)] = len(seen)
    if isinstance(value, dict):
        return ("dict", tuple((snapshot(k, seen), snapshot(v, seen)) for k, v in value.items()))
    if isinstance(value, (list, tuple, set, frozenset)):
        items = sorted(value, key=repr) if isinstance(value, (set, frozenset)) else value
        return (type(value).__name__, tuple(snapshot(v, seen) for v in items))
    if hasattr(value, "__dict__") and not callable(value):
        return (type(value).__qualname__, snapshot(vars(value), seen))
    return ("object", type(value).__qualname__, id(value))


def snapshots(elements) -> list:
    return [snapshot(vars(element)) for element in elements]


def plant() -> ctmm.Chain:
    return ctmm.Chain("two", [Fixed("wall"), Spring("k0", 100.0), Mass("m0", 1.0, force=1.0),
                              SpringDamper("k1", 80.0, 0.4), Mass("m1", 1.5), Free("end")])


def test_chain_verbs_leave_elements_unchanged():
    elements = plant().elements
    before = snapshots(elements)
    system = ctmm.Chain("again", list(elements))    # building a second system on the same elements
    undamped = ctmm.Chain("undamped", [elements[0], elements[1], elements[2], Spring("k1", 80.0), elements[4],
                                       elements[5]])
    ctmm.natural_frequencies(undamped, n_modes=2)
    ctmm.frequency_response(system, np.linspace(1.0, 20.0, 7), input="m0.force", output=["m1.x", "m0.v"])
    ctmm.simulate(system, 0.05, 0.01)
    assert snapshots(elements) == before
    assert "layout" not in vars(elements[0]) or vars(elements[0])["layout"] is None


def test_controlled_chain_verbs_leave_elements_and_loops_unchanged():
    system = ControlledChain(plant(), [Feedback("L", "m1.x", "m0", gain=5.0, delay=0.05)])
    objects = [*system.plant.elements, *system.loops, system]
    before = snapshots(objects)
    ctmm.frequency_response(system, np.linspace(1.0, 20.0, 5), input="L.reference", output=["m1.x", "L.u"])
    simulate_controlled(system, 0.05, 0.01)
    unstable_root_count(system, delay=[0.0, 0.1])
    stability_chart(system, x=("gain", np.linspace(0.0, 4.0, 5)), y=("delay", np.linspace(0.0, 0.2, 4)))
    assert snapshots(objects) == before


def test_planar_flexible_verbs_leave_bodies_unchanged():
    beam = ModalBeam("b", length=1.0, bending_stiffness=5.0, mass_per_length=0.7, n_modes=2,
                     loads=(Load(point=(0.5, 0.0), force_y=lambda t: math.sin(t)),))
    elements = [Pinned("o"), RigidBody("hub", mass=2.0, inertia=0.1, outboard=(0.2, 0.0)),
                FixedMounting("mount"), beam]
    before = snapshots(elements)
    model = PlanarModel.chain("m", elements)
    n = model.n_coordinates
    q0, v0 = np.zeros(n), np.zeros(n)
    v0[0] = 1.0
    accelerations(model, q0, v0, 0.0)
    model.energy(q0, v0, 0.0)
    simulate_rk4(model, q0, v0, t_final=0.01, dt=0.005)
    simulate_implicit(model, q0, v0, t_final=0.01, dt=0.005)
    assert snapshots(elements) == before
    model_before = snapshot(vars(model))
    accelerations(model, q0, v0, 0.0)
    simulate_rk4(model, q0, v0, t_final=0.01, dt=0.005)
    assert snapshot(vars(model)) == model_before     # the compiled model is not a cache either


def test_snapshot_sees_a_written_attribute():
    """The comparison above can fail: a layout written onto a boundary changes the snapshot."""
    boundary = Free("end")
    before = snapshot(vars(boundary))
    boundary.layout = plant().layout
    assert snapshot(vars(boundary)) != before
    beam = ModalBeam("b", length=1.0, bending_stiffness=5.0, mass_per_length=0.7, n_modes=1)
    before = snapshot(vars(beam))
    beam.data.K[0, 0] += 1.0                            # a changed array deep inside is seen too
    assert snapshot(vars(beam)) != before


@pytest.mark.parametrize("verb", ["frequency_response", "simulate"])
def test_state_index_is_derived_not_stored(verb):
    system = ControlledChain(plant(), [Feedback("L", "m1.x", "m0", gain=5.0)])
    assert "state_index" not in vars(system)
    if verb == "frequency_response":
        ctmm.frequency_response(system, [1.0, 2.0], input="m0.force", output="m1.x")
    else:
        ctmm.simulate(system, 0.02, 0.01)
    assert "state_index" not in vars(system)
    assert system.state_index == [0, 1, 2, 3, 5]    # sensing matrix after the sensed point m1 (j = 3)
