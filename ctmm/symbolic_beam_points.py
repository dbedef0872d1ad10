"""Deformed points of planar beams and ``ctmm.fem`` subsystems on casadi symbols, from the numpy definitions.

:class:`ctmm.compiled_planar_sensors.SymbolicKinematics` (the tree's kinematics of generated loop sensors, cut points and
exported sensors) places the children and named points of a deformable body with :class:`DeformedPoints`, which
runs the numpy path's own statements on traced casadi scalars (:mod:`ctmm.traced_scalar`):

* a child's inboard end and a named end of a deformable body: :meth:`ctmm.planar.model.PlanarModel.beam_point_local`
  with ``shortening=True``, as :meth:`~ctmm.planar.model.PlanarModel.points` and the ports' point sensors use it: a
  ``ModalBeam`` end ``X_e + S_e eta`` moved by the foreshortening ``-1/2 w^T G1(x_e) w`` under
  ``second_order_inertia=True`` (its rate ``-w^T G1(x_e) w_dot``), a ``ctmm.fem`` subsystem's outboard node by its
  nodal displacement (``point_local``);
* the deformed centre of mass: a ``ctmm.fem`` subsystem's ``centroid_local``; a ``ModalBeam``'s ``s_bar / m`` (as
  stated in :meth:`~ctmm.planar.model.PlanarModel.points`).

and of a spatial beam or ``ctmm.fem`` spatial subsystem (:func:`spatial_deformed_point`, the point sensors of
:class:`ctmm.compiled_spatial_loops.SpatialSymbols`): :func:`ctmm.spatial.beam_ports.deformed_point`, the numpy point
sensors' definition, moved by the shortening of a ``SpatialBeam`` with ``second_order_inertia``.

So the generated positions and velocities equal the numpy ones to rounding (``tests/test_symbolic_beam_points.py``).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .planar.model import PlanarModel
from .spatial.beam_ports import deformed_point
from .traced_scalar import traced_array, untraced

__all__ = ["DeformedPoints", "spatial_deformed_point"]


class DeformedPoints:
    """Points of the deformable bodies of a planar model in their floating frames, on casadi symbols.

    Parameters
    ----------
    model : PlanarModel
    q, v : casadi SX
        Coordinate [m, rad, modal] and rate symbols (``n_coordinates`` each).
    """

    def __init__(self, model: PlanarModel, q: Any, v: Any) -> None:
        n = model.n_coordinates
        self.model = model
        self.q = traced_array([q[k] for k in range(n)])
        self.v = traced_array([v[k] for k in range(n)])

    def end(self, j: int, end: int) -> tuple[tuple, tuple]:
        """End ``end`` (index into the body's ends) of deformable body ``j`` in its frame: position [m] and velocity
        relative to the frame [m/s] (2-tuples of casadi expressions), with the foreshortening of a second-order
        beam."""
        position, velocity = self.model.beam_point_local(j, end, self.q, self.v, shortening=True)
        return tuple(map(untraced, position)), tuple(map(untraced, velocity))

    def centroid(self, j: int) -> tuple[tuple, tuple]:
        """Deformed centre of mass of deformable body ``j`` in its frame: position [m] and velocity relative to the
        frame [m/s] (2-tuples of casadi expressions)."""
        d, index = self.model.beams[j].data, self.model.modal_index[j]
        eta, eta_dot = self.q[index], self.v[index]
        if hasattr(d, "centroid_local"):                 # a ctmm.fem subsystem states its own
            position, velocity = d.centroid_local(eta, eta_dot)
        else:
            position = np.array([d.Sx + eta[d.nq:] @ d.b_p, eta[:d.nq] @ d.b_q], dtype=object) / d.m
            velocity = np.array([eta_dot[d.nq:] @ d.b_p, eta_dot[:d.nq] @ d.b_q], dtype=object) / d.m
        return tuple(map(untraced, position)), tuple(map(untraced, velocity))


def spatial_deformed_point(body: Any, point: Any, eta: Any, eta_dot: Any) -> tuple[Any, Any]:
    """Point ``point`` (body-axes position [m] of the undeformed point) of a spatial beam or ``ctmm.fem`` spatial
    subsystem ``body`` on its modal coordinate symbols ``eta`` and rate symbols ``eta_dot`` (casadi columns): its
    position in the floating frame [m] and velocity relative to the frame [m/s] (casadi columns of 3), by
    :func:`ctmm.spatial.beam_ports.deformed_point`."""
    import casadi as ca

    coordinates = traced_array([eta[k] for k in range(eta.numel())])
    rates = traced_array([eta_dot[k] for k in range(eta_dot.numel())])
    position = deformed_point(body, point, coordinates)
    velocity = deformed_point(body, point, rates, rate=True, coordinates=coordinates)
    return ca.vertcat(*map(untraced, position)), ca.vertcat(*map(untraced, velocity))
