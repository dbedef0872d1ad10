"""The element contract: one description, two solution domains.

Every element maps the state at its inboard connection point to the state at its outboard
connection point, ``z_out = U z_in + u``.

* **Frequency domain** (linear MSTMM): :meth:`Element.transfer_matrix` returns ``U(s)`` for an
  array of Laplace variables ``s`` (``s = i*omega`` for steady state), shape ``s.shape + (n, n)``;
  :meth:`Element.load_vector` returns the affine part ``u(s)`` produced by harmonic input
  amplitudes (phasors), shape ``s.shape + (n,)``.
* **Time domain** (DT-TMM): :meth:`Element.discretize` returns a :class:`DiscreteElement`
  that builds real ``(U, u)`` every step from the integrator's linearisation
  ``v = A x + B``, ``a = C x + D`` evaluated at the element's connection points.

Elements are immutable descriptions; any history or state lives in the stepper's arrays.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..errors import ModelError, unknown_name
from ..layouts import StateLayout
from .. import validation


@dataclass(frozen=True)
class LumpedCoefficients:
    """The 1-D lumped form of an element: its mass, damping and stiffness coefficients.

    A 1-D lumped element is either a *point* (its two connection points coincide; the
    coefficients act between the point and ground: force ``-(m a + c v + k x)`` on the point) or
    a *connector* (massless in the usual sense; the coefficients act on the relative motion of
    its outboard and inboard points: force ``f = -m (a_out - a_in) - c (v_out - v_in) -
    k (x_out - x_in - l)`` on the outboard point, for a connector ``m`` is an inertance).  The
    frequency-domain dynamic stiffness is ``m s^2 + c s + k`` in both cases.  Framework code that
    assembles global ``M, C, K`` matrices, vectorised time steps or Sturm counts reads these
    numbers instead of asking for element classes (``docs/adding_an_element.md``).

    Attributes
    ----------
    connector : bool
        True for a connector (two distinct points), False for a point element.
    mass : float
        Mass [kg] of a point, or inertance [kg] of a connector, >= 0.
    damping : float
        Viscous damping [N s/m], >= 0.
    stiffness : float
        Stiffness [N/m], >= 0.
    free_length : float
        Free length [m] of a connector (0 for a point).
    """

    connector: bool
    mass: float = 0.0
    damping: float = 0.0
    stiffness: float = 0.0
    free_length: float = 0.0

    def dynamic_stiffness(self, s: np.ndarray) -> np.ndarray:
        """``m s^2 + c s + k`` [N/m] for Laplace variables ``s`` [1/s]."""
        s = np.asarray(s, dtype=complex)
        return self.mass * s * s + self.damping * s + self.stiffness


class Element(ABC):
    """Base class of all transfer-matrix elements.

    Attributes
    ----------
    name : str
        Unique name in the system; signals are addressed as ``"name.quantity"``.
    layout : StateLayout
        State vector layout at both ends.
    inputs : tuple of str
        Names of the element's input signals (e.g. ``("force",)`` for a mass), addressed
        as ``"name.force"`` in frequency responses and simulations.
    is_point : bool
        True when the element sits at one point (kinematics pass through unchanged, e.g. a
        lumped mass); False for field elements that connect two different points (springs).
    """

    layout: StateLayout
    inputs: tuple[str, ...] = ()
    is_point: bool = False

    def __init__(self, name: str) -> None:
        self.name = validation.name("element", name)

    # -- frequency domain ---------------------------------------------------------------
    @abstractmethod
    def transfer_matrix(self, s: np.ndarray) -> np.ndarray:
        """Transfer matrix ``U(s)``, shape ``np.shape(s) + (n, n)``, complex."""

    def load_vector(self, s: np.ndarray, amplitudes: Mapping[str, Any]) -> np.ndarray:
        """Affine part ``u(s)`` for input phasors ``amplitudes`` (keys from :attr:`inputs`).

        The default element has no inputs and returns zeros.
        """
        self.check_inputs(amplitudes)
        s = np.asarray(s)
        return np.zeros(s.shape + (self.layout.size,), dtype=complex)

    def subdivide(self, omega_max: float) -> list["Element"]:
        """Pieces whose chained transfer matrices equal this element's, for use up to ``omega_max``.

        Optional capability used by :func:`ctmm.frequency.assemble` (``subdivide=True``),
        :func:`~ctmm.frequency.eigenvalue_count`, :func:`~ctmm.frequency.natural_frequencies` and
        :func:`~ctmm.frequency.mode_shapes`: a distributed element whose matrix grows
        exponentially with frequency (e.g. :class:`~ctmm.elements.beams.BeamField`, entries
        ``~ cosh(beta L)``) returns pieces short enough that every solver step stays well
        conditioned up to ``omega_max`` [rad/s].  The product of the pieces' matrices (last
        piece leftmost) must equal this element's matrix; the pieces take no inputs.  The
        default returns ``[self]``.
        """
        return [self]

    def check_inputs(self, amplitudes: Mapping[str, Any]) -> None:
        """Raise :class:`~ctmm.errors.UnknownNameError` for input names the element lacks."""
        for key in amplitudes:
            if key not in self.inputs:
                raise unknown_name(f"input of element {self.name!r}",
                                   key, self.inputs)

    # -- time domain --------------------------------------------------------------------
    def discretize(self, scheme: Any) -> "DiscreteElement":
        """Return the discrete-time form of the element for ``scheme`` (DT-TMM)."""
        raise ModelError(f"element {self.name!r} ({type(self).__name__}) has no discrete-time form")

    def lumped_coefficients(self) -> LumpedCoefficients | None:
        """The element's 1-D lumped form, or None when it is not a 1-D lumped element.

        Optional capability: elements that return coefficients get the lumped fast paths (scalar
        Riccati solves, vectorised time steps, Sturm counts, state-space export); the others are
        solved through :meth:`transfer_matrix` and :meth:`discretize` alone.
        """
        return None

    def parameters(self) -> dict[str, Any]:
        """Physical parameters by name (used by reports and independent reference models)."""
        return {}

    def __repr__(self) -> str:
        params = ", ".join(f"{k}={v!r}" for k, v in self.parameters().items())
        return f"{type(self).__name__}({self.name!r}{', ' if params else ''}{params})"


class DiscreteElement(ABC):
    """Discrete-time face of an element: real ``(U, u)`` for each time step.

    The stepper supplies, for the element's inboard and outboard connection points, the
    integrator's affine relations of the *evaluation-level* kinematics to the unknown
    displacement ``x`` of the step: ``x_eval = cx x + dx``, ``v_eval = A x + B``,
    ``a_eval = C x + D`` (arrays over the layout's displacement components), and the
    evaluation time ``t``.
    """

    element: Element

    @abstractmethod
    def step_matrices(self, t: float, inboard: "Linearisation", outboard: "Linearisation"
                      ) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(U, u)`` of the step: ``U`` shape ``(n, n)``, ``u`` shape ``(n,)``."""

    def load(self, t: float) -> Any:
        """The element's own external load at time ``t`` [s] (0 by default).

        The stepper weights it to the step's evaluation level,
        ``(1 - w) load(t_n) + w load(t_n + h)`` (:class:`~ctmm.schemes.StepCoefficients`), adds the
        loads of force hooks and passes the sum to :meth:`step_matrices` as ``force``.
        """
        return 0.0


class Linearisation:
    """Affine relations of evaluation-level kinematics to the unknown displacement of a step.

    Attributes are floats or arrays over the displacement components:
    ``cx, dx`` (displacement level), ``A, B`` (velocity), ``C, D`` (acceleration), all in terms of
    the step's unknown ``delta``, and ``xp``, the predictor: the displacement at the unknown's
    time is ``xp + delta`` (see :mod:`ctmm.schemes`).
    """

    __slots__ = ("cx", "dx", "A", "B", "C", "D", "xp")

    def __init__(self, cx, dx, A, B, C, D, xp=0.0) -> None:  # noqa: N803 - book notation
        self.cx, self.dx, self.A, self.B, self.C, self.D, self.xp = cx, dx, A, B, C, D, xp

    @classmethod
    def ground(cls, cx: float, A: float, C: float) -> "Linearisation":
        """Linearisation of a point that does not move (all offsets zero)."""
        return cls(cx, 0.0, A, 0.0, C, 0.0)
