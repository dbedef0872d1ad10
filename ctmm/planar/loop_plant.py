"""A closed kinematic loop model as a plant of the one loop-closing time driver.

:class:`KinematicLoopPlant` implements the plant protocol of :mod:`ctmm.control.plants` for a
:class:`~ctmm.planar.closed_loops.KinematicLoopModel`, so that feedback loops, open-loop actuator inputs and
co-simulated controllers act on a mechanism with cut joints (``docs/closed_loops.md`` §3c):

* the ports are those of the spanning tree (:class:`~ctmm.planar.ports.PlanarPorts`: hinge angles and
  rates, body angles, point positions and velocities; hinge torques, body forces and moments) and of the cut
  joints (:class:`~ctmm.planar.loop_ports.KinematicLoopPorts`: ``"<cut>.angle"``, ``"<cut>.rate"``,
  ``"<cut>.moment"``; ``"<cut>.torque"``);
* the accelerations are the closed-loop ones, ``qddot`` with the cut forces solved as boundary unknowns
  **with the actuator inputs applied** (:meth:`KinematicLoopModel.solve`: the sweep is affine in the
  applied forces, so the boundary compliance ``G`` is unchanged and the cut forces react to the drive);
* the stored signals add the cut forces ``"<cut>.force_x|y"`` [N] (with the row's actuator values:
  ``signals_need_inputs``), the constraint drift ``"drift"`` [m] and ``"drift_rate"`` [m/s];
* the implicit DT-TMM schemes step the spanning tree (``implicit_model``) with the cut forces added to the
  actuator inputs at every Newton iterate (``implicit_inputs``), as in the open-loop scheme runs;
* every accepted step is projected onto the cut joints (``step_projection``,
  :class:`ctmm.loop_integration.StepProjection`): the schemes' and RK4's; ``solve_ivp`` runs at every controller
  sample (:mod:`ctmm.control.explicit_loops`; Baumgarte alone holds the drift between).
"""
from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np

from ..loop_integration import StepProjection
from .closed_loops import KinematicLoopModel
from .guards import check_scheme, divergence_guard
from .integrate import check_state, model_signals
from .loop_ports import KinematicLoopPorts, loop_sensor_signals, tree_outputs
from .loop_verbs import cut_moment_signals
from .model import PlanarModel

__all__ = ["KinematicLoopPlant"]


class KinematicLoopPlant:
    """A :class:`~ctmm.planar.closed_loops.KinematicLoopModel` as a plant of the loop-closing driver.

    Parameters
    ----------
    model : KinematicLoopModel
        The tree plus cut joints; its actuators and sensors are the tree's and the cut joints' ports.
    """

    label = "kinematic loop"
    schemes = True
    signals_need_inputs = True

    def __init__(self, model: KinematicLoopModel) -> None:
        self.model = model
        self.ports = KinematicLoopPorts(model)
        self.n_positions = self.n_velocities = model.tree.n_coordinates
        self.element_names = (tuple(model.tree.body_names) + tuple(model.tree.joint_names)
                              + tuple(cut.name for cut in model.cuts))

    @property
    def implicit_model(self) -> PlanarModel:
        """The model an implicit DT-TMM scheme steps: the spanning tree (cut forces through the inputs)."""
        return self.model.tree

    def implicit_inputs(self, inputs: Callable[[float, np.ndarray, np.ndarray], Any] | None
                        ) -> Callable[[float, np.ndarray, np.ndarray], Any]:
        """The ``inputs`` hook of the tree's implicit stepper: the actuator values of ``inputs`` (or none)
        plus the cut forces solved with them (:meth:`KinematicLoopModel.cut_inputs`)."""
        def hook(t: float, q: np.ndarray, v: np.ndarray) -> Any:
            driven = inputs(t, q, v) if inputs is not None else None
            return self.model.cut_inputs(q, v, t, driven)
        return hook

    def step_projection(self) -> StepProjection:
        """A projection onto the cut joints for the accepted steps of the loop driver's runs (the RK4's rule)."""
        return StepProjection(self.model, f"kinematic loop {self.model.name!r}")

    def position_rates(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``qdot = v`` [rad/s, m/s]."""
        return v

    def accelerations(self, q: np.ndarray, v: np.ndarray, t: float, inputs: Any) -> np.ndarray:
        """Closed-loop ``qddot`` with the actuator ``inputs`` (cut forces as boundary unknowns)."""
        return self.model.solve(q, v, t, inputs)[0]

    def signals(self, t: np.ndarray, q: np.ndarray, v: np.ndarray, outputs: Sequence[str],
                inputs: Sequence[Any] | None = None) -> tuple[dict, dict]:
        """Tree coordinates, rates and sensor ``outputs``; the cut forces [N] (with the row's actuator
        ``inputs``), ``"drift"`` [m] and ``"drift_rate"`` [m/s]."""
        model = self.model
        t = np.asarray(t, dtype=float)
        n = self.n_positions
        q, v = np.reshape(q, (len(t), n)), np.reshape(v, (len(t), n))
        signals, units = model_signals(model.tree, t, q, v, tree_outputs(self.ports, outputs))
        cut_signals, cut_units = loop_sensor_signals(self.ports, t, q, v, outputs)
        signals.update(cut_signals)
        units.update(cut_units)
        rows = [None] * len(t) if inputs is None else list(inputs)
        forces = np.array([model.solve(q[k], v[k], float(t[k]), rows[k])[1] for k in range(len(t))]
                          ).reshape(len(t), len(model.cuts), 2)
        drift = np.zeros(len(t))
        rate = np.zeros(len(t))
        for k in range(len(t)):
            phi, phi_dot = model.constraints(q[k], v[k], float(t[k]))
            drift[k], rate[k] = np.max(np.abs(phi)), np.max(np.abs(phi_dot))
        for j, cut in enumerate(model.cuts):
            for axis, column in (("x", 0), ("y", 1)):
                signals[f"{cut.name}.force_{axis}"] = forces[:, j, column]
                units[f"{cut.name}.force_{axis}"] = "N"
        moments = cut_moment_signals(model, t, q, v, rows)
        signals.update(moments)
        units.update(dict.fromkeys(moments, "N m"))
        signals["drift"], units["drift"] = drift, "m"
        signals["drift_rate"], units["drift_rate"] = rate, "m/s"
        return signals, units

    def guard(self, q0: np.ndarray, bound: float | None, v0: np.ndarray | None = None
              ) -> Callable[[float, np.ndarray, float | None, str], None]:
        """The tree's guards (divergence bound from ``q0``, non-finite states) at every accepted step."""
        tree = self.model.tree
        guard = divergence_guard(tree, q0, bound)
        return lambda t, y, step, method: check_state(tree, guard, t, y, step, method)

    def check_step(self, q0: np.ndarray, v0: np.ndarray, dt: float, policy: str) -> None:
        """RK4 step against the limit of the closed-loop accelerations linearised about the initial state
        (cut forces and Baumgarte terms included; the feedback loops are not)."""
        check_scheme(self.model.tree, q0, v0, dt, scheme="rk4", policy=policy,
                     accelerations=lambda _, q, v, t: self.model.solve(q, v, t)[0],
                     label=f"kinematic loop model {self.model.name!r}")
