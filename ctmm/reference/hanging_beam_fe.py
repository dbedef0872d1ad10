"""Independent finite-element reference: a beam with a tip mass hanging (or standing) in gravity.

Shares no code with the transfer-matrix elements.  A uniform Euler-Bernoulli beam of length ``L``
along the gravity direction, rooted at ``x = 0`` (clamped, or pinned with a rotational spring
``k``), with a tip mass ``M`` and rotary inertia ``J`` at ``x = L``.  Gravity ``g`` [m/s^2] acts
along the beam (positive: from the root to the tip, a hanging beam; negative: standing); the
straight configuration is an equilibrium with the axial tension

    T(x) = g (M + rhoA (L - x))            [N]

Linearised transverse motion (Euler-Bernoulli, the standard second variation of the tension's
work ``1/2 int T w'^2 dx``): cubic Hermite elements (nodal ``w``, ``w'``), consistent mass,
bending stiffness and the consistent geometric stiffness ``int T(x) N'^T N' dx`` integrated by
three-point Gauss-Legendre (exact: the integrand is a polynomial of degree 5).  Frequencies from
``scipy.linalg.eigh(K, M)`` (conforming Rayleigh-Ritz: upper bounds, converging like ``h^4``);
receptances from ``(K - omega^2 M) x = f``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["HangingBeam"]

_GAUSS_POINTS, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(3)


def _hermite_slopes(xi: float, h: float) -> np.ndarray:
    """``dN/dx`` of the four cubic Hermite functions at ``xi = x / h`` in ``[0, 1]``."""
    return np.array([(-6 * xi + 6 * xi ** 2) / h, 1 - 4 * xi + 3 * xi ** 2,
                     (6 * xi - 6 * xi ** 2) / h, -2 * xi + 3 * xi ** 2])


@dataclass(frozen=True)
class HangingBeam:
    """Beam + tip mass in axial gravity (module docstring); all in SI units.

    ``root`` is ``"clamped"`` or ``"pinned"`` (then ``root_stiffness`` [N m/rad] acts on the root slope).
    """

    length: float
    bending_stiffness: float
    mass_per_length: float
    gravity: float
    tip_mass: float = 0.0
    tip_inertia: float = 0.0
    root: str = "clamped"
    root_stiffness: float = 0.0

    def tension(self, x: np.ndarray) -> np.ndarray:
        """Axial tension [N] at ``x`` [m]."""
        return self.gravity * (self.tip_mass + self.mass_per_length * (self.length - np.asarray(x)))

    def matrices(self, elements: int) -> tuple[np.ndarray, np.ndarray]:
        """Stiffness (bending + geometric) and mass matrices of the free DOFs."""
        h, EI, rho = self.length / elements, self.bending_stiffness, self.mass_per_length
        k = EI / h ** 3 * np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                                    [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h * h, -6 * h, 4 * h * h]])
        m = rho * h / 420 * np.array([[156, 22 * h, 54, -13 * h], [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                                      [54, 13 * h, 156, -22 * h], [-13 * h, -3 * h * h, -22 * h, 4 * h * h]])
        n = 2 * (elements + 1)
        K, M = np.zeros((n, n)), np.zeros((n, n))
        for e in range(elements):
            geometric = np.zeros((4, 4))
            for point, weight in zip(_GAUSS_POINTS, _GAUSS_WEIGHTS):
                xi = 0.5 * (point + 1)
                slopes = _hermite_slopes(xi, h)
                geometric += 0.5 * weight * h * float(self.tension((e + xi) * h)) * np.outer(slopes, slopes)
            dofs = slice(2 * e, 2 * e + 4)
            K[dofs, dofs] += k + geometric
            M[dofs, dofs] += m
        M[n - 2, n - 2] += self.tip_mass
        M[n - 1, n - 1] += self.tip_inertia
        if self.root == "clamped":
            keep = np.arange(2, n)
        elif self.root == "pinned":
            K[1, 1] += self.root_stiffness
            keep = np.arange(1, n)
        else:
            raise ValueError(f"root must be 'clamped' or 'pinned', got {self.root!r}")
        return K[np.ix_(keep, keep)], M[np.ix_(keep, keep)]

    def natural_frequencies(self, elements: int, count: int) -> np.ndarray:
        """Lowest ``count`` natural frequencies [rad/s] (all eigenvalues must be positive: a stable beam)."""
        K, M = self.matrices(elements)
        eigenvalues = scipy.linalg.eigh(K, M, eigvals_only=True)[:count]
        if eigenvalues[0] <= 0:
            raise ValueError(f"the straight configuration is unstable (lowest eigenvalue {eigenvalues[0]:.6g})")
        return np.sqrt(eigenvalues)

    def tip_receptance(self, elements: int, omega: np.ndarray) -> np.ndarray:
        """Tip deflection per unit tip transverse force [m/N] at ``omega`` [rad/s] (undamped)."""
        K, M = self.matrices(elements)
        f = np.zeros(K.shape[0])
        f[-2] = 1.0
        return np.array([np.linalg.solve(K - w * w * M, f)[-2] for w in np.atleast_1d(omega)])
