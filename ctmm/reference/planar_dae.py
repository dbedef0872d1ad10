"""Independent global DAE reference for planar rigid-body systems with closed loops (no transfer matrices).

Written from scratch for the closed-loop and nonlinear-law checks (issue 16); it shares no code with
:mod:`ctmm.planar`, :mod:`ctmm.nonlinear_laws` or the closed-loop mechanism -- its inputs are plain
numbers and plain functions.

Formulation
-----------
Absolute coordinates ``q = (x_C, y_C, theta)`` of every body's centre of mass; the mass matrix
``M = diag(m, m, J_C)``.  A revolute joint makes point ``s_a`` of body ``a`` (or a ground point)
coincide with point ``s_b`` of body ``b``::

    Phi = r_a + R(theta_a) s_a - r_b - R(theta_b) s_b = 0          (2 equations)

with the Jacobian ``Phi_q = [I, R'(theta_a) s_a | -I, -R'(theta_b) s_b]`` and
``Phi_q q'' = gamma = R(theta_a) s_a w_a^2 - R(theta_b) s_b w_b^2``.  The joint may carry a moment law:
``f(delta, rate)`` with ``delta = theta_b - theta_a - rest``, the moment ``-f`` acting on ``b`` and ``+f``
on ``a``.  A bushing (:meth:`PlanarDAE.add_bushing`) is a force element instead of a constraint: the
radial force ``-f(|d|) d / |d|`` on ``b`` of the separation ``d = P_b - P_a`` (and its moment law).  A motor
(:meth:`PlanarDAE.add_motor`) is a control input: the torque ``T = law(t, delta, rate)`` on ``b`` (``-T`` on ``a``)
of the relative angle ``delta = theta_b - theta_a`` and its rate read ``delay`` seconds earlier (the initial state
held before ``t = 0``); with a delay the run is the method of steps (segments of the shortest delay, each reading
the dense output of the completed ones).  A drive (:meth:`PlanarDAE.add_drive`) is one more constraint row: the
relative angle ``theta_b - theta_a = angle(t)``, its multiplier the drive's moment on ``b``.  Index-1 form with Baumgarte stabilisation (``gamma - 2 alpha Phi' - beta^2 Phi``)::

    [[M, Phi_q^T], [Phi_q, 0]] [q''; mu] = [Q; gamma - 2 alpha Phi' - beta^2 Phi]

solved at every right-hand side by a dense solve, integrated by ``scipy.integrate.solve_ivp`` (DOP853) at
tight tolerance.  The joint force on body ``b`` is ``+mu`` (on ``a``: ``-mu``); the position drift
``max |Phi|`` is reported (:attr:`DAESolution.max_drift`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np
import scipy.integrate

from ..errors import ModelError

__all__ = ["PlanarDAE", "DAESolution"]


def _rotation(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


_TURN = np.array([[0.0, -1.0], [1.0, 0.0]])


@dataclass
class _Body:
    name: str
    mass: float
    inertia: float
    points: dict


@dataclass
class _Revolute:
    a: int | None                # body index; None = ground
    point_a: np.ndarray          # body-frame vector from the centre of mass (or ground position)
    b: int
    point_b: np.ndarray
    moment: Callable | None
    rest: float


@dataclass
class _Bushing:
    a: int | None
    point_a: np.ndarray
    b: int
    point_b: np.ndarray
    radial: Callable
    moment: Callable | None
    rest: float


@dataclass
class _Motor:
    a: int | None
    b: int
    law: Callable
    delay: float


@dataclass
class DAESolution:
    """Time history of a :class:`PlanarDAE` run.

    Attributes
    ----------
    t : ndarray (N,)
        Times [s].
    q, v : ndarray (N, 3 n_bodies)
        ``(x_C, y_C, theta)`` per body [m, m, rad] and their rates.
    drift : ndarray (N,)
        ``max |Phi|`` of all joints [m].
    forces : ndarray (N, n_joints, 2)
        Joint force on body ``b`` of each joint, global axes [N].
    names : tuple of str
        Body names.
    drive_moments : ndarray (N, n_drives)
        Moment of each drive (:meth:`PlanarDAE.add_drive`) on its body ``b`` [N m].
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    drift: np.ndarray
    forces: np.ndarray
    names: tuple
    drive_moments: np.ndarray | None = None

    def angle(self, body: str) -> np.ndarray:
        """Absolute angle history of ``body`` [rad]."""
        return self.q[:, 3 * self.names.index(body) + 2]

    def rate(self, body: str) -> np.ndarray:
        """Angular velocity history of ``body`` [rad/s]."""
        return self.v[:, 3 * self.names.index(body) + 2]

    @property
    def max_drift(self) -> float:
        """Largest constraint violation over the run [m]."""
        return float(np.max(self.drift))


class PlanarDAE:
    """Planar rigid bodies joined by revolute joints (any topology, closed loops included).

    Parameters
    ----------
    gravity : (float, float)
        [m/s^2].
    """

    def __init__(self, gravity: Sequence[float] = (0.0, -9.81)) -> None:
        self.gravity = np.asarray(gravity, float)
        self.bodies: list[_Body] = []
        self.joints: list[_Revolute] = []
        self.bushings: list[_Bushing] = []
        self.motors: list[_Motor] = []
        self.drives: list[tuple] = []               # (a, b, angle, rate, acceleration): theta_b - theta_a = angle(t)
        self._history: Callable | None = None       # t -> (q, v) of the completed run (delayed motors)
        self._layout: tuple | None = None          # (key, arrays) of _joint_layout
        self._block: tuple | None = None           # (key, matrix) of _mass_block

    def add_body(self, name: str, *, mass: float, inertia: float, points: Mapping[str, Sequence[float]]) -> None:
        """A body with ``mass`` [kg], ``inertia`` about its centre of mass [kg m^2] and named ``points``
        (body-frame vectors from the centre of mass [m])."""
        if not (mass > 0 and inertia > 0):
            raise ModelError(f"PlanarDAE body {name!r}: mass and inertia must be > 0, got {mass!r}, {inertia!r}")
        self.bodies.append(_Body(name, float(mass), float(inertia),
                                 {k: np.asarray(p, float) for k, p in points.items()}))

    def _index(self, name: str) -> int:
        for i, body in enumerate(self.bodies):
            if body.name == name:
                return i
        raise ModelError(f"PlanarDAE: no body {name!r}")

    def add_revolute(self, body_a: str | None, point_a, body_b: str, point_b: str, *,
                     moment: Callable[[float, float], float] | None = None, rest: float = 0.0) -> None:
        """Revolute joint between ``body_a`` point ``point_a`` (or the ground point ``point_a`` = (x, y) when
        ``body_a`` is None) and ``body_b`` point ``point_b``, with an optional moment law ``moment(delta, rate)``
        (restoring moment [N m] of ``delta = theta_b - theta_a - rest``)."""
        self.joints.append(_Revolute(*self._ends(body_a, point_a, body_b, point_b), moment, float(rest)))

    def _ends(self, body_a: str | None, point_a, body_b: str, point_b: str) -> tuple:
        """``(a, s_a, b, s_b)``: body indices (None: ground) and body-frame vectors (ground: the position)."""
        if body_a is None:
            a, sa = None, np.asarray(point_a, float)
        else:
            a = self._index(body_a)
            sa = self.bodies[a].points[point_a]
        b = self._index(body_b)
        return a, sa, b, self.bodies[b].points[point_b]

    def add_bushing(self, body_a: str | None, point_a, body_b: str, point_b: str, *,
                    radial: Callable[[float], float], moment: Callable[[float, float], float] | None = None,
                    rest: float = 0.0) -> None:
        """A force element (no constraint) between ``body_a`` point ``point_a`` (or the ground point) and
        ``body_b`` point ``point_b``: with ``d = P_b - P_a`` the force on ``b`` is ``-radial(|d|) d / |d|``
        (``-`` of it on ``a``), plus the optional moment law of :meth:`add_revolute`."""
        self.bushings.append(_Bushing(*self._ends(body_a, point_a, body_b, point_b), radial, moment, float(rest)))

    def add_motor(self, body_a: str | None, body_b: str, law: Callable[[float, float, float], float], *,
                  delay: float = 0.0) -> None:
        """A control torque ``T = law(t, delta, rate)`` [N m] on ``body_b`` (``-T`` on ``body_a``; ground when None)
        of the relative angle ``delta = theta_b - theta_a`` [rad] and its rate [rad/s] at ``t - delay`` [s] (before
        ``t = 0``: the initial state)."""
        if not delay >= 0.0:
            raise ModelError(f"PlanarDAE motor: delay must be >= 0 s, got {delay!r}")
        self.motors.append(_Motor(None if body_a is None else self._index(body_a), self._index(body_b), law,
                                  float(delay)))

    def add_drive(self, body_a: str | None, body_b: str, angle: Callable[[float], float],
                  rate: Callable[[float], float], acceleration: Callable[[float], float]) -> None:
        """A prescribed relative angle ``theta_b - theta_a = angle(t)`` [rad] (``theta_a = 0`` at the ground) with
        its rate and acceleration: one more constraint row, appended after the joints' rows; its multiplier is the
        drive's moment on ``body_b`` [N m] (``-`` of it on ``body_a``)."""
        self.drives.append((None if body_a is None else self._index(body_a), self._index(body_b), angle, rate,
                            acceleration))

    def _drive_rows(self, q: np.ndarray, v: np.ndarray, t: float) -> tuple[np.ndarray, ...]:
        """``Phi``, ``Phi'``, ``Phi_q`` and ``gamma`` of the drives at time ``t`` [s]."""
        nd, nb = len(self.drives), len(self.bodies)
        phi, phi_dot, jac, gamma = np.zeros(nd), np.zeros(nd), np.zeros((nd, 3 * nb)), np.zeros(nd)
        for k, (a, b, angle, rate, acceleration) in enumerate(self.drives):
            # sign: the joints' rows are Phi = P_a - P_b with the force +mu on b; here Phi = angle(t) - (th_b - th_a)
            # so that M q'' = Q - Phi_q^T mu puts +mu on body b
            phi[k] = angle(t) - q[3 * b + 2] + (0.0 if a is None else q[3 * a + 2])
            phi_dot[k] = rate(t) - v[3 * b + 2] + (0.0 if a is None else v[3 * a + 2])
            jac[k, 3 * b + 2] = -1.0
            if a is not None:
                jac[k, 3 * a + 2] = 1.0
            gamma[k] = -acceleration(t)
        return phi, phi_dot, jac, gamma

    def _motor_torques(self, t: float, q: np.ndarray, v: np.ndarray, Q: np.ndarray) -> None:
        for motor in self.motors:
            if motor.delay > 0.0:
                qs, vs = self._history(t - motor.delay)
            else:
                qs, vs = q, v
            ta = 0.0 if motor.a is None else qs[3 * motor.a + 2]
            wa = 0.0 if motor.a is None else vs[3 * motor.a + 2]
            torque = float(motor.law(t, qs[3 * motor.b + 2] - ta, vs[3 * motor.b + 2] - wa))
            Q[3 * motor.b + 2] += torque
            if motor.a is not None:
                Q[3 * motor.a + 2] -= torque

    # ------------------------------------------------------------------------------------------------
    def assemble(self, angles: Mapping[str, float], rates: Mapping[str, float],
                 offsets: Mapping[str, Sequence[float]] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Consistent ``(q, v)`` from every body's absolute angle and rate: positions follow the joints (and
        bushings, with the body's ``offsets`` [m] of its bushing point from the other point, at rest relative
        to it) from the ground; joints closing a loop are only checked afterwards (:meth:`constraints`)."""
        offsets = {name: np.asarray(value, float) for name, value in (offsets or {}).items()}
        nb = len(self.bodies)
        q, v = np.zeros(3 * nb), np.zeros(3 * nb)
        for i, body in enumerate(self.bodies):
            q[3 * i + 2], v[3 * i + 2] = angles[body.name], rates[body.name]
        placed: set = set()
        for _ in range(nb):
            for joint in self.joints + self.bushings:
                if joint.b in placed or (joint.a is not None and joint.a not in placed):
                    continue
                point, velocity = self._point(q, v, joint.a, joint.point_a)
                i = joint.b
                r = _rotation(q[3 * i + 2]) @ joint.point_b
                q[3 * i:3 * i + 2] = point - r + offsets.get(self.bodies[i].name, 0.0)
                v[3 * i:3 * i + 2] = velocity - v[3 * i + 2] * (_TURN @ r)
                placed.add(i)
        if len(placed) != nb:
            raise ModelError("PlanarDAE.assemble: some bodies are not connected to the ground")
        return q, v

    def _point(self, q, v, i, s):
        if i is None:
            return s.copy(), np.zeros(2)
        r = _rotation(q[3 * i + 2]) @ s
        return q[3 * i:3 * i + 2] + r, v[3 * i:3 * i + 2] + v[3 * i + 2] * (_TURN @ r)

    def _joint_layout(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(bodies, points, jacobian)`` of the joints, built once per set of bodies and joints: body indices
        ``(2, nj)`` of sides ``a`` and ``b`` (the ground: ``n_bodies``), their body-frame points ``(2, nj, 2)``
        and ``Phi_q`` ``(nj, 2, 3 (nb + 1))`` with its constant (translation) entries, the rotation columns 0."""
        nb = len(self.bodies)
        key = (nb, tuple(map(id, self.joints)))
        cached = self._layout
        if cached is not None and cached[0] == key:
            return cached[1]
        bodies = np.array([[nb if j.a is None else j.a for j in self.joints], [j.b for j in self.joints]], dtype=int)
        points = np.array([[j.point_a for j in self.joints], [j.point_b for j in self.joints]], dtype=float)
        rows = np.arange(len(self.joints))
        jac = np.zeros((len(self.joints), 2, 3 * (nb + 1)))
        for side, sign in ((0, 1.0), (1, -1.0)):
            jac[rows, 0, 3 * bodies[side]] = sign
            jac[rows, 1, 3 * bodies[side] + 1] = sign
        self._layout = (key, (bodies, points, jac))
        return bodies, points, jac

    def constraints(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``Phi``, ``Phi'``, ``Phi_q`` and ``gamma`` of all joints (all joints at once, both sides of every joint
        at once: the ground is one more body at rest at the origin, its columns dropped; ``Phi = P_a - P_b``)."""
        nb, nj = len(self.bodies), len(self.joints)
        if nj == 0:
            return np.zeros(0), np.zeros(0), np.zeros((0, 3 * nb)), np.zeros(0)
        bodies, s, jac0 = self._joint_layout()
        q_all = np.concatenate([np.asarray(q, float), np.zeros(3)]).reshape(nb + 1, 3)
        v_all = np.concatenate([np.asarray(v, float), np.zeros(3)]).reshape(nb + 1, 3)
        theta, omega = q_all[bodies, 2], v_all[bodies, 2]                     # (2, nj): sides a, b
        cos, sin = np.cos(theta), np.sin(theta)
        r, turned = np.empty(s.shape), np.empty(s.shape)                     # (2, nj, 2)
        r[..., 0] = cos * s[..., 0] - sin * s[..., 1]
        r[..., 1] = sin * s[..., 0] + cos * s[..., 1]
        turned[..., 0] = -r[..., 1]                                           # _TURN @ r
        turned[..., 1] = r[..., 0]
        points = q_all[bodies, :2] + r
        velocities = v_all[bodies, :2] + omega[..., None] * turned
        centripetal = r * (omega ** 2)[..., None]
        jac = jac0.copy()
        rows = np.arange(nj)
        jac[rows, :, 3 * bodies[0] + 2] = turned[0]
        jac[rows, :, 3 * bodies[1] + 2] = -turned[1]
        return ((points[0] - points[1]).ravel(), (velocities[0] - velocities[1]).ravel(),
                jac[:, :, :3 * nb].reshape(2 * nj, 3 * nb), (centripetal[0] - centripetal[1]).ravel())

    def _generalised_forces(self, q: np.ndarray, v: np.ndarray, t: float = 0.0) -> np.ndarray:
        nb = len(self.bodies)
        Q = np.zeros(3 * nb)
        self._motor_torques(t, q, v, Q)
        for i, body in enumerate(self.bodies):
            Q[3 * i:3 * i + 2] = body.mass * self.gravity
        for bushing in self.bushings:
            pa, _ = self._point(q, v, bushing.a, bushing.point_a)
            pb, _ = self._point(q, v, bushing.b, bushing.point_b)
            d = pb - pa
            r = math.hypot(d[0], d[1])
            force = -float(bushing.radial(r)) * d / r if r > 0.0 else np.zeros(2)
            for i, s, sign in ((bushing.b, bushing.point_b, 1.0), (bushing.a, bushing.point_a, -1.0)):
                if i is None:
                    continue
                arm = _rotation(q[3 * i + 2]) @ s
                Q[3 * i:3 * i + 2] += sign * force
                Q[3 * i + 2] += sign * (arm[0] * force[1] - arm[1] * force[0])
        for joint in self.joints + self.bushings:
            if joint.moment is None:
                continue
            ta = 0.0 if joint.a is None else q[3 * joint.a + 2]
            wa = 0.0 if joint.a is None else v[3 * joint.a + 2]
            f = float(joint.moment(q[3 * joint.b + 2] - ta - joint.rest, v[3 * joint.b + 2] - wa))
            Q[3 * joint.b + 2] -= f
            if joint.a is not None:
                Q[3 * joint.a + 2] += f
        return Q

    def solve(self, q: np.ndarray, v: np.ndarray, baumgarte: float = 0.0, t: float = 0.0
              ) -> tuple[np.ndarray, np.ndarray]:
        """Accelerations ``q''`` and multipliers ``mu`` (joint forces on the ``b`` bodies) at ``(q, v)`` and time
        ``t`` [s] (the motors' laws; delayed motors read the run in progress)."""
        return self._solve_rows(q, v, baumgarte, t)[:2]

    def _mass_block(self, rows: int) -> np.ndarray:
        """A new ``(3 nb + rows) x (3 nb + rows)`` matrix, zero but for the bodies' diagonal mass block ``diag(m, m,
        J)`` (the constant part of the system of :meth:`_solve_rows`; built once per set of bodies)."""
        size = 3 * len(self.bodies) + rows
        key = (tuple(map(id, self.bodies)), rows)
        if self._block is None or self._block[0] != key:
            block = np.zeros((size, size))
            block[:3 * len(self.bodies), :3 * len(self.bodies)] = np.diag(
                np.concatenate([[b.mass, b.mass, b.inertia] for b in self.bodies]))
            self._block = (key, block)
        return self._block[1].copy()

    def _solve_rows(self, q: np.ndarray, v: np.ndarray, baumgarte: float, t: float
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`solve` and the joints' ``Phi`` [m] at ``(q, v)`` (the drift of a stored row)."""
        nb = len(self.bodies)
        joints = self.constraints(q, v)
        phi, phi_dot, jac, gamma = ((np.concatenate([x, y]) if len(y) else x)
                                    for x, y in zip(joints, self._drive_rows(q, v, t)))
        m = len(phi)
        A = self._mass_block(m)
        A[:3 * nb, 3 * nb:] = jac.T
        A[3 * nb:, :3 * nb] = jac
        rhs = np.concatenate([self._generalised_forces(q, v, t),
                              gamma - 2.0 * baumgarte * phi_dot - baumgarte ** 2 * phi])
        x = np.linalg.solve(A, rhs)
        # M q'' = Q - Phi_q^T x: the force on body b of joint k is +x_k (Phi_q block of b is -I)
        return x[:3 * nb], x[3 * nb:], joints[0]

    def simulate(self, state: tuple[np.ndarray, np.ndarray], t_final: float, *, t_eval: np.ndarray | None = None,
                 baumgarte: float = 10.0, rtol: float = 1e-11, atol: float = 1e-12) -> DAESolution:
        """Integrate from ``state = (q0, v0)`` (:meth:`assemble`) to ``t_final`` [s] (DOP853, tight)."""
        q0, v0 = state
        n = len(q0)
        y0 = np.concatenate([q0, v0])

        def rhs(t, y):
            a, _ = self.solve(y[:n], y[n:], baumgarte, t)
            return np.concatenate([y[n:], a])

        delays = [motor.delay for motor in self.motors if motor.delay > 0.0]
        segments: list = []                         # (t_start, t_end, dense output) of the completed segments

        def history(t: float) -> tuple[np.ndarray, np.ndarray]:
            if t <= 0.0:
                return q0, v0
            for start, end, dense in reversed(segments):
                if start <= t <= end + 1e-12 * max(1.0, end):     # round-off of the segment ends
                    y = dense(min(t, end))
                    return y[:n], y[n:]
            raise ModelError(f"PlanarDAE: the delayed state at t = {t} s is not yet computed")  # pragma: no cover

        self._history = history
        span = min(delays) if delays else t_final
        times, states, t_start, y = [], [], 0.0, y0
        grid = None if t_eval is None else np.asarray(t_eval, float)
        n_segments = max(1, math.ceil(t_final / span * (1.0 - 1e-12)))
        for segment in range(n_segments):
            last = segment == n_segments - 1
            t_end = t_final if last else (segment + 1) * span
            inside = None if grid is None else grid[(grid >= t_start) & ((grid <= t_end) if last else (grid < t_end))]
            sol = scipy.integrate.solve_ivp(rhs, (t_start, t_end), y, method="DOP853", t_eval=inside, rtol=rtol,
                                            atol=atol, dense_output=bool(delays))
            if not sol.success:
                raise ModelError(f"PlanarDAE.simulate failed: {sol.message}")
            first = 1 if grid is None and times else 0  # without t_eval a segment starts at the previous end
            times.append(sol.t[first:])
            states.append(sol.y[:, first:])
            if delays:                              # one segment only without delays
                segments.append((t_start, t_end, sol.sol))
                y = sol.sol(t_end)
            t_start = t_end
        t_out = np.concatenate(times)
        y_out = np.concatenate(states, axis=1)
        q, v = y_out[:n].T, y_out[n:].T
        solved = [self._solve_rows(qi, vi, baumgarte, ti)[1:] for ti, qi, vi in zip(t_out, q, v)]   # one per row
        drift = np.array([np.max(np.abs(phi), initial=0.0) for _, phi in solved])
        multipliers = np.array([mu for mu, _ in solved])
        rows = 2 * len(self.joints)
        forces = multipliers[:, :rows].reshape(len(t_out), -1, 2)
        return DAESolution(t_out, q, v, drift, forces, tuple(b.name for b in self.bodies), multipliers[:, rows:])

    def energy(self, q: np.ndarray, v: np.ndarray, potentials: Sequence[Callable | None] = ()) -> float:
        """Kinetic + gravitational energy [J], plus ``potentials[k](delta)`` of joint ``k`` (joints, then bushings:
        of their moment law) when given."""
        energy = 0.0
        for i, body in enumerate(self.bodies):
            vel = v[3 * i:3 * i + 2]
            energy += 0.5 * body.mass * vel @ vel + 0.5 * body.inertia * v[3 * i + 2] ** 2
            energy -= body.mass * self.gravity @ q[3 * i:3 * i + 2]
        for joint, potential in zip(self.joints + self.bushings, potentials):
            if potential is not None:
                ta = 0.0 if joint.a is None else q[3 * joint.a + 2]
                energy += float(potential(q[3 * joint.b + 2] - ta - joint.rest))
        return float(energy)
