"""Cut points on deformable bodies in the generated kinematic-loop step (issue 13 item 1).

A side of a planar cut joint may be a point of a ``ctmm.flexible.ModalBeam`` (its outboard end or a named
outboard station) or an outboard boundary node of a ``ctmm.fem`` subsystem (:mod:`ctmm.planar.cut_points`,
``docs/closed_loops.md`` §4).  The generated RK4 of :mod:`ctmm.compiled_kinematic_loops` states such a side with the
numpy path's own statements: the methods of :class:`ctmm.planar.cut_points.CutPoints` run here on object arrays of
casadi SX scalars (as :func:`ctmm.planar.beam_body_terms.symbolic_beam_terms` runs the beam's numpy terms), so

* the point's position and velocity are :meth:`CutPoints.point` (the frame's inboard motion from
  :class:`ctmm.compiled_planar_sensors.SymbolicKinematics`, the deformed point ``X_e + S_e eta`` in the frame with the
  foreshortening ``-1/2 w^T G1(x_e) w`` of a modal beam when the model has it); its acceleration is the exact time
  derivative of that velocity (``J qddot + (dPhi'/dq) qdot`` in :func:`ctmm.compiled_kinematic_loops.symbolic_closed_loop`);
* its cross-section angle is :meth:`CutPoints.angle` (the frame angle plus ``d_e . eta``);
* a cut force or moment on it is :meth:`CutPoints.add_force` / :meth:`CutPoints.add_moment`: a wrench on the
  body's floating frame ``(f_x, f_y, x_P f_y - y_P f_x)`` (frame axes, moment about the frame's root, the deformed
  point ``(x_P, y_P)``) and the generalised forces ``S_e^T f`` on its internal coordinates (through the
  foreshortening too: ``-f_x G1 w``; a subsystem: the nodal load at that node).

The generalised forces enter the body's element terms as its modal actuator forces; the frame wrench enters them as
an applied wrench at the inboard point: on the protocol (:mod:`ctmm.protocol`, ``[F_in ; 0] = M x + h + ...``) it
is ``h <- h - [R f ; x_P f_y - y_P f_x ; 0]`` (``R`` the frame's rotation), what the numpy sweep does with
:attr:`ctmm.planar.ports.ActuatorInputs.frame_wrench` (:meth:`~ctmm.planar.ports.ActuatorInputs.inboard_wrench`).
The frame's second-order inertia (``ModalBeam(second_order_inertia=True)``) is in the beam's own terms.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .articulated import articulated_sweep
from .compiled_planar_sensors import SymbolicKinematics
from .compiled_parameters import compile_refusal, parameter_vector, symbolic_numbers
from .compiled_scene import coordinate_accelerations
from .compiled_station_loads import symbolic_terms_with_station_loads
from .errors import ModelError
from .ops import CASADI
from .planar.model import PlanarModel
from .planar.ports import PlanarPorts
from .traced_scalar import TracedScalar, traced_array as _objects, untraced as _untraced

__all__ = ["SymbolicCutSides", "TracedScalar", "deformable_bodies", "is_deformable_side",
           "load_sizes",
           "symbolic_accelerations_with_frame_loads"]


def is_deformable_side(side: tuple[int, Any]) -> bool:
    """Whether a side ``(body index or -1, point)`` of :attr:`CutPoints.sides` is a deformable body's point (its
    point an end index, not a body-frame vector or a ground position)."""
    return side[0] >= 0 and not isinstance(side[1], np.ndarray)


def deformable_bodies(model: Any) -> list[int]:
    """The deformable bodies (indices, ascending) that cut points of kinematic loop model ``model`` lie on."""
    return sorted({side[0] for pair in model.cut_points.sides for side in pair if is_deformable_side(side)})


def load_sizes(tree: PlanarModel, bodies: Sequence[int]) -> list[int]:
    """Load inputs per deformable body of :func:`symbolic_accelerations_with_frame_loads`: its frame wrench (3) and
    one generalised force per internal coordinate."""
    return [3 + len(tree.modal_index[j]) for j in bodies]


class SymbolicCutSides:
    """The deformable sides of a kinematic loop model's cut joints on casadi symbols (module docstring).

    Parameters
    ----------
    model : KinematicLoopModel
        Its :attr:`cut_points` (:class:`ctmm.planar.cut_points.CutPoints`) are traced.
    kinematics : SymbolicKinematics
        Of ``model.tree`` on the coordinate and rate symbols ``q, v``.
    """

    def __init__(self, model: Any, kinematics: SymbolicKinematics) -> None:
        tree = model.tree
        self.sides, self.tree = model.cut_points, tree
        n = tree.n_coordinates
        q = _objects([kinematics.q[k] for k in range(n)])
        v = _objects([kinematics.v[k] for k in range(n)])
        bodies = deformable_bodies(model)
        inboard = np.zeros((tree.n_bodies, 2), dtype=object)
        inboard_velocity = np.zeros((tree.n_bodies, 2), dtype=object)
        theta, omega = np.zeros(tree.n_bodies, dtype=object), np.zeros(tree.n_bodies, dtype=object)
        for j in bodies:
            (position, velocity) = kinematics.inboard(j)
            inboard[j, :], inboard_velocity[j, :] = _objects(position), _objects(velocity)
            theta[j], omega[j] = TracedScalar(kinematics.theta[j]), TracedScalar(kinematics.omega[j])
        self.points = {"theta": theta, "omega": omega, "inboard": inboard, "inboard_velocity": inboard_velocity,
                       "q": q, "qdot": v, "t": 0.0}
        self.bodies = bodies
        self.frame: dict[int, Any] = {j: np.zeros(3, dtype=object) for j in bodies}
        self.modal: dict[int, Any] = {j: np.zeros(len(tree.modal_index[j]), dtype=object) for j in bodies}

    def motion(self, side: tuple[int, int]) -> tuple[Any, Any]:
        """Position [m] and velocity [m/s] of a deformable side (casadi columns of 2), global axes."""
        import casadi as ca

        position, velocity, _ = self.sides.point(self.points, *side)
        return ca.vertcat(*map(_untraced, position)), ca.vertcat(*map(_untraced, velocity))

    def angle(self, side: tuple[int, int]) -> tuple[Any, Any]:
        """Cross-section angle [rad] and rate [rad/s] of a deformable side."""
        angle, rate = self.sides.angle(self.points, *side)
        return _untraced(angle), _untraced(rate)

    def add_force(self, side: tuple[int, int], force: Any) -> None:
        """Add the force ``force`` (casadi column of 2, global axes [N]) on a deformable side to the loads."""
        unused = np.zeros((self.tree.n_bodies, 3), dtype=object)
        self.sides.add_force(self.points, *side, _objects([force[0], force[1]]), unused, self.modal, self.frame)

    def add_moment(self, side: tuple[int, int], moment: Any) -> None:
        """Add the moment ``moment`` [N m] on a deformable side to the loads."""
        unused = np.zeros((self.tree.n_bodies, 3), dtype=object)
        self.sides.add_moment(*side, TracedScalar(moment), unused, self.modal, self.frame)

    def loads(self) -> list[Any]:
        """The loads so far as the load inputs of :func:`symbolic_accelerations_with_frame_loads`: per deformable
        body its frame wrench (frame axes, moment about the root) and generalised forces."""
        return [_untraced(value) for j in self.bodies for value in (*self.frame[j], *self.modal[j])]


def symbolic_accelerations_with_frame_loads(tree: PlanarModel, actuators: Sequence[str], bodies: Sequence[int]
                                            ) -> Any:
    """``qddot = acceleration(q, qdot, u, p, t)`` of a compilable planar tree on casadi SX symbols (as
    :func:`ctmm.compiled_scene.symbolic_accelerations_with_inputs`) whose inputs ``u`` are the ports' ``actuators``
    (beam station loads with their frame wrench, :mod:`ctmm.compiled_station_loads`) and then, per deformable body of
    ``bodies`` (:func:`load_sizes`), a wrench on its floating frame ``(f_x, f_y, moment about the root)`` [N, N, N m]
    in frame axes and the generalised forces on its internal coordinates (module docstring)."""
    import casadi as ca

    reason = compile_refusal(tree)
    if reason:
        raise ModelError(f"symbolic accelerations: {reason}")
    bodies = [int(j) for j in bodies]
    if any(j not in tree.beams for j in bodies):
        raise ModelError(f"symbolic accelerations: bodies {bodies} must be deformable bodies of {tree.name!r} "
                         f"(allowed: {sorted(tree.beams)})")
    n, n_p = tree.n_coordinates, parameter_vector(tree).size
    ports = PlanarPorts(tree)
    units = [ports.inputs({name: 1.0}) for name in actuators]
    sizes = load_sizes(tree, bodies)
    q, v, u = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("u", len(units) + sum(sizes))
    p, t = ca.SX.sym("p", n_p), ca.SX.sym("t")
    loads, offset = {}, len(units)
    for j, size in zip(bodies, sizes):
        loads[j] = (u[offset:offset + 3], [u[offset + 3 + i] for i in range(size - 3)])
        offset += size
    scene, terms, joints = symbolic_terms_with_station_loads(tree, units, q, v, u[:len(units)],
                                                             symbolic_numbers(tree, p, t), loads)
    solution = articulated_sweep(CASADI, scene.tree, terms, joints)
    return ca.Function("acceleration", [q, v, u, p, t], [coordinate_accelerations(tree, solution.x, solution.relative)])
