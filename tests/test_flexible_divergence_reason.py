"""The reason :func:`ctmm.flexible.outputs.check_divergence` gives for a diverged beam.

A pinned beam's highest frequency is far above its own clamped modes: an RK4 step at ``omega_max h = 2.9``
of the model (above 2 sqrt 2) but ``0.86`` of the beam's clamped modes must be reported as the unstable
explicit step, not as an unstable model.  ``omega_max`` is checked independently: the pinned-free Euler-Bernoulli
beam's second elastic mode (``tan x = tanh x``) bounds it from below (Rayleigh-Ritz).
"""
from __future__ import annotations

import numpy as np
import pytest

from ctmm.errors import SimulationError
from ctmm.flexible import ModalBeam
from ctmm.flexible.outputs import highest_frequency, model_highest_frequency
from ctmm.planar import Pinned, PlanarModel, simulate_implicit, simulate_rk4
from ctmm.schemes import Newmark

EI, MU, LENGTH = 1.0, 0.7, 1.0


@pytest.fixture(scope="module")
def pinned_beam() -> PlanarModel:
    return PlanarModel.chain("pb", [Pinned("o"), ModalBeam("b", length=LENGTH, bending_stiffness=EI,
                                                           mass_per_length=MU, n_modes=2)])


def test_the_model_frequency_is_the_pinned_beams_not_the_clamped_modes(pinned_beam):
    omega, source = model_highest_frequency(pinned_beam)
    # Rayleigh-Ritz bounds the highest of rigid rotation + 2 modes from above the exact second elastic mode
    # of the pinned-free beam (tan x = tanh x, x = 7.0686), far above the clamped modes of the beam alone
    pinned_free_second = 7.0686 ** 2 * np.sqrt(EI / (MU * LENGTH ** 4))
    assert omega >= pinned_free_second > 2.0 * highest_frequency(pinned_beam)[0]
    assert "linearised" in source


def test_an_rk4_step_above_the_models_limit_is_reported_as_the_step(pinned_beam):
    omega, _ = model_highest_frequency(pinned_beam)
    dt = 2.9 / omega
    assert dt * highest_frequency(pinned_beam)[0] < 2.83         # the clamped modes alone would clear the step
    q0 = np.array([0.0, 0.01, 0.0])
    with pytest.raises(SimulationError, match="explicit RK4 step is unstable") as info:
        simulate_rk4(pinned_beam, q0, np.zeros(3), t_final=400 * dt, dt=dt, stability_check="ignore")
    assert info.value.element == "b" and "model itself is unstable" not in str(info.value)


def test_an_implicit_scheme_is_not_declared_within_its_limit(pinned_beam):
    q0, v0 = np.array([0.3, 0.0, 0.0]), np.array([2.0, 0.0, 0.0])
    with pytest.warns(Warning, match="stab"), pytest.raises(SimulationError, match="StabilityLimitWarning") as info:
        simulate_implicit(pinned_beam, q0, v0, t_final=1.0, dt=0.025, scheme=Newmark(beta=0.25, gamma=0.3))
    assert "within the" not in str(info.value)
