"""Manipulator runs that go wrong: named controller failures with partial results on the scene run by
``ctmm.simulate``, divergence of the compiled path, the RK4 limit before the run, bad options (issue 11)."""
from __future__ import annotations

import math
import shutil

import numpy as np
import pytest

import ctmm
from ctmm.errors import ModelError, SimulationError
from ctmm.guard import StabilityLimitWarning
from ctmm.manipulator import (SEED_KD, SEED_KP, SEED_MOVE, SEED_PZT_GAIN, HubPD, PZTFeedback, manipulator_scene,
                              scene_references, seed_manipulator)
from ctmm.reference.manipulator_lagrange import ManipulatorLagrange

G_SEED = np.eye(3) * SEED_PZT_GAIN
PD = HubPD(SEED_KP, SEED_KD)
NAMED = r"controller '_Torque' \(outputs \['motor.torque'\]\)"
ELEMENT = "controller '_Torque' (outputs ['motor.torque'])"


@pytest.fixture(scope="module")
def system():
    return manipulator_scene(seed_manipulator(), pd=PD, pzt=PZTFeedback(G_SEED))


def simulate(scene, t_final, dt, **options):
    return ctmm.simulate(scene, t_final, dt, references=scene_references(PD, SEED_MOVE), **options)


class _Torque:
    """Hub torque controller that misbehaves from ``after`` [s] on."""

    inputs = ("hub.theta",)
    outputs = ("motor.torque",)
    sample_time = None
    direct_feedthrough = False

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
    with pytest.raises(SimulationError, match=f"{NAMED} {match}") as info:
        simulate(system, 0.03, 0.002, method=method, controllers=[_Torque(0.01, mode)], store_every=2,
                 outputs=["arm.tip.w"])
    error = info.value
    assert error.time == pytest.approx(0.01) and error.element == ELEMENT
    partial = error.partial_result
    assert partial.time[-1] == pytest.approx(0.008) and partial["arm.q3"].shape == partial.time.shape
    assert np.all(np.isfinite(partial["arm.tip.w"])) and partial["hub_pd.u"].shape == partial.time.shape


def test_store_every_and_options_are_validated(system):
    with pytest.raises(ModelError, match="store_every must be an integer >= 1, got 0"):
        simulate(system, 0.01, 0.002, store_every=0)
    with pytest.raises(ModelError, match="stability_check must be one of"):
        simulate(system, 0.01, 0.002, method="newmark", stability_check="maybe")
    with pytest.raises(ModelError, match="divergence_bound must be a number > 0"):
        simulate(system, 0.01, 0.002, divergence_bound=0.0)


def _rk4_limit(M, C, K) -> float:
    eigen = np.linalg.eigvals(np.block([[np.zeros_like(M), np.eye(len(M))],
                                         [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]]))
    return 2 * math.sqrt(2) / np.max(np.abs(eigen))


def _suggested(run) -> float:
    with pytest.raises(ModelError, match=r"use dt <= ") as info:
        run()
    return float(str(info.value).split("use dt <= ")[1].split(" s")[0])


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_rk4_step_above_the_limit_is_reported_before_the_run(system):
    # omega_max of the linearised hub + arm, independently from the Lagrange reference: the largest
    # |eigenvalue| of [[0, I], [-M^-1 K, -M^-1 C]]; the compiled path checks the closed loop
    # (K += kp (hub), C += kd (hub) + B_voltage G C_slopes (V = -G slope rates)), ctmm.simulate the
    # plant without its loops (planar_time: "step limit of the plant before the run")
    pytest.importorskip("casadi")
    from ctmm.manipulator.compiled import CompiledManipulator

    seed = seed_manipulator()
    lin = ManipulatorLagrange.from_manipulator(seed, 3).linearize()
    M, C, K = lin["M"], lin["D"].copy(), lin["K"].copy()
    plant_limit = _rk4_limit(M, C, K)
    K[0, 0] += SEED_KP
    C[0, 0] += SEED_KD
    C += lin["B_voltage"] @ G_SEED @ lin["C_slopes"]
    closed_limit = _rk4_limit(M, C, K)
    compiled = CompiledManipulator(seed, PD, PZTFeedback(G_SEED), SEED_MOVE, block=2, chunks=5)
    suggested = _suggested(lambda: compiled.simulate(0.04, 0.02, stability_check="error"))
    assert suggested == pytest.approx(closed_limit, rel=1e-3)          # 266.78 rad/s both ways
    suggested = _suggested(lambda: simulate(system, 0.04, 0.02, stability_check="error"))
    assert suggested == pytest.approx(plant_limit, rel=1e-3)           # 272.10 rad/s both ways


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_compiled_path_stops_at_the_first_bad_block():
    pytest.importorskip("casadi")
    from ctmm.manipulator.compiled import CompiledManipulator

    seed, pzt = seed_manipulator(), PZTFeedback(G_SEED)
    for bad in ({"block": 0}, {"block": 2.5}, {"chunks": True}):
        with pytest.raises(ModelError, match=f"{next(iter(bad))} must be an integer >= 1"):
            CompiledManipulator(seed, PD, pzt, SEED_MOVE, **bad)
    compiled = CompiledManipulator(seed, PD, pzt, SEED_MOVE, block=2, chunks=5)
    with pytest.warns(StabilityLimitWarning):
        with pytest.raises(SimulationError, match="diverged") as info:
            compiled.simulate(0.4, 0.02, divergence_bound=1.0)
    partial = info.value.partial_result
    assert partial.t.size >= 1 and partial.t[-1] < info.value.time
    assert np.all(np.abs(partial.theta - partial.theta[0]) <= 1.0)


@pytest.mark.parametrize("method", ["rk4", "newmark"])
def test_controller_failing_at_the_first_sample_gives_an_empty_partial_result(system, method):
    with pytest.raises(SimulationError, match=f"{NAMED} raised ZeroDivisionError at t = 0 s") as info:
        simulate(system, 0.01, 0.002, method=method, controllers=[_Torque(0.0, "raise")])
    partial = info.value.partial_result
    assert partial.time.size == 0 and partial["arm.q3"].shape == (0,) and partial["pzt1.u"].shape == (0,)


def test_both_manipulator_models_refuse_a_pzt_law_that_does_not_fit():
    from ctmm.manipulator.compiled import CompiledManipulator

    seed = seed_manipulator()
    for make in (lambda pzt: CompiledManipulator(seed, PD, pzt, SEED_MOVE),
                 lambda pzt: manipulator_scene(seed, pd=PD, pzt=pzt)):
        with pytest.raises(ModelError, match="pzt gains are for 2 patches, the manipulator has 3"):
            make(PZTFeedback(np.eye(2)))
        with pytest.raises(ModelError, match="pzt must be a PZTFeedback or None, got 'fast'"):
            make("fast")
