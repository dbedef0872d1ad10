"""Bad inputs named in issue 11 and valid edge inputs of the public API, one test each.

The random fuzz over every public function is in :mod:`test_api_fuzz`; here are the concrete
cases the issue lists (each with its exact message), the cases owned by other parts of the
package (strict expected failures naming the owner), and valid edge inputs (a single mass,
``omega = 0``, one frequency) checked against closed-form results.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import ctmm
from ctmm import signals, stability
from ctmm.control import ControlledChain, ControllerStep, Feedback, simulate_controlled
from ctmm.elements import Fixed, Free, Mass, Spring

from test_api_fuzz import chain, controlled, pendulum, sim_result

# --------------------------------------------------------------------------------------------
# issue 11 examples, one by one
# --------------------------------------------------------------------------------------------
def test_tiny_dt_is_refused_before_the_run():
    # Refused from the planned step count and memory, before any step: a run of 1e300 steps (or 128 GB of rows)
    # would never return.  No wall-clock bound here (timings are the benchmarks'; a loaded machine took 6 s).
    with pytest.raises(ctmm.ModelError, match=r"dt=1e-300 s .* gives 1e\+300 steps; at most 5e\+07"):
        ctmm.simulate(chain(), 1.0, 1e-300)
    with pytest.raises(ctmm.ModelError, match=r"dt=1e-06 s .* GiB"):   # 1e6 steps of 4001 points: 128 GB
        big = ctmm.Chain("big", [Fixed("w")] + [e for i in range(2_000)
                                                for e in (Spring(f"k{i}", 1.0), Mass(f"m{i}", 1.0))] + [Free("e")])
        ctmm.simulate(big, 1.0, 1e-6)


def test_x0_as_a_list_names_x0():
    with pytest.raises(ctmm.ModelError, match=r"x0 must be a mapping \{element name: number\} or None, got \[0\.1\]"):
        ctmm.simulate(chain(), 0.1, 0.01, x0=[0.1])


def test_initial_displacement_on_a_fixed_support_is_refused():
    with pytest.raises(ctmm.ModelError, match=r"x0\['w'\] = 0.5: 'w' is a support that prescribes its own motion"):
        ctmm.simulate(chain(), 0.1, 0.01, x0={"w": 0.5})
    with pytest.raises(ctmm.ModelError, match=r"v0\['w'\] = 1.0"):
        ctmm.simulate(chain(), 0.1, 0.01, v0={"w": 1.0})
    ctmm.simulate(chain(), 0.1, 0.01, x0={"w": 0.0})   # its own position is consistent: accepted


def test_steady_state_response_refuses_several_frequencies():
    with pytest.raises(ctmm.ModelError, match=r"omega must be one frequency .* got \[1\.0, 2\.0\]; call once"):
        ctmm.steady_state_response(chain(), [1.0, 2.0])


def test_controlled_chain_with_a_number_for_a_loop():
    with pytest.raises(ctmm.ModelError, match=r"loops\[0\] must be a Feedback loop, got 3"):
        ControlledChain(chain(), [3])


def test_lti_controller_with_nan_coefficient():
    control = pytest.importorskip("control")
    with pytest.raises(ctmm.ModelError, match=r"loop 'L': gain \(LTI controller\) numerator coefficients must be "
                                              r"finite, got \[1\.0, nan\]"):
        Feedback("L", "m.x", "m", gain=control.tf([1.0, math.nan], [1.0, 1.0]))


@pytest.mark.parametrize("s", [math.nan, math.inf, complex(1.0, -math.inf)])
def test_characteristic_function_at_non_finite_s(s):
    with pytest.raises(ctmm.ModelError, match=r"s must contain only finite values"):
        ctmm.characteristic_function(chain(), s)


def test_planar_accelerations_with_an_extra_coordinate():
    from ctmm.planar import accelerations

    with pytest.raises(ctmm.ModelError, match=r"q must have length 1 \(coordinates l\.theta\) for model 'p', "
                                              r"got \[0\.0, 0\.0\]"):
        accelerations(pendulum(), [0.0, 0.0], [0.0])


def test_uniform_link_with_an_overflowing_inertia():
    from ctmm.planar import RigidBody

    with pytest.raises(ctmm.ModelError, match=r"l: inertia mass \* length\*\*2 / 12 must be finite and > 0, got inf "
                                              r"\(mass=1.0, length=1e\+300\)"):
        RigidBody.uniform_link("l", mass=1.0, length=1e300)


def test_manipulator_store_every_zero():
    from ctmm.manipulator import SEED_KD, SEED_KP, HubPD, manipulator_scene, seed_manipulator

    scene = manipulator_scene(seed_manipulator(), pd=HubPD(SEED_KP, SEED_KD), pzt=None)
    with pytest.raises(ctmm.ModelError, match=r"store_every must be an integer >= 1, got 0"):
        ctmm.simulate(scene, 0.01, 0.001, store_every=0)


def test_frequency_response_of_none():
    with pytest.raises(ctmm.ModelError, match=r"frequency_response: system must be a ctmm.Chain or a "
                                              r"ctmm.control.ControlledChain, got NoneType \(None\)"):
        ctmm.frequency_response(None, [1.0], input="m.force", output="m.x")


def test_the_chain_stepper_refuses_a_controlled_chain_and_names_the_verb_that_honours_it():
    from ctmm.timestep import simulate as simulate_chain

    with pytest.raises(ctmm.ModelError, match=r"system must be a ctmm.Chain, got .*use ctmm.simulate"):
        simulate_chain(controlled(), 0.1, 0.01)


class _TwoOutputs:
    """A controller that returns two values for its one output."""

    inputs = ("m.x",)
    outputs = ("m.force",)
    sample_time = None
    direct_feedthrough = False

    def init(self, t0):
        return None

    def step(self, t, y, state):
        return ControllerStep(np.array([1.0, 2.0]), state)


def test_controller_returning_two_values_for_one_output():
    with pytest.raises((ctmm.ModelError, ctmm.SimulationError), match=r"m\.force|outputs"):
        simulate_controlled(chain(), 0.05, 0.01, controllers=[_TwoOutputs()])


def test_algebraically_singular_acceleration_loop():
    system = ControlledChain(chain(), [Feedback("L", "m.a", "m", gain=-1.0)])   # m a = ... + a: no solution
    with pytest.raises((ctmm.ModelError, ctmm.SimulationError), match=r"'L'"):
        simulate_controlled(system, 0.05, 0.01, x0={"m": 0.1})


def test_stability_with_huge_delay():
    """A delay (or contour height) whose line sampling would exhaust memory is refused up front."""
    with pytest.raises(ctmm.ModelError, match=r"delay 1e\+300 s .* would need .* samples.*use delays below"):
        stability.unstable_root_count(controlled(), delay=1e300)
    with pytest.raises(ctmm.ModelError, match=r"contour 2e\+300 rad/s long .*smaller im_max"):
        stability.unstable_root_count(controlled(), im_max=1e300)


def test_delay_margin_with_huge_delay_max():
    """delay_max=1e300 would list every crossing up to it: refused with the largest useful value."""
    with pytest.raises(ctmm.ModelError, match=r"delay_max=1e\+300 s would list .* crossings.*give delay_max <="):
        stability.delay_margin(controlled(), delay_max=1e300)


def test_simulation_result_indexed_by_a_list():
    with pytest.raises(ctmm.UnknownNameError, match=r"unknown signal \"\['m\.x'\]\"; available: .*m\.x"):
        sim_result()[["m.x"]]


# --------------------------------------------------------------------------------------------
# valid edge inputs give correct results (closed-form references)
# --------------------------------------------------------------------------------------------
K, M = 10.0, 1.0
OMEGA_N = math.sqrt(K / M)


def test_single_mass_natural_frequency_and_shape():
    assert ctmm.natural_frequencies(chain(), n_modes=np.int64(1))[0] == pytest.approx(OMEGA_N, rel=1e-10)
    modes = ctmm.mode_shapes(chain(), n_modes=1)
    assert modes.natural_frequencies[0] == pytest.approx(OMEGA_N, rel=1e-10)


def test_single_mass_receptance_at_zero_and_one_frequency():
    """``x/F = 1 / (k - m w^2)``; omega = 0 (static) and a scalar omega are valid."""
    static = ctmm.frequency_response(chain(), 0.0, input="m.force", output="m.x")
    assert static("m.x", "m.force")[0] == pytest.approx(1.0 / K, rel=1e-12)
    scalar = ctmm.frequency_response(chain(), 2.0, input="m.force", output=("m.x",))
    assert scalar()[0] == pytest.approx(1.0 / (K - M * 4.0), rel=1e-12)


def test_single_mass_steady_state_of_a_harmonic_force():
    system = ctmm.Chain("c", [Fixed("w"), Spring("k", K), Mass("m", M, force=signals.Harmonic(1.0, 2.0)), Free("e")])
    phasor = ctmm.steady_state_response(system, 2.0, outputs="m.x")["m.x"]
    assert abs(phasor) == pytest.approx(1.0 / (K - 4.0 * M), rel=1e-12)


def test_single_mass_free_vibration_matches_cosine():
    """x(t) = x0 cos(w t); average-acceleration Newmark phase error ~ w^3 dt^2 t / 12 = 2.6e-6 rad here."""
    result = ctmm.simulate(chain(), 1.0, 1e-3, x0={"m": 0.1})
    exact = 0.1 * np.cos(OMEGA_N * result.time)
    assert np.max(np.abs(result["m.x"] - exact)) < 0.1 * 4e-6


def test_natural_frequencies_refuse_a_controlled_chain():
    with pytest.raises(ctmm.ModelError, match=r"natural_frequencies cannot honour the feedback loops \['L'\] of "
                                              r"'c\+control'.*characteristic_roots.*system.plant"):
        ctmm.natural_frequencies(controlled(), n_modes=1)


def test_mode_shapes_below_the_first_natural_frequency_are_empty():
    modes = ctmm.mode_shapes(chain(), omega_max=0.5 * OMEGA_N)
    assert modes.natural_frequencies.shape == (0,) and modes.shapes.shape == (0, 3, 2)


def test_single_feedback_without_a_list_and_empty_loops():
    loop = Feedback("L", sensor="m.x", actuator="m", gain=5.0)
    assert ControlledChain(chain(), loop).loops == (loop,)
    assert ControlledChain(chain(), []).loops == ()
    # closed loop m x'' + (k + g) x = 0: natural frequency sqrt((k + g) / m)
    closed = ControlledChain(chain(), [loop])
    assert ctmm.characteristic_function(closed, 1j * math.sqrt((K + 5.0) / M)) == pytest.approx(0.0, abs=1e-9)
