"""Speed at matched error: spatial pendulum chains of N = 5, 10, 30, 100, 300 links.

Problems (both pinned to the ground at the first joint, g = 9.81 m/s^2 along -z, released at
rest, simulated for ``T_FINAL`` s):

* ``revolute`` -- N uniform links (1 m, 1 kg each along the body x axis, centre of mass at
  0.5 m, inertia of a solid cylinder of radius 0.1 m: diag(5e-3, 1.03/12, 1.03/12) kg m^2),
  revolute joints about the body y axis (even links) and the body z axis (odd links); starting angles 0 (y joints) and 0.2 rad (z joints):
  a horizontal zig-zag that falls and twists out of its plane.
* ``ball`` -- the same links on ball-and-socket joints, each joint turned 0.1 rad about z at the
  start (a horizontal spiral).

Error = max over links of the angle of ``R_ref^T R`` (world orientation of each link) at
``T_FINAL`` [rad].  Each peer's step is halved from ``DT_START`` until its error is <= 1e-6 rad
("matched"); every run is recorded (error and CPU time side by side; runs shorter than 1 s are
timed best of 3, for every method).  Times are CPU time of this process (``time.process_time``: every
peer runs single-threaded in it), not wall-clock, so other processes on the shared machine do not
enter them.

Peers (optional imports, benchmarks only):

* ``pinocchio_rk4`` -- Pinocchio ABA + classical RK4 in Python (quaternions integrated as
  4-vectors, ``q_dot = 1/2 q (x) (omega, 0)``, normalised every step);
* ``mujoco_rk4``    -- MuJoCo's RK4 integrator, ``mj_step`` in a Python loop (model built with
  ``MjSpec``, contacts off);
* ``ctmm_rk4``      -- ctmm's generated RK4 (``ctmm.simulate(..., compiled=True)``, the time loop
  in C generated from the spatial body and joint terms, :mod:`ctmm.compiled_spatial`): the compiled
  loop alone is timed (every 10th state stored; compiling and the verb's result assembly outside
  the timing; first compile time, wall and CPU (this process and the compiler), and instructions per
  rate evaluation in the JSON).  Chains of ``FOLD_MIN_VELOCITIES`` (20) or more velocities (revolute
  N >= 20, ball N >= 7) compile as folds over their segments (``gcc -O3``; straight-line code
  ``gcc -O1``; ``fold_period`` in the JSON; their instruction count is of the calling code only);
  ``--fold on | off`` forces the fold or the straight-line code.  Run it with ``CTMM_CACHE`` set to an
  empty folder for first-compile times.  ``--first-compile`` measures only that (issue 13's target,
  default N = 100): each chain compiled into a fresh cache folder at the default flags, CPU and wall, C
  size, and the kernel's CPU per step, in ``results/spatial_chain_first_compile.json``.

(A thinner rod, axial inertia 1e-4 kg m^2 as in the planar benchmark, made the ball chain of
N = 100 blow up (NaN) in Pinocchio ABA + RK4 within 0.3 s at h = 1 ms while N = 30 and 60 ran
fine and alike; the near-massless axial spin is the suspect, not investigated further.)

Reference: the global equations ``M(q) vdot = -h(q, v)`` with Pinocchio's CRBA (``M``) and
``nonLinearEffects`` (``h``), dense Cholesky, and the same RK4 at the fine step
``DT_START / 2^5`` (0.3 ms); its own error is estimated as ``|fine - (2 x fine step)| / 15``
and stored; where it exceeds 10 % of the target no step is declared "matched" (the ball chain
of N = 100: round-off amplified by the motion, estimate 9e-7 rad).  At N = 5 the
reference is checked against the independent global model :mod:`ctmm.reference.spatial_tree`
(scipy DOP853, rtol = atol = 1e-12); the difference is in the JSON.  Not ABA, because ABA
loses accuracy on long ball-joint chains: at N = 100 (state after 0.5 s) Pinocchio's ABA
accelerations differed by 0.17 (of 33) rad/s^2 from the global model, while CRBA + Cholesky
and MuJoCo agreed with it to 5e-8 (condition number of M 3.5e8); each case stores
``aba_minus_crba`` at the reference's final state.  (scipy DOP853 at 1e-12 on ABA also stalled
there.)  Pinocchio's ``Data`` grows like N^3 (measured 0.13 / 0.45 / 1.8 GB for ball chains of N = 30 /
60 / 100), so ball chains with N > 100 have no reference and are skipped, as are runs whose
estimated wall time exceeds ``RUN_BUDGET_S``.

Run ``python benchmarks/spatial_chain.py`` (``--quick``: N = 5, 10; ``--sizes``, ``--kinds`` to choose); writes
``benchmarks/results/spatial_chain.json`` and ``spatial_chain.png``.
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import platform
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.integrate  # noqa: E402
import scipy.linalg  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from ctmm.reference import spatial_tree as reference_model  # noqa: E402

try:                                   # the spatial TMM (issue 14), if it has landed
    import ctmm.spatial as ctmm_spatial  # noqa: E402
except ImportError:
    ctmm_spatial = None

T_FINAL, G = 1.0, 9.81
TARGET_RAD = 1e-6
DT_START = 1e-2
HALVINGS = 6
REFERENCE_DT = DT_START / 2 ** 5
RUN_BUDGET_S = 40.0
REPEATS, REPEAT_BELOW_S = 3, 1.0    # every method: runs shorter than 1 s timed best of 3
PINOCCHIO_MAX_NV = 300          # Data of nv = 300 already takes ~1.8 GB (N^3 growth)
INERTIA = np.diag([5e-3, 1.03 / 12, 1.03 / 12])   # 1 kg, 1 m rod of radius 0.1 m
COM = np.array([0.5, 0.0, 0.0])
KINDS = ("revolute", "ball")


def revolute_axis(i: int) -> np.ndarray:
    return np.array([0.0, 1.0, 0.0]) if i % 2 == 0 else np.array([0.0, 0.0, 1.0])


def initial_state(n: int, kind: str):
    """Pinocchio / reference layout: angles, or scalar-last quaternions; zero velocities."""
    if kind == "revolute":
        q = np.array([0.0 if i % 2 == 0 else 0.2 for i in range(n)])
        return q, np.zeros(n)
    quat = np.array([0.0, 0.0, np.sin(0.05), np.cos(0.05)])
    return np.tile(quat, n), np.zeros(3 * n)


def quaternion_rates(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``1/2 q (x) (omega, 0)`` for all joints of a ball chain (scalar-last)."""
    quat, omega = q.reshape(-1, 4), v.reshape(-1, 3)
    vec, w = quat[:, :3], quat[:, 3:]
    rate_vec = 0.5 * (w * omega + np.cross(vec, omega))
    rate_w = -0.5 * np.sum(vec * omega, axis=1, keepdims=True)
    return np.hstack([rate_vec, rate_w]).ravel()


def normalize_quaternions(q: np.ndarray) -> np.ndarray:
    quat = q.reshape(-1, 4)
    return (quat / np.linalg.norm(quat, axis=1, keepdims=True)).ravel()


def rotation_error(rotations: np.ndarray, reference: np.ndarray) -> float:
    """Largest angle [rad] of ``R_ref^T R`` over the links."""
    relative = np.einsum("bji,bjk->bik", reference, rotations)
    cosine = np.clip((np.trace(relative, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    sine = np.linalg.norm(relative - np.transpose(relative, (0, 2, 1)), axis=(1, 2)) / (2 ** 1.5)
    return float(np.max(np.arctan2(sine, cosine)))


# -- Pinocchio --------------------------------------------------------------------------------
class PinocchioChain:
    def __init__(self, n: int, kind: str) -> None:
        import pinocchio as pin

        self.pin, self.n, self.kind = pin, n, kind
        model = pin.Model()
        model.gravity.linear = np.array([0.0, 0.0, -G])
        parent = 0
        for i in range(n):
            placement = pin.SE3(np.eye(3), np.array([1.0 if i else 0.0, 0.0, 0.0]))
            joint = (pin.JointModelRevoluteUnaligned(revolute_axis(i)) if kind == "revolute"
                     else pin.JointModelSpherical())
            parent = model.addJoint(parent, joint, placement, f"j{i}")
            model.appendBodyToJoint(parent, pin.Inertia(1.0, COM, INERTIA), pin.SE3.Identity())
        self.model, self.data = model, model.createData()
        self.tau = np.zeros(model.nv)

    def acceleration(self, q, v):
        return self.pin.aba(self.model, self.data, q, v, self.tau)

    def global_acceleration(self, q, v):
        """``M^{-1} (-h)`` with CRBA and nonLinearEffects (dense Cholesky)."""
        pin = self.pin
        mass = pin.crba(self.model, self.data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        bias = pin.nonLinearEffects(self.model, self.data, q, v)
        return scipy.linalg.cho_solve(scipy.linalg.cho_factor(mass), -bias)

    def rates(self, q, v, method: str = "aba"):
        qdot = v if self.kind == "revolute" else quaternion_rates(q, v)
        if method == "aba":
            return qdot, self.acceleration(q, v)
        return qdot, self.global_acceleration(q, v)

    def rotations(self, q) -> np.ndarray:
        if self.kind == "ball":
            q = normalize_quaternions(q)
        self.pin.forwardKinematics(self.model, self.data, q)
        return np.array([self.data.oMi[j].rotation for j in range(1, self.n + 1)])

    def rk4(self, q, v, dt: float, steps: int, method: str = "aba"):
        for _ in range(steps):
            k1q, k1v = self.rates(q, v, method)
            k2q, k2v = self.rates(q + 0.5 * dt * k1q, v + 0.5 * dt * k1v, method)
            k3q, k3v = self.rates(q + 0.5 * dt * k2q, v + 0.5 * dt * k2v, method)
            k4q, k4v = self.rates(q + dt * k3q, v + dt * k3v, method)
            q = q + dt / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
            v = v + dt / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
            if self.kind == "ball":
                q = normalize_quaternions(q)
        return q, v


# -- MuJoCo -----------------------------------------------------------------------------------
def mujoco_chain(n: int, kind: str, dt: float):
    import mujoco

    spec = mujoco.MjSpec()
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_RK4
    spec.option.timestep = dt
    spec.option.gravity = [0.0, 0.0, -G]
    spec.option.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    body = spec.worldbody
    for i in range(n):
        body = body.add_body(pos=[1.0 if i else 0.0, 0.0, 0.0], mass=1.0, ipos=COM.tolist(),
                             inertia=np.diag(INERTIA).tolist())
        if kind == "revolute":
            body.add_joint(type=mujoco.mjtJoint.mjJNT_HINGE, axis=revolute_axis(i).tolist())
        else:
            body.add_joint(type=mujoco.mjtJoint.mjJNT_BALL)
    model = spec.compile()
    data = mujoco.MjData(model)
    q0, _ = initial_state(n, kind)
    if kind == "ball":                         # MuJoCo quaternions are scalar-first
        q0 = q0.reshape(-1, 4)[:, [3, 0, 1, 2]].ravel()
    data.qpos[:] = q0
    return mujoco, model, data


def mujoco_run(n: int, kind: str, dt: float, steps: int):
    mujoco, model, data = mujoco_chain(n, kind, dt)
    start = time.process_time()
    for _ in range(steps):
        mujoco.mj_step(model, data)
    wall = time.process_time() - start
    mujoco.mj_kinematics(model, data)
    return data.xmat[1:].reshape(n, 3, 3).copy(), wall


# -- ctmm -------------------------------------------------------------------------------------
CTMM_STORE_EVERY = 10        # every dt of the halvings gives a whole number of strides (100 2^k steps)
CTMM_SCENES: dict = {}       # (n, kind) -> compiled scene (compiled once per chain, outside the timing)
CTMM_COMPILE_CPU: dict = {}  # (n, kind) -> CPU time of its first compile [s] (this process and the compiler)
CTMM_FOLD = None             # ctmm.compiled_spatial: None = the library's rule (fold from FOLD_MIN_VELOCITIES)


def ctmm_model(n: int, kind: str):
    """The chain as a ``ctmm.spatial.SpatialModel``: body origin at the inboard joint, the next joint
    at (1, 0, 0) of the body, as the Pinocchio placements."""
    sp = ctmm_spatial
    elements = []
    for i in range(n):
        elements.append(sp.SpatialBody(f"l{i}", 1.0, INERTIA, COM, {"end": (1.0, 0.0, 0.0)}))
        common = dict(name=f"j{i}", parent=None if i == 0 else f"l{i - 1}", child=f"l{i}",
                      point=(0.0, 0.0, 0.0) if i == 0 else "end")
        elements.append(sp.Revolute(axis=revolute_axis(i), **common) if kind == "revolute"
                        else sp.Spherical(**common))
    return sp.SpatialModel(f"{kind}_chain_{n}", elements, gravity=(0.0, 0.0, -G))


def cpu_with_compiler() -> float:
    """CPU time [s] of this process and of its finished children (the compiler)."""
    import resource

    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def ctmm_scene(n: int, kind: str):
    """The compiled scene of the chain (generated, compiled or loaded from the cache on first use;
    its ``compile_time_s`` is recorded)."""
    from ctmm.compiled_spatial import CompiledSpatialScene

    if (n, kind) not in CTMM_SCENES:
        start = cpu_with_compiler()
        CTMM_SCENES[(n, kind)] = CompiledSpatialScene(ctmm_model(n, kind), store_every=CTMM_STORE_EVERY,
                                                      fold=CTMM_FOLD)
        CTMM_COMPILE_CPU[(n, kind)] = cpu_with_compiler() - start
    return CTMM_SCENES[(n, kind)]


def first_compile_case(n: int, kind: str, steps: int = 1280, repeats: int = 5) -> dict:
    """The first compile of the chain's generated RK4 into a fresh cache folder at the library's default flags (issue
    13's target: <= 3 s for a 100-body scene): CPU of this process and the compiler, wall time, the C text's size,
    and the compiled loop's CPU per step (``steps`` steps of 1 ms, every 10th stored, best of ``repeats``)."""
    import tempfile

    from ctmm.compiled_spatial import CompiledSpatialScene

    model = ctmm_model(n, kind)
    with tempfile.TemporaryDirectory() as folder:
        start_cpu, start_wall = cpu_with_compiler(), time.perf_counter()
        scene = CompiledSpatialScene(model, store_every=CTMM_STORE_EVERY, cache_dir=folder, fold=CTMM_FOLD)
        wall, cpu = time.perf_counter() - start_wall, cpu_with_compiler() - start_cpu
        c_bytes = sum(path.stat().st_size for path in Path(folder).rglob("*.c"))
    q0, v0 = initial_state(n, kind)
    if kind == "ball":                          # ctmm quaternions are scalar-first
        q0 = q0.reshape(-1, 4)[:, [3, 0, 1, 2]].ravel()
    x0 = np.concatenate([q0, v0])
    per_step = []
    for _ in range(repeats):
        start = time.process_time()
        scene.run(x0, 1e-3, steps)
        per_step.append((time.process_time() - start) / steps)
    return {"n": n, "kind": kind, "fold_period": scene.rates.period, "first_compile_cpu_s": cpu,
            "first_compile_wall_s": wall, "c_bytes": c_bytes, "per_step_cpu_us": min(per_step) * 1e6,
            "load_average": os.getloadavg()}


def ctmm_adapter(n: int, kind: str, dt: float):
    """ctmm's generated RK4 (``ctmm.compiled_spatial``, what ``ctmm.simulate(model, T_FINAL, dt,
    compiled=True)`` runs): the compiled time loop alone is timed (``CompiledSpatialScene.run``, every
    10th state stored), compiling outside the timing and the verb's result assembly (body positions and
    angular velocities of every stored row, numpy) excluded, as the peers store nothing.  Quaternions
    are integrated as coordinates, not normalised (rotations use ``q / |q|``).  Returns the (n, 3, 3)
    world orientations of the links at ``T_FINAL`` and the CPU time [s]."""
    from ctmm.ops import NUMPY

    scene = ctmm_scene(n, kind)
    model = scene.model
    steps = int(round(T_FINAL / dt))
    q0, v0 = initial_state(n, kind)
    if kind == "ball":                          # ctmm quaternions are scalar-first
        q0 = q0.reshape(-1, 4)[:, [3, 0, 1, 2]].ravel()
    x0 = np.concatenate([q0, v0])
    start = time.process_time()
    states = scene.run(x0, dt, steps)
    wall = time.process_time() - start
    q_end, v_end = states[-1, :model.n_positions], states[-1, model.n_positions:]
    bodies = ctmm_spatial.SpatialScene(model).terms(NUMPY, q_end[None], v_end[None])[2]
    return np.array([body.rotation[0] for body in bodies]), wall


# -- driver -----------------------------------------------------------------------------------
def fine_reference(chain: "PinocchioChain", q0, v0):
    """Rotations at T_FINAL (CRBA + Cholesky, RK4 at REFERENCE_DT), the estimate of their
    error [rad] and the final state."""
    q, v = chain.rk4(q0.copy(), v0.copy(), REFERENCE_DT, int(round(T_FINAL / REFERENCE_DT)),
                     "global")
    coarse = chain.rotations(chain.rk4(q0.copy(), v0.copy(), 2 * REFERENCE_DT,
                                       int(round(T_FINAL / (2 * REFERENCE_DT))), "global")[0])
    fine = chain.rotations(q)
    return fine, rotation_error(coarse, fine) / 15.0, (q, v)


def reference_tree(n: int, kind: str) -> "reference_model.SpatialTree":
    """The chain as a tree of the independent global model."""
    joint = "revolute" if kind == "revolute" else "spherical"
    bodies = [reference_model.SpatialBody(
        f"l{i}", i - 1, joint, 1.0, COM, INERTIA,
        axes=[revolute_axis(i)] if kind == "revolute" else np.zeros((0, 3)),
        joint_position=(1.0 if i else 0.0, 0.0, 0.0)) for i in range(n)]
    return reference_model.SpatialTree(tuple(bodies), gravity=(0.0, 0.0, -G))


def reference_check(log) -> dict:
    """At N = 5: the Pinocchio fine-step reference against the independent global model."""
    out = {}
    for kind in KINDS:
        n = 5
        chain = PinocchioChain(n, kind)
        q0, v0 = initial_state(n, kind)
        tree = reference_tree(n, kind)

        def rhs(_t, y, tree=tree):
            q, v = y[: tree.nq], y[tree.nq:]
            return np.concatenate([reference_model.configuration_rate(tree, q, v),
                                   reference_model.forward_dynamics(tree, q, v)])

        sol = scipy.integrate.solve_ivp(rhs, (0.0, T_FINAL), np.concatenate([q0, v0]),
                                        method="DOP853", rtol=1e-12, atol=1e-12,
                                        t_eval=[T_FINAL])
        difference = rotation_error(chain.rotations(sol.y[: tree.nq, -1]),
                                    fine_reference(chain, q0, v0)[0])
        out[kind] = {"n": n, "global_model": "spatial_tree + DOP853 1e-12",
                     "max_rotation_difference_rad": difference}
        log(f"reference check N=5 {kind}: Pinocchio vs global model {difference:.1e} rad")
    return out


def halving_runs(run, estimate_one_step, log, label) -> dict:
    """Run with dt = DT_START / 2^k until the error is <= TARGET_RAD (or the budget ends)."""
    runs, matched = [], None
    for k in range(HALVINGS + 1):
        dt = DT_START / 2 ** k
        steps = int(round(T_FINAL / dt))
        estimate = estimate_one_step() * steps
        if estimate > RUN_BUDGET_S:
            runs.append({"dt_s": dt, "skipped": True, "estimated_wall_time_s": estimate})
            log(f"{label} dt {dt:.2e} skipped (estimated {estimate:.0f} s)")
            break
        error, wall = run(dt, steps)
        if wall < REPEAT_BELOW_S:          # short runs: best of REPEATS (a shared machine's noise)
            wall = min([wall] + [run(dt, steps)[1] for _ in range(REPEATS - 1)])
        runs.append({"dt_s": dt, "max_error_rad": error, "cpu_time_s": wall,
                     "time_per_step_s": wall / steps})
        log(f"{label} dt {dt:.2e} cpu {wall:8.3f} s  error {error:.2e}")
        if error <= TARGET_RAD:
            matched = runs[-1]
            break
    return {"runs": runs, "matched": matched}


def one_step_time(run_steps, repeats: int = 3) -> float:
    start = time.process_time()
    run_steps(repeats)
    return (time.process_time() - start) / repeats


def run_case(n: int, kind: str, log) -> dict:
    nv = n if kind == "revolute" else 3 * n
    case = {"n": n, "kind": kind, "methods": {}}
    if nv > PINOCCHIO_MAX_NV:
        case["skipped"] = (f"no reference: Pinocchio Data for nv = {nv} would need ~"
                           f"{1.8 * (nv / 300) ** 3:.0f} GB (N^3 growth, measured)")
        log(f"N={n} {kind}: {case['skipped']}")
        return case
    chain = PinocchioChain(n, kind)
    q0, v0 = initial_state(n, kind)
    start = time.perf_counter()
    reference, estimate, (q_end, v_end) = fine_reference(chain, q0, v0)
    if kind == "ball":
        q_end = normalize_quaternions(q_end)
    global_acc = chain.global_acceleration(q_end, v_end)
    case["aba_minus_crba"] = {
        "max_abs_rad_s2": float(np.max(np.abs(chain.acceleration(q_end, v_end) - global_acc))),
        "max_abs_acceleration_rad_s2": float(np.max(np.abs(global_acc)))}
    case["reference"] = f"pinocchio_crba_cholesky_rk4_dt_{REFERENCE_DT:.3g}"
    case["reference_error_estimate_rad"] = estimate
    case["reference_accurate_enough"] = bool(estimate <= 0.1 * TARGET_RAD)
    case["reference_wall_time_s"] = time.perf_counter() - start
    label = f"N={n:4d} {kind:8s}"

    def pin_run(dt, steps):
        t0 = time.process_time()
        q, _ = chain.rk4(q0.copy(), v0.copy(), dt, steps)
        wall = time.process_time() - t0
        return rotation_error(chain.rotations(q), reference), wall

    case["methods"]["pinocchio_rk4"] = halving_runs(
        pin_run, lambda: one_step_time(lambda k: chain.rk4(q0.copy(), v0.copy(), 1e-3, k)),
        log, f"{label} pinocchio_rk4")
    try:
        def mj_run(dt, steps):
            rotations, wall = mujoco_run(n, kind, dt, steps)
            return rotation_error(rotations, reference), wall

        case["methods"]["mujoco_rk4"] = halving_runs(
            mj_run, lambda: mujoco_run(n, kind, 1e-3, 3)[1] / 3, log, f"{label} mujoco_rk4")
    except ImportError:
        case["methods"]["mujoco_rk4"] = {"skipped": "mujoco not installed"}
    if ctmm_spatial is None:
        case["methods"]["ctmm_rk4"] = {"skipped": "ctmm.spatial not available"}
    else:
        try:
            def ctmm_run(dt, steps):
                rotations, wall = ctmm_adapter(n, kind, dt)
                return rotation_error(rotations, reference), wall

            case["methods"]["ctmm_rk4"] = halving_runs(
                ctmm_run, lambda: ctmm_adapter(n, kind, T_FINAL / 10)[1] / 10, log,
                f"{label} ctmm_rk4")
            scene = ctmm_scene(n, kind)
            case["methods"]["ctmm_rk4"].update({
                "first_compile_s": scene.compile_time_s,
                "first_compile_cpu_s": CTMM_COMPILE_CPU[(n, kind)],
                "compile_note": ("generate C, compile (gcc -O3 folded, -O1 straight-line) or load from the cache; "
                                 "once per chain"),
                "instructions_per_rate": int(scene.rates.velocity_rate.n_instructions()),
                "fold_period": scene.rates.period})
            log(f"{label} ctmm_rk4 first compile {scene.compile_time_s:.1f} s")
        except NotImplementedError as exc:
            case["methods"]["ctmm_rk4"] = {"skipped": str(exc)}
    if not case["reference_accurate_enough"]:
        for method in case["methods"].values():
            if method.get("matched"):
                method["matched"] = None
                method["matched_withheld"] = ("reference error estimate "
                                              f"{estimate:.1e} rad > 10 % of the target")
    del chain
    gc.collect()
    return case


def plot(results: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    styles = {"revolute": "-", "ball": "--"}
    for kind in KINDS:
        for name in ("pinocchio_rk4", "mujoco_rk4", "ctmm_rk4"):
            ns, walls = [], []
            for case in results["cases"]:
                matched = case["methods"].get(name, {}).get("matched") \
                    if case["kind"] == kind else None
                if matched:
                    ns.append(case["n"])
                    walls.append(matched["cpu_time_s"])
            if ns:
                ax1.loglog(ns, walls, "o" + styles[kind], label=f"{name} {kind}")
    ax1.set_xlabel("N links")
    ax1.set_ylabel(f"CPU time at error <= {TARGET_RAD:g} rad [s]")
    ax1.legend(fontsize="small")
    for case in results["cases"]:
        if case["n"] != 30:
            continue
        for name, method in case["methods"].items():
            points = [(r["cpu_time_s"], r["max_error_rad"]) for r in method.get("runs", [])
                      if "cpu_time_s" in r]
            if points:
                x, y = zip(*points)
                ax2.loglog(x, y, "o" + styles[case["kind"]], label=f"{name} {case['kind']}")
    ax2.axhline(TARGET_RAD, color="k", lw=0.5)
    ax2.set_xlabel("CPU time [s]")
    ax2.set_ylabel(f"max link orientation error at {T_FINAL:g} s [rad]")
    ax2.set_title("N = 30: work against precision (dt halved)")
    if ax2.get_legend_handles_labels()[0]:
        ax2.legend(fontsize="small")
    fig.suptitle(f"Spatial pendulum chains ({results['machine']})")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="N = 5, 10 only")
    parser.add_argument("--sizes", type=int, nargs="+", help="chain lengths N (default 5 10 30 100 300)")
    parser.add_argument("--kinds", nargs="+", choices=KINDS, default=list(KINDS))
    parser.add_argument("--fold", choices=("auto", "on", "off"), default="auto",
                        help="ctmm: fold over segments (on), straight-line code (off), or the library's rule")
    parser.add_argument("--first-compile", action="store_true",
                        help="ctmm's first compile only (fresh cache folder, default flags; sizes default 100): "
                             "spatial_chain_first_compile.json")
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = parser.parse_args(argv)
    global CTMM_FOLD
    CTMM_FOLD = {"auto": None, "on": True, "off": False}[args.fold]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    def log(text):
        print(text, flush=True)

    if args.first_compile:
        cases = [first_compile_case(n, kind) for n in args.sizes or [100] for kind in args.kinds]
        for case in cases:
            log(f"{case['kind']} N = {case['n']}: first compile {case['first_compile_cpu_s']:.2f} s CPU "
                f"({case['first_compile_wall_s']:.2f} s wall), C {case['c_bytes'] / 1e3:.0f} kB, "
                f"{case['per_step_cpu_us']:.1f} us per step")
        results = {"definition": " ".join(first_compile_case.__doc__.split()),
                   "machine": f"{os.cpu_count()}-core {platform.machine()}, Python {platform.python_version()}",
                   "cases": cases}
        (out / "spatial_chain_first_compile.json").write_text(json.dumps(results, indent=2) + "\n")
        return results

    results = {"problem": __doc__.split("Error =")[0].strip(),
               "error_definition": f"max over links of angle(R_ref^T R) at T = {T_FINAL} s "
                                   f"[rad]; matched = largest dt = {DT_START:g}/2^k with "
                                   f"error <= {TARGET_RAD:g}",
               "machine": f"{os.cpu_count()}-core {platform.machine()}, Python "
                          f"{platform.python_version()}, numpy {np.__version__}",
               "load_average_start": os.getloadavg(), "cases": []}
    results["reference_check"] = reference_check(log)
    results["ctmm_fold"] = args.fold
    for n in args.sizes or ([5, 10] if args.quick else [5, 10, 30, 100, 300]):
        for kind in args.kinds:
            results["cases"].append(run_case(n, kind, log))
    results["load_average_end"] = os.getloadavg()
    results["note"] = ("CPU time of the runs (time.process_time) on a shared 2-core machine (see load averages; "
                       "first_compile_s is wall-clock, first_compile_cpu_s CPU): compare methods within one case")
    (out / "spatial_chain.json").write_text(json.dumps(results, indent=2) + "\n")
    plot(results, out / "spatial_chain.png")
    return results


if __name__ == "__main__":
    main()
