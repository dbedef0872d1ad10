"""Time domain: the controlled manipulator as a planar multibody model with a modal beam.

Model (``docs/manipulator.md`` §6): ``Fixed("ground")`` -> ``ActuatedHinge("motor")`` ->
``RigidBody("hub")`` (inertia ``J_h`` about the pivot = its centre of mass, outboard end at
``r_h``) -> ``FixedMounting("mount")`` (the seed's "fixed hinge whose inboard body is a rigid
body and whose outboard body is a piezoelectric beam") -> :class:`~ctmm.flexible.ModalBeam`
``"arm"`` (``n_modes`` clamped-free modes, 3 in the seed; Kelvin-Voigt damping; geometric
stiffening).  Forward dynamics is the O(n) mixed TMM sweep of :mod:`ctmm.flexible.kernel`
(modal accelerations eliminated locally).

How the control laws enter (DESIGN §1):

* **embedded** (no delay): the PD is the hinge law of the ``ActuatedHinge``
  (``kappa = kp beta' h^2 + kd gamma' h`` in the implicit DT-TMM); the PZT law is the modal
  damping matrix ``D_pzt = Psi^T diag(c_a) G Psi`` on the beam's modal equations through the
  :class:`~ctmm.flexible.ModalForce` hook (``Psi_jk = phi_k'(x2_j) - phi_k'(x1_j)`` from the
  beam's own shapes) -- exact and implicit (no added lag) in Newmark.  With
  ``on_limit="saturate"`` the PZT law is a (complex-step safe) saturated ``law`` instead.
* **delayed** (``delay > 0``, ``delay >= dt``): the delayed law's torque / generalised forces
  are known from the stored history (FORMULAS §5.2; seed 001 §9.6.2) and enter as time
  functions; the history is a :class:`~ctmm.control.history.DelayHistory` with 4-point Lagrange
  interpolation on the step grid (4th order, a window of ``O(delay / dt)`` steps), the history
  before ``t = 0`` is the initial state held and ``theta_d(t < 0) = theta_d(0)``.
* **co-simulation**: any :class:`~ctmm.control.protocol.Controller` (Python object or
  :class:`~ctmm.control.fmu.FMUController`) reading ``SIGNALS`` and writing ``"motor.torque"``
  and/or ``"<patch>.voltage"``, sampled at its ``sample_time`` (a multiple of ``dt``; ``None``:
  every step) with zero-order hold by the shared master :class:`~ctmm.control.cosim.CoSimulation`
  (named failures, samples recorded in ``extra``); the wiring is checked by
  :func:`~ctmm.control.cosim.check_wiring` against :meth:`FlexibleManipulator.signal_names` and
  :meth:`FlexibleManipulator.output_names`, and the held outputs are read by those names.  A
  controller that writes the torque replaces the embedded PD; one that writes any voltage
  replaces the embedded PZT law (unwritten patches get 0 V).

Integrators: ``"rk4"`` (:func:`ctmm.ode.integrate_rk4` on the sweep) and ``"newmark"``
(:func:`ctmm.planar.simulate_implicit`, trapezoidal Newmark with Newton), each one run whose
per-step callback appends the histories and samples the controllers; the time functions of the
model read both.  In Newmark a step after a sample with a new held output starts from the
acceleration with that output (``after_step`` of :func:`~ctmm.planar.simulate_implicit`).
"""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .. import validation
from ..control.cosim import CoSimulation, check_wiring
from ..control.history import DelayHistory
from ..errors import ModelError, SimulationError
from .laws import HubPD, PZTFeedback, check_pzt
from .parameters import Manipulator
from .results import ManipulatorSimulation

__all__ = ["FlexibleManipulator", "ManipulatorSimulation", "SIGNALS_HELP"]

SIGNALS_HELP = ("hub.theta [rad], hub.theta_dot [rad/s], tip.deflection [m], tip.deflection_dot [m/s], "
                "<patch>.slope [rad], <patch>.slope_rate [rad/s]; outputs motor.torque [N m], <patch>.voltage [V]")
METHODS = ("rk4", "newmark")


@dataclass(frozen=True)
class FlexibleManipulator:
    """Time-domain controlled manipulator (module docstring).

    Parameters
    ----------
    manipulator : Manipulator
    pd : HubPD or None
        Embedded (or, with ``delay > 0``, history-based) PD; ``None``: a controller must drive
        the motor (or the hub is free).
    pzt : PZTFeedback or None
        PZT law (``None``: patches not driven unless a controller writes voltages).
    reference : object with ``angle(t)`` and ``rate(t)``
        Desired hub angle and rate (e.g. :class:`~ctmm.manipulator.CycloidalMove`).
    n_modes : int
        Clamped-free modes of the arm (seed: 3).
    geometric_stiffening : bool
        Centrifugal stiffening of the arm (``ModalBeam``'s option).
    hub_mass : float
        Hub mass [kg] (its centre is the fixed pivot: enters the pivot reaction only).
    """

    manipulator: Manipulator
    pd: HubPD | None
    pzt: PZTFeedback | None
    reference: Any
    n_modes: int = 3
    geometric_stiffening: bool = True
    hub_mass: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.manipulator, Manipulator):
            raise ModelError(f"manipulator must be a Manipulator, got {self.manipulator!r}")
        if self.pd is not None and not isinstance(self.pd, HubPD):
            raise ModelError(f"pd must be a HubPD or None, got {self.pd!r}")
        check_pzt(self.pzt, self.manipulator.n_patches)
        for attr in ("angle", "rate"):
            if not callable(getattr(self.reference, attr, None)):
                raise ModelError(f"reference must provide angle(t) and rate(t), got {self.reference!r}")
        if isinstance(self.n_modes, bool) or not isinstance(self.n_modes, (int, np.integer)) or self.n_modes < 1:
            raise ModelError(f"n_modes must be an integer >= 1, got {self.n_modes!r}")
        validation.positive("hub_mass", self.hub_mass)
        from .scene import arm_beam, patch_slope_matrix

        beam = arm_beam(self.manipulator, self.n_modes, self.geometric_stiffening)
        object.__setattr__(self, "_beam", beam)
        object.__setattr__(self, "_Psi", patch_slope_matrix(beam, self.manipulator))

    # ------------------------------------------------------------------ model pieces
    @property
    def slope_matrix(self) -> np.ndarray:
        """``Psi`` (P, n): slope difference over each patch per unit modal coordinate [rad/m]."""
        return self._Psi

    @property
    def tip_shape(self) -> np.ndarray:
        """``phi(L)`` of the arm modes (tip deflection = ``phi(L) . q``)."""
        return self._beam.data.tip_phi

    @property
    def pzt_damping(self) -> np.ndarray:
        """``D_pzt = Psi^T diag(c_a) G Psi`` [N s/m]: the embedded PZT law on the modal equations."""
        if self.pzt is None:
            return np.zeros((self.n_modes, self.n_modes))
        return self._Psi.T @ (self.manipulator.moments_per_volt[:, None] * self.pzt.gains) @ self._Psi

    def signal_names(self) -> list[str]:
        names = ["hub.theta", "hub.theta_dot", "tip.deflection", "tip.deflection_dot"]
        for p in self.manipulator.patches:
            names += [f"{p.name}.slope", f"{p.name}.slope_rate"]
        return names

    def output_names(self) -> list[str]:
        return ["motor.torque"] + [f"{p.name}.voltage" for p in self.manipulator.patches]

    def _measure(self, q: np.ndarray, v: np.ndarray) -> dict[str, float]:
        out = {"hub.theta": q[0], "hub.theta_dot": v[0], "tip.deflection": q[1:] @ self.tip_shape,
               "tip.deflection_dot": v[1:] @ self.tip_shape}
        slope, rate = self._Psi @ q[1:], self._Psi @ v[1:]
        for k, p in enumerate(self.manipulator.patches):
            out[f"{p.name}.slope"] = slope[k]
            out[f"{p.name}.slope_rate"] = rate[k]
        return out

    def model(self, *, torque=None, modal_force=None):
        """The planar model.  Without arguments: both laws embedded (zero delay).

        ``torque(t)`` / ``modal_force(t)`` replace the PD / PZT law by time functions (history or
        held controller outputs).
        """
        from ..flexible import ModalForce
        from ..planar import ActuatedHinge, Fixed, PlanarModel, RigidBody
        from ..planar.elements import FixedMounting

        hub = RigidBody("hub", mass=self.hub_mass, inertia=self.manipulator.hub.inertia,
                        center_of_mass=(0.0, 0.0), outboard=(self.manipulator.hub.radius, 0.0))
        if torque is None and self.pd is not None:
            ref = self.reference
            motor = ActuatedHinge("motor", kp=self.pd.kp, kd=self.pd.kd,
                                  reference=ref.angle, reference_rate=ref.rate)
        else:
            law = torque or (lambda t: 0.0)
            motor = ActuatedHinge("motor", torque=law)
        forces = []
        if modal_force is not None:
            forces.append(ModalForce(force=modal_force, label="PZT (history/held)"))
        elif self.pzt is not None:
            if self.pzt.on_limit == "saturate":
                forces.append(ModalForce(law=self._saturated_law(), label="PZT (saturated)"))
            else:
                forces.append(ModalForce(damping=self.pzt_damping, label="PZT modal-velocity feedback"))
        beam = self._beam.with_modal_forces(*forces) if forces else self._beam
        return PlanarModel.chain("manipulator", [Fixed("ground"), motor, hub, FixedMounting("mount"), beam],
                                 gravity=(0.0, 0.0))

    def _saturated_law(self):
        Psi, ca, G = self._Psi, self.manipulator.moments_per_volt, self.pzt.gains
        limit = self.manipulator.voltage_limit

        def law(t, eta, eta_dot):                       # complex-step safe saturation
            V = -G @ (Psi @ eta_dot)
            Vr = np.real(V)
            V = np.where(Vr > limit, limit + 0 * V, np.where(Vr < -limit, -limit + 0 * V, V))
            return Psi.T @ (ca * V)

        return law

    # ------------------------------------------------------------------ simulation
    def simulate(self, t_final: float, dt: float, *, method: str = "rk4", controllers: Sequence[Any] = (),
                 store_every: int = 1, theta0: float | None = None, divergence_bound: float | None = None,
                 stability_check: str = "warn") -> ManipulatorSimulation:
        """Simulate from rest at ``theta0`` (default ``theta_d(0)``) over ``[0, t_final]``.

        Parameters
        ----------
        t_final, dt : float
            End time and step [s] (``t_final`` a whole multiple of ``dt``).
        method : {"rk4", "newmark"}
        controllers : sequence of Controller
            Co-simulated controllers (module docstring).
        store_every : int
            Keep every ``store_every``-th step, >= 1.
        theta0 : float, optional
            Initial hub angle [rad].
        divergence_bound : float, optional
            Largest allowed distance of the hub angle [rad] or a modal coordinate [m] from its
            initial value; default ``1e6 * max(1, |theta0|)``; ``math.inf`` checks only
            finiteness.  (The arm's own bound -- deflection beyond its length -- always applies.)
        stability_check : {"warn", "error", "ignore"}
            ``"rk4"``: compare ``omega_max dt`` with ``2 sqrt 2`` before the run (``omega_max``
            of the linearisation about the initial state, embedded laws included).

        Raises
        ------
        SimulationError
            Divergence, a voltage limit (``on_limit="raise"``) or a controller that raises or
            returns NaN or the wrong number of outputs: names the time and the coordinate, patch
            or controller; ``partial_result`` is the :class:`ManipulatorSimulation` up to the
            last stored step.  A controller whose ``init`` fails: named, without a partial result.
        """
        from ..planar.guards import check_scheme, divergence_guard, with_partial
        from ..planar.integrate import check_store_every, step_total

        if method not in METHODS:
            raise ModelError(f"method must be one of {METHODS}, got {method!r}")
        n_steps = step_total(t_final, dt)              # validates t_final and dt
        dt = float(dt)
        store_every = check_store_every(store_every)
        if theta0 is not None:
            theta0 = validation.finite("theta0", theta0)
        plan = _Plan(self, controllers, dt)
        theta_start = float(self.reference.angle(0.0)) if theta0 is None else validation.finite("theta0", theta0)
        run = _Run(self, plan, dt, n_steps, theta_start)
        try:
            run.guard = divergence_guard(run.model, run.q0, divergence_bound)
            if method == "rk4":
                check_scheme(run.model, run.q0, np.zeros_like(run.q0), dt, scheme="rk4", policy=stability_check)
            elif stability_check not in ("warn", "error", "ignore"):
                raise ModelError(f"stability_check must be one of ('warn', 'error', 'ignore'), "
                                 f"got {stability_check!r}")
            start = _time.perf_counter()
            try:
                if method == "rk4":
                    run.rk4(store_every)
                else:
                    run.newmark(store_every)
            except SimulationError as exc:
                raise with_partial(exc, lambda: run.result(method, _time.perf_counter() - start)) from exc.__cause__
            wall = _time.perf_counter() - start
            return run.result(method, wall)
        finally:
            run.cosim.close()                          # release controller resources (FMU instances)


class _Plan:
    """Which law is embedded, history-based or co-simulated (validated once)."""

    def __init__(self, owner: FlexibleManipulator, controllers: list, dt: float) -> None:
        controllers = list(controllers)
        for i, c in enumerate(controllers):
            for attr in ("inputs", "outputs", "init", "step"):
                if not hasattr(c, attr):
                    raise ModelError(f"controller {i} ({c!r}) lacks {attr!r} (see ctmm.control.protocol)")
        self.actuators = owner.output_names()          # [motor torque, patch voltages...]
        written = check_wiring(controllers, owner.signal_names(), self.actuators, dt,
                               what="manipulator controllers")
        self.controllers = controllers
        self.labels = [f"controller {i} ({getattr(c, 'name', type(c).__name__)})" for i, c in enumerate(controllers)]
        self.torque_by_controller = self.actuators[0] in written
        self.voltage_by_controller = any(name in written for name in self.actuators[1:])
        pd, pzt = owner.pd, owner.pzt
        self.pd_delayed = (not self.torque_by_controller and pd is not None and pd.delay > 0.0)
        self.pzt_delayed = (not self.voltage_by_controller and pzt is not None and pzt.delay > 0.0)
        for law, flag in ((pd, self.pd_delayed), (pzt, self.pzt_delayed)):
            if flag and law.delay < dt * (1 - 1e-9):
                raise ModelError(f"loop delay {law.delay!r} s is shorter than the step dt = {dt!r} s; "
                                 "use delay = 0 (embedded) or delay >= dt")
        self.embedded_pd = pd is not None and not self.torque_by_controller and not self.pd_delayed
        self.embedded_pzt = pzt is not None and not self.voltage_by_controller and not self.pzt_delayed
        self.needs_inputs = self.torque_by_controller or self.voltage_by_controller or self.pd_delayed \
            or self.pzt_delayed


class _Run:
    """Mutable state of one simulation: history, held controller outputs, records."""

    def __init__(self, owner: FlexibleManipulator, plan: _Plan, dt: float, n_steps: int, theta0: float) -> None:
        self.o, self.plan, self.h, self.N = owner, plan, dt, n_steps
        m = owner.manipulator
        self.P = m.n_patches
        self.ca = m.moments_per_volt
        self.limit = m.voltage_limit
        self.policy = owner.pzt.on_limit if owner.pzt is not None else "report"
        self.held_torque = 0.0
        self.held_voltage = np.zeros(self.P)
        q0 = np.zeros(1 + owner.n_modes)
        q0[0] = theta0
        delays = [law.delay for law, flag in ((owner.pd, plan.pd_delayed), (owner.pzt, plan.pzt_delayed)) if flag]
        window = {"delay": max(delays, default=0.0), "step": dt, "interpolation": "lagrange"}
        self.hist_q = DelayHistory(0.0, q0, **window)              # before the model: probed at t = 0
        self.hist_v = DelayHistory(0.0, np.zeros_like(q0), **window)
        self.model = owner.model(
            torque=(self._torque if (plan.torque_by_controller or plan.pd_delayed) else None),
            modal_force=(self._modal_force if (plan.voltage_by_controller or plan.pzt_delayed) else None))
        if self.model.n_coordinates != q0.size:
            raise ModelError(f"the planar model has {self.model.n_coordinates} coordinates, expected {q0.size} "
                             "(hub angle and arm modes; internal error)")
        self.q0 = q0
        self.rec = {k: [] for k in ("t", "q", "v", "V", "tau", "raw")}
        self.guard = None                              # DivergenceGuard, set by simulate
        self.evaluations = 0
        self.iterations: list = []
        self.cosim = CoSimulation(plan.controllers, dt, 0.0, labels=plan.labels)   # init(0) of each controller

    # -- inputs seen by the model (time functions) -------------------------------------
    def _torque(self, t: float) -> float:
        if self.plan.torque_by_controller:
            return self.held_torque
        pd, ref = self.o.pd, self.o.reference
        s = t - pd.delay
        qd, vd = self.hist_q(s), self.hist_v(s)
        sr = max(s, 0.0)
        return pd.kp * (ref.angle(sr) - qd[0]) + pd.kd * (ref.rate(sr) - vd[0])

    def _voltages_delayed(self, t: float) -> np.ndarray:
        vd = self.hist_v(t - self.o.pzt.delay)
        return self.o.pzt.voltages(self.o.slope_matrix @ vd[1:])

    def _modal_force(self, t: float) -> np.ndarray:
        if self.plan.voltage_by_controller:
            V = self.held_voltage
        else:
            V = self._limit(self._voltages_delayed(t), t)
        return self.o.slope_matrix.T @ (self.ca * V)

    def _limit(self, V: np.ndarray, t: float) -> np.ndarray:
        if self.policy == "saturate":
            return np.clip(V, -self.limit, self.limit)
        return V

    # -- per step bookkeeping -------------------------------------------------------------
    def _sample(self, n: int, q: np.ndarray, v: np.ndarray, history: bool = True) -> bool:
        """Controllers due at step ``n``; record inputs/outputs at ``t_n``; history.  Returns
        whether a controller was sampled (its held output may have jumped)."""
        t = n * self.h
        if history and n > 0:                          # the start (n = 0) is the histories' first sample
            self.hist_q.append(t, q)
            self.hist_v.append(t, v)
        sampled = False
        if self.plan.controllers:
            y_all = self.o._measure(q, v)
            controllers = self.plan.controllers
            sampled = bool(self.cosim.sample(n, t, lambda i: np.array([y_all[name] for name in controllers[i].inputs],
                                                             dtype=float)))
            held = self.cosim.held_values(self.plan.actuators)
            self.held_torque, self.held_voltage = float(held[0]), held[1:]
            if self.policy == "saturate":
                self.held_voltage = np.clip(self.held_voltage, -self.limit, self.limit)
        # applied torque and voltages at t_n (records)
        pd, ref = self.o.pd, self.o.reference
        if self.plan.torque_by_controller or self.plan.pd_delayed:
            tau = self._torque(t)
        elif pd is not None:
            tau = pd.kp * (ref.angle(t) - q[0]) + pd.kd * (ref.rate(t) - v[0])
        else:
            tau = 0.0
        if self.plan.voltage_by_controller:
            raw = self.held_voltage.copy()
        elif self.plan.pzt_delayed:
            raw = self._voltages_delayed(t)
        elif self.o.pzt is not None:
            raw = self.o.pzt.voltages(self.o.slope_matrix @ v[1:])
        else:
            raw = np.zeros(self.P)
        if self.policy == "raise" and self.P and np.max(np.abs(raw)) > self.limit:
            k = int(np.argmax(np.abs(raw)))
            raise SimulationError(f"voltage limit exceeded at t = {t:.6g} s: patch "
                                  f"{self.o.manipulator.patch_names[k]!r} needs {raw[k]:.4g} V, limit "
                                  f"{self.limit:g} V", time=t, element=self.o.manipulator.patch_names[k])
        self._current = (t, q.copy(), v.copy(), self._limit(raw, t), tau, raw)
        return sampled

    def _store(self) -> None:
        t, q, v, V, tau, raw = self._current
        for key, value in zip(("t", "q", "v", "V", "tau", "raw"), (t, q, v, V, tau, raw)):
            self.rec[key].append(value)

    # -- integrators ---------------------------------------------------------------------------
    def rk4(self, store_every: int) -> None:
        from ..flexible.outputs import check_divergence
        from ..ode import integrate_rk4, second_order_rate
        from ..planar.integrate import guard_rates
        from ..planar.sweep import accelerations

        model, h, N = self.model, self.h, self.N
        n = len(self.q0)

        def after_step(k: int, t: float, y: np.ndarray) -> None:
            q, v = y[:n], y[n:]
            self.evaluations += 4
            self.guard.check(t, q)
            guard_rates(model, t, v)
            check_divergence(model, q, t, h, "rk4")
            self._sample(k, q, v)
            if k % store_every == 0 or k == N:
                self._store()

        self._sample(0, self.q0, np.zeros_like(self.q0))
        self._store()
        rate = second_order_rate(lambda q, v, t: accelerations(model, q, v, t), n)
        integrate_rk4(rate, np.concatenate((self.q0, np.zeros_like(self.q0))), h=h, n_steps=N, after_step=after_step)

    def newmark(self, store_every: int) -> None:
        """One implicit run; at every accepted step its callback appends the histories, samples the
        controllers (a new held output restarts the step's acceleration) and stores the records."""
        from ..planar import simulate_implicit
        from ..schemes import Newmark

        q, v = self.q0.copy(), np.zeros_like(self.q0)
        history = self.plan.pd_delayed or self.plan.pzt_delayed

        def after_step(n: int, t: float, qn: np.ndarray, vn: np.ndarray) -> bool:
            sampled = self._sample(n, qn, vn, history=history)
            if n % store_every == 0 or n == self.N:
                self._store()
            return sampled

        self._sample(0, q, v, history=history)
        self._store()
        try:
            sim = simulate_implicit(self.model, q, v, t_final=self.N * self.h, dt=self.h, scheme=Newmark(0.25, 0.5),
                                    store_every=self.N, divergence_bound=self.guard.bound, stability_check="ignore",
                                    after_step=after_step)
        except SimulationError as exc:
            exc.partial_result = None          # the manipulator's own records are the partial result
            raise
        self.iterations = list(np.asarray(sim.iterations).ravel())
        self.evaluations = int(sim.n_evaluations)

    def result(self, method: str, wall: float) -> ManipulatorSimulation:
        r = self.rec
        t = np.asarray(r["t"], dtype=float)
        n = 1 + self.o.n_modes
        Q = np.asarray(r["q"], dtype=float).reshape(len(t), n)       # (0, n) if nothing was stored
        Vt = np.asarray(r["v"], dtype=float).reshape(len(t), n)
        V = np.asarray(r["V"], dtype=float).reshape(len(t), self.P)
        raw = np.asarray(r["raw"], dtype=float).reshape(len(t), self.P)
        over = np.any(np.abs(raw) > self.limit, axis=1) if self.P else np.zeros(len(t), bool)
        step = np.diff(t).mean() if len(t) > 1 else self.h
        ref = self.o.reference
        return ManipulatorSimulation(
            t=t, theta=Q[:, 0], theta_dot=Vt[:, 0], desired=np.array([ref.angle(float(x)) for x in t]),
            q=Q[:, 1:], q_dot=Vt[:, 1:], tip_deflection=Q[:, 1:] @ self.o.tip_shape, voltages=V,
            torque=np.asarray(r["tau"], dtype=float), method=method, dt=self.h, wall_time_s=wall,
            n_evaluations=self.evaluations, voltage_limit=self.limit,
            peak_voltage=float(np.max(np.abs(raw), initial=0.0)),
            time_over_limit=float(np.count_nonzero(over) * step),
            saturated=(over if self.policy == "saturate" else np.zeros(len(t), bool)),
            iterations=np.asarray(self.iterations) if self.iterations else None,
            extra=self.cosim.outputs(until=float(t[-1]) if len(t) else -math.inf))
