"""Bad input gives clear errors naming the parameter, the value and what is allowed."""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm.elements import (BeamClamped, BeamFree, Damper, Elastic, Fixed, Free, GroundedSpring, Mass, Spring,
                           SpringDamper)
from ctmm.schemes import GeneralizedAlpha, Newmark, WilsonTheta
from ctmm.spatial_beam_elements import SpatialClamped


def chain():
    return ctmm.Chain("c", [Fixed("w"), Spring("k", 10.0), Mass("m", 1.0), Free("e")])


@pytest.mark.parametrize("factory, pattern", [
    (lambda: Mass("m", 0.0), r"m: mass must be > 0, got 0"),
    (lambda: Mass("m", -1.0), r"mass must be > 0, got -1"),
    (lambda: Mass("m", float("nan")), r"mass must be finite, got nan"),
    (lambda: Spring("k", 0.0), r"k: stiffness must be > 0"),
    (lambda: Spring("k", float("inf")), r"stiffness must be finite"),
    (lambda: Damper("c", -0.1), r"damping must be > 0, got -0.1"),
    (lambda: SpringDamper("kc", 1.0, -1.0), r"damping must be >= 0, got -1"),
    (lambda: SpringDamper("kc", 0.0, 0.0), r"needs stiffness > 0 or damping > 0"),
    (lambda: GroundedSpring("g", -5.0), r"stiffness must be > 0"),
    (lambda: Elastic("s", -1.0), r"stiffness must be >= 0"),
    (lambda: Mass("m", 1.0, force="ten"), r"force must be a real number"),
    (lambda: Mass("m.1", 1.0), r"element name must be a non-empty string without '\.'"),
    (lambda: Newmark(beta=0.0), r"beta must be > 0"),
    (lambda: GeneralizedAlpha(1.5), r"rho_infinity must be in \[0.0, 1.0\]"),
    (lambda: WilsonTheta(0.5), r"theta must be >= 1"),
])
def test_invalid_parameters(factory, pattern):
    with pytest.raises(ctmm.ModelError, match=pattern):
        factory()


def test_a_loop_without_gain_is_refused_naming_gain():
    """No default gain: a forgotten ``gain=`` must not build a silently open (zero-gain) loop."""
    with pytest.raises(TypeError, match=r"missing 1 required positional argument: 'gain'"):
        ctmm.control.Feedback("pd", "m.x", "m")
    with pytest.raises(TypeError, match=r"'gain'"):
        ctmm.control.Feedback("pd", "m.x", "m", delay=0.01)


def test_model_error_is_value_error():
    assert issubclass(ctmm.ModelError, ValueError)
    assert issubclass(ctmm.SimulationError, RuntimeError)


def test_chain_structure_errors_reported_together():
    with pytest.raises(ctmm.ModelError) as info:
        ctmm.Chain("bad", [Spring("k", 1.0), Mass("k", 1.0), Fixed("w2"), Mass("m", 1.0), Spring("x", 1.0)])
    text = str(info.value)
    assert "first element must be a boundary" in text
    assert "last element must be a boundary" in text
    assert "duplicate element name 'k'" in text
    assert "boundary 'w2' at position 2 is inside the chain" in text


@pytest.mark.parametrize("start, end", [
    (lambda: Fixed("w"), lambda: BeamFree("e")),
    (lambda: BeamClamped("w"), lambda: Free("e")),
    (lambda: SpatialClamped("w"), lambda: Free("e")),
])
def test_chain_refuses_a_boundary_of_another_layout(start, end):
    """A beam or spatial-beam boundary ends an axial chain: a mixed-layout chain (Chain's docstring), refused by
    name; it was accepted and acted as Fixed / Free."""
    with pytest.raises(ctmm.ModelError, match="is for the '(bending|spatial_beam)' layout, the elements use 'axial'"):
        ctmm.Chain("mixed", [start(), Spring("k", 100.0), Mass("m", 1.0), end()])


@pytest.mark.parametrize("call, pattern", [
    (lambda c: ctmm.simulate(c, 1.0, 0.0), r"dt must be > 0, got 0"),
    (lambda c: ctmm.simulate(c, 1.0, -1e-3), r"dt must be > 0"),
    (lambda c: ctmm.simulate(c, float("nan"), 1e-3), r"t_final must be finite"),
    (lambda c: ctmm.simulate(c, 1.0, 0.3), r"whole number of steps"),
    (lambda c: ctmm.simulate(c, 1.0, 1e-3, scheme="rk99"), r"unknown scheme 'rk99'; available: forward_euler"),
    (lambda c: ctmm.simulate(c, 1.0, 1e-3, solver="lu"), r"solver must be one of"),
    (lambda c: ctmm.frequency_response(c, [-1.0], input="m.force", output="m.x"), r"omega must be >= 0"),
    (lambda c: ctmm.frequency_response(c, [np.nan], input="m.force", output="m.x"), r"omega must contain only finite"),
    (lambda c: ctmm.natural_frequencies(c), r"give exactly one of n_modes"),
    (lambda c: ctmm.natural_frequencies(c, n_modes=0), r"n_modes must be an integer >= 1"),
    (lambda c: ctmm.natural_frequencies(c, n_modes=5), r"fewer than 5 natural frequencies"),
])
def test_invalid_calls(call, pattern):
    with pytest.raises(ctmm.ModelError, match=pattern):
        call(chain())


@pytest.mark.parametrize("name", ["m.nope", "nothing.x", "m", "m.in.out.x"])
def test_unknown_signal_lists_available(name):
    with pytest.raises(ctmm.UnknownNameError, match=r"unknown signal .* available: .*m\.x"):
        ctmm.frequency_response(chain(), [1.0], input="m.force", output=name)


def test_unknown_input_lists_available():
    with pytest.raises(ctmm.UnknownNameError, match=r"unknown input 'm\.torque'; available: .*m\.force"):
        ctmm.frequency_response(chain(), [1.0], input="m.torque", output="m.x")


def test_unknown_initial_condition_name():
    with pytest.raises(ctmm.UnknownNameError, match=r"unknown element 'mass9'; available"):
        ctmm.simulate(chain(), 0.01, 1e-3, x0={"mass9": 0.1})


def test_unknown_scenario_lists_available():
    from ctmm.scenario import run_scenario

    with pytest.raises(ctmm.UnknownNameError, match=r"unknown scenario 'nope'; available: .*table7_1"):
        run_scenario("nope")


@pytest.mark.parametrize("call, pattern", [
    (lambda c: c.position(["m"]), r"unknown element \"\['m'\]\"; available: e, k, m, w"),
    (lambda c: ctmm.control.Feedback("L", [(3, 1.0)], "m", 1.0), r"sensor must be a signal name or a sequence of "
                                                            r"\(signal, weight\) pairs, got \[\(3, 1\.0\)\]"),
    (lambda c: ctmm.simulate(c, 0.1, 0.01, x0={"m": "0.5"}), r"x0\['m'\] must be a real number, got '0\.5'"),
    (lambda c: Mass("m", "1.5"), r"m: mass must be a real number, got '1\.5'"),
    (lambda c: ctmm.Chain("", list(c.elements)), r"chain name must be a non-empty string, got ''"),
    (lambda c: ctmm.simulate(c, 0.1, 0.01, force_hook=3), r"force_hook must be a callable or None, got 3"),
    (lambda c: ctmm.simulate(c, 0.1, 0.01, fast=1), r"fast must be True, False or None, got 1"),
    (lambda c: ctmm.frequency_response(c, [], input="m.force", output="m.x"),
     r"omega must contain at least one frequency \[rad/s\], got \[\]"),
])
def test_invalid_calls_name_parameter_and_value(call, pattern):
    with pytest.raises(ctmm.ModelError, match=pattern):
        call(chain())


@pytest.mark.parametrize("value", [[1.0, True], (0.5, np.True_), [[1.0, 2.0], [False, 3.0]], np.array([True, False]),
                                   np.array([1.0, True], dtype=object)])
def test_finite_arrays_refuse_booleans_inside_lists_and_arrays(value):
    """A boolean is not a number: ``[1.0, True]`` is refused, not read as ``[1.0, 1.0]``."""
    from ctmm import validation

    with pytest.raises(ctmm.ModelError, match=r"gains must be an array of real numbers \(a boolean is not read"):
        validation.finite_array("gains", value)


def test_finite_arrays_take_integers_and_numpy_numbers():
    from ctmm import validation

    for value, expected in (([1, 2.5], [1.0, 2.5]), (np.arange(3), [0.0, 1.0, 2.0]), ((np.float32(0.5), np.int64(2)),
                                                                                   [0.5, 2.0])):
        array = validation.finite_array("gains", value)
        assert array.dtype == np.float64 and array.tolist() == expected


def test_a_planar_gravity_with_a_boolean_is_refused():
    from ctmm.planar import Pinned, PlanarModel, RigidBody

    with pytest.raises(ctmm.ModelError, match=r"gravity must be an array of real numbers.*\(0.0, True\)"):
        PlanarModel.chain("p", [Pinned("o"), RigidBody.uniform_link("l", mass=1.0, length=1.0)], gravity=(0.0, True))
