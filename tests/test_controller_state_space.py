"""The one realisation of a loop's controller ``C(s)`` (:mod:`ctmm.controller_state_space`).

Independent reference: python-control's own frequency response of the transfer function the user gave
(``C(i w)`` evaluated from its polynomials) against ``C (i w I - A)^-1 B + D`` of the realisation.  The refusals
are checked on the verbs that realise the controller (one message, naming what needed the realisation).
"""
from __future__ import annotations

import control
import numpy as np
import pytest

import ctmm
from ctmm.control import ControlledChain, Feedback
from ctmm.controller_state_space import controller_state_space
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.errors import ModelError
from ctmm.interop import to_state_space


def realised_response(A, B, C, D, omega):
    k = A.shape[0]
    return np.array([C @ np.linalg.solve(1j * w * np.eye(k) - A, B) + D if k else D for w in omega])


@pytest.mark.parametrize("gain", [control.tf([2.0, 30.0], [0.01, 1.0]),
                                  control.tf([1.0, 3.0, 5.0], [1.0, 0.4, 9.0, 2.0]),
                                  control.tf([4.0], [1.0])])
def test_realisation_reproduces_the_transfer_function(gain):
    omega = np.logspace(-2, 3, 40)
    A, B, C, D = controller_state_space("c", gain)
    expected = np.array([complex(gain(1j * w)) for w in omega])
    np.testing.assert_allclose(realised_response(A, B, C, D, omega), expected, rtol=1e-11, atol=1e-14)
    assert A.shape == (B.size, B.size) and C.shape == B.shape


def test_static_gain_has_no_states():
    A, B, C, D = controller_state_space("c", 12.5)
    assert A.shape == (0, 0) and B.shape == (0,) and C.shape == (0,) and D == 12.5


@pytest.mark.parametrize("gain, match", [
    (control.tf([0.5, 10.0], [1.0]), r"loop 'c': the controller C\(s\) cannot be realised in time .*improper PD"),
    (control.tf([1.0], [1.0, np.nan]), r"loop 'c': the controller C\(s\) has a non-finite coefficient"),
    (control.ss(np.zeros((1, 1)), np.ones((1, 2)), np.ones((1, 1)), np.zeros((1, 2))),
     r"loop 'c': the controller must be SISO, got 2 inputs"),
])
def test_bad_controllers_are_refused_naming_the_loop(gain, match):
    with pytest.raises(ModelError, match=match):
        controller_state_space("c", gain)


def chain_with(gain, delay=0.0):
    plant = ctmm.Chain("one", [Fixed("wall"), SpringDamper("k0", 100.0, 0.5), Mass("m0", 1.0), Free("end")])
    return ControlledChain(plant, [Feedback("pd", "m0.x", "m0", gain=gain, delay=delay)])


def test_improper_controller_is_refused_with_one_message_on_each_path():
    """``kp + kd s``: the time driver and the state-space export refuse it with the one message, each naming what
    needed the realisation."""
    system = chain_with(control.tf([0.5, 10.0], [1.0]))
    with pytest.raises(ModelError, match=r"loop 'pd': the controller C\(s\) cannot be realised in time .*to_frd"):
        ctmm.simulate(system, 0.1, 0.01)
    with pytest.raises(ModelError, match=r"loop 'pd': the controller C\(s\) cannot be realised by to_state_space"):
        to_state_space(system, inputs="m0.force", outputs="m0.x")


def test_time_and_state_space_paths_share_the_realisation():
    """The closed loop of a first-order lag controller: the exported state space has the controller's pole
    where the hand-closed model ``m x'' + c x' + k x = -K z``, ``tau z' = x - z`` puts it."""
    gain = control.tf([50.0], [0.05, 1.0])
    exported = to_state_space(chain_with(gain), inputs="m0.force", outputs="m0.x")
    m, c, k, tau, K = 1.0, 0.5, 100.0, 0.05, 50.0
    A = np.array([[0.0, 1.0, 0.0], [-k / m, -c / m, -K / m], [1.0 / tau, 0.0, -1.0 / tau]])
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(exported.A)), np.sort_complex(np.linalg.eigvals(A)),
                               rtol=1e-10)
