"""First compile against run of the generated spatial DT-TMM schemes, by Newton tangent construction (issue 13).

The generated Newton step of :mod:`ctmm.compiled_spatial_schemes` (and of the kinematic loop schemes of
:mod:`ctmm.compiled_spatial_loop_schemes`, and the loops in the step, which build on it) needs the tangent
``d r / d a`` of its residual ``r(a) = a - v_dot(q_n (+) delta(a), v(a))``.  Three constructions, each built in a
fresh cache folder:

* ``symbolic``: ``casadi.jacobian`` of the residual's SX expression (the default below 8 velocities before
  session 15): every entry repeats the retraction and the sweep, so one free body's step was 0.46 MB of C and a
  free body held by a revolute cut 1.2 MB (18 s of gcc at ``-O1``);
* ``mapped_all_inputs``: the mapped tangent as it was (:func:`ctmm.mapped_tangent.mapped_columns`: the residual's
  forward derivative along *every* input, zero seeds on the held ones, mapped over the unit seeds, and the value
  by a separate copy of the residual), reproduced here;
* ``default``: what the library builds now (:func:`ctmm.mapped_tangent.value_and_jacobian`: the directional
  derivative along ``a`` alone, ``casadi.jtimes``, mapped over the unit seeds, the value taken from its first
  evaluation), at every size.

Per case and construction: ``c_kB`` (the generated C), ``python_cpu_s`` (building the expressions, functions and
C text: this process), ``compiler_cpu_s`` (gcc with the library's flags, ``-O1`` for spatial kernels: the children
CPU, ``os.times``), ``run_cpu_us_per_step`` (the generated run of ``RUN_STEPS`` steps, ``CompiledSpatialScheme.run``,
best of ``REPEATS`` rounds interleaved over the constructions, process CPU), ``newton_iterations`` (the run's total)
and ``max_difference`` (largest difference of the stored states from the ``symbolic`` run: the same root to the
Newton tolerance).  Ratios against ``symbolic`` in the same run.

Measured 2026-11-26 (session 15; load 5-7 on 2 cores from other jobs; 1000 steps, best of 7 rounds; C, gcc CPU,
kernel CPU per step, ratios to ``symbolic``): free body (6 velocities) Newmark ``mapped_all_inputs`` 0.61 / 0.47 /
1.96, ``default`` 0.51 / 0.38 / 1.90 (458 -> 232 kB, 6.2 -> 2.4 s, 17 -> 32 us); Houbolt 0.63 / 0.50 / 2.06 and
0.53 / 0.43 / 1.79; revolute + ball (4) Newmark 0.76 / 0.75 / 1.53 and 0.66 / 0.66 / 1.46; a free body held by a
revolute cut (kinematic loop scheme, 6) 0.51 / 0.29 / 1.43 and 0.44 / 0.26 / 1.48 (1206 -> 530 kB, 19.4 -> 5.0 s,
42 -> 62 us).  The same Newton iterations and stored states (difference 0) in every case.  Table in
docs/spatial.md ("DT-TMM schemes in generated C").

Run ``python benchmarks/spatial_scheme_tangent.py [--quick]``; writes
``benchmarks/results/spatial_scheme_tangent.json``.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, Callable, Iterator

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import ctmm.spatial as sp  # noqa: E402
from ctmm import compiled_spatial_schemes  # noqa: E402
from ctmm.compiled_spatial_loop_schemes import CompiledSpatialLoopScheme  # noqa: E402
from ctmm.compiled_spatial_schemes import CompiledSpatialScheme  # noqa: E402
from ctmm.mapped_tangent import mapped_columns  # noqa: E402
from ctmm.signals import Harmonic, Step  # noqa: E402
from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel  # noqa: E402
from ctmm.spatial.integrate import initial_state  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results" / "spatial_scheme_tangent.json"
CONSTRUCTIONS = ("symbolic", "mapped_all_inputs", "default")
DT = 1e-3
RUN_STEPS = 1000
REPEATS = 7


def tumbling_top() -> tuple[sp.SpatialModel, np.ndarray]:
    """A torque-free free body spun about its intermediate axis (6 velocities): model and ``[q ; v]``."""
    model = sp.SpatialModel("top", [sp.SpatialBody("body", 2.0, (0.1, 0.2, 0.3)),
                                    sp.Free(name="base", parent=None, child="body")], gravity=(0, 0, 0))
    return model, initial_state(model, {}, {"base.vx": 0.3, "base.wx": 0.1, "base.wy": 4.0, "base.wz": 0.2})


def double_pendulum() -> tuple[sp.SpatialModel, np.ndarray]:
    """A revolute link carrying a second one on a ball joint (4 velocities): model and ``[q ; v]``."""
    model = sp.SpatialModel("double", [
        sp.SpatialBody("upper", 1.0, (0.02, 0.03, 0.015), center_of_mass=(0, 0, -0.25), points={"tip": (0, 0, -0.5)}),
        sp.SpatialBody("lower", 0.7, (0.01, 0.012, 0.006), center_of_mass=(0.1, 0, -0.2)),
        sp.Revolute(name="hinge", parent=None, child="upper", axis=(1, 0, 0)),
        sp.Spherical(name="ball", parent="upper", point="tip", child="lower")], gravity=(0, 0, -9.81))
    return model, initial_state(model, {"hinge.angle": 0.4}, {"hinge.angle_rate": 1.5, "ball.wy": -2.0,
                                                               "ball.wz": 1.0})


def hinged_body() -> tuple[SpatialKinematicLoopModel, np.ndarray]:
    """A free body held at the ground by a revolute cut (a compound pendulum, 6 tree velocities), pushed at its tip
    by a sine and steps: the kinematic loop model and its consistent ``[q ; v]``."""
    tree = sp.SpatialModel("hinged", [
        sp.SpatialBody("p", 1.2, np.diag([0.02, 0.03, 0.025]), (0.1, 0.0, -0.3), {"tip": (0.2, 0.0, -0.6)}),
        sp.Free(name="free", parent=None, child="p"),
        sp.Load("push", "p", "tip", force=(Harmonic(3.0, 20.0), Step(1.0, 0.011), Step(-2.0, 0.005)))])
    loop = SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="hinge", parent=None, child="p", kind="revolute",
                                                            axis=(0, 1, 0))], baumgarte=20.0)
    q, v = loop.consistent_state({"free.qw": np.cos(0.25), "free.qy": np.sin(0.25), "free.x": 0.01},
                                 {"free.wy": 2.0}, keep=["free.wy"])
    return loop, np.concatenate([q, v])


def cases() -> dict[str, tuple[Callable[..., Any], Any, np.ndarray, str]]:
    """``name -> (compiled class, model, [q ; v], scheme)``."""
    top, top_start = tumbling_top()
    double, double_start = double_pendulum()
    hinge, hinge_start = hinged_body()
    return {"free_body_newmark": (CompiledSpatialScheme, top, top_start, "newmark"),
            "free_body_houbolt": (CompiledSpatialScheme, top, top_start, "houbolt"),
            "double_pendulum_newmark": (CompiledSpatialScheme, double, double_start, "newmark"),
            "hinged_body_loop_newmark": (CompiledSpatialLoopScheme, hinge, hinge_start, "newmark")}


def mapped_all_inputs(function: Any, index: int, name: str) -> Any:
    """The mapped tangent before session 15: the value by the function, the columns by
    :func:`ctmm.mapped_tangent.mapped_columns` (the forward derivative along every input, zero seeds on the held
    ones)."""
    import casadi as ca

    inputs = [ca.MX.sym(function.name_in(i), function.sparsity_in(i)) for i in range(function.n_in())]
    size = function.size1_in(index)
    columns = mapped_columns(function, [index], size, f"{name}_columns")
    return ca.Function(name, inputs, [function.call(inputs)[0], columns(*inputs, ca.DM.eye(size))])


@contextlib.contextmanager
def construction(label: str) -> Iterator[str | None]:
    """The ``tangent`` argument of ``label`` (with the old mapped construction patched in for
    ``mapped_all_inputs``)."""
    if label != "mapped_all_inputs":
        yield "symbolic" if label == "symbolic" else None
        return
    original = compiled_spatial_schemes.value_and_jacobian
    compiled_spatial_schemes.value_and_jacobian = mapped_all_inputs
    try:
        yield "mapped"
    finally:
        compiled_spatial_schemes.value_and_jacobian = original


def cpu() -> tuple[float, float]:
    """``(this process, its waited-for children)`` CPU time [s] (user + system)."""
    times = os.times()
    return times.user + times.system, times.children_user + times.children_system


def c_size(folder: str) -> int:
    """Bytes of the generated C under ``folder``."""
    return sum(path.stat().st_size for path in Path(folder).rglob("*.c"))


def measure(case: tuple[Callable[..., Any], Any, np.ndarray, str], run_steps: int, repeats: int) -> list[dict]:
    """One row per construction (module docstring)."""
    kind, model, start, scheme = case
    rows, built = {}, {}
    with tempfile.TemporaryDirectory() as base:
        for label in CONSTRUCTIONS:
            folder = tempfile.mkdtemp(dir=base)
            own, children = cpu()
            with construction(label) as tangent:
                compiled = kind(model, scheme, cache_dir=folder, tangent=tangent)
            own_after, children_after = cpu()
            state = compiled.initial_state(start)
            built[label] = (compiled, state)
            rows[label] = {"construction": label, "tangent": compiled.tangent, "c_kB": c_size(folder) / 1e3,
                           "python_cpu_s": own_after - own, "compiler_cpu_s": children_after - children,
                           "run": []}
        for _ in range(repeats):
            for label, (compiled, state) in built.items():
                began = time.process_time()
                stored = compiled.run(state, DT, run_steps)
                rows[label]["run"].append(time.process_time() - began)
                rows[label]["stored"] = stored
    reference = rows["symbolic"]["stored"]
    for label, row in rows.items():
        stored, compiled = row.pop("stored"), built[label][0]
        nq, n = compiled.model.n_positions, compiled.model.n_velocities
        row.update(run_cpu_us_per_step=1e6 * min(row.pop("run")) / run_steps,
                   newton_iterations=int(stored[-1, compiled.status_index + 2]),
                   max_difference=float(np.max(np.abs(stored[:, :nq + n] - reference[:, :nq + n]))))
    first = rows["symbolic"]
    for row in rows.values():
        row.update(c_ratio=row["c_kB"] / first["c_kB"], compiler_cpu_ratio=row["compiler_cpu_s"] /
                   first["compiler_cpu_s"], run_cpu_ratio=row["run_cpu_us_per_step"] / first["run_cpu_us_per_step"])
    return list(rows.values())


def main(quick: bool, only: list[str] | None = None) -> dict:
    run_steps = 300 if quick else RUN_STEPS
    repeats = 3 if quick else REPEATS
    rows = []
    load_before = os.getloadavg()
    for name, case in cases().items():
        if only and name not in only:
            continue
        for row in measure(case, run_steps, repeats):
            row["case"] = name
            rows.append(row)
            print(f"{name:26s} {row['construction']:18s} C {row['c_kB']:7.0f} kB (x{row['c_ratio']:.2f})  python "
                  f"{row['python_cpu_s']:5.2f} s  gcc {row['compiler_cpu_s']:6.2f} s (x{row['compiler_cpu_ratio']:.2f})"
                  f"  run {row['run_cpu_us_per_step']:6.1f} us/step (x{row['run_cpu_ratio']:.2f})  Newton "
                  f"{row['newton_iterations']}  diff {row['max_difference']:.1e}", flush=True)
    measured = {"machine": platform.platform(), "python": sys.version.split()[0], "load_average_before": load_before,
                "load_average_after": os.getloadavg(), "run_steps": run_steps, "repeats": repeats, "dt": DT,
                "rows": rows}
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(measured, indent=1))
    return measured


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="300 steps per timed run, 3 rounds (default 1000, 7)")
    parser.add_argument("--case", action="append", help="run only this case (repeatable)")
    arguments = parser.parse_args()
    main(arguments.quick, arguments.case)
