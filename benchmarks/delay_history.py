"""Cost per step of a delayed closed loop against run length: the delay history must be O(1).

Model: the README's seed chain (fixed - K1 - m2 - K3 - m4 - K5 - m6 - free; 1 kg, 1000 N/m,
0.5 N s/m) with the delayed velocity loop ``u = -Ka m6.v(t - tau)`` on m2, Ka = 1 N s/m,
tau = 0.02 s, released from x(m6) = 0.01 m; Newmark(1/4, 1/2), dt = 1e-4 s; runs of
1 000, 5 000, 20 000 and 40 000 steps (``--quick``: 1 000 and 5 000).

For each run: CPU time per step (``time.process_time`` of this process, best of ``--repeat``;
wall time reported too, the machine is shared), the largest error of m6.x against the exact
delay equation (``ctmm.reference.delay_chain.method_of_steps``, DOP853 rtol 1e-12, solved once
over the longest run), and a SHA-256 of the result (states and loop signals) so that runs of two
versions can be compared bit for bit.

Run ``python benchmarks/delay_history.py --label after`` (and, for the version before the change,
the same script with that version of ctmm first on ``PYTHONPATH`` and ``--label before``);
results are merged by label into ``benchmarks/results/delay_history.json`` with the machine load.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

import ctmm
from ctmm.control import ControlledChain, Feedback, simulate_controlled
from ctmm.elements import Fixed, Free, Mass, SpringDamper
from ctmm.reference.chain import GlobalChain
from ctmm.reference.delay_chain import GlobalLoop, method_of_steps

DT = 1e-4
DELAY = 0.02
GAIN = 1.0
X_TIP = 0.01
RESULTS = Path(__file__).parent / "results" / "delay_history.json"


def model() -> ControlledChain:
    plant = ctmm.Chain("seed_chain", [Fixed("wall"), SpringDamper("K1", 1000.0, 0.5), Mass("m2", 1.0),
                                      SpringDamper("K3", 1000.0, 0.5), Mass("m4", 1.0),
                                      SpringDamper("K5", 1000.0, 0.5), Mass("m6", 1.0), Free("tip")])
    return ControlledChain(plant, [Feedback("Ka", sensor="m6.v", actuator="m2", gain=GAIN, delay=DELAY)])


def reference(t_final: float):
    chain = GlobalChain([1.0, 1.0, 1.0], [1000.0, 1000.0, 1000.0, 0.0], [0.5, 0.5, 0.5, 0.0],
                        start="fixed", end="free")
    loop = GlobalLoop(2, "velocity", 0, GAIN, DELAY)
    return method_of_steps(chain, [loop], t_final, [0.0, 0.0, X_TIP], [0.0, 0.0, 0.0], rtol=1e-12, atol=1e-15)


def digest(result) -> str:
    h = hashlib.sha256()
    for array in (result.states, result.velocity, result.acceleration, result["Ka.y"], result["Ka.u"]):
        h.update(np.ascontiguousarray(array).tobytes())
    return h.hexdigest()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--label", required=True, help="name of this version, e.g. before / after")
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    steps_list = [1000, 5000] if args.quick else [1000, 5000, 20000, 40000]
    system = model()
    exact = reference(max(steps_list) * DT).evaluate(np.arange(max(steps_list) + 1) * DT)
    rows = []
    for steps in steps_list:
        cpu, wall = [], []
        for _ in range(args.repeat):
            c0, w0 = time.process_time(), time.perf_counter()
            result = simulate_controlled(system, steps * DT, DT, x0={"m6": X_TIP})
            cpu.append(time.process_time() - c0)
            wall.append(time.perf_counter() - w0)
        error = float(np.max(np.abs(result["m6.x"] - exact.displacement[: steps + 1, 2])))
        rows.append({"steps": steps, "cpu_us_per_step": 1e6 * min(cpu) / steps,
                     "wall_us_per_step": 1e6 * min(wall) / steps, "max_error_m6_x_m": error,
                     "sha256": digest(result)})
        print(f"{args.label:>8} {steps:6d} steps: {rows[-1]['cpu_us_per_step']:8.1f} us/step (cpu), "
              f"error {error:.3e} m")
    data = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    data["model"] = (f"seed chain, Feedback Ka: m6.v -> m2, gain {GAIN} N s/m, delay {DELAY} s, dt {DT} s, "
                     f"Newmark(1/4, 1/2), x(m6, 0) = {X_TIP} m; error = max |m6.x - method of steps| [m]")
    data[args.label] = {"rows": rows, "load_average_1_5_15_min": os.getloadavg(), "cpus": os.cpu_count(),
                        "python": platform.python_version(), "date_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ",
                                                                                         time.gmtime())}
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(data, indent=1) + "\n")


if __name__ == "__main__":
    main()
