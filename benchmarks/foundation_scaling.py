"""Cost against chain length: frequency responses and time steps of n = 10 ... 10 000 masses.

Chain: fixed-free, wall -- (K || c) -- m -- (K || c) -- m ... m (free end), K = 1000 N/m,
m = 0.1 kg, light stiffness-proportional damping c = 2e-4 s * K = 0.2 N s/m (modal damping
ratio 1e-4 s * omega_j, at most 2 % at the band edge 2 sqrt(K/m) = 200 rad/s).

(a) Frequency response, 1000 log-spaced omega from omega_1/2 to 0.95 * 200 rad/s
(omega_1 = 200 sin(pi / (2 (2n + 1))) rad/s), unit force on the first mass m1, outputs: the
driving point m1.x and the tip m_n.x (both from one solve).  Methods, same run, same machine:

* ``ctmm``            -- :func:`ctmm.frequency_response` (batched Riccati transfer);
* ``banded``          -- :func:`ctmm.reference.chain.frequency_response_banded` (``solve_banded``
                         per frequency; its dense-assembly part is timed separately);
* ``banded_vectorised`` -- the same banded dynamic stiffness solved for all frequencies at once:
                         a benchmark-local Thomas elimination (no pivoting) over the n rows with
                         every step a numpy operation on the whole frequency vector; the fastest
                         plain-numpy global baseline (issue 17 asked the "1.5x the banded solve"
                         claim to be re-measured against it);
* ``dense``           -- :func:`ctmm.reference.chain.frequency_response` (LU per frequency),
                         called on chunks of frequencies to bound memory;
* ``python_control``  -- ``control.ss`` of :func:`ctmm.reference.chain.state_space` and
                         ``control.frequency_response`` (no slycot: one dense complex solve of
                         size 2n per frequency);
* ``prototype``       -- the change proposed for :mod:`ctmm.assembly` (see ``proposed_kernel``):
                         the same Riccati recursion for 2x2 layouts written element-wise over
                         the frequency batch, without log-det and without (B, 2, 2) temporaries.
                         Not part of ctmm; measured here to size the proposal.

A baseline whose full run is estimated (from a probe of 10 of the 1000 frequencies) to take
more than ``BUDGET_S`` is measured on the probe only and its time extrapolated linearly in the
number of frequencies (flag ``extrapolated``); where even one frequency is out of reach (memory,
n^3 cost) it is skipped with an n^3 estimate.  Accuracy: max relative difference to the banded
solve over all frequencies computed, and max relative error against a 30-digit mpmath solution
(Thomas algorithm on the tridiagonal dynamic stiffness) at the 10 probe frequencies and at the
frequencies where ctmm and the banded solve differ most.

(b) Time stepping: the same chains (free lengths 0), initial displacement
x_i(0) = 0.01 sin(pi i / (2 n)) m, zero velocity, constant 100 N on m1, Newmark(1/4, 1/2),
dt = 1e-4 s, 200 steps.  Methods: ``ctmm.simulate`` fast path and generic path,
:func:`ctmm.reference.chain.newmark_global` dense and banded, and ``global_banded_On`` (a
benchmark-local textbook global Newmark with a banded Cholesky factorised once and tridiagonal
mat-vecs: the O(n) global baseline; ``newmark_global(banded=True)`` still does dense O(n^2)
mat-vecs ``C @ v``, ``K @ x`` every step).  Wall time per step; max |x - x_banded| [m] over all
masses and steps run.

Run ``python benchmarks/foundation_scaling.py`` (``--quick`` for n <= 1000); writes
``benchmarks/results/foundation_scaling.json`` and ``.png``.
"""
from __future__ import annotations

import argparse
import cProfile
import io
import os
import platform
import pstats
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import scipy.linalg as sla  # noqa: E402
import control  # noqa: E402  (imported before any timing: its import takes seconds)

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import ctmm  # noqa: E402
from ctmm.elements.boundary import Fixed, Free  # noqa: E402
from ctmm.elements.lumped import Connector, Mass, PointElement, SpringDamper  # noqa: E402
from ctmm.reference import chain as reference  # noqa: E402
from ctmm.scenario import write_json_atomic  # noqa: E402

STIFFNESS, MASS, DAMPING = 1000.0, 0.1, 0.2
SIZES = (10, 100, 1000, 10_000)
N_OMEGA = 1000
PROBE = 10                 # probe frequencies (also the high-precision subset)
BUDGET_S = 120.0           # a baseline estimated above this is measured on the probe only
DENSE_CHUNK_BYTES = 2e8    # memory bound of one dense chunk of dynamic-stiffness matrices
DT, N_STEPS, FORCE = 1e-4, 200, 100.0
RESULTS = ROOT / "benchmarks" / "results"


# ------------------------------------------------------------------------------------------
# models
# ------------------------------------------------------------------------------------------
def ctmm_chain(n: int) -> ctmm.Chain:
    elements = [Fixed("wall")]
    for i in range(1, n + 1):
        elements.append(SpringDamper(f"k{i}", STIFFNESS, DAMPING))
        elements.append(Mass(f"m{i}", MASS, force=FORCE if i == 1 else 0.0))
    elements.append(Free("end"))
    return ctmm.Chain(f"chain{n}", elements)


def global_chain(n: int) -> reference.GlobalChain:
    return reference.GlobalChain.uniform(n, MASS, STIFFNESS, DAMPING, start="fixed", end="free")


def omega_grid(n: int) -> np.ndarray:
    band_edge = 2.0 * np.sqrt(STIFFNESS / MASS)
    omega_1 = band_edge * np.sin(np.pi / (2 * (2 * n + 1)))
    return np.logspace(np.log10(0.5 * omega_1), np.log10(0.95 * band_edge), N_OMEGA)


def probe_indices() -> np.ndarray:
    return np.unique(np.round(np.linspace(0, N_OMEGA - 1, PROBE)).astype(int))


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------
CPU_TIMES: dict = {}  # id of the last timed call -> best CPU time (read by _cpu())


def timed(call, *, repeat_until: float = 1.0, max_repeats: int = 3):
    """Best wall time [s] of repeated calls (short calls only) and the last result.

    The best process CPU time of the same calls is kept in ``CPU_TIMES["last"]`` (the machine
    is shared; single-threaded code has CPU time ~ wall time when the machine is quiet).
    """
    best, best_cpu, spent, runs, result = np.inf, np.inf, 0.0, 0, None
    while runs < max_repeats and (runs == 0 or spent < repeat_until):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = call()
        elapsed, cpu = time.perf_counter() - start, time.process_time() - start_cpu
        best, best_cpu, spent, runs = min(best, elapsed), min(best_cpu, cpu), spent + elapsed, runs + 1
    CPU_TIMES["last"] = best_cpu
    return result, best, runs


def _cpu() -> float:
    return CPU_TIMES["last"]


def profile_top(call, limit: int = 12) -> list[dict]:
    """cProfile ``call()`` and return the ``limit`` functions with the largest own time."""
    prof = cProfile.Profile()
    prof.enable()
    call()
    prof.disable()
    stats = pstats.Stats(prof, stream=io.StringIO())
    total = sum(v[2] for v in stats.stats.values())
    rows = sorted(stats.stats.items(), key=lambda kv: kv[1][2], reverse=True)[:limit]
    out = []
    for (filename, line, func), (cc, nc, tt, ct, _) in rows:
        short = filename.split("/work/main/")[-1].split("site-packages/")[-1]
        out.append({"function": f"{short}:{line}({func})", "ncalls": nc, "tottime_s": tt,
                    "cumtime_s": ct, "share_of_total": tt / total if total else float("nan")})
    return out


def relative_difference(value: np.ndarray, ref: np.ndarray) -> dict:
    """Max pointwise |value - ref| / |ref| where |ref| is representable (> 1e-280)."""
    ok = np.abs(ref) > 1e-280
    rel = np.abs(value[ok] - ref[ok]) / np.abs(ref[ok])
    return {"max": float(np.max(rel)) if rel.size else float("nan"),
            "frequencies_compared": int(ok.sum()), "frequencies_underflowing": int((~ok).sum())}


def high_precision_frf(n: int, omega: np.ndarray, digits: int = 30) -> np.ndarray:
    """Driving-point and tip receptance per unit force on mass 0 with mpmath (Thomas algorithm).

    Returns complex array (2, len(omega)): row 0 = x_0, row 1 = x_{n-1}.
    """
    import mpmath as mp

    mp.mp.dps = digits
    out = np.empty((2, omega.size), dtype=complex)
    k, c, m = mp.mpf(STIFFNESS), mp.mpf(DAMPING), mp.mpf(MASS)
    for idx, w in enumerate(omega):
        w = mp.mpf(float(w))
        conn = k + mp.mpc(0, 1) * w * c                  # connector dynamic stiffness
        off = -conn
        # diag: interior 2 conn - w^2 m, last (free end) conn - w^2 m
        diag = [2 * conn - w * w * m] * (n - 1) + [conn - w * w * m]
        # forward elimination (rhs = e_0), then back substitution
        cp = [mp.mpc(0)] * n
        dp = [mp.mpc(0)] * n
        cp[0] = off / diag[0]
        dp[0] = mp.mpc(1) / diag[0]
        for i in range(1, n):
            denom = diag[i] - off * cp[i - 1]
            cp[i] = off / denom if i < n - 1 else mp.mpc(0)
            dp[i] = (-off * dp[i - 1]) / denom
        x = dp[n - 1]
        x_tip = x
        for i in range(n - 2, -1, -1):
            x = dp[i] - cp[i] * x
        out[0, idx] = complex(x)
        out[1, idx] = complex(x_tip)
    return out


# ------------------------------------------------------------------------------------------
# the proposed kernel (prototype; not part of ctmm)
# ------------------------------------------------------------------------------------------
def proposed_kernel(system: ctmm.Chain, omega: np.ndarray, input_element: str,
                    output_elements: list[str]) -> np.ndarray:
    """Riccati transfer of a fixed-free lumped 1-D chain, element-wise over the frequency batch.

    Same recursion as :func:`ctmm.assembly.riccati_solve` for ``z = [x, f]`` with the start
    partition ``f-part = x`` (known 0 at the wall) and ``e-part = f``: per element
    ``G = a21 S + 1``, ``S <- (S + a12) / G``, ``r = a21 P + u2``, ``P <- P + u1 - S r``;
    back-substitution ``e <- (e - r) / G``, ``x = S e + P``.  A connector has ``a12 = -1/(k+cs)``,
    ``a21 = 0`` (so ``G = 1``, ``r = 0``); a point ``a12 = 0``, ``a21 = -(m s^2 + c_g s + k_g)``.
    No log-det, no permutation, no (B, 2, 2) arrays.  Returns (n_outputs, B) displacements per
    unit force.
    """
    if not (isinstance(system.start, Fixed) and isinstance(system.end, Free)):
        raise ValueError("prototype handles fixed-free chains only")
    s = 1j * np.asarray(omega, dtype=float)
    s2 = s * s
    batch = s.shape
    S = np.zeros(batch, dtype=complex)
    P = np.zeros(batch, dtype=complex)
    want = {system.position(name): k for k, name in enumerate(output_elements)}
    load_at = system.position(input_element)
    saved_S, saved_P = {}, {}
    back = []  # (position, G, r) of point elements, for the backward pass
    for pos, e in enumerate(system.body, start=1):
        if isinstance(e, Connector):
            S = S - 1.0 / (e.stiffness + e.damping * s)
        elif isinstance(e, PointElement):
            a21 = -(e.mass * s2 + e.damping * s + e.stiffness)
            G = a21 * S + 1.0
            S = S / G
            r = a21 * P
            if pos == load_at:
                r = r + 1.0
            P = P - S * r
            back.append((pos, G, r))
        else:
            raise ValueError(f"prototype handles lumped elements only, got {e!r}")
        if pos in want:
            saved_S[pos], saved_P[pos] = S, P
    # free end: force e_N = 0; go back through the point elements only (connectors keep e)
    e = np.zeros(batch, dtype=complex)
    out = np.empty((len(output_elements),) + batch, dtype=complex)
    pending = sorted(want, reverse=True)
    for pos, G, r in reversed(back):
        while pending and pending[0] >= pos:  # outputs outboard of this point see the current e
            p = pending.pop(0)
            out[want[p]] = saved_S[p] * e + saved_P[p]
        e = (e - r) / G
    for p in pending:
        out[want[p]] = saved_S[p] * e + saved_P[p]
    return out


# ------------------------------------------------------------------------------------------
# (a) frequency responses
# ------------------------------------------------------------------------------------------
def frf_case(n: int, *, run_big_baselines: bool = True) -> dict:
    omega = omega_grid(n)
    probe = probe_indices()
    glob = global_chain(n)
    outputs = ["m1.x", f"m{n}.x"]
    case: dict = {"n": n, "omega_min": float(omega[0]), "omega_max": float(omega[-1]),
                  "n_omega": N_OMEGA, "methods": {}}
    t0 = time.perf_counter()
    system = ctmm_chain(n)
    case["ctmm_chain_construction_s"] = time.perf_counter() - t0

    # ctmm
    frf, t_ctmm, runs = timed(lambda: ctmm.frequency_response(system, omega, input="m1.force", output=outputs),
                              repeat_until=1.0 if n < 10_000 else 0.0)
    H_ctmm = np.stack([frf(o, "m1.force") for o in outputs])
    case["methods"]["ctmm"] = {"time_s": t_ctmm, "cpu_time_s": _cpu(), "runs": runs, "measured_on": N_OMEGA,
                               "extrapolated": False}
    print(f"[frf n={n}] ctmm {t_ctmm:.3f} s", flush=True)

    # banded (full) + its assembly part; both outputs from one solve per frequency
    def banded_once():
        return banded_frequency_loop(*reference.assemble_banded(glob), omega)
    H_band, t_band, runs = timed(banded_once, repeat_until=1.0 if n < 10_000 else 0.0)
    cpu_band = _cpu()
    _, t_band_asm, _ = timed(lambda: reference.assemble_banded(glob), repeat_until=0.2 if n < 10_000 else 0.0)
    # the reference function itself (one output per call) must give the same numbers
    check = reference.frequency_response_banded(glob, omega[probe], 0, n - 1)
    case["banded_matches_reference_function"] = float(np.max(np.abs(check - H_band[1, probe])))
    case["methods"]["banded"] = {"time_s": t_band, "cpu_time_s": cpu_band, "runs": runs, "measured_on": N_OMEGA,
                                 "extrapolated": False,
                                 "assembly_s": t_band_asm, "solve_only_s": t_band - t_band_asm,
                                 "note": "assemble_banded (via dense M, C, K) + solve_banded per frequency; "
                                         "both outputs from one solve"}
    print(f"[frf n={n}] banded {t_band:.3f} s (assembly {t_band_asm:.3f} s)", flush=True)

    # banded, vectorised over the frequencies (Thomas elimination, assembly included)
    def banded_vectorised():
        Mb, Cb, Kb = reference.assemble_banded(glob)
        return thomas_frequency_batch(Mb, Cb, Kb, omega)
    H_vec, t_vec, runs = timed(banded_vectorised, repeat_until=1.0 if n < 10_000 else 0.0)
    case["methods"]["banded_vectorised"] = {"time_s": t_vec, "cpu_time_s": _cpu(), "runs": runs,
                                            "measured_on": N_OMEGA, "extrapolated": False,
                                            "note": "assemble_banded + Thomas elimination over the n rows, "
                                                    "vectorised over all frequencies (benchmark-local)"}
    print(f"[frf n={n}] banded vectorised {t_vec:.3f} s", flush=True)

    # prototype of the proposed kernel
    H_proto, t_proto, runs = timed(lambda: proposed_kernel(system, omega, "m1", ["m1", f"m{n}"]))
    case["methods"]["prototype"] = {"time_s": t_proto, "cpu_time_s": _cpu(), "runs": runs, "measured_on": N_OMEGA,
                                    "extrapolated": False,
                                    "note": "proposed d=1 Riccati kernel (benchmark-local prototype, not ctmm)"}
    print(f"[frf n={n}] prototype {t_proto:.3f} s", flush=True)

    # dense: chunks of frequencies
    results = {"ctmm": H_ctmm, "banded": H_band, "banded_vectorised": H_vec, "prototype": H_proto}
    chunk = max(1, int(DENSE_CHUNK_BYTES // (16.0 * n * n)))

    # dense: the algebra of reference.frequency_response, both outputs from one solve
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
    results["dense"] = _budgeted(case, "dense", n, dense_both, probe, run_big_baselines,
                                 skip_above=3000, note="dense M, C, K; numpy.linalg.solve (LU) per frequency "
                                 "on chunks of frequencies (same algebra as reference.frequency_response)")

    # python-control
    def control_call(idx):
        A, B = reference.state_space(glob)
        Cm = np.zeros((2, 2 * n))
        Cm[0, 0] = Cm[1, n - 1] = 1.0
        sys_ss = control.ss(A, B[:, :1], Cm, np.zeros((2, 1)))
        resp = control.frequency_response(sys_ss, omega[idx])
        return np.asarray(resp.complex)[:, 0, :]
    results["python_control"] = _budgeted(case, "python_control", n, control_call, probe, run_big_baselines,
                                          skip_above=3000, note="control.ss(reference.state_space) + "
                                          "control.frequency_response; slycot absent -> dense solve of "
                                          "(sI - A) per frequency")

    # accuracy: 30-digit reference at the probe frequencies and where ctmm and banded differ most
    worst = [int(np.argmax(np.abs(H_ctmm[row] - H_band[row]) / np.maximum(np.abs(H_band[row]), 1e-300)))
             for row in range(2)]
    hp_idx = np.unique(np.concatenate([probe, worst]))
    t_hp = time.perf_counter()
    H_hp = high_precision_frf(n, omega[hp_idx])
    case["high_precision_s"] = time.perf_counter() - t_hp
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
    return case


def banded_frequency_loop(Mb: np.ndarray, Cb: np.ndarray, Kb: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Driving-point and tip responses to a unit force on the first mass by ``solve_banded`` per frequency.

    ``Mb, Cb, Kb`` [kg, N s/m, N/m] in ``solve_banded((1, 1))`` layout (:func:`ctmm.reference.chain.assemble_banded`),
    ``omega`` [rad/s]; both outputs from one solve per frequency.  Returns (2, n_omega) [m/N].
    """
    rhs = np.zeros(Mb.shape[1], dtype=complex)
    rhs[0] = 1.0
    X = np.empty((2, omega.size), dtype=complex)
    for k, w in enumerate(omega):
        x = sla.solve_banded((1, 1), Kb - w ** 2 * Mb + 1j * w * Cb, rhs)
        X[0, k], X[1, k] = x[0], x[-1]
    return X


def thomas_frequency_batch(Mb: np.ndarray, Cb: np.ndarray, Kb: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Driving-point and tip responses to a unit force on the first mass, all frequencies at once.

    Tridiagonal dynamic stiffness ``Z = K - w^2 M + i w C`` in ``solve_banded((1, 1))`` layout
    (row 0 superdiagonal, row 1 diagonal, row 2 subdiagonal); forward elimination and back
    substitution over the rows, each a numpy operation over the frequency vector.  Returns (2, n_omega).
    """
    w = omega[:, None]
    Z = Kb[:, None, :] - (w ** 2) * Mb[:, None, :] + 1j * w * Cb[:, None, :]     # (3, n_omega, n)
    upper, diag, lower = Z[0], Z[1], Z[2]
    n = diag.shape[1]
    c_prime = np.empty_like(diag)
    d_prime = np.empty_like(diag)
    c_prime[:, 0] = upper[:, 1] / diag[:, 0] if n > 1 else 0.0
    d_prime[:, 0] = 1.0 / diag[:, 0]
    for i in range(1, n):
        denominator = diag[:, i] - lower[:, i - 1] * c_prime[:, i - 1]
        if i < n - 1:
            c_prime[:, i] = upper[:, i + 1] / denominator
        d_prime[:, i] = -lower[:, i - 1] * d_prime[:, i - 1] / denominator
    x = d_prime[:, n - 1].copy()
    tip = x.copy()
    for i in range(n - 2, -1, -1):
        x = d_prime[:, i] - c_prime[:, i] * x
    return np.stack([x, tip])


def _budgeted(case, key, n, call, probe, run_big, *, skip_above: int, note: str):
    """Measure ``call(indices)``: full grid if the probe-based estimate fits the budget."""
    entry = {"note": note}
    case["methods"][key] = entry
    if n > skip_above or not run_big:
        entry.update({"skipped": True, "time_s": None, "indices": np.array([], dtype=int)})
        return None
    H_probe, t_probe, _ = timed(lambda: call(probe), repeat_until=0.0, max_repeats=1)
    cpu_probe = _cpu()
    estimate = t_probe / probe.size * N_OMEGA
    if estimate <= BUDGET_S:
        idx = np.arange(N_OMEGA)
        H, t_full, runs = timed(lambda: call(idx), repeat_until=1.0)
        entry.update({"time_s": t_full, "cpu_time_s": _cpu(), "runs": runs, "measured_on": N_OMEGA,
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
    """n^3 estimates for skipped dense / python-control runs from the largest measured size."""
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


# ------------------------------------------------------------------------------------------
# (b) time stepping
# ------------------------------------------------------------------------------------------
def global_newmark_banded_On(glob, n_steps, dt, x0, v0, force, beta=0.25, gamma=0.5):
    """Textbook global Newmark with a banded Cholesky factorised once and tridiagonal mat-vecs."""
    Mb, Cb, Kb = _bands_uniform(glob)
    h = dt

    def matvec(band, x):
        y = band[1] * x
        y[:-1] += band[0, 1:] * x[1:]
        y[1:] += band[2, :-1] * x[:-1]
        return y
    eff = Mb + gamma * h * Cb + beta * h * h * Kb
    upper = np.vstack([eff[0], eff[1]])  # (2, n) upper form for cholesky_banded
    chol = sla.cholesky_banded(upper, lower=False)
    x, v = x0.copy(), v0.copy()
    a = (force - matvec(Cb, v) - matvec(Kb, x)) / glob.masses
    for _ in range(n_steps):
        x_p = x + h * v + (0.5 - beta) * h * h * a
        v_p = v + (1.0 - gamma) * h * a
        a = sla.cho_solve_banded((chol, False), force - matvec(Cb, v_p) - matvec(Kb, x_p))
        x = x_p + beta * h * h * a
        v = v_p + gamma * h * a
    return x


def _bands_uniform(glob):
    """Bands of M, C, K straight from the chain data (no dense matrices; fixed start)."""
    n = glob.size
    k, c = glob.stiffness, glob.damping
    def band(conn, ground):
        b = np.zeros((3, n))
        b[1] = conn[:-1] + conn[1:] + ground
        b[0, 1:] = -conn[1:-1]
        b[2, :-1] = -conn[1:-1]
        return b
    Mb = np.zeros((3, n))
    Mb[1] = glob.masses
    return Mb, band(c, glob.ground_damping), band(k, glob.ground_stiffness)


def stepping_case(n: int, *, run_big_baselines: bool = True) -> dict:
    system = ctmm_chain(n)
    glob = global_chain(n)
    i = np.arange(1, n + 1)
    x0 = 0.01 * np.sin(np.pi * i / (2 * n))
    x0_map = {f"m{j}": float(x0[j - 1]) for j in i}
    force = np.zeros(n)
    force[0] = FORCE
    case: dict = {"n": n, "dt": DT, "methods": {}}
    mass_points = 2 * i  # connection point of mass j (point after the mass element)

    def ctmm_run(steps, fast):
        return ctmm.simulate(system, steps * DT, DT, method="newmark", x0=x0_map, fast=fast, progress=False)

    # banded reference (reference.newmark_global, banded) first: it defines the comparison
    def ref_run(steps, banded):
        return reference.newmark_global(glob, steps * DT, DT, x0, np.zeros(n), lambda t: force, banded=banded)

    runs_spec = [
        ("ctmm_fast", lambda s: ctmm_run(s, True), None),
        ("ctmm_generic", lambda s: ctmm_run(s, False), None),
        ("global_banded", lambda s: ref_run(s, True), 20_000),
        ("global_dense", lambda s: ref_run(s, False), 3000),
        ("global_banded_On", lambda s: global_newmark_banded_On(glob, s, DT, x0, np.zeros(n), force), None),
    ]
    finals = {}
    for key, call, skip_above in runs_spec:
        entry: dict = {}
        case["methods"][key] = entry
        if skip_above is not None and (n > skip_above or not run_big_baselines):
            entry.update({"skipped": True, "time_per_step_s": None})
            continue
        probe_steps = 5
        _, t_probe, _ = timed(lambda: call(probe_steps), repeat_until=0.0, max_repeats=1)
        estimate = t_probe / probe_steps * N_STEPS
        steps = N_STEPS if estimate <= BUDGET_S else max(probe_steps, int(BUDGET_S / 4 / (t_probe / probe_steps)))
        out, wall, runs = timed(lambda: call(steps), repeat_until=1.0 if estimate < 30 else 0.0)
        entry.update({"steps": steps, "wall_time_s": wall, "time_per_step_s": wall / steps,
                      "cpu_time_per_step_s": _cpu() / steps, "runs": runs,
                      "reduced_steps": steps < N_STEPS})
        if key.startswith("ctmm"):
            entry["loop_time_per_step_s"] = out.info["wall_time_s"] / steps
            x_hist = out.states[:, mass_points, 0]
        elif key == "global_banded_On":
            x_hist = out[None, :]
        else:
            x_hist = out.displacement
        finals[key] = (steps, x_hist)
        print(f"[step n={n}] {key} {wall / steps * 1e3:.3f} ms/step ({steps} steps)", flush=True)
    ref_steps, ref_hist = finals["global_banded"]
    for key, (steps, x_hist) in finals.items():
        entry = case["methods"][key]
        if key == "global_banded_On":
            if steps == ref_steps:
                entry["max_difference_m"] = float(np.max(np.abs(x_hist[-1] - ref_hist[-1])))
                entry["compared"] = "final step"
            continue
        common = min(steps, ref_steps) + 1
        entry["max_difference_m"] = float(np.max(np.abs(x_hist[:common] - ref_hist[:common])))
        entry["compared"] = f"all masses, steps 0..{common - 1}"
    case["max_displacement_m"] = float(np.max(np.abs(ref_hist)))
    return case


# ------------------------------------------------------------------------------------------
# summary
# ------------------------------------------------------------------------------------------
def slope(ns, ts) -> float:
    ns, ts = np.asarray(ns, float), np.asarray(ts, float)
    ok = np.isfinite(ts) & (ts > 0)
    return float(np.polyfit(np.log(ns[ok]), np.log(ts[ok]), 1)[0]) if ok.sum() >= 2 else float("nan")


def code_version() -> dict:
    """Commit of the measured code and the files of ctmm/ that differ from it (shared tree)."""
    import subprocess

    def git(*args):
        try:
            return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=30).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return None
    status = git("status", "--porcelain", "--", "ctmm")
    return {"commit": git("rev-parse", "HEAD"),
            "uncommitted_ctmm_files": status.splitlines() if status else []}


def machine() -> dict:
    info = {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
            "python": platform.python_version(), "numpy": np.__version__, "cpu_count": os.cpu_count(),
            "OPENBLAS_NUM_THREADS": os.environ.get("OPENBLAS_NUM_THREADS")}
    try:
        import scipy

        info["scipy"], info["control"] = scipy.__version__, control.__version__
        info["load_average_1_5_15min"] = list(os.getloadavg())
    except (ImportError, OSError):
        pass
    try:
        with open("/proc/cpuinfo") as handle:
            for line in handle:
                if line.startswith("model name"):
                    info["cpu_model"] = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return info


def targets(frf_cases: list[dict]) -> dict:
    by_n = {c["n"]: c for c in frf_cases}
    out: dict = {}
    if 1000 in by_n:
        m = by_n[1000]["methods"]
        t_c = m["ctmm"]["time_s"]
        pc = m["python_control"].get("time_s")
        pc_cpu, c_cpu = m["python_control"].get("cpu_time_s"), m["ctmm"].get("cpu_time_s")
        out["frf_1000_vs_python_control"] = {
            "target": ">= 20x faster", "speedup": (pc / t_c) if pc else None,
            "speedup_cpu_time": (pc_cpu / c_cpu) if pc_cpu and c_cpu else None,
            "met": (pc / t_c >= 20.0) if pc else None,
            "python_control_extrapolated": m["python_control"].get("extrapolated")}
        t_b = m["banded"]["time_s"]
        acc_c = m["ctmm"]["rel_error_vs_mpmath_tip"]["max"], m["ctmm"]["rel_error_vs_mpmath_driving_point"]["max"]
        acc_b = m["banded"]["rel_error_vs_mpmath_tip"]["max"], m["banded"]["rel_error_vs_mpmath_driving_point"]["max"]
        out["frf_1000_vs_banded"] = {
            "target": "within 2x of the banded LAPACK solve at equal accuracy",
            "time_ratio_ctmm_over_banded": t_c / t_b, "met": t_c <= 2.0 * t_b,
            "time_ratio_cpu_time": c_cpu / m["banded"]["cpu_time_s"],
            "rel_error_vs_mpmath_tip": {"ctmm": acc_c[0], "banded": acc_b[0]},
            "rel_error_vs_mpmath_driving_point": {"ctmm": acc_c[1], "banded": acc_b[1]},
            "prototype_time_ratio_over_banded": m["prototype"]["time_s"] / t_b}
        vec = m["banded_vectorised"]
        out["frf_1000_vs_banded_vectorised"] = {
            "what": "ctmm against the banded dynamic stiffness solved for all frequencies at once (Thomas "
                    "elimination vectorised over omega): the fastest plain-numpy global baseline",
            "time_ratio_ctmm_over_banded_vectorised": t_c / vec["time_s"],
            "time_ratio_cpu_time": c_cpu / vec["cpu_time_s"],
            "rel_error_vs_mpmath_tip": {"ctmm": acc_c[0], "banded_vectorised": vec["rel_error_vs_mpmath_tip"]["max"]},
            "rel_error_vs_mpmath_driving_point": {"ctmm": acc_c[1],
                                                  "banded_vectorised": vec["rel_error_vs_mpmath_driving_point"]["max"]}}
    ns = [c["n"] for c in frf_cases if c["n"] >= 100]
    if len(ns) >= 2:
        s_ctmm = slope(ns, [by_n[n]["methods"]["ctmm"]["time_s"] for n in ns])
        out["frf_cost_linear_in_n"] = {"target": "cost O(n)", "fitted_exponent_n>=100": s_ctmm,
                                       "met": abs(s_ctmm - 1.0) <= 0.15,
                                       "prototype_exponent": slope(ns, [by_n[n]["methods"]["prototype"]["time_s"]
                                                                        for n in ns]),
                                       "banded_exponent": slope(ns, [by_n[n]["methods"]["banded"]["time_s"]
                                                                     for n in ns])}
    return out


def warm_up() -> None:
    """One small call of every timed library function (lazy imports, first-call caches)."""
    small = ctmm_chain(3)
    ctmm.frequency_response(small, [1.0, 2.0], input="m1.force", output="m3.x")
    ctmm.simulate(small, 2 * DT, DT, x0={"m1": 0.0})
    ctmm.simulate(small, 2 * DT, DT, x0={"m1": 0.0}, fast=False)
    control.frequency_response(control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]), [1.0])
    reference.frequency_response_banded(global_chain(3), [1.0], 0, 2)


def run(sizes=SIZES, *, quick: bool = False) -> dict:
    version = code_version()  # before any timing: the working tree is shared and may change
    warm_up()
    frf_cases = [frf_case(n) for n in sizes]
    fill_skips(frf_cases)
    step_cases = [stepping_case(n) for n in sizes]
    n_prof = 1000 if 1000 in sizes else sizes[-1]
    system = ctmm_chain(n_prof)
    omega = omega_grid(n_prof)
    x0_map = {f"m{j}": 0.01 * np.sin(np.pi * j / (2 * n_prof)) for j in range(1, n_prof + 1)}
    profiles = {
        f"ctmm.frequency_response n={n_prof}": profile_top(
            lambda: ctmm.frequency_response(system, omega, input="m1.force", output=["m1.x", f"m{n_prof}.x"])),
        f"ctmm.simulate fast path n={n_prof}, 200 steps": profile_top(
            lambda: ctmm.simulate(system, N_STEPS * DT, DT, x0=x0_map, fast=True)),
        f"ctmm.simulate generic path n={n_prof}, 10 steps": profile_top(
            lambda: ctmm.simulate(system, 10 * DT, DT, x0=x0_map, fast=False)),
    }
    step_ns = [c["n"] for c in step_cases if c["n"] >= 100]
    step_slopes = {key: slope(step_ns, [c["methods"][key].get("time_per_step_s") or np.nan
                                        for c in step_cases if c["n"] >= 100])
                   for key in step_cases[0]["methods"]}
    return {
        "benchmark": "foundation_scaling",
        "chain": ("fixed-free wall-(K||c)-m x n, K=1000 N/m, m=0.1 kg, c=0.2 N s/m (stiffness-proportional "
                  "light damping, zeta_j = 1e-4 s * omega_j)"),
        "frequency_response": {
            "definition": ("1000 log-spaced omega in [omega_1/2, 0.95*200] rad/s, unit force on m1, outputs m1.x "
                           "(driving point) and m_n.x (tip) from one solve; time = whole call, best of up to 3 "
                           "while < 1 s spent"),
            "cases": frf_cases},
        "time_stepping": {
            "definition": (f"Newmark(1/4,1/2), dt={DT} s, {N_STEPS} steps (fewer when the probe estimate exceeds "
                           f"{BUDGET_S} s: flag reduced_steps), x_i(0)=0.01 sin(pi i/(2n)) m, 100 N on m1; "
                           "time per step = whole call / steps (ctmm: also loop-only); difference to "
                           "reference.newmark_global(banded=True) over all masses and steps"),
            "cases": step_cases,
            "fitted_exponent_time_per_step_vs_n_(n>=100)": step_slopes},
        "targets": targets(frf_cases),
        "profiles_top_own_time": profiles,
        "machine": machine(),
        "code_version": version,
        "quick": quick,
    }


def plot(summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_f, ax_s) = plt.subplots(1, 2, figsize=(12, 4.8))
    cases = summary["frequency_response"]["cases"]
    ns = [c["n"] for c in cases]
    for key, marker in (("ctmm", "o"), ("banded", "s"), ("banded_vectorised", "v"), ("dense", "D"), ("python_control", "^"),
                        ("prototype", "x")):
        t = [c["methods"][key].get("time_s") for c in cases]
        ext = [c["methods"][key].get("extrapolated", False) for c in cases]
        pts = [(n, v) for n, v in zip(ns, t) if v is not None]
        if pts:
            line = ax_f.loglog(*zip(*pts), marker=marker, label=key + (" (open: extrapolated)" if any(ext) else ""))[0]
            for n, v, e in zip(ns, t, ext):
                if v is not None and e:
                    ax_f.loglog([n], [v], marker=marker, mfc="white", color=line.get_color())
    ax_f.set_xlabel("masses n")
    ax_f.set_ylabel("wall time for 1000 frequencies [s]")
    ax_f.set_title("(a) frequency response")
    scases = summary["time_stepping"]["cases"]
    sns = [c["n"] for c in scases]
    for key, marker in (("ctmm_fast", "o"), ("ctmm_generic", "v"), ("global_banded", "s"),
                        ("global_dense", "D"), ("global_banded_On", "x")):
        pts = [(n, c["methods"][key].get("time_per_step_s")) for n, c in zip(sns, scases)]
        pts = [p for p in pts if p[1] is not None]
        if pts:
            ax_s.loglog(*zip(*pts), marker=marker, label=key)
    ax_s.set_xlabel("masses n")
    ax_s.set_ylabel("wall time per Newmark step [s]")
    ax_s.set_title("(b) time stepping")
    for ax in (ax_f, ax_s):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    load = summary.get("machine", {}).get("load_average_1_5_15min")
    if load:
        fig.suptitle(f"shared 2-core machine, load average {load[0]:.1f} during the run "
                     "(CPU times in the JSON)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="n <= 1000 only")
    parser.add_argument("--output", type=Path, default=RESULTS, help="output folder")
    args = parser.parse_args(argv)
    started = time.perf_counter()
    summary = run(SIZES[:3] if args.quick else SIZES, quick=args.quick)
    summary["total_wall_time_s"] = time.perf_counter() - started
    args.output.mkdir(parents=True, exist_ok=True)
    write_json_atomic(args.output / "foundation_scaling.json", summary)
    plot(summary, args.output / "foundation_scaling.png")
    return summary


if __name__ == "__main__":
    main()
