"""One bending plane of a spatial beam field with the rotary inertia of its section (Rayleigh beam).

Planar state ``[w, theta, shear, moment]`` of :mod:`ctmm.elements.beams` (``shear``, ``moment`` exerted by
the inboard on the outboard part).  The slice ``[x, x + dx]`` of a beam whose section has the mass moment
of inertia ``rho I`` per length [kg m] about the bending axis turns with ``theta = w'``; Euler's law
for the slice gains the inertia moment ``-rho I s^2 theta dx``:

    w' = theta,  theta' = -moment / EI*,  shear' = -(rho A s^2 + c_v s) w,
    moment' = -shear - (T + rho I s^2) theta

(the kinetic energy ``1/2 rho I (w_t')^2`` added to Euler-Bernoulli's gives ``EI w'''' - (T + rho I s^2)
w'' + rho A s^2 w = 0``; ``shear = EI w''' - (T + rho I s^2) w'`` is the force conjugate to ``w``, so a
free end is ``shear = moment = 0``).  The rotary inertia enters exactly like a tension ``T + rho I s^2``
(for ``s = i omega``: a compression ``rho I omega^2`` growing with frequency).  The field matrix is
``U = D expm(A_hat) D^-1`` with the dimensionless ``A_hat = L D^-1 A D``, ``D = diag(L, 1, EI/L^2, EI/L)``
(entries ``1``, ``EI / EI*``, ``(beta L)^4``, ``(T + rho I s^2) L^2 / EI``), by ``scipy.linalg.expm``
(scaling and squaring, round-off level for the pieces of wave number ``<= 4`` the solvers use).

Wittrick-Williams ``J0`` (:meth:`RayleighPlane.clamped_frequency_count`): the plane cut into pieces with
``beta l <= 3``, ``omega l sqrt(rho I / EI) <= 2`` and ``|T| l^2 / EI <= pi^2``.  Such a piece has no
clamped-clamped frequency at or below ``omega``: for clamped ends ``int EI w''^2 >= lambda_1 int rho A
w^2`` (``lambda_1 = (4.730 / l)^4 EI / rho A``, Euler-Bernoulli's first clamped frequency squared) and
``>= lambda_2 int rho I w'^2`` (``lambda_2 = 4 pi^2 EI / (rho I l^2)``, the clamped buckling load), a
compression takes at most a quarter of ``int EI w''^2``, so the Rayleigh quotient is at least ``(3/4) /
(1 / lambda_1 + 1 / lambda_2) >= 2.8 omega^2``.  ``J0`` is then the Sturm count of the interior nodes'
dynamic stiffness.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.linalg

from . import validation
from .elements.bending import laplace_array
from .errors import ModelError

__all__ = ["RayleighPlane"]

_COUNT_BETA, _COUNT_ROTARY = 3.0, 2.0


class RayleighPlane:
    """Bending plane with section rotary inertia (module docstring); not a chain element by itself.

    Parameters
    ----------
    length : float
        ``L`` [m].
    bending_stiffness : float
        ``EI`` [N m^2].
    mass_per_length : float
        ``rho A`` [kg/m].
    rotary_inertia_per_length : float
        ``rho I`` [kg m] about the bending axis, > 0.
    axial_force : float
        Tension ``T`` [N].
    loss_factor, kelvin_voigt_time, viscous_damping : float
        As :class:`ctmm.elements.beams.BeamField`.
    """

    def __init__(self, length: float, bending_stiffness: float, mass_per_length: float,
                 rotary_inertia_per_length: float, *, axial_force: float = 0.0, loss_factor: float = 0.0,
                 kelvin_voigt_time: float = 0.0, viscous_damping: float = 0.0) -> None:
        self.length = length
        self.bending_stiffness = bending_stiffness
        self.mass_per_length = mass_per_length
        self.rotary_inertia_per_length = validation.positive("rotary_inertia_per_length", rotary_inertia_per_length)
        self.axial_force = axial_force
        self.loss_factor = loss_factor
        self.kelvin_voigt_time = kelvin_voigt_time
        self.viscous_damping = viscous_damping

    def transfer_matrix(self, s: Any) -> np.ndarray:
        """``U(s)``, shape ``np.shape(s) + (4, 4)`` (module docstring)."""
        s = laplace_array(s)
        L, EI = self.length, self.bending_stiffness
        factor = 1 + 1j * self.loss_factor * np.where(s.imag < 0, -1.0, 1.0) + self.kelvin_voigt_time * s
        A = np.zeros(s.shape + (4, 4), dtype=complex)
        A[..., 0, 1] = 1.0
        A[..., 1, 3] = -1.0 / factor
        A[..., 2, 0] = -(self.mass_per_length * s * s + self.viscous_damping * s) * L ** 4 / EI
        A[..., 3, 1] = -(self.axial_force + self.rotary_inertia_per_length * s * s) * L * L / EI
        A[..., 3, 2] = -1.0
        D = np.array([L, 1.0, EI / L ** 2, EI / L])
        return scipy.linalg.expm(A) * D[:, None] / D[None, :]

    def wave_number(self, omega_max: float) -> float:
        """``omega L sqrt(rho I / EI)``: the rotary inertia's tension parameter at ``omega_max`` [rad/s]."""
        return omega_max * self.length * math.sqrt(self.rotary_inertia_per_length / self.bending_stiffness)

    def clamped_frequency_count(self, omega: Any) -> np.ndarray:
        """Clamped-clamped natural frequencies strictly below ``omega`` [rad/s] (undamped; module docstring)."""
        omega = np.asarray(omega, dtype=float)
        if not np.all(np.isfinite(omega)) or np.any(omega < 0):
            raise ModelError(f"omega must be finite and >= 0 rad/s, got {omega!r}")
        flat = omega.reshape(-1)
        top = float(np.max(flat, initial=0.0))
        L, EI = self.length, self.bending_stiffness
        pieces = max(1, math.ceil(L * (self.mass_per_length * top ** 2 / EI) ** 0.25 / _COUNT_BETA),
                     math.ceil(self.wave_number(top) / _COUNT_ROTARY),
                     math.ceil(math.sqrt(abs(self.axial_force) / EI) * L / math.pi))
        if pieces == 1:
            return np.zeros(omega.shape, dtype=np.int64)
        piece = RayleighPlane(L / pieces, EI, self.mass_per_length, self.rotary_inertia_per_length,
                              axial_force=self.axial_force)
        U = np.real(piece.transfer_matrix(1j * flat))
        U11, U12, U21, U22 = U[:, :2, :2], U[:, :2, 2:], U[:, 2:, :2], U[:, 2:, 2:]
        X = np.linalg.inv(U12)                     # end forces on the piece: [F_in; F_out] = K [d_in; d_out]
        k_in, k_cross, k_out = -X @ U11, X, -U22 @ X
        n = 2 * (pieces - 1)
        G = np.zeros((flat.size, n, n))
        for node in range(pieces - 1):
            i = slice(2 * node, 2 * node + 2)
            G[:, i, i] += k_out + k_in
            if node + 1 < pieces - 1:
                j = slice(2 * node + 2, 2 * node + 4)
                G[:, i, j] += k_cross
                G[:, j, i] += np.swapaxes(k_cross, -1, -2)
        G = 0.5 * (G + np.swapaxes(G, -1, -2))
        return np.sum(np.linalg.eigvalsh(G) < 0, axis=-1).astype(np.int64).reshape(omega.shape)
