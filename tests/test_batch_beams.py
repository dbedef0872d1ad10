"""Parameter sets of modal spatial beams on one generated kernel: ``ctmm.simulate(..., compiled=True,
parameters=...)`` and ``ctmm.simulate_batch`` of models with a :class:`~ctmm.spatial.SpatialBeam` (issue 13).

Independent check: every member equals the model *rebuilt by hand with the member's numbers* (a new
``SpatialBeam``, its modal data computed again) and run by the numpy RK4 (``ctmm.simulate`` without
``compiled``), to 1e-12 of max(1, peak) (measured 1e-14); the cache folder (counted by the operating system) shows that one library served
every set.  A set that diverges fails by its index, the others kept; a beam's length is refused with the reason.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError, SimulationError

pytest.importorskip("casadi")

from test_batch import assert_round_off, libraries  # noqa: E402  (round-off relative to max(1, peak))
pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")

DT, T_FINAL = 2e-3, 0.1
BEAM = dict(length=1.0, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=4.0, n_modes_y=2,
            n_modes_z=1, n_torsion_modes=1, torsional_stiffness=1.5, polar_inertia_per_length=0.004,
            n_axial_modes=1, axial_stiffness=300.0, damping_ratio=0.01, stiffness_damping=0.002)
START = dict(x0={"j.angle": 0.2, "b.qy1": 0.01, "b.qz1": -0.02}, v0={"j.angle_rate": 1.5})
SETS = [{"b.mass_per_length": 1.3, "b.bending_stiffness_y": 9.0, "b.torsional_stiffness": 2.5, "b.damping_ratio": 0.05},
        {"b.bending_stiffness_z": 2.5, "b.axial_stiffness": 150.0, "b.polar_inertia_per_length": 0.007,
         "b.stiffness_damping": 0.01, "j.stiffness": 5.0, "gravity.z": -4.0},
        {}]


def plant(stiffness=3.0, gravity_z=-9.81, **beam):
    """A beam on a sprung, damped revolute joint about an axis tilted from the vertical (gravity bends and
    twists it), written out number by number."""
    return sp.SpatialModel("flexarm", [
        sp.SpatialBeam("b", **{**BEAM, **beam}),
        sp.Revolute(name="j", parent=None, child="b", axis=(0.0, 0.3, 1.0), stiffness=stiffness, damping=0.2,
                    actuated=True)], gravity=(0.0, 0.5, gravity_z))


def rebuilt(values: dict) -> dict:
    """The keyword arguments of :func:`plant` for a set ``{name: number}``."""
    out = {}
    for name, value in values.items():
        owner, _, attribute = name.partition(".")
        out[{"j": "stiffness", "gravity": "gravity_z"}.get(owner, attribute)] = value
    return out


def controlled(gain=1.0, **numbers):
    return with_feedback(plant(**numbers), [Feedback("pd", [("j.angle", 4.0), ("j.rate", 0.5)], "j.torque",
                                                     gain=gain)])


def test_beam_sets_on_one_library_equal_the_numpy_run_of_the_rebuilt_model(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    batch = ctmm.simulate_batch(plant(), SETS, T_FINAL, DT, **START)
    assert not batch.failures and len(libraries(tmp_path)) == 1
    for k, values in enumerate(SETS):
        model = plant(**rebuilt(values))
        numpy_run = ctmm.simulate(model, T_FINAL, DT, method="rk4", **START)
        assert batch.results[k].info["parameters"] == values
        for name in list(model.coordinates) + list(model.velocities):
            assert_round_off(batch.results[k][name], numpy_run[name], (k, name))
    moved = np.abs(batch.stacked("b.qy1")[0] - batch.stacked("b.qy1")[2])
    assert moved.max() > 1e-3                              # the numbers really changed the run
    single = ctmm.simulate(plant(), T_FINAL, DT, compiled=True, parameters=SETS[1], **START)
    assert_round_off(single["b.u1"], batch.results[1]["b.u1"], "simulate(parameters=)", 1e-15)
    assert len(libraries(tmp_path)) == 1


def test_controlled_beam_sets_equal_the_numpy_loop_driver(tmp_path, monkeypatch):
    """Beam numbers and the loop gain as inputs of one CompiledControlledSpatial, a station output of the beam."""
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    sets = {"pd.gain": [2.0, 0.5], "b.bending_stiffness_y": [8.0, 5.0], "b.mass_per_length": [0.7, 1.1],
            "b.axial_stiffness": [200.0, 400.0]}
    batch = ctmm.simulate_batch(controlled(), sets, T_FINAL, DT, outputs=["b.tip.y"], references={"pd": 0.1},
                                **START)
    assert not batch.failures and len(libraries(tmp_path)) == 1
    for k in range(2):
        values = {name: column[k] for name, column in sets.items()}
        model = controlled(gain=values.pop("pd.gain"), **rebuilt(values))
        numpy_run = ctmm.simulate(model, T_FINAL, DT, method="rk4", outputs=["b.tip.y"], references={"pd": 0.1},
                                  **START)
        assert batch.results[k].info["kernel"] == "shared"
        for name in ["j.angle", "j.angle_rate", "b.qy1", "b.qz1", "b.twist1", "b.u1", "pd.u", "b.tip.y"]:
            assert_round_off(batch.results[k][name], numpy_run[name], (k, name))


def test_a_diverging_beam_set_fails_by_index_and_a_length_is_refused(tmp_path, monkeypatch):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    # an axial stiffness 10^5 times larger: the axial mode (about 9000 rad/s) is far past the RK4 limit 2.8/dt
    sets = [{"b.axial_stiffness": 250.0}, {"b.axial_stiffness": 3e7}, {"b.mass_per_length": 1.0}]
    batch = ctmm.simulate_batch(plant(), sets, T_FINAL, DT, divergence_bound=10.0, **START)
    assert list(batch.failures) == [1] and isinstance(batch.failures[1], SimulationError)
    assert batch.results[1] is None and batch.failures[1].partial_result is not None
    numpy_run = ctmm.simulate(plant(mass_per_length=1.0), T_FINAL, DT, method="rk4", **START)
    assert_round_off(batch.results[2]["b.qy2"], numpy_run["b.qy2"], "set 2 after the failure")
    with pytest.raises(ModelError, match=r"parameters\['b.length'\]: the length of beam 'b' .*mode shapes depend on "
                                         r"it.*b.mass_per_length"):
        ctmm.simulate(plant(), T_FINAL, DT, compiled=True, parameters={"b.length": 1.2}, **START)
    with pytest.raises(ModelError, match=r"parameter_sets\[1\]: .*'b.n_modes_y'.*part of the compiled structure"):
        ctmm.simulate_batch(plant(), [{"b.mass_per_length": 1.0}, {"b.n_modes_y": 3}], T_FINAL, DT)


def test_finite_element_bodies_have_no_parameter_names():
    """Their numbers are not a rigid body's nor a modal beam's: refused by name, not listed as "<body>.mass"."""
    from scenarios import spatial_fem_chain

    with pytest.raises(ModelError, match="parameters: .*finite-element bodies 'beam1'"):
        ctmm.parameter_names(spatial_fem_chain.model())
