"""Manipulator runs that go wrong: named controller failures with partial results, divergence of the
Python and compiled paths, the RK4 limit before the run, bad options (issue 11)."""
from __future__ import annotations

import math
import shutil

import numpy as np
import pytest

from ctmm.errors import ModelError, SimulationError
from ctmm.guard import StabilityLimitWarning
from ctmm.manipulator import SEED_KD, SEED_KP, SEED_MOVE, SEED_PZT_GAIN, FlexibleManipulator, HubPD, PZTFeedback, \
    seed_manipulator
from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

G_SEED = np.eye(3) * SEED_PZT_GAIN


@pytest.fixture(scope="module")
def system():
    return FlexibleManipulator(seed_manipulator(), HubPD(SEED_KP, SEED_KD), PZTFeedback(G_SEED), SEED_MOVE)


class _Torque:
    """Hub torque controller that misbehaves from ``after`` [s] on."""

    inputs = ("hub.theta",)
    outputs = ("motor.torque",)
    sample_time = None

    def __init__(self, after: float, mode: str) -> None:
        self.after, self.mode = after, mode

    def init(self, t):
        return None

    def step(self, t, y, state):
        if t < self.after:
            return [0.0], state
        if self.mode == "raise":
            raise ZeroDivisionError("gain schedule")
        if self.mode == "nan":
            return [math.nan], state
        return [1.0, 2.0], state


@pytest.mark.parametrize("mode, match", [("raise", "raised ZeroDivisionError at t = 0.01 s: gain schedule"),
                                         ("nan", "returned a non-finite value"),
                                         ("shape", "returned 2 value.*expected 1")])
@pytest.mark.parametrize("method", ["rk4", "newmark"])
def test_failing_controller_is_named_with_time_and_partial_result(system, mode, match, method):
    with pytest.raises(SimulationError, match=f"controller 0 \\(_Torque\\) {match}") as info:
        system.simulate(0.03, 0.002, method=method, controllers=[_Torque(0.01, mode)], store_every=2)
    error = info.value
    assert error.time == pytest.approx(0.01) and error.element == "controller 0 (_Torque)"
    partial = error.partial_result
    assert partial.t[-1] == pytest.approx(0.008) and partial.q.shape == (partial.t.size, 3)
    assert np.all(np.isfinite(partial.tip_deflection)) and partial.torque.shape == partial.t.shape


def test_store_every_and_options_are_validated(system):
    with pytest.raises(ModelError, match="store_every must be an integer >= 1, got 0"):
        system.simulate(0.01, 0.002, store_every=0)
    with pytest.raises(ModelError, match="stability_check must be one of"):
        system.simulate(0.01, 0.002, method="newmark", stability_check="maybe")
    with pytest.raises(ModelError, match="divergence_bound must be a number > 0"):
        system.simulate(0.01, 0.002, divergence_bound=0.0)


def test_rk4_step_above_the_limit_is_reported_before_the_run(system):
    # omega_max of the linearised hub + arm with its embedded PD and PZT laws, independently from
    # the Lagrange reference: the largest |eigenvalue| of [[0, I], [-M^-1 K, -M^-1 C]] with
    # K += kp (hub), C += kd (hub) + B_voltage G C_slopes (V = -G slope rates)
    lin = ManipulatorLagrange.from_manipulator(system.manipulator, 3).linearize()
    M, C, K = lin["M"], lin["D"].copy(), lin["K"].copy()
    K[0, 0] += SEED_KP
    C[0, 0] += SEED_KD
    C += lin["B_voltage"] @ G_SEED @ lin["C_slopes"]
    eigen = np.linalg.eigvals(np.block([[np.zeros_like(M), np.eye(len(M))],
                                         [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]]))
    limit = 2 * math.sqrt(2) / np.max(np.abs(eigen))
    with pytest.raises(ModelError, match=r"use dt <= ") as info:
        system.simulate(0.04, 0.02, stability_check="error")
    suggested = float(str(info.value).split("use dt <= ")[1].split(" s")[0])
    assert suggested == pytest.approx(limit, rel=1e-3)          # 266.78 rad/s both ways


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_compiled_path_stops_at_the_first_bad_block(system):
    pytest.importorskip("casadi")
    from ctmm.manipulator.compiled import CompiledManipulator

    for bad in ({"block": 0}, {"block": 2.5}, {"chunks": True}):
        with pytest.raises(ModelError, match=f"{next(iter(bad))} must be an integer >= 1"):
            CompiledManipulator(system.manipulator, system.pd, system.pzt, system.reference, **bad)
    compiled = CompiledManipulator(system.manipulator, system.pd, system.pzt, system.reference, block=2, chunks=5)
    with pytest.warns(StabilityLimitWarning):
        with pytest.raises(SimulationError, match="diverged") as info:
            compiled.simulate(0.4, 0.02, divergence_bound=1.0)
    partial = info.value.partial_result
    assert partial.t.size >= 1 and partial.t[-1] < info.value.time
    assert np.all(np.abs(partial.theta - partial.theta[0]) <= 1.0)


@pytest.mark.parametrize("method", ["rk4", "newmark"])
def test_controller_failing_at_the_first_sample_gives_an_empty_partial_result(system, method):
    with pytest.raises(SimulationError, match=r"controller 0 \(_Torque\) raised ZeroDivisionError at t = 0 s") as info:
        system.simulate(0.01, 0.002, method=method, controllers=[_Torque(0.0, "raise")])
    partial = info.value.partial_result
    assert partial.t.size == 0 and partial.q.shape == (0, 3) and partial.peak_voltage == 0.0


def test_both_manipulator_models_refuse_a_pzt_law_that_does_not_fit():
    from ctmm.manipulator import manipulator_scene

    seed = seed_manipulator()
    for make in (lambda pzt: FlexibleManipulator(seed, HubPD(SEED_KP, SEED_KD), pzt, SEED_MOVE),
                 lambda pzt: manipulator_scene(seed, pd=HubPD(SEED_KP, SEED_KD), pzt=pzt)):
        with pytest.raises(ModelError, match="pzt gains are for 2 patches, the manipulator has 3"):
            make(PZTFeedback(np.eye(2)))
        with pytest.raises(ModelError, match="pzt must be a PZTFeedback or None, got 'fast'"):
            make("fast")
