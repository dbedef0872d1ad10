"""Spatial DT-TMM schemes against RK4 of the same model: wall time and error from the same run.

Two models of ``tests/test_spatial_schemes.py``:

* ``double_pendulum`` -- a revolute link carrying a second link on a ball joint, 0.5 s;
* ``stiff_hinge`` -- a pendulum on a ball joint carrying a body on a stiff 6-DOF elastic hinge
  (highest frequency 1000 rad/s, swing about 2 rad/s), 0.3 s: RK4 needs ``dt < 2.8 ms``.

Every run is :func:`ctmm.simulate` (RK4 or a DT-TMM scheme, one sweep per RK4 stage or Newton
iteration, numpy path); its error is the largest difference of body rotations, origins [m] and world
angular velocities [rad/s] at the end from the independent global Newton-Euler model's RK4
(``ctmm/reference/spatial_tree.py``, dt = 1 ms, its error below 1e-7); for the stiff hinge the
error of the swing (arm angular velocity, body origins) from the reference at dt = 0.25 ms (the
hinge's own vibration, of amplitude about 1e-4 rad, is resolved by no step benchmarked here).  A run that diverges is
recorded as such (``error = null``).  Results: ``benchmarks/results/spatial_schemes.json``.

Run ``python benchmarks/spatial_schemes.py`` (about a minute).
"""
from __future__ import annotations

import json
import pathlib
import sys
import time

import numpy as np

import ctmm
from ctmm.errors import SimulationError
from ctmm.reference import spatial_tree as reference
from ctmm.reference.spatial_kinematics import kinematics
from ctmm.spatial.integrate import initial_state

ROOT = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT.parent / "tests"))

from test_spatial_schemes import double_pendulum, final_state, pose_error, stiff_hinge, to_reference  # noqa: E402

CASES = {
    "double_pendulum": (double_pendulum, 0.5, 1e-3, [("rk4", 0.02), ("rk4", 0.01), ("newmark", 0.01),
                                                     ("newmark", 0.005),
                                               ("generalized_alpha", 0.005), ("houbolt", 0.005),
                                               ("wilson_theta", 0.005), ("forward_euler", 0.005)]),
    "stiff_hinge": (stiff_hinge, 0.3, 2.5e-4, [("rk4", 0.005), ("rk4", 0.0025), ("newmark", 0.01), ("newmark", 0.005),
                                       ("generalized_alpha", 0.01)]),
}


def run() -> dict:
    rows = []
    for case, (build, t_final, reference_step, runs) in CASES.items():
        model, tree, x0, v0 = build()
        start = initial_state(model, x0, v0)
        fine = reference.simulate(tree, to_reference(model, tree, start[:model.n_positions]),
                                  start[model.n_positions:], t_final, reference_step)
        for method, dt in runs:
            began = time.perf_counter()
            try:
                result = ctmm.simulate(model, t_final, dt, method=method, x0=x0, v0=v0, divergence_bound=1e3)
            except SimulationError as exc:
                rows.append({"case": case, "method": method, "dt_s": dt, "wall_time_s": time.perf_counter() - began,
                             "error": None, "outcome": f"diverged at t = {exc.time} s"})
                continue
            wall = time.perf_counter() - began
            q, v = final_state(model, result)
            if case == "stiff_hinge":                # the swing: the hinge's 1000 rad/s vibration is not resolved
                ours = kinematics(tree, to_reference(model, tree, q), v)
                theirs = kinematics(tree, fine.q[-1], fine.v[-1])
                error = max(np.abs(ours.omega[0] - theirs.omega[0]).max(), np.abs(ours.origin - theirs.origin).max())
            else:
                error = pose_error(tree, to_reference(model, tree, q), v, fine.q[-1], fine.v[-1])
            sweeps = result.info.get("n_evaluations")
            rows.append({"case": case, "method": method, "dt_s": dt, "wall_time_s": wall, "error": float(error),
                         "sweeps": int(sweeps) if sweeps is not None else None, "outcome": "ok"})
            print(f"{case:16s} {method:18s} dt={dt:<7g} wall={wall:7.3f} s error={error:.2e}")
    return {"benchmark": "spatial_schemes", "error": "double_pendulum: max |R - R_ref|, |origin - origin_ref| [m], "
            "|omega - omega_ref| [rad/s], |v - v_ref| at t_final against the global reference's RK4 (dt = 1 ms); "
            "stiff_hinge: max |omega_arm - ref| [rad/s], |origins - ref| [m] (reference dt = 0.25 ms)",
            "rows": rows}


if __name__ == "__main__":
    data = run()
    out = ROOT / "results" / "spatial_schemes.json"
    out.write_text(json.dumps(data, indent=1))
    print(f"wrote {out}")
