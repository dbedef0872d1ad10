"""Per-call set-up of ``compiled=True`` on 1-D chains against the chain's size: CPU time and peak memory.

The chain of ``benchmarks/chain_compiled.py`` (``Fixed - [k, c] - m_0 - ... - m_{n-1} - Free``, n = 100, 1 000 and
10 000 masses), plain (``model(n).plant``) and with its real-time loop ``u = -500 x_{n-1}`` on ``m_0``, on the generated
RK4 (:mod:`ctmm.compiled_chain`) and the generated Newmark (:mod:`ctmm.compiled_chain_schemes`), 10 steps of
dt = 1e-4 s stored every 10th: the call is its set-up (the affine form read from the sweep and certified, the
loops' rows, the key, loading the library) and its result.

Every case runs in a fresh process (``--tree``: the ``ctmm`` checkout it imports, e.g. one of the commit before a
change, so that before and after run in the same session) with its address space capped at :data:`MEMORY_LIMIT_GB`
and its CPU at :data:`CPU_LIMIT_S` (a case beyond them is recorded as stopped).  In it: a first call (generates and
compiles, or loads the library from the run's cache folder), then a second call with the library cached, then a
third under ``tracemalloc``.  Rows: ``first_call_cpu_s`` and ``cached_call_cpu_s`` (``time.process_time`` of the
process: the compiler's own time is not in it), ``peak_rss_mb`` (``ru_maxrss`` after the calls minus after the
imports, the whole process), ``cached_call_python_peak_mb`` (the ``tracemalloc`` peak of the third call: the Python
heap of one cached call), and the largest difference of the cached call's stored positions to the first's.  The
load average is recorded: the machine is shared (2 cores), CPU times vary by tens of per cent between runs.

Measured 2026-11-25 (session 11; ``before_5c990b6``: a checkout of commit 5c990b6 by ``--tree``, then ``after``: this
change, one sample each, load average 4-10 on 2 cores).  Cached call, CPU [s], RK4 / RK4 + loop / Newmark / Newmark +
loop: n = 100 0.19 / 0.16 / 0.16 / 0.16 -> 0.10 / 0.19 / 0.09 / 0.14; n = 1000 1.31 / 2.08 / 1.54 / 2.03 -> 0.91 / 1.38
/ 0.87 / 0.76; n = 10 000 stopped by the 4 GB cap (3.07 GB resident; 19 GB seen uncapped) -> 7.6 / 14.5 / 7.3 / 10.9.
Peak RSS [MB]: 18-21 -> 17-21 at n = 100, 221-229 -> 29-47 at 1000, > 3070 -> 138-324 at 10 000; Python heap of one
cached call 2.3 -> 0.6-1.4, 189 -> 6-14, ... -> 64-138 MB.  Before, the affine form probed every state at once (a
``(1 + 2 m) x n`` batch through the sweep); now it comes from the certified tridiagonal rates (three probes), so the
call is a fixed number of sweeps of ``O(n)`` each (about 0.2 ms of CPU per node per sweep: the numpy path's own
set-up of the same 10-step RK4 call is 7.5 s at n = 10 000).  At n = 100 the RK4 with its loop makes a few more
(small) sweeps than the one batched probe did.  First call at n = 10 000 (generate and compile, wall-clock of the
kernel object): 10-24 s.  Cached calls equal the first bit for bit.  Measured apart (same session, load ~6): the
base-excited chain of ``tests/test_compiled_chain_setup.py`` (harmonic start and end motion, a harmonic force; the
condensed form, one sweep per state before) on the generated RK4, cached call 21.4 s -> 0.27 s CPU at n = 300, 0.7 s
at n = 1000.

Run ``python benchmarks/chain_setup_scaling.py [--label after] [--tree PATH] [--sizes 100 1000 10000]``; adds the
run under its label to ``benchmarks/results/chain_setup_scaling.json``.
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
OUT = ROOT / "benchmarks" / "results" / "chain_setup_scaling.json"
MEMORY_LIMIT_GB = 4.0
"""Address space of one case's process [GB] (the machine is shared)."""
CPU_LIMIT_S = 600
"""CPU time of one case's process [s]."""
STEPS = 10
CASES = [(method, loop) for method in ("rk4", "newmark") for loop in (False, True)]

CHILD = r"""
import json, os, resource, sys, time, tracemalloc
resource.setrlimit(resource.RLIMIT_AS, (int({limit} * 2**30),) * 2)
resource.setrlimit(resource.RLIMIT_CPU, ({cpu},) * 2)
sys.path.insert(0, {benchmarks!r})
import numpy as np
import ctmm
from chain_compiled import DT, model, positions, start
n, method, loop = {n}, {method!r}, {loop}
system = model(n) if loop else model(n).plant
x0 = {{f"m{{i}}": float(value) for i, value in enumerate(start(n))}}
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss

def call():
    began = time.process_time()
    result = ctmm.simulate(system, {steps} * DT, DT, method=method, x0=x0, compiled=True, store_every={steps})
    return result, time.process_time() - began

row = {{}}
try:
    first, row["first_call_cpu_s"] = call()
    again, row["cached_call_cpu_s"] = call()
    row["compile_time_s"] = again.info["compile_time_s"]
    row["peak_rss_mb"] = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024.0
    tracemalloc.start()
    call()
    row["cached_call_python_peak_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    row["cached_vs_first_m"] = float(np.max(np.abs(positions(again, n) - positions(first, n))))
    row["path"] = again.info.get("path")
except MemoryError:
    row["stopped"] = "MemoryError (address space capped at {limit} GB)"
    row["peak_rss_mb"] = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024.0
print("ROW " + json.dumps(row))
"""


def case(tree: Path, n: int, method: str, loop: bool, cache: str) -> dict:
    """One case in a fresh process importing ``ctmm`` from ``tree``."""
    code = CHILD.format(limit=MEMORY_LIMIT_GB, cpu=CPU_LIMIT_S, benchmarks=str(ROOT / "benchmarks"), n=n,
                        method=method, loop=loop, steps=STEPS)
    environment = {**os.environ, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg",
                   "CTMM_CACHE": cache}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=environment)
    rows = [line[4:] for line in done.stdout.splitlines() if line.startswith("ROW ")]
    row = json.loads(rows[-1]) if rows else {"stopped": f"exit {done.returncode}: {done.stderr.strip()[-300:]}"}
    return {"n": n, "method": method, "loop": loop, **row}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--label", default="after")
    parser.add_argument("--tree", type=Path, default=ROOT, help="checkout whose ctmm the cases import")
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000, 10000])
    parser.add_argument("--out", type=Path, default=OUT)
    arguments = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="ctmm-chain-setup-") as cache:
        for n in arguments.sizes:
            for method, loop in CASES:
                row = case(arguments.tree.resolve(), n, method, loop, cache)
                row["load_average"] = list(os.getloadavg())
                rows.append(row)
                print(json.dumps(row), flush=True)
    stored = json.loads(arguments.out.read_text()) if arguments.out.exists() else {}
    stored[arguments.label] = {"machine": platform.platform(), "python": platform.python_version(),
                               "steps": STEPS, "rows": rows}
    arguments.out.parent.mkdir(parents=True, exist_ok=True)
    arguments.out.write_text(json.dumps(stored, indent=1) + "\n")


if __name__ == "__main__":
    main()
