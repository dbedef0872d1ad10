"""Where the generated DT-TMM schemes of planar and spatial models pay: CPU per step against the numpy stepper.

The generated Newton step of spatial schemes (:mod:`ctmm.compiled_spatial_schemes`) and of planar schemes the
implicit sweep does not cover forms its ``n x n`` tangent (``2 n`` directional derivatives of the sweep beyond
:data:`ctmm.mapped_tangent.MAPPED_MIN_COORDINATES`) and factors it: O(N^2 .. N^3) per Newton iteration.  Planar
schemes with linear hinge laws and no modal bodies iterate from 8 coordinates with one implicit articulated sweep
per iterate (:mod:`ctmm.compiled_sweep_newton`, O(N)): the planar rows from N = 10 on measure that iteration.
The numpy steppers iterate on the transfer form (planar: one linearised articulated sweep per iteration, O(N);
spatial: the sweep tangent, :func:`ctmm.spatial.implicit.simulate_spatial_implicit`).  So the generated step wins
on small models by far and loses on large ones; this benchmark finds the crossover that
:data:`ctmm.compiled_default.SCHEME_MAXIMUM_COORDINATES` and ``SCHEME_MAXIMUM_VELOCITIES`` are read from.

Models: planar pendulum chains of N uniform links on smooth hinges (``planar_chain.chain``, start horizontal at
rest) and spatial revolute zig-zag chains (``spatial_chain.ctmm_model``, axes alternating y / z, start at rest),
Newmark, ``dt`` = 1 ms, both through ``ctmm.simulate(..., method="newmark", compiled=True | False)`` in the same
run:

* ``first_call_cpu_s`` -- the first generated call (build, generate C, gcc in a fresh cache folder, run);
* ``cached_call_cpu_s`` -- a second 2-step call (the library in the cache): what every call pays once (planar:
  building the step's expressions for the cache key; spatial: the model's description), CPU;
* ``generated_cpu_per_step_s`` -- the generated step on its loaded library (``simulate_scheme_generated`` /
  ``simulate_spatial_scheme_generated`` with the compiled object) over steps worth about :data:`TIMED_CPU_S`;
* ``numpy_cpu_per_step_s`` -- the numpy stepper over :data:`NUMPY_STEPS` steps after a 2-step warm-up (the traced
  rigid sweep built), CPU per step;
* ``ratio`` -- generated / numpy per step (< 1: the generated step is faster);
* ``generated_vs_numpy`` -- max |hinge angle generated - numpy| over the numpy horizon [rad] (round-off expected);
* the 1-minute load average (2 cores shared with other jobs: ratios in the same run are what to compare).

Loops part (:func:`pd_chain`): the planar chains with a real-time PD on every hinge, the loops inside the generated
Newton step (:mod:`ctmm.compiled_scheme_loops`) against the numpy DT-TMM path with the same loops.

CPU time is ``resource.getrusage`` of this process and its finished children (the C compiler).
Run ``python benchmarks/compiled_schemes_default.py [--quick] [--loops]`` (``--loops``: that part alone, merged
into the stored rows); writes
``benchmarks/results/compiled_schemes_default.json``.
"""
from __future__ import annotations

import contextlib
import json
import os
import platform
import resource
import sys
import tempfile
from pathlib import Path
from typing import Iterator

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
for path in (ROOT, ROOT / "benchmarks"):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

import ctmm  # noqa: E402

DT = 1e-3
NUMPY_STEPS = 20
TIMED_CPU_S = 0.5
PLANAR_SIZES = (2, 5, 10, 12, 15, 20, 40, 80, 150, 300)
SPATIAL_SIZES = (2, 3, 5, 10)
"""(N = 20: gcc passed its 600 s wall-clock limit on the generated Newmark, load ~15 on 2 cores, session 12.)"""
LOOP_SIZES = (3, 15, 30)
QUICK_PLANAR, QUICK_SPATIAL, QUICK_LOOPS = (5, 20), (3,), (3,)


def cpu() -> float:
    """CPU time [s] of this process and its finished children (the C compiler)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


@contextlib.contextmanager
def fresh_cache() -> Iterator[None]:
    """``$CTMM_CACHE`` set to a new empty folder inside the block (first compiles), restored after it."""
    previous = os.environ.get("CTMM_CACHE")
    os.environ["CTMM_CACHE"] = tempfile.mkdtemp(prefix="ctmm-bench-")
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop("CTMM_CACHE", None)
        else:
            os.environ["CTMM_CACHE"] = previous


def planar_model(n: int):
    from planar_chain import chain

    return chain(n)


def spatial_model(n: int):
    from spatial_chain import ctmm_model

    return ctmm_model(n, "revolute")


def coordinates(result) -> np.ndarray:
    """The stored hinge angles of a result [rad], (steps, hinges)."""
    names = [name for name in result.signals() if name.endswith((".theta", ".angle"))]
    return np.column_stack([np.asarray(result[name], dtype=float) for name in names])


def generated_per_step(kind: str, model, scheme: str) -> tuple[float, np.ndarray]:
    """CPU per step [s] of the generated step on its compiled library (loaded from the cache), over enough steps
    for about :data:`TIMED_CPU_S` of CPU, and the hinge angles of its first :data:`NUMPY_STEPS` steps."""
    from ctmm.compiled_scene_schemes import CompiledSceneScheme, simulate_scheme_generated
    from ctmm.compiled_spatial_schemes import CompiledSpatialScheme, simulate_spatial_scheme_generated

    if kind == "planar":
        compiled, zero = CompiledSceneScheme(model, scheme), np.zeros(model.n_coordinates)

        def run(steps: int) -> np.ndarray:
            return simulate_scheme_generated(model, zero, zero, t_final=steps * DT, dt=DT, scheme=scheme,
                                             compiled=compiled, stability_check="ignore").q
    else:
        compiled = CompiledSpatialScheme(model, scheme)

        def run(steps: int) -> np.ndarray:
            return coordinates(simulate_spatial_scheme_generated(model, steps * DT, DT, scheme=scheme,
                                                                 compiled=compiled))
    began = cpu()
    angles = run(NUMPY_STEPS)
    estimate = max((cpu() - began) / NUMPY_STEPS, 1e-7)
    steps = int(min(max(TIMED_CPU_S / estimate, NUMPY_STEPS), 20000))
    began = cpu()
    run(steps)
    return (cpu() - began) / steps, angles


def numpy_per_step(kind: str, model, scheme: str) -> tuple[float, np.ndarray]:
    """CPU per step [s] of the numpy stepper over :data:`NUMPY_STEPS` steps after a 2-step warm-up (the traced
    sweeps built) and its hinge angles (planar: :func:`ctmm.planar.simulate_implicit`, what ``compiled=False`` runs,
    coordinates in the model's order; spatial: ``ctmm.simulate(..., compiled=False)``)."""
    from ctmm.planar import simulate_implicit

    if kind == "planar":
        zero = np.zeros(model.n_coordinates)

        def run(steps: int) -> np.ndarray:
            return simulate_implicit(model, zero, zero, t_final=steps * DT, dt=DT, scheme=scheme,
                                     stability_check="ignore").q
    else:
        def run(steps: int) -> np.ndarray:
            return coordinates(ctmm.simulate(model, steps * DT, DT, method=scheme, compiled=False))
    run(2)
    began = cpu()
    angles = run(NUMPY_STEPS)
    return (cpu() - began) / NUMPY_STEPS, angles


def measure(kind: str, n: int, scheme: str = "newmark") -> dict:
    """One row (module docstring)."""
    model = planar_model(n) if kind == "planar" else spatial_model(n)
    options = dict(method=scheme, stability_check="ignore") if kind == "planar" else dict(method=scheme)
    with fresh_cache():
        began = cpu()
        ctmm.simulate(model, 2 * DT, DT, compiled=True, **options)
        first = cpu() - began
        began = cpu()
        ctmm.simulate(model, 2 * DT, DT, compiled=True, **options)
        call = cpu() - began
        generated_step, generated = generated_per_step(kind, model, scheme)
    numpy_step, angles = numpy_per_step(kind, model, scheme)
    difference = float(np.max(np.abs(generated - angles)))
    return result_row(kind, n, scheme, first, generated_step, numpy_step, difference, call)


def result_row(kind: str, n: int, scheme: str, first: float, generated_step: float, numpy_step: float,
               difference: float, call: float | None = None) -> dict:
    """The JSON row (module docstring), printed."""
    row = {"kind": kind, "n_bodies": n, "scheme": scheme, "dt_s": DT, "first_call_cpu_s": first,
           **({} if call is None else {"cached_call_cpu_s": call}), "generated_cpu_per_step_s": generated_step,
           "numpy_cpu_per_step_s": numpy_step, "ratio": generated_step / numpy_step,
           "generated_vs_numpy": difference, "load_average_1min": os.getloadavg()[0]}
    cached = "" if call is None else f"  cached call {call:5.2f} s"
    print(f"{kind:15s} N={n:3d} first call {first:6.2f} s{cached}  generated {generated_step * 1e6:9.1f} us/step  "
          f"numpy {numpy_step * 1e6:9.1f} us/step  ratio {row['ratio']:7.3f}  |gen - numpy| {difference:.1e}  load "
          f"{row['load_average_1min']:.1f}", flush=True)
    return row


def pd_chain(n: int):
    """The pendulum chain with a real-time PD on every hinge (``u = -(20 angle + 2 rate)``), a ControlledModel."""
    from ctmm.control import ControlledModel, Feedback

    loops = [Feedback("pd0", [("link0.theta", 20.0), ("link0.omega", 2.0)], "base.torque", gain=1.0)]
    loops += [Feedback(f"pd{i}", [(f"h{i}.angle", 20.0), (f"h{i}.rate", 2.0)], f"h{i}.torque", gain=1.0)
              for i in range(1, n)]
    return ControlledModel(planar_model(n), loops)


def measure_loops(n: int, scheme: str = "newmark") -> dict:
    """The row of :func:`pd_chain`: first generated call (fresh cache), CPU per step of a cached generated call and of
    the numpy DT-TMM path with the same loops (both through ``ctmm.simulate``, differences of two run lengths, so
    the calls' set-up cancels), max |hinge angle difference| over the numpy horizon."""
    controlled = pd_chain(n)

    def per_step(compiled: bool, steps: int) -> tuple[float, object]:
        began = cpu()
        short = ctmm.simulate(controlled, steps * DT, DT, method=scheme, compiled=compiled)
        middle = cpu()
        ctmm.simulate(controlled, 3 * steps * DT, DT, method=scheme, compiled=compiled)
        return (cpu() - 2 * middle + began) / (2 * steps), short
    with fresh_cache():
        began = cpu()
        ctmm.simulate(controlled, 2 * DT, DT, method=scheme, compiled=True)
        first = cpu() - began
        generated_step, generated = per_step(True, 2000)
    numpy_step, numpy_run = per_step(False, NUMPY_STEPS)
    difference = float(np.max(np.abs(coordinates(generated)[:NUMPY_STEPS + 1] - coordinates(numpy_run))))
    return result_row("planar_pd_loops", n, scheme, first, generated_step, numpy_step, difference)


def rows(quick: bool = False) -> list[dict]:
    """Every row: planar, spatial, then planar with loops."""
    planar, spatial = (QUICK_PLANAR, QUICK_SPATIAL) if quick else (PLANAR_SIZES, SPATIAL_SIZES)
    return [measure("planar", n) for n in planar] + [measure("spatial", n) for n in spatial] + \
        [measure_loops(n) for n in (QUICK_LOOPS if quick else LOOP_SIZES)]


def main() -> None:
    quick = "--quick" in sys.argv[1:]
    path = ROOT / "benchmarks" / "results" / "compiled_schemes_default.json"
    if "--loops" in sys.argv[1:]:           # the loops part alone, the other stored rows kept
        kept = json.loads(path.read_text())["rows"] if path.exists() else []
        measured = [row for row in kept if row["kind"] != "planar_pd_loops"] + \
            [measure_loops(n) for n in (QUICK_LOOPS if quick else LOOP_SIZES)]
    else:
        measured = rows(quick)
    out = {"benchmark": "compiled_schemes_default", "machine": platform.platform(),
           "python": platform.python_version(), "quick": quick, "rows": measured}
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
