"""Bending of a beam element with shear deformation and rotary inertia (Timoshenko), for the planar and the
spatial beam elements (:class:`ctmm.fem.BeamElement`, :class:`ctmm.fem.SpatialBeamElement`).

One bending plane, element DOFs ``d = [v_a, theta_a, v_b, theta_b]`` (deflection [m] and section rotation
[rad] at the ends; the section rotation is the slope ``v'`` only without shear).  Interdependent
interpolation (the exact static solution of the Timoshenko beam for end values; Friedman and Kosmatka,
Computers & Structures 47, 1993), with ``xi = x / L`` and the shear parameter
``phi = 12 EI / (kappa G A L^2)``::

    v     = [1 - 3 xi^2 + 2 xi^3 + phi (1 - xi),  L (xi - 2 xi^2 + xi^3 + phi (xi - xi^2) / 2),
             3 xi^2 - 2 xi^3 + phi xi,            L (-xi^2 + xi^3 - phi (xi - xi^2) / 2)] d / (1 + phi)
    theta = [6 (xi^2 - xi) / L,  1 - 4 xi + 3 xi^2 + phi (1 - xi),  6 (xi - xi^2) / L,
             -2 xi + 3 xi^2 + phi xi] d / (1 + phi)

(``phi = 0``: the Hermite cubic and its slope).  The shear strain ``gamma = v' - theta`` is constant on
the element.  Strain energy ``1/2 int (EI theta'^2 + kappa G A gamma^2) dx``, kinetic energy
``1/2 int (rho A v_dot^2 + rho I theta_dot^2) dx``, geometric stiffness ``N int v'^2 dx``: all by five-point
Gauss quadrature, exact (polynomials of degree <= 6).  The stiffness is exact for end loads at any
``phi``; the frequencies converge at ``O(h^2)`` like the Euler-Bernoulli element (``docs/mixed.md`` §7c).
"""
from __future__ import annotations

import numpy as np

from .. import validation

__all__ = ["shear_parameter", "bending_shapes", "bending_matrices"]

_X, _W = np.polynomial.legendre.leggauss(5)
_XI, _WEIGHT = 0.5 * (_X + 1.0), 0.5 * _W


def shear_parameter(owner: str, bending_stiffness: float, shear_stiffness: float | None, length: float) -> float:
    """``phi = 12 EI / (kappa G A L^2)`` [-]; 0 without shear deformation (``shear_stiffness`` None)."""
    if shear_stiffness is None:
        return 0.0
    return 12.0 * bending_stiffness / (validation.positive(f"{owner}: shear_stiffness", shear_stiffness) * length ** 2)


def bending_shapes(xi: np.ndarray, length: float, phi: float) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                        np.ndarray]:
    """Rows over ``[v_a, theta_a, v_b, theta_b]`` at ``xi`` (P,): deflection ``v``, slope ``v'`` [1/m],
    section rotation ``theta`` and its derivative ``theta'`` [1/m], each (P, 4) (module docstring)."""
    x = np.asarray(xi, dtype=float)
    L, f = length, 1.0 / (1.0 + phi)
    v = f * np.stack([1 - 3 * x ** 2 + 2 * x ** 3 + phi * (1 - x), L * (x - 2 * x ** 2 + x ** 3 + phi * (x - x ** 2) / 2),
                      3 * x ** 2 - 2 * x ** 3 + phi * x, L * (-x ** 2 + x ** 3 - phi * (x - x ** 2) / 2)], -1)
    slope = f * np.stack([(-6 * x + 6 * x ** 2 - phi) / L, 1 - 4 * x + 3 * x ** 2 + phi * (1 - 2 * x) / 2,
                          (6 * x - 6 * x ** 2 + phi) / L, -2 * x + 3 * x ** 2 - phi * (1 - 2 * x) / 2], -1)
    theta = f * np.stack([6 * (x ** 2 - x) / L, 1 - 4 * x + 3 * x ** 2 + phi * (1 - x), 6 * (x - x ** 2) / L,
                          -2 * x + 3 * x ** 2 + phi * x], -1)
    curvature = f * np.stack([(12 * x - 6) / L ** 2, (-4 + 6 * x - phi) / L, (6 - 12 * x) / L ** 2,
                              (-2 + 6 * x + phi) / L], -1)
    return v, slope, theta, curvature


def bending_matrices(length: float, bending_stiffness: float, shear_stiffness: float | None, mass_per_length: float,
                     rotary_inertia_per_length: float, axial_force: float, owner: str = "beam"
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(K, M, K_G)`` (4 x 4) over ``[v_a, theta_a, v_b, theta_b]`` of one bending plane (module docstring).

    Parameters
    ----------
    length : float
        ``L`` [m].
    bending_stiffness : float
        ``EI`` [N m^2].
    shear_stiffness : float or None
        ``kappa G A`` [N]; None: no shear deformation (Euler-Bernoulli).
    mass_per_length, rotary_inertia_per_length : float
        ``rho A`` [kg/m], ``rho I`` [kg m].
    axial_force : float
        ``N`` [N] (tension > 0).
    owner : str
        Name used in error messages.
    """
    phi = shear_parameter(owner, bending_stiffness, shear_stiffness, length)
    v, slope, theta, curvature = bending_shapes(_XI, length, phi)
    w = _WEIGHT * length
    K = bending_stiffness * np.einsum("p,pk,pl->kl", w, curvature, curvature)
    if shear_stiffness is not None:
        gamma = slope - theta
        K += shear_stiffness * np.einsum("p,pk,pl->kl", w, gamma, gamma)
    M = mass_per_length * np.einsum("p,pk,pl->kl", w, v, v) + \
        rotary_inertia_per_length * np.einsum("p,pk,pl->kl", w, theta, theta)
    G = axial_force * np.einsum("p,pk,pl->kl", w, slope, slope)
    return K, M, G
