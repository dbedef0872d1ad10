"""Generated spatial kernels with time signals on loads and driven joints (issue 13): the generated
accelerations against Pinocchio, the generated RK4 against the numpy RK4, user callables refused by name."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm.compiled_spatial import spatial_compile_refusal
from ctmm.errors import ModelError
from ctmm.signals import Harmonic, Step

pytest.importorskip("casadi")

# the driven angle 0.4 sin(2 t + 0.3), its rate and acceleration
ANGLE, RATE, ACCELERATION = Harmonic(0.4, 2.0, 0.3), Harmonic(0.8, 2.0, 0.3 + np.pi / 2), Harmonic(-1.6, 2.0, 0.3)


def body(name: str) -> sp.SpatialBody:
    return sp.SpatialBody(name, 1.0, (0.1, 0.2, 0.25), (0.0, 0.0, -0.5), {"tip": (0.0, 0.0, -1.0)})


def driven_chain(position=ANGLE, force=(Step(0.5, 0.01), 0.0, Harmonic(0.3, 5.0))) -> sp.SpatialModel:
    """A revolute, a revolute driven by sines in the middle, a ball joint; a load (a step and a sine) at the tip."""
    return sp.SpatialModel("driven", [
        body("a"), body("b"), body("c"),
        sp.Revolute(name="ja", parent=None, child="a", axis=(1, 0, 0)),
        sp.Revolute(name="jb", parent="a", point="tip", child="b", axis=(0, 1, 1), position=position, rate=RATE,
                    acceleration=ACCELERATION),
        sp.Spherical(name="jc", parent="b", point="tip", child="c"),
        sp.Load("push", "c", "tip", force=force)])


def test_driven_joint_on_the_time_symbol_equals_pinocchio() -> None:
    """The generated accelerations at two times equal Pinocchio's with the driven acceleration moved to the
    right-hand side (the load set to zero: Pinocchio's ABA takes none here)."""
    pin = pytest.importorskip("pinocchio")
    from spatial_pinocchio_helpers import pinocchio_driven_chain

    from ctmm.compiled_spatial import CompiledSpatialScene

    model = driven_chain(force=(0.0, 0.0, 0.0))
    assert spatial_compile_refusal(model, time_signals=True) == ""
    scene = CompiledSpatialScene(model)
    pm, _ = pinocchio_driven_chain(pin, model)
    data = pm.createData()
    q, v = np.array([0.3, 0.9, 0.1, -0.3, 0.2]), np.array([0.5, 0.2, -0.4, 0.3])
    quat = q[1:] / np.linalg.norm(q[1:])
    for t in (0.0, 0.7):
        qp, vp = np.r_[q[0], ANGLE(t), quat[1:], quat[0]], np.r_[v[0], RATE(t), v[1:]]
        M = pin.crba(pm, data, qp)
        M = np.triu(M) + np.triu(M, 1).T
        bias = pin.nle(pm, data, qp, vp)
        free = [0, 2, 3, 4]
        expected = np.linalg.solve(M[np.ix_(free, free)], -bias[free] - M[free, 1] * ACCELERATION(t))
        np.testing.assert_allclose(scene.accelerations(q, v, t=t), expected, rtol=0,
                                   atol=1e-10 * max(1.0, np.abs(expected).max()))


def test_generated_rk4_with_time_signals_equals_the_numpy_rk4() -> None:
    model = driven_chain()
    v0 = {"ja.angle_rate": 0.5, "jc.wx": 0.3}
    generated = ctmm.simulate(model, 0.1, 1e-3, compiled=True, v0=v0)
    reference = ctmm.simulate(model, 0.1, 1e-3, method="rk4", v0=v0)
    assert generated.info["method"] == "rk4-generated"
    for name in model.coordinates + model.velocities:
        np.testing.assert_allclose(generated[name], reference[name], rtol=0, atol=1e-12)
    assert np.ptp(generated["jc.wx"]) > 1e-2                                   # the load and the drive acted


def test_user_callables_are_refused_by_name() -> None:
    with pytest.raises(ModelError, match=r"without a symbolic form in driven joint 'jb' \(position\[0\] is a UserFunction\)"):
        ctmm.simulate(driven_chain(position=lambda t: 0.4 * np.sin(2 * t + 0.3)), 0.01, 1e-3, compiled=True)
    with pytest.raises(ModelError, match=r"without a symbolic form in load 'push' \(force\[0\]"):
        ctmm.simulate(driven_chain(force=(lambda t: t, 0.0, 0.0)), 0.01, 1e-3, compiled=True)
    # the paths that state the terms at one time keep refusing any signal that is not a constant
    assert "signals that are not constants in driven joint 'jb' (position[0] is a Harmonic), load 'push' (force[0] " \
        "is a Step)" in spatial_compile_refusal(driven_chain())


def test_time_signals_with_the_numbers_as_inputs() -> None:
    """``numbers="inputs"`` (one library per structure): the loads' part kept from the terms on the time symbol."""
    from ctmm.compiled_spatial import CompiledSpatialScene

    model = driven_chain()
    scene = CompiledSpatialScene(model, numbers="inputs")
    q, v = np.array([0.3, 0.9, 0.1, -0.3, 0.2]), np.array([0.5, 0.2, -0.4, 0.3])
    for t in (0.0, 0.7):
        expected = sp.accelerations(model, q, v, t)
        np.testing.assert_allclose(scene.accelerations(q, v, t=t), expected, rtol=0,
                                   atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("method", ["newmark", "houbolt"])
def test_generated_dt_tmm_scheme_with_time_signals_equals_the_numpy_scheme(method) -> None:
    """The generated Lie-group step (Newton in C) states the signals at its time symbol, as the numpy scheme."""
    model = driven_chain()
    v0 = {"ja.angle_rate": 0.5, "jc.wx": 0.3}
    generated = ctmm.simulate(model, 0.1, 1e-3, method=method, compiled=True, v0=v0)
    reference = ctmm.simulate(model, 0.1, 1e-3, method=method, v0=v0)
    assert generated.scheme_name == f"dt-tmm-generated/{method}"
    for name in model.coordinates + model.velocities:
        np.testing.assert_allclose(generated[name], reference[name], rtol=0, atol=1e-11)
    assert np.ptp(generated["jc.wx"]) > 1e-2
