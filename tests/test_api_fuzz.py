"""Property-based fuzz of the public API: every bad input gives a clear error (issue 11, item 8).

Each entry of :data:`CASES` calls one public function or constructor with one parameter replaced
by a value drawn from a catalogue of bad inputs for that parameter's *kind* (bad types, shapes,
NaN/inf, negative and zero values, huge/tiny values, unknown names, empty inputs, wrong
containers, bools for numbers, strings for numbers, None).  The call must raise
:class:`ctmm.ModelError` (or a ``TypeError`` subclass) whose message names the parameter and the
offending value: no silent acceptance, no internal error, no generic message.

:data:`PUBLIC_API` lists every public name of the package with where it is checked, and
:func:`test_public_api_list_is_complete` keeps the list in step with the ``__all__`` lists.
The concrete cases of the issue and valid edge inputs (a single mass, one frequency,
``omega = 0``, checked against closed-form results) are in :mod:`test_api_edge_inputs`.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ctmm
from ctmm import interop, signals, stability
from ctmm.control import ControlledChain, Feedback, PlantCache, simulate_controlled
from ctmm.control.analysis import closed_loop_response, loop_transfer_function, margins
from ctmm.elements import (BeamField, BeamHinge, BeamPointMass, BeamSpring, Damper, Elastic, Fixed, Free,
                           GroundedSpring, Mass, PrescribedDisplacement, PrescribedForce, Spring, SpringDamper)
from ctmm.modal import modal_response

from _controllers_import import load_controllers

controllers = load_controllers()

# --------------------------------------------------------------------------------------------
# the public API and where each name is checked
# --------------------------------------------------------------------------------------------
FUZZED = "fuzzed in CASES"
PUBLIC_API: dict[str, str] = {
    # ctmm
    "ctmm.Chain": FUZZED, "ctmm.simulate": FUZZED, "ctmm.characteristic_function": FUZZED,
    "ctmm.frequency_response": FUZZED, "ctmm.natural_frequencies": FUZZED, "ctmm.mode_shapes": FUZZED,
    "ctmm.eigenvalue_count": FUZZED, "ctmm.steady_state_response": FUZZED,
    "ctmm.linearize": FUZZED, "ctmm.LinearizedSystem": "result",
    "ctmm.signals": "module: its classes are fuzzed", "ctmm.control": "module", "ctmm.stability": "module",
    "ctmm.ModelError": "exception type", "ctmm.SimulationError": "exception type",
    "ctmm.ConvergenceError": "exception type", "ctmm.SingularSystemError": "exception type",
    "ctmm.UnknownNameError": "exception type", "ctmm.__version__": "string",
    "ctmm.load_scene": "tests/test_scene_files.py (every error: file, line, key, allowed values)",
    "ctmm.export_fmu": "tests/test_fmu_export.py (bad arguments, refusals, fmpy round trips)",
    # ctmm.elements
    "ctmm.elements.Element": "abstract base", "ctmm.elements.DiscreteElement": "abstract base",
    "ctmm.elements.Linearisation": "internal record of the stepper", "ctmm.elements.Boundary": "abstract base",
    "ctmm.elements.Fixed": FUZZED, "ctmm.elements.Free": FUZZED, "ctmm.elements.Elastic": FUZZED,
    "ctmm.elements.PrescribedDisplacement": FUZZED, "ctmm.elements.PrescribedForce": FUZZED,
    "ctmm.elements.PointElement": "base of Mass/GroundedSpring", "ctmm.elements.Mass": FUZZED,
    "ctmm.elements.GroundedSpring": FUZZED, "ctmm.elements.Connector": "base of Spring/Damper",
    "ctmm.elements.Spring": FUZZED, "ctmm.elements.Damper": FUZZED, "ctmm.elements.SpringDamper": FUZZED,
    "ctmm.elements.Inerter": "tests/test_inerter.py",
    "ctmm.elements.LumpedCoefficients": "record of an element's lumped form (tests/test_inerter.py)",
    "ctmm.elements.BeamField": FUZZED, "ctmm.elements.BeamPointMass": FUZZED,
    "ctmm.elements.BeamSpring": FUZZED, "ctmm.elements.BeamHinge": FUZZED,
    "ctmm.elements.BeamPointLoad": "tests/test_beams_*.py", "ctmm.elements.BeamClamped": "tests/test_beams_*.py",
    "ctmm.elements.BeamFree": "tests/test_beams_*.py", "ctmm.elements.BeamPinned": "tests/test_beams_*.py",
    "ctmm.elements.BeamSliding": "tests/test_beams_*.py",
    # ctmm.control
    "ctmm.control.Controller": "protocol: check_controllers fuzzed", "ctmm.control.ControllerStep": "record",
    "ctmm.control.Feedback": FUZZED, "ctmm.control.ControlledChain": FUZZED,
    "ctmm.control.simulate_controlled": FUZZED, "ctmm.control.FMUController": FUZZED,
    "ctmm.control.build_fmu": FUZZED, "ctmm.control.loop_transfer_function": FUZZED,
    "ctmm.control.margins": FUZZED, "ctmm.control.closed_loop_response": FUZZED,
    "ctmm.control.bode_plot": "tests/test_control_tools.py", "ctmm.control.nyquist_plot": "tests/test_control_tools.py",
    "ctmm.control.PlantCache": FUZZED,
    "ctmm.sensitivity": "module: tests/test_sensitivity.py", "ctmm.control.tune": "tests/test_tuning.py",
    "ctmm.simulate_batch": "tests/test_batch.py (bad sets refused by index and name, failures kept by index)",
    "ctmm.parameter_names": "tests/test_batch.py",
    "ctmm.control.Quantity": "tests/test_tuning.py", "ctmm.control.Constraint": "tests/test_tuning.py",
    "ctmm.control.TuningResult": "result",
    "ctmm.control.DelayedController": "tests/test_api_fuzz_planar.py", "ctmm.control.StaticGainController": FUZZED,
    "ctmm.control.ControlledModel": "tests/test_api_fuzz_planar.py", "ctmm.control.with_feedback": "tests/test_api_fuzz_planar.py",
    "ctmm.control.encirclements": "tests/test_control_tools.py",
    # ctmm.stability
    "ctmm.stability.LoopCharacteristic": "tests/test_stability.py", "ctmm.stability.characteristic_roots": FUZZED,
    "ctmm.stability.spectral_abscissa": "tests/test_roots.py", "ctmm.stability.spectral_seeds": "tests/test_roots.py",
    "ctmm.stability.unstable_root_count": FUZZED, "ctmm.stability.DelayMargin": "result record",
    "ctmm.stability.delay_margin": FUZZED, "ctmm.stability.GainMargin": "result record",
    "ctmm.stability.gain_margin": FUZZED, "ctmm.stability.SimulationCheck": "result record",
    "ctmm.stability.crosscheck_by_simulation": FUZZED,
    "ctmm.stability.stability_chart": FUZZED, "ctmm.stability.StabilityChart": "result",
    "ctmm.stability.Boundary": "result record", "ctmm.stability.RootCounts": "result record",
    "ctmm.stability.gain_crossovers": FUZZED,
    # ctmm.planar
    "ctmm.planar.ActuatedHinge": "tests/test_planar_model.py", "ctmm.planar.DamperHinge": "tests/test_planar_model.py",
    "ctmm.planar.DrivenHinge": "tests/test_planar_model.py", "ctmm.planar.ElasticHinge": FUZZED,
    "ctmm.planar.Fixed": "tests/test_planar_model.py", "ctmm.planar.Free": "tests/test_planar_model.py",
    "ctmm.planar.FreeBase": "tests/test_planar_model.py", "ctmm.planar.Load": FUZZED,
    "ctmm.planar.Pinned": "tests/test_planar_model.py", "ctmm.planar.RigidBody": FUZZED,
    "ctmm.planar.SmoothHinge": "tests/test_planar_model.py", "ctmm.planar.NonlinearHinge": "tests/test_nonlinear_laws.py",
    "ctmm.planar.SpringDamperHinge": "tests/test_planar_model.py", "ctmm.planar.PlanarModel": FUZZED,
    "ctmm.planar.InstantaneousSolution": "result record", "ctmm.planar.accelerations": FUZZED,
    "ctmm.planar.ode_rhs": "tests/test_planar_integration.py", "ctmm.planar.solve_instant": FUZZED,
    "ctmm.planar.PlanarSimulation": "result", "ctmm.planar.simulate_rk4": FUZZED,
    "ctmm.planar.simulate_scipy": FUZZED, "ctmm.planar.simulate_implicit": FUZZED,
    # ctmm.flexible
    "ctmm.flexible.ModalBeam": FUZZED, "ctmm.flexible.ModalForce": "tests/test_flexible_beam.py",
    "ctmm.flexible.BeamData": "tests/test_flexible_beam.py", "ctmm.flexible.ModeSet": "tests/test_flexible_beam.py",
    "ctmm.flexible.FlexibleSolution": "result record", "ctmm.flexible.solve_flexible": "tests/test_flexible_beam.py",
    "ctmm.flexible.finite_segment_beam": FUZZED, "ctmm.flexible.tip_deflection": "tests/test_flexible_time.py",
    "ctmm.flexible.axial_tip_displacement": "tests/test_flexible_time.py", "ctmm.flexible.mape": "metric",
    "ctmm.flexible.spinup_law": "tests/test_flexible_scenarios.py",
    # ctmm.manipulator
    "ctmm.manipulator.Arm": FUZZED, "ctmm.manipulator.Hub": FUZZED,
    "ctmm.manipulator.PiezoMaterial": "tests/test_manipulator_parameters.py", "ctmm.manipulator.PZT_5A": "constant",
    "ctmm.manipulator.PZT_5H": "constant", "ctmm.manipulator.PZTPatch": FUZZED,
    "ctmm.manipulator.Manipulator": FUZZED,
    "ctmm.manipulator.moment_per_volt": "tests/test_manipulator_parameters.py",
    "ctmm.manipulator.CycloidalMove": FUZZED,
    "ctmm.manipulator.seed_manipulator": "tests/test_manipulator_*.py", "ctmm.manipulator.SEED_KP": "constant",
    "ctmm.manipulator.SEED_KD": "constant", "ctmm.manipulator.SEED_PZT_GAIN": "constant",
    "ctmm.manipulator.SEED_MOVE": "constant", "ctmm.manipulator.HubPD": FUZZED,
    "ctmm.manipulator.PZTFeedback": "tests/test_manipulator_time.py",
    "ctmm.manipulator.manipulator_plant": "tests/test_manipulator_scene.py",
    "ctmm.manipulator.manipulator_scene": "tests/test_api_fuzz_planar.py",
    "ctmm.manipulator.scene_references": "tests/test_api_fuzz_planar.py",
    "ctmm.manipulator.ManipulatorSimulation": "result",
    # ctmm.controllers, ctmm.interop, ctmm.signals, ctmm.modal
    "ctmm.controllers.SaturatedPD": FUZZED, "ctmm.controllers.SaturatedPDState": "state record",
    "ctmm.controllers.PID": FUZZED, "ctmm.controllers.PIDState": "state record",
    "ctmm.controllers.FMU_SOURCES": "constant", "ctmm.controllers.fmu_source": FUZZED,
    "ctmm.interop.to_frd": FUZZED, "ctmm.interop.to_state_space": FUZZED,
    "ctmm.interop.assemble_matrices": FUZZED, "ctmm.interop.control_name": "string helper",
    "ctmm.interop.default_signal_names": "tests/test_linearize.py",
    "ctmm.signals.Constant": FUZZED, "ctmm.signals.Harmonic": FUZZED, "ctmm.signals.Step": FUZZED,
    "ctmm.signals.SquareWave": FUZZED, "ctmm.signals.Ramp": FUZZED, "ctmm.signals.as_signal": FUZZED,
    "ctmm.signals.harmonic_amplitude": "internal use by the frequency domain", "ctmm.modal.modal_response": FUZZED,
    # result objects
    "FrequencyResponse.__call__": FUZZED, "FrequencyResponse.plot": "tests/test_frequency_domain.py",
    "SimulationResult.__getitem__": FUZZED, "SimulationResult.to_dataframe": "optional pandas",
    "SimulationResult.plot": "tests/test_time_domain.py",
}
SIGNALS_API = ("Constant", "Harmonic", "Step", "SquareWave", "Ramp", "as_signal", "harmonic_amplitude")


def test_public_api_list_is_complete():
    """Every name exported by the package appears in PUBLIC_API (fuzzed here or tested elsewhere)."""
    import ctmm.controllers
    import ctmm.flexible
    import ctmm.manipulator
    import ctmm.planar

    modules = {"ctmm": ctmm, "ctmm.elements": ctmm.elements, "ctmm.control": ctmm.control,
               "ctmm.stability": ctmm.stability, "ctmm.planar": ctmm.planar, "ctmm.flexible": ctmm.flexible,
               "ctmm.manipulator": ctmm.manipulator, "ctmm.controllers": ctmm.controllers,
               "ctmm.interop": interop}
    exported = {f"{prefix}.{name}" for prefix, module in modules.items() for name in module.__all__}
    exported |= {f"ctmm.signals.{name}" for name in SIGNALS_API}
    missing = sorted(exported - set(PUBLIC_API))
    assert not missing, f"public names missing from PUBLIC_API: {missing}"
    fuzzed = {case.api for case in CASES}
    claimed = {name for name, where in PUBLIC_API.items() if where == FUZZED}
    assert claimed <= fuzzed, f"marked as fuzzed but without a case: {sorted(claimed - fuzzed)}"


# --------------------------------------------------------------------------------------------
# models used by the cases
# --------------------------------------------------------------------------------------------
def chain() -> ctmm.Chain:
    return ctmm.Chain("c", [Fixed("w"), Spring("k", 10.0), Mass("m", 1.0), Free("e")])


def controlled() -> ControlledChain:
    return ControlledChain(chain(), [Feedback("L", sensor="m.v", actuator="m", gain=1.0, delay=0.01)])


def pendulum():
    from ctmm.planar import PlanarModel, Pinned, RigidBody

    return PlanarModel.chain("p", [Pinned("o"), RigidBody.uniform_link("l", mass=1.0, length=1.0)])


def sim_result():
    return ctmm.simulate(chain(), 0.02, 0.01)


def frf():
    return ctmm.frequency_response(chain(), [1.0], input="m.force", output="m.x")


# --------------------------------------------------------------------------------------------
# catalogues of bad values by kind
# --------------------------------------------------------------------------------------------
class Opaque:
    """An object of no meaning to ctmm (its repr is short and stable)."""

    def __repr__(self) -> str:
        return "Opaque()"


NOT_NUMBERS = [None, "abc", "1.5", True, False, [1.0, 2.0], [], {"a": 1.0}, Opaque(), 1j, np.array([1.0])]
NON_FINITE = [math.nan, math.inf, -math.inf]
_finite_floats = st.floats(allow_nan=False, allow_infinity=False)
BAD: dict[str, st.SearchStrategy] = {
    "real": st.sampled_from(NOT_NUMBERS + NON_FINITE),
    "positive": st.sampled_from(NOT_NUMBERS + NON_FINITE + [0.0, -0.0, -1.0, -1e-300, -1e300])
    | st.floats(max_value=0.0, allow_nan=False, allow_infinity=False),
    "nonnegative": st.sampled_from(NOT_NUMBERS + NON_FINITE + [-1.0, -1e-300])
    | st.floats(max_value=-1e-300, allow_nan=False, allow_infinity=False),
    "integer": st.sampled_from([0, -1, True, 1.5, "2", [1], math.nan, math.inf, Opaque()])
    | st.integers(max_value=0),
    "system": st.sampled_from([None, 1.0, "c", [], {}, Opaque(), True,
                               [Fixed("w"), Mass("m", 1.0), Free("e")]]),
    "names": st.sampled_from([None, 1.0, True, [1.0], {"m.x": 1.0}, [], Opaque(), ("m.x", 3)]),
    "mapping": st.sampled_from([[("m", 1.0)], 1.0, "m", True, Opaque(), {"m": math.nan}, {"m": "a"},
                                {1: 1.0}, {"m": None}, {"m": math.inf}, {"m": [1.0]}]),
    "frequencies": st.sampled_from([None, "a", True, [], [[1.0, 2.0]], {"a": 1.0}, Opaque(), [1.0, "x"]])
    | st.lists(st.sampled_from(NON_FINITE) | st.floats(max_value=-1e-300, allow_nan=False), min_size=1,
               max_size=3),
    "frequency": st.sampled_from([None, "a", True, [], [1.0, 2.0], {"a": 1.0}, Opaque(), -1.0]
                                 + NON_FINITE),
    "complex": st.sampled_from([None, "a", True, [], {"a": 1.0}, Opaque(), math.nan, math.inf,
                                complex(math.nan, 0.0), [1j, complex(0.0, math.inf)]]),
    "flag": st.sampled_from([1, 0, 0.0, "yes", [], Opaque(), math.nan]),
    "callable": st.sampled_from([1.0, "f", [], {}, Opaque(), True]),
    "option": st.sampled_from(["nope", "", None, 1, [], {}, True, Opaque()]),
    "name": st.sampled_from(["", "a.b", "a b", None, 1.0, [], Opaque(), True]),
    "text": st.sampled_from(["", "  ", None, 1.0, [], Opaque(), True]),
    "numbers": st.sampled_from([None, "a", True, [], {"a": 1.0}, Opaque(), [math.nan], [1.0, math.inf], ["x"]]),
    "loops": st.sampled_from([None, 3, "L", [3], {"L": 1.0}, [None], Opaque(), [chain()]]),
    "controllers": st.sampled_from([None, 3, [3], "pd", [Opaque()], Opaque()]),
    "elements": st.sampled_from([None, 3.0, "abc", Opaque(), True, {"w": Fixed("w")}, [1.0, 2.0, 3.0]]),
    "coordinates": st.sampled_from([None, "a", True, [], [0.0, 0.0], [[0.0]], {"q": 0.0}, Opaque(),
                                    [math.nan], [math.inf]]),
    "time_step": st.sampled_from([1e-300, 1e-200, 1e-30]),
    "path": st.sampled_from([None, 3.0, True, [], {}, "", Opaque()]),
}


@dataclass(frozen=True)
class Case:
    """One parameter of one public callable: ``call(value)`` must refuse every bad ``value``."""

    api: str
    parameter: str
    kind: str
    call: Callable[[Any], Any]
    valid: tuple = ()   # values of the kind's catalogue that are valid for this parameter (skipped)

    def __repr__(self) -> str:  # readable hypothesis reports
        return f"Case({self.api}, {self.parameter}, {self.kind})"


def _force(value):
    return Mass("m", 1.0, force=value)


CASES: list[Case] = [
    # elements
    Case("ctmm.elements.Mass", "mass", "positive", lambda v: Mass("m", v)),
    Case("ctmm.elements.Mass", "element name", "name", lambda v: Mass(v, 1.0)),
    Case("ctmm.elements.Mass", "force", "real", lambda v: _force(v) if not callable(v) else _force("x")),
    Case("ctmm.elements.Spring", "stiffness", "positive", lambda v: Spring("k", v)),
    Case("ctmm.elements.Spring", "free_length", "real", lambda v: Spring("k", 1.0, free_length=v)),
    Case("ctmm.elements.Damper", "damping", "positive", lambda v: Damper("c", v)),
    Case("ctmm.elements.SpringDamper", "damping", "nonnegative", lambda v: SpringDamper("k", 1.0, v)),
    Case("ctmm.elements.GroundedSpring", "stiffness", "positive", lambda v: GroundedSpring("g", v)),
    Case("ctmm.elements.Elastic", "stiffness", "nonnegative", lambda v: Elastic("s", v)),
    Case("ctmm.elements.Fixed", "position", "real", lambda v: Fixed("w", position=v)),
    Case("ctmm.elements.Free", "element name", "name", lambda v: Free(v)),
    Case("ctmm.elements.PrescribedDisplacement", "displacement", "real", lambda v: PrescribedDisplacement("p", v)),
    Case("ctmm.elements.PrescribedForce", "force", "real", lambda v: PrescribedForce("p", v)),
    # chain and frequency domain
    Case("ctmm.Chain", "elements", "elements", lambda v: ctmm.Chain("c", v)),
    Case("ctmm.Chain", "chain name", "text", lambda v: ctmm.Chain(v, list(chain().elements))),
    Case("ctmm.frequency_response", "system", "system",
         lambda v: ctmm.frequency_response(v, [1.0], input="m.force", output="m.x")),
    Case("ctmm.frequency_response", "omega", "frequencies",
         lambda v: ctmm.frequency_response(chain(), v, input="m.force", output="m.x")),
    Case("ctmm.frequency_response", "input", "names",
         lambda v: ctmm.frequency_response(chain(), [1.0], input=v, output="m.x")),
    Case("ctmm.frequency_response", "output", "names",
         lambda v: ctmm.frequency_response(chain(), [1.0], input="m.force", output=v)),
    Case("ctmm.frequency_response", "solver", "option",
         lambda v: ctmm.frequency_response(chain(), [1.0], input="m.force", output="m.x", solver=v)),
    Case("ctmm.steady_state_response", "system", "system", lambda v: ctmm.steady_state_response(v, 1.0)),
    Case("ctmm.steady_state_response", "omega", "frequency", lambda v: ctmm.steady_state_response(chain(), v)),
    Case("ctmm.steady_state_response", "outputs", "names",
         lambda v: ctmm.steady_state_response(chain(), 1.0, outputs=v), valid=(None,)),
    Case("ctmm.characteristic_function", "s", "complex", lambda v: ctmm.characteristic_function(chain(), v)),
    Case("ctmm.characteristic_function", "system", "system", lambda v: ctmm.characteristic_function(v, 1j)),
    Case("ctmm.natural_frequencies", "n_modes", "integer", lambda v: ctmm.natural_frequencies(chain(), n_modes=v)),
    Case("ctmm.natural_frequencies", "omega_max", "positive",
         lambda v: ctmm.natural_frequencies(chain(), omega_max=v), valid=(None,)),
    Case("ctmm.natural_frequencies", "system", "system", lambda v: ctmm.natural_frequencies(v, n_modes=1)),
    Case("ctmm.mode_shapes", "n_modes", "integer", lambda v: ctmm.mode_shapes(chain(), n_modes=v)),
    Case("ctmm.mode_shapes", "system", "system", lambda v: ctmm.mode_shapes(v, n_modes=1)),
    Case("ctmm.eigenvalue_count", "omega", "frequencies", lambda v: ctmm.eigenvalue_count(chain(), v)),
    Case("ctmm.eigenvalue_count", "system", "system", lambda v: ctmm.eigenvalue_count(v, 1.0)),
    # time domain
    Case("ctmm.simulate", "system", "system", lambda v: ctmm.simulate(v, 0.1, 0.01)),
    Case("ctmm.simulate", "t_final", "real", lambda v: ctmm.simulate(chain(), v, 0.01)),
    Case("ctmm.simulate", "dt", "positive", lambda v: ctmm.simulate(chain(), 0.1, v)),
    Case("ctmm.simulate", "dt", "time_step", lambda v: ctmm.simulate(chain(), 1.0, v)),
    Case("ctmm.simulate", "t0", "real", lambda v: ctmm.simulate(chain(), 0.1, 0.01, t0=v)),
    Case("ctmm.simulate", "x0", "mapping", lambda v: ctmm.simulate(chain(), 0.1, 0.01, x0=v)),
    Case("ctmm.simulate", "v0", "mapping", lambda v: ctmm.simulate(chain(), 0.1, 0.01, v0=v)),
    Case("ctmm.simulate", "solver", "option", lambda v: ctmm.simulate(chain(), 0.1, 0.01, solver=v)),
    Case("ctmm.simulate", "scheme", "option", lambda v: ctmm.simulate(chain(), 0.1, 0.01, scheme=v)),
    Case("ctmm.simulate", "fast", "flag", lambda v: ctmm.simulate(chain(), 0.1, 0.01, fast=v)),
    Case("ctmm.simulate", "progress", "flag", lambda v: ctmm.simulate(chain(), 0.1, 0.01, progress=v)),
    Case("ctmm.simulate", "force_hook", "callable", lambda v: ctmm.simulate(chain(), 0.1, 0.01, force_hook=v)),
    Case("ctmm.modal.modal_response", "times", "frequencies", lambda v: modal_response(chain(), v)),
    Case("ctmm.modal.modal_response", "system", "system", lambda v: modal_response(v, [0.0, 1.0])),
    Case("ctmm.modal.modal_response", "x0", "mapping", lambda v: modal_response(chain(), [0.0], x0=v)),
    Case("ctmm.modal.modal_response", "n_modes", "integer",
         lambda v: modal_response(chain(), [0.0], n_modes=v), valid=(None,)),
    # control
    Case("ctmm.control.Feedback", "loop name", "name", lambda v: Feedback(v, sensor="m.x", actuator="m", gain=1.0)),
    Case("ctmm.control.Feedback", "sensor", "names", lambda v: Feedback("L", sensor=v, actuator="m", gain=1.0)),
    Case("ctmm.control.Feedback", "actuator", "names", lambda v: Feedback("L", sensor="m.x", actuator=v, gain=1.0)),
    Case("ctmm.control.Feedback", "gain", "real", lambda v: Feedback("L", sensor="m.x", actuator="m", gain=v)),
    Case("ctmm.control.Feedback", "delay", "nonnegative",
         lambda v: Feedback("L", sensor="m.x", actuator="m", gain=1.0, delay=v)),
    Case("ctmm.control.ControlledChain", "plant", "system", lambda v: ControlledChain(v, [])),
    Case("ctmm.control.ControlledChain", "loops", "loops", lambda v: ControlledChain(chain(), v)),
    Case("ctmm.control.simulate_controlled", "system", "system", lambda v: simulate_controlled(v, 0.1, 0.01)),
    Case("ctmm.control.simulate_controlled", "dt", "positive", lambda v: simulate_controlled(controlled(), 0.1, v)),
    Case("ctmm.control.simulate_controlled", "dt", "time_step",
         lambda v: simulate_controlled(controlled(), 1.0, v)),
    Case("ctmm.control.simulate_controlled", "x0", "mapping",
         lambda v: simulate_controlled(controlled(), 0.1, 0.01, x0=v)),
    Case("ctmm.control.simulate_controlled", "controllers", "controllers",
         lambda v: simulate_controlled(chain(), 0.1, 0.01, controllers=v)),
    Case("ctmm.control.loop_transfer_function", "omega", "frequencies",
         lambda v: loop_transfer_function(controlled(), "L", v)),
    Case("ctmm.control.loop_transfer_function", "loop", "names",
         lambda v: loop_transfer_function(controlled(), v, [1.0]), valid=(None,)),
    Case("ctmm.control.margins", "margins", "system", lambda v: margins(v)),
    Case("ctmm.control.closed_loop_response", "input", "names",
         lambda v: closed_loop_response(controlled(), [1.0], v, "m.x")),
    Case("ctmm.control.PlantCache", "omega", "frequencies",
         lambda v: PlantCache(controlled(), v, inputs="m.force", outputs="m.x")),
    Case("ctmm.control.PlantCache", "inputs", "names",
         lambda v: PlantCache(controlled(), [1.0], inputs=v, outputs="m.x")),
    # stability
    Case("ctmm.stability.unstable_root_count", "system", "system", lambda v: stability.unstable_root_count(v)),
    Case("ctmm.stability.unstable_root_count", "gain", "numbers",
         lambda v: stability.unstable_root_count(controlled(), gain=v), valid=(None,)),
    Case("ctmm.stability.unstable_root_count", "sigma", "real",
         lambda v: stability.unstable_root_count(controlled(), sigma=v)),
    Case("ctmm.stability.delay_margin", "delay_max", "positive",
         lambda v: stability.delay_margin(controlled(), delay_max=v), valid=(None,)),
    Case("ctmm.stability.gain_crossovers", "system", "system", lambda v: stability.gain_crossovers(v)),
    Case("ctmm.stability.gain_crossovers", "im_max", "positive",
         lambda v: stability.gain_crossovers(controlled(), im_max=v), valid=(None,)),
    Case("ctmm.stability.gain_margin", "max_factor", "positive",
         lambda v: stability.gain_margin(controlled(), max_factor=v)),
    Case("ctmm.stability.characteristic_roots", "re_min", "real",
         lambda v: stability.characteristic_roots(controlled(), re_min=v, im_max=50.0)),
    # signals, controllers, interop
    Case("ctmm.signals.Constant", "value", "real", lambda v: signals.Constant(v)),
    Case("ctmm.signals.Harmonic", "amplitude", "real", lambda v: signals.Harmonic(v, 1.0)),
    Case("ctmm.signals.Harmonic", "omega", "nonnegative", lambda v: signals.Harmonic(1.0, v)),
    Case("ctmm.signals.Step", "time", "real", lambda v: signals.Step(1.0, v)),
    Case("ctmm.signals.SquareWave", "period", "positive", lambda v: signals.SquareWave(1.0, v)),
    Case("ctmm.signals.SquareWave", "duration", "positive",
         lambda v: signals.SquareWave(1.0, 1.0, v), valid=(math.inf,)),
    Case("ctmm.signals.Ramp", "slope", "real", lambda v: signals.Ramp(v)),
    Case("ctmm.signals.Ramp", "offset", "real", lambda v: signals.Ramp(1.0, v)),
    Case("ctmm.signals.Ramp", "start", "real", lambda v: signals.Ramp(1.0, 0.0, v)),
    Case("ctmm.signals.as_signal", "force", "real", lambda v: signals.as_signal("force", v)),
    Case("ctmm.controllers.SaturatedPD", "kp", "real",
         lambda v: controllers.SaturatedPD(("m.x", "m.v"), "m.force", kp=v, kd=1.0)),
    Case("ctmm.controllers.SaturatedPD", "limit", "positive",
         lambda v: controllers.SaturatedPD(("m.x", "m.v"), "m.force", kp=1.0, kd=1.0, limit=v), valid=(None,)),
    Case("ctmm.controllers.PID", "sample_time", "positive",
         lambda v: controllers.PID("m.x", "m.force", kp=1.0, ki=0.0, kd=0.0, derivative_filter_time=0.0,
                                   sample_time=v)),
    Case("ctmm.controllers.fmu_source", "FMU source", "option", lambda v: controllers.fmu_source(v)),
    Case("ctmm.control.FMUController", "path", "path",
         lambda v: __import__("ctmm.control").control.FMUController(v, inputs=("m.x",), outputs=("m.force",),
                                                                    sample_time=0.01)),
    Case("ctmm.control.build_fmu", "source_dir", "path", lambda v: __import__("ctmm.control").control.build_fmu(v)),
    Case("ctmm.interop.to_frd", "source", "system", lambda v: interop.to_frd(v, [1.0], inputs="m.force",
                                                                            outputs="m.x")),
    Case("ctmm.interop.to_frd", "omega", "frequencies",
         lambda v: interop.to_frd(chain(), v, inputs="m.force", outputs="m.x")),
    Case("ctmm.interop.to_state_space", "system", "system", lambda v: interop.to_state_space(v)),
    Case("ctmm.interop.assemble_matrices", "system", "system", lambda v: interop.assemble_matrices(v)),
    Case("ctmm.interop.to_state_space", "inputs", "names",
         lambda v: interop.to_state_space(chain(), inputs=v), valid=(None,)),
    Case("ctmm.interop.to_state_space", "outputs", "names",
         lambda v: interop.to_state_space(chain(), outputs=v), valid=(None,)),
    Case("ctmm.linearize", "system", "system", lambda v: ctmm.linearize(v)),
    Case("ctmm.linearize", "outputs", "names", lambda v: ctmm.linearize(chain(), outputs=v), valid=(None,)),
    # results
    Case("FrequencyResponse.__call__", "output", "names", lambda v: frf()(v), valid=(None,)),
    Case("SimulationResult.__getitem__", "signal", "names", lambda v: sim_result()[v]),
    # planar, flexible, manipulator
    Case("ctmm.planar.RigidBody", "mass", "positive",
         lambda v: __import__("ctmm.planar").planar.RigidBody.uniform_link("l", mass=v, length=1.0)),
    Case("ctmm.planar.PlanarModel", "chain elements", "elements",
         lambda v: __import__("ctmm.planar").planar.PlanarModel.chain("p", v)),
    Case("ctmm.planar.accelerations", "q", "coordinates",
         lambda v: __import__("ctmm.planar").planar.accelerations(pendulum(), v, [0.0])),
    Case("ctmm.planar.accelerations", "model", "system",
         lambda v: __import__("ctmm.planar").planar.accelerations(v, [0.0], [0.0])),
    Case("ctmm.planar.solve_instant", "qdot", "coordinates",
         lambda v: __import__("ctmm.planar").planar.solve_instant(pendulum(), [0.0], v)),
    Case("ctmm.planar.solve_instant", "t", "real",
         lambda v: __import__("ctmm.planar").planar.solve_instant(pendulum(), [0.0], [0.0], v)),
    Case("ctmm.planar.simulate_rk4", "store_every", "integer",
         lambda v: __import__("ctmm.planar").planar.simulate_rk4(pendulum(), [0.0], [0.0], t_final=0.02, dt=0.01,
                                                                  store_every=v)),
    Case("ctmm.planar.simulate_rk4", "dt", "time_step",
         lambda v: __import__("ctmm.planar").planar.simulate_rk4(pendulum(), [0.0], [0.0], t_final=1.0, dt=v)),
    Case("ctmm.planar.simulate_rk4", "q0", "coordinates",
         lambda v: __import__("ctmm.planar").planar.simulate_rk4(pendulum(), v, [0.0], t_final=0.02, dt=0.01)),
    Case("ctmm.planar.simulate_scipy", "t_final", "positive",
         lambda v: __import__("ctmm.planar").planar.simulate_scipy(pendulum(), [0.0], [0.0], t_final=v)),
    Case("ctmm.planar.simulate_scipy", "rtol", "positive",
         lambda v: __import__("ctmm.planar").planar.simulate_scipy(pendulum(), [0.0], [0.0], t_final=0.01, rtol=v)),
    Case("ctmm.planar.simulate_scipy", "t_eval", "frequencies",
         lambda v: __import__("ctmm.planar").planar.simulate_scipy(pendulum(), [0.0], [0.0], t_final=0.01, t_eval=v),
         valid=(None,)),
    Case("ctmm.planar.simulate_implicit", "store_every", "integer",
         lambda v: __import__("ctmm.planar").planar.simulate_implicit(pendulum(), [0.0], [0.0], t_final=0.02,
                                                                       dt=0.01, store_every=v)),
    Case("ctmm.planar.simulate_implicit", "max_iterations", "integer",
         lambda v: __import__("ctmm.planar").planar.simulate_implicit(pendulum(), [0.0], [0.0], t_final=0.02,
                                                                       dt=0.01, max_iterations=v)),
    Case("ctmm.flexible.finite_segment_beam", "n_segments", "integer",
         lambda v: __import__("ctmm.flexible").flexible.finite_segment_beam(
             "b", length=1.0, bending_stiffness=1.0, mass_per_length=1.0, n_segments=v)),
    Case("ctmm.flexible.finite_segment_beam", "length", "positive",
         lambda v: __import__("ctmm.flexible").flexible.finite_segment_beam(
             "b", length=v, bending_stiffness=1.0, mass_per_length=1.0, n_segments=2)),
    Case("ctmm.elements.BeamField", "length", "positive", lambda v: BeamField("b", v, 1.0, 1.0)),
    Case("ctmm.elements.BeamField", "bending_stiffness", "positive", lambda v: BeamField("b", 1.0, v, 1.0)),
    Case("ctmm.elements.BeamPointMass", "mass", "nonnegative", lambda v: BeamPointMass("p", v, 1.0)),
    Case("ctmm.elements.BeamSpring", "translational", "nonnegative", lambda v: BeamSpring("s", v, 1.0)),
    Case("ctmm.elements.BeamHinge", "rotational_stiffness", "positive", lambda v: BeamHinge("h", v)),
    Case("ctmm.planar.RigidBody", "inertia", "positive",
         lambda v: __import__("ctmm.planar").planar.RigidBody("b", mass=1.0, inertia=v)),
    Case("ctmm.planar.ElasticHinge", "stiffness", "positive",
         lambda v: __import__("ctmm.planar").planar.ElasticHinge("h", stiffness=v)),
    Case("ctmm.planar.Load", "force_x", "real", lambda v: __import__("ctmm.planar").planar.Load(force_x=v)),
    Case("ctmm.flexible.ModalBeam", "n_modes", "integer",
         lambda v: __import__("ctmm.flexible").flexible.ModalBeam("b", length=1.0, bending_stiffness=1.0,
                                                                 mass_per_length=1.0, n_modes=v)),
    Case("ctmm.manipulator.Hub", "inertia", "positive",
         lambda v: __import__("ctmm.manipulator").manipulator.Hub(inertia=v)),
    Case("ctmm.manipulator.HubPD", "delay", "nonnegative",
         lambda v: __import__("ctmm.manipulator").manipulator.HubPD(1.0, 1.0, delay=v)),
    Case("ctmm.manipulator.CycloidalMove", "duration", "positive",
         lambda v: __import__("ctmm.manipulator").manipulator.CycloidalMove(1.0, v)),
    Case("ctmm.stability.stability_chart", "x", "numbers",
         lambda v: stability.stability_chart(controlled(), v, ("delay", [0.0, 0.1]))),
    Case("ctmm.stability.crosscheck_by_simulation", "points", "loops",
         lambda v: stability.crosscheck_by_simulation(controlled(), v, t_final=0.1, dt=0.01)),
    Case("ctmm.manipulator.Manipulator", "patches", "loops",
         lambda v: __import__("ctmm.manipulator").manipulator.Manipulator(patches=v)),
    Case("ctmm.manipulator.PZTPatch", "thickness", "positive",
         lambda v: __import__("ctmm.manipulator").manipulator.PZTPatch("p", 0.1, 0.2, thickness=v)),
    Case("ctmm.flexible.ModalBeam", "bending_stiffness", "positive",
         lambda v: __import__("ctmm.flexible").flexible.ModalBeam("b", length=1.0, bending_stiffness=v,
                                                                 mass_per_length=1.0, n_modes=2)),
    Case("ctmm.manipulator.Arm", "length", "positive", lambda v: __import__("ctmm.manipulator").manipulator.Arm(
        length=v)),
    Case("ctmm.control.StaticGainController", "sample_time", "positive",
         lambda v: ctmm.control.StaticGainController(["a.x"], ["b.force"], [[1.0]], sample_time=v), valid=(None,)),
]


def _mentions(message: str, value: Any) -> bool:
    """Whether ``message`` shows the offending ``value`` (or, for a container, an offending item)."""
    candidates = [repr(value)[:40]]
    if isinstance(value, float) and math.isfinite(value):
        candidates += [f"{value:.3g}", str(value)]
    if isinstance(value, dict):
        candidates += [repr(k)[:40] for k in value] + [repr(v)[:40] for v in value.values()]
    if isinstance(value, (list, tuple)):
        for item in value:
            candidates.append(repr(item)[:40])
            if isinstance(item, float):
                candidates.append(repr(float(item)))
            if isinstance(item, (list, tuple)):
                candidates += [repr(x)[:40] for x in item]
    return any(c in message for c in candidates)


def check_refused(case: Case, value: Any) -> None:
    """``case.call(value)`` raises ModelError (or TypeError) naming the parameter and the value."""
    if any(value is ok or (type(value) is type(ok) and value == ok) for ok in case.valid):
        return
    started = time.process_time()      # CPU time: a refusal runs no simulation first (wall time depends on load)
    try:
        result = case.call(value)
    except ctmm.ModelError as exc:
        error: Exception = exc
    except TypeError as exc:  # Python's convention for a wrong type: accepted if the message is clear
        error = exc
    except Exception as exc:  # noqa: BLE001 - the point of the test
        pytest.fail(f"{case!r} with {value!r}: internal error {type(exc).__name__}: {exc}")
    else:
        pytest.fail(f"{case!r} accepted {value!r} silently (returned {type(result).__name__})")
    message = str(error)
    assert case.parameter.split()[0] in message, f"{case!r}: message does not name the parameter: {message}"
    assert _mentions(message, value), f"{case!r}: message does not show the value {value!r}: {message}"
    spent = time.process_time() - started
    assert spent < 5.0, f"{case!r} took {spent:.1f} s of CPU to refuse {value!r}"


@settings(max_examples=400, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_bad_input_is_refused_clearly(data):
    """Random (case, bad value) pairs: a clear ModelError, never silence or an internal error."""
    case = data.draw(st.sampled_from(CASES), label="case")
    value = data.draw(BAD[case.kind], label="value")
    check_refused(case, value)


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c.api}-{c.parameter}-{c.kind}")
def test_every_case_refuses_its_first_examples(case):
    """Every case once with the canonical bad values of its kind (so no case depends on the draw)."""
    canonical = {"real": [None, "abc", math.nan, True], "positive": [0.0, -1.0, math.inf, "abc"],
                 "nonnegative": [-1.0, math.nan, None], "integer": [0, True, 1.5],
                 "system": [None, "c", [Fixed("w"), Mass("m", 1.0), Free("e")]],
                 "names": [None, [1.0], []], "mapping": [[("m", 1.0)], {"m": math.nan}],
                 "frequencies": [[], [-1.0], [math.nan], "a", [[1.0, 2.0]]], "frequency": [[1.0, 2.0], -1.0, math.inf],
                 "complex": [math.nan, "a", complex(0.0, math.inf)], "flag": [1, "yes"],
                 "callable": [1.0, "f"], "option": ["nope", [], None], "name": ["", "a.b", None],
                 "text": ["", None, 1.0], "numbers": [[], "a", [math.nan]],
                 "loops": [None, [3], "L"], "controllers": [[3], None, 3],
                 "elements": [None, 3.0, "abc"], "coordinates": [[0.0, 0.0], [], [math.nan]],
                 "time_step": [1e-300], "path": [None, 3.0, ""]}[case.kind]
    for value in canonical:
        check_refused(case, value)
