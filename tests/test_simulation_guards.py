"""ctmm.simulate: controlled systems honoured, stability limits before the run, divergence stopped with
the partial result, failing user code named (issue 11).

Independent references: global closed-loop Newmark on M, C, K (``ctmm.reference.delay_newmark``),
the eigenvalues of the global M, K (``ctmm.reference.chain``), the analytic stability limit of the
linear-acceleration method (Wilson theta = 1: omega h = 2 sqrt 3) and Newmark's limit
``1 / sqrt(gamma/2 - beta)`` (Hughes eq. 9.1.30).
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import scipy.linalg as sla

import ctmm
from ctmm.control import ControlledChain, ControllerStep, Feedback, simulate_controlled
from ctmm.elements import Damper, Fixed, Free, GroundedSpring, Mass, Spring, SpringDamper
from ctmm.errors import ModelError, SimulationError
from ctmm.guard import StabilityLimitWarning
from ctmm.reference import chain as ref
from ctmm.reference.delay_newmark import newmark_closed_loop
from ctmm.schemes import GeneralizedAlpha, Houbolt, Newmark, WilsonTheta
from ctmm.step_limit import frequency_bound, highest_natural_frequency
from ctmm.timestep import simulate as simulate_chain

from _chain_convert import random_chain, to_global
from test_controlled_frequency import build


def seed_plant(**forces) -> ctmm.Chain:
    """README seed chain: wall -K1- m2 -K3- m4 -K5- m6 - free (1 kg, 1000 N/m, 0.5 N s/m)."""
    return ctmm.Chain("seed", [Fixed("wall"), SpringDamper("K1", 1000, 0.5), Mass("m2", 1, force=forces.get("m2", 0.0)),
                               SpringDamper("K3", 1000, 0.5), Mass("m4", 1), SpringDamper("K5", 1000, 0.5),
                               Mass("m6", 1), Free("tip")])


def oscillator(k: float = 100.0, m: float = 1.0) -> ctmm.Chain:
    """Undamped oscillator, omega = sqrt(k / m) [rad/s]."""
    return ctmm.Chain("sdof", [Fixed("wall"), Spring("k", k), Mass("m", m), Free("tip")])


# ----------------------------------------------------------- bug 1: controlled systems honoured
def test_simulate_closes_the_loops_of_a_controlled_chain():
    """Issue 11: m6.x at 0.5 s was the open loop's (0.00506 m); now it is the closed loop's, equal to
    the global closed-loop Newmark of M, C, K."""
    setup = build([1.0, 1.0, 1.0], [1000.0] * 3 + [0.0], [0.5] * 3 + [0.0], [0.0] * 3, start="fixed", end="free",
                  loops=[(2, "velocity", 0, 50.0, 0.01, None, False)])
    result = ctmm.simulate(setup.system, 0.5, 1e-3, x0={"m0": 0.01})
    reference = newmark_closed_loop(setup.chain, setup.global_loops, 0.5, 1e-3, [0.01, 0.0, 0.0], [0.0] * 3)
    x = np.column_stack([result[f"m{i}.x"] for i in range(3)])
    assert np.max(np.abs(x - reference.displacement)) < 1e-12
    np.testing.assert_allclose(result["loop0.u"], reference.control[:, 0], rtol=0, atol=1e-10)
    open_loop = ctmm.simulate(setup.plant, 0.5, 1e-3, x0={"m0": 0.01})
    assert abs(open_loop["m2.x"][-1] - result["m2.x"][-1]) > 1e-3     # the loop matters here


def test_simulate_routes_controllers_and_refuses_what_does_not_apply():
    plant = seed_plant()
    system = ControlledChain(plant, [Feedback("Ka", sensor="m6.v", actuator="m2", gain=50.0, delay=0.01)])
    a = ctmm.simulate(system, 0.05, 1e-3, x0={"m6": 0.01}, references={"Ka": 0.1})
    b = simulate_controlled(system, 0.05, 1e-3, x0={"m6": 0.01}, references={"Ka": 0.1})
    np.testing.assert_array_equal(a.states, b.states)
    with pytest.raises(ModelError, match="solver='plain' applies to uncontrolled chains only"):
        ctmm.simulate(system, 0.05, 1e-3, solver="plain")
    with pytest.raises(ModelError, match="system must be a ctmm.Chain, got ControlledChain.*; use ctmm.simulate"):
        simulate_chain(system, 0.05, 1e-3)


# ------------------------------------------------------------ bug 2: stability limit before the run
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_highest_natural_frequency_against_global_eigenvalues(seed):
    chain = random_chain(np.random.default_rng(seed), 7, start="fixed", end="elastic", damped=True, grounded=True)
    M, _, K = ref.assemble(to_global(chain))
    exact = math.sqrt(sla.eigh(K, M, eigvals_only=True)[-1])
    omega, is_exact = highest_natural_frequency(chain, rtol=1e-9)
    assert is_exact and exact <= omega <= exact * (1 + 2e-9)
    assert frequency_bound(chain) >= exact


def test_frequency_bound_with_a_pure_damper_is_an_upper_bound():
    chain = ctmm.Chain("d", [Fixed("wall"), SpringDamper("k1", 400.0, 0.0), Mass("m1", 1.0), Damper("c", 2.0),
                             Mass("m2", 4.0), GroundedSpring("g", 100.0), Free("tip")])
    omega, is_exact = highest_natural_frequency(chain)
    assert not is_exact and omega >= 20.0          # true undamped frequencies: 20 and 5 rad/s


def test_newmark_limit_warns_or_errs_before_the_run():
    """omega = 10 rad/s; Newmark(0.01, 1/2) is stable for omega dt <= 1/sqrt(0.24) = 2.041."""
    chain = oscillator(100.0)
    limit = 1.0 / math.sqrt(0.5 / 2 - 0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stable = ctmm.simulate(chain, 2.0, 0.2, x0={"m": 0.01}, scheme=Newmark(0.01, 0.5))   # omega dt = 2
    assert np.max(np.abs(stable["m.x"])) < 0.02
    with pytest.warns(StabilityLimitWarning, match=r"omega_max \* dt = 2.06 exceeds its limit 2.041"):
        ctmm.simulate(chain, 0.206, 0.206, x0={"m": 0.01}, scheme=Newmark(0.01, 0.5))
    with pytest.raises(ModelError, match="exceeds its limit"):
        ctmm.simulate(chain, 10.0, 1.0, x0={"m": 0.01}, scheme=Newmark(0.01, 0.5), stability_check="error")
    with pytest.raises(ModelError, match=r"Newmark\(beta=0.25, gamma=0.0\) is not stable at any step size"):
        ctmm.simulate(chain, 10.0, 1.0, x0={"m": 0.01}, scheme=Newmark(0.25, 0.0))
    with pytest.raises(ModelError, match="stability_check must be"):
        ctmm.simulate(chain, 10.0, 1.0, scheme=Newmark(0.01, 0.5), stability_check="loud")


def test_issue_newmark_blow_up_is_stopped_early():
    """Issue 11: beta = 0.01 at omega dt = 10 returned 6e165 m; ignoring the check, the guard stops it."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(SimulationError, match=r"diverged at t = \d+ s: 'm' is .* beyond the bound 1e\+06") as info:
            ctmm.simulate(oscillator(100.0), 500.0, 1.0, x0={"m": 0.01}, scheme=Newmark(0.01, 0.5),
                          stability_check="ignore")
    partial = info.value.partial_result
    assert info.value.element == "m" and info.value.time < 50.0
    assert len(partial.time) == int(round(info.value.time)) and np.max(np.abs(partial["m.x"])) <= 1e6


def test_wilson_theta_one_limit_is_two_sqrt_three():
    """The linear-acceleration method (theta = 1): bounded just below omega dt = 2 sqrt 3, growing above."""
    omega = 10.0
    chain = oscillator(omega ** 2)
    below, above = 0.98 * 2 * math.sqrt(3) / omega, 1.02 * 2 * math.sqrt(3) / omega
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = ctmm.simulate(chain, 300 * below, below, x0={"m": 0.01}, scheme=WilsonTheta(1.0))
    assert np.max(np.abs(run["m.x"])) < 0.0105
    with pytest.warns(StabilityLimitWarning, match="limit 3.464"):
        run = ctmm.simulate(chain, 40 * above, above, x0={"m": 0.01}, scheme=WilsonTheta(1.0))
    assert np.max(np.abs(run["m.x"])) > 1.0


@pytest.mark.parametrize("scheme", [GeneralizedAlpha(0.0), Houbolt(), WilsonTheta(1.4), Newmark(0.3025, 0.6)])
def test_unconditionally_stable_schemes_do_not_warn(scheme):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = ctmm.simulate(oscillator(1e6), 5.0, 0.1, x0={"m": 0.01}, scheme=scheme)   # omega dt = 100
    amplitude = np.abs(run["m.x"])
    assert np.max(amplitude[-10:]) <= np.max(amplitude[1:11])   # no growth (Wilson overshoots at first)


# ---------------------------------------------------- bugs 4, 5: user code named, partial results
def raising_after(t_fail, value=1.0):
    def force(t):
        if t > t_fail:
            raise KeyError("sensor offline")
        return value
    return force


@pytest.mark.parametrize("fast", [True, False])
@pytest.mark.parametrize("force, match", [
    (raising_after(0.0505), r"user function 'm2: force' raised KeyError at t = 0.051 s"),
    (lambda t: math.nan if t > 0.0505 else 1.0, r"'m2: force' returned a non-finite value \[nan\] at t = 0.051 s"),
    (lambda t: [1.0, 2.0] if t > 0.0505 else 1.0, r"'m2: force' returned 2 value\(s\) at t = 0.051 s; expected 1"),
])
def test_force_callback_failure_is_named_with_partial_result(force, match, fast):
    with pytest.raises(SimulationError, match=match) as info:
        ctmm.simulate(seed_plant(m2=force), 0.1, 1e-3, fast=fast)
    partial = info.value.partial_result
    assert info.value.time == pytest.approx(0.051) and "m2: force" in info.value.element
    assert len(partial.time) == 51 and partial.time[-1] == pytest.approx(0.05)
    assert np.all(np.isfinite(partial.states))


def test_failing_force_in_a_controlled_run_keeps_every_loop_signal():
    system = ControlledChain(seed_plant(m2=raising_after(0.0305)),
                             [Feedback("Ka", sensor="m6.v", actuator="m2", gain=50.0, delay=0.01),
                              Feedback("Kp", sensor="m4.x", actuator="m4", gain=10.0)])
    with pytest.raises(SimulationError, match="'m2: force' raised KeyError at t = 0.031 s") as info:
        ctmm.simulate(system, 0.1, 1e-3, x0={"m6": 0.01})
    partial = info.value.partial_result
    assert len(partial.time) == 31
    for name in ("Ka.y", "Ka.u", "Kp.y", "Kp.u", "m6.x"):
        assert partial[name].shape == (31,) and np.all(np.isfinite(partial[name]))
    full = ctmm.simulate(ControlledChain(seed_plant(m2=1.0), system.loops), 0.03, 1e-3, x0={"m6": 0.01})
    np.testing.assert_array_equal(partial["Ka.u"], full["Ka.u"])       # same run up to the failure


class Gain:
    """A co-simulated proportional controller ``u = -k y`` whose ``step`` can misbehave after ``t_bad``."""

    inputs = ("m6.x",)
    outputs = ("m2.force",)
    sample_time = 2e-3
    direct_feedthrough = True
    name = "P"

    def __init__(self, mode: str, t_bad: float = 0.02) -> None:
        self.mode, self.t_bad = mode, t_bad

    def init(self, t0):
        return 0

    def step(self, t, y, state):
        u = -50.0 * y
        if t > self.t_bad:
            if self.mode == "raise":
                raise ZeroDivisionError("bad")
            if self.mode == "nan":
                u = np.array([math.nan])
            if self.mode == "two":
                u = np.array([u[0], 1.0])
        return ControllerStep(u, state + 1)


@pytest.mark.parametrize("mode, match", [
    ("raise", r"controller 'P' \(outputs \['m2.force'\]\) raised ZeroDivisionError at t = 0.022 s"),
    ("nan", r"controller 'P' \(outputs \['m2.force'\]\) returned a non-finite value \[nan\] at t = 0.022 s"),
    ("two", r"controller 'P' \(outputs \['m2.force'\]\) returned 2 value\(s\) at t = 0.022 s; expected 1"),
])
def test_controller_failure_is_named_with_partial_samples(mode, match):
    with pytest.raises(SimulationError, match=match) as info:
        ctmm.simulate(seed_plant(), 0.1, 1e-3, x0={"m6": 0.01}, controllers=[Gain(mode)])
    partial = info.value.partial_result
    assert info.value.time == pytest.approx(0.022)
    samples = partial["m2.force@samples"]
    assert len(partial.time) == 23 and samples[-1, 0] <= partial.time[-1]
    assert samples.shape == (11, 2) and np.all(np.isfinite(samples))


def test_lti_controller_with_nan_coefficient_is_refused():
    import control

    with pytest.raises(ModelError, match=r"loop 'L': gain \(LTI controller\) state-space matrix C must be finite"):
        Feedback("L", sensor="m6.v", actuator="m2", gain=control.ss([[-1.0]], [[1.0]], [[math.nan]], [[0.0]]))


def test_singular_acceleration_loop_is_a_model_error_naming_the_loop():
    """u = -g a(m2) on m2 (1 kg) with g = -1: (m + g) a = F has no unique acceleration."""
    system = ControlledChain(seed_plant(), [Feedback("La", sensor="m2.a", actuator="m2", gain=-1.0)])
    with pytest.raises(ModelError, match=r"singular algebraic loop: loop 'La' senses \['m2.a'\] with gain -1 "
                                         r"and d\(sensed\)/d\(own force\) = 1"):
        ctmm.simulate(system, 0.01, 1e-3, x0={"m6": 0.01})


def test_initial_values_are_validated():
    with pytest.raises(ModelError, match=r"x0 must be a mapping \{element name: number\} or None, got \[0.1\]"):
        ctmm.simulate(seed_plant(), 0.01, 1e-3, x0=[0.1])
    with pytest.raises(ModelError, match=r"x0\['wall'\] = 0.1: 'wall' is a support that prescribes its own motion"):
        ctmm.simulate(seed_plant(), 0.01, 1e-3, x0={"wall": 0.1})
    with pytest.raises(ModelError, match=r"gives 1e\+300 steps; at most 5e\+07 are allowed"):
        ctmm.simulate(seed_plant(), 1.0, 1e-300)
