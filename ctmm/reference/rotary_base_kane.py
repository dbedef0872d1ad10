"""Independent Kane / assumed-modes model of a cantilever on a rotary base with a prescribed angle.

Seed 001 §9.4 (Figs. 9.20-9.24) checks the finite-segment transfer model of a plane-motion cantilever
on a rotary base against Kane's method.  This module is that Kane model, written without any code of
the planar model, of the finite-segment beam or of a sweep: an Euler-Bernoulli beam (``EI``, ``EA``,
``rhoA``, length ``L``) clamped at radius ``r_h`` on a hub whose angle ``theta(t)`` is prescribed.
Deformation (Kane, Ryan and Banerjee 1987, "stretch" formulation): the stretch ``s(x)`` and the
transverse displacement ``v(x)`` are the assumed-mode sums ``s = sum phi_i(x) a_i`` (clamped-free rod
modes ``sin((2i - 1) pi x / 2L)``) and ``v = sum psi_j(x) b_j`` (clamped-free bending modes, own
scaling of :func:`ctmm.reference.beams.clamped_free_mode`); a material point is at, in the hub frame::

    rho(x) = [r_h + x + s(x) - 1/2 int_0^x v'^2 dxi ,  v(x)]

(the foreshortening ``- 1/2 int v'^2`` gives the geometric (centrifugal) stiffening), strain energy
``1/2 int (EA s'^2 + EI v''^2) dx``.  With ``z = [a; b]``, ``P = d rho / dz`` and the hub's ``omega``,
``alpha`` the acceleration of a point is, in the hub frame,
``P z'' + [-b'^T H(x) b', 0] + 2 omega J P z' + alpha J rho - omega^2 rho`` (``H(x) = int_0^x psi' psi'^T``,
``J`` the +90 degree rotation).  Kane's equations with mass points at Gauss-Legendre stations::

    sum m_p P_p^T a_p + K z = 0,           drive moment  tau = J_hub alpha + sum m_p (J rho_p)^T a_p

(the hub's own mass is on the axis).  Outputs: transverse and longitudinal tip deformation
``v(L)``, ``s(L) - 1/2 int_0^L v'^2``, the drive moment and the prescribed angular velocity.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.integrate

from .beams import beta_roots, clamped_free_mode

__all__ = ["RotaryBaseBeam", "RotaryBaseHistory"]

_J = np.array([[0.0, -1.0], [1.0, 0.0]])


@dataclass(frozen=True)
class RotaryBaseHistory:
    """Histories on ``time`` [s]: ``transverse`` and ``longitudinal`` tip deformation [m] (hub frame),
    ``drive_moment`` [N m], ``angular_velocity`` [rad/s] and the modal coordinates ``z`` (T, n)."""

    time: np.ndarray
    transverse: np.ndarray
    longitudinal: np.ndarray
    drive_moment: np.ndarray
    angular_velocity: np.ndarray
    z: np.ndarray


class RotaryBaseBeam:
    """Kane model of a cantilever on a hub with a prescribed angle (module docstring).

    Parameters
    ----------
    length, bending_stiffness, axial_stiffness, mass_per_length : float
        ``L`` [m], ``EI`` [N m^2], ``EA`` [N], ``rhoA`` [kg/m].
    hub_radius, hub_inertia : float
        ``r_h`` [m] (clamp radius), ``J_hub`` [kg m^2] about the axis.
    rate, acceleration : callable
        Prescribed ``omega(t)`` [rad/s] and ``alpha(t)`` [rad/s^2].
    bending_modes, axial_modes : int
        Numbers of assumed modes.
    stations : int
        Gauss-Legendre mass points along the beam.
    """

    def __init__(self, *, length: float, bending_stiffness: float, axial_stiffness: float, mass_per_length: float,
                 hub_radius: float, hub_inertia: float, rate: Callable[[float], float],
                 acceleration: Callable[[float], float], bending_modes: int = 4, axial_modes: int = 3,
                 stations: int = 48) -> None:
        L = length
        self.length, self.hub_radius, self.hub_inertia = L, hub_radius, hub_inertia
        self.rate, self.acceleration = rate, acceleration
        gx, gw = np.polynomial.legendre.leggauss(stations)
        x, w = L * (gx + 1) / 2, L * gw / 2
        self.x, self.m = x, mass_per_length * w
        betas = beta_roots("clamped-free", bending_modes)
        psi = np.array([clamped_free_mode(b, x / L) for b in betas]).T                  # (P, nb)
        dpsi = np.array([clamped_free_mode(b, x / L, 1) / L for b in betas]).T
        d2psi = np.array([clamped_free_mode(b, x / L, 2) / L ** 2 for b in betas]).T
        k = (2 * np.arange(1, axial_modes + 1) - 1) * np.pi / (2 * L)
        phi, dphi = np.sin(np.outer(x, k)), np.cos(np.outer(x, k)) * k
        self.na, self.nb = axial_modes, bending_modes
        # H(x_p) = int_0^x_p psi' psi'^T by Gauss on [0, x_p]
        self.H = np.empty((stations, bending_modes, bending_modes))
        for p, xp in enumerate(x):
            xs, ws = xp * (gx + 1) / 2, xp * gw / 2
            d = np.array([clamped_free_mode(b, xs / L, 1) / L for b in betas]).T
            self.H[p] = np.einsum("q,qi,qj->ij", ws, d, d)
        self.H_tip = np.einsum("q,qi,qj->ij", w, dpsi, dpsi)
        self.phi, self.psi = phi, psi
        self.phi_tip = np.sin(k * L)
        self.psi_tip = np.array([clamped_free_mode(b, np.array(1.0)) for b in betas])
        n = axial_modes + bending_modes
        self.K = np.zeros((n, n))
        self.K[:axial_modes, :axial_modes] = axial_stiffness * np.einsum("p,pi,pj->ij", w, dphi, dphi)
        self.K[axial_modes:, axial_modes:] = bending_stiffness * np.einsum("p,pi,pj->ij", w, d2psi, d2psi)
        self.n = n

    def _terms(self, z: np.ndarray, zd: np.ndarray, t: float):
        a, b = z[:self.na], z[self.na:]
        bd = zd[self.na:]
        Hb = self.H @ b                                                             # (P, nb)
        rho = np.stack([self.hub_radius + self.x + self.phi @ a - 0.5 * Hb @ b, self.psi @ b], axis=1)   # (P, 2)
        P = np.zeros((len(self.x), 2, self.n))
        P[:, 0, :self.na], P[:, 0, self.na:], P[:, 1, self.na:] = self.phi, -Hb, self.psi
        omega, alpha = self.rate(t), self.acceleration(t)
        bias = np.zeros_like(rho)
        bias[:, 0] = -np.einsum("i,pij,j->p", bd, self.H, bd)
        bias += 2 * omega * (P @ zd) @ _J.T + alpha * rho @ _J.T - omega ** 2 * rho
        return rho, P, bias, alpha

    def accelerations(self, z: np.ndarray, zd: np.ndarray, t: float) -> np.ndarray:
        """``z''`` of the modal coordinates."""
        _, P, bias, _ = self._terms(z, zd, t)
        M = np.einsum("p,pik,pil->kl", self.m, P, P)
        return np.linalg.solve(M, -self.K @ z - np.einsum("p,pik,pi->k", self.m, P, bias))

    def drive_moment(self, z: np.ndarray, zd: np.ndarray, t: float) -> float:
        """Hub torque [N m] that keeps the prescribed motion."""
        zdd = self.accelerations(z, zd, t)
        rho, P, bias, alpha = self._terms(z, zd, t)
        acc = P @ zdd + bias                                                        # (P, 2) hub frame
        return float(self.hub_inertia * alpha + np.einsum("p,pi,pi->", self.m, rho @ _J.T, acc))

    def simulate(self, t_final: float, times: np.ndarray, rtol: float = 1e-10, atol: float = 1e-13
                 ) -> RotaryBaseHistory:
        """From the undeformed state at rest, DOP853 at ``times``."""
        n = self.n
        sol = scipy.integrate.solve_ivp(lambda t, y: np.concatenate([y[n:], self.accelerations(y[:n], y[n:], t)]),
                                        (0.0, t_final), np.zeros(2 * n), method="DOP853", t_eval=times,
                                        rtol=rtol, atol=atol)
        if not sol.success:
            raise RuntimeError(f"rotary-base Kane reference failed: {sol.message}")
        z, zd = sol.y[:n].T, sol.y[n:].T
        b = z[:, self.na:]
        return RotaryBaseHistory(
            time=sol.t, transverse=b @ self.psi_tip,
            longitudinal=z[:, :self.na] @ self.phi_tip - 0.5 * np.einsum("ki,ij,kj->k", b, self.H_tip, b),
            drive_moment=np.array([self.drive_moment(z[k], zd[k], t) for k, t in enumerate(sol.t)]),
            angular_velocity=np.array([self.rate(t) for t in sol.t]), z=z)
