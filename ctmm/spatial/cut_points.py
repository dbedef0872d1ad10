"""The points a spatial cut joint joins: where they are, how they move and how the cut's loads reach them.

A side of a :class:`~ctmm.spatial.closed_loop_cuts.SpatialCutJoint` is one of

* the **ground**: a fixed world location; takes no load;
* a **rigid-body point** (a named point of a :class:`~ctmm.spatial.elements.SpatialBody`): ``o + R p``;
* a **point of a deformable body**: a named point (``"tip"``, a station) of a
  :class:`~ctmm.spatial.beam.SpatialBeam` or a boundary node of a ``ctmm.fem`` spatial subsystem
  (``SpatialFiniteElementModel.subsystem(...)``).  In the body's floating frame it sits at
  ``rho = p + S eta`` (``eta`` the body's internal coordinates; a beam station: ``S = Phi(x_e)``, the mode-shape
  values of both bending planes and the axial shapes, the deformed point of the beam's sensors and ports; a
  subsystem node: ``S`` picks the node's ``u_x, u_y, u_z``), so in the world ``x = o + R rho``,
  ``v = v_o + omega x R rho + R S eta'`` and
  ``a = a_o + alpha x R rho + omega x (omega x R rho) + 2 omega x R rho' + R rho''``; on a ``SpatialBeam`` with
  ``second_order_inertia`` ``rho`` also moves along the axis by the shortening ``-1/2 eta^T G1(x_e) eta`` of the bent
  axis, as the beam's own points, sensors and point loads do.  A force on it is a point load
  at that point, through the body's own load path (``spatial_beam_terms`` / ``subsystem_terms`` ``loads``, the
  path of the point-force actuators): its virtual work ``f . delta x`` gives the frame wrench and the generalised
  force ``S^T R^T f``; on a beam with ``geometric_stiffening`` its beam-axis component ``f_1`` also tensions the
  beam up to the point, ``-f_1 G1(x_e) eta`` (the first-order geometric stiffness of every point load; the loop is
  then energy-exact only to that order, ``docs/closed_loops.md`` §8.7).

The cross-section at a deformable point turns with the body's frame and by the small rotation ``theta = L eta``
(a beam: ``Lambda(x_e)``, ``[twist, -w_z', w_y']``; a subsystem node: its ``r_x, r_y, r_z``): its axes
``R E(theta)``, ``E = Rz(theta_z) Ry(theta_y) Rx(theta_x)``, its angular velocity ``omega + R Theta(theta) theta'``
and acceleration ``alpha + omega x (R Theta theta') + R (Theta theta'' + Theta' theta')`` -- the convention of the
beam's and the node's own point frames and moment loads (a moment ``m`` there does the generalised work
``(Theta L)^T R^T m``), so revolute and universal cuts, whose alignment rows read these axes, join deformable points
too.  Refused by name: prismatic cuts there (their force acts at the moving child point on the parent), and
alignment rows at a subsystem node without rotation DOFs (a particle has no axes).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError, unknown_name
from .closed_loop_cuts import SpatialCutJoint, cross
from .model import SpatialModel

__all__ = ["CutSide", "resolve_side", "side_point", "side_frame", "side_acceleration"]

_AXIS = np.array([1.0, 0.0, 0.0])
"""The beam axis ``e1`` in the beam's frame (the direction of a second-order beam's shortening)."""


@dataclass(frozen=True)
class CutSide:
    """One side of a cut joint (module docstring).

    Attributes
    ----------
    body : int
        Body index in the tree; -1 for the ground.
    point : (3,) array
        Body axes from the body origin (undeformed) [m]; at the ground the world location.
    shape : (3, n) array or None
        Frame displacement of the point per internal coordinate (deformable bodies only) [m].
    modal : slice or None
        Where the body's internal coordinate rates live in ``v`` (and their accelerations in ``v'``).
    turn : (3, n) array or None
        The section's small rotation ``theta`` [rad] per internal coordinate (deformable bodies; ``None`` at a
        subsystem node without rotation DOFs).
    shortening : (n, n) array or None
        ``G1(x_e)`` [1/m] at a point of a ``SpatialBeam`` with ``second_order_inertia``: the point moves along the
        beam axis by the shortening ``u = -1/2 eta^T G1 eta`` [m] of the bent axis, as the beam's own points, sensors
        and point loads do (:func:`ctmm.spatial.beam_ports.deformed_point`, :mod:`ctmm.spatial.beam_terms`);
        ``None`` elsewhere.
    """

    body: int
    point: np.ndarray
    shape: np.ndarray | None = None
    modal: slice | None = None
    turn: np.ndarray | None = None
    shortening: np.ndarray | None = None

    @property
    def deformable(self) -> bool:
        """Whether the point is on a SpatialBeam or a ``ctmm.fem`` subsystem."""
        return self.shape is not None


def resolve_side(tree: SpatialModel, cut: SpatialCutJoint, body: str | None, point: object) -> CutSide:
    """The :class:`CutSide` of ``cut`` on ``body`` (``None``: the ground at the world location ``point``) at its
    named ``point``.

    Raises
    ------
    ModelError
        An unknown body or point; a prismatic cut, or a spherical cut with a law, at a deformable body's point;
        alignment rows at a subsystem node without rotation DOFs.
    """
    if body is None:
        return CutSide(-1, np.asarray(point, float))
    names = [b.name for b in tree.bodies]
    if body not in names:
        raise unknown_name(f"cut joint {cut.name!r}: body", body, names)
    j = names.index(body)
    element = tree.bodies[j]
    points = element.points
    if point not in points:
        raise unknown_name(f"cut joint {cut.name!r}: point of {body}", point, sorted(points))
    location = np.asarray(points[point], float)
    if tree.modal[j] is None:
        return CutSide(j, location)
    if cut.kind == "prismatic":
        raise ModelError(f"cut joint {cut.name!r}: {body!r} is a deformable body (a SpatialBeam or ctmm.fem "
                         "subsystem); a prismatic cut's force acts at the moving child point on the parent, not "
                         "reached there: spherical, revolute and universal cuts join deformable points "
                         "(docs/closed_loops.md §8.7)")
    if cut.kind == "spherical" and cut.has_law:
        raise ModelError(f"cut joint {cut.name!r}: {body!r} is a deformable body (a SpatialBeam or ctmm.fem "
                         "subsystem); a spherical cut's 3-axis law reads the bodies' frames, not the turned section "
                         "at a deformable point: put the law's cut at rigid-body points (docs/closed_loops.md §8.1b)")
    n = tree.modal[j].velocity.stop - tree.modal[j].velocity.start
    shape, turn = np.zeros((3, n)), np.zeros((3, n))
    if hasattr(element, "spatial_terms"):                    # a ctmm.fem spatial subsystem: a boundary node
        data = element.data
        _, trans, rot = data.point_rows[data.node_at_position[tuple(np.round(location, 12))]]
        if trans is not None:
            shape[:, list(trans)] = np.eye(3)
        if rot is None:
            turn = None
            if cut.kind != "spherical":
                raise ModelError(f"cut joint {cut.name!r}: {body}.{point} is a subsystem node without rotation DOFs "
                                 f"(a particle has no axes); a {cut.kind} cut's alignment rows need them: use a "
                                 "spherical cut there")
        else:
            turn[:, list(rot)] = np.eye(3)
    else:                                                    # a SpatialBeam station
        Phi, Lam, G1 = element.data.station(float(location[0]))
        shape[:], turn[:] = Phi, Lam
        if element.data.second_order is not None:
            return CutSide(j, location, shape, tree.modal[j].velocity, turn, np.asarray(G1, float))
    return CutSide(j, location, shape, tree.modal[j].velocity, turn)


def _local(side: CutSide, state: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Frame position ``rho`` and its rate relative to the frame (``(B, 3)``) of a body-side point."""
    if not side.deformable:
        return side.point[None], np.zeros((1, 3))
    eta, eta_dot = state[5], state[6]
    rho, rho_dot = side.point + eta @ side.shape.T, eta_dot @ side.shape.T
    if side.shortening is not None:     # u = -1/2 eta^T G1 eta along the axis, u' = -eta^T G1 eta'
        bent = eta @ side.shortening
        rho = rho - np.multiply.outer((bent * eta).sum(-1) * 0.5, _AXIS)
        rho_dot = rho_dot - np.multiply.outer((bent * eta_dot).sum(-1), _AXIS)
    return rho, rho_dot


def side_point(bodies: list, side: CutSide) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """World position, velocity (``(B, 3)``) and body rotation ``(B, 3, 3)`` of a side (ground: fixed, ``None``);
    ``bodies`` per body ``(R, origin, velocity of the origin, omega, inboard point[, eta, eta'])`` (batched, world;
    the last two on deformable bodies)."""
    if side.body < 0:
        return side.point[None], np.zeros((1, 3)), None
    state = bodies[side.body]
    R, origin, velocity, omega = state[:4]
    rho, rho_dot = _local(side, state)
    arm = (R @ rho[:, :, None])[:, :, 0]
    return origin + arm, velocity + cross(omega, arm) + (R @ rho_dot[:, :, None])[:, :, 0], R


def _section(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``E = Rz Ry Rx`` of ``theta`` ``(B, 3)`` and the columns ``Rz Ry e1``, ``Rz e2`` of ``Theta`` (``(B, 3)``
    each) with ``Theta = [Rz Ry e1, Rz e2, e3]`` ``(B, 3, 3)``."""
    c, s = np.cos(theta), np.sin(theta)
    one, zero = np.ones(len(theta)), np.zeros(len(theta))
    Rx = np.stack([np.stack([one, zero, zero], -1), np.stack([zero, c[:, 0], -s[:, 0]], -1),
                   np.stack([zero, s[:, 0], c[:, 0]], -1)], 1)
    Ry = np.stack([np.stack([c[:, 1], zero, s[:, 1]], -1), np.stack([zero, one, zero], -1),
                   np.stack([-s[:, 1], zero, c[:, 1]], -1)], 1)
    Rz = np.stack([np.stack([c[:, 2], -s[:, 2], zero], -1), np.stack([s[:, 2], c[:, 2], zero], -1),
                   np.stack([zero, zero, one], -1)], 1)
    first = np.stack([c[:, 2] * c[:, 1], s[:, 2] * c[:, 1], -s[:, 1]], -1)
    second = np.stack([-s[:, 2], c[:, 2], zero], -1)
    return Rz @ Ry @ Rx, np.stack([first, second, np.stack([zero, zero, one], -1)], -1), first, second


def side_frame(bodies: list, side: CutSide) -> tuple[np.ndarray | None, np.ndarray]:
    """Axes ``(B, 3, 3)`` (``None`` at the ground) and angular velocity ``(B, 3)`` (world) of a side: its body's,
    or at a deformable point its cross-section's (module docstring)."""
    if side.body < 0:
        return None, np.zeros((1, 3))
    state = bodies[side.body]
    R, omega = state[0], state[3]
    if not side.deformable or side.turn is None:
        return R, omega
    E, Theta, _, _ = _section(state[5] @ side.turn.T)
    return R @ E, omega + (R @ (Theta @ (state[6] @ side.turn.T)[:, :, None]))[:, :, 0]


def side_acceleration(bodies: list, side: CutSide, A: np.ndarray, rates: np.ndarray) -> tuple[np.ndarray, ...]:
    """Position, velocity, acceleration ``(B, 3)`` of a side's point and the angular acceleration of its body
    frame (at a deformable point: of its cross-section, :func:`side_frame`), from the inboard point accelerations
    ``A`` ``(B, n_bodies, 6)`` and ``v'`` ``rates`` ``(B, nv)`` of a batched sweep at one state (``bodies`` of that
    state, :func:`side_point`)."""
    batch = A.shape[0]
    if side.body < 0:
        return side.point, np.zeros(3), np.zeros((batch, 3)), np.zeros((batch, 3))
    state = bodies[side.body]
    R, origin, velocity, omega, inboard = (a[0] for a in state[:5])
    rho, rho_dot = (a[0] for a in _local(side, state))
    arm, moving = R @ rho, R @ rho_dot
    r = origin + arm - inboard
    alpha = A[:, side.body, 3:]
    acceleration = A[:, side.body, :3] + cross(alpha, r) + cross(omega, cross(omega, r))
    if side.deformable:
        relative = rates[:, side.modal] @ side.shape.T
        if side.shortening is not None:         # u'' = -eta^T G1 eta'' - eta'^T G1 eta'
            eta, eta_dot = state[5][0], state[6][0]
            relative = relative - np.multiply.outer(rates[:, side.modal] @ (side.shortening @ eta)
                                                    + eta_dot @ side.shortening @ eta_dot, _AXIS)
        acceleration = acceleration + 2.0 * cross(omega, moving) + relative @ R.T
        if side.turn is not None:                # the section: alpha + omega x R Theta theta' + R (Theta theta'')'
            theta, theta_dot = side.turn @ state[5][0], side.turn @ state[6][0]
            _, Theta, first, second = (a[0] for a in _section(theta[None]))
            e3 = np.array([0.0, 0.0, 1.0])
            spin = (cross(e3 * theta_dot[2], second) * theta_dot[1]
                    + cross(e3 * theta_dot[2] + second * theta_dot[1], first) * theta_dot[0])
            alpha = (alpha + cross(omega, R @ (Theta @ theta_dot))
                     + (rates[:, side.modal] @ side.turn.T @ Theta.T + spin) @ R.T)
    return origin + arm, velocity + cross(omega, arm) + moving, acceleration, alpha
