"""Controllers as Python objects and as FMUs built from C sources (nothing downloaded, nothing skipped).

References: the FMU and Python laws are the same equations (controllers/pd.py, controllers/pid.py,
controllers/fmu/*/sources/*.c) evaluated in IEEE double without fused multiply-add, so their
outputs must agree exactly; the closed-loop plant is integrated exactly under zero-order hold by
the matrix exponential of the augmented system [[A, B], [0, 0]] h (Franklin, Powell & Workman,
Digital Control of Dynamic Systems, 3rd ed., sec. 4.3.3).
"""
from __future__ import annotations

import math
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

from ctmm.control.fmu import FMUController, FMUControllerState, build_fmu
from ctmm.control.protocol import Controller
from ctmm.errors import ModelError, SimulationError

from _controllers_import import load_controllers

controllers = load_controllers()
SaturatedPD = controllers.SaturatedPD
PID = controllers.PID

PD_IO = dict(inputs={"y": "m6.x", "ydot": "m6.v"}, outputs={"u": "m2.force"})
PI_IO = dict(inputs={"y": "m6.x"}, outputs={"u": "m2.force"})


# ----------------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fmus")


@pytest.fixture(scope="session")
def fmus(fmu_dir) -> dict[str, Path]:
    """All shipped FMU sources compiled with gcc into a session folder."""
    assert shutil.which("gcc"), "gcc is required to build the test FMUs"
    return {name: build_fmu(controllers.fmu_source(name), fmu_dir / name, compiler="gcc")
            for name in controllers.FMU_SOURCES}


def edited_fmu(source: Path, target: Path, edit) -> Path:
    """Copy an FMU with its modelDescription.xml passed through ``edit(text) -> text``."""
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(target, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                new = edit(data.decode())
                assert new != data.decode(), "the edit changed nothing"
                data = new.encode()
            zout.writestr(item, data)
    return target


def run_open_loop(controller, ys: np.ndarray, h: float):
    state = controller.init(0.0)
    outputs = []
    for k, y in enumerate(ys):
        u, state = controller.step(k * h, y, state)
        outputs.append(u.copy())
    return np.array(outputs), state


# ----------------------------------------------------------------------------------- building


def test_built_fmus_validate_clean(fmus):
    from fmpy.validation import validate_fmu

    for name, path in fmus.items():
        assert path.name == f"{name}.fmu"
        assert validate_fmu(str(path)) == [], name


def test_build_is_cached_and_rebuilds_on_change(fmus, fmu_dir, tmp_path):
    path = fmus["pd_controller"]
    stamp_before = path.with_name(path.name + ".sha256").read_text()
    mtime = path.stat().st_mtime_ns
    again = build_fmu(controllers.fmu_source("pd_controller"), fmu_dir / "pd_controller", compiler="gcc")
    assert again == path and path.stat().st_mtime_ns == mtime  # cache hit: not rewritten

    source = shutil.copytree(controllers.fmu_source("pd_controller"), tmp_path / "pd_copy")
    first = build_fmu(source, tmp_path / "out", compiler="gcc")
    stamp_first = first.with_name(first.name + ".sha256").read_text()
    assert stamp_first == stamp_before  # same content, same hash, wherever it lives
    c_file = source / "sources" / "pd_controller.c"
    c_file.write_text(c_file.read_text() + "\n/* changed */\n")
    second = build_fmu(source, tmp_path / "out", compiler="gcc")
    assert second == first
    assert second.with_name(second.name + ".sha256").read_text() != stamp_first


def test_build_default_cache_folder(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv("CTMM_CACHE", raising=False)    # $CTMM_CACHE would take precedence
    path = build_fmu(controllers.fmu_source("pi_controller"), compiler="gcc")
    assert path.name == "pi_controller.fmu" and path.parent.parent == tmp_path / "cache" / "ctmm" / "fmu"
    assert build_fmu(controllers.fmu_source("pi_controller"), compiler="gcc") == path


def test_build_reports_compiler_errors(tmp_path):
    source = shutil.copytree(controllers.fmu_source("pi_controller"), tmp_path / "broken")
    c_file = source / "sources" / "pi_controller.c"
    c_file.write_text(c_file.read_text() + "\nthis is not C;\n")
    with pytest.raises(ModelError, match=r"compiling FMU 'pi_controller' failed(.|\n)*error"):
        build_fmu(source, tmp_path / "out", compiler="gcc")


def test_build_input_errors(tmp_path):
    with pytest.raises(ModelError, match="existing folder"):
        build_fmu(tmp_path / "nowhere")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ModelError, match="no modelDescription.xml"):
        build_fmu(tmp_path / "empty")
    with pytest.raises(ModelError, match="not found on PATH"):
        build_fmu(controllers.fmu_source("pd_controller"), tmp_path / "out", compiler="no-such-cc-42")
    with pytest.raises(ModelError, match="unknown FMU source 'pid'; available: lag_filter_me, pd_controller"):
        controllers.fmu_source("pid")


# ----------------------------------------------------------------------------------- PD: FMU == Python


def test_pd_fmu_equals_python_object_including_saturation(fmus):
    h, kp, kd, r, limit = 1e-3, 40.0, 4.0, 0.05, 1.5
    rng = np.random.default_rng(7)
    ys = np.column_stack([rng.normal(0.0, 0.05, 400), rng.normal(0.0, 0.5, 400)])
    fmu = FMUController(fmus["pd_controller"], **PD_IO, sample_time=h,
                        parameters={"kp": kp, "kd": kd, "reference": r, "limit": limit})
    python = SaturatedPD(("m6.x", "m6.v"), ("m2.force",), kp=kp, kd=kd, reference=r, limit=limit, sample_time=h)
    assert fmu.inputs == python.inputs and fmu.outputs == python.outputs
    assert fmu.direct_feedthrough and python.direct_feedthrough

    u_fmu, s_fmu = run_open_loop(fmu, ys, h)
    u_py, s_py = run_open_loop(python, ys, h)
    with s_fmu:
        saturated_in_fmu = s_fmu.slave.getInteger([0])[0]  # local "saturation_count"
    np.testing.assert_array_equal(u_fmu, u_py)
    assert 0 < s_py.saturated_samples < len(ys)  # the sequence does exercise the saturation
    assert saturated_in_fmu == s_py.saturated_samples and s_py.samples == len(ys)
    assert np.max(np.abs(u_py)) == limit


def test_pd_without_limit_is_linear_and_fmi3_matches_fmi2(fmus):
    h = 0.01
    rng = np.random.default_rng(3)
    ys = rng.normal(size=(50, 2))
    params = {"kp": 3.0, "kd": 0.25, "reference": -0.5}
    fmi2 = FMUController(fmus["pd_controller"], **PD_IO, parameters=params, sample_time=h)
    fmi3 = FMUController(fmus["pd_controller_fmi3"], **PD_IO, parameters=params, sample_time=h)
    assert (fmi2.fmi_version, fmi3.fmi_version) == (2, 3)
    u2, s2 = run_open_loop(fmi2, ys, h)
    u3, s3 = run_open_loop(fmi3, ys, h)
    s2.close()
    s3.close()
    np.testing.assert_array_equal(u2, u3)
    np.testing.assert_allclose(u2[:, 0], 3.0 * (-0.5 - ys[:, 0]) - 0.25 * ys[:, 1], rtol=0, atol=1e-15)


# ----------------------------------------------------------------------------------- PI: internal state


def test_pi_fmu_state_save_restore_reproduces_continuation(fmus):
    h = 0.01
    ctrl = FMUController(fmus["pi_controller"], **PI_IO, parameters={"kp": 2.0, "ki": 5.0, "reference": 1.0},
                         sample_time=h)
    assert ctrl.can_snapshot
    ys = np.random.default_rng(11).normal(size=(40, 1))
    with ctrl.init(0.0) as state:
        for k in range(20):
            ctrl.step(k * h, ys[k], state)
        snap = ctrl.snapshot(state)
        first = [ctrl.step((20 + k) * h, ys[20 + k], state).outputs[0] for k in range(20)]
        integral_first = state.slave.getReal([6])[0]
        assert state.steps == 40
        restored = ctrl.restore(state, snap)
        assert restored is state and state.time == pytest.approx(20 * h) and state.steps == 20
        second = [ctrl.step((20 + k) * h, ys[20 + k], state).outputs[0] for k in range(20)]
        assert state.slave.getReal([6])[0] == integral_first
    assert state.closed and snap.handle is None  # close released the snapshot
    assert first == second
    # the continuation depends on the saved integrator: a fresh instance gives other outputs
    with ctrl.init(20 * h) as fresh:
        third = [ctrl.step((20 + k) * h, ys[20 + k], fresh).outputs[0] for k in range(20)]
    assert third != first


def test_pi_fmu_equals_python_pid_with_zero_derivative(fmus):
    h, kp, ki, r = 0.02, 1.5, 4.0, 0.3
    ys = np.random.default_rng(5).normal(size=(100, 1))
    fmu = FMUController(fmus["pi_controller"], **PI_IO, parameters={"kp": kp, "ki": ki, "reference": r},
                        sample_time=h)
    pid = PID("m6.x", "m2.force", kp=kp, ki=ki, kd=0.0, derivative_filter_time=0.0, sample_time=h, reference=r)
    u_fmu, state = run_open_loop(fmu, ys, h)
    state.close()
    u_pid, _ = run_open_loop(pid, ys, h)
    np.testing.assert_array_equal(u_fmu, u_pid)


# ----------------------------------------------------------------------------------- closed loop


def test_closed_loop_mass_spring_fmu_equals_python(fmus):
    """m x'' + c x' + k x = F, F from the saturated PD, exact ZOH plant, sample time h."""
    mass, damping, stiffness = 2.0, 0.3, 50.0
    h, n_steps = 1e-3, 2000
    kp, kd, r, limit = 200.0, 20.0, 0.1, 15.0
    a = np.array([[0.0, 1.0], [-stiffness / mass, -damping / mass]])
    b = np.array([[0.0], [1.0 / mass]])
    augmented = scipy.linalg.expm(np.block([[a, b], [np.zeros((1, 3))]]) * h)
    ad, bd = augmented[:2, :2], augmented[:2, 2]

    def closed_loop(controller):
        z = np.zeros(2)
        state = controller.init(0.0)
        history = np.zeros((n_steps + 1, 3))  # last row: final state, no input
        history[0, :2] = z
        for k in range(n_steps):
            u, state = controller.step(k * h, z.copy(), state)
            z = ad @ z + bd * u[0]
            history[k, 2] = u[0]
            history[k + 1, :2] = z
        return history, state

    fmu = FMUController(fmus["pd_controller"], **PD_IO, sample_time=h,
                        parameters={"kp": kp, "kd": kd, "reference": r, "limit": limit})
    python = SaturatedPD(("m6.x", "m6.v"), ("m2.force",), kp=kp, kd=kd, reference=r, limit=limit, sample_time=h)
    with_fmu, fmu_state = closed_loop(fmu)
    fmu_state.close()
    with_python, py_state = closed_loop(python)
    np.testing.assert_allclose(with_fmu, with_python, rtol=0, atol=1e-12)
    assert py_state.saturated_samples > 0  # the step in the reference saturates the actuator first
    # physics sanity: static equilibrium kp (r - x) = k x
    assert with_python[-1, 0] == pytest.approx(kp * r / (kp + stiffness), rel=1e-3)


# ----------------------------------------------------------------------------------- FMU metadata


def test_direct_feedthrough_from_model_structure(fmus, tmp_path):
    base = fmus["pd_controller"]
    declared = '<Unknown index="8" dependencies="6 7" dependenciesKind="dependent dependent"/>'
    assert FMUController(base, **PD_IO, sample_time=0.1).direct_feedthrough is True
    none = edited_fmu(base, tmp_path / "none.fmu", lambda s: s.replace(declared, '<Unknown index="8" dependencies=""/>'))
    assert FMUController(none, **PD_IO, sample_time=0.1).direct_feedthrough is False
    undeclared = edited_fmu(base, tmp_path / "undeclared.fmu", lambda s: s.replace(declared, '<Unknown index="8"/>'))
    assert FMUController(undeclared, **PD_IO, sample_time=0.1).direct_feedthrough is True
    assert FMUController(base, **PD_IO, sample_time=0.1, direct_feedthrough=False).direct_feedthrough is False
    # a PI FMU mapped without its input: nothing mapped feeds through
    only_output = FMUController(fmus["pi_controller"], inputs={}, outputs={"u": "m2.force"}, sample_time=0.1)
    assert only_output.direct_feedthrough is False and only_output.inputs == ()


def test_fmu_controller_is_an_immutable_protocol_object(fmus):
    ctrl = FMUController(fmus["pd_controller"], **PD_IO, parameters={"kp": 1.0}, sample_time=0.1)
    assert isinstance(ctrl, Controller)
    assert isinstance(SaturatedPD(("a.x", "a.v"), "b.f", kp=1.0, kd=0.0), Controller)
    assert isinstance(PID("a.x", "b.f", kp=1.0, ki=0.0, kd=0.0, derivative_filter_time=0.0, sample_time=0.1),
                      Controller)
    with pytest.raises(AttributeError, match="immutable"):
        ctrl.sample_time = 1.0
    with pytest.raises(TypeError):
        ctrl.parameters["kp"] = 2.0
    assert "pd_controller" in repr(ctrl)


# ----------------------------------------------------------------------------------- errors


def test_missing_fmu_path(tmp_path):
    with pytest.raises(ModelError, match="FMU file not found"):
        FMUController(tmp_path / "missing.fmu", **PD_IO, sample_time=0.1)


def test_unknown_variable_lists_available_names(fmus):
    path = fmus["pd_controller"]
    with pytest.raises(ModelError, match=r"unknown FMU input variable 'position'; available: y, ydot"):
        FMUController(path, inputs={"position": "m6.x"}, outputs={"u": "m2.force"}, sample_time=0.1)
    with pytest.raises(ModelError, match=r"unknown FMU output variable 'force'; available: u"):
        FMUController(path, inputs={"y": "m6.x"}, outputs={"force": "m2.force"}, sample_time=0.1)
    with pytest.raises(ModelError, match=r"unknown FMU parameter variable 'kq'; available: fail_at_time, kd, kp, "
                                         r"limit, reference"):
        FMUController(path, **PD_IO, parameters={"kq": 1.0}, sample_time=0.1)


def test_wrong_causality_and_bad_values(fmus):
    path = fmus["pd_controller"]
    with pytest.raises(ModelError, match=r"'u' has causality 'output'; allowed here: 'input'"):
        FMUController(path, inputs={"u": "m6.x"}, outputs={"u": "m2.force"}, sample_time=0.1)
    with pytest.raises(ModelError, match=r"'kp' has causality 'parameter'; allowed here: 'output'"):
        FMUController(path, inputs={}, outputs={"kp": "m2.force"}, sample_time=0.1)
    with pytest.raises(ModelError, match="sample_time must be > 0"):
        FMUController(path, **PD_IO, sample_time=0.0)
    with pytest.raises(ModelError, match=r"parameters\['kd'\] must be finite"):
        FMUController(path, **PD_IO, parameters={"kd": math.nan}, sample_time=0.1)
    with pytest.raises(ModelError, match="at least one FMU output"):
        FMUController(path, inputs={"y": "m6.x"}, outputs={}, sample_time=0.1)


def test_model_exchange_only_fmu_needs_model_exchange_functions(fmus, tmp_path):
    def to_model_exchange(text: str) -> str:
        start = text.index("<CoSimulation")
        end = text.index("/>", start) + 2
        return text[:start] + '<ModelExchange modelIdentifier="pd_controller"/>' + text[end:]

    me_only = edited_fmu(fmus["pd_controller"], tmp_path / "me_only.fmu", to_model_exchange)
    # run as model exchange, the co-simulation binary lacks the model-exchange functions
    with pytest.raises(ModelError, match=r"does not export the FMI 2 model exchange functions "
                                         r"fmi2CompletedIntegratorStep, .*fmi2NewDiscreteStates"):
        FMUController(me_only, **PD_IO, sample_time=0.1)
    with pytest.raises(ModelError, match=r"does not provide the co-simulation interface; it provides: model exchange"):
        FMUController(me_only, **PD_IO, sample_time=0.1, interface="co-simulation")


def test_fmi1_is_rejected(fmus, tmp_path):
    fmi1 = edited_fmu(fmus["pd_controller"], tmp_path / "fmi1.fmu",
                      lambda s: s.replace('fmiVersion="2.0"', 'fmiVersion="1.0"'))
    with pytest.raises(ModelError, match="FMI 1.0|fmiVersion"):
        FMUController(fmi1, **PD_IO, sample_time=0.1)


def test_snapshot_needs_the_capability(fmus, tmp_path):
    no_state = edited_fmu(fmus["pd_controller"], tmp_path / "no_state.fmu",
                          lambda s: s.replace('canGetAndSetFMUstate="true"', 'canGetAndSetFMUstate="false"'))
    ctrl = FMUController(no_state, **PD_IO, sample_time=0.1)
    with ctrl.init(0.0) as state:
        with pytest.raises(ModelError, match="does not support saving its state"):
            ctrl.snapshot(state)


@pytest.mark.parametrize("name", ["pd_controller", "pd_controller_fmi3"])
def test_dostep_failure_on_nan_input_carries_the_time(fmus, name):
    h = 0.01
    ctrl = FMUController(fmus[name], **PD_IO, parameters={"kp": 1.0}, sample_time=h)
    with ctrl.init(0.0) as state:
        for k in range(3):
            ctrl.step(k * h, np.array([0.1, 0.0]), state)
        snap = ctrl.snapshot(state)
        with pytest.raises(SimulationError, match=r"DoStep failed at t = 0\.03.*input not finite") as info:
            ctrl.step(3 * h, np.array([math.nan, 0.0]), state)
        assert info.value.time == pytest.approx(3 * h)
        with pytest.raises(SimulationError, match="failed at t = 0.03"):
            ctrl.step(3 * h, np.array([0.1, 0.0]), state)
        ctrl.restore(state, snap)  # rewinding clears the failure
        u, _ = ctrl.step(3 * h, np.array([0.1, 0.0]), state)
        assert u[0] == pytest.approx(-0.1)


def test_dostep_failure_at_fail_at_time(fmus):
    h = 0.01
    ctrl = FMUController(fmus["pi_controller"], **PI_IO, parameters={"ki": 1.0, "fail_at_time": 0.05},
                         sample_time=h)
    with ctrl.init(0.0) as state:
        for k in range(5):
            ctrl.step(k * h, np.array([0.0]), state)
        with pytest.raises(SimulationError, match="fail_at_time") as info:
            ctrl.step(5 * h, np.array([0.0]), state)
    assert info.value.time == pytest.approx(0.05)


def test_step_protocol_misuse(fmus):
    ctrl = FMUController(fmus["pd_controller"], **PD_IO, sample_time=0.01)
    state = ctrl.init(0.0)
    assert isinstance(state, FMUControllerState)
    with pytest.raises(SimulationError, match="next communication point is 0.0"):
        ctrl.step(0.5, np.zeros(2), state)
    with pytest.raises(SimulationError, match=r"y must have shape \(2,\)"):
        ctrl.step(0.0, np.zeros(3), state)
    state.close()
    state.close()  # idempotent
    with pytest.raises(SimulationError, match="closed"):
        ctrl.step(0.0, np.zeros(2), state)


# ----------------------------------------------------------------------------------- Python controllers


def test_python_controller_validation():
    with pytest.raises(ModelError, match="kp must be finite"):
        SaturatedPD(("a.x", "a.v"), "b.f", kp=math.inf, kd=0.0)
    with pytest.raises(ModelError, match="limit must be > 0"):
        SaturatedPD(("a.x", "a.v"), "b.f", kp=1.0, kd=0.0, limit=-1.0)
    with pytest.raises(ModelError, match="sample_time must be > 0"):
        SaturatedPD(("a.x", "a.v"), "b.f", kp=1.0, kd=0.0, sample_time=0.0)
    with pytest.raises(ModelError, match="inputs must name exactly 2 signal"):
        SaturatedPD(("a.x",), "b.f", kp=1.0, kd=0.0)
    with pytest.raises(ModelError, match="reference must be callable"):
        SaturatedPD(("a.x", "a.v"), "b.f", kp=1.0, kd=0.0, reference=lambda: 0.0)
    with pytest.raises(ModelError, match="derivative_filter_time must be >= 0"):
        PID("a.x", "b.f", kp=1.0, ki=0.0, kd=1.0, derivative_filter_time=-0.1, sample_time=0.1)
    with pytest.raises(ModelError, match="sample_time must be > 0"):
        PID("a.x", "b.f", kp=1.0, ki=0.0, kd=1.0, derivative_filter_time=0.0, sample_time=-1.0)
    with pytest.raises(TypeError):
        SaturatedPD(("a.x", "a.v"), "b.f", 1.0, 0.0)  # gains are keyword-only


def test_saturated_pd_tracks_a_moving_reference_and_reports_nan():
    pd = SaturatedPD(("a.x", "a.v"), "b.f", kp=10.0, kd=2.0, reference=math.sin, reference_rate=math.cos)
    t = 0.3
    u, state = pd.step(t, np.array([math.sin(t), math.cos(t)]), pd.init(0.0))
    assert u[0] == 0.0 and state.samples == 1 and not state.last_saturated
    with pytest.raises(SimulationError, match="non-finite output") as info:
        pd.step(0.5, np.array([math.nan, 0.0]), state)
    assert info.value.time == 0.5


def test_pid_filtered_derivative_is_backward_euler():
    """Error step 0 -> 1 at sample 1: D_k = kd/(Tf+h) * (Tf/(Tf+h))**(k-1)."""
    kd, tf, h = 2.0, 0.05, 0.01
    pid = PID("a.x", "b.f", kp=0.0, ki=0.0, kd=kd, derivative_filter_time=tf, sample_time=h)
    state = pid.init(0.0)
    outputs = []
    for k in range(30):
        u, state = pid.step(k * h, np.array([0.0 if k == 0 else -1.0]), state)
        outputs.append(u[0])
    expected = [0.0] + [kd / (tf + h) * (tf / (tf + h)) ** (k - 1) for k in range(1, 30)]
    np.testing.assert_allclose(outputs, expected, rtol=1e-13, atol=0)
    # Tf = 0: plain backward difference kd (e_k - e_{k-1}) / h
    raw = PID("a.x", "b.f", kp=0.0, ki=0.0, kd=kd, derivative_filter_time=0.0, sample_time=h)
    s = raw.init(0.0)
    _, s = raw.step(0.0, np.array([0.0]), s)
    u, s = raw.step(h, np.array([-0.5]), s)
    assert u[0] == pytest.approx(kd * 0.5 / h)


def test_pid_integral_anti_windup_and_feedthrough():
    pid = PID("a.x", "b.f", kp=0.0, ki=10.0, kd=0.0, derivative_filter_time=0.0, sample_time=0.1, limit=1.0)
    assert pid.direct_feedthrough is False  # a pure I law uses past errors only
    state = pid.init(0.0)
    for k in range(50):
        u, state = pid.step(0.1 * k, np.array([-1.0]), state)  # e = 1 for ever
    assert u[0] == 1.0 and state.saturated_samples == 48
    # I_1 = 0.1 (u_1 = 1 = limit, not clipped), I_2 = 0.2, then clamped while saturated
    assert state.integral == pytest.approx(0.2)
    outputs = []
    for k in range(3):  # error reverses: the integral unwinds at once, no windup delay
        u, state = pid.step(5.0 + 0.1 * k, np.array([1.0]), state)
        outputs.append(u[0])
    np.testing.assert_allclose(outputs, [1.0, 1.0, 0.0], atol=1e-12)
