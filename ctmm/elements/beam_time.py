"""Time form of the beam field: cubic Hermite finite elements in the chain DT-TMM.

A :class:`~ctmm.elements.beams.BeamField` states its physics once (``EI``, ``rho A``, length,
axial force, Kelvin-Voigt and viscous damping).  In the frequency domain its transfer matrix is
exact; in time the span is meshed into ``N`` equal cubic Hermite elements
(:class:`BeamSegment`, consistent mass), whose interior nodes become connection points of the
chain that the DT-TMM stepper integrates (:class:`BendingMesh`).  Derivation in
``docs/beams.md`` ("time domain"); summary:

*Element* (length ``h``, DOFs ``d = [w1, theta1, w2, theta2]``, end loads ``F`` acting on the
element, conjugate to ``d``)::

    F = K d + C_d d' + M d'',   K = EI/h^3 [[12, 6h, -12, 6h], [6h, 4h^2, -6h, 2h^2], ...] + K_T,
    M = rho A h/420 [[156, 22h, 54, -13h], ...],   C_d = tau K_EI + (c_v / rho A) M

(``K_T`` the geometric stiffness of a constant tension ``T``, ``tau`` the Kelvin-Voigt time,
``c_v`` the external viscous damping per length).  With the inboard state ``[w, theta | shear,
moment]`` exerted *on* the element and the outboard state exerted *by* it, ``F_L = f_in``,
``F_R = -f_out``.

*DT-TMM step*: the scheme gives ``x = cx delta + dx``, ``v = A delta + B``, ``a = C delta + D``
at both ends, so ``F = K_e delta + g`` with ``K_e = cx K + A C_d + C M`` and
``g = K dx + C_d B + M D``.  Solving the first block row for ``delta_R`` gives the transfer
relation (``X = K_e,LR^-1``)::

    [delta_R]   [ -X K_LL              X      ] [delta_L]   [ -X g_L            ]
    [f_out  ] = [ K_RR X K_LL - K_RL   -K_RR X ] [f_in   ] + [ K_RR X g_L - g_R  ]

``K_e,LR`` is never singular for ``cx, A, C >= 0`` without compression (its determinant is
``h^2 (12 a^2 + 300 a b + 7 b^2)`` with ``a = cx EI/h^3``, ``b = C rho A h/420``).  The same
formula with ``K + s C_d + s^2 M`` is the element's frequency-domain matrix
(:meth:`BeamSegment.transfer_matrix`): the steady state the time model converges to.

*Mesh rule* (:func:`time_element_count`): the consistent-mass Hermite element overestimates a
natural frequency by about ``(lambda h)^4 / 1440`` (``lambda = (rho A omega^2/EI)^(1/4)``), and a
second-order step by about ``(omega dt)^2 / 12`` (average-acceleration Newmark).  At the relative
tolerance ``FREQUENCY_TOLERANCE = 1e-3`` the step resolves the band ``omega <= sqrt(12 tol)/dt``;
the default mesh resolves the same band (``lambda h <= (1440 tol)^(1/4)``), with at least two
elements.  A coarser mesh given by ``BeamField(time_elements=...)`` is used, with a
:class:`BeamMeshWarning` naming the modes the step resolves and the mesh does not.

*Initial state*: the accelerations at ``t0`` solve ``M a = F - K x - C_d v`` globally (the
consistent mass couples the nodes): one transfer solve of the chain with the step relation at
``cx = A = 0``, ``C = 1``, ``dx = x0``, ``B = v0``, ``D = 0`` (so ``delta = a``), which also gives the
internal forces at ``t0``.
"""
from __future__ import annotations

import math
import warnings
from typing import Any, Mapping

import numpy as np

from .. import validation
from ..assembly import BoundaryEnd, BoundaryStart, clamped_start_solve, predicted_forces, shift_forces
from ..errors import ModelError
from ..layouts import BENDING
from ..system import Chain
from .base import DiscreteElement, Element, Linearisation
from .beams import MAX_TIME_ELEMENTS, BeamField
from .bending import laplace_array
from .boundary import Boundary

__all__ = ["FREQUENCY_TOLERANCE", "BeamMeshWarning", "hermite_matrices", "stiffness_to_transfer", "BeamSegment",
           "DiscreteBeamSegment", "time_element_count", "resolved_frequency", "field_segments", "BendingMesh",
           "bending_mesh"]

#: Relative natural-frequency error [-] that the default mesh and the step both keep below.
FREQUENCY_TOLERANCE = 1e-3
_HERMITE_ERROR = 1.0 / 1440.0        # relative frequency error of a mode / (lambda h)^4
_STEP_ERROR = 1.0 / 12.0             # relative period error of a mode / (omega dt)^2


class BeamMeshWarning(UserWarning):
    """The time step resolves beam modes that the finite-element mesh of the beam does not."""


def hermite_matrices(length: float, bending_stiffness: float, mass_per_length: float,
                     axial_force: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bending stiffness, geometric stiffness and consistent mass of one cubic Hermite element.

    Parameters
    ----------
    length : float
        Element length ``h`` [m].
    bending_stiffness : float
        ``EI`` [N m^2].
    mass_per_length : float
        ``rho A`` [kg/m].
    axial_force : float
        Constant tension ``T`` [N] (negative: compression).

    Returns
    -------
    (K, K_T, M) : numpy.ndarray
        4x4 matrices on ``[w1, theta1, w2, theta2]`` [N/m, N, N m ...], [kg, kg m, kg m^2].
    """
    h = length
    K = bending_stiffness / h ** 3 * np.array([[12.0, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                                               [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
    KT = axial_force / (30 * h) * np.array([[36.0, 3 * h, -36, 3 * h], [3 * h, 4 * h * h, -3 * h, -h * h],
                                            [-36, -3 * h, 36, -3 * h], [3 * h, -h * h, -3 * h, 4 * h * h]])
    M = mass_per_length * h / 420 * np.array([[156.0, 22 * h, 54, -13 * h], [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                                              [54, 13 * h, 156, -22 * h], [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
    return K, KT, M


def stiffness_to_transfer(stiffness: np.ndarray, offset: np.ndarray | None = None):
    """Transfer form ``z_out = U z_in + u`` of an element with end loads ``F = K d + g``.

    Parameters
    ----------
    stiffness : numpy.ndarray
        ``K`` [..., 4, 4] on ``[w_L, theta_L, w_R, theta_R]`` (loads acting on the element).
    offset : numpy.ndarray, optional
        ``g`` [..., 4] (loads at ``d = 0``).

    Returns
    -------
    (U, u) : numpy.ndarray
        ``U`` [..., 4, 4] and ``u`` [..., 4] for ``z = [w, theta, shear, moment]``.
    """
    K_LL, K_LR, K_RL, K_RR = (stiffness[..., :2, :2], stiffness[..., :2, 2:], stiffness[..., 2:, :2],
                              stiffness[..., 2:, 2:])
    X = np.linalg.inv(K_LR)
    U = np.concatenate([np.concatenate([-X @ K_LL, X], axis=-1),
                        np.concatenate([K_RR @ X @ K_LL - K_RL, -K_RR @ X], axis=-1)], axis=-2)
    if offset is None:
        return U, None
    g_L, g_R = offset[..., :2, None], offset[..., 2:, None]
    u = np.concatenate([-(X @ g_L), K_RR @ X @ g_L - g_R], axis=-2)[..., 0]
    return U, u


class BeamSegment(Element):
    """One cubic Hermite beam element (consistent mass) of length ``length`` [m] cut from ``field``.

    The time form of a piece of :class:`~ctmm.elements.beams.BeamField`: the physics (``EI``,
    ``rho A``, tension, Kelvin-Voigt and viscous damping) is the field's; its loss factor is
    refused (hysteretic damping has no causal time form).  Made by :func:`field_segments`;
    usable in any bending chain in both domains (:meth:`transfer_matrix` is the finite-element
    matrix, not the exact field one).
    """

    layout = BENDING
    is_point = False

    def __init__(self, name: str, field: BeamField, length: float) -> None:
        super().__init__(name)
        if not isinstance(field, BeamField):
            raise ModelError(f"{name}: field must be a BeamField, got {type(field).__name__}")
        if field.loss_factor:
            raise ModelError(f"{field.name}: loss_factor={field.loss_factor!r} (hysteretic damping) has no time-domain"
                             " form; use kelvin_voigt_time=tau (damping ratio tau omega / 2 at omega [rad/s]) or "
                             "viscous_damping for a time simulation")
        self.field = field
        self.length = validation.positive(f"{name}: length", length)

    def parameters(self) -> dict[str, Any]:
        return {**self.field.parameters(), "length": self.length}

    @property
    def is_conservative(self) -> bool:
        """False when the field is damped."""
        return self.field.is_conservative

    def matrices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Stiffness ``K`` (bending + geometric), damping ``C_d`` and consistent mass ``M`` (4x4)."""
        f = self.field
        K, KT, M = hermite_matrices(self.length, f.bending_stiffness, f.mass_per_length, f.axial_force)
        return K + KT, f.kelvin_voigt_time * K + (f.viscous_damping / f.mass_per_length) * M, M

    def transfer_matrix(self, s: Any) -> np.ndarray:
        """Finite-element transfer matrix from ``K + s C_d + s^2 M``, shape ``np.shape(s) + (4, 4)``."""
        s = laplace_array(s)[..., None, None]
        K, C, M = self.matrices()
        return stiffness_to_transfer(K + s * C + s * s * M)[0]

    def discretize(self, scheme: Any) -> "DiscreteBeamSegment":
        return DiscreteBeamSegment(self)


class DiscreteBeamSegment(DiscreteElement):
    """DT-TMM form of a :class:`BeamSegment` (see the module docstring)."""

    def __init__(self, element: BeamSegment) -> None:
        self.element = element
        self.K, self.C, self.M = element.matrices()
        self._key: tuple | None = None

    def step_matrices(self, t: float, inboard: Linearisation, outboard: Linearisation, force: Any = 0.0):
        key = (inboard.cx, inboard.A, inboard.C)
        if key != self._key:          # U depends on the scheme constants only: one inverse per step size
            self._U, _ = stiffness_to_transfer(key[0] * self.K + key[1] * self.C + key[2] * self.M)
            self._key = key
        ends = [np.concatenate([np.ravel(getattr(inboard, name)), np.ravel(getattr(outboard, name))])
                for name in ("dx", "B", "D")]
        g = self.K @ ends[0] + self.C @ ends[1] + self.M @ ends[2]
        U = self._U
        u = np.concatenate([-(U[:2, 2:] @ g[:2]), -(U[2:, 2:] @ g[:2]) - g[2:]])
        return U, u


def resolved_frequency(field: BeamField, elements: int, tolerance: float = FREQUENCY_TOLERANCE) -> float:
    """Highest angular frequency [rad/s] that ``elements`` Hermite elements of ``field`` resolve.

    ``lambda h = (1440 tol)^(1/4)`` with ``lambda = (rho A omega^2 / EI)^(1/4)``, ``h = L / elements``.
    """
    lam = (tolerance / _HERMITE_ERROR) ** 0.25 * elements / field.length
    return lam * lam * math.sqrt(field.bending_stiffness / field.mass_per_length)


def time_element_count(field: BeamField, dt: float, tolerance: float = FREQUENCY_TOLERANCE) -> int:
    """Default number of Hermite elements of ``field`` for the step ``dt`` [s].

    Enough that every mode the step resolves to ``tolerance`` (``omega dt <= sqrt(12 tol)``) has
    a mesh frequency error below ``tolerance`` too; also ``sqrt(|T|/EI) h <= (1440 tol)^(1/4)``
    for an axial force; at least 2.
    """
    omega = math.sqrt(tolerance / _STEP_ERROR) / validation.positive("dt", dt)
    beta_max = (tolerance / _HERMITE_ERROR) ** 0.25
    beta = field.length * (field.mass_per_length * omega ** 2 / field.bending_stiffness) ** 0.25
    tension = math.sqrt(abs(field.axial_force) / field.bending_stiffness) * field.length
    return max(2, math.ceil(max(beta, tension) / beta_max))


def field_segments(field: BeamField, dt: float) -> tuple[BeamSegment, ...]:
    """The Hermite elements ``"<name>[1]" ... "<name>[N]"`` of ``field`` for the step ``dt`` [s].

    ``N = field.time_elements`` when given (a :class:`BeamMeshWarning` when it is below
    :func:`time_element_count`), else :func:`time_element_count`.

    Raises
    ------
    ModelError
        The field has a loss factor (hysteretic damping has no time-domain form), or ``dt`` is
        so small that the default count exceeds :data:`~ctmm.elements.beams.MAX_TIME_ELEMENTS`.
    """
    needed = time_element_count(field, dt)
    count = needed if field.time_elements is None else field.time_elements
    if count > MAX_TIME_ELEMENTS:
        raise ModelError(f"{field.name}: the step dt={dt!r} s resolves modes that need {count} Hermite elements, more "
                         f"than {MAX_TIME_ELEMENTS} (each step costs O(N)); use a larger dt or give "
                         f"time_elements <= {MAX_TIME_ELEMENTS} (the band above it is then in error)")
    if count < needed:
        band = math.sqrt(FREQUENCY_TOLERANCE / _STEP_ERROR) / dt
        warnings.warn(f"{field.name}: time_elements={count} resolves modes up to {resolved_frequency(field, count):.4g}"
                      f" rad/s (frequency error <= {FREQUENCY_TOLERANCE:g}), but the step dt={dt!r} s resolves them "
                      f"up to {band:.4g} rad/s: modes in between are in error; use time_elements >= {needed} "
                      "(or the default)", BeamMeshWarning, stacklevel=6)
    return tuple(BeamSegment(f"{field.name}[{k + 1}]", field, field.length / count) for k in range(count))


class BendingMesh:
    """A bending chain as stepped in time: every beam field replaced by its Hermite elements.

    Attributes
    ----------
    chain : Chain
        The meshed chain (fields replaced by :class:`BeamSegment` elements).
    original : Chain
        The chain as given.
    rows : numpy.ndarray
        Index in :attr:`chain` of every connection point of :attr:`original`.
    nodes : dict
        ``{field name: (point indices in chain of its N + 1 nodes, node positions [m] from its inboard end)}``.
    """

    def __init__(self, system: Chain, dt: float) -> None:
        self.original = system
        elements, rows, self.nodes = [system.elements[0]], [0], {}
        for e in system.body:
            first = len(elements) - 1
            if isinstance(e, BeamField):
                pieces = field_segments(e, dt)
                elements.extend(pieces)
                self.nodes[e.name] = (np.arange(first, first + len(pieces) + 1),
                                      np.linspace(0.0, e.length, len(pieces) + 1))
            else:
                elements.append(e)
            rows.append(len(elements) - 1)
        elements.append(system.end)
        self.chain = Chain(system.name, elements) if self.nodes else system
        self.rows = np.array(rows)

    def initial_state(self, x0: Mapping[str, Any] | None, v0: Mapping[str, Any] | None):
        """Initial ``(w, theta)`` [m, rad] and their rates at every point of :attr:`chain`, ``(n, 2)`` each.

        ``x0`` / ``v0`` map element names to a value ``w`` (slope 0) or a pair ``(w, theta)``
        at the element's point (a field: its outboard end), or, for a beam field, a callable
        ``shape(x) -> (w, theta)`` of the distance ``x`` [m] from its inboard end, applied at
        every node.  Unspecified points start at rest at 0; supports hold their displacements.  A
        point given twice with different values (a field's end and a point element there) is refused.
        """
        return self._values("x0", x0), self._values("v0", v0)

    def _values(self, label: str, values: Mapping[str, Any] | None) -> np.ndarray:
        target = np.zeros((self.chain.n_points, 2))
        given = np.zeros(self.chain.n_points, dtype=bool)
        if values is not None and not isinstance(values, Mapping):
            raise ModelError(f"{label} must be a mapping {{element name: value}}, got {values!r:.80}")
        for name, value in (values or {}).items():
            for point, pair in self._pairs(label, name, value):
                if given[point] and np.any(target[point] != pair):
                    raise ModelError(f"{label}[{name!r}] = {pair.tolist()} at a point already given "
                                     f"{target[point].tolist()} by another entry of {label}")
                target[point], given[point] = pair, True
        for j, e in enumerate(self.chain.body, start=1):   # a point element's two points coincide
            if e.is_point:
                if given[j - 1] and given[j] and np.any(target[j - 1] != target[j]):
                    raise ModelError(f"{label}: the two sides of point element {e.name!r} are given different values "
                                     f"{target[j - 1].tolist()} and {target[j].tolist()}")
                source = j if given[j] and not given[j - 1] else j - 1
                target[[j - 1, j]], given[[j - 1, j]] = target[source], given[source]
        return target

    def _pairs(self, label: str, name: str, value: Any) -> list[tuple[int, np.ndarray]]:
        """``(point of chain, (w, theta))`` that the entry ``label[name] = value`` sets."""
        element = self.original.element(name)
        if name in self.nodes:
            if not callable(value):
                raise ModelError(f"{label}[{name!r}] must be a callable shape(x) -> (w, theta) of the distance x [m] "
                                 f"from the beam's inboard end, got {value!r:.80}")
            points, positions = self.nodes[name]
            return [(int(p), _pair(f"{label}[{name!r}]({x:.6g})", value(x))) for p, x in zip(points, positions)]
        pair = _pair(f"{label}[{name!r}]", value)
        pos = self.original.position(name)
        held = element.constrained_dofs(BENDING)[0] if isinstance(element, Boundary) else ()
        if any(pair[i] != 0.0 for i in held):
            raise ModelError(f"{label}[{name!r}] = {value!r}: {name!r} is a support that holds its own motion; "
                             "give initial values to moving points only")
        return [(int(self.rows[min(pos, len(self.rows) - 1) if not element.is_point or pos == 0 else pos - 1]), pair)]

    def initial_motion(self, discrete, x: np.ndarray, v: np.ndarray, t0: float, extra: Mapping[int, Any]):
        """Accelerations ``(n, 2)`` and internal forces ``(n, 2)`` at ``t0`` (one transfer solve)."""
        chain, zero = self.chain, np.zeros(2)
        lins = [Linearisation(0.0, x[j], 0.0, v[j], 1.0, zero, x[j]) for j in range(chain.n_points)]
        Us, us = [], []
        for j, disc in enumerate(discrete, start=1):
            U, u = disc.step_matrices(t0, lins[j - 1], lins[j], disc.load(t0) + extra.get(j, 0.0))
            Us.append(np.asarray(U, dtype=float)[None])
            us.append(np.asarray(u, dtype=float)[None])
        e_idx, S0, P0 = chain.start.start_discrete(BENDING, t0, lins[0])
        Bm, b = chain.end.end_discrete(BENDING, t0, lins[-1])
        reference = predicted_forces(Us, us, 2)
        us, start, end = shift_forces(Us, us, BoundaryStart(e_idx, S0[None], P0[None]),
                                      BoundaryEnd(Bm[None], b[None]), reference, 2)
        states = clamped_start_solve(Us, us, start, end, want_log_det=False).states[:, 0, :]
        return states[:, :2].copy(), states[:, 2:4] + reference[:, 0, :]


def _pair(label: str, value: Any) -> np.ndarray:
    """``value`` as ``(w, theta)``: a number is ``(w, 0)``."""
    try:
        pair = np.array([float(value), 0.0]) if np.ndim(value) == 0 else np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        pair = np.array([np.nan])
    if pair.shape != (2,) or not np.all(np.isfinite(pair)):
        raise ModelError(f"{label} must be a finite number w [m] or a pair (w [m], theta [rad]), got {value!r:.80}")
    return pair


def bending_mesh(system: Chain, dt: float, hooks: tuple = ()) -> BendingMesh | None:
    """The :class:`BendingMesh` of a bending chain for the step ``dt`` [s]; ``None`` for other layouts.

    ``hooks`` are the stepper's per-step callbacks (force hooks, loop and co-simulation hooks):
    they address elements by their position in the chain as given, which the mesh changes, so a
    chain with beam fields and any hook is refused (:class:`~ctmm.errors.ModelError`).
    """
    if system.layout.name != BENDING.name:
        return None
    fields = [e.name for e in system.body if isinstance(e, BeamField)]
    if fields and any(hook is not None for hook in hooks):
        raise ModelError(f"beam fields {fields} in a time simulation with force hooks, feedback loops or co-simulated "
                         "controllers are not supported yet (those address the elements of the unmeshed chain); "
                         "simulate the plain chain, or use ctmm.planar with ctmm.flexible beams for control")
    return BendingMesh(system, dt)

