"""Points and boundaries of the bending layout (:data:`~ctmm.layouts.BENDING`), in both domains.

State ``z = [w, theta, shear, moment]`` (see :mod:`ctmm.elements.beams` for the convention:
``shear`` and ``moment`` are exerted by the inboard part on the outboard part, in ``+w`` and
``+theta``).  The frequency-domain matrices are written with ``s``; the DT-TMM forms replace
``s^2 w`` by the step's acceleration ``a = C delta + D``, ``s w`` by ``v = A delta + B`` and
``w`` by ``x = cx delta + dx`` (``delta`` = the step's displacement correction, see
:mod:`ctmm.schemes`):

=================  ===========================================  ==============================================
element            frequency domain                             DT-TMM step
=================  ===========================================  ==============================================
BeamPointMass      ``shear_out = shear_in - M s^2 w``             ``shear_out = shear_in - M (C delta_w + D_w)``
                   ``moment_out = moment_in - J s^2 theta``       ``moment_out = moment_in - J (C delta_t + D_t)``
BeamSpring         ``shear_out = shear_in - (k_t + c_t s) w``     ``... - k_t (cx delta + dx) - c_t (A delta + B)``
BeamPointLoad      ``shear_out = shear_in + P``,                  same, with ``P(t), C(t)`` at the step's
                   ``moment_out = moment_in + C`` (phasors)       evaluation level
BeamHinge          ``theta_out = theta_in - moment/(k_h + c_h s)``  no time form yet (massless hinge: the
                                                                   initial accelerations are not defined by it)
=================  ===========================================  ==============================================

Boundaries: :class:`BeamClamped` / :class:`BeamFree` are :class:`~ctmm.elements.boundary.Fixed` /
:class:`~ctmm.elements.boundary.Free` on both pairs; :class:`BeamPinned` (``w = 0, moment = 0``)
and :class:`BeamSliding` (``theta = 0, shear = 0``) are mixed conditions, also in time (the held
displacement's correction is ``-x_pred`` so that it stays at 0).
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from .. import validation
from ..errors import ModelError
from ..layouts import BENDING, StateLayout
from ..signals import SignalLike, TimeFunction, as_signal, harmonic_amplitude
from .base import DiscreteElement, Element, Linearisation
from .boundary import Boundary, Fixed, Free

__all__ = ["laplace_array", "identity_matrices", "BeamPointMass", "BeamSpring", "BeamHinge", "BeamPointLoad",
           "BeamClamped", "BeamFree", "BeamPinned", "BeamSliding"]


def laplace_array(s: Any) -> np.ndarray:
    """``s`` [1/s] as a complex array; :class:`~ctmm.errors.ModelError` unless it is numeric and finite."""
    try:
        array = np.asarray(s, dtype=complex)
    except (TypeError, ValueError):
        raise ModelError(f"s must be a (complex) number or array, got {s!r}") from None
    if not np.all(np.isfinite(array)):
        raise ModelError("s must contain only finite values")
    return array


# ----------------------------------------------------------------------------------------
# point and connector elements
def identity_matrices(s: np.ndarray) -> np.ndarray:
    """Identity transfer matrices, shape ``s.shape + (4, 4)`` (complex), of the bending state."""
    return np.broadcast_to(np.eye(4, dtype=complex), np.shape(s) + (4, 4)).copy()


class BeamPointMass(Element):
    """Point mass ``M`` [kg] with rotary inertia ``J`` [kg m^2] on a beam.

    Newton/Euler for the point (kinematics continuous): ``M s^2 w = shear_in - shear_out``,
    ``J s^2 θ = moment_in - moment_out``, hence ``shear_out = shear_in - M s^2 w`` and
    ``moment_out = moment_in - J s^2 θ`` (FORMULAS §2.3 with ``moment = -M_F``).
    """

    layout = BENDING
    is_point = True

    def __init__(self, name: str, mass: float, rotary_inertia: float = 0.0) -> None:
        super().__init__(name)
        self.mass = validation.nonnegative(f"{name}: mass", mass)
        self.rotary_inertia = validation.nonnegative(f"{name}: rotary_inertia", rotary_inertia)
        if self.mass == 0.0 and self.rotary_inertia == 0.0:
            raise ModelError(f"{name}: mass and rotary_inertia are both 0; give at least one > 0")

    def parameters(self) -> dict[str, Any]:
        return {"mass": self.mass, "rotary_inertia": self.rotary_inertia}

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        U = identity_matrices(s)
        U[..., 2, 0] = -self.mass * s * s
        U[..., 3, 1] = -self.rotary_inertia * s * s
        return U

    def discretize(self, scheme: Any) -> "DiscreteBendingPoint":
        return DiscreteBendingPoint(self, inertia=(self.mass, self.rotary_inertia))


class BeamSpring(Element):
    """Grounded translational and rotational spring (and optional dampers) at a beam station.

    Parameters
    ----------
    translational : float
        Stiffness ``k_t`` [N/m] against deflection, >= 0.
    rotational : float
        Stiffness ``k_r`` [N m/rad] against slope, >= 0.
    translational_damping, rotational_damping : float, optional
        Dampers ``c_t`` [N s/m] and ``c_r`` [N m s/rad] in parallel, >= 0.

    ``shear_out = shear_in - (k_t + c_t s) w``, ``moment_out = moment_in - (k_r + c_r s) θ``.
    """

    layout = BENDING
    is_point = True

    def __init__(self, name: str, translational: float, rotational: float, *,
                 translational_damping: float = 0.0, rotational_damping: float = 0.0) -> None:
        super().__init__(name)
        self.translational = validation.nonnegative(f"{name}: translational", translational)
        self.rotational = validation.nonnegative(f"{name}: rotational", rotational)
        self.translational_damping = validation.nonnegative(f"{name}: translational_damping",
                                                            translational_damping)
        self.rotational_damping = validation.nonnegative(f"{name}: rotational_damping", rotational_damping)
        if not any((self.translational, self.rotational, self.translational_damping,
                    self.rotational_damping)):
            raise ModelError(f"{name}: all spring and damper constants are 0; give at least one > 0")

    @property
    def is_conservative(self) -> bool:
        """False when a damper is present."""
        return not (self.translational_damping or self.rotational_damping)

    def parameters(self) -> dict[str, Any]:
        return {"translational": self.translational, "rotational": self.rotational,
                "translational_damping": self.translational_damping,
                "rotational_damping": self.rotational_damping}

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        U = identity_matrices(s)
        U[..., 2, 0] = -(self.translational + self.translational_damping * s)
        U[..., 3, 1] = -(self.rotational + self.rotational_damping * s)
        return U

    def discretize(self, scheme: Any) -> "DiscreteBendingPoint":
        return DiscreteBendingPoint(self, stiffness=(self.translational, self.rotational),
                                    damping=(self.translational_damping, self.rotational_damping))


class BeamHinge(Element):
    """In-span elastic hinge (rotational spring ``k_h``, optional damper ``c_h``) in a beam.

    ``w``, shear and moment are continuous; the moment transmitted to the outboard side is
    ``moment = -(k_h + c_h s)(θ_out - θ_in)``, so ``θ_out = θ_in - moment / (k_h + c_h s)``
    (FORMULAS §2.3: ``θ_R = θ_L + M/k_h`` with ``M = -moment``).  A field-type element
    (the slope jumps), ``is_point = False``.
    """

    layout = BENDING
    is_point = False

    def __init__(self, name: str, rotational_stiffness: float, *, damping: float = 0.0) -> None:
        super().__init__(name)
        self.rotational_stiffness = validation.positive(f"{name}: rotational_stiffness",
                                                        rotational_stiffness)
        self.damping = validation.nonnegative(f"{name}: damping", damping)

    @property
    def is_conservative(self) -> bool:
        """False when the hinge has a damper."""
        return not self.damping

    def parameters(self) -> dict[str, Any]:
        return {"rotational_stiffness": self.rotational_stiffness, "damping": self.damping}

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        U = identity_matrices(s)
        U[..., 1, 3] = -1.0 / (self.rotational_stiffness + self.damping * s)
        return U


class BeamPointLoad(Element):
    """External point force ``P`` (+w) [N] and moment ``C`` (+θ) [N m] on a beam station.

    Inputs ``("force", "moment")``; equilibrium of the massless station gives
    ``shear_out = shear_in + P`` and ``moment_out = moment_in + C``; the transfer matrix is
    the identity and the loads enter :meth:`load_vector` (frequency domain: phasors of the
    inputs) or the step's affine part (time domain: the signals ``force`` and ``moment``).

    Parameters
    ----------
    name : str
        Element name.
    force : float or callable, optional
        Force ``P(t)`` [N] in ``+w`` for time simulations: a constant, a
        :class:`~ctmm.signals.Harmonic`, a :class:`~ctmm.signals.Step` or any ``f(t)``.
    moment : float or callable, optional
        Moment ``C(t)`` [N m] in ``+theta`` for time simulations.
    """

    layout = BENDING
    is_point = True
    inputs = ("force", "moment")

    def __init__(self, name: str, *, force: SignalLike = 0.0, moment: SignalLike = 0.0) -> None:
        super().__init__(name)
        self.force: TimeFunction = as_signal(f"{name}: force", force)
        self.moment: TimeFunction = as_signal(f"{name}: moment", moment)

    def steady_state_amplitudes(self) -> dict[str, complex]:
        """Phasors of the element's own loads (constant or harmonic signals only)."""
        return {"force": harmonic_amplitude(self.force), "moment": harmonic_amplitude(self.moment)}

    def discretize(self, scheme: Any) -> "DiscreteBendingPoint":
        return DiscreteBendingPoint(self, loads=(self.force, self.moment))

    def transfer_matrix(self, s: Any) -> np.ndarray:
        return identity_matrices(laplace_array(s))

    def load_vector(self, s: Any, amplitudes: Mapping[str, Any]) -> np.ndarray:
        self.check_inputs(amplitudes)
        s = laplace_array(s)
        u = np.zeros(s.shape + (4,), dtype=complex)
        u[..., 2] = amplitudes.get("force", 0.0)
        u[..., 3] = amplitudes.get("moment", 0.0)
        return u


# ----------------------------------------------------------------------------------------
# boundaries of the bending layout
class BeamClamped(Fixed):
    """Clamped beam end: ``w = 0``, ``theta = 0`` (shear and moment unknown)."""

    dimensions: frozenset[int] = frozenset()        # no d = 2 joint terms yet (plan S4C)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.layout = BENDING


class BeamFree(Free):
    """Free beam end: ``shear = 0``, ``moment = 0`` (deflection and slope unknown)."""

    dimensions: frozenset[int] = frozenset()        # no d = 2 joint terms yet (plan S4C)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.layout = BENDING


class _MixedBeamBoundary(Boundary):
    """Beam end where one displacement and the non-conjugate force vanish.

    ``zero_components`` names the two components that are zero (at the start they are the
    known half ``z_f = 0``; at the end they are the conditions ``Bm z = 0``).  Such a boundary
    is neither "all displacements known" nor "all forces known": code that only understands
    those two kinds reads :attr:`known` and gets a :class:`~ctmm.errors.ModelError` instead
    of a silently wrong model.  Code that understands mixed conditions (the Riccati solver,
    the Wittrick-Williams count) uses :meth:`start`, :meth:`end` and :meth:`constrained_dofs`.
    """

    zero_components: tuple[str, str] = ()  # type: ignore[assignment]
    dimensions: frozenset[int] = frozenset()        # no d = 2 joint terms yet (plan S4C)

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.layout = BENDING

    @property  # type: ignore[override]
    def known(self) -> str:
        raise ModelError(
            f"boundary {self.name!r} ({type(self).__name__}) fixes {' and '.join(self.zero_components)}: "
            "a mixed displacement/force condition that this solver does not support yet "
            "(supported: BeamClamped/Fixed, BeamFree/Free, Elastic)")

    def _stiffness(self, s):
        """Support stiffness on the force-prescribed displacement: 0 (the conjugate force vanishes)."""
        return np.zeros(np.shape(s), dtype=complex)

    def constrained_dofs(self, layout: StateLayout) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """(constrained, force-prescribed) displacement indices: pinned ``((w,), (theta,))``,
        sliding ``((theta,), (w,))`` as layout indices."""
        if layout.name != BENDING.name:
            raise ModelError(f"boundary {self.name!r} needs the bending layout, got {layout.name!r}")
        fixed = tuple(layout.index(c) for c in self.constrained_displacements)
        return fixed, tuple(i for i in range(layout.half) if i not in fixed)

    def known_indices(self, layout: StateLayout) -> list[int]:
        """Indices of the components that are zero at this boundary."""
        if layout.name != BENDING.name:
            raise ModelError(f"boundary {self.name!r} needs the bending layout, got {layout.name!r}")
        return [layout.index(c) for c in self.zero_components]

    @property
    def constrained_displacements(self) -> tuple[str, ...]:
        """Displacement components held at zero (the others have zero conjugate force)."""
        return tuple(c for c in self.zero_components if c in BENDING.displacements)

    def unknown_indices(self, layout: StateLayout) -> list[int]:
        known = self.known_indices(layout)
        return [i for i in range(layout.size) if i not in known]

    def start(self, layout: StateLayout, s: Any, amplitudes: Mapping[str, Any]):
        """Start relation: the two zero components, ``z_f = 0`` (``S0 = 0``, ``P0 = 0``)."""
        self.check_inputs(amplitudes)
        s = np.asarray(s, dtype=complex)
        S0 = np.zeros(s.shape + (2, 2), dtype=complex)
        P0 = np.zeros(s.shape + (2,), dtype=complex)
        return self.unknown_indices(layout), S0, P0

    def end(self, layout: StateLayout, s: Any, amplitudes: Mapping[str, Any]):
        """End conditions ``Bm z = 0`` selecting the two zero components."""
        self.check_inputs(amplitudes)
        s = np.asarray(s, dtype=complex)
        Bm = np.zeros(s.shape + (2, layout.size), dtype=complex)
        for row, index in enumerate(self.known_indices(layout)):
            Bm[..., row, index] = 1.0
        return Bm, np.zeros(s.shape + (2,), dtype=complex)

    def _held_corrections(self, layout: StateLayout, lin: Linearisation) -> np.ndarray:
        """Values of the two zero components in the step's unknowns: ``-x_pred`` for a held
        displacement (its correction keeps it at 0), 0 for a force."""
        predictor = np.broadcast_to(np.asarray(lin.xp, dtype=float), (layout.half,))
        return np.array([-predictor[i] if i < layout.half else 0.0 for i in self.known_indices(layout)])

    def start_discrete(self, layout: StateLayout, t: float, lin: Linearisation, *,
                       load_step: tuple[float, float, float] | None = None):
        """Time-domain start relation: the two zero components at the step's unknown time."""
        return self.unknown_indices(layout), np.zeros((2, 2)), self._held_corrections(layout, lin)

    def end_discrete(self, layout: StateLayout, t: float, lin: Linearisation, *,
                     load_step: tuple[float, float, float] | None = None):
        """Time-domain end conditions ``Bm z = b`` selecting the two zero components."""
        Bm = np.zeros((2, layout.size))
        for row, index in enumerate(self.known_indices(layout)):
            Bm[row, index] = 1.0
        return Bm, self._held_corrections(layout, lin)


class BeamPinned(_MixedBeamBoundary):
    """Pinned (simply supported) beam end: ``w = 0``, ``moment = 0``."""

    zero_components = ("w", "moment")


class BeamSliding(_MixedBeamBoundary):
    """Sliding (guided) beam end: ``theta = 0``, ``shear = 0``."""

    zero_components = ("theta", "shear")



class DiscreteBendingPoint(DiscreteElement):
    """DT-TMM form of a bending point element: inertia, grounded spring/damper and loads.

    Parameters
    ----------
    element : Element
        The point element described.
    inertia : (float, float)
        Mass [kg] and rotary inertia [kg m^2].
    stiffness, damping : (float, float)
        Grounded translational / rotational stiffness [N/m, N m/rad] and dampers [N s/m, N m s/rad].
    loads : (signal, signal) or None
        Force [N] and moment [N m] signals of the station.
    """

    def __init__(self, element: Element, *, inertia=(0.0, 0.0), stiffness=(0.0, 0.0), damping=(0.0, 0.0),
                 loads: tuple[TimeFunction, TimeFunction] | None = None) -> None:
        self.element = element
        self.inertia, self.stiffness, self.damping = (np.asarray(v, dtype=float) for v in (inertia, stiffness, damping))
        self.loads = loads

    def load(self, t: float) -> np.ndarray:
        """External force and moment ``[P, C]`` [N, N m] at time ``t`` [s] (zeros without loads)."""
        if self.loads is None:
            return np.zeros(2)
        return np.array([float(self.loads[0](t)), float(self.loads[1](t))])

    def step_matrices(self, t: float, inboard: Linearisation, outboard: Linearisation, force: Any = 0.0):
        """``shear/moment_out = shear/moment_in - (J C + c A + k cx) delta - (J D + c B + k dx) + load``.

        ``force`` [N, or (N, N m)] is the load at the step's evaluation level (a scalar acts on ``shear``).
        """
        lin = inboard
        U = np.eye(4)
        U[[2, 3], [0, 1]] = -(self.inertia * lin.C + self.damping * lin.A + self.stiffness * lin.cx)
        u = np.zeros(4)
        u[2:] = -(self.inertia * lin.D + self.damping * lin.B + self.stiffness * lin.dx)
        u[2:] += np.array([force, 0.0]) if np.ndim(force) == 0 else np.asarray(force, dtype=float)
        return U, u
