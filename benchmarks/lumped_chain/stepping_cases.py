"""Case (b) of ``foundation_scaling``: Newmark time steps of the chain by ctmm's paths and by global Newmark.

The chain of :mod:`lumped_chain.model` (free lengths 0), initial displacement x_i(0) = 0.01 sin(pi i / (2 n)) m, zero
velocity, constant ``FORCE`` = 100 N on m1, Newmark(1/4, 1/2), dt = 1e-4 s, ``N_STEPS`` = 200 steps.  Methods:

* ``ctmm``            -- ``ctmm.simulate(method="newmark")`` as a user calls it (default options; ``path`` from
                         ``info["path"]``: the lumped DT-TMM path in numpy);
* ``ctmm_generic``    -- the same with ``fast=False`` (the elements' own step matrices);
* ``ctmm_compiled``   -- the same with ``compiled=True`` (the generated DT-TMM Newmark in C; first-call and compile
                         times recorded apart; the timed calls find the library in the disk cache, their set-up per
                         call is ``setup_per_call_s`` and the loop alone ``loop_time_per_step_s``);
* ``global_banded`` / ``global_dense`` -- :func:`ctmm.reference.chain.newmark_global` (banded / dense factorisation;
                         it still does dense O(n^2) mat-vecs every step);
* ``global_banded_linear`` -- :func:`lumped_chain.global_baselines.global_newmark_banded_linear`, the O(n) global
                         baseline (final displacements only).

Time per step = whole call / steps (wall and CPU); ``max_difference_m`` = max |x - x_banded| [m] over all masses and
the steps both ran.  A method whose probe (5 steps) extrapolates beyond ``BUDGET_S`` runs fewer steps
(``reduced_steps``).
"""
from __future__ import annotations

import numpy as np

import ctmm
from ctmm.reference import chain as reference  # (benchmarks may use the validation models)

from .global_baselines import global_newmark_banded_linear
from benchmark_support.measure import timed
from .model import FORCE, ctmm_chain, global_chain

DT, N_STEPS = 1e-4, 200    # [s], steps
BUDGET_S = 120.0           # a method estimated above this [s] runs fewer steps
COMPILED_UP_TO = 1000      # compiled=True above this many masses is not run (set-up memory, see compile_first)


def initial_displacements(n: int) -> np.ndarray:
    """x_i(0) = 0.01 sin(pi i / (2 n)) [m], i = 1 ... n."""
    return 0.01 * np.sin(np.pi * np.arange(1, n + 1) / (2 * n))


def stepping_case(n: int, *, run_big_baselines: bool = True) -> dict:
    """Time per step and difference to the banded global Newmark of every method of the module docstring."""
    system = ctmm_chain(n)
    glob = global_chain(n)
    x0 = initial_displacements(n)
    x0_map = {f"m{j}": float(x0[j - 1]) for j in range(1, n + 1)}
    force = np.zeros(n)
    force[0] = FORCE
    case: dict = {"n": n, "dt": DT, "methods": {}}

    def ctmm_run(steps, **options):
        return ctmm.simulate(system, steps * DT, DT, method="newmark", x0=x0_map, progress=False, **options)

    def ref_run(steps, banded):
        return reference.newmark_global(glob, steps * DT, DT, x0, np.zeros(n), lambda t: force, banded=banded)

    first = compile_first(case, n, lambda: ctmm_run(N_STEPS, compiled=True))
    runs_spec = [
        ("ctmm", lambda s: ctmm_run(s), None),
        ("ctmm_generic", lambda s: ctmm_run(s, fast=False), None),
        ("ctmm_compiled", lambda s: ctmm_run(s, compiled=True), None if first else 0),
        ("global_banded", lambda s: ref_run(s, True), 20_000),
        ("global_dense", lambda s: ref_run(s, False), 3000),
        ("global_banded_linear", lambda s: global_newmark_banded_linear(glob, s, DT, x0, np.zeros(n), force), None),
    ]
    finals = {}
    for key, call, skip_above in runs_spec:
        entry: dict = case["methods"].setdefault(key, {})
        if skip_above is not None and (n > skip_above or not run_big_baselines):
            entry.update({"skipped": True, "time_per_step_s": None})
            continue
        probe_steps = 5
        _, t_probe, _, _ = timed(lambda: call(probe_steps), repeat_until=0.0, max_repeats=1)
        estimate = t_probe / probe_steps * N_STEPS
        steps = N_STEPS if estimate <= BUDGET_S else max(probe_steps, int(BUDGET_S / 4 / (t_probe / probe_steps)))
        out, wall, cpu, runs = timed(lambda: call(steps), repeat_until=1.0 if estimate < 30 else 0.0)
        entry.update({"steps": steps, "wall_time_s": wall, "time_per_step_s": wall / steps,
                      "cpu_time_per_step_s": cpu / steps, "runs": runs, "reduced_steps": steps < N_STEPS})
        if key.startswith("ctmm"):
            entry["path"] = out.info.get("path")
            entry["loop_time_per_step_s"] = out.info["wall_time_s"] / steps
            if "compile_time_s" in out.info:                  # generated path: per-call set-up, library cached
                entry["setup_per_call_s"] = out.info["compile_time_s"]
            x_hist = np.column_stack([out[f"m{j}.x"] for j in range(1, n + 1)])
        elif key == "global_banded_linear":
            x_hist = out[None, :]
        else:
            x_hist = out.displacement
        finals[key] = (steps, x_hist)
        print(f"[step n={n}] {key} {wall / steps * 1e3:.3f} ms/step ({steps} steps)", flush=True)
    compare(case, finals)
    return case


def compile_first(case: dict, n: int, call) -> bool:
    """First ``compiled=True`` call (generation, C compile or disk cache, load): its times into the case.

    Not run above ``COMPILED_UP_TO`` masses: the call's set-up (the certification of the chain's affine rates) held
    19 GB at n = 10 000 when it was stopped (about n^2 growth; 2-4 s CPU per call at n = 1000, every call).
    """
    entry = case["methods"].setdefault("ctmm_compiled", {})
    if n > COMPILED_UP_TO:
        entry.update({"skipped": True, "time_per_step_s": None,
                      "reason": f"not run above {COMPILED_UP_TO} masses: the set-up of every call grows about as n^2 "
                                "in memory (19 GB resident at n = 10 000 when stopped, 2-4 s CPU per call at n = 1000)"})
        return False
    try:
        result, wall, cpu, _ = timed(call, max_repeats=1)
    except ctmm.ModelError as error:                       # no C compiler: recorded, not timed
        entry.update({"skipped": True, "time_per_step_s": None, "reason": str(error)})
        return False
    entry.update({"first_call_s": wall, "first_call_cpu_s": cpu,
                  "compile_time_s": result.info.get("compile_time_s")})
    return True


def compare(case: dict, finals: dict) -> None:
    """Differences [m] of every method to ``global_banded`` over the steps both ran (final step for the O(n) one)."""
    ref_steps, ref_hist = finals["global_banded"]
    for key, (steps, x_hist) in finals.items():
        entry = case["methods"][key]
        if key == "global_banded_linear":
            if steps == ref_steps:
                entry["max_difference_m"] = float(np.max(np.abs(x_hist[-1] - ref_hist[-1])))
                entry["compared"] = "final step"
            continue
        common = min(steps, ref_steps) + 1
        entry["max_difference_m"] = float(np.max(np.abs(x_hist[:common] - ref_hist[:common])))
        entry["compared"] = f"all masses, steps 0..{common - 1}"
    case["max_displacement_m"] = float(np.max(np.abs(ref_hist)))
