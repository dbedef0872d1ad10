"""Lumped 1-D chain elements: masses, springs, dampers, grounded springs.

Derivation (layout :data:`~ctmm.layouts.AXIAL`, ``z = [x, f]``, ``f`` = force exerted by the
inboard part on the outboard part; full text in ``docs/elements/lumped.md``):

*Point element* (mass ``m``, grounded spring ``k_g`` and damper ``c_g``, external force ``F``):
Newton's law for the point, ``m a = f_in - f_out + F - c_g v - k_g x``, with the kinematics
continuous (``x_out = x_in``) gives

    f_out = f_in - (m s^2 + c_g s + k_g) x + F                       (frequency domain)
    f_out = f_in - (m C + c_g A + k_g cx) x - (m D + c_g B + k_g dx) + F_eval   (DT-TMM)

*Connector* (spring ``k`` with free length ``l`` in parallel with a damper ``c``, massless):
the force transmitted to the outboard point is ``f = -k (x_out - x_in - l) - c (v_out - v_in)``
(a stretched connector pulls the outboard point back), constant along the connector, so

    x_out = x_in - f / (k + c s)                                       (frequency domain)
    x_out = x_in + (k l - k (dx_out - dx_in) - c (B_out - B_in) - f) / (k cx + c A)  (DT-TMM)

Frequency-domain quantities are deviations from the static configuration, so the free
length does not appear there.

*On the element protocol* (issue 12, :mod:`ctmm.protocol` with point dimension ``d = 1``,
:mod:`ctmm.lumped_forms`): a point element is a **body** with ``M = [m]``,
``h = [c_g v + k_g x - F]`` and ``Kin = RF = [1]``, ``c = 0`` at its point ``"out"`` (the same
point as ``"in"``); a connector is a **joint** with ``S = [1]`` and the law
``tau = -k (q_rel - l) - c v_rel + F`` (tangents ``tau_q = -k``, ``tau_v = -c``; an inertance ``b``
as ``tau_a = -b``).  :meth:`PointElement.terms` and :meth:`Connector.terms` state this once.
"""
from __future__ import annotations

from typing import Any, Mapping


from .. import validation
from ..errors import ModelError
from ..ops import Ops
from ..protocol import BodyTerms, JointTerms, Motion
from ..signals import SignalLike, TimeFunction, as_signal, harmonic_amplitude
from .axial import AxialBody, AxialJoint


class PointElement(AxialBody):
    """A point of the 1-D chain with inertia, grounding and an external force.

    Subclasses only set the data ``mass``, ``damping``, ``stiffness`` and ``force``; the physics
    is :meth:`terms`, and every form (``U(s)``, the DT-TMM step, the lumped coefficients) is derived
    from it by :class:`~ctmm.elements.axial.AxialBody`.
    """

    inputs = ("force",)

    def __init__(self, name: str, *, mass: float = 0.0, damping: float = 0.0, stiffness: float = 0.0,
                 force: SignalLike = 0.0) -> None:
        super().__init__(name)
        self.mass = validation.nonnegative(f"{name}: mass", mass)
        self.damping = validation.nonnegative(f"{name}: damping", damping)
        self.stiffness = validation.nonnegative(f"{name}: stiffness", stiffness)
        self.force: TimeFunction = as_signal(f"{name}: force", force)
        self.derive_forms()

    def terms(self, ops: Ops, motion: Motion, eta: Any = None, eta_dot: Any = None, t: float = 0.0,
              u: Mapping[str, Any] | None = None) -> BodyTerms:
        """The point's physics as body terms (``d = 1``, no internal coordinates).

        Parameters
        ----------
        ops : Ops
        motion : Motion
            ``pose = (x,)`` [m], ``twist = (v,)`` [m/s] of the point (ops scalars).
        eta, eta_dot : unused
            A lumped point has no internal coordinates.
        t : float
            Time [s] (unused: the load enters through ``u``).
        u : mapping, optional
            ``{"force": F}`` [N], the external force in +x (0 when absent).

        Returns
        -------
        BodyTerms
            ``M = [m]``, ``h = [c v + k x - F]``, ``Kin["out"] = RF["out"] = [1]``, ``c["out"] = 0``:
            ``f_in = m a + c v + k x - F + f_out``.
        """
        x, v = motion.pose[0], motion.twist[0]
        force = (u or {}).get("force", 0.0)
        one = ops.eye(1)
        h = ops.zeros(1, 1) + v * self.damping + x * self.stiffness - force
        return BodyTerms(M=ops.block([[self.mass]]), h=h, Kin={"out": one}, c={"out": ops.zeros(1, 1)},
                         RF={"out": one})

    def coefficient_key(self) -> tuple | None:
        """:meth:`terms` reads ``mass``, ``damping``, ``stiffness`` (exact bits) and the inputs; None for a subclass
        with its own terms."""
        if type(self).terms is not PointElement.terms:
            return None
        return PointElement.terms, self.inputs, self.mass.hex(), self.damping.hex(), self.stiffness.hex()

    def own_load(self, t: float) -> float:
        """External force [N] of the point at time ``t`` [s]."""
        return float(self.force(t))

    def steady_state_amplitudes(self) -> dict[str, complex]:
        """Phasors of the element's own loads (constant or harmonic signals only)."""
        return {"force": harmonic_amplitude(self.force)}

    def parameters(self) -> dict[str, Any]:
        return {"mass": self.mass, "damping": self.damping, "stiffness": self.stiffness}


class Mass(PointElement):
    """Lumped mass with an optional external force.

    Parameters
    ----------
    name : str
        Element name.
    mass : float
        Mass [kg], > 0.
    force : float or callable, optional
        External force [N] in +x: a constant, :class:`~ctmm.signals.Harmonic` or any ``f(t)``.
    """

    def __init__(self, name: str, mass: float, *, force: SignalLike = 0.0) -> None:
        super().__init__(name, mass=validation.positive(f"{name}: mass", mass), force=force)

    def parameters(self) -> dict[str, Any]:
        return {"mass": self.mass}


class GroundedSpring(PointElement):
    """Spring (and optional damper) from a chain point to ground.

    Parameters
    ----------
    stiffness : float
        Stiffness [N/m], > 0.
    damping : float, optional
        Viscous damping [N s/m], >= 0.
    """

    def __init__(self, name: str, stiffness: float, *, damping: float = 0.0) -> None:
        super().__init__(name, stiffness=validation.positive(f"{name}: stiffness", stiffness),
                         damping=damping)

    def parameters(self) -> dict[str, Any]:
        return {"stiffness": self.stiffness, "damping": self.damping}


class Connector(AxialJoint):
    """Massless spring ``k`` (free length ``l``) in parallel with a viscous damper ``c``.

    Subclasses only choose which of the data are given; ``k + c > 0`` is required.  The input
    ``"force"`` is an actuator acting *across* the connector: ``+F`` on its outboard point and
    ``-F`` on its inboard point (seed 001 Fig. 9.30), so ``f = -k (dx - l) - c dv + F``.  The
    physics is :meth:`terms`; every form is derived from it by :class:`~ctmm.elements.axial.AxialJoint`.
    """

    inputs = ("force",)
    inertance = 0.0          # [kg]; an Inerter sets its own

    def __init__(self, name: str, *, stiffness: float = 0.0, damping: float = 0.0,
                 free_length: float = 0.0) -> None:
        super().__init__(name)
        self.stiffness = validation.nonnegative(f"{name}: stiffness", stiffness)
        self.damping = validation.nonnegative(f"{name}: damping", damping)
        self.free_length = validation.finite(f"{name}: free_length", free_length)
        if self.stiffness == 0.0 and self.damping == 0.0:
            raise ModelError(f"{name}: a connector needs stiffness > 0 or damping > 0, got both 0")
        self.derive_forms()

    def terms(self, ops: Ops, q_rel: Any, v_rel: Any, t: float = 0.0,
              u: Mapping[str, Any] | None = None) -> JointTerms:
        """The connector's physics as joint terms (``d = 1``, one free direction).

        Parameters
        ----------
        ops : Ops
        q_rel, v_rel : ops scalars
            Elongation ``x_out - x_in`` [m] and its rate [m/s].
        t : float
            Time [s] (unused).
        u : mapping, optional
            ``{"force": F}`` [N], the actuator force across the connector (0 when absent).

        Returns
        -------
        JointTerms
            ``S = [1]``, ``tau = -k (q_rel - l) - c v_rel + F`` (force on the outboard point),
            ``tau_q = -k``, ``tau_v = -c`` and, with an inertance ``b``, ``tau_a = -b`` (the law's
            ``-b a_rel``, which the contexts take through ``kappa``).
        """
        force = (u or {}).get("force", 0.0)
        tau = ops.zeros(1, 1) + (q_rel - self.free_length) * (-self.stiffness) - v_rel * self.damping + force
        return JointTerms(S=ops.eye(1), tau=tau, tau_q=ops.block([[-self.stiffness]]),
                          tau_v=ops.block([[-self.damping]]),
                          tau_a=ops.block([[-self.inertance]]) if self.inertance else None)

    def coefficient_key(self) -> tuple | None:
        """:meth:`terms` reads ``stiffness``, ``damping``, ``free_length``, ``inertance`` (exact bits) and the inputs;
        None for a subclass with its own terms."""
        if type(self).terms is not Connector.terms:
            return None
        return (Connector.terms, self.inputs, self.stiffness.hex(), self.damping.hex(), self.free_length.hex(),
                float(self.inertance).hex())

    def parameters(self) -> dict[str, Any]:
        return {"stiffness": self.stiffness, "damping": self.damping, "free_length": self.free_length}


class Spring(Connector):
    """Linear massless spring.

    Parameters
    ----------
    stiffness : float
        Stiffness [N/m], > 0.
    free_length : float, optional
        Free length [m] (used in absolute coordinates in the time domain).
    """

    def __init__(self, name: str, stiffness: float, *, free_length: float = 0.0) -> None:
        super().__init__(name, stiffness=validation.positive(f"{name}: stiffness", stiffness),
                         free_length=free_length)


class Damper(Connector):
    """Massless viscous damper.

    Parameters
    ----------
    damping : float
        Damping coefficient [N s/m], > 0.
    """

    def __init__(self, name: str, damping: float) -> None:
        super().__init__(name, damping=validation.positive(f"{name}: damping", damping))


class SpringDamper(Connector):
    """Spring in parallel with a viscous damper (Kelvin-Voigt connector).

    Parameters
    ----------
    stiffness : float
        Stiffness [N/m], >= 0.
    damping : float
        Damping coefficient [N s/m], >= 0 (not both zero).
    free_length : float, optional
        Free length [m].
    """

    def __init__(self, name: str, stiffness: float, damping: float, *, free_length: float = 0.0) -> None:
        super().__init__(name, stiffness=stiffness, damping=damping, free_length=free_length)
