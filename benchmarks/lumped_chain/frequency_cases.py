"""Case (a) of ``foundation_scaling``: the chain's frequency response by ctmm's paths and by global solves.

For one chain length ``n`` (:mod:`lumped_chain.model`: 1000 frequencies, unit force on ``m1``, outputs the driving
point ``m1.x`` and the tip ``m<n>.x`` from one solve), same run, same machine:

* ``ctmm``            -- :func:`ctmm.frequency_response` as a user calls it; its ``path`` and ``kernel`` (from
                         ``info["kernel"]``) are recorded: the Riccati recursion in C
                         (:mod:`ctmm.compiled_chain_frequency`) where a C compiler is present, the default;
* ``ctmm_numpy``      -- :func:`ctmm.chain_assembly.solve` with ``compiled=False``: the numpy recursion batched
                         over omega, the path :func:`ctmm.frequency_response` takes without a C compiler;
* ``banded``          -- reference assembly (:func:`ctmm.reference.chain.assemble_banded`, through dense matrices;
                         its time is reported apart) + ``solve_banded`` per frequency;
* ``banded_vectorised`` -- the same banded system solved for all frequencies at once (Thomas elimination);
* ``dense``           -- dense ``M, C, K`` and ``numpy.linalg.solve`` per frequency on chunks of frequencies;
* ``python_control``  -- ``control.ss`` of :func:`ctmm.reference.chain.state_space` and
                         ``control.frequency_response`` (no slycot: a dense complex solve of size 2n per frequency).

A baseline whose full run is estimated (from the probe frequencies) to exceed ``BUDGET_S`` is measured on the probe
only and its time extrapolated linearly in the number of frequencies (flag ``extrapolated``); above ``skip_above``
masses it is skipped with an n^3 estimate (:func:`fill_skips`).  Accuracy: max relative difference to the banded
solve, and max relative error against the 30-digit mpmath solve at the probe frequencies and where ctmm and the
banded solve differ most.
"""
from __future__ import annotations

import time

import control  # (imported before any timing: its import takes seconds)
import numpy as np

import ctmm
from ctmm.chain_assembly import laplace_variables, solve
from ctmm.reference import chain as reference  # (benchmarks may use the validation models)

from .global_baselines import banded_frequency_loop, thomas_frequency_batch
from benchmark_support.measure import timed
from .model import N_OMEGA, ctmm_chain, global_chain, high_precision_frf, omega_grid, probe_indices, relative_difference

BUDGET_S = 120.0           # a baseline estimated above this [s] is measured on the probe only
DENSE_CHUNK_BYTES = 2e8    # memory bound of one dense chunk of dynamic-stiffness matrices [bytes]


def numpy_recursion(system: ctmm.Chain, omega: np.ndarray, outputs: list[str]) -> np.ndarray:
    """Responses [m/N] at ``outputs`` to a unit force on ``m1`` by the numpy Riccati recursion (no C), (2, B)."""
    s = laplace_variables(omega)
    source = system.input("m1.force")
    points = [system.signal(o).point for o in outputs]
    solution = solve(system, s, {source.position: {source.input: 1.0}}, points=sorted(set(points)), compiled=False)
    return np.stack([solution.at(p)[:, 0] for p in points])


def frf_case(n: int, *, run_big_baselines: bool = True) -> dict:
    """Time and accuracy of every method of the module docstring for the chain of ``n`` masses."""
    omega = omega_grid(n)
    probe = probe_indices()
    glob = global_chain(n)
    outputs = ["m1.x", f"m{n}.x"]
    case: dict = {"n": n, "omega_min": float(omega[0]), "omega_max": float(omega[-1]),
                  "n_omega": N_OMEGA, "methods": {}}
    system = ctmm_chain(n)
    repeat = 1.0 if n < 10_000 else 0.0

    frf, t_ctmm, cpu, runs = timed(lambda: ctmm.frequency_response(system, omega, input="m1.force", output=outputs),
                                   repeat_until=repeat)
    H_ctmm = np.stack([frf(o, "m1.force") for o in outputs])
    case["methods"]["ctmm"] = {"time_s": t_ctmm, "cpu_time_s": cpu, "runs": runs, "measured_on": N_OMEGA,
                               "extrapolated": False, "kernel": frf.info["kernel"],
                               "path": f"ctmm.frequency_response (default; kernel {frf.info['kernel']!r})"}
    print(f"[frf n={n}] ctmm ({frf.info['kernel']}) {t_ctmm:.3f} s", flush=True)

    H_numpy, t_numpy, cpu, runs = timed(lambda: numpy_recursion(system, omega, outputs), repeat_until=repeat)
    case["methods"]["ctmm_numpy"] = {"time_s": t_numpy, "cpu_time_s": cpu, "runs": runs, "measured_on": N_OMEGA,
                                     "extrapolated": False, "kernel": "numpy",
                                     "path": "ctmm.chain_assembly.solve(compiled=False): the numpy recursion, "
                                             "ctmm.frequency_response's path without a C compiler"}
    print(f"[frf n={n}] ctmm numpy recursion {t_numpy:.3f} s", flush=True)

    def banded_once():
        return banded_frequency_loop(*reference.assemble_banded(glob), omega)
    H_band, t_band, cpu_band, runs = timed(banded_once, repeat_until=repeat)
    _, t_band_asm, cpu_asm, _ = timed(lambda: reference.assemble_banded(glob), repeat_until=0.2 if n < 10_000 else 0.0)
    # the reference function itself (one output per call) must give the same numbers
    check = reference.frequency_response_banded(glob, omega[probe], 0, n - 1)
    case["banded_matches_reference_function"] = float(np.max(np.abs(check - H_band[1, probe])))
    case["methods"]["banded"] = {"time_s": t_band, "cpu_time_s": cpu_band, "runs": runs, "measured_on": N_OMEGA,
                                 "extrapolated": False, "assembly_s": t_band_asm, "assembly_cpu_s": cpu_asm,
                                 "solve_only_s": t_band - t_band_asm,
                                 "note": "assemble_banded (via dense M, C, K) + solve_banded per frequency; "
                                         "both outputs from one solve"}
    print(f"[frf n={n}] banded {t_band:.3f} s (assembly {t_band_asm:.3f} s)", flush=True)

    def banded_vectorised():
        return thomas_frequency_batch(*reference.assemble_banded(glob), omega)
    H_vec, t_vec, cpu, runs = timed(banded_vectorised, repeat_until=repeat)
    case["methods"]["banded_vectorised"] = {"time_s": t_vec, "cpu_time_s": cpu, "runs": runs,
                                            "measured_on": N_OMEGA, "extrapolated": False,
                                            "note": "assemble_banded + Thomas elimination over the n rows, "
                                                    "vectorised over all frequencies (benchmark-local)"}
    print(f"[frf n={n}] banded vectorised {t_vec:.3f} s", flush=True)

    results = {"ctmm": H_ctmm, "ctmm_numpy": H_numpy, "banded": H_band, "banded_vectorised": H_vec}
    chunk = max(1, int(DENSE_CHUNK_BYTES // (16.0 * n * n)))

    def dense_both(idx):
        M, C, K = reference.assemble(glob)
        rhs = np.zeros(n, dtype=complex)
        rhs[0] = 1.0
        out = np.empty((2, idx.size), dtype=complex)
        for start in range(0, idx.size, chunk):
            sel = idx[start:start + chunk]
            w = omega[sel][:, None, None]
            X = reference.solve_dynamic_stiffness(K[None] - w ** 2 * M[None] + 1j * w * C[None], rhs, omega[sel])
            out[0, start:start + sel.size] = X[:, 0]
            out[1, start:start + sel.size] = X[:, -1]
        return out
    results["dense"] = budgeted(case, "dense", n, dense_both, probe, run_big_baselines,
                                skip_above=3000, note="dense M, C, K; numpy.linalg.solve (LU) per frequency "
                                "on chunks of frequencies (same algebra as reference.frequency_response)")

    def control_call(idx):
        A, B = reference.state_space(glob)
        Cm = np.zeros((2, 2 * n))
        Cm[0, 0] = Cm[1, n - 1] = 1.0
        sys_ss = control.ss(A, B[:, :1], Cm, np.zeros((2, 1)))
        resp = control.frequency_response(sys_ss, omega[idx])
        return np.asarray(resp.complex)[:, 0, :]
    results["python_control"] = budgeted(case, "python_control", n, control_call, probe, run_big_baselines,
                                         skip_above=3000, note="control.ss(reference.state_space) + "
                                         "control.frequency_response; slycot absent -> dense solve of "
                                         "(sI - A) per frequency")
    accuracy(case, n, omega, probe, results, H_ctmm, H_band)
    return case


def accuracy(case: dict, n: int, omega: np.ndarray, probe: np.ndarray, results: dict, H_ctmm: np.ndarray,
             H_band: np.ndarray) -> None:
    """Relative differences to the banded solve and errors against the 30-digit solve, into ``case["methods"]``."""
    worst = [int(np.argmax(np.abs(H_ctmm[row] - H_band[row]) / np.maximum(np.abs(H_band[row]), 1e-300)))
             for row in range(2)]
    hp_idx = np.unique(np.concatenate([probe, worst]))
    started = time.perf_counter()
    H_hp = high_precision_frf(n, omega[hp_idx])
    case["high_precision_s"] = time.perf_counter() - started
    case["high_precision_frequencies"] = {"indices": hp_idx.tolist(), "omega": omega[hp_idx].tolist(),
                                          "largest_ctmm_banded_difference_at": worst}
    for key, H in results.items():
        entry = case["methods"][key]
        if H is None:
            entry.pop("indices", None)
            continue
        measured = entry.pop("indices", np.arange(N_OMEGA))
        for row, label in enumerate(("driving_point", "tip")):
            entry[f"rel_diff_to_banded_{label}"] = relative_difference(H[row], H_band[row, measured])
            sel = np.isin(measured, hp_idx)
            hp_rows = np.searchsorted(hp_idx, measured[sel])
            entry[f"rel_error_vs_mpmath_{label}"] = relative_difference(H[row, sel], H_hp[row, hp_rows])
    case["magnitude_range"] = {"driving_point": [float(np.min(np.abs(H_band[0]))), float(np.max(np.abs(H_band[0])))],
                               "tip": [float(np.min(np.abs(H_band[1]))), float(np.max(np.abs(H_band[1])))]}
def budgeted(case: dict, key: str, n: int, call, probe: np.ndarray, run_big: bool, *, skip_above: int,
             note: str) -> np.ndarray | None:
    """Measure ``call(indices)``: the full grid if the probe-based estimate fits ``BUDGET_S``, else the probe."""
    entry = {"note": note}
    case["methods"][key] = entry
    if n > skip_above or not run_big:
        entry.update({"skipped": True, "time_s": None, "indices": np.array([], dtype=int)})
        return None
    H_probe, t_probe, cpu_probe, _ = timed(lambda: call(probe), repeat_until=0.0, max_repeats=1)
    estimate = t_probe / probe.size * N_OMEGA
    if estimate <= BUDGET_S:
        idx = np.arange(N_OMEGA)
        H, t_full, cpu_full, runs = timed(lambda: call(idx), repeat_until=1.0)
        entry.update({"time_s": t_full, "cpu_time_s": cpu_full, "runs": runs, "measured_on": N_OMEGA,
                      "extrapolated": False,
                      "indices": idx})
        print(f"[frf n={n}] {key} {t_full:.3f} s", flush=True)
        return H
    entry.update({"time_s": estimate, "cpu_time_s": cpu_probe / probe.size * N_OMEGA, "probe_time_s": t_probe,
                  "measured_on": int(probe.size),
                  "extrapolated": True, "runs": 1, "indices": probe,
                  "extrapolation": f"probe of {probe.size} frequencies x {N_OMEGA / probe.size:g}"})
    print(f"[frf n={n}] {key} extrapolated {estimate:.1f} s from a {t_probe:.2f} s probe", flush=True)
    return H_probe


def fill_skips(cases: list[dict]) -> None:
    """n^3 estimates [s] for skipped dense / python-control runs from the largest measured size."""
    for key, power in (("dense", 3), ("python_control", 3)):
        measured = [c for c in cases if c["methods"][key].get("time_s") is not None]
        if not measured:
            continue
        base = measured[-1]
        for c in cases:
            entry = c["methods"][key]
            if entry.get("skipped"):
                est = base["methods"][key]["time_s"] * (c["n"] / base["n"]) ** power
                mem = 16.0 * (c["n"] * (2 if key == "python_control" else 1)) ** 2
                entry["estimated_time_s"] = est
                entry["reason"] = (f"skipped: one complex matrix needs {mem / 1e9:.1f} GB and the O(n^3) cost "
                                   f"extrapolates to ~{est:.3g} s from n={base['n']} (n^3 scaling)")

