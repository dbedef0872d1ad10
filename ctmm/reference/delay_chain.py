"""Closed-loop global references for 1-D chains with feedback and time delay (no TMM code).

A feedback loop (:class:`GlobalLoop`) applies the control force

.. math:: u(t) = -g \\, [y_s(t - \\tau) - y_r(t - \\tau)]

to ``actuator_mass`` (and ``-u`` to ``reaction_mass`` when the actuator acts across a
connector), where ``y`` is the displacement, velocity or acceleration of ``sensor_mass``
(minus that of ``relative_to`` for relative sensing).  With ``b = e_act - e_react`` and
``c = e_sens - e_rel`` the closed loop obeys

.. math:: M \\ddot x + C \\dot x + K x + \\sum_l g_l\\, b_l c_l^T\\, x^{(p_l)}(t - \\tau_l) = f(t)

(``p = 0, 1, 2`` for displacement, velocity, acceleration sensing).  In the Laplace domain
the dynamic stiffness is ``s²M + sC + K + Σ g s^p e^{-sτ} b cᵀ``: acceleration feedback adds to
the mass-like term, velocity feedback to the damping-like term.  The loop matrices are
generally non-symmetric (non-collocated control).

Delayed acceleration feedback turns the equations into a *neutral* delay differential
equation (the highest derivative appears delayed); it is well posed only if the difference
operator is stable (e.g. ``|g| < m`` for a collocated loop on one mass).  Zero-delay
acceleration feedback is folded into the mass matrix ``M + g b cᵀ`` (which must stay
regular).
"""
from __future__ import annotations

import bisect
import math
import operator
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np
import scipy.linalg as sla
from numpy.polynomial import chebyshev
from scipy.integrate import solve_ivp

from ..errors import ModelError, SimulationError
from ..validation import finite, finite_array, positive
from .chain import (GlobalChain, TimeHistory, assemble, force_function, mass_index,
                    output_from_displacements, solve_dynamic_stiffness, sort_roots)

SENSED = ("displacement", "velocity", "acceleration")
HistoryFunction = Callable[[float], "tuple[np.ndarray, np.ndarray, np.ndarray]"]


@dataclass(frozen=True)
class GlobalLoop:
    """One linear feedback loop ``u(t) = -gain * (y_sensor - y_relative)(t - delay)``.

    Parameters
    ----------
    sensor_mass : int
        Mass whose motion is measured.
    quantity : {"displacement", "velocity", "acceleration"}
        Measured quantity ``y`` [m], [m/s], [m/s²].
    actuator_mass : int
        Mass receiving ``+u`` [N].
    gain : float
        Feedback gain [N/m], [N s/m] or [N s²/m] (finite, any sign).
    delay : float
        Time delay τ [s] >= 0.
    relative_to : int, optional
        Mass whose quantity is subtracted from the sensor's (relative sensing).
    reaction_mass : int, optional
        Mass receiving ``-u`` (actuator acting across a connector).
    """

    sensor_mass: int
    quantity: str
    actuator_mass: int
    gain: float
    delay: float = 0.0
    relative_to: int | None = None
    reaction_mass: int | None = None

    def __post_init__(self) -> None:
        for key in ("sensor_mass", "actuator_mass", "relative_to", "reaction_mass"):
            value = getattr(self, key)
            if value is None and key in ("relative_to", "reaction_mass"):
                continue
            try:
                if isinstance(value, bool):
                    raise TypeError
                index = operator.index(value)
            except TypeError:
                raise ModelError(f"{key} must be an integer mass index, got {value!r}") from None
            if index < 0:
                raise ModelError(f"{key} must be >= 0, got {value!r}")
            object.__setattr__(self, key, index)
        if self.quantity not in SENSED:
            raise ModelError(f"quantity must be one of {SENSED}, got {self.quantity!r}")
        object.__setattr__(self, "gain", finite("gain", self.gain))
        delay = finite("delay", self.delay)
        if delay < 0.0:
            raise ModelError(f"delay must be >= 0 s, got {self.delay!r}")
        object.__setattr__(self, "delay", delay)
        if self.relative_to == self.sensor_mass:
            raise ModelError(f"relative_to must differ from sensor_mass, got {self.relative_to!r}")
        if self.reaction_mass == self.actuator_mass:
            raise ModelError(f"reaction_mass must differ from actuator_mass, got {self.reaction_mass!r}")

    @property
    def order(self) -> int:
        """Derivative order ``p`` of the measured quantity (0, 1, 2)."""
        return SENSED.index(self.quantity)


@dataclass(frozen=True)
class LoopTerm:
    """A loop reduced to numbers: force ``-gain * actuator * (sensor · y_p(t - delay))``.

    ``order`` is the derivative order ``p`` of the sensed quantity, ``delay`` in s, ``actuator`` and
    ``sensor`` are vectors over the chain's masses (``+1`` / ``-1`` entries).
    """

    order: int
    gain: float
    delay: float
    actuator: np.ndarray
    sensor: np.ndarray

    @property
    def matrix(self) -> np.ndarray:
        return self.gain * np.outer(self.actuator, self.sensor)


def loop_terms(chain: GlobalChain, loops: Sequence[GlobalLoop]) -> list[LoopTerm]:
    """The loops of ``chain`` as :class:`LoopTerm` vectors (checked: a list or tuple of :class:`GlobalLoop`)."""
    if isinstance(loops, GlobalLoop) or not isinstance(loops, (list, tuple)) or not all(
            isinstance(loop, GlobalLoop) for loop in loops):
        raise ModelError(f"loops must be a list or tuple of GlobalLoop, got {loops!r}")
    terms = []
    for number, loop in enumerate(loops):
        b, c = np.zeros(chain.size), np.zeros(chain.size)
        b[mass_index(chain, f"loops[{number}].actuator_mass", loop.actuator_mass)] += 1.0
        c[mass_index(chain, f"loops[{number}].sensor_mass", loop.sensor_mass)] += 1.0
        if loop.reaction_mass is not None:
            b[mass_index(chain, f"loops[{number}].reaction_mass", loop.reaction_mass)] -= 1.0
        if loop.relative_to is not None:
            c[mass_index(chain, f"loops[{number}].relative_to", loop.relative_to)] -= 1.0
        terms.append(LoopTerm(loop.order, loop.gain, loop.delay, b, c))
    return terms


def closed_loop_dynamic_stiffness(chain: GlobalChain, loops: Sequence[GlobalLoop], s) -> np.ndarray:
    """``s²M + sC + K + Σ g s^p e^{-sτ} b cᵀ`` for complex ``s`` [1/s]; shape s.shape + (n, n)."""
    s = np.asarray(s, dtype=complex)
    if not np.all(np.isfinite(s)):
        raise ModelError("s must contain only finite values")
    M, C, K = assemble(chain)
    z = s[..., None, None]
    D = z ** 2 * M + z * C + K + 0j
    for term in loop_terms(chain, loops):
        D = D + term.matrix * (z ** term.order * np.exp(-z * term.delay))
    return D


def closed_loop_frequency_response(chain: GlobalChain, loops: Sequence[GlobalLoop], omega,
                                   input_mass: int, output_mass: int,
                                   quantity: str = "displacement") -> np.ndarray:
    """Closed-loop harmonic response per unit force on ``input_mass`` (dense solves).

    Solves ``(K - ω²M + iωC + Σ g (iω)^p e^{-iωτ} b cᵀ) X = e_input``.  Outputs as in
    :func:`ctmm.reference.chain.frequency_response`; ``"force"`` is the passive connector force
    (spring + damper) of connector ``output_mass`` and excludes any actuator force.

    Parameters
    ----------
    omega : array_like
        Real angular frequencies [rad/s].
    """
    w = finite_array("omega", omega)
    flat = np.atleast_1d(w).ravel()
    if quantity not in ("displacement", "velocity", "acceleration", "force"):
        raise ModelError("quantity must be one of ('displacement', 'velocity', 'acceleration', "
                         f"'force'), got {quantity!r}")
    D = closed_loop_dynamic_stiffness(chain, loops, 1j * flat)
    rhs = np.zeros(chain.size, dtype=complex)
    rhs[mass_index(chain, "input_mass", input_mass)] = 1.0
    X = solve_dynamic_stiffness(D, rhs, flat)
    return output_from_displacements(chain, X, flat, output_mass, quantity).reshape(w.shape)


def closed_loop_characteristic(chain: GlobalChain, loops: Sequence[GlobalLoop], s) -> np.ndarray:
    """Characteristic function ``det(s²M + sC + K + Σ g s^p e^{-sτ} b cᵀ)``, vectorised over
    complex ``s`` [1/s] (any shape); units [N^n/m^n].  Its zeros are the closed-loop roots."""
    return np.linalg.det(closed_loop_dynamic_stiffness(chain, loops, s))


def closed_loop_roots(chain: GlobalChain, loops: Sequence[GlobalLoop]) -> np.ndarray:
    """Finite closed-loop roots of delay-free loops from the first-order generalized eigenproblem

    ``[[0, I], [-K', -C']] z = s [[I, 0], [0, M']] z`` with ``M' = M + Σ_{p=2} g b cᵀ``,
    ``C' = C + Σ_{p=1} g b cᵀ``, ``K' = K + Σ_{p=0} g b cᵀ``.  Infinite eigenvalues (singular
    ``M'``) are dropped.  Sorted by |Im s|.  A diagonal positive ``M'`` (no acceleration feedback
    across masses, every DOF with mass) is divided out first: the standard eigenproblem of
    ``[[0, I], [-M'^-1 K', -M'^-1 C']]`` has the same roots at a fraction of the QZ cost.

    Raises
    ------
    ModelError
        If a loop has a non-zero delay (the spectrum is then infinite; use
        :func:`closed_loop_characteristic`).
    """
    terms = loop_terms(chain, loops)
    for number, term in enumerate(terms):
        if term.delay != 0.0:
            raise ModelError(f"closed_loop_roots needs delay-free loops, loops[{number}].delay = "
                             f"{term.delay!r}; use closed_loop_characteristic for delays")
    M, C, K = _effective_matrices(chain, terms)
    n = chain.size
    masses = np.diag(M)
    if np.all(masses > 0.0) and not np.any(M - np.diag(masses)):
        roots = np.linalg.eigvals(np.block([[np.zeros((n, n)), np.eye(n)], [-K / masses[:, None], -C / masses[:, None]]]))
        return sort_roots(roots)
    left = np.block([[np.zeros((n, n)), np.eye(n)], [-K, -C]])
    right = np.block([[np.eye(n), np.zeros((n, n))], [np.zeros((n, n)), M]])
    roots = sla.eigvals(left, right)
    return sort_roots(roots[np.isfinite(roots)])


def _effective_matrices(chain: GlobalChain, terms: list[LoopTerm]):
    """M, C, K with every zero-delay loop folded in by derivative order."""
    matrices = list(assemble(chain))            # M, C, K -> orders 2, 1, 0
    for term in terms:
        if term.delay == 0.0:
            matrices[2 - term.order] = matrices[2 - term.order] + term.matrix
    return tuple(matrices)


# ---------------------------------------------------------------------------------------------
# method of steps
# ---------------------------------------------------------------------------------------------
_DEGREE = 8
_NODES = np.cos(np.pi * np.arange(_DEGREE + 1) / _DEGREE)          # Chebyshev–Lobatto on [-1, 1]
_FIT = np.linalg.inv(chebyshev.chebvander(_NODES, _DEGREE))          # values -> coefficients


class _Piecewise:
    """Piecewise Chebyshev interpolant (degree 8 per solver step) of a vector function."""

    def __init__(self, breaks: np.ndarray, function: Callable[[float], np.ndarray]) -> None:
        self.breaks = [float(value) for value in breaks]
        middle, half = 0.5 * (breaks[1:] + breaks[:-1]), 0.5 * np.diff(breaks)
        times = middle[:, None] + half[:, None] * _NODES[None, :]
        values = np.array([[function(float(time)) for time in row] for row in times])
        self.coefficients = np.einsum("ki,mid->mkd", _FIT, values)

    def __call__(self, time: float) -> np.ndarray:
        j = min(max(bisect.bisect_right(self.breaks, time) - 1, 0), len(self.breaks) - 2)
        left, right = self.breaks[j], self.breaks[j + 1]
        return chebyshev.chebval((2.0 * time - left - right) / (right - left), self.coefficients[j])


def _segment_index(starts: list[float], time: float) -> int:
    """Index of the segment holding ``time`` (right-continuous, -1 before the first start).

    Times within round-off (1e-12 relative) of a segment start count as inside that segment,
    so ``t - τ`` computed in floating point from a segment start lands in the intended one."""
    return bisect.bisect_right(starts, time + 1e-12 * max(1.0, abs(time))) - 1


@dataclass
class _Segment:
    start: float
    end: float
    solution: object                        # scipy OdeSolution of [x, v]
    acceleration: _Piecewise | None = None


class DelaySolution:
    """Dense solution of the closed-loop delay equations from :func:`method_of_steps`.

    Call :meth:`evaluate` with times in ``[0, t_final]`` to get a :class:`TimeHistory`.  At a
    segment boundary ``t = kτ`` the right limit is returned (it matters only for the
    acceleration of a neutral system, which may jump there).
    """

    def __init__(self, chain: GlobalChain, terms: list[LoopTerm], t_final: float,
                 history: HistoryFunction, force: Callable[[float], np.ndarray]) -> None:
        self.chain, self.t_final = chain, t_final
        self._history, self._force = history, force
        self._delayed = [term for term in terms if term.delay > 0.0]
        M, self._C, self._K = _effective_matrices(chain, terms)
        if np.linalg.cond(M) > 1e12:
            raise ModelError("zero-delay acceleration feedback makes the effective mass matrix "
                             "M + g b cᵀ singular; change the gain of the acceleration loop")
        self._inverse_mass = np.linalg.inv(M)
        self.segments: list[_Segment] = []
        self._starts: list[float] = []

    def _past(self, time: float, order: int, limit: int) -> np.ndarray:
        """Quantity of derivative ``order`` at the past ``time`` from segments ``<= limit``
        (right-continuous between segments), from the initial history before 0."""
        k = min(_segment_index(self._starts, time), limit)
        if k < 0:
            return self._history(time)[order]
        if order == 2:
            return self.segments[k].acceleration(time)
        n = self.chain.size
        return self.segments[k].solution(time)[order * n:(order + 1) * n]

    def _acceleration(self, time: float, x: np.ndarray, v: np.ndarray, limit: int) -> np.ndarray:
        """``a = M'⁻¹ (f - C' v - K' x - Σ g b (c · y(t - τ)))`` at one time [m/s²]."""
        load = self._force(time) - self._C @ v - self._K @ x
        for term in self._delayed:
            sensed = float(term.sensor @ self._past(time - term.delay, term.order, limit))
            load = load - term.gain * sensed * term.actuator
        return self._inverse_mass @ load

    def _solve_segment(self, start: float, end: float, z0: np.ndarray, rtol: float,
                       atol: float) -> None:
        n, limit = self.chain.size, len(self.segments) - 1

        def rhs(time: float, z: np.ndarray) -> np.ndarray:
            return np.concatenate([z[n:], self._acceleration(time, z[:n], z[n:], limit)])

        result = solve_ivp(rhs, (start, end), z0, method="DOP853", dense_output=True,
                           rtol=rtol, atol=atol)
        if not result.success:
            raise SimulationError(f"solve_ivp failed on [{start}, {end}] s: {result.message}",
                                  time=float(result.t[-1]))
        segment = _Segment(start, end, result.sol)
        if any(term.order == 2 for term in self._delayed):
            def acceleration(time: float) -> np.ndarray:
                state = result.sol(time)
                return self._acceleration(time, state[:n], state[n:], limit)
            segment.acceleration = _Piecewise(np.asarray(result.sol.ts), acceleration)
        self.segments.append(segment)
        self._starts.append(float(start))

    def evaluate(self, t) -> TimeHistory:
        """Displacements, velocities, accelerations at times ``t`` [s] in ``[0, t_final]``."""
        times = finite_array("t", t, ndim=1)
        if np.any(times < 0.0) or np.any(times > self.t_final * (1 + 1e-12)):
            raise ModelError(f"t must lie in [0, {self.t_final}] s")
        n = self.chain.size
        x, v, a = (np.empty((times.size, n)) for _ in range(3))
        for i, time in enumerate(times):
            k = min(max(_segment_index(self._starts, float(time)), 0), len(self.segments) - 1)
            state = self.segments[k].solution(float(time))
            x[i], v[i] = state[:n], state[n:]
            a[i] = self._acceleration(float(time), x[i], v[i], k - 1)
        return TimeHistory(times, x, v, a)


def _history_function(chain: GlobalChain, history, x0: np.ndarray, v0: np.ndarray) -> HistoryFunction:
    if history is None:
        held = (x0, v0, np.zeros(chain.size))
        return lambda time: held
    if not callable(history):
        raise ModelError(f"history must be a callable theta -> (x, v, a) or None, got {history!r}")

    def checked(time: float):
        values = tuple(np.asarray(item, dtype=float) for item in history(time))
        if len(values) != 3 or any(item.shape != (chain.size,) for item in values):
            raise ModelError(f"history(theta) must return (x, v, a), each of shape ({chain.size},)")
        return values
    return checked


def method_of_steps(chain: GlobalChain, loops: Sequence[GlobalLoop], t_final: float, x0, v0,
                    history: HistoryFunction | None = None,
                    force_fn: Callable[[float], np.ndarray] | None = None, *,
                    rtol: float = 1e-10, atol: float = 1e-12) -> DelaySolution:
    """Solve the closed-loop delay equations by the method of steps.

    The time axis is cut into intervals of length ``τ_min`` (smallest positive delay).  On
    interval ``k`` every delayed quantity lies in an earlier interval (or in the initial
    history), so the equations are an ODE there, solved by ``solve_ivp`` (DOP853, dense
    output).  Delayed displacements and velocities come from earlier dense outputs; delayed
    accelerations (neutral equation) from a piecewise degree-8 Chebyshev interpolant of the
    equation of motion evaluated on the earlier intervals' dense output.  Zero-delay loops are
    folded into ``M', C', K'``; with no delayed loop this is a single ODE solve.

    Parameters
    ----------
    loops : sequence of GlobalLoop
    t_final : float
        End time [s] > 0.
    x0, v0 : array_like, shape (n,)
        State at ``t = 0`` [m], [m/s].
    history : callable, optional
        ``theta -> (x, v, a)`` for ``theta < 0``; default: the initial state held constant,
        ``(x0, v0, 0)``.
    force_fn : callable, optional
        External forces ``f(t) -> (n,)`` [N]; zero when omitted.
    rtol, atol : float
        ``solve_ivp`` tolerances.

    Returns
    -------
    DelaySolution
        Dense solution; ``.evaluate(t)`` returns a :class:`TimeHistory`.
    """
    t_final = positive("t_final", t_final)
    rtol, atol = positive("rtol", rtol), positive("atol", atol)
    terms = loop_terms(chain, loops)
    x0 = _vector(chain, "x0", x0)
    v0 = _vector(chain, "v0", v0)
    force = force_function(chain, force_fn)
    solution = DelaySolution(chain, terms, t_final, _history_function(chain, history, x0, v0), force)
    delays = [term.delay for term in terms if term.delay > 0.0]
    step = min(delays) if delays else t_final
    count = max(1, math.ceil(t_final / step - 1e-9))
    z = np.concatenate([x0, v0])
    for k in range(count):
        start, end = k * step, (t_final if k == count - 1 else (k + 1) * step)
        solution._solve_segment(start, end, z, rtol, atol)
        z = solution.segments[-1].solution(end)
    return solution


def _vector(chain: GlobalChain, name: str, value) -> np.ndarray:
    array = finite_array(name, value, ndim=1)
    if array.shape != (chain.size,):
        raise ModelError(f"{name} must have shape ({chain.size},), got shape {array.shape}")
    return array


__all__ = ["GlobalLoop", "DelaySolution", "closed_loop_dynamic_stiffness",
           "closed_loop_frequency_response", "closed_loop_characteristic", "closed_loop_roots",
           "method_of_steps"]
