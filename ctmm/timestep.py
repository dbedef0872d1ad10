"""Time domain: DT-TMM stepping of a chain with any :mod:`ctmm.schemes` integrator.

Each step (seed 002 §7.2-7.3): the scheme expresses velocity and acceleration at every
connection point as affine functions of the unknown displacement; every element then has a
real transfer matrix ``(U, u)`` for that step; the chain is solved by Riccati transfer for the
unknown boundary states and back-substituted; the scheme updates the history.

Two interchangeable paths compute the same thing:

* the **lumped fast path** (1-D chains whose elements all have a lumped form,
  :meth:`~ctmm.elements.base.Element.lumped_coefficients`: masses, springs, dampers, inerters):
  element matrices for all elements are built in one
  vectorised numpy pass; ``U`` is constant while the scheme's ``cx, A, C`` are, so the Riccati
  ``S_j, G_j`` are computed once and each step only runs the affine recursion (scalar loop);
* the **generic path**: ``DiscreteElement.step_matrices`` per element and
  :func:`ctmm.assembly.riccati_solve` (or ``plain_solve`` for comparison).
"""
from __future__ import annotations

import dataclasses
import math
import time as _time
from typing import Callable, Mapping

import numpy as np

from . import validation
from .assembly import (SOLVERS, BoundaryEnd, BoundaryStart, clamped_start_solve, predicted_forces,
                       shift_forces)
from .elements.base import Linearisation
from .chain_ode import ChainDynamics
from .massless_points import algebraic_point_rates, algebraic_points, balanced_start, hold_supports
from .chain_start import initial_acceleration, initial_forces, initial_state, point_labels, rest_positions
from .elements.beam_time import bending_mesh
from .elements.nonlinear_connector import newton_step
from .errors import ModelError, SimulationError
from .guard import DivergenceGuard
from .progress import progress_bar
from .results import SimulationResult
from .schemes import History, Scheme, as_scheme
from .signals import Constant
from .step_limit import check_scheme_step
from .system import Chain, require_system

ForceHook = Callable[[float, float, float, History], Mapping[int, float]]
"""``hook(t_n, dt, w, history) -> {element position: force [N]}`` at the step's evaluation level
(``(1 - w) F(t_n) + w F(t_n + dt)``); point elements get a force on their point, connectors
a force across them."""


# -- the stepper ------------------------------------------------------------------------
class _LumpedKernel:
    """Vectorised element matrices of a 1-D lumped chain for one step."""

    def __init__(self, system: Chain) -> None:
        body = system.body
        self.n = len(body)
        lumped = [e.lumped_coefficients() for e in body]
        self.is_point = np.array([not c.connector for c in lumped])
        get = lambda attr: np.array([getattr(c, attr) for c in lumped], dtype=float)  # noqa: E731
        # mass: a point's mass, or a connector's inertance
        self.mass, self.damping, self.stiffness = get("mass"), get("damping"), get("stiffness")
        self.free_length = get("free_length")
        self.point_pos = np.flatnonzero(self.is_point)
        # connectors in series (a massless node between them): their shared point can hold one
        # predicted force only, so their affine parts carry the difference (affine_part)
        con = np.flatnonzero(~self.is_point)
        self.series = bool(np.any(np.diff(con) == 1))
        self.const_force = np.zeros(self.n)
        self.variable_forces = []
        for j in self.point_pos:
            f = body[j].force
            if isinstance(f, Constant):
                self.const_force[j] = f.value
            else:
                self.variable_forces.append((j, f))

    def forces(self, t: float) -> np.ndarray:
        out = self.const_force.copy()
        for j, f in self.variable_forces:
            out[j] = float(f(t))
        return out

    def constant_part(self, cx: float, A: float, C: float):
        """Per-element (U12, U21): connectors carry U12 = -1/k_eff, points U21 = -impedance."""
        pts, con = self.is_point, ~self.is_point
        k_eff = np.ones(self.n)
        k_eff[con] = self.stiffness[con] * cx + self.damping[con] * A + self.mass[con] * C
        U12 = np.zeros(self.n)
        U12[con] = -1.0 / k_eff[con]
        U21 = np.zeros(self.n)
        U21[pts] = -(self.mass[pts] * C + self.damping[pts] * A + self.stiffness[pts] * cx)
        self._con = np.flatnonzero(con)
        self._pts = np.flatnonzero(pts)
        self._con_kl = self.stiffness[con] * self.free_length[con]
        self._con_k, self._con_c, self._con_keff = self.stiffness[con], self.damping[con], k_eff[con]
        self._con_b = self.mass[con]
        self._pts_m, self._pts_c, self._pts_k = self.mass[pts], self.damping[pts], self.stiffness[pts]
        return U12, U21, k_eff

    def affine_part(self, coeffs, k_eff, load: np.ndarray, across: np.ndarray | None = None):
        """Affine parts in *incremental force* form, and the predicted point forces ``f_pred``.

        The force at every point is written ``f = f_pred + phi``: ``f_pred`` is the force of the
        adjacent connector at the scheme's predictor (``delta = 0``), so a connector's affine term
        vanishes identically and a point element's is the residual of its predicted equilibrium.
        Solving for the small corrections ``(delta, phi)`` avoids recovering ``delta`` as the
        difference of O(stretch) quantities (see :mod:`ctmm.schemes`).
        """
        dx, B, D = coeffs.dx[:, 0], coeffs.B[:, 0], coeffs.D[:, 0]
        con, pts = self._con, self._pts
        n_points = self.n + 1
        predicted = (self._con_kl - self._con_k * (dx[con + 1] - dx[con]) - self._con_c * (B[con + 1] - B[con])
                     - self._con_b * (D[con + 1] - D[con]))
        if across is not None:
            predicted = predicted + across[con]
        f_pred = np.full(n_points, np.nan)
        f_pred[con] = predicted          # inboard point of connector (element con+1 -> point con)
        f_pred[con + 1] = predicted      # outboard point
        known = ~np.isnan(f_pred)
        if not known[0]:
            f_pred[0] = 0.0
            known[0] = True
        idx = np.where(known, np.arange(n_points), 0)
        np.maximum.accumulate(idx, out=idx)
        f_pred = f_pred[idx]             # points between point elements inherit the inboard value
        u0 = np.zeros(self.n)
        u1 = np.zeros(self.n)
        if self.series:  # a massless node keeps the inboard connector's force: the outboard one's offsets
            u0[con] = (predicted - f_pred[con]) / self._con_keff
            u1[con] = f_pred[con] - f_pred[con + 1]
        u1[pts] = (f_pred[pts] - f_pred[pts + 1] + load[pts]
                   - (self._pts_m * D[pts] + self._pts_c * B[pts] + self._pts_k * dx[pts]))
        return u0, u1, f_pred


def _scalar_riccati(U12, U21, u0, u1, fixed_start: bool, S0: float, P0: float, end_row, end_b: float,
                    cache: dict):
    """Riccati transfer for 2x2 lumped chains with Python floats (``U11 = U22 = 1``).

    Partition: ``f = force`` and ``e = x`` (stiffness form ``force_j = S_j x_j + P_j``).  A
    displacement-type start (``fixed_start``) is first rebased past its first connector (see
    :func:`_clamped_start`); without any connector the compliance form ``f = x``, ``e = force``
    is used.  Returns the point states ``(x, force)`` as arrays.
    """
    if fixed_start and "first_connector" not in cache:
        connectors = np.flatnonzero(U12)
        cache["first_connector"] = int(connectors[0]) if connectors.size else None
    if fixed_start and cache["first_connector"] is not None:
        return _clamped_start(U12, U21, u0, u1, P0, end_row, end_b, cache)
    n = len(U12)
    if fixed_start:  # f = x, e = force:   U11=1, U12=U12, U21=U21, U22=1
        a12, a21 = U12, U21
    else:            # f = force, e = x:   U11=1, U12=U21, U21=U12, U22=1
        a12, a21 = U21, U12
    key = ("S", fixed_start, S0)
    if key not in cache:
        S = np.empty(n + 1)
        G = np.empty(n)
        alpha = np.empty(n)
        S[0] = S0
        s = S0
        for j in range(n):
            g = a21[j] * s + 1.0
            s = (s + a12[j]) / g
            G[j] = g
            S[j + 1] = s
            # 1 - S_j a21_j = (1 - a12_j a21_j) / G_j (U11 = U22 = 1). The left form cancels
            # when S_j a21_j ~ 1 (a soft connector after a stiff part: alpha ~ k / (K + k) comes
            # out with relative error eps K / k); the right one is exact for lumped elements,
            # where a12 a21 = 0.
            alpha[j] = (1.0 - a12[j] * a21[j]) / g
        cache[key] = (S, G, alpha)
    S, G, alpha = cache[key]
    v1, v2 = (u0, u1) if fixed_start else (u1, u0)
    if n < 16:  # short chains: plain Python floats beat the LAPACK call overhead
        return _scalar_sweeps_python(a21, S, G, alpha, v1, v2, P0, end_row, end_b, fixed_start, cache)
    if "bands" not in cache:
        # forward:  P_j - alpha_j P_{j-1} = v1_j - S_j v2_j                     (lower bidiagonal)
        # backward: e_{j-1} - e_j / G_j = -(a21_j P_{j-1} + v2_j) / G_j        (upper bidiagonal)
        lower = np.zeros((2, n))
        lower[0] = 1.0
        lower[1, : n - 1] = -alpha[1:]
        upper = np.zeros((2, n))
        upper[1] = 1.0
        upper[0, 1:] = -1.0 / G[: n - 1]
        cache["bands"] = (alpha, lower, upper)
    alpha, lower, upper = cache["bands"]
    rhs = v1 - S[1:] * v2
    rhs[0] += alpha[0] * P0
    P_tail, info = _dtbtrs(lower, rhs, uplo="L")
    P = np.concatenate(([P0], P_tail))
    e_n = _end_unknown(end_row, end_b, fixed_start, S[n], P[n])
    c = -(a21 * P[:n] + v2) / G
    c[n - 1] += e_n / G[n - 1]
    E_head, info = _dtbtrs(upper, c, uplo="U")
    E = np.concatenate((E_head, [e_n]))
    F = S * E + P
    return (F, E) if fixed_start else (E, F)


def _clamped_start(U12, U21, u0, u1, P0: float, end_row, end_b: float, cache: dict):
    """:func:`_scalar_riccati` for a displacement-type start, in stiffness form.

    The compliance form ``x_j = S_j force_j + P_j`` that a known start displacement suggests is
    unstable on stiff chains: ``P_j`` is the displacement of the chain cut at ``j`` under the
    step's loads, which a soft connector near the start makes orders of magnitude larger than the
    displacement of the whole chain (a stiff part further out holds it back), and the digits are
    lost when ``x_j = S_j force_j + P_j`` is formed (measured: 1e-5 relative per Newmark step on
    a chain with springs 1e0-1e9 N/m at h = 1e-2, where the global solve loses 1e-13).  The
    stiffness form ``force_j = S_j x_j + P_j`` carries ``P_j``, the reaction of the chain clamped
    at ``j``, which the loads bound; its recursion is Gaussian elimination without pivoting of
    the symmetric positive definite effective stiffness (backward stable) and its
    back-substitution ``x_{j-1} = (k x_j + P_{j-1} - k u0) / (k + K_{j-1})`` only averages.

    Points ``0 .. c`` up to the first connector ``c`` are clamped (``x = P0``, point elements
    pass ``x`` on); connector ``c`` turns the clamp into the force-type start relation
    ``force_{c+1} = x_{c+1} / U12_c + u1_c - (x_c + u0_c) / U12_c`` (``x_{c+1} = x_c + U12_c
    force + u0_c``), the rest of the chain is solved in stiffness form, and the prefix forces
    follow backwards from ``force_out = force_in + U21 x + u1``.
    """
    c = cache["first_connector"]
    x_prefix = np.full(c + 1, P0)                                       # points 0 .. c
    if c:
        x_prefix[1:] += np.cumsum(u0[:c])
    S_start = 1.0 / U12[c]
    P_start = u1[c] - (x_prefix[-1] + u0[c]) * S_start
    x_rest, f_rest = _scalar_riccati(U12[c + 1:], U21[c + 1:], u0[c + 1:], u1[c + 1:], False, S_start,
                                     P_start, end_row, end_b, cache)
    f_prefix = np.empty(c + 1)
    f_prefix[c] = f_rest[0] - u1[c]
    for j in range(c - 1, -1, -1):
        f_prefix[j] = f_prefix[j + 1] - U21[j] * x_prefix[j] - u1[j]
    return np.concatenate((x_prefix, x_rest)), np.concatenate((f_prefix, f_rest))


def _dtbtrs(band: np.ndarray, rhs: np.ndarray, uplo: str):
    """Solve a bidiagonal triangular system stored in LAPACK band form (O(n), compiled)."""
    from scipy.linalg.lapack import dtbtrs

    x, info = dtbtrs(band, rhs, uplo=uplo)
    if info != 0:
        raise SimulationError(f"singular Riccati recursion (LAPACK dtbtrs info={info})")
    return x, info


def _end_unknown(end_row, end_b: float, fixed_start: bool, S_n: float, P_n: float) -> float:
    """End unknown ``e`` of the sweep: ``Bm = [cf, ce]`` on ``(f, e)``, ``f = S e + P`` -> ``(cf S + ce) e = b - cf P``
    (``end_row``: coefficients of (x, force); ``(f, e) = (x, force)`` if ``fixed_start``, else swapped)."""
    cx_, cf_ = end_row
    cf, ce = (cx_, cf_) if fixed_start else (cf_, cx_)
    h = cf * S_n + ce
    if h == 0.0 or not math.isfinite(h):
        raise SimulationError("the boundary equations of the step are singular")
    return (end_b - cf * P_n) / h


def _scalar_sweeps_python(a21, S, G, alpha, v1, v2, P0, end_row, end_b, fixed_start, cache):
    """The two sweeps of :func:`_scalar_riccati` on Python floats (fast for short chains)."""
    n = len(G)
    if "lists" not in cache:
        cache["lists"] = (a21.tolist(), S.tolist(), G.tolist(), alpha.tolist())
    a21l, Sl, Gl, alphal = cache["lists"]
    v1l, v2l = v1.tolist(), v2.tolist()
    Pl = [P0]
    p = P0
    for j in range(n):  # affine Riccati recursion P_j = alpha_j P_{j-1} + v1 - S_j v2
        p = alphal[j] * p + v1l[j] - Sl[j + 1] * v2l[j]
        Pl.append(p)
    e = _end_unknown(end_row, end_b, fixed_start, Sl[n], Pl[n])
    El = [0.0] * (n + 1)
    El[n] = e
    for j in range(n, 0, -1):  # back-substitution e_{j-1} = (e_j - a21 P_{j-1} - v2) / G_j
        e = (e - a21l[j - 1] * Pl[j - 1] - v2l[j - 1]) / Gl[j - 1]
        El[j - 1] = e
    E = np.array(El)
    F = S * E + np.array(Pl)
    return (F, E) if fixed_start else (E, F)


#: Most steps one run may take (more is almost certainly a unit mistake in ``dt``).
MAX_STEPS = 100_000_000


def simulate(system: Chain, t_final: float, dt: float, *, scheme: Scheme | str = "newmark",
             x0: Mapping[str, float] | None = None, v0: Mapping[str, float] | None = None,
             t0: float = 0.0, solver: str = "riccati", fast: bool | None = None,
             force_hook: ForceHook | None = None, progress: bool | None = None,
             stability_check: str | None = None, divergence_bound: float | None = None,
             _step=None, _before_step=None, _after_step=None, _system_for_result=None,
             _divergence_hint: str = "") -> SimulationResult:
    """Simulate a chain with the discrete-time transfer matrix method.

    Parameters
    ----------
    system : Chain
        The model (a plain chain; :func:`ctmm.simulate` also takes controlled chains).
    t_final : float
        End time [s] (> t0).
    dt : float
        Step size [s] (> 0).
    scheme : Scheme or str
        Integrator: ``"newmark"``, ``"generalized_alpha"``, ``"wilson_theta"``, ``"houbolt"``,
        ``"forward_euler"`` or an instance such as ``Newmark(beta=0.3, gamma=0.6)``.
    x0, v0 : mapping, optional
        Initial absolute positions [m] / velocities [m/s] by element name (see
        :func:`initial_state`).
    t0 : float
        Start time [s].
    solver : {"riccati", "plain"}
        Chain solver; ``"plain"`` (overall products) is for comparison only.
    fast : bool, optional
        Force (True) or forbid (False) the vectorised lumped-chain path; default: use it when the
        chain qualifies and ``solver == "riccati"``.
    force_hook : callable, optional
        ``force_hook(t_n, dt, w, history) -> {element position: force [N]}``: extra forces at
        the step's evaluation level (see :data:`ForceHook`; used by delayed and co-simulated
        control).
    progress : bool, optional
        Show a progress bar (default: only on a terminal for long runs).
    stability_check : {"warn", "error", "ignore"}, optional
        What to do, before the run, when ``dt`` exceeds the stability limit of a conditionally
        stable scheme for the chain's highest natural frequency (:mod:`ctmm.step_limit`).
        Default: an error when no step is stable (Newmark with ``gamma < 1/2``), a
        :class:`~ctmm.guard.StabilityLimitWarning` otherwise.
    divergence_bound : float, optional
        Largest allowed distance [m] of any point from its rest position; default
        ``1e6 * max(1 m, largest initial excursion)``; ``math.inf`` checks finiteness only.

    Returns
    -------
    SimulationResult

    Raises
    ------
    SimulationError
        When a step produces non-finite values, a point leaves the divergence bound, or user code
        (a force callback) fails; with the time and the element, and the result up to the last
        good step attached as ``partial_result``.
    ModelError
        Bad input, or a step beyond the scheme's stability limit with ``stability_check="error"``.
    """
    system = require_system(system, controlled=False)
    t_final, dt, t0 = validation.finite("t_final", t_final), validation.positive("dt", dt), validation.finite("t0", t0)
    if t_final <= t0:
        raise ModelError(f"t_final must be > t0={t0}, got {t_final!r}")
    validation.step_count(t_final, t0, dt, bytes_per_step=8.0 * system.n_points * 2 * system.layout.size)
    solver = validation.option("solver", solver, SOLVERS)
    fast = validation.flag("fast", fast, optional=True)
    progress = validation.flag("progress", progress, optional=True)
    force_hook = validation.callable_or_none("force_hook", force_hook)
    scheme = as_scheme(scheme)
    original, mesh = system, bending_mesh(system, dt, (force_hook, _step, _before_step, _after_step))
    system, rows = (mesh.chain, mesh.rows) if mesh else (system, slice(None))
    lumped = all(e.lumped_coefficients() is not None for e in system.body) and system.layout.size == 2
    fast = (lumped and solver == "riccati") if fast is None else fast
    if fast and not (lumped and solver == "riccati"):
        raise ModelError("fast=True needs a 1-D chain of lumped elements and solver='riccati'")
    if (t_final - t0) / dt > MAX_STEPS:
        raise ModelError(f"dt={dt!r} s gives {(t_final - t0) / dt:.3g} steps over {t_final - t0!r} s; at most "
                         f"{MAX_STEPS:.0e} steps are allowed (check the unit of dt)")
    n_steps = int(round((t_final - t0) / dt))
    if n_steps < 1 or abs(n_steps * dt - (t_final - t0)) > 1e-9 * max(1.0, abs(t_final)):
        raise ModelError(f"(t_final - t0) = {t_final - t0!r} s must be a whole number of steps dt={dt!r} (>= 1)")
    x, v, consistent = (*mesh.initial_state(x0, v0), False) if mesh else dttmm_start_state(system, x0, v0, t0)
    algebraic = np.zeros(system.n_points, dtype=bool) if mesh else algebraic_points(system)
    consistent = consistent and force_hook is None    # a loop force's rate at t0 is not known here
    check_scheme_step(system, scheme, dt, stability_check)
    guard = DivergenceGuard.from_start(point_labels(system), 0 * x[:, 0] if mesh else rest_positions(system), x[:, 0],
                                       bound=divergence_bound, hint=_divergence_hint)
    n_pts = system.n_points
    d = system.layout.half
    times = t0 + dt * np.arange(n_steps + 1)
    states = np.full((n_steps + 1, n_pts, system.layout.size), np.nan)
    vel, acc = (np.full((n_steps + 1, n_pts, d), np.nan) for _ in range(2))
    done = 0                                 # rows of the result that are complete
    started = _time.perf_counter()
    bar = progress_bar(n_steps, f"simulate {system.name}", enabled=progress)
    try:
        extra0 = force_hook(t0, dt, 0.0, History(x, v, np.zeros_like(x), [x, x])) if force_hook else {}
        discrete = None if fast else [e.discretize(scheme) for e in system.body]
        motion = mesh.initial_motion(discrete, x, v, t0, extra0) if mesh else None
        a = motion[0] if mesh else initial_acceleration(system, x, v, t0, extra0)
        history = History(x.copy(), v.copy(), a.copy(), [x.copy(), x.copy()], 0)
        states[0, :, :d], vel[0], acc[0] = x, v, a
        acc[0, algebraic] = np.nan
        if not consistent:                # off the balance at t0: its rate there is unknown
            vel[0, algebraic] = np.nan
        states[0, :, d:2 * d] = motion[1] if mesh else initial_forces(system, x, v, extra0, a, t0)[:, None]
        done = 1
        kernel = _LumpedKernel(system) if fast else None
        newton = [] if any(getattr(disc, "newton", False) for disc in discrete or ()) else None  # iterations
        cache: dict = {}
        for i in range(n_steps):
            t_n = times[i]
            if _before_step is not None:      # may restart history.a at a load discontinuity
                _before_step(i, float(t_n), history)
            coeffs = scheme.coefficients(history, dt)
            t_eval = t_n + coeffs.unknown_offset
            w = coeffs.load_weight
            extra = force_hook(t_n, dt, w, history) if force_hook else {}
            try:
                if _step is not None:
                    x_new, f_new = _step(coeffs, t_n, dt, w, t_eval, extra, history)
                elif fast:
                    load = (1.0 - w) * kernel.forces(t_n) + w * kernel.forces(t_n + dt) if w != 1.0 \
                        else kernel.forces(t_n + dt)
                    across = np.zeros(kernel.n)
                    for pos, value in extra.items():
                        if kernel.is_point[pos - 1]:
                            load[pos - 1] += value
                        else:
                            across[pos - 1] += value
                    x_new, f_new = _fast_step(system, kernel, coeffs, load, (t_n, dt, w), cache, across)
                else:
                    solve = lambda: _generic_step(system, discrete, coeffs, t_n, dt, w, t_eval, extra, solver)  # noqa: E731
                    x_new, f_new = newton_step(solve, discrete, coeffs, t_eval, newton) if newton is not None else solve()
            except np.linalg.LinAlgError as exc:
                raise SimulationError(f"the step to t = {times[i + 1]:.6g} s is singular ({exc}): the chain "
                                      "equations have no unique solution at this step", time=float(times[i + 1]),
                                      element=system.name) from exc
            bad = ~(np.isfinite(x_new) & np.isfinite(f_new))
            if np.any(bad):
                point = int(np.flatnonzero(bad)[0]) // d
                name = system.elements[min(point + 1, len(system.elements) - 1)].name
                raise SimulationError(f"non-finite state at t = {times[i + 1]:.6g} s at the point "
                                      f"{system.point_names()[point]!r} (element {name!r})"
                                      + (f"; {_divergence_hint}" if _divergence_hint else ""),
                                      time=float(times[i + 1]), element=name)
            history = scheme.update(history, x_new.reshape(n_pts, d), dt, coeffs)  # x_new is the correction
            guard.check(float(times[i + 1]), history.x[:, 0])
            states[i + 1, :, :d] = history.x
            states[i + 1, :, d:2 * d] = scheme.interpolate_force(f_new.reshape(n_pts, d), states[i, :, d:2 * d])
            vel[i + 1], acc[i + 1] = history.v, history.a
            if np.any(algebraic):
                algebraic_point_rates(states, vel, acc, i + 1, dt, algebraic, consistent)
            if _after_step is not None:
                _after_step(i + 1, float(times[i + 1]), history, states[i + 1])
            done = i + 2
            bar.update(1)
    except SimulationError as exc:
        if exc.time is None:             # raised by a solver that does not know the time
            exc.time = float(times[min(done, n_steps)])
            exc.args = (f"{exc.args[0] if exc.args else exc} (step to t = {exc.time:.6g} s)",) + exc.args[1:]
        if exc.partial_result is None:
            exc.partial_result = SimulationResult(
                times[:done], states[:done, rows], vel[:done, rows], acc[:done, rows], _system_for_result or original,
                scheme.name, {"n_steps": done - 1, "dt": dt, "failed_at_s": exc.time})
        raise
    finally:
        bar.close()
    info = {"wall_time_s": _time.perf_counter() - started, "n_steps": n_steps, "dt": dt,
            "path": "lumped-fast" if fast else f"generic-{solver}", **_newton_info(newton)}
    return SimulationResult(times, states[:, rows], vel[:, rows], acc[:, rows], _system_for_result or original,
                            scheme.name, info)


def _newton_info(iterations: list | None) -> dict:
    return {"newton_iterations_max": max(iterations), "newton_iterations_mean": float(np.mean(iterations))} \
        if iterations else {}


def dttmm_start_state(system: Chain, x0, v0, t0: float) -> tuple[np.ndarray, np.ndarray, bool]:
    """:func:`~ctmm.chain_start.initial_state` with the massless points of a lumped chain at their
    consistent start (:meth:`ctmm.chain_ode.ChainDynamics.start_points`: static balance under the given
    positions, velocities from the balance), so the first step sees the right connector forces.  Chains
    off the ``d = 1`` protocol, or whose support or massless-node force has no closed-form rate, keep
    :func:`initial_state` (massless points at rest length).  The flag says whether the massless points
    start consistently."""
    try:
        dynamics = ChainDynamics(system)
    except ModelError:                        # e.g. nonlinear connectors next to massless points
        x, v = balanced_start(system, x0, v0, t0)
        return x, v, False
    consistent = True
    try:
        x, v = dynamics.start_points(t0, x0, v0)
    except ModelError as exc:
        if "closed-form rate" not in str(exc):
            raise
        x, v = initial_state(system, x0, v0)
        consistent = False
    hold_supports(dynamics, x, v, t0)          # no closed-form rate: the support starts at rest as before
    return x, v, consistent


def _fast_step(system: Chain, kernel: _LumpedKernel, coeffs, load, step: tuple, cache: dict,
               across: np.ndarray | None = None):
    """One DT-TMM step of a lumped chain: the correction ``delta`` to the predictor and the forces.

    Solved in the incremental-force form around the scheme's predictor; when the predictor is
    far from the solution (stiff parts at large steps: the force corrections exceed the forces
    themselves) the step is solved once more around the first solution (one step of iterative
    refinement, see :func:`_refinement_needed`).
    """
    key = (coeffs.cx, coeffs.A, coeffs.C)
    if cache.get("key") != key:
        cache.clear()
        cache["key"] = key
        cache["const"] = kernel.constant_part(*key)
    delta, phi, f_reference = _fast_solve(system, kernel, coeffs, load, step, cache, across)
    forces = phi + f_reference
    if _refinement_needed(phi, forces):
        around = _coefficients_around(coeffs, delta[:, None])
        xi, phi, f_reference = _fast_solve(system, kernel, around, load, step, cache, across)
        delta = delta + xi
        forces = phi + f_reference
    return delta, forces


def _coefficients_around(coeffs, q: np.ndarray):
    """The step's coefficients for the unknown ``xi = delta - q`` (``q`` per point, ``(N+1, d)``).

    Exact change of unknown around a first solution ``q``: ``x_eval = cx xi + (dx + cx q)``,
    ``v_eval = A xi + (B + A q)``, ``a_eval = C xi + (D + C q)``; the point's displacement at
    ``xi = 0`` is ``x_pred + q``.  The transfer matrices (``cx, A, C``) do not change.
    """
    return dataclasses.replace(coeffs, dx=coeffs.dx + coeffs.cx * q, B=coeffs.B + coeffs.A * q,
                               D=coeffs.D + coeffs.C * q, x_pred=coeffs.x_pred + q)


def _refinement_needed(phi: np.ndarray, forces: np.ndarray) -> bool:
    """True when the force corrections ``phi`` of a step exceed the forces themselves.

    The incremental-force solve has absolute errors of about ``eps |f_reference|`` (the connector
    forces at the predictor, ``forces - phi``) while the forces are ``|forces|``; the ratio
    ``|phi| / |forces|`` (2-norms) measures the loss.  Solving once more around the first
    solution makes the reference forces those of the solution (the ratio becomes its error), so
    one refinement restores the digits.  At ordinary steps the predictor is accurate to O(h^3)
    and the ratio is tiny: the second solve is skipped.  Two dot products (no temporaries): the
    check runs every step; a non-finite step gives False (the caller reports it).
    """
    phi, forces = phi.ravel(), forces.ravel()
    return bool(phi @ phi > forces @ forces)


def _fast_solve(system: Chain, kernel: _LumpedKernel, coeffs, load, step: tuple, cache: dict,
                across: np.ndarray | None):
    """Solve one step ``step = (t_n, h, w)`` for ``delta`` and the force corrections ``phi``."""
    U12, U21, k_eff = cache["const"]
    u0, u1, f_pred = kernel.affine_part(coeffs, k_eff, load, across)
    lin0 = Linearisation(coeffs.cx, coeffs.dx[0, 0], coeffs.A, coeffs.B[0, 0], coeffs.C, coeffs.D[0, 0],
                         coeffs.x_pred[0, 0])
    linN = Linearisation(coeffs.cx, coeffs.dx[-1, 0], coeffs.A, coeffs.B[-1, 0], coeffs.C, coeffs.D[-1, 0],
                         coeffs.x_pred[-1, 0])
    _, S0, P0 = system.start.start_discrete(system.layout, step[0] + coeffs.unknown_offset, lin0, load_step=step)
    Bm, b = system.end.end_discrete(system.layout, step[0] + coeffs.unknown_offset, linN, load_step=step)
    fixed_start = system.start.known == "displacement"
    P0_phi = float(P0[0]) if fixed_start else float(P0[0]) - f_pred[0]   # known force -> its correction
    b_phi = float(b[0]) - float(Bm[0, 1]) * f_pred[-1]
    delta, phi = _scalar_riccati(U12, U21, u0, u1, fixed_start, float(S0[0, 0]), P0_phi,
                                 (float(Bm[0, 0]), float(Bm[0, 1])), b_phi, cache)
    return delta, phi, f_pred


def _generic_step(system, discrete, coeffs, t_n, dt, w, t_eval, extra, solver):
    """One DT-TMM step with the elements' own ``step_matrices`` (same refinement as :func:`_fast_step`)."""
    d = system.layout.half
    x_part, phi, reference = _generic_solve(system, discrete, coeffs, t_n, dt, w, t_eval, extra, solver)
    forces = phi + reference
    if solver == "riccati" and _refinement_needed(phi, forces):
        around = _coefficients_around(coeffs, x_part.reshape(system.n_points, d))
        xi, phi, reference = _generic_solve(system, discrete, around, t_n, dt, w, t_eval, extra, solver)
        x_part = x_part + xi
        forces = phi + reference
    return x_part, (forces[:, 0] if d == 1 else forces).copy()


def _generic_solve(system, discrete, coeffs, t_n, dt, w, t_eval, extra, solver):
    """Solve one step: displacement corrections, force corrections and reference forces ``(N+1, d)``."""
    pick = (lambda arr, j: float(arr[j, 0])) if system.layout.half == 1 else (lambda arr, j: arr[j])
    lins = [Linearisation(coeffs.cx, pick(coeffs.dx, j), coeffs.A, pick(coeffs.B, j), coeffs.C,
                          pick(coeffs.D, j), pick(coeffs.x_pred, j)) for j in range(system.n_points)]
    Us, us = [], []
    for j, disc in enumerate(discrete, start=1):
        force = extra.get(j, 0.0) + (1.0 - w) * disc.load(t_n) + w * disc.load(t_n + dt)
        U, u = disc.step_matrices(t_eval, lins[j - 1], lins[j], force)
        Us.append(np.asarray(U, dtype=float)[None])
        us.append(np.asarray(u, dtype=float).reshape(1, -1))
    e_idx, S0, P0 = system.start.start_discrete(system.layout, t_eval, lins[0], load_step=(t_n, dt, w))
    Bm, b = system.end.end_discrete(system.layout, t_eval, lins[-1], load_step=(t_n, dt, w))
    d = system.layout.half
    start, end = BoundaryStart(e_idx, S0[None], P0[None]), BoundaryEnd(Bm[None], b[None])
    if solver == "riccati":  # incremental-force form (see ctmm.assembly.shift_forces), stiffness form
        reference = predicted_forces(Us, us, d)
        us, start, end = shift_forces(Us, us, start, end, reference, d)
        states = clamped_start_solve(Us, us, start, end, want_log_det=False).states[:, 0, :]
        reference = reference[:, 0, :]
    else:
        states = SOLVERS[solver](Us, us, start, end).states[:, 0, :]
        reference = np.zeros((len(states), d))
    x_part = states[:, 0].copy() if d == 1 else states[:, :d].copy()
    return x_part, states[:, d:2 * d].copy(), reference
