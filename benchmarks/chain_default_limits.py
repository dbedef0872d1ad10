"""End to end, cold cache: does ``compiled=None`` gain from the generated path on long 1-D chains? (issue 13).

:func:`ctmm.compiled_default.default_refusal` sends a fixed-step run of at least
:data:`~ctmm.compiled_default.MINIMUM_STEPS` steps to the generated path up to a chain size that depends on the
chain's kind (:data:`~ctmm.compiled_default.MAXIMUM_CHAIN_POINTS`,
:data:`~ctmm.compiled_default.MAXIMUM_BANDED_CHAIN_POINTS`). This benchmark measures the banded kind (every moving
point a mass, no inerters, fixed supports: the generated set-up is ``O(n)``, ``benchmarks/chain_setup_scaling.py``)
at its sizes: the chain of ``benchmarks/chain_compiled.py`` (``Fixed - [k, c] - m_0 - ... - m_{n-1} - Free``, n = 1
000, 2 500, 5 000 and 10 000 masses: 2 001, 5 001, 10 001 and 20 001 points), plain, with its real-time loop ``u =
-500 x_{n-1}`` on ``m_0`` and with that loop delayed by :data:`DELAY_STEPS` steps, on RK4 and on Newmark (a DT-TMM
scheme), dt = 1e-4 s, a run of ``MINIMUM_STEPS`` steps.

Every case runs in a fresh process with an empty ``CTMM_CACHE`` folder (cold: generate and compile) and its address
space capped at :data:`MEMORY_LIMIT_GB`.  CPU time is the process's ``time.process_time`` plus its children's
(``RUSAGE_CHILDREN``: the C compiler), so that a compile is counted whole.

* ``generated_cpu_s``: ``compiled=True``, the whole run (set-up, generate, compile, ``MINIMUM_STEPS`` steps) stored
  every :data:`STORE_EVERY` th step; ``compile_time_s`` from its ``info``.
* ``numpy_cpu_s``: ``compiled=False`` (each call on a fresh model) for :data:`SHORT_STEPS` and the whole run is
  **extrapolated** from them, ``T(s1) + (MINIMUM_STEPS - s1) (T(s2) - T(s1)) / (s2 - s1)``: its per-step cost is
  constant (a fixed step of a linear chain) and a whole numpy run at 20 002 points would take hours; the short runs
  store every step (the numpy DT-TMM path has no ``store_every``). Before them (and before the generated run) a
  numpy run of a 5-mass chain, not counted, imports the modules both paths use (which favours the numpy path
  slightly). ``numpy_setup_cpu_s`` and ``numpy_step_cpu_s`` are the two parts.
* ``speedup``: ``numpy_cpu_s / generated_cpu_s`` (> 1: the generated path is faster end to end).
* ``error``: the largest difference of the positions of the generated run at step ``s2`` (a stored row) to the numpy
  run's last row, relative to the largest of the latter (the round-off contract).

The load average is recorded per case: the machine is shared (2 cores, other work running), CPU times vary by
tens of per cent between runs.  Run ``python benchmarks/chain_default_limits.py [--sizes 1000 2500 5000 10000]
[--label after]``; adds the run under its label to ``benchmarks/results/chain_default_limits.json``.

Measured 2026-11-26 (session 12, one sample per case, cold cache, load average 4-12 on 2 cores shared with other
work; only n = 10 000 masses, 20 001 points, in the time available; ``benchmarks/results/chain_default_limits.json``):

* plain chain, RK4: generated 42.2 s CPU (compile 207 s of wall time under load), numpy 29.1 s (set-up 24.3 s,
  0.96 ms per step): **0.69x**, the generated path slower; error 0 (bit for bit at step 50).
* plain chain, Newmark: generated 28.5 s CPU (compile 110 s wall), numpy set-up 21.6 s and a per-step cost below the
  variation of the set-up between two calls (the 50-step call took 1.6 s less than the 10-step one): not faster;
  error 3.5e-16.
* real-time loop, RK4: generated 57.5 s CPU, numpy 229.9 s (set-up 27.5 s, 40.5 ms per step: the closed-loop driver):
  **4.0x**; error 0.
* real-time loop, Newmark: generated 39.2 s CPU, numpy 17 150 s (set-up 30.7 s, 3.42 s per step: the loop-closing
  DT-TMM step in Python): **438x**; error 3.5e-16.

So a plain banded chain gains nothing above the old limit (its numpy run is one sparse mat-vec per stage or a banded
solve per step, against a compile that grows with the chain), a banded chain with feedback loops gains 4x at 20 001
points with RK4 and 438x with Newmark: the default's banded limit applies to chains with loops. Not measured here: 2
001 to 10 001 points and the delayed loop (its numpy step is that of the real-time loop plus the ring of samples).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "chain_default_limits.json"
MEMORY_LIMIT_GB = 6.0
"""Address space of one case's process [GB] (the machine is shared)."""
CPU_LIMIT_S = 1200
"""CPU time of one case's process [s]."""
STORE_EVERY = 50
"""Stored every this many steps in the whole generated run (and in the numpy RK4 runs) [-]."""
SHORT_STEPS = {"rk4": (10, 500), "newmark": (10, 50)}
"""Step counts of the numpy runs the whole run's time is extrapolated from, per method [-] (the second a multiple of
:data:`STORE_EVERY`: the generated run's stored row there is compared with it; RK4's numpy step is cheap, its
difference must stand out of the set-up's variation under load)."""
DELAY_STEPS = 10
"""Delay of the delayed loop in steps of dt [-]."""
LOOPS = ("none", "realtime", "delayed")
METHODS = ("rk4", "newmark")

CHILD = r"""
import json, resource, sys, time
resource.setrlimit(resource.RLIMIT_AS, (int({limit} * 2**30),) * 2)
resource.setrlimit(resource.RLIMIT_CPU, ({cpu},) * 2)
sys.path.insert(0, {benchmarks!r})
import numpy as np
import ctmm
from ctmm.compiled_default import MINIMUM_STEPS
from ctmm.control import ControlledChain, Feedback
from chain_compiled import DT, GAIN, model, start
n, method, loop = {n}, {method!r}, {loop!r}

def system():
    plant = model(n).plant
    if loop == "none":
        return plant
    delay = {delay} * DT if loop == "delayed" else 0.0
    return ControlledChain(plant, [Feedback("tip", f"m{{n - 1}}.x", "m0", gain=GAIN, delay=delay)])

def cpu():
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime

x0 = {{f"m{{i}}": float(value) for i, value in enumerate(start(n))}}
names = [f"m{{i}}.x" for i in range(n)]

def run(steps, compiled, every):
    options = {{"store_every": every}} if every != 1 else {{}}
    began = cpu()
    result = ctmm.simulate(system(), steps * DT, DT, method=method, x0=x0, compiled=compiled, **options)
    return result, cpu() - began

def positions(result):
    return np.column_stack([result[name] for name in names])

row = {{"steps": MINIMUM_STEPS}}
try:
    warm = ctmm.simulate(model(5).plant, {short}[0] * DT, DT, method=method, compiled=False)   # imports, first use
    generated, row["generated_cpu_s"] = run(MINIMUM_STEPS, True, {every})
    row["compile_time_s"] = generated.info.get("compile_time_s")
    row["generated_path"] = generated.info.get("path")
    s1, s2 = {short}
    _, first = run(s1, False, 1)
    reference, second = run(s2, False, 1)
    per_step = (second - first) / (s2 - s1)
    row["numpy_setup_cpu_s"] = first - s1 * per_step
    row["numpy_step_cpu_s"] = per_step
    row["numpy_cpu_s"] = first + (MINIMUM_STEPS - s1) * per_step
    row["speedup"] = row["numpy_cpu_s"] / row["generated_cpu_s"]
    expected = positions(reference)[-1]
    stored = np.asarray(generated.time)
    at = int(np.argmin(np.abs(stored - s2 * DT)))
    assert abs(stored[at] - s2 * DT) < 1e-9 * DT * s2 + 1e-12, (stored[:3], s2 * DT)
    row["error"] = float(np.max(np.abs(positions(generated)[at] - expected)) / np.max(np.abs(expected)))
except MemoryError:
    row["stopped"] = "MemoryError (address space capped at {limit} GB)"
print("ROW " + json.dumps(row))
"""


def case(n: int, method: str, loop: str) -> dict:
    """One case in a fresh process with an empty kernel cache."""
    with tempfile.TemporaryDirectory(prefix="ctmm-chain-limits-") as cache:
        code = CHILD.format(limit=MEMORY_LIMIT_GB, cpu=CPU_LIMIT_S, benchmarks=str(ROOT / "benchmarks"), n=n,
                            method=method, loop=loop, delay=DELAY_STEPS, every=STORE_EVERY,
                            short=SHORT_STEPS[method])
        environment = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg",
                       "CTMM_CACHE": cache}
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=environment)
    rows = [line[4:] for line in done.stdout.splitlines() if line.startswith("ROW ")]
    row = json.loads(rows[-1]) if rows else {"stopped": f"exit {done.returncode}: {done.stderr.strip()[-300:]}"}
    return {"n": n, "points": 2 * n + 1, "method": method, "loop": loop, **row}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--label", default="after")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 2500, 5000, 10000])
    parser.add_argument("--methods", nargs="+", default=list(METHODS))
    parser.add_argument("--loops", nargs="+", default=list(LOOPS))
    parser.add_argument("--out", type=Path, default=OUT)
    arguments = parser.parse_args()
    rows = []
    for n in arguments.sizes:                       # in the order given
        for method in arguments.methods:
            for loop in arguments.loops:
                row = case(n, method, loop)
                row["load_average"] = list(os.getloadavg())
                rows.append(row)
                print(json.dumps(row), flush=True)
                stored = json.loads(arguments.out.read_text()) if arguments.out.exists() else {}
                stored[arguments.label] = {"machine": platform.platform(), "python": platform.python_version(),
                                           "store_every": STORE_EVERY, "short_steps": SHORT_STEPS, "rows": rows}
                arguments.out.parent.mkdir(parents=True, exist_ok=True)
                arguments.out.write_text(json.dumps(stored, indent=1) + "\n")     # after every case


if __name__ == "__main__":
    main()
