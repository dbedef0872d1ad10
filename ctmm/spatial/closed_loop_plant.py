"""A spatial kinematic loop model as a plant of the one loop-closing time driver (``docs/closed_loops.md`` §8.6).

:class:`SpatialLoopPlant` implements the plant protocol of :mod:`ctmm.control.plants` for a
:class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel`, so that feedback loops
(``ctmm.control.with_feedback(loop_model, loops)``), open-loop port actuator inputs, references, sensor outputs and
co-simulated controllers act on a spatial mechanism with cut joints:

* the ports are the spanning tree's (:class:`~ctmm.spatial.ports.SpatialPorts`) and the revolute and prismatic cut
  joints' (:class:`~ctmm.spatial.closed_loop_ports.SpatialLoopPorts`: coordinate, rate; torque or force);
* the accelerations are the closed-loop ones with the actuator values of the stage applied to the tree **before**
  the cut loads are solved (:meth:`SpatialKinematicLoopModel.solve`: the sweep is affine in the applied loads, so
  the cut loads react to the drive);
* the stored signals add the cut forces ``"<cut>.force_x|y|z"`` [N] (and moments of revolute and universal cuts)
  with the row's actuator values (``signals_need_inputs``), ``"drift"`` and ``"drift_rate"``.

The DT-TMM schemes step the spanning tree (``implicit_model``) with the cut loads solved under each iterate's actuator
values (``implicit_inputs``); they and ``"rk4"`` project every accepted step onto the cut joints
(``step_projection``), the ``solve_ivp`` methods at every controller sample (:mod:`ctmm.control.explicit_loops`;
Baumgarte alone holds the drift between).
"""
from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np

from ..loop_integration import StepProjection
from .closed_loops import SpatialKinematicLoopModel
from .model import SpatialModel
from .integrate import divergence_check, spatial_signals
from .closed_loop_ports import SpatialLoopPorts

__all__ = ["SpatialLoopPlant", "add_cut_signals"]


def add_cut_signals(model: SpatialKinematicLoopModel, signals: dict, units: dict, forces: np.ndarray,
                    moments: np.ndarray, drift: np.ndarray, drift_rate: np.ndarray) -> None:
    """Add ``"<cut>.force_x|y|z"`` [N], ``"<cut>.moment_x|y|z"`` [N m] (all but spherical cuts without a law; on the
    child, world axes), ``"drift"`` and ``"drift_rate"`` to ``signals`` and ``units`` (``forces``, ``moments``:
    ``(N, n_cuts, 3)``)."""
    for j, cut in enumerate(model.cuts):
        for axis, label in enumerate("xyz"):
            signals[f"{cut.name}.force_{label}"], units[f"{cut.name}.force_{label}"] = forces[:, j, axis], "N"
            if cut.kind != "spherical" or cut.law is not None:
                signals[f"{cut.name}.moment_{label}"] = moments[:, j, axis]
                units[f"{cut.name}.moment_{label}"] = "N m"
    signals["drift"], units["drift"] = drift, ""
    signals["drift_rate"], units["drift_rate"] = drift_rate, ""


class SpatialLoopPlant:
    """A :class:`SpatialKinematicLoopModel` as a plant of the loop-closing driver (module docstring).

    Parameters
    ----------
    model : SpatialKinematicLoopModel
    """

    label = "spatial kinematic loop"
    schemes = True
    signals_need_inputs = True

    def __init__(self, model: SpatialKinematicLoopModel) -> None:
        self.model = model
        self.ports = SpatialLoopPorts(model)
        self.n_positions, self.n_velocities = model.tree.n_positions, model.tree.n_velocities
        self.element_names = tuple(self.ports.element_names) + tuple(cut.name for cut in model.cuts)

    @property
    def implicit_model(self) -> SpatialModel:
        """The model an implicit DT-TMM scheme steps: the spanning tree (cut loads through the inputs)."""
        return self.model.tree

    def implicit_inputs(self, inputs: Callable[[float, np.ndarray, np.ndarray], Any] | None
                        ) -> Callable[[float, np.ndarray, np.ndarray], Any]:
        """The ``input_map`` of the tree's implicit stepper: the actuator values of ``inputs`` (or none) plus the cut
        loads solved with them (:meth:`SpatialKinematicLoopModel.cut_inputs`)."""
        def hook(t: float, q: np.ndarray, v: np.ndarray) -> Any:
            return self.model.cut_inputs(q, v, t, inputs(t, q, v) if inputs is not None else None)
        return hook

    def step_projection(self) -> StepProjection:
        """A projection onto the cut joints for the accepted steps of the loop driver's runs (the RK4's rule)."""
        return StepProjection(self.model, f"spatial kinematic loop {self.model.name!r}")

    def position_rates(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``q_dot = G(q) v`` (1-D)."""
        return self.model.tree.position_rates(q[None], v[None])[0]

    def accelerations(self, q: np.ndarray, v: np.ndarray, t: float, inputs: Any) -> np.ndarray:
        """Closed-loop ``v_dot`` with the actuator ``inputs`` (:class:`~ctmm.spatial.ports.SpatialInputs`)."""
        return self.model.solve(q, v, t, inputs)[0]

    def signals(self, t: np.ndarray, q: np.ndarray, v: np.ndarray, outputs: Sequence[str],
                inputs: Sequence[Any] | None = None) -> tuple[dict, dict]:
        """The tree's coordinates, velocities, body positions and angular velocities, the sensor ``outputs``, the
        cut loads with the row's actuator ``inputs``, ``"drift"`` and ``"drift_rate"``."""
        model, ports = self.model, self.ports
        t = np.asarray(t, dtype=float)
        nq, nv = self.n_positions, self.n_velocities
        q, v = np.reshape(q, (len(t), nq)), np.reshape(v, (len(t), nv))
        signals, units = spatial_signals(model.tree, t, np.concatenate([q, v], axis=1))
        outputs = [name for name in dict.fromkeys(outputs) if name not in ports.input_dependent]  # cut forces: below
        if outputs:
            sensors = ports.resolve(outputs)
            values = np.array([ports.values(sensors, q[k], v[k], float(t[k])) for k in range(len(t))]
                              ).reshape(len(t), len(outputs))
            for k, name in enumerate(outputs):
                signals[name], units[name] = values[:, k], ports.sensor_unit(name)
        rows = [None] * len(t) if inputs is None else list(inputs)
        forces = np.zeros((len(t), len(model.cuts), 3))
        moments = np.zeros((len(t), len(model.cuts), 3))
        drift, rate = np.zeros(len(t)), np.zeros(len(t))
        for k in range(len(t)):
            phi, phi_dot, loads, law = model.stored_row(q[k], v[k], float(t[k]), rows[k])
            forces[k], moments[k] = [f for f, _ in loads], [m for _, m in loads]
            moments[k] += law                                            # a spherical cut's law
            drift[k], rate[k] = np.max(np.abs(phi)), np.max(np.abs(phi_dot))
        add_cut_signals(model, signals, units, forces, moments, drift, rate)
        return signals, units

    def guard(self, q0: np.ndarray, bound: float | None, v0: np.ndarray | None = None
              ) -> Callable[[float, np.ndarray, float | None, str], None]:
        """The tree's run guard (finite states, ``divergence_bound`` from the start) at every accepted step."""
        size = self.n_positions + self.n_velocities
        start = np.concatenate([q0, np.zeros(self.n_velocities) if v0 is None else v0])
        check = divergence_check(self.model.tree, start, bound)
        return lambda t, y, step, method: check(t, y[:size], method)

    def check_step(self, q0: np.ndarray, v0: np.ndarray, dt: float, policy: str) -> None:
        """No pre-run step limit for spatial models yet (the run's own guards apply)."""
