"""Seed 002, Table 7.1 / Fig. 7.3: spring-mass chain by linear MSTMM, DT-TMM and the exact solution.

Chain (Fig. 7.1): wall - K1 - m2 - K3 - m4 - K5 - m6 - K7 - m8 - K9 - m10 (free end), K = 1000 N/m,
free length l = 0.1 m, m = 0.1 kg, constant force f = 100 N on the first mass from t = 0, zero
initial velocities.  The table's "initial displacement x0 = 0.1 ... 0.5 m" is read as

* reading A (used for the figure): absolute initial positions x_i(0) = 0.1 i m, i.e. every spring
  at its free length l = 0.1 m -- the only reading in which the positions in the table and the
  free lengths agree;
* reading B (reported in the JSON): displacements u_i(0) = 0.1 i m from the unstretched state.

Three solutions are compared, as in Fig. 7.3: the exact solution (matrix exponential of the
global M, K model in ctmm.reference.chain -- solid line), the DT-TMM (Newmark average
acceleration, h = 1 ms, "+") and the linear MSTMM (natural frequencies and modes from the
transfer matrices, modal superposition, "*").
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ctmm.scenario import accuracy

NAME = "table7_1"
DESCRIPTION = "Seed 002 Table 7.1 / Fig. 7.3: 5-mass chain by linear MSTMM, DT-TMM and the exact solution"

STIFFNESS, FREE_LENGTH, MASS, FORCE = 1000.0, 0.1, 0.1, 100.0


def build_chain():
    """The Table 7.1 chain with the book's element numbering (springs odd, masses even), built from its scene file
    ``scenarios/files/table7_1.toml`` (the one source of the TMM chain; the exact reference uses the constants above)."""
    from ctmm.scene_files import load_scene

    return load_scene(Path(__file__).resolve().parent / "files" / "table7_1.toml").system


def _exact(chain, times: np.ndarray, u0: np.ndarray) -> np.ndarray:
    from ctmm.reference import chain as reference

    g = reference.GlobalChain(np.full(5, MASS), np.r_[np.full(5, STIFFNESS), 0.0],
                              free_length=np.r_[np.full(5, FREE_LENGTH), 0.0], start="fixed", end="free")
    hist = reference.exact_response(g, times, u0, np.zeros(5), np.r_[FORCE, np.zeros(4)])
    return hist.displacement + FREE_LENGTH * np.arange(1, 6)   # absolute positions


def run(output_dir: Path, quick: bool = False, results: dict | None = None) -> dict:
    import matplotlib.pyplot as plt

    import ctmm
    from ctmm.modal import modal_response

    chain = build_chain()
    names = [f"m{2 * i + 2}" for i in range(5)]
    t_end, dt = (0.1, 1e-3) if quick else (0.5, 1e-3)
    summary: dict = {"reading": "A: absolute initial positions x_i(0) = 0.1 i m (springs at free length)",
                     "parameters": {"K": STIFFNESS, "l": FREE_LENGTH, "m": MASS, "F": FORCE, "dt": dt,
                                    "t_end": t_end, "scheme": "newmark(beta=1/4, gamma=1/2)"}}
    histories = {}
    for reading, offset in (("A", 0.0), ("B", 0.1)):
        x0 = {name: 0.1 * (i + 1) + offset * (i + 1) for i, name in enumerate(names)}
        start = time.perf_counter()
        sim = ctmm.simulate(chain, t_end, dt, method="newmark", x0=x0)
        t_dt = time.perf_counter() - start
        start = time.perf_counter()
        modal = modal_response(chain, sim.time, x0=x0)
        t_modal = time.perf_counter() - start
        start = time.perf_counter()
        exact = _exact(chain, sim.time, offset * np.arange(1, 6))
        t_exact = time.perf_counter() - start
        x_dt = np.column_stack([sim[f"{n}.x"] for n in names])
        x_modal = np.column_stack([modal[n] for n in names])
        histories[reading] = (sim.time, exact, x_dt, x_modal)
        if results is not None:                  # ctmm run --save
            results[f"reading_{reading}"] = sim
        summary[f"reading_{reading}"] = {
            "dt_tmm_max_error_m": float(np.max(np.abs(x_dt - exact))),
            "linear_mstmm_max_error_m": float(np.max(np.abs(x_modal - exact))),
            "dt_tmm_wall_time_s": t_dt, "linear_mstmm_wall_time_s": t_modal,
            "exact_wall_time_s": t_exact}
    a = summary["reading_A"]
    summary.update({"accuracy": [
        accuracy("linear MSTMM error vs exact", a["linear_mstmm_max_error_m"], "m", 1e-9,
                 "max over masses and steps |x_MSTMM - x_exact|, reading A (modal superposition with the TMM "
                 "natural frequencies and modes against the matrix exponential of the global model)",
                 source="README: natural frequencies = eigh to < 1e-13 relative; 1e-9 m on 0.1 m motions"),
        accuracy("DT-TMM error vs exact", a["dt_tmm_max_error_m"], "m", 0.033,
                 "max over masses and steps |x_DT-TMM - x_exact|, reading A (Newmark, h = 1 ms: a "
                 "discretisation error of order h^2)",
                 source="Newmark phase-error estimate A w^3 h^2 t / 12 with A = 0.1 m, w = 200 rad/s, t = 0.5 s")],
                    "wall_time_s": a["dt_tmm_wall_time_s"], "reference_wall_time_s": a["exact_wall_time_s"]})
    t, exact, x_dt, x_modal = histories["A"]
    fig, ax = plt.subplots(figsize=(8, 4.5))
    every = max(1, len(t) // 50)
    for i, name in enumerate(names):
        line, = ax.plot(t, exact[:, i], "-", lw=1.2, label="exact (m2 ... m10, bottom to top)" if i == 0 else None)
        ax.plot(t[::every], x_dt[::every, i], "+", color=line.get_color(), ms=7,
                label="DT-TMM (Newmark)" if i == 0 else None)
        ax.plot(t[::every][::2], x_modal[::every, i][::2], "*", color=line.get_color(), ms=5,
                label="linear MSTMM (modal)" if i == 0 else None)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("position x [m]")
    ax.set_title("Table 7.1 chain (reading A): exact (-), DT-TMM (+), linear MSTMM (*)")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    png = Path(output_dir) / "table7_1.png"
    fig.savefig(png, dpi=120)
    plt.close(fig)
    summary["figures"] = [png.name]
    return summary
