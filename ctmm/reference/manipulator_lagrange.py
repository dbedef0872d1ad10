"""Independent reference for the controlled flexible manipulator: assumed modes + Lagrange.

No transfer matrices: the hub angle ``theta`` and the amplitudes ``eta_k`` of the first ``N``
clamped-free modes of the arm (floating frame attached to the hub) are the coordinates; the
equations come from the kinetic and strain energies; ``scipy.integrate.solve_ivp`` integrates
them at tight tolerance (method of steps for delayed loops).  Only plain numbers are read from
the parameter objects.

Model (``docs/manipulator.md`` §3)
----------------------------------
Arm point at ``x`` (from the clamp, hub radius ``r``): position ``R(theta) [r + x + u_x, u]``,
``u = sum_k phi_k(x) eta_k``, foreshortening ``u_x = -1/2 int_0^x u'^2`` (only with
``stiffening=True``).  Mass-normalised modes (``int rho A phi_k phi_l = delta_kl``,
``int EI phi_k'' phi_l'' = omega_k^2 delta_kl``).  To second order in the deformation

    T = 1/2 (J0 + eta^T A eta) theta_dot^2 + theta_dot a^T eta_dot + 1/2 eta_dot^T eta_dot
    V = 1/2 eta^T K eta,   K = diag(omega_k^2),   D = tau_d K (Kelvin-Voigt),
    J0 = J_h + rho A ((r + L)^3 - r^3)/3,  a_k = int rho A (r + x) phi_k dx,
    A = I - K_G (stiffening) or I,  K_G,kl = int_0^L N(x) phi_k' phi_l' dx,
    N(x) = rho A [r (L - x) + (L^2 - x^2)/2]     (centrifugal tension per theta_dot^2)

Lagrange's equations:

    (J0 + eta^T A_h eta) theta_ddot + a^T eta_ddot + 2 theta_dot eta^T A_h eta_dot = tau
    a theta_ddot + eta_ddot + D eta_dot + K eta - theta_dot^2 A eta = c_a Psi^T V

(``A_h = A`` with ``consistent_inertia``, else ``I``: the usual first-order consistent model
keeps the stiffening only in the modal equations.)

with the PZT moment pairs' generalised forces ``Psi_jk = phi_k'(x2_j) - phi_k'(x1_j)``.
Controls: ``tau = kp (theta_d - theta)(t - tau_p) + kd (theta_d_dot - theta_dot)(t - tau_p)``
(seed eq. (9.64)), ``V = -G dtheta_dot(t - tau_a)`` with the sensed slope-rate differences
``dtheta_dot = Psi eta_dot`` (seed eq. (9.65) is ``G = diag(Ka_i)``) or ``V = -Ka eta_dot`` on
the first modal velocities, optionally saturated at ``+-V_max``.

Frequency domain: the linearisation about rest (``theta_dot = 0``, ``eta = 0``) in modal form,
and an exact-in-the-limit *port* form with the static (residual-flexibility) correction of
the truncated modes, which converges like ``N^-5`` instead of ``N^-1`` for moment pairs.

Mode shapes (``xi = x/L``, ``beta_k`` roots of ``1 + cos b cosh b = 0``), evaluated without
cancellation for any ``k``:  ``s(xi) = cosh - cos - sigma (sinh - sin)`` written as
``E1 e^{beta (xi - 1)} + E2 e^{-beta xi} - cos(beta xi) + sigma sin(beta xi)``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.integrate
import scipy.optimize

__all__ = ["clamped_free_beta", "ClampedFreeModes", "ManipulatorLagrange", "ReferenceSimulation"]


# --------------------------------------------------------------------------------------- modes
def clamped_free_beta(n: int) -> np.ndarray:
    """First ``n`` roots of ``1 + cos b cosh b = 0`` (as ``cos b + sech b = 0``, Brent in ``[(k-1) pi, k pi]``)."""
    def f(b: float) -> float:
        return math.cos(b) + 2.0 * math.exp(-b) / (1.0 + math.exp(-2.0 * b))

    out = np.empty(n)
    for k in range(1, n + 1):
        lo, hi = (k - 1) * math.pi + 1e-9, k * math.pi
        out[k - 1] = scipy.optimize.brentq(f, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)
    return out


class ClampedFreeModes:
    """Mass-normalised clamped-free modes ``phi_k(x)`` of a uniform arm (k = 1..n).

    Parameters
    ----------
    n : int
        Number of modes.
    length, bending_stiffness, mass_per_length : float
        ``L`` [m], ``EI`` [N m^2], ``rho A`` [kg/m].
    """

    def __init__(self, n: int, length: float, bending_stiffness: float, mass_per_length: float) -> None:
        self.n = int(n)
        self.L, self.EI, self.rhoA = float(length), float(bending_stiffness), float(mass_per_length)
        b = clamped_free_beta(self.n)
        self.beta = b
        e = np.exp(-b)
        den = 1.0 - e * e + 2.0 * np.sin(b) * e
        self.sigma = (1.0 + e * e + 2.0 * np.cos(b) * e) / den
        self.E1 = (np.sin(b) - np.cos(b) - e) / den
        self.E2 = 0.5 * (1.0 + self.sigma)
        self.omega = b ** 2 * math.sqrt(self.EI / (self.rhoA * self.L ** 4))
        self.scale = 1.0 / math.sqrt(self.rhoA * self.L)

    def evaluate(self, x, derivative: int = 0) -> np.ndarray:
        """``d^m phi_k / dx^m`` at ``x`` [m]: array ``x.shape + (n,)``."""
        xi = np.asarray(x, dtype=float)[..., None] / self.L
        b = self.beta
        bx = b * xi
        m = derivative
        hyper = self.E1 * np.exp(b * (xi - 1.0)) + (-1.0) ** m * self.E2 * np.exp(-bx)
        trig = -np.cos(bx + m * math.pi / 2) + self.sigma * np.sin(bx + m * math.pi / 2)
        return self.scale * (b / self.L) ** m * (hyper + trig)


# ----------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class ReferenceSimulation:
    """Time histories of the reference (arrays over ``t``).

    ``theta`` [rad], ``theta_dot`` [rad/s], ``eta``/``eta_dot`` (``(nt, N)``), ``tip_deflection``
    ``u(L)`` [m] in the hub frame, ``voltages`` ``(nt, P)`` [V] (after saturation),
    ``hub_torque`` [N m], ``saturated`` (True where any patch is at its limit).
    """

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    eta: np.ndarray
    eta_dot: np.ndarray
    tip_deflection: np.ndarray
    voltages: np.ndarray
    hub_torque: np.ndarray
    saturated: np.ndarray
    nfev: int


def _gauss(a: float, b: float, n: int = 12):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (b - a) * x + 0.5 * (b + a), 0.5 * (b - a) * w


# --------------------------------------------------------------------------------- the model
class ManipulatorLagrange:
    """Assumed-modes Lagrange model of hub + arm + PZT moment pairs.

    Parameters
    ----------
    n_modes : int
        Number of clamped-free modes ``N``.
    hub_inertia, hub_radius : float
        ``J_h`` [kg m^2] about the pivot, ``r`` [m] pivot-to-clamp distance.
    length, bending_stiffness, mass_per_length : float
        Arm ``L`` [m], ``EI`` [N m^2], ``rho A`` [kg/m].
    kelvin_voigt_time : float
        ``tau_d`` [s]: modal damping ``D = tau_d K``.
    patch_ends : array (P, 2)
        ``[x1, x2]`` of every patch [m].
    moments_per_volt : array (P,)
        ``c_a`` [N m/V].
    stiffening : bool
        Centrifugal stiffening in the modal equations (``-theta_dot^2 (I - K_G) eta``).
    consistent_inertia : bool
        Also use ``A = I - K_G`` in the hub inertia and Coriolis terms (all second-order terms of
        ``T`` with foreshortening, i.e. exactly Lagrange's equations of the energies above); with
        ``False`` the hub equation keeps ``A = I`` (the usual first-order consistent model, and
        the one of :class:`ctmm.flexible.ModalBeam`).
    """

    def __init__(self, n_modes: int, *, hub_inertia: float, hub_radius: float, length: float,
                 bending_stiffness: float, mass_per_length: float, kelvin_voigt_time: float = 0.0,
                 patch_ends=(), moments_per_volt=(), stiffening: bool = False,
                 consistent_inertia: bool = False) -> None:
        self.N = int(n_modes)
        self.Jh, self.r = float(hub_inertia), float(hub_radius)
        self.L, self.EI, self.rhoA = float(length), float(bending_stiffness), float(mass_per_length)
        self.tau_d = float(kelvin_voigt_time)
        self.patch_ends = np.asarray(patch_ends, dtype=float).reshape(-1, 2)
        self.ca = np.asarray(moments_per_volt, dtype=float).reshape(-1)
        self.P = self.patch_ends.shape[0]
        if self.ca.size != self.P:
            raise ValueError("one moment per volt per patch")
        self.stiffening = bool(stiffening)
        self.consistent_inertia = bool(consistent_inertia)
        modes = ClampedFreeModes(self.N, self.L, self.EI, self.rhoA)
        self.modes = modes
        r, L, rhoA = self.r, self.L, self.rhoA
        self.J0 = self.Jh + rhoA * ((r + L) ** 3 - r ** 3) / 3.0
        # a_k = int rho A (r + x) phi_k dx = rho A (L/beta)^4 (phi''(0) - r phi'''(0))  (phi'''' = (beta/L)^4 phi)
        self.a = rhoA * (L / modes.beta) ** 4 * (modes.evaluate(0.0, 2) - r * modes.evaluate(0.0, 3))
        self.omega = modes.omega
        self.K = np.diag(self.omega ** 2)
        self.D = self.tau_d * self.K
        self.Psi = (modes.evaluate(self.patch_ends[:, 1], 1) - modes.evaluate(self.patch_ends[:, 0], 1)
                    ).reshape(self.P, self.N)
        self.phi_tip = modes.evaluate(L, 0)
        self.KG = self._geometric_stiffness() if self.stiffening else np.zeros((self.N, self.N))
        self.A = np.eye(self.N) - self.KG                  # modal equations
        self.A_hub = self.A if self.consistent_inertia else np.eye(self.N)

    @classmethod
    def from_manipulator(cls, manipulator, n_modes: int, *, stiffening: bool = False,
                         consistent_inertia: bool = False) -> "ManipulatorLagrange":
        """Read the plain numbers of a :class:`ctmm.manipulator.Manipulator`."""
        arm, hub = manipulator.arm, manipulator.hub
        return cls(n_modes, hub_inertia=hub.inertia, hub_radius=hub.radius, length=arm.length,
                   bending_stiffness=arm.youngs_modulus * arm.width * arm.thickness ** 3 / 12.0,
                   mass_per_length=arm.density * arm.width * arm.thickness,
                   kelvin_voigt_time=arm.kelvin_voigt_time,
                   patch_ends=[[p.start, p.end] for p in manipulator.patches],
                   moments_per_volt=[-p.material.youngs_modulus * p.material.d31
                                     * (arm.width if p.width is None else p.width)
                                     * (arm.thickness + p.thickness) / 2.0 for p in manipulator.patches],
                   stiffening=stiffening, consistent_inertia=consistent_inertia)

    def _geometric_stiffness(self) -> np.ndarray:
        cells = max(8, 4 * self.N)
        edges = np.linspace(0.0, self.L, cells + 1)
        KG = np.zeros((self.N, self.N))
        for a, b in zip(edges[:-1], edges[1:]):
            x, w = _gauss(a, b, 16)
            d1 = self.modes.evaluate(x, 1)
            Nx = self.rhoA * (self.r * (self.L - x) + 0.5 * (self.L ** 2 - x ** 2))
            KG += (d1 * (w * Nx)[:, None]).T @ d1
        return 0.5 * (KG + KG.T)

    # ------------------------------------------------------------------------- dynamics
    def mass_matrix(self, eta) -> np.ndarray:
        """``M(eta)`` of ``[theta, eta]``."""
        eta = np.asarray(eta, dtype=float)
        M = np.empty((self.N + 1, self.N + 1))
        M[0, 0] = self.J0 + eta @ self.A_hub @ eta
        M[0, 1:] = self.a
        M[1:, 0] = self.a
        M[1:, 1:] = np.eye(self.N)
        return M

    def accelerations(self, theta_dot: float, eta, eta_dot, torque: float, voltages=()) -> np.ndarray:
        """``[theta_ddot, eta_ddot]`` for given hub torque [N m] and patch voltages [V]."""
        eta = np.asarray(eta, dtype=float)
        eta_dot = np.asarray(eta_dot, dtype=float)
        V = np.asarray(voltages, dtype=float).reshape(-1) if self.P else np.zeros(0)
        Aeta = self.A @ eta
        Heta = self.A_hub @ eta
        r0 = torque - 2.0 * theta_dot * (Heta @ eta_dot)
        r1 = (-self.D @ eta_dot - self.K @ eta + theta_dot ** 2 * Aeta
              + (self.Psi.T @ (self.ca * V) if self.P else 0.0))
        # M = [[J0 + eta^T A_hub eta, a^T], [a, I]]: eliminate eta_ddot = r1 - a theta_ddot (Schur complement)
        thdd = (r0 - self.a @ r1) / (self.J0 + eta @ Heta - self.a @ self.a)
        out = np.empty(self.N + 1)
        out[0] = thdd
        out[1:] = r1 - self.a * thdd
        return out

    def clamp_load(self, theta_dot: float, eta, eta_dot, accelerations) -> np.ndarray:
        """Force and moment exerted by the hub on the arm at the clamp, hub-frame axes
        ``[f_axial, f_transverse, moment]`` [N, N, N m] (Newton-Euler of the whole arm).

        Arm point ``p = (r + x, u)`` in hub axes; its acceleration in hub axes is
        ``a = (-2 w u_dot - theta_ddot u - w^2 (r + x),  u_ddot + theta_ddot (r + x) - w^2 u)``;
        the PZT pairs are internal, so ``f = int rho A a``; moments about the fixed pivot give
        ``M_c = int rho A p x a - r f_Y = a^T eta_ddot + theta_ddot (J_a + eta^T eta)
        + 2 w eta^T eta_dot - r f_Y``.  The kinematics ``p = (r + x, u)`` are the model's (the
        stiffening of the modal equations changes ``eta_ddot``, not this balance); with
        ``consistent_inertia`` the second-order foreshortening terms would be missing, so that
        option is refused.
        """
        if self.consistent_inertia:
            raise ValueError("clamp_load has no foreshortening terms: not for consistent_inertia=True")
        eta, eta_dot = np.asarray(eta, float), np.asarray(eta_dot, float)
        thdd, etadd = float(accelerations[0]), np.asarray(accelerations[1:], float)
        w = float(theta_dot)
        S1 = self.rhoA * ((self.r + self.L) ** 2 - self.r ** 2) / 2.0      # int rho A (r + x)
        Ja = self.J0 - self.Jh                                              # int rho A (r + x)^2
        mphi = self.modal_mass_moments()                                    # int rho A phi_k
        fX = -2.0 * w * (mphi @ eta_dot) - thdd * (mphi @ eta) - w ** 2 * S1
        fY = mphi @ etadd + thdd * S1 - w ** 2 * (mphi @ eta)
        Mc = self.a @ etadd + thdd * (Ja + eta @ eta) + 2.0 * w * (eta @ eta_dot) - self.r * fY
        return np.array([fX, fY, Mc])

    def modal_mass_moments(self) -> np.ndarray:
        """``int rho A phi_k dx = -rho A (L/beta_k)^4 phi_k'''(0)`` (as ``phi'''' = (beta/L)^4 phi``)."""
        return -self.rhoA * (self.L / self.modes.beta) ** 4 * self.modes.evaluate(0.0, 3)

    def quadrature(self, f: Callable) -> np.ndarray:
        """``int_0^L f(x) dx`` by composite Gauss-Legendre (``f`` maps ``x (m,)`` to ``(m, ...)``)."""
        cells = max(8, 4 * self.N)
        edges = np.linspace(0.0, self.L, cells + 1)
        total = 0.0
        for a, b in zip(edges[:-1], edges[1:]):
            x, w = _gauss(a, b, 16)
            total = total + np.tensordot(w, f(x), axes=(0, 0))
        return np.asarray(total)

    # -------------------------------------------------------------------------- simulation
    def voltages_from(self, eta_dot, gains, *, sensing: str = "slopes") -> np.ndarray:
        """``V = -G Psi eta_dot`` (``"slopes"``) or ``V = -Ka eta_dot[:n]`` (``"modal"``)."""
        eta_dot = np.asarray(eta_dot, dtype=float)
        G = np.asarray(gains, dtype=float)
        if sensing == "slopes":
            return -G @ (self.Psi @ eta_dot)
        if sensing == "modal":
            return -G @ eta_dot[: G.shape[1]]
        raise ValueError(f"sensing must be 'slopes' or 'modal', got {sensing!r}")

    def simulate(self, t_final: float, *, reference=None, kp: float = 0.0, kd: float = 0.0,
                 pd_delay: float = 0.0, pzt_gains=None, pzt_delay: float = 0.0, sensing: str = "slopes",
                 voltage_limit: float | None = None, torque: Callable | None = None,
                 theta0: float = 0.0, eta0=None, theta_dot0: float = 0.0, eta_dot0=None,
                 t_eval=None, rtol: float = 1e-11, atol: float = 1e-13, method: str = "DOP853",
                 breakpoints=()) -> ReferenceSimulation:
        """Integrate the closed loop from rest/given state over ``[0, t_final]``.

        Parameters
        ----------
        reference : object with ``angle(t)``, ``rate(t)`` or None
            Desired hub angle ``theta_d`` (None: 0).
        kp, kd : float
            PD gains [N m/rad, N m s/rad].
        pd_delay, pzt_delay : float
            Loop delays [s] (history before 0 = the initial state held, ``theta_d(t<0) = theta_d(0)``).
        pzt_gains : array (P, P) or (P, n) or None
            ``G`` (``sensing="slopes"``) or ``Ka`` (``"modal"``) [V s/rad or V per modal velocity].
        voltage_limit : float or None
            Saturate ``|V|`` at this value [V] (None: no saturation).
        torque : callable or None
            Extra open-loop hub torque ``torque(t)`` [N m].
        t_eval : array or None
            Output times (default 1001 points).
        """
        N, P = self.N, self.P
        ref_angle = (lambda t: 0.0) if reference is None else reference.angle
        ref_rate = (lambda t: 0.0) if reference is None else reference.rate
        G = np.zeros((P, N if sensing == "modal" else P)) if pzt_gains is None else np.asarray(pzt_gains, float)
        y0 = np.zeros(2 * N + 2)
        y0[0] = theta0
        y0[N + 1] = theta_dot0
        if eta0 is not None:
            y0[1:N + 1] = eta0
        if eta_dot0 is not None:
            y0[N + 2:] = eta_dot0
        extra = torque or (lambda t: 0.0)
        segments: list = []    # (t_start, t_end, dense solution)

        def history(t: float) -> np.ndarray:
            if t <= 0.0:
                return y0
            for ta, tb, sol in reversed(segments):
                if ta <= t <= tb + 1e-15:
                    return sol(min(t, tb))
            raise RuntimeError(f"no history at t = {t}")  # pragma: no cover

        def controls(t: float, y: np.ndarray):
            yp = y if pd_delay == 0.0 else history(t - pd_delay)
            tp = max(t - pd_delay, 0.0)
            tau = kp * (ref_angle(tp) - yp[0]) + kd * (ref_rate(tp) - yp[N + 1]) + extra(t)
            if P:
                ya = y if pzt_delay == 0.0 else history(t - pzt_delay)
                V = self.voltages_from(ya[N + 2:], G, sensing=sensing)
                if voltage_limit is not None:
                    V = np.clip(V, -voltage_limit, voltage_limit)
            else:
                V = np.zeros(0)
            return tau, V

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            tau, V = controls(t, y)
            acc = self.accelerations(y[N + 1], y[1:N + 1], y[N + 2:], tau, V)
            return np.concatenate([y[N + 1:], acc])

        cuts = {0.0, float(t_final)}
        for tau in (pd_delay, pzt_delay):
            if tau > 0.0:
                cuts.update(np.arange(tau, t_final, tau).tolist())
        cuts.update(float(b) for b in breakpoints if 0.0 < b < t_final)
        if reference is not None:
            t0 = getattr(reference, "start_time", None)
            T = getattr(reference, "duration", None)
            if t0 is not None and T is not None:
                for b in (t0, t0 + T, t0 + pd_delay, t0 + T + pd_delay):
                    if 0.0 < b < t_final:
                        cuts.add(float(b))
        cuts = sorted(cuts)
        y = y0.copy()
        nfev = 0
        for ta, tb in zip(cuts[:-1], cuts[1:]):
            if tb - ta <= 1e-14:
                continue
            sol = scipy.integrate.solve_ivp(rhs, (ta, tb), y, method=method, rtol=rtol, atol=atol,
                                            dense_output=True)
            if not sol.success:
                raise RuntimeError(f"reference integration failed at t = {sol.t[-1]}: {sol.message}")
            nfev += sol.nfev
            segments.append((ta, tb, sol.sol))
            y = sol.y[:, -1]
        t_out = np.linspace(0.0, t_final, 1001) if t_eval is None else np.asarray(t_eval, dtype=float)
        Y = np.array([history(t) if t > 0 else y0 for t in t_out])
        taus, Vs = [], []
        for t, yy in zip(t_out, Y):
            tau, V = controls(t, yy)
            taus.append(tau)
            Vs.append(V)
        Vs = np.array(Vs).reshape(len(t_out), P)
        sat = (np.any(np.abs(Vs) >= voltage_limit * (1 - 1e-12), axis=1) if (voltage_limit is not None and P)
               else np.zeros(len(t_out), bool))
        return ReferenceSimulation(t=t_out, theta=Y[:, 0], theta_dot=Y[:, N + 1], eta=Y[:, 1:N + 1],
                                   eta_dot=Y[:, N + 2:], tip_deflection=Y[:, 1:N + 1] @ self.phi_tip,
                                   voltages=Vs, hub_torque=np.array(taus), saturated=sat, nfev=nfev)

    # -------------------------------------------------------------------- linearisation
    def linearize(self):
        """``M, D, K`` of ``[theta, eta]`` about rest and the input matrices.

        Returns
        -------
        dict with ``M, D, K`` ((N+1)^2), ``B_torque`` (N+1,), ``B_voltage`` ((N+1, P): ``c_a Psi^T``),
        ``C_slopes`` ((P, N+1): ``dtheta = C q``), ``C_tip`` ((N+1,): ``u(L) = C q``).
        """
        n = self.N + 1
        M = self.mass_matrix(np.zeros(self.N))
        K = np.zeros((n, n))
        K[1:, 1:] = self.K
        D = np.zeros((n, n))
        D[1:, 1:] = self.D
        Bt = np.zeros(n)
        Bt[0] = 1.0
        Bv = np.zeros((n, self.P))
        Bv[1:, :] = self.Psi.T * self.ca
        Cs = np.zeros((self.P, n))
        Cs[:, 1:] = self.Psi
        Ct = np.zeros(n)
        Ct[1:] = self.phi_tip
        return {"M": M, "D": D, "K": K, "B_torque": Bt, "B_voltage": Bv, "C_slopes": Cs, "C_tip": Ct}

    def _static_ports(self) -> np.ndarray:
        """Static flexibility ``F_ab = (1/EI) int m_a m_b dx`` of the ports [q, pairs..., tip].

        ``m_a`` is the clamped-arm bending-moment distribution of port ``a``'s unit load:
        distributed ``rho A (r + x)``: ``rho A [(r + x)(L - x)^2/2 + (L - x)^3/3]``; patch pair:
        the indicator of ``[x1, x2]``; tip force: ``L - x``.  Exact Gauss-Legendre on pieces.
        """
        L, r, rhoA = self.L, self.r, self.rhoA
        cuts = sorted({0.0, L, *self.patch_ends.ravel().tolist()})

        def moments(x):
            cols = [rhoA * ((r + x) * (L - x) ** 2 / 2.0 + (L - x) ** 3 / 3.0)]
            for x1, x2 in self.patch_ends:
                cols.append(((x >= x1) & (x <= x2)).astype(float))
            cols.append(L - x)
            return np.array(cols)

        F = 0.0
        for a, b in zip(cuts[:-1], cuts[1:]):
            if b - a <= 0:
                continue
            x, w = _gauss(a, b, 8)
            mid = 0.5 * (a + b)
            m = moments(x)
            # indicator evaluated at the piece's midpoint (pieces never straddle a patch end)
            for j, (x1, x2) in enumerate(self.patch_ends):
                m[1 + j] = 1.0 if x1 <= mid <= x2 else 0.0
            F = F + (m * w) @ m.T
        return np.asarray(F) / self.EI

    def _port_modal(self) -> np.ndarray:
        """``b_ak`` = virtual work of port ``a`` in mode ``k``: ``[a_k; Psi_jk; phi_k(L)]``."""
        return np.vstack([self.a[None, :], self.Psi, self.phi_tip[None, :]])

    def frequency_response(self, omega, *, kp: float = 0.0, kd: float = 0.0, pd_delay: float = 0.0,
                           pzt_gains=None, pzt_delay: float = 0.0, static_correction: bool = True,
                           pd_closed: bool = True, pzt_closed=True) -> dict:
        """Closed-loop responses per unit desired angle, motor torque and injected voltages.

        Linear model about rest: ``y = H(s) f`` on the ports (distributed inertia load
        ``f_q = -s^2 theta``, pairs ``f_j = c_a,j V_j``, tip), hub
        ``J0 s^2 theta + s^2 y_q = tau``; ``H = sum_k b_k b_k^T / (s^2 + omega_k^2 (1 + tau_d s))
        [+ (F - sum_k b_k b_k^T / omega_k^2) / (1 + tau_d s)]`` (static correction).

        Parameters
        ----------
        omega : array
            [rad/s].
        pzt_closed : bool or sequence of bool
            Which PZT loops are closed (per patch).

        Returns
        -------
        dict of arrays over ``omega`` with keys ``"theta_d"`` and ``"torque"`` and ``"voltage_j"``
        (one per patch): each a dict ``{"theta", "tip", "slopes" (P, nw), "voltages" (P, nw),
        "pd_output", "pzt_sensed" (P, nw)}`` of responses per unit of that input.
        ``pzt_sensed`` is ``y_k = sum_j G_kj s dtheta_j`` (the loop's sensed value).
        """
        w = np.atleast_1d(np.asarray(omega, dtype=float))
        s = 1j * w
        P = self.P
        G = np.zeros((P, P)) if pzt_gains is None else np.asarray(pzt_gains, float)
        closed = np.broadcast_to(np.asarray(pzt_closed, dtype=bool), (P,)) if P else np.zeros(0, bool)
        bmat = self._port_modal()                                 # (2 + P, N)
        kv = 1.0 + self.tau_d * s                                 # (nw,)
        denom = s[:, None] ** 2 + self.omega[None, :] ** 2 * kv[:, None]
        H = np.einsum("ak,wk,bk->wab", bmat, 1.0 / denom, bmat)
        if static_correction:
            R = self._static_ports() - (bmat / self.omega ** 2) @ bmat.T
            H = H + R[None, :, :] / kv[:, None, None]
        Cpd = (kp + kd * s) * np.exp(-s * pd_delay) if pd_closed else np.zeros_like(s)
        ga = np.exp(-s * pzt_delay)
        iq, ip, it = 0, slice(1, 1 + P), 1 + P
        # unknowns X = [theta, V_1..V_P]; equations:
        #   hub:  (J0 s^2 + Cpd) theta + s^2 (H_qq (-s^2 theta) + H_qp c V) = tau_ext + Cpd theta_d
        #   pzt k (closed): V_k + ga sum_j G_kj s (H_pq (-s^2 theta) + H_pp c V)_j = V_inj,k
        nw = w.size
        n = 1 + P
        A = np.zeros((nw, n, n), dtype=complex)
        s2 = s ** 2
        A[:, 0, 0] = self.J0 * s2 + Cpd - s2 * s2 * H[:, iq, iq]
        if P:
            A[:, 0, 1:] = s2[:, None] * H[:, iq, ip] * self.ca[None, :]
            Hpq = H[:, ip, iq]                                    # (nw, P)
            Hpp = H[:, ip, ip] * self.ca[None, None, :]           # (nw, P, P) slopes per volt
            Gm = np.where(closed[:, None], G, 0.0)
            A[:, 1:, 0] = (ga * s)[:, None] * np.einsum("kj,wj->wk", Gm, Hpq) * (-s2)[:, None]
            A[:, 1:, 1:] = np.eye(P)[None] + (ga * s)[:, None, None] * np.einsum("kj,wjl->wkl", Gm, Hpp)
        inputs = {"theta_d": np.zeros((nw, n), complex), "torque": np.zeros((nw, n), complex)}
        inputs["theta_d"][:, 0] = Cpd
        inputs["torque"][:, 0] = 1.0
        for j in range(P):
            e = np.zeros((nw, n), complex)
            e[:, 1 + j] = 1.0
            inputs[f"voltage_{j + 1}"] = e
        out = {}
        for key, rhs in inputs.items():
            X = np.linalg.solve(A, rhs[..., None])[..., 0]
            theta, V = X[:, 0], X[:, 1:].T                            # V: (P, nw)
            f_q = -s2 * theta
            f_p = self.ca[:, None] * V
            tip = H[:, it, iq] * f_q + (np.einsum("wj,jw->w", H[:, it, ip], f_p) if P else 0.0)
            slopes = (H[:, ip, iq].T * f_q[None, :] + np.einsum("wjl,lw->jw", H[:, ip, ip], f_p)) if P else \
                np.zeros((0, nw))
            sensed = (G @ (slopes * s[None, :])) if P else np.zeros((0, nw))
            ext = {"theta_d": 1.0, "torque": 0.0}.get(key, 0.0)
            out[key] = {"theta": theta, "tip": tip, "slopes": slopes, "voltages": V,
                        "pd_output": Cpd * (ext - theta), "pzt_sensed": sensed}
        return out
