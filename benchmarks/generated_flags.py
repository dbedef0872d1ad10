"""Compiler flags of the generated kernels: first-compile CPU against run CPU, per kernel family (issue 13).

Every ``compiled=True`` run goes through one library built by :func:`ctmm.generated_loop.compiled_time_loop`
(casadi's straight-line C: long functions of scalar temporaries, no loops to vectorise).  A clean checkout (CI, a
new user) compiles each kernel once; the compiler's share of that first call grows with the C text while the run
of the compiled code barely depends on how hard gcc optimised it.  This benchmark measures both for each flag set.

Cases (the families of the test suite's ~440 kernels, models of ``benchmarks/kernel_cache.py`` and
``benchmarks/kinematic_loops_generated.py``): a 1-D chain of 100 masses with a real-time loop (RK4 and Newmark),
a planar pendulum chain of 10 links (RK4, Newmark, RK4 with a PD and a delayed loop), the planar four-bar
(RK4 with the cut forces and the projection in the step), a spatial revolute chain of 6 links (RK4) and the
R-U-S-R spatial four-bar (RK4 with projection).

Per case and flag set (each in a fresh cache folder): ``compile_cpu_s``, the CPU of the first call (this process
and the compiler it waited for, ``os.times``) minus the CPU of a cached call of the same length (so: building the
expressions, generating the C and compiling it); ``compiler_cpu_s``, the compiler's part alone (children CPU);
``run_cpu_us_per_step``, the CPU spent inside the compiled functions (every call of a loaded kernel timed) per step,
the best of ``REPEATS`` cached calls over ``RUN_STEPS`` steps taken in rounds over the flag sets (interleaved: a
change of the shared machine's load slows every flag set alike); ``call_cpu_us_per_step``, the whole cached call's
CPU per step (with the Python around the kernel: stored signals, checks); ``max_difference``, the largest difference
of every stored signal from the ``-O2`` run (the flags change no number: gcc without ``-ffast-math`` keeps IEEE
order).  Ratios against ``-O2`` in the same run.

The flag set is forced by wrapping :func:`ctmm.codegen.load_casadi_keyed` as
:mod:`ctmm.generated_loop` calls it (the library's choice per family is what the run labelled ``default`` uses).

Measured 2026-11-26 (session 14; load 9-15 on 2 cores from other jobs; 2000 steps, best of 9 rounds; ratios to
``-O2``, gcc CPU / kernel CPU per step): chain 100 + loop RK4 ``-O1`` 0.79 / 1.50, ``-O0`` 0.35 / 4.8; its Newmark
``-O1`` 0.82 / 1.29; planar pendulum N = 10 RK4 ``-O1`` 0.54-0.67 / 1.06-1.16, Newmark 0.67 / 1.23, with a PD and a
delayed loop 0.59-0.64 / 1.00-1.13; planar four-bar 0.60-0.68 / 1.01-1.15; spatial revolute N = 6 0.62-0.68 /
1.09-1.26; spatial four-bar 0.54-0.73 / 0.81; ``-O0`` everywhere 0.25-0.40 / 2.3-4.8.  ``default`` and ``-O1`` are
the same flags for the straight-line families after this session: their difference (up to 15-20 %) is the spread
of the measurement on this machine.  Every stored signal bit for bit equal across the flag sets.  Hence
:data:`ctmm.codegen.STRAIGHT_LINE_FLAGS` (``-O1``) for straight-line RK4 kernels and ``-O2`` for chains and the
DT-TMM schemes.

Run ``python benchmarks/generated_flags.py [--quick]``; writes ``benchmarks/results/generated_flags.json``.
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
from typing import Any, Callable

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import ctmm  # noqa: E402
from ctmm import generated_loop  # noqa: E402
from chain_compiled import model as controlled_chain, start as chain_start  # noqa: E402
from kernel_cache import pendulum_chain, spatial_chain, states  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results" / "generated_flags.json"
FLAG_SETS = {"-O2": ("-O2", "-shared", "-fPIC"), "default": None, "-O1": ("-O1", "-shared", "-fPIC"),
             "-O0": ("-O0", "-shared", "-fPIC")}
DT = 1e-3
RUN_STEPS = 2000
REPEATS = 9


def cases() -> dict[str, Callable[[float], Any]]:
    """``name -> run(t_final)``: one ``ctmm.simulate(..., compiled=True)`` of each family."""
    from ctmm.control import Feedback, with_feedback
    from scenarios import four_bar, spatial_four_bar

    chain = controlled_chain(100)
    x0 = {f"m{i}": value for i, value in enumerate(chain_start(100))}
    pendulum = pendulum_chain(10)
    loops = with_feedback(pendulum_chain(10), [
        Feedback("pd", [("h0.angle", 8.0), ("h0.rate", 1.0)], "h0.torque", gain=1.0),
        Feedback("late", [("b9.theta", 3.0)], "h5.torque", gain=0.5, delay=4e-3)])
    arm = spatial_chain(6)
    arm_q0 = 0.1 * (np.arange(arm.n_positions) % 2)
    planar_loop = four_bar.mechanism()
    planar_q0, planar_v0 = four_bar.start(planar_loop)
    spatial_loop = spatial_four_bar.mechanism()
    spatial_q0, spatial_v0 = spatial_four_bar.start(spatial_loop)
    return {
        "chain100_loop_rk4": lambda t: ctmm.simulate(chain, t, DT, method="rk4", compiled=True, x0=x0),
        "chain100_loop_newmark": lambda t: ctmm.simulate(chain, t, DT, method="newmark", compiled=True, x0=x0),
        "planar_pendulum10_rk4": lambda t: ctmm.simulate(pendulum, t, DT, method="rk4", compiled=True,
                                                         x0=np.full(10, 0.2)),
        "planar_pendulum10_newmark": lambda t: ctmm.simulate(pendulum, t, DT, method="newmark", compiled=True,
                                                             x0=np.full(10, 0.2)),
        "planar_pendulum10_loops_rk4": lambda t: ctmm.simulate(loops, t, DT, compiled=True, x0=np.full(10, 0.2)),
        "planar_four_bar_rk4": lambda t: ctmm.simulate(planar_loop, t, DT, method="rk4", compiled=True,
                                                       x0=planar_q0, v0=planar_v0),
        "spatial_revolute6_rk4": lambda t: ctmm.simulate(arm, t, DT, method="rk4", compiled=True, x0=arm_q0),
        "spatial_four_bar_rk4": lambda t: ctmm.simulate(spatial_loop, t, DT, method="rk4", compiled=True,
                                                        x0=spatial_q0, v0=spatial_v0),
    }


def cpu() -> tuple[float, float]:
    """``(this process, its waited-for children)`` CPU time [s] (user + system)."""
    times = os.times()
    return times.user + times.system, times.children_user + times.children_system


class Timed:
    """A loaded kernel function whose calls add their CPU time [s] to ``spent[0]``; everything else delegated."""

    def __init__(self, function: Any, spent: list[float]) -> None:
        self.function, self.spent = function, spent

    def __call__(self, *arguments: Any) -> Any:
        began = time.process_time()
        try:
            return self.function(*arguments)
        finally:
            self.spent[0] += time.process_time() - began

    def call(self, *arguments: Any) -> Any:
        began = time.process_time()
        try:
            return self.function.call(*arguments)
        finally:
            self.spent[0] += time.process_time() - began

    def buffer(self) -> tuple[Any, Callable[[], None]]:
        """casadi's buffer interface (:class:`ctmm.generated_loop.BlockRunner`), its evaluation timed."""
        buffer, evaluate = self.function.buffer()

        def timed() -> None:
            began = time.process_time()
            evaluate()
            self.spent[0] += time.process_time() - began
        return buffer, timed

    def map(self, *arguments: Any) -> "Timed":
        return Timed(self.function.map(*arguments), self.spent)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.function, name)


def with_flags(flags: tuple[str, ...] | None, spent: list[float]) -> Callable[[], None]:
    """Force ``flags`` on every generated kernel (``None``: the library's own) and time the calls of the loaded
    functions into ``spent[0]``; returns the undo."""
    original = generated_loop.load_casadi_keyed

    def forced(*arguments: Any, **options: Any) -> Any:
        if flags is not None:
            options["flags"] = flags
        return tuple(Timed(function, spent) for function in original(*arguments, **options))
    generated_loop.load_casadi_keyed = forced

    def undo() -> None:
        generated_loop.load_casadi_keyed = original
    return undo


def timed_call(run: Callable[[float], Any], flags: tuple[str, ...] | None, folder: str,
               t_final: float) -> tuple[Any, float, float, float, float]:
    """``(result, own CPU, children CPU, kernel CPU, call CPU)`` [s] of one call of ``run`` with the cache folder
    ``folder`` and the flag set ``flags``."""
    spent = [0.0]
    undo = with_flags(flags, spent)
    os.environ["CTMM_CACHE"] = folder
    try:
        own, children = cpu()
        began = time.process_time()
        result = run(t_final)
        call = time.process_time() - began
        own_after, children_after = cpu()
    finally:
        os.environ.pop("CTMM_CACHE", None)
        undo()
    return result, own_after - own, children_after - children, spent[0], call


def measure(run: Callable[[float], Any], run_steps: int, repeats: int) -> list[dict]:
    """Rows of one case, one per flag set (module docstring): first calls in fresh cache folders, then the cached
    calls of every flag set in turn, ``repeats`` rounds (interleaved, so that a change of the machine's load
    slows every flag set alike), best of them."""
    t_final = run_steps * DT
    with tempfile.TemporaryDirectory() as base:
        folders = {label: tempfile.mkdtemp(dir=base) for label in FLAG_SETS}
        first, rows = {}, {}
        for label, flags in FLAG_SETS.items():
            first[label], own, compiler, _, _ = timed_call(run, flags, folders[label], t_final)
            rows[label] = {"flags": label, "first_call_cpu_s": own + compiler, "compiler_cpu_s": compiler,
                           "kernel": [], "call": []}
        for _ in range(repeats):
            for label, flags in FLAG_SETS.items():
                result, _, _, kernel, call = timed_call(run, flags, folders[label], t_final)
                if not np.array_equal(states(result), states(first[label]), equal_nan=True):
                    raise AssertionError(f"a cached call with {label} differs from its first call")
                rows[label]["kernel"].append(kernel)
                rows[label]["call"].append(call)
    reference = states(first["-O2"])
    for label, row in rows.items():
        kernel, call = row.pop("kernel"), row.pop("call")
        row.update(compile_cpu_s=row.pop("first_call_cpu_s") - min(call),
                   run_cpu_us_per_step=1e6 * min(kernel) / run_steps, call_cpu_us_per_step=1e6 * min(call) / run_steps,
                   max_difference=float(np.max(np.abs(states(first[label]) - reference))))
    base = rows["-O2"]
    for row in rows.values():
        row.update(compile_cpu_ratio=row["compile_cpu_s"] / base["compile_cpu_s"],
                   run_cpu_ratio=row["run_cpu_us_per_step"] / base["run_cpu_us_per_step"])
    return list(rows.values())


def main(quick: bool, only: list[str] | None = None) -> dict:
    run_steps = 1000 if quick else RUN_STEPS
    repeats = 5 if quick else REPEATS
    rows = []
    for case, run in cases().items():
        if only and case not in only:
            continue
        for row in measure(run, run_steps, repeats):
            row["case"] = case
            rows.append(row)
            print(f"{case:28s} {row['flags']:8s} compile {row['compile_cpu_s']:6.2f} s (gcc {row['compiler_cpu_s']:6.2f}"
                  f" s, x{row['compile_cpu_ratio']:.2f})  kernel {row['run_cpu_us_per_step']:7.2f} us/step "
                  f"(x{row['run_cpu_ratio']:.2f}; call {row['call_cpu_us_per_step']:7.1f})  diff "
                  f"{row['max_difference']:.1e}", flush=True)
    measured = {"machine": platform.platform(), "python": sys.version.split()[0], "load_average": os.getloadavg(),
                "run_steps": run_steps, "repeats": repeats, "dt": DT, "rows": rows}
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(measured, indent=1))
    return measured


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1000 steps per timed call, 5 rounds (default 2000, 9)")
    parser.add_argument("--case", action="append", help="run only this case (repeatable)")
    arguments = parser.parse_args()
    main(arguments.quick, arguments.case)
