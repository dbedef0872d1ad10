"""compiled=True loads a cached kernel library without rebuilding the time loop or generating C (issue 13).

The cache key is computed before the time loop's graph and the C text
(:func:`ctmm.generated_loop.compiled_time_loop`, :func:`ctmm.codegen.load_casadi_keyed`).  A second
call must not build anything (the builders are replaced by functions that raise); a changed number
must give a new library whose results follow the new number.  References: the discrete solutions of
one undamped oscillator ``m x'' + k x = 0`` under RK4 (the RK4 polynomial of the 2x2 system matrix,
raised to the step count) and under the average-acceleration Newmark rule (phase ``2 atan(w dt / 2)``
per step), computed here with numpy, never with the generated code.
"""
from __future__ import annotations

import numpy as np
import pytest

import ctmm
from ctmm import codegen, generated_loop
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.errors import ModelError

DT, T_FINAL, X0 = 1e-3, 0.2, 0.01


def oscillator(mass: float, stiffness: float) -> ctmm.Chain:
    return ctmm.Chain("oscillator", [Fixed("wall"), SpringDamper("spring", stiffness, 0.0), Mass("m", mass),
                                     Free("end")])


def rk4_reference(mass: float, stiffness: float, n_steps: int) -> np.ndarray:
    """x at steps 0..n of RK4 on y' = A y: y_{n+1} = (I + hA + (hA)^2/2 + (hA)^3/6 + (hA)^4/24) y_n."""
    hA = DT * np.array([[0.0, 1.0], [-stiffness / mass, 0.0]])
    step = np.eye(2) + hA + hA @ hA / 2 + hA @ hA @ hA / 6 + hA @ hA @ hA @ hA / 24
    y, out = np.array([X0, 0.0]), [X0]
    for _ in range(n_steps):
        y = step @ y
        out.append(y[0])
    return np.array(out)


def newmark_reference(mass: float, stiffness: float, n_steps: int) -> np.ndarray:
    """x at steps 0..n of the average-acceleration rule on an undamped oscillator from rest:
    x_n = x0 cos(n theta), theta = 2 atan(w dt / 2)."""
    theta = 2.0 * np.arctan(np.sqrt(stiffness / mass) * DT / 2.0)
    return X0 * np.cos(theta * np.arange(n_steps + 1))


def run(chain: ctmm.Chain, method) -> np.ndarray:
    result = ctmm.simulate(chain, T_FINAL, DT, method=method, compiled=True, x0={"m": X0})
    assert result.info["path"].startswith("generated")
    return np.asarray(result["m.x"])


def trajectory(result) -> np.ndarray:
    """Every stored signal of a run (sample records too), one after the other (non-empty)."""
    names = sorted(result.signals())
    assert names and len(result.time) > 1
    return np.concatenate([np.ravel(np.asarray(result[name], dtype=float)) for name in names])


def entries(folder) -> list[str]:
    return sorted(path.name for path in (folder / "kernels").iterdir() if not path.name.startswith("."))


def forbid_building(monkeypatch) -> None:
    def refuse(*_args, **_kwargs):
        raise AssertionError("the time loop or the C text was built although the library is cached")

    monkeypatch.setattr(generated_loop, "time_loop_functions", refuse)
    monkeypatch.setattr(codegen, "casadi_source", refuse)


@pytest.mark.parametrize("method, reference", [("rk4", rk4_reference), ("newmark", newmark_reference)])
def test_second_call_loads_without_building_and_a_changed_number_rebuilds(tmp_path, monkeypatch, method,
                                                                          reference):
    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    n_steps = round(T_FINAL / DT)
    first = run(oscillator(2.0, 400.0), method)
    np.testing.assert_allclose(first, reference(2.0, 400.0, n_steps), rtol=0, atol=1e-12 * X0)
    built = entries(tmp_path)
    assert len(built) == 1

    with monkeypatch.context() as patch:
        forbid_building(patch)
        again = run(oscillator(2.0, 400.0), method)
    assert np.array_equal(again, first)
    assert entries(tmp_path) == built

    stiffer = run(oscillator(2.0, 900.0), method)             # one number edited: a new library
    assert len(entries(tmp_path)) == 2
    np.testing.assert_allclose(stiffer, reference(2.0, 900.0, n_steps), rtol=0, atol=1e-12 * X0)
    assert np.max(np.abs(stiffer - first)) > 1e-3 * X0


def test_planar_and_spatial_scenes_load_without_building(tmp_path, monkeypatch):
    from ctmm import planar, spatial

    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    pendulum = planar.PlanarModel.chain("pendulum", [
        planar.Fixed("ground"), planar.SmoothHinge("hinge"),
        planar.RigidBody("link", mass=1.0, inertia=0.1, center_of_mass=(0.5, 0.0), outboard=(1.0, 0.0))],
        gravity=(0.0, -9.81))
    arm = spatial.SpatialModel("arm", [
        spatial.SpatialBody("link", 1.0, np.diag([0.01, 0.1, 0.1]), (0.5, 0.0, 0.0)),
        spatial.Revolute(name="joint", parent=None, child="link", point=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0))],
        gravity=(0.0, 0.0, -9.81))
    runs = [lambda: ctmm.simulate(pendulum, 0.05, DT, method="rk4", compiled=True, x0=np.array([0.3])),
            lambda: ctmm.simulate(arm, 0.05, DT, method="rk4", compiled=True, x0=np.array([0.3]))]
    first = [trajectory(run_it()) for run_it in runs]
    built = entries(tmp_path)
    assert len(built) == 2
    with monkeypatch.context() as patch:
        forbid_building(patch)
        again = [trajectory(run_it()) for run_it in runs]
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    assert entries(tmp_path) == built


def counting_build() -> tuple[list, object]:
    """``(calls, build)``: ``build()`` returns two casadi functions and appends to ``calls``."""
    import casadi as ca

    calls: list = []

    def build():
        calls.append(1)
        x = ca.SX.sym("x")
        return [ca.Function("square", [x], [x * x]), ca.Function("triple", [x], [3 * x])]

    return calls, build


def test_load_casadi_keyed_builds_once_per_key(tmp_path):
    calls, build = counting_build()
    parts = [("numbers", b"1")]
    square, triple = codegen.load_casadi_keyed(parts, ["square", "triple"], build, "keyed", cache_dir=tmp_path)
    assert float(square(3.0)) == 9.0 and float(triple(3.0)) == 9.0 and len(calls) == 1
    codegen.load_casadi_keyed(parts, ["square", "triple"], build, "keyed", cache_dir=tmp_path)
    assert len(calls) == 1                                       # cached: build() not called
    codegen.load_casadi_keyed([("numbers", b"2")], ["square", "triple"], build, "keyed", cache_dir=tmp_path)
    assert len(calls) == 2 and len(entries(tmp_path)) == 2       # another key: another entry


def test_load_casadi_keyed_rebuilds_a_damaged_entry_and_refuses_wrong_names(tmp_path):
    calls, build = counting_build()
    parts = [("numbers", b"1")]
    codegen.load_casadi_keyed(parts, ["square", "triple"], build, "keyed", cache_dir=tmp_path)
    (library,) = (tmp_path / "kernels").glob("keyed-k*/keyed.so")
    library.write_bytes(library.read_bytes()[:100])              # truncated: checksum no longer matches
    square, _ = codegen.load_casadi_keyed(parts, ["square", "triple"], build, "keyed", cache_dir=tmp_path)
    assert len(calls) == 2 and float(square(4.0)) == 16.0
    with pytest.raises(ModelError, match="'triple', 'square'"):
        codegen.load_casadi_keyed([("numbers", b"3")], ["triple", "square"], build, "keyed", cache_dir=tmp_path)
    with pytest.raises(ModelError, match="name must be"):
        codegen.load_casadi_keyed(parts, ["square"], build, "bad name", cache_dir=tmp_path)


def spatial_arm(mass: float = 1.0, links: int = 2) -> "ctmm.spatial.SpatialModel":
    from ctmm import spatial

    elements: list = []
    for i in range(links):
        elements.append(spatial.SpatialBody(f"l{i}", mass if i == links - 1 else 1.0, np.diag([0.01, 0.1, 0.1]),
                                            (0.5, 0.0, 0.0), {"end": (1.0, 0.0, 0.0)}))
        elements.append(spatial.Revolute(name=f"j{i}", parent=None if i == 0 else f"l{i - 1}", child=f"l{i}",
                                         point=(0.0, 0.0, 0.0) if i == 0 else "end",
                                         axis=(0.0, 1.0, 0.0) if i % 2 else (0.0, 0.0, 1.0), actuated=True))
    return spatial.SpatialModel("arm", elements, gravity=(0.0, 0.0, -9.81))


def forbid_symbols(monkeypatch) -> None:
    """Building the symbolic step of a described kernel raises (spatial rates, a chain scheme's step)."""
    from ctmm import compiled_spatial_loops
    from ctmm.compiled_chain_schemes import CompiledChainScheme
    from ctmm.compiled_spatial import SpatialRates

    def refuse(*_args, **_kwargs):
        raise AssertionError("the symbolic step was built although the library is cached")

    monkeypatch.setattr(SpatialRates, "_build", refuse)
    monkeypatch.setattr(CompiledChainScheme, "_step_function", refuse)
    monkeypatch.setattr(compiled_spatial_loops, "loop_acceleration", refuse)
    forbid_building(monkeypatch)


def textbook_newmark(mass: float, stiffness: float, beta: float, gamma: float, n_steps: int) -> np.ndarray:
    """x at steps 0..n of Newmark(beta, gamma) on m x'' + k x = 0 from x0 at rest, written here."""
    x, v, a, out = X0, 0.0, -stiffness * X0 / mass, [X0]
    for _ in range(n_steps):
        x_pred, v_pred = x + DT * v + (0.5 - beta) * DT * DT * a, v + (1.0 - gamma) * DT * a
        a = -stiffness * x_pred / (mass + beta * DT * DT * stiffness)
        x, v = x_pred + beta * DT * DT * a, v_pred + gamma * DT * a
        out.append(x)
    return np.array(out)


def controlled_arm_run(gain: float, compiled: bool | None = True) -> ctmm.SimulationResult:
    """The arm with a real-time loop on its first joint and a PID co-simulated on the second."""
    from ctmm.control import Feedback, with_feedback

    from _controllers_import import load_controllers

    controlled = with_feedback(spatial_arm(), [Feedback("hold", "j0.angle", "j0.torque", gain=gain)])
    pid = load_controllers().PID("j1.angle", "j1.torque", kp=4.0, ki=0.0, kd=0.3, derivative_filter_time=0.02,
                                 sample_time=0.01)
    return ctmm.simulate(controlled, 0.05, DT, x0=np.array([0.3, 0.1]), controllers=[pid], compiled=compiled)


def test_described_kernels_load_without_building_their_symbols(tmp_path, monkeypatch):
    """A spatial arm (numbers constants of the code), the arm with a loop and a co-simulated PID, and a chain's
    generated Newmark: the second call computes the key from the model's description and loads the library; no
    symbol is built."""
    from ctmm.schemes import Newmark

    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    runs = [lambda: trajectory(ctmm.simulate(spatial_arm(), 0.05, DT, method="rk4", compiled=True,
                                             x0=np.array([0.3, 0.1]))),
            lambda: trajectory(controlled_arm_run(5.0)),
            lambda: run(oscillator(2.0, 400.0), Newmark(0.3, 0.6))]
    first = [run_it() for run_it in runs]
    built = entries(tmp_path)
    assert len(built) == 3
    with monkeypatch.context() as patch:
        forbid_symbols(patch)
        again = [run_it() for run_it in runs]
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    assert entries(tmp_path) == built
    np.testing.assert_allclose(first[2], textbook_newmark(2.0, 400.0, 0.3, 0.6, round(T_FINAL / DT)), rtol=0,
                               atol=1e-13 * X0)


def test_a_changed_number_or_option_gives_a_new_described_library_and_new_numbers(tmp_path, monkeypatch):
    """One number (the tip link's mass; the spring's stiffness) or one option (the Newmark parameters) edited: a new
    library whose numbers follow the edit (the numpy RK4 of the arm; the textbook Newmark written here)."""
    from ctmm.schemes import Newmark

    monkeypatch.setenv("CTMM_CACHE", str(tmp_path))
    x0 = np.array([0.3, 0.1])
    light = ctmm.simulate(spatial_arm(1.0), 0.05, DT, method="rk4", compiled=True, x0=x0)
    heavy = ctmm.simulate(spatial_arm(1.5), 0.05, DT, method="rk4", compiled=True, x0=x0)
    assert len(entries(tmp_path)) == 2
    numpy_heavy = ctmm.simulate(spatial_arm(1.5), 0.05, DT, method="rk4", x0=x0)
    np.testing.assert_allclose(trajectory(heavy), trajectory(numpy_heavy), rtol=0, atol=1e-12)
    assert np.max(np.abs(trajectory(heavy) - trajectory(light))) > 1e-6
    soft, stiff = controlled_arm_run(5.0), controlled_arm_run(6.0)               # one loop gain edited
    assert len(entries(tmp_path)) == 4
    np.testing.assert_allclose(trajectory(stiff), trajectory(controlled_arm_run(6.0, None)), rtol=0, atol=1e-12)
    assert np.max(np.abs(trajectory(stiff) - trajectory(soft))) > 1e-6
    n_steps = round(T_FINAL / DT)
    base = run(oscillator(2.0, 400.0), Newmark(0.3, 0.6))
    stiffer = run(oscillator(2.0, 400.0 * (1 + 1e-9)), Newmark(0.3, 0.6))
    other = run(oscillator(2.0, 400.0), Newmark(0.3025, 0.6))
    assert len(entries(tmp_path)) == 7
    for x, (stiffness, beta) in ((stiffer, (400.0 * (1 + 1e-9), 0.3)), (other, (400.0, 0.3025))):
        np.testing.assert_allclose(x, textbook_newmark(2.0, stiffness, beta, 0.6, n_steps), rtol=0, atol=1e-13 * X0)
        assert np.max(np.abs(x - base)) > 1e-12 * X0
