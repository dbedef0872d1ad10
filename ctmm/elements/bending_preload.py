"""Axial preload in the bending layout (:data:`~ctmm.layouts.BENDING`): a beam whose tension varies
linearly along it, and the geometric moment of a rigid segment (frequency domain).

A straight chain hanging (or standing) in gravity along its axis carries an axial tension ``T(x)``
[N] (positive: tension) equal to the axial gravity component times the mass outboard of ``x``.  At
first order the tension keeps the transverse motion's equations linear (``docs/planar.md``, exact
fields in gravity):

* :class:`VaryingTensionBeamField` -- an Euler-Bernoulli field with ``T(x) = T_in + (T_out - T_in)
  x / L``, ``z' = A(x, s) z`` with ``A(x, s) = A_0(s) + T(x) B`` (``A_0``: the constant-tension
  field of :func:`ctmm.elements.beams.beam_state_matrix` at ``T = 0``, ``B = -e_4 e_2^T``:
  ``moment' = -shear - T theta``).  No closed form exists (``EI -> 0``: Bessel ``J0``); the field
  matrix is integrated by the sixth-order Magnus method with three Gauss points (Blanes, Casas,
  Oteo, Ros, Phys. Rep. 470 (2009) 151, eq. (253)); for ``A`` linear in ``x`` its third
  difference ``alpha_3`` vanishes and, per sub-step ``h``, ``alpha_1 = h A(x_m)``, ``alpha_2 = T' h^2
  B``, ``C_1 = [alpha_1, alpha_2]``, ``C_2 = -[alpha_1, C_1] / 60``, ``Omega = alpha_1 + [C_1 - 20
  alpha_1, alpha_2 + C_2] / 240`` (its leading terms are the fourth-order ``h A(x_m) - (T' h^3 /
  12) [A_0, B]``).
  ``expm(Omega)`` stays in the symplectic group (reciprocity is kept to round-off).  Every field
  matrix is **error-controlled**: it is computed with ``m`` and ``2 m`` sub-steps and the difference of
  the dimensionless matrices ``D^-1 U D`` (``D = diag(L, 1, EI/L^2, EI/L)``), divided by 63 (the
  sixth-order Richardson estimate of the finer one's error), must be at most ``tolerance``
  times ``max(1, |D^-1 U D|)``; ``m`` doubles up to :data:`MAX_SUB_STEPS`, beyond which a
  :class:`~ctmm.errors.ModelError` names the piece (split it).  The finer matrix is returned.  The
  estimate is asymptotic (the ratio 64 per halving is observed from the first doubling on: 3.9e-5,
  6.5e-7, 1.0e-8, 1.6e-10 for 3-6-12-24-48 sub-steps of a heavy piece), not a rigorous bound.
* :class:`GeometricMoment` -- the preload's moment on a rigid segment, a grounded rotational
  stiffness ``moment_out = moment_in - k_g theta`` of either sign placed after
  :class:`~ctmm.elements.bending_bodies.RigidSegment` (``theta`` is constant along it).  For a
  segment of length ``l`` with the tension ``T_out`` at its outboard point and its own axial weight
  ``W`` at its centre of mass ``a``: ``k_g = T_out l + W a`` (``int T dx theta`` of the field).

Wittrick-Williams: :meth:`VaryingTensionBeamField.clamped_frequency_count` splits the field into
pieces with no clamped-clamped frequency below ``omega`` (``beta <= 3`` and ``max|T| l^2 / EI <=
pi^2``: by the min-max principle a varying tension's frequencies lie above those of the constant
``min T``, which have none there, ``ctmm.elements.beams.BeamField.clamped_frequency_count``) and
counts the negative eigenvalues of the interior nodes' dynamic stiffness; :meth:`subdivide` gives
such pieces directly.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import validation
from ..errors import ModelError
from ..layouts import BENDING
from .base import Element
from .bending import identity_matrices, laplace_array

__all__ = ["VaryingTensionBeamField", "GeometricMoment", "DEFAULT_TOLERANCE", "MAX_SUB_STEPS"]

#: Largest estimated relative error of a field matrix (dimensionless entries) by default.
DEFAULT_TOLERANCE = 1e-11
#: Most Magnus sub-steps per field before the piece is refused.
MAX_SUB_STEPS = 512
#: Largest wave number (``beta`` and ``sqrt(max|T|/EI) l``) of a piece made by ``subdivide``.
SUBDIVISION_LIMIT = 3.0
#: Largest wave number of one Magnus sub-step at the first attempt.
_STEP_LIMIT = 0.25


class VaryingTensionBeamField(Element):
    """Uniform Euler-Bernoulli beam with a linearly varying axial tension (module docstring).

    Parameters
    ----------
    name : str
    length : float
        ``L`` [m], > 0.
    bending_stiffness : float
        ``EI`` [N m^2], > 0.
    mass_per_length : float
        ``rhoA`` [kg/m], > 0.
    inboard_tension, outboard_tension : float
        Axial tension ``T`` [N] at ``x = 0`` and ``x = L`` (negative: compression).
    kelvin_voigt_time : float, optional
        Strain-rate damping time ``tau >= 0`` [s]: ``EI* = EI (1 + tau s)``.
    tolerance : float, optional
        Largest estimated relative error of the field matrix (default :data:`DEFAULT_TOLERANCE`).
    """

    layout = BENDING
    is_point = False

    def __init__(self, name: str, length: float, bending_stiffness: float, mass_per_length: float, *,
                 inboard_tension: float, outboard_tension: float, kelvin_voigt_time: float = 0.0,
                 tolerance: float = DEFAULT_TOLERANCE) -> None:
        super().__init__(name)
        self.length = validation.positive(f"{name}: length", length)
        self.bending_stiffness = validation.positive(f"{name}: bending_stiffness", bending_stiffness)
        self.mass_per_length = validation.positive(f"{name}: mass_per_length", mass_per_length)
        self.inboard_tension = validation.finite(f"{name}: inboard_tension", inboard_tension)
        self.outboard_tension = validation.finite(f"{name}: outboard_tension", outboard_tension)
        self.kelvin_voigt_time = validation.nonnegative(f"{name}: kelvin_voigt_time", kelvin_voigt_time)
        self.tolerance = validation.positive(f"{name}: tolerance", tolerance)
        if self.tolerance < 1e-14:
            raise ModelError(f"{name}: tolerance must be >= 1e-14 (round-off of the sub-steps), got {tolerance!r}")

    def parameters(self) -> dict[str, Any]:
        return {"length": self.length, "bending_stiffness": self.bending_stiffness,
                "mass_per_length": self.mass_per_length, "inboard_tension": self.inboard_tension,
                "outboard_tension": self.outboard_tension, "kelvin_voigt_time": self.kelvin_voigt_time,
                "tolerance": self.tolerance}

    @property
    def is_conservative(self) -> bool:
        """False with Kelvin-Voigt damping (checked by ``natural_frequencies``)."""
        return not self.kelvin_voigt_time

    def tension(self, x: Any) -> np.ndarray:
        """``T(x)`` [N] at ``x`` [m] from the inboard end."""
        x = np.asarray(x, dtype=float)
        return self.inboard_tension + (self.outboard_tension - self.inboard_tension) * x / self.length

    def discretize(self, scheme: Any):
        """Refused: a frequency-domain element (in time the modal beam carries the preload)."""
        raise ModelError(f"element {self.name!r} (VaryingTensionBeamField) has no time-domain form; use the "
                         "frequency-domain verbs on this chain")

    # -- frequency domain --------------------------------------------------------------
    def _wave_numbers(self, omega_max: float, length: float) -> tuple[float, float]:
        beta = length * (self.mass_per_length * omega_max ** 2 / self.bending_stiffness) ** 0.25
        largest = max(abs(self.inboard_tension), abs(self.outboard_tension))
        return beta, math.sqrt(largest / self.bending_stiffness) * length

    def _magnus(self, s: np.ndarray, steps: int) -> np.ndarray:
        """Field matrices by ``steps`` sixth-order Magnus sub-steps, shape ``s.shape + (4, 4)``.

        Each sub-step's ``Omega`` is formed dimensionless (``D_h^-1 Omega D_h``, ``D_h = diag(h, 1,
        EI/h^2, EI/h)``: entries ``1``, ``beta_h^4``, ``T h^2 / EI``) and exponentiated by
        :func:`_expm_small`.
        """
        h, EI = self.length / steps, self.bending_stiffness
        stiffness = 1 + self.kelvin_voigt_time * s                  # EI* / EI
        A0 = np.zeros(s.shape + (4, 4), dtype=complex)              # h D_h^-1 A_0 D_h
        A0[..., 0, 1] = 1.0
        A0[..., 1, 3] = -1.0 / stiffness
        A0[..., 2, 0] = -self.mass_per_length * s * s * h ** 4 / EI
        A0[..., 3, 2] = -1.0
        B = np.zeros((4, 4), dtype=complex)                         # h D_h^-1 B D_h / (h^2 / EI)
        B[3, 1] = -1.0
        ramp = (self.outboard_tension - self.inboard_tension) / self.length * h ** 3 / EI   # T' h^3 / EI
        middles = self.tension((np.arange(steps) + 0.5) * h) * h * h / EI
        a1 = A0[None] + middles[:, None, None, None] * B            # h A(x_m)
        a2 = ramp * B                                               # (sqrt(15) h / 3) (A_3 - A_1)
        c1 = _bracket(a1, a2)
        c2 = -_bracket(a1, c1) / 60.0
        omega = a1 + _bracket(c1 - 20.0 * a1, a2 + c2) / 240.0
        E = _expm_small(omega)
        while E.shape[0] > 1:                                       # ordered product, pairwise
            odd = E[-1:] if E.shape[0] % 2 else E[:0]
            E = np.concatenate([E[1::2] @ E[0:-1:2] if E.shape[0] % 2 else E[1::2] @ E[0::2], odd])
        U = E[0]
        D = np.array([h, 1.0, EI / h ** 2, EI / h])
        return U * D[:, None] / D[None, :]

    def _scaled(self, U: np.ndarray) -> np.ndarray:
        L, EI = self.length, self.bending_stiffness
        D = np.array([L, 1.0, EI / L ** 2, EI / L])
        return U * D[None, :] / D[:, None]

    def transfer_matrix(self, s: Any) -> np.ndarray:
        """Certified field matrix ``z(L) = U(s) z(0)``, shape ``np.shape(s) + (4, 4)`` (module docstring).

        Raises
        ------
        ModelError
            If :data:`MAX_SUB_STEPS` sub-steps do not reach ``tolerance``.
        """
        s = laplace_array(s)
        flat = s.reshape(-1)
        if flat.size == 0:
            return identity_matrices(s)
        beta, tension = self._wave_numbers(float(np.max(np.abs(flat))), self.length)
        steps = max(2, math.ceil(max(beta, tension) / _STEP_LIMIT))
        if 2 * steps > MAX_SUB_STEPS:
            raise ModelError(f"{self.name}: at |s| = {np.max(np.abs(flat)):.6g} 1/s the field's wave number is "
                             f"{max(beta, tension):.3g}: more than {MAX_SUB_STEPS} sub-steps; split the field "
                             f"(split({self.pieces_for(float(np.max(np.abs(flat))))}))")
        coarse = self._magnus(flat, steps)
        while True:
            fine = self._magnus(flat, 2 * steps)
            scaled = self._scaled(fine)
            error = float(np.max(np.abs(scaled - self._scaled(coarse)))) / 63.0
            size = max(1.0, float(np.max(np.abs(scaled))))
            if error <= self.tolerance * size:
                return fine.reshape(s.shape + (4, 4))
            if 2 * steps >= MAX_SUB_STEPS:
                raise ModelError(f"{self.name}: the varying-tension field reaches an estimated relative error "
                                 f"{error / size:.2e} > tolerance {self.tolerance:.1e} with {2 * steps} sub-steps at "
                                 f"|s| <= {np.max(np.abs(flat)):.6g} 1/s; split the field (split(n))")
            steps, coarse = 2 * steps, fine

    def split(self, pieces: int) -> tuple["VaryingTensionBeamField", ...]:
        """``pieces`` equal segments ``"<name>_1" ...`` (tension continued linearly) whose product is this field."""
        pieces = validation.integer(f"{self.name}: pieces", pieces, minimum=1)
        edges = self.tension(np.linspace(0.0, self.length, pieces + 1))
        return tuple(VaryingTensionBeamField(f"{self.name}_{i + 1}", self.length / pieces, self.bending_stiffness,
                                             self.mass_per_length, inboard_tension=float(edges[i]),
                                             outboard_tension=float(edges[i + 1]),
                                             kelvin_voigt_time=self.kelvin_voigt_time, tolerance=self.tolerance)
                     for i in range(pieces))

    def pieces_for(self, omega_max: float, *, limit: float = SUBDIVISION_LIMIT) -> int:
        """Equal pieces that keep ``beta`` and ``sqrt(max|T|/EI) l`` at most ``limit`` up to ``omega_max`` [rad/s]."""
        omega_max = validation.nonnegative("omega_max", omega_max)
        limit = validation.positive("limit", limit)
        return max(1, math.ceil(max(self._wave_numbers(omega_max, self.length)) / limit))

    def subdivide(self, omega_max: float) -> list["VaryingTensionBeamField"]:
        """Pieces with every wave number ``<= 3`` up to ``omega_max`` [rad/s] (solver hook; no clamped
        frequency of a piece lies below ``omega_max``)."""
        pieces = self.pieces_for(omega_max)
        return [self] if pieces == 1 else list(self.split(pieces))

    # -- Wittrick-Williams -------------------------------------------------------------
    def clamped_frequency_count(self, omega: Any) -> np.ndarray:
        """Natural frequencies of the field clamped at both ends strictly below ``omega`` [rad/s] (``J0``).

        Undamped (``kelvin_voigt_time`` ignored); module docstring for the method.
        """
        omega = np.asarray(omega, dtype=float)
        if not np.all(np.isfinite(omega)) or np.any(omega < 0):
            raise ModelError(f"{self.name}: omega must be finite and >= 0 rad/s, got {omega!r}")
        flat = omega.reshape(-1)
        pieces = self.pieces_for(float(np.max(flat, initial=0.0)))
        if pieces == 1:
            return np.zeros(omega.shape, dtype=np.int64)
        undamped = VaryingTensionBeamField(self.name, self.length, self.bending_stiffness, self.mass_per_length,
                                           inboard_tension=self.inboard_tension,
                                           outboard_tension=self.outboard_tension, tolerance=self.tolerance)
        n = 2 * (pieces - 1)
        G = np.zeros((flat.size, n, n))
        for index, piece in enumerate(undamped.split(pieces)):
            K = _dynamic_stiffness(np.real(piece.transfer_matrix(1j * flat)))
            if index > 0:                     # inboard end = interior node index - 1
                i = slice(2 * index - 2, 2 * index)
                G[:, i, i] += K[:, :2, :2]
            if index < pieces - 1:            # outboard end = interior node index
                j = slice(2 * index, 2 * index + 2)
                G[:, j, j] += K[:, 2:, 2:]
                if index > 0:
                    G[:, i, j] += K[:, :2, 2:]
                    G[:, j, i] += K[:, 2:, :2]
        G = 0.5 * (G + np.swapaxes(G, -1, -2))
        return np.sum(np.linalg.eigvalsh(G) < 0, axis=-1).astype(np.int64).reshape(omega.shape)


def _bracket(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Commutator ``[X, Y] = X Y - Y X`` (batched)."""
    return X @ Y - Y @ X


def _expm_small(X: np.ndarray) -> np.ndarray:
    """``expm`` of a batch ``(..., 4, 4)`` of dimensionless matrices: scaling to norm ``<= 1`` and
    squaring of the degree-19 Taylor polynomial (truncation ``1 / 20! < 1e-18``), evaluated by
    Paterson-Stockmeyer (seven products)."""
    norm = float(np.max(np.sum(np.abs(X), axis=-1), initial=0.0))
    squarings = max(0, math.ceil(math.log2(norm))) if norm > 1.0 else 0
    Y = X / 2.0 ** squarings
    eye = np.broadcast_to(np.eye(4, dtype=complex), Y.shape)
    Y2 = Y @ Y
    Y3 = Y2 @ Y
    powers = np.stack([eye, Y, Y2, Y3], axis=-1)               # (..., 4, 4, 4 powers)
    Y4 = Y3 @ Y
    E = powers @ _INVERSE_FACTORIALS[16:20]
    for block in range(3, -1, -1):            # degrees 4 block .. 4 block + 3
        E = powers @ _INVERSE_FACTORIALS[4 * block:4 * block + 4] + Y4 @ E
    for _ in range(squarings):
        E = E @ E
    return E


_INVERSE_FACTORIALS = np.array([1.0 / math.factorial(k) for k in range(20)])


def _dynamic_stiffness(U: np.ndarray) -> np.ndarray:
    """``[F_in; F_out] = K [w_in, theta_in, w_out, theta_out]``, end forces acting on the field."""
    U11, U12, U21, U22 = U[..., :2, :2], U[..., :2, 2:], U[..., 2:, :2], U[..., 2:, 2:]
    X = np.linalg.inv(U12)
    top = np.concatenate([-X @ U11, X], axis=-1)
    bottom = np.concatenate([-U21 + U22 @ X @ U11, -U22 @ X], axis=-1)
    return np.concatenate([top, bottom], axis=-2)


class GeometricMoment(Element):
    """Grounded rotational stiffness of an axial preload: ``moment_out = moment_in - k_g theta`` (module docstring).

    Parameters
    ----------
    name : str
    stiffness : float
        ``k_g`` [N m/rad], any finite sign (negative: a compressed, standing segment).
    """

    layout = BENDING
    is_point = True

    def __init__(self, name: str, stiffness: float) -> None:
        super().__init__(name)
        self.stiffness = validation.finite(f"{name}: stiffness", stiffness)

    def parameters(self) -> dict[str, Any]:
        return {"stiffness": self.stiffness}

    def transfer_matrix(self, s: Any) -> np.ndarray:
        s = laplace_array(s)
        U = identity_matrices(s)
        U[..., 3, 1] = -self.stiffness
        return U

    def discretize(self, scheme: Any):
        """Refused: a frequency-domain element of the exact-field form."""
        raise ModelError(f"element {self.name!r} (GeometricMoment) has no time-domain form")
