"""Shapes and modal integrals of the modal spatial beam (:class:`~ctmm.spatial.beam.SpatialBeam`).

Floating frame: the **root tangent frame** (origin at the inboard end ``I``, body ``x`` along the
undeformed axis, ``y`` and ``z`` the principal axes of the cross-section).  A point of the axis at
abscissa ``x`` is at ``rho(x) = [x, 0, 0] + Phi(x) eta`` (body axes) and its cross-section is twisted
by ``gamma(x) = chi(x) . eta``, with the modal coordinates

``eta = [q_y (n_y) ; q_z (n_z) ; r (n_t) ; p (n_a)]``

(bending deflections along ``y`` and ``z``, twist, axial extension).  ``Phi`` has three rows
``Phi_x = psi`` (axial shapes on the ``p`` columns), ``Phi_y = phi`` (on ``q_y``), ``Phi_z = phi``
(on ``q_z``); every shape is clamped at the root and free at the tip:

* bending: the clamped-free Euler-Bernoulli eigenfunctions of :mod:`ctmm.flexible.modes`
  (``int phi^2 = L``), one set per plane;
* twist and axial: the clamped-free rod shapes ``sqrt(2) sin((2k - 1) pi x / (2 L))`` (same scaling).

With ``static_shapes`` every direction that has modes also gets the static tip-load shapes (bending:
``(3 xi^2 - xi^3)/2`` and ``xi^2``, the tip-force and tip-moment deflections; rods: ``sqrt(3) xi``), which
the free-end modes cannot represent (no end strain), each made orthogonal to the modes and to the
previous one (``int`` over the beam, Gram-Schmidt twice on the quadrature: :func:`static_map`) and scaled to
``int shape^2 = L``: then ``K`` is the full integral below.  The raw shapes lie nearly in the modes' span (their
Gram condition is 2.5e9 with four bending modes), so with them the modal mass would be as badly conditioned and a
round-off change of the numbers (numpy against generated code) would move the modal accelerations by 1e-8; the
orthonormal shapes span the same space (the same physics, ``tests/test_spatial_beam_static_shapes.py``) with a
modal mass of condition 1.  Their coefficients grow as the square root of the raw Gram condition, so each
evaluation carries a round-off of about ``eps sqrt(condition)``: the raw condition is refused above
:data:`STATIC_CONDITION` (round-off then below 1e-10).

All integrals are over ``[0, L]`` on Gauss-Legendre points (``rhoA`` uniform)::

    E[k][i] = rhoA int Phi_k^T Phi_i      (n x n, k, i in x, y, z)
    b_i     = rhoA int Phi_i,  c_i = rhoA int x Phi_i
    b_t     = j_p int chi,     M_t = j_p int chi chi^T          (j_p: polar mass moment per length)
    b_r     = int J_b Lambda,  M_r = int Lambda^T J_b Lambda   (J_b = diag(0, rho I_y', rho I_z'): bending sections)
    K       = diag(EI_y int phi''phi''^T, EI_z int phi''phi''^T, GJ int chi'chi'^T, EA int psi'psi'^T)
    G1(x_e) = int_0^x_e w' w'^T,  G2 = int (L - x) w' w'^T,  G3 = int (L^2 - x^2)/2 w' w'^T

(``w' w'^T`` of each bending plane, ``phi'`` on its columns: the geometric stiffness of the axial force in both
planes, block diagonal -- the axial force couples no plane to the other; with ``wagner_term`` also
``(j_p / rhoA) chi' chi'^T`` on the twist block, the Wagner term ``N I_p / A`` of :mod:`ctmm.spatial_beam_torsion`).
End rotation of a station ``x_e``: ``theta = Lambda(x_e) eta = [gamma ; -w_z' ; w_y']`` (body axes).

Section rotary inertia in bending (Rayleigh; ``rotary_inertia_per_length_y|z`` of the beam, 0 by default).  A
section turns by ``Lambda(x) eta`` relative to the frame; its kinetic energy per length, to the order the twist's is
kept, is ``1/2 (omega + Lambda eta_dot)^T J_s (omega + Lambda eta_dot)`` with ``J_s = diag(j_p, rho I_y', rho
I_z')`` in frame axes (``rho I_y'`` about body ``y``, turning with ``-w_z'``: the beam's
``rotary_inertia_per_length_z``; ``rho I_z'`` about ``z`` with ``w_y'``: its ``rotary_inertia_per_length_y``).
Integrated: ``1/2 omega^T L J_s omega + omega^T (e1 b_t^T + b_r) eta_dot + 1/2 eta_dot^T (M_t + M_r) eta_dot``,
whose coefficients are constant: the Euler-Poincare equations add ``L J_s`` to the frame's inertia ``J``, the
coupling ``b_r`` beside ``e1 b_t^T`` (and its transpose in the modal rows), ``M_r`` to the modal mass and the
gyroscopic moment ``omega x (b_r eta_dot)``; no other velocity term (``d/dt dT/d eta_dot = b_r^T alpha + M_r
eta''``, ``dT/d eta = 0``): conservative.  ``M_r`` is the modal rotary-inertia matrix ``sum over the planes of rho I
int w' w'^T`` (the Rayleigh term of the beam equation ``EI w'''' - rho I w''_tt + rhoA w_tt = 0``; its natural end
condition ``EI w''' - rho I w'_tt = 0`` is reached in the Ritz limit).  Not kept: the turned section's inertia
``R(theta) J_s R(theta)^T`` and its angular velocity's dependence on ``theta`` (second order in ``eta``: the
gyroscopic ``2 Omega rho I_p`` coupling and spin softening of a spinning shaft).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ModelError
from ..flexible.modes import ModeSet, gauss_points
from .beam_second_order import SecondOrderTensors

__all__ = ["rod_shapes", "static_map", "SpatialBeamData", "STATIC_CONDITION"]

STATIC_CONDITION = 1e11
"""Largest condition number of one direction's raw shape Gram matrix ``int shapes shapes^T / L`` (modes and raw
static shapes) accepted with static shapes (about 6 modes per direction with them; more add nothing but
round-off): the orthonormalised static shapes then carry a round-off below 1e-10 relative."""


def rod_shapes(x: Any, length: float, count: int, derivative: int = 0) -> np.ndarray:
    """Clamped-free rod shapes ``sqrt(2) sin((2k - 1) pi x / (2 L))`` or their ``derivative`` (0, 1):
    ``(count, len(x))``; ``int_0^L shape^2 = L``."""
    x = np.atleast_1d(np.asarray(x, dtype=float))
    k = np.arange(1, count + 1)[:, None]
    a = (2 * k - 1) * math.pi / (2 * length)
    y = a * x[None, :]
    return math.sqrt(2.0) * (np.sin(y) if derivative == 0 else a * np.cos(y))


def static_map(shapes: np.ndarray, count: int, weights: np.ndarray) -> np.ndarray:
    """Coefficients ``T`` (``(count, len(shapes))``) of the last ``count`` rows of ``shapes`` (samples
    ``(m + count, G)`` of the modes, then the raw static shapes, at quadrature points with ``weights``, the
    inner product ``sum weights f g``) made orthogonal to the span of the rows before them (Gram-Schmidt,
    twice: re-orthogonalisation keeps the round-off at ``eps`` times the shapes' Gram condition's square root)
    and to unit norm: ``T @ shapes`` are the orthonormal static shapes, spanning with the modes what the raw
    shapes span."""
    root = np.sqrt(weights)
    samples = shapes * root                                     # sum of squares = inner product
    basis: list[tuple[np.ndarray, np.ndarray]] = []             # (coefficients, samples), orthonormal
    for row in range(len(shapes)):
        coefficients = np.zeros(len(shapes))
        coefficients[row] = 1.0
        vector = samples[row].copy()
        for _ in range(2):
            for known, known_samples in basis:
                projection = known_samples @ vector
                vector -= projection * known_samples
                coefficients -= projection * known
        norm = float(np.linalg.norm(vector))
        basis.append((coefficients / norm, vector / norm))
    return np.array([coefficients for coefficients, _ in basis[len(shapes) - count:]])


class SpatialBeamData:
    """Modal integrals of a :class:`~ctmm.spatial.beam.SpatialBeam` (module notation), numpy constants.

    Parameters
    ----------
    beam : SpatialBeam
        The validated element (reads its lengths, stiffnesses, mode counts, switches and hooks).
    """

    def __init__(self, beam: Any) -> None:
        L, rhoA = beam.length, beam.mass_per_length
        self.L, self.rhoA = L, rhoA
        self.static = beam.static_shapes
        self.mode_sets = {"y": ModeSet.clamped_free(beam.n_modes_y), "z": ModeSet.clamped_free(beam.n_modes_z)}
        self.rods = {"t": beam.n_torsion_modes, "a": beam.n_axial_modes}
        self.columns, start = {}, 0
        for direction in ("y", "z", "t", "a"):
            count = beam.direction_counts[direction]
            self.columns[direction] = slice(start, start + count)
            start += count
        n = self.n = start
        x, w = gauss_points(beam.quadrature, L)
        self.static_maps: dict[str, np.ndarray] = {}
        """``{direction: T}`` with static shapes: the orthonormalised static shapes are ``T @ [modes ; raw static
        shapes]`` (``T``: ``(n_static, n_modes + n_static)``), for the shapes and every derivative."""
        for direction in ("y", "z", "t", "a") if self.static else ():
            base, raw = self._raw(direction, x, 0)
            if not len(base):
                continue
            shapes = np.vstack([base, raw])
            condition = np.linalg.cond((shapes * w) @ shapes.T / L)
            if condition > STATIC_CONDITION:
                raise ModelError(f"{beam.name}: static_shapes with {len(shapes)} shapes in direction {direction!r} are "
                                 f"nearly linearly dependent (Gram condition {condition:.3g} > {STATIC_CONDITION:g}); "
                                 "use fewer modes with them (3 to 6 reach 1e-8 for a tip body), or static_shapes=False")
            self.static_maps[direction] = static_map(shapes, len(raw), w / L)
        Phi = self.shapes(x)                                    # (3, n, G)
        self.E = [[rhoA * (Phi[k] * w) @ Phi[i].T for i in range(3)] for k in range(3)]
        self.b = rhoA * Phi @ w                                 # (3, n)
        self.c = rhoA * Phi @ (w * x)                           # (3, n)
        self.m = rhoA * L
        self.first_moment = rhoA * L * L / 2
        self.second_moment = rhoA * L ** 3 / 3
        chi = np.zeros((n, len(x)))
        chi[self.columns["t"]] = self.direction_shapes("t", x)
        jp = beam.polar_inertia_per_length
        self.jp = jp
        self.b_t = jp * chi @ w
        self.M_t = jp * (chi * w) @ chi.T
        K = np.zeros((n, n))
        stiffness = {"y": beam.bending_stiffness_y, "z": beam.bending_stiffness_z,
                     "t": beam.torsional_stiffness or 0.0, "a": beam.axial_stiffness or 0.0}
        for direction, value in stiffness.items():
            block = self.columns[direction]
            if self.static:                    # static shapes are not orthogonal to the modes: the full integral
                curvature = self.direction_shapes(direction, x, 2 if direction in "yz" else 1)
                K[block, block] = value * (curvature * w) @ curvature.T
            elif direction in "yz":              # EI int phi''^2 = EI b^4 / L^3 (exact)
                K[block, block] = np.diag(value * np.array(self.mode_sets[direction].betas) ** 4 / L ** 3)
            else:                                # int psi'^2 = ((2k - 1) pi / 2L)^2 L
                k = np.arange(1, self.rods[direction] + 1)
                K[block, block] = np.diag(value * ((2 * k - 1) * math.pi / (2 * L)) ** 2 * L)
        # bending sections (Rayleigh): Lambda rows theta_y = -w_z', theta_z = w_y', rho I about y (with w_z), about z
        self.rotary = np.array([0.0, beam.rotary_inertia_per_length_z, beam.rotary_inertia_per_length_y])
        turn = np.zeros((3, n, len(x)))
        slopes = self.slopes(x)
        turn[1, self.columns["z"]] = -slopes[self.columns["z"]]
        turn[2, self.columns["y"]] = slopes[self.columns["y"]]
        self.b_r = np.array([self.rotary[k] * turn[k] @ w for k in range(3)])                  # (3, n)
        self.M_r = sum(self.rotary[k] * (turn[k] * w) @ turn[k].T for k in (1, 2))           # (n, n)
        self.modal_mass = self.E[0][0] + self.E[1][1] + self.E[2][2] + self.M_t + self.M_r
        D = beam.stiffness_damping * K + 2 * beam.damping_ratio * np.diag(
            np.sqrt(np.clip(np.diag(K) * np.diag(self.modal_mass), 0.0, None)))
        self.K, self.D = K, D
        self.frequencies = np.sqrt(np.diag(K) / np.diag(self.modal_mass))
        self.wagner = beam.polar_inertia_per_length / rhoA if beam.wagner_term else 0.0
        """``I_p / A`` [m^2] of the Wagner term (0 without it)."""
        self.G2 = self.geometric(x, w * (L - x))
        self.G3 = self.geometric(x, w * (L * L - x * x) / 2)
        self.stiffening = beam.geometric_stiffening
        self.second_order = SecondOrderTensors(self, beam.quadrature) if beam.second_order_inertia else None
        self.K_total, self.D_total = K.copy(), D.copy()
        self.forces = []
        for hook in beam.modal_forces:
            if hook.stiffness is not None:
                self.K_total = self.K_total + hook.stiffness
            if hook.damping is not None:
                self.D_total = self.D_total + hook.damping
            if hook.force is not None:
                self.forces.append((hook.label, hook.force))
        self.quadrature = beam.quadrature
        self.abscissae: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}     # filled next, by station()
        self.abscissae = {float(point[0]): self.station(float(point[0])) for point in beam.points.values()}
        """``{x: (Phi (3, n), Lambda (3, n), G1 (n, n))}`` of every point of the beam (computed once)."""
        self.memo: dict[str, Any] = {}
        """Numbers derived from the integrals above by their users, built once (:meth:`remembered`)."""

    def remembered(self, key: str, build: Any) -> Any:
        """``build(self)``, computed on the first call with ``key`` and kept in :attr:`memo` (derived constants
        that do not change between calls, e.g. the stacked integrals of
        :func:`~ctmm.spatial.beam_terms.spatial_beam_terms`)."""
        value = self.memo.get(key)
        if value is None:
            value = self.memo[key] = build(self)
        return value

    def __copy__(self) -> "SpatialBeamData":
        """A shallow copy with an empty :attr:`memo` (a copy whose integrals are then changed, as the scaled views
        of :mod:`ctmm.compiled_spatial_beam_numbers`, never reads the original's derived numbers)."""
        out = object.__new__(type(self))
        out.__dict__.update(self.__dict__)
        out.memo = {}
        return out

    def direction_shapes(self, direction: str, x: Any, derivative: int = 0) -> np.ndarray:
        """Shapes of one direction (``"y"``, ``"z"`` bending; ``"t"`` twist, ``"a"`` axial) or their
        ``derivative`` (bending 0..2, rods 0..1) at ``x`` [m]: ``(count, len(x))``.  With static shapes: after
        the bending modes the tip-force and tip-moment deflections ``(3 xi^2 - xi^3)/2`` and ``xi^2``, after the
        rod modes ``sqrt(3) xi`` (``xi = x / L``)."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        base, raw = self._raw(direction, x, derivative)
        if not self.static or not len(base):
            return base
        return np.vstack([base, self.static_maps[direction] @ np.vstack([base, raw])])

    def _raw(self, direction: str, x: np.ndarray, derivative: int) -> tuple[np.ndarray, np.ndarray]:
        """Modes and the raw static shapes of a direction (or their derivative) at ``x``."""
        L, xi = self.L, x / self.L
        if direction in ("y", "z"):
            modes = self.mode_sets[direction]
            if not len(modes):
                return np.zeros((0, len(x))), np.zeros((0, len(x)))
            force = ((3 * xi ** 2 - xi ** 3) / 2, (3 * xi - 1.5 * xi ** 2) / L, (3 - 3 * xi) / L ** 2)[derivative]
            moment = (xi ** 2, 2 * xi / L, 2 * np.ones_like(xi) / L ** 2)[derivative]
            return modes.evaluate(xi, derivative) / L ** derivative, np.vstack([force, moment])
        count = self.rods[direction]
        if not count:
            return np.zeros((0, len(x))), np.zeros((0, len(x)))
        linear = math.sqrt(3.0) * (xi if derivative == 0 else np.ones_like(xi) / L)
        return rod_shapes(x, L, count, derivative), linear[None]

    def shapes(self, x: Any) -> np.ndarray:
        """``Phi`` at stations ``x`` [m]: ``(3, n, len(x))`` (rows ``x, y, z``)."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        out = np.zeros((3, self.n, len(x)))
        for row, direction in ((0, "a"), (1, "y"), (2, "z")):
            out[row, self.columns[direction]] = self.direction_shapes(direction, x)
        return out

    def slopes(self, x: Any) -> np.ndarray:
        """Bending slopes ``w'`` at ``x``: ``(n, len(x))`` (``phi'`` on the ``q_y`` and ``q_z`` columns) [1/m]."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        out = np.zeros((self.n, len(x)))
        for plane in ("y", "z"):
            out[self.columns[plane]] = self.direction_shapes(plane, x, 1)
        return out

    def geometric(self, x: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """``sum_k weights_k (w_y' w_y'^T + w_z' w_z'^T + (I_p / A) chi' chi'^T)(x_k)`` (n x n): the geometric
        stiffness integral, one block per bending plane (the axial force couples no plane to the other) and the
        Wagner term's twist block (:attr:`wagner`, 0 without it)."""
        slopes = self.slopes(x)
        out = np.zeros((self.n, self.n))
        for plane in ("y", "z"):
            rows = self.columns[plane]
            out[rows, rows] = (slopes[rows] * weights) @ slopes[rows].T
        if self.wagner and self.rods["t"]:
            rows = self.columns["t"]
            twist = self.direction_shapes("t", x, 1)
            out[rows, rows] = self.wagner * (twist * weights) @ twist.T
        return out

    def station(self, x_e: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(Phi(x_e) (3, n), Lambda(x_e) (3, n), G1(x_e) (n, n))`` of a station at ``x_e`` [m]."""
        if x_e in self.abscissae:
            return self.abscissae[x_e]
        Phi = self.shapes([x_e])[:, :, 0]
        slopes = self.slopes([x_e])[:, 0]
        Lam = np.zeros((3, self.n))
        Lam[0, self.columns["t"]] = self.direction_shapes("t", [x_e])[:, 0]
        Lam[1, self.columns["z"]] = -slopes[self.columns["z"]]
        Lam[2, self.columns["y"]] = slopes[self.columns["y"]]
        G1 = np.zeros((self.n, self.n))
        if x_e > 0.0:
            xs, ws = gauss_points(self.quadrature, x_e)
            G1 = self.geometric(xs, ws)
        return Phi, Lam, G1
