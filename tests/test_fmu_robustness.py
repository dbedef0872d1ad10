"""FMU loading that cannot corrupt the process, typed FMI 3 interfaces, failures, build_fmu inputs.

All FMUs are built from the project's own C sources (controllers/fmu) in a session folder and then
damaged or edited in tmp folders.  Independent references: the expected typed outputs are
computed here with numpy's IEEE float32 / integer arithmetic from the law written in
controllers/fmu/typed_io_fmi3/modelDescription.xml; process state is read from the operating
system (current directory, /proc/self/maps, the temp folder), not from ctmm.
"""
from __future__ import annotations

import gc
import math
import os
import re
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest

from ctmm.control.fmu import FMUController, build_fmu
from ctmm.errors import ModelError, SimulationError

from _controllers_import import load_controllers

controllers = load_controllers()

PD_IO = dict(inputs={"y": "m6.x", "ydot": "m6.v"}, outputs={"u": "m2.force"})
TYPED_IN = {"position": "m6.x", "count_in": "c.n", "enable": "c.on", "level": "c.level"}
TYPED_OUT = {"command": "m2.force", "count_out": "c.count", "active": "c.active", "level_out": "c.level_out"}


@pytest.fixture(scope="session")
def own_fmus(tmp_path_factory) -> dict[str, Path]:
    assert shutil.which("gcc"), "gcc is required to build the test FMUs"
    folder = tmp_path_factory.mktemp("robust_fmus")
    return {name: build_fmu(controllers.fmu_source(name), folder / name, compiler="gcc")
            for name in ("pd_controller", "pd_controller_fmi3", "typed_io_fmi3", "lag_filter_me")}


def rewrite(source: Path, target: Path, edit) -> Path:
    """Copy an FMU archive, passing each member through ``edit(name, data) -> data or None``."""
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(target, "w") as zout:
        for item in zin.infolist():
            data = edit(item.filename, zin.read(item.filename))
            if data is not None:
                zout.writestr(item, data)
    return target


def edit_xml(replace: str, by: str):
    def edit(name: str, data: bytes):
        if name == "modelDescription.xml":
            text = data.decode()
            assert replace in text
            return text.replace(replace, by).encode()
        return data
    return edit


def mapped(fragment: str) -> bool:
    """Whether a file whose path contains ``fragment`` is mapped into this process (Linux)."""
    return fragment in Path("/proc/self/maps").read_text()


# ----------------------------------------------------------------------- loading without side effects

def _damaged(kind: str, base: Path, tmp: Path) -> Path:
    target = tmp / f"{kind}.fmu"
    if kind == "truncated_archive":
        target.write_bytes(base.read_bytes()[:2000])
    elif kind == "not_a_zip":
        target.write_bytes(b"this is not an FMU\n" * 10)
    elif kind == "truncated_binary":
        rewrite(base, target, lambda n, d: d[: len(d) // 3] if n.endswith(".so") else d)
    elif kind == "truncated_segment":  # no section table to give it away: a segment is cut
        rewrite(base, target, lambda n, d: (d[:0x28] + bytes(8) + d[0x30:])[: int(len(d) * 0.6)]
                if n.endswith(".so") else d)
    elif kind == "garbage_binary":
        rewrite(base, target, lambda n, d: b"\x7fELF\x02\x01\x01" + b"\0" * 57 + b"x" * 100 if n.endswith(".so") else d)
    elif kind == "missing_binary":
        rewrite(base, target, lambda n, d: None if n.endswith(".so") else d)
    elif kind == "no_model_description":
        rewrite(base, target, lambda n, d: None if n == "modelDescription.xml" else d)
    elif kind == "broken_xml":
        rewrite(base, target, lambda n, d: d[:300] if n == "modelDescription.xml" else d)
    elif kind == "schema_violation":
        rewrite(base, target, edit_xml('causality="input"', 'causality="sideways"'))
    elif kind == "unsafe_member":
        rewrite(base, target, lambda n, d: d)
        with zipfile.ZipFile(target, "a") as archive:
            archive.writestr("../escape.txt", b"x")
    return target


DAMAGE = {
    "truncated_archive": r"not a valid FMU: not a ZIP archive or truncated",
    "not_a_zip": r"not a valid FMU: not a ZIP archive",
    "truncated_binary": r"library 'binaries/linux64/pd_controller\.so' is truncated or corrupt: .* past the end of the file",
    "truncated_segment": r"library 'binaries/linux64/pd_controller\.so' is truncated or corrupt: loadable segment",
    "garbage_binary": r"cannot load the shared library 'binaries/linux64/pd_controller\.so': .*ELF",
    "missing_binary": r"no binary for this platform: expected binaries/linux64/pd_controller\.so.*ships C sources.*"
                      r"build_fmu",
    "no_model_description": r"has no modelDescription\.xml",
    "broken_xml": r"cannot read modelDescription\.xml",
    "schema_violation": r"cannot read the model description of FMU .*sideways.*validate=False accepts",
    "unsafe_member": r"unsafe member name '\.\./escape\.txt'",
}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/maps and ELF binaries")
@pytest.mark.parametrize("kind", list(DAMAGE))
def test_failed_load_leaves_the_process_as_it_was(own_fmus, tmp_path, kind, monkeypatch):
    base = own_fmus["pd_controller"]
    damaged = _damaged(kind, base, tmp_path)
    scratch = tmp_path / "scratch"  # a temp folder of our own: other processes share /tmp
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    cwd = os.getcwd()
    with pytest.raises(ModelError, match=DAMAGE[kind]) as info:
        FMUController(damaged, **PD_IO, sample_time=0.01)
    assert str(damaged) in str(info.value)                      # names the file
    gc.collect()
    assert os.getcwd() == cwd                                   # working directory untouched
    assert list(scratch.iterdir()) == []                        # no temporary folder left behind
    assert not mapped(str(scratch))                             # no extracted library stays loaded
    # and the process still loads and runs FMUs
    good = FMUController(base, **PD_IO, parameters={"kp": 2.0}, sample_time=0.01)
    with good.init(0.0) as state:
        u, _ = good.step(0.0, np.array([0.25, 0.0]), state)
    assert u[0] == -0.5


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/maps")
def test_close_unloads_the_library_and_failed_instantiation_too(own_fmus, tmp_path):
    controller = FMUController(own_fmus["pd_controller_fmi3"], **PD_IO, sample_time=0.01)
    folder = controller.unzip_dir.name
    state = controller.init(0.0)
    assert mapped(folder)
    state.close()
    assert not mapped(folder)
    wrong_token = rewrite(own_fmus["pd_controller_fmi3"], tmp_path / "token.fmu",
                          edit_xml('instantiationToken="{ce437997', 'instantiationToken="{00000000'))
    bad = FMUController(wrong_token, **PD_IO, sample_time=0.01)
    cwd = os.getcwd()
    with pytest.raises(ModelError, match=r"fmi3Instantiate failed.*FMU log: wrong instantiation token"):
        bad.init(0.0)
    assert os.getcwd() == cwd and not mapped(bad.unzip_dir.name)
    folders = [controller.unzip_dir.name, bad.unzip_dir.name]
    del controller, bad, state
    gc.collect()
    assert not any(mapped(name) for name in folders)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/maps")
@pytest.mark.parametrize("name", ["pd_controller", "pd_controller_fmi3", "lag_filter_me"])
def test_closing_one_instance_keeps_the_others_of_the_same_fmu_alive(own_fmus, name):
    io = LAG_IO if name == "lag_filter_me" else PD_IO
    controller = FMUController(own_fmus[name], **io, sample_time=0.1)
    first, second, third = controller.init(0.0), controller.init(0.0), controller.init(0.0)
    y = np.array([0.5] * len(io["inputs"]))
    controller.step(0.0, y, first)
    first.close()
    second.close()
    assert mapped(controller.unzip_dir.name)  # one dlopen reference per live instance
    expected = controller.step(0.0, y, third).outputs
    with controller.init(0.0) as fourth:
        np.testing.assert_array_equal(controller.step(0.0, y, fourth).outputs, expected)
    third.close()
    assert not mapped(controller.unzip_dir.name)


# ----------------------------------------------------------------------- typed FMI 3 interface

def reference_typed(y: np.ndarray, k: int, gain: float, offset: int, invert: bool) -> list[float]:
    """The law of typed_io_fmi3 in numpy: float32 input and command, rounded integers, bool."""
    position = np.float32(y[0])
    enable = y[2] != 0.0
    command = np.float32(np.float64(gain) * np.float64(position)) if enable else np.float32(0.0)
    if invert and enable:
        command = -command
    count = int(np.rint(y[1])) + offset + k
    return [float(command), float(count), float(enable), float(np.uint8(np.rint(y[3])))]


def test_typed_inputs_outputs_and_parameters_match_numpy(own_fmus):
    gain, offset = 1.7, -3
    ctrl = FMUController(own_fmus["typed_io_fmi3"], inputs=TYPED_IN, outputs=TYPED_OUT,
                         parameters={"gain": gain, "offset": offset, "invert": True}, sample_time=0.05)
    rng = np.random.default_rng(2)
    ys = np.column_stack([rng.normal(0.0, 10.0, 30), rng.uniform(-50, 50, 30), rng.integers(0, 2, 30),
                          rng.uniform(0, 255.4, 30)])
    ys[:3, 1] = [2.5, 3.5, -2.5]  # ties go to the even integer
    with ctrl.init(0.0) as state:
        got = [ctrl.step(k * 0.05, ys[k], state).outputs for k in range(len(ys))]
    expected = [reference_typed(ys[k], k, gain, offset, True) for k in range(len(ys))]
    np.testing.assert_array_equal(np.array(got), np.array(expected))
    assert np.array(got).dtype == np.float64
    assert [row[1] for row in got[:3]] == [2 + offset, 4 + offset + 1, -2 + offset + 2]


@pytest.mark.parametrize("column, value, message", [
    (1, math.nan, r"input 'count_in' = .*nan.* at t = 0\.1 cannot be converted to the FMU type Int32; "
                  r"allowed: finite values that round to \[-2147483648, 2147483647\]"),
    (3, 255.6, r"input 'level' = .*255\.6.* cannot be converted to the FMU type UInt8; allowed: .*\[0, 255\]"),
    (3, -0.6, r"input 'level' .* UInt8"),
    (2, math.inf, r"input 'enable' = .*inf.* Boolean; allowed: finite values \(0 is false"),
    (0, 1e39, r"input 'position' = .*1e\+39.* Float32; allowed: finite values with \|y\| <= 3\.4e38"),
])
def test_unconvertible_input_is_a_simulation_error_naming_variable_and_time(own_fmus, column, value, message):
    ctrl = FMUController(own_fmus["typed_io_fmi3"], inputs=TYPED_IN, outputs=TYPED_OUT, sample_time=0.05)
    y = np.array([0.5, 1.0, 1.0, 3.0])
    with ctrl.init(0.0) as state:
        ctrl.step(0.0, y, state)
        ctrl.step(0.05, y, state)
        y[column] = value
        with pytest.raises(SimulationError, match=r"FMU 'typed_io_fmi3' .*" + message) as info:
            ctrl.step(0.1, y, state)
        assert info.value.time == pytest.approx(0.1)
        y[column] = 1.0
        assert ctrl.step(0.1, y, state).outputs[1] == 1.0 + 2  # nothing was sent: the FMU is intact


def test_integer_start_values_beyond_2_to_the_53_are_set_exactly():
    """Int64/UInt64 parameters are Python or numpy integers set as they are: 2**64 - 1 and 2**62 + 1 are not
    floats (they were compared with their float rounding and refused as 'must be an integer')."""
    from types import SimpleNamespace

    from ctmm.control.fmu_variables import convert_start_value

    for kind, value in (("UInt64", 2 ** 64 - 1), ("UInt64", np.uint64(2 ** 64 - 1)), ("Int64", 2 ** 62 + 1),
                        ("Int64", np.int64(-2 ** 63))):
        variable = SimpleNamespace(name="n", type=kind, declaredType=None, min=None, max=None)
        converted = convert_start_value(variable, value, 3, "FMU 'x'")
        assert type(converted) is int and converted == int(value)
    variable = SimpleNamespace(name="n", type="Int64", declaredType=None, min=None, max=None)
    with pytest.raises(ModelError, match=r"parameters\['n'\] must be an integer .* got np.float32\(1.5\)"):
        convert_start_value(variable, np.float32(1.5), 3, "FMU 'x'")
    with pytest.raises(ModelError, match=r"parameters\['n'\] = 9223372036854775808 is outside the Int64 range"):
        convert_start_value(variable, 2 ** 63, 3, "FMU 'x'")
    variable = SimpleNamespace(name="f", type="Float64", declaredType=None, min=None, max=None)
    with pytest.raises(ModelError, match=r"parameters\['f'\] = 1000.* is outside the Float64 range"):
        convert_start_value(variable, 10 ** 400, 3, "FMU 'x'")     # an int too large for a float: no OverflowError


def test_64_bit_integer_inputs_at_the_type_limit_are_refused_not_wrapped():
    """float(2**63 - 1) is 2**63: a signal of 2**63 passed the range check of an Int64 input and was cast to
    -2**63 (2**64 to a UInt64 input: 0).  The documented contract: outside the type's range is an error."""
    from types import SimpleNamespace

    from ctmm.control.fmu_variables import ValueChannel, variable_type

    for kind, too_large, largest in (("Int64", 2.0 ** 63, 2.0 ** 63 - 1024), ("UInt64", 2.0 ** 64, 2.0 ** 64 - 2048),
                                     ("Int32", 2.0 ** 31, 2.0 ** 31 - 1)):
        channel = ValueChannel(variable_type(SimpleNamespace(type=kind), 3), [0], [0], ["n"])
        with pytest.raises(SimulationError, match=re.escape(f"input 'n' = {too_large!r} at t = 0.5 cannot be "
                                                            f"converted to the FMU type {kind};")):
            channel.load(np.array([too_large]), 0.5, "FMU 'x'")
        channel.load(np.array([largest]), 0.5, "FMU 'x'")
        assert int(channel.view[0]) == int(largest)
    channel = ValueChannel(variable_type(SimpleNamespace(type="Int64"), 3), [0], [0], ["n"])
    channel.load(np.array([-2.0 ** 63]), 0.5, "FMU 'x'")
    assert int(channel.view[0]) == -2 ** 63


def test_parameter_and_start_value_errors_name_the_variable(own_fmus):
    path = own_fmus["typed_io_fmi3"]
    cases = [
        ({"offset": 1.5}, r"parameters\['offset'\] must be an integer \(the variable has type Int32\), got 1\.5"),
        ({"offset": 2.0 ** 40}, r"parameters\['offset'\] = .* outside the Int32 range"),
        ({"invert": 2}, r"parameters\['invert'\] must be True or False"),
        ({"gain": "high"}, r"parameters\['gain'\] must be a real number, got 'high'"),
        ({"gain": math.inf}, r"parameters\['gain'\] must be finite"),
        ({"weights": [1.0, 2.0, 3.0]}, r"'weights' is an array \(dimensions \[3\]\); FMUController maps and "
                                       r"sets scalar variables only"),
        ({"command": 1.0}, r"'command' \(causality 'output'.*cannot be set; allowed: parameters"),
        ({"time": 1.0}, r"'time' \(causality 'independent'.*cannot be set"),
        ({"position": 1.0}, r"input 'position' is mapped to a ctmm signal in inputs"),
    ]
    for parameters, message in cases:
        with pytest.raises(ModelError, match=message):
            FMUController(path, inputs=TYPED_IN, outputs=TYPED_OUT, parameters=parameters)
    with pytest.raises(ModelError, match=r"unknown FMU parameter variable 'gian'; available: count_in, "
                                         r"discard_at_time, enable, gain, invert, level, offset, position, weights"):
        FMUController(path, inputs={}, outputs=TYPED_OUT, parameters={"gian": 1.0})
    # the start value of an unmapped input is settable and used
    ctrl = FMUController(path, inputs={"position": "m6.x"}, outputs=TYPED_OUT,
                         parameters={"enable": False, "level": 9, "count_in": 4})
    with ctrl.init(0.0) as state:
        u, _ = ctrl.step(0.0, np.array([3.0]), state)
    np.testing.assert_array_equal(u, [0.0, 4.0, 0.0, 9.0])


def test_array_variables_are_refused_at_construction(own_fmus):
    with pytest.raises(ModelError, match=r"FMU 'typed_io_fmi3' .*'history' is an array \(dimensions \[3\]\)"):
        FMUController(own_fmus["typed_io_fmi3"], inputs={}, outputs={"history": "m2.force"})


def test_discard_in_dostep_names_fmu_call_time_and_status(own_fmus):
    ctrl = FMUController(own_fmus["typed_io_fmi3"], inputs=TYPED_IN, outputs=TYPED_OUT,
                         parameters={"discard_at_time": 0.1}, sample_time=0.05)
    state = ctrl.init(0.0)
    y = np.array([0.5, 1.0, 1.0, 3.0])
    ctrl.step(0.0, y, state)
    snapshot = ctrl.snapshot(state)
    ctrl.step(0.05, y, state)
    with pytest.raises(SimulationError, match=r"FMU 'typed_io_fmi3' \(.*typed_io_fmi3\.fmu'\): fmi3DoStep failed at "
                                              r"t = 0\.1 \(status Discard\); FMU log: .*discarded") as info:
        ctrl.step(0.1, y, state)
    assert info.value.time == pytest.approx(0.1) and state.failed_at == pytest.approx(0.1)
    ctrl.restore(state, snapshot)
    assert ctrl.step(0.05, y, state).outputs[1] == 1.0 + 1
    state.close()
    assert state.closed and snapshot.handle is None


def test_default_experiment_step_fixed_internal_step_and_instance_name(own_fmus, tmp_path):
    path = own_fmus["typed_io_fmi3"]
    ctrl = FMUController(path, inputs=TYPED_IN, outputs=TYPED_OUT, instance_name="left wheel")
    assert ctrl.sample_time == 0.05 and ctrl.instance_name == "left wheel" and ctrl.variable_step
    with ctrl.init(0.0) as state:
        assert state.slave.instanceName == "left wheel"
    with pytest.raises(ModelError, match="instance_name must be a non-empty str"):
        FMUController(path, inputs=TYPED_IN, outputs=TYPED_OUT, instance_name="")
    no_step = rewrite(path, tmp_path / "no_step.fmu", edit_xml(' stepSize="0.05"', ""))
    with pytest.raises(ModelError, match=r"sample_time is required \(the FMU declares no DefaultExperiment stepSize\)"):
        FMUController(no_step, inputs=TYPED_IN, outputs=TYPED_OUT)
    fixed = rewrite(path, tmp_path / "fixed.fmu", edit_xml('providesIntermediateUpdate="false"',
                                                           'providesIntermediateUpdate="false" fixedInternalStepSize="0.01"'))
    with pytest.warns(UserWarning, match=r"sample_time = 0\.015 s is not a whole multiple of the FMU's "
                                         r"fixedInternalStepSize 0\.01 s.*may lag"):
        FMUController(fixed, inputs=TYPED_IN, outputs=TYPED_OUT, sample_time=0.015)
    assert FMUController(fixed, inputs=TYPED_IN, outputs=TYPED_OUT, sample_time=0.03).sample_time == 0.03


# ----------------------------------------------------------------------- model exchange

LAG_IO = dict(inputs={"u": "m6.x"}, outputs={"y": "m2.force", "crossing_time": "c.t", "crossings": "c.n"})


def lag_exact(t: np.ndarray, t_start: float, x_start: float, u: float, time_constant: float) -> np.ndarray:
    """x(t) of der(x) = (u - x) / T from x(t_start) = x_start with u held."""
    return u + (x_start - u) * np.exp(-(t - t_start) / time_constant)


def test_model_exchange_fmu_is_integrated_with_exact_time_and_located_state_events(own_fmus):
    time_constant, reset_time, h = 0.5, 0.73, 0.1  # the reset lies on neither the sample nor the RK4 grid
    ctrl = FMUController(own_fmus["lag_filter_me"], **LAG_IO, parameters={"reset_time": reset_time}, sample_time=h)
    assert ctrl.interface == "model exchange" and ctrl.solver_step == 0.01  # DefaultExperiment stepSize
    assert ctrl.direct_feedthrough is False and not ctrl.can_snapshot
    with ctrl.init(0.0) as state, pytest.raises(ModelError, match="snapshots are offered for co-simulation"):
        ctrl.snapshot(state)
    with ctrl.init(0.0) as state:
        got = np.array([ctrl.step(k * h, np.array([1.0]), state).outputs for k in range(13)])
        assert state.integrator.events == 3  # crossing, reset (time event), crossing
    t = np.arange(13) * h
    exact = np.where(t < reset_time, lag_exact(t, 0.0, 0.0, 1.0, time_constant),
                     lag_exact(t, reset_time, 0.0, 1.0, time_constant))
    np.testing.assert_allclose(got[:, 0], exact, rtol=0, atol=2e-9)  # RK4, 0.01 s: O(1e-10) per unit time
    crossing = time_constant * math.log(2.0)  # x = 0.5 in the analytic solution
    assert got[3, 1] == -1.0 and got[4, 1] == pytest.approx(crossing, abs=1e-9) and got[4, 2] == 1.0
    assert got[-1, 1] == pytest.approx(reset_time + crossing, abs=1e-9) and got[-1, 2] == 2.0
    # a held input that changes at a sample: the solution restarts from the sampled state
    with ctrl.init(0.0) as state:
        ctrl.step(0.0, np.array([2.0]), state)
        u = ctrl.step(0.1, np.array([-1.0]), state).outputs[0]
        v = ctrl.step(0.2, np.array([-1.0]), state).outputs[0]
    x1 = lag_exact(np.array(0.1), 0.0, 0.0, 2.0, time_constant)
    # RK4 local error (dt / T)**5 / 120 * |x - u| = 5e-11 per 0.01 s step for |x - u| <= 2
    assert u == pytest.approx(x1, abs=1e-9)
    assert v == pytest.approx(lag_exact(np.array(0.2), 0.1, x1, -1.0, time_constant), abs=2e-9)


def test_model_exchange_discrete_input_is_set_in_event_mode(own_fmus):
    """'frozen' (Boolean, discrete) holds x; the FMU refuses it outside event mode."""
    ctrl = FMUController(own_fmus["lag_filter_me"], inputs={"u": "m6.x", "frozen": "c.hold"},
                         outputs={"y": "m2.force"}, sample_time=0.1)
    frozen = [0, 0, 1, 1, 1, 0, 0]
    with ctrl.init(0.0) as state:
        got = [ctrl.step(k * 0.1, np.array([1.0, frozen[k]]), state).outputs[0] for k in range(len(frozen))]
        # one event per sample for the discrete input, plus the threshold crossing between 0.6 and 0.7 s
        assert state.integrator.events == len(frozen) + 1
    x, expected = 0.0, []
    for k, hold in enumerate(frozen):  # exact ZOH solution, x held on the frozen samples
        expected.append(x)
        x = x if hold else float(lag_exact(np.array(0.1), 0.0, x, 1.0, 0.5))
    np.testing.assert_allclose(got, expected, rtol=0, atol=2e-9)
    assert got[3] == got[4] == got[5] and got[5] != got[6]  # held exactly while frozen


class ZenoModel:
    """Stand-in for fmpy's FMU2Model: x' = -1, indicator x - 0.5, each event puts x 1e-9 above it."""

    def __init__(self) -> None:
        self.x, self.t = 1.0, 0.0

    def setTime(self, t):
        self.t = t

    def setContinuousStates(self, x, n):
        self.x = x[0]

    def getContinuousStates(self, x, n):
        x[0] = self.x

    def getDerivatives(self, dx, n):
        dx[0] = -1.0

    def getEventIndicators(self, z, n):
        z[0] = self.x - 0.5

    def completedIntegratorStep(self):
        return False, False

    def enterEventMode(self):
        pass

    def newDiscreteStates(self):
        if self.t > 0.0:  # not at initialization
            self.x = 0.5 + 1e-9
        return False, False, False, True, False, 0.0

    def enterContinuousTimeMode(self):
        pass


def test_model_exchange_chattering_stops_instead_of_hanging():
    from ctmm.control.fmu_model_exchange import ModelExchangeIntegrator, ModelExchangeTerminated

    integrator = ModelExchangeIntegrator(ZenoModel(), 2, 1, 1, solver_step=0.1, max_events=50)
    integrator.start()
    with pytest.raises(ModelExchangeTerminated, match=r"more than 50 events between t = 0\.0 s and 1\.0 s "
                                                      r"\(chattering\); last event at 0\.50000"):
        integrator.advance(0.0, 1.0)


def test_model_exchange_options_are_checked(own_fmus):
    path = own_fmus["lag_filter_me"]
    coarse = FMUController(path, **LAG_IO, sample_time=0.1, solver_step=0.1)
    with coarse.init(0.0) as state:
        y = [coarse.step(k * 0.1, np.array([1.0]), state).outputs[0] for k in range(5)]
    error = abs(y[-1] - lag_exact(np.array(0.4), 0.0, 0.0, 1.0, 0.5))
    assert 1e-7 < error < 1e-4  # no error control: a coarse step gives an RK4-sized error
    with pytest.raises(ModelError, match=r"solver_step must be > 0"):
        FMUController(path, **LAG_IO, sample_time=0.1, solver_step=0.0)
    with pytest.raises(ModelError, match=r"does not provide the co-simulation interface; it provides: model exchange"):
        FMUController(path, **LAG_IO, sample_time=0.1, interface="co-simulation")
    with pytest.raises(ModelError, match=r"interface must be one of \('co-simulation', 'model exchange'\)"):
        FMUController(path, **LAG_IO, sample_time=0.1, interface="scheduled")
    with pytest.raises(ModelError, match=r"solver_step applies to model-exchange FMUs only"):
        FMUController(own_fmus["pd_controller"], **PD_IO, sample_time=0.1, solver_step=0.01)
    bad = FMUController(path, **LAG_IO, sample_time=0.1, parameters={"time_constant": -1.0})
    with pytest.raises(ModelError, match=r"fmi2EnterInitializationMode failed \(status Error\); FMU log: "
                                         r"time_constant must be > 0"):
        bad.init(0.0)


# ----------------------------------------------------------------------- build_fmu inputs

def _outputs(path: Path) -> np.ndarray:
    ctrl = FMUController(path, **PD_IO, parameters={"kp": 3.0, "kd": 0.5, "limit": 2.0}, sample_time=0.01)
    ys = np.random.default_rng(4).normal(size=(20, 2))
    with ctrl.init(0.0) as state:
        return np.array([ctrl.step(k * 0.01, ys[k], state).outputs for k in range(20)])


@pytest.mark.parametrize("name", ["pd_controller", "typed_io_fmi3"])
def test_build_from_a_source_fmu_and_from_its_extracted_folder(own_fmus, tmp_path, name):
    source_only = rewrite(own_fmus[name], tmp_path / f"{name}.fmu", lambda n, d: None if n.startswith("binaries/") else d)
    with pytest.raises(ModelError, match="no binary for this platform.*build_fmu"):
        FMUController(source_only, inputs={}, outputs={"u" if name == "pd_controller" else "command": "m2.force"},
                      sample_time=0.01)
    from_file = build_fmu(source_only, tmp_path / "from_file", compiler="gcc")
    extracted = tmp_path / "extracted"
    with zipfile.ZipFile(source_only) as archive:
        archive.extractall(extracted)
    from_folder = build_fmu(extracted, tmp_path / "from_folder", compiler="gcc")
    for built in (from_file, from_folder):
        with zipfile.ZipFile(built) as archive:
            names = set(archive.namelist())
        with zipfile.ZipFile(own_fmus[name]) as archive:
            assert set(archive.namelist()) <= names  # everything of the input is kept
    if name == "pd_controller":
        np.testing.assert_array_equal(_outputs(from_file), _outputs(own_fmus[name]))
        np.testing.assert_array_equal(_outputs(from_folder), _outputs(own_fmus[name]))


def test_build_honours_the_declared_source_list(tmp_path):
    source = shutil.copytree(controllers.fmu_source("pd_controller"), tmp_path / "pd")
    (source / "sources" / "harness.c").write_text('#error "not part of the FMU"\n')
    with pytest.raises(ModelError, match=r"compiling FMU 'pd_controller' failed(.|\n)*harness\.c"):
        build_fmu(source, tmp_path / "out0", compiler="gcc")  # no list: every sources/*.c
    description = source / "modelDescription.xml"
    text = description.read_text()
    start = text.index("<CoSimulation")
    end = text.index("/>", start)
    description.write_text(text[:end] + '>\n    <SourceFiles><File name="pd_controller.c"/>'
                           '<File name="unsupported_fmi2.c"/></SourceFiles>\n  </CoSimulation>' + text[end + 2:])
    built = build_fmu(source, tmp_path / "out1", compiler="gcc")
    assert FMUController(built, **PD_IO, sample_time=0.01).fmi_version == 2
    description.write_text(description.read_text().replace('File name="pd_controller.c"', 'File name="gone.c"'))
    with pytest.raises(ModelError, match=r"source file 'gone\.c' listed for 'pd_controller' is missing"):
        build_fmu(source, tmp_path / "out2", compiler="gcc")


def test_build_uses_build_description_definitions_and_list(tmp_path):
    source = shutil.copytree(controllers.fmu_source("typed_io_fmi3"), tmp_path / "typed")
    (source / "sources" / "harness.c").write_text('#error "not part of the FMU"\n')
    built = build_fmu(source, tmp_path / "out", compiler="gcc")  # the #error files are never compiled
    assert FMUController(built, inputs=TYPED_IN, outputs=TYPED_OUT).fmi_version == 3
    build_description = source / "sources" / "buildDescription.xml"
    build_description.write_text(build_description.read_text().replace('language="C99"', 'language="C++17"'))
    with pytest.raises(ModelError, match=r"language 'C\+\+17' is not supported; allowed: C89"):
        build_fmu(source, tmp_path / "out2", compiler="gcc")


def test_build_fmu_refuses_a_file_that_is_not_an_fmu(tmp_path):
    junk = tmp_path / "junk.fmu"
    junk.write_text("no zip")
    with pytest.raises(ModelError, match="is a file but not an FMU"):
        build_fmu(junk, tmp_path / "out")


# ----------------------------------------------------------------------- in a closed-loop simulation

@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/maps")
def test_fmu_failure_in_a_closed_loop_keeps_the_partial_result_and_frees_the_fmu(own_fmus):
    import ctmm
    from ctmm.control import simulate_controlled
    from ctmm.elements import Fixed, Free, Mass, SpringDamper

    plant = ctmm.Chain("seed", [Fixed("start"), SpringDamper("k0", 100.0, 0.5), Mass("m0", 1.0),
                                SpringDamper("k1", 80.0, 0.3), Mass("m1", 1.5), SpringDamper("k2", 120.0, 0.4),
                                Mass("m2", 2.0), Free("end")])
    fmu = FMUController(own_fmus["pd_controller"], inputs={"y": "m2.x", "ydot": "m2.v"}, outputs={"u": "m0.force"},
                        parameters={"kp": 60.0, "kd": 5.0, "fail_at_time": 0.3}, sample_time=0.004)
    with pytest.raises(SimulationError, match=r"FMU 'pd_controller' .*fmi2DoStep failed at t = 0\.3 \(status "
                                              r"Error\).*reached fail_at_time") as info:
        simulate_controlled(plant, 1.0, 0.002, x0={"m0": -0.05, "m2": 0.1}, controllers=[fmu])
    assert info.value.time == pytest.approx(0.3)
    partial = info.value.partial_result
    # the state at t = 0.3 s is computed before the controller is sampled there, so it is kept
    assert partial is not None and partial.time[-1] == pytest.approx(0.3) and np.all(np.isfinite(partial["m2.x"]))
    gc.collect()
    assert not mapped(fmu.unzip_dir.name)  # the co-simulation master closed the instance


def test_schema_violation_is_refused_unless_validation_is_switched_off(own_fmus, tmp_path):
    odd = rewrite(own_fmus["pd_controller"], tmp_path / "odd.fmu",
                  edit_xml("generationTool=", 'vendorFlag="x" generationTool='))
    with pytest.raises(ModelError, match=r"attribute 'vendorFlag' is not allowed.*validate=False accepts"):
        FMUController(odd, **PD_IO, sample_time=0.01)
    ctrl = FMUController(odd, **PD_IO, parameters={"kp": 2.0}, sample_time=0.01, validate=False)
    with ctrl.init(0.0) as state:
        assert ctrl.step(0.0, np.array([0.25, 0.0]), state).outputs[0] == -0.5
    with pytest.raises(ModelError, match="validate must be True or False"):
        FMUController(odd, **PD_IO, sample_time=0.01, validate="no")


def test_step_and_build_argument_errors(own_fmus, tmp_path):
    ctrl = FMUController(own_fmus["pd_controller"], **PD_IO, sample_time=0.1)
    with ctrl.init(0.0) as state:
        with pytest.raises(SimulationError, match=r"y must be 2 real numbers ordered like \('m6\.x', 'm6\.v'\), got 'ab'"):
            ctrl.step(0.0, "ab", state)
        with pytest.raises(ModelError, match="state must be the FMUControllerState returned by this controller's init"):
            ctrl.step(0.0, np.zeros(2), object())
    with pytest.raises(ModelError, match="compiler must be a C compiler command"):
        build_fmu(controllers.fmu_source("pd_controller"), tmp_path, compiler=None)


def test_variables_in_scaled_units_are_converted_to_and_from_si(tmp_path):
    """A PD FMU whose y is in 'mm' measured from 2 mm (BaseUnit m, factor 0.001, offset 0.002), ydot in 'mm/s' and
    u in 'kN': the FMU sees (x - 0.002) / 0.001 and x' / 0.001, and ctmm gets 1000 u, as the FMI standard's
    ``SI value = factor * value + offset`` says (the SI numbers were passed unscaled)."""
    import ctmm
    from ctmm.elements import Fixed, Free, Mass, Spring

    source = shutil.copytree(controllers.fmu_source("pd_controller"), tmp_path / "pd_units")
    xml = (source / "modelDescription.xml").read_text()
    xml = xml.replace('<Unit name="s"><BaseUnit s="1"/></Unit>',
                      '<Unit name="s"><BaseUnit s="1"/></Unit>\n'
                      '    <Unit name="mm_from_rest"><BaseUnit m="1" factor="0.001" offset="0.002"/></Unit>\n'
                      '    <Unit name="mm/s"><BaseUnit m="1" s="-1" factor="0.001"/></Unit>\n'
                      '    <Unit name="kN"><BaseUnit kg="1" m="1" s="-2" factor="1000"/></Unit>')
    for name, unit in (("y", "mm_from_rest"), ("ydot", "mm/s"), ("u", "kN")):
        head, tail = xml.split(f'name="{name}" ', 1)
        tail = tail.replace("<Real start=\"0.0\"/>", f'<Real start="0.0" unit="{unit}"/>', 1) if name != "u" \
            else tail.replace("<Real/>", '<Real unit="kN"/>', 1)
        xml = head + f'name="{name}" ' + tail
    (source / "modelDescription.xml").write_text(xml)
    kp, kd = 2e-3, 1e-4                                   # kN per mm, kN s per mm
    fmu = FMUController(build_fmu(source, tmp_path / "out", compiler="gcc"), inputs={"y": "m.x", "ydot": "m.v"},
                        outputs={"u": "m.force"}, parameters={"kp": kp, "kd": kd}, sample_time=0.01)
    with fmu.init(0.0) as state:
        x, v = 0.012, -0.3                                # 10 mm from the 2 mm rest, -300 mm/s
        u, _ = fmu.step(0.0, np.array([x, v]), state)
    assert u[0] == pytest.approx(1000.0 * (kp * (0.0 - 10.0) - kd * (-300.0)), rel=1e-13)
    # in a loop: every held sample is the law in SI, u = -1e6 kp (x - 0.002) - 1e6 kd v = -2000 x - 100 v + 4 [N]
    chain = ctmm.Chain("one", [Fixed("w"), Spring("k", 50.0), Mass("m", 2.0), Free("e")])
    with_fmu = ctmm.simulate(chain, 0.2, 0.005, x0={"m": x}, controllers=[fmu])
    held = with_fmu["m.force@samples"]
    at_samples = with_fmu["m.x"][::2][:len(held)], with_fmu["m.v"][::2][:len(held)]
    np.testing.assert_allclose(held[:, 1], -2000.0 * at_samples[0] - 100.0 * at_samples[1] + 4.0, rtol=0,
                               atol=1e-11)
    # a relativeQuantity (a difference of positions, here by its declared type) ignores the offset: x / 0.001
    gap = xml.replace("</UnitDefinitions>", '</UnitDefinitions>\n  <TypeDefinitions><SimpleType name="Gap">'
                      '<Real unit="mm_from_rest" relativeQuantity="true"/></SimpleType></TypeDefinitions>')
    (source / "modelDescription.xml").write_text(gap.replace('unit="mm_from_rest"/>', 'declaredType="Gap"/>'))
    relative = FMUController(build_fmu(source, tmp_path / "relative", compiler="gcc"), inputs={"y": "m.x"},
                             outputs={"u": "m.force"}, parameters={"kp": kp}, sample_time=0.01)
    with relative.init(0.0) as state:
        assert relative.step(0.0, np.array([x]), state).outputs[0] == pytest.approx(1000.0 * kp * -12.0, rel=1e-13)
