"""The generated DT-TMM Newton of planar models iterates as the Python stepper (:mod:`ctmm.compiled_newton_weighting`).

The Python stepper (:func:`ctmm.planar.implicit.simulate_implicit`, the transfer form) is the independent side:
on a pinned modal beam with an unstable Newmark (``gamma = 0.3``) both runs must end at the same step with the
same error, the residual of a failed Newton step to its printed digits (the plain residual ``a - qddot`` cycled
at 0.45 s there while the transfer form converged and diverged at 0.6 s).
"""
from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from ctmm.compiled_newton_weighting import generalized_force_units
from ctmm.compiled_scene_schemes import simulate_scheme_generated
from ctmm.errors import ConvergenceError, SimulationError
from ctmm.flexible import ModalBeam
from ctmm.planar import FreeBase, Pinned, PlanarModel, RigidBody, simulate_implicit
from ctmm.schemes import Newmark

UNSTABLE = Newmark(beta=0.25, gamma=0.3)


@pytest.fixture(scope="module")
def pinned_beam() -> PlanarModel:
    return PlanarModel.chain("pb", [Pinned("o"), ModalBeam("b", length=1.0, bending_stiffness=1.0,
                                                           mass_per_length=0.7, n_modes=2)])


def _start() -> tuple[np.ndarray, np.ndarray]:
    return np.array([0.3, 0.0, 0.0]), np.array([2.0, 0.0, 0.0])


def _both(model: PlanarModel, **options) -> list[SimulationError]:
    errors = []
    for run in (simulate_implicit, simulate_scheme_generated):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")            # the stability check warns about gamma < 1/2
            with pytest.raises(SimulationError) as info:
                run(model, *_start(), t_final=1.0, dt=0.025, scheme=UNSTABLE, **options)
        errors.append(info.value)
    return errors


def test_both_stop_on_the_beam_divergence_at_the_same_time(pinned_beam):
    python, generated = _both(pinned_beam)
    assert type(python) is type(generated) is SimulationError        # neither is a ConvergenceError
    assert python.time == generated.time == pytest.approx(0.6)
    assert python.element == generated.element == "b"
    assert str(python) == str(generated)
    assert np.max(np.abs(python.partial_result.q - generated.partial_result.q)) <= 1e-9


def test_a_failed_newton_step_is_the_same_step_with_the_same_message(pinned_beam):
    python, generated = _both(pinned_beam, max_iterations=5)
    assert isinstance(python, ConvergenceError) and isinstance(generated, ConvergenceError)
    assert python.time == generated.time == pytest.approx(0.3)
    assert len(python.partial_result.t) == len(generated.partial_result.t) == 12
    number = r"= ([0-9.e+-]+) after"
    assert float(re.search(number, str(generated)).group(1)) == pytest.approx(
        float(re.search(number, str(python)).group(1)), rel=1e-3)
    assert re.sub(number, "", str(generated)) == "generated " + re.sub(number, "", str(python))


def test_the_generalized_force_basis_covers_hinges_and_modes_only(pinned_beam):
    assert len(generalized_force_units(pinned_beam)) == pinned_beam.n_coordinates
    free = PlanarModel.chain("free", [FreeBase("base"), RigidBody("body", mass=1.0, inertia=0.1)])
    assert generalized_force_units(free) is None        # plain residual there (documented)
