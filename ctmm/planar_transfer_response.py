"""Frequency responses of planar models by the one sweep's frequency context, batched over omega.

Rigid trees, modal beams and ``ctmm.fem`` subsystems (every body on the element protocol).  About a static
operating point ``q0`` the linearised body terms are ``Z_j(s) = s^2 M0 + s C0 + K0`` and
the joints ``kappa(s) = k + c s`` (:meth:`ctmm.planar.body_forms.PlanarScene.linear_terms`).  One
articulated sweep (:func:`ctmm.articulated.articulated_sweep`) on these terms, numpy-batched over all
``s = i omega`` at once, solves the dynamic-stiffness equations ``Z(s) x = f`` of the whole tree in
``O(N)`` per frequency, where

* the right-hand side ``f`` is one actuator at unit amplitude (one sweep per input column): a hinge
  torque is the amplitude of its joint's ``tau``; a body force or moment, a beam's modal force and a
  station force or moment load the body terms ``h = -[wrench at the inboard point ; modal forces]``
  (:meth:`ctmm.planar.ports.ActuatorInputs.inboard_wrench` at ``q0``);
* the unknowns are the displacement amplitudes ``x = [dx, dy, dtheta ; d eta]`` of every body, mapped to
  the coordinate amplitudes ``q_hat`` (:meth:`~ctmm.planar.body_forms.PlanarScene.coordinate_accelerations`);
* a sensor is the linear functional ``y = (dy/dq + s dy/dqdot) q_hat``
  (:func:`ctmm.planar_linearization.output_matrix`: angles, positions, their rates ``s x``, hinge angles,
  beam stations, coordinates).

The answer holds ``O(outputs x inputs x frequencies)`` numbers; the sweep's batched terms, while it runs,
``O(N x CHUNK)`` (frequencies are swept :data:`CHUNK` at a time).  Rigid trees on hinges, welds and held drives
take the compiled kernel of :mod:`ctmm.compiled_sweep` when a C compiler is present (frequency by frequency in C,
every input column in one sweep, both certificates decided there); the others, and every model without a
compiler, the generic :func:`~ctmm.articulated.articulated_sweep`, one sweep per input column.  The
feedback loops of a ``ControlledModel`` (with and without delay, static or LTI ``C(s)``) are closed at
each frequency by the phasor formula ``(I + K G_yu) u = K (r - G_yw w)``, ``K = diag(C_l(s) e^{-s tau_l})``
(:func:`ctmm.loop_phasors.close_loops`; a loop without delay is ``tau = 0``).

Certified or handed back, never a silent wrong number: at each frequency every pivot the sweep divides by
(joint pivots ``D_j``, modal blocks ``C_j``) is measured against the size of the terms it is made of; a
pivot below :data:`PIVOT_TOLERANCE` of them (``s`` at or next to a pole of the model, or a resonance of a
substructure that the elimination meets as a zero pivot), an answer whose a-posteriori backward error (the
residual of the joint equations and modal rows against the moduli of their terms) exceeds
:data:`~ctmm.sweep_response.RESIDUAL_TOLERANCE` (eliminations whose errors compounded along the tree: moderate
pivots each accepted alone), a non-finite answer, or a loop matrix
``I + K G_yu`` whose smallest singular value is below ``(1 + |K G_yu|_2) / RESOLVENT_CONDITION`` (a closed-loop
pole at or next to ``s``; :data:`~ctmm.controlled_linearization.RESOLVENT_CONDITION`)
marks that frequency as not answered here; :func:`ctmm.planar_frequency.frequency_response` answers
those by the dense resolvent, which answers or refuses them (its rule).

Not stated here (the caller uses the dense linearisation for the whole response): hinges with
translational springs and nonlinear hinges, beams with user state laws (not complex-step safe), a
moving or time-varying operating point, names that are not plain actuator / sensor / loop ports.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .errors import ModelError
from .protocol import JointTerms
from .sweep_response import CHUNK, PIVOT_TOLERANCE, ArticulatedResponse, closed_loop_response

__all__ = ["SweepResponse", "closed_loop_response", "sweep_applies", "PIVOT_TOLERANCE", "CHUNK"]


def sweep_applies(model: Any, point: Any) -> bool:
    """True when the one sweep's frequency context states ``model`` about ``point`` (module docstring):
    revolute (linear laws), driven, welded and free-base joints, rigid bodies and modal beams without user
    state laws, at a static operating point."""
    from .planar.model import BUSHING

    if np.any(point.qdot != 0.0) or not point.equilibrium or model.nonlinear_hinges:
        return False
    if any(int(kind) == BUSHING for kind in model.joint_kind):
        return False
    return not any(beam.data.laws for beam in model.beams.values())


class SweepResponse(ArticulatedResponse):
    """The open-loop response ``G(s)`` of a planar model about a static operating point by the batched sweep.

    Parameters
    ----------
    model : PlanarModel
    point : OperatingPoint
        A static equilibrium (:func:`ctmm.planar_linearization.operating_point`).
    ports : PlanarPorts, optional
        The model's resolved ports (built when omitted).

    Raises
    ------
    ModelError
        The model is not stated by the sweep (:func:`sweep_applies`), or ``point`` is not an equilibrium.
    """

    def __init__(self, model: Any, point: Any, ports: Any = None) -> None:
        from .planar.body_forms import PlanarScene
        from .planar.ports import PlanarPorts

        if not sweep_applies(model, point):
            raise ModelError(f"the one sweep's frequency context does not state {model.name!r} (hinges with "
                             "translational springs, nonlinear hinges, beams with user laws, or a moving point)")
        self.model, self.point = model, point
        self.scene = PlanarScene(model)
        self.terms = self.scene.linear_terms(point.q, point.t)
        self.ports = PlanarPorts(model) if ports is None else ports
        self.rigid = all(body[0].shape[0] == 3 for body in self.terms.bodies)     # no internal coordinates
        self.theta = np.asarray(model.body_angles(point.q, np.zeros(model.n_coordinates), point.t)[0], dtype=float)
        self.prepare(self.terms.tree, self.terms.bodies, self.terms.joints)

    def loads(self, name: str) -> tuple[list, list]:
        """Body load columns ``h`` (1, 3 + n_j, 1) and joint terms of actuator ``name`` at unit amplitude."""
        inputs = self.ports.inputs({name: 1.0})
        wrench = inputs.inboard_wrench(self.model, self.theta)
        if self.rigid:                              # rigid bodies: one array, a view per body
            loads = list(np.negative(wrench).reshape(-1, 1, 3, 1))
        else:
            loads = []
            for j, (M0, _, _, _, _) in enumerate(self.terms.bodies):
                h = np.zeros((1, M0.shape[0], 1))
                h[0, :3, 0] = -wrench[j]
                if j in inputs.modal_force:
                    h[0, 3:, 0] = -np.asarray(inputs.modal_force[j], dtype=float)
                loads.append(h)
        joints = []
        for j, joint in enumerate(self.terms.joints):
            if joint.axis is not None and joint.prescribed is None and inputs.hinge_torque[j] != 0.0:
                joints.append(JointTerms(S=joint.S, tau=np.full((1, 1, 1), float(inputs.hinge_torque[j])),
                                         tau_q=joint.tau_q, tau_v=joint.tau_v, axis=joint.axis))
            else:
                joints.append(joint)
        return loads, joints

    def check(self, inputs: Sequence[str], outputs: Sequence[str]) -> None:
        """Every input an actuator and every output a sensor of the model's ports (else their errors)."""
        for name in inputs:
            self.ports.check_actuator(name)
        for name in outputs:
            self.ports.check_sensor(name)

    def rows(self, outputs: list) -> np.ndarray:
        """``(outputs, 2 n)``: ``[dy/dq, dy/dqdot]`` (:func:`ctmm.planar_linearization.output_matrix`)."""
        from .planar_linearization import output_matrix

        return output_matrix(self.model, outputs, self.point)

    def point_amplitudes(self, answer: Any) -> np.ndarray:
        """Coordinate amplitudes ``q_hat`` (L, B, n) from the compiled kernel's ``A_in`` (n, 3, L, B) (rigid
        bodies: each body's angle amplitude is its ``x[j, 2]``; the kernel takes no free bases)."""
        x = answer.x
        index = np.asarray(self.model.theta_index)
        bodies = np.flatnonzero(index >= 0)
        out = np.zeros(x.shape[2:] + (self.model.n_coordinates,), dtype=x.dtype)
        if bodies.size:
            out[:, :, index[bodies]] = np.moveaxis(x[bodies, 2], 0, -1)
        return out

    def amplitudes(self, solution: Any) -> np.ndarray:
        """Coordinate amplitudes ``q_hat`` (B, n) of a frequency-context sweep."""
        return self.scene.coordinate_accelerations(solution)
