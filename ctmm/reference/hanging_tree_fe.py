"""Independent finite-element reference: a tree of parallel beams hanging (or standing) in gravity, one bending plane.

Shares no code with the transfer-matrix elements or with ctmm's exact-field bridge.  Every beam of the
tree lies along the gravity direction; the root beam is clamped at its ``x = 0``; every other beam is
welded, parallel, at a station ``at`` of its parent (the same deflection ``w`` and slope ``w'`` there); a
body whose centre is at a beam's tip (mass ``tip_mass``, rotary inertia ``tip_inertia`` about the
bending axis) may sit there.  Gravity ``g`` [m/s^2] acts along the beams (positive: from the root
towards the tips, a hanging tree; negative: standing).  The straight tree is an equilibrium; its axial
tension follows from statics alone: at ``x`` on a beam it carries the weight of everything hung below
``x`` on that beam,

    T(x) = g (rhoA (L - x) + tip_mass + sum over the children at stations a > x of their whole mass)   [N]

Linearised bending in one plane (Euler-Bernoulli; the second variation of the tension's work ``1/2 int T
w'^2 dx``): cubic Hermite elements (nodal ``w``, ``w'``), consistent mass, bending stiffness and the
consistent geometric stiffness ``int T(x) N'^T N' dx``, all integrated by four-point Gauss-Legendre (exact:
polynomials of degree <= 6; ``T`` is linear on every element because every element lies between two
stations).  Frequencies from ``scipy.linalg.eigh(K, M)`` (conforming Rayleigh-Ritz: upper bounds,
converging like ``h^4``), solved inverted for accuracy at the low end
(:meth:`HangingTree.natural_frequencies`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.linalg

__all__ = ["TreeBeam", "HangingTree"]

_GAUSS_POINTS, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(4)


@dataclass(frozen=True)
class TreeBeam:
    """One beam of the tree, SI units; ``parent`` ``None`` for the root beam (clamped), otherwise the name of
    the beam it is welded to at the station ``at`` [m] of that beam."""

    name: str
    length: float
    bending_stiffness: float
    mass_per_length: float
    parent: str | None = None
    at: float = 0.0
    tip_mass: float = 0.0
    tip_inertia: float = 0.0


def _hermite(xi: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Values and ``d/dx`` of the four cubic Hermite functions at ``xi = x / h``."""
    values = np.array([1 - 3 * xi ** 2 + 2 * xi ** 3, h * (xi - 2 * xi ** 2 + xi ** 3), 3 * xi ** 2 - 2 * xi ** 3,
                       h * (-xi ** 2 + xi ** 3)])
    slopes = np.array([(-6 * xi + 6 * xi ** 2) / h, 1 - 4 * xi + 3 * xi ** 2, (6 * xi - 6 * xi ** 2) / h,
                       -2 * xi + 3 * xi ** 2])
    return values, slopes


@dataclass(frozen=True)
class HangingTree:
    """Parallel beams along gravity ``gravity`` [m/s^2] (module docstring); ``beams`` parents first."""

    beams: Sequence[TreeBeam]
    gravity: float

    def mass(self, name: str) -> float:
        """Whole mass [kg] of beam ``name`` with its tip body and everything hung on it."""
        beam = next(b for b in self.beams if b.name == name)
        return beam.mass_per_length * beam.length + beam.tip_mass + sum(
            self.mass(b.name) for b in self.beams if b.parent == name)

    def tension(self, name: str, x: float) -> float:
        """Tension [N] at ``x`` [m] on beam ``name`` (between stations)."""
        beam = next(b for b in self.beams if b.name == name)
        hung = sum(self.mass(b.name) for b in self.beams if b.parent == name and b.at > x)
        return self.gravity * (beam.mass_per_length * (beam.length - x) + beam.tip_mass + hung)

    def matrices(self, elements: int) -> tuple[np.ndarray, np.ndarray]:
        """Stiffness (bending + geometric) and mass of the free DOFs, ``elements`` per piece between stations."""
        dofs = 0
        nodes: dict[tuple[str, float], int] = {}
        blocks = []
        for beam in self.beams:
            stations = sorted({0.0, beam.length} | {b.at for b in self.beams if b.parent == beam.name})
            if beam.parent is None:
                nodes[(beam.name, 0.0)], dofs = dofs, dofs + 2
            else:
                nodes[(beam.name, 0.0)] = nodes[(beam.parent, beam.at)]
            first = nodes[(beam.name, 0.0)]
            for start, end in zip(stations[:-1], stations[1:]):
                h = (end - start) / elements
                for e in range(elements):
                    left = first if e == 0 and start == 0.0 else previous
                    previous, dofs = dofs, dofs + 2
                    x0 = start + e * h
                    tension = [self.tension(beam.name, x0 + h * (1 + p) / 2) for p in _GAUSS_POINTS]
                    blocks.append((beam, h, [left, left + 1, previous, previous + 1], tension))
                nodes[(beam.name, end)] = previous
            blocks.append((beam, None, [previous, previous + 1], None))
        K, M = np.zeros((dofs, dofs)), np.zeros((dofs, dofs))
        for beam, h, index, tension in blocks:
            at = np.ix_(index, index)
            if h is None:                              # the tip body
                M[at] += np.diag([beam.tip_mass, beam.tip_inertia])
                continue
            for p, weight, T in zip(_GAUSS_POINTS, _GAUSS_WEIGHTS, tension):
                xi = (1 + p) / 2
                N, dN = _hermite(xi, h)
                d2N = np.array([(-6 + 12 * xi) / h ** 2, (-4 + 6 * xi) / h, (6 - 12 * xi) / h ** 2, (-2 + 6 * xi) / h])
                K[at] += 0.5 * h * weight * (beam.bending_stiffness * np.outer(d2N, d2N) + T * np.outer(dN, dN))
                M[at] += 0.5 * h * weight * beam.mass_per_length * np.outer(N, N)
        return K[2:, 2:], M[2:, 2:]                    # the root's w and w' held (clamped)

    def natural_frequencies(self, elements: int, count: int) -> np.ndarray:
        """Lowest ``count`` natural frequencies [rad/s] of a statically stable tree (positive definite ``K``).

        Solved inverted, ``M x = mu (K + sigma M) x`` with ``mu = 1 / (omega^2 + sigma)`` and a small shift
        ``sigma``: the low frequencies are then resolved to round-off relative to themselves (the direct
        ``eigh(K, M)`` resolves them only relative to the highest element frequency, ~1e-5 at 32 elements)."""
        K, M = self.matrices(elements)
        shift = 1e-6 * np.trace(K) / np.trace(M)
        mu = scipy.linalg.eigh(M, K + shift * M, eigvals_only=True)
        return np.sqrt(1.0 / np.sort(mu)[::-1][:count] - shift)
