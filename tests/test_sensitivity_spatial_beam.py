"""Exact sensitivities in the numbers of modal spatial beams (ctmm.compiled_spatial_beam_numbers through
ctmm.sensitivity_spatial and ctmm.sensitivity_time_spatial).

The parametrised beam terms are checked against the terms of the model rebuilt with the changed numbers (every beam
number at once, a free-floating beam with a child body and gravity on two axes: equal to round-off); the derivatives
of the frequency response (``ctmm.frequency_response``), of the spectral abscissa (eigenvalues of
``ctmm.linearize``), of a resonance peak, of the delay margin (secant-refined crossovers of ``ctmm.control.loop_transfer_function``, as
``ctmm.control.margins`` refines them) and of RK4 histories
(``ctmm.simulate(method="rk4")``) against Richardson-extrapolated central differences of those verbs on rebuilt
models (steps ``h, h/2``, ``h = 1e-3 |p|``, error ``O(h^4)``; bound 1e-6 relative, the existing standard; the
every-sensor history test, whose 15 outputs in 11 numbers make the numpy runs its cost, one central difference at
``h = 3e-4 |p|``, its measured error stated there).
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
import ctmm.spatial as sp
from ctmm import sensitivity as S
from ctmm.control import Feedback, with_feedback
from ctmm.errors import ModelError
from tests.test_sensitivity import central_difference, relative
from tests.test_sensitivity_spatial import richardson

BEAM = dict(length=1.0, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=4.0, n_modes_y=2,
            n_modes_z=1, n_torsion_modes=1, torsional_stiffness=1.5, polar_inertia_per_length=0.004,
            damping_ratio=0.01, stiffness_damping=0.002)


def arm(**changes):
    """A beam on a sprung, damped revolute joint about the vertical (gravity sags it: the equilibrium moves with
    the beam's numbers) closed by a PD loop on the joint."""
    model = sp.SpatialModel("flexarm", [
        sp.SpatialBeam("b", **{**BEAM, **changes}),
        sp.Revolute(name="j", parent=None, child="b", axis=(0, 0, 1), stiffness=3.0, damping=0.2, actuated=True)],
        gravity=(0, 0, -9.81))
    return with_feedback(model, [Feedback("pd", [("j.angle", 4.0), ("j.rate", 0.5)], "j.torque", gain=1.0)])


def test_beam_numbers_as_inputs_equal_the_terms_of_the_rebuilt_model():
    from ctmm.compiled_spatial_loops import loop_acceleration
    from ctmm.compiled_spatial_parameters import spatial_parameter_layout, spatial_parameter_vector
    from ctmm.spatial.ports import SpatialPorts

    def model(**numbers):
        return sp.SpatialModel("floating", [
            sp.SpatialBeam("a", length=0.8, n_modes_y=2, n_modes_z=1, n_torsion_modes=1, n_axial_modes=1,
                           stations={"mid": 0.5}, **{**dict(
                               mass_per_length=1.2, bending_stiffness_y=4.0, bending_stiffness_z=6.0,
                               torsional_stiffness=2.0, axial_stiffness=300.0, polar_inertia_per_length=0.003,
                               damping_ratio=0.02, stiffness_damping=0.001), **numbers}),
            sp.Free(name="base", parent=None, child="a"),
            sp.SpatialBody("tip", 0.3, np.diag([0.01, 0.02, 0.025]), center_of_mass=(0.05, 0.0, 0.0)),
            sp.Revolute(name="j", parent="a", child="tip", point="tip", axis=(0, 1, 0), stiffness=2.0, damping=0.1)],
            gravity=(0.5, 0.0, -9.81))

    base = model()
    layout = spatial_parameter_layout(base)
    beam_entries = [e.name for e in layout if e.name.startswith("a.")]
    assert beam_entries == ["a.mass_per_length", "a.polar_inertia_per_length", "a.bending_stiffness_y",
                            "a.bending_stiffness_z", "a.torsional_stiffness", "a.axial_stiffness", "a.damping_ratio",
                            "a.stiffness_damping"]
    changed = {e.kind: 1.3 * e.value for e in layout if e.name.startswith("a.")}
    p = spatial_parameter_vector(base)
    p[[k for k, e in enumerate(layout) if e.name.startswith("a.")]] *= 1.3
    p[[k for k, e in enumerate(layout) if e.kind == "gravity"]] *= 0.7
    rebuilt = model(**changed)
    rebuilt = sp.SpatialModel("floating", list(rebuilt.bodies) + list(rebuilt.joints), gravity=(0.35, 0.0, -6.867))
    rng = np.random.default_rng(1)
    q = np.asarray(base.neutral(), dtype=float)
    q[:3] += 0.1 * rng.normal(size=3)
    q[3:7] = rng.normal(size=4)
    q[3:7] /= np.linalg.norm(q[3:7])
    q[7:] += 0.01 * rng.normal(size=q.size - 7)
    v = 0.5 * rng.normal(size=base.n_velocities)
    parametrised = loop_acceleration(base, SpatialPorts(base), (), layout)

    def numeric(m):
        return np.asarray(loop_acceleration(m, SpatialPorts(m), ())(q, v, [], [], 0.0)).ravel()

    at_model = np.asarray(parametrised(q, v, [], spatial_parameter_vector(base), 0.0)).ravel()
    at_changed = np.asarray(parametrised(q, v, [], p, 0.0)).ravel()
    reference = numeric(rebuilt)
    assert np.max(np.abs(at_model - numeric(base))) < 1e-12 * np.max(np.abs(at_model))
    assert np.max(np.abs(at_changed - at_model)) > 0.02 * np.max(np.abs(at_model))         # the numbers matter
    assert np.max(np.abs(at_changed - reference)) < 1e-12 * np.max(np.abs(reference))


@pytest.mark.parametrize("pair, names", [
    (("j.torque", "b.tip.y"), ["b.mass_per_length", "b.bending_stiffness_y", "b.damping_ratio"]),
    (("b.tip.moment_x", "b.tip.twist"), ["b.torsional_stiffness", "b.polar_inertia_per_length"]),
    (("b.tip.force_z", "b.tip.z"), ["b.bending_stiffness_z", "b.mass_per_length"])])
def test_beam_frequency_response_derivatives_against_richardson_differences(pair, names):
    system = arm()
    omega = np.array([3.0, 12.0, 40.0])
    found = S.frequency_response_sensitivity(system, names, omega, input=pair[0], output=pair[1])

    def response(s):
        return ctmm.frequency_response(s, omega, input=pair[0], output=pair[1]).response

    assert np.max(np.abs(found.response - response(system))) < 1e-10 * np.max(np.abs(found.response))
    for i, name in enumerate(names):
        expected = richardson(response, system, name)
        assert np.max(np.abs(expected)) > 1e-6 * np.max(np.abs(found.response))    # the number matters
        assert relative(found.derivative[i], expected) < 1e-6, name


def test_beam_resonance_peak_derivative_against_richardson_differences():
    # the bending resonance of the joint angle (29 rad/s; envelope theorem at the refined maximiser); the peak is
    # the verb's own refined maximum, checked against the TMM response around it
    system = arm(n_modes_y=1, n_modes_z=0, n_torsion_modes=0)
    w = np.linspace(20.0, 60.0, 200)
    found = S.peak_sensitivity(system, ["b.bending_stiffness_y"], w, input="j.torque", output="j.angle")
    assert 25.0 < found.frequency < 35.0
    near = found.frequency * np.array([0.999, 1.0, 1.001])
    magnitude = np.abs(ctmm.frequency_response(system, near, input="j.torque", output="j.angle").response).ravel()
    assert abs(magnitude[1] - found.value) < 1e-10 * found.value and magnitude[1] > max(magnitude[0], magnitude[2])
    expected = richardson(lambda s: S.peak_sensitivity(s, [], w, input="j.torque", output="j.angle").value, system,
                          "b.bending_stiffness_y")
    assert relative(found.gradient["b.bending_stiffness_y"], expected) < 1e-6


def test_beam_abscissa_derivatives_against_eigenvalues_of_the_linearisation():
    system = arm()
    names = ["b.mass_per_length", "b.damping_ratio", "b.stiffness_damping"]
    found = S.spectral_abscissa_sensitivity(system, names)

    def abscissa(s):
        return np.max(np.linalg.eigvals(np.asarray(ctmm.linearize(s, inputs=[]).state_space.A)).real)

    assert abs(found.value - abscissa(system)) < 1e-10
    for name in names:
        assert relative(found.gradient[name], richardson(abscissa, system, name)) < 1e-6, name


def delay_margin_at(system, omega: float) -> float:
    """The delay margin ``PM / omega_c`` of the gain crossover near ``omega`` [rad/s]: secant iterations on
    ``|L(i omega)| = 1`` of ``ctmm.control.loop_transfer_function`` (what ``margins`` refines, without its certified
    search of every crossover: 0.3 s instead of 2 s per model here)."""
    from ctmm.control.analysis import loop_transfer_function

    def L(x):
        return complex(loop_transfer_function(system, "pd", [x])("pd.L")[0])

    a, b = omega, omega * (1 + 1e-3)
    fa, fb = abs(L(a)) - 1, abs(L(b)) - 1
    for _ in range(30):
        a, fa, b = b, fb, b - fb * (b - a) / (fb - fa)
        fb = abs(L(b)) - 1
        if abs(b - a) < 1e-14 * b:
            break
    return float((np.angle(L(b)) + np.pi) % (2 * np.pi) / b)


@pytest.mark.slow
def test_beam_delay_margin_derivative_against_richardson_differences():
    # the delay margin is set by the beam's bending crossover (83 rad/s), not by the rigid one (4.4 rad/s)
    system = arm(n_modes_y=1, n_modes_z=0, n_torsion_modes=0)
    found = S.margin_sensitivity(system, "pd", ["b.bending_stiffness_y"], np.linspace(0.5, 60.0, 200))
    crossover = found.margins.delay_crossover_frequency
    assert crossover > 60.0 and abs(found.margins.delay_margin - delay_margin_at(system, crossover)) < 1e-12
    expected = richardson(lambda s: delay_margin_at(s, crossover), system, "b.bending_stiffness_y")
    assert relative(found.delay_margin["b.bending_stiffness_y"], expected) < 1e-6


def test_beam_rk4_history_derivatives_against_richardson_differences_of_the_simulation():
    system = arm()
    names = ["b.mass_per_length", "b.torsional_stiffness"]
    start = dict(x0={"j.angle": 0.3, "b.qy1": 0.01, "b.twist1": 0.02})
    outputs = ["j.angle", "b.tip.y", "b.twist1_rate"]
    found = S.simulation_sensitivity(system, names, t_final=0.1, dt=0.005, outputs=outputs, **start)

    def history(s):
        run = ctmm.simulate(s, 0.1, 0.005, method="rk4", outputs=outputs, **start)
        return np.array([run[name] for name in outputs])

    assert np.max(np.abs(found.values - history(system))) < 1e-12
    for i, name in enumerate(names):
        assert relative(found.derivative[i], richardson(history, system, name)) < 1e-6, name


def test_beam_refusals_name_what_is_allowed():
    with pytest.raises(ModelError, match="b.mass_per_length"):           # geometry is not a parameter
        S.frequency_response_sensitivity(arm(), ["b.length"], [1.0], input="j.torque", output="b.tip.y")
    with pytest.raises(ModelError, match="constant of the generated expression"):
        S.frequency_response_sensitivity(arm(), ["b.axial_stiffness"], [1.0], input="j.torque", output="b.tip.y")
    from scenarios import spatial_fem_chain

    with pytest.raises(ModelError, match="finite-element subsystems"):
        S.spectral_abscissa_sensitivity(spatial_fem_chain.model(), ["gravity.z"])


def test_every_spatial_sensor_kind_in_every_parameter_kind_against_central_differences_of_the_simulation():
    # outputs of every sensor kind (joint coordinate and rate, modal coordinate, beam station deflection, slope rate
    # and twist, beam station point and velocity, a body's offset point, centre of mass, body-axes rate, angle,
    # rotation vector, world rate) in one number of each kind (beam mass, inertia, stiffness, damping; joint law
    # stiffness, damping, reference; body mass, product of inertia; gravity): no spatial sensor depends on the numbers
    # directly (mode shapes are fixed by length and end conditions), so dy/dp = dy/dx S must match central
    # differences of ctmm.simulate (h = 3e-4 |p|: truncation and round-off balanced); bound 1e-6 of each output's
    # derivative plus the differences' round-off floor 1e-10 |y| / |p| (worst found: 0.12 of the bound, a small
    # derivative in b.bending_stiffness_z, the z mode barely excited; b.mass_per_length 0.06, every other number
    # <= 0.035 of it; Richardson over h = 1e-3, 5e-4 had 0.22 in b.bending_stiffness_z, h = 1e-4 alone 1.04)
    model = sp.SpatialModel("flexarm_tip", [
        sp.SpatialBeam("b", **{**BEAM, "n_modes_z": 1}, stations={"mid": 0.5}),
        sp.Revolute(name="j", parent=None, child="b", axis=(0, 0, 1), stiffness=3.0, damping=0.2, reference=0.05),
        sp.SpatialBody("tip", 0.3, [[0.01, 0.001, 0.0], [0.001, 0.02, 0.0], [0.0, 0.0, 0.025]],
                       center_of_mass=(0.05, 0.0, 0.01), points={"p": (0.1, 0.02, 0.0)}),
        sp.Revolute(name="k", parent="b", child="tip", point="tip", axis=(0, 1, 0), stiffness=2.0, damping=0.1)],
        gravity=(0.3, 0.0, -9.81))
    names = ["b.mass_per_length", "b.polar_inertia_per_length", "b.bending_stiffness_z", "b.torsional_stiffness",
             "b.damping_ratio", "j.reference", "tip.mass", "tip.inertia.xy", "k.stiffness", "k.damping", "gravity.x"]
    outputs = ["j.angle", "k.rate", "b.qy1", "b.tip.w_y", "b.mid.slope_z_rate", "b.tip.twist", "b.mid.y", "b.tip.vz",
               "tip.p.x", "tip.p.vy", "tip.com.z", "tip.omega_body_y", "tip.angle_x", "tip.rotation_y", "b.omega_z"]
    start = dict(x0={"j.angle": 0.3, "b.qy1": 0.01, "b.twist1": 0.02, "k.angle": 0.2}, v0={"b.qz1_rate": 0.1})
    found = S.simulation_sensitivity(model, names, t_final=0.06, dt=0.003, outputs=outputs, **start)

    def history(s):
        run = ctmm.simulate(s, 0.06, 0.003, method="rk4", outputs=outputs, **start)
        return np.array([run[name] for name in outputs])

    values = history(model)
    assert np.max(np.abs(found.values - values)) < 1e-12
    scales = np.max(np.abs(values), axis=1)
    for i, name in enumerate(names):
        expected = central_difference(history, model, name, step=3e-4)
        value = abs(S.parameter_values(model, [name])[name])
        for o, output in enumerate(outputs):
            bound = 1e-6 * np.max(np.abs(expected[o])) + 1e-10 * scales[o] / value
            assert np.max(np.abs(found.derivative[i, o] - expected[o])) < bound, (name, output)
