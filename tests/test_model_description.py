"""``ctmm.model_description.describe``: the complete byte description behind the described kernel keys (issue 13).

A description must change with any number or structure the generators could read (else a cached library of
another model would load: a silent wrong answer) and must refuse (``None``, the caller keys on the built step)
whatever it cannot describe exactly.
"""
from __future__ import annotations

import copy

import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.model_description import describe, package_digest
from ctmm.signals import Harmonic

from _controllers_import import load_controllers


def chain(stiffness: float = 400.0, force=0.0, name: str = "m") -> ctmm.Chain:
    return ctmm.Chain("c", [Fixed("w"), SpringDamper("k", stiffness, 0.3), Mass(name, 2.0, force=force), Free("e")])


def test_equal_models_describe_equally_and_every_edit_shows():
    base = describe(chain())
    assert base is not None and base == describe(chain())
    assert describe(chain(np.nextafter(400.0, 500.0))) != base           # one unit in the last place
    assert describe(chain(name="n")) != base                              # a name
    assert describe(chain(force=Harmonic(1.0, 3.0))) != describe(chain(force=Harmonic(1.0, 3.0 + 1e-15)))
    loop = Feedback("p", "m.x", "m", gain=20.0, delay=0.004)
    assert describe(ControlledChain(chain(), [loop])) != describe(ControlledChain(chain(), [
        Feedback("p", "m.x", "m", gain=20.0, delay=0.005)]))
    assert describe((chain(), 1e-3)) != describe((chain(), 2e-3))         # options beside the model


def test_containers_floats_and_shared_references_are_exact():
    shared = np.arange(3.0)
    assert describe([shared, shared]) != describe([shared, shared.copy()])       # the graph's shape
    assert describe({"a": 1, "b": 2}) != describe({"b": 2, "a": 1})              # insertion order is read
    assert describe({1, 2, 3}) == describe({3, 2, 1})
    assert describe(0.1) != describe(0.1 + 2 ** -56) and describe(-0.0) != describe(0.0)
    assert describe(np.zeros((2, 3))) != describe(np.zeros((3, 2)))
    assert describe(np.float32(1.0)) != describe(1.0)
    cyclic: list = [1.0]
    cyclic.append(cyclic)
    assert describe(cyclic) is not None


def test_what_cannot_be_described_exactly_is_refused():
    assert describe(chain(force=lambda t: 0.0)) is None                  # a user's function of time
    assert describe(lambda: 0) is None and describe(np) is None
    assert describe(copy) is None
    control = pytest.importorskip("control")
    assert describe(ControlledChain(chain(), [Feedback("lag", "m.x", "m", gain=control.tf([2.0], [0.1, 1.0]))])) \
        is None                                                          # a python-control object

    class Outside:                                                       # a class from outside ctmm
        value = 1.0

    assert describe(Outside()) is None
    pid = load_controllers().PID("m.x", "m.force", kp=1.0, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                 sample_time=0.01)
    assert describe(pid) is None                                         # ctmm.controllers: not the package's files


def test_package_digest_reads_the_package_text():
    digest = package_digest()
    assert len(digest) == 64 and digest == package_digest()
