"""Planar cut joints: the revolute joints that close kinematic loops, with their optional moment laws.

A :class:`CutJoint` makes a point of one body (or of the ground) coincide with a point of another body; the
mechanism that solves its force as a boundary unknown is :mod:`ctmm.planar.closed_loops`
(``docs/closed_loops.md``).  The joint may carry a rotary spring / damper law and an actuator torque, acting on
the **relative angle across the cut**

``dtheta = theta_child - theta_parent``  [rad]  (a ground side: 0; a ``ModalBeam`` end: the frame angle plus the
elastic end slope ``phi'(x_e) . q``; a ``ctmm.fem`` subsystem node: the frame angle plus the node's ``r_z``)

and its rate.  The moment on the child side is (the sign convention of the tree's hinges,
:class:`ctmm.planar.NonlinearHinge`, and of :class:`ctmm.planar.ActuatedHinge`)::

    tau = torque(t) - moment_law(dtheta - rest_angle, dtheta_dot)          [N m]

and ``-tau`` acts on the parent side: a pure moment pair, added to the cut's constraint force (which it does not
change: the boundary compliance of the cut points is the same).

A **driven** cut (``angle`` given) prescribes the relative angle instead, ``dtheta = angle(t)``: one more constraint
row of the cut, whose unknown is the drive's moment on the child (the boundary unknowns of
:mod:`ctmm.planar.closed_loops` then hold it with the force); it takes no law or torque.
"""
from __future__ import annotations

from dataclasses import dataclass

from .. import validation
from ..errors import ModelError
from ..nonlinear_laws import Law
from ..signals import SignalLike, TimeFunction, as_signal
from .elements import DrivenHinge

__all__ = ["CutJoint"]


@dataclass(frozen=True)
class CutJoint:
    """Revolute joint closing a loop: point ``child`` coincides with point ``parent`` (module docstring).

    Parameters
    ----------
    name : str
        Joint name.
    parent : str
        ``"body.end"`` (an end of a rigid body, :attr:`RigidBody.outboard`, or of a ``ModalBeam``) or the name of a
        :class:`~ctmm.planar.elements.Fixed` ground point of the tree model.
    child : str
        ``"body.end"``.
    moment_law : ctmm.nonlinear_laws.Law, optional
        Restoring moment ``f(delta, rate)`` [N m] of ``delta = dtheta - rest_angle`` [rad] and ``dtheta_dot``
        [rad/s]: ``LinearLaw(stiffness, damping)`` is a torsional spring parallel to a damper; ``None``
        (default): a smooth joint.
    rest_angle : float
        Relative angle ``dtheta`` [rad] at which the law's deflection is zero.
    torque : float or callable, optional
        Actuator torque ``u(t)`` [N m] on the child side (``-u`` on the parent side); ``None``: none.
    angle, angle_rate, angle_acceleration : float or callable, optional
        A driven cut: the prescribed relative angle ``dtheta = angle(t)`` [rad] and its first [rad/s] and second
        [rad/s^2] time derivatives (checked for consistency by finite differences at a few times, as a
        :class:`~ctmm.planar.elements.DrivenHinge`'s); ``None`` (default): not driven.
    """

    name: str
    parent: str
    child: str
    moment_law: Law | None = None
    rest_angle: float = 0.0
    torque: SignalLike | None = None
    angle: SignalLike | None = None
    angle_rate: SignalLike = 0.0
    angle_acceleration: SignalLike = 0.0

    def __post_init__(self) -> None:
        validation.name("cut joint", self.name)
        for label in ("parent", "child"):
            value = getattr(self, label)
            if not isinstance(value, str) or not value:
                raise ModelError(f"cut joint {self.name!r}: {label} must be 'body.end' or a ground name, got {value!r}")
        if self.moment_law is not None and not isinstance(self.moment_law, Law):
            raise ModelError(f"cut joint {self.name!r}: moment_law must be a ctmm.nonlinear_laws.Law (e.g. "
                             f"LinearLaw(stiffness, damping)) or None, got {self.moment_law!r}")
        object.__setattr__(self, "rest_angle", validation.finite(f"cut joint {self.name!r}: rest_angle",
                                                                 self.rest_angle))
        if self.torque is not None:
            object.__setattr__(self, "torque", as_signal(f"cut joint {self.name!r}: torque", self.torque))
        if self.angle is None:
            return
        if self.has_moment:
            raise ModelError(f"cut joint {self.name!r}: a driven cut (angle given) takes no moment_law or torque (its "
                             f"moment is the drive's), got moment_law={self.moment_law!r}, torque={self.torque!r}")
        try:
            drive = DrivenHinge(self.name, angle=self.angle, rate=self.angle_rate,
                                acceleration=self.angle_acceleration)
        except ModelError as exc:
            raise ModelError(f"cut joint {self.name!r}: angle, angle_rate and angle_acceleration must be a signal of "
                             f"time and its first and second derivatives ({exc})") from None
        for label, value in (("angle", drive.angle), ("angle_rate", drive.rate),
                             ("angle_acceleration", drive.acceleration)):
            object.__setattr__(self, label, value)

    @property
    def driven(self) -> bool:
        """Whether the relative angle is prescribed (:attr:`angle`)."""
        return self.angle is not None

    @property
    def has_moment(self) -> bool:
        """Whether the joint carries a moment law or a torque (else it is smooth)."""
        return self.moment_law is not None or self.torque is not None

    def moment(self, relative_angle: float, relative_rate: float, t: float) -> float:
        """Moment on the child side ``tau = torque(t) - moment_law(dtheta - rest_angle, dtheta_dot)`` [N m] of the
        relative angle [rad], its rate [rad/s] and the time [s]."""
        torque: TimeFunction | None = self.torque       # type: ignore[assignment]
        value = 0.0 if torque is None else float(torque(t))
        if self.moment_law is not None:
            value -= float(self.moment_law.force(relative_angle - self.rest_angle, relative_rate))
        return value

    def potential(self, relative_angle: float) -> float:
        """Energy stored in the moment law at the relative angle [rad] [J] (0 without a law)."""
        if self.moment_law is None:
            return 0.0
        return float(self.moment_law.potential(relative_angle - self.rest_angle))
