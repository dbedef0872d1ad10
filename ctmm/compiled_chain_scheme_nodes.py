"""Generated DT-TMM steps of 1-D chains with massless points or a prescribed boundary motion (issue 13).

:mod:`ctmm.compiled_chain_schemes` steps the moving masses of a chain whose every moving point has a mass and whose
supports stand still.  The Python DT-TMM path (:func:`ctmm.timestep.simulate`) keeps a scheme history at every
connection point, massless ones and the prescribed supports included, and solves the chain at the scheme's
evaluation level.  This module states that same step on the chain's nodes:

* the **free nodes** (masses and massless nodes, :class:`ctmm.chain_ode.ChainDynamics`) each keep the history
  ``(x, v, a, x_{n-1}, x_{n-2})`` and take the correction ``delta`` the step solves for;
* a **moving support** (a prescribed start or end displacement given by a signal) keeps its history too and takes
  the correction ``X(t_eval) - x_pred`` (the Python path's boundary relation,
  :meth:`ctmm.elements.boundary.Boundary.start_discrete`), so its velocity is the scheme's, as there;
* the equation of every free node at the evaluation level is its row of the explicit context
  (:meth:`~ctmm.chain_ode.ChainDynamics.forces`: the acceleration of a mass, the force balance of a massless node),
  affine in the nodes' ``x_eval``, ``v_eval``, the supports' ``(x, v, a)_eval`` and the loads, read exactly by unit
  probes (:func:`node_form`): ``(C I_mass - cx Rx - A Rv) delta = Rx dx + Rv B + r0 + loads + supports - I_mass D``,
  tridiagonal (factorised once), the loads weighted ``(1 - w) s(t_n) + w s(t_n + h)`` as the other generated
  chain steps weight them.

Stored as the Python DT-TMM path stores them: positions and velocities of the scheme at every point (the velocity of
an algebraic massless point from its positions, :func:`ctmm.massless_points.algebraic_point_rates`, read from the
positions the history keeps), accelerations of the equation of motion at the masses (``NaN`` at massless points, the
support's scheme acceleration on it), connector law forces.

Refused (:class:`~ctmm.errors.ModelError`, named): loops and held actuators with massless points or a prescribed
motion (the generated RK4 takes them), connectors with inertance next to massless points, varying loads on massless
nodes, load or motion signals without a symbolic form.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
import scipy.sparse

from .chain_ode import ChainDynamics
from .chain_point_rows import point_forces_rows
from .chain_start import initial_acceleration, point_labels, rest_positions
from .compiled_chain_kernel import banded_solver
from .errors import ModelError
from .guard import DivergenceGuard
from .massless_points import algebraic_points
from .results import SimulationResult
from .signals import Constant, signal_parameters, symbolic_signal
from .timestep import dttmm_start_state

__all__ = ["NodeForm", "node_form", "node_guard", "node_kinematics", "node_result", "node_start", "node_step"]


@dataclass(frozen=True)
class NodeForm:
    """The rows of a chain's free nodes at the evaluation level (module docstring).

    Attributes
    ----------
    free : ndarray of int
        Node indices of the masses and massless nodes, in chain order.
    inertial : ndarray of bool
        Which free nodes have a mass (their row is an acceleration [m/s^2]; a massless node's a force [N]).
    Rx, Rv : ndarray, shape (f, f)
        Rows per unit ``x_eval`` [m] and ``v_eval`` [m/s] of the free nodes.
    r0 : ndarray, shape (f,)
        Rows at rest (constant loads and still supports).
    loads : list of (ndarray, signal)
        Rows per unit varying load and its signal.
    supports : list of (ndarray (f, 3), signal)
        Rows per unit ``(x, v, a)_eval`` of each moving support and its displacement signal (start first).
    """

    free: np.ndarray
    inertial: np.ndarray
    Rx: np.ndarray
    Rv: np.ndarray
    r0: np.ndarray
    loads: list
    supports: list


def _symbolic(signal: Any, what: str) -> Any:
    """The parameters of a signal with a symbolic form, else a named ModelError."""
    parameters = signal_parameters(signal)
    if parameters is None:
        raise ModelError(f"{what} {signal!r} is a Python callable of time, which generated kernels cannot evaluate; "
                         "give a ctmm.signals Constant, Harmonic, Step or SquareWave, or use compiled=False")
    return parameters


def _still(boundary: Any) -> tuple[float, float, float]:
    """Position [m], velocity, acceleration of a support that stands still (zeros for a force-type boundary and a
    moving support, whose motion is its history)."""
    if boundary.known != "displacement":
        return 0.0, 0.0, 0.0
    signal = getattr(boundary, "displacement", None)
    if signal is not None:
        return (float(signal.value) if isinstance(signal, Constant) else 0.0), 0.0, 0.0
    return float(getattr(boundary, "position", 0.0)), 0.0, 0.0


def node_form(dynamics: ChainDynamics) -> NodeForm:
    """The :class:`NodeForm` of a plain lumped chain by unit probes of its explicit context (one batched call).

    Raises
    ------
    ModelError
        A connector with inertance next to a massless node, a varying load on a massless node, load or motion
        signals without a symbolic form.
    """
    chain, tree = dynamics.chain, dynamics.tree
    free = np.flatnonzero(~dynamics.held)
    inertial = dynamics.inertial[free]
    if dynamics.index_Q.size and any(getattr(e.lumped_coefficients(), "mass", 0.0) and not e.is_point
                                     for e in chain.body):
        raise ModelError(f"chain {chain.name!r}: a connector with inertance (inerter) and points without inertia; "
                         "the generated DT-TMM step does not take both: use compiled=False")
    massless = set(dynamics.index_Q.tolist())
    for position, name, signal, element in dynamics.loads:
        body = 0 if position == 0 else (len(tree.bodies) - 1 if position == len(chain.elements) - 1 else
                                         tree.positions.index(position) if position in tree.positions else -1)
        if not isinstance(signal, Constant) and body >= 0 and tree.node[body] in massless:
            raise ModelError(f"chain {chain.name!r}: the varying {name!r} load {signal!r} of {element.name!r} acts "
                             "on a point without inertia; the generated DT-TMM step does not take it: give the point "
                             "a mass, or use compiled=False")
    start, end = chain.start, chain.end
    start_moves = start.known == "displacement" and hasattr(start, "displacement") and \
        not isinstance(start.displacement, Constant)
    end_moves = end.known == "displacement" and hasattr(end, "displacement") and not isinstance(end.displacement,
                                                                                               Constant)
    base_start = (0.0, 0.0, 0.0) if start_moves else _still(start)
    base_end = (0.0, 0.0, 0.0) if end_moves else _still(end)
    n, f = tree.n_nodes, free.size
    varying = [(position, name, signal) for position, name, signal, _ in dynamics.loads
               if not isinstance(signal, Constant)]
    constant: dict[int, dict[str, float]] = {}
    for position, name, signal, _ in dynamics.loads:
        if isinstance(signal, Constant):
            constant.setdefault(position, {})[name] = float(signal.value)
    # probes: rest, x of each free node, v of each, each varying load, (x, v, a) of each moving support
    cases: list[tuple[np.ndarray, np.ndarray, dict, tuple, tuple]] = []

    def case(x_unit: int = -1, v_unit: int = -1, load: int = -1, start_motion=None, end_motion=None) -> None:
        x, v = np.zeros(n), np.zeros(n)
        if x_unit >= 0:
            x[free[x_unit]] = 1.0
        if v_unit >= 0:
            v[free[v_unit]] = 1.0
        motion = start_motion if start_motion is not None else base_start
        if start.known == "displacement":
            x[dynamics.held], v[dynamics.held] = motion[0], motion[1]
        inputs = {position: dict(values) for position, values in constant.items()}
        if load >= 0:
            position, name, _ = varying[load]
            slot = inputs.setdefault(position, {})
            slot[name] = slot.get(name, 0.0) + 1.0
        if hasattr(start, "displacement"):
            inputs.setdefault(0, {})["displacement"] = float(motion[2])
        cases.append((x, v, inputs, tuple(end_motion if end_motion is not None else base_end)))

    case()
    for j in range(f):
        case(x_unit=j)
    for j in range(f):
        case(v_unit=j)
    for j in range(len(varying)):
        case(load=j)
    moving = [(start_moves, start), (end_moves, end)]
    for moves, boundary in moving:
        if moves:
            for slot in range(3):
                unit = tuple(float(slot == k) for k in range(3))
                case(start_motion=unit) if boundary is start else case(end_motion=unit)
    rows = np.zeros((len(cases), f))              # one batched sweep per (inputs, wall): the state probes together
    start = 0
    while start < len(cases):
        stop = start + 1
        while stop < len(cases) and cases[stop][2:] == cases[start][2:]:
            stop += 1
        x, v = np.array([c[0] for c in cases[start:stop]]), np.array([c[1] for c in cases[start:stop]])
        rows[start:stop] = dynamics.forces(x, v, 0.0, cases[start][2], cases[start][3])[:, free]
        start = stop
    base = rows[0]
    Rx, Rv = (rows[1:1 + f] - base).T, (rows[1 + f:1 + 2 * f] - base).T
    at = 1 + 2 * f
    loads = []
    for j, (_, _, signal) in enumerate(varying):
        _symbolic(signal, "a load signal")
        loads.append((rows[at + j] - base, signal))
    at += len(varying)
    supports = []
    for moves, boundary in moving:
        if moves:
            _symbolic(boundary.displacement, f"{boundary.name}: the displacement signal")
            supports.append(((rows[at:at + 3] - base).T, boundary.displacement))
            at += 3
    return NodeForm(free, inertial, Rx, Rv, base, loads, supports)


def node_step(form: NodeForm, maps: Any, dt: float, size: int) -> Any:
    """``(state, t_n) -> new histories`` of one set of :class:`~ctmm.compiled_chain_schemes.SchemeMaps`: the state
    ``[history of the free nodes (5 f), history of each moving support (5 each), ...]`` (``size`` entries), the new
    histories ``5 (f + supports)`` entries."""
    import casadi as ca

    f = form.free.size
    y, t_n = ca.MX.sym("y", size), ca.MX.sym("t")
    w, t_eval = maps.load_weight, t_n + maps.offset
    parts = [y[j * f:(j + 1) * f] for j in range(5)]

    def rows(r: int, history: list) -> Any:
        return sum((float(maps.coefficients[r, c]) * history[c] for c in range(5) if maps.coefficients[r, c]),
                   ca.MX.zeros(history[0].numel()))

    dx, B, D = (rows(r, parts) for r in range(3))
    mass = form.inertial.astype(float)
    sparse = [ca.DM(scipy.sparse.csc_matrix(matrix)) for matrix in (form.Rx, form.Rv)]
    rhs = ca.mtimes(sparse[0], dx) + ca.mtimes(sparse[1], B) + ca.DM(form.r0) - ca.DM(mass) * D
    for column, signal in form.loads:
        parameters = signal_parameters(signal)
        value = symbolic_signal(type(signal), t_n + dt, parameters)
        if w != 1.0:
            value = (1.0 - w) * symbolic_signal(type(signal), t_n, parameters) + w * value
        rhs += ca.DM(column) * value
    out, supports = [], []
    for k, (columns, signal) in enumerate(form.supports):
        start = 5 * f + 5 * k
        history = [y[start + j] for j in range(5)]
        predicted = sum((float(maps.predictor[c]) * history[c] for c in range(5) if maps.predictor[c]), 0.0)
        correction = symbolic_signal(type(signal), t_eval, signal_parameters(signal)) - predicted
        evaluated = [maps.cx * correction + rows(0, history), maps.A * correction + rows(1, history),
                     maps.C * correction + rows(2, history)]
        for slot in range(3):
            rhs += ca.DM(columns[:, slot]) * evaluated[slot]
        supports.append((history, correction))
    matrix = maps.C * np.diag(mass) - maps.cx * form.Rx - maps.A * form.Rv
    delta = banded_solver(matrix)(rhs)

    def updated(history: list, correction: Any) -> list:
        every = history + [correction]
        return [sum((float(maps.update[r, c]) * every[c] for c in range(6) if maps.update[r, c]),
                    ca.MX.zeros(history[0].numel())) for r in range(5)]

    out += updated(parts, delta)
    for history, correction in supports:
        out += updated(history, correction)
    return ca.Function("node_step", [y, t_n], [ca.vertcat(*out)])


def node_start(dynamics: ChainDynamics, form: NodeForm, x0: Any, v0: Any) -> tuple[np.ndarray, bool]:
    """``(state, consistent)``: the histories at ``t = 0`` as the Python DT-TMM path starts
    (:func:`ctmm.timestep.dttmm_start_state`, :func:`ctmm.chain_start.initial_acceleration`; the older positions
    equal to the positions), and whether the massless points start on their balance."""
    chain = dynamics.chain
    x, v, consistent = dttmm_start_state(chain, x0, v0, 0.0)
    a = initial_acceleration(chain, x, v, 0.0, {})
    point = _first_points(dynamics, form)
    blocks = [np.concatenate([x[point, 0], v[point, 0], a[point, 0], x[point, 0], x[point, 0]])]
    for index in _support_points(dynamics, form):
        blocks.append(np.array([x[index, 0], v[index, 0], a[index, 0], x[index, 0], x[index, 0]]))
    return np.concatenate(blocks), consistent


def _first_points(dynamics: ChainDynamics, form: NodeForm) -> np.ndarray:
    """The first connection point of every free node."""
    nodes = dynamics.node_of_point
    return np.array([int(np.flatnonzero(nodes == k)[0]) for k in form.free])


def _support_points(dynamics: ChainDynamics, form: NodeForm) -> list[int]:
    """A connection point of each moving support, in the order of :attr:`NodeForm.supports`."""
    chain, out = dynamics.chain, []
    if form.supports and chain.start.known == "displacement" and hasattr(chain.start, "displacement") and \
            not isinstance(chain.start.displacement, Constant):
        out.append(0)
    if len(out) < len(form.supports):
        out.append(chain.n_points - 1)
    return out


def node_guard(dynamics: ChainDynamics, form: NodeForm, states: np.ndarray, bound: float | None
               ) -> tuple[Callable[[float, int], None], np.ndarray]:
    """``(check(t, row), passes)``: the Python DT-TMM path's guard (:class:`~ctmm.guard.DivergenceGuard` on every
    connection point from the start) on the positions of the stored ``states``, and whether it accepts each row
    (the rows it refuses go to ``check``, which raises with its message)."""
    chain = dynamics.chain
    x = node_kinematics(dynamics, form, states)[0]
    guard = DivergenceGuard.from_start(point_labels(chain), rest_positions(chain), x[0], bound=bound)
    return (lambda t, row: guard.check(t, x[row])), guard.passes(x)


def node_kinematics(dynamics: ChainDynamics, form: NodeForm, states: np.ndarray) -> tuple:
    """``(x, v, a_supports, x_nodes, v_nodes, motion)`` of stored rows: positions [m] and velocities [m/s]
    ``(rows, n_points)`` of every point (accelerations of the supports, ``NaN`` elsewhere), of every node, and the
    moving supports' ``{point: (x, v, a)}``."""
    chain = dynamics.chain
    f, count, n_points = form.free.size, len(states), chain.n_points
    nodes = dynamics.node_of_point
    x_nodes, v_nodes = np.zeros((count, dynamics.tree.n_nodes)), np.zeros((count, dynamics.tree.n_nodes))
    x_nodes[:, form.free], v_nodes[:, form.free] = states[:, :f], states[:, f:2 * f]
    motion: dict[int, tuple] = {}                       # support point -> (x, v, a) columns
    for k, index in enumerate(_support_points(dynamics, form)):
        start = 5 * f + 5 * k
        motion[index] = (states[:, start], states[:, start + 1], states[:, start + 2])
    x = np.zeros((count, n_points))
    v, a = np.zeros((count, n_points)), np.full((count, n_points), np.nan)
    boundary = np.tile(np.array([*_still(chain.start), *_still(chain.end)]), (count, 1))   # (still supports)
    if chain.start.known == "displacement":
        held = (motion[0][0], motion[0][1]) if 0 in motion else (boundary[:, 0], boundary[:, 1])
        x_nodes[:, dynamics.held], v_nodes[:, dynamics.held] = held[0][:, None], held[1][:, None]
    wall = motion.get(n_points - 1) if nodes[n_points - 1] < 0 else None
    for p, k in enumerate(nodes):
        if k >= 0:
            x[:, p], v[:, p] = x_nodes[:, k], v_nodes[:, k]
        elif wall is not None:
            x[:, p], v[:, p], a[:, p] = wall
        else:
            x[:, p], v[:, p], a[:, p] = boundary[:, 3], boundary[:, 4], boundary[:, 5]
    return x, v, a, x_nodes, v_nodes, motion


def node_result(dynamics: ChainDynamics, form: NodeForm, times: np.ndarray, steps: np.ndarray, states: np.ndarray,
                dt: float, consistent: bool, method: str, info: dict) -> SimulationResult:
    """The stored rows (``steps``: the step of each row, 0 first) as the result (module docstring)."""
    chain = dynamics.chain
    f, count, n_points = form.free.size, len(times), chain.n_points
    nodes = dynamics.node_of_point
    x, v, a, x_nodes, v_nodes, motion = node_kinematics(dynamics, form, states)
    start_moving = 0 in motion
    # accelerations of the equation of motion at the stored states: the rows of the masses (exact, affine)
    times = np.asarray(times, float)
    rows = states[:, :f] @ form.Rx.T + states[:, f:2 * f] @ form.Rv.T + form.r0
    for column, signal in form.loads:
        rows += np.array([float(signal(t)) for t in times])[:, None] * column
    for k, (columns, _) in enumerate(form.supports):
        rows += states[:, 5 * f + 5 * k:5 * f + 5 * k + 3] @ columns.T
    column_of = {int(k): j for j, k in enumerate(form.free)}
    for p, k in enumerate(nodes):
        if k >= 0 and dynamics.inertial[k]:
            a[:, p] = rows[:, column_of[int(k)]]
        elif k >= 0 and dynamics.held[k]:
            a[:, p] = motion[0][2] if start_moving else _still(chain.start)[2]
    forces = point_forces_rows(chain, times, x, v, np.where(np.isnan(a), 0.0, a),
                               [None] * count)
    algebraic = algebraic_points(chain)
    if np.any(algebraic):                               # their velocity from the positions the history keeps
        old1, old2 = np.zeros((count, n_points)), np.zeros((count, n_points))
        for p, k in enumerate(nodes):
            if k >= 0 and k in form.free:
                j = int(np.flatnonzero(form.free == k)[0])
                old1[:, p], old2[:, p] = states[:, 3 * f + j], states[:, 4 * f + j]
        first = v[0, algebraic] if consistent else np.full(int(algebraic.sum()), np.nan)
        xa, o1, o2 = x[:, algebraic], old1[:, algebraic], old2[:, algebraic]
        later = (3.0 * xa - 4.0 * o1 + o2) / (2.0 * dt)
        one = 2.0 * (xa - o1) / dt - first if consistent else (xa - o1) / dt
        step = np.asarray(steps)[:, None]
        v[:, algebraic] = np.where(step >= 2, later, np.where(step == 1, one, first))
        a[:, algebraic] = np.nan
    array = np.stack([x, forces], axis=2)
    return SimulationResult(np.asarray(times, float), array, v[:, :, None], a[:, :, None], chain, method, dict(info))
