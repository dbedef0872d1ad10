"""``ctmm.simulate``'s default (``compiled=None``) runs the generated code where it pays (issue 13 item 2,
:mod:`ctmm.compiled_default`).

References: a long pendulum run against an independent ``solve_ivp`` (DOP853, rtol 1e-12) of the pendulum's own
equation ``(I_O) theta'' = -m g c sin(theta)`` (not ctmm's sweep), the numpy path for the contract "generated =
numpy to round-off", and the numpy path's own result where the default must fall back to it.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ctmm
import ctmm.spatial
from ctmm import compiled_default
from ctmm.codegen import find_compiler
from ctmm.control import ControlledModel, Feedback
from ctmm.compiled_default import MINIMUM_STEPS, default_refusal
from ctmm.elements import Fixed, Free, Inerter, Mass, SpringDamper
from ctmm.errors import ModelError
from ctmm.nonlinear_laws import CubicSpring
from ctmm.planar import NonlinearHinge, Pinned, PlanarModel, RigidBody, SmoothHinge

try:
    find_compiler()
    HAVE_COMPILER = True
except ModelError:
    HAVE_COMPILER = False

needs_compiler = pytest.mark.skipif(not HAVE_COMPILER, reason="no C compiler")
G = 9.81


def pendulum(n: int = 1) -> PlanarModel:
    elements = [Pinned("base")]
    for i in range(n):
        if i:
            elements.append(SmoothHinge(f"h{i}"))
        elements.append(RigidBody.uniform_link(f"link{i}", mass=1.0, length=1.0))
    return PlanarModel.chain(f"pendulum{n}", elements, gravity=(0.0, -G))


def spatial_chain(n: int) -> ctmm.spatial.SpatialModel:
    """Links of 1 kg, 1 m along x on revolute joints about y (even) and z (odd), gravity -z."""
    sp = ctmm.spatial
    elements = []
    for i in range(n):
        elements.append(sp.SpatialBody(f"l{i}", 1.0, (5e-3, 0.086, 0.086), (0.5, 0.0, 0.0), {"end": (1.0, 0.0, 0.0)}))
        elements.append(sp.Revolute(name=f"j{i}", parent=None if i == 0 else f"l{i - 1}", child=f"l{i}",
                                    point=(0.0, 0.0, 0.0) if i == 0 else "end",
                                    axis=(0.0, 1.0, 0.0) if i % 2 == 0 else (0.0, 0.0, 1.0)))
    return sp.SpatialModel(f"chain{n}", elements, gravity=(0.0, 0.0, -G))


def chain() -> ctmm.Chain:
    return ctmm.Chain("two", [Fixed("wall"), SpringDamper("k0", 400.0, 0.2), Mass("m0", 1.0),
                              SpringDamper("k1", 100.0, 0.1), Mass("m1", 0.5), Free("end")])


@needs_compiler
def test_long_planar_run_is_generated_and_matches_an_independent_solution():
    dt, t_final = 1e-3, MINIMUM_STEPS * 1e-3
    result = ctmm.simulate(pendulum(), t_final, dt, x0={"link0.theta": 0.8})
    assert result.info["compiled"].startswith("generated")
    # uniform link about its pin: I_O = m L^2 / 3, centre of mass at L / 2; angle from the x axis, gravity -y
    rates = lambda t, y: [y[1], -1.0 * G * 0.5 * np.cos(y[0]) / (1.0 / 3.0)]
    reference = solve_ivp(rates, (0.0, t_final), [0.8, 0.0], method="DOP853", rtol=1e-12, atol=1e-12,
                          t_eval=np.asarray(result.time), max_step=0.01)
    assert np.max(np.abs(np.asarray(result["link0.theta"]) - reference.y[0])) < 1e-9     # RK4 at h = 1 ms


def test_short_run_stays_on_numpy():
    result = ctmm.simulate(pendulum(), 0.1, 1e-3, x0={"link0.theta": 0.3})
    assert "compiled" not in result.info and result.info["method"] == "rk4"


@needs_compiler
def test_what_the_generated_path_refuses_runs_on_numpy_with_the_reason():
    """A Python callable of time cannot be generated: the default runs numpy (the same numbers as
    compiled=False, bit for bit) and says why; compiled=True refuses it by name."""
    def forced() -> ctmm.Chain:
        return ctmm.Chain("forced", [Fixed("wall"), SpringDamper("k0", 400.0, 0.2),
                                     Mass("m0", 1.0, force=lambda t: np.sin(3.0 * t)), Free("end")])

    t_final = MINIMUM_STEPS * 1e-3
    result = ctmm.simulate(forced(), t_final, 1e-3)
    assert result.info["compiled"].startswith("numpy") and "Python callable" in result.info["compiled"]
    reference = ctmm.simulate(forced(), t_final, 1e-3, compiled=False)
    assert "compiled" not in reference.info
    np.testing.assert_array_equal(result["m0.x"], reference["m0.x"])
    with pytest.raises(ModelError, match="Python callable"):
        ctmm.simulate(forced(), 0.01, 1e-3, compiled=True)


@needs_compiler
def test_long_chain_newmark_is_generated_and_matches_numpy_and_the_energy_identity():
    dt, t_final = 1e-3, MINIMUM_STEPS * 1e-3
    result = ctmm.simulate(chain(), t_final, dt, x0={"m0": 0.01})
    assert result.info["compiled"].startswith("generated")
    numpy_result = ctmm.simulate(chain(), t_final, dt, x0={"m0": 0.01}, compiled=False)
    np.testing.assert_allclose(result["m1.x"], numpy_result["m1.x"], rtol=0, atol=1e-12)
    # independent: Newmark (average acceleration) of the undamped pair conserves x' M x'/2 + x' K x/2 to
    # round-off; with the light dampers the energy only decays
    energy = lambda r: 0.5 * (np.asarray(r["m0.v"]) ** 2 + 0.5 * np.asarray(r["m1.v"]) ** 2) + 0.5 * (
        400.0 * np.asarray(r["m0.x"]) ** 2 + 100.0 * (np.asarray(r["m1.x"]) - np.asarray(r["m0.x"])) ** 2)
    assert np.all(np.diff(energy(result)) <= 1e-15)


def test_default_refusal_names_why_numpy_runs(monkeypatch):
    model, plain = pendulum(), chain()
    long_run = dict(t_final=10.0, t0=0.0, dt=1e-3, controllers=(), fast=None, force_hook=None, solver="riccati")
    assert "short run" in default_refusal(model, "rk4", **{**long_run, "t_final": 0.1})
    assert "no generated form" in default_refusal(model, "DOP853", **long_run)
    assert default_refusal(model, "newmark", **long_run) is None
    assert default_refusal(pendulum(300), "houbolt", **long_run) is None     # the O(N) sweep iteration applies
    assert "a DT-TMM scheme of 301 coordinates (> 300" in default_refusal(pendulum(301), "houbolt", **long_run)
    links = [RigidBody.uniform_link(f"link{i}", mass=1.0, length=1.0) for i in range(16)]
    hinges = [NonlinearHinge("cubic", moment_law=CubicSpring(1.0, 2.0))] + [SmoothHinge(f"h{i}") for i in range(2, 16)]
    elements = [Pinned("base"), links[0], *[e for pair in zip(hinges, links[1:]) for e in pair]]
    stiff = PlanarModel.chain("cubic", elements, gravity=(0.0, -G))     # a nonlinear law: the n x n tangent, <= 15
    assert "a DT-TMM scheme of 16 coordinates (> 15" in default_refusal(stiff, "houbolt", **long_run)
    pd = lambda n: ControlledModel(pendulum(n), [Feedback("pd", [("link0.theta", 5.0)], "base.torque", gain=1.0)])
    assert default_refusal(pd(30), "newmark", **long_run) is None          # the numpy loops cost more there
    assert "31 coordinates with loops (> 30" in default_refusal(pd(31), "newmark", **long_run)
    assert default_refusal(pendulum(16), "rk4", **long_run) is None          # the RK4 has no size limit
    assert default_refusal(spatial_chain(10), "newmark", **long_run) is None
    assert "a DT-TMM scheme of 11 velocities (> 10" in default_refusal(spatial_chain(11), "newmark", **long_run)
    assert "co-simulated controllers" in default_refusal(model, "rk4", **{**long_run, "controllers": (object(),)})
    assert "no generated form" in default_refusal(plain, "DOP853", **long_run)
    assert "numpy-path options" in default_refusal(plain, "newmark", **{**long_run, "solver": "dense"})
    big = ctmm.Chain("big", [Fixed("wall"), Inerter("b", 1.0, stiffness=1.0)]
                     + [e for i in range(1001) for e in (Mass(f"m{i}", 1.0), SpringDamper(f"k{i}", 1.0, 0.0))]
                     + [Mass("last", 1.0), Free("end")])       # an inerter: a dense generated set-up
    assert "a chain of 2005 points with inerters (b)" in default_refusal(big, "newmark", **long_run)
    for bad in (dict(t_final=float("inf")), dict(t_final=float("nan")), dict(dt=0.0), dict(dt=None), dict(dt=-1e-3)):
        assert default_refusal(model, "rk4", **{**long_run, **bad}) == "no fixed step"     # the verb refuses them
    monkeypatch.setenv("PATH", "")
    assert default_refusal(model, "rk4", **long_run) == "no C compiler"


@needs_compiler
@pytest.mark.parametrize("method", ["newmark", "houbolt"])
def test_a_planar_scheme_is_generated_by_default_and_equals_numpy(monkeypatch, method):
    """Schemes of small planar models take the generated path by default (a long run: the step threshold lowered
    for the test) and give the numpy stepper's answer to round-off (the contract of the generated path)."""
    monkeypatch.setattr(compiled_default, "MINIMUM_STEPS", 100)
    model, dt, t_final = pendulum(3), 1e-3, 0.1
    result = ctmm.simulate(model, t_final, dt, method=method, x0={"link0.theta": 0.8, "link2.theta": -0.4})
    assert result.info["compiled"].startswith("generated")
    reference = ctmm.simulate(model, t_final, dt, method=method, x0={"link0.theta": 0.8, "link2.theta": -0.4},
                              compiled=False)
    assert "compiled" not in reference.info
    for name in ("link0.theta", "link2.theta", "link1.theta_dot"):
        np.testing.assert_allclose(result[name], reference[name], rtol=0, atol=1e-12)
    start = {"link0.theta": 0.8, "link9.theta": -0.4, "link15.theta": 1.0}
    big = ctmm.simulate(pendulum(16), t_final, dt, method=method, x0=start)  # the O(N) sweep iteration: generated
    assert big.info["compiled"].startswith("generated")
    numpy_big = ctmm.simulate(pendulum(16), t_final, dt, method=method, x0=start, compiled=False)
    for name in ("link0.theta", "link15.theta", "link9.theta_dot"):
        np.testing.assert_allclose(big[name], numpy_big[name], rtol=0, atol=1e-12)


@needs_compiler
def test_a_planar_scheme_with_loops_is_generated_by_default_and_equals_numpy(monkeypatch):
    """Loops inside the generated Newton step (:mod:`ctmm.compiled_scheme_loops`) by default: the Python DT-TMM path
    with the same loops to the loops' round-off contract (1e-10, ``tests/test_compiled_scene_schemes_loops.py``)."""
    from test_compiled_scene_schemes import DP_START, double_pendulum
    from test_compiled_scene_schemes_loops import pd_loops

    monkeypatch.setattr(compiled_default, "MINIMUM_STEPS", 20)
    plant = double_pendulum()
    controlled = ControlledModel(plant, pd_loops())
    options = dict(method="newmark", x0=dict(zip(plant.coordinates, DP_START[0])),
                   v0=dict(zip(plant.coordinates, DP_START[1])))
    result = ctmm.simulate(controlled, 0.2, 0.01, **options)
    assert result.info["compiled"].startswith("generated")
    reference = ctmm.simulate(controlled, 0.2, 0.01, compiled=False, **options)
    for name in reference.signals():
        assert np.max(np.abs(result[name] - reference[name])) <= 1e-10, name


@needs_compiler
def test_a_spatial_scheme_is_generated_by_default_and_equals_numpy(monkeypatch):
    monkeypatch.setattr(compiled_default, "MINIMUM_STEPS", 50)
    model, dt, t_final = spatial_chain(2), 1e-3, 0.05
    start = {"j0.angle": 0.3, "j1.angle": 0.5}
    result = ctmm.simulate(model, t_final, dt, method="generalized_alpha", x0=start)
    assert result.info["compiled"].startswith("generated")
    reference = ctmm.simulate(model, t_final, dt, method="generalized_alpha", x0=start, compiled=False)
    for name in ("j0.angle", "j1.angle", "j1.angle_rate"):
        np.testing.assert_allclose(result[name], reference[name], rtol=0, atol=1e-12)


@pytest.mark.parametrize("t_final", [np.inf, -np.inf, np.nan])
def test_a_non_finite_end_time_is_refused_by_the_verb_by_name(t_final):
    """The default's step count does not overflow on an infinite end time: the verb names the bad number."""
    with pytest.raises(ModelError, match="t_final"):
        ctmm.simulate(chain(), t_final, 0.01)
