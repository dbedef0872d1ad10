"""Cut points on deformable spatial bodies in the generated kinematic-loop step (issue 13 item 1).

A spherical, revolute or universal cut joint of a :class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel`
may join a point of a ``SpatialBeam`` (its tip or a station) or a boundary node of a ``ctmm.fem`` spatial subsystem
(:mod:`ctmm.spatial.cut_points`, ``docs/closed_loops.md`` §8.7).  The generated step of
:mod:`ctmm.compiled_spatial_kinematic_loops` places and turns such a point with the numpy path's own statements:
:func:`ctmm.spatial.cut_points.side_point` and :func:`~ctmm.spatial.cut_points.side_frame` run here on object
arrays of :class:`ctmm.compiled_cut_points.TracedScalar` (casadi scalars), so the point is ``o + R (p + S eta)``,
its velocity ``v_o + omega x R rho + R S eta'``, the cross-section's axes ``R E(L eta)`` and angular velocity
``omega + R Theta L eta'`` exactly as there.  The cut loads enter the body's own load path as in the numpy path (a
wrench at the point in the body's terms: the beam's or the subsystem's point load, its virtual work on the internal
coordinates and, with geometric stiffening, the tension up to the point).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .compiled_cut_points import TracedScalar
from .spatial.cut_points import CutSide, resolve_side, side_frame, side_point

__all__ = ["SymbolicStates", "deformable_sides", "symbolic_deformable_frame", "symbolic_deformable_point"]


class SymbolicStates(list):
    """The body states of :meth:`ctmm.spatial.body_forms.SpatialScene.terms` on symbols with the coordinate and
    velocity symbols ``q``, ``v`` they were computed from (a deformable point reads its body's internal
    coordinates from them)."""

    def __init__(self, states: Any, q: Any, v: Any) -> None:
        super().__init__(states)
        self.q, self.v = q, v


def deformable_sides(model: Any) -> dict[tuple[int, tuple[float, ...]], CutSide]:
    """The deformable sides of ``model``'s cut joints by ``(body index, point in body axes)`` (the sides of
    :func:`ctmm.compiled_spatial_kinematic_loops.symbolic_spatial_closed_loop`)."""
    out = {}
    for cut in model.cuts:
        for body, point in ((cut.parent, cut.point), (cut.child, cut.child_point)):
            side = resolve_side(model.tree, cut, body, point)
            if side.deformable:
                out[(side.body, tuple(float(x) for x in side.point))] = side
    return out


def _traced(matrix: Any, rows: int, columns: int) -> np.ndarray:
    """A casadi matrix as a batched object array ``(1, rows, columns)`` of traced scalars."""
    out = np.empty((1, rows, columns), dtype=object)
    for r in range(rows):
        for c in range(columns):
            out[0, r, c] = TracedScalar(matrix[r, c])
    return out


def _traced_body(state: Any, q: Any, v: Any, layout: Any) -> tuple:
    """A body's symbolic state as the batched tuple the numpy side functions read: ``(R, origin, velocity, omega,
    inboard, eta, eta')`` of traced scalars (``B = 1``)."""
    n = layout.velocity.stop - layout.velocity.start
    return (_traced(state.rotation, 3, 3), *(_traced(x, 3, 1)[:, :, 0] for x in (state.origin, state.velocity,
                                                                                 state.omega, state.inboard)),
            _traced(q[layout.position], n, 1)[:, :, 0], _traced(v[layout.velocity], n, 1)[:, :, 0])


def _untraced(values: np.ndarray) -> Any:
    """A casadi matrix of an object array of traced scalars (numbers as they are), 1-D or 2-D."""
    import casadi as ca

    values = np.atleast_2d(np.asarray(values, dtype=object))
    return ca.vertcat(*(ca.horzcat(*(v.value if isinstance(v, TracedScalar) else v for v in row)) for row in values))


def symbolic_deformable_frame(state: Any, side: CutSide, q: Any, v: Any, layout: Any) -> tuple[Any, Any]:
    """Axes (casadi 3 x 3, section to world) and angular velocity [rad/s] (casadi column of 3) of the cross-section
    at the deformable side ``side`` (arguments of :func:`symbolic_deformable_point`):
    :func:`ctmm.spatial.cut_points.side_frame` traced (module docstring)."""
    axes, omega = side_frame({side.body: _traced_body(state, q, v, layout)}, side)
    return _untraced(axes[0]), _untraced(omega[0]).T


def symbolic_deformable_point(state: Any, side: CutSide, q: Any, v: Any, layout: Any) -> tuple[Any, Any]:
    """World position [m] and velocity [m/s] (casadi columns of 3) of the deformable side ``side`` from its body's
    symbolic state ``state`` (:class:`ctmm.spatial.body_forms.BodyState`) and the coordinate and velocity symbols
    ``q, v`` (its internal coordinates at ``layout.position`` and ``layout.velocity``, :attr:`SpatialModel.modal`):
    :func:`ctmm.spatial.cut_points.side_point` traced (module docstring)."""
    position, velocity, _ = side_point({side.body: _traced_body(state, q, v, layout)}, side)
    return _untraced(position[0]).T, _untraced(velocity[0]).T
