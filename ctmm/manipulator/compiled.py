"""Compiled fast path of the manipulator: its scene through the generated kernels (issue 13).

:class:`CompiledManipulator` runs the manipulator with embedded laws (no delay, no saturation, no
co-simulated controller) as the controlled scene
:func:`~ctmm.manipulator.scene.manipulator_scene` -- hub on a torque hinge, modal arm, the PD loop
``"hub_pd"`` and one slope-rate loop per PZT patch on the arm's station ports -- compiled by
:class:`~ctmm.compiled_scene.CompiledScene`: the one articulated sweep generated from the element
definitions, the loops closed inside the generated RK4 stage (:mod:`ctmm.compiled_loops`; the patch
moment pairs cancel on the arm's floating frame, so they act as modal forces), whole intervals of
``block`` steps and ``chunks`` stored states per C call.  The cycloidal reference enters the generated
code as a :class:`~ctmm.compiled_references.SymbolicReference`.  It replaced a hand-derived closed form of
the same sweep (same results to round-off, measured in ``benchmarks/compiled_scenes.py``).

The C library is cached on disk by :mod:`ctmm.codegen` (keyed by the serialized step and sizes, before
any C is generated, the compiler and the flags: :func:`ctmm.generated_loop.compiled_time_loop`;
folder: :func:`ctmm.codegen.cache_directory`).
"""
from __future__ import annotations

import time as _time
from typing import Any

import numpy as np

from .. import validation
from ..compiled_references import SymbolicReference
from ..compiled_scene import CompiledScene
from ..errors import ModelError, SimulationError
from ..guard import DivergenceGuard
from ..planar.guards import check_scheme, check_stored
from ..planar.integrate import step_total
from .laws import HubPD, PZTFeedback, check_pzt
from .parameters import CycloidalMove, Manipulator
from .results import ManipulatorSimulation
from .scene import HUB_LOOP, arm_beam, manipulator_scene, patch_slope_matrix

__all__ = ["CompiledManipulator"]


def cycloid_reference(kp: float, kd: float, move: CycloidalMove) -> SymbolicReference:
    """The hub loop's reference ``kp theta_d(t) + kd theta_d'(t)`` of a cycloidal ``move``, as numbers
    and on casadi symbols (``s = (t - t0) / T`` clipped to ``[0, 1]``)."""
    import casadi as ca

    a, b, duration, start = move.start_angle, move.final_angle, move.duration, move.start_time

    def symbolic(t: Any) -> Any:
        s = ca.fmin(ca.fmax((t - start) / duration, 0.0), 1.0)
        angle = a + (b - a) * (s - ca.sin(2 * ca.pi * s) / (2 * ca.pi))
        rate = (b - a) / duration * (1 - ca.cos(2 * ca.pi * s))
        return kp * angle + kd * rate

    return SymbolicReference(lambda t: kp * move.angle(t) + kd * move.rate(t), symbolic)


class CompiledManipulator:
    """Compiled RK4 of the manipulator with embedded laws: the scene of
    :func:`~ctmm.manipulator.manipulator_scene` with undelayed, unsaturated loops, tracking a cycloidal
    move (module docstring).

    Parameters
    ----------
    manipulator : Manipulator
        The seed's parameters.
    pd : HubPD
        The hub PD, without delay.
    pzt : PZTFeedback or None
        The slope-rate law, without delay and not saturating (``on_limit`` ``"report"`` or ``"raise"``
        is checked after the run).
    reference : CycloidalMove
        The hub's move.
    n_modes : int
        Clamped-free modes of the arm.
    geometric_stiffening : bool
        Centrifugal stiffening of the arm.
    hub_mass : float
        Hub mass [kg] (at the pivot: it does not enter the planar dynamics about it).
    block : int
        RK4 steps per stored state (``store_every``).
    chunks : int
        Stored states per compiled call.

    Attributes
    ----------
    scene : CompiledScene
        The generated kernel of the controlled scene.
    slope_matrix : ndarray (n_patches, n_modes)
        ``Psi``: patch slope differences per modal coordinate.
    """

    def __init__(self, manipulator: Manipulator, pd: HubPD, pzt: PZTFeedback | None, reference: CycloidalMove, *,
                 n_modes: int = 3, geometric_stiffening: bool = True, hub_mass: float = 1.0, block: int = 1,
                 chunks: int = 250) -> None:
        if not isinstance(manipulator, Manipulator):
            raise ModelError(f"manipulator must be a ctmm.manipulator.Manipulator, got {manipulator!r}")
        if pd is not None and not isinstance(pd, HubPD):
            raise ModelError(f"pd must be a ctmm.manipulator.HubPD, got {pd!r}")
        check_pzt(pzt, manipulator.n_patches)
        if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
            raise ModelError(f"n_modes must be an integer >= 1, got {n_modes!r}")
        geometric_stiffening = validation.flag("geometric_stiffening", geometric_stiffening)
        hub_mass = validation.positive("hub_mass", hub_mass)
        problems = []
        if pd is None or pd.delay > 0:
            problems.append("an embedded (undelayed) hub PD")
        if pzt is not None and (pzt.delay > 0 or pzt.on_limit == "saturate"):
            problems.append("an embedded, unsaturated PZT law (no delay)")
        if not isinstance(reference, CycloidalMove):
            problems.append("a CycloidalMove reference")
        if problems:
            raise ModelError("the compiled manipulator path needs " + ", ".join(problems)
                             + "; simulate manipulator_scene(...) with ctmm.simulate instead")
        for label, value in (("block", block), ("chunks", chunks)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ModelError(f"{label} must be an integer >= 1, got {value!r}")
        self.manipulator, self.pd, self.pzt, self.reference = manipulator, pd, pzt, reference
        self.block, self.chunks = int(block), int(chunks)
        self.n = int(n_modes)
        beam = arm_beam(manipulator, self.n, geometric_stiffening)
        self.slope_matrix = patch_slope_matrix(beam, manipulator)
        self.tip_shape = np.asarray(beam.data.tip_phi, dtype=float)
        loops_pzt = None if pzt is None else PZTFeedback(pzt.gains, delay=pzt.delay)   # limit checked after the run
        controlled = manipulator_scene(manipulator, pd=pd, pzt=loops_pzt, n_modes=self.n,
                                       geometric_stiffening=geometric_stiffening, hub_mass=hub_mass)
        self.scene = CompiledScene(controlled, store_every=self.block, rows=self.chunks,
                                   references={HUB_LOOP: cycloid_reference(pd.kp, pd.kd, reference)})

    def accelerations(self, q, qdot, t: float = 0.0, *, dt: float = 1e-3) -> np.ndarray:
        """``[theta'', q'']`` from the compiled sweep with the laws closed (``q, qdot``: hub angle and
        modal coordinates, ``1 + n_modes`` each; ``dt`` is not used: the kernel takes the step at run time)."""
        size = 1 + self.n
        q, qdot = np.asarray(q, dtype=float), np.asarray(qdot, dtype=float)
        if q.shape != (size,) or qdot.shape != (size,):
            raise ModelError(f"q and qdot must have length {size} (hub.theta, arm.q1..q{self.n}), got shapes "
                             f"{q.shape} and {qdot.shape}")
        rates = self.scene.closed_loop_rates(np.concatenate([q, qdot]), validation.finite("t", t))
        return rates[size:2 * size]

    def simulate(self, t_final: float, dt: float, *, theta0: float | None = None,
                 divergence_bound: float | None = None, stability_check: str = "warn") -> ManipulatorSimulation:
        """RK4 from rest; stores every ``block``-th step.  ``t_final`` must be a multiple of
        ``block * dt``.

        ``divergence_bound`` and ``stability_check`` as in :func:`ctmm.simulate`;
        the step is checked against the closed loop's linearised RK4 limit before the run, the bound
        on the stored states after it (no per-step Python work), and a run that diverges or goes
        non-finite raises :class:`~ctmm.errors.SimulationError` at the first bad stored state with
        the history up to the last good one as ``partial_result``.
        """
        n_steps = step_total(t_final, dt)              # validates t_final and dt
        dt = float(dt)
        if n_steps % self.block:
            raise ModelError(f"t_final = {t_final!r} must be a whole multiple of block * dt = {self.block * dt!r}")
        n = self.n
        q0 = np.zeros(1 + n)
        q0[0] = self.reference.angle(0.0) if theta0 is None else validation.finite("theta0", theta0)
        names = ["hub.theta"] + [f"arm.q{i + 1}" for i in range(n)]
        guard = DivergenceGuard.from_start(names, q0, q0, bound=divergence_bound)
        check_scheme(None, q0, np.zeros(1 + n), dt, scheme="rk4", policy=stability_check,
                     label="the compiled manipulator",
                     accelerations=lambda _, q, v, t: self.accelerations(q, v, t, dt=dt))
        start = _time.perf_counter()
        states = self.scene.run(q0, np.zeros(1 + n), dt, n_steps)
        wall = _time.perf_counter() - start
        t = dt * self.block * np.arange(len(states) + 1)
        Y = np.column_stack([np.vstack([np.concatenate([q0, np.zeros(1 + n)]), states[:, :2 + 2 * n]]), t])
        check_stored(guard, t, Y[:, :1 + n], Y[:, 1 + n:2 + 2 * n],
                     lambda k: self._result(Y[:k], wall, dt, k - 1, check_limit=False))
        return self._result(Y, wall, dt, n_steps // self.block)

    def _result(self, Y: np.ndarray, wall: float, dt: float, n_blocks: int, *,
                check_limit: bool = True) -> ManipulatorSimulation:
        """Histories from the stored states ``Y`` (rows ``[q, qdot, t]``); voltage limit check."""
        n = self.n
        t = Y[:, -1]
        q, v = Y[:, :1 + n], Y[:, 1 + n:2 + 2 * n]
        pd, mv, pzt, arm = self.pd, self.reference, self.pzt, self.manipulator
        desired = mv.angle(t)
        torque = pd.kp * (desired - q[:, 0]) + pd.kd * (mv.rate(t) - v[:, 0])
        if pzt is not None:
            V = -(pzt.gains @ (self.slope_matrix @ v[:, 1:].T)).T
        else:
            V = np.zeros((t.size, arm.n_patches))
        limit = arm.voltage_limit
        peak = float(np.abs(V).max()) if V.size else 0.0
        over = np.any(np.abs(V) > limit, axis=1) if V.size else np.zeros(t.size, bool)
        result = ManipulatorSimulation(
            t=t, theta=q[:, 0], theta_dot=v[:, 0], desired=np.asarray(desired, float), q=q[:, 1:], q_dot=v[:, 1:],
            tip_deflection=q[:, 1:] @ self.tip_shape, voltages=V, torque=torque, method="rk4-compiled", dt=dt,
            wall_time_s=wall, n_evaluations=4 * n_blocks * self.block, voltage_limit=limit, peak_voltage=peak,
            time_over_limit=float(np.count_nonzero(over) * dt * self.block), saturated=np.zeros(t.size, bool))
        if check_limit and pzt is not None and pzt.on_limit == "raise" and peak > limit:
            k = int(np.argmax(over))
            patch = arm.patch_names[int(np.argmax(np.abs(V[k])))]
            raise SimulationError(f"voltage limit exceeded at t = {t[k]:.6g} s: patch {patch!r} needs "
                                  f"{peak:.4g} V > {limit:g} V", time=float(t[k]), element=patch,
                                  partial_result=self._result(Y[:k], wall, dt, k - 1, check_limit=False))
        return result
