"""Spatial frequency responses: the one sweep's frequency context against the dense resolvent (issues 13/14).

Problem: a serial chain of N rigid links (0.4 m, 1 kg, principal inertias (0.002, 0.014, 0.014) kg m^2) on
revolute joints whose axes alternate z, y, x (stiffness 50 N m/rad, damping 0.2 N m s/rad, every joint
actuated), in zero gravity at rest (``"gravity": "none"``) and hanging in gravity ``GRAVITY`` (along the chain,
with a sideways part: ``"gravity": "hanging"``) at its static equilibrium (every joint deflected and preloaded: the
joint coupling and the rotation stiffness of ``ctmm.spatial_transfer_response``);
``ctmm.frequency_response(chain, np.logspace(-1, 2, 500), input=["j<N-1>.torque", "link<N-1>.tip.force_y"],
output=["j<N-1>.angle", "link<N-1>.tip.z"])``.

Methods (one run, one machine):

* ``sweep``      -- :func:`ctmm.frequency_response` with the operating point given: the one articulated sweep
                    (``d = 6``) on the linearised terms, batched over the 500 frequencies, O(N) per frequency;
* ``sweep_only`` -- :meth:`~ctmm.spatial_transfer_response.SpatialSweepResponse.response` alone (terms
                    linearised beforehand): the per-frequency work, by the compiled kernel of
                    :mod:`ctmm.compiled_sweep` at ``d = 6`` (the default with a C compiler; the chain is damped: its
                    complex variant); ``kernel_only`` its C call alone (both inputs in one call);
* ``sweep_only_generic`` -- the same without a compiler: the generic numpy sweep
                    (:func:`ctmm.articulated.articulated_sweep`), one sweep per input;
* ``planar_kernel_only`` -- for scale, the same kernel at ``d = 3`` on the planar pendulum chain of
                    ``benchmarks/planar_chain.py`` with N links (one load case, undamped: the real variant);
                    ``kernel_vs_planar_kernel`` the ratio of CPU times (the spatial kernel's arithmetic: 6 x 6 blocks,
                    products with ``S``, two load cases, complex numbers);
* ``operating_point_check`` -- :func:`ctmm.spatial_linearization.operating_point` of the given point (the
                    equilibrium check of the whole call; the later time probes only where the time enters);
                    ``output_rows`` -- :func:`ctmm.spatial_linearization.output_matrix` of the two outputs (the
                    complex step of the sensors along the position directions);
* ``first_compile`` -- wall time and the compiler's CPU time of building each ``d = 6`` variant into an empty cache
                    folder (then cached on disk);
* ``resolvent``  -- the former path: :func:`ctmm.linearize` (complex-step tangent, 2N x 2N) and the dense
                    ``(s I - A)^-1 B`` with a condition number per frequency
                    (:func:`ctmm.controlled_linearization.delayed_loop_response`).

Times: best wall time ``*_s`` and best CPU time ``*_cpu_s`` of this process.  Error: largest
``|G_sweep - G_resolvent|`` over the frequencies, relative to the largest ``|G|`` of each (output, input) pair
(of a pair zero by structure -- the hanging chain's tip ``z`` under the last torque, 1e-24 of round-off -- to the
largest ``|G|`` of all pairs)
(the accuracy against the independent Newton-Euler and Lagrange references is in
``tests/test_spatial_frf_sweep.py`` and ``tests/test_spatial_frf_sweep_gravity.py``).  Run ``python benchmarks/spatial_frf.py`` (``--quick``: N = 5 only;
``--sizes``, default 5 and 30); writes ``benchmarks/results/spatial_frf.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
if str(ROOT / "benchmarks") not in sys.path:
    sys.path.insert(0, str(ROOT / "benchmarks"))

import ctmm  # noqa: E402
import ctmm.spatial as sp  # noqa: E402
from ctmm.controlled_linearization import delayed_loop_response  # noqa: E402
from ctmm.errors import ModelError  # noqa: E402
from ctmm.spatial_linearization import linearize_spatial, operating_point, output_matrix  # noqa: E402
from ctmm.spatial_transfer_response import SpatialSweepResponse  # noqa: E402
from ctmm.sweep_response import PIVOT_TOLERANCE, RESIDUAL_TOLERANCE  # noqa: E402
from planar_frf import best, write_result  # noqa: E402  (best wall and CPU time; the JSON)

OMEGA = np.logspace(-1, 2, 500)
RESULTS = ROOT / "benchmarks" / "results" / "spatial_frf.json"
AXES = ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0))
GRAVITY = (-9.81, 0.0, -0.5)
"""[m/s^2] of the hanging case: along the chain (-x) with a sideways part that deflects it."""


def chain(n: int, gravity: tuple = (0.0, 0.0, 0.0)) -> sp.SpatialModel:
    """The sprung chain of the module docstring (default weightless)."""
    elements: list = []
    for j in range(n):
        elements.append(sp.SpatialBody(f"link{j}", 1.0, (0.002, 0.014, 0.014), center_of_mass=(0.2, 0.0, 0.0),
                                       points={"tip": (0.4, 0.0, 0.0)}))
        elements.append(sp.Revolute(name=f"j{j}", parent=None if j == 0 else f"link{j - 1}", child=f"link{j}",
                                    point=(0.0, 0.0, 0.0) if j == 0 else "tip", axis=AXES[j % 3], stiffness=50.0,
                                    damping=0.2, actuated=True))
    return sp.SpatialModel(f"spatial_chain{n}", elements, gravity=gravity)


def ports(n: int) -> tuple[list, list]:
    return [f"j{n - 1}.torque", f"link{n - 1}.tip.force_y"], [f"j{n - 1}.angle", f"link{n - 1}.tip.z"]


def at_rest(model: sp.SpatialModel) -> tuple[np.ndarray, np.ndarray]:
    """The equilibrium: the neutral pose in zero gravity, else the static equilibrium."""
    if not np.any(model.gravity):
        return model.neutral(), np.zeros(model.n_velocities)
    return operating_point(model).q, np.zeros(model.n_velocities)


def sweep(model: sp.SpatialModel, n: int, omega: np.ndarray = OMEGA, point: tuple | None = None):
    inputs, outputs = ports(n)
    return ctmm.frequency_response(model, omega, input=inputs, output=outputs,
                                   operating_point=at_rest(model) if point is None else point)


def resolvent(model: sp.SpatialModel, n: int, omega: np.ndarray = OMEGA, point: tuple | None = None) -> np.ndarray:
    inputs, outputs = ports(n)
    point = at_rest(model) if point is None else point
    return delayed_loop_response(lambda a, b: linearize_spatial(model, point, inputs=a, outputs=b), (),
                                 1j * omega, inputs, outputs, model.name)[0]


def generic_plant(model: sp.SpatialModel, point) -> SpatialSweepResponse:
    """The plant as it is without a C compiler (the generic numpy sweep)."""
    import ctmm.sweep_response as sweep_module

    present = sweep_module.compiler_present
    sweep_module.compiler_present = lambda: False
    try:
        plant = SpatialSweepResponse(model, point)
    finally:
        sweep_module.compiler_present = present
    assert plant.compiled is None
    return plant


def kernel_call(plant, inputs: list):
    """The compiled kernel's C call of ``plant`` for ``inputs`` (body loads and joint torques as the plant forms
    them) as a repeatable call."""
    kernel = plant.compiled
    h = np.zeros((len(plant.bodies), kernel.d, len(inputs)))
    tau = np.zeros((len(kernel.free), len(inputs)))
    for i, (body_loads, joints) in enumerate(plant.loads(name) for name in inputs):
        h[:, :, i] = np.stack([column[0, :, 0] for column in body_loads])
        for k, j in enumerate(kernel.free):
            if joints[j].tau is not None:
                tau[k, i] = np.asarray(joints[j].tau).reshape(-1)[0].real
    return lambda: kernel.solve(1j * OMEGA, h, tau, pivot_tolerance=PIVOT_TOLERANCE,
                                residual_tolerance=RESIDUAL_TOLERANCE)


def planar_kernel(n: int):
    """The d = 3 kernel's C call on the planar pendulum chain of N links (hanging, one load case)."""
    from planar_chain import chain as planar_chain
    from planar_frf import hanging, ports as planar_ports
    from ctmm.planar_linearization import operating_point as planar_point
    from ctmm.planar_transfer_response import SweepResponse

    model = planar_chain(n)
    plant = SweepResponse(model, planar_point(model, hanging(n)))
    assert plant.compiled is not None
    return kernel_call(plant, [planar_ports(n)[0]])


def first_compile() -> dict:
    """Wall time and the compiler's CPU time [s] of building each d = 6 kernel variant into an empty cache folder."""
    import tempfile
    import time

    from ctmm.codegen import shared_library
    from ctmm.compiled_sweep import COMPLEX_FLAGS, REAL_FLAGS, kernel_source

    out = {}
    for label, complex_scalar, flags in (("real", False, REAL_FLAGS), ("complex", True, COMPLEX_FLAGS)):
        folder = tempfile.mkdtemp(prefix="ctmm-bench-spatial-frf-cache-")
        started, before = time.perf_counter(), os.times()
        shared_library(kernel_source(6, complex_scalar), "first_compile", flags=flags, cache_dir=folder)
        after = os.times()
        out[f"first_compile_d6_{label}_s"] = time.perf_counter() - started
        out[f"first_compile_d6_{label}_cpu_s"] = (after.children_user - before.children_user
                                                  + after.children_system - before.children_system)
    return out


def run(n: int, hanging: bool = False) -> dict:
    model = chain(n, GRAVITY if hanging else (0.0, 0.0, 0.0))
    inputs, outputs = ports(n)
    try:
        point = at_rest(model)                          # the equilibrium search is not timed
    except ModelError as exc:                           # recorded, not timed (N = 100 hanging: not found)
        out = {"n_links": n, "gravity": "hanging" if hanging else "none", "no_operating_point": str(exc)}
        print(json.dumps(out), flush=True)
        return out
    plant = SpatialSweepResponse(model, operating_point(model, point))
    generic = generic_plant(model, operating_point(model, point))
    cases = {"sweep": (lambda: sweep(model, n, point=point), 5),
             "sweep_only": (lambda: plant.response(1j * OMEGA, inputs, outputs), 5),
             "sweep_only_generic": (lambda: generic.response(1j * OMEGA, inputs, outputs), 3),
             "operating_point_check": (lambda: operating_point(model, point), 5),
             "output_rows": (lambda: output_matrix(model, outputs, plant.point, plant.ports), 5),
             "resolvent": (lambda: resolvent(model, n, point=point), 1)}
    if plant.compiled is not None:
        cases["kernel_only"] = (kernel_call(plant, inputs), 5)
        cases["planar_kernel_only"] = (planar_kernel(n), 5)
    out, results = {"n_links": n, "gravity": "hanging" if hanging else "none", "n_frequencies": int(OMEGA.size),
                    "largest_joint_angle_rad": float(np.max(np.abs(point[0]), initial=0.0))}, {}
    for name, (call, count) in cases.items():
        out[f"{name}_s"], out[f"{name}_cpu_s"], results[name] = best(call, count)
    G, dense = results["sweep"].response, results["resolvent"]
    scale = np.max(np.abs(dense), axis=-1, keepdims=True)
    overall = float(np.max(scale))
    # a pair that is zero by structure (its largest entry round-off, below 1e-12 of the largest of all pairs):
    # its error against the largest of all pairs
    scale = np.where(scale > 1e-12 * overall, scale, overall)
    if plant.compiled is not None:
        out["kernel_vs_planar_kernel"] = out["kernel_only_cpu_s"] / out["planar_kernel_only_cpu_s"]
    compiled, fallback = results["sweep_only"], results["sweep_only_generic"]
    out["error_generic_vs_compiled"] = float(np.max(np.abs(compiled[0] - fallback[0])) / np.max(np.abs(fallback[0])))
    out["generic_certifies_the_same"] = bool(np.array_equal(compiled[1], fallback[1]))
    out.update({"error_sweep_vs_resolvent": float(np.max(np.abs(G - dense) / scale)),
                "dense_frequencies_in_sweep": results["sweep"].info["n_dense_frequencies"],
                "method": results["sweep"].info["method"]})
    print(json.dumps(out), flush=True)
    return out


def ball_chain(n: int) -> sp.SpatialModel:
    """The links of :func:`chain` on spherical joints with rotary dampers (0.2 N m s/rad about every axis, no
    springs: the sweep does not state sprung ball joints; 3 x 3 pivots, the compiled sweep's multi-direction
    variant), weightless."""
    elements: list = []
    for j in range(n):
        elements.append(sp.SpatialBody(f"link{j}", 1.0, (0.002, 0.014, 0.014), center_of_mass=(0.2, 0.0, 0.0),
                                       points={"tip": (0.4, 0.0, 0.0)}))
        elements.append(sp.Spherical(name=f"j{j}", parent=None if j == 0 else f"link{j - 1}", child=f"link{j}",
                                     point=(0.0, 0.0, 0.0) if j == 0 else "tip", damping=0.2))
    return sp.SpatialModel(f"spatial_ball_chain{n}", elements, gravity=(0.0, 0.0, 0.0))


def run_ball(n: int) -> dict:
    """The ball-joint chain's row: the compiled multi-direction sweep against the generic one and the resolvent
    (inputs: tip forces y and z of the last link; outputs: its joint's rotation ``rx`` and the tip's z)."""
    model = ball_chain(n)
    inputs, outputs = [f"link{n - 1}.tip.force_y", f"link{n - 1}.tip.force_z"], [f"j{n - 1}.rx", f"link{n - 1}.tip.z"]
    point = at_rest(model)
    plant = SpatialSweepResponse(model, operating_point(model, point))
    generic = generic_plant(model, operating_point(model, point))
    cases = {"sweep_only": (lambda: plant.response(1j * OMEGA, inputs, outputs), 5),
             "sweep_only_generic": (lambda: generic.response(1j * OMEGA, inputs, outputs), 3),
             "resolvent": (lambda: delayed_loop_response(
                 lambda a, b: linearize_spatial(model, point, inputs=a, outputs=b), (), 1j * OMEGA, inputs, outputs,
                 model.name)[0], 1)}
    out, results = {"n_links": n, "joints": "spherical", "gravity": "none", "n_frequencies": int(OMEGA.size),
                    "compiled": plant.compiled is not None and plant.compiled.multi}, {}
    for name, (call, count) in cases.items():
        out[f"{name}_s"], out[f"{name}_cpu_s"], results[name] = best(call, count)
    compiled, fallback, dense = results["sweep_only"], results["sweep_only_generic"], results["resolvent"]
    out["generic_vs_compiled_cpu"] = out["sweep_only_generic_cpu_s"] / out["sweep_only_cpu_s"]
    out["error_generic_vs_compiled"] = float(np.max(np.abs(compiled[0] - fallback[0])) / np.max(np.abs(fallback[0])))
    out["generic_certifies_the_same"] = bool(np.array_equal(compiled[1], fallback[1]))
    scale = np.max(np.abs(dense), axis=-1, keepdims=True)
    scale = np.where(scale > 1e-12 * np.max(scale), scale, np.max(scale))     # pairs zero by structure (run)
    out["error_compiled_vs_resolvent"] = float(np.max(np.abs(np.moveaxis(compiled[0], 0, -1) - dense) / scale))
    out["certified_frequencies"] = int(np.count_nonzero(compiled[1]))
    print(json.dumps(out), flush=True)
    return out


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="N = 5 only")
    parser.add_argument("--sizes", type=int, nargs="+", default=None)
    parser.add_argument("--output", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    sizes = args.sizes or ([5] if args.quick else [5, 30])
    resolvent(chain(2), 2, OMEGA[:2])                 # warm-up: the first linearisation imports and builds caches
    compile_time = first_compile()
    print(json.dumps(compile_time), flush=True)
    rows = [run(n, hanging) for n in sizes for hanging in (False, True)]
    rows += [run_ball(n) for n in sizes]                # the ball-joint chain (multi-direction pivots)
    return write_result("spatial_frf", rows, args.output, compile_time)


if __name__ == "__main__":
    main()
