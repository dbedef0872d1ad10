"""Shared run, summary and plotting of the mixed-method scenarios (``fem_chain``, ``particle_net``,
``particle_chain``): the mixed model and its global reference with the same RK4 step, the accuracy entry
of their coordinates, the particles' global positions, the rotation and energy panels."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

import ctmm
from ctmm.scenario import accuracy

GLOBAL_MODEL = "global Lagrange model of ctmm.reference.mixed_global"


@dataclass(frozen=True)
class SameStepRun:
    """Histories of the mixed model (``q``, ``v``, its coordinate order) and of the global reference (``q_ref``,
    ``v_ref``, the reference's order), ``error`` = max |q - q_ref| [rad or m], energies [J] every ``every`` steps."""

    time: np.ndarray
    q: np.ndarray
    v: np.ndarray
    q_ref: np.ndarray
    v_ref: np.ndarray
    error: float
    every: int
    energy: np.ndarray
    energy_ref: np.ndarray
    wall_time_s: float

    @property
    def energy_drift(self) -> float:
        """(max - min) / max |E| of the mixed run's energy."""
        return float(np.ptp(self.energy) / np.max(np.abs(self.energy)))

    @property
    def energy_error(self) -> float:
        """max |E - E_ref| / max |E_ref|."""
        return float(np.max(np.abs(self.energy - self.energy_ref)) / np.max(np.abs(self.energy_ref)))


def same_step_run(mixed, reference, q0: np.ndarray, t_final: float, step: float,
                  order: Sequence[int] | None = None) -> SameStepRun:
    """RK4 of ``mixed`` (``ctmm.simulate``) and of ``reference`` (``GlobalChain.rk4``) from ``q0`` at rest.

    ``order``: the mixed coordinates' indices in the reference's order (default: the same order)."""
    names = mixed.coordinates
    order = list(range(len(names))) if order is None else list(order)
    result = ctmm.simulate(mixed, t_final, step, method="rk4", x0=q0)
    q, v = histories(result, names)
    _, q_ref, v_ref = reference.rk4(q0[order], np.zeros(len(order)), t_final, step)
    every = max(1, q.shape[0] // 200)
    energy = np.array([mixed.energy(q[k], v[k]) for k in range(0, q.shape[0], every)])
    energy_ref = np.array([reference.energy(q_ref[k], v_ref[k]) for k in range(0, q.shape[0], every)])
    return SameStepRun(result.time, q, v, q_ref, v_ref, float(np.max(np.abs(q[:, order] - q_ref))), every, energy,
                       energy_ref, result.info["wall_time_s"])


def histories(result: Any, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates and their rates (rows: times, columns: ``names``) of a simulation result."""
    return np.column_stack([result[c] for c in names]), np.column_stack([result[c + "_dot"] for c in names])


def same_step(step: float) -> str:
    """How the mixed run and the global reference were integrated (``step`` [s])."""
    return f"same RK4 step h = {step * 1e3:g} ms, {GLOBAL_MODEL}"


def coordinates_accuracy(error: float, bound: float, coordinates: str, step: float, source: str) -> dict:
    """The accuracy entry ``max |q_TMM - q_global|`` [rad or m] over ``coordinates`` (what they are)."""
    return accuracy("coordinates vs global model, same integrator", error, "rad or m", bound,
                    f"max over t and all coordinates ({coordinates}) of |q_TMM - q_global|, {same_step(step)}",
                    source=source)


def largest_net_displacement(q: np.ndarray, names: Sequence[str]) -> float:
    """Largest ``|q|`` [m] of the subsystem's coordinates (``"net.*"``) over a history."""
    return float(np.max(np.abs(q[:, [i for i, c in enumerate(names) if c.startswith("net.")]])))


def particle_positions(reference: Any, history: np.ndarray, names: Sequence[str], body: str, hinge: int,
                       particles: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Global positions [m] (rows of ``history``, x and y) of the ``particles`` ``{name: position in the axes of
    body}`` carried by ``body`` from the reference's hinge ``hinge``, displaced by ``"net.<name>_ux"``, ``_uy``."""
    out: dict[str, list] = {p: [] for p in particles}
    for row in history:
        tip = reference.hinge_positions(row)[hinge]
        th = row[names.index(f"{body}.theta")]
        R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        for p, xy in particles.items():
            out[p].append(tip + R @ (np.asarray(xy) + row[[names.index(f"net.{p}_ux"), names.index(f"net.{p}_uy")]]))
    return {p: np.array(v) for p, v in out.items()}


def plot_rotations(ax: Any, run: SameStepRun, names: Sequence[str], bodies: Sequence[str],
                   label: Callable[[str], str]) -> None:
    """The bodies' angles of the mixed run (lines) and of the reference (crosses, every fourth sample)."""
    for body in bodies:
        i = names.index(f"{body}.theta")
        ax.plot(run.time, run.q[:, i], label=label(body))
        ax.plot(run.time[::run.every * 4], run.q_ref[::run.every * 4, i], "kx")


def plot_energy(ax: Any, run: SameStepRun, title: str) -> None:
    """``E(t) - E(0)`` [J] of the mixed run and of the reference."""
    t = run.time[::run.every]
    ax.plot(t, run.energy - run.energy[0], label="mixed (RK4)")
    ax.plot(t, run.energy_ref - run.energy_ref[0], "k--", label="global model (RK4)")
    ax.set(xlabel="t [s]", ylabel="E(t) - E(0) [J]", title=title)
