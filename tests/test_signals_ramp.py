"""The ramp signal ``offset + slope * max(t - start, 0)`` (``ctmm.signals.Ramp``) on every path that takes signals.

Independent references: closed forms (a free mass under a ramped force, ``x = slope t^3 / (6 m)``, which RK4
integrates exactly; a mass on a spring behind a base moving at constant speed, ``x = v t - (v / w) sin(w t)``),
Newton's equation of a pendulum hinged on a crank turning at constant speed (DOP853 at 1e-12); the generated code
against the numpy path (chains, planar and spatial trees, loop references and inputs).  The frequency domain and the rate
paths refuse what they cannot take by name.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import ctmm
import ctmm.spatial as sp
from ctmm.closed_form_rates import signal_derivatives
from ctmm.control import ControlledChain, Feedback
from ctmm.elements import Fixed, Free, Mass, PrescribedDisplacement, Spring, SpringDamper
from ctmm.errors import ModelError
from ctmm.planar import DrivenHinge, PlanarModel, RigidBody, SpringDamperHinge
from ctmm.planar import elements as planar_elements
from ctmm.signals import Ramp, Step, harmonic_amplitude

pytest.importorskip("casadi")


def test_ramp_values_rate_and_closed_form_rates():
    ramp = Ramp(2.5, offset=-0.4, start=0.3)
    for t, expected in ((-1.0, -0.4), (0.0, -0.4), (0.3, -0.4), (0.5, -0.4 + 2.5 * 0.2), (2.0, -0.4 + 2.5 * 1.7)):
        assert ramp(t) == pytest.approx(expected, rel=1e-15, abs=1e-15)
    assert ramp.rate() == Step(2.5, 0.3)
    rising = signal_derivatives("m", "displacement", Ramp(0.7, 0.1))
    assert rising(0.0) == (0.1, 0.7, 0.0) and rising(2.0) == pytest.approx((0.1 + 1.4, 0.7, 0.0), rel=1e-15)
    late = signal_derivatives("base", "displacement", ramp)              # its rate jumps at t = 0.3
    with pytest.raises(ModelError, match=r"base: the displacement signal Ramp\(slope=2.5.*start <= 0"):
        late(0.0)
    with pytest.raises(ModelError, match=r"Ramp\(slope=2.5.*no steady-state harmonic amplitude"):
        harmonic_amplitude(ramp)
    assert ctmm.signals.as_signal("force", ramp) is ramp


def test_a_free_mass_under_a_ramped_force_generated_and_numpy():
    """``m x'' = slope t`` from rest: ``x = slope t^3 / (6 m)``, a cubic that RK4 integrates exactly."""
    m, slope = 2.0, 3.0
    chain = ctmm.Chain("push", [Free("s"), Mass("m", m, force=Ramp(slope)), Free("e")])
    for compiled in (False, True):
        run = ctmm.simulate(chain, 1.0, 0.01, method="rk4", compiled=compiled)
        assert run.info["method"] == ("rk4-generated" if compiled else "rk4")
        np.testing.assert_allclose(run["m.x"], slope * run.time ** 3 / (6 * m), rtol=0, atol=1e-14)
        np.testing.assert_allclose(run["m.v"], slope * run.time ** 2 / (2 * m), rtol=0, atol=1e-14)
    with pytest.raises(ModelError, match=r"Ramp\(slope=3.0.*no steady-state harmonic amplitude"):
        ctmm.steady_state_response(chain, 1.0)


def test_a_base_moving_at_constant_speed_generated_and_numpy():
    """``m x'' = -k (x - v t)`` from rest: ``x = v t - (v / w) sin(w t)``, ``w^2 = k / m``; a ramp starting later
    (a velocity jump) is refused by the ODE paths by name and runs on a DT-TMM scheme."""
    m, k, v = 2.0, 200.0, 0.3
    w = np.sqrt(k / m)
    chain = ctmm.Chain("base", [PrescribedDisplacement("b", Ramp(v)), Spring("k", k), Mass("m", m), Free("e")])
    runs = [ctmm.simulate(chain, 1.0, 1e-3, method="rk4", compiled=compiled) for compiled in (False, True)]
    assert runs[1].info["method"] == "rk4-generated"
    for run in runs:
        np.testing.assert_allclose(run["m.x"], v * run.time - v / w * np.sin(w * run.time), rtol=0, atol=1e-10)
    np.testing.assert_allclose(runs[1]["m.x"], runs[0]["m.x"], rtol=0, atol=1e-14)
    late = ctmm.Chain("late", [PrescribedDisplacement("b", Ramp(v, start=0.2)), Spring("k", k), Mass("m", m),
                               Free("e")])
    for compiled in (False, True):
        with pytest.raises(ModelError, match=r"b: the displacement signal Ramp\(slope=0.3, offset=0.0, start=0.2\)"):
            ctmm.simulate(late, 0.1, 1e-3, method="rk4", compiled=compiled)
    assert np.isfinite(ctmm.simulate(late, 0.1, 1e-3, method="newmark")["m.x"]).all()


def test_loop_references_and_inputs_as_ramps_generated_equal_numpy():
    plant = ctmm.Chain("c", [Fixed("s"), SpringDamper("k0", 100.0, 0.5), Mass("m0", 1.0, force=Ramp(0.3)),
                             Free("e")])
    system = ControlledChain(plant, [Feedback("pd", "m0.x", "m0", gain=50.0)])
    options = dict(references={"pd": Ramp(0.1, 0.01, 0.1)}, inputs={"m0.force": Ramp(-1.0, start=0.05)})
    generated = ctmm.simulate(system, 0.5, 1e-3, method="rk4", compiled=True, **options)
    python = ctmm.simulate(system, 0.5, 1e-3, method="rk4", compiled=False, **options)
    assert generated.info["method"] == "rk4-generated"
    assert np.ptp(python["m0.x"]) > 1e-2
    for name in ("m0.x", "m0.v", "pd.u"):
        np.testing.assert_allclose(generated[name], python[name], rtol=0, atol=1e-12)


# a crank (length L1) turning at constant speed W from TH0, a uniform arm (mass M2, length L2) on a spring-damper
# hinge at its tip, under gravity
W, TH0, L1, M2, L2, K, C, G = 4.0, 0.3, 0.2, 0.3, 0.4, 2.0, 0.05, 9.81


def _crank_arm():
    """Newton-Euler of the arm about the crank's tip ``P`` (``P'' = -W^2 L1 (cos phi, sin phi)``, ``phi = TH0 + W t``):
    ``I_P th'' = -K (th - phi) - C (th' - W) - M2 G a cos th + M2 a W^2 L1 sin(phi - th)``, ``a = L2 / 2``."""
    a, inertia = L2 / 2, M2 * L2 ** 2 / 3

    def rate(t, z):
        phi = TH0 + W * t
        return [z[1], (-K * (z[0] - phi) - C * (z[1] - W) - M2 * G * a * np.cos(z[0])
                       + M2 * a * W ** 2 * L1 * np.sin(phi - z[0])) / inertia]
    return rate


def test_a_planar_crank_driven_at_constant_speed():
    """The crank's angle is ``TH0 + W t`` exactly; the arm follows Newton-Euler; the generated RK4 follows the ramp
    on its time symbol (= numpy to round-off); the time-history sensitivities refuse the moving drive by name."""
    model = PlanarModel.chain("crank", [
        planar_elements.Fixed("g"), DrivenHinge("motor", angle=Ramp(W, TH0), rate=W),
        RigidBody.uniform_link("crank", mass=0.5, length=L1), SpringDamperHinge("h", stiffness=K, damping=C),
        RigidBody.uniform_link("arm", mass=M2, length=L2)], gravity=(0.0, -G))
    run = ctmm.simulate(model, 1.0, 1e-3, method="rk4", x0={"arm.theta": 0.5})
    for t, q, qdot in zip(run.time[::100], run["arm.theta"][::100], run["arm.theta_dot"][::100]):
        angles, rates = model.body_angles(np.array([q]), np.array([qdot]), t)
        assert angles[0] == pytest.approx(TH0 + W * t, rel=0, abs=1e-14) and rates[0] == W
    exact = solve_ivp(_crank_arm(), (0.0, 1.0), [0.5, 0.0], t_eval=run.time, rtol=1e-12, atol=1e-14,
                      method="DOP853").y
    np.testing.assert_allclose(run["arm.theta"], exact[0], rtol=0, atol=1e-9)
    generated = ctmm.simulate(model, 1.0, 1e-3, method="rk4", compiled=True, x0={"arm.theta": 0.5})
    assert generated.info["method"] == "rk4-generated"
    np.testing.assert_allclose(generated["arm.theta"], run["arm.theta"], rtol=0, atol=1e-12)
    with pytest.raises(ModelError, match=r"driven hinges whose motion is not constant: 'motor'"):
        ctmm.sensitivity.simulation_sensitivity(model, ["arm.mass"], t_final=0.1, dt=1e-3)


def _spatial_model() -> sp.SpatialModel:
    """A cart on a prismatic guide pushed by a ramped force; a crank driven about z at constant speed carrying a free
    arm about z (the in-plane pendulum of :func:`_crank_arm` without spring, damper and gravity)."""
    arm_inertia = np.diag([1e-4, M2 * L2 ** 2 / 12, M2 * L2 ** 2 / 12])
    return sp.SpatialModel("ramps", [
        sp.SpatialBody("cart", 2.0, np.diag([0.1, 0.1, 0.1]), points={"side": (0.0, 0.3, 0.0)}),
        sp.SpatialBody("crank", 0.5, np.diag([1e-3, 2e-3, 2e-3]), (L1 / 2, 0.0, 0.0), {"tip": (L1, 0.0, 0.0)}),
        sp.SpatialBody("arm", M2, arm_inertia, (L2 / 2, 0.0, 0.0)),
        sp.Prismatic(name="p", parent=None, child="cart", axis=(1, 0, 0)),
        sp.Revolute(name="drive", parent=None, child="crank", axis=(0, 0, 1), point=(0.0, 0.0, 1.0),
                    position=Ramp(W, TH0), rate=W, acceleration=0.0),
        sp.Revolute(name="h", parent="crank", point="tip", child="arm", axis=(0, 0, 1)),
        sp.Load("push", "cart", "side", force=(Ramp(3.0, start=0.2), 0.0, 0.0))], gravity=(0.0, 0.0, -G))


def test_spatial_ramps_generated_equal_numpy_and_the_closed_forms():
    """The cart: ``x = 3 (t - 0.2)^3 / (6 * 2)`` after 0.2 s (RK4 exact on the cubic between the steps, the kink on
    a step); the arm's relative angle by Newton-Euler; the generated RK4 equals the numpy one to round-off."""
    model = _spatial_model()
    x0, v0 = {"h.angle": 0.4}, {"h.angle_rate": -0.5}
    generated = ctmm.simulate(model, 0.6, 1e-3, compiled=True, x0=x0, v0=v0)
    python = ctmm.simulate(model, 0.6, 1e-3, method="rk4", x0=x0, v0=v0)
    assert generated.info["method"] == "rk4-generated"
    for name in model.coordinates + model.velocities:
        np.testing.assert_allclose(generated[name], python[name], rtol=0, atol=1e-12)
    t = python.time
    np.testing.assert_allclose(python["p.position"], 3.0 * np.maximum(t - 0.2, 0.0) ** 3 / 12.0, rtol=0,
                               atol=1e-12)
    a, inertia = L2 / 2, M2 * L2 ** 2 / 3

    def rate(time, z):
        phi = TH0 + W * time
        return [z[1], M2 * a * W ** 2 * L1 * np.sin(phi - z[0]) / inertia]
    exact = solve_ivp(rate, (0.0, 0.6), [TH0 + 0.4, W - 0.5], t_eval=t, rtol=1e-12, atol=1e-14, method="DOP853").y
    np.testing.assert_allclose(python["h.angle"], exact[0] - TH0 - W * t, rtol=0, atol=1e-9)


def test_ramp_in_a_scene_file(tmp_path):
    from ctmm.scene_files import load_scene

    path = tmp_path / "ramp.toml"
    path.write_text('[system]\nkind = "chain"\nname = "push"\n'
                    '[[system.elements]]\ntype = "Free"\nname = "s"\n'
                    '[[system.elements]]\ntype = "Mass"\nname = "m"\nmass = 2.0\n'
                    'force = { type = "Ramp", slope = 3.0, offset = 0.5, start = 0.1 }\n'
                    '[[system.elements]]\ntype = "Free"\nname = "e"\n'
                    '[study]\nverb = "simulate"\nt_final = 0.2\ndt = 0.01\n')
    scene = load_scene(path)
    assert scene.system.elements[1].force == Ramp(3.0, 0.5, 0.1)


def test_fmu_parameter_names_of_ramp_fields_with_units():
    """A planar model's ramped hinge torque and load: the parameter vector holds the ramps' fields, named with their
    units (a slope per second)."""
    from ctmm.compiled_parameters import parameter_vector
    from ctmm.fmu_export_model import parameter_names
    from ctmm.planar import ActuatedHinge, Load, Pinned

    model = PlanarModel.chain("ramped", [
        Pinned("o"), RigidBody.uniform_link("a", mass=1.0, length=0.5),
        ActuatedHinge("h", torque=Ramp(0.2, 0.1, 0.05)),
        RigidBody("b", mass=0.4, inertia=0.01, outboard=(0.3, 0.0),
                  loads=(Load(point=(0.3, 0.0), force_x=Ramp(-1.5, start=0.1)),))])
    names = {name: unit for name, unit, _ in parameter_names(model)}
    vector = parameter_vector(model)
    assert len(names) == vector.size
    assert names["h.law.torque.slope"] == "N m/s" and names["h.law.torque.start"] == "s"
    assert names["b.load0.force_x.slope"] == "N/s" and names["b.load0.force_x.offset"] == "N"
    position = list(names).index("b.load0.force_x.slope")
    assert vector[position:position + 3].tolist() == [-1.5, 0.0, 0.1]
