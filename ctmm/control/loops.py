"""Feedback loops embedded in the transfer matrices (seed 001 §9.5-9.6; FORMULAS §5).

A :class:`Feedback` applies the control force

    u(t) = -C[ y(t - tau) - r(t - tau) ],    y = sum_i c_i * signal_i

at an actuator: on a *point element* (force ``+u`` on its point, e.g. a mass) or *across a
connector* (``+u`` on its outboard point, ``-u`` on its inboard point, like an actuator in
parallel with the spring-damper ``K3, C3`` of seed Fig. 9.30).  ``C`` is a gain or a
python-control LTI controller; ``signal_i`` are displacement, velocity, acceleration or force
signals anywhere in the chain (upstream, downstream or collocated with the actuator; a
relative measurement is two terms).

Embedding without control states (the extended state vector)
-----------------------------------------------------------
Each loop adds two components to the state vector:

* ``y`` -- the sensed value: unknown at the start, carried unchanged (identity rows);
* ``acc`` -- an accumulator: zero at the start, ``acc += c_i * signal_i`` when the sweep passes
  the point of ``signal_i`` (a unit lower-triangular, invertible *sensing* matrix).

The actuator's transfer matrix gets the column ``-C(s) e^{-s tau}`` on ``y`` (force row of a point
element; displacement row ``/(k + c s)`` of a connector), and the end condition gains
``acc - y = 0``.  Because ``y`` is an unknown of the boundary-value problem, the closed loop is
solved exactly by the same Riccati sweep wherever the sensor sits, and the characteristic
determinant of the extended chain vanishes at the closed-loop roots (with exact delays).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from collections.abc import Iterable, Mapping
from typing import Any, Sequence

import numpy as np

from .. import validation
from ..assembly import BoundaryEnd, BoundaryStart
from ..elements.lumped import Connector
from ..errors import ModelError, unknown_name
from ..saturation import check_limits, clip, refuse_saturation
from ..system import Chain, Signal


def _is_lti(gain: Any) -> bool:
    """True for a python-control LTI system.  Without python-control imported no object can be one, so a plain
    number is answered without importing it (the import costs ~1.5 s of CPU on first use)."""
    control = sys.modules.get("control")
    return control is not None and isinstance(gain, control.LTI)


def _lti_siso(name: str, gain: Any):
    import control

    if gain.ninputs != 1 or gain.noutputs != 1:
        raise ModelError(f"loop {name!r}: controller must be SISO, got {gain.ninputs} inputs, "
                         f"{gain.noutputs} outputs")
    if not control.isctime(gain):
        raise ModelError(f"loop {name!r}: discrete-time LTI controllers are not embeddable; "
                         "use a sampled controller object (co-simulation) instead")
    if isinstance(gain, control.StateSpace):
        for label, matrix in (("A", gain.A), ("B", gain.B), ("C", gain.C), ("D", gain.D)):
            values = np.asarray(matrix, dtype=complex)
            if not np.all(np.isfinite(values)):
                raise ModelError(f"loop {name!r}: gain (LTI controller) state-space matrix {label} must be "
                                 f"finite, got {values.real.tolist()}")
    tf = control.tf(gain)
    for label, coefficients in (("numerator", tf.num[0][0]), ("denominator", tf.den[0][0])):
        values = np.asarray(coefficients, dtype=complex)
        if not np.all(np.isfinite(values)):
            raise ModelError(f"loop {name!r}: gain (LTI controller) {label} coefficients must be finite, "
                             f"got {values.real.tolist()}")
    if not np.any(np.asarray(tf.den[0][0]) != 0):
        raise ModelError(f"loop {name!r}: gain (LTI controller) denominator must not be zero, got {gain!r}")
    return gain


def _weighted_terms(loop: str, role: str, value: Any, single: str, item: str) -> tuple:
    """``(name, weight)`` pairs from a name or a sequence of pairs, validated."""
    if isinstance(value, str):
        return ((value, 1.0),)
    try:
        terms = tuple((name, validation.finite(f"loop {loop!r}: {role} weight", weight))
                      for name, weight in value)
        if not all(isinstance(name, str) for name, _ in terms):
            raise TypeError("names must be strings")
    except (TypeError, ValueError) as exc:
        raise ModelError(f"loop {loop!r}: {role} must be {single} or a sequence of ({item}, weight) pairs, "
                         f"got {value!r}") from exc
    if not terms:
        raise ModelError(f"loop {loop!r}: {role} needs at least one {item}, got {value!r}")
    return terms


@dataclass(frozen=True)
class Feedback:
    """A feedback loop ``u = -C (y(t - delay) - r(t - delay))`` with force ``u`` at ``actuator``.

    Parameters
    ----------
    name : str
        Loop name; signals ``"<name>.y"``, ``"<name>.u"`` and input ``"<name>.reference"``.
    sensor : str or sequence of (str, float)
        Measured signal name (e.g. ``"m6.x"``, ``"m6.v"``, ``"m6.a"``, ``"k3.f"``) or weighted
        terms, e.g. ``[("m6.x", 1.0), ("m5.x", -1.0)]`` for a relative measurement.
    actuator : str or sequence of (str, float)
        Where the control force/moment ``u`` enters: an element input (``"m2.force"``,
        ``"pzt.moment"``), or an element name meaning its first input (``"m2"``: force on a
        mass; ``"K3"``: force across a connector), or weighted inputs, e.g. a PZT moment pair
        ``[("p1.moment", -1.0), ("p2.moment", 1.0)]``.  ``u`` enters every element exactly as its
        input would (the element's unit-input load vector is the loop's column).
    gain : float or control.LTI
        Static gain [N per sensed unit] or a SISO continuous-time python-control system ``C(s)``.
        Required (no default: a loop built without it would silently do nothing).
    delay : float
        Loop delay ``tau`` [s], >= 0 (exact ``e^{-s tau}`` in the frequency domain; history in time).
    saturation : (float, float) or None
        Actuator limits ``(low, high)`` [actuator unit: N, N m, or V for a PZT loop whose weights are
        the moments per volt], ``low < high`` (``-inf``/``inf`` for a one-sided limit): the applied
        force is ``min(max(u, low), high)`` (:meth:`saturate`).  Honoured by the time paths of planar
        models (:func:`ctmm.simulate`: RK4, scipy and every implicit scheme; the result holds
        ``"<name>.u_demand"``, ``"<name>.saturated"`` and ``info["time_saturated_s"]``).  A saturated
        loop is not linear: the frequency-domain, linearisation and stability verbs refuse it (use
        :meth:`unsaturated` for the small-signal loop inside the limits), and a 1-D
        :class:`ControlledChain` refuses it (its loops are embedded linearly in every path).
        ``None`` (default): no limit.
    """

    name: str
    sensor: Any
    actuator: str
    gain: Any
    delay: float = 0.0
    saturation: Any = None
    terms: tuple = field(init=False, repr=False, compare=False)
    actuator_terms: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        validation.name("loop", self.name)
        object.__setattr__(self, "actuator_terms",
                           _weighted_terms(self.name, "actuator", self.actuator, "an input name", "input"))
        object.__setattr__(self, "terms", _weighted_terms(self.name, "sensor", self.sensor, "a signal name", "signal"))
        if _is_lti(self.gain):
            _lti_siso(self.name, self.gain)
        else:
            object.__setattr__(self, "gain", validation.finite(f"loop {self.name!r}: gain", self.gain))
        object.__setattr__(self, "delay", validation.nonnegative(f"loop {self.name!r}: delay", self.delay))
        if self.saturation is not None:
            object.__setattr__(self, "saturation", check_limits(self.name, self.saturation))

    def with_parameters(self, *, gain: Any = None, delay: float | None = None) -> "Feedback":
        """A copy with a new gain/controller and/or delay (the plant and the saturation are untouched)."""
        return Feedback(self.name, self.sensor, self.actuator, self.gain if gain is None else gain,
                        self.delay if delay is None else delay, self.saturation)

    def unsaturated(self) -> "Feedback":
        """The same loop without its saturation: the small-signal (linearised) loop about an operating
        point strictly inside the limits (slope 1; at a limit the slope is 0 and the loop is open)."""
        return Feedback(self.name, self.sensor, self.actuator, self.gain, self.delay)

    def saturate(self, u: Any) -> Any:
        """``u`` clipped to :attr:`saturation` (``u`` itself without one), branch-free and complex-step
        safe: the real part decides, so the derivative is 1 inside the limits and 0 at them."""
        return clip(self.saturation, u)

    @property
    def is_lti(self) -> bool:
        """True when the gain is a python-control LTI system."""
        return _is_lti(self.gain)

    def controller_response(self, s: np.ndarray) -> np.ndarray:
        """``C(s)`` (without the delay) over an array of Laplace variables."""
        s = np.asarray(s, dtype=complex)
        if self.is_lti:
            return np.asarray(self.gain(s), dtype=complex).reshape(s.shape)
        return np.full(s.shape, self.gain, dtype=complex)

    def loop_gain(self, s: np.ndarray) -> np.ndarray:
        """``C(s) e^{-s tau}`` over an array of Laplace variables."""
        s = np.asarray(s, dtype=complex)
        return self.controller_response(s) * np.exp(-s * self.delay)

    def denominator(self, s: np.ndarray) -> np.ndarray:
        """Denominator of ``C(s)`` (1 for a gain): clears the controller's poles from determinants."""
        s = np.asarray(s, dtype=complex)
        if self.is_lti:
            import control

            tf = control.tf(self.gain)
            return np.polyval(np.asarray(tf.den[0][0], dtype=float), s)
        return np.ones(s.shape, dtype=complex)


@dataclass(frozen=True)
class _Resolved:
    loop: Feedback
    index: int            # loop number
    actuators: tuple      # ((element position, input name, weight), ...)
    sensing: tuple        # ((point, component, derivative, weight), ...)

    @property
    def actuator_pos(self) -> int:
        """Position of the (first) actuated element."""
        return self.actuators[0][0]


class ControlledChain:
    """A :class:`~ctmm.system.Chain` closed by :class:`Feedback` loops.

    The plant is not copied or rebuilt: loops only add the extended-state rows described in
    the module docstring.  All frequency-domain functions (``frequency_response``,
    ``characteristic_function``, ...) and :func:`ctmm.control.simulate_controlled` accept it.

    Parameters
    ----------
    plant : Chain
        The uncontrolled chain.
    loops : sequence of Feedback
        Loops (unique names).
    """

    def __init__(self, plant: Chain, loops: Sequence[Feedback]) -> None:
        if not isinstance(plant, Chain):
            raise ModelError(f"plant must be a ctmm.Chain, got {plant!r}")
        if isinstance(loops, Feedback):
            loops = [loops]
        if isinstance(loops, (str, bytes, Mapping)) or not isinstance(loops, Iterable):
            raise ModelError(f"loops must be a list of Feedback loops, got {loops!r}")
        self.plant = plant
        self.loops: tuple[Feedback, ...] = tuple(loops)
        self.name = plant.name + "+control"
        problems = [f"loops[{i}] must be a Feedback loop, got {lp!r}"
                    for i, lp in enumerate(self.loops) if not isinstance(lp, Feedback)]
        if problems:
            raise ModelError(f"controlled chain {self.name!r} is invalid:\n  - " + "\n  - ".join(problems))
        names = [lp.name for lp in self.loops]
        if len(set(names)) != len(names):
            problems.append(f"loop names must be unique, got {names}")
        clash = set(names) & {e.name for e in plant.elements}
        if clash:
            problems.append(f"loop names {sorted(clash)} clash with element names")
        if problems:
            raise ModelError(f"controlled chain {self.name!r} is invalid:\n  - " + "\n  - ".join(problems))
        self._resolved = tuple(self._resolve(i, lp) for i, lp in enumerate(self.loops))
        extras = []
        for lp in self.loops:
            extras += [f"{lp.name}:y", f"{lp.name}:acc"]
        self.layout = plant.layout.with_extras(*extras)
        self._by_loop = {lp.name: i for i, lp in enumerate(self.loops)}

    def _resolve(self, index: int, loop: Feedback) -> _Resolved:
        plant = self.plant
        known = [e.name for e in plant.body if e.inputs] + [n for n in plant.input_names()
                                                           if plant.element(n.split(".")[0]) in plant.body]
        actuators = []
        for name, weight in loop.actuator_terms:
            if name not in known:
                raise unknown_name(f"actuator of loop {loop.name!r} (an element input, or an element "
                                   "with inputs)", name, known)
            element_name, _, input_name = name.partition(".")
            element = plant.element(element_name)
            actuators.append((plant.position(element_name), input_name or element.inputs[0], weight))
        sensing = []
        for signal_name, weight in loop.terms:
            try:
                sig: Signal = plant.signal(signal_name)
            except ModelError as exc:
                raise type(exc)(f"loop {loop.name!r}: sensor {exc}") from None
            sensing.append((sig.point, sig.component, sig.derivative, weight))
        return _Resolved(loop, index, tuple(actuators), tuple(sensing))

    # -- delegation to the plant ----------------------------------------------------------
    @property
    def elements(self):
        return self.plant.elements

    @property
    def body(self):
        return self.plant.body

    @property
    def start(self):
        return self.plant.start

    @property
    def end(self):
        return self.plant.end

    @property
    def n_points(self) -> int:
        return self.plant.n_points

    def point_names(self):
        return self.plant.point_names()

    def position(self, name: str) -> int:
        return self.plant.position(name)

    def element(self, name: str):
        return self.plant.element(name)

    def loop(self, name: str) -> Feedback:
        """The loop called ``name``."""
        if not isinstance(name, str) or name not in self._by_loop:
            raise unknown_name("loop", name, list(self._by_loop))
        return self.loops[self._by_loop[name]]

    def with_loops(self, loops: Sequence[Feedback]) -> "ControlledChain":
        """The same plant closed by other loops (cheap: nothing of the plant is rebuilt)."""
        return ControlledChain(self.plant, loops)

    # -- names ----------------------------------------------------------------------------
    def signal_names(self) -> list[str]:
        return self.plant.signal_names() + [f"{lp.name}.{q}" for lp in self.loops for q in ("y", "u")]

    def signal(self, name: str) -> Signal:
        parts = name.split(".") if isinstance(name, str) else []
        if len(parts) == 2 and parts[0] in self._by_loop:
            i = self._by_loop[parts[0]]
            d = self.plant.layout.size
            if parts[1] == "y":
                return Signal(name, self.n_points - 1, d + 2 * i, 0)
            if parts[1] == "u":
                return Signal(name, self.n_points - 1, d + 2 * i, -1)  # -1: control force, see below
            raise unknown_name("signal", name, self.signal_names())
        try:
            return self.plant.signal(name)
        except ModelError:
            raise unknown_name("signal", str(name), self.signal_names()) from None

    def input_names(self) -> list[str]:
        return self.plant.input_names() + [f"{lp.name}.reference" for lp in self.loops]

    def input(self, name: str):
        parts = name.split(".") if isinstance(name, str) else []
        if len(parts) == 2 and parts[0] in self._by_loop:
            if parts[1] != "reference":
                raise unknown_name("input", name, self.input_names())
            return _LoopInput(name, self._by_loop[parts[0]])
        try:
            return self.plant.input(name)
        except ModelError:
            raise unknown_name("input", str(name), self.input_names()) from None

    @property
    def state_index(self) -> list[int]:
        """Index, in the states of the extended matrices (:meth:`assemble_frequency`, the
        real-time step of :mod:`ctmm.control.simulate`), of plant connection point ``j``: one
        matrix per plant element, plus one sensing matrix after every sensed point."""
        sensed = {point for r in self._resolved for point, *_ in r.sensing}
        index, count = [], 0
        for j in range(len(self.plant.body) + 1):
            count += (j > 0) + (j in sensed)
            index.append(count)
        return index

    # -- frequency domain -----------------------------------------------------------------
    def assemble_frequency(self, s: np.ndarray, amplitudes: Mapping[Any, Mapping[str, Any]]):
        """Extended element matrices (elements interleaved with sensing matrices) at ``s``.

        Returns ``Us, us, start, end`` for :func:`ctmm.assembly.riccati_solve`; the property
        :attr:`state_index` maps connection point ``j`` to the index of its state in the result.
        """
        from ..frequency import assemble as assemble_plant

        refuse_saturation(self.loops, "the frequency-domain verbs")
        s = np.asarray(s, dtype=complex)
        self._refuse_long_fields(float(np.max(np.abs(s), initial=0.0)))
        plant_amps = {k: v for k, v in amplitudes.items() if not isinstance(k, str)}
        refs = {k: v for k, v in amplitudes.items() if isinstance(k, str)}
        Us_p, us_p, start_p, end_p = assemble_plant(self.plant, s, plant_amps)
        gains = [r.loop.loop_gain(s) for r in self._resolved]
        ref_amp = [refs.get(r.loop.name, {}).get("reference", 0.0) for r in self._resolved]
        columns = [[(pos, weight * np.asarray(self.plant.elements[pos].load_vector(s, {name: 1.0})))
                    for pos, name, weight in r.actuators] for r in self._resolved]
        return self._extend(s, Us_p, us_p, start_p, end_p, gains, ref_amp,
                            lambda point, comp, deriv: s ** deriv, columns=columns)

    def _refuse_long_fields(self, omega_max: float) -> None:
        """Refuse a plant element that one transfer matrix cannot hold exactly up to ``omega_max``
        [rad/s] (a long :class:`~ctmm.elements.beams.BeamField`: entries ``~ cosh beta`` lose
        ``~ e^beta eps``); plain chains subdivide it themselves, the loop matrices are per element."""
        for element in self.plant.body:
            hook = getattr(element, "subdivide", None)
            pieces = len(hook(omega_max)) if hook is not None and omega_max > 0 else 1
            if pieces > 1:
                raise ModelError(f"element {element.name!r} of controlled chain {self.plant.name!r} is too long "
                                 f"for one transfer matrix up to |s| = {omega_max:.6g} rad/s (digits would be "
                                 f"lost); put its pieces *{element.name}.split({pieces}) in its place in the plant")

    def _extend(self, s, Us_p, us_p, start_p, end_p, gains, ref_amp, derivative_factor,
                sensing_offset=None, columns=None):
        """Extended matrices; ``columns[i]`` = ``[(element position, unit-input load vector), ...]``
        of loop ``i`` (the control force enters like that input)."""
        refuse_saturation(self.loops, "the embedded (linear) loop matrices of a 1-D ControlledChain")
        nb = s.shape[0] if np.ndim(s) else 1
        d0 = self.plant.layout.size
        n = self.layout.size
        nl = len(self._resolved)
        dtype = np.result_type(Us_p[0], *[np.asarray(g) for g in gains]) if gains else Us_p[0].dtype
        sensing_at: dict[int, list] = {}
        for r in self._resolved:
            for (point, comp, deriv, weight) in r.sensing:
                sensing_at.setdefault(point, []).append((r.index, comp, deriv, weight))
        Us, us, state_index = [], [], []

        def add_sensing(point: int) -> None:
            if point not in sensing_at:
                return
            U = np.broadcast_to(np.eye(n, dtype=dtype), (nb, n, n)).copy()
            u = np.zeros((nb, n), dtype=dtype)
            for (i, comp, deriv, weight) in sensing_at[point]:
                row = d0 + 2 * i + 1
                factor = derivative_factor(point, comp, deriv)
                U[:, row, comp] += weight * factor
                if sensing_offset is not None:
                    u[:, row] += weight * sensing_offset(point, comp, deriv)
            Us.append(U)
            us.append(u)

        add_sensing(0)
        state_index.append(len(Us))
        for j, (Up, up) in enumerate(zip(Us_p, us_p), start=1):
            U = np.zeros((nb, n, n), dtype=dtype)
            U[:, :d0, :d0] = Up
            U[:, d0:, d0:] = np.eye(n - d0)
            u = np.zeros((nb, n), dtype=dtype)
            u[:, :d0] = up
            for r in self._resolved:
                g = gains[r.index]
                col = d0 + 2 * r.index
                ref = g * ref_amp[r.index]
                for pos, unit in columns[r.index]:
                    if pos != j:
                        continue
                    unit = np.broadcast_to(unit, (nb, d0))
                    U[:, :d0, col] += -g[..., None] * unit if np.ndim(g) else -g * unit
                    u[:, :d0] += (ref[..., None] if np.ndim(ref) else ref) * unit
            Us.append(U)
            us.append(u)
            add_sensing(j)
            state_index.append(len(Us))
        if state_index != self.state_index:   # the matrices and the documented index must agree
            raise ModelError(f"{self!r}: {len(Us_p)} plant matrices for {len(self.plant.body)} elements")
        # start: y unknown (e), acc known (= 0)
        e_idx = list(start_p.e_indices) + [d0 + 2 * i for i in range(nl)]
        nf = n - len(e_idx)
        m = len(e_idx)
        S0 = np.zeros((nb, nf, m), dtype=dtype)
        S0[:, : d0 - len(start_p.e_indices), : len(start_p.e_indices)] = start_p.S0
        P0 = np.zeros((nb, nf), dtype=dtype)
        P0[:, : d0 - len(start_p.e_indices)] = start_p.P0
        Bm = np.zeros((nb, m, n), dtype=dtype)
        Bm[:, : end_p.Bm.shape[1], :d0] = end_p.Bm
        b = np.zeros((nb, m), dtype=dtype)
        b[:, : end_p.b.shape[1]] = end_p.b
        for i in range(nl):
            row = end_p.Bm.shape[1] + i
            Bm[:, row, d0 + 2 * i + 1] = 1.0
            Bm[:, row, d0 + 2 * i] = -1.0
        return Us, us, BoundaryStart(e_idx, S0, P0), BoundaryEnd(Bm, b)

    def characteristic_scale(self, s: np.ndarray) -> np.ndarray:
        """Factor that makes the extended chain's determinant entire in ``s``.

        Connectors contribute ``k + c s`` (their transfer matrices have ``1/(k + c s)``), LTI
        controllers their denominators.
        """
        s = np.asarray(s, dtype=complex)
        scale = np.ones(s.shape, dtype=complex)
        for e in self.plant.body:
            if isinstance(e, Connector):
                scale = scale * e.connector_stiffness(s)
        for r in self._resolved:
            scale = scale * r.loop.denominator(s)
        return scale

    def __repr__(self) -> str:
        return f"ControlledChain({self.plant!r}, loops={[lp.name for lp in self.loops]})"


def actuator_inputs(system: ControlledChain, loop: str) -> list[tuple[str, float]]:
    """The plant inputs ``[(input name, weight), ...]`` through which the force of ``loop`` enters
    (an element name stands for its first input: ``"m2"`` -> ``"m2.force"``; weights [-]).

    Also reachable as ``ctmm.control.analysis.actuator_inputs``; used by the state-space
    realisation (:mod:`ctmm.interop`) and the certified contour height (:mod:`ctmm.certification`).
    """
    lp = system.loop(loop)
    refuse_saturation([lp], "a linear model of the loop (state space, linearisation, sensitivity)")
    out = []
    for name, weight in lp.actuator_terms:
        if "." not in name:
            name = f"{name}.{system.plant.element(name).inputs[0]}"
        out.append((name, float(weight)))
    return out


@dataclass(frozen=True)
class _LoopInput:
    name: str
    loop_index: int

    @property
    def position(self) -> str:  # key used in amplitude mappings
        return self.name.split(".")[0]

    @property
    def input(self) -> str:
        return "reference"
