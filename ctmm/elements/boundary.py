"""Boundary elements: what is known at the start and what is imposed at the end of a chain.

A boundary at the **start** gives the known half of the first state vector in terms of the
unknown half, ``z_f = S0 z_e + P0`` (``e`` = unknown components).  A boundary at the **end**
gives linear conditions ``Bm z_n = b`` on the last state vector.  Both faces exist in the
frequency domain (phasors, deviations from equilibrium) and in the time domain (absolute values
at the step's unknown time).

Sign convention: the force half of ``z`` is the force exerted by the inboard part on the
outboard part.  At the start the inboard part *is* the support; at the end the outboard part is.

=====================  ==================================  ======================================
boundary               start                               end
=====================  ==================================  ======================================
Fixed                  x = position (f unknown)            x = position
Free                   f = 0 (x unknown)                   f = 0
Elastic(k, c)          f = -k (x - anchor) - c v           f = k (x - anchor) + c v
PrescribedDisplacement x = X(t)                            x = X(t)
PrescribedForce        f = F(t)  (F on the chain, +x)      f = -F(t)  (F on the chain, +x)
=====================  ==================================  ======================================

The table is written for one displacement/force pair; for layouts with several pairs
(bending: ``w, theta``) every pair is treated alike.

*On the element protocol* (issue 12, point dimension ``d = 1``, :mod:`ctmm.lumped_forms`) a
boundary is a **joint to ground** (:meth:`Boundary.terms`): ``Fixed`` a weld (no free
direction), ``PrescribedDisplacement`` a prescribed joint, ``Free`` a free joint without law,
``Elastic`` the connector law with free length ``anchor`` (start) or ``-anchor`` (end: the ground
is the child), ``PrescribedForce`` the law ``tau = F`` (start) or ``-F`` (end).  ``q_rel`` is the
child's displacement minus the parent's, the ground at 0.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .. import validation
from ..errors import ModelError
from ..layouts import StateLayout
from ..ops import Ops
from ..protocol import JointTerms
from ..signals import SignalLike, TimeFunction, as_signal, harmonic_amplitude
from .base import Element, Linearisation


class Boundary(Element):
    """Base class of boundary elements (first or last element of a chain)."""

    is_point = True
    known: str = "displacement"  # which half is known: "displacement" or "force"

    def __init__(self, name: str) -> None:
        super().__init__(name)
        # any layout (None) unless a subclass fixes one: the chain passes its layout to the
        # boundary methods (start, end, ...) as an argument and never writes it here
        self.layout: StateLayout | None = None

    def transfer_matrix(self, s: np.ndarray) -> np.ndarray:
        raise ModelError(f"boundary {self.name!r} has no transfer matrix")

    # -- element protocol (d = 1) ---------------------------------------------------------
    dimensions = frozenset({1})

    def terms(self, ops: Ops, q_rel: Any = 0.0, v_rel: Any = 0.0, t: float = 0.0,
              u: Mapping[str, Any] | None = None, *, side: str = "start") -> JointTerms:
        """The boundary as a joint to ground (module docstring).

        Parameters
        ----------
        ops : Ops
        q_rel, v_rel : ops scalars
            Child displacement minus parent displacement [m] and its rate [m/s] (ground at 0).
        t : float
            Time [s].
        u : mapping, optional
            The boundary's input (``"force"`` [N] or ``"displacement"``: the prescribed motion at
            the level of the context's unknowns -- acceleration [m/s^2] in time, displacement phasor
            [m] in the frequency context).
        side : {"start", "end"}
            ``"start"``: the ground is the parent; ``"end"``: the ground is the child.
        """
        if side not in ("start", "end"):
            raise ModelError(f"{self.name}: side must be 'start' or 'end', got {side!r}")
        return self._joint_terms(ops, q_rel, v_rel, t, u or {}, side)

    def _joint_terms(self, ops: Ops, q_rel: Any, v_rel: Any, t: float, u: Mapping[str, Any],
                     side: str) -> JointTerms:
        raise ModelError(f"boundary {self.name!r} ({type(self).__name__}) has no joint terms")

    # -- helpers ------------------------------------------------------------------------
    def _stiffness(self, s: np.ndarray) -> np.ndarray:
        return np.zeros(np.shape(s), dtype=complex)

    def _value_phasor(self, amplitudes: Mapping[str, Any]) -> Any:
        key = self.inputs[0] if self.inputs else None
        return amplitudes.get(key, 0.0) if key else 0.0

    def unknown_indices(self, layout: StateLayout) -> list[int]:
        """Indices of the components unknown at a start boundary."""
        d = layout.half
        return list(range(d, 2 * d)) if self.known == "displacement" else list(range(d))

    def constrained_dofs(self, layout: StateLayout) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """Split the displacement components ``0 .. d-1`` into (constrained, force-prescribed).

        A constrained displacement is held at a prescribed value (its conjugate force is an
        unknown reaction); for every other displacement component the conjugate force is
        prescribed: zero, an input, or elastic with the support stiffness of ``_stiffness(s)``.
        Uniform boundaries constrain all (``known == "displacement"``) or none; mixed boundaries
        (e.g. :class:`~ctmm.elements.beams.BeamPinned`) override this.
        """
        d = layout.half
        if self.known == "displacement":
            return tuple(range(d)), ()
        return (), tuple(range(d))

    # -- frequency domain ---------------------------------------------------------------
    def start(self, layout: StateLayout, s: np.ndarray, amplitudes: Mapping[str, Any]):
        """Start relation ``z_f = S0 z_e + P0``: returns ``(e_indices, S0, P0)`` over ``s``."""
        self.check_inputs(amplitudes)
        s = np.asarray(s, dtype=complex)
        d = layout.half
        S0 = np.zeros(s.shape + (d, d), dtype=complex)
        P0 = np.zeros(s.shape + (d,), dtype=complex)
        k = self._stiffness(s)
        for i in range(d):
            S0[..., i, i] = -k if self.known == "force" else 0.0
            P0[..., i] = self._start_value(amplitudes)
        return self.unknown_indices(layout), S0, P0

    def _start_value(self, amplitudes):
        return self._value_phasor(amplitudes)

    def end(self, layout: StateLayout, s: np.ndarray, amplitudes: Mapping[str, Any]):
        """End condition ``Bm z_n = b``: returns ``(Bm, b)`` over ``s``."""
        self.check_inputs(amplitudes)
        s = np.asarray(s, dtype=complex)
        d, n = layout.half, layout.size
        Bm = np.zeros(s.shape + (d, n), dtype=complex)
        b = np.zeros(s.shape + (d,), dtype=complex)
        k = self._stiffness(s)
        for i in range(d):
            if self.known == "displacement":
                Bm[..., i, i] = 1.0
                b[..., i] = self._value_phasor(amplitudes)
            else:
                Bm[..., i, d + i] = 1.0
                Bm[..., i, i] = -k
                b[..., i] = self._end_force_value(amplitudes)
        return Bm, b

    def _end_force_value(self, amplitudes):
        return self._value_phasor(amplitudes)

    # -- time domain --------------------------------------------------------------------
    def start_discrete(self, layout: StateLayout, t: float, lin: Linearisation, *,
                       load_step: tuple[float, float, float] | None = None):
        """Time-domain start relation at the unknown's time ``t`` [s] (see :meth:`start`).

        ``load_step = (t_n [s], h [s], w)`` weights a prescribed force as the scheme weights its loads,
        ``(1 - w) F(t_n) + w F(t_n + h)`` (the balance's time for generalized-alpha, Wilson-theta's linear
        extrapolation), as the elements' loads are; ``None`` evaluates it at ``t``.  Prescribed
        displacements are always taken at ``t``, the unknown's time.
        """
        d = layout.half
        k_eff, offset = self._discrete_spring(lin)
        S0 = np.zeros((d, d))
        P0 = np.zeros(d)
        for i in range(d):
            if self.known == "force":
                S0[i, i] = -k_eff
                P0[i] = self._weighted_force(t, load_step) - offset
            else:  # the unknown is the correction to the predictor xp
                P0[i] = self._position_signal(t) - float(np.ravel(lin.xp)[i] if np.ndim(lin.xp) else lin.xp)
        return self.unknown_indices(layout), S0, P0

    def end_discrete(self, layout: StateLayout, t: float, lin: Linearisation, *,
                     load_step: tuple[float, float, float] | None = None):
        """Time-domain end condition ``Bm z_n = b`` at the unknown's time ``t`` [s] (``load_step`` as in
        :meth:`start_discrete`)."""
        d, n = layout.half, layout.size
        k_eff, offset = self._discrete_spring(lin)
        Bm = np.zeros((d, n))
        b = np.zeros(d)
        for i in range(d):
            if self.known == "displacement":
                Bm[i, i] = 1.0
                b[i] = self._position_signal(t) - float(np.ravel(lin.xp)[i] if np.ndim(lin.xp) else lin.xp)
            else:
                Bm[i, d + i] = 1.0
                Bm[i, i] = -k_eff
                b[i] = offset - self._weighted_force(t, load_step)
        return Bm, b

    def _weighted_force(self, t: float, load_step: tuple[float, float, float] | None) -> float:
        if load_step is None:
            return self._force_signal(t)
        t_n, h, w = load_step
        after = self._force_signal(t_n + h)
        return after if w == 1.0 else (1.0 - w) * self._force_signal(t_n) + w * after

    def _discrete_spring(self, lin: Linearisation) -> tuple[float, float]:
        return 0.0, 0.0

    def _position_signal(self, t: float) -> float:
        return 0.0

    def _force_signal(self, t: float) -> float:
        return 0.0


class Fixed(Boundary):
    """Rigid support: displacement held at ``position`` [m] (0 in the frequency domain)."""

    known = "displacement"

    def __init__(self, name: str, *, position: float = 0.0) -> None:
        super().__init__(name)
        self.position = validation.finite(f"{name}: position", position)

    def _position_signal(self, t):
        return self.position

    def _joint_terms(self, ops, q_rel, v_rel, t, u, side):
        return JointTerms(S=ops.zeros(1, 0))                 # weld

    def parameters(self):
        return {"position": self.position}


class Free(Boundary):
    """Free end: no force."""

    known = "force"

    def _joint_terms(self, ops, q_rel, v_rel, t, u, side):
        zero = ops.zeros(1, 1)
        return JointTerms(S=ops.eye(1), tau=zero, tau_q=zero, tau_v=zero)


class Elastic(Boundary):
    """Spring (and damper) support to ground, anchored at ``anchor`` [m].

    Parameters
    ----------
    stiffness : float
        Support stiffness [N/m], >= 0.
    damping : float, optional
        Support damping [N s/m], >= 0 (not both zero).
    anchor : float, optional
        Position [m] of the support's unstretched end in absolute time-domain coordinates.
    """

    known = "force"

    def __init__(self, name: str, stiffness: float, *, damping: float = 0.0, anchor: float = 0.0) -> None:
        super().__init__(name)
        self.stiffness = validation.nonnegative(f"{name}: stiffness", stiffness)
        self.damping = validation.nonnegative(f"{name}: damping", damping)
        self.anchor = validation.finite(f"{name}: anchor", anchor)
        if self.stiffness == 0.0 and self.damping == 0.0:
            raise ModelError(f"{name}: elastic support needs stiffness > 0 or damping > 0; use Free")

    def _stiffness(self, s):
        return self.stiffness + self.damping * np.asarray(s, dtype=complex)

    def _discrete_spring(self, lin):
        # support force on the chain: -k (x_eval - anchor) - c v_eval with x_eval = cx x + dx, v_eval = A x + B
        k_eff = self.stiffness * lin.cx + self.damping * lin.A
        offset = self.stiffness * (lin.dx - self.anchor) + self.damping * lin.B
        return k_eff, float(np.squeeze(offset))

    def _end_force_value(self, amplitudes):
        return 0.0

    def _joint_terms(self, ops, q_rel, v_rel, t, u, side):
        length = self.anchor if side == "start" else -self.anchor
        tau = ops.zeros(1, 1) + (q_rel - length) * (-self.stiffness) - v_rel * self.damping
        return JointTerms(S=ops.eye(1), tau=tau, tau_q=ops.block([[-self.stiffness]]),
                          tau_v=ops.block([[-self.damping]]))

    def parameters(self):
        return {"stiffness": self.stiffness, "damping": self.damping, "anchor": self.anchor}


class PrescribedDisplacement(Boundary):
    """Support with a prescribed displacement ``X(t)`` [m] (input ``"displacement"`` for FRFs)."""

    known = "displacement"
    inputs = ("displacement",)

    def __init__(self, name: str, displacement: SignalLike = 0.0) -> None:
        super().__init__(name)
        self.displacement: TimeFunction = as_signal(f"{name}: displacement", displacement)

    def _position_signal(self, t):
        return float(self.displacement(t))

    def _joint_terms(self, ops, q_rel, v_rel, t, u, side):
        return JointTerms(S=ops.eye(1), prescribed=ops.zeros(1, 1) + u.get("displacement", 0.0))

    def steady_state_amplitudes(self):
        return {"displacement": harmonic_amplitude(self.displacement)}


class PrescribedForce(Boundary):
    """Chain end loaded by a force ``F(t)`` [N] acting on the chain in +x (input ``"force"``)."""

    known = "force"
    inputs = ("force",)

    def __init__(self, name: str, force: SignalLike = 0.0) -> None:
        super().__init__(name)
        self.force: TimeFunction = as_signal(f"{name}: force", force)

    def _force_signal(self, t):
        return float(self.force(t))

    def _joint_terms(self, ops, q_rel, v_rel, t, u, side):
        zero = ops.zeros(1, 1)
        force = u.get("force", 0.0)
        return JointTerms(S=ops.eye(1), tau=zero + (force if side == "start" else -force), tau_q=zero, tau_v=zero)

    def _end_force_value(self, amplitudes):
        return -self._value_phasor(amplitudes)

    def steady_state_amplitudes(self):
        return {"force": harmonic_amplitude(self.force)}
