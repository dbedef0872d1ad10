"""The loops of a ``ControlledModel`` around the linearisation of its plant (planar and spatial).

One function for every plant that :func:`ctmm.linearize` linearises about an operating point
(:mod:`ctmm.planar_linearization`, :mod:`ctmm.spatial_linearization`): given the plant's tangent
``A`` (states ``x``, deviations from the operating point) and two maps from port names to the
columns of ``B`` (actuators) and the rows of ``C`` (sensors), :func:`close_model_loops` builds the
state space of the controlled model:

* each loop ``u = -C(s) e^{-s tau} (y - r)``, ``y = sum_i c_i sensor_i``, acts through its weighted
  actuator terms; loops without delay are closed inside ``A`` by the linear fractional
  transformation of :func:`ctmm.loop_closure.close_loops` (an LTI controller's states appended as
  ``"<loop>.controller<k>"``);
* a loop with ``tau > 0`` stays open beside the state space: input ``"<loop>_u"`` (the loop force),
  output ``"<loop>_y"`` (the weighted sensor sum), :class:`~ctmm.linearized.DelayedLoop`;
* exogenous inputs are actuator ports (or ``"<loop>.reference"`` of a loop without delay: ``D = -1``
  on its sensed sum), outputs are sensor ports, ``"<loop>.y"`` (the sensed value) and ``"<loop>.u"``
  (the loop force, from the closure) of a loop without delay.

The sensed values are deviations from their values at the operating point, so a loop acts on the
deviation of its sensors (its reference equals the sensed value at the operating point).

:func:`delayed_loop_response` is the frequency-domain side: the response of such a linearisation
with its delayed loops closed exactly by ``e^{-s tau}`` at every frequency
(:func:`ctmm.loop_phasors.close_loops`), through :func:`resolvent`: ``(s I - A)^-1 B`` that refuses a
frequency at or next to a pole on the imaginary axis (one rule for planar and spatial models).
"""
from __future__ import annotations

from typing import Any, Callable, Sequence

import numpy as np
import scipy.linalg

from . import validation
from .entire_values import circle_mean_logs
from .errors import ModelError, SingularSystemError
from .linearized import DelayedLoop, LinearizedSystem, control_name
from .loop_closure import close_loops
from .loop_phasors import close_loops as close_phasor_loops, loop_signal

__all__ = ["loop_ports", "exogenous_inputs", "requested_outputs", "close_model_loops", "controller_response",
           "delayed_loop_response", "delayed_loop_response_function", "resolvent", "FrequencyAtPoleError", "RESOLVENT_CONDITION"]

RESOLVENT_CONDITION = 1.0 / float(np.sqrt(np.finfo(float).eps))
"""Largest accepted 2-norm condition number of the system :func:`resolvent` solves (the balanced ``s I - A``
scaled by rows and columns; ``1/sqrt(eps)``, about 6.7e7): beyond it the solve may lose more than half the
digits, and ``s`` lies next to a pole -- :func:`resolvent` refuses it."""


def loop_ports(loops: Sequence[Any]) -> tuple[list[str], list[str]]:
    """The actuators and the sensors the ``loops`` use (each once, in loop order)."""
    actuators = list(dict.fromkeys(name for lp in loops for name, _ in lp.actuator_terms))
    sensors = list(dict.fromkeys(name for lp in loops for name, _ in lp.terms))
    return actuators, sensors


def exogenous_inputs(loops: Sequence[Any], inputs: Any, default: Sequence[str]) -> tuple[list[str], dict[int, int]]:
    """Requested inputs (``default`` for ``None``, none for ``[]``) and ``{input index: loop index}``
    of the ``"<loop>.reference"`` among them (refused for a delayed loop)."""
    if inputs is None:
        return list(default), {}
    if isinstance(inputs, (list, tuple)) and not inputs:
        return [], {}                               # no exogenous input (e.g. for eigenvalues only)
    exo = list(validation.names("inputs", inputs))
    index = {lp.name: j for j, lp in enumerate(loops)}
    references = {}
    for k, name in enumerate(exo):
        head, _, tail = name.partition(".")
        if head in index:
            if tail != "reference" or loops[index[head]].delay > 0.0:
                raise ModelError(f"linearize: input {name!r}: the inputs of a loop are '<loop>.reference' of a "
                                 "loop without delay; a delayed loop is left open (its force is the input "
                                 "'<loop>_u')")
            references[k] = index[head]
    return exo, references


def requested_outputs(loops: Sequence[Any], outputs: Any, default: Sequence[str]
                      ) -> tuple[list[str], dict[int, tuple]]:
    """Requested outputs (``default`` for ``None``, only the delayed loops' ports for ``[]``) and
    ``{output index: (loop index, "y" or "u")}`` of the loop signals among them."""
    if outputs is None:
        req = list(default)
    elif isinstance(outputs, (list, tuple)) and not outputs:
        req = []
    else:
        req = list(validation.names("outputs", outputs))
    index = {lp.name: j for j, lp in enumerate(loops)}
    loop_outputs = {}
    for k, name in enumerate(req):
        head, _, tail = name.partition(".")
        if head in index and tail in ("y", "u"):
            if loops[index[head]].delay > 0.0:
                raise ModelError(f"linearize: output {name!r}: the delayed loop {head!r} is left open, its "
                                 f"sensed value and force are the ports '{head}_y' and '{head}_u' already")
            loop_outputs[k] = (index[head], tail)
    return req, loop_outputs


def close_model_loops(A: np.ndarray, loops: Sequence[Any], *, inputs: Any, outputs: Any,
                      default_inputs: Sequence[str], default_outputs: Sequence[str],
                      input_columns: Callable[[list[str]], np.ndarray],
                      output_rows: Callable[[list[str]], np.ndarray],
                      states: Sequence[str], name: str, point: Any,
                      output_feedthrough: Callable[[list[str], list[str]], np.ndarray] | None = None) -> LinearizedSystem:
    """The :class:`LinearizedSystem` of a plant's tangent ``A`` with ``loops`` (module docstring).

    Parameters
    ----------
    A : ndarray, shape (n, n)
        The plant's tangent (states ``states``).
    loops : sequence of Feedback
        The controlled model's loops (port names of the plant).
    inputs, outputs : as for :func:`ctmm.linearize`
        ``None`` gives ``default_inputs`` / ``default_outputs``.
    default_inputs, default_outputs : sequence of str
        The plant's default exogenous actuator ports and sensed outputs.
    input_columns : callable
        Actuator port names -> ``B`` columns ``(n, len(names))``.
    output_rows : callable
        Sensor port names -> ``C`` rows ``(len(names), n)``.
    states : sequence of str
        Names of the plant's states (controller states are appended).
    name : str
        The model's name.
    point : OperatingPoint
        Where ``A`` was taken.
    output_feedthrough : callable, optional
        (Sensor names, actuator names) -> ``D`` rows of sensors that respond to the actuators at once (a kinematic
        loop's cut forces); ``None``: no feedthrough.

    Returns
    -------
    LinearizedSystem
    """
    import control

    exo, references = exogenous_inputs(loops, inputs, default_inputs)
    req, loop_outputs = requested_outputs(loops, outputs, default_outputs)
    loop_actuators, loop_sensors = loop_ports(loops)
    plant_in = list(dict.fromkeys([x for k, x in enumerate(exo) if k not in references] + loop_actuators))
    plant_out = list(dict.fromkeys([x for k, x in enumerate(req) if k not in loop_outputs] + loop_sensors))
    col = {port: k for k, port in enumerate(plant_in)}
    row = {port: k for k, port in enumerate(plant_out)}
    # plant ports -> [exogenous inputs, one force per loop], [requested outputs, one sensed sum per loop]
    S_in = np.zeros((len(plant_in), len(exo) + len(loops)))
    S_out = np.zeros((len(req) + len(loops), len(plant_out)))
    for k, port in enumerate(exo):
        if k not in references:
            S_in[col[port], k] = 1.0
    for k, port in enumerate(req):
        if k not in loop_outputs:
            S_out[k, row[port]] = 1.0
        elif loop_outputs[k][1] == "y":             # the sensed value (not y - r)
            for sensor, weight in loops[loop_outputs[k][0]].terms:
                S_out[k, row[sensor]] += weight
    for j, lp in enumerate(loops):
        for port, weight in lp.actuator_terms:
            S_in[col[port], len(exo) + j] += weight
        for port, weight in lp.terms:
            S_out[len(req) + j, row[port]] += weight
    n = A.shape[0]
    B = np.asarray(input_columns(plant_in), dtype=float).reshape(n, len(plant_in)) @ S_in
    C = S_out @ np.asarray(output_rows(plant_out), dtype=float).reshape(len(plant_out), n)
    D = np.zeros((C.shape[0], B.shape[1])) if output_feedthrough is None else S_out @ np.asarray(
        output_feedthrough(plant_out, plant_in), dtype=float).reshape(len(plant_out), len(plant_in)) @ S_in
    for k, j in references.items():
        D[len(req) + j, k] = -1.0                   # the loop acts on y - r
    A_cl, B_cl, C_cl, D_cl, sizes, C_u, D_u = close_loops((A, B, C, D), loops, len(exo))
    real_time = [lp for lp in loops if lp.delay == 0.0]
    for k, (j, part) in loop_outputs.items():
        if part == "u":                             # the loop force, from the closure
            C_cl[k], D_cl[k] = C_u[real_time.index(loops[j])], D_u[real_time.index(loops[j])]
    delayed = [lp for lp in loops if lp.delay > 0.0]
    all_states = list(states) + [f"{lp.name}.controller{k}" for lp, size in zip(real_time, sizes)
                                 for k in range(size)]
    labels_in = [control_name(x) for x in exo] + [control_name(f"{lp.name}.u") for lp in delayed]
    labels_out = [control_name(x) for x in req] + [control_name(f"{lp.name}.y") for lp in delayed]
    if not labels_in and len(labels_out) == 1:
        raise ModelError(f"linearize: inputs={inputs!r} leaves the linearisation of {name!r} with no input and "
                         f"the one output {req + [lp.name for lp in delayed]}, a state space python-control cannot "
                         "hold (its D would be 1 x 0); name an input (an actuator or '<loop>.reference') or a "
                         "second output" + ("" if inputs is None else ", or leave inputs=None"))
    ss = control.ss(A_cl, B_cl, C_cl, D_cl, inputs=labels_in, outputs=labels_out,
                    states=[control_name(x) for x in all_states], name=control_name(name))
    return LinearizedSystem(ss, tuple(DelayedLoop(lp.name, lp.gain, lp.delay) for lp in delayed), point)


def controller_response(gain: Any, s: np.ndarray) -> np.ndarray:
    """``C(s)`` of a loop's gain at ``s``: a python-control LTI evaluated, or the static gain."""
    if callable(gain):                                  # a python-control LTI C(s)
        return np.asarray(gain(s), dtype=complex).reshape(s.shape)
    return np.full(s.shape, float(gain), dtype=complex)


def delayed_loop_response(linearize: Callable[[list[str], list[str]], LinearizedSystem], loops: Sequence[Any],
                          s: np.ndarray, inputs: Sequence[str], outputs: Sequence[str],
                          name: str) -> tuple[np.ndarray, Any]:
    """Response ``[i_out, i_in, k]`` of a controlled model's linearisation, delayed loops closed exactly.

    Parameters
    ----------
    linearize : callable
        ``(inputs, outputs) -> LinearizedSystem`` of the model with its ``loops`` (delayed loops open).
    loops : sequence of Feedback
    s : ndarray
        Laplace variables ``i omega``.
    inputs, outputs : sequence of str
        Requested ports, ``"<loop>.reference"``, ``"<loop>.y"``, ``"<loop>.u"`` of any loop.
    name : str
        The model's name (for :func:`resolvent`'s refusal of a frequency at a pole).

    Returns
    -------
    response : ndarray, shape (len(outputs), len(inputs), len(s))
    linearized : LinearizedSystem
    """
    delayed = {lp.name: j for j, lp in enumerate(lp for lp in loops if lp.delay > 0.0)}
    lin_in = [x for x in inputs if loop_signal(x, delayed, ("reference",)) is None]
    lin_out = [x for x in outputs if loop_signal(x, delayed, ("y", "u")) is None]
    lin = linearize(lin_in, lin_out)
    ss = lin.state_space
    A, B, C, D = (np.asarray(m, dtype=float) for m in (ss.A, ss.B, ss.C, ss.D))
    n_i, n_o, n_d = len(lin_in), len(lin_out), len(delayed)

    def closed(z: np.ndarray) -> np.ndarray:
        G = C @ resolvent(A, B, z, name) + D             # (frequencies, lin_out + delayed y, lin_in + delayed u)
        blocks = (G[:, :n_o, :n_i], G[:, :n_o, n_i:], G[:, n_o:, :n_i], G[:, n_o:, n_i:])
        K = np.zeros((z.size, n_d, n_d), dtype=complex)
        for j, loop in enumerate(lin.delays):
            K[:, j, j] = controller_response(loop.gain, z) * np.exp(-z * loop.delay)
        return close_phasor_loops(blocks, K, inputs, outputs, lin_in, lin_out, delayed)
    try:
        return closed(np.asarray(s)), lin
    except FrequencyAtPoleError:
        if not delayed:
            raise
    return np.stack([_closed_at_pole(closed, z) for z in np.asarray(s)], axis=-1), lin


def _closed_at_pole(closed: Callable[[np.ndarray], np.ndarray], s: complex) -> np.ndarray:
    """``closed(s)`` (``[i_out, i_in]``), or where the plant's resolvent refuses ``s`` (a pole of the plant with the
    delayed loops open, which the loops may move: the closed loop is then analytic around ``s``) its certified mean
    on a small circle around ``s`` (:func:`ctmm.entire_values.circle_mean_logs`); the refusal stands where no mean
    is certified (a pole of the closed loop too)."""
    try:
        return closed(np.array([s]))[:, :, 0]
    except FrequencyAtPoleError as refused:
        def logs(circle: np.ndarray) -> np.ndarray:
            with np.errstate(divide="ignore"):
                return np.log(closed(circle).reshape(-1, circle.size))
        try:
            shape = closed(np.array([s * (1.0 + 1e-3)])).shape[:2]
            return np.exp(circle_mean_logs(logs, s, label="the closed loop's response")).reshape(shape)
        except (SingularSystemError, FrequencyAtPoleError):
            raise refused from None


class FrequencyAtPoleError(ModelError):
    """:func:`resolvent` refused a frequency at or next to a pole on the imaginary axis (a
    :class:`~ctmm.errors.ModelError`; the margins' crossing search tells such a sign change of ``L``
    through infinity from a crossing by it)."""


def delayed_loop_response_function(linearize: Callable[[list[str], list[str]], LinearizedSystem],
                                   loops: Sequence[Any], inputs: Sequence[str], outputs: Sequence[str],
                                   name: str) -> Callable[[np.ndarray], np.ndarray]:
    """``s -> response [i_out, i_in, k]`` of :func:`delayed_loop_response`, linearising once: ``linearize``
    runs at the first call only (the ports it is asked for follow from ``inputs``, ``outputs`` and
    ``loops``, the same at every call), and every call answers from that linearisation -- the numbers of
    :func:`delayed_loop_response` at each ``s``, for the price of the resolvent (e.g. the repeated
    evaluations of a crossover search, :func:`ctmm.control.margins`)."""
    taken: list[LinearizedSystem] = []

    def linearized(lin_in: list[str], lin_out: list[str]) -> LinearizedSystem:
        if not taken:
            taken.append(linearize(lin_in, lin_out))
        return taken[0]

    return lambda s: delayed_loop_response(linearized, loops, s, inputs, outputs, name)[0]


def resolvent(A: np.ndarray, B: np.ndarray, s: np.ndarray, name: str) -> np.ndarray:
    """``(s I - A)^-1 B`` at every Laplace variable ``s``, refusing a frequency at or next to a pole.

    ``A`` is balanced first (:func:`scipy.linalg.matrix_balance`: ``A_bal = T^-1 A T``, ``T`` a diagonal of
    powers of two, exact in floating point), so that the test does not depend on the units of the states; then,
    at each ``s``, the rows and columns of ``s I - A_bal`` are scaled by powers of two (``D_r``, ``D_c``: the
    largest modulus of each row, then of each column, brought to about 1), and the system actually solved is
    ``M_s Z = D_r T^-1 B``, ``M_s = D_r (s I - A_bal) D_c``, answer ``X = T D_c Z``.  The rule measures that
    system: a frequency where ``cond_2(M_s) > RESOLVENT_CONDITION`` (``1/sqrt(eps)``) is refused -- there the
    response is unbounded or its digits are lost (an undamped mode at ``omega``, a rigid-body mode or a free
    rotation at ``omega = 0``), and no number is returned rather than a wrong one.  The row and column scaling
    changes the answer by round-off only; it answers stiff models (a fast mode ``1e4`` times above a slow one,
    e.g. a stiff plate subsystem beside soft joints) whose balanced ``s I - A`` alone is ill-conditioned at low
    frequencies although the scaled solve is accurate.

    What the bound certifies: the LU solve with partial pivoting is backward stable, so each column ``z`` of
    ``Z`` has ``|z_computed - z|_2 <= cond_2(M_s) eps c |z|_2`` with ``c`` a modest safety factor (the
    dimension times the pivot growth, in practice a few units): the relative error of every answered column,
    measured in the scaled states ``(T D_c)^-1 x``, is at most ``cond_2(M_s) * eps * c <= sqrt(eps) c`` (about
    half the digits at the limit, typically far more: 1e-10 for the stiff plate chain of
    tests/test_resolvent_scaling.py).  A state much smaller than the others in those scaled units carries that
    absolute error, not a relative one.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        State matrix [1/s].
    B : ndarray, shape (n, m)
        Input matrix.
    s : ndarray of complex, shape (k,)
        ``i omega`` [rad/s].
    name : str
        The model's name (for the message).

    Returns
    -------
    ndarray of complex, shape (k, n, m)

    Raises
    ------
    FrequencyAtPoleError
        A frequency at or next to a pole (a :class:`~ctmm.errors.ModelError`): names ``omega`` [rad/s], the condition
        number of ``M_s`` and the nearest pole of ``A``.
    """
    n = A.shape[0]
    if n == 0:
        return np.zeros((s.size, 0, B.shape[1]), dtype=complex)
    balanced, (scaling, _) = scipy.linalg.matrix_balance(A, permute=False, separate=True)   # T^-1 A T, T = diag
    pencil = s[:, None, None] * np.eye(n) - balanced
    rows, columns = _equilibration(pencil)
    scaled = rows[:, :, None] * pencil * columns[:, None, :]                 # D_r (s I - A_bal) D_c, exact
    with np.errstate(all="ignore"):
        condition = np.linalg.cond(scaled)
    bad = np.flatnonzero(~(condition <= RESOLVENT_CONDITION))
    if bad.size:
        k = int(bad[0])
        poles = np.linalg.eigvals(A)
        pole = complex(poles[np.argmin(np.abs(poles - s[k]))])
        raise FrequencyAtPoleError(f"frequency_response: s I - A of {name!r} is singular at omega = "
                         f"{float(np.imag(s[k]))!r} rad/s, or nearly so (condition number {float(condition[k]):.3g} of the balanced, "
                         f"row- and column-scaled s I - A > 1/sqrt(eps) = {RESOLVENT_CONDITION:.3g}); the nearest pole is "
                         f"{pole.real:.9g}{pole.imag:+.9g}j 1/s (an undamped mode on the imaginary axis, or a rigid-body "
                         "mode or free rotation at omega = 0), where the response is unbounded: leave that frequency "
                         "out or move it off the pole")
    right = rows[:, :, None] * (B / scaling[:, None])[None, :, :]               # D_r T^-1 B
    solution = np.linalg.solve(scaled, right) * columns[:, :, None]             # T^-1 X = D_c Z
    return solution * scaling[None, :, None]


def _equilibration(pencil: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row and column scale factors ``D_r``, ``D_c`` of a stack of square matrices ``M``: powers of two (exact in
    floating point) that bring the largest modulus of each row of ``D_r M``, then of each column of ``D_r M D_c``,
    into ``[1/sqrt(2), sqrt(2)]`` (LAPACK ``zgeequ``'s equilibration, rounded to powers of two).  A zero row or
    column keeps the factor 1 (the matrix is singular: its condition number stays infinite).

    Parameters
    ----------
    pencil : ndarray of complex, shape (k, n, n)

    Returns
    -------
    rows, columns : ndarray, shape (k, n)
    """
    def reciprocal(largest: np.ndarray) -> np.ndarray:
        return np.exp2(-np.round(np.log2(np.where(largest > 0.0, largest, 1.0))))

    with np.errstate(all="ignore"):
        rows = reciprocal(np.abs(pencil).max(axis=2))
        columns = reciprocal(np.abs(rows[:, :, None] * pencil).max(axis=1))
    return rows, columns
