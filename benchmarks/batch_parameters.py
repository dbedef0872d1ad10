"""Parameter sets on one generated kernel (issue 13): ``ctmm.simulate_batch`` against one compile per set
and against the numpy path.

Rows (time and error together, ratios from one run, ``benchmarks/results/batch_parameters.json``), each
a sweep of ``B`` parameter sets of one scene:

1. **Planar chain** of N = 20 links on sprung, damped hinges (gravity): link masses and hinge stiffnesses.
2. **Controlled planar double pendulum**: a real-time PD and a delayed loop (3 steps): loop gains and a mass.
3. **Spatial chain** of N = 10 links on sprung revolute joints about alternating axes: masses, stiffnesses,
   gravity.
4. **Controlled spatial chain** (N = 6) with a joint-torque loop: its gain and masses.
5. **Spatial hub beam**: a modal ``SpatialBeam`` (2 + 1 bending, 1 torsion, 1 axial mode) on a sprung revolute
   joint under gravity: its mass per length, ``EI_y``, ``EI_z``, ``GJ``, ``EA`` and damping ratio.

Columns per row: (a) ``simulate_batch`` from a fresh cache folder (one compile, then every set on the
same library; wall time of the whole call, and its first compile); (b) one compile per set (each set's
model through ``ctmm.simulate(..., compiled=True)`` in a fresh cache folder: numbers as constants for
spatial models, the behaviour before this issue); (c) the numpy path (``ctmm.simulate`` without
``compiled``).  (b) and (c) run on the first ``min(B, 4)`` sets and are given per set.  Errors: the
largest difference of (a) and (b) from (c) over the stored coordinates of those sets, relative to their
peak (round-off: the same RK4), and for row 3 of set 0 against the independent global reference
``ctmm.reference.spatial_tree`` (its own RK4).  Ratios: per set, (b) and (c) over (a) with its compile
spread over the sets, and (c) over the runs of (a) alone (what many sets tend to).

Session 8: sequential planar sets without loops (row 1) run their RK4 in one C call per block for all sets
(``casadi.Function.map``, serial; ``ctmm.batch.ParameterKernel.run_mapped``).  Row 1 measured before (commit
3254dc0) / after in one sitting, load 8-9 on 2 cores: runs 36.5 / 38.5 ms per set (within the noise: the Python
per set, model rebuilt and certified, step limit checked, result built, dominates the 1.5 ms of C; measured
apart with ``stability_check="ignore"``, CPU, load 3-4: 64 sets of N = 20 x 500 steps 343 -> 290 ms, of N = 5 x
2000 steps 262 -> 176 ms, the latter saving the C calls per block and set).

Session 9: sequential spatial sets without loops are mapped too.  ``--mapped`` measures, on one compiled kernel,
the spatial chain N = 5 (rows of row 3's kind) x 64 sets x 500 steps: ``ParameterKernel.run_mapped`` (all sets in
one C call per block) against ``ParameterKernel.run`` set by set, CPU time (``time.process_time``), best of 3
interleaved, both the whole batch (results built and checked) and the C runs alone
(``CompiledSpatialScene.run`` with ``parameters`` against one call per set); results in
``benchmarks/results/batch_parameters_mapped.json``.

Session 10: sets with loops are mapped too (``ctmm.batch_loops``: each set's controller states and delay ring in
its state, its loop numbers in its parameter column).  ``--mapped`` measures three scenes, 64 sets x 500 steps each:
the spatial chain above, the controlled planar pendulum of row 2 (real-time PD with a harmonic reference whose
amplitude is swept, a loop delayed 3 steps) and a controlled spatial chain N = 4 (real-time joint-torque loop, a
body force at a point delayed 2 steps), CPU best of 5 interleaved; ``benchmarks/results/batch_parameters_mapped.json``
holds one row per scene.

Run: ``python benchmarks/batch_parameters.py [--quick] [--rows 5] [--mapped]`` (``--rows``: only those rows, the
others kept in the results file; ``--mapped``: only the mapped-against-set-by-set measurement).
"""
from __future__ import annotations

import argparse
import copy
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
for path in (ROOT, ROOT / "tests"):
    if str(path) not in sys.path:
        sys.path.insert(0, str(path))

import ctmm  # noqa: E402
import ctmm.spatial as sp  # noqa: E402
from ctmm.control import Feedback  # noqa: E402
from ctmm.control.controlled_model import ControlledModel  # noqa: E402
from ctmm.planar import Fixed, PlanarModel, RigidBody, SpringDamperHinge  # noqa: E402
from ctmm.reference import spatial_tree as ref  # noqa: E402
from spatial_linear_helpers import reference_tree  # noqa: E402


def planar_chain(masses, stiffnesses) -> PlanarModel:
    items: list = [Fixed("ground")]
    for i, (mass, k) in enumerate(zip(masses, stiffnesses)):
        items += [SpringDamperHinge(f"h{i}", stiffness=k, damping=0.05),
                  RigidBody(f"l{i}", mass=mass, inertia=mass / 12.0, center_of_mass=(0.5, 0.0), outboard=(1.0, 0.0))]
    return PlanarModel.chain("chain", items)


def controlled_pendulum(pd_gain, late_gain, rod_mass) -> ControlledModel:
    plant = planar_chain([rod_mass, 0.5], [0.5, 0.5])
    loops = [Feedback("pd", [("l0.theta", 1.0), ("l0.omega", 0.3)], "h0.torque", gain=pd_gain),
             Feedback("late", "h1.angle", "h1.torque", gain=late_gain, delay=3e-3)]
    return ControlledModel(plant, loops)


def spatial_chain(masses, stiffnesses, gravity_z=-9.81, actuated=False) -> sp.SpatialModel:
    elements = []
    for i, (mass, k) in enumerate(zip(masses, stiffnesses)):
        elements.append(sp.SpatialBody(f"l{i}", mass, np.diag([0.01, 0.04, 0.045]) * mass, (0.25, 0.0, 0.0),
                                       {"end": (0.5, 0.0, 0.0)}))
        elements.append(sp.Revolute(name=f"j{i}", parent=None if i == 0 else f"l{i - 1}", child=f"l{i}",
                                    point=(0.0, 0.0, 0.0) if i == 0 else "end", axis=(0, 1, 0) if i % 2 else (0, 0, 1),
                                    stiffness=k, damping=0.05, actuated=actuated and i == 1))
    return sp.SpatialModel("chain", elements, gravity=(0.0, 0.3, gravity_z))


def hub_beam(numbers) -> sp.SpatialModel:
    """A modal beam on a sprung, damped revolute joint about a tilted axis, gravity bending and twisting it."""
    beam = dict(length=1.0, mass_per_length=0.9, bending_stiffness_y=6.0, bending_stiffness_z=4.0, n_modes_y=2,
                n_modes_z=1, n_torsion_modes=1, torsional_stiffness=1.5, polar_inertia_per_length=0.004,
                n_axial_modes=1, axial_stiffness=300.0, damping_ratio=0.01, stiffness_damping=0.002)
    beam.update({name.partition(".")[2]: value for name, value in numbers.items()})
    return sp.SpatialModel("hubbeam", [sp.SpatialBeam("b", **beam), sp.Revolute(
        name="j", parent=None, child="b", axis=(0.0, 0.3, 1.0), stiffness=3.0, damping=0.2)], gravity=(0.0, 0.5, -9.81))


def controlled_spatial(gain, masses) -> ControlledModel:
    return ControlledModel(spatial_chain(masses, [1.0] * len(masses), actuated=True),
                           [Feedback("hold", "j1.angle", "j1.torque", gain=gain)])


def scenes(quick: bool) -> list[dict]:
    """Each scene: a builder of the system from a set's numbers, the sets (names and values), the run."""
    rng = np.random.default_rng(13)
    count = 4 if quick else 16
    n_planar, n_spatial = (6, 4) if quick else (20, 10)
    rows = []
    masses = rng.uniform(0.5, 2.0, (count, n_planar))
    stiff = rng.uniform(0.5, 5.0, (count, n_planar))
    rows.append(dict(label=f"planar chain N = {n_planar}", t_final=0.5, dt=1e-3,
                     sets=[{**{f"l{i}.mass": m[i] for i in range(n_planar)},
                            **{f"l{i}.inertia": m[i] / 12.0 for i in range(n_planar)},
                            **{f"h{i}.stiffness": k[i] for i in range(n_planar)}} for m, k in zip(masses, stiff)],
                     build=lambda s: planar_chain([s[f"l{i}.mass"] for i in range(n_planar)],
                                                  [s[f"h{i}.stiffness"] for i in range(n_planar)]),
                     x0=np.full(n_planar, 0.2)))
    gains = rng.uniform(2.0, 12.0, (count, 3))
    rows.append(dict(label="controlled planar pendulum (PD + delayed loop)", t_final=0.5, dt=1e-3,
                     sets=[{"pd.gain": g[0], "late.gain": -0.2 * g[1], "l0.mass": g[2] / 6.0,
                            "l0.inertia": g[2] / 72.0} for g in gains],
                     build=lambda s: controlled_pendulum(s["pd.gain"], s["late.gain"], s["l0.mass"]),
                     x0=np.array([0.4, -0.3])))
    masses = rng.uniform(0.5, 2.0, (count, n_spatial))
    stiff = rng.uniform(0.5, 5.0, (count, n_spatial))
    inertia = np.array([0.01, 0.04, 0.045])
    rows.append(dict(label=f"spatial chain N = {n_spatial}", t_final=0.25, dt=1e-3, reference=True,
                     sets=[{**{f"l{i}.mass": m[i] for i in range(n_spatial)},
                            **{f"l{i}.inertia.{axis}": m[i] * inertia[a] for i in range(n_spatial)
                               for a, axis in enumerate(("xx", "yy", "zz"))},
                            **{f"j{i}.stiffness": k[i] for i in range(n_spatial)}, "gravity.z": -9.81 * m[0]}
                           for m, k in zip(masses, stiff)],
                     build=lambda s: spatial_chain([s[f"l{i}.mass"] for i in range(n_spatial)],
                                                   [s[f"j{i}.stiffness"] for i in range(n_spatial)], s["gravity.z"]),
                     x0=np.full(n_spatial, 0.2)))
    rows.append(dict(label="controlled spatial chain N = 4 (joint-torque loop)", t_final=0.25, dt=1e-3,
                     sets=[{"hold.gain": 4.0 * m[0], **{f"l{i}.mass": m[i] for i in range(4)},
                            **{f"l{i}.inertia.{axis}": m[i] * inertia[a] for i in range(4)
                               for a, axis in enumerate(("xx", "yy", "zz"))}} for m in masses],
                     build=lambda s: controlled_spatial(s["hold.gain"], [s[f"l{i}.mass"] for i in range(4)]),
                     x0=np.full(4, 0.2)))
    numbers = rng.uniform(0.5, 2.0, (count, 6))
    rows.append(dict(label="spatial hub beam (6 modes)", t_final=0.25, dt=1e-3,
                     sets=[{"b.mass_per_length": 0.9 * f[0], "b.bending_stiffness_y": 6.0 * f[1],
                            "b.bending_stiffness_z": 4.0 * f[2], "b.torsional_stiffness": 1.5 * f[3],
                            "b.axial_stiffness": 300.0 * f[4], "b.damping_ratio": 0.01 * f[5]} for f in numbers],
                     build=hub_beam, x0=np.array([0.2, 0.01, 0.0, -0.02, 0.0, 0.0])))
    return rows


def coordinates(system) -> list[str]:
    plant = getattr(system, "plant", system)
    return list(plant.coordinates)


def largest(runs, others, names) -> float:
    worst = 0.0
    for run, other in zip(runs, others):
        for name in names:
            scale = max(1.0, float(np.max(np.abs(other[name]))))
            worst = max(worst, float(np.max(np.abs(run[name] - other[name]))) / scale)
    return worst


def measure(row: dict) -> dict:
    sets, build, dt, t_final, x0 = row["sets"], row["build"], row["dt"], row["t_final"], row["x0"]
    base = build(sets[0])
    names = coordinates(base)
    with tempfile.TemporaryDirectory() as folder:
        os.environ["CTMM_CACHE"] = folder
        start = time.perf_counter()
        batch = ctmm.simulate_batch(base, sets, t_final, dt, x0=x0)
        batch_wall = time.perf_counter() - start
    assert not batch.failures, batch.failures
    few = min(len(sets), 4)
    separate, separate_wall = [], 0.0
    for values in sets[:few]:
        with tempfile.TemporaryDirectory() as folder:
            os.environ["CTMM_CACHE"] = folder
            start = time.perf_counter()
            separate.append(ctmm.simulate(build(values), t_final, dt, x0=x0, compiled=True))
            separate_wall += time.perf_counter() - start
    numpy_runs, numpy_wall = [], 0.0
    for values in sets[:few]:
        start = time.perf_counter()
        numpy_runs.append(ctmm.simulate(build(values), t_final, dt, x0=x0, method="rk4"))
        numpy_wall += time.perf_counter() - start
    out = {"scene": row["label"], "sets": len(sets), "steps": int(round(t_final / dt)),
           "batch_wall_s": batch_wall, "batch_compile_s": batch.compile_time_s,
           "batch_per_set_s": batch_wall / len(sets), "batch_runs_per_set_s": batch.wall_time_s / len(sets),
           "separate_per_set_s": separate_wall / few, "numpy_per_set_s": numpy_wall / few,
           "batch_error": largest(batch.results[:few], numpy_runs, names),
           "separate_error": largest(separate, numpy_runs, names)}
    out["ratio_separate_to_batch"] = out["separate_per_set_s"] / out["batch_per_set_s"]
    out["ratio_numpy_to_batch"] = out["numpy_per_set_s"] / out["batch_per_set_s"]
    out["ratio_numpy_to_batch_runs"] = out["numpy_per_set_s"] / out["batch_runs_per_set_s"]
    if row.get("reference"):
        model = build(sets[0])
        run = ref.simulate(reference_tree(model), x0, np.zeros(len(x0)), t_final, dt)
        scale = max(1.0, float(np.max(np.abs(run.q))))
        out["reference_error"] = max(float(np.max(np.abs(batch.results[0][name] - run.q[:, i]))) / scale
                                     for i, name in enumerate(names))
    return out


def mapped_scene(label: str, base, sets: list, start: dict, steps: int, dt: float, names: list,
                 references=None) -> dict:
    """Sets per CPU second of ``sets`` on one compiled kernel of ``base``, mapped (one C call per block over all
    sets) and set by set: the whole batch (results built and checked) and the C runs alone (module docstring)."""
    from ctmm.batch import ParameterKernel
    from ctmm.batch_loops import run_members
    from ctmm.compiled_spatial_parameters import spatial_parameter_vector
    from ctmm.parameter_sets import plant_and_loops

    count = len(sets)
    with tempfile.TemporaryDirectory() as folder:
        os.environ["CTMM_CACHE"] = folder
        kernel = ParameterKernel(base, steps * dt, dt, references=references)
        scene = kernel.scene()
        members = [kernel.member(values) for values in sets]
        if kernel.kind == "spatial":
            numbers = np.array([spatial_parameter_vector(member) for member in members])
            x = np.concatenate([start["x0"], np.zeros(len(start["x0"]))])

            def mapped_c() -> None:
                scene.run(x, dt, steps, parameters=numbers)

            def one_by_one_c() -> None:
                for member in members:          # the shared scene with each set's numbers (as ParameterKernel.run)
                    member_scene = copy.copy(scene)
                    member_scene.parameters = spatial_parameter_vector(member)
                    member_scene.run(x, dt, steps)
        else:                               # loops: each set prepared on the kernel (its laws, numbers, state)
            x0, v0 = kernel.start(start["x0"], start.get("v0"))
            prepared = [kernel.loop_run(*plant_and_loops(member), kernel.space.references_with(values), x0, v0)
                        for member, values in zip(members, sets)]

            def mapped_c() -> None:
                run_members(scene, prepared, kernel.step, steps)

            def one_by_one_c() -> None:
                for run in prepared:
                    run.scene.run(run.q0, run.v0, kernel.step, steps)

        timed = {"mapped": lambda: kernel.run_mapped(sets, start),
                 "set_by_set": lambda: [kernel.run(values, **start) for values in sets],
                 "mapped_c": mapped_c, "set_by_set_c": one_by_one_c}
        best = {name: float("inf") for name in timed}
        for _ in range(5):
            for name, call in timed.items():
                clock = time.process_time()
                call()
                best[name] = min(best[name], time.process_time() - clock)
        mapped = [result for result, _ in kernel.run_mapped(sets, start)]
        alone = [kernel.run(values, **start) for values in sets]
    equal = all(np.array_equal(a[name], b[name]) for a, b in zip(mapped, alone) for name in names)
    out = {"scene": label, "kind": kernel.kind, "sets": count, "steps": steps, "load": os.getloadavg()[0],
           "equal_to_the_bit": equal, "compared": names,
           **{f"{name}_cpu_s": value for name, value in best.items()},
           **{f"{name}_sets_per_s": count / value for name, value in best.items()}}
    print(f"{label}: {count} sets x {steps} steps (load {out['load']:.1f}), CPU best of 5 | whole batch: "
          f"mapped {best['mapped'] * 1e3:.0f} ms ({count / best['mapped']:.0f} sets/s), set by set "
          f"{best['set_by_set'] * 1e3:.0f} ms ({count / best['set_by_set']:.0f} sets/s) | C runs alone: mapped "
          f"{best['mapped_c'] * 1e3:.1f} ms, one call per set {best['set_by_set_c'] * 1e3:.1f} ms | same bits: {equal}")
    return out


def mapped_against_set_by_set(quick: bool) -> list[dict]:
    """Mapped against set by set (:func:`mapped_scene`): the spatial chain N = 5 without loops, a looped planar
    double pendulum (real-time PD with a harmonic reference, a loop delayed 3 steps) and a looped spatial chain
    N = 4 (a real-time joint-torque loop, a body force delayed 2 steps); 64 sets x 500 steps (``quick``: 8 x 100)."""
    from ctmm.signals import Harmonic

    count, steps, dt = 8 if quick else 64, 100 if quick else 500, 1e-3
    rng = np.random.default_rng(9)
    n = 5
    masses, stiff = rng.uniform(0.5, 2.0, (count, n)), rng.uniform(0.5, 5.0, (count, n))
    rows = [mapped_scene(f"spatial chain N = {n}", spatial_chain([1.0] * n, [1.0] * n),
                         [{**{f"l{i}.mass": m[i] for i in range(n)}, **{f"j{i}.stiffness": k[i] for i in range(n)}}
                          for m, k in zip(masses, stiff)], {"x0": np.full(n, 0.2), "v0": None}, steps, dt,
                         [f"j{i}.angle" for i in range(n)])]
    gains = rng.uniform(2.0, 12.0, (count, 4))
    rows.append(mapped_scene("controlled planar pendulum (PD + harmonic reference + delayed loop)",
                             controlled_pendulum(4.0, -1.0, 1.0),
                             [{"pd.gain": g[0], "late.gain": -0.2 * g[1], "l0.mass": g[2] / 6.0,
                               "l0.inertia": g[2] / 72.0, "pd.reference.amplitude": 0.02 * g[3]} for g in gains],
                             {"x0": np.array([0.4, -0.3])}, steps, dt,
                             ["l0.theta", "l1.theta", "pd.u", "late.y", "late.u"],
                             references={"pd": Harmonic(0.1, 7.0, 0.0)}))
    plant_masses = rng.uniform(0.5, 2.0, (count, 4))
    looped = ControlledModel(spatial_chain([1.0] * 4, [1.0] * 4, actuated=True),
                             [Feedback("hold", "j1.angle", "j1.torque", gain=3.0),
                              Feedback("push", "l3.end.vz", "l3.end.force_z", gain=0.5, delay=2 * dt)])
    rows.append(mapped_scene("controlled spatial chain N = 4 (joint-torque loop + delayed body force)", looped,
                             [{"hold.gain": 4.0 * m[0], "push.gain": m[1] - 1.0,
                               **{f"l{i}.mass": m[i] for i in range(4)}} for m in plant_masses],
                             {"x0": np.full(4, 0.2)}, steps, dt, ["j0.angle", "j3.angle", "hold.u", "push.u"]))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small scenes and 4 sets (a smoke run)")
    parser.add_argument("--rows", type=int, nargs="+", help="measure only these rows (1-based); the others are "
                        "kept from the written results")
    parser.add_argument("--mapped", action="store_true", help="only the mapped-against-set-by-set measurement "
                        "(spatial chain N = 5, looped planar pendulum, looped spatial chain N = 4; 64 sets each)")
    args = parser.parse_args()
    if args.mapped:
        rows = mapped_against_set_by_set(args.quick)
        if not args.quick:
            target = ROOT / "benchmarks" / "results" / "batch_parameters_mapped.json"
            target.write_text(json.dumps({"machine": platform.platform(), "python": platform.python_version(),
                                          "cpus": os.cpu_count(), "rows": rows}, indent=2) + "\n")
            print(f"written {target}")
        return
    chosen = scenes(args.quick)
    if args.rows:
        if not all(1 <= k <= len(chosen) for k in args.rows):
            parser.error(f"--rows must be between 1 and {len(chosen)}, got {args.rows}")
        chosen = [chosen[k - 1] for k in args.rows]
    rows = [measure(row) for row in chosen]
    for row in rows:
        print(f"{row['scene']}: {row['sets']} sets x {row['steps']} steps | batch {row['batch_wall_s']:.2f} s "
              f"(compile {row['batch_compile_s']:.2f} s, runs {row['batch_runs_per_set_s'] * 1e3:.1f} ms/set) | "
              f"per set: batch {row['batch_per_set_s'] * 1e3:.1f} ms, separate compiles "
              f"{row['separate_per_set_s'] * 1e3:.0f} ms ({row['ratio_separate_to_batch']:.1f}x), numpy "
              f"{row['numpy_per_set_s'] * 1e3:.0f} ms ({row['ratio_numpy_to_batch']:.1f}x; "
              f"{row['ratio_numpy_to_batch_runs']:.1f}x the runs alone) | error vs numpy: batch "
              f"{row['batch_error']:.1e}, separate {row['separate_error']:.1e}"
              + (f", batch vs reference {row['reference_error']:.1e}" if "reference_error" in row else ""))
    if not args.quick:
        target = ROOT / "benchmarks" / "results" / "batch_parameters.json"
        if args.rows and target.exists():         # the other rows as measured before, in the scenes' order
            measured = {row["scene"]: row for row in json.loads(target.read_text())["rows"]}
            measured.update({row["scene"]: row for row in rows})
            rows = [measured[row["label"]] for row in scenes(False) if row["label"] in measured]
        target.write_text(json.dumps({"machine": platform.platform(), "python": platform.python_version(),
                                      "cpus": os.cpu_count(), "rows": rows}, indent=2) + "\n")
        print(f"written {target}")


if __name__ == "__main__":
    main()
