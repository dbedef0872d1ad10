"""Parameter sweeps of the characteristic function: one loop's parameters as a batch axis.

Everything here works on the characteristic function ``Delta(s)`` of the transfer-matrix model
(:func:`ctmm.characteristic_function`: determinant of the Riccati boundary equations, entire in
``s``, exact delays ``e^{-s tau}``); :mod:`ctmm.stability` and :mod:`ctmm.stability_chart` build
on it.  Methods: ``docs/stability.md``.

The loop as an affine term
--------------------------
A :class:`~ctmm.control.loops.Feedback` loop ``u = -k C(s) e^{-s tau} sum_j w_j y_j`` enters the
extended transfer matrix of its actuator in *one column* (the coefficient of the sensed value
``y``), so the overall boundary matrix is ``A0 + g(s) a b^T`` with ``g = k C e^{-s tau}`` and, by
the matrix determinant lemma, its determinant is affine in ``g``.  The sensed value is linear in
the sensor weights ``w_j``; hence, with ``D(s)`` the controller denominator,

    Delta(s; k, tau, w) = D(s) Delta_0(s) + k e^{-s tau} sum_j w_j T_j(s),            (1)

where ``Delta_0`` is ``Delta`` with the loop open and ``T_j = D Delta_0 C P_j`` with ``P_j`` the
response of sensor term ``j`` to a unit actuator force.  :class:`LoopCharacteristic` computes
``Delta_0`` and the ``P_j`` by the TMM once per ``s`` and then evaluates (1) for any number of
parameter sets by array arithmetic.  ``tests/test_stability.py`` checks (1) against direct
evaluations of the closed loop.

Counting right-half-plane roots
-------------------------------
:func:`count` applies the argument principle to the rectangle ``[sigma, sigma + R] x [-R, R]``,
using ``Delta(conj s) = conj Delta(s)``: the count is the phase change of ``Delta`` along the
upper half of the boundary divided by ``pi``.  ``R`` is chosen so that beyond it the loop term is
smaller than half the open-loop term (``sum_j |k w_j T_j| e^{max(0, -sigma) tau} < |D Delta_0|/2``),
which holds for retarded loops (strictly proper loop transfer functions); then on the far edges
``arg Delta`` is ``arg D Delta_0`` (computed once) plus the principal ``arg(1 + L)``, and only the
line ``Re s = sigma`` has to be sampled for every parameter set.

Executors
---------
Every sweep in ctmm takes ``executor=``: ``None`` (sequential, the default), ``"threads"`` or
``"processes"`` (a pool of ``os.cpu_count()`` workers created for the call and shut down after
it), or any object with the :class:`concurrent.futures.Executor` interface -- including
``distributed.Client(...).get_executor()`` of dask.distributed -- which is used as given and not
shut down.  Work is handed out as picklable callables and arguments (module-level functions),
results come back in input order.
"""
from __future__ import annotations

import math
import os
import warnings
from concurrent.futures import Executor, ProcessPoolExecutor, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Iterable, Iterator, Sequence

import numpy as np

from . import validation
from .assembly import SOLVERS
from .certification import ContourCertificate, StabilityWarning, loop_bound
from .control.loops import ControlledChain, Feedback
from .elements.lumped import Connector
from .errors import ModelError, SingularSystemError, unknown_name
from .frequency import assemble, characteristic_function
from .progress import progress_bar

__all__ = ["LoopCharacteristic", "managed_executor", "executor_workers", "parallel_map",
           "as_controlled", "find_loop", "delay_free_answer"]

_MAX_STEP = 0.4          # largest complex-log step of a component between samples
_COUNT_STEP = 1.0        # largest phase step of Delta(s; p) between samples when counting
TINY = 1e-13            # components below this (relative to the largest at s) are ignored
_MAX_SAMPLES = 200_000   # largest initial line sampling for a proven contour height


# --------------------------------------------------------------------------------------------
# the loop as an affine term
# --------------------------------------------------------------------------------------------
def as_controlled(system: Any, what: str = "stability analysis") -> ControlledChain:
    """``system`` as a :class:`ControlledChain`, or a :class:`ModelError` that says why not."""
    if isinstance(system, ControlledChain):
        return system
    from .system import Chain

    if isinstance(system, Chain):
        raise ModelError(f"{what} needs a feedback loop, but {system.name!r} is a plain Chain with no "
                         "loop (nothing depends on a gain or a delay, a chart would be constant); "
                         f"delay-free answer: {delay_free_answer(system)}. Close a loop with "
                         "ctmm.control.ControlledChain(plant, [Feedback(...)]), or use "
                         "ctmm.stability.spectral_abscissa(system, ...) for its roots")
    raise ModelError(f"{what} needs a ControlledChain, got {system!r}")


def delay_free_answer(system: Any, radius: float = 1e4) -> str:
    """Stability of a system without delay, in words: roots in Re s > 0 with |s| < ``radius``."""
    from .roots import ContourError, count_roots_in_rectangle

    try:
        count = count_roots_in_rectangle(characteristic_callable(system), (0.0, radius), (-radius, radius),
                                         max_evaluations=50_000)
    except ContourError as exc:
        return (f"not asymptotically stable: a root lies on the imaginary axis near "
                f"s = {exc.location:.4g} (e.g. a rigid-body or undamped mode)")
    except ModelError as exc:  # pragma: no cover - unusual models
        return f"undetermined ({exc})"
    if not count.reliable:
        return f"undetermined (count {count.count} not verified)"
    if count.count == 0:
        return f"stable (no root with Re s > 0, |Im s| < {radius:.0e} rad/s)"
    return f"unstable ({count.count} root(s) with Re s > 0)"


def find_loop(system: ControlledChain, loop: str | None) -> Feedback:
    """The loop called ``loop`` (the only loop when ``None``); unknown names list the loops."""
    if loop is None:
        if len(system.loops) != 1:
            raise unknown_name("loop (give loop=...)", "<none given>", [lp.name for lp in system.loops])
        return system.loops[0]
    if not isinstance(loop, str):
        raise ModelError(f"loop must be a loop name (str), got {loop!r}")
    return system.loop(loop)


def _log_characteristic(system: Any, s: np.ndarray) -> np.ndarray:
    """``log Delta(s)`` (unnormalised, complex) without forming ``Delta`` (no overflow).

    Same determinant and pole-clearing factor as :func:`ctmm.characteristic_function`, but the
    factor is summed as logarithms: a product of ``k + c s`` over a chain of thousands of
    connectors overflows at high frequency."""
    with np.errstate(divide="ignore", invalid="ignore"):
        Us, us, start, end = assemble(system, s)
        sol = SOLVERS["riccati"](Us, us, start, end, want_states=False)
        return sol.log_det + _log_pole_factor(system, s)


def _log_pole_factor(system: Any, s: np.ndarray) -> np.ndarray:
    """``log`` of the connector stiffnesses ``k + c s`` (and LTI controller denominators) that
    clear the poles of the element matrices, summed term by term."""
    s = np.asarray(s, dtype=complex)
    controlled = isinstance(system, ControlledChain)
    body = system.plant.body if controlled else getattr(system, "body", None)
    if body is None:      # another model type: its own (product) scale
        return np.log(np.asarray(system.characteristic_scale(s), dtype=complex))
    out = np.zeros(s.shape, dtype=complex)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for element in body:
            if isinstance(element, Connector):
                out = out + np.log(np.asarray(element.connector_stiffness(s), dtype=complex))
        for lp in (system.loops if controlled else ()):
            if lp.is_lti:
                out = out + np.log(np.asarray(lp.denominator(s), dtype=complex))
    return out


def _normalised(logs: np.ndarray) -> np.ndarray:
    """``exp(logs)`` divided by the largest modulus in each column (zeros where log is -inf)."""
    finite = np.isfinite(logs.real)
    top = np.max(np.where(finite, logs.real, -np.inf), axis=0)
    top = np.where(np.isfinite(top), top, 0.0)
    with np.errstate(under="ignore", invalid="ignore", over="ignore"):
        values = np.exp(logs - top)
    return np.where(finite, values, 0.0)


def _components_chunk(model: "LoopCharacteristic", s: np.ndarray) -> np.ndarray:
    return model._components_direct(s)


class LoopCharacteristic:
    """``Delta(s; k, tau, w)`` of a controlled chain as an affine function of one loop, eq. (1).

    Parameters
    ----------
    system : ControlledChain
        The closed loop; every other loop stays as it is.
    loop : str, optional
        Loop name (default: the only loop).

    Attributes
    ----------
    parameter_names : tuple of str
        ``"gain"``, ``"delay"`` and the loop's sensor signal names (their weights ``w_j``).
    gain : float
        Current gain factor ``k``: the loop's gain for a static gain, 1 for an LTI controller
        (then ``k`` scales ``C(s)``).
    delay : float
        Current delay [s].
    weights : numpy.ndarray
        Current sensor weights.

    Notes
    -----
    Values are returned divided by a positive real function of ``s`` (the largest modulus of the
    components at that ``s``) and by a constant.  That keeps them of order one on long chains and
    changes neither the zeros nor the changes of argument, which is all the stability tools use;
    for the characteristic function itself use :func:`ctmm.characteristic_function`.

    Examples
    --------
    >>> import numpy as np, ctmm
    >>> from ctmm.elements import Free, Mass
    >>> from ctmm.control import ControlledChain, Feedback
    >>> plant = ctmm.Chain("mass", [Free("a"), Mass("m", 2.0), Free("b")])
    >>> pd = Feedback("pd", [("m.x", 3.0), ("m.v", 1.0)], "m", gain=1.0, delay=0.1)
    >>> model = LoopCharacteristic(ControlledChain(plant, [pd]))
    >>> s = np.array([0.5 + 1j])
    >>> d = model.evaluate(s, gain=[1.0, 2.0], delay=[0.1, 0.3])[:, 0]
    >>> def exact(k, tau):        # m s^2 + k (kp + kd s) e^{-s tau}
    ...     return 2 * s[0] ** 2 + k * (3 + s[0]) * np.exp(-tau * s[0])
    >>> bool(abs(d[1] / d[0] - exact(2.0, 0.3) / exact(1.0, 0.1)) < 1e-12)
    True
    """

    def __init__(self, system: ControlledChain, loop: str | None = None) -> None:
        self.system = as_controlled(system)
        self.loop = find_loop(self.system, loop)
        lp = self.loop
        self.term_names = tuple(sig for sig, _ in lp.terms)
        if len(set(self.term_names)) != len(self.term_names):
            raise ModelError(f"loop {lp.name!r} senses the same signal twice ({self.term_names}); "
                             "combine the weights into one term")
        self.parameter_names = ("gain", "delay") + self.term_names
        self.weights = np.array([w for _, w in lp.terms], dtype=float)
        self.gain = 1.0 if lp.is_lti else float(lp.gain)
        self.delay = float(lp.delay)
        plant = self.system.plant
        signals = [plant.signal(name) for name in self.term_names]
        groups: dict[tuple[int, int], int] = {}
        for j, sig in enumerate(signals):
            key = (sig.point, sig.component)
            if key not in groups or sig.derivative < signals[groups[key]].derivative:
                groups[key] = j
        self._group_of = np.array([list(groups).index((sig.point, sig.component)) for sig in signals])
        reps = list(groups.values())
        self._power = np.array([sig.derivative - signals[reps[g]].derivative
                                for sig, g in zip(signals, self._group_of)])
        index = self.system.loops.index(lp)

        def closed_by(new: Feedback) -> ControlledChain:
            loops = list(self.system.loops)
            loops[index] = new
            return self.system.with_loops(loops)

        reference = lp.gain if lp.is_lti else 1.0
        self._base = closed_by(Feedback(lp.name, lp.sensor, lp.actuator, gain=0.0, delay=0.0))
        self._groups = [closed_by(Feedback(lp.name, self.term_names[r], lp.actuator, gain=reference,
                                           delay=0.0)) for r in reps]
        others = [other for other in self.system.loops if other is not lp]
        self.open_system = self.system.with_loops(others) if others else plant
        # unit loop force: every weighted actuator input of the loop (e.g. a PZT moment pair)
        self._amplitudes: dict = {}
        for name, weight in lp.actuator_terms:
            element_name, _, input_name = name.partition(".")
            element = self.open_system.element(element_name)
            resolved = self.open_system.input(f"{element_name}.{input_name or element.inputs[0]}")
            slot = self._amplitudes.setdefault(resolved.position, {})
            slot[resolved.input] = slot.get(resolved.input, 0.0) + weight
        self._sensed = [(sig.point, sig.component, sig.derivative) for sig in signals]
        self.executor = None
        self.n_evaluations = 0
        self._phase = None

    # -- components ---------------------------------------------------------------------
    def _components_direct(self, s: np.ndarray) -> np.ndarray:
        """``[D Delta_0, T_1, ...]`` at ``s``, divided by the largest modulus at each ``s``.

        Fast path: with the loop open, ``Delta_0`` (log of the boundary determinant) and the
        responses ``P_j`` of the sensed signals to a unit actuator force come from the open chain
        (no extended states); by the matrix determinant lemma the loop adds
        ``T_j = D Delta_0 C P_j``.  Where the open chain is singular (an open-loop root exactly
        at a sample, e.g. s = 0 of a free chain) the extended closed chains are swept instead."""
        s = np.asarray(s, dtype=complex).ravel()
        out = np.empty((1 + len(self._sensed), s.size), dtype=complex)
        log_open = _log_characteristic(self.open_system, s)
        regular = np.isfinite(log_open)
        if regular.any():
            try:
                out[:, regular] = self._components_open(s[regular], log_open[regular])
            except SingularSystemError:
                regular[:] = False
        if not regular.all():
            out[:, ~regular] = self._components_closed(s[~regular]) * self._closed_phase()
        return out

    def _closed_phase(self) -> complex:
        """Phase of the constant ratio (open path)/(closed path) of ``D Delta_0`` (e.g. -1: the
        extended chain's determinant carries the sign of the loop's constraint row)."""
        if getattr(self, "_phase", None) is None:
            for s_ref in (0.7 + 1.3j, 1.9 + 0.4j, 0.3 + 3.1j):
                ref = np.array([s_ref])
                log_open = _log_characteristic(self.open_system, ref)
                if not np.isfinite(log_open[0]):
                    continue
                open_base = self._components_open(ref, log_open)[0, 0]
                closed_base = self._components_closed(ref)[0, 0]
                if open_base != 0 and closed_base != 0:
                    ratio = open_base / closed_base
                    self._phase = ratio / abs(ratio)
                    break
            else:  # pragma: no cover - an open chain singular at every reference point
                self._phase = 1.0
        return self._phase

    def _components_open(self, s: np.ndarray, log_open: np.ndarray) -> np.ndarray:
        from .frequency import solve

        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            states = solve(self.open_system, s, self._amplitudes).states
            log_base = log_open
            controller = np.zeros(s.size, complex)
            if self.loop.is_lti:
                log_base = log_base + np.log(self.loop.denominator(s).astype(complex))
                controller = np.log(self.loop.controller_response(s).astype(complex))
            logs = [log_base]
            for point, component, derivative in self._sensed:
                response = states[point, :, component] * s ** derivative
                logs.append(log_base + controller + np.log(response.astype(complex)))
            return _normalised(np.array(logs))

    def _components_closed(self, s: np.ndarray) -> np.ndarray:
        logs = [_log_characteristic(self._base, s)]
        if self.loop.is_lti:
            with np.errstate(divide="ignore"):
                logs[0] = logs[0] + np.log(self.loop.denominator(s).astype(complex))
        logs += [_log_characteristic(g, s) for g in self._groups]
        values = _normalised(np.array(logs))
        base = values[0]
        groups = values[1:] - base
        terms = groups[self._group_of] * s[None, :] ** self._power[:, None]
        return np.vstack([base[None, :], terms])

    def components(self, s: Any) -> tuple[np.ndarray, np.ndarray]:
        """``(Delta_0 D, T)`` at ``s``: shapes ``(n,)`` and ``(n_terms, n)`` (scaled, see Notes)."""
        s = np.asarray(s, dtype=complex).ravel()
        self.n_evaluations += s.size
        executor = self.executor
        if executor is None or s.size < 64:
            out = self._components_direct(s)
        else:
            chunks = np.array_split(s, executor_workers(executor))
            parts = list(executor.map(_components_chunk, [self] * len(chunks), chunks))
            out = np.concatenate(parts, axis=1)
        return out[0], out[1:]

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["executor"] = None
        return state

    # -- evaluation -----------------------------------------------------------------------
    def parameters(self, n: int, gain: Any = None, delay: Any = None,
                   weights: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Broadcast parameter sets to arrays ``(n,)``, ``(n,)``, ``(n, n_terms)`` (defaults: current)."""
        k = np.broadcast_to(np.asarray(self.gain if gain is None else gain, dtype=float), (n,))
        tau = np.broadcast_to(np.asarray(self.delay if delay is None else delay, dtype=float), (n,))
        w = np.broadcast_to(np.asarray(self.weights if weights is None else weights, dtype=float),
                            (n, self.weights.size))
        return k, tau, w

    @staticmethod
    def combine(s: np.ndarray, base: np.ndarray, terms: np.ndarray, gain: np.ndarray,
                delay: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """Eq. (1) from components: shape ``(n_parameter_sets, n_s)``.

        Delays and weight vectors shared by several sets are evaluated once (charts have one
        delay per row), so the cost is a few multiply-adds per set and sample."""
        delays, d_index = np.unique(delay, return_inverse=True)
        rows, w_index = np.unique(weights, axis=0, return_inverse=True)
        loop = rows @ terms
        with np.errstate(over="ignore", invalid="ignore"):
            phase = np.exp(-delays[:, None] * s[None, :])
            if delays.size * 4 < delay.size and rows.shape[0] == 1:
                return base[None, :] + gain[:, None] * (phase * loop[0])[d_index.ravel()]
            return base[None, :] + gain[:, None] * phase[d_index.ravel()] * loop[w_index.ravel()]

    def evaluate(self, s: Any, *, gain: Any = None, delay: Any = None, weights: Any = None) -> np.ndarray:
        """Scaled ``Delta`` at ``s`` for parameter sets (1-D arrays or scalars, broadcast).

        Returns
        -------
        numpy.ndarray
            Shape ``(n_sets, n_s)``.
        """
        s = np.asarray(s, dtype=complex).ravel()
        n = n_sets(gain, delay, weights)
        k, tau, w = self.parameters(n, gain, delay, weights)
        base, terms = self.components(s)
        return self.combine(s, base, terms, k, tau, w)

    def char_fn(self, *, gain: float | None = None, delay: float | None = None,
                weights: Any = None):
        """Vectorised ``s -> Delta(s)`` at one parameter set (for :mod:`ctmm.roots`)."""
        k, tau, w = self.parameters(1, gain, delay, weights)

        def delta(s: np.ndarray) -> np.ndarray:
            s = np.asarray(s, dtype=complex)
            base, terms = self.components(s.ravel())
            return self.combine(s.ravel(), base, terms, k, tau, w)[0].reshape(s.shape)

        return delta


# --------------------------------------------------------------------------------------------
# sampling the contour
# --------------------------------------------------------------------------------------------
class _Path:
    """Adaptive samples of the components on a polyline ``vertices[0] -> vertices[1] -> ...``."""

    def __init__(self, model: LoopCharacteristic, vertices: Sequence[complex], n_initial: int,
                 rate: float, min_step: float, seeds: Sequence[complex] = ()) -> None:
        self.model, self.rate, self.min_step = model, rate, min_step
        v = np.asarray(vertices, dtype=complex)
        lengths = np.abs(np.diff(v))
        per = np.maximum(8, np.ceil(n_initial * lengths / lengths.sum())).astype(int)
        pts = [v[k] + (v[k + 1] - v[k]) * np.arange(per[k]) / per[k] for k in range(len(v) - 1)]
        self.s = np.append(np.concatenate(pts), v[-1])
        if len(seeds):               # extra samples on a vertical line (open-loop resonances)
            self.s = np.unique(np.concatenate([self.s, np.asarray(seeds, dtype=complex)]).imag) * 1j \
                + v[0].real
        self.delta = 1e-7 * float(lengths.sum())
        self.values, self.logderiv = self._evaluate(self.s)
        self._refine_components()

    def _evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Components at ``s`` and their logarithmic rates along the path (forward difference)."""
        direction = self._direction(s)
        base, terms = self.model.components(np.concatenate([s, s + self.delta * direction]))
        both = np.vstack([base[None, :], terms])
        n = s.size
        v, w = both[:, :n], both[:, n:]
        with np.errstate(all="ignore"):
            rate = np.log(w / v) / self.delta
        rate = np.where(np.isfinite(rate) & (np.abs(v) > TINY), rate, 0.0)
        return v, rate

    def _direction(self, s: np.ndarray) -> np.ndarray:  # unit tangent at each sample
        raise NotImplementedError

    def bad_intervals(self) -> np.ndarray:
        """Intervals where a component turns by more than ``_MAX_STEP`` rad (observed or
        predicted from the rates) or changes its modulus by more than a factor e^1.5."""
        v, rate = self.values, self.logderiv
        h = np.abs(np.diff(self.s))
        big = (np.abs(v[:, 1:]) > TINY) & (np.abs(v[:, :-1]) > TINY)
        with np.errstate(all="ignore"):
            step = np.log(v[:, 1:] / v[:, :-1])
        step = np.where(big & np.isfinite(step), step, 0.0)
        phase_rate = np.maximum(np.abs(rate.imag[:, 1:]), np.abs(rate.imag[:, :-1]))
        modulus_rate = np.maximum(np.abs(rate.real[:, 1:]), np.abs(rate.real[:, :-1]))
        bad = (np.abs(step.imag) > _MAX_STEP) | (h * phase_rate > 2 * _MAX_STEP) | \
            (np.abs(step.real) > 1.5) | (h * modulus_rate > 3.0)
        bad = np.any(bad, axis=0) | (h * self.rate > _MAX_STEP)
        return bad & (h > self.min_step)

    def insert(self, intervals: np.ndarray, *, rates: bool = False) -> None:
        """Add the midpoints of ``intervals`` (with companion points for the rates only when
        ``rates``: they serve the component refinement of the constructor)."""
        if not intervals.any():
            return
        j = np.flatnonzero(intervals)
        mid = 0.5 * (self.s[j] + self.s[j + 1])
        if rates:
            v, g = self._evaluate(mid)
        else:
            base, terms = self.model.components(mid)
            v, g = np.vstack([base[None, :], terms]), np.zeros((1 + terms.shape[0], mid.size), complex)
        self.s = np.insert(self.s, j + 1, mid)
        self.values = np.insert(self.values, j + 1, v, axis=1)
        self.logderiv = np.insert(self.logderiv, j + 1, g, axis=1)

    def _refine_components(self) -> None:
        for _ in range(60):
            bad = self.bad_intervals()
            if not bad.any():
                return
            self.insert(bad, rates=True)

    @property
    def base(self) -> np.ndarray:
        return self.values[0]

    @property
    def terms(self) -> np.ndarray:
        return self.values[1:]


class _VerticalPath(_Path):
    def _direction(self, s: np.ndarray) -> np.ndarray:
        return np.full(s.size, 1j)


class _FarPath(_Path):
    """``sigma + X -> sigma + X + iR -> sigma + iR`` (right edge up, top edge left)."""

    def __init__(self, model, sigma, X, R, n_initial, rate, min_step):
        self._corner = complex(sigma + X, R)
        super().__init__(model, [sigma + X, self._corner, complex(sigma, R)], n_initial, rate,
                         min_step)

    def _direction(self, s: np.ndarray) -> np.ndarray:
        on_top = np.abs(s.imag - self._corner.imag) <= 1e-12 * max(1.0, abs(self._corner))
        return np.where(on_top, -1.0 + 0j, 1j)


@dataclass
class Contour:
    """Everything :func:`count` needs for one line ``Re s = sigma`` and one parameter box."""

    model: LoopCharacteristic
    sigma: float
    radius: float
    line: _VerticalPath            # sigma -> sigma + iR (ascending imaginary part)
    far_phase: float               # phase change of Delta_0 along sigma+R -> sigma+R+iR -> sigma+iR
    notes: list = field(default_factory=list)
    certificate: ContourCertificate | None = None

    @property
    def omega(self) -> np.ndarray:
        return self.line.s.imag


def _loop_bound(base: np.ndarray, terms: np.ndarray, weight_bound: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (weight_bound[:, None] * np.abs(terms)).sum(0) / np.abs(base)
    return np.where(np.isfinite(ratio), ratio, np.inf)


def _sampled_ratio(model: LoopCharacteristic, weight_bound: np.ndarray, sigma: float, growth: float,
                   low: float, high: float, seeds: Sequence[complex] = ()) -> tuple[np.ndarray, np.ndarray]:
    """``(omega, e^{max(0,-sigma) tau} |L|)`` on ``sigma + i [low, high]``: log-spaced samples
    refined until every component turns by less than ``_MAX_STEP`` between samples."""
    low = max(low, 1e-3)
    decades = max(1, int(math.ceil(math.log10(high / low))))
    vertices = sigma + 1j * np.logspace(math.log10(low), math.log10(high), 4 * decades + 1)
    path = _VerticalPath(model, vertices, 40 * decades, 0.0, 1e-13 * high,
                         [sigma + 1j * w for w in np.asarray(seeds, float) if 0 <= w <= high])
    return path.s.imag, growth * _loop_bound(path.base, path.terms, weight_bound)


def _neutral_error(model: LoopCharacteristic, detail: str) -> ModelError:
    return ModelError(
        f"loop {model.loop.name!r} is neutral or improper: {detail}; such a loop can have infinitely "
        "many roots near a vertical line and no finite contour encloses them all. Pass im_max=<rad/s> "
        "to count roots in a bounded frequency range (the result is then reported as not certified)")


def contour_height(model: LoopCharacteristic, weight_bound: np.ndarray, sigma: float, tau_max: float,
            im_max: float | None) -> tuple[float, np.ndarray, ContourCertificate]:
    """Contour height ``R`` [rad/s], open-loop poles (line seeds) and the certificate of the
    region ``Re s >= sigma, |Im s| <= R`` for a parameter box (:mod:`ctmm.certification`); a
    user ``im_max`` too small for the loop warns (:class:`StabilityWarning`)."""
    growth = math.exp(max(0.0, -sigma) * tau_max)
    if im_max is not None:
        im_max = validation.positive("im_max", im_max)
    notes: list[str] = []
    try:
        bound = loop_bound(model, weight_bound)
    except ModelError as exc:
        bound, reason = None, str(exc)
    if bound is None:
        notes.append(f"{reason}; no bound on the loop term")
        seeds = np.zeros(0)
        if im_max is not None:
            return im_max, seeds, ContourCertificate(sigma, im_max, "user", math.nan, False, tuple(notes))
        for top in (1e7, 1e6, 1e5, 1e4):      # distributed models may fail to evaluate very high
            try:
                omega, ratio = _sampled_ratio(model, weight_bound, sigma, growth, 1e-3, top)
                break
            except (np.linalg.LinAlgError, SingularSystemError):
                continue
        else:
            raise ModelError(f"loop {model.loop.name!r}: the model cannot be evaluated on Re s = "
                             f"{sigma:.6g} above 1e3 rad/s to find a contour height; pass im_max")
        big = np.flatnonzero(ratio >= 0.5)
        if big.size and omega[big[-1]] >= 0.1 * top:
            raise _neutral_error(model, f"its sampled loop term does not decay (|L| = {ratio[big[-1]]:.3g} "
                                        f"at omega = {omega[big[-1]]:.3g} rad/s)")
        radius = float(max(2.0 * omega[big[-1]], 1e-2)) if big.size else 1e-2
        notes.append(f"height from |L| sampled on Re s = {sigma:.6g} up to {top:.0e} rad/s")
        return radius, seeds, ContourCertificate(sigma, radius, "sampled", math.nan, False, tuple(notes))
    proven = bound.radius(0.5 / growth)
    seeds = bound.poles
    if not math.isfinite(proven):
        if im_max is None:
            raise _neutral_error(model, f"its loop term tends to {bound.at_infinity * growth:.6g} >= 1/2 at "
                                        "high frequency (direct feedthrough, e.g. acceleration feedback at "
                                        "the actuated mass, or a controller that is not strictly proper)")
        notes.append("neutral loop: the loop term does not decay, roots may exist at any frequency")
    if im_max is None:
        if proven * tau_max / _MAX_STEP <= _MAX_SAMPLES:
            return proven, seeds, ContourCertificate(sigma, proven, "bound", proven, True)
        omega, ratio = _sampled_ratio(model, weight_bound, sigma, growth, 1e-3, proven, seeds.imag)
        big = np.flatnonzero(ratio >= 0.5)
        radius = float(max(2.0 * omega[big[-1]], 1e-2)) if big.size else 1e-2
        notes.append(f"the proven height {proven:.6g} rad/s would need more than {_MAX_SAMPLES} samples "
                     f"at delay {tau_max:.6g} s; height from |L| sampled up to it (poles as samples)")
        return radius, seeds, ContourCertificate(sigma, radius, "sampled", proven, False, tuple(notes))
    certified = im_max >= proven
    if not certified and math.isfinite(proven):
        omega, ratio = _sampled_ratio(model, weight_bound, sigma, growth, im_max, proven, seeds.imag)
        beyond = ratio[omega > im_max]
        if beyond.size and beyond.max() >= 0.5:
            message = (f"im_max = {im_max:.6g} rad/s is too small for loop {model.loop.name!r}: its loop "
                       f"term reaches {beyond.max():.3g} (>= 1/2) at omega = "
                       f"{omega[omega > im_max][np.argmax(beyond)]:.6g} rad/s, roots beyond im_max may be "
                       f"missed; the proven height is {proven:.6g} rad/s (any im_max >= it is certified)")
            warnings.warn(message, StabilityWarning, stacklevel=4)
            notes.append(message)
        else:
            notes.append(f"im_max = {im_max:.6g} rad/s is below the proven height {proven:.6g} rad/s "
                         "(the sampled loop term stays below 1/2 in between)")
    return im_max, seeds, ContourCertificate(sigma, im_max, "user", proven, certified, tuple(notes))


def build_contour(model: LoopCharacteristic, weight_bound: np.ndarray, tau_max: float, *,
                  sigma: float = 0.0, im_max: float | None = None, resolution: int = 256) -> Contour:
    """The counting contour of a parameter box: height (proven when possible), far-edge phase,
    line samples seeded with the open-loop resonances, and the certificate.

    Parameters
    ----------
    model : LoopCharacteristic
    weight_bound : numpy.ndarray
        Largest ``|k w_j|`` per sensor term over the box (:func:`loop_weight_bound`).
    tau_max : float
        Largest delay of the box [s].
    sigma : float
        Abscissa of the counting line [1/s].
    im_max : float, optional
        User height [rad/s] (default: the proven height, :mod:`ctmm.certification`).
    resolution : int
        Initial number of line samples.
    """
    radius, poles, certificate = contour_height(model, weight_bound, sigma, tau_max, im_max)
    growth = math.exp(max(0.0, -sigma) * tau_max)
    notes = list(certificate.notes)
    for _ in range(8):
        far = _FarPath(model, sigma, radius, radius, 48, tau_max, 1e-12 * radius)
        ratio = growth * _loop_bound(far.base, far.terms, weight_bound)
        if np.all(ratio < 0.5) or certificate.source != "sampled":
            if not np.all(ratio < 0.5):
                notes.append(f"the loop term is not small on the far contour edges (max ratio "
                             f"{ratio.max():.3g}); roots beyond im_max = {radius:.6g} rad/s may be missed")
            break
        radius *= 2.0
    else:
        raise ModelError(f"no contour height found for loop {model.loop.name!r}: the loop term stays "
                         "large far from the origin; pass im_max")
    if radius != certificate.im_max or notes != list(certificate.notes):
        certificate = replace(certificate, im_max=radius, notes=tuple(notes))
    with np.errstate(all="ignore"):
        steps = np.angle(far.base[1:] / far.base[:-1])
    if not np.all(np.isfinite(steps)):
        raise ModelError("the open-loop characteristic function vanishes on the far contour edge; "
                         "pass a different im_max")
    n0 = max(resolution, int(math.ceil(radius * tau_max / _MAX_STEP)))
    seeds = _resonance_samples(poles, sigma, radius)
    line = _VerticalPath(model, [complex(sigma, 0.0), complex(sigma, radius)], n0, tau_max,
                         1e-13 * radius, seeds)
    return Contour(model, sigma, radius, line, float(steps.sum()), notes, certificate)


def _resonance_samples(poles: np.ndarray, sigma: float, radius: float) -> np.ndarray:
    """Samples of ``sigma + i omega`` at each open-loop pole's imaginary part and half-power
    points (distance of the pole to the line) on either side, inside ``[0, radius]``."""
    if poles.size == 0:
        return np.zeros(0, complex)
    width = np.maximum(np.abs(poles.real - sigma), 1e-9 * radius)
    omega = np.concatenate([poles.imag, poles.imag - width, poles.imag + width])
    omega = omega[(omega > 0) & (omega < radius)]
    return sigma + 1j * omega


# --------------------------------------------------------------------------------------------
# counting, vectorised over parameter sets
# --------------------------------------------------------------------------------------------
def _phase_steps(delta: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):
        return np.angle(delta[:, :-1] * np.conj(delta[:, 1:]))    # from sample j+1 down to j


def count(contour: Contour, gain: np.ndarray, delay: np.ndarray, weights: np.ndarray, *,
           chunk: int = 2048, refine: bool = True, rounds: int = 80,
           min_step: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Roots in Re s > sigma for each parameter set: ``(counts, reliable)``.

    Samples are added to the line where a set's phase step exceeds ``_COUNT_STEP`` (sets that
    are resolved keep their count).  ``counts`` is -1 where ``Delta`` vanishes at a sample of the
    line (a root on it).  Intervals are not split below ``min_step`` [rad/s]: sets that need
    finer samples (a root that close to the line) are returned as not reliable."""
    n = gain.size
    counts = np.full(n, -1, dtype=int)
    reliable = np.zeros(n, dtype=bool)
    line = contour.line
    pending = np.arange(n)
    for round_ in range(rounds):
        if pending.size == 0:
            break
        last = round_ == rounds - 1 or not refine
        h = np.diff(line.s.imag)
        refine_here = np.zeros(h.size, bool)
        unresolved = []
        for start in range(0, pending.size, chunk):
            idx = pending[start:start + chunk]
            delta = LoopCharacteristic.combine(line.s, line.base, line.terms, gain[idx], delay[idx],
                                               weights[idx])
            steps = _phase_steps(delta)
            bad = (np.abs(steps) > _COUNT_STEP) & (h > max(line.min_step, min_step))[None, :]
            open_ = bad.any(axis=1) & (not last)
            if open_.any():
                refine_here |= bad[open_].any(axis=0)
                unresolved.append(idx[open_])
            done = ~open_
            d, st = delta[done], steps[done]
            zero = np.any(d == 0, axis=1) | ~np.all(np.isfinite(d), axis=1)
            with np.errstate(all="ignore"):
                top = np.angle(d[:, -1] / line.base[-1])
                total = (contour.far_phase + top + st.sum(axis=1)) / math.pi
            rounded = np.round(np.where(np.isfinite(total), total, 0.0))
            counts[idx[done]] = np.where(zero, -1, rounded.astype(int))
            reliable[idx[done]] = ~zero & (np.abs(total - rounded) < 0.05) & \
                ~np.any(np.abs(st) > _COUNT_STEP, axis=1)
        pending = np.concatenate(unresolved) if unresolved else np.array([], int)
        if pending.size:
            line.insert(refine_here)
    return counts, reliable


def n_sets(gain: Any, delay: Any, weights: Any) -> int:
    """Number of parameter sets given as scalars / 1-D arrays (and weights rows), broadcast."""
    sizes = [int(np.size(v)) for v in (gain, delay) if v is not None and np.ndim(v) > 0]
    if weights is not None and np.ndim(weights) == 2:
        sizes.append(int(np.shape(weights)[0]))
    n = max(sizes, default=1)
    if any(size not in (1, n) for size in sizes):
        raise ModelError(f"parameter arrays must have a common length, got lengths {sizes}")
    return n


def check_parameters(k: np.ndarray, tau: np.ndarray, w: np.ndarray) -> None:
    """``ModelError`` for non-finite gains, delays or weights and for negative delays."""
    for label, values in (("gain", k), ("delay", tau), ("weights", w)):
        if not np.all(np.isfinite(values)):
            raise ModelError(f"{label} must contain only finite values, found {values[~np.isfinite(values)][0]!r}")
    if np.any(tau < 0):
        raise ModelError(f"delays must be >= 0 [s], got {tau[tau < 0][0]!r}")


def loop_weight_bound(k: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Largest ``|k w_j|`` per sensor term over parameter sets (gains ``(n,)``, weights ``(n, t)``)."""
    return np.max(np.abs(k[:, None] * w), axis=0)


def characteristic_callable(system: Any):
    """``s -> ctmm.characteristic_function(system, s)`` with floating-point warnings silenced."""
    def delta(s: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return characteristic_function(system, s)

    return delta


# --------------------------------------------------------------------------------------------
# executors
# --------------------------------------------------------------------------------------------
def _is_executor(value: Any) -> bool:
    return isinstance(value, Executor) or (callable(getattr(value, "submit", None))
                                           and callable(getattr(value, "map", None)))


@contextmanager
def managed_executor(executor: Any) -> Iterator[Any]:
    """Resolve an ``executor`` option; pools created here are shut down on exit."""
    if executor is None:
        yield None
    elif isinstance(executor, str):
        kinds = {"threads": ThreadPoolExecutor, "processes": ProcessPoolExecutor}
        if executor not in kinds:
            raise ModelError(f"executor must be None, 'threads', 'processes' or an Executor, got {executor!r}")
        with kinds[executor](max_workers=os.cpu_count() or 2) as pool:
            yield pool
    elif _is_executor(executor):
        yield executor
    else:
        raise ModelError(f"executor must be None, 'threads', 'processes' or an Executor, got {executor!r}")


def executor_workers(executor: Any) -> int:
    """Number of parallel workers of an executor (to split work into that many chunks)."""
    workers = getattr(executor, "_max_workers", None)
    if isinstance(workers, int) and workers > 0:
        return workers
    client = getattr(executor, "_client", None)
    if client is not None:                             # distributed.client.ClientExecutor
        try:
            return max(1, sum(client.nthreads().values()))
        except Exception:  # noqa: BLE001 - a closed client: fall back on the CPU count
            pass
    return os.cpu_count() or 2


def parallel_map(function: Callable[[Any], Any], items: Iterable[Any], *, executor: Any = None,
                 progress: bool | None = None, description: str = "sweep") -> list:
    """``[function(item) for item in items]``, sequentially or on ``executor``, in input order.

    Parameters
    ----------
    function : callable
        A picklable (module-level) function of one argument for process pools.
    items : iterable
        Arguments.
    executor : Executor, "threads", "processes" or None
        See the module docstring.
    progress : bool, optional
        Show a progress bar (default: on terminals for 50 items or more).
    description : str
        Label of the progress bar.
    """
    items = list(items)
    bar = progress_bar(len(items), description, enabled=progress, min_total=50)
    results = []
    try:
        with managed_executor(executor) as pool:
            if pool is None:
                for item in items:
                    results.append(function(item))
                    bar.update()
            else:
                futures = [pool.submit(function, item) for item in items]
                for future in futures:
                    results.append(future.result())
                    bar.update()
    finally:
        bar.close()
    return results
