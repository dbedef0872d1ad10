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

Counting the roots of the loop's characteristic function on a contour is in
:mod:`ctmm.counting_contour`.

Executors
---------
Every sweep in ctmm takes ``executor=``; the options and what happens when a task fails or a worker
process dies are described in :mod:`ctmm.executors`.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .assembly import SOLVERS, ChainSolution
from .control.loops import ControlledChain, Feedback
from .elements.lumped import Connector
from .errors import ModelError, SingularSystemError, unknown_name
from .controlled_chain_frequency import compiled_log_det
from .frequency import assemble, characteristic_function, solve
from .entire_values import entire_logs
from .executors import executor_workers, managed_executor, parallel_map
from .saturation import refuse_saturation

__all__ = ["AffineCharacteristic", "LoopCharacteristic", "normalised_columns", "managed_executor", "executor_workers", "parallel_map",
           "as_controlled", "find_loop", "delay_free_answer"]

TINY = 1e-13             # components below this (relative to the largest at s) are ignored


# --------------------------------------------------------------------------------------------
# the loop as an affine term
# --------------------------------------------------------------------------------------------
def as_controlled(system: Any, what: str = "stability analysis") -> ControlledChain:
    """``system`` as a :class:`ControlledChain`, or a :class:`ModelError` that says why not."""
    if isinstance(system, ControlledChain):
        refuse_saturation(system.loops, what)
        return system
    from .system import Chain

    if isinstance(system, Chain):
        raise ModelError(f"{what} needs a feedback loop, but {system.name!r} is a plain Chain with no "
                         "loop (nothing depends on a gain or a delay, a chart would be constant); "
                         f"delay-free answer: {delay_free_answer(system)}. Close a loop with "
                         "ctmm.control.ControlledChain(plant, [Feedback(...)]), or use "
                         "ctmm.stability.spectral_abscissa(system, ...) for its roots")
    raise ModelError(f"system must be a ctmm.control.ControlledChain for {what}, got {system!r}")


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
    connectors overflows at high frequency.  Where the sweep fails (a connector's stiffness or a
    substructure resonance at ``s``), the value is the certified circle mean of
    :func:`ctmm.entire_values.entire_logs`."""
    return entire_logs(lambda z: _direct_log_characteristic(system, z), s)[0]


def _direct_log_characteristic(system: Any, s: np.ndarray) -> np.ndarray:
    """``log Delta(s)`` by one Riccati sweep (NaN or ``LinAlgError`` where the sweep fails)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        log_det = compiled_log_det(system, s)      # lumped (controlled) chains: the compiled recursion
        if log_det is not None:
            return log_det + _log_pole_factor(system, s)
        Us, us, start, end = assemble(system, s, subdivide=True)     # long beams: exact pieces
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
    # connectors with the same law share one logarithm (a chain of 500 equal springs: one log, times 500)
    multiplicity: dict[tuple, list] = {}
    for element in body:
        if isinstance(element, Connector):
            co = element.axial_coefficients()        # what connector_stiffness reads
            key = (type(element).connector_stiffness, co.inertia, co.damping, co.stiffness)
            multiplicity.setdefault(key, [element, 0])[1] += 1
    out = np.zeros(s.shape, dtype=complex)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for element, count in multiplicity.values():
            log = np.log(np.asarray(element.connector_stiffness(s), dtype=complex))
            out.real += count * log.real           # part by part: count * (-inf + 0j) would give nan
            out.imag += count * log.imag
        for lp in (system.loops if controlled else ()):
            if lp.is_lti:
                out = out + np.log(np.asarray(lp.denominator(s), dtype=complex))
    return out


def normalised_columns(logs: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
    """``exp(logs)`` divided by the largest modulus in each column (zeros where log is -inf).

    ``scale``: when given (shape ``(n_columns,)``, float), receives the log of each column's divisor.  The
    divisor is a positive, not a holomorphic, function of ``s``: Cauchy integrals over small circles
    (:mod:`ctmm.roots`' Newton steps) multiply it back."""
    finite = np.isfinite(logs.real)
    top = np.max(np.where(finite, logs.real, -np.inf), axis=0)
    top = np.where(np.isfinite(top), top, 0.0)
    if scale is not None:
        scale[...] = top
    with np.errstate(under="ignore", invalid="ignore", over="ignore"):
        values = np.exp(logs - top)
    return np.where(finite, values, 0.0)


class AffineCharacteristic:
    """Eq. (1) evaluated from components: ``Delta = base + k e^{-s tau} sum_j w_j T_j``.

    Shared by :class:`LoopCharacteristic` (transfer-matrix chains) and
    :class:`ctmm.state_space_characteristic.StateSpaceCharacteristic` (linear(ised) state-space
    models).  A subclass sets ``gain``, ``delay``, ``weights``, ``term_names``,
    ``parameter_names``, ``loop`` (with ``name`` and ``is_lti``), ``system_name``,
    ``executor = None``, ``n_evaluations = 0`` and implements :meth:`components_at`.
    """

    gain: float
    delay: float
    weights: np.ndarray
    executor: Any = None
    n_evaluations: int = 0

    def components_at(self, s: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
        """``[base, T_1, ...]`` at ``s`` (shape ``(1 + n_terms, n)``), divided by a positive
        function of ``s`` (its log written into ``scale`` when given, shape ``(n,)``)."""
        raise NotImplementedError

    def components(self, s: Any, scale: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``(Delta_0 D, T)`` at ``s``: shapes ``(n,)`` and ``(n_terms, n)`` (scaled, see Notes); ``scale`` (shape
        ``(n,)``, float), when given, receives the log of the positive divisor at each ``s``."""
        s = np.asarray(s, dtype=complex).ravel()
        self.n_evaluations += s.size
        executor = self.executor
        if executor is None or s.size < 64:
            out = self.components_at(s, scale)
        else:
            chunks = np.array_split(s, executor_workers(executor))
            parts = list(executor.map(_components_chunk, [self] * len(chunks), chunks))
            out = np.concatenate(parts, axis=1)
            if scale is not None:
                scale[...] = out[-1].real
            out = out[:-1]
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

        def scaled(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """``(Delta(s) e^-g(s), g(s))``: the values of ``delta`` and the log of their positive divisor."""
            s = np.asarray(s, dtype=complex)
            scale = np.zeros(s.size)
            base, terms = self.components(s.ravel(), scale)
            return self.combine(s.ravel(), base, terms, k, tau, w)[0].reshape(s.shape), scale.reshape(s.shape)

        def delta(s: np.ndarray) -> np.ndarray:
            return scaled(s)[0]

        delta.scaled = scaled          # type: ignore[attr-defined]
        return delta


def _components_chunk(model: "AffineCharacteristic", s: np.ndarray) -> np.ndarray:
    """The components at ``s`` with the log of their divisor as a last row."""
    scale = np.zeros(s.size)
    return np.vstack([model.components_at(s, scale), scale[None, :]])


class LoopCharacteristic(AffineCharacteristic):
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
        self.system_name = self.system.name
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
        self._points = sorted({point for point, _, _ in self._sensed})   # lumped plants: the compiled recursion
        self.executor = None
        self.n_evaluations = 0
        self._phase = None

    # -- components ---------------------------------------------------------------------
    def components_at(self, s: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
        """``[D Delta_0, T_1, ...]`` at ``s``, divided by the largest modulus at each ``s`` (its log written into
        ``scale`` when given).

        Fast path: with the loop open, ``Delta_0`` (log of the boundary determinant) and the
        responses ``P_j`` of the sensed signals to a unit actuator force come from the open chain
        (no extended states); by the matrix determinant lemma the loop adds
        ``T_j = D Delta_0 C P_j``.  Where the open chain is singular (an open-loop root exactly
        at a sample, e.g. s = 0 of a free chain) the extended closed chains are swept instead.
        Where a sweep fails although the function is finite (a connector's stiffness ``c s`` or
        ``b s^2`` vanishing at ``s = 0``, a substructure resonance making a Riccati pivot
        singular), the components are the certified circle means of
        :func:`ctmm.entire_values.entire_logs`."""
        s = np.asarray(s, dtype=complex).ravel()
        out = np.empty((1 + len(self._sensed), s.size), dtype=complex)
        try:             # one sweep for the determinant and the responses (a regular open chain)
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                solution = solve(self.open_system, s, self._amplitudes, want_log_det=True, points=self._points)
                log_open = solution.log_det + _log_pole_factor(self.open_system, s)
            if np.all(np.isfinite(log_open)):
                logs = self._component_logs(s, log_open, solution)
                if not np.isnan(logs).any():
                    out[:] = normalised_columns(logs, scale)
                    return out
        except (SingularSystemError, np.linalg.LinAlgError):   # a root of the open chain at a sample
            pass
        log_open = _log_characteristic(self.open_system, s)
        regular = np.isfinite(log_open)
        part = np.zeros(s.size)               # the logs of the divisors, copied into scale at the end
        if regular.any():
            try:
                inside = np.zeros(int(regular.sum()))
                out[:, regular] = normalised_columns(entire_logs(self._open_logs, s[regular],
                                                                 label=f"loop {self.loop.name!r}"), inside)
                part[regular] = inside
            except SingularSystemError:
                regular[:] = False
        if not regular.all():
            inside = np.zeros(int((~regular).sum()))
            out[:, ~regular] = self._components_closed(s[~regular], inside) * self._closed_phase()
            part[~regular] = inside
        if scale is not None:
            scale[...] = part
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

    def _open_logs(self, s: np.ndarray) -> np.ndarray:
        """Unnormalised logs of ``[D Delta_0, T_1, ...]`` from one open-chain sweep (NaN or an
        exception where the sweep fails: :func:`ctmm.entire_values.entire_logs` repairs them)."""
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            solution = solve(self.open_system, s, self._amplitudes, want_log_det=True, points=self._points)
            log_open = solution.log_det + _log_pole_factor(self.open_system, s)
        return self._component_logs(s, log_open, solution)

    def _components_open(self, s: np.ndarray, log_open: np.ndarray,
                         states: ChainSolution | None = None) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            if states is None:
                states = solve(self.open_system, s, self._amplitudes, points=self._points)
        return normalised_columns(self._component_logs(s, log_open, states))

    def _component_logs(self, s: np.ndarray, log_open: np.ndarray, states: ChainSolution) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            log_base = log_open
            controller = np.zeros(s.size, complex)
            if self.loop.is_lti:
                log_base = log_base + np.log(self.loop.denominator(s).astype(complex))
                controller = np.log(self.loop.controller_response(s).astype(complex))
            logs = [log_base]
            for point, component, derivative in self._sensed:
                response = states.at(point)[:, component] * s ** derivative
                logs.append(log_base + controller + np.log(response.astype(complex)))
            return np.array(logs)

    def _components_closed(self, s: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
        logs = [_log_characteristic(self._base, s)]
        if self.loop.is_lti:
            with np.errstate(divide="ignore"):
                logs[0] = logs[0] + np.log(self.loop.denominator(s).astype(complex))
        logs += [_log_characteristic(g, s) for g in self._groups]
        values = normalised_columns(np.array(logs), scale)
        base = values[0]
        groups = values[1:] - base
        terms = groups[self._group_of] * s[None, :] ** self._power[:, None]
        return np.vstack([base[None, :], terms])

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


