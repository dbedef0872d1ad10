"""Timing, profiling and provenance helpers of the benchmark scripts (CPU and wall time of the same calls)."""
from __future__ import annotations

import cProfile
import io
import os
import platform
import pstats
import subprocess
import time
from pathlib import Path
from typing import Any, Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def timed(call: Callable[[], Any], *, repeat_until: float = 1.0, max_repeats: int = 3
          ) -> tuple[Any, float, float, int]:
    """Best wall and best CPU time [s] of repeated calls (short calls only) and the last result.

    Returns ``(result, best_wall_s, best_cpu_s, runs)``: calls are repeated up to ``max_repeats`` times while
    less than ``repeat_until`` [s] of wall time has been spent.  The machine is shared: CPU time
    (``time.process_time``, single-threaded code) is the figure to compare.
    """
    best, best_cpu, spent, runs, result = np.inf, np.inf, 0.0, 0, None
    while runs < max_repeats and (runs == 0 or spent < repeat_until):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = call()
        elapsed, cpu = time.perf_counter() - start, time.process_time() - start_cpu
        best, best_cpu, spent, runs = min(best, elapsed), min(best_cpu, cpu), spent + elapsed, runs + 1
    return result, best, best_cpu, runs


def profile_top(call: Callable[[], Any], limit: int = 12) -> list[dict]:
    """cProfile ``call()`` and return the ``limit`` functions with the largest own time [s]."""
    prof = cProfile.Profile()
    prof.enable()
    call()
    prof.disable()
    stats = pstats.Stats(prof, stream=io.StringIO())
    total = sum(v[2] for v in stats.stats.values())
    rows = sorted(stats.stats.items(), key=lambda kv: kv[1][2], reverse=True)[:limit]
    out = []
    for (filename, line, func), (_, nc, tt, ct, _) in rows:
        short = filename.split(f"{ROOT}/")[-1].split("site-packages/")[-1]
        out.append({"function": f"{short}:{line}({func})", "ncalls": nc, "tottime_s": tt,
                    "cumtime_s": ct, "share_of_total": tt / total if total else float("nan")})
    return out


def slope(ns, ts) -> float:
    """Exponent of a least-squares power law ``t ~ n^p`` through the finite positive times ``ts`` [s]."""
    ns, ts = np.asarray(ns, float), np.asarray(ts, float)
    ok = np.isfinite(ts) & (ts > 0)
    return float(np.polyfit(np.log(ns[ok]), np.log(ts[ok]), 1)[0]) if ok.sum() >= 2 else float("nan")


def code_version() -> dict:
    """Commit of the measured code and the files of ctmm/ that differ from it."""
    def git(*args):
        try:
            return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=30).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return None
    status = git("status", "--porcelain", "--", "ctmm")
    return {"commit": git("rev-parse", "HEAD"),
            "uncommitted_ctmm_files": status.splitlines() if status else []}


def machine() -> dict:
    """Platform, library versions, CPU model and load average of the machine running the benchmark."""
    import scipy
    import control

    info = {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
            "python": platform.python_version(), "numpy": np.__version__, "scipy": scipy.__version__,
            "control": control.__version__, "cpu_count": os.cpu_count(),
            "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS"),
            "load_average_1_5_15min": list(os.getloadavg())}
    try:
        with open("/proc/cpuinfo") as handle:
            for line in handle:
                if line.startswith("model name"):
                    info["cpu_model"] = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return info
