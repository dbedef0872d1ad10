"""Per-call cost of ``compiled=True`` when the kernel library is already in the cache (issue 13).

Before: every call rebuilt the symbolic time loop (``ctmm.generated_loop.time_loop_functions``: casadi
``fold`` / ``mapaccum`` and the symbolic calls of the step) and generated the C text only to hash it
into the cache key (reported in issue 13 as seconds per call; see the measurements below).  Now the key is
computed from the serialized step before any of that (:func:`ctmm.generated_loop.compiled_time_loop`)
and a cached library is loaded by its functions' names.

Cases (each in a fresh cache folder): a 1-D chain of 100 masses with a real-time loop
(``benchmarks/chain_compiled.py`` ``model(100)``, ``start(100)``), 1 s at dt = 1e-3, ``method="rk4"``
and ``method="newmark"``; a planar pendulum chain of 10 links (RK4, 1 s at 1e-3); a spatial revolute
chain of 6 and of 16 links (RK4, 1 s at 1e-3); a three-mass chain with a PID on the generated Newmark; a planar pendulum chain of 40 links (folded, RK4, 1 s at
1e-3; session 8); the
16-link chain with a real-time loop in the step and a PID co-simulated every 10 steps (0.2 s).  Rows: first
call (generate + compile), then the best of seven further calls (library from the cache), each as the whole
``ctmm.simulate`` wall time, its CPU time (``time.process_time``: less sensitive to other jobs on the machine) and as
``result.info["compile_time_s"]`` (building the kernel object: symbols, key, loading; the part this
change acts on), and whether the further calls return the first call's numbers bit for bit.
The machine is shared (2 cores, other jobs): whole-call times vary by tens of per cent between runs.

Measured 2026-11-25 (2-core machine shared with other jobs; ``before1/2``: commit 83628ad, ``after1/2``:
this change, alternated; best CPU time of a cached call over both runs, before -> after): chain 100 +
loop RK4 0.094 -> 0.088 s, Newmark 0.098 -> 0.087 s, planar 10 links 0.031 -> 0.025 s, spatial 6
links 0.040 -> 0.032 s, spatial 16 links 0.098 -> 0.087 s; results bit for bit equal.  On this commit
the rebuild this change removes was already small (measured apart, best of 5 CPU: time loop + C text
+ hash 7.9 / 19.8 ms -> serialize + hash 2.8 / 9.2 ms for the spatial 6 / 16 links; the chain's time
loop 3-11 ms, its C text 3-14 ms), so the gain is 6-20 % of a whole call; the seconds per
call of the report did not reproduce on this commit.  What a cached
call still pays: building the symbolic rates and step (the key needs them: 30-50 ms for the spatial
chains), the chain's affine-form certification and the results' post-processing.

Session 7 (keys on a description, :mod:`ctmm.model_description`, before any symbol is built: spatial scenes and
controlled spatial kernels with constant numbers, the chain DT-TMM schemes; new cases ``chain3_newmark_pid``, a
three-mass chain on the generated Newmark with a PID co-simulated every 10 steps (refused before), and
``spatial16_loop_pid``).  Measured 2026-11-25 (``session7_before4/5``: commit 5057868, ``session7_after3/4``: this
change, alternated, the machine quiet; best of 7 cached calls, before -> after, both runs; kernel =
``info["compile_time_s"]``, CPU of the whole call): spatial 6 links kernel 25 -> 2.3-2.5 ms, CPU 33 -> 10-11 ms;
spatial 16 links kernel 64 -> 3.5 ms, CPU 88-92 -> 27-28 ms; spatial 16 links + loop + PID kernel 60-62 -> 9-10 ms,
CPU 74-76 -> 21-23 ms; chain 100 + loop Newmark kernel 28 -> 27-28 ms, CPU 91-92 -> 90-91 ms (no gain: the step
build it skips is traded for describing the 100-mass model, and the affine form and its certification, which the
run needs, dominate); chain RK4 and planar unchanged (they keep the built step's key); ``chain3_newmark_pid``
cached call 29-30 ms for 1000 steps (kernel 4.1 ms); every cached call bit for bit equal to the first.

Session 8 (planar scenes keyed on their description before any symbol is built, ``numbers="inputs"`` without
the numbers, a hit certified against the numpy sweep; new case ``planar_pendulum40_rk4``, folded).  Measured
2026-11-25 (``session8_before1/2``: commit 3254dc0, ``session8_after1/2``: this change, alternated, load 6-8 on
2 cores; best CPU of 7 cached calls, before -> after): planar 10 links 0.027-0.030 -> 0.009 s, planar 40 links
0.055-0.061 -> 0.035-0.036 s; other cases unchanged; every cached call bit for bit equal to the first.  The
cached ``CompiledScene`` alone (best of 7 CPU): 21 / 27 / 46 ms -> 4.2 / 11 / 24 ms at N = 10 / 40 / 100.

Session 13 (planar DT-TMM schemes, and planar scenes with loops whose numbers are inputs, keyed on their description
before anything is built: the plant without its numbers, its structure key, the scheme options or the loops' constants;
a hit certified against the numpy sweep and, with loops, on the loop sensors; new cases ``planar_pendulum10_newmark``,
0.1 s at 1 ms, and ``planar_pendulum10_loops_rk4``, a real-time PD and a delayed loop, 0.1 s at 1 ms).  Measured
2026-11-26 (``session13_before1/2``: commit 6765695, ``session13_after1/2``: this change, alternated, load 6 on 2
cores; best CPU of 7 cached calls, before -> after): Newmark 0.19-0.27 -> 0.024-0.035 s, loops 0.081-0.086 ->
0.026-0.042 s (kernel 0.13 -> 0.02-0.04 s); first calls 4-6 s wall both; every cached call bit for bit equal to the
first.

Run ``python benchmarks/kernel_cache.py [--label after]``; adds the run under its label to
``benchmarks/results/kernel_cache.json`` (``before``: the same file run from a checkout of the commit
before the change, ``--out`` pointing here).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import ctmm  # noqa: E402
from chain_compiled import model as controlled_chain, start  # noqa: E402
from ctmm import planar, spatial  # noqa: E402


REPEATS = 7


def pendulum_chain(n: int) -> planar.PlanarModel:
    elements: list = [planar.Fixed("ground")]
    for i in range(n):
        elements += [planar.SmoothHinge(f"h{i}"), planar.RigidBody(f"b{i}", mass=1.0, inertia=0.1,
                                                             center_of_mass=(0.5, 0.0), outboard=(1.0, 0.0))]
    return planar.PlanarModel.chain(f"pendulum_{n}", elements, gravity=(0.0, -9.81))


def spatial_chain(n: int, actuated: bool = False) -> spatial.SpatialModel:
    elements: list = []
    for i in range(n):
        elements.append(spatial.SpatialBody(f"l{i}", 1.0, np.diag([0.01, 0.1, 0.1]), (0.5, 0.0, 0.0),
                                            {"end": (1.0, 0.0, 0.0)}))
        elements.append(spatial.Revolute(name=f"j{i}", parent=None if i == 0 else f"l{i - 1}", child=f"l{i}",
                                         point=(0.0, 0.0, 0.0) if i == 0 else "end",
                                         axis=(0.0, 1.0, 0.0) if i % 2 else (0.0, 0.0, 1.0), actuated=actuated))
    return spatial.SpatialModel(f"spatial_{n}", elements, gravity=(0.0, 0.0, -9.81))


def cases() -> dict:
    chain = controlled_chain(100)
    x0 = {f"m{i}": value for i, value in enumerate(start(100))}
    pendulum, long_pendulum = pendulum_chain(10), pendulum_chain(40)
    arm, long_arm = spatial_chain(6), spatial_chain(16)
    arm_q0 = 0.1 * (np.arange(arm.n_positions) % 2)
    long_q0 = 0.1 * (np.arange(long_arm.n_positions) % 2)
    sys.path.insert(0, str(ROOT / "tests"))
    from _controllers_import import load_controllers
    from ctmm.elements import Fixed, Free, Mass, SpringDamper

    pid = load_controllers().PID("m2.x", "m2.force", kp=40.0, ki=10.0, kd=3.0, derivative_filter_time=0.01,
                                 sample_time=0.01, reference=0.01)
    from ctmm.control import Feedback, with_feedback

    arm16 = with_feedback(spatial_chain(16, actuated=True), [Feedback("hold", "j0.angle", "j0.torque", gain=5.0)])
    arm_pid = load_controllers().PID("j1.angle", "j1.torque", kp=4.0, ki=0.0, kd=0.3, derivative_filter_time=0.02,
                                     sample_time=0.01)
    three = ctmm.Chain("three", [Fixed("s"), SpringDamper("k0", 100.0, 0.5), Mass("m0", 1.0),
                                 SpringDamper("k1", 80.0, 0.3), Mass("m1", 1.5), SpringDamper("k2", 60.0, 0.2),
                                 Mass("m2", 1.2), Free("e")])
    return {
        **planar_cases(),
        "chain3_newmark_pid": lambda: ctmm.simulate(three, 1.0, 1e-3, method="newmark", compiled=True,
                                                    x0={"m1": 0.02}, controllers=[pid]),
        "chain100_loop_rk4": lambda: ctmm.simulate(chain, 1.0, 1e-3, method="rk4", compiled=True, x0=x0),
        "chain100_loop_newmark": lambda: ctmm.simulate(chain, 1.0, 1e-3, method="newmark", compiled=True, x0=x0),
        "planar_pendulum10_rk4": lambda: ctmm.simulate(pendulum, 1.0, 1e-3, method="rk4", compiled=True,
                                                       x0=np.full(10, 0.2)),
        "planar_pendulum40_rk4": lambda: ctmm.simulate(long_pendulum, 1.0, 1e-3, method="rk4", compiled=True,
                                                       x0=np.full(40, 0.2)),
        "spatial_revolute6_rk4": lambda: ctmm.simulate(arm, 1.0, 1e-3, method="rk4", compiled=True, x0=arm_q0),
        "spatial_revolute16_rk4": lambda: ctmm.simulate(long_arm, 1.0, 1e-3, method="rk4", compiled=True,
                                                        x0=long_q0),
        "spatial16_loop_pid": lambda: ctmm.simulate(arm16, 0.2, 1e-3, compiled=True, x0=long_q0,
                                                    controllers=[arm_pid]),
    }


def planar_cases() -> dict:
    """Session 13: the planar DT-TMM scheme and a planar scene with loops (their numbers as inputs), keyed before
    anything is built (a design loop's call with another gain finds the same library, as in
    ``tests/test_cached_call.py``)."""
    from ctmm.control import Feedback, with_feedback

    pendulum = pendulum_chain(10)

    def controlled(gain: float) -> object:
        return with_feedback(pendulum_chain(10), [
            Feedback("pd", [("h0.angle", 8.0), ("h0.rate", 1.0)], "h0.torque", gain=gain),
            Feedback("late", [("b9.theta", 3.0)], "h5.torque", gain=0.5, delay=4e-3)])

    return {
        "planar_pendulum10_newmark": lambda: ctmm.simulate(pendulum, 0.1, 1e-3, method="newmark", compiled=True,
                                                           x0=np.full(10, 0.2)),
        "planar_pendulum10_loops_rk4": lambda: ctmm.simulate(controlled(1.0), 0.1, 1e-3, compiled=True,
                                                             x0=np.full(10, 0.2)),
    }


def states(result) -> np.ndarray:
    """Every stored signal, one column each (a spatial result's ``states`` is empty)."""
    return np.concatenate([np.ravel(np.asarray(result[name], dtype=float)) for name in sorted(result.signals())])


def main(label: str, out: Path) -> dict:
    rows = []
    for case, run in cases().items():
        with tempfile.TemporaryDirectory() as folder:
            os.environ["CTMM_CACHE"] = folder
            began = time.perf_counter()
            try:
                result = run()
            except ctmm.ModelError as exc:          # a case this checkout refuses (before a feature)
                rows.append({"case": case, "refused": str(exc)[:200]})
                print(f"{case:24s} refused: {str(exc)[:100]}", flush=True)
                continue
            first_s, first = time.perf_counter() - began, states(result)
            first_kernel_s = result.info.get("compile_time_s", float("nan"))
            again, cpu, kernel = [], [], []
            equal = True
            for _ in range(REPEATS):
                began, began_cpu = time.perf_counter(), time.process_time()
                result = run()
                again.append(time.perf_counter() - began)
                cpu.append(time.process_time() - began_cpu)
                kernel.append(result.info.get("compile_time_s", float("nan")))
                equal &= bool(np.array_equal(states(result), first, equal_nan=True))
            row = {"case": case, "first_call_s": first_s, "first_kernel_s": first_kernel_s,
                   "cached_call_s": min(again), "cached_call_cpu_s": min(cpu),
                   "cached_kernel_s": min(kernel), "results_equal": equal}
            rows.append(row)
            print(f"{case:24s} first {first_s:7.3f} s (kernel {first_kernel_s:7.3f} s)  cached "
                  f"{row['cached_call_s']:7.3f} s (cpu {row['cached_call_cpu_s']:7.3f} s, kernel "
                  f"{row['cached_kernel_s']:7.4f} s)  equal {equal}", flush=True)
    os.environ.pop("CTMM_CACHE", None)
    measured = json.loads(out.read_text()) if out.exists() else {}
    measured[label] = {"machine": platform.platform(), "python": sys.version.split()[0], "rows": rows}
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(measured, indent=1))
    return measured


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--label", default="after", help="name of this run in the results file (default 'after')")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results" / "kernel_cache.json")
    arguments = parser.parse_args()
    main(arguments.label, arguments.out)
