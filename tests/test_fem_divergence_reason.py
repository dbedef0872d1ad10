"""The reason a finite-element subsystem's divergence gives (:class:`ctmm.fem.family.SubsystemFamily`): decided, as a
modal beam's (:func:`ctmm.flexible.outputs.divergence_reason`), not "may".

A cantilever of three Hermite beam elements welded to the ground.  Its highest frequency ``omega_max`` comes from
the assembled finite-element matrices directly (``FiniteElementModel.natural_frequencies``, ``eigh(K, M)`` clamped at
the root), not from the planar model: the RK4 limit is ``2 sqrt 2 / omega_max``.

* An RK4 step 5 % above that limit: the run diverges and the message must name the step, with its limit.
* A stable step (0.3 of the limit) on the same cantilever under twice its Euler buckling load
  ``pi^2 EI / (4 L^2)`` (compression in every element): the model itself is unstable, and the message must say
  so (with the limit, and that the step is within it).
"""
from __future__ import annotations

import re

import numpy as np
import pytest
import scipy.linalg

from ctmm.errors import ModelError, SimulationError
from ctmm.fem import BeamElement, FiniteElementModel
from ctmm.planar import PlanarModel, simulate_rk4
from ctmm.planar.elements import Fixed

EI, EA, RHO_A, LENGTH, ELEMENTS = 2.0, 50.0, 1.0, 1.0, 3
RK4_LIMIT = 2.0 * np.sqrt(2.0)              # omega h on the imaginary axis of the classical RK4


def cantilever(axial_force: float = 0.0) -> tuple[FiniteElementModel, PlanarModel]:
    nodes = {f"n{k}": (k * LENGTH / ELEMENTS, 0.0) for k in range(ELEMENTS + 1)}
    fe = FiniteElementModel("beam", nodes, [BeamElement(f"e{k}", f"n{k}", f"n{k + 1}", EI, EA, RHO_A, axial_force)
                                            for k in range(ELEMENTS)])
    return fe, PlanarModel.chain("cantilever", [Fixed("ground"), fe.subsystem("sub", ("n0",))], gravity=(0.0, 0.0))


def stated_limit(message: str) -> float:
    return float(re.search(r"limit 2 sqrt 2/omega_max = ([0-9.e+-]+) s", message).group(1))


def tip_displaced(model: PlanarModel) -> np.ndarray:
    q0 = np.zeros(model.n_coordinates)
    q0[model.coordinates.index(f"sub.n{ELEMENTS}_uy")] = 0.01
    return q0


def test_an_rk4_step_above_the_subsystems_limit_is_named_as_the_cause():
    fe, model = cantilever()
    limit = RK4_LIMIT / fe.natural_frequencies(clamped=["n0"]).max()
    dt = 1.05 * limit
    q0 = tip_displaced(model)
    with pytest.raises(SimulationError, match="the explicit RK4 step is unstable") as info:
        simulate_rk4(model, q0, np.zeros_like(q0), t_final=2000 * dt, dt=dt, stability_check="ignore")
    message = str(info.value)
    assert info.value.element == "sub" and "may" not in message and "model itself" not in message
    assert f"dt = {dt:g} s" in message
    assert stated_limit(message) == pytest.approx(limit, rel=1e-3)


def test_a_buckled_subsystem_at_a_stable_step_is_named_as_the_model():
    buckling = np.pi ** 2 * EI / (4.0 * LENGTH ** 2)
    fe, model = cantilever(axial_force=-2.0 * buckling)
    stable, _ = cantilever()
    with pytest.raises(ModelError, match="statically unstable"):       # eigh(K, M) has a negative eigenvalue
        fe.natural_frequencies(clamped=["n0"])
    assert stable.natural_frequencies(clamped=["n0"])[0] > 0.0
    free = [i for i in range(fe.n_dofs) if i not in fe.dofs["n0"]]
    omega_squared = scipy.linalg.eigh(fe.stiffness[np.ix_(free, free)], fe.mass[np.ix_(free, free)], eigvals_only=True)
    limit = RK4_LIMIT / np.sqrt(omega_squared.max())
    dt = 0.3 * limit
    q0 = tip_displaced(model)
    with pytest.warns(Warning, match="small-deformation"), \
            pytest.raises(SimulationError, match="model itself is unstable") as info:
        simulate_rk4(model, q0, np.zeros_like(q0), t_final=20000 * dt, dt=dt, stability_check="ignore")
    message = str(info.value)
    assert info.value.element == "sub" and "may" not in message and "step is unstable" not in message
    assert f"dt = {dt:g} s is within the RK4 stability limit" in message
    assert stated_limit(message) == pytest.approx(limit, rel=1e-3)
    assert "buckling" in message
