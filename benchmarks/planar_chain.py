"""Speed against error: planar pendulum chains of N = 5, 20, 100, 300, 1000 links.

Problem: N uniform links (length 1 m and mass 1 kg *each*, J_C = m L^2 / 12), smooth hinges,
pinned to the ground, g = 9.81 m/s^2, released horizontally at rest, simulated for 1 s with
h = 1e-3 s.  Error = max over links of |theta_abs(1 s) - theta_ref(1 s)| [rad].

Methods (all measured in one run, on the same machine):

* ``tmm_rk4``       -- acceleration TMM (O(n) Riccati sweep, pure Python/numpy) + own RK4
* ``tmm_rk4_generated`` -- the same sweep and RK4 loop in C generated from the element
                       definitions (``ctmm.simulate(..., compiled=True)``,
                       :func:`ctmm.compiled_scene.simulate_rk4_generated`; whole interval in C, time
                       loop only; ``compile_s``: first compile in a fresh cache folder); from
                       ``FOLD_MIN_BODIES`` links folded over segments of the chain
                       (:mod:`ctmm.compiled_scene_fold`, ``fold_period`` in the JSON); at N = 20, 100, 300
                       also the other code (``_straight``: straight-line, ``fold=False``, N <= 300;
                       ``_folded``: ``fold=True``).  It replaced the hand-typed C of
                       ``ctmm.planar.compiled`` (removed, issue 13), whose last run here measured
                       6.5 / 33 / 25 / 895 us per step at N = 5 / 20 / 100 / 1000
* ``dttmm_newmark`` -- implicit DT-TMM, Newmark(1/4, 1/2), Newton (O(n) tangent sweep)
* ``lagrange_rk4``  -- global Lagrange model (dense M(q), Cholesky, O(n^3)) + the same RK4;
                       skipped when the estimate exceeds 2 minutes
* ``pinocchio_rk4`` -- Pinocchio ABA + the same RK4 loop in Python (optional peer)
* ``mujoco_rk4``    -- MuJoCo's built-in RK4, ``mj_step`` in a Python loop (optional peer)

Reference: the Lagrange model with DOP853 at rtol = atol = 1e-12 (N <= 100); for N = 1000 the
TMM right-hand side with DOP853 at the same tolerance (the independence of the TMM from the
Lagrange model is established by the tests at N <= 100 and by the KKT check at N = 1000).

Run ``python benchmarks/planar_chain.py`` (``--quick`` for N <= 20, ``--sizes 5 20 100 300`` for
others); writes ``benchmarks/results/planar_chain.json`` and ``planar_chain.png``
(``--generated-only``: reference, numpy and generated RK4 only, ``planar_chain_generated.json``).
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

from ctmm.planar import Pinned, PlanarModel, RigidBody, SmoothHinge  # noqa: E402
from ctmm.planar.implicit import simulate_implicit  # noqa: E402
from ctmm.planar.integrate import simulate_rk4, simulate_scipy  # noqa: E402
from ctmm.compiled_scene import CompiledScene, simulate_rk4_generated  # noqa: E402
from ctmm.compiled_scene_fold import FOLD_MIN_BODIES  # noqa: E402
from ctmm.reference.planar_lagrange import PlanarLagrange  # noqa: E402

T_FINAL, H, G = 1.0, 1e-3, 9.81
LAGRANGE_BUDGET_S = 120.0
PINOCCHIO_MAX_N = 300
GENERATED_MAX_N = 1000
"""Largest chain of ``tmm_rk4_generated`` (from ``FOLD_MIN_BODIES`` links folded over segments: its first
compile does not grow with N)."""
STRAIGHT_MAX_N = 300
"""Largest chain compiled as straight-line code too (``fold=False``): its first compile grows faster than N
(16 s at N = 100, 69 s at N = 300 on the loaded 2-core machine, 2026-11-25)."""
FOLD_COMPARE_SIZES = (20, 100, 300)
"""Sizes where folded and straight-line generated code are both measured."""


def chain(n: int) -> PlanarModel:
    elements = [Pinned("base")]
    for i in range(n):
        if i:
            elements.append(SmoothHinge(f"h{i}"))
        elements.append(RigidBody.uniform_link(f"link{i}", mass=1.0, length=1.0))
    return PlanarModel.chain(f"chain{n}", elements, gravity=(0.0, -G))


def rk4_loop(acc, q, v, h, n_steps):
    for k in range(n_steps):
        t = k * h
        a1 = acc(q, v, t)
        q2, v2 = q + 0.5 * h * v, v + 0.5 * h * a1
        a2 = acc(q2, v2, t + 0.5 * h)
        q3, v3 = q + 0.5 * h * v2, v + 0.5 * h * a2
        a3 = acc(q3, v3, t + 0.5 * h)
        q4, v4 = q + h * v3, v + h * a3
        a4 = acc(q4, v4, t + h)
        q = q + (h / 6.0) * (v + 2.0 * v2 + 2.0 * v3 + v4)
        v = v + (h / 6.0) * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return q, v


def reference(n: int, model: PlanarModel):
    q0, v0 = np.zeros(n), np.zeros(n)
    start = time.perf_counter()
    if n <= 100:
        sol = PlanarLagrange(model).simulate(q0, v0, T_FINAL, t_eval=[T_FINAL], rtol=1e-12,
                                             atol=1e-12)
        q_ref, kind = sol.y[:n, -1], "lagrange_dop853_1e-12"
    else:
        sim = simulate_scipy(model, q0, v0, t_final=T_FINAL, method="DOP853", rtol=1e-12,
                             atol=1e-12, t_eval=[T_FINAL])
        q_ref, kind = sim.q[-1], "tmm_dop853_1e-12"
    return q_ref, time.perf_counter() - start, kind


def pinocchio_chain(n: int):
    import pinocchio as pin

    model = pin.Model()
    model.gravity.linear = np.array([0.0, -G, 0.0])
    parent = 0
    for i in range(n):
        placement = pin.SE3(np.eye(3), np.array([1.0 if i else 0.0, 0.0, 0.0]))
        joint = model.addJoint(parent, pin.JointModelRZ(), placement, f"j{i}")
        inertia = pin.Inertia(1.0, np.array([0.5, 0.0, 0.0]), np.diag([1e-4, 1 / 12, 1 / 12]))
        model.appendBodyToJoint(joint, inertia, pin.SE3.Identity())
        parent = joint
    data = model.createData()
    tau = np.zeros(n)
    return lambda q, v, t: pin.aba(model, data, q, v, tau)


def mujoco_chain(n: int):
    import mujoco

    body = ""
    for i in reversed(range(n)):
        pos = "1 0 0" if i else "0 0 0"
        body = (f'<body name="l{i}" pos="{pos}"><joint name="j{i}" type="hinge" axis="0 0 1"/>'
                f'<inertial pos="0.5 0 0" mass="1" diaginertia="1e-4 {1 / 12} {1 / 12}"/>'
                f"{body}</body>")
    xml = (f'<mujoco><option timestep="{H}" integrator="RK4" gravity="0 {-G} 0">'
           f'<flag contact="disable"/></option><worldbody>{body}</worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    return model, mujoco.MjData(model), mujoco


def generated_variants(n: int) -> list[tuple[str, bool | None]]:
    """``(method name, fold)`` of the generated RK4 runs at N = ``n``: the default (``fold=None``, as
    ``ctmm.simulate(..., compiled=True)``: folded over segments from ``FOLD_MIN_BODIES`` links), and at
    :data:`FOLD_COMPARE_SIZES` the other code too (``_straight``: ``fold=False`` up to
    :data:`STRAIGHT_MAX_N`; ``_folded``: ``fold=True``)."""
    variants: list[tuple[str, bool | None]] = [("tmm_rk4_generated", None)]
    if n in FOLD_COMPARE_SIZES:
        if n >= FOLD_MIN_BODIES and n <= STRAIGHT_MAX_N:
            variants.append(("tmm_rk4_generated_straight", False))
        elif n < FOLD_MIN_BODIES:
            variants.append(("tmm_rk4_generated_folded", True))
    return variants


def run_case(n: int, results: dict, log, generated_only: bool = False) -> None:
    model = chain(n)
    q0, v0 = np.zeros(n), np.zeros(n)
    q_ref, ref_time, ref_kind = reference(n, model)
    case = {"n": n, "reference": ref_kind, "reference_wall_time_s": ref_time, "methods": {}}
    steps = int(round(T_FINAL / H))

    def record(name, q_end_absolute, wall, **extra):
        error = float(np.max(np.abs(q_end_absolute - q_ref)))
        case["methods"][name] = {"wall_time_s": wall, "time_per_step_s": wall / steps,
                                 "max_error_rad": error, **extra}
        log(f"N={n:5d} {name:15s} wall {wall:9.3f} s  per step {wall / steps * 1e6:9.1f} us  "
            f"error {error:.2e}")

    sim = simulate_rk4(model, q0, v0, t_final=T_FINAL, dt=H, store_every=steps)
    record("tmm_rk4", sim.q[-1], sim.wall_time_s)
    if n <= GENERATED_MAX_N:
        for name, fold in generated_variants(n):
            with tempfile.TemporaryDirectory() as folder:     # first compile, outside the timing
                scene = CompiledScene(model, store_every=steps, cache_dir=folder, fold=fold)
                run = lambda: simulate_rk4_generated(model, q0, v0, t_final=T_FINAL, dt=H,  # noqa: E731
                                                     store_every=steps, scene=scene)
                run()                                           # warm-up (first call into the library)
                sim = run()
            record(name, sim.q[-1], sim.wall_time_s, compile_s=scene.compile_time_s, fold_period=scene.period)
    else:
        case["methods"]["tmm_rk4_generated"] = {
            "skipped": True, "reason": f"N > {GENERATED_MAX_N}: first compile too long for this benchmark"}
    if generated_only:
        results["cases"].append(case)
        return
    sim = simulate_implicit(model, q0, v0, t_final=T_FINAL, dt=H, store_every=steps)
    record("dttmm_newmark", sim.q[-1], sim.wall_time_s,
           newton_iterations_mean=float(sim.iterations.mean()),
           newton_iterations_max=int(sim.iterations.max()))
    lag = PlanarLagrange(model)
    probe = time.perf_counter()
    for _ in range(5):
        lag.accelerations(q0 + 0.1, v0 + 0.1, 0.0)
    estimate = (time.perf_counter() - probe) / 5 * 4 * steps
    if estimate <= LAGRANGE_BUDGET_S:
        start = time.perf_counter()
        q_end, _ = rk4_loop(lambda q, v, t: lag.accelerations(q, v, t), q0, v0, H, steps)
        record("lagrange_rk4", q_end, time.perf_counter() - start)
    else:
        case["methods"]["lagrange_rk4"] = {"skipped": True, "estimated_wall_time_s": estimate,
                                           "reason": f"estimate > {LAGRANGE_BUDGET_S:.0f} s"}
        log(f"N={n:5d} lagrange_rk4    skipped (estimated {estimate:.0f} s)")
    if n > PINOCCHIO_MAX_N:
        case["methods"]["pinocchio_rk4"] = {
            "skipped": True, "reason": "pinocchio.Data of a 300-joint chain already takes 1.8 GB "
            "(measured); the 1000-joint Data was killed by the out-of-memory killer"}
    else:
        try:
            aba = pinocchio_chain(n)
            start = time.perf_counter()
            q_end, _ = rk4_loop(aba, q0.copy(), v0.copy(), H, steps)
            record("pinocchio_rk4", np.cumsum(q_end), time.perf_counter() - start)
        except ImportError:
            case["methods"]["pinocchio_rk4"] = {"skipped": True,
                                                "reason": "pinocchio not installed"}
    try:
        mj_model, mj_data, mujoco = mujoco_chain(n)
        start = time.perf_counter()
        for _ in range(steps):
            mujoco.mj_step(mj_model, mj_data)
        record("mujoco_rk4", np.cumsum(mj_data.qpos.copy()), time.perf_counter() - start)
    except ImportError:
        case["methods"]["mujoco_rk4"] = {"skipped": True, "reason": "mujoco not installed"}
    except ValueError as exc:   # MJCF nesting depth limit for long chains
        case["methods"]["mujoco_rk4"] = {"skipped": True, "reason": f"MJCF rejected: {exc}"}
    results["cases"].append(case)


def where_time_goes(n: int) -> dict:
    """Split one pure-Python forward-dynamics call into its parts (mean over repeats)."""
    from ctmm.planar.rigid_sweep import model_sweep
    from ctmm.planar.sweep import accelerations, body_terms, hinge_torques

    model = chain(n)
    rng = np.random.default_rng(0)
    q, v = rng.normal(size=n), rng.normal(size=n)
    repeats = max(5, 2000 // n)

    def timed(fn):
        start = time.perf_counter()
        for _ in range(repeats):
            out = fn()
        return (time.perf_counter() - start) / repeats, out

    start = time.perf_counter()
    accelerations(model, q, v, 0.0)                 # the first call traces the sweep (once per structure)
    trace = time.perf_counter() - start
    total, _ = timed(lambda: accelerations(model, q, v, 0.0))
    angles, (theta, omega) = timed(lambda: model.body_angles(q, v, 0.0))
    terms, (K, b, E, _) = timed(lambda: body_terms(model, theta, omega, 0.0))
    laws, tau = timed(lambda: hinge_torques(model, theta, omega, 0.0))
    zeros = np.zeros(n)
    sweep = model_sweep(model)
    kernel, _ = timed(lambda: sweep(K, b, E, zeros, tau, zeros))
    numpy_sweep, _ = timed(lambda: sweep.numpy_sweep(K, b, E, zeros, tau, zeros))
    return {"n": n, "first_call_with_trace_s": trace, "accelerations_call_s": total, "body_angles_s": angles,
            "body_terms_numpy_s": terms, "hinge_laws_s": laws,
            "recursion_traced_s": kernel, "recursion_per_body_s": kernel / n,
            "recursion_numpy_s": numpy_sweep}


def plot(results: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    names = sorted({m for c in results["cases"] for m in c["methods"]})
    for name in names:
        ns, per_step, err = [], [], []
        for c in results["cases"]:
            m = c["methods"].get(name, {})
            if "time_per_step_s" in m:
                ns.append(c["n"])
                per_step.append(m["time_per_step_s"])
                err.append(max(m["max_error_rad"], 1e-16))
        if ns:
            ax1.loglog(ns, per_step, "o-", label=name)
            ax2.loglog(per_step, err, "o-", label=name)
            for n_, x, y in zip(ns, per_step, err):
                ax2.annotate(str(n_), (x, y), fontsize=7)
    ns = np.array([5, 1000])
    ax1.loglog(ns, 1e-5 * ns, "k:", label="slope 1")
    ax1.set_xlabel("N links")
    ax1.set_ylabel("wall time per step [s]")
    ax1.legend(fontsize="small")
    ax2.set_xlabel("wall time per step [s]")
    ax2.set_ylabel("max angle error at 1 s [rad]")
    ax2.set_title("h = 1 ms, labels = N")
    fig.suptitle(f"Planar pendulum chain ({results['machine']})")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="N = 5, 20 only")
    parser.add_argument("--sizes", type=int, nargs="+", help="chain sizes N (default 5 20 100 300 1000)")
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    parser.add_argument("--generated-only", action="store_true",
                        help="the reference, numpy RK4 and generated RK4 runs only (folded against straight-line)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = {"problem": "pinned chain, N uniform links L = 1 m, m = 1 kg each, smooth hinges, "
                          "g = 9.81, horizontal at rest, T = 1 s, h = 1e-3 s",
               "error_definition": "max over links |theta_abs(1 s) - theta_ref(1 s)| [rad]",
               "machine": f"{os.cpu_count()}-core {platform.machine()}, Python "
                          f"{platform.python_version()}, numpy {np.__version__}",
               "cases": []}
    results["load_average_start"] = os.getloadavg()
    for n in args.sizes or ([5, 20] if args.quick else [5, 20, 100, 300, 1000]):
        run_case(n, results, lambda s: print(s, flush=True), args.generated_only)
    if args.generated_only:
        results["note"] = "generated runs only (--generated-only)"
        (out / "planar_chain_generated.json").write_text(json.dumps(results, indent=2) + "\n")
        return results
    results["where_time_goes"] = [where_time_goes(n) for n in (100, 1000)]
    results["load_average_end"] = os.getloadavg()
    results["note"] = ("timings are wall-clock on a shared 2-core machine (other jobs running; see "
                       "load averages): compare methods within one case, not across runs")
    (out / "planar_chain.json").write_text(json.dumps(results, indent=2) + "\n")
    plot(results, out / "planar_chain.png")
    return results


if __name__ == "__main__":
    main()
