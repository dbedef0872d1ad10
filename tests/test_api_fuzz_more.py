"""More bad inputs of the public API (options merged with issue 11) and third-party FMUs as controllers.

Part 1 extends :mod:`test_api_fuzz` (same :class:`Case` and :func:`check_refused` rule: a
``ModelError`` or ``TypeError`` naming the parameter and the value) to the options the first fuzz
did not reach: ``ctmm.simulate`` ``references``/``controllers``/``stability_check``/
``divergence_bound``, zero-step runs, ``to_dataframe``, the ``plot`` methods of results, beam outputs and
laws of :mod:`ctmm.flexible`, the manipulator's ``seed_manipulator``, result files (unwritable paths, files whose
arrays disagree), ``parallel_map``, the scheme limits of :mod:`ctmm.guard`, loop weights of
``unstable_root_count``, ``build_fmu`` output folders and the CLI's duplicate names.

Part 2 uses the Modelica Reference-FMUs (https://github.com/modelica/Reference-FMUs, BSD-2) as
controllers.  They are not shipped with ctmm: build them (``cmake -DFMI_VERSION=2`` and ``=3``) and
point ``CTMM_REFERENCE_FMUS`` to a folder holding ``fmi2/*.fmu`` and ``fmi3/*.fmu``; without it
these tests are skipped.  Independent references: the laws the FMUs document (Dahlquist
``x' = -k x`` in closed form and its forward-Euler co-simulation ``(1 - k h)^n``; Van der Pol by
scipy's ``solve_ivp``; Stair's counter ``1 + floor(t)``; the bouncing ball's parabolas and
restitution) and the exact zero-order-hold discretisation of the plant (matrix exponential of the
augmented system, Franklin, Powell & Workman, *Digital Control of Dynamic Systems*, sec. 4.3.3).
"""
from __future__ import annotations

import gc
import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg

import ctmm
from ctmm import guard, results, stability
from ctmm.control import FMUController, build_fmu
from ctmm.control.static_gain import StaticGainController
from ctmm.elements import Fixed, Free, Mass, Spring
from ctmm.executors import parallel_map

from test_api_fuzz import Case, Opaque, chain, check_refused, controlled, frf, pendulum, sim_result


def _square(x: float) -> float:
    return x * x


# --------------------------------------------------------------------------------------------
# part 1: bad inputs
# --------------------------------------------------------------------------------------------
MORE_CASES: list[tuple[Case, list]] = [
    (Case("ctmm.simulate", "references", "references",
          lambda v: ctmm.simulate(controlled(), 0.02, 0.01, references=v)),
     [3, "L", [("L", 1.0)], True, Opaque(), {1: 1.0}, {"nope": 1.0}, {"L": math.nan}, {"L": "a"}]),
    (Case("ctmm.simulate", "references", "references (plain chain)",
          lambda v: ctmm.simulate(chain(), 0.02, 0.01, references=v)), [3, "L", [("L", 1.0)], Opaque()]),
    (Case("ctmm.simulate", "controllers", "falsy non-lists",
          lambda v: ctmm.simulate(chain(), 0.02, 0.01, controllers=v)), [0, "", None, False, 3, [3]]),
    (Case("ctmm.simulate", "stability_check", "option",
          lambda v: ctmm.simulate(controlled(), 0.02, 0.01, stability_check=v)), ["nope", "WARN", 1, True]),
    (Case("ctmm.simulate", "divergence_bound", "positive",
          lambda v: ctmm.simulate(controlled(), 0.02, 0.01, divergence_bound=v)), [0.0, -1.0, math.nan, "1", True]),
    (Case("ctmm.simulate", "coupling", "option",
          lambda v: ctmm.simulate(controlled(), 0.02, 0.01, coupling=v)), ["nope", None, 1]),
    (Case("ctmm.simulate", "t_final", "zero steps", lambda v: ctmm.simulate(chain(), v, 0.01)), [1e-300, 1e-12]),
    (Case("ctmm.simulate", "t_final", "zero steps (controlled)",
          lambda v: ctmm.simulate(controlled(), v, 0.01)), [1e-300, 1e-12]),
    (Case("SimulationResult.to_dataframe", "units_in_names", "flag",
          lambda v: sim_result().to_dataframe(units_in_names=v)), [1, "yes", None, Opaque()]),
    (Case("SimulationResult.to_dataframe", "names", "names",
          lambda v: sim_result().to_dataframe(v)), ["m.x", {"m.x": 1}, 3]),
    (Case("SimulationResult.plot", "ax", "axes", lambda v: sim_result().plot("m.x", ax=v)), [3, "ax", Opaque()]),
    (Case("SimulationResult.plot", "names", "none given", lambda v: sim_result().plot(*v)), [()]),
    (Case("FrequencyResponse.plot", "ax", "axes", lambda v: frf().plot(ax=v)), [3, "ax", Opaque()]),
    (Case("FrequencyResponse.plot", "output", "names", lambda v: frf().plot(output=v)), ["", "nope", 3]),
    (Case("ModeShapes.plot", "component", "names",
          lambda v: ctmm.mode_shapes(chain(), n_modes=1).plot(component=v)), ["nope", 3, Opaque()]),
    (Case("ModeShapes.plot", "modes", "indices",
          lambda v: ctmm.mode_shapes(chain(), n_modes=1).plot(modes=v)), ["ab", [5], [-1], [1.5], 3]),
    (Case("ctmm.flexible.tip_deflection", "beam", "names",
          lambda v: __import__("ctmm.flexible").flexible.tip_deflection(pendulum(), [0.0], v)),
     ["l", "nope", None, 3]),
    (Case("ctmm.flexible.axial_tip_displacement", "beam", "names",
          lambda v: __import__("ctmm.flexible").flexible.axial_tip_displacement(pendulum(), [0.0], v)), ["l"]),
    (Case("ctmm.flexible.mape", "y", "numbers", lambda v: __import__("ctmm.flexible").flexible.mape(v, [1.0])),
     [None, "a", [math.nan], [], [1.0, 2.0]]),
    (Case("ctmm.flexible.mape", "floor", "fraction",
          lambda v: __import__("ctmm.flexible").flexible.mape([1.0], [1.0], floor=v)), [0.0, -1.0, math.nan, 2.0]),
    (Case("ctmm.flexible.spinup_law", "ramp_time", "positive",
          lambda v: __import__("ctmm.flexible").flexible.spinup_law(6.0, v)), [0.0, -1.0, math.nan, "a"]),
    (Case("ctmm.flexible.spinup_law", "final_rate", "real",
          lambda v: __import__("ctmm.flexible").flexible.spinup_law(v)), [math.nan, "a", None]),
    (Case("ctmm.manipulator.seed_manipulator", "n_patches", "0..3",
          lambda v: __import__("ctmm.manipulator").manipulator.seed_manipulator(n_patches=v)), [True, 4, -1, 1.5]),
    (Case("ctmm.executors.parallel_map", "progress", "flag",
          lambda v: parallel_map(_square, [1.0], progress=v)), [1, "yes", math.nan, Opaque()]),
    (Case("ctmm.executors.parallel_map", "description", "text",
          lambda v: parallel_map(_square, [1.0], description=v)), [None, 1.0, Opaque()]),
    (Case("ctmm.executors.parallel_map", "function", "callable",
          lambda v: parallel_map(v, [1.0])), [None, 1.0, "f"]),
    (Case("ctmm.executors.parallel_map", "items", "iterable",
          lambda v: parallel_map(_square, v)), [None, 1.0, "ab"]),
    (Case("ctmm.guard.newmark_limit", "beta", "real", lambda v: guard.newmark_limit(v, 0.5)),
     [math.nan, "a", None, -1.0]),
    (Case("ctmm.guard.newmark_limit", "gamma", "real", lambda v: guard.newmark_limit(0.25, v)), [math.nan, "a"]),
    (Case("ctmm.guard.wilson_limit", "theta", "positive", lambda v: guard.wilson_limit(v)),
     [math.nan, 0.0, -1.0, "a", None]),
    (Case("ctmm.guard.wilson_amplification", "omega_h", "nonnegative",
          lambda v: guard.wilson_amplification(1.4, v)), [math.nan, -1.0, "a"]),
    (Case("ctmm.guard.check_step", "dt", "positive",
          lambda v: guard.check_step("Newmark", 10.0, v, 1.0, policy="error")), [-0.01, 0.0, math.nan, "a"]),
    (Case("ctmm.guard.check_step", "omega_max", "nonnegative",
          lambda v: guard.check_step("Newmark", v, 0.01, 1.0, policy="error")), [math.nan, -1.0, "a"]),
    (Case("ctmm.stability.unstable_root_count", "weights", "numbers",
          lambda v: stability.unstable_root_count(controlled(), weights=v)),
     ["a", [math.nan], [1.0, 2.0, 3.0], Opaque(), [[1.0, 2.0]]]),
    (Case("ctmm.control.StaticGainController", "limits", "positive numbers",
          lambda v: StaticGainController(["m.x"], ["m.force"], [[1.0]], limits=v)),
     [["a"], {"m.force": 1.0}, [1 + 2j], Opaque(), [0.0], "5"]),
    (Case("ctmm.control.build_fmu", "output_dir", "folder path",
          lambda v: build_fmu(Path(__file__).parents[1] / "controllers" / "fmu" / "pd_controller", v, compiler="gcc")),
     [3, ["out"], Opaque()]),
]


@pytest.mark.parametrize("case, values", MORE_CASES, ids=lambda c: f"{c.api}-{c.parameter}-{c.kind}"
                         if isinstance(c, Case) else "")
def test_more_bad_inputs_are_refused_clearly(case, values):
    for value in values:
        check_refused(case, value)


def test_valid_neighbours_of_the_refused_values_still_run():
    """The fixes refuse only what is wrong: one step, infinite bound, empty references, a lambda on threads."""
    assert len(ctmm.simulate(chain(), 0.01, 0.01).time) == 2
    ctmm.simulate(controlled(), 0.02, 0.01, divergence_bound=math.inf, references={})
    ctmm.simulate(chain(), 0.02, 0.01, controllers=[], references={})
    assert parallel_map(lambda x: x + 1, [1, 2], executor="threads") == [2, 3]
    assert guard.newmark_limit(0.25, 0.5) == math.inf and guard.check_step("N", math.inf, 0.01, math.inf) is None
    assert list(stability.unstable_root_count(controlled(), weights=[1.0])) == [0]
    gain = StaticGainController(["m.x"], ["m.force"], [[2.0]], limits=[1.5])
    u, clipped = gain.step(0.0, np.array([1.0]), 0)
    assert list(u) == [1.5] and clipped == 1                    # clip(2 * 1.0, +-1.5), one clipped sample
    with pytest.raises(ctmm.SimulationError, match=r"y must be 1 real numbers ordered like \('m.x',\), got "
                                                   r"array\(\[1., 2.\]\) at t = 0.0 s"):
        gain.step(0.0, np.array([1.0, 2.0]), 0)                 # was numpy's matmul core-dimension ValueError


def test_a_lambda_for_worker_processes_is_refused_before_any_pool_starts():
    with pytest.raises(ctmm.ModelError, match=r"function <function .*<lambda>.* cannot be sent to worker processes"):
        parallel_map(lambda x: x, [1, 2], executor="processes")


@pytest.mark.parametrize("path", ["/proc/ctmm-result.h5", "bad\0name.h5"])
def test_unwritable_result_paths_are_result_file_errors(path):
    """A folder where no file can be created, or a NUL in the name: ResultFileError, no temp file left."""
    sim = sim_result()
    frf = ctmm.frequency_response(chain(), [1.0], input="m.force", output="m.x")
    for result in (sim, frf):
        with pytest.raises(results.result_files.ResultFileError, match=r"path .* cannot be written"):
            result.save(path)


def test_result_file_whose_arrays_disagree_with_its_time_grid_is_refused(tmp_path):
    h5py = pytest.importorskip("h5py")
    sim = sim_result()
    good = sim.save(tmp_path / "good.h5")
    assert np.array_equal(results.load(good)["m.x"], sim["m.x"])
    for name in ("time", "states", "signals/m.x"):
        damaged = tmp_path / f"damaged_{name.replace('/', '_')}.h5"
        damaged.write_bytes(good.read_bytes())
        with h5py.File(damaged, "a") as handle:
            values = handle[name][...]
            del handle[name]
            handle[name] = values[:1]        # one row only: the file no longer matches itself
        with pytest.raises(results.result_files.ResultFileError, match=r"is inconsistent"):
            results.load(damaged)
    frf = ctmm.frequency_response(chain(), [1.0, 2.0], input="m.force", output="m.x").save(tmp_path / "frf.h5")
    with h5py.File(frf, "a") as handle:
        values = handle["response"][...]
        attributes = dict(handle["response"].attrs)
        del handle["response"]
        handle["response"] = values[:, :, :1]
        handle["response"].attrs.update(attributes)
    with pytest.raises(results.result_files.ResultFileError, match=r"response has shape \(1, 1, 1\)"):
        results.load(frf)


def test_build_fmu_output_dir_that_is_a_file(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(ctmm.ModelError, match=r"output_dir .*file.* cannot be used as a folder"):
        build_fmu(Path(__file__).parents[1] / "controllers" / "fmu" / "pd_controller", blocker, compiler="gcc")


def test_cli_runs_a_name_given_twice_once(tmp_path, monkeypatch, capsys):
    from ctmm import cli, scenario

    calls = []
    monkeypatch.setattr(scenario, "run_scenario", lambda name, output, quick: calls.append(name) or
                        {"passed": True, "accuracy": []})
    assert cli.main(["run", "table7_1", "table7_1", "--output", str(tmp_path)]) == 0
    assert calls == ["table7_1"]


# --------------------------------------------------------------------------------------------
# part 2: Reference-FMUs as controllers
# --------------------------------------------------------------------------------------------
REFERENCE = os.environ.get("CTMM_REFERENCE_FMUS")
needs_reference = pytest.mark.skipif(not REFERENCE, reason="set CTMM_REFERENCE_FMUS to a folder with fmi2/ and "
                                     "fmi3/ builds of modelica/Reference-FMUs")
VERSIONS = [pytest.param(2, id="fmi2"), pytest.param(3, id="fmi3")]
STIFFNESS, MASS = 10.0, 1.0


def fmu(version: int, model: str) -> Path:
    path = Path(REFERENCE) / f"fmi{version}" / f"{model}.fmu"
    assert path.is_file(), f"{path} missing from CTMM_REFERENCE_FMUS"
    return path


def plant() -> ctmm.Chain:
    return ctmm.Chain("c", [Fixed("w"), Spring("k", STIFFNESS), Mass("m", MASS), Free("e")])


def zoh_response(x0: float, h: float, n: int, force) -> np.ndarray:
    """Exact sampled-data response: m x'' = -k x + F_j held on [t_j, t_j + h), F_j = force(j, x_j)."""
    a = np.array([[0.0, 1.0], [-STIFFNESS / MASS, 0.0]])
    b = np.array([[0.0], [1.0 / MASS]])
    augmented = scipy.linalg.expm(np.block([[a, b], [np.zeros((1, 3))]]) * h)
    z, xs = np.array([x0, 0.0]), [x0]
    for j in range(n):
        z = augmented[:2, :2] @ z + augmented[:2, 2] * force(j, z[0])
        xs.append(z[0])
    return np.array(xs)


@needs_reference
@pytest.mark.parametrize("version", VERSIONS)
def test_feedthrough_as_a_proportional_controller(version):
    """Feedthrough (u = y, a parameter set) closes x -> force: the run converges to the exact ZOH loop."""
    h = 0.01
    with pytest.warns(UserWarning, match="fixedInternalStepSize") if version == 3 else _no_warning():
        controller = FMUController(fmu(version, "Feedthrough"), inputs={"Float64_continuous_input": "m.x"},
                                   outputs={"Float64_continuous_output": "m.force"}, sample_time=h,
                                   parameters={"Float64_fixed_parameter": 3.0, "Int32_input": 7})
    assert controller.parameters["Float64_fixed_parameter"] == 3.0 and controller.direct_feedthrough
    exact = zoh_response(0.1, h, 50, lambda j, x: x)
    errors = []
    for dt in (h, h / 4):
        run = ctmm.simulate(plant(), 0.5, dt, x0={"m": 0.1}, controllers=[controller])
        samples = run["m.force@samples"]
        np.testing.assert_array_equal(samples[:, 1], run["m.x"][::round(h / dt)][:len(samples)])  # u = y
        errors.append(np.max(np.abs(run["m.x"][::round(h / dt)] - exact)))
    assert errors[0] < 1e-3 * 0.1               # 0.1 % of the amplitude at dt = h
    assert errors[1] < errors[0] / 3.0          # converging to the exact sampled-data loop


@needs_reference
def test_feedthrough_loop_converges_at_second_order_in_dt():
    h = 0.01
    controller = FMUController(fmu(2, "Feedthrough"), inputs={"Float64_continuous_input": "m.x"},
                               outputs={"Float64_continuous_output": "m.force"}, sample_time=h)
    exact = zoh_response(0.1, h, 50, lambda j, x: x)
    errors = [np.max(np.abs(ctmm.simulate(plant(), 0.5, dt, x0={"m": 0.1}, controllers=[controller])["m.x"]
                            [::round(h / dt)] - exact)) for dt in (h / 2, h / 8)]
    assert errors[1] < errors[0] / 10.0         # order 2: 16x smaller for a 4x smaller step


@needs_reference
@pytest.mark.parametrize("version", VERSIONS)
def test_dahlquist_drives_the_plant_in_both_interfaces(version):
    """x' = -k x: co-simulation samples are the FMU's forward Euler (1 - k h)^n; model exchange is ctmm's
    RK4 with one step per sample (solver_step defaults to the FMU's stepSize 0.1 s), whose amplification
    on x' = z x / h is the Taylor polynomial of e^z to degree 4."""
    k, h = 2.0, 0.1
    n = np.arange(10)                           # samples at 0, h, ..., t_final - h
    z = -k * h
    rk4 = (1.0 + z + z ** 2 / 2.0 + z ** 3 / 6.0 + z ** 4 / 24.0) ** n
    assert np.max(np.abs(rk4 - np.exp(z * n))) < 1e-5    # and RK4 is close to the exact solution
    for interface, expected, tolerance in (("co-simulation", (1.0 - k * h) ** n, 1e-14),
                                           ("model exchange", rk4, 1e-14)):
        controller = FMUController(fmu(version, "Dahlquist"), inputs={}, outputs={"x": "m.force"},
                                   parameters={"k": k}, sample_time=h, interface=interface)
        run = ctmm.simulate(plant(), 1.0, 0.01, controllers=[controller])
        samples = run["m.force@samples"]
        assert samples.shape == (10, 2)
        np.testing.assert_allclose(samples[:, 0], h * n, atol=1e-12)
        np.testing.assert_allclose(samples[:, 1], expected, rtol=0, atol=tolerance)
        exact = zoh_response(0.0, h, 10, lambda j, x: samples[j, 1])
        finer = ctmm.simulate(plant(), 1.0, 0.0025, controllers=[controller])
        errors = [np.max(np.abs(r["m.x"][::round(h / dt)] - exact)) for r, dt in ((run, 0.01), (finer, 0.0025))]
        assert errors[0] < 0.015 * np.max(np.abs(exact))
        assert errors[1] < errors[0] / 10.0           # second order: the acceleration restarts at each sample


@needs_reference
@pytest.mark.parametrize("version", VERSIONS)
def test_van_der_pol_as_a_model_exchange_block(version):
    mu, h = 0.5, 0.01
    controller = FMUController(fmu(version, "VanDerPol"), inputs={}, outputs={"x0": "m.force"},
                               parameters={"mu": mu}, sample_time=h, interface="model exchange")
    samples = ctmm.simulate(plant(), 1.0, h, controllers=[controller])["m.force@samples"]
    solution = scipy.integrate.solve_ivp(lambda t, x: [x[1], mu * (1.0 - x[0] ** 2) * x[1] - x[0]], (0.0, 1.0),
                                         [2.0, 0.0], t_eval=samples[:, 0], rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(samples[:, 1], solution.y[0], rtol=0, atol=1e-8)


@needs_reference
@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("interface", ["co-simulation", "model exchange"])
def test_stair_time_events(version, interface):
    controller = FMUController(fmu(version, "Stair"), inputs={}, outputs={"counter": "m.force"}, sample_time=0.2,
                               interface=interface)
    samples = ctmm.simulate(plant(), 3.0, 0.01, controllers=[controller])["m.force@samples"]
    np.testing.assert_array_equal(samples[:, 1], 1.0 + np.floor(np.round(samples[:, 0], 9)))


@needs_reference
@pytest.mark.parametrize("version", VERSIONS)
def test_bouncing_ball_state_event_in_model_exchange(version):
    """h(t) = 1 - g t^2 / 2 until the impact at sqrt(2/g), then v = e sqrt(2 g) upwards."""
    g, e = 9.81, 0.7
    controller = FMUController(fmu(version, "BouncingBall"), inputs={}, outputs={"h": "m.force"}, sample_time=0.01,
                               interface="model exchange", parameters={"e": e}, solver_step=1e-3)
    samples = ctmm.simulate(plant(), 0.8, 0.01, controllers=[controller])["m.force@samples"]
    impact = math.sqrt(2.0 / g)
    after = samples[:, 0] - impact
    expected = np.where(after < 0, 1.0 - g * samples[:, 0] ** 2 / 2.0,
                        e * math.sqrt(2.0 * g) * after - g * after ** 2 / 2.0)
    np.testing.assert_allclose(samples[:, 1], expected, rtol=0, atol=1e-6)
    with pytest.raises(ctmm.ModelError, match=r"parameters\['e'\] = 2.0 is outside the range .*\[0.5, 1\]"):
        FMUController(fmu(version, "BouncingBall"), inputs={}, outputs={"h": "m.force"}, parameters={"e": 2.0})


@needs_reference
def test_feedthrough_takes_64_bit_integer_start_values_exactly():
    """Feedthrough (FMI 3) copies UInt64_input / Int64_input to its outputs: the FMU's own integer outputs, read
    through fmpy, are the start values given, bit for bit (2**64 - 1 was refused as 'must be an integer')."""
    values = {"UInt64_input": 2 ** 64 - 1, "Int64_input": -(2 ** 62) - 1}
    with pytest.warns(UserWarning, match="fixedInternalStepSize"):
        controller = FMUController(fmu(3, "Feedthrough"), inputs={}, outputs={"Float64_continuous_output": "m.force"},
                                   parameters=values, sample_time=0.05)
    assert controller.parameters == values
    references = {v.name: v.valueReference for v in controller.model_description.modelVariables}
    with controller.init(0.0) as state:
        controller.step(0.0, np.zeros(0), state)
        assert state.slave.getUInt64([references["UInt64_output"]]) == [2 ** 64 - 1]
        assert state.slave.getInt64([references["Int64_output"]]) == [-(2 ** 62) - 1]


@needs_reference
def test_feedthrough_refuses_a_signal_beyond_the_int64_range_instead_of_wrapping_it():
    """A measured 2**63 for an Int64 input reached the FMU as -2**63 (its output flipped sign)."""
    with pytest.warns(UserWarning, match="fixedInternalStepSize"):
        controller = FMUController(fmu(3, "Feedthrough"), inputs={"Int64_input": "m.x"},
                                   outputs={"Int64_output": "m.force"}, sample_time=0.05)
    with controller.init(0.0) as state:
        assert controller.step(0.0, np.array([2.0 ** 62]), state).outputs[0] == 2.0 ** 62
        with pytest.raises(ctmm.SimulationError, match=r"'Int64_input' = 9.223372036854776e\+18 at t = 0.05 "
                                                       r"cannot be converted to the FMU type Int64"):
            controller.step(0.05, np.array([2.0 ** 63]), state)


@needs_reference
def test_unsupported_reference_fmus_are_refused_clearly_and_leave_the_process_clean():
    before_temp = set(os.listdir(tempfile.gettempdir()))
    before_cwd = os.getcwd()
    with pytest.raises(ctmm.ModelError, match=r"scheduled execution is not supported"):
        FMUController(fmu(3, "Clocks"), inputs={}, outputs={"result2": "m.force"}, sample_time=0.1)
    with pytest.raises(ctmm.ModelError, match=r"'y' is an array"):
        FMUController(fmu(3, "StateSpace"), inputs={}, outputs={"y": "m.force"}, sample_time=0.1)
    with pytest.raises(ctmm.ModelError, match=r"Enumeration_input.* = 7 is not an item of the enumeration"):
        FMUController(fmu(2, "Feedthrough"), inputs={}, outputs={"Float64_continuous_output": "m.force"},
                      parameters={"Enumeration_input": 7}, sample_time=0.1)
    with pytest.raises(ctmm.ModelError, match=r"solver_step=1e-300 s gives 1e\+298 RK4 steps"):
        FMUController(fmu(2, "Dahlquist"), inputs={}, outputs={"x": "m.force"}, sample_time=0.01,
                      interface="model exchange", solver_step=1e-300)
    controller = FMUController(fmu(2, "Dahlquist"), inputs={}, outputs={"x": "zz.force"}, sample_time=0.1)
    with pytest.raises(ctmm.ModelError, match=r"zz"):
        ctmm.simulate(plant(), 0.2, 0.01, controllers=[controller])
    del controller
    gc.collect()
    assert os.getcwd() == before_cwd
    assert not {n for n in set(os.listdir(tempfile.gettempdir())) - before_temp if n.startswith("ctmm-fmu-")}
    maps = Path("/proc/self/maps").read_text() if Path("/proc/self/maps").exists() else ""
    assert "Clocks.so" not in maps and "StateSpace.so" not in maps


class _no_warning:
    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        return False
