"""The loop characteristic of a linear(ised) state-space model: delay stability of any model.

The stability tools (:mod:`ctmm.stability`, :mod:`ctmm.stability_chart`,
:mod:`ctmm.root_counts`) work on one delayed loop entering the characteristic function as an
affine term, ``Delta(s; k, tau, w) = base(s) + k e^{-s tau} sum_j w_j T_j(s)``
(:class:`ctmm.sweeps.AffineCharacteristic`).  For a transfer-matrix chain the components come
from the TMM (:class:`ctmm.sweeps.LoopCharacteristic`); here they come from a finite-dimensional
realisation, so the same tools accept

* a :class:`ctmm.linearize.LinearizedSystem` (``state_space`` with the delayed loops left open as
  input ``"<loop>_u"`` and output ``"<loop>_y"``, closed by ``u(t) = -gain y(t - delay)``), and
* a ``ctmm.control.ControlledModel`` (planar or spatial plant + loops): the plant is linearised by
  :func:`ctmm.linearize` about its static (hanging) equilibrium with the loops' actuators as inputs
  and their sensor terms as outputs; the sensor weights stay parameters (a chart over ``kp, kd``).

The characteristic function
---------------------------
With the loop under study open (every other loop closed; they must have no delay), the open
system is ``x' = A x + b u``, ``y_j = c_j x + d_j u`` (``b = sum_i v_i B_i`` over the weighted
actuator inputs).  An LTI controller ``C(s) = Cc (sI - Ac)^-1 Bc + Dc`` is appended to the states:
with ``u_tilde = -k e^{-s tau} sum_j w_j y_j`` the controller input,

    A' = [[A, -b Cc], [0, Ac]],  b' = [b Dc; -Bc],  c_j' = [c_j, -d_j Cc],  d_j' = d_j Dc,

so ``y_j = P_j(s) C(s) u_tilde`` with ``P_j = c_j (sI - A)^-1 b + d_j``.  Then

    Delta(s) = det(sI - A') (1 + k e^{-s tau} sum_j w_j P'_j(s)),
    base = det(sI - A') = D(s) det(sI - A),   T_j = det(sI - A') P'_j(s),             (1)

the same form (and the same ``D``: the controller denominator) as eq. (1) of :mod:`ctmm.sweeps`.
``base`` is a log-determinant and ``P'_j`` a linear solve, both batched over ``s``; at an exact
eigenvalue of ``A'`` (``det = 0``) the matrix determinant lemma gives ``T_j = det(sI - A' + b' c_j')``
instead.  The components are divided by their largest modulus at each ``s`` (zeros and phase
changes unchanged).

Certification
-------------
The realisation ``(A', b', c', d')`` is the one :mod:`ctmm.certification` bounds: with
``beta = ||T^-1 A' T||_inf`` after balancing, ``|L(s)| <= G/(|s| - beta) + H`` for every ``s``
with ``|s| > beta``, which gives the contour height ``R`` with ``|L| < 1/2`` for ``|s| >= R``
in the right half plane.  Nothing is sampled beyond ``R``, so every result is certified (or the
loop is neutral: ``|L(inf)| = |k d' | >= 1/2``, refused unless ``im_max`` is given).

What is refused
---------------
Other loops with a delay (the characteristic would hold two exponentials: not affine in one
loop), other loops with an LTI controller (ControlledModel; close them in
:func:`ctmm.linearize` and pass the :class:`LinearizedSystem`), and models without a loop.
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .control.controlled_model import ControlledModel
from .control.loops import ControlledChain
from .controller_state_space import controller_state_space
from .errors import ModelError, unknown_name
from .linearized import control_name
from .planar.model import PlanarModel
from .saturation import refuse_saturation
from .sweeps import (AffineCharacteristic, LoopCharacteristic, as_controlled, characteristic_callable,
                     normalised_columns)

__all__ = ["StateSpaceLoop", "LoopRealisation", "StateSpaceCharacteristic", "loop_characteristic",
           "is_loop_system", "loop_realisation", "characteristic_of"]


@dataclass(frozen=True)
class StateSpaceLoop:
    """A loop ``u(t) = -gain sum_j w_j y_j(t - delay)`` around a state-space model.

    Attributes
    ----------
    name : str
    terms : tuple of (str, float)
        Sensed outputs (ctmm names; matched to state-space labels through
        :func:`ctmm.interop.control_name`) and their weights.
    actuator_terms : tuple of (str, float)
        Inputs the loop force enters, with weights.
    gain : float or control.LTI
        Static gain or SISO controller ``C(s)``.
    delay : float
        [s], >= 0.
    """

    name: str
    terms: tuple
    actuator_terms: tuple
    gain: Any
    delay: float

    @property
    def is_lti(self) -> bool:
        """True when the gain is a controller ``C(s)`` rather than a number."""
        return not isinstance(self.gain, numbers.Real)


@dataclass(frozen=True)
class LoopRealisation:
    """A state-space model ``x' = A x + B u``, ``y = C x + D u`` with named ports and its loops."""

    name: str
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    inputs: tuple
    outputs: tuple
    loops: tuple

    def loop(self, name: str | None) -> StateSpaceLoop:
        """The loop called ``name`` (the only loop when ``None``)."""
        names = [lp.name for lp in self.loops]
        if name is None:
            if len(self.loops) != 1:
                raise unknown_name("loop (give loop=...)", "<none given>", names)
            return self.loops[0]
        if not isinstance(name, str):
            raise ModelError(f"loop must be a loop name (str), got {name!r}")
        if name not in names:
            raise unknown_name("loop", name, names)
        return self.loops[names.index(name)]

    def input_column(self, loop: str, name: str) -> int:
        """Column of ``B`` of input ``name`` (ctmm name or label)."""
        return _port(self.inputs, name, f"input of loop {loop!r}")

    def output_row(self, loop: str, name: str) -> int:
        """Row of ``C`` of output ``name`` (ctmm name or label)."""
        return _port(self.outputs, name, f"sensed output of loop {loop!r}")


def _port(labels: tuple, name: str, kind: str) -> int:
    for candidate in (name, control_name(name)):
        if candidate in labels:
            return labels.index(candidate)
    raise unknown_name(kind, name, list(labels))


# --------------------------------------------------------------------------------------------
# what the stability tools accept
# --------------------------------------------------------------------------------------------
def _is_linearized(system: Any) -> bool:
    return hasattr(system, "state_space") and hasattr(system, "delays")


def _is_controlled_model(system: Any) -> bool:
    return isinstance(system, ControlledModel)


def is_loop_system(system: Any) -> bool:
    """True for the models the delay-stability tools accept: a ControlledChain, a
    LinearizedSystem or a ControlledModel."""
    return isinstance(system, ControlledChain) or _is_linearized(system) or _is_controlled_model(system)


def _refuse(system: Any, what: str) -> ModelError:
    if isinstance(system, PlanarModel):
        return ModelError(f"{what} needs a feedback loop, but {system!r:.60} is a PlanarModel with no loop; "
                          "close one with ctmm.control.with_feedback(model, [Feedback(...)]) or pass "
                          "ctmm.linearize(...) of a model with a delayed loop")
    try:
        as_controlled(system, what)
    except ModelError as exc:
        return ModelError(f"{exc}; a ctmm.linearize(...) result with a delayed loop or a "
                          "ctmm.control.ControlledModel is accepted too")
    return ModelError(f"system must be a ControlledChain, LinearizedSystem or ControlledModel for {what}, "
                      f"got {system!r:.80}")  # pragma: no cover - as_controlled accepts only those


def loop_characteristic(system: Any, loop: str | None = None,
                        what: str = "stability analysis") -> AffineCharacteristic:
    """The loop characteristic of any accepted model (module docstring); ModelError otherwise."""
    if isinstance(system, ControlledChain):
        return LoopCharacteristic(system, loop)
    if _is_linearized(system) or _is_controlled_model(system):
        return StateSpaceCharacteristic(system, loop)
    raise _refuse(system, what)


def _as_array(value: Any, shape: tuple, label: str) -> np.ndarray:
    out = np.asarray(value, dtype=float)
    if out.size == 0:
        return np.zeros(shape)
    out = out.reshape(shape)
    if not np.all(np.isfinite(out)):
        raise ModelError(f"state_space.{label} must be finite, got a non-finite entry")
    return out


def _labels(ss: Any, attribute: str, count: int) -> tuple:
    labels = tuple(getattr(ss, attribute, ()) or ())
    if len(labels) != count:
        raise ModelError(f"state_space needs {count} {attribute} (named ports), got {labels!r}")
    return labels


def _matrices(ss: Any) -> tuple:
    """``(A, B, C, D, input labels, output labels)`` of a python-control StateSpace."""
    try:
        A = np.atleast_2d(np.asarray(ss.A, dtype=float))
        n_in, n_out = int(ss.ninputs), int(ss.noutputs)
    except (AttributeError, TypeError, ValueError) as exc:
        raise ModelError(f"state_space must be a control.StateSpace with A, B, C, D, got "
                         f"{type(ss).__name__} ({exc})") from None
    n = A.shape[0] if A.size else 0
    return (_as_array(ss.A, (n, n), "A"), _as_array(ss.B, (n, n_in), "B"), _as_array(ss.C, (n_out, n), "C"),
            _as_array(ss.D, (n_out, n_in), "D"), _labels(ss, "input_labels", n_in),
            _labels(ss, "output_labels", n_out))


def _from_linearized(system: Any) -> LoopRealisation:
    matrices = _matrices(system.state_space)
    loops = []
    for delayed in tuple(system.delays):
        name, gain, delay = delayed.name, delayed.gain, float(delayed.delay)
        if not np.isfinite(delay) or delay < 0:
            raise ModelError(f"delayed loop {name!r}: delay must be finite and >= 0 [s], got {delayed.delay!r}")
        if isinstance(gain, numbers.Real) and not np.isfinite(gain):
            raise ModelError(f"delayed loop {name!r}: gain must be finite, got {gain!r}")
        loops.append(StateSpaceLoop(name, ((f"{name}.y", 1.0),), ((f"{name}.u", 1.0),), gain, delay))
    if not loops:
        raise ModelError("stability analysis needs a delayed loop, but this LinearizedSystem has none "
                         "(delays=()); its roots are the eigenvalues of state_space.A")
    return LoopRealisation(str(getattr(system, "name", "linearised model")), *matrices, tuple(loops))


def _from_controlled_model(system: Any) -> LoopRealisation:
    """Linearise the plant about its static equilibrium, loop actuators in, sensor terms out."""
    from .linearize import linearize

    loops = tuple(system.loops)
    refuse_saturation(loops, "stability analysis")
    if not loops:
        raise _refuse(system.plant, "stability analysis")
    sensors = list(dict.fromkeys(name for lp in loops for name, _ in lp.terms))
    actuators = list(dict.fromkeys(name for lp in loops for name, _ in lp.actuator_terms))
    linear = linearize(system.plant, inputs=actuators, outputs=sensors)
    specs = tuple(StateSpaceLoop(lp.name, tuple(lp.terms), tuple(lp.actuator_terms), lp.gain, float(lp.delay))
                  for lp in loops)
    return LoopRealisation(system.name, *_matrices(linear.state_space), specs)


def loop_realisation(system: Any) -> LoopRealisation:
    """The state-space model and loops of a LinearizedSystem or a ControlledModel."""
    if _is_linearized(system):
        return _from_linearized(system)
    if _is_controlled_model(system):
        return _from_controlled_model(system)
    raise _refuse(system, "stability analysis")


def characteristic_of(system: Any) -> Callable[[np.ndarray], np.ndarray]:
    """Vectorised ``s -> Delta(s)`` of a chain (TMM) or of a one-loop state-space model."""
    if _is_linearized(system) or _is_controlled_model(system):
        model = StateSpaceCharacteristic(system)
        return model.char_fn()
    return characteristic_callable(system)


# --------------------------------------------------------------------------------------------
# the characteristic
# --------------------------------------------------------------------------------------------
def _weighted(real: LoopRealisation, lp: StateSpaceLoop) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(b, rows, C_rows, D_rows)``: the loop's input column and its sensed rows."""
    b = np.zeros(real.A.shape[0])
    d_in = np.zeros(real.D.shape[0])
    for name, weight in lp.actuator_terms:
        column = real.input_column(lp.name, name)
        b = b + float(weight) * real.B[:, column]
        d_in = d_in + float(weight) * real.D[:, column]
    rows = [real.output_row(lp.name, name) for name, _ in lp.terms]
    return b, np.array(rows, int), real.C[rows], d_in[rows]


def _close_static(real: LoopRealisation, others: list[StateSpaceLoop]) -> LoopRealisation:
    """Close delay-free static loops: ``u_o = -g_o sum w y``, solved with the feedthrough."""
    if not others:
        return real
    n_in = real.B.shape[1]
    K = np.zeros((n_in, real.C.shape[0]))
    for lp in others:
        if lp.is_lti:
            raise ModelError(f"loop {lp.name!r} has an LTI controller and no delay: close it in the "
                             "linearisation (ctmm.linearize) and pass the LinearizedSystem")
        for act, v in lp.actuator_terms:
            for sens, w in lp.terms:
                K[real.input_column(lp.name, act), real.output_row(lp.name, sens)] += float(lp.gain) * v * w
    try:
        E = np.linalg.solve(np.eye(n_in) + K @ real.D, K)        # (I + K D)^-1 K
    except np.linalg.LinAlgError:
        raise ModelError(f"the delay-free loops {[lp.name for lp in others]} form a singular algebraic "
                         "loop (I + K D is singular)") from None
    A = real.A - real.B @ E @ real.C
    B = real.B - real.B @ E @ real.D
    C = real.C - real.D @ E @ real.C
    D = real.D - real.D @ E @ real.D
    return LoopRealisation(real.name, A, B, C, D, real.inputs, real.outputs, real.loops)


def _augmented(A, b, C, d, lp: StateSpaceLoop):
    """Append the states of an LTI controller (module docstring)."""
    if not lp.is_lti:
        return A, b, C, d
    Ac, Bc, Cc, dc = controller_state_space(lp.name, lp.gain, "for the state-space characteristic (the loop may "
                                            "be neutral or advanced)")
    nc = Ac.shape[0]
    n = A.shape[0]
    A2 = np.zeros((n + nc, n + nc))
    A2[:n, :n], A2[:n, n:], A2[n:, n:] = A, -np.outer(b, Cc), Ac
    b2 = np.concatenate([b * dc, -Bc])
    C2 = np.hstack([C, -np.outer(d, Cc)])
    return A2, b2, C2, d * dc


class StateSpaceCharacteristic(AffineCharacteristic):
    """``Delta(s; k, tau, w)`` of one delayed loop around a state-space model, eq. (1).

    Parameters
    ----------
    system : LinearizedSystem or ControlledModel
        A :func:`ctmm.linearize` result (loops ``"<loop>_u"`` / ``"<loop>_y"``) or a planar plant
        with loops (linearised about its static equilibrium).
    loop : str, optional
        Loop name (default: the only loop).

    Attributes
    ----------
    parameter_names : tuple of str
        ``"gain"``, ``"delay"`` and the sensed outputs (their weights).
    gain, delay, weights
        Current gain factor (1 for an LTI controller, which ``gain`` then scales), delay [s] and
        sensor weights.
    A, b, C, d : numpy.ndarray
        The open-loop realisation of eq. (1) (controller states appended).

    Examples
    --------
    A unit mass under delayed PD, ``s^2 + (1 + s) e^{-s tau}``:

    >>> import numpy as np, control
    >>> from typing import NamedTuple
    >>> class Lin(NamedTuple):
    ...     state_space: object
    ...     delays: tuple
    >>> class Loop(NamedTuple):
    ...     name: str
    ...     gain: float
    ...     delay: float
    >>> ss = control.ss([[0, 1], [0, 0]], [[0], [1]], [[1, 1]], [[0]], inputs=["pd_u"], outputs=["pd_y"])
    >>> model = StateSpaceCharacteristic(Lin(ss, (Loop("pd", 1.0, 0.2),)))
    >>> s = np.array([0.3 + 2j])
    >>> d = model.evaluate(s, gain=[1.0, 2.0], delay=[0.2, 0.5])[:, 0]
    >>> exact = lambda k, tau: s[0] ** 2 + k * (1 + s[0]) * np.exp(-tau * s[0])
    >>> bool(abs(d[1] / d[0] - exact(2.0, 0.5) / exact(1.0, 0.2)) < 1e-12)
    True
    """

    def __init__(self, system: Any, loop: str | None = None) -> None:
        self.system = system
        real = loop_realisation(system)
        lp = real.loop(loop)
        self.loop = lp
        self.system_name = real.name
        self.term_names = tuple(name for name, _ in lp.terms)
        if len(set(self.term_names)) != len(self.term_names):
            raise ModelError(f"loop {lp.name!r} senses the same signal twice ({self.term_names}); "
                             "combine the weights into one term")
        delayed = [o.name for o in real.loops if o is not lp and o.delay > 0]
        if delayed:
            raise ModelError(f"loop {lp.name!r} is studied, but loop(s) {delayed} also have a delay: the "
                             "characteristic function would hold two exponentials (not affine in one "
                             "loop); set their delays to 0 or study a model without them")
        real = _close_static(real, [o for o in real.loops if o is not lp])
        b, _, C, d = _weighted(real, lp)
        self.A, self.b, self.C, self.d = _augmented(real.A, b, C, d, lp)
        self.parameter_names = ("gain", "delay") + self.term_names
        self.weights = np.array([float(w) for _, w in lp.terms])
        self.gain = 1.0 if lp.is_lti else float(lp.gain)
        self.delay = float(lp.delay)
        self.executor = None
        self.n_evaluations = 0

    def __getstate__(self) -> dict:
        state = super().__getstate__()
        state["system"] = None          # not needed for the components (models may hold lambdas)
        return state

    def open_loop_realisation(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(A, b, C, d)`` of the open loop ``y_j = P_j(s) C(s) u`` (for :mod:`ctmm.certification`)."""
        return self.A, self.b, self.C, self.d

    def components_at(self, s: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
        """``[base, T_1, ...]`` of eq. (1) at ``s``, divided by the largest modulus at each ``s`` (its log written
        into ``scale`` when given)."""
        s = np.asarray(s, dtype=complex).ravel()
        n, n_terms = self.A.shape[0], self.C.shape[0]
        logs = np.full((1 + n_terms, s.size), -np.inf + 0j)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            if n == 0:
                logs[0] = 0.0
                logs[1:] = np.log(self.d.astype(complex))[:, None]
                return normalised_columns(logs, scale)
            M = s[:, None, None] * np.eye(n)[None] - self.A[None]
            sign, log_abs = np.linalg.slogdet(M)
            regular = sign != 0
            if regular.any():
                x = np.linalg.solve(M[regular], np.broadcast_to(self.b, (int(regular.sum()), n))[..., None])[..., 0]
                response = x @ self.C.T + self.d[None, :]                        # (n_regular, n_terms)
                logs[0, regular] = np.log(sign[regular]) + log_abs[regular]
                logs[1:, regular] = logs[0, regular][None, :] + np.log(response.T)
            for i in np.flatnonzero(~regular):                                   # det(sI - A) = 0 exactly
                for j in range(n_terms):
                    logs[1 + j, i] = np.log(complex(np.linalg.det(M[i] + np.outer(self.b, self.C[j]))))
        return normalised_columns(logs, scale)
