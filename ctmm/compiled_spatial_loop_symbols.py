"""A spatial kinematic loop model on casadi symbols: the loop sensors of its generated kernels (issues 13 x 16).

:class:`SpatialKinematicLoopSymbols` states the sensors of a
:class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel` for :class:`ctmm.compiled_loops.ClosedLoops`: the
tree's (:class:`ctmm.compiled_spatial_loops.SpatialSymbols`), the cut coordinates and rates, the cut laws' moments
and forces, a spherical cut law's moment -- functions of the state and the time -- and, given the closed-loop rates
on symbols, the cut forces ``"<cut>.force_x|y|z"`` [N] (on the child, world axes) under the kernel's actuator values
``w``: ``F = F_0(q, v, t) + J(q, v, t) w`` exactly (:meth:`SpatialKinematicLoopSymbols.input_sensor_map`; the cut
unknowns of :func:`ctmm.compiled_spatial_kinematic_loops.symbolic_spatial_closed_loop` are affine in the applied
loads, which are linear in ``w``), which :class:`~ctmm.compiled_input_sensors.InputDependentSensors` closes as it does
the planar cut forces: a real-time loop on one as the algebraic loop of the stage, a delayed one sampled with its
exact rate.  Used by the generated loop driver (:mod:`ctmm.compiled_kinematic_loop_control`) and, without the cut
forces, by the generated DT-TMM schemes with loops (:mod:`ctmm.compiled_spatial_loop_scheme_control`).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .compiled_input_sensors import affine_sensor_map
from .errors import ModelError

__all__ = ["SpatialKinematicLoopSymbols"]


class SpatialKinematicLoopSymbols:
    """A spatial kinematic loop model on symbols for :class:`ctmm.compiled_loops.ClosedLoops`: the tree's sensors by
    :class:`ctmm.compiled_spatial_loops.SpatialSymbols`, the cut sensors ``"<cut>.angle"`` / ``"<cut>.position"``
    and ``"<cut>.rate"`` (a cut law's ``"<cut>.law_moment"`` / ``"<cut>.law_force"`` too) by the cut coordinates on
    symbols, a spherical cut law's ``"<cut>.moment_x|y|z"`` by its moment on symbols
    (:func:`ctmm.compiled_spatial_kinematic_loops.symbolic_spatial_closed_loop`) and, given ``closed``, every cut's
    force ``"<cut>.force_x|y|z"`` under the kernel's actuator values (:meth:`input_sensor_map`).

    Parameters
    ----------
    model : SpatialKinematicLoopModel
    ports : SpatialLoopPorts
        The ports of the controlled model (the tree's and the cut joints').
    coordinates : casadi.Function
        ``cut_coordinates(q, v, t) -> [s_1, s_1', ...]``.
    law_moments : casadi.Function, optional
        ``law_moments(q, v, t) -> [m_1 ; m_2 ; ...]`` (3 per cut; needed by the spherical law moment sensors).
    closed : casadi.Function, optional
        ``closed(q, v, u, p, t)`` of :func:`ctmm.compiled_spatial_kinematic_loops.symbolic_spatial_closed_loop` with
        the kernel's actuators: the cut forces ``"<cut>.force_x|y|z"`` become sensors that respond to the actuators
        at once (:attr:`input_dependent`, closed by :class:`~ctmm.compiled_input_sensors.InputDependentSensors`);
        without it they are refused by name.

    Attributes
    ----------
    input_dependent : frozenset of str
        The sensors that respond to the actuators at once (the cut forces; empty without ``closed``).
    parameters : numpy.ndarray
        The plant's numbers of the kernel's parameter column (none: every number is a constant of the code).

    The sensors read the time ``t`` too (:attr:`time_sensors`): with driven tree joints the tree's sensors outboard
    of them, the cut coordinates and the law moments move with the prescribed motion, as in the numpy driver.
    """

    time_sensors = True

    def __init__(self, model: Any, ports: Any, coordinates: Any, law_moments: Any = None, closed: Any = None
                 ) -> None:
        from .compiled_spatial_loops import SpatialSymbols
        from .spatial.ports import SpatialPorts

        self.model, self.ports, self.coordinates, self.law_moments = model, ports, coordinates, law_moments
        self.closed, self.parameters = closed, np.zeros(0)
        self.tree_symbols = SpatialSymbols(model.tree, SpatialPorts(model.tree))
        self.n_positions, self.n_velocities = model.tree.n_positions, model.tree.n_velocities
        self.cut_index = {cut.name: k for k, cut in enumerate(model.cuts)}
        self.input_dependent = frozenset(f"{cut.name}.force_{axis}" for cut in model.cuts for axis in "xyz"
                                         ) if closed is not None else frozenset()

    def input_sensor_map(self, names: Sequence[str], n_actuators: int) -> Any:
        """``(q, v, p, t) -> (F_0, J)``: the cut forces ``names`` (``"<cut>.force_x|y|z"`` [N], on the child, world
        axes, as :meth:`SpatialKinematicLoopModel.cut_loads` of :meth:`~SpatialKinematicLoopModel.solve` with the
        inputs) ``F = F_0 + J w`` under the kernel's actuator values ``w`` (``n_actuators``, the ``closed`` rates'
        inputs; ``p`` empty), exactly (:func:`ctmm.compiled_input_sensors.affine_sensor_map`)."""
        import casadi as ca

        q, v = ca.SX.sym("q", self.n_positions), ca.SX.sym("v", self.n_velocities)
        w, p, t = ca.SX.sym("w", n_actuators), ca.SX.sym("p", 0), ca.SX.sym("t")
        forces = self.closed(q, v, w, p, t)[6]
        F = ca.vertcat(*[forces[3 * self.cut_index[name.rpartition(".")[0]] + "xyz".index(name[-1])]
                         for name in names])
        return affine_sensor_map(F, w, [q, v, p, t])

    def position_rates(self, q: Any, v: Any) -> Any:
        """``q' = G(q) v`` (quaternion rates from body-axes angular velocities)."""
        return self.tree_symbols.position_rates(q, v)

    def sensor(self, name: str, q: Any, v: Any, t: Any = 0.0) -> Any:
        """Sensor ``name`` as an expression of the symbols ``q``, ``v`` and the time ``t`` [s].

        A spherical cut's law moment ``"<cut>.moment_x|y|z"`` [N m] (world axes) is ``law_moments(q, v, t)``
        (:func:`ctmm.compiled_spherical_cut_law.symbolic_spherical_law_moment`).

        Raises
        ------
        ModelError
            A cut force ``"<cut>.force_x|y|z"``: it responds to the actuators at once (read with the kernel's
            actuator values, :meth:`input_sensor_map`, where ``closed`` is given; refused by name where not: the
            generated DT-TMM schemes).
        """
        cut_name, _, part = name.rpartition(".")
        if cut_name in self.cut_index and part in ("force_x", "force_y", "force_z"):
            if self.closed is not None:
                raise ModelError(f"sensor {name!r}: a cut force responds to the actuators at once, not a function of "
                                 "the state alone; read it with the kernel's actuator values (input_sensor_map)")
            raise ModelError(f"sensor {name!r}: a cut force responds to the actuators at once, and the generated "
                             "DT-TMM schemes read their loop sensors from the state alone; use method='rk4' (the "
                             "generated loop driver closes loops on cut forces) or compiled=None")
        if cut_name in self.cut_index and part in ("moment_x", "moment_y", "moment_z") and \
                self.model.cuts[self.cut_index[cut_name]].kind == "spherical":
            return self.law_moments(q, v, t)[3 * self.cut_index[cut_name] + "xyz".index(part[-1])]
        if cut_name in self.cut_index and part in ("angle", "position", "rate"):
            return self.coordinates(q, v, t)[2 * self.cut_index[cut_name] + (part == "rate")]
        if cut_name in self.cut_index and part in ("law_moment", "law_force"):     # -law(s - rest, s')
            k, cut = self.cut_index[cut_name], self.model.cuts[self.cut_index[cut_name]]
            coordinates = self.coordinates(q, v, t)
            return -cut.law.force(coordinates[2 * k] - cut.rest, coordinates[2 * k + 1])
        return self.tree_symbols.sensor(name, q, v, t)
