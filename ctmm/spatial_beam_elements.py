"""Rigid bodies, springs, loads and boundaries of spatial beam chains (layout :data:`SPATIAL_BEAM`).

Frequency-domain elements of :class:`ctmm.Chain` structures built from exact
:class:`~ctmm.spatial_beam_fields.SpatialBeamField` pieces, state
``z = [u (3), theta (3), f (3), m (3)]`` in chain axes, ``f, m`` exerted by the inboard part on the
outboard part (:mod:`ctmm.spatial_beam_fields`).  ``skew(r) x = r x x``.

* :class:`SpatialRigidBody` -- mass ``m``, inertia ``I_c`` (3 x 3 about the centre of mass, chain
  axes), centre of mass ``c`` and outboard point ``r`` from the inboard point ``P``.  Kinematics
  ``u_out = u_in - skew(r) theta``, ``theta_out = theta_in``; Newton
  ``m s^2 (u_in - skew(c) theta) = f_in - f_out``; Euler about ``P``
  ``s^2 (I_P theta + m skew(c) u_in) = m_in - m_out - skew(r) f_out`` with
  ``I_P = I_c - m skew(c)^2``.  Zero ``r`` is a point body.
* :class:`SpatialSpring` -- massless 6-DOF spring / damper between coincident points,
  ``F = -(K + s C)(d_out - d_in)`` on the outboard side: ``d_out = d_in - (K + s C)^-1 F``,
  ``F`` continuous (``K + s C`` must be invertible: a free direction has no transfer matrix).
* :class:`SpatialHinge` -- massless revolute hinge about an axis with the law ``k + c s``, rigid
  in the other five directions (``theta_out = theta_in - a a^T m / (k + c s)``).
* :class:`SpatialGroundSpring` -- 6-DOF spring / damper from a point to the ground,
  ``F_out = F_in - (K + s C) d``: elastic supports anywhere, and the **elastic boundary**
  (``SpatialFree`` start or end next to a ``SpatialGroundSpring``).
* :class:`SpatialGeometricStiffness` -- the rotational stiffness of an axial preload on a rigid body,
  ``m_out = m_in - k (I - g g^T) theta`` (``g`` the unit preload direction, ``k`` of either sign):
  constant forces ``F_i g`` at points ``a_i g`` on the body give ``d(r x F) = -(sum a_i F_i)
  (I - g g^T) theta`` (:mod:`ctmm.spatial_exact_fields`, gravity along the chain).
* :class:`SpatialPointLoad` -- inputs ``fx, fy, fz, mx, my, mz`` (force and moment on the point,
  chain axes): ``F_out = F_in + load``.
* Boundaries: :class:`SpatialClamped` (``d = 0``), :class:`SpatialFree` (``F = 0``) and
  :class:`SpatialSupport` (a chosen subset of the six displacements held at zero, the
  conjugate forces of the others zero; :class:`SpatialPinned` holds the three translations: a
  spherical pin).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from . import validation
from .elements.base import Element, Linearisation
from .elements.bending import laplace_array
from .elements.boundary import Boundary, Fixed, Free
from .errors import ModelError
from .layouts import StateLayout
from .spatial_beam_fields import SPATIAL_BEAM

__all__ = ["SpatialRigidBody", "SpatialSpring", "SpatialHinge", "SpatialGroundSpring", "SpatialGeometricStiffness",
           "SpatialPointLoad",
           "SpatialClamped", "SpatialFree", "SpatialSupport", "SpatialPinned", "skew"]


def skew(r: Any) -> np.ndarray:
    """``skew(r) x = r x x`` (3 x 3)."""
    x, y, z = np.asarray(r, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _identity(s: np.ndarray) -> np.ndarray:
    return np.broadcast_to(np.eye(12, dtype=complex), s.shape + (12, 12)).copy()


def _matrix6(name: str, value: Any, *, definite: bool) -> np.ndarray:
    """A symmetric 6 x 6 matrix (6 numbers: its diagonal), positive (semi-)definite."""
    try:
        K = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"{name} must be 6 numbers or a 6 x 6 matrix, got {value!r}") from None
    if K.shape == (6,):
        K = np.diag(K)
    if K.shape != (6, 6) or not np.all(np.isfinite(K)):
        raise ModelError(f"{name} must be 6 finite numbers or a finite 6 x 6 matrix, got shape {K.shape}")
    if np.max(np.abs(K - K.T)) > 1e-12 * max(np.max(np.abs(K)), 1e-300):
        raise ModelError(f"{name} must be symmetric, got {K.tolist()}")
    smallest = np.linalg.eigvalsh(K)[0]
    scale = np.max(np.abs(K))
    if (definite and smallest <= 1e-12 * scale) or smallest < -1e-12 * scale:
        kind = "positive definite (every direction restrained)" if definite else "positive semi-definite"
        raise ModelError(f"{name} must be {kind}, got eigenvalues {np.linalg.eigvalsh(K).tolist()}")
    return K


class SpatialRigidBody(Element):
    """Rigid body in a spatial beam chain (module docstring).

    Parameters
    ----------
    name : str
    mass : float
        ``m`` [kg], >= 0.
    inertia : array_like
        ``I_c`` [kg m^2] about the centre of mass in chain axes: 3 principal moments (chain axes
        principal) or a symmetric positive semi-definite 3 x 3 matrix.
    center_of_mass : array_like (3,), optional
        ``c`` [m] from the inboard point (default 0).
    offset : array_like (3,), optional
        Outboard point ``r`` [m] from the inboard point (default 0: a point body).
    """

    layout = SPATIAL_BEAM
    is_point = False

    def __init__(self, name: str, mass: float, inertia: Any = (0.0, 0.0, 0.0), *,
                 center_of_mass: Any = (0.0, 0.0, 0.0), offset: Any = (0.0, 0.0, 0.0)) -> None:
        super().__init__(name)
        self.mass = validation.nonnegative(f"{name}: mass", mass)
        try:
            J = np.array(inertia, dtype=float)
        except (TypeError, ValueError):
            raise ModelError(f"{name}: inertia must be 3 numbers or a 3 x 3 matrix [kg m^2], got {inertia!r}") from None
        J = np.diag(J) if J.shape == (3,) else J
        if J.shape != (3, 3) or not np.all(np.isfinite(J)) or np.max(np.abs(J - J.T)) > 1e-12 * max(np.abs(J).max(),
                                                                                                    1e-300):
            raise ModelError(f"{name}: inertia must be 3 numbers or a finite symmetric 3 x 3 matrix [kg m^2], "
                             f"got {inertia!r}")
        if np.linalg.eigvalsh(J)[0] < -1e-12 * max(np.abs(J).max(), 1e-300):
            raise ModelError(f"{name}: inertia must be positive semi-definite, got eigenvalues "
                             f"{np.linalg.eigvalsh(J).tolist()} kg m^2")
        self.inertia = J
        self.center_of_mass = validation.vector(f"{name}: center_of_mass", center_of_mass, unit="m")
        self.offset = validation.vector(f"{name}: offset", offset, unit="m")
        if self.mass == 0.0 and not np.any(J) and not np.any(self.offset):
            raise ModelError(f"{name}: mass, inertia and offset are all zero; give a body or leave it out")

    def parameters(self) -> dict[str, Any]:
        return {"mass": self.mass, "inertia": self.inertia.tolist(), "center_of_mass": self.center_of_mass.tolist(),
                "offset": self.offset.tolist()}

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        s2 = (s * s)[..., None, None]
        m, C, Rr = self.mass, skew(self.center_of_mass), skew(self.offset)
        inertia_point = self.inertia - m * C @ C
        U = _identity(s)
        U[..., 0:3, 3:6] = -Rr
        df_du, df_dt = -m * s2 * np.eye(3), m * s2 * C          # f_out = f_in + df_du u + df_dt theta
        U[..., 6:9, 0:3] = df_du
        U[..., 6:9, 3:6] = df_dt
        # m_out = m_in - skew(r) f_out - s^2 (I_P theta + m skew(c) u)
        U[..., 9:12, 0:3] = -Rr @ df_du - m * s2 * C
        U[..., 9:12, 3:6] = -Rr @ df_dt - s2 * inertia_point
        U[..., 9:12, 6:9] = -Rr
        return U


class _SixDirectionSpring(Element):
    """Stiffness ``K`` and damping ``C`` (6 x 6, translations first) of the two spring elements."""

    layout = SPATIAL_BEAM
    definite = False

    def __init__(self, name: str, stiffness: Any, *, damping: Any = None) -> None:
        super().__init__(name)
        self.stiffness = _matrix6(f"{name}: stiffness", stiffness, definite=self.definite)
        self.damping_matrix = (np.zeros((6, 6)) if damping is None
                               else _matrix6(f"{name}: damping", damping, definite=False))
        if not np.any(self.stiffness) and not np.any(self.damping_matrix):
            raise ModelError(f"{name}: stiffness and damping are both zero; give a spring or leave it out")

    @property
    def is_conservative(self) -> bool:
        """False with a damper."""
        return not np.any(self.damping_matrix)

    def parameters(self) -> dict[str, Any]:
        return {"stiffness": self.stiffness.tolist(), "damping": self.damping_matrix.tolist()}

    def impedance(self, s: np.ndarray) -> np.ndarray:
        """``K + s C`` over ``s``, shape ``s.shape + (6, 6)``."""
        return self.stiffness + s[..., None, None] * self.damping_matrix


class SpatialSpring(_SixDirectionSpring):
    """Massless 6-DOF spring and damper between two coincident points (module docstring).

    Parameters
    ----------
    name : str
    stiffness : array_like
        ``K`` [N/m, N m/rad; translations first]: 6 numbers (diagonal) or a symmetric 6 x 6
        matrix, positive definite.
    damping : array_like, optional
        ``C`` [N s/m, N m s/rad], 6 numbers or 6 x 6, positive semi-definite (default 0).
    """

    is_point = False
    definite = True

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        U = _identity(s)
        U[..., 0:6, 6:12] = -np.linalg.inv(self.impedance(s))
        return U


class SpatialHinge(Element):
    """Massless revolute hinge about ``axis`` (chain axes) with the law ``k + c s``, rigid otherwise.

    The moment along the axis transmitted to the outboard side is ``a . m = -(k + c s) phi`` with
    ``phi`` the relative rotation: ``theta_out = theta_in - a a^T m / (k + c s)``; displacements,
    force and moment continuous (the spatial form of :class:`ctmm.elements.bending.BeamHinge`).

    Parameters
    ----------
    name : str
    axis : array_like (3,)
        Hinge axis (normalised here), chain axes.
    stiffness : float
        ``k`` [N m/rad], >= 0.
    damping : float, optional
        ``c`` [N m s/rad], >= 0; ``k + c`` must be > 0 (a free hinge has no transfer matrix).
    """

    layout = SPATIAL_BEAM
    is_point = False

    def __init__(self, name: str, axis: Any, stiffness: float, *, damping: float = 0.0) -> None:
        super().__init__(name)
        self.axis = validation.unit_vector(f"{name}: axis", axis)
        self.stiffness = validation.nonnegative(f"{name}: stiffness", stiffness)
        self.damping = validation.nonnegative(f"{name}: damping", damping)
        if self.stiffness == 0.0 and self.damping == 0.0:
            raise ModelError(f"{name}: stiffness and damping are both 0 (a free hinge inside the chain has no "
                             "transfer matrix); give stiffness > 0 or damping > 0")

    @property
    def is_conservative(self) -> bool:
        """False with a damper."""
        return not self.damping

    def parameters(self) -> dict[str, Any]:
        return {"axis": self.axis.tolist(), "stiffness": self.stiffness, "damping": self.damping}

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        U = _identity(s)
        U[..., 3:6, 9:12] = -np.outer(self.axis, self.axis) / (self.stiffness + self.damping * s)[..., None, None]
        return U


class SpatialGroundSpring(_SixDirectionSpring):
    """6-DOF spring and damper from a point to the ground (module docstring).

    Parameters
    ----------
    name : str
    stiffness : array_like
        ``K`` [N/m, N m/rad], 6 numbers or a symmetric 6 x 6 matrix, positive semi-definite.
    damping : array_like, optional
        ``C`` [N s/m, N m s/rad], positive semi-definite (default 0).
    """

    is_point = True

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        U = _identity(s)
        U[..., 6:12, 0:6] = -self.impedance(s)
        return U


class SpatialGeometricStiffness(Element):
    """Rotational stiffness of an axial preload on a rigid body (module docstring).

    Parameters
    ----------
    name : str
    stiffness : float
        ``k`` [N m/rad], any finite sign (negative: a standing, compressed body).
    direction : array_like (3,)
        Preload direction ``g`` (chain axes; normalised).
    """

    layout = SPATIAL_BEAM
    is_point = True

    def __init__(self, name: str, stiffness: float, direction: Any) -> None:
        super().__init__(name)
        self.stiffness = validation.finite(f"{name}: stiffness", stiffness)
        g = np.asarray(direction, dtype=float)
        if g.shape != (3,) or not np.all(np.isfinite(g)) or not np.linalg.norm(g) > 0:
            raise ModelError(f"{name}: direction must be 3 finite numbers, not all 0, got {direction!r}")
        self.direction = g / np.linalg.norm(g)

    def parameters(self) -> dict[str, Any]:
        return {"stiffness": self.stiffness, "direction": self.direction.tolist()}

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        U = _identity(s)
        g = self.direction
        U[..., 9:12, 3:6] = -self.stiffness * (np.eye(3) - np.outer(g, g))
        return U


class SpatialPointLoad(Element):
    """Harmonic force and moment on a point of a spatial beam chain, chain axes.

    Inputs ``("fx", "fy", "fz", "mx", "my", "mz")`` [N, N m] (phasors); ``F_out = F_in + load``.
    Also a named marker: its signals (``"<name>.uy"``, ``"<name>.fx"``, ...) are the state at
    the point.
    """

    layout = SPATIAL_BEAM
    is_point = True
    inputs = ("fx", "fy", "fz", "mx", "my", "mz")

    def transfer_matrix(self, s: Any) -> np.ndarray:
        return _identity(laplace_array(s))

    def load_vector(self, s: Any, amplitudes: Mapping[str, Any]) -> np.ndarray:
        self.check_inputs(amplitudes)
        s = laplace_array(s)
        u = np.zeros(s.shape + (12,), dtype=complex)
        for k, name in enumerate(self.inputs):
            u[..., 6 + k] = amplitudes.get(name, 0.0)
        return u


class SpatialClamped(Fixed):
    """Clamped end: all six displacements zero."""

    dimensions: frozenset[int] = frozenset()

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.layout = SPATIAL_BEAM


class SpatialFree(Free):
    """Free end: force and moment zero."""

    dimensions: frozenset[int] = frozenset()

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.layout = SPATIAL_BEAM


class SpatialSupport(Boundary):
    """End where the displacements ``held`` are zero and the forces conjugate to the others vanish.

    Parameters
    ----------
    name : str
    held : sequence of str
        Components of ``("ux", "uy", "uz", "theta_x", "theta_y", "theta_z")`` held at zero
        (at least one, not all six: use :class:`SpatialClamped`).
    """

    dimensions: frozenset[int] = frozenset()

    def __init__(self, name: str, held: Sequence[str]) -> None:
        super().__init__(name)
        self.layout = SPATIAL_BEAM
        names = SPATIAL_BEAM.displacements
        if isinstance(held, str) or not all(isinstance(h, str) for h in held) or not set(held) <= set(names):
            raise ModelError(f"{name}: held must be names among {list(names)}, got {held!r}")
        if not 0 < len(set(held)) < 6:
            raise ModelError(f"{name}: held must name 1 to 5 displacements (all six: SpatialClamped, none: "
                             f"SpatialFree), got {held!r}")
        self.held = tuple(c for c in names if c in held)

    def parameters(self) -> dict[str, Any]:
        return {"held": list(self.held)}

    @property  # type: ignore[override]
    def known(self) -> str:
        raise ModelError(f"boundary {self.name!r} ({type(self).__name__}) holds {list(self.held)}: a mixed "
                         "displacement/force condition; only the Riccati solvers of spatial beam chains support it")

    def _check(self, layout: StateLayout) -> None:
        if layout.name != SPATIAL_BEAM.name:
            raise ModelError(f"boundary {self.name!r} needs the spatial beam layout, got {layout.name!r}")

    def known_indices(self, layout: StateLayout) -> list[int]:
        """The six components that are zero: held displacements and the other displacements' forces."""
        self._check(layout)
        return [i if c in self.held else 6 + i for i, c in enumerate(SPATIAL_BEAM.displacements)]

    def unknown_indices(self, layout: StateLayout) -> list[int]:
        known = self.known_indices(layout)
        return [i for i in range(12) if i not in known]

    def constrained_dofs(self, layout: StateLayout) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """(held, force-free) displacement indices."""
        self._check(layout)
        fixed = tuple(SPATIAL_BEAM.index(c) for c in self.held)
        return fixed, tuple(i for i in range(6) if i not in fixed)

    def start(self, layout: StateLayout, s: Any, amplitudes: Mapping[str, Any]):
        """``z_f = 0`` on the six known components (``S0 = 0``, ``P0 = 0``)."""
        self.check_inputs(amplitudes)
        s = np.asarray(s, dtype=complex)
        return (self.unknown_indices(layout), np.zeros(s.shape + (6, 6), dtype=complex),
                np.zeros(s.shape + (6,), dtype=complex))

    def end(self, layout: StateLayout, s: Any, amplitudes: Mapping[str, Any]):
        """``Bm z = 0`` selecting the six known components."""
        self.check_inputs(amplitudes)
        s = np.asarray(s, dtype=complex)
        Bm = np.zeros(s.shape + (6, 12), dtype=complex)
        for row, index in enumerate(self.known_indices(layout)):
            Bm[..., row, index] = 1.0
        return Bm, np.zeros(s.shape + (6,), dtype=complex)

    def start_discrete(self, layout: StateLayout, t: float, lin: Linearisation, *,
                       load_step: tuple[float, float, float] | None = None):
        raise ModelError(f"boundary {self.name!r}: spatial beam chains are frequency-domain structures")

    def end_discrete(self, layout: StateLayout, t: float, lin: Linearisation, *,
                     load_step: tuple[float, float, float] | None = None):
        raise ModelError(f"boundary {self.name!r}: spatial beam chains are frequency-domain structures")


class SpatialPinned(SpatialSupport):
    """Spherical pin: the three translations held, moments zero."""

    def __init__(self, name: str) -> None:
        super().__init__(name, ("ux", "uy", "uz"))
