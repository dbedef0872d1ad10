"""Time-domain simulation of controlled chains (seed 001 §9.6; FORMULAS §5.1-5.2).

How each loop of a :class:`~ctmm.control.loops.ControlledChain` enters the DT-TMM step:

* **real time** (``delay < dt``): implicit, through the extended state of
  :mod:`ctmm.control.loops` with the integrator's linearisation of the sensed quantity
  (``x = cx x + dx``, ``v = A x + B``, ``a = C x + D``) -- no lag.  A delay ``0 < tau < dt`` is
  the linear interpolation between the previous value and the unknown one, so the implicit gain
  is ``K (1 - tau/dt_e)`` plus a known force (``dt_e`` = distance to the evaluation time);
* **time delay** (``delay >= dt``): ``u = -K y(t - tau)`` is known from the stored history and
  enters as an external force (§9.6.2); between stored steps the history
  (:class:`~ctmm.control.history.DelayHistory`) is interpolated by cubic Hermite polynomials
  (``y`` and its derivative) or linearly for accelerations and forces, which keeps the
  integrator's second order; before ``t0`` the history is the initial value;
* **LTI controllers** ``C(s)`` are realised by the trapezoidal (Tustin) rule on the step grid,
  which is second order and adds no lag: ``u_{n+1} = g e_{n+1} + (known)`` is embedded like a gain.

Co-simulated controllers (Python objects or FMUs, :class:`~ctmm.control.protocol.Controller`)
are sampled at their sample time (a multiple of ``dt``) with a zero-order hold by the shared
master :class:`~ctmm.control.cosim.CoSimulation`.  A controller
with direct feedthrough that reads an acceleration or an internal force -- which depend on its
own output at the same instant -- forms an algebraic loop: it is reported (``ModelError``)
unless ``coupling="previous"`` explicitly accepts the one-sample lag.
"""
from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

import numpy as np

from .. import validation
from ..assembly import SOLVERS, predicted_forces, shift_forces
from ..capabilities import require_chain
from ..chain_start import NodeInertia, acceleration_change, initial_acceleration, initial_forces
from ..controller_state_space import controller_state_space
from ..elements.base import Linearisation
from ..elements.lumped import PointElement
from ..errors import ModelError, SimulationError, unknown_name
from ..guard import unstable_loops_hint
from ..results import SimulationResult
from ..saturation import refuse_saturation
from ..schemes import History, as_scheme
from ..signals import as_signal
from ..system import Chain, require_system
from ..timestep import simulate as simulate_plant
from .cosim import CoSimulation, check_wiring
from .history import DelayHistory
from .loops import ControlledChain
from .protocol import Controller, check_controllers, check_references


class _TustinLTI:
    """Trapezoidal realisation of a SISO ``C(s)``: ``u_{n+1} = gain * e_{n+1} + offset(state, e_n)``."""

    def __init__(self, system: Any, dt: float, loop: str = "") -> None:
        A, B, C, D = controller_state_space(loop, system, "in time")
        B, C = B.reshape(-1, 1), C.reshape(1, -1)
        n = A.shape[0]
        self.n = n
        if n == 0:
            self.M1 = np.zeros((0, 0))
            self.M2 = np.zeros((0, 1))
            self.C = np.zeros((1, 0))
        else:
            left = np.eye(n) - 0.5 * dt * A
            self.M1 = np.linalg.solve(left, np.eye(n) + 0.5 * dt * A)
            self.M2 = np.linalg.solve(left, 0.5 * dt * B)
            self.C = C
        self.D = D
        self.gain = float((self.C @ self.M2)[0, 0]) + self.D if n else self.D

    def offset(self, state: np.ndarray, e_n: float) -> float:
        if self.n == 0:
            return 0.0
        return float((self.C @ (self.M1 @ state + self.M2[:, 0] * e_n))[0])

    def advance(self, state: np.ndarray, e_n: float, e_next: float) -> np.ndarray:
        if self.n == 0:
            return state
        return self.M1 @ state + self.M2[:, 0] * (e_n + e_next)


def _sense(terms, x: np.ndarray, v: np.ndarray, a: np.ndarray, f: np.ndarray, d: int):
    """Sensed value and its time derivative (None when unknown) from point arrays."""
    y, dy = 0.0, 0.0
    for point, comp, deriv, weight in terms:
        if comp >= d:  # force component
            y += weight * f[point]
            dy = None
            continue
        series = (x, v, a)
        y += weight * series[deriv][point, comp]
        if dy is not None:
            dy = dy + weight * series[deriv + 1][point, comp] if deriv < 2 else None
    return y, dy


def simulate_controlled(system: ControlledChain | Chain, t_final: float, dt: float, *,
                        scheme: Any = "newmark", x0: Mapping[str, float] | None = None,
                        v0: Mapping[str, float] | None = None, t0: float = 0.0,
                        references: Mapping[str, Any] | None = None,
                        controllers: Sequence[Controller] = (), coupling: str = "hold",
                        progress: bool | None = None, stability_check: str | None = None,
                        divergence_bound: float | None = None) -> SimulationResult:
    """Simulate a chain closed by embedded loops and/or co-simulated controllers.

    Parameters
    ----------
    system : ControlledChain or Chain
        Plant with embedded :class:`~ctmm.control.loops.Feedback` loops (or a bare chain when
        only co-simulated controllers are used).
    t_final, dt : float
        End time and step [s].
    scheme : Scheme or str
        DT-TMM integrator (see :func:`ctmm.simulate`).
    x0, v0 : mapping, optional
        Initial positions / velocities by element name.
    references : mapping, optional
        ``{loop name: r(t)}`` reference signals (default 0): ``u = -C (y - r)``.
    controllers : sequence of Controller
        Co-simulated controllers (Python objects, FMUs) with their sample times.
    coupling : {"hold", "previous"}
        ``"hold"``: zero-order hold, algebraic loops are errors; ``"previous"``: accept the
        one-sample lag of an algebraic loop explicitly.
    progress : bool, optional
        Show a progress bar.
    stability_check : {"warn", "error", "ignore"}, optional
        Pre-run check of ``dt`` against the scheme's limit for the plant's highest undamped
        natural frequency (see :func:`ctmm.timestep.simulate`; loops are not included).
    divergence_bound : float, optional
        Largest allowed distance [m] of a point from rest (default ``1e6 * max(1 m, initial
        excursion)``); beyond it the run stops and the error names the loops.

    Returns
    -------
    SimulationResult
        With loop signals ``"<loop>.y"`` (sensed value) and ``"<loop>.u"`` (control force), and
        each controller output under ``"<output>@samples"`` (columns: sample time, value).

    Raises
    ------
    ModelError
        Bad input; a loop whose algebraic equation at ``t0`` is singular (an undelayed loop that
        senses the acceleration or force it drives, with a gain that cancels the inertia).
    SimulationError
        Divergence, a non-finite state or failing user code (controller, reference or force
        callback), naming the time and the loop, controller or element; ``partial_result``
        holds every signal (loop and controller signals included) up to the last good step.
    """
    require_chain(system, "simulate_controlled")
    system = require_system(system)
    controllers = check_controllers(controllers)
    references = check_references(references)
    dt = validation.positive("dt", dt)
    validation.step_count(validation.finite("t_final", t_final), validation.finite("t0", t0), dt)
    controlled = system if isinstance(system, ControlledChain) else ControlledChain(system, [])
    refuse_saturation(controlled.loops, "a DT-TMM scheme on a 1-D ControlledChain (its loops are embedded linearly "
                      "in the step; use method='rk4' or a solve_ivp method)")
    plant = controlled.plant
    scheme = as_scheme(scheme)
    if coupling not in ("hold", "previous"):
        raise ModelError(f"coupling must be 'hold' or 'previous', got {coupling!r}")
    d = plant.layout.half
    refs = {}
    for name, value in references.items():
        loop_names = [loop.name for loop in controlled.loops]
        if name not in loop_names:
            error = unknown_name("loop", name, loop_names)
            raise type(error)(f"references[{name!r}]: {error}")
        refs[name] = as_signal(f"references[{name!r}] (reference of loop {name!r})", value)
    loops = controlled._resolved
    realtime = [r for r in loops if r.loop.delay < dt]
    delayed = [r for r in loops if r.loop.delay >= dt]
    lti = {r.index: _TustinLTI(r.loop.gain, dt, r.loop.name) for r in loops if r.loop.is_lti}
    ctrl_state = {i: np.zeros(m.n) for i, m in lti.items()}
    try:
        cosim = _ChainControllers(controlled, controllers, dt, coupling, t0)
    except SimulationError as exc:  # a controller's init failed: nothing was computed
        exc.partial_result = SimulationResult.empty(controlled, scheme.name)
        raise
    hist: dict[int, DelayHistory] = {}
    u_prev: dict[int, float] = {}
    e_prev: dict[int, float] = {}
    store = {"t": [], "y": {r.index: [] for r in loops}, "u": {r.index: [] for r in loops}}

    def error_at(r, t: float) -> float:
        ref = refs.get(r.loop.name)
        return hist[r.index](t) - (float(ref(t)) if ref is not None else 0.0)

    def delayed_force(r, t: float) -> float:
        """u(t) = -C[e(t - tau)] for a history loop (controller advanced on the step grid)."""
        e_d = error_at(r, t - r.loop.delay)
        if r.index in lti:
            m = lti[r.index]
            return -(m.gain * e_d + m.offset(ctrl_state[r.index], e_prev[r.index]))
        return -r.loop.gain * e_d

    def force_hook(t_n: float, h: float, w: float, history: History) -> dict[int, float]:
        forces: dict[int, float] = {}
        if not hist:  # initial call (t0): consistent loop forces, then start the histories
            forces = dict(cosim.forces(t_n, history, None))
            u0, a0, f0, pre = _consistent_start(plant, loops, lti, refs, history.x, history.v, t0, forces, d)
            for r in loops:
                y, dy = _sense(r.sensing, history.x, history.v, a0, f0, d)
                hist[r.index] = DelayHistory(t0, y, dy, before=pre[r.index], delay=r.loop.delay, step=dt)
                ref = refs.get(r.loop.name)
                e_prev[r.index] = y - (float(ref(t0)) if ref is not None else 0.0)
                u_prev[r.index] = u0[r.index]
                u_start[r.index] = u0[r.index]
                for pos, _, weight in r.actuators:
                    forces[pos] = forces.get(pos, 0.0) + weight * u0[r.index]
            return forces
        for r in delayed:
            u_new = delayed_force(r, t_n + h)
            u_eval = (1.0 - w) * u_prev[r.index] + w * u_new
            for pos, _, weight in r.actuators:
                forces[pos] = forces.get(pos, 0.0) + weight * u_eval
            _pending[r.index] = u_new
        for pos, value in held_before.items():   # sampled this step by before_step (empty without controllers)
            forces[pos] = forces.get(pos, 0.0) + value
        return forces

    _pending: dict[int, float] = {}
    u_start: dict[int, float] = {}  # loop forces at t0, filled by the initial branch of force_hook
    _last_f = [np.zeros(plant.n_points)]
    _rt_gain: dict[int, float] = {}

    def step(coeffs, t_n, h, w, t_eval, extra, history):
        """Extended (real-time loops) DT-TMM step."""
        lins = [Linearisation(coeffs.cx, float(coeffs.dx[j, 0]), coeffs.A, float(coeffs.B[j, 0]), coeffs.C,
                              float(coeffs.D[j, 0]), float(coeffs.x_pred[j, 0])) for j in range(plant.n_points)]
        Us_p, us_p, unit = [], [], {}
        actuated = {pos for r in loops for pos, _, _ in r.actuators}
        for j, e in enumerate(plant.body, start=1):
            force = extra.get(j, 0.0)
            if isinstance(e, PointElement):
                force += (1.0 - w) * float(e.force(t_n)) + w * float(e.force(t_n + h))
            disc = e.discretize(scheme)
            U, u = disc.step_matrices(t_eval, lins[j - 1], lins[j], force)
            if j in actuated:  # unit-input column of the step (affine response to a unit force)
                unit[j] = np.asarray(disc.step_matrices(t_eval, lins[j - 1], lins[j], force + 1.0)[1], float) - u
            Us_p.append(np.asarray(U, float)[None])
            us_p.append(np.asarray(u, float)[None])
        e_idx, S0, P0 = plant.start.start_discrete(plant.layout, t_eval, lins[0], load_step=(t_n, h, w))
        Bm, b = plant.end.end_discrete(plant.layout, t_eval, lins[-1], load_step=(t_n, h, w))
        from ..assembly import BoundaryEnd, BoundaryStart

        dt_e = coeffs.unknown_offset
        gains, known_u = [], {}
        for r in loops:
            if r.loop.delay >= dt:
                gains.append(np.zeros(1))
                continue
            theta = r.loop.delay / dt_e
            g = lti[r.index].gain if r.index in lti else r.loop.gain
            offset = lti[r.index].offset(ctrl_state[r.index], e_prev[r.index]) if r.index in lti else 0.0
            ref = refs.get(r.loop.name)
            r_eval = float(ref(t_eval - r.loop.delay)) if ref is not None else 0.0
            y_old = hist[r.index](t_n) if theta > 0 else 0.0
            # u = -g [ (1-theta) y_eval + theta y_n - r ] - offset
            gains.append(np.array([g * (1.0 - theta)]))
            known_u[r.index] = -g * (theta * y_old - r_eval) - offset
            _rt_gain[r.index] = g * (1.0 - theta)
        for r in realtime:  # known part of the real-time control force
            for pos, _, weight in r.actuators:
                us_p[pos - 1] = us_p[pos - 1] + weight * known_u[r.index] * unit[pos][None]
        columns = [[(pos, weight * unit[pos][None]) for pos, _, weight in r.actuators] for r in loops]

        def factor(point, comp, deriv):
            if comp >= d:
                return 1.0
            return (coeffs.cx, coeffs.A, coeffs.C)[deriv]

        def offset_fn(point, comp, deriv):
            if comp >= d:
                return 0.0
            return (coeffs.dx, coeffs.B, coeffs.D)[deriv][point, comp]

        Us, us, start, end = controlled._extend(
            np.zeros(1), Us_p, us_p, BoundaryStart(e_idx, S0[None], P0[None]),
            BoundaryEnd(Bm[None], b[None]), gains, [0.0] * len(loops), factor, offset_fn, columns=columns)
        reference_pts = predicted_forces(Us_p, us_p, d)   # incremental-force form on the plant rows
        idx = np.asarray(controlled.state_index)
        reference = np.zeros((len(Us) + 1, 1, d))
        reference[: idx[0] + 1] = reference_pts[0]
        for j in range(1, len(idx)):
            reference[idx[j - 1] + 1: idx[j] + 1] = reference_pts[j]
        us, start, end = shift_forces(Us, us, start, end, reference, d)
        try:
            sol = SOLVERS["riccati"](Us, us, start, end, want_log_det=False)      # states only
        except np.linalg.LinAlgError as exc:
            raise SimulationError(f"the step at t = {t_n + h:.6g} s is singular with the real-time loop(s) "
                                  f"{[r.loop.name for r in realtime]} closed (an algebraic loop through an "
                                  "acceleration or force sensor cancels the inertia); change their gains",
                                  time=float(t_n + h), element=realtime[0].loop.name) from exc
        states = sol.states[idx, 0, :].copy()
        states[:, d:2 * d] += reference_pts[:, 0, :]
        for r in realtime:
            y_eval = states[-1, plant.layout.size + 2 * r.index]
            _pending[r.index] = -_rt_gain[r.index] * y_eval + known_u[r.index]
        return states[:, 0].copy(), states[:, d].copy()

    def after_step(i: int, t: float, history: History, state_row: np.ndarray) -> None:
        f = state_row[:, d]
        _last_f[0] = f
        for r in loops:
            y, dy = _sense(r.sensing, history.x, history.v, history.a, f, d)
            hist[r.index].append(t, y, dy)
            ref = refs.get(r.loop.name)
            e_now = hist[r.index](t - r.loop.delay) - (float(ref(t - r.loop.delay)) if ref is not None else 0.0)
            if r.index in lti:
                ctrl_state[r.index] = lti[r.index].advance(ctrl_state[r.index], e_prev[r.index], e_now)
                u_now = -(lti[r.index].C @ ctrl_state[r.index] if lti[r.index].n else 0.0) - lti[r.index].D * e_now
                u_now = float(np.squeeze(u_now))
            else:
                u_now = -r.loop.gain * e_now
            e_prev[r.index] = e_now
            u_prev[r.index] = u_now
            store["y"][r.index].append(y)
            store["u"][r.index].append(u_now)
        cosim.after_step(t, history, f)

    held_before: dict[int, float] = {}
    lumped = plant.layout.size == 2 and all(e.lumped_coefficients() is not None for e in plant.body)
    inertia = NodeInertia(plant) if lumped and len(cosim.master) else None

    def before_step(i: int, t_n: float, history: History) -> None:
        """Restart the acceleration where a held controller output jumps at ``t_n``.

        The scheme's predictor uses ``a_n``, the acceleration at ``t_n`` under the force held
        BEFORE the sample; a zero-order hold switches the force at ``t_n``, so ``a_n`` is replaced
        by ``a_n + M^-1 dF`` (positions and velocities are continuous; :func:`ctmm.chain_start.
        acceleration_change`: a force on a mass moves its node, a force across a connector both
        neighbours, inerters couple nodes).  Without this restart every switch acts ``dt/2`` late
        and a sampled loop converges at first order in ``dt`` instead of the scheme's order.  A
        multistep scheme also restarts its history (:meth:`ctmm.schemes.Scheme.restart`)."""
        now = cosim.forces(t_n, history, _last_f[0])
        if i > 0 and lumped:
            jumps = {pos: now.get(pos, 0.0) - held_before.get(pos, 0.0) for pos in set(now) | set(held_before)}
            jumps = {pos: jump for pos, jump in jumps.items() if jump != 0.0}
            if jumps:
                history.a += acceleration_change(plant, jumps, inertia)
                scheme.restart(history)           # Houbolt: its start-up again (docs/schemes.md)
        held_before.clear()
        held_before.update(now)

    hints = []
    if loops:
        hints.append(unstable_loops_hint([r.loop.name for r in loops]))
    if len(cosim.master):
        written = [o for c in cosim.master.controllers for o in c.outputs]
        hints.append(f"or a co-simulated controller (outputs {written}) destabilises the plant")
    try:
        result = simulate_plant(plant, t_final, dt, scheme=scheme, x0=x0, v0=v0, t0=t0,
                                force_hook=force_hook, progress=progress,
                                _step=step if realtime else None, _after_step=after_step,
                                _before_step=before_step if len(cosim.master) else None,
                                fast=None if not realtime else False, _system_for_result=controlled,
                                stability_check=stability_check, divergence_bound=divergence_bound,
                                _divergence_hint=" ".join(hints))
    except SimulationError as exc:
        partial = exc.partial_result
        if partial is not None:
            _attach_signals(partial, loops, hist, store, u_start, cosim, dt)
        raise
    finally:
        cosim.close()
    _attach_signals(result, loops, hist, store, u_start, cosim, dt)
    return result


def _attach_signals(result: SimulationResult, loops, hist, store, u_start, cosim: "_ChainControllers",
                    dt: float) -> None:
    """Add loop and controller signals to a (possibly partial) result, cut to its time rows."""
    rows = len(result.time)
    for r in loops:
        if r.index in hist:
            y = np.array([hist[r.index].start_value] + store["y"][r.index])[:rows]
            u = np.array([u_start[r.index]] + store["u"][r.index])[:rows]
        else:  # failed before the loop histories started
            y, u = np.zeros(0), np.zeros(0)
        result.extra[f"{r.loop.name}.y"] = y
        result.extra[f"{r.loop.name}.u"] = u
    last = result.time[-1] if rows else -math.inf
    result.extra.update(cosim.master.outputs(until=last))
    result.info["loops"] = {r.loop.name: ("real-time" if r.loop.delay < dt else "history") for r in loops}
    result.info["controllers"] = cosim.master.describe()


def _consistent_start(plant: Chain, loops, lti, refs, x, v, t0: float, forces: Mapping[int, float], d: int):
    """Loop forces, accelerations and point forces at ``t0`` that satisfy every loop law.

    A delayed loop (``tau > 0``) reads the history before ``t0`` -- the initial state held, with
    zero acceleration -- so its force is known.  An undelayed loop that senses an acceleration or
    an internal force depends on its own force at the same instant; everything is affine in the
    vector of loop forces ``u``, so evaluate the equilibrium at ``u = 0`` and at unit forces and
    solve ``u = -G (y(u) - r)`` exactly.  Returns ``(u, a0, f0, pre)`` with ``pre`` the sensed
    values of the held pre-``t0`` state per loop.
    """

    def sensed(u: np.ndarray) -> np.ndarray:
        extra = dict(forces)
        for r in loops:
            for pos, _, weight in r.actuators:
                extra[pos] = extra.get(pos, 0.0) + weight * u[r.index]
        a = initial_acceleration(plant, x, v, t0, extra)
        f = np.nan_to_num(initial_forces(plant, x, v, extra, a, t0))
        return np.array([_sense(r.sensing, x, v, a, f, d)[0] for r in loops]), a, f

    n = len(loops)
    f_held = np.nan_to_num(initial_forces(plant, x, v, forces, t0=t0))
    pre = {r.index: _sense(r.sensing, x, v, np.zeros_like(x), f_held, d)[0] for r in loops}
    if n == 0:
        a = initial_acceleration(plant, x, v, t0, forces)
        return {}, a, f_held, pre
    gains = np.array([lti[r.index].D if r.index in lti else r.loop.gain for r in loops])
    refs0 = np.array([float(refs[r.loop.name](t0 - r.loop.delay)) if r.loop.name in refs else 0.0
                      for r in loops])
    delayed = np.array([r.loop.delay > 0.0 for r in loops])
    y_pre = np.array([pre[r.index] for r in loops])
    y_zero = sensed(np.zeros(n))[0]
    J = np.column_stack([sensed(np.eye(n)[k])[0] - y_zero for k in range(n)])  # dy/du
    # undelayed rows: u = -G (y0 + J u - r);  delayed rows: u = -G (y_pre - r)
    lhs = np.eye(n) + np.where(delayed[:, None], 0.0, gains[:, None] * J)
    rhs = -gains * (np.where(delayed, y_pre, y_zero) - refs0)
    _, singular_values, vh = np.linalg.svd(lhs)
    if not singular_values[-1] > 1e-12 * max(1.0, singular_values[0]):
        involved = [loops[k] for k in np.flatnonzero(np.abs(vh[-1]) > 1e-6)]
        details = "; ".join(f"loop {r.loop.name!r} senses {[name for name, _ in r.loop.terms]} with gain "
                            f"{gains[r.index]:.6g} and d(sensed)/d(own force) = {J[r.index, r.index]:.6g}"
                            for r in involved)
        raise ModelError(f"singular algebraic loop: {details}. An undelayed loop that senses an acceleration "
                         "or a force depends on its own force at the same instant, and with these gains "
                         "(1 + gain * d(sensed)/d(force) = 0) the closed loop has no unique acceleration "
                         "(the loop cancels the inertia). Change the gain or the sensor, or add a delay")
    u = np.linalg.solve(lhs, rhs)
    y, a, f = sensed(u)
    return {r.index: float(u[r.index]) for r in loops}, a, f, pre


def _check_drivable(plant: Chain, outputs: Sequence[str], actuators: Sequence[Any]) -> None:
    """Refuse controller outputs the time stepper cannot apply (it would drop or misplace them).

    The stepper adds a controller output to the first input of a body element (a force on a
    point element, a force across a connector); boundary inputs (prescribed displacement or
    force) and other inputs of an element are not driven in time.
    """
    for name, actuator in zip(outputs, actuators):
        element = plant.elements[actuator.position]
        if 0 < actuator.position < len(plant.elements) - 1 and actuator.input == element.inputs[0]:
            continue
        drivable = [f"{e.name}.{e.inputs[0]}" for e in plant.body if e.inputs]
        where = "a boundary input" if element not in plant.body else f"not the first input of {element.name!r}"
        raise ModelError(f"controller output {name!r} is {where}, which co-simulated controllers cannot drive "
                         f"in time; drivable outputs: {', '.join(drivable)} (a prescribed boundary motion or "
                         f"force is given as the boundary's own signal, e.g. PrescribedDisplacement(name, function))")


class _ChainControllers:
    """The chain's side of the co-simulation (:class:`~ctmm.control.cosim.CoSimulation`).

    Controller inputs are read from the step's point arrays (positions, velocities,
    accelerations, internal forces); outputs act as forces on the first input of a body element.
    Accelerations and internal forces depend on the outputs at the same instant (algebraic loops).
    """

    def __init__(self, system: ControlledChain, controllers: Sequence[Controller], dt: float, coupling: str,
                 t0: float) -> None:
        plant = system.plant
        self.half = plant.layout.half
        for c in controllers:
            if not isinstance(c, Controller):
                raise ModelError(f"{c!r} does not implement the Controller protocol "
                                 "(inputs, outputs, sample_time, direct_feedthrough, init, step)")
        check_wiring(controllers, plant.signal, plant.input, dt, what="co-simulated controllers of the chain")
        self.sensing = [[plant.signal(n) for n in c.inputs] for c in controllers]
        self.actuators = [[plant.input(n) for n in c.outputs] for c in controllers]
        for c, actuators in zip(controllers, self.actuators):
            _check_drivable(plant, c.outputs, actuators)
        instantaneous = {n for c, sensing in zip(controllers, self.sensing) for n, s in zip(c.inputs, sensing)
                         if s.derivative == 2 or s.component >= self.half}
        self.master = CoSimulation(controllers, dt, t0, coupling=coupling, instantaneous=instantaneous)
        self.step_index = 0

    def _measure(self, sensing, history: History, f: np.ndarray | None) -> np.ndarray:
        y = []
        for s in sensing:
            if s.component >= self.half:
                y.append(0.0 if f is None else float(f[s.point]))
            else:
                y.append(float((history.x, history.v, history.a)[s.derivative][s.point, s.component]))
        return np.array(y)

    def forces(self, t_n: float, history: History, f: np.ndarray | None) -> dict[int, float]:
        """Held controller outputs as forces by element position, sampling the controllers due at ``t_n``."""
        if not self.sensing:
            return {}
        self.master.sample(self.step_index, t_n, lambda i: self._measure(self.sensing[i], history, f))
        out: dict[int, float] = {}
        for actuators, held in zip(self.actuators, self.master.held):
            for act, value in zip(actuators, held):
                out[act.position] = out.get(act.position, 0.0) + float(value)
        return out

    def after_step(self, t: float, history: History, f: np.ndarray) -> None:
        self.step_index += 1

    def close(self) -> None:
        self.master.close()
