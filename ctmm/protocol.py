"""The element protocol of the one core (issue 12, ``docs/plans/one_core.md`` §2): bodies and joints.

Every family states its physics once, in :mod:`ctmm.ops` operations, as

* a **body** -- inertia, connection points and internal coordinates -- returning :class:`BodyTerms`,
  the acceleration-linear transfer relations (seed 003 eqs. 6.7/6.8 generalised)::

      [F_in ; 0] = M x + h + sum_e RF[e] F_e        (Newton-Euler about "in" + internal equations)
      A_e        = Kin[e] x + c[e]                  (kinematics of the outboard point e)

  with ``x = [A_in (d) ; eta_ddot (n)]`` and ``F_e`` the wrench this body exerts on what hangs at
  point ``e``;
* a **joint** -- a massless relation between a parent point and a child's inboard point --
  returning :class:`JointTerms`: ``A_child = A_parent + S a_rel + c``, and along the free
  directions the law ``S^T F_child = tau(q_rel, v_rel, t, u)`` (``F_child``: wrench of the parent
  on the child), or a prescribed ``a_rel`` (driven joint: ``S^T F_child`` is then an output).

Point state dimension ``d``: planar ``d = 3`` (``A = [a_x, a_y, alpha]``, ``F = [f_x, f_y, tau]``).
**Spatial bodies (issue 14) fit the same shapes with d = 6**: ``A = [a (3); alpha (3)]``,
``F = [f (3); m (3)]``, ``M`` the 6 x 6 spatial inertia about ``in`` (plus ``n`` modal rows),
``Kin[e] = X(r_e)`` the 6 x 6 rigid transport, ``RF[e] = X(r_e)^T``, ``c[e]`` the centripetal and
gyroscopic terms ``omega x (omega x r)``, a spherical joint ``S = [0; I3]`` (6 x 3), a revolute one
a 6 x 1 column; nothing in :mod:`ctmm.articulated` depends on ``d`` or on the number of free
directions ``k`` (only the ``SO(3)`` update of a ball joint's coordinates differs, and that is the
integrator's business, not the sweep's).

Shapes under :data:`ctmm.ops.NUMPY`: every entry is a batched matrix with leading axis ``B``
(``M (B, d+n, d+n)``, ``h (B, d+n, 1)``, ``Kin[e] (B, d, d+n)``, ``c[e] (B, d, 1)``,
``RF[e] (B, d+n, d)``; ``S (B or 1, d, k)``, ``tau (B, k, 1)``, ``tau_q, tau_v (B, k, k)``);
under :data:`ctmm.ops.CASADI` the same without ``B``.  Constants may use ``B = 1``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Hashable, Mapping, Protocol

import numpy as np

from .ops import Ops

__all__ = ["Motion", "BodyTerms", "JointTerms", "Body", "Joint"]


@dataclass(frozen=True)
class Motion:
    """Pose and twist of a body's inboard point in global axes.

    Planar: ``pose = (x, y, theta)`` [m, m, rad] and ``twist = (v_x, v_y, omega)`` [m/s, rad/s];
    spatial (issue 14): ``pose = (r, R)``, ``twist = (v, omega)``.  Entries are ops scalars.
    """

    pose: tuple
    twist: tuple


@dataclass(frozen=True)
class BodyTerms:
    """Acceleration-linear transfer relations of one body (module docstring).

    Attributes
    ----------
    M : matrix (d + n, d + n)
        Generalised inertia about the inboard point [kg, kg m, kg m^2 and modal units].
    h : column (d + n, 1)
        Velocity, gravity, load, elastic and input terms [N, N m and modal forces].
    Kin : mapping of point name to matrix (d, d + n)
        Kinematics of the outboard points.
    c : mapping of point name to column (d, 1)
        Velocity-product accelerations of the outboard points [m/s^2, rad/s^2].
    RF : mapping of point name to matrix (d + n, d)
        How the wrench exerted at each outboard point enters the equations.
    """

    M: Any
    h: Any
    Kin: Mapping[str, Any] = field(default_factory=dict)
    c: Mapping[str, Any] = field(default_factory=dict)
    RF: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class JointTerms:
    """A joint's kinematics and law (module docstring).

    Attributes
    ----------
    S : matrix (d, k)
        Free directions (``k = 0``: weld; ``S = I``: free base).
    c : column (d, 1) or None
        Velocity-product term of the relative motion (``S_dot v_rel``); ``None`` for zero.
    tau : column (k, 1) or None
        Generalised force along the free directions (law and input) [N, N m]; ``None`` when driven.
    tau_q, tau_v : matrix (k, k) or None
        ``d tau / d q_rel`` and ``d tau / d v_rel`` (``-stiffness``, ``-damping``) -- the law's
        tangents, from which the implicit and frequency contexts form ``kappa``.
    tau_a : matrix (k, k) or None
        ``d tau / d a_rel`` (``-inertance``: a 1-D inerter); ``None`` for zero.  It adds
        ``-tau_a`` to ``kappa`` in every context (``s^2`` times it in the frequency context).
    prescribed : column (k, 1) or None
        Prescribed relative acceleration ``a_rel`` of a driven joint.
    """

    S: Any
    c: Any = None
    tau: Any = None
    tau_q: Any = None
    tau_v: Any = None
    prescribed: Any = None
    tau_a: Any = None

    @property
    def free(self) -> int:
        """Number of free directions ``k``."""
        return int(self.S.shape[-1])


class Body(Protocol):
    """A body family (§2.1): physics in :meth:`terms`, batched over the leading axis."""

    name: str
    points: tuple[str, ...]
    coordinates: tuple[str, ...]
    inputs: tuple[str, ...]
    dimensions: frozenset[int]

    def parameters(self) -> Mapping[str, np.ndarray]:
        """Numeric parameters (stacked per family for batching, symbols for code generation)."""

    def structure(self) -> Hashable:
        """Equal for elements that can share generated code."""

    def terms(self, ops: Ops, motion: Motion, eta: Any, eta_dot: Any, t: float,
              u: Mapping[str, Any]) -> BodyTerms:
        """The physics; inputs ``u`` enter affinely."""


class Joint(Protocol):
    """A joint family (§2.1): a law along the free directions, or a driven motion."""

    name: str
    coordinates: tuple[str, ...]
    inputs: tuple[str, ...]
    dimensions: frozenset[int]

    def parameters(self) -> Mapping[str, np.ndarray]: ...

    def structure(self) -> Hashable: ...

    def terms(self, ops: Ops, q_rel: Any, v_rel: Any, t: float, u: Mapping[str, Any]) -> JointTerms:
        """Free directions and law at relative coordinates ``q_rel`` and rates ``v_rel``."""
