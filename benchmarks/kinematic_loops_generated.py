"""Closed kinematic loops in generated C: the four-bar's RK4 with projection, generated vs numpy (issues 13/16).

Problem: the four-bar linkage of ``scenarios/four_bar.py`` (crank 0.2 m, coupler 0.6 m, rocker 0.5 m, the cubic
rocker spring and quadratic damper, gravity; crank at 90 deg with 3 rad/s), closed by the cut joint ``h3``, over
``T`` = 1 s at dt = 1 ms.

Methods (one run, one machine):

* ``numpy``     -- :func:`ctmm.planar.closed_loops.simulate_kinematic_loops` (RK4, ``1 + 2 m`` numpy sweeps per
                   stage, the projection after every step);
* ``generated`` -- :class:`ctmm.compiled_kinematic_loops.CompiledKinematicLoops` ``.run`` (the same step generated
                   as C, whole blocks of steps per call, library loaded), and the whole
                   :func:`~ctmm.compiled_kinematic_loops.simulate_kinematic_loops_generated` (with the cut forces and
                   drift of the stored states); ``compile_s``: build, generate and compile in a fresh cache folder.
* ``dae``       -- the reference: the global DAE (:mod:`ctmm.reference.planar_dae`, DOP853 at 1e-11).

Spatial row: the R-U-S-R four-bar of ``scenarios/spatial_four_bar.py`` (spherical cut ``s3``, crank at 3 rad/s),
``T`` at dt = 1 ms: :class:`ctmm.compiled_spatial_kinematic_loops.CompiledSpatialKinematicLoops` ``.run`` against
:func:`ctmm.spatial.closed_loop_time.simulate_spatial_loops` (RK4 with projection), per-step times and their largest
coordinate difference.

Controlled row (issue 13 x 16): the same four-bar with a PD loop on the cut's relative angle driving the cut torque
``"h3.torque"`` (``u = -(6 dtheta + 0.6 dtheta' - 6 target)``, read 10 ms late) through ``ctmm.simulate(with_feedback(
loop, [pd]), compiled=True)`` (:mod:`ctmm.compiled_kinematic_loop_control`: Baumgarte only, as the numpy loop driver)
against the numpy driver (``compiled=None``): the generated run alone (``info["wall_time_s"]``) and the whole verb
(with the stored signals, which the numpy plant computes per stored row: every step, and ``store_every=10``) per
step, their largest angle difference and
each one's error against the DAE with the same delayed PD as a motor at the cut (method of steps).

Spherical-law row (issue 13): a body on a free joint held at the ground by a spherical cut carrying a 3-axis law
(cubic spring 2 N m/rad + 15 N m/rad^3 and a 0.02 N m s/rad damper per component of the relative rotation vector,
rest (0.1, -0.2, 0.05) rad, gravity; the model of ``tests/test_spatial_spherical_cut_law.py``), ``T`` at dt = 1 ms:
:class:`~ctmm.compiled_spatial_kinematic_loops.CompiledSpatialKinematicLoops` ``.run`` against
:func:`~ctmm.spatial.closed_loop_time.simulate_spatial_loops`, per-step times and their largest coordinate
difference (the DAE check is the test's); ``--spherical`` runs this row alone and merges it into the stored JSON.

Spatial scheme row (issue 13): the R-U-S-R four-bar with Newmark at dt = 1 ms over ``T`` / 5 (the numpy scheme
re-solves the cut loads at every Newton iterate: ~70 ms per step):
:class:`~ctmm.compiled_spatial_loop_schemes.CompiledSpatialLoopScheme` against
:func:`~ctmm.spatial.closed_loop_time.simulate_spatial_loop_scheme`, both projected after every step;
``--spatial-scheme`` runs this row alone and merges it into the stored JSON.

Flexible row (issue 13 item 1): the flexible-coupler four-bar of the scenario (``FLEX_EI`` = 80 N m^2, ``FLEX_MODES``
= 5 clamped-free modes with second-order inertia, the cut at the beam's end, ``FLEX_STEP`` = 0.25 ms) over
``T_FLEX`` (0.05 s; quick 0.02 s): :class:`~ctmm.compiled_kinematic_loops.CompiledKinematicLoops` ``.run`` (the cut
point on the beam through :mod:`ctmm.compiled_cut_points`) against the numpy RK4 with projection, per-step times and
their largest coordinate difference (the numpy path is checked against the extrapolated finite-segment DAE by the
scenario).

Figures: per-step wall and CPU time [us] (best of 3), the largest angle difference generated - numpy [rad]
(consistency: round-off) and the largest angle error of each against the DAE [rad].  Run
``python benchmarks/kinematic_loops_generated.py`` (``--quick``: T = 0.2 s); writes
``benchmarks/results/kinematic_loops_generated.json``.
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

from ctmm.compiled_kinematic_loops import CompiledKinematicLoops, simulate_kinematic_loops_generated  # noqa: E402
from ctmm.compiled_spatial_kinematic_loops import (CompiledSpatialKinematicLoops,  # noqa: E402
                                                   simulate_spatial_kinematic_loops_generated)
from ctmm.scenarios import spatial_four_bar  # noqa: E402
from ctmm.spatial.closed_loop_time import simulate_spatial_loops  # noqa: E402
from ctmm.planar.closed_loops import simulate_kinematic_loops  # noqa: E402
from ctmm.scenarios.four_bar import (DAMPER, FLEX_EI, FLEX_MODES, FLEX_STEP, SPRING,  # noqa: E402
                                     flexible_mechanism, flexible_start, mechanism, reference, start)

RESULTS = ROOT / "benchmarks" / "results" / "kinematic_loops_generated.json"
DT = 1e-3
T_FLEX = 0.05           # the flexible row's horizon [s]
NAMES = ("crank", "coupler", "rocker")


def four_bar():
    """The linkage with the rocker spring and damper and its start ``(loop, q0, v0)``."""
    loop = mechanism(SPRING + DAMPER)
    q0, v0 = start(loop)
    return loop, q0, v0


def best(call, repeats: int = 3) -> tuple[float, float]:
    """Best wall and CPU time [s] of ``call`` after one warm-up."""
    call()
    walls, cpus = [], []
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        call()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return min(walls), min(cpus)


def compiled_fresh(kind, loop):
    """``(kernel, compile_s)``: the generated kernel ``kind(loop)`` from the shared cache, and the seconds to build,
    generate and compile it in a fresh cache folder."""
    with tempfile.TemporaryDirectory() as folder:
        started = time.perf_counter()
        kind(loop, cache_dir=folder)
        compile_s = time.perf_counter() - started
    return kind(loop), compile_s


def kernel_row(prefix: str, steps: int, kernel_call, numpy_call, generated_call) -> dict:
    """``"<prefix>_..."`` figures of a row: per-step wall and CPU times [us] of the generated kernel's run
    (``kernel_call``) and of the numpy run (``numpy_call``, its result a simulation), the CPU speed-up, the largest
    coordinate difference of the whole generated run (``generated_call``) from the numpy one and its largest drift."""
    run_wall, run_cpu = best(kernel_call)
    numpy_wall, numpy_cpu = best(numpy_call, repeats=1)
    generated, numpy_run = generated_call(), numpy_call()
    return {f"{prefix}_generated_run_us_per_step": 1e6 * run_wall / steps,
            f"{prefix}_generated_run_cpu_us_per_step": 1e6 * run_cpu / steps,
            f"{prefix}_numpy_us_per_step": 1e6 * numpy_wall / steps,
            f"{prefix}_numpy_cpu_us_per_step": 1e6 * numpy_cpu / steps,
            f"{prefix}_speedup_run_cpu": numpy_cpu / run_cpu,
            f"{prefix}_generated_minus_numpy": float(np.max(np.abs(generated.q - numpy_run.q))),
            f"{prefix}_max_drift": float(np.max(generated.drift))}


def spatial_timings(prefix: str, loop, q0, v0, kernel, t_final: float, steps: int) -> dict:
    """``<prefix>_...`` figures of a spatial loop model (:func:`kernel_row`): the generated ``kernel``'s run against
    the numpy RK4 with projection."""
    return kernel_row(prefix, steps, lambda: kernel.run(q0, v0, DT, steps),
                      lambda: simulate_spatial_loops(loop, q0, v0, t_final=t_final, dt=DT),
                      lambda: simulate_spatial_kinematic_loops_generated(loop, q0, v0, t_final=t_final, dt=DT,
                                                                         compiled=kernel))


def flexible_four_bar() -> tuple:
    """The scenario's flexible-coupler linkage (second-order inertia) and its start ``(loop, q0, v0)``."""
    loop = flexible_mechanism(FLEX_EI, n_modes=FLEX_MODES, second_order_inertia=True)
    q0, v0 = flexible_start(loop)
    return loop, q0, v0


def flexible(t_final: float) -> dict:
    """The flexible row (module docstring)."""
    loop, q0, v0 = flexible_four_bar()
    steps = int(round(t_final / FLEX_STEP))
    kernel, compile_s = compiled_fresh(CompiledKinematicLoops, loop)
    return {"flexible_problem": f"four-bar with a ModalBeam coupler (EI = {FLEX_EI:g} N m^2, {FLEX_MODES} modes, "
                                f"second-order inertia, cut at its end), T = {t_final} s, dt = {FLEX_STEP} s",
            "flexible_compile_s": compile_s,
            **kernel_row("flexible", steps, lambda: kernel.run(q0, v0, FLEX_STEP, steps),
                         lambda: simulate_kinematic_loops(loop, q0, v0, t_final=t_final, dt=FLEX_STEP),
                         lambda: simulate_kinematic_loops_generated(loop, q0, v0, t_final=t_final, dt=FLEX_STEP,
                                                                    compiled=kernel))}


def spatial(t_final: float, steps: int) -> dict:
    """The spatial row (module docstring)."""
    loop = spatial_four_bar.mechanism()
    q0, v0 = spatial_four_bar.start(loop)
    return {"spatial_problem": f"R-U-S-R four-bar (scenarios/spatial_four_bar.py), T = {t_final} s, dt = {DT} s",
            **spatial_timings("spatial", loop, q0, v0, CompiledSpatialKinematicLoops(loop), t_final, steps)}


def spherical_ball():
    """The spherical-law row's model and start ``(loop, q0, v0)`` (module docstring)."""
    import ctmm.spatial as sp
    from ctmm.nonlinear_laws import CubicSpring, LinearLaw, ParallelLaw
    from ctmm.spatial.closed_loops import SpatialCutJoint, SpatialKinematicLoopModel

    tree = sp.SpatialModel("ball", [sp.SpatialBody("p", 1.2, np.diag([0.02, 0.03, 0.025]),
                                                   center_of_mass=(0.1, 0.0, -0.3)),
                                    sp.Free(name="free", parent=None, child="p")])
    law = ParallelLaw(CubicSpring(2.0, 15.0), LinearLaw(0.0, 0.02))
    loop = SpatialKinematicLoopModel(tree, [SpatialCutJoint(name="ball", parent=None, child="p", law=law,
                                                            rest=(0.1, -0.2, 0.05))])
    turn = np.sin(0.3)
    q0, v0 = loop.consistent_state({"free.qw": np.cos(0.3), "free.qx": 0.6 * turn, "free.qy": 0.8 * turn},
                                   {"free.wx": 1.0, "free.wz": 2.0})
    return loop, q0, v0


def spherical(t_final: float, steps: int) -> dict:
    """The spherical-law row (module docstring)."""
    loop, q0, v0 = spherical_ball()
    kernel, compile_s = compiled_fresh(CompiledSpatialKinematicLoops, loop)
    return {"spherical_problem": f"body on a free joint held by a spherical cut with a 3-axis cubic spring + damper "
                                 f"(tests/test_spatial_spherical_cut_law.py), T = {t_final} s, dt = {DT} s",
            "spherical_load_average": list(os.getloadavg()), "spherical_compile_s": compile_s,
            **spatial_timings("spherical", loop, q0, v0, kernel, t_final, steps)}


def spatial_scheme(t_final: float) -> dict:
    """The spatial scheme row (module docstring)."""
    from ctmm.compiled_spatial_loop_schemes import CompiledSpatialLoopScheme, simulate_spatial_loop_scheme_generated
    from ctmm.spatial.closed_loop_time import simulate_spatial_loop_scheme

    loop = spatial_four_bar.mechanism()
    q0, v0 = spatial_four_bar.start(loop)
    span = t_final / 5.0
    steps = int(round(span / DT))
    kernel, compile_s = compiled_fresh(CompiledSpatialLoopScheme, loop)
    generated: list = []
    run_wall, run_cpu = best(lambda: generated.append(simulate_spatial_loop_scheme_generated(
        loop, q0, v0, t_final=span, dt=DT, scheme="newmark", compiled=kernel)))
    kernel_wall = min(info["wall_time_s"] for _, info in generated[1:])
    plain: list = []
    numpy_wall, numpy_cpu = best(lambda: plain.append(simulate_spatial_loop_scheme(loop, q0, v0, t_final=span, dt=DT,
                                                                                   scheme="newmark")), repeats=1)
    return {"scheme_problem": f"R-U-S-R four-bar, Newmark with projection, T = {span} s, dt = {DT} s",
            "scheme_load_average": list(os.getloadavg()), "scheme_compile_s": compile_s,
            "scheme_generated_run_us_per_step": 1e6 * kernel_wall / steps,
            "scheme_generated_whole_cpu_us_per_step": 1e6 * run_cpu / steps,
            "scheme_numpy_us_per_step": 1e6 * numpy_wall / steps,
            "scheme_numpy_cpu_us_per_step": 1e6 * numpy_cpu / steps,
            "scheme_speedup_whole_cpu": numpy_cpu / run_cpu,
            "scheme_generated_minus_numpy": float(np.max(np.abs(generated[-1][0].q - plain[-1][0].q)))}


def controlled(t_final: float, steps: int) -> dict:
    """The controlled row (module docstring)."""
    import ctmm
    from ctmm.control import Feedback, with_feedback

    loop, q0, v0 = four_bar()
    target = float(loop.relative_angles(q0, v0)[0][0]) + 0.2
    pd = Feedback("pd", sensor=[("h3.angle", 6.0), ("h3.rate", 0.6)], actuator="h3.torque", gain=1.0, delay=0.01)
    system = with_feedback(loop, [pd])
    options = dict(x0=q0, v0=v0, references={"pd": 6.0 * target})
    runs: list = []

    def generated_call() -> None:
        runs.append(ctmm.simulate(system, t_final, DT, compiled=True, **options))

    whole_wall, whole_cpu = best(generated_call)
    kernel_wall = min(run.info["wall_time_s"] for run in runs[1:])
    ctmm.simulate(system, t_final, DT, compiled=True, store_every=10, **options)     # its library compiled once
    sparse_wall, sparse_cpu = best(lambda: ctmm.simulate(system, t_final, DT, compiled=True, store_every=10,
                                                         **options))
    numpy_wall, numpy_cpu = best(lambda: runs.append(ctmm.simulate(system, t_final, DT, **options)), repeats=1)
    generated, numpy_run = runs[1], runs[-1]
    dae = reference(SPRING + DAMPER)
    dae.add_motor("rocker", "coupler", lambda t, angle, rate: -(6.0 * angle + 0.6 * rate - 6.0 * target), delay=0.01)
    exact = dae.simulate(dae.assemble(dict(zip(NAMES, q0)), dict(zip(NAMES, v0))), t_final, t_eval=generated.time)

    def error(run) -> float:
        return float(max(np.max(np.abs(run[f"{name}.theta"] - exact.angle(name))) for name in NAMES))

    return {"controlled_problem": f"four-bar with a 10 ms delayed PD on the cut angle driving h3.torque, T = {t_final} "
                                  f"s, dt = {DT} s",
            "controlled_generated_run_us_per_step": 1e6 * kernel_wall / steps,
            "controlled_generated_whole_us_per_step": 1e6 * whole_wall / steps,
            "controlled_generated_whole_cpu_us_per_step": 1e6 * whole_cpu / steps,
            "controlled_generated_whole_every10_cpu_us_per_step": 1e6 * sparse_cpu / steps,
            "controlled_numpy_us_per_step": 1e6 * numpy_wall / steps,
            "controlled_numpy_cpu_us_per_step": 1e6 * numpy_cpu / steps,
            "controlled_speedup_whole_cpu": numpy_cpu / whole_cpu,
            "controlled_generated_minus_numpy_rad": float(max(np.max(np.abs(generated[f"{name}.theta"]
                                                                            - numpy_run[f"{name}.theta"]))
                                                              for name in NAMES)),
            "controlled_generated_vs_dae_rad": error(generated), "controlled_numpy_vs_dae_rad": error(numpy_run),
            "controlled_max_drift_m": float(np.max(generated["drift"]))}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="T = 0.2 s")
    parser.add_argument("--spherical", action="store_true",
                        help="the spherical-law row alone, merged into the stored JSON")
    parser.add_argument("--spatial-scheme", action="store_true",
                        help="the spatial scheme row alone, merged into the stored JSON")
    args = parser.parse_args(argv)
    t_final = 0.2 if args.quick else 1.0
    steps = int(round(t_final / DT))
    if args.spherical or args.spatial_scheme:
        row = {**(spherical(t_final, steps) if args.spherical else {}),
               **(spatial_scheme(t_final) if args.spatial_scheme else {})}
        for key, value in row.items():
            print(f"{key:40s} {value}")
        if not args.quick:
            stored = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
            RESULTS.write_text(json.dumps({**stored, **row}, indent=2) + "\n")
        return row
    loop, q0, v0 = four_bar()
    kernel, compile_s = compiled_fresh(CompiledKinematicLoops, loop)
    generated_wall, generated_cpu = best(lambda: kernel.run(q0, v0, DT, steps))
    whole_wall, whole_cpu = best(lambda: simulate_kinematic_loops_generated(loop, q0, v0, t_final=t_final, dt=DT,
                                                                           compiled=kernel))
    numpy_wall, numpy_cpu = best(lambda: simulate_kinematic_loops(loop, q0, v0, t_final=t_final, dt=DT), repeats=1)
    generated = simulate_kinematic_loops_generated(loop, q0, v0, t_final=t_final, dt=DT, compiled=kernel)
    numpy_run = simulate_kinematic_loops(loop, q0, v0, t_final=t_final, dt=DT)
    dae = reference(SPRING + DAMPER)
    exact = dae.simulate(dae.assemble(dict(zip(NAMES, q0)), dict(zip(NAMES, v0))), t_final, t_eval=generated.t)
    angles = np.column_stack([exact.angle(name) for name in NAMES])
    out = {"machine": {"python": sys.version.split()[0], "platform": platform.platform(),
                       "load_average": list(os.getloadavg())},
           "problem": f"four-bar (scenarios/four_bar.py, rocker spring + damper), T = {t_final} s, dt = {DT} s, "
                      f"{steps} steps",
           "compile_s": compile_s,
           "generated_run_us_per_step": 1e6 * generated_wall / steps,
           "generated_run_cpu_us_per_step": 1e6 * generated_cpu / steps,
           "generated_whole_us_per_step": 1e6 * whole_wall / steps,
           "generated_whole_cpu_us_per_step": 1e6 * whole_cpu / steps,
           "numpy_us_per_step": 1e6 * numpy_wall / steps, "numpy_cpu_us_per_step": 1e6 * numpy_cpu / steps,
           "speedup_run_cpu": numpy_cpu / generated_cpu, "speedup_whole_cpu": numpy_cpu / whole_cpu,
           "generated_minus_numpy_rad": float(np.max(np.abs(generated.q - numpy_run.q))),
           "generated_vs_dae_rad": float(np.max(np.abs(generated.q - angles))),
           "numpy_vs_dae_rad": float(np.max(np.abs(numpy_run.q - angles))),
           "max_drift_m": float(np.max(generated.drift))}
    out.update(spatial(t_final, steps))
    out.update(controlled(t_final, steps))
    out.update(spherical(t_final, steps))
    out.update(spatial_scheme(t_final))
    out.update(flexible(0.02 if args.quick else T_FLEX))
    for key, value in out.items():
        print(f"{key:36s} {value}")
    if not args.quick:
        RESULTS.parent.mkdir(exist_ok=True)
        RESULTS.write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
