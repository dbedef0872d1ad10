"""Spherical cut points on deformable spatial bodies in the generated kinematic-loop step (issue 13 item 1).

A spherical cut joint of a :class:`~ctmm.spatial.closed_loops.SpatialKinematicLoopModel` may pin a point of a
``SpatialBeam`` (its tip or a station) or a boundary node of a ``ctmm.fem`` spatial subsystem
(:mod:`ctmm.spatial.cut_points`, ``docs/closed_loops.md`` §8.7).  The generated step of
:mod:`ctmm.compiled_spatial_kinematic_loops` places such a point with the numpy path's own statement:
:func:`ctmm.spatial.cut_points.side_point` runs here on object arrays of
:class:`ctmm.compiled_cut_points.TracedScalar` (casadi scalars), so the point is ``o + R (p + S eta)`` and its
velocity ``v_o + omega x R rho + R S eta'`` exactly as there.  The cut force enters the body's own load path as in
the numpy path (a wrench at the point in the body's terms: the beam's or the subsystem's point load, its virtual
work ``S^T R^T f`` on the internal coordinates and, with geometric stiffening, the tension up to the point).
Revolute and universal cuts at deformable points read the cross-section's axes (:func:`side_frame`), not in the
generated step yet: refused by name (:func:`deformable_cut_refusal`).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .compiled_cut_points import TracedScalar
from .spatial.cut_points import CutSide, resolve_side, side_point

__all__ = ["SymbolicStates", "deformable_cut_refusal", "deformable_sides", "symbolic_deformable_point"]


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


def deformable_cut_refusal(model: Any) -> str:
    """Why a cut joint of ``model`` at a deformable point cannot run in the generated step (an empty string when
    none is refused): only spherical cuts there (module docstring)."""
    refused = [cut.name for cut in model.cuts if cut.name in model.deformable_cuts and cut.kind != "spherical"]
    if refused:
        return (f"cut joints {refused} align the cross-section at a point of a SpatialBeam or ctmm.fem subsystem: the "
                "generated step places deformable points (spherical cuts) but not their section axes yet; use "
                "compiled=None")
    return ""


def _traced(matrix: Any, rows: int, columns: int) -> np.ndarray:
    """A casadi matrix as a batched object array ``(1, rows, columns)`` of traced scalars."""
    out = np.empty((1, rows, columns), dtype=object)
    for r in range(rows):
        for c in range(columns):
            out[0, r, c] = TracedScalar(matrix[r, c])
    return out


def symbolic_deformable_point(state: Any, side: CutSide, q: Any, v: Any, layout: Any) -> tuple[Any, Any]:
    """World position [m] and velocity [m/s] (casadi columns of 3) of the deformable side ``side`` from its body's
    symbolic state ``state`` (:class:`ctmm.spatial.body_forms.BodyState`) and the coordinate and velocity symbols
    ``q, v`` (its internal coordinates at ``layout.position`` and ``layout.velocity``, :attr:`SpatialModel.modal`):
    :func:`ctmm.spatial.cut_points.side_point` traced (module docstring)."""
    import casadi as ca

    n = layout.velocity.stop - layout.velocity.start
    eta = _traced(q[layout.position], n, 1)[:, :, 0]
    eta_dot = _traced(v[layout.velocity], n, 1)[:, :, 0]
    traced = (_traced(state.rotation, 3, 3), *(_traced(x, 3, 1)[:, :, 0] for x in (state.origin, state.velocity,
                                                                                     state.omega, state.inboard)),
              eta, eta_dot)
    position, velocity, _ = side_point({side.body: traced}, side)

    def column(values: np.ndarray) -> Any:
        return ca.vertcat(*(value.value if isinstance(value, TracedScalar) else value for value in values[0]))

    return column(position), column(velocity)
